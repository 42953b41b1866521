//! Writing a simulated project directory:
//!
//! ```text
//! project.toml        what the pipeline needs (cameras, images, targets, balls, distances, LRF)
//! images/S00_left.png one 8-bit PNG per camera per station (S00 is the main station)
//! scans/S00.csv       the servo sweep as `pingcal-scan` v1 CSV (docs/formats.md)
//! truth.json          the ground truth (see [`Truth`])
//! simulation.toml     the full simulator configuration used (re-run with --config)
//! ```
//!
//! `project.toml` (version 1) is described by [`ProjectFile`]; every path in it is relative
//! to the folder holding it.

use crate::render::{render_image, RayTable};
use crate::{SimError, Simulation};
use image::ImageEncoder;
use nalgebra::{Matrix3, Vector3};
use pingcal_geometry::to_opk;
use pingcal_geometry::Rigid3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::Path;

pub use pingcal_project::{
    BallLabel, CameraModel, Intrinsics, KeyedValues, Method, Parameter, ProjectBalls,
    ProjectCamera, ProjectDistance, ProjectFile, ProjectFrames, ProjectImage, ProjectLrf,
    ProjectRig, ProjectRigCamera, ProjectStereo, ProjectTargets, TargetFamily,
};
use pingcal_project::{LrfKind, ScanAtStation, ScanEntry};

/// A rigid transform as written in JSON: `y = rotation · x + translation_mm`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PoseJson {
    /// Row-major 3×3 rotation.
    pub rotation: [[f64; 3]; 3],
    /// Translation (mm).
    pub translation_mm: [f64; 3],
    /// ω, φ, κ of the rotation (degrees, R = R_ω R_φ R_κ).
    pub opk_deg: [f64; 3],
}

impl PoseJson {
    /// From a [`Rigid3`].
    pub fn from_pose(p: &Rigid3) -> Self {
        let r = p.rotation;
        let (o, f, k) = to_opk(&r);
        Self {
            rotation: [
                [r[(0, 0)], r[(0, 1)], r[(0, 2)]],
                [r[(1, 0)], r[(1, 1)], r[(1, 2)]],
                [r[(2, 0)], r[(2, 1)], r[(2, 2)]],
            ],
            translation_mm: [p.translation.x, p.translation.y, p.translation.z],
            opk_deg: [o.to_degrees(), f.to_degrees(), k.to_degrees()],
        }
    }

    /// To a [`Rigid3`].
    pub fn to_pose(&self) -> Rigid3 {
        let r = &self.rotation;
        Rigid3 {
            rotation: Matrix3::new(
                r[0][0], r[0][1], r[0][2], r[1][0], r[1][1], r[1][2], r[2][0], r[2][1], r[2][2],
            ),
            translation: Vector3::from(self.translation_mm),
        }
    }

    /// How far this transform puts `x` from `y` (mm): `|rotation · x + translation − y|`, the
    /// check error it gives on a pair of measured centres.
    pub fn misfit_mm(&self, x: [f64; 3], y: [f64; 3]) -> f64 {
        (self.to_pose().transform(&Vector3::from(x)) - Vector3::from(y)).norm()
    }

    /// The angle of the rotation between this transform's rotation and `rotation` (row-major),
    /// degrees.
    pub fn angle_to_deg(&self, rotation: &[[f64; 3]; 3]) -> f64 {
        let other = Matrix3::from_row_slice(&rotation.concat());
        pingcal_geometry::rotation_angle(&(other * self.to_pose().rotation.transpose()))
            .to_degrees()
    }
}

/// True intrinsics of one camera (names as in results.json).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TruthCamera {
    /// `left` / `right`.
    pub id: String,
    /// The camera model (absent: the default, [`CameraModel::DEFAULT`]).
    #[serde(default = "default_model", skip_serializing_if = "is_default_model")]
    pub model: CameraModel,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Pixel pitch (mm).
    pub pixel_size_mm: f64,
    /// The model's parameters by their keys (as results.json's cameras).
    #[serde(flatten)]
    pub params: KeyedValues,
}

fn default_model() -> CameraModel {
    CameraModel::DEFAULT
}

fn is_default_model(m: &CameraModel) -> bool {
    m.is_default()
}

impl TruthCamera {
    /// The true parameters, in the model's slice order (a key the file lacks is 0).
    pub fn intrinsics(&self) -> Intrinsics {
        let zeros = vec![0.0; self.model.parameter_names().len()];
        Intrinsics::from_table(self.model, &self.params, &zeros)
    }
}

/// True pose of one image.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TruthImage {
    /// File (relative to the project folder).
    pub file: String,
    /// Camera id.
    pub camera: String,
    /// Station id.
    pub station: String,
    /// `camera_from_photogrammetric`: photogrammetric frame → this camera (read also as
    /// `photogrammetric_to_camera`, its name before).
    #[serde(alias = "photogrammetric_to_camera")]
    pub camera_from_photogrammetric: PoseJson,
    /// `camera_from_world`: world → this camera (read also as `world_to_camera`).
    #[serde(alias = "world_to_camera")]
    pub camera_from_world: PoseJson,
    /// Projection centre in the photogrammetric frame (mm).
    pub centre_photogrammetric_mm: [f64; 3],
}

/// A true target centre.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TruthTarget {
    /// Target number (AICON number, or 1001… for plain targets).
    pub id: u32,
    /// `coded` or `plain`.
    pub kind: String,
    /// Ring code value (smallest rotation) for coded targets.
    pub code: Option<u32>,
    /// Surface it is on.
    pub surface: String,
    /// Centre in the photogrammetric frame.
    pub photogrammetric_mm: [f64; 3],
    /// Centre in the LRF frame.
    pub lrf_mm: [f64; 3],
    /// Centre in the world (room corner) frame.
    pub world_mm: [f64; 3],
    /// Unit normal in the photogrammetric frame.
    pub normal_photogrammetric: [f64; 3],
}

/// A true ball centre.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TruthBall {
    /// `B1` … `B16`.
    pub id: String,
    /// Diameter (mm).
    pub diameter_mm: f64,
    /// Check ball (true) or control ball.
    pub check: bool,
    /// Centre in the photogrammetric frame.
    pub photogrammetric_mm: [f64; 3],
    /// Centre in the LRF frame.
    pub lrf_mm: [f64; 3],
    /// Centre in the world frame.
    pub world_mm: [f64; 3],
}

/// A true plane of the corner.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TruthSurface {
    /// `wall1`, `wall2`, `floor`.
    pub name: String,
    /// Unit normal of the base plane (world, into the room).
    pub normal_world: [f64; 3],
    /// Bulge at the centre (mm, along the normal).
    pub bulge_mm: f64,
    /// Extents (mm).
    pub size_mm: [f64; 2],
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

/// `truth.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Truth {
    /// The seed.
    pub seed: u64,
    /// What wrote it.
    pub generator: String,
    /// Conventions, in words.
    pub conventions: Vec<String>,
    /// The extrinsic, `p_camera = R·p_lrf + t` (results.json convention).
    pub extrinsic: PoseJson,
    /// `photogrammetric_from_world`: world → photogrammetric frame (read also as
    /// `world_to_photogrammetric`, its name before).
    #[serde(alias = "world_to_photogrammetric")]
    pub photogrammetric_from_world: PoseJson,
    /// `lrf_from_world`: world → LRF frame (read also as `world_to_lrf`).
    #[serde(alias = "world_to_lrf")]
    pub lrf_from_world: PoseJson,
    /// LRF mount offset (rotating frame), mm.
    pub lrf_mount_offset_mm: [f64; 3],
    /// The LRF's true mount and range model (offset, tilts, servo scale, range offset and
    /// scale); the project file leaves it at zero.
    #[serde(default)]
    pub lrf_mount: pingcal_lrf::MountModel,
    /// The servo's time offset against the scanner (`[lrf] servo_time_offset_s`), seconds;
    /// written only when not 0.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub lrf_servo_time_offset_s: f64,
    /// True intrinsics.
    pub cameras: Vec<TruthCamera>,
    /// `right_from_left`: left camera frame → right camera frame (read also as
    /// `left_to_right`).
    #[serde(alias = "left_to_right")]
    pub right_from_left: PoseJson,
    /// Every sensor of the head but the reference (the main, left camera): the right camera,
    /// the `[[rig.cameras]]` and the LRF, each with `camera_from_sensor` in the reference
    /// camera's photogrammetric frame as `extrinsic` (the LRF's in the frame a calibration
    /// defines, [`Truth::extrinsic_as_calibrated`]); results.json's `sensors` are these.
    #[serde(default)]
    pub sensors: Vec<TruthSensor>,
    /// Image poses.
    pub images: Vec<TruthImage>,
    /// Targets.
    pub targets: Vec<TruthTarget>,
    /// Balls.
    pub balls: Vec<TruthBall>,
    /// Caliper distances with their true values.
    pub distances: Vec<crate::scene::Distance>,
    /// The corner's planes.
    pub surfaces: Vec<TruthSurface>,
}

/// A sensor of the head in truth.json's `sensors`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TruthSensor {
    /// Its id: a camera's, or `lrf`.
    pub id: String,
    /// `camera`, or the LRF's kind (`rotating`, `fixed`).
    pub kind: String,
    /// `p_reference = rotation · p_sensor + translation_mm`.
    pub camera_from_sensor: PoseJson,
}

impl Truth {
    /// The true extrinsic in the LRF frame a calibration defines: origin on the servo axis
    /// at the scan plane (`pingcal_pipeline::joint`), i.e. the truth's frame moved along the
    /// servo axis (Y) by the mount's `offset_y`, which no calibration can tell from the
    /// extrinsic's ty: `t' = t + R·(0, offset_y, 0)`. Compare estimates with this one.
    pub fn extrinsic_as_calibrated(&self) -> PoseJson {
        as_calibrated(self.extrinsic, self.lrf_mount.offset_mm[1])
    }
}

/// `extrinsic` moved along its servo axis (Y) by the mount's `offset_y` (see
/// [`Truth::extrinsic_as_calibrated`]).
fn as_calibrated(mut e: PoseJson, offset_y: f64) -> PoseJson {
    for k in 0..3 {
        e.translation_mm[k] += e.rotation[k][1] * offset_y;
    }
    e
}

/// What was written.
#[derive(Debug, Clone)]
pub struct ProjectSummary {
    /// Number of images.
    pub images: usize,
    /// Number of scans.
    pub scans: usize,
    /// Number of targets (coded).
    pub targets: usize,
    /// Coded targets.
    pub coded: usize,
    /// Balls.
    pub balls: usize,
}

fn arr(v: &Vector3<f64>) -> [f64; 3] {
    [v.x, v.y, v.z]
}

pub(crate) fn io(path: &Path, e: impl std::fmt::Display) -> SimError {
    SimError::Io {
        path: path.display().to_string(),
        what: e.to_string(),
    }
}

/// Writes an 8-bit grey image as PNG (fast compression: the simulator's images are many).
pub(crate) fn write_png(path: &Path, img: &image::GrayImage) -> Result<(), SimError> {
    let mut bytes = Vec::new();
    image::codecs::png::PngEncoder::new_with_quality(
        &mut bytes,
        image::codecs::png::CompressionType::Fast,
        image::codecs::png::FilterType::Sub,
    )
    .write_image(
        img.as_raw(),
        img.width(),
        img.height(),
        image::ExtendedColorType::L8,
    )
    .map_err(|e| io(path, e))?;
    std::fs::write(path, bytes).map_err(|e| io(path, e))
}

/// Image file name of camera `cam` at station `st`.
fn image_file(st: &str, cam: &str) -> String {
    format!("images/{st}_{cam}.png")
}

/// The ground truth of a simulation.
pub fn truth_of(sim: &Simulation) -> Truth {
    let photogrammetric_from_world = sim.photogrammetric_from_world();
    let lrf_from_world = sim.lrf_from_world;
    let ext = crate::lrf::extrinsic(&sim.config.lrf);
    let mut images = Vec::new();
    for st in &sim.stations {
        for (ci, cam) in sim.rig.cameras.iter().enumerate() {
            let camera_from_world = st.camera_pose(&sim.rig, ci);
            let camera_from_photogrammetric =
                camera_from_world.compose(&photogrammetric_from_world.inverse());
            images.push(TruthImage {
                file: image_file(&st.id, &cam.id),
                camera: cam.id.clone(),
                station: st.id.clone(),
                camera_from_photogrammetric: PoseJson::from_pose(&camera_from_photogrammetric),
                camera_from_world: PoseJson::from_pose(&camera_from_world),
                centre_photogrammetric_mm: arr(&camera_from_photogrammetric.centre()),
            });
        }
    }
    let checks = &sim.config.balls.check_balls;
    let mut truth = Truth {
        seed: sim.seed,
        generator: format!("pingcal-sim {}", env!("CARGO_PKG_VERSION")),
        conventions: vec![
            "lengths in mm; angles in degrees; opk_deg = (omega, phi, kappa) with R = R_omega R_phi R_kappa".into(),
            "camera frame: X image right, Y optical axis, Z image up; photogrammetric frame = the main station's left camera".into(),
            "LRF frame: paper eq. 2, x = r cos(a) cos(b), y = r sin(a), z = r cos(a) sin(b), Y = servo shaft".into(),
            "extrinsic: p_camera = rotation * p_lrf + translation_mm (as results.json)".into(),
            "poses: y = rotation * x + translation_mm from the named frame to the camera".into(),
            "intrinsics: the photogrammetric model of docs/formats.md, distortion applied forward; pixels from the centre of the top-left pixel, v down".into(),
            "world: origin at the room corner, X along wall1, Y along wall2, Z up".into(),
        ],
        extrinsic: PoseJson::from_pose(&ext),
        photogrammetric_from_world: PoseJson::from_pose(&photogrammetric_from_world),
        lrf_from_world: PoseJson::from_pose(&lrf_from_world),
        lrf_mount_offset_mm: sim.config.lrf.mount().offset_mm,
        lrf_mount: sim.config.lrf.mount(),
        lrf_servo_time_offset_s: sim.config.lrf.servo_time_offset_s,
        cameras: sim
            .rig
            .cameras
            .iter()
            .map(|c| TruthCamera {
                id: c.id.clone(),
                model: sim.config.camera.model,
                width: c.model.width,
                height: c.model.height,
                pixel_size_mm: c.model.pixel_size_mm,
                params: Intrinsics::new(sim.config.camera.model, c.params.clone())
                    .expect("validated parameter count")
                    .to_table(),
            })
            .collect(),
        right_from_left: PoseJson::from_pose(&sim.rig.right_from_left()),
        sensors: Vec::new(),
        images,
        targets: sim
            .scene
            .targets
            .iter()
            .map(|t| TruthTarget {
                id: t.id,
                kind: if t.code.is_some() { "coded" } else { "plain" }.into(),
                code: t.code,
                surface: sim.scene.surfaces[t.surface].name.clone(),
                photogrammetric_mm: arr(&photogrammetric_from_world.transform(&t.centre)),
                lrf_mm: arr(&lrf_from_world.transform(&t.centre)),
                world_mm: arr(&t.centre),
                normal_photogrammetric: arr(&(photogrammetric_from_world.rotation * t.normal)),
            })
            .collect(),
        balls: sim
            .scene
            .balls
            .iter()
            .map(|b| TruthBall {
                id: format!("B{}", b.id),
                diameter_mm: 2.0 * b.radius,
                check: checks.contains(&b.id),
                photogrammetric_mm: arr(&photogrammetric_from_world.transform(&b.centre)),
                lrf_mm: arr(&lrf_from_world.transform(&b.centre)),
                world_mm: arr(&b.centre),
            })
            .collect(),
        distances: sim.scene.distances.clone(),
        surfaces: sim
            .scene
            .surfaces
            .iter()
            .map(|s| TruthSurface {
                name: s.name.clone(),
                normal_world: arr(&s.n),
                bulge_mm: s.bulge_mm,
                size_mm: [s.u_max, s.v_max],
            })
            .collect(),
    };
    truth.sensors = truth_sensors(sim, &truth);
    truth
}

/// truth.json's `sensors`: every camera of the head after the left one, then the LRF.
fn truth_sensors(sim: &Simulation, truth: &Truth) -> Vec<TruthSensor> {
    let cameras = (sim.rig.cameras.iter().zip(&sim.rig.camera_from_left)).skip(1);
    let mut out: Vec<TruthSensor> = cameras
        .map(|(c, from_left)| TruthSensor {
            id: c.id.clone(),
            kind: "camera".into(),
            camera_from_sensor: PoseJson::from_pose(&from_left.inverse()),
        })
        .collect();
    out.push(TruthSensor {
        id: "lrf".into(),
        kind: kind_name(sim.config.lrf.kind).into(),
        camera_from_sensor: truth.extrinsic_as_calibrated(),
    });
    for r in &sim.range_sensors {
        let mount = r.config.mount();
        out.push(TruthSensor {
            id: r.id.clone(),
            kind: kind_name(r.config.kind).into(),
            camera_from_sensor: as_calibrated(
                PoseJson::from_pose(&crate::lrf::extrinsic(&r.config)),
                mount.offset_mm[1],
            ),
        });
    }
    out
}

/// `rotating` or `fixed`.
fn kind_name(k: LrfKind) -> &'static str {
    match k {
        LrfKind::Rotating => "rotating",
        LrfKind::Fixed => "fixed",
    }
}

/// Where each ball is in the main image, to the nearest pixel, as a user would note it on
/// the photograph (balls outside the image are left out).
fn ball_labels(sim: &Simulation) -> Vec<BallLabel> {
    use pingcal_ba::camera::CameraModel;
    let main = sim.stations.iter().find(|s| s.main).expect("main station");
    let cam = &sim.rig.cameras[0];
    let pose = main.camera_pose(&sim.rig, 0);
    sim.scene
        .balls
        .iter()
        .filter_map(|b| {
            let uv = cam
                .model
                .project(&cam.params, &pose.transform(&b.centre), None, None)?;
            let inside = uv.x >= 0.0
                && uv.y >= 0.0
                && uv.x <= cam.model.width as f64 - 1.0
                && uv.y <= cam.model.height as f64 - 1.0;
            inside.then(|| BallLabel {
                id: format!("B{}", b.id),
                x: uv.x.round(),
                y: uv.y.round(),
            })
        })
        .collect()
}

/// The start a user of the simulated head would write into the project file: the nominal
/// focal length (`[camera] nominal_c_mm`), the principal point at the image centre, no
/// distortion (the model's nominal start, [`pingcal_ba::camera::ModelKind::nominal`]); and
/// the parameters to self-calibrate: all but those the model's sample lens does not have
/// ([`pingcal_ba::camera::SampleLens::held`]: held at 0 as a user holds the terms a lens
/// does not need).
pub(crate) fn initial_and_free(cfg: &crate::config::CameraConfig) -> (Intrinsics, Vec<Parameter>) {
    let model = cfg.model;
    let values = if model.in_mm() {
        let mut v = vec![0.0; model.parameter_names().len()];
        v[0] = cfg.nominal_c_mm;
        v
    } else {
        model.nominal(
            cfg.nominal_c_mm / cfg.pixel_size_mm,
            cfg.width,
            cfg.height,
            cfg.pixel_size_mm,
        )
    };
    let held = model.sample().held;
    let free = Parameter::of(model)
        .into_iter()
        .filter(|p| !held.contains(&p.as_str()))
        .collect();
    (
        Intrinsics::new(model, values).expect("the model's count"),
        free,
    )
}

/// The project file of a simulation.
pub fn project_of(sim: &Simulation) -> ProjectFile {
    let cfg = &sim.config;
    let main = sim.stations.iter().find(|s| s.main).expect("main station");
    let (initial, free) = initial_and_free(&cfg.camera);
    ProjectFile {
        version: 1,
        name: format!("simulated test field (seed {})", sim.seed),
        method: Method::All,
        main_station: main.id.clone(),
        main_camera: "left".into(),
        board: None,
        targets: ProjectTargets {
            family: TargetFamily::from_code_bits(cfg.targets.code_bits)
                .expect("validated: targets.code_bits is 12 or 14"),
            dot_radius_mm: cfg.targets.dot_radius_mm,
            ring_inner: cfg.targets.ring_inner,
            ring_outer: cfg.targets.ring_outer,
            layout: None,
            layout_sigma_mm: 20.0,
            measure_saturated: false,
        },
        balls: ProjectBalls {
            diameter_mm: cfg.balls.diameter_mm,
            check: cfg
                .balls
                .check_balls
                .iter()
                .map(|b| format!("B{b}"))
                .collect(),
            labels: ball_labels(sim),
        },
        cameras: sim
            .rig
            .cameras
            .iter()
            .map(|c| ProjectCamera {
                id: c.id.clone(),
                model: cfg.camera.model,
                width: c.model.width,
                height: c.model.height,
                pixel_size_mm: c.model.pixel_size_mm,
                initial: initial.to_table(),
                free: free.clone(),
            })
            .collect(),
        stereo: Some(ProjectStereo {
            left: "left".into(),
            right: "right".into(),
            baseline_mm: 120.0,
        }),
        rig: (!cfg.rig.is_empty()).then(|| ProjectRig {
            cameras: (cfg.rig.cameras.iter())
                .map(|c| ProjectRigCamera {
                    id: c.id.clone(),
                    opk_deg: c.opk_deg.map(|v| v.round()),
                    t_mm: c.t_mm.map(|v| v.round()),
                    hold: false,
                })
                .collect(),
        }),
        images: sim
            .stations
            .iter()
            .flat_map(|st| {
                sim.rig.cameras.iter().map(move |c| ProjectImage {
                    file: image_file(&st.id, &c.id),
                    camera: c.id.clone(),
                    station: st.id.clone(),
                })
            })
            .collect(),
        distances: sim
            .scene
            .distances
            .iter()
            .map(|d| ProjectDistance {
                from: d.from,
                to: d.to,
                distance_mm: (d.measured_mm * 1e4).round() / 1e4,
                sigma_mm: d.sigma_mm,
            })
            .collect(),
        lrf: project_lrf(None, &cfg.lrf, &main.id, &scan_files(sim)),
        lrfs: (sim.range_sensors.iter())
            .map(|r| {
                project_lrf(
                    Some(&r.id),
                    &r.config,
                    &main.id,
                    &range_scan_files(r, &main.id),
                )
            })
            .collect(),
        frames: ProjectFrames::default(),
        network: Default::default(),
    }
}

/// A range sensor's table of the project (`[lrf]`, or one of `[[lrfs]]` with its `id`, its
/// scan files then under `scans/<id>/`): its keys `c` as a user of the simulated head would
/// write them (no mount values: the calibration estimates them), its scan files `files`.
fn project_lrf(
    id: Option<&str>,
    c: &crate::config::LrfConfig,
    main_station: &str,
    files: &[(&str, &[crate::lrf::Scan])],
) -> ProjectLrf {
    ProjectLrf {
        id: id.map(String::from),
        model: "Hokuyo URG-04LX on Dynamixel MX-28T".into(),
        kind: (c.kind == LrfKind::Fixed).then_some(LrfKind::Fixed),
        station: main_station.to_string(),
        scans: (files.iter())
            .map(|(station, _)| {
                let file = scan_path(id, station);
                match c.kind {
                    LrfKind::Rotating => ScanEntry::File(file),
                    LrfKind::Fixed => ScanEntry::AtStation(ScanAtStation {
                        file,
                        station: station.to_string(),
                    }),
                }
            })
            .collect(),
        bag: None,
        cloud_unit: None,
        noise: None,
        noise_sigma_mm: None,
        max_range_mm: c.max_range_mm,
        accuracy_near_mm: c.accuracy_near_mm,
        accuracy_far_fraction: c.accuracy_far_fraction,
        mount_offset_mm: [0.0; 3],
        mount_tilt_x_deg: 0.0,
        mount_tilt_z_deg: 0.0,
        servo_zero_deg: 0.0,
        servo_resolution_deg: c.servo_resolution_deg,
        self_calibrate: None,
        lrf_model: None,
        room_planes: None,
    }
}

/// The scan file of station `station` of `[lrf]` (`id` None) or of one of `[[lrfs]]`.
fn scan_path(id: Option<&str>, station: &str) -> String {
    match id {
        None => format!("scans/{station}.csv"),
        Some(id) => format!("scans/{id}/{station}.csv"),
    }
}

/// [`scan_files`] of one of `[[lrfs]]` (`main`: the main station's id).
fn range_scan_files<'a>(
    r: &'a crate::RangeSensorSim,
    main: &'a str,
) -> Vec<(&'a str, &'a [crate::lrf::Scan])> {
    if r.fixed_scans.is_empty() {
        vec![(main, &r.scans[..])]
    } else {
        (r.fixed_scans.iter())
            .map(|(id, scans)| (id.as_str(), &scans[..]))
            .collect()
    }
}

/// The scan files of the simulation: (station, its scans): the main station's sweep of a
/// rotating LRF, or a fixed LRF's scans at each of its stations.
fn scan_files(sim: &Simulation) -> Vec<(&str, &[crate::lrf::Scan])> {
    if sim.fixed_scans.is_empty() {
        let main = sim.stations.iter().find(|s| s.main).expect("main station");
        vec![(main.id.as_str(), &sim.scans[..])]
    } else {
        (sim.fixed_scans.iter())
            .map(|(id, scans)| (id.as_str(), &scans[..]))
            .collect()
    }
}

/// Renders every image and writes the whole project into `dir` (created if needed).
/// Callers that must not leave a partial project looking complete write into a temporary
/// folder and rename it (as `pingcal simulate` does).
pub fn write_project(sim: &Simulation, dir: &Path) -> Result<ProjectSummary, SimError> {
    std::fs::create_dir_all(dir.join("images")).map_err(|e| io(&dir.join("images"), e))?;
    std::fs::create_dir_all(dir.join("scans")).map_err(|e| io(&dir.join("scans"), e))?;
    let tables: Vec<RayTable> = sim.rig.cameras.iter().map(RayTable::new).collect();
    let jobs: Vec<(usize, usize, usize)> = sim
        .stations
        .iter()
        .enumerate()
        .flat_map(|(si, _)| (0..sim.rig.cameras.len()).map(move |ci| (si, ci)))
        .enumerate()
        .map(|(k, (si, ci))| (k, si, ci))
        .collect();
    jobs.par_iter().try_for_each(|&(k, si, ci)| {
        let st = &sim.stations[si];
        let cam = &sim.rig.cameras[ci];
        let img = render_image(
            &sim.scene,
            cam,
            &st.camera_pose(&sim.rig, ci),
            &sim.config.render,
            Some(&tables[ci]),
            sim.seed,
            k as u64,
        );
        write_png(&dir.join(image_file(&st.id, &cam.id)), &img)
    })?;
    for (station, scans) in scan_files(sim) {
        let scan_path = dir.join(scan_path(None, station));
        let csv = crate::lrf::write_scans_csv(Vec::new(), scans, &sim.config.lrf)
            .map_err(|e| io(&scan_path, e))?;
        std::fs::write(&scan_path, csv).map_err(|e| io(&scan_path, e))?;
    }
    let main = sim.stations.iter().find(|s| s.main).expect("main station");
    for r in &sim.range_sensors {
        let folder = dir.join("scans").join(&r.id);
        std::fs::create_dir_all(&folder).map_err(|e| io(&folder, e))?;
        for (station, scans) in range_scan_files(r, &main.id) {
            let path = dir.join(scan_path(Some(&r.id), station));
            let csv = crate::lrf::write_scans_csv(Vec::new(), scans, &r.config)
                .map_err(|e| io(&path, e))?;
            std::fs::write(&path, csv).map_err(|e| io(&path, e))?;
        }
    }
    let project = project_of(sim);
    let text = format!(
        "# pingcal project file, version 1, written by `pingcal simulate --seed {}`.\n# Paths are relative to this file; lengths in mm.\n\n{}",
        sim.seed,
        project.to_toml_string()
    );
    std::fs::write(dir.join("project.toml"), text).map_err(|e| io(&dir.join("project.toml"), e))?;
    let truth = truth_of(sim);
    let json = serde_json::to_string_pretty(&truth).map_err(|e| io(&dir.join("truth.json"), e))?;
    std::fs::write(dir.join("truth.json"), json + "\n")
        .map_err(|e| io(&dir.join("truth.json"), e))?;
    let cfg_text = format!(
        "# The simulator configuration that produced this project (seed {}).\n{}",
        sim.seed,
        sim.config.to_toml_string()
    );
    std::fs::write(dir.join("simulation.toml"), cfg_text)
        .map_err(|e| io(&dir.join("simulation.toml"), e))?;
    Ok(ProjectSummary {
        images: jobs.len(),
        scans: scan_files(sim).iter().map(|(_, s)| s.len()).sum(),
        targets: sim.scene.targets.len(),
        coded: sim
            .scene
            .targets
            .iter()
            .filter(|t| t.code.is_some())
            .count(),
        balls: sim.scene.balls.len(),
    })
}

/// Reads a `truth.json`.
pub fn read_truth(path: &Path) -> Result<Truth, SimError> {
    let text = std::fs::read_to_string(path).map_err(|e| io(path, e))?;
    serde_json::from_str(&text).map_err(|e| io(path, e))
}

/// Reads a `project.toml`.
pub fn read_project(path: &Path) -> Result<ProjectFile, SimError> {
    let text = std::fs::read_to_string(path).map_err(|e| io(path, e))?;
    ProjectFile::parse(&text, &path.display().to_string()).map_err(|e| SimError::Io {
        path: path.display().to_string(),
        what: e.to_string(),
    })
}

#[cfg(test)]
mod tests {
    /// A simulated project frees every parameter, and the pipeline fixes a camera's
    /// parameters by `Parameter::index_in`: the project's order is the bundle adjuster's.
    #[test]
    fn the_free_parameters_are_in_the_bundle_adjusters_order() {
        let names: Vec<&str> = super::Parameter::of(super::CameraModel::Photogrammetric)
            .iter()
            .map(|p| p.as_str())
            .collect();
        assert_eq!(names, pingcal_ba::camera::PHOTOGRAMMETRIC_PARAMS);
    }

    /// truth.json's poses are written frame-named (`lrf_from_world`, …), and a file written
    /// before (`world_to_lrf`, …) still reads, to the same values.
    #[test]
    fn truth_keys_are_frame_named_and_the_old_ones_still_read() {
        let pose = |t: f64| {
            format!(
                r#"{{"rotation": [[1,0,0],[0,1,0],[0,0,1]], "translation_mm": [{t},2,3], "opk_deg": [0,0,0]}}"#
            )
        };
        let old = format!(
            r#"{{"seed": 1, "generator": "g", "conventions": [], "extrinsic": {},
            "world_to_photogrammetric": {}, "world_to_lrf": {}, "lrf_mount_offset_mm": [0,0,0],
            "cameras": [], "left_to_right": {},
            "images": [{{"file": "f", "camera": "c", "station": "s",
                "photogrammetric_to_camera": {}, "world_to_camera": {},
                "centre_photogrammetric_mm": [0,0,0]}}],
            "targets": [], "balls": [], "distances": [], "surfaces": []}}"#,
            pose(1.0),
            pose(2.0),
            pose(3.0),
            pose(4.0),
            pose(5.0),
            pose(6.0)
        );
        let t: super::Truth = serde_json::from_str(&old).unwrap();
        assert_eq!(t.photogrammetric_from_world.translation_mm[0], 2.0);
        assert_eq!(t.lrf_from_world.translation_mm[0], 3.0);
        assert_eq!(t.right_from_left.translation_mm[0], 4.0);
        assert_eq!(
            t.images[0].camera_from_photogrammetric.translation_mm[0],
            5.0
        );
        assert_eq!(t.images[0].camera_from_world.translation_mm[0], 6.0);
        let written = serde_json::to_string(&t).unwrap();
        for key in [
            "photogrammetric_from_world",
            "lrf_from_world",
            "right_from_left",
            "camera_from_photogrammetric",
            "camera_from_world",
        ] {
            assert!(written.contains(&format!("\"{key}\"")), "{key} not written");
        }
        for key in [
            "world_to_photogrammetric",
            "world_to_lrf",
            "left_to_right",
            "photogrammetric_to_camera",
            "world_to_camera",
        ] {
            assert!(!written.contains(key), "{key} still written");
        }
        assert_eq!(serde_json::from_str::<super::Truth>(&written).unwrap(), t);
    }
}
