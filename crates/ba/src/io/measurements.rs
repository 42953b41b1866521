//! pingcal's own measurement file: cameras, images, image points, distances and control
//! points of a photogrammetric network, in JSON (read and written with serde).
//!
//! # The format
//!
//! A complete example (units: object space in mm, image points in pixels with the origin at
//! the centre of the top-left pixel, x right, y down, as everywhere in pingcal):
//!
//! ```json
//! {
//!   "format": "pingcal-measurements v1",
//!   "cameras": [
//!     {
//!       "name": "left",
//!       "model": "photogrammetric",
//!       "width": 1280, "height": 720, "pixel_size_mm": 0.00375,
//!       "intrinsics": {"c": 2.45, "xp": 0.0, "yp": 0.0, "K1": 0.0},
//!       "calibrate": ["c", "xp", "yp", "K1", "K2", "K3", "P1", "P2"]
//!     }
//!   ],
//!   "images": [
//!     {"name": "main", "camera": "left",
//!      "pose": {"centre": [0, 0, 0], "omega_phi_kappa_deg": [0, 0, 0]}, "fixed": true},
//!     {"name": "st02", "camera": "left"}
//!   ],
//!   "image_points": [
//!     {"image": "main", "point": "17", "x": 640.25, "y": 355.5, "sigma_px": 0.05},
//!     {"image": "st02", "point": "17", "x": 512.0, "y": 300.75, "sigma_px": 0.05}
//!   ],
//!   "distances": [
//!     {"a": "17", "b": "18", "mm": 1000.12, "sigma_mm": 0.05}
//!   ],
//!   "control_points": [
//!     {"id": "17", "xyz": [0, 2000, 0], "fixed": true},
//!     {"id": "18", "xyz": [1000, 2000, 0], "sigma_mm": [0.1, 0.1, 0.1]},
//!     {"id": "19", "xyz": [0, 2500, 300]}
//!   ]
//! }
//! ```
//!
//! * `format` is optional on reading; the writer always writes it. A UTF-8 byte-order mark
//!   at the start is skipped. Numbers beyond ±[`MAX_MAGNITUDE`] (1e12) are refused.
//! * `model` (default: the photogrammetric model's) is a camera model's own name
//!   ([`crate::camera::CameraModel::name`], one line each in the camera crate's registry,
//!   [`crate::camera::kind::REGISTRY`]), and `intrinsics` holds values of its parameters by
//!   their names ([`crate::camera::CameraModel::parameter_names`]; missing ones are 0). The
//!   focal length and principal point are required: `c` for the models in mm, `fx, fy, cx,
//!   cy` for those in pixels ([`crate::camera::ModelKind::required_parameters`]).
//!
//!   `calibrate` lists the ones adjusted (self-calibration); the others are held fixed. An
//!   empty or missing `calibrate` holds the camera fixed. `width`, `height` and
//!   `pixel_size_mm` are required for every model (the pixel models use them only to
//!   describe the sensor). A name the model does not have is refused with the list of its
//!   names.
//! * `pose` (optional): the projection centre in object space and the angles ω, φ, κ in
//!   degrees with R = R_ω R_φ R_κ ([`pingcal_geometry::from_opk`]), the object → camera
//!   rotation. An image without a pose gets one from [`crate::initial`]. `fixed: true`
//!   (default false) holds the pose (datum (a) of issue 3: the main station);
//!   `fixed_centre_axes` (e.g. `"XYZ"`, `"Z"`) holds only those coordinates of the pose's
//!   centre (a GNSS-surveyed camera station), the rotation staying free.
//! * `image_points`: `sigma_px` is the standard deviation of each coordinate.
//! * `distances`: measured distance `mm` between the points `a` and `b`, with σ `sigma_mm`.
//! * `control_points`: `fixed: true` holds the point at `xyz`; `sigma_mm` (per axis) makes
//!   it a weighted control point; `fixed_axes` (e.g. `"Z"`, `"XY"`) holds only those
//!   coordinates at `xyz` exactly (the others free, or weighted by their `sigma_mm`); with
//!   none of these, `xyz` is only an approximate coordinate (an initial value for
//!   resection) and the point is free.
//!
//! # Conversion to a [`Problem`]
//!
//! [`Measurements::to_problem`] checks the references and values and builds the
//! [`Problem`]: one [`crate::problem::Camera`] per camera, one image per image, one point
//! per distinct point name (in order of first appearance in `image_points`, then control
//! points), one observation per image point. Fixed control points become
//! [`crate::problem::Point::fixed`] (a point both fixed and with σ is fixed); weighted
//! control points become [`crate::problem::PointPrior`]s and distances
//! [`crate::problem::Distance`]s, observation equations of the same adjustment.
//! Points and images without known coordinates or poses are left at zero / identity and
//! are flagged in [`Built::known_points`] / [`Built::known_poses`] for the initialiser.

use crate::camera::{CameraModel, ModelKind, PhotogrammetricCamera, PHOTOGRAMMETRIC_PARAMS};
use crate::keys::{CameraKey, ImageKey, PointKey};
use crate::problem::{Camera, Image, Observation, Point, PointPrior, Problem};
use nalgebra::{Vector2, Vector3};
use pingcal_geometry::Rigid3;
use pingcal_geometry::{from_opk, to_opk};
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, HashMap};
use std::path::Path;
use std::sync::Arc;

/// The format tag written into every file.
pub const FORMAT: &str = "pingcal-measurements v1";

/// A whole measurement file.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Measurements {
    /// Format tag ([`FORMAT`]).
    #[serde(default)]
    pub format: Option<String>,
    /// Cameras (interior orientation).
    #[serde(default)]
    pub cameras: Vec<CameraSpec>,
    /// Images.
    #[serde(default)]
    pub images: Vec<ImageSpec>,
    /// Image measurements.
    #[serde(default)]
    pub image_points: Vec<ImagePoint>,
    /// Measured distances between object points.
    #[serde(default)]
    pub distances: Vec<Distance>,
    /// Control points.
    #[serde(default)]
    pub control_points: Vec<ControlPoint>,
}

/// A camera: model, sensor and initial intrinsics.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraSpec {
    /// Name, referred to by images.
    pub name: String,
    /// Camera model: a model's own name ([`CameraModel::name`]; by default the
    /// photogrammetric model's).
    #[serde(default = "default_model")]
    pub model: String,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Pixel pitch, mm.
    pub pixel_size_mm: f64,
    /// Initial intrinsics by name (`c` required; others default to 0).
    pub intrinsics: BTreeMap<String, f64>,
    /// Names of the intrinsics to adjust.
    #[serde(default)]
    pub calibrate: Vec<String>,
}

fn default_model() -> String {
    PhotogrammetricCamera::NAME.into()
}

/// Exterior orientation as written in the file.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PoseSpec {
    /// Projection centre in object space, mm.
    pub centre: [f64; 3],
    /// ω, φ, κ in degrees (R = R_ω R_φ R_κ, object → camera).
    pub omega_phi_kappa_deg: [f64; 3],
}

impl PoseSpec {
    /// The pose.
    pub fn to_pose(&self) -> Rigid3 {
        let [o, p, k] = self.omega_phi_kappa_deg.map(f64::to_radians);
        Rigid3::from_rotation_and_centre(from_opk(o, p, k), Vector3::from(self.centre))
    }

    /// The file form of a pose.
    pub fn from_pose(pose: &Rigid3) -> Self {
        let (o, p, k) = to_opk(&pose.rotation);
        let c = pose.centre();
        Self {
            centre: [c.x, c.y, c.z],
            omega_phi_kappa_deg: [o.to_degrees(), p.to_degrees(), k.to_degrees()],
        }
    }
}

/// An image.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImageSpec {
    /// Name, referred to by image points.
    pub name: String,
    /// Name of the camera that took it.
    pub camera: String,
    /// Approximate or known pose.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pose: Option<PoseSpec>,
    /// Pose held fixed (needs `pose`).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub fixed: bool,
    /// Coordinates of the projection centre held one by one at the pose's `centre`, as
    /// letters (`"XYZ"` for a centre surveyed by GNSS, `"Z"` for a known height; needs
    /// `pose`); the rotation and the other coordinates stay free
    /// ([`crate::problem::Image::fixed_centre`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fixed_centre_axes: Option<String>,
}

/// One image measurement.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImagePoint {
    /// Image name.
    pub image: String,
    /// Point name.
    pub point: String,
    /// Pixel column (origin at the centre of the top-left pixel, right).
    pub x: f64,
    /// Pixel row (down).
    pub y: f64,
    /// Standard deviation of each coordinate, pixels.
    pub sigma_px: f64,
}

/// A measured distance between two object points.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Distance {
    /// First point.
    pub a: String,
    /// Second point.
    pub b: String,
    /// Measured distance, mm.
    pub mm: f64,
    /// Its standard deviation, mm.
    pub sigma_mm: f64,
}

/// A control point.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ControlPoint {
    /// Point name.
    pub id: String,
    /// Coordinates, mm.
    pub xyz: [f64; 3],
    /// Standard deviations per axis, mm (weighted control).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma_mm: Option<[f64; 3]>,
    /// Held fixed.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub fixed: bool,
    /// Coordinates held one by one, as letters: `"Z"` (a levelled point's height), `"XY"`…
    /// ([`crate::problem::Point::fixed_axes`]); the others stay free.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fixed_axes: Option<String>,
}

/// The held axes of `fixed_axes` (letters X, Y, Z, each at most once; case ignored), or
/// None when the text is not such a set.
fn parse_axes(text: &str) -> Option<[bool; 3]> {
    let mut held = [false; 3];
    for c in text.chars() {
        let k = match c.to_ascii_uppercase() {
            'X' => 0,
            'Y' => 1,
            'Z' => 2,
            _ => return None,
        };
        if std::mem::replace(&mut held[k], true) {
            return None;
        }
    }
    Some(held)
}

/// The axes held by an optional `fixed_axes`-style text ([`parse_axes`]), or the error
/// naming `what` (the item and its key).
fn held_axes(text: Option<&str>, what: impl Fn() -> String) -> Result<[bool; 3], MeasurementError> {
    match text {
        None => Ok([false; 3]),
        Some(t) => parse_axes(t).ok_or_else(|| MeasurementError::BadFixedAxes {
            what: what(),
            value: t.to_string(),
        }),
    }
}

/// What is wrong with a measurement file. Each names the item concerned.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MeasurementError {
    /// The file could not be read or written.
    #[error("{file}: {message}")]
    Io {
        /// The file's path as given.
        file: String,
        /// The operating system's reason.
        message: String,
    },
    /// The JSON is malformed or does not match the format.
    #[error("{file}:{line}:{column}: {message}")]
    Syntax {
        /// The file's name as given to [`Measurements::parse`].
        file: String,
        /// 1-based line of the JSON text where the parser stopped.
        line: usize,
        /// 1-based column in that line.
        column: usize,
        /// The parser's message (control characters escaped).
        message: String,
    },
    /// An unsupported camera model.
    #[error("camera '{camera}': unknown model '{model}' (expected one of {expected})")]
    UnknownModel {
        /// The camera's name.
        camera: String,
        /// The `model` given.
        model: String,
        /// The models' names, comma-separated.
        expected: String,
    },
    /// An intrinsic name that the model does not have.
    #[error("camera '{camera}': unknown intrinsic parameter '{name}' for model {model} (expected one of {expected})")]
    UnknownParameter {
        /// The camera's name.
        camera: String,
        /// The intrinsic's name, from `intrinsics` or `calibrate`.
        name: String,
        /// The camera's `model`.
        model: String,
        /// The model's parameter names, comma separated.
        expected: String,
    },
    /// A camera without a required intrinsic (`c`; `fx, fy, cx, cy`), or with a bad size
    /// or pixel pitch.
    #[error("camera '{camera}': {message}")]
    BadCamera {
        /// The camera's name.
        camera: String,
        /// What is missing or wrong.
        message: String,
    },
    /// Two items with the same name.
    #[error("duplicate {what} '{name}'")]
    Duplicate {
        /// The kind of item: `"camera"`, `"image"` or `"control point"`.
        what: &'static str,
        /// The name given twice.
        name: String,
    },
    /// An image of an unknown camera.
    #[error("image '{image}' refers to unknown camera '{camera}'")]
    UnknownCamera {
        /// The image's name.
        image: String,
        /// The camera name it gives.
        camera: String,
    },
    /// A camera that took no image.
    #[error("camera '{camera}' has no images")]
    CameraWithoutImages {
        /// The camera's name.
        camera: String,
    },
    /// An image point of an unknown image.
    #[error("image point {index} (point '{point}') refers to unknown image '{image}'")]
    UnknownImage {
        /// 0-based position of the image point in `image_points`.
        index: usize,
        /// The image name it gives.
        image: String,
        /// The point's name.
        point: String,
    },
    /// A distance between points that are nowhere else.
    #[error("distance {index} ('{a}'–'{b}') refers to unknown point '{point}' (not measured in any image nor a control point)")]
    UnknownDistancePoint {
        /// 0-based position of the distance in `distances`.
        index: usize,
        /// The distance's first point, as given.
        a: String,
        /// The distance's second point, as given.
        b: String,
        /// The one of the two that is unknown.
        point: String,
    },
    /// A fixed image without a pose.
    #[error("image '{image}' is fixed but has no pose")]
    FixedWithoutPose {
        /// The image's name.
        image: String,
    },
    /// `fixed_axes` (of a control point) or `fixed_centre_axes` (of an image) that is not a
    /// set of the letters X, Y, Z; `what` names the item and the key.
    #[error("{what} \"{value}\" is not a set of the axes X, Y, Z (expected e.g. \"Z\" or \"XY\", each letter once)")]
    BadFixedAxes {
        /// The item and the key, e.g. `control point '17': fixed_axes`.
        what: String,
        /// The text given.
        value: String,
    },
    /// Held centre coordinates without a pose to hold them at.
    #[error(
        "image '{image}' has fixed_centre_axes but no pose (its centre gives the held coordinates)"
    )]
    HeldCentreWithoutPose {
        /// The image's name.
        image: String,
    },
    /// A NaN, infinite or non-positive value where a positive finite one is required.
    #[error("{what}: {value} is not a valid value ({expected})")]
    BadValue {
        /// The item and the key holding the value, e.g. `camera 'left': pixel_size_mm`.
        what: String,
        /// The value found, in the file's units (mm, pixels, degrees).
        value: f64,
        /// What the value must be.
        expected: &'static str,
    },
    /// The same point measured twice in one image.
    #[error("point '{point}' is measured twice in image '{image}'")]
    DuplicateObservation {
        /// The image's name.
        image: String,
        /// The point's name.
        point: String,
    },
    /// Any of the above, in the file named (control characters of echoed values escaped).
    #[error("{file}: {}", super::printable(&.source.to_string()))]
    InFile {
        /// The file's name as given to [`MeasurementError::in_file`].
        file: String,
        /// The error found in it.
        source: Box<MeasurementError>,
    },
}

impl MeasurementError {
    /// The error as found in `file` (unless it names a file already).
    pub fn in_file(self, file: &str) -> Self {
        match self {
            e @ (MeasurementError::Io { .. }
            | MeasurementError::Syntax { .. }
            | MeasurementError::InFile { .. }) => e,
            e => MeasurementError::InFile {
                file: file.into(),
                source: Box::new(e),
            },
        }
    }
}

/// Things that do not stop the conversion but deserve the user's attention.
#[derive(Clone, Debug, PartialEq)]
pub enum Warning {
    /// An image with fewer than 3 points cannot be oriented.
    FewPoints {
        /// The image's name.
        image: String,
        /// Its number of image points.
        count: usize,
    },
    /// A point measured in one image only, and not control: it adds nothing.
    SingleRay {
        /// The point's name.
        point: String,
    },
}

impl std::fmt::Display for Warning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Warning::FewPoints { image, count } => write!(
                f,
                "image '{image}' has only {count} points (at least 3 are needed to orient it)"
            ),
            Warning::SingleRay { point } => {
                write!(f, "point '{point}' is measured in one image only")
            }
        }
    }
}

/// A [`Problem`] built from [`Measurements`], with what the initialiser needs to know.
#[derive(Clone, Debug)]
pub struct Built {
    /// The problem.
    pub problem: Problem,
    /// Per point: coordinates known (control point, fixed, weighted or approximate).
    pub known_points: Vec<bool>,
    /// Per image: pose given in the file.
    pub known_poses: Vec<bool>,
    /// Point name → index in `problem.points`.
    pub point_index: HashMap<String, usize>,
    /// Non-fatal findings.
    pub warnings: Vec<Warning>,
}

/// No value of a measurement file (mm, pixels, degrees) is larger: a `1e300` is a
/// corrupt number, not a measurement, and would only overflow further on.
pub const MAX_MAGNITUDE: f64 = 1e12;

fn positive(what: impl FnOnce() -> String, v: f64) -> Result<(), MeasurementError> {
    if v > 0.0 && v <= MAX_MAGNITUDE {
        Ok(())
    } else {
        Err(MeasurementError::BadValue {
            what: what(),
            value: v,
            expected: "a positive number up to 1e12",
        })
    }
}

fn finite(what: impl FnOnce() -> String, v: f64) -> Result<(), MeasurementError> {
    if v.abs() <= MAX_MAGNITUDE {
        Ok(())
    } else {
        Err(MeasurementError::BadValue {
            what: what(),
            value: v,
            expected: "a finite number within ±1e12",
        })
    }
}

impl CameraSpec {
    /// The model and its parameter values with their fixed flags (see the module doc for
    /// the models, their intrinsics and the required ones).
    pub fn build(&self) -> Result<Camera, MeasurementError> {
        let (w, h, ps) = (self.width, self.height, self.pixel_size_mm);
        let kind = ModelKind::from_model_name(&self.model).ok_or_else(|| {
            MeasurementError::UnknownModel {
                camera: self.name.clone(),
                model: self.model.clone(),
                expected: ModelKind::ALL.map(ModelKind::model_name).join(", "),
            }
        })?;
        let model: Arc<dyn CameraModel> = kind.model(w, h, ps);
        let required = kind.required_parameters();
        let bad = |message: String| MeasurementError::BadCamera {
            camera: self.name.clone(),
            message,
        };
        if self.width == 0 || self.height == 0 {
            return Err(bad(format!(
                "image size {}×{} must be positive",
                self.width, self.height
            )));
        }
        positive(
            || format!("camera '{}': pixel_size_mm", self.name),
            self.pixel_size_mm,
        )?;
        let names = model.parameter_names();
        let index = |name: &str| {
            names.iter().position(|p| *p == name).ok_or_else(|| {
                MeasurementError::UnknownParameter {
                    camera: self.name.clone(),
                    name: name.to_string(),
                    model: self.model.clone(),
                    expected: names.join(", "),
                }
            })
        };
        let mut params = vec![0.0; names.len()];
        for (name, v) in &self.intrinsics {
            let k = index(name)?;
            finite(|| format!("camera '{}': intrinsic {name}", self.name), *v)?;
            params[k] = *v;
        }
        for name in required {
            if !self.intrinsics.contains_key(*name) {
                return Err(bad(format!(
                    "the intrinsic '{name}' is required for model {}",
                    self.model
                )));
            }
        }
        // The focal lengths (c; fx, fy) must be positive.
        for name in ["c", "fx", "fy"].iter().filter(|n| required.contains(n)) {
            positive(
                || format!("camera '{}': {name}", self.name),
                params[index(name)?],
            )?;
        }
        let mut fixed = vec![true; names.len()];
        for name in &self.calibrate {
            fixed[index(name)?] = false;
        }
        let mut cam = Camera::new(self.name.clone(), model, params);
        cam.fixed = fixed;
        Ok(cam)
    }
}

impl Measurements {
    /// Parses the JSON text (a UTF-8 byte-order mark at the start is skipped); `file` names
    /// the source in errors.
    pub fn parse(text: &str, file: &str) -> Result<Self, MeasurementError> {
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        serde_json::from_str(text).map_err(|e| MeasurementError::Syntax {
            file: file.into(),
            line: e.line(),
            column: e.column(),
            message: super::printable(&e.to_string()),
        })
    }

    /// Reads a file.
    pub fn read(path: &Path) -> Result<Self, MeasurementError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| MeasurementError::Io {
            file: file.clone(),
            message: e.to_string(),
        })?;
        Self::parse(&text, &file)
    }

    /// The JSON text (pretty-printed, with the format tag).
    pub fn to_json(&self) -> String {
        let mut m = self.clone();
        m.format = Some(FORMAT.into());
        // Serialization of these plain structs cannot fail; non-finite numbers become null.
        serde_json::to_string_pretty(&m).unwrap_or_default()
    }

    /// Writes the file atomically (a temporary file renamed over the target), so that a
    /// failed write never leaves a partial file looking complete.
    pub fn write(&self, path: &Path) -> Result<(), MeasurementError> {
        let file = path.display().to_string();
        let io = |e: std::io::Error| MeasurementError::Io {
            file: file.clone(),
            message: e.to_string(),
        };
        let tmp = path.with_extension("json.partial");
        std::fs::write(&tmp, self.to_json()).map_err(io)?;
        std::fs::rename(&tmp, path).map_err(io)
    }

    /// Checks the file and builds the [`Problem`] (see the module doc). The errors name the
    /// item concerned; [`MeasurementError::in_file`] adds the file's name.
    pub fn to_problem(&self) -> Result<Built, MeasurementError> {
        let mut b = Builder::default();
        b.add_cameras(&self.cameras)?;
        let known_poses = b.add_images(&self.images)?;
        b.add_image_points(&self.image_points)?;
        let known_points = b.add_control_points(&self.control_points)?;
        b.add_distances(&self.distances)?;
        b.add_priors(&self.control_points);
        let warnings = warnings(&b.problem, &known_points);
        Ok(Built {
            problem: b.problem,
            known_points,
            known_poses,
            point_index: b.point_index,
            warnings,
        })
    }
}

/// The [`Problem`] being built from a measurements file, with the name → index maps its
/// sections are resolved with. The sections are added in the file's order of dependence:
/// cameras, images, image points, control points, distances.
#[derive(Default)]
struct Builder {
    problem: Problem,
    camera_index: HashMap<String, usize>,
    image_index: HashMap<String, usize>,
    point_index: HashMap<String, usize>,
}

impl Builder {
    /// The cameras, refusing a name given twice.
    fn add_cameras(&mut self, cameras: &[CameraSpec]) -> Result<(), MeasurementError> {
        for c in cameras {
            if self
                .camera_index
                .insert(c.name.clone(), self.problem.cameras.len())
                .is_some()
            {
                return Err(MeasurementError::Duplicate {
                    what: "camera",
                    name: c.name.clone(),
                });
            }
            self.problem.cameras.push(c.build()?);
        }
        Ok(())
    }

    /// The images, refusing an unknown camera, a name given twice, a fixed image without
    /// a pose, a non-finite pose and a camera no image uses. Returns, per image, whether
    /// the file gives its pose.
    fn add_images(&mut self, images: &[ImageSpec]) -> Result<Vec<bool>, MeasurementError> {
        let mut known_poses = Vec::new();
        let mut used_cameras = vec![false; self.problem.cameras.len()];
        for im in images {
            let camera = *self.camera_index.get(&im.camera).ok_or_else(|| {
                MeasurementError::UnknownCamera {
                    image: im.name.clone(),
                    camera: im.camera.clone(),
                }
            })?;
            used_cameras[camera] = true;
            if self
                .image_index
                .insert(im.name.clone(), self.problem.images.len())
                .is_some()
            {
                return Err(MeasurementError::Duplicate {
                    what: "image",
                    name: im.name.clone(),
                });
            }
            if im.fixed && im.pose.is_none() {
                return Err(MeasurementError::FixedWithoutPose {
                    image: im.name.clone(),
                });
            }
            if im.fixed_centre_axes.is_some() && im.pose.is_none() {
                return Err(MeasurementError::HeldCentreWithoutPose {
                    image: im.name.clone(),
                });
            }
            let fixed_centre = held_axes(im.fixed_centre_axes.as_deref(), || {
                format!("image '{}': fixed_centre_axes", im.name)
            })?;
            if let Some(p) = &im.pose {
                for v in p.centre.iter().chain(&p.omega_phi_kappa_deg) {
                    finite(|| format!("pose of image '{}'", im.name), *v)?;
                }
            }
            known_poses.push(im.pose.is_some());
            self.problem.images.push(Image {
                name: im.name.clone(),
                camera: CameraKey(camera),
                camera_from_object: im.pose.map(|p| p.to_pose()).unwrap_or_default(),
                fixed: im.fixed,
                fixed_centre,
            });
        }
        if let Some(k) = used_cameras.iter().position(|u| !u) {
            return Err(MeasurementError::CameraWithoutImages {
                camera: self.problem.cameras[k].name.clone(),
            });
        }
        Ok(known_poses)
    }

    /// The index of the point named `name`, added (free, at the origin) when new.
    fn point(&mut self, name: &str) -> usize {
        if let Some(&k) = self.point_index.get(name) {
            return k;
        }
        self.point_index
            .insert(name.to_string(), self.problem.points.len());
        self.problem.points.push(Point {
            name: name.to_string(),
            position: Vector3::zeros(),
            fixed: false,
            fixed_axes: [false; 3],
        });
        self.problem.points.len() - 1
    }

    /// The observations (and their points), refusing an unknown image, a non-finite
    /// coordinate, a non-positive σ and a point measured twice in one image.
    fn add_image_points(&mut self, image_points: &[ImagePoint]) -> Result<(), MeasurementError> {
        let mut seen = std::collections::HashSet::new();
        for (index, ip) in image_points.iter().enumerate() {
            let image =
                *self
                    .image_index
                    .get(&ip.image)
                    .ok_or_else(|| MeasurementError::UnknownImage {
                        index,
                        image: ip.image.clone(),
                        point: ip.point.clone(),
                    })?;
            let what = || format!("image point {index} ('{}' in '{}')", ip.point, ip.image);
            finite(what, ip.x)?;
            finite(what, ip.y)?;
            positive(|| format!("{}: sigma_px", what()), ip.sigma_px)?;
            let point = self.point(&ip.point);
            if !seen.insert((image, point)) {
                return Err(MeasurementError::DuplicateObservation {
                    image: ip.image.clone(),
                    point: ip.point.clone(),
                });
            }
            self.problem.observations.push(Observation {
                image: ImageKey(image),
                point: PointKey(point),
                uv: Vector2::new(ip.x, ip.y),
                sigma: ip.sigma_px,
            });
        }
        Ok(())
    }

    /// The control points' coordinates (and fixedness), refusing an id given twice, a
    /// non-finite coordinate and a non-positive σ. Returns, per point, whether its
    /// coordinates are known.
    fn add_control_points(
        &mut self,
        control_points: &[ControlPoint],
    ) -> Result<Vec<bool>, MeasurementError> {
        let mut control_seen = std::collections::HashSet::new();
        for cp in control_points {
            if !control_seen.insert(cp.id.clone()) {
                return Err(MeasurementError::Duplicate {
                    what: "control point",
                    name: cp.id.clone(),
                });
            }
            for v in cp.xyz {
                finite(|| format!("control point '{}'", cp.id), v)?;
            }
            if let Some(s) = cp.sigma_mm {
                for v in s {
                    positive(|| format!("control point '{}': sigma_mm", cp.id), v)?;
                }
            }
            let axes = held_axes(cp.fixed_axes.as_deref(), || {
                format!("control point '{}': fixed_axes", cp.id)
            })?;
            let k = self.point(&cp.id);
            self.problem.points[k].position = Vector3::from(cp.xyz);
            self.problem.points[k].fixed = cp.fixed;
            self.problem.points[k].fixed_axes = axes;
        }
        let mut known_points = vec![false; self.problem.points.len()];
        for cp in control_points {
            known_points[self.point_index[&cp.id]] = true;
        }
        Ok(known_points)
    }

    /// The measured distances, refusing an unknown point, a non-positive length or σ and
    /// a distance from a point to itself.
    fn add_distances(&mut self, distances: &[Distance]) -> Result<(), MeasurementError> {
        for (index, d) in distances.iter().enumerate() {
            for p in [&d.a, &d.b] {
                if !self.point_index.contains_key(p.as_str()) {
                    return Err(MeasurementError::UnknownDistancePoint {
                        index,
                        a: d.a.clone(),
                        b: d.b.clone(),
                        point: p.clone(),
                    });
                }
            }
            positive(|| format!("distance {index} ('{}'–'{}')", d.a, d.b), d.mm)?;
            positive(
                || format!("distance {index} ('{}'–'{}'): sigma_mm", d.a, d.b),
                d.sigma_mm,
            )?;
            let (a, b) = (self.point_index[&d.a], self.point_index[&d.b]);
            if a == b {
                return Err(MeasurementError::BadValue {
                    what: format!("distance {index} joins '{}' to itself", d.a),
                    value: d.mm,
                    expected: "two different points",
                });
            }
            self.problem.distances.push(crate::problem::Distance {
                a: PointKey(a),
                b: PointKey(b),
                value: d.mm,
                sigma: d.sigma_mm,
            });
        }
        Ok(())
    }

    /// The priors of the free control points given with a σ (weighted control points).
    fn add_priors(&mut self, control_points: &[ControlPoint]) {
        for cp in control_points {
            if let (Some(s), false) = (cp.sigma_mm, cp.fixed) {
                self.problem.point_priors.push(PointPrior {
                    point: PointKey(self.point_index[&cp.id]),
                    position: Vector3::from(cp.xyz),
                    sigma: Vector3::from(s),
                });
            }
        }
    }
}

/// The non-fatal findings: images with fewer than 3 points, and points of unknown
/// coordinates measured in one image only.
fn warnings(problem: &Problem, known_points: &[bool]) -> Vec<Warning> {
    let mut warnings = Vec::new();
    let mut per_image = vec![0usize; problem.images.len()];
    let mut per_point = vec![0usize; problem.points.len()];
    for o in &problem.observations {
        per_image[o.image.0] += 1;
        per_point[o.point.0] += 1;
    }
    for (im, &n) in problem.images.iter().zip(&per_image) {
        if n < 3 {
            warnings.push(Warning::FewPoints {
                image: im.name.clone(),
                count: n,
            });
        }
    }
    for (k, pt) in problem.points.iter().enumerate() {
        if per_point[k] == 1 && !known_points[k] {
            warnings.push(Warning::SingleRay {
                point: pt.name.clone(),
            });
        }
    }
    warnings
}

impl Measurements {
    /// A copy with the adjusted values of `problem` (built from `self` by
    /// [`Measurements::to_problem`], possibly reduced by the initialiser: images and
    /// cameras are matched by name): camera intrinsics, image poses, and the coordinates
    /// of the file's control points left free (approximate ones). To write a result file in
    /// the input format.
    pub fn with_solution(&self, problem: &Problem) -> Measurements {
        let mut out = self.clone();
        for c in &mut out.cameras {
            if let Some(pc) = problem.cameras.iter().find(|pc| pc.name == c.name) {
                for (name, v) in pc.model.parameter_names().iter().zip(&pc.params) {
                    if *v != 0.0 || c.intrinsics.contains_key(*name) {
                        c.intrinsics.insert(name.to_string(), *v);
                    }
                }
            }
        }
        for im in &mut out.images {
            if let Some(pi) = problem.images.iter().find(|pi| pi.name == im.name) {
                im.pose = Some(PoseSpec::from_pose(&pi.camera_from_object));
            }
        }
        for cp in &mut out.control_points {
            if cp.fixed || cp.sigma_mm.is_some() {
                continue;
            }
            if let Some(pt) = problem.points.iter().find(|pt| pt.name == cp.id) {
                cp.xyz = [pt.position.x, pt.position.y, pt.position.z];
            }
        }
        out
    }
}

/// The model of a camera of a [`Problem`] built by [`Measurements::to_problem`] (or
/// by hand), when it is the photogrammetric one: needed to write it back.
pub fn camera_spec(
    name: &str,
    model: &PhotogrammetricCamera,
    params: &[f64],
    fixed: &[bool],
) -> CameraSpec {
    CameraSpec {
        name: name.into(),
        model: default_model(),
        width: model.width,
        height: model.height,
        pixel_size_mm: model.pixel_size_mm,
        intrinsics: PHOTOGRAMMETRIC_PARAMS
            .iter()
            .zip(params)
            .map(|(n, v)| (n.to_string(), *v))
            .collect(),
        calibrate: PHOTOGRAMMETRIC_PARAMS
            .iter()
            .zip(fixed)
            .filter(|(_, f)| !**f)
            .map(|(n, _)| n.to_string())
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    pub(crate) const EXAMPLE: &str = r#"{
      "format": "pingcal-measurements v1",
      "cameras": [
        {"name": "left", "model": "photogrammetric",
         "width": 1280, "height": 720, "pixel_size_mm": 0.00375,
         "intrinsics": {"c": 2.45, "xp": 0.0, "yp": 0.0, "K1": 0.0},
         "calibrate": ["c", "xp", "yp", "K1", "K2", "K3", "P1", "P2"]}
      ],
      "images": [
        {"name": "main", "camera": "left",
         "pose": {"centre": [0, 0, 0], "omega_phi_kappa_deg": [0, 0, 0]}, "fixed": true},
        {"name": "st02", "camera": "left"}
      ],
      "image_points": [
        {"image": "main", "point": "17", "x": 640.25, "y": 355.5, "sigma_px": 0.05},
        {"image": "st02", "point": "17", "x": 512.0, "y": 300.75, "sigma_px": 0.05}
      ],
      "distances": [
        {"a": "17", "b": "18", "mm": 1000.12, "sigma_mm": 0.05}
      ],
      "control_points": [
        {"id": "17", "xyz": [0, 2000, 0], "fixed": true},
        {"id": "18", "xyz": [1000, 2000, 0], "sigma_mm": [0.1, 0.1, 0.1]},
        {"id": "19", "xyz": [0, 2500, 300]}
      ]
    }"#;

    #[test]
    fn the_documented_example_parses_builds_and_round_trips() {
        let m = Measurements::parse(EXAMPLE, "example.json").unwrap();
        let b = m.to_problem().unwrap();
        assert_eq!(b.problem.cameras.len(), 1);
        assert_eq!(b.problem.images.len(), 2);
        assert_eq!(b.problem.points.len(), 3);
        assert_eq!(b.problem.observations.len(), 2);
        assert_eq!(b.problem.distances.len(), 1);
        assert_eq!(b.problem.distances[0].value, 1000.12);
        assert_eq!(b.problem.point_priors.len(), 1);
        assert_eq!(
            b.problem.point_priors[0].point,
            PointKey(b.point_index["18"])
        );
        let p17 = b.point_index["17"];
        assert!(b.problem.points[p17].fixed && b.known_points[p17]);
        let p18 = b.point_index["18"];
        assert!(!b.problem.points[p18].fixed && b.known_points[p18]);
        assert_eq!(b.known_poses, vec![true, false]);
        assert!(b.problem.images[0].fixed);
        let cam = &b.problem.cameras[0];
        assert_eq!(cam.params[0], 2.45);
        assert_eq!(
            cam.fixed,
            vec![false, false, false, false, false, false, false, false, true, true]
        );
        // Both images have fewer than 3 points.
        assert_eq!(
            b.warnings
                .iter()
                .filter(|w| matches!(w, Warning::FewPoints { .. }))
                .count(),
            2
        );
        let again = Measurements::parse(&m.to_json(), "again.json").unwrap();
        assert_eq!(again.cameras, m.cameras);
        assert_eq!(again.images, m.images);
        assert_eq!(again.image_points, m.image_points);
        assert_eq!(again.distances, m.distances);
        assert_eq!(again.control_points, m.control_points);
    }

    #[test]
    fn errors_name_the_file_and_escape_control_characters() {
        let e = edit(|m| {
            m.image_points[0].point = "3\r6".into();
            let d = m.image_points[0].clone();
            m.image_points.push(d)
        })
        .unwrap_err()
        .in_file("m.json")
        .to_string();
        assert_eq!(e, "m.json: point '3\\r6' is measured twice in image 'main'");
        // A syntax error names its file already and is left as it is.
        let e = Measurements::parse("{\"cameras\": [}", "broken.json").unwrap_err();
        let text = e.to_string();
        assert_eq!(e.in_file("other.json").to_string(), text);
    }

    #[test]
    fn fixed_axes_hold_single_coordinates_and_bad_ones_are_refused() {
        let b = edit(|m| m.control_points[2].fixed_axes = Some("xZ".into())).unwrap();
        let p19 = &b.problem.points[b.point_index["19"]];
        assert_eq!(p19.fixed_axes, [true, false, true]);
        assert!(!p19.fixed && p19.is_partly_held());
        for bad in ["W", "ZZ", "X Y", "1"] {
            let e = edit(|m| m.control_points[2].fixed_axes = Some(bad.into()))
                .unwrap_err()
                .to_string();
            assert!(
                e.contains("control point '19'") && e.contains(&format!("\"{bad}\"")),
                "{bad}: {e}"
            );
        }
    }

    #[test]
    fn an_image_holds_single_centre_coordinates_only_with_a_pose() {
        let b = edit(|m| m.images[0].fixed_centre_axes = Some("Zx".into())).unwrap();
        let im = &b.problem.images[0];
        assert_eq!(im.fixed_centre, [true, false, true]);
        let e = edit(|m| m.images[1].fixed_centre_axes = Some("Y".into()))
            .unwrap_err()
            .to_string();
        assert!(e.contains("image 'st02'") && e.contains("no pose"), "{e}");
        for bad in ["XX", "centre", ""] {
            let e = edit(|m| m.images[0].fixed_centre_axes = Some(bad.into()));
            match bad {
                // an empty set holds nothing: allowed, the same as no key
                "" => assert_eq!(e.unwrap().problem.images[0].fixed_centre, [false; 3]),
                _ => {
                    let e = e.unwrap_err().to_string();
                    assert!(
                        e.contains("fixed_centre_axes") && e.contains(bad),
                        "{bad}: {e}"
                    );
                }
            }
        }
    }

    #[test]
    fn a_byte_order_mark_is_skipped() {
        let m = Measurements::parse(&format!("\u{feff}{EXAMPLE}"), "bom.json").unwrap();
        assert_eq!(m.cameras.len(), 1);
    }

    /// A network written in the form of the module doc's example (one camera, the first
    /// image with a pose and `fixed: true`, the others without, image points and a measured
    /// distance, no control points) solves, and the first image keeps its given pose.
    /// Before, one given pose sent the initialiser to its "with control" start, where
    /// every other image "sees 0 oriented points".
    #[test]
    fn a_network_in_the_form_of_the_doc_example_solves() {
        use crate::camera::CameraModel;
        use crate::initial::incremental::{initialise, IncrementalOptions};
        use rand::Rng;
        let mut rng = pingcal_geometry::consensus::rng(14);
        let cam = PhotogrammetricCamera::new(1280, 720, 0.00375);
        let mut params = vec![0.0; 10];
        params[0] = 2.45;
        let points: Vec<Vector3<f64>> = (0..60)
            .map(|k| {
                let (a, b) = (rng.random_range(0.0..2000.0), rng.random_range(0.0..1500.0));
                match k % 3 {
                    0 => Vector3::new(a, b, 0.0),
                    1 => Vector3::new(a, 0.0, b),
                    _ => Vector3::new(0.0, a, b),
                }
            })
            .collect();
        let target = Vector3::new(700.0, 700.0, 500.0);
        let poses: Vec<Rigid3> = (0..10)
            .map(|i| {
                let ang = 0.2 + 1.2 * i as f64 / 9.0;
                let centre = Vector3::new(3200.0 * ang.cos(), 3200.0 * ang.sin(), 1200.0);
                Rigid3::looking_at(centre, target, rng.random_range(-0.3..0.3))
            })
            .collect();
        let mut image_points = Vec::new();
        for (i, pose) in poses.iter().enumerate() {
            for (j, x) in points.iter().enumerate() {
                if let Some(uv) = cam.project(&params, &pose.transform(x), None, None) {
                    if uv.x > 0.0 && uv.y > 0.0 && uv.x < 1279.0 && uv.y < 719.0 {
                        image_points.push(serde_json::json!({
                            "image": format!("st{i:02}"), "point": j.to_string(),
                            "x": uv.x, "y": uv.y, "sigma_px": 0.05}));
                    }
                }
            }
        }
        let main = PoseSpec::from_pose(&poses[0]);
        let mut images = vec![serde_json::json!({"name": "st00", "camera": "left",
            "pose": {"centre": main.centre, "omega_phi_kappa_deg": main.omega_phi_kappa_deg},
            "fixed": true})];
        images.extend(
            (1..10).map(|i| serde_json::json!({"name": format!("st{i:02}"), "camera": "left"})),
        );
        let text = serde_json::json!({
            "format": "pingcal-measurements v1",
            "cameras": [{"name": "left", "model": "photogrammetric",
                "width": 1280, "height": 720, "pixel_size_mm": 0.00375,
                "intrinsics": {"c": 2.45, "xp": 0.0, "yp": 0.0, "K1": 0.0}}],
            "images": images,
            "image_points": image_points,
            "distances": [{"a": "0", "b": "1", "mm": (points[0] - points[1]).norm(), "sigma_mm": 0.05}],
        })
        .to_string();
        let m = Measurements::parse(&text, "doc-form.json").unwrap();
        let built = m.to_problem().unwrap();
        let init = initialise(
            &built.problem,
            &built.known_points,
            &built.known_poses,
            &IncrementalOptions::default(),
        )
        .unwrap();
        assert!(
            init.unoriented_images.is_empty(),
            "{:?}",
            init.unoriented_images
        );
        let mut problem = init.problem;
        crate::solver::solve(&mut problem, &crate::solver::Options::default(), |_| {}).unwrap();
        assert!(problem.rms_px() < 1e-3, "RMS {} px", problem.rms_px());
        let first = &problem.images[0];
        assert_eq!(first.name, "st00");
        assert!((first.camera_from_object.centre() - poses[0].centre()).norm() < 1e-6);
        let p5 = &problem.points[init.point_map[built.point_index["5"]].unwrap()];
        assert!((p5.position - points[5]).norm() < 0.1, "{:?}", p5.position);
    }

    #[test]
    fn writer_writes_a_file_that_reads_back() {
        let m = Measurements::parse(EXAMPLE, "example.json").unwrap();
        let dir = std::env::temp_dir().join(format!("pingcal-meas-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("m.json");
        m.write(&path).unwrap();
        let back = Measurements::read(&path).unwrap();
        assert_eq!(back.image_points, m.image_points);
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn with_solution_writes_poses_and_intrinsics_back() {
        let m = Measurements::parse(EXAMPLE, "example.json").unwrap();
        let mut b = m.to_problem().unwrap();
        b.problem.cameras[0].params[0] = 2.5;
        b.problem.cameras[0].params[4] = 1e-4;
        b.problem.images[1].camera_from_object = PoseSpec {
            centre: [100.0, 0.0, 5.0],
            omega_phi_kappa_deg: [1.0, 2.0, 3.0],
        }
        .to_pose();
        let out = m.with_solution(&b.problem);
        assert_eq!(out.cameras[0].intrinsics["c"], 2.5);
        assert_eq!(out.cameras[0].intrinsics["K2"], 1e-4);
        let pose = out.images[1].pose.unwrap();
        assert!((pose.centre[0] - 100.0).abs() < 1e-9);
        assert!((pose.omega_phi_kappa_deg[2] - 3.0).abs() < 1e-9);
        // The result reads back and builds the same problem size.
        let again = Measurements::parse(&out.to_json(), "out.json").unwrap();
        assert_eq!(again.to_problem().unwrap().problem.points.len(), 3);
    }

    #[test]
    fn pose_spec_round_trips() {
        let p = PoseSpec {
            centre: [1.0, -2.0, 3.0],
            omega_phi_kappa_deg: [10.0, -20.0, 170.0],
        };
        let q = PoseSpec::from_pose(&p.to_pose());
        for k in 0..3 {
            assert!((p.centre[k] - q.centre[k]).abs() < 1e-9);
            assert!((p.omega_phi_kappa_deg[k] - q.omega_phi_kappa_deg[k]).abs() < 1e-9);
        }
    }

    fn edit(f: impl FnOnce(&mut Measurements)) -> Result<Built, MeasurementError> {
        let mut m = Measurements::parse(EXAMPLE, "example.json").unwrap();
        f(&mut m);
        m.to_problem()
    }

    /// Each model name builds its model with the intrinsics by name; a name the model does
    /// not have, a missing required one and an unknown model are one-line errors naming the
    /// file, the camera and the value.
    #[test]
    fn every_camera_model_is_chosen_by_name() {
        let set = |m: &mut Measurements, model: &str, values: &[(&str, f64)], free: &[&str]| {
            let c = &mut m.cameras[0];
            c.model = model.into();
            c.intrinsics = values.iter().map(|(n, v)| (n.to_string(), *v)).collect();
            c.calibrate = free.iter().map(|n| n.to_string()).collect();
        };
        let pix = [("fx", 650.0), ("fy", 651.0), ("cx", 639.5), ("cy", 359.5)];
        for (model, n) in [("opencv", 16), ("fisheye", 8)] {
            let mut values = pix.to_vec();
            values.push(("k2", 0.01));
            let b = edit(|m| set(m, model, &values, &["fx", "k2"])).unwrap();
            let cam = &b.problem.cameras[0];
            assert_eq!(cam.model.name(), model);
            assert_eq!(cam.params.len(), n);
            assert_eq!(&cam.params[..4], &[650.0, 651.0, 639.5, 359.5]);
            let k2 = cam.model.parameter_names().iter().position(|p| *p == "k2");
            assert_eq!(cam.params[k2.unwrap()], 0.01);
            assert_eq!(cam.free_indices(), vec![0, k2.unwrap()]);
        }
        let b = edit(|m| set(m, "brown_backward", &[("c", 2.45), ("K1", 0.02)], &["c"])).unwrap();
        let cam = &b.problem.cameras[0];
        assert_eq!(cam.model.name(), "brown_backward");
        assert_eq!(cam.params[..4], [2.45, 0.0, 0.0, 0.02]);
        assert_eq!(cam.model.pixel_size_mm(), Some(0.00375));

        let e = edit(|m| {
            set(
                m,
                "fisheye",
                &[pix[0], pix[1], pix[2], pix[3], ("k5", 0.1)],
                &[],
            )
        })
        .unwrap_err()
        .in_file("m.json")
        .to_string();
        assert_eq!(
            e,
            "m.json: camera 'left': unknown intrinsic parameter 'k5' for model fisheye \
             (expected one of fx, fy, cx, cy, k1, k2, k3, k4)"
        );
        let e = edit(|m| set(m, "opencv", &pix[..3], &[])).unwrap_err();
        assert_eq!(
            e.to_string(),
            "camera 'left': the intrinsic 'cy' is required for model opencv"
        );
        let e = edit(|m| set(m, "opencv", &pix, &["K1"])).unwrap_err();
        assert!(
            matches!(e, MeasurementError::UnknownParameter { .. }),
            "{e}"
        );
        let mut neg = pix;
        neg[1].1 = -1.0;
        let e = edit(|m| set(m, "opencv", &neg, &[])).unwrap_err();
        assert!(matches!(e, MeasurementError::BadValue { .. }), "{e}");
        let e = edit(|m| set(m, "kannala", &pix, &[]))
            .unwrap_err()
            .in_file("m.json")
            .to_string();
        assert!(
            e.starts_with("m.json: camera 'left': unknown model 'kannala'"),
            "{e}"
        );
        assert!(!e.contains('\n'));
    }

    #[test]
    fn bad_input_is_named() {
        let e = edit(|m| m.image_points[1].image = "nowhere".into()).unwrap_err();
        assert!(matches!(&e, MeasurementError::UnknownImage { image, .. } if image == "nowhere"));
        assert!(e.to_string().contains("nowhere"));
        let e = edit(|m| m.distances[0].b = "99".into()).unwrap_err();
        assert!(
            matches!(&e, MeasurementError::UnknownDistancePoint { point, .. } if point == "99")
        );
        let e = edit(|m| {
            let mut c = m.cameras[0].clone();
            c.name = "right".into();
            m.cameras.push(c);
        })
        .unwrap_err();
        assert_eq!(
            e,
            MeasurementError::CameraWithoutImages {
                camera: "right".into()
            }
        );
        let e = edit(|m| m.images[1].camera = "middle".into()).unwrap_err();
        assert!(matches!(e, MeasurementError::UnknownCamera { .. }));
        let e = edit(|m| m.image_points[0].sigma_px = 0.0).unwrap_err();
        assert!(matches!(e, MeasurementError::BadValue { .. }), "{e}");
        let e = edit(|m| m.image_points[0].x = f64::NAN).unwrap_err();
        assert!(matches!(e, MeasurementError::BadValue { .. }), "{e}");
        let e = edit(|m| m.cameras[0].calibrate.push("K9".into())).unwrap_err();
        assert!(matches!(e, MeasurementError::UnknownParameter { .. }));
        let e = edit(|m| {
            m.cameras[0].intrinsics.remove("c");
        })
        .unwrap_err();
        assert!(matches!(e, MeasurementError::BadCamera { .. }));
        let e = edit(|m| m.images[1].fixed = true).unwrap_err();
        assert!(matches!(e, MeasurementError::FixedWithoutPose { .. }));
        let e = edit(|m| {
            let d = m.image_points[0].clone();
            m.image_points.push(d)
        })
        .unwrap_err();
        assert!(matches!(e, MeasurementError::DuplicateObservation { .. }));
        let e = Measurements::parse("{\"cameras\": [}", "broken.json").unwrap_err();
        assert!(
            matches!(&e, MeasurementError::Syntax { file, line: 1, .. } if file == "broken.json"),
            "{e}"
        );
    }

    proptest::proptest! {
        #[test]
        fn arbitrary_text_never_panics(s in "\\PC{0,200}") {
            if let Ok(m) = Measurements::parse(&s, "x.json") {
                let _ = m.to_problem();
            }
        }
    }
}
