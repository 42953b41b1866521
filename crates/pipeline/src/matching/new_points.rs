//! Step 2 of matching: new points from pairs of unused detections whose rays meet, grown
//! with the blobs of the other oriented images and intersected from all their rays.

use super::{MIN_RAYS, MIN_RAYS_NUMBERED, TOL_PX};
use crate::ids::{DetIdx, DetectionId, IdVec, ImageId};
use crate::scene::{DetectionSet, Detections, PointKind, Scene, ScenePoint};
use nalgebra::{Vector2, Vector3};
use pingcal_ba::camera::CameraModel;
use pingcal_ba::initial::intersection::{intersect, IntersectionOptions, Ray};
use pingcal_targets::{Target, TargetKind};

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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::network::tests::{blob, Field};

    /// Two rays that cross give the crossing; rays that meet behind a camera, nearly
    /// parallel rays, and rays that pass more than 4 · [`TOL_PX`] apart (seen from camera
    /// a, principal distance 1000 px) give none.
    #[test]
    fn rays_meet_only_ahead_of_both_cameras_and_within_the_tolerance() {
        let x = Vector3::new(30.0, 2000.0, -40.0);
        let ray = |c: Vector3<f64>, to: Vector3<f64>| WorldRay {
            centre: c,
            dir: (to - c).normalize(),
        };
        let (ca, cb) = (
            Vector3::new(-400.0, 0.0, 0.0),
            Vector3::new(400.0, 0.0, 0.0),
        );
        let met = ray_meeting(&ray(ca, x), &ray(cb, x), 1000.0).expect("they cross");
        assert!((met - x).norm() < 1e-9, "{met}");
        // rays looking ahead whose lines cross 2 m behind the cameras
        let behind = Vector3::new(0.0, -2000.0, 0.0);
        let away = |c: Vector3<f64>| ray(c, 2.0 * c - behind);
        assert!(
            ray_meeting(&away(ca), &away(cb), 1000.0).is_none(),
            "behind"
        );
        let far = Vector3::new(0.0, 1e7, 0.0);
        assert!(
            ray_meeting(&ray(ca, far), &ray(cb, far), 1000.0).is_none(),
            "parallel"
        );
        // 20 mm apart at 2 m: 10 px from camera a, beyond 8 px
        let skew = ray(cb, x + Vector3::new(0.0, 0.0, 20.0));
        assert!(ray_meeting(&ray(ca, x), &skew, 1000.0).is_none());
        let near = ray(cb, x + Vector3::new(0.0, 0.0, 12.0));
        assert!(ray_meeting(&ray(ca, x), &near, 1000.0).is_some(), "6 px");
    }

    /// With the images oriented and the coded targets measured, the plain blobs of five
    /// images become the six plain points: each at its true position, measured by its own
    /// blob in every image it projects into. A seventh point whose blobs are in two images
    /// only (fewer than [`MIN_RAYS`]) is not made, and no blob is taken twice.
    #[test]
    fn new_points_intersect_the_plain_blobs_of_a_field_made_in_memory() {
        let field = Field::new();
        let mut dets = field.detections(true);
        let lone = Vector3::new(250.0, 2100.0, -250.0);
        let mut scene = field.scene_with_coded(&dets, &[0, 1, 2, 3, 4]);
        for i in [ImageId(1), ImageId(3)] {
            let uv = scene.project_into(i, &lone).expect("in view");
            let mut targets: Vec<Target> = dets[i].targets.iter().cloned().collect();
            targets.push(blob(uv, None));
            dets[i].ball_fits = vec![None; targets.len()].into();
            dets[i].targets = targets.into();
        }
        let coded = scene.points.len();
        let added = new_points(&dets, &mut scene, TargetKind::Plain);
        assert_eq!(added, field.plain.len());
        let oriented = scene.oriented();
        let mut taken = DetectionSet::empty(&dets);
        for p in scene.points.iter().skip(coded) {
            assert_eq!(p.kind, PointKind::Plain);
            let truth = (field.plain.iter())
                .find(|x| (*x - p.position).norm() < 1e-3)
                .unwrap_or_else(|| panic!("{} at {} is no plain point", p.name, p.position));
            let visible = (oriented.iter())
                .filter(|&&i| scene.project_into(i, truth).is_some())
                .count();
            assert_eq!(p.obs.len(), visible, "{}: one ray per image", p.name);
            for &d in &p.obs {
                assert!(!taken.contains(d), "{}: a blob taken twice", p.name);
                taken.insert(d);
                let uv = scene.project_into(d.image, truth).expect("in view");
                let t = dets.target(d);
                assert!(
                    (uv - Vector2::new(t.x, t.y)).norm() < 1e-6,
                    "{}: another's blob",
                    p.name
                );
            }
        }
        assert!(scene
            .points
            .iter()
            .all(|p| (p.position - lone).norm() > 100.0));
    }
}
