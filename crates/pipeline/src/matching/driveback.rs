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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ids::ImageId;
    use crate::matching::TOL_PX;
    use crate::network::tests::Field;

    /// Driveback gives each point the detection at its projection in every image that does
    /// not measure it yet, and nothing else: in image 0 a plain blob moved 2.5 px (beyond
    /// [`TOL_PX`]) stays free, and the detection where coded target 2 projects but which
    /// reads 99 is a named blunder of that number, not a measurement of 2.
    #[test]
    fn driveback_takes_each_projection_s_blob_and_refuses_a_wrong_number() {
        let field = Field::new();
        let mut dets = field.detections(true);
        let i0 = ImageId(0);
        let wrong = (dets[i0].targets.ids())
            .find(|&k| dets[i0].targets[k].id == Some(2))
            .expect("target 2 in image 0");
        dets[i0].targets[wrong].id = Some(99);
        let first_plain = (dets[i0].targets.ids())
            .find(|&k| dets[i0].targets[k].kind == TargetKind::Plain)
            .expect("a plain blob in image 0");
        let moved = (
            dets[i0].targets[first_plain].x,
            dets[i0].targets[first_plain].y,
        );
        dets[i0].targets[first_plain].x += 2.5;
        let mut scene = field.scene_with_coded(&dets, &[1, 2, 3, 4]);
        for (k, x) in field.plain.iter().enumerate() {
            scene.points.push(ScenePoint {
                name: format!("P{}", k + 1),
                kind: PointKind::Plain,
                position: *x,
                obs: Vec::new(),
            });
        }
        let before: Vec<usize> = scene.points.iter().map(|p| p.obs.len()).collect();
        let added = driveback(&dets, &mut scene, TOL_PX);

        let images = scene.oriented();
        let mut expected = 0;
        for (j, p) in scene.points.iter_enumerated() {
            let new = &p.obs[before[j.0]..];
            for &d in new {
                let uv = scene.project_into(d.image, &p.position).expect("in view");
                let t = dets.target(d);
                assert!(
                    (uv.x - t.x).hypot(uv.y - t.y) < 1e-6,
                    "{} took a blob off its projection",
                    p.name
                );
                assert!(
                    d != DetectionId::new(i0, wrong),
                    "{} took the wrong number",
                    p.name
                );
            }
            let visible = (images.iter())
                .filter(|&&i| scene.project_into(i, &p.position).is_some())
                .count();
            let measured_before = if p.kind == PointKind::Plain { 0 } else { 4 };
            let refused = match (&p.kind, p.name.as_str()) {
                (PointKind::Coded(2), _) => 1,
                (PointKind::Plain, _) if p.obs.iter().all(|d| d.image != i0) => {
                    let uv = scene.project_into(i0, &p.position).expect("P1 in image 0");
                    assert!(
                        (uv.x - moved.0).hypot(uv.y - moved.1) < 1e-6,
                        "{} missed image 0",
                        p.name
                    );
                    1
                }
                _ => 0,
            };
            assert_eq!(p.obs.len(), visible - refused, "{}", p.name);
            expected += visible - measured_before - refused;
        }
        assert_eq!(added, expected);
        assert_eq!(scene.blunders.len(), 1);
        let b = &scene.blunders[0];
        assert_eq!(
            (b.det, b.number, b.stage),
            (DetectionId::new(i0, wrong), 99, "driveback")
        );
        assert!(b.why.starts_with("where target 2 is"), "{}", b.why);
    }
}
