//! The whole calibration of one project, one file per step, in the order they run:
//!
//! | step | file | what it does |
//! |---|---|---|
//! | 1 | [`detect`] | targets (coded, plain) and ball silhouettes in every image, in parallel; image sizes checked against their cameras |
//! | 2 | [`network`] | the coded targets' image points → initial orientation of every image (relative start, resection, intersection, bundle), scaled by the distances, moved into the main image's frame |
//! | 3 | [`matching`] | plain targets and balls: known points projected into every image ("driveback"), new points by multi-image epipolar matching; balls told from targets by their size in millimetres |
//! | 4 | [`bundle`] | the final self-calibrating adjustment: distances, stereo rig, main image as datum, ball centres corrected for the sphere's eccentricity, data snooping, precision |
//! | 5 | [`lrf`] | the LRF cloud from the scans and the spheres fitted to the balls |
//! | 6 | [`extrinsic`] | spheres ↔ balls by distance invariants, the 3D conformal transform with σ, control / check / leave-one-out tables; the Fan et al. 2019 corner baseline |
//! | 7 | [`results`], [`report`] | `results.json` (SPEC.md), `cloud.ply`, and the data of `report.html` |
//!
//! Every failure is a [`PipelineError`]: one line that names the file, image, target or ball
//! concerned and what was expected. Nothing is written until every step has succeeded.

pub mod bundle;
pub mod detect;
pub mod extrinsic;
pub mod lrf;
pub mod matching;
pub mod network;
pub mod report;
pub mod results;

use indicatif::{MultiProgress, ProgressBar, ProgressStyle};
use nalgebra::Vector3;
use pingcal_ba::pose::Pose;
use pingcal_project::Project;
use std::sync::Mutex;

/// Why a calibration failed: one line.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct PipelineError(pub String);

impl PipelineError {
    /// An error from a message.
    pub fn new(msg: impl Into<String>) -> Self {
        Self(msg.into())
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
}

impl Default for Options {
    fn default() -> Self {
        Self {
            seed: 1,
            threads: 0,
            snoop_critical: 3.29,
        }
    }
}

/// Progress bars and the step log of one project. Lines go to stderr (unless quiet) and
/// into the report.
pub struct Reporter {
    multi: Option<MultiProgress>,
    prefix: String,
    lines: Mutex<Vec<String>>,
}

impl Reporter {
    /// `multi`: where bars and lines are drawn (None: silent).
    pub fn new(multi: Option<MultiProgress>, prefix: impl Into<String>) -> Self {
        Self {
            multi,
            prefix: prefix.into(),
            lines: Mutex::new(Vec::new()),
        }
    }

    /// A silent reporter (tests, batch with --quiet).
    pub fn silent() -> Self {
        Self::new(None, "")
    }

    /// Logs one line.
    pub fn log(&self, line: impl Into<String>) {
        let line = line.into();
        if let Some(m) = &self.multi {
            if m.is_hidden() {
                eprintln!("{}{line}", self.prefix);
            } else {
                let _ = m.println(format!("{}{line}", self.prefix));
            }
        }
        self.lines.lock().expect("log lock").push(line);
    }

    /// A progress bar of `len` steps (hidden when silent).
    pub fn bar(&self, len: u64, what: &str) -> ProgressBar {
        match &self.multi {
            Some(m) => {
                let pb = m.add(ProgressBar::new(len));
                pb.set_style(
                    ProgressStyle::with_template(
                        "{prefix}{msg:<24} [{bar:30}] {pos}/{len} {elapsed_precise}",
                    )
                    .expect("valid template")
                    .progress_chars("=> "),
                );
                pb.set_prefix(self.prefix.clone());
                pb.set_message(what.to_string());
                pb
            }
            None => ProgressBar::hidden(),
        }
    }

    /// The lines logged so far.
    pub fn lines(&self) -> Vec<String> {
        self.lines.lock().expect("log lock").clone()
    }
}

/// What a point of the model is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PointKind {
    /// A coded target with its number.
    Coded(u32),
    /// A plain target.
    Plain,
    /// A ping-pong ball (its centre).
    Ball,
}

impl PointKind {
    /// `coded`, `plain` or `ball`.
    pub fn as_str(&self) -> &'static str {
        match self {
            PointKind::Coded(_) => "coded",
            PointKind::Plain => "plain",
            PointKind::Ball => "ball",
        }
    }
}

/// An object point and the detections that measure it.
#[derive(Clone, Debug)]
pub struct ModelPoint {
    /// Label: the coded number, `P1`…, or the ball id.
    pub name: String,
    /// What it is.
    pub kind: PointKind,
    /// Position (photogrammetric frame once [`network`] is done), mm.
    pub position: Vector3<f64>,
    /// (project image index, detection index) of each measurement.
    pub obs: Vec<(usize, usize)>,
}

/// The photogrammetric model as it grows through the steps.
#[derive(Clone, Debug)]
pub struct Model {
    /// Pose of each project image (None: not oriented).
    pub poses: Vec<Option<Pose>>,
    /// Intrinsics of each project camera.
    pub intrinsics: Vec<Vec<f64>>,
    /// Object points.
    pub points: Vec<ModelPoint>,
    /// Why images are not oriented (project image index, reason).
    pub unoriented: Vec<(usize, String)>,
}

impl Model {
    /// Detections already used by a point, per image.
    pub fn used(&self, detections: &[detect::ImageDetections]) -> Vec<Vec<bool>> {
        let mut used: Vec<Vec<bool>> = detections
            .iter()
            .map(|d| vec![false; d.targets.len()])
            .collect();
        for p in &self.points {
            for &(i, k) in &p.obs {
                used[i][k] = true;
            }
        }
        used
    }
}

/// Everything a calibration produces.
pub struct Outcome {
    /// `results.json`.
    pub results: results::Results,
    /// The data of `report.html`.
    pub report: pingcal_report::ReportData,
    /// `cloud.ply` (the LRF cloud with the fitted sphere centres).
    pub cloud_ply: Vec<u8>,
}

/// Runs the whole calibration of `project`.
pub fn calibrate(project: &Project, opts: &Options, rep: &Reporter) -> Result<Outcome> {
    let t0 = std::time::Instant::now();
    let dets = detect::detect_all(project, rep)?;
    let mut timing = vec![("detection".to_string(), t0.elapsed().as_secs_f64())];
    let t = std::time::Instant::now();
    let mut model = network::initial_network(project, &dets, opts, rep)?;
    timing.push(("initial orientation".into(), t.elapsed().as_secs_f64()));
    let t = std::time::Instant::now();
    matching::add_points(project, &dets, &mut model, opts, rep)?;
    timing.push(("matching".into(), t.elapsed().as_secs_f64()));
    let t = std::time::Instant::now();
    let adjusted = bundle::final_adjustment(project, &dets, &mut model, opts, rep)?;
    timing.push(("bundle adjustment".into(), t.elapsed().as_secs_f64()));
    let t = std::time::Instant::now();
    let lrf = lrf::lrf_spheres(project, opts, rep)?;
    timing.push(("LRF spheres".into(), t.elapsed().as_secs_f64()));
    let t = std::time::Instant::now();
    let ext = extrinsic::extrinsics(project, &model, &adjusted, &lrf, &dets, opts, rep)?;
    timing.push(("extrinsic".into(), t.elapsed().as_secs_f64()));
    let line = timing
        .iter()
        .map(|(n, s)| format!("{n} {s:.2} s"))
        .collect::<Vec<_>>()
        .join(", ");
    rep.log(format!("time: {line}"));
    let stages = Stages {
        project,
        dets: &dets,
        model: &model,
        adjusted: &adjusted,
        lrf: &lrf,
        ext: &ext,
    };
    Ok(results::assemble(&stages, rep, timing))
}

/// What the steps produced, for the results and the report.
pub struct Stages<'a> {
    /// The project.
    pub project: &'a Project,
    /// Step 1.
    pub dets: &'a [detect::ImageDetections],
    /// Steps 2–4 (the final model).
    pub model: &'a Model,
    /// Step 4.
    pub adjusted: &'a bundle::Adjusted,
    /// Step 5.
    pub lrf: &'a lrf::LrfData,
    /// Step 6.
    pub ext: &'a extrinsic::Extrinsics,
}
