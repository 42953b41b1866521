//! The size of a point's blobs in millimetres, which tells balls from targets (step 3 of
//! matching) and, when no ball was found, the network's scale from the coded targets' dots.

use crate::scene::{Detections, PointKind, Scene, ScenePoint};
use nalgebra::Vector2;
use pingcal_ba::camera::CameraModel;

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
            cam.project(params, &xc, None, None)
                .map(|_| 2.0 * xc.norm() * (0.5 * angle).tan())
        })
        .collect();
    if d.is_empty() {
        return None;
    }
    d.sort_by(|a, b| a.total_cmp(b));
    Some(d[d.len() / 2])
}

/// The blob diameters (mm) of the coded (or else the plain) points, sorted.
pub(super) fn blob_sizes(dets: &Detections, scene: &Scene, coded: bool) -> Vec<f64> {
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
