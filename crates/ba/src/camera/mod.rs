//! Camera (sensor) models: the map from a point in the camera frame to pixels, with
//! analytic Jacobians with respect to that point and to every intrinsic parameter.
//!
//! A new model (OpenCV, Kannala–Brandt, …) is added by implementing [`CameraModel`]; the
//! solver never looks inside a model.
//!
//! Pixel convention everywhere in pingcal: origin at the centre of the top-left pixel,
//! u to the right, v down.

mod bal;
mod photogrammetric;

pub use bal::BalCamera;
pub use photogrammetric::{PhotogrammetricCamera, PHOTOGRAMMETRIC_PARAMS};

use nalgebra::{Matrix2x3, Vector2, Vector3};

/// A camera model: intrinsic parameters in a flat slice, projection with Jacobians.
pub trait CameraModel: Send + Sync + std::fmt::Debug {
    /// Short name of the model (as written in files and reports).
    fn name(&self) -> &'static str;

    /// Names of the intrinsic parameters, in the order of the parameter slice.
    fn parameter_names(&self) -> &'static [&'static str];

    /// Number of intrinsic parameters.
    fn num_params(&self) -> usize {
        self.parameter_names().len()
    }

    /// Projects `xc` (camera frame) to pixels.
    ///
    /// Returns `None` when the point cannot be imaged by the model (behind the camera, or
    /// on the plane through the projection centre). When given, `jac_point` receives
    /// ∂(u,v)/∂xc (2×3) and `jac_params` receives ∂(u,v)/∂params as a row-major 2×n slice
    /// (first the n derivatives of u, then those of v).
    fn project(
        &self,
        params: &[f64],
        xc: &Vector3<f64>,
        jac_point: Option<&mut Matrix2x3<f64>>,
        jac_params: Option<&mut [f64]>,
    ) -> Option<Vector2<f64>>;

    /// Back-projects a pixel to a unit ray direction in the camera frame, or `None` if the
    /// distortion cannot be inverted there.
    fn unproject(&self, params: &[f64], uv: &Vector2<f64>) -> Option<Vector3<f64>>;

    /// Pixel pitch in mm, for models that know their sensor (reports give residuals in µm).
    fn pixel_size_mm(&self) -> Option<f64> {
        None
    }
}

#[cfg(test)]
pub(crate) mod jacobian_checks {
    //! Central finite-difference checks of every analytic camera Jacobian.
    use super::*;
    use rand::Rng;

    /// Compares analytic and central-difference Jacobians at `xc`, `params`.
    /// Relative tolerance `tol` with respect to the larger of |analytic| and the column norm.
    pub fn check(model: &dyn CameraModel, params: &[f64], xc: &Vector3<f64>, tol: f64) {
        let n = model.num_params();
        let mut jp = Matrix2x3::zeros();
        let mut ji = vec![0.0; 2 * n];
        model
            .project(params, xc, Some(&mut jp), Some(&mut ji))
            .expect("projectable");
        for k in 0..3 {
            let h = 1e-6 * xc.norm().max(1.0);
            let (mut a, mut b) = (*xc, *xc);
            a[k] += h;
            b[k] -= h;
            let fd = (model.project(params, &a, None, None).unwrap()
                - model.project(params, &b, None, None).unwrap())
                / (2.0 * h);
            let an = jp.column(k).into_owned();
            let scale = an.norm().max(fd.norm()).max(1e-8);
            assert!(
                (fd - an).norm() / scale < tol,
                "{} d/dxc[{k}]: fd {fd:?} analytic {an:?}",
                model.name()
            );
        }
        let uv0 = model.project(params, xc, None, None).unwrap();
        for k in 0..n {
            // Step so that the image moves by ~1e-4 of its coordinate size: rounding error
            // ~1e-12 and truncation error ~1e-8 relative.
            let col = Vector2::new(ji[k], ji[n + k]).norm();
            let h = if col > 0.0 {
                1e-4 * uv0.norm().max(1.0) / col
            } else {
                1e-6 * params[k].abs().max(1e-3)
            };
            let (mut a, mut b) = (params.to_vec(), params.to_vec());
            a[k] += h;
            b[k] -= h;
            let fd = (model.project(&a, xc, None, None).unwrap()
                - model.project(&b, xc, None, None).unwrap())
                / (2.0 * h);
            let an = Vector2::new(ji[k], ji[n + k]);
            let scale = an.norm().max(fd.norm()).max(1e-8);
            assert!(
                (fd - an).norm() / scale < tol,
                "{} d/d{}: fd {fd:?} analytic {an:?}",
                model.name(),
                model.parameter_names()[k]
            );
        }
    }

    pub fn rng(seed: u64) -> pingcal_geometry::consensus::SeededRng {
        pingcal_geometry::consensus::rng(seed)
    }

    pub fn uniform(r: &mut pingcal_geometry::consensus::SeededRng, lo: f64, hi: f64) -> f64 {
        r.random_range(lo..hi)
    }
}
