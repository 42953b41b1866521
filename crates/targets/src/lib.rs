//! # pingcal-targets: target detection and identification in images
//!
//! Plain circular (retro-reflective) targets, AICON / Schneider ring-coded targets
//! (12 and 14 bit) and ping-pong-ball silhouettes.
