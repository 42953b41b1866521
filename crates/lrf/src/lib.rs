//! # pingcal-lrf: the rotating 2D laser range finder side of the calibration
//!
//! This crate replaces GOM Inspect and the registration step of Manouchehri &
//! Hosseininaveh (ISPRS 2023): it reads LRF scans, builds the 3D cloud (paper eq. 2), finds
//! the ping-pong balls automatically and fits their centres with a fixed-radius fit along the
//! beams, registers the LRF and photogrammetric frames (3D conformal transform with σ's,
//! control/check table and leave-one-out), matches the balls of both frames without labels,
//! and implements the Fan et al. 2019 room-corner baseline the paper compares against.
//!
//! Units are millimetres; frames are those of docs/formats.md (`p_camera = R · p_lrf + t`).
//!
//! Modules, in pipeline order:
//! - [`scan`]: the `pingcal-scan` CSV format, streaming reader and writer.
//! - [`sensor`]: the LRF as a sensor: beam geometry (eq. 2 plus the mount model), the range
//!   noise profiles (URG-04LX by default, UTM-30LX, UST-10LX, VLP-16, σ = a + b·r), and the forward model a simulator needs (rays, readings).
//! - [`settings`]: the sensor's settings resolved once, for the project file and the
//!   command line alike: the range noise, the servo source and motion.
//! - [`cloud`]: scans to a 3D cloud through the sensor's beam geometry.
//! - [`cloud_file`]: [`cloud_file::read_cloud_file`] reads scans, PLY, PCD or XYZ into a cloud.
//! - [`ply`], [`xyz`], [`pcd`]: PLY (ascii/binary), text and PCD (ascii, binary,
//!   binary_compressed through [`lzf`]) clouds; labelled point files.
//! - [`sphere_fit`]: along-ray fixed-radius fit, orthogonal and free-radius fits, covariances.
//! - [`clustering`]: Euclidean clusters with a link per point, in time bounded by the points.
//! - [`ball_finder`]: planes removed, clusters, RANSAC with radius bounds, along-ray fit,
//!   mixed-pixel rejection; balls with too few points are reported, not used.
//! - [`sphere_size`]: when nothing of the nominal size is found, a sphere of another size the
//!   cloud shows, if any.
//! - [`room`]: the mount self-calibrated from the room's planes (walls, floor, ceiling seen
//!   from both half-sweeps), and the beam-on-plane observation the joint adjustment adds.
//! - [`sweep`]: what a servo sweep (a full turn, a nod, a partial sweep) can tell of the
//!   mount: its extent, and the estimated parameters that lean on undetermined ones.
//! - [`registration`]: Horn/Umeyama closed form, weighted least squares with the covariances of
//!   both sides (optional scale), σ of R and t, control/check table, leave-one-out.
//! - [`correspondence`]: automatic ball matching by pairwise-distance invariants, RANSAC over triples.
//! - [`corner`]: the Fan et al. 2019 baseline (scan lines on a room corner, P3P with
//!   orthogonal edges, corner frame from target planes, DLT + resection, composition).
//! - [`corner_baseline`]: the whole Fan et al. 2019 baseline from pipeline data in one call.
//! - [`fixed`]: a fixed 2D LRF's beams on planes and balls as bundle-adjustment residuals.
//! - [`simulate`]: test and benchmark support: scans of a scene of planes and balls,
//!   through [`sensor`] (no production module uses it).
//! - [`error`]: the error type; every failure names the file and line, or the points.

pub mod ball_finder;
pub mod beam;
pub mod cloud;
pub mod cloud_file;
pub mod clustering;
pub mod corner;
pub mod corner_baseline;
pub mod correspondence;
pub mod error;
pub mod fixed;
pub mod lzf;
pub mod pcd;
pub mod ply;
pub mod registration;
pub mod room;
pub mod scan;
pub mod sensor;
pub mod settings;
pub mod simulate;
pub mod sphere_fit;
pub mod sphere_size;
pub mod sweep;
mod words;
pub mod xyz;

pub use cloud::Cloud;
pub use error::{LrfError, Result};
/// The linear-algebra crate of the public API (points are `nalgebra::Vector3<f64>`).
pub use nalgebra;
pub use sensor::{LrfSensor, MountModel, RangeNoise};
