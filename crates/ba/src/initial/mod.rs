//! Initial values from nothing but image measurements and approximate intrinsics.
//!
//! | module | what it does |
//! |---|---|
//! | [`resection`] | pose of one image from points of known coordinates (P3P + RANSAC, then LM) |
//! | [`relative`] | relative orientation of two images (essential matrix, 8-point, RANSAC) |
//! | [`intersection`] | object point from several oriented rays, with angle and cheirality checks |
//! | [`incremental`] | a whole network: resect, intersect, add images one by one, bundle between steps |

pub mod incremental;
pub mod intersection;
pub mod relative;
pub mod resection;
