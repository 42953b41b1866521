//! The `conventions` block of `results.json`: in words, which frame is which (origin, axes,
//! unit), which way every transform written maps, and the order and units of the angles, so
//! that a program or a person reading the file (or `ros/`, `opencv/`, `kalibr/` beside it)
//! need not guess. The numbers are elsewhere; this block only names them.

use pingcal_project::Project;
use serde::Serialize;
use std::collections::BTreeMap;

/// `results.json`'s `conventions`.
#[derive(Clone, Debug, Serialize)]
pub struct ConventionsJson {
    /// Frame name → origin, axes and unit.
    pub frames: BTreeMap<String, String>,
    /// Key of `results.json` (or output file) → the direction of the transform it holds.
    pub transforms: BTreeMap<String, String>,
    /// Angle sets → their order, sense and unit.
    pub angles: BTreeMap<String, String>,
    /// The quaternions' component order and sense.
    pub quaternion: String,
    /// The 4×4 matrices' layout.
    pub matrix_4x4: String,
    /// Length units.
    pub units: String,
    /// The id of the main camera, whose frame is the photogrammetric frame.
    pub main_camera: String,
    /// The tf frame id of the main camera's optical frame (`[frames] camera`).
    pub tf_camera_frame: String,
    /// The tf frame id of the LRF frame (`[frames] lrf`).
    pub tf_lrf_frame: String,
}

fn map(pairs: &[(&str, String)]) -> BTreeMap<String, String> {
    pairs
        .iter()
        .map(|(k, v)| (k.to_string(), v.clone()))
        .collect()
}

fn frames(project: &Project) -> BTreeMap<String, String> {
    let f = &project.file;
    let mut pairs = vec![
        ("photogrammetric", format!(
            "camera frame of the main camera '{}' (at station '{}'): origin at its projection centre, X to image right, Y forward along the optical axis, Z to image up; right-handed; mm",
            f.main_camera, f.main_station
        )),
        ("opencv", format!(
            "the same camera in OpenCV's camera frame: x right, y down, z forward; p_opencv = C p_photogrammetric = (X, -Z, Y), C = [[1,0,0],[0,0,-1],[0,1,0]]; the ROS optical frame '{}' (REP 103) has these axes",
            f.frames.camera
        )),
        ("lrf", format!(
            "the LRF frame of cloud.ply and lrf_mm (docs/formats.md): origin at the 2D LRF's centre, Y along the servo shaft, X along the beam at alpha = 0 when beta = 0; mm; the tf frame '{}'",
            f.frames.lrf
        )),
    ];
    if let Some(st) = &f.stereo {
        pairs.push(("stereo", format!(
            "'{}' is the left camera (OpenCV camera 1, Kalibr cam0), '{}' the right (camera 2, cam1); each has a photogrammetric and an OpenCV frame as above",
            st.left, st.right
        )));
    }
    map(&pairs)
}

fn transforms(project: &Project) -> BTreeMap<String, String> {
    let (cam, lrf) = (&project.file.frames.camera, &project.file.frames.lrf);
    map(&[
        ("extrinsic", "p_photogrammetric = R p_lrf + t (rotation, translation_mm, matrix_4x4, quaternion_xyzw, opk_deg); the same in methods[].extrinsic".into()),
        ("extrinsic.opencv", "p_opencv = R_cv p_lrf + t_cv, R_cv = C R, t_cv = C t (mm)".into()),
        ("bundle.rig", "p_right = R p_left + t in the photogrammetric frames (mm)".into()),
        ("sensors", "camera_from_sensor: p_photogrammetric = R p_sensor + t, the sensor's frame its own (a camera's photogrammetric frame, the LRF frame); the cameras' poses those of the bundle (bundle.rig, the exports), every sigma from the joint adjustment's covariance when it gave the result; sigma_rotation_deg of opk_deg; the LRF's is extrinsic".into()),
        ("sensor_pairs", "a_from_b: p_a = R p_b + t = camera_from_a^-1 camera_from_b, with sigmas from the joint covariance of a and b (two range sensors: of one problem holding both their adjustments; null where none can be had)".into()),
        ("bundle.rig.opencv", "p_right_opencv = R_cv p_left_opencv + t_cv, R_cv = C R C^T, t_cv = C t (mm): stereoCalibrate's R and T".into()),
        ("ros/", format!(
            "tf from parent '{cam}' to child '{lrf}': the child's pose in the parent, i.e. p_{cam} = R_cv p_{lrf} + t_cv / 1000 (m)"
        )),
        ("opencv/stereo.yaml", "R, T: p_right = R p_left + T in OpenCV frames, T in mm; R1, R2, P1, P2, Q as cv2.stereoRectify returns them (flags CALIB_ZERO_DISPARITY, alpha -1)".into()),
        ("kalibr/camchain.yaml", "cam1.T_cn_cnm1: p_cam1 = T p_cam0 in OpenCV frames, m".into()),
        ("balls, targets", "photogrammetric frame (mm); balls[].lrf_mm in the LRF frame".into()),
    ])
}

fn angles() -> BTreeMap<String, String> {
    map(&[
        ("opk_deg", "omega, phi, kappa in degrees, R = R_omega R_phi R_kappa with the passive elementary rotations of photogrammetry, i.e. R = R_x(-omega) R_y(-phi) R_z(-kappa) with active (counter-clockwise) ones: scipy Rotation.from_euler('XYZ', [-omega, -phi, -kappa], degrees=True); sigma_rotation_deg their sigma".into()),
        ("ros rpy", "roll, pitch, yaw in radians, R = R_z(yaw) R_y(pitch) R_x(roll), active (URDF origin rpy, tf2 setRPY): scipy Rotation.from_euler('xyz', [roll, pitch, yaw])".into()),
    ])
}

/// The block for `project` (its camera ids, stations and tf frame names).
pub fn conventions(project: &Project) -> ConventionsJson {
    ConventionsJson {
        frames: frames(project),
        transforms: transforms(project),
        angles: angles(),
        quaternion: "(x, y, z, w): unit, Hamilton, active (it rotates vectors as R does; scipy Rotation.from_quat and tf2/ROS order), w >= 0".into(),
        matrix_4x4: "row-major [[R, t], [0, 0, 0, 1]] of the same transform, t in mm".into(),
        units: "mm in results.json and opencv/; m in ros/ and kalibr/; pixels for OpenCV and Kalibr intrinsics".into(),
        main_camera: project.file.main_camera.clone(),
        tf_camera_frame: project.file.frames.camera.clone(),
        tf_lrf_frame: project.file.frames.lrf.clone(),
    }
}
