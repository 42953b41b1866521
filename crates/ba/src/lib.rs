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
//! | [`loss`] | robust losses (Huber, Cauchy) |
//! | [`problem`] | cameras, images, points, observations, distances, control |
//! | [`solver`] | Schur-complement Levenberg–Marquardt, precision, data snooping |
//! | [`report`] | the adjustment report (Australis layout) as text and JSON |
//! | [`bal`] | BAL problem files; [`synthetic`]: generated BAL problems |
//! | [`initial`] | initial values: resection, relative orientation, intersection, incremental network |

pub mod bal;
pub mod camera;
pub mod initial;
pub mod io;
pub mod loss;
pub mod pose;
pub mod problem;
pub mod report;
pub mod rotation;
pub mod solver;
pub mod synthetic;
