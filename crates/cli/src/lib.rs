//! The `pingcal` command line: one file per subcommand in [`commands`] (`Args`, then `run`:
//! check the input, call the libraries, print); `main.rs` only dispatches. The calibration
//! itself is the library `pingcal_pipeline`; the binary adds argument parsing, progress
//! bars, printing and the writing of result folders.

pub mod commands;
