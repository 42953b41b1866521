//! Step 6: the extrinsic, by the paper's sphere method and by the Fan et al. 2019 baseline.
//!
//! **Spheres.** The LRF spheres and the photogrammetric balls are matched without labels
//! ([`pingcal_lrf::correspondence::match_balls`]: distances between balls are the same in
//! both frames); the 3D conformal transform `p_camera = R · p_lrf + t` is estimated on the
//! control balls (all matched balls not listed as check balls) by weighted least squares with
//! the covariances of both sides ([`pingcal_lrf::registration::evaluate`]; σ's scaled by the
//! registration's a-posteriori σ0²) and judged on the
//! check balls (dx = estimated − reference, as the paper's Table 4) and by leave-one-out.
//!
//! **Corner.** [`pingcal_lrf::corner_baseline::fan_baseline`]: the LRF pose in the room
//! corner from one scan's three lines, the camera pose by DLT on the main image, composed.
//! It uses no ball; it is judged on the same check balls (all matched balls when there are
//! no check balls).

use super::bundle::Adjusted;
use super::ids::{PointId, SphereId};
use super::lrf::LrfData;
use super::scene::{main_image, Detections, PointKind, Scene};
use crate::context::{Options, PipelineError, Result};
use crate::progress::Reporter;
use nalgebra::{Matrix3, Vector2, Vector3};
use pingcal_ba::camera::CameraModel;
use pingcal_geometry::{Rigid3, Sim3};
use pingcal_lrf::corner_baseline::{fan_baseline, BaselineInput};
use pingcal_lrf::correspondence::{match_balls, MatchOptions};
use pingcal_lrf::registration::{
    check_table, evaluate, CheckTable, Evaluation, PointObs, RegistrationOptions,
};
use pingcal_project::Project;

/// The corner baseline's outcome.
pub struct CornerOutcome {
    /// LRF → camera.
    pub camera_from_lrf: Sim3,
    /// Its check table.
    pub check: CheckTable,
    /// What the baseline chose and why.
    pub notes: Vec<String>,
}

/// Both methods.
pub struct Extrinsics {
    /// Matched pairs: (LRF sphere, scene point of the ball).
    pub pairs: Vec<(SphereId, PointId)>,
    /// RMS of the matching (mm).
    pub match_rms_mm: f64,
    /// LRF spheres, labelled with their matched ball ids.
    pub lrf_points: Vec<PointObs>,
    /// Camera balls, labelled.
    pub cam_points: Vec<PointObs>,
    /// The sphere method (None when not asked).
    pub spheres: Option<Evaluation>,
    /// The corner baseline (None when not asked), or why it failed.
    pub corner: Option<std::result::Result<CornerOutcome, String>>,
    /// Check balls used.
    pub check_ids: Vec<String>,
    /// Why the methods ran on the cloud through the mount the room's planes gave rather than
    /// the project's (None: the project's, as always unless they failed there; see
    /// `pingcal_pipeline::calibrate`).
    pub through_room: Option<String>,
}

/// The balls of the scene with their positions and covariances from the bundle adjustment.
type CameraBalls = Vec<(PointId, Vector3<f64>, Matrix3<f64>)>;

/// The balls of the scene that the bundle adjustment determined.
fn camera_balls(scene: &Scene, adj: &Adjusted) -> CameraBalls {
    let mut cam_balls = Vec::new();
    for (j, p) in scene.points.iter_enumerated() {
        if p.kind != PointKind::Ball {
            continue;
        }
        let Some(k) = adj.solved.map.point(j) else {
            continue;
        };
        let cov = adj.precision.point_covariances[k.0].unwrap_or(Matrix3::identity());
        cam_balls.push((j, p.position, cov));
    }
    cam_balls
}

/// The LRF spheres matched to the camera balls, by ball name.
struct Matched {
    pairs: Vec<(SphereId, PointId)>,
    rms_mm: f64,
    lrf_points: Vec<PointObs>,
    cam_points: Vec<PointObs>,
}

/// Range offsets tried by [`match_tolerating_range_offset`], mm: a URG's offset reaches
/// centimetres, and the joint adjustment estimates it once the balls are matched.
const RANGE_OFFSETS_TRIED_MM: [f64; 9] = [0.0, -8.0, 8.0, -16.0, 16.0, -24.0, 24.0, -32.0, 32.0];

/// [`match_balls`] on the LRF centres as fitted, and, when that leaves balls unmatched, on
/// the centres corrected for each range offset δ of [`RANGE_OFFSETS_TRIED_MM`]: every beam
/// of a scanner whose ranges are δ too long puts a fixed-radius sphere's centre δ farther
/// along its line of sight, `c' = c − δ c/|c|`, which changes the distances between balls by
/// up to 2δ sin(θ/2) and can defeat the distance invariants. The offset that matches the
/// most balls (then the lowest RMS) wins; the pairs are what is kept, the centres stay as
/// fitted.
fn match_tolerating_range_offset(
    lrf: &[Vector3<f64>],
    cam: &[Vector3<f64>],
    rep: &Reporter,
) -> std::result::Result<pingcal_lrf::correspondence::Matching, pingcal_lrf::LrfError> {
    let first = match_balls(lrf, cam, &MatchOptions::default());
    let all = lrf.len().min(cam.len());
    if first.as_ref().is_ok_and(|m| m.pairs.len() == all) {
        return first;
    }
    let mut best: Option<(f64, pingcal_lrf::correspondence::Matching)> = None;
    for &delta in &RANGE_OFFSETS_TRIED_MM[1..] {
        let moved: Vec<Vector3<f64>> = lrf.iter().map(|c| c - c.normalize() * delta).collect();
        let Ok(m) = match_balls(&moved, cam, &MatchOptions::default()) else {
            continue;
        };
        let better = best
            .as_ref()
            .is_none_or(|(_, b)| (m.pairs.len(), -m.rms_mm) > (b.pairs.len(), -b.rms_mm));
        if better {
            best = Some((delta, m));
        }
    }
    match (first, best) {
        (Ok(f), Some((d, b))) if b.pairs.len() > f.pairs.len() => {
            rep.log(format!("  correspondence: {} balls matched with the LRF centres corrected for a range offset of {d:+.0} mm (against {} as fitted)", b.pairs.len(), f.pairs.len()));
            Ok(b)
        }
        (Err(_), Some((d, b))) => {
            rep.log(format!("  correspondence: matched only with the LRF centres corrected for a range offset of {d:+.0} mm: the joint adjustment estimates it"));
            Ok(b)
        }
        (first, _) => first,
    }
}

/// Matches the LRF spheres to the camera balls; fewer than three pairs is an error.
fn match_spheres(
    project: &Project,
    scene: &Scene,
    lrf: &LrfData,
    cam_balls: &CameraBalls,
    rep: &Reporter,
) -> Result<Matched> {
    let f = &project.file;
    let lrf_centres: Vec<Vector3<f64>> = lrf.found.balls.iter().map(|b| b.centre).collect();
    let cam_centres: Vec<Vector3<f64>> = cam_balls.iter().map(|b| b.1).collect();
    let too_few = |n: usize| {
        PipelineError::Data(format!(
            "{}: only {n} balls were found by both sensors (LRF: {} spheres in {}; photographs: {} balls); at least 3 are needed for the extrinsic",
            project.path.display(),
            lrf_centres.len(),
            (f.lrf.scans.iter().map(|s| s.file()).collect::<Vec<_>>()).join(", "),
            cam_centres.len()
        ))
    };
    let matching = match_tolerating_range_offset(&lrf_centres, &cam_centres, rep).map_err(|e| {
        if lrf_centres.len() < 3 || cam_centres.len() < 3 {
            too_few(lrf_centres.len().min(cam_centres.len()))
        } else {
            PipelineError::Data(format!(
                "{}: the LRF spheres cannot be matched to the balls of the photographs: {e}",
                project.path.display()
            ))
        }
    })?;
    if matching.pairs.len() < 3 {
        return Err(too_few(matching.pairs.len()));
    }
    let mut pairs: Vec<(SphereId, PointId)> = matching
        .pairs
        .iter()
        .map(|&(l, c)| (SphereId(l), cam_balls[c].0))
        .collect();
    pairs.sort_by(|a, b| scene.points[a.1].name.cmp(&scene.points[b.1].name));
    let mut lrf_points = Vec::new();
    let mut cam_points = Vec::new();
    for &(l, j) in &pairs {
        let name = scene.points[j].name.clone();
        let b = &lrf.found.balls[l.0];
        lrf_points.push(PointObs {
            id: name.clone(),
            xyz: b.centre,
            cov: b.cov,
        });
        let cb = cam_balls.iter().find(|c| c.0 == j).expect("matched ball");
        cam_points.push(PointObs {
            id: name,
            xyz: cb.1,
            cov: cb.2,
        });
    }
    rep.log(format!(
        "correspondence: {} of {} LRF spheres matched to {} photogrammetric balls, RMS {:.1} mm",
        pairs.len(),
        lrf_centres.len(),
        cam_centres.len(),
        matching.rms_mm
    ));
    Ok(Matched {
        pairs,
        rms_mm: matching.rms_mm,
        lrf_points,
        cam_points,
    })
}

/// The check balls of the project (`check`) that both sensors found (the others are logged).
fn check_balls(check: &[String], m: &Matched, rep: &Reporter) -> Vec<String> {
    let matched: Vec<String> = m.cam_points.iter().map(|p| p.id.clone()).collect();
    let mut check_ids = Vec::new();
    for c in check {
        if matched.contains(c) {
            check_ids.push(c.clone());
        } else {
            rep.log(format!(
                "  check ball {c} was not found by both sensors: it cannot be judged"
            ));
        }
    }
    check_ids
}

/// The sphere method: the registration on the control balls, judged on the check balls
/// (or by leave-one-out without them).
fn sphere_method(
    project: &Project,
    m: &Matched,
    check_ids: &[String],
    rep: &Reporter,
) -> Result<Evaluation> {
    let matched = m.cam_points.len();
    let control = matched - check_ids.len();
    if control < 3 {
        return Err(PipelineError::Data(format!(
            "{}: only {control} control balls are left after taking the check balls ({}) out of the {} matched; at least 3 are needed",
            project.path.display(),
            check_ids.join(", "),
            matched
        )));
    }
    // σ's scaled by the registration's own σ0²: the sphere-fit covariances are nominal
    // (they treat every beam as independent, while one scan line's points share its
    // servo angle error), and 11 control balls give 27 degrees of freedom to estimate σ0
    let ev = evaluate(
        &m.lrf_points,
        &m.cam_points,
        &[],
        check_ids,
        &RegistrationOptions {
            posterior: true,
            ..RegistrationOptions::default()
        },
    )
    .map_err(|e| PipelineError::Adjustment(format!("sphere registration: {e}")))?;
    let table = if ev.check.rows.is_empty() {
        &ev.leave_one_out
    } else {
        &ev.check
    };
    rep.log(format!(
        "spheres: extrinsic from {} control balls, mean check error {:.2} mm (sd {:.2}) on {} balls{}",
        ev.control.rows.len(),
        table.mean_mm,
        table.sd_mm,
        table.rows.len(),
        if ev.check.rows.is_empty() { " (leave-one-out)" } else { "" }
    ));
    Ok(ev)
}

/// What the extrinsic's methods work on: the scene, its adjustment, the LRF's data and the
/// image detections.
pub type Inputs<'a> = (&'a Scene, &'a Adjusted, &'a LrfData, &'a Detections);

/// Runs the methods the project asks for.
pub fn extrinsics(
    project: &Project,
    inputs: Inputs<'_>,
    opts: &Options,
    rep: &Reporter,
) -> Result<Extrinsics> {
    let method = project.file.method;
    run_methods(
        project,
        inputs,
        opts,
        rep,
        method.spheres(),
        method.corner(),
    )
}

/// The matching and the sphere method only (no corner baseline): the joint adjustment's
/// start when it looks at the LRF again through its estimated mount.
pub fn spheres_only(
    project: &Project,
    inputs: Inputs<'_>,
    opts: &Options,
    rep: &Reporter,
) -> Result<Extrinsics> {
    run_methods(project, inputs, opts, rep, true, false)
}

/// The labels of balls the images did not measure where a sphere of `lrf` matched to none of
/// `pairs` lies through `camera_from_lrf` ([`super::matching::unmeasured_labels_at`]).
pub fn unmeasured_labels(
    project: &Project,
    scene: &Scene,
    lrf: &LrfData,
    pairs: &[(SphereId, PointId)],
    camera_from_lrf: &Rigid3,
) -> Vec<String> {
    let unmatched: Vec<Vector3<f64>> = (lrf.found.balls.iter().enumerate())
        .filter(|&(s, _)| !pairs.iter().any(|&(q, _)| q.0 == s))
        .map(|(_, b)| b.centre)
        .collect();
    super::matching::unmeasured_labels_at(project, scene, &unmatched, camera_from_lrf)
}

/// The spheres of `lrf` matched one to one to the balls `balls` (scene point, centre in the
/// photogrammetric frame) that `camera_from_lrf` puts within `radius` of them, nearest pairs
/// first: with the extrinsic and the LRF's model near the truth, a sphere of the right ball
/// is within a few millimetres of it and another ball at least a diameter away, so the rule
/// is unambiguous.
pub fn match_by_extrinsic(
    lrf: &LrfData,
    balls: &[(PointId, Vector3<f64>)],
    camera_from_lrf: &Rigid3,
    radius: f64,
) -> Vec<(SphereId, PointId)> {
    let mut candidates: Vec<(f64, usize, usize)> = Vec::new();
    for (s, ball) in lrf.found.balls.iter().enumerate() {
        let at = camera_from_lrf.transform(&ball.centre);
        for (k, (_, c)) in balls.iter().enumerate() {
            let d = (at - c).norm();
            if d <= radius {
                candidates.push((d, s, k));
            }
        }
    }
    candidates.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
    let (mut sphere_used, mut ball_used) =
        (vec![false; lrf.found.balls.len()], vec![false; balls.len()]);
    let mut pairs = Vec::new();
    for (_, s, k) in candidates {
        if !sphere_used[s] && !ball_used[k] {
            sphere_used[s] = true;
            ball_used[k] = true;
            pairs.push((SphereId(s), balls[k].0));
        }
    }
    pairs.sort_by_key(|&(s, _)| s.0);
    pairs
}

/// The spheres of `lrf` matched to the balls of the bundle by [`match_by_extrinsic`] with
/// `camera_from_lrf` (no sphere method, no corner baseline): how the joint adjustment's
/// later passes re-decide which sphere is which ball as its estimate improves. An error
/// when fewer than three match.
pub fn spheres_by_extrinsic(
    project: &Project,
    scene: &Scene,
    adj: &Adjusted,
    lrf: &LrfData,
    camera_from_lrf: &Rigid3,
    rep: &Reporter,
) -> Result<Extrinsics> {
    let cam_balls = camera_balls(scene, adj);
    let centres: Vec<(PointId, Vector3<f64>)> = cam_balls.iter().map(|b| (b.0, b.1)).collect();
    let radius = 0.5 * project.file.balls.diameter_mm;
    let mut pairs = match_by_extrinsic(lrf, &centres, camera_from_lrf, radius);
    if pairs.len() < 3 {
        return Err(PipelineError::Data(format!(
            "only {} LRF spheres lie within a ball's radius of where the estimated extrinsic puts a ball",
            pairs.len()
        )));
    }
    pairs.sort_by(|a, b| scene.points[a.1].name.cmp(&scene.points[b.1].name));
    let (mut lrf_points, mut cam_points, mut ss) = (Vec::new(), Vec::new(), 0.0);
    for &(l, j) in &pairs {
        let name = scene.points[j].name.clone();
        let b = &lrf.found.balls[l.0];
        let cb = cam_balls.iter().find(|c| c.0 == j).expect("matched ball");
        ss += (camera_from_lrf.transform(&b.centre) - cb.1).norm_squared();
        lrf_points.push(PointObs {
            id: name.clone(),
            xyz: b.centre,
            cov: b.cov,
        });
        cam_points.push(PointObs {
            id: name,
            xyz: cb.1,
            cov: cb.2,
        });
    }
    let m = Matched {
        rms_mm: (ss / pairs.len() as f64).sqrt(),
        pairs,
        lrf_points,
        cam_points,
    };
    rep.log(format!(
        "correspondence by the estimated extrinsic: {} of {} LRF spheres within a ball's radius of a ball, RMS {:.1} mm",
        m.pairs.len(),
        lrf.found.balls.len(),
        m.rms_mm
    ));
    let check_ids = check_balls(&project.file.balls.check, &m, rep);
    Ok(Extrinsics {
        pairs: m.pairs,
        match_rms_mm: m.rms_mm,
        lrf_points: m.lrf_points,
        cam_points: m.cam_points,
        spheres: None,
        corner: None,
        check_ids,
        through_room: None,
    })
}

/// The matching, then the sphere method and the corner baseline where asked.
fn run_methods(
    project: &Project,
    (scene, adj, lrf, dets): Inputs<'_>,
    opts: &Options,
    rep: &Reporter,
    with_spheres: bool,
    with_corner: bool,
) -> Result<Extrinsics> {
    let f = &project.file;
    let cam_balls = camera_balls(scene, adj);
    let m = match_spheres(project, scene, lrf, &cam_balls, rep)?;
    let check_ids = check_balls(&f.balls.check, &m, rep);
    let spheres = if with_spheres {
        Some(sphere_method(project, &m, &check_ids, rep)?)
    } else {
        None
    };
    let corner = if with_corner {
        let r = corner_method(project, scene, lrf, dets, opts, &m, &check_ids);
        match &r {
            Ok(c) => rep.log(format!(
                "corner baseline: mean check error {:.2} mm (sd {:.2}) on {} balls",
                c.check.mean_mm,
                c.check.sd_mm,
                c.check.rows.len()
            )),
            Err(e) => {
                if !with_spheres {
                    return Err(PipelineError::Adjustment(format!("corner baseline: {e}")));
                }
                rep.log(format!("corner baseline failed: {e}"));
            }
        }
        Some(r)
    } else {
        None
    };
    Ok(Extrinsics {
        pairs: m.pairs,
        match_rms_mm: m.rms_mm,
        lrf_points: m.lrf_points,
        cam_points: m.cam_points,
        spheres,
        corner,
        check_ids,
        through_room: None,
    })
}

fn corner_method(
    project: &Project,
    scene: &Scene,
    lrf: &LrfData,
    dets: &Detections,
    opts: &Options,
    m: &Matched,
    check_ids: &[String],
) -> std::result::Result<CornerOutcome, String> {
    let (lrf_points, cam_points) = (&m.lrf_points, &m.cam_points);
    let Some((header, scans)) = &lrf.scans else {
        return Err("it needs the scan lines (a pingcal-scan CSV), not a point cloud".into());
    };
    let main = main_image(project);
    let c = scene.camera_of[main];
    let targets: Vec<(String, Vector3<f64>)> = scene
        .points
        .iter()
        .filter(|p| p.kind != PointKind::Ball)
        .map(|p| (p.name.clone(), p.position))
        .collect();
    let mut main_image = Vec::new();
    for p in scene.points.iter().filter(|p| p.kind != PointKind::Ball) {
        for &d in &p.obs {
            if d.image != main {
                continue;
            }
            let t = dets.target(d);
            if let Some(r) =
                scene.cameras[c].unproject(&scene.intrinsics[c], &Vector2::new(t.x, t.y))
            {
                if r.y > 0.0 {
                    main_image.push((p.name.clone(), Vector2::new(r.x / r.y, r.z / r.y)));
                }
            }
        }
    }
    // the rough camera←LRF rotation the baseline's prior needs: that of the matched control
    // balls (the LRF need not look the way the camera does), or the identity (Fan's setting)
    let control = |set: &[PointObs]| -> Vec<Vector3<f64>> {
        set.iter()
            .filter(|p| !check_ids.contains(&p.id))
            .map(|p| p.xyz)
            .collect()
    };
    let rough =
        pingcal_lrf::registration::umeyama(&control(lrf_points), &control(cam_points), None, false)
            .map_or_else(|_| Matrix3::identity(), |s| s.rotation);
    let l = &project.file.lrf;
    let input = BaselineInput {
        header,
        scans,
        mount: &lrf.mount,
        range_sigma_mm: l.accuracy_near_mm / 3.0,
        targets: &targets,
        main_image: &main_image,
        seed: opts.seed,
        rough_camera_from_lrf: rough,
    };
    let res = fan_baseline(&input).map_err(|e| e.to_string())?;
    let ids: Vec<&String> = if check_ids.is_empty() {
        cam_points.iter().map(|p| &p.id).collect()
    } else {
        check_ids.iter().collect()
    };
    let pick = |set: &[PointObs]| -> Vec<PointObs> {
        ids.iter()
            .filter_map(|id| set.iter().find(|p| &p.id == *id).cloned())
            .collect()
    };
    let check = check_table(&res.camera_from_lrf, &pick(lrf_points), &pick(cam_points));
    Ok(CornerOutcome {
        camera_from_lrf: res.camera_from_lrf,
        check,
        notes: res.notes,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use pingcal_geometry::opk::from_opk_deg;
    use pingcal_lrf::ball_finder::{Ball, FindResult};

    /// A camera-from-LRF transform of a few degrees about each axis and a few hundred mm.
    fn camera_from_lrf() -> Rigid3 {
        Rigid3::new(
            from_opk_deg([3.0, -5.0, 7.0]),
            Vector3::new(120.0, -80.0, 45.0),
        )
    }

    /// Eight balls around the LRF (LRF frame, mm): every 45° of azimuth, at 1.4–2.6 m and
    /// heights of ±0.4 m, so that no two are alike.
    fn balls_around_the_lrf() -> Vec<Vector3<f64>> {
        (0..8)
            .map(|k| {
                let a = f64::from(k) * std::f64::consts::FRAC_PI_4 + 0.1;
                let r = 1400.0 + 170.0 * f64::from(k);
                let z = 400.0 * (1.3 * f64::from(k)).sin();
                Vector3::new(r * a.cos(), r * a.sin(), z)
            })
            .collect()
    }

    /// The LRF's data with a sphere at each of `centres` (LRF frame) and nothing else.
    fn lrf_with_spheres(centres: &[Vector3<f64>]) -> LrfData {
        let balls = (centres.iter())
            .map(|c| Ball {
                centre: *c,
                cov: Matrix3::identity(),
                inliers: Vec::new(),
                cluster_points: 0,
                rejected_points: 0,
                sigma0: 1.0,
                range_mm: c.norm(),
                support: Default::default(),
            })
            .collect();
        LrfData {
            cloud: Default::default(),
            found: FindResult {
                balls,
                ..FindResult::default()
            },
            scans: None,
            mount: Default::default(),
            noise: Default::default(),
        }
    }

    /// Ranges 32 mm too long move every sphere's centre 32 mm along its line of sight, which
    /// changes the distances between balls on opposite sides by up to 64 mm, beyond the
    /// distance invariants' 20 mm: matched as fitted, the balls are not all paired; with the
    /// offsets tried, every LRF sphere is paired with its own ball (the camera's list in
    /// another order) and the log names the offset.
    #[test]
    fn ranges_too_long_by_a_constant_still_match_every_ball() {
        let lrf_true = balls_around_the_lrf();
        let t = camera_from_lrf();
        // the camera's list in another order: cam[k] is ball order[k]
        let order = [5, 2, 7, 0, 3, 6, 1, 4];
        let cam: Vec<Vector3<f64>> = order.iter().map(|&k| t.transform(&lrf_true[k])).collect();
        let long: Vec<Vector3<f64>> = (lrf_true.iter())
            .map(|c| c + c.normalize() * 32.0)
            .collect();
        let as_fitted = match_balls(&long, &cam, &MatchOptions::default());
        assert!(
            as_fitted.as_ref().map_or(true, |m| m.pairs.len() < 8),
            "the offset should defeat the invariants: {as_fitted:?}"
        );
        let rep = Reporter::silent();
        let m = match_tolerating_range_offset(&long, &cam, &rep).expect("matched");
        let mut pairs = m.pairs.clone();
        pairs.sort();
        let truth: Vec<(usize, usize)> = (0..8)
            .map(|l| (l, order.iter().position(|&k| k == l).expect("in order")))
            .collect();
        assert_eq!(pairs, truth);
        assert!(m.rms_mm < 1e-6, "exact after the correction: {}", m.rms_mm);
        let lines = rep.lines();
        assert!(
            lines.iter().any(|l| l.contains("range offset of +32 mm")),
            "{lines:?}"
        );
    }

    /// Through a known extrinsic each sphere takes the ball it lands on, nearest first, one
    /// to one: of two spheres within reach of one ball the nearer takes it, a sphere 60 mm
    /// from every ball (beyond the 19 mm reach) takes none, and a ball no sphere reaches
    /// stays unpaired.
    #[test]
    fn spheres_take_the_balls_they_land_on_nearest_first_one_to_one() {
        let t = camera_from_lrf();
        let inv = t.inverse();
        let balls: Vec<(PointId, Vector3<f64>)> = (balls_around_the_lrf().iter().take(4))
            .enumerate()
            .map(|(k, c)| (PointId(k), t.transform(c)))
            .collect();
        let at = |k: usize, off: Vector3<f64>| inv.transform(&(balls[k].1 + off));
        let lrf = lrf_with_spheres(&[
            at(2, Vector3::new(0.0, 0.0, 3.0)),
            at(0, Vector3::new(8.0, 0.0, 0.0)),
            at(0, Vector3::new(0.0, 2.0, 0.0)),
            at(1, Vector3::new(0.0, 0.0, -5.0)),
            at(3, Vector3::new(60.0, 0.0, 0.0)),
        ]);
        let pairs = match_by_extrinsic(&lrf, &balls, &t, 19.0);
        assert_eq!(
            pairs,
            vec![
                (SphereId(0), PointId(2)),
                (SphereId(2), PointId(0)),
                (SphereId(3), PointId(1)),
            ]
        );
    }
}
