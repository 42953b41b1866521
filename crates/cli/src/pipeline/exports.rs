//! The files that `calibrate` writes beside `results.json` for other ecosystems, as pure
//! functions from the results to text (the command writes them):
//!
//! - `ros/`: the tf from the main camera's optical frame (parent, `[frames] camera`) to the
//!   LRF frame (child, `[frames] lrf`), `p_camera = R_cv p_lrf + t_cv` in metres, as the
//!   `static_transform_publisher` command of ROS 1 (`x y z qx qy qz qw frame child`) and of
//!   ROS 2 (`--x … --qw … --frame-id … --child-frame-id …`), a launch file for each (ROS 1
//!   XML, ROS 2 Python) and a URDF fixed joint (origin xyz in m, rpy in rad);
//! - `opencv/`: a FileStorage YAML per camera (K, distortion k1 k2 p1 p2 k3, image size)
//!   (`camera_<id>.yaml`) and, for a stereo pair, `stereo.yaml` (R, T in mm, E, F and the rectification of
//!   [`super::rectify`]);
//! - `kalibr/camchain.yaml`: Kalibr's camchain (pinhole-radtan; `T_cn_cnm1` in metres).
//!
//! Numbers are written with Rust's shortest round-trip form (every digit needed to read
//! back the same f64), always with a decimal point so that every YAML reader takes them for
//! floats.

use super::rectify::{stereo_cv, CvCamera};
use super::results::{CameraJson, ExtrinsicJson, Results, RigJson};
use nalgebra::{Matrix3, Vector3};
use std::fmt::Write;

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

fn cv_camera(c: &CameraJson) -> CvCamera {
    let o = &c.opencv;
    CvCamera {
        k: [o.fx, o.fy, o.cx, o.cy],
        dist: o.dist,
    }
}

fn k_data(c: &CameraJson) -> [f64; 9] {
    let o = &c.opencv;
    [o.fx, 0.0, o.cx, 0.0, o.fy, o.cy, 0.0, 0.0, 1.0]
}

/// A file name made of the camera id (letters, digits, `_ - .`; anything else becomes `_`).
fn file_stem(id: &str) -> String {
    id.replace(
        |c: char| !(c.is_ascii_alphanumeric() || "_-.".contains(c)),
        "_",
    )
}

/// `opencv/camera_<id>.yaml`: one camera in OpenCV's model (`results.json`'s `cameras[].opencv`).
pub fn opencv_camera_yaml(c: &CameraJson) -> String {
    let o = &c.opencv;
    let mut s = format!(
        "%YAML:1.0\n---\n# camera '{}' in OpenCV's pinhole model with radial-tangential distortion (k1, k2, p1, p2, k3); written by pingcal calibrate; B2 = {} dropped (OpenCV has no shear)\ncamera_name: \"{}\"\ncamera_model: \"pinhole\"\ndistortion_model: \"plumb_bob\"\nimage_width: {}\nimage_height: {}\n",
        c.id,
        num(o.opencv_dropped_b2),
        c.id,
        o.image_width,
        o.image_height
    );
    cv_matrix(&mut s, "camera_matrix", 3, 3, &k_data(c));
    cv_matrix(&mut s, "distortion_coefficients", 1, 5, &o.dist);
    s
}

fn flat<const R: usize, const C: usize>(m: &nalgebra::SMatrix<f64, R, C>) -> Vec<f64> {
    (0..R)
        .flat_map(|i| (0..C).map(move |j| m[(i, j)]))
        .collect()
}

/// `opencv/stereo.yaml` for the rig (left = camera 1, right = camera 2), or `None` for a
/// degenerate pair.
pub fn opencv_stereo_yaml(left: &CameraJson, right: &CameraJson, rig: &RigJson) -> Option<String> {
    let r = matrix3(&rig.opencv.rotation);
    let t = Vector3::from(rig.opencv.translation_mm);
    let (w, h) = (left.opencv.image_width, left.opencv.image_height);
    let s = stereo_cv(&cv_camera(left), &cv_camera(right), (w, h), &r, &t)?;
    let mut out = format!(
        "%YAML:1.0\n---\n# stereo pair: camera 1 = '{}' (left), camera 2 = '{}' (right); p_2 = R p_1 + T in OpenCV camera frames, T in mm; R1 R2 P1 P2 Q as cv2.stereoRectify gives them (CALIB_ZERO_DISPARITY, alpha -1); written by pingcal calibrate\nleft_camera: \"{}\"\nright_camera: \"{}\"\ntranslation_unit: \"mm\"\nimage_width: {w}\nimage_height: {h}\n",
        left.id, right.id, left.id, right.id
    );
    cv_matrix(&mut out, "K1", 3, 3, &k_data(left));
    cv_matrix(&mut out, "D1", 1, 5, &left.opencv.dist);
    cv_matrix(&mut out, "K2", 3, 3, &k_data(right));
    cv_matrix(&mut out, "D2", 1, 5, &right.opencv.dist);
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

/// One camera of the camchain (its lines after `camN:`).
fn kalibr_camera(out: &mut String, n: usize, c: &CameraJson, overlaps: &[usize]) {
    let o = &c.opencv;
    let _ = writeln!(
        out,
        "  # camera '{}'; k3 = {} and B2 = {} dropped (radtan has k1 k2 r1 r2)",
        c.id,
        num(o.dist[4]),
        num(o.opencv_dropped_b2)
    );
    let lists = overlaps.iter().map(|k| k.to_string()).collect::<Vec<_>>();
    let _ = writeln!(out, "  cam_overlaps: [{}]", lists.join(", "));
    let _ = writeln!(out, "  camera_model: pinhole");
    let _ = writeln!(out, "  distortion_coeffs: [{}]", nums(&o.dist[..4]));
    let _ = writeln!(out, "  distortion_model: radtan");
    let _ = writeln!(out, "  intrinsics: [{}]", nums(&[o.fx, o.fy, o.cx, o.cy]));
    let _ = writeln!(out, "  resolution: [{}, {}]", o.image_width, o.image_height);
    let _ = writeln!(out, "  rostopic: /cam{n}/image_raw");
}

/// `kalibr/camchain.yaml`: `cams` in order (cam0, cam1), and for a rig cam1's `T_cn_cnm1`
/// (`p_cam1 = T p_cam0`, OpenCV frames, metres).
pub fn kalibr_camchain(cams: &[&CameraJson], rig: Option<&RigJson>) -> String {
    let mut out = String::from("# Kalibr camchain written by pingcal calibrate; the rostopics are placeholders: set them to your image topics\n");
    for (n, c) in cams.iter().enumerate() {
        let _ = writeln!(out, "cam{n}:");
        if n > 0 {
            if let Some(r) = rig {
                let rot = &r.opencv.rotation;
                let t = r.opencv.translation_mm.map(|v| v / 1000.0);
                let _ = writeln!(out, "  T_cn_cnm1:");
                for i in 0..3 {
                    let _ = writeln!(out, "  - [{}, {}]", nums(&rot[i]), num(t[i]));
                }
                let _ = writeln!(out, "  - [0.0, 0.0, 0.0, 1.0]");
            }
        }
        let overlaps: Vec<usize> = (0..cams.len()).filter(|&k| k != n).collect();
        kalibr_camera(&mut out, n, c, &overlaps);
    }
    out
}

/// The cameras in Kalibr's order: left and right of the rig, else the main camera alone.
fn chain(r: &Results) -> Vec<&CameraJson> {
    let find = |id: &str| r.cameras.iter().find(|c| c.id == id);
    match &r.bundle.rig {
        Some(rig) => [&rig.left, &rig.right]
            .iter()
            .filter_map(|id| find(id))
            .collect(),
        None => find(&r.conventions.main_camera).into_iter().collect(),
    }
}

/// Every file of `ros/`, `opencv/` and `kalibr/` for `r`.
pub fn exports(r: &Results) -> Vec<OutputFile> {
    let conv = &r.conventions;
    let mut out = ros_files(&r.extrinsic, &conv.tf_camera_frame, &conv.tf_lrf_frame);
    for c in &r.cameras {
        out.push((
            format!("opencv/camera_{}.yaml", file_stem(&c.id)),
            opencv_camera_yaml(c),
        ));
    }
    let cams = chain(r);
    if let (Some(rig), [left, right]) = (&r.bundle.rig, cams.as_slice()) {
        if let Some(y) = opencv_stereo_yaml(left, right, rig) {
            out.push(("opencv/stereo.yaml".into(), y));
        }
    }
    out.push((
        "kalibr/camchain.yaml".into(),
        kalibr_camchain(&cams, r.bundle.rig.as_ref()),
    ));
    out
}

#[cfg(test)]
mod tests {
    use super::super::results::{cv_from_photogrammetric, extrinsic_json, opencv_of, rig_json};
    use super::*;
    use nalgebra::{Quaternion, Rotation3, UnitQuaternion};
    use pingcal_geometry::{from_opk_deg, Rigid3, Sim3};
    use pingcal_project::CameraParams;

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
        let p = [
            c_mm, 0.012, -0.009, -0.021, 0.0004, -2e-6, 0.00015, -0.0001, 0.0, 0.0,
        ];
        CameraJson {
            id: id.into(),
            params: CameraParams::from_slice(&p),
            sigma: Default::default(),
            high_correlations: Vec::new(),
            opencv: opencv_of(&p, 1280, 720, 0.00375),
        }
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
        let y = opencv_camera_yaml(&c);
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
        let chain = kalibr_camchain(&[&a, &b], Some(&rig));
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
        let y = opencv_stereo_yaml(&a, &b, &rig).unwrap();
        let rc = Matrix3::from_row_slice(&cv_data(&y, "R"));
        let tc = Vector3::from_row_slice(&cv_data(&y, "T"));
        assert!((rc * c * p_left + tc - c * (r * p_left + t)).norm() < 1e-12);
        assert!(chain.contains("cam0:\n") && chain.contains("distortion_model: radtan"));
    }
}
