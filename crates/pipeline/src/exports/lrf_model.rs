//! The LRF's whole model for ROS: a URDF with the servo (its zero and scale as a mimic
//! joint), the mount's offsets and tilts, and the extrinsic's fixed joint, with its
//! `robot_state_publisher` launch files; the range correction, which tf cannot apply, is
//! stated in the file's comment.

use super::{num, rpy, OutputFile, Tf};
use crate::results::ExtrinsicJson;
use nalgebra::Matrix3;
use pingcal_lrf::MountModel;

/// The servo axis of the URDF: `R_β` is a rotation about +Y by −β, i.e. about −Y by β.
pub const SERVO_AXIS: [f64; 3] = [0.0, -1.0, 0.0];

/// `R_x(tilt_x) · R_z(tilt_z)` of the mount (docs/lrf.md).
pub fn mount_tilt(m: &MountModel) -> Matrix3<f64> {
    let (sx, cx) = m.tilt_x_deg.to_radians().sin_cos();
    let (sz, cz) = m.tilt_z_deg.to_radians().sin_cos();
    let rx = Matrix3::new(1.0, 0.0, 0.0, 0.0, cx, -sx, 0.0, sx, cx);
    let rz = Matrix3::new(cz, -sz, 0.0, sz, cz, 0.0, 0.0, 0.0, 1.0);
    rx * rz
}

/// The names of the URDF's frames and joints below the LRF frame `lrf`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LrfChainNames {
    /// The continuous joint the servo's `sensor_msgs/JointState` drives (`<lrf>_servo`).
    pub servo_joint: String,
    /// The mimic joint that adds the servo's zero and scale (`<lrf>_servo_correction`).
    pub correction_joint: String,
    /// The fixed joint of the mount (`<lrf>_mount`).
    pub mount_joint: String,
    /// The frame turned by the raw servo reading (`<lrf>_servo_raw`).
    pub raw_link: String,
    /// The frame turned by β, the turning frame of docs/lrf.md (`<lrf>_turning`).
    pub turning_link: String,
    /// The 2D scanner's frame, a LaserScan's `frame_id` (`<lrf>_scanner`).
    pub scanner_link: String,
}

impl LrfChainNames {
    /// The names below LRF frame `lrf`.
    pub fn of(lrf: &str) -> Self {
        LrfChainNames {
            servo_joint: format!("{lrf}_servo"),
            correction_joint: format!("{lrf}_servo_correction"),
            mount_joint: format!("{lrf}_mount"),
            raw_link: format!("{lrf}_servo_raw"),
            turning_link: format!("{lrf}_turning"),
            scanner_link: format!("{lrf}_scanner"),
        }
    }
}

/// One `<joint>` of a URDF (`extra`: its axis, mimic, … lines).
fn urdf_joint(
    name: &str,
    kind: &str,
    parent: &str,
    child: &str,
    xyz: &str,
    rpy: &str,
    extra: &str,
) -> String {
    format!(
        "  <joint name=\"{name}\" type=\"{kind}\">\n    <parent link=\"{parent}\"/>\n    <child link=\"{child}\"/>\n    <origin xyz=\"{xyz}\" rpy=\"{rpy}\"/>\n{extra}  </joint>\n"
    )
}

/// The comment of [`lrf_model_urdf`]: the model, the chain, and the range correction tf
/// cannot apply.
fn lrf_model_comment(tf: &Tf, m: &MountModel, source: &str, n: &LrfChainNames) -> String {
    format!(
        "<!-- The LRF's whole model, results.json's lrf_model (source: {source}), written by pingcal calibrate:\n     p_lrf = R_beta (R_x(tilt_x) R_z(tilt_z) (r cos(alpha), r sin(alpha), 0) + offset), beta = (servo - servo_zero) (1 + servo_scale),\n     R_beta = [[cos beta, 0, -sin beta], [0, 1, 0], [sin beta, 0, cos beta]] (about -Y by beta); the LRF frame '{lrf}' is pingcal's (that of cloud.ply).\n     Chain: '{cam}' -> fixed joint (the extrinsic, as laser_joint.urdf) -> '{lrf}' -> '{sj}' (continuous about -Y; its position is the servo's raw\n     reading in rad, as the servo's sensor_msgs/JointState gives it: name the joint as your servo driver does, or rename it here) -> '{raw}' ->\n     '{cj}' (mimic: multiplier = servo_scale = {scale}, offset = -servo_zero (1 + servo_scale) = {off} rad, servo_zero = {zero} deg, so the two add to beta)\n     -> '{turn}' -> '{mj}' (fixed: xyz = offset = {ox} m, rpy of R_x(tilt_x) R_z(tilt_z), tilt_x = {tx} deg, tilt_z = {tz} deg) -> '{scan}',\n     the frame_id your LaserScan messages must carry (angle alpha about its z from its x axis).\n     Not in tf: the range correction r = (reported - range_offset) / (1 + range_scale) with range_offset = {ro} mm ({rom} m) and\n     range_scale = {rs}: apply it to every range before use (tf moves frames; it cannot change a range).{timing} Every other part of the model is in this file.\n     Run it with lrf_model_ros1.launch or lrf_model_ros2.launch.py (robot_state_publisher); it publishes the extrinsic too, so do not run\n     static_transform_*.launch beside it. -->\n",
        lrf = tf.child,
        cam = tf.parent,
        sj = n.servo_joint,
        raw = n.raw_link,
        cj = n.correction_joint,
        scale = num(m.servo_scale),
        off = num(mimic_offset(m)),
        zero = num(m.servo_zero_deg),
        turn = n.turning_link,
        mj = n.mount_joint,
        ox = m.offset_mm.map(|v| num(v / 1000.0)).join(" "),
        tx = num(m.tilt_x_deg),
        tz = num(m.tilt_z_deg),
        scan = n.scanner_link,
        ro = num(m.range_offset_mm),
        rom = num(m.range_offset_mm / 1000.0),
        rs = num(m.range_scale),
        timing = timing_note(m),
    )
}

/// The servo time offset of `m`, which tf cannot apply either (nothing when it is zero).
fn timing_note(m: &MountModel) -> String {
    if m.servo_time_offset_s == 0.0 {
        return String::new();
    }
    format!(
        "\n     Nor the servo's time offset: its stamps are {t} s later than the scanner's (servo_time_offset_s), so stamp the servo's JointState\n     messages {t} s earlier (or look the servo's tf up at a beam's time + {t} s).",
        t = num(m.servo_time_offset_s)
    )
}

/// The mimic joint's offset, rad: `−servo_zero · (1 + servo_scale)`.
fn mimic_offset(m: &MountModel) -> f64 {
    -m.servo_zero_deg.to_radians() * (1.0 + m.servo_scale)
}

/// `ros/lrf_model.urdf`: the camera frame `parent`, the extrinsic `e` to the LRF frame
/// `child`, then the servo (a continuous joint about [`SERVO_AXIS`] at the raw reading, a
/// mimic joint adding `multiplier · q + offset` with multiplier = servo_scale and offset =
/// −servo_zero·(1 + servo_scale), so that the two angles add to β), then the mount (a fixed
/// joint: xyz = offset in m, rpy of `R_x(tilt_x) R_z(tilt_z)`) to the 2D scanner's frame.
/// Composed, `lrf_from_scanner(q) · (r cos α, r sin α, 0) = R_β (R_x R_z (r cos α, r sin α,
/// 0) + offset)`: the model of `m` but for the range correction, which the comment states.
pub fn lrf_model_urdf(
    e: &ExtrinsicJson,
    m: &MountModel,
    source: &str,
    parent: &str,
    child: &str,
) -> String {
    let tf = Tf::of(e, parent, child);
    let n = LrfChainNames::of(child);
    let axis = format!("    <axis xyz=\"{}\"/>\n", SERVO_AXIS.map(num).join(" "));
    let zero = "0.0 0.0 0.0";
    let mimic = format!(
        "{axis}    <mimic joint=\"{}\" multiplier=\"{}\" offset=\"{}\"/>\n",
        n.servo_joint,
        num(m.servo_scale),
        num(mimic_offset(m))
    );
    let joints = [
        urdf_joint(
            &(tf.node_name().trim_start_matches("pingcal_").to_string() + "_joint"),
            "fixed",
            parent,
            child,
            &tf.t.map(num).join(" "),
            &tf.rpy.map(num).join(" "),
            "",
        ),
        urdf_joint(
            &n.servo_joint,
            "continuous",
            child,
            &n.raw_link,
            zero,
            zero,
            &axis,
        ),
        urdf_joint(
            &n.correction_joint,
            "continuous",
            &n.raw_link,
            &n.turning_link,
            zero,
            zero,
            &mimic,
        ),
        urdf_joint(
            &n.mount_joint,
            "fixed",
            &n.turning_link,
            &n.scanner_link,
            &m.offset_mm.map(|v| num(v / 1000.0)).join(" "),
            &rpy(&mount_tilt(m)).map(num).join(" "),
            "",
        ),
    ];
    let links: String = [parent, child, &n.raw_link, &n.turning_link, &n.scanner_link]
        .iter()
        .map(|l| format!("  <link name=\"{l}\"/>\n"))
        .collect();
    format!(
        "<?xml version=\"1.0\"?>\n{}<robot name=\"pingcal_lrf_model\">\n{links}{}</robot>\n",
        lrf_model_comment(&tf, m, source, &n),
        joints.concat()
    )
}

/// `ros/lrf_model_ros1.launch`: `robot_state_publisher` with `lrf_model.urdf` beside it.
fn lrf_model_ros1_launch(what: &str) -> String {
    format!("<launch>\n  <!-- ROS 1: {what} -->\n  <param name=\"robot_description\" textfile=\"$(dirname)/lrf_model.urdf\" />\n  <node pkg=\"robot_state_publisher\" type=\"robot_state_publisher\" name=\"pingcal_lrf_model_state_publisher\" />\n</launch>\n")
}

/// `ros/lrf_model_ros2.launch.py`: `robot_state_publisher` with `lrf_model.urdf` beside it.
fn lrf_model_ros2_launch(what: &str) -> String {
    format!("# ROS 2 launch file: {what}\nimport os\n\nfrom launch import LaunchDescription\nfrom launch_ros.actions import Node\n\n\ndef generate_launch_description():\n    urdf = os.path.join(os.path.dirname(os.path.abspath(__file__)), \"lrf_model.urdf\")\n    with open(urdf, encoding=\"utf-8\") as f:\n        description = f.read()\n    return LaunchDescription([\n        Node(\n            package=\"robot_state_publisher\",\n            executable=\"robot_state_publisher\",\n            name=\"pingcal_lrf_model_state_publisher\",\n            parameters=[{{\"robot_description\": description}}],\n        ),\n    ])\n")
}

/// The LRF model's files of `ros/`: the URDF ([`lrf_model_urdf`]) and its launch files.
pub fn lrf_model_files(
    e: &ExtrinsicJson,
    m: &MountModel,
    source: &str,
    parent: &str,
    child: &str,
) -> Vec<OutputFile> {
    let what = format!(
        "the LRF's whole model (lrf_model.urdf beside this file, see its comment) through robot_state_publisher: '{parent}' -> '{child}' -> '{}';\n# the servo's sensor_msgs/JointState on /joint_states drives its joint '{}' (written by pingcal calibrate)",
        LrfChainNames::of(child).scanner_link,
        LrfChainNames::of(child).servo_joint
    );
    vec![
        (
            "ros/lrf_model.urdf".into(),
            lrf_model_urdf(e, m, source, parent, child),
        ),
        (
            "ros/lrf_model_ros1.launch".into(),
            lrf_model_ros1_launch(&what.replace("\n#", "\n    ")),
        ),
        (
            "ros/lrf_model_ros2.launch.py".into(),
            lrf_model_ros2_launch(&what),
        ),
    ]
}
