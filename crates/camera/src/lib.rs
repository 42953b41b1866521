//! Camera (sensor) models: the map from a point in the camera frame to pixels, with
//! analytic Jacobians with respect to that point and to every intrinsic parameter.
//!
//! | model | type | parameters |
//! |---|---|---|
//! | photogrammetric (docs/formats.md, forward Brown + affinity B1, B2) | [`PhotogrammetricCamera`] | c, xp, yp, K1–K3, P1, P2, B1, B2 (mm) |
//! | Brown backward (DBAT, PhotoModeler, Australis: a correction of the measured point) | [`BrownBackwardCamera`] | c, xp, yp, K1–K3, P1, P2, B1, B2 (mm) |
//! | OpenCV (rational radial, tangential, thin prism) | [`OpenCvCamera`] | fx, fy, cx, cy, k1, k2, p1, p2, k3–k6, s1–s4 (px) |
//! | Kannala–Brandt fisheye (OpenCV's `cv::fisheye`, Kalibr's `pinhole-equi`) | [`FisheyeCamera`] | fx, fy, cx, cy, k1–k4 (px) |
//! | double sphere (Usenko et al. 2018, Kalibr's `ds`): lenses beyond 180° | [`DoubleSphereCamera`] | fx, fy, cx, cy, ξ, α (px) |
//! | BAL benchmark | [`BalCamera`] | f, k1, k2 |
//!
//! Every model but BAL works in the camera frame of docs/formats.md: X to image right, **Y along
//! the optical axis**, Z to image up, so that models are interchangeable in one network
//! and with the initialisers. An affinity (differential scale) and shear are B1, B2 in
//! the two photogrammetric models and fx ≠ fy in the OpenCV and fisheye models.
//!
//! A new model is added by implementing [`CameraModel`]; the solver never looks inside a
//! model. Check its analytic Jacobians with [`check_jacobians`] at many random states
//! (central differences; a relative agreement of 1e-6 is what the models here meet):
//!
//! ```
//! use nalgebra::Vector3;
//! use pingcal_camera::{check_jacobians, OpenCvCamera};
//! let params = [650.0, 651.0, 640.0, 360.0, -0.1, 0.01, 1e-4, -2e-4, 0.0,
//!               0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
//! let worst = check_jacobians(&OpenCvCamera, &params, &Vector3::new(0.3, 2.0, -0.4), 1e-6)
//!     .expect("analytic and numerical Jacobians agree");
//! assert!(worst < 1e-6);
//! ```
//!
//! Exact conversions between models, where the two forms coincide, are in
//! [`opencv_from_photogrammetric`] and [`photogrammetric_from_opencv`]; the module
//! [`opencv`] lists which conversions are exact and which are not. The modules
//! [`opencv`], [`fisheye`] and [`brown_backward`] state each model's mathematics.
//!
//! Pixel convention everywhere in pingcal: origin at the centre of the top-left pixel,
//! u to the right, v down.

mod bal;
pub mod brown_backward;
pub mod double_sphere;
pub mod fisheye;
pub mod forms;
pub mod kind;
pub mod opencv;
mod photogrammetric;
pub mod refit;
pub mod sensor;

pub use bal::BalCamera;
pub use brown_backward::{BrownBackwardCamera, BROWN_BACKWARD_PARAMS};
pub use double_sphere::{DoubleSphereCamera, DOUBLE_SPHERE_PARAMS};
pub use fisheye::{FisheyeCamera, FISHEYE_PARAMS};
pub use kind::{LensClass, ModelEntry, ModelKind, SampleLens, MM_KEYS, REGISTRY};
pub use opencv::{
    opencv_from_photogrammetric, photogrammetric_from_opencv, ConversionError, OpenCvCamera,
    OPENCV_PARAMS,
};
pub use photogrammetric::{PhotogrammetricCamera, PHOTOGRAMMETRIC_PARAMS};
pub use sensor::{CameraAt, SensorCamera};

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

    /// The image scale at the principal point, pixels per unit of tan(angle off axis): the
    /// focal length in pixels (the mean of fx and fy; c over the pixel pitch). What sizes
    /// and search windows are judged by.
    fn focal_px(&self, params: &[f64]) -> f64;

    /// The principal point, pixels.
    fn principal_point_px(&self, params: &[f64]) -> Vector2<f64>;
}

/// A disagreement found by [`check_jacobians`].
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum JacobianMismatch {
    /// The parameter slice does not have the model's length.
    #[error("{model}: {given} parameters given, the model has {expected}")]
    ParameterCount {
        /// Model name.
        model: &'static str,
        /// Length of the slice given.
        given: usize,
        /// The model's number of parameters.
        expected: usize,
    },
    /// The point (or a point a difference step away) does not project.
    #[error("{model}: the point ({:.6e}, {:.6e}, {:.6e}) or a neighbour does not project", point[0], point[1], point[2])]
    NotProjectable {
        /// Model name.
        model: &'static str,
        /// The camera-frame point.
        point: [f64; 3],
    },
    /// An analytic column disagrees with its central difference.
    #[error("{model} ∂(u, v)/∂{parameter}: analytic ({:.9e}, {:.9e}), central difference ({:.9e}, {:.9e}), relative error {relative:.2e} > {tolerance:.1e}", analytic[0], analytic[1], numeric[0], numeric[1])]
    Mismatch {
        /// Model name.
        model: &'static str,
        /// `X`, `Y`, `Z` (camera-frame point) or the intrinsic's name.
        parameter: String,
        /// The analytic column (∂u, ∂v).
        analytic: [f64; 2],
        /// The central difference.
        numeric: [f64; 2],
        /// |analytic − numeric| / max(|analytic|, |numeric|, noise/tol) (see
        /// [`check_jacobians`]).
        relative: f64,
        /// The tolerance it exceeded.
        tolerance: f64,
    },
}

/// Compares a model's analytic Jacobians (w.r.t. the camera-frame point and every
/// intrinsic) with central differences at `xc`, `params`; returns the worst relative
/// error, or the first column whose relative error exceeds `tol`.
///
/// The numerical column is a central difference with Richardson extrapolation,
/// `(4·D(h/2) − D(h))/3` (truncation error O(h⁴)), with steps h = 1e-6·max(|xc|, 1) for
/// the point and, for a parameter, the step that moves the image by ~1e-4 of its
/// coordinate size but at most 1e-3·max(|p|, 1) (a parameter the image is insensitive to
/// at this point would otherwise get a step beyond its range), or 1e-6·max(|p|, 1e-3) if
/// its analytic column is zero. The relative
/// error of a column is |analytic − numeric| / max(|analytic|, |numeric|, noise/tol),
/// norms of the 2-vectors (∂u, ∂v), where noise = 64·ε·max(|uv|, 1)/h bounds the
/// rounding error of the extrapolated difference: a column too small for differences of
/// the pixel coordinates to resolve (e.g. ∂u/∂Y on the optical axis) is compared in
/// absolute terms at that resolution. So a tolerance of 1e-6 separates a wrong
/// derivative from difference noise for any smooth model; use it at many random states
/// and near the model's special points (e.g. the optical axis).
pub fn check_jacobians(
    model: &dyn CameraModel,
    params: &[f64],
    xc: &Vector3<f64>,
    tol: f64,
) -> Result<f64, JacobianMismatch> {
    let n = model.num_params();
    if params.len() != n {
        return Err(JacobianMismatch::ParameterCount {
            model: model.name(),
            given: params.len(),
            expected: n,
        });
    }
    let not_projectable = || JacobianMismatch::NotProjectable {
        model: model.name(),
        point: [xc.x, xc.y, xc.z],
    };
    let mut jp = Matrix2x3::zeros();
    let mut ji = vec![0.0; 2 * n];
    let uv0 = model
        .project(params, xc, Some(&mut jp), Some(&mut ji))
        .ok_or_else(not_projectable)?;
    let mut worst: f64 = 0.0;
    let noise_scale = 64.0 * f64::EPSILON * uv0.norm().max(1.0);
    let mut compare = |name: &str, an: Vector2<f64>, fd: Vector2<f64>, h: f64| {
        let scale = an.norm().max(fd.norm()).max(noise_scale / (h * tol));
        let relative = (fd - an).norm() / scale;
        // `!(a < b)` so that a NaN is a mismatch.
        if !(relative < tol) {
            return Err(JacobianMismatch::Mismatch {
                model: model.name(),
                parameter: name.to_string(),
                analytic: [an.x, an.y],
                numeric: [fd.x, fd.y],
                relative,
                tolerance: tol,
            });
        }
        worst = worst.max(relative);
        Ok(())
    };
    for k in 0..3 {
        let h = 1e-6 * xc.norm().max(1.0);
        let diff = |h: f64| -> Option<Vector2<f64>> {
            let (mut a, mut b) = (*xc, *xc);
            a[k] += h;
            b[k] -= h;
            Some(
                (model.project(params, &a, None, None)? - model.project(params, &b, None, None)?)
                    / (2.0 * h),
            )
        };
        let fd = richardson(diff(h), diff(0.5 * h)).ok_or_else(not_projectable)?;
        compare(["X", "Y", "Z"][k], jp.column(k).into_owned(), fd, h)?;
    }
    for k in 0..n {
        let col = Vector2::new(ji[k], ji[n + k]).norm();
        let h = if col > 0.0 {
            (1e-4 * uv0.norm().max(1.0) / col).min(1e-3 * params[k].abs().max(1.0))
        } else {
            1e-6 * params[k].abs().max(1e-3)
        };
        let diff = |h: f64| -> Option<Vector2<f64>> {
            let (mut a, mut b) = (params.to_vec(), params.to_vec());
            a[k] += h;
            b[k] -= h;
            Some(
                (model.project(&a, xc, None, None)? - model.project(&b, xc, None, None)?)
                    / (2.0 * h),
            )
        };
        let fd = richardson(diff(h), diff(0.5 * h)).ok_or_else(not_projectable)?;
        compare(
            model.parameter_names()[k],
            Vector2::new(ji[k], ji[n + k]),
            fd,
            h,
        )?;
    }
    Ok(worst)
}

/// Richardson extrapolation of central differences at steps h and h/2.
fn richardson(d1: Option<Vector2<f64>>, d2: Option<Vector2<f64>>) -> Option<Vector2<f64>> {
    Some((4.0 * d2? - d1?) / 3.0)
}

#[cfg(test)]
pub(crate) mod jacobian_checks {
    //! Test helpers: [`check`] asserts [`super::check_jacobians`]; seeded random numbers.
    use super::*;
    use rand::Rng;

    /// Asserts that the analytic Jacobians at `xc`, `params` agree with central
    /// differences to the relative tolerance `tol` ([`check_jacobians`]); returns the
    /// worst relative error.
    pub fn check(model: &dyn CameraModel, params: &[f64], xc: &Vector3<f64>, tol: f64) -> f64 {
        match check_jacobians(model, params, xc, tol) {
            Ok(worst) => worst,
            Err(e) => panic!("{e}"),
        }
    }

    pub fn rng(seed: u64) -> pingcal_geometry::consensus::SeededRng {
        pingcal_geometry::consensus::rng(seed)
    }

    pub fn uniform(r: &mut pingcal_geometry::consensus::SeededRng, lo: f64, hi: f64) -> f64 {
        r.random_range(lo..hi)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;

    /// A wide-angle or fisheye lens of each kind on a 1280 × 800 sensor of 3 µm pixels.
    fn lenses() -> Vec<(Arc<dyn CameraModel>, Vec<f64>)> {
        let k = |m: ModelKind| m.model(1280, 800, 0.003);
        vec![
            (
                k(ModelKind::Photogrammetric),
                vec![
                    1.9, 0.01, -0.02, -0.04, 1.2e-3, -2e-5, 2e-4, -1e-4, 1e-4, 0.0,
                ],
            ),
            (
                k(ModelKind::BrownBackward),
                vec![1.9, 0.01, -0.02, 0.03, -5e-4, 1e-5, 2e-4, -1e-4, 1e-4, 0.0],
            ),
            (
                k(ModelKind::OpenCv),
                vec![
                    380.0, 381.0, 641.0, 399.0, -0.1, 0.02, 1e-4, -2e-4, 0.001, 0.3, 0.01, 0.002,
                    0.0, 0.0, 0.0, 0.0,
                ],
            ),
            (
                k(ModelKind::KannalaBrandt),
                vec![360.0, 361.0, 641.0, 399.0, 0.02, -0.005, 0.001, -2e-4],
            ),
            (
                k(ModelKind::DoubleSphere),
                vec![350.0, 351.0, 641.0, 399.0, -0.2, 0.58],
            ),
        ]
    }

    /// Every pixel of a 64 × 40 grid over the whole image: unprojected, projected back to
    /// within 1e-9 px; every direction unprojected from a pixel is one the model projects.
    #[test]
    fn every_model_round_trips_over_the_whole_image() {
        for (m, p) in lenses() {
            let mut worst: f64 = 0.0;
            for i in 0..=64 {
                for j in 0..=40 {
                    let uv = Vector2::new(1279.0 * i as f64 / 64.0, 799.0 * j as f64 / 40.0);
                    let ray = m
                        .unproject(&p, &uv)
                        .unwrap_or_else(|| panic!("{}: {uv:?} does not unproject", m.name()));
                    assert!((ray.norm() - 1.0).abs() < 1e-12);
                    let back = m.project(&p, &(ray * 3.0), None, None).unwrap();
                    worst = worst.max((back - uv).norm());
                }
            }
            assert!(worst < 1e-9, "{}: worst round trip {worst:e} px", m.name());
        }
    }

    #[test]
    fn the_principal_point_is_where_the_axis_projects_and_the_focal_length_its_scale() {
        for (m, p) in lenses() {
            let pp = m.principal_point_px(&p);
            let axis = m
                .project(&p, &Vector3::new(0.0, 1.0, 0.0), None, None)
                .unwrap();
            assert!((axis - pp).norm() < 1e-9, "{}: {axis:?} {pp:?}", m.name());
            // d(u, v)/d(tan θ) on the axis, averaged over x and z.
            let mut jp = Matrix2x3::zeros();
            m.project(&p, &Vector3::new(0.0, 1.0, 0.0), Some(&mut jp), None);
            let scale = 0.5 * (jp[(0, 0)].abs() + jp[(1, 2)].abs());
            let f = m.focal_px(&p);
            // the affinity B1 of the photogrammetric models scales x only
            assert!((scale - f).abs() < 1e-3 * f, "{}: {scale} {f}", m.name());
        }
    }

    #[test]
    fn kinds_name_their_models() {
        for (k, name) in ModelKind::ALL.iter().zip(ModelKind::NAMES) {
            assert_eq!(k.name(), name);
            assert_eq!(ModelKind::from_name(name), Some(*k));
            let m = k.model(640, 480, 0.005);
            assert_eq!(m.parameter_names(), k.parameter_names());
            let ideal = k.nominal(500.0, 640, 480, 0.005);
            assert!((m.focal_px(&ideal) - 500.0).abs() < 1e-9, "{k}");
            let pp = m.principal_point_px(&ideal);
            assert!(
                (pp - Vector2::new(319.5, 239.5)).norm() < 1e-9,
                "{k}: {pp:?}"
            );
        }
        assert_eq!(ModelKind::from_name("fisheye"), None);
    }
}
