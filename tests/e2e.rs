//! End-to-end tests of the `pingcal` binary (issue 7, "Must show"): a simulated project is
//! calibrated and compared with the simulator's truth, and broken copies of it must fail
//! with one clear `pingcal: error: ` line, no panic and no output files.
//!
//! `pingcal simulate --seed 3` runs once per test binary ([`common::pristine`]); every test
//! works on its own copy under `$TMP/pingcal-e2e-<pid>/<test>`, removed when it passes.

use crate::common;

mod fixed_lrf;
mod observation_group;
mod rig;
mod rig_check;

use common::{
    read_json, replace_once, two_step_method, Work, LRF_AS_STATED, OUTPUTS, QUARTER_BEAMS,
};
use serde_json::Value;
use std::fs;
use std::path::{Path, PathBuf};

/// A path argument.
fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 temp path")
}

/// A number of a JSON value, with the key path in the failure message.
fn num(v: &Value, what: &str) -> f64 {
    let x = v
        .as_f64()
        .unwrap_or_else(|| panic!("{what} is not a number: {v}"));
    assert!(x.is_finite(), "{what} = {x} is not finite");
    x
}

/// A 3-vector of a JSON value.
fn vec3(v: &Value, what: &str) -> [f64; 3] {
    let a = v
        .as_array()
        .unwrap_or_else(|| panic!("{what} is not an array: {v}"));
    assert_eq!(a.len(), 3, "{what} has {} elements, not 3", a.len());
    [0, 1, 2].map(|i| num(&a[i], &format!("{what}[{i}]")))
}

/// A 3×3 matrix (rows) of a JSON value.
fn mat3(v: &Value, what: &str) -> [[f64; 3]; 3] {
    let a = v
        .as_array()
        .unwrap_or_else(|| panic!("{what} is not an array: {v}"));
    assert_eq!(a.len(), 3, "{what} has {} rows, not 3", a.len());
    [0, 1, 2].map(|i| vec3(&a[i], &format!("{what}[{i}]")))
}

/// Angle of the rotation a·bᵀ, in degrees (atan2 form: accurate for small angles).
fn angle_between_deg(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> f64 {
    let d = |i: usize, j: usize| (0..3).map(|k| a[i][k] * b[j][k]).sum::<f64>();
    let cos2 = d(0, 0) + d(1, 1) + d(2, 2) - 1.0; // 2 cos θ
    let axis = [d(2, 1) - d(1, 2), d(0, 2) - d(2, 0), d(1, 0) - d(0, 1)]; // 2 sin θ · n
    let sin2 = axis.iter().map(|x| x * x).sum::<f64>().sqrt();
    sin2.atan2(cos2).to_degrees()
}

/// The pristine simulated project calibrates, and its results agree with the simulator's
/// truth within the precision the results claim.
#[test]
fn calibrate_simulated_project() {
    let w = Work::new("calibrate_simulated_project");
    let common::Calibration {
        project: p,
        out,
        run,
    } = common::calibration();
    let (p, out) = (p.as_path(), out.as_path());
    let ctx = format!(
        "exit {:?}\nstdout: {}\nstderr: {}",
        run.code, run.stdout, run.stderr
    );
    assert!(run.success(), "calibrate failed: {ctx}");
    assert!(!run.stderr.contains("panicked"), "{ctx}");
    eprintln!("calibrate: {:.1} s", run.secs);

    // stdout: one JSON line
    let lines: Vec<&str> = run
        .stdout
        .lines()
        .filter(|l| !l.trim().is_empty())
        .collect();
    assert_eq!(lines.len(), 1, "--json prints one line per project: {ctx}");
    let summary: Value = serde_json::from_str(lines[0]).expect("the stdout line is JSON");
    assert_eq!(summary["ok"], Value::Bool(true), "{ctx}");
    assert_eq!(summary["out"].as_str(), Some(s(out)), "{ctx}");
    for f in OUTPUTS {
        assert!(out.join(f).is_file(), "no {f} in {}", out.display());
    }

    let r = read_json(&out.join("results.json"));
    let truth = read_json(&p.join("truth.json"));
    let project_text = fs::read_to_string(p.join("project.toml")).unwrap();

    // --- the extrinsic: a proper rotation, σ's, and the truth within them ---
    let ext = &r["extrinsic"];
    let rot = mat3(&ext["rotation"], "extrinsic.rotation");
    for i in 0..3 {
        for j in 0..3 {
            let dot: f64 = (0..3).map(|k| rot[k][i] * rot[k][j]).sum();
            let want = if i == j { 1.0 } else { 0.0 };
            assert!(
                (dot - want).abs() < 1e-9,
                "extrinsic.rotation is not orthonormal: (RᵀR)[{i}][{j}] = {dot}"
            );
        }
    }
    let det = rot[0][0] * (rot[1][1] * rot[2][2] - rot[1][2] * rot[2][1])
        - rot[0][1] * (rot[1][0] * rot[2][2] - rot[1][2] * rot[2][0])
        + rot[0][2] * (rot[1][0] * rot[2][1] - rot[1][1] * rot[2][0]);
    assert!((det - 1.0).abs() < 1e-9, "det(extrinsic.rotation) = {det}");
    let t = vec3(&ext["translation_mm"], "extrinsic.translation_mm");
    let sig_t = vec3(
        &ext["sigma_translation_mm"],
        "extrinsic.sigma_translation_mm",
    );
    let sig_r = vec3(&ext["sigma_rotation_deg"], "extrinsic.sigma_rotation_deg");
    for (i, s) in sig_t.iter().chain(&sig_r).enumerate() {
        assert!(*s > 0.0, "σ {i} of the extrinsic is {s}: expected positive");
    }

    // the top-level extrinsic is the joint adjustment's (the simulator writes method =
    // "all"), and the paper's two steps ran beside it
    let methods = r["methods"].as_array().expect("results.methods");
    let find = |name: &str| {
        methods
            .iter()
            .find(|m| m["method"] == name)
            .unwrap_or_else(|| panic!("the {name} method ran (method = \"all\")"))
    };
    let (joint, spheres) = (find("joint"), find("spheres"));
    assert_eq!(joint["error"], Value::Null, "joint adjustment: {joint}");
    assert_eq!(spheres["error"], Value::Null, "sphere method: {spheres}");
    assert_eq!(
        vec3(&joint["extrinsic"]["translation_mm"], "joint translation"),
        t,
        "the top-level extrinsic is not the joint adjustment's"
    );
    let mount = r["lrf_mount"].as_array().expect("results.lrf_mount");
    assert_eq!(mount.len(), 8, "{mount:?}");
    let offset_y = mount
        .iter()
        .find(|m| m["name"] == "offset_y")
        .expect("offset_y");
    assert!(
        offset_y["held"]
            .as_str()
            .is_some_and(|h| h.contains("origin")),
        "offset_y is the frame's origin, never estimated: {offset_y}"
    );
    for m in mount.iter().filter(|m| m["held"].is_null()) {
        let s = m["sigma"].as_f64().expect("an estimated parameter has a σ");
        assert!(s > 0.0 && s.is_finite(), "{m}");
    }

    let true_rot = mat3(&truth["extrinsic"]["rotation"], "truth.extrinsic.rotation");
    let true_t = vec3(
        &truth["extrinsic"]["translation_mm"],
        "truth.extrinsic.translation_mm",
    );
    // in the frame the calibration defines: origin on the servo axis at the scan plane
    // (`pingcal_sim::Truth::extrinsic_as_calibrated`)
    let offset_y = truth["lrf_mount"]["offset_mm"][1].as_f64().unwrap_or(0.0);
    let true_t: [f64; 3] = std::array::from_fn(|k| true_t[k] + true_rot[k][1] * offset_y);
    // Each component within 5σ + 0.5 mm: if the reported σ is honest, a 5σ deviation of a
    // normal error happens about once in 1.7 million, so this does not fail by chance; the
    // 0.5 mm floor covers the error of the photogrammetric frame itself (datum of the main
    // image, scale from five distances of σ 0.1 mm), which the extrinsic's σ does not hold.
    for i in 0..3 {
        let err = t[i] - true_t[i];
        let bound = 5.0 * sig_t[i] + 0.5;
        eprintln!(
            "translation[{i}]: {:.3} mm, true {:.3}, error {err:+.3} mm, σ {:.3}, bound {bound:.3}",
            t[i], true_t[i], sig_t[i]
        );
        assert!(
            err.abs() < bound,
            "translation[{i}] = {} mm, truth {} mm: error {err} mm exceeds 5σ + 0.5 = {bound} mm",
            t[i],
            true_t[i]
        );
    }
    // The same reasoning for the rotation: 5 times the largest angle σ, plus 0.02° for the
    // frame's own orientation error.
    let ang = angle_between_deg(&rot, &true_rot);
    let max_sig_r = sig_r.iter().cloned().fold(0.0, f64::max);
    let bound = 5.0 * max_sig_r + 0.02;
    eprintln!("rotation error {ang:.4}°, max σ {max_sig_r:.4}°, bound {bound:.4}°");
    assert!(
        ang < bound,
        "rotation error {ang}° exceeds 5·max σ + 0.02° = {bound}°"
    );

    // --- check points ---
    let checks = r["check_points"].as_array().expect("results.check_points");
    assert!(!checks.is_empty(), "no check points");
    let mut sum = 0.0;
    let mut ids = Vec::new();
    for (k, c) in checks.iter().enumerate() {
        let id = c["id"]
            .as_str()
            .unwrap_or_else(|| panic!("check_points[{k}].id is not a string: {c}"));
        let [dx, dy, dz, e] =
            ["dx_mm", "dy_mm", "dz_mm", "error_mm"].map(|f| num(&c[f], &format!("{id}.{f}")));
        let norm = (dx * dx + dy * dy + dz * dz).sqrt();
        assert!(
            (e - norm).abs() < 1e-9 * (1.0 + norm),
            "{id}: error_mm = {e}, |(dx, dy, dz)| = {norm}"
        );
        sum += e;
        ids.push(id.to_string());
    }
    let mean = num(&r["mean_check_error_mm"], "mean_check_error_mm");
    assert!(
        (mean - sum / checks.len() as f64).abs() < 1e-9,
        "mean_check_error_mm = {mean}, mean of check_points = {}",
        sum / checks.len() as f64
    );
    // the project names its check balls; those are the ones judged
    for id in &ids {
        assert!(
            project_text.contains(&format!("\"{id}\"")),
            "check point {id} is not a ball of project.toml"
        );
    }

    one_lrf_model(&w, p, out, &r);
    overlays_put_the_balls_on_their_images(p, out, &r);
    export_losses_are_the_same_in_the_files_and_the_report(out);

    // --- bundle ---
    let b = &r["bundle"];
    let sigma0 = num(&b["sigma0"], "bundle.sigma0");
    let rms = num(&b["rms_image_px"], "bundle.rms_image_px");
    assert!(sigma0 > 0.0 && rms > 0.0, "bundle: {b}");
    let n_images = project_text.matches("[[images]]").count() as u64;
    assert_eq!(b["images"].as_u64(), Some(n_images), "bundle.images: {b}");
    assert!(b["points"].as_u64().unwrap_or(0) > 0, "bundle.points: {b}");
    assert!(
        b["iterations"].as_u64().unwrap_or(0) > 0,
        "bundle.iterations: {b}"
    );

    // --- cameras: every SPEC key, and c against the truth ---
    let cams = r["cameras"].as_array().expect("results.cameras");
    let true_cams = truth["cameras"].as_array().expect("truth.cameras");
    assert_eq!(cams.len(), true_cams.len(), "number of cameras");
    for tc in true_cams {
        let id = tc["id"].as_str().expect("truth camera id");
        let c = cams
            .iter()
            .find(|c| c["id"] == id)
            .unwrap_or_else(|| panic!("camera {id} is not in results.json"));
        for k in [
            "c_mm", "xp_mm", "yp_mm", "k1", "k2", "k3", "p1", "p2", "b1", "b2",
        ] {
            num(&c[k], &format!("cameras[{id}].{k}"));
        }
        let (est, tru) = (num(&c["c_mm"], "c_mm"), num(&tc["c_mm"], "truth c_mm"));
        eprintln!("camera {id}: c = {est:.5} mm, true {tru:.5} mm");
        assert!(
            (est - tru).abs() < 0.005,
            "camera {id}: c = {est} mm, truth {tru} mm"
        );
    }

    // --- report and cloud ---
    let html = fs::read_to_string(out.join("report.html")).expect("report.html");
    assert!(
        html.starts_with("<!DOCTYPE html>"),
        "report.html starts with {:?}",
        &html[..html.len().min(40)]
    );
    for id in &ids {
        assert!(html.contains(id.as_str()), "report.html does not name {id}");
    }
    let ply = fs::read(out.join("cloud.ply")).expect("cloud.ply");
    assert!(ply.starts_with(b"ply\n"), "cloud.ply is not a PLY file");

    // --- the report in a real browser (headless Chromium), when the machine has one ---
    if std::path::Path::new("/usr/bin/chromium").exists() {
        let script = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../report/scripts/check-report.sh"
        );
        let png = w.dir.join("report.png");
        let st = std::process::Command::new("bash")
            .arg(script)
            .arg(out.join("report.html"))
            .arg(&png)
            .arg("100000")
            .status()
            .expect("run check-report.sh");
        assert!(
            st.success(),
            "headless Chromium could not render report.html"
        );
    } else {
        println!("skipped the browser check: /usr/bin/chromium not installed");
    }
}

/// χ² with 3 degrees of freedom at 1 − 0.0027 (the probability of a normal deviate beyond
/// 3σ): a ball's `Σ (dᵢ/σᵢ)²` above it is a 3σ event.
const CHI2_3_AT_3_SIGMA: f64 = 14.16;

/// Issue 33's "one truth": after the joint adjustment every ball has an LRF centre through
/// the estimated model (`lrf_model`), `R · lrf_mm + t` lands on the camera-side centre
/// within 3σ of the predicted error and 6 mm, the check rows are those residuals, and
/// `pingcal cloud --lrf-model results.json` on the project's scans gives the same cloud and
/// the same spheres.
fn one_lrf_model(w: &Work, p: &Path, out: &Path, r: &Value) {
    let lrf_centres = balls_on_their_lrf_centres(r, f64::INFINITY);
    let balls = r["balls"].as_array().expect("results.balls");
    let html = fs::read_to_string(out.join("report.html")).expect("report.html");
    let n = balls.len();
    assert!(
        html.contains(&format!("{n} / {n} / {n}")),
        "the report's summary does not count {n} balls, {n} LRF centres and {n} matched"
    );
    cloud_of_the_lrf_model(w, p, out, &lrf_centres);
}

/// Every ball of `r` has an LRF centre through the joint adjustment's model, its
/// `residual_mm` is `R · lrf_mm + t − photogrammetric_mm`, within 3σ of its predicted σ and
/// at most `max_mm`, and a check ball's check row is that residual. Returns the LRF centres.
fn balls_on_their_lrf_centres(r: &Value, max_mm: f64) -> Vec<[f64; 3]> {
    assert_eq!(
        r["lrf_model"]["source"], "joint adjustment",
        "{}",
        r["lrf_model"]
    );
    let rot = mat3(&r["extrinsic"]["rotation"], "extrinsic.rotation");
    let t = vec3(
        &r["extrinsic"]["translation_mm"],
        "extrinsic.translation_mm",
    );
    let balls = r["balls"].as_array().expect("results.balls");
    let mut lrf_centres = Vec::new();
    for b in balls {
        let id = b["id"].as_str().expect("ball id");
        let l = vec3(&b["lrf_mm"], &format!("{id}.lrf_mm (every ball has one)"));
        let c = vec3(&b["photogrammetric_mm"], "photogrammetric_mm");
        let (res, sig) = (
            vec3(&b["residual_mm"], "residual_mm"),
            vec3(&b["residual_sigma_mm"], "residual_sigma_mm"),
        );
        let d: [f64; 3] =
            std::array::from_fn(|i| (0..3).map(|k| rot[i][k] * l[k]).sum::<f64>() + t[i] - c[i]);
        let chi2: f64 = (0..3).map(|i| (d[i] / sig[i]).powi(2)).sum();
        let norm = d.iter().map(|v| v * v).sum::<f64>().sqrt();
        eprintln!("{id}: |R l + t − c| = {norm:.2} mm, Σ(d/σ)² = {chi2:.2}");
        close3(
            d,
            res,
            1e-9,
            &format!("{id}: residual_mm against R · lrf_mm + t − c"),
        );
        assert!(
            chi2 < CHI2_3_AT_3_SIGMA && norm <= max_mm,
            "{id}: R · lrf_mm + t is {norm:.2} mm from the camera-side centre, Σ(d/σ)² = {chi2:.2} (σ {sig:?})"
        );
        if let Some(row) = (r["check_points"].as_array().unwrap().iter()).find(|c| c["id"] == id) {
            let dx = ["dx_mm", "dy_mm", "dz_mm"].map(|k| num(&row[k], k));
            close3(dx, d, 1e-9, &format!("{id}: the check row against balls[]"));
        }
        lrf_centres.push(l);
    }
    lrf_centres
}

/// `pingcal cloud --lrf-model results.json` on the project's scans gives `cloud.ply`'s
/// points and spheres at `lrf_centres`.
fn cloud_of_the_lrf_model(w: &Work, p: &Path, out: &Path, lrf_centres: &[[f64; 3]]) {
    let scans: Vec<PathBuf> = fs::read_dir(p.join("scans"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|f| f.extension().is_some_and(|x| x == "csv"))
        .collect();
    assert_eq!(scans.len(), 1, "the simulated project has one scan file");
    let (ply, centres) = (w.dir.join("again.ply"), w.dir.join("again.txt"));
    let run = w.run(&[
        "cloud",
        s(&scans[0]),
        "--lrf-model",
        s(&out.join("results.json")),
        "--out",
        s(&ply),
        "--balls",
        s(&centres),
    ]);
    assert!(run.success(), "pingcal cloud --lrf-model: {}", run.stderr);
    let vertices = |f: &Path| {
        let b = fs::read(f).unwrap();
        let end = b.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
        b[end..].to_vec()
    };
    assert!(
        vertices(&ply) == vertices(&out.join("cloud.ply")),
        "cloud.ply is not the cloud of its own lrf_model"
    );
    let again: Vec<[f64; 3]> = (fs::read_to_string(&centres).unwrap().lines())
        .filter(|l| !l.starts_with('#'))
        .map(|l| {
            let v: Vec<f64> = l
                .split_whitespace()
                .skip(1)
                .map(|x| x.parse().unwrap())
                .collect();
            [v[0], v[1], v[2]]
        })
        .collect();
    for l in lrf_centres {
        let nearest = (again.iter())
            .map(|a| (0..3).map(|k| (a[k] - l[k]).powi(2)).sum::<f64>().sqrt())
            .fold(f64::INFINITY, f64::min);
        // the centres file has three decimals: a rounding of at most 0.0005 mm per axis
        assert!(
            nearest < 0.001,
            "lrf_mm {l:?}: nearest sphere of `pingcal cloud --lrf-model` at {nearest} mm"
        );
    }
}

/// The LRF drawn on the images: `overlays/` holds one PNG per image at the image's size,
/// the report shows them, and on the main image every ball with an LRF centre has its
/// LRF points (drawn in the ball colour) inside the silhouette where the camera sees it:
/// the ball's photogrammetric centre projected with the main camera's OpenCV model, of
/// radius `f · r / depth` (plus 2 px for the discs' size and the extrinsic's error).
fn overlays_put_the_balls_on_their_images(p: &Path, out: &Path, r: &Value) {
    let images = fs::read_dir(p.join("images")).expect("images/").count();
    let dir = out.join("overlays");
    let drawn: Vec<PathBuf> = fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(drawn.len(), images, "one overlay per image");
    let html = fs::read_to_string(out.join("report.html")).expect("report.html");
    assert_eq!(
        html.matches("<img src=\"data:image/png;base64,").count(),
        images
    );
    let cam = r["cameras"]
        .as_array()
        .and_then(|c| {
            c.iter()
                .find(|c| c["id"] == r["conventions"]["main_camera"])
        })
        .expect("the main camera in results.cameras");
    let o = &cam["opencv"];
    let k = ["fx", "fy", "cx", "cy"].map(|n| num(&o[n], n));
    let d: Vec<f64> = (0..5).map(|i| num(&o["dist"][i], "dist")).collect();
    let stem = format!("{}_{}", station_of_main(p), cam["id"].as_str().unwrap());
    let png = fs::read(dir.join(format!("{stem}.png"))).expect("the main image's overlay");
    let mut dec = png::Decoder::new(std::io::Cursor::new(png))
        .read_info()
        .unwrap();
    let mut px = vec![0; dec.output_buffer_size().unwrap()];
    let info = dec.next_frame(&mut px).unwrap();
    let (w, h) = (info.width as i64, info.height as i64);
    assert_eq!(
        [w, h],
        [
            o["image_width"].as_i64().unwrap(),
            o["image_height"].as_i64().unwrap()
        ]
    );
    let magenta = |x: i64, y: i64| {
        let i = 3 * (y * w + x) as usize;
        (0..w).contains(&x)
            && (0..h).contains(&y)
            && px[i..i + 3] == pingcal_report::overlay::BALL_RGB
    };
    let radius = 0.5 * project_number(p, "diameter_mm");
    let mut checked = 0;
    for b in r["balls"].as_array().unwrap() {
        if b["lrf_mm"].is_null() {
            continue;
        }
        let [x, y, z] = vec3(&b["photogrammetric_mm"], "photogrammetric_mm");
        let (xn, yn) = (x / y, -z / y);
        let r2 = xn * xn + yn * yn;
        let rad = 1.0 + d[0] * r2 + d[1] * r2 * r2 + d[4] * r2 * r2 * r2;
        let xd = xn * rad + 2.0 * d[2] * xn * yn + d[3] * (r2 + 2.0 * xn * xn);
        let yd = yn * rad + d[2] * (r2 + 2.0 * yn * yn) + 2.0 * d[3] * xn * yn;
        let (u, v) = (k[0] * xd + k[2], k[1] * yd + k[3]);
        let rim = k[0] * radius / y + 2.0;
        if u < rim || v < rim || u > (w as f64) - rim || v > (h as f64) - rim {
            continue;
        }
        let n = (-(rim as i64)..=rim as i64)
            .flat_map(|dy| (-(rim as i64)..=rim as i64).map(move |dx| (dx, dy)))
            .filter(|&(dx, dy)| ((dx * dx + dy * dy) as f64) <= rim * rim)
            .filter(|&(dx, dy)| magenta(u.round() as i64 + dx, v.round() as i64 + dy))
            .count();
        assert!(
            n >= 5,
            "ball {}: {n} LRF pixels within {rim:.1} px of its image ({u:.1}, {v:.1})",
            b["id"]
        );
        checked += 1;
    }
    assert!(
        checked >= 3,
        "only {checked} balls with LRF centres in the main image"
    );
}

/// The number of the first `key = number` line of project `p`'s project.toml.
fn project_number(p: &Path, key: &str) -> f64 {
    let text = fs::read_to_string(p.join("project.toml")).unwrap();
    let line = text
        .lines()
        .find(|l| l.trim_start().starts_with(&format!("{key} =")))
        .unwrap_or_else(|| panic!("no {key} in project.toml"));
    let v = line.split('=').nth(1).unwrap().split('#').next().unwrap();
    v.trim().parse().unwrap_or_else(|e| panic!("{line}: {e}"))
}

/// The losses the export files state (`largest X px, RMS Y px` in their comments) are the
/// report's (to its 3 decimals): Kalibr's camchain (cam0, cam1 in order) and each camera's
/// camera_info.
fn export_losses_are_the_same_in_the_files_and_the_report(out: &Path) {
    // the report rounds to 3 decimals, the files to 4: half of each, and a hair for the
    // binary representation of the decimals
    const ROUNDED: f64 = 0.0005 + 0.00005 + 1e-12;
    let stated = |text: &str| -> Vec<(f64, f64)> {
        text.match_indices("largest ")
            .map(|(k, _)| {
                let mut w = text[k..].split_whitespace();
                let max: f64 = w.nth(1).unwrap().parse().unwrap();
                let rms: f64 = w.nth(2).unwrap().parse().unwrap();
                (max, rms)
            })
            .collect()
    };
    let html = fs::read_to_string(out.join("report.html")).unwrap();
    let row = |cam: &str, files: &str| -> (f64, f64) {
        let key = format!("<td class=\"l\">{cam}</td><td class=\"l\">{files}</td>");
        let at = html
            .find(&key)
            .unwrap_or_else(|| panic!("no loss row {key}"));
        let cells: Vec<f64> = html[at..]
            .split("</tr>")
            .next()
            .unwrap()
            .split("<td>")
            .skip(1)
            .map(|c| c.trim_end_matches("</td>").parse().unwrap())
            .collect();
        (cells[0], cells[1])
    };
    let kalibr = stated(&fs::read_to_string(out.join("kalibr/camchain.yaml")).unwrap());
    assert_eq!(kalibr.len(), 2, "{kalibr:?}");
    for (cam, (max, rms)) in ["left", "right"].iter().zip(&kalibr) {
        let (rmax, rrms) = row(cam, "kalibr/camchain.yaml");
        assert!(
            (rmax - max).abs() <= ROUNDED && (rrms - rms).abs() <= ROUNDED,
            "{cam}: camchain states {max} / {rms} px, the report {rmax} / {rrms}"
        );
        let info = fs::read_to_string(out.join(format!("ros/camera_info_{cam}.yaml"))).unwrap();
        let (max, rms) = stated(&info)[0];
        let files = format!("opencv/camera_{cam}.yaml, ros/camera_info_{cam}.yaml");
        let (rmax, rrms) = row(cam, &files);
        assert!(
            (rmax - max).abs() <= ROUNDED && (rrms - rms).abs() <= ROUNDED,
            "{cam}: camera_info states {max} / {rms} px, the report {rmax} / {rrms}"
        );
    }
}

/// The main station of project `p` (its `main_station = "…"` line).
fn station_of_main(p: &Path) -> String {
    let text = fs::read_to_string(p.join("project.toml")).unwrap();
    let line = text
        .lines()
        .find(|l| l.trim_start().starts_with("main_station"))
        .expect("main_station in project.toml");
    line.split('"')
        .nth(1)
        .expect("a quoted station")
        .to_string()
}

#[test]
fn missing_image() {
    let w = Work::new("missing_image");
    let p = w.project("project");
    fs::remove_file(p.join("images/S03_left.png")).unwrap();
    w.calibrate_fails(&p, "input", &["S03_left.png"]);
}

/// An intersection angle that leaves the network without targets: the images it could not
/// orient say why, naming the key (issue 17).
#[test]
fn an_intersection_angle_that_refuses_every_target_is_named() {
    let w = Work::new("intersection_angle");
    let p = w.project("project");
    let toml = p.join("project.toml");
    let mut text = fs::read_to_string(&toml).unwrap();
    text.push_str("\n[network]\nmin_intersection_angle_deg = 89.0\n");
    fs::write(&toml, text).unwrap();
    w.calibrate_fails(
        &p,
        "data",
        &[
            "left out of the network",
            "under 89°",
            "min_intersection_angle_deg",
        ],
    );
}

/// A missing scan: named.
#[test]
fn missing_scan() {
    let w = Work::new("missing_scan");
    let p = w.project("project");
    fs::remove_file(p.join("scans/S00.csv")).unwrap();
    w.calibrate_fails(&p, "input", &["S00.csv"]);
}

/// An image of the wrong size for its camera: both sizes and the image named.
#[test]
fn image_of_the_wrong_size() {
    let w = Work::new("image_of_the_wrong_size");
    let p = w.project("project");
    fs::write(p.join("images/S02_right.png"), common::gray_png(640, 480)).unwrap();
    // the detect step prints sizes as W×H (crates/pipeline/src/detect.rs)
    w.calibrate_fails(&p, "input", &["S02_right.png", "640×480", "1280×720"]);
}

/// A truncated image: named, no panic.
#[test]
fn corrupt_image() {
    let w = Work::new("corrupt_image");
    let p = w.project("project");
    let f = p.join("images/S04_left.png");
    let bytes = fs::read(&f).unwrap();
    fs::write(&f, &bytes[..5000]).unwrap();
    w.calibrate_fails(&p, "input", &["S04_left.png"]);
}

/// A scan line that is not numbers: the file and the line named.
#[test]
fn malformed_scan_line() {
    let w = Work::new("malformed_scan_line");
    let p = w.project("project");
    let f = p.join("scans/S00.csv");
    let text = fs::read_to_string(&f).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    // line 100 (1-based) is a scan: stamp, servo angle, ranges
    let (stamp, rest) = lines[99].split_once(',').expect("a scan line");
    let (_servo, ranges) = rest.split_once(',').expect("a scan line");
    lines[99] = format!("{stamp},forty-five,{ranges}");
    fs::write(&f, lines.join("\n") + "\n").unwrap();
    w.calibrate_fails(&p, "input", &["S00.csv", "100"]);
}

/// A distance to a target no image shows: the calibration still finishes (the other distances
/// fix the scale) and warns naming the entry and the target.
#[test]
fn distance_to_an_unseen_target() {
    let w = Work::new("distance_to_an_unseen_target");
    let p = w.quick_project("project");
    let toml = p.join("project.toml");
    let mut text = fs::read_to_string(&toml).unwrap();
    let k = text.matches("[[distances]]").count();
    assert!(k >= 1, "the simulated project has distances");
    // `[[distances]]` after `[lrf]` is valid TOML: one more element of the array of tables.
    // From 8 (an end of a simulated distance, so seen) to 999 (not in the test field).
    text.push_str("\n[[distances]]\nfrom = 8\nto = 999\ndistance_mm = 500.0\nsigma_mm = 0.1\n");
    fs::write(&toml, text).unwrap();
    let out = w.dir.join("out");
    let run = w.run(&["calibrate", s(&toml), "--out", s(&out)]);
    let ctx = format!(
        "exit {:?}\nstdout: {}\nstderr: {}",
        run.code, run.stdout, run.stderr
    );
    assert!(run.success(), "calibrate failed: {ctx}");
    let warning =
        format!("warning: distances[{k}] (8 – 999) not used: coded target 999 was not identified");
    assert!(run.stderr.contains(&warning), "no '{warning}': {ctx}");
    assert_eq!(
        run.stderr.matches("not used: coded target").count(),
        1,
        "only the unseen distance is left out: {ctx}"
    );
    let report = fs::read_to_string(out.join("report.html")).unwrap();
    assert!(
        report.contains("not used: coded target 999 was not identified"),
        "the report's warnings do not name the unused distance"
    );
}

/// Every distance names a target no image shows: nothing fixes the scale, the run stops
/// naming them.
#[test]
fn no_distance_left_to_fix_the_scale() {
    let w = Work::new("no_distance_left_to_fix_the_scale");
    let p = w.project("project");
    let toml = p.join("project.toml");
    let text = fs::read_to_string(&toml).unwrap();
    let cut = text.find("[[distances]]").expect("distances");
    let (before, after) = text.split_at(cut);
    // the simulated distances are gone (each table ends at a blank line or the next table)
    let rest: String = after
        .split("\n[")
        .skip(1)
        .filter(|t| !t.starts_with("[distances]]"))
        .map(|t| format!("\n[{t}"))
        .collect();
    let text = format!(
        "{before}{}\n[[distances]]\nfrom = 998\nto = 999\ndistance_mm = 500.0\nsigma_mm = 0.1\n",
        rest.trim_start()
    );
    fs::write(&toml, text).unwrap();
    let err = w.calibrate_fails(&p, "data", &["998", "999", "scale"]);
    eprintln!("{err}");
}

/// A scan that shows no ball (only its first 30 lines are kept): "at least 3" balls asked.
#[test]
fn fewer_than_three_balls_seen_by_both_sensors() {
    let w = Work::new("fewer_than_three_balls");
    let p = w.project("project");
    let f = p.join("scans/S00.csv");
    let text = fs::read_to_string(&f).unwrap();
    let head: Vec<&str> = text.lines().take(36).collect(); // 6 header lines + 30 scans
    assert!(head[35].split(',').count() > 100, "line 36 is a scan");
    fs::write(&f, head.join("\n") + "\n").unwrap();
    let err = w.calibrate_fails(&p, "data", &["balls", "at least 3", "S00.csv"]);
    eprintln!("{err}");
}

/// A main station with no image: named (the LRF station moves with it, or the
/// LRF-station check would answer first).
#[test]
fn main_station_not_in_the_images() {
    let w = Work::new("main_station_not_in_the_images");
    let p = w.project("project");
    let toml = p.join("project.toml");
    replace_once(&toml, "main_station = \"S00\"", "main_station = \"S99\"");
    let text = fs::read_to_string(&toml).unwrap();
    let lrf = text.find("\n[lrf]\n").expect("an [lrf] table");
    let (before, after) = text.split_at(lrf);
    assert_eq!(after.matches("station = \"S00\"").count(), 1);
    fs::write(
        &toml,
        format!(
            "{before}{}",
            after.replace("station = \"S00\"", "station = \"S99\"")
        ),
    )
    .unwrap();
    w.calibrate_fails(&p, "input", &["S99", "main_station"]);
}

/// A value of the wrong type in project.toml: the file and the line named.
#[test]
fn project_file_syntax_error() {
    let w = Work::new("project_file_syntax_error");
    let p = w.project("project");
    let toml = p.join("project.toml");
    let text = fs::read_to_string(&toml).unwrap();
    let line = 1 + text
        .lines()
        .position(|l| l == "width = 1280")
        .expect("a camera width");
    fs::write(&toml, text.replacen("width = 1280", "width = \"wide\"", 1)).unwrap();
    w.calibrate_fails(&p, "input", &["project.toml", &format!("line {line}")]);
}

/// Two projects in one run, one broken: the good one is written, the bad one reported,
/// one JSON line each, and the exit code says that something failed.
#[test]
fn batch_with_one_bad_project() {
    let w = Work::new("batch_with_one_bad_project");
    let good = w.quick_project("good");
    let bad = w.quick_project("bad");
    fs::remove_file(bad.join("images/S03_left.png")).unwrap();
    let run = w.run(&[
        "calibrate",
        s(&good.join("project.toml")),
        s(&bad.join("project.toml")),
        "--json",
    ]);
    let ctx = format!(
        "exit {:?}\nstdout: {}\nstderr: {}",
        run.code, run.stdout, run.stderr
    );
    assert!(
        !run.success() && run.code.is_some(),
        "one project failed: expected a non-zero exit: {ctx}"
    );
    assert!(!run.stderr.contains("panicked"), "{ctx}");
    for l in run.stderr.lines().filter(|l| !l.trim().is_empty()) {
        assert!(
            l.starts_with("pingcal: error: "),
            "stderr line {l:?}: {ctx}"
        );
    }
    let lines = run.json_lines();
    assert_eq!(lines.len(), 2, "one JSON line per project: {ctx}");
    let find = |dir: &Path| {
        let name = s(&dir.join("project.toml")).to_string();
        lines
            .iter()
            .find(|l| l["project"].as_str() == Some(name.as_str()))
            .unwrap_or_else(|| panic!("no JSON line for {name}: {ctx}"))
    };
    let g = find(&good);
    assert_eq!(g["ok"], Value::Bool(true), "{g}");
    let b = find(&bad);
    assert_eq!(b["ok"], Value::Bool(false), "{b}");
    let e = b["error"].as_str().expect("the bad project's error");
    assert!(e.contains("S03_left.png"), "error {e:?}");
    // without --out each project writes into results/ beside its project file
    for f in OUTPUTS {
        assert!(good.join("results").join(f).is_file(), "good: no {f}");
        assert!(!bad.join("results").join(f).exists(), "bad: {f} written");
    }
    read_json(&good.join("results/results.json"));
}

/// ω, φ, κ (degrees) of a rotation in pingcal's one convention, written out here from the
/// convention's definition (passive factors, `R = R_ω R_φ R_κ`: R₀₂ = −sin φ,
/// R₁₂ = sin ω cos φ, R₂₂ = cos ω cos φ, R₀₁ = cos φ sin κ, R₀₀ = cos φ cos κ), not taken
/// from the code under test.
fn opk_of(r: &[[f64; 3]; 3]) -> [f64; 3] {
    [
        r[1][2].atan2(r[2][2]).to_degrees(),
        (-r[0][2]).asin().to_degrees(),
        r[0][1].atan2(r[0][0]).to_degrees(),
    ]
}

/// The three numbers of the first `(a, b, c)` after `key` in `text`.
fn triple_after(text: &str, key: &str) -> [f64; 3] {
    let at = text
        .find(key)
        .unwrap_or_else(|| panic!("no '{key}' in:\n{text}"));
    let rest = &text[at + key.len()..];
    let open = rest.find('(').expect("a '(' after the key");
    let close = open + rest[open..].find(')').expect("a ')'");
    let v: Vec<f64> = rest[open + 1..close]
        .split(',')
        .map(|x| {
            x.trim()
                .parse()
                .unwrap_or_else(|_| panic!("not a number in {rest}"))
        })
        .collect();
    [v[0], v[1], v[2]]
}

fn close3(a: [f64; 3], b: [f64; 3], tol: f64, what: &str) {
    for k in 0..3 {
        assert!(
            (a[k] - b[k]).abs() <= tol,
            "{what}: {a:?} against {b:?} (tolerance {tol})"
        );
    }
}

/// Issue 12: `calibrate` (results.json and report.html), `register` and `demo` print the
/// same ω φ κ for the same rotation, in the documented convention; and the same project
/// with the same seed gives the same bytes.
#[test]
fn one_angle_convention_everywhere_and_the_same_bytes_for_the_same_input() {
    let w = Work::new("one_angle_convention_everywhere");
    let p = w.project("project");
    let toml = p.join("project.toml");
    // the shared calibration of the same project in another folder and process
    let (out1, out2) = (common::calibration().out.clone(), w.dir.join("out2"));
    // an earlier run's overlay of an image this project does not have, and a user's note
    fs::create_dir_all(out2.join("overlays")).unwrap();
    fs::write(out2.join("overlays/S99_gone.png"), b"an earlier run's").unwrap();
    fs::write(out2.join("overlays/notes.txt"), b"mine").unwrap();
    let run = w.run(&["calibrate", s(&toml), "--out", s(&out2), "--quiet"]);
    assert!(run.success(), "calibrate failed: {}", run.stderr);
    for f in [
        "results.json",
        "cloud.ply",
        "overlays/S00_left.png",
        "overlays/S05_right.png",
    ] {
        assert!(
            fs::read(out1.join(f)).unwrap() == fs::read(out2.join(f)).unwrap(),
            "{f} differs between two runs of the same project and seed"
        );
    }
    assert!(
        !out2.join("overlays/S99_gone.png").exists(),
        "an earlier run's overlay passes for this run's"
    );
    assert!(
        out2.join("overlays/notes.txt").exists(),
        "a user's file was removed"
    );

    // results.json: opk_deg is the documented convention's angles of `rotation`, for every
    // method; the report shows the same numbers.
    let r = read_json(&out1.join("results.json"));
    let report = fs::read_to_string(out1.join("report.html")).unwrap();
    for m in r["methods"].as_array().expect("methods") {
        let e = &m["extrinsic"];
        if e.is_null() {
            continue;
        }
        let rot = mat3(&e["rotation"], "rotation");
        let opk = vec3(&e["opk_deg"], "opk_deg");
        close3(
            opk,
            opk_of(&rot),
            1e-9,
            &format!("{} opk_deg against its rotation", m["method"]),
        );
        for a in opk {
            let shown = format!("{:.4}", a);
            assert!(
                report.contains(&shown),
                "report.html does not show ω φ κ {shown}"
            );
        }
    }
    let opk = vec3(&r["extrinsic"]["opk_deg"], "extrinsic.opk_deg");
    let rot = mat3(&r["extrinsic"]["rotation"], "extrinsic.rotation");
    let t = vec3(
        &r["extrinsic"]["translation_mm"],
        "extrinsic.translation_mm",
    );

    // register: the balls' camera coordinates, and the LRF coordinates the extrinsic gives
    // them exactly (p_lrf = Rᵀ (q − t)), so that register must find that very rotation.
    let (mut cam, mut lrf) = (String::new(), String::new());
    for b in r["balls"].as_array().expect("balls") {
        let q = vec3(&b["photogrammetric_mm"], "ball");
        let d = [q[0] - t[0], q[1] - t[1], q[2] - t[2]];
        let p: Vec<f64> = (0..3)
            .map(|k| (0..3).map(|j| rot[j][k] * d[j]).sum())
            .collect();
        let id = b["id"].as_str().unwrap();
        cam += &format!("{id} {:.9} {:.9} {:.9}\n", q[0], q[1], q[2]);
        lrf += &format!("{id} {:.9} {:.9} {:.9}\n", p[0], p[1], p[2]);
    }
    fs::write(w.dir.join("lrf.txt"), lrf).unwrap();
    fs::write(w.dir.join("cam.txt"), cam).unwrap();
    let reg_json = w.dir.join("register.json");
    let run = w.run(&[
        "register",
        s(&w.dir.join("lrf.txt")),
        s(&w.dir.join("cam.txt")),
        "--out",
        s(&reg_json),
    ]);
    assert!(run.success(), "register failed: {}", run.stderr);
    let reg = read_json(&reg_json);
    close3(
        vec3(&reg["extrinsic"]["opk_deg"], "register opk_deg"),
        opk,
        1e-6,
        "register's opk_deg against calibrate's",
    );
    close3(
        triple_after(&run.stdout, "ω φ κ ="),
        opk,
        0.0006,
        "register's printed ω φ κ against calibrate's",
    );

    // demo: the printed angles of each method and of the truth are those of its own
    // results.json and truth.json.
    let demo = w.dir.join("demo");
    let run = w.run(&["demo", "--out", s(&demo), "--quiet"]);
    assert!(run.success(), "demo failed: {}", run.stderr);
    let dr = read_json(&demo.join("results").join("results.json"));
    // issue 33: on the demo every ball's two centres agree within 3σ and 6 mm
    balls_on_their_lrf_centres(&dr, 6.0);
    for m in dr["methods"].as_array().expect("methods") {
        let Some(name) = m["method"].as_str() else {
            continue;
        };
        if m["extrinsic"].is_null() {
            continue;
        }
        let line = run
            .stdout
            .lines()
            .find(|l| l.starts_with(name) && l.contains('('))
            .unwrap_or_else(|| panic!("demo prints no row for {name}:\n{}", run.stdout));
        // the row's second triple is ω φ κ (the first is t, then σ t for the sphere method)
        let triples: Vec<[f64; 3]> = line
            .match_indices('(')
            .map(|(i, _)| triple_after(&line[i..], ""))
            .collect();
        let opk = opk_of(&mat3(&m["extrinsic"]["rotation"], "demo rotation"));
        assert!(
            triples
                .iter()
                .any(|t| (0..3).all(|k| (t[k] - opk[k]).abs() <= 0.0006)),
            "demo's {name} row {line:?} does not show ω φ κ {opk:?}"
        );
    }
    let truth = read_json(&demo.join("truth.json"));
    let te = &truth["extrinsic"];
    let line = run
        .stdout
        .lines()
        .find(|l| l.starts_with("truth"))
        .expect("a truth row");
    let shown = line
        .match_indices('(')
        .map(|(i, _)| triple_after(&line[i..], ""))
        .nth(1)
        .expect("truth ω φ κ");
    close3(
        shown,
        opk_of(&mat3(&te["rotation"], "truth rotation")),
        0.0006,
        "demo's truth ω φ κ against truth.json's rotation",
    );
    close3(
        vec3(&te["opk_deg"], "truth opk_deg"),
        opk_of(&mat3(&te["rotation"], "truth rotation")),
        1e-9,
        "truth.json's opk_deg against its rotation",
    );
}

/// Issue 14: the start-up bundles of `pingcal ba` reject gross errors; the summary and the
/// report count and list them (they said "0 rejected" before). The measurement file is the
/// one of `bad-inputs/` written in the format's documented form, with one image point moved
/// by 60 px.
#[test]
fn ba_reports_the_start_up_rejections() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data/bad-inputs/measurements_doc_example_style.json");
    if !src.exists() {
        println!("skipped: {} is absent", src.display());
        return;
    }
    let w = common::Work::new("ba_startup_rejections");
    let mut m = read_json(&src);
    let x = num(&m["image_points"][10]["x"], "x");
    m["image_points"][10]["x"] = (x + 60.0).into();
    let (image, point) = (
        m["image_points"][10]["image"].as_str().unwrap().to_string(),
        m["image_points"][10]["point"].as_str().unwrap().to_string(),
    );
    let file = w.dir.join("m.json");
    fs::write(&file, serde_json::to_string(&m).unwrap()).unwrap();
    let report = w.dir.join("report.txt");
    let run = w.run(&["ba", s(&file), "--report", s(&report), "--quiet"]);
    assert!(run.success(), "ba failed: {}", run.stderr);
    // Only the blunder: its point's and its image's good observations, dragged before it
    // was gone, are kept (they used to be rejected with it: 12 in all).
    let summary = run.stdout.lines().last().unwrap_or("");
    assert!(summary.contains(", 1 rejected;"), "{summary}");
    let text = fs::read_to_string(&report).unwrap();
    assert!(
        text.contains("REJECTED OBSERVATIONS")
            && text.contains(&format!("image {image} point {point} at"))
            && text.contains("start-up bundle: residual"),
        "{text}"
    );
}

/// Issue 14's verdict: `ok` on the clean simulation; `doubtful`, saying why, when the LRF
/// scanner sits 25 mm off the servo axis and the project does not know it (the two-step
/// method cannot absorb it; the check error then hides behind shared geometry).
#[test]
fn verdict_is_ok_on_a_clean_simulation_and_doubtful_with_an_unknown_mount_offset() {
    let w = Work::new("verdict");
    let out = &common::calibration().out;
    let r = read_json(&out.join("results.json"));
    assert_eq!(
        r["verdict"]["status"], "ok",
        "clean simulation: {}",
        r["verdict"]
    );
    let checks = r["verdict"]["checks"].as_array().expect("verdict.checks");
    assert!(checks.len() >= 4, "{checks:?}");
    let report = fs::read_to_string(out.join("report.html")).unwrap();
    assert!(
        report.contains("Verdict: ok"),
        "report.html shows no verdict"
    );
    // a stereo baseline entered in centimetres: the adjusted rig says otherwise (the quick
    // project: the check is the images')
    let p = w.quick_project("project");
    let text = fs::read_to_string(p.join("project.toml")).unwrap();
    let line = text
        .lines()
        .find(|l| l.starts_with("baseline_mm"))
        .expect("the simulated project has a [stereo] baseline_mm")
        .to_string();
    let mm: f64 = line.split('=').nth(1).unwrap().trim().parse().unwrap();
    replace_once(
        &p.join("project.toml"),
        &line,
        &format!("baseline_mm = {}", mm / 10.0),
    );
    let out_b = w.dir.join("out-baseline");
    let run = w.run(&[
        "calibrate",
        s(&p.join("project.toml")),
        "--out",
        s(&out_b),
        "--quiet",
    ]);
    assert!(
        run.calibrated(&out_b.join("results.json")),
        "calibrate failed: {}",
        run.stderr
    );
    let v = read_json(&out_b.join("results.json"))["verdict"].clone();
    assert_eq!(v["status"], "doubtful", "a wrong baseline_mm: {v}");
    assert!(
        v["reasons"]
            .to_string()
            .contains("adjusted stereo baseline"),
        "{v}"
    );

    // (the small field's rendering and beams: the offset's effects are the LRF's, and a
    // quarter of the beams show them as plainly)
    let q = w.simulate(
        "offset",
        &format!("[render]\nsupersampling = 2\n[lrf]\nmount_offset_mm = [0.0, 0.0, 25.0]\n{QUARTER_BEAMS}"),
    );
    // the simulator's project leaves the mount at zero, as a user who does not know it would
    assert!(fs::read_to_string(q.join("project.toml"))
        .unwrap()
        .contains("mount_offset_mm = [0.0, 0.0, 0.0]"));
    // The paper's two steps, which cannot absorb a mount error (the joint adjustment below).
    two_step_method(&q);
    // (seed 3 of the RANSAC: with the mount error the label-free ball correspondence can be
    // ambiguous for other seeds, which issues 13 and 19 deal with)
    let calibrate = |out: &Path| {
        let toml = q.join("project.toml");
        let run = w.run(&[
            "calibrate",
            s(&toml),
            "--out",
            s(out),
            "--quiet",
            "--seed",
            "3",
        ]);
        assert!(
            run.calibrated(&out.join("results.json")),
            "calibrate failed: {}",
            run.stderr
        );
    };
    let out = w.dir.join("out-offset");
    calibrate(&out);
    let r = read_json(&out.join("results.json"));
    let v = &r["verdict"];
    assert_eq!(
        v["status"], "doubtful",
        "an unknown 25 mm mount offset: {v}"
    );
    // A 25 mm offset puts a 38 mm ball's points from the two sides of the sweep apart: the
    // finder refuses such doubled balls (beams pass through them), and the verdict names the
    // mount either through the registration's misfit of the balls it kept or through the
    // balls seen twice.
    let reasons = v["reasons"].to_string();
    assert!(
        (reasons.contains("registration's σ0") || reasons.contains("seen twice"))
            && reasons.contains("mount"),
        "the reasons name the misfit and its likely cause: {reasons}"
    );
    let report = fs::read_to_string(out.join("report.html")).unwrap();
    assert!(
        report.contains("Verdict: doubtful"),
        "report.html shows no verdict"
    );
    // With the joint adjustment, whose result is then the one given, the two-step misfit is
    // a note on the LRF's model, not a reason to doubt that result.
    replace_once(
        &q.join("project.toml"),
        "method = \"spheres\"",
        "method = \"all\"",
    );
    let out = w.dir.join("out-offset-all");
    calibrate(&out);
    let v = read_json(&out.join("results.json"))["verdict"].clone();
    let (notes, reasons) = (v["notes"].to_string(), v["reasons"].to_string());
    assert!(notes.contains("registration's σ0"), "{v}");
    assert!(!reasons.contains("registration's σ0"), "{v}");
}

/// Unit mistakes that all used to end in the bare "no ball was found in two or more
/// oriented images": the error names the likely cause from the values.
#[test]
fn a_unit_mistake_is_named_when_no_ball_is_found() {
    let w = Work::new("unit_mistake_no_ball");
    type Edit = fn(&str) -> String;
    let cases: [(&str, Edit, &[&str]); 4] = [
        // the principal distance in µm
        (
            "c_um",
            |t| t.replace("c_mm = 2.45\n", "c_mm = 2450.0\n"),
            &["c_mm = 2450", "the sensor's diagonal", "in mm?"],
        ),
        // the distances in metres
        (
            "distances_m",
            |t| metres(t),
            &["scale", "distances", "in mm"],
        ),
        // a ball of 100 m (1e9 mm is refused up front, beyond any length a project gives)
        (
            "huge_ball",
            |t| t.replace("diameter_mm = 38.0", "diameter_mm = 1e5"),
            &["largest", "plain blobs", "diameter_mm"],
        ),
        // only the main stereo pair
        (
            "main_pair_only",
            |t| only_station(t, "S00"),
            &["only 2 of 2 images are oriented", "3 rays"],
        ),
    ];
    for (name, edit, needles) in cases {
        let p = w.project(name);
        let toml = p.join("project.toml");
        let text = fs::read_to_string(&toml).unwrap();
        let edited = edit(&text);
        assert_ne!(edited, text, "{name}: the edit changed nothing");
        fs::write(&toml, edited).unwrap();
        // a wrong principal distance may stop the network before the balls are looked for
        // (no distance left to fix the scale): the cause must be named either way
        // (the principal distance is refused as the project loads: an input error; the
        // others are found in the data)
        let (mut all, kind) = if name == "c_um" {
            (vec![], "input")
        } else {
            (vec!["no ball was found"], "data")
        };
        all.extend_from_slice(needles);
        let err = w.calibrate_fails(&p, kind, &all);
        eprintln!("{name}: {err}");
    }
}

/// `text` with every `distance_mm` and `sigma_mm` divided by 1000.
fn metres(text: &str) -> String {
    text.lines()
        .map(|l| match l.split_once(" = ") {
            Some((k @ ("distance_mm" | "sigma_mm"), v)) => {
                format!("{k} = {}", v.parse::<f64>().expect("a number") / 1000.0)
            }
            _ => l.to_string(),
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// `text` with the `[[images]]` tables of every station but `keep` removed.
fn only_station(text: &str, keep: &str) -> String {
    text.split("\n\n")
        .filter(|t| !t.starts_with("[[images]]") || t.contains(&format!("station = \"{keep}\"")))
        .collect::<Vec<_>>()
        .join("\n\n")
}

/// A field of 10 coded targets, too few for any image pair to be relatively oriented (issue
/// 19: "a network start that uses every start the field allows"): `auto` starts it from the
/// stereo head's nominal pose, or, when the project names a layout of the coded targets, by
/// resecting every image from it; both give the same calibration, a layout point the images
/// place elsewhere is named, and a mono field without a layout is told what to add.
#[test]
fn a_field_too_sparse_for_a_relative_start_starts_from_its_layout_or_its_stereo_head() {
    let w = Work::new("sparse_field_starts");
    // the starts are the images' business: half the supersampling, the LRF as stated (a
    // quarter of the beams), the two-step method
    let config = format!(
        "[targets]\ncoded = 10\n[distances]\ncount = 3\n[render]\nsupersampling = 2\n{LRF_AS_STATED}{QUARTER_BEAMS}"
    );
    let p = w.simulate("sparse", &config);
    two_step_method(&p);
    let toml = p.join("project.toml");
    let calibrate = |name: &str, start: &str| -> Value {
        let out = w.dir.join(name);
        let run = w.run(&[
            "calibrate",
            s(&toml),
            "--out",
            s(&out),
            "--quiet",
            "--start",
            start,
        ]);
        assert!(run.success(), "{name}: calibrate failed: {}", run.stderr);
        read_json(&out.join("results.json"))
    };
    // the relative orientation alone cannot start it
    let out = w.dir.join("relative");
    let run = w.run(&[
        "calibrate",
        s(&toml),
        "--out",
        s(&out),
        "--quiet",
        "--start",
        "relative",
    ]);
    assert!(
        !run.success() && run.stderr.contains("relative orientation failed"),
        "{}",
        run.stderr
    );
    // auto: the stereo head's nominal pose, the failed relative start a warning
    let stereo = calibrate("stereo", "auto");
    assert_eq!(
        stereo["bundle"]["network_start"],
        "the stereo head's nominal pose"
    );
    let report = fs::read_to_string(w.dir.join("stereo/report.html")).unwrap();
    assert!(
        report.contains("relative orientation failed"),
        "the report names the failed start"
    );

    // a layout from the truth's room coordinates, off by up to ±10 mm, one target 400 mm off
    let truth = read_json(&p.join("truth.json"));
    let coded: Vec<&Value> = truth["targets"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|t| t["kind"] == "coded")
        .collect();
    let moved = coded[4]["id"].as_u64().unwrap();
    let mut layout = String::from("id,x_mm,y_mm,z_mm\n");
    for (k, t) in coded.iter().enumerate() {
        let id = t["id"].as_u64().unwrap();
        let x: Vec<f64> = (0..3)
            .map(|a| t["world_mm"][a].as_f64().unwrap() + ((7 * k + 3 * a) % 21) as f64 - 10.0)
            .collect();
        let dz = if id == moved { 400.0 } else { 0.0 };
        layout.push_str(&format!("{id},{},{},{}\n", x[0], x[1], x[2] + dz));
    }
    fs::write(p.join("layout.csv"), layout).unwrap();
    replace_once(
        &toml,
        "ring_outer = 3.0\n",
        "ring_outer = 3.0\nlayout = \"layout.csv\"\n",
    );
    let from_layout = calibrate("layout", "auto");
    assert_eq!(
        from_layout["bundle"]["network_start"],
        "resection from the layout"
    );
    let report = fs::read_to_string(w.dir.join("layout/report.html")).unwrap();
    let named = format!("target {moved} is ");
    let at = report
        .find(&named)
        .expect("the report names the layout point 400 mm off");
    let mm: f64 = report[at + named.len()..]
        .split(' ')
        .next()
        .and_then(|v| v.parse().ok())
        .expect("a distance in mm");
    // 400 mm, give or take the layout's own errors (±10 mm on each axis)
    assert!((mm - 400.0).abs() < 30.0, "{named}{mm} mm");
    assert_eq!(
        report.matches("<li>layout.csv: target ").count(),
        1,
        "only the moved point is named among the report's warnings"
    );
    // The same adjustment from either start: the same minimum, to the solver's convergence
    // (well under a hundredth of the extrinsic's σ, ~1 mm).
    for key in ["translation_mm", "opk_deg"] {
        for a in 0..3 {
            let (x, y) = (
                stereo["extrinsic"][key][a].as_f64().unwrap(),
                from_layout["extrinsic"][key][a].as_f64().unwrap(),
            );
            assert!(
                (x - y).abs() < 1e-3,
                "extrinsic {key}[{a}]: {x} (stereo start) vs {y} (layout start)"
            );
        }
    }

    // mono: without the layout nothing starts, and the error says what to add; with it, it does
    let text = fs::read_to_string(&toml).unwrap();
    let (head, rest) = text.split_once("\n[stereo]\n").expect("a [stereo] table");
    let rest = &rest[rest.find("\n[").expect("a table after [stereo]")..];
    fs::write(
        &toml,
        format!("{head}{rest}").replace("layout = \"layout.csv\"\n", ""),
    )
    .unwrap();
    w.calibrate_fails(
        &p,
        "data",
        &["relative orientation failed", "[targets] layout"],
    );
    replace_once(
        &toml,
        "ring_outer = 3.0\n",
        "ring_outer = 3.0\nlayout = \"layout.csv\"\n",
    );
    let mono = calibrate("mono", "auto");
    assert_eq!(mono["bundle"]["network_start"], "resection from the layout");
}

/// Issue 13: a servo that turns through half a turn sees every ball from one side only, and
/// some of the mount's parameters cannot be told from the extrinsic. The joint adjustment
/// names each parameter it holds, with the sweep as the reason, and gives finite values and
/// σ's for the rest; nothing is NaN.
#[test]
fn a_half_sweep_names_the_mount_parameters_it_cannot_estimate() {
    let w = Work::new("half_sweep");
    let p = w.simulate(
        "half",
        "[render]\nsupersampling = 2\n[lrf]\nservo_start_deg = -90.0\nservo_end_deg = 90.0\nmount_offset_mm = [8.0, -5.0, 12.0]\nmount_tilt_x_deg = 0.4\nrange_offset_mm = 12.0\n",
    );
    let (run, out) = w.calibrate(&p, &[]);
    assert!(run.success(), "calibrate failed: {}", run.stderr);
    let r = read_json(&out.join("results.json"));
    let mount = r["lrf_mount"].as_array().expect("results.lrf_mount");
    // what the data leave free is held and the sweep named as the cause (on this seed the
    // later passes, through the estimated mount, may determine everything: then nothing is)
    for m in mount.iter().filter(|m| m["name"] != "offset_y") {
        if let Some(h) = m["held"].as_str() {
            assert!(
                h.contains("turned through"),
                "the half sweep is not named: {m}"
            );
        }
    }
    for m in mount {
        match m["held"].as_str() {
            Some(h) => assert!(!h.is_empty() && m["sigma"].is_null(), "{m}"),
            None => {
                let (v, s) = (m["value"].as_f64(), m["sigma"].as_f64());
                assert!(
                    v.is_some_and(f64::is_finite) && s.is_some_and(|s| s > 0.0 && s.is_finite()),
                    "an estimated parameter needs a finite value and σ: {m}"
                );
            }
        }
    }
    let text = fs::read_to_string(out.join("results.json")).unwrap();
    assert!(
        !text.contains("NaN") && !text.contains("nan"),
        "a NaN in results.json"
    );
}

/// Issue 40: when the project's mount is so far off that the spheres of its cloud match too
/// few balls for the two-step method (here the scan plane's tilt stated 6.3° off and ten of
/// the sixteen balls named check balls: through that mount the six balls matched are all
/// check balls), the calibration does not stop there. With the joint adjustment asked for,
/// step 6 runs again on the cloud through the mount the room's walls, floor and ceiling give
/// (all sixteen balls match there), says so in the two-step method's notes, and the joint
/// adjustment's extrinsic is within 5σ of the truth.
#[test]
fn a_mount_too_far_off_for_the_two_step_start_starts_from_the_rooms() {
    let w = Work::new("room_fallback");
    let p = w.simulate(
        "tilted",
        &format!("[render]\nsupersampling = 2\n[lrf]\n{QUARTER_BEAMS}"),
    );
    let toml = p.join("project.toml");
    replace_once(
        &toml,
        "mount_tilt_x_deg = 0.0\n",
        "mount_tilt_x_deg = -6.0\n",
    );
    replace_once(
        &toml,
        "check = [\"B4\", \"B9\", \"B11\", \"B12\", \"B15\"]",
        "check = [\"B2\", \"B4\", \"B5\", \"B7\", \"B9\", \"B11\", \"B12\", \"B14\", \"B15\", \"B16\"]",
    );
    // the premise: the two-step method alone stops for want of control balls
    two_step_method(&p);
    let why = w.calibrate_fails(&p, "data", &["control balls are left"]);
    replace_once(&toml, "method = \"spheres\"", "method = \"all\"");
    let (run, out) = w.calibrate(&p, &[]);
    assert!(
        run.calibrated(&out.join("results.json")),
        "calibrate failed: {}",
        run.stderr
    );
    let r = read_json(&out.join("results.json"));
    let spheres = (r["methods"].as_array().expect("methods").iter())
        .find(|m| m["method"] == "spheres")
        .expect("the two-step method's entry");
    let note = spheres["notes"][0].as_str().unwrap_or_default();
    assert!(
        note.contains("through the mount the room's planes gave")
            && note.contains("control balls are left"),
        "the two-step method's notes: {spheres}\n(alone it said: {why})"
    );
    let truth = read_json(&p.join("truth.json"));
    let offset_y = truth["lrf_mount"]["offset_mm"][1].as_f64().unwrap();
    for k in 0..3 {
        let want = num(&truth["extrinsic"]["translation_mm"][k], "true t")
            + num(&truth["extrinsic"]["rotation"][k][1], "true R") * offset_y;
        let got = num(&r["extrinsic"]["translation_mm"][k], "t");
        let sigma = num(&r["extrinsic"]["sigma_translation_mm"][k], "σ of t");
        assert!(
            (got - want).abs() <= 5.0 * sigma + 0.5,
            "t[{k}] = {got} mm ± {sigma}, truth {want} mm"
        );
    }
}

/// Issue 37: a continuous sweep, forward then back, whose servo stamps are 20 ms late
/// against the scanner's. The joint adjustment estimates the time offset with its σ
/// (results.json's `lrf_mount` entry `time_offset_s`, and the `lrf_model` every LRF output
/// uses), within 3σ of the truth and precise enough to tell 20 ms from none (σ under 10
/// ms: at 2.5°/s the offset turns the beams by 0.05°, 0.9 mm at 1 m, and the five seeds of
/// bench/joint gave σ 6.3–6.5 ms); the check balls stay within what the field gives (mean ≤
/// 3 mm). The scans give the time between beams, from which each beam's servo rate comes.
#[test]
fn a_continuous_sweeps_servo_time_offset_is_estimated() {
    let w = Work::new("time_offset");
    let p = w.simulate(
        "sweep",
        "[render]\nsupersampling = 2\n[lrf]\ncontinuous_sweep = true\nservo_passes = 2\nservo_step_deg = 0.25\nservo_time_offset_s = 0.02\n",
    );
    let (run, out) = w.calibrate(&p, &[]);
    assert!(
        run.calibrated(&out.join("results.json")),
        "calibrate failed: {}",
        run.stderr
    );
    let r = read_json(&out.join("results.json"));
    let truth = read_json(&p.join("truth.json"));
    let want = num(&truth["lrf_servo_time_offset_s"], "truth's time offset");
    let mount = r["lrf_mount"].as_array().expect("results.lrf_mount");
    let t = (mount.iter())
        .find(|m| m["name"] == "time_offset_s")
        .unwrap_or_else(|| panic!("no time_offset_s in lrf_mount: {mount:?}"));
    let (value, sigma) = (num(&t["value"], "time offset"), num(&t["sigma"], "its σ"));
    assert!(
        sigma > 0.0 && sigma < 0.01,
        "σ of the time offset {sigma} s"
    );
    assert!(
        (value - want).abs() <= 3.0 * sigma,
        "time offset {value} s ± {sigma}, truth {want} s"
    );
    // the model every LRF output uses carries it, and the report's mount table in seconds
    let model = num(&r["lrf_model"]["servo_time_offset_s"], "lrf_model's offset");
    assert_eq!(model, value);
    let report = fs::read_to_string(out.join("report.html")).unwrap();
    let row = report
        .split("<tr")
        .find(|r| r.contains(">time_offset_s<"))
        .unwrap_or_else(|| panic!("no time_offset_s row in the report's mount table"));
    assert!(
        row.contains("<td class=\"l\">s</td>"),
        "the time offset's unit: {row}"
    );
    let joint = (r["methods"].as_array().expect("methods").iter())
        .find(|m| m["method"] == "joint")
        .expect("the joint method");
    let check = num(&joint["mean_check_error_mm"], "joint check error");
    assert!(check <= 3.0, "mean check error {check} mm");
}

/// A start that falls into another minimum gives way to one that does not: on the default
/// field rendered with 0.9 px of blur, seed 10 (bench/robustness), the relative orientation
/// orients every image but fits the coded targets at RMS 5.8 px (a sound start: 0.02 px);
/// kept, it made the matching remove 23 coded reads as blunders and take 36 plain targets for
/// balls, and the verdict was doubtful. `auto` now tries the stereo head's start as well,
/// keeps its 0.018 px, says so in a warning, and the calibration is ok.
#[test]
fn a_start_in_another_minimum_gives_way_to_a_better_one() {
    let w = Work::new("suspect_start");
    let cfg = w.dir.join("blur.toml");
    // the start is the images' business: the LRF as stated (a quarter of the beams), the
    // two-step method
    fs::write(
        &cfg,
        format!("[render]\nblur_sigma_px = 0.9\n{LRF_AS_STATED}{QUARTER_BEAMS}"),
    )
    .unwrap();
    let p = w.dir.join("sim");
    let sim = w.run(&[
        "simulate",
        "--seed",
        "10",
        "--config",
        s(&cfg),
        "--out",
        s(&p),
    ]);
    assert!(sim.success(), "simulate failed: {}", sim.stderr);
    two_step_method(&p);
    let (run, out) = w.calibrate(&p, &["--seed", "10"]);
    assert!(run.success(), "calibrate: {}", run.stderr);
    let r = read_json(&out.join("results.json"));
    assert_eq!(
        r["bundle"]["network_start"],
        "the stereo head's nominal pose"
    );
    assert_eq!(
        r["bundle"]["coded_blunders"].as_array().map(Vec::len),
        Some(0)
    );
    let report = fs::read_to_string(out.join("report.html")).unwrap();
    assert!(
        report.contains("relative orientation oriented 22 images at RMS"),
        "no warning of the start passed over in the report"
    );
}

/// Issue 49: a typo in a measured distance or a control point is named as the blunder. The
/// pristine project with 5 mm added to its first `[[distances]]` entry (σ 0.1 mm: 50 σ):
/// data snooping rejects that distance — in the log, results.json's
/// `bundle.rejected_distances`, the report and the verdict (`doubtful`, "a typo?") — and
/// rejects as many image points as the clean calibration, none in its place (it rejected the
/// image points of the distance's targets, then dropped the distance with "coded target …
/// was not identified", and the verdict was ok). The same for a control point with
/// `pingcal ba` (the project format has no control points): the demo-like measurement file
/// of the shared data, with five of its points as weighted control (σ 0.5 mm) at their
/// adjusted coordinates, then one of them 5 mm off in X.
#[test]
fn a_typo_in_a_distance_or_a_control_point_is_named_as_the_blunder() {
    let w = Work::new("typo_named_as_the_blunder");
    let p = w.project("project");
    let toml = p.join("project.toml");
    let text = fs::read_to_string(&toml).unwrap();
    let at = text.find("distance_mm = ").expect("a distance") + "distance_mm = ".len();
    let end = at + text[at..].find('\n').expect("end of line");
    let given: f64 = text[at..end].trim().parse().expect("a number");
    let typo = given + 5.0;
    fs::write(&toml, format!("{}{typo}{}", &text[..at], &text[end..])).unwrap();
    let out = w.dir.join("out");
    let run = w.run(&["calibrate", s(&toml), "--out", s(&out)]);
    let ctx = format!(
        "exit {:?}\nstdout: {}\nstderr: {}",
        run.code, run.stdout, run.stderr
    );
    assert_eq!(run.code, Some(3), "doubtful: {ctx}");
    let named = "distances[0]: the distance ";
    let log = format!("{}{}", run.stdout, run.stderr);
    assert!(log.contains(&format!("warning: {named}")), "the log: {ctx}");
    assert!(
        !log.contains("not used: coded target"),
        "a target dropped: {ctx}"
    );
    let r = read_json(&out.join("results.json"));
    let clean = read_json(&common::calibration().out.join("results.json"));
    let rejected = r["bundle"]["rejected_distances"]
        .as_array()
        .expect("an array");
    assert_eq!(rejected.len(), 1, "{rejected:?}");
    let d = &rejected[0];
    assert_eq!(d["entry"], 0, "{d}");
    assert_eq!(num(&d["given_mm"], "given_mm"), typo, "{d}");
    // the other distances put its targets where they are: within a few of their σ's
    let adjusted = num(&d["adjusted_mm"], "adjusted_mm");
    assert!(
        (adjusted - given).abs() < 0.5,
        "adjusted {adjusted}, truth {given}"
    );
    assert!(num(&d["w"], "w").abs() > 10.0, "{d}");
    println!(
        "distance {} – {} given {typo} (truth {given}): adjusted {adjusted:.3}, w {:.1}; image points rejected {} (clean {})",
        d["from"], d["to"], d["w"], r["bundle"]["rejected"], clean["bundle"]["rejected"]
    );
    assert_eq!(
        r["bundle"]["rejected"], clean["bundle"]["rejected"],
        "image points rejected in its place"
    );
    assert_eq!(
        r["bundle"]["distances"].as_u64(),
        clean["bundle"]["distances"].as_u64().map(|n| n - 1),
        "only the typo is left out"
    );
    assert_eq!(clean["bundle"]["rejected_distances"], serde_json::json!([]));
    assert_eq!(r["verdict"]["status"], "doubtful");
    let reasons = r["verdict"]["reasons"].to_string();
    assert!(
        reasons.contains(named) && reasons.contains("a typo?"),
        "{reasons}"
    );
    let report = fs::read_to_string(out.join("report.html")).unwrap();
    assert!(
        report.contains(named) && report.contains("a typo?"),
        "the report"
    );

    let src = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data/bad-inputs/measurements_doc_example_style.json");
    if !src.exists() {
        println!("control point case skipped: {} is absent", src.display());
        return;
    }
    let ba = |m: &Value, name: &str| -> Value {
        let (file, out) = (
            w.dir.join(format!("{name}.json")),
            w.dir.join(format!("{name}-out.json")),
        );
        fs::write(&file, serde_json::to_string(m).unwrap()).unwrap();
        let run = w.run(&[
            "ba",
            s(&file),
            "--snoop",
            "3.29",
            "--out",
            s(&out),
            "--quiet",
        ]);
        assert!(run.success(), "ba {name}: {}", run.stderr);
        read_json(&out)
    };
    let mut m = read_json(&src);
    let free = ba(&m, "free");
    let control = ["396", "497", "264", "360", "115"];
    let xyz = |id: &str| {
        (free["object_points"].as_array().unwrap().iter())
            .find(|p| p["name"] == id)
            .map(|p| p["xyz"].clone())
            .expect("an adjusted point")
    };
    m["control_points"] = control
        .iter()
        .map(|id| serde_json::json!({"id": id, "xyz": xyz(id), "sigma_mm": [0.5, 0.5, 0.5]}))
        .collect();
    let clean = ba(&m, "control");
    let x = num(&m["control_points"][2]["xyz"][0], "x");
    m["control_points"][2]["xyz"][0] = (x + 5.0).into();
    let typo = ba(&m, "typo");
    assert_eq!(clean["rejected_control_points"], serde_json::json!([]));
    let rejected = typo["rejected_control_points"]
        .as_array()
        .expect("an array");
    assert_eq!(rejected.len(), 1, "{rejected:?}");
    let c = &rejected[0];
    assert_eq!(c["point"], "264", "{c}");
    assert!(
        (num(&c["estimated"][0], "estimated x") - x).abs() < 1.0,
        "{c}"
    );
    println!(
        "control point 264 given {} mm off in X: w {}, image points rejected {} (clean {})",
        5.0,
        c["w"],
        typo["rejected"].as_array().map_or(0, Vec::len),
        clean["rejected"].as_array().map_or(0, Vec::len)
    );
    // the same image points, by image and point (their w's move a little with σ0)
    let points = |r: &Value| {
        let mut v: Vec<(String, String)> = (r["rejected"].as_array().unwrap().iter())
            .map(|x| (x["image"].to_string(), x["point"].to_string()))
            .collect();
        v.sort();
        v
    };
    assert_eq!(
        points(&typo),
        points(&clean),
        "image points rejected in its place"
    );
    assert_eq!(typo["rejected_distances"], serde_json::json!([]));
}
