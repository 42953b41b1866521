//! Step 1 of matching: every scene point projected into every oriented image that does not
//! measure it yet takes the nearest free detection of its kind ("driveback").

use crate::ids::{DetectionId, PointId};
use crate::scene::{CodedBlunder, Detections, PointKind, Scene, ScenePoint};
use pingcal_targets::driveback::{assign, Predicted};
use pingcal_targets::{Target, TargetKind};

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
