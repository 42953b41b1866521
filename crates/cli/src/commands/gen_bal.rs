//! `pingcal gen-bal`: not built yet (issue 2).

use super::CmdResult;

/// Arguments of `pingcal gen-bal`.
#[derive(clap::Args)]
pub struct Args {
    /// Arguments (not yet defined).
    #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
    rest: Vec<String>,
}

/// Runs the command.
pub fn run(_args: Args) -> CmdResult {
    Err("'pingcal gen-bal' is not implemented yet (issue 2)".into())
}
