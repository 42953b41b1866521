//! Real recordings as they come (issue 53): unit slips in a scan file found when the
//! project is loaded, before the camera side runs; text files cut short refused naming the
//! file and the line; bags whose values a scan file cannot hold refused at conversion.

use crate::common::Work;
use std::path::Path;

/// The scan file `path` with `f` applied to each scan line's fields (stamp, servo, ranges):
/// the header lines as they are.
fn mutate_scans(path: &Path, f: impl Fn(&mut Vec<String>)) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut out = String::with_capacity(text.len());
    for line in text.lines() {
        if line.starts_with('#') || line.starts_with("stamp_s") || line.trim().is_empty() {
            out.push_str(line);
        } else {
            let mut fields: Vec<String> = line.split(',').map(str::to_string).collect();
            f(&mut fields);
            out.push_str(&fields.join(","));
        }
        out.push('\n');
    }
    std::fs::write(path, out).unwrap();
}

/// A change to a scan line's fields.
type Mutation = fn(&mut Vec<String>);

/// The demo's scan file (a simulated project's, v1) with its servo column in radians, and
/// with its ranges in metres: `pingcal calibrate` refuses each when it loads the project
/// (one error line, no output folder: the camera side never ran) and `pingcal cloud`
/// refuses the file, each message naming the likely unit and the file.
#[test]
fn unit_slips_in_a_scan_file_are_refused_at_load_naming_the_unit() {
    let w = Work::new("unit_slips");
    let cases: [(&str, Mutation, [&str; 2]); 2] = [
        (
            "radians",
            |f| {
                let deg: f64 = f[1].parse().unwrap();
                f[1] = format!("{:.6}", deg.to_radians());
            },
            [
                "the servo angles span -3.14…3.14: radians?",
                "the scan file's column is degrees",
            ],
        ),
        (
            "metres",
            |f| {
                for r in &mut f[2..] {
                    let mm: f64 = r.parse().unwrap();
                    *r = format!("{}", mm / 1000.0);
                }
            },
            [
                "every range is under 20 mm, the largest ",
                ": metres? the file says range_unit=mm",
            ],
        ),
    ];
    for (name, f, needles) in cases {
        let p = w.quick_project(name);
        let scans = p.join("scans/S00.csv");
        mutate_scans(&scans, f);
        let t0 = std::time::Instant::now();
        let err = w.calibrate_fails(&p, "input", &needles);
        eprintln!(
            "{name}: refused by calibrate in {:.2} s",
            t0.elapsed().as_secs_f64()
        );
        assert!(err.contains("S00.csv"), "{err}");
        let run = w.run(&["cloud", scans.to_str().unwrap()]);
        assert!(!run.success(), "{}", run.stdout);
        let last = run.stderr.trim().lines().last().unwrap_or("");
        for n in needles.iter().chain(&["S00.csv"]) {
            assert!(last.contains(n), "{n:?} not in {last}");
        }
    }
}

/// A text file of a cloud or of scans whose last line was cut in the middle of a number is
/// refused naming the file and the line (it was read as far as it went): a scan CSV, an
/// XYZ, an ascii PCD and an ascii PLY, through `pingcal cloud`; the same files whole are read.
#[test]
fn a_text_file_cut_mid_number_is_refused_naming_the_file_and_line() {
    let w = Work::new("cut_short");
    let scan = "# pingcal-scan v1\n# angle_min_deg=-10\n# angle_increment_deg=10\n# range_unit=mm\nstamp_s,servo_deg,r0,r1,r2\n0.0,0,1000,1010,1020\n0.1,1,1001,1011,1021\n";
    let xyz = "1000 0 0\n0 1000 0\n0 0 1000\n1000 1000 0\n";
    let pcd = "VERSION .7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 4\nHEIGHT 1\nPOINTS 4\nDATA ascii\n1000 0 0\n0 1000 0\n0 0 1000\n1000 1000 0\n";
    let ply = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nend_header\n1000 0 0\n0 1000 0\n0 0 1000\n1000 1000 0\n";
    for (name, whole, line) in [
        ("s.csv", scan, 7),
        ("c.xyz", xyz, 4),
        ("c.pcd", pcd, 13),
        ("c.ply", ply, 11),
    ] {
        let p = w.dir.join(name);
        std::fs::write(&p, whole).unwrap();
        let run = w.run(&["cloud", p.to_str().unwrap()]);
        assert!(run.success(), "{name}: {}", run.stderr);
        // cut two characters before the end: mid-number, no line break
        std::fs::write(&p, &whole[..whole.len() - 3]).unwrap();
        let run = w.run(&["cloud", p.to_str().unwrap()]);
        assert!(!run.success(), "{name}: {}", run.stdout);
        let want = format!(
            "{}:{line}: the last line does not end with a line break: the file was cut short",
            p.display()
        );
        assert!(run.stderr.contains(&want), "{name}: {}", run.stderr);
    }
}

/// The bags `pingcal scans` used to convert into files its own readers refuse
/// (`../shared/data/bad-inputs`): refused at conversion, naming the message and the value;
/// and the real VLP-16 frame cut mid-number refused naming its line.
#[test]
fn bags_with_values_no_scan_file_holds_are_refused_naming_the_value() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/bad-inputs");
    if !dir.is_dir() {
        println!("skipped: {} is absent", dir.display());
        return;
    }
    let w = Work::new("bad_bags");
    let out = w.dir.join("o.csv");
    for (bag, want) in [
        (
            "bag_angle_increment_1e30_written_by_scans.db3",
            "no scan a scan file can hold: 20 scan(s) with an angle or a step beyond a turn (the first: message 0: angle_min -1 rad, angle_increment 1e30 rad over 100 beams)",
        ),
        (
            "bag_servo_1e300_written_by_scans.mcap",
            "no servo angle a scan file can hold: 20 value(s) not a number or beyond ±1e6° (the first: message 0: 1e300)",
        ),
        (
            "bag_servo_nan_written_by_scans.db3",
            "no servo angle a scan file can hold: 20 value(s) not a number or beyond ±1e6° (the first: message 0: NaN)",
        ),
    ] {
        let b = dir.join(bag);
        let run = w.run(&[
            "scans",
            b.to_str().unwrap(),
            "--scan-topic",
            "/scan",
            "--servo-topic",
            "/servo",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(!run.success(), "{bag}: {}", run.stdout);
        assert!(
            run.stderr.contains(bag) && run.stderr.contains(want),
            "{bag}: {}",
            run.stderr
        );
        assert!(!out.exists(), "{bag}: a file was written");
    }
    let xyz = dir.join("xyz_cut_mid_number_loses_74pct_silently.xyz");
    let run = w.run(&[
        "cloud",
        xyz.to_str().unwrap(),
        "--unit",
        "m",
        "--diameter-mm",
        "600",
        "--noise",
        "VLP-16",
    ]);
    assert!(!run.success());
    assert!(
        run.stderr
            .contains("xyz_cut_mid_number_loses_74pct_silently.xyz:3620: the last line does not end with a line break"),
        "{}",
        run.stderr
    );
}

/// The simulated project's scans as a bag on two clocks (`make_clock_bags.py --project`:
/// LaserScan header stamps from the scanner's boot, a `std_msgs/Float64` servo without
/// header, record times from 1.7e9 s), read through `[lrf.bag]` with no option about time:
/// the record times are chosen, said in the log, and the calibration is the CSV's to the
/// byte (but the corner baseline's naming of its scan by line or by message).
#[test]
fn a_simulated_bag_on_two_clocks_calibrates_as_its_csv() {
    let py = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../target/rosbags-venv/bin/python");
    let ok = py.is_file()
        && std::process::Command::new(&py)
            .args(["-c", "import rosbags, numpy"])
            .status()
            .is_ok_and(|s| s.success());
    if !ok {
        println!(
            "skipped: no {} with rosbags and numpy (bash tests/rosbag/setup.sh makes it)",
            py.display()
        );
        return;
    }
    let w = Work::new("clocks_sim");
    let p = w.quick_project("project");
    let writer =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/rosbag/make_clock_bags.py");
    let o = std::process::Command::new(&py)
        .arg(&writer)
        .arg("--project")
        .arg(&p)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (run, csv_out) = w.calibrate(&p, &[]);
    assert!(run.success(), "{}", run.stderr);
    let bag_out = w.dir.join("out-bag");
    let toml = p.join("project-clocks.toml");
    let run = w.run(&[
        "calibrate",
        toml.to_str().unwrap(),
        "--out",
        bag_out.to_str().unwrap(),
    ]);
    assert!(run.success(), "{}", run.stderr);
    let log = format!("{}{}", run.stdout, run.stderr);
    assert!(
        log.contains("[lrf.bag] topic /scan: time base: record times (the scans' header stamps are 1.700e9 s behind their record times"),
        "{log}"
    );
    let norm = |dir: &Path| {
        let text = std::fs::read_to_string(dir.join("results.json")).unwrap();
        let mut out = String::new();
        for line in text.lines() {
            // the corner baseline names its scan by file line (CSV) or message (bag)
            match line.split_once("(file line ") {
                Some((head, tail)) => {
                    out.push_str(head);
                    out.push_str(tail.split_once(',').map_or("", |(_, t)| t));
                }
                None => out.push_str(line),
            }
            out.push('\n');
        }
        out
    };
    assert!(norm(&csv_out) == norm(&bag_out), "results.json differ");
}

/// `pingcal calibrate` reads a `pingcal-scan` v4 file, each scan in its own geometry: the
/// project's scans written again as v4, every other scan with one beam more before its
/// first (a no return, the geometry starting one step earlier: a `# geometry` line before
/// each scan), give the calibration of the v1 file to the byte (but the corner baseline's
/// naming of its scan by file line). Read with the file's geometry, every beam of those
/// scans would turn by a step.
#[test]
fn calibrate_reads_a_v4_scan_file_as_the_same_scans() {
    let w = Work::new("v4_calibrate");
    let p = w.quick_project("project");
    let (run, v1_out) = w.calibrate(&p, &[]);
    assert!(run.success(), "{}", run.stderr);
    let scans = p.join("scans/S00.csv");
    let text = std::fs::read_to_string(&scans).unwrap();
    let (mut a0, mut inc, mut k) = (String::new(), String::new(), 0usize);
    let mut out = String::new();
    for line in text.lines() {
        if let Some(v) = line.strip_prefix("# angle_min_deg=") {
            a0 = v.to_string();
        }
        if let Some(v) = line.strip_prefix("# angle_increment_deg=") {
            inc = v.to_string();
        }
        if line == "# pingcal-scan v1" {
            out.push_str("# pingcal-scan v4\n");
        } else if let Some(cols) = line.strip_prefix("stamp_s,servo_deg,") {
            out.push_str(&format!("stamp_s,servo_deg,servo_end_deg,{cols}\n"));
        } else if line.starts_with('#') || line.trim().is_empty() {
            out.push_str(line);
            out.push('\n');
        } else {
            let (stamp, rest) = line.split_once(',').unwrap();
            let (servo, ranges) = rest.split_once(',').unwrap();
            let n = ranges.split(',').count();
            let (first, zero, beams) = if k % 2 == 1 {
                let (a, d): (f64, f64) = (a0.parse().unwrap(), inc.parse().unwrap());
                (format!("{}", a - d), "0,", n + 1)
            } else {
                (a0.clone(), "", n)
            };
            out.push_str(&format!(
                "# geometry angle_min_deg={first} angle_increment_deg={inc} beams={beams}\n{stamp},{servo},{servo},{zero}{ranges}\n"
            ));
            k += 1;
        }
    }
    std::fs::write(&scans, out).unwrap();
    let v4_out = w.dir.join("out-v4");
    let run = w.run(&[
        "calibrate",
        p.join("project.toml").to_str().unwrap(),
        "--out",
        v4_out.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(run.success(), "{}", run.stderr);
    let norm = |dir: &Path| {
        let text = std::fs::read_to_string(dir.join("results.json")).unwrap();
        text.lines()
            .map(|l| match l.split_once("(file line ") {
                Some((head, tail)) => format!("{head}{}", tail.split_once(',').map_or("", |t| t.1)),
                None => l.to_string(),
            })
            .collect::<Vec<_>>()
            .join("\n")
    };
    assert!(norm(&v1_out) == norm(&v4_out), "results.json differ");
}

/// A sphere-calib frame whose cloud was cut mid-number is refused naming the cloud file
/// and its last line (it gave the unchanged verdict and no word).
#[test]
fn a_sphere_calib_cloud_cut_short_is_refused_naming_it() {
    let w = Work::new("sphere_cut");
    let d = w.dir.join("sc");
    let run = w.run(&[
        "simulate",
        "--kind",
        "sphere-calib",
        "--frames",
        "4",
        "--seed",
        "7",
        "--out",
        d.to_str().unwrap(),
    ]);
    assert!(run.success(), "{}", run.stderr);
    let cloud = d.join("clouds/F01.xyz");
    let bytes = std::fs::read(&cloud).unwrap();
    // two thirds in, not just after a line break
    let mut at = bytes.len() * 2 / 3;
    while bytes[at - 1] == b'\n' {
        at -= 1;
    }
    let cut = &bytes[..at];
    std::fs::write(&cloud, cut).unwrap();
    let line = cut.iter().filter(|&&b| b == b'\n').count() + 1;
    let run = w.run(&[
        "sphere-calib",
        d.join("sphere-calib.toml").to_str().unwrap(),
        "--out",
        w.dir.join("out").to_str().unwrap(),
    ]);
    assert!(!run.success(), "{}", run.stdout);
    let want = format!(
        "F01.xyz:{line}: the last line does not end with a line break: the file was cut short"
    );
    assert!(run.stderr.contains(&want), "{want}: {}", run.stderr);
}
