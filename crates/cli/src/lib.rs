//! The `pingcal` command line and the calibration pipeline.
//!
//! - [`pipeline`]: the whole calibration of a project, one file per step, in order.
//! - [`commands`]: one file per subcommand (`Args` and `run`); `main.rs` only dispatches.

pub mod commands;
pub mod pipeline;
#[cfg(test)]
mod test_support;
