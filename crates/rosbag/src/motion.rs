//! How the servo moves, and the servo angle of a scan under each kind of motion.
//!
//! * **Stop-and-go**: the servo steps, stops, the scanner sweeps, repeat. Its message comes
//!   when it has stopped, before the scan: the scan's angle is the last servo angle at or
//!   before the scan's stamp (zero-order hold, [`ServoSeries::hold`]). Interpolating between
//!   two rest angles to the scan's stamp would assume a motion that did not happen (an
//!   error of step · lead / period).
//! * **Continuous**: the servo turns while the scanner sweeps; each beam has its own time
//!   (the scan's stamp + k · `time_increment`) and the angle is interpolated linearly
//!   between the servo messages around it ([`ServoSeries::at`]).
//!
//! [`classify`] tells them apart from the servo series and the scans' stamps (`auto`):
//!
//! 1. From the servo's first move to its 16th, a *rest* is two consecutive messages with the
//!    same angle (within 1e-6°). At least one rest for every four moves: stop-and-go (the
//!    servo publishes while it stands; a continuous sweep has almost none).
//! 2. Otherwise, when four scans in five of that stretch have exactly one servo message
//!    since the scan before them, at a lead that varies by less than a fifth of the scan
//!    period: stop-and-go (one message per step, sent when the servo has stopped,
//!    in step with the scans).
//! 3. Otherwise: continuous (the angle changes at every message, at a rate of its own).
//!
//! A servo that never moves is stop-and-go. A continuous sweep whose servo publishes once
//! per scan in step with the scanner looks like rule 2 to the data: say `continuous` then.

pub use pingcal_lrf::settings::ServoMotion;

/// The servo angle over time: samples in time order (nanoseconds, degrees).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ServoSeries {
    /// Sample times, ns, strictly increasing.
    pub times_ns: Vec<i64>,
    /// Angles, degrees.
    pub deg: Vec<f64>,
}

/// What [`ServoSeries::insert`] did with a sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Inserted {
    /// A new time.
    New,
    /// A time already there with another angle: the later sample replaced it.
    Replaced,
    /// The same time and angle as a sample already there.
    Duplicate,
}

impl ServoSeries {
    /// Inserts a sample in time order (samples nearly always come in order: the search
    /// starts from the end); a repeated time keeps the later sample's angle.
    pub fn insert(&mut self, t: i64, deg: f64) -> Inserted {
        let at = if self.times_ns.last().is_none_or(|&l| l < t) {
            self.times_ns.len()
        } else {
            self.times_ns.partition_point(|&s| s < t)
        };
        if self.times_ns.get(at) == Some(&t) {
            if self.deg[at] == deg {
                return Inserted::Duplicate;
            }
            self.deg[at] = deg;
            return Inserted::Replaced;
        }
        self.times_ns.insert(at, t);
        self.deg.insert(at, deg);
        Inserted::New
    }

    /// The angle at `base_ns + off_ns` (off_ns ≥ 0, fractional), interpolated linearly
    /// between the samples around it, or `None` outside the samples.
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

    /// The last angle at or before `t_ns` (zero-order hold), or `None` before the first
    /// sample.
    pub fn hold(&self, t_ns: i64) -> Option<f64> {
        let k = self.times_ns.partition_point(|&s| s <= t_ns);
        (k > 0).then(|| self.deg[k - 1])
    }

    /// Forgets the samples no scan stamped at or after `t_ns` needs (all but the last one at
    /// or before it), keeping the last [`KEPT_SAMPLES`] at least; the work is done when it
    /// frees half the series or more (linear in the data overall).
    pub fn forget_before(&mut self, t_ns: i64) {
        let k = self.times_ns.partition_point(|&s| s <= t_ns);
        let cut = k
            .saturating_sub(1)
            .min(self.times_ns.len().saturating_sub(KEPT_SAMPLES));
        if cut > 0 && cut * 2 >= self.times_ns.len() {
            self.times_ns.drain(..cut);
            self.deg.drain(..cut);
        }
    }

    /// The median time between consecutive samples among the last [`KEPT_SAMPLES`], ns (0
    /// with fewer than two).
    pub fn median_interval_ns(&self) -> i64 {
        let from = self.times_ns.len().saturating_sub(KEPT_SAMPLES);
        let mut d: Vec<i64> = self.times_ns[from..]
            .windows(2)
            .map(|w| w[1] - w[0])
            .collect();
        if d.is_empty() {
            return 0;
        }
        let mid = d.len() / 2;
        *d.select_nth_unstable(mid).1
    }
}

/// The motion [`classify`] chose and why (one line, for the summary).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Decision {
    /// Stop-and-go or continuous.
    pub motion: ServoMotion,
    /// Why, in words.
    pub reason: String,
}

/// Samples [`ServoSeries::forget_before`] always keeps.
pub const KEPT_SAMPLES: usize = 64;

/// Two consecutive servo angles closer than this (degrees) are a rest.
pub const REST_DEG: f64 = 1e-6;
/// The servo's moves [`classify`] looks at.
pub const MOVES_TO_DECIDE: usize = 16;
/// How much later than the stretch [`classify`] looks at both series must have been read
/// (messages of a bag are in time order to within this), ns.
pub const SLACK_NS: i64 = 500_000_000;

/// Tells stop-and-go from continuous (module doc) from the servo series and the scan
/// stamps read so far, both complete up to `seen_until_ns`; `None` while that is not enough
/// and more may come (`complete` false).
pub fn classify(
    s: &ServoSeries,
    scans: &[i64],
    seen_until_ns: i64,
    complete: bool,
) -> Option<Decision> {
    let (t, d) = (&s.times_ns, &s.deg);
    let n = d.len();
    let is_rest = |k: usize| (d[k + 1] - d[k]).abs() <= REST_DEG;
    let first = (0..n.saturating_sub(1)).find(|&k| !is_rest(k));
    let (mut moves, mut rests, mut end) = (0usize, 0usize, 0usize);
    if let Some(m0) = first {
        for k in m0..n - 1 {
            if is_rest(k) {
                rests += 1;
            } else {
                moves += 1;
            }
            end = k + 1;
            if moves == MOVES_TO_DECIDE {
                break;
            }
        }
    }
    let enough = moves >= MOVES_TO_DECIDE && t[end].saturating_add(SLACK_NS) <= seen_until_ns;
    if !enough && !complete {
        return None;
    }
    let decision = |motion, reason: String| Some(Decision { motion, reason });
    let Some(m0) = first else {
        return decision(
            ServoMotion::StopAndGo,
            "the servo never moves: its angle is held".into(),
        );
    };
    if rests * 4 >= moves {
        return decision(
            ServoMotion::StopAndGo,
            format!("the servo rests between its steps ({rests} repeated angles among its first {moves} moves)"),
        );
    }
    if let Some(lead_ns) = locked(t, (t[m0], t[end]), scans) {
        return decision(
            ServoMotion::StopAndGo,
            format!(
                "one servo message {:.1} ms before each scan, in step with the scans",
                lead_ns as f64 * 1e-6
            ),
        );
    }
    decision(
        ServoMotion::Continuous,
        format!(
            "the servo angle changes at {moves} messages of {} in a row (a ramp)",
            moves + rests
        ),
    )
}

/// The median lead of the servo message before each scan when the scans stamped within
/// `window` (and the one after it) have, four times in five at least, exactly one servo
/// message since the scan before them, at a steady lead (module doc, rule 2; a scan that
/// repeats a stamp or a message lost now and then do not hide the pattern).
fn locked(t: &[i64], window: (i64, i64), scans: &[i64]) -> Option<i64> {
    let mut inside: Vec<i64> = scans.iter().copied().filter(|&s| s >= window.0).collect();
    inside.sort_unstable();
    inside.dedup();
    let after = inside.partition_point(|&s| s <= window.1);
    inside.truncate((after + 1).min(inside.len()));
    if inside.len() < 4 {
        return None;
    }
    let mut leads = Vec::new();
    let mut periods = Vec::new();
    for w in inside.windows(2) {
        let (a, b) = (w[0], w[1]);
        periods.push(b - a);
        let from = t.partition_point(|&x| x <= a);
        let to = t.partition_point(|&x| x <= b);
        if to - from == 1 {
            leads.push(b - t[to - 1]);
        }
    }
    if leads.len() * 5 < periods.len() * 4 {
        return None;
    }
    periods.sort_unstable();
    let period = periods[periods.len() / 2];
    leads.sort_unstable();
    // the spread of the middle 80 % of the leads
    let cut = leads.len() / 10;
    let (lo, hi) = (leads[cut], leads[leads.len() - 1 - cut]);
    if period <= 0 || (hi - lo) * 5 > period {
        return None;
    }
    Some(leads[leads.len() / 2])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn series(samples: &[(i64, f64)]) -> ServoSeries {
        let mut s = ServoSeries::default();
        for &(t, d) in samples {
            s.insert(t, d);
        }
        s
    }

    #[test]
    fn the_servo_is_interpolated_between_samples_and_none_outside() {
        let s = series(&[(1_000, 10.0), (2_000, 20.0), (4_000, 0.0)]);
        assert_eq!(s.at(1_000, 0.0), Some(10.0));
        assert_eq!(s.at(1_000, 500.0), Some(15.0));
        assert!((s.at(2_000, 1_000.5).unwrap() - (20.0 - 20.0 * 1_000.5 / 2_000.0)).abs() < 1e-12);
        assert_eq!(s.at(4_000, 0.0), Some(0.0));
        assert_eq!(s.at(999, 0.0), None);
        assert_eq!(s.at(4_000, 0.5), None);
        assert_eq!(s.hold(999), None);
        assert_eq!(s.hold(1_000), Some(10.0));
        assert_eq!(s.hold(3_999), Some(20.0));
        assert_eq!(s.hold(9_999), Some(0.0));
    }

    #[test]
    fn samples_out_of_order_are_sorted_and_repeats_told_apart() {
        let mut s = series(&[(3, 3.0), (1, 1.0)]);
        assert_eq!(s.insert(2, 2.0), Inserted::New);
        assert_eq!(s.insert(2, 2.0), Inserted::Duplicate);
        assert_eq!(s.insert(2, 2.5), Inserted::Replaced);
        assert_eq!((s.times_ns, s.deg), (vec![1, 2, 3], vec![1.0, 2.5, 3.0]));
    }

    const MS: i64 = 1_000_000;

    /// A stop-and-go rig: one servo message `lead` before each scan (period 100 ms, steps
    /// of 0.088°), and optionally one more after each scan.
    fn stop_and_go(lead: i64, after: bool) -> (ServoSeries, Vec<i64>) {
        let mut s = ServoSeries::default();
        let mut scans = Vec::new();
        for k in 0..60i64 {
            let t = 1_000 * MS + k * 100 * MS;
            let deg = k as f64 * 0.087890625;
            s.insert(t - lead, deg);
            if after {
                s.insert(t + 70 * MS, deg);
            }
            scans.push(t);
        }
        (s, scans)
    }

    #[test]
    fn stop_and_go_is_told_by_its_rests_or_its_messages_in_step_with_the_scans() {
        for (lead, after, why) in [
            (10 * MS, false, "in step with the scans"),
            (50 * MS, false, "in step with the scans"),
            (0, true, "rests between its steps"),
        ] {
            let (s, scans) = stop_and_go(lead, after);
            let d = classify(&s, &scans, i64::MAX, false).unwrap();
            assert_eq!(d.motion, ServoMotion::StopAndGo, "{lead}: {}", d.reason);
            assert!(d.reason.contains(why), "{}", d.reason);
        }
        // too little seen yet
        let (s, scans) = stop_and_go(10 * MS, false);
        assert_eq!(classify(&s, &scans, 2_000 * MS, false), None);
        assert!(classify(&s, &scans, 2_000 * MS, true).is_some());
    }

    #[test]
    fn a_ramp_sampled_faster_than_the_scans_is_continuous() {
        // 30°/s, JointState at 50 Hz, scans at 10 Hz
        let mut s = ServoSeries::default();
        for k in 0..100i64 {
            s.insert(k * 20 * MS, 30.0 * k as f64 * 0.02);
        }
        let scans: Vec<i64> = (0..20).map(|k| 10 * MS + k * 100 * MS).collect();
        let d = classify(&s, &scans, i64::MAX, false).unwrap();
        assert_eq!(d.motion, ServoMotion::Continuous, "{}", d.reason);
        // a servo that never moves holds its angle
        let still = series(&[(0, 5.0), (MS, 5.0)]);
        let d = classify(&still, &scans, i64::MAX, true).unwrap();
        assert_eq!(d.motion, ServoMotion::StopAndGo);
    }
}
