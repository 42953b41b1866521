//! `pingcal calibrate`: not built yet (issue 7).

use super::CmdResult;

/// Arguments of `pingcal calibrate`.
#[derive(clap::Args)]
pub struct Args {
    /// Arguments (not yet defined).
    #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
    rest: Vec<String>,
}

/// Runs the command.
pub fn run(_args: Args) -> CmdResult {
    Err("'pingcal calibrate' is not implemented yet (issue 7)".into())
}
