//! The integration tests of the `pingcal` binary, one test binary (each module was a file of
//! its own, and each file a binary that linked the whole workspace): end to end runs of the
//! commands on a simulated project, the safety of the command line, the ecosystems' own
//! readers of the exports, the docs' commands and the crate graph.
//!
//! Run one module with `cargo test -p pingcal --release --test cli <module>::`, e.g.
//! `cargo test -p pingcal --release --test cli e2e::`.

#[path = "e2e/common.rs"]
mod common;
mod fuzz;

mod architecture;
mod board_field;
mod boards;
mod cli_safety;
mod cloud_input;
mod docs_commands;
mod e2e;
mod ecosystem;
mod lrf_mount;
mod plan;
mod real_recordings;
mod scans;
mod sigma_honesty;
mod sphere_calib;
