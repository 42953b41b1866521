//! OpenCV's camera model (`cv::projectPoints`, `cv::calibrateCamera`): pinhole with
//! rational radial, tangential (decentering) and thin-prism distortion, in pixels.
//!
//! # Frames and units
//! * Camera frame: pingcal's (docs/formats.md), X right, **Y along the optical axis**, Z up. OpenCV's
//!   camera frame (x right, y down, z forward) is `x_cv = X`, `y_cv = −Z`, `z_cv = Y`; an
//!   OpenCV pose `x_cv = R·X + t` becomes pingcal's `camera_from_object` by the rows
//!   `(R₀, R₂, −R₁)` and `(t₀, t₂, −t₁)`. A point images only if Y > 0.
//! * Pixels: OpenCV puts integer coordinates at pixel *centres*, (0, 0) the centre of the
//!   top-left pixel, u right, v down — pingcal's convention, so (cx, cy) are OpenCV's own
//!   numbers, unchanged.
//!
//! # The model
//! Parameters, in OpenCV's order (the camera matrix, then `distCoeffs`):
//! `fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4` (px for fx…cy, the
//! rest unitless on the normalised plane). With `x' = X/Y`, `y' = −Z/Y`, `r² = x'² + y'²`:
//!
//! ```text
//! R   = (1 + k1 r² + k2 r⁴ + k3 r⁶) / (1 + k4 r² + k5 r⁴ + k6 r⁶)
//! x'' = x' R + 2 p1 x' y' + p2 (r² + 2x'²) + s1 r² + s2 r⁴
//! y'' = y' R + p1 (r² + 2y'²) + 2 p2 x' y' + s3 r² + s4 r⁴
//! u   = fx x'' + cx,    v = fy y'' + cy
//! ```
//!
//! OpenCV's tilted-sensor terms τx, τy are not part of the model. Points where the
//! denominator of R is not positive are refused.
//!
//! Terms a calibration does not use are held at zero by the user: set them to 0 in the
//! parameter slice and mark them in pingcal-ba's `problem::Camera::fixed` (the five-term model
//! `k1, k2, p1, p2, k3` of OpenCV's default is [`OpenCvCamera::five_term_fixed`]).
//!
//! # Conversions
//! * Photogrammetric (docs/formats.md, forward) with B1 = B2 = 0 ↔ OpenCV with fx = fy, k4…k6 =
//!   s1…s4 = 0: **exact** both ways ([`opencv_from_photogrammetric`],
//!   [`photogrammetric_from_opencv`]). With ps the pixel pitch, (W, H) the image size:
//!   `fx = fy = c/ps`, `cx = (W−1)/2 + xp/ps`, `cy = (H−1)/2 − yp/ps`, `k1 = K1 c²`,
//!   `k2 = K2 c⁴`, `k3 = K3 c⁶`, `p1 = −P2 c`, `p2 = P1 c` (the swap and sign from OpenCV's
//!   y down and its naming of the decentering terms).
//! * Photogrammetric with B1 or B2 ≠ 0, or OpenCV with fx ≠ fy or rational / thin-prism
//!   terms: **not exact** (the photogrammetric affinity acts after the distortion, OpenCV's
//!   fx/fy before it; the rational and prism terms have no photogrammetric counterpart);
//!   the converters refuse them ([`ConversionError`]) rather than approximate.
//! * Forward (photogrammetric) ↔ backward ([`super::BrownBackwardCamera`]) Brown, and
//!   OpenCV ↔ fisheye ([`super::FisheyeCamera`]): **not exact** (the inverse of a
//!   polynomial distortion is not a polynomial of the same form; the fisheye's θ-polynomial
//!   is not a rational function of r); no converter, re-estimate instead.

use super::{CameraModel, PhotogrammetricCamera};
use nalgebra::{Matrix2, Matrix2x3, Vector2, Vector3};

/// Names of the sixteen parameters, in slice order (OpenCV's).
pub const OPENCV_PARAMS: [&str; 16] = [
    "fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6", "s1", "s2", "s3", "s4",
];

/// OpenCV's camera model (see the module doc). It has no constants.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct OpenCvCamera;

impl OpenCvCamera {
    /// The `fixed` mask of OpenCV's default five-term model: fx, fy, cx, cy, k1, k2, p1,
    /// p2, k3 free; k4…k6 and s1…s4 held (at the values in the slice, normally 0).
    pub fn five_term_fixed() -> Vec<bool> {
        (0..16).map(|k| k >= 9).collect()
    }

    /// The distorted normalised point (x'', y'') and its Jacobian ∂(x'', y'')/∂(x', y'),
    /// or `None` where the rational denominator is not positive.
    fn distort(p: &[f64], x: f64, y: f64) -> Option<(Vector2<f64>, Matrix2<f64>, Terms)> {
        let (k1, k2, p1, p2, k3) = (p[4], p[5], p[6], p[7], p[8]);
        let (k4, k5, k6) = (p[9], p[10], p[11]);
        let (s1, s2, s3, s4) = (p[12], p[13], p[14], p[15]);
        let r2 = x * x + y * y;
        let num = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
        let den = 1.0 + r2 * (k4 + r2 * (k5 + r2 * k6));
        if !(den > 0.0) {
            return None;
        }
        let rad = num / den;
        let dnum = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2);
        let dden = k4 + r2 * (2.0 * k5 + 3.0 * k6 * r2);
        let drad = (dnum - rad * dden) / den; // dR/d(r²)
        let xd = x * rad + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x) + r2 * (s1 + s2 * r2);
        let yd = y * rad + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y + r2 * (s3 + s4 * r2);
        let px = s1 + 2.0 * s2 * r2; // d(s1 r² + s2 r⁴)/d(r²)
        let py = s3 + 2.0 * s4 * r2;
        let j00 = rad + 2.0 * x * x * drad + 2.0 * p1 * y + 6.0 * p2 * x + 2.0 * x * px;
        let j01 = 2.0 * x * y * drad + 2.0 * p1 * x + 2.0 * p2 * y + 2.0 * y * px;
        let j10 = 2.0 * x * y * drad + 2.0 * p1 * x + 2.0 * p2 * y + 2.0 * x * py;
        let j11 = rad + 2.0 * y * y * drad + 6.0 * p1 * y + 2.0 * p2 * x + 2.0 * y * py;
        Some((
            Vector2::new(xd, yd),
            Matrix2::new(j00, j01, j10, j11),
            Terms { r2, rad, den },
        ))
    }
}

struct Terms {
    r2: f64,
    rad: f64,
    den: f64,
}

impl CameraModel for OpenCvCamera {
    fn name(&self) -> &'static str {
        "opencv"
    }

    fn parameter_names(&self) -> &'static [&'static str] {
        &OPENCV_PARAMS
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
        if !(xc.y > 0.0) {
            return None;
        }
        let (fx, fy, cx, cy) = (params[0], params[1], params[2], params[3]);
        let iy = 1.0 / xc.y;
        let (x, y) = (xc.x * iy, -xc.z * iy);
        let (d, jd, t) = Self::distort(params, x, y)?;
        let uv = Vector2::new(fx * d.x + cx, fy * d.y + cy);
        if let Some(jp) = jac_point {
            // ∂(x', y')/∂(X, Y, Z) = 1/Y · [[1, −x', 0], [0, −y', −1]].
            let m = Matrix2x3::new(iy, -x * iy, 0.0, 0.0, -y * iy, -iy);
            let j = jd * m;
            *jp = Matrix2x3::new(
                fx * j[(0, 0)],
                fx * j[(0, 1)],
                fx * j[(0, 2)],
                fy * j[(1, 0)],
                fy * j[(1, 1)],
                fy * j[(1, 2)],
            );
        }
        if let Some(ji) = jac_params {
            let Terms { r2, rad, den } = t;
            let (r4, r6) = (r2 * r2, r2 * r2 * r2);
            // ∂R/∂k1..k3 = r^{2i}/den; ∂R/∂k4..k6 = −R r^{2i}/den.
            let (a1, a2, a3) = (r2 / den, r4 / den, r6 / den);
            let (b1, b2, b3) = (-rad * a1, -rad * a2, -rad * a3);
            let u: [f64; 16] = [
                d.x,
                0.0,
                1.0,
                0.0,
                fx * x * a1,
                fx * x * a2,
                fx * 2.0 * x * y,
                fx * (r2 + 2.0 * x * x),
                fx * x * a3,
                fx * x * b1,
                fx * x * b2,
                fx * x * b3,
                fx * r2,
                fx * r4,
                0.0,
                0.0,
            ];
            let v: [f64; 16] = [
                0.0,
                d.y,
                0.0,
                1.0,
                fy * y * a1,
                fy * y * a2,
                fy * (r2 + 2.0 * y * y),
                fy * 2.0 * x * y,
                fy * y * a3,
                fy * y * b1,
                fy * y * b2,
                fy * y * b3,
                0.0,
                0.0,
                fy * r2,
                fy * r4,
            ];
            ji[..16].copy_from_slice(&u);
            ji[16..32].copy_from_slice(&v);
        }
        Some(uv)
    }

    fn unproject(&self, params: &[f64], uv: &Vector2<f64>) -> Option<Vector3<f64>> {
        let (fx, fy, cx, cy) = (params[0], params[1], params[2], params[3]);
        if fx == 0.0 || fy == 0.0 {
            return None;
        }
        let target = Vector2::new((uv.x - cx) / fx, (uv.y - cy) / fy);
        // Newton on d(q) = target from q = target, each step halved until the misfit
        // shrinks: the rational model of a wide lens bends far from the axis, where a full
        // step can overshoot into a region the iteration never leaves.
        let mut q = target;
        let (mut d, mut j, _) = Self::distort(params, q.x, q.y)?;
        for _ in 0..100 {
            let miss = (d - target).norm();
            let step = j.try_inverse()? * (d - target);
            // converged: the step is at rounding, or the misfit is (an ill-conditioned
            // Jacobian far off axis leaves steps of a few ε·|q| that never shrink)
            if !(step.norm() >= 1e-15 * (1.0 + q.norm())) || miss < 4.0 * f64::EPSILON {
                return (miss < 1e-12 * (1.0 + target.norm()) && step.norm().is_finite())
                    .then(|| Vector3::new(q.x, 1.0, -q.y).normalize());
            }
            let mut t = 1.0;
            loop {
                let trial = q - step * t;
                if let Some((dt, jt, _)) = Self::distort(params, trial.x, trial.y) {
                    if (dt - target).norm() < miss || t < 1e-3 {
                        (q, d, j) = (trial, dt, jt);
                        break;
                    }
                }
                t *= 0.5;
                if t < 1e-3 {
                    return None;
                }
            }
        }
        None
    }
}

/// A conversion between models that is not exact for the given parameters.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ConversionError {
    /// The source has a term the target cannot represent exactly.
    #[error("no exact conversion: {term} = {value:e} (must be {required})")]
    NotExact {
        /// The offending parameter.
        term: &'static str,
        /// Its value.
        value: f64,
        /// What it must be for the conversion to be exact.
        required: &'static str,
    },
    /// A parameter slice of the wrong length.
    #[error("{model}: {given} parameters given, the model has {expected}")]
    ParameterCount {
        /// Model name.
        model: &'static str,
        /// Length given.
        given: usize,
        /// The model's number of parameters.
        expected: usize,
    },
    /// A camera constant or pixel pitch that is not positive and finite.
    #[error("{what} = {value:e} must be positive and finite")]
    NotPositive {
        /// Which quantity.
        what: &'static str,
        /// Its value.
        value: f64,
    },
}

/// Photogrammetric parameters (of `camera`'s sensor) → OpenCV parameters with the same
/// projection of every point (exact; see the module doc). Refuses B1 or B2 ≠ 0.
pub fn opencv_from_photogrammetric(
    camera: &PhotogrammetricCamera,
    params: &[f64],
) -> Result<[f64; 16], ConversionError> {
    if params.len() != 10 {
        return Err(ConversionError::ParameterCount {
            model: "photogrammetric",
            given: params.len(),
            expected: 10,
        });
    }
    for (k, term) in [(8, "B1"), (9, "B2")] {
        if params[k] != 0.0 {
            return Err(ConversionError::NotExact {
                term,
                value: params[k],
                required: "0",
            });
        }
    }
    let ps = camera.pixel_size_mm;
    if !(ps > 0.0 && ps.is_finite()) {
        return Err(ConversionError::NotPositive {
            what: "pixel_size_mm",
            value: ps,
        });
    }
    let c = params[0];
    if !(c > 0.0 && c.is_finite()) {
        return Err(ConversionError::NotPositive {
            what: "c",
            value: c,
        });
    }
    let (w, h) = (camera.width as f64, camera.height as f64);
    let c2 = c * c;
    let mut out = [0.0; 16];
    out[0] = c / ps;
    out[1] = c / ps;
    out[2] = 0.5 * (w - 1.0) + params[1] / ps;
    out[3] = 0.5 * (h - 1.0) - params[2] / ps;
    out[4] = params[3] * c2;
    out[5] = params[4] * c2 * c2;
    out[6] = -params[7] * c;
    out[7] = params[6] * c;
    out[8] = params[5] * c2 * c2 * c2;
    Ok(out)
}

/// OpenCV parameters → photogrammetric parameters for `camera`'s sensor (its size and
/// pixel pitch), exact; refuses fx ≠ fy and non-zero k4…k6, s1…s4.
pub fn photogrammetric_from_opencv(
    camera: &PhotogrammetricCamera,
    params: &[f64],
) -> Result<[f64; 10], ConversionError> {
    if params.len() != 16 {
        return Err(ConversionError::ParameterCount {
            model: "opencv",
            given: params.len(),
            expected: 16,
        });
    }
    if params[1] != params[0] {
        return Err(ConversionError::NotExact {
            term: "fy",
            value: params[1],
            required: "equal to fx",
        });
    }
    for k in 9..16 {
        if params[k] != 0.0 {
            return Err(ConversionError::NotExact {
                term: OPENCV_PARAMS[k],
                value: params[k],
                required: "0",
            });
        }
    }
    let ps = camera.pixel_size_mm;
    if !(ps > 0.0 && ps.is_finite()) {
        return Err(ConversionError::NotPositive {
            what: "pixel_size_mm",
            value: ps,
        });
    }
    if !(params[0] > 0.0 && params[0].is_finite()) {
        return Err(ConversionError::NotPositive {
            what: "fx",
            value: params[0],
        });
    }
    let (w, h) = (camera.width as f64, camera.height as f64);
    let c = params[0] * ps;
    let c2 = c * c;
    Ok([
        c,
        (params[2] - 0.5 * (w - 1.0)) * ps,
        (0.5 * (h - 1.0) - params[3]) * ps,
        params[4] / c2,
        params[5] / (c2 * c2),
        params[8] / (c2 * c2 * c2),
        params[7] / c,
        -params[6] / c,
        0.0,
        0.0,
    ])
}

#[cfg(test)]
mod tests {
    use super::super::jacobian_checks::{check, rng, uniform};
    use super::*;

    fn random_params(r: &mut pingcal_geometry::consensus::SeededRng) -> [f64; 16] {
        [
            uniform(r, 600.0, 700.0),
            uniform(r, 600.0, 700.0),
            uniform(r, 620.0, 660.0),
            uniform(r, 340.0, 380.0),
            uniform(r, -0.2, 0.2),
            uniform(r, -0.05, 0.05),
            uniform(r, -1e-3, 1e-3),
            uniform(r, -1e-3, 1e-3),
            uniform(r, -0.01, 0.01),
            uniform(r, -0.1, 0.1),
            uniform(r, -0.02, 0.02),
            uniform(r, -0.005, 0.005),
            uniform(r, -1e-3, 1e-3),
            uniform(r, -1e-4, 1e-4),
            uniform(r, -1e-3, 1e-3),
            uniform(r, -1e-4, 1e-4),
        ]
    }

    #[test]
    fn jacobians_match_central_differences_at_random_states() {
        let mut r = rng(21);
        let mut worst: f64 = 0.0;
        for _ in 0..500 {
            let params = random_params(&mut r);
            let y = uniform(&mut r, 0.3, 5.0);
            let xc = Vector3::new(
                uniform(&mut r, -1.0, 1.0) * y,
                y,
                uniform(&mut r, -0.6, 0.6) * y,
            );
            worst = worst.max(check(&OpenCvCamera, &params, &xc, 1e-6));
        }
        // On the optical axis too (r = 0).
        let params = random_params(&mut r);
        worst = worst.max(check(
            &OpenCvCamera,
            &params,
            &Vector3::new(0.0, 2.0, 0.0),
            1e-6,
        ));
        println!("opencv: worst relative Jacobian error {worst:.2e}");
    }

    #[test]
    fn unproject_inverts_project_and_rear_points_are_refused() {
        let mut r = rng(22);
        for _ in 0..200 {
            let p = random_params(&mut r);
            let xc = Vector3::new(uniform(&mut r, -1.0, 1.0), 1.0, uniform(&mut r, -0.6, 0.6));
            let uv = OpenCvCamera.project(&p, &xc, None, None).unwrap();
            let ray = OpenCvCamera.unproject(&p, &uv).unwrap();
            assert!((ray - xc.normalize()).norm() < 1e-10, "{ray:?} {xc:?}");
        }
        let p = random_params(&mut r);
        assert!(OpenCvCamera
            .project(&p, &Vector3::new(0.0, -1.0, 0.0), None, None)
            .is_none());
    }

    #[test]
    fn principal_point_and_the_opencv_frame() {
        // OpenCV: x_cv = (0.1, 0.2, 1) → u = fx·0.1 + cx, v = fy·0.2 + cy (no distortion).
        let mut p = [0.0; 16];
        p[..4].copy_from_slice(&[600.0, 610.0, 320.0, 240.0]);
        let uv = OpenCvCamera
            .project(&p, &Vector3::new(0.1, 1.0, -0.2), None, None)
            .unwrap();
        assert!((uv - Vector2::new(380.0, 362.0)).norm() < 1e-12, "{uv:?}");
    }

    /// Photogrammetric ↔ OpenCV: a grid of points projects to the same pixels within
    /// 1e-9 px, both ways; affinity and rational terms are refused.
    #[test]
    fn photogrammetric_conversion_is_exact() {
        let cam = PhotogrammetricCamera::new(1280, 720, 0.00375);
        let mut r = rng(23);
        let mut worst: f64 = 0.0;
        for _ in 0..50 {
            let pg = [
                uniform(&mut r, 2.3, 2.6),
                uniform(&mut r, -0.05, 0.05),
                uniform(&mut r, -0.05, 0.05),
                uniform(&mut r, -0.03, 0.03),
                uniform(&mut r, -5e-4, 5e-4),
                uniform(&mut r, -2e-5, 2e-5),
                uniform(&mut r, -1e-3, 1e-3),
                uniform(&mut r, -1e-3, 1e-3),
                0.0,
                0.0,
            ];
            let cv = opencv_from_photogrammetric(&cam, &pg).unwrap();
            let back = photogrammetric_from_opencv(&cam, &cv).unwrap();
            for i in 0..21 {
                for j in 0..13 {
                    let xc = Vector3::new(-1.0 + 0.1 * i as f64, 1.0, -0.6 + 0.1 * j as f64);
                    let a = cam.project(&pg, &xc, None, None).unwrap();
                    let b = OpenCvCamera.project(&cv, &xc, None, None).unwrap();
                    let c = cam.project(&back, &xc, None, None).unwrap();
                    worst = worst.max((a - b).norm()).max((a - c).norm());
                }
            }
        }
        println!("photogrammetric ↔ opencv: worst disagreement {worst:.2e} px");
        assert!(worst < 1e-9, "{worst:e} px");
        let mut pg = [2.45, 0.0, 0.0, -0.02, 0.0, 0.0, 0.0, 0.0, 1e-4, 0.0];
        assert!(matches!(
            opencv_from_photogrammetric(&cam, &pg),
            Err(ConversionError::NotExact { term: "B1", .. })
        ));
        pg[8] = 0.0;
        let mut cv = opencv_from_photogrammetric(&cam, &pg).unwrap();
        cv[9] = 0.01;
        assert!(matches!(
            photogrammetric_from_opencv(&cam, &cv),
            Err(ConversionError::NotExact { term: "k4", .. })
        ));
        cv[9] = 0.0;
        cv[1] += 1.0;
        assert!(photogrammetric_from_opencv(&cam, &cv).is_err());
        assert!(photogrammetric_from_opencv(&cam, &cv[..9]).is_err());
    }
}
