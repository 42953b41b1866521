//! `pingcal cloud` on clouds from elsewhere (issues 15, 16): a PCD in metres with `--unit m`,
//! the warning when the unit looks wrong, and bad input refused in one line naming the
//! file: no points, NaN or infinite coordinates, a diameter of 0, negative, or larger than
//! the cloud.

use std::path::{Path, PathBuf};
use std::process::Command;

fn pcd(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../lrf/tests/data/pcd")
        .join(name)
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("pingcal-cloud-input-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

/// (exit success, stdout, stderr)
fn run(args: &[&str]) -> (bool, String, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_pingcal"))
        .args(args)
        .output()
        .unwrap();
    (
        o.status.success(),
        String::from_utf8_lossy(&o.stdout).into(),
        String::from_utf8_lossy(&o.stderr).into(),
    )
}

fn refused(args: &[&str], needles: &[&str]) {
    let (ok, out, err) = run(args);
    assert!(!ok, "{args:?} succeeded: {out}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    for n in needles {
        assert!(err.contains(n), "{n:?} not in {err}");
    }
}

#[test]
fn a_pcd_in_metres_reads_with_unit_m_and_warns_without() {
    let f = pcd("cloud_binary_compressed.pcd");
    let f = f.to_str().unwrap();
    let (ok, out, err) = run(&["cloud", f, "--unit", "m"]);
    assert!(ok, "{err}");
    assert!(out.contains("cloud: 18 points from 1 file(s)"), "{out}");
    assert!(!err.contains("probably"), "{err}");
    let (ok, _, err) = run(&["cloud", f]);
    assert!(ok, "{err}");
    assert!(
        err.contains("cloud_binary_compressed.pcd: the cloud is")
            && err.contains("probably metres (--unit m"),
        "{err}"
    );
    assert!(
        err.contains("--diameter-mm 38 is larger than the cloud"),
        "{err}"
    );
    let (ok, _, err) = run(&["cloud", f, "--unit", "cm"]);
    assert!(!ok && err.contains("expected m or mm"), "{err}");
}

#[test]
fn bad_clouds_are_refused_naming_the_file() {
    let empty = tmp("empty.xyz");
    std::fs::write(&empty, "# nothing\n").unwrap();
    refused(
        &["cloud", empty.to_str().unwrap()],
        &["empty.xyz: no points"],
    );
    let nan = tmp("nan.xyz");
    std::fs::write(&nan, "1 2 3\nnan 2 3\n").unwrap();
    refused(
        &["cloud", nan.to_str().unwrap()],
        &["nan.xyz:2: x: expected a number"],
    );
    let inf = tmp("inf.ply");
    std::fs::write(
        &inf,
        "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n1 inf 3\n",
    )
    .unwrap();
    refused(&["cloud", inf.to_str().unwrap()], &["inf.ply:9:"]);
    let all_nan = tmp("nan.pcd");
    std::fs::write(
        &all_nan,
        "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nDATA ascii\nnan nan nan\n",
    )
    .unwrap();
    refused(
        &["cloud", all_nan.to_str().unwrap()],
        &["nan.pcd: no points"],
    );
}

#[test]
fn a_diameter_of_zero_or_negative_is_refused() {
    let f = pcd("cloud.xyz");
    let f = f.to_str().unwrap();
    for d in ["0", "-38"] {
        refused(
            &["cloud", f, "--diameter-mm", d],
            &["--diameter-mm: expected a positive number"],
        );
    }
}
