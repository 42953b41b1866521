//! `pingcal demo`: not built yet (issue 7).

use super::CmdResult;

/// Arguments of `pingcal demo`.
#[derive(clap::Args)]
pub struct Args {
    /// Arguments (not yet defined).
    #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
    rest: Vec<String>,
}

/// Runs the command.
pub fn run(_args: Args) -> CmdResult {
    Err("'pingcal demo' is not implemented yet (issue 7)".into())
}
