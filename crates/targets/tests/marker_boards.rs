//! ChArUco boards and AprilGrids (issue 51), rendered with known corners: every corner in
//! view found with its id, within a tenth of a pixel RMS of the truth, no wrong id; boards
//! turned through every quadrant, upside down, a third out of the image, and of another
//! dictionary.
//!
//! The boards are drawn in memory from their own `is_white` (the layout the detector reads
//! is the layout the renderer draws, so the layouts themselves are checked apart: OpenCV's
//! and Kalibr's corner numbering against their frames in the unit tests and below), through
//! a homography from the board's plane (mm) to the image, each pixel the mean of 4 × 4
//! samples, blurred (σ ≈ 1 px) and with Gaussian noise (σ = 0.01), as the chessboards of
//! `boards.rs`.

use super::boards::blurred;
use nalgebra::{Matrix3, Vector3};
use pingcal_targets::board::{
    detect_aprilgrid, detect_charuco, Aprilgrid, Charuco, MarkerBoardDetection, MarkerDictionary,
};
use pingcal_targets::GrayImage;

const WHITE: f32 = 0.85;
const BLACK: f32 = 0.12;
const BACKGROUND: f32 = 0.45;

/// Renders a board whose shade at a board point (mm) is `shade` through `h` (mm → px).
fn render(
    shade: impl Fn(f64, f64) -> f32,
    h: &Matrix3<f64>,
    w: usize,
    ht: usize,
    seed: u64,
) -> GrayImage {
    let inv = h.try_inverse().expect("a homography");
    let ss = 4;
    let mut img = GrayImage::new(w, ht, 0.0);
    for y in 0..ht {
        for x in 0..w {
            let mut acc = 0.0;
            for sy in 0..ss {
                for sx in 0..ss {
                    let px = x as f64 + (sx as f64 + 0.5) / ss as f64 - 0.5;
                    let py = y as f64 + (sy as f64 + 0.5) / ss as f64 - 0.5;
                    let q = inv * Vector3::new(px, py, 1.0);
                    acc += shade(q.x / q.z, q.y / q.z);
                }
            }
            img.data[y * w + x] = acc / (ss * ss) as f32;
        }
    }
    blurred(img, 2, seed)
}

/// A view: the board point `mid` (mm) at `centre` (px), `scale` px a mm, turned by `angle`,
/// with a perspective `persp` (the homography's bottom row, per px).
fn view(mid: [f64; 2], scale: f64, angle: f64, centre: [f64; 2], persp: [f64; 2]) -> Matrix3<f64> {
    let (s, c) = angle.sin_cos();
    let to_mid = Matrix3::new(1.0, 0.0, -mid[0], 0.0, 1.0, -mid[1], 0.0, 0.0, 1.0);
    let rot = Matrix3::new(
        scale * c,
        -scale * s,
        0.0,
        scale * s,
        scale * c,
        0.0,
        0.0,
        0.0,
        1.0,
    );
    let p = Matrix3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, persp[0], persp[1], 1.0);
    let shift = Matrix3::new(1.0, 0.0, centre[0], 0.0, 1.0, centre[1], 0.0, 0.0, 1.0);
    shift * p * rot * to_mid
}

fn project(h: &Matrix3<f64>, p: [f64; 3]) -> [f64; 2] {
    let q = h * Vector3::new(p[0], p[1], 1.0);
    [q.x / q.z, q.y / q.z]
}

/// What a detection scored against the truth.
#[derive(Default, Debug)]
struct Score {
    found: usize,
    expected: usize,
    wrong: usize,
    sq: f64,
}

impl Score {
    /// Adds `det` against `truth` (each id's true position), `expected` of them in view. A
    /// corner more than 1 px from its id's truth is a wrong id.
    fn add(
        &mut self,
        det: &MarkerBoardDetection,
        truth: impl Fn(usize) -> [f64; 2],
        expected: usize,
    ) {
        for c in &det.corners {
            let t = truth(c.id);
            let d2 = (c.uv[0] - t[0]).powi(2) + (c.uv[1] - t[1]).powi(2);
            if d2 > 1.0 {
                self.wrong += 1;
            } else {
                self.sq += d2;
                self.found += 1;
            }
        }
        self.expected += expected;
    }

    fn rms(&self) -> f64 {
        (self.sq / self.found.max(1) as f64).sqrt()
    }
}

/// The turns of the views: every quadrant, upside down (π) among them.
const ANGLES: [f64; 8] = [0.1, 0.9, 1.7, 2.6, std::f64::consts::PI, 4.3, 5.2, 6.0];

fn charuco(dict: &str) -> Charuco {
    Charuco {
        cols: 6,
        rows: 4,
        square_mm: 20.0,
        marker_mm: 15.0,
        dictionary: MarkerDictionary::named(dict).unwrap(),
    }
}

fn charuco_shade(b: &Charuco) -> impl Fn(f64, f64) -> f32 + '_ {
    let pad = 0.5 * b.square_mm;
    let (wmm, hmm) = (
        (b.cols + 1) as f64 * b.square_mm,
        (b.rows + 1) as f64 * b.square_mm,
    );
    move |x, y| match b.is_white(x, y) {
        Some(true) => WHITE,
        Some(false) => BLACK,
        None if x > -pad && y > -pad && x < wmm + pad && y < hmm + pad => WHITE,
        None => BACKGROUND,
    }
}

/// A ChArUco view `k`: turned by ANGLES[k], 1.9 to 2.5 px a mm, a slight perspective.
fn charuco_view(b: &Charuco, k: usize, centre: [f64; 2]) -> Matrix3<f64> {
    let mid = [
        0.5 * (b.cols + 1) as f64 * b.square_mm,
        0.5 * (b.rows + 1) as f64 * b.square_mm,
    ];
    let persp = [
        4e-4 * (k as f64 - 3.5) / 3.5,
        -3e-4 * ((k % 3) as f64 - 1.0),
    ];
    view(mid, 1.9 + 0.08 * k as f64, ANGLES[k], centre, persp)
}

/// Corners at least `margin` px inside the image.
fn in_view(points: impl Iterator<Item = [f64; 2]>, w: f64, h: f64, margin: f64) -> usize {
    points
        .filter(|p| p[0] > margin && p[1] > margin && p[0] < w - margin && p[1] < h - margin)
        .count()
}

#[test]
fn charuco_boards_turned_every_way_give_every_corner_with_its_id() {
    let mut score = Score::default();
    for dict in ["DICT_5X5_100", "DICT_4X4_50", "DICT_6X6_250"] {
        let b = charuco(dict);
        for k in 0..ANGLES.len() {
            let h = charuco_view(&b, k, [320.0, 240.0]);
            let img = render(charuco_shade(&b), &h, 640, 480, k as u64);
            let det = detect_charuco(&img, &b).unwrap_or_else(|e| panic!("{dict} view {k}: {e}"));
            let truth = |id| project(&h, b.board_point(id));
            let before = score.found;
            score.add(&det, truth, b.corner_count());
            assert_eq!(
                score.found - before,
                b.corner_count(),
                "{dict} view {k}: {det:?}"
            );
        }
    }
    println!("ChArUco whole: {score:?}, RMS {:.3} px", score.rms());
    assert_eq!(score.wrong, 0);
    assert_eq!(score.found, score.expected);
    assert!(score.rms() < 0.1, "RMS {} px", score.rms());
}

#[test]
fn charuco_boards_a_third_out_of_the_image_give_their_visible_corners_with_their_ids() {
    let b = charuco("DICT_5X5_100");
    let mut score = Score::default();
    for k in 0..ANGLES.len() {
        // The board's centre near the image's edge: about a third of it outside.
        let centre = [[90.0, 240.0], [550.0, 240.0], [320.0, 70.0], [320.0, 410.0]][k % 4];
        let h = charuco_view(&b, k, centre);
        let img = render(charuco_shade(&b), &h, 640, 480, 100 + k as u64);
        let truth = |id| project(&h, b.board_point(id));
        // In view: a square's side from the image's edge (a corner needs a marker beside it).
        let side = 20.0 * (1.9 + 0.08 * k as f64);
        let visible = in_view((0..b.corner_count()).map(truth), 640.0, 480.0, side);
        let all = in_view((0..b.corner_count()).map(truth), 640.0, 480.0, 0.0);
        assert!(all < b.corner_count(), "view {k}: the board is not cut");
        let det = detect_charuco(&img, &b).unwrap_or_else(|e| panic!("view {k}: {e}"));
        let before = (score.found, score.wrong);
        score.add(&det, truth, visible);
        let found = score.found - before.0;
        assert!(
            found >= visible,
            "view {k}: {found} of {visible} corners in view"
        );
    }
    println!("ChArUco cut: {score:?}, RMS {:.3} px", score.rms());
    assert_eq!(score.wrong, 0);
    assert!(score.rms() < 0.1, "RMS {} px", score.rms());
}

#[test]
fn a_board_of_another_dictionary_or_kind_is_refused_in_one_line_never_given_wrong_ids() {
    let cases = [
        ("DICT_4X4_50", "DICT_5X5_100"),
        ("DICT_6X6_250", "DICT_4X4_50"),
        ("DICT_5X5_100", "DICT_6X6_250"),
        ("DICT_4X4_50", "DICT_ARUCO_ORIGINAL"),
    ];
    for (k, (drawn, sought)) in cases.into_iter().enumerate() {
        let b = charuco(drawn);
        let h = charuco_view(&b, k, [320.0, 240.0]);
        let img = render(charuco_shade(&b), &h, 640, 480, 200 + k as u64);
        let e =
            detect_charuco(&img, &charuco(sought)).expect_err(&format!("{drawn} read as {sought}"));
        let line = e.to_string();
        assert!(
            !line.contains('\n') && line.contains("markers read"),
            "{line}"
        );
        let e =
            detect_aprilgrid(&img, &aprilgrid()).expect_err("a ChArUco board read as an AprilGrid");
        assert!(!e.to_string().contains('\n'));
    }
    let g = aprilgrid();
    let h = aprilgrid_view(&g, 1, [320.0, 240.0]);
    let img = render(aprilgrid_shade(&g), &h, 640, 480, 210);
    for dict in ["DICT_6X6_250", "DICT_6X6_1000", "DICT_4X4_50"] {
        detect_charuco(&img, &charuco(dict)).expect_err(&format!("an AprilGrid read as {dict}"));
    }
}

fn aprilgrid() -> Aprilgrid {
    Aprilgrid {
        cols: 4,
        rows: 3,
        tag_mm: 30.0,
        spacing: 0.3,
        family: MarkerDictionary::named("tag36h11").unwrap(),
    }
}

fn aprilgrid_shade(g: &Aprilgrid) -> impl Fn(f64, f64) -> f32 + '_ {
    let pitch = (1.0 + g.spacing) * g.tag_mm;
    let (wmm, hmm) = (g.cols as f64 * pitch, g.rows as f64 * pitch);
    move |x, y| {
        if x < -pitch || y < -pitch || x > wmm + pitch || y > hmm + pitch {
            BACKGROUND
        } else if g.is_white(x, y) {
            WHITE
        } else {
            BLACK
        }
    }
}

/// An AprilGrid view `k`: turned by ANGLES[k], 1.6 to 2.2 px a mm, y up on the board (its
/// frame seen from the front: the image's y flipped).
fn aprilgrid_view(g: &Aprilgrid, k: usize, centre: [f64; 2]) -> Matrix3<f64> {
    let pitch = (1.0 + g.spacing) * g.tag_mm;
    let mid = [0.5 * g.cols as f64 * pitch, 0.5 * g.rows as f64 * pitch];
    let persp = [
        4e-4 * (k as f64 - 3.5) / 3.5,
        -3e-4 * ((k % 3) as f64 - 1.0),
    ];
    let flip = Matrix3::new(1.0, 0.0, 0.0, 0.0, -1.0, 2.0 * mid[1], 0.0, 0.0, 1.0);
    view(mid, 1.6 + 0.08 * k as f64, ANGLES[k], centre, persp) * flip
}

#[test]
fn aprilgrids_turned_every_way_give_every_tag_corner_with_kalibrs_id() {
    let g = aprilgrid();
    let mut score = Score::default();
    for k in 0..ANGLES.len() {
        let h = aprilgrid_view(&g, k, [320.0, 240.0]);
        let img = render(aprilgrid_shade(&g), &h, 640, 480, 300 + k as u64);
        let det = detect_aprilgrid(&img, &g).unwrap_or_else(|e| panic!("view {k}: {e}"));
        let truth = |id| project(&h, g.board_point(id));
        let before = score.found;
        score.add(&det, truth, g.corner_count());
        assert_eq!(score.found - before, g.corner_count(), "view {k}: {det:?}");
    }
    println!("AprilGrid whole: {score:?}, RMS {:.3} px", score.rms());
    assert_eq!(score.wrong, 0);
    assert!(score.rms() < 0.1, "RMS {} px", score.rms());
}

#[test]
fn aprilgrids_a_third_out_of_the_image_give_their_visible_corners_with_their_ids() {
    let g = aprilgrid();
    let mut score = Score::default();
    for k in 0..ANGLES.len() {
        let centre = [[90.0, 240.0], [550.0, 240.0], [320.0, 80.0], [320.0, 400.0]][k % 4];
        let h = aprilgrid_view(&g, k, centre);
        let img = render(aprilgrid_shade(&g), &h, 640, 480, 400 + k as u64);
        let truth = |id| project(&h, g.board_point(id));
        // In view: whole tags (a tag is read whole), a tag's side from the image's edge.
        let side = g.tag_mm * (1.6 + 0.08 * k as f64);
        let tags_in = (0..g.cols * g.rows).filter(|&t| {
            let base = 2 * (t / g.cols) * 2 * g.cols + 2 * (t % g.cols);
            let pts = [base, base + 1, base + 2 * g.cols, base + 2 * g.cols + 1];
            in_view(pts.iter().map(|&p| truth(p)), 640.0, 480.0, 0.3 * side) == 4
        });
        let visible = 4 * tags_in.count();
        assert!(visible < g.corner_count(), "view {k}: the board is not cut");
        let det = detect_aprilgrid(&img, &g).unwrap_or_else(|e| panic!("view {k}: {e}"));
        let before = score.found;
        score.add(&det, truth, visible);
        let found = score.found - before;
        assert!(
            found >= visible,
            "view {k}: {found} of {visible} corners in view"
        );
    }
    println!("AprilGrid cut: {score:?}, RMS {:.3} px", score.rms());
    assert_eq!(score.wrong, 0);
    assert!(score.rms() < 0.1, "RMS {} px", score.rms());
}

/// A board drawn by OpenCV itself, upside down and in perspective (`fixtures/opencv_charuco.py`
/// made the image, its true corners and OpenCV's `CharucoDetector` corners): every corner
/// with OpenCV's id, near the truth and near OpenCV's.
#[test]
fn an_opencv_drawn_charuco_board_gives_opencvs_ids() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures");
    let img = pingcal_targets::load_image(&dir.join("opencv_charuco.png")).expect("the fixture");
    let text = std::fs::read_to_string(dir.join("opencv_charuco.json")).expect("the fixture");
    let json: serde_json::Value = serde_json::from_str(&text).expect("json");
    let b = Charuco {
        cols: 6,
        rows: 4,
        square_mm: 40.0,
        marker_mm: 30.0,
        dictionary: MarkerDictionary::named("DICT_5X5_100").unwrap(),
    };
    let det = detect_charuco(&img, &b).unwrap_or_else(|e| panic!("{e}"));
    let at = |key: &str, id: usize| {
        let p = &json[key][id.to_string()];
        [p[0].as_f64().unwrap(), p[1].as_f64().unwrap()]
    };
    let mut truth = Score::default();
    truth.add(&det, |id| at("truth", id), b.corner_count());
    let mut opencv = Score::default();
    opencv.add(&det, |id| at("corners", id), b.corner_count());
    println!(
        "OpenCV's board: to the truth {truth:?}, RMS {:.3} px; to OpenCV's corners RMS {:.3} px",
        truth.rms(),
        opencv.rms()
    );
    assert_eq!((truth.found, truth.wrong), (24, 0));
    assert_eq!((opencv.found, opencv.wrong), (24, 0));
    assert!(truth.rms() < 0.1, "RMS {} px", truth.rms());
}

/// Boards too small for every corner (ChArUco squares of 24 and 28 px, marker cells of 2.2
/// to 3.5 px; AprilGrid tags of 24 px, cells of 2.4 px), in stronger perspective: corners
/// are lost, never given a wrong id.
#[test]
fn small_boards_lose_corners_but_never_give_a_wrong_id() {
    let persp = |k: usize| {
        [
            8e-4 * (k as f64 - 3.5) / 3.5,
            -6e-4 * ((k % 3) as f64 - 1.0),
        ]
    };
    let mut score = Score::default();
    for dict in ["DICT_4X4_50", "DICT_5X5_100", "DICT_6X6_250"] {
        let b = charuco(dict);
        for (k, scale) in [1.2, 1.4]
            .into_iter()
            .cycle()
            .take(ANGLES.len())
            .enumerate()
        {
            let h = view([70.0, 50.0], scale, ANGLES[k], [320.0, 240.0], persp(k));
            let img = render(charuco_shade(&b), &h, 640, 480, 500 + k as u64);
            score.expected += b.corner_count();
            if let Ok(det) = detect_charuco(&img, &b) {
                score.add(&det, |id| project(&h, b.board_point(id)), 0);
            }
        }
    }
    let g = aprilgrid();
    for (k, angle) in ANGLES.into_iter().enumerate() {
        let mid = [78.0, 58.5];
        let flip = Matrix3::new(1.0, 0.0, 0.0, 0.0, -1.0, 2.0 * mid[1], 0.0, 0.0, 1.0);
        let h = view(mid, 0.8, angle, [320.0, 240.0], persp(k)) * flip;
        let img = render(aprilgrid_shade(&g), &h, 640, 480, 600 + k as u64);
        score.expected += g.corner_count();
        if let Ok(det) = detect_aprilgrid(&img, &g) {
            score.add(&det, |id| project(&h, g.board_point(id)), 0);
        }
    }
    println!("small boards: {score:?}, RMS {:.3} px", score.rms());
    assert_eq!(score.wrong, 0);
    assert!(score.found > score.expected / 2, "{score:?}");
}

/// The rectangles of a printed page at `ppm` px a mm (each pixel its exact black cover;
/// text and discs left out), blurred and with noise as the rendered boards.
fn rasterise(
    page: &pingcal_targets::sheet::Page,
    size: (f64, f64),
    ppm: f64,
    seed: u64,
) -> GrayImage {
    use pingcal_targets::sheet::Shape;
    let (w, h) = ((size.0 * ppm) as usize, (size.1 * ppm) as usize);
    let mut img = GrayImage::new(w, h, WHITE);
    for shape in &page.shapes {
        if let Shape::Rect {
            x,
            y,
            w: rw,
            h: rh,
            white,
        } = *shape
        {
            let (x0, x1, y0, y1) = (x * ppm, (x + rw) * ppm, y * ppm, (y + rh) * ppm);
            let tone = if white { WHITE } else { BLACK };
            for py in (y0.floor().max(0.0) as usize)..(y1.ceil() as usize).min(h) {
                let cy = (y1.min(py as f64 + 1.0) - y0.max(py as f64)).max(0.0);
                for px in (x0.floor().max(0.0) as usize)..(x1.ceil() as usize).min(w) {
                    let cx = (x1.min(px as f64 + 1.0) - x0.max(px as f64)).max(0.0);
                    let a = (cx * cy) as f32;
                    let v = &mut img.data[py * w + px];
                    *v = *v * (1.0 - a) + tone * a;
                }
            }
        }
    }
    blurred(img, 2, seed)
}

/// The printed pages read back: every corner found with its id, at the board's own spacing
/// (the page's frame: ChArUco's y down the page, the AprilGrid's up it); a board too large
/// for the page upright is turned a quarter and still read whole.
#[test]
fn printed_charuco_and_aprilgrid_pages_read_back_whole_at_their_size() {
    use pingcal_targets::board::printable::{aprilgrid_page, charuco_page};
    use pingcal_targets::sheet::PageSize;
    let a4 = PageSize::A4.mm();
    let ppm = 3.0;
    let check =
        |det: &MarkerBoardDetection, point: &dyn Fn(usize) -> [f64; 3], flip: f64, turned: bool| {
            let c0 = det.corners[0];
            let p0 = point(c0.id);
            for c in &det.corners {
                let p = point(c.id);
                let d = [(p[0] - p0[0]) * ppm, flip * (p[1] - p0[1]) * ppm];
                let e = [c.uv[0] - c0.uv[0], c.uv[1] - c0.uv[1]];
                if turned {
                    let (dl, el) = (d[0].hypot(d[1]), e[0].hypot(e[1]));
                    assert!(
                        (dl - el).abs() < 0.3,
                        "corner {}: {el} px from corner {}, expected {dl}",
                        c.id,
                        c0.id
                    );
                } else {
                    assert!(
                        (d[0] - e[0]).hypot(d[1] - e[1]) < 0.3,
                        "corner {}: {e:?} from corner {}, expected {d:?}",
                        c.id,
                        c0.id
                    );
                }
            }
        };
    let b = charuco("DICT_5X5_100");
    let page = charuco_page(&b, PageSize::A4).expect("fits");
    let det = detect_charuco(&rasterise(&page, a4, ppm, 700), &b).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(det.corners.len(), b.corner_count());
    check(&det, &|id| b.board_point(id), 1.0, false);
    let big = Charuco {
        cols: 12,
        rows: 8,
        square_mm: 15.0,
        marker_mm: 11.0,
        ..b
    };
    let page = charuco_page(&big, PageSize::A4).expect("fits turned");
    let det =
        detect_charuco(&rasterise(&page, a4, ppm, 701), &big).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(det.corners.len(), big.corner_count());
    check(&det, &|id| big.board_point(id), 1.0, true);
    let g = aprilgrid();
    let page = aprilgrid_page(&g, PageSize::A4).expect("fits");
    let det =
        detect_aprilgrid(&rasterise(&page, a4, ppm, 702), &g).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(det.corners.len(), g.corner_count());
    check(&det, &|id| g.board_point(id), -1.0, false);
    let too_big = Charuco {
        square_mm: 40.0,
        ..big
    };
    let e = charuco_page(&too_big, PageSize::A4).expect_err("too large");
    assert!(e.to_string().contains("does not fit"), "{e}");
}
