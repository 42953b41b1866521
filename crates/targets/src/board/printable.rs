//! A chessboard printed at true size: its squares centred on one page, the square diagonal
//! to corner 0 white (the numbering rule of [`super`]), corner 0 marked, a header naming the
//! board, and the sheet's 100 mm scale bar ([`crate::sheet`]) to check the print's scale.

use super::Chessboard;
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
    let (pw, ph) = page.mm();
    let (rw, rh) = (pw - 2.0 * MARGIN, ph - 2.0 * MARGIN - HEADER - FOOTER);
    let turned = !(w <= rw && h <= rh);
    let (bw, bh) = if turned { (h, w) } else { (w, h) };
    if bw > rw || bh > rh {
        return Err(TargetError::Invalid(format!(
            "a chessboard of {} × {} inner corners with {s} mm squares is {w} × {h} mm: it does not fit on {} paper ({rw:.0} × {rh:.0} mm inside the margins); choose a larger page or smaller squares",
            board.cols, board.rows, page.name()
        )));
    }
    let (x0, y0) = ((pw - bw) / 2.0, MARGIN + HEADER + (rh - bh) / 2.0);
    // Square (a, b) of the board, and corner (col, row), on the page.
    let place = |a: f64, b: f64| {
        if turned {
            (x0 + (board.rows as f64 + 1.0 - b) * s - s, y0 + a * s)
        } else {
            (x0 + a * s, y0 + b * s)
        }
    };
    let mut shapes = vec![Shape::Text {
        x: MARGIN,
        y: MARGIN + 3.5,
        size: 3.5,
        text: format!(
            "pingcal chessboard - inner_corners = [{}, {}] - square_mm = {s} - print at 100 %, no fit to page, and glue flat",
            board.cols, board.rows
        ),
        centred: false,
    }];
    for b in 0..=board.rows {
        for a in 0..=board.cols {
            // Square (a, b) is white when a + b is even: (0, 0) and (1, 1) are corner 0's.
            if (a + b) % 2 == 1 {
                let (x, y) = place(a as f64, b as f64);
                shapes.push(Shape::Rect {
                    x,
                    y,
                    w: s,
                    h: s,
                    white: false,
                });
            }
        }
    }
    let (cx, cy) = if turned {
        (x0 + board.rows as f64 * s, y0 + s)
    } else {
        (x0 + s, y0 + s)
    };
    shapes.push(Shape::Text {
        x: cx,
        y: cy - s - 1.5,
        size: 3.0,
        text: "corner 0 below".into(),
        centred: true,
    });
    shapes.extend(crate::sheet::scale_bar(ph));
    Ok(crate::sheet::Page { shapes })
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
