//! The scene: what the steps pass along and refine.
//!
//! Step 1 ([`super::detect`]) gives the [`Detections`] of every image; from step 2
//! ([`super::network`]) on, a [`Scene`] holds the camera models, their intrinsics, the pose
//! of each oriented image, and the object points with the detections that measure them.
//! Each later step refines the same scene: matching adds points and measurements, the
//! bundle adjustment moves everything and drops gross errors. Everything here is joined by
//! the typed ids of [`super::ids`].
//!
//! The helpers that several steps need (projecting a point into an image, the σ of an
//! image point, which detections are taken) live here, below every step, so that a step
//! never reaches into another one.

use super::ids::{CameraId, DetIdx, DetectionId, IdVec, ImageId, PointId};
use nalgebra::{Vector2, Vector3};
#[cfg(doc)]
use pingcal_ba::camera::ModelKind;
use pingcal_ba::camera::{CameraModel, SensorCamera};
use pingcal_geometry::Rigid3;
use pingcal_project::Project;
use pingcal_project::ProjectCamera;
use pingcal_targets::ellipse::Ellipse;
use pingcal_targets::Target;

/// The detector's σ of a centre is about half the scatter seen against truth (issue 4's
/// Monte Carlo); image points are weighted with twice that σ, and never below
/// [`MIN_SIGMA_PX`].
pub const SIGMA_FACTOR: f64 = 2.0;
/// Smallest σ given to an image point (px).
pub const MIN_SIGMA_PX: f64 = 0.03;

/// σ of a target's image point (px).
pub fn target_sigma(t: &Target) -> f64 {
    let s = SIGMA_FACTOR * t.sigma_px;
    if s.is_finite() {
        s.max(MIN_SIGMA_PX)
    } else {
        1.0
    }
}

/// The measurements of one image.
#[derive(Clone, Debug)]
pub struct ImageMeasurements {
    /// Width (px).
    pub width: usize,
    /// Height (px).
    pub height: usize,
    /// Targets: coded (with or without a number) and plain (targets or balls).
    pub targets: IdVec<DetIdx, Target>,
    /// For each target: the silhouette refitted as a ball (plain blobs only).
    pub ball_fits: IdVec<DetIdx, Option<BallFit>>,
}

/// A plain blob's silhouette refitted as a ball ([`pingcal_targets::ball`]).
#[derive(Clone, Debug)]
pub struct BallFit {
    /// The ellipse fitted to the silhouette's edge points.
    pub ellipse: Ellipse,
    /// σ of the ellipse's centre (px).
    pub sigma_px: f64,
    /// The sub-pixel edge points, in order around the outline: kept only for a camera whose
    /// balls are fitted to them ([`ModelKind::silhouette_is_ellipse`] false), empty otherwise.
    pub edges: Vec<(f64, f64)>,
}

/// The detections of every project image.
pub type Detections = IdVec<ImageId, ImageMeasurements>;

impl Detections {
    /// The target of detection `d`.
    pub fn target(&self, d: DetectionId) -> &Target {
        &self[d.image].targets[d.det]
    }
}

/// A set of detections (those taken by a point, or by a step).
#[derive(Clone, Debug)]
pub struct DetectionSet(IdVec<ImageId, IdVec<DetIdx, bool>>);

impl DetectionSet {
    /// No detection of `dets`.
    pub fn empty(dets: &Detections) -> Self {
        Self(
            dets.iter()
                .map(|d| vec![false; d.targets.len()].into())
                .collect(),
        )
    }

    /// Whether `d` is in the set.
    pub fn contains(&self, d: DetectionId) -> bool {
        self.0[d.image][d.det]
    }

    /// Puts `d` in the set.
    pub fn insert(&mut self, d: DetectionId) {
        self.0[d.image][d.det] = true;
    }
}

/// What a point of the scene is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PointKind {
    /// A coded target with its number.
    Coded(u32),
    /// A plain target.
    Plain,
    /// A ping-pong ball (its centre).
    Ball,
}

impl PointKind {
    /// `coded`, `plain` or `ball`.
    pub fn as_str(&self) -> &'static str {
        match self {
            PointKind::Coded(_) => "coded",
            PointKind::Plain => "plain",
            PointKind::Ball => "ball",
        }
    }
}

/// An object point and the detections that measure it.
#[derive(Clone, Debug)]
pub struct ScenePoint {
    /// Label: the coded number, `P1`…, or the ball id.
    pub name: String,
    /// What it is.
    pub kind: PointKind,
    /// Position (photogrammetric frame once [`super::network`] is done), mm.
    pub position: Vector3<f64>,
    /// The detections measuring it (at most one per image).
    pub obs: Vec<DetectionId>,
}

/// The camera of project camera `c`: its model ([`pingcal_ba::camera::ModelKind`], the
/// project's `model`) built for its sensor.
pub fn sensor_camera(c: &ProjectCamera) -> SensorCamera {
    SensorCamera::new(c.model, c.width, c.height, c.pixel_size_mm)
}

/// The photogrammetric scene as it grows through the steps.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The model of each project camera with its sensor.
    pub cameras: IdVec<CameraId, SensorCamera>,
    /// The camera of each project image.
    pub camera_of: IdVec<ImageId, CameraId>,
    /// Intrinsics of each project camera.
    pub intrinsics: IdVec<CameraId, Vec<f64>>,
    /// Pose of each project image (None: not oriented).
    pub poses: IdVec<ImageId, Option<Rigid3>>,
    /// Object points.
    pub points: IdVec<PointId, ScenePoint>,
    /// Why images are not oriented.
    pub unoriented: Vec<(ImageId, String)>,
    /// How the network started, for the log and results.json (e.g. "relative orientation").
    pub start: String,
    /// Doubts the steps raised that the report must show (a start that failed before the
    /// one that worked, a layout point the images place elsewhere).
    pub warnings: Vec<String>,
    /// Coded numbers read where the network puts no such target (named blunders): their
    /// detections are used by no point.
    pub blunders: Vec<CodedBlunder>,
}

/// The named blunder of coded detection `d`, which read number `n`, when it lies `off_px` from
/// where the network puts target `n` in its image and that is beyond the reach of the
/// detection's own code ring (`ring_outer` times its dot's major semi-axis): no centring
/// error puts a target outside its own ring, so the number is not that target's. None when it
/// is within reach (a poor centre, not a wrong number).
pub fn coded_blunder(
    project: &Project,
    dets: &Detections,
    d: DetectionId,
    n: u32,
    off_px: f64,
    stage: &'static str,
) -> Option<CodedBlunder> {
    let t = dets.target(d);
    let reach = project.file.targets.ring_outer * t.ellipse.a;
    (off_px > reach).then(|| CodedBlunder {
        det: d,
        number: n,
        stage,
        why: format!(
            "{off_px:.1} px from where the network puts target {n}, beyond its code ring ({reach:.1} px)"
        ),
    })
}

/// A coded number read where the network says that target is not: a misread number (or a
/// target that moved between the images). The detection is removed from its point and used by
/// none, and the blunder is logged and reported (report.html's rejections, results.json's
/// `bundle.coded_blunders`).
#[derive(Clone, Debug, PartialEq)]
pub struct CodedBlunder {
    /// The detection.
    pub det: DetectionId,
    /// The number it read.
    pub number: u32,
    /// The step that found it.
    pub stage: &'static str,
    /// Why, with the figures (how far from where the network puts the target).
    pub why: String,
}

impl Scene {
    /// A scene of `project` with no image oriented and no point; the intrinsics are the
    /// project's initial values.
    pub fn new(project: &Project) -> Self {
        let f = &project.file;
        Scene {
            cameras: f.cameras.iter().map(sensor_camera).collect(),
            camera_of: f
                .images
                .iter()
                .map(|im| {
                    CameraId(
                        f.cameras
                            .iter()
                            .position(|c| c.id == im.camera)
                            .expect("validated camera"),
                    )
                })
                .collect(),
            intrinsics: f.cameras.iter().map(|c| c.intrinsics().values).collect(),
            poses: f.images.iter().map(|_| None).collect(),
            points: IdVec::new(),
            unoriented: Vec::new(),
            start: String::new(),
            warnings: Vec::new(),
            blunders: Vec::new(),
        }
    }

    /// Detections already used by a point, or named a blunder (no point may use them).
    pub fn used(&self, dets: &Detections) -> DetectionSet {
        let mut used = DetectionSet::empty(dets);
        for p in &self.points {
            for &d in &p.obs {
                used.insert(d);
            }
        }
        for b in &self.blunders {
            used.insert(b.det);
        }
        used
    }

    /// Names `b` a blunder (once per detection): its detection leaves every point. Returns
    /// whether it is new.
    pub fn add_blunder(&mut self, b: CodedBlunder) -> bool {
        if self.blunders.iter().any(|x| x.det == b.det) {
            return false;
        }
        for p in self.points.iter_mut() {
            p.obs.retain(|&d| d != b.det);
        }
        self.blunders.push(b);
        true
    }

    /// The oriented images, in project order.
    pub fn oriented(&self) -> Vec<ImageId> {
        self.poses
            .ids()
            .filter(|&i| self.poses[i].is_some())
            .collect()
    }

    /// The point of coded target `n`, if the scene has it.
    pub fn coded(&self, n: u32) -> Option<PointId> {
        self.points.position(|p| p.kind == PointKind::Coded(n))
    }

    /// Projects `x` into image `i` (None: not oriented, behind, or outside the frame).
    pub fn project_into(&self, i: ImageId, x: &Vector3<f64>) -> Option<Vector2<f64>> {
        let pose = self.poses[i]?;
        let c = self.camera_of[i];
        let cam = &self.cameras[c];
        let xc = pose.transform(x);
        if xc.y <= 0.0 {
            return None;
        }
        let uv = cam.project(&self.intrinsics[c], &xc, None, None)?;
        cam.on_image(&uv).then_some(uv)
    }
}

/// The main image of the project.
pub fn main_image(project: &Project) -> ImageId {
    ImageId(project.main_image())
}

/// The file name of image `i` (as `[[images]] file` gives it).
pub fn image_file(project: &Project, i: ImageId) -> &str {
    &project.file.images[i.0].file
}
