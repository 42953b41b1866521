//! Outliers: data snooping (Baarda) on standardized residuals, with automatic rejection.
//!
//! After each adjustment the observation with the largest standardized residual |w| (see
//! [`super::Precision::standardized_residuals`], [`super::Precision::distance_standardized`]
//! and [`super::Precision::control_standardized`]) is removed if |w| exceeds the critical
//! value (3.29 for a 0.1 % two-sided test), and the network is adjusted again; one
//! observation at a time, because a gross error spreads into the residuals of its
//! neighbours. Every kind of observation takes part in the one comparison — image points,
//! measured distances, weighted control points — so that a wrong distance is named as the
//! blunder it is rather than the image points of its targets, whose residuals show only
//! the share of its error that the network passes on to them. An observation of several
//! components (an image point's u and v, a control point's X, Y and Z) is judged by its
//! largest |w| and removed whole. A point left with fewer than two rays is dropped with its
//! last ray.
//!
//! The statistic uses the a-priori σ of each observation (Baarda) while σ0 ≤ 1; when σ0
//! shows the a-priori σ to be optimistic (σ0 > 1), w is divided by σ0 (Pope's τ test), so
//! that a uniformly pessimistic prior does not reject good observations wholesale.

use super::{precision, solve, Options, Precision, PrecisionError, SolveError, Summary};
use crate::keys::PointKey;
use crate::problem::Problem;

/// An image point removed as a gross error.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Rejection {
    /// Image name.
    pub image: String,
    /// Point name.
    pub point: String,
    /// Measured pixel coordinates.
    pub uv: [f64; 2],
    /// Standardized residuals (u, v) when it was removed.
    pub w: [f64; 2],
    /// Reason in words.
    pub reason: String,
}

/// A measured distance ([`crate::problem::Distance`]) removed as a gross error.
#[derive(Clone, Debug, serde::Serialize)]
pub struct DistanceRejection {
    /// One end: the point's name.
    pub a: String,
    /// The other end: the point's name.
    pub b: String,
    /// The distance given (the measurement), in the object-space unit.
    pub given: f64,
    /// Its a-priori standard deviation.
    pub sigma: f64,
    /// The distance between the two points as the adjustment without it puts them.
    pub estimated: f64,
    /// Its standardized residual when it was removed.
    pub w: f64,
    /// Reason in words.
    pub reason: String,
}

/// A weighted control point ([`crate::problem::PointPrior`]) removed as a gross error.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ControlRejection {
    /// The point's name.
    pub point: String,
    /// The coordinates given (the measurement).
    pub given: [f64; 3],
    /// Their a-priori standard deviations.
    pub sigma: [f64; 3],
    /// The point's coordinates as the adjustment without the control puts it.
    pub estimated: [f64; 3],
    /// Its standardized residuals (X, Y, Z) when it was removed.
    pub w: [f64; 3],
    /// Reason in words.
    pub reason: String,
}

/// The result of an adjustment with data snooping.
#[derive(Clone, Debug)]
pub struct SnoopResult {
    /// Summary of the last adjustment.
    pub summary: Summary,
    /// Precision of the last adjustment.
    pub precision: Precision,
    /// Image points removed, in order.
    pub rejected: Vec<Rejection>,
    /// Distances removed, in order.
    pub rejected_distances: Vec<DistanceRejection>,
    /// Control points removed, in order.
    pub rejected_control_points: Vec<ControlRejection>,
}

/// An adjustment with data snooping failed.
#[derive(Debug, thiserror::Error)]
pub enum SnoopError {
    /// The adjustment failed.
    #[error(transparent)]
    Solve(#[from] SolveError),
    /// The precision (needed for the test statistics) could not be computed.
    #[error(transparent)]
    Precision(#[from] PrecisionError),
    /// The distance or control point that data snooping found to be the worst observation
    /// was needed for the datum: without it the network has a datum defect.
    #[error("data snooping finds {what} to be a gross error, but without it {defect}: check the value given")]
    DatumLost {
        /// The observation, in words, with its value and w.
        what: String,
        /// The datum defect left without it.
        defect: String,
    },
}

/// The observation whose |w| is largest: its kind and index in the problem.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Worst {
    /// [`Problem::observations`]`[o]`.
    Image(usize),
    /// [`Problem::distances`]`[k]`.
    Distance(usize),
    /// [`Problem::point_priors`]`[k]`.
    Control(usize),
}

/// How many observations data snooping may remove ([`adjust_with_snooping_limited`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SnoopLimits {
    /// Observations of every kind together.
    pub total: usize,
    /// Distances and control points together: once this many are removed, the others are no
    /// longer tested (a typo is one value; several values of the object that disagree with
    /// the network are not typos, and whether they are is for the caller to judge, e.g. from
    /// their w's in the result's precision).
    pub distances_and_control: usize,
}

/// The largest |w| of every kind of observation, divided by `scale` (σ0 when above 1); the
/// distances and control points only when `object` (they may still be removed).
fn worst(prec: &Precision, scale: f64, object: bool) -> Option<(Worst, f64)> {
    let largest = |w: &[f64]| w.iter().fold(f64::NAN, |m, x| m.max(x.abs()));
    let images = (prec.standardized_residuals.iter().enumerate())
        .map(|(o, w)| (Worst::Image(o), largest(w)));
    let distances = (prec.distance_standardized.iter().enumerate())
        .map(|(k, w)| (Worst::Distance(k), w.abs()))
        .filter(|_| object);
    let control = (prec.control_standardized.iter().enumerate())
        .map(|(k, w)| (Worst::Control(k), largest(w)))
        .filter(|_| object);
    images
        .chain(distances)
        .chain(control)
        .filter_map(|(o, m)| {
            let m = m / scale;
            m.is_finite().then_some((o, m))
        })
        .max_by(|a, b| a.1.total_cmp(&b.1))
}

/// What was removed, with the keys of the distances' ends and of the control points, whose
/// estimates are read from the problem at the end.
#[derive(Default)]
struct Removed {
    images: Vec<Rejection>,
    distances: Vec<(DistanceRejection, PointKey, PointKey)>,
    control: Vec<(ControlRejection, PointKey)>,
    /// The kind of the last removal.
    last: Option<Worst>,
}

impl Removed {
    fn len(&self) -> usize {
        self.images.len() + self.distances.len() + self.control.len()
    }

    /// The last observation removed, in words, when it was a distance or a control point
    /// (an observation that may take part in the datum).
    fn last_datum_observation(&self) -> Option<String> {
        match self.last {
            Some(Worst::Distance(_)) => self.distances.last().map(|(d, ..)| {
                format!(
                    "the distance {} – {} given as {} (w = {:.1})",
                    d.a, d.b, d.given, d.w
                )
            }),
            Some(Worst::Control(_)) => self.control.last().map(|(c, _)| {
                format!(
                    "control point {} given at ({}, {}, {}) (w = {:.1})",
                    c.point,
                    c.given[0],
                    c.given[1],
                    c.given[2],
                    c.w.iter().fold(0.0f64, |m, x| m.max(x.abs()))
                )
            }),
            _ => None,
        }
    }

    /// Removes observation `what` from `problem` and records it.
    fn remove(&mut self, problem: &mut Problem, prec: &Precision, what: Worst, reason: String) {
        self.last = Some(what);
        match what {
            Worst::Image(o) => {
                self.remove_image(problem, o, prec.standardized_residuals[o], reason)
            }
            Worst::Distance(k) => {
                let d = problem.distances.remove(k);
                self.distances.push((
                    DistanceRejection {
                        a: problem.points[d.a].name.clone(),
                        b: problem.points[d.b].name.clone(),
                        given: d.value,
                        sigma: d.sigma,
                        estimated: f64::NAN,
                        w: prec.distance_standardized[k],
                        reason,
                    },
                    d.a,
                    d.b,
                ));
            }
            Worst::Control(k) => {
                let c = problem.point_priors.remove(k);
                self.control.push((
                    ControlRejection {
                        point: problem.points[c.point].name.clone(),
                        given: c.position.into(),
                        sigma: c.sigma.into(),
                        estimated: [f64::NAN; 3],
                        w: prec.control_standardized[k],
                        reason,
                    },
                    c.point,
                ));
            }
        }
    }

    /// Removes image observation `o`, and the point's last ray with it when only one is
    /// left (a single ray does not determine a point that is not held).
    fn remove_image(&mut self, problem: &mut Problem, o: usize, w: [f64; 2], reason: String) {
        let ob = problem.observations.remove(o);
        self.images.push(Rejection {
            image: problem.images[ob.image].name.clone(),
            point: problem.points[ob.point].name.clone(),
            uv: [ob.uv.x, ob.uv.y],
            w,
            reason,
        });
        let rays: Vec<usize> = (0..problem.observations.len())
            .filter(|&k| problem.observations[k].point == ob.point)
            .collect();
        if rays.len() == 1 && !problem.points[ob.point].held().iter().any(|h| *h) {
            let last = problem.observations.remove(rays[0]);
            self.images.push(Rejection {
                image: problem.images[last.image].name.clone(),
                point: problem.points[last.point].name.clone(),
                uv: [last.uv.x, last.uv.y],
                w: [f64::NAN; 2],
                reason: "the point's other rays were rejected: a single ray does not determine it"
                    .into(),
            });
        }
    }

    /// The result, with the estimates of the removed distances and control points read
    /// from the adjusted `problem`.
    fn finish(self, problem: &Problem, summary: Summary, precision: Precision) -> SnoopResult {
        let at = |p: PointKey| problem.points[p].position;
        SnoopResult {
            summary,
            precision,
            rejected: self.images,
            rejected_distances: (self.distances.into_iter())
                .map(|(r, a, b)| DistanceRejection {
                    estimated: (at(a) - at(b)).norm(),
                    ..r
                })
                .collect(),
            rejected_control_points: (self.control.into_iter())
                .map(|(r, p)| ControlRejection {
                    estimated: at(p).into(),
                    ..r
                })
                .collect(),
        }
    }
}

/// Adjusts `problem`, removing gross errors one at a time while the largest |w| over every
/// kind of observation exceeds `critical` (at most `max_rejections`). Removed observations
/// leave `problem`.
pub fn adjust_with_snooping(
    problem: &mut Problem,
    options: &Options,
    critical: f64,
    max_rejections: usize,
) -> Result<SnoopResult, SnoopError> {
    let limits = SnoopLimits {
        total: max_rejections,
        distances_and_control: usize::MAX,
    };
    adjust_with_snooping_limited(problem, options, critical, limits)
}

/// [`adjust_with_snooping`] removing at most `limits.distances_and_control` distances and
/// control points.
pub fn adjust_with_snooping_limited(
    problem: &mut Problem,
    options: &Options,
    critical: f64,
    limits: SnoopLimits,
) -> Result<SnoopResult, SnoopError> {
    let mut removed = Removed::default();
    loop {
        let summary = solve(problem, options, |_| {})?;
        let prec = match (precision(problem), removed.last_datum_observation()) {
            (Err(PrecisionError::DatumDefect(defect)), Some(what)) => {
                return Err(SnoopError::DatumLost { what, defect })
            }
            (p, _) => p?,
        };
        let scale = prec.sigma0.max(1.0);
        let object = removed.distances.len() + removed.control.len() < limits.distances_and_control;
        match worst(&prec, scale, object) {
            Some((what, m)) if m > critical && removed.len() < limits.total => {
                let reason = if scale > 1.0 {
                    format!("standardized residual {m:.2} (÷ sigma0 {scale:.3}) > {critical:.2}")
                } else {
                    format!("standardized residual {m:.2} > {critical:.2}")
                };
                removed.remove(problem, &prec, what, reason);
            }
            _ => return Ok(removed.finish(problem, summary, prec)),
        }
    }
}
