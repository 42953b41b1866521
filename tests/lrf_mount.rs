//! `pingcal lrf-mount` end to end (issue 53): a nodding 360° scanner's scans (the
//! simulator's, no image rendered) give what the nod determines and name the sweep for the
//! rest; its refusals name what the data lack.

use pingcal_sim::lrf::write_scans_csv;
use pingcal_sim::{SimConfig, Simulation};
use std::path::Path;
use std::process::Command;

fn lrf_mount(args: &[&str]) -> (bool, String, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_pingcal"))
        .arg("lrf-mount")
        .args(args)
        .output()
        .unwrap();
    (
        o.status.success(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

fn temp(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("pingcal-lrf-mount-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The nodding scanner of `crates/sim/tests/nod.rs` (±18°, 1024 beams over the circle).
fn write_nod(path: &Path) {
    let mut cfg = SimConfig::default();
    let l = &mut cfg.lrf;
    (l.beams, l.angle_min_deg, l.angle_increment_deg) = (1024, -180.0, 360.0 / 1024.0);
    (l.servo_start_deg, l.servo_end_deg, l.servo_step_deg) = (-18.0, 18.0, 0.2);
    l.servo_passes = 2;
    l.mount_offset_mm = [10.0, 5.0, 20.0];
    (l.mount_tilt_x_deg, l.mount_tilt_z_deg, l.range_offset_mm) = (0.8, -0.6, 20.0);
    let sim = Simulation::new(&cfg, 1).unwrap();
    let file = std::fs::File::create(path).unwrap();
    write_scans_csv(std::io::BufWriter::new(file), &sim.scans, &cfg.lrf).unwrap();
}

/// The nod's walls are found (no "no wall"), the sweep is named, and every parameter has a
/// σ or a reason naming the nod.
#[test]
fn a_nod_gives_each_parameter_a_sigma_or_the_reason_its_sweep_does_not() {
    let d = temp("nod");
    let scans = d.join("nod.csv");
    write_nod(&scans);
    let out = d.join("mount.json");
    let (ok, stdout, stderr) =
        lrf_mount(&[scans.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert!(ok, "{stdout}{stderr}");
    assert!(
        stdout.starts_with("sweep: a ±18.0° nod (servo -18.0…18.0°)"),
        "{stdout}"
    );
    for name in [
        "offset_x",
        "offset_z",
        "tilt_x",
        "tilt_z",
        "servo_scale",
        "range_offset",
    ] {
        let line = stdout.lines().find(|l| l.starts_with(name)).unwrap();
        assert!(
            line.contains(" ± ") || line.contains("held: the sweep is a ±18.0° nod"),
            "{line}"
        );
    }
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    // the servo's readings, quantised to the encoder's 0.088°
    let sweep = json["sweep_deg"].as_array().unwrap();
    assert!((sweep[0].as_f64().unwrap() + 18.0).abs() < 0.1, "{sweep:?}");
    assert!((sweep[1].as_f64().unwrap() - 18.0).abs() < 0.1, "{sweep:?}");
    let _ = std::fs::remove_dir_all(&d);
}

/// A point cloud has no readings; a cloud of scattered ranges has no plane: each refusal
/// says which, in one line naming the file.
#[test]
fn refusals_name_what_the_scans_lack() {
    let d = temp("refusals");
    let xyz = d.join("cloud.xyz");
    std::fs::write(&xyz, "1000 0 0\n0 1000 0\n0 0 1000\n1000 1000 0\n").unwrap();
    let (ok, _, err) = lrf_mount(&[xyz.to_str().unwrap()]);
    assert!(
        !ok && err.contains("cloud.xyz: a point cloud: lrf-mount needs the scans"),
        "{err}"
    );
    // ranges drawn at random over 0.5–4 m: points in a volume, no surface
    let mut text = String::from(
        "# pingcal-scan v1\n# angle_min_deg=-45\n# angle_increment_deg=0.9\n# range_unit=mm\nstamp_s,servo_deg",
    );
    for i in 0..100 {
        text += &format!(",r{i}");
    }
    let mut x: u64 = 12345;
    for k in 0..200 {
        text += &format!("\n{:.1},{:.1}", k as f64 * 0.1, -90.0 + 0.9 * k as f64);
        for _ in 0..100 {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            text += &format!(",{}", 500 + (x >> 33) % 3500);
        }
    }
    text += "\n";
    let scans = d.join("scattered.csv");
    std::fs::write(&scans, text).unwrap();
    let (ok, _, err) = lrf_mount(&[scans.to_str().unwrap()]);
    assert!(
        !ok && err.contains(
            "scattered.csv: no wall, floor or ceiling was found in the cloud's 20000 points"
        ) && err.lines().count() == 1,
        "{err}"
    );
    // the options, each refused for what it names, before any work
    let model = d.join("nomodel.json");
    std::fs::write(&model, "{\"a\": 1}\n").unwrap();
    let s = scans.to_str().unwrap();
    let cases: [(Vec<&str>, &str); 4] = [
        (
            vec![s, "--lrf-model", model.to_str().unwrap()],
            "nomodel.json: no `lrf_model` block",
        ),
        (
            vec![s, "--out", d.to_str().unwrap()],
            "is a folder, expected a file name",
        ),
        (
            vec![s, "--noise", "FOO"],
            "--noise: unknown noise profile \"FOO\"",
        ),
        (vec!["missing.csv"], "missing.csv: No such file"),
    ];
    for (args, cause) in cases {
        let (ok, _, err) = lrf_mount(&args);
        assert!(
            !ok && err.contains(cause) && err.lines().count() == 1,
            "{args:?}: {err}"
        );
    }
    let _ = std::fs::remove_dir_all(&d);
}
