//! The whole calibration of one project, one file per step, in the order they run:
//!
//! | step | file | what it does |
//! |---|---|---|
//! | 1 | [`detect`] | targets (coded, plain) and ball silhouettes in every image, in parallel; image sizes checked against their cameras |
//! | 2 | [`network`] | the coded targets' image points → initial orientation of every image (relative start, resection, intersection, bundle), scaled by the distances, moved into the main image's frame |
//! | 3 | [`matching`] | plain targets and balls: known points projected into every image ("driveback"), new points by multi-image epipolar matching; balls told from targets by their size in millimetres |
//! | 4 | [`bundle`] | the final self-calibrating adjustment: distances, stereo rig, main image as datum, ball centres corrected for the sphere's eccentricity, data snooping, precision |
//! | 4b | [`board_camera`] | a project whose field is a board (issue 51): the camera self-calibrated from the board's corners, each placement an image of its own pose, the corners held as control points of the board's frame |
//! | 5 | [`lrf`] | the LRF cloud from the scans and the spheres fitted to the balls |
//! | 6 | [`extrinsic`] | spheres ↔ balls by distance invariants, the 3D conformal transform with σ, control / check / leave-one-out tables; the Fan et al. 2019 corner baseline |
//! | 7 | [`joint`], [`joint_starts`] | the joint adjustment: image points, distances and the LRF beams on the balls together, the extrinsic and the LRF's mount, range errors and servo timing among the unknowns, what the data cannot determine held and named; started from the room's mount, else the project's, with passes through each estimate, the simpler model where the mount is insignificant |
//! | 7b | [`final_lrf`] | the LRF as the calibration's own model sees it: the cloud made again through the joint adjustment's estimated mount and range model, its spheres found and matched by the estimated extrinsic, the check tables from them; every output's LRF side uses it |
//! | 7c | [`verdict`] | whether to trust the calibration: `ok`, `doubtful` or `failed`, by statistical tests of every adjustment and of the check points |
//! | 8 | [`conventions`], [`results`], then [`report`] | `results.json` (docs/formats.md; its `conventions` block names every frame and transform) and `cloud.ply`, then the data of `report.html` |
//! | 9 | [`rectify`], [`exports`] | the same numbers for ROS (tf commands, launch files, URDF joint), OpenCV (FileStorage YAML, stereo rectification as `stereoRectify` gives it) and Kalibr (camchain) |
//! | 10 | [`out_folders`], [`result_set`] | where each project of a run writes (distinct folders for a batch); the output folder: the whole set written beside it and switched in at once under the folder's lock, so a folder never holds a mix of two runs and a user's own files stay |
//!
//! Below the steps lie the modules they share, lowest first: [`ids`] (typed ids and the
//! vector they index), [`progress`] (the [`Reporter`] and the [`Progress`] trait through
//! which the caller shows the progress: the library never prints), [`context`] (the run's
//! [`Options`] and its [`PipelineError`]), [`scene`] (the [`scene::Scene`] that the steps
//! pass along and refine, and the helpers they share) and [`adjust`] (the scene as a
//! bundle-adjustment problem and back, for every step that adjusts). After step 7,
//! [`stages`] gathers what the steps produced for those that judge and write it, and
//! [`outcome`] is what the caller writes. Each module uses only modules before it in
//! `tests/layers.rs`'s `ORDER` (shared modules first, then the steps in their order) and no
//! item of this crate root, which only runs the steps ([`calibrate`]); that test checks it.

//! Every failure is a [`PipelineError`]: one line that names the file, image, target or ball
//! concerned and what was expected, of a kind that says what to do about it (an input to
//! mend, data that do not allow a step, an adjustment that failed). Nothing is written until
//! every step has succeeded.

pub mod adjust;
pub mod board_camera;
pub mod board_lrf;
pub mod bundle;
pub mod context;
pub mod conventions;
pub mod detect;
pub mod exports;
pub mod extrinsic;
pub mod final_lrf;
pub mod fixed_lrf;
pub mod head;
pub mod ids;
pub mod joint;
pub mod joint_starts;
pub mod lrf;
pub mod matching;
pub mod network;
pub mod out_folders;
pub mod outcome;
pub mod overlays;
pub mod progress;
pub mod range_sensors;
pub mod rectify;
pub mod report;
pub mod result_set;
pub mod results;
pub mod scene;
pub mod sphere_calib;
pub mod stages;
#[cfg(test)]
mod test_support;
pub mod verdict;

pub use context::{Options, PipelineError, Result};
pub use joint_starts::{FIRST_PLANE_GATE_MM, JOINT_REFINEMENTS, MODEL_ALPHA};
pub use outcome::Outcome;
pub use progress::{Progress, Reporter, Task};
pub use stages::Stages;

use pingcal_project::Project;

/// Step 6 again on the cloud through the mount the room's planes give, when it `failed` on
/// the project's mount and the joint adjustment is asked for: under a mount error of
/// centimetres and a degree the spheres of the project's cloud may match too few balls to
/// start from (a ball seen twice, centres moved by the range errors), while the room's
/// walls, floor and ceiling give the mount without any ball. The methods then run on that
/// cloud, which [`extrinsic::Extrinsics::through_room`] says with the reason; the joint
/// adjustment's priors stay at the project's mount. None when the joint adjustment is not
/// asked for, the room gives no mount, or step 6 fails there too.
fn through_room(
    project: &Project,
    inputs: extrinsic::Inputs<'_>,
    failed: &PipelineError,
    opts: &Options,
    rep: &Reporter,
) -> Option<(lrf::LrfData, extrinsic::Extrinsics)> {
    let (scene, adjusted, lrf, dets) = inputs;
    if !project.file.method.joint() {
        return None;
    }
    rep.log(format!(
        "the extrinsic through the project's mount failed ({failed}): trying the mount the room's planes give"
    ));
    let room = lrf::room_mount(project, lrf, opts.seed, rep)?;
    let lrf_r = lrf::through_mount(project, lrf, room.mount, opts, rep)?;
    match extrinsic::extrinsics(project, (scene, adjusted, &lrf_r, dets), opts, rep) {
        Ok(mut ext) => {
            ext.through_room = Some(format!(
                "the two-step methods and the joint adjustment's start use the LRF cloud through the mount the room's planes gave: through the project's mount, {failed}"
            ));
            Some((lrf_r, ext))
        }
        Err(e) => {
            rep.log(format!(
                "the extrinsic through the room's mount failed too ({e})"
            ));
            None
        }
    }
}

/// Runs the whole calibration of `project`.
pub fn calibrate(project: &Project, opts: &Options, rep: &Reporter) -> Result<Outcome> {
    calibrate_with_groups(project, opts, &joint::BUILT_IN, rep)
}

/// Runs the whole calibration of `project` with the joint adjustment's observation groups
/// that `groups` make ([`joint::BUILT_IN`] and a caller's own: [`joint::groups`] says what a
/// group is).
pub fn calibrate_with_groups(
    project: &Project,
    opts: &Options,
    groups: &[joint::GroupBuilder],
    rep: &Reporter,
) -> Result<Outcome> {
    let mut timing = Vec::new();
    let (dets, scene, adjusted) = camera_side(project, opts, rep, &mut timing)?;
    let camera = (&dets, &scene, &adjusted);
    let others = range_sensors(project, camera, (opts, groups), rep);
    let mut out = range_side(project, camera, (opts, groups), &others, timing, rep)?;
    out.range_sensors = others;
    Ok(out)
}

/// Each of `[[lrfs]]` calibrated against the camera side as its own project's `[lrf]`
/// ([`Project::range_sensors`]), its failure kept as its reason.
fn range_sensors(
    project: &Project,
    camera: (&scene::Detections, &scene::Scene, &bundle::Adjusted),
    settings: (&Options, &[joint::GroupBuilder]),
    rep: &Reporter,
) -> Vec<outcome::RangeSensor> {
    (project.range_sensors.iter())
        .map(|p| {
            let id = p.file.lrf.id().to_string();
            rep.log(format!("range sensor '{id}' ([[lrfs]]):"));
            let outcome =
                range_side(p, camera, settings, &[], Vec::new(), rep).map_err(|e| e.to_string());
            if let Err(e) = &outcome {
                rep.log(format!("range sensor '{id}' was not calibrated: {e}"));
            }
            outcome::RangeSensor {
                id,
                kind: p.file.lrf.kind().as_str().to_string(),
                outcome,
            }
        })
        .collect()
}

/// Steps 5–10 for `project`'s `[lrf]` against the camera side `camera`, with the other
/// range sensors `others` (already calibrated) taken into the verdict and `sensors`.
fn range_side(
    project: &Project,
    camera: (&scene::Detections, &scene::Scene, &bundle::Adjusted),
    (opts, groups): (&Options, &[joint::GroupBuilder]),
    others: &[outcome::RangeSensor],
    mut timing: Vec<(String, f64)>,
    rep: &Reporter,
) -> Result<Outcome> {
    let (dets, scene, adjusted) = camera;
    let mut scene = scene.clone();
    // A step after the bundle that fails while the camera model cannot hold the lens most
    // likely fails because of it: the error says so.
    let blame_lens = |e: PipelineError| match &adjusted.lens_doubt {
        Some(d) => e.map_message(|m| format!("{m}; but first: {d}")),
        None => e,
    };
    if project.file.lrf.kind() == pingcal_project::LrfKind::Fixed {
        let t = std::time::Instant::now();
        let (lrf, ext, joint) =
            fixed_lrf::calibrate_fixed(project, (dets, &scene, adjusted), opts, rep)
                .map_err(blame_lens)?;
        if let Some(Err(e)) = &joint {
            rep.log(format!("joint adjustment failed: {e}"));
        }
        timing.push(("fixed LRF".into(), t.elapsed().as_secs_f64()));
        let camera = (dets, &scene, adjusted);
        let out = (&lrf, &ext.pairs[..]);
        let st = stages(project, camera, (&lrf, &ext, &joint), out);
        return Ok(outputs(&st, others, timing, rep));
    }
    let t = std::time::Instant::now();
    let lrf = lrf::lrf_spheres(project, opts, rep).map_err(blame_lens)?;
    timing.push(("LRF spheres".into(), t.elapsed().as_secs_f64()));
    let t = std::time::Instant::now();
    let prior = lrf.mount;
    let (lrf, ext) = match extrinsic::extrinsics(project, (&scene, adjusted, &lrf, dets), opts, rep)
    {
        Ok(ext) => (lrf, ext),
        Err(e) => match through_room(project, (&scene, adjusted, &lrf, dets), &e, opts, rep) {
            Some((lrf_r, ext_r)) => {
                scene.warnings.extend(ext_r.through_room.clone());
                (lrf_r, ext_r)
            }
            None => return Err(blame_lens(e)),
        },
    };
    timing.push(("extrinsic".into(), t.elapsed().as_secs_f64()));
    let t = std::time::Instant::now();
    let mut joint = if project.file.method.joint() {
        let inputs = (dets, &scene, adjusted);
        let r = joint_starts::run_joint(project, inputs, (&lrf, prior), &ext, (opts, groups), rep);
        if let Err(e) = &r {
            rep.log(format!("joint adjustment failed: {e}"));
        }
        timing.push(("joint adjustment".into(), t.elapsed().as_secs_f64()));
        Some(r)
    } else {
        None
    };
    let remade = match &mut joint {
        Some(Ok(j)) => {
            let t = std::time::Instant::now();
            let check = &project.file.balls.check;
            let r = final_lrf::through_estimate(project, &lrf, &scene, check, j, opts, rep);
            timing.push(("LRF through the estimate".into(), t.elapsed().as_secs_f64()));
            r
        }
        _ => None,
    };
    let (lrf_out, pairs_out) = match &remade {
        Some(r) => (&r.lrf, &r.pairs[..]),
        None => (&lrf, &ext.pairs[..]),
    };
    let camera = (dets, &scene, adjusted);
    let st = stages(project, camera, (&lrf, &ext, &joint), (lrf_out, pairs_out));
    Ok(outputs(&st, others, timing, rep))
}

/// What the steps produced, for those that judge and write it: the camera's side, the LRF's
/// (its data, the two-step methods, the joint adjustment) and the LRF data the outputs use.
#[allow(clippy::type_complexity)]
fn stages<'a>(
    project: &'a Project,
    (dets, scene, adjusted): (
        &'a scene::Detections,
        &'a scene::Scene,
        &'a bundle::Adjusted,
    ),
    (lrf, ext, joint): (
        &'a lrf::LrfData,
        &'a extrinsic::Extrinsics,
        &'a Option<std::result::Result<joint::JointOutcome, joint::JointError>>,
    ),
    (lrf_out, pairs_out): (&'a lrf::LrfData, &'a [(ids::SphereId, ids::PointId)]),
) -> Stages<'a> {
    Stages {
        project,
        dets,
        scene,
        adjusted,
        lrf,
        ext,
        joint,
        lrf_out,
        pairs_out,
    }
}

/// Steps 1–4, the camera's side: detection, the initial network, matching and the final
/// bundle adjustment (with its doubt about the lens, logged and warned), each step's time
/// pushed on `timing`.
fn camera_side(
    project: &Project,
    opts: &Options,
    rep: &Reporter,
    timing: &mut Vec<(String, f64)>,
) -> Result<(scene::Detections, scene::Scene, bundle::Adjusted)> {
    let t0 = std::time::Instant::now();
    let dets = detect::detect_all(project, opts, rep)?;
    timing.push(("detection".to_string(), t0.elapsed().as_secs_f64()));
    let t = std::time::Instant::now();
    let mut scene = network::initial_network(project, &dets, opts, rep)?;
    timing.push(("initial orientation".into(), t.elapsed().as_secs_f64()));
    let t = std::time::Instant::now();
    matching::add_points(project, &dets, &mut scene, opts, rep)?;
    timing.push(("matching".into(), t.elapsed().as_secs_f64()));
    let t = std::time::Instant::now();
    let mut adjusted = bundle::final_adjustment(project, &dets, &mut scene, opts, rep)?;
    adjusted.lens_doubt = verdict::lens_doubt(project, &adjusted);
    if let Some(w) = &adjusted.lens_doubt {
        rep.log(format!("warning: {w}"));
        scene.warnings.push(w.clone());
    }
    timing.push(("bundle adjustment".into(), t.elapsed().as_secs_f64()));
    Ok((dets, scene, adjusted))
}

/// The verdict, the overlays, results.json, the report, the cloud and the exports of the
/// stages (`timing`: each step's time, logged and kept in the results).
fn outputs(
    stages: &Stages,
    others: &[outcome::RangeSensor],
    mut timing: Vec<(String, f64)>,
    rep: &Reporter,
) -> Outcome {
    let line = timing
        .iter()
        .map(|(n, s)| format!("{n} {s:.2} s"))
        .collect::<Vec<_>>()
        .join(", ");
    rep.log(format!("time: {line}"));
    let mut verdict = verdict::judge(stages);
    range_sensors::judge(&mut verdict, others);
    let expected_check_error_mm = verdict::expected_check_error_mm(stages);
    rep.log(format!(
        "verdict: {}{}",
        verdict.status.as_str(),
        if verdict.reasons.is_empty() {
            String::new()
        } else {
            format!(" ({})", verdict.reasons.join("; "))
        }
    ));
    let t = std::time::Instant::now();
    let drawn = overlays::draw(stages, rep);
    let secs = t.elapsed().as_secs_f64();
    rep.log(format!("time: overlays {secs:.2} s"));
    timing.push(("overlays".into(), secs));
    let mut results = results::assemble(stages, verdict, timing);
    let head = match stages.joint {
        Some(Ok(j)) => Some(j.head.clone()),
        _ => None,
    };
    range_sensors::add_sensors(&mut results, others);
    let base = &stages.adjusted.solved.problem;
    range_sensors::joint_pairs(
        &mut results,
        (head.as_ref(), others),
        (base.parameters.len(), base.residuals.len()),
    );
    let losses: Vec<_> = results.cameras.iter().map(exports::export_loss).collect();
    let loss_rows = exports::report_rows(&results, &losses);
    let mut report = report::build(stages, &results, drawn.report, loss_rows, rep);
    report.summary.extend(range_sensors::summary(others));
    let diameter = stages.project.file.balls.diameter_mm;
    let cloud_ply = results::cloud_ply(stages.lrf_out, 0.5 * diameter);
    let exports = exports::exports(&results, &losses);
    Outcome {
        results,
        report,
        cloud_ply,
        exports,
        expected_check_error_mm,
        overlays: drawn.files,
        range_sensors: Vec::new(),
        head,
    }
}
