//! Step 3 of matching: balls told from plain targets by the size of their blobs in
//! millimetres.

use super::diagnosis::no_ball_diagnosis;
use super::sizes::blob_diameter_mm;
use crate::context::{PipelineError, Result};
use crate::ids::PointId;
use crate::progress::Reporter;
use crate::scene::{Detections, PointKind, Scene};
use nalgebra::Vector3;
use pingcal_project::Project;

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
