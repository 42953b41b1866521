//! The camera stations of the stereo head ([`crate::head`]): the main station, where
//! the LRF scanned, and a convergent network around the field at several heights, with
//! 90° rolls, as a photogrammetrist would plan it for self-calibration.
//!
//! Poses are world → camera (`x_cam = R·X + t`, [`Rigid3`]), camera frame X right, Y forward
//! (optical axis), Z up (docs/formats.md).

use crate::config::{ConfigError, SimConfig};
pub use crate::head::{look_at_rotation, main_left_pose, CameraUnit, StereoRig};
use crate::rng_for;
use crate::scene::{check_inside, TestField};
use crate::SimError;
use nalgebra::Vector3;
use pingcal_geometry::Rigid3;
use rand::Rng;

type V3 = Vector3<f64>;

/// A station: the pose of the head's left camera, and whether it is the main station.
#[derive(Debug, Clone)]
pub struct Station {
    /// `S00` (main), `S01`, …
    pub id: String,
    /// World → left camera.
    pub left_from_world: Rigid3,
    /// True for the station where the LRF scanned.
    pub main: bool,
}

impl Station {
    /// World → camera pose of camera `cam` (0 left, 1 right, then `[[rig.cameras]]`) of
    /// `rig` at this station.
    pub fn camera_pose(&self, rig: &StereoRig, cam: usize) -> Rigid3 {
        if cam == 0 {
            self.left_from_world
        } else {
            rig.camera_from_left[cam].compose(&self.left_from_world)
        }
    }
}

/// All stations: the main one (`S00`) first, then the convergent ones, then the extra ones.
/// Refuses a camera behind (or closer than `stations.min_wall_clearance_mm` to) a wall.
pub fn build_stations(
    cfg: &SimConfig,
    scene: &TestField,
    seed: u64,
) -> Result<Vec<Station>, SimError> {
    let sc = &cfg.stations;
    let mut rng = rng_for(seed, "stations", 0);
    let mut out = vec![Station {
        id: "S00".into(),
        left_from_world: main_left_pose(sc),
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
            left_from_world: Rigid3::from_rotation_and_centre(r, centre),
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
            left_from_world: Rigid3::from_rotation_and_centre(
                look_at_rotation(&c, &l, e.roll_deg.to_radians()),
                c,
            ),
            main: false,
        });
        keys.push(format!("stations.extra[{i}].centre_mm"));
    }
    let rig = StereoRig::from_config(cfg);
    for (st, key) in out.iter().zip(&keys) {
        for cam in 0..rig.cameras.len() {
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
