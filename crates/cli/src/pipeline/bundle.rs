//! Step 4: the final self-calibrating bundle adjustment.
//!
//! - Datum: the main image is held fixed (its camera frame is the photogrammetric frame);
//!   the measured distances (observation equations with their σ) give the scale.
//! - Intrinsics: the parameters each camera frees in the project, shared by its images.
//! - Stereo head: with `[stereo]`, the right image of every station follows its left image
//!   through one rig pose, adjusted with everything else.
//! - Balls: the centre of a ball's silhouette is not the image of its centre; each ball
//!   measurement is corrected by the cone fit of [`pingcal_targets::ball`] with the current
//!   intrinsics, and the adjustment is run twice so that the correction uses calibrated
//!   intrinsics.
//! - Gross errors: data snooping (Baarda's w, Pope's τ when σ0 > 1) removes one image point
//!   at a time ([`pingcal_ba::solver::adjust_with_snooping`]).

use super::detect::ImageDetections;
use super::network::{ba_cameras, camera_index, target_sigma};
use super::{Model, Options, PipelineError, PointKind, Reporter, Result};
use nalgebra::Vector2;
use pingcal_ba::camera::{CameraModel, PhotogrammetricCamera};
use pingcal_ba::pose::Pose;
use pingcal_ba::problem::{Distance, Image, Observation, Point, Problem, Rig, RigMember};
use pingcal_ba::solver::{self, Precision, PrecisionError, Rejection, SnoopError};
use pingcal_project::Project;
use pingcal_targets::ball::{sphere_centre_from_ellipse, FnCamera};

/// Smallest σ of a ball's corrected centre (px): the limb of a shaded sphere is softer
/// than a target's edge.
pub const MIN_BALL_SIGMA_PX: f64 = 0.05;

/// The adjusted network.
pub struct Adjusted {
    /// The last problem solved (its solution is also in the [`Model`]).
    pub problem: Problem,
    /// Per observation of `problem`: (model point, project image, detection).
    pub obs_map: Vec<(usize, usize, usize)>,
    /// Project image → image of `problem`.
    pub image_index: Vec<Option<usize>>,
    /// Model point → point of `problem` (None: fewer than two rays).
    pub point_index: Vec<Option<usize>>,
    /// Precision of the last adjustment.
    pub precision: Precision,
    /// Image points removed as gross errors.
    pub rejected: Vec<Rejection>,
    /// The stereo rig (left → right camera frame), when there is one.
    pub rig: Option<Pose>,
    /// Eccentricity corrections of the ball measurements (px), for the report.
    pub ball_shifts_px: Vec<f64>,
    /// Iterations of all final adjustments.
    pub iterations: usize,
}

/// The measurement of detection `k` of image `i` for point kind `kind`: the detected centre,
/// or for a ball the image of the sphere's centre; with its σ and the correction applied.
fn measurement(
    dets: &[ImageDetections],
    i: usize,
    k: usize,
    kind: PointKind,
    cam: &PhotogrammetricCamera,
    params: &[f64],
    radius: f64,
) -> (Vector2<f64>, f64, f64) {
    let t = &dets[i].targets[k];
    let raw = Vector2::new(t.x, t.y);
    if kind != PointKind::Ball {
        return (raw, target_sigma(t), 0.0);
    }
    let (e, s) = dets[i].ball_fits[k].unwrap_or((t.ellipse, t.sigma_px));
    let rays = FnCamera(
        |x: f64, y: f64| {
            cam.unproject(params, &Vector2::new(x, y))
                .map(|r| [r.x, r.y, r.z])
        },
        |r: [f64; 3]| {
            cam.project(params, &nalgebra::Vector3::from(r), None, None)
                .map(|p| [p.x, p.y])
        },
    );
    let sigma = (super::network::SIGMA_FACTOR * s).max(MIN_BALL_SIGMA_PX);
    match sphere_centre_from_ellipse(&e, &rays, Some(radius)) {
        Some(c) => {
            let p = Vector2::new(c.x, c.y);
            (p, sigma, (p - Vector2::new(e.cx, e.cy)).norm())
        }
        None => (Vector2::new(e.cx, e.cy), sigma, 0.0),
    }
}

struct Built {
    problem: Problem,
    obs_map: Vec<(usize, usize, usize)>,
    image_index: Vec<Option<usize>>,
    point_index: Vec<Option<usize>>,
    shifts: Vec<f64>,
}

/// The problem of the model's current state. `rig`: the stereo rig pose to use (None: no
/// rig constraint). Distances whose targets are missing are left out.
fn build(project: &Project, dets: &[ImageDetections], model: &Model, rig: Option<Pose>) -> Built {
    let f = &project.file;
    let cam_of = camera_index(project);
    let cams = super::matching::models(project);
    let main = project.main_image();
    let mut problem = Problem {
        cameras: ba_cameras(project, &model.intrinsics),
        ..Problem::default()
    };
    let mut image_index = vec![None; f.images.len()];
    for (i, im) in f.images.iter().enumerate() {
        if let Some(pose) = model.poses[i] {
            image_index[i] = Some(problem.images.len());
            problem.images.push(Image {
                name: im.file.clone(),
                camera: cam_of[i],
                pose,
                fixed: i == main,
            });
        }
    }
    let mut point_index = vec![None; model.points.len()];
    let mut obs_map = Vec::new();
    let mut shifts = Vec::new();
    let radius = 0.5 * f.balls.diameter_mm;
    for (j, p) in model.points.iter().enumerate() {
        let obs: Vec<(usize, usize)> = p
            .obs
            .iter()
            .copied()
            .filter(|&(i, _)| image_index[i].is_some())
            .collect();
        if obs.len() < 2 {
            continue;
        }
        let pj = problem.points.len();
        point_index[j] = Some(pj);
        problem.points.push(Point {
            name: p.name.clone(),
            position: p.position,
            fixed: false,
        });
        for (i, k) in obs {
            let c = cam_of[i];
            let (uv, sigma, shift) =
                measurement(dets, i, k, p.kind, &cams[c], &model.intrinsics[c], radius);
            if p.kind == PointKind::Ball {
                shifts.push(shift);
            }
            problem.observations.push(Observation {
                image: image_index[i].expect("filtered"),
                point: pj,
                uv,
                sigma,
            });
            obs_map.push((j, i, k));
        }
    }
    for d in &f.distances {
        let find = |n: u32| {
            model
                .points
                .iter()
                .position(|p| p.kind == PointKind::Coded(n))
                .and_then(|j| point_index[j])
        };
        if let (Some(a), Some(b)) = (find(d.from), find(d.to)) {
            problem.distances.push(Distance {
                a,
                b,
                value: d.distance_mm,
                sigma: d.sigma_mm,
            });
        }
    }
    if let (Some(rig_pose), Some(st)) = (rig, &f.stereo) {
        let (base_cam, member_cam) = if f.main_camera == st.right {
            (&st.right, &st.left)
        } else {
            (&st.left, &st.right)
        };
        let mut members = Vec::new();
        for (i, im) in f.images.iter().enumerate() {
            if im.camera != *member_cam {
                continue;
            }
            let base = f
                .images
                .iter()
                .position(|b| b.station == im.station && b.camera == *base_cam);
            if let (Some(mi), Some(bi)) = (image_index[i], base.and_then(|b| image_index[b])) {
                members.push(RigMember {
                    image: mi,
                    base: bi,
                });
            }
        }
        if !members.is_empty() {
            problem.rigs.push(Rig {
                name: "stereo".into(),
                pose: rig_pose,
                fixed: false,
                members,
            });
            problem.sync_rigs();
        }
    }
    Built {
        problem,
        obs_map,
        image_index,
        point_index,
        shifts,
    }
}

/// Copies the solution of `b.problem` back into the model.
fn read_back(model: &mut Model, b: &Built) {
    for (i, idx) in b.image_index.iter().enumerate() {
        if let Some(k) = idx {
            model.poses[i] = Some(b.problem.images[*k].pose);
        }
    }
    for (j, idx) in b.point_index.iter().enumerate() {
        if let Some(k) = idx {
            model.points[j].position = b.problem.points[*k].position;
        }
    }
    model.intrinsics = b.problem.cameras.iter().map(|c| c.params.clone()).collect();
}

/// The rig pose (base → member camera frame) from the main station, or the first station
/// where both cameras are oriented.
fn initial_rig(project: &Project, model: &Model) -> Option<Pose> {
    let f = &project.file;
    let st = f.stereo.as_ref()?;
    let (base_cam, member_cam) = if f.main_camera == st.right {
        (&st.right, &st.left)
    } else {
        (&st.left, &st.right)
    };
    let mut stations: Vec<&str> = vec![f.main_station.as_str()];
    stations.extend(f.images.iter().map(|im| im.station.as_str()));
    for s in stations {
        let pose_of = |cam: &str| {
            f.images
                .iter()
                .position(|im| im.station == s && im.camera == cam)
                .and_then(|i| model.poses[i])
        };
        if let (Some(b), Some(m)) = (pose_of(base_cam), pose_of(member_cam)) {
            return Some(m.compose(&b.inverse()));
        }
    }
    None
}

/// A quick adjustment of the model as it stands (no rig, no snooping); measurements more
/// than `3 ·` [`super::matching::TOL_PX`] from their point afterwards are dropped.
pub fn refine(
    project: &Project,
    dets: &[ImageDetections],
    model: &mut Model,
    opts: &Options,
) -> Result<()> {
    let mut b = build(project, dets, model, None);
    let options = solver::Options {
        max_iterations: 30,
        threads: opts.threads,
        ..solver::Options::default()
    };
    solver::solve(&mut b.problem, &options, |_| {})
        .map_err(|e| PipelineError::new(format!("bundle adjustment during matching: {e}")))?;
    read_back(model, &b);
    let limit = 3.0 * super::matching::TOL_PX;
    let mut drop: Vec<(usize, usize, usize)> = Vec::new();
    for (o, ob) in b.problem.observations.iter().enumerate() {
        if let Some(r) = b.problem.residual(ob) {
            if r.norm() > limit {
                drop.push(b.obs_map[o]);
            }
        }
    }
    for (j, i, k) in drop {
        model.points[j].obs.retain(|&o| o != (i, k));
    }
    model.points.retain(|p| p.obs.len() >= 2);
    Ok(())
}

/// Removes rejected measurements from the model (a point has one measurement per image).
fn remove_rejected(project: &Project, model: &mut Model, rejected: &[Rejection]) {
    for r in rejected {
        let Some(i) = project.file.images.iter().position(|im| im.file == r.image) else {
            continue;
        };
        for p in model.points.iter_mut().filter(|p| p.name == r.point) {
            p.obs.retain(|&(im, _)| im != i);
        }
    }
}

/// Removes from the model a point whose position the network does not determine and returns its
/// measurements as rejections. This happens when data snooping has taken the rays of a point
/// down to one, and then that one too (`pingcal_ba::solver::adjust_with_snooping` drops a lone
/// ray but keeps the point, which the precision then finds undetermined), or when its rays are
/// nearly parallel. A coded target that a distance refers to cannot go: that is an error naming
/// it.
fn drop_undetermined(
    project: &Project,
    dets: &[ImageDetections],
    model: &mut Model,
    name: &str,
) -> Result<Vec<Rejection>> {
    let Some(j) = model.points.iter().position(|p| p.name == name) else {
        return Err(PipelineError::new(format!(
            "final bundle adjustment: point '{name}' is not determined by its rays"
        )));
    };
    if let PointKind::Coded(n) = model.points[j].kind {
        if project
            .file
            .distances
            .iter()
            .any(|d| d.from == n || d.to == n)
        {
            return Err(PipelineError::new(format!(
                "{}: coded target {n} of the distances is not determined by its rays after data snooping: it needs more images in which it is measured well",
                project.path.display()
            )));
        }
    }
    let p = model.points.remove(j);
    Ok(p.obs
        .iter()
        .map(|&(i, k)| {
            let t = &dets[i].targets[k];
            Rejection {
                image: project.file.images[i].file.clone(),
                point: name.to_string(),
                uv: [t.x, t.y],
                w: [f64::NAN; 2],
                reason: "data snooping left the point too few rays to determine it: the point is dropped".into(),
            }
        })
        .collect())
}

/// The final adjustment (see the module doc).
pub fn final_adjustment(
    project: &Project,
    dets: &[ImageDetections],
    model: &mut Model,
    opts: &Options,
    rep: &Reporter,
) -> Result<Adjusted> {
    let f = &project.file;
    for (k, d) in f.distances.iter().enumerate() {
        for n in [d.from, d.to] {
            let p = model.points.iter().find(|p| p.kind == PointKind::Coded(n));
            if p.is_none_or(|p| p.obs.len() < 2) {
                return Err(PipelineError::new(format!(
                    "{}: distances[{k}] ({} – {}): coded target {n} was not identified in two or more oriented images",
                    project.path.display(),
                    d.from,
                    d.to
                )));
            }
        }
    }
    let options = solver::Options {
        max_iterations: 100,
        threads: opts.threads,
        ..solver::Options::default()
    };
    let mut rig = initial_rig(project, model);
    let mut rejected_all = Vec::new();
    let mut iterations = 0;
    let pb = rep.bar(3, "bundle adjustment");
    for round in 0..2 {
        let (b, r) = loop {
            let mut b = build(project, dets, model, rig);
            let max_rej = b.problem.observations.len() / 20;
            match solver::adjust_with_snooping(
                &mut b.problem,
                &options,
                opts.snoop_critical,
                max_rej,
            ) {
                Ok(r) => break (b, r),
                Err(SnoopError::Precision(PrecisionError::PointUndetermined(name))) => {
                    rejected_all.extend(drop_undetermined(project, dets, model, &name)?);
                    rep.log(format!(
                        "  point {name} dropped: after data snooping its rays no longer determine it"
                    ));
                }
                Err(e) => {
                    return Err(PipelineError::new(format!("final bundle adjustment: {e}")));
                }
            }
        };
        iterations += r.summary.iterations;
        read_back(model, &b);
        rig = b.problem.rigs.first().map(|r| r.pose).or(rig);
        remove_rejected(project, model, &r.rejected);
        rep.log(format!(
            "  bundle round {}: {} iterations, sigma0 {:.3}, RMS {:.3} px, {} image points rejected",
            round + 1,
            r.summary.iterations,
            r.precision.sigma0,
            r.precision.rms_image_px,
            r.rejected.len()
        ));
        rejected_all.extend(r.rejected);
        pb.inc(1);
    }
    // the final solution, aligned with the model's measurements
    let mut b = build(project, dets, model, rig);
    let summary = solver::solve(&mut b.problem, &options, |_| {})
        .map_err(|e| PipelineError::new(format!("final bundle adjustment: {e}")))?;
    iterations += summary.iterations;
    read_back(model, &b);
    let precision = solver::precision(&b.problem).map_err(|e| {
        PipelineError::new(format!(
            "{}: the network's precision cannot be computed: {e}",
            project.path.display()
        ))
    })?;
    pb.finish_and_clear();
    let rig = b.problem.rigs.first().map(|r| r.pose);
    rep.log(format!(
        "bundle adjustment: {} images, {} points ({} balls), {} image points, {} distances; sigma0 {:.3}, RMS {:.3} px, {} rejected",
        b.problem.images.len(),
        b.problem.points.len(),
        model.points.iter().filter(|p| p.kind == PointKind::Ball).count(),
        b.problem.observations.len(),
        b.problem.distances.len(),
        precision.sigma0,
        precision.rms_image_px,
        rejected_all.len()
    ));
    Ok(Adjusted {
        obs_map: b.obs_map,
        image_index: b.image_index,
        point_index: b.point_index,
        ball_shifts_px: b.shifts,
        problem: b.problem,
        precision,
        rejected: rejected_all,
        rig,
        iterations,
    })
}
