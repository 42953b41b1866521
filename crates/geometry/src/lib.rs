//! # pingcal-geometry: the geometry every pingcal crate stands on
//!
//! One type per concept, stated once:
//!
//! | module | what it holds |
//! |---|---|
//! | [`so3`] | rotations: the skew matrix, the exponential and logarithm maps, re-orthonormalisation, the solvers' left perturbation |
//! | [`opk`] | the one ω φ κ angle convention of pingcal (photogrammetric, passive: `R = R_ω R_φ R_κ`) |
//! | [`rigid`] | [`Rigid3`] (`x_a = R x_b + t`) and [`Sim3`] (`x_a = s R x_b + t`), named by their frames |
//! | [`umeyama`](mod@umeyama) | the closed-form (weighted) rigid or similarity transform between point sets |
//! | [`dlt`] | Hartley normalisation and the normalised-DLT homography |
//! | [`plane`] | the least-squares plane of a point set |
//! | [`least_squares`] | small dense nonlinear least squares: Gauss–Newton or Levenberg–Marquardt on a few unknowns' normal equations |
//! | [`consensus`] | robust estimation: an [`Estimator`] trait, MSAC / RANSAC with local optimisation, seeded ChaCha streams |
//! | [`stats`] | the χ² quantile every σ0 bound and honest-σ band uses |
//!
//! ## Why a crate of its own, below `ba`
//!
//! The LRF side (`pingcal-lrf`), the target detector (`pingcal-targets`) and the simulator
//! need rigid transforms, rotations, angle conventions and RANSAC, but not the bundle
//! adjuster. When these lived in `ba` and were written again in `lrf`, they drifted: two
//! rigid-transform types, and two ω φ κ conventions of opposite sign that printed different
//! angles for the same rotation. A crate below all of them is the one place they live; `ba`
//! re-exports what its users expect from it. The crate depends only on `nalgebra` and on the
//! ChaCha generator; it never prints and never panics on data.
//!
//! ## Frames and names
//!
//! A transform is named `a_from_b`: it maps coordinates in frame `b` to coordinates in frame
//! `a`, `x_a = a_from_b · x_b`. Composition reads right to left, so names chain:
//! `camera_from_lrf = camera_from_object.compose(&object_from_lrf)`. The frames of pingcal
//! are those of docs/formats.md: *object* (the photogrammetric frame of the test field), *camera*
//! (X right, Y along the optical axis, Z up), *lrf* (paper eq. 2: Y along the servo shaft).
//! The extrinsic of the calibration is `camera_from_lrf`; an image's exterior orientation is
//! `camera_from_object`.
//!
//! Units: millimetres and radians in code; degrees only where an angle is printed or read.

pub mod consensus;
pub mod dlt;
pub mod least_squares;
pub mod opk;
pub mod plane;
pub mod rigid;
pub mod so3;
pub mod stats;
pub mod umeyama;

pub use consensus::{Consensus, ConsensusOptions, Estimator, RefitRule, Sampling, Scoring};
pub use opk::{from_opk, from_opk_deg, opk_sigma_deg, to_opk, to_opk_deg};
pub use plane::Plane;
pub use rigid::{Rigid3, Sim3};
pub use so3::{exp_so3, log_so3, orthonormalize, rotation_angle, skew};
pub use umeyama::{umeyama, UmeyamaError};

/// The linear-algebra crate of the public API.
pub use nalgebra;
