//! From a bag's `LaserScan` and servo messages to pingcal scans
//! ([`pingcal_lrf::scan::ScanLine`]), as drivers publish them, in one pass over the bags.
//!
//! **The servo angle** of a scan depends on how the servo moves ([`ServoMotion`],
//! [`crate::motion`]): a stop-and-go servo's last angle before the scan is held for the
//! whole scan; a continuous sweep's angle is interpolated at the time of the scan's first
//! and last beam (its stamp + k · `time_increment`), the beams between linear in their index
//! (the `pingcal-scan` v2 columns `servo_deg`, `servo_end_deg`). `auto` tells them apart
//! from the servo series and says which it used ([`Assembled::motion`]). Scans before the
//! first servo message, or (continuous) whose last beam is after the last one, or
//! (stop-and-go) more than one servo interval after the last one, are skipped and counted.
//!
//! **What drivers publish** and how it is met, every case counted in [`Assembled`]:
//! empty scans (no beams) are skipped; ranges that are 0, NaN, ±inf, outside
//! `[range_min, range_max]` or under 20 mm are no return (0, as in the CSV), counted by
//! reason ([`Masked`]); a message stored twice (the same bytes on the scan topic; the same
//! time and angle on the servo topic) is read once; a scan whose stamp repeats the scan
//! before it is kept, one whose stamp goes back is dropped (a scan file is in time order);
//! intensities are kept when there is one per beam; the beam geometry may change between
//! scans (each scan comes with its own [`ScanHeader`]: a `pingcal-scan` v4 file holds them
//! all). Several bags are read in the order given.
//!
//! **Time base.** Each topic's time is its header stamp or its record time, as
//! [`Topics::stamps`] says (`auto`: [`crate::clock`], which tells two clocks apart).
//! **Values no scan file holds** (a scan's beams beyond a turn, a servo value NaN or beyond
//! ±1e6°) are skipped, counted and the first named ([`Assembled::bad_geometry`],
//! [`Assembled::bad_servo`]): what is written, the readers read. **Beam timing** follows the
//! drivers' `time_increment` / `scan_time` conventions ([`BeamTimings`]).
//!
//! **One pass.** The scan and servo topics are read together; a scan waits until the servo
//! series is known past its last beam (by [`crate::motion::SLACK_NS`]: the messages of a
//! bag are in time order to within that), and `auto` waits for the servo's first 16 moves.
//! Should more than [`MAX_PENDING_SCANS`] scans wait (a servo topic that falls silent for
//! long), the bags are read again in two passes, the servo series first: memory stays
//! bounded whatever the data.
//!
//! Units: metres become millimetres and radians degrees. The message stores `float32`
//! values, so the millimetres (and the beam geometry's degrees) are the shortest decimal
//! that rounds to the stored `float32` (whole mm for a sensor that measures in mm, as the
//! recorder's metres were), else the exact `float32` value; a JointState's radians
//! likewise become the shortest decimal degrees that convert back to them exactly.
//!
//! A scan's `line` is its 1-based message number on the scan topic (in its bag).

use crate::error::{Result, RosbagError};
pub use crate::motion::{ServoMotion, ServoSeries};

mod stream;
use crate::msgs::{self, JointState};
use crate::{Bag, RawMessage};
use pingcal_lrf::scan::{ScanHeader, ScanLine, MIN_VALID_RANGE_MM};

pub use pingcal_lrf::settings::{ServoSource, Stamps};

/// The topics to read and how.
#[derive(Debug, Clone, PartialEq)]
pub struct Topics {
    /// The `sensor_msgs/LaserScan` topic.
    pub scan: String,
    /// The servo topic.
    pub servo: String,
    /// How the servo topic's messages give the angle.
    pub source: ServoSource,
    /// Whose time the messages are taken at ([`crate::clock`]).
    pub stamps: Stamps,
}

pub(crate) fn expect_type(bag: &Bag, m: &RawMessage, expected: &[&str]) -> Result<()> {
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
pub(crate) fn no_messages(bag: &Bag, topic: &str) -> RosbagError {
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

pub(crate) fn decode_err(bag: &Bag, m: &RawMessage, index: u64, msg: String) -> RosbagError {
    RosbagError::Decode {
        file: bag.name().to_string(),
        topic: m.topic.to_string(),
        index,
        expected: m.msg_type.to_string(),
        msg,
    }
}

/// What the servo topic's messages held besides the servo: the joint names of its
/// JointState messages, the child frames of its tf messages (for the error that lists them).
#[derive(Debug, Default)]
pub(crate) struct ServoNames {
    /// Names seen, in order, at most [`ServoNames::MAX`].
    pub names: std::collections::BTreeSet<String>,
}

impl ServoNames {
    const MAX: usize = 64;

    fn add(&mut self, name: &str) {
        if self.names.len() < Self::MAX && !self.names.contains(name) {
            self.names.insert(name.to_string());
        }
    }
}

/// The servo samples one message gives (time ns: its header stamp, or its record time
/// when `record`; degrees), the names it held in `names`; false when the message has no
/// sample of the servo asked for.
pub(crate) fn servo_samples(
    m: &RawMessage,
    source: &ServoSource,
    record: bool,
    out: &mut Vec<(i64, f64)>,
    names: &mut ServoNames,
) -> std::result::Result<bool, String> {
    let at = |stamp_ns: i64| if record { m.time_ns } else { stamp_ns };
    match source {
        ServoSource::Joint(name) => {
            let js = JointState::decode(m.data, m.encoding)?;
            js.name.iter().for_each(|n| names.add(n));
            let Some(k) = js.name.iter().position(|n| n == name) else {
                return Ok(false);
            };
            let p = js
                .position
                .get(k)
                .ok_or_else(|| format!("joint {name} has no position"))?;
            out.push((at(js.stamp_ns), joint_deg(*p)));
        }
        ServoSource::Numeric { scale, offset } => {
            let v = msgs::decode_numeric(m.msg_type, m.data, m.encoding)?;
            out.push((m.time_ns, v * scale + offset));
        }
        ServoSource::Tf { child, axis } => {
            let mut hit = false;
            for t in msgs::decode_tf(m.data, m.encoding)? {
                names.add(&t.child_frame_id);
                if t.child_frame_id == *child {
                    out.push((at(t.stamp_ns), msgs::twist_deg(t.rotation, *axis)));
                    hit = true;
                }
            }
            return Ok(hit);
        }
    }
    Ok(true)
}

pub(crate) fn servo_types(source: &ServoSource) -> Vec<&'static str> {
    match source {
        ServoSource::Joint(_) => vec![msgs::JOINT_STATE],
        ServoSource::Numeric { .. } => msgs::NUMERIC.to_vec(),
        ServoSource::Tf { .. } => vec![msgs::TF_MESSAGE],
    }
}

/// The error for a servo topic that gave no sample: absent or empty (`messages` 0), or
/// without the joint / child frame asked for, listing those there are.
pub(crate) fn no_servo_samples(
    bags: &[Bag],
    topics: &Topics,
    messages: u64,
    names: &ServoNames,
) -> RosbagError {
    let files: Vec<&str> = bags.iter().map(Bag::name).collect();
    let files = files.join(", ");
    if messages == 0 {
        return match bags {
            [one] => no_messages(one, &topics.servo),
            _ => RosbagError::topic(
                &files,
                &topics.servo,
                "no messages on the servo topic in any of the bags",
            ),
        };
    }
    let there: Vec<String> = names.names.iter().map(|n| format!("{n:?}")).collect();
    let there = if there.is_empty() {
        "none".to_string()
    } else {
        there.join(", ")
    };
    let what = match &topics.source {
        ServoSource::Joint(j) => {
            format!("no joint named {j:?} in its {messages} JointState messages (joints there: {there})")
        }
        ServoSource::Tf { child, .. } => format!(
            "no transform to child frame {child:?} in its {messages} messages (child frames there: {there})"
        ),
        ServoSource::Numeric { .. } => format!("no servo samples in its {messages} messages"),
    };
    RosbagError::topic(&files, &topics.servo, what)
}

/// Reads the servo samples of all `bags` (a pass of its own), sorted by time, at the time
/// base `topics.stamps` gives ([`crate::clock::choose`]); a repeated time keeps its last
/// sample; a value that is not a servo angle (not a number, beyond ±1e6°) is skipped.
pub fn servo_series(bags: &[Bag], topics: &Topics) -> Result<ServoSeries> {
    let record = crate::clock::choose(
        bags,
        &topics.scan,
        &topics.servo,
        &topics.source,
        topics.stamps,
    )?
    .record;
    let types = servo_types(&topics.source);
    let mut samples = Vec::new();
    let mut names = ServoNames::default();
    let mut messages = 0u64;
    for bag in bags {
        let mut index = 0u64;
        bag.for_each(&[topics.servo.as_str()], &mut |m| {
            expect_type(bag, m, &types)?;
            servo_samples(m, &topics.source, record, &mut samples, &mut names)
                .map_err(|e| decode_err(bag, m, index, e))?;
            samples.retain(|&(_, d)| servo_value_ok(d));
            index += 1;
            Ok(())
        })?;
        messages += index;
    }
    if samples.is_empty() {
        return Err(no_servo_samples(bags, topics, messages, &names));
    }
    let mut series = ServoSeries::default();
    for (t, d) in samples {
        series.insert(t, d);
    }
    Ok(series)
}

/// A servo angle a scan file can hold: a number within ±[`MAX_SERVO_DEG`].
pub fn servo_value_ok(deg: f64) -> bool {
    deg.abs() <= MAX_SERVO_DEG
}

pub use pingcal_lrf::scan::MAX_SERVO_DEG;

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

/// Ranges read as no return, by reason.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Masked {
    /// 0 (many drivers' "no return").
    pub zero: u64,
    /// NaN.
    pub nan: u64,
    /// +inf or −inf.
    pub inf: u64,
    /// Under the message's `range_min` (and not 0).
    pub below_min: u64,
    /// Over the message's `range_max` (and finite).
    pub above_max: u64,
    /// Within `[range_min, range_max]` but under 20 mm (the URG error codes).
    pub under_20mm: u64,
}

impl Masked {
    /// All of them.
    pub fn total(&self) -> u64 {
        self.zero + self.nan + self.inf + self.below_min + self.above_max + self.under_20mm
    }
}

/// A range in metres (`float32`) as millimetres (module doc), 0 for no return.
pub fn range_mm(r: f32, range_min: f32, range_max: f32) -> f64 {
    range_mm_counted(r, range_min, range_max, &mut Masked::default())
}

/// [`range_mm`], counting a no return in `masked` by its reason.
pub fn range_mm_counted(r: f32, range_min: f32, range_max: f32, masked: &mut Masked) -> f64 {
    let reason = if r.is_nan() {
        &mut masked.nan
    } else if r.is_infinite() {
        &mut masked.inf
    } else if r == 0.0 {
        &mut masked.zero
    } else if r < range_min {
        &mut masked.below_min
    } else if r > range_max {
        &mut masked.above_max
    } else {
        let mm = shortest_decimal(f64::from(r) * 1000.0, 3, |c| (c / 1000.0) as f32 == r);
        if mm >= MIN_VALID_RANGE_MM {
            return mm;
        }
        &mut masked.under_20mm
    };
    *reason += 1;
    0.0
}

/// An angle in radians (`float32`) as degrees (module doc).
pub fn angle_deg(a: f32) -> f64 {
    shortest_decimal(f64::from(a).to_degrees(), 9, |c| c.to_radians() as f32 == a)
}

/// A time in seconds (`float32`, e.g. `time_increment`) as the shortest decimal that
/// rounds to it.
pub fn seconds(s: f32) -> f64 {
    shortest_decimal(f64::from(s), 12, |c| c as f32 == s)
}

/// A joint position in radians (`float64`) as degrees: the shortest decimal (at most 9
/// decimals) whose radians are exactly `p` (the degrees a recorder or an encoder's steps
/// of 360/2ⁿ° gave), else the plain conversion.
pub fn joint_deg(p: f64) -> f64 {
    shortest_decimal(p.to_degrees(), 9, |c| c.to_radians() == p)
}

/// Messages skipped for a value a scan file cannot hold: how many, and the first (its
/// message number and the value).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Skipped {
    /// Messages skipped.
    pub count: u64,
    /// "message K: VALUE" of the first.
    pub first: Option<String>,
}

impl Skipped {
    /// Counts message `index`, naming it and its value (`what`) when it is the first.
    pub fn add(&mut self, index: u64, what: impl FnOnce() -> String) {
        self.count += 1;
        if self.first.is_none() {
            self.first = Some(format!("message {index}: {}", what()));
        }
    }
}

/// How the scans' beams were timed where the driver's `time_increment` is not the plain
/// time between beams: scans counted by convention.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct BeamTimings {
    /// `time_increment` 0: the time between beams from `scan_time` (a turn per scan).
    pub from_scan_time: u64,
    /// `time_increment` negative: the beams measured from the last to the first.
    pub reversed: u64,
    /// `time_increment` the whole scan's time (longer than a scan per beam): divided by the
    /// beams.
    pub per_scan: u64,
    /// `time_increment` not a number, or longer than a scan either way: not used.
    pub ignored: u64,
}

/// What [`read_scans`] did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Assembled {
    /// The time base used ([`crate::clock`]), and why.
    pub clock: crate::clock::Clock,
    /// Scans skipped because their beams are no scan (an angle or a step beyond a turn).
    pub bad_geometry: Skipped,
    /// Servo values skipped: not a number, or beyond ±1e6°.
    pub bad_servo: Skipped,
    /// Scans whose beams were timed by a convention of their driver.
    pub timing: BeamTimings,
    /// Scans given to the caller.
    pub scans: u64,
    /// Scans skipped because they start before the first servo sample.
    pub before_servo: u64,
    /// Scans skipped because they end after the last servo sample (module doc).
    pub after_servo: u64,
    /// Scans whose beam geometry differs from the scan before them.
    pub geometry_changes: u64,
    /// Scans with no beams, skipped.
    pub empty_scans: u64,
    /// Ranges read as no return, by reason.
    pub masked: Masked,
    /// Scan messages that repeat an earlier one byte for byte, read once.
    pub duplicate_scans: u64,
    /// Servo samples that repeat an earlier one's time and angle, read once.
    pub duplicate_servo: u64,
    /// Scans whose stamp equals the scan before them (kept).
    pub repeated_stamps: u64,
    /// Scans whose stamp is earlier than the scan before them (dropped).
    pub backward_stamps: u64,
    /// Scans that carried one intensity per beam (kept).
    pub with_intensities: u64,
    /// How the servo was taken to move (stop-and-go or continuous).
    pub motion: ServoMotion,
    /// Why (`auto`), or "as asked".
    pub motion_reason: String,
    /// Passes over the bags (1, or 2 when the servo fell silent for long: module doc).
    pub passes: u32,
}

impl Assembled {
    /// What was met and done, one line each, in words (warnings start with `warning: `):
    /// the servo motion and why, and every count that is not 0.
    pub fn notes(&self) -> Vec<String> {
        let mut out = vec![
            format!("time base: {} ({})", self.clock.name(), self.clock.reason),
            format!(
                "servo motion: {} ({})",
                self.motion.name(),
                self.motion_reason
            ),
        ];
        let t = &self.timing;
        for (n, what) in [
            (t.from_scan_time, "time_increment 0: the time between beams from scan_time (a turn per scan)"),
            (t.reversed, "time_increment negative: the beams measured from the last to the first"),
            (t.per_scan, "time_increment longer than a scan per beam: taken as the whole scan's time, divided by the beams"),
        ] {
            if n > 0 {
                out.push(format!("{n} scan(s) with {what}"));
            }
        }
        for (s, what) in [
            (&self.bad_geometry, "scan(s) whose beams a scan file cannot hold (an angle or a step beyond a turn) skipped"),
            (&self.bad_servo, "servo value(s) not a number or beyond ±1e6° skipped"),
        ] {
            if let Some(first) = &s.first {
                out.push(format!("warning: {} {what} (the first: {first})", s.count));
            }
        }
        if t.ignored > 0 {
            out.push(format!(
                "warning: {} scan(s) with a time_increment that is not a number or longer than a scan: their beams are taken at the scan's stamp",
                t.ignored
            ));
        }
        let m = &self.masked;
        if m.total() > 0 {
            let parts: Vec<String> = [
                (m.zero, "0"),
                (m.nan, "NaN"),
                (m.inf, "±inf"),
                (m.below_min, "under range_min"),
                (m.above_max, "over range_max"),
                (m.under_20mm, "under 20 mm"),
            ]
            .iter()
            .filter(|(n, _)| *n > 0)
            .map(|(n, what)| format!("{n} {what}"))
            .collect();
            out.push(format!(
                "{} range(s) read as no return: {}",
                m.total(),
                parts.join(", ")
            ));
        }
        if self.with_intensities > 0 {
            out.push(format!(
                "intensities kept for {} scan(s)",
                self.with_intensities
            ));
        }
        if self.geometry_changes > 0 {
            out.push(format!(
                "the beam geometry changes {} time(s) between scans; each scan is read with its own",
                self.geometry_changes
            ));
        }
        let warnings = [
            (self.empty_scans, "empty scan(s) (no beams) skipped".to_string()),
            (
                self.duplicate_scans,
                "scan message(s) stored twice read once".into(),
            ),
            (
                self.duplicate_servo,
                "servo message(s) stored twice read once".into(),
            ),
            (
                self.repeated_stamps,
                "scan(s) with the stamp of the scan before them (kept)".into(),
            ),
            (
                self.backward_stamps,
                "scan(s) stamped earlier than the scan before them dropped (a scan file is in time order)".into(),
            ),
            (
                self.before_servo,
                "scan(s) before the first servo message skipped (no servo angle)".into(),
            ),
            (
                self.after_servo,
                "scan(s) after the last servo message skipped (no servo angle)".into(),
            ),
        ];
        for (n, what) in warnings {
            if n > 0 {
                out.push(format!("warning: {n} {what}"));
            }
        }
        if self.passes > 1 {
            out.push(format!(
                "read in two passes: more than {MAX_PENDING_SCANS} scans waited for the servo"
            ));
        }
        out
    }
}

/// Scans that may wait for the servo series in the one-pass read (module doc).
pub const MAX_PENDING_SCANS: usize = 4_096;

/// Reads the scans of all `bags` in order and gives each one, with its own beam geometry,
/// to `f`; `motion` says how the servo moves ([`ServoMotion::Auto`]: told from the data).
pub fn read_scans(
    bags: &[Bag],
    topics: &Topics,
    motion: ServoMotion,
    f: &mut dyn FnMut(&ScanHeader, ScanLine) -> Result<()>,
) -> Result<Assembled> {
    stream::read(bags, topics, motion, f)
}

/// Reads the scans of a fixed LRF (no servo) on the topic `scan` of all `bags` in order and
/// gives each one, with its own beam geometry and at servo 0, to `f`: what a fixed LRF's
/// scan file holds (`pingcal scans --fixed`).
pub fn read_fixed_scans(
    bags: &[Bag],
    scan: &str,
    stamps: Stamps,
    f: &mut dyn FnMut(&ScanHeader, ScanLine) -> Result<()>,
) -> Result<Assembled> {
    stream::read_fixed(bags, scan, stamps, f)
}

/// The names the messages of a servo-like topic hold (at most its first 1,000 messages
/// are read): a JointState topic's joint names, a tf topic's frames as `parent→child`;
/// empty for other types.
pub fn names_on_topic(bag: &Bag, topic: &str, msg_type: &str) -> Result<Vec<String>> {
    const MAX_MESSAGES: u64 = 1_000;
    if msg_type != msgs::JOINT_STATE && msg_type != msgs::TF_MESSAGE {
        return Ok(Vec::new());
    }
    let mut names = std::collections::BTreeSet::new();
    let mut index = 0u64;
    let read = bag.for_each(&[topic], &mut |m| {
        if m.msg_type == msgs::JOINT_STATE {
            let js =
                JointState::decode(m.data, m.encoding).map_err(|e| decode_err(bag, m, index, e))?;
            names.extend(js.name);
        } else if m.msg_type == msgs::TF_MESSAGE {
            let tf =
                msgs::decode_tf(m.data, m.encoding).map_err(|e| decode_err(bag, m, index, e))?;
            names.extend(
                tf.into_iter()
                    .map(|t| format!("{}→{}", t.frame_id, t.child_frame_id)),
            );
        }
        index += 1;
        if index >= MAX_MESSAGES {
            return Err(RosbagError::Stopped);
        }
        Ok(())
    });
    match read {
        Ok(()) | Err(RosbagError::Stopped) => Ok(names.into_iter().collect()),
        Err(e) => Err(e),
    }
}
