//! What a servo sweep can tell of the mount: the sweep's extent, and a real rig's errors
//! for what a partial sweep leaves undetermined.
//!
//! A full turn sees every plane from both halves (β and β + 180° with the beam angle
//! mirrored), and a wrong mount shows as the two views disagreeing. A nod (a 360° scanner
//! tilted back and forth by a few tens of degrees) or any partial sweep sees each plane at
//! many servo angles too, but a mount error then moves the whole cloud nearly rigidly (the
//! planes take that up) and shows only through how it changes with the servo angle: the
//! narrower the sweep, the less of it. What such a sweep determines is found, as for a full
//! turn, from the adjustment's covariance ([`crate::room`]). But a parameter held at its
//! start for want of data is held at a value a real rig's error off, and the parameters
//! correlated with it would take up that error (in a simulated ±18° nod, the offsets held
//! at zero moved the range offset by up to 3σ). So after a partial sweep the held ones are freed
//! again under priors of a real rig's error ([`RIG_ERROR`]) at their start: the estimated
//! parameters carry that uncertainty in their σ's, and one whose σ is then no better than
//! a real rig's error is held too, with the reason.

use crate::cloud::BeamReading;
use crate::sensor::{MountParam, MOUNT_PARAM_NAMES};

/// A real rig's mount and range errors ([`crate::sensor::MountModel::to_params`] units):
/// offsets of 15 mm, tilts of 1°, a servo scale of 0.5 %, a range offset of 30 mm (the
/// URG-04LX datasheet's ±30 mm) and a range scale of 1 % (published rotating-LRF
/// calibrations find offsets of up to ±15 mm and tilts of tenths of a degree).
pub const RIG_ERROR: [f64; 8] = [
    15.0,
    15.0,
    15.0,
    0.017_453_292_519_943_295,
    0.017_453_292_519_943_295,
    0.005,
    30.0,
    0.01,
];

/// A sweep spanning at least this (degrees) is a full turn.
pub const FULL_TURN_DEG: f64 = 359.0;

/// The servo angles a set of scans spans.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sweep {
    /// The smallest servo reading (degrees).
    pub min_deg: f64,
    /// The largest servo reading (degrees).
    pub max_deg: f64,
}

impl Sweep {
    /// The sweep of `readings` (None when there are none).
    pub fn of(readings: &[BeamReading]) -> Option<Sweep> {
        let mut it = readings
            .iter()
            .map(|r| r.servo_deg)
            .filter(|v| v.is_finite());
        let first = it.next()?;
        let (min_deg, max_deg) = it.fold((first, first), |(a, b), v| (a.min(v), b.max(v)));
        Some(Sweep { min_deg, max_deg })
    }

    /// Its span (degrees).
    pub fn span_deg(&self) -> f64 {
        self.max_deg - self.min_deg
    }

    /// Whether it is a full turn (every plane seen from both halves).
    pub fn is_full_turn(&self) -> bool {
        self.span_deg() >= FULL_TURN_DEG
    }

    /// In words: "a full turn (servo −180.0…179.9°)", "a ±18.0° nod (servo −18.0…18.0°)"
    /// (a sweep about the servo's zero), "a 36.0° sweep (servo 72.0…108.0°)".
    pub fn describe(&self) -> String {
        let (a, b, span) = (self.min_deg, self.max_deg, self.span_deg());
        let range = format!("servo {a:.1}…{b:.1}°");
        if self.is_full_turn() {
            format!("a full turn ({range})")
        } else if (a + b).abs() <= 0.1 * span.max(1.0) {
            format!("a ±{:.1}° nod ({range})", span / 2.0)
        } else {
            format!("a {span:.1}° sweep ({range})")
        }
    }

    /// What to record instead, for parameter `k` ([`MountParam::at`]) this sweep does not
    /// determine.
    pub fn advice(&self, k: usize) -> &'static str {
        match MountParam::at(k) {
            MountParam::RangeScale => {
                "no sweep does: a range scale scales the whole room, and only a known length (the balls of a calibration) gives it"
            }
            _ => {
                "record a full turn of the servo (each plane seen from both halves of it), which determines it"
            }
        }
    }
}

/// Why parameter `k` is held when, with the parameters `weak` free under priors of a real
/// rig's error ([`RIG_ERROR`]), its σ (`sd`, [`crate::sensor::MountModel::to_params`]
/// units) is more than a real rig's error.
pub fn vaguer_than_a_rig(k: usize, sd: f64, weak: &[usize], sweep: &Sweep) -> String {
    let p = MountParam::at(k);
    let u = p.unit();
    let names: Vec<&str> = weak.iter().map(|&j| MOUNT_PARAM_NAMES[j]).collect();
    format!(
        "the sweep is {}: with {} (which it does not determine) free within a real rig's error, it gives it no better than a real rig's error (σ {:.4}{u} against {:.4}{u}); {}",
        sweep.describe(),
        names.join(", "),
        p.in_report_unit(sd),
        p.in_report_unit(RIG_ERROR[k]),
        sweep.advice(k)
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(servo: &[f64]) -> Vec<BeamReading> {
        servo
            .iter()
            .map(|&s| BeamReading::at_rest(s, 0.0, 1000.0))
            .collect()
    }

    #[test]
    fn a_sweep_is_named_by_its_extent() {
        let nod = Sweep::of(&at(&[-18.0, 3.0, 18.0])).unwrap();
        assert_eq!(nod.describe(), "a ±18.0° nod (servo -18.0…18.0°)");
        assert!(!nod.is_full_turn());
        let part = Sweep::of(&at(&[72.0, 108.0])).unwrap();
        assert_eq!(part.describe(), "a 36.0° sweep (servo 72.0…108.0°)");
        let full = Sweep::of(&at(&[-180.0, 179.912])).unwrap();
        assert!(full.is_full_turn(), "{}", full.describe());
        assert!(Sweep::of(&[]).is_none());
    }
}
