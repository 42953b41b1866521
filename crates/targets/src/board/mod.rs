//! # Boards: chessboards, ChArUco boards and AprilGrids of known layout
//!
//! A calibration board is a planar field of known layout: a chessboard of `cols × rows`
//! inner corners and square side `square_mm`. [`detect_chessboard`] finds every inner
//! corner of one board in an image, sub-pixel, with its σ, and numbers them by the board's
//! layout; a board it cannot find whole is refused with a one-line reason
//! ([`BoardMiss`]).
//!
//! Boards with markers number their corners by the markers read, so a board partly out of
//! the image, covered or upside down gives its visible corners with their ids
//! ([`MarkerBoardDetection`], or a one-line [`MarkerMiss`]): [`charuco::detect_charuco`]
//! (OpenCV's ChArUco layout and frame, [`charuco`]) and [`aprilgrid::detect_aprilgrid`]
//! (Kalibr's AprilGrid layout and frame, [`aprilgrid`]), both with the square markers of
//! [`markers`] (OpenCV's ArUco dictionaries, the AprilTag library's tag36h11; no crate: see
//! [`markers`] and `docs/boards.md`).
//!
//! ## Numbering (the same as OpenCV's `findChessboardCornersSB`)
//!
//! Corner `id = row · cols + col`, `col` in `0..cols` along the board's first dimension
//! (`inner_corners[0]`), `row` in `0..rows`. Its point in the board's frame is
//! `(col · square, row · square, 0)` mm ([`Chessboard::board_point`]). The board is seen
//! from its printed side: the row direction is the column direction turned by +90° in the
//! image (x right, y down), so the board frame's z = x × y points away from the camera, into
//! the board. Corner 0 is the end of the board whose two diagonal squares are **white**;
//! when `cols + rows` is even the two ends of the diagonal look the same (the board is
//! symmetric under a half turn), and corner 0 is then the one nearer the image's top-left
//! corner ([`BoardDetection::symmetric`] says so). A square board (`cols == rows`) is
//! numbered the same way among its four quarter turns.
//!
//! ## The detector
//!
//! 0. The image's own scale first; when it finds no board, the image halved and quartered
//!    (a blurred board: a large image, a soft lens), the corners refined on the image itself.
//! 1. [`saddles`]: x-corner candidates: the saddle response `f_xy² − f_xx f_yy` of the
//!    image smoothed at σ = 1.5 px, local maxima, kept where a ring of samples around them
//!    changes sign four times (two dark and two light sectors, opposite each other), with the
//!    two edge directions from those sign changes.
//! 2. [`grid`]: the grid grown from a seed over the candidates: each next corner predicted
//!    by a homography of the corners found around it and taken when a candidate lies within
//!    a quarter of the local square side; the board is taken only when the grown grid has
//!    exactly `cols × rows` (or `rows × cols`) corners, no holes.
//! 3. [`refine`]: each corner's sub-pixel position from the image gradients around it (each
//!    gradient is orthogonal to the vector from the corner to its pixel: the least-squares
//!    point of those lines, iterated, as OpenCV's `cornerSubPix`), in a window of a third of
//!    the local square side (3 to 7 px half width); its σ from the residuals of that fit.

pub mod aprilgrid;
pub mod charuco;
pub mod grid;
mod marker_board;
pub mod markers;
pub mod planar;
pub mod printable;
pub mod refine;
pub mod saddles;

use crate::raster::GrayImage;

/// The code tables of [`markers`], generated (`codes/generate.py`).
mod codes {
    pub(crate) mod tables;
}

pub use aprilgrid::{detect_aprilgrid, Aprilgrid};
pub use charuco::{detect_charuco, Charuco};
pub use markers::MarkerDictionary;
pub use planar::PlanarBoard;

/// A chessboard: `cols × rows` inner corners, squares `square_mm` on a side.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Chessboard {
    /// Inner corners along the board's first dimension (`inner_corners[0]`).
    pub cols: usize,
    /// Inner corners along the second dimension (`inner_corners[1]`).
    pub rows: usize,
    /// Side of a square (mm).
    pub square_mm: f64,
}

impl Chessboard {
    /// The inner corners `COLSxROWS` (`9x6`, also with `×` or `X`), as a command line
    /// gives them.
    pub fn parse_inner_corners(text: &str) -> Result<(usize, usize), String> {
        let parts: Vec<&str> = text.split(['x', 'X', '×']).map(str::trim).collect();
        match parts[..] {
            [c, r] => match (c.parse::<usize>(), r.parse::<usize>()) {
                (Ok(c), Ok(r)) if c >= 2 && r >= 2 => Ok((c, r)),
                _ => Err(format!(
                    "board '{text}': expected the inner corners as COLSxROWS, each at least 2 (e.g. 9x6)"
                )),
            },
            _ => Err(format!(
                "board '{text}': expected the inner corners as COLSxROWS (e.g. 9x6)"
            )),
        }
    }

    /// The number of inner corners.
    pub fn corner_count(&self) -> usize {
        self.cols * self.rows
    }

    /// The point of corner `id` in the board's frame (mm): `(col · square, row · square, 0)`.
    pub fn board_point(&self, id: usize) -> [f64; 3] {
        let (col, row) = (id % self.cols, id / self.cols);
        [
            col as f64 * self.square_mm,
            row as f64 * self.square_mm,
            0.0,
        ]
    }

    /// Whether the two ends of the board's diagonal look alike (a half turn maps the board
    /// onto itself, colours included): `cols + rows` even.
    pub fn is_half_turn_symmetric(&self) -> bool {
        (self.cols + self.rows) % 2 == 0
    }
}

/// One corner of a detected board.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoardCorner {
    /// `row · cols + col` (see the module doc; an AprilGrid's [`aprilgrid`] point id, its
    /// `cols` the points of a row, `2 ·` the tags').
    pub id: usize,
    /// Column, `0..cols`.
    pub col: usize,
    /// Row, `0..rows`.
    pub row: usize,
    /// Sub-pixel position (px, origin at the centre of the top-left pixel, y down).
    pub uv: [f64; 2],
    /// Its standard deviation per coordinate (px), from the sub-pixel fit's residuals.
    pub sigma_px: f64,
}

/// A board found in an image: all its inner corners, in id order.
#[derive(Clone, Debug, PartialEq)]
pub struct BoardDetection {
    /// Every inner corner, `corners[id].id == id`.
    pub corners: Vec<BoardCorner>,
    /// The board is symmetric under a half (or quarter) turn, so corner 0 was chosen as the
    /// one nearer the image's top-left corner rather than by the colour of its squares.
    pub symmetric: bool,
}

/// A board with markers found in an image: its visible corners, in id order.
#[derive(Clone, Debug, PartialEq)]
pub struct MarkerBoardDetection {
    /// The corners found, ascending ids (each id at most once); their points in the board's
    /// frame are the board's `board_point(id)`.
    pub corners: Vec<BoardCorner>,
    /// The markers (tags) read and taken.
    pub markers: usize,
}

/// Why no board with markers was found: one line for the log.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum MarkerMiss {
    /// The board's description is unusable.
    #[error("{0}")]
    BadBoard(String),
    /// Too few of the board's markers read.
    #[error("{found} of the board's {dictionary} markers read, at least {needed} needed (board out of view, too small, or of another dictionary?)")]
    TooFewMarkers {
        /// The board's dictionary (or tag family).
        dictionary: &'static str,
        /// Markers read.
        found: usize,
        /// Needed.
        needed: usize,
    },
    /// Markers read, but too few agree on the board's plane.
    #[error("only {found} of the {dictionary} markers read lie on one plane as the board's layout says, at least {needed} needed (another board layout?)")]
    Disagreeing {
        /// The board's dictionary (or tag family).
        dictionary: &'static str,
        /// Markers agreeing.
        found: usize,
        /// Needed.
        needed: usize,
    },
}

/// Why no board was found: one line for the log.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum BoardMiss {
    /// The board's size is unusable (fewer than 2 corners a side).
    #[error("a chessboard needs at least 2 × 2 inner corners, got {cols} × {rows}")]
    BadBoard {
        /// Given columns.
        cols: usize,
        /// Given rows.
        rows: usize,
    },
    /// Too few x-corners in the whole image.
    #[error("only {found} chessboard corner candidates in the image, the board has {needed}")]
    TooFewCandidates {
        /// Candidates found.
        found: usize,
        /// Inner corners of the board.
        needed: usize,
    },
    /// A grid of the board's size was found, but the grid goes on past it: a larger board.
    #[error("the grid of {cols} × {rows} inner corners goes on past its side: a larger board than the project's?")]
    LargerBoard {
        /// Board columns.
        cols: usize,
        /// Board rows.
        rows: usize,
    },
    /// The largest grid found is not the board (partly out of the image, covered, or
    /// another board).
    #[error("no grid of {cols} × {rows} inner corners: the largest found has {found} corners over {found_cols} × {found_rows} (board partly outside the image, covered or of another size?)")]
    WrongGrid {
        /// Board columns.
        cols: usize,
        /// Board rows.
        rows: usize,
        /// Corners of the largest grid grown.
        found: usize,
        /// Columns of the largest grid grown.
        found_cols: usize,
        /// Rows of the largest grid grown.
        found_rows: usize,
    },
}

/// The image's own scale first, then halved and quartered (each pixel the mean of 2 × 2 or
/// 4 × 4): a blurred board (a large image, a soft lens) has corners too wide for the
/// candidates' scale. The corners are refined on the image itself.
const LEVELS: [usize; 3] = [1, 2, 4];

/// Finds the chessboard `board` in `img`: every inner corner, sub-pixel with its σ,
/// numbered as the module doc says; or why not (the reason at the image's own scale).
pub fn detect_chessboard(img: &GrayImage, board: &Chessboard) -> Result<BoardDetection, BoardMiss> {
    if board.cols < 2 || board.rows < 2 {
        return Err(BoardMiss::BadBoard {
            cols: board.cols,
            rows: board.rows,
        });
    }
    let mut first_miss = None;
    for k in LEVELS {
        if img.width / k < 32 || img.height / k < 32 {
            break;
        }
        let level = (k > 1).then(|| downsample(img, k));
        match find_grid(level.as_ref().unwrap_or(img), board) {
            Ok(numbered) => return Ok(refined(img, board, &numbered, k)),
            Err(miss) => {
                first_miss.get_or_insert(miss);
            }
        }
    }
    Err(first_miss.unwrap_or(BoardMiss::TooFewCandidates {
        found: 0,
        needed: board.corner_count(),
    }))
}

/// The board's grid numbered, at the pixel of `img`.
fn find_grid(img: &GrayImage, board: &Chessboard) -> Result<grid::Numbered, BoardMiss> {
    let candidates = saddles::find(img);
    if candidates.len() < board.corner_count() {
        return Err(BoardMiss::TooFewCandidates {
            found: candidates.len(),
            needed: board.corner_count(),
        });
    }
    let grown = grid::grow_board(&candidates, board)?;
    grid::number(img, &grown, board).ok_or(BoardMiss::WrongGrid {
        cols: board.cols,
        rows: board.rows,
        found: grown.ni * grown.nj,
        found_cols: grown.ni,
        found_rows: grown.nj,
    })
}

/// The corners of `numbered`, found at level `k` (positions `k` times coarser), refined on
/// `img` with a window up to `k` times the usual.
fn refined(
    img: &GrayImage,
    board: &Chessboard,
    numbered: &grid::Numbered,
    k: usize,
) -> BoardDetection {
    let kf = k as f64;
    // A level pixel's centre x is the mean of the image's k pixels from k·x on.
    let cells: Vec<[f64; 2]> = numbered
        .cells
        .iter()
        .map(|p| [kf * p[0] + 0.5 * (kf - 1.0), kf * p[1] + 0.5 * (kf - 1.0)])
        .collect();
    let corners = cells
        .iter()
        .enumerate()
        .map(|(id, &p)| {
            let spacing = grid::local_spacing(&cells, board, id);
            let fit = refine::refine(img, p, spacing, k);
            BoardCorner {
                id,
                col: id % board.cols,
                row: id / board.cols,
                uv: fit.uv,
                sigma_px: fit.sigma_px,
            }
        })
        .collect();
    BoardDetection {
        corners,
        symmetric: numbered.symmetric,
    }
}

/// `img` with each `k × k` block averaged (the last partial row and column dropped).
fn downsample(img: &GrayImage, k: usize) -> GrayImage {
    let (w, h) = (img.width / k, img.height / k);
    let mut out = GrayImage::new(w, h, 0.0);
    let norm = 1.0 / (k * k) as f32;
    for y in 0..h {
        for x in 0..w {
            let mut s = 0.0;
            for yy in y * k..(y + 1) * k {
                for xx in x * k..(x + 1) * k {
                    s += img.get(xx, yy);
                }
            }
            out.data[y * w + x] = s * norm;
        }
    }
    out
}
