//! # pingcal-ba: bundle adjustment for close-range photogrammetry
//!
//! Geometry (SO(3), poses), camera models with analytic Jacobians, a sparse
//! Schur-complement Levenberg–Marquardt solver, and BAL problem I/O.
