//! Step 2: the initial network from the coded targets alone.
//!
//! Every coded target read in two or more images becomes a point; the incremental
//! initialiser of `pingcal-ba` ([`pingcal_ba::initial::incremental`]) starts from the best
//! relatively oriented image pair, resects and intersects the rest with bundle adjustments
//! between rounds (self-calibrating once three images are oriented), rejects gross errors
//! and scales the network by the measured distances. The result is moved into the
//! photogrammetric frame (docs/formats.md, "Frames"): the main image's camera frame (origin at its
//! projection centre, X right, Y forward, Z up).

use super::adjust::{rig_cameras, Datum, SceneProblem};
use super::ids::{DetectionId, IdVec, ImageId, PointId};
use super::scene::{
    coded_blunder, image_file, main_image, CodedBlunder, Detections, PointKind, Scene, ScenePoint,
};
use crate::context::{Options, PipelineError, Result};
use crate::progress::Reporter;
use nalgebra::{Matrix3, Vector3};
use pingcal_ba::initial::incremental::{initialise, IncrementalOptions, Initialised};
use pingcal_ba::problem::{PointPrior, Problem};
use pingcal_ba::solver;
use pingcal_ba::{ImageKey, PointKey};
use pingcal_geometry::rigid::Sim3;
use pingcal_geometry::umeyama::umeyama;
use pingcal_geometry::Rigid3;
use pingcal_project::Project;
use pingcal_targets::TargetKind;
use std::collections::{BTreeMap, BTreeSet};

/// The initial network, in the photogrammetric frame, scaled by the distances.
pub fn initial_network(
    project: &Project,
    dets: &Detections,
    opts: &Options,
    rep: &Reporter,
) -> Result<Scene> {
    let f = &project.file;
    let seen = coded_tracks(dets);
    enough_coded_targets(project, seen.len())?;
    let start = starting_scene(project, &seen);
    let sp = SceneProblem::build(project, dets, &start, Datum::Free, &[]);
    scaled_by_a_distance(project, &sp)?;
    let mut options = IncrementalOptions {
        bundle: solver::Options {
            max_iterations: 50,
            threads: opts.threads,
            ..solver::Options::default()
        },
        ..IncrementalOptions::default()
    };
    let min_angle = f.network.min_intersection_angle_deg;
    options.intersection.min_angle_deg = min_angle;
    let pb = rep.task("orienting images", 1);
    let (start_used, init, scene, failed) =
        first_start(project, dets, &sp, start, opts.start, &options)?;
    pb.finish();
    for s in &init.steps {
        rep.log(format!("  {s}"));
    }
    let mut scene = scene;
    let removed = coincident_coded(project, dets, &mut scene);
    if removed > 0 {
        rep.log(format!(
            "  {removed} coded point(s) removed: another coded point lies within its code ring"
        ));
    }
    log_blunders(project, dets, &scene, 0, rep);
    note_refused_by_angle(&init, min_angle, &mut scene, rep);
    scene.start = start_used.describe().into();
    scene.warnings = failed;
    log_network(project, &scene, &init, rep);
    Ok(scene)
}

/// An error unless at least 5 coded targets (`seen` of them) were read in two or more
/// images: fewer cannot orient the images.
fn enough_coded_targets(project: &Project, seen: usize) -> Result<()> {
    if seen < 5 {
        return Err(PipelineError::Data(format!(
            "{}: only {} coded targets were read in two or more images; at least 5 are needed to orient the images (are the targets {} and large enough in the images?)",
            project.path.display(),
            seen,
            project.file.targets.family
        )));
    }
    Ok(())
}

/// An error unless a measured distance of `sp` joins two of its coded targets: without
/// one the network's scale is undefined.
fn scaled_by_a_distance(project: &Project, sp: &SceneProblem) -> Result<()> {
    if sp.problem.distances.is_empty() {
        let list: Vec<String> = (project.file.distances.iter())
            .map(|d| format!("{}–{}", d.from, d.to))
            .collect();
        return Err(PipelineError::Data(format!(
            "{}: no measured distance joins two coded targets read in two or more images ([[distances]]: {}); the scale of the network is undefined",
            project.path.display(),
            if list.is_empty() { "none".into() } else { list.join(", ") }
        )));
    }
    Ok(())
}

/// Logs the coded targets that the initialiser left out because their rays meet at under
/// `min_angle` degrees, and adds that to the reason of every image left unoriented (it may
/// be so for want of them).
fn note_refused_by_angle(init: &Initialised, min_angle: f64, scene: &mut Scene, rep: &Reporter) {
    if init.refused_by_angle.is_empty() {
        return;
    }
    let list: Vec<String> = (init.refused_by_angle.iter())
        .map(|(name, a)| format!("{name} ({a:.2}°)"))
        .collect();
    let why = format!(
        "{} coded target(s) left out of the network: their rays meet at under {min_angle}° ([network] min_intersection_angle_deg)",
        list.len()
    );
    rep.log(format!("  {why}: {}", list.join(", ")));
    for (_, reason) in &mut scene.unoriented {
        reason.push_str(&format!("; {why}"));
    }
}

/// Logs the network's warnings, the images left unoriented and why, and one line of how it
/// started, how many images and points it has and its RMS.
fn log_network(project: &Project, scene: &Scene, init: &Initialised, rep: &Reporter) {
    for w in &scene.warnings {
        rep.log(format!("warning: {w}"));
    }
    for (i, why) in &scene.unoriented {
        rep.log(format!(
            "  image {} not oriented: {why}",
            image_file(project, *i)
        ));
    }
    rep.log(format!(
        "initial network from {}: {} of {} images oriented, {} coded targets, RMS {:.3} px",
        scene.start,
        scene.oriented().len(),
        scene.poses.len(),
        scene.points.len(),
        init.problem.rms_px()
    ));
}

pub use crate::context::Start;

/// The starts to try for `asked`, in order: in `auto`, the layout's when the project names
/// one, the relative orientation, then the stereo head's when there is one.
fn starts_to_try(project: &Project, asked: Start) -> Result<Vec<Start>> {
    let layout = project.layout.is_some();
    let stereo = project.file.stereo.is_some();
    let refuse = |what: &str| {
        Err(PipelineError::Input(format!(
            "{}: --start {what}",
            project.path.display()
        )))
    };
    match asked {
        Start::Auto => Ok([Start::Layout, Start::Relative, Start::Stereo]
            .into_iter()
            .filter(|s| match s {
                Start::Layout => layout,
                Start::Stereo => stereo,
                _ => true,
            })
            .collect()),
        Start::Layout if !layout => refuse("layout: the project names no [targets] layout"),
        Start::Stereo if !stereo => refuse("stereo: the project has no [stereo] head"),
        s => Ok(vec![s]),
    }
}

/// A start that orients every image with its coded targets' image residuals above this RMS
/// (px) is suspect: a good network of the simulated field fits them to 0.016–0.019 px, and a
/// relative orientation that fell into another minimum (blur 0.9, seed 10 of
/// bench/robustness) to 5.8 px, which then took 36 plain targets for balls. In `auto` the
/// remaining starts are tried too and the lowest RMS kept (each costs about 0.1 s).
pub const SUSPECT_START_RMS_PX: f64 = 1.0;

/// The first start of [`starts_to_try`] that orients every image at an RMS of at most
/// [`SUSPECT_START_RMS_PX`] (else the first that orients the most images, unless its RMS is
/// suspect and a later one orients as many at a lower RMS): which one, the initialiser's
/// solution and the scene in the main image's frame, and one warning for each start that
/// failed or was passed over. When none works, the error gives each one's reason and what
/// the project could add.
fn first_start(
    project: &Project,
    dets: &Detections,
    sp: &SceneProblem,
    start: Scene,
    asked: Start,
    options: &IncrementalOptions,
) -> Result<(Start, Initialised, Scene, Vec<String>)> {
    let mut failed = Vec::new();
    let mut passed_over = Vec::new();
    let mut best: Option<(Start, Initialised, Scene)> = None;
    for s in starts_to_try(project, asked)? {
        let tried = try_start(s, project, sp, options).and_then(|init| {
            into_main_frame(project, dets, start.clone(), sp, &init)
                .map(|scene| (init, scene))
                .map_err(|e| e.to_string())
        });
        match tried {
            Ok((init, scene)) => {
                if keep_if_better(&mut best, (s, init, scene), &mut passed_over) {
                    break;
                }
            }
            Err(e) => failed.push(format!("{} failed ({e})", s.describe())),
        }
    }
    if let Some((s, init, _)) = &best {
        let rms = init.problem.rms_px();
        if rms > SUSPECT_START_RMS_PX {
            passed_over.push(format!(
                "its coded targets fit at RMS {rms:.3} px, more than the {SUSPECT_START_RMS_PX} px of a sound start: {} may have found another minimum, and no other start did better",
                s.describe()
            ));
        }
    }
    if let Some((s, init, scene)) = best {
        let warnings = (failed.iter().chain(&passed_over))
            .map(|f| format!("the network started from {}: {f}", s.describe()))
            .collect();
        return Ok((s, init, scene, warnings));
    }
    Err(no_start(project, asked, &failed))
}

/// A start that worked, with its initialiser's solution and its scene.
type Started = (Start, Initialised, Scene);

/// Makes `tried` the `best` start when there is none yet, when it orients more images, or
/// when the best one's RMS is suspect and `tried` orients as many at a lower RMS (which
/// `passed_over` then says). True when the best start now orients every image at an RMS
/// of at most [`SUSPECT_START_RMS_PX`]: no later start is tried.
fn keep_if_better(
    best: &mut Option<Started>,
    tried: Started,
    passed_over: &mut Vec<String>,
) -> bool {
    let (s, init, scene) = tried;
    let (rms, n) = (init.problem.rms_px(), scene.oriented().len());
    // as many images as the suspect start before it, at a lower RMS
    let lower = |b: &Started| {
        let rms_b = b.1.problem.rms_px();
        n == b.2.oriented().len() && rms_b > SUSPECT_START_RMS_PX && rms < rms_b
    };
    let better = best
        .as_ref()
        .is_none_or(|b| n > b.2.oriented().len() || lower(b));
    if let Some(b) = best.as_ref().filter(|b| lower(b)) {
        passed_over.push(format!(
            "{} oriented {} images at RMS {:.3} px; {} oriented {} at RMS {:.3} px, which is kept",
            b.0.describe(),
            b.2.oriented().len(),
            b.1.problem.rms_px(),
            s.describe(),
            n,
            rms
        ));
    }
    if better {
        *best = Some((s, init, scene));
    }
    let done =
        |b: &Started| b.2.unoriented.is_empty() && b.1.problem.rms_px() <= SUSPECT_START_RMS_PX;
    best.as_ref().is_some_and(done)
}

/// The error when no start worked: each one's reason (`failed`) and, in `auto`, what the
/// project could add to start otherwise.
fn no_start(project: &Project, asked: Start, failed: &[String]) -> PipelineError {
    let mut missing = Vec::new();
    if project.layout.is_none() {
        missing.push("name the coded targets' approximate coordinates in [targets] layout");
    }
    if project.file.stereo.is_none() {
        missing.push("describe the stereo head in [stereo] (its nominal baseline starts it)");
    }
    PipelineError::Data(format!(
        "{}: initial orientation: {}{}",
        project.path.display(),
        failed.join("; "),
        if missing.is_empty() || asked != Start::Auto {
            String::new()
        } else {
            format!("; to start otherwise, {}", missing.join(", or "))
        }
    ))
}

/// One start of the initialiser on the coded targets' problem `sp`.
fn try_start(
    s: Start,
    project: &Project,
    sp: &SceneProblem,
    options: &IncrementalOptions,
) -> std::result::Result<Initialised, String> {
    let run = |problem: &Problem, points: &[bool], poses: &[bool]| {
        initialise(problem, points, poses, options).map_err(|e| e.to_string())
    };
    match s {
        Start::Auto | Start::Relative => run(&sp.problem, &[], &[]),
        Start::Layout => {
            let (problem, known) = with_layout(project, sp)?;
            run(&problem, &known, &[])
        }
        Start::Stereo => {
            // the stations whose pairs share the most targets, until one orients every image
            let mut best: Option<Initialised> = None;
            let mut first_error = None;
            for (base, member) in stereo_pairs(project, sp)?
                .into_iter()
                .take(STEREO_PAIRS_TRIED)
            {
                let (problem, known) = with_stereo_pair(project, sp, base, member)?;
                match run(&problem, &[], &known) {
                    Ok(init) => {
                        let n = |i: &Initialised| i.image_map.iter().flatten().count();
                        if best.as_ref().is_none_or(|b| n(&init) > n(b)) {
                            best = Some(init);
                        }
                        if best
                            .as_ref()
                            .is_some_and(|b| b.unoriented_images.is_empty())
                        {
                            break;
                        }
                    }
                    Err(e) => {
                        first_error.get_or_insert(e);
                    }
                }
            }
            best.ok_or_else(|| first_error.unwrap_or_default())
        }
    }
}

/// The most stations whose stereo pair [`Start::Stereo`] tries.
const STEREO_PAIRS_TRIED: usize = 3;

/// The fewest points a start may orient from: layout targets read in two images, or coded
/// targets common to a stereo pair (an image needs four to be resected).
const MIN_START_POINTS: usize = 4;

/// `sp`'s problem with the layout's targets at their layout coordinates, each held by a
/// prior of `layout_sigma_mm`; and which points are known.
fn with_layout(
    project: &Project,
    sp: &SceneProblem,
) -> std::result::Result<(Problem, Vec<bool>), String> {
    let layout = project.layout.as_ref().ok_or("no [targets] layout")?;
    let sigma = project.file.targets.layout_sigma_mm;
    let mut problem = sp.problem.clone();
    let mut known = vec![false; problem.points.len()];
    for (k, pt) in problem.points.iter_mut().enumerate() {
        let Some(xyz) = pt.name.parse().ok().and_then(|id| layout.points.get(&id)) else {
            continue;
        };
        pt.position = Vector3::from(*xyz);
        known[k] = true;
        problem.point_priors.push(PointPrior {
            point: PointKey(k),
            position: pt.position,
            sigma: Vector3::repeat(sigma),
        });
    }
    let n = known.iter().filter(|k| **k).count();
    if n < MIN_START_POINTS {
        return Err(format!(
            "{n} of the {} coded targets read in two or more images are in the layout, {MIN_START_POINTS} or more are needed",
            known.len()
        ));
    }
    Ok((problem, known))
}

/// The stations' stereo pairs (base and member problem images) that share four or more
/// coded targets, those sharing the most first.
fn stereo_pairs(
    project: &Project,
    sp: &SceneProblem,
) -> std::result::Result<Vec<(ImageKey, ImageKey)>, String> {
    let f = &project.file;
    let (base_cam, member_cam) = rig_cameras(project).ok_or("no [stereo] head")?;
    let slot = |station: &str, cam: &str| {
        f.images
            .iter()
            .position(|im| im.station == station && im.camera == cam)
            .and_then(|i| sp.map.image(ImageId(i)))
    };
    let seen = |i: ImageKey| -> BTreeSet<PointKey> {
        sp.problem
            .observations
            .iter()
            .filter(|o| o.image == i)
            .map(|o| o.point)
            .collect()
    };
    let stations: BTreeSet<&str> = f.images.iter().map(|im| im.station.as_str()).collect();
    let mut pairs: Vec<(usize, ImageKey, ImageKey)> = stations
        .iter()
        .filter_map(|st| Some((slot(st, base_cam)?, slot(st, member_cam)?)))
        .map(|(a, b)| (seen(a).intersection(&seen(b)).count(), a, b))
        .filter(|(n, _, _)| *n >= MIN_START_POINTS)
        .collect();
    if pairs.is_empty() {
        return Err("no station's stereo pair shares 4 or more coded targets".into());
    }
    pairs.sort_by_key(|(n, a, _)| (std::cmp::Reverse(*n), *a));
    Ok(pairs.into_iter().map(|(_, a, b)| (a, b)).collect())
}

/// `sp`'s problem with the stereo pair's `base` and `member` images at the head's nominal
/// pose (base at the origin, member offset by the baseline along X, no rotation between
/// them); and which poses are known.
fn with_stereo_pair(
    project: &Project,
    sp: &SceneProblem,
    base: ImageKey,
    member: ImageKey,
) -> std::result::Result<(Problem, Vec<bool>), String> {
    let stereo = project.file.stereo.as_ref().ok_or("no [stereo] head")?;
    let (base_cam, _) = rig_cameras(project).ok_or("no [stereo] head")?;
    // The right camera's centre in the left camera's frame is (baseline, 0, 0).
    let sign = if base_cam == stereo.left { 1.0 } else { -1.0 };
    let member_from_base = Rigid3::from_rotation_and_centre(
        Matrix3::identity(),
        Vector3::new(sign * stereo.baseline_mm, 0.0, 0.0),
    );
    let mut problem = sp.problem.clone();
    problem.images[base].camera_from_object = Rigid3::identity();
    problem.images[member].camera_from_object = member_from_base;
    let mut known = vec![false; problem.images.len()];
    known[base.0] = true;
    known[member.0] = true;
    Ok((problem, known))
}

/// The layout's targets that the adjusted `scene` places more than `LAYOUT_GATE` σ from
/// their layout coordinates once the similarity transform from the layout into the scene is
/// fitted to the others (the worst one left out and the transform fitted again, while it
/// exceeds the gate): one warning each (a wrong id or coordinate in the layout), and one for
/// a scale that differs from the distances' by more than `LAYOUT_SCALE_TOLERANCE`.
pub fn layout_warnings(project: &Project, scene: &Scene) -> Vec<String> {
    let (Some(layout), Some(file)) = (&project.layout, &project.file.targets.layout) else {
        return Vec::new();
    };
    let sigma = project.file.targets.layout_sigma_mm;
    let mut pairs: Vec<(u32, Vector3<f64>, Vector3<f64>)> = scene
        .points
        .iter()
        .filter_map(|p| match p.kind {
            PointKind::Coded(id) => layout
                .points
                .get(&id)
                .map(|xyz| (id, Vector3::from(*xyz), p.position)),
            _ => None,
        })
        .collect();
    let fit = |pairs: &[(u32, Vector3<f64>, Vector3<f64>)]| {
        let (src, dst): (Vec<_>, Vec<_>) = pairs.iter().map(|(_, a, b)| (*a, *b)).unzip();
        umeyama(&src, &dst, None, true).ok()
    };
    // the distance (mm, layout scale) of a pair from where a fit puts it
    let off = |t: &Sim3, (_, a, b): &(u32, Vector3<f64>, Vector3<f64>)| {
        (t.transform(a) - b).norm() / t.scale
    };
    let mut out = Vec::new();
    while let Some(all) = fit(&pairs) {
        let worst =
            (0..pairs.len()).max_by(|&a, &b| off(&all, &pairs[a]).total_cmp(&off(&all, &pairs[b])));
        // the worst point against the transform of the others
        let suspect = worst
            .filter(|_| pairs.len() > MIN_START_POINTS)
            .and_then(|k| {
                let mut others = pairs.clone();
                let p = others.remove(k);
                let d = off(&fit(&others)?, &p);
                (d > LAYOUT_GATE * sigma).then_some((k, d))
            });
        let Some((k, d)) = suspect else {
            if (all.scale - 1.0).abs() > LAYOUT_SCALE_TOLERANCE {
                out.push(format!(
                    "{file}: the layout's scale is {:.4} times the distances': is it in mm?",
                    1.0 / all.scale
                ));
            }
            break;
        };
        out.push(format!(
            "{file}: target {} is {d:.0} mm from where the images put it (layout_sigma_mm = {sigma}): a wrong id or coordinate?",
            pairs[k].0
        ));
        pairs.remove(k);
    }
    out
}

/// How far the layout's scale may be from the distances' before it is doubted (a tape
/// measure over a room is good to a few parts in a thousand).
const LAYOUT_SCALE_TOLERANCE: f64 = 0.02;

/// The distance, in layout σ, beyond which a layout point is doubted: the 99.9 % quantile
/// of a χ distribution with 3 degrees of freedom (√16.27).
const LAYOUT_GATE: f64 = 4.03;

/// Every coded number read in two or more images, with its detections.
fn coded_tracks(dets: &Detections) -> BTreeMap<u32, Vec<DetectionId>> {
    let mut seen: BTreeMap<u32, Vec<DetectionId>> = BTreeMap::new();
    for (i, d) in dets.iter_enumerated() {
        for (k, t) in d.targets.iter_enumerated() {
            if let (TargetKind::Coded, Some(id)) = (t.kind, t.id) {
                seen.entry(id).or_default().push(DetectionId::new(i, k));
            }
        }
    }
    seen.retain(|_, v| v.len() >= 2);
    seen
}

/// The scene the initialiser starts from: one point per coded number, every image taken
/// (the initialiser ignores the starting poses and positions), no datum.
fn starting_scene(project: &Project, seen: &BTreeMap<u32, Vec<DetectionId>>) -> Scene {
    let mut scene = Scene::new(project);
    scene.poses = scene
        .poses
        .iter()
        .map(|_| Some(Rigid3::identity()))
        .collect();
    scene.points = seen
        .iter()
        .map(|(id, obs)| ScenePoint {
            name: id.to_string(),
            kind: PointKind::Coded(*id),
            position: Vector3::zeros(),
            obs: obs.clone(),
        })
        .collect();
    scene
}

/// The initialiser's solution as a scene in the main image's frame: its oriented images, its
/// determined points without the measurements it rejected (two or more left), the
/// intrinsics, and why the other images were not oriented. A coded measurement rejected
/// beyond the reach of its own ring is a named blunder ([`coded_blunder`]).
fn into_main_frame(
    project: &Project,
    dets: &Detections,
    start: Scene,
    sp: &SceneProblem,
    init: &Initialised,
) -> Result<Scene> {
    let f = &project.file;
    let mut scene = start;
    let mut poses: IdVec<ImageId, Option<Rigid3>> = scene.poses.iter().map(|_| None).collect();
    for (k, &i) in sp.map.images.iter().enumerate() {
        poses[i] = init.image_map[k].map(|m| init.problem.images[m].camera_from_object);
    }
    let main = main_image(project);
    let Some(main_pose) = poses[main] else {
        return Err(main_not_oriented(project, init));
    };
    // into the main image's frame: X' = R X + t; image poses P' = P ∘ M⁻¹
    let to_main = main_pose.inverse();
    for p in poses.iter_mut().flatten() {
        *p = p.compose(&to_main);
    }
    let (points, blunders) =
        points_in_main_frame(project, dets, (&scene, sp, init), &poses, &main_pose);
    scene.unoriented = init
        .unoriented_images
        .iter()
        .filter_map(|(name, why)| {
            f.images
                .iter()
                .position(|im| im.file == *name)
                .map(|i| (ImageId(i), why.clone()))
        })
        .collect();
    scene.intrinsics = init
        .problem
        .cameras
        .iter()
        .map(|c| c.params.clone())
        .collect();
    scene.poses = poses;
    scene.points = points;
    for b in blunders {
        scene.add_blunder(b);
    }
    Ok(scene)
}

/// The error when the initialiser left the main image unoriented, with its reason.
fn main_not_oriented(project: &Project, init: &Initialised) -> PipelineError {
    let main = main_image(project);
    let why = init
        .unoriented_images
        .iter()
        .find(|(n, _)| n == image_file(project, main))
        .map(|(_, w)| w.clone())
        .unwrap_or_else(|| "unknown".into());
    PipelineError::Data(format!(
        "{}: the main image could not be oriented: {why}",
        image_file(project, main)
    ))
}

/// The points of `start` that the initialiser determined, moved by `main_pose` into the main
/// image's frame, without the measurements it rejected or of images `poses` leaves
/// unoriented (two or more measurements left); and the named blunders among the coded
/// measurements it rejected ([`coded_blunder`]).
fn points_in_main_frame(
    project: &Project,
    dets: &Detections,
    (start, sp, init): (&Scene, &SceneProblem, &Initialised),
    poses: &IdVec<ImageId, Option<Rigid3>>,
    main_pose: &Rigid3,
) -> (IdVec<PointId, ScenePoint>, Vec<CodedBlunder>) {
    let rejected = |d: &DetectionId, name: &str| {
        let file = image_file(project, d.image);
        (init.rejected_observations.iter())
            .find(|(i, p, _)| i == file && p == name)
            .map(|r| r.2)
    };
    let mut points = IdVec::new();
    let mut blunders = Vec::new();
    for (k, &j) in sp.map.points.iter().enumerate() {
        let p = &start.points[j];
        for (d, off) in p
            .obs
            .iter()
            .filter_map(|d| Some((*d, rejected(d, &p.name)?)))
        {
            if let PointKind::Coded(n) = p.kind {
                blunders.extend(coded_blunder(project, dets, d, n, off, "network start"));
            }
        }
        let Some(m) = init.point_map[k] else { continue };
        let mut p = p.clone();
        p.position = main_pose.transform(&init.problem.points[m].position);
        p.obs
            .retain(|d| poses[d.image].is_some() && rejected(d, &p.name).is_none());
        if p.obs.len() >= 2 {
            points.push(p);
        }
    }
    (points, blunders)
}

/// Logs the named blunders of `scene` from the `from`-th on: one line each.
pub fn log_blunders(
    project: &Project,
    dets: &Detections,
    scene: &Scene,
    from: usize,
    rep: &Reporter,
) {
    for b in scene.blunders.iter().skip(from) {
        let t = dets.target(b.det);
        rep.log(format!(
            "  blunder ({}): coded number {} read in {} at ({:.1}, {:.1}) px is {}: removed",
            b.stage,
            b.number,
            image_file(project, b.det.image),
            t.x,
            t.y,
            b.why
        ));
    }
}

/// Two coded points that the oriented images put on one target are one target read as two
/// numbers: each projects, in an image where the other is measured, within the reach of that
/// measurement's code ring (`ring_outer` times its dot's major semi-axis, in pixels, so that a
/// network of any scale is judged alike). The measurements of the one read in fewer images are
/// named blunders (misreads of the other's number) and it is removed; with as many, both go.
/// Returns how many points were removed.
pub fn coincident_coded(project: &Project, dets: &Detections, scene: &mut Scene) -> usize {
    let ring = project.file.targets.ring_outer;
    let coded: Vec<(PointId, u32)> = (scene.points.ids())
        .filter_map(|j| match scene.points[j].kind {
            PointKind::Coded(n) => Some((j, n)),
            _ => None,
        })
        .collect();
    // whether `q` projects within the ring's reach of a measurement of `p`
    let near = |p: &ScenePoint, q: &ScenePoint| {
        p.obs.iter().any(|&d| {
            let t = dets.target(d);
            scene
                .project_into(d.image, &q.position)
                .is_some_and(|uv| (uv.x - t.x).hypot(uv.y - t.y) < ring * t.ellipse.a)
        })
    };
    let mut gone: BTreeSet<PointId> = BTreeSet::new();
    let mut blunders = Vec::new();
    for (a, &(ja, na)) in coded.iter().enumerate() {
        for &(jb, nb) in &coded[a + 1..] {
            let (pa, pb) = (&scene.points[ja], &scene.points[jb]);
            if !(near(pa, pb) && near(pb, pa)) {
                continue;
            }
            let (la, lb) = (pa.obs.len(), pb.obs.len());
            for (j, n, other, p) in [(ja, na, nb, pa), (jb, nb, na, pb)] {
                let fewer = if j == ja { la <= lb } else { lb <= la };
                if !fewer {
                    continue;
                }
                gone.insert(j);
                for &o in &p.obs {
                    blunders.push(super::scene::CodedBlunder {
                        det: o,
                        number: n,
                        stage: "coincident numbers",
                        why: format!(
                            "where target {other} is: the images put {n} and {other} within a code ring of each other, and {other} is read in {} images, {n} in {}",
                            if n == na { lb } else { la },
                            p.obs.len()
                        ),
                    });
                }
            }
        }
    }
    for b in blunders {
        scene.add_blunder(b);
    }
    for &j in gone.iter().rev() {
        scene.points.remove(j);
    }
    gone.len()
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::adjust::tests::{fixture, project_of, target};
    use crate::scene::ImageMeasurements;
    use pingcal_targets::ellipse::Ellipse;
    use pingcal_targets::Target;

    /// Five images of one camera (1000 × 800 px, principal distance 1000 px) from stations
    /// S0–S4 on an arc 800 mm wide, S2 the main one; the distance between coded targets 1 and
    /// 12 is `{D12}`, replaced by the true one.
    const FIELD: &str = r#"
version = 1
name = "field in memory"
method = "spheres"
main_station = "S2"
main_camera = "cam"
[targets]
family = "aicon14"
dot_radius_mm = 5.0
[balls]
diameter_mm = 38.0
[[cameras]]
id = "cam"
model = "photogrammetric"
width = 1000
height = 800
pixel_size_mm = 0.01
free = []
initial = { c_mm = 10.0 }
[[images]]
file = "s0.png"
camera = "cam"
station = "S0"
[[images]]
file = "s1.png"
camera = "cam"
station = "S1"
[[images]]
file = "s2.png"
camera = "cam"
station = "S2"
[[images]]
file = "s3.png"
camera = "cam"
station = "S3"
[[images]]
file = "s4.png"
camera = "cam"
station = "S4"
[[distances]]
from = 1
to = 12
distance_mm = {D12}
sigma_mm = 0.1
[lrf]
model = "urg"
station = "S2"
scans = ["scan.csv"]
max_range_mm = 4000.0
accuracy_near_mm = 30.0
accuracy_far_fraction = 0.03
"#;

    /// A small field made in memory, in the main image's frame (its camera at the origin,
    /// X right, Y forward, Z up): twelve coded targets 1–12 and six plain targets on an
    /// uneven wall about 2 m ahead, and the true poses of the five images of [`FIELD`].
    pub(crate) struct Field {
        pub project: Project,
        pub poses: Vec<Rigid3>,
        pub coded: Vec<(u32, Vector3<f64>)>,
        pub plain: Vec<Vector3<f64>>,
    }

    impl Field {
        pub(crate) fn new() -> Self {
            let coded: Vec<(u32, Vector3<f64>)> = (1..=12u32)
                .map(|n| {
                    let (col, row) = (f64::from((n - 1) % 4), f64::from((n - 1) / 4));
                    // an uneven wall: depth varies by ±250 mm, no three targets in a line
                    let x = -540.0 + 360.0 * col + 23.0 * row;
                    let z = -300.0 + 300.0 * row - 17.0 * col;
                    let y = 2000.0 + 250.0 * ((0.7 * f64::from(n)).sin());
                    (n, Vector3::new(x, y, z))
                })
                .collect();
            let plain = (0..6)
                .map(|k| {
                    let k = f64::from(k);
                    Vector3::new(-450.0 + 180.0 * k, 1900.0 + 60.0 * k, 150.0 - 70.0 * k)
                })
                .collect();
            let centres = [
                Vector3::new(-800.0, 150.0, 0.0),
                Vector3::new(-400.0, 0.0, 300.0),
                Vector3::zeros(),
                Vector3::new(400.0, 0.0, -300.0),
                Vector3::new(800.0, 150.0, 100.0),
            ];
            let aim = Vector3::new(0.0, 2000.0, 0.0);
            let poses = (centres.iter())
                .map(|c| Rigid3::looking_at(*c, aim, 0.0))
                .collect();
            let d12 = (coded[0].1 - coded[11].1).norm();
            let project = project_of(&FIELD.replace("{D12}", &format!("{d12:.12}")));
            Field {
                project,
                poses,
                coded,
                plain,
            }
        }

        /// A scene of the project with every image at its true pose and no point.
        pub(crate) fn oriented_scene(&self) -> Scene {
            let mut scene = Scene::new(&self.project);
            for (k, pose) in self.poses.iter().enumerate() {
                scene.poses[ImageId(k)] = Some(*pose);
            }
            scene
        }

        /// The detections of the field, exact: in every image, the coded targets then the
        /// plain ones that project into it (`plain`: whether the plain ones are there).
        pub(crate) fn detections(&self, plain: bool) -> Detections {
            let scene = self.oriented_scene();
            (0..self.poses.len())
                .map(|i| {
                    let i = ImageId(i);
                    let coded = (self.coded.iter())
                        .filter_map(|(n, x)| Some(blob(scene.project_into(i, x)?, Some(*n))));
                    let plains = (self.plain.iter().filter(|_| plain))
                        .filter_map(|x| Some(blob(scene.project_into(i, x)?, None)));
                    let targets: Vec<Target> = coded.chain(plains).collect();
                    ImageMeasurements {
                        width: 1000,
                        height: 800,
                        ball_fits: vec![None; targets.len()].into(),
                        targets: targets.into(),
                    }
                })
                .collect::<Vec<_>>()
                .into()
        }
    }

    impl Field {
        /// [`Field::oriented_scene`] with the coded targets as points at their true
        /// positions, measured by their detections in `images` (those reading their number).
        pub(crate) fn scene_with_coded(&self, dets: &Detections, images: &[usize]) -> Scene {
            let mut scene = self.oriented_scene();
            for &(n, x) in &self.coded {
                let obs = (images.iter())
                    .flat_map(|&i| {
                        let i = ImageId(i);
                        (dets[i].targets.iter_enumerated())
                            .filter(move |(_, t)| t.id == Some(n))
                            .map(move |(k, _)| DetectionId::new(i, k))
                    })
                    .collect();
                scene.points.push(ScenePoint {
                    name: n.to_string(),
                    kind: PointKind::Coded(n),
                    position: x,
                    obs,
                });
            }
            scene
        }
    }

    /// A detection at `uv`: a coded target reading `number`, or a plain one without.
    pub(crate) fn blob(uv: nalgebra::Vector2<f64>, number: Option<u32>) -> Target {
        let mut t = target(uv.x, number.unwrap_or(0));
        t.y = uv.y;
        t.ellipse = Ellipse::circle(uv.x, uv.y, 3.0);
        t.centroid = [uv.x, uv.y];
        t.id = number;
        if number.is_none() {
            t.kind = TargetKind::Plain;
        }
        t
    }

    /// The largest distance (mm) between a camera centre of `a` and of `b`, and the largest
    /// angle (degrees) between their rotations.
    fn pose_error(a: &Rigid3, b: &Rigid3) -> (f64, f64) {
        let dr = a.rotation * b.rotation.transpose();
        let cos = ((dr.trace() - 1.0) / 2.0).clamp(-1.0, 1.0);
        ((a.centre() - b.centre()).norm(), cos.acos().to_degrees())
    }

    /// From exact image points of twelve coded targets in five images, the initial network
    /// finds every image's pose and every target's position in the main image's frame and
    /// at the scale of the one distance: the relative start, resection and intersection
    /// recover the truth to a micrometre (exact data leave only the solver's tolerance).
    #[test]
    fn the_initial_network_recovers_a_small_field_made_in_memory() {
        let field = Field::new();
        let dets = field.detections(false);
        let rep = Reporter::silent();
        let scene = initial_network(&field.project, &dets, &Options::default(), &rep)
            .expect("the field orients");
        assert!(scene.unoriented.is_empty(), "{:?}", scene.unoriented);
        for (k, truth) in field.poses.iter().enumerate() {
            let got = scene.poses[ImageId(k)].expect("oriented");
            let (dc, da) = pose_error(&got, truth);
            assert!(dc < 1e-3 && da < 1e-6, "image {k}: {dc} mm, {da}°");
        }
        assert_eq!(scene.points.len(), field.coded.len());
        for p in &scene.points {
            let PointKind::Coded(n) = p.kind else {
                panic!("{} is not coded", p.name)
            };
            let truth = field.coded[n as usize - 1].1;
            assert!((p.position - truth).norm() < 1e-3, "target {n}");
        }
        assert!(scene.blunders.is_empty() && scene.warnings.is_empty());
        let lines = rep.lines();
        assert!(
            lines
                .iter()
                .any(|l| l.contains("5 of 5 images oriented, 12 coded targets")),
            "{lines:?}"
        );
    }

    /// The network is refused before any work with fewer than five coded targets read twice,
    /// and without a distance that joins two of them (its scale would be undefined); each
    /// error names the project file.
    #[test]
    fn a_network_without_five_coded_targets_or_a_scale_is_refused() {
        let mut field = Field::new();
        field.coded.truncate(4);
        let dets = field.detections(false);
        let rep = Reporter::silent();
        let e = initial_network(&field.project, &dets, &Options::default(), &rep)
            .expect_err("four targets")
            .to_string();
        assert!(e.starts_with("project.toml: only 4 coded targets"), "{e}");
        let mut field = Field::new();
        field.project.file.distances[0].to = 13;
        let dets = field.detections(false);
        let e = initial_network(&field.project, &dets, &Options::default(), &rep)
            .expect_err("no distance joins two targets")
            .to_string();
        assert!(
            e.contains("([[distances]]: 1–13); the scale of the network is undefined"),
            "{e}"
        );
    }

    /// Two coded points that the images put within a code ring of each other (3 dot radii: 9
    /// px for these 3 px dots) are one target read as two numbers: the one read in fewer images
    /// goes, its measurements named blunders; a point 20 px away stays.
    #[test]
    fn two_numbers_on_one_target_remove_the_one_read_less() {
        let (project, _, mut scene) = fixture();
        let in_view = |x: &Vector3<f64>| {
            scene
                .project_into(ImageId(0), x)
                .is_some_and(|uv| uv.x > 10.0 && uv.x < 90.0 && uv.y > 10.0 && uv.y < 70.0)
        };
        let ahead = [
            Vector3::new(0.0, 0.0, 1000.0),
            Vector3::new(0.0, 1000.0, 0.0),
        ]
        .into_iter()
        .find(in_view)
        .expect("a point ahead of the camera");
        // 500 px principal distance at 1000 mm: 0.5 px a mm across
        let side = Vector3::new(1.0, 0.0, 0.0);
        scene.points[PointId(0)].position = ahead;
        scene.points[PointId(1)].position = ahead - 40.0 * side;
        scene.points[PointId(2)].position = ahead + 10.0 * side;
        let at = |i: usize, k: usize| {
            let uv = scene
                .project_into(ImageId(i.min(1)), &scene.points[PointId(k)].position)
                .unwrap();
            let mut t = target(uv.x, k as u32 + 1);
            t.y = uv.y;
            t.ellipse = Ellipse::circle(uv.x, uv.y, 3.0);
            t
        };
        let dets: Detections = (0..3)
            .map(|i| ImageMeasurements {
                width: 100,
                height: 80,
                targets: (0..3).map(|k| at(i, k)).collect::<Vec<_>>().into(),
                ball_fits: vec![None; 3].into(),
            })
            .collect::<Vec<_>>()
            .into();
        let removed = coincident_coded(&project, &dets, &mut scene);
        assert_eq!(removed, 1);
        let names: Vec<&str> = scene.points.iter().map(|p| p.name.as_str()).collect();
        assert_eq!(names, ["1", "2"], "3 (two images) is 5 px from 1 (three)");
        assert_eq!(scene.blunders.len(), 2, "both of 3's measurements");
        assert!(scene.blunders.iter().all(|b| b.number == 3
            && b.stage == "coincident numbers"
            && b.why.contains("target 1")));
    }

    /// Without a layout or a stereo head, `auto` tries the relative orientation only, and
    /// asking for the layout's or the stereo head's start is refused, naming the file and
    /// what the project lacks.
    #[test]
    fn the_starts_tried_are_those_the_project_allows() {
        let field = Field::new();
        let p = &field.project;
        assert_eq!(starts_to_try(p, Start::Auto).unwrap(), [Start::Relative]);
        assert_eq!(
            starts_to_try(p, Start::Relative).unwrap(),
            [Start::Relative]
        );
        let e = starts_to_try(p, Start::Layout).unwrap_err().to_string();
        assert_eq!(
            e,
            "project.toml: --start layout: the project names no [targets] layout"
        );
        let e = starts_to_try(p, Start::Stereo).unwrap_err().to_string();
        assert_eq!(
            e,
            "project.toml: --start stereo: the project has no [stereo] head"
        );
    }
}
