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
//! **Observation groups.** The range observations come in groups behind one trait
//! ([`groups::ObservationGroup`]: the beams on the control balls, the beams on the room's
//! planes, …); each group gives its residuals and parameter blocks, its χ² line, its gross
//! errors and what it left out, and the adjustment, its outlier rounds and its outcome
//! iterate over them. A new kind is one file and one line of [`BUILT_IN`]. The rooms of this
//! module, one job each: `problem` (the joint problem built from the groups), `rounds` (the
//! outlier rounds), `estimability` (what the data determine), `convergence` (the second
//! start), `outcome` (the outcome, its tables and its log).
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

mod ball_beams;
mod convergence;
mod estimability;
pub use estimability::largest_shift;
pub mod groups;
mod outcome;
mod plane_beams;
mod problem;
mod rounds;

pub use ball_beams::{AT_SILHOUETTE, GRAZING, NAME as BALL_BEAMS};
pub use convergence::{Convergence, SAME_MINIMUM_Z, SECOND_START_Z};
pub use groups::{GroupBuilder, GroupOutcome, ObservationGroup};
pub use outcome::{BallBeamCounts, JointOutcome, LrfView, MountEstimate};
pub(crate) use rounds::keep_flags;

use super::bundle::Adjusted;
use super::extrinsic::Extrinsics;
use super::ids::{PointId, SphereId};
use super::lrf::LrfData;
use super::scene::{Detections, Scene};
use crate::context::Result;
use crate::progress::Reporter;
use nalgebra::Vector3;
use pingcal_geometry::Rigid3;
use pingcal_lrf::room::Gate;
use pingcal_lrf::sensor::{MountModel, MountParam, RangeNoise, MOUNT_PARAM_NAMES};
use pingcal_project::Project;

/// The built-in observation groups, in the order their blocks and residuals enter the joint
/// problem: a new kind of observation is its file and one line here.
pub const BUILT_IN: [GroupBuilder; 2] =
    [ball_beams::BallBeams::build, plane_beams::PlaneBeams::build];

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

/// The joint adjustment (see the module doc) with the observation groups `builders` make
/// ([`BUILT_IN`] unless a caller adds its own).
pub fn joint_adjustment(
    input: &JointInput,
    builders: &[GroupBuilder],
    rep: &Reporter,
) -> Result<JointOutcome> {
    let pb = rep.task("joint adjustment", 3);
    let asked = asked(input.project);
    let (mut free, mut held) = free_set(input);
    let mut joint = problem::Joint::build(input, builders)?;
    // every asked-for parameter under its plausible prior, then held where the data do
    // not determine it, and adjusted again without it
    let (p, prec, mut rejected) = rounds::final_rounds(&mut joint, &free)?;
    pb.advance(1);
    let mut shifts = [None; 8];
    let any_held = estimability::estimability(&mut joint, &p, &mut free, (&mut held, &mut shifts))?;
    for (k, why) in held.iter().enumerate() {
        if let (Some(why), true) = (why, asked[k]) {
            rep.log(format!("  joint: {} held: {why}", MOUNT_PARAM_NAMES[k]));
        }
    }
    if let Some(why) = joint.time_offset.as_ref().and_then(|t| t.held.as_ref()) {
        rep.log(format!("  joint: the servo time offset held: {why}"));
    }
    let (p, prec) = if any_held {
        let (p, prec, more) = rounds::final_rounds(&mut joint, &free)?;
        rejected.iter_mut().zip(more).for_each(|(r, m)| *r += m);
        (p, prec)
    } else {
        (p, prec)
    };
    let second = convergence::second_start(&joint, &p, &prec, &free, input.seed)?;
    pb.advance(1);
    let mut out = outcome::finish(input, &joint, (&free, &held), rejected, second, rep)?;
    out.held_shifts = shifts;
    pb.finish();
    Ok(out)
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

/// A mount parameter in its reporting unit (degrees for the tilts).
fn to_unit(k: usize, v: f64) -> f64 {
    MountParam::at(k).in_report_unit(v)
}

/// The reporting unit of mount parameter `k`.
fn unit(k: usize) -> &'static str {
    MountParam::at(k).unit()
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
