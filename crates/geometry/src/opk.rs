//! The one angle convention of pingcal: ω, φ, κ of a rotation `a_from_b`.
//!
//! `R = R_ω · R_φ · R_κ`, each factor the *passive* (frame-to-frame) elementary rotation
//! that photogrammetry uses (Australis, PhotoModeler, DBAT, the paper's Table 3):
//!
//! ```text
//!        ⎡1    0     0  ⎤        ⎡cos φ  0  −sin φ⎤        ⎡ cos κ  sin κ  0⎤
//! R_ω =  ⎢0  cos ω  sin ω⎥   R_φ = ⎢  0    1    0  ⎥   R_κ = ⎢−sin κ  cos κ  0⎥
//!        ⎣0 −sin ω  cos ω⎦        ⎣sin φ  0   cos φ⎦        ⎣   0      0    1⎦
//! ```
//!
//! For a rotation `a_from_b` the rows of R are the axes of frame `a` written in frame `b`:
//! ω, φ, κ turn frame `b` into frame `a`, first about its X axis by ω, then about the new Y
//! by φ, then about the new Z by κ. An image's exterior orientation (`camera_from_object`)
//! and the extrinsic (`camera_from_lrf`) are printed this way, in every command, in
//! `results.json` (`opk_deg`), in `truth.json` and in the report.
//!
//! The passive elementary rotations are the transposes of the active (counter-clockwise)
//! ones, so in terms of the active `R_x, R_y, R_z`: `R = R_x(−ω) R_y(−φ) R_z(−κ)`. Code that
//! wants "the rotation by these angles" in the active sense must negate them; there is no
//! second convention in pingcal.
//!
//! φ is in [−π/2, π/2]; at φ = ±π/2 (gimbal lock) ω and κ are not separable and [`to_opk`]
//! returns κ = atan2(R₀₁, R₀₀) of the rounded matrix, which is still a valid decomposition.

use nalgebra::{Matrix3, Vector3};

/// Rotation from the angles ω, φ, κ (radians): `R = R_ω · R_φ · R_κ` (passive factors, see
/// the module doc).
pub fn from_opk(omega: f64, phi: f64, kappa: f64) -> Matrix3<f64> {
    let (so, co) = omega.sin_cos();
    let (sp, cp) = phi.sin_cos();
    let (sk, ck) = kappa.sin_cos();
    let rw = Matrix3::new(1.0, 0.0, 0.0, 0.0, co, so, 0.0, -so, co);
    let rp = Matrix3::new(cp, 0.0, -sp, 0.0, 1.0, 0.0, sp, 0.0, cp);
    let rk = Matrix3::new(ck, sk, 0.0, -sk, ck, 0.0, 0.0, 0.0, 1.0);
    rw * rp * rk
}

/// The angles ω, φ, κ (radians) of `r = R_ω · R_φ · R_κ` (see [`from_opk`]); φ in
/// [−π/2, π/2], ω and κ in (−π, π].
pub fn to_opk(r: &Matrix3<f64>) -> (f64, f64, f64) {
    // With the passive forms: R[0][2] = −sin φ, R[1][2] = sin ω cos φ, R[2][2] = cos ω cos φ,
    // R[0][0] = cos φ cos κ, R[0][1] = cos φ sin κ.
    let phi = (-r[(0, 2)]).clamp(-1.0, 1.0).asin();
    let omega = r[(1, 2)].atan2(r[(2, 2)]);
    let kappa = r[(0, 1)].atan2(r[(0, 0)]);
    (omega, phi, kappa)
}

/// [`from_opk`] with the angles in degrees, as files and users give them.
pub fn from_opk_deg(opk_deg: [f64; 3]) -> Matrix3<f64> {
    from_opk(
        opk_deg[0].to_radians(),
        opk_deg[1].to_radians(),
        opk_deg[2].to_radians(),
    )
}

/// [`to_opk`] in degrees, as every output of pingcal prints it.
pub fn to_opk_deg(r: &Matrix3<f64>) -> [f64; 3] {
    let (o, p, k) = to_opk(r);
    [o.to_degrees(), p.to_degrees(), k.to_degrees()]
}

/// The standard deviations of ω, φ, κ (degrees) of the rotation `r` whose left update
/// `r ← exp([δθ]×) r` has covariance `cov_dtheta` (rad²): `J Σ Jᵀ` with `J = ∂(ω, φ, κ)/∂δθ`
/// by central differences of [`to_opk`] (a component that jumps by ±π across the step,
/// at gimbal lock, gets a zero column rather than 2π/h).
pub fn opk_sigma_deg(r: &Matrix3<f64>, cov_dtheta: &Matrix3<f64>) -> [f64; 3] {
    let opk = |m: &Matrix3<f64>| {
        let (o, p, k) = to_opk(m);
        Vector3::new(o, p, k)
    };
    let e0 = opk(r);
    let h = 1e-7;
    let mut j = Matrix3::zeros();
    for k in 0..3 {
        let mut d = Vector3::zeros();
        d[k] = h;
        let ep = opk(&(crate::so3::exp_so3(&d) * r));
        let em = opk(&(crate::so3::exp_so3(&-d) * r));
        let mut col = (ep - em) / (2.0 * h);
        for q in 0..3 {
            if (ep[q] - e0[q]).abs() > 1.0 || (em[q] - e0[q]).abs() > 1.0 {
                col[q] = 0.0;
            }
        }
        j.set_column(k, &col);
    }
    let c = j * cov_dtheta * j.transpose();
    [0, 1, 2].map(|k| c[(k, k)].max(0.0).sqrt().to_degrees())
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Rotation3, Vector3};

    /// At the identity, ω φ κ are the rotation-vector components to first order, so their
    /// σ's are those of δθ; and a rotation about Z only moves κ.
    #[test]
    fn opk_sigmas_follow_the_rotation_covariance() {
        let cov = Matrix3::from_diagonal(&Vector3::new(1e-6, 4e-6, 9e-6));
        let s = opk_sigma_deg(&Matrix3::identity(), &cov);
        for (k, want) in [1e-3f64, 2e-3, 3e-3].iter().enumerate() {
            assert!(
                (s[k] - want.to_degrees()).abs() < 1e-9 * want.to_degrees(),
                "{s:?}"
            );
        }
        let z = Matrix3::from_diagonal(&Vector3::new(0.0, 0.0, 1e-6));
        let s = opk_sigma_deg(&from_opk(0.3, -0.2, 1.0), &z);
        assert!(s[2] > 0.0 && s.iter().all(|v| v.is_finite()), "{s:?}");
    }

    #[test]
    fn opk_round_trip() {
        for &(o, p, k) in &[(0.1, -0.4, 2.5), (-3.0, 1.2, -0.1), (0.0, 0.0, 0.0)] {
            let (o2, p2, k2) = to_opk(&from_opk(o, p, k));
            assert!((o - o2).abs() < 1e-12 && (p - p2).abs() < 1e-12 && (k - k2).abs() < 1e-12);
        }
        let d = to_opk_deg(&from_opk_deg([0.8, -1.2, 0.6]));
        assert!(
            (d[0] - 0.8).abs() < 1e-12 && (d[1] + 1.2).abs() < 1e-12 && (d[2] - 0.6).abs() < 1e-12
        );
    }

    /// The module doc's statement: passive factors are active ones with the angles negated,
    /// and the rows of `a_from_b` are `a`'s axes in `b`.
    #[test]
    fn passive_is_active_with_negated_angles() {
        let (o, p, k) = (0.3, -0.2, 1.1);
        let active = (Rotation3::from_axis_angle(&Vector3::x_axis(), -o)
            * Rotation3::from_axis_angle(&Vector3::y_axis(), -p)
            * Rotation3::from_axis_angle(&Vector3::z_axis(), -k))
        .into_inner();
        assert!((from_opk(o, p, k) - active).norm() < 1e-15);
        // A camera turned by κ = +90° about Z: its X axis is the object's Y axis.
        let r = from_opk(0.0, 0.0, std::f64::consts::FRAC_PI_2);
        assert!((r.row(0).transpose() - Vector3::y()).norm() < 1e-15);
    }
}
