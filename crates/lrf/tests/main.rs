//! The integration tests of pingcal-lrf, one test binary (each module was a file of its own).
//! Run one module with `cargo test -p pingcal-lrf --release --test lrf <module>::`.

mod common;

mod ball_range_study;
mod clutter;
mod corner_baseline;
mod density;
mod find_and_register;
mod parsers_never_panic;
mod pcd;
mod reader_mutations;
mod registration_mc;
mod sphere_bias;
mod sphere_invariant;
