//! `pingcal targets --board` and `pingcal detect --board` (issue 51): a chessboard printed at
//! true size, found and numbered in the real OpenCV sample photographs (skipped when
//! `../shared/data/opencv-chessboard` is absent), and bad board sizes refused in one line.

use crate::common::Work;
use std::path::Path;

#[test]
fn a_chessboard_is_printed_with_its_squares_at_true_size() {
    let w = Work::new("boards-print");
    let out = w.dir.join("board.svg");
    let run = w.run(&[
        "targets",
        "--board",
        "9x6",
        "--square-mm",
        "25",
        "--out",
        out.to_str().expect("utf-8"),
    ]);
    assert_eq!(run.code, Some(0), "{}", run.stderr);
    let svg = std::fs::read_to_string(&out).expect("the SVG");
    // 10 × 7 squares, 35 of them black, each 25 mm on a side (the page is in millimetres).
    let squares = svg
        .matches(r#"width="25.0000" height="25.0000" fill="black""#)
        .count();
    assert_eq!(squares, 35, "{}", &svg[..svg.len().min(2000)]);
    let run = w.run(&[
        "targets",
        "--board",
        "9x6",
        "--square-mm",
        "40",
        "--out",
        out.to_str().expect("utf-8"),
    ]);
    assert_eq!(run.code, Some(1));
    assert!(
        run.stderr.contains("does not fit on A4 paper"),
        "{}",
        run.stderr
    );
    let run = w.run(&[
        "targets",
        "--board",
        "9by6",
        "--square-mm",
        "25",
        "--out",
        out.to_str().expect("utf-8"),
    ]);
    assert!(
        run.stderr
            .starts_with("pingcal: error: board '9by6': expected the inner corners as COLSxROWS"),
        "{}",
        run.stderr
    );
}

#[test]
fn the_real_sample_photographs_show_their_boards_numbered() {
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/opencv-chessboard");
    if !data.join("left01.jpg").exists() {
        println!("skipped: ../shared/data/opencv-chessboard is absent");
        return;
    }
    let w = Work::new("boards-detect");
    let out = w.dir.join("corners.json");
    let images: Vec<String> = ["left01.jpg", "left12.jpg", "right09.jpg"]
        .iter()
        .map(|n| data.join(n).display().to_string())
        .collect();
    let mut args = vec![
        "detect",
        "--board",
        "9x6",
        "--out",
        out.to_str().expect("utf-8"),
    ];
    args.extend(images.iter().map(String::as_str));
    let run = w.run(&args);
    assert_eq!(run.code, Some(0), "{}", run.stderr);
    assert!(
        run.stdout
            .contains("chessboard 9 × 6 found in 3 of 3 images"),
        "{}",
        run.stdout
    );
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).expect("JSON")).expect("JSON");
    for image in doc["images"].as_array().expect("images") {
        let corners = image["corners"].as_array().expect("corners");
        assert_eq!(corners.len(), 54);
        for (k, c) in corners.iter().enumerate() {
            assert_eq!(c["id"], k);
            assert_eq!(c["col"], k % 9);
            assert_eq!(c["row"], k / 9);
        }
    }
    // The same photograph looked at for a smaller board: refused with the reason.
    let run = w.run(&["detect", "--board", "7x6", &images[0]]);
    assert_eq!(run.code, Some(0), "{}", run.stderr);
    assert!(
        run.stdout
            .contains("no chessboard 7 × 6: the grid of 7 × 6 inner corners goes on past its side"),
        "{}",
        run.stdout
    );
}
