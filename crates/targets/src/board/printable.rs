//! A chessboard printed at true size: its squares centred on one page, the square diagonal
//! to corner 0 white (the numbering rule of [`super`]), corner 0 marked, a header naming the
//! board, and the sheet's 100 mm scale bar ([`crate::sheet`]) to check the print's scale.
//! ChArUco boards and AprilGrids likewise ([`charuco_page`], [`aprilgrid_page`]), drawn as
//! OpenCV and Kalibr draw them.

use super::{Aprilgrid, Charuco, Chessboard};
use crate::sheet::{PageSize, Shape, FOOTER, HEADER, MARGIN};
use crate::TargetError;

/// The page of `board` on paper `page`, the board upright or turned a quarter (columns
/// down the page), whichever fits; refused when its `(cols + 1) × (rows + 1)` squares fit
/// neither way.
pub fn chessboard_page(
    board: &Chessboard,
    page: PageSize,
) -> Result<crate::sheet::Page, TargetError> {
    let s = board.square_mm;
    if board.cols < 2 || board.rows < 2 || !(s > 0.0) || !s.is_finite() {
        return Err(TargetError::Invalid(format!(
            "a chessboard of {} × {} inner corners and {s} mm squares: expected at least 2 × 2 and a positive square",
            board.cols, board.rows
        )));
    }
    let (w, h) = ((board.cols + 1) as f64 * s, (board.rows + 1) as f64 * s);
    // Square (a, b) is white when a + b is even: (0, 0) and (1, 1) are corner 0's.
    let rects: Vec<BoardRect> = (0..=board.rows)
        .flat_map(|b| {
            (0..=board.cols)
                .filter(move |a| (a + b) % 2 == 1)
                .map(move |a| (a as f64 * s, b as f64 * s, s, s, false))
        })
        .collect();
    let title = format!(
        "pingcal chessboard - inner_corners = [{}, {}] - square_mm = {s} - print at 100 %, no fit to page, and glue flat",
        board.cols, board.rows
    );
    let what = format!(
        "a chessboard of {} × {} inner corners with {s} mm squares",
        board.cols, board.rows
    );
    // corner 0 is the board's point (s, s); the label a square and 1.5 mm above it
    let corner_0 = ((s, s), -s - 1.5, "corner 0 below");
    board_page(&what, title, (w, h), (&rects, &[corner_0]), page)
}

/// A black or white rectangle of a board, in the printed board's millimetres (x right, y
/// down the page, from the top-left of the board's extent).
type BoardRect = (f64, f64, f64, f64, bool);

/// A label of a board's page: the board's point it names (printed mm, as [`BoardRect`]), the
/// page's vertical offset of the text from it (mm), the text.
type BoardLabel<'a> = ((f64, f64), f64, &'a str);

/// The page of a board `w × h` mm drawn as `rects` (in order) with its `labels`, upright or
/// turned a quarter, whichever fits, under the header `title`; `what` names the board in a
/// refusal.
fn board_page(
    what: &str,
    title: String,
    (w, h): (f64, f64),
    (rects, labels): (&[BoardRect], &[BoardLabel]),
    page: PageSize,
) -> Result<crate::sheet::Page, TargetError> {
    let (pw, ph) = page.mm();
    let (rw, rh) = (pw - 2.0 * MARGIN, ph - 2.0 * MARGIN - HEADER - FOOTER);
    let turned = !(w <= rw && h <= rh);
    let (bw, bh) = if turned { (h, w) } else { (w, h) };
    if bw > rw || bh > rh {
        return Err(TargetError::Invalid(format!(
            "{what} is {w} × {h} mm: it does not fit on {} paper ({rw:.0} × {rh:.0} mm inside the margins); choose a larger page or a smaller board",
            page.name()
        )));
    }
    let (x0, y0) = ((pw - bw) / 2.0, MARGIN + HEADER + (rh - bh) / 2.0);
    let mut shapes = vec![Shape::Text {
        x: MARGIN,
        y: MARGIN + 3.5,
        size: 3.5,
        text: title,
        centred: false,
    }];
    shapes.extend(rects.iter().map(|&(x, y, rw, rh, white)| {
        // Turned a quarter clockwise: the board's top edge runs down the page's right side.
        let (x, y, w, h) = if turned {
            (x0 + (bw - y - rh), y0 + x, rh, rw)
        } else {
            (x0 + x, y0 + y, rw, rh)
        };
        Shape::Rect { x, y, w, h, white }
    }));
    shapes.extend(labels.iter().map(|&((x, y), dy, text)| {
        let (x, y) = if turned {
            (x0 + bw - y, y0 + x)
        } else {
            (x0 + x, y0 + y)
        };
        Shape::Text {
            x,
            y: y + dy,
            size: 3.0,
            text: text.into(),
            centred: true,
        }
    }));
    shapes.extend(crate::sheet::scale_bar(ph));
    Ok(crate::sheet::Page { shapes })
}

/// A marker's rectangles at `(x, y)` (its top-left, printed mm), `side` mm, `border` black
/// cells a side: the black square, then its white code cells.
fn marker_rects(
    dict: &super::MarkerDictionary,
    id: usize,
    (x, y): (f64, f64),
    side: f64,
    border: usize,
) -> Vec<BoardRect> {
    let n = dict.bits();
    let cell = side / (n + 2 * border) as f64;
    let mut out = vec![(x, y, side, side, false)];
    for r in 0..n {
        for c in 0..n {
            if dict.is_white(id, r, c) {
                let (cx, cy) = ((c + border) as f64 * cell, (r + border) as f64 * cell);
                out.push((x + cx, y + cy, cell, cell, true));
            }
        }
    }
    out
}

/// The page of the ChArUco board `board` (OpenCV's layout, [`super::charuco`]) on paper
/// `page`, upright or turned a quarter; refused when it fits neither way or its dictionary
/// has too few markers.
pub fn charuco_page(board: &Charuco, page: PageSize) -> Result<crate::sheet::Page, TargetError> {
    let (s, m) = (board.square_mm, board.marker_mm);
    if board.cols < 2 || board.rows < 2 || !(m > 0.0 && m < s) || !s.is_finite() {
        return Err(TargetError::Invalid(format!(
            "a ChArUco board of {} × {} inner corners, {s} mm squares and {m} mm markers: expected at least 2 × 2 and a marker smaller than its square",
            board.cols, board.rows
        )));
    }
    if let Some(why) = board.too_many_markers() {
        return Err(TargetError::Invalid(why));
    }
    let dict = &board.dictionary;
    let mut rects = Vec::new();
    let mut k = 0;
    for y in 0..=board.rows {
        for x in 0..=board.cols {
            let (px, py) = (x as f64 * s, y as f64 * s);
            if (x + y) % 2 == 0 {
                rects.push((px, py, s, s, false));
            } else {
                let d = 0.5 * (s - m);
                rects.extend(marker_rects(dict, k, (px + d, py + d), m, 1));
                k += 1;
            }
        }
    }
    let title = format!(
        "pingcal ChArUco - inner_corners = [{}, {}] - square_mm = {s} - marker_mm = {m} - {} - print at 100 %, no fit to page, and glue flat",
        board.cols,
        board.rows,
        dict.name()
    );
    let size = ((board.cols + 1) as f64 * s, (board.rows + 1) as f64 * s);
    let what = format!(
        "a ChArUco board of {} × {} inner corners with {s} mm squares",
        board.cols, board.rows
    );
    board_page(&what, title, size, (&rects, &[]), page)
}

/// The page of the AprilGrid `board` (Kalibr's layout, [`super::aprilgrid`]) on paper
/// `page`, upright or turned a quarter; refused when it fits neither way.
pub fn aprilgrid_page(
    board: &Aprilgrid,
    page: PageSize,
) -> Result<crate::sheet::Page, TargetError> {
    let (t, sp) = (board.tag_mm, board.spacing);
    let tags = board.cols * board.rows;
    if tags < 2 || !(t > 0.0) || !(sp > 0.0) || !t.is_finite() || tags > board.family.len() {
        return Err(TargetError::Invalid(format!(
            "an AprilGrid of {} × {} tags of {t} mm, spacing {sp}: expected 2 to {} tags, a positive size and gap",
            board.cols,
            board.rows,
            board.family.len()
        )));
    }
    let (g, pitch) = (sp * t, (1.0 + sp) * t);
    let w = (board.cols - 1) as f64 * pitch + t + 2.0 * g;
    let h = (board.rows - 1) as f64 * pitch + t + 2.0 * g;
    // Board frame (y up, origin at tag 0's bottom-left) to the printed board (y down).
    let print = |x: f64, y_top: f64| (x + g, h - g - y_top);
    let mut rects = Vec::new();
    for tr in 0..=board.rows {
        for tc in 0..=board.cols {
            // The gap's crossing below-left of tag (tc, tr): its corner square.
            let (x, y) = (tc as f64 * pitch - g, tr as f64 * pitch - g);
            let (px, py) = print(x, y + g);
            rects.push((px, py, g, g, false));
        }
    }
    for id in 0..tags {
        let (tc, tr) = (id % board.cols, id / board.cols);
        let (x, y) = (tc as f64 * pitch, tr as f64 * pitch);
        rects.extend(marker_rects(&board.family, id, print(x, y + t), t, 2));
    }
    let title = format!(
        "pingcal AprilGrid - tags = [{}, {}] - tag_mm = {t} - tag_spacing = {sp} - {} - tag 0 bottom left - print at 100 %, no fit to page",
        board.cols,
        board.rows,
        board.family.name()
    );
    let what = format!(
        "an AprilGrid of {} × {} tags of {t} mm",
        board.cols, board.rows
    );
    board_page(&what, title, (w, h), (&rects, &[]), page)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn black_area(page: &crate::sheet::Page) -> f64 {
        page.shapes
            .iter()
            .map(|s| match s {
                Shape::Rect {
                    w, h, white: false, ..
                } if *w > 5.0 && *h > 5.0 => w * h,
                _ => 0.0,
            })
            .sum()
    }

    #[test]
    fn a_board_is_printed_at_its_size_upright_or_turned_and_refused_when_too_large() {
        let small = Chessboard {
            cols: 7,
            rows: 5,
            square_mm: 20.0,
        };
        let page = chessboard_page(&small, PageSize::A4).expect("fits upright");
        // 8 × 6 squares, half of them black.
        assert!((black_area(&page) - 24.0 * 400.0).abs() < 1e-9);
        let wide = Chessboard {
            cols: 9,
            rows: 6,
            square_mm: 25.0,
        };
        let page = chessboard_page(&wide, PageSize::A4).expect("fits turned");
        assert!((black_area(&page) - 35.0 * 625.0).abs() < 1e-9);
        let big = Chessboard {
            cols: 9,
            rows: 6,
            square_mm: 40.0,
        };
        let e = chessboard_page(&big, PageSize::A4).expect_err("too large");
        assert!(e.to_string().contains("does not fit"), "{e}");
    }
}
