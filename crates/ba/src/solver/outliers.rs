//! Outliers: data snooping (Baarda) on standardized residuals, with automatic rejection.
//!
//! After each adjustment the image observation with the largest standardized residual
//! |w| (see [`super::Precision::standardized_residuals`]) is removed if |w| exceeds the
//! critical value (3.29 for a 0.1 % two-sided test), and the network is adjusted again;
//! one observation at a time, because a gross error spreads into the residuals of its
//! neighbours. A point left with fewer than two rays is dropped with its last ray.
//!
//! The statistic uses the a-priori σ of each observation (Baarda) while σ0 ≤ 1; when σ0
//! shows the a-priori σ to be optimistic (σ0 > 1), w is divided by σ0 (Pope's τ test), so
//! that a uniformly pessimistic prior does not reject good observations wholesale.

use super::{precision, solve, Options, Precision, PrecisionError, SolveError, Summary};
use crate::problem::Problem;

/// Why an observation was removed.
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

/// The result of an adjustment with data snooping.
#[derive(Clone, Debug)]
pub struct SnoopResult {
    /// Summary of the last adjustment.
    pub summary: Summary,
    /// Precision of the last adjustment.
    pub precision: Precision,
    /// What was removed, in order.
    pub rejected: Vec<Rejection>,
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
}

/// Adjusts `problem`, removing gross errors one at a time while the largest |w| exceeds
/// `critical` (at most `max_rejections`). Removed observations leave `problem`.
pub fn adjust_with_snooping(
    problem: &mut Problem,
    options: &Options,
    critical: f64,
    max_rejections: usize,
) -> Result<SnoopResult, SnoopError> {
    let mut rejected = Vec::new();
    loop {
        let summary = solve(problem, options, |_| {})?;
        let prec = precision(problem)?;
        let scale = prec.sigma0.max(1.0);
        let worst = prec
            .standardized_residuals
            .iter()
            .enumerate()
            .filter_map(|(o, w)| {
                let m = w[0].abs().max(w[1].abs()) / scale;
                m.is_finite().then_some((o, m))
            })
            .max_by(|a, b| a.1.total_cmp(&b.1));
        match worst {
            Some((o, m)) if m > critical && rejected.len() < max_rejections => {
                let ob = problem.observations[o];
                let w = prec.standardized_residuals[o];
                rejected.push(Rejection {
                    image: problem.images[ob.image].name.clone(),
                    point: problem.points[ob.point].name.clone(),
                    uv: [ob.uv.x, ob.uv.y],
                    w,
                    reason: if scale > 1.0 {
                        format!(
                            "standardized residual {m:.2} (÷ sigma0 {scale:.3}) > {critical:.2}"
                        )
                    } else {
                        format!("standardized residual {m:.2} > {critical:.2}")
                    },
                });
                problem.observations.remove(o);
                // A point with a single ray left is not determined: drop that ray too.
                let rays: Vec<usize> = (0..problem.observations.len())
                    .filter(|&k| problem.observations[k].point == ob.point)
                    .collect();
                if rays.len() == 1 && !problem.points[ob.point].held().iter().any(|h| *h) {
                    let last = problem.observations.remove(rays[0]);
                    rejected.push(Rejection {
                        image: problem.images[last.image].name.clone(),
                        point: problem.points[last.point].name.clone(),
                        uv: [last.uv.x, last.uv.y],
                        w: [f64::NAN; 2],
                        reason: "the point's other rays were rejected: a single ray does not determine it".into(),
                    });
                }
            }
            _ => {
                return Ok(SnoopResult {
                    summary,
                    precision: prec,
                    rejected,
                })
            }
        }
    }
}
