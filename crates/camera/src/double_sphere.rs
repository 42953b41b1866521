//! The double-sphere model (Usenko, Demmel & Cremers, "The Double Sphere Camera Model",
//! 3DV 2018; Kalibr's `ds`, Basalt's `ds`), in pixels: a point is projected onto a unit
//! sphere, then onto a second unit sphere shifted by ξ along the axis, then by a pinhole
//! shifted by α/(1 − α). It models lenses of more than 180° field of view with six
//! parameters and has a closed-form unprojection.
//!
//! # Frames and units
//! Camera frame of pingcal (X right, **Y along the optical axis**, Z up); the paper's (and
//! OpenCV's) frame is `x = X`, `y = −Z`, `z = Y`. Pixels: (0, 0) the centre of the top-left
//! pixel, u right, v down, so (cx, cy) are Kalibr's (pu, pv) unchanged.
//!
//! # The model
//! Parameters `fx, fy, cx, cy, xi, alpha` (Kalibr writes `[xi, alpha, fu, fv, pu, pv]`). In
//! the paper's frame, with `d₁ = |(x, y, z)|`, `s = ξ d₁ + z`, `d₂ = |(x, y, s)|` and
//! `D = α d₂ + (1 − α) s`:
//!
//! ```text
//! u = fx · x / D + cx,   v = fy · y / D + cy
//! ```
//!
//! A point projects when `z > −w₂ d₁`, with `w₁ = α/(1 − α)` for α ≤ ½ (else
//! `(1 − α)/α`) and `w₂ = (w₁ + ξ)/√(2 w₁ ξ + ξ² + 1)`: the region where the projection is
//! one-to-one (the paper's eq. 43). The unprojection, with `m = ((u − cx)/fx, (v − cy)/fy)`,
//! `r² = |m|²`, valid for α ≤ ½ or `r² ≤ 1/(2α − 1)`:
//!
//! ```text
//! m_z = (1 − α² r²) / (α √(1 − (2α − 1) r²) + 1 − α)
//! ray = (m_z ξ + √(m_z² + (1 − ξ²) r²)) / (m_z² + r²) · (m_x, m_y, m_z) − (0, 0, ξ)
//! ```
//!
//! # Jacobians
//! `∂d₁/∂p = p/d₁`, `∂s/∂p = ξ p/d₁ + e_z`, `∂d₂/∂p = (x e_x + y e_y + s ∂s/∂p)/d₂`,
//! `∂D/∂p = α ∂d₂/∂p + (1 − α) ∂s/∂p`, then `∂u/∂p = fx (e_x − (x/D) ∂D/∂p)/D` (v alike);
//! `∂D/∂ξ = (α s/d₂ + 1 − α) d₁`, `∂D/∂α = d₂ − s`, `∂u/∂θ = −fx x ∂D/∂θ / D²`.

use super::CameraModel;
use nalgebra::{Matrix2x3, Vector2, Vector3};

/// Names of the six parameters, in slice order.
pub const DOUBLE_SPHERE_PARAMS: [&str; 6] = ["fx", "fy", "cx", "cy", "xi", "alpha"];

/// The double-sphere model (see the module doc). It has no constants.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DoubleSphereCamera;

impl DoubleSphereCamera {
    /// `w₂` of the projection's validity condition `z > −w₂ d₁`.
    fn w2(xi: f64, alpha: f64) -> f64 {
        let w1 = if alpha <= 0.5 {
            alpha / (1.0 - alpha)
        } else {
            (1.0 - alpha) / alpha
        };
        (w1 + xi) / (2.0 * w1 * xi + xi * xi + 1.0).sqrt()
    }

    /// The largest angle off the optical axis that projects, radians (π for a model that
    /// sees all around but straight behind).
    pub fn max_angle(params: &[f64]) -> f64 {
        let w2 = Self::w2(params[4], params[5]).clamp(-1.0, 1.0);
        // z > −w₂ d₁ ⇔ cos θ > −w₂.
        (-w2).acos()
    }
}

impl CameraModel for DoubleSphereCamera {
    fn name(&self) -> &'static str {
        "double-sphere"
    }

    fn parameter_names(&self) -> &'static [&'static str] {
        &DOUBLE_SPHERE_PARAMS
    }

    /// On the axis `D = (1 + ξ) z`: the scale is f/(1 + ξ).
    fn focal_px(&self, params: &[f64]) -> f64 {
        0.5 * (params[0] + params[1]) / (1.0 + params[4])
    }

    fn principal_point_px(&self, params: &[f64]) -> Vector2<f64> {
        Vector2::new(params[2], params[3])
    }

    fn project(
        &self,
        params: &[f64],
        xc: &Vector3<f64>,
        jac_point: Option<&mut Matrix2x3<f64>>,
        jac_params: Option<&mut [f64]>,
    ) -> Option<Vector2<f64>> {
        let (fx, fy, cx, cy, xi, alpha) = (
            params[0], params[1], params[2], params[3], params[4], params[5],
        );
        // The paper's frame.
        let (x, y, z) = (xc.x, -xc.z, xc.y);
        let d1 = (x * x + y * y + z * z).sqrt();
        if !(d1 > 0.0 && d1.is_finite() && (0.0..1.0).contains(&alpha)) {
            return None;
        }
        if !(z > -Self::w2(xi, alpha) * d1) {
            return None;
        }
        let s = xi * d1 + z;
        let d2 = (x * x + y * y + s * s).sqrt();
        let den = alpha * d2 + (1.0 - alpha) * s;
        if !(den > 0.0) {
            return None;
        }
        let (mx, my) = (x / den, y / den);
        let uv = Vector2::new(fx * mx + cx, fy * my + cy);
        if let Some(jp) = jac_point {
            let p = Vector3::new(x, y, z);
            let ds = p * (xi / d1) + Vector3::z();
            let dd2 = (Vector3::new(x, y, 0.0) + ds * s) / d2;
            let dden = dd2 * alpha + ds * (1.0 - alpha);
            // ∂(u, v)/∂(x, y, z) in the paper's frame.
            let du = (Vector3::x() - dden * mx) * (fx / den);
            let dv = (Vector3::y() - dden * my) * (fy / den);
            // (X, Y, Z) = (x, z, −y): ∂/∂X = ∂/∂x, ∂/∂Y = ∂/∂z, ∂/∂Z = −∂/∂y.
            *jp = Matrix2x3::new(du.x, du.z, -du.y, dv.x, dv.z, -dv.y);
        }
        if let Some(ji) = jac_params {
            let dden_xi = (alpha * s / d2 + 1.0 - alpha) * d1;
            let dden_alpha = d2 - s;
            ji[..6].copy_from_slice(&[
                mx,
                0.0,
                1.0,
                0.0,
                -fx * mx * dden_xi / den,
                -fx * mx * dden_alpha / den,
            ]);
            ji[6..12].copy_from_slice(&[
                0.0,
                my,
                0.0,
                1.0,
                -fy * my * dden_xi / den,
                -fy * my * dden_alpha / den,
            ]);
        }
        Some(uv)
    }

    fn unproject(&self, params: &[f64], uv: &Vector2<f64>) -> Option<Vector3<f64>> {
        let (fx, fy, cx, cy, xi, alpha) = (
            params[0], params[1], params[2], params[3], params[4], params[5],
        );
        if fx == 0.0 || fy == 0.0 || !(0.0..1.0).contains(&alpha) {
            return None;
        }
        let (mx, my) = ((uv.x - cx) / fx, (uv.y - cy) / fy);
        let r2 = mx * mx + my * my;
        let inner = 1.0 - (2.0 * alpha - 1.0) * r2;
        if !(inner >= 0.0) {
            return None;
        }
        let mz = (1.0 - alpha * alpha * r2) / (alpha * inner.sqrt() + 1.0 - alpha);
        let disc = mz * mz + (1.0 - xi * xi) * r2;
        if !(disc >= 0.0) || mz * mz + r2 == 0.0 {
            return None;
        }
        let k = (mz * xi + disc.sqrt()) / (mz * mz + r2);
        let (x, y, z) = (k * mx, k * my, k * mz - xi);
        let ray = Vector3::new(x, z, -y);
        let n = ray.norm();
        if !(n > 0.0 && n.is_finite()) {
            return None;
        }
        let ray = ray / n;
        // Outside the one-to-one region the formula gives a ray that projects elsewhere.
        let back = self.project(params, &ray, None, None)?;
        ((back - uv).norm() <= 1e-6 * (1.0 + uv.norm())).then_some(ray)
    }
}

#[cfg(test)]
mod tests {
    use super::super::jacobian_checks::{check, rng, uniform};
    use super::*;

    /// A 190° lens on a 1280 × 800 sensor (Usenko et al.'s fitted values are ξ ≈ −0.2,
    /// α ≈ 0.6 for such lenses).
    fn random_params(r: &mut pingcal_geometry::consensus::SeededRng) -> [f64; 6] {
        [
            uniform(r, 330.0, 370.0),
            uniform(r, 330.0, 370.0),
            uniform(r, 620.0, 660.0),
            uniform(r, 380.0, 420.0),
            uniform(r, -0.3, 0.1),
            uniform(r, 0.5, 0.65),
        ]
    }

    /// A random direction θ off axis, at a random distance.
    fn point(r: &mut pingcal_geometry::consensus::SeededRng, t: f64) -> Vector3<f64> {
        let az = uniform(r, -std::f64::consts::PI, std::f64::consts::PI);
        let d = uniform(r, 0.3, 5.0);
        Vector3::new(t.sin() * az.cos(), t.cos(), t.sin() * az.sin()) * d
    }

    #[test]
    fn jacobians_match_central_differences_over_the_whole_field_of_view() {
        let mut r = rng(61);
        let mut worst: f64 = 0.0;
        for _ in 0..500 {
            let p = random_params(&mut r);
            let t = uniform(&mut r, 0.0, 0.98 * DoubleSphereCamera::max_angle(&p));
            worst = worst.max(check(&DoubleSphereCamera, &p, &point(&mut r, t), 1e-6));
        }
        for t in [0.0, 1e-9, 1e-4, 0.5, std::f64::consts::FRAC_PI_2, 1.65] {
            let p = random_params(&mut r);
            worst = worst.max(check(&DoubleSphereCamera, &p, &point(&mut r, t), 1e-6));
        }
        println!("double sphere: worst relative Jacobian error {worst:.2e}");
    }

    #[test]
    fn unproject_inverts_project_over_the_whole_field_of_view() {
        let mut r = rng(62);
        for _ in 0..2000 {
            let p = random_params(&mut r);
            let t = uniform(&mut r, 0.0, 0.999 * DoubleSphereCamera::max_angle(&p));
            let xc = point(&mut r, t);
            let uv = DoubleSphereCamera.project(&p, &xc, None, None).unwrap();
            let ray = DoubleSphereCamera.unproject(&p, &uv).unwrap();
            assert!(
                (ray - xc.normalize()).norm() < 1e-9,
                "θ {t}: {ray:?} {xc:?}"
            );
        }
    }

    #[test]
    fn beyond_its_field_of_view_nothing_projects() {
        let p = [350.0, 350.0, 640.0, 400.0, -0.2, 0.6];
        let max = DoubleSphereCamera::max_angle(&p);
        // ξ = −0.2, α = 0.6: w₁ = 2/3, w₂ = 0.4667/0.8794 = 0.5307, a field of 2 × 122.05°.
        assert!(
            (max.to_degrees() - 122.05).abs() < 0.01,
            "{}",
            max.to_degrees()
        );
        let mut r = rng(63);
        for _ in 0..100 {
            let t = uniform(&mut r, max + 1e-6, std::f64::consts::PI);
            assert!(DoubleSphereCamera
                .project(&p, &point(&mut r, t), None, None)
                .is_none());
        }
        assert!(DoubleSphereCamera
            .project(&p, &Vector3::zeros(), None, None)
            .is_none());
    }

    /// The paper's formula, written out in its own frame, for points in front and beside.
    #[test]
    fn matches_the_papers_formula() {
        let (fx, fy, cx, cy, xi, alpha) = (348.1, 347.9, 641.2, 399.3, -0.21, 0.59);
        let p = [fx, fy, cx, cy, xi, alpha];
        for (x, y, z) in [
            (0.3f64, -0.2f64, 1.0f64),
            (2.0, 0.5, 0.1),
            (-1.0, 1.0, -0.3),
        ] {
            let d1 = (x * x + y * y + z * z).sqrt();
            let d2 = (x * x + y * y + (xi * d1 + z) * (xi * d1 + z)).sqrt();
            let den = alpha * d2 + (1.0 - alpha) * (xi * d1 + z);
            let expected = Vector2::new(fx * x / den + cx, fy * y / den + cy);
            let uv = DoubleSphereCamera
                .project(&p, &Vector3::new(x, z, -y), None, None)
                .unwrap();
            assert!((uv - expected).norm() < 1e-10, "{uv:?} {expected:?}");
        }
    }
}
