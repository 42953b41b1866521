//! The crate's error type: every failure names the file, the line and what was expected,
//! or, for geometry, the points involved and why the problem is degenerate.

use thiserror::Error;

/// Everything that can go wrong in this crate. Never a panic on user input.
#[derive(Debug, Error)]
pub enum LrfError {
    /// The file could not be opened or read.
    #[error("{file}: {source}")]
    Io {
        /// File name as given by the caller.
        file: String,
        /// The underlying error.
        source: std::io::Error,
    },
    /// A line (or, for binary PLY, a record) of a file is malformed.
    #[error("{file}:{line}: {msg}")]
    Parse {
        /// File name as given by the caller.
        file: String,
        /// 1-based line number (for binary PLY: the vertex record number).
        line: usize,
        /// What was found and what was expected.
        msg: String,
    },
    /// A file is empty or holds no usable data.
    #[error("{file}: {msg}")]
    Empty {
        /// File name as given by the caller.
        file: String,
        /// What is missing.
        msg: String,
    },
    /// Fewer points than the estimation needs.
    #[error("too few points: {needed} needed, {got} given ({ids})")]
    TooFewPoints {
        /// Minimum number of points.
        needed: usize,
        /// Number given.
        got: usize,
        /// Their ids, comma separated (may be empty).
        ids: String,
    },
    /// The points are (nearly) on one line: the rotation about it is undetermined.
    #[error(
        "points {ids} are nearly collinear (largest distance from their common line {max_offset_mm:.3} mm): \
         the rotation about that line is undetermined; add points off the line"
    )]
    Collinear {
        /// Their ids, comma separated.
        ids: String,
        /// Largest distance of a point from the best-fit line, in mm.
        max_offset_mm: f64,
    },
    /// A fit did not converge or met degenerate geometry (named in the message).
    #[error("{0}")]
    Degenerate(String),
    /// Input values are inconsistent (named in the message).
    #[error("{0}")]
    Invalid(String),
}

/// What [`LrfError::cut_short`] says.
const CUT_SHORT: &str = "the last line does not end with a line break: the file was cut short (in the middle of a number?); copy it again whole";

/// Result alias used throughout the crate.
pub type Result<T> = std::result::Result<T, LrfError>;

impl LrfError {
    pub(crate) fn parse(file: &str, line: usize, msg: impl Into<String>) -> Self {
        LrfError::Parse {
            file: file.to_string(),
            line,
            msg: msg.into(),
        }
    }
    /// The text of line `line_no` without a UTF-8 byte-order mark when it is the first
    /// line (editors on Windows write one; it is not part of the data).
    pub(crate) fn without_bom(line_no: usize, s: &str) -> &str {
        if line_no == 1 {
            s.strip_prefix('\u{feff}').unwrap_or(s)
        } else {
            s
        }
    }
    /// The refusal of a text file whose last line has no line break: it was cut short
    /// (a copy or a recording stopped mid-way), and its last value may be cut mid-number.
    pub(crate) fn cut_short(file: &str, line: usize) -> Self {
        LrfError::parse(file, line, CUT_SHORT)
    }

    /// Whether this is the refusal of [`LrfError::cut_short`].
    pub(crate) fn is_cut_short(&self) -> bool {
        matches!(self, LrfError::Parse { msg, .. } if msg == CUT_SHORT)
    }
    pub(crate) fn io(file: &str, source: std::io::Error) -> Self {
        LrfError::Io {
            file: file.to_string(),
            source,
        }
    }
}
