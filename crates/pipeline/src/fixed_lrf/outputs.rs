//! The fixed LRF's outcome in the shapes the later steps read: the check tables of the
//! balls its scans cut (a row per ball and station), the cloud of every station's beams in
//! the main station's LRF frame, the corner baseline, and the joint adjustment's outcome.

use super::adjust::{beam_error, FieldBall, FixedProblem};
use super::planes::{adjustment_reach, on_what, BallOnStem, FieldPlane, On};
use super::stations::Station;
use super::{RANGE_NAMES, UNKNOWN_NAMES};
use crate::bundle::Adjusted;
use crate::extrinsic::{CornerOutcome, Extrinsics};
use crate::head::HeadPoses;
use crate::ids::{PointId, SphereId};
use crate::joint::groups::{rms, LeftOut};
use crate::joint::{Convergence, GroupOutcome, JointOutcome, LrfView, MountEstimate};
use crate::lrf::LrfData;
use crate::progress::Reporter;
use crate::scene::Scene;
use nalgebra::{DMatrix, Matrix3, Vector3};
use pingcal_ba::solver::{self, VarianceEstimate};
use pingcal_ba::Problem;
use pingcal_geometry::{opk_sigma_deg, Rigid3, Sim3};
use pingcal_lrf::ball_finder::{Ball, FindResult, Support};
use pingcal_lrf::cloud::Cloud;
use pingcal_lrf::fixed::grazes_sphere;
use pingcal_lrf::registration::{check_table, PointObs};
use pingcal_lrf::sensor::MountModel;
use pingcal_project::{Method, Project};

type V3 = Vector3<f64>;

/// Fewest beams of one station on a ball for its row of the check tables.
pub const MIN_BALL_BEAMS: usize = 6;
/// Fewest distinct beam directions of one station on a ball for its row of the check
/// tables: a cut's centre is a circle's, and a circle through two or three directions (a
/// ping-pong ball 1.5 m from a URG holds about four beams, their rims mixed with the wall)
/// is not determined by them, whatever its linearised σ says (on the simulator such cuts
/// were 20–120 mm off and failed the check in 3 seeds of 10).
pub const MIN_BALL_DIRECTIONS: usize = 6;
/// How far the corner baseline may put a ball from where its station's beams see it, when
/// its check table chooses the ball's beams (mm): one scan line fixes the extrinsic to
/// centimetres (2–14 mm and up to 1.7° on the simulator, about 45 mm at 1.5 m).
pub const CORNER_SLACK_MM: f64 = 50.0;
/// Beam directions of a cut are counted in bins of this (degrees): a tenth of a degree, under
/// the URG's 0.35° step and over a cloud point's angular noise.
pub const DIRECTION_BIN_DEG: f64 = 0.1;

/// One ball cut by one station's scans: its centre fitted in the LRF frame from those beams
/// alone, and the photogrammetric ball in that station's camera frame.
#[derive(Clone, Debug)]
struct BallCut {
    ball: usize,
    station: usize,
    lrf: PointObs,
    cam: PointObs,
    beams: usize,
}

/// Every ball the stations' scans cut, fitted: the beams on it as the adjustment decides
/// them through `e` ([`on_what`]: the ray meets its sphere within the gate, clear of its
/// stem), less those that graze it ([`grazes_sphere`]: their footprint mixes it with what
/// is behind); a cut with fewer than [`MIN_BALL_BEAMS`] beams or [`MIN_BALL_DIRECTIONS`]
/// directions is left out. `slack` (mm): how far `e` may put a ball from where the beams see
/// it (the corner baseline's, whose error is centimetres): a ball's beams are then those whose
/// rays meet its sphere widened by the slack and whose points lie within the gate and the
/// slack of its surface; 0 for the adjustment's own estimate.
fn ball_cuts(
    stations: &[Station],
    (planes, balls): (&[FieldPlane], &[FieldBall]),
    (e, range): (&Rigid3, [f64; 2]),
    slack: f64,
) -> Vec<BallCut> {
    let stems: Vec<BallOnStem> = (balls.iter())
        .map(|b| BallOnStem::new(b.centre, b.radius, planes))
        .collect();
    let mut out = Vec::new();
    for (s, st) in stations.iter().enumerate() {
        let mut on: Vec<Vec<(V3, f64, i64)>> = vec![Vec::new(); balls.len()];
        for (b, ray) in st.beams.iter().zip(st.rays(e, range)) {
            let gate = (super::adjust::GATE_SIGMAS * b.sigma).max(super::MIN_GATE_MM);
            let k = if slack > 0.0 {
                // a ball whose sphere widened by the slack the ray meets, its point within the
                // gate and the slack of the ball's surface
                balls.iter().position(|bl| {
                    let w = ray.origin - bl.centre;
                    let along = -ray.dir.dot(&w);
                    let miss2 = w.norm_squared() - along * along;
                    along > 0.0
                        && miss2 < (bl.radius + slack).powi(2)
                        && ((ray.point() - bl.centre).norm() - bl.radius).abs() <= gate + slack
                })
            } else {
                match on_what(&ray, planes, &stems, adjustment_reach(gate)) {
                    Some((On::Ball(k), _))
                        if !grazes_sphere(
                            &ray.origin,
                            &ray.dir,
                            &balls[k].centre,
                            balls[k].radius,
                        ) =>
                    {
                        Some(k)
                    }
                    _ => None,
                }
            };
            let Some(k) = k else { continue };
            let x = b.point_at((b.range_mm - range[0]) / (1.0 + range[1]));
            // the direction in bins of DIRECTION_BIN_DEG: a cloud's points give each beam's
            // angle with the noise of its point, a scan file exactly
            let bin = (b.alpha_rad.to_degrees() / DIRECTION_BIN_DEG).round() as i64;
            on[k].push((x, b.sigma, bin));
        }
        for (k, (ball, on)) in balls.iter().zip(&on).enumerate() {
            let mut directions: Vec<i64> = on.iter().map(|p| p.2).collect();
            directions.sort_unstable();
            directions.dedup();
            if on.len() < MIN_BALL_BEAMS || directions.len() < MIN_BALL_DIRECTIONS {
                continue;
            }
            let cam = st.pose.transform(&ball.centre);
            let c0 = e.inverse().transform(&cam);
            let on: Vec<(V3, f64)> = on.iter().map(|&(x, s, _)| (x, s)).collect();
            let (c, cov) = fit_centre(&on, ball.radius, c0);
            let id = format!("{} at {}", ball.name, st.id);
            out.push(BallCut {
                ball: k,
                station: s,
                lrf: PointObs {
                    id: id.clone(),
                    xyz: c,
                    cov,
                },
                cam: PointObs {
                    id,
                    xyz: cam,
                    cov: Matrix3::zeros(),
                },
                beams: on.len(),
            });
        }
    }
    out
}

/// The centre of the sphere of `radius` through the points (each with its σ), from `c0`
/// (damped Gauss–Newton: a scan through the ball's equator leaves its centre's distance
/// from the scan plane to the start), and its covariance.
fn fit_centre(points: &[(V3, f64)], radius: f64, c0: V3) -> (V3, Matrix3<f64>) {
    let mut c = c0;
    let mut h = Matrix3::identity();
    for _ in 0..20 {
        h = Matrix3::zeros();
        let mut g = V3::zeros();
        for (x, s) in points {
            let d = c - x;
            let n = d.norm().max(1e-9);
            let j = d / n / *s;
            h += j * j.transpose();
            g += j * ((n - radius) / s);
        }
        let damping = 1e-6 * h.trace().max(1e-12);
        let Some(step) = (h + Matrix3::identity() * damping)
            .cholesky()
            .map(|ch| ch.solve(&(-g)))
        else {
            break;
        };
        c += step;
        if step.norm() < 1e-6 {
            break;
        }
    }
    let damping = 1e-6 * h.trace().max(1e-12);
    let cov = (h + Matrix3::identity() * damping)
        .try_inverse()
        .unwrap_or_else(Matrix3::zeros);
    (c, cov)
}

/// The LRF side and the camera side of the cuts of the balls whose check flag is `check`.
fn sides(cuts: &[BallCut], balls: &[FieldBall], check: bool) -> (Vec<PointObs>, Vec<PointObs>) {
    (cuts.iter())
        .filter(|c| balls[c.ball].check == check)
        .map(|c| (c.lrf.clone(), c.cam.clone()))
        .unzip()
}

/// Fan et al.'s single shot when `method` asks for it: the main station's if its scan saw
/// the corner, else the first station's that did (the notes say which), with its check
/// table; or why it failed at every station.
pub fn corner_outcome(
    project: &Project,
    stations: &[Station],
    (planes, balls): (&[FieldPlane], &[FieldBall]),
    corners: &[(String, Result<Rigid3, String>)],
) -> Option<Result<CornerOutcome, String>> {
    if !matches!(project.file.method, Method::Corner | Method::All) {
        return None;
    }
    let main = &project.file.main_station;
    let chosen = (corners.iter().find(|(st, r)| st == main && r.is_ok()))
        .or_else(|| corners.iter().find(|(_, r)| r.is_ok()));
    let Some((st, Ok(e))) = chosen else {
        let why: Vec<String> = (corners.iter())
            .map(|(st, r)| format!("{st}: {}", r.as_ref().err().map_or("", |s| s.as_str())))
            .collect();
        return Some(Err(format!(
            "no station's scan saw the room corner ({})",
            why.join("; ")
        )));
    };
    let k = stations
        .iter()
        .position(|s| &s.id == st)
        .expect("a station's corner");
    let cuts: Vec<BallCut> = ball_cuts(
        &stations[k..=k],
        (planes, balls),
        (e, [0.0; 2]),
        CORNER_SLACK_MM,
    );
    let check = balls.iter().any(|b| b.check);
    let (l, c) = sides(&cuts, balls, check);
    let sim = Sim3::new(1.0, e.rotation, e.translation);
    Some(Ok(CornerOutcome {
        camera_from_lrf: sim,
        check: check_table(&sim, &l, &c),
        notes: vec![format!(
            "the single shot of the room corner at station {st} (Fan et al. 2019), the fixed LRF's scans there"
        )],
    }))
}

/// The fixed LRF's data through the extrinsic `e` and range model: the cloud of every
/// station's beams in the main station's LRF frame (`e⁻¹` of the object frame, which is the
/// main camera's), the balls cut as its spheres, the main station's scans (for the corner
/// baseline's notes), the range model as the mount; and the balls' pairs.
pub fn lrf_data(
    project: &Project,
    stations: &[Station],
    e: &Rigid3,
    range: [f64; 2],
    (planes, balls): (&[FieldPlane], &[FieldBall]),
) -> (LrfData, Vec<(SphereId, PointId)>) {
    let inv = e.inverse();
    let mut cloud = Cloud::default();
    let mut origins = Vec::new();
    for st in stations {
        let origin = inv.transform(&st.pose.inverse().transform(&e.translation));
        for x in st.object_points(e, range) {
            cloud.points.push(inv.transform(&x));
            origins.push(origin);
        }
    }
    cloud.origins = Some(origins);
    let cuts = ball_cuts(stations, (planes, balls), (e, range), 0.0);
    let mut found = FindResult::default();
    let mut pairs = Vec::new();
    for cut in &cuts {
        // the cut's centre from its station's LRF frame into the main station's
        let to_main = inv
            .compose(&stations[cut.station].pose.inverse())
            .compose(e);
        let centre = to_main.transform(&cut.lrf.xyz);
        let r = to_main.rotation;
        pairs.push((SphereId(found.balls.len()), balls[cut.ball].point));
        found.balls.push(Ball {
            centre,
            cov: r * cut.lrf.cov * r.transpose(),
            inliers: Vec::new(),
            cluster_points: cut.beams,
            rejected_points: 0,
            sigma0: 1.0,
            range_mm: centre.norm(),
            support: Support::default(),
        });
    }
    let main = &project.file.main_station;
    let scans = (stations
        .iter()
        .find(|s| &s.id == main && !s.lines.is_empty()))
    .map(|s| (s.header, s.lines.clone()));
    let lrf = LrfData {
        cloud,
        found,
        scans,
        mount: MountModel {
            range_offset_mm: range[0],
            range_scale: range[1],
            ..MountModel::default()
        },
        noise: project.lrf.noise,
    };
    (lrf, pairs)
}

/// The two-step methods' place: the balls' pairs and sides, the corner baseline.
pub fn extrinsics(
    project: &Project,
    (lrf, pairs): &(LrfData, Vec<(SphereId, PointId)>),
    scene: &Scene,
    corner: Option<Result<CornerOutcome, String>>,
) -> Extrinsics {
    let lrf_points = (pairs.iter())
        .map(|&(s, p)| PointObs {
            id: scene.points[p].name.clone(),
            xyz: lrf.found.balls[s.0].centre,
            cov: lrf.found.balls[s.0].cov,
        })
        .collect();
    let cam_points = (pairs.iter())
        .map(|&(_, p)| PointObs::new(scene.points[p].name.clone(), scene.points[p].position, 0.0))
        .collect();
    Extrinsics {
        pairs: pairs.clone(),
        match_rms_mm: 0.0,
        lrf_points,
        cam_points,
        spheres: None,
        corner,
        check_ids: project.file.balls.check.clone(),
        through_room: None,
    }
}

/// Each group's χ² with its a-priori σ's at the solution of `p`.
pub fn group_chi2s(fp: &FixedProblem, p: &Problem) -> [f64; 3] {
    let (e, s) = (fp.errors(p), fp.sigmas());
    std::array::from_fn(|g| crate::joint::groups::chi2(&e[g], &s[g]))
}

/// The group names, in the order of the problem's residuals.
const GROUPS: [&str; 3] = [super::PLANE_GROUP, super::BALL_GROUP, super::TARGETS_GROUP];

/// The joint adjustment's outcome (see the module doc).
pub fn joint_outcome(
    fp: &FixedProblem,
    adj: &Adjusted,
    (stations, planes, balls): (&[Station], &[FieldPlane], &[FieldBall]),
    (p, estimate): (&Problem, &VarianceEstimate),
    (free, held): (&[bool; 8], &[Option<String>; 8]),
    (chi2s, rejected): ([f64; 3], [usize; 3]),
) -> JointOutcome {
    let prec = &estimate.precision;
    let (e, range) = fp.solution(p);
    let ext_cov = prec.parameter_covariance(fp.ext.0, fp.ext.0);
    let range_cov = prec.parameter_covariance(fp.range.0, fp.range.0);
    let prior_chi2: f64 = (0..2)
        .filter(|&k| free[6 + k])
        .map(|k| (range[k] / super::adjust::RANGE_PLAUSIBLE[k]).powi(2))
        .sum();
    let redundancy = prec.redundancy;
    let chi2 = adj.sigma0_a_priori.powi(2) * adj.precision.redundancy as f64
        + chi2s.iter().sum::<f64>()
        + prior_chi2;
    let groups = group_lines(fp, p, chi2s, rejected);
    let cuts = ball_cuts(stations, (planes, balls), (&e, range), 0.0);
    let sim = Sim3::new(1.0, e.rotation, e.translation);
    let (cl, cc) = sides(&cuts, balls, true);
    let (ol, oc) = sides(&cuts, balls, false);
    let (lrf_points, cam_points) = (cuts.iter())
        .map(|c| (c.lrf.clone(), c.cam.clone()))
        .unzip();
    let mount = range_estimates(fp, prec, (range, &range_cov, &ext_cov), (free, held));
    let mut mount_cov = DMatrix::zeros(8, 8);
    for a in 0..2 {
        for b in 0..2 {
            mount_cov[(6 + a, 6 + b)] = range_cov[(a, b)];
        }
    }
    JointOutcome {
        camera_from_lrf: e,
        sigma_translation_mm: [3, 4, 5].map(|k| ext_cov[(k, k)].max(0.0).sqrt()),
        sigma_opk_deg: opk_sigma_deg(&e.rotation, &Matrix3::from_fn(|a, b| ext_cov[(a, b)])),
        extrinsic_cov: ext_cov,
        mount,
        time_offset: None,
        mount_model: MountModel {
            range_offset_mm: range[0],
            range_scale: range[1],
            ..MountModel::default()
        },
        mount_cov,
        groups,
        sigma0: (chi2 / redundancy.max(1) as f64).sqrt(),
        variance_components: estimate.components.clone(),
        redundancy,
        check: check_table(&sim, &cl, &cc),
        control: check_table(&sim, &ol, &oc),
        lrf_points,
        cam_points,
        ball_centres: ball_centres(adj, balls, p, prec),
        notes: notes(fp, p, (stations, planes), held),
        lrf_view: LrfView::default(),
        planes: Vec::new(),
        convergence: convergence(fp, p, prec, free),
        hold_mount: Some(
            "a fixed LRF has no servo and no mount: its range offset and scale are its model"
                .into(),
        ),
        held_shifts: [None; 8],
        head: HeadPoses::default(),
    }
}

/// Each group's line at the solution `p` (`chi2s` before the re-weighting, `rejected` per
/// group).
fn group_lines(
    fp: &FixedProblem,
    p: &Problem,
    chi2s: [f64; 3],
    rejected: [usize; 3],
) -> Vec<GroupOutcome> {
    let errors = fp.errors(p);
    let counts = [fp.beams[0].len(), fp.beams[1].len(), fp.targets.len()];
    (0..3)
        .map(|g| GroupOutcome {
            group: GROUPS[g].to_string(),
            unit: "mm".into(),
            observations: counts[g],
            rejected: rejected[g],
            left_out: match g {
                0 => vec![LeftOut {
                    reason: "at grazing incidence".into(),
                    count: fp.oblique,
                }],
                1 => vec![
                    LeftOut {
                        reason: "on a check ball".into(),
                        count: fp.check_beams.len(),
                    },
                    LeftOut {
                        reason: "missed or grazed the ball at the start".into(),
                        count: fp.grazing,
                    },
                ],
                _ => Vec::new(),
            },
            // + 0.0: an empty group's sums are −0.0, written as 0
            chi2: chi2s[g] + 0.0,
            rms: rms(&errors[g]) + 0.0,
        })
        .collect()
}

/// The range model's two estimates (as the rotating LRF's mount entries), each with its σ
/// and correlations with the extrinsic, or why it was held.
fn range_estimates(
    fp: &FixedProblem,
    prec: &solver::Precision,
    (range, range_cov, ext_cov): ([f64; 2], &DMatrix<f64>, &DMatrix<f64>),
    (free, held): (&[bool; 8], &[Option<String>; 8]),
) -> Vec<MountEstimate> {
    (0..2)
        .map(|k| MountEstimate {
            name: RANGE_NAMES[k],
            value: range[k],
            sigma: free[6 + k].then(|| range_cov[(k, k)].max(0.0).sqrt()),
            held: held[6 + k].clone(),
            corr_extrinsic: free[6 + k].then(|| {
                let cross = prec.parameter_covariance(fp.range.0, fp.ext.0);
                std::array::from_fn(|j| {
                    let d = (range_cov[(k, k)] * ext_cov[(j, j)]).sqrt();
                    if d > 0.0 {
                        cross[(k, j)] / d
                    } else {
                        0.0
                    }
                })
            }),
        })
        .collect()
}

/// The joint adjustment's centre of every ball (its image rays and, for a control ball,
/// its beams), with its covariance.
fn ball_centres(
    adj: &Adjusted,
    balls: &[FieldBall],
    p: &Problem,
    prec: &solver::Precision,
) -> Vec<(PointId, PointObs)> {
    (balls.iter())
        .filter_map(|b| {
            let k = adj.solved.map.point(b.point)?;
            let cov = prec.point_covariances[k.0].unwrap_or_else(Matrix3::zeros);
            Some((
                b.point,
                PointObs {
                    id: b.name.clone(),
                    xyz: p.points[k.0].position,
                    cov,
                },
            ))
        })
        .collect()
}

/// The notes: what was held, each station's beams on the planes and balls, each plane's
/// beams and flatness.
fn notes(
    fp: &FixedProblem,
    p: &Problem,
    (stations, planes): (&[Station], &[FieldPlane]),
    held: &[Option<String>; 8],
) -> Vec<String> {
    let mut out: Vec<String> = (held.iter().enumerate())
        .filter_map(|(k, why)| {
            let name = if k < 6 {
                UNKNOWN_NAMES[k]
            } else {
                RANGE_NAMES[k - 6]
            };
            why.as_ref().map(|w| format!("held: {name}: {w}"))
        })
        .collect();
    let (e, range) = fp.solution(p);
    let err = |o: &super::adjust::BeamObs| beam_error(p, &o.residual, &e, &range);
    for (s, st) in stations.iter().enumerate() {
        let mut line = format!("station {}: {} beams", st.id, st.beams.len());
        let mut on = 0;
        for (g, what) in [(0, "plane"), (1, "ball")] {
            let mut seen: Vec<usize> = (fp.beams[g].iter())
                .filter(|o| o.station == s)
                .map(|o| match o.on {
                    On::Plane(k) | On::Ball(k) => k,
                })
                .collect();
            seen.sort_unstable();
            seen.dedup();
            for k in seen {
                let errs: Vec<f64> = (fp.beams[g].iter())
                    .filter(|o| {
                        o.station == s && matches!(o.on, On::Plane(j) | On::Ball(j) if j == k)
                    })
                    .map(err)
                    .collect();
                on += errs.len();
                line += &format!("; {what} {k}: {} (RMS {:.1} mm)", errs.len(), rms(&errs));
            }
        }
        line += &format!("; {} on neither", st.beams.len() - on);
        out.push(line);
    }
    for (k, pl) in planes.iter().enumerate() {
        let on: Vec<&super::adjust::BeamObs> = (fp.beams[0].iter())
            .filter(|o| o.on == On::Plane(k))
            .collect();
        let errs: Vec<f64> = on.iter().map(|o| err(o)).collect();
        let bend = bend_mm(fp, p, k);
        out.push(format!(
            "plane {k}: {} targets flat to {:.2} mm RMS, its bend up to {bend:.1} mm over them (from the plane tangent at their centre); {} beams on it, RMS {:.1} mm",
            pl.members.len(),
            pl.rms_mm,
            errs.len(),
            rms(&errs)
        ));
    }
    out
}

/// The largest bend of plane `k` at its targets (its departure from the flat plane through
/// its frame's centre, mm) at the solution of `p`: where the targets measure the wall's
/// shape (beyond them the bend is the beams' alone, and noisy).
fn bend_mm(fp: &FixedProblem, p: &Problem, k: usize) -> f64 {
    let key = fp.planes[k];
    let pingcal_ba::ParameterValue::Vector(v) = &p[key].value else {
        return f64::NAN;
    };
    (fp.targets.iter())
        .filter(|t| t.plane == key)
        .map(|t| pingcal_lrf::fixed::bend_at(&t.frame, v, &p.points[t.point.0].position).0)
        .fold(0.0f64, |m, b| m.max(b.abs()))
}

/// The second start: from the solution with every free extrinsic unknown moved by 1 σ
/// (signs alternating) and the range model by 1 σ, the minimum reached compared in σ's.
fn convergence(
    fp: &FixedProblem,
    p: &Problem,
    prec: &solver::Precision,
    free: &[bool; 8],
) -> Convergence {
    let row = |k: usize| {
        if k < 6 {
            prec.parameter_offsets[fp.ext.0] + k
        } else {
            prec.parameter_offsets[fp.range.0] + k - 6
        }
    };
    let sd: Vec<f64> = (0..8)
        .map(|k| prec.parameters_covariance[(row(k), row(k))].max(0.0).sqrt())
        .collect();
    let mut q = fp.problem_from(p, free, false);
    let delta: Vec<f64> = (0..6)
        .map(|k| {
            if free[k] {
                sd[k] * if k % 2 == 0 { 1.0 } else { -1.0 }
            } else {
                0.0
            }
        })
        .collect();
    q[fp.ext].plus(&delta);
    let dr: Vec<f64> = (6..8).map(|k| if free[k] { sd[k] } else { 0.0 }).collect();
    q[fp.range].plus(&dr);
    let mut p1 = fp.problem_from(p, free, false);
    let s1 = solver::solve(&mut p1, &fp.options, |_| {});
    let s2 = solver::solve(&mut q, &fp.options, |_| {});
    let (s1, s2) = match (s1, s2) {
        (Ok(a), Ok(b)) => (a, b),
        (Err(e), _) | (_, Err(e)) => {
            return Convergence {
                termination: format!("the solver failed from the second start: {e}"),
                converged: false,
                iterations: 0,
                gradient_max_norm: f64::NAN,
                cost: (f64::NAN, f64::NAN),
                max_difference_z: f64::INFINITY,
                same_minimum: false,
                second_lower: false,
            }
        }
    };
    let ((e1, r1), (e2, r2)) = (fp.solution(&p1), fp.solution(&q));
    let dw = pingcal_geometry::log_so3(&(e2.rotation * e1.rotation.transpose()));
    let dt = e2.translation - e1.translation;
    let diffs = [
        dw[0],
        dw[1],
        dw[2],
        dt[0],
        dt[1],
        dt[2],
        r2[0] - r1[0],
        r2[1] - r1[1],
    ];
    let z = (0..8)
        .filter(|&k| free[k] && sd[k] > 0.0)
        .map(|k| diffs[k].abs() / sd[k])
        .fold(0.0, f64::max);
    let same = z <= crate::joint::SAME_MINIMUM_Z;
    Convergence {
        termination: s1.termination.to_string(),
        converged: !matches!(
            s1.termination,
            solver::Termination::MaxIterations | solver::Termination::TrustRegionTooSmall
        ),
        iterations: s1.iterations,
        gradient_max_norm: (s1.log.last()).map_or(f64::NAN, |i| i.gradient_max_norm),
        cost: (s1.final_cost, s2.final_cost),
        max_difference_z: z,
        same_minimum: same,
        second_lower: !same && s2.final_cost < s1.final_cost,
    }
}

/// The outcome's lines in the log.
pub fn log_outcome(out: &JointOutcome, rep: &Reporter) {
    let t = out.camera_from_lrf.translation;
    let o = out.camera_from_lrf.opk_deg();
    let s = out.sigma_translation_mm;
    let so = out.sigma_opk_deg;
    rep.log(format!(
        "  fixed LRF joint: t = ({:.1} ± {:.1}, {:.1} ± {:.1}, {:.1} ± {:.1}) mm, ω φ κ = ({:.3} ± {:.3}, {:.3} ± {:.3}, {:.3} ± {:.3})°, σ0 {:.3}",
        t.x, s[0], t.y, s[1], t.z, s[2], o[0], so[0], o[1], so[1], o[2], so[2], out.sigma0
    ));
    for g in &out.groups {
        rep.log(format!(
            "  fixed LRF joint: {}: {} observations ({} rejected), RMS {:.2} {}",
            g.group, g.observations, g.rejected, g.rms, g.unit
        ));
    }
    for n in &out.notes {
        rep.log(format!("  fixed LRF joint: {n}"));
    }
}
