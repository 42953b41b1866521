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

/// Issue 15: `--balls` through a symlink writes the file behind it, the link stays a link;
/// `/dev/stdout` and a FIFO are written straight, with no temporary file left.
#[cfg(unix)]
#[test]
fn outputs_go_through_symlinks_and_into_devices() {
    let f = pcd("cloud_ascii.pcd");
    let f = f.to_str().unwrap();
    let d = tmp("links");
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(d.join("a")).unwrap();
    std::fs::create_dir_all(d.join("b")).unwrap();
    std::fs::write(d.join("b/balls.txt"), "old").unwrap();
    std::os::unix::fs::symlink("../b/balls.txt", d.join("a/balls.txt")).unwrap();
    let link = d.join("a/balls.txt");
    let (ok, _, err) = run(&["cloud", f, "--unit", "m", "--balls", link.to_str().unwrap()]);
    assert!(ok, "{err}");
    assert!(std::fs::symlink_metadata(&link)
        .unwrap()
        .file_type()
        .is_symlink());
    let text = std::fs::read_to_string(d.join("b/balls.txt")).unwrap();
    assert!(text.starts_with("# pingcal cloud: ball centres"), "{text}");
    let names = |dir: &Path| -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        v.sort();
        v
    };
    assert_eq!(names(&d.join("a")), ["balls.txt"]);
    assert_eq!(names(&d.join("b")), ["balls.txt"]);

    let (ok, out, err) = run(&["cloud", f, "--unit", "m", "--balls", "/dev/stdout"]);
    assert!(ok, "{err}");
    assert!(out.starts_with("# pingcal cloud: ball centres"), "{out}");

    let fifo = d.join("b/fifo");
    assert!(Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap()
        .success());
    let reader = {
        let fifo = fifo.clone();
        std::thread::spawn(move || std::fs::read_to_string(fifo).unwrap())
    };
    let (ok, _, err) = run(&["cloud", f, "--unit", "m", "--balls", fifo.to_str().unwrap()]);
    assert!(ok, "{err}");
    let got = reader.join().unwrap();
    assert!(got.starts_with("# pingcal cloud: ball centres"), "{got}");
    assert_eq!(names(&d.join("b")), ["balls.txt", "fifo"]);
    let _ = std::fs::remove_dir_all(&d);
}
