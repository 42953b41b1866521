//! # pingcal-ba: bundle adjustment for close-range photogrammetry
//!
//! A library a photogrammetrist can reuse for any test field:
//!
//! | module | what it holds |
//! |---|---|
//! | [`geometry`] | re-exported [`pingcal_geometry`]: [`Rigid3`] (an image's `camera_from_object`, `x_cam = R·X + t`, and its local update), SO(3), the ω φ κ convention |
//! | [`camera`] | camera models ([`camera::CameraModel`]): photogrammetric (docs/formats.md, forward Brown with affinity B1, B2), Brown backward (DBAT / PhotoModeler / Australis correction form), OpenCV (rational, tangential, thin prism), Kannala–Brandt fisheye, BAL; [`camera::check_jacobians`] for a new model |
//! | [`datum`] | the datum diagnosed before solving: control, fixed images, or a free network |
//! | [`io`] | pingcal's measurement file (JSON) and DBAT's mark-point, control and camera files |
//! | [`loss`] | robust losses (Huber, Cauchy) |
//! | [`problem`] | cameras, images, points, observations, distances, control, the problem's own parameter blocks |
//! | [`residual`] | every observation beside the image points, on one trait ([`Residual`]: its whitened residual, its blocks, its analytic Jacobian): distances, control points, weighted pose priors, and kinds defined outside the crate (pingcal-lrf's laser beams) with their own parameter blocks (an extrinsic, a mount); [`residual::check_residual_jacobians`] for a new kind |
//! | [`solver`] | Schur-complement Levenberg–Marquardt with a dense, sparse or iterative (PCG) reduced-system solver chosen by structure; precision at any size (a sparse selected inversion of the reduced system; free networks by inner constraints through an S-transformation), data snooping, variance components |
//! | [`report`] | the adjustment report (Australis layout) as text and JSON |
//! | [`bal`] | BAL problem files; [`synthetic`]: generated BAL problems |
//! | [`initial`] | initial values: resection, relative orientation, intersection, incremental network |
//! | [`workflow`] | a measurement file adjusted end to end (datum, start, estimability, adjustment with snooping, precision, report), as `pingcal ba` runs it |
//!
//! # A small network, end to end
//!
//! A wall and a floor of targets seen from five stations with one photogrammetric camera,
//! two control points and a measured distance; self-calibrated, then its precision. The
//! items used most are re-exported at the crate root.
//!
//! ```
//! use pingcal_ba::{precision, solve, Camera, CameraModel, Distance, Image, ImageKey,
//!     Observation, Options, PhotogrammetricCamera, Point, PointKey, PointPrior, Problem, Rigid3};
//! use nalgebra::Vector3;
//! use std::sync::Arc;
//!
//! // The camera (1280 × 720 px, 3.75 µm pixels) and its true intrinsics: c, xp, yp (mm),
//! // K1, K2, K3, P1, P2, B1, B2.
//! let model = Arc::new(PhotogrammetricCamera::new(1280, 720, 0.00375));
//! let truth = vec![2.45, 0.012, -0.008, -0.021, 4e-4, 0.0, 1.5e-4, -1e-4, 0.0, 0.0];
//! // Targets (mm, object frame Z up) on a back wall at Y = 3000 and on the floor.
//! let mut targets = Vec::new();
//! for i in 0..6 {
//!     for j in 0..5 {
//!         let (a, b) = (-1250.0 + 500.0 * i as f64, -900.0 + 450.0 * j as f64);
//!         targets.push(Vector3::new(a, 3000.0, b));
//!         targets.push(Vector3::new(a, 1000.0 + 350.0 * j as f64, -1200.0));
//!     }
//! }
//! // Five convergent stations, two of them rolled by 90°.
//! let stations = [(-900.0, 0.0), (-400.0, 0.0), (0.0, 1.5708), (400.0, 0.0), (900.0, -1.5708)];
//! let poses: Vec<Rigid3> = stations
//!     .iter()
//!     .map(|&(x, roll)| {
//!         Rigid3::looking_at(Vector3::new(x, -600.0, 300.0), Vector3::new(0.0, 2000.0, -600.0), roll)
//!     })
//!     .collect();
//! let mut problem = Problem::default();
//! // Start from nominal intrinsics: only c is known roughly. Each block added returns its
//! // typed key (CameraKey, ImageKey, PointKey): an observation names its image and point by
//! // them, so that one cannot be passed for the other.
//! let mut start = vec![0.0; 10];
//! start[0] = 2.4;
//! let camera = problem.add_camera(Camera::new("cam", model.clone(), start));
//! let images: Vec<ImageKey> = poses
//!     .iter()
//!     .enumerate()
//!     .map(|(k, pose)| {
//!         problem.add_image(Image {
//!             name: format!("station{k}"),
//!             camera,
//!             camera_from_object: *pose, // here the truth; in practice from `initial`
//!             fixed: false,
//!             fixed_centre: [false; 3],
//!         })
//!     })
//!     .collect();
//! let mut keys: Vec<PointKey> = Vec::new();
//! for (p, x) in targets.iter().enumerate() {
//!     let point = problem.add_point(Point::new(format!("T{p}"), *x));
//!     keys.push(point);
//!     for (&image, pose) in images.iter().zip(&poses) {
//!         if let Some(uv) = model.project(&truth, &pose.transform(x), None, None) {
//!             if uv.x > 0.0 && uv.x < 1279.0 && uv.y > 0.0 && uv.y < 719.0 {
//!                 // σ = 0.1 px; the measurements are exact here.
//!                 problem.observations.push(Observation { image, point, uv, sigma: 0.1 });
//!             }
//!         }
//!     }
//! }
//! // The datum: three control points (1 mm) and a measured distance (0.1 mm).
//! for p in [0, 29, 59] {
//!     problem.point_priors.push(PointPrior {
//!         point: keys[p],
//!         position: targets[p],
//!         sigma: Vector3::repeat(1.0),
//!     });
//! }
//! let d = (targets[2] - targets[50]).norm();
//! problem.distances.push(Distance { a: keys[2], b: keys[50], value: d, sigma: 0.1 });
//!
//! let summary = solve(&mut problem, &Options::default(), |_| {}).expect("solves");
//! assert!(summary.final_cost < 1e-6 * summary.initial_cost);
//! let c = problem.cameras[0].params[0];
//! assert!((c - 2.45).abs() < 1e-6, "c = {c}");
//! let p = precision(&problem).expect("a datum");
//! println!("c = {c:.4} mm ± {:.1e}, σ0 {:.2}", p.intrinsics[0].sigmas[0], p.sigma0);
//! ```

pub mod bal;
pub mod datum;
pub mod diagnostics;
pub mod initial;
pub mod io;
pub mod keys;
pub mod loss;
pub mod problem;
pub mod report;
pub mod residual;
pub mod solver;
pub mod synthetic;
pub mod workflow;

/// The camera models ([`pingcal_camera`]), re-exported: the adjuster takes any of them.
pub use pingcal_camera as camera;
/// The geometry foundation ([`Rigid3`], SO(3), ω φ κ, Umeyama, consensus), re-exported so
/// that a user of the adjuster needs one dependency.
pub use pingcal_geometry as geometry;
pub use pingcal_geometry::{Rigid3, Sim3};

pub use camera::{CameraModel, PhotogrammetricCamera};
pub use keys::{CameraKey, ImageKey, ParameterKey, PointKey};
pub use problem::{Camera, Distance, Image, Observation, Point, PointPrior, Problem};
pub use residual::{
    Block, Jacobians, ParameterBlock, ParameterPrior, ParameterValue, PosePrior, Residual,
    ResidualBlock, Value,
};
pub use solver::{precision, solve, Options};
