//! A camera as the rest of pingcal meets it: a model of the registry ([`ModelKind`]) built for
//! one sensor, with the sensor's image size and pixel pitch. The pipeline's scene, the
//! sphere-calib camera and the simulator's cameras are all this one type; the intrinsic
//! parameters stay beside it (they are what an adjustment moves), so every question takes them.
//!
//! A [`SensorCamera`] is itself a [`CameraModel`] (it hands every call to the built model), so
//! it goes wherever a model does.

use crate::{CameraModel, ModelKind};
use nalgebra::{Matrix2x3, Vector2, Vector3};
use std::sync::Arc;

/// A camera model built for a sensor: which model, the model itself, the image size and the
/// pixel pitch.
#[derive(Clone, Debug)]
pub struct SensorCamera {
    /// Which model of the registry.
    pub kind: ModelKind,
    /// The model, built for the sensor ([`ModelKind::model`]).
    pub model: Arc<dyn CameraModel>,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Pixel pitch (mm).
    pub pixel_size_mm: f64,
}

impl SensorCamera {
    /// A camera of model `kind` on a `width × height` sensor of pitch `pixel_size_mm`.
    pub fn new(kind: ModelKind, width: u32, height: u32, pixel_size_mm: f64) -> Self {
        SensorCamera {
            kind,
            model: kind.model(width, height, pixel_size_mm),
            width,
            height,
            pixel_size_mm,
        }
    }

    /// The focal length in mm at `params`: the image scale that turns a size in pixels at a
    /// depth into millimetres (`size_px · pixel pitch · depth / focal_mm`).
    pub fn focal_mm(&self, params: &[f64]) -> f64 {
        self.model.focal_px(params) * self.pixel_size_mm
    }

    /// The unit ray through pixel (`x`, `y`) at `params`, normalised again and None unless
    /// finite (where a lens's inverse is asked far outside its field of view).
    pub fn ray(&self, params: &[f64], x: f64, y: f64) -> Option<Vector3<f64>> {
        self.model
            .unproject(params, &Vector2::new(x, y))
            .map(|r| r.normalize())
            .filter(|r| r.iter().all(|v| v.is_finite()))
    }

    /// The pixel of a point (or direction) `p` of the camera frame at `params`; None when it
    /// does not project or the pixel is not finite.
    pub fn pixel(&self, params: &[f64], p: &Vector3<f64>) -> Option<(f64, f64)> {
        self.model
            .project(params, p, None, None)
            .map(|uv| (uv.x, uv.y))
            .filter(|(x, y)| x.is_finite() && y.is_finite())
    }

    /// The focal length in pixels at the image's centre, measured through the lens: one over
    /// the angle between the rays ([`Self::ray`]) of the centre pixel and its right
    /// neighbour. NaN when they cannot be formed.
    pub fn centre_focal_px(&self, params: &[f64]) -> f64 {
        let (cx, cy) = (
            (f64::from(self.width) - 1.0) / 2.0,
            (f64::from(self.height) - 1.0) / 2.0,
        );
        match (self.ray(params, cx, cy), self.ray(params, cx + 1.0, cy)) {
            (Some(a), Some(b)) if a.angle(&b) > 0.0 => 1.0 / a.angle(&b),
            _ => f64::NAN,
        }
    }

    /// This camera at the intrinsic values `params`: what takes a camera's two maps
    /// (pixel → ray, ray → pixel) with nothing else.
    pub fn at<'a>(&'a self, params: &'a [f64]) -> CameraAt<'a> {
        CameraAt {
            camera: self,
            params,
        }
    }

    /// Whether pixel `uv` lies on the image, pixel centres from 0 to size − 1 and half a
    /// pixel beyond them (the outer edges of the border pixels).
    pub fn on_image(&self, uv: &Vector2<f64>) -> bool {
        let (w, h) = (f64::from(self.width), f64::from(self.height));
        uv.x >= -0.5 && uv.y >= -0.5 && uv.x <= w - 0.5 && uv.y <= h - 0.5
    }
}

/// A [`SensorCamera`] at given intrinsic values ([`SensorCamera::at`]). Its maps are the
/// model's own, as they are: [`Self::ray`] is [`CameraModel::unproject`] (not normalised again,
/// not checked for finiteness) and [`Self::pixel`] is [`CameraModel::project`].
#[derive(Clone, Copy, Debug)]
pub struct CameraAt<'a> {
    /// The camera.
    pub camera: &'a SensorCamera,
    /// Its intrinsic values, in the model's order.
    pub params: &'a [f64],
}

impl CameraAt<'_> {
    /// The ray through pixel (`x`, `y`) ([`CameraModel::unproject`]).
    pub fn ray(&self, x: f64, y: f64) -> Option<Vector3<f64>> {
        self.camera
            .model
            .unproject(self.params, &Vector2::new(x, y))
    }

    /// The pixel of camera-frame point (or direction) `p` ([`CameraModel::project`]).
    pub fn pixel(&self, p: &Vector3<f64>) -> Option<Vector2<f64>> {
        self.camera.model.project(self.params, p, None, None)
    }
}

impl CameraModel for SensorCamera {
    fn name(&self) -> &'static str {
        self.model.name()
    }

    fn parameter_names(&self) -> &'static [&'static str] {
        self.model.parameter_names()
    }

    fn project(
        &self,
        params: &[f64],
        xc: &Vector3<f64>,
        jac_point: Option<&mut Matrix2x3<f64>>,
        jac_params: Option<&mut [f64]>,
    ) -> Option<Vector2<f64>> {
        self.model.project(params, xc, jac_point, jac_params)
    }

    fn unproject(&self, params: &[f64], uv: &Vector2<f64>) -> Option<Vector3<f64>> {
        self.model.unproject(params, uv)
    }

    /// The sensor's pitch (every model, not only those that know their sensor).
    fn pixel_size_mm(&self) -> Option<f64> {
        Some(self.pixel_size_mm)
    }

    fn focal_px(&self, params: &[f64]) -> f64 {
        self.model.focal_px(params)
    }

    fn principal_point_px(&self, params: &[f64]) -> Vector2<f64> {
        self.model.principal_point_px(params)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every model of the registry, on a sensor of its sample lens: a pixel's ray projects
    /// back to the pixel, the centre's focal length measured through the lens is the model's
    /// within the lens's distortion, and the sensor answers for the model's pitch.
    #[test]
    fn every_model_maps_pixels_to_rays_and_back() {
        for kind in ModelKind::ALL {
            let (w, h, pitch) = (1280, 960, 0.005);
            let cam = SensorCamera::new(kind, w, h, pitch);
            let params = kind.nominal(900.0, w, h, pitch);
            for (x, y) in [(10.0, 20.0), (640.0, 480.0), (1000.0, 700.0)] {
                let r = cam
                    .ray(&params, x, y)
                    .unwrap_or_else(|| panic!("{kind:?}: no ray at ({x}, {y})"));
                assert!((r.norm() - 1.0).abs() < 1e-12);
                let (u, v) = cam.pixel(&params, &(r * 3000.0)).unwrap();
                assert!(
                    (u - x).abs() < 1e-6 && (v - y).abs() < 1e-6,
                    "{kind:?}: {u} {v}"
                );
            }
            let f = cam.centre_focal_px(&params);
            assert!(
                (f / cam.focal_px(&params) - 1.0).abs() < 0.01,
                "{kind:?}: {f}"
            );
            assert_eq!(cam.pixel_size_mm(), Some(pitch));
            assert!((cam.focal_mm(&params) - cam.focal_px(&params) * pitch).abs() < 1e-12);
        }
    }

    /// The view at given values answers with the model's own maps, bit for bit.
    #[test]
    fn the_view_at_values_is_the_model_itself() {
        let kind = ModelKind::DEFAULT;
        let cam = SensorCamera::new(kind, 640, 480, 0.006);
        let params = kind.nominal(700.0, 640, 480, 0.006);
        let at = cam.at(&params);
        let uv = Vector2::new(100.25, 300.5);
        let r = at.ray(uv.x, uv.y).unwrap();
        assert_eq!(Some(r), cam.model.unproject(&params, &uv));
        assert_eq!(at.pixel(&r), cam.model.project(&params, &r, None, None));
    }

    #[test]
    fn the_image_reaches_half_a_pixel_beyond_the_border_centres() {
        let cam = SensorCamera::new(ModelKind::DEFAULT, 100, 50, 0.01);
        assert!(cam.on_image(&Vector2::new(-0.5, 49.5)));
        assert!(cam.on_image(&Vector2::new(99.5, -0.5)));
        assert!(!cam.on_image(&Vector2::new(99.6, 10.0)));
        assert!(!cam.on_image(&Vector2::new(10.0, -0.6)));
    }
}
