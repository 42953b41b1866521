//! Why no ball was found: the clause that the error of step 3 ends with.

use super::sizes::blob_sizes;
use super::MIN_RAYS;
use crate::scene::{image_file, sensor_camera, Detections, Scene};
use pingcal_ba::camera::CameraModel;
use pingcal_project::Project;

/// Why no ball was found, as far as the scene tells: a clause to append to the error
/// (empty when nothing stands out). Checked in this order, the first that applies wins:
/// 1. fewer oriented images than a plain point needs rays ([`MIN_RAYS`]);
/// 2. a principal distance that no lens has (under 0.1 or over 20 sensor widths), most
///    often a value in µm or in pixels;
/// 3. the coded targets' dots, whose size the project gives, measuring a factor of two or
///    more from it: the network's scale is wrong, so the distances' unit is suspect;
/// 4. no plain blob as large as the threshold between dot and ball: the ball diameter.
pub(super) fn no_ball_diagnosis(project: &Project, dets: &Detections, scene: &Scene) -> String {
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
pub(crate) fn implausible_principal_distance(project: &Project) -> Option<String> {
    project.file.cameras.iter().enumerate().find_map(|(k, c)| {
        let focal_px = sensor_camera(c).focal_px(&c.intrinsics().values);
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
