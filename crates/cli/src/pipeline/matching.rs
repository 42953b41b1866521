//! Step 3: plain targets and balls, which carry no number.
//!
//! 1. **Driveback** (Australis' term): every point of the model is projected into every
//!    oriented image that does not measure it yet; the nearest unused detection of the
//!    right kind takes it when it is within [`TOL_PX`] and the next one is at least twice as
//!    far ([`pingcal_targets::driveback::assign`]).
//! 2. **New points** (first coded targets whose number was read in fewer than two images,
//!    then round blobs): for every pair of oriented images, two unused detections whose rays
//!    meet within [`TOL_PX`] (reprojected) in front of both cameras give a candidate point;
//!    its support is the number of other oriented images with an unused blob within
//!    [`TOL_PX`] of its projection. Candidates are taken greedily, best supported first;
//!    a point needs [`MIN_RAYS`] rays ([`MIN_RAYS_NUMBERED`] for a coded target whose
//!    number was read), and is intersected again from all of them.
//! 3. **Balls or targets**: a blob's size in millimetres is its semi-major axis in pixels
//!    times depth over principal distance; the median over its images decides: nearer the
//!    ball diameter than the target dot diameter → a ball.
//! 4. **Ball ids**: the labels of the project (`[balls] labels`, pixel positions in the main
//!    image) name the ball projecting nearest to each; without labels, balls are numbered
//!    B1, B2, … by their column in the main image.
//!
//! A short bundle adjustment between rounds keeps the model consistent.

use super::detect::ImageDetections;
use super::{Model, ModelPoint, Options, PipelineError, PointKind, Reporter, Result};
use nalgebra::{Vector2, Vector3};
use pingcal_ba::camera::{CameraModel, PhotogrammetricCamera};
use pingcal_ba::initial::intersection::{intersect, IntersectionOptions, Ray};
use pingcal_project::Project;
use pingcal_targets::driveback::{assign, Predicted};
use pingcal_targets::{Target, TargetKind};

/// Largest distance (px) between a projection and the detection that takes it.
pub const TOL_PX: f64 = 2.0;
/// Fewest rays of a new point.
pub const MIN_RAYS: usize = 3;
/// Fewest rays of a new coded target whose number one of its detections read: the number
/// already says which target it is, so one more ray on its epipolar line suffices.
pub const MIN_RAYS_NUMBERED: usize = 2;

/// The camera models of the project (one per camera, in project order).
pub fn models(project: &Project) -> Vec<PhotogrammetricCamera> {
    project
        .file
        .cameras
        .iter()
        .map(|c| PhotogrammetricCamera::new(c.width, c.height, c.pixel_size_mm))
        .collect()
}

/// Projects `x` into image `i` (None: not oriented, behind, or outside the frame).
pub fn project_into(
    model: &Model,
    cams: &[PhotogrammetricCamera],
    cam_of: &[usize],
    i: usize,
    x: &Vector3<f64>,
) -> Option<Vector2<f64>> {
    let pose = model.poses[i]?;
    let c = cam_of[i];
    let xc = pose.transform(x);
    if xc.y <= 0.0 {
        return None;
    }
    let uv = cams[c].project(&model.intrinsics[c], &xc, None, None)?;
    let (w, h) = (cams[c].width as f64, cams[c].height as f64);
    (uv.x >= -0.5 && uv.y >= -0.5 && uv.x <= w - 0.5 && uv.y <= h - 0.5).then_some(uv)
}

fn kind_of(p: &ModelPoint) -> TargetKind {
    match p.kind {
        PointKind::Coded(_) => TargetKind::Coded,
        _ => TargetKind::Plain,
    }
}

/// Step 1: driveback of every model point. Returns the number of measurements added.
pub fn driveback(
    project: &Project,
    dets: &[ImageDetections],
    model: &mut Model,
    tol_px: f64,
) -> usize {
    let cams = models(project);
    let cam_of = super::network::camera_index(project);
    let mut used = model.used(dets);
    let mut added = 0;
    for i in 0..dets.len() {
        if model.poses[i].is_none() {
            continue;
        }
        let mut predicted = Vec::new();
        let mut which = Vec::new();
        for (j, p) in model.points.iter().enumerate() {
            if p.obs.iter().any(|&(im, _)| im == i) {
                continue;
            }
            if let Some(uv) = project_into(model, &cams, &cam_of, i, &p.position) {
                predicted.push(Predicted {
                    label: p.name.clone(),
                    kind: kind_of(p),
                    x: uv.x,
                    y: uv.y,
                });
                which.push(j);
            }
        }
        // only unused detections, and a coded detection whose number was read only by
        // its own point (a different number is a different target)
        let free: Vec<usize> = (0..dets[i].targets.len())
            .filter(|&k| !used[i][k])
            .collect();
        let cand: Vec<Target> = free.iter().map(|&k| dets[i].targets[k].clone()).collect();
        for (pi, di) in assign(&predicted, &cand, tol_px) {
            let k = free[di];
            let j = which[pi];
            let t = &dets[i].targets[k];
            if let (Some(read), PointKind::Coded(id)) = (t.id, model.points[j].kind) {
                if read != id {
                    continue;
                }
            }
            model.points[j].obs.push((i, k));
            used[i][k] = true;
            added += 1;
        }
    }
    added
}

/// A camera ray in the model frame.
struct WorldRay {
    centre: Vector3<f64>,
    dir: Vector3<f64>,
}

/// Step 2: new points from unused detections of one kind: round blobs (`Plain`), or coded
/// targets whose number is not in the model yet (`Coded`: read in one image only, or not
/// read at all; a point takes the number one of its detections read, and detections that
/// read different numbers never pair). Returns how many were added.
pub fn new_points(
    project: &Project,
    dets: &[ImageDetections],
    model: &mut Model,
    kind: TargetKind,
) -> usize {
    let known: Vec<u32> = model
        .points
        .iter()
        .filter_map(|p| match p.kind {
            PointKind::Coded(n) => Some(n),
            _ => None,
        })
        .collect();
    let wanted = |t: &Target| {
        t.kind == kind && (kind != TargetKind::Coded || t.id.is_none_or(|n| !known.contains(&n)))
    };
    let cams = models(project);
    let cam_of = super::network::camera_index(project);
    let used = model.used(dets);
    let oriented: Vec<usize> = (0..dets.len())
        .filter(|&i| model.poses[i].is_some())
        .collect();
    // unused plain blobs and their rays, per image
    let rays: Vec<Vec<(usize, WorldRay)>> = (0..dets.len())
        .map(|i| {
            let Some(pose) = model.poses[i] else {
                return Vec::new();
            };
            let c = cam_of[i];
            dets[i]
                .targets
                .iter()
                .enumerate()
                .filter(|(k, t)| !used[i][*k] && wanted(t))
                .filter_map(|(k, t)| {
                    let d = cams[c].unproject(&model.intrinsics[c], &Vector2::new(t.x, t.y))?;
                    Some((
                        k,
                        WorldRay {
                            centre: pose.centre(),
                            dir: pose.rotation.transpose() * d.normalize(),
                        },
                    ))
                })
                .collect()
        })
        .collect();
    let nearest = |i: usize, uv: &Vector2<f64>, taken: &[Vec<bool>]| -> Option<(usize, f64)> {
        let mut best: Option<(usize, f64)> = None;
        let mut second = f64::INFINITY;
        for (k, _) in &rays[i] {
            if taken[i][*k] {
                continue;
            }
            let t = &dets[i].targets[*k];
            let d = (Vector2::new(t.x, t.y) - uv).norm();
            match best {
                Some((_, bd)) if d >= bd => second = second.min(d),
                _ => {
                    if let Some((_, bd)) = best {
                        second = second.min(bd);
                    }
                    best = Some((*k, d));
                }
            }
        }
        best.filter(|&(_, d)| d <= TOL_PX && second > 2.0 * d.max(TOL_PX / 2.0))
    };
    let f_px: Vec<f64> = (0..dets.len())
        .map(|i| model.intrinsics[cam_of[i]][0] / cams[cam_of[i]].pixel_size_mm)
        .collect();
    let no_taken: Vec<Vec<bool>> = dets.iter().map(|d| vec![false; d.targets.len()]).collect();
    // candidates: (support, rms, image a, det a, image b, det b, point)
    type Candidate = (usize, f64, usize, usize, usize, usize, Vector3<f64>);
    let mut cands: Vec<Candidate> = Vec::new();
    for (ai, &a) in oriented.iter().enumerate() {
        for &b in &oriented[ai + 1..] {
            for (ka, ra) in &rays[a] {
                for (kb, rb) in &rays[b] {
                    // closest points of the two rays
                    let w0 = ra.centre - rb.centre;
                    let (aa, bb, cc) = (1.0, ra.dir.dot(&rb.dir), 1.0);
                    let (dd, ee) = (ra.dir.dot(&w0), rb.dir.dot(&w0));
                    let den = aa * cc - bb * bb;
                    if den < 1e-6 {
                        continue; // < ~0.08° between the rays
                    }
                    let s = (bb * ee - cc * dd) / den;
                    let t = (aa * ee - bb * dd) / den;
                    if s <= 0.0 || t <= 0.0 {
                        continue;
                    }
                    // the rays' gap seen from camera a, in pixels, before any projection
                    let gap = (ra.centre + ra.dir * s - rb.centre - rb.dir * t).norm();
                    if gap / s.min(t) * f_px[a] > 4.0 * TOL_PX {
                        continue;
                    }
                    let x = 0.5 * (ra.centre + ra.dir * s + rb.centre + rb.dir * t);
                    let ea = project_into(model, &cams, &cam_of, a, &x);
                    let eb = project_into(model, &cams, &cam_of, b, &x);
                    let (Some(ua), Some(ub)) = (ea, eb) else {
                        continue;
                    };
                    let ta = &dets[a].targets[*ka];
                    let tb = &dets[b].targets[*kb];
                    if let (Some(na), Some(nb)) = (ta.id, tb.id) {
                        if na != nb {
                            continue;
                        }
                    }
                    let ra_px = (ua - Vector2::new(ta.x, ta.y)).norm();
                    let rb_px = (ub - Vector2::new(tb.x, tb.y)).norm();
                    if ra_px > TOL_PX || rb_px > TOL_PX {
                        continue;
                    }
                    let mut support = 2;
                    for &o in &oriented {
                        if o == a || o == b {
                            continue;
                        }
                        if let Some(uv) = project_into(model, &cams, &cam_of, o, &x) {
                            if nearest(o, &uv, &no_taken).is_some() {
                                support += 1;
                            }
                        }
                    }
                    let numbered = ta.id.is_some() || tb.id.is_some();
                    let needed = if numbered {
                        MIN_RAYS_NUMBERED
                    } else {
                        MIN_RAYS
                    };
                    if support >= needed {
                        let rms = ((ra_px * ra_px + rb_px * rb_px) / 2.0).sqrt();
                        cands.push((support, rms, a, *ka, b, *kb, x));
                    }
                }
            }
        }
    }
    cands.sort_by(|p, q| {
        q.0.cmp(&p.0)
            .then(p.1.total_cmp(&q.1))
            .then((p.2, p.3, p.4, p.5).cmp(&(q.2, q.3, q.4, q.5)))
    });
    let mut taken = no_taken;
    let mut added = 0;
    let first_plain = model
        .points
        .iter()
        .filter(|p| !matches!(p.kind, PointKind::Coded(_)))
        .count();
    for (_, _, a, ka, b, kb, x) in cands {
        if taken[a][ka] || taken[b][kb] {
            continue;
        }
        let mut obs = vec![(a, ka), (b, kb)];
        for &o in &oriented {
            if o == a || o == b {
                continue;
            }
            if let Some(uv) = project_into(model, &cams, &cam_of, o, &x) {
                if let Some((k, _)) = nearest(o, &uv, &taken) {
                    obs.push((o, k));
                }
            }
        }
        let mut numbers: Vec<u32> = obs
            .iter()
            .filter_map(|&(i, k)| dets[i].targets[k].id)
            .collect();
        numbers.sort_unstable();
        numbers.dedup();
        let needed = if numbers.is_empty() {
            MIN_RAYS
        } else {
            MIN_RAYS_NUMBERED
        };
        if obs.len() < needed {
            continue;
        }
        if numbers.len() > 1
            || numbers
                .iter()
                .any(|n| model.points.iter().any(|p| p.kind == PointKind::Coded(*n)))
        {
            continue;
        }
        let ray_list: Vec<Ray> = obs
            .iter()
            .map(|&(i, k)| {
                let c = cam_of[i];
                Ray {
                    pose: model.poses[i].expect("oriented"),
                    model: &cams[c],
                    params: &model.intrinsics[c],
                    uv: Vector2::new(dets[i].targets[k].x, dets[i].targets[k].y),
                }
            })
            .collect();
        let Ok(ix) = intersect(
            &ray_list,
            &IntersectionOptions {
                min_angle_deg: 1.0,
                max_rms_px: TOL_PX,
            },
        ) else {
            continue;
        };
        for &(i, k) in &obs {
            taken[i][k] = true;
        }
        added += 1;
        let (name, point_kind) = match numbers.first() {
            Some(n) => (n.to_string(), PointKind::Coded(*n)),
            None => (format!("P{}", first_plain + added), PointKind::Plain),
        };
        model.points.push(ModelPoint {
            name,
            kind: point_kind,
            position: ix.position,
            obs,
        });
    }
    added
}

/// Median size (mm) of a point's blobs: semi-major axis × depth / principal distance, × 2.
pub fn blob_diameter_mm(
    project: &Project,
    dets: &[ImageDetections],
    model: &Model,
    p: &ModelPoint,
) -> Option<f64> {
    let cam_of = super::network::camera_index(project);
    let mut d: Vec<f64> = p
        .obs
        .iter()
        .filter_map(|&(i, k)| {
            let pose = model.poses[i]?;
            let c = cam_of[i];
            let depth = pose.transform(&p.position).y;
            let px = project.file.cameras[c].pixel_size_mm;
            let cc = model.intrinsics[c][0];
            let a = dets[i].targets[k].ellipse.a;
            (depth > 0.0).then(|| 2.0 * a * px * depth / cc)
        })
        .collect();
    if d.is_empty() {
        return None;
    }
    d.sort_by(|a, b| a.total_cmp(b));
    Some(d[d.len() / 2])
}

/// Step 3 and 4: which new points are balls, and their ids.
pub fn classify_and_name_balls(
    project: &Project,
    dets: &[ImageDetections],
    model: &mut Model,
    rep: &Reporter,
) -> Result<()> {
    let f = &project.file;
    let ball_d = f.balls.diameter_mm;
    let dot_d = 2.0 * f.targets.dot_radius_mm;
    let threshold = 0.5 * (ball_d + dot_d);
    let mut sizes = Vec::new();
    for j in 0..model.points.len() {
        if model.points[j].kind != PointKind::Plain {
            continue;
        }
        if let Some(d) = blob_diameter_mm(project, dets, model, &model.points[j]) {
            if d > threshold {
                model.points[j].kind = PointKind::Ball;
                sizes.push(d);
            }
        }
    }
    let balls: Vec<usize> = (0..model.points.len())
        .filter(|&j| model.points[j].kind == PointKind::Ball)
        .collect();
    if !sizes.is_empty() {
        sizes.sort_by(|a, b| a.total_cmp(b));
        rep.log(format!(
            "balls: {} found (blob sizes {:.1}–{:.1} mm, median {:.1}; nominal {ball_d} mm, target dots {dot_d} mm)",
            balls.len(),
            sizes[0],
            sizes[sizes.len() - 1],
            sizes[sizes.len() / 2]
        ));
    }
    // ids
    let cams = models(project);
    let cam_of = super::network::camera_index(project);
    let main = project.main_image();
    let mc = cam_of[main];
    let pose = model.poses[main].expect("main image oriented");
    let uv: Vec<Option<Vector2<f64>>> = balls
        .iter()
        .map(|&j| {
            let xc = pose.transform(&model.points[j].position);
            cams[mc].project(&model.intrinsics[mc], &xc, None, None)
        })
        .collect();
    let mut names: Vec<Option<String>> = vec![None; balls.len()];
    if f.balls.labels.is_empty() {
        let mut order: Vec<usize> = (0..balls.len()).collect();
        order.sort_by(|&a, &b| {
            let ka = uv[a].map(|p| (p.x, p.y)).unwrap_or((f64::INFINITY, 0.0));
            let kb = uv[b].map(|p| (p.x, p.y)).unwrap_or((f64::INFINITY, 0.0));
            ka.partial_cmp(&kb).unwrap_or(std::cmp::Ordering::Equal)
        });
        for (n, &k) in order.iter().enumerate() {
            names[k] = Some(format!("B{}", n + 1));
        }
    } else {
        // each label takes the nearest ball within 3 ball radii (in pixels at that ball)
        for l in &f.balls.labels {
            let lp = Vector2::new(l.x, l.y);
            let best = (0..balls.len())
                .filter(|&k| names[k].is_none())
                .filter_map(|k| uv[k].map(|p| (k, (p - lp).norm())))
                .min_by(|a, b| a.1.total_cmp(&b.1));
            let Some((k, d)) = best else { continue };
            let depth = pose.transform(&model.points[balls[k]].position).y;
            let r_px =
                0.5 * ball_d * model.intrinsics[mc][0] / (depth * f.cameras[mc].pixel_size_mm);
            if d <= (3.0 * r_px).max(10.0) {
                names[k] = Some(l.id.clone());
            } else {
                rep.log(format!(
                    "  label {} at ({:.0}, {:.0}) in the main image: no ball within {:.0} px (nearest {d:.0} px)",
                    l.id,
                    l.x,
                    l.y,
                    (3.0 * r_px).max(10.0)
                ));
            }
        }
        let mut extra = 0;
        for n in names.iter_mut().filter(|n| n.is_none()) {
            extra += 1;
            *n = Some(format!("B?{extra}"));
        }
        if extra > 0 {
            rep.log(format!(
                "  {extra} balls have no label (named B?1…); they are used as control points"
            ));
        }
    }
    for (k, &j) in balls.iter().enumerate() {
        model.points[j].name = names[k].clone().expect("named");
    }
    // plain targets renumbered P1… in a stable order
    let mut n = 0;
    for p in model.points.iter_mut() {
        if p.kind == PointKind::Plain {
            n += 1;
            p.name = format!("P{n}");
        }
    }
    if balls.is_empty() {
        return Err(PipelineError::new(format!(
            "{}: no ball was found in two or more oriented images (balls of {ball_d} mm; targets of {dot_d} mm)",
            project.path.display()
        )));
    }
    Ok(())
}

/// Runs steps 1–4 with bundle adjustments in between.
pub fn add_points(
    project: &Project,
    dets: &[ImageDetections],
    model: &mut Model,
    opts: &Options,
    rep: &Reporter,
) -> Result<()> {
    let pb = rep.bar(3, "matching targets");
    let a1 = driveback(project, dets, model, TOL_PX);
    let n1 = new_points(project, dets, model, TargetKind::Coded)
        + new_points(project, dets, model, TargetKind::Plain);
    pb.inc(1);
    super::bundle::refine(project, dets, model, opts)?;
    let a2 = driveback(project, dets, model, TOL_PX);
    let n2 = new_points(project, dets, model, TargetKind::Coded)
        + new_points(project, dets, model, TargetKind::Plain);
    pb.inc(1);
    super::bundle::refine(project, dets, model, opts)?;
    let a3 = driveback(project, dets, model, TOL_PX);
    pb.finish_and_clear();
    rep.log(format!(
        "matching: {} measurements added by driveback, {} new points by multi-image matching",
        a1 + a2 + a3,
        n1 + n2
    ));
    classify_and_name_balls(project, dets, model, rep)
}
