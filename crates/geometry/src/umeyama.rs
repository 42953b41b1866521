//! The closed-form transform between two point sets (Horn 1987; Umeyama 1991), weighted.
//!
//! Given pairs `(pᵢ, qᵢ)` and weights `wᵢ ≥ 0`, it minimises `Σ wᵢ |qᵢ − (s R pᵢ + t)|²`:
//! with the weighted means `p̄, q̄` and `H = Σ wᵢ (qᵢ − q̄)(pᵢ − p̄)ᵀ = U Σ Vᵀ`,
//! `R = U D Vᵀ` with `D = diag(1, 1, det(U Vᵀ))` (a proper rotation even for noisy or
//! planar data), `s = tr(Σ D) / Σ wᵢ |pᵢ − p̄|²` when the scale is estimated (else 1), and
//! `t = q̄ − s R p̄`. The result is `dst_from_src`.
//!
//! Three points not on a line determine it; on a line the rotation about it is free and the
//! SVD picks one — callers that must know check collinearity first (the registration does).

use crate::rigid::Sim3;
use nalgebra::{Matrix3, Vector3};

/// Why [`umeyama`] gave no transform.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum UmeyamaError {
    /// The two sets differ in length (or the weights do).
    #[error("{src} source points, {dst} target points and {weights} weights: they must pair up")]
    LengthMismatch {
        /// Source points.
        src: usize,
        /// Target points.
        dst: usize,
        /// Weights (the point count when none were given).
        weights: usize,
    },
    /// Fewer than 3 pairs.
    #[error("{0} point pairs: a 3D transform needs at least 3")]
    TooFew(usize),
    /// The weights are not positive in sum (or not finite).
    #[error("the weights sum to {0}: they must be positive")]
    Weights(f64),
    /// All source points coincide, so no scale can be taken.
    #[error("all source points coincide: no scale")]
    Coincident,
    /// A non-finite input or result.
    #[error("the closed-form transform is not finite (non-finite points?)")]
    NotFinite,
}

/// `dst ≈ s R src + t` by weighted least squares (`weights: None` = all 1), with `s = 1`
/// unless `with_scale`. See the module doc for the formulas.
pub fn umeyama(
    src: &[Vector3<f64>],
    dst: &[Vector3<f64>],
    weights: Option<&[f64]>,
    with_scale: bool,
) -> Result<Sim3, UmeyamaError> {
    let nw = weights.map_or(src.len(), <[f64]>::len);
    if src.len() != dst.len() || nw != src.len() {
        return Err(UmeyamaError::LengthMismatch {
            src: src.len(),
            dst: dst.len(),
            weights: nw,
        });
    }
    if src.len() < 3 {
        return Err(UmeyamaError::TooFew(src.len()));
    }
    let w = |i: usize| weights.map_or(1.0, |w| w[i]);
    let ws: f64 = (0..src.len()).map(w).sum();
    if !(ws > 0.0 && ws.is_finite()) {
        return Err(UmeyamaError::Weights(ws));
    }
    let ms = (0..src.len()).map(|i| src[i] * w(i)).sum::<Vector3<f64>>() / ws;
    let md = (0..src.len()).map(|i| dst[i] * w(i)).sum::<Vector3<f64>>() / ws;
    let mut cov = Matrix3::zeros();
    let mut var_s = 0.0;
    for (i, (p, q)) in src.iter().zip(dst).enumerate() {
        cov += (q - md) * (p - ms).transpose() * w(i);
        var_s += w(i) * (p - ms).norm_squared();
    }
    if !cov.iter().all(|v| v.is_finite()) {
        return Err(UmeyamaError::NotFinite);
    }
    let svd = cov.svd(true, true);
    let (Some(u), Some(vt)) = (svd.u, svd.v_t) else {
        return Err(UmeyamaError::NotFinite);
    };
    let mut d = Matrix3::identity();
    if (u * vt).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    let r = u * d * vt;
    let scale = if with_scale {
        if !(var_s > 0.0) {
            return Err(UmeyamaError::Coincident);
        }
        svd.singular_values.component_mul(&d.diagonal()).sum() / var_s
    } else {
        1.0
    };
    let t = md - r * ms * scale;
    if !(r.iter().all(|v| v.is_finite()) && t.iter().all(|v| v.is_finite()) && scale.is_finite()) {
        return Err(UmeyamaError::NotFinite);
    }
    Ok(Sim3::new(scale, r, t))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::opk::from_opk;

    fn cloud() -> Vec<Vector3<f64>> {
        (0..12)
            .map(|i| {
                let f = i as f64;
                Vector3::new(f.sin() * 100.0, f * 13.0 - 40.0, (f * 0.7).cos() * 60.0)
            })
            .collect()
    }

    #[test]
    fn recovers_an_exact_similarity_and_a_rigid_one() {
        let truth = Sim3::new(1.7, from_opk(0.4, -1.1, 2.9), Vector3::new(5.0, -7.0, 30.0));
        let src = cloud();
        let dst: Vec<_> = src.iter().map(|p| truth.transform(p)).collect();
        let s = umeyama(&src, &dst, None, true).unwrap();
        assert!((s.rotation - truth.rotation).norm() < 1e-12);
        assert!((s.scale - 1.7).abs() < 1e-12 && (s.translation - truth.translation).norm() < 1e-9);
        let rigid = Sim3 {
            scale: 1.0,
            ..truth
        };
        let dst: Vec<_> = src.iter().map(|p| rigid.transform(p)).collect();
        let r = umeyama(&src, &dst, Some(&vec![2.0; src.len()]), false).unwrap();
        assert!((r.rotation - truth.rotation).norm() < 1e-12 && r.scale == 1.0);
    }

    #[test]
    fn weights_turn_off_an_outlier() {
        let truth = Sim3::new(1.0, from_opk(0.1, 0.2, 0.3), Vector3::new(1.0, 2.0, 3.0));
        let src = cloud();
        let mut dst: Vec<_> = src.iter().map(|p| truth.transform(p)).collect();
        dst[3].x += 500.0;
        let mut w = vec![1.0; src.len()];
        w[3] = 0.0;
        let r = umeyama(&src, &dst, Some(&w), false).unwrap();
        assert!((r.translation - truth.translation).norm() < 1e-9);
    }

    #[test]
    fn bad_inputs_are_named() {
        let p = cloud();
        assert!(matches!(
            umeyama(&p[..2], &p[..2], None, false),
            Err(UmeyamaError::TooFew(2))
        ));
        assert!(matches!(
            umeyama(&p, &p[..5], None, false),
            Err(UmeyamaError::LengthMismatch { .. })
        ));
        let z = vec![0.0; p.len()];
        assert!(matches!(
            umeyama(&p, &p, Some(&z), false),
            Err(UmeyamaError::Weights(_))
        ));
        let same = vec![Vector3::new(1.0, 1.0, 1.0); 4];
        assert_eq!(
            umeyama(&same, &same, None, true),
            Err(UmeyamaError::Coincident)
        );
        let mut nan = p.clone();
        nan[0].x = f64::NAN;
        assert_eq!(umeyama(&nan, &p, None, false), Err(UmeyamaError::NotFinite));
    }
}
