//! Step 7: the joint adjustment — image points, distances and every LRF beam that hit a
//! ball in one bundle adjustment, with the extrinsic and the rotating LRF's mount and range
//! errors among its unknowns.
//!
//! **One problem.** The bundle's final problem (intrinsics, image poses, targets, ball
//! centres in the photogrammetric frame, distances; each group of image observations
//! weighted by its variance component) gains two parameter blocks
//! ([`pingcal_ba::ParameterBlock`]): the extrinsic `camera_from_lrf` (a pose, left-perturbed
//! like the image poses) and the mount
//! `θ = [offset_x, offset_y, offset_z, tilt_x, tilt_z, servo_scale, range_offset, range_scale]`
//! of [`pingcal_lrf::sensor::MountModel`]; and every non-grazing beam on a control ball
//! becomes an observation of the same adjustment ([`pingcal_lrf::beam::BeamOnBall`], a
//! [`pingcal_ba::Residual`] on the ball's centre, the extrinsic and the mount). The solver
//! adjusts everything together and the covariances (extrinsic, mount, their correlations,
//! the balls) come from the joint normal equations. The balls' eccentricity corrections of
//! the image points are those of the bundle's solution (they change by far less than a
//! pixel when the centres move by a millimetre).
//!
//! **Beam observations.** A beam (servo angle, beam angle, range) predicts the range at
//! which its ray meets the sphere of the project's ball radius centred on the ball:
//! `c = camera_from_lrf⁻¹ · X`, `e = r − r̂(θ, c)` ([`pingcal_lrf::beam::beam_range_residual`]),
//! whitened by the sensor's σ(r). Beams that graze the ball at the two-step estimate (the root
//! of the along-ray distance below `pingcal_lrf::beam::GRAZING_KAPPA` of the radius) are left
//! out: their range is a footprint effect more than a distance. The check balls' beams are
//! left out too, so that the check points stay independent of the estimate.
//!
//! **What the data cannot fix.** The servo's zero and the extrinsic's rotation about the
//! servo axis (Y) are one thing, and so are `offset_y` (along the servo axis) and the
//! extrinsic's translation along Y: the LRF frame is *defined* with its origin on the servo
//! axis at the scan plane and its zero at the project's `servo_zero_deg`, so neither is an
//! unknown. What else the sweep and the field can determine is found from the data
//! (`estimability`): the adjustment is first run with every asked-for mount parameter
//! estimated under its plausible prior (below); at its solution the cofactors with a weak
//! prior (σ of [`PRIOR_SIGMA`], [`pingcal_ba::ParameterPrior`]) in place of the plausible one
//! decide: a parameter whose σ is more than [`MAX_PRIOR_SHARE`] of that prior (the data add
//! nothing), or that is correlated with another unknown at |ρ| > [`MAX_CORRELATION`], is held
//! at its start value (the project's, or the estimate of the pass before) and named, one at
//! a time, and the adjustment is run again without it.
//!
//! **A real rig's a-priori knowledge.** Every other parameter is estimated, with a prior of
//! the plausible size of such an error ([`PLAUSIBLE`], e.g. ±20 mm for a scanner offset) at
//! the project's value. Where the data determine a parameter well the prior does nothing;
//! where they determine it only loosely (a σ of 11 mm for an offset along a direction the
//! balls hardly constrain) it keeps the estimate inside what a real mount can be, and its σ
//! says how loose it is. Holding such a parameter at zero instead would put the whole of the
//! rig's true error, unseen by any σ, into the extrinsic: with offsets of 10–18 mm held this
//! way, the check balls came out 3–7 times their σ.
//!
//! **Gross errors.** Beams whose standardised residual (Baarda's w, from the joint
//! redundancy numbers) exceeds [`BEAM_REJECT`] times the beams' σ0 (at least 1) after an
//! adjustment (mixed pixels at the ball's edge, the stem) are removed and the adjustment run
//! again, at most [`REJECT_ROUNDS`] times.
//!
//! **Weights.** The final adjustment estimates the variance component of every group
//! (targets, ball silhouettes, distances, beams; [`pingcal_ba::solver::estimate_variance_components`])
//! and weights each by its own: the covariances are those of that adjustment. `sigma0` is the
//! a-priori one (the bundle's χ² with its a-priori σ's plus the beams' with the sensor's σ(r),
//! over the joint redundancy), which the verdict tests.
//!
//! **Check points.** Each check ball's sphere is fitted again to its own beams with the
//! estimated mount and mapped by the estimated extrinsic; its camera side is the joint
//! adjustment's centre (its image rays only); `dx = estimated − reference`, as the two-step
//! method's table.

use super::bundle::{Adjusted, OBSERVATION_GROUPS};
use super::extrinsic::Extrinsics;
use super::ids::{PointId, SphereId};
use super::lrf::LrfData;
use super::scene::{Detections, PointKind, Scene};
use crate::context::{PipelineError, Result};
use crate::progress::Reporter;
use nalgebra::{DMatrix, Matrix3, Vector3};
use pingcal_ba::solver::{self, Precision, VarianceComponent};
use pingcal_ba::{
    ParameterBlock, ParameterKey, ParameterPrior, ParameterValue, Problem, ResidualBlock,
};
use pingcal_geometry::{opk_sigma_deg, Rigid3, Sim3};
use pingcal_lrf::beam::{fit_sphere_to_beams, BeamOnBall};
use pingcal_lrf::cloud::BeamReading;
use pingcal_lrf::registration::{check_table, CheckTable, PointObs};
use pingcal_lrf::room::{self, BeamOnPlane, Gate, PlaneFrame, RoomOptions};
use pingcal_lrf::sensor::{MountModel, MountParam, RangeNoise, MOUNT_PARAM_NAMES};
use pingcal_lrf::sphere_fit::FitOptions;
use pingcal_project::Project;

/// σ of the weak prior on each mount parameter while estimability is tested, in the
/// parameter's unit (mm, rad, 1): far wider than any real error, so that the prior only
/// makes the normal equations regular.
pub const PRIOR_SIGMA: [f64; 8] = [100.0, 100.0, 100.0, 0.2, 0.2, 0.1, 100.0, 0.1];

/// The plausible size of each mount error (published rotating-LRF calibrations: offsets
/// up to ±20 mm, tilts up to ±1°, servo scale ±0.5 %, URG range offsets of centimetres,
/// range scale ±1 %): the σ of the final adjustment's prior on each estimated parameter.
pub const PLAUSIBLE: [f64; 8] = [20.0, 20.0, 20.0, 0.01745, 0.01745, 0.005, 25.0, 0.01];

/// σ of the weak prior on the servo time offset while its estimability is tested (s).
pub const TIME_OFFSET_PRIOR_SIGMA_S: f64 = 10.0;

/// The plausible size of a servo time offset (s): the σ of the final adjustment's prior on
/// it. Drivers stamp a servo's and a scanner's messages some milliseconds to tens of
/// milliseconds apart (a USB or serial latency, a scan stamped at its start or its end).
pub const TIME_OFFSET_PLAUSIBLE_S: f64 = 0.1;

/// The servo time offset's name, as results.json and the notes give it.
pub const TIME_OFFSET_NAME: &str = "time_offset_s";

/// A parameter whose posterior σ is more than this share of its prior σ is not determined
/// by the data.
pub const MAX_PRIOR_SHARE: f64 = 0.2;

/// A parameter correlated with another unknown beyond this is held.
pub const MAX_CORRELATION: f64 = 0.999;

/// A sweep of less than this (degrees) is not a full turn of the servo.
pub const FULL_TURN_DEG: f64 = 350.0;

/// Beams whose standardised residual |w| over the beams' σ0 (at least 1) is above this after
/// an adjustment are gross errors (α ≈ 0.1 %).
pub const BEAM_REJECT: f64 = 3.29;

/// Rounds of beam rejection.
pub const REJECT_ROUNDS: usize = 3;

/// The room's planes give the joint adjustment at most this many beams each (taken evenly
/// in scan order): enough that the planes fix the mount parameters they can to a fraction
/// of a millimetre, few enough that the adjustment's time stays that of the balls.
pub const PLANE_BEAMS: usize = 2000;

/// Why the joint adjustment gave no result.
#[derive(Clone, Debug)]
pub struct JointError {
    /// One line.
    pub message: String,
    /// It did not converge from any start (its results were absurd for the field): the
    /// calibration failed, which the verdict says; else an error that leaves the two-step
    /// result standing as a doubtful one.
    pub not_converged: bool,
}

impl JointError {
    /// An error that leaves the two-step result standing.
    pub fn other(message: impl Into<String>) -> Self {
        Self {
            message: message.into(),
            not_converged: false,
        }
    }
}

impl std::fmt::Display for JointError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message)
    }
}

/// One mount parameter's outcome.
#[derive(Clone, Debug)]
pub struct MountEstimate {
    /// Its name ([`MOUNT_PARAM_NAMES`]).
    pub name: &'static str,
    /// Value (mm, degrees for the tilts, 1 for the scales).
    pub value: f64,
    /// Its σ (same unit); None when held.
    pub sigma: Option<f64>,
    /// Why it was held (None: estimated).
    pub held: Option<String>,
    /// Correlation with the extrinsic's ω, φ, κ (as rotation-vector components) and t
    /// (None when held).
    pub corr_extrinsic: Option<[f64; 6]>,
}

/// The joint adjustment's outcome.
#[derive(Clone, Debug)]
pub struct JointOutcome {
    /// LRF → main camera.
    pub camera_from_lrf: Rigid3,
    /// σ of the translation (mm).
    pub sigma_translation_mm: [f64; 3],
    /// σ of ω, φ, κ (degrees).
    pub sigma_opk_deg: [f64; 3],
    /// Covariance of (δθ, t) of the extrinsic (rad, mm).
    pub extrinsic_cov: DMatrix<f64>,
    /// The mount parameters in [`MOUNT_PARAM_NAMES`] order.
    pub mount: Vec<MountEstimate>,
    /// The servo time offset ([`TIME_OFFSET_NAME`], seconds), where the servo turned during
    /// the scans (a continuous sweep); None for a stop-and-go sweep.
    pub time_offset: Option<MountEstimate>,
    /// The estimated mount model (with the servo time offset).
    pub mount_model: MountModel,
    /// Covariance of the mount parameters ([`MountModel::to_params`] units: mm, rad, 1;
    /// zero rows for held ones).
    pub mount_cov: DMatrix<f64>,
    /// Beams used, and removed as gross errors or as grazing.
    pub beams: usize,
    /// Beams removed as gross errors.
    pub beams_rejected: usize,
    /// Beams left out as grazing.
    pub beams_grazing: usize,
    /// Beams left out because their footprint reaches the ball's silhouette (mixed pixels,
    /// [`pingcal_lrf::beam::BeamOnBall::at_silhouette`]); not counted as grazing.
    pub beams_silhouette: usize,
    /// σ0 of the whole adjustment with the a-priori σ's, and its redundancy.
    pub sigma0: f64,
    /// The σ0 of every group of the joint adjustment (targets, balls, distances, the beams
    /// against the sensor's σ(r)), by which it was re-weighted.
    pub variance_components: Vec<VarianceComponent>,
    /// Redundancy.
    pub redundancy: i64,
    /// RMS of the beam residuals (mm).
    pub rms_beam_mm: f64,
    /// Check-ball errors (dx = estimated − reference).
    pub check: CheckTable,
    /// Control-ball residuals (their spheres refitted with the estimated mount).
    pub control: CheckTable,
    /// The LRF side of every matched ball, refitted with the estimated mount.
    pub lrf_points: Vec<PointObs>,
    /// The camera side of every matched ball, from the joint adjustment.
    pub cam_points: Vec<PointObs>,
    /// Every ball of the scene: its centre and covariance in the photogrammetric frame from
    /// the joint adjustment (a control ball's LRF beams join its image rays; a check ball
    /// has its image rays only).
    pub ball_centres: Vec<(PointId, PointObs)>,
    /// Held parameters and other choices, one line each.
    pub notes: Vec<String>,
    /// The LRF as the pass that gave this outcome saw it (through its start mount).
    pub lrf_view: LrfView,
    /// Beams on the room's planes used, and removed as gross errors.
    pub plane_beams: usize,
    /// Beams on the room's planes removed as gross errors.
    pub plane_beams_rejected: usize,
    /// RMS of the plane beams' residuals (mm).
    pub rms_plane_mm: f64,
    /// The room's planes as estimated (unit normal, offset; LRF frame): where the next pass
    /// looks for their beams.
    pub planes: Vec<(Vector3<f64>, f64)>,
    /// How the adjustment converged and whether a second start agreed.
    pub convergence: Convergence,
    /// Why every mount parameter was held (the simpler model chosen), if it was.
    pub hold_mount: Option<String>,
}

/// What the LRF step gave the joint adjustment's pass: the spheres found in the cloud
/// through its start mount and how many were matched (the verdict judges these, not those
/// of the project's mount, when the joint adjustment's result is the one given).
#[derive(Clone, Debug, Default)]
pub struct LrfView {
    /// The pass (1: the project's mount; more: the cloud again through an estimate).
    pub pass: usize,
    /// Spheres found.
    pub spheres: usize,
    /// Spheres matched to balls of the photogrammetric model.
    pub matched: usize,
    /// Candidates rejected because as many beams pass through them as meet them.
    pub seen_twice_rejected: usize,
    /// Spheres kept although seen twice.
    pub seen_twice_kept: usize,
    /// Balls of the photogrammetric model matched to no sphere while a rejected LRF
    /// candidate lies within a ball's diameter of where this pass's extrinsic puts them:
    /// a ball the cloud's residual mount error spoilt (beams through it, a fit lost), which
    /// a cloud through a better mount may give back.
    pub rejected_at_unmatched: usize,
    /// Labels (`[balls] labels`) of balls the images did not measure where a sphere matched
    /// to no ball lies in the main image ([`super::matching::unmeasured_labels_at`]): those
    /// spheres are balls the photographs missed, not spurious ones.
    pub unmeasured_labels: Vec<String>,
}

/// The balls of the joint adjustment: (LRF sphere, scene point, name, is a check ball).
fn joint_balls<'a>(
    ext: &'a Extrinsics,
    scene: &'a Scene,
) -> Vec<(SphereId, PointId, &'a str, bool)> {
    ext.pairs
        .iter()
        .map(|&(s, p)| {
            let name = scene.points[p].name.as_str();
            (s, p, name, ext.check_ids.iter().any(|c| c == name))
        })
        .collect()
}

/// Which mount parameters the project asks for.
fn asked(project: &Project) -> [bool; 8] {
    let mut free = [false; 8];
    for p in project.file.lrf.self_calibrated() {
        free[p.index()] = true;
    }
    free
}

/// The joint problem's own parameter blocks: the extrinsic (δω, δt) and the mount's 8; the
/// planes and the servo time offset follow.
#[derive(Clone, Copy, Debug)]
struct Keys {
    extrinsic: ParameterKey,
    mount: ParameterKey,
}

/// Where the extrinsic's 6 unknowns (δω, δt) and the mount's 8 are among the rows of a
/// precision's parameter covariance: read from the solver's offsets of their blocks
/// (`Precision::parameter_offsets`), not from the order the blocks were added in.
#[derive(Clone, Copy, Debug)]
struct Rows {
    extrinsic: usize,
    mount: usize,
}

impl Rows {
    fn of(keys: &Keys, prec: &Precision) -> Self {
        Rows {
            extrinsic: prec.parameter_offsets[keys.extrinsic.0],
            mount: prec.parameter_offsets[keys.mount.0],
        }
    }

    /// The row of the extrinsic's unknown `k` (0–2 δω, 3–5 δt).
    fn ext(&self, k: usize) -> usize {
        self.extrinsic + k
    }

    /// The row of mount parameter `k` ([`MountParam::index`]).
    fn mount(&self, k: usize) -> usize {
        self.mount + k
    }

    /// The extrinsic's rows and those of the free mount parameters, each with its name.
    fn named(&self, free: &[bool; 8]) -> Vec<(usize, String)> {
        let ext = ["ω", "φ", "κ", "tx", "ty", "tz"];
        (0..6)
            .map(|k| (self.ext(k), format!("the extrinsic's {}", ext[k])))
            .chain(
                (0..8)
                    .filter(|&k| free[k])
                    .map(|k| (self.mount(k), MOUNT_PARAM_NAMES[k].to_string())),
            )
            .collect()
    }
}

/// The beams on the control balls left out of the joint problem at its start.
#[derive(Clone, Copy, Debug)]
struct LeftOut {
    /// Grazing (or missing) the ball.
    grazing: usize,
    /// Their footprint reaching the silhouette (and not grazing).
    silhouette: usize,
}

/// The joint problem before its mount's free set and its priors are chosen: the bundle's
/// final problem with the two parameter blocks, and the beams on control balls.
struct Joint {
    base: Problem,
    beams: Vec<BeamOnBall>,
    /// Beams on the room's planes (their planes are the parameter blocks from 2 on).
    planes: Vec<BeamOnPlane>,
    /// What the solver did in the last adjustment of [`final_rounds`].
    last: Option<solver::Summary>,
    /// Per image observation of `base`, its group ([`OBSERVATION_GROUPS`]).
    group_of: Vec<usize>,
    /// The project's mount: where the priors are centred.
    prior_theta: [f64; 8],
    /// The servo angles the beams span (degrees).
    sweep_deg: f64,
    /// The servo time offset's parameter block, where the servo turned during the scans
    /// (a continuous sweep); see [`TimeOffset`].
    time_offset: Option<TimeOffset>,
    /// The extrinsic's and the mount's blocks.
    keys: Keys,
    options: solver::Options,
}

/// The servo time offset τ in the joint problem ([`MountModel::servo_time_offset_s`]).
#[derive(Clone, Debug)]
struct TimeOffset {
    /// Its parameter block (after the planes').
    block: ParameterKey,
    /// Where its prior is centred: the project's value (s).
    prior: f64,
    /// Why it is held (None: estimated).
    held: Option<String>,
}

impl TimeOffset {
    /// Estimated, not held.
    fn free(&self) -> bool {
        self.held.is_none()
    }
}

impl Joint {
    /// The joint problem of `input`, and the beams left out.
    fn build(input: &JointInput) -> Result<(Self, LeftOut)> {
        let JointInput {
            project,
            scene,
            adj,
            lrf,
            ext,
            ..
        } = *input;
        let readings = lrf.cloud.readings.as_ref().ok_or_else(|| {
            PipelineError::Input(format!(
                "{}: the joint adjustment needs the LRF's beams (pingcal-scan CSV files), not a point cloud: use method = \"spheres\"",
                project.path.display()
            ))
        })?;
        let radius = 0.5 * project.file.balls.diameter_mm;
        let theta0 = input.mount0.to_params();
        let tau0 = input.mount0.servo_time_offset_s;
        let mut base = adj.solved.problem.clone();
        base.parameters.clear();
        let keys = Keys {
            extrinsic: base.add_parameter(ParameterBlock::pose("camera_from_lrf", input.start)),
            mount: base.add_parameter(ParameterBlock::vector("lrf mount", theta0.to_vec())),
        };
        base.residuals.clear();
        let (mut beams, mut grazing, mut silhouette) = (Vec::new(), 0, 0);
        // the ball finder's footprint (its sphere fits leave out the same beams)
        let fit = FitOptions::default();
        for (s, p, _, check) in joint_balls(ext, scene) {
            let Some(k) = adj.solved.map.point(p) else {
                continue;
            };
            if check || base.points[k].fixed {
                continue;
            }
            let centre = base.points[k].position;
            for &i in &lrf.found.balls[s.0].inliers {
                let beam = BeamOnBall {
                    reading: readings[i],
                    radius,
                    sigma: input.noise.sigma(readings[i].range_mm).max(1e-3),
                    servo_zero_deg: input.mount0.servo_zero_deg,
                    ball: k,
                    extrinsic: keys.extrinsic,
                    mount: keys.mount,
                    time_offset: None,
                    half_width_mm: fit.beam_half_width(readings[i].range_mm),
                };
                if beam.grazing(&centre, &input.start, &theta0, tau0) {
                    grazing += 1;
                } else if beam.at_silhouette(&centre, &input.start, &theta0, tau0) {
                    silhouette += 1;
                } else {
                    beams.push(beam);
                }
            }
        }
        if beams.is_empty() {
            return Err(PipelineError::Data(format!(
                "{}: the joint adjustment has no LRF beam on a control ball",
                project.path.display()
            )));
        }
        let mut planes = plane_beams(input, readings, keys.mount, &mut base);
        let time_offset = time_offset_block(input, readings, &mut base);
        if let Some(t) = &time_offset {
            beams.iter_mut().for_each(|b| b.time_offset = Some(t.block));
            planes
                .iter_mut()
                .for_each(|b| b.time_offset = Some(t.block));
        }
        let group_of = (adj.solved.map.observations.iter())
            .map(|&(j, _)| usize::from(scene.points[j].kind == PointKind::Ball))
            .collect();
        let options = solver::Options {
            max_iterations: 100,
            ..solver::Options::default()
        };
        let servo = readings.iter().map(|r| r.servo_deg);
        let sweep_deg =
            servo.clone().fold(f64::NEG_INFINITY, f64::max) - servo.fold(f64::INFINITY, f64::min);
        let joint = Self {
            base,
            beams,
            planes,
            last: None,
            group_of,
            prior_theta: input.prior.to_params(),
            sweep_deg,
            time_offset,
            keys,
            options,
        };
        Ok((
            joint,
            LeftOut {
                grazing,
                silhouette,
            },
        ))
    }

    /// The problem with the mount's components `free` estimated (the others held at their
    /// values in `start`), every beam, and a prior of σ `prior[k]` on each free component k
    /// (at the project's value), its unknowns starting at those of `start` (the bundle's
    /// solution and the pass's start, or an earlier solution).
    fn problem_from(&self, start: &Problem, free: &[bool; 8], prior: &[f64; 8]) -> Problem {
        let mut p = start.clone();
        p[self.keys.mount].fixed = free.iter().map(|f| !f).collect();
        // the servo time offset under the weak prior while the mount's is weak
        let weak = prior == &PRIOR_SIGMA;
        if let Some(t) = &self.time_offset {
            p[t.block].fixed = vec![!t.free()];
        }
        p.residuals = (self.beams.iter().cloned())
            .map(ResidualBlock::new)
            .chain(self.planes.iter().cloned().map(ResidualBlock::new))
            .chain(
                self.plane_blocks()
                    .map(|k| ResidualBlock::new(room::flatness_prior(k))),
            )
            .collect();
        let components: Vec<usize> = (0..8).filter(|&k| free[k]).collect();
        if !components.is_empty() {
            p.residuals.push(ResidualBlock::new(ParameterPrior {
                parameter: self.keys.mount,
                value: components.iter().map(|&k| self.prior_theta[k]).collect(),
                sigma: components.iter().map(|&k| prior[k]).collect(),
                components,
            }));
        }
        if let Some(t) = self.time_offset.as_ref().filter(|t| t.free()) {
            p.residuals.push(ResidualBlock::new(ParameterPrior {
                parameter: t.block,
                components: vec![0],
                value: vec![t.prior],
                sigma: vec![if weak {
                    TIME_OFFSET_PRIOR_SIGMA_S
                } else {
                    TIME_OFFSET_PLAUSIBLE_S
                }],
            }));
        }
        p
    }

    /// χ² of the final adjustment's plausible-range prior on the free mount components.
    fn prior_chi2(&self, free: &[bool; 8], theta: &[f64; 8], tau: f64) -> f64 {
        let tau_chi2 = (self.time_offset.as_ref().filter(|t| t.free()))
            .map_or(0.0, |t| ((tau - t.prior) / TIME_OFFSET_PLAUSIBLE_S).powi(2));
        (0..8)
            .filter(|&k| free[k])
            .map(|k| ((theta[k] - self.prior_theta[k]) / PLAUSIBLE[k]).powi(2))
            .sum::<f64>()
            + tau_chi2
    }

    /// The servo time offset at the solution of `p` (s; 0 without one).
    fn tau(&self, p: &Problem) -> f64 {
        self.time_offset
            .as_ref()
            .map_or(0.0, |t| match &p[t.block].value {
                ParameterValue::Vector(v) => v[0],
                _ => unreachable!("the time offset is a vector block"),
            })
    }

    /// The parameter blocks of the planes, in order.
    fn plane_blocks(&self) -> impl Iterator<Item = ParameterKey> + '_ {
        let mut seen: Vec<ParameterKey> = self.planes.iter().map(|b| b.plane).collect();
        seen.sort_unstable();
        seen.dedup();
        seen.into_iter()
    }

    /// Adjusts `p` and returns its precision and what the solver did.
    fn solve(&self, p: &mut Problem) -> Result<(Precision, solver::Summary)> {
        let summary = solver::solve(p, &self.options, |_| {})
            .map_err(|e| PipelineError::Adjustment(format!("joint adjustment: {e}")))?;
        let prec = solver::precision(p)
            .map_err(|e| PipelineError::Adjustment(format!("joint adjustment: {e}")))?;
        Ok((prec, summary))
    }
}

/// The beams on the room's planes of `input` (see [`JointInput::planes`]), each plane a
/// parameter block `(a, b, d)` appended to `base`; none when no mount parameter is asked for
/// (the planes then fix nothing).
fn plane_beams(
    input: &JointInput,
    readings: &[BeamReading],
    mount: ParameterKey,
    base: &mut Problem,
) -> Vec<BeamOnPlane> {
    if input.planes.is_empty()
        || input.hold_mount.is_some()
        || !asked(input.project).iter().any(|&a| a)
    {
        return Vec::new();
    }
    let opts = RoomOptions {
        noise: input.noise,
        max_beams_per_plane: PLANE_BEAMS,
        ..RoomOptions::default()
    };
    let mut obs = room::associate(
        readings,
        &input.mount0,
        input.planes,
        input.plane_gate,
        &opts,
    );
    let planes = room::drop_thin_planes(&mut obs, input.planes);
    let frames = PlaneFrame::of_beams(readings, &obs, &input.mount0, &planes);
    let keys: Vec<ParameterKey> = (planes.iter().enumerate())
        .map(|(k, (_, d))| {
            let mut v = vec![0.0; room::PLANE_UNKNOWNS];
            v[2] = *d;
            base.add_parameter(ParameterBlock::vector(format!("plane {}", k + 1), v))
        })
        .collect();
    obs.iter()
        .map(|o| BeamOnPlane {
            reading: readings[o.reading],
            sigma: o.sigma,
            servo_zero_deg: input.mount0.servo_zero_deg,
            frame: frames[o.plane],
            plane: keys[o.plane],
            mount,
            time_offset: None,
        })
        .collect()
}

/// The servo time offset's block of `input`'s joint problem, appended to `base`, where the
/// servo turned during the scans (a beam with a servo rate: a continuous sweep whose scan
/// file gives the time between beams); None for a stop-and-go sweep. It starts at the start
/// mount's value, is estimated while the data determine it ([`estimability`]) under a prior
/// of [`TIME_OFFSET_PLAUSIBLE_S`] at the project's value, and is held otherwise.
fn time_offset_block(
    input: &JointInput,
    readings: &[BeamReading],
    base: &mut Problem,
) -> Option<TimeOffset> {
    if !readings.iter().any(|r| r.servo_rate_deg_s != 0.0) {
        return None;
    }
    let block = base.add_parameter(ParameterBlock::vector(
        "servo time offset",
        vec![input.mount0.servo_time_offset_s],
    ));
    Some(TimeOffset {
        block,
        prior: input.prior.servo_time_offset_s,
        held: None,
    })
}

/// Each plane beam's `n·p − d` (mm) at the solution of `p` (NaN where undefined).
fn plane_errors(joint: &Joint, p: &Problem) -> Vec<f64> {
    let (_, theta) = joint.solution(p);
    let tau = joint.tau(p);
    (joint.planes.iter())
        .map(|b| {
            let ParameterValue::Vector(v) = &p[b.plane].value else {
                return f64::NAN;
            };
            b.error(v, &theta, tau).unwrap_or(f64::NAN)
        })
        .collect()
}

/// The planes of a solved joint problem (unit normal, offset), in block order.
fn solved_planes(joint: &Joint, p: &Problem) -> Vec<(Vector3<f64>, f64)> {
    let mut out: Vec<(ParameterKey, (Vector3<f64>, f64))> = Vec::new();
    for b in &joint.planes {
        if out.iter().any(|(k, _)| *k == b.plane) {
            continue;
        }
        if let ParameterValue::Vector(v) = &p[b.plane].value {
            out.push((b.plane, (b.frame.normal_at(v[0], v[1]).0, v[2])));
        }
    }
    out.sort_by_key(|(k, _)| *k);
    out.into_iter().map(|(_, p)| p).collect()
}

impl Joint {
    /// The extrinsic and the mount of a solved joint problem.
    fn solution(&self, p: &Problem) -> (Rigid3, [f64; 8]) {
        let ParameterValue::Pose(ext) = p[self.keys.extrinsic].value else {
            unreachable!("the extrinsic is a pose block")
        };
        let ParameterValue::Vector(theta) = &p[self.keys.mount].value else {
            unreachable!("the mount is a vector block")
        };
        (ext, std::array::from_fn(|k| theta[k]))
    }
}

/// Each beam's `e` (mm) at the solution of `p` (NaN where undefined).
fn beam_errors(joint: &Joint, p: &Problem) -> Vec<f64> {
    let (ext, theta) = joint.solution(p);
    let tau = joint.tau(p);
    (joint.beams.iter())
        .map(|b| {
            b.range_error(&p[b.ball].position, &ext, &theta, tau)
                .unwrap_or(f64::NAN)
        })
        .collect()
}

/// Holds, one at a time, the asked-for mount parameters that the data cannot determine
/// (see the module doc), naming each with its reason; judged on the cofactors at the
/// solution `at` (no new adjustment: the precision with the weak priors in place of the
/// plausible ones). Returns whether it held any.
fn estimability(
    joint: &mut Joint,
    at: &Problem,
    free: &mut [bool; 8],
    held: &mut [Option<String>; 8],
) -> Result<bool> {
    let mut any = false;
    let tau_free = |j: &Joint| j.time_offset.as_ref().is_some_and(|t| t.free());
    while free.iter().any(|&f| f) || tau_free(joint) {
        let p = joint.problem_from(at, free, &PRIOR_SIGMA);
        let prec = solver::precision(&p)
            .map_err(|e| PipelineError::Adjustment(format!("joint adjustment: {e}")))?;
        // the cofactors of (extrinsic, mount): the covariance with σ0 = 1
        let cov = &prec.parameters_covariance / prec.sigma0.powi(2).max(f64::MIN_POSITIVE);
        let rows = Rows::of(&joint.keys, &prec);
        // the servo time offset: the same two tests, on its own row (k = 8)
        let tau = (joint.time_offset.as_ref().filter(|t| t.free())).and_then(|t| {
            let i = prec.parameter_offsets[t.block.0];
            time_offset_not_estimable(i, &cov, rows, free).map(|(rank, why)| (rank, 8, why))
        });
        let worst = (0..8)
            .filter(|&k| free[k])
            .filter_map(|k| not_estimable(k, &cov, rows, free).map(|(rank, why)| (rank, k, why)))
            .chain(tau)
            .max_by(|a, b| a.0.total_cmp(&b.0));
        let Some((_, k, why)) = worst else { break };
        any = true;
        if k == 8 {
            let t = joint.time_offset.as_mut().expect("tested above");
            t.held = Some(why);
            continue;
        }
        free[k] = false;
        held[k] = Some(if joint.sweep_deg < FULL_TURN_DEG {
            format!(
                "{why}; the servo turned through {:.0}° only: a full turn sees every ball twice, from both sides, which is what tells the scanner's offsets and its range offset from the extrinsic",
                joint.sweep_deg
            )
        } else {
            why
        });
    }
    Ok(any)
}

/// Which observations of one group are kept after an adjustment: those whose
/// standardised residual `w` over the group's σ0 (from its own redundancy, at least 1) is at
/// most [`BEAM_REJECT`]. `e` and `sigma` are the residuals (mm) and their σ's, `w` and `q`
/// the group's standardised residuals and redundancy numbers.
fn keep_flags(e: &[f64], sigma: &[f64], w: &[Vec<f64>], q: &[Vec<f64>]) -> Vec<bool> {
    let vv: f64 = e.iter().zip(sigma).map(|(e, s)| (e / s).powi(2)).sum();
    let r: f64 = q.iter().map(|q| q[0]).sum();
    let s0 = (vv / r.max(1.0)).sqrt().max(1.0);
    w.iter().map(|w| !(w[0].abs() / s0 > BEAM_REJECT)).collect()
}

/// Beams removed as gross errors: on balls, on planes.
#[derive(Clone, Copy, Debug, Default)]
struct Rejected {
    balls: usize,
    planes: usize,
}

/// The adjustment with the plausible-range prior, removing gross beam errors (see the
/// module doc) of the balls' and the planes' beams, each group judged by its own σ0.
/// Returns the solved problem, its precision and the beams removed.
fn final_rounds(joint: &mut Joint, free: &[bool; 8]) -> Result<(Problem, Precision, Rejected)> {
    let mut rejected = Rejected::default();
    for round in 0..=REJECT_ROUNDS {
        let mut p = joint.problem_from(&joint.base, free, &PLAUSIBLE);
        let (prec, summary) = joint.solve(&mut p)?;
        joint.last = Some(summary);
        let (nb, np) = (joint.beams.len(), joint.planes.len());
        let (w, q) = (
            &prec.residual_standardized,
            &prec.residual_redundancy_numbers,
        );
        let sb: Vec<f64> = joint.beams.iter().map(|b| b.sigma).collect();
        let sp: Vec<f64> = joint.planes.iter().map(|b| b.sigma).collect();
        let keep_b = keep_flags(&beam_errors(joint, &p), &sb, &w[..nb], &q[..nb]);
        let keep_p = keep_flags(
            &plane_errors(joint, &p),
            &sp,
            &w[nb..nb + np],
            &q[nb..nb + np],
        );
        let bad_b = keep_b.iter().filter(|k| !**k).count();
        let bad_p = keep_p.iter().filter(|k| !**k).count();
        if round == REJECT_ROUNDS || bad_b + bad_p == 0 {
            return Ok((p, prec, rejected));
        }
        let mut it = keep_b.iter();
        joint
            .beams
            .retain(|_| *it.next().expect("one flag per beam"));
        let mut it = keep_p.iter();
        joint
            .planes
            .retain(|_| *it.next().expect("one flag per plane beam"));
        rejected.balls += bad_b;
        rejected.planes += bad_p;
    }
    unreachable!("the last round returns")
}

/// The LRF side of every matched ball (its sphere fitted again with `mount`) and the camera
/// side: the joint adjustment's centre and covariance.
fn ball_points(
    input: &JointInput,
    p: &Problem,
    prec: &Precision,
    mount: &MountModel,
) -> (Vec<PointObs>, Vec<PointObs>) {
    let (mut lrf_points, mut cam_points) = (Vec::new(), Vec::new());
    let Some(readings) = input.lrf.cloud.readings.as_ref() else {
        return (lrf_points, cam_points);
    };
    let radius = 0.5 * input.project.file.balls.diameter_mm;
    for (s, point, name, _) in joint_balls(input.ext, input.scene) {
        let Some(k) = input.adj.solved.map.point(point) else {
            continue;
        };
        let Some(cov) = prec.point_covariances[k.0] else {
            continue;
        };
        let ball = &input.lrf.found.balls[s.0];
        let rs: Vec<BeamReading> = ball.inliers.iter().map(|&i| readings[i]).collect();
        let Some((c, lrf_cov)) =
            fit_sphere_to_beams(&rs, mount, radius, &ball.centre, &input.noise)
        else {
            continue;
        };
        lrf_points.push(PointObs {
            id: name.to_string(),
            xyz: c,
            cov: lrf_cov,
        });
        cam_points.push(PointObs {
            id: name.to_string(),
            xyz: p.points[k].position,
            cov,
        });
    }
    (lrf_points, cam_points)
}

/// Every ball of the scene with its centre and covariance at the solution `p`.
fn ball_centres(input: &JointInput, p: &Problem, prec: &Precision) -> Vec<(PointId, PointObs)> {
    (input.scene.points.iter_enumerated())
        .filter(|(_, q)| q.kind == PointKind::Ball)
        .filter_map(|(j, q)| {
            let k = input.adj.solved.map.point(j)?;
            let cov = prec.point_covariances[k.0]?;
            let obs = PointObs {
                id: q.name.clone(),
                xyz: p.points[k].position,
                cov,
            };
            Some((j, obs))
        })
        .collect()
}

/// How far the second start moves the solution: every extrinsic and free mount unknown by
/// this many of its σ's (random signs). Far enough that a solver that stopped short would
/// stop elsewhere; near enough that the beams on the balls stay those of the solution (a
/// start a ball's radius off leaves beams beside the ball, clamped, and their own small
/// minimum: [`pingcal_lrf::beam::GRAZING_KAPPA`]). A start far off is what the starts of
/// the pipeline try (the room's mount, the project's) and the absurdity test judges.
pub const SECOND_START_Z: f64 = 3.0;

/// Two solutions are the same minimum when no extrinsic or mount unknown differs by more
/// than this many of its σ's: within the result's own uncertainty, judged on the largest of
/// up to 14 unknowns. (The solver's tolerances leave far less; a beam that grazes its ball
/// at one solution and not at the other makes a kink in the cost, and nearby minima a few
/// tenths of a σ apart — 1.0 σ in the half-sweep test project and the stress study's one
/// doubtful run, with χ²/2 1.6 apart of 3,800 — which that σ covers. Distinct minima of a
/// wrong start lie many σ apart.)
pub const SAME_MINIMUM_Z: f64 = 2.0;

/// How the final adjustment converged, and whether a second start reached its minimum.
#[derive(Clone, Debug, Default)]
pub struct Convergence {
    /// Why the solver stopped (its gradient, step or cost-change test), in words.
    pub termination: String,
    /// Whether that is convergence (not the iteration limit or a trust region that shrank).
    pub converged: bool,
    /// Iterations of that adjustment.
    pub iterations: usize,
    /// The gradient's largest component at the solution (whitened units).
    pub gradient_max_norm: f64,
    /// ½χ² of the solution and of the second start's (whitened units).
    pub cost: (f64, f64),
    /// The largest difference between the two solutions' extrinsic and mount unknowns, in
    /// σ's of the first.
    pub max_difference_z: f64,
    /// Whether the second start reached the same minimum ([`SAME_MINIMUM_Z`]).
    pub same_minimum: bool,
    /// The second start found a lower minimum, which is the one given.
    pub second_lower: bool,
}

impl Convergence {
    /// One line for logs and notes.
    pub fn describe(&self) -> String {
        format!(
            "{} after {} iterations (largest gradient component {:.2e}); a second start from the solution moved by {} σ in every extrinsic and mount unknown reached {} (χ²/2 {:.3} against {:.3}, largest difference {:.3} σ)",
            self.termination,
            self.iterations,
            self.gradient_max_norm,
            SECOND_START_Z,
            if self.same_minimum {
                "the same minimum"
            } else if self.second_lower {
                "a lower minimum, which is given"
            } else {
                "another, higher minimum"
            },
            self.cost.0,
            self.cost.1,
            self.max_difference_z
        )
    }

    /// Why the result is doubtful, if it is: no convergence, or another minimum.
    pub fn doubt(&self) -> Option<String> {
        if !self.converged {
            Some(format!(
                "the joint adjustment did not converge ({})",
                self.termination
            ))
        } else if !self.same_minimum {
            Some(format!(
                "a second start of the joint adjustment from a perturbed solution reached {} (χ²/2 {:.3} against {:.3}, unknowns {:.1} σ apart): the minimum is not unique within the start's error",
                if self.second_lower { "a lower minimum, which is given" } else { "another minimum" },
                self.cost.0,
                self.cost.1,
                self.max_difference_z
            ))
        } else {
            None
        }
    }
}

/// The second start (see [`SECOND_START_Z`]) and what it found; `better` is the solution to
/// give: the first one polished, or the second's when it found a lower minimum.
struct SecondStart {
    summary: Convergence,
    better: Option<Problem>,
}

/// Starts the solved joint problem `p` (precision `prec`, free mount components `free`)
/// again from a perturbed solution and compares the minimum it reaches.
fn second_start(
    joint: &Joint,
    p: &Problem,
    prec: &Precision,
    free: &[bool; 8],
    seed: u64,
) -> Result<SecondStart> {
    use rand::Rng;
    let mut g = pingcal_geometry::consensus::rng(seed ^ 0x5ec0_57a7);
    let cov = &prec.parameters_covariance;
    let rows = Rows::of(&joint.keys, prec);
    let mut step = |k: usize| {
        let sign = if g.random_bool(0.5) { 1.0 } else { -1.0 };
        sign * SECOND_START_Z * cov[(k, k)].max(0.0).sqrt()
    };
    let ext_delta: Vec<f64> = (0..6).map(|k| step(rows.ext(k))).collect();
    let delta: Vec<f64> = (0..8)
        .map(|k| if free[k] { step(rows.mount(k)) } else { 0.0 })
        .collect();
    let tau = joint.time_offset.as_ref().filter(|t| t.free());
    let tau_delta = tau.map(|t| step(prec.parameter_offsets[t.block.0]));
    let mut q = p.clone();
    q[joint.keys.extrinsic].plus(&ext_delta);
    q[joint.keys.mount].plus(&delta);
    if let (Some(t), Some(d)) = (tau, tau_delta) {
        q[t.block].plus(&[d]);
    }
    // both solved to the solver's tightest tolerances: the first solution is polished (it
    // was near), the second started afresh
    let tight = solver::Options {
        function_tolerance: 1e-12,
        parameter_tolerance: 1e-12,
        max_iterations: 200,
        ..joint.options.clone()
    };
    let solve = |p: &mut Problem| {
        solver::solve(p, &tight, |_| {})
            .map_err(|e| PipelineError::Adjustment(format!("joint adjustment: {e}")))
    };
    let summary2 = solve(&mut q)?;
    let mut p1 = p.clone();
    let summary1 = solve(&mut p1)?;
    let p = &p1;
    let last = joint.last.as_ref();
    let (cost1, cost2) = (summary1.final_cost, summary2.final_cost);
    // the unknowns' differences in σ's of the first solution
    let (e1, t1) = joint.solution(p);
    let (e2, t2) = joint.solution(&q);
    let dr = pingcal_geometry::log_so3(&(e2.rotation * e1.rotation.transpose()));
    let dt = e2.translation - e1.translation;
    let mut z: f64 = 0.0;
    for k in 0..6 {
        let d = if k < 3 { dr[k] } else { dt[k - 3] };
        let i = rows.ext(k);
        z = z.max(d.abs() / cov[(i, i)].max(1e-30).sqrt());
    }
    for k in (0..8).filter(|&k| free[k]) {
        let i = rows.mount(k);
        z = z.max((t2[k] - t1[k]).abs() / cov[(i, i)].max(1e-30).sqrt());
    }
    if let Some(t) = tau {
        let i = prec.parameter_offsets[t.block.0];
        z = z.max((joint.tau(&q) - joint.tau(p)).abs() / cov[(i, i)].max(1e-30).sqrt());
    }
    let same = z <= SAME_MINIMUM_Z;
    let lower = !same && cost2 < cost1;
    let summary = Convergence {
        termination: summary1.termination.to_string(),
        converged: !matches!(
            summary1.termination,
            solver::Termination::MaxIterations | solver::Termination::TrustRegionTooSmall
        ),
        iterations: last.map_or(0, |s| s.iterations) + summary1.iterations,
        gradient_max_norm: (summary1.log.last()).map_or(f64::NAN, |i| i.gradient_max_norm),
        cost: (cost1, cost2),
        max_difference_z: z,
        same_minimum: same,
        second_lower: lower,
    };
    Ok(SecondStart {
        summary,
        better: Some(if lower { q } else { p1 }),
    })
}

/// The free mount parameters of `input` and why each other one is held.
fn free_set(input: &JointInput) -> ([bool; 8], [Option<String>; 8]) {
    let asked = asked(input.project);
    let mut held: [Option<String>; 8] = Default::default();
    let mut free = asked;
    let origin = MountParam::OffsetY.index();
    free[origin] = false;
    held[origin] = Some("it is the LRF frame's origin along the servo axis (the extrinsic's ty absorbs it): defined, not estimated".into());
    for k in 0..8 {
        if held[k].is_some() {
            continue;
        }
        if !free[k] {
            held[k] =
                Some("not asked for in [lrf] self_calibrate: held at the project's value".into());
        } else if let Some(why) = input.hold_mount {
            free[k] = false;
            held[k] = Some(why.to_string());
        }
    }
    (free, held)
}

/// The joint adjustment (see the module doc).
pub fn joint_adjustment(input: &JointInput, rep: &Reporter) -> Result<JointOutcome> {
    let pb = rep.task("joint adjustment", 3);
    let asked = asked(input.project);
    let (mut free, mut held) = free_set(input);
    let (mut joint, left_out) = Joint::build(input)?;
    // every asked-for parameter under its plausible prior, then held where the data do
    // not determine it, and adjusted again without it
    let (p, prec, mut rejected) = final_rounds(&mut joint, &free)?;
    pb.advance(1);
    let any_held = estimability(&mut joint, &p, &mut free, &mut held)?;
    for (k, why) in held.iter().enumerate() {
        if let (Some(why), true) = (why, asked[k]) {
            rep.log(format!("  joint: {} held: {why}", MOUNT_PARAM_NAMES[k]));
        }
    }
    if let Some(why) = joint.time_offset.as_ref().and_then(|t| t.held.as_ref()) {
        rep.log(format!("  joint: the servo time offset held: {why}"));
    }
    let (p, prec) = if any_held {
        let (p, prec, more) = final_rounds(&mut joint, &free)?;
        rejected.balls += more.balls;
        rejected.planes += more.planes;
        (p, prec)
    } else {
        (p, prec)
    };
    let second = second_start(&joint, &p, &prec, &free, input.seed)?;
    let p = match &second.better {
        Some(q) => q.clone(),
        None => p,
    };
    pb.advance(1);
    let out = finish(
        input,
        &joint,
        p,
        (&free, &held),
        (left_out, rejected),
        second,
        rep,
    )?;
    pb.finish();
    Ok(out)
}

/// The outcome of the solved joint problem `p` (see the module doc): σ0 with the a-priori
/// σ's, the covariances with every group weighted by its own variance component, the
/// check and control tables.
fn finish(
    input: &JointInput,
    joint: &Joint,
    p: Problem,
    (free, held): (&[bool; 8], &[Option<String>; 8]),
    (left_out, rejected): (LeftOut, Rejected),
    second: SecondStart,
    rep: &Reporter,
) -> Result<JointOutcome> {
    // σ0 with the a-priori σ's of the image points, distances and beams (what the verdict
    // tests): the bundle's χ² and the beams' at the joint solution
    let chi2_lrf = joint_chi2_lrf(joint, &p);
    let bundle = &input.adj.precision;
    let chi2 = input.adj.sigma0_a_priori.powi(2) * bundle.redundancy as f64
        + chi2_lrf
        + joint.prior_chi2(free, &joint.solution(&p).1, joint.tau(&p));
    // the covariances with every group weighted by its own variance component
    let mut p = p;
    let estimate = solver::estimate_variance_components(
        &mut p,
        &joint.options,
        &joint.group_of,
        &OBSERVATION_GROUPS,
    )
    .map_err(|e| PipelineError::Adjustment(format!("joint adjustment: {e}")))?;
    let prec = estimate.precision;
    let redundancy = prec.redundancy;
    let sigma0 = (chi2 / redundancy.max(1) as f64).sqrt();
    let (ext, theta) = joint.solution(&p);
    let cov = prec.parameters_covariance.clone();
    let rows = Rows::of(&joint.keys, &prec);
    let mount_model = MountModel {
        servo_time_offset_s: joint.tau(&p),
        ..MountModel::from_params(&theta, input.mount0.servo_zero_deg)
    };
    let (lrf_points, cam_points) = ball_points(input, &p, &prec, &mount_model);
    let ball_centres = ball_centres(input, &p, &prec);
    let sim = Sim3::new(1.0, ext.rotation, ext.translation);
    let pick = |set: &[PointObs], check: bool| -> Vec<PointObs> {
        set.iter()
            .filter(|p| input.ext.check_ids.contains(&p.id) == check)
            .cloned()
            .collect()
    };
    let check = check_table(&sim, &pick(&lrf_points, true), &pick(&cam_points, true));
    let control = check_table(&sim, &pick(&lrf_points, false), &pick(&cam_points, false));
    let ecov = DMatrix::from_fn(6, 6, |a, b| cov[(rows.ext(a), rows.ext(b))]);
    let rot_cov = Matrix3::from_fn(|a, b| ecov[(a, b)]);
    let rms = |e: Vec<f64>| (e.iter().map(|e| e * e).sum::<f64>() / e.len().max(1) as f64).sqrt();
    let planes = solved_planes(joint, &p);
    let out = JointOutcome {
        camera_from_lrf: ext,
        sigma_translation_mm: [3, 4, 5].map(|k| ecov[(k, k)].max(0.0).sqrt()),
        sigma_opk_deg: opk_sigma_deg(&ext.rotation, &rot_cov),
        extrinsic_cov: ecov,
        mount: (0..8)
            .map(|k| mount_estimate(k, &theta, &cov, rows, held))
            .collect(),
        time_offset: (joint.time_offset.as_ref()).map(|t| {
            time_offset_estimate(
                t,
                joint.tau(&p),
                (&cov, rows),
                prec.parameter_offsets[t.block.0],
            )
        }),
        mount_model,
        mount_cov: DMatrix::from_fn(8, 8, |a, b| {
            if free[a] && free[b] {
                cov[(rows.mount(a), rows.mount(b))]
            } else {
                0.0
            }
        }),
        beams: joint.beams.len(),
        beams_rejected: rejected.balls,
        beams_grazing: left_out.grazing,
        beams_silhouette: left_out.silhouette,
        plane_beams: joint.planes.len(),
        plane_beams_rejected: rejected.planes,
        rms_plane_mm: rms(plane_errors(joint, &p)),
        sigma0,
        variance_components: estimate.components,
        redundancy,
        rms_beam_mm: rms(beam_errors(joint, &p)),
        check,
        control,
        lrf_points,
        cam_points,
        ball_centres,
        notes: outcome_notes(input, held, planes.len(), joint.planes.len()),
        lrf_view: LrfView {
            pass: input.pass,
            spheres: input.lrf.found.balls.len(),
            matched: input.ext.pairs.len(),
            seen_twice_rejected: input.lrf.found.seen_twice_rejected(),
            seen_twice_kept: input.lrf.found.seen_twice_kept(),
            rejected_at_unmatched: rejected_at_unmatched(input, &ext),
            unmeasured_labels: super::extrinsic::unmeasured_labels(
                input.project,
                input.scene,
                input.lrf,
                &input.ext.pairs,
                &ext,
            ),
        },
        planes,
        convergence: second.summary,
        hold_mount: input.hold_mount.map(String::from),
    };
    log_outcome(&out, rep);
    Ok(out)
}

/// χ² of the LRF's beams (on the balls and on the planes) with the sensor's σ's at the
/// solution of `p`.
fn joint_chi2_lrf(joint: &Joint, p: &Problem) -> f64 {
    let balls: f64 = (beam_errors(joint, p).iter().zip(&joint.beams))
        .map(|(e, b)| (e / b.sigma).powi(2))
        .sum();
    let planes: f64 = (plane_errors(joint, p).iter().zip(&joint.planes))
        .map(|(e, b)| (e / b.sigma).powi(2))
        .sum();
    balls + planes
}

/// The notes of an outcome: the pass, the planes, the parameters held.
fn outcome_notes(
    input: &JointInput,
    held: &[Option<String>; 8],
    planes: usize,
    plane_beams: usize,
) -> Vec<String> {
    let pass = (input.pass > 1).then(|| format!(
        "pass {}: the LRF cloud made again from its readings through the mount the pass before estimated, its spheres found and matched again ({} of {} spheres matched)",
        input.pass,
        input.ext.pairs.len(),
        input.lrf.found.balls.len()
    ));
    let room = (planes > 0).then(|| format!(
        "the room's planes constrain the mount: {plane_beams} beams on {planes} planes (walls, floor, ceiling seen from both half-sweeps), each plane an unknown"
    ));
    pass.into_iter()
        .chain(room)
        .chain(held.iter().enumerate().filter_map(|(k, h)| {
            h.as_ref()
                .map(|h| format!("{} held: {h}", MOUNT_PARAM_NAMES[k]))
        }))
        .collect()
}

fn log_outcome(out: &JointOutcome, rep: &Reporter) {
    rep.log(format!(
        "joint: {} beams ({} rejected, {} grazing, {} at a silhouette), {} beams on {} planes ({} rejected, RMS {:.2} mm), sigma0 {:.3}, RMS beam {:.2} mm; mean check error {:.2} mm (sd {:.2}) on {} balls",
        out.beams, out.beams_rejected, out.beams_grazing, out.beams_silhouette, out.plane_beams, out.planes.len(),
        out.plane_beams_rejected, out.rms_plane_mm, out.sigma0, out.rms_beam_mm,
        out.check.mean_mm, out.check.sd_mm, out.check.rows.len()
    ));
    rep.log(format!(
        "joint: variance components {}",
        out.variance_components
            .iter()
            .map(|c| format!(
                "{} {:.3} (redundancy {:.1})",
                c.group, c.sigma0, c.redundancy
            ))
            .collect::<Vec<_>>()
            .join(", ")
    ));
    rep.log(format!(
        "joint: convergence: {}",
        out.convergence.describe()
    ));
}

/// How many balls of the model have no sphere but a rejected candidate near where
/// `camera_from_lrf` puts them (see [`LrfView::rejected_at_unmatched`]).
fn rejected_at_unmatched(input: &JointInput, camera_from_lrf: &Rigid3) -> usize {
    let lrf_from_camera = camera_from_lrf.inverse();
    let near = input.project.file.balls.diameter_mm;
    (input.scene.points.iter_enumerated())
        .filter(|&(k, p)| {
            p.kind == PointKind::Ball && !input.ext.pairs.iter().any(|&(_, q)| q == k)
        })
        .filter(|(_, p)| {
            let at = lrf_from_camera.transform(&p.position);
            (input.lrf.found.rejected.iter()).any(|r| (r.centre - at).norm() < near)
        })
        .count()
}

impl JointOutcome {
    /// Whether an estimated mount parameter is more than `z` σ from its value in `start`.
    pub fn moved_mount(&self, start: &MountModel, z: f64) -> bool {
        let start = start.to_params();
        self.mount.iter().enumerate().any(|(k, m)| {
            let d = (m.value - to_unit(k, start[k])).abs();
            m.sigma.is_some_and(|s| s > 0.0 && d > z * s)
        })
    }

    /// Why the cloud this pass saw looks distorted by a mount error, if it does: many beams
    /// judged grazing, balls seen twice, spheres that match no ball.
    pub fn distorted_cloud(&self) -> Option<String> {
        let used = self.beams + self.beams_grazing + self.beams_rejected;
        let v = &self.lrf_view;
        let twice = v.seen_twice_rejected + v.seen_twice_kept;
        if self.beams_grazing as f64 > 0.2 * used as f64 {
            Some(format!(
                "{} of {used} beams were grazing",
                self.beams_grazing
            ))
        } else if twice >= 2 {
            Some(format!("{twice} LRF candidates were seen twice"))
        } else if v.rejected_at_unmatched > 0 {
            Some(format!(
                "{} ball(s) of the model were rejected in the cloud where the estimate puts them",
                v.rejected_at_unmatched
            ))
        } else if v.spheres > v.matched {
            Some(format!(
                "{} of {} spheres match no ball",
                v.spheres - v.matched,
                v.spheres
            ))
        } else {
            None
        }
    }
}

/// A mount parameter in its reporting unit (degrees for the tilts).
fn to_unit(k: usize, v: f64) -> f64 {
    MountParam::at(k).in_report_unit(v)
}

fn unit(k: usize) -> &'static str {
    MountParam::at(k).unit()
}

/// Why parameter `k` cannot be estimated, judged on the cofactors `cov` of the extrinsic
/// (6: δω, δt) and the mount (8; with the weak priors on): None when it can. The second value
/// ranks how badly (larger: worse).
fn not_estimable(
    k: usize,
    cov: &DMatrix<f64>,
    rows: Rows,
    free: &[bool; 8],
) -> Option<(f64, String)> {
    let undetermined = |sd: f64| {
        let (sd, prior, u) = (to_unit(k, sd), to_unit(k, PRIOR_SIGMA[k]), unit(k));
        format!("the data do not determine it (σ {sd:.3}{u} against a prior of {prior:.3}{u}: the sweep and the balls leave it free)")
    };
    let row = (rows.mount(k), PRIOR_SIGMA[k]);
    row_not_estimable(
        row,
        (cov, rows, free),
        undetermined,
        "the data cannot tell them apart",
    )
}

/// The two tests of an unknown at row `i` of the cofactors `cov` under a weak prior of
/// `prior_sigma`: its σ beyond [`MAX_PRIOR_SHARE`] of the prior (`undetermined` of its σ
/// says so; ranked above every correlation), or its correlation with the extrinsic or a free
/// mount parameter beyond [`MAX_CORRELATION`] (said with `why_correlated`, ranked by |ρ|).
fn row_not_estimable(
    (i, prior_sigma): (usize, f64),
    (cov, rows, free): (&DMatrix<f64>, Rows, &[bool; 8]),
    undetermined: impl FnOnce(f64) -> String,
    why_correlated: &str,
) -> Option<(f64, String)> {
    let sd = cov[(i, i)].max(0.0).sqrt();
    let share = sd / prior_sigma;
    if !(share <= MAX_PRIOR_SHARE) {
        return Some((1e6 + share, undetermined(sd)));
    }
    correlated(i, cov, rows, free).map(|(other, r)| {
        (
            r.abs(),
            format!("it is correlated with {other} at ρ = {r:.4}: {why_correlated}"),
        )
    })
}

/// The first unknown among the extrinsic's and the free mount parameters (their `rows`)
/// that unknown `i` is correlated with beyond [`MAX_CORRELATION`]: its name and the
/// correlation.
fn correlated(i: usize, cov: &DMatrix<f64>, rows: Rows, free: &[bool; 8]) -> Option<(String, f64)> {
    (rows.named(free).into_iter())
        .filter(|&(j, _)| j != i)
        .find_map(|(j, other)| {
            let r = cov[(i, j)] / (cov[(i, i)] * cov[(j, j)]).sqrt();
            (r.abs() > MAX_CORRELATION).then_some((other, r))
        })
}

/// Why the servo time offset (row `i` of the cofactors `cov`: the extrinsic's 6, the
/// mount's 8, the planes', then its own) cannot be estimated: its σ against the weak prior,
/// or its correlation with the extrinsic or a free mount parameter. A sweep in one direction
/// at one speed moves every beam's servo angle by the same rate × τ: one angle about the
/// servo axis, which the extrinsic's rotation takes; a sweep forward and back (or at
/// several speeds) tells them apart.
fn time_offset_not_estimable(
    i: usize,
    cov: &DMatrix<f64>,
    rows: Rows,
    free: &[bool; 8],
) -> Option<(f64, String)> {
    const WHY: &str = "a sweep in one direction at one speed turns every beam by the same angle, which the extrinsic's rotation about the servo axis takes; sweep forward and back (or at two speeds) to estimate it";
    let undetermined = |sd: f64| {
        format!("the data do not determine it (σ {sd:.3} s against a prior of {TIME_OFFSET_PRIOR_SIGMA_S} s): {WHY}")
    };
    let row = (i, TIME_OFFSET_PRIOR_SIGMA_S);
    row_not_estimable(row, (cov, rows, free), undetermined, WHY)
}

/// What the joint adjustment starts from.
#[derive(Clone, Copy)]
pub struct JointInput<'a> {
    /// The project.
    pub project: &'a Project,
    /// Step 1.
    pub dets: &'a Detections,
    /// The scene after the final bundle adjustment.
    pub scene: &'a Scene,
    /// Step 4.
    pub adj: &'a Adjusted,
    /// Step 5.
    pub lrf: &'a LrfData,
    /// Step 6 (its matching, and the sphere method's extrinsic as the start).
    pub ext: &'a Extrinsics,
    /// The start of the extrinsic.
    pub start: Rigid3,
    /// The start of the mount (the project's values, or an earlier pass's estimate).
    pub mount0: MountModel,
    /// The project's mount, where the priors are centred.
    pub prior: MountModel,
    /// Which pass this is (1: the LRF through the project's mount).
    pub pass: usize,
    /// The range noise profile.
    pub noise: RangeNoise,
    /// The room's planes (unit normal, offset; LRF frame) near where `mount0` puts them:
    /// their beams join the adjustment as observations of the mount, each plane an unknown
    /// (empty: none).
    pub planes: &'a [(Vector3<f64>, f64)],
    /// The gate that finds the planes' beams ([`pingcal_lrf::room::associate`]).
    pub plane_gate: Gate,
    /// Hold every mount parameter at the project's value, for this reason (the simpler
    /// model); None: estimate what the project asks for.
    pub hold_mount: Option<&'a str>,
    /// Seed of the second start's perturbation.
    pub seed: u64,
}

fn mount_estimate(
    k: usize,
    theta: &[f64; 8],
    cov: &DMatrix<f64>,
    rows: Rows,
    held: &[Option<String>; 8],
) -> MountEstimate {
    let unit = |v: f64| to_unit(k, v);
    let name = MOUNT_PARAM_NAMES[k];
    estimate_of_row(
        name,
        unit(theta[k]),
        unit,
        (cov, rows),
        rows.mount(k),
        &held[k],
    )
}

/// The servo time offset's outcome: its value `tau` (s), its σ and its correlations with
/// the extrinsic from `cov` (its row `i`), or why it was held.
fn time_offset_estimate(
    t: &TimeOffset,
    tau: f64,
    (cov, rows): (&DMatrix<f64>, Rows),
    i: usize,
) -> MountEstimate {
    estimate_of_row(TIME_OFFSET_NAME, tau, |v| v, (cov, rows), i, &t.held)
}

/// The outcome of the unknown at row `i` of `cov` (value and σ in the unit `unit` makes of
/// the vector's): its σ and its correlations with the extrinsic (its `rows`) when it was
/// estimated (`held` None), else why it was held.
fn estimate_of_row(
    name: &'static str,
    value: f64,
    unit: impl Fn(f64) -> f64,
    (cov, rows): (&DMatrix<f64>, Rows),
    i: usize,
    held: &Option<String>,
) -> MountEstimate {
    let estimated = held.is_none();
    MountEstimate {
        name,
        value,
        sigma: estimated.then(|| unit(cov[(i, i)].max(0.0).sqrt())),
        held: held.clone(),
        corr_extrinsic: estimated.then(|| {
            std::array::from_fn(|k| {
                let j = rows.ext(k);
                cov[(i, j)] / (cov[(i, i)] * cov[(j, j)]).sqrt()
            })
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The project's spelling of a mount parameter (`[lrf] self_calibrate`) and the LRF's
    /// enum index the same entry of the mount's vector.
    #[test]
    fn the_projects_mount_parameters_are_the_vectors_entries() {
        use pingcal_project::MountParameter;
        assert_eq!(MountParameter::ALL.len(), MountParam::ALL.len());
        for (k, p) in MountParameter::ALL.into_iter().enumerate() {
            assert_eq!(p.index(), k);
            assert_eq!(MountParam::at(k).index(), k);
            assert_eq!(MountParam::at(p.index()).name(), p.as_str());
        }
    }
}
