//! The integration tests of pingcal-ba, one test binary (each module was a file of its own).
//! Run one module with `cargo test -p pingcal-ba --release --test ba <module>::`.

mod common;

mod camera_models;
mod dbat_camcal;
mod estimability;
mod held_coordinates;
mod precision;
mod reader_mutations;
mod recovery;
mod residuals;
mod rig;
mod selected_inverse;
mod snooping;
mod solver_bal;
