//! # pingcal-targets: target detection and identification in images
//!
//! Plain circular (retro-reflective) targets, AICON / Schneider ring-coded targets
//! (12 and 14 bit) and ping-pong-ball silhouettes.

pub mod aicon;
pub mod ball;
pub mod blobs;
pub mod candidates;
pub mod centre;
pub mod detect;
pub mod ellipse;
pub mod homography;
pub mod image_io;
pub mod overlay;
pub mod printable;
pub mod threshold;

pub use detect::{
    detect_file, detect_image, DetectParams, Detector, ImageDetections, Target, TargetKind,
};
pub use image_io::{decode_image, load_image, GrayImage};

/// Errors of this crate. Each names the file (where there is one) and what is wrong.
#[derive(Debug, thiserror::Error)]
pub enum TargetError {
    #[error("{file}: {what}")]
    Image { file: String, what: String },
    #[error("{0}")]
    Invalid(String),
}
