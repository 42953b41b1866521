//! # pingcal-targets: target detection and identification in images
//!
//! Replaces Australis's automatic target measurement: plain circular (retro-reflective)
//! targets, AICON / Schneider ring-coded targets (12 and 14 bit) and ping-pong-ball
//! silhouettes, measured to a few hundredths of a pixel, on real photographs (flash hot spots,
//! vignetting, partly covered targets).
//!
//! Pixel coordinates everywhere: origin at the centre of the top-left pixel, x to the right,
//! y down.
//!
//! ## Entry points
//! - [`load_image`] / [`decode_image`]: any TIFF / PNG / JPEG (8 or 16 bit, grey or colour) to
//!   an `f32` grey [`GrayImage`], with errors naming the file.
//! - [`Detector::new`]`(DetectParams)` then [`Detector::detect`]`(&GrayImage) -> ImageDetections`
//!   (or [`detect_image`], [`detect_file`], and [`detect_files`] for many files decoded and
//!   detected in parallel): targets with kind coded / plain / ball, number,
//!   centre and σ.
//! - [`ball::sphere_centre_from_ellipse`]`(&Ellipse, &dyn CameraRays, Option<radius>)`: the
//!   eccentricity correction of a ball's silhouette, once the camera's intrinsics are known.
//! - [`driveback::assign`]: plain targets and balls identified by projecting the model.
//! - [`homography::ransac_homography`]: seeded RANSAC homography (ID checks on flat panels).
//! - [`sheet::layout`], [`sheet::to_pdf`], [`sheet::to_svg`]: printable pages of coded and
//!   plain targets at true size, with a scale bar.
//! - [`overlay::draw_detections`]: debug overlay PNG.
//!
//! ## Modules, in pipeline order
//! - [`image_io`]: loading and conversion, after [`image_checks`] (header against data, size); [`tiff_strips`]: its fast path for grey strip TIFFs.
//!   [`png_rows`]: its fast path for grey PNGs.
//! - [`threshold`]: the threshold ladder and per-target local levels (hot spots, vignetting).
//! - [`blobs`]: connected components with moments.
//! - [`candidates`]: shape tests, grouping across threshold levels.
//! - [`centre`]: sub-pixel edge points, robust ellipse fit, weighted centroid, σ estimates.
//! - [`ellipse`]: ellipse geometry and the direct least-squares fit.
//! - [`aicon`]: code tables (generated), ring sampling after affine rectification, bit
//!   reading, minimum rotation, lookup, refusals.
//! - [`ball`]: sphere silhouettes and the eccentricity correction.
//! - [`dot`]: a flat dot's centre through a strongly non-linear (wide-angle, fisheye) lens.
//! - [`silhouette`]: a sphere of known radius in a real photograph: edges from the colour
//!   gradient, candidate circles, the robust fit of its silhouette cone to the visible outline.
//! - [`detect`]: the top-level detector.
//! - [`driveback`]: identification by projection.
//! - [`homography`], [`printable`], [`overlay`].
//! - [`board`]: chessboards of known layout: x-corners, the grid, sub-pixel corners with
//!   their σ, numbered by the board ([`board::detect_chessboard`]).

pub mod aicon;
pub mod ball;
pub mod blobs;
pub mod board;
pub mod candidates;
pub mod centre;
pub mod detect;
pub mod dot;
pub mod driveback;
pub mod ellipse;
pub mod glyphs;
pub mod homography;
pub mod image_checks;
pub mod image_io;
pub mod overlay;
pub mod png_rows;
pub mod printable;
pub mod raster;
pub mod refusal;
pub mod sheet;
pub mod silhouette;
pub mod threshold;
pub mod tiff_strips;

pub use aicon::confidence;

pub use detect::{
    detect_file, detect_files, detect_image, DetectParams, Detector, ImageDetections, Target,
    TargetKind,
};
pub use image_io::{decode_image, load_colour, load_image, GrayImage};

/// Errors of this crate. Each names the file (where there is one) and what is wrong.
#[derive(Debug, thiserror::Error)]
pub enum TargetError {
    /// An image file that cannot be read, decoded or written.
    #[error("{file}: {what}")]
    Image {
        /// The file's path or name, as given.
        file: String,
        /// What is wrong (e.g. "empty file", "cannot write: …").
        what: String,
    },
    /// A value given to the library that it cannot use (a code table size, an ID list, a
    /// page size, …).
    #[error("{0}")]
    Invalid(
        /// The value and what was expected, as one sentence.
        String,
    ),
}
