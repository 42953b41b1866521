//! A measurement file adjusted end to end, as `pingcal ba` runs it: the datum diagnosed,
//! initial values found (resection, relative orientation, intersection: [`initialise`]),
//! the intrinsics' estimability judged before solving, the self-calibrating adjustment
//! (with data snooping when asked), its precision and the [`AdjustmentReport`].
//!
//! Every failure is one line that names the file (`source`) and what was expected; what
//! the start-up could not do (images not oriented, points not determined or refused by
//! their intersection angle) and the rejections are returned for the caller to tell.

use crate::datum::{self, DatumError};
use crate::initial::incremental::{initialise, IncrementalOptions, InitError, Step};
use crate::initial::intersection::IntersectionOptions;
use crate::io::measurements::Built;
use crate::loss::Loss;
use crate::problem::Problem;
use crate::report::AdjustmentReport;
use crate::solver::{
    self, ControlRejection, DistanceRejection, Options, Precision, PrecisionError, Rejection,
    SnoopError, SolveError, Summary,
};

/// Why a measurement file was not adjusted, or has no precision: one line naming the file
/// (where the failure is the file's) and what was expected.
#[derive(Debug, thiserror::Error)]
pub enum WorkflowError {
    /// The datum diagnosis found the datum missing or defined twice.
    #[error("{file}: {error}")]
    Datum {
        /// The measurement file.
        file: String,
        /// What is wrong with the datum.
        error: DatumError,
    },
    /// Nothing fixes the network (no control point, no fixed image, no distance) and a free
    /// network was not asked for.
    #[error("{file}: the datum is not defined: no control point, no fixed image and no distance, so the network's scale is free (the result would be at an arbitrary scale): fix an image (\"fixed\": true, with its pose) and give a distance, give control points, or ask for --free-network")]
    NoDatum {
        /// The measurement file.
        file: String,
    },
    /// The start-up found no initial values.
    #[error("{file}: no initial values: {error}")]
    Initial {
        /// The measurement file.
        file: String,
        /// Why.
        error: InitError,
    },
    /// A camera-model parameter the network cannot determine, named before the adjustment.
    #[error("{file}: {error}")]
    NotDeterminable {
        /// The measurement file.
        file: String,
        /// The parameter and why.
        error: PrecisionError,
    },
    /// The adjustment with data snooping failed.
    #[error(transparent)]
    Snooping(#[from] SnoopError),
    /// The adjustment failed.
    #[error(transparent)]
    Solve(#[from] SolveError),
    /// The adjusted network's precision could not be computed.
    #[error(transparent)]
    Precision(#[from] PrecisionError),
    /// `--precision` of an adjusted problem could not be computed.
    #[error("{file}: no precision: {error} (the adjustment itself is done)")]
    NoPrecision {
        /// The problem file.
        file: String,
        /// Why.
        error: PrecisionError,
    },
}

/// How to adjust a measurement file.
#[derive(Clone, Debug)]
pub struct AdjustOptions {
    /// The solver's options (iterations, tolerances, threads).
    pub solver: Options,
    /// The smallest angle (degrees) between two rays of a point the intersection accepts.
    pub min_intersection_angle_deg: f64,
    /// Data snooping's critical value of the standardized residuals (None: no snooping).
    pub snoop: Option<f64>,
    /// A robust loss replacing the file's.
    pub loss: Option<Loss>,
    /// Adjust as a free network (inner constraints) where the file fixes no datum.
    pub free_network: bool,
    /// Diagnose the datum before solving (always for a free network).
    pub check_datum: bool,
}

/// A measurement file's adjustment and what its start-up could not do.
pub struct Adjusted {
    /// What the start-up did, in order.
    pub steps: Vec<Step>,
    /// Images the start-up could not orient, with the reason.
    pub unoriented_images: Vec<(String, String)>,
    /// Points the start-up could not determine, with the reason.
    pub undetermined_points: Vec<(String, String)>,
    /// Of those, the points refused by the intersection angle, with their largest angle.
    pub refused_by_angle: Vec<(String, f64)>,
    /// The intrinsics' estimability was not judged before the adjustment (a reduced system
    /// of this many unknowns is too large for the test); the precision names any defect.
    pub estimability_not_checked: Option<usize>,
    /// A free network without distances: its scale is arbitrary.
    pub arbitrary_scale: bool,
    /// The adjusted problem.
    pub problem: Problem,
    /// The last adjustment's summary.
    pub summary: Summary,
    /// Its precision.
    pub precision: Precision,
    /// Image points rejected by the start-up's bundles and by data snooping.
    pub rejected: Vec<Rejection>,
    /// Distances rejected by data snooping.
    pub rejected_distances: Vec<DistanceRejection>,
    /// Control points rejected by data snooping.
    pub rejected_control_points: Vec<ControlRejection>,
    /// The adjustment report.
    pub report: AdjustmentReport,
}

/// Adjusts `built` (read from `source`, named in every error) with `options`.
pub fn adjust(
    built: &Built,
    source: &str,
    options: &AdjustOptions,
) -> Result<Adjusted, WorkflowError> {
    let file = || source.to_string();
    if options.check_datum || options.free_network {
        datum::check(&built.problem, options.free_network).map_err(|error| {
            WorkflowError::Datum {
                file: file(),
                error,
            }
        })?;
    }
    // A file that fixes nothing is adjusted as a free network: without a distance its scale
    // is arbitrary, which is a datum left undefined unless asked for.
    let arbitrary_scale = !datum::has_datum(&built.problem) && built.problem.distances.is_empty();
    if arbitrary_scale && !options.free_network {
        return Err(WorkflowError::NoDatum { file: file() });
    }
    let init_options = IncrementalOptions {
        bundle: options.solver.clone(),
        intersection: IntersectionOptions {
            min_angle_deg: options.min_intersection_angle_deg,
            ..IntersectionOptions::default()
        },
        ..IncrementalOptions::default()
    };
    let init = initialise(
        &built.problem,
        &built.known_points,
        &built.known_poses,
        &init_options,
    )
    .map_err(|error| WorkflowError::Initial {
        file: file(),
        error,
    })?;
    let mut problem = init.problem;
    // a camera-model parameter the network cannot determine: named before the adjustment
    let estimability_not_checked = match solver::check_intrinsics(&problem) {
        Err(error @ PrecisionError::NotDeterminable(_)) => {
            return Err(WorkflowError::NotDeterminable {
                file: file(),
                error,
            });
        }
        Ok(solver::Estimability::NotChecked(n)) => Some(n),
        // any other defect is named by the adjustment's precision
        _ => None,
    };
    if let Some(l) = options.loss {
        problem.loss = l;
    }
    let initial: Vec<Vec<f64>> = built
        .problem
        .cameras
        .iter()
        .map(|c| c.params.clone())
        .collect();
    // The start-up bundles' rejections are reported with the adjustment's own.
    let mut rejected = init.rejections;
    let (mut rejected_distances, mut rejected_control_points) = (Vec::new(), Vec::new());
    let (summary, precision) = match options.snoop {
        Some(w) => {
            let max_rejections = problem.observations.len() / 10;
            let r = solver::adjust_with_snooping(&mut problem, &options.solver, w, max_rejections)?;
            rejected.extend(r.rejected);
            rejected_distances = r.rejected_distances;
            rejected_control_points = r.rejected_control_points;
            (r.summary, r.precision)
        }
        None => {
            let summary = solver::solve(&mut problem, &options.solver, |_| {})?;
            let precision = solver::precision(&problem)?;
            (summary, precision)
        }
    };
    let mut report = AdjustmentReport::new(&problem, &initial, &summary, &precision, &rejected);
    report.rejected_distances = rejected_distances.clone();
    report.rejected_control_points = rejected_control_points.clone();
    Ok(Adjusted {
        steps: init.steps,
        unoriented_images: init.unoriented_images,
        undetermined_points: init.undetermined_points,
        refused_by_angle: init.refused_by_angle,
        estimability_not_checked,
        arbitrary_scale,
        problem,
        summary,
        precision,
        rejected,
        rejected_distances,
        rejected_control_points,
        report,
    })
}

/// What `--precision` reports of a BAL problem: σ0, the redundancy, and the medians over
/// the cameras and the points of the largest of their three σ's.
#[derive(Clone, Debug, serde::Serialize)]
pub struct PrecisionSummary {
    /// σ0.
    pub sigma0: f64,
    /// Observations minus unknowns.
    pub redundancy: i64,
    /// How the cofactors were computed ([`Precision::cofactors`]).
    pub method: &'static str,
    /// Seconds the precision took.
    pub time_s: f64,
    /// Median over the cameras of the largest σ of the projection centre.
    pub median_camera_centre_sigma: f64,
    /// Median over the points of the largest σ of the coordinates.
    pub median_point_sigma: f64,
}

/// The precision of an adjusted problem (read from `source`), summarised.
pub fn precision_summary(
    problem: &Problem,
    source: &str,
) -> Result<PrecisionSummary, WorkflowError> {
    let t = std::time::Instant::now();
    let prec = solver::precision(problem).map_err(|error| WorkflowError::NoPrecision {
        file: source.to_string(),
        error,
    })?;
    let time_s = t.elapsed().as_secs_f64();
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
    };
    let centre = median(
        (prec.poses.iter().flatten())
            .map(|s| s.centre.iter().copied().fold(0.0, f64::max))
            .collect(),
    );
    let point = median(
        (0..problem.points.len())
            .filter_map(|p| prec.point_sigma(p))
            .map(|s| s.max())
            .collect(),
    );
    Ok(PrecisionSummary {
        sigma0: prec.sigma0,
        redundancy: prec.redundancy,
        method: prec.cofactors,
        time_s,
        median_camera_centre_sigma: centre,
        median_point_sigma: point,
    })
}

/// The JSON of an adjusted BAL problem, as `pingcal ba --out` writes it: the solver's
/// summary, the sizes, the threads, and the precision ([`precision_summary`]) or why there is
/// none (`precision_error`).
pub fn run_json(
    problem: &Problem,
    summary: &Summary,
    precision: Option<&Result<PrecisionSummary, WorkflowError>>,
    threads: usize,
) -> Result<serde_json::Value, serde_json::Error> {
    let mut json = serde_json::json!({
        "initial_cost": summary.initial_cost,
        "final_cost": summary.final_cost,
        "iterations": summary.iterations,
        "successful_steps": summary.successful_steps,
        "time_s": summary.time_s,
        "linear_solver_time_s": summary.linear_solver_time_s,
        "evaluation_time_s": summary.evaluation_time_s,
        "schur_time_s": summary.schur_time_s,
        "setup_time_s": summary.setup_time_s,
        "linear_solver": summary.linear_solver.kind,
        "linear_solver_reason": summary.linear_solver.reason,
        "schur_product": summary.schur_product,
        "reduced_dimension": summary.reduced_dimension,
        "reduced_nonzeros": summary.reduced_nonzeros,
        "linear_iterations": summary.linear_iterations,
        "clusters": summary.clusters,
        "termination": summary.termination,
        "rms_px": problem.rms_px(),
        "cameras": problem.images.len(),
        "points": problem.points.len(),
        "observations": problem.observations.len(),
        "threads": threads,
    });
    match precision {
        Some(Ok(p)) => json["precision"] = serde_json::to_value(p)?,
        Some(Err(e)) => json["precision_error"] = e.to_string().into(),
        None => {}
    }
    Ok(json)
}
