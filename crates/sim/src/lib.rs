//! # pingcal-sim: simulator of the paper's test field and sensors
//!
//! Room corner with targets and ping-pong balls, a stereo camera and a rotating LRF,
//! written as real project files (PNG images, `pingcal-scan` CSV, `project.toml`) with
//! ground truth (`truth.json`), after Manouchehri & Hosseininaveh (ISPRS 2023).
//!
//! | module | what it simulates |
//! |---|---|
//! | [`config`] | every number, from TOML, defaults from the paper, validation |
//! | [`scene`] | the room corner (tilted, bulged planes), targets, balls on stems, caliper distances; ray casting |
//! | [`coded_target`] | where the bits of an AICON ring code go on a printed target (the code tables are `pingcal_targets::aicon`) |
//! | [`stations`] | the MYNT EYE D1000-like stereo head and the camera stations |
//! | [`render`] | images: exact ray casting with supersampling, flash, blur, vignetting, noise |
//! | [`lrf`] | the Hokuyo URG-04LX on a Dynamixel MX-28T: scans through `pingcal_lrf::sensor` (the calibration's own sensor model), with footprint and servo |
//! | [`project_files`] | `project.toml`, PNG images, scan CSV, `truth.json` |
//! | [`sphere_calib`] | a data set for the single-sphere calibration (issue 15): a 16-beam spinning lidar and the camera seeing one large sphere moved to N places, clouds, images, `truth.json` |
//! | [`board_field`] | a board field (issue 51): a chessboard in N placements before the head's left camera and a fixed 2D LRF, images, 2D clouds (PCD), `truth.json` |
//! | [`sphere_clutter`] | its harder scene (issue 36): a shaded sphere with a highlight on a stand, bricks, tiles and bright round plates, frames cut by the border |
//!
//! ## Frames (all lengths in mm)
//! * **World** (test field): origin at the corner's vertex, X along wall 1's floor edge,
//!   Y along wall 2's floor edge, Z up; the room is x, y, z > 0. The planes are tilted by a
//!   few tenths of a degree and bulged by a few mm, so they are not exactly these axes.
//! * **Camera** (docs/formats.md): origin at the projection centre, X image right, Y optical axis,
//!   Z image up. Poses are world → camera, `x_cam = R·X + t`.
//! * **Photogrammetric**: the main station's left camera frame (the paper's origin).
//! * **LRF** (paper eq. 2): origin at the scanner centre, Y along the servo shaft.
//! * **Extrinsic** (truth.json, as results.json): `p_camera = R·p_lrf + t`, camera = the
//!   main station's left camera.
//!
//! ## Entry points
//! ```no_run
//! let cfg = pingcal_sim::SimConfig::default();
//! let sim = pingcal_sim::Simulation::new(&cfg, 1).unwrap();
//! let summary = pingcal_sim::project_files::write_project(&sim, std::path::Path::new("out")).unwrap();
//! let truth = pingcal_sim::project_files::read_truth(&std::path::Path::new("out/truth.json")).unwrap();
//! ```
//! Same configuration and seed ⇒ byte-identical files.

pub mod board_field;
pub mod coded_target;
pub mod config;
pub mod head;
pub mod lrf;
pub mod place;
pub mod project_files;
pub mod render;
pub mod scene;
pub mod sphere_calib;
pub mod sphere_clutter;
pub mod stations;

pub use config::{ConfigError, SimConfig};
pub use project_files::{read_truth, write_project, ProjectSummary, Truth};
pub use scene::TestField;
pub use stations::{Station, StereoRig};

use config::LrfConfig;
use pingcal_geometry::Rigid3;
use pingcal_project::LrfKind;
use rand::{RngCore, SeedableRng};

/// Errors of the simulator, each one line naming what is wrong.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// An impossible configuration value.
    #[error("invalid configuration: {0}")]
    Invalid(#[from] ConfigError),
    /// A configuration file that cannot be read as TOML or holds an impossible value.
    #[error("{file}: {what}")]
    Config {
        /// The file.
        file: String,
        /// What is wrong.
        what: String,
    },
    /// A file that cannot be written or read.
    #[error("{path}: {what}")]
    Io {
        /// The path.
        path: String,
        /// What went wrong.
        what: String,
    },
}

/// An independent random stream for (`seed`, `stream`, `index`): every random choice of
/// the simulator draws from its own stream, so parallel work stays deterministic.
pub fn rng_for(seed: u64, stream: &str, index: u64) -> rand_chacha::ChaCha8Rng {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in stream.bytes() {
        h ^= b as u64;
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    let mut z = seed ^ h.rotate_left(17) ^ index.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    // splitmix64 finaliser.
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^= z >> 31;
    rand_chacha::ChaCha8Rng::seed_from_u64(z)
}

/// Everything simulated except the images (which [`project_files::write_project`]
/// renders while writing).
#[derive(Debug, Clone)]
pub struct Simulation {
    /// The configuration used.
    pub config: SimConfig,
    /// The seed.
    pub seed: u64,
    /// The test field (world frame).
    pub scene: TestField,
    /// The stereo head with its true intrinsics.
    pub rig: StereoRig,
    /// The stations, main first.
    pub stations: Vec<Station>,
    /// World → LRF frame (at the main station).
    pub lrf_from_world: Rigid3,
    /// The servo sweep at the main station (a rotating LRF; empty for a fixed one).
    pub scans: Vec<lrf::Scan>,
    /// A fixed LRF's scans at each of its stations, in the order of `[lrf] scan_stations`
    /// (empty for a rotating LRF).
    pub fixed_scans: Vec<(String, Vec<lrf::Scan>)>,
    /// Each of `[[lrfs]]` with its scans of the same field.
    pub range_sensors: Vec<RangeSensorSim>,
}

/// One of `[[lrfs]]`, simulated: its keys and its scans, as [`Simulation`]'s for `[lrf]`.
#[derive(Debug, Clone)]
pub struct RangeSensorSim {
    /// Its id.
    pub id: String,
    /// Its keys.
    pub config: LrfConfig,
    /// World → its frame (at the main station).
    pub lrf_from_world: Rigid3,
    /// A rotating one's sweep (empty for a fixed one).
    pub scans: Vec<lrf::Scan>,
    /// A fixed one's scans at each of its stations (empty for a rotating one).
    pub fixed_scans: Vec<(String, Vec<lrf::Scan>)>,
}

/// A range sensor of keys `lrf_cfg` on the head: world → its frame at the main station,
/// and its scans of `scene` (a rotating one's sweep, or a fixed one's at its stations),
/// their noise drawn from `seed`.
#[allow(clippy::type_complexity)]
fn range_scans(
    lrf_cfg: &LrfConfig,
    (scene, stations): (&TestField, &[Station]),
    seed: u64,
) -> Result<(Rigid3, Vec<lrf::Scan>, Vec<(String, Vec<lrf::Scan>)>), SimError> {
    let main = stations
        .iter()
        .find(|s| s.main)
        .expect("main station")
        .left_from_world;
    let lrf_from_world = lrf::lrf_from_world(&main, lrf_cfg);
    Ok(match lrf_cfg.kind {
        LrfKind::Rotating => {
            let scene_lrf = scene.transformed(&lrf_from_world);
            (
                lrf_from_world,
                lrf::simulate_scans(&scene_lrf, lrf_cfg, seed),
                Vec::new(),
            )
        }
        LrfKind::Fixed => {
            let at = fixed_stations(lrf_cfg, stations)?;
            let fixed = lrf::simulate_fixed_scans(scene, &at, lrf_cfg, seed);
            (lrf_from_world, Vec::new(), fixed)
        }
    })
}

/// A fixed LRF's stations (id, `left_from_world`): `[lrf] scan_stations` (each one of the
/// field's), else every station of the field, main first.
fn fixed_stations(
    lrf_cfg: &LrfConfig,
    stations: &[Station],
) -> Result<Vec<(String, Rigid3)>, SimError> {
    if lrf_cfg.scan_stations.is_empty() {
        return Ok((stations.iter())
            .map(|s| (s.id.clone(), s.left_from_world))
            .collect());
    }
    (lrf_cfg.scan_stations.iter())
        .map(|id| {
            let st = stations.iter().find(|s| &s.id == id).ok_or_else(|| {
                SimError::Invalid(ConfigError::new(
                    "lrf.scan_stations",
                    id,
                    format!(
                        "not a station of the field (its stations: {})",
                        (stations.iter().map(|s| s.id.as_str()))
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                ))
            })?;
            Ok((st.id.clone(), st.left_from_world))
        })
        .collect()
}

impl Simulation {
    /// Builds the scene, stations and LRF scans for `cfg` and `seed`.
    pub fn new(cfg: &SimConfig, seed: u64) -> Result<Self, SimError> {
        cfg.validate()?;
        if cfg.field.kind == config::FieldKind::Board {
            return Err(SimError::Invalid(ConfigError::new(
                "field.kind",
                "board",
                "this is the room's simulation; a board field is written by `pingcal simulate --config` (board_field)",
            )));
        }
        let scene = TestField::build(cfg, seed)?;
        let stations = stations::build_stations(cfg, &scene, seed)?;
        let rig = StereoRig::from_config(cfg);
        let (lrf_from_world, scans, fixed_scans) =
            range_scans(&cfg.lrf, (&scene, &stations), seed)?;
        let range_sensors = (cfg.lrfs.iter())
            .map(|r| {
                // its own noise: a seed of its own, drawn from the run's and its id
                let own = rng_for(seed, &format!("lrfs.{}", r.id), 0).next_u64();
                let (lrf_from_world, scans, fixed_scans) =
                    range_scans(&r.lrf, (&scene, &stations), own)?;
                Ok(RangeSensorSim {
                    id: r.id.clone(),
                    config: r.lrf.clone(),
                    lrf_from_world,
                    scans,
                    fixed_scans,
                })
            })
            .collect::<Result<Vec<_>, SimError>>()?;
        Ok(Self {
            config: cfg.clone(),
            seed,
            scene,
            rig,
            stations,
            lrf_from_world,
            scans,
            fixed_scans,
            range_sensors,
        })
    }

    /// `photogrammetric_from_world`: world → photogrammetric frame (the main station's left
    /// camera, whose `left_from_world` it is).
    pub fn photogrammetric_from_world(&self) -> Rigid3 {
        self.stations
            .iter()
            .find(|s| s.main)
            .expect("main station")
            .left_from_world
    }
}
