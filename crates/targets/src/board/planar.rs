//! Any board of the three kinds as one: a planar field of known layout whose corners are
//! found in an image and numbered, each id a point of the board's frame. The calibration
//! takes a board through this type alone, so that a new kind of board is a new variant here
//! and nothing else.

use super::{
    detect_aprilgrid, detect_charuco, detect_chessboard, Aprilgrid, BoardDetection, Charuco,
    Chessboard,
};
use crate::raster::GrayImage;

/// The fewest corners of a board found: fewer fix its pose poorly (a resection needs 4 in
/// general position; a few more make it checkable).
pub const MIN_CORNERS: usize = 6;

/// A calibration board of any kind.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PlanarBoard {
    /// A chessboard (its corner 0 at the board frame's origin).
    Chessboard(Chessboard),
    /// A ChArUco board (OpenCV's layout: the board's corner at the origin).
    Charuco(Charuco),
    /// Kalibr's AprilGrid (tag 0's bottom-left corner at the origin).
    Aprilgrid(Aprilgrid),
}

impl PlanarBoard {
    /// The number of corners (ids `0..corner_count()`).
    pub fn corner_count(&self) -> usize {
        match self {
            PlanarBoard::Chessboard(b) => b.corner_count(),
            PlanarBoard::Charuco(b) => b.corner_count(),
            PlanarBoard::Aprilgrid(b) => b.corner_count(),
        }
    }

    /// Corner `id`'s point in the board's frame (mm; z = 0 on the board).
    pub fn board_point(&self, id: usize) -> [f64; 3] {
        match self {
            PlanarBoard::Chessboard(b) => b.board_point(id),
            PlanarBoard::Charuco(b) => b.board_point(id),
            PlanarBoard::Aprilgrid(b) => b.board_point(id),
        }
    }

    /// The printed pattern's outer rectangle in the board's frame, `[x0, x1, y0, y1]` (mm):
    /// a chessboard's and a ChArUco board's outer squares, an AprilGrid's tags.
    pub fn extent(&self) -> [f64; 4] {
        match self {
            PlanarBoard::Chessboard(b) => {
                let sq = b.square_mm;
                [-sq, b.cols as f64 * sq, -sq, b.rows as f64 * sq]
            }
            PlanarBoard::Charuco(b) => {
                let sq = b.square_mm;
                [0.0, (b.cols + 1) as f64 * sq, 0.0, (b.rows + 1) as f64 * sq]
            }
            PlanarBoard::Aprilgrid(b) => {
                let side = |n: usize| n as f64 * b.tag_mm + (n as f64 - 1.0) * b.spacing * b.tag_mm;
                [0.0, side(b.cols), 0.0, side(b.rows)]
            }
        }
    }

    /// Whether the printed face looks out along the board frame's +Z (Kalibr's AprilGrid: x
    /// right, y up the print, z out of it); else along −Z (OpenCV's and pingcal's boards: x
    /// right, y down the print, z into it).
    pub fn faces_plus_z(&self) -> bool {
        matches!(self, PlanarBoard::Aprilgrid(_))
    }

    /// The board printed at `f` times its size (every length times `f`).
    pub fn scaled(&self, f: f64) -> PlanarBoard {
        match *self {
            PlanarBoard::Chessboard(b) => PlanarBoard::Chessboard(Chessboard {
                square_mm: b.square_mm * f,
                ..b
            }),
            PlanarBoard::Charuco(b) => PlanarBoard::Charuco(Charuco {
                square_mm: b.square_mm * f,
                marker_mm: b.marker_mm * f,
                ..b
            }),
            PlanarBoard::Aprilgrid(b) => PlanarBoard::Aprilgrid(Aprilgrid {
                tag_mm: b.tag_mm * f,
                ..b
            }),
        }
    }

    /// The pattern's unit: a square's side, an AprilGrid's tag's (mm).
    pub fn unit_mm(&self) -> f64 {
        match self {
            PlanarBoard::Chessboard(b) => b.square_mm,
            PlanarBoard::Charuco(b) => b.square_mm,
            PlanarBoard::Aprilgrid(b) => b.tag_mm,
        }
    }

    /// Whether the printed pattern is white at `(x, y)` mm of the board's frame; None
    /// outside it ([`PlanarBoard::extent`]). For rendering boards (tests, the simulator): a
    /// chessboard's square `(⌊x/s⌋, ⌊y/s⌋)` is white when the two add up even.
    pub fn is_white(&self, x: f64, y: f64) -> Option<bool> {
        let [x0, x1, y0, y1] = self.extent();
        if x < x0 || x > x1 || y < y0 || y > y1 {
            return None;
        }
        match self {
            PlanarBoard::Chessboard(b) => {
                let (i, j) = (
                    (x / b.square_mm).floor() as i64,
                    (y / b.square_mm).floor() as i64,
                );
                Some((i + j).rem_euclid(2) == 0)
            }
            PlanarBoard::Charuco(b) => b.is_white(x, y),
            PlanarBoard::Aprilgrid(b) => Some(b.is_white(x, y)),
        }
    }

    /// What the board is, in a few words for the log (`chessboard 9 × 6 inner corners, 25
    /// mm squares`).
    pub fn describe(&self) -> String {
        match self {
            PlanarBoard::Chessboard(b) => format!(
                "chessboard {} × {} inner corners, {} mm squares",
                b.cols, b.rows, b.square_mm
            ),
            PlanarBoard::Charuco(b) => format!(
                "ChArUco board {} × {} inner corners, {} mm squares, {} mm {} markers",
                b.cols,
                b.rows,
                b.square_mm,
                b.marker_mm,
                b.dictionary.name()
            ),
            PlanarBoard::Aprilgrid(b) => format!(
                "AprilGrid {} × {} {} tags of {} mm, spacing {}",
                b.cols,
                b.rows,
                b.family.name(),
                b.tag_mm,
                b.spacing
            ),
        }
    }

    /// Finds the board in `img`: its corners, numbered by the board's layout, with their
    /// σ (at least [`MIN_CORNERS`]); or why not, in one line.
    pub fn detect(&self, img: &GrayImage) -> Result<BoardDetection, String> {
        let found = self.detect_any(img)?;
        match found.corners.len() {
            n if n < MIN_CORNERS => Err(format!(
                "{n} of the board's corners found, at least {MIN_CORNERS} needed (the board too small, too far or mostly out of view?)"
            )),
            _ => Ok(found),
        }
    }

    /// [`PlanarBoard::detect`] without the least number of corners.
    fn detect_any(&self, img: &GrayImage) -> Result<BoardDetection, String> {
        match self {
            PlanarBoard::Chessboard(b) => detect_chessboard(img, b).map_err(|m| m.to_string()),
            PlanarBoard::Charuco(b) => detect_charuco(img, b)
                .map(|d| BoardDetection {
                    corners: d.corners,
                    symmetric: false,
                })
                .map_err(|m| m.to_string()),
            PlanarBoard::Aprilgrid(b) => detect_aprilgrid(img, b)
                .map(|d| BoardDetection {
                    corners: d.corners,
                    symmetric: false,
                })
                .map_err(|m| m.to_string()),
        }
    }
}
