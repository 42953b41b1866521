//! Typed keys of a [`Problem`]'s blocks (as factrs' keys): an image names its camera, an
//! observation its image and point, a distance its two points, a control point and a rig
//! member theirs, and a residual the blocks it depends on, each by a key of that kind, so
//! that a point's index cannot be passed where an image's or a parameter block's is meant.
//! A key is the block's index in the problem's vector of that kind ([`Problem::cameras`],
//! [`Problem::images`], [`Problem::points`], [`Problem::parameters`]), returned by the
//! problem's `add_camera`, `add_image`, `add_point` and `add_parameter`; `problem[key]`, or
//! `problem.points[key]` and the like, is the block (a slice of blocks of another kind is
//! not indexed by it). Its `.0` is the plain index, for the solver's own arrays. This module
//! depends on nothing else of the crate: the problem and the residuals both name their
//! blocks by these keys.
//!
//! ```
//! use pingcal_ba::{PointKey, Problem};
//! use nalgebra::Vector3;
//! let mut problem = Problem::default();
//! let key: PointKey = problem.add_point(pingcal_ba::Point::new("T1", Vector3::zeros()));
//! assert_eq!(problem.points[key].name, "T1");
//! ```
//!
//! A point's key does not index the images:
//!
//! ```compile_fail
//! use pingcal_ba::{PointKey, Problem};
//! let problem = Problem::default();
//! let _ = &problem.images[PointKey(0)];
//! ```
//!
//! [`Problem`]: crate::problem::Problem
//! [`Problem::cameras`]: crate::problem::Problem::cameras
//! [`Problem::points`]: crate::problem::Problem::points
//! [`Problem::images`]: crate::problem::Problem::images
//! [`Problem::parameters`]: crate::problem::Problem::parameters

/// An object point of a problem (index into [`Problem::points`](crate::problem::Problem::points)).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct PointKey(pub usize);

/// An image of a problem, its pose (index into [`Problem::images`](crate::problem::Problem::images)).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ImageKey(pub usize);

/// One of a problem's own parameter blocks (index into [`Problem::parameters`](crate::problem::Problem::parameters)).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ParameterKey(pub usize);

/// A camera (intrinsics) of a problem (index into [`Problem::cameras`](crate::problem::Problem::cameras)).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct CameraKey(pub usize);

macro_rules! display_index {
    ($($key:ty),*) => {$(
        /// The index, as a number.
        impl std::fmt::Display for $key {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                self.0.fmt(f)
            }
        }
    )*};
}

display_index!(PointKey, ImageKey, ParameterKey, CameraKey);
