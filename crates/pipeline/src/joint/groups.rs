//! The joint adjustment's observation groups: one trait, so that a kind of observation joins
//! the adjustment, its outlier rounds, its χ² and its outcome in one file and one line of
//! [`super::BUILT_IN`].
//!
//! **What a group is.** A set of observations of one kind (the beams on the control balls,
//! the beams on the room's planes, …) that become residual blocks of the one joint problem
//! ([`pingcal_ba::Residual`], each whitened by its own σ and naming its variance-component
//! group), plus whatever parameter blocks of its own it needs (a plane each) and the
//! constraints on those (a plane's flatness prior). The joint problem is the bundle's final
//! problem, the sensor's blocks ([`SensorKeys`]), and the residuals of every group in the
//! order of the registry; nothing in the adjustment names a group's type.
//!
//! **What the adjustment asks of a group.**
//! - its residual blocks, one per observation, with the sensor's blocks as the problem has
//!   them ([`ObservationGroup::residuals`]), and the constraints on its own blocks
//!   ([`ObservationGroup::constraints`]);
//! - each observation's error `e` and a-priori σ at a solution ([`ObservationGroup::errors`],
//!   [`ObservationGroup::sigmas`]): its χ² with the a-priori σ's is `Σ (e/σ)²`, its RMS is
//!   `√(Σ e² / n)`, and its blunder test compares each observation's standardised
//!   residual `w` (Baarda's, from the joint redundancy numbers) with the group's own σ0
//!   (`√(Σ (e/σ)² / Σ r)`, at least 1): beyond [`super::BEAM_REJECT`] it is a gross error
//!   (the outlier rounds) and [`ObservationGroup::retain`] removes it;
//! - what it left out before the adjustment and why ([`ObservationGroup::left_out`]), and
//!   its notes.
//!
//! **Where a group is registered.** A [`GroupBuilder`] makes a group from the joint
//! adjustment's input (or none, when the data have no such observations); [`super::BUILT_IN`] lists
//! the built-in ones in the order their residuals and blocks enter the problem; a run uses
//! that list unless its caller gives its own (`pingcal_pipeline::calibrate_with_groups`: a
//! test adds a taped distance between two balls this way).

use super::JointInput;
use crate::context::Result;
use nalgebra::Vector3;
use pingcal_ba::{ParameterKey, Problem, ResidualBlock};
use pingcal_geometry::Rigid3;
use pingcal_lrf::cloud::BeamReading;
use serde::Serialize;
use std::any::Any;

/// The sensor's parameter blocks of the joint problem, which a group's residuals depend on:
/// the extrinsic `camera_from_lrf`, the mount's 8 and the servo time offset (where the
/// servo turned during the scans).
#[derive(Clone, Copy, Debug)]
pub struct SensorKeys {
    /// The extrinsic (a pose block).
    pub extrinsic: ParameterKey,
    /// The mount (a vector block of 8).
    pub mount: ParameterKey,
    /// The servo time offset (a vector block of 1); None: τ = 0, not an unknown.
    pub time_offset: Option<ParameterKey>,
}

/// A solution of the joint problem as the groups read it: the problem (points, planes) and
/// the sensor's values, taken once.
#[derive(Clone, Copy, Debug)]
pub struct At<'a> {
    /// The solved problem.
    pub problem: &'a Problem,
    /// The extrinsic.
    pub camera_from_lrf: Rigid3,
    /// The mount's 8 ([`pingcal_lrf::sensor::MountModel::to_params`]).
    pub mount: [f64; 8],
    /// The servo time offset (s; 0 without one).
    pub time_offset_s: f64,
}

/// What a [`GroupBuilder`] is given: the adjustment's input, the LRF's readings and the
/// sensor's extrinsic and mount blocks (the time offset's block is added after every
/// group's own blocks, and given to [`ObservationGroup::residuals`]).
#[derive(Clone, Copy)]
pub struct GroupContext<'a, 'b> {
    /// The joint adjustment's input.
    pub input: &'a JointInput<'b>,
    /// Every beam of the LRF's scans.
    pub readings: &'a [BeamReading],
    /// The extrinsic's block.
    pub extrinsic: ParameterKey,
    /// The mount's block.
    pub mount: ParameterKey,
}

/// Makes a group from the context, adding its own parameter blocks to the problem; `None`
/// when the data have none of its observations (an error when the adjustment cannot go on
/// without them).
pub type GroupBuilder =
    fn(&GroupContext, &mut Problem) -> Result<Option<Box<dyn ObservationGroup>>>;

/// A group of observations of the joint adjustment: see the module doc.
pub trait ObservationGroup: std::fmt::Debug + Send + Sync {
    /// Its name in the log, results.json and the report: the variance-component group of
    /// its residuals ([`pingcal_ba::Residual::group`]).
    fn name(&self) -> &str;
    /// The unit of its errors (`mm`).
    fn unit(&self) -> &str {
        "mm"
    }
    /// How many observations it has now.
    fn len(&self) -> usize;
    /// Whether it has none.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// One residual block per observation, in order, on the sensor's blocks `keys`.
    fn residuals(&self, keys: &SensorKeys) -> Vec<ResidualBlock>;
    /// Constraints on its own parameter blocks (not observations: no blunder test, no χ²
    /// line); they follow every group's residuals in the problem.
    fn constraints(&self) -> Vec<ResidualBlock> {
        Vec::new()
    }
    /// Each observation's a-priori σ (in [`ObservationGroup::unit`]).
    fn sigmas(&self) -> Vec<f64>;
    /// Each observation's error at the solution `at` (NaN where it is undefined).
    fn errors(&self, at: &At) -> Vec<f64>;
    /// Keeps the observations flagged `true` (one flag per observation, in order).
    fn retain(&mut self, keep: &[bool]);
    /// What it left out before the adjustment: (why, how many).
    fn left_out(&self) -> Vec<(&'static str, usize)> {
        Vec::new()
    }
    /// Lines for the outcome's notes, at the solution `at`.
    fn notes(&self, _at: &At) -> Vec<String> {
        Vec::new()
    }
    /// The group as [`Any`], for the outcome of a kind's own (the planes the next pass
    /// looks for).
    fn as_any(&self) -> &dyn Any;
}

/// One group's line of the joint adjustment's outcome (results.json's
/// `observation_groups`, the report's χ² table).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct GroupOutcome {
    /// The group's name ([`ObservationGroup::name`]).
    pub group: String,
    /// The unit of `rms`.
    pub unit: String,
    /// Observations in the final adjustment.
    pub observations: usize,
    /// Observations removed as gross errors.
    pub rejected: usize,
    /// Observations left out before the adjustment, by reason.
    pub left_out: Vec<LeftOut>,
    /// `Σ (e/σ)²` with the a-priori σ's at the solution (before the re-weighting by the
    /// variance components): its share of the joint χ² that `sigma0` tests.
    pub chi2: f64,
    /// RMS of the errors at the final solution.
    pub rms: f64,
}

/// Observations of a group left out before the adjustment.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LeftOut {
    /// Why.
    pub reason: String,
    /// How many.
    pub count: usize,
}

impl GroupOutcome {
    /// How many were left out for `reason` (0 when none).
    pub fn left_out(&self, reason: &str) -> usize {
        (self.left_out.iter())
            .find(|l| l.reason == reason)
            .map_or(0, |l| l.count)
    }
}

/// `Σ (e/σ)²` of `errors` with the σ's `sigmas`.
pub fn chi2(errors: &[f64], sigmas: &[f64]) -> f64 {
    errors
        .iter()
        .zip(sigmas)
        .map(|(e, s)| (e / s).powi(2))
        .sum()
}

/// RMS of `errors` (0 of none).
pub fn rms(errors: &[f64]) -> f64 {
    (errors.iter().map(|e| e * e).sum::<f64>() / errors.len().max(1) as f64).sqrt()
}

/// A plane of the room as the joint adjustment estimated it (unit normal, offset; LRF frame).
pub type Plane = (Vector3<f64>, f64);
