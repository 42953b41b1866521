//! The messages pingcal reads, decoded field by field from either wire format
//! ([`crate::wire`]): `sensor_msgs/LaserScan`, `sensor_msgs/JointState`, the numeric
//! `std_msgs` (Float32, Float64, Int32, UInt16) and `tf2_msgs/TFMessage`.

use crate::wire::{Encoding, Wire, WireError};

/// The type names this crate decodes, in their ROS 1 spelling (`pkg/Name`).
pub const LASER_SCAN: &str = "sensor_msgs/LaserScan";
/// `sensor_msgs/JointState`.
pub const JOINT_STATE: &str = "sensor_msgs/JointState";
/// `tf2_msgs/TFMessage`.
pub const TF_MESSAGE: &str = "tf2_msgs/TFMessage";
/// The numeric `std_msgs` types a servo angle may come in.
pub const NUMERIC: [&str; 4] = [
    "std_msgs/Float32",
    "std_msgs/Float64",
    "std_msgs/Int32",
    "std_msgs/UInt16",
];

/// A type name in its ROS 1 spelling: ROS 2's `pkg/msg/Name` becomes `pkg/Name`.
pub fn normalize_type(t: &str) -> String {
    t.replacen("/msg/", "/", 1)
}

/// `sensor_msgs/LaserScan`, in its own units (seconds, radians, metres).
#[derive(Debug, Clone, PartialEq)]
pub struct LaserScan {
    /// `header.stamp`, nanoseconds since the epoch.
    pub stamp_ns: i64,
    /// `header.frame_id`.
    pub frame_id: String,
    /// Angle of beam 0, radians.
    pub angle_min: f32,
    /// Angle of the last beam, radians.
    pub angle_max: f32,
    /// Angle between beams, radians.
    pub angle_increment: f32,
    /// Time between beams, seconds.
    pub time_increment: f32,
    /// Time between scans, seconds.
    pub scan_time: f32,
    /// Shortest valid range, metres.
    pub range_min: f32,
    /// Longest valid range, metres.
    pub range_max: f32,
    /// Ranges, metres.
    pub ranges: Vec<f32>,
    /// Intensities (may be empty).
    pub intensities: Vec<f32>,
}

impl LaserScan {
    /// Decodes one message.
    pub fn decode(data: &[u8], enc: Encoding) -> Result<Self, WireError> {
        let mut w = Wire::new(data, enc)?;
        let (stamp_ns, frame_id) = w.header()?;
        Ok(LaserScan {
            stamp_ns,
            frame_id,
            angle_min: w.f32("angle_min")?,
            angle_max: w.f32("angle_max")?,
            angle_increment: w.f32("angle_increment")?,
            time_increment: w.f32("time_increment")?,
            scan_time: w.f32("scan_time")?,
            range_min: w.f32("range_min")?,
            range_max: w.f32("range_max")?,
            ranges: w.f32_seq("ranges")?,
            intensities: w.f32_seq("intensities")?,
        })
    }
}

/// `sensor_msgs/JointState`.
#[derive(Debug, Clone, PartialEq)]
pub struct JointState {
    /// `header.stamp`, nanoseconds.
    pub stamp_ns: i64,
    /// Joint names.
    pub name: Vec<String>,
    /// Positions (radians for a revolute joint).
    pub position: Vec<f64>,
    /// Velocities.
    pub velocity: Vec<f64>,
    /// Efforts.
    pub effort: Vec<f64>,
}

impl JointState {
    /// Decodes one message.
    pub fn decode(data: &[u8], enc: Encoding) -> Result<Self, WireError> {
        let mut w = Wire::new(data, enc)?;
        let (stamp_ns, _) = w.header()?;
        Ok(JointState {
            stamp_ns,
            name: w.string_seq("name")?,
            position: w.f64_seq("position")?,
            velocity: w.f64_seq("velocity")?,
            effort: w.f64_seq("effort")?,
        })
    }
}

/// The value of a numeric `std_msgs` message of type `ty` (ROS 1 spelling), as `f64`.
pub fn decode_numeric(ty: &str, data: &[u8], enc: Encoding) -> Result<f64, WireError> {
    let mut w = Wire::new(data, enc)?;
    match ty {
        "std_msgs/Float32" => w.f32("data").map(f64::from),
        "std_msgs/Float64" => w.f64("data"),
        "std_msgs/Int32" => w.i32("data").map(f64::from),
        "std_msgs/UInt16" => w.u16("data").map(f64::from),
        _ => Err(format!("{ty} is not a numeric std_msgs type")),
    }
}

/// One `geometry_msgs/TransformStamped` of a `tf2_msgs/TFMessage`.
#[derive(Debug, Clone, PartialEq)]
pub struct Transform {
    /// `header.stamp`, nanoseconds.
    pub stamp_ns: i64,
    /// Parent frame.
    pub frame_id: String,
    /// Child frame.
    pub child_frame_id: String,
    /// Translation x, y, z (metres).
    pub translation: [f64; 3],
    /// Rotation quaternion x, y, z, w.
    pub rotation: [f64; 4],
}

/// Decodes a `tf2_msgs/TFMessage`: its transforms.
pub fn decode_tf(data: &[u8], enc: Encoding) -> Result<Vec<Transform>, WireError> {
    let mut w = Wire::new(data, enc)?;
    let n = w.len("transforms", 4)?;
    (0..n)
        .map(|_| {
            let (stamp_ns, frame_id) = w.header()?;
            let child_frame_id = w.string("child_frame_id")?;
            let mut translation = [0.0; 3];
            for t in &mut translation {
                *t = w.f64("translation")?;
            }
            let mut rotation = [0.0; 4];
            for q in &mut rotation {
                *q = w.f64("rotation")?;
            }
            Ok(Transform {
                stamp_ns,
                frame_id,
                child_frame_id,
                translation,
                rotation,
            })
        })
        .collect()
}

/// The rotation angle (degrees) of quaternion `q` (x, y, z, w) about unit `axis`: the
/// twist part of its swing–twist decomposition, in (−180°, 180°].
pub fn twist_deg(q: [f64; 4], axis: [f64; 3]) -> f64 {
    let p = q[0] * axis[0] + q[1] * axis[1] + q[2] * axis[2];
    2.0 * p.atan2(q[3]).to_degrees()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn type_names_are_normalized_to_ros1() {
        assert_eq!(normalize_type("sensor_msgs/msg/LaserScan"), LASER_SCAN);
        assert_eq!(normalize_type(LASER_SCAN), LASER_SCAN);
    }

    #[test]
    fn twist_about_an_axis() {
        let h = 0.3f64.to_radians() / 2.0 * 100.0; // 30° about y
        let q = [0.0, h.sin(), 0.0, h.cos()];
        assert!((twist_deg(q, [0.0, 1.0, 0.0]) - 30.0).abs() < 1e-12);
        assert!((twist_deg(q, [0.0, -1.0, 0.0]) + 30.0).abs() < 1e-12);
    }
}
