//! Whose time a bag's messages are taken at: a message's header stamp (the clock of the
//! driver that stamped it) or the bag's record time (the recorder's clock).
//!
//! The two need not be one clock. A scanner driver may stamp its scans from the scanner's
//! own boot (168 s) while the recorder's times are since the epoch (1.7·10⁹ s); a topic
//! without a header (`std_msgs/Int32`, `Float64`) has only record times. Matching a scan's
//! header stamp against such a servo's record times finds no servo angle, or the wrong one.
//!
//! [`choose`] with [`Stamps::Auto`] looks at the first [`SAMPLE_MESSAGES`] messages of each
//! topic: a topic's *lag* is the median of (record time − header stamp).
//!
//! - The servo topic has no header: the scan topic's header stamps keep the recorder's
//!   clock when its lag lies within `[-AHEAD_S, MAX_LAG_S]` (a message is recorded after it
//!   is stamped, within a second): header stamps for the scans; otherwise (stamped more than
//!   [`AHEAD_S`] after being recorded, or recorded more than [`MAX_LAG_S`] after being
//!   stamped) the record times for both topics.
//! - Both topics have headers: their header stamps keep one clock when their lags differ
//!   by at most [`PAIR_S`] (whatever the recorder's clock): header stamps; otherwise the
//!   record times for both.
//!
//! [`Clock::reason`] says which and why, with the lags.

use crate::error::{Result, RosbagError};
use crate::msgs::{self, JointState, LaserScan};
use crate::{Bag, RawMessage};
pub use pingcal_lrf::settings::{ServoSource, Stamps};

/// Messages of each topic [`choose`] looks at.
pub const SAMPLE_MESSAGES: usize = 64;
/// A header stamp later than its record time by more than this (s) is on another clock.
pub const AHEAD_S: f64 = 0.05;
/// A header stamp earlier than its record time by more than this (s) is on another clock.
pub const MAX_LAG_S: f64 = 1.0;
/// Two topics' lags that differ by more than this (s) are two clocks.
pub const PAIR_S: f64 = 0.25;

/// The time base of a read, and why.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Clock {
    /// The record times for every topic; else the header stamps where a message has one.
    pub record: bool,
    /// Why, in words.
    pub reason: String,
}

impl Clock {
    /// "record times" or "header stamps".
    pub fn name(&self) -> &'static str {
        if self.record {
            "record times"
        } else {
            "header stamps"
        }
    }
}

/// A message's header stamp, ns; `None` for a type without a header (or one that cannot
/// be decoded: the read proper names it).
fn header_stamp(m: &RawMessage) -> Option<i64> {
    match m.msg_type {
        msgs::LASER_SCAN => LaserScan::decode(m.data, m.encoding)
            .ok()
            .map(|s| s.stamp_ns),
        msgs::JOINT_STATE => JointState::decode(m.data, m.encoding)
            .ok()
            .map(|j| j.stamp_ns),
        msgs::TF_MESSAGE => msgs::decode_tf(m.data, m.encoding)
            .ok()
            .and_then(|t| t.first().map(|t| t.stamp_ns)),
        _ => None,
    }
}

/// What the first messages of one topic say of its clock.
#[derive(Debug, Default)]
struct Sample {
    /// record − header, ns, of the messages with a header.
    lags: Vec<i64>,
    /// Messages looked at.
    seen: usize,
    /// The topic's type.
    msg_type: String,
}

impl Sample {
    /// The median lag, seconds; `None` for a topic without headers.
    fn lag_s(&mut self) -> Option<f64> {
        if self.lags.is_empty() {
            return None;
        }
        let mid = self.lags.len() / 2;
        Some(*self.lags.select_nth_unstable(mid).1 as f64 * 1e-9)
    }

    fn full(&self) -> bool {
        self.seen >= SAMPLE_MESSAGES
    }
}

/// A lag in words: "1e9 s ahead of" or "0.012 s behind".
fn lag_words(lag_s: f64) -> String {
    let ahead = lag_s < 0.0;
    let v = lag_s.abs();
    let v = if v >= 1e4 {
        format!("{v:.3e}")
    } else {
        format!("{v:.3}")
    };
    format!(
        "{v} s {} their record times",
        if ahead { "ahead of" } else { "behind" }
    )
}

/// The time base for reading the scans of topic `scan` and the servo of topic `servo`
/// (read as `source` says) from `bags` as `asked` (module doc).
pub fn choose(
    bags: &[Bag],
    scan_topic: &str,
    servo_topic: &str,
    source: &ServoSource,
    asked: Stamps,
) -> Result<Clock> {
    let headerless = matches!(source, ServoSource::Numeric { .. });
    match asked {
        Stamps::Record => {
            return Ok(Clock {
                record: true,
                reason: "as asked".into(),
            })
        }
        Stamps::Header => {
            return Ok(Clock {
                record: false,
                reason: if headerless {
                    "as asked (the servo topic has no header: its record times)".into()
                } else {
                    "as asked".into()
                },
            })
        }
        Stamps::Auto => {}
    }
    let (mut scan, mut servo) = (Sample::default(), Sample::default());
    for bag in bags {
        let read = bag.for_each(&[scan_topic, servo_topic], &mut |m| {
            let s = if m.topic == scan_topic {
                &mut scan
            } else {
                &mut servo
            };
            if !s.full() {
                s.seen += 1;
                s.msg_type = m.msg_type.to_string();
                if let Some(h) = header_stamp(m) {
                    s.lags.push(m.time_ns.saturating_sub(h));
                }
            }
            if scan.full() && servo.full() {
                return Err(RosbagError::Stopped);
            }
            Ok(())
        });
        match read {
            Err(RosbagError::Stopped) => break,
            other => other?,
        }
    }
    Ok(decide(scan.lag_s(), servo.lag_s(), &servo.msg_type))
}

/// The choice of [`choose`] from the scan topic's and the servo topic's lags (s; `None`
/// for a topic without headers, or none read).
fn decide(scan: Option<f64>, servo: Option<f64>, servo_type: &str) -> Clock {
    let header = |reason: String| Clock {
        record: false,
        reason,
    };
    let record = |reason: String| Clock {
        record: true,
        reason,
    };
    let Some(a) = scan else {
        return header("no scan to tell from".into());
    };
    match servo {
        None => {
            let kind = if servo_type.is_empty() {
                "no servo message read".to_string()
            } else {
                format!("the servo topic ({servo_type}) has no header, only record times")
            };
            if (-AHEAD_S..=MAX_LAG_S).contains(&a) {
                header(format!(
                    "the scans' header stamps keep the recorder's clock ({}); {kind}",
                    lag_words(a)
                ))
            } else {
                record(format!(
                    "the scans' header stamps are {}: a clock of their own (e.g. the scanner's boot time), and {kind}",
                    lag_words(a)
                ))
            }
        }
        Some(b) if (a - b).abs() <= PAIR_S => header(format!(
            "both topics' header stamps keep one clock (the scans' {}, the servo's {})",
            lag_words(a),
            lag_words(b)
        )),
        Some(b) => record(format!(
            "the two topics' header stamps keep two clocks (the scans' {}, the servo's {})",
            lag_words(a),
            lag_words(b)
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_header_clock_ahead_of_the_record_times_picks_the_record_times() {
        for (lag, record) in [
            (-1e9, true),
            (-0.5, true),
            (0.0, false),
            (0.1, false),
            (-0.01, false),
            (-168.0 + 1.7e9, true),
            (2.0, true),
        ] {
            let c = decide(Some(lag), None, "std_msgs/Int32");
            assert_eq!(c.record, record, "{lag}: {}", c.reason);
            assert!(c.reason.contains("std_msgs/Int32"), "{}", c.reason);
        }
        // two headers: one clock however far from the recorder's, or two
        assert!(!decide(Some(-1e9), Some(-1e9 + 0.01), "sensor_msgs/JointState").record);
        let c = decide(Some(-0.5), Some(0.0), "sensor_msgs/JointState");
        assert!(c.record && c.reason.contains("two clocks"), "{}", c.reason);
        assert!(!decide(None, None, "").record);
    }

    #[test]
    fn lags_in_words() {
        assert_eq!(lag_words(-1e9), "1.000e9 s ahead of their record times");
        assert_eq!(lag_words(0.0125), "0.013 s behind their record times");
    }
}
