//! # The LRF's settings, resolved once
//!
//! What a user says about the sensor — in a project's `[lrf]`, sphere-calib's `[lidar]` or
//! a command's flags — becomes here the values the readers and the fits use, by one
//! function each, so that the project file and the command line are read alike and nothing
//! downstream parses a word again:
//!
//! - [`range_noise`]: the range noise of a named profile ([`NoiseProfile`]) or of
//!   σ = a + b·r, refused when both are given or the line is not a noise;
//! - [`ServoSource::from_keys`]: where a bag's servo angle comes from (a JointState's joint,
//!   a numeric topic's scale and offset, a tf child frame about an axis);
//! - [`ServoMotion`]: how the servo moves while the scanner sweeps;
//! - [`Stamps`]: whose time a bag's messages are taken at.
//!
//! The words of the closed sets ([`NoiseProfile`], [`crate::cloud_file::CloudUnit`],
//! [`ServoMotion`], [`Stamps`]) are refused while a file is read, with the words allowed.

use crate::sensor::{NoiseProfile, RangeNoise};

/// How the servo moves while the scanner sweeps (`[lrf.bag] servo_motion`,
/// `--servo-motion`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ServoMotion {
    /// Tell from the servo series (`pingcal_rosbag::motion::classify`).
    #[default]
    Auto,
    /// The servo stands still during each scan: zero-order hold of its last angle.
    StopAndGo,
    /// The servo turns while the scanner sweeps: interpolated at each beam's time.
    Continuous,
}

impl ServoMotion {
    /// Every motion, as the command line and the project file spell them.
    pub const NAMES: [&'static str; 3] = ["auto", "stop-and-go", "continuous"];

    /// The name as the command line and the project file spell it.
    pub fn name(self) -> &'static str {
        Self::NAMES[self as usize]
    }

    /// The motion spelled `word`, if any.
    pub fn from_word(word: &str) -> Option<Self> {
        [Self::Auto, Self::StopAndGo, Self::Continuous]
            .into_iter()
            .find(|m| m.name() == word)
    }

    /// Parses `auto`, `stop-and-go` or `continuous`.
    pub fn parse(s: &str) -> Result<Self, String> {
        Self::from_word(s)
            .ok_or_else(|| format!("servo motion {s:?}: expected auto, stop-and-go or continuous"))
    }
}

impl serde::Serialize for ServoMotion {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

impl<'de> serde::Deserialize<'de> for ServoMotion {
    /// One of [`ServoMotion::NAMES`], anything else refused with the words allowed.
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        crate::words::deserialize(d, &Self::NAMES, Self::from_word)
    }
}

/// Whose time a bag's messages are taken at (`[lrf.bag] stamps`, `--stamps`): a message's
/// header stamp (the driver's clock) or the bag's record time (the recorder's clock).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Stamps {
    /// Tell from the data (`pingcal_rosbag::clock`): the header stamps where both topics'
    /// keep the clock the other topic's times keep, else the record times.
    #[default]
    Auto,
    /// The header stamps (a topic without a header, e.g. `std_msgs/Int32`, has only its
    /// record times).
    Header,
    /// The bag's record times, for every topic.
    Record,
}

impl Stamps {
    /// Every choice, as the command line and the project file spell them.
    pub const NAMES: [&'static str; 3] = ["auto", "header", "record"];

    /// The name as the command line and the project file spell it.
    pub fn name(self) -> &'static str {
        Self::NAMES[self as usize]
    }

    /// The choice spelled `word`, if any.
    pub fn from_word(word: &str) -> Option<Self> {
        [Self::Auto, Self::Header, Self::Record]
            .into_iter()
            .find(|m| m.name() == word)
    }

    /// Parses `auto`, `header` or `record`.
    pub fn parse(s: &str) -> Result<Self, String> {
        Self::from_word(s).ok_or_else(|| format!("stamps {s:?}: expected auto, header or record"))
    }
}

impl serde::Serialize for Stamps {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

impl<'de> serde::Deserialize<'de> for Stamps {
    /// One of [`Stamps::NAMES`], anything else refused with the words allowed.
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        crate::words::deserialize(d, &Self::NAMES, Self::from_word)
    }
}

/// Where the servo angle comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum ServoSource {
    /// `sensor_msgs/JointState`: the position (radians) of the named joint.
    Joint(String),
    /// A numeric `std_msgs` topic: degrees = value · `scale` + `offset` (e.g. Dynamixel
    /// ticks with scale 360/4096). Such messages have no stamp: the bag's record time is
    /// used.
    Numeric {
        /// Degrees per unit.
        scale: f64,
        /// Degrees at value 0.
        offset: f64,
    },
    /// `tf2_msgs/TFMessage`: the rotation of the named child frame about `axis` (unit
    /// vector in the parent frame), degrees.
    Tf {
        /// The child frame.
        child: String,
        /// The servo axis.
        axis: [f64; 3],
    },
}

/// The keys that say where the servo angle comes from, as a project's `[lrf.bag]` or the
/// flags of `pingcal scans` give them (absent: `None`).
#[derive(Debug, Clone, Copy, Default)]
pub struct ServoKeys<'a> {
    /// `servo_joint`: the joint of a JointState topic.
    pub joint: Option<&'a str>,
    /// `servo_scale`: a numeric topic's degrees per unit (default 1).
    pub scale: Option<f64>,
    /// `servo_offset`: a numeric topic's degrees at value 0 (default 0).
    pub offset: Option<f64>,
    /// `servo_tf_child`: the child frame of a tf topic.
    pub tf_child: Option<&'a str>,
    /// `servo_axis`: a tf topic's servo axis (default `[0, 1, 0]`), any length but 0.
    pub axis: Option<[f64; 3]>,
}

/// How the keys of a [`ServoKeys`] are named in errors.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum KeyStyle {
    /// As a file's keys: `servo_axis`.
    File,
    /// As flags: `--servo-axis`.
    Flags,
}

impl KeyStyle {
    /// `key` (a file's spelling) as this style writes it.
    fn name(self, key: &str) -> String {
        match self {
            KeyStyle::File => key.to_string(),
            KeyStyle::Flags => format!("--{}", key.replace('_', "-")),
        }
    }
}

impl ServoSource {
    /// The source the keys give: a joint, a tf child frame (about the axis made a unit
    /// vector) or else a numeric topic; refused, naming the keys as `style` writes them,
    /// when more than one source is given, an axis without a tf child or of length 0 (or not
    /// finite), or a scale or offset not finite or a scale of 0.
    pub fn from_keys(k: &ServoKeys<'_>, style: KeyStyle) -> Result<ServoSource, String> {
        let n = |key: &str| style.name(key);
        let numeric = k.scale.is_some() || k.offset.is_some();
        let given = [k.joint.is_some(), numeric, k.tf_child.is_some()];
        if given.iter().filter(|g| **g).count() > 1 {
            return Err(format!(
                "{}, {}/{} and {}: give one, the joint of a JointState topic, the scale and offset of a numeric one or the child frame of a tf topic",
                n("servo_joint"),
                n("servo_scale"),
                n("servo_offset"),
                n("servo_tf_child")
            ));
        }
        if let (Some(a), None) = (k.axis, k.tf_child) {
            return Err(format!(
                "{} = {a:?}: only for a tf servo topic (with {})",
                n("servo_axis"),
                n("servo_tf_child")
            ));
        }
        if let Some(joint) = k.joint {
            return Ok(ServoSource::Joint(joint.to_string()));
        }
        if let Some(child) = k.tf_child {
            let a = k.axis.unwrap_or([0.0, 1.0, 0.0]);
            let norm = a.iter().map(|v| v * v).sum::<f64>().sqrt();
            if !(norm.is_finite() && norm > 0.0) {
                return Err(format!(
                    "{} = {a:?}: expected three finite numbers, not all 0",
                    n("servo_axis")
                ));
            }
            return Ok(ServoSource::Tf {
                child: child.to_string(),
                axis: a.map(|v| v / norm),
            });
        }
        let scale = k.scale.unwrap_or(1.0);
        let offset = k.offset.unwrap_or(0.0);
        if !(scale.is_finite() && scale != 0.0 && offset.is_finite()) {
            return Err(format!(
                "{} = {scale}, {} = {offset}: expected finite numbers, the scale not 0",
                n("servo_scale"),
                n("servo_offset")
            ));
        }
        Ok(ServoSource::Numeric { scale, offset })
    }
}

/// The largest `a` of σ = a + b·r, mm (1 km: a value in the wrong unit, or a corrupt one).
pub const MAX_NOISE_A_MM: f64 = 1e6;

/// The range noise a sensor's settings give: the named profile, or σ = a + b·r of `linear`
/// (`[a_mm, b]`, a > 0 mm up to [`MAX_NOISE_A_MM`], 0 ≤ b ≤ 1), or `None` when neither is
/// given (the caller's default). Refused, naming the settings as `keys` (`[named,
/// linear]`, e.g. `["[lrf] noise", "[lrf] noise_sigma_mm"]` or `["--noise",
/// "--noise-sigma"]`), when both are given or the line is no noise.
pub fn range_noise(
    named: Option<NoiseProfile>,
    linear: Option<[f64; 2]>,
    keys: [&str; 2],
) -> Result<Option<RangeNoise>, String> {
    match (named, linear) {
        (Some(_), Some(_)) => Err(format!(
            "{} and {}: give one, a named profile or [a, b]",
            keys[0], keys[1]
        )),
        (Some(p), None) => Ok(Some(p.noise())),
        (None, Some([a, b])) => {
            let ok = a > 0.0 && a <= MAX_NOISE_A_MM && (0.0..=1.0).contains(&b);
            if !ok {
                return Err(format!(
                    "{} = [{a}, {b}]: expected 0 < a <= {MAX_NOISE_A_MM:e} mm and 0 <= b <= 1 (σ = a + b·r)",
                    keys[1]
                ));
            }
            Ok(Some(RangeNoise::Linear { a_mm: a, b }))
        }
        (None, None) => Ok(None),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_servo_source_from_the_keys_or_the_reason() {
        let keys = ServoKeys::default();
        assert_eq!(
            ServoSource::from_keys(&keys, KeyStyle::File),
            Ok(ServoSource::Numeric {
                scale: 1.0,
                offset: 0.0
            })
        );
        let tf = ServoKeys {
            tf_child: Some("servo_link"),
            axis: Some([0.0, 2.0, 0.0]),
            ..keys
        };
        assert_eq!(
            ServoSource::from_keys(&tf, KeyStyle::File),
            Ok(ServoSource::Tf {
                child: "servo_link".into(),
                axis: [0.0, 1.0, 0.0]
            })
        );
        let both = ServoKeys {
            joint: Some("servo"),
            scale: Some(0.088),
            ..keys
        };
        let e = ServoSource::from_keys(&both, KeyStyle::Flags).unwrap_err();
        assert!(
            e.starts_with(
                "--servo-joint, --servo-scale/--servo-offset and --servo-tf-child: give one"
            ),
            "{e}"
        );
        let zero = ServoKeys {
            axis: Some([0.0; 3]),
            ..tf
        };
        let e = ServoSource::from_keys(&zero, KeyStyle::File).unwrap_err();
        assert_eq!(
            e,
            "servo_axis = [0.0, 0.0, 0.0]: expected three finite numbers, not all 0"
        );
        let lone_axis = ServoKeys {
            axis: Some([0.0, 1.0, 0.0]),
            ..keys
        };
        let e = ServoSource::from_keys(&lone_axis, KeyStyle::File).unwrap_err();
        assert!(
            e.contains("servo_axis = [0.0, 1.0, 0.0]: only for a tf servo topic"),
            "{e}"
        );
        let flat = ServoKeys {
            scale: Some(0.0),
            ..keys
        };
        let e = ServoSource::from_keys(&flat, KeyStyle::Flags).unwrap_err();
        assert_eq!(
            e,
            "--servo-scale = 0, --servo-offset = 0: expected finite numbers, the scale not 0"
        );
    }

    #[test]
    fn one_range_noise_from_a_name_or_a_line() {
        let keys = ["noise", "noise_sigma_mm"];
        assert_eq!(range_noise(None, None, keys), Ok(None));
        assert_eq!(
            range_noise(Some(NoiseProfile::Vlp16), None, keys),
            Ok(Some(RangeNoise::Linear { a_mm: 10.0, b: 0.0 }))
        );
        assert_eq!(
            range_noise(None, Some([5.0, 0.002]), keys)
                .unwrap()
                .unwrap()
                .sigma(1000.0),
            7.0
        );
        for bad in [
            [0.0, 0.01],
            [5.0, f64::NAN],
            [5.0, -0.1],
            [2e6, 0.0],
            [5.0, 2.0],
        ] {
            let e = range_noise(None, Some(bad), keys).unwrap_err();
            assert!(e.starts_with("noise_sigma_mm = ["), "{e}");
        }
        let e = range_noise(Some(NoiseProfile::Urg04lx), Some([5.0, 0.0]), keys).unwrap_err();
        assert_eq!(
            e,
            "noise and noise_sigma_mm: give one, a named profile or [a, b]"
        );
    }

    #[test]
    fn the_closed_sets_read_their_words_and_list_them_otherwise() {
        #[derive(serde::Deserialize, Debug)]
        struct T {
            noise: Option<NoiseProfile>,
            unit: Option<crate::cloud_file::CloudUnit>,
            motion: Option<ServoMotion>,
        }
        let t: T =
            serde_json::from_str(r#"{"noise": "utm_30lx", "unit": "m", "motion": "stop-and-go"}"#)
                .unwrap();
        assert_eq!(t.noise, Some(NoiseProfile::Utm30lx));
        assert_eq!(t.unit, Some(crate::cloud_file::CloudUnit::M));
        assert_eq!(t.motion, Some(ServoMotion::StopAndGo));
        for (json, allowed) in [
            (
                r#"{"noise": "bogus"}"#,
                "expected one of URG-04LX, UTM-30LX, UST-10LX, VLP-16",
            ),
            (r#"{"unit": "cm"}"#, "expected one of mm, m"),
            (
                r#"{"motion": "jerky"}"#,
                "expected one of auto, stop-and-go, continuous",
            ),
        ] {
            let e = serde_json::from_str::<T>(json).unwrap_err().to_string();
            assert!(e.contains(allowed), "{e}");
        }
    }
}
