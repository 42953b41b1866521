//! # The schema of `project.toml`
//!
//! One struct per table of the file, named `Project…` after it, with serde's
//! `deny_unknown_fields` so a misspelt key is refused. The closed sets (`method`, `family`,
//! `model`, `free`, `self_calibrate`) are the enums of [`crate::closed_sets`], those of the
//! LRF (`[lrf] noise`, `cloud_unit`, `[lrf.bag] servo_motion`) the LRF crate's; the rest is plain numbers and
//! strings, checked after reading by [`ProjectFile::validate`]. Defaults are serde's
//! `default` attributes below and nothing else.

use crate::closed_sets::{CameraModel, LrfKind, Method, MountParameter, Parameter, TargetFamily};
use crate::intrinsics::{Intrinsics, KeyedValues};
use pingcal_lrf::cloud_file::CloudUnit;
use pingcal_lrf::sensor::NoiseProfile;
use pingcal_lrf::settings::{ServoMotion, Stamps};
use serde::{Deserialize, Serialize};

/// Names of the ten photogrammetric parameters, in the order of [`CameraParams::to_slice`].
pub const PARAMETER_NAMES: [&str; 10] = pingcal_camera::PHOTOGRAMMETRIC_PARAMS;

/// `project.toml`, version 1.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProjectFile {
    /// Format version (1).
    pub version: u32,
    /// A name for reports.
    pub name: String,
    /// `joint` (the default), `spheres`, `corner`, `both` (spheres and corner) or `all`.
    #[serde(default)]
    pub method: Method,
    /// The station where the LRF scanned; its `main_camera` image defines the
    /// photogrammetric frame.
    pub main_station: String,
    /// The camera whose frame is the photogrammetric frame (`left`).
    pub main_camera: String,
    /// Coded targets; a project with `[board]` may leave the table out
    /// ([`ProjectTargets::absent`]).
    #[serde(
        default = "ProjectTargets::absent",
        skip_serializing_if = "ProjectTargets::is_absent"
    )]
    pub targets: ProjectTargets,
    /// A calibration board (`[board]`, [`crate::board`]); optional.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub board: Option<crate::board::ProjectBoard>,
    /// Balls; a project with `[board]` may leave the table out ([`ProjectBalls::absent`]).
    #[serde(
        default = "ProjectBalls::absent",
        skip_serializing_if = "ProjectBalls::is_absent"
    )]
    pub balls: ProjectBalls,
    /// Cameras with initial intrinsics.
    pub cameras: Vec<ProjectCamera>,
    /// The stereo head (optional for a mono camera).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stereo: Option<ProjectStereo>,
    /// More cameras on the head (`[rig]`, issue 52): each one's pose relative to the main
    /// camera, estimated (started at the given pose) or held at it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rig: Option<ProjectRig>,
    /// Images.
    pub images: Vec<ProjectImage>,
    /// Caliper distances between coded targets.
    #[serde(default)]
    pub distances: Vec<ProjectDistance>,
    /// The LRF.
    pub lrf: ProjectLrf,
    /// More range sensors on the head (`[[lrfs]]`, issue 52): each a table of `[lrf]`'s keys
    /// with its `id`, calibrated against the same camera side as `[lrf]`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub lrfs: Vec<ProjectLrf>,
    /// Names of the frames in the ROS outputs (optional).
    #[serde(default, skip_serializing_if = "ProjectFrames::is_default")]
    pub frames: ProjectFrames,
    /// How the photogrammetric network is started (optional).
    #[serde(default, skip_serializing_if = "ProjectNetwork::is_default")]
    pub network: ProjectNetwork,
}

/// `[network]`: the start of the photogrammetric network.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProjectNetwork {
    /// The smallest largest angle between a coded target's rays (degrees) for the initial
    /// intersection to take it; the targets below are left out and listed in the log.
    /// Default 2: a target seen from almost one direction has a depth σ of about
    /// σ_ray / sin(angle), 30 times its lateral σ at 2°.
    #[serde(default = "default_min_intersection_angle")]
    pub min_intersection_angle_deg: f64,
}

impl Default for ProjectNetwork {
    fn default() -> Self {
        ProjectNetwork {
            min_intersection_angle_deg: default_min_intersection_angle(),
        }
    }
}

impl ProjectNetwork {
    /// Whether every key has its default (the table is then not written).
    pub fn is_default(&self) -> bool {
        *self == ProjectNetwork::default()
    }
}

fn default_min_intersection_angle() -> f64 {
    2.0
}

/// `[frames]`: the tf frame ids (and URDF link names) that `calibrate` writes into `ros/`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProjectFrames {
    /// The main camera's optical frame (x right, y down, z forward), the tf parent
    /// (`camera_optical`).
    #[serde(default = "default_camera_frame")]
    pub camera: String,
    /// The LRF frame of `cloud.ply`, the tf child (`laser`).
    #[serde(default = "default_lrf_frame")]
    pub lrf: String,
}

impl Default for ProjectFrames {
    fn default() -> Self {
        ProjectFrames {
            camera: default_camera_frame(),
            lrf: default_lrf_frame(),
        }
    }
}

impl ProjectFrames {
    /// Whether both names are the defaults (the table is then not written).
    pub fn is_default(&self) -> bool {
        *self == ProjectFrames::default()
    }
}

fn default_camera_frame() -> String {
    "camera_optical".into()
}

fn default_lrf_frame() -> String {
    "laser".into()
}

/// `[targets]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProjectTargets {
    /// `aicon14` or `aicon12`.
    pub family: TargetFamily,
    /// Radius of the central dot (mm), printed size.
    pub dot_radius_mm: f64,
    /// Inner radius of the printed code ring, in dot radii (AICON: 2); the detector samples
    /// the ring between this and `ring_outer`.
    #[serde(default = "default_ring_inner")]
    pub ring_inner: f64,
    /// Outer radius of the printed code ring, in dot radii (AICON: 3).
    #[serde(default = "default_ring_outer")]
    pub ring_outer: f64,
    /// A file of the coded targets' approximate coordinates (`id,x_mm,y_mm,z_mm`, relative to
    /// project.toml; see [`crate::Layout`]): the network then starts by resecting every image
    /// from them. Optional.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub layout: Option<String>,
    /// σ of each layout coordinate (mm): how far the targets may be from the layout. Only
    /// the start uses the layout, the adjustment does not.
    #[serde(default = "default_layout_sigma")]
    pub layout_sigma_mm: f64,
    /// Measure the targets with more than a fifth of their samples saturated instead of
    /// refusing them: flagged, with three times their σ, so they weigh a ninth in the
    /// adjustment (a flat scan or render of a target sheet, whose white is at full scale by
    /// nature). `pingcal calibrate --saturated` does the same for one run.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub measure_saturated: bool,
}

impl ProjectTargets {
    /// No `[targets]` table (a board's project): no dot, so nothing to detect;
    /// [`ProjectFile::validate`] accepts it beside `[board]` only.
    pub fn absent() -> Self {
        ProjectTargets {
            family: TargetFamily::Aicon14,
            dot_radius_mm: 0.0,
            ring_inner: default_ring_inner(),
            ring_outer: default_ring_outer(),
            layout: None,
            layout_sigma_mm: default_layout_sigma(),
            measure_saturated: false,
        }
    }

    /// Whether this is [`ProjectTargets::absent`] (not written).
    pub fn is_absent(&self) -> bool {
        *self == Self::absent()
    }
}

fn default_layout_sigma() -> f64 {
    20.0
}

fn default_ring_inner() -> f64 {
    2.0
}

fn default_ring_outer() -> f64 {
    3.0
}

/// `[balls]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProjectBalls {
    /// Ball diameter (mm).
    pub diameter_mm: f64,
    /// Balls used as check points (ids `B4`, …); optional.
    #[serde(default)]
    pub check: Vec<String>,
    /// Where numbered balls are in the main image (optional).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub labels: Vec<BallLabel>,
}

impl ProjectBalls {
    /// No `[balls]` table (a board's project): no ball; [`ProjectFile::validate`] accepts
    /// it beside `[board]` only.
    pub fn absent() -> Self {
        ProjectBalls {
            diameter_mm: 0.0,
            check: Vec::new(),
            labels: Vec::new(),
        }
    }

    /// Whether this is [`ProjectBalls::absent`] (not written).
    pub fn is_absent(&self) -> bool {
        *self == Self::absent()
    }
}

/// A ball's number and its approximate position in the main image (pixels, origin at the
/// centre of the top-left pixel, y down); the nearest ball found within a few ball radii
/// takes the id.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BallLabel {
    /// Ball id (`B1` …).
    pub id: String,
    /// Column (px).
    pub x: f64,
    /// Row (px).
    pub y: f64,
}

/// `[[cameras]]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProjectCamera {
    /// Camera id used by images.
    pub id: String,
    /// The camera model: one of [`pingcal_camera::ModelKind::NAMES`], by default
    /// [`pingcal_camera::ModelKind::DEFAULT`].
    #[serde(default = "default_model")]
    pub model: CameraModel,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Pixel pitch (mm).
    pub pixel_size_mm: f64,
    /// Initial values (the camera's data sheet or an earlier calibration), with the keys of
    /// the model ([`crate::intrinsics`]); missing ones from [`ProjectCamera::nominal`].
    pub initial: KeyedValues,
    /// Which parameters to self-calibrate (the model's parameter names: `c`, `xp`, `K1` …
    /// for the photogrammetric model, `fx`, `cx`, `k1` … for the others).
    pub free: Vec<Parameter>,
}

fn default_model() -> CameraModel {
    CameraModel::DEFAULT
}

impl ProjectCamera {
    /// The start of the parameters a project does not give: no distortion, the principal
    /// point at the image centre, the focal length the project gives (`c_mm` or `fx`, `fy`),
    /// for the double sphere ξ = −0.2, α = ½ ([`pingcal_camera::ModelKind::nominal`]).
    pub fn nominal(&self) -> Vec<f64> {
        let focal_px = if self.model.in_mm() {
            self.initial.get("c_mm").unwrap_or(0.0) / self.pixel_size_mm
        } else {
            let (fx, fy) = (self.initial.get("fx"), self.initial.get("fy"));
            let f = fx.or(fy).unwrap_or(0.0);
            0.5 * (fx.unwrap_or(f) + fy.unwrap_or(f))
        };
        let mut p = self
            .model
            .nominal(focal_px, self.width, self.height, self.pixel_size_mm);
        if !self.model.in_mm() {
            // `nominal` may scale fx, fy (the double sphere's by 1 + ξ, for the scale on
            // its axis); the project's own fx, fy are taken as given
            p[0] = focal_px;
            p[1] = focal_px;
        }
        p
    }

    /// The initial values of every parameter of the model, in its slice order.
    pub fn intrinsics(&self) -> Intrinsics {
        Intrinsics::from_table(self.model, &self.initial, &self.nominal())
    }

    /// For each parameter of the model, in its slice order, whether it is self-calibrated.
    pub fn free_flags(&self) -> Vec<bool> {
        Parameter::of(self.model)
            .iter()
            .map(|p| self.free.contains(p))
            .collect()
    }
}

/// The ten photogrammetric parameters, named as in results.json. Missing ones are 0.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraParams {
    /// Principal distance (mm).
    pub c_mm: f64,
    /// Principal point x (mm).
    #[serde(default)]
    pub xp_mm: f64,
    /// Principal point y (mm).
    #[serde(default)]
    pub yp_mm: f64,
    /// K1 (mm⁻²).
    #[serde(default)]
    pub k1: f64,
    /// K2 (mm⁻⁴).
    #[serde(default)]
    pub k2: f64,
    /// K3 (mm⁻⁶).
    #[serde(default)]
    pub k3: f64,
    /// P1 (mm⁻¹).
    #[serde(default)]
    pub p1: f64,
    /// P2 (mm⁻¹).
    #[serde(default)]
    pub p2: f64,
    /// B1.
    #[serde(default)]
    pub b1: f64,
    /// B2.
    #[serde(default)]
    pub b2: f64,
}

impl CameraParams {
    /// From the slice order `[c, xp, yp, K1, K2, K3, P1, P2, B1, B2]`.
    pub fn from_slice(p: &[f64; 10]) -> Self {
        Self {
            c_mm: p[0],
            xp_mm: p[1],
            yp_mm: p[2],
            k1: p[3],
            k2: p[4],
            k3: p[5],
            p1: p[6],
            p2: p[7],
            b1: p[8],
            b2: p[9],
        }
    }

    /// To the slice order.
    pub fn to_slice(&self) -> [f64; 10] {
        [
            self.c_mm, self.xp_mm, self.yp_mm, self.k1, self.k2, self.k3, self.p1, self.p2,
            self.b1, self.b2,
        ]
    }
}

/// `[stereo]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProjectStereo {
    /// Left camera id.
    pub left: String,
    /// Right camera id.
    pub right: String,
    /// Nominal baseline (mm), an initial value.
    pub baseline_mm: f64,
}

/// `[rig]`: the head's cameras beyond `[stereo]`'s pair (or beside a single main camera),
/// each rigidly mounted: its images of a station follow the main camera's image of that
/// station through one relative pose, shared by all stations.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProjectRig {
    /// `[[rig.cameras]]`.
    pub cameras: Vec<ProjectRigCamera>,
}

/// `[[rig.cameras]]`: a camera of `[[cameras]]` on the head, with its pose relative to the
/// main camera.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProjectRigCamera {
    /// The camera's id in `[[cameras]]`.
    pub id: String,
    /// Its rotation relative to the main camera (ω, φ, κ; degrees): `x_cam = R (x_main − C)`
    /// with `R = R_ω R_φ R_κ`; `[0, 0, 60]` faces 60° to the side about the head's up axis.
    pub opk_deg: [f64; 3],
    /// Its projection centre `C` in the main camera's frame (X right, Y forward, Z up; mm).
    pub t_mm: [f64; 3],
    /// Hold the pose at these values (a head calibrated before) instead of estimating it;
    /// by default estimated, started where the images' own orientations put it (these
    /// values where no station orients both cameras).
    #[serde(default)]
    pub hold: bool,
}

/// `[[images]]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProjectImage {
    /// Path relative to project.toml.
    pub file: String,
    /// Camera id.
    pub camera: String,
    /// Station id (images of one station were taken at the same time by the head).
    pub station: String,
}

/// `[[distances]]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProjectDistance {
    /// Coded target number at one end.
    pub from: u32,
    /// Coded target number at the other end.
    pub to: u32,
    /// Measured distance (mm).
    pub distance_mm: f64,
    /// Its σ (mm).
    pub sigma_mm: f64,
}

/// `[lrf]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProjectLrf {
    /// Its id: required for each of `[[lrfs]]` (its results are under `lrfs/<id>/`, its
    /// tf frame is the id); `[lrf]`'s is `lrf` when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub id: Option<String>,
    /// Sensor model, for reports.
    pub model: String,
    /// The kind of LRF: `"rotating"` (a 2D scanner turned by a servo; the default) or
    /// `"fixed"` (a 2D scanner bolted to the head, its scans taken at stations of the head).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kind: Option<LrfKind>,
    /// Station where it scanned (a rotating LRF: the main station; a fixed LRF: the station
    /// of every scan file listed without its own).
    pub station: String,
    /// Scan files (`pingcal-scan` CSV, or PLY / PCD / XYZ clouds), relative to project.toml
    /// (may be empty when `[lrf.bag]` names bags): each a path, or `{ file, station }` for
    /// a fixed LRF's scans at the stations of the head.
    #[serde(default)]
    pub scans: Vec<ScanEntry>,
    /// ROS bags to read the scans from, besides `scans` (`[lrf.bag]`).
    #[serde(default)]
    pub bag: Option<ProjectBag>,
    /// Unit of the coordinates of the cloud files among `scans` (PLY, PCD, XYZ): `"mm"`
    /// (absent: the default) or `"m"`. Scan files are always mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cloud_unit: Option<CloudUnit>,
    /// Maximum range (mm).
    pub max_range_mm: f64,
    /// Datasheet accuracy under 1 m (± mm, taken as 3σ).
    pub accuracy_near_mm: f64,
    /// Datasheet accuracy beyond 1 m (± fraction of range, taken as 3σ).
    pub accuracy_far_fraction: f64,
    /// Named range-noise profile (`"URG-04LX"`, `"UTM-30LX"`, `"UST-10LX"`, `"VLP-16"`)
    /// instead of the `accuracy_*` keys' profile.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise: Option<NoiseProfile>,
    /// Linear range-noise profile σ = a + b·r (`[a_mm, b]`) instead of the `accuracy_*` keys'.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise_sigma_mm: Option<[f64; 2]>,
    /// Offset of the scanner centre from the servo shaft in the rotating frame (mm).
    #[serde(default)]
    pub mount_offset_mm: [f64; 3],
    /// Tilt of the scan plane about the rotating frame's X axis (degrees).
    #[serde(default)]
    pub mount_tilt_x_deg: f64,
    /// Tilt of the scan plane about the rotating frame's Z axis (degrees).
    #[serde(default)]
    pub mount_tilt_z_deg: f64,
    /// Servo reading at which the scan plane is the LRF frame's X–Y plane (degrees).
    #[serde(default)]
    pub servo_zero_deg: f64,
    /// Servo encoder resolution (degrees).
    #[serde(default)]
    pub servo_resolution_deg: f64,
    /// Mount and range parameters the joint adjustment may estimate (absent: every one the
    /// data determine; `[]`: none). `offset_y` is the LRF frame's origin along the servo
    /// axis and is never estimated.
    #[serde(default)]
    pub self_calibrate: Option<Vec<MountParameter>>,
    /// The whole LRF model (mount and range) from a file, relative to project.toml: the
    /// `mount.json` of `pingcal lrf-mount` or a calibration's `results.json` (their
    /// `lrf_model` block), instead of the `mount_*` and `servo_zero_deg` keys.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lrf_model: Option<String>,
    /// Use the room's planes (walls, floor, ceiling seen from both half-sweeps) to find the
    /// mount before the balls and as constraints of the joint adjustment (absent: true).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub room_planes: Option<bool>,
}

/// One entry of `[lrf] scans`: a path (taken at `[lrf] station`), or a path and the station
/// where the head stood (a fixed LRF).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum ScanEntry {
    /// A path, relative to project.toml.
    File(String),
    /// A path and its station.
    AtStation(ScanAtStation),
}

/// `{ file, station }` of `[lrf] scans`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScanAtStation {
    /// The path, relative to project.toml.
    pub file: String,
    /// The station where the head stood (a station of `[[images]]`).
    pub station: String,
}

impl ScanEntry {
    /// Its path, relative to project.toml.
    pub fn file(&self) -> &str {
        match self {
            ScanEntry::File(f) => f,
            ScanEntry::AtStation(s) => &s.file,
        }
    }

    /// Its station, or `default` (`[lrf] station`) when the entry gives none.
    pub fn station<'a>(&'a self, default: &'a str) -> &'a str {
        match self {
            ScanEntry::File(_) => default,
            ScanEntry::AtStation(s) => &s.station,
        }
    }
}

impl std::fmt::Display for ScanEntry {
    /// The path, as messages name the entry.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.file())
    }
}

impl ProjectFile {
    /// This file with the `k`-th of `[[lrfs]]` as its `[lrf]` (no `[[lrfs]]`), its id the
    /// tf frame of that sensor's outputs.
    pub fn with_range_sensor(&self, k: usize) -> ProjectFile {
        let mut f = self.clone();
        let lrf = f.lrfs.swap_remove(k);
        f.frames.lrf = lrf.id().to_string();
        f.lrf = lrf;
        f.lrfs.clear();
        f
    }
}

impl ProjectLrf {
    /// Its id (`[lrf]`'s absent one is `lrf`).
    pub fn id(&self) -> &str {
        self.id.as_deref().unwrap_or("lrf")
    }

    /// The kind (absent: rotating).
    pub fn kind(&self) -> LrfKind {
        self.kind.unwrap_or(LrfKind::Rotating)
    }

    /// Each scan entry's station, in order.
    pub fn scan_stations(&self) -> Vec<&str> {
        self.scans
            .iter()
            .map(|s| s.station(&self.station))
            .collect()
    }
}

/// `[lrf.bag]`: ROS 1 / ROS 2 bags holding the LRF's scans and the servo angle (as
/// `pingcal scans` reads them).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProjectBag {
    /// Bag files or ROS 2 bag folders, relative to project.toml.
    pub files: Vec<String>,
    /// The `sensor_msgs/LaserScan` topic.
    pub scan_topic: String,
    /// The servo topic (`sensor_msgs/JointState` with `servo_joint`, `tf2_msgs/TFMessage`
    /// with `servo_tf_child`, else numeric `std_msgs`).
    pub servo_topic: String,
    /// The servo's joint name in the JointState messages.
    #[serde(default)]
    pub servo_joint: Option<String>,
    /// Numeric servo topic: degrees per unit (default 1).
    #[serde(default)]
    pub servo_scale: Option<f64>,
    /// Numeric servo topic: degrees at value 0 (default 0).
    #[serde(default)]
    pub servo_offset: Option<f64>,
    /// `tf2_msgs/TFMessage` servo topic: the child frame that turns with the servo.
    #[serde(default)]
    pub servo_tf_child: Option<String>,
    /// tf servo topic: the servo axis in the parent frame (default `[0, 1, 0]`).
    #[serde(default)]
    pub servo_axis: Option<[f64; 3]>,
    /// How the servo moves: `"auto"` (absent: told from the servo series), `"stop-and-go"`
    /// (the last angle before each scan is held) or `"continuous"` (interpolated at each
    /// beam's time).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub servo_motion: Option<ServoMotion>,
    /// Whose time the messages are taken at: `"auto"` (absent: the header stamps unless the
    /// two topics keep different clocks), `"header"` or `"record"` (the bag's record times).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stamps: Option<Stamps>,
}

impl ProjectLrf {
    /// The mount parameters asked for (see [`ProjectLrf::self_calibrate`]).
    pub fn self_calibrated(&self) -> Vec<MountParameter> {
        match &self.self_calibrate {
            Some(v) => v.clone(),
            None => MountParameter::ALL
                .into_iter()
                .filter(|p| *p != MountParameter::OffsetY)
                .collect(),
        }
    }
}
