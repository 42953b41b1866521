//! The joint problem: the bundle's final problem with the sensor's parameter blocks and
//! every observation group's residuals, before the mount's free set and its priors are
//! chosen ([`Joint::problem_from`] makes each adjustment's problem from it).

use super::groups::{At, GroupBuilder, GroupContext, ObservationGroup, SensorKeys};
use super::{
    JointInput, PLAUSIBLE, PRIOR_SIGMA, TIME_OFFSET_PLAUSIBLE_S, TIME_OFFSET_PRIOR_SIGMA_S,
};
use crate::context::{PipelineError, Result};
use crate::scene::PointKind;
use pingcal_ba::solver::{self, Precision};
use pingcal_ba::{
    ParameterBlock, ParameterKey, ParameterPrior, ParameterValue, Problem, ResidualBlock,
};
use pingcal_geometry::Rigid3;
use pingcal_lrf::cloud::BeamReading;

/// The joint problem before its mount's free set and its priors are chosen.
pub(super) struct Joint {
    /// The bundle's final problem with the sensor's blocks and the groups' own, and no
    /// residual blocks (each adjustment's problem adds them).
    pub base: Problem,
    /// The observation groups, in the order of the registry.
    pub groups: Vec<Box<dyn ObservationGroup>>,
    /// What the solver did in the last adjustment of [`super::rounds::final_rounds`].
    pub last: Option<solver::Summary>,
    /// Per image observation of `base`, its group ([`crate::bundle::OBSERVATION_GROUPS`]).
    pub group_of: Vec<usize>,
    /// The project's mount: where the priors are centred.
    pub prior_theta: [f64; 8],
    /// The servo angles the beams span (degrees).
    pub sweep_deg: f64,
    /// The servo time offset's parameter block, where the servo turned during the scans
    /// (a continuous sweep); see [`TimeOffset`].
    pub time_offset: Option<TimeOffset>,
    /// The sensor's blocks.
    pub keys: SensorKeys,
    /// The solver's options.
    pub options: solver::Options,
}

/// The servo time offset τ in the joint problem
/// ([`pingcal_lrf::sensor::MountModel::servo_time_offset_s`]).
#[derive(Clone, Debug)]
pub(super) struct TimeOffset {
    /// Its parameter block (after the groups' own).
    pub block: ParameterKey,
    /// Where its prior is centred: the project's value (s).
    pub prior: f64,
    /// Why it is held (None: estimated).
    pub held: Option<String>,
}

impl TimeOffset {
    /// Estimated, not held.
    pub fn free(&self) -> bool {
        self.held.is_none()
    }
}

impl Joint {
    /// The joint problem of `input` with the groups `builders` make.
    pub fn build(input: &JointInput, builders: &[GroupBuilder]) -> Result<Self> {
        let (project, scene, adj) = (input.project, input.scene, input.adj);
        let readings = input.lrf.cloud.readings.as_ref().ok_or_else(|| {
            PipelineError::Input(format!(
                "{}: the joint adjustment needs the LRF's beams (pingcal-scan CSV files), not a point cloud: use method = \"spheres\"",
                project.path.display()
            ))
        })?;
        let theta0 = input.mount0.to_params();
        let mut base = adj.solved.problem.clone();
        base.parameters.clear();
        let extrinsic = base.add_parameter(ParameterBlock::pose("camera_from_lrf", input.start));
        let mount = base.add_parameter(ParameterBlock::vector("lrf mount", theta0.to_vec()));
        base.residuals.clear();
        let cx = GroupContext {
            input,
            readings,
            extrinsic,
            mount,
        };
        let mut groups = Vec::new();
        for build in builders {
            groups.extend(build(&cx, &mut base)?);
        }
        let time_offset = time_offset_block(input, readings, &mut base);
        let keys = SensorKeys {
            extrinsic,
            mount,
            time_offset: time_offset.as_ref().map(|t| t.block),
        };
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
        Ok(Self {
            base,
            groups,
            last: None,
            group_of,
            prior_theta: input.prior.to_params(),
            sweep_deg,
            time_offset,
            keys,
            options,
        })
    }

    /// The problem with the mount's components `free` estimated (the others held at their
    /// values in `start`), every group's observations and constraints, and a prior of σ
    /// `prior[k]` on each free component k (at the project's value), its unknowns starting
    /// at those of `start` (the bundle's solution and the pass's start, or an earlier
    /// solution).
    pub fn problem_from(&self, start: &Problem, free: &[bool; 8], prior: &[f64; 8]) -> Problem {
        let mut p = start.clone();
        p[self.keys.mount].fixed = free.iter().map(|f| !f).collect();
        // the servo time offset under the weak prior while the mount's is weak
        let weak = prior == &PRIOR_SIGMA;
        if let Some(t) = &self.time_offset {
            p[t.block].fixed = vec![!t.free()];
        }
        p.residuals = (self.groups.iter())
            .flat_map(|g| g.residuals(&self.keys))
            .chain(self.groups.iter().flat_map(|g| g.constraints()))
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
    pub fn prior_chi2(&self, free: &[bool; 8], theta: &[f64; 8], tau: f64) -> f64 {
        let tau_chi2 = (self.time_offset.as_ref().filter(|t| t.free()))
            .map_or(0.0, |t| ((tau - t.prior) / TIME_OFFSET_PLAUSIBLE_S).powi(2));
        (0..8)
            .filter(|&k| free[k])
            .map(|k| ((theta[k] - self.prior_theta[k]) / PLAUSIBLE[k]).powi(2))
            .sum::<f64>()
            + tau_chi2
    }

    /// The servo time offset at the solution of `p` (s; 0 without one).
    pub fn tau(&self, p: &Problem) -> f64 {
        self.time_offset
            .as_ref()
            .map_or(0.0, |t| match &p[t.block].value {
                ParameterValue::Vector(v) => v[0],
                _ => unreachable!("the time offset is a vector block"),
            })
    }

    /// The extrinsic and the mount of a solved joint problem.
    pub fn solution(&self, p: &Problem) -> (Rigid3, [f64; 8]) {
        let ParameterValue::Pose(ext) = p[self.keys.extrinsic].value else {
            unreachable!("the extrinsic is a pose block")
        };
        let ParameterValue::Vector(theta) = &p[self.keys.mount].value else {
            unreachable!("the mount is a vector block")
        };
        (ext, std::array::from_fn(|k| theta[k]))
    }

    /// The solution of `p` as the groups read it.
    pub fn at<'a>(&self, p: &'a Problem) -> At<'a> {
        let (camera_from_lrf, mount) = self.solution(p);
        At {
            problem: p,
            camera_from_lrf,
            mount,
            time_offset_s: self.tau(p),
        }
    }

    /// Adjusts `p` and returns its precision and what the solver did.
    pub fn solve(&self, p: &mut Problem) -> Result<(Precision, solver::Summary)> {
        let summary = solver::solve(p, &self.options, |_| {})
            .map_err(|e| PipelineError::Adjustment(format!("joint adjustment: {e}")))?;
        let prec = solver::precision(p)
            .map_err(|e| PipelineError::Adjustment(format!("joint adjustment: {e}")))?;
        Ok((prec, summary))
    }

    /// The group of type `G`, if the problem has one.
    pub fn group<G: 'static>(&self) -> Option<&G> {
        (self.groups.iter()).find_map(|g| g.as_any().downcast_ref::<G>())
    }
}

/// The servo time offset's block of `input`'s joint problem, appended to `base`, where the
/// servo turned during the scans (a beam with a servo rate: a continuous sweep whose scan
/// file gives the time between beams); None for a stop-and-go sweep. It starts at the start
/// mount's value, is estimated while the data determine it
/// ([`super::estimability::estimability`]) under a prior of [`TIME_OFFSET_PLAUSIBLE_S`] at
/// the project's value, and is held otherwise.
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
