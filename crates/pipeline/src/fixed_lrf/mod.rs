//! Steps 5–7 for a fixed 2D LRF (`[lrf] kind = "fixed"`): a scanner bolted to the head,
//! its scans taken at stations of the head whose images orient it in the field, calibrated
//! in one joint adjustment with the photographs.
//!
//! 1. **Stations** (`stations`): each scan file with its station's main image; the image's
//!    pose from the bundle places the head there.
//! 2. **The field's planes** (`planes`): the walls, floor and ceiling the targets define,
//!    found among the adjusted targets; each plane's flatness (its targets' RMS about it)
//!    is measured and named, not assumed.
//! 3. **The start** (`start`): Fan et al. 2019's single shot of the room corner
//!    (`pingcal_lrf::corner_baseline`) at every station whose scan sees two walls and the
//!    floor, and the 24 axis-aligned turns, each refined on the planes; the one that puts
//!    the most beams on them.
//! 4. **The adjustment** (`adjust`): the bundle's final problem (poses, targets, balls,
//!    intrinsics all unknown) with the extrinsic, the range model (offset `k`, scale `s`)
//!    and a plane block per plane; observations: the beams on the planes and on the
//!    control balls ([`pingcal_lrf::fixed::FixedBeamOn`]: the range the ray predicts, the
//!    ball's side of the scan plane decided by the photogrammetric ball) and each plane's
//!    targets on it ([`pingcal_lrf::fixed::PointOnPlane`]). What the data do not determine
//!    (a horizontal scan plane that meets only vertical walls cannot fix its height nor its
//!    tilts) is held at the start, named in the log, results.json and the report with
//!    what to add; the verdict is then not `ok`.
//! 5. **Checks** (`outputs`): each ball the scans cut, fitted from one station's beams in
//!    the LRF frame (no extrinsic in it) and compared with the photogrammetric ball in that
//!    station's camera frame through the extrinsic: a row per ball and station, control
//!    and check balls apart.
//!
//! The outcome takes the rotating LRF's shapes ([`LrfData`], [`Extrinsics`],
//! [`JointOutcome`]) so that the verdict, results.json, the report, the overlays and the
//! exports are the same code for both kinds: the cloud is every station's beams through
//! the estimate in the main station's LRF frame.

mod adjust;
mod outputs;
mod planes;
mod start;
mod stations;

pub use adjust::{not_determined, GATE_SIGMAS, MIN_GATE_MM};
pub use planes::{FieldPlane, MIN_PLANE_TARGETS, PLANE_TOL_MM};
pub use start::{axis_turns, GATES_MM};
pub use stations::{read_beams, Station};

use crate::bundle::{Adjusted, OBSERVATION_GROUPS};
use crate::context::{Options, PipelineError, Result};
use crate::extrinsic::Extrinsics;
use crate::head::HeadPoses;
use crate::joint::{JointError, JointOutcome};
use crate::lrf::LrfData;
use crate::progress::Reporter;
use crate::scene::{Detections, PointKind, Scene};
use adjust::{FieldBall, FixedProblem};
use pingcal_ba::solver;
use pingcal_project::Project;

/// The variance-component group of the beams on the planes.
pub const PLANE_GROUP: &str = pingcal_lrf::fixed::FIXED_PLANE_GROUP;
/// The variance-component group of the beams on the balls.
pub const BALL_GROUP: &str = pingcal_lrf::fixed::FIXED_BALL_GROUP;
/// The variance-component group of the targets on the planes.
pub const TARGETS_GROUP: &str = "targets on planes";

/// The names of the extrinsic's unknowns (its left update: rotation vector, translation).
pub const UNKNOWN_NAMES: [&str; 6] = [
    "the extrinsic's rotation about X (ω)",
    "the extrinsic's rotation about Y (φ)",
    "the extrinsic's rotation about Z (κ)",
    "the extrinsic's tx",
    "the extrinsic's ty",
    "the extrinsic's tz",
];

/// The names of the range model's unknowns.
pub const RANGE_NAMES: [&str; 2] = ["range_offset", "range_scale"];

/// σ of the weak priors while what the data determine is tested: the extrinsic's rotation
/// (rad) and translation (mm), the range offset (mm) and scale.
pub const WEAK_PRIOR: [f64; 8] = [0.2, 0.2, 0.2, 500.0, 500.0, 500.0, 100.0, 0.1];

/// What a fixed LRF's calibration gives the later steps: its data, the two-step methods'
/// place (the corner baseline) and the joint adjustment (None when `method = "corner"`).
pub type FixedOutcome = (
    LrfData,
    Extrinsics,
    Option<std::result::Result<JointOutcome, JointError>>,
);

/// Steps 5–7 for a fixed LRF (see the module doc). A joint adjustment that fails is the
/// calibration's failure: a fixed LRF has no two-step result to fall back on.
pub fn calibrate_fixed(
    project: &Project,
    (dets, scene, adj): (&Detections, &Scene, &Adjusted),
    opts: &Options,
    rep: &Reporter,
) -> Result<FixedOutcome> {
    let noise = project.lrf.noise;
    let stations = stations::read_stations(project, scene, &adj.solved, &noise, rep)?;
    let planes = planes::planes_of_targets(scene, opts.seed);
    for (k, pl) in planes.iter().enumerate() {
        rep.log(format!(
            "  fixed LRF: plane {k} of the field: {} targets, flat to {:.2} mm RMS, normal ({:.3}, {:.3}, {:.3})",
            pl.members.len(),
            pl.rms_mm,
            pl.normal.x,
            pl.normal.y,
            pl.normal.z
        ));
    }
    let balls = field_balls(project, scene);
    let sigma = project.file.lrf.accuracy_near_mm / 3.0;
    let corners = start::corner_at_stations(&stations, scene, dets, sigma, opts.seed);
    for (st, r) in &corners {
        match r {
            Ok(e) => rep.log(format!(
                "  fixed LRF: the corner at {st} (Fan et al. 2019): t = ({:.1}, {:.1}, {:.1}) mm",
                e.translation.x, e.translation.y, e.translation.z
            )),
            Err(why) => rep.log(format!("  fixed LRF: no corner at {st}: {why}")),
        }
    }
    let corner = outputs::corner_outcome(project, &stations, (&planes, &balls), &corners);
    if !project.file.method.joint() {
        let e = match &corner {
            Some(Ok(c)) => c.camera_from_lrf.rigid(),
            Some(Err(e)) => return Err(PipelineError::Data(format!("corner baseline: {e}"))),
            None => {
                return Err(PipelineError::Data(
                    "no method asked for the fixed LRF".into(),
                ))
            }
        };
        let data = outputs::lrf_data(project, &stations, &e, [0.0; 2], (&planes, &balls));
        let ext = outputs::extrinsics(project, &data, scene, corner);
        return Ok((data.0, ext, None));
    }
    let starts = start::starts(&stations, &planes, &ball_spheres(&balls, &planes), &corners);
    let best = starts
        .first()
        .ok_or_else(|| PipelineError::Data("the fixed LRF: no start of the adjustment".into()))?;
    rep.log(format!(
        "  fixed LRF: start from {}: {} beams on the planes within {} mm, RMS {:.1} mm",
        best.source,
        best.on_planes,
        GATES_MM[GATES_MM.len() - 1],
        best.rms_mm
    ));
    let mut fp = FixedProblem::build(
        adj,
        scene,
        &stations,
        (&planes, &balls),
        best.camera_from_lrf,
    )?;
    let joint = adjusted(&mut fp, (project, adj), (&stations, &planes, &balls), rep)
        .map_err(|e| PipelineError::Adjustment(e.to_string()))?;
    let (e, range) = (
        joint.camera_from_lrf,
        [
            joint.mount_model.range_offset_mm,
            joint.mount_model.range_scale,
        ],
    );
    let data = outputs::lrf_data(project, &stations, &e, range, (&planes, &balls));
    let ext = outputs::extrinsics(project, &data, scene, corner);
    Ok((data.0, ext, Some(Ok(joint))))
}

/// The balls of the field: every ball the bundle adjusted, a check ball when the project
/// names it in `[balls] check`.
fn field_balls(project: &Project, scene: &Scene) -> Vec<FieldBall> {
    let radius = 0.5 * project.file.balls.diameter_mm;
    (scene.points.iter_enumerated())
        .filter(|(_, p)| p.kind == PointKind::Ball)
        .map(|(j, p)| FieldBall {
            point: j,
            name: p.name.clone(),
            centre: p.position,
            radius,
            check: project.file.balls.check.contains(&p.name),
        })
        .collect()
}

/// Centre and radius of every ball.
fn ball_spheres(balls: &[FieldBall], planes: &[FieldPlane]) -> Vec<planes::BallOnStem> {
    (balls.iter())
        .map(|b| planes::BallOnStem::new(b.centre, b.radius, planes))
        .collect()
}

/// The adjustment's rounds, what the data determine, the rounds again without what they do
/// not, the variance components, and the outcome.
fn adjusted(
    fp: &mut FixedProblem,
    (project, adj): (&Project, &Adjusted),
    field: (&[Station], &[FieldPlane], &[FieldBall]),
    rep: &Reporter,
) -> std::result::Result<JointOutcome, JointError> {
    let fail = |e: PipelineError| JointError::other(e.to_string());
    let mut free = [true; 8];
    let mut held: [Option<String>; 8] = Default::default();
    // the first pass under weak priors (an undetermined unknown would leave the normal
    // equations singular), then held where the data do not determine it, then the final
    // pass without the priors
    let (p, _, mut rejected) = adjust::rounds(fp, &free, true).map_err(fail)?;
    adjust::estimability(fp, &p, &mut free, &mut held).map_err(fail)?;
    for (k, why) in held.iter().enumerate() {
        if let Some(why) = why {
            let name = if k < 6 {
                UNKNOWN_NAMES[k]
            } else {
                RANGE_NAMES[k - 6]
            };
            rep.log(format!("  fixed LRF: {name} held: {why}"));
        }
    }
    let (mut p, _, more) = adjust::rounds(fp, &free, false).map_err(fail)?;
    rejected.iter_mut().zip(more).for_each(|(r, m)| *r += m);
    let chi2s = outputs::group_chi2s(fp, &p);
    let estimate = solver::estimate_variance_components(
        &mut p,
        &fp.options,
        &fp.group_of,
        &OBSERVATION_GROUPS,
    )
    .map_err(|e| JointError::other(format!("fixed LRF adjustment (variance components): {e}")))?;
    let mut out = outputs::joint_outcome(
        fp,
        adj,
        field,
        (&p, &estimate),
        (&free, &held),
        (chi2s, rejected),
    );
    out.head = HeadPoses::of_problem(project, &p, &estimate.precision, Some((fp.ext, "fixed")));
    outputs::log_outcome(&out, rep);
    Ok(out)
}
