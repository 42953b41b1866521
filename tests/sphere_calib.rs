//! The single-sphere calibration (issue 15) against the simulator's truth: pingcal's
//! weighted estimate and the published closed form (Tóth, Pusztai & Hajder 2020) on the
//! same simulated frames.
//!
//! * `recovers_truth_within_its_sigma` (fast, 4 seeds): every component of pingcal's
//!   extrinsic error within 4 σ, and the RMS of the z-scores over seeds and components in
//!   [0.4, 2.0] (24 z-scores: a 95 % range of a χ²₂₄ RMS for correct σ is about
//!   [0.7, 1.3]; the wider bounds leave room for the lidar fit's known small optimism).
//! * `twenty_seed_comparison` (`#[ignore]`, the bench: `bash bench/spherecalib/run.sh`, or
//!   `cargo test --release -p pingcal --test cli sphere_calib:: -- --ignored --nocapture`): the
//!   table of mean |Δt|, mean ΔR and the ratio of the RMS error to the reported σ for both.

use nalgebra::{Matrix3, Rotation3, Vector3};
use pingcal_pipeline::sphere_calib::{calibrate, Outcome};
use pingcal_sim::place::simulate_sphere_calib_into;
use pingcal_sim::sphere_calib::{read_sphere_calib_truth, SphereCalibConfig};

/// Errors of one estimate against the truth.
#[derive(Debug, Clone, Copy)]
struct Errors {
    dt: Vector3<f64>,
    dtheta: Vector3<f64>,
    sigma_t: Vector3<f64>,
    sigma_theta: Vector3<f64>,
}

impl Errors {
    fn of(
        r: &Matrix3<f64>,
        t: &Vector3<f64>,
        rt: &Matrix3<f64>,
        tt: &Vector3<f64>,
    ) -> (Vector3<f64>, Vector3<f64>) {
        // R = exp([δθ]×) R_true: δθ about the camera axes, as the registration's covariance
        let d = Rotation3::from_matrix_unchecked(r * rt.transpose()).scaled_axis();
        (t - tt, d)
    }
    fn z(&self) -> [f64; 6] {
        let mut z = [0.0; 6];
        for k in 0..3 {
            z[k] = self.dt[k] / self.sigma_t[k];
            z[k + 3] = self.dtheta[k] / self.sigma_theta[k];
        }
        z
    }
}

/// Simulates seed `seed` into a temporary folder, calibrates, compares with the truth:
/// (pingcal, closed form, frames used).
fn run_seed(seed: u64) -> (Errors, Errors, usize, Outcome, [Vec<f64>; 2]) {
    run_seed_in(seed, SphereCalibConfig::default()).0
}

/// [`run_seed`] with `cfg`; also the frames whose silhouette is at least half in the image
/// and whose cloud gave the lidar's sphere but which were left out, or whose chosen
/// silhouette is not the ball's (its circle's centre more than half its radius from the
/// image of the ball's true centre): ids, visible fraction and why.
#[allow(clippy::type_complexity)]
fn run_seed_in(
    seed: u64,
    mut cfg: SphereCalibConfig,
) -> (
    (Errors, Errors, usize, Outcome, [Vec<f64>; 2]),
    Vec<(String, f64, String)>,
) {
    let dir = std::env::temp_dir().join(format!(
        "pingcal-spherecalib-{}-{seed}-{:?}",
        std::process::id(),
        cfg.scene
    ));
    let _ = std::fs::remove_dir_all(&dir);
    // the bench's lidar σ (bench/spherecalib/run.sh SIGMA_MM), default the VLP-16 profile
    if let Ok(v) = std::env::var("PINGCAL_SPHERECALIB_LIDAR_SIGMA_MM") {
        cfg.noise = pingcal_lrf::RangeNoise::linear(v.parse().unwrap(), 0.0).unwrap();
        cfg.noise_name = None;
    }
    simulate_sphere_calib_into(&dir, &cfg, seed).unwrap();
    let truth = read_sphere_calib_truth(&dir.join("truth.json")).unwrap();
    let o = calibrate(&dir.join("sphere-calib.toml"), 1).unwrap();
    let missed: Vec<(String, f64, String)> = o
        .frames
        .iter()
        .zip(&truth.frames)
        .filter(|(f, t)| t.visible_fraction >= 0.5 && f.lidar.is_some())
        .filter_map(|(f, t)| {
            let truth = Vector3::from(t.centre_camera_mm);
            let why = match (&f.skipped, &f.image) {
                (Some(why), _) => why.clone(),
                // chosen, but another silhouette than the ball's (a plate, the marking): its
                // circle's centre is not within half its radius of the true centre's image
                (None, Some(s))
                    if o.camera.project(&truth).is_none_or(|uv| {
                        (uv.0 - s.image_centre.0).hypot(uv.1 - s.image_centre.1) > 0.5 * s.radius_px
                    }) =>
                {
                    format!(
                        "not the ball: {:.0} mm from its true centre",
                        (s.centre - truth).norm()
                    )
                }
                _ => return None,
            };
            Some((f.id.clone(), t.visible_fraction, why))
        })
        .collect();
    let tp = truth.extrinsic.to_pose();
    let reg = &o.evaluation.registration;
    let (dt, dtheta) = Errors::of(
        &reg.camera_from_lrf.rotation,
        &reg.camera_from_lrf.translation,
        &tp.rotation,
        &tp.translation,
    );
    let ours = Errors {
        dt,
        dtheta,
        sigma_t: reg.sigma_translation_mm,
        sigma_theta: reg.sigma_rotation_vector_deg.map(f64::to_radians),
    };
    let cf = &o
        .closed_form
        .as_ref()
        .expect("every frame has a closed form")
        .registration;
    let (dt, dtheta) = Errors::of(
        &cf.camera_from_lrf.rotation,
        &cf.camera_from_lrf.translation,
        &tp.rotation,
        &tp.translation,
    );
    let theirs = Errors {
        dt,
        dtheta,
        sigma_t: cf.sigma_translation_mm,
        sigma_theta: cf.sigma_rotation_vector_deg.map(f64::to_radians),
    };
    let used = o.frames.iter().filter(|f| f.skipped.is_none()).count();
    // per-frame centre errors, for the log, and their z-scores (camera, lidar)
    let mut zs: [Vec<f64>; 2] = [Vec::new(), Vec::new()];
    for (f, tf) in o.frames.iter().zip(&truth.frames) {
        let ct = Vector3::from(tf.centre_camera_mm);
        let lt = Vector3::from(tf.centre_lidar_mm);
        if let Some(s) = &f.image {
            let d = s.centre - ct;
            let sd = s.cov.diagonal().map(f64::sqrt);
            if f.skipped.is_none() {
                zs[0].extend((0..3).map(|k| d[k] / sd[k]));
            }
            println!(
                "seed {seed} {} camera Δ = ({:.2}, {:.2}, {:.2}) σ ({:.2}, {:.2}, {:.2}), closed form Δ = ({:.2}, {:.2}, {:.2}); range {:.0} mm",
                f.id, d.x, d.y, d.z, sd.x, sd.y, sd.z,
                s.closed_form.map_or(f64::NAN, |c| (c - ct).x), s.closed_form.map_or(f64::NAN, |c| (c - ct).y), s.closed_form.map_or(f64::NAN, |c| (c - ct).z), ct.norm()
            );
        }
        if let Some(l) = &f.lidar {
            let (n, s0) = (l.inliers, l.sigma0);
            let d = l.centre - lt;
            let sd = l.cov.diagonal().map(f64::sqrt);
            if f.skipped.is_none() {
                zs[1].extend((0..3).map(|k| d[k] / sd[k]));
            }
            println!(
                "seed {seed} {} lidar  Δ = ({:.2}, {:.2}, {:.2}) σ ({:.2}, {:.2}, {:.2}), {n} rays, σ0 {s0:.2}",
                f.id, d.x, d.y, d.z, sd.x, sd.y, sd.z
            );
        }
        if let Some(s) = &f.skipped {
            println!("seed {seed} {} skipped: {s}", f.id);
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    ((ours, theirs, used, o, zs), missed)
}

struct Summary {
    mean_dt: f64,
    mean_dr_deg: f64,
    rms_z: [f64; 6],
    rms_z_all: f64,
    max_abs_z: f64,
}

fn summarise(e: &[Errors]) -> Summary {
    let n = e.len() as f64;
    let mut rms_z = [0.0; 6];
    let mut max_abs_z: f64 = 0.0;
    for x in e {
        for (k, z) in x.z().iter().enumerate() {
            rms_z[k] += z * z / n;
            max_abs_z = max_abs_z.max(z.abs());
        }
    }
    let rms_z_all = (rms_z.iter().sum::<f64>() / 6.0).sqrt();
    Summary {
        mean_dt: e.iter().map(|x| x.dt.norm()).sum::<f64>() / n,
        mean_dr_deg: e.iter().map(|x| x.dtheta.norm().to_degrees()).sum::<f64>() / n,
        rms_z: rms_z.map(f64::sqrt),
        rms_z_all,
        max_abs_z,
    }
}

fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|z| z * z).sum::<f64>() / v.len().max(1) as f64).sqrt()
}

fn table(seeds: std::ops::RangeInclusive<u64>) -> (Summary, Summary, usize) {
    let (mut ours, mut theirs, mut frames) = (Vec::new(), Vec::new(), 0);
    let mut zs: [Vec<f64>; 2] = [Vec::new(), Vec::new()];
    for seed in seeds {
        let (a, b, used, _, z) = run_seed(seed);
        zs[0].extend(&z[0]);
        zs[1].extend(&z[1]);
        println!(
            "seed {seed}: {used} frames; pingcal |Δt| {:.2} mm, ΔR {:.4}°, z {:?}; closed form |Δt| {:.2} mm, ΔR {:.4}°",
            a.dt.norm(),
            a.dtheta.norm().to_degrees(),
            a.z().map(|z| (z * 100.0).round() / 100.0),
            b.dt.norm(),
            b.dtheta.norm().to_degrees()
        );
        ours.push(a);
        theirs.push(b);
        frames += used;
    }
    println!(
        "centres of the frames used: RMS z-score of the camera centres {:.2} ({} components), of the lidar centres {:.2}",
        rms(&zs[0]),
        zs[0].len(),
        rms(&zs[1])
    );
    (summarise(&ours), summarise(&theirs), frames)
}

fn print(name: &str, s: &Summary) {
    println!(
        "| {name} | {:.2} | {:.4} | {:.2} {:.2} {:.2} | {:.2} {:.2} {:.2} | {:.2} | {:.1} |",
        s.mean_dt,
        s.mean_dr_deg,
        s.rms_z[0],
        s.rms_z[1],
        s.rms_z[2],
        s.rms_z[3],
        s.rms_z[4],
        s.rms_z[5],
        s.rms_z_all,
        s.max_abs_z
    );
}

#[test]
fn recovers_truth_within_its_sigma() {
    let (ours, theirs, frames) = table(1..=4);
    println!("| method | mean |Δt| mm | mean ΔR ° | RMS z of tx ty tz | RMS z of θx θy θz | RMS z | max |z| |");
    print("pingcal", &ours);
    print("closed form", &theirs);
    // the far frames (beyond ~8.5 m only one ring crosses the sphere) are rejected by the
    // finder as undetermined: most seeds use 8 or 9 of 10
    assert!(frames >= 28, "only {frames} of 40 frames used");
    assert!(
        ours.max_abs_z < 4.0,
        "an error beyond 4σ: {}",
        ours.max_abs_z
    );
    assert!(
        (0.4..=2.0).contains(&ours.rms_z_all),
        "RMS of the z-scores {:.2}",
        ours.rms_z_all
    );
    assert!(ours.mean_dt < 5.0 && ours.mean_dr_deg < 0.1);
}

/// The 20-seed comparison of the closing note (bench/spherecalib/run.sh runs it).
#[test]
#[ignore]
fn twenty_seed_comparison() {
    let (ours, theirs, frames) = table(1..=20);
    println!("frames used: {frames} of 200");
    println!("| method | mean |Δt| mm | mean ΔR ° | RMS z of tx ty tz | RMS z of θx θy θz | RMS z | max |z| |");
    println!("|---|---|---|---|---|---|---|");
    print("pingcal (weighted, cone fit)", &ours);
    print("closed form (Tóth et al., SVD)", &theirs);
}

/// The harder rendering (a shaded sphere with a highlight on a stand, bricks, tiles,
/// bright round plates, every fourth frame across the border) over `seeds`: per seed the
/// frames used, those at least half visible with a lidar sphere that were left out, and
/// whether every component of the extrinsic is within 3σ of the truth. Returns (seeds
/// within 3σ, frames at least half visible left out).
fn cluttered_study(seeds: std::ops::RangeInclusive<u64>, frames: usize) -> (usize, usize) {
    let (mut within, mut missed_all, mut n) = (0, 0, 0);
    for seed in seeds {
        let cfg = SphereCalibConfig {
            frames,
            ..SphereCalibConfig::cluttered()
        };
        let ((ours, _, used, o, _), missed) = run_seed_in(seed, cfg);
        let z = ours.z();
        let max_z = z.iter().map(|v| v.abs()).fold(0.0, f64::max);
        within += usize::from(max_z <= 3.0);
        missed_all += missed.len();
        n += 1;
        println!(
            "cluttered seed {seed}: {used} of {} frames used; |Δt| {:.2} mm, ΔR {:.4}°, max |z| {max_z:.2}; σ0 {:.2} (σ's scaled by {}); half-visible frames left out or not the ball: {missed:?}",
            o.frames.len(),
            ours.dt.norm(),
            ours.dtheta.norm().to_degrees(),
            o.sensor_sigma0,
            o.sigma_scale
                .map_or("none".to_string(), |k| format!("{k:.2}")),
        );
    }
    println!("cluttered: {within} of {n} seeds within 3σ on every component; {missed_all} frames at least half visible left out or not the ball");
    (within, missed_all)
}

/// The ten-seed study of the harder rendering (`bash bench/spherecalib/run.sh cluttered`).
#[test]
#[ignore]
fn cluttered_ten_seed_study() {
    cluttered_study(1..=10, 10);
}

/// Two seeds of the harder rendering: in every frame whose silhouette is at least half in
/// the image the ball is chosen, never a plate, the window or the floor marking. Seed 4's
/// F04 and F09 are balls whose dark lower half is against dark bricks (the edge search
/// following only the strongest edge left them out). (The ten-seed study, `bash
/// bench/spherecalib/run.sh cluttered`: the extrinsic within 3σ in 9 of 10, the σ's of the
/// five doubtful seeds scaled by their σ0; no frame at least half visible left out over 10
/// seeds; docs/sphere-calib.md.)
#[test]
fn the_harder_rendering_finds_the_ball_in_clutter() {
    let (_, missed) = cluttered_study(2..=2, 8);
    assert_eq!(missed, 0);
    let (_, missed) = cluttered_study(4..=4, 10);
    assert_eq!(missed, 0);
}

/// The command as a user runs it: a frame with two spheres in its cloud and a frame whose
/// image has no sphere are reported and left out; an earlier results.json is never
/// replaced without `--overwrite`; bad values are one line naming the file.
#[test]
fn the_command_reports_frames_it_leaves_out_and_keeps_earlier_results() {
    let exe = env!("CARGO_BIN_EXE_pingcal");
    let dir = std::env::temp_dir().join(format!("pingcal-spherecalib-cli-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let data = dir.join("data");
    let run = |args: &[&str]| {
        let o = std::process::Command::new(exe).args(args).output().unwrap();
        (
            o.status.success(),
            String::from_utf8_lossy(&o.stdout).to_string(),
            String::from_utf8_lossy(&o.stderr).to_string(),
        )
    };
    let d = data.to_str().unwrap();
    let (ok, out, err) = run(&[
        "simulate",
        "--kind",
        "sphere-calib",
        "--frames",
        "6",
        "--seed",
        "7",
        "--out",
        d,
    ]);
    assert!(ok, "{out}{err}");
    assert!(
        out.starts_with("simulate: wrote") && out.contains("6 frames"),
        "{out}"
    );
    // a data set is never written over another
    let (ok, _, err) = run(&["simulate", "--kind", "sphere-calib", "--out", d]);
    assert!(
        !ok && err.contains("already exists and is not an empty folder"),
        "{err}"
    );
    let (ok, _, err) = run(&["simulate", "--out", d, "--frames", "3"]);
    assert!(
        !ok && err.contains(
            "--frames, --lidar-sigma-mm, --azimuth-step-deg, --scene: only for --kind sphere-calib"
        ),
        "{err}"
    );
    // frame 2: a second sphere, frame 3's, put into its cloud as one scan would see both:
    // frame 3's sphere points added, and frame 2's points in that sphere's shadow removed
    // (the finder refuses a sphere that beams pass through); frame 4: a black image
    let truth = read_sphere_calib_truth(&data.join("truth.json")).unwrap();
    let c3 = Vector3::from(truth.frames[2].centre_lidar_mm);
    let r = truth.sphere_diameter_mm / 2.0;
    // (lines that are no point, a header, are kept as they are, as points far away)
    let points = |file: &str| -> Vec<(String, Vector3<f64>)> {
        std::fs::read_to_string(data.join(file))
            .unwrap()
            .lines()
            .map(|l| {
                let v: Vec<f64> = l
                    .split_whitespace()
                    .filter_map(|t| t.parse().ok())
                    .collect();
                let p = if v.len() >= 3 {
                    Vector3::new(v[0], v[1], v[2]) * 1000.0
                } else {
                    Vector3::repeat(f64::INFINITY)
                };
                (l.to_string(), p)
            })
            .collect()
    };
    let shadowed = |p: &Vector3<f64>| {
        let d = p.normalize();
        p.iter().all(|v| v.is_finite())
            && d.dot(&c3) > 0.0
            && (c3 - d * d.dot(&c3)).norm() < r
            && p.norm() > d.dot(&c3) - r
    };
    let mut two = String::new();
    for (line, p) in points("clouds/F02.xyz") {
        if !shadowed(&p) {
            two += &line;
            two.push('\n');
        }
    }
    for (line, p) in points("clouds/F03.xyz") {
        if p.iter().all(|v| v.is_finite()) && (p - c3).norm() < r + 50.0 {
            two += &line;
            two.push('\n');
        }
    }
    std::fs::write(data.join("clouds/F02.xyz"), two).unwrap();
    let black = pingcal_targets::GrayImage {
        width: 1280,
        height: 720,
        data: vec![0.0; 1280 * 720],
    };
    pingcal_targets::image_io::to_luma8(&black)
        .save(data.join("images/F04.png"))
        .unwrap();
    let project = data.join("sphere-calib.toml");
    let p = project.to_str().unwrap();
    let (ok, out, err) = run(&["sphere-calib", p]);
    assert!(ok, "{out}{err}");
    assert!(
        out.contains("F02    not used:") && out.contains("2 spheres of 600 mm found, one expected"),
        "{out}"
    );
    assert!(
        out.contains("F04    not used:")
            && out.contains("F04.png: no sphere silhouette where the lidar's sphere is"),
        "{out}"
    );
    let last = out.lines().last().unwrap();
    // the farthest frame (8.5–10 m) may be left out too: one ring on the sphere
    assert!(
        last.contains(": 4 of 6 frames;") || last.contains(": 3 of 6 frames;"),
        "{last}"
    );
    let results = data.join("results/results.json");
    let first = std::fs::read_to_string(&results).unwrap();
    let json: serde_json::Value = serde_json::from_str(&first).unwrap();
    assert_eq!(json["frames"][1]["used"], false);
    assert!(
        json["extrinsic"]["sigma_translation_mm"][0]
            .as_f64()
            .unwrap()
            > 0.0
    );
    assert!(json["closed_form"]["translation_mm"].is_array());
    // an earlier results.json is kept
    let (ok, _, err) = run(&["sphere-calib", p]);
    assert!(!ok);
    assert!(
        err.trim_end().lines().count() == 1 && err.contains("results.json: already exists"),
        "{err}"
    );
    assert_eq!(std::fs::read_to_string(&results).unwrap(), first);
    let (ok, out, err) = run(&["sphere-calib", p, "--overwrite", "--quiet"]);
    assert!(ok && out.lines().count() == 1, "{out}{err}");
    let text = std::fs::read_to_string(&project).unwrap();
    // a camera constant 3 % off (2.52 mm for 2.45): every camera centre 3 % too far,
    // doubtful whatever model error the scatter gives; as calibrate, exit 3 with the results
    // written, 0 with --accept-doubtful
    let camera = data.join("camera.toml");
    let camera_text = std::fs::read_to_string(&camera).unwrap();
    assert!(camera_text.contains("c_mm = 2.45\n"));
    std::fs::write(
        &camera,
        camera_text.replace("c_mm = 2.45\n", "c_mm = 2.52\n"),
    )
    .unwrap();
    let code = |args: &[&str]| {
        let o = std::process::Command::new(exe).args(args).output().unwrap();
        (
            o.status.code(),
            String::from_utf8_lossy(&o.stderr).to_string(),
        )
    };
    let (c, err) = code(&["sphere-calib", p, "--overwrite", "--quiet"]);
    assert_eq!(c, Some(3), "{err}");
    assert!(
        err.contains("pingcal: doubtful: the registration's σ0")
            && err
                .trim_end()
                .ends_with("pingcal: verdict: doubtful; --accept-doubtful exits 0 on doubtful"),
        "{err}"
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&results).unwrap()).unwrap();
    assert_eq!(json["verdict"]["status"], "doubtful");
    assert!(json["sigma0_sensors"].as_f64().unwrap() > 10.0);
    let (c, err) = code(&[
        "sphere-calib",
        p,
        "--overwrite",
        "--quiet",
        "--accept-doubtful",
    ]);
    assert_eq!(c, Some(0), "{err}");
    std::fs::write(&camera, camera_text).unwrap();
    // bad values: one line naming the file
    std::fs::write(
        &project,
        text.replace("sphere_diameter_mm = 600.0", "sphere_diameter_mm = 0.0"),
    )
    .unwrap();
    let (ok, _, err) = run(&["sphere-calib", p, "--overwrite"]);
    assert!(!ok);
    assert_eq!(
        err.trim_end(),
        format!("pingcal: error: {p}: sphere_diameter_mm = 0: expected a positive number of mm")
    );
    std::fs::write(
        &project,
        text.replace("clouds/F05.xyz", "clouds/missing.xyz"),
    )
    .unwrap();
    let (ok, _, err) = run(&["sphere-calib", p, "--overwrite"]);
    assert!(
        !ok && err.trim_end().lines().count() == 1 && err.contains("missing.xyz"),
        "{err}"
    );
    // bad inputs, one line each naming the frame or file and what to do: an image of
    // another size than the camera's, an empty cloud, a camera file in no known form
    let one_line = |edit: &dyn Fn(&str) -> String, expect: &[&str]| {
        std::fs::write(&project, edit(&text)).unwrap();
        let (ok, _, err) = run(&["sphere-calib", p, "--overwrite"]);
        assert!(!ok && err.trim_end().lines().count() == 1, "{err}");
        for e in expect {
            assert!(err.contains(e), "{err}");
        }
    };
    pingcal_targets::image_io::to_luma8(&pingcal_targets::GrayImage {
        width: 640,
        height: 480,
        data: vec![0.0; 640 * 480],
    })
    .save(data.join("images/small.png"))
    .unwrap();
    one_line(
        &|t| t.replace("images/F03.png", "images/small.png"),
        &[
            "small.png: 640 × 480 pixels, but the camera",
            "is 1280 × 720 (frame F03): give the camera file of the camera that took these images",
        ],
    );
    std::fs::write(data.join("clouds/empty.xyz"), "").unwrap();
    one_line(
        &|t| t.replace("clouds/F03.xyz", "clouds/empty.xyz"),
        &[
            "empty.xyz",
            "no points",
            "frame F03's cloud: give its points, or take the frame out of the project",
        ],
    );
    std::fs::write(data.join("camera.json"), "{\"fx\": 1}").unwrap();
    one_line(
        &|t| t.replace("camera = \"camera.toml\"", "camera = \"camera.json\""),
        &["camera.json: not a camera file pingcal reads: expected a camera.toml (model ="],
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// SphereCalib's real example 3, camera 2 (`../shared/data/spherecalib-ex3-cam2`: eight
/// photographs of a shaded exercise ball on a stool in a brick courtyard, eight VLP-16
/// frames): the ball is found in all eight clouds and all eight photographs, and in every
/// frame the lidar's centre, carried into the camera by the extrinsic estimated *without*
/// that frame (leave-one-out), images inside the ball's own fitted circle — what the
/// authors' overlays in `reference/` show. Prints per frame the pixel offset of the lidar
/// centre from the circle's centre (all frames' extrinsic and leave-one-out), σ0 and the
/// extrinsic with its σ.
#[test]
fn spherecalib_example_3_finds_the_ball_in_every_photograph() {
    let project = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data/spherecalib-ex3-cam2/sphere-calib.toml");
    if !project.exists() {
        println!("skipped: {} is absent", project.display());
        return;
    }
    let o = calibrate(&project, 1).unwrap();
    let reg = &o.evaluation.registration;
    assert_eq!(o.frames.len(), 8);
    println!("frame  circle r px  offset px (all)  offset px (leave-one-out)  outline used");
    for f in &o.frames {
        assert!(f.skipped.is_none(), "{}: {:?}", f.id, f.skipped);
        let (l, s) = (f.lidar.as_ref().unwrap(), f.image.as_ref().unwrap());
        let at = |p: &Vector3<f64>| {
            let uv = o.camera.project(p).unwrap();
            (uv.0 - s.image_centre.0).hypot(uv.1 - s.image_centre.1)
        };
        let all = at(&reg.camera_from_lrf.transform(&l.centre));
        let row = o
            .evaluation
            .leave_one_out
            .rows
            .iter()
            .find(|r| r.id == f.id)
            .unwrap();
        let loo = at(&(s.centre + Vector3::new(row.dx_mm, row.dy_mm, row.dz_mm)));
        println!(
            "{:5}  {:11.1}  {:15.1}  {:25.1}  {:11.0} %",
            f.id,
            s.radius_px,
            all,
            loo,
            100.0 * s.coverage
        );
        // on the ball: inside its circle
        assert!(
            loo < s.radius_px,
            "{}: {loo:.1} px from the ball's centre",
            f.id
        );
    }
    // the centres agree to some 100 mm only (a long lens at 5–7 m: about 30 mm of distance
    // per pixel of radius; a ball "around 0.3 m" squashed on a stool; a 16-beam lidar): the
    // sensors' σ's are far too small, so the run is doubtful and every σ is scaled by σ0,
    // after which the leave-one-out errors agree with their σ's
    let k = o.sigma_scale.expect("the σ's scaled");
    assert!(k > 10.0 && k == o.sensor_sigma0 && (reg.sigma0 - 1.0).abs() < 1e-6);
    assert_eq!(
        o.verdict.status,
        pingcal_pipeline::verdict::Status::Doubtful
    );
    let loo = o.verdict.checks.iter().find(|c| c.name == "leave-one-out");
    assert!(loo.is_some_and(|c| c.passed), "{:?}", o.verdict.checks);
    let t = reg.camera_from_lrf.translation;
    println!(
        "σ0 against the sensors' σ's {:.2}; every σ scaled by {k:.2}",
        o.sensor_sigma0
    );
    println!(
        "σ0 {:.2}; t = ({:.1}, {:.1}, {:.1}) ± ({:.1}, {:.1}, {:.1}) mm, ω φ κ σ ({:.3}, {:.3}, {:.3})°; mean leave-one-out error {:.1} mm",
        reg.sigma0,
        t.x,
        t.y,
        t.z,
        reg.sigma_translation_mm.x,
        reg.sigma_translation_mm.y,
        reg.sigma_translation_mm.z,
        reg.sigma_opk_deg.x,
        reg.sigma_opk_deg.y,
        reg.sigma_opk_deg.z,
        o.evaluation.leave_one_out.mean_mm
    );
}

/// Issue 53: sixteen frames of the sphere carried along a shallow arc at one height, every
/// position within 143 mm of the chord through the two ends (under the 150 mm off a line a
/// triple needs to give a rotation): the refusal names the line and the distance and what
/// to do, not a disagreement among the frames.
#[test]
fn frames_along_a_shallow_arc_are_refused_for_their_line() {
    use pingcal_sim::sphere_calib::{write_sphere_calib, SphereCalibSim};
    let cfg = SphereCalibConfig {
        frames: 16,
        ..SphereCalibConfig::default()
    };
    let mut sim = SphereCalibSim::new(&cfg, 3).unwrap();
    // 4 m ahead, 1.5 m to either side, the middle 143 mm farther than the ends
    sim.centres_lidar = (0..16)
        .map(|k| {
            let s = -1.0 + 2.0 * k as f64 / 15.0;
            Vector3::new(4000.0 + 143.0 * (1.0 - s * s), 1500.0 * s, 0.0)
        })
        .collect();
    let dir = std::env::temp_dir().join(format!("pingcal-spherecalib-arc-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    write_sphere_calib(&sim, &dir).unwrap();
    let err = match calibrate(&dir.join("sphere-calib.toml"), 1) {
        Err(e) => e.to_string(),
        Ok(o) => panic!("calibrated: {:?}", o.verdict),
    };
    let _ = std::fs::remove_dir_all(&dir);
    assert!(
        err.contains("the sphere's 16 positions lie within")
            && err.contains("mm of a line")
            && err.contains("move it up and down as well as across")
            && !err.contains("agree"),
        "{err}"
    );
    // the distance is the lidar's centres' (a few mm of fit noise on the 143 mm)
    let mm: f64 = err
        .split("lie within ")
        .nth(1)
        .and_then(|t| t.split(' ').next())
        .and_then(|t| t.parse().ok())
        .unwrap_or_else(|| panic!("{err}"));
    assert!((mm - 143.0).abs() <= 10.0, "{err}");
}

/// Issue 53 on real frames: three of SphereCalib's example 3 (S3, S4, S5), whose lidar
/// centres lie within 8 mm of a line, are refused for the line, not for a disagreement.
#[test]
fn real_frames_on_a_line_are_refused_for_their_line() {
    let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data/spherecalib-ex3-cam2");
    if !data.join("sphere-calib.toml").exists() {
        eprintln!("skipped: {} is absent", data.display());
        return;
    }
    let d = data.canonicalize().unwrap();
    let mut text = format!(
        "version = 1\ncamera = \"{}\"\nsphere_diameter_mm = 600.0\n\n[lidar]\nunit = \"m\"\nnoise = \"VLP-16\"\n",
        d.join("camera.toml").display()
    );
    for s in [3, 4, 5] {
        text += &format!(
            "\n[[frames]]\nid = \"S{s}\"\ncloud = \"{}\"\nimage = \"{}\"\n",
            d.join(format!("clouds/L1_S{s}.xyz")).display(),
            d.join(format!("images/C2_S{s}.png")).display()
        );
    }
    let dir = std::env::temp_dir().join(format!("pingcal-spherecalib-line-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let project = dir.join("line.toml");
    std::fs::write(&project, text).unwrap();
    let err = match calibrate(&project, 1) {
        Err(e) => e.to_string(),
        Ok(o) => panic!("calibrated: {:?}", o.verdict),
    };
    let _ = std::fs::remove_dir_all(&dir);
    assert!(
        err.contains("the sphere's 3 positions lie within 8 mm of a line (the lidar's centres, the line through frames S4 and S5)")
            && err.contains("move it up and down as well as across"),
        "{err}"
    );
}
