//! # pingcal-sim: simulator of the paper's test field and sensors
//!
//! Room corner with targets and ping-pong balls, a stereo camera and a rotating LRF,
//! written as real project files (PNG images, `pingcal-scan` CSV) with ground truth.
