//! Step 2: the initial network from the coded targets alone.
//!
//! Every coded target read in two or more images becomes a point; the incremental
//! initialiser of `pingcal-ba` ([`pingcal_ba::initial::incremental`]) starts from the best
//! relatively oriented image pair, resects and intersects the rest with bundle adjustments
//! between rounds (self-calibrating once three images are oriented), rejects gross errors
//! and scales the network by the measured distances. The result is moved into the
//! photogrammetric frame of SPEC.md: the main image's camera frame (origin at its
//! projection centre, X right, Y forward, Z up).

use super::detect::ImageDetections;
use super::{Model, ModelPoint, Options, PipelineError, PointKind, Reporter, Result};
use nalgebra::Vector3;
use pingcal_ba::camera::PhotogrammetricCamera;
use pingcal_ba::initial::incremental::{initialise, IncrementalOptions};
use pingcal_ba::pose::Pose;
use pingcal_ba::problem::{Camera, Distance, Image, Observation, Point, Problem};
use pingcal_ba::solver;
use pingcal_project::{Parameter, Project};
use pingcal_targets::{Target, TargetKind};
use std::collections::BTreeMap;
use std::sync::Arc;

/// The detector's σ of a centre is about half the scatter seen against truth (issue 4's
/// Monte Carlo); image points are weighted with twice that σ, and never below
/// [`MIN_SIGMA_PX`].
pub const SIGMA_FACTOR: f64 = 2.0;
/// Smallest σ given to an image point (px).
pub const MIN_SIGMA_PX: f64 = 0.03;

/// σ of a target's image point (px).
pub fn target_sigma(t: &Target) -> f64 {
    let s = SIGMA_FACTOR * t.sigma_px;
    if s.is_finite() {
        s.max(MIN_SIGMA_PX)
    } else {
        1.0
    }
}

/// The cameras of the project as bundle-adjustment cameras (free parameters as the project
/// says), with `params` as their values.
pub fn ba_cameras(project: &Project, params: &[Vec<f64>]) -> Vec<Camera> {
    project
        .file
        .cameras
        .iter()
        .zip(params)
        .map(|(c, p)| {
            let model = Arc::new(PhotogrammetricCamera::new(
                c.width,
                c.height,
                c.pixel_size_mm,
            ));
            let mut cam = Camera::new(c.id.clone(), model, p.clone());
            for p in Parameter::ALL {
                cam.fixed[p.index()] = !c.free.contains(&p);
            }
            cam
        })
        .collect()
}

/// Index of each image's camera in the project's camera list.
pub fn camera_index(project: &Project) -> Vec<usize> {
    project
        .file
        .images
        .iter()
        .map(|im| {
            project
                .file
                .cameras
                .iter()
                .position(|c| c.id == im.camera)
                .expect("validated camera")
        })
        .collect()
}

/// The initial network, in the photogrammetric frame, scaled by the distances.
pub fn initial_network(
    project: &Project,
    dets: &[ImageDetections],
    opts: &Options,
    rep: &Reporter,
) -> Result<Model> {
    let f = &project.file;
    let cam_of = camera_index(project);
    let initial: Vec<Vec<f64>> = f
        .cameras
        .iter()
        .map(|c| c.initial.to_slice().to_vec())
        .collect();
    // coded number → (image, detection) measurements
    let mut seen: BTreeMap<u32, Vec<(usize, usize)>> = BTreeMap::new();
    for (i, d) in dets.iter().enumerate() {
        for (k, t) in d.targets.iter().enumerate() {
            if let (TargetKind::Coded, Some(id)) = (t.kind, t.id) {
                seen.entry(id).or_default().push((i, k));
            }
        }
    }
    seen.retain(|_, v| v.len() >= 2);
    if seen.len() < 5 {
        return Err(PipelineError::new(format!(
            "{}: only {} coded targets were read in two or more images; at least 5 are needed to orient the images (are the targets {} and large enough in the images?)",
            project.path.display(),
            seen.len(),
            f.targets.family
        )));
    }
    let points: Vec<ModelPoint> = seen
        .iter()
        .map(|(id, obs)| ModelPoint {
            name: id.to_string(),
            kind: PointKind::Coded(*id),
            position: Vector3::zeros(),
            obs: obs.clone(),
        })
        .collect();
    let mut problem = Problem {
        cameras: ba_cameras(project, &initial),
        images: f
            .images
            .iter()
            .zip(&cam_of)
            .map(|(im, &c)| Image {
                name: im.file.clone(),
                camera: c,
                pose: Pose::identity(),
                fixed: false,
            })
            .collect(),
        ..Problem::default()
    };
    for (j, p) in points.iter().enumerate() {
        problem.points.push(Point {
            name: p.name.clone(),
            position: Vector3::zeros(),
            fixed: false,
        });
        for &(i, k) in &p.obs {
            let t = &dets[i].targets[k];
            problem.observations.push(Observation {
                image: i,
                point: j,
                uv: nalgebra::Vector2::new(t.x, t.y),
                sigma: target_sigma(t),
            });
        }
    }
    let index: BTreeMap<&str, usize> = points
        .iter()
        .enumerate()
        .map(|(j, p)| (p.name.as_str(), j))
        .collect();
    for d in &f.distances {
        if let (Some(&a), Some(&b)) = (
            index.get(d.from.to_string().as_str()),
            index.get(d.to.to_string().as_str()),
        ) {
            problem.distances.push(Distance {
                a,
                b,
                value: d.distance_mm,
                sigma: d.sigma_mm,
            });
        }
    }
    if problem.distances.is_empty() {
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
    let pb = rep.bar(1, "orienting images");
    let init = initialise(&problem, &[], &[], &options).map_err(|e| {
        PipelineError::new(format!(
            "{}: initial orientation: {e}",
            project.path.display()
        ))
    })?;
    pb.finish_and_clear();
    for s in &init.steps {
        rep.log(format!("  {s}"));
    }
    let main = project.main_image();
    let mut poses: Vec<Option<Pose>> = init
        .image_map
        .iter()
        .map(|m| m.map(|k| init.problem.images[k].pose))
        .collect();
    let Some(main_pose) = poses[main] else {
        let why = init
            .unoriented_images
            .iter()
            .find(|(n, _)| *n == f.images[main].file)
            .map(|(_, w)| w.clone())
            .unwrap_or_else(|| "unknown".into());
        return Err(PipelineError::new(format!(
            "{}: the main image could not be oriented: {why}",
            f.images[main].file
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
    let mut model_points = Vec::new();
    for (j, mut p) in points.into_iter().enumerate() {
        let Some(k) = init.point_map[j] else { continue };
        p.position = main_pose.transform(&init.problem.points[k].position);
        p.obs.retain(|&(i, _)| {
            poses[i].is_some() && !rejected.contains(&(f.images[i].file.as_str(), p.name.as_str()))
        });
        if p.obs.len() >= 2 {
            model_points.push(p);
        }
    }
    let unoriented: Vec<(usize, String)> = init
        .unoriented_images
        .iter()
        .filter_map(|(name, why)| {
            f.images
                .iter()
                .position(|im| im.file == *name)
                .map(|i| (i, why.clone()))
        })
        .collect();
    for (i, why) in &unoriented {
        rep.log(format!("  image {} not oriented: {why}", f.images[*i].file));
    }
    let intrinsics = init
        .problem
        .cameras
        .iter()
        .map(|c| c.params.clone())
        .collect();
    rep.log(format!(
        "initial network: {} of {} images oriented, {} coded targets, RMS {:.3} px",
        poses.iter().filter(|p| p.is_some()).count(),
        poses.len(),
        model_points.len(),
        init.problem.rms_px()
    ));
    Ok(Model {
        poses,
        intrinsics,
        points: model_points,
        unoriented,
    })
}
