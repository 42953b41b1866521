//! A fixed 2D LRF (issue 50): the simulator's `[lrf] kind = "fixed"` calibrated by the joint
//! adjustment; and a horizontal scan plane in a room of vertical walls, whose height and
//! tilts the data cannot fix: held, named, and the verdict not `ok`.

use crate::common::Work;
use nalgebra::{Matrix3, Vector3};
use serde_json::Value as Json;

/// results.json and truth.json of a run.
fn read(path: &std::path::Path) -> Json {
    serde_json::from_str(&std::fs::read_to_string(path).expect("read")).expect("JSON")
}

/// A transform's rotation and translation from results.json's / truth.json's `extrinsic`.
fn transform(e: &Json) -> (Matrix3<f64>, Vector3<f64>) {
    let r = Matrix3::from_fn(|i, j| e["rotation"][i][j].as_f64().expect("rotation"));
    let t = Vector3::from_fn(|i, _| e["translation_mm"][i].as_f64().expect("translation"));
    (r, t)
}

/// The default fixed-LRF simulation (every station, the scanner pitched to reach the floor)
/// gives the true extrinsic: within 3 mm and 0.2° (the bounds), each translation
/// component within 4σ of the truth (one seed: 4σ leaves a 1-in-5000 chance per
/// component), the verdict ok, and the groups of its adjustment in results.json.
#[test]
fn the_default_fixed_lrf_simulation_gives_the_true_extrinsic() {
    let w = Work::new("fixed_lrf_default");
    let project = w.simulate("p", "[lrf]\nkind = \"fixed\"\n");
    let toml = std::fs::read_to_string(project.join("project.toml")).expect("project");
    assert!(
        toml.contains("kind = \"fixed\"") && toml.contains("station = \"S05\""),
        "{toml}"
    );
    let (run, out) = w.calibrate(&project, &[]);
    assert!(run.success(), "{}\n{}", run.stdout, run.stderr);
    let r = read(&out.join("results.json"));
    let truth = read(&project.join("truth.json"));
    let (re, te) = (transform(&r["extrinsic"]), transform(&truth["extrinsic"]));
    let dt = re.1 - te.1;
    let dr = (re.0 * te.0.transpose() - Matrix3::identity()).norm() / 2f64.sqrt();
    assert!(dt.norm() <= 3.0, "|Δt| = {:.2} mm ({dt:?})", dt.norm());
    assert!(dr.to_degrees() <= 0.2, "ΔR = {:.3}°", dr.to_degrees());
    for k in 0..3 {
        let s = r["extrinsic"]["sigma_translation_mm"][k]
            .as_f64()
            .expect("σ");
        assert!(
            dt[k].abs() <= 4.0 * s,
            "t[{k}] off by {:.2} mm, σ {s:.2}",
            dt[k]
        );
    }
    assert_eq!(r["verdict"]["status"], "ok", "{}", r["verdict"]);
    let text = r.to_string();
    for group in ["LRF beams on planes", "targets on planes"] {
        assert!(text.contains(group), "{group} in results.json");
    }

    // the same scans as clouds of 2D points in the scanner's frame (an .xyz file in metres
    // at every station but the main one): the same beams, so the same extrinsic (their
    // stations give no corner: the start comes from the main station's)
    let clouds = w.project("clouds");
    crate::common::copy_dir(&project, &clouds);
    let mut toml = std::fs::read_to_string(clouds.join("project.toml")).expect("project");
    for k in 1..=10 {
        let csv = clouds.join(format!("scans/S{k:02}.csv"));
        let reader = pingcal_lrf::scan::open_scan_file(&csv).expect("a scan file");
        let h = reader.header();
        let mut xyz = String::from("# the fixed LRF's 2D points, scanner frame, metres\n");
        for line in reader {
            let line = line.expect("a scan line");
            for (i, &r) in line.ranges_mm.iter().enumerate() {
                if r > 0.0 {
                    let a = h.beam_angle_deg(i).to_radians();
                    let (x, y) = (r * a.cos() / 1000.0, r * a.sin() / 1000.0);
                    xyz += &format!("{x:.9} {y:.9} 0\n");
                }
            }
        }
        std::fs::write(clouds.join(format!("scans/S{k:02}.xyz")), xyz).expect("write");
        toml = toml.replace(&format!("scans/S{k:02}.csv"), &format!("scans/S{k:02}.xyz"));
    }
    toml = toml.replacen("[lrf]\n", "[lrf]\ncloud_unit = \"m\"\n", 1);
    std::fs::write(clouds.join("project.toml"), toml).expect("project");
    let (run, out) = w.calibrate(&clouds, &[]);
    assert!(run.success(), "{}\n{}", run.stdout, run.stderr);
    let c = read(&out.join("results.json"));
    let ce = transform(&c["extrinsic"]);
    let (dt, dr) = (
        (ce.1 - re.1).norm(),
        (ce.0 * re.0.transpose() - Matrix3::identity()).norm(),
    );
    // within a tenth of their σ (0.1–0.6 mm, 2–5e-4 rad): the starts differ, not the data
    assert!(
        dt < 0.05 && dr < 2e-5,
        "clouds vs scans: {dt:.4} mm, {dr:.2e} rad"
    );
}

/// A horizontal scan plane that meets only the vertical walls (level stations at one
/// height, no pitch): the scan plane's height (tz) cannot be fixed by walls parallel to it
/// nor its tilts; what is held is named in results.json and the verdict is not ok.
#[test]
fn a_horizontal_scan_plane_among_vertical_walls_is_named_not_ok() {
    let w = Work::new("fixed_lrf_horizontal");
    let config = "[stations]\nmain_centre_mm = [1150.0, 1100.0, 700.0]\nmain_look_at_mm = [250.0, 230.0, 700.0]\nheights_mm = [700.0]\nrolls_deg = [0.0]\nlook_at_mm = [300.0, 300.0, 700.0]\nlook_jitter_mm = 0.0\n\n[lrf]\nkind = \"fixed\"\nextrinsic_opk_deg = [0.0, 0.0, 0.0]\n";
    let project = w.simulate("p", config);
    let (run, out) = w.calibrate(&project, &["--accept-doubtful"]);
    assert!(run.success(), "{}\n{}", run.stdout, run.stderr);
    let r = read(&out.join("results.json"));
    assert_ne!(r["verdict"]["status"], "ok", "{}", r["verdict"]);
    let reasons = r["verdict"]["reasons"].to_string();
    assert!(reasons.contains("held: the extrinsic's tz"), "{reasons}");
    assert!(
        reasons.contains("add a tilted plane or the floor"),
        "{reasons}"
    );
}

/// One station facing the corner, its scan reaching the floor (Fan et al.'s single shot):
/// the joint adjustment's result with its σ, each translation component within 5σ of the
/// truth, and the corner baseline beside it in results.json's methods.
#[test]
fn one_station_facing_the_corner_gives_the_single_shot_and_the_corner_beside_it() {
    let w = Work::new("fixed_lrf_single_shot");
    let project = w.simulate("p", "[lrf]\nkind = \"fixed\"\nscan_stations = [\"S00\"]\n");
    let (run, out) = w.calibrate(&project, &["--accept-doubtful"]);
    assert!(run.success(), "{}\n{}", run.stdout, run.stderr);
    let r = read(&out.join("results.json"));
    let truth = read(&project.join("truth.json"));
    let methods = r["methods"].as_array().expect("methods");
    let of = |name: &str| methods.iter().find(|m| m["method"] == name).expect(name);
    let (joint, corner) = (of("joint"), of("corner"));
    assert!(
        corner["extrinsic"].is_object(),
        "the corner baseline: {}",
        corner["error"]
    );
    let (je, te) = (
        transform(&joint["extrinsic"]),
        transform(&truth["extrinsic"]),
    );
    for k in 0..3 {
        let s = joint["extrinsic"]["sigma_translation_mm"][k]
            .as_f64()
            .expect("σ");
        let d = je.1[k] - te.1[k];
        assert!(
            s > 0.0 && d.abs() <= 5.0 * s,
            "t[{k}] off by {d:.2} mm, σ {s:.2}"
        );
    }
}
