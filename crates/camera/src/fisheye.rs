//! The Kannala–Brandt fisheye model as OpenCV's `cv::fisheye` writes it (without its skew
//! α), in pixels: an equidistant projection with an odd polynomial in the angle off axis.
//!
//! # Frames and units
//! Camera frame of docs/formats.md (X right, **Y along the optical axis**, Z up); OpenCV's frame is
//! `x_cv = X`, `y_cv = −Z`, `z_cv = Y` (see [`super::OpenCvCamera`]). Pixels: integer
//! coordinates at pixel centres, (0, 0) the centre of the top-left pixel, u right, v down —
//! OpenCV's convention and pingcal's, so (cx, cy) are OpenCV's numbers unchanged.
//!
//! # The model
//! Parameters `fx, fy, cx, cy, k1, k2, k3, k4` (OpenCV's order: K, then `D`). With
//! `ρ = √(X² + Z²)`, the angle off the optical axis `θ = atan2(ρ, Y)` ∈ [0, π] and
//!
//! ```text
//! θd = θ (1 + k1 θ² + k2 θ⁴ + k3 θ⁶ + k4 θ⁸)
//! x' = θd · X/ρ,   y' = −θd · Z/ρ
//! u  = fx x' + cx,   v = fy y' + cy
//! ```
//!
//! For Y > 0 this is OpenCV's `θ = atan(r)`, `r = |(x_cv, y_cv)|/z_cv`; using `atan2`
//! extends it to points at and beyond 90° off axis, which a fisheye lens can see. Every
//! point with θ < π projects; the point straight behind the camera (ρ = 0, Y ≤ 0), where
//! the direction X/ρ is undefined, is refused. Near the optical axis (θ → 0) the model is
//! evaluated as `g = θd/ρ = P(θ²)·(θ/sin θ)/|xc|` with `P = θd/θ`, and the derivative of g
//! along ρ through the series of `(sin θ cos θ − θ)/θ³` for θ < 0.1, so that value and
//! Jacobian are finite and accurate down to θ = 0 exactly.
//!
//! # Jacobians
//! With `L = |xc|`, `s = sin θ = ρ/L`, `θd' = dθd/dθ = P + 2θ² P'` (P' = dP/d(θ²)):
//! `∂g/∂Y = −θd'/L²` and `∂g/∂X = X·h`, `∂g/∂Z = Z·h` with
//! `h = (θd' s cos θ − θd)/(L³ s³) = [P·S(θ) + 2P'·(sin θ cos θ)/θ]·(θ/s)³/L³`,
//! `S(θ) = (sin θ cos θ − θ)/θ³`. Then `∂x'/∂xc = g·e_X + X ∂g/∂xc` and
//! `∂y'/∂xc = −(g·e_Z + Z ∂g/∂xc)`; `∂g/∂k_i = θ^{2i}·θ/ρ`.

use super::CameraModel;
use nalgebra::{Matrix2x3, Vector2, Vector3};

/// Names of the eight parameters, in slice order (OpenCV's).
pub const FISHEYE_PARAMS: [&str; 8] = ["fx", "fy", "cx", "cy", "k1", "k2", "k3", "k4"];

/// The Kannala–Brandt fisheye model (see the module doc). It has no constants.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FisheyeCamera;

/// S(θ) = (sin θ cos θ − θ)/θ³ = (sin 2θ − 2θ)/(2θ³), by its series below 0.1; `sc` is
/// sin θ cos θ.
fn s_of_theta(t: f64, sc: f64) -> f64 {
    if t < 0.1 {
        // (sin x − x)/2 with x = 2θ: Σ_{n≥1} (−1)ⁿ x^{2n+1}/(2·(2n+1)!), divided by θ³.
        let t2 = t * t;
        -2.0 / 3.0
            + t2 * (2.0 / 15.0
                + t2 * (-4.0 / 315.0 + t2 * (2.0 / 2835.0 + t2 * (-4.0 / 155_925.0))))
    } else {
        (sc - t) / (t * t * t)
    }
}

impl FisheyeCamera {
    /// θd(θ) and the polynomial pieces P(θ²) = θd/θ, P'(θ²) = dP/d(θ²).
    fn poly(p: &[f64], t: f64) -> (f64, f64) {
        let (k1, k2, k3, k4) = (p[4], p[5], p[6], p[7]);
        let t2 = t * t;
        let pp = 1.0 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4)));
        let dp = k1 + t2 * (2.0 * k2 + t2 * (3.0 * k3 + t2 * 4.0 * k4));
        (pp, dp)
    }
}

impl CameraModel for FisheyeCamera {
    fn name(&self) -> &'static str {
        "fisheye"
    }

    fn parameter_names(&self) -> &'static [&'static str] {
        &FISHEYE_PARAMS
    }

    fn focal_px(&self, params: &[f64]) -> f64 {
        0.5 * (params[0] + params[1])
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
        let (fx, fy, cx, cy) = (params[0], params[1], params[2], params[3]);
        let (x, y, z) = (xc.x, xc.y, xc.z);
        let rho = x.hypot(z);
        let l = rho.hypot(y);
        if !(l > 0.0 && l.is_finite()) || (rho == 0.0 && y <= 0.0) {
            return None;
        }
        let t = rho.atan2(y);
        // θ/ρ by a division where ρ > 0 (θ/ρ → 1/Y on the axis): sin θ from θ would lose
        // digits near the rear pole, where θ ≈ π carries an absolute rounding of ε·π.
        let t_over_rho = if rho > 0.0 { t / rho } else { 1.0 / l };
        let tos = t_over_rho * l; // θ/sin θ
        let (pp, dp) = Self::poly(params, t);
        let g = pp * t_over_rho; // θd/ρ
        let (xp, yp) = (g * x, -g * z);
        let uv = Vector2::new(fx * xp + cx, fy * yp + cy);
        if let Some(jp) = jac_point {
            // sin θ cos θ/θ = (ρ/L)(Y/L)/θ.
            let (sin_t, cos_t) = (rho / l, y / l);
            let sc_over_t = if t < 1e-4 {
                1.0 - 2.0 * t * t / 3.0
            } else {
                sin_t * cos_t / t
            };
            let s = s_of_theta(t, sin_t * cos_t);
            let h = (pp * s + 2.0 * dp * sc_over_t) * tos * tos * tos / (l * l * l);
            let dtd = pp + 2.0 * t * t * dp; // dθd/dθ
            let gy = -dtd / (l * l);
            let gx = x * h;
            let gz = z * h;
            // x' = g X, y' = −g Z.
            *jp = Matrix2x3::new(
                fx * (g + x * gx),
                fx * x * gy,
                fx * x * gz,
                -fy * z * gx,
                -fy * z * gy,
                -fy * (g + z * gz),
            );
        }
        if let Some(ji) = jac_params {
            let t2 = t * t;
            let mut tk = t_over_rho;
            ji[..8].copy_from_slice(&[xp, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
            ji[8..16].copy_from_slice(&[0.0, yp, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0]);
            for i in 0..4 {
                tk *= t2; // θ^{2(i+1)}·θ/ρ = ∂g/∂k_{i+1}
                ji[4 + i] = fx * x * tk;
                ji[12 + i] = -fy * z * tk;
            }
        }
        Some(uv)
    }

    fn unproject(&self, params: &[f64], uv: &Vector2<f64>) -> Option<Vector3<f64>> {
        let (fx, fy, cx, cy) = (params[0], params[1], params[2], params[3]);
        if fx == 0.0 || fy == 0.0 {
            return None;
        }
        let (xp, yp) = ((uv.x - cx) / fx, (uv.y - cy) / fy);
        let td = xp.hypot(yp);
        if !td.is_finite() {
            return None;
        }
        if td == 0.0 {
            return Some(Vector3::new(0.0, 1.0, 0.0));
        }
        // Solve θ P(θ²) = θd for θ ∈ [0, π) by Newton from θ = θd.
        let mut t = td.min(3.0);
        for _ in 0..60 {
            let (pp, dp) = Self::poly(params, t);
            let dtd = pp + 2.0 * t * t * dp;
            if !(dtd > 0.0) {
                return None;
            }
            let step = (t * pp - td) / dtd;
            t -= step;
            if !(0.0..std::f64::consts::PI).contains(&t) {
                return None;
            }
            if step.abs() < 1e-15 * (1.0 + t) {
                let (pp, _) = Self::poly(params, t);
                if (t * pp - td).abs() > 1e-12 * (1.0 + td) {
                    return None;
                }
                let s = t.sin() / td;
                return Some(Vector3::new(s * xp, t.cos(), -s * yp));
            }
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::super::jacobian_checks::{check, rng, uniform};
    use super::*;

    fn random_params(r: &mut pingcal_geometry::consensus::SeededRng) -> [f64; 8] {
        [
            uniform(r, 280.0, 320.0),
            uniform(r, 280.0, 320.0),
            uniform(r, 620.0, 660.0),
            uniform(r, 500.0, 540.0),
            uniform(r, -0.05, 0.05),
            uniform(r, -0.01, 0.01),
            uniform(r, -0.002, 0.002),
            uniform(r, -2e-4, 2e-4),
        ]
    }

    /// A random direction θ off axis, at a random distance.
    fn point(r: &mut pingcal_geometry::consensus::SeededRng, t: f64) -> Vector3<f64> {
        let az = uniform(r, -std::f64::consts::PI, std::f64::consts::PI);
        let d = uniform(r, 0.3, 5.0);
        Vector3::new(t.sin() * az.cos(), t.cos(), t.sin() * az.sin()) * d
    }

    #[test]
    fn jacobians_match_central_differences_from_the_axis_to_beyond_90_degrees() {
        let mut r = rng(31);
        let mut worst: f64 = 0.0;
        for _ in 0..500 {
            let p = random_params(&mut r);
            let t = uniform(&mut r, 0.0, 1.9); // up to ~109° off axis
            worst = worst.max(check(&FisheyeCamera, &p, &point(&mut r, t), 1e-6));
        }
        // Near and on the optical axis, both sides of the series switch at θ = 0.1.
        for t in [
            0.0,
            1e-12,
            1e-8,
            1e-5,
            1e-3,
            0.0999,
            0.1,
            0.1001,
            1.5,
            std::f64::consts::FRAC_PI_2,
            1.6,
        ] {
            let p = random_params(&mut r);
            worst = worst.max(check(&FisheyeCamera, &p, &point(&mut r, t), 1e-6));
        }
        // Far behind the image plane, up to 178° off axis.
        for t in [2.0, 2.5, 3.0, 3.1] {
            let p = random_params(&mut r);
            worst = worst.max(check(&FisheyeCamera, &p, &point(&mut r, t), 1e-6));
        }
        // And at 179.9°.
        let p = random_params(&mut r);
        worst = worst.max(check(
            &FisheyeCamera,
            &p,
            &point(&mut r, std::f64::consts::PI - 1.6e-3),
            1e-6,
        ));
        println!("fisheye: worst relative Jacobian error {worst:.2e}");
    }

    #[test]
    fn the_optical_axis_gives_finite_values_and_jacobians() {
        let p = [300.0, 301.0, 640.0, 512.0, 0.03, -0.004, 1e-3, -1e-4];
        let mut jp = Matrix2x3::zeros();
        let mut ji = [0.0; 16];
        let uv = FisheyeCamera
            .project(
                &p,
                &Vector3::new(0.0, 2.0, 0.0),
                Some(&mut jp),
                Some(&mut ji),
            )
            .unwrap();
        assert_eq!(uv, Vector2::new(640.0, 512.0));
        assert!(jp.iter().chain(ji.iter()).all(|v| v.is_finite()));
        // On the axis, ∂u/∂X = fx/Y, ∂v/∂Z = −fy/Y.
        assert!((jp[(0, 0)] - 150.0).abs() < 1e-12 && (jp[(1, 2)] + 150.5).abs() < 1e-12);
    }

    #[test]
    fn unproject_inverts_project_up_to_beyond_90_degrees_and_behind_is_refused() {
        let mut r = rng(32);
        for _ in 0..300 {
            let p = random_params(&mut r);
            let t = uniform(&mut r, 0.0, 1.9);
            let xc = point(&mut r, t);
            let uv = FisheyeCamera.project(&p, &xc, None, None).unwrap();
            let ray = FisheyeCamera.unproject(&p, &uv).unwrap();
            assert!(
                (ray - xc.normalize()).norm() < 1e-10,
                "θ {t}: {ray:?} {xc:?}"
            );
        }
        let p = random_params(&mut r);
        assert!(FisheyeCamera
            .project(&p, &Vector3::new(0.0, -1.0, 0.0), None, None)
            .is_none());
        assert!(FisheyeCamera
            .project(&p, &Vector3::zeros(), None, None)
            .is_none());
        // Just off the rear pole still projects (θ < π).
        assert!(FisheyeCamera
            .project(&p, &Vector3::new(1e-3, -1.0, 0.0), None, None)
            .is_some());
    }

    /// For points in front, the same pixels as OpenCV's formula with θ = atan(r).
    #[test]
    fn matches_opencv_formula_in_front() {
        let p = [300.0, 301.0, 640.0, 512.0, 0.03, -0.004, 1e-3, -1e-4];
        let (a, b): (f64, f64) = (0.7, -0.4); // x_cv/z_cv, y_cv/z_cv
        let rr = (a * a + b * b).sqrt();
        let t = rr.atan();
        let td =
            t * (1.0 + 0.03 * t.powi(2) - 0.004 * t.powi(4) + 1e-3 * t.powi(6) - 1e-4 * t.powi(8));
        let expected = Vector2::new(300.0 * td / rr * a + 640.0, 301.0 * td / rr * b + 512.0);
        let uv = FisheyeCamera
            .project(&p, &Vector3::new(a * 2.0, 2.0, -b * 2.0), None, None)
            .unwrap();
        assert!((uv - expected).norm() < 1e-10, "{uv:?} {expected:?}");
    }
}
