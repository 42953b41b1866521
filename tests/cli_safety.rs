//! Nothing lost, nothing silent (issue 14): the command line refuses what it would lose or
//! ignore, before any work, in one line naming the path, option or id.
//!
//! - a batch's projects write into distinct folders (or the run is refused), and a failed
//!   re-run leaves the earlier results as they were;
//! - an output folder that cannot be written is refused before the pipeline runs;
//! - negative numbers parse, and `--mount-offset-mm` accepts its shown default;
//! - `ba` refuses the measurement-file options on BAL input, and every `--threads` a count
//!   beyond 1024; on DBAT's files it refuses a missing or malformed camera and a datum
//!   given too little or twice, before solving;
//! - ids given twice are refused (`register`, `targets`, project.toml's `check`);
//! - `calibrate`'s cloud.ply reads back as exactly the scan points.
//!
//! Every test works on its own copy of the simulated project (`tests/e2e/common.rs`).

use crate::common;

use crate::fuzz;

use common::{assert_clean_failure, read_json, Run, Work, OUTPUTS};
use serde_json::Value;
use std::fs;
use std::path::{Path, PathBuf};

/// A path argument.
fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 temp path")
}

/// The context of a run, for assertion messages.
fn ctx(run: &Run) -> String {
    format!(
        "exit {:?}\nstdout: {}\nstderr: {}",
        run.code, run.stdout, run.stderr
    )
}

/// A run that must fail with one `pingcal: error: ` line holding every needle (no output
/// folder to check).
fn fails(run: &Run, needles: &[&str]) -> String {
    let nowhere = Path::new("/nonexistent-pingcal-output");
    assert_clean_failure(run, nowhere, needles)
}

/// Item 1: `a/proj/project.toml` and `b/proj/project.toml` with `--out out` both wrote
/// `out/proj` and both said ok; now each has its folder and its three outputs. The same
/// project file given twice is refused before any work.
#[test]
fn a_batch_writes_each_project_into_its_own_folder() {
    let w = Work::new("batch_distinct");
    let a = w.quick_project("a/proj");
    let b = w.quick_project("b/proj");
    let out = w.dir.join("out");
    let run = w.run(&[
        "calibrate",
        s(&a.join("project.toml")),
        s(&b.join("project.toml")),
        "--out",
        s(&out),
        "--json",
    ]);
    assert!(run.success(), "{}", ctx(&run));
    let lines = run.json_lines();
    assert_eq!(lines.len(), 2, "{}", ctx(&run));
    let mut outs: Vec<String> = lines
        .iter()
        .map(|l| {
            assert_eq!(l["ok"], Value::Bool(true), "{l}");
            l["out"].as_str().expect("out").to_string()
        })
        .collect();
    outs.sort();
    assert_eq!(
        outs,
        [s(&out.join("a-proj")), s(&out.join("b-proj"))],
        "{}",
        ctx(&run)
    );
    for d in ["a-proj", "b-proj"] {
        for f in OUTPUTS {
            assert!(out.join(d).join(f).is_file(), "{d}: no {f}");
        }
        read_json(&out.join(d).join("results.json"));
    }
    assert!(!out.join("proj").exists(), "nothing in the shared out/proj");

    let toml = a.join("project.toml");
    let twice = w.run(&["calibrate", s(&toml), s(&toml), "--out", s(&out), "--quiet"]);
    fails(&twice, &[s(&toml), "given twice"]);
}

/// Item 2: a failing re-run into a folder with good results used to delete them; now they
/// stay byte for byte and the error says so.
#[test]
fn a_failed_rerun_keeps_the_earlier_results() {
    let w = Work::new("failed_rerun");
    let p = w.quick_project("project");
    let out = w.dir.join("out");
    let toml = p.join("project.toml");
    let args = ["calibrate", s(&toml), "--out", s(&out), "--quiet"];
    let first = w.run(&args);
    assert!(first.success(), "{}", ctx(&first));
    let before: Vec<Vec<u8>> = OUTPUTS
        .iter()
        .map(|f| fs::read(out.join(f)).expect("an output"))
        .collect();
    fs::remove_file(p.join("images/S03_left.png")).unwrap();
    let again = w.run(&args);
    let err = fails(&again, &["S03_left.png", "left as they were", s(&out)]);
    eprintln!("{err}");
    for (f, bytes) in OUTPUTS.iter().zip(&before) {
        let now = fs::read(out.join(f)).unwrap_or_else(|e| panic!("{f} is gone: {e}"));
        assert!(now == *bytes, "{f} changed by the failed run");
    }
    let left: Vec<String> = ["", "ros", "opencv", "kalibr"]
        .iter()
        .flat_map(|sub| fs::read_dir(out.join(sub)).unwrap())
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.'))
        .collect();
    assert!(left.is_empty(), "temporary files left: {left:?}");
    one_writer_and_a_killed_runs_leftovers(&w, &p, &out, &before);
}

/// Issue 39: a second writer into a folder whose lock a live process holds is refused,
/// named, and the results stay byte for byte; a killed run's lock, hidden new folder and
/// `.partial` file are taken over and cleared by the next run, whose results are complete
/// and swapped in as one folder (a new inode: not written file by file).
fn one_writer_and_a_killed_runs_leftovers(w: &Work, p: &Path, out: &Path, before: &[Vec<u8>]) {
    common::copy_dir(&common::quick_pristine().join("images"), &p.join("images"));
    let toml = p.join("project.toml");
    let args = ["calibrate", s(&toml), "--out", s(out), "--quiet"];
    let lock = out.with_file_name(".out.pingcal-lock");
    let mut holder = std::process::Command::new("sleep")
        .arg("600")
        .spawn()
        .unwrap();
    fs::write(&lock, holder.id().to_string()).unwrap();
    let refused = w.run(&args);
    let _ = holder.kill();
    let _ = holder.wait();
    fails(
        &refused,
        &["another pingcal", &format!("process {}", holder.id())],
    );
    for (f, bytes) in OUTPUTS.iter().zip(before) {
        assert!(
            fs::read(out.join(f)).unwrap() == *bytes,
            "{f} changed by a refused run"
        );
    }
    // the holder is gone: its lock is stale, like a killed run's, with its leftovers
    let new = out.with_file_name(format!(".out.pingcal-new-{}", holder.id()));
    fs::create_dir_all(new.join("ros")).unwrap();
    fs::write(new.join("results.json"), b"{\"half\":").unwrap();
    fs::write(out.join(".results.json.partial"), b"{").unwrap();
    use std::os::unix::fs::MetadataExt;
    let inode = fs::metadata(out).unwrap().ino();
    let again = w.run(&args);
    assert!(again.success(), "{}", ctx(&again));
    assert!(
        !lock.exists() && !new.exists(),
        "a killed run's lock or folder is left"
    );
    assert!(!out.join(".results.json.partial").exists());
    assert_ne!(
        fs::metadata(out).unwrap().ino(),
        inode,
        "not swapped in as one folder"
    );
    for f in OUTPUTS {
        assert!(out.join(f).is_file(), "{f} missing after the swap");
    }
    read_json(&out.join("results.json"));
}

/// Item 3: `--out a_file` and `--out /proc/x` failed only after the whole pipeline; now
/// before any work: the project's missing image (found by the first step) is not what the
/// error names.
#[test]
fn an_unwritable_output_folder_is_refused_before_any_work() {
    let w = Work::new("unwritable_out");
    let p = w.project("project");
    fs::remove_file(p.join("images/S03_left.png")).unwrap();
    let toml = p.join("project.toml");
    let file = w.dir.join("a_file");
    fs::write(&file, b"not a folder").unwrap();
    let run = w.run(&["calibrate", s(&toml), "--out", s(&file), "--quiet"]);
    let err = fails(&run, &[s(&file), "not a folder"]);
    assert!(!err.contains("S03_left"), "the pipeline ran first: {err}");
    if Path::new("/proc/self").exists() {
        let run = w.run(&["calibrate", s(&toml), "--out", "/proc/x", "--quiet"]);
        let err = fails(&run, &["/proc/x", "cannot create the output folder"]);
        assert!(!err.contains("S03_left"), "the pipeline ran first: {err}");
    }
    let run = w.run(&[
        "cloud",
        s(&p.join("scans/S00.csv")),
        "--out",
        "/proc/x/c.ply",
    ]);
    if Path::new("/proc/self").exists() {
        fails(&run, &["--out /proc/x/c.ply", "cannot create"]);
    }
}

/// Item 4: negative numbers parse (`--tilt-x-deg -0.3` was "unexpected argument '-0'"),
/// and `--mount-offset-mm` accepts the default its help shows.
#[test]
fn negative_numbers_and_the_shown_mount_default_are_accepted() {
    let w = Work::new("negative_numbers");
    let p = w.project("project");
    let scan = p.join("scans/S00.csv");
    let help = w.run(&["cloud", "--help"]);
    assert!(help.success(), "{}", ctx(&help));
    let flat = help.stdout.split_whitespace().collect::<Vec<_>>().join(" ");
    let at = flat
        .find("--mount-offset-mm <")
        .expect("the option in the help");
    let rest = &flat[at..];
    let shown = rest[rest.find("[default: ").expect("a shown default") + 10..]
        .split(']')
        .next()
        .unwrap()
        .to_string();
    for args in [
        vec!["--mount-offset-mm", shown.as_str()],
        vec![
            "--tilt-x-deg",
            "-0.3",
            "--tilt-z-deg",
            "-1.5e-2",
            "--servo-zero-deg",
            "-0.1",
            "--mount-offset-mm",
            "-1.5,0,-2",
        ],
    ] {
        let mut all = vec!["cloud", s(&scan)];
        all.extend(&args);
        let run = w.run(&all);
        assert!(run.success(), "{args:?}: {}", ctx(&run));
        assert!(run.stdout.contains("ball(s)"), "{}", ctx(&run));
    }
    let run = w.run(&["cloud", s(&scan), "--mount-offset-mm", "-1,2"]);
    fails(&run, &["--mount-offset-mm", "three numbers"]);
}

/// Item 5: `ba` on a BAL file ignored `--snoop`, `--calibrate` and `--report`; now they are
/// refused naming the file. `--threads 100000` is refused with the allowed range, by `ba`
/// and `calibrate`.
#[test]
fn ba_refuses_measurement_options_on_bal_and_absurd_thread_counts() {
    let w = Work::new("ba_options");
    let bal = w.dir.join("p.bal");
    let gen = w.run(&[
        "gen-bal",
        "--cameras",
        "4",
        "--points",
        "40",
        "--obs-per-point",
        "3",
        "--noise-px",
        "0.5",
        "--seed",
        "1",
        "--out",
        s(&bal),
    ]);
    assert!(gen.success(), "{}", ctx(&gen));
    let report = w.dir.join("r.txt");
    for (args, named) in [
        (vec!["--snoop", "3.29"], "--snoop applies"),
        (vec!["--calibrate", "c,xp"], "--calibrate applies"),
        (vec!["--report", s(&report)], "--report applies"),
        (vec!["--free-network"], "--free-network applies"),
        (
            vec!["--min-intersection-angle", "2"],
            "--min-intersection-angle applies",
        ),
    ] {
        let mut all = vec!["ba", s(&bal), "--quiet"];
        all.extend(&args);
        let run = w.run(&all);
        fails(&run, &[named, "measurement files", s(&bal)]);
    }
    assert!(!report.exists(), "a report for a refused run");
    let run = w.run(&["ba", s(&bal), "--threads", "100000"]);
    fails(&run, &["--threads 100000", "0 (all cores) to 1024"]);
    for eta in ["0", "1.5", "NaN"] {
        let run = w.run(&["ba", s(&bal), "--solver", "iterative", "--eta", eta]);
        fails(&run, &[&format!("--eta {eta}"), "strictly between 0 and 1"]);
    }
    for dim in ["0", "5000"] {
        let run = w.run(&["ba", s(&bal), "--cluster-max-dim", dim]);
        fails(
            &run,
            &[&format!("--cluster-max-dim {dim}"), "1 to 4096 unknowns"],
        );
    }
    let p = w.project("project");
    let toml = p.join("project.toml");
    let run = w.run(&["calibrate", s(&toml), "--threads", "100000", "--quiet"]);
    fails(&run, &["--threads 100000", "0 (all cores) to 1024"]);
    let ok = w.run(&["ba", s(&bal), "--threads", "2", "--quiet"]);
    assert!(ok.success(), "{}", ctx(&ok));
}

/// Item 6: an id given twice was counted twice (`register --check`, project.toml's
/// `check`) or printed twice (`targets --ids 2,2,2`); now it is refused, named.
#[test]
fn ids_given_twice_are_refused() {
    let w = Work::new("duplicate_ids");
    let pts = w.dir.join("points.txt");
    fs::write(
        &pts,
        "B1 0 0 0\nB2 100 0 0\nB3 0 100 0\nB4 0 0 100\nB5 100 100 0\n",
    )
    .unwrap();
    let run = w.run(&["register", s(&pts), s(&pts), "--check", "B4,B5,B4"]);
    fails(&run, &["--check", "'B4' is given twice"]);
    let run = w.run(&["register", s(&pts), s(&pts), "--control", "B1,B2,B3,B1"]);
    fails(&run, &["--control", "'B1' is given twice"]);
    let svg = w.dir.join("t.svg");
    let run = w.run(&["targets", "--ids", "2,2,2", "--out", s(&svg)]);
    fails(&run, &["'2,2,2'", "2 is given twice"]);
    assert!(!svg.exists(), "targets wrote the refused list");

    let p = w.project("project");
    let toml = p.join("project.toml");
    common::replace_once(
        &toml,
        "check = [\"B4\", \"B9\",",
        "check = [\"B4\", \"B9\", \"B9\",",
    );
    w.calibrate_fails(&p, "input", &["project.toml", "'B9' appears twice"]);
}

/// Item 7: calibrate's cloud.ply held 400 drawn points per sphere among the scan points;
/// now `pingcal cloud results/cloud.ply` reads back exactly the scan's points through the
/// calibration's LRF model (and finds the same balls).
#[test]
fn cloud_ply_reads_back_as_exactly_the_scan_points() {
    let w = Work::new("cloud_ply_round_trip");
    let common::Calibration {
        project: p, out, ..
    } = common::calibration();
    // cloud.ply is made through the calibration's LRF model (results.json's lrf_model),
    // which `pingcal cloud --lrf-model` applies to the same scan
    let model = out.join("results.json");
    let scan = w.run(&[
        "cloud",
        s(&p.join("scans/S00.csv")),
        "--lrf-model",
        s(&model),
    ]);
    let back = w.run(&["cloud", s(&out.join("cloud.ply"))]);
    assert!(
        scan.success() && back.success(),
        "{}\n{}",
        ctx(&scan),
        ctx(&back)
    );
    let counts = |r: &Run| {
        let l = r.stdout.trim();
        let n = |after: &str, before: &str| -> usize {
            let i = l
                .find(before)
                .unwrap_or_else(|| panic!("{before:?} in {l:?}"));
            l[..i]
                .rsplit(after)
                .next()
                .unwrap()
                .trim()
                .parse()
                .unwrap_or_else(|e| panic!("{l:?}: {e}"))
        };
        (n("cloud:", " points"), n(",", " ball(s)"))
    };
    let (points, balls) = counts(&scan);
    assert!(points > 1000 && balls >= 3, "{}", scan.stdout);
    assert_eq!(
        counts(&back),
        (points, balls),
        "{}\n{}",
        scan.stdout,
        back.stdout
    );
    let ply = fs::read(out.join("cloud.ply")).unwrap();
    let head = String::from_utf8_lossy(&ply[..ply.len().min(2000)]).into_owned();
    assert!(
        head.contains(&format!("element vertex {points}\n")) && head.contains("element sphere "),
        "{head}"
    );
}

/// Issue 18: `pingcal targets` writes a real PDF (it wrote SVG bytes into a `.pdf`), one SVG
/// per page when there are several; the old `--dot-mm` (a diameter, while the project's
/// `dot_radius_mm` is a radius) and other extensions are refused, named.
#[test]
fn targets_are_written_as_pdf_or_svg_pages_by_the_extension() {
    let w = Work::new("targets_pdf_svg");
    let pdf = w.dir.join("t.pdf");
    let run = w.run(&[
        "targets",
        "--ids",
        "2-51",
        "--plain",
        "20",
        "--out",
        s(&pdf),
    ]);
    assert!(run.success(), "{}", run.stderr);
    assert!(fs::read(&pdf).unwrap().starts_with(b"%PDF-"), "not a PDF");
    assert!(run.stdout.contains("on 3 A4 pages"), "{}", run.stdout);
    let svg = w.dir.join("t.svg");
    let run = w.run(&["targets", "--ids", "2-51", "--out", s(&svg)]);
    assert!(run.success(), "{}", run.stderr);
    for k in 1..=2 {
        let page = fs::read_to_string(w.dir.join(format!("t-{k}.svg"))).unwrap();
        assert!(page.starts_with("<?xml") && page.contains("page 2 of 2") == (k == 2));
    }
    let run = w.run(&["targets", "--dot-mm", "8", "--out", s(&w.dir.join("d.pdf"))]);
    fails(&run, &["--dot-mm 8", "--dot-radius-mm 4"]);
    let run = w.run(&["targets", "--out", s(&w.dir.join("t.png"))]);
    fails(&run, &["t.png", "expected a .pdf or .svg"]);
    let big = w.dir.join("big.pdf");
    let run = w.run(&["targets", "--dot-radius-mm", "30", "--out", s(&big)]);
    fails(&run, &["does not fit on an A4 page"]);
}

/// Issue 15 (Build): `--noise` names a sensor's range-noise profile. The default is the
/// URG-04LX as before: `--noise URG-04LX` gives the same bytes (cloud.ply, balls, stdout) as
/// no option; an unknown name lists the known ones; `--noise-sigma A,B` needs two numbers.
#[test]
fn noise_profiles_default_to_the_urg_and_unknown_names_list_the_known() {
    let w = Work::new("noise_profiles");
    let p = w.project("project");
    let scan = p.join("scans/S00.csv");
    let outputs = |tag: &str, extra: &[&str]| {
        let (ply, balls) = (
            w.dir.join(format!("{tag}.ply")),
            w.dir.join(format!("{tag}.txt")),
        );
        let mut args = vec!["cloud", s(&scan), "--out", s(&ply), "--balls", s(&balls)];
        args.extend(extra);
        let run = w.run(&args);
        assert!(run.success(), "{}", ctx(&run));
        let stdout = run.stdout.replace(s(&ply), "OUT");
        (fs::read(&ply).unwrap(), fs::read(&balls).unwrap(), stdout)
    };
    let default = outputs("default", &[]);
    let urg = outputs("urg", &["--noise", "URG-04LX"]);
    assert!(default == urg, "the default is not the URG-04LX profile");
    let utm = outputs("utm", &["--noise", "utm-30lx"]);
    assert!(utm.2.contains("ball(s)"), "{}", utm.2);
    let lin = outputs("lin", &["--noise-sigma", "10,0.001"]);
    assert!(lin.2.contains("ball(s)"), "{}", lin.2);
    let run = w.run(&["cloud", s(&scan), "--noise", "LMS-111"]);
    fails(&run, &["--noise: unknown noise profile \"LMS-111\" (known: URG-04LX, UTM-30LX, UST-10LX, VLP-16)"]);
    let run = w.run(&["cloud", s(&scan), "--noise-sigma", "1"]);
    fails(&run, &["--noise-sigma: expected two numbers A,B, found 1"]);
    let run = w.run(&["cloud", s(&scan), "--noise-sigma", "0,0.01"]);
    fails(
        &run,
        &["--noise-sigma = [0, 0.01]: expected 0 < a", "(σ = a + b·r)"],
    );
}

/// DBAT's files: the camera is DBAT's XML, named with its line when malformed; without
/// control the datum is refused as undefined until `--free-network`, and control with
/// `--free-network` as defined twice; all before any solving. With the shared camcal data,
/// the free network adjusts.
#[test]
fn dbat_files_name_their_camera_and_datum_problems() {
    let w = Work::new("dbat_datum");
    let marks = w.dir.join("markpts.txt");
    let lines: String = (1..=2)
        .flat_map(|i| {
            (1..=3).map(move |p| format!("{i}, {p}, {}, {}, 0.1\n", 100 * p + 7 * i, 200 + 50 * p))
        })
        .collect();
    fs::write(&marks, lines).unwrap();
    let camera = w.dir.join("camera.xml");
    let xml = "<document dbat_camera_version=\"1.0\">\n<cameras>\n<camera>\n<name>cam</name>\n<sensor>auto,4.8</sensor>\n<image>1600,1200</image>\n<focal>8.5</focal>\n</camera>\n</cameras>\n</document>\n";
    fs::write(&camera, xml).unwrap();
    let control = w.dir.join("control.txt");
    fs::write(&control, "1,a,0,0,0\n2,b,1,0,0\n3,c,0,1,0\n").unwrap();
    let run = w.run(&["ba", s(&marks), "--dbat", s(&control)]);
    fails(&run, &["--dbat-camera FILE", s(&marks)]);
    let run = w.run(&["ba", s(&marks), "--dbat-camera", s(&camera)]);
    fails(
        &run,
        &["the datum is not defined", "free network", s(&marks)],
    );
    let run = w.run(&[
        "ba",
        s(&marks),
        "--dbat-camera",
        s(&camera),
        "--dbat",
        s(&control),
        "--free-network",
    ]);
    fails(
        &run,
        &["the datum is defined twice", "3 fixed control points"],
    );
    let bad = w.dir.join("bad.xml");
    fs::write(
        &bad,
        xml.replace("<focal>8.5</focal>", "<focal>8,5</focal>"),
    )
    .unwrap();
    let run = w.run(&["ba", s(&marks), "--dbat-camera", s(&bad), "--free-network"]);
    fails(
        &run,
        &[&format!(
            "{}:7: focal '8,5' is not a finite number",
            s(&bad)
        )],
    );
    let run = w.run(&[
        "ba",
        s(&marks),
        "--dbat-camera",
        s(&camera),
        "--free-network",
        "--min-intersection-angle",
        "200",
    ]);
    fails(&run, &["--min-intersection-angle 200"]);

    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/dbat-camcal");
    if !data.join("c4040z.xml").exists() {
        println!(
            "skipped the real-data run: DBAT's camcal data set not found at {} (shared data absent)",
            data.display()
        );
        return;
    }
    let run = w.run(&[
        "ba",
        s(&data.join("measurements/markpts.txt")),
        "--dbat-camera",
        s(&data.join("c4040z.xml")),
        "--free-network",
        "--quiet",
    ]);
    assert!(run.success(), "{}", ctx(&run));
    assert!(run.stdout.contains("redundancy 3720"), "{}", ctx(&run));
}

/// Issue 17: `pingcal ba` names a camera parameter the network cannot determine before it
/// adjusts. Two images of a plane taken with the same orientation give a plane's two
/// constraints on the interior orientation once only, so c, xp and yp are not determined
/// together; a third image rolled 90° and turned determines them.
#[test]
fn ba_names_an_undeterminable_interior_orientation_before_solving() {
    use pingcal_ba::camera::{CameraModel, PhotogrammetricCamera};
    use pingcal_ba::io::measurements::{
        CameraSpec, ControlPoint, ImagePoint, ImageSpec, Measurements, PoseSpec,
    };
    use pingcal_geometry::Rigid3;
    let w = Work::new("ba_undeterminable");
    let model = PhotogrammetricCamera::new(1280, 720, 0.00375);
    let params = [2.45, 0.01, -0.01, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    // a wall tilted 30° against the images, a grid of 8 × 5 points held as control
    let points: Vec<nalgebra::Vector3<f64>> = (0..40)
        .map(|k| {
            let (i, j) = ((k % 8) as f64 - 3.5, (k / 8) as f64 - 2.0);
            nalgebra::Vector3::new(180.0 * i, 2500.0 + 0.58 * 180.0 * i, 150.0 * j)
        })
        .collect();
    let write = |poses: &[Rigid3], name: &str| {
        let mut image_points = Vec::new();
        let mut images = Vec::new();
        for (k, pose) in poses.iter().enumerate() {
            let image = format!("im{k}");
            for (j, x) in points.iter().enumerate() {
                let uv = model
                    .project(&params, &pose.transform(x), None, None)
                    .expect("in front");
                if (0.0..1280.0).contains(&uv.x) && (0.0..720.0).contains(&uv.y) {
                    image_points.push(ImagePoint {
                        image: image.clone(),
                        point: format!("P{j}"),
                        x: uv.x,
                        y: uv.y,
                        sigma_px: 0.1,
                    });
                }
            }
            images.push(ImageSpec {
                name: image,
                camera: "cam".into(),
                pose: Some(PoseSpec::from_pose(pose)),
                fixed: false,
                fixed_centre_axes: None,
            });
        }
        let names = ["c", "xp", "yp"];
        let m = Measurements {
            format: Some("pingcal-measurements v1".into()),
            cameras: vec![CameraSpec {
                name: "cam".into(),
                model: "photogrammetric".into(),
                width: 1280,
                height: 720,
                pixel_size_mm: 0.00375,
                intrinsics: [("c", params[0]), ("xp", params[1]), ("yp", params[2])]
                    .into_iter()
                    .map(|(n, v)| (n.to_string(), v))
                    .collect(),
                calibrate: names.iter().map(|n| n.to_string()).collect(),
            }],
            images,
            image_points,
            distances: Vec::new(),
            control_points: (0..points.len())
                .map(|j| ControlPoint {
                    id: format!("P{j}"),
                    xyz: points[j].into(),
                    sigma_mm: None,
                    fixed: true,
                    fixed_axes: None,
                })
                .collect(),
        };
        let path = w.dir.join(name);
        m.write(&path).unwrap();
        path
    };
    let look = |c: [f64; 3], roll: f64| {
        let c = nalgebra::Vector3::from(c);
        Rigid3::looking_at(c, c + nalgebra::Vector3::new(0.0, 2500.0, 0.0), roll)
    };
    // the same orientation, moved sideways and up
    let parallel = [look([0.0, 0.0, 0.0], 0.0), look([300.0, 0.0, 200.0], 0.0)];
    let file = write(&parallel, "parallel.json");
    let run = w.run(&["ba", s(&file), "--quiet"]);
    fails(
        &run,
        &[
            s(&file),
            "of camera 'cam' (2 images) cannot be determined by this network",
        ],
    );
    // a third image, rolled 90° and looking at the wall from the side: determined
    let third = Rigid3::looking_at(
        nalgebra::Vector3::new(-900.0, 300.0, 300.0),
        nalgebra::Vector3::new(0.0, 2500.0, 0.0),
        std::f64::consts::FRAC_PI_2,
    );
    let file = write(&[parallel[0], parallel[1], third], "rolled.json");
    let run = w.run(&["ba", s(&file), "--quiet"]);
    assert!(run.success(), "{}", ctx(&run));
}

/// `pingcal ba --precision` on a BAL problem writes the free network's σ0 (at the simulated
/// 0.5 px noise) and σ's into its JSON; with a measurement file, whose precision is always
/// computed, the option is refused by name.
#[test]
fn ba_precision_of_a_bal_problem() {
    let w = Work::new("ba_precision");
    let out = w.dir.join("out.json");
    let run = w.run(&[
        "ba",
        "--synthetic",
        "30x1500",
        "--precision",
        "--quiet",
        "--out",
        s(&out),
    ]);
    assert!(run.success(), "{}", ctx(&run));
    let json = read_json(&out);
    let p = &json["precision"];
    // σ0's relative sd is 1/√(2·redundancy) ≈ 0.004 (redundancy ≈ 13,000): 5 % is 12 sd.
    let sigma0 = p["sigma0"].as_f64().expect("sigma0");
    assert!((sigma0 - 0.5).abs() < 0.025, "σ0 {sigma0}");
    assert!(p["median_point_sigma"].as_f64().is_some_and(|v| v > 0.0));
    assert!(p["method"]
        .as_str()
        .is_some_and(|m| m.contains("inner constraints")));

    let project = w.dir.join("m.json");
    fs::write(&project, "{}").unwrap();
    let refused = w.run(&["ba", s(&project), "--precision"]);
    assert!(!refused.success());
    assert!(
        refused.stderr.contains("--precision is for BAL problems"),
        "{}",
        ctx(&refused)
    );
}

/// The iterative solver on a street says how it clustered the images for its
/// preconditioner, in the log and in the JSON; `--preconditioner schur-jacobi` has none.
#[test]
fn ba_iterative_says_how_it_clustered_the_images() {
    let w = Work::new("ba_clusters");
    let out = w.dir.join("out.json");
    let args = ["ba", "--synthetic", "60x3000", "--solver", "iterative"];
    let run = w.run(&[&args[..], &["--cluster-max-dim", "90", "--out", s(&out)]].concat());
    assert!(run.success(), "{}", ctx(&run));
    assert!(
        run.stdout.contains("preconditioner: cluster-Jacobi, "),
        "{}",
        ctx(&run)
    );
    let json = read_json(&out);
    let clusters = json["clusters"]["clusters"].as_u64().expect("clusters");
    // 60 images of 9 unknowns, at most 10 per cluster.
    assert!((6..30).contains(&clusters), "{}", json["clusters"]);
    assert!(json["clusters"]["largest_dim"]
        .as_u64()
        .is_some_and(|d| d <= 90));
    // How S is applied: chosen (a street with clusters: explicit), in the log and the JSON.
    assert!(
        run.stdout.contains(
            "Schur product: explicit (estimated per step (products and their set-up): implicit "
        ),
        "{}",
        ctx(&run)
    );
    assert_eq!(json["schur_product"]["product"], "explicit");
    let run = w.run(
        &[
            &args[..],
            &["--preconditioner", "schur-jacobi", "--out", s(&out)],
        ]
        .concat(),
    );
    assert!(run.success(), "{}", ctx(&run));
    assert!(read_json(&out)["clusters"].is_null());
    // Or asked for.
    let run = w.run(
        &[
            &args[..],
            &["--schur-product", "implicit", "--out", s(&out)],
        ]
        .concat(),
    );
    assert!(run.success(), "{}", ctx(&run));
    let json = read_json(&out);
    assert_eq!(json["schur_product"]["product"], "implicit");
    assert!(json["schur_product"]["reason"]
        .as_str()
        .is_some_and(|r| r.starts_with("asked for; estimated per step (products")));
    let refused = w.run(&[&args[..], &["--schur-product", "sideways"]].concat());
    assert!(!refused.success());
    assert!(
        refused.stderr.contains("'sideways'") && refused.stderr.contains("--schur-product"),
        "{}",
        ctx(&refused)
    );
}

/// Issue 39: a full disk during the write leaves the earlier set as it was, file by file,
/// and nothing half-made (no hidden folder, no empty `ros/`). The output folder is on a
/// small tmpfs that holds one result set but not two; where a tmpfs cannot be mounted (not
/// root, no CAP_SYS_ADMIN) the test says so and passes.
#[test]
fn a_full_disk_leaves_the_earlier_set() {
    let w = Work::new("full_disk");
    let p = w.quick_project("project");
    let disk = w.dir.join("disk");
    fs::create_dir_all(&disk).unwrap();
    let mount = |options: &str| {
        std::process::Command::new("mount")
            .args(["-t", "tmpfs", "-o", options, "tmpfs", s(&disk)])
            .output()
            .map(|o| o.status.success())
            .unwrap_or(false)
    };
    if !mount("size=512m") {
        eprintln!("a_full_disk_leaves_the_earlier_set: skipped: cannot mount a tmpfs here");
        return;
    }
    let out = disk.join("res");
    let toml = p.join("project.toml");
    let read_all = |d: &Path| -> Vec<(PathBuf, Vec<u8>)> {
        walk(d)
            .into_iter()
            .map(|f| {
                let b = fs::read(&f).unwrap();
                (f, b)
            })
            .collect()
    };
    let first = w.run(&["calibrate", s(&toml), "--out", s(&out), "--quiet"]);
    // the disk shrunk to hold one set and half of another (in whole pages per file, as
    // tmpfs counts them), so the second run's new set cannot be written beside the first
    let pages: u64 = walk(&disk)
        .iter()
        .map(|f| fs::metadata(f).unwrap().len().div_ceil(4096))
        .sum();
    let size = (pages + pages / 2 + 16) * 4096;
    let shrunk = mount(&format!("remount,size={size}"));
    let before = read_all(&disk);
    let second = w.run(&[
        "calibrate",
        s(&toml),
        "--out",
        s(&out),
        "--quiet",
        "--seed",
        "2",
        "--json",
    ]);
    let after = read_all(&disk);
    let dirs: Vec<String> = fs::read_dir(&disk)
        .unwrap()
        .chain(fs::read_dir(&out).unwrap())
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    let _ = std::process::Command::new("umount").arg(s(&disk)).status();
    assert!(first.success(), "{}", ctx(&first));
    assert!(shrunk, "the tmpfs could not be shrunk to {size} bytes");
    fails(&second, &["No space left on device", "left as they were"]);
    let line: Value = serde_json::from_str(second.stdout.trim()).expect("one JSON line");
    assert_eq!(line["error_kind"], "output", "{line}");
    assert!(before.len() > 20, "{} files", before.len());
    let names = |v: &[(PathBuf, Vec<u8>)]| v.iter().map(|f| f.0.clone()).collect::<Vec<_>>();
    assert_eq!(
        names(&after),
        names(&before),
        "files added or lost on the full disk"
    );
    for ((f, a), (_, b)) in after.iter().zip(&before) {
        assert!(a == b, "{} changed by the failed run", f.display());
    }
    assert!(
        dirs.iter().all(|d| !d.starts_with('.')),
        "left behind: {dirs:?}"
    );
}

/// Every file below `dir`, sorted.
fn walk(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for e in fs::read_dir(dir).into_iter().flatten().flatten() {
        let path = e.path();
        if e.file_type().unwrap().is_dir() {
            out.extend(walk(&path));
        } else {
            out.push(path);
        }
    }
    out.sort();
    out
}

/// Issue 33's four projects, copies of the quick simulated one (`method = "spheres"`, the
/// mount as stated): `ok` as it is; `doubtful` with a 25 mm scanner offset the project
/// states and the rig does not have (the paper's two steps cannot absorb it: the
/// registration's σ0 and the check balls fail their χ² tests); `failed` with
/// `method = "corner"` (the sphere method gives no extrinsic, `verdict::judge`); `bad`
/// missing an image (not calibrated). Their
/// `project.toml` paths, in that order.
fn verdict_projects(w: &Work) -> [String; 4] {
    let ok = w.quick_project("ok");
    let doubtful = w.quick_project("doubtful");
    let toml = doubtful.join("project.toml");
    common::replace_once(
        &toml,
        "mount_offset_mm = [0.0, 0.0, 0.0]",
        "mount_offset_mm = [25.0, 0.0, 0.0]",
    );
    let failed = w.quick_project("failed");
    let toml = failed.join("project.toml");
    common::replace_once(&toml, "method = \"spheres\"", "method = \"corner\"");
    let [ok, doubtful, failed] =
        [ok, doubtful, failed].map(|p| s(&p.join("project.toml")).to_string());
    [ok, doubtful, failed, bad_project(w)]
}

/// A copy of the simulated project missing an image: it cannot be calibrated. Its
/// `project.toml` path.
fn bad_project(w: &Work) -> String {
    let bad = w.quick_project("bad");
    fs::remove_file(bad.join("images/S03_left.png")).expect("remove an image");
    s(&bad.join("project.toml")).to_string()
}

/// A calibrated project's JSON line: its verdict, its reasons and `results.json`'s agree,
/// and the results are in `out`.
fn assert_calibrated(l: &Value, verdict: &str) {
    assert_eq!(l["verdict"], verdict, "{l}");
    assert_eq!(l["ok"], Value::Bool(true), "{l}");
    assert_eq!(l["results_written"], Value::Bool(true), "{l}");
    let out = Path::new(l["out"].as_str().expect("out"));
    let r = read_json(&out.join("results.json"));
    assert_eq!(r["verdict"]["status"], verdict, "{l}");
    assert_eq!(l["reasons"], r["verdict"]["reasons"], "{l}");
    assert_eq!(
        l["reasons"].as_array().expect("reasons").is_empty(),
        verdict == "ok",
        "{l}"
    );
}

/// A project that could not be calibrated: `verdict` `error`, the error (every one of these
/// projects misses an image: an `input` error), nothing written.
fn assert_error(l: &Value, needle: &str) {
    assert_eq!(l["verdict"], "error", "{l}");
    assert_eq!(l["error_kind"], "input", "{l}");
    assert_eq!(l["ok"], Value::Bool(false), "{l}");
    assert_eq!(l["results_written"], Value::Bool(false), "{l}");
    assert!(l["error"].as_str().expect("error").contains(needle), "{l}");
    let out = Path::new(l["out"].as_str().expect("out"));
    assert!(!out.join("results.json").exists(), "{l}");
}

/// Issue 33: a script tells a doubtful calibration from a good one. Each project alone: the
/// summary line (under `--quiet`) or the JSON line says the verdict, stderr its reasons,
/// the exit code is 0 ok, 3 doubtful, 4 failed, 1 not calibrated; a batch of all four prints
/// their lines in the order given and exits with the worst, 1.
#[test]
fn calibrate_says_its_verdict_in_the_json_line_and_the_exit_code() {
    let w = Work::new("verdict_exit");
    let [ok, doubtful, failed, bad] = verdict_projects(&w);
    let out = |name: &str| s(&w.dir.join("out").join(name)).to_string();
    // ok alone, --quiet: the summary line starts with the verdict, stderr is empty
    let run = w.run(&["calibrate", &ok, "--out", &out("ok"), "--quiet"]);
    assert_eq!(run.code, Some(0), "{}", ctx(&run));
    let prefix = format!("calibrate: {ok}: verdict ok; sigma0 ");
    assert!(run.stdout.starts_with(&prefix), "{}", ctx(&run));
    assert!(run.stderr.trim().is_empty(), "{}", ctx(&run));
    // doubtful alone, --quiet: its reasons on stderr, one line each, then the exit's reason
    let run = w.run(&["calibrate", &doubtful, "--out", &out("d"), "--quiet"]);
    assert_eq!(run.code, Some(3), "{}", ctx(&run));
    assert!(
        run.stdout
            .starts_with(&format!("calibrate: {doubtful}: verdict doubtful (")),
        "{}",
        ctx(&run)
    );
    let r = read_json(&w.dir.join("out/d/results.json"));
    for why in r["verdict"]["reasons"].as_array().expect("reasons") {
        let line = format!("pingcal: {doubtful}: doubtful: {}", why.as_str().unwrap());
        assert!(run.stderr.lines().any(|l| l == line), "{}", ctx(&run));
    }
    assert!(
        run.stderr.contains("registration's σ0"),
        "the reasons name the misfit: {}",
        ctx(&run)
    );
    let last = run.stderr.trim().lines().last().unwrap_or_default();
    assert!(last.contains("--accept-doubtful"), "{}", ctx(&run));
    // failed and bad alone, --json
    let run = w.run(&["calibrate", &failed, "--out", &out("f"), "--json"]);
    assert_eq!(run.code, Some(4), "{}", ctx(&run));
    let lines = run.json_lines();
    assert_eq!(lines.len(), 1, "{}", ctx(&run));
    assert_calibrated(&lines[0], "failed");
    assert!(lines[0]["reasons"][0]
        .as_str()
        .is_some_and(|r| r.contains("the sphere method gave no extrinsic")));
    let run = w.run(&["calibrate", &bad, "--out", &out("b"), "--json"]);
    assert_eq!(run.code, Some(1), "{}", ctx(&run));
    let lines = run.json_lines();
    assert_eq!(lines.len(), 1, "{}", ctx(&run));
    assert_error(&lines[0], "S03_left.png");
    // all four: one line each in the order given, the worst (not calibrated) decides
    let batch = w.dir.join("batch");
    let all = [&ok, &doubtful, &failed, &bad].map(String::as_str);
    let run = w.run(&[&["calibrate"], &all[..], &["--out", s(&batch), "--json"]].concat());
    assert_eq!(run.code, Some(1), "{}", ctx(&run));
    let lines = run.json_lines();
    assert_eq!(lines.len(), 4, "{}", ctx(&run));
    for (l, p) in lines.iter().zip(all) {
        assert_eq!(l["project"], p, "{}", ctx(&run));
    }
    assert_calibrated(&lines[0], "ok");
    assert_calibrated(&lines[1], "doubtful");
    assert_calibrated(&lines[2], "failed");
    assert_error(&lines[3], "S03_left.png");
}

/// `--accept-doubtful` exits 0 on a batch whose worst verdict is doubtful, which otherwise
/// exits 3; the JSON lines still say `doubtful`.
#[test]
fn accept_doubtful_exits_0_when_the_worst_verdict_is_doubtful() {
    let w = Work::new("accept_doubtful");
    let [ok, doubtful, _, _] = verdict_projects(&w);
    let out = w.dir.join("out");
    let args = ["calibrate", &ok, &doubtful, "--out", s(&out), "--json"];
    let run = w.run(&args);
    assert_eq!(run.code, Some(3), "{}", ctx(&run));
    let lines = run.json_lines();
    assert_eq!(lines.len(), 2, "{}", ctx(&run));
    assert_calibrated(&lines[0], "ok");
    assert_calibrated(&lines[1], "doubtful");
    // --json hides the step log: the reasons are on stderr
    assert!(
        run.stderr
            .contains(&format!("pingcal: {doubtful}: doubtful: ")),
        "{}",
        ctx(&run)
    );
    let run = w.run(&[&args[..], &["--accept-doubtful"]].concat());
    assert_eq!(run.code, Some(0), "{}", ctx(&run));
    let lines = run.json_lines();
    assert_eq!(lines.len(), 2, "{}", ctx(&run));
    assert_calibrated(&lines[1], "doubtful");
    let help = w.run(&["calibrate", "--help"]);
    for code in ["0 ", "3 ", "4 ", "1 ", "2 "] {
        assert!(
            help.stdout
                .lines()
                .any(|l| l.trim_start().starts_with(code)),
            "--help does not give exit code {code}: {}",
            help.stdout
        );
    }
}

/// The workspace's root.
fn workspace() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// docs/batch/slurm-array.sh really run: `tests/batch/slurm.sh` starts a single-node Slurm
/// here, submits the script as a two-task array (the ok and the doubtful project) with
/// `sbatch --wait`, and stops it; each task's JSON line and results folder are checked, and
/// sbatch's exit code is the worst task's (3). Skips, saying why, where Slurm cannot run
/// (not root, slurm-wlm not installed).
#[test]
fn the_slurm_job_array_of_docs_batch_runs_one_project_per_task() {
    let w = Work::new("slurm");
    let [ok, doubtful, _, _] = verdict_projects(&w);
    let work = w.dir.join("slurm-work");
    let script = workspace().join("tests/batch/slurm.sh");
    let out = std::process::Command::new("bash")
        .args([s(&script), s(&work), common::bin(), &ok, &doubtful])
        .output()
        .expect("run bash");
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    if out.status.code() == Some(77) {
        eprintln!("slurm job array not run: {}", stdout.trim());
        return;
    }
    assert!(
        out.status.success(),
        "slurm.sh: {:?}\n{stdout}\n{stderr}",
        out.status
    );
    let rc = fs::read_to_string(work.join("sbatch.rc")).expect("sbatch.rc");
    assert_eq!(
        rc.trim(),
        "3",
        "sbatch --wait: the worst task's code\n{stdout}"
    );
    for (task, verdict) in [(0, "ok"), (1, "doubtful")] {
        let json = work.join(format!("results/{task}.json"));
        let text = fs::read_to_string(&json).unwrap_or_else(|e| panic!("{json:?}: {e}\n{stdout}"));
        let lines: Vec<Value> = text
            .lines()
            .map(|l| serde_json::from_str(l).expect("a JSON line"))
            .collect();
        assert_eq!(lines.len(), 1, "{text}");
        assert_eq!(lines[0]["project"], [&ok, &doubtful][task].as_str());
        assert_eq!(
            Path::new(lines[0]["out"].as_str().unwrap()),
            work.join(format!("results/{task}"))
        );
        assert_calibrated(&lines[0], verdict);
        for f in OUTPUTS {
            assert!(work.join(format!("results/{task}/{f}")).is_file(), "{f}");
        }
    }
}

/// docs/batch/k8s-indexed-job.yaml is a valid Indexed Job (parsed by PyYAML: the target's
/// ecosystem venv, else the system's python3; skipped, saying why, without either), and its
/// container's script, run here with `/projects` and `/results` moved into a temporary
/// folder, picks the project of `JOB_COMPLETION_INDEX`, writes its JSON line and exits as
/// pingcal does (1 for a project that cannot be calibrated, and for an index past the
/// list). No cluster is run.
#[test]
fn the_kubernetes_indexed_job_of_docs_batch_is_valid_and_its_script_runs() {
    let w = Work::new("k8s");
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| workspace().join("target"));
    let venv = target.join("ecosystem-venv/bin/python");
    let python = if venv.is_file() {
        s(&venv).to_string()
    } else {
        "python3".into()
    };
    let manifest = workspace().join("docs/batch/k8s-indexed-job.yaml");
    let check = r#"
import json, sys, yaml
docs = list(yaml.safe_load_all(open(sys.argv[1])))
assert len(docs) == 1, docs
j = docs[0]
assert j["apiVersion"] == "batch/v1" and j["kind"] == "Job", j
spec = j["spec"]
assert spec["completionMode"] == "Indexed", spec
assert isinstance(spec["completions"], int) and spec["completions"] >= 1, spec
assert isinstance(spec["parallelism"], int) and spec["parallelism"] >= 1, spec
pod = spec["template"]["spec"]
assert pod["restartPolicy"] == "Never", pod  # what podFailurePolicy and Indexed retries need
(c,) = pod["containers"]
for rule in spec.get("podFailurePolicy", {}).get("rules", []):
    codes = rule.get("onExitCodes")
    assert codes is None or codes["containerName"] == c["name"], rule
volumes = {v["name"] for v in pod["volumes"]}
mounts = {m["mountPath"]: m["name"] for m in c["volumeMounts"]}
assert set(mounts.values()) <= volumes, (mounts, volumes)
assert "/projects" in mounts and "/results" in mounts, mounts
assert c["command"] == ["/bin/sh", "-c"], c["command"]
(script,) = c["args"]
assert "JOB_COMPLETION_INDEX" in script, script
print(json.dumps(script))
"#;
    let out = std::process::Command::new(&python)
        .args(["-c", check, s(&manifest)])
        .output();
    let out = match out {
        Ok(o) if String::from_utf8_lossy(&o.stderr).contains("No module named 'yaml'") => {
            eprintln!(
                "k8s manifest not checked: {python} has no PyYAML (bash tests/ecosystem/setup.sh)"
            );
            return;
        }
        Ok(o) => o,
        Err(e) => {
            eprintln!("k8s manifest not checked: {python}: {e}");
            return;
        }
    };
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let script: String = serde_json::from_slice(&out.stdout).expect("the script");
    let bad = bad_project(&w);
    let (projects, results) = (w.dir.join("projects"), w.dir.join("results"));
    fs::create_dir_all(&projects).unwrap();
    fs::create_dir_all(&results).unwrap();
    fs::write(projects.join("projects.txt"), format!("{bad}\n")).unwrap();
    let script = script
        .replace("/projects/", &format!("{}/", s(&projects)))
        .replace("/results/", &format!("{}/", s(&results)));
    let bin_dir = Path::new(common::bin()).parent().unwrap();
    let path = format!(
        "{}:{}",
        s(bin_dir),
        std::env::var("PATH").unwrap_or_default()
    );
    let pod = |index: &str| {
        std::process::Command::new("/bin/sh")
            .args(["-c", &script])
            .env("JOB_COMPLETION_INDEX", index)
            .env("PATH", &path)
            .output()
            .expect("run the pod's script")
    };
    let o = pod("0");
    assert_eq!(o.status.code(), Some(1), "{o:?}");
    let l: Value = serde_json::from_str(&fs::read_to_string(results.join("0.json")).unwrap())
        .expect("the pod's JSON line");
    assert_eq!(l["project"], bad.as_str());
    assert_error(&l, "S03_left.png");
    let o = pod("1");
    assert_eq!(o.status.code(), Some(1), "{o:?}");
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("no line 2"),
        "{o:?}"
    );
}

/// `../shared/data/bad-inputs`, or `None` (saying so) where the shared data is absent.
fn bad_inputs(test: &str) -> Option<PathBuf> {
    let d = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/bad-inputs");
    if d.is_dir() {
        Some(d)
    } else {
        println!("{test}: skipped: {} is absent", d.display());
        None
    }
}

/// A run that succeeds with a `pingcal: warning: ` line on stderr holding every needle.
fn warns(run: &Run, needles: &[&str]) {
    assert!(run.success(), "{}", ctx(run));
    let w = run
        .stderr
        .lines()
        .find(|l| l.contains("warning: ") && needles.iter().all(|n| l.contains(n)));
    assert!(w.is_some(), "no warning naming {needles:?}: {}", ctx(run));
}

/// The summary line of `pingcal cloud` without its file count (`3 plane(s), 10 ball(s) …`).
fn found(run: &Run) -> String {
    let last = run.stdout.lines().last().unwrap_or("");
    last.split_once(" file(s), ")
        .map_or(last.to_string(), |(_, r)| r.to_string())
}

/// Issue 39: every file of `bad-inputs/` gives one clear line naming the file and what is
/// wrong, or (the legal ones) the right result: the one of the same input without the fault.
#[test]
fn every_bad_input_is_named_or_gives_the_right_result() {
    let Some(b) = bad_inputs("every_bad_input_is_named_or_gives_the_right_result") else {
        return;
    };
    let w = Work::new("bad_inputs");
    let f = |name: &str| b.join(name);
    let out = |name: &str| w.dir.join(name);
    let ply = out("x.ply");
    // the BAL file with a line duplicated
    let bal = f("bal_duplicated_line_accepted_rms75100px_rc0.bal");
    let run = w.run(&["ba", s(&bal), "--out", s(&out("b.json"))]);
    fails(&run, &[s(&bal), ":644:", "trailing data"]);
    // ranges beyond any range finder: masked and counted
    let huge = f("cloud_range_1e300_writes_inf_into_ply.csv");
    let run = w.run(&["cloud", s(&huge), "--out", s(&ply)]);
    fails(
        &run,
        &[
            s(&huge),
            "no valid ranges",
            "2 ranges beyond 1e6 mm",
            "line 6",
        ],
    );
    assert!(!ply.exists());
    for (name, value, line) in [
        ("scan_csv_slow_11477156d6.csv", "1e308", "line 12"),
        (
            "scan_one_range_999999mm_hangs_cloud_and_calibrate.csv",
            "999999",
            "",
        ),
    ] {
        let scan = f(name);
        let clean = out(&format!("clean-{name}"));
        let text = fs::read_to_string(&scan).unwrap();
        fs::write(&clean, text.replace(&format!(",{value},"), ",0,")).unwrap();
        let want = w.run(&["cloud", s(&clean)]);
        let run = w.run(&["cloud", s(&scan)]);
        warns(&run, &[s(&scan), "masked as no return", line]);
        assert_eq!(
            found(&run),
            found(&want),
            "{name}: not the clean scan's result"
        );
    }
    // beam geometry beyond a turn: refused at the header, no PLY
    for (name, inc) in [
        ("scan_angle_increment_1e308_writes_nan_ply.csv", "1e308"),
        ("scan_angle_increment_360_accepted.csv", "360"),
    ] {
        let scan = f(name);
        let run = w.run(&["cloud", s(&scan), "--out", s(&ply)]);
        let e = fails(
            &run,
            &[
                s(&scan),
                &format!("angle_increment_deg = {inc} over 682 beams"),
            ],
        );
        assert!(e.contains("at most 360°"), "{e}");
        assert!(!ply.exists());
    }
    let jpeg = f("jpeg_truncated_accepted_0315baa11a.jpg");
    let run = w.run(&["detect", s(&jpeg), "--out", s(&out("d.json"))]);
    fails(&run, &[s(&jpeg), "truncated JPEG"]);
    // register: a byte-order mark is legal (the clean file's result), a 1e308 is not
    let (lrf, cam) = (
        f("register_lrf_points.txt"),
        f("register_camera_points.txt"),
    );
    let want = w.run(&["register", s(&lrf), s(&cam)]);
    let bom = f("register_bom_in_lrf_file_silently_drops_B1.txt");
    let run = w.run(&["register", s(&bom), s(&cam)]);
    assert!(run.success() && want.success(), "{}", ctx(&run));
    assert!(run.stdout.contains("16 control"), "{}", ctx(&run));
    assert_eq!(run.stdout, want.stdout, "the BOM changed the result");
    let big = f("register_check_point_1e308_gives_inf_mean_and_null_json.txt");
    let r = out("r.json");
    let run = w.run(&[
        "register",
        s(&lrf),
        s(&big),
        "--check",
        "B4,B9",
        "--out",
        s(&r),
    ]);
    fails(&run, &[s(&big), ":10:", "1e308"]);
    assert!(!r.exists());
    // measurement files: no datum refused; the documented style gives the rig's baseline
    let none = f("measurements_no_datum_adjusted_at_arbitrary_scale.json");
    let run = w.run(&["ba", s(&none), "--out", s(&out("n.json"))]);
    fails(
        &run,
        &[s(&none), "the datum is not defined", "scale is free"],
    );
    let doc = f("measurements_doc_example_style.json");
    let m = out("m.json");
    let run = w.run(&["ba", s(&doc), "--out", s(&m), "--quiet"]);
    assert!(run.success(), "{}", ctx(&run));
    let ext = read_json(&m)["exterior"].clone();
    let centre = |name: &str| -> Vec<f64> {
        let e = ext
            .as_array()
            .unwrap()
            .iter()
            .find(|e| e["name"] == name)
            .unwrap();
        let v = |k: &str| {
            e[k].as_array().map(|a| {
                a.iter()
                    .map(|x| x.as_f64().unwrap_or(0.0))
                    .collect::<Vec<f64>>()
            })
        };
        v("centre")
            .unwrap()
            .into_iter()
            .chain(v("sigma_centre").unwrap_or_default())
            .collect()
    };
    let (l, r) = (centre("S00_left"), centre("S00_right"));
    let baseline = (0..3).map(|k| (r[k] - l[k]).powi(2)).sum::<f64>().sqrt();
    let sigma = (r[3].powi(2) + r[4].powi(2) + r[5].powi(2)).sqrt();
    assert!(
        (baseline - 120.0).abs() <= 4.0 * sigma,
        "the stereo baseline is {baseline} ± {sigma} mm, the simulated rig's 120 mm"
    );
    // DBAT: the control file's error names it, its line and the value as written there
    let camcal = b.join("../dbat-camcal");
    let control = f("dbat_control_bad_value_blamed_on_markpts.txt");
    let run = w.run(&[
        "ba",
        s(&camcal.join("measurements/markpts.txt")),
        "--dbat-camera",
        s(&camcal.join("c4040z.xml")),
        "--dbat",
        s(&control),
        "--out",
        s(&out("w.json")),
    ]);
    fails(
        &run,
        &[&format!("{}:6:", s(&control)), "Z = -2147483648 is beyond"],
    );
}

/// The pristine project's copy `sub` with its project.toml edited by `edit`.
fn edited(w: &Work, sub: &str, edit: impl Fn(String) -> String) -> PathBuf {
    let p = w.project(sub);
    let toml = p.join("project.toml");
    let text = fs::read_to_string(&toml).unwrap();
    let new = edit(text.clone());
    assert_ne!(new, text, "{sub}: the edit changed nothing");
    fs::write(&toml, new).unwrap();
    toml
}

/// Issue 39, "seen too": values no instrument has, a file listed twice under two
/// spellings, an empty ball label and a mount parameter that is never estimated are
/// refused before any work, naming the entry and the bound.
#[test]
fn implausible_project_values_and_files_listed_twice_are_refused_up_front() {
    let w = Work::new("implausible_project");
    let line = |t: &str, key: &str, value: &str| -> String {
        t.lines()
            .map(|l| match l.split_once(" = ") {
                Some((k, _)) if k == key => format!("{key} = {value}"),
                _ => l.to_string(),
            })
            .collect::<Vec<_>>()
            .join("\n")
            + "\n"
    };
    type Edit = Box<dyn Fn(String) -> String>;
    let cases: Vec<(&str, Edit, Vec<&str>)> = vec![
        (
            "offset",
            Box::new(move |t| line(&t, "mount_offset_mm", "[1e308, 0.0, 0.0]")),
            vec!["[lrf] mount_offset_mm = [1e308, 0, 0]", "±1000 mm"],
        ),
        (
            "tilt",
            Box::new(move |t| line(&t, "mount_tilt_x_deg", "1e308")),
            vec!["[lrf] mount_tilt_x_deg = 1e308", "±90°"],
        ),
        (
            "k1",
            Box::new(|t: String| t.replacen("k1 = 0.0", "k1 = 1e308", 1)),
            vec![
                "initial k1 = 1e308",
                "the distortion would move the sensor's corner",
            ],
        ),
        (
            "label",
            Box::new(|t: String| t.replacen("id = \"B1\"", "id = \"\"", 1)),
            vec!["[balls] labels: an id is empty"],
        ),
        (
            "offset_y",
            Box::new(|t: String| {
                t.replacen(
                    "servo_zero_deg = 0.0",
                    "servo_zero_deg = 0.0\nself_calibrate = [\"offset_y\"]",
                    1,
                )
            }),
            vec![
                "self_calibrate: \"offset_y\"",
                "never estimated",
                "estimable: offset_x",
            ],
        ),
        (
            "image_twice",
            Box::new(|t: String| {
                t.replacen(
                    "file = \"images/S01_left.png\"",
                    "file = \"images/./S00_left.png\"",
                    1,
                )
            }),
            vec!["images[2] file \"images/./S00_left.png\" is the same file as images[0]"],
        ),
        (
            "scan_twice",
            Box::new(|t: String| {
                t.replacen(
                    "scans = [\"scans/S00.csv\"]",
                    "scans = [\"scans/S00.csv\", \"scans/../scans/S00.csv\"]",
                    1,
                )
            }),
            vec!["[lrf] scans[1] \"scans/../scans/S00.csv\" is the same file as [lrf] scans[0]"],
        ),
    ];
    for (sub, edit, needles) in cases {
        let toml = edited(&w, sub, edit);
        let run = w.run(&[
            "calibrate",
            s(&toml),
            "--out",
            s(&w.dir.join("out")),
            "--quiet",
        ]);
        let mut all = needles.clone();
        all.push(s(&toml));
        fails(&run, &all);
    }
}

/// Issue 39: one range of 999,999 mm in a project's scan is masked by the project's
/// `max_range_mm` and counted in a warning that `--quiet` keeps on stderr; the calibration
/// is the clean scan's (the time is measured in bench/bounded, not here).
#[test]
fn a_far_range_in_a_projects_scan_is_masked_with_a_warning_quiet_or_not() {
    let w = Work::new("far_range_calibrate");
    let p = w.quick_project("project");
    let scan = p.join("scans/S00.csv");
    let text = fs::read_to_string(&scan).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let at = lines
        .iter()
        .position(|l| {
            !l.starts_with('#')
                && !l.starts_with("stamp_s")
                && l.split(',').skip(2).any(|r| r != "0")
        })
        .expect("a scan line with a return");
    let mut fields: Vec<String> = lines[at].split(',').map(str::to_string).collect();
    let k = 2 + fields[2..].iter().position(|r| r != "0").unwrap();
    fields[k] = "999999".into();
    lines[at] = fields.join(",");
    fs::write(&scan, lines.join("\n") + "\n").unwrap();
    let (run, out) = w.calibrate(&p, &[]);
    warns(
        &run,
        &[
            s(&scan),
            "1 range beyond the sensor's [lrf] max_range_mm = 5600",
            &format!("first on line {}", at + 1),
        ],
    );
    read_json(&out.join("results.json"));
}

/// Issue 39: two runs into one output folder at once: the second, started while the first
/// holds the folder, is refused naming the first's process; the first writes its whole set.
#[test]
fn two_runs_into_one_folder_at_once_one_is_refused_named() {
    let w = Work::new("two_at_once");
    let p = w.quick_project("project");
    let out = w.dir.join("out");
    let toml = p.join("project.toml");
    let args = ["calibrate", s(&toml), "--out", s(&out), "--quiet"];
    let lock = w.dir.join(".out.pingcal-lock");
    let mut first = std::process::Command::new(common::bin())
        .args(args)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let t0 = std::time::Instant::now();
    while !lock.exists() {
        assert!(
            t0.elapsed().as_secs() < 60,
            "the first run never took the lock"
        );
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    let second = w.run(&args);
    let status = first.wait().unwrap();
    fails(
        &second,
        &[
            "another pingcal",
            &format!("process {}", first.id()),
            "choose another --out",
        ],
    );
    assert!(status.success(), "the first run failed: {status:?}");
    for f in OUTPUTS {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    read_json(&out.join("results.json"));
    assert!(!lock.exists(), "the lock is left");
}

/// `png` with its IHDR saying `w` × `h` (the CRC made right again).
fn png_sized(png: &[u8], w: u32, h: u32) -> Vec<u8> {
    let mut p = png.to_vec();
    p[16..20].copy_from_slice(&w.to_be_bytes());
    p[20..24].copy_from_slice(&h.to_be_bytes());
    let crc = common::crc32(&p[12..29]);
    p[29..33].copy_from_slice(&crc.to_be_bytes());
    p
}

/// An uncompressed grey 64 × 50 TIFF whose one strip starts at byte `strip`.
fn tiff_with_strip_at(strip: u32) -> Vec<u8> {
    common::grey_tiff(64, 50, strip, 251)
}

/// Issue 39, "seen too": cloud and image files whose header disagrees with their data are
/// refused naming the file and what disagrees, and an image too large to hold names its
/// size, before anything is allocated.
#[test]
fn headers_that_disagree_with_their_data_are_refused() {
    let w = Work::new("header_data");
    let head = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n";
    let cases = [
        (
            "faces.ply",
            format!("{head}element face 100\nproperty list uchar int vertex_indices\nend_header\n1 2 3\n4 5 6\n7 8 10\n"),
            "file ends after 0 of 100 faces",
        ),
        (
            "zlist.ply",
            head.replace("property float z", "property list uchar float z") + "end_header\n1 2 1 3\n",
            "vertex property z is a list",
        ),
    ];
    for (name, text, needle) in cases {
        let f = w.dir.join(name);
        fs::write(&f, text).unwrap();
        let run = w.run(&["cloud", s(&f)]);
        fails(&run, &[s(&f), needle]);
    }
    let png = fs::read(common::pristine().join("images/S00_left.png")).unwrap();
    let mut images = vec![
        (
            "shrunk.png",
            png_sized(&png, 1280, 360),
            "the IHDR's size and format take".to_string(),
        ),
        (
            "huge.png",
            png_sized(&png, 30_000, 30_000),
            "30000 × 30000 pixels (900 megapixels)".to_string(),
        ),
        (
            "strip.tif",
            tiff_with_strip_at(8),
            "strip 0's data (bytes 8–3208) lies in the image file directory".to_string(),
        ),
    ];
    if let Some(b) = bad_inputs("headers_that_disagree_with_their_data_are_refused (its JPEG case)")
    {
        let mut jpeg = fs::read(b.join("jpeg_truncated_accepted_0315baa11a.jpg")).unwrap();
        jpeg.extend_from_slice(&[0xFF, 0xD9]);
        // the SOF0 of this baseline JPEG: FF C0, length, precision, height, width
        let at = jpeg.windows(2).position(|m| m == [0xFF, 0xC0]).unwrap();
        jpeg[at + 5..at + 9].copy_from_slice(&[2, 208, 0, 1]); // 720 rows, 1 column
        images.push(("sof.jpg", jpeg, "the SOF's size holds at most".to_string()));
    }
    for (name, bytes, needle) in images {
        let f = w.dir.join(name);
        fs::write(&f, bytes).unwrap();
        let run = w.run(&["detect", s(&f), "--out", s(&w.dir.join("d.json"))]);
        fails(&run, &[s(&f), &needle]);
    }
}

/// Issue 39: `pingcal cloud` on a real VLP-16 frame of a 600 mm sphere with the default
/// 38 mm diameter finds nothing of 38 mm, and says that a sphere of about 600 mm is evident,
/// where the 600 mm run finds it (the time: bench/bounded).
#[test]
fn a_sphere_of_another_size_is_named_when_the_nominal_finds_nothing() {
    let frame = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data/spherecalib-vlp16/scans/L1_S1.xyz");
    if !frame.exists() {
        println!("skipped: {} is absent", frame.display());
        return;
    }
    let w = Work::new("evident_sphere");
    let args = ["cloud", s(&frame), "--unit", "m", "--noise", "VLP-16"];
    let run = w.run(&args);
    warns(
        &run,
        &[
            "no ball of 38 mm found",
            "spheres of another size are evident: ",
        ],
    );
    let line = run.stderr.lines().find(|l| l.contains("evident")).unwrap();
    let first = line.split("evident: ").nth(1).unwrap();
    let d: f64 = first.split(" mm").next().unwrap().parse().unwrap();
    assert!((d - 600.0).abs() <= 0.1 * 600.0, "{line}");
    let at: Vec<f64> = first
        .split("at (")
        .nth(1)
        .unwrap()
        .split(')')
        .next()
        .unwrap()
        .split(", ")
        .map(|v| v.parse().unwrap())
        .collect();
    let mut full = args.to_vec();
    full.extend(["--diameter-mm", "600", "--why"]);
    let run = w.run(&full);
    let ball = run
        .stdout
        .lines()
        .find(|l| l.starts_with("ball L1: ("))
        .expect("the 600 mm ball");
    let c: Vec<f64> = ball["ball L1: (".len()..]
        .split(')')
        .next()
        .unwrap()
        .split(", ")
        .map(|v| v.parse().unwrap())
        .collect();
    let dist = (0..3).map(|k| (c[k] - at[k]).powi(2)).sum::<f64>().sqrt();
    // the free size's fixed-radius fit against the nominal's: within their radii's difference
    assert!(
        dist <= (d / 2.0 - 300.0).abs() + 10.0,
        "{line} against {ball}"
    );
}

/// Issue 39's fuzz harness (`tests/fuzz/`): every reader's valid input mutated, each case
/// under a time limit; no panic, no hang, no silent acceptance, every refusal naming the
/// file. The short form runs here; `PINGCAL_FUZZ_CASES=3000 cargo test --release -p pingcal
/// --test cli cli_safety::fuzz -- --nocapture` is the long one (`PINGCAL_FUZZ_SEED` another
/// sequence).
#[test]
fn fuzz_the_readers() {
    let env = |k: &str| std::env::var(k).ok().and_then(|v| v.parse::<u64>().ok());
    let cases = env("PINGCAL_FUZZ_CASES").map_or(fuzz::SHORT_CASES, |n| n as usize);
    let seed = env("PINGCAL_FUZZ_SEED").unwrap_or(39);
    let t0 = std::time::Instant::now();
    let tallies = fuzz::fuzz(cases, seed);
    println!(
        "{}({:.1} s, seed {seed})",
        fuzz::table(&tallies),
        t0.elapsed().as_secs_f64()
    );
    let bad: Vec<&String> = tallies.iter().flat_map(|(_, t)| &t.examples).collect();
    assert!(
        bad.is_empty(),
        "{} case(s):\n{}",
        bad.len(),
        bad.iter()
            .map(|s| s.as_str())
            .collect::<Vec<_>>()
            .join("\n")
    );
}

/// Issue 49: every closed-set key of project.toml given a wrong word — the LRF's `noise`,
/// `cloud_unit` and `servo_motion` as the others — is refused while the file is read: one
/// line naming the file, the line and the words allowed, and nothing before it (no step
/// ran, no image was read: a run that is not quiet logs its steps on stderr), no output.
#[test]
fn a_wrong_word_of_any_closed_set_is_refused_at_load_before_any_step() {
    let w = Work::new("closed_set_words");
    let bag = "[lrf.bag]\nfiles = [\"run.bag\"]\nscan_topic = \"/scan\"\nservo_topic = \"/joint_states\"\nservo_joint = \"servo\"\nservo_motion = \"auto\"\n";
    // (key, the first line starting with this, its replacement, the words allowed); a
    // replacement ending in the line it replaces inserts the wrong word before it
    let cases: [(&str, &str, &str, &str); 8] = [
        (
            "method",
            "method = ",
            "method = \"bogus\"",
            "spheres, corner",
        ),
        (
            "family",
            "family = ",
            "family = \"bogus\"",
            "aicon14, aicon12",
        ),
        (
            "model",
            "model = \"photogrammetric\"",
            "model = \"bogus\"",
            "photogrammetric",
        ),
        ("free", "free = [", "free = [\"bogus\"]", "c, xp, yp"),
        (
            "noise",
            "max_range_mm = ",
            "noise = \"bogus\"",
            "URG-04LX, UTM-30LX, UST-10LX, VLP-16",
        ),
        (
            "cloud_unit",
            "max_range_mm = ",
            "cloud_unit = \"bogus\"",
            "mm, m",
        ),
        (
            "self_calibrate",
            "max_range_mm = ",
            "self_calibrate = [\"bogus\"]",
            "offset_x, offset_y",
        ),
        (
            "servo_motion",
            "servo_motion = ",
            "servo_motion = \"bogus\"",
            "auto, stop-and-go, continuous",
        ),
    ];
    for (key, start, wrong, allowed) in cases {
        let toml = edited(&w, key, |t| {
            let mut done = false;
            let mut out = String::new();
            for l in (t + bag).lines() {
                if !done && l.starts_with(start) {
                    done = true;
                    out += wrong;
                    out += "\n";
                    if l.starts_with(&format!("{key} = ")) {
                        continue;
                    }
                }
                out += l;
                out += "\n";
            }
            out
        });
        let text = fs::read_to_string(&toml).unwrap();
        let at = text.find("\"bogus\"").expect("the wrong word");
        let line = text[..at].matches('\n').count() + 1;
        let run = w.run(&["calibrate", s(&toml), "--out", s(&w.dir.join("out"))]);
        let out = w.dir.join("out");
        let err = assert_clean_failure(
            &run,
            &out,
            &[
                &format!("{}: line {line}: {key}", s(&toml)),
                "\"bogus\"",
                &format!("expected one of {allowed}"),
            ],
        );
        assert_eq!(
            run.stderr.trim(),
            err,
            "{key}: something ran before the refusal"
        );
    }
}
