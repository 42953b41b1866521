//! # pingcal-project: the project file
//!
//! A calibration is described by one `project.toml` (version 1). Every path in it is relative
//! to the folder that holds it. This crate holds its schema ([`ProjectFile`]), reads it with
//! errors that name the file and line ([`ProjectFile::parse`]), and checks it against itself
//! and the files it names ([`Project::load`]): cameras referenced by images exist, the main
//! station has an image of the main camera, images and scans exist, distances join two
//! different targets with a positive σ, and so on. Checks that need the images decoded (their
//! size) or the targets detected (a distance between targets never seen) belong to the
//! pipeline, which reports them in the same one-line style.
//!
//! The README's section "The project file" has a complete, commented example; the tests
//! of this crate parse and validate that very text, so it cannot drift.

use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Names of the ten photogrammetric parameters, in the order of [`CameraParams::to_slice`].
pub const PARAMETER_NAMES: [&str; 10] = ["c", "xp", "yp", "K1", "K2", "K3", "P1", "P2", "B1", "B2"];

/// `project.toml`, version 1.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProjectFile {
    /// Format version (1).
    pub version: u32,
    /// A name for reports.
    pub name: String,
    /// `spheres`, `corner` or `both`.
    pub method: String,
    /// The station where the LRF scanned; its `main_camera` image defines the
    /// photogrammetric frame.
    pub main_station: String,
    /// The camera whose frame is the photogrammetric frame (`left`).
    pub main_camera: String,
    /// Coded targets.
    pub targets: ProjectTargets,
    /// Balls.
    pub balls: ProjectBalls,
    /// Cameras with initial intrinsics.
    pub cameras: Vec<ProjectCamera>,
    /// The stereo head (optional for a mono camera).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stereo: Option<ProjectStereo>,
    /// Images.
    pub images: Vec<ProjectImage>,
    /// Caliper distances between coded targets.
    #[serde(default)]
    pub distances: Vec<ProjectDistance>,
    /// The LRF.
    pub lrf: ProjectLrf,
}

/// `[targets]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProjectTargets {
    /// `aicon14` or `aicon12`.
    pub family: String,
    /// Radius of the central dot (mm), printed size.
    pub dot_radius_mm: f64,
    /// Inner radius of the code ring, in dot radii.
    #[serde(default = "default_ring_inner")]
    pub ring_inner: f64,
    /// Outer radius of the code ring, in dot radii.
    #[serde(default = "default_ring_outer")]
    pub ring_outer: f64,
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
    /// `photogrammetric` (SPEC.md).
    pub model: String,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Pixel pitch (mm).
    pub pixel_size_mm: f64,
    /// Initial values (camera manual).
    pub initial: CameraParams,
    /// Which parameters to self-calibrate (names of [`PARAMETER_NAMES`]).
    pub free: Vec<String>,
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
    /// Sensor model, for reports.
    pub model: String,
    /// Station where it scanned (the main station).
    pub station: String,
    /// Scan files (`pingcal-scan` CSV, or PLY / XYZ clouds), relative to project.toml.
    pub scans: Vec<String>,
    /// Maximum range (mm).
    pub max_range_mm: f64,
    /// Datasheet accuracy under 1 m (± mm, taken as 3σ).
    pub accuracy_near_mm: f64,
    /// Datasheet accuracy beyond 1 m (± fraction of range, taken as 3σ).
    pub accuracy_far_fraction: f64,
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
}

/// Why a project cannot be used: one line naming the file, and the entry and value.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ProjectError {
    /// The file cannot be read.
    #[error("{path}: {what}")]
    Io {
        /// The file.
        path: String,
        /// What happened.
        what: String,
    },
    /// TOML syntax or a field of the wrong type (the message has the line).
    #[error("{path}: {what}")]
    Syntax {
        /// The file.
        path: String,
        /// The parser's message, flattened to one line.
        what: String,
    },
    /// A value that makes no sense, or a reference to something that is not there.
    #[error("{path}: {what}")]
    Invalid {
        /// The file.
        path: String,
        /// Which entry, which value, what was expected.
        what: String,
    },
}

impl ProjectFile {
    /// Parses the text of a project file; `file` names it in errors.
    pub fn parse(text: &str, file: &str) -> Result<Self, ProjectError> {
        toml::from_str(text).map_err(|e| ProjectError::Syntax {
            path: file.to_string(),
            what: one_line(&e.to_string()),
        })
    }

    /// The text of the file (as `pingcal simulate` writes it).
    pub fn to_toml_string(&self) -> String {
        toml::to_string(self).expect("a project file always serialises")
    }

    /// The method, checked.
    pub fn method(&self) -> Method {
        match self.method.as_str() {
            "spheres" => Method::Spheres,
            "corner" => Method::Corner,
            _ => Method::Both,
        }
    }

    /// Checks the file against itself (not the files it names); `file` names it in errors.
    pub fn validate(&self, file: &str) -> Result<(), ProjectError> {
        let bad = |what: String| ProjectError::Invalid {
            path: file.to_string(),
            what,
        };
        if self.version != 1 {
            return Err(bad(format!(
                "version = {}: this pingcal reads version 1",
                self.version
            )));
        }
        if !matches!(self.method.as_str(), "spheres" | "corner" | "both") {
            return Err(bad(format!(
                "method = \"{}\": expected \"spheres\", \"corner\" or \"both\"",
                self.method
            )));
        }
        if !matches!(self.targets.family.as_str(), "aicon14" | "aicon12") {
            return Err(bad(format!(
                "[targets] family = \"{}\": expected \"aicon14\" or \"aicon12\"",
                self.targets.family
            )));
        }
        let t = &self.targets;
        if !(t.dot_radius_mm > 0.0 && t.dot_radius_mm.is_finite()) {
            return Err(bad(format!(
                "[targets] dot_radius_mm = {}: expected a positive length",
                t.dot_radius_mm
            )));
        }
        if !(t.ring_inner > 1.0 && t.ring_outer > t.ring_inner && t.ring_outer.is_finite()) {
            return Err(bad(format!(
                "[targets] ring_inner = {}, ring_outer = {}: expected 1 < ring_inner < ring_outer",
                t.ring_inner, t.ring_outer
            )));
        }
        if !(self.balls.diameter_mm > 0.0 && self.balls.diameter_mm.is_finite()) {
            return Err(bad(format!(
                "[balls] diameter_mm = {}: expected a positive length",
                self.balls.diameter_mm
            )));
        }
        let mut seen = BTreeSet::new();
        for l in &self.balls.labels {
            if !seen.insert(l.id.as_str()) {
                return Err(bad(format!("[balls] labels: id '{}' appears twice", l.id)));
            }
            if !(l.x.is_finite() && l.y.is_finite()) {
                return Err(bad(format!(
                    "[balls] labels: '{}' has no finite position",
                    l.id
                )));
            }
        }
        if !self.balls.labels.is_empty() {
            for c in &self.balls.check {
                if !seen.contains(c.as_str()) {
                    return Err(bad(format!(
                        "[balls] check: '{c}' is not one of the labelled balls"
                    )));
                }
            }
        }
        if self.cameras.is_empty() {
            return Err(bad("no [[cameras]]".into()));
        }
        let mut cams = BTreeMap::new();
        for (k, c) in self.cameras.iter().enumerate() {
            let at = format!("cameras[{k}] (id '{}')", c.id);
            if cams.insert(c.id.as_str(), c).is_some() {
                return Err(bad(format!("{at}: the id is used twice")));
            }
            if c.model != "photogrammetric" {
                return Err(bad(format!(
                    "{at}: model = \"{}\": expected \"photogrammetric\"",
                    c.model
                )));
            }
            if c.width < 16 || c.height < 16 {
                return Err(bad(format!(
                    "{at}: {}×{} pixels is not an image size",
                    c.width, c.height
                )));
            }
            if !(c.pixel_size_mm > 0.0 && c.pixel_size_mm < 1.0) {
                return Err(bad(format!(
                    "{at}: pixel_size_mm = {}: expected a pitch in mm (e.g. 0.00375)",
                    c.pixel_size_mm
                )));
            }
            if !(c.initial.c_mm > 0.0 && c.initial.c_mm.is_finite()) {
                return Err(bad(format!(
                    "{at}: initial c_mm = {}: expected a positive principal distance",
                    c.initial.c_mm
                )));
            }
            if c.initial.to_slice().iter().any(|v| !v.is_finite()) {
                return Err(bad(format!("{at}: an initial parameter is not finite")));
            }
            for f in &c.free {
                if !PARAMETER_NAMES.contains(&f.as_str()) {
                    return Err(bad(format!(
                        "{at}: free parameter '{f}' is not one of {}",
                        PARAMETER_NAMES.join(", ")
                    )));
                }
            }
        }
        if let Some(s) = &self.stereo {
            for id in [&s.left, &s.right] {
                if !cams.contains_key(id.as_str()) {
                    return Err(bad(format!(
                        "[stereo]: camera '{id}' is not in [[cameras]]"
                    )));
                }
            }
            if s.left == s.right {
                return Err(bad("[stereo]: left and right are the same camera".into()));
            }
        }
        if !cams.contains_key(self.main_camera.as_str()) {
            return Err(bad(format!(
                "main_camera = \"{}\" is not in [[cameras]]",
                self.main_camera
            )));
        }
        if self.images.is_empty() {
            return Err(bad("no [[images]]".into()));
        }
        let mut files = BTreeSet::new();
        let mut per_station: BTreeMap<&str, BTreeSet<&str>> = BTreeMap::new();
        for (k, im) in self.images.iter().enumerate() {
            let at = format!("images[{k}] ('{}')", im.file);
            if !cams.contains_key(im.camera.as_str()) {
                return Err(bad(format!(
                    "{at}: camera '{}' is not in [[cameras]]",
                    im.camera
                )));
            }
            if !files.insert(im.file.as_str()) {
                return Err(bad(format!("{at}: the file is listed twice")));
            }
            if !per_station
                .entry(im.station.as_str())
                .or_default()
                .insert(im.camera.as_str())
            {
                return Err(bad(format!(
                    "{at}: station '{}' already has an image of camera '{}'",
                    im.station, im.camera
                )));
            }
        }
        match per_station.get(self.main_station.as_str()) {
            None => {
                return Err(bad(format!(
                    "main_station = \"{}\" is not the station of any image (stations: {})",
                    self.main_station,
                    per_station.keys().cloned().collect::<Vec<_>>().join(", ")
                )))
            }
            Some(c) if !c.contains(self.main_camera.as_str()) => {
                return Err(bad(format!(
                    "main_station \"{}\" has no image of the main camera '{}'",
                    self.main_station, self.main_camera
                )))
            }
            _ => {}
        }
        for (k, d) in self.distances.iter().enumerate() {
            let at = format!("distances[{k}] ({} – {})", d.from, d.to);
            if d.from == d.to {
                return Err(bad(format!("{at}: both ends are the same target")));
            }
            if !(d.distance_mm > 0.0 && d.distance_mm.is_finite()) {
                return Err(bad(format!(
                    "{at}: distance_mm = {}: expected a positive length",
                    d.distance_mm
                )));
            }
            if !(d.sigma_mm > 0.0 && d.sigma_mm.is_finite()) {
                return Err(bad(format!(
                    "{at}: sigma_mm = {}: expected a positive σ",
                    d.sigma_mm
                )));
            }
        }
        let l = &self.lrf;
        if l.scans.is_empty() {
            return Err(bad("[lrf] scans: no scan file".into()));
        }
        if l.station != self.main_station {
            return Err(bad(format!(
                "[lrf] station = \"{}\" but main_station = \"{}\": the LRF scans from the main station",
                l.station, self.main_station
            )));
        }
        if !(l.max_range_mm > 0.0
            && l.accuracy_near_mm > 0.0
            && l.accuracy_far_fraction > 0.0
            && l.max_range_mm.is_finite()
            && l.accuracy_near_mm.is_finite()
            && l.accuracy_far_fraction.is_finite())
        {
            return Err(bad(
                "[lrf] max_range_mm, accuracy_near_mm and accuracy_far_fraction must be positive"
                    .into(),
            ));
        }
        if l.mount_offset_mm.iter().any(|v| !v.is_finite())
            || ![l.mount_tilt_x_deg, l.mount_tilt_z_deg, l.servo_zero_deg]
                .iter()
                .all(|v| v.is_finite())
        {
            return Err(bad("[lrf] a mount value is not finite".into()));
        }
        Ok(())
    }
}

/// Which extrinsic method(s) to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// Ping-pong balls (the paper's method).
    Spheres,
    /// Fan et al. 2019 room corner.
    Corner,
    /// Both, side by side.
    Both,
}

impl Method {
    /// Runs the sphere method.
    pub fn spheres(self) -> bool {
        matches!(self, Method::Spheres | Method::Both)
    }

    /// Runs the corner baseline.
    pub fn corner(self) -> bool {
        matches!(self, Method::Corner | Method::Both)
    }
}

/// A project file read, checked, with its paths resolved.
#[derive(Debug, Clone)]
pub struct Project {
    /// The file.
    pub path: PathBuf,
    /// Its folder (paths are relative to it).
    pub dir: PathBuf,
    /// The contents.
    pub file: ProjectFile,
    /// Image paths, resolved, in the order of `file.images`.
    pub image_paths: Vec<PathBuf>,
    /// Scan paths, resolved.
    pub scan_paths: Vec<PathBuf>,
}

impl Project {
    /// Reads, validates and checks that every named file exists.
    pub fn load(path: &Path) -> Result<Self, ProjectError> {
        let name = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| ProjectError::Io {
            path: name.clone(),
            what: format!("cannot read the project file: {e}"),
        })?;
        let file = ProjectFile::parse(&text, &name)?;
        file.validate(&name)?;
        let dir = path
            .parent()
            .map(Path::to_path_buf)
            .unwrap_or_else(|| PathBuf::from("."));
        let resolve = |rel: &str, what: String| -> Result<PathBuf, ProjectError> {
            let p = dir.join(rel);
            if p.is_file() {
                Ok(p)
            } else {
                Err(ProjectError::Invalid {
                    path: name.clone(),
                    what: format!("{what}: {} not found", p.display()),
                })
            }
        };
        let image_paths = file
            .images
            .iter()
            .enumerate()
            .map(|(k, im)| resolve(&im.file, format!("images[{k}] file \"{}\"", im.file)))
            .collect::<Result<Vec<_>, _>>()?;
        let scan_paths = file
            .lrf
            .scans
            .iter()
            .enumerate()
            .map(|(k, s)| resolve(s, format!("[lrf] scans[{k}] \"{s}\"")))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Project {
            path: path.to_path_buf(),
            dir,
            file,
            image_paths,
            scan_paths,
        })
    }

    /// The index of the main image (main camera at the main station).
    pub fn main_image(&self) -> usize {
        self.file
            .images
            .iter()
            .position(|im| {
                im.station == self.file.main_station && im.camera == self.file.main_camera
            })
            .expect("validated: the main station has an image of the main camera")
    }
}

fn one_line(s: &str) -> String {
    s.lines()
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect::<Vec<_>>()
        .join(" ")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The README's example: the first ```toml block after the heading "## The project file".
    fn readme_example() -> String {
        let readme = include_str!("../../../README.md");
        let at = readme
            .find("## The project file")
            .expect("README has a section '## The project file'");
        let rest = &readme[at..];
        let start = rest
            .find("```toml\n")
            .expect("a toml block in that section")
            + 8;
        let len = rest[start..].find("```").expect("the block ends");
        rest[start..start + len].to_string()
    }

    #[test]
    fn the_documented_example_is_valid() {
        let p = ProjectFile::parse(&readme_example(), "example.toml").unwrap();
        p.validate("example.toml").unwrap();
        assert_eq!(p.cameras.len(), 2);
        assert_eq!(p.balls.labels.len(), 2);
        assert_eq!(p.method(), Method::Both);
        // round trip
        let again = ProjectFile::parse(&p.to_toml_string(), "again").unwrap();
        assert_eq!(again, p);
    }

    fn err_of(edit: impl Fn(&mut ProjectFile)) -> String {
        let mut p = ProjectFile::parse(&readme_example(), "example.toml").unwrap();
        edit(&mut p);
        p.validate("p.toml").unwrap_err().to_string()
    }

    #[test]
    fn invalid_values_are_named() {
        let e = err_of(|p| p.main_station = "S99".into());
        assert!(
            e.contains("main_station = \"S99\" is not the station of any image"),
            "{e}"
        );
        let e = err_of(|p| p.images[0].camera = "middle".into());
        assert!(e.contains("camera 'middle' is not in [[cameras]]"), "{e}");
        let e = err_of(|p| p.cameras[0].free.push("K9".into()));
        assert!(e.contains("free parameter 'K9'"), "{e}");
        let e = err_of(|p| p.distances[0].sigma_mm = 0.0);
        assert!(e.contains("distances[0]") && e.contains("sigma_mm"), "{e}");
        let e = err_of(|p| p.method = "magic".into());
        assert!(e.contains("method = \"magic\""), "{e}");
        let e = err_of(|p| p.balls.check.push("B99".into()));
        assert!(e.contains("'B99' is not one of the labelled balls"), "{e}");
        assert!(e.starts_with("p.toml: "), "{e}");
    }

    #[test]
    fn syntax_errors_have_the_line() {
        let text = readme_example().replace("width = 1280", "width = \"wide\"");
        let e = ProjectFile::parse(&text, "x.toml").unwrap_err().to_string();
        assert!(e.starts_with("x.toml: ") && e.contains("line"), "{e}");
        assert!(!e.contains('\n'));
        let e = ProjectFile::parse(
            &readme_example().replace("[lrf]", "[lrf]\ncolour = 3"),
            "x.toml",
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("colour"), "{e}");
    }

    proptest::proptest! {
        #[test]
        fn parser_never_panics(cut in 0usize..4000, junk in "[ -~\n]{0,40}") {
            let example = readme_example();
            let cut = cut.min(example.len());
            let cut = (0..=cut).rev().find(|&c| example.is_char_boundary(c)).unwrap_or(0);
            let text = format!("{}{}", &example[..cut], junk);
            if let Ok(p) = ProjectFile::parse(&text, "fuzz.toml") {
                let _ = p.validate("fuzz.toml");
            }
        }
    }
}
