//! Typed keys of a [`Problem`]'s blocks (as factrs' keys): a residual names the point, the
//! image pose or the parameter block it depends on by a key of that kind, so that a point's
//! index cannot be passed where a parameter block's is meant. A key is the block's index in
//! the problem's vector of that kind ([`Problem::points`], [`Problem::images`],
//! [`Problem::parameters`]); `problem[key]` is the block. This module depends on nothing
//! else of the crate: the problem and the residuals both name their blocks by these keys.
//!
//! [`Problem`]: crate::problem::Problem
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
