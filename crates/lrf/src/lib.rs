//! # pingcal-lrf: the rotating 2D laser range finder side of the calibration
//!
//! Scan files to point clouds, automatic ball (sphere) finding and fitting, rigid
//! registration with check points, and the Fan et al. 2019 corner baseline.
