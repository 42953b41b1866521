//! The messages pingcal reads, decoded field by field from either wire format
//! ([`crate::wire`]): `sensor_msgs/LaserScan`, `sensor_msgs/JointState`, the numeric
//! `std_msgs` (Float32, Float64, Int32, UInt16), `tf2_msgs/TFMessage`, and for
//! `pingcal frames` `sensor_msgs/PointCloud2`, `sensor_msgs/Image` and
//! `sensor_msgs/CompressedImage`.

use crate::wire::{Encoding, Wire, WireError};

/// The type names this crate decodes, in their ROS 1 spelling (`pkg/Name`).
pub const LASER_SCAN: &str = "sensor_msgs/LaserScan";
/// `sensor_msgs/JointState`.
pub const JOINT_STATE: &str = "sensor_msgs/JointState";
/// `tf2_msgs/TFMessage`.
pub const TF_MESSAGE: &str = "tf2_msgs/TFMessage";
/// `sensor_msgs/PointCloud2`.
pub const POINT_CLOUD2: &str = "sensor_msgs/PointCloud2";
/// `sensor_msgs/Image`.
pub const IMAGE: &str = "sensor_msgs/Image";
/// `sensor_msgs/CompressedImage`.
pub const COMPRESSED_IMAGE: &str = "sensor_msgs/CompressedImage";
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

/// One point of a [`PointCloud2`]: x, y, z (the message's unit, metres), and its
/// intensity and ring when the message has those fields.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CloudPoint {
    /// x, y, z.
    pub xyz: [f64; 3],
    /// `intensity`, when present.
    pub intensity: Option<f64>,
    /// `ring`, when present.
    pub ring: Option<f64>,
}

/// `sensor_msgs/PointCloud2`: its stamp, frame and points (points with a non-finite
/// coordinate, an organized cloud's "no return", are left out).
#[derive(Debug, Clone, PartialEq)]
pub struct PointCloud2 {
    /// `header.stamp`, ns.
    pub stamp_ns: i64,
    /// `header.frame_id`.
    pub frame_id: String,
    /// The points.
    pub points: Vec<CloudPoint>,
    /// Whether the message had `intensity` and `ring` fields.
    pub has_intensity: bool,
    /// See `has_intensity`.
    pub has_ring: bool,
}

/// A `PointField` datatype's reader: (size in bytes, value from the bytes).
fn field_value(datatype: u8, b: &[u8], big: bool) -> Option<f64> {
    let a = |n: usize| -> Option<Vec<u8>> {
        let mut v = b.get(..n)?.to_vec();
        if big {
            v.reverse();
        }
        Some(v)
    };
    Some(match datatype {
        1 => f64::from(b.first().copied()? as i8),
        2 => f64::from(*b.first()?),
        3 => f64::from(i16::from_le_bytes(a(2)?.try_into().ok()?)),
        4 => f64::from(u16::from_le_bytes(a(2)?.try_into().ok()?)),
        5 => f64::from(i32::from_le_bytes(a(4)?.try_into().ok()?)),
        6 => f64::from(u32::from_le_bytes(a(4)?.try_into().ok()?)),
        7 => f64::from(f32::from_le_bytes(a(4)?.try_into().ok()?)),
        8 => f64::from_le_bytes(a(8)?.try_into().ok()?),
        _ => return None,
    })
}

impl PointCloud2 {
    /// Decodes one message: the fields `x`, `y`, `z` (any numeric type) and, where present,
    /// `intensity` and `ring`.
    pub fn decode(data: &[u8], enc: Encoding) -> Result<Self, WireError> {
        let mut w = Wire::new(data, enc)?;
        let (stamp_ns, frame_id) = w.header()?;
        let height = w.u32("height")? as usize;
        let width = w.u32("width")? as usize;
        let nf = w.len("fields", 9)?;
        let mut fields = Vec::with_capacity(nf);
        for _ in 0..nf {
            let name = w.string("fields.name")?;
            let offset = w.u32("fields.offset")? as usize;
            let datatype = w.u8("fields.datatype")?;
            let _count = w.u32("fields.count")?;
            fields.push((name, offset, datatype));
        }
        let big = w.u8("is_bigendian")? != 0;
        let point_step = w.u32("point_step")? as usize;
        let row_step = w.u32("row_step")? as usize;
        let bytes = w.u8_seq("data")?;
        let find = |n: &str| fields.iter().find(|f| f.0 == n).map(|f| (f.1, f.2));
        let (Some(x), Some(y), Some(z)) = (find("x"), find("y"), find("z")) else {
            return Err("PointCloud2 without the fields x, y and z".into());
        };
        let (fi, fr) = (find("intensity"), find("ring"));
        if point_step == 0 || width.saturating_mul(point_step) > row_step {
            return Err(format!(
                "{width} points of {point_step} bytes in a row of {row_step}: expected a point_step > 0 that fits"
            ));
        }
        if height.saturating_mul(row_step) > bytes.len() {
            return Err(format!(
                "{height} rows of {row_step} bytes, the data has {}",
                bytes.len()
            ));
        }
        let mut points = Vec::with_capacity(height * width);
        for r in 0..height {
            for c in 0..width {
                let at = r * row_step + c * point_step;
                let p = bytes
                    .get(at..at + point_step)
                    .ok_or("a point beyond the data")?;
                let get =
                    |(off, ty): (usize, u8)| p.get(off..).and_then(|b| field_value(ty, b, big));
                let (Some(px), Some(py), Some(pz)) = (get(x), get(y), get(z)) else {
                    return Err(format!(
                        "point {} of row {r}: a field beyond its {point_step} bytes",
                        c
                    ));
                };
                if !(px.is_finite() && py.is_finite() && pz.is_finite()) {
                    continue;
                }
                points.push(CloudPoint {
                    xyz: [px, py, pz],
                    intensity: fi.and_then(get),
                    ring: fr.and_then(get),
                });
            }
        }
        Ok(PointCloud2 {
            stamp_ns,
            frame_id,
            points,
            has_intensity: fi.is_some(),
            has_ring: fr.is_some(),
        })
    }
}

/// `sensor_msgs/Image`, its pixels borrowed from the message.
#[derive(Debug, Clone, PartialEq)]
pub struct Image<'a> {
    /// `header.stamp`, ns.
    pub stamp_ns: i64,
    /// Rows.
    pub height: u32,
    /// Columns.
    pub width: u32,
    /// `mono8`, `rgb8`, `bgr8`, `rgba8`, `bgra8`, `mono16`, ...
    pub encoding: String,
    /// 16-bit pixels are big-endian.
    pub big_endian: bool,
    /// Bytes per row.
    pub step: u32,
    /// The pixels.
    pub data: &'a [u8],
}

impl<'a> Image<'a> {
    /// Decodes one message.
    pub fn decode(data: &'a [u8], enc: Encoding) -> Result<Self, WireError> {
        let mut w = Wire::new(data, enc)?;
        let (stamp_ns, _) = w.header()?;
        Ok(Image {
            stamp_ns,
            height: w.u32("height")?,
            width: w.u32("width")?,
            encoding: w.string("encoding")?,
            big_endian: w.u8("is_bigendian")? != 0,
            step: w.u32("step")?,
            data: w.u8_seq("data")?,
        })
    }
}

/// `sensor_msgs/CompressedImage`: a JPEG or PNG file's bytes, borrowed from the message.
#[derive(Debug, Clone, PartialEq)]
pub struct CompressedImage<'a> {
    /// `header.stamp`, ns.
    pub stamp_ns: i64,
    /// `format` (`jpeg`, `png`, or image_transport's `rgb8; jpeg compressed bgr8`).
    pub format: String,
    /// The file's bytes.
    pub data: &'a [u8],
}

impl<'a> CompressedImage<'a> {
    /// Decodes one message.
    pub fn decode(data: &'a [u8], enc: Encoding) -> Result<Self, WireError> {
        let mut w = Wire::new(data, enc)?;
        let (stamp_ns, _) = w.header()?;
        Ok(CompressedImage {
            stamp_ns,
            format: w.string("format")?,
            data: w.u8_seq("data")?,
        })
    }
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
