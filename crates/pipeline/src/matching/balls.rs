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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ids::DetectionId;
    use crate::network::tests::{blob, Field};
    use crate::scene::ScenePoint;
    use pingcal_targets::ellipse::Ellipse;
    use pingcal_targets::Target;

    /// The field's scene with its coded targets, and a plain point at each of `points`
    /// measured in every image by a blob of `size_mm` across (its own size in pixels at
    /// its depth in each image).
    fn scene_with_blobs(field: &Field, points: &[(Vector3<f64>, f64)]) -> (Detections, Scene) {
        let mut dets = field.detections(false);
        let mut scene = field.scene_with_coded(&dets, &[0, 1, 2, 3, 4]);
        for (k, &(x, size_mm)) in points.iter().enumerate() {
            let mut obs = Vec::new();
            for i in scene.oriented() {
                let Some(uv) = scene.project_into(i, &x) else {
                    continue;
                };
                let depth = scene.poses[i].expect("oriented").transform(&x).y;
                let mut t = blob(uv, None);
                t.ellipse = Ellipse::circle(uv.x, uv.y, 0.5 * size_mm * 1000.0 / depth);
                let mut targets: Vec<Target> = dets[i].targets.iter().cloned().collect();
                targets.push(t);
                let det = DetectionId::new(i, crate::ids::DetIdx(targets.len() - 1));
                dets[i].ball_fits = vec![None; targets.len()].into();
                dets[i].targets = targets.into();
                obs.push(det);
            }
            scene.points.push(ScenePoint {
                name: format!("P{}", k + 1),
                kind: PointKind::Plain,
                position: x,
                obs,
            });
        }
        (dets, scene)
    }

    /// Blobs of 38 mm (the project's balls) make balls and blobs of 10 mm (its target dots)
    /// stay plain targets, whatever their depth; a 38 mm blob 10 mm from coded target 5's
    /// centre, inside its code ring (15 mm), is a piece of that ring: dropped, not a ball.
    #[test]
    fn blobs_of_the_ball_s_size_are_balls_and_a_piece_of_a_code_ring_is_dropped() {
        let field = Field::new();
        let ring_piece = field.coded[4].1 + Vector3::new(10.0, 0.0, 0.0);
        let points = [
            (field.plain[0], 38.0),
            (field.plain[1], 10.0),
            (field.plain[2], 38.0),
            (field.plain[3], 10.0),
            (ring_piece, 38.0),
            (field.plain[5], 38.0),
        ];
        let (dets, mut scene) = scene_with_blobs(&field, &points);
        let rep = Reporter::silent();
        let balls = classify_balls(&field.project, &dets, &mut scene, &rep).expect("balls");
        let names: Vec<&str> = balls
            .iter()
            .map(|&j| scene.points[j].name.as_str())
            .collect();
        assert_eq!(names, ["P1", "P3", "P6"]);
        let plain: Vec<&str> = (scene.points.iter())
            .filter(|p| p.kind == PointKind::Plain)
            .map(|p| p.name.as_str())
            .collect();
        assert_eq!(plain, ["P2", "P4"], "P5 dropped");
        let lines = rep.lines();
        assert!(
            lines
                .iter()
                .any(|l| l.contains("from coded target 5's centre dropped")),
            "{lines:?}"
        );
        assert!(
            lines.iter().any(|l| l.starts_with("balls: 3 found")),
            "{lines:?}"
        );
    }

    /// With no blob larger than halfway between a target dot and a ball, no ball is found:
    /// the error names the project and says what to check (the largest blob's size against
    /// the threshold, and the ball diameter).
    #[test]
    fn no_blob_of_a_ball_s_size_is_an_error_that_says_what_to_check() {
        let field = Field::new();
        let points = [(field.plain[0], 10.0), (field.plain[1], 20.0)];
        let (dets, mut scene) = scene_with_blobs(&field, &points);
        let e = classify_balls(&field.project, &dets, &mut scene, &Reporter::silent())
            .expect_err("no ball")
            .to_string();
        assert!(e.starts_with("project.toml: no ball was found"), "{e}");
        // 20 mm across the blob's width at its depth: a little less across its distance
        let at = e
            .find("the largest of 2 plain blobs measures ")
            .expect("the largest")
            + 38;
        let mm: f64 = e[at..].split(' ').next().unwrap().parse().unwrap();
        assert!((19.0..=20.0).contains(&mm), "{e}");
        assert!(e.ends_with("is [balls] diameter_mm right?"), "{e}");
    }
}
