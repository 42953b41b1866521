//! Step 4 of matching: the balls' ids, from the project's labels in the main image or by
//! column; and the labels of balls the images missed, near which an LRF sphere lies.

use crate::ids::PointId;
use crate::progress::Reporter;
use crate::scene::{main_image, PointKind, Scene};
use nalgebra::{Vector2, Vector3};
use pingcal_ba::camera::CameraModel;
use pingcal_geometry::Rigid3;
use pingcal_project::Project;

/// Step 4: the ids of the balls, and plain targets renumbered P1… in a stable order.
pub fn name_balls(project: &Project, scene: &mut Scene, balls: &[PointId], rep: &Reporter) {
    let main = main_image(project);
    let mc = scene.camera_of[main];
    let pose = scene.poses[main].expect("main image oriented");
    let uv: Vec<Option<Vector2<f64>>> = balls
        .iter()
        .map(|&j| {
            let xc = pose.transform(&scene.points[j].position);
            scene.cameras[mc].project(&scene.intrinsics[mc], &xc, None, None)
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
            let uv = scene.cameras[mc].project(&scene.intrinsics[mc], &xc, None, None)?;
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::adjust::tests::fixture;
    use crate::scene::ScenePoint;
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
                .project(&scene.intrinsics[mc], &xc, None, None)
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

    /// Without labels the balls are B1, B2, … from left to right in the main image (then top
    /// to bottom at one column), and a ball that does not project into it comes last.
    #[test]
    fn without_labels_balls_are_numbered_by_column_then_row() {
        let uv = [
            Some(Vector2::new(300.0, 50.0)),
            None,
            Some(Vector2::new(100.0, 400.0)),
            Some(Vector2::new(300.0, 20.0)),
            Some(Vector2::new(200.0, 10.0)),
        ];
        assert_eq!(names_by_column(&uv), ["B4", "B5", "B1", "B3", "B2"]);
    }
}
