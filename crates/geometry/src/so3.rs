//! Rotations on SO(3): the skew matrix, the exponential and logarithm maps (angle-axis),
//! re-orthonormalisation.
//!
//! The local update used by every solver of pingcal is multiplicative on the left:
//! `R ← exp([δ]×) · R`, with δ a 3-vector in radians about the axes of the frame R maps
//! *into*. Its derivative with respect to δ at δ = 0, applied to a vector `v`, is
//! `∂(R v)/∂δ = −[R v]×`.

use nalgebra::{Matrix3, Vector3};

/// The skew-symmetric matrix `[v]×` with `[v]× w = v × w`.
#[inline]
pub fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// The exponential map: the rotation by angle `|w|` (radians) about the axis `w/|w|`
/// (Rodrigues' formula `I + sin θ/θ [w]× + (1 − cos θ)/θ² [w]×²`, with a Taylor expansion
/// near zero so that it is exact to rounding).
pub fn exp_so3(w: &Vector3<f64>) -> Matrix3<f64> {
    let theta2 = w.norm_squared();
    let k = skew(w);
    let (a, b) = if theta2 < 1e-12 {
        // sin θ / θ and (1 − cos θ)/θ² to second order.
        (1.0 - theta2 / 6.0, 0.5 - theta2 / 24.0)
    } else {
        let theta = theta2.sqrt();
        (theta.sin() / theta, (1.0 - theta.cos()) / theta2)
    };
    Matrix3::identity() + k * a + k * k * b
}

/// The logarithm map: the angle-axis vector `w` with `exp_so3(w) = r`, `|w| ≤ π`.
///
/// `r` must be a rotation (orthonormal, det +1) to rounding; near θ = π the axis is taken
/// from the symmetric part, which is well conditioned there.
pub fn log_so3(r: &Matrix3<f64>) -> Vector3<f64> {
    let cos = ((r.trace() - 1.0) * 0.5).clamp(-1.0, 1.0);
    let v = Vector3::new(
        r[(2, 1)] - r[(1, 2)],
        r[(0, 2)] - r[(2, 0)],
        r[(1, 0)] - r[(0, 1)],
    );
    let sin = 0.5 * v.norm();
    let theta = sin.atan2(cos);
    if theta < 1e-6 {
        // θ / sin θ ≈ 1 + θ²/6
        return v * (0.5 * (1.0 + theta * theta / 6.0));
    }
    if std::f64::consts::PI - theta > 1e-4 {
        return v * (0.5 * theta / sin);
    }
    // Near π: the symmetric part is cos θ I + (1 − cos θ) a aᵀ, so (R + Rᵀ)/2 − cos θ I is
    // (1 − cos θ) a aᵀ; take its largest column (free of the small antisymmetric part).
    let b = (r + r.transpose()) * 0.5 - Matrix3::identity() * cos;
    let (mut best, mut bn) = (0, 0.0);
    for j in 0..3 {
        let n = b.column(j).norm();
        if n > bn {
            best = j;
            bn = n;
        }
    }
    let mut axis: Vector3<f64> = b.column(best) / bn;
    // Fix the sign so that the small antisymmetric part agrees.
    if axis.dot(&v) < 0.0 {
        axis = -axis;
    }
    axis * theta
}

/// The angle of the rotation `r` (radians, in [0, π]): `|log_so3(r)|`, computed from the
/// trace; π (the worst) for a non-finite matrix, so that a comparison against a tolerance
/// fails instead of passing on NaN.
pub fn rotation_angle(r: &Matrix3<f64>) -> f64 {
    let c = ((r.trace() - 1.0) * 0.5).clamp(-1.0, 1.0);
    if c.is_nan() {
        std::f64::consts::PI
    } else {
        c.acos()
    }
}

/// Makes `r` exactly orthonormal (the nearest rotation by SVD), guarding against drift.
pub fn orthonormalize(r: &Matrix3<f64>) -> Matrix3<f64> {
    let svd = r.svd(true, true);
    let (Some(u), Some(vt)) = (svd.u, svd.v_t) else {
        return *r;
    };
    let mut m = u * vt;
    if m.determinant() < 0.0 {
        let mut u2 = u;
        u2.column_mut(2).neg_mut();
        m = u2 * vt;
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exp_log_round_trip_including_near_pi_and_zero() {
        let cases = [
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(1e-9, -2e-9, 3e-9),
            Vector3::new(0.3, -0.2, 0.1),
            Vector3::new(1.0, 2.0, -0.5).normalize() * (std::f64::consts::PI - 1e-7),
            Vector3::new(0.0, 0.0, 3.0),
        ];
        for w in cases {
            let r = exp_so3(&w);
            assert!((r.transpose() * r - Matrix3::identity()).norm() < 1e-14);
            assert!((r.determinant() - 1.0).abs() < 1e-14);
            let w2 = log_so3(&r);
            assert!((exp_so3(&w2) - r).norm() < 1e-12, "{w:?} -> {w2:?}");
            assert!((rotation_angle(&r) - w2.norm()).abs() < 1e-7);
        }
    }

    #[test]
    fn left_perturbation_derivative_is_minus_skew() {
        let r = exp_so3(&Vector3::new(0.4, -0.7, 1.1));
        let v = Vector3::new(0.3, 2.0, -1.0);
        let h = 1e-6;
        let analytic = -skew(&(r * v));
        for k in 0..3 {
            let mut d = Vector3::zeros();
            d[k] = h;
            let fd = (exp_so3(&d) * r * v - exp_so3(&(-d)) * r * v) / (2.0 * h);
            assert!((fd - analytic.column(k)).norm() < 1e-9);
        }
    }

    #[test]
    fn orthonormalize_restores_a_rotation() {
        let r = exp_so3(&Vector3::new(0.2, 0.5, -0.3)) + Matrix3::repeat(1e-6);
        let m = orthonormalize(&r);
        assert!((m.transpose() * m - Matrix3::identity()).norm() < 1e-14);
        assert!((m.determinant() - 1.0).abs() < 1e-14);
        assert!((m - r).norm() < 1e-5);
    }
}
