//! The head's exports beyond the stereo pair (issue 52): `ros/head.urdf`, every sensor of
//! results.json's `sensors` as a fixed joint from the main camera's optical frame, and the
//! cameras of `[rig]` in Kalibr's camera chain.
//!
//! Frames: a camera's child frame is its OpenCV optical frame `<id>_optical` (x right, y
//! down, z forward), so its joint is `C R Cᵀ, C t` of `camera_from_sensor`
//! (`C` = [`crate::results::cv_from_photogrammetric`]); the LRF's is the LRF frame, so its
//! joint is `C R, C t`, as `ros/laser_joint.urdf`'s.

use super::{num, nums, rpy};
use crate::results::{cv_from_photogrammetric, ExtrinsicJson, Results};
use nalgebra::{Matrix3, Vector3};
use std::fmt::Write;

/// `p_parent = R p_child + t` of a sensor's joint (R, t in mm), in the frames above.
pub(super) fn joint_of(e: &ExtrinsicJson, camera: bool) -> (Matrix3<f64>, Vector3<f64>) {
    let c = cv_from_photogrammetric();
    let r = Matrix3::from_fn(|i, j| e.rotation[i][j]);
    let t = Vector3::from(e.translation_mm);
    if camera {
        (c * r * c.transpose(), c * t)
    } else {
        (c * r, c * t)
    }
}

/// The tf frame of sensor `id` of `r`: a camera's `<id>_optical`, `[lrf]`'s the project's
/// LRF frame (`tf_lrf_frame`), each of `[[lrfs]]`'s its id.
pub(super) fn frame_of(r: &Results, id: &str, kind: &str) -> String {
    let first_range = r.sensors.iter().find(|s| s.kind != "camera");
    if kind == "camera" {
        format!("{id}_optical")
    } else if first_range.is_some_and(|s| s.id == id) {
        r.conventions.tf_lrf_frame.clone()
    } else {
        id.to_string()
    }
}

/// `ros/head.urdf`, or None when the head has no sensor but the LRF (`laser_joint.urdf`
/// is that one).
pub fn head_urdf(r: &Results) -> Option<String> {
    if !r.sensors.iter().any(|s| s.kind == "camera") {
        return None;
    }
    let conv = &r.conventions;
    let parent = &conv.tf_camera_frame;
    let mut out = format!(
        "<?xml version=\"1.0\"?>\n<!-- Every sensor of the head as a fixed joint from '{parent}', the main camera '{}''s optical frame (written by pingcal calibrate, results.json's sensors): a camera's child frame is its optical frame '<id>_optical' (x right, y down, z forward), [lrf]'s '{}', each of [[lrfs]]'s its id; p_parent = R p_child + t, t in m. A rotating LRF's servo chain below its frame is in lrf_model.urdf. Copy the <joint>s into your robot's URDF (its links are yours). -->\n<robot name=\"pingcal_head\">\n  <link name=\"{parent}\"/>\n",
        conv.main_camera, conv.tf_lrf_frame
    );
    for s in &r.sensors {
        let child = frame_of(r, &s.id, &s.kind);
        let (rot, t) = joint_of(&s.camera_from_sensor, s.kind == "camera");
        let xyz: Vec<String> = t.iter().map(|v| num(v / 1000.0)).collect();
        let _ = write!(
            out,
            "  <link name=\"{child}\"/>\n  <joint name=\"{parent}_to_{child}_joint\" type=\"fixed\">\n    <parent link=\"{parent}\"/>\n    <child link=\"{child}\"/>\n    <origin xyz=\"{}\" rpy=\"{}\"/>\n  </joint>\n",
            xyz.join(" "),
            rpy(&rot).map(num).join(" ")
        );
    }
    out.push_str("</robot>\n");
    Some(out)
}

/// Kalibr's `T_cn_cnm1` of camera `next` after camera `prev` (ids; the main camera has no
/// entry in `sensors`): `p_next = T p_prev` in OpenCV frames, t in m, from `sensors`.
pub fn t_cn_cnm1(r: &Results, prev: &str, next: &str) -> Option<(Matrix3<f64>, Vector3<f64>)> {
    let pose = |id: &str| {
        if id == r.conventions.main_camera {
            return Some((Matrix3::identity(), Vector3::zeros()));
        }
        let s = r
            .sensors
            .iter()
            .find(|s| s.id == id && s.kind == "camera")?;
        Some(joint_of(&s.camera_from_sensor, true))
    };
    let ((rp, tp), (rn, tn)) = (pose(prev)?, pose(next)?);
    // main_from_next⁻¹ · main_from_prev
    Some((rn.transpose() * rp, rn.transpose() * (tp - tn) / 1000.0))
}

/// Writes `T_cn_cnm1` (`rot`, `t` in m) as Kalibr's 4 × 4.
pub(super) fn write_t_cn_cnm1(out: &mut String, rot: &Matrix3<f64>, t: &Vector3<f64>) {
    let _ = writeln!(out, "  T_cn_cnm1:");
    for i in 0..3 {
        let row = [rot[(i, 0)], rot[(i, 1)], rot[(i, 2)]];
        let _ = writeln!(out, "  - [{}, {}]", nums(&row), num(t[i]));
    }
    let _ = writeln!(out, "  - [0.0, 0.0, 0.0, 1.0]");
}
