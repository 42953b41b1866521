//! One module per subcommand. Each exposes `Args` (clap) and `run(Args) -> CmdResult`.

pub mod ba;
pub mod calibrate;
pub mod cloud;
pub mod demo;
pub mod detect;
pub mod frames;
pub mod gen_bal;
pub mod lrf_mount;
pub mod plan;
pub mod preflight;
pub mod progress;
pub mod register;
pub mod scans;
pub mod simulate;
pub mod sphere_calib;
pub mod targets;

/// The error every command returns: printed by `main` as one line.
pub type CmdError = Box<dyn std::error::Error + Send + Sync>;
/// The result every command returns.
pub type CmdResult = Result<(), CmdError>;

/// A command's end with an exit code of its own (not the 1 of every other error): `main`
/// prints `pingcal: MESSAGE` (nothing when the message is empty) and exits with `code`.
/// `pingcal calibrate` ends so when its verdict is doubtful (3) or failed (4).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Exit {
    /// The process's exit code.
    pub code: i32,
    /// One line for stderr (empty: none).
    pub message: String,
}

impl std::fmt::Display for Exit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} (exit {})", self.message, self.code)
    }
}

impl std::error::Error for Exit {}

/// The output folder's set and the atomic writes of single files (in the pipeline library).
pub use pingcal_pipeline::result_set::{
    self, partial_path, write_atomic, write_target, WriteTarget,
};
