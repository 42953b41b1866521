//! The head: the stereo pair (MYNT EYE D1000-like) and any cameras of `[[rig.cameras]]`,
//! with their true parameters and poses relative to the left camera, and the pose of the main station's left camera. Below both the
//! scene (which places the targets where the main image sees them) and the station plan.
//!
//! Poses are world → camera (`x_cam = R·X + t`, [`Rigid3`]), camera frame X right, Y forward
//! (optical axis), Z up (docs/formats.md).

use crate::config::{SimConfig, StationConfig};
use nalgebra::{Matrix3, Vector3};
use pingcal_ba::camera::{CameraModel, PhotogrammetricCamera, SensorCamera};
use pingcal_geometry::from_opk;
use pingcal_geometry::Rigid3;

type V3 = Vector3<f64>;

/// The photogrammetric model of `cam`'s sensor when the camera's model is that type (for
/// its own field-of-view test: its forward distortion polynomial folds back far outside the
/// field of view).
fn photogrammetric(cam: &SensorCamera) -> Option<PhotogrammetricCamera> {
    (cam.model.name() == PhotogrammetricCamera::NAME)
        .then(|| PhotogrammetricCamera::new(cam.width, cam.height, cam.pixel_size_mm))
}

/// One camera of the head: its model and true parameters.
#[derive(Debug, Clone)]
pub struct CameraUnit {
    /// `left` or `right`.
    pub id: String,
    /// The model and its sensor.
    pub model: SensorCamera,
    /// True parameters, in the model's slice order (the photogrammetric model's
    /// `[c, xp, yp, K1, K2, K3, P1, P2, B1, B2]`).
    pub params: Vec<f64>,
}

impl CameraUnit {
    /// Largest ideal (undistorted) image radius, in mm from the principal point, over the
    /// image border (the photogrammetric model; 0 for the others, which
    /// [`Self::project_in_view`] judges by their unprojection). Points whose ideal radius
    /// exceeds it are outside the image even when the distortion polynomial (which folds
    /// back far outside the field of view) maps them inside.
    pub fn max_ideal_radius_mm(&self) -> f64 {
        let Some(cam) = photogrammetric(&self.model) else {
            return 0.0;
        };
        let (w, h) = (cam.width as f64 - 1.0, cam.height as f64 - 1.0);
        let mut r: f64 = 0.0;
        for (u, v) in [
            (0.0, 0.0),
            (w, 0.0),
            (0.0, h),
            (w, h),
            (0.5 * w, 0.0),
            (0.5 * w, h),
            (0.0, 0.5 * h),
            (w, 0.5 * h),
        ] {
            let xy = cam.pixel_to_sensor(&nalgebra::Vector2::new(u, v));
            if let Some(q) = cam.undistort_sensor(&self.params, &xy) {
                r = r.max(q.norm());
            }
        }
        r
    }

    /// Projects a camera-frame point if it is really in the field of view. The
    /// photogrammetric model: in front, and within the ideal radius of the image border
    /// (see [`Self::max_ideal_radius_mm`]). The others (which see beside and behind the
    /// lens plane): the model projects it, and the pixel's own ray is the point's (no fold
    /// of the distortion brings it there).
    pub fn project_in_view(&self, xc: &V3, r_max: f64) -> Option<nalgebra::Vector2<f64>> {
        if self.model.name() != PhotogrammetricCamera::NAME {
            let uv = self.model.project(&self.params, xc, None, None)?;
            let ray = self.model.unproject(&self.params, &uv)?;
            return ((ray - xc.normalize()).norm() < 1e-6).then_some(uv);
        }
        if xc.y <= 0.0 {
            return None;
        }
        let c = self.params[0];
        let (x, z) = (
            c * xc.x / xc.y - self.params[1],
            c * xc.z / xc.y - self.params[2],
        );
        if (x * x + z * z).sqrt() > r_max {
            return None;
        }
        self.model.project(&self.params, xc, None, None)
    }
}

/// The head: the stereo pair (left, index 0; right, index 1) and any cameras of
/// `[[rig.cameras]]` after them, each with its pose relative to the left camera.
#[derive(Debug, Clone)]
pub struct StereoRig {
    /// Left, right, then the `[[rig.cameras]]` in order.
    pub cameras: Vec<CameraUnit>,
    /// Per camera: left-camera frame → that camera's frame (the identity for the left).
    pub camera_from_left: Vec<Rigid3>,
}

/// `x_cam = R_rel (x_left − C)` for a camera at `centre` (left frame) turned by `opk_deg`.
fn from_left(opk_deg: [f64; 3], centre: [f64; 3]) -> Rigid3 {
    let [o, p, k] = opk_deg.map(f64::to_radians);
    Rigid3::from_rotation_and_centre(from_opk(o, p, k), V3::from(centre))
}

impl StereoRig {
    /// The head from the configuration.
    pub fn from_config(cfg: &SimConfig) -> Self {
        let c = &cfg.camera;
        let model = SensorCamera::new(c.model, c.width, c.height, c.pixel_size_mm);
        let unit = |id: &str, params: &[f64]| CameraUnit {
            id: id.into(),
            model: model.clone(),
            params: params.to_vec(),
        };
        let mut cameras = vec![unit("left", &c.left.params), unit("right", &c.right.params)];
        let mut camera_from_left = vec![
            Rigid3::identity(),
            from_left(c.right_opk_deg, c.right_offset_mm),
        ];
        for extra in &cfg.rig.cameras {
            cameras.push(unit(
                &extra.id,
                extra.params.as_deref().unwrap_or(&c.left.params),
            ));
            camera_from_left.push(from_left(extra.opk_deg, extra.t_mm));
        }
        Self {
            cameras,
            camera_from_left,
        }
    }

    /// Left-camera frame → right-camera frame.
    pub fn right_from_left(&self) -> Rigid3 {
        self.camera_from_left[1]
    }
}

/// The rotation world → camera for a camera at `centre` looking at `look_at`, rolled by
/// `roll` (radians) about its optical axis ([`Rigid3::looking_at`]).
pub fn look_at_rotation(centre: &V3, look_at: &V3, roll: f64) -> Matrix3<f64> {
    Rigid3::looking_at(*centre, *look_at, roll).rotation
}

/// The main station's left camera pose (world → camera).
pub fn main_left_pose(sc: &StationConfig) -> Rigid3 {
    let c = V3::from(sc.main_centre_mm);
    Rigid3::from_rotation_and_centre(look_at_rotation(&c, &V3::from(sc.main_look_at_mm), 0.0), c)
}
