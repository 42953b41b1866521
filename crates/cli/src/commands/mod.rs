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

/// The error every command returns, printed by `main` as one line: each library's own error
/// converts into it (`?`), a command's own message is [`CmdError::Message`], and a verdict's
/// end with a code of its own is [`CmdError::Exit`].
#[derive(Debug, thiserror::Error)]
pub enum CmdError {
    /// A command's end with an exit code of its own (see [`Exit`]).
    #[error(transparent)]
    Exit(#[from] Exit),
    /// A command's own one-line message.
    #[error("{0}")]
    Message(String),
    /// Reading or writing a file (the message names it where the command knows it).
    #[error(transparent)]
    Io(#[from] std::io::Error),
    /// A JSON file that does not parse, or a value that does not serialise.
    #[error(transparent)]
    Json(#[from] serde_json::Error),
    /// The project file or its layout.
    #[error(transparent)]
    Project(#[from] pingcal_project::ProjectError),
    /// The calibration pipeline.
    #[error(transparent)]
    Pipeline(#[from] pingcal_pipeline::PipelineError),
    /// The LRF's files and fits.
    #[error(transparent)]
    Lrf(#[from] pingcal_lrf::LrfError),
    /// A ROS bag.
    #[error(transparent)]
    Rosbag(#[from] pingcal_rosbag::RosbagError),
    /// The simulator.
    #[error(transparent)]
    Sim(#[from] pingcal_sim::SimError),
    /// The target detector's images.
    #[error(transparent)]
    Targets(#[from] pingcal_targets::TargetError),
    /// A BAL problem file.
    #[error(transparent)]
    Bal(#[from] pingcal_ba::bal::BalError),
    /// A pingcal measurement file.
    #[error(transparent)]
    Measurements(#[from] pingcal_ba::io::measurements::MeasurementError),
    /// DBAT's camera and measurement files.
    #[error(transparent)]
    Dbat(#[from] pingcal_ba::io::dbat::DbatError),
    /// The bundle adjustment's solver.
    #[error(transparent)]
    Solve(#[from] pingcal_ba::solver::SolveError),
    /// A measurement file's adjustment (`pingcal ba`).
    #[error(transparent)]
    Workflow(#[from] pingcal_ba::workflow::WorkflowError),
    /// The planner.
    #[error(transparent)]
    Plan(#[from] pingcal_plan::PlanError),
    /// A synthetic BAL problem's sizes (`pingcal gen-bal`).
    #[error(transparent)]
    Synthetic(#[from] pingcal_ba::synthetic::SyntheticError),
    /// Writing the outputs.
    #[error(transparent)]
    Output(#[from] pingcal_pipeline::result_set::OutputError),
}

impl From<String> for CmdError {
    fn from(m: String) -> Self {
        CmdError::Message(m)
    }
}

impl From<&str> for CmdError {
    fn from(m: &str) -> Self {
        CmdError::Message(m.to_string())
    }
}

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
