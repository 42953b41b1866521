//! What every step of the calibration shares: the run's settings ([`Options`]) and its
//! failure ([`PipelineError`], one line). The lowest module of the pipeline after the
//! typed ids and the progress: every step imports from here, none from the crate root.

/// Why a calibration failed: one line that names the file, image, target or ball and what
/// was expected, of one of three kinds that say what to do about it ([`PipelineError::kind`]:
/// `pingcal calibrate --json` gives it as `error_kind`).
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    /// An input cannot be used as given: a file that does not read, a setting out of its
    /// range, an image of the wrong size, a point cloud where the method needs the beams.
    /// Mend the project.
    #[error("{0}")]
    Input(String),
    /// The data do not allow a step: too few coded targets, balls or beams seen, no distance
    /// left for the scale, a network that does not orient, a camera parameter the images do
    /// not determine. Take more (or better spread) data, or ask for less.
    #[error("{0}")]
    Data(String),
    /// An adjustment failed on data that passed the checks before it: a singular system, no
    /// convergence, a precision that cannot be computed.
    #[error("{0}")]
    Adjustment(String),
}

impl PipelineError {
    /// `input`, `data` or `adjustment`.
    pub fn kind(&self) -> &'static str {
        match self {
            PipelineError::Input(_) => "input",
            PipelineError::Data(_) => "data",
            PipelineError::Adjustment(_) => "adjustment",
        }
    }

    /// The same kind of error with `f` of its message.
    pub fn map_message(self, f: impl FnOnce(String) -> String) -> Self {
        match self {
            PipelineError::Input(m) => PipelineError::Input(f(m)),
            PipelineError::Data(m) => PipelineError::Data(f(m)),
            PipelineError::Adjustment(m) => PipelineError::Adjustment(f(m)),
        }
    }
}

/// Result of a pipeline step.
pub type Result<T> = std::result::Result<T, PipelineError>;

/// Settings of a run.
#[derive(Clone, Debug)]
pub struct Options {
    /// Seed of every random choice (RANSAC in the LRF steps).
    pub seed: u64,
    /// Worker threads of the bundle adjustments (0: all cores).
    pub threads: usize,
    /// Baarda's critical value for data snooping of image points (3.29: α = 0.1 %).
    pub snoop_critical: f64,
    /// How the initial network starts.
    pub start: Start,
    /// Measure saturated targets (flagged, σ tripled) instead of refusing them, whatever
    /// `[targets] measure_saturated` says (`pingcal calibrate --saturated`).
    pub measure_saturated: bool,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            seed: 1,
            threads: 0,
            snoop_critical: 3.29,
            start: Start::Auto,
            measure_saturated: false,
        }
    }
}

/// How the initial network may start (`pingcal calibrate --start`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Start {
    /// Every start the project allows, in the order below, until one works.
    #[default]
    Auto,
    /// Every image resected from the coded targets' approximate coordinates
    /// (`[targets] layout`), the layout held only as loosely as `layout_sigma_mm` says.
    Layout,
    /// The relative orientation of the best-conditioned image pair, its rays corrected for
    /// a radial distortion when the nominal intrinsics leave too few consistent points.
    Relative,
    /// One station's stereo pair at the head's nominal pose: the cameras parallel, the
    /// right one `[stereo] baseline_mm` to the right of the left one.
    Stereo,
}

impl Start {
    /// For the log, the warnings and results.json.
    pub fn describe(self) -> &'static str {
        match self {
            Start::Auto => "the first start that works",
            Start::Layout => "resection from the layout",
            Start::Relative => "relative orientation",
            Start::Stereo => "the stereo head's nominal pose",
        }
    }
}
