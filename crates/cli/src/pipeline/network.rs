//! Step 2: the initial network from the coded targets alone.
//!
//! Every coded target read in two or more images becomes a point; the incremental
//! initialiser of `pingcal-ba` ([`pingcal_ba::initial::incremental`]) starts from the best
//! relatively oriented image pair, resects and intersects the rest with bundle adjustments
//! between rounds (self-calibrating once three images are oriented), rejects gross errors
//! and scales the network by the measured distances. The result is moved into the
//! photogrammetric frame of SPEC.md: the main image's camera frame (origin at its
//! projection centre, X right, Y forward, Z up).

use super::adjust::{Datum, SceneProblem};
use super::ids::{DetectionId, IdVec, ImageId};
use super::scene::{image_file, main_image, Detections, PointKind, Scene, ScenePoint};
use super::{Options, PipelineError, Reporter, Result};
use nalgebra::Vector3;
use pingcal_ba::initial::incremental::{initialise, IncrementalOptions, Initialised};
use pingcal_ba::solver;
use pingcal_geometry::Rigid3;
use pingcal_project::Project;
use pingcal_targets::TargetKind;
use std::collections::BTreeMap;

/// The initial network, in the photogrammetric frame, scaled by the distances.
pub fn initial_network(
    project: &Project,
    dets: &Detections,
    opts: &Options,
    rep: &Reporter,
) -> Result<Scene> {
    let f = &project.file;
    let seen = coded_tracks(dets);
    if seen.len() < 5 {
        return Err(PipelineError::new(format!(
            "{}: only {} coded targets were read in two or more images; at least 5 are needed to orient the images (are the targets {} and large enough in the images?)",
            project.path.display(),
            seen.len(),
            f.targets.family
        )));
    }
    let start = starting_scene(project, &seen);
    let sp = SceneProblem::build(project, dets, &start, Datum::Free, None);
    if sp.problem.distances.is_empty() {
        let list: Vec<String> = f
            .distances
            .iter()
            .map(|d| format!("{}–{}", d.from, d.to))
            .collect();
        return Err(PipelineError::new(format!(
            "{}: no measured distance joins two coded targets read in two or more images ([[distances]]: {}); the scale of the network is undefined",
            project.path.display(),
            if list.is_empty() { "none".into() } else { list.join(", ") }
        )));
    }
    let options = IncrementalOptions {
        bundle: solver::Options {
            max_iterations: 50,
            threads: opts.threads,
            ..solver::Options::default()
        },
        ..IncrementalOptions::default()
    };
    let pb = rep.task("orienting images", 1);
    let init = initialise(&sp.problem, &[], &[], &options).map_err(|e| {
        PipelineError::new(format!(
            "{}: initial orientation: {e}",
            project.path.display()
        ))
    })?;
    pb.finish();
    for s in &init.steps {
        rep.log(format!("  {s}"));
    }
    let scene = into_main_frame(project, start, &sp, &init)?;
    for (i, why) in &scene.unoriented {
        rep.log(format!(
            "  image {} not oriented: {why}",
            image_file(project, *i)
        ));
    }
    rep.log(format!(
        "initial network: {} of {} images oriented, {} coded targets, RMS {:.3} px",
        scene.oriented().len(),
        scene.poses.len(),
        scene.points.len(),
        init.problem.rms_px()
    ));
    Ok(scene)
}

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
/// intrinsics, and why the other images were not oriented.
fn into_main_frame(
    project: &Project,
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
        let why = init
            .unoriented_images
            .iter()
            .find(|(n, _)| n == image_file(project, main))
            .map(|(_, w)| w.clone())
            .unwrap_or_else(|| "unknown".into());
        return Err(PipelineError::new(format!(
            "{}: the main image could not be oriented: {why}",
            image_file(project, main)
        )));
    };
    // into the main image's frame: X' = R X + t; image poses P' = P ∘ M⁻¹
    let to_main = main_pose.inverse();
    for p in poses.iter_mut().flatten() {
        *p = p.compose(&to_main);
    }
    let rejected: Vec<(&str, &str)> = init
        .rejected_observations
        .iter()
        .map(|(i, p, _)| (i.as_str(), p.as_str()))
        .collect();
    let mut points = IdVec::new();
    for (k, &j) in sp.map.points.iter().enumerate() {
        let Some(m) = init.point_map[k] else { continue };
        let mut p = scene.points[j].clone();
        p.position = main_pose.transform(&init.problem.points[m].position);
        p.obs.retain(|d| {
            poses[d.image].is_some()
                && !rejected.contains(&(image_file(project, d.image), p.name.as_str()))
        });
        if p.obs.len() >= 2 {
            points.push(p);
        }
    }
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
    Ok(scene)
}
