//! Step 3: plain targets and balls, which carry no number.
//!
//! 1. **Driveback** (Australis' term): every point of the scene is projected into every
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
//! A short bundle adjustment between rounds ([`refine`]) keeps the scene consistent.

use super::adjust::{Datum, SceneProblem};
use super::ids::{DetIdx, DetectionId, IdVec, ImageId, PointId};
use super::scene::{
    coded_blunder, image_file, main_image, CodedBlunder, DetectionSet, Detections, PointKind,
    Scene, SceneCamera, ScenePoint,
};
use crate::context::{Options, PipelineError, Result};
use crate::progress::Reporter;
use nalgebra::{Vector2, Vector3};
use pingcal_ba::initial::intersection::{intersect, IntersectionOptions, Ray};
use pingcal_ba::solver;
use pingcal_geometry::Rigid3;
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

fn kind_of(p: &ScenePoint) -> TargetKind {
    match p.kind {
        PointKind::Coded(_) => TargetKind::Coded,
        _ => TargetKind::Plain,
    }
}

/// Step 1: driveback of every scene point. Returns the number of measurements added.
pub fn driveback(dets: &Detections, scene: &mut Scene, tol_px: f64) -> usize {
    let mut used = scene.used(dets);
    let mut added = 0;
    for i in scene.oriented() {
        let mut predicted = Vec::new();
        let mut which: Vec<PointId> = Vec::new();
        for (j, p) in scene.points.iter_enumerated() {
            if p.obs.iter().any(|d| d.image == i) {
                continue;
            }
            if let Some(uv) = scene.project_into(i, &p.position) {
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
        let free: Vec<DetectionId> = dets[i]
            .targets
            .ids()
            .map(|k| DetectionId::new(i, k))
            .filter(|&d| !used.contains(d))
            .collect();
        let cand: Vec<Target> = free.iter().map(|&d| dets.target(d).clone()).collect();
        for (pi, di) in assign(&predicted, &cand, tol_px) {
            let d = free[di];
            let j = which[pi];
            if let (Some(read), PointKind::Coded(id)) = (dets.target(d).id, scene.points[j].kind) {
                if read != id {
                    // the detection is where target `id` is, and reads another number
                    let t = dets.target(d);
                    let off = (predicted[pi].x - t.x).hypot(predicted[pi].y - t.y);
                    scene.add_blunder(CodedBlunder {
                        det: d,
                        number: read,
                        stage: "driveback",
                        why: format!("where target {id} is ({off:.1} px from its projection)"),
                    });
                    used.insert(d);
                    continue;
                }
            }
            scene.points[j].obs.push(d);
            used.insert(d);
            added += 1;
        }
    }
    added
}

/// A camera ray in the scene frame.
struct WorldRay {
    centre: Vector3<f64>,
    dir: Vector3<f64>,
}

/// The detections a round of new points may use, with their rays, per image.
struct Blobs<'a> {
    dets: &'a Detections,
    rays: IdVec<ImageId, Vec<(DetIdx, WorldRay)>>,
    /// Principal distance of each image's camera, in pixels.
    f_px: IdVec<ImageId, f64>,
    /// No detection (the support of a candidate counts every blob).
    none_taken: DetectionSet,
}

impl<'a> Blobs<'a> {
    /// The unused detections for which `wanted` is true, in the oriented images.
    fn new(dets: &'a Detections, scene: &Scene, wanted: impl Fn(&Target) -> bool) -> Self {
        let used = scene.used(dets);
        let rays = dets
            .iter_enumerated()
            .map(|(i, di)| {
                let Some(pose) = scene.poses[i] else {
                    return Vec::new();
                };
                let c = scene.camera_of[i];
                di.targets
                    .iter_enumerated()
                    .filter(|(k, t)| !used.contains(DetectionId::new(i, *k)) && wanted(t))
                    .filter_map(|(k, t)| {
                        let d = scene.cameras[c]
                            .unproject(&scene.intrinsics[c], &Vector2::new(t.x, t.y))?;
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
        let f_px = scene
            .camera_of
            .iter()
            .map(|&c| scene.cameras[c].focal_px(&scene.intrinsics[c]))
            .collect();
        Blobs {
            dets,
            rays,
            f_px,
            none_taken: DetectionSet::empty(dets),
        }
    }

    /// The blob of image `i` nearest `uv`, unless taken: within [`TOL_PX`], and the next one
    /// at least twice as far.
    fn nearest(&self, i: ImageId, uv: &Vector2<f64>, taken: &DetectionSet) -> Option<DetIdx> {
        let mut best: Option<(DetIdx, f64)> = None;
        let mut second = f64::INFINITY;
        for (k, _) in &self.rays[i] {
            if taken.contains(DetectionId::new(i, *k)) {
                continue;
            }
            let t = &self.dets[i].targets[*k];
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
            .map(|(k, _)| k)
    }
}

/// A candidate point from two detections of two images.
struct Candidate {
    /// Images whose free blobs agree with it (the two included).
    support: usize,
    /// RMS reprojection error in the two images (px).
    rms: f64,
    a: DetectionId,
    b: DetectionId,
    /// Midpoint of the two rays.
    x: Vector3<f64>,
}

/// The midpoint of the closest approach of two rays, when both meet it in front of their
/// cameras and their gap, seen from camera a (`f_px`: its principal distance in pixels),
/// is within 4 · [`TOL_PX`].
fn ray_meeting(ra: &WorldRay, rb: &WorldRay, f_px: f64) -> Option<Vector3<f64>> {
    // closest points of the two rays
    let w0 = ra.centre - rb.centre;
    let (aa, bb, cc) = (1.0, ra.dir.dot(&rb.dir), 1.0);
    let (dd, ee) = (ra.dir.dot(&w0), rb.dir.dot(&w0));
    let den = aa * cc - bb * bb;
    if den < 1e-6 {
        return None; // < ~0.08° between the rays
    }
    let s = (bb * ee - cc * dd) / den;
    let t = (aa * ee - bb * dd) / den;
    if s <= 0.0 || t <= 0.0 {
        return None;
    }
    // the rays' gap seen from camera a, in pixels, before any projection
    let gap = (ra.centre + ra.dir * s - rb.centre - rb.dir * t).norm();
    if gap / s.min(t) * f_px > 4.0 * TOL_PX {
        return None;
    }
    Some(0.5 * (ra.centre + ra.dir * s + rb.centre + rb.dir * t))
}

/// The candidate of detections `a` and `b` (rays `ra`, `rb`), if their rays meet, the point
/// reprojects within [`TOL_PX`] onto both, the numbers they read (if any) agree, and
/// enough oriented images have a free blob where it projects.
fn pair_candidate(
    scene: &Scene,
    blobs: &Blobs,
    oriented: &[ImageId],
    (a, ra): (DetectionId, &WorldRay),
    (b, rb): (DetectionId, &WorldRay),
) -> Option<Candidate> {
    let x = ray_meeting(ra, rb, blobs.f_px[a.image])?;
    let ua = scene.project_into(a.image, &x)?;
    let ub = scene.project_into(b.image, &x)?;
    let ta = blobs.dets.target(a);
    let tb = blobs.dets.target(b);
    if let (Some(na), Some(nb)) = (ta.id, tb.id) {
        if na != nb {
            return None;
        }
    }
    let ra_px = (ua - Vector2::new(ta.x, ta.y)).norm();
    let rb_px = (ub - Vector2::new(tb.x, tb.y)).norm();
    if ra_px > TOL_PX || rb_px > TOL_PX {
        return None;
    }
    let mut support = 2;
    for &o in oriented {
        if o == a.image || o == b.image {
            continue;
        }
        if let Some(uv) = scene.project_into(o, &x) {
            if blobs.nearest(o, &uv, &blobs.none_taken).is_some() {
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
    (support >= needed).then(|| Candidate {
        support,
        rms: ((ra_px * ra_px + rb_px * rb_px) / 2.0).sqrt(),
        a,
        b,
        x,
    })
}

/// Every candidate of every pair of oriented images, best supported first, then by RMS,
/// then by detection.
fn candidates(scene: &Scene, blobs: &Blobs, oriented: &[ImageId]) -> Vec<Candidate> {
    let mut cands = Vec::new();
    for (ai, &a) in oriented.iter().enumerate() {
        for &b in &oriented[ai + 1..] {
            for (ka, ra) in &blobs.rays[a] {
                for (kb, rb) in &blobs.rays[b] {
                    let da = (DetectionId::new(a, *ka), ra);
                    let db = (DetectionId::new(b, *kb), rb);
                    cands.extend(pair_candidate(scene, blobs, oriented, da, db));
                }
            }
        }
    }
    cands.sort_by(|p, q| {
        q.support
            .cmp(&p.support)
            .then(p.rms.total_cmp(&q.rms))
            .then((p.a, p.b).cmp(&(q.a, q.b)))
    });
    cands
}

/// A new point grown from a candidate: its detections and the number it carries.
struct Grown {
    obs: Vec<DetectionId>,
    number: Option<u32>,
    position: Vector3<f64>,
}

/// Grows candidate `c` with the nearest untaken blob of every other oriented image, and
/// intersects it from all its rays. None when it has too few rays, reads two numbers or
/// one the scene already has, or does not intersect within [`TOL_PX`].
fn grow(
    scene: &Scene,
    blobs: &Blobs,
    oriented: &[ImageId],
    taken: &DetectionSet,
    c: &Candidate,
) -> Option<Grown> {
    let mut obs = vec![c.a, c.b];
    for &o in oriented {
        if o == c.a.image || o == c.b.image {
            continue;
        }
        if let Some(uv) = scene.project_into(o, &c.x) {
            if let Some(k) = blobs.nearest(o, &uv, taken) {
                obs.push(DetectionId::new(o, k));
            }
        }
    }
    let mut numbers: Vec<u32> = obs
        .iter()
        .filter_map(|&d| blobs.dets.target(d).id)
        .collect();
    numbers.sort_unstable();
    numbers.dedup();
    let needed = if numbers.is_empty() {
        MIN_RAYS
    } else {
        MIN_RAYS_NUMBERED
    };
    if obs.len() < needed {
        return None;
    }
    if numbers.len() > 1 || numbers.iter().any(|n| scene.coded(*n).is_some()) {
        return None;
    }
    let ray_list: Vec<Ray> = obs
        .iter()
        .map(|&d| {
            let c = scene.camera_of[d.image];
            let t = blobs.dets.target(d);
            Ray {
                camera_from_object: scene.poses[d.image].expect("oriented"),
                model: scene.cameras[c].model.as_ref(),
                params: &scene.intrinsics[c],
                uv: Vector2::new(t.x, t.y),
            }
        })
        .collect();
    let ix = intersect(
        &ray_list,
        &IntersectionOptions {
            min_angle_deg: 1.0,
            max_rms_px: TOL_PX,
        },
    )
    .ok()?;
    Some(Grown {
        obs,
        number: numbers.first().copied(),
        position: ix.position,
    })
}

/// Step 2: new points from unused detections of one kind: round blobs (`Plain`), or coded
/// targets whose number is not in the scene yet (`Coded`: read in one image only, or not
/// read at all; a point takes the number one of its detections read, and detections that
/// read different numbers never pair). Candidates are taken greedily, best first, each
/// detection by one point at most. Returns how many were added.
pub fn new_points(dets: &Detections, scene: &mut Scene, kind: TargetKind) -> usize {
    let known: Vec<u32> = scene
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
    let blobs = Blobs::new(dets, scene, wanted);
    let oriented = scene.oriented();
    let mut taken = DetectionSet::empty(dets);
    let mut added = 0;
    let first_plain = scene
        .points
        .iter()
        .filter(|p| !matches!(p.kind, PointKind::Coded(_)))
        .count();
    for c in candidates(scene, &blobs, &oriented) {
        if taken.contains(c.a) || taken.contains(c.b) {
            continue;
        }
        let Some(g) = grow(scene, &blobs, &oriented, &taken, &c) else {
            continue;
        };
        for &d in &g.obs {
            taken.insert(d);
        }
        added += 1;
        let (name, point_kind) = match g.number {
            Some(n) => (n.to_string(), PointKind::Coded(n)),
            None => (format!("P{}", first_plain + added), PointKind::Plain),
        };
        scene.points.push(ScenePoint {
            name,
            kind: point_kind,
            position: g.position,
            obs: g.obs,
        });
    }
    added
}

/// Median size (mm) of a point's blobs: the angle between the rays through the two ends of
/// the blob's major axis (through the camera's model, so that a fisheye's compression
/// toward the edge is undone) times the point's distance.
pub fn blob_diameter_mm(dets: &Detections, scene: &Scene, p: &ScenePoint) -> Option<f64> {
    let mut d: Vec<f64> = p
        .obs
        .iter()
        .filter_map(|&o| {
            let pose = scene.poses[o.image]?;
            let c = scene.camera_of[o.image];
            let (cam, params) = (&scene.cameras[c], &scene.intrinsics[c]);
            let xc = pose.transform(&p.position);
            let e = dets.target(o).ellipse;
            let half = Vector2::new(e.theta.cos(), e.theta.sin()) * e.a;
            let centre = Vector2::new(e.cx, e.cy);
            let q1 = cam.unproject(params, &(centre + half))?;
            let q2 = cam.unproject(params, &(centre - half))?;
            let angle = q1.angle(&q2);
            cam.project(params, &xc)
                .map(|_| 2.0 * xc.norm() * (0.5 * angle).tan())
        })
        .collect();
    if d.is_empty() {
        return None;
    }
    d.sort_by(|a, b| a.total_cmp(b));
    Some(d[d.len() / 2])
}

/// Plain points inside a coded target's code ring (nearer its centre than the ring's outer
/// radius, `ring_outer` dot radii) are removed and logged: nothing else can be printed there,
/// and a ball that near would hide the target, so such a point is a piece of that ring read
/// as a blob in a few images (in the simulation, 11 and 16 mm from coded targets 342 and 29,
/// large enough to pass for balls).
fn drop_ring_pieces(project: &Project, scene: &mut Scene, rep: &Reporter) {
    let t = &project.file.targets;
    let reach = t.ring_outer * t.dot_radius_mm;
    let coded: Vec<(u32, Vector3<f64>)> = (scene.points.iter())
        .filter_map(|p| match p.kind {
            PointKind::Coded(n) => Some((n, p.position)),
            _ => None,
        })
        .collect();
    let pieces: Vec<(PointId, u32, f64)> = (scene.points.ids())
        .filter(|&j| scene.points[j].kind == PointKind::Plain)
        .filter_map(|j| {
            let x = scene.points[j].position;
            let (n, d) = (coded.iter())
                .map(|(n, c)| (*n, (x - c).norm()))
                .min_by(|a, b| a.1.total_cmp(&b.1))?;
            (d < reach).then_some((j, n, d))
        })
        .collect();
    // from the last, so that the ids still to remove stay valid
    for &(j, n, d) in pieces.iter().rev() {
        let p = scene.points.remove(j);
        rep.log(format!(
            "  a point of {} rays {d:.1} mm from coded target {n}'s centre dropped: inside its code ring ({reach:.0} mm), a piece of it",
            p.obs.len()
        ));
    }
}

/// Step 3: the plain points whose blobs are nearer the ball diameter than the target dot
/// diameter become balls, once the pieces of code rings are dropped (`drop_ring_pieces`).
/// Returns them.
pub fn classify_balls(
    project: &Project,
    dets: &Detections,
    scene: &mut Scene,
    rep: &Reporter,
) -> Result<Vec<PointId>> {
    drop_ring_pieces(project, scene, rep);
    let f = &project.file;
    let ball_d = f.balls.diameter_mm;
    let dot_d = 2.0 * f.targets.dot_radius_mm;
    let threshold = 0.5 * (ball_d + dot_d);
    let mut sizes = Vec::new();
    for j in scene.points.ids() {
        if scene.points[j].kind != PointKind::Plain {
            continue;
        }
        if let Some(d) = blob_diameter_mm(dets, scene, &scene.points[j]) {
            if d > threshold {
                scene.points[j].kind = PointKind::Ball;
                sizes.push(d);
            }
        }
    }
    let balls: Vec<PointId> = scene
        .points
        .ids()
        .filter(|&j| scene.points[j].kind == PointKind::Ball)
        .collect();
    if balls.is_empty() {
        return Err(PipelineError::Data(format!(
            "{}: no ball was found in two or more oriented images (balls of {ball_d} mm; targets of {dot_d} mm){}",
            project.path.display(),
            no_ball_diagnosis(project, dets, scene)
        )));
    }
    sizes.sort_by(|a, b| a.total_cmp(b));
    rep.log(format!(
        "balls: {} found (blob sizes {:.1}–{:.1} mm, median {:.1}; nominal {ball_d} mm, target dots {dot_d} mm)",
        balls.len(),
        sizes[0],
        sizes[sizes.len() - 1],
        sizes[sizes.len() / 2]
    ));
    Ok(balls)
}

/// Step 4: the ids of the balls, and plain targets renumbered P1… in a stable order.
pub fn name_balls(project: &Project, scene: &mut Scene, balls: &[PointId], rep: &Reporter) {
    let main = main_image(project);
    let mc = scene.camera_of[main];
    let pose = scene.poses[main].expect("main image oriented");
    let uv: Vec<Option<Vector2<f64>>> = balls
        .iter()
        .map(|&j| {
            let xc = pose.transform(&scene.points[j].position);
            scene.cameras[mc].project(&scene.intrinsics[mc], &xc)
        })
        .collect();
    let names = if project.file.balls.labels.is_empty() {
        names_by_column(&uv)
    } else {
        names_by_label(project, scene, balls, &uv, rep)
    };
    for (k, &j) in balls.iter().enumerate() {
        scene.points[j].name = names[k].clone();
    }
    let mut n = 0;
    for p in scene.points.iter_mut() {
        if p.kind == PointKind::Plain {
            n += 1;
            p.name = format!("P{n}");
        }
    }
}

/// Without labels: B1, B2, … by column (then row) in the main image.
fn names_by_column(uv: &[Option<Vector2<f64>>]) -> Vec<String> {
    let mut names = vec![String::new(); uv.len()];
    let mut order: Vec<usize> = (0..uv.len()).collect();
    order.sort_by(|&a, &b| {
        let ka = uv[a].map(|p| (p.x, p.y)).unwrap_or((f64::INFINITY, 0.0));
        let kb = uv[b].map(|p| (p.x, p.y)).unwrap_or((f64::INFINITY, 0.0));
        ka.partial_cmp(&kb).unwrap_or(std::cmp::Ordering::Equal)
    });
    for (n, &k) in order.iter().enumerate() {
        names[k] = format!("B{}", n + 1);
    }
    names
}

/// How far from its label a ball at `depth` (mm along the main camera's axis) may project
/// and still take it: 3 ball radii in pixels at that depth, at least 10 px.
fn label_reach_px(project: &Project, scene: &Scene, depth: f64) -> f64 {
    let mc = scene.camera_of[main_image(project)];
    let focal = scene.cameras[mc].focal_px(&scene.intrinsics[mc]);
    let r_px = 0.5 * project.file.balls.diameter_mm * focal / depth;
    (3.0 * r_px).max(10.0)
}

/// With labels: each label takes the nearest ball within [`label_reach_px`] of its position
/// in the main image; balls no label takes are B?1, B?2, …
fn names_by_label(
    project: &Project,
    scene: &Scene,
    balls: &[PointId],
    uv: &[Option<Vector2<f64>>],
    rep: &Reporter,
) -> Vec<String> {
    let f = &project.file;
    let pose = scene.poses[main_image(project)].expect("main image oriented");
    let mut names: Vec<Option<String>> = vec![None; balls.len()];
    for l in &f.balls.labels {
        let lp = Vector2::new(l.x, l.y);
        let best = (0..balls.len())
            .filter(|&k| names[k].is_none())
            .filter_map(|k| uv[k].map(|p| (k, (p - lp).norm())))
            .min_by(|a, b| a.1.total_cmp(&b.1));
        let Some((k, d)) = best else { continue };
        let depth = pose.transform(&scene.points[balls[k]].position).y;
        let reach = label_reach_px(project, scene, depth);
        if d <= reach {
            names[k] = Some(l.id.clone());
        } else {
            rep.log(format!(
                "  label {} at ({:.0}, {:.0}) in the main image: no ball within {reach:.0} px (nearest {d:.0} px)",
                l.id, l.x, l.y,
            ));
        }
    }
    let mut extra = 0;
    let names: Vec<String> = names
        .into_iter()
        .map(|n| {
            n.unwrap_or_else(|| {
                extra += 1;
                format!("B?{extra}")
            })
        })
        .collect();
    if extra > 0 {
        rep.log(format!(
            "  {extra} balls have no label (named B?1…); they are used as control points"
        ));
    }
    names
}

/// The labels (`[balls] labels`) of balls the images did not measure near which, in the main
/// image, one of `centres` (LRF frame) projects through `camera_from_lrf` (the scene's frame
/// from the LRF's), within the label rule's reach (`label_reach_px`: 3 ball radii at its
/// depth, at least 10 px): an LRF sphere there is the labelled ball that the photographs
/// missed, not a spurious sphere. Empty without labels or without an oriented main image.
pub fn unmeasured_labels_at(
    project: &Project,
    scene: &Scene,
    centres: &[Vector3<f64>],
    camera_from_lrf: &Rigid3,
) -> Vec<String> {
    let f = &project.file;
    let main = main_image(project);
    let Some(pose) = scene.poses[main] else {
        return Vec::new();
    };
    let mc = scene.camera_of[main];
    let measured =
        |id: &str| (scene.points.iter()).any(|p| p.kind == PointKind::Ball && p.name == id);
    let projected: Vec<(Vector2<f64>, f64)> = (centres.iter())
        .filter_map(|c| {
            let xc = pose.transform(&camera_from_lrf.transform(c));
            let uv = scene.cameras[mc].project(&scene.intrinsics[mc], &xc)?;
            (xc.y > 0.0).then(|| (uv, label_reach_px(project, scene, xc.y)))
        })
        .collect();
    (f.balls.labels.iter())
        .filter(|l| !measured(&l.id))
        .filter(|l| {
            let lp = Vector2::new(l.x, l.y);
            (projected.iter()).any(|(uv, reach)| (uv - lp).norm() <= *reach)
        })
        .map(|l| l.id.clone())
        .collect()
}

/// A quick adjustment of the scene as it stands (no rig, no snooping); measurements more
/// than `3 ·` [`TOL_PX`] from their point afterwards are dropped (a coded one beyond the reach
/// of its own ring as a named blunder, [`coded_blunder`]), and points left with fewer than
/// two.
pub fn refine(
    project: &Project,
    dets: &Detections,
    scene: &mut Scene,
    opts: &Options,
) -> Result<()> {
    let mut sp = SceneProblem::build(project, dets, scene, Datum::MainImage, None);
    let options = solver::Options {
        max_iterations: 30,
        threads: opts.threads,
        ..solver::Options::default()
    };
    solver::solve(&mut sp.problem, &options, |_| {}).map_err(|e| {
        PipelineError::Adjustment(format!("bundle adjustment during matching: {e}"))
    })?;
    sp.write_back(scene);
    let limit = 3.0 * TOL_PX;
    let mut drop: Vec<(PointId, DetectionId, f64)> = Vec::new();
    for (o, ob) in sp.problem.observations.iter().enumerate() {
        if let Some(r) = sp.problem.residual(ob) {
            if r.norm() > limit {
                let (j, d) = sp.map.observations[o];
                drop.push((j, d, r.norm()));
            }
        }
    }
    for (j, d, off) in drop {
        scene.points[j].obs.retain(|&o| o != d);
        if let PointKind::Coded(n) = scene.points[j].kind {
            if let Some(b) = coded_blunder(project, dets, d, n, off, "matching") {
                scene.add_blunder(b);
            }
        }
    }
    scene.points.retain(|p| p.obs.len() >= 2);
    Ok(())
}

/// One round: driveback, then new coded targets, then new round blobs. Returns the
/// measurements and the points added.
fn round(dets: &Detections, scene: &mut Scene) -> (usize, usize) {
    let a = driveback(dets, scene, TOL_PX);
    let n = new_points(dets, scene, TargetKind::Coded) + new_points(dets, scene, TargetKind::Plain);
    (a, n)
}

/// Runs steps 1–4 with bundle adjustments in between.
pub fn add_points(
    project: &Project,
    dets: &Detections,
    scene: &mut Scene,
    opts: &Options,
    rep: &Reporter,
) -> Result<()> {
    let pb = rep.task("matching targets", 3);
    let blunders_before = scene.blunders.len();
    let (a1, n1) = round(dets, scene);
    pb.advance(1);
    refine(project, dets, scene, opts)?;
    let (a2, n2) = round(dets, scene);
    pb.advance(1);
    refine(project, dets, scene, opts)?;
    let a3 = driveback(dets, scene, TOL_PX);
    pb.finish();
    rep.log(format!(
        "matching: {} measurements added by driveback, {} new points by multi-image matching",
        a1 + a2 + a3,
        n1 + n2
    ));
    let removed = super::network::coincident_coded(project, dets, scene);
    if removed > 0 {
        rep.log(format!(
            "  {removed} coded point(s) removed: another coded point lies within its code ring"
        ));
    }
    super::network::log_blunders(project, dets, scene, blunders_before, rep);
    let balls = classify_balls(project, dets, scene, rep)?;
    name_balls(project, scene, &balls, rep);
    Ok(())
}

/// Why no ball was found, as far as the scene tells: a clause to append to the error
/// (empty when nothing stands out). Checked in this order, the first that applies wins:
/// 1. fewer oriented images than a plain point needs rays ([`MIN_RAYS`]);
/// 2. a principal distance that no lens has (under 0.1 or over 20 sensor widths), most
///    often a value in µm or in pixels;
/// 3. the coded targets' dots, whose size the project gives, measuring a factor of two or
///    more from it: the network's scale is wrong, so the distances' unit is suspect;
/// 4. no plain blob as large as the threshold between dot and ball: the ball diameter.
fn no_ball_diagnosis(project: &Project, dets: &Detections, scene: &Scene) -> String {
    let f = &project.file;
    let oriented = scene.oriented();
    if oriented.len() < MIN_RAYS {
        // with more images than are oriented, the cure is orienting them, not new stations
        let cure = match scene.unoriented.first() {
            Some((i, why)) => format!(
                "the others were not oriented ({}: {why}{}): more coded targets in common, or [targets] layout",
                image_file(project, *i),
                if scene.unoriented.len() > 1 { ", …" } else { "" }
            ),
            None => "add stations".into(),
        };
        return format!(
            ": only {} of {} images are oriented and a ball needs {MIN_RAYS} rays: {cure}",
            oriented.len(),
            f.images.len()
        );
    }
    if let Some(c) = implausible_principal_distance(project) {
        return c;
    }
    let dot_d = 2.0 * f.targets.dot_radius_mm;
    let coded = blob_sizes(dets, scene, true);
    if let Some(&m) = coded.get(coded.len() / 2) {
        let ratio = m / dot_d;
        if !(0.5..=2.0).contains(&ratio) {
            let distances = f.distances.iter().map(|d| d.distance_mm);
            let span =
                distances.clone().fold(f64::INFINITY, f64::min)..distances.fold(0.0, f64::max);
            return format!(
                ": the coded targets' dots measure {m:.3} mm across (median of {}) where the project says {dot_d} mm, \
                 so the network's scale is {} times the true one: are the distances ({}–{} mm) in mm, and dot_radius_mm a radius?",
                coded.len(),
                factor(ratio),
                span.start,
                span.end
            );
        }
    }
    let plain = blob_sizes(dets, scene, false);
    let threshold = 0.5 * (f.balls.diameter_mm + dot_d);
    match plain.last() {
        None => ": no plain target or ball was intersected".into(),
        Some(&largest) => format!(
            ": the largest of {} plain blobs measures {largest:.1} mm, below the {threshold:.1} mm between dot and ball: \
             is [balls] diameter_mm right?",
            plain.len()
        ),
    }
}

/// The blob diameters (mm) of the coded (or else the plain) points, sorted.
fn blob_sizes(dets: &Detections, scene: &Scene, coded: bool) -> Vec<f64> {
    let mut v: Vec<f64> = scene
        .points
        .iter()
        .filter(|p| match p.kind {
            PointKind::Coded(_) => coded,
            PointKind::Plain => !coded,
            PointKind::Ball => false,
        })
        .filter_map(|p| blob_diameter_mm(dets, scene, p))
        .collect();
    v.sort_by(|a, b| a.total_cmp(b));
    v
}

/// `x` as a factor a person reads at a glance: 0.49, 1000, 1.0e-4.
fn factor(x: f64) -> String {
    if (0.01..100.0).contains(&x) {
        format!("{x:.2}")
    } else {
        format!("{x:.1e}")
    }
}

/// The first camera whose initial focal length is under 0.1 or over 20 sensor widths (a
/// 600 mm lens on a 36 mm sensor is 17), as an error clause.
pub(super) fn implausible_principal_distance(project: &Project) -> Option<String> {
    project.file.cameras.iter().enumerate().find_map(|(k, c)| {
        let focal_px = SceneCamera::of(c).focal_px(&c.intrinsics().values);
        let rel = focal_px / c.width as f64;
        (!(0.1..=20.0).contains(&rel)).then(|| match c.model.in_mm() {
            true => {
                let width = c.width as f64 * c.pixel_size_mm;
                format!(
                    ": cameras[{k}] c_mm = {} is {} sensor widths ({} px of {} mm = {width:.3} mm): is it in mm?",
                    focal_px * c.pixel_size_mm,
                    factor(rel),
                    c.width,
                    c.pixel_size_mm
                )
            }
            false => format!(
                ": cameras[{k}] fx, fy = {focal_px} px is {} image widths ({} px): is it in pixels?",
                factor(rel),
                c.width
            ),
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::adjust::tests::fixture;
    use pingcal_project::BallLabel;

    /// A sphere matched to no ball is explained by the label of a ball the images did not
    /// measure only when it projects within the label rule's reach of that label, and a
    /// measured ball's label explains nothing.
    #[test]
    fn an_unmatched_sphere_at_an_unmeasured_label_is_that_ball() {
        let (mut project, _, mut scene) = fixture();
        let main = main_image(&project);
        let mc = scene.camera_of[main];
        let pixel = |scene: &Scene, x: Vector3<f64>| {
            let xc = scene.poses[main].unwrap().transform(&x);
            scene.cameras[mc]
                .project(&scene.intrinsics[mc], &xc)
                .unwrap()
        };
        let measured = Vector3::new(-100.0, 1500.0, 50.0);
        scene.points.push(ScenePoint {
            name: "B1".into(),
            kind: PointKind::Ball,
            position: measured,
            obs: Vec::new(),
        });
        let missed = Vector3::new(200.0, 1500.0, -80.0);
        for (id, at) in [("B1", measured), ("B2", missed)] {
            let uv = pixel(&scene, at);
            project.file.balls.labels.push(BallLabel {
                id: id.into(),
                x: uv.x + 3.0,
                y: uv.y - 2.0,
            });
        }
        let id = Rigid3::identity();
        let at = |p: &Project, c: &[Vector3<f64>]| unmeasured_labels_at(p, &scene, c, &id);
        assert_eq!(at(&project, &[missed]), vec!["B2".to_string()]);
        assert!(at(&project, &[measured]).is_empty(), "B1 is measured");
        let far = Vector3::new(600.0, 1500.0, 300.0);
        assert!(at(&project, &[far]).is_empty(), "far from both");
        project.file.balls.labels.clear();
        assert!(
            at(&project, &[missed]).is_empty(),
            "no labels, no explanation"
        );
    }
}
