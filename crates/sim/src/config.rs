//! Every number of the simulation, readable from a TOML file, with the paper's values as
//! defaults, and a validation that refuses impossible values with an error naming the key.
//!
//! All lengths in mm, angles in degrees, unless the key name says otherwise. A TOML file
//! needs to give only the keys it changes; unknown keys are refused (a typo must not be
//! silently ignored).

use pingcal_lrf::scan::ScanHeader;
use pingcal_lrf::sensor::{LrfSensor, MountModel, RangeNoise};
use pingcal_project::{Board, BoardKind, CameraModel, LrfKind, ProjectBoard};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// A configuration error: the key (TOML path), its value and why it is refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{key} = {value}: {why}")]
pub struct ConfigError {
    /// TOML path of the offending value, e.g. `targets.dot_radius_mm`.
    pub key: String,
    /// The value as given.
    pub value: String,
    /// What is wrong with it.
    pub why: String,
}

impl ConfigError {
    pub(crate) fn new(
        key: impl Into<String>,
        value: impl std::fmt::Display,
        why: impl Into<String>,
    ) -> Self {
        Self {
            key: key.into(),
            value: value.to_string(),
            why: why.into(),
        }
    }
}

/// The whole simulation configuration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(default, deny_unknown_fields)]
pub struct SimConfig {
    /// The room corner (walls and floor).
    pub room: RoomConfig,
    /// Retro-reflective targets (coded and plain).
    pub targets: TargetConfig,
    /// Ping-pong balls on stems.
    pub balls: BallConfig,
    /// Caliper distances between coded targets.
    pub distances: DistanceConfig,
    /// The stereo head.
    pub camera: CameraConfig,
    /// More cameras on the head (`[[rig.cameras]]`); none by default, and then not written.
    #[serde(skip_serializing_if = "RigConfig::is_empty")]
    pub rig: RigConfig,
    /// The camera stations.
    pub stations: StationConfig,
    /// Image formation.
    pub render: RenderConfig,
    /// The 2D LRF and its servo.
    pub lrf: LrfConfig,
    /// More range sensors on the head (`[[lrfs]]`, issue 52): each `id` and `[lrf]`'s keys
    /// (`kind`, `extrinsic_opk_deg`, `extrinsic_t_mm`, …); none by default, then not written.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub lrfs: Vec<RangeSensorConfig>,
    /// Which field: the room (the default, not written when it is) or a board in several
    /// placements ([`crate::board_field`]).
    #[serde(skip_serializing_if = "FieldConfig::is_default")]
    pub field: FieldConfig,
    /// The board of a board field, as a project's `[board]` (absent: [`default_board`]);
    /// only with `[field] kind = "board"`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub board: Option<ProjectBoard>,
}

/// What kind of field is simulated (`[field] kind`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FieldKind {
    /// The room corner of targets and balls, seen by the stereo head's stations.
    #[default]
    Room,
    /// A board in several placements before the head's left camera and a fixed LRF.
    Board,
}

/// `[field]`: the room (default) or a board field ([`crate::board_field`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FieldConfig {
    /// `"room"` (default) or `"board"`.
    pub kind: FieldKind,
    /// Placements of the board (a board field).
    pub placements: usize,
    /// The board centre's distance from the camera, mm, stratified over the placements.
    pub range_mm: [f64; 2],
    /// The board's turn away from facing the camera about its horizontal and its vertical
    /// axis, at most, degrees (0: every board vertical and square to the camera's forward
    /// axis).
    pub max_tilt_deg: f64,
    /// The turn about the horizontal axis alone, at most, degrees (absent: `max_tilt_deg`;
    /// 0: every board vertical, turned only about the vertical, the usual way before a
    /// horizontal scan).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_pitch_deg: Option<f64>,
    /// The LRF's scans of each placement (the board held still for a second before a 10 Hz
    /// scanner: 10).
    pub scans_per_placement: usize,
    /// The board as printed over the board as given (`[board] square_mm`): 0.925 is a page
    /// printed "fit to page", its 20 mm squares 18.5 mm.
    pub print_scale: f64,
}

impl Default for FieldConfig {
    fn default() -> Self {
        Self {
            kind: FieldKind::Room,
            placements: 8,
            range_mm: [500.0, 1100.0],
            max_tilt_deg: 35.0,
            max_pitch_deg: None,
            scans_per_placement: 10,
            print_scale: 1.0,
        }
    }
}

impl FieldConfig {
    /// Whether every key has its default (the table is then not written).
    pub fn is_default(&self) -> bool {
        *self == FieldConfig::default()
    }
}

/// The board of a board field without `[board]`: a chessboard of 7 × 5 inner corners and
/// 60 mm squares (a 480 × 360 mm pattern).
pub fn default_board() -> ProjectBoard {
    ProjectBoard {
        kind: Some(BoardKind::Chessboard),
        inner_corners: Some([7, 5]),
        square_mm: Some(60.0),
        ..ProjectBoard::default()
    }
}

/// The room corner: vertex at the world origin, wall 1 along +X (plane y ≈ 0), wall 2 along
/// +Y (plane x ≈ 0), floor z ≈ 0; the room is x > 0, y > 0, z > 0.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RoomConfig {
    /// Length of each wall along the floor.
    pub wall_length_mm: f64,
    /// Height of the walls.
    pub wall_height_mm: f64,
    /// Each plane's normal is tilted by up to this angle about each axis (uniform), so the
    /// corner is neither exactly orthogonal nor exactly the world axes.
    pub max_tilt_deg: f64,
    /// Each plane bulges (pillow shape, zero at its edges) by up to this much (random sign).
    pub max_bulge_mm: f64,
    /// Mean diffuse albedo of the walls (matt paint).
    pub wall_albedo: f64,
    /// Mean diffuse albedo of the floor.
    pub floor_albedo: f64,
    /// Relative amplitude of the procedural texture (0 = uniform).
    pub texture_amplitude: f64,
}

impl Default for RoomConfig {
    fn default() -> Self {
        Self {
            wall_length_mm: 2500.0,
            wall_height_mm: 2000.0,
            max_tilt_deg: 0.3,
            max_bulge_mm: 3.0,
            wall_albedo: 0.45,
            floor_albedo: 0.3,
            texture_amplitude: 0.15,
        }
    }
}

/// Printed retro-reflective targets. Geometry in units of the dot radius R: central dot of
/// radius R, code ring between `ring_inner` R and `ring_outer` R, black background disc of
/// radius `background` R (plain targets: `plain_background` R).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TargetConfig {
    /// Total number of targets (paper: 78).
    pub count: usize,
    /// How many of them are AICON coded (the rest are plain).
    pub coded: usize,
    /// Bits of the AICON code ring (12 or 14).
    pub code_bits: u32,
    /// Radius R of the central dot.
    pub dot_radius_mm: f64,
    /// Inner radius of the code ring, in R.
    pub ring_inner: f64,
    /// Outer radius of the code ring, in R.
    pub ring_outer: f64,
    /// Radius of the black background of a coded target, in R.
    pub background: f64,
    /// Radius of the black background of a plain target, in R.
    pub plain_background: f64,
    /// Spacing of the candidate grid on each plane (targets are then thinned evenly).
    pub grid_spacing_mm: f64,
    /// Keep targets at least this far from a plane's edges.
    pub edge_margin_mm: f64,
    /// Albedo of the black background print.
    pub black_albedo: f64,
    /// Brightness of retro-reflective material relative to a white Lambertian surface lit
    /// by the same flash, for light returning to the flash. With the default flash this is
    /// really the exposure of the retro targets: photogrammetrists expose so that the
    /// targets are bright but not clipped, and a detector refuses clipped targets (their
    /// edge level is wrong). The default 1.0 keeps a target facing the camera under full
    /// scale from 0.95 m on (`retro_gain · flash_at_1m / d² + 0.8 · ambient < 1`); 3.0
    /// clipped every target nearer than 1.6 m, i.e. most of the field.
    pub retro_gain: f64,
}

impl Default for TargetConfig {
    fn default() -> Self {
        Self {
            count: 78,
            coded: 26,
            code_bits: 14,
            dot_radius_mm: 8.0,
            ring_inner: 2.0,
            ring_outer: 3.0,
            background: 3.5,
            plain_background: 2.0,
            grid_spacing_mm: 110.0,
            edge_margin_mm: 80.0,
            black_albedo: 0.04,
            retro_gain: 1.0,
        }
    }
}

/// Where one ball stands (optional explicit placement).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BallPlacement {
    /// `wall1`, `wall2` or `floor`.
    pub surface: String,
    /// Position of the stem's foot along the plane's first edge.
    pub u_mm: f64,
    /// Position of the stem's foot along the plane's second edge.
    pub v_mm: f64,
    /// Distance from the plane to the ball centre.
    pub standoff_mm: f64,
}

/// Ping-pong balls on stems.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BallConfig {
    /// Number of balls (paper: 16).
    pub count: usize,
    /// Ball diameter (paper: 38 mm).
    pub diameter_mm: f64,
    /// Distance from the plane to the ball centre: drawn uniformly in this range.
    pub standoff_range_mm: [f64; 2],
    /// Radius of the stem (a thin grey rod along the plane normal).
    pub stem_radius_mm: f64,
    /// Albedo of the ball (white celluloid).
    pub albedo: f64,
    /// Albedo of the stem.
    pub stem_albedo: f64,
    /// Keep a stem's foot this far from any target centre.
    pub clearance_mm: f64,
    /// Explicit placements (replace the automatic ones when given).
    pub placements: Option<Vec<BallPlacement>>,
    /// Ball numbers used as check points (paper: 4, 9, 11, 12, 15).
    pub check_balls: Vec<u32>,
}

impl Default for BallConfig {
    fn default() -> Self {
        Self {
            count: 16,
            diameter_mm: 38.0,
            standoff_range_mm: [60.0, 140.0],
            stem_radius_mm: 2.0,
            albedo: 0.9,
            stem_albedo: 0.3,
            clearance_mm: 40.0,
            placements: None,
            check_balls: vec![4, 9, 11, 12, 15],
        }
    }
}

/// Caliper distances between coded targets.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DistanceConfig {
    /// Number of measured distances (paper: 5).
    pub count: usize,
    /// Standard deviation of a caliper measurement.
    pub sigma_mm: f64,
    /// Shortest and longest distance chosen.
    pub length_range_mm: [f64; 2],
}

impl Default for DistanceConfig {
    fn default() -> Self {
        Self {
            count: 5,
            sigma_mm: 0.1,
            length_range_mm: [300.0, 1200.0],
        }
    }
}

/// Intrinsics of one camera, in its model's slice order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Intrinsics {
    /// The parameters of `[camera] model` in its order
    /// ([`pingcal_ba::camera::ModelKind::parameter_names`]): for the photogrammetric model
    /// `[c, xp, yp, K1, K2, K3, P1, P2, B1, B2]` (mm, mm⁻², mm⁻⁴, mm⁻⁶, mm⁻¹, unitless),
    /// for the models in pixels fx, fy, cx, cy and then their distortion's.
    pub params: Vec<f64>,
}

/// The stereo head (MYNT EYE D1000-like).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CameraConfig {
    /// The camera model (by default the photogrammetric one; [`CameraConfig::for_model`]
    /// gives each model its lens).
    pub model: CameraModel,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Pixel pitch.
    pub pixel_size_mm: f64,
    /// True intrinsics of the left camera.
    pub left: Intrinsics,
    /// True intrinsics of the right camera.
    pub right: Intrinsics,
    /// Centre of the right camera in the left camera frame (X right, Y forward, Z up).
    pub right_offset_mm: [f64; 3],
    /// Rotation of the right camera relative to the left (ω, φ, κ), degrees.
    pub right_opk_deg: [f64; 3],
    /// Nominal focal length written as the initial value in project.toml (mm; for the
    /// models in pixels, fx = fy = this over the pixel pitch).
    pub nominal_c_mm: f64,
}

impl Default for CameraConfig {
    fn default() -> Self {
        Self {
            model: CameraModel::DEFAULT,
            width: 1280,
            height: 720,
            pixel_size_mm: 0.00375,
            // The default model's sample lens (the camera crate's registry): barrel
            // distortion of a ~90° lens, K1 r² ≈ −15 % at the image corner (r = 2.75 mm).
            left: Intrinsics {
                params: CameraModel::DEFAULT.sample().left.to_vec(),
            },
            right: Intrinsics {
                params: CameraModel::DEFAULT.sample().right.to_vec(),
            },
            right_offset_mm: [120.0, 0.4, -0.3],
            right_opk_deg: [0.15, -0.25, 0.1],
            nominal_c_mm: 2.45,
        }
    }
}

impl CameraConfig {
    /// The head with lenses of `model` on the default sensor (1280 × 720, 3.75 µm): the
    /// model's sample lenses in the camera crate's registry
    /// ([`pingcal_ba::camera::ModelKind::sample`]; the photogrammetric model's are the
    /// default head's). The nominal focal length is the default's for the models in mm,
    /// for the others the left lens's scale on the axis rounded to whole pixels.
    pub fn for_model(model: CameraModel) -> Self {
        let base = CameraConfig::default();
        let lens = model.sample();
        let (left, right) = (lens.left.to_vec(), lens.right.to_vec());
        let nominal_c_mm = if model.in_mm() {
            base.nominal_c_mm
        } else {
            let m = model.model(base.width, base.height, base.pixel_size_mm);
            m.focal_px(&left).round() * base.pixel_size_mm
        };
        CameraConfig {
            model,
            left: Intrinsics { params: left },
            right: Intrinsics { params: right },
            nominal_c_mm,
            ..base
        }
    }
}

/// One of `[[lrfs]]`: its id and its keys as `[lrf]` has them (one flat table).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "toml::Table", into = "toml::Table")]
pub struct RangeSensorConfig {
    /// Its id (the project's `[[lrfs]] id`, its scans under `scans/<id>/`).
    pub id: String,
    /// Its keys, as `[lrf]`'s.
    pub lrf: LrfConfig,
}

impl TryFrom<toml::Table> for RangeSensorConfig {
    type Error = String;

    fn try_from(mut t: toml::Table) -> Result<Self, String> {
        let id = match t.remove("id") {
            Some(toml::Value::String(id)) => id,
            _ => return Err("each of [[lrfs]] needs its id = \"…\"".into()),
        };
        let lrf = LrfConfig::deserialize(toml::Value::Table(t))
            .map_err(|e| format!("[[lrfs]] id = \"{id}\": {e}"))?;
        Ok(Self { id, lrf })
    }
}

impl From<RangeSensorConfig> for toml::Table {
    fn from(r: RangeSensorConfig) -> Self {
        let mut t = toml::Table::try_from(&r.lrf).expect("an LRF's keys serialise");
        t.insert("id".into(), toml::Value::String(r.id));
        t
    }
}

/// `[rig]`: the head's cameras beyond the stereo pair (issue 52).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(default, deny_unknown_fields)]
pub struct RigConfig {
    /// `[[rig.cameras]]`, each with its pose relative to the left camera.
    pub cameras: Vec<RigCameraConfig>,
}

impl RigConfig {
    /// No extra camera (the default head).
    pub fn is_empty(&self) -> bool {
        self.cameras.is_empty()
    }
}

/// `[[rig.cameras]]`: a camera of the head beside the stereo pair, of `[camera] model` on
/// its sensor.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RigCameraConfig {
    /// Its id (the images are `S00_<id>.png`, …), not `left` or `right`.
    pub id: String,
    /// Its rotation relative to the left camera (ω, φ, κ), degrees, as
    /// `camera.right_opk_deg`: `[0, 0, 60]` turns it 60° to the side about the head's up
    /// axis.
    pub opk_deg: [f64; 3],
    /// Its projection centre in the left camera's frame (X right, Y forward, Z up), mm, as
    /// `camera.right_offset_mm`.
    pub t_mm: [f64; 3],
    /// Its true intrinsics (absent: the left camera's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub params: Option<Vec<f64>>,
}

/// An explicitly placed extra station.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StationPlacement {
    /// Left camera centre in world coordinates.
    pub centre_mm: [f64; 3],
    /// The point the optical axis passes through.
    pub look_at_mm: [f64; 3],
    /// Roll about the optical axis.
    pub roll_deg: f64,
}

/// Camera stations: the main station (beside the LRF) and a convergent network.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct StationConfig {
    /// Left camera centre of the main station (world).
    pub main_centre_mm: [f64; 3],
    /// Where the main station looks.
    pub main_look_at_mm: [f64; 3],
    /// Number of convergent (non-main) stations.
    pub convergent: usize,
    /// Heights of the convergent stations (cycled).
    pub heights_mm: Vec<f64>,
    /// Horizontal distance range from the look-at point.
    pub distance_range_mm: [f64; 2],
    /// Azimuth span (about the corner's diagonal) covered by the convergent stations.
    pub azimuth_span_deg: f64,
    /// Rolls about the optical axis (cycled), e.g. 0, 90, −90.
    pub rolls_deg: Vec<f64>,
    /// Where the convergent stations look.
    pub look_at_mm: [f64; 3],
    /// Random jitter of each station's look-at point.
    pub look_jitter_mm: f64,
    /// Explicit stations added to the generated ones.
    pub extra: Vec<StationPlacement>,
    /// A camera centre must be at least this far inside the room.
    pub min_wall_clearance_mm: f64,
}

impl Default for StationConfig {
    fn default() -> Self {
        Self {
            main_centre_mm: [1150.0, 1100.0, 700.0],
            main_look_at_mm: [250.0, 230.0, 520.0],
            convergent: 10,
            heights_mm: vec![450.0, 900.0, 1350.0],
            distance_range_mm: [1100.0, 1600.0],
            azimuth_span_deg: 70.0,
            rolls_deg: vec![0.0, 90.0, 0.0, -90.0],
            look_at_mm: [300.0, 300.0, 450.0],
            look_jitter_mm: 60.0,
            extra: Vec::new(),
            min_wall_clearance_mm: 100.0,
        }
    }
}

/// Image formation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RenderConfig {
    /// Sub-pixel rays per axis on pixels near targets, balls and stems (n² rays per pixel).
    pub supersampling: u32,
    /// Flash irradiance on a surface facing it at 1 m, as a fraction of full scale for a
    /// white (albedo 1) Lambertian surface.
    pub flash_at_1m: f64,
    /// Ambient light, same unit.
    pub ambient: f64,
    /// Gaussian blur (optics + defocus), σ in pixels; 0 = none.
    pub blur_sigma_px: f64,
    /// Vignetting: relative loss of light at the image corner (cos⁴-like, quadratic in r).
    pub vignetting: f64,
    /// Electrons at full scale (photon noise: Poisson in electrons).
    pub full_well_e: f64,
    /// Read noise, electrons RMS.
    pub read_noise_e: f64,
    /// Switch all noise off (for tests).
    pub noise: bool,
}

impl Default for RenderConfig {
    fn default() -> Self {
        Self {
            supersampling: 4,
            flash_at_1m: 0.8,
            ambient: 0.12,
            blur_sigma_px: 0.6,
            vignetting: 0.25,
            full_well_e: 6000.0,
            read_noise_e: 6.0,
            noise: true,
        }
    }
}

/// The Hokuyo URG-04LX turned by a Dynamixel MX-28T, and its mount on the stereo head.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LrfConfig {
    /// `"rotating"` (the default: a sweep of the room from the main station) or `"fixed"`:
    /// the scanner bolted to the head (its scan plane the LRF frame's XY plane as the
    /// extrinsic puts it), `scans_per_station` scans at each of `scan_stations`, the servo
    /// and mount keys unused (the range offset and scale still apply).
    #[serde(skip_serializing_if = "is_rotating")]
    pub kind: LrfKind,
    /// A fixed LRF's stations (absent or empty: every station of the field, spread over
    /// it); each must be a station's id (`S00`, `S01`, …).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub scan_stations: Vec<String>,
    /// A fixed LRF's scans at each station (default 5).
    #[serde(skip_serializing_if = "is_default_scans_per_station")]
    pub scans_per_station: usize,
    /// Number of beams per scan.
    pub beams: usize,
    /// Angle of beam 0.
    pub angle_min_deg: f64,
    /// Angle between beams.
    pub angle_increment_deg: f64,
    /// Maximum range.
    pub max_range_mm: f64,
    /// Minimum range (URG error codes below 20).
    pub min_range_mm: f64,
    /// Datasheet accuracy under 1 m (± value).
    pub accuracy_near_mm: f64,
    /// Datasheet accuracy beyond 1 m, fraction of the range (± value).
    pub accuracy_far_fraction: f64,
    /// How many σ the datasheet's ± is taken to be (3: the ± bounds 99.7 % of readings).
    pub accuracy_sigmas: f64,
    /// Full width of the beam footprint (for mixed pixels), degrees.
    pub beam_width_deg: f64,
    /// Surfaces with a reflectivity under this give no return.
    pub min_reflectivity: f64,
    /// Servo angle of the first scan.
    pub servo_start_deg: f64,
    /// Servo angle of the last scan.
    pub servo_end_deg: f64,
    /// Servo step between scans. Default: one encoder tick (0.088°), a slow turn of about
    /// 7 minutes giving the paper's "extremely high-density" cloud: about four times the
    /// points per ball of a 0.35° step, which halves the σ of the sphere centres.
    pub servo_step_deg: f64,
    /// Encoder resolution of the servo (MX-28T: 360/4096 degrees).
    pub servo_resolution_deg: f64,
    /// Servo positioning noise (true angle minus reported), σ.
    pub servo_sigma_deg: f64,
    /// Scan period.
    pub scan_period_s: f64,
    /// Time between two beams of a scan (URG-04LX: a 100 ms turn of 1024 steps).
    pub beam_time_s: f64,
    /// The servo turns while the LRF scans (at `servo_step_deg` per `scan_period_s`), each
    /// beam at its own angle; the scan file is then `pingcal-scan` v2 with the servo angle at
    /// each scan's first and last beam. False: stop-and-go (the servo stands still during
    /// each scan).
    pub continuous_sweep: bool,
    /// Time offset between the servo's stamps and the scanner's, seconds (default 0): the
    /// servo's stamp of an instant is this much later than the scanner's, so a reader that
    /// interpolates the servo's angles at a beam's time gets the angle the servo had this
    /// much earlier. Only a continuous sweep shows it (a stop-and-go servo stands still
    /// while the scanner sweeps): each beam's servo angle in the scan file is off by
    /// −speed · offset. Estimating it needs the sweep to change speed or direction
    /// (`servo_passes = 2`).
    pub servo_time_offset_s: f64,
    /// Passes of the servo over `servo_start_deg`…`servo_end_deg` (default 1), alternately
    /// forward and back: scans of pass 2 go from the end back to the start.
    pub servo_passes: usize,
    /// Extrinsic, `p_camera = R·p_lrf + t` with the main left camera: rotation ω, φ, κ (a
    /// fixed LRF left at this default faces forward, pitched [`FIXED_PITCH_DEG`] down:
    /// [`LrfConfig::extrinsic_opk_deg_of_kind`]).
    pub extrinsic_opk_deg: [f64; 3],
    /// Extrinsic translation t.
    pub extrinsic_t_mm: [f64; 3],
    /// The scanner is mounted as a real one is (true, the default): off its servo axis by
    /// `mount_offset_mm`, its scan plane tilted, its servo angle scaled and its ranges offset
    /// and scaled by the keys below, whose defaults are a realistic rig's (offset (3, −2, 8)
    /// mm, tilts 0.3° and −0.2°, range offset +12 mm; published rotating-LRF calibrations
    /// find offsets of up to ±15 mm and tilts of tenths of a degree). False: the ideal rig
    /// of the paper's eq. 2, every one of them zero (a key set to anything else is then
    /// refused).
    pub mount_errors: bool,
    /// Offset of the 2D scanner's centre from the servo shaft, in the rotating frame
    /// (eq. 2 assumes zero; a real gimbal is never perfect).
    pub mount_offset_mm: [f64; 3],
    /// Tilt of the scan plane about the turning frame's X axis (the α = 0 beam), degrees.
    pub mount_tilt_x_deg: f64,
    /// Tilt of the scan plane about Z (a zero error of the beam angle), degrees.
    pub mount_tilt_z_deg: f64,
    /// Scale error of the servo angle (`β = servo · (1 + servo_scale)`).
    pub servo_scale: f64,
    /// Range offset: the sensor reports `true · (1 + range_scale) + range_offset_mm`.
    pub range_offset_mm: f64,
    /// Range scale error.
    pub range_scale: f64,
    /// Switch range and servo noise off (for tests).
    pub noise: bool,
}

/// The default mount and range errors of the simulated scanner ([`LrfConfig::mount_errors`]).
pub const REALISTIC_MOUNT: MountModel = MountModel {
    offset_mm: [3.0, -2.0, 8.0],
    tilt_x_deg: 0.3,
    tilt_z_deg: -0.2,
    servo_zero_deg: 0.0,
    servo_scale: 0.0,
    range_offset_mm: 12.0,
    range_scale: 0.0,
    servo_time_offset_s: 0.0,
};

/// Whether `kind` is the default, rotating (not written to simulation.toml).
fn is_rotating(kind: &LrfKind) -> bool {
    *kind == LrfKind::Rotating
}

/// How far a fixed LRF left at the default extrinsic is pitched down (degrees about the
/// camera's X axis; [`LrfConfig::extrinsic_opk_deg_of_kind`]).
pub const FIXED_PITCH_DEG: f64 = 20.0;

/// A fixed LRF's scans at each station, by default.
pub const SCANS_PER_STATION: usize = 5;

/// Whether `n` is [`SCANS_PER_STATION`] (not written to simulation.toml).
fn is_default_scans_per_station(n: &usize) -> bool {
    *n == SCANS_PER_STATION
}

impl Default for LrfConfig {
    fn default() -> Self {
        Self {
            kind: LrfKind::Rotating,
            scan_stations: Vec::new(),
            scans_per_station: SCANS_PER_STATION,
            beams: 682,
            angle_min_deg: -119.53125,
            angle_increment_deg: 0.3515625,
            max_range_mm: 5600.0,
            min_range_mm: 20.0,
            accuracy_near_mm: 30.0,
            accuracy_far_fraction: 0.03,
            accuracy_sigmas: 3.0,
            beam_width_deg: 0.35,
            min_reflectivity: 0.08,
            // A full turn: the URG's 240° field reaches only 29.5° past the shaft (α = 90°)
            // on the far side, so a half turn would leave half the field unscanned.
            servo_start_deg: -180.0,
            servo_end_deg: 180.0 - 0.087890625,
            servo_step_deg: 0.087890625,
            servo_resolution_deg: 360.0 / 4096.0,
            servo_sigma_deg: 0.02,
            scan_period_s: 0.1,
            beam_time_s: 0.1 / 1024.0,
            continuous_sweep: false,
            servo_time_offset_s: 0.0,
            servo_passes: 1,
            // Paper Table 2: the LRF frame is close to the camera frame, offset by ~(70, 10, 90) mm.
            extrinsic_opk_deg: [0.8, -1.2, 0.6],
            extrinsic_t_mm: [72.0, 12.0, 91.0],
            mount_errors: true,
            mount_offset_mm: REALISTIC_MOUNT.offset_mm,
            mount_tilt_x_deg: REALISTIC_MOUNT.tilt_x_deg,
            mount_tilt_z_deg: REALISTIC_MOUNT.tilt_z_deg,
            servo_scale: REALISTIC_MOUNT.servo_scale,
            range_offset_mm: REALISTIC_MOUNT.range_offset_mm,
            range_scale: REALISTIC_MOUNT.range_scale,
            noise: true,
        }
    }
}

impl LrfConfig {
    /// The range-noise profile of the datasheet accuracies, each divided by
    /// `accuracy_sigmas` (±30 mm up to 1 m, ±3 % of the range beyond), whether or not
    /// `noise` is on.
    pub fn range_noise(&self) -> RangeNoise {
        RangeNoise::from_datasheet(
            self.accuracy_near_mm,
            self.accuracy_far_fraction,
            self.accuracy_sigmas,
        )
    }

    /// The true mount and range model of the simulated scanner (written to truth.json;
    /// the project file the simulator writes leaves it at zero, as a user who does not know
    /// it would).
    pub fn mount(&self) -> MountModel {
        if !self.mount_errors {
            return MountModel::default();
        }
        if self.kind == LrfKind::Fixed {
            // no servo, no mount: the scanner is the LRF frame; its ranges still err
            return MountModel {
                range_offset_mm: self.range_offset_mm,
                range_scale: self.range_scale,
                ..MountModel::default()
            };
        }
        MountModel {
            offset_mm: self.mount_offset_mm,
            tilt_x_deg: self.mount_tilt_x_deg,
            tilt_z_deg: self.mount_tilt_z_deg,
            servo_zero_deg: 0.0,
            servo_scale: self.servo_scale,
            range_offset_mm: self.range_offset_mm,
            range_scale: self.range_scale,
            // the simulator turns its servo itself (`servo_time_offset_s` is in truth.json
            // on its own)
            servo_time_offset_s: 0.0,
        }
    }

    /// The extrinsic's ω, φ, κ as the simulation uses them: `extrinsic_opk_deg`, except
    /// that a fixed LRF left at the rotating default faces forward (κ − 90°: its fan,
    /// centred on its beam α = 0, looks where the camera looks, as a robot's scanner does)
    /// and is pitched [`FIXED_PITCH_DEG`] down (ω), as the field guide recommends for a
    /// fixed scanner in this field: its scan plane then reaches the floor from every
    /// station, which fixes the plane's height and tilts (a horizontal scan plane meets
    /// only the vertical walls, which cannot), and from the main station it sees the
    /// corner's two walls and floor (Fan et al.'s single shot).
    pub fn extrinsic_opk_deg_of_kind(&self) -> [f64; 3] {
        let o = self.extrinsic_opk_deg;
        if self.kind == LrfKind::Fixed && o == LrfConfig::default().extrinsic_opk_deg {
            [o[0] + FIXED_PITCH_DEG, o[1], o[2] - 90.0]
        } else {
            o
        }
    }

    /// Range noise σ at true range `r` (mm), of [`LrfConfig::range_noise`].
    pub fn range_sigma_mm(&self, r: f64) -> f64 {
        self.range_noise().sigma(r)
    }

    /// The sensor these keys describe, as the calibration models it: the beams, eq. 2 with
    /// the mount offset, the range noise (none when `noise` is off), readings rounded to
    /// whole mm between `min_range_mm` and `max_range_mm`.
    pub fn sensor(&self) -> LrfSensor {
        LrfSensor {
            header: ScanHeader {
                angle_min_deg: self.angle_min_deg,
                angle_increment_deg: self.angle_increment_deg,
                mm_per_unit: 1.0,
                time_increment_s: self.continuous_sweep.then_some(self.beam_time_s),
            },
            beams: self.beams,
            mount: self.mount(),
            noise: if self.noise {
                self.range_noise()
            } else {
                RangeNoise::Noiseless
            },
            min_range_mm: self.min_range_mm,
            max_range_mm: self.max_range_mm,
            quantise: true,
        }
    }
}

impl SimConfig {
    /// This field seen through lenses of `model` ([`CameraConfig::for_model`]), with the
    /// targets' dots (rounded to 0.5 mm) and the balls (to 1 mm) grown by the ratio of the
    /// default lens's focal length to the new one's, as a user of a wider lens prints
    /// larger targets and takes larger balls so that they keep the size in pixels the
    /// detector, the decoder and the ball's silhouette need.
    pub fn with_camera_model(mut self, model: CameraModel) -> Self {
        let old_f = self.camera.nominal_c_mm;
        self.camera = CameraConfig::for_model(model);
        let ratio = old_f / self.camera.nominal_c_mm;
        if ratio > 1.0 {
            self.targets.dot_radius_mm = (2.0 * self.targets.dot_radius_mm * ratio).round() / 2.0;
            self.balls.diameter_mm = (self.balls.diameter_mm * ratio).round();
        }
        self
    }

    /// Reads a TOML file (only the keys it gives override the defaults) and validates it.
    pub fn from_toml_file(path: &Path) -> Result<Self, crate::SimError> {
        let text = std::fs::read_to_string(path).map_err(|e| crate::SimError::Io {
            path: path.display().to_string(),
            what: e.to_string(),
        })?;
        let cfg = Self::from_toml_str(&text).map_err(|e| crate::SimError::Config {
            file: path.display().to_string(),
            what: e,
        })?;
        Ok(cfg)
    }

    /// Parses and validates TOML text. The error is one line naming the key.
    pub fn from_toml_str(text: &str) -> Result<Self, String> {
        let cfg: SimConfig = toml::from_str(text).map_err(|e| {
            e.to_string()
                .lines()
                .filter(|l| !l.trim().is_empty())
                .map(str::trim)
                .collect::<Vec<_>>()
                .join(" ")
        })?;
        cfg.validate().map_err(|e| e.to_string())?;
        Ok(cfg)
    }

    /// The configuration as TOML text (all keys).
    pub fn to_toml_string(&self) -> String {
        toml::to_string(self).expect("the configuration serialises")
    }

    /// Checks every value that could make the simulation impossible or meaningless.
    /// Geometric checks that need the built scene (a ball inside a wall, a camera behind a
    /// wall) are repeated by [`crate::scene::TestField::build`] and [`crate::stations::build_stations`].
    pub fn validate(&self) -> Result<(), ConfigError> {
        validate_room(&self.room)?;
        validate_target_codes(&self.targets)?;
        validate_target_geometry(&self.targets)?;
        validate_balls(&self.balls)?;
        validate_ball_placements(&self.balls)?;
        validate_distances(&self.distances)?;
        validate_camera(&self.camera)?;
        validate_rig(&self.camera, &self.rig)?;
        validate_stations(&self.stations)?;
        validate_render(&self.render)?;
        validate_lrf_ranges(&self.lrf)?;
        validate_lrf_servo(&self.lrf)?;
        validate_range_sensors(&self.lrfs)?;
        validate_field(&self.field)?;
        self.board_of_field().map(|_| ())
    }

    /// The board of a board field, resolved: `[board]` (a chessboard's table) or
    /// [`default_board`]; `None` for a room. `[board]` beside a room, a board read `from` a
    /// file or of another kind than a chessboard is refused.
    pub fn board_of_field(&self) -> Result<Option<Board>, ConfigError> {
        if self.field.kind == FieldKind::Room {
            let (f, d) = (&self.field, FieldConfig::default());
            let board_keys = [
                ("field.placements", f.placements != d.placements),
                ("field.range_mm", f.range_mm != d.range_mm),
                ("field.max_tilt_deg", f.max_tilt_deg != d.max_tilt_deg),
                ("field.max_pitch_deg", f.max_pitch_deg != d.max_pitch_deg),
                (
                    "field.scans_per_placement",
                    f.scans_per_placement != d.scans_per_placement,
                ),
                ("field.print_scale", f.print_scale != d.print_scale),
            ];
            if let Some((key, _)) = board_keys.iter().find(|(_, given)| *given) {
                return Err(ConfigError::new(
                    *key,
                    "given",
                    "a key of a board field: set [field] kind = \"board\"",
                ));
            }
            return match &self.board {
                Some(_) => Err(ConfigError::new(
                    "board",
                    "a table",
                    "only for [field] kind = \"board\" (the room's field is its targets)",
                )),
                None => Ok(None),
            };
        }
        let given = self.board.clone().unwrap_or_else(default_board);
        if let Some(f) = &given.from {
            return Err(ConfigError::new(
                "board.from",
                f,
                "the simulator needs the board's own keys (kind, inner_corners, square_mm)",
            ));
        }
        let board = given
            .table()
            .map_err(|e| ConfigError::new("board", "the table", e))?;
        board
            .planar()
            .map_err(|e| ConfigError::new("board", "the table", e))?;
        Ok(Some(board))
    }
}

// The checks of one value each, shared by the sections.
fn pos(key: &str, v: f64) -> Result<(), ConfigError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(ConfigError::new(key, v, "must be a positive number"))
    }
}
fn nonneg(key: &str, v: f64) -> Result<(), ConfigError> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(ConfigError::new(key, v, "must be zero or positive"))
    }
}
fn unit(key: &str, v: f64) -> Result<(), ConfigError> {
    if v.is_finite() && (0.0..=1.0).contains(&v) {
        Ok(())
    } else {
        Err(ConfigError::new(key, v, "must be between 0 and 1"))
    }
}
fn range(key: &str, r: [f64; 2]) -> Result<(), ConfigError> {
    if r.iter().all(|v| v.is_finite() && *v > 0.0) && r[0] <= r[1] {
        Ok(())
    } else {
        Err(ConfigError::new(
            key,
            format!("[{}, {}]", r[0], r[1]),
            "must be two positive numbers, the first not larger",
        ))
    }
}
fn finite3(key: &str, v: [f64; 3]) -> Result<(), ConfigError> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(ConfigError::new(
            key,
            format!("{v:?}"),
            "must be finite numbers",
        ))
    }
}

/// `[field]`: the placements, their ranges and tilts, the print scale (checked whatever
/// the kind; the defaults pass).
fn validate_field(f: &FieldConfig) -> Result<(), ConfigError> {
    if !(3..=100).contains(&f.placements) {
        return Err(ConfigError::new(
            "field.placements",
            f.placements,
            "expected 3 to 100 placements of the board",
        ));
    }
    range("field.range_mm", f.range_mm)?;
    if !(f.range_mm[0] >= 200.0 && f.range_mm[1] <= 2000.0) {
        return Err(ConfigError::new(
            "field.range_mm",
            format!("[{}, {}]", f.range_mm[0], f.range_mm[1]),
            "expected distances from 200 to 2000 mm (the wall stands at 2500 mm)",
        ));
    }
    if !(f.max_tilt_deg.is_finite() && (0.0..=60.0).contains(&f.max_tilt_deg)) {
        return Err(ConfigError::new(
            "field.max_tilt_deg",
            f.max_tilt_deg,
            "expected 0 to 60 degrees",
        ));
    }
    if let Some(p) = f
        .max_pitch_deg
        .filter(|p| !(p.is_finite() && (0.0..=60.0).contains(p)))
    {
        return Err(ConfigError::new(
            "field.max_pitch_deg",
            p,
            "expected 0 to 60 degrees",
        ));
    }
    if !(1..=1000).contains(&f.scans_per_placement) {
        return Err(ConfigError::new(
            "field.scans_per_placement",
            f.scans_per_placement,
            "expected 1 to 1000 scans at each placement of the board",
        ));
    }
    if !(f.print_scale.is_finite() && (0.5..=1.5).contains(&f.print_scale)) {
        return Err(ConfigError::new(
            "field.print_scale",
            f.print_scale,
            "expected the printed size over the given one, 0.5 to 1.5",
        ));
    }
    Ok(())
}

/// `[room]`: sizes, tilt, bulge and albedos.
fn validate_room(r: &RoomConfig) -> Result<(), ConfigError> {
    pos("room.wall_length_mm", r.wall_length_mm)?;
    pos("room.wall_height_mm", r.wall_height_mm)?;
    nonneg("room.max_tilt_deg", r.max_tilt_deg)?;
    if r.max_tilt_deg > 10.0 {
        return Err(ConfigError::new(
            "room.max_tilt_deg",
            r.max_tilt_deg,
            "a room corner tilted by more than 10° is not a room corner",
        ));
    }
    nonneg("room.max_bulge_mm", r.max_bulge_mm)?;
    if r.max_bulge_mm > 0.05 * r.wall_length_mm.min(r.wall_height_mm) {
        return Err(ConfigError::new(
            "room.max_bulge_mm",
            r.max_bulge_mm,
            "larger than 5 % of the wall size: not a plane",
        ));
    }
    unit("room.wall_albedo", r.wall_albedo)?;
    unit("room.floor_albedo", r.floor_albedo)?;
    unit("room.texture_amplitude", r.texture_amplitude)?;
    Ok(())
}

/// `[targets]`: how many targets, how many coded, and the code table.
fn validate_target_codes(t: &TargetConfig) -> Result<(), ConfigError> {
    if t.count == 0 {
        return Err(ConfigError::new(
            "targets.count",
            t.count,
            "needs at least one target",
        ));
    }
    if t.coded > t.count {
        return Err(ConfigError::new(
            "targets.coded",
            t.coded,
            format!("more coded targets than targets ({})", t.count),
        ));
    }
    if !(t.code_bits == 12 || t.code_bits == 14) {
        return Err(ConfigError::new(
            "targets.code_bits",
            t.code_bits,
            "AICON rings have 12 or 14 bits",
        ));
    }
    let ncodes = crate::coded_target::code_table(t.code_bits).codes.len();
    if t.coded > ncodes {
        return Err(ConfigError::new(
            "targets.coded",
            t.coded,
            format!("the {}-bit table has only {ncodes} codes", t.code_bits),
        ));
    }
    Ok(())
}

/// `[targets]`: dot, ring and background radii, grid, print.
fn validate_target_geometry(t: &TargetConfig) -> Result<(), ConfigError> {
    pos("targets.dot_radius_mm", t.dot_radius_mm)?;
    pos("targets.grid_spacing_mm", t.grid_spacing_mm)?;
    nonneg("targets.edge_margin_mm", t.edge_margin_mm)?;
    if !(t.ring_inner > 1.0) {
        return Err(ConfigError::new(
            "targets.ring_inner",
            t.ring_inner,
            "the code ring must start outside the dot (> 1 dot radius)",
        ));
    }
    if !(t.ring_outer > t.ring_inner) {
        return Err(ConfigError::new(
            "targets.ring_outer",
            t.ring_outer,
            format!("must exceed targets.ring_inner ({})", t.ring_inner),
        ));
    }
    if !(t.background > t.ring_outer) {
        return Err(ConfigError::new(
            "targets.background",
            t.background,
            format!("must exceed targets.ring_outer ({})", t.ring_outer),
        ));
    }
    if !(t.plain_background > 1.0) {
        return Err(ConfigError::new(
            "targets.plain_background",
            t.plain_background,
            "must exceed the dot (> 1 dot radius)",
        ));
    }
    if t.grid_spacing_mm < 2.0 * t.background * t.dot_radius_mm {
        return Err(ConfigError::new(
            "targets.grid_spacing_mm",
            t.grid_spacing_mm,
            format!(
                "targets of diameter {} mm would overlap",
                2.0 * t.background * t.dot_radius_mm
            ),
        ));
    }
    unit("targets.black_albedo", t.black_albedo)?;
    nonneg("targets.retro_gain", t.retro_gain)?;
    Ok(())
}

/// `[balls]`: ball and stem sizes and albedos.
fn validate_balls(b: &BallConfig) -> Result<(), ConfigError> {
    pos("balls.diameter_mm", b.diameter_mm)?;
    range("balls.standoff_range_mm", b.standoff_range_mm)?;
    if b.standoff_range_mm[0] <= 0.5 * b.diameter_mm {
        return Err(ConfigError::new(
            "balls.standoff_range_mm",
            format!("[{}, {}]", b.standoff_range_mm[0], b.standoff_range_mm[1]),
            format!(
                "a standoff under the ball radius ({} mm) puts the ball inside the wall",
                0.5 * b.diameter_mm
            ),
        ));
    }
    pos("balls.stem_radius_mm", b.stem_radius_mm)?;
    if b.stem_radius_mm >= 0.5 * b.diameter_mm {
        return Err(ConfigError::new(
            "balls.stem_radius_mm",
            b.stem_radius_mm,
            "the stem must be thinner than the ball",
        ));
    }
    unit("balls.albedo", b.albedo)?;
    unit("balls.stem_albedo", b.stem_albedo)?;
    nonneg("balls.clearance_mm", b.clearance_mm)?;
    Ok(())
}

/// `[balls]`: explicit placements, how many balls, the check balls.
fn validate_ball_placements(b: &BallConfig) -> Result<(), ConfigError> {
    if let Some(ps) = &b.placements {
        for (i, p) in ps.iter().enumerate() {
            if !["wall1", "wall2", "floor"].contains(&p.surface.as_str()) {
                return Err(ConfigError::new(
                    format!("balls.placements[{i}].surface"),
                    &p.surface,
                    "must be wall1, wall2 or floor",
                ));
            }
            if !(p.standoff_mm.is_finite() && p.standoff_mm > 0.5 * b.diameter_mm) {
                return Err(ConfigError::new(
                    format!("balls.placements[{i}].standoff_mm"),
                    p.standoff_mm,
                    format!(
                        "under the ball radius ({} mm): the ball is inside the wall",
                        0.5 * b.diameter_mm
                    ),
                ));
            }
        }
    } else if b.count == 0 {
        return Err(ConfigError::new(
            "balls.count",
            b.count,
            "needs at least 3 balls",
        ));
    }
    let nballs = b.placements.as_ref().map_or(b.count, |p| p.len());
    if nballs < 3 {
        return Err(ConfigError::new(
            "balls.count",
            nballs,
            "needs at least 3 balls",
        ));
    }
    for &c in &b.check_balls {
        if c == 0 || c as usize > nballs {
            return Err(ConfigError::new(
                "balls.check_balls",
                c,
                format!("no such ball (1..={nballs})"),
            ));
        }
    }
    Ok(())
}

/// `[distances]`: caliper σ and lengths.
fn validate_distances(d: &DistanceConfig) -> Result<(), ConfigError> {
    pos("distances.sigma_mm", d.sigma_mm).or_else(|e| {
        if d.sigma_mm == 0.0 {
            Ok(())
        } else {
            Err(e)
        }
    })?;
    range("distances.length_range_mm", d.length_range_mm)?;
    Ok(())
}

/// `[camera]`: image size, pixel, intrinsics and the right camera's pose.
fn validate_camera(c: &CameraConfig) -> Result<(), ConfigError> {
    if c.width < 16 || c.width > 20000 {
        return Err(ConfigError::new(
            "camera.width",
            c.width,
            "must be between 16 and 20000 pixels",
        ));
    }
    if c.height < 16 || c.height > 20000 {
        return Err(ConfigError::new(
            "camera.height",
            c.height,
            "must be between 16 and 20000 pixels",
        ));
    }
    pos("camera.pixel_size_mm", c.pixel_size_mm)?;
    pos("camera.nominal_c_mm", c.nominal_c_mm)?;
    let n = c.model.parameter_names().len();
    for (name, i) in [("left", &c.left), ("right", &c.right)] {
        if i.params.len() != n {
            return Err(ConfigError::new(
                format!("camera.{name}.params"),
                format!("{} numbers", i.params.len()),
                format!(
                    "must be the {n} parameters of model '{}' ({})",
                    c.model,
                    c.model.parameter_names().join(", ")
                ),
            ));
        }
        if !i.params.iter().all(|v| v.is_finite()) {
            return Err(ConfigError::new(
                format!("camera.{name}.params"),
                format!("{:?}", i.params),
                "must be finite numbers",
            ));
        }
        pos(&format!("camera.{name}.params[0] (c or fx)"), i.params[0])?;
    }
    finite3("camera.right_offset_mm", c.right_offset_mm)?;
    finite3("camera.right_opk_deg", c.right_opk_deg)?;
    Ok(())
}

/// `[[lrfs]]`: distinct ids of letters, digits, `_` or `-` other than `lrf`, each sensor's
/// keys as `[lrf]`'s are checked (an error names its entry).
fn validate_range_sensors(lrfs: &[RangeSensorConfig]) -> Result<(), ConfigError> {
    for (k, r) in lrfs.iter().enumerate() {
        let safe = !r.id.is_empty()
            && r.id
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-');
        if !safe || r.id == "lrf" || lrfs[..k].iter().any(|o| o.id == r.id) {
            return Err(ConfigError::new(
                format!("lrfs[{k}].id"),
                format!("{:?}", r.id),
                "must be a new id of letters, digits, '_' or '-' (not \"lrf\" nor another's)",
            ));
        }
        let named = |e: ConfigError| {
            ConfigError::new(
                format!("lrfs[{k}] ({})", r.id),
                e.to_string(),
                "as [lrf]'s keys",
            )
        };
        validate_lrf_ranges(&r.lrf).map_err(named)?;
        validate_lrf_servo(&r.lrf).map_err(named)?;
    }
    Ok(())
}

/// `[[rig.cameras]]`: distinct ids other than the pair's, finite poses, intrinsics of the
/// model's count.
fn validate_rig(c: &CameraConfig, r: &RigConfig) -> Result<(), ConfigError> {
    let n = c.model.parameter_names().len();
    for (i, cam) in r.cameras.iter().enumerate() {
        let key = |k: &str| format!("rig.cameras[{i}].{k}");
        let taken = ["left", "right"].contains(&cam.id.as_str())
            || r.cameras[..i].iter().any(|o| o.id == cam.id);
        if cam.id.is_empty()
            || taken
            || !cam
                .id
                .chars()
                .all(|ch| ch.is_ascii_alphanumeric() || ch == '_' || ch == '-')
        {
            return Err(ConfigError::new(
                key("id"),
                format!("{:?}", cam.id),
                "must be a new camera id of letters, digits, '_' or '-' (not left, right or another camera's)",
            ));
        }
        finite3(&key("opk_deg"), cam.opk_deg)?;
        finite3(&key("t_mm"), cam.t_mm)?;
        if let Some(p) = &cam.params {
            if p.len() != n || !p.iter().all(|v| v.is_finite()) || p[0] <= 0.0 {
                return Err(ConfigError::new(
                    key("params"),
                    format!("{p:?}"),
                    format!(
                        "must be the {n} finite parameters of model '{}' ({}), the first positive",
                        c.model,
                        c.model.parameter_names().join(", ")
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// `[stations]`: the main station and the convergent network.
fn validate_stations(s: &StationConfig) -> Result<(), ConfigError> {
    finite3("stations.main_centre_mm", s.main_centre_mm)?;
    finite3("stations.main_look_at_mm", s.main_look_at_mm)?;
    finite3("stations.look_at_mm", s.look_at_mm)?;
    if s.main_centre_mm == s.main_look_at_mm {
        return Err(ConfigError::new(
            "stations.main_look_at_mm",
            format!("{:?}", s.main_look_at_mm),
            "equals the main station's centre",
        ));
    }
    if s.convergent > 0 && s.heights_mm.is_empty() {
        return Err(ConfigError::new(
            "stations.heights_mm",
            "[]",
            "needs at least one height",
        ));
    }
    if s.convergent > 0 && s.rolls_deg.is_empty() {
        return Err(ConfigError::new(
            "stations.rolls_deg",
            "[]",
            "needs at least one roll",
        ));
    }
    for (i, h) in s.heights_mm.iter().enumerate() {
        pos(&format!("stations.heights_mm[{i}]"), *h)?;
    }
    range("stations.distance_range_mm", s.distance_range_mm)?;
    nonneg("stations.look_jitter_mm", s.look_jitter_mm)?;
    nonneg("stations.min_wall_clearance_mm", s.min_wall_clearance_mm)?;
    nonneg("stations.azimuth_span_deg", s.azimuth_span_deg)?;
    Ok(())
}

/// `[render]`: supersampling, light, blur, vignetting and sensor noise.
fn validate_render(rc: &RenderConfig) -> Result<(), ConfigError> {
    if rc.supersampling == 0 || rc.supersampling > 64 {
        return Err(ConfigError::new(
            "render.supersampling",
            rc.supersampling,
            "must be between 1 and 64",
        ));
    }
    nonneg("render.flash_at_1m", rc.flash_at_1m)?;
    nonneg("render.ambient", rc.ambient)?;
    nonneg("render.blur_sigma_px", rc.blur_sigma_px)?;
    if rc.blur_sigma_px > 20.0 {
        return Err(ConfigError::new(
            "render.blur_sigma_px",
            rc.blur_sigma_px,
            "more than 20 px of blur",
        ));
    }
    unit("render.vignetting", rc.vignetting)?;
    pos("render.full_well_e", rc.full_well_e)?;
    nonneg("render.read_noise_e", rc.read_noise_e)?;
    Ok(())
}

/// `[lrf]`: beams, ranges, accuracy, footprint and reflectivity.
fn validate_lrf_ranges(l: &LrfConfig) -> Result<(), ConfigError> {
    if l.beams == 0 {
        return Err(ConfigError::new(
            "lrf.beams",
            l.beams,
            "needs at least one beam",
        ));
    }
    pos("lrf.angle_increment_deg", l.angle_increment_deg)?;
    if !l.angle_min_deg.is_finite() || l.angle_min_deg < -180.0 {
        return Err(ConfigError::new(
            "lrf.angle_min_deg",
            l.angle_min_deg,
            "must be at least -180",
        ));
    }
    pos("lrf.max_range_mm", l.max_range_mm)?;
    nonneg("lrf.min_range_mm", l.min_range_mm)?;
    if l.min_range_mm >= l.max_range_mm {
        return Err(ConfigError::new(
            "lrf.min_range_mm",
            l.min_range_mm,
            format!("not under lrf.max_range_mm ({})", l.max_range_mm),
        ));
    }
    nonneg("lrf.accuracy_near_mm", l.accuracy_near_mm)?;
    nonneg("lrf.accuracy_far_fraction", l.accuracy_far_fraction)?;
    pos("lrf.accuracy_sigmas", l.accuracy_sigmas)?;
    nonneg("lrf.beam_width_deg", l.beam_width_deg)?;
    unit("lrf.min_reflectivity", l.min_reflectivity)?;
    Ok(())
}

/// `[lrf]`: the servo sweep (then the extrinsic and the mount).
fn validate_lrf_servo(l: &LrfConfig) -> Result<(), ConfigError> {
    pos("lrf.servo_step_deg", l.servo_step_deg)?;
    pos("lrf.servo_resolution_deg", l.servo_resolution_deg)?;
    nonneg("lrf.servo_sigma_deg", l.servo_sigma_deg)?;
    pos("lrf.scan_period_s", l.scan_period_s)?;
    if !l.servo_time_offset_s.is_finite() || l.servo_time_offset_s.abs() > 1.0 {
        return Err(ConfigError::new(
            "lrf.servo_time_offset_s",
            l.servo_time_offset_s,
            "expected a finite offset of at most ±1 s",
        ));
    }
    if l.servo_time_offset_s != 0.0 && !l.continuous_sweep {
        return Err(ConfigError::new(
            "lrf.servo_time_offset_s",
            l.servo_time_offset_s,
            "only a continuous sweep shows it: set lrf.continuous_sweep = true",
        ));
    }
    if !(1..=16).contains(&l.servo_passes) {
        return Err(ConfigError::new(
            "lrf.servo_passes",
            l.servo_passes,
            "expected 1 to 16 passes",
        ));
    }
    pos("lrf.beam_time_s", l.beam_time_s)?;
    if l.beam_time_s * l.beams.saturating_sub(1) as f64 > l.scan_period_s {
        return Err(ConfigError::new(
            "lrf.beam_time_s",
            l.beam_time_s,
            format!(
                "the {} beams would take longer than lrf.scan_period_s ({})",
                l.beams, l.scan_period_s
            ),
        ));
    }
    if !(l.servo_start_deg.is_finite()
        && l.servo_end_deg.is_finite()
        && l.servo_start_deg <= l.servo_end_deg)
    {
        return Err(ConfigError::new(
            "lrf.servo_end_deg",
            l.servo_end_deg,
            format!(
                "must not be under lrf.servo_start_deg ({})",
                l.servo_start_deg
            ),
        ));
    }
    if (l.servo_end_deg - l.servo_start_deg) / l.servo_step_deg > 100_000.0 {
        return Err(ConfigError::new(
            "lrf.servo_step_deg",
            l.servo_step_deg,
            "more than 100000 scans",
        ));
    }
    if l.kind == LrfKind::Fixed && !(1..=1000).contains(&l.scans_per_station) {
        return Err(ConfigError::new(
            "lrf.scans_per_station",
            l.scans_per_station,
            "expected 1 to 1000 scans at each station",
        ));
    }
    validate_lrf_mount(l)
}

/// `[lrf]`: the extrinsic, and the mount and range errors (zero unless `mount_errors`,
/// within the bounds of a mount error).
fn validate_lrf_mount(l: &LrfConfig) -> Result<(), ConfigError> {
    finite3("lrf.extrinsic_opk_deg", l.extrinsic_opk_deg)?;
    finite3("lrf.extrinsic_t_mm", l.extrinsic_t_mm)?;
    if !l.mount_errors {
        let d = REALISTIC_MOUNT;
        for (key, v, default) in [
            (
                "lrf.mount_offset_mm[0]",
                l.mount_offset_mm[0],
                d.offset_mm[0],
            ),
            (
                "lrf.mount_offset_mm[1]",
                l.mount_offset_mm[1],
                d.offset_mm[1],
            ),
            (
                "lrf.mount_offset_mm[2]",
                l.mount_offset_mm[2],
                d.offset_mm[2],
            ),
            ("lrf.mount_tilt_x_deg", l.mount_tilt_x_deg, d.tilt_x_deg),
            ("lrf.mount_tilt_z_deg", l.mount_tilt_z_deg, d.tilt_z_deg),
            ("lrf.servo_scale", l.servo_scale, d.servo_scale),
            ("lrf.range_offset_mm", l.range_offset_mm, d.range_offset_mm),
            ("lrf.range_scale", l.range_scale, d.range_scale),
        ] {
            if v != default && v != 0.0 {
                return Err(ConfigError::new(
                    key,
                    v,
                    "lrf.mount_errors = false makes every mount and range error zero: remove this key, or set mount_errors = true",
                ));
            }
        }
    }
    finite3("lrf.mount_offset_mm", l.mount_offset_mm)?;
    for (k, v) in l.mount_offset_mm.iter().enumerate() {
        if v.abs() > 100.0 {
            return Err(ConfigError::new(
                [
                    "lrf.mount_offset_mm[0]",
                    "lrf.mount_offset_mm[1]",
                    "lrf.mount_offset_mm[2]",
                ][k],
                *v,
                "a scanner more than 100 mm off its servo axis is not a mount error",
            ));
        }
    }
    for (key, v, max, what) in [
        ("lrf.mount_tilt_x_deg", l.mount_tilt_x_deg, 5.0, "degrees"),
        ("lrf.mount_tilt_z_deg", l.mount_tilt_z_deg, 5.0, "degrees"),
        ("lrf.servo_scale", l.servo_scale, 0.05, "(a fraction)"),
        ("lrf.range_offset_mm", l.range_offset_mm, 100.0, "mm"),
        ("lrf.range_scale", l.range_scale, 0.05, "(a fraction)"),
    ] {
        if !(v.abs() <= max) {
            return Err(ConfigError::new(
                key,
                v,
                format!("expected a finite value within ±{max} {what}"),
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_round_trip_through_toml() {
        let cfg = SimConfig::default();
        cfg.validate().unwrap();
        let back = SimConfig::from_toml_str(&cfg.to_toml_string()).unwrap();
        assert_eq!(back, cfg);
        // A partial file keeps the other defaults.
        let partial =
            SimConfig::from_toml_str("[balls]\nstandoff_range_mm = [70.0, 150.0]\n").unwrap();
        assert_eq!(partial.balls.standoff_range_mm, [70.0, 150.0]);
        assert_eq!(partial.balls.count, 16);
        assert_eq!(partial.targets, TargetConfig::default());
    }

    #[test]
    fn each_section_refuses_its_bad_values_naming_the_key() {
        let cases: Vec<(&str, &str)> = vec![
            ("[room]\nmax_tilt_deg = 11.0\n", "room.max_tilt_deg = 11: a room corner tilted by more than 10° is not a room corner"),
            ("[targets]\ncode_bits = 13\n", "targets.code_bits = 13: AICON rings have 12 or 14 bits"),
            ("[targets]\nring_outer = 1.5\n", "targets.ring_outer = 1.5: must exceed targets.ring_inner (2)"),
            ("[balls]\nstem_radius_mm = 30.0\n", "balls.stem_radius_mm = 30: the stem must be thinner than the ball"),
            ("[balls]\ncheck_balls = [17]\n", "balls.check_balls = 17: no such ball (1..=16)"),
            ("[distances]\nsigma_mm = -1.0\n", "distances.sigma_mm = -1: must be a positive number"),
            ("[camera]\nwidth = 8\n", "camera.width = 8: must be between 16 and 20000 pixels"),
            ("[stations]\nconvergent = 2\nrolls_deg = []\n", "stations.rolls_deg = []: needs at least one roll"),
            ("[render]\nsupersampling = 0\n", "render.supersampling = 0: must be between 1 and 64"),
            ("[lrf]\nmin_range_mm = 6000.0\n", "lrf.min_range_mm = 6000: not under lrf.max_range_mm (5600)"),
            ("[lrf]\nservo_end_deg = -200.0\n", "lrf.servo_end_deg = -200: must not be under lrf.servo_start_deg (-180)"),
            ("[field]\nkind = \"board\"\nplacements = 2\n", "field.placements = 2: expected 3 to 100 placements of the board"),
            ("[field]\nplacements = 5\n", "field.placements = given: a key of a board field: set [field] kind = \"board\""),
            ("[field]\nrange_mm = [100.0, 900.0]\n", "field.range_mm = [100, 900]: expected distances from 200 to 2000 mm (the wall stands at 2500 mm)"),
            ("[field]\nkind = \"board\"\nscans_per_placement = 0\n", "field.scans_per_placement = 0: expected 1 to 1000 scans at each placement of the board"),
            ("[field]\nmax_tilt_deg = 70.0\n", "field.max_tilt_deg = 70: expected 0 to 60 degrees"),
            ("[field]\nprint_scale = 0.0\n", "field.print_scale = 0: expected the printed size over the given one, 0.5 to 1.5"),
            ("[board]\nkind = \"chessboard\"\ninner_corners = [7, 5]\nsquare_mm = 20.0\n", "board = a table: only for [field] kind = \"board\" (the room's field is its targets)"),
            ("[field]\nkind = \"board\"\n[board]\nkind = \"chessboard\"\ninner_corners = [7, 5]\n", "board = the table: [board] kind = \"chessboard\" needs square_mm"),
            ("[field]\nkind = \"board\"\n[board]\nkind = \"aprilgrid\"\ntags = [6, 6]\ntag_mm = 88.0\ntag_spacing = 0.3\ntag_family = \"tag16h5\"\n", "board = the table: [board]: marker dictionary 'tag16h5': not one pingcal reads (it reads DICT_4X4_50, DICT_4X4_100, DICT_4X4_250, DICT_4X4_1000, DICT_5X5_50, DICT_5X5_100, DICT_5X5_250, DICT_5X5_1000, DICT_6X6_50, DICT_6X6_100, DICT_6X6_250, DICT_6X6_1000, DICT_7X7_50, DICT_7X7_100, DICT_7X7_250, DICT_7X7_1000, DICT_ARUCO_ORIGINAL, tag36h11)"),
            ("[field]\nkind = \"board\"\n[board]\nfrom = \"target.yaml\"\n", "board.from = target.yaml: the simulator needs the board's own keys (kind, inner_corners, square_mm)"),
        ];
        for (toml, want) in cases {
            assert_eq!(SimConfig::from_toml_str(toml).unwrap_err(), want, "{toml}");
        }
    }

    /// `[field]` and `[board]` are written only for a board field: a room's configuration
    /// reads and writes as before; a board field's round-trips.
    #[test]
    fn a_room_writes_no_field_and_a_board_field_round_trips() {
        let room = SimConfig::default().to_toml_string();
        assert!(
            !room.contains("[field]") && !room.contains("[board]"),
            "{room}"
        );
        let text = "[field]\nkind = \"board\"\nprint_scale = 0.925\n[board]\nkind = \"chessboard\"\ninner_corners = [9, 6]\nsquare_mm = 20.0\n";
        let cfg = SimConfig::from_toml_str(text).unwrap();
        assert_eq!(cfg.field.kind, FieldKind::Board);
        assert_eq!(
            cfg.board_of_field().unwrap(),
            Some(Board::Chessboard {
                cols: 9,
                rows: 6,
                square_mm: 20.0
            })
        );
        assert_eq!(
            SimConfig::from_toml_str(&cfg.to_toml_string()).unwrap(),
            cfg
        );
        let e = SimConfig::from_toml_str("[field]\nkind = \"boards\"\n").unwrap_err();
        assert!(
            e.contains("boards") && e.contains("room") && e.contains("board"),
            "{e}"
        );
    }

    #[test]
    fn sensor_maps_the_lrf_keys() {
        let l = LrfConfig {
            mount_offset_mm: [1.0, 2.0, 3.0],
            ..LrfConfig::default()
        };
        let s = l.sensor();
        assert_eq!(s.beams, 682);
        assert_eq!(s.header.beam_angle_deg(0), -119.53125);
        assert_eq!(s.mount.offset_mm, [1.0, 2.0, 3.0]);
        assert_eq!(s.noise, RangeNoise::urg_04lx());
        assert_eq!((s.min_range_mm, s.max_range_mm), (20.0, 5600.0));
        let quiet = LrfConfig {
            noise: false,
            ..LrfConfig::default()
        };
        assert_eq!(quiet.sensor().noise, RangeNoise::Noiseless);
    }

    #[test]
    fn range_sigma_follows_the_datasheet() {
        let l = LrfConfig::default();
        assert_eq!(l.range_sigma_mm(500.0), 10.0);
        assert!((l.range_sigma_mm(3000.0) - 30.0).abs() < 1e-12);
    }

    /// `[[rig.cameras]]` and `[[lrfs]]` (issue 52): read with their keys, written and read
    /// back the same; a bad entry named.
    #[test]
    fn more_cameras_and_range_sensors_round_trip_and_are_checked() {
        let text = "[[rig.cameras]]\nid = \"side\"\nopk_deg = [0.0, 0.0, 60.0]\nt_mm = [60.0, -25.0, 10.0]\n\n[[lrfs]]\nid = \"floor\"\nkind = \"fixed\"\nextrinsic_t_mm = [-40.0, 30.0, -150.0]\n";
        let cfg = SimConfig::from_toml_str(text).unwrap();
        cfg.validate().unwrap();
        assert_eq!(cfg.rig.cameras[0].opk_deg, [0.0, 0.0, 60.0]);
        assert_eq!(cfg.lrfs[0].id, "floor");
        assert_eq!(cfg.lrfs[0].lrf.kind, LrfKind::Fixed);
        assert_eq!(cfg.lrfs[0].lrf.extrinsic_t_mm, [-40.0, 30.0, -150.0]);
        assert_eq!(cfg.lrfs[0].lrf.beams, LrfConfig::default().beams);
        let back = SimConfig::from_toml_str(&cfg.to_toml_string()).unwrap();
        assert_eq!(back, cfg);
        let e = SimConfig::from_toml_str("[[lrfs]]\nkind = \"fixed\"\n").unwrap_err();
        assert!(e.contains("needs its id"), "{e}");
        let e = SimConfig::from_toml_str("[[lrfs]]\nid = \"x\"\nbeamz = 3\n").unwrap_err();
        assert!(
            e.contains("[[lrfs]] id = \"x\"") && e.contains("beamz"),
            "{e}"
        );
        let mut twice = cfg.clone();
        twice.lrfs.push(twice.lrfs[0].clone());
        let e = twice.validate().unwrap_err().to_string();
        assert!(e.contains("lrfs[1].id"), "{e}");
        let mut same = cfg.clone();
        same.rig.cameras[0].id = "right".into();
        let e = same.validate().unwrap_err().to_string();
        assert!(e.contains("rig.cameras[0].id"), "{e}");
    }
}
