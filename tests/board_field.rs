//! `pingcal simulate` of a board field (issue 51, `[field] kind = "board"`): the files of a
//! small field are written, load as `pingcal calibrate` loads a project, and the detector
//! finds the board in every image; a bad key is refused naming it. `pingcal calibrate` of a
//! board project: its results, overlays, report and exports; a board given the wrong size
//! refused, a wrong square named by the verdict.

use crate::common::{copy_dir, read_json, replace_once, Work};
use pingcal_sim::board_field::read_board_truth;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

#[test]
fn a_small_board_field_is_written_and_loads() {
    let w = Work::new("board-field");
    let config = "[field]\nkind = \"board\"\nplacements = 3\nscans_per_placement = 2\n";
    let dir = w.simulate("field", config);
    let project = pingcal_project::Project::load(&dir.join("project.toml")).unwrap();
    assert_eq!(project.file.images.len(), 3);
    assert_eq!(project.scans.len(), 3);
    let truth = read_board_truth(&dir.join("truth.json")).unwrap();
    assert_eq!(truth.placements.len(), 3);
    assert!(truth
        .placements
        .iter()
        .all(|p| p.board_beams_per_scan.iter().all(|&n| n >= 30)));
    let images: Vec<String> = (1..=3)
        .map(|k| dir.join(format!("images/P{k}.png")).display().to_string())
        .collect();
    let mut args = vec!["detect", "--board", "7x5"];
    args.extend(images.iter().map(String::as_str));
    let run = w.run(&args);
    assert!(run.success(), "{}", run.stderr);
    assert!(
        (run.stdout.lines().chain(run.stderr.lines()))
            .any(|l| l.contains("chessboard 7 × 5 found in 3 of 3 images")),
        "{}\n{}",
        run.stdout,
        run.stderr
    );
    let bad = w.dir.join("bad.toml");
    std::fs::write(&bad, "[field]\nkind = \"board\"\nplacements = 2\n").unwrap();
    let out = w.dir.join("bad");
    let run = w.run(&[
        "simulate",
        "--out",
        out.to_str().unwrap(),
        "--config",
        bad.to_str().unwrap(),
    ]);
    assert!(!run.success());
    assert!(
        run.stderr
            .contains("field.placements = 2: expected 3 to 100 placements of the board"),
        "{}",
        run.stderr
    );
    assert!(!out.exists());
}

/// The default board field (8 placements of a 7 × 5 chessboard before a fixed LRF), made once
/// per test run.
fn board_field() -> &'static Path {
    static FIELD: OnceLock<(Work, PathBuf)> = OnceLock::new();
    let (_, dir) = FIELD.get_or_init(|| {
        let w = Work::new("board-calibrate-field");
        let dir = w.simulate("field", "[field]\nkind = \"board\"\n");
        (w, dir)
    });
    dir
}

/// A copy of the board field in `w` with `[board] square_mm = 60.0` made `square` (and the
/// inner corners `corners`).
fn board_given(w: &Work, corners: &str, square: &str) -> PathBuf {
    let dir = w.dir.join("given");
    copy_dir(board_field(), &dir);
    let toml = dir.join("project.toml");
    replace_once(&toml, "inner_corners = [7, 5]", corners);
    replace_once(&toml, "square_mm = 60.0", square);
    dir
}

/// The board project calibrates: verdict ok, the extrinsic within 5 mm and 0.3° of the truth,
/// every station's beams on the board (`board_beams`, `board_beams_rms_mm` near the
/// scanner's 10 mm σ), the board's scale 1 within 4σ; the overlays, the report and the ROS,
/// OpenCV and Kalibr files written with them.
#[test]
fn a_board_project_calibrates_with_its_beams_on_the_board() {
    let w = Work::new("board-calibrate");
    let (run, out) = w.calibrate(board_field(), &[]);
    assert!(run.success(), "{}\n{}", run.stdout, run.stderr);
    assert!(run.stdout.contains("verdict ok"), "{}", run.stdout);
    let r = read_json(&out.join("results.json"));
    let t = read_json(&board_field().join("truth.json"));
    assert_eq!(r["method"], "board");
    assert_eq!(r["verdict"]["status"], "ok", "{}", r["verdict"]);
    let (e, tr) = (&r["extrinsic"], &t["extrinsic"]);
    let dt: f64 = (0..3)
        .map(|k| {
            (e["translation_mm"][k].as_f64().unwrap() - tr["translation_mm"][k].as_f64().unwrap())
                .powi(2)
        })
        .sum::<f64>()
        .sqrt();
    assert!(dt < 5.0, "|Δt| {dt} mm: {e}");
    for k in 0..3 {
        let d = e["opk_deg"][k].as_f64().unwrap() - tr["opk_deg"][k].as_f64().unwrap();
        assert!(d.abs() < 0.3, "opk {k}: {d}°");
    }
    let stations = r["stations"].as_array().unwrap();
    assert_eq!(stations.len(), 8);
    for s in stations {
        let n = s["board_beams"].as_u64().unwrap();
        let rms = s["board_beams_rms_mm"].as_f64().unwrap();
        assert!(n > 300 && (7.0..15.0).contains(&rms), "{s}");
    }
    let (scale, sd) = (
        r["board_scale"].as_f64().unwrap(),
        r["board_scale_sigma"].as_f64().unwrap(),
    );
    assert!((scale - 1.0).abs() < 4.0 * sd, "{scale} ± {sd}");
    for f in [
        "report.html",
        "overlays/P1.png",
        "ros/laser_joint.urdf",
        "opencv/camera_left.yaml",
        "kalibr/camchain.yaml",
    ] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
}

/// A board given with the wrong number of inner corners is found in no photograph: the
/// calibration is refused with the detector's reason for each image.
#[test]
fn a_board_of_the_wrong_size_is_refused() {
    let w = Work::new("board-wrong-size");
    let dir = board_given(&w, "inner_corners = [9, 6]", "square_mm = 60.0");
    w.calibrate_fails(
        &dir,
        "data",
        &["the chessboard 9 × 6 inner corners, 60 mm squares was found in 0 of 8 photographs"],
    );
}

/// A board given with the wrong square (50 mm for its 60): the LRF's metric ranges show it
/// (the board's scale 1.2, named by the verdict), and the extrinsic stays metric.
#[test]
fn a_wrong_square_is_named_by_the_verdict() {
    let w = Work::new("board-wrong-square");
    let dir = board_given(&w, "inner_corners = [7, 5]", "square_mm = 50.0");
    let (run, out) = w.calibrate(&dir, &["--accept-doubtful"]);
    assert!(run.success(), "{}", run.stderr);
    let r = read_json(&out.join("results.json"));
    assert_eq!(r["verdict"]["status"], "doubtful");
    let reasons = r["verdict"]["reasons"].to_string();
    assert!(
        reasons.contains("the board's scale against the LRF's ranges is 1.2"),
        "{reasons}"
    );
    let (scale, sd) = (
        r["board_scale"].as_f64().unwrap(),
        r["board_scale_sigma"].as_f64().unwrap(),
    );
    assert!((scale - 1.2).abs() < 4.0 * sd, "{scale} ± {sd}");
    let t = read_json(&board_field().join("truth.json"));
    let dt: f64 = (0..3)
        .map(|k| {
            (r["extrinsic"]["translation_mm"][k].as_f64().unwrap()
                - t["extrinsic"]["translation_mm"][k].as_f64().unwrap())
            .powi(2)
        })
        .sum::<f64>()
        .sqrt();
    assert!(dt < 5.0, "|Δt| {dt} mm");
}

/// `pingcal detect --board FILE` and `pingcal targets --board FILE` with a board a file
/// describes: a simulated ChArUco board found in its photographs by its project's `[board]`,
/// an AprilGrid by Kalibr's `target.yaml`, and a ChArUco board printed at true size.
#[test]
fn boards_with_markers_are_found_and_printed_from_a_file() {
    let w = Work::new("board-files");
    let charuco = "kind = \"charuco\"\ninner_corners = [7, 5]\nsquare_mm = 60.0\nmarker_mm = 45.0\ndictionary = \"DICT_5X5_100\"";
    let config = format!(
        "[field]\nkind = \"board\"\nplacements = 3\nscans_per_placement = 1\n[board]\n{charuco}\n"
    );
    let dir = w.simulate("charuco", &config);
    let project = dir.join("project.toml");
    let images: Vec<String> = (1..=3)
        .map(|k| dir.join(format!("images/P{k}.png")).display().to_string())
        .collect();
    let mut args = vec!["detect", "--board", project.to_str().unwrap()];
    args.extend(images.iter().map(String::as_str));
    let run = w.run(&args);
    assert!(run.success(), "{}", run.stderr);
    assert!(
        run.stdout.contains("detect: ChArUco board 7 × 5 inner corners, 60 mm squares, 45 mm DICT_5X5_100 markers found in 3 of 3 images"),
        "{}",
        run.stdout
    );
    let small = w.dir.join("small.toml");
    std::fs::write(
        &small,
        "[board]\nkind = \"charuco\"\ninner_corners = [5, 3]\nsquare_mm = 30.0\nmarker_mm = 22.0\ndictionary = \"DICT_4X4_50\"\n",
    )
    .unwrap();
    let svg = w.dir.join("charuco.svg");
    let run = w.run(&[
        "targets",
        "--board",
        small.to_str().unwrap(),
        "--out",
        svg.to_str().unwrap(),
    ]);
    assert!(run.success(), "{}", run.stderr);
    assert!(svg.is_file());
    let yaml = w.dir.join("target.yaml");
    std::fs::write(
        &yaml,
        "target_type: 'aprilgrid'\ntagCols: 6\ntagRows: 4\ntagSize: 0.06\ntagSpacing: 0.3\n",
    )
    .unwrap();
    let grid = w.simulate(
        "aprilgrid",
        "[field]\nkind = \"board\"\nplacements = 3\nscans_per_placement = 1\n[board]\nkind = \"aprilgrid\"\ntags = [6, 4]\ntag_mm = 60.0\ntag_spacing = 0.3\n",
    );
    let image = grid.join("images/P1.png");
    let run = w.run(&[
        "detect",
        "--board",
        yaml.to_str().unwrap(),
        image.to_str().unwrap(),
    ]);
    assert!(run.success(), "{}", run.stderr);
    assert!(
        run.stdout
            .contains("AprilGrid 6 × 4 tag36h11 tags of 60 mm, spacing 0.3 found in 1 of 1 images"),
        "{}",
        run.stdout
    );
}

/// A board project with a rotating LRF is refused in one line (its sweep is not a fixed
/// scanner's scans at the placements), and one whose photograph cannot be read names it.
#[test]
fn a_board_project_refuses_a_rotating_lrf_and_an_unreadable_photograph() {
    let w = Work::new("board-refusals");
    let dir = board_given(&w, "inner_corners = [7, 5]", "square_mm = 60.0");
    let toml = dir.join("project.toml");
    let text = std::fs::read_to_string(&toml).unwrap();
    let first = text.find("[[lrf.scans]]").unwrap();
    let second = first + 1 + text[first + 1..].find("[[lrf.scans]]").unwrap();
    let rotating = text[..second].replacen("kind = \"fixed\"", "kind = \"rotating\"", 1);
    std::fs::write(&toml, &rotating).unwrap();
    w.calibrate_fails(
        &dir,
        "input",
        &[
            "a board project calibrates a fixed LRF",
            "a rotating LRF before a board is not supported",
        ],
    );
    std::fs::write(&toml, &text).unwrap();
    std::fs::write(dir.join("images/P4.png"), b"not an image").unwrap();
    w.calibrate_fails(
        &dir,
        "input",
        &["images/P4.png", "not a TIFF, PNG or JPEG image"],
    );
}
