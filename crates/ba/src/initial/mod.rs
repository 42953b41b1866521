//! Initial values from nothing but image measurements and approximate intrinsics.
//!
//! | module | what it does |
//! |---|---|
//! | [`resection`] | pose of one image from points of known coordinates (P3P + RANSAC, then LM) |
//! | [`relative`] | relative orientation of two images (essential matrix, 8-point, RANSAC; homography for flat scenes) |
//! | [`intersection`] | object point from several oriented rays, with angle and cheirality checks |
//! | [`incremental`] | a whole network: resect, intersect, add images one by one, bundle between steps |
//!
//! From a measurement file to an adjusted network:
//!
//! ```no_run
//! use pingcal_ba::initial::incremental::{initialise, IncrementalOptions};
//! use pingcal_ba::io::measurements::Measurements;
//! use pingcal_ba::solver::{solve, Options};
//!
//! let m = Measurements::read("field.json".as_ref())?;
//! let built = m.to_problem()?;
//! for w in &built.warnings {
//!     eprintln!("warning: {w}");
//! }
//! let init = initialise(
//!     &built.problem,
//!     &built.known_points,
//!     &built.known_poses,
//!     &IncrementalOptions::default(),
//! )?;
//! for (image, why) in &init.unoriented_images {
//!     eprintln!("image '{image}' not oriented: {why}");
//! }
//! let mut problem = init.problem;
//! let summary = solve(&mut problem, &Options::default(), |_| {})?;
//! println!("{} iterations, RMS {:.3} px", summary.iterations, problem.rms_px());
//! m.with_solution(&problem).write("field-adjusted.json".as_ref())?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod incremental;
pub mod intersection;
pub mod relative;
pub mod resection;
