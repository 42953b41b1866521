//! # pingcal-report: the calibration report as one self-contained HTML file
//!
//! [`render_html`] turns a [`ReportData`] (filled in by the pipeline of `crates/cli`) into a
//! single HTML5 document with inline SVG plots: no JavaScript, no network access, no external
//! fonts or style sheets, so the file can be mailed, archived or opened offline as it is.
//!
//! Sections, in order (each with an `id` anchor listed in the table of contents; the
//! verdict, when there is one, comes before them all):
//!
//! | id | heading | what it shows | drawn in |
//! |---|---|---|---|
//! | `summary` | Summary | key → value summary lines | `render/summary.rs` |
//! | `extrinsic` | Extrinsic calibration | per method: R, t (mm), ω φ κ (deg) with σ, or why the method failed | `render/extrinsic.rs` |
//! | `extrinsic_precision` | Extrinsic precision | σ of t and of the rotation per method as bars, the correlations of (θ, t) | `charts.rs` |
//! | `checks` | Check points | the paper's Figure 7: check-point error per ball and method, mean lines, tables | `render/checks.rs` |
//! | `images` | Image residuals | per image, magnified residual vectors (rejected points as red ×), RMS table | `render/images.rs` |
//! | `histogram` | Residual histogram | the image residual components with the normal density of their RMS | `charts.rs` |
//! | `coverage` | Image coverage | per image, where its accepted points fell and how many cells of a 5 × 5 grid they hit | `charts.rs` |
//! | `network` | Network | cameras and points in plan (X–Y) and elevation (X–Z), σ ellipses magnified | `render/network.rs` |
//! | `exterior` | Exterior orientation | per image: projection centre, ω φ κ, their σ | `tables.rs` |
//! | `points` | Point precision | σX σY σZ of every point, their RMS, and the relative precision | `tables.rs` |
//! | `distances` | Distances | measured and adjusted distances, the residual and its ratio to the a-priori σ | `tables.rs` |
//! | `rig` | Stereo rig | the rig's relative orientation with σ | `tables.rs` |
//! | `sensors` | Sensors of the head | every sensor's pose to the main camera and every pair's, with σ | `tables.rs` |
//! | `cloud` | LRF cloud | the LRF cloud in X–Y and X–Z with the fitted spheres at true scale | `render/cloud.rs` |
//! | `overlays` | LRF on the images | the LRF's points drawn on the photographs ([`overlay`]) | `overlay_section.rs` |
//! | `intrinsics` | Intrinsics | per camera: parameters, σ, free/fixed, high correlations | `render/intrinsics.rs` |
//! | `distortion` | Distortion profile | the radial distortion profile Δr(r) of every camera, to its sensor corner | `charts.rs` |
//! | `opencv` | OpenCV parameters | every camera in OpenCV's pinhole model with (k1, k2, p1, p2, k3) | `tables.rs` |
//! | `mount` | LRF mount and range | the joint adjustment's LRF mount and range parameters: value, σ, why any was held, the largest correlation with the extrinsic | `render/mount.rs` |
//! | `rejected` | Rejected | what was rejected and why | `render/rejected.rs` |
//! | `warnings` | Warnings | warnings of the pipeline | `render/warnings.rs` |
//! | `steps` | Pipeline steps | the pipeline log (collapsible) | `render/steps.rs` |
//!
//! The document's head, the verdict and the table of contents are `render/mod.rs`; each
//! section's module says in its doc what the section shows.
//!
//! Every user string is HTML-escaped ([`escape`]); non-finite numbers print as "—" and never
//! reach an SVG coordinate; the output is deterministic (no timestamps, no hash-map order).
//! The document is also well-formed XML (void elements are self-closed, only the five XML
//! entities are used), which the tests check.
//!
//! [`render_sphere_calib_html`] renders the report of `pingcal sphere-calib` from a
//! [`SphereCalibReport`]: the same page with that method's sections ([`sphere_calib`]).
//!
//! [`sample::sample_report`] builds a realistic synthetic [`ReportData`] for demos and tests;
//! `cargo run -p pingcal-report --example sample_report -- OUT.html` writes it, and
//! `crates/report/scripts/check-report.sh OUT.html OUT.png` screenshots it with headless
//! Chromium.

use serde::{Deserialize, Serialize};

mod charts;
mod fmt;
pub mod overlay;
mod overlay_section;
mod plot;
mod render;
pub mod sample;
mod section;
pub mod sphere_calib;
mod tables;

pub use fmt::escape;
pub use overlay::{base64, Overlay};
pub use sphere_calib::{render_sphere_calib_html, SphereCalibReport, SphereFrameRow};

/// Everything the report shows. Empty vectors render as "none" sections, never as errors.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct ReportData {
    /// Document title, e.g. "pingcal calibration — simulated test field (seed 1)".
    pub title: String,
    /// Program and version that produced the report, e.g. "pingcal 0.1.0".
    pub generator: String,
    /// The verdict on the calibration, shown first (None: not judged).
    #[serde(default)]
    pub verdict: Option<VerdictView>,
    /// Key → value lines shown at the top (σ0, RMS, mean check error …), in order.
    pub summary: Vec<(String, String)>,
    /// Pipeline log lines, in order.
    pub steps: Vec<String>,
    /// Image residuals of the bundle adjustment, one entry per image.
    pub images: Vec<ImageResiduals>,
    /// Camera stations and object points of the photogrammetric network.
    pub network: Network,
    /// The (subsampled) LRF cloud and the spheres fitted in it.
    pub cloud: CloudView,
    /// Extrinsic calibration methods ("spheres", "corner (Fan et al. 2019)" …) and their checks.
    pub methods: Vec<MethodResult>,
    /// Interior orientation per camera.
    pub intrinsics: Vec<Intrinsics>,
    /// The LRF's mount and range parameters of the joint adjustment (empty when it did not
    /// run).
    #[serde(default)]
    pub lrf_mount: Vec<MountRow>,
    /// Observations, images, balls … that were rejected, with the reason.
    pub rejected: Vec<Rejection>,
    /// Warnings of the pipeline.
    pub warnings: Vec<String>,
    /// Exterior orientation of every adjusted image.
    #[serde(default)]
    pub exterior: Vec<ExteriorRow>,
    /// The measured distances of the bundle adjustment.
    #[serde(default)]
    pub distances: Vec<DistanceRow>,
    /// The stereo rig's relative orientation (None: no rig).
    #[serde(default)]
    pub rig: Option<RigOrientation>,
    /// Every sensor of the head but the main camera (results.json's `sensors`), then every
    /// pair (`sensor_pairs`).
    #[serde(default)]
    pub sensors: Vec<SensorRow>,
    /// Every pair of sensors' relative pose.
    #[serde(default)]
    pub sensor_pairs: Vec<SensorRow>,
    /// What each export's camera model loses against pingcal's, per camera and file
    /// (shown in the `opencv` section).
    #[serde(default)]
    pub export_losses: Vec<ExportLossRow>,
    /// The LRF's points drawn on the images ([`overlay`]), the main station's first.
    #[serde(default)]
    pub overlays: Vec<Overlay>,
}

/// Exterior orientation of one image.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct ExteriorRow {
    /// Image name.
    pub name: String,
    /// Projection centre X, Y, Z in mm, photogrammetric frame.
    pub centre_mm: [f64; 3],
    /// ω, φ, κ of the rotation object → camera, degrees.
    pub opk_deg: [f64; 3],
    /// σ of the projection centre, mm (None: not adjusted, e.g. the datum image).
    pub sigma_centre_mm: Option<[f64; 3]>,
    /// σ of the small rotations about the camera's X, Y, Z axes, degrees (None: not
    /// adjusted).
    pub sigma_rotation_deg: Option<[f64; 3]>,
    /// Why there is no σ (datum, rig member …), empty otherwise.
    pub note: String,
}

/// One measured distance of the bundle adjustment.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct DistanceRow {
    /// From point (label).
    pub from: String,
    /// To point (label).
    pub to: String,
    /// Measured length, mm.
    pub measured_mm: f64,
    /// Adjusted length, mm.
    pub adjusted_mm: f64,
    /// A-priori σ of the measurement, mm.
    pub sigma_mm: f64,
}

/// The stereo rig: `p_right = R · p_left + t`.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct RigOrientation {
    /// Left (base) camera.
    pub left: String,
    /// Right (member) camera.
    pub right: String,
    /// t in mm.
    pub translation_mm: [f64; 3],
    /// ω, φ, κ of R in degrees.
    pub opk_deg: [f64; 3],
    /// Length of the baseline, mm.
    pub baseline_mm: f64,
    /// σ of t in mm (None: not computed).
    pub sigma_translation_mm: Option<[f64; 3]>,
    /// σ of the small rotations of R about the right camera's axes, degrees (None: not
    /// computed).
    pub sigma_rotation_deg: Option<[f64; 3]>,
}

/// A sensor's pose relative to the main camera (`p_main = R p_sensor + t`), or a pair's
/// (`p_a = R p_b + t`), with σ's.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct SensorRow {
    /// The sensor's id, or a pair's `a ← b`.
    pub name: String,
    /// `camera`, `rotating`, `fixed`; empty for a pair.
    pub kind: String,
    /// t in mm.
    pub translation_mm: [f64; 3],
    /// ω, φ, κ of R in degrees.
    pub opk_deg: [f64; 3],
    /// σ of t (None: not known).
    pub sigma_translation_mm: Option<[f64; 3]>,
    /// σ of ω, φ, κ, degrees (None: not known).
    pub sigma_opk_deg: Option<[f64; 3]>,
}

/// Whether to trust the calibration: `ok`, `doubtful` or `failed`, why, and the tests.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct VerdictView {
    /// `ok`, `doubtful` or `failed`.
    pub status: String,
    /// Why it is not `ok`, one sentence each.
    pub reasons: Vec<String>,
    /// What the tests of a method whose result is not the one given found (they do not
    /// change the status).
    #[serde(default)]
    pub notes: Vec<String>,
    /// The statistical tests.
    pub checks: Vec<VerdictCheckView>,
    /// Their level (probability of a false alarm each).
    pub alpha: f64,
}

/// One statistical test of the verdict.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct VerdictCheckView {
    /// What is tested.
    pub name: String,
    /// The statistic.
    pub value: f64,
    /// Its bound.
    pub bound: f64,
    /// `value ≤ bound`.
    pub passed: bool,
}

/// Image residuals of one image.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct ImageResiduals {
    /// Image name (file name or camera/station label).
    pub name: String,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Measured image points with their residuals.
    pub points: Vec<ImagePoint>,
}

/// One measured image point.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct ImagePoint {
    /// Point label (target or ball id).
    pub label: String,
    /// Kind of point: "coded", "plain" or "ball" (anything else is drawn grey).
    pub kind: String,
    /// Measured x in pixels (image right).
    pub x: f64,
    /// Measured y in pixels (image down).
    pub y: f64,
    /// Residual x in pixels, observed − computed.
    pub dx: f64,
    /// Residual y in pixels, observed − computed.
    pub dy: f64,
    /// True when the observation was rejected (data snooping …); not in the RMS.
    pub rejected: bool,
}

/// The photogrammetric network.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Network {
    /// Camera stations (exposures).
    pub cameras: Vec<CameraStation>,
    /// Object points (targets and ball centres).
    pub points: Vec<NetworkPoint>,
}

/// One camera station (exposure).
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct CameraStation {
    /// Station or image name.
    pub name: String,
    /// Projection centre in mm, photogrammetric frame.
    pub centre: [f64; 3],
    /// Rows = camera axes X (right), Y (forward), Z (up) expressed in the photogrammetric frame.
    pub rotation: [[f64; 3]; 3],
    /// True for the main station (where the LRF scanned); highlighted in the plots.
    pub main: bool,
}

/// One object point of the network.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct NetworkPoint {
    /// Point label.
    pub label: String,
    /// Kind of point: "coded", "plain" or "ball".
    pub kind: String,
    /// Coordinates in mm, photogrammetric frame.
    pub xyz: [f64; 3],
    /// Standard deviations of X, Y, Z in mm (0 or non-finite: not drawn).
    pub sigma: [f64; 3],
}

/// The LRF cloud and its spheres.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct CloudView {
    /// Points in the LRF frame, mm, already subsampled by the caller to ≤ 50k.
    pub points: Vec<[f32; 3]>,
    /// Spheres (balls) fitted in the cloud.
    pub spheres: Vec<Sphere>,
}

/// One sphere fitted in the LRF cloud.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Sphere {
    /// Sphere label (as found in the cloud).
    pub label: String,
    /// Centre in mm, LRF frame.
    pub centre: [f64; 3],
    /// Radius in mm.
    pub radius: f64,
    /// Standard deviations of the centre in mm.
    pub sigma: [f64; 3],
    /// Number of inlier points of the fit.
    pub inliers: usize,
    /// Label of the photogrammetric ball this sphere was matched to, if any.
    pub matched_to: Option<String>,
}

/// Result of one extrinsic calibration method.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct MethodResult {
    /// Method name, e.g. "spheres" or "corner (Fan et al. 2019)".
    pub name: String,
    /// Rotation R of `p_camera = R · p_lrf + t`.
    pub rotation: [[f64; 3]; 3],
    /// Translation t in mm.
    pub translation_mm: [f64; 3],
    /// ω, φ, κ in degrees.
    pub opk_deg: [f64; 3],
    /// σ of t in mm, when estimated.
    pub sigma_translation_mm: Option<[f64; 3]>,
    /// σ of ω, φ, κ in degrees, when estimated.
    pub sigma_rotation_deg: Option<[f64; 3]>,
    /// Control / check / leave-one-out table.
    pub checks: Vec<CheckRow>,
    /// Mean check-point error in mm.
    pub mean_check_error_mm: Option<f64>,
    /// Standard deviation of the check-point error in mm.
    pub sd_check_error_mm: Option<f64>,
    /// When the method failed: why (the other fields are then not shown).
    pub error: Option<String>,
    /// Correlation matrix (6 × 6, row by row) of (θx, θy, θz, tx, ty, tz): the small
    /// rotations about the camera axes and the translation (None: not computed).
    #[serde(default)]
    pub correlation: Option<Vec<Vec<f64>>>,
}

/// One row of a control/check table.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct CheckRow {
    /// Ball (point) id.
    pub id: String,
    /// Difference in X, mm.
    pub dx_mm: f64,
    /// Difference in Y, mm.
    pub dy_mm: f64,
    /// Difference in Z, mm.
    pub dz_mm: f64,
    /// Length of the difference, mm.
    pub error_mm: f64,
    /// "check", "control" or "loo" (leave-one-out).
    pub role: String,
}

/// Interior orientation of one camera.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Intrinsics {
    /// Camera name.
    pub camera: String,
    /// Parameter names (c, xp, yp, k1 …).
    pub names: Vec<String>,
    /// Units per parameter ("mm", "px", "" …).
    pub units: Vec<String>,
    /// Values per parameter.
    pub values: Vec<f64>,
    /// Standard deviations per parameter (0 or non-finite for fixed parameters).
    pub sigmas: Vec<f64>,
    /// True when the parameter was estimated.
    pub free: Vec<bool>,
    /// Pairs of parameters with their correlation; |r| > 0.9 are highlighted.
    pub high_correlations: Vec<(String, String, f64)>,
    /// Radial distance from the principal point to the farthest sensor corner, mm (None:
    /// unknown; the distortion profile is then not drawn).
    #[serde(default)]
    pub r_max_mm: Option<f64>,
    /// The same camera in OpenCV's pinhole model (None: not converted).
    #[serde(default)]
    pub opencv: Option<OpenCvParams>,
    /// The camera model's name ([`pingcal_camera::ModelKind::name`]).
    #[serde(default)]
    pub model: String,
    /// The lens's mapping for models without K1–K3: (radius from the principal point in
    /// px, angle of the ray off the optical axis in degrees) along the image's longest
    /// half-diagonal, and the focal length in px (the distortion section draws it against
    /// the pinhole's and the equidistant lens's).
    #[serde(default)]
    pub lens_curve: Option<(Vec<(f64, f64)>, f64)>,
}

/// A camera in OpenCV's model: the camera matrix and its distortion coefficients.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct OpenCvParams {
    /// fx, px.
    pub fx: f64,
    /// fy, px.
    pub fy: f64,
    /// cx, px.
    pub cx: f64,
    /// cy, px.
    pub cy: f64,
    /// The distortion coefficients in OpenCV's order (k1, k2, p1, p2, k3, then k4–k6 and
    /// s1–s4 where the model has them; k1–k4 for the fisheye model).
    pub dist: Vec<f64>,
    /// `plumb_bob`, `rational_polynomial`, `thin_prism` or `fisheye`.
    #[serde(default)]
    pub distortion_model: String,
    /// Image width, px.
    pub width: u32,
    /// Image height, px.
    pub height: u32,
}

/// How far an exported camera model puts pingcal's rays from their pixels, over a grid of
/// the whole image.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct ExportLossRow {
    /// Camera name.
    pub camera: String,
    /// The files that carry the model (`opencv/…, ros/camera_info_…`).
    pub files: String,
    /// The model as written (`plumb_bob: k1 k2 p1 p2 k3`, `radtan refit`, …).
    pub model: String,
    /// The largest distance, px.
    pub max_px: f64,
    /// The root mean square distance, px.
    pub rms_px: f64,
}

/// One parameter of the LRF's mount and range model from the joint adjustment.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct MountRow {
    /// Its name (`offset_x`, …, `range_scale`).
    pub name: String,
    /// Value.
    pub value: f64,
    /// σ (None when held).
    pub sigma: Option<f64>,
    /// Unit ("mm", "°", "").
    pub unit: String,
    /// Why it was held (None: estimated).
    pub held: Option<String>,
    /// Its largest correlation with a component of the extrinsic: (component, r).
    pub max_corr_extrinsic: Option<(String, f64)>,
}

/// Something the pipeline rejected.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Rejection {
    /// What was rejected (observation, image, ball …).
    pub what: String,
    /// Why.
    pub why: String,
}

/// Renders the whole report as one self-contained HTML5 document (deterministic).
pub fn render_html(data: &ReportData) -> String {
    render::document(data)
}
