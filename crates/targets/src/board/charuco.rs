//! ChArUco boards, OpenCV's layout (`cv2.aruco.CharucoBoard((cols + 1, rows + 1),
//! square, marker, dictionary)`, OpenCV ≥ 4.6 without the legacy pattern).
//!
//! ## Layout and frame
//!
//! `(cols + 1) × (rows + 1)` squares of side `square_mm`; square `(x, y)` (x to the right, y
//! down the printed board, from the top-left) is black when `x + y` is even, so the top-left
//! square is black. Marker `k` (of the dictionary) lies centred in the `k`-th white square in
//! row-major order, upright, `marker_mm` on a side with one black border cell. Inner corner
//! `id = row · cols + col` is the corner between squares `(col, row)` and
//! `(col + 1, row + 1)`; its point in the board's frame is `((col + 1) · square,
//! (row + 1) · square, 0)` mm ([`Charuco::board_point`], OpenCV's `getChessboardCorners`):
//! the origin at the outer top-left corner of the squares, x to the right, y down the
//! printed board, z = x × y into the board (away from a camera that sees its printed side).
//!
//! ## Detection
//!
//! The markers ([`super::markers`]); those not on this board, or off the homography of the
//! board's plane that the others agree on, dropped; each inner corner next to a marker
//! found predicted through the homography of its neighbouring markers' corners and refined
//! sub-pixel ([`super::refine::refine_in`], a window kept inside the white margin around
//! the markers) with its σ. A board partly out of the image, covered or turned any way
//! gives its visible corners with their ids.

use super::marker_board::{agreeing, consistent, marker_side_px, refined_corner};
use super::markers::{find_markers, Marker, MarkerDictionary};
use super::{BoardCorner, MarkerBoardDetection, MarkerMiss};
use crate::homography::fit_homography;
use crate::raster::GrayImage;

/// A ChArUco board.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Charuco {
    /// Inner corners along the board's first dimension (squares: `cols + 1`).
    pub cols: usize,
    /// Inner corners along the second dimension (squares: `rows + 1`).
    pub rows: usize,
    /// Side of a square (mm).
    pub square_mm: f64,
    /// Side of a marker (mm), less than the square's.
    pub marker_mm: f64,
    /// The markers' dictionary.
    pub dictionary: MarkerDictionary,
}

impl Charuco {
    /// The number of inner corners.
    pub fn corner_count(&self) -> usize {
        self.cols * self.rows
    }

    /// Why the board cannot be made of its dictionary: more white squares than markers in it;
    /// None when it can.
    pub fn too_many_markers(&self) -> Option<String> {
        let dict = &self.dictionary;
        (self.marker_count() > dict.len()).then(|| {
            format!(
                "a ChArUco board of {} × {} inner corners has {} markers; {} has {}",
                self.cols,
                self.rows,
                self.marker_count(),
                dict.name(),
                dict.len()
            )
        })
    }

    /// The number of markers: the white squares.
    pub fn marker_count(&self) -> usize {
        ((self.cols + 1) * (self.rows + 1)) / 2
    }

    /// The point of inner corner `id` in the board's frame (mm), see the module doc.
    pub fn board_point(&self, id: usize) -> [f64; 3] {
        let (col, row) = (id % self.cols, id / self.cols);
        [
            (col + 1) as f64 * self.square_mm,
            (row + 1) as f64 * self.square_mm,
            0.0,
        ]
    }

    /// The square `(x, y)` of marker `k`.
    fn marker_square(&self, k: usize) -> (usize, usize) {
        let sx = self.cols + 1;
        let mut seen = 0;
        for y in 0..=self.rows {
            for x in 0..sx {
                if (x + y) % 2 == 1 {
                    if seen == k {
                        return (x, y);
                    }
                    seen += 1;
                }
            }
        }
        (usize::MAX, usize::MAX)
    }

    /// The marker in square `(x, y)`, if it is white.
    fn marker_in(&self, x: usize, y: usize) -> Option<usize> {
        ((x + y) % 2 == 1).then(|| (y * (self.cols + 1) + x) / 2)
    }

    /// Marker `k`'s corners in the board's frame (mm, the plane's x and y), top-left first,
    /// clockwise as printed (OpenCV's order).
    fn marker_corners(&self, k: usize) -> [[f64; 2]; 4] {
        let (x, y) = self.marker_square(k);
        let d = 0.5 * (self.square_mm - self.marker_mm);
        let (x0, y0) = (x as f64 * self.square_mm + d, y as f64 * self.square_mm + d);
        let m = self.marker_mm;
        [[x0, y0], [x0 + m, y0], [x0 + m, y0 + m], [x0, y0 + m]]
    }

    /// Whether the printed board is white at `(x, y)` mm in its frame; `None` outside the
    /// squares. For rendering boards (tests, the simulator).
    pub fn is_white(&self, x: f64, y: f64) -> Option<bool> {
        let s = self.square_mm;
        let (sx, sy) = ((x / s).floor(), (y / s).floor());
        if sx < 0.0 || sy < 0.0 || sx > self.cols as f64 || sy > self.rows as f64 {
            return None;
        }
        let (sx, sy) = (sx as usize, sy as usize);
        let Some(k) = self.marker_in(sx, sy) else {
            return Some(false);
        };
        let d = 0.5 * (s - self.marker_mm);
        let (lx, ly) = (x - sx as f64 * s - d, y - sy as f64 * s - d);
        if lx < 0.0 || ly < 0.0 || lx >= self.marker_mm || ly >= self.marker_mm {
            return Some(true);
        }
        let n = self.dictionary.bits();
        let cell = self.marker_mm / (n + 2) as f64;
        let (c, r) = ((lx / cell) as usize, (ly / cell) as usize);
        if c == 0 || r == 0 || c > n || r > n || k >= self.dictionary.len() {
            return Some(false);
        }
        Some(self.dictionary.is_white(k, r - 1, c - 1))
    }
}

/// Finds the ChArUco board `board` in `img`: every inner corner next to a marker found,
/// sub-pixel with its σ and its id; or why not.
pub fn detect_charuco(
    img: &GrayImage,
    board: &Charuco,
) -> Result<MarkerBoardDetection, MarkerMiss> {
    let dict = &board.dictionary;
    if board.cols < 2
        || board.rows < 2
        || !(board.marker_mm > 0.0 && board.marker_mm < board.square_mm)
    {
        return Err(MarkerMiss::BadBoard(format!(
            "a ChArUco board needs at least 2 × 2 inner corners and a marker smaller than its square, got {} × {}, marker {} mm in {} mm",
            board.cols, board.rows, board.marker_mm, board.square_mm
        )));
    }
    if let Some(why) = board.too_many_markers() {
        return Err(MarkerMiss::BadBoard(why));
    }
    let read: Vec<Marker> = find_markers(img, dict, 1)
        .into_iter()
        .filter(|m| m.id < board.marker_count())
        .collect();
    let markers = agreeing(
        read,
        |k| board.marker_corners(k),
        board.square_mm,
        dict.name(),
    )?;
    let side_px = marker_side_px(&markers) * board.square_mm / board.marker_mm;
    let margin_px = side_px * 0.5 * (1.0 - board.marker_mm / board.square_mm);
    let half = ((0.8 * margin_px).floor() as i64).clamp(2, 7);
    let mut corners = Vec::new();
    for id in 0..board.corner_count() {
        let (col, row) = (id % board.cols, id / board.cols);
        let around: Vec<&Marker> = [
            (col, row),
            (col + 1, row),
            (col, row + 1),
            (col + 1, row + 1),
        ]
        .iter()
        .filter_map(|&(x, y)| board.marker_in(x, y))
        .filter_map(|k| markers.iter().find(|m| m.id == k))
        .collect();
        if around.is_empty() {
            continue;
        }
        let (src, dst): (Vec<[f64; 2]>, Vec<[f64; 2]>) = around
            .iter()
            .flat_map(|m| board.marker_corners(m.id).into_iter().zip(m.corners))
            .unzip();
        let Some(h) = fit_homography(&src, &dst) else {
            continue;
        };
        let p = board.board_point(id);
        let Some(start) = h.apply([p[0], p[1]]) else {
            continue;
        };
        if let Some(c) = refined_corner(img, start, half, margin_px.min(0.2 * side_px)) {
            corners.push(BoardCorner {
                id,
                col,
                row,
                uv: c.0,
                sigma_px: c.1,
            });
        }
    }
    Ok(MarkerBoardDetection {
        corners: consistent(corners, |id| board.board_point(id), 3.0 * board.square_mm),
        markers: markers.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// OpenCV 5.1's `CharucoBoard((5, 4), 0.04, 0.03, DICT_4X4_50)` (mm here):
    /// `getChessboardCorners()` and `getObjPoints()` of its first markers.
    #[test]
    fn the_layout_is_opencvs() {
        let b = Charuco {
            cols: 4,
            rows: 3,
            square_mm: 40.0,
            marker_mm: 30.0,
            dictionary: MarkerDictionary::named("DICT_4X4_50").unwrap(),
        };
        assert_eq!(b.board_point(0), [40.0, 40.0, 0.0]);
        assert_eq!(b.board_point(1), [80.0, 40.0, 0.0]);
        assert_eq!(b.board_point(4), [40.0, 80.0, 0.0]);
        assert_eq!(b.marker_count(), 10);
        assert_eq!(b.marker_corners(0)[0], [45.0, 5.0]);
        assert_eq!(b.marker_corners(0)[2], [75.0, 35.0]);
        assert_eq!(b.marker_corners(1)[0], [125.0, 5.0]);
        assert_eq!(b.marker_corners(2)[0], [5.0, 45.0]);
        // The top-left square is black, its right neighbour white around marker 0.
        assert_eq!(b.is_white(20.0, 20.0), Some(false));
        assert_eq!(b.is_white(42.0, 20.0), Some(true));
        for k in 0..b.marker_count() {
            let (x, y) = b.marker_square(k);
            assert_eq!(b.marker_in(x, y), Some(k));
        }
    }
}
