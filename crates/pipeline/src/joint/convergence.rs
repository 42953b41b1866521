//! Convergence: how the final adjustment converged, and whether a second start from a
//! perturbed solution reaches the same minimum ([`SECOND_START_Z`], [`SAME_MINIMUM_Z`]).

use super::estimability::Rows;
use super::problem::Joint;
use crate::context::{PipelineError, Result};
use pingcal_ba::solver::{self, Precision};
use pingcal_ba::Problem;

/// How far the second start moves the solution: every extrinsic and free mount unknown by
/// this many of its σ's (random signs). Far enough that a solver that stopped short would
/// stop elsewhere; near enough that the beams on the balls stay those of the solution (a
/// start a ball's radius off leaves beams beside the ball, clamped, and their own small
/// minimum: [`pingcal_lrf::beam::GRAZING_KAPPA`]). A start far off is what the starts of
/// the pipeline try (the room's mount, the project's) and the absurdity test judges.
pub const SECOND_START_Z: f64 = 3.0;

/// Two solutions are the same minimum when no extrinsic or mount unknown differs by more
/// than this many of its σ's: within the result's own uncertainty, judged on the largest of
/// up to 14 unknowns. (The solver's tolerances leave far less; a beam that grazes its ball
/// at one solution and not at the other makes a kink in the cost, and nearby minima a few
/// tenths of a σ apart — 1.0 σ in the half-sweep test project and the stress study's one
/// doubtful run, with χ²/2 1.6 apart of 3,800 — which that σ covers. Distinct minima of a
/// wrong start lie many σ apart.)
pub const SAME_MINIMUM_Z: f64 = 2.0;

/// How the final adjustment converged, and whether a second start reached its minimum.
#[derive(Clone, Debug, Default)]
pub struct Convergence {
    /// Why the solver stopped (its gradient, step or cost-change test), in words.
    pub termination: String,
    /// Whether that is convergence (not the iteration limit or a trust region that shrank).
    pub converged: bool,
    /// Iterations of that adjustment.
    pub iterations: usize,
    /// The gradient's largest component at the solution (whitened units).
    pub gradient_max_norm: f64,
    /// ½χ² of the solution and of the second start's (whitened units).
    pub cost: (f64, f64),
    /// The largest difference between the two solutions' extrinsic and mount unknowns, in
    /// σ's of the first.
    pub max_difference_z: f64,
    /// Whether the second start reached the same minimum ([`SAME_MINIMUM_Z`]).
    pub same_minimum: bool,
    /// The second start found a lower minimum, which is the one given.
    pub second_lower: bool,
}

impl Convergence {
    /// One line for logs and notes.
    pub fn describe(&self) -> String {
        format!(
            "{} after {} iterations (largest gradient component {:.2e}); a second start from the solution moved by {} σ in every extrinsic and mount unknown reached {} (χ²/2 {:.3} against {:.3}, largest difference {:.3} σ)",
            self.termination,
            self.iterations,
            self.gradient_max_norm,
            SECOND_START_Z,
            if self.same_minimum {
                "the same minimum"
            } else if self.second_lower {
                "a lower minimum, which is given"
            } else {
                "another, higher minimum"
            },
            self.cost.0,
            self.cost.1,
            self.max_difference_z
        )
    }

    /// Why the result is doubtful, if it is: no convergence, or another minimum.
    pub fn doubt(&self) -> Option<String> {
        if !self.converged {
            Some(format!(
                "the joint adjustment did not converge ({})",
                self.termination
            ))
        } else if !self.same_minimum {
            Some(format!(
                "a second start of the joint adjustment from a perturbed solution reached {} (χ²/2 {:.3} against {:.3}, unknowns {:.1} σ apart): the minimum is not unique within the start's error",
                if self.second_lower { "a lower minimum, which is given" } else { "another minimum" },
                self.cost.0,
                self.cost.1,
                self.max_difference_z
            ))
        } else {
            None
        }
    }
}

/// The second start (see [`SECOND_START_Z`]) and what it found; `better` is the solution to
/// give: the first one polished, or the second's when it found a lower minimum.
pub(super) struct SecondStart {
    pub summary: Convergence,
    pub better: Problem,
}

/// Starts the solved joint problem `p` (precision `prec`, free mount components `free`)
/// again from a perturbed solution and compares the minimum it reaches.
pub(super) fn second_start(
    joint: &Joint,
    p: &Problem,
    prec: &Precision,
    free: &[bool; 8],
    seed: u64,
) -> Result<SecondStart> {
    let rows = Rows::of(&joint.keys, prec);
    let q = perturbed(joint, p, prec, (rows, free), seed);
    // both solved to the solver's tightest tolerances: the first solution is polished (it
    // was near), the second started afresh
    let tight = solver::Options {
        function_tolerance: 1e-12,
        parameter_tolerance: 1e-12,
        max_iterations: 200,
        ..joint.options.clone()
    };
    let solve = |p: &mut Problem| {
        solver::solve(p, &tight, |_| {})
            .map_err(|e| PipelineError::Adjustment(format!("joint adjustment: {e}")))
    };
    let mut q = q;
    let summary2 = solve(&mut q)?;
    let mut p1 = p.clone();
    let summary1 = solve(&mut p1)?;
    let last = joint.last.as_ref();
    let (cost1, cost2) = (summary1.final_cost, summary2.final_cost);
    let z = largest_difference(joint, (&p1, &q), prec, (rows, free));
    let same = z <= SAME_MINIMUM_Z;
    let lower = !same && cost2 < cost1;
    let summary = Convergence {
        termination: summary1.termination.to_string(),
        converged: !matches!(
            summary1.termination,
            solver::Termination::MaxIterations | solver::Termination::TrustRegionTooSmall
        ),
        iterations: last.map_or(0, |s| s.iterations) + summary1.iterations,
        gradient_max_norm: (summary1.log.last()).map_or(f64::NAN, |i| i.gradient_max_norm),
        cost: (cost1, cost2),
        max_difference_z: z,
        same_minimum: same,
        second_lower: lower,
    };
    Ok(SecondStart {
        summary,
        better: if lower { q } else { p1 },
    })
}

/// `p` with every extrinsic and free mount unknown (and the servo time offset, when it is
/// estimated) moved by [`SECOND_START_Z`] of its σ in `prec`, with random signs (`seed`).
fn perturbed(
    joint: &Joint,
    p: &Problem,
    prec: &Precision,
    (rows, free): (Rows, &[bool; 8]),
    seed: u64,
) -> Problem {
    use rand::Rng;
    let mut g = pingcal_geometry::consensus::rng(seed ^ 0x5ec0_57a7);
    let cov = &prec.parameters_covariance;
    let mut step = |k: usize| {
        let sign = if g.random_bool(0.5) { 1.0 } else { -1.0 };
        sign * SECOND_START_Z * cov[(k, k)].max(0.0).sqrt()
    };
    let ext_delta: Vec<f64> = (0..6).map(|k| step(rows.ext(k))).collect();
    let delta: Vec<f64> = (0..8)
        .map(|k| if free[k] { step(rows.mount(k)) } else { 0.0 })
        .collect();
    let tau = joint.time_offset.as_ref().filter(|t| t.free());
    let tau_delta = tau.map(|t| step(prec.parameter_offsets[t.block.0]));
    let mut q = p.clone();
    q[joint.keys.extrinsic].plus(&ext_delta);
    q[joint.keys.mount].plus(&delta);
    if let (Some(t), Some(d)) = (tau, tau_delta) {
        q[t.block].plus(&[d]);
    }
    q
}

/// The largest difference between the extrinsic, free mount and time offset unknowns of
/// the two solutions `p` and `q`, in σ's of `prec`.
fn largest_difference(
    joint: &Joint,
    (p, q): (&Problem, &Problem),
    prec: &Precision,
    (rows, free): (Rows, &[bool; 8]),
) -> f64 {
    let cov = &prec.parameters_covariance;
    let (e1, t1) = joint.solution(p);
    let (e2, t2) = joint.solution(q);
    let dr = pingcal_geometry::log_so3(&(e2.rotation * e1.rotation.transpose()));
    let dt = e2.translation - e1.translation;
    let mut z: f64 = 0.0;
    for k in 0..6 {
        let d = if k < 3 { dr[k] } else { dt[k - 3] };
        let i = rows.ext(k);
        z = z.max(d.abs() / cov[(i, i)].max(1e-30).sqrt());
    }
    for k in (0..8).filter(|&k| free[k]) {
        let i = rows.mount(k);
        z = z.max((t2[k] - t1[k]).abs() / cov[(i, i)].max(1e-30).sqrt());
    }
    if let Some(t) = joint.time_offset.as_ref().filter(|t| t.free()) {
        let i = prec.parameter_offsets[t.block.0];
        z = z.max((joint.tau(q) - joint.tau(p)).abs() / cov[(i, i)].max(1e-30).sqrt());
    }
    z
}
