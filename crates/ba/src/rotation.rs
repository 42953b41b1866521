//! Rotations on SO(3): the exponential and logarithm maps (angle-axis), the skew matrix,
//! and the photogrammetric ω, φ, κ angles.
//!
//! The local update used by the solver is multiplicative on the left:
//! `R ← exp([δ]×) · R`, with δ a 3-vector in radians. Its derivative with respect to δ at
//! δ = 0, applied to a vector `v`, is `∂(R v)/∂δ = −[R v]×`.

use nalgebra::{Matrix3, Vector3};

/// The skew-symmetric matrix `[v]×` with `[v]× w = v × w`.
#[inline]
pub fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// The exponential map: the rotation by angle `|w|` (radians) about the axis `w/|w|`
/// (Rodrigues' formula, with a Taylor expansion near zero so that it is exact to rounding).
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
        // θ/ sin θ ≈ 1 + θ²/6
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

/// Rotation from the photogrammetric angles ω, φ, κ (radians): `R = R_ω · R_φ · R_κ`, with
/// `R_ω` about X, `R_φ` about Y, `R_κ` about Z (each the passive, frame-to-frame form used by
/// Australis: the rows of R are the camera axes in object space).
pub fn from_opk(omega: f64, phi: f64, kappa: f64) -> Matrix3<f64> {
    let (so, co) = omega.sin_cos();
    let (sp, cp) = phi.sin_cos();
    let (sk, ck) = kappa.sin_cos();
    let rw = Matrix3::new(1.0, 0.0, 0.0, 0.0, co, so, 0.0, -so, co);
    let rp = Matrix3::new(cp, 0.0, -sp, 0.0, 1.0, 0.0, sp, 0.0, cp);
    let rk = Matrix3::new(ck, sk, 0.0, -sk, ck, 0.0, 0.0, 0.0, 1.0);
    rw * rp * rk
}

/// The angles ω, φ, κ (radians) of `r = R_ω · R_φ · R_κ` (see [`from_opk`]); φ in [−π/2, π/2].
pub fn to_opk(r: &Matrix3<f64>) -> (f64, f64, f64) {
    // With the passive forms: R[0][2] = −sin φ, R[1][2] = sin ω cos φ, R[2][2] = cos ω cos φ,
    // R[0][0] = cos φ cos κ, R[0][1] = cos φ sin κ.
    let phi = (-r[(0, 2)]).clamp(-1.0, 1.0).asin();
    let omega = r[(1, 2)].atan2(r[(2, 2)]);
    let kappa = r[(0, 1)].atan2(r[(0, 0)]);
    (omega, phi, kappa)
}

/// Makes `r` exactly orthonormal (nearest rotation by SVD), guarding against drift.
pub fn orthonormalize(r: &Matrix3<f64>) -> Matrix3<f64> {
    let svd = r.svd(true, true);
    let (u, vt) = (svd.u.unwrap(), svd.v_t.unwrap());
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
    fn opk_round_trip() {
        let (o, p, k) = (0.1, -0.4, 2.5);
        let r = from_opk(o, p, k);
        let (o2, p2, k2) = to_opk(&r);
        assert!((o - o2).abs() < 1e-12 && (p - p2).abs() < 1e-12 && (k - k2).abs() < 1e-12);
    }
}
