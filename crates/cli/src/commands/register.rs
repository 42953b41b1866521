//! `pingcal register`: not built yet (issue 5).

use super::CmdResult;

/// Arguments of `pingcal register`.
#[derive(clap::Args)]
pub struct Args {
    /// Arguments (not yet defined).
    #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
    rest: Vec<String>,
}

/// Runs the command.
pub fn run(_args: Args) -> CmdResult {
    Err("'pingcal register' is not implemented yet (issue 5)".into())
}
