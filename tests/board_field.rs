//! `pingcal simulate` of a board field (issue 51, `[field] kind = "board"`): the files of a
//! small field are written, load as `pingcal calibrate` loads a project, and the detector
//! finds the board in every image; a bad key is refused naming it.

use crate::common::Work;
use pingcal_sim::board_field::read_board_truth;

#[test]
fn a_small_board_field_is_written_and_loads() {
    let w = Work::new("board-field");
    let config = "[field]\nkind = \"board\"\nplacements = 3\n[lrf]\nscans_per_station = 2\n";
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
