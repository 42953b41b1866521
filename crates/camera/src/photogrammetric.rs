//! The photogrammetric camera model of docs/formats.md (Australis / Fraser 1997 parameter set),
//! with distortion applied **forward**, to the ideal image point.
//!
//! # Frames and units
//! * Camera frame (the paper's convention): X to image right, **Y along the optical axis**
//!   (forward), Z to image up. A point images only if Y > 0.
//! * Image coordinates on the sensor, in mm: x right, y up, relative to the centre of the
//!   pixel array; the principal point is (xp, yp) in that system.
//! * Pixels: origin at the centre of the top-left pixel, u right, v down:
//!   `u = (W − 1)/2 + x/ps`, `v = (H − 1)/2 − y/ps`, ps the pixel size in mm.
//!
//! # The model
//! With `x̄ = c·X/Y`, `ȳ = c·Z/Y` (the ideal image point relative to the principal point,
//! mm) and `r² = x̄² + ȳ²`:
//!
//! ```text
//! Δx = x̄ (K1 r² + K2 r⁴ + K3 r⁶) + P1 (r² + 2x̄²) + 2 P2 x̄ ȳ + B1 x̄ + B2 ȳ
//! Δy = ȳ (K1 r² + K2 r⁴ + K3 r⁶) + P2 (r² + 2ȳ²) + 2 P1 x̄ ȳ
//! x  = xp + x̄ + Δx,    y = yp + ȳ + Δy
//! ```
//!
//! Units: c, xp, yp in mm; K1 in mm⁻², K2 in mm⁻⁴, K3 in mm⁻⁶; P1, P2 in mm⁻¹; B1, B2
//! unitless. Australis and MicMac write the same terms as *corrections* to measured
//! coordinates (backward), so their K1…P2 have roughly the opposite sign of ours; B1 is
//! the affinity (differential scale) and B2 the shear term.

use super::CameraModel;
use nalgebra::{Matrix2, Matrix2x3, Vector2, Vector3};

/// Names of the ten parameters, in slice order.
pub const PHOTOGRAMMETRIC_PARAMS: [&str; 10] =
    ["c", "xp", "yp", "K1", "K2", "K3", "P1", "P2", "B1", "B2"];

/// The photogrammetric camera model (see the module doc). Its constants are the sensor's
/// size in pixels and its pixel pitch; the ten parameters are in the slice.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PhotogrammetricCamera {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Pixel pitch in mm (square pixels).
    pub pixel_size_mm: f64,
}

impl PhotogrammetricCamera {
    /// Its [`CameraModel::name`].
    pub const NAME: &'static str = "photogrammetric";

    /// A camera of `width × height` pixels of pitch `pixel_size_mm`.
    pub fn new(width: u32, height: u32, pixel_size_mm: f64) -> Self {
        Self {
            width,
            height,
            pixel_size_mm,
        }
    }

    /// Pixel → sensor mm (x right, y up, relative to the array centre).
    pub fn pixel_to_sensor(&self, uv: &Vector2<f64>) -> Vector2<f64> {
        let (cx, cy) = self.centre_px();
        Vector2::new(
            (uv.x - cx) * self.pixel_size_mm,
            (cy - uv.y) * self.pixel_size_mm,
        )
    }

    /// Sensor mm → pixel.
    pub fn sensor_to_pixel(&self, xy: &Vector2<f64>) -> Vector2<f64> {
        let (cx, cy) = self.centre_px();
        Vector2::new(
            cx + xy.x / self.pixel_size_mm,
            cy - xy.y / self.pixel_size_mm,
        )
    }

    fn centre_px(&self) -> (f64, f64) {
        (
            (self.width as f64 - 1.0) * 0.5,
            (self.height as f64 - 1.0) * 0.5,
        )
    }

    /// The distortion Δ at the ideal point (x̄, ȳ) and its 2×2 Jacobian ∂(x̄+Δx, ȳ+Δy)/∂(x̄, ȳ).
    pub(crate) fn distort(p: &[f64], xb: f64, yb: f64) -> (Vector2<f64>, Matrix2<f64>) {
        let (k1, k2, k3, p1, p2, b1, b2) = (p[3], p[4], p[5], p[6], p[7], p[8], p[9]);
        let r2 = xb * xb + yb * yb;
        let radial = r2 * (k1 + r2 * (k2 + r2 * k3));
        let dr = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2); // d(radial)/d(r²)
        let dx = xb * radial + p1 * (r2 + 2.0 * xb * xb) + 2.0 * p2 * xb * yb + b1 * xb + b2 * yb;
        let dy = yb * radial + p2 * (r2 + 2.0 * yb * yb) + 2.0 * p1 * xb * yb;
        let j00 = 1.0 + radial + 2.0 * xb * xb * dr + 6.0 * p1 * xb + 2.0 * p2 * yb + b1;
        let j01 = 2.0 * xb * yb * dr + 2.0 * p1 * yb + 2.0 * p2 * xb + b2;
        let j10 = 2.0 * xb * yb * dr + 2.0 * p2 * xb + 2.0 * p1 * yb;
        let j11 = 1.0 + radial + 2.0 * yb * yb * dr + 6.0 * p2 * yb + 2.0 * p1 * xb;
        (Vector2::new(dx, dy), Matrix2::new(j00, j01, j10, j11))
    }

    /// Removes the distortion from a sensor point (mm, relative to the array centre):
    /// the ideal point (x̄, ȳ) relative to the principal point, by Newton's method.
    pub fn undistort_sensor(&self, params: &[f64], xy: &Vector2<f64>) -> Option<Vector2<f64>> {
        let target = Vector2::new(xy.x - params[1], xy.y - params[2]);
        let mut q = target;
        for _ in 0..50 {
            let (d, j) = Self::distort(params, q.x, q.y);
            let g = q + d - target;
            let step = j.try_inverse()? * g;
            q -= step;
            if !q.iter().all(|v| v.is_finite()) {
                return None;
            }
            if step.norm() < 1e-14 * (1.0 + q.norm()) {
                let (d, _) = Self::distort(params, q.x, q.y);
                return ((q + d - target).norm() < 1e-9).then_some(q);
            }
        }
        None
    }
}

impl CameraModel for PhotogrammetricCamera {
    fn name(&self) -> &'static str {
        Self::NAME
    }

    fn parameter_names(&self) -> &'static [&'static str] {
        &PHOTOGRAMMETRIC_PARAMS
    }

    fn project(
        &self,
        params: &[f64],
        xc: &Vector3<f64>,
        jac_point: Option<&mut Matrix2x3<f64>>,
        jac_params: Option<&mut [f64]>,
    ) -> Option<Vector2<f64>> {
        if !(xc.y > 0.0) {
            return None;
        }
        let c = params[0];
        let iy = 1.0 / xc.y;
        let (mx, mz) = (xc.x * iy, xc.z * iy);
        let (xb, yb) = (c * mx, c * mz);
        let (d, jd) = Self::distort(params, xb, yb);
        let xs = params[1] + xb + d.x;
        let ys = params[2] + yb + d.y;
        let s = 1.0 / self.pixel_size_mm;
        let (cx, cy) = self.centre_px();
        let uv = Vector2::new(cx + xs * s, cy - ys * s);
        if let Some(jp) = jac_point {
            // ∂(x̄, ȳ)/∂(X, Y, Z) = c/Y · [[1, −mx, 0], [0, −mz, 1]].
            let a = c * iy;
            let m = Matrix2x3::new(a, -a * mx, 0.0, 0.0, -a * mz, a);
            let j = jd * m;
            *jp = Matrix2x3::new(
                s * j[(0, 0)],
                s * j[(0, 1)],
                s * j[(0, 2)],
                -s * j[(1, 0)],
                -s * j[(1, 1)],
                -s * j[(1, 2)],
            );
        }
        if let Some(ji) = jac_params {
            let r2 = xb * xb + yb * yb;
            let (r4, r6) = (r2 * r2, r2 * r2 * r2);
            // c enters through (x̄, ȳ) = c (mx, mz).
            let dxs_dc = jd[(0, 0)] * mx + jd[(0, 1)] * mz;
            let dys_dc = jd[(1, 0)] * mx + jd[(1, 1)] * mz;
            let rows: [[f64; 10]; 2] = [
                [
                    dxs_dc,
                    1.0,
                    0.0,
                    xb * r2,
                    xb * r4,
                    xb * r6,
                    r2 + 2.0 * xb * xb,
                    2.0 * xb * yb,
                    xb,
                    yb,
                ],
                [
                    dys_dc,
                    0.0,
                    1.0,
                    yb * r2,
                    yb * r4,
                    yb * r6,
                    2.0 * xb * yb,
                    r2 + 2.0 * yb * yb,
                    0.0,
                    0.0,
                ],
            ];
            for k in 0..10 {
                ji[k] = s * rows[0][k];
                ji[10 + k] = -s * rows[1][k];
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
        self.sensor_to_pixel(&Vector2::new(params[1], params[2]))
    }

    fn unproject(&self, params: &[f64], uv: &Vector2<f64>) -> Option<Vector3<f64>> {
        let q = self.undistort_sensor(params, &self.pixel_to_sensor(uv))?;
        let c = params[0];
        Some(Vector3::new(q.x / c, 1.0, q.y / c).normalize())
    }
}

#[cfg(test)]
mod tests {
    use super::super::jacobian_checks::{check, rng, uniform};
    use super::*;

    /// A MYNT EYE D1000-like camera (1280×720, 3.75 µm, c = 2.45 mm) with wide-angle
    /// distortion of the size such lenses have (K1 r² up to ~20 % at the corner, 2.75 mm).
    fn random_params(r: &mut pingcal_geometry::consensus::SeededRng) -> [f64; 10] {
        [
            uniform(r, 2.3, 2.6),
            uniform(r, -0.05, 0.05),
            uniform(r, -0.05, 0.05),
            uniform(r, -0.03, 0.03),
            uniform(r, -5e-4, 5e-4),
            uniform(r, -2e-5, 2e-5),
            uniform(r, -1e-3, 1e-3),
            uniform(r, -1e-3, 1e-3),
            uniform(r, -1e-3, 1e-3),
            uniform(r, -1e-3, 1e-3),
        ]
    }

    #[test]
    fn jacobians_match_central_differences_at_random_states() {
        let cam = PhotogrammetricCamera::new(1280, 720, 0.00375);
        let mut r = rng(11);
        for _ in 0..300 {
            let params = random_params(&mut r);
            let y = uniform(&mut r, 0.3, 5.0);
            let xc = Vector3::new(
                uniform(&mut r, -0.9, 0.9) * y,
                y,
                uniform(&mut r, -0.5, 0.5) * y,
            );
            check(&cam, &params, &xc, 1e-6);
        }
    }

    #[test]
    fn principal_point_projects_to_its_pixel_and_unproject_inverts() {
        let cam = PhotogrammetricCamera::new(1280, 720, 0.00375);
        let mut params = [0.0; 10];
        params[0] = 2.45;
        params[1] = 0.0375; // 10 px right
        params[2] = -0.0375; // 10 px down
        let uv = cam
            .project(&params, &Vector3::new(0.0, 1.0, 0.0), None, None)
            .unwrap();
        assert!((uv - Vector2::new(649.5, 369.5)).norm() < 1e-12, "{uv:?}");
        let mut r = rng(3);
        for _ in 0..100 {
            let p = random_params(&mut r);
            let xc = Vector3::new(uniform(&mut r, -1.0, 1.0), 1.0, uniform(&mut r, -0.5, 0.5));
            let uv = cam.project(&p, &xc, None, None).unwrap();
            let ray = cam.unproject(&p, &uv).unwrap();
            assert!(
                (ray - xc.normalize()).norm() < 1e-10,
                "{ray:?} {:?} {p:?}",
                xc.normalize()
            );
        }
        assert!(cam
            .project(&params, &Vector3::new(0.0, -1.0, 0.0), None, None)
            .is_none());
    }
}
