//! The joint adjustment's outcome: σ0 with the a-priori σ's, the covariances with every
//! group weighted by its own variance component, every group's line, the mount's and the
//! servo time offset's estimates, the check and control tables, and the log's lines.

use super::ball_beams;
use super::convergence::{Convergence, SecondStart};
use super::estimability::Rows;
use super::groups::{self, GroupOutcome, LeftOut};
use super::plane_beams::PlaneBeams;
use super::problem::{Joint, TimeOffset};
use super::rounds::Rejected;
use super::{joint_balls, to_unit, JointInput, TIME_OFFSET_NAME};
use crate::bundle::OBSERVATION_GROUPS;
use crate::context::{PipelineError, Result};
use crate::head::HeadPoses;
use crate::ids::PointId;
use crate::progress::Reporter;
use crate::scene::PointKind;
use nalgebra::{DMatrix, Matrix3, Vector3};
use pingcal_ba::solver::{self, Precision, VarianceComponent};
use pingcal_ba::Problem;
use pingcal_geometry::{opk_sigma_deg, Rigid3, Sim3};
use pingcal_lrf::beam::fit_sphere_to_beams;
use pingcal_lrf::cloud::BeamReading;
use pingcal_lrf::registration::{check_table, CheckTable, PointObs};
use pingcal_lrf::sensor::{MountModel, MOUNT_PARAM_NAMES};

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
    /// Every observation group's line: its observations, those removed as gross errors and
    /// left out, its χ² and RMS ([`GroupOutcome`]), in the order of the joint problem.
    pub groups: Vec<GroupOutcome>,
    /// σ0 of the whole adjustment with the a-priori σ's, and its redundancy.
    pub sigma0: f64,
    /// The σ0 of every group of the joint adjustment (targets, balls, distances, the beams
    /// against the sensor's σ(r)), by which it was re-weighted.
    pub variance_components: Vec<VarianceComponent>,
    /// Redundancy.
    pub redundancy: i64,
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
    /// The room's planes as estimated (unit normal, offset; LRF frame): where the next pass
    /// looks for their beams.
    pub planes: Vec<(Vector3<f64>, f64)>,
    /// How the adjustment converged and whether a second start agreed.
    pub convergence: Convergence,
    /// Why every mount parameter was held (the simpler model chosen), if it was.
    pub hold_mount: Option<String>,
    /// Per mount parameter held because the data do not determine it: how far the
    /// extrinsic (δω rad, δt mm, as `extrinsic_cov`) would move were its held value off by
    /// its plausible size.
    pub held_shifts: [Option<[f64; 6]>; 8],
    /// The head's cameras and the LRF from this adjustment, with their joint covariance
    /// ([`crate::head`]); `sensors` of results.json.
    pub head: HeadPoses,
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
    /// to no ball lies in the main image ([`crate::matching::unmeasured_labels_at`]): those
    /// spheres are balls the photographs missed, not spurious ones.
    pub unmeasured_labels: Vec<String>,
}

impl JointOutcome {
    /// The line of the group named `name`, if the adjustment had that group.
    pub fn group(&self, name: &str) -> Option<&GroupOutcome> {
        self.groups.iter().find(|g| g.group == name)
    }

    /// The beams on the control balls: used, removed as gross errors, left out as grazing and
    /// at a silhouette, and their RMS (all 0 when the adjustment had no such group).
    pub fn ball_beams(&self) -> BallBeamCounts {
        let g = self.group(ball_beams::NAME);
        BallBeamCounts {
            used: g.map_or(0, |g| g.observations),
            rejected: g.map_or(0, |g| g.rejected),
            grazing: g.map_or(0, |g| g.left_out(ball_beams::GRAZING)),
            silhouette: g.map_or(0, |g| g.left_out(ball_beams::AT_SILHOUETTE)),
            rms_mm: g.map_or(0.0, |g| g.rms),
        }
    }

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
        let b = self.ball_beams();
        let (grazing, used) = (b.grazing, b.used + b.grazing + b.rejected);
        let v = &self.lrf_view;
        let twice = v.seen_twice_rejected + v.seen_twice_kept;
        if grazing as f64 > 0.2 * used as f64 {
            Some(format!("{grazing} of {used} beams were grazing"))
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

/// The beams on the control balls of an outcome ([`JointOutcome::ball_beams`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BallBeamCounts {
    /// Beams in the final adjustment.
    pub used: usize,
    /// Beams removed as gross errors.
    pub rejected: usize,
    /// Beams left out as grazing the ball.
    pub grazing: usize,
    /// Beams left out because their footprint reaches the ball's silhouette.
    pub silhouette: usize,
    /// RMS of their residuals at the final solution (mm).
    pub rms_mm: f64,
}

/// The outcome of the solved joint problem `p` (see the module doc): σ0 with the a-priori
/// σ's, the covariances with every group weighted by its own variance component, the
/// check and control tables.
pub(super) fn finish(
    input: &JointInput,
    joint: &Joint,
    (free, held): (&[bool; 8], &[Option<String>; 8]),
    rejected: Rejected,
    second: SecondStart,
    rep: &Reporter,
) -> Result<JointOutcome> {
    let mut p = second.better;
    // σ0 with the a-priori σ's of the image points, distances and beams (what the verdict
    // tests): the bundle's χ² and every group's at the joint solution
    let chi2s = group_chi2s(joint, &p);
    let bundle = &input.adj.precision;
    let chi2 = input.adj.sigma0_a_priori.powi(2) * bundle.redundancy as f64
        + chi2s.iter().sum::<f64>()
        + joint.prior_chi2(free, &joint.solution(&p).1, joint.tau(&p));
    // the covariances with every group weighted by its own variance component
    let estimate = solver::estimate_variance_components(
        &mut p,
        &joint.options,
        &joint.group_of,
        &OBSERVATION_GROUPS,
    )
    .map_err(|e| PipelineError::Adjustment(format!("joint adjustment: {e}")))?;
    let prec = estimate.precision;
    let redundancy = prec.redundancy;
    let (ext, theta) = joint.solution(&p);
    let mount_model = MountModel {
        servo_time_offset_s: joint.tau(&p),
        ..MountModel::from_params(&theta, input.mount0.servo_zero_deg)
    };
    let sensor = sensor_estimates(joint, (&p, &prec), (free, held));
    let tables = tables(input, (&p, &prec), &ext, &mount_model);
    let out = JointOutcome {
        camera_from_lrf: ext,
        sigma_translation_mm: [3, 4, 5].map(|k| sensor.extrinsic_cov[(k, k)].max(0.0).sqrt()),
        sigma_opk_deg: opk_sigma_deg(
            &ext.rotation,
            &Matrix3::from_fn(|a, b| sensor.extrinsic_cov[(a, b)]),
        ),
        extrinsic_cov: sensor.extrinsic_cov,
        mount: sensor.mount,
        time_offset: sensor.time_offset,
        mount_model,
        mount_cov: sensor.mount_cov,
        groups: group_outcomes(joint, &p, &chi2s, &rejected),
        sigma0: (chi2 / redundancy.max(1) as f64).sqrt(),
        variance_components: estimate.components,
        redundancy,
        check: tables.check,
        control: tables.control,
        lrf_points: tables.lrf_points,
        cam_points: tables.cam_points,
        ball_centres: ball_centres(input, &p, &prec),
        notes: outcome_notes(input, joint, &p, held),
        lrf_view: lrf_view(input, &ext),
        planes: (joint.group::<PlaneBeams>()).map_or_else(Vec::new, |g| g.solved(&p)),
        convergence: second.summary,
        hold_mount: input.hold_mount.map(String::from),
        held_shifts: [None; 8],
        head: HeadPoses::of_problem(
            input.project,
            &p,
            &prec,
            Some((joint.keys.extrinsic, "rotating")),
        ),
    };
    log_outcome(&out, rep);
    Ok(out)
}

/// Each group's χ² with its a-priori σ's at the solution of `p`.
fn group_chi2s(joint: &Joint, p: &Problem) -> Vec<f64> {
    let at = joint.at(p);
    (joint.groups.iter())
        .map(|g| groups::chi2(&g.errors(&at), &g.sigmas()))
        .collect()
}

/// Every group's line: `chi2s` at the solution before the re-weighting, the RMS at the
/// final solution `p`, and the observations `rejected` (per group) as gross errors.
fn group_outcomes(
    joint: &Joint,
    p: &Problem,
    chi2s: &[f64],
    rejected: &Rejected,
) -> Vec<GroupOutcome> {
    let at = joint.at(p);
    (joint.groups.iter().zip(chi2s).zip(rejected))
        .map(|((g, &chi2), &rejected)| GroupOutcome {
            group: g.name().to_string(),
            unit: g.unit().to_string(),
            observations: g.len(),
            rejected,
            left_out: (g.left_out().into_iter())
                .map(|(reason, count)| LeftOut {
                    reason: reason.to_string(),
                    count,
                })
                .collect(),
            chi2,
            rms: groups::rms(&g.errors(&at)),
        })
        .collect()
}

/// The sensor's estimates from the solution `p` and its precision `prec`.
struct SensorEstimates {
    extrinsic_cov: DMatrix<f64>,
    mount: Vec<MountEstimate>,
    time_offset: Option<MountEstimate>,
    mount_cov: DMatrix<f64>,
}

/// The extrinsic's covariance, the mount's and the servo time offset's estimates, found in
/// `prec` by their blocks' keys.
fn sensor_estimates(
    joint: &Joint,
    (p, prec): (&Problem, &Precision),
    (free, held): (&[bool; 8], &[Option<String>; 8]),
) -> SensorEstimates {
    let (_, theta) = joint.solution(p);
    let cov = &prec.parameters_covariance;
    let rows = Rows::of(&joint.keys, prec);
    SensorEstimates {
        extrinsic_cov: DMatrix::from_fn(6, 6, |a, b| cov[(rows.ext(a), rows.ext(b))]),
        mount: (0..8)
            .map(|k| mount_estimate(k, &theta, cov, rows, held))
            .collect(),
        time_offset: (joint.time_offset.as_ref()).map(|t| {
            time_offset_estimate(
                t,
                joint.tau(p),
                (cov, rows),
                prec.parameter_offsets[t.block.0],
            )
        }),
        mount_cov: DMatrix::from_fn(8, 8, |a, b| {
            if free[a] && free[b] {
                cov[(rows.mount(a), rows.mount(b))]
            } else {
                0.0
            }
        }),
    }
}

/// The check and control tables and both sides of every matched ball.
struct Tables {
    check: CheckTable,
    control: CheckTable,
    lrf_points: Vec<PointObs>,
    cam_points: Vec<PointObs>,
}

/// The balls' tables at the solution (`ext`, `mount`).
fn tables(
    input: &JointInput,
    (p, prec): (&Problem, &Precision),
    ext: &Rigid3,
    mount: &MountModel,
) -> Tables {
    let (lrf_points, cam_points) = ball_points(input, p, prec, mount);
    let sim = Sim3::new(1.0, ext.rotation, ext.translation);
    let pick = |set: &[PointObs], check: bool| -> Vec<PointObs> {
        set.iter()
            .filter(|p| input.ext.check_ids.contains(&p.id) == check)
            .cloned()
            .collect()
    };
    Tables {
        check: check_table(&sim, &pick(&lrf_points, true), &pick(&cam_points, true)),
        control: check_table(&sim, &pick(&lrf_points, false), &pick(&cam_points, false)),
        lrf_points,
        cam_points,
    }
}

/// The LRF as this pass saw it, with the solution's extrinsic `ext`.
fn lrf_view(input: &JointInput, ext: &Rigid3) -> LrfView {
    LrfView {
        pass: input.pass,
        spheres: input.lrf.found.balls.len(),
        matched: input.ext.pairs.len(),
        seen_twice_rejected: input.lrf.found.seen_twice_rejected(),
        seen_twice_kept: input.lrf.found.seen_twice_kept(),
        rejected_at_unmatched: rejected_at_unmatched(input, ext),
        unmeasured_labels: crate::extrinsic::unmeasured_labels(
            input.project,
            input.scene,
            input.lrf,
            &input.ext.pairs,
            ext,
        ),
    }
}

/// The notes of an outcome: the pass, each group's, the parameters held.
fn outcome_notes(
    input: &JointInput,
    joint: &Joint,
    p: &Problem,
    held: &[Option<String>; 8],
) -> Vec<String> {
    let pass = (input.pass > 1).then(|| format!(
        "pass {}: the LRF cloud made again from its readings through the mount the pass before estimated, its spheres found and matched again ({} of {} spheres matched)",
        input.pass,
        input.ext.pairs.len(),
        input.lrf.found.balls.len()
    ));
    let at = joint.at(p);
    pass.into_iter()
        .chain(joint.groups.iter().flat_map(|g| g.notes(&at)))
        .chain(held.iter().enumerate().filter_map(|(k, h)| {
            h.as_ref()
                .map(|h| format!("{} held: {h}", MOUNT_PARAM_NAMES[k]))
        }))
        .collect()
}

/// The log's lines of an outcome: the beams on the balls, every other group, σ0, the check
/// balls, the variance components and the convergence.
fn log_outcome(out: &JointOutcome, rep: &Reporter) {
    let others: String = (out.groups.iter())
        .filter(|g| g.group != ball_beams::NAME)
        .map(|g| {
            format!(
                ", {} {} ({} rejected, RMS {:.2} {})",
                g.observations, g.group, g.rejected, g.rms, g.unit
            )
        })
        .collect();
    let b = out.ball_beams();
    rep.log(format!(
        "joint: {} beams ({} rejected, {} grazing, {} at a silhouette){others}, sigma0 {:.3}, RMS beam {:.2} mm; mean check error {:.2} mm (sd {:.2}) on {} balls",
        b.used,
        b.rejected,
        b.grazing,
        b.silhouette,
        out.sigma0,
        b.rms_mm,
        out.check.mean_mm,
        out.check.sd_mm,
        out.check.rows.len()
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

/// The outcome of mount parameter `k` at `theta` (its row in `cov` found by `rows`).
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
