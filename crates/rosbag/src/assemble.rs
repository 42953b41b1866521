//! From a bag's `LaserScan` and servo messages to pingcal scans
//! ([`pingcal_lrf::scan::ScanLine`]): each beam's time is the scan's stamp plus its index
//! times `time_increment`, and the servo angle is interpolated linearly in time between the
//! servo messages around it.
//!
//! A scan's first and last beam get their own servo angle (`servo_deg`, `servo_end_deg`:
//! the `pingcal-scan` v2 columns) and the beams between are linear in their index, which is
//! exact when no servo message falls inside the scan (the servo samples are slower than
//! the scans, or the servo stands still while it scans). Scans whose first beam is before
//! the first servo message, or whose last beam is after the last, are skipped and counted.
//!
//! Units: metres become millimetres and radians degrees. The message stores `float32`
//! values, so the millimetres (and the beam geometry's degrees) are the shortest decimal
//! that rounds to the stored `float32` (whole mm for a sensor that measures in mm, as the
//! recorder's metres were), else the exact `float32` value; a JointState's radians
//! likewise become the shortest decimal degrees that convert back to them exactly; ranges that are not finite or
//! outside `[range_min, range_max]` are no return (0, as in the CSV).
//!
//! A scan's `line` is its 1-based message number on the scan topic (in its bag).
//!
//! Each scan comes with its own beam geometry (count, first angle, step) in the
//! [`ScanHeader`] handed over with it: some drivers change it between messages (a beam
//! more or less, another field of view), and no scan is lost or resampled for it. The
//! caller groups the scans by geometry (`pingcal scans` writes one file per geometry, as a
//! `pingcal-scan` file has one); [`Assembled::geometry_changes`] counts the changes.

use crate::error::{Result, RosbagError};
use crate::msgs::{self, JointState, LaserScan};
use crate::{Bag, RawMessage};
use pingcal_lrf::scan::{ScanHeader, ScanLine, MIN_VALID_RANGE_MM};

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

/// The topics to read and how.
#[derive(Debug, Clone, PartialEq)]
pub struct Topics {
    /// The `sensor_msgs/LaserScan` topic.
    pub scan: String,
    /// The servo topic.
    pub servo: String,
    /// How the servo topic's messages give the angle.
    pub source: ServoSource,
}

/// The servo angle over time: samples in time order (nanoseconds, degrees).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ServoSeries {
    /// Sample times, ns, strictly increasing.
    pub times_ns: Vec<i64>,
    /// Angles, degrees.
    pub deg: Vec<f64>,
}

impl ServoSeries {
    /// The angle at `base_ns + off_ns` (off_ns ≥ 0, fractional), or `None` outside the
    /// samples.
    pub fn at(&self, base_ns: i64, off_ns: f64) -> Option<f64> {
        let whole = base_ns.checked_add(off_ns.floor() as i64)?;
        let last = *self.times_ns.last()?;
        let t = |k: usize| (self.times_ns[k] - base_ns) as f64;
        if whole < self.times_ns[0] || whole > last || (whole == last && off_ns > off_ns.floor()) {
            return None;
        }
        // first sample strictly after `whole`
        let k1 = self.times_ns.partition_point(|&s| s <= whole);
        if k1 == self.times_ns.len() {
            return Some(self.deg[k1 - 1]); // exactly at the last sample
        }
        let k0 = k1 - 1;
        let (d0, d1) = (self.deg[k0], self.deg[k1]);
        let f = (off_ns - t(k0)) / (t(k1) - t(k0));
        Some(d0 + f * (d1 - d0))
    }
}

fn expect_type(bag: &Bag, m: &RawMessage, expected: &[&str]) -> Result<()> {
    if expected.contains(&m.msg_type) {
        return Ok(());
    }
    Err(RosbagError::WrongType {
        file: bag.name().to_string(),
        topic: m.topic.to_string(),
        found: m.msg_type.to_string(),
        expected: expected.join(" or "),
    })
}

/// The error for a topic that gave no message: absent (listing the topics present) or
/// empty.
fn no_messages(bag: &Bag, topic: &str) -> RosbagError {
    let topics = match bag.topics() {
        Ok(t) => t,
        Err(e) => return e,
    };
    if topics.iter().any(|t| t.name == topic) {
        return RosbagError::topic(bag.name(), topic, "no messages on the topic");
    }
    let present: Vec<String> = topics
        .iter()
        .map(|t| format!("{} ({})", t.name, t.msg_type))
        .collect();
    RosbagError::MissingTopic {
        file: bag.name().to_string(),
        topic: topic.to_string(),
        present: if present.is_empty() {
            "none".into()
        } else {
            present.join(", ")
        },
    }
}

fn decode_err(bag: &Bag, m: &RawMessage, index: u64, msg: String) -> RosbagError {
    RosbagError::Decode {
        file: bag.name().to_string(),
        topic: m.topic.to_string(),
        index,
        expected: m.msg_type.to_string(),
        msg,
    }
}

/// The servo samples one message gives.
fn servo_samples(
    m: &RawMessage,
    source: &ServoSource,
    out: &mut Vec<(i64, f64)>,
) -> std::result::Result<bool, String> {
    match source {
        ServoSource::Joint(name) => {
            let js = JointState::decode(m.data, m.encoding)?;
            let Some(k) = js.name.iter().position(|n| n == name) else {
                return Ok(false);
            };
            let p = js
                .position
                .get(k)
                .ok_or_else(|| format!("joint {name} has no position"))?;
            out.push((js.stamp_ns, joint_deg(*p)));
        }
        ServoSource::Numeric { scale, offset } => {
            let v = msgs::decode_numeric(m.msg_type, m.data, m.encoding)?;
            out.push((m.time_ns, v * scale + offset));
        }
        ServoSource::Tf { child, axis } => {
            for t in msgs::decode_tf(m.data, m.encoding)? {
                if t.child_frame_id == *child {
                    out.push((t.stamp_ns, msgs::twist_deg(t.rotation, *axis)));
                }
            }
        }
    }
    Ok(true)
}

fn servo_types(source: &ServoSource) -> Vec<&'static str> {
    match source {
        ServoSource::Joint(_) => vec![msgs::JOINT_STATE],
        ServoSource::Numeric { .. } => msgs::NUMERIC.to_vec(),
        ServoSource::Tf { .. } => vec![msgs::TF_MESSAGE],
    }
}

/// Reads the servo samples of all `bags` (first pass), sorted by time; a repeated time
/// keeps its last sample.
pub fn servo_series(bags: &[Bag], topics: &Topics) -> Result<ServoSeries> {
    let types = servo_types(&topics.source);
    let mut samples = Vec::new();
    let mut messages = 0u64;
    let mut matched = 0u64;
    for bag in bags {
        let mut index = 0u64;
        bag.for_each(&[topics.servo.as_str()], &mut |m| {
            expect_type(bag, m, &types)?;
            let hit = servo_samples(m, &topics.source, &mut samples)
                .map_err(|e| decode_err(bag, m, index, e))?;
            matched += u64::from(hit);
            index += 1;
            Ok(())
        })?;
        messages += index;
    }
    let files: Vec<&str> = bags.iter().map(Bag::name).collect();
    let files = files.join(", ");
    if messages == 0 {
        return Err(match bags {
            [one] => no_messages(one, &topics.servo),
            _ => RosbagError::topic(
                &files,
                &topics.servo,
                "no messages on the servo topic in any of the bags",
            ),
        });
    }
    if samples.is_empty() {
        let what = match &topics.source {
            ServoSource::Joint(j) => {
                format!("no joint named {j:?} in its {matched} JointState messages")
            }
            ServoSource::Tf { child, .. } => {
                format!("no transform to child frame {child:?} in its {messages} messages")
            }
            ServoSource::Numeric { .. } => "no servo samples".into(),
        };
        return Err(RosbagError::topic(
            &files,
            &topics.servo,
            format!("{what} ({messages} messages)"),
        ));
    }
    samples.sort_by_key(|s| s.0);
    let mut series = ServoSeries::default();
    for (t, d) in samples {
        if series.times_ns.last() == Some(&t) {
            *series.deg.last_mut().unwrap_or(&mut 0.0) = d;
        } else {
            series.times_ns.push(t);
            series.deg.push(d);
        }
    }
    Ok(series)
}

/// The shortest decimal with at most `max_decimals` decimals near `approx` that `same`
/// accepts, else `approx`.
fn shortest_decimal(approx: f64, max_decimals: i32, same: impl Fn(f64) -> bool) -> f64 {
    (0..=max_decimals)
        .map(|k| {
            let s = 10f64.powi(k);
            (approx * s).round() / s
        })
        .find(|&c| same(c))
        .unwrap_or(approx)
}

/// A range in metres (`float32`) as millimetres (module doc), 0 for no return.
pub fn range_mm(r: f32, range_min: f32, range_max: f32) -> f64 {
    if !r.is_finite() || r < range_min || r > range_max {
        return 0.0;
    }
    let mm = shortest_decimal(f64::from(r) * 1000.0, 3, |c| (c / 1000.0) as f32 == r);
    if mm < MIN_VALID_RANGE_MM {
        0.0
    } else {
        mm
    }
}

/// An angle in radians (`float32`) as degrees (module doc).
pub fn angle_deg(a: f32) -> f64 {
    shortest_decimal(f64::from(a).to_degrees(), 9, |c| c.to_radians() as f32 == a)
}

/// A joint position in radians (`float64`) as degrees: the shortest decimal (at most 9
/// decimals) whose radians are exactly `p` (the degrees a recorder or an encoder's steps
/// of 360/2ⁿ° gave), else the plain conversion.
pub fn joint_deg(p: f64) -> f64 {
    shortest_decimal(p.to_degrees(), 9, |c| c.to_radians() == p)
}

/// What [`assemble`] did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Assembled {
    /// Scans given to the caller.
    pub scans: u64,
    /// Scans skipped because they start before the first servo sample.
    pub before_servo: u64,
    /// Scans skipped because they end after the last servo sample.
    pub after_servo: u64,
    /// Scans whose beam geometry differs from the scan before them.
    pub geometry_changes: u64,
}

/// The beam geometry of a scan.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Geometry {
    n: usize,
    angle_min: f32,
    angle_increment: f32,
}

struct Pass<'a> {
    series: &'a ServoSeries,
    /// The geometry of the last scan read.
    geometry: Option<Geometry>,
    last_stamp: Option<i64>,
    done: Assembled,
}

impl Pass<'_> {
    fn check_geometry(&mut self, s: &LaserScan) -> std::result::Result<(), String> {
        let g = Geometry {
            n: s.ranges.len(),
            angle_min: s.angle_min,
            angle_increment: s.angle_increment,
        };
        if g.n == 0
            || !(g.angle_increment != 0.0)
            || !g.angle_min.is_finite()
            || !g.angle_increment.is_finite()
        {
            return Err(format!(
                "{} beams from {} rad in steps of {} rad: not a scan",
                g.n, g.angle_min, g.angle_increment
            ));
        }
        if self.geometry.is_some_and(|last| last != g) {
            self.done.geometry_changes += 1;
        }
        self.geometry = Some(g);
        Ok(())
    }

    /// The header of the last scan read (its beam geometry, in mm and degrees).
    fn header(&self) -> ScanHeader {
        let g = self.geometry.unwrap_or(Geometry {
            n: 0,
            angle_min: 0.0,
            angle_increment: 0.0,
        });
        ScanHeader {
            angle_min_deg: angle_deg(g.angle_min),
            angle_increment_deg: angle_deg(g.angle_increment),
            mm_per_unit: 1.0,
        }
    }

    /// The scan line of one message, or `None` when it is outside the servo samples.
    fn line(&mut self, s: &LaserScan, index: u64) -> std::result::Result<Option<ScanLine>, String> {
        self.check_geometry(s)?;
        if self.last_stamp.is_some_and(|t| s.stamp_ns < t) {
            return Err(
                "its stamp is earlier than the scan before it: scans must be in time order".into(),
            );
        }
        self.last_stamp = Some(s.stamp_ns);
        let ti = f64::from(s.time_increment);
        if !ti.is_finite() || ti < 0.0 {
            return Err(format!(
                "time_increment {ti} s: expected a finite value ≥ 0"
            ));
        }
        let end_off = (s.ranges.len() - 1) as f64 * ti * 1e9;
        let (Some(start), Some(end)) = (
            self.series.at(s.stamp_ns, 0.0),
            self.series.at(s.stamp_ns, end_off),
        ) else {
            if s.stamp_ns < self.series.times_ns[0] {
                self.done.before_servo += 1;
            } else {
                self.done.after_servo += 1;
            }
            return Ok(None);
        };
        Ok(Some(ScanLine {
            line: usize::try_from(index + 1).unwrap_or(usize::MAX),
            stamp_s: s.stamp_ns as f64 * 1e-9,
            servo_deg: start,
            servo_end_deg: Some(end),
            ranges_mm: s
                .ranges
                .iter()
                .map(|&r| range_mm(r, s.range_min, s.range_max))
                .collect(),
        }))
    }
}

/// Reads the scans of all `bags` in order (second pass) and gives each one, with its own
/// beam geometry, to `f`.
pub fn assemble(
    bags: &[Bag],
    topics: &Topics,
    series: &ServoSeries,
    f: &mut dyn FnMut(&ScanHeader, ScanLine) -> Result<()>,
) -> Result<Assembled> {
    let mut pass = Pass {
        series,
        geometry: None,
        last_stamp: None,
        done: Assembled::default(),
    };
    for bag in bags {
        let mut index = 0u64;
        bag.for_each(&[topics.scan.as_str()], &mut |m| {
            expect_type(bag, m, &[msgs::LASER_SCAN])?;
            let scan =
                LaserScan::decode(m.data, m.encoding).map_err(|e| decode_err(bag, m, index, e))?;
            let line = pass.line(&scan, index).map_err(|e| {
                RosbagError::topic(bag.name(), m.topic, format!("message {index}: {e}"))
            })?;
            index += 1;
            let Some(line) = line else { return Ok(()) };
            let header = pass.header();
            pass.done.scans += 1;
            f(&header, line)
        })?;
        if index == 0 && bags.len() == 1 {
            return Err(no_messages(bag, &topics.scan));
        }
    }
    if pass.geometry.is_none() {
        let files: Vec<&str> = bags.iter().map(Bag::name).collect();
        return Err(RosbagError::topic(
            &files.join(", "),
            &topics.scan,
            "no LaserScan messages in any of the bags",
        ));
    }
    Ok(pass.done)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_come_back_as_the_decimal_millimetres_they_were() {
        for mm in [1532.0, 20.0, 5600.0, 1234.5, 999.999] {
            let r = (mm / 1000.0) as f32;
            assert_eq!(range_mm(r, 0.02, 30.0), mm);
        }
        assert_eq!(range_mm(f32::INFINITY, 0.02, 30.0), 0.0);
        assert_eq!(range_mm(f32::NAN, 0.02, 30.0), 0.0);
        assert_eq!(range_mm(0.01, 0.02, 30.0), 0.0);
        assert_eq!(range_mm(31.0, 0.02, 30.0), 0.0);
        assert_eq!(angle_deg((-119.53125f64).to_radians() as f32), -119.53125);
        assert_eq!(angle_deg(0.3515625f64.to_radians() as f32), 0.3515625);
        for deg in [-179.824219, 45.0, 0.087890625 * 37.0, -0.000001] {
            assert_eq!(joint_deg(f64::to_radians(deg)), deg);
        }
    }

    #[test]
    fn the_servo_is_interpolated_between_samples_and_none_outside() {
        let s = ServoSeries {
            times_ns: vec![1_000, 2_000, 4_000],
            deg: vec![10.0, 20.0, 0.0],
        };
        assert_eq!(s.at(1_000, 0.0), Some(10.0));
        assert_eq!(s.at(1_000, 500.0), Some(15.0));
        assert!((s.at(2_000, 1_000.5).unwrap() - (20.0 - 20.0 * 1_000.5 / 2_000.0)).abs() < 1e-12);
        assert_eq!(s.at(4_000, 0.0), Some(0.0));
        assert_eq!(s.at(999, 0.0), None);
        assert_eq!(s.at(4_000, 0.5), None);
    }

    fn scan(stamp_ns: i64, n: usize, angle_min: f32) -> LaserScan {
        LaserScan {
            stamp_ns,
            frame_id: "laser".into(),
            angle_min,
            angle_max: 1.0,
            angle_increment: 0.01,
            time_increment: 0.001,
            scan_time: 0.1,
            range_min: 0.02,
            range_max: 30.0,
            ranges: vec![1.5; n],
            intensities: vec![],
        }
    }

    fn pass(series: &ServoSeries) -> Pass<'_> {
        Pass {
            series,
            geometry: None,
            last_stamp: None,
            done: Assembled::default(),
        }
    }

    #[test]
    fn each_beam_time_is_stamp_plus_index_times_increment() {
        // the servo turns 1°/ms from t = 0; beams 1 ms apart
        let s = ServoSeries {
            times_ns: vec![0, 1_000_000_000],
            deg: vec![0.0, 1000.0],
        };
        let mut p = pass(&s);
        let l = p.line(&scan(10_000_000, 11, -1.0), 0).unwrap().unwrap();
        assert!((l.servo_deg - 10.0).abs() < 1e-9, "{}", l.servo_deg);
        assert!(
            (l.servo_end_deg.unwrap() - 20.0).abs() < 1e-6,
            "{:?}",
            l.servo_end_deg
        );
        assert_eq!((l.line, l.stamp_s), (1, 0.01));
    }

    #[test]
    fn scans_outside_the_servo_samples_are_counted_and_out_of_order_refused() {
        let s = ServoSeries {
            times_ns: vec![1_000_000_000, 2_000_000_000],
            deg: vec![0.0, 10.0],
        };
        let mut p = pass(&s);
        assert_eq!(p.line(&scan(0, 10, -1.0), 0), Ok(None));
        assert!(p.line(&scan(1_500_000_000, 10, -1.0), 1).unwrap().is_some());
        // its last beam, 9 ms after the stamp, is after the last sample
        assert_eq!(p.line(&scan(1_995_000_000, 10, -1.0), 2), Ok(None));
        assert_eq!((p.done.before_servo, p.done.after_servo), (1, 1));
        let e = p.line(&scan(1_000_000_000, 10, -1.0), 4).unwrap_err();
        assert!(e.contains("scans must be in time order"), "{e}");
    }

    #[test]
    fn each_scan_keeps_its_own_beam_geometry_and_the_changes_are_counted() {
        let s = ServoSeries {
            times_ns: vec![0, 10_000_000_000],
            deg: vec![0.0, 10.0],
        };
        let mut p = pass(&s);
        assert!(p.line(&scan(1_000_000_000, 10, -1.0), 0).unwrap().is_some());
        // a beam more, then another first angle, then back
        let l = p.line(&scan(2_000_000_000, 11, -1.0), 1).unwrap().unwrap();
        assert_eq!(l.ranges_mm.len(), 11);
        assert!(p.line(&scan(3_000_000_000, 10, -0.5), 2).unwrap().is_some());
        assert_eq!(p.header().angle_min_deg, angle_deg(-0.5));
        assert!(p.line(&scan(4_000_000_000, 10, -1.0), 3).unwrap().is_some());
        assert_eq!(p.header().angle_min_deg, angle_deg(-1.0));
        assert_eq!(p.done.geometry_changes, 3);
        let e = p.line(&scan(5_000_000_000, 0, -1.0), 4).unwrap_err();
        assert!(e.contains("not a scan"), "{e}");
    }
}
