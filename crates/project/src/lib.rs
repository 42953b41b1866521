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
//! The modules, in the order a file goes through them: `schema` (the tables of the file),
//! `closed_sets` (the words `method`, `family`, `model`, `free` and `self_calibrate` take,
//! refused at parse time when unknown, as the LRF's words are: `[lrf] noise`, `cloud_unit`,
//! `[lrf.bag] servo_motion`), `parse` (text to [`ProjectFile`], errors with the line),
//! `validate` (the file against itself) and `settings` (the `[lrf]` keys resolved into the
//! values the pipeline uses: [`LrfSettings`]). Every refusal of a project happens in
//! [`Project::load`], before the pipeline reads an image.
//!
//! docs/project.md has a complete, commented example; the tests of this crate parse and
//! validate that very text, so it cannot drift.

#[macro_use]
pub mod board;
pub mod camera_file;
mod closed_sets;
pub mod intrinsics;
mod layout;
mod parse;
mod schema;
pub mod settings;
pub mod sphere_calib;
mod validate;
pub mod yaml;

pub use board::{board_file, Board, ProjectBoard};
pub use camera_file::{CameraFile, CameraFormat};
pub use closed_sets::{
    ArucoDictionary, BoardKind, CameraModel, LrfKind, Method, MountParameter, Parameter, TagFamily,
    TargetFamily,
};
pub use intrinsics::{Intrinsics, KeyedValues};
pub use layout::{Layout, LayoutError};
pub use schema::{
    BallLabel, CameraParams, ProjectBag, ProjectBalls, ProjectCamera, ProjectDistance, ProjectFile,
    ProjectFrames, ProjectImage, ProjectLrf, ProjectNetwork, ProjectRig, ProjectRigCamera,
    ProjectStereo, ProjectTargets, ScanAtStation, ScanEntry, PARAMETER_NAMES,
};
pub use settings::{BagServo, LrfSettings};
pub use sphere_calib::{SphereCalibFile, SphereCalibFrame, SphereCalibLidar};

use pingcal_lrf::cloud_file::{read_lrf_model, CloudPath};
use std::path::{Path, PathBuf};

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

/// The most bytes of a text file the project names (a layout of 10⁶ targets is 50 MB).
const MAX_TEXT_BYTES: u64 = 64 << 20;

/// The text of `path`, refused (not read) when larger than [`MAX_TEXT_BYTES`]; `what` names
/// it in errors.
fn read_small(path: &Path, what: &str) -> Result<String, ProjectError> {
    let io = |e: String| ProjectError::Io {
        path: path.display().to_string(),
        what: format!("cannot read {what}: {e}"),
    };
    let len = std::fs::metadata(path)
        .map_err(|e| io(e.to_string()))?
        .len();
    if len > MAX_TEXT_BYTES {
        return Err(io(format!(
            "{len} bytes, more than the {MAX_TEXT_BYTES} a text file of a project may have"
        )));
    }
    std::fs::read_to_string(path).map_err(|e| io(e.to_string()))
}

/// Refuses a file named twice, under any spelling (`images/./a.png`, `../p/images/a.png`, a
/// symbolic link): the paths are compared as [`std::fs::canonicalize`] resolves them.
/// `names[k]` names `paths[k]` in the error; `file` is the project file.
fn once_each(paths: &[PathBuf], names: &[String], file: &str) -> Result<(), ProjectError> {
    let mut seen: std::collections::HashMap<PathBuf, usize> = Default::default();
    for (k, p) in paths.iter().enumerate() {
        let canon = std::fs::canonicalize(p).unwrap_or_else(|_| p.clone());
        if let Some(&first) = seen.get(&canon) {
            return Err(ProjectError::Invalid {
                path: file.to_string(),
                what: format!(
                    "{} is the same file as {}: each file is listed once",
                    names[k], names[first]
                ),
            });
        }
        seen.insert(canon, k);
    }
    Ok(())
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
    /// `[lrf] scans`, resolved and classified (scan file or cloud), in their order.
    pub scans: Vec<CloudPath>,
    /// The coded targets' layout (`[targets] layout`), read.
    pub layout: Option<Layout>,
    /// `[lrf.bag]` files (bag files or ROS 2 bag folders), resolved.
    pub bag_paths: Vec<PathBuf>,
    /// The `[lrf]` settings, resolved: the range noise, the clouds' unit, the bag's servo,
    /// and the mount (the `lrf_model` file's when the project names one).
    pub lrf: LrfSettings,
    /// Each of `[[lrfs]]` as a project of its own: this one's file with that sensor as its
    /// `[lrf]` (and its id as the tf frame of its outputs), resolved and checked as `[lrf]`
    /// is; calibrated against the same camera side.
    pub range_sensors: Vec<Project>,
}

/// Reads every `pingcal-scan` file of `[lrf] scans` through
/// ([`pingcal_lrf::scan::check_scan_file`]): a malformed line, a file cut short, data that
/// contradict the file's units (a servo column in radians, ranges in metres), or a servo
/// that contradicts the LRF's `kind` (a rotating LRF's that never turned, a fixed one's that
/// did: [`pingcal_lrf::scan::ServoSpan::kind_slip`]) are refused here, before the camera
/// side runs, naming the entry and the file.
fn check_scan_files(
    paths: &[PathBuf],
    entries: &[String],
    name: &str,
    kind: LrfKind,
) -> Result<(), ProjectError> {
    let refuse = |entry: &str, what: String| ProjectError::Invalid {
        path: name.to_string(),
        what: format!("{entry}: {what}"),
    };
    for (p, entry) in paths.iter().zip(entries) {
        if !CloudPath::new(p.clone()).is_scans() {
            continue;
        }
        let span =
            pingcal_lrf::scan::check_scan_file(p).map_err(|e| refuse(entry, e.to_string()))?;
        if let Some(why) = span.and_then(|s| s.kind_slip(kind == LrfKind::Fixed)) {
            return Err(refuse(entry, format!("{}: {why}", p.display())));
        }
    }
    Ok(())
}

impl Project {
    /// Reads, validates and checks that every named file exists, and reads the scan files
    /// through ([`pingcal_lrf::scan::check_scan_file`]): a malformed line or a unit slip is refused here.
    pub fn load(path: &Path) -> Result<Self, ProjectError> {
        let name = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| ProjectError::Io {
            path: name.clone(),
            what: format!("cannot read the project file: {e}"),
        })?;
        let file = ProjectFile::parse(&text, &name)?;
        let mut project = Self::resolved(path, file.clone())?;
        for k in 0..file.lrfs.len() {
            let one = file.with_range_sensor(k);
            let id = one.lrf.id().to_string();
            let sensor = Self::resolved(path, one).map_err(|e| match e {
                ProjectError::Invalid { path, what } => ProjectError::Invalid {
                    path,
                    what: format!("[[lrfs]] id = \"{id}\" (checked as its own [lrf]): {what}"),
                },
                other => other,
            })?;
            project.range_sensors.push(sensor);
        }
        Ok(project)
    }

    /// `file` (read from `path`) validated and its files resolved, without `[[lrfs]]`'s
    /// projects ([`Project::load`] adds them).
    fn resolved(path: &Path, file: ProjectFile) -> Result<Self, ProjectError> {
        let name = path.display().to_string();
        let mut lrf = file.checked(&name)?;
        let dir = path
            .parent()
            .map(Path::to_path_buf)
            .unwrap_or_else(|| PathBuf::from("."));
        // `rel` under the project's folder, when `accept` takes it (a file; a bag may be a
        // ROS 2 bag's folder)
        let resolve_as = |rel: &str, what: String, accept: fn(&Path) -> bool| {
            let p = dir.join(rel);
            if accept(&p) {
                Ok(p)
            } else {
                Err(ProjectError::Invalid {
                    path: name.clone(),
                    what: format!("{what}: {} not found", p.display()),
                })
            }
        };
        let resolve = |rel: &str, what: String| resolve_as(rel, what, Path::is_file);
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
            .map(|(k, s)| resolve(s.file(), format!("[lrf] scans[{k}] \"{s}\"")))
            .collect::<Result<Vec<_>, _>>()?;
        let images: Vec<String> = (file.images.iter().enumerate())
            .map(|(k, im)| format!("images[{k}] file \"{}\"", im.file))
            .collect();
        once_each(&image_paths, &images, &name)?;
        let scans: Vec<String> = (file.lrf.scans.iter().enumerate())
            .map(|(k, s)| format!("[lrf] scans[{k}] \"{s}\""))
            .collect();
        once_each(&scan_paths, &scans, &name)?;
        check_scan_files(&scan_paths, &scans, &name, file.lrf.kind())?;
        let layout = match &file.targets.layout {
            None => None,
            Some(rel) => {
                let p = resolve(rel, format!("[targets] layout \"{rel}\""))?;
                let text = read_small(&p, "the layout named by [targets] layout")?;
                let layout = Layout::parse(&text, &p.display().to_string()).map_err(|e| {
                    ProjectError::Invalid {
                        path: name.clone(),
                        what: format!("[targets] layout: {e}"),
                    }
                })?;
                Some(layout)
            }
        };
        // `[board] from`: Kalibr's file read and checked now (the table was checked with
        // the rest of the file).
        if let Some(b) = file.board.as_ref().filter(|b| b.from.is_some()) {
            b.resolve(&dir).map_err(|what| ProjectError::Invalid {
                path: name.clone(),
                what,
            })?;
        }
        let bags = file.lrf.bag.as_ref().map_or(&[][..], |b| &b.files[..]);
        let bag_paths = bags
            .iter()
            .enumerate()
            .map(|(k, s)| resolve_as(s, format!("[lrf.bag] files[{k}] \"{s}\""), Path::exists))
            .collect::<Result<Vec<_>, _>>()?;
        let bag_names: Vec<String> = (bags.iter().enumerate())
            .map(|(k, s)| format!("[lrf.bag] files[{k}] \"{s}\""))
            .collect();
        once_each(&bag_paths, &bag_names, &name)?;
        if let Some(rel) = &file.lrf.lrf_model {
            let p = resolve(rel, format!("[lrf] lrf_model \"{rel}\""))?;
            lrf.mount = read_lrf_model(&p).map_err(|e| ProjectError::Invalid {
                path: name.clone(),
                what: format!("[lrf] lrf_model: {e}"),
            })?;
        }
        Ok(Project {
            path: path.to_path_buf(),
            dir,
            file,
            image_paths,
            scans: scan_paths.into_iter().map(CloudPath::new).collect(),
            layout,
            bag_paths,
            lrf,
            range_sensors: Vec::new(),
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

#[cfg(test)]
mod tests;
