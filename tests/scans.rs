//! `pingcal scans` (issue 16): bags written by an independent writer (the `rosbags` Python
//! package, `tests/rosbag/make_fixtures.sh`) become the scan file they were made from, and
//! the command keeps the other commands' output rule (an earlier file survives a failed
//! run, no partial file is left, an input is never the output).

use pingcal_lrf::cloud::{Cloud, MountModel};
use pingcal_lrf::scan::{open_scan_file, ScanHeader, ScanLine};
use std::path::{Path, PathBuf};
use std::process::Command;

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../rosbag/tests/data")
        .join(name)
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("pingcal-scans-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

fn pingcal(args: &[&str]) -> (bool, String, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_pingcal"))
        .args(args)
        .output()
        .unwrap();
    let text = |b: &[u8]| String::from_utf8_lossy(b).into_owned();
    (o.status.success(), text(&o.stdout), text(&o.stderr))
}

/// `pingcal scans BAG --scan-topic /scan --servo-topic /joint_states --servo-joint servo
/// --out OUT`.
fn scans_by_joint(bag: &Path, out: &Path) -> (bool, String, String) {
    pingcal(&scans_args(bag, "servo", out))
}

/// The arguments of `pingcal scans BAG --scan-topic /scan --servo-topic /joint_states
/// --servo-joint JOINT --out OUT`.
fn scans_args<'a>(bag: &'a Path, joint: &'a str, out: &'a Path) -> Vec<&'a str> {
    vec![
        "scans",
        bag.to_str().unwrap(),
        "--scan-topic",
        "/scan",
        "--servo-topic",
        "/joint_states",
        "--servo-joint",
        joint,
        "--out",
        out.to_str().unwrap(),
    ]
}

fn read(p: &Path) -> (ScanHeader, Vec<ScanLine>) {
    let r = open_scan_file(p).unwrap();
    let h = r.header();
    (h, r.map(Result::unwrap).collect())
}

#[test]
fn every_bag_becomes_the_scan_file_it_was_made_from() {
    let (h, want) = read(&data("scans.csv"));
    let mount = MountModel::default();
    let want_cloud = Cloud::from_scans(&h, want.iter().cloned().map(Ok), &mount).unwrap();
    let servo = [
        vec!["--servo-topic", "/joint_states", "--servo-joint", "servo"],
        vec![
            "--servo-topic",
            "/servo_ticks",
            "--servo-scale",
            "0.087890625",
            "--servo-offset",
            "-180",
        ],
    ];
    for bag in [
        "ros1.bag",
        "ros1_bz2.bag",
        "ros1_lz4.bag",
        "ros2.db3",
        "ros2.mcap",
        "ros2_be.mcap",
        "ros2_zstd.mcap",
        "ros2_lz4.mcap",
    ] {
        for s in &servo {
            let out = tmp(&format!("{bag}.csv"));
            let _ = std::fs::remove_file(&out);
            let b = data(bag);
            let mut args = vec![
                "scans",
                b.to_str().unwrap(),
                "--scan-topic",
                "/scan",
                "--out",
                out.to_str().unwrap(),
            ];
            args.extend(s);
            let (ok, stdout, stderr) = pingcal(&args);
            assert!(ok, "{bag}: {stderr}");
            assert!(
                stdout.starts_with("scans: 5 scans of 682 beams from 1 bag(s)"),
                "{stdout}"
            );
            let text = std::fs::read_to_string(&out).unwrap();
            assert!(text.starts_with("# pingcal-scan v2\n"), "{bag}");
            let (got_h, got) = read(&out);
            // the bag's time_increment is kept (the CSV made the bags has none)
            assert_eq!(got_h.time_increment_s, Some(0.1 / 1024.0), "{bag}");
            let got_h = ScanHeader {
                time_increment_s: None,
                ..got_h
            };
            assert_eq!(got_h, h, "{bag}");
            assert_eq!(got.len(), want.len(), "{bag}");
            for (g, w) in got.iter().zip(&want) {
                assert_eq!(
                    (g.stamp_s, g.servo_deg, &g.ranges_mm),
                    (w.stamp_s, w.servo_deg, &w.ranges_mm),
                    "{bag}"
                );
                assert_eq!(g.servo_end_deg, Some(w.servo_deg), "{bag}");
            }
            let cloud = Cloud::from_scans(&got_h, got.into_iter().map(Ok), &mount).unwrap();
            assert_eq!(cloud.points, want_cloud.points, "{bag}");
        }
    }
}

#[test]
fn list_prints_topics_types_and_counts() {
    let b = data("ros2.mcap");
    let (ok, stdout, stderr) = pingcal(&["scans", b.to_str().unwrap(), "--list"]);
    assert!(ok, "{stderr}");
    let rows: Vec<Vec<&str>> = stdout
        .lines()
        .skip(1)
        .map(|l| l.split_whitespace().collect())
        .collect();
    assert_eq!(rows[3], ["/scan", "sensor_msgs/LaserScan", "5"], "{stdout}");
    assert_eq!(
        rows[1],
        ["/joint_states", "sensor_msgs/JointState", "10"],
        "{stdout}"
    );
    // the joints of a JointState topic and the frames of a tf topic are named
    assert_eq!(rows[2], ["joints:", "pan,", "servo"], "{stdout}");
    assert!(
        stdout.contains("\n    frames: laser_base→servo_link\n"),
        "{stdout}"
    );
    assert_eq!(stdout.lines().last(), Some("scans: 5 topic(s) in 1 bag(s)"));
}

#[test]
fn a_failed_run_keeps_the_earlier_file_and_an_input_is_never_the_output() {
    let out = tmp("kept.csv");
    std::fs::write(&out, "earlier\n").unwrap();
    let b = data("ros1.bag");
    let (ok, _, stderr) = pingcal(&scans_args(&b, "tilt", &out));
    assert!(!ok);
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.contains("ros1.bag: topic /joint_states: no joint named \"tilt\""),
        "{stderr}"
    );
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "earlier\n");
    // its own temporary file is gone (the folder is shared with tests running beside it)
    let partial = out.with_file_name(".kept.csv.partial");
    assert!(!partial.exists(), "{partial:?} left");
    // the bag given as --out is refused before it is touched
    let copy = tmp("copy.bag");
    std::fs::copy(&b, &copy).unwrap();
    let c = copy.to_str().unwrap();
    let (ok, _, stderr) = pingcal(&[
        "scans",
        c,
        "--scan-topic",
        "/scan",
        "--servo-topic",
        "/servo_ticks",
        "--out",
        c,
    ]);
    assert!(!ok);
    assert!(stderr.contains("is one of the bags read"), "{stderr}");
    assert_eq!(std::fs::read(&copy).unwrap(), std::fs::read(&b).unwrap());
}

#[test]
fn a_ros2_bag_folder_reads_its_storage_files() {
    let dir = tmp("bagdir");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::copy(data("ros2.db3"), dir.join("run_0.db3")).unwrap();
    std::fs::write(
        dir.join("metadata.yaml"),
        "rosbag2_bagfile_information: {}\n",
    )
    .unwrap();
    let out = tmp("bagdir.csv");
    let _ = std::fs::remove_file(&out);
    let (ok, stdout, stderr) = scans_by_joint(&dir, &out);
    assert!(ok, "{stderr}");
    assert!(
        stdout.starts_with("scans: 5 scans of 682 beams from 1 bag(s)"),
        "{stdout}"
    );
    let empty = tmp("emptydir");
    std::fs::create_dir_all(&empty).unwrap();
    let (ok, _, stderr) = pingcal(&["scans", empty.to_str().unwrap(), "--list"]);
    assert!(
        !ok && stderr.contains("a directory without .db3 or .mcap files"),
        "{stderr}"
    );
}

/// A driver that changes the beam geometry between messages (`geometry.bag`: A A B A C,
/// `make_fixtures.py`): no scan is lost or resampled; all are in one file (`pingcal-scan`
/// v4), each in its own geometry, every range and servo angle as recorded, and `pingcal
/// cloud` reads it.
#[test]
fn a_changed_beam_geometry_keeps_every_scan_in_one_file() {
    // a folder of its own: the other tests look for .partial files in theirs
    let dir = tmp("geometry");
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("geometry.csv");
    let _ = std::fs::remove_file(&out);
    let b = data("geometry.bag");
    let (ok, stdout, stderr) = scans_by_joint(&b, &out);
    assert!(ok, "{stderr}");
    assert!(
        stdout.starts_with("scans: 5 scans of 10 beams") && stdout.contains("(pingcal-scan v4)"),
        "{stdout}"
    );
    assert!(
        stdout.contains("scans: one file for every beam geometry"),
        "{stdout}"
    );
    // (beams, first angle) of scans k = 0..4 in the bag
    let want: [(usize, f64); 5] = [
        (10, -10.0),
        (10, -10.0),
        (11, -10.0),
        (10, -10.0),
        (10, -5.0),
    ];
    let (h, lines) = read(&out);
    assert_eq!(lines.len(), 5);
    for (k, (l, (n, a0))) in lines.iter().zip(want).enumerate() {
        let g = l.geometry_or(&h);
        assert_eq!(
            (g.angle_min_deg, g.angle_increment_deg),
            (a0, 1.0),
            "scan {k}"
        );
        let ranges: Vec<f64> = (0..n).map(|i| (1000 + 10 * k + i) as f64).collect();
        assert_eq!(l.ranges_mm, ranges, "scan {k}");
        assert!((l.servo_deg - 2.0 * k as f64).abs() < 1e-9, "scan {k}");
    }
    let (ok, stdout, stderr) = pingcal(&["cloud", out.to_str().unwrap()]);
    assert!(
        ok && stdout.starts_with("cloud: 51 points from 1 file(s)"),
        "{stdout}{stderr}"
    );
    let partial = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(Result::ok)
        .any(|e| e.file_name().to_string_lossy().ends_with(".partial"));
    assert!(!partial, "a .partial file was left in {dir:?}");
}

/// `--out` through a symlink replaces the file behind it (the link stays a link), and
/// `/dev/stdout` is written straight, as the other commands' outputs are.
#[test]
fn out_goes_through_a_symlink_and_into_a_device() {
    let dir = tmp("symlinked");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("a")).unwrap();
    std::fs::create_dir_all(dir.join("b")).unwrap();
    std::fs::write(dir.join("b/real.csv"), "earlier\n").unwrap();
    let link = dir.join("a/scans.csv");
    std::os::unix::fs::symlink("../b/real.csv", &link).unwrap();
    let (ok, _, stderr) = scans_by_joint(&data("ros1.bag"), &link);
    assert!(ok, "{stderr}");
    assert!(std::fs::symlink_metadata(&link)
        .unwrap()
        .file_type()
        .is_symlink());
    let (_, lines) = read(&dir.join("b/real.csv"));
    assert_eq!(lines.len(), 5);
    for sub in ["a", "b"] {
        let left: Vec<_> = std::fs::read_dir(dir.join(sub))
            .unwrap()
            .filter_map(Result::ok)
            .filter(|e| e.file_name().to_string_lossy().ends_with(".partial"))
            .collect();
        assert!(left.is_empty(), "{left:?}");
    }
    let (ok, stdout, stderr) = scans_by_joint(&data("ros1.bag"), Path::new("/dev/stdout"));
    assert!(ok, "{stderr}");
    assert!(
        stdout.starts_with("# pingcal-scan v2\n"),
        "{}",
        &stdout[..80.min(stdout.len())]
    );
}

/// Issue 37: a bag as drivers write it (`drivers.db3`: empty scans, NaN/±inf/0 and
/// out-of-range ranges, changing beam counts, intensities, a repeated and a backward
/// stamp; `make_fixtures.py --drivers`): converted with every count named, the
/// intensities in a v3 file; a wrong joint lists the joints there are.
#[test]
fn a_drivers_bag_is_converted_with_the_counts_named() {
    let dir = tmp("drivers");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("drivers.csv");
    let b = data("drivers.db3");
    let args = |joint: &'static str| scans_args(&b, joint, &out);
    let run = |a: Vec<&str>| pingcal(&a);
    let (ok, stdout, stderr) = run(args("tilt"));
    assert!(ok, "{stderr}");
    for want in [
        "2 empty, 0 duplicate(s), 82 ranges masked",
        "scans: servo motion: stop-and-go (one servo message 10.0 ms before each scan",
        "scans: 82 range(s) read as no return: 15 0, 13 NaN, 27 ±inf, 14 under range_min, 13 over range_max",
        "scans: intensities kept for 21 scan(s)",
    ] {
        assert!(stdout.contains(want), "{want}: {stdout}");
    }
    for want in [
        "warning: topic /scan: 2 empty scan(s) (no beams) skipped",
        "warning: topic /scan: 1 scan(s) with the stamp of the scan before them (kept)",
        "warning: topic /scan: 1 scan(s) stamped earlier than the scan before them dropped",
    ] {
        assert!(stderr.contains(want), "{want}: {stderr}");
    }
    // the beam count changes: one file, v4, every scan with its own count and intensities
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(text.starts_with("# pingcal-scan v4\n"), "{text}");
    assert!(text.contains("# time_increment_s=0.0005\n"), "{text}");
    let (_, lines) = read(&out);
    assert_eq!(lines.len(), 21);
    assert!(lines
        .iter()
        .all(|l| l.intensities.len() == l.ranges_mm.len()));
    let counts: std::collections::BTreeSet<usize> =
        lines.iter().map(|l| l.ranges_mm.len()).collect();
    assert!(counts.len() > 1, "{counts:?}");
    let (ok, _, stderr) = run(args("servo"));
    assert!(!ok);
    assert!(
        stderr.contains("no joint named \"servo\" in its 24 JointState messages (joints there: \"pan\", \"tilt\")"),
        "{stderr}"
    );
    // every message stored twice: 8 scans, not 16
    let (ok, stdout, stderr) = pingcal(&[
        "scans",
        data("dup.db3").to_str().unwrap(),
        "--scan-topic",
        "/scan",
        "--servo-topic",
        "/servo_int",
        "--servo-scale",
        "0.087890625",
        "--servo-offset",
        "-180",
        "--out",
        dir.join("dup.csv").to_str().unwrap(),
    ]);
    assert!(ok, "{stderr}");
    let scans: u64 = stdout
        .lines()
        .filter_map(|l| l.strip_prefix("scans: "))
        .filter_map(|l| {
            l.split_once(" scans of ")
                .map(|(n, _)| n.parse::<u64>().unwrap())
        })
        .sum();
    assert_eq!(scans, 8, "{stdout}");
    assert!(stdout.contains("8 duplicate(s)"), "{stdout}");
    assert!(
        stderr.contains("8 scan message(s) stored twice read once"),
        "{stderr}"
    );
}

/// `--servo-motion` overrides `auto`: interpolating a stop-and-go bag moves every angle.
#[test]
fn servo_motion_is_said_and_can_be_given() {
    let out = tmp("stopgo.csv");
    let b = data("stopgo_50ms.mcap");
    let mut args = scans_args(&b, "servo", &out);
    let (ok, stdout, stderr) = pingcal(&args);
    assert!(ok, "{stderr}");
    assert!(
        stdout.contains("servo motion: stop-and-go (one servo message 50.0 ms before each scan"),
        "{stdout}"
    );
    let (_, held) = read(&out);
    args.extend(["--servo-motion", "continuous"]);
    let (ok, stdout, stderr) = pingcal(&args);
    assert!(ok, "{stderr}");
    assert!(
        stdout.contains("servo motion: continuous (as asked)"),
        "{stdout}"
    );
    let (_, moved) = read(&out);
    // the last scan has no servo message after it to interpolate to
    assert_eq!(moved.len() + 1, held.len());
    for (a, b) in moved.iter().zip(&held) {
        assert!(
            (a.servo_deg - b.servo_deg - 0.087890625).abs() < 1e-6,
            "{} {}",
            a.servo_deg,
            b.servo_deg
        );
    }
    let (ok, _, stderr) = pingcal(&[&args[..10], &["--servo-motion", "jerky"]].concat());
    assert!(
        !ok && stderr.contains("expected auto, stop-and-go or continuous"),
        "{stderr}"
    );
}

/// The `rosbags` venv's Python (`tests/rosbag/make_fixtures.sh` makes it), or `None` after
/// printing why the test is skipped.
fn rosbags_python(test: &str) -> Option<PathBuf> {
    let py = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../target/rosbags-venv/bin/python");
    let ok = py.is_file()
        && Command::new(&py)
            .args(["-c", "import rosbags, numpy, PIL"])
            .status()
            .is_ok_and(|s| s.success());
    if !ok {
        println!(
            "{test}: skipped: no {} with rosbags, numpy and pillow (bash tests/rosbag/make_fixtures.sh makes it)",
            py.display()
        );
    }
    ok.then_some(py)
}

/// Issue 37: `pingcal frames` on a bag of PointCloud2 and Image / CompressedImage messages
/// written by `rosbags` from a simulated sphere calibration (`make_frames_bag.py`: each
/// frame still for three messages, then carried on for two) finds the ten still moments,
/// pairs cloud and image, and writes a project that `pingcal sphere-calib` runs as it is,
/// with the result of the frames written directly.
#[test]
fn frames_from_a_bag_make_a_project_sphere_calib_runs() {
    let Some(py) = rosbags_python("frames_from_a_bag_make_a_project_sphere_calib_runs") else {
        return;
    };
    let dir = tmp("frames");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let sim = dir.join("sim");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let (ok, _, stderr) = pingcal(&[
        "simulate",
        "--kind",
        "sphere-calib",
        "--out",
        &s(&sim),
        "--seed",
        "1",
    ]);
    assert!(ok, "{stderr}");
    let (ok, _, stderr) = pingcal(&[
        "sphere-calib",
        &s(&sim.join("sphere-calib.toml")),
        "--accept-doubtful",
    ]);
    assert!(ok, "{stderr}");
    let direct: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(sim.join("results/results.json")).unwrap())
            .unwrap();
    let writer =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/rosbag/make_frames_bag.py");
    for kind in ["raw", "compressed"] {
        let bag = dir.join(format!("{kind}.mcap"));
        let o = Command::new(&py)
            .args([s(&writer), s(&sim), s(&bag), kind.into()])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let out = dir.join(format!("out-{kind}"));
        let (ok, stdout, stderr) = pingcal(&[
            "frames",
            &s(&bag),
            "--cloud-topic",
            "/points",
            "--image-topic",
            "/image",
            "--camera",
            &s(&sim.join("camera.toml")),
            "--sphere-diameter-mm",
            "600",
            "--out",
            &s(&out),
        ]);
        assert!(ok, "{stderr}");
        assert!(
            stdout.starts_with("frames: 10 frames from 50 clouds and 50 images (10 still moment(s) of the clouds, 10 of the images)"),
            "{stdout}"
        );
        // each frame's cloud is one of its still clouds, every point kept, with its
        // intensity and ring
        let listing: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(bag.with_extension("json")).unwrap())
                .unwrap();
        for (k, f) in listing.as_array().unwrap().iter().enumerate() {
            let text =
                std::fs::read_to_string(out.join(format!("clouds/F{:02}.xyz", k + 1))).unwrap();
            let head = text.lines().next().unwrap();
            assert!(head.starts_with("# x y z intensity ring, metres"), "{head}");
            let stamp: i64 = head
                .rsplit("stamp ")
                .next()
                .unwrap()
                .trim_end_matches(" ns)")
                .parse()
                .unwrap();
            let still: Vec<i64> = f["still_ns"]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_i64().unwrap())
                .collect();
            assert!(
                still.contains(&stamp),
                "F{}: {stamp} not in {still:?}",
                k + 1
            );
            assert_eq!(
                text.lines().count() - 1,
                f["points"].as_u64().unwrap() as usize
            );
            // a raw image written as PNG; a compressed one as the PNG it is
            assert!(out.join(format!("images/F{:02}.png", k + 1)).is_file());
        }
        // the verdict (ok or doubtful) is sphere-calib's own business; the frames are ours
        let (ok, stdout, stderr) = pingcal(&[
            "sphere-calib",
            &s(&out.join("sphere-calib.toml")),
            "--accept-doubtful",
        ]);
        assert!(ok, "{kind}: {stderr}");
        assert!(stdout.contains(" 9 of 10 frames; t = "), "{stdout}");
        let got: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(out.join("results/results.json")).unwrap(),
        )
        .unwrap();
        // the bag's clouds carry 3 mm of noise more: the same extrinsic within a few σ
        for i in 0..3 {
            let (a, b) = (
                got["extrinsic"]["translation_mm"][i].as_f64().unwrap(),
                direct["extrinsic"]["translation_mm"][i].as_f64().unwrap(),
            );
            assert!((a - b).abs() < 5.0, "{kind}: t[{i}] {a} against {b}");
        }
    }
}

/// Issue 53: bags written by `rosbags` (`make_clock_bags.py`) of a 360° scanner nodded by a
/// servo, whose scans' header clock is ahead of the record times by 1e9 s, by 0.5 s, equal
/// to them, or counts from the scanner's boot (the bag); the servo a
/// `std_msgs/Int32` with no header, or a JointState stamped on the scans' clock. With no
/// option beyond the topics and the servo's scale and offset, `auto` picks the clock the
/// bag needs and says so; every scan is in one file (v4, the beam count changes from scan
/// to scan) with the source's servo angle and beam angles to 0.001°; and `--stamps header`
/// on the 0.5 s bag shows what the wrong clock gives.
#[test]
fn two_clocks_in_one_bag_are_told_apart() {
    let Some(py) = rosbags_python("two_clocks_in_one_bag_are_told_apart") else {
        return;
    };
    let dir = tmp("clocks");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let writer =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/rosbag/make_clock_bags.py");
    let o = Command::new(&py).arg(&writer).arg(&dir).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let listing: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("clocks.json")).unwrap()).unwrap();
    let int32 = [
        "--servo-topic",
        "/lidar_servo_angle",
        "--servo-scale",
        "1",
        "--servo-offset",
        "-90",
    ];
    let joint = ["--servo-topic", "/joint_states", "--servo-joint", "servo"];
    for (name, case) in listing.as_object().unwrap() {
        let bag = dir.join(name);
        let want = case["scans"].as_array().unwrap();
        for (servo, key) in [(&int32[..], "int32"), (&joint[..], "joint")] {
            let out = dir.join(format!("{name}.{key}.csv"));
            let mut args = vec![
                "scans",
                bag.to_str().unwrap(),
                "--scan-topic",
                "/scan",
                "--out",
                out.to_str().unwrap(),
            ];
            args.extend(servo);
            let (ok, stdout, stderr) = pingcal(&args);
            assert!(ok, "{name} {key}: {stderr}");
            let clock = case[key].as_str().unwrap();
            let said = format!("scans: time base: {clock} ");
            assert!(stdout.contains(&said), "{name} {key}: {stdout}");
            assert!(
                stdout.starts_with(&format!("scans: {} scans of ", want.len()))
                    && stdout.contains("(pingcal-scan v4)"),
                "{name} {key}: {stdout}"
            );
            let (h, got) = read(&out);
            assert_eq!(got.len(), want.len(), "{name} {key}");
            for (k, (g, w)) in got.iter().zip(want).enumerate() {
                let geo = g.geometry_or(&h);
                let deg = |v: &serde_json::Value| v.as_f64().unwrap().to_degrees();
                assert!(
                    (g.servo_deg - w["servo_deg"].as_f64().unwrap()).abs() < 1e-3,
                    "{name} {key} scan {k}: servo {} against {}",
                    g.servo_deg,
                    w["servo_deg"]
                );
                assert!((geo.angle_min_deg - deg(&w["angle_min"])).abs() < 1e-3);
                assert!((geo.angle_increment_deg - deg(&w["angle_increment"])).abs() < 1e-3);
                assert_eq!(g.ranges_mm.len() as u64, w["beams"].as_u64().unwrap());
            }
        }
    }
    // the wrong clock, asked for: the scans take the servo angle of half a second later
    let bag = dir.join("clock_ahead_0.5.mcap");
    let out = dir.join("forced.csv");
    let mut args = vec![
        "scans",
        bag.to_str().unwrap(),
        "--scan-topic",
        "/scan",
        "--out",
        out.to_str().unwrap(),
        "--stamps",
        "header",
    ];
    args.extend(int32);
    let (ok, stdout, stderr) = pingcal(&args);
    assert!(ok, "{stderr}");
    assert!(
        stdout.contains("time base: header stamps (as asked (the servo topic has no header"),
        "{stdout}"
    );
    let (_, got) = read(&out);
    let want = listing["clock_ahead_0.5.mcap"]["scans"].as_array().unwrap();
    let wrong = got
        .iter()
        .zip(want)
        .filter(|(g, w)| (g.servo_deg - w["servo_deg"].as_f64().unwrap()).abs() > 1e-3)
        .count();
    assert!(wrong > got.len() / 2, "{wrong} of {}", got.len());
    let (ok, _, stderr) = pingcal(&[&args[..6], &["--stamps", "sundial"]].concat());
    assert!(
        !ok && stderr.contains("expected auto, header or record"),
        "{stderr}"
    );
    // the converted file of the bag is one file `pingcal cloud` reads
    let (ok, stdout, stderr) = pingcal(&[
        "cloud",
        dir.join("clock_boot.db3.int32.csv").to_str().unwrap(),
    ]);
    assert!(ok, "{stderr}");
    assert!(stdout.starts_with("cloud: "), "{stdout}");
}

/// Issue 53: drivers time their beams in more than one way (`make_clock_bags.py
/// --timing`: a continuous sweep at 30°/s and scans whose `time_increment` is 0.0025 s, 0
/// with a `scan_time` of 0.1 s, −0.0025 s, or the whole scan's 0.05 s, in turn): each scan's
/// first and last beam get the ramp's angle at their own time, every convention is counted
/// in the summary, and the file (v4) keeps each scan's time between beams.
#[test]
fn the_drivers_beam_timings_are_met() {
    let Some(py) = rosbags_python("the_drivers_beam_timings_are_met") else {
        return;
    };
    let dir = tmp("timing");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let writer =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/rosbag/make_clock_bags.py");
    let o = Command::new(&py)
        .arg(&writer)
        .arg("--timing")
        .arg(&dir)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = dir.join("t.csv");
    let (ok, stdout, stderr) = scans_by_joint(&dir.join("timing.mcap"), &out);
    assert!(ok, "{stderr}");
    for want in [
        "servo motion: continuous",
        "6 scan(s) with time_increment 0: the time between beams from scan_time",
        "6 scan(s) with time_increment negative: the beams measured from the last to the first",
        "6 scan(s) with time_increment longer than a scan per beam: taken as the whole scan's time",
    ] {
        assert!(stdout.contains(want), "{want}: {stdout}");
    }
    let (h, got) = read(&out);
    assert_eq!(got.len(), 24);
    let ramp = |t: f64| -10.0 + 30.0 * t;
    let f32s = |v: f32| f64::from(v);
    // seconds between beams, by the scan's convention
    let beam = [
        f32s(0.0025),
        f32s(0.1) * f32s(1f32.to_radians()) / std::f64::consts::TAU,
        -f32s(0.0025),
        f32s(0.05) / 20.0,
    ];
    for (k, l) in got.iter().enumerate() {
        let t = 0.1 + 0.1 * k as f64;
        let b = beam[k % 4];
        assert!((l.servo_deg - ramp(t)).abs() < 1e-6, "{k}: {}", l.servo_deg);
        let end = l.servo_end_deg.unwrap();
        assert!((end - ramp(t + 19.0 * b)).abs() < 1e-6, "{k}: {end}");
        let ti = l.geometry_or(&h).time_increment_s.unwrap();
        assert!((ti - b).abs() < 1e-9, "{k}: {ti} against {b}");
    }
}

/// `--fixed` (issue 50): a fixed LRF's bag, no servo topic: every scan of the bag as read,
/// each at servo 0, with the ranges and stamps the servo read gives the same scans; the
/// file is one a fixed LRF's project takes (its servo never turns) and a rotating one's
/// refuses. A servo flag beside `--fixed` is refused.
#[test]
fn a_fixed_lrfs_bag_gives_its_scans_at_servo_zero() {
    let (_, want) = read(&data("scans.csv"));
    for bag in ["ros1.bag", "ros2.mcap", "ros2.db3"] {
        let out = tmp(&format!("fixed-{bag}.csv"));
        let path = data(bag);
        let args = [
            "scans",
            path.to_str().unwrap(),
            "--scan-topic",
            "/scan",
            "--fixed",
            "--out",
            out.to_str().unwrap(),
        ];
        let (ok, stdout, stderr) = pingcal(&args);
        assert!(ok, "{bag}: {stdout}\n{stderr}");
        assert!(stdout.contains("a fixed LRF: servo 0"), "{stdout}");
        let (_, got) = read(&out);
        assert!(got.len() >= want.len(), "{bag}: {} scans", got.len());
        assert!(got.iter().all(|l| l.servo_deg == 0.0), "{bag}");
        for w in &want {
            let g = (got.iter())
                .find(|g| g.stamp_s == w.stamp_s)
                .unwrap_or_else(|| panic!("{bag}: no scan at {}", w.stamp_s));
            assert_eq!(g.ranges_mm, w.ranges_mm, "{bag} at {}", w.stamp_s);
        }
        let span = pingcal_lrf::scan::check_scan_file(&out)
            .expect("a valid scan file")
            .expect("its servo span");
        assert_eq!(span.kind_slip(true), None, "{bag}");
        assert!(span.kind_slip(false).is_some(), "{bag}");
    }
    let path = data("ros1.bag");
    let out = tmp("fixed-refused.csv");
    let (ok, _, stderr) = pingcal(&[
        "scans",
        path.to_str().unwrap(),
        "--scan-topic",
        "/scan",
        "--fixed",
        "--servo-topic",
        "/joint_states",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!ok && stderr.contains("--fixed"), "{stderr}");
    assert!(!out.exists());
}

/// `--from` / `--to` (issue 50: one station of a robot that stopped at several in one
/// recording): only the scans in the window, in seconds after the bag's first scan; a window
/// that holds none, or ends before it starts, refused in one line.
#[test]
fn a_time_window_takes_one_stations_scans() {
    let path = data("ros1.bag");
    // `pingcal scans ros1.bag --scan-topic /scan --fixed EXTRA… --out OUT`
    let fixed = |extra: &[&str], out: &Path| {
        let head = [
            "scans",
            path.to_str().unwrap(),
            "--scan-topic",
            "/scan",
            "--fixed",
        ];
        let tail = ["--out", out.to_str().unwrap()];
        pingcal(&[&head[..], extra, &tail[..]].concat())
    };
    let all_out = tmp("window-all.csv");
    let (ok, o, e) = fixed(&[], &all_out);
    assert!(ok, "{o}\n{e}");
    let (_, all) = read(&all_out);
    let t0 = all[0].stamp_s;
    let (a, b) = (all[1].stamp_s - t0, all[3].stamp_s - t0);
    let out = tmp("window.csv");
    let (from, to) = (format!("{}", a - 0.01), format!("{}", b + 0.01));
    let (ok, o, e) = fixed(&["--from", &from, "--to", &to], &out);
    assert!(ok, "{o}\n{e}");
    let (_, got) = read(&out);
    let want: Vec<f64> = all[1..=3].iter().map(|l| l.stamp_s).collect();
    assert_eq!(got.iter().map(|l| l.stamp_s).collect::<Vec<_>>(), want);
    let none = tmp("window-none.csv");
    let (ok, _, e) = fixed(&["--from", "100000"], &none);
    assert!(!ok && e.contains("no scan between --from and --to"), "{e}");
    assert!(!none.exists());
    let (ok, _, e) = fixed(&["--from", "5", "--to", "1"], &none);
    assert!(!ok && e.contains("--to 1 is before --from 5"), "{e}");
}
