//! The files that `calibrate` writes beside `results.json` for other ecosystems, as pure
//! functions from the results to text (the command writes them):
//!
//! - `ros/`: the tf from the main camera's optical frame (parent, `[frames] camera`) to the
//!   LRF frame (child, `[frames] lrf`), `p_camera = R_cv p_lrf + t_cv` in metres, as the
//!   `static_transform_publisher` command of ROS 1 (`x y z qx qy qz qw frame child`) and of
//!   ROS 2 (`--x … --qw … --frame-id … --child-frame-id …`), a launch file for each (ROS 1
//!   XML, ROS 2 Python) and a URDF fixed joint (origin xyz in m, rpy in rad); each camera's
//!   `camera_info_<id>.yaml` ([`ros_camera_info`]); the LRF's whole model as a URDF with
//!   the servo, its zero and scale (a mimic joint) and the mount, and its
//!   `robot_state_publisher` launch files ([`lrf_model_urdf`], [`lrf_model_files`]);
//! - `opencv/`: a FileStorage YAML per camera (K, distortion k1 k2 p1 p2 k3, image size)
//!   (`camera_<id>.yaml`) and, for a stereo pair, `stereo.yaml` (R, T in mm, E, F and the rectification of
//!   [`super::rectify`]);
//! - `kalibr/camchain.yaml`: Kalibr's camchain (pinhole-radtan refitted to pingcal's model,
//!   [`export_loss`]; `T_cn_cnm1` in metres).
//!
//! No file loses anything silently: each camera file's comment states what its model drops
//! of pingcal's (K1 K2 K3 P1 P2 B1 B2) and the largest and RMS distance in px, over a grid of
//! the whole image, between the pixels and their rays through pingcal's model projected by
//! the file's model ([`export_loss`]); the URDF's comment states the range correction tf
//! cannot apply.
//!
//! Numbers are written with Rust's shortest round-trip form (every digit needed to read
//! back the same f64), always with a decimal point so that every YAML reader takes them for
//! floats.

use super::rectify::{stereo_cv, CvCamera, StereoCv};
use super::results::{CameraJson, ExtrinsicJson, Results, RigJson};
use nalgebra::{Matrix3, Matrix3x4, Vector3};

use std::fmt::Write;

mod head;
mod lrf_model;

pub use lrf_model::{lrf_model_files, lrf_model_urdf, mount_tilt, LrfChainNames, SERVO_AXIS};

/// One output file: its path below the output folder, and its text.
pub type OutputFile = (String, String);

/// `x` so that it reads back exactly, with a decimal point (`1.0`, `-0.25`, `0.000001`).
pub fn num(x: f64) -> String {
    let s = format!("{x}");
    if x.is_finite() && !s.contains('.') {
        s + ".0"
    } else {
        s
    }
}

fn nums(xs: &[f64]) -> String {
    xs.iter().map(|&x| num(x)).collect::<Vec<_>>().join(", ")
}

// ---- What each exported camera model loses against pingcal's -------------------------

pub use pingcal_ba::camera::forms::Form;
pub use pingcal_ba::camera::refit::{grid_pixels, loss_grid, Loss, GRID_STEP_PX};

/// A loss beyond this many pixels anywhere on the image is said so in the file.
pub const NOTED_LOSS_PX: f64 = 0.05;

/// `largest 0.123 px, RMS 0.045 px`, and a warning beyond [`NOTED_LOSS_PX`].
fn loss_words(loss: &Loss) -> String {
    let note = if loss.max_px > NOTED_LOSS_PX {
        format!(" (more than {NOTED_LOSS_PX} px: use pingcal's model where this matters)")
    } else {
        String::new()
    };
    format!(
        "largest {:.4} px, RMS {:.4} px{note}",
        loss.max_px, loss.rms_px
    )
}

/// What the exported models of one camera hold and lose against pingcal's, over
/// [`loss_grid`] ([`pingcal_ba::camera::forms`]).
#[derive(Clone, Debug, PartialEq)]
pub struct ExportLoss {
    /// The grid's counts (n_u, n_v).
    pub grid: (usize, usize),
    /// Grid pixels pingcal's model gives no ray (left out of the figures).
    pub missed: usize,
    /// OpenCV's model (`opencv/`, `results.json`'s `cameras[].opencv`).
    pub opencv: Form,
    /// ROS's `camera_info` model (`ros/camera_info_*.yaml`).
    pub ros: Form,
    /// Kalibr's model (`kalibr/camchain.yaml`).
    pub kalibr: Form,
}

/// What camera `c`'s exported models hold and lose against pingcal's over the image
/// ([`ExportLoss`]). `None` when pingcal's model gives no ray anywhere on the grid.
pub fn export_loss(c: &CameraJson) -> Option<ExportLoss> {
    use pingcal_ba::camera::forms::{form, Ecosystem, Source};
    use pingcal_ba::camera::refit::GridRays;
    let (w, h) = (c.opencv.image_width, c.opencv.image_height);
    let model = c.model();
    let grid = GridRays::of(model.as_ref(), &c.params.values, &grid_pixels(w, h));
    let src = Source {
        kind: c.params.model,
        params: &c.params.values,
        width: w,
        height: h,
        pixel_size_mm: c.pixel_size_mm,
        grid: &grid,
    };
    Some(ExportLoss {
        grid: loss_grid(w, h),
        missed: grid.missed,
        opencv: form(&src, Ecosystem::OpenCv)?,
        ros: form(&src, Ecosystem::Ros)?,
        kalibr: form(&src, Ecosystem::Kalibr)?,
    })
}

/// What form `f` of camera `c` drops of pingcal's model, in words (the files' comments and
/// the report).
fn drops(c: &CameraJson, f: &Form) -> String {
    let model = c.params.model;
    let v = |k: &str| num(c.params.get(k).unwrap_or(0.0));
    match (model.opencv_closed_form(), f.fitted) {
        (true, false) => format!(
            "B2 = {} dropped (no shear in OpenCV's model) and B1 = {} kept to first order only (in fx)",
            v("b2"),
            v("b1")
        ),
        (_, false) => format!("pingcal's {model} model as it is"),
        (_, true) => format!(
            "{} {} fitted to pingcal's {model} model ({}) by least squares in px{}",
            f.camera_model,
            f.distortion_model,
            c.params.keys().join(" "),
            if f.intrinsics_fitted {
                ", fx fy cx cy fitted too"
            } else {
                ""
            }
        ),
    }
}

/// The comment line of a camera file: what it drops and what that costs over the image.
fn loss_comment(c: &CameraJson, f: &Form, loss: &ExportLoss) -> String {
    let (nu, nv) = loss.grid;
    let missed = match loss.missed {
        0 => String::new(),
        n => format!(" ({n} grid pixels left out: pingcal's model gives them no ray)"),
    };
    format!(
        "{}; over a {nu} x {nv} grid of the whole image the rays of pingcal's model land {} from their pixels{missed}",
        drops(c, f),
        loss_words(&f.loss)
    )
}

fn matrix3(m: &[[f64; 3]; 3]) -> Matrix3<f64> {
    Matrix3::from_fn(|i, j| m[i][j])
}

/// Roll, pitch, yaw (radians) of `r = R_z(yaw) R_y(pitch) R_x(roll)` (URDF, tf2 `setRPY`);
/// at pitch = ±90° the yaw is taken as 0.
pub fn rpy(r: &Matrix3<f64>) -> [f64; 3] {
    let cp = r[(0, 0)].hypot(r[(1, 0)]);
    let pitch = (-r[(2, 0)]).atan2(cp);
    if cp < 1e-12 {
        return [(-r[(1, 2)]).atan2(r[(1, 1)]), pitch, 0.0];
    }
    [
        r[(2, 1)].atan2(r[(2, 2)]),
        pitch,
        r[(1, 0)].atan2(r[(0, 0)]),
    ]
}

/// The tf of the extrinsic in ROS units: translation (m), quaternion (x, y, z, w), rpy (rad).
struct Tf<'a> {
    parent: &'a str,
    child: &'a str,
    t: [f64; 3],
    q: [f64; 4],
    rpy: [f64; 3],
}

impl<'a> Tf<'a> {
    fn of(e: &ExtrinsicJson, parent: &'a str, child: &'a str) -> Self {
        let t = e.opencv.translation_mm.map(|v| v / 1000.0);
        Tf {
            parent,
            child,
            t,
            q: e.opencv.quaternion_xyzw,
            rpy: rpy(&matrix3(&e.opencv.rotation)),
        }
    }

    fn ros1_args(&self) -> String {
        let v: Vec<String> = self.t.iter().chain(&self.q).map(|&x| num(x)).collect();
        format!("{} {} {}", v.join(" "), self.parent, self.child)
    }

    fn ros2_args(&self) -> Vec<(String, String)> {
        let keys = ["--x", "--y", "--z", "--qx", "--qy", "--qz", "--qw"];
        let vals = self.t.iter().chain(&self.q).map(|&x| num(x));
        let mut out: Vec<(String, String)> = keys.iter().map(|k| k.to_string()).zip(vals).collect();
        out.push(("--frame-id".into(), self.parent.into()));
        out.push(("--child-frame-id".into(), self.child.into()));
        out
    }

    fn node_name(&self) -> String {
        let clean = |s: &str| s.replace(|c: char| !c.is_ascii_alphanumeric(), "_");
        format!("pingcal_{}_to_{}", clean(self.parent), clean(self.child))
    }

    fn what(&self) -> String {
        format!(
            "the tf from '{}' (parent) to '{}' (child): p_{} = R p_{} + t, t in m (written by pingcal calibrate, the extrinsic of results.json)",
            self.parent, self.child, self.parent, self.child
        )
    }
}

fn ros1_command(tf: &Tf) -> String {
    format!(
        "#!/bin/sh\n# ROS 1: {}\n# tf2_ros static_transform_publisher x y z qx qy qz qw frame_id child_frame_id\nexec rosrun tf2_ros static_transform_publisher {}\n",
        tf.what(),
        tf.ros1_args()
    )
}

fn ros2_command(tf: &Tf) -> String {
    let args: Vec<String> = tf
        .ros2_args()
        .iter()
        .map(|(k, v)| format!("{k} {v}"))
        .collect();
    format!(
        "#!/bin/sh\n# ROS 2: {}\nexec ros2 run tf2_ros static_transform_publisher {}\n",
        tf.what(),
        args.join(" ")
    )
}

fn ros1_launch(tf: &Tf) -> String {
    format!(
        "<launch>\n  <!-- {} -->\n  <node pkg=\"tf2_ros\" type=\"static_transform_publisher\" name=\"{}\"\n        args=\"{}\" />\n</launch>\n",
        tf.what(),
        tf.node_name(),
        tf.ros1_args()
    )
}

fn ros2_launch(tf: &Tf) -> String {
    let mut args = String::new();
    for (k, v) in tf.ros2_args() {
        let _ = writeln!(args, "                \"{k}\", \"{v}\",");
    }
    format!(
        "# ROS 2 launch file: {}\nfrom launch import LaunchDescription\nfrom launch_ros.actions import Node\n\n\ndef generate_launch_description():\n    return LaunchDescription([\n        Node(\n            package=\"tf2_ros\",\n            executable=\"static_transform_publisher\",\n            name=\"{}\",\n            arguments=[\n{args}            ],\n        ),\n    ])\n",
        tf.what(),
        tf.node_name()
    )
}

fn urdf(tf: &Tf) -> String {
    let xyz = tf.t.map(num).join(" ");
    let rpy = tf.rpy.map(num).join(" ");
    format!(
        "<?xml version=\"1.0\"?>\n<!-- {}; copy the <joint> into your robot's URDF (its links are yours) -->\n<robot name=\"pingcal_calibration\">\n  <link name=\"{p}\"/>\n  <link name=\"{c}\"/>\n  <joint name=\"{n}\" type=\"fixed\">\n    <parent link=\"{p}\"/>\n    <child link=\"{c}\"/>\n    <origin xyz=\"{xyz}\" rpy=\"{rpy}\"/>\n  </joint>\n</robot>\n",
        tf.what(),
        p = tf.parent,
        c = tf.child,
        n = tf.node_name().trim_start_matches("pingcal_").to_string() + "_joint",
    )
}

/// The files of `ros/` for the extrinsic `e`, parent frame `parent`, child `child`.
pub fn ros_files(e: &ExtrinsicJson, parent: &str, child: &str) -> Vec<OutputFile> {
    let tf = Tf::of(e, parent, child);
    vec![
        (
            "ros/ros1_static_transform_publisher.sh".into(),
            ros1_command(&tf),
        ),
        (
            "ros/ros2_static_transform_publisher.sh".into(),
            ros2_command(&tf),
        ),
        ("ros/static_transform_ros1.launch".into(), ros1_launch(&tf)),
        (
            "ros/static_transform_ros2.launch.py".into(),
            ros2_launch(&tf),
        ),
        ("ros/laser_joint.urdf".into(), urdf(&tf)),
    ]
}

/// An `!!opencv-matrix` node of FileStorage YAML (row-major `data`).
fn cv_matrix(out: &mut String, name: &str, rows: usize, cols: usize, data: &[f64]) {
    let _ = writeln!(
        out,
        "{name}: !!opencv-matrix\n   rows: {rows}\n   cols: {cols}\n   dt: d\n   data: [ {} ]",
        nums(data)
    );
}

/// The OpenCV pinhole camera of a form, for the stereo geometry (`None` for a fisheye).
fn cv_camera(f: &Form) -> Option<CvCamera> {
    let (k, dist) = f.opencv_pinhole()?;
    Some(CvCamera { k, dist })
}

fn k_data(f: &Form) -> [f64; 9] {
    let [fx, fy, cx, cy] = f.k();
    [fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0]
}

/// A file name made of the camera id (letters, digits, `_ - .`; anything else becomes `_`).
fn file_stem(id: &str) -> String {
    id.replace(
        |c: char| !(c.is_ascii_alphanumeric() || "_-.".contains(c)),
        "_",
    )
}

/// `opencv/camera_<id>.yaml`: one camera in OpenCV's model (`results.json`'s
/// `cameras[].opencv`: pinhole with 5, 8 or 12 coefficients, or `cv::fisheye`), with what
/// that model loses ([`export_loss`]) in its comment.
pub fn opencv_camera_yaml(c: &CameraJson, loss: &ExportLoss) -> String {
    let f = &loss.opencv;
    let what = if f.is_opencv_fisheye() {
        format!(
            "OpenCV's fisheye model (cv::fisheye, {})",
            f.coefficient_names().join(" ")
        )
    } else {
        format!(
            "OpenCV's pinhole model with {} distortion ({})",
            f.distortion_model,
            f.coefficient_names().join(", ")
        )
    };
    let mut s = format!(
        "%YAML:1.0\n---\n# camera '{}' in {what}; written by pingcal calibrate\n# {}\ncamera_name: \"{}\"\ncamera_model: \"{}\"\ndistortion_model: \"{}\"\nimage_width: {}\nimage_height: {}\n",
        c.id,
        loss_comment(c, f, loss),
        c.id,
        f.camera_model,
        f.distortion_model,
        c.opencv.image_width,
        c.opencv.image_height
    );
    cv_matrix(&mut s, "camera_matrix", 3, 3, &k_data(f));
    cv_matrix(
        &mut s,
        "distortion_coefficients",
        1,
        f.coeffs.len(),
        &f.coeffs,
    );
    s
}

fn flat<const R: usize, const C: usize>(m: &nalgebra::SMatrix<f64, R, C>) -> Vec<f64> {
    (0..R)
        .flat_map(|i| (0..C).map(move |j| m[(i, j)]))
        .collect()
}

/// OpenCV's stereo geometry of the rig (left = camera 1, right = camera 2), or `None` for
/// a degenerate pair or fisheye cameras (whose rectification `cv::fisheye` computes
/// otherwise; pingcal does not write it).
fn stereo_of(left: &Form, right: &Form, size: (u32, u32), rig: &RigJson) -> Option<StereoCv> {
    let (r, t) = rig_cv(rig);
    stereo_cv(&cv_camera(left)?, &cv_camera(right)?, size, &r, &t)
}

/// The stereo rig in OpenCV's camera frames: `p_right = R p_left + t`, t in mm.
fn rig_cv(rig: &RigJson) -> (Matrix3<f64>, Vector3<f64>) {
    (
        matrix3(&rig.opencv.rotation),
        Vector3::from(rig.opencv.translation_mm),
    )
}

/// `opencv/stereo.yaml` for the rig (left = camera 1, right = camera 2), or `None` for a
/// degenerate pair or fisheye cameras.
pub fn opencv_stereo_yaml(
    (left, lf): (&CameraJson, &Form),
    (right, rf): (&CameraJson, &Form),
    rig: &RigJson,
) -> Option<String> {
    let (w, h) = (left.opencv.image_width, left.opencv.image_height);
    let s = stereo_of(lf, rf, (w, h), rig)?;
    let (r, t) = rig_cv(rig);
    let mut out = format!(
        "%YAML:1.0\n---\n# stereo pair: camera 1 = '{}' (left), camera 2 = '{}' (right); p_2 = R p_1 + T in OpenCV camera frames, T in mm; R1 R2 P1 P2 Q as cv2.stereoRectify gives them (CALIB_ZERO_DISPARITY, alpha -1); written by pingcal calibrate\nleft_camera: \"{}\"\nright_camera: \"{}\"\ntranslation_unit: \"mm\"\nimage_width: {w}\nimage_height: {h}\n",
        left.id, right.id, left.id, right.id
    );
    cv_matrix(&mut out, "K1", 3, 3, &k_data(lf));
    cv_matrix(&mut out, "D1", 1, lf.coeffs.len(), &lf.coeffs);
    cv_matrix(&mut out, "K2", 3, 3, &k_data(rf));
    cv_matrix(&mut out, "D2", 1, rf.coeffs.len(), &rf.coeffs);
    cv_matrix(&mut out, "R", 3, 3, &flat(&r));
    cv_matrix(&mut out, "T", 3, 1, t.as_slice());
    cv_matrix(&mut out, "E", 3, 3, &flat(&s.e));
    cv_matrix(&mut out, "F", 3, 3, &flat(&s.f));
    cv_matrix(&mut out, "R1", 3, 3, &flat(&s.r1));
    cv_matrix(&mut out, "R2", 3, 3, &flat(&s.r2));
    cv_matrix(&mut out, "P1", 3, 4, &flat(&s.p1));
    cv_matrix(&mut out, "P2", 3, 4, &flat(&s.p2));
    cv_matrix(&mut out, "Q", 4, 4, &flat(&s.q));
    Some(out)
}

/// A `{rows, cols, data}` matrix as `camera_calibration_parsers` writes it (row-major).
fn ros_matrix(out: &mut String, name: &str, rows: usize, cols: usize, data: &[f64]) {
    let _ = writeln!(
        out,
        "{name}:\n  rows: {rows}\n  cols: {cols}\n  data: [{}]",
        nums(data)
    );
}

/// A camera's rectification in `camera_info`: R and P (P's last column in m).
#[derive(Clone, Debug, PartialEq)]
pub struct RosRectification {
    /// The rectifying rotation R.
    pub r: Matrix3<f64>,
    /// The projection P of the rectified image; `P[0][3] = Tx = −fx'·B` (B the baseline,
    /// m) for the right camera of a horizontal pair, 0 for the left.
    pub p: Matrix3x4<f64>,
    /// What R and P are, for the comment.
    pub what: String,
}

impl RosRectification {
    /// A camera alone: R = I, P = [K | 0] (K of form `f`).
    pub fn mono(f: &Form) -> Self {
        let k = Matrix3::from_row_slice(&k_data(f));
        RosRectification {
            r: Matrix3::identity(),
            p: Matrix3x4::from_fn(|i, j| if j < 3 { k[(i, j)] } else { 0.0 }),
            what: "R = I and P = [K | 0] (a camera alone)".into(),
        }
    }

    /// A camera of a stereo pair that OpenCV's `stereoRectify` cannot take (a fisheye
    /// form): R = I, P = [K | 0], and the comment says why.
    pub fn pair_unrectified(f: &Form) -> Self {
        RosRectification {
            what: "R = I and P = [K | 0]: no stereo rectification is written for this pair (OpenCV's stereoRectify takes pinhole cameras; the rig is in results.json and kalibr/camchain.yaml)".into(),
            ..RosRectification::mono(f)
        }
    }

    /// Camera `n` (1 left, 2 right) of a stereo pair: R1, P1 or R2, P2 of `s` (OpenCV's,
    /// as ROS's stereo calibrator writes them), P's last column from mm to m.
    pub fn stereo(s: &StereoCv, n: usize) -> Self {
        let (r, p) = if n == 1 { (s.r1, s.p1) } else { (s.r2, s.p2) };
        let mut p = p;
        for i in 0..3 {
            p[(i, 3)] /= 1000.0;
        }
        RosRectification {
            r,
            p,
            what: format!("R{n} and P{n} of opencv/stereo.yaml's rectification (P's last column Tx = -fx' B with the baseline B in m, as ROS's stereo calibrator and image_geometry take it)"),
        }
    }
}

/// `ros/camera_info_<id>.yaml`: camera `c` in the YAML that ROS's
/// `camera_calibration_parsers` reads and writes (`camera_info_manager`'s
/// `camera_info_url`), K and D of its ROS form (`plumb_bob`, `rational_polynomial` or
/// `equidistant`), R and P of `rect`.
pub fn ros_camera_info(c: &CameraJson, rect: &RosRectification, loss: &ExportLoss) -> String {
    let f = &loss.ros;
    let same = if f.kind == loss.opencv.kind && f.params == loss.opencv.params {
        format!("K and D as opencv/camera_{}.yaml", file_stem(&c.id))
    } else {
        "K and D fitted for ROS (its distortion models do not hold OpenCV's)".to_string()
    };
    let mut s = format!(
        "# ROS camera_info of camera '{}' (camera_calibration_parsers' YAML, as camera_info_manager reads it), written by pingcal calibrate:\n# {same} ({}: {}); {}\n# {}\nimage_width: {}\nimage_height: {}\ncamera_name: {:?}\n",
        c.id,
        f.distortion_model,
        f.coefficient_names().join(" "),
        rect.what,
        loss_comment(c, f, loss),
        c.opencv.image_width,
        c.opencv.image_height,
        c.id
    );
    ros_matrix(&mut s, "camera_matrix", 3, 3, &k_data(f));
    let _ = writeln!(s, "distortion_model: {}", f.distortion_model);
    ros_matrix(
        &mut s,
        "distortion_coefficients",
        1,
        f.coeffs.len(),
        &f.coeffs,
    );
    ros_matrix(&mut s, "rectification_matrix", 3, 3, &flat(&rect.r));
    ros_matrix(&mut s, "projection_matrix", 3, 4, &flat(&rect.p));
    s
}

/// One camera of the camchain (its lines after `camN:`), in its Kalibr form of `loss`.
fn kalibr_camera(
    out: &mut String,
    n: usize,
    c: &CameraJson,
    loss: &ExportLoss,
    overlaps: &[usize],
) {
    let k = &loss.kalibr;
    let (intrinsics, model) = (k.kalibr_intrinsics(), k.camera_model);
    let same_k = match (k.fitted, k.intrinsics_fitted) {
        (true, false) => " (fx fy cx cy as opencv/'s)",
        _ => "",
    };
    let _ = writeln!(
        out,
        "  # camera '{}': {}{same_k}",
        c.id,
        loss_comment(c, k, loss)
    );
    let lists = overlaps.iter().map(|k| k.to_string()).collect::<Vec<_>>();
    let _ = writeln!(out, "  cam_overlaps: [{}]", lists.join(", "));
    let _ = writeln!(out, "  camera_model: {model}");
    let _ = writeln!(out, "  distortion_coeffs: [{}]", nums(&k.coeffs));
    let _ = writeln!(out, "  distortion_model: {}", k.distortion_model);
    let _ = writeln!(out, "  intrinsics: [{}]", nums(&intrinsics));
    let _ = writeln!(
        out,
        "  resolution: [{}, {}]",
        c.opencv.image_width, c.opencv.image_height
    );
    let _ = writeln!(out, "  rostopic: /cam{n}/image_raw");
}

/// `kalibr/camchain.yaml`: `cams` in order (cam0, cam1), each with its [`export_loss`], and
/// for a rig cam1's `T_cn_cnm1` (`p_cam1 = T p_cam0`, OpenCV frames, metres).
pub fn kalibr_camchain(cams: &[(&CameraJson, &ExportLoss)], rig: Option<&RigJson>) -> String {
    let link = rig.map(|r| {
        let (rot, t) = rig_cv(r);
        (rot, t / 1000.0)
    });
    let links: Vec<_> = (0..cams.len()).map(|n| link.filter(|_| n == 1)).collect();
    kalibr_chain(cams, &links)
}

/// `kalibr/camchain.yaml` of `cams` in order, `links[n]` cam n's `T_cn_cnm1` (`p_camn = R
/// p_camn-1 + t`, OpenCV frames, t in m; None: not written).
fn kalibr_chain(cams: &[(&CameraJson, &ExportLoss)], links: &[Link]) -> String {
    let mut out = String::from("# Kalibr camchain written by pingcal calibrate; the rostopics are placeholders: set them to your image topics\n");
    for (n, (c, loss)) in cams.iter().enumerate() {
        let _ = writeln!(out, "cam{n}:");
        if let Some(Some((rot, t))) = links.get(n).filter(|_| n > 0) {
            head::write_t_cn_cnm1(&mut out, rot, t);
        }
        let overlaps: Vec<usize> = (0..cams.len()).filter(|&k| k != n).collect();
        kalibr_camera(&mut out, n, c, loss, &overlaps);
    }
    out
}

/// A camera's `T_cn_cnm1` in Kalibr's chain (rotation, translation in m).
type Link = Option<(Matrix3<f64>, Vector3<f64>)>;

/// The indices (into `r.cameras`) of the cameras in Kalibr's order: left and right of the
/// rig, else the main camera alone; then the cameras of `[rig]` (`sensors`' cameras not
/// yet in the chain).
fn chain(r: &Results) -> Vec<usize> {
    let find = |id: &str| r.cameras.iter().position(|c| c.id == id);
    let mut order: Vec<usize> = match &r.bundle.rig {
        Some(rig) => [&rig.left, &rig.right]
            .iter()
            .filter_map(|id| find(id))
            .collect(),
        None => find(&r.conventions.main_camera).into_iter().collect(),
    };
    for s in r.sensors.iter().filter(|s| s.kind == "camera") {
        if let Some(i) = find(&s.id).filter(|i| !order.contains(i)) {
            order.push(i);
        }
    }
    order
}

/// Each camera's `T_cn_cnm1` along `order` (in `cams`' order): cam1's of the stereo rig
/// where it has one (`bundle.rig`), every other from `sensors` ([`head::t_cn_cnm1`]).
fn chain_links(r: &Results, order: &[usize]) -> Vec<Link> {
    (0..order.len())
        .map(|n| {
            if n == 0 {
                return None;
            }
            if let (1, Some(rig)) = (n, &r.bundle.rig) {
                let (rot, t) = rig_cv(rig);
                return Some((rot, t / 1000.0));
            }
            let (prev, next) = (&r.cameras[order[n - 1]].id, &r.cameras[order[n]].id);
            head::t_cn_cnm1(r, prev, next)
        })
        .collect()
}

/// Every file of `ros/`, `opencv/` and `kalibr/` for `r` (a camera whose `losses` entry is
/// `None` has no camera files).
pub fn exports(r: &Results, losses: &[Option<ExportLoss>]) -> Vec<OutputFile> {
    let conv = &r.conventions;
    let (cam, lrf) = (&conv.tf_camera_frame, &conv.tf_lrf_frame);
    let mut out = ros_files(&r.extrinsic, cam, lrf);
    // a fixed LRF has no servo chain: its URDF is the fixed joint of `ros_files`
    if r.lrf_model.kind == pingcal_project::LrfKind::Rotating {
        out.extend(lrf_model_files(
            &r.extrinsic,
            &r.lrf_model.model,
            &r.lrf_model.source,
            cam,
            lrf,
        ));
    }
    let order = chain(r);
    let pair = match (&r.bundle.rig, order.as_slice()) {
        (Some(rig), &[a, b]) => match (&losses[a], &losses[b]) {
            (Some(la), Some(lb)) => Some((rig, a, b, la, lb)),
            _ => None,
        },
        _ => None,
    };
    let stereo = pair.and_then(|(rig, a, b, la, lb)| {
        let c = &r.cameras[a];
        let size = (c.opencv.image_width, c.opencv.image_height);
        stereo_of(&la.opencv, &lb.opencv, size, rig).map(|s| (a, b, s))
    });
    for (i, (c, loss)) in r.cameras.iter().zip(losses).enumerate() {
        let Some(loss) = loss else { continue };
        let stem = file_stem(&c.id);
        out.push((
            format!("opencv/camera_{stem}.yaml"),
            opencv_camera_yaml(c, loss),
        ));
        let rect = match &stereo {
            Some((a, _, s)) if *a == i => RosRectification::stereo(s, 1),
            Some((_, b, s)) if *b == i => RosRectification::stereo(s, 2),
            _ if pair.is_some_and(|(_, a, b, _, _)| a == i || b == i) => {
                RosRectification::pair_unrectified(&loss.ros)
            }
            _ => RosRectification::mono(&loss.ros),
        };
        out.push((
            format!("ros/camera_info_{stem}.yaml"),
            ros_camera_info(c, &rect, loss),
        ));
    }
    if let Some((rig, a, b, la, lb)) = pair {
        let y = opencv_stereo_yaml(
            (&r.cameras[a], &la.opencv),
            (&r.cameras[b], &lb.opencv),
            rig,
        );
        if let Some(y) = y {
            out.push(("opencv/stereo.yaml".into(), y));
        }
    }
    let order: Vec<usize> = (order.into_iter())
        .filter(|&i| losses[i].is_some())
        .collect();
    let cams: Vec<(&CameraJson, &ExportLoss)> = (order.iter())
        .filter_map(|&i| losses[i].as_ref().map(|l| (&r.cameras[i], l)))
        .collect();
    out.push((
        "kalibr/camchain.yaml".into(),
        kalibr_chain(&cams, &chain_links(r, &order)),
    ));
    if let Some(urdf) = head::head_urdf(r) {
        out.push(("ros/head.urdf".into(), urdf));
    }
    out
}

/// The report's table of what each camera's exports lose ([`export_loss`] of each camera
/// of `r`, in `losses`).
pub fn report_rows(
    r: &Results,
    losses: &[Option<ExportLoss>],
) -> Vec<pingcal_report::ExportLossRow> {
    let mut rows = Vec::new();
    for (c, loss) in r.cameras.iter().zip(losses) {
        let Some(loss) = loss else { continue };
        let stem = file_stem(&c.id);
        let row = |files: String, f: &Form| pingcal_report::ExportLossRow {
            camera: c.id.clone(),
            files,
            model: format!("{} {}: {}", f.camera_model, f.distortion_model, drops(c, f)),
            max_px: f.loss.max_px,
            rms_px: f.loss.rms_px,
        };
        if loss.ros == loss.opencv {
            rows.push(row(
                format!("opencv/camera_{stem}.yaml, ros/camera_info_{stem}.yaml"),
                &loss.opencv,
            ));
        } else {
            rows.push(row(format!("opencv/camera_{stem}.yaml"), &loss.opencv));
            rows.push(row(format!("ros/camera_info_{stem}.yaml"), &loss.ros));
        }
        rows.push(row("kalibr/camchain.yaml".into(), &loss.kalibr));
    }
    rows
}

#[cfg(test)]
mod tests {
    use super::super::results::{cv_from_photogrammetric, extrinsic_json, opencv_of, rig_json};
    use super::*;
    use nalgebra::{Quaternion, Rotation3, UnitQuaternion};
    use pingcal_geometry::{from_opk_deg, Rigid3, Sim3};
    use pingcal_lrf::MountModel;
    use pingcal_project::{CameraModel, Intrinsics};

    /// A rotation far from the identity (the LRF looks sideways), and t in mm.
    fn extrinsic() -> (Matrix3<f64>, Vector3<f64>, ExtrinsicJson) {
        let r = from_opk_deg([93.0, -31.0, 147.0]);
        let t = Vector3::new(71.4, 12.8, -88.9);
        let e = extrinsic_json(&Sim3::new(1.0, r, t), Some([0.5, 0.7, 0.9]), None);
        (r, t, e)
    }

    /// A point of the LRF frame mapped by `r`, `t` (from a file) into the optical frame in
    /// m, and the extrinsic's own image of it (p_cv = C (R p + t) / 1000).
    fn both(rot: &Matrix3<f64>, t_m: &Vector3<f64>, r: &Matrix3<f64>, t: &Vector3<f64>) -> f64 {
        let mut worst: f64 = 0.0;
        for p in [
            Vector3::new(1000.0, 0.0, 0.0),
            Vector3::new(-300.0, 800.0, 3000.0),
        ] {
            let want = cv_from_photogrammetric() * (r * p + t) / 1000.0;
            worst = worst.max((rot * (p / 1000.0) + t_m - want).norm());
        }
        worst
    }

    fn floats(words: &[&str]) -> Vec<f64> {
        words.iter().map(|w| w.parse().unwrap()).collect()
    }

    fn file<'a>(files: &'a [OutputFile], name: &str) -> &'a str {
        &files.iter().find(|(p, _)| p.ends_with(name)).unwrap().1
    }

    #[test]
    fn numbers_read_back_exactly_and_look_like_floats() {
        assert_eq!(num(1.0), "1.0");
        assert_eq!(num(-0.5), "-0.5");
        assert_eq!(num(-0.0), "-0.0");
        for x in [
            1e-7,
            -1.234567,
            0.1 + 0.2,
            123456.789e3,
            5.555113410016133e-9,
        ] {
            let s = num(x);
            assert_eq!(s.parse::<f64>().unwrap(), x);
            assert!(s.contains('.') && !s.contains('e'), "{s}");
        }
    }

    /// rpy is URDF's: R = R_z(yaw) R_y(pitch) R_x(roll), also at pitch = ±90°.
    #[test]
    fn rpy_composes_back_in_urdf_order() {
        for opk in [
            [93.0, -31.0, 147.0],
            [10.0, 90.0, -20.0],
            [-170.0, 5.0, 179.0],
        ] {
            let r = from_opk_deg(opk);
            let [roll, pitch, yaw] = rpy(&r);
            let back = Rotation3::from_axis_angle(&Vector3::z_axis(), yaw)
                * Rotation3::from_axis_angle(&Vector3::y_axis(), pitch)
                * Rotation3::from_axis_angle(&Vector3::x_axis(), roll);
            assert!((back.matrix() - r).norm() < 1e-12, "{opk:?}");
        }
    }

    /// The ROS 1 and ROS 2 commands and the URDF map LRF points (m) as the extrinsic maps
    /// them into the optical frame; R transposed (the inverse direction) is far off.
    #[test]
    fn ros_files_carry_the_extrinsic_into_the_optical_frame() {
        let (r, t, e) = extrinsic();
        let files = ros_files(&e, "cam", "laser");
        let ros1 = file(&files, "ros1_static_transform_publisher.sh");
        let line = ros1.lines().last().unwrap();
        let words: Vec<&str> = line.split_whitespace().collect();
        assert_eq!(
            &words[..4],
            ["exec", "rosrun", "tf2_ros", "static_transform_publisher"]
        );
        assert_eq!(&words[11..], ["cam", "laser"]);
        let v = floats(&words[4..11]);
        let q = UnitQuaternion::from_quaternion(Quaternion::new(v[6], v[3], v[4], v[5]));
        let tm = Vector3::new(v[0], v[1], v[2]);
        let rq = q.to_rotation_matrix().into_inner();
        assert!(both(&rq, &tm, &r, &t) < 1e-12, "{}", both(&rq, &tm, &r, &t));
        assert!(both(&rq.transpose(), &tm, &r, &t) > 0.01);
        let ros2 = file(&files, "ros2_static_transform_publisher.sh");
        let flags: Vec<&str> = ros2.lines().last().unwrap().split_whitespace().collect();
        let at = |k: &str| flags[flags.iter().position(|w| *w == k).unwrap() + 1];
        let v2 = floats(&["--x", "--y", "--z", "--qx", "--qy", "--qz", "--qw"].map(at));
        assert_eq!(v2, v);
        assert_eq!((at("--frame-id"), at("--child-frame-id")), ("cam", "laser"));
        let urdf = file(&files, "laser_joint.urdf");
        let attr = |k: &str| {
            let s = &urdf[urdf.find(&format!("{k}=\"")).unwrap() + k.len() + 2..];
            floats(&s[..s.find('"').unwrap()].split(' ').collect::<Vec<_>>())
        };
        let (xyz, a) = (attr("xyz"), attr("rpy"));
        let ru = Rotation3::from_euler_angles(a[0], a[1], a[2]).into_inner();
        assert!(both(&ru, &Vector3::new(xyz[0], xyz[1], xyz[2]), &r, &t) < 1e-12);
        assert!(
            urdf.contains("<parent link=\"cam\"/>") && urdf.contains("<child link=\"laser\"/>")
        );
    }

    fn camera_json(id: &str, c_mm: f64) -> CameraJson {
        camera_with(
            id,
            [
                c_mm, 0.012, -0.009, -0.021, 0.0004, -2e-6, 0.00015, -0.0001, 0.0, 0.0,
            ],
        )
    }

    /// A 1280 × 720 camera of 3.75 µm pixels with pingcal's parameters `p`.
    fn camera_with(id: &str, p: [f64; 10]) -> CameraJson {
        model_camera(id, Intrinsics::photogrammetric(p))
    }

    /// A 1280 × 720 camera of 3.75 µm pixels of any model.
    fn model_camera(id: &str, params: Intrinsics) -> CameraJson {
        CameraJson {
            id: id.into(),
            model_name: (params.model != CameraModel::Photogrammetric).then(|| params.model.name()),
            opencv: opencv_of(&params, 1280, 720, 0.00375),
            params,
            sigma: Default::default(),
            high_correlations: Vec::new(),
            pixel_size_mm: 0.00375,
        }
    }

    fn losses(c: &CameraJson) -> ExportLoss {
        export_loss(c).expect("the camera exports")
    }

    /// The `data` of matrix `name` in a FileStorage YAML.
    fn cv_data(yaml: &str, name: &str) -> Vec<f64> {
        let s = &yaml[yaml.find(&format!("\n{name}: !!opencv-matrix")).unwrap()..];
        let s = &s[s.find("data: [").unwrap() + 7..];
        floats(
            &s[..s.find(']').unwrap()]
                .split(',')
                .map(str::trim)
                .collect::<Vec<_>>(),
        )
    }

    /// K is laid out as OpenCV's [fx 0 cx; 0 fy cy; 0 0 1], distortion k1 k2 p1 p2 k3.
    #[test]
    fn opencv_camera_yaml_has_opencvs_layout() {
        let c = camera_json("left", 2.45);
        let y = opencv_camera_yaml(&c, &losses(&c));
        assert!(y.starts_with("%YAML:1.0\n---\n"));
        let o = &c.opencv;
        assert_eq!(
            cv_data(&y, "camera_matrix"),
            [o.fx, 0.0, o.cx, 0.0, o.fy, o.cy, 0.0, 0.0, 1.0]
        );
        assert_eq!(cv_data(&y, "distortion_coefficients"), o.dist);
        assert!(y.contains("image_width: 1280\nimage_height: 720\n"));
    }

    /// cam1's T_cn_cnm1 maps a point of cam0's optical frame (m) into cam1's as the rig
    /// does; the stereo YAML's R, T are the rig's in OpenCV frames.
    #[test]
    fn camchain_and_stereo_carry_the_rig_left_to_right() {
        let r = from_opk_deg([0.3, -0.25, 0.1]);
        let t = Vector3::new(-120.0, -0.12, 0.83);
        let rig = rig_json(&Rigid3::new(r, t), "left", "right");
        let (a, b) = (camera_json("left", 2.45), camera_json("right", 2.452));
        let (la, lb) = (losses(&a), losses(&b));
        let chain = kalibr_camchain(&[(&a, &la), (&b, &lb)], Some(&rig));
        let rows: Vec<Vec<f64>> = chain
            .lines()
            .filter(|l| l.starts_with("  - ["))
            .map(|l| floats(&l[5..l.len() - 1].split(", ").collect::<Vec<_>>()))
            .collect();
        let m = nalgebra::Matrix4::from_fn(|i, j| rows[i][j]);
        let c = cv_from_photogrammetric();
        let p_left = Vector3::new(150.0, 2000.0, -80.0);
        let want = c * (r * p_left + t) / 1000.0;
        let got = m * (c * p_left / 1000.0).push(1.0);
        assert!((got.xyz() - want).norm() < 1e-15, "{got:?} vs {want:?}");
        let y = opencv_stereo_yaml((&a, &la.opencv), (&b, &lb.opencv), &rig).unwrap();
        let rc = Matrix3::from_row_slice(&cv_data(&y, "R"));
        let tc = Vector3::from_row_slice(&cv_data(&y, "T"));
        assert!((rc * c * p_left + tc - c * (r * p_left + t)).norm() < 1e-12);
        assert!(chain.contains("cam0:\n") && chain.contains("distortion_model: radtan"));
    }

    /// The numbers after `key: [` on the line of `key` (YAML flow sequence).
    fn flow(text: &str, key: &str) -> Vec<f64> {
        let s = &text[text.find(&format!("{key}: [")).unwrap() + key.len() + 3..];
        floats(&s[..s.find(']').unwrap()].split(", ").collect::<Vec<_>>())
    }

    /// camera_info's `data` of matrix `name` (camera_calibration_parsers' layout).
    fn ros_data(yaml: &str, name: &str, rows: usize, cols: usize) -> Vec<f64> {
        let s = &yaml[yaml.find(&format!("\n{name}:\n")).unwrap()..];
        assert!(
            s.contains(&format!(":\n  rows: {rows}\n  cols: {cols}\n  data: [")),
            "{name}"
        );
        flow(s, "  data")
    }

    /// With neither K3 nor B1, B2, OpenCV's model is pingcal's and the radtan fit finds
    /// OpenCV's k1 k2 p1 p2 again (the loss is the rays' Newton precision).
    #[test]
    fn the_loss_is_nil_when_nothing_is_dropped() {
        let c = camera_with(
            "a",
            [
                2.45, 0.012, -0.009, -0.021, 0.0004, 0.0, 0.00015, -0.0001, 0.0, 0.0,
            ],
        );
        let l = losses(&c);
        assert_eq!(l.grid, (161, 91));
        assert_eq!(l.missed, 0);
        assert!(l.opencv.loss.max_px < 1e-6, "{:?}", l.opencv);
        assert!(l.kalibr.loss.max_px < 1e-6, "{:?}", l.kalibr);
        assert!(!l.kalibr.intrinsics_fitted);
        for (got, want) in l.kalibr.coeffs.iter().zip(&c.opencv.dist) {
            assert!(
                (got - want).abs() < 1e-9 * (1.0 + want.abs()),
                "{got} {want}"
            );
        }
    }

    /// With K3, B1 and B2 the losses are real: the refit is a least-squares minimum (any
    /// coefficient moved raises the RMS), beats dropping K3, and the file states the loss
    /// of the numbers it writes.
    #[test]
    fn the_radtan_refit_is_the_least_squares_one_and_states_its_loss() {
        use pingcal_ba::camera::refit::GridRays;
        use pingcal_ba::camera::OpenCvCamera;
        let c = camera_with(
            "wide",
            [
                2.45, 0.012, -0.009, -0.021, 0.0004, -2e-5, 0.00015, -0.0001, 2e-4, -1e-4,
            ],
        );
        let l = losses(&c);
        let g = GridRays::of(
            c.model().as_ref(),
            &c.params.values,
            &grid_pixels(1280, 720),
        );
        let o = &c.opencv;
        let k = l.kalibr.k();
        let p = |k: [f64; 4], cf: &[f64]| {
            let mut p = vec![0.0; 16];
            p[..4].copy_from_slice(&k);
            p[4..8].copy_from_slice(&cf[..4]);
            p
        };
        let dropped = g.loss(&OpenCvCamera, &p([o.fx, o.fy, o.cx, o.cy], &o.dist));
        assert!(
            l.kalibr.loss.max_px < dropped.max_px,
            "{:?} vs {dropped:?}",
            l.kalibr.loss
        );
        assert!(l.opencv.loss.max_px > 0.05 && l.kalibr.loss.max_px > NOTED_LOSS_PX);
        assert_eq!(
            g.loss(&OpenCvCamera, &p(k, &l.kalibr.coeffs)),
            l.kalibr.loss
        );
        for j in 0..4 {
            for h in [-1.0, 1.0] {
                let mut cf = l.kalibr.coeffs.clone();
                cf[j] += h * 1e-4 * (cf[j].abs() + 1e-6);
                assert!(
                    g.loss(&OpenCvCamera, &p(k, &cf)).rms_px > l.kalibr.loss.rms_px,
                    "{j} {h}"
                );
            }
        }
        let chain = kalibr_camchain(&[(&c, &l)], None);
        assert_eq!(flow(&chain, "distortion_coeffs"), l.kalibr.coeffs);
        assert_eq!(flow(&chain, "intrinsics"), k);
        let words = format!(
            "largest {:.4} px, RMS {:.4} px (more than",
            l.kalibr.loss.max_px, l.kalibr.loss.rms_px
        );
        assert!(chain.contains(&words), "{chain}");
        let yaml = opencv_camera_yaml(&c, &l);
        assert!(
            yaml.contains(&format!("largest {:.4} px", l.opencv.loss.max_px)),
            "{yaml}"
        );
    }

    /// Issue 35: a Kannala–Brandt camera is OpenCV's fisheye, ROS's equidistant and Kalibr's
    /// pinhole-equi, each exactly; a double sphere is Kalibr's ds exactly and a fitted
    /// fisheye elsewhere, with the loss stated.
    #[test]
    fn wide_angle_and_fisheye_cameras_export_in_each_ecosystems_model() {
        let kb = model_camera(
            "kb",
            Intrinsics::new(
                CameraModel::KannalaBrandt,
                vec![386.0, 386.5, 641.0, 359.0, 0.02, -0.005, 0.001, -1e-4],
            )
            .unwrap(),
        );
        let l = losses(&kb);
        assert_eq!(kb.opencv.distortion_model, "fisheye");
        assert_eq!(kb.opencv.dist, [0.02, -0.005, 0.001, -1e-4]);
        for f in [&l.opencv, &l.ros, &l.kalibr] {
            assert!(!f.fitted && f.loss.max_px < 1e-9, "{f:?}");
        }
        let y = opencv_camera_yaml(&kb, &l);
        assert!(
            y.contains("camera_model: \"fisheye\"\ndistortion_model: \"fisheye\""),
            "{y}"
        );
        assert_eq!(cv_data(&y, "distortion_coefficients"), kb.opencv.dist);
        let info = ros_camera_info(&kb, &RosRectification::mono(&l.ros), &l);
        assert!(info.contains("\ndistortion_model: equidistant\n"), "{info}");
        assert_eq!(
            ros_data(&info, "distortion_coefficients", 1, 4),
            kb.opencv.dist
        );
        let chain = kalibr_camchain(&[(&kb, &l)], None);
        assert!(
            chain.contains("camera_model: pinhole\n")
                && chain.contains("distortion_model: equidistant\n")
        );
        assert_eq!(flow(&chain, "intrinsics"), [386.0, 386.5, 641.0, 359.0]);

        let ds = model_camera(
            "ds",
            Intrinsics::new(
                CameraModel::DoubleSphere,
                vec![310.0, 310.4, 641.0, 359.0, -0.2, 0.58],
            )
            .unwrap(),
        );
        let l = losses(&ds);
        assert!(!l.kalibr.fitted && l.kalibr.loss.max_px < 1e-9);
        let chain = kalibr_camchain(&[(&ds, &l)], None);
        assert!(chain.contains("camera_model: ds\n") && chain.contains("distortion_model: none\n"));
        assert_eq!(
            flow(&chain, "intrinsics"),
            [-0.2, 0.58, 310.0, 310.4, 641.0, 359.0]
        );
        assert!(l.opencv.fitted && l.opencv.loss.max_px > 0.0);
        let y = opencv_camera_yaml(&ds, &l);
        assert!(
            y.contains(&format!("largest {:.4} px", l.opencv.loss.max_px))
                && y.contains("fitted to pingcal's double-sphere model"),
            "{y}"
        );
    }

    /// camera_info reads back with K, D as the OpenCV YAML and R, P of a camera alone; for
    /// a stereo pair R2, P2 of the rectification with P2's Tx = −fx'·B in metres.
    #[test]
    fn camera_info_has_the_parsers_layout_and_the_rectification() {
        let c = camera_json("left", 2.45);
        let l = losses(&c);
        let y = ros_camera_info(&c, &RosRectification::mono(&l.ros), &l);
        let o = &c.opencv;
        let k = [o.fx, 0.0, o.cx, 0.0, o.fy, o.cy, 0.0, 0.0, 1.0];
        assert!(y.contains("\nimage_width: 1280\nimage_height: 720\ncamera_name: \"left\"\n"));
        assert!(y.contains("\ndistortion_model: plumb_bob\n"));
        assert_eq!(ros_data(&y, "camera_matrix", 3, 3), k);
        assert_eq!(ros_data(&y, "distortion_coefficients", 1, 5), o.dist);
        assert_eq!(
            ros_data(&y, "rectification_matrix", 3, 3),
            flat(&Matrix3::<f64>::identity())
        );
        let p = ros_data(&y, "projection_matrix", 3, 4);
        assert_eq!(
            p,
            [k[0], 0.0, k[2], 0.0, 0.0, k[4], k[5], 0.0, 0.0, 0.0, 1.0, 0.0]
        );
        let rig = rig_json(
            &Rigid3::new(
                from_opk_deg([0.3, -0.25, 0.1]),
                Vector3::new(-120.0, -0.12, 0.83),
            ),
            "left",
            "right",
        );
        let b = camera_json("right", 2.452);
        let (la, lb) = (losses(&c), losses(&b));
        let s = stereo_of(&la.opencv, &lb.opencv, (1280, 720), &rig).unwrap();
        let y2 = ros_camera_info(&b, &RosRectification::stereo(&s, 2), &lb);
        assert_eq!(ros_data(&y2, "rectification_matrix", 3, 3), flat(&s.r2));
        let p2 = ros_data(&y2, "projection_matrix", 3, 4);
        let baseline_m = Vector3::from(rig.opencv.translation_mm).norm() / 1000.0;
        assert!(
            (p2[3] / p2[0] + baseline_m).abs() < 1e-12,
            "{} vs {baseline_m}",
            p2[3] / p2[0]
        );
        assert_eq!(p2[..3], flat(&s.p2)[..3]);
    }

    /// A `<joint>` of a URDF: type, parent, child, origin (xyz, rpy), axis and mimic
    /// (joint, multiplier, offset).
    struct Joint {
        kind: String,
        parent: String,
        child: String,
        xyz: Vector3<f64>,
        rpy: [f64; 3],
        axis: Option<Vector3<f64>>,
        mimic: Option<(String, f64, f64)>,
    }

    fn attr(tag: &str, key: &str) -> String {
        let s = &tag[tag.find(&format!(" {key}=\"")).unwrap() + key.len() + 3..];
        s[..s.find('"').unwrap()].to_string()
    }

    fn v3(s: &str) -> Vector3<f64> {
        Vector3::from_vec(floats(&s.split(' ').collect::<Vec<_>>()))
    }

    fn joints(urdf: &str) -> Vec<Joint> {
        let tag = |j: &str, t: &str| {
            j.find(&format!("<{t} "))
                .map(|i| j[i..].split('>').next().unwrap().to_string())
        };
        urdf.split("<joint ")
            .skip(1)
            .map(|j| {
                let j = &format!(" {}", &j[..j.find("</joint>").unwrap()]);
                let origin = tag(j, "origin").unwrap();
                Joint {
                    kind: attr(j, "type"),
                    parent: attr(&tag(j, "parent").unwrap(), "link"),
                    child: attr(&tag(j, "child").unwrap(), "link"),
                    xyz: v3(&attr(&origin, "xyz")),
                    rpy: v3(&attr(&origin, "rpy")).into(),
                    axis: tag(j, "axis").map(|a| v3(&attr(&a, "xyz"))),
                    mimic: tag(j, "mimic").map(|m| {
                        (
                            attr(&m, "joint"),
                            attr(&m, "multiplier").parse().unwrap(),
                            attr(&m, "offset").parse().unwrap(),
                        )
                    }),
                }
            })
            .collect()
    }

    /// A mount far from zero (every term of the model matters).
    fn mount() -> MountModel {
        MountModel {
            offset_mm: [12.5, -3.25, 40.0],
            tilt_x_deg: 1.7,
            tilt_z_deg: -2.3,
            servo_zero_deg: 4.5,
            servo_scale: 0.012,
            range_offset_mm: 6.5,
            range_scale: -0.004,
            servo_time_offset_s: 0.0,
        }
    }

    /// `parent_from_child` of the chain from `from` down to `to`, the joint `name` at
    /// position `q` (its mimics follow it), URDF's `origin · Rot(axis, position)`; mm.
    fn compose(
        js: &[Joint],
        names: &LrfChainNames,
        from: &str,
        to: &str,
        q: f64,
    ) -> (Matrix3<f64>, Vector3<f64>) {
        let (mut r, mut t) = (Matrix3::identity(), Vector3::zeros());
        let mut link = from.to_string();
        while link != to {
            let j = js.iter().find(|j| j.parent == link).unwrap();
            let [a, b, c] = j.rpy;
            let o = Rotation3::from_euler_angles(a, b, c).into_inner();
            let pos = match (&j.mimic, j.kind.as_str()) {
                (Some((m, mul, off)), _) => {
                    assert_eq!(m, &names.servo_joint);
                    mul * q + off
                }
                (None, "continuous") => q,
                (None, kind) => {
                    assert_eq!(kind, "fixed");
                    0.0
                }
            };
            let turn = j.axis.map_or(Matrix3::identity(), |ax| {
                Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(ax), pos).into_inner()
            });
            t += r * (j.xyz * 1000.0);
            r = r * o * turn;
            link = j.child.clone();
        }
        (r, t)
    }

    /// The URDF's chain from the LRF frame down to the scanner, composed at the raw servo
    /// reading (rad), maps each beam (at the corrected range the comment states) where
    /// `MountModel::beam` does, to 1e-9 mm; the camera frame is the extrinsic's parent.
    #[test]
    fn lrf_model_urdf_composes_to_the_mount_model() {
        let (_, _, e) = extrinsic();
        let m = mount();
        let urdf = lrf_model_urdf(&e, &m, "joint adjustment", "cam", "laser");
        let js = joints(&urdf);
        let n = LrfChainNames::of("laser");
        assert_eq!(js.len(), 4);
        assert_eq!(
            (js[0].parent.as_str(), js[0].child.as_str()),
            ("cam", "laser")
        );
        assert!(urdf.contains(&format!("range_offset = {} mm", num(m.range_offset_mm))));
        assert!(urdf.contains(&format!("range_scale = {}", num(m.range_scale))));
        let mut worst: f64 = 0.0;
        for servo_deg in [-60.0, -7.25, 0.0, 4.5, 33.0, 95.0] {
            let (r, t) = compose(
                &js,
                &n,
                "laser",
                &n.scanner_link,
                f64::to_radians(servo_deg),
            );
            for (reported, alpha_deg) in [
                (800.0, -120.0),
                (2345.0, -10.5),
                (1500.0, 0.0),
                (4000.0, 77.0),
            ] {
                let want = m.beam(reported, alpha_deg, servo_deg).0;
                let (s, c) = f64::to_radians(alpha_deg).sin_cos();
                let range = m.true_range(reported);
                let got = r * Vector3::new(range * c, range * s, 0.0) + t;
                worst = worst.max((got - want).norm());
            }
        }
        assert!(worst < 1e-9, "{worst} mm");
        let flipped = urdf.replace(
            "<axis xyz=\"0.0 -1.0 0.0\"/>",
            "<axis xyz=\"0.0 1.0 0.0\"/>",
        );
        let (r, t) = compose(&joints(&flipped), &n, "laser", &n.scanner_link, 0.6);
        let want = m.beam(1500.0, 10.0, 0.6f64.to_degrees()).0;
        let (s, c) = 10f64.to_radians().sin_cos();
        let rr = m.true_range(1500.0);
        assert!((r * Vector3::new(rr * c, rr * s, 0.0) + t - want).norm() > 100.0);
    }

    /// The mimic's multiplier and offset and the mount's numbers read back exactly, and the
    /// launch files load `lrf_model.urdf` into robot_state_publisher.
    #[test]
    fn lrf_model_numbers_read_back_exactly() {
        let (_, _, e) = extrinsic();
        let m = mount();
        let files = lrf_model_files(&e, &m, "spheres", "cam", "laser");
        let urdf = file(&files, "lrf_model.urdf");
        let js = joints(urdf);
        let (_, mul, off) = js[2].mimic.clone().unwrap();
        assert_eq!(mul, m.servo_scale);
        assert_eq!(off, -m.servo_zero_deg.to_radians() * (1.0 + m.servo_scale));
        assert_eq!(js[3].xyz, Vector3::from(m.offset_mm) / 1000.0);
        let [a, b, c] = js[3].rpy;
        let back = Rotation3::from_euler_angles(a, b, c).into_inner();
        assert!((back - mount_tilt(&m)).norm() < 1e-15);
        assert_eq!(
            js[0].xyz,
            Vector3::from(e.opencv.translation_mm.map(|v| v / 1000.0))
        );
        let ros1 = file(&files, "lrf_model_ros1.launch");
        assert!(
            ros1.contains("textfile=\"$(dirname)/lrf_model.urdf\"")
                && ros1.contains("pkg=\"robot_state_publisher\"")
        );
        let ros2 = file(&files, "lrf_model_ros2.launch.py");
        assert!(
            ros2.contains("\"lrf_model.urdf\"")
                && ros2.contains("executable=\"robot_state_publisher\"")
        );
    }
}
