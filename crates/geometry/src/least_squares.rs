//! Small dense nonlinear least squares: the one iteration behind pingcal's fits of a few
//! unknowns (a sphere's centre from LRF beams, from a silhouette's rays, from points or rays
//! with a free radius). The bundle adjuster, with its thousands of unknowns, has its own
//! sparse solver in `pingcal-ba`; this is for problems whose normal matrix is a few by a few.
//!
//! ## The problem
//!
//! A problem gives, at parameters `x`, its weighted residuals' normal equations
//! ([`Normal`]):
//!
//! ```text
//!   N = Jᵀ W J,   g = Jᵀ W r,   cost = rᵀ W r
//! ```
//!
//! with `r(x)` the residuals, `J = ∂r/∂x` and `W` their weights (a problem whose residuals
//! are already divided by their σ has `W = I`). The problem forms `N` and `g` itself, by a
//! sum over its residuals or from a stored Jacobian ([`Normal::from_jacobian`]), and may
//! refuse a point where it is not defined (`None`: a camera inside the sphere).
//!
//! ## The step
//!
//! [`Strategy::GaussNewton`] takes `δ = −N⁻¹ g` at every iteration, shortened by the
//! problem's own [`Objective::limit_step`] where a full step could leave the domain (through
//! the camera). It suits problems close to linear from a good start, and it is what the
//! covariance `N⁻¹` of the result is computed from.
//!
//! [`Strategy::LevenbergMarquardt`] solves `(N + λ diag N) δ = −g` by Cholesky (the diagonal
//! at least 1e-12, so a parameter the data do not touch still has a step), takes the step
//! only if the cost does not rise, and then divides λ by 10 (down to 1e-12); a rejected step
//! multiplies λ by 10 and is tried again, 12 times at most, from λ = 1e-6. It suits starts far
//! from the answer and problems with flat directions.
//!
//! Both stop when the problem's own test says a step was small ([`Options::small_step`], on
//! `|δ|` and `|x|` before and after the step: e.g. `|δ| < 10⁻¹⁰ (1 + |x|)`), when
//! Levenberg–Marquardt's cost falls by less than [`Options::cost_tolerance`] of `1 + cost`,
//! when Levenberg–Marquardt finds no step that lowers the cost, or after
//! [`Options::max_iterations`]. The work is bounded by `max_iterations` (times 12 trial
//! steps for Levenberg–Marquardt) evaluations, whatever the values.
//!
//! [`minimize`] returns the parameters and the last normal equations formed (for
//! Gauss–Newton those of the point the last step was taken from); `None` when the problem
//! refuses its start or a Gauss–Newton point, when Gauss–Newton's `N` is singular, or when the
//! result is not finite.

use nalgebra::allocator::Allocator;
use nalgebra::{DMatrix, DVector, DefaultAllocator, Dim, Dyn, OMatrix, OVector};

/// A problem's normal equations at some parameters: `N = Jᵀ W J`, `g = Jᵀ W r` and the cost
/// `rᵀ W r`.
#[derive(Clone, Debug)]
pub struct Normal<D: Dim>
where
    DefaultAllocator: Allocator<D, D> + Allocator<D>,
{
    /// `N = Jᵀ W J`.
    pub matrix: OMatrix<f64, D, D>,
    /// `g = Jᵀ W r`.
    pub gradient: OVector<f64, D>,
    /// `rᵀ W r`.
    pub cost: f64,
}

impl Normal<Dyn> {
    /// The normal equations of weighted residuals `r` and their Jacobian `j` (rows:
    /// residuals, columns: parameters).
    pub fn from_jacobian(r: &DVector<f64>, j: &DMatrix<f64>) -> Normal<Dyn> {
        let jt = j.transpose();
        Normal {
            gradient: &jt * r,
            matrix: &jt * j,
            cost: r.norm_squared(),
        }
    }
}

/// A least-squares problem: its normal equations at `x`, and how far a step from `x` may go.
pub trait Objective<D: Dim>
where
    DefaultAllocator: Allocator<D, D> + Allocator<D>,
{
    /// The normal equations at `x`; `None` where the problem is not defined.
    fn normal(&mut self, x: &OVector<f64, D>) -> Option<Normal<D>>;

    /// The step to take from `x` when the solver proposes `step` (the default: `step`).
    fn limit_step(&self, x: &OVector<f64, D>, step: OVector<f64, D>) -> OVector<f64, D> {
        let _ = x;
        step
    }
}

impl<D: Dim, F> Objective<D> for F
where
    DefaultAllocator: Allocator<D, D> + Allocator<D>,
    F: FnMut(&OVector<f64, D>) -> Option<Normal<D>>,
{
    fn normal(&mut self, x: &OVector<f64, D>) -> Option<Normal<D>> {
        self(x)
    }
}

/// How each step is found (see the [module](self)).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Strategy {
    /// `δ = −N⁻¹ g`, every step taken.
    GaussNewton,
    /// `(N + λ diag N) δ = −g`, a step taken only if the cost does not rise.
    LevenbergMarquardt,
}

/// The lengths a step test reads.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Step {
    /// `|δ|`.
    pub length: f64,
    /// `|x|` before the step.
    pub from: f64,
    /// `|x|` after the step.
    pub to: f64,
}

/// When to stop, and how to step.
#[derive(Clone, Copy, Debug)]
pub struct Options {
    /// The step rule.
    pub strategy: Strategy,
    /// Iterations (normal equations solved and a step taken) at most.
    pub max_iterations: usize,
    /// Converged when this says the step taken was small (e.g.
    /// `|s| s.length < 1e-10 * (1.0 + s.from)`).
    pub small_step: fn(Step) -> bool,
    /// Levenberg–Marquardt only: converged when the cost falls by less than this fraction of
    /// `1 + cost`.
    pub cost_tolerance: f64,
}

/// What [`minimize`] found.
#[derive(Clone, Debug)]
pub struct Solution<D: Dim>
where
    DefaultAllocator: Allocator<D, D> + Allocator<D>,
{
    /// The parameters.
    pub x: OVector<f64, D>,
    /// The last normal equations formed (Gauss–Newton: at the point the last step was taken
    /// from; Levenberg–Marquardt: at `x`).
    pub normal: Normal<D>,
    /// Iterations done.
    pub iterations: usize,
    /// Whether a tolerance was met (not the iteration limit, nor a Levenberg–Marquardt step
    /// that found no lower cost).
    pub converged: bool,
}

/// Minimizes the problem's cost from `x0` (see the [module](self)).
pub fn minimize<D: Dim>(
    x0: OVector<f64, D>,
    options: &Options,
    objective: &mut impl Objective<D>,
) -> Option<Solution<D>>
where
    DefaultAllocator: Allocator<D, D> + Allocator<D>,
{
    let start = objective.normal(&x0)?;
    let solution = match options.strategy {
        Strategy::GaussNewton => gauss_newton((x0, start), options, objective)?,
        Strategy::LevenbergMarquardt => levenberg_marquardt((x0, start), options, objective)?,
    };
    solution.x.iter().all(|v| v.is_finite()).then_some(solution)
}

/// Whether the step `dx` from `from` to `to` is small by the options' test.
fn small_step<D: Dim>(
    options: &Options,
    dx: &OVector<f64, D>,
    from: &OVector<f64, D>,
    to: &OVector<f64, D>,
) -> bool
where
    DefaultAllocator: Allocator<D>,
{
    (options.small_step)(Step {
        length: dx.norm(),
        from: from.norm(),
        to: to.norm(),
    })
}

/// Gauss–Newton from `x` and its normal equations; the normal equations kept are those of
/// the point the last step was taken from (none is formed after the last step).
fn gauss_newton<D: Dim>(
    (mut x, mut normal): (OVector<f64, D>, Normal<D>),
    options: &Options,
    objective: &mut impl Objective<D>,
) -> Option<Solution<D>>
where
    DefaultAllocator: Allocator<D, D> + Allocator<D>,
{
    let mut iterations = 0;
    let mut converged = false;
    while iterations < options.max_iterations {
        let dx = normal.matrix.clone().try_inverse()? * -&normal.gradient;
        let dx = objective.limit_step(&x, dx);
        let from = x.clone();
        x += &dx;
        iterations += 1;
        converged = small_step(options, &dx, &from, &x);
        if converged || iterations == options.max_iterations {
            break;
        }
        normal = objective.normal(&x)?;
    }
    Some(Solution {
        x,
        normal,
        iterations,
        converged,
    })
}

/// Levenberg–Marquardt from `x` and its normal equations.
fn levenberg_marquardt<D: Dim>(
    (mut x, mut normal): (OVector<f64, D>, Normal<D>),
    options: &Options,
    objective: &mut impl Objective<D>,
) -> Option<Solution<D>>
where
    DefaultAllocator: Allocator<D, D> + Allocator<D>,
{
    let mut lambda = 1e-6;
    let mut iterations = 0;
    let mut converged = false;
    'outer: while iterations < options.max_iterations {
        iterations += 1;
        let mut improved = false;
        for _ in 0..12 {
            let mut damped = normal.matrix.clone();
            for k in 0..damped.nrows() {
                damped[(k, k)] += lambda * normal.matrix[(k, k)].max(1e-12);
            }
            let Some(cholesky) = damped.cholesky() else {
                lambda *= 10.0;
                continue;
            };
            let dx = cholesky.solve(&-&normal.gradient);
            let trial = &x + &dx;
            let Some(at_trial) = objective.normal(&trial) else {
                lambda *= 10.0;
                continue;
            };
            if at_trial.cost.is_finite() && at_trial.cost <= normal.cost {
                converged = small_step(options, &dx, &x, &trial)
                    || normal.cost - at_trial.cost < options.cost_tolerance * (1.0 + normal.cost);
                x = trial;
                normal = at_trial;
                lambda = (lambda * 0.1).max(1e-12);
                improved = true;
                if converged {
                    break 'outer;
                }
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    Some(Solution {
        x,
        normal,
        iterations,
        converged,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix2, Vector2, Vector3};

    /// Rosenbrock's valley as residuals `(10 (y − x²), 1 − x)`: minimum 0 at (1, 1).
    fn rosenbrock(p: &Vector2<f64>) -> Option<Normal<nalgebra::U2>> {
        let (x, y) = (p.x, p.y);
        let r = Vector2::new(10.0 * (y - x * x), 1.0 - x);
        let j = Matrix2::new(-20.0 * x, 10.0, -1.0, 0.0);
        Some(Normal {
            matrix: j.transpose() * j,
            gradient: j.transpose() * r,
            cost: r.norm_squared(),
        })
    }

    fn options(strategy: Strategy) -> Options {
        Options {
            strategy,
            max_iterations: 100,
            small_step: |s| s.length < 1e-12 * (1.0 + s.to),
            cost_tolerance: 0.0,
        }
    }

    #[test]
    fn both_strategies_find_rosenbrocks_minimum_from_its_classic_start() {
        for strategy in [Strategy::GaussNewton, Strategy::LevenbergMarquardt] {
            let s = minimize(Vector2::new(-1.2, 1.0), &options(strategy), &mut rosenbrock).unwrap();
            assert!(
                (s.x - Vector2::new(1.0, 1.0)).norm() < 1e-9,
                "{strategy:?}: {}",
                s.x
            );
            assert!(s.converged, "{strategy:?}");
        }
    }

    #[test]
    fn levenberg_marquardt_never_raises_the_cost() {
        let mut costs = Vec::new();
        let mut f = |p: &Vector2<f64>| {
            let n = rosenbrock(p);
            costs.push(n.as_ref().map_or(f64::INFINITY, |n| n.cost));
            n
        };
        let s = minimize(
            Vector2::new(-1.2, 1.0),
            &options(Strategy::LevenbergMarquardt),
            &mut f,
        )
        .unwrap();
        assert!(s.normal.cost <= costs[0]);
        assert!(s.normal.cost < 1e-20, "{}", s.normal.cost);
    }

    /// A step limit keeps Gauss–Newton inside the domain (here: `x > 0`, at most half way
    /// to 0 per step) where the full step would leave it.
    #[test]
    fn the_problems_step_limit_is_applied() {
        struct Log;
        impl Objective<nalgebra::U1> for Log {
            fn normal(&mut self, x: &nalgebra::Vector1<f64>) -> Option<Normal<nalgebra::U1>> {
                // r = ln x − ln 5, J = 1/x: undefined for x ≤ 0
                (x.x > 0.0).then(|| {
                    let (r, j) = (x.x.ln() - 5f64.ln(), 1.0 / x.x);
                    Normal {
                        matrix: nalgebra::Matrix1::new(j * j),
                        gradient: nalgebra::Vector1::new(j * r),
                        cost: r * r,
                    }
                })
            }
            fn limit_step(
                &self,
                x: &nalgebra::Vector1<f64>,
                step: nalgebra::Vector1<f64>,
            ) -> nalgebra::Vector1<f64> {
                step.map(|s| s.max(-0.5 * x.x))
            }
        }
        // from 100 the full Gauss–Newton step is −100 ln 20 ≈ −300: through 0
        let s = minimize(
            nalgebra::Vector1::new(100.0),
            &options(Strategy::GaussNewton),
            &mut Log,
        )
        .unwrap();
        assert!((s.x.x - 5.0).abs() < 1e-9, "{}", s.x);
    }

    #[test]
    fn no_iteration_asked_is_no_step_taken() {
        for strategy in [Strategy::GaussNewton, Strategy::LevenbergMarquardt] {
            let options = Options {
                max_iterations: 0,
                ..options(strategy)
            };
            let s = minimize(Vector2::new(-1.2, 1.0), &options, &mut rosenbrock).unwrap();
            assert_eq!(
                (s.x, s.iterations, s.converged),
                (Vector2::new(-1.2, 1.0), 0, false)
            );
        }
    }

    #[test]
    fn the_normal_equations_of_a_jacobian_are_its_products() {
        let j = DMatrix::from_row_slice(3, 2, &[1.0, 2.0, 0.0, 1.0, 3.0, -1.0]);
        let r = DVector::from_vec(vec![0.5, -1.0, 2.0]);
        let n = Normal::from_jacobian(&r, &j);
        assert_eq!(n.matrix, j.transpose() * &j);
        assert_eq!(n.gradient, j.transpose() * &r);
        assert_eq!(n.cost, 5.25);
    }

    /// A singular Gauss–Newton system (a direction the residuals do not depend on) is `None`;
    /// Levenberg–Marquardt's damping steps past it.
    #[test]
    fn a_flat_direction_stops_gauss_newton_but_not_levenberg_marquardt() {
        let mut flat = |p: &Vector3<f64>| {
            let r = DVector::from_vec(vec![p.x - 1.0, p.y + 2.0]);
            let j = DMatrix::from_row_slice(2, 3, &[1.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
            let n = Normal::from_jacobian(&r, &j);
            Some(Normal {
                matrix: n.matrix.fixed_view::<3, 3>(0, 0).into_owned(),
                gradient: n.gradient.fixed_rows::<3>(0).into_owned(),
                cost: n.cost,
            })
        };
        let start = Vector3::new(0.0, 0.0, 7.0);
        assert!(minimize(start, &options(Strategy::GaussNewton), &mut flat).is_none());
        let s = minimize(start, &options(Strategy::LevenbergMarquardt), &mut flat).unwrap();
        assert!(
            (s.x - Vector3::new(1.0, -2.0, 7.0)).norm() < 1e-9,
            "{}",
            s.x
        );
    }
}
