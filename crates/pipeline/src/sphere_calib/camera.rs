//! The camera of a sphere-calib project: any of pingcal's camera models
//! ([`pingcal_ba::camera::CameraModel`]) with known parameters, from any form of the camera
//! file ([`pingcal_project::CameraFile`]). Every pixel ↔ ray of the image side goes through
//! the model's own `project` and `unproject`, in pingcal's camera frame (X right, Y forward,
//! Z up), so distortion is exact whatever the model.

use nalgebra::Vector3;
use pingcal_ba::camera::SensorCamera;
use pingcal_project::CameraFile;
use pingcal_targets::ball::CameraRays;

type V3 = Vector3<f64>;

/// A camera with known intrinsics: the model built for its sensor, the values, and the file
/// they were read from. Every pixel ↔ ray is the sensor camera's ([`SensorCamera::ray`],
/// [`SensorCamera::pixel`]) at these values.
#[derive(Debug)]
pub struct Camera {
    /// The model built for the sensor (its width, height and pitch).
    pub sensor: SensorCamera,
    /// Its parameters, in the model's order.
    pub params: Vec<f64>,
    /// The file it was read from, as read.
    pub file: CameraFile,
}

impl Camera {
    /// From a camera file: the model the project file's `model` word names, built as
    /// `pingcal calibrate` builds it.
    pub fn from_file(c: &CameraFile) -> Self {
        Camera {
            sensor: SensorCamera::new(c.intrinsics.model, c.width, c.height, c.pixel_size_mm),
            params: c.intrinsics.values.clone(),
            file: c.clone(),
        }
    }

    /// The unit ray through a pixel ([`SensorCamera::ray`]).
    pub fn ray(&self, x: f64, y: f64) -> Option<V3> {
        self.sensor.ray(&self.params, x, y)
    }

    /// The pixel of a point (or direction) of the camera frame ([`SensorCamera::pixel`]).
    pub fn project(&self, p: &V3) -> Option<(f64, f64)> {
        self.sensor.pixel(&self.params, p)
    }

    /// The focal length in pixels at the image's centre ([`SensorCamera::centre_focal_px`]).
    pub fn f_px(&self) -> f64 {
        self.sensor.centre_focal_px(&self.params)
    }
}

impl CameraRays for Camera {
    fn pixel_to_ray(&self, x: f64, y: f64) -> Option<[f64; 3]> {
        self.ray(x, y).map(|r| [r.x, r.y, r.z])
    }

    fn ray_to_pixel(&self, ray: [f64; 3]) -> Option<[f64; 2]> {
        self.project(&V3::from(ray)).map(|(x, y)| [x, y])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_model_maps_pixels_to_rays_and_back() {
        let photo = "model = \"photogrammetric\"\nwidth = 1280\nheight = 720\npixel_size_mm = 0.00375\n[params]\nc_mm = 2.45\nk1 = -0.021\nk2 = 4.0e-4\n";
        let cv = "model = \"opencv\"\nwidth = 1280\nheight = 1024\n[params]\nfx = 4548.4\nfy = 4544.4\ncx = 703.2\ncy = 609.2\nk1 = -0.1\np1 = 0.001\n";
        let fish = "model = \"fisheye\"\nwidth = 640\nheight = 480\n[params]\nfx = 300.0\nfy = 301.0\ncx = 320.0\ncy = 240.0\nk1 = 0.01\n";
        for text in [photo, cv, fish] {
            let cam = Camera::from_file(&CameraFile::parse(text, "c.toml").unwrap());
            for (x, y) in [(10.0, 20.0), (300.0, 200.0), (600.0, 400.0)] {
                let r = cam
                    .ray(x, y)
                    .unwrap_or_else(|| panic!("{text}: no ray at ({x}, {y})"));
                let (u, v) = cam.project(&(r * 3000.0)).unwrap();
                assert!(
                    (u - x).abs() < 1e-6 && (v - y).abs() < 1e-6,
                    "{text}: {u} {v}"
                );
            }
            assert!(cam.f_px() > 100.0);
        }
    }
}
