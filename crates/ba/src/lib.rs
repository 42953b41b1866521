//! # pingcal-ba: bundle adjustment for close-range photogrammetry
//!
//! A library a photogrammetrist can reuse for any test field:
//!
//! | module | what it holds |
//! |---|---|
//! | [`geometry`] | re-exported [`pingcal_geometry`]: [`Rigid3`] (an image's `camera_from_object`, `x_cam = R·X + t`, and its local update), SO(3), the ω φ κ convention |
//! | [`camera`] | camera models ([`camera::CameraModel`]): photogrammetric (SPEC.md, forward Brown with affinity B1, B2), Brown backward (DBAT / PhotoModeler / Australis correction form), OpenCV (rational, tangential, thin prism), Kannala–Brandt fisheye, BAL; [`camera::check_jacobians`] for a new model |
//! | [`datum`] | the datum diagnosed before solving: control, fixed images, or a free network |
//! | [`io`] | pingcal's measurement file (JSON) and DBAT's mark-point, control and camera files |
//! | [`loss`] | robust losses (Huber, Cauchy) |
//! | [`problem`] | cameras, images, points, observations, distances, control |
//! | [`solver`] | Schur-complement Levenberg–Marquardt with a dense, sparse or iterative (PCG) reduced-system solver chosen by structure; precision (free networks of any number of points by bordering), data snooping, variance components |
//! | [`report`] | the adjustment report (Australis layout) as text and JSON |
//! | [`bal`] | BAL problem files; [`synthetic`]: generated BAL problems |
//! | [`initial`] | initial values: resection, relative orientation, intersection, incremental network |

pub mod bal;
pub mod camera;
pub mod datum;
pub mod initial;
pub mod io;
pub mod loss;
pub mod problem;
pub mod report;
pub mod solver;
pub mod synthetic;

/// The geometry foundation ([`Rigid3`], SO(3), ω φ κ, Umeyama, consensus), re-exported so
/// that a user of the adjuster needs one dependency.
pub use pingcal_geometry as geometry;
pub use pingcal_geometry::{Rigid3, Sim3};
