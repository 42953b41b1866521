//! `pingcal plan` (issue 18's planner), run as a user runs it, on a small field (five
//! convergent stations, half the rendering's supersampling, a 0.35° servo step: about 11 s
//! for two seeds on two cores): the table and `plan.json` hold every number, removing a
//! station or a distance makes the ball centres' σ grow (and never shrinks the extrinsic's
//! beyond its σ0's own wobble), a seed's calibration gives the same numbers in another plan
//! (σ-honesty's ten seeds), and bad input is refused in one line naming the file or option.

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("pingcal-plan-test-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Runs the binary in `cwd`: (success, stdout, stderr).
fn run(cwd: &Path, args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_pingcal"))
        .args(args)
        .current_dir(cwd)
        .output()
        .expect("run pingcal");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn num(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

#[test]
fn plan_predicts_ranks_removals_and_repeats_itself() {
    let d = dir("small");
    std::fs::write(d.join("small.toml"), crate::common::SMALL_FIELD).unwrap();
    let args = [
        "plan",
        "--config",
        "small.toml",
        "--seeds",
        "2",
        "--quiet",
        "--out",
    ];
    let (ok, stdout, stderr) = run(&d, &[&args[..], &["p1.json"]].concat());
    assert!(ok, "plan failed\nstdout: {stdout}\nstderr: {stderr}");
    assert!(!stdout.contains("with honest σ's"), "{stdout}");
    for want in [
        "2 seed(s) from 1, 2 calibrated, 0 failed; 6 stations, 5 distances, 16 balls (5 check)",
        "predicted σ",
        "Monte Carlo RMS error",
        "tx mm",
        "κ deg",
        "ball X mm",
        "check balls: expected mean error",
        "this field should give about",
        "remove each and see (seed 1)",
        "station S03",
        "plan: wrote p1.json",
    ] {
        assert!(stdout.contains(want), "no {want:?} in\n{stdout}");
    }
    let p: Value = serde_json::from_str(&std::fs::read_to_string(d.join("p1.json")).unwrap())
        .expect("plan.json is JSON");
    assert_eq!(p["calibrated"], 2);
    assert_eq!(p["failures"].as_array().unwrap().len(), 0);
    let ext = p["extrinsic"].as_array().unwrap();
    assert_eq!(ext.len(), 6);
    for c in ext.iter().chain(p["ball_centres"].as_array().unwrap()) {
        let (s, m) = (num(&c["predicted_sigma"]), num(&c["monte_carlo_rms_error"]));
        assert!(s > 0.0 && s.is_finite() && m > 0.0 && m.is_finite(), "{c}");
        assert!((num(&c["ratio"]) - m / s).abs() < 1e-12, "{c}");
        // 2 seeds are too few for the honest band
        assert!(c["consistent_with_honest_sigma"].is_null(), "{c}");
    }
    // a 5-station field's σ: about a millimetre, not a micrometre nor a metre
    assert!(
        (0.2..10.0).contains(&num(&ext[0]["predicted_sigma"])),
        "{}",
        ext[0]
    );
    let e = num(&p["expected_check_error_mm"]);
    assert!((0.5..20.0).contains(&e), "expected check error {e}");
    assert_eq!(p["runs"].as_array().unwrap().len(), 2);

    // remove each and see: 5 stations besides the main one and 5 distances, none breaks it
    let sens = p["sensitivity"].as_array().unwrap();
    assert_eq!(sens.len(), 10, "{sens:?}");
    let mut station_growth = Vec::new();
    for s in sens {
        assert!(s["failed"].is_null(), "{s}");
        let ball = num(&s["ball_sigma_growth"]);
        let t = num(&s["translation_sigma_growth"]);
        // less data can only widen the ball centres' σ (σ0 is estimated, so allow nothing
        // below 1); the extrinsic's σ is dominated by the LRF side and may move by the
        // variance components' estimates only, which the joint adjustment makes for every
        // group: the balls' (redundancy about 500) has a relative standard error of
        // 1/√(2·500) ≈ 3 %, so allow 3 of those
        assert!(
            ball > 1.0,
            "removing {} shrank the balls' σ: {s}",
            s["removed"]
        );
        assert!(
            t > 0.9,
            "removing {} shrank the extrinsic's σ: {s}",
            s["removed"]
        );
        if s["removed"].as_str().unwrap().starts_with("station") {
            station_growth.push(ball);
        }
    }
    assert_eq!(station_growth.len(), 5);
    // ranked: the translation's growth does not increase down the list
    let t: Vec<f64> = sens
        .iter()
        .map(|s| num(&s["translation_sigma_growth"]))
        .collect();
    assert!(t.windows(2).all(|w| w[0] >= w[1]), "not ranked: {t:?}");
    // some station is worth more than a tenth of the ball centres' σ
    let max_station = station_growth.iter().cloned().fold(0.0, f64::max);
    assert!(max_station > 1.1, "{station_growth:?}");

    // the same input gives the same numbers: seeds 1 and 2 calibrated in this plan (beside
    // its removals) and in σ-honesty's plan of 10 seeds without removals (another process,
    // other seeds beside them on the threads) give the same runs, value for value (each
    // number as written, so to the last bit of the f64)
    let many = crate::sigma_honesty::small_plan();
    assert_eq!(
        p["runs"].as_array().unwrap()[..],
        many["runs"].as_array().unwrap()[..2],
        "seeds 1 and 2 differ between two plans"
    );
    std::fs::remove_dir_all(&d).unwrap();
}

/// A fixed LRF's plan (issue 50): its scans at three of the small field's stations;
/// removing a station takes its scans with its images, so each removal calibrates and
/// says what the station is worth (before, a scan station without its images broke every
/// removal).
#[test]
fn a_fixed_lrfs_plan_removes_a_stations_scans_with_it() {
    let d = dir("fixed");
    let config = format!(
        "{}kind = \"fixed\"\nscan_stations = [\"S00\", \"S01\", \"S02\"]\n",
        crate::common::SMALL_FIELD
    );
    std::fs::write(d.join("fixed.toml"), config).unwrap();
    let args = [
        "plan",
        "--config",
        "fixed.toml",
        "--seeds",
        "1",
        "--quiet",
        "--out",
        "p.json",
    ];
    let (ok, stdout, stderr) = run(&d, &args);
    assert!(ok, "plan failed\nstdout: {stdout}\nstderr: {stderr}");
    let p: Value = serde_json::from_str(&std::fs::read_to_string(d.join("p.json")).unwrap())
        .expect("plan.json is JSON");
    assert_eq!(p["calibrated"], 1, "{stdout}");
    let sens = p["sensitivity"].as_array().unwrap();
    let stations: Vec<&Value> = (sens.iter())
        .filter(|s| s["removed"].as_str().unwrap().starts_with("station"))
        .collect();
    assert_eq!(stations.len(), 5, "{sens:?}");
    for s in &stations {
        assert!(s["failed"].is_null(), "{s}");
        assert!(num(&s["translation_sigma_growth"]) > 0.9, "{s}");
    }
    // a station with scans is worth more to the extrinsic than one with images only
    let growth = |id: &str| {
        (stations.iter())
            .find(|s| s["removed"] == format!("station {id}"))
            .map(|s| num(&s["translation_sigma_growth"]))
            .expect("a station's row")
    };
    let with_scans = growth("S01").max(growth("S02"));
    let without = ["S03", "S04", "S05"].map(growth);
    assert!(
        without.iter().all(|&g| g < with_scans),
        "S01/S02 {with_scans} vs {without:?}"
    );
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn bad_plans_are_refused_in_one_line() {
    let d = dir("bad");
    // zero seeds
    let (ok, _, err) = run(&d, &["plan", "--seeds", "0"]);
    assert!(
        !ok && err.contains("--seeds 0: expected at least 1"),
        "{err}"
    );
    // a configuration with an error: one line naming the file; an earlier plan.json stays
    std::fs::write(d.join("bad.toml"), "[stations]\nconvergant = 5\n").unwrap();
    std::fs::write(d.join("plan.json"), "earlier").unwrap();
    let (ok, _, err) = run(&d, &["plan", "--config", "bad.toml", "--out", "plan.json"]);
    assert!(!ok, "{err}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(
        err.starts_with("pingcal: error: bad.toml: ") && err.contains("convergant"),
        "{err}"
    );
    assert_eq!(
        std::fs::read_to_string(d.join("plan.json")).unwrap(),
        "earlier"
    );
    // no station but the main one: a diagnosis before any simulation
    std::fs::write(d.join("alone.toml"), "[stations]\nconvergent = 0\n").unwrap();
    let (ok, _, err) = run(&d, &["plan", "--config", "alone.toml"]);
    assert!(!ok, "{err}");
    assert!(
        err.contains("alone.toml: stations.convergent = 0")
            && err.contains("only the main station"),
        "{err}"
    );
    // --write-config writes a configuration the simulator reads back, and never replaces a file
    let (ok, out, err) = run(&d, &["plan", "--write-config", "simulation.toml"]);
    assert!(ok, "{out}{err}");
    let text = std::fs::read_to_string(d.join("simulation.toml")).unwrap();
    assert!(text.contains("convergent = 10"), "{text}");
    let (ok, _, err) = run(&d, &["plan", "--write-config", "simulation.toml"]);
    assert!(!ok && err.contains("already exists"), "{err}");
    std::fs::remove_dir_all(&d).unwrap();
}
