//! # pingcal-ba: bundle adjustment for close-range photogrammetry
//!
//! A library a photogrammetrist can reuse for any test field:
//!
//! | module | what it holds |
//! |---|---|
//! | [`rotation`] | SO(3): exp/log maps, skew matrix, ω φ κ angles |
//! | [`pose`] | exterior orientation `x_cam = R·X + t` and its local update |
//! | [`camera`] | camera models ([`camera::CameraModel`]): photogrammetric (SPEC.md), BAL |
//! | [`io`] | pingcal's measurement file (JSON) and DBAT's mark-point and control files |
//! | [`initial`] | initial values: resection, relative orientation, intersection, incremental network |

pub mod bal;
pub mod camera;
pub mod initial;
pub mod io;
pub mod loss;
pub mod pose;
pub mod problem;
pub mod rotation;
pub mod solver;
pub mod synthetic;
