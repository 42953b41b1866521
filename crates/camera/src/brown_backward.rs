//! Brown's model in its **backward** (correction) form, as DBAT, PhotoModeler and Australis
//! use it: the distortion is a correction applied to the *measured* image point, and the
//! corrected point obeys the pinhole. Projection therefore inverts the correction.
//!
//! # Frames and units
//! As the photogrammetric model ([`super::PhotogrammetricCamera`]): camera frame X right,
//! **Y along the optical axis**, Z up; sensor coordinates (x, y) in mm, x right, **y up**,
//! relative to the centre of the pixel array; pixels with origin at the centre of the
//! top-left pixel, u right, v down, `u = (W − 1)/2 + x/ps`, `v = (H − 1)/2 − y/ps`.
//!
//! # The model
//! Parameters `c, xp, yp, K1, K2, K3, P1, P2, B1, B2` (mm-based units as in the forward
//! model). For a measured point m = (x, y):
//!
//! ```text
//! w  = m − (xp, yp)                            (relative to the principal point)
//! a  = (wx + B1 wx + B2 wy, wy)                (affinity B1 and shear B2, applied first)
//! a + Δ(a) = c · (X/Y, Z/Y)                    (the corrected point obeys the pinhole)
//! Δ(a) = a (K1 r² + K2 r⁴ + K3 r⁶) + (P1 (r² + 2ax²) + 2 P2 ax ay,
//!                                     P2 (r² + 2ay²) + 2 P1 ax ay),   r² = |a|²
//! ```
//!
//! Projection solves `G(a) = a + Δ(a) = q` (q the pinhole point) by Newton's method with
//! the analytic 2×2 Jacobian J = ∂G/∂a, from a = q, to a step below 1e-12 px; then
//! `w = A⁻¹ a` (A = [[1 + B1, B2], [0, 1]]) and m = (xp, yp) + w. Points where J is
//! singular or folds over (det J ≤ 0) are refused, as are 1 + B1 ≤ 0 and Y ≤ 0.
//! Back-projection is closed-form: the ray is (G(a)x/c, 1, G(a)y/c).
//!
//! # Jacobians (implicit function theorem)
//! At the solution, dG = J da + (∂G/∂k) dk = dq, so `da = J⁻¹ (dq − ∂G/∂k dk)` with
//! ∂G/∂K1 = a r², ∂G/∂K2 = a r⁴, ∂G/∂K3 = a r⁶, ∂G/∂P1 = (r² + 2ax², 2ax ay),
//! ∂G/∂P2 = (2ax ay, r² + 2ay²), dq = c/Y [[1, −X/Y, 0], [0, −Z/Y, 1]] dxc + (X/Y, Z/Y) dc.
//! Then `dm = A⁻¹ da + d(xp, yp) + (−wx, 0)/(1 + B1) dB1 + (−wy, 0)/(1 + B1) dB2`, and
//! `du = dmx/ps`, `dv = −dmy/ps`.
//!
//! # DBAT's parameterisation
//! DBAT's camera model 3 is this form in its own image frame (mm from the image corner, y
//! down): `x_corr = w_d + Δ(w_d)`, `w_d = diag(1 + as, 1)·m_d − pp_internal`, with its
//! reported px = pp_internal/(1 + as) (pingcal-ba's `io::dbat`). Rewritten in pingcal's frame
//! (y up, relative to the array centre) it is exactly the model above with
//! `xp = px − (W/2)·ps`, `yp = (H/2)·ps − py` (pingcal-ba's `io::dbat::dbat_principal_point`),
//! `B1 = as`, `B2 = 0`, and DBAT's K1, K2, K3, P1 unchanged. The flip of y changes the sign
//! of the textbook P2; `tests/dbat_camcal.rs` found DBAT's published P2 to have the
//! opposite sign of the textbook term in its y-down frame, so DBAT's P2 is this model's P2
//! unchanged too (the test `matches_dbat_model_3` checks the rest of the mapping exactly).
//! Australis's B1 (affinity) and B2 (shear) act on the measured point like A here.
//!
//! Forward ([`super::PhotogrammetricCamera`]) and backward coefficients are not exactly
//! convertible: their K and P are approximately negatives of each other only to first
//! order.

use super::{CameraModel, PhotogrammetricCamera};
use nalgebra::{Matrix2, Matrix2x3, Vector2, Vector3};

/// Names of the ten parameters, in slice order (those of the forward model).
pub const BROWN_BACKWARD_PARAMS: [&str; 10] =
    ["c", "xp", "yp", "K1", "K2", "K3", "P1", "P2", "B1", "B2"];

/// Brown's backward (correction) model (see the module doc). Its constants are the
/// sensor's size in pixels and its pixel pitch.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BrownBackwardCamera {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Pixel pitch in mm (square pixels).
    pub pixel_size_mm: f64,
}

/// Convergence of the inversion: Newton step below this many pixels.
const STEP_PX: f64 = 1e-12;

impl BrownBackwardCamera {
    /// A camera of `width × height` pixels of pitch `pixel_size_mm`.
    pub fn new(width: u32, height: u32, pixel_size_mm: f64) -> Self {
        Self {
            width,
            height,
            pixel_size_mm,
        }
    }

    fn sensor(&self) -> PhotogrammetricCamera {
        PhotogrammetricCamera::new(self.width, self.height, self.pixel_size_mm)
    }

    /// G(a) = a + Δ(a) and J = ∂G/∂a (the forward model's distortion without B1, B2).
    fn correct(p: &[f64], a: &Vector2<f64>) -> (Vector2<f64>, Matrix2<f64>) {
        let k = [0.0, 0.0, 0.0, p[3], p[4], p[5], p[6], p[7], 0.0, 0.0];
        let (d, j) = PhotogrammetricCamera::distort(&k, a.x, a.y);
        (a + d, j)
    }

    /// The affinity-corrected point a with G(a) = q, by Newton's method; `None` if it does
    /// not converge or J is singular or folded there.
    fn invert(&self, p: &[f64], q: &Vector2<f64>) -> Option<(Vector2<f64>, Matrix2<f64>)> {
        let tol = STEP_PX * self.pixel_size_mm;
        let mut a = *q;
        for _ in 0..100 {
            let (g, j) = Self::correct(p, &a);
            let step = j.try_inverse()? * (g - q);
            a -= step;
            if !a.iter().all(|v| v.is_finite()) {
                return None;
            }
            if step.norm() <= tol.max(4.0 * f64::EPSILON * a.norm()) {
                let (_, j) = Self::correct(p, &a);
                return (j.determinant() > 0.0).then_some((a, j));
            }
        }
        None
    }
}

impl CameraModel for BrownBackwardCamera {
    fn name(&self) -> &'static str {
        "brown_backward"
    }

    fn parameter_names(&self) -> &'static [&'static str] {
        &BROWN_BACKWARD_PARAMS
    }

    fn project(
        &self,
        params: &[f64],
        xc: &Vector3<f64>,
        jac_point: Option<&mut Matrix2x3<f64>>,
        jac_params: Option<&mut [f64]>,
    ) -> Option<Vector2<f64>> {
        let s1 = 1.0 + params[8];
        if !(xc.y > 0.0) || !(s1 > 0.0) || !(self.pixel_size_mm > 0.0) {
            return None;
        }
        let (c, b2) = (params[0], params[9]);
        let iy = 1.0 / xc.y;
        let (mx, mz) = (xc.x * iy, xc.z * iy);
        let q = Vector2::new(c * mx, c * mz);
        let (a, j) = self.invert(params, &q)?;
        let w = Vector2::new((a.x - b2 * a.y) / s1, a.y);
        let m = Vector2::new(params[1] + w.x, params[2] + w.y);
        let uv = self.sensor().sensor_to_pixel(&m);
        if jac_point.is_none() && jac_params.is_none() {
            return Some(uv);
        }
        let ji = j.try_inverse()?;
        let ainv = Matrix2::new(1.0 / s1, -b2 / s1, 0.0, 1.0);
        let k = ainv * ji; // dm = K (dq − ∂G/∂k dk) + …
        let s = 1.0 / self.pixel_size_mm;
        if let Some(jp) = jac_point {
            let f = c * iy;
            let dq = Matrix2x3::new(f, -f * mx, 0.0, 0.0, -f * mz, f);
            let dm = k * dq;
            *jp = Matrix2x3::new(
                s * dm[(0, 0)],
                s * dm[(0, 1)],
                s * dm[(0, 2)],
                -s * dm[(1, 0)],
                -s * dm[(1, 1)],
                -s * dm[(1, 2)],
            );
        }
        if let Some(jo) = jac_params {
            let r2 = a.norm_squared();
            let (r4, r6) = (r2 * r2, r2 * r2 * r2);
            let cols: [Vector2<f64>; 10] = [
                k * Vector2::new(mx, mz),
                Vector2::new(1.0, 0.0),
                Vector2::new(0.0, 1.0),
                -(k * (a * r2)),
                -(k * (a * r4)),
                -(k * (a * r6)),
                -(k * Vector2::new(r2 + 2.0 * a.x * a.x, 2.0 * a.x * a.y)),
                -(k * Vector2::new(2.0 * a.x * a.y, r2 + 2.0 * a.y * a.y)),
                Vector2::new(-w.x / s1, 0.0),
                Vector2::new(-w.y / s1, 0.0),
            ];
            for (i, col) in cols.iter().enumerate() {
                jo[i] = s * col.x;
                jo[10 + i] = -s * col.y;
            }
        }
        Some(uv)
    }

    fn pixel_size_mm(&self) -> Option<f64> {
        Some(self.pixel_size_mm)
    }

    fn focal_px(&self, params: &[f64]) -> f64 {
        params[0] / self.pixel_size_mm
    }

    fn principal_point_px(&self, params: &[f64]) -> Vector2<f64> {
        self.sensor()
            .sensor_to_pixel(&Vector2::new(params[1], params[2]))
    }

    fn unproject(&self, params: &[f64], uv: &Vector2<f64>) -> Option<Vector3<f64>> {
        let c = params[0];
        if c == 0.0 || !(self.pixel_size_mm > 0.0) {
            return None;
        }
        let m = self.sensor().pixel_to_sensor(uv);
        let w = Vector2::new(m.x - params[1], m.y - params[2]);
        let a = Vector2::new((1.0 + params[8]) * w.x + params[9] * w.y, w.y);
        let (g, _) = Self::correct(params, &a);
        let ray = Vector3::new(g.x / c, 1.0, g.y / c);
        ray.iter().all(|v| v.is_finite()).then(|| ray.normalize())
    }
}

#[cfg(test)]
mod tests {
    use super::super::jacobian_checks::{check, rng, uniform};
    use super::*;

    /// A MYNT-like wide-angle camera with backward coefficients of the size of the forward
    /// ones (opposite sign: a correction of ~20 % of r at the corner).
    fn random_params(r: &mut pingcal_geometry::consensus::SeededRng) -> [f64; 10] {
        [
            uniform(r, 2.3, 2.6),
            uniform(r, -0.05, 0.05),
            uniform(r, -0.05, 0.05),
            uniform(r, -0.005, 0.03),
            uniform(r, -5e-4, 5e-4),
            uniform(r, -2e-5, 2e-5),
            uniform(r, -1e-3, 1e-3),
            uniform(r, -1e-3, 1e-3),
            uniform(r, -1e-3, 1e-3),
            uniform(r, -1e-3, 1e-3),
        ]
    }

    fn cam() -> BrownBackwardCamera {
        BrownBackwardCamera::new(1280, 720, 0.00375)
    }

    #[test]
    fn jacobians_match_central_differences_at_random_states() {
        let mut r = rng(41);
        let mut worst: f64 = 0.0;
        for _ in 0..500 {
            let params = random_params(&mut r);
            let y = uniform(&mut r, 0.3, 5.0);
            let xc = Vector3::new(
                uniform(&mut r, -0.9, 0.9) * y,
                y,
                uniform(&mut r, -0.5, 0.5) * y,
            );
            worst = worst.max(check(&cam(), &params, &xc, 1e-6));
        }
        println!("brown_backward: worst relative Jacobian error {worst:.2e}");
    }

    /// Projection inverts the correction to 1e-12 px: the corrected measured point is the
    /// pinhole point; unproject inverts project.
    #[test]
    fn projection_inverts_the_correction_and_unproject_inverts_project() {
        let cam = cam();
        let mut r = rng(42);
        for _ in 0..300 {
            let p = random_params(&mut r);
            let xc = Vector3::new(uniform(&mut r, -0.9, 0.9), 1.0, uniform(&mut r, -0.5, 0.5));
            let uv = cam.project(&p, &xc, None, None).unwrap();
            // The correction of the measured point, written out, lands on the pinhole point.
            let m = cam.sensor().pixel_to_sensor(&uv);
            let (wx, wy) = (m.x - p[1], m.y - p[2]);
            let (ax, ay) = ((1.0 + p[8]) * wx + p[9] * wy, wy);
            let r2 = ax * ax + ay * ay;
            let rad = r2 * (p[3] + r2 * (p[4] + r2 * p[5]));
            let gx = ax + ax * rad + p[6] * (r2 + 2.0 * ax * ax) + 2.0 * p[7] * ax * ay;
            let gy = ay + ay * rad + p[7] * (r2 + 2.0 * ay * ay) + 2.0 * p[6] * ax * ay;
            let miss = Vector2::new(gx - p[0] * xc.x, gy - p[0] * xc.z) / cam.pixel_size_mm;
            assert!(miss.norm() < 1e-11, "{miss:?} px");
            let ray = cam.unproject(&p, &uv).unwrap();
            assert!((ray - xc.normalize()).norm() < 1e-11, "{ray:?}");
        }
        let p = random_params(&mut r);
        assert!(cam
            .project(&p, &Vector3::new(0.0, -1.0, 0.0), None, None)
            .is_none());
    }
}
