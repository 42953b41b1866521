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
//!
//! One file per job: driveback (step 1, `driveback.rs`), new points by multi-image matching
//! (step 2, `new_points.rs`), balls told from targets (step 3, `balls.rs`; why none was
//! found, `diagnosis.rs`; both measure the blobs in mm, `sizes.rs`), their names (step 4,
//! `names.rs`); this file runs them in rounds with [`refine`] between.

mod balls;
mod diagnosis;
mod driveback;
mod names;
mod new_points;
mod sizes;

pub use balls::classify_balls;
pub(crate) use diagnosis::implausible_principal_distance;
pub use driveback::driveback;
pub use names::{name_balls, unmeasured_labels_at};
pub use new_points::new_points;
pub use sizes::blob_diameter_mm;

use crate::adjust::{head_cameras, rig_starts, Datum, SceneProblem};
use crate::context::{Options, PipelineError, Result};
use crate::ids::{DetectionId, ImageId, PointId};
use crate::progress::Reporter;
use crate::scene::{coded_blunder, Detections, PointKind, Scene};
use pingcal_ba::solver;
use pingcal_project::Project;
use pingcal_targets::TargetKind;

/// Largest distance (px) between a projection and the detection that takes it.
pub const TOL_PX: f64 = 2.0;
/// Fewest rays of a new point.
pub const MIN_RAYS: usize = 3;
/// Fewest rays of a new coded target whose number one of its detections read: the number
/// already says which target it is, so one more ray on its epipolar line suffices.
pub const MIN_RAYS_NUMBERED: usize = 2;

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
    let mut sp = SceneProblem::build(project, dets, scene, Datum::MainImage, &[]);
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
    place_rig_members(project, dets, scene, rep);
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

/// Fewest points of the network a rig member placed through its rig must measure to stay.
pub const MIN_PLACED_POINTS: usize = 2;

/// The images of the head's cameras ([`head_cameras`]) that the network start left
/// unoriented — too few points of their own to be resected — whose station's base image
/// is oriented: each is put at the base image's pose through its rig's start
/// ([`rig_starts`]: the images' own orientations at other stations, else the project's
/// pose), given the network's points at their projections (driveback), and kept when it
/// then measures [`MIN_PLACED_POINTS`] or more of them; the final adjustment's rig ties it
/// to its base image. A camera that sees only a few targets at each station is tied to the
/// field this way. Returns how many were placed.
pub fn place_rig_members(
    project: &Project,
    dets: &Detections,
    scene: &mut Scene,
    rep: &Reporter,
) -> usize {
    let f = &project.file;
    let starts = rig_starts(project, scene);
    let mut placed = Vec::new();
    for (head, start) in head_cameras(project).iter().zip(starts) {
        let Some(member_from_base) = start else {
            continue;
        };
        for (i, why) in scene.unoriented.clone() {
            let im = &f.images[i.0];
            let base = (f.images.iter())
                .position(|b| b.station == im.station && b.camera == head.base)
                .and_then(|b| scene.poses[ImageId(b)]);
            if let (true, Some(base)) = (im.camera == head.camera, base) {
                scene.poses[i] = Some(member_from_base.compose(&base));
                placed.push((i, why));
            }
        }
    }
    if placed.is_empty() {
        return 0;
    }
    driveback(dets, scene, TOL_PX);
    let mut kept = 0;
    for (i, why) in placed {
        let seen = scene
            .points
            .iter()
            .filter(|p| p.obs.iter().any(|d| d.image == i))
            .count();
        let file = &f.images[i.0].file;
        if seen >= MIN_PLACED_POINTS {
            scene.unoriented.retain(|(u, _)| *u != i);
            rep.log(format!(
                "  {file}: placed through its rig (it {why}); it measures {seen} points of the network"
            ));
            kept += 1;
        } else {
            scene.poses[i] = None;
            for p in scene.points.iter_mut() {
                p.obs.retain(|d| d.image != i);
            }
        }
    }
    scene.points.retain(|p| p.obs.len() >= 2);
    kept
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ids::ImageId;
    use crate::network::tests::Field;

    /// After the quick adjustment, a coded measurement moved 15 px off its target (what the
    /// adjustment leaves of it is beyond 3 · [`TOL_PX`]) is dropped from its point, and every
    /// exact measurement stays. Whether it is also a named blunder depends on its own code
    /// ring's reach (3 dot semi-axes): with dots of 3 px its residual is within 9 px, a poor
    /// centre; with dots of 1 px it is beyond 3 px, a number read where its target is not.
    #[test]
    fn refine_drops_a_measurement_far_from_its_point_and_names_it_beyond_its_ring() {
        let field = Field::new();
        for (dot_px, named) in [(3.0, false), (1.0, true)] {
            let mut dets = field.detections(false);
            let mut scene = field.scene_with_coded(&dets, &[0, 1, 2, 3, 4]);
            let off = scene.points[PointId(6)].obs[3];
            assert_eq!(off.image, ImageId(3));
            let t = &mut dets[off.image].targets[off.det];
            t.x += 15.0;
            t.ellipse.a = dot_px;
            let before: usize = scene.points.iter().map(|p| p.obs.len()).sum();
            refine(&field.project, &dets, &mut scene, &Options::default()).expect("adjusted");
            let after: usize = scene.points.iter().map(|p| p.obs.len()).sum();
            assert_eq!(after, before - 1, "dots of {dot_px} px");
            assert!(!scene.points[PointId(6)].obs.contains(&off));
            assert_eq!(
                scene.blunders.len(),
                usize::from(named),
                "dots of {dot_px} px"
            );
            if let Some(b) = scene.blunders.first() {
                assert_eq!((b.det, b.number, b.stage), (off, 7, "matching"));
            }
        }
    }
}
