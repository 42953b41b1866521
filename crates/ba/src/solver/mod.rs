//! Levenberg–Marquardt with the Schur complement.
//!
//! The trust-region strategy is Ceres' Levenberg–Marquardt: the damped system
//! `(JᵀJ + D/μ) δ = −Jᵀr` with D the diagonal of JᵀJ clamped to [1e-6, 1e32], the step
//! accepted when the ratio ρ of actual to predicted cost decrease exceeds 1e-3, and the
//! radius μ updated by `μ ← μ / max(1/3, 1 − (2ρ − 1)³)` on success, `μ ← μ/ν, ν ← 2ν` on
//! failure. Convergence is declared by the same three tests as Ceres (function, gradient
//! and parameter tolerance), so that both stop at the same point on the same problem.
//!
//! Each iteration: evaluate residuals and Jacobians (`evaluate`) in parallel; eliminate
//! the points (`schur`); factorize the reduced camera system (`linear`) with a
//! symbolic factorization computed once (`layout`); back-substitute the points.

mod choice;
pub mod clusters;
mod constraints;
mod estimability;
mod evaluate;
mod free_network;
mod iterative;
mod layout;
mod linear;
mod outliers;
mod precision;
mod schur;
mod selected_inverse;
mod sigma;
mod variance;

pub use choice::{available_memory, ProductChoice, SchurProduct, SolverChoice, TooLarge};
pub use clusters::{ClusterStats, DEFAULT_MAX_DIM as DEFAULT_CLUSTER_DIM};
pub use estimability::{check_intrinsics, Estimability, MAX_CHECK_UNKNOWNS, NULL_EIGENVALUE};
pub use free_network::MAX_FREE_NETWORK_UNKNOWNS;
pub use iterative::{CgOptions, Preconditioner};
pub use linear::LinearSolverKind;
pub use outliers::{
    adjust_with_snooping, adjust_with_snooping_limited, ControlRejection, DistanceRejection,
    Rejection, SnoopError, SnoopLimits, SnoopResult,
};
pub use precision::{
    free_network_precision_bordered, points_covariance, points_covariance_with, precision,
    precision_with, CofactorMethod,
};
pub use selected_inverse::MAX_SELECTED_WORK;
pub use sigma::{IntrinsicsPrecision, PoseSigma, Precision, PrecisionError, MAX_DENSE_PRECISION};
pub use variance::{
    estimate_variance_components, variance_components, VarianceComponent, VarianceError,
    VarianceEstimate, MIN_GROUP_REDUNDANCY, VCE_MAX_ROUNDS, VCE_TOLERANCE,
};

use crate::problem::{Problem, ProblemError};
use layout::Layout;
use nalgebra::Vector3;
use pingcal_geometry::log_so3;
use rayon::prelude::*;
use std::time::Instant;

/// Options of the solver. The defaults are Ceres' defaults.
#[derive(Clone, Debug)]
pub struct Options {
    /// Most LM iterations (accepted and rejected steps).
    pub max_iterations: usize,
    /// Stop when |Δcost| ≤ function_tolerance · cost after an accepted step.
    pub function_tolerance: f64,
    /// Stop when max |Jᵀr| ≤ gradient_tolerance.
    pub gradient_tolerance: f64,
    /// Stop when |δ| ≤ parameter_tolerance · (|x| + parameter_tolerance).
    pub parameter_tolerance: f64,
    /// Initial trust-region radius μ (the damping is 1/μ).
    pub initial_trust_region_radius: f64,
    /// Largest trust-region radius.
    pub max_trust_region_radius: f64,
    /// Stop when the radius falls below this.
    pub min_trust_region_radius: f64,
    /// Solver of the reduced camera system (`Auto`: chosen by its structure, see
    /// [`SolverChoice`]).
    pub linear_solver: LinearSolverKind,
    /// The conjugate-gradient solve of the iterative solver.
    pub cg: CgOptions,
    /// Memory the linear algebra may use, bytes (`None`: 80 % of what the system reports
    /// available, or no limit where it reports nothing).
    pub memory_limit_bytes: Option<f64>,
    /// Worker threads (0: all cores).
    pub threads: usize,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            max_iterations: 50,
            function_tolerance: 1e-6,
            gradient_tolerance: 1e-10,
            parameter_tolerance: 1e-8,
            initial_trust_region_radius: 1e4,
            max_trust_region_radius: 1e16,
            min_trust_region_radius: 1e-32,
            linear_solver: LinearSolverKind::Auto,
            cg: CgOptions::default(),
            memory_limit_bytes: None,
            threads: 0,
        }
    }
}

/// Why the solver stopped.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Termination {
    /// The relative cost change of an accepted step fell below the function tolerance.
    FunctionTolerance,
    /// The gradient's max-norm fell below the gradient tolerance.
    GradientTolerance,
    /// The step fell below the parameter tolerance.
    ParameterTolerance,
    /// The iteration limit was reached.
    MaxIterations,
    /// The trust region shrank below its minimum: no step decreases the cost.
    TrustRegionTooSmall,
}

impl std::fmt::Display for Termination {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Termination::FunctionTolerance => {
                "converged: relative cost change below the function tolerance"
            }
            Termination::GradientTolerance => "converged: gradient below the gradient tolerance",
            Termination::ParameterTolerance => "converged: step below the parameter tolerance",
            Termination::MaxIterations => "stopped: iteration limit reached",
            Termination::TrustRegionTooSmall => {
                "stopped: trust region too small, no step decreases the cost"
            }
        })
    }
}

/// One iteration, as the per-iteration log shows it.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Iteration {
    /// Iteration number (1-based).
    pub iteration: usize,
    /// Cost after this iteration (½ Σ ρ).
    pub cost: f64,
    /// Cost decrease achieved (0 for a rejected step).
    pub cost_change: f64,
    /// Max-norm of the gradient at the start of the iteration.
    pub gradient_max_norm: f64,
    /// Norm of the step.
    pub step_norm: f64,
    /// Ratio of actual to predicted decrease.
    pub relative_decrease: f64,
    /// Trust-region radius used.
    pub trust_region_radius: f64,
    /// Whether the step was accepted.
    pub accepted: bool,
    /// Time in the linear solver, seconds.
    pub linear_solver_time_s: f64,
    /// Conjugate-gradient iterations (0 for a direct solver).
    pub linear_iterations: usize,
    /// Wall time of the iteration, seconds.
    pub iteration_time_s: f64,
}

/// What the solver did.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Summary {
    /// Cost ½ Σ ρ at the start.
    pub initial_cost: f64,
    /// Cost at the end.
    pub final_cost: f64,
    /// LM iterations (accepted + rejected).
    pub iterations: usize,
    /// Accepted steps.
    pub successful_steps: usize,
    /// Why it stopped.
    pub termination: Termination,
    /// Wall time, seconds.
    pub time_s: f64,
    /// Time in the linear solver, seconds.
    pub linear_solver_time_s: f64,
    /// Time evaluating residuals and Jacobians (and the cost of trial steps), seconds.
    pub evaluation_time_s: f64,
    /// Time forming the Schur complement and back-substituting, seconds.
    pub schur_time_s: f64,
    /// Time setting up (block structure, ordering, symbolic factorization), seconds.
    pub setup_time_s: f64,
    /// Whether the dense path was used.
    pub dense: bool,
    /// The solver of the reduced system that ran, and why it was chosen.
    pub linear_solver: SolverChoice,
    /// Conjugate-gradient iterations over all steps (0 for a direct solver).
    pub linear_iterations: usize,
    /// The clusters of the cluster-Jacobi preconditioner, when the conjugate gradients ran
    /// with it.
    pub clusters: Option<ClusterStats>,
    /// How the conjugate gradients applied S, when they ran (from the start: a move to a
    /// factorization is in `linear_solver`).
    pub schur_product: Option<ProductChoice>,
    /// Dimension of the reduced camera system.
    pub reduced_dimension: usize,
    /// Stored entries of its upper triangle.
    pub reduced_nonzeros: usize,
    /// Per-iteration log.
    pub log: Vec<Iteration>,
}

/// Why the solver could not run.
#[derive(Debug, thiserror::Error)]
pub enum SolveError {
    /// The problem is malformed.
    #[error(transparent)]
    Problem(#[from] ProblemError),
    /// The linear algebra could not be set up.
    #[error("{0}")]
    Setup(String),
    /// The solver asked for needs more memory than there is.
    #[error(transparent)]
    TooLarge(#[from] TooLarge),
}

/// Adjusts `problem` in place. `on_iteration` is called after every iteration (for logs
/// and progress bars).
pub fn solve(
    problem: &mut Problem,
    options: &Options,
    mut on_iteration: impl FnMut(&Iteration) + Send,
) -> Result<Summary, SolveError> {
    problem.validate()?;
    problem.sync_rigs();
    let threads = if options.threads == 0 {
        rayon::current_num_threads()
    } else {
        options.threads
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| SolveError::Setup(format!("cannot start {threads} threads: {e}")))?;
    let par = if threads > 1 {
        faer::Par::rayon(threads)
    } else {
        faer::Par::Seq
    };
    pool.install(|| run(problem, options, par, &mut on_iteration))
}

/// The solver of the reduced system for one adjustment.
enum Linear {
    /// A factorization of S, assembled explicitly.
    Direct(linear::Factorizer),
    /// Conjugate gradients on S applied implicitly.
    Iterative(Box<iterative::SchurOperator>),
}

impl Linear {
    /// The sparse factorization for `Sparse`, the dense one otherwise.
    fn direct(kind: LinearSolverKind, layout: &Layout, par: faer::Par) -> Result<Self, SolveError> {
        Ok(Linear::Direct(match kind {
            LinearSolverKind::Sparse => {
                linear::Factorizer::sparse(layout, par).map_err(SolveError::Setup)?
            }
            _ => linear::Factorizer::dense(par),
        }))
    }
}

struct Backup {
    rigs: Vec<pingcal_geometry::Rigid3>,
    poses: Vec<pingcal_geometry::Rigid3>,
    intrinsics: Vec<Vec<f64>>,
    points: Vec<Vector3<f64>>,
    parameters: Vec<crate::residual::ParameterValue>,
}

impl Backup {
    fn take(p: &Problem) -> Self {
        Self {
            rigs: p.rigs.iter().map(|r| r.member_from_base).collect(),
            poses: p.images.iter().map(|i| i.camera_from_object).collect(),
            intrinsics: p.cameras.iter().map(|c| c.params.clone()).collect(),
            points: p.points.iter().map(|x| x.position).collect(),
            parameters: p.parameters.iter().map(|b| b.value.clone()).collect(),
        }
    }
    fn restore(&self, p: &mut Problem) {
        for (i, pose) in p.images.iter_mut().zip(&self.poses) {
            i.camera_from_object = *pose;
        }
        for (r, pose) in p.rigs.iter_mut().zip(&self.rigs) {
            r.member_from_base = *pose;
        }
        for (c, v) in p.cameras.iter_mut().zip(&self.intrinsics) {
            c.params.copy_from_slice(v);
        }
        for (x, v) in p.points.iter_mut().zip(&self.points) {
            x.position = *v;
        }
        for (b, v) in p.parameters.iter_mut().zip(&self.parameters) {
            b.value.clone_from(v);
        }
    }
}

fn not_projectable(problem: &Problem, u: evaluate::Undefined) -> SolveError {
    SolveError::Problem(u.describe(problem))
}

/// The Levenberg–Marquardt minimizer (Ceres's `TrustRegionMinimizer`): takes the steps
/// [`Strategy`] computes, keeps those that lower the cost, and grows or shrinks the trust
/// region by how well the linear model predicted the decrease.
fn run(
    problem: &mut Problem,
    options: &Options,
    par: faer::Par,
    on_iteration: &mut (impl FnMut(&Iteration) + Send),
) -> Result<Summary, SolveError> {
    let t0 = Instant::now();
    let layout = Layout::new(problem);
    let (linear, choice) = choose_linear(&layout, options, par)?;
    let (clusters, schur_product) = match &linear {
        Linear::Iterative(op) => (op.cluster_stats, Some(op.product.clone())),
        Linear::Direct(_) => (None, None),
    };
    let setup_time_s = t0.elapsed().as_secs_f64();
    let mut lin = evaluate::Linearization::new(&layout);
    evaluate::linearize(problem, &layout, &mut lin).map_err(|o| not_projectable(problem, o))?;
    let mut strategy = Strategy::new(linear, choice, par, &layout);
    strategy.schur.prepare(&layout, &lin);

    let initial_cost = lin.cost;
    if !initial_cost.is_finite() {
        return Err(SolveError::Problem(ProblemError::NotFinite {
            what: "the initial cost".into(),
        }));
    }
    let mut m = Minimizer {
        cost: lin.cost,
        radius: options.initial_trust_region_radius,
        decrease_factor: 2.0,
        successful_steps: 0,
        eval_time: 0.0,
        log: Vec::new(),
    };
    let mut termination = Termination::MaxIterations;

    for iteration in 1..=options.max_iterations {
        let ti = Instant::now();
        let gradient_max_norm = strategy.schur.gradient_max_norm();
        if gradient_max_norm <= options.gradient_tolerance {
            termination = Termination::GradientTolerance;
            break;
        }
        let mut it = Iteration {
            iteration,
            cost: m.cost,
            cost_change: 0.0,
            gradient_max_norm,
            step_norm: 0.0,
            relative_decrease: 0.0,
            trust_region_radius: m.radius,
            accepted: false,
            linear_solver_time_s: 0.0,
            linear_iterations: 0,
            iteration_time_s: 0.0,
        };
        if strategy.compute_step(&layout, &lin, 1.0 / m.radius, options, &mut it)? {
            let stop = m.try_step(problem, &layout, &mut lin, &mut strategy, options, &mut it)?;
            if let Some(stop) = stop {
                termination = stop;
                it.iteration_time_s = ti.elapsed().as_secs_f64();
                on_iteration(&it);
                m.log.push(it);
                break;
            }
        } else {
            m.shrink();
        }
        it.iteration_time_s = ti.elapsed().as_secs_f64();
        on_iteration(&it);
        m.log.push(it);
        if m.radius < options.min_trust_region_radius {
            termination = Termination::TrustRegionTooSmall;
            break;
        }
    }
    Ok(Summary {
        initial_cost,
        final_cost: m.cost,
        iterations: m.log.len(),
        successful_steps: m.successful_steps,
        termination,
        time_s: t0.elapsed().as_secs_f64(),
        linear_solver_time_s: strategy.linear_time,
        evaluation_time_s: m.eval_time,
        schur_time_s: strategy.schur_time,
        setup_time_s,
        dense: strategy.choice.kind == LinearSolverKind::Dense,
        linear_solver: strategy.choice,
        linear_iterations: strategy.linear_iterations,
        clusters,
        schur_product,
        reduced_dimension: layout.n_reduced,
        reduced_nonzeros: layout.nnz(),
        log: m.log,
    })
}

/// The linear solver `options` ask for (or `Auto` picks within the memory limit), set up
/// for `layout`.
fn choose_linear(
    layout: &Layout,
    options: &Options,
    par: faer::Par,
) -> Result<(Linear, SolverChoice), SolveError> {
    let limit = options
        .memory_limit_bytes
        .or_else(|| available_memory().map(|m| 0.8 * m));
    let choice = choice::choose(
        layout,
        options.linear_solver,
        rayon::current_num_threads(),
        limit,
    )?;
    let linear = match choice.kind {
        LinearSolverKind::Iterative => Linear::Iterative(Box::new(iterative::SchurOperator::new(
            layout,
            options.cg.preconditioner,
            options.cg.product,
            rayon::current_num_threads(),
            limit,
        )?)),
        kind => Linear::direct(kind, layout, par)?,
    };
    Ok((linear, choice))
}

/// The minimizer's state between steps.
struct Minimizer {
    cost: f64,
    radius: f64,
    /// How much the radius shrinks at the next rejected step (doubles at each in a row).
    decrease_factor: f64,
    successful_steps: usize,
    eval_time: f64,
    log: Vec<Iteration>,
}

impl Minimizer {
    /// A rejected (or unsolvable) step: a smaller trust region, and smaller still next time.
    fn shrink(&mut self) {
        self.radius /= self.decrease_factor;
        self.decrease_factor *= 2.0;
    }

    /// Tries the step `strategy` solved for: kept (and the problem linearized again) when
    /// the cost falls by at least 1e-3 of the predicted decrease, undone otherwise. The
    /// termination when the step or the cost's change is below its tolerance.
    fn try_step(
        &mut self,
        problem: &mut Problem,
        layout: &Layout,
        lin: &mut evaluate::Linearization,
        strategy: &mut Strategy,
        options: &Options,
        it: &mut Iteration,
    ) -> Result<Option<Termination>, SolveError> {
        let (dc, dp) = strategy.back_substitute(layout, lin);
        let step_norm = (dc.iter().map(|v| v * v).sum::<f64>()
            + dp.iter().map(|v| v.norm_squared()).sum::<f64>())
        .sqrt();
        it.step_norm = step_norm;
        let x_norm = parameter_norm(problem);
        if step_norm <= options.parameter_tolerance * (x_norm + options.parameter_tolerance) {
            return Ok(Some(Termination::ParameterTolerance));
        }
        let predicted =
            predicted_decrease(layout, lin, dc, dp) + constraints::decrease(layout, lin, dc, dp);
        let backup = Backup::take(problem);
        apply_step(problem, layout, dc, dp);
        let te = Instant::now();
        let new_cost = evaluate::cost(problem).ok().filter(|c| c.is_finite());
        self.eval_time += te.elapsed().as_secs_f64();
        let cost = self.cost;
        match new_cost {
            Some(new_cost) if predicted > 0.0 && (cost - new_cost) / predicted > 1e-3 => {
                let rho = (cost - new_cost) / predicted;
                it.relative_decrease = rho;
                it.cost_change = cost - new_cost;
                it.accepted = true;
                it.cost = new_cost;
                self.successful_steps += 1;
                let converged = (cost - new_cost).abs() <= options.function_tolerance * cost;
                self.cost = new_cost;
                self.radius = (self.radius / (1.0f64 / 3.0).max(1.0 - (2.0 * rho - 1.0).powi(3)))
                    .min(options.max_trust_region_radius);
                self.decrease_factor = 2.0;
                evaluate::linearize(problem, layout, lin)
                    .map_err(|o| not_projectable(problem, o))?;
                strategy.schur.prepare(layout, lin);
                if converged {
                    return Ok(Some(Termination::FunctionTolerance));
                }
            }
            other => {
                it.relative_decrease = other.map_or(f64::NEG_INFINITY, |c| (cost - c) / predicted);
                backup.restore(problem);
                self.shrink();
            }
        }
        Ok(None)
    }
}

/// The step computation (Ceres's trust-region strategy and linear solver): the damped
/// normal equations reduced to the Schur complement on the cameras, solved by the chosen
/// factorization or by conjugate gradients (moving to the factorization when they need
/// too many iterations), then the points' step by back-substitution.
struct Strategy {
    linear: Linear,
    choice: SolverChoice,
    par: faer::Par,
    schur: schur::Schur,
    /// The step of the reduced (camera-side) unknowns.
    dc: Vec<f64>,
    /// The step of the free points.
    dp: Vec<Vector3<f64>>,
    schur_time: f64,
    linear_time: f64,
    linear_iterations: usize,
}

impl Strategy {
    fn new(linear: Linear, choice: SolverChoice, par: faer::Par, layout: &Layout) -> Self {
        Strategy {
            linear,
            choice,
            par,
            schur: schur::Schur::new(layout),
            dc: vec![0.0; layout.n_reduced],
            dp: vec![Vector3::zeros(); layout.free_points.len()],
            schur_time: 0.0,
            linear_time: 0.0,
            linear_iterations: 0,
        }
    }

    /// Solves the normal equations damped by `lambda` for the reduced step; false when
    /// they cannot be solved (the minimizer then shrinks the trust region).
    fn compute_step(
        &mut self,
        layout: &Layout,
        lin: &evaluate::Linearization,
        lambda: f64,
        options: &Options,
        it: &mut Iteration,
    ) -> Result<bool, SolveError> {
        let ts = Instant::now();
        let mut solved = match &mut self.linear {
            Linear::Direct(_) => self.schur.assemble(layout, lin, lambda).is_ok(),
            Linear::Iterative(op) => op.prepare(&mut self.schur, layout, lin, lambda).is_ok(),
        };
        self.schur_time += ts.elapsed().as_secs_f64();
        if solved {
            let tl = Instant::now();
            match &mut self.linear {
                Linear::Direct(factorizer) => {
                    self.dc.copy_from_slice(&self.schur.rhs);
                    solved = factorizer.solve(layout, &self.schur.values, &mut self.dc);
                }
                Linear::Iterative(op) => {
                    match op.solve(&self.schur, layout, lin, &options.cg, &mut self.dc) {
                        Some(cg) => {
                            it.linear_iterations = cg.iterations;
                            self.linear_iterations += cg.iterations;
                        }
                        None => solved = false,
                    }
                }
            }
            self.fall_back_if_slow(layout, options, it)?;
            it.linear_solver_time_s = tl.elapsed().as_secs_f64();
            self.linear_time += it.linear_solver_time_s;
        }
        Ok(solved)
    }

    /// Too many CG iterations for what `Auto` estimated: the factorization from the next
    /// step on (this step's inexact solution is still a descent step).
    fn fall_back_if_slow(
        &mut self,
        layout: &Layout,
        options: &Options,
        it: &Iteration,
    ) -> Result<(), SolveError> {
        if let (Linear::Iterative(_), Some(kind)) = (&self.linear, self.choice.fallback) {
            if it.linear_iterations > options.cg.switch_after {
                self.linear = Linear::direct(kind, layout, self.par)?;
                self.choice.reason = format!(
                    "{}; moved to {kind} at step {}: the conjugate gradients needed {} iterations",
                    self.choice.reason, it.iteration, it.linear_iterations
                );
                self.choice.kind = kind;
                self.choice.fallback = None;
            }
        }
        Ok(())
    }

    /// The points' step from the reduced one; both steps.
    fn back_substitute(
        &mut self,
        layout: &Layout,
        lin: &evaluate::Linearization,
    ) -> (&[f64], &[Vector3<f64>]) {
        let ts = Instant::now();
        self.schur
            .back_substitute(layout, lin, &self.dc, &mut self.dp);
        self.schur_time += ts.elapsed().as_secs_f64();
        (&self.dc, &self.dp)
    }
}

/// |x|: rotations as angle-axis vectors, translations, intrinsics, points.
fn parameter_norm(p: &Problem) -> f64 {
    let mut s = 0.0;
    for im in &p.images {
        s += log_so3(&im.camera_from_object.rotation).norm_squared()
            + im.camera_from_object.translation.norm_squared();
    }
    for c in &p.cameras {
        s += c.params.iter().map(|v| v * v).sum::<f64>();
    }
    for x in &p.points {
        s += x.position.norm_squared();
    }
    for pb in &p.parameters {
        s += match &pb.value {
            crate::residual::ParameterValue::Vector(v) => v.iter().map(|x| x * x).sum::<f64>(),
            crate::residual::ParameterValue::Pose(q) => {
                log_so3(&q.rotation).norm_squared() + q.translation.norm_squared()
            }
        };
    }
    s.sqrt()
}

/// Decrease of the linear model: ½|r|² − ½|r + Jδ|² = −rᵀJδ − ½|Jδ|².
fn predicted_decrease(
    layout: &Layout,
    lin: &evaluate::Linearization,
    dc: &[f64],
    dp: &[Vector3<f64>],
) -> f64 {
    (0..lin.r.len())
        .into_par_iter()
        .with_min_len(256)
        .map(|o| {
            let mut jd = nalgebra::Vector2::zeros();
            for s in layout.segs(o) {
                let base = layout.block_offset[s.block as usize] + s.block_off as usize;
                let (j0, j1) = layout.jc_rows(&lin.jc, o, s);
                for k in 0..s.len as usize {
                    jd.x += j0[k] * dc[base + k];
                    jd.y += j1[k] * dc[base + k];
                }
            }
            let f = layout.free_point_index[layout.obs_point[o] as usize];
            if f != u32::MAX {
                jd += lin.jp[o] * dp[f as usize];
            }
            -lin.r[o].dot(&jd) - 0.5 * jd.norm_squared()
        })
        .sum()
}

fn apply_step(problem: &mut Problem, layout: &Layout, dc: &[f64], dp: &[Vector3<f64>]) {
    for p in 0..layout.point_slot.len() {
        // Only the free coordinates move: a held one keeps its value exactly.
        for (axis, row) in layout.point_rows(p) {
            problem.points[p].position[axis] += dc[row];
        }
    }
    for (r, slot) in layout.rig_slot.iter().enumerate() {
        if let Some(s) = slot {
            let o = layout.slot_offset(*s);
            problem.rigs[r].member_from_base = problem.rigs[r].member_from_base.plus(&dc[o..o + 6]);
        }
    }
    for (i, im) in problem.images.iter_mut().enumerate() {
        if let Some(s) = layout.image_slot[i] {
            let o = layout.block_offset[s.block as usize] + s.off as usize;
            im.camera_from_object = match &layout.image_centre_axes[i] {
                None => im.camera_from_object.plus(&dc[o..o + 6]),
                // (δω, δC): R ← exp([δω]×) R, C ← C + δC on the free coordinates only.
                Some(axes) => {
                    let pose = &im.camera_from_object;
                    let mut centre = pose.centre();
                    for (k, &a) in axes.iter().enumerate() {
                        centre[a] += dc[o + 3 + k];
                    }
                    let w = &dc[o..o + 3];
                    let rotation = pose.plus(&[w[0], w[1], w[2], 0.0, 0.0, 0.0]).rotation;
                    pingcal_geometry::Rigid3::from_rotation_and_centre(rotation, centre)
                }
            };
        }
    }
    for (c, cam) in problem.cameras.iter_mut().enumerate() {
        if let Some(s) = layout.camera_slot[c] {
            let o = layout.block_offset[s.block as usize] + s.off as usize;
            for (k, &idx) in layout.camera_free[c].iter().enumerate() {
                cam.params[idx] += dc[o + k];
            }
        }
    }
    for (f, &p) in layout.free_points.iter().enumerate() {
        problem.points[p].position += dp[f];
    }
    for (k, slot) in layout.parameter_slot.iter().enumerate() {
        if let Some(s) = slot {
            let o = layout.slot_offset(*s);
            let pb = &mut problem.parameters[k];
            let mut delta = vec![0.0; pb.tangent_dim()];
            for (i, &c) in layout.parameter_free[k].iter().enumerate() {
                delta[c] = dc[o + i];
            }
            pb.plus(&delta);
        }
    }
    problem.sync_rigs();
}

#[cfg(test)]
mod tests {
    //! Finite-difference check of the whole observation Jacobian as the solver assembles it
    //! (camera model ∘ pose update ∘ point), through the same step mapping the solver uses.
    use super::*;
    use crate::camera::PhotogrammetricCamera;
    use crate::keys::{CameraKey, ImageKey, PointKey};
    use crate::problem::{Camera, Image, Observation, Point};
    use nalgebra::{Vector2, Vector3};
    use pingcal_geometry::exp_so3;
    use pingcal_geometry::Rigid3;
    use std::sync::Arc;

    fn small_problem(loss: crate::loss::Loss) -> Problem {
        let model = Arc::new(PhotogrammetricCamera::new(1280, 720, 0.00375));
        let params = vec![
            2.45, 0.01, -0.02, -0.02, 3e-4, -1e-5, 2e-4, -1e-4, 1e-4, -2e-4,
        ];
        let mut left = Camera::new("left", model.clone(), params.clone());
        left.fixed[5] = true; // one intrinsic held fixed
        let right = Camera::new("right", model, params); // shared by two images
        let mut images = Vec::new();
        for (k, cam) in [0usize, 1, 1].into_iter().enumerate() {
            let r = exp_so3(&Vector3::new(0.1 * k as f64, -0.05, 0.2 - 0.1 * k as f64));
            images.push(Image {
                name: format!("i{k}"),
                camera: CameraKey(cam),
                camera_from_object: Rigid3::from_rotation_and_centre(
                    r,
                    Vector3::new(0.3 * k as f64, -2.0, 0.1),
                ),
                fixed: false,
                fixed_centre: [false; 3],
            });
        }
        let points: Vec<Point> = (0..6)
            .map(|k| Point {
                name: k.to_string(),
                position: Vector3::new(
                    -0.5 + 0.2 * k as f64,
                    0.5 + 0.1 * (k % 3) as f64,
                    -0.3 + 0.1 * k as f64,
                ),
                fixed: k == 5,
                fixed_axes: [false; 3],
            })
            .collect();
        let mut observations = Vec::new();
        for i in 0..3 {
            for p in 0..6 {
                // Measurements a few pixels off, so that residuals (and the robust
                // weights) are not trivial.
                let uv = Vector2::new(600.0 + 13.0 * p as f64, 300.0 + 7.0 * i as f64);
                observations.push(Observation {
                    image: ImageKey(i),
                    point: PointKey(p),
                    uv,
                    sigma: 0.5,
                });
            }
        }
        Problem {
            cameras: vec![left, right],
            images,
            points,
            observations,
            loss,
            ..Default::default()
        }
    }

    /// The gradient of the total cost (image observations, distances, control points) that
    /// the Schur step uses equals the central difference of the cost.
    #[test]
    fn gradient_with_distances_control_and_rig_matches_central_differences() {
        use crate::problem::{Distance, PointPrior};
        let mut problem = small_problem(crate::loss::Loss::Cauchy(4.0));
        problem.distances.push(Distance {
            a: PointKey(0),
            b: PointKey(3),
            value: 0.55,
            sigma: 0.01,
        });
        problem.distances.push(Distance {
            a: PointKey(3),
            b: PointKey(5),
            value: 0.5,
            sigma: 0.02,
        }); // 5 is fixed
        problem.point_priors.push(PointPrior {
            point: PointKey(1),
            position: Vector3::new(-0.29, 0.61, -0.21),
            sigma: Vector3::new(0.01, 0.02, 0.03),
        });
        problem.point_priors.push(PointPrior {
            point: PointKey(3),
            position: Vector3::new(0.11, 0.49, 0.01),
            sigma: Vector3::new(0.05, 0.05, 0.05),
        });
        // Image 2 follows image 0 through a free rig (a stereo head).
        let rig_pose = problem.images[2]
            .camera_from_object
            .compose(&problem.images[0].camera_from_object.inverse());
        problem.rigs.push(crate::problem::Rig {
            name: "stereo".into(),
            member_from_base: rig_pose,
            fixed: false,
            members: vec![crate::problem::RigMember {
                image: ImageKey(2),
                base: ImageKey(0),
            }],
        });
        problem.sync_rigs();
        let layout = Layout::new(&problem);
        assert!(
            layout.point_slot[0].is_some()
                && layout.point_slot[3].is_some()
                && layout.point_slot[5].is_none()
        );
        assert!(layout.image_slot[2].is_none() && layout.rig_slot[0].is_some());
        let mut lin = evaluate::Linearization::new(&layout);
        evaluate::linearize(&problem, &layout, &mut lin).unwrap();
        let mut schur = schur::Schur::new(&layout);
        schur.prepare(&layout, &lin);
        let (nc, np) = (layout.n_reduced, layout.free_points.len());
        let cost0 = evaluate::cost(&problem).unwrap();
        assert!((cost0 - lin.cost).abs() <= 1e-12 * cost0);
        for v in 0..nc + 3 * np {
            let h = 1e-6;
            let eval =
                |sign: f64| evaluate::cost(&stepped(&problem, &layout, v, sign * h)).unwrap();
            let fd = (eval(1.0) - eval(-1.0)) / (2.0 * h);
            let an = if v < nc {
                schur.gc[v]
            } else {
                schur.gp[(v - nc) / 3][(v - nc) % 3]
            };
            let scale = an.abs().max(fd.abs()).max(1.0);
            assert!(
                (an - fd).abs() / scale < 1e-6,
                "var {v}: gradient {an} fd {fd}"
            );
        }
    }

    /// `problem` moved by `step` along unknown `v` of `layout` (the reduced unknowns first,
    /// then the free points' coordinates).
    fn stepped(problem: &Problem, layout: &Layout, v: usize, step: f64) -> Problem {
        let (nc, np) = (layout.n_reduced, layout.free_points.len());
        let mut dc = vec![0.0; nc];
        let mut dp = vec![Vector3::zeros(); np];
        if v < nc {
            dc[v] = step;
        } else {
            dp[(v - nc) / 3][(v - nc) % 3] = step;
        }
        let mut q = problem.clone();
        apply_step(&mut q, layout, &dc, &dp);
        q
    }

    /// Whitened residuals, and the robust cost ½ Σ ρ.
    fn residuals(p: &Problem) -> (Vec<f64>, f64) {
        let mut cost = 0.0;
        let r = p
            .observations
            .iter()
            .flat_map(|o| {
                let r = p.residual(o).unwrap() / o.sigma;
                cost += 0.5 * p.loss.evaluate(r.norm_squared()).0;
                [r.x, r.y]
            })
            .collect();
        (r, cost)
    }

    /// With the trivial loss every Jacobian column is checked; with a robust loss (where the
    /// solver uses the IRLS weights √ρ′, as Ceres does for ρ″ ≤ 0) the gradient Jᵀr of the
    /// robust cost is checked instead.
    #[test]
    fn assembled_jacobian_matches_central_differences() {
        for loss in [
            crate::loss::Loss::Trivial,
            crate::loss::Loss::Huber(3.0),
            crate::loss::Loss::Cauchy(5.0),
        ] {
            let robust = loss != crate::loss::Loss::Trivial;
            let problem = small_problem(loss);
            let layout = Layout::new(&problem);
            // Image 0 owns camera "left" alone, so its intrinsics fold into its block.
            assert_eq!(layout.num_blocks(), 4);
            let mut lin = evaluate::Linearization::new(&layout);
            evaluate::linearize(&problem, &layout, &mut lin).unwrap();
            let nc = layout.n_reduced;
            let np = layout.free_points.len();
            for v in 0..nc + 3 * np {
                let h = 1e-6;
                let eval = |sign: f64| residuals(&stepped(&problem, &layout, v, sign * h));
                let ((plus, cost_plus), (minus, cost_minus)) = (eval(1.0), eval(-1.0));
                let mut gradient = 0.0;
                for o in 0..problem.observations.len() {
                    // Analytic column v of observation o.
                    let mut an = Vector2::zeros();
                    if v < nc {
                        for s in layout.segs(o) {
                            let base = layout.block_offset[s.block as usize] + s.block_off as usize;
                            if v >= base && v < base + s.len as usize {
                                let (j0, j1) = layout.jc_rows(&lin.jc, o, s);
                                an = Vector2::new(j0[v - base], j1[v - base]);
                            }
                        }
                    } else {
                        let f = layout.free_point_index[layout.obs_point[o] as usize];
                        if f as usize == (v - nc) / 3 {
                            an = lin.jp[o].column((v - nc) % 3).into_owned();
                        }
                    }
                    gradient += an.dot(&lin.r[o]);
                    if robust {
                        continue;
                    }
                    let q = layout.obs_order[o] as usize; // problem order of residuals
                    let fd = Vector2::new(
                        plus[2 * q] - minus[2 * q],
                        plus[2 * q + 1] - minus[2 * q + 1],
                    ) / (2.0 * h);
                    let scale = an.norm().max(fd.norm()).max(1.0);
                    assert!(
                        (an - fd).norm() / scale < 1e-6,
                        "obs {o} var {v}: analytic {an:?} fd {fd:?}"
                    );
                }
                let fd = (cost_plus - cost_minus) / (2.0 * h);
                let scale = gradient.abs().max(fd.abs()).max(1.0);
                assert!(
                    (gradient - fd).abs() / scale < 1e-6,
                    "{loss:?} var {v}: gradient {gradient} fd {fd}"
                );
            }
        }
    }
}

#[cfg(test)]
mod schur_tests {
    //! The Schur-complement step equals the step from the full damped normal equations.
    use super::*;
    use crate::keys::{CameraKey, PointKey};
    use crate::synthetic::SyntheticBal;
    use nalgebra::{DMatrix, DVector};

    /// A small BAL problem with every kind of unknown: a fixed image and point, a camera
    /// shared by two images, a distance (its points join the reduced system) and two
    /// control points, one on an eliminated point and one on a reduced one.
    fn mixed_problem() -> Problem {
        let s = SyntheticBal {
            cameras: 5,
            points: 40,
            obs_per_point: 3,
            noise_px: 1.0,
            perturbation: 1.0,
            seed: 5,
            ..Default::default()
        };
        let mut problem = s.generate().unwrap().problem;
        problem.images[0].fixed = true;
        problem.points[3].fixed = true;
        // A camera shared by two images: its intrinsics get a block of their own.
        problem.images[4].camera = CameraKey(3);
        // A distance (its points join the reduced system) and two control points, one on an
        // eliminated point and one on a reduced one.
        use crate::problem::{Distance, PointPrior};
        let d0 = (problem.points[7].position - problem.points[9].position).norm();
        problem.distances.push(Distance {
            a: PointKey(7),
            b: PointKey(9),
            value: d0 + 0.01,
            sigma: 0.005,
        });
        let (x10, x9) = (problem.points[10].position, problem.points[9].position);
        problem.point_priors.push(PointPrior {
            point: PointKey(10),
            position: x10 + Vector3::new(0.01, 0.0, -0.02),
            sigma: Vector3::new(0.02, 0.03, 0.04),
        });
        problem.point_priors.push(PointPrior {
            point: PointKey(9),
            position: x9,
            sigma: Vector3::new(0.1, 0.1, 0.1),
        });
        problem
    }

    /// The whole whitened Jacobian, dense over [camera-side unknowns, free points], and the
    /// residuals: image observations, the distance, the control points.
    fn full_jacobian(
        problem: &Problem,
        layout: &Layout,
        lin: &evaluate::Linearization,
    ) -> (DMatrix<f64>, DVector<f64>) {
        // Dense J over [camera-side unknowns, free points].
        let nc = layout.n_reduced;
        let n = nc + 3 * layout.free_points.len();
        let m = 2 * problem.observations.len();
        let mut j = DMatrix::<f64>::zeros(m, n);
        let mut r = DVector::<f64>::zeros(m);
        for o in 0..problem.observations.len() {
            r[2 * o] = lin.r[o].x;
            r[2 * o + 1] = lin.r[o].y;
            for s in layout.segs(o) {
                let base = layout.block_offset[s.block as usize] + s.block_off as usize;
                let (j0, j1) = layout.jc_rows(&lin.jc, o, s);
                for k in 0..s.len as usize {
                    j[(2 * o, base + k)] = j0[k];
                    j[(2 * o + 1, base + k)] = j1[k];
                }
            }
            let f = layout.free_point_index[layout.obs_point[o] as usize];
            if f != u32::MAX {
                for k in 0..3 {
                    j[(2 * o, nc + 3 * f as usize + k)] = lin.jp[o][(0, k)];
                    j[(2 * o + 1, nc + 3 * f as usize + k)] = lin.jp[o][(1, k)];
                }
            }
        }
        // Rows of the distance and the control points.
        let col_of = |p: usize| -> usize {
            match layout.point_slot[p] {
                Some(sl) => layout.slot_offset(sl),
                None => nc + 3 * layout.free_point_index[p] as usize,
            }
        };
        let extra = 1 + 3 * problem.point_priors.len();
        let mut j = j.resize_vertically(m + extra, 0.0);
        let mut r = r.resize_vertically(m + extra, 0.0);
        // The distance, written out here: (|X_a − X_b| − value)/σ, ∂/∂X_a = uᵀ/σ.
        let d = problem.distances[0];
        let v = problem.points[d.a].position - problem.points[d.b].position;
        r[m] = (v.norm() - d.value) / d.sigma;
        let ja = v.normalize() / d.sigma;
        for k in 0..3 {
            j[(m, col_of(7) + k)] = ja[k];
            j[(m, col_of(9) + k)] = -ja[k];
        }
        for (q, pr) in problem.point_priors.iter().enumerate() {
            let x = problem.points[pr.point].position;
            for k in 0..3 {
                r[m + 1 + 3 * q + k] = (x[k] - pr.position[k]) / pr.sigma[k];
                j[(m + 1 + 3 * q + k, col_of(pr.point.0) + k)] = 1.0 / pr.sigma[k];
            }
        }
        (j, r)
    }

    /// `points_covariance` (the Schur form, correlations between points included) equals
    /// σ0² (JᵀJ)⁻¹ of the whole dense system, for eliminated, reduced and fixed points.
    #[test]
    fn joint_point_covariance_equals_the_inverse_of_the_full_normal_matrix() {
        let mut problem = mixed_problem();
        solve(&mut problem, &Options::default(), |_| {}).unwrap();
        let layout = Layout::new(&problem);
        let mut lin = evaluate::Linearization::new(&layout);
        evaluate::linearize(&problem, &layout, &mut lin).unwrap();
        let (j, _) = full_jacobian(&problem, &layout, &lin);
        let q = (j.transpose() * &j).try_inverse().unwrap();
        let s02 = precision(&problem).unwrap().sigma0.powi(2);
        // 0, 1, 2 eliminated; 7, 9 (distance) and 10 (control) reduced; 3 fixed.
        let points = [0usize, 7, 3, 1, 10, 9, 2];
        let cov = points_covariance(&problem, &points).unwrap();
        let col = |p: usize| match layout.point_slot[p] {
            Some(sl) => Some(layout.slot_offset(sl)),
            None if problem.points[p].fixed => None,
            None => Some(layout.n_reduced + 3 * layout.free_point_index[p] as usize),
        };
        let mut worst: f64 = 0.0;
        for (a, &pa) in points.iter().enumerate() {
            for (b, &pb) in points.iter().enumerate() {
                for (u, v) in (0..3).flat_map(|u| (0..3).map(move |v| (u, v))) {
                    let want = match (col(pa), col(pb)) {
                        (Some(ca), Some(cb)) => s02 * q[(ca + u, cb + v)],
                        _ => 0.0,
                    };
                    worst = worst.max((cov[(3 * a + u, 3 * b + v)] - want).abs());
                }
            }
        }
        let scale = cov.diagonal().amax();
        assert!(
            worst <= 1e-8 * scale,
            "largest difference {worst} (diagonal up to {scale})"
        );
        // The points are correlated (so the cross blocks are tested, not zeros against zeros).
        let cross = (0..3).flat_map(|u| (0..3).map(move |v| (u, v)));
        let cross = cross
            .map(|(u, v)| cov[(u, 3 * 3 + v)].abs())
            .fold(0.0, f64::max);
        assert!(
            cross > 1e-3 * scale,
            "points 0 and 1 look uncorrelated ({cross})"
        );
    }

    /// The layout, linearization and explicitly assembled Schur complement of `problem`
    /// at its estimate, for the damping `lambda`.
    fn assembled(
        problem: &Problem,
        lambda: f64,
    ) -> (Layout, evaluate::Linearization, schur::Schur) {
        let layout = Layout::new(problem);
        let mut lin = evaluate::Linearization::new(&layout);
        evaluate::linearize(problem, &layout, &mut lin).unwrap();
        let mut schur = schur::Schur::new(&layout);
        schur.prepare(&layout, &lin);
        schur.assemble(&layout, &lin, lambda).unwrap();
        (layout, lin, schur)
    }

    #[test]
    fn schur_step_equals_full_normal_equations_step() {
        let problem = mixed_problem();
        let lambda = 0.37;
        let (layout, lin, schur) = assembled(&problem, lambda);
        let mut dc = schur.rhs.clone();
        let mut fact = linear::Factorizer::sparse(&layout, faer::Par::Seq).unwrap();
        assert!(fact.solve(&layout, &schur.values, &mut dc));
        let mut dp = vec![Vector3::zeros(); layout.free_points.len()];
        schur.back_substitute(&layout, &lin, &dc, &mut dp);

        let (j, r) = full_jacobian(&problem, &layout, &lin);
        let n = j.ncols();
        let nc = layout.n_reduced;
        let mut h = j.transpose() * &j;
        for k in 0..n {
            h[(k, k)] += lambda * h[(k, k)].clamp(1e-6, 1e32);
        }
        let g = j.transpose() * &r;
        let full = h.cholesky().unwrap().solve(&(-g));
        let mut err: f64 = 0.0;
        for k in 0..nc {
            err = err.max((full[k] - dc[k]).abs() / full.amax());
        }
        for (f, d) in dp.iter().enumerate() {
            for k in 0..3 {
                err = err.max((full[nc + 3 * f + k] - d[k]).abs() / full.amax());
            }
        }
        assert!(err < 1e-9, "relative difference {err}");
        // And the dense path gives the same.
        let mut dc2 = schur.rhs.clone();
        let mut dense = linear::Factorizer::dense(faer::Par::Seq);
        assert!(dense.solve(&layout, &schur.values, &mut dc2));
        assert!(dc
            .iter()
            .zip(&dc2)
            .all(|(a, b)| (a - b).abs() <= 1e-9 * full.amax()));
    }

    /// The products (implicit, and explicit split over three workers' column ranges) and
    /// the preconditioners of the iterative solver against the assembled S of the same
    /// damped step (distances, control points, a rig, shared and fixed cameras included),
    /// and its solution against the factorization's.
    #[test]
    fn implicit_schur_equals_the_assembled_one() {
        let problem = mixed_problem();
        let lambda = 0.37;
        let (layout, lin, schur) = assembled(&problem, lambda);
        let n = layout.n_reduced;
        let rows = layout.row_indices();
        let mut dense = nalgebra::DMatrix::<f64>::zeros(n, n);
        for j in 0..n {
            for k in layout.col_ptr[j]..layout.col_ptr[j + 1] {
                dense[(rows[k], j)] = schur.values[k];
                dense[(j, rows[k])] = schur.values[k];
            }
        }
        let rhs_explicit = schur.rhs.clone();
        let preconditioners = [
            Preconditioner::SchurJacobi,
            // Small enough to leave several clusters, large enough to merge blocks.
            Preconditioner::ClusterJacobi { max_dim: 30 },
        ];
        let forms = [false, true]
            .into_iter()
            .flat_map(|e| preconditioners.map(|p| (e, p)));
        for (explicit, preconditioner) in forms {
            let (_, _, mut schur) = assembled(&problem, lambda);
            let (product, workers) = match explicit {
                true => (SchurProduct::Explicit, 3),
                false => (SchurProduct::Implicit, 1),
            };
            let mut op =
                iterative::SchurOperator::new(&layout, preconditioner, product, workers, None)
                    .unwrap();
            op.prepare(&mut schur, &layout, &lin, lambda).unwrap();
            check_implicit(&layout, &lin, &schur, &mut op, &dense, &rhs_explicit);
            let clusters = op.clusters_for_test();
            let merged = clusters.blocks.iter().filter(|m| m.len() > 1).count();
            match preconditioner {
                Preconditioner::SchurJacobi => assert_eq!(merged, 0),
                Preconditioner::ClusterJacobi { max_dim } => {
                    assert!(merged >= 1, "no cluster of several blocks");
                    assert!(clusters.dim.iter().all(|&d| d <= max_dim));
                }
            }
            // Preconditioner: each cluster the inverse of S restricted to its blocks.
            for (c, members) in clusters.blocks.iter().enumerate() {
                let idx: Vec<usize> = (members.iter())
                    .flat_map(|&b| {
                        let (o, d) = (
                            layout.block_offset[b as usize],
                            layout.block_dim[b as usize],
                        );
                        o..o + d
                    })
                    .collect();
                let d = idx.len();
                assert_eq!(d, clusters.dim[c]);
                let sub = nalgebra::DMatrix::from_fn(d, d, |i, j| dense[(idx[i], idx[j])]);
                let inv = sub.cholesky().unwrap().inverse();
                for (j, &col) in idx.iter().enumerate() {
                    let mut r = vec![0.0; n];
                    let mut z = vec![0.0; n];
                    r[col] = 1.0;
                    op.precondition_for_test(&layout, &r, &mut z);
                    for (i, &row) in idx.iter().enumerate() {
                        assert!(
                            (z[row] - inv[(i, j)]).abs() <= 1e-9 * inv.amax(),
                            "{preconditioner:?}, explicit {explicit}: cluster {c}, ({i}, {j})"
                        );
                    }
                    let outside = (0..n).filter(|k| !idx.contains(k)).map(|k| z[k].abs());
                    assert_eq!(outside.fold(0.0, f64::max), 0.0);
                }
            }
            // A tight solve equals the factorization's step.
            let mut direct = schur.rhs.clone();
            let mut fact = linear::Factorizer::sparse(&layout, faer::Par::Seq).unwrap();
            assert!(fact.solve(&layout, &schur.values, &mut direct));
            let tight = CgOptions {
                eta: 0.0,
                max_iterations: 10 * n,
                ..CgOptions::default()
            };
            let mut x = vec![0.0; n];
            let cg = op.solve(&schur, &layout, &lin, &tight, &mut x).unwrap();
            let amax = direct.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            for (a, b) in x.iter().zip(&direct) {
                assert!(
                    (a - b).abs() <= 1e-8 * amax,
                    "{preconditioner:?}, explicit {explicit}: {a} vs {b} after {} iterations",
                    cg.iterations
                );
            }
        }
    }

    /// The right-hand side and the implicit product of `op` against the assembled S.
    fn check_implicit(
        layout: &Layout,
        lin: &evaluate::Linearization,
        schur: &schur::Schur,
        op: &mut iterative::SchurOperator,
        dense: &nalgebra::DMatrix<f64>,
        rhs_explicit: &[f64],
    ) {
        let n = layout.n_reduced;
        let scale = dense.amax();
        for (a, b) in schur.rhs.iter().zip(rhs_explicit) {
            assert!(
                (a - b).abs() <= 1e-11 * rhs_explicit.iter().fold(0.0f64, |m, v| m.max(v.abs()))
            );
        }
        let mut rng = pingcal_geometry::consensus::rng(5);
        for _ in 0..3 {
            let x: Vec<f64> = (0..n)
                .map(|_| rand::Rng::random_range(&mut rng, -1.0..1.0))
                .collect();
            let mut y = vec![0.0; n];
            op.apply(schur, layout, lin, &x, &mut y);
            let want = dense * nalgebra::DVector::from_column_slice(&x);
            for k in 0..n {
                assert!(
                    (y[k] - want[k]).abs() <= 1e-11 * scale * n as f64,
                    "S·x[{k}]: implicit {} explicit {}",
                    y[k],
                    want[k]
                );
            }
        }
    }
}
