//! The camera model of the Bundle Adjustment in the Large (BAL) data sets
//! (Agarwal, Snavely, Seitz, Szeliski 2010), so that public BA benchmarks run unchanged.
//!
//! Parameters `[f, k1, k2]`. With `P = R·X + t` the point in the camera frame,
//! `p = −P_xy / P_z` (the camera looks down −z), and
//! `(u, v) = f · (1 + k1·|p|² + k2·|p|⁴) · p`. BAL's image coordinates have their origin at
//! the image centre and **y up**; the model reports them as they are in the file, so that
//! residuals and costs are those Ceres reports on the same file.

use super::CameraModel;
use nalgebra::{Matrix2x3, Vector2, Vector3};

/// The BAL camera model (see the module doc). It has no constants.
#[derive(Clone, Copy, Debug, Default)]
pub struct BalCamera;

const NAMES: [&str; 3] = ["f", "k1", "k2"];

impl CameraModel for BalCamera {
    fn name(&self) -> &'static str {
        "bal"
    }

    fn parameter_names(&self) -> &'static [&'static str] {
        &NAMES
    }

    fn focal_px(&self, params: &[f64]) -> f64 {
        params[0]
    }

    /// BAL's image origin is the principal point.
    fn principal_point_px(&self, _params: &[f64]) -> Vector2<f64> {
        Vector2::zeros()
    }

    fn project(
        &self,
        params: &[f64],
        xc: &Vector3<f64>,
        jac_point: Option<&mut Matrix2x3<f64>>,
        jac_params: Option<&mut [f64]>,
    ) -> Option<Vector2<f64>> {
        let (f, k1, k2) = (params[0], params[1], params[2]);
        if !(xc.z.abs() > 1e-12 * xc.norm()) {
            return None;
        }
        let iz = 1.0 / xc.z;
        let p = Vector2::new(-xc.x * iz, -xc.y * iz);
        let r2 = p.norm_squared();
        let d = 1.0 + r2 * (k1 + k2 * r2);
        let uv = p * (f * d);
        if let Some(jp) = jac_point {
            // ∂uv/∂p = f (d I + p (∂d/∂p)ᵀ), ∂d/∂p = 2 (k1 + 2 k2 r²) p.
            let dd = 2.0 * (k1 + 2.0 * k2 * r2);
            let a00 = f * (d + dd * p.x * p.x);
            let a01 = f * dd * p.x * p.y;
            let a11 = f * (d + dd * p.y * p.y);
            // ∂p/∂P = [[−1/z, 0, x/z²], [0, −1/z, y/z²]] = [[−iz, 0, −px iz], [0, −iz, −py iz]].
            let (b00, b02) = (-iz, -p.x * iz);
            let (b11, b12) = (-iz, -p.y * iz);
            *jp = Matrix2x3::new(
                a00 * b00,
                a01 * b11,
                a00 * b02 + a01 * b12,
                a01 * b00,
                a11 * b11,
                a01 * b02 + a11 * b12,
            );
        }
        if let Some(ji) = jac_params {
            let r4 = r2 * r2;
            ji[0] = d * p.x;
            ji[1] = f * r2 * p.x;
            ji[2] = f * r4 * p.x;
            ji[3] = d * p.y;
            ji[4] = f * r2 * p.y;
            ji[5] = f * r4 * p.y;
        }
        Some(uv)
    }

    fn unproject(&self, params: &[f64], uv: &Vector2<f64>) -> Option<Vector3<f64>> {
        let (f, k1, k2) = (params[0], params[1], params[2]);
        if f == 0.0 {
            return None;
        }
        let q = uv / f; // = d(|p|) p
        let qn = q.norm();
        // Solve ρ (1 + k1 ρ² + k2 ρ⁴) = |q| for ρ = |p| by Newton from ρ = |q|.
        let mut rho = qn;
        for _ in 0..30 {
            let r2 = rho * rho;
            let g = rho * (1.0 + k1 * r2 + k2 * r2 * r2) - qn;
            let dg = 1.0 + 3.0 * k1 * r2 + 5.0 * k2 * r2 * r2;
            if dg <= 0.0 {
                return None;
            }
            let step = g / dg;
            rho -= step;
            if step.abs() < 1e-15 * rho.max(1.0) {
                break;
            }
        }
        let p = if qn > 0.0 { q * (rho / qn) } else { q };
        Some(Vector3::new(-p.x, -p.y, 1.0).normalize() * -1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::super::jacobian_checks::{check, rng, uniform};
    use super::*;

    #[test]
    fn jacobians_match_central_differences_at_random_states() {
        let mut r = rng(7);
        for _ in 0..200 {
            let params = [
                uniform(&mut r, 300.0, 1500.0),
                uniform(&mut r, -0.3, 0.3),
                uniform(&mut r, -0.1, 0.1),
            ];
            let xc = Vector3::new(
                uniform(&mut r, -2.0, 2.0),
                uniform(&mut r, -2.0, 2.0),
                uniform(&mut r, -8.0, -2.0),
            );
            check(&BalCamera, &params, &xc, 1e-6);
        }
    }

    #[test]
    fn unproject_inverts_project() {
        let params = [800.0, -0.1, 0.02];
        let xc = Vector3::new(0.5, -0.3, -3.0);
        let uv = BalCamera.project(&params, &xc, None, None).unwrap();
        let ray = BalCamera.unproject(&params, &uv).unwrap();
        assert!((ray - xc.normalize()).norm() < 1e-12, "{ray:?}");
    }
}
