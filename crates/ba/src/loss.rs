//! Robust loss functions ρ(s) of the squared, σ-normalised residual norm s = |r/σ|².
//!
//! Conventions follow Ceres: the cost of one observation is ½ ρ(s), and a loss with scale
//! `a` is quadratic (ρ(s) ≈ s) for s ≪ a². The solver uses iteratively reweighted least
//! squares: the residual and its Jacobian are scaled by √ρ′(s) (for the losses here ρ″ ≤ 0,
//! where Ceres' second-order correction vanishes as well).

use serde::{Deserialize, Serialize};

/// A robust loss with its scale (in units of σ).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", content = "scale", rename_all = "lowercase")]
pub enum Loss {
    /// ρ(s) = s: ordinary least squares.
    #[default]
    Trivial,
    /// ρ(s) = s for s ≤ a², 2a√s − a² beyond.
    Huber(f64),
    /// ρ(s) = a² ln(1 + s/a²).
    Cauchy(f64),
}

impl Loss {
    /// ρ(s) and ρ′(s).
    #[inline]
    pub fn evaluate(&self, s: f64) -> (f64, f64) {
        match *self {
            Loss::Trivial => (s, 1.0),
            Loss::Huber(a) => {
                let a2 = a * a;
                if s <= a2 {
                    (s, 1.0)
                } else {
                    let r = s.sqrt();
                    (2.0 * a * r - a2, a / r)
                }
            }
            Loss::Cauchy(a) => {
                let a2 = a * a;
                let q = 1.0 + s / a2;
                (a2 * q.ln(), 1.0 / q)
            }
        }
    }

    /// Whether the scale is usable (positive and finite).
    pub fn is_valid(&self) -> bool {
        match *self {
            Loss::Trivial => true,
            Loss::Huber(a) | Loss::Cauchy(a) => a.is_finite() && a > 0.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn derivatives_match_differences_and_small_residuals_are_quadratic() {
        for loss in [Loss::Trivial, Loss::Huber(1.5), Loss::Cauchy(2.0)] {
            for s in [0.01, 0.5, 2.0, 9.0, 100.0] {
                let h = 1e-6 * s;
                let fd = (loss.evaluate(s + h).0 - loss.evaluate(s - h).0) / (2.0 * h);
                assert!((fd - loss.evaluate(s).1).abs() < 1e-7, "{loss:?} at {s}");
            }
            let (r, d) = loss.evaluate(1e-8);
            assert!((r - 1e-8).abs() < 1e-15 && (d - 1.0).abs() < 1e-7);
        }
    }
}
