//! The one-pass reading of [`crate::assemble::read_scans`]: scans wait in a queue until the
//! servo series is known past them, then get their servo angle and go to the caller.

use super::{
    angle_deg, decode_err, expect_type, no_messages, no_servo_samples, range_mm_counted, seconds,
    servo_samples, servo_types, servo_value_ok, Assembled, ServoNames, Topics, MAX_PENDING_SCANS,
};
use crate::error::{Result, RosbagError};
use crate::motion::{classify, Decision, Inserted, ServoMotion, ServoSeries, SLACK_NS};
use crate::msgs::{self, LaserScan};
use crate::{Bag, RawMessage};
use pingcal_lrf::scan::{ScanHeader, ScanLine};
use std::collections::{HashSet, VecDeque};

/// Scan messages a copy is looked for among (a message stored twice is stored next to
/// itself, or nearly: a bag read twice is told by its stamps going back instead).
const DUPLICATE_WINDOW: usize = 4_096;

/// The beam geometry of a scan, as the message gives it, and the time between its beams
/// as the driver's conventions give it ([`beam_time_s`]).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Geometry {
    n: usize,
    angle_min: f32,
    angle_increment: f32,
    /// Seconds from one beam to the next (negative: the beams measured last to first), 0
    /// when unknown: the message's `float32` exactly, where it is used as given.
    beam_s: f64,
    /// The message's `time_increment`, when `beam_s` is it.
    given: Option<f32>,
}

impl Geometry {
    fn header(&self) -> ScanHeader {
        // the float32 as its shortest decimal (module doc of `assemble`)
        let decimal = match self.given {
            Some(ti) => seconds(ti.abs()).copysign(f64::from(ti)),
            None => self.beam_s,
        };
        ScanHeader {
            angle_min_deg: angle_deg(self.angle_min),
            angle_increment_deg: angle_deg(self.angle_increment),
            mm_per_unit: 1.0,
            time_increment_s: (self.beam_s != 0.0).then_some(decimal),
        }
    }
}

/// How the time between beams was found, for the counts of [`Assembled`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum BeamTiming {
    /// `time_increment` as the message gives it (or 0 with no `scan_time` either).
    AsGiven,
    /// `time_increment` 0: from `scan_time` and the beam step (a turn per `scan_time`).
    FromScanTime,
    /// `time_increment` negative: the beams measured from the last to the first.
    Reversed,
    /// `time_increment` the whole scan's time: divided by the beams.
    PerScan,
    /// `time_increment` not a number, or longer than a scan whichever way it is read:
    /// ignored.
    Ignored,
}

/// The time from one beam to the next (s) as the drivers' conventions give it, and how:
/// `time_increment` per beam; 0 with a `scan_time`: the beams' share of a turn per
/// `scan_time`; negative: the beams were measured from the last to the first; so long that
/// the beams would outlast the scan period (`scan_time`, else `period_s`, the time since
/// the scan before) by half: the whole scan's time, divided by the beams.
fn beam_time_s(s: &LaserScan, period_s: Option<f64>) -> (f64, BeamTiming) {
    let ti = f64::from(s.time_increment);
    let st = f64::from(s.scan_time);
    let n = s.ranges.len();
    let period = if st.is_finite() && st > 0.0 {
        Some(st)
    } else {
        period_s.filter(|p| *p > 0.0)
    };
    let fits = |b: f64| period.is_none_or(|p| b.abs() * n.saturating_sub(1) as f64 <= 1.5 * p);
    if !ti.is_finite() {
        return (0.0, BeamTiming::Ignored);
    }
    if ti == 0.0 {
        return match period {
            Some(p) if st > 0.0 => {
                let share = f64::from(s.angle_increment).abs() / std::f64::consts::TAU;
                (p * share, BeamTiming::FromScanTime)
            }
            _ => (0.0, BeamTiming::AsGiven),
        };
    }
    let given = ti;
    if fits(given) {
        let how = if ti < 0.0 {
            BeamTiming::Reversed
        } else {
            BeamTiming::AsGiven
        };
        return (given, how);
    }
    let per_beam = given / n.max(1) as f64;
    if fits(per_beam) {
        return (per_beam, BeamTiming::PerScan);
    }
    (0.0, BeamTiming::Ignored)
}

/// A scan waiting for its servo angle.
struct Pending {
    stamp_ns: i64,
    /// Time of its last beam after its first, ns.
    end_off_ns: f64,
    header: ScanHeader,
    line: ScanLine,
}

/// A `float32` as its shortest decimal, in e-notation when huge or tiny.
fn short32(v: f32) -> String {
    pingcal_lrf::scan::short(format!("{v}").parse().unwrap_or(f64::NAN))
}

/// A 128-bit hash of a message's bytes (two multiplicative lanes over 8-byte words): the
/// identity of a message for telling exact duplicates, at memory speed.
fn identity(data: &[u8]) -> u128 {
    const K1: u64 = 0x9E37_79B9_7F4A_7C15;
    const K2: u64 = 0xC2B2_AE3D_27D4_EB4F;
    let (mut a, mut b) = (data.len() as u64, !(data.len() as u64));
    let mut words = data.chunks_exact(8);
    for w in &mut words {
        let w = u64::from_le_bytes([w[0], w[1], w[2], w[3], w[4], w[5], w[6], w[7]]);
        a = (a ^ w).wrapping_mul(K1).rotate_left(29);
        b = (b ^ w.rotate_left(17)).wrapping_mul(K2).rotate_left(31);
    }
    let mut tail = [0u8; 8];
    tail[..words.remainder().len()].copy_from_slice(words.remainder());
    let w = u64::from_le_bytes(tail);
    a = (a ^ w).wrapping_mul(K1);
    b = (b ^ w).wrapping_mul(K2);
    let fmix = |mut x: u64| {
        x ^= x >> 33;
        x = x.wrapping_mul(0xff51_afd7_ed55_8ccd);
        x ^= x >> 33;
        x
    };
    (u128::from(fmix(a ^ b.rotate_left(7))) << 64) | u128::from(fmix(b ^ a))
}

struct Stream<'a> {
    topics: &'a Topics,
    /// Every topic at its record times ([`crate::clock`]), else at its header stamps.
    record: bool,
    series: ServoSeries,
    /// The servo series is complete (read in a pass of its own).
    servo_complete: bool,
    servo_until: i64,
    scan_until: i64,
    decision: Option<Decision>,
    /// Scan stamps kept for [`classify`] until it has decided.
    scan_stamps: Vec<i64>,
    pending: VecDeque<Pending>,
    geometry: Option<Geometry>,
    last_stamp: Option<i64>,
    /// The identities of the last [`DUPLICATE_WINDOW`] scan messages, and their order.
    seen: HashSet<u128>,
    seen_order: VecDeque<u128>,
    servo_messages: u64,
    names: ServoNames,
    samples: Vec<(i64, f64)>,
    /// Scans already given to the caller in an earlier pass, not to be given again.
    skip: u64,
    done: Assembled,
    /// The one-pass read gave up (too many scans waiting).
    overflow: bool,
    /// Scans that may wait ([`MAX_PENDING_SCANS`]).
    cap: usize,
    /// The first of two passes: the servo series and the scans' stamps only.
    stamps_only: bool,
    /// A fixed LRF: no servo; every scan is given as read, at servo 0.
    fixed: bool,
    /// How long after the last servo message a stop-and-go scan still holds its angle, ns
    /// (the median servo interval, once the series is complete).
    hold_limit: Option<i64>,
    /// The series' length at which [`classify`] is tried again.
    next_classify: usize,
}

impl<'a> Stream<'a> {
    fn new(topics: &'a Topics, asked: ServoMotion, record: bool) -> Self {
        Stream {
            topics,
            record,
            series: ServoSeries::default(),
            servo_complete: false,
            servo_until: i64::MIN,
            scan_until: i64::MIN,
            decision: match asked {
                ServoMotion::Auto => None,
                m => Some(Decision {
                    motion: m,
                    reason: "as asked".into(),
                }),
            },
            scan_stamps: Vec::new(),
            pending: VecDeque::new(),
            geometry: None,
            last_stamp: None,
            seen: HashSet::new(),
            seen_order: VecDeque::new(),
            servo_messages: 0,
            names: ServoNames::default(),
            samples: Vec::new(),
            skip: 0,
            done: Assembled::default(),
            overflow: false,
            cap: MAX_PENDING_SCANS,
            stamps_only: false,
            fixed: false,
            hold_limit: None,
            next_classify: 2,
        }
    }

    fn servo(&mut self, bag: &Bag, m: &RawMessage, index: u64) -> Result<()> {
        expect_type(bag, m, &servo_types(&self.topics.source))?;
        self.servo_messages += 1;
        self.samples.clear();
        let record = self.record;
        servo_samples(
            m,
            &self.topics.source,
            record,
            &mut self.samples,
            &mut self.names,
        )
        .map_err(|e| decode_err(bag, m, index, e))?;
        for &(t, d) in &self.samples {
            if !servo_value_ok(d) {
                // a scan file holds no such angle: skipped, counted, the first named
                self.done.bad_servo.add(index, || format!("{d:e}"));
                continue;
            }
            if self.series.insert(t, d) == Inserted::Duplicate {
                self.done.duplicate_servo += 1;
            }
            self.servo_until = self.servo_until.max(t);
        }
        Ok(())
    }

    /// Checks a scan's geometry; `None` for an empty scan or one whose beams a scan file
    /// cannot hold (counted, the first named: `index` is its message number).
    fn geometry(&mut self, s: &LaserScan, stamp_ns: i64, index: u64) -> Option<Geometry> {
        let period_s = self
            .last_stamp
            .map(|t| stamp_ns.saturating_sub(t) as f64 * 1e-9);
        let (beam_s, timing) = beam_time_s(s, period_s);
        let g = Geometry {
            n: s.ranges.len(),
            angle_min: s.angle_min,
            angle_increment: s.angle_increment,
            beam_s,
            given: matches!(timing, BeamTiming::AsGiven | BeamTiming::Reversed)
                .then_some(s.time_increment),
        };
        if g.n == 0 {
            self.done.empty_scans += 1;
            return None;
        }
        let h = g.header();
        if !pingcal_lrf::scan::geometry_ok(h.angle_min_deg, h.angle_increment_deg, g.n) {
            self.done.bad_geometry.add(index, || {
                format!(
                    "angle_min {} rad, angle_increment {} rad over {} beams",
                    short32(s.angle_min),
                    short32(s.angle_increment),
                    g.n
                )
            });
            return None;
        }
        let t = &mut self.done.timing;
        match timing {
            BeamTiming::AsGiven => {}
            BeamTiming::FromScanTime => t.from_scan_time += 1,
            BeamTiming::Reversed => t.reversed += 1,
            BeamTiming::PerScan => t.per_scan += 1,
            BeamTiming::Ignored => t.ignored += 1,
        }
        if self.geometry.is_some_and(|last| last != g) {
            self.done.geometry_changes += 1;
        }
        self.geometry = Some(g);
        Some(g)
    }

    fn scan(&mut self, bag: &Bag, m: &RawMessage, index: u64) -> Result<()> {
        expect_type(bag, m, &[msgs::LASER_SCAN])?;
        let id = identity(m.data);
        if !self.seen.insert(id) {
            self.done.duplicate_scans += 1;
            return Ok(());
        }
        self.seen_order.push_back(id);
        if self.seen_order.len() > DUPLICATE_WINDOW {
            if let Some(old) = self.seen_order.pop_front() {
                self.seen.remove(&old);
            }
        }
        let s = LaserScan::decode(m.data, m.encoding).map_err(|e| decode_err(bag, m, index, e))?;
        let stamp_ns = if self.record { m.time_ns } else { s.stamp_ns };
        if self.decision.is_none() {
            // every scan's stamp, empty or out of order too, tells how the servo keeps time
            self.scan_stamps.push(stamp_ns);
        }
        if self.stamps_only {
            return Ok(());
        }
        let Some(g) = self.geometry(&s, stamp_ns, index) else {
            return Ok(());
        };
        match self.last_stamp {
            Some(t) if stamp_ns < t => {
                self.done.backward_stamps += 1;
                return Ok(());
            }
            Some(t) if stamp_ns == t => self.done.repeated_stamps += 1,
            _ => {}
        }
        self.last_stamp = Some(stamp_ns);
        self.scan_until = self.scan_until.max(stamp_ns);
        let masked = &mut self.done.masked;
        let ranges_mm: Vec<f64> = s
            .ranges
            .iter()
            .map(|&r| range_mm_counted(r, s.range_min, s.range_max, masked))
            .collect();
        let intensities = if s.intensities.len() == s.ranges.len() {
            self.done.with_intensities += 1;
            s.intensities
        } else {
            Vec::new()
        };
        self.pending.push_back(Pending {
            stamp_ns,
            end_off_ns: (g.n - 1) as f64 * g.beam_s * 1e9,
            header: g.header(),
            line: ScanLine {
                line: usize::try_from(index + 1).unwrap_or(usize::MAX),
                stamp_s: stamp_ns as f64 * 1e-9,
                servo_deg: 0.0,
                servo_end_deg: None,
                ranges_mm,
                intensities,
                geometry: None,
            },
        });
        Ok(())
    }

    /// Decides the motion once enough is known, then gives the caller every waiting scan
    /// whose servo angle is known (all of them at the `end`).
    fn flush(
        &mut self,
        end: bool,
        f: &mut dyn FnMut(&ScanHeader, ScanLine) -> Result<()>,
    ) -> Result<()> {
        if self.fixed {
            while let Some(p) = self.pending.pop_front() {
                self.done.scans += 1;
                f(&p.header, p.line)?;
            }
            return Ok(());
        }
        let forced = self.servo_complete && self.pending.len() > self.cap;
        if !end && !forced && self.pending.len() > self.cap {
            self.overflow = true;
            return Err(RosbagError::Stopped);
        }
        let samples = self.series.times_ns.len();
        // classify again only when the series has doubled (or at the end): the work stays
        // linear in the data whatever the servo does
        if self.decision.is_none()
            && samples > 0
            && (end || forced || samples >= self.next_classify)
        {
            let until = if self.servo_complete {
                self.scan_until
            } else {
                self.servo_until.min(self.scan_until)
            };
            self.decision = classify(&self.series, &self.scan_stamps, until, end || forced);
            if self.decision.is_some() {
                self.scan_stamps = Vec::new();
            }
            self.next_classify = samples * 2;
        }
        let Some(motion) = self.decision.as_ref().map(|d| d.motion) else {
            return Ok(());
        };
        let hold_limit = if end || self.servo_complete {
            // the series is complete: its median interval, once
            *self
                .hold_limit
                .get_or_insert_with(|| self.series.median_interval_ns())
        } else {
            0
        };
        while let Some(p) = self.pending.front() {
            // the beams measured last to first end at the stamp
            let last_beam = p
                .stamp_ns
                .saturating_add(p.end_off_ns.max(0.0).ceil() as i64);
            let known =
                end || self.servo_complete || self.servo_until > last_beam.saturating_add(SLACK_NS);
            if !known {
                break;
            }
            let Some(mut p) = self.pending.pop_front() else {
                break;
            };
            if !self.servo_complete {
                // no scan to come is stamped before this one (those are dropped)
                self.series.forget_before(p.stamp_ns);
            }
            if let Some((start, stop)) = self.angles(motion, &p, hold_limit) {
                p.line.servo_deg = start;
                p.line.servo_end_deg = Some(stop);
                self.done.scans += 1;
                if self.done.scans > self.skip {
                    f(&p.header, p.line)?;
                }
            }
        }
        Ok(())
    }

    /// The servo angle at a scan's first and last beam, or `None` (counted) outside the
    /// servo series.
    fn angles(&mut self, motion: ServoMotion, p: &Pending, hold_limit: i64) -> Option<(f64, f64)> {
        let s = &self.series;
        let first = *s.times_ns.first()?;
        let last = *s.times_ns.last()?;
        // the first beam measured (the last one of a scan measured last to first)
        let earliest = p
            .stamp_ns
            .saturating_add(p.end_off_ns.min(0.0).floor() as i64);
        if earliest < first {
            self.done.before_servo += 1;
            return None;
        }
        let got = match motion {
            ServoMotion::Continuous => s.at(p.stamp_ns, 0.0).zip(s.at(p.stamp_ns, p.end_off_ns)),
            _ if p.stamp_ns > last && p.stamp_ns - last > hold_limit => None,
            _ => s.hold(p.stamp_ns).map(|d| (d, d)),
        };
        if got.is_none() {
            self.done.after_servo += 1;
        }
        got
    }

    /// One pass over the bags: both topics, or only the scans when the series is complete.
    fn pass(
        &mut self,
        bags: &[Bag],
        f: &mut dyn FnMut(&ScanHeader, ScanLine) -> Result<()>,
    ) -> Result<()> {
        let topics = self.topics;
        let wanted: Vec<&str> = if self.servo_complete {
            vec![topics.scan.as_str()]
        } else {
            vec![topics.scan.as_str(), topics.servo.as_str()]
        };
        for bag in bags {
            let (mut scans, mut servos) = (0u64, 0u64);
            bag.for_each(&wanted, &mut |m| {
                if topics.scan == topics.servo {
                    // one topic cannot be both: the error names the type it lacks
                    expect_type(bag, m, &[msgs::LASER_SCAN])?;
                    expect_type(bag, m, &servo_types(&topics.source))?;
                }
                if m.topic == topics.servo && !self.servo_complete {
                    self.servo(bag, m, servos)?;
                    servos += 1;
                } else {
                    self.scan(bag, m, scans)?;
                    scans += 1;
                }
                self.flush(false, f)
            })?;
            if scans == 0 && bags.len() == 1 {
                return Err(no_messages(bag, &topics.scan));
            }
        }
        Ok(())
    }
}

/// [`crate::assemble::read_scans`].
pub fn read(
    bags: &[Bag],
    topics: &Topics,
    motion: ServoMotion,
    f: &mut dyn FnMut(&ScanHeader, ScanLine) -> Result<()>,
) -> Result<Assembled> {
    read_with_cap(bags, topics, motion, MAX_PENDING_SCANS, f)
}

/// [`read`] with at most `cap` scans waiting before it falls back to two passes.
fn read_with_cap(
    bags: &[Bag],
    topics: &Topics,
    motion: ServoMotion,
    cap: usize,
    f: &mut dyn FnMut(&ScanHeader, ScanLine) -> Result<()>,
) -> Result<Assembled> {
    let clock = crate::clock::choose(
        bags,
        &topics.scan,
        &topics.servo,
        &topics.source,
        topics.stamps,
    )?;
    let mut st = Stream::new(topics, motion, clock.record);
    st.cap = cap;
    st.done.passes = 1;
    match st.pass(bags, f) {
        Err(RosbagError::Stopped) if st.overflow => {
            // two passes: the servo series and the scans' stamps first, then the scans;
            // the scans already given are not given again
            let given = st.done.scans;
            let mut first = Stream::new(topics, motion, clock.record);
            first.stamps_only = true;
            first.pass(bags, &mut |_, _| Ok(()))?;
            if first.series.times_ns.is_empty() {
                return Err(no_servo_samples(
                    bags,
                    topics,
                    first.servo_messages,
                    &first.names,
                ));
            }
            let decision = first
                .decision
                .take()
                .or_else(|| classify(&first.series, &first.scan_stamps, i64::MAX, true));
            st = Stream::new(topics, motion, clock.record);
            st.cap = cap;
            st.done.passes = 2;
            st.skip = given;
            st.done.duplicate_servo = first.done.duplicate_servo;
            st.series = first.series;
            st.servo_complete = true;
            st.decision = decision;
            st.pass(bags, f)?;
        }
        other => other?,
    }
    if st.series.times_ns.is_empty() {
        if let Some(first) = &st.done.bad_servo.first {
            let files: Vec<&str> = bags.iter().map(Bag::name).collect();
            return Err(RosbagError::topic(
                &files.join(", "),
                &topics.servo,
                format!(
                    "no servo angle a scan file can hold: {} value(s) not a number or beyond ±1e6° (the first: {first})",
                    st.done.bad_servo.count
                ),
            ));
        }
        return Err(no_servo_samples(bags, topics, st.servo_messages, &st.names));
    }
    if let Some(e) = no_scan(bags, &topics.scan, &st) {
        return Err(e);
    }
    st.flush(true, f)?;
    let d = st.decision.take().unwrap_or(Decision {
        motion: ServoMotion::StopAndGo,
        reason: "no scan to tell from".into(),
    });
    st.done.motion = d.motion;
    st.done.motion_reason = d.reason;
    st.done.clock = clock;
    Ok(st.done)
}

/// The error of a read that met no scan a file can hold (none, or only bad geometries; an
/// empty scan counts as met).
fn no_scan(bags: &[Bag], topic: &str, st: &Stream) -> Option<RosbagError> {
    if st.geometry.is_some() || st.done.empty_scans > 0 {
        return None;
    }
    let files: Vec<&str> = bags.iter().map(Bag::name).collect();
    let what = match &st.done.bad_geometry.first {
        Some(first) => format!(
            "no scan a scan file can hold: {} scan(s) with an angle or a step beyond a turn (the first: {first})",
            st.done.bad_geometry.count
        ),
        None => "no LaserScan messages in any of the bags".into(),
    };
    Some(RosbagError::topic(&files.join(", "), topic, what))
}

/// [`crate::assemble::read_fixed_scans`]: one pass over the scan topic, every scan at
/// servo 0, at its header stamps unless `stamps` asks for the record times.
pub fn read_fixed(
    bags: &[Bag],
    scan: &str,
    stamps: crate::clock::Stamps,
    f: &mut dyn FnMut(&ScanHeader, ScanLine) -> Result<()>,
) -> Result<Assembled> {
    let topics = Topics {
        scan: scan.to_string(),
        servo: String::new(),
        source: crate::assemble::ServoSource::Joint(String::new()),
        stamps,
    };
    let record = stamps == crate::clock::Stamps::Record;
    let mut st = Stream::new(&topics, ServoMotion::StopAndGo, record);
    st.fixed = true;
    // the pass reads the scan topic only
    st.servo_complete = true;
    st.done.passes = 1;
    st.pass(bags, f)?;
    if let Some(e) = no_scan(bags, scan, &st) {
        return Err(e);
    }
    st.flush(true, f)?;
    st.done.motion = ServoMotion::StopAndGo;
    st.done.motion_reason = "a fixed LRF: no servo".into();
    st.done.clock = crate::clock::Clock {
        record,
        reason: if record {
            "record times, as asked".into()
        } else {
            "a fixed LRF has no servo topic to keep another clock".into()
        },
    };
    Ok(st.done)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assemble::ServoSource;

    fn read_all(name: &str, motion: ServoMotion, cap: usize) -> (Vec<ScanLine>, Assembled) {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data")
            .join(name);
        let bags = [Bag::open(&path).unwrap()];
        let topics = Topics {
            scan: "/scan".into(),
            servo: "/joint_states".into(),
            source: ServoSource::Joint("servo".into()),
            stamps: crate::clock::Stamps::Auto,
        };
        let mut lines = Vec::new();
        let done = read_with_cap(&bags, &topics, motion, cap, &mut |_, l| {
            lines.push(l);
            Ok(())
        })
        .unwrap();
        (lines, done)
    }

    /// When too many scans wait for the servo, the bags are read again in two passes and
    /// give the same scans, each once.
    #[test]
    fn the_two_pass_fallback_gives_the_same_scans_once() {
        for (name, motion) in [
            ("sweep_cont.mcap", ServoMotion::Auto),
            ("stopgo_10ms.mcap", ServoMotion::Auto),
            ("stopgo_50ms.mcap", ServoMotion::StopAndGo),
        ] {
            let (one, a) = read_all(name, motion, MAX_PENDING_SCANS);
            let (two, b) = read_all(name, motion, 2);
            assert_eq!((a.passes, b.passes), (1, 2), "{name}");
            assert_eq!(one.len(), two.len(), "{name}");
            for (x, y) in one.iter().zip(&two) {
                assert_eq!(x, y, "{name}");
            }
            assert_eq!((a.scans, a.motion), (b.scans, b.motion), "{name}");
        }
    }

    /// The drivers' conventions for `time_increment` and `scan_time`: per beam, 0 with a
    /// scan time (a turn per scan), negative (last beam first), the whole scan's time, and
    /// nonsense.
    #[test]
    fn beams_are_timed_by_the_drivers_conventions() {
        let scan = |ti: f32, st: f32| LaserScan {
            stamp_ns: 0,
            frame_id: String::new(),
            angle_min: -std::f32::consts::PI,
            angle_max: std::f32::consts::PI,
            angle_increment: std::f32::consts::TAU / 360.0,
            time_increment: ti,
            scan_time: st,
            range_min: 0.1,
            range_max: 10.0,
            ranges: vec![1.0; 360],
            intensities: vec![],
        };
        let near = |a: f64, b: f64| (a - b).abs() < 1e-6 * b.abs().max(1e-9);
        let (b, how) = beam_time_s(&scan(0.1 / 359.0, 0.1), None);
        assert!(near(b, f64::from(0.1f32 / 359.0)) && how == BeamTiming::AsGiven);
        let (b, how) = beam_time_s(&scan(0.0, 0.1), None);
        assert!(
            near(b, 0.1 / 360.0) && how == BeamTiming::FromScanTime,
            "{b}"
        );
        let (b, how) = beam_time_s(&scan(0.0, 0.0), Some(0.1));
        assert!(b == 0.0 && how == BeamTiming::AsGiven);
        let (b, how) = beam_time_s(&scan(-0.1 / 359.0, 0.1), None);
        assert!(near(b, -f64::from(0.1f32 / 359.0)) && how == BeamTiming::Reversed);
        // the whole scan's time in time_increment: per beam it is a 360th, scan_time or not
        for st in [0.1, 0.0] {
            let (b, how) = beam_time_s(&scan(0.1, st), Some(0.1));
            assert!(
                near(b, f64::from(0.1f32) / 360.0) && how == BeamTiming::PerScan,
                "{st}"
            );
        }
        for ti in [f32::NAN, 1e30] {
            assert_eq!(
                beam_time_s(&scan(ti, 0.1), None),
                (0.0, BeamTiming::Ignored)
            );
        }
        // nothing to compare with: as given
        assert_eq!(beam_time_s(&scan(0.1, 0.0), None).1, BeamTiming::AsGiven);
    }

    #[test]
    fn identity_tells_messages_apart_by_every_byte() {
        let a: Vec<u8> = (0..=255u8).collect();
        let mut seen = HashSet::new();
        assert!(seen.insert(identity(&a)));
        for i in 0..a.len() {
            let mut b = a.clone();
            b[i] ^= 1;
            assert!(seen.insert(identity(&b)), "byte {i}");
        }
        assert!(seen.insert(identity(&a[..255])));
        assert!(!seen.insert(identity(&a)));
    }
}
