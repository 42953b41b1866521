//! Chessboards (issue 51): rendered boards with known corners, and the real OpenCV sample
//! photographs (`shared/data/opencv-chessboard`, 9 × 6 inner corners) against OpenCV's own
//! corners.
//!
//! The rendered boards are drawn in memory: a homography from the board's plane to the
//! image, each pixel the mean of 4 × 4 samples, blurred (σ ≈ 0.9 px) and with Gaussian noise
//! (σ = 0.01 of the 0–1 range). Their corners are known exactly, so the detector's error is
//! measured, not compared.
//!
//! `bench/boards/opencv-chessboard.json` is OpenCV's output on the real photographs
//! (`cv2.findChessboardCornersSB` corners and `cv2.calibrateCamera` on them), made by
//! `bench/boards/opencv.py` and committed as a reference of what OpenCV says; the images
//! themselves stay in `../shared`.

use nalgebra::{Matrix3, Vector3};
use pingcal_targets::board::{detect_chessboard, BoardMiss, Chessboard};
use pingcal_targets::GrayImage;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

const WHITE: f32 = 0.85;
const BLACK: f32 = 0.12;
const BACKGROUND: f32 = 0.45;

/// Renders `board` seen through `h` (board plane in squares, inner corner (col, row) at
/// (col, row), to pixels). The square diagonal to corner 0 is white (the numbering rule);
/// a white margin of half a square surrounds the squares.
fn render(board: &Chessboard, h: &Matrix3<f64>, w: usize, ht: usize, seed: u64) -> GrayImage {
    let inv = h.try_inverse().expect("a homography");
    let ss = 4;
    let mut img = GrayImage::new(w, ht, 0.0);
    let (c, r) = (board.cols as f64, board.rows as f64);
    for y in 0..ht {
        for x in 0..w {
            let mut acc = 0.0;
            for sy in 0..ss {
                for sx in 0..ss {
                    let px = x as f64 + (sx as f64 + 0.5) / ss as f64 - 0.5;
                    let py = y as f64 + (sy as f64 + 0.5) / ss as f64 - 0.5;
                    let q = inv * Vector3::new(px, py, 1.0);
                    let (u, v) = (q.x / q.z, q.y / q.z);
                    acc += if u < -1.5 || v < -1.5 || u > c + 0.5 || v > r + 0.5 {
                        BACKGROUND
                    } else if u < -1.0
                        || v < -1.0
                        || u > c
                        || v > r
                        || (u.floor() as i64 + v.floor() as i64).rem_euclid(2) == 0
                    {
                        WHITE
                    } else {
                        BLACK
                    };
                }
            }
            img.data[y * w + x] = acc / (ss * ss) as f32;
        }
    }
    blur_and_noise(img, seed)
}

/// Two passes of the binomial [1 2 1]/4 (σ ≈ 1 px) and Gaussian noise of 0.01.
fn blur_and_noise(img: GrayImage, seed: u64) -> GrayImage {
    blurred(img, 2, seed)
}

/// `passes` passes of the binomial [1 2 1]/4 (σ ≈ √(passes / 2) px) and Gaussian noise of
/// 0.01.
pub(crate) fn blurred(mut img: GrayImage, passes: usize, seed: u64) -> GrayImage {
    let (w, h) = (img.width, img.height);
    for _ in 0..passes {
        let src = img.data.clone();
        for y in 0..h {
            for x in 0..w {
                let at = |xx: usize, yy: usize| src[yy.min(h - 1) * w + xx.min(w - 1)];
                let (xm, ym) = (x.saturating_sub(1), y.saturating_sub(1));
                let row = |yy| 0.25 * at(xm, yy) + 0.5 * at(x, yy) + 0.25 * at(x + 1, yy);
                img.data[y * w + x] = 0.25 * row(ym) + 0.5 * row(y) + 0.25 * row(y + 1);
            }
        }
    }
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let noise = Normal::new(0.0, 0.01).expect("a normal");
    for v in &mut img.data {
        *v += noise.sample(&mut rng) as f32;
    }
    img
}

/// A view of the board: `side` px a square, turned by `angle`, centred at (cx, cy), with
/// a perspective `(px, py)` (the homography's bottom row).
fn view(
    board: &Chessboard,
    side: f64,
    angle: f64,
    centre: [f64; 2],
    persp: [f64; 2],
) -> Matrix3<f64> {
    let (s, c) = angle.sin_cos();
    let mid = [
        (board.cols as f64 - 1.0) / 2.0,
        (board.rows as f64 - 1.0) / 2.0,
    ];
    let to_mid = Matrix3::new(1.0, 0.0, -mid[0], 0.0, 1.0, -mid[1], 0.0, 0.0, 1.0);
    let rot = Matrix3::new(
        side * c,
        -side * s,
        0.0,
        side * s,
        side * c,
        0.0,
        0.0,
        0.0,
        1.0,
    );
    let p = Matrix3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, persp[0], persp[1], 1.0);
    let shift = Matrix3::new(1.0, 0.0, centre[0], 0.0, 1.0, centre[1], 0.0, 0.0, 1.0);
    shift * p * rot * to_mid
}

fn project(h: &Matrix3<f64>, col: usize, row: usize) -> [f64; 2] {
    let q = h * Vector3::new(col as f64, row as f64, 1.0);
    [q.x / q.z, q.y / q.z]
}

const NINE_BY_SIX: Chessboard = Chessboard {
    cols: 9,
    rows: 6,
    square_mm: 25.0,
};

#[test]
fn rendered_boards_are_found_whole_numbered_and_within_a_few_hundredths_of_a_pixel() {
    let mut sq = Vec::new();
    let mut z2 = Vec::new();
    // Turned through every quadrant (the numbering must follow the board, not the image),
    // tilted, 18 to 40 px a square.
    for (k, angle) in [0.1f64, 0.9, 1.7, 2.6, 3.4, 4.3, 5.2, 6.0]
        .iter()
        .enumerate()
    {
        let side = 18.0 + 3.0 * k as f64;
        let persp = [
            4e-4 * (k as f64 - 3.5) / 3.5,
            -3e-4 * ((k % 3) as f64 - 1.0),
        ];
        let h = view(&NINE_BY_SIX, side, *angle, [320.0, 240.0], persp);
        let img = render(&NINE_BY_SIX, &h, 640, 480, k as u64);
        let found = detect_chessboard(&img, &NINE_BY_SIX)
            .unwrap_or_else(|e| panic!("view {k} (turned {angle} rad): {e}"));
        assert_eq!(found.corners.len(), 54);
        assert!(!found.symmetric, "9 × 6 has one corner 0");
        for c in &found.corners {
            let t = project(&h, c.col, c.row);
            let e = [c.uv[0] - t[0], c.uv[1] - t[1]];
            assert!(
                e[0].hypot(e[1]) < 0.25,
                "view {k}: corner {} at {:?}, truth {:?} (wrong number or far off)",
                c.id,
                c.uv,
                t
            );
            sq.push(e[0] * e[0] + e[1] * e[1]);
            z2.push((e[0] * e[0] + e[1] * e[1]) / (2.0 * c.sigma_px * c.sigma_px));
        }
    }
    let rms = (sq.iter().sum::<f64>() / sq.len() as f64).sqrt();
    let z = (z2.iter().sum::<f64>() / z2.len() as f64).sqrt();
    println!(
        "rendered 9 × 6 boards: {} corners, RMS error {rms:.4} px, RMS error/σ {z:.2}",
        sq.len()
    );
    assert!(rms < 0.05, "RMS {rms} px");
    // The σ's come from the fit's residuals, which on a rendered board are mostly the
    // corner's own shape, not noise: pessimistic here (error/σ ≈ 0.2), about right on the
    // real photographs (median σ 0.13 px per coordinate against a calibration RMS of
    // 0.19 px per point, 0.13 per coordinate; bench/boards/README.md).
    assert!(z > 0.1 && z < 5.0, "RMS error/σ {z}");
}

#[test]
fn a_board_symmetric_under_a_half_turn_says_so_and_takes_corner_0_nearest_the_top_left() {
    let board = Chessboard {
        cols: 8,
        rows: 6,
        square_mm: 20.0,
    };
    for (k, angle) in [0.05f64, std::f64::consts::PI + 0.05].iter().enumerate() {
        let h = view(&board, 30.0, *angle, [320.0, 240.0], [0.0, 0.0]);
        let img = render(&board, &h, 640, 480, 10 + k as u64);
        let found = detect_chessboard(&img, &board).expect("found");
        assert!(found.symmetric);
        let first = found.corners[0].uv;
        let last = found.corners[47].uv;
        assert!(
            first[0].hypot(first[1]) < last[0].hypot(last[1]),
            "{first:?} {last:?}"
        );
    }
}

#[test]
fn a_board_partly_outside_the_image_or_of_another_size_is_refused_with_a_reason() {
    // Shifted so that two columns fall outside the image.
    let h = view(&NINE_BY_SIX, 40.0, 0.0, [120.0, 240.0], [0.0, 0.0]);
    let img = render(&NINE_BY_SIX, &h, 640, 480, 20);
    let miss = detect_chessboard(&img, &NINE_BY_SIX).expect_err("partly outside");
    assert!(
        matches!(
            miss,
            BoardMiss::WrongGrid { .. } | BoardMiss::TooFewCandidates { .. }
        ),
        "{miss}"
    );
    println!("partly outside: {miss}");
    // A whole 9 × 6 board looked for as 7 × 6 is not taken for one.
    let h = view(&NINE_BY_SIX, 30.0, 0.2, [320.0, 240.0], [0.0, 0.0]);
    let img = render(&NINE_BY_SIX, &h, 640, 480, 21);
    let seven = Chessboard {
        cols: 7,
        ..NINE_BY_SIX
    };
    match detect_chessboard(&img, &seven) {
        Err(miss) => {
            println!("7 × 6 looked for on a 9 × 6: {miss}");
            assert!(matches!(miss, BoardMiss::LargerBoard { .. }), "{miss}");
        }
        Ok(d) => panic!("a 9 × 6 board taken for a 7 × 6: {:?}", d.corners[0]),
    }
}

#[test]
fn a_board_too_blurred_for_the_images_own_scale_is_found_on_a_coarser_one() {
    // σ ≈ 7 px: the corners are too wide for the candidates at the image's own scale.
    let h = view(&NINE_BY_SIX, 60.0, 0.3, [400.0, 300.0], [1e-4, -1e-4]);
    let sharp = render(&NINE_BY_SIX, &h, 800, 600, 30);
    let img = blurred(sharp, 98, 31);
    let found = detect_chessboard(&img, &NINE_BY_SIX).expect("found on a coarser level");
    let sq: f64 = found
        .corners
        .iter()
        .map(|c| {
            let t = project(&h, c.col, c.row);
            (c.uv[0] - t[0]).powi(2) + (c.uv[1] - t[1]).powi(2)
        })
        .sum();
    let rms = (sq / 54.0).sqrt();
    println!("blurred (σ ≈ 7 px) board: RMS error {rms:.3} px");
    // The edges are 7 px wide, their gradient a tenth of a sharp one's against the same noise.
    assert!(rms < 0.35, "RMS {rms} px");
}

#[test]
fn images_without_a_board_are_refused_with_a_reason_and_never_a_panic() {
    use rand::Rng;
    let mut rng = rand::rngs::StdRng::seed_from_u64(40);
    let noise = GrayImage {
        width: 320,
        height: 240,
        data: (0..320 * 240).map(|_| rng.random::<f32>()).collect(),
    };
    let flat = GrayImage::new(320, 240, 0.5);
    let tiny = GrayImage::new(5, 3, 0.5);
    let empty = GrayImage::new(0, 0, 0.0);
    for (what, img) in [
        ("noise", &noise),
        ("flat", &flat),
        ("tiny", &tiny),
        ("empty", &empty),
    ] {
        match detect_chessboard(img, &NINE_BY_SIX) {
            Err(miss) => println!("{what}: {miss}"),
            Ok(d) => panic!("{what}: a board of {} corners", d.corners.len()),
        }
    }
    let bad = Chessboard {
        cols: 1,
        ..NINE_BY_SIX
    };
    assert!(matches!(
        detect_chessboard(&flat, &bad),
        Err(BoardMiss::BadBoard { .. })
    ));
}

mod real {
    //! The OpenCV sample photographs against OpenCV's corners.

    use super::NINE_BY_SIX;
    use pingcal_targets::board::detect_chessboard;
    use std::path::{Path, PathBuf};

    fn data() -> Option<PathBuf> {
        let p =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/opencv-chessboard");
        p.join("left01.jpg").exists().then_some(p)
    }

    fn reference() -> serde_json::Value {
        let p =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../../bench/boards/opencv-chessboard.json");
        serde_json::from_str(&std::fs::read_to_string(p).expect("the committed reference"))
            .expect("JSON")
    }

    /// Every board OpenCV finds is found, all 54 corners numbered as OpenCV numbers them
    /// (each within 2 px of OpenCV's corner of the same number: the squares are 20–40 px,
    /// so a wrong number would be a square away), and the corners agree with OpenCV's
    /// within the bound measured (see bench/boards/README.md for why not 0.1 px).
    #[test]
    fn every_board_opencv_finds_is_found_with_its_corners_numbered_as_opencv_numbers_them() {
        let Some(dir) = data() else {
            println!("skipped: ../shared/data/opencv-chessboard is absent");
            return;
        };
        let reference = reference();
        let mut sq = Vec::new();
        let mut found_here = 0;
        for image in reference["images"].as_array().expect("images") {
            let name = image["image"].as_str().expect("name");
            let img = pingcal_targets::load_image(&dir.join(name)).expect("image");
            let found = detect_chessboard(&img, &NINE_BY_SIX);
            let Some(theirs) = image["corners"].as_array() else {
                println!(
                    "{name}: OpenCV finds no board; pingcal: {}",
                    found
                        .as_ref()
                        .map(|_| "found".to_string())
                        .unwrap_or_else(|e| e.to_string())
                );
                continue;
            };
            let ours =
                found.unwrap_or_else(|e| panic!("{name}: OpenCV finds the board, pingcal: {e}"));
            found_here += 1;
            assert_eq!(ours.corners.len(), 54, "{name}");
            for (c, t) in ours.corners.iter().zip(theirs) {
                let (x, y) = (t[0].as_f64().expect("x"), t[1].as_f64().expect("y"));
                let d = (c.uv[0] - x).hypot(c.uv[1] - y);
                assert!(
                    d < 2.0,
                    "{name}: corner {} at {:?}, OpenCV's at ({x}, {y})",
                    c.id,
                    c.uv
                );
                sq.push(d * d);
            }
        }
        let rms = (sq.iter().sum::<f64>() / sq.len() as f64).sqrt();
        println!("{found_here} boards, {} corners: RMS distance to cv2.findChessboardCornersSB's {rms:.3} px", sq.len());
        assert_eq!(found_here, 25);
        assert!(rms < 0.4, "RMS {rms} px from OpenCV's SB corners");
    }
}
