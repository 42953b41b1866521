//! Kalibr's AprilGrid (`target_type: aprilgrid`, `kalibr_create_target_pdf --type apriltag`).
//!
//! ## Layout and frame
//!
//! `cols × rows` tags of the AprilTag family (tag36h11), each a black square `tag_mm` on a
//! side: a border two cells wide around the 6 × 6 code cells (Kalibr's `borderBits = 2`),
//! drawn upright; the gap between tags `spacing · tag_mm`, with a black square of the gap's
//! side at each corner of every tag (Kalibr's `symmCorners`, which makes the tags' corners
//! x-corners). Tag `id = row · cols + col`, tag 0 at the bottom-left of the printed board,
//! rows going up.
//!
//! The board's frame is Kalibr's: the origin at the bottom-left corner of tag 0, x along the
//! rows of tags, y up the printed board, z = x × y out of the printed face (towards a camera
//! that sees it). Its points are the tags' corners, `2 · cols` a row of points:
//! point `id = prow · 2 · cols + pcol`, at `((pcol / 2) · (1 + spacing) · tag + (pcol % 2) ·
//! tag, (prow / 2) · (1 + spacing) · tag + (prow % 2) · tag, 0)` mm
//! ([`Aprilgrid::board_point`]); tag `t` has the points `2·(t / cols)` and `2·(t / cols) + 1`
//! of rows and `2·(t % cols)`, `2·(t % cols) + 1` of columns (Kalibr's
//! `GridCalibrationTargetAprilgrid`: tag 0's corners are points 0, 1, `2·cols + 1`, `2·cols`,
//! counter-clockwise from its bottom-left).
//!
//! ## Detection
//!
//! The tags ([`super::markers`], two border cells); those not on this board, or off the
//! homography the others agree on, dropped; each tag's four corners refined sub-pixel
//! ([`super::refine::refine_in`], a window inside the gap) with their σ.

use super::marker_board::{agreeing, consistent, refined_corner};
use super::markers::{find_markers, MarkerDictionary};
use super::{BoardCorner, MarkerBoardDetection, MarkerMiss};
use crate::raster::GrayImage;

/// Kalibr's AprilGrid.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aprilgrid {
    /// Tags along a row.
    pub cols: usize,
    /// Rows of tags.
    pub rows: usize,
    /// Side of a tag's black square (mm).
    pub tag_mm: f64,
    /// The gap between tags as a fraction of `tag_mm` (Kalibr's `tagSpacing`).
    pub spacing: f64,
    /// The tag family (tag36h11, [`MarkerDictionary::named`]).
    pub family: MarkerDictionary,
}

/// Border cells of Kalibr's tags.
const BORDER: usize = 2;

impl Aprilgrid {
    /// The number of points (tag corners): `4 · cols · rows`.
    pub fn corner_count(&self) -> usize {
        4 * self.cols * self.rows
    }

    /// The point `id` in the board's frame (mm), see the module doc.
    pub fn board_point(&self, id: usize) -> [f64; 3] {
        let (pcol, prow) = (id % (2 * self.cols), id / (2 * self.cols));
        let pitch = (1.0 + self.spacing) * self.tag_mm;
        let at = |k: usize| (k / 2) as f64 * pitch + (k % 2) as f64 * self.tag_mm;
        [at(pcol), at(prow), 0.0]
    }

    /// Tag `t`'s corner points, in the order of the upright tag's corners as seen printed:
    /// top-left, top-right, bottom-right, bottom-left.
    fn tag_points(&self, t: usize) -> [usize; 4] {
        let w = 2 * self.cols;
        let base = 2 * (t / self.cols) * w + 2 * (t % self.cols);
        [base + w, base + w + 1, base + 1, base]
    }

    /// Whether the printed board is white at `(x, y)` mm in its frame (white paper around
    /// the pattern). For rendering boards (tests, the simulator).
    pub fn is_white(&self, x: f64, y: f64) -> bool {
        let pitch = (1.0 + self.spacing) * self.tag_mm;
        let (tc, tr) = ((x / pitch).floor(), (y / pitch).floor());
        let (lx, ly) = (x - tc * pitch, y - tr * pitch);
        let (c, r) = (self.cols as f64, self.rows as f64);
        if lx >= self.tag_mm && ly >= self.tag_mm {
            // A gap's crossing: black beside a tag.
            return !(tc >= -1.0 && tr >= -1.0 && tc < c && tr < r);
        }
        if lx >= self.tag_mm || ly >= self.tag_mm || tc < 0.0 || tr < 0.0 || tc >= c || tr >= r {
            return true;
        }
        let t = tr as usize * self.cols + tc as usize;
        let n = self.family.bits();
        let cell = self.tag_mm / (n + 2 * BORDER) as f64;
        let (cx, cy) = ((lx / cell) as usize, ((self.tag_mm - ly) / cell) as usize);
        let inner = BORDER..BORDER + n;
        if !inner.contains(&cx) || !inner.contains(&cy) || t >= self.family.len() {
            return false;
        }
        self.family.is_white(t, cy - BORDER, cx - BORDER)
    }
}

/// Finds the AprilGrid `board` in `img`: the four corners of every tag found, sub-pixel with
/// their σ and Kalibr's ids; or why not.
pub fn detect_aprilgrid(
    img: &GrayImage,
    board: &Aprilgrid,
) -> Result<MarkerBoardDetection, MarkerMiss> {
    let fam = &board.family;
    if board.cols < 1 || board.rows < 1 || board.cols * board.rows < 2 || !(board.spacing > 0.0) {
        return Err(MarkerMiss::BadBoard(format!(
            "an AprilGrid needs at least 2 tags and a gap between them, got {} × {}, spacing {}",
            board.cols, board.rows, board.spacing
        )));
    }
    if board.cols * board.rows > fam.len() {
        return Err(MarkerMiss::BadBoard(format!(
            "an AprilGrid of {} × {} tags needs {} tags; {} has {}",
            board.cols,
            board.rows,
            board.cols * board.rows,
            fam.name(),
            fam.len()
        )));
    }
    let tags: Vec<_> = find_markers(img, fam, BORDER)
        .into_iter()
        .filter(|m| m.id < board.cols * board.rows)
        .collect();
    let plane = |t: usize| {
        board.tag_points(t).map(|p| {
            let q = board.board_point(p);
            [q[0], q[1]]
        })
    };
    let pitch = (1.0 + board.spacing) * board.tag_mm;
    let tags = agreeing(tags, plane, pitch, fam.name())?;
    let mut corners = Vec::new();
    for tag in &tags {
        let side_px = (0..4)
            .map(|i| {
                let (a, b) = (tag.corners[i], tag.corners[(i + 1) % 4]);
                ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()
            })
            .sum::<f64>()
            / 4.0;
        let gap_px = board.spacing * side_px;
        let cell_px = side_px / (fam.bits() + 2 * BORDER) as f64;
        let reach = gap_px.min(BORDER as f64 * cell_px);
        let half = ((0.7 * reach).floor() as i64).clamp(2, 7);
        for (k, &id) in board.tag_points(tag.id).iter().enumerate() {
            if let Some((uv, sigma_px)) = refined_corner(img, tag.corners[k], half, 0.6 * reach) {
                corners.push(BoardCorner {
                    id,
                    col: id % (2 * board.cols),
                    row: id / (2 * board.cols),
                    uv,
                    sigma_px,
                });
            }
        }
    }
    corners.sort_by_key(|c| c.id);
    Ok(MarkerBoardDetection {
        corners: consistent(corners, |id| board.board_point(id), 2.5 * pitch),
        markers: tags.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Kalibr's `GridCalibrationTargetAprilgrid` for 2 × 2 tags: points 0, 1, 5, 4 are tag 0's
    /// (bottom-left, bottom-right, top-right, top-left), 2, 3, 7, 6 tag 1's, 8, 9, 13, 12
    /// tag 2's; point `(c, r)` at `((c / 2)·(1 + s)·t + (c % 2)·t, …)`.
    #[test]
    fn the_numbering_and_frame_are_kalibrs() {
        let g = Aprilgrid {
            cols: 2,
            rows: 2,
            tag_mm: 10.0,
            spacing: 0.3,
            family: MarkerDictionary::named("tag36h11").unwrap(),
        };
        // tag_points: top-left, top-right, bottom-right, bottom-left.
        assert_eq!(g.tag_points(0), [4, 5, 1, 0]);
        assert_eq!(g.tag_points(1), [6, 7, 3, 2]);
        assert_eq!(g.tag_points(2), [12, 13, 9, 8]);
        assert_eq!(g.board_point(0), [0.0, 0.0, 0.0]);
        assert_eq!(g.board_point(1), [10.0, 0.0, 0.0]);
        assert_eq!(g.board_point(2), [13.0, 0.0, 0.0]);
        assert_eq!(g.board_point(4), [0.0, 10.0, 0.0]);
        assert_eq!(g.board_point(15), [23.0, 23.0, 0.0]);
        // Tag 0's border is black, its top-left code cell (id 0's code starts 0xd: 1101…)
        // white, the gap white, the gap's crossing black.
        let cell = 1.0;
        assert!(!g.is_white(0.5, 0.5));
        assert!(g.is_white(2.0 + 0.5 * cell, 10.0 - 2.0 - 0.5 * cell));
        assert!(!g.is_white(2.0 + 2.5 * cell, 10.0 - 2.0 - 0.5 * cell));
        assert!(g.is_white(11.5, 5.0));
        assert!(!g.is_white(11.5, 11.5));
        assert!(!g.is_white(-1.5, -1.5));
        assert!(g.is_white(-4.0, 5.0));
    }
}
