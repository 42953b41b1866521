//! The fixed LRF's joint adjustment: the bundle's final problem (every image pose, target,
//! ball and intrinsic still unknown) with the extrinsic, the range model `[k, s]` and a
//! plane block per field plane, the beams on the planes and on the control balls, and each
//! plane's targets on it; what the data do not determine held and named; gross errors
//! removed by each group's own σ0 as the rotating LRF's adjustment does.

use super::planes::{adjustment_reach, on_what, BallOnStem, FieldPlane, On};
use super::stations::Station;
use super::{RANGE_NAMES, TARGETS_GROUP, UNKNOWN_NAMES, WEAK_PRIOR};
use crate::bundle::Adjusted;
use crate::context::{PipelineError, Result};
use crate::ids::PointId;
use crate::joint::{keep_flags, MAX_CORRELATION, MAX_PRIOR_SHARE, PLAUSIBLE, REJECT_ROUNDS};
use crate::scene::{PointKind, Scene};
use nalgebra::{DMatrix, Vector3};
use pingcal_ba::solver::{self, Precision};
use pingcal_ba::{ParameterBlock, ParameterKey, ParameterPrior, ParameterValue, Problem};
use pingcal_ba::{ResidualBlock, Value};
use pingcal_geometry::Rigid3;
use pingcal_lrf::fixed::{self, FIXED_PLANE_UNKNOWNS};
use pingcal_lrf::fixed::{FixedBeam, FixedBeamOn, PointOnPlane, PoseBlockPrior, Surface};
use pingcal_lrf::room::PlaneFrame;

type V3 = Vector3<f64>;

/// The plausible size of a fixed scanner's range offset and scale (mm, 1): the σ of their
/// priors in the final adjustment (the rotating mount's range entries).
pub(super) const RANGE_PLAUSIBLE: [f64; 2] = [PLAUSIBLE[6], PLAUSIBLE[7]];

/// A ball of the adjustment: its scene point, name, centre and radius, and whether it is a
/// check ball (its beams left out).
#[derive(Clone, Debug)]
pub struct FieldBall {
    /// The scene point.
    pub point: PointId,
    /// Its name (`B4`).
    pub name: String,
    /// Its centre (the bundle's).
    pub centre: V3,
    /// Radius (mm).
    pub radius: f64,
    /// A check ball.
    pub check: bool,
}

/// One beam observation: its station, the beam's index there, and its residual.
#[derive(Clone, Debug)]
pub struct BeamObs {
    /// The station (index into the stations).
    pub station: usize,
    /// What it is on.
    pub on: On,
    /// The residual.
    pub residual: FixedBeamOn,
}

/// The joint problem before its free set and priors are chosen.
pub struct FixedProblem {
    /// The bundle's problem with the sensor's and the planes' blocks, no residuals.
    pub base: Problem,
    /// The extrinsic's block.
    pub ext: ParameterKey,
    /// The range model's block.
    pub range: ParameterKey,
    /// The planes' blocks.
    pub planes: Vec<ParameterKey>,
    /// The extrinsic where the adjustment started (where the weak priors are centred, and
    /// where a held component stays).
    pub start: Rigid3,
    /// The beams on planes, then on balls.
    pub beams: [Vec<BeamObs>; 2],
    /// Each plane's targets on it.
    pub targets: Vec<PointOnPlane>,
    /// Beams of check balls (station, residual), not in the adjustment.
    pub check_beams: Vec<(usize, FixedBeamOn)>,
    /// Beams on a ball that miss or graze it at the start, left out.
    pub grazing: usize,
    /// Beams meeting their plane beyond [`MIN_COS_INCIDENCE`] at the start, left out.
    pub oblique: usize,
    /// Per image observation of `base`, its group.
    pub group_of: Vec<usize>,
    /// The solver's options.
    pub options: solver::Options,
}

/// A beam meeting its plane at a larger incidence than this cosine's is left out: its
/// footprint stretches along the plane and its range carries it more than the plane's
/// distance (the rotating LRF's room planes use the same bound,
/// [`pingcal_lrf::room::RoomOptions::min_cos_incidence`]).
pub const MIN_COS_INCIDENCE: f64 = 0.3;

/// The gate within which a beam is on a surface at the start: [`GATE_SIGMAS`] of the
/// beam's σ, at least this (mm).
pub const MIN_GATE_MM: f64 = 30.0;

/// The gate in the beam's σ's: wide, because it is centred on the start's prediction, not
/// the truth, and cuts a beam's noise unevenly by the start's error (with 3σ the
/// simulator's extrinsic was pulled 1.3 mm towards its start); what lies beyond the noise
/// the rounds' gross-error test removes.
pub const GATE_SIGMAS: f64 = 5.0;

impl FixedProblem {
    /// The problem of the stations' beams through the start `e` on `planes` and `balls`.
    pub fn build(
        adj: &Adjusted,
        scene: &Scene,
        stations: &[Station],
        (planes, balls): (&[FieldPlane], &[FieldBall]),
        e: Rigid3,
    ) -> Result<Self> {
        let mut base = adj.solved.problem.clone();
        base.parameters.clear();
        base.residuals.clear();
        let ext = base.add_parameter(ParameterBlock::pose("camera_from_lrf", e));
        let range = base.add_parameter(ParameterBlock::vector("lrf range", vec![0.0, 0.0]));
        let frames: Vec<(ParameterKey, PlaneFrame)> = (0..planes.len())
            .map(|k| {
                let (pl, frame) = (&planes[k], edge_frame(planes, k));
                let mut v = vec![0.0; FIXED_PLANE_UNKNOWNS];
                v[2] = pl.normal.dot(&pl.centre);
                (
                    base.add_parameter(ParameterBlock::vector("plane", v)),
                    frame,
                )
            })
            .collect();
        let keys = (ext, range, &frames[..]);
        let (beams, check_beams, [grazing, oblique]) =
            classify(adj, stations, (planes, balls), keys, (&e, &base));
        if beams[0].is_empty() && beams[1].is_empty() {
            return Err(PipelineError::Data(
                "no beam of the fixed LRF lies on a plane of the field or a control ball at the start: its scans do not see the field the targets define".into(),
            ));
        }
        let targets = targets_on_planes(adj, planes, &frames);
        let group_of = (adj.solved.map.observations.iter())
            .map(|&(j, _)| usize::from(scene.points[j].kind == PointKind::Ball))
            .collect();
        Ok(Self {
            base,
            ext,
            range,
            planes: frames.iter().map(|(k, _)| *k).collect(),
            start: e,
            beams,
            targets,
            check_beams,
            grazing,
            oblique,
            group_of,
            options: solver::Options {
                max_iterations: 100,
                ..solver::Options::default()
            },
        })
    }

    /// The problem with the unknowns `free` (the extrinsic's 6, then `k`, `s`) estimated
    /// (the others held at their values in `from`), every observation, and priors: weak
    /// ones on every free unknown (`weak`, for the estimability test) or the plausible ones
    /// on the range model.
    pub fn problem_from(&self, from: &Problem, free: &[bool; 8], weak: bool) -> Problem {
        let mut p = from.clone();
        p[self.ext].fixed = (0..6).map(|k| !free[k]).collect();
        p[self.range].fixed = (6..8).map(|k| !free[k]).collect();
        let beams = self
            .beams
            .iter()
            .flatten()
            .map(|o| ResidualBlock::new(o.residual));
        let targets = self.targets.iter().map(|t| ResidualBlock::new(*t));
        let flat = (self.planes.iter()).map(|&k| ResidualBlock::new(fixed::flatness_prior(k)));
        p.residuals = beams.chain(targets).collect();
        // after the observations: the rounds read the residuals' standardized values and
        // redundancy numbers in this order
        p.residuals.extend(flat);
        let ext: Vec<usize> = (0..6).filter(|&k| free[k] && weak).collect();
        if !ext.is_empty() {
            p.residuals.push(ResidualBlock::new(PoseBlockPrior {
                parameter: self.ext,
                value: self.start,
                sigma: ext.iter().map(|&k| WEAK_PRIOR[k]).collect(),
                components: ext,
            }));
        }
        let range: Vec<usize> = (0..2).filter(|&k| free[6 + k]).collect();
        if !range.is_empty() {
            let sigma = |k: usize| {
                if weak {
                    WEAK_PRIOR[6 + k]
                } else {
                    RANGE_PLAUSIBLE[k]
                }
            };
            p.residuals.push(ResidualBlock::new(ParameterPrior {
                parameter: self.range,
                value: vec![0.0; range.len()],
                sigma: range.iter().map(|&k| sigma(k)).collect(),
                components: range,
            }));
        }
        p
    }

    /// The extrinsic and the range model of a solved problem.
    pub fn solution(&self, p: &Problem) -> (Rigid3, [f64; 2]) {
        let ParameterValue::Pose(e) = p[self.ext].value else {
            unreachable!("the extrinsic is a pose block")
        };
        let ParameterValue::Vector(r) = &p[self.range].value else {
            unreachable!("the range model is a vector block")
        };
        (e, [r[0], r[1]])
    }

    /// Each group's errors (mm) at the solution of `p`: the beams on planes, on balls, the
    /// targets on planes.
    pub fn errors(&self, p: &Problem) -> [Vec<f64>; 3] {
        let (e, range) = self.solution(p);
        let beam_errors = |obs: &[BeamObs]| -> Vec<f64> {
            obs.iter()
                .map(|o| beam_error(p, &o.residual, &e, &range))
                .collect()
        };
        let targets = (self.targets.iter())
            .map(|t| {
                let ParameterValue::Vector(v) = &p[t.plane].value else {
                    return f64::NAN;
                };
                t.error(&p.points[t.point.0].position, v)
            })
            .collect();
        [
            beam_errors(&self.beams[0]),
            beam_errors(&self.beams[1]),
            targets,
        ]
    }

    /// Each group's a-priori σ's.
    pub fn sigmas(&self) -> [Vec<f64>; 3] {
        let s = |obs: &[BeamObs]| obs.iter().map(|o| o.residual.beam.sigma).collect();
        [
            s(&self.beams[0]),
            s(&self.beams[1]),
            self.targets.iter().map(|t| t.sigma).collect(),
        ]
    }

    /// Adjusts `p`: its precision.
    pub fn solve(&self, p: &mut Problem) -> Result<Precision> {
        let err = |e: String| PipelineError::Adjustment(format!("fixed LRF adjustment: {e}"));
        solver::solve(p, &self.options, |_| {}).map_err(|e| err(e.to_string()))?;
        solver::precision(p).map_err(|e| err(e.to_string()))
    }
}

/// The beams on planes and on control balls, on check balls, and how many missed or grazed
/// their ball and how many met their plane beyond [`MIN_COS_INCIDENCE`] at the start `e`, of
/// every station through `e`.
#[allow(clippy::type_complexity)]
fn classify(
    adj: &Adjusted,
    stations: &[Station],
    (planes, balls): (&[FieldPlane], &[FieldBall]),
    (ext, range, frames): (ParameterKey, ParameterKey, &[(ParameterKey, PlaneFrame)]),
    (e, base): (&Rigid3, &Problem),
) -> ([Vec<BeamObs>; 2], Vec<(usize, FixedBeamOn)>, [usize; 2]) {
    let spheres: Vec<BallOnStem> = (balls.iter())
        .map(|b| BallOnStem::new(b.centre, b.radius, planes))
        .collect();
    let mut beams: [Vec<BeamObs>; 2] = [Vec::new(), Vec::new()];
    let mut check_beams = Vec::new();
    let (mut grazing, mut oblique) = (0, 0);
    for (s, st) in stations.iter().enumerate() {
        for (b, ray) in st.beams.iter().zip(st.rays(e, [0.0, 0.0])) {
            let gate = (GATE_SIGMAS * b.sigma).max(MIN_GATE_MM);
            let Some((on, predicted)) = on_what(&ray, planes, &spheres, adjustment_reach(gate))
            else {
                continue;
            };
            // σ at the range the surface predicts, not the one measured: weights from the
            // noisy range favour the beams whose noise shortened them (a range bias of
            // −2σ²/r, 0.4 mm at 2 m for the URG, that the range scale and the extrinsic took)
            let beam = FixedBeam {
                sigma: st.noise.sigma(predicted).max(1.0),
                ..*b
            };
            let surface = match on {
                On::Plane(k) => {
                    if planes[k].normal.dot(&ray.dir).abs() < MIN_COS_INCIDENCE {
                        oblique += 1;
                        continue;
                    }
                    Surface::Plane(frames[k].0, frames[k].1)
                }
                On::Ball(k) => match adj.solved.map.point(balls[k].point) {
                    Some(key) => Surface::Ball(key, balls[k].radius),
                    None => continue,
                },
            };
            let residual = FixedBeamOn {
                beam,
                station: st.key,
                extrinsic: ext,
                range,
                surface,
            };
            // a beam that misses or grazes its ball at the start is left out
            let grazes = match on {
                On::Ball(k) => residual.grazes(&st.pose, e, &balls[k].centre),
                On::Plane(_) => false,
            };
            if grazes || beam_error(base, &residual, e, &[0.0, 0.0]).is_nan() {
                grazing += 1;
                continue;
            }
            match on {
                On::Ball(k) if balls[k].check => check_beams.push((s, residual)),
                On::Ball(_) => beams[1].push(BeamObs {
                    station: s,
                    on,
                    residual,
                }),
                On::Plane(_) => beams[0].push(BeamObs {
                    station: s,
                    on,
                    residual,
                }),
            }
        }
    }
    (beams, check_beams, [grazing, oblique])
}

/// The frame of plane `k` with its axes along its edges: the first along the line where it
/// meets the plane most square to it (a wall's along the floor, the floor's along a wall),
/// so that the bend's `ũ²ṽ²` is a panel held at its edges bowing between them (in axes
/// turned 45° from the edges, as the default's frame put them on the walls, a pillow is not
/// in the bend's span, and the fixed scanner's pitch took 2σ of its misfit); the default
/// frame when no other plane is square enough to it (30°).
fn edge_frame(planes: &[FieldPlane], k: usize) -> PlaneFrame {
    let pl = &planes[k];
    let mut frame = PlaneFrame::new(pl.normal, pl.centre, pl.spread);
    let edge = (planes.iter().enumerate())
        .filter(|(j, _)| *j != k)
        .map(|(_, q)| pl.normal.cross(&q.normal))
        .max_by(|a, b| a.norm().total_cmp(&b.norm()))
        .filter(|c| c.norm() >= 0.5);
    if let Some(c) = edge {
        frame.e1 = c.normalize();
        frame.e2 = frame.normal.cross(&frame.e1);
    }
    frame
}

/// `e` of a beam at the solution of `p` (NaN where undefined).
pub fn beam_error(p: &Problem, r: &FixedBeamOn, e: &Rigid3, range: &[f64; 2]) -> f64 {
    let pose = &p.images[r.station.0].camera_from_object;
    let surface = match r.surface {
        Surface::Plane(k, _) => match &p[k].value {
            ParameterValue::Vector(v) => Value::Vector(v),
            ParameterValue::Pose(_) => return f64::NAN,
        },
        Surface::Ball(k, _) => Value::Point(&p.points[k.0].position),
    };
    r.error(pose, e, range, &surface).unwrap_or(f64::NAN)
}

/// Each plane's targets on it, with the plane's own RMS (at least 0.5 mm) as σ.
fn targets_on_planes(
    adj: &Adjusted,
    planes: &[FieldPlane],
    frames: &[(ParameterKey, PlaneFrame)],
) -> Vec<PointOnPlane> {
    let mut out = Vec::new();
    for (pl, (key, frame)) in planes.iter().zip(frames) {
        for &j in &pl.members {
            if let Some(point) = adj.solved.map.point(j) {
                out.push(PointOnPlane {
                    point,
                    plane: *key,
                    frame: *frame,
                    sigma: pl.rms_mm.max(0.5),
                    group: TARGETS_GROUP,
                });
            }
        }
    }
    out
}

/// The adjustment's rounds: adjusted, each group's gross errors removed (by its own σ0,
/// [`keep_flags`]) and adjusted again, at most [`REJECT_ROUNDS`] times; with the weak
/// priors on every free unknown (`weak`: the first pass, before what the data determine is
/// known) or without them (the final one). Returns the
/// solved problem, its precision and the observations removed per group.
pub fn rounds(
    fp: &mut FixedProblem,
    free: &[bool; 8],
    weak: bool,
) -> Result<(Problem, Precision, [usize; 3])> {
    let mut rejected = [0usize; 3];
    for round in 0..=REJECT_ROUNDS {
        let mut p = fp.problem_from(&fp.base, free, weak);
        let prec = fp.solve(&mut p)?;
        let (errors, sigmas) = (fp.errors(&p), fp.sigmas());
        let (w, q) = (
            &prec.residual_standardized,
            &prec.residual_redundancy_numbers,
        );
        let mut start = 0;
        let keep: Vec<Vec<bool>> = (0..3)
            .map(|g| {
                let n = errors[g].len();
                let r = start..start + n;
                start += n;
                keep_flags(&errors[g], &sigmas[g], &w[r.clone()], &q[r])
            })
            .collect();
        let bad: Vec<usize> = keep
            .iter()
            .map(|k| k.iter().filter(|k| !**k).count())
            .collect();
        if round == REJECT_ROUNDS || bad.iter().all(|&b| b == 0) {
            return Ok((p, prec, rejected));
        }
        for (beams, keep) in fp.beams.iter_mut().zip(&keep) {
            let mut it = keep.iter();
            beams.retain(|_| *it.next().expect("one flag per beam"));
        }
        let mut it = keep[2].iter();
        fp.targets
            .retain(|_| *it.next().expect("one flag per target"));
        rejected.iter_mut().zip(bad).for_each(|(r, b)| *r += b);
    }
    unreachable!("the last round returns")
}

/// Holds, one at a time, the unknowns the data do not determine, judged on the cofactors at
/// the solution `at` with weak priors (σ beyond [`MAX_PRIOR_SHARE`] of the prior, or a
/// correlation beyond [`MAX_CORRELATION`]); each held one's reason in `held`.
pub fn estimability(
    fp: &FixedProblem,
    at: &Problem,
    free: &mut [bool; 8],
    held: &mut [Option<String>; 8],
) -> Result<()> {
    while free.iter().any(|&f| f) {
        let p = fp.problem_from(at, free, true);
        let prec = solver::precision(&p).map_err(|e| {
            PipelineError::Adjustment(format!(
                "fixed LRF adjustment (what the data determine): {e}"
            ))
        })?;
        let cov = &prec.parameters_covariance / prec.sigma0.powi(2).max(f64::MIN_POSITIVE);
        let row = |k: usize| match k {
            0..=5 => prec.parameter_offsets[fp.ext.0] + k,
            _ => prec.parameter_offsets[fp.range.0] + k - 6,
        };
        let worst = (0..8)
            .filter(|&k| free[k])
            .filter_map(|k| not_determined(k, &cov, &row, free).map(|(rank, why)| (rank, k, why)))
            .max_by(|a, b| a.0.total_cmp(&b.0));
        let Some((_, k, why)) = worst else { break };
        free[k] = false;
        held[k] = Some(why);
    }
    Ok(())
}

/// Why unknown `k` is not determined (σ under the weak prior, correlation), with a rank
/// (larger: worse); None when it is.
pub fn not_determined(
    k: usize,
    cov: &DMatrix<f64>,
    row: &dyn Fn(usize) -> usize,
    free: &[bool; 8],
) -> Option<(f64, String)> {
    let sd = |k: usize| cov[(row(k), row(k))].max(0.0).sqrt();
    let share = sd(k) / WEAK_PRIOR[k];
    let name = |k: usize| {
        if k < 6 {
            UNKNOWN_NAMES[k]
        } else {
            RANGE_NAMES[k - 6]
        }
    };
    if share > MAX_PRIOR_SHARE {
        return Some((
            share,
            format!(
                "the data do not determine {}: σ {:.3} under a weak prior of {} (the beams meet too few directions of surface: add a tilted plane or the floor in the scan, or balls or larger spheres at the scan plane's height)",
                name(k),
                sd(k),
                WEAK_PRIOR[k]
            ),
        ));
    }
    let (j, rho) = (0..8)
        .filter(|&j| j != k && free[j])
        .map(|j| {
            (
                j,
                cov[(row(k), row(j))] / (sd(k) * sd(j)).max(f64::MIN_POSITIVE),
            )
        })
        .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))?;
    (rho.abs() > MAX_CORRELATION && share >= sd(j) / WEAK_PRIOR[j]).then(|| {
        (
            rho.abs(),
            format!(
                "{} is correlated with {} at ρ = {rho:.4}: the data tell only their combination",
                name(k),
                name(j)
            ),
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A wall's frame runs along the floor, the floor's along the wall most square to it; a
    /// plane with no other square to it keeps the default frame.
    #[test]
    fn a_planes_frame_runs_along_its_edge() {
        let wall = FieldPlane::square(V3::new(-0.72, 0.69, 0.0), 0.0, 1000.0);
        let floor = FieldPlane::square(V3::z(), 0.0, 1000.0);
        let planes = [wall.clone(), floor];
        let f = edge_frame(&planes, 0);
        let along = wall.normal.cross(&V3::z()).normalize();
        assert!(f.e1.cross(&along).norm() < 1e-12, "{:?}", f.e1);
        assert!(f.e2.cross(&V3::z()).norm() < 1e-12, "{:?}", f.e2);
        let g = edge_frame(&planes, 1);
        assert!(g.e1.cross(&along).norm() < 1e-12, "{:?}", g.e1);
        let alone = edge_frame(&planes[..1], 0);
        assert_eq!(
            alone,
            PlaneFrame::new(wall.normal, wall.centre, wall.spread)
        );
    }
}
