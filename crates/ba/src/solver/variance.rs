//! Variance components of groups of observations (Förstner 1979, "Ein Verfahren zur
//! Schätzung von Varianz- und Kovarianzkomponenten"; Koch, *Parameter Estimation and
//! Hypothesis Testing in Linear Models*, § 3.6).
//!
//! One σ0 for a whole network is right only when every group of observations (image points
//! of one kind, distances) has the right a-priori σ *relative to the others*. When one group
//! is weighted too pessimistically, the common σ0 falls below 1 and scales down the
//! covariance of everything, also of what another, honestly weighted group determines.
//! Each group `g` has its own estimate
//!
//! `σ̂0_g² = Σ_{i∈g} vᵢ² pᵢ / r_g`, `r_g = Σ_{i∈g} rᵢ` (its redundancy numbers
//! [`Precision::redundancy_numbers`], which add up to the network's redundancy),
//!
//! and [`estimate_variance_components`] re-weights each group by it and adjusts again until
//! every estimated group's σ0 is 1 (Förstner's iteration; at convergence it is Helmert's
//! estimate). A group whose redundancy is below [`MIN_GROUP_REDUNDANCY`] keeps its a-priori
//! σ: its σ0 is reported, but with so few degrees of freedom it is too uncertain to weight
//! by (the relative standard error of a σ0 from r degrees of freedom is about `1/√(2r)`).

use super::{precision, solve, Options, Precision, PrecisionError, SolveError};
use crate::problem::Problem;

/// Groups with less redundancy than this are not re-weighted (the relative standard error
/// of their σ0 would exceed `1/√60 ≈ 13 %`).
pub const MIN_GROUP_REDUNDANCY: f64 = 30.0;

/// Förstner's iteration stops when every re-weighted group's σ0 is within this of 1.
pub const VCE_TOLERANCE: f64 = 1e-3;

/// Most re-weighting rounds.
pub const VCE_MAX_ROUNDS: usize = 20;

/// One group's variance component.
#[derive(Clone, Debug, serde::Serialize)]
pub struct VarianceComponent {
    /// The group's name.
    pub group: String,
    /// Scalar observations in it (two per image point).
    pub observations: usize,
    /// Its share of the redundancy (sum of its redundancy numbers).
    pub redundancy: f64,
    /// Its σ0 relative to the a-priori σ's the caller gave: the factor by which they were
    /// too large (< 1) or too small (> 1).
    pub sigma0: f64,
    /// Whether its observations were re-weighted by it (false: too little redundancy, the
    /// a-priori σ's are kept).
    pub reweighted: bool,
}

/// The groups' σ0 at the current estimate and weights: image observation `o` is in group
/// `group_of[o]` (named `names[group_of[o]]`); the distances, if any, are one more group
/// named `distances`, and the residuals of [`Problem::residuals`] one group per
/// [`crate::residual::Residual::group`] name. Control-point priors are in none.
pub fn variance_components(
    problem: &Problem,
    precision: &Precision,
    group_of: &[usize],
    names: &[&str],
) -> Vec<VarianceComponent> {
    let k = names.len();
    let extra = residual_groups(problem);
    let groups = k + 1 + extra.len();
    let (mut vpv, mut red, mut n) = (vec![0.0; groups], vec![0.0; groups], vec![0usize; groups]);
    for (o, ob) in problem.observations.iter().enumerate() {
        let g = group_of[o];
        if let Some(r) = problem.residual(ob) {
            vpv[g] += (r / ob.sigma).norm_squared();
        }
        red[g] += precision.redundancy_numbers[o][0] + precision.redundancy_numbers[o][1];
        n[g] += 2;
    }
    for (d, r) in problem
        .distances
        .iter()
        .zip(&precision.distance_redundancy_numbers)
    {
        let l = (problem.points[d.a].position - problem.points[d.b].position).norm();
        vpv[k] += ((l - d.value) / d.sigma).powi(2);
        red[k] += r;
        n[k] += 1;
    }
    for (rb, q) in problem
        .residuals
        .iter()
        .zip(&precision.residual_redundancy_numbers)
    {
        let g = k
            + 1
            + extra
                .iter()
                .position(|e| e == rb.residual.group())
                .unwrap_or(0);
        let r = super::evaluate::constraint_residual(problem, &*rb.residual, rb.sigma_scale, None);
        vpv[g] += r.map_or(0.0, |r| r.r.iter().map(|v| v * v).sum());
        red[g] += q.iter().sum::<f64>();
        n[g] += q.len();
    }
    names
        .iter()
        .copied()
        .chain(std::iter::once("distances"))
        .chain(extra.iter().map(String::as_str))
        .enumerate()
        .filter(|&(g, _)| n[g] > 0)
        .map(|(g, name)| VarianceComponent {
            group: name.to_string(),
            observations: n[g],
            redundancy: red[g],
            sigma0: if red[g] > 0.0 {
                (vpv[g] / red[g]).sqrt()
            } else {
                f64::NAN
            },
            reweighted: red[g] >= MIN_GROUP_REDUNDANCY,
        })
        .collect()
}

/// The distinct group names of [`Problem::residuals`], in the order they first appear.
fn residual_groups(problem: &Problem) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for rb in &problem.residuals {
        let g = rb.residual.group();
        if !out.iter().any(|e| e == g) {
            out.push(g.to_string());
        }
    }
    out
}

/// Why the variance components could not be estimated.
#[derive(Debug, thiserror::Error)]
pub enum VarianceError {
    /// An adjustment failed.
    #[error(transparent)]
    Solve(#[from] SolveError),
    /// The precision failed.
    #[error(transparent)]
    Precision(#[from] PrecisionError),
}

/// The outcome of [`estimate_variance_components`].
#[derive(Clone, Debug)]
pub struct VarianceEstimate {
    /// Each group's σ0 relative to its a-priori σ's (the product over the rounds).
    pub components: Vec<VarianceComponent>,
    /// The network's σ0 with the a-priori σ's (the first round): what a χ² test of the
    /// a-priori model judges.
    pub sigma0_a_priori: f64,
    /// The precision at the final estimate and weights (its σ0 about 1).
    pub precision: Precision,
    /// Solver iterations over all rounds.
    pub iterations: usize,
}

/// Adjusts `problem` with Förstner's re-weighting of its groups (see the module doc): the
/// image observations by `group_of` (names `names`), the distances as one group, the residuals by their group name. The σ's of
/// the re-weighted groups' observations in `problem` end multiplied by their group's σ0, so
/// that the returned precision (σ0-scaled, its σ0 then about 1) has each group weighted by
/// its own estimate.
pub fn estimate_variance_components(
    problem: &mut Problem,
    options: &Options,
    group_of: &[usize],
    names: &[&str],
) -> Result<VarianceEstimate, VarianceError> {
    let mut total: Option<Vec<VarianceComponent>> = None;
    let mut sigma0_a_priori = f64::NAN;
    let mut iterations = 0;
    for _ in 0..VCE_MAX_ROUNDS {
        iterations += solve(problem, options, |_| {})?.iterations;
        let prec = precision(problem)?;
        if sigma0_a_priori.is_nan() {
            sigma0_a_priori = prec.sigma0;
        }
        let comps = variance_components(problem, &prec, group_of, names);
        let total = total.get_or_insert_with(|| {
            comps
                .iter()
                .map(|c| VarianceComponent {
                    sigma0: 1.0,
                    ..c.clone()
                })
                .collect()
        });
        let done = comps
            .iter()
            .all(|c| !c.reweighted || (c.sigma0 - 1.0).abs() < VCE_TOLERANCE);
        for (t, c) in total.iter_mut().zip(&comps) {
            t.redundancy = c.redundancy;
            if t.reweighted {
                t.sigma0 *= c.sigma0;
            } else {
                t.sigma0 = c.sigma0;
            }
        }
        if done {
            return Ok(VarianceEstimate {
                components: total.clone(),
                sigma0_a_priori,
                precision: prec,
                iterations,
            });
        }
        let factor = |name: &str| {
            comps
                .iter()
                .find(|c| c.group == name && c.reweighted && c.sigma0.is_finite() && c.sigma0 > 0.0)
                .map_or(1.0, |c| c.sigma0)
        };
        let f: Vec<f64> = names.iter().map(|n| factor(n)).collect();
        for (o, ob) in problem.observations.iter_mut().enumerate() {
            ob.sigma *= f[group_of[o]];
        }
        let fd = factor("distances");
        for d in &mut problem.distances {
            d.sigma *= fd;
        }
        for rb in &mut problem.residuals {
            rb.sigma_scale *= factor(rb.residual.group());
        }
    }
    // not converged in VCE_MAX_ROUNDS: the last weights, adjusted once more
    iterations += solve(problem, options, |_| {})?.iterations;
    Ok(VarianceEstimate {
        components: total.unwrap_or_default(),
        sigma0_a_priori,
        precision: precision(problem)?,
        iterations,
    })
}
