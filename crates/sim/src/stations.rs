//! The stereo head (MYNT EYE D1000-like) and the camera stations: the main station, where
//! the LRF scanned, and a convergent network around the field at several heights, with
//! 90° rolls, as a photogrammetrist would plan it for self-calibration.
//!
//! Poses are world → camera (`x_cam = R·X + t`, [`Pose`]), camera frame X right, Y forward
//! (optical axis), Z up (SPEC.md).

use crate::config::{ConfigError, SimConfig, StationConfig};
use crate::rng_for;
use crate::scene::Scene;
use crate::SimError;
use nalgebra::{Matrix3, Vector3};
use pingcal_ba::camera::PhotogrammetricCamera;
use pingcal_ba::pose::Pose;
use pingcal_ba::rotation::from_opk;
use rand::Rng;

type V3 = Vector3<f64>;

/// One camera of the head: its model and true parameters.
#[derive(Debug, Clone)]
pub struct CameraUnit {
    /// `left` or `right`.
    pub id: String,
    /// Sensor geometry.
    pub model: PhotogrammetricCamera,
    /// True `[c, xp, yp, K1, K2, K3, P1, P2, B1, B2]`.
    pub params: [f64; 10],
}

impl CameraUnit {
    /// Largest ideal (undistorted) image radius, in mm from the principal point, over the
    /// image border. Points whose ideal radius exceeds it are outside the image even when
    /// the distortion polynomial (which folds back far outside the field of view) maps
    /// them inside.
    pub fn max_ideal_radius_mm(&self) -> f64 {
        let (w, h) = (
            self.model.width as f64 - 1.0,
            self.model.height as f64 - 1.0,
        );
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
            let xy = self.model.pixel_to_sensor(&nalgebra::Vector2::new(u, v));
            if let Some(q) = self.model.undistort_sensor(&self.params, &xy) {
                r = r.max(q.norm());
            }
        }
        r
    }

    /// Projects a camera-frame point if it is really in the field of view (in front, and
    /// within the ideal radius of the image border, see [`Self::max_ideal_radius_mm`]).
    pub fn project_in_view(&self, xc: &V3, r_max: f64) -> Option<nalgebra::Vector2<f64>> {
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
        use pingcal_ba::camera::CameraModel;
        self.model.project(&self.params, xc, None, None)
    }
}

/// The stereo head: left and right cameras and the right camera's pose in the left frame.
#[derive(Debug, Clone)]
pub struct StereoRig {
    /// Left camera (index 0) and right camera (index 1).
    pub cameras: [CameraUnit; 2],
    /// Left-camera frame → right-camera frame.
    pub left_to_right: Pose,
}

impl StereoRig {
    /// The head from the configuration.
    pub fn from_config(cfg: &SimConfig) -> Self {
        let c = &cfg.camera;
        let model = PhotogrammetricCamera::new(c.width, c.height, c.pixel_size_mm);
        let o = c.right_opk_deg;
        // Right camera orientation relative to left: x_right = R_rel (x_left − C_right).
        let r_rel = from_opk(o[0].to_radians(), o[1].to_radians(), o[2].to_radians());
        let left_to_right = Pose::from_rotation_and_centre(r_rel, V3::from(c.right_offset_mm));
        Self {
            cameras: [
                CameraUnit {
                    id: "left".into(),
                    model,
                    params: c.left.params,
                },
                CameraUnit {
                    id: "right".into(),
                    model,
                    params: c.right.params,
                },
            ],
            left_to_right,
        }
    }
}

/// A station: the pose of the head's left camera, and whether it is the main station.
#[derive(Debug, Clone)]
pub struct Station {
    /// `S00` (main), `S01`, …
    pub id: String,
    /// World → left camera.
    pub left_pose: Pose,
    /// True for the station where the LRF scanned.
    pub main: bool,
}

impl Station {
    /// World → camera pose of camera `cam` (0 left, 1 right) of `rig` at this station.
    pub fn camera_pose(&self, rig: &StereoRig, cam: usize) -> Pose {
        if cam == 0 {
            self.left_pose
        } else {
            rig.left_to_right.compose(&self.left_pose)
        }
    }
}

/// The rotation world → camera for a camera at `centre` looking at `look_at`, rolled by
/// `roll` (radians) about its optical axis; image up is world up when `roll` = 0.
pub fn look_at_rotation(centre: &V3, look_at: &V3, roll: f64) -> Matrix3<f64> {
    let fwd = (look_at - centre).normalize();
    let up_world = if fwd.cross(&V3::z()).norm() < 1e-6 {
        V3::y()
    } else {
        V3::z()
    };
    let right = fwd.cross(&up_world).normalize();
    let up = right.cross(&fwd);
    let (s, c) = roll.sin_cos();
    let right_r = right * c + up * s;
    let up_r = up * c - right * s;
    Matrix3::from_rows(&[right_r.transpose(), fwd.transpose(), up_r.transpose()])
}

/// The main station's left camera pose (world → camera).
pub fn main_left_pose(sc: &StationConfig) -> Pose {
    let c = V3::from(sc.main_centre_mm);
    Pose::from_rotation_and_centre(look_at_rotation(&c, &V3::from(sc.main_look_at_mm), 0.0), c)
}

/// All stations: the main one (`S00`) first, then the convergent ones, then the extra ones.
/// Refuses a camera behind (or closer than `stations.min_wall_clearance_mm` to) a wall.
pub fn build_stations(cfg: &SimConfig, scene: &Scene, seed: u64) -> Result<Vec<Station>, SimError> {
    let sc = &cfg.stations;
    let mut rng = rng_for(seed, "stations", 0);
    let mut out = vec![Station {
        id: "S00".into(),
        left_pose: main_left_pose(sc),
        main: true,
    }];
    let mut keys = vec!["stations.main_centre_mm".to_string()];
    let look = V3::from(sc.look_at_mm);
    // Convergent ring: azimuths spread symmetrically about the corner's diagonal (45°).
    let n = sc.convergent;
    for k in 0..n {
        let frac = if n > 1 {
            k as f64 / (n - 1) as f64
        } else {
            0.5
        };
        let az = (45.0 - 0.5 * sc.azimuth_span_deg + frac * sc.azimuth_span_deg).to_radians();
        let dist = sc.distance_range_mm[0]
            + (sc.distance_range_mm[1] - sc.distance_range_mm[0]) * ((k * 7 + 3) % n.max(1)) as f64
                / (n.max(2) - 1) as f64;
        let height = sc.heights_mm[k % sc.heights_mm.len()];
        let roll = sc.rolls_deg[k % sc.rolls_deg.len()].to_radians();
        let centre = V3::new(look.x + dist * az.cos(), look.y + dist * az.sin(), height);
        let j = sc.look_jitter_mm;
        let jit = if j > 0.0 {
            V3::new(
                rng.random_range(-j..=j),
                rng.random_range(-j..=j),
                rng.random_range(-j..=j),
            )
        } else {
            V3::zeros()
        };
        let r = look_at_rotation(&centre, &(look + jit), roll);
        out.push(Station {
            id: format!("S{:02}", k + 1),
            left_pose: Pose::from_rotation_and_centre(r, centre),
            main: false,
        });
        keys.push("stations.distance_range_mm / stations.heights_mm".to_string());
    }
    for (i, e) in sc.extra.iter().enumerate() {
        let c = V3::from(e.centre_mm);
        let l = V3::from(e.look_at_mm);
        if !(c.iter().chain(l.iter()).all(|v| v.is_finite())) || (c - l).norm() < 1.0 {
            return Err(ConfigError::new(
                format!("stations.extra[{i}].look_at_mm"),
                format!("{:?}", e.look_at_mm),
                "must be finite and away from the centre",
            )
            .into());
        }
        out.push(Station {
            id: format!("S{:02}", out.len()),
            left_pose: Pose::from_rotation_and_centre(
                look_at_rotation(&c, &l, e.roll_deg.to_radians()),
                c,
            ),
            main: false,
        });
        keys.push(format!("stations.extra[{i}].centre_mm"));
    }
    let rig = StereoRig::from_config(cfg);
    for (st, key) in out.iter().zip(&keys) {
        for cam in 0..2 {
            let c = st.camera_pose(&rig, cam).centre();
            check_inside(
                &scene.surfaces,
                &c,
                key,
                &st.id,
                &rig.cameras[cam].id,
                sc.min_wall_clearance_mm,
            )?;
        }
    }
    Ok(out)
}

/// Refuses a camera centre `c` less than `clearance` inside any of the room's planes.
pub fn check_inside(
    surfaces: &[crate::scene::Surface],
    c: &V3,
    key: &str,
    station: &str,
    camera: &str,
    clearance: f64,
) -> Result<(), ConfigError> {
    for s in surfaces {
        let d = s.plane_distance(c);
        if d < clearance {
            return Err(ConfigError::new(
                key,
                format!("[{:.0}, {:.0}, {:.0}]", c.x, c.y, c.z),
                format!(
                    "station {station} puts the {camera} camera {:.0} mm {} {} (needs {clearance} mm inside the room): a camera behind a wall",
                    d.abs(),
                    if d < 0.0 { "behind" } else { "in front of" },
                    s.name,
                ),
            ));
        }
    }
    Ok(())
}
