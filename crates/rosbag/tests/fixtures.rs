//! The bags of `tests/data/`, written by an independent writer (the `rosbags` Python
//! package, `tests/rosbag/make_fixtures.sh`) from the scans in `tests/data/scans.csv`:
//! every format must decode to those scans and the same cloud, and bad input must give a
//! one-line error naming the file and the topic.

use pingcal_lrf::cloud::{Cloud, MountModel};
use pingcal_lrf::scan::{open_scan_file, ScanHeader, ScanLine};
use pingcal_rosbag::assemble::{read_scans, Assembled, ServoMotion, ServoSource, Stamps, Topics};
use pingcal_rosbag::{Bag, RosbagError};
use std::path::{Path, PathBuf};

const BAGS: [&str; 8] = [
    "ros1.bag",
    "ros1_bz2.bag",
    "ros1_lz4.bag",
    "ros2.db3",
    "ros2.mcap",
    "ros2_be.mcap",
    "ros2_zstd.mcap",
    "ros2_lz4.mcap",
];

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

fn joint(name: &str) -> Topics {
    Topics {
        scan: "/scan".into(),
        servo: "/joint_states".into(),
        source: ServoSource::Joint(name.into()),
        stamps: Stamps::Auto,
    }
}

fn ticks() -> Topics {
    Topics {
        scan: "/scan".into(),
        servo: "/servo_ticks".into(),
        source: ServoSource::Numeric {
            scale: 0.087890625,
            offset: -180.0,
        },
        stamps: Stamps::Auto,
    }
}

fn tf() -> Topics {
    Topics {
        scan: "/scan".into(),
        servo: "/tf".into(),
        source: ServoSource::Tf {
            child: "servo_link".into(),
            axis: [0.0, 1.0, 0.0],
        },
        stamps: Stamps::Auto,
    }
}

type Scans = (Option<ScanHeader>, Vec<ScanLine>, Assembled);

fn read(paths: &[PathBuf], topics: &Topics) -> Result<Scans, RosbagError> {
    read_as(paths, topics, ServoMotion::Auto)
}

fn read_as(paths: &[PathBuf], topics: &Topics, motion: ServoMotion) -> Result<Scans, RosbagError> {
    let bags = paths
        .iter()
        .map(|p| Bag::open(p))
        .collect::<Result<Vec<_>, _>>()?;
    let mut header = None;
    let mut lines = Vec::new();
    let done = read_scans(&bags, topics, motion, &mut |h, l| {
        header = Some(*h);
        lines.push(l);
        Ok(())
    })?;
    Ok((header, lines, done))
}

fn csv() -> (ScanHeader, Vec<ScanLine>) {
    let r = open_scan_file(&data("scans.csv")).unwrap();
    let h = r.header();
    (h, r.map(Result::unwrap).collect())
}

fn max_abs(a: impl Iterator<Item = f64>) -> f64 {
    a.fold(0.0, |m, x| m.max(x.abs()))
}

#[test]
fn every_format_gives_the_csv_scans_and_cloud() {
    let (h, want) = csv();
    let mount = MountModel::default();
    let want_cloud = Cloud::from_scans(&h, want.iter().cloned().map(Ok), &mount).unwrap();
    for name in BAGS {
        for topics in [joint("servo"), ticks(), tf()] {
            let (got_h, got, done) = read(&[data(name)], &topics).unwrap();
            let got_h = got_h.map(|g| ScanHeader {
                time_increment_s: None,
                ..g
            });
            assert_eq!(got_h, Some(h), "{name}");
            assert_eq!(
                (done.scans, done.before_servo, done.after_servo),
                (want.len() as u64, 0, 0),
                "{name}"
            );
            assert_eq!(
                done.motion,
                ServoMotion::StopAndGo,
                "{name}: {}",
                done.motion_reason
            );
            // every no-return of the CSV is an inf, a NaN or a 0 in the bag, in turn
            let zeros = want
                .iter()
                .flat_map(|l| &l.ranges_mm)
                .filter(|r| **r == 0.0)
                .count();
            let m = done.masked;
            assert_eq!(
                (m.total(), m.below_min, m.above_max),
                (zeros as u64, 0, 0),
                "{name}"
            );
            assert!(m.inf > 0 && m.nan > 0 && m.zero > 0, "{name}: {m:?}");
            assert_eq!(got.len(), want.len(), "{name}");
            for (g, w) in got.iter().zip(&want) {
                // the CSV's 3-decimal stamps around 1.7e9 s are f64 values 2.4e-7 s apart
                assert!(
                    (g.stamp_s - w.stamp_s).abs() <= 2.4e-7,
                    "{name}: {} {}",
                    g.stamp_s,
                    w.stamp_s
                );
                assert!((g.servo_deg - w.servo_deg).abs() < 1e-9, "{name}");
                assert!(
                    (g.servo_end_deg.unwrap() - w.servo_deg).abs() < 1e-9,
                    "{name}"
                );
                let d = max_abs(g.ranges_mm.iter().zip(&w.ranges_mm).map(|(a, b)| a - b));
                assert!(d <= 1e-9, "{name}: ranges differ by {d} mm");
            }
            let cloud = Cloud::from_scans(&h, got.into_iter().map(Ok), &mount).unwrap();
            assert_eq!(cloud.len(), want_cloud.len(), "{name}");
            let d = max_abs(
                cloud
                    .points
                    .iter()
                    .zip(&want_cloud.points)
                    .map(|(a, b)| (a - b).norm()),
            );
            assert!(d <= 1e-9, "{name}: the cloud differs by {d} mm");
        }
    }
}

/// A continuous sweep: the servo turns at 30°/s while it scans; each scan's first and last
/// beam get the ramp's angle at their own time (sweep.csv, written from the ramp).
#[test]
fn a_continuous_sweep_gives_each_beam_its_time_s_servo_angle() {
    let r = open_scan_file(&data("sweep.csv")).unwrap();
    let h = r.header();
    let want: Vec<ScanLine> = r.map(Result::unwrap).collect();
    let (got_h, got, done) = read(&[data("sweep.mcap")], &joint("servo")).unwrap();
    assert_eq!(
        (got_h.map(|g| g.angle_min_deg), done.scans),
        (Some(h.angle_min_deg), 2)
    );
    assert_eq!(
        done.motion,
        ServoMotion::Continuous,
        "{}",
        done.motion_reason
    );
    for (g, w) in got.iter().zip(&want) {
        assert!(
            (g.servo_deg - w.servo_deg).abs() < 1e-9,
            "{} {}",
            g.servo_deg,
            w.servo_deg
        );
        let (ge, we) = (g.servo_end_deg.unwrap(), w.servo_end_deg.unwrap());
        assert!((ge - we).abs() < 1e-9, "{ge} {we}");
        assert!(
            ge - g.servo_deg > 1.9,
            "the servo turned ~2° during the scan"
        );
        assert_eq!(g.ranges_mm, w.ranges_mm);
    }
    let mount = MountModel::default();
    let a = Cloud::from_scans(&h, got.into_iter().map(Ok), &mount).unwrap();
    let b = Cloud::from_scans(&h, want.into_iter().map(Ok), &mount).unwrap();
    let d = max_abs(a.points.iter().zip(&b.points).map(|(p, q)| (p - q).norm()));
    assert!(a.len() == b.len() && d < 1e-6, "{d} mm");
}

#[test]
fn topics_are_listed_with_types_and_counts() {
    for name in BAGS {
        let bag = Bag::open(&data(name)).unwrap();
        let list: Vec<(String, String, u64)> = bag
            .topics()
            .unwrap()
            .into_iter()
            .map(|t| (t.name, t.msg_type, t.count))
            .collect();
        let want = [
            ("/empty", "std_msgs/Float64", 0),
            ("/joint_states", "sensor_msgs/JointState", 10),
            ("/scan", "sensor_msgs/LaserScan", 5),
            ("/servo_ticks", "std_msgs/Float64", 10),
            ("/tf", "tf2_msgs/TFMessage", 10),
        ];
        let want: Vec<_> = want
            .iter()
            .map(|(a, b, c)| (a.to_string(), b.to_string(), *c))
            .collect();
        assert_eq!(list, want, "{name}");
    }
}

/// The error of reading `path` with `topics`, checked to be one line naming the file.
fn error(path: &Path, topics: &Topics) -> String {
    let Err(e) = read(&[path.to_path_buf()], topics) else {
        panic!("{}: read without an error", path.display())
    };
    let e = e.to_string();
    assert!(!e.contains('\n'), "{e}");
    assert!(e.starts_with(&path.display().to_string()), "{e}");
    e
}

#[test]
fn missing_and_mistyped_topics_name_the_file_and_topic() {
    for name in BAGS {
        let p = data(name);
        let t = Topics {
            servo: "/servo".into(),
            ..joint("servo")
        };
        let e = error(&p, &t);
        assert!(e.contains("topic /servo is not in the bag (topics present: /empty (std_msgs/Float64), /joint_states (sensor_msgs/JointState), /scan (sensor_msgs/LaserScan), /servo_ticks"), "{e}");
        let t = Topics {
            scan: "/joint_states".into(),
            ..joint("servo")
        };
        let e = error(&p, &t);
        assert!(
            e.ends_with(
                "topic /joint_states is sensor_msgs/JointState, expected sensor_msgs/LaserScan"
            ),
            "{e}"
        );
        let t = Topics {
            servo: "/scan".into(),
            ..ticks()
        };
        let e = error(&p, &t);
        assert!(e.contains("topic /scan is sensor_msgs/LaserScan, expected std_msgs/Float32 or std_msgs/Float64"), "{e}");
        let t = Topics {
            servo: "/empty".into(),
            ..ticks()
        };
        let e = error(&p, &t);
        assert!(e.ends_with("topic /empty: no messages on the topic"), "{e}");
        let e = error(&p, &joint("tilt"));
        assert!(e.contains("topic /joint_states: no joint named \"tilt\" in its 10 JointState messages (joints there: \"pan\", \"servo\")"), "{e}");
    }
}

fn mutated(name: &str, tag: &str, f: impl Fn(&mut Vec<u8>)) -> PathBuf {
    let mut b = std::fs::read(data(name)).unwrap();
    f(&mut b);
    let dir = std::env::temp_dir().join(format!("pingcal-rosbag-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(format!("{tag}-{name}"));
    std::fs::write(&p, b).unwrap();
    p
}

#[test]
fn truncated_bags_and_corrupt_chunks_are_one_line_errors() {
    for name in BAGS {
        let p = mutated(name, "half", |b| b.truncate(b.len() / 2));
        let e = error(&p, &joint("servo"));
        println!("{e}");
    }
    let p = mutated("ros1.bag", "cut", |b| b.truncate(b.len() - 3000));
    let e = error(&p, &joint("servo"));
    assert!(e.contains("truncated in the record at byte"), "{e}");
    // The chunk record starts at byte 4109 (after the bag header record and its padding),
    // its data at 4158. bz2 has block CRCs: a flip anywhere is found. The LZ4 frames
    // `rosbags` writes have no checksum, so only a flip in their structure is (here its
    // magic number); ROS 1 bags have no checksum of their own.
    for (name, at) in [("ros1_bz2.bag", 5000), ("ros1_lz4.bag", 4158)] {
        let p = mutated(name, "flip", |b| {
            for x in &mut b[at..at + 16] {
                *x ^= 0x5a;
            }
        });
        let e = error(&p, &joint("servo"));
        let kind = &name[5..8];
        assert!(
            e.contains(&format!(": chunk at byte 4109: {kind} data")),
            "{e}"
        );
    }
}

mod never_panic {
    use super::*;
    use proptest::prelude::*;

    fn exercise(p: &Path) {
        if let Ok(bag) = Bag::open(p) {
            let _ = bag.topics();
        }
        let _ = read(&[p.to_path_buf()], &joint("servo"));
        let _ = read(&[p.to_path_buf()], &ticks());
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 256, failure_persistence: None, ..ProptestConfig::default() })]
        #[test]
        fn truncated_or_flipped_bags_never_panic(
            which in 0..BAGS.len(),
            cut in 0.0..1.0f64,
            flips in proptest::collection::vec((0.0..1.0f64, 1u8..=255), 0..8),
        ) {
            let name = BAGS[which];
            let p = mutated(name, "prop", |b| {
                let n = b.len();
                for (at, x) in &flips {
                    let i = ((*at * n as f64) as usize).min(n - 1);
                    b[i] ^= x;
                }
                if flips.is_empty() {
                    b.truncate((cut * n as f64) as usize);
                }
            });
            exercise(&p);
        }
    }
}

/// Issue 37: bags as drivers write them (`drivers.bag`, `drivers.db3`, written by `rosbags`
/// with `make_fixtures.py --drivers`; `drivers.json` says what they hold).
mod drivers {
    use super::*;
    use pingcal_rosbag::assemble::Masked;
    use serde_json::Value;

    const TICK: f64 = 0.087890625;

    fn json(name: &str) -> Value {
        serde_json::from_str(&std::fs::read_to_string(data(name)).unwrap()).unwrap()
    }

    fn servos() -> [(Topics, f64); 3] {
        let topics = |servo: &str, source| Topics {
            scan: "/scan".into(),
            servo: servo.into(),
            source,
            stamps: Stamps::Auto,
        };
        [
            (
                topics("/joint_states", ServoSource::Joint("tilt".into())),
                0.0,
            ),
            (
                topics(
                    "/servo_int",
                    ServoSource::Numeric {
                        scale: TICK,
                        offset: -180.0,
                    },
                ),
                0.0,
            ),
            (
                topics(
                    "/tf",
                    ServoSource::Tf {
                        child: "servo_link".into(),
                        axis: [0.0, 1.0, 0.0],
                    },
                ),
                1e-9,
            ),
        ]
    }

    /// Empty scans, NaN/±inf/0/out-of-range ranges, changing beam counts, intensities, a
    /// repeated and a backward stamp, the servo from a JointState, an Int32 and tf: every
    /// count named, every other scan and range equal to the source (ranges to 0.01 mm,
    /// servo angles exactly, the tf's through its quaternion to 1e-9°).
    #[test]
    fn driver_bags_give_every_scan_with_the_counts_named() {
        let want = json("drivers.json");
        let scans = want["scans"].as_array().unwrap();
        let c = &want["masked"];
        let masked = Masked {
            zero: c["zero"].as_u64().unwrap(),
            nan: c["nan"].as_u64().unwrap(),
            inf: c["inf"].as_u64().unwrap(),
            below_min: c["below_min"].as_u64().unwrap(),
            above_max: c["above_max"].as_u64().unwrap(),
            under_20mm: 0,
        };
        for bag in ["drivers.bag", "drivers.db3"] {
            for (topics, tol) in servos() {
                let (_, got, done) = read(&[data(bag)], &topics).unwrap();
                let what = format!("{bag} {}", topics.servo);
                assert_eq!(
                    done.motion,
                    ServoMotion::StopAndGo,
                    "{what}: {}",
                    done.motion_reason
                );
                assert_eq!(done.scans, scans.len() as u64, "{what}");
                assert_eq!(done.empty_scans, want["empty"].as_u64().unwrap(), "{what}");
                assert_eq!(done.masked, masked, "{what}");
                assert_eq!(
                    (done.repeated_stamps, done.backward_stamps),
                    (
                        want["repeated"].as_u64().unwrap(),
                        want["backward"].as_u64().unwrap()
                    ),
                    "{what}"
                );
                assert_eq!(done.with_intensities, scans.len() as u64, "{what}");
                assert!(
                    done.geometry_changes >= 15,
                    "{what}: {}",
                    done.geometry_changes
                );
                assert_eq!((done.before_servo, done.after_servo), (0, 0), "{what}");
                for (g, w) in got.iter().zip(scans) {
                    let k = w["message"].as_u64().unwrap();
                    assert_eq!(g.line as u64, k + 1, "{what}");
                    assert_eq!(
                        (g.stamp_s * 1e9).round() as i64 / 1000,
                        w["stamp_ns"].as_i64().unwrap() / 1000,
                        "{what} scan {k}"
                    );
                    let deg = w["servo_deg"].as_f64().unwrap();
                    assert!(
                        (g.servo_deg - deg).abs() <= tol && g.servo_end_deg == Some(g.servo_deg),
                        "{what} scan {k}: {} {deg}",
                        g.servo_deg
                    );
                    let r = w["ranges_m"].as_array().unwrap();
                    assert_eq!(g.ranges_mm.len(), r.len(), "{what} scan {k}");
                    for (mm, m) in g.ranges_mm.iter().zip(r) {
                        match m.as_f64() {
                            None => assert_eq!(*mm, 0.0, "{what} scan {k}"),
                            Some(m) => assert!(
                                (mm - m * 1000.0).abs() <= 0.01,
                                "{what} scan {k}: {mm} {m}"
                            ),
                        }
                    }
                    let i: Vec<f32> = w["intensities"]
                        .as_array()
                        .unwrap()
                        .iter()
                        .map(|v| v.as_f64().unwrap() as f32)
                        .collect();
                    assert_eq!(g.intensities, i, "{what} scan {k}");
                }
            }
        }
    }

    /// `dup.db3`: 8 scans and their servo messages, every message stored twice.
    #[test]
    fn a_bag_with_every_message_stored_twice_gives_each_scan_once() {
        for (topics, _) in servos() {
            let (_, got, done) = read(&[data("dup.db3")], &topics).unwrap();
            assert_eq!((got.len(), done.scans), (8, 8), "{}", topics.servo);
            assert_eq!(done.duplicate_scans, 8, "{}", topics.servo);
            assert_eq!(done.duplicate_servo, 8, "{}", topics.servo);
            assert_eq!(
                done.motion,
                ServoMotion::StopAndGo,
                "{}",
                done.motion_reason
            );
        }
    }

    /// A stop-and-go servo whose message comes 10 ms or 50 ms before each scan: `auto`
    /// picks stop-and-go and every scan has the servo's rest angle exactly; interpolating
    /// instead (`continuous`) would move it by step · lead / period.
    #[test]
    fn stop_and_go_holds_the_rest_angle_whatever_the_lead() {
        let want = json("stopgo.json");
        let rest: Vec<f64> = want["rest_deg"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        for lead in [0.010, 0.050] {
            let bag = data(&format!("stopgo_{}ms.mcap", (lead * 1000.0) as u32));
            let (_, got, done) = read(std::slice::from_ref(&bag), &joint("servo")).unwrap();
            assert_eq!(
                done.motion,
                ServoMotion::StopAndGo,
                "{lead}: {}",
                done.motion_reason
            );
            assert!(
                done.motion_reason.contains("before each scan"),
                "{}",
                done.motion_reason
            );
            let angles: Vec<f64> = got.iter().map(|l| l.servo_deg).collect();
            assert_eq!(angles, rest, "{lead}");
            let (_, interp, _) = read_as(&[bag], &joint("servo"), ServoMotion::Continuous).unwrap();
            let step = 2.0 * TICK;
            for (l, r) in interp.iter().zip(&rest) {
                let moved = l.servo_deg - r;
                assert!((moved - step * lead / 0.1).abs() < 1e-9, "{lead}: {moved}");
            }
        }
    }

    /// A continuous sweep (30°/s, JointState at 50 Hz): `auto` picks continuous, and each
    /// scan's first and last beam get the ramp's angle at their own time.
    #[test]
    fn a_continuous_sweep_is_told_and_interpolated_at_each_beam_s_time() {
        let (h, got, done) = read(&[data("sweep_cont.mcap")], &joint("servo")).unwrap();
        assert_eq!(
            done.motion,
            ServoMotion::Continuous,
            "{}",
            done.motion_reason
        );
        assert_eq!(done.scans, 24);
        let ti = h.unwrap().time_increment_s.unwrap();
        assert_eq!(ti, 0.0025);
        for (k, l) in got.iter().enumerate() {
            let t = 0.005 + 0.1 * k as f64;
            let ramp = |t: f64| -10.0 + 30.0 * t;
            assert!((l.servo_deg - ramp(t)).abs() < 1e-9, "{k}: {}", l.servo_deg);
            let end = l.servo_end_deg.unwrap();
            // the message's time_increment is the float32 nearest 2.5 ms
            let ti32 = f64::from(0.0025f32);
            assert!((end - ramp(t + 19.0 * ti32)).abs() < 1e-9, "{k}: {end}");
        }
    }
}
