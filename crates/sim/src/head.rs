//! The stereo head (MYNT EYE D1000-like): its two cameras with their true parameters, the
//! rig's relative pose, and the pose of the main station's left camera. Below both the
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

/// The stereo head: left and right cameras and the right camera's pose in the left frame.
#[derive(Debug, Clone)]
pub struct StereoRig {
    /// Left camera (index 0) and right camera (index 1).
    pub cameras: [CameraUnit; 2],
    /// Left-camera frame → right-camera frame.
    pub right_from_left: Rigid3,
}

impl StereoRig {
    /// The head from the configuration.
    pub fn from_config(cfg: &SimConfig) -> Self {
        let c = &cfg.camera;
        let model = SensorCamera::new(c.model, c.width, c.height, c.pixel_size_mm);
        let o = c.right_opk_deg;
        // Right camera orientation relative to left: x_right = R_rel (x_left − C_right).
        let r_rel = from_opk(o[0].to_radians(), o[1].to_radians(), o[2].to_radians());
        let right_from_left = Rigid3::from_rotation_and_centre(r_rel, V3::from(c.right_offset_mm));
        Self {
            cameras: [
                CameraUnit {
                    id: "left".into(),
                    model: model.clone(),
                    params: c.left.params.clone(),
                },
                CameraUnit {
                    id: "right".into(),
                    model,
                    params: c.right.params.clone(),
                },
            ],
            right_from_left,
        }
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
