//! Step 7: `results.json` (the keys docs/formats.md lists) and `cloud.ply`; [`super::report`]
//! builds the report data from them.
//!
//! `extrinsic`, `check_points` and `mean_check_error_mm` are the joint adjustment's when it
//! ran and succeeded, else the sphere method's, else the corner baseline's; `methods` holds
//! every method side by side, and `lrf_mount` the joint adjustment's mount and range
//! parameters with their σ, why any was held, and their correlations with the extrinsic. Every estimate has
//! its standard deviation. Camera parameters are in the units of docs/formats.md (mm, mm⁻², …) and
//! also converted to OpenCV's (fx, fy, cx, cy, k1, k2, p1, p2, k3): `k1 = K1 c²`,
//! `k2 = K2 c⁴`, `k3 = K3 c⁶`, `p1 = −P2 c`, `p2 = P1 c` (OpenCV's y axis points down),
//! `fx = c (1 + B1) / pixel`, `fy = c / pixel`, `cx = (W − 1)/2 + xp / pixel`,
//! `cy = (H − 1)/2 − yp / pixel`; B1 enters fx to first order and B2 (shear) has no OpenCV
//! counterpart: `opencv_dropped_b2` says how large it was.
//!
//! Every transform is also written as a 4×4 matrix and a unit quaternion, and again in
//! OpenCV's camera frame (`p_cv = C · p`, C = [`cv_from_photogrammetric`]); the
//! `conventions` block ([`conventions`]) says in words which frame is which and which way
//! every transform maps, for the programs and people that read the file.

use super::adjust::rig_cameras;
use super::bundle::Adjusted;
pub use super::conventions::{conventions, ConventionsJson};
use super::extrinsic::Extrinsics;
use super::ids::CameraId;
use super::joint::JointOutcome;
use super::lrf::LrfData;
use super::scene::{image_file, PointKind, Scene};
use super::verdict::Verdict;
use crate::stages::Stages;
use nalgebra::{Matrix3, Vector3};
use pingcal_ba::camera::forms::{form, opencv_of_photogrammetric, Ecosystem, Source};
use pingcal_ba::camera::refit::{grid_pixels, GridRays};
use pingcal_ba::solver::VarianceComponent;
use pingcal_geometry::Sim3;
use pingcal_lrf::registration::{CheckRow, PointObs};
use pingcal_project::{Intrinsics, Project};
use serde::Serialize;

pub mod sensors;
mod transforms;

pub use sensors::{SensorJson, SensorPairJson};
pub use transforms::{
    cv_from_photogrammetric, extrinsic_json, matrix_4x4, quaternion_xyzw, rig_json, transform_json,
    ExtrinsicJson, RigJson, TransformJson,
};
use transforms::{mat, rig_of};

/// One method's results.
#[derive(Clone, Debug, Serialize)]
pub struct MethodJson {
    /// `spheres` or `corner`.
    pub method: String,
    /// The extrinsic.
    pub extrinsic: Option<ExtrinsicJson>,
    /// Check balls (dx = estimated − reference).
    pub check_points: Vec<CheckRow>,
    /// Mean of their errors (mm).
    pub mean_check_error_mm: Option<f64>,
    /// Their standard deviation (mm).
    pub sd_check_error_mm: Option<f64>,
    /// Where the check rows come from: `check` balls or `leave_one_out`.
    pub check_points_source: String,
    /// Residuals of the control balls (spheres only).
    pub control_points: Vec<CheckRow>,
    /// Leave-one-out over the control balls (spheres only).
    pub leave_one_out: Vec<CheckRow>,
    /// σ0 of the registration (spheres), of the joint adjustment with the a-priori σ's
    /// (joint).
    pub sigma0: Option<f64>,
    /// Joint only: the beams' σ0 against the sensor's σ(r) (their variance component), by
    /// which they were re-weighted before the extrinsic's covariance was taken.
    pub variance_components: Vec<VarianceComponent>,
    /// Joint only: every observation group of the adjustment (the beams on the balls, on
    /// the planes, …) with its observations, those removed as gross errors and left out, its
    /// χ² with the a-priori σ's and its RMS: the lines σ0's χ² is the sum of (with the
    /// bundle's and the priors').
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub observation_groups: Vec<super::joint::GroupOutcome>,
    /// Why the method failed.
    pub error: Option<String>,
    /// What it chose and why.
    pub notes: Vec<String>,
}

/// Bundle adjustment summary.
#[derive(Clone, Debug, Serialize)]
pub struct BundleJson {
    /// A-posteriori σ0 with the a-priori σ's of the image points and distances (what the
    /// verdict tests).
    pub sigma0: f64,
    /// σ0 of each group of observations (`targets`, `balls`, `distances`) against its
    /// a-priori σ's: the variance components by which the final adjustment re-weighted each
    /// group (those with redundancy of at least 30) before its covariances were taken.
    pub variance_components: Vec<VarianceComponent>,
    /// RMS image residual (px).
    pub rms_image_px: f64,
    /// Oriented images.
    pub images: usize,
    /// Images of the project left out (file, why).
    pub unoriented_images: Vec<(String, String)>,
    /// How the initial network started (`pingcal calibrate --start`).
    pub network_start: String,
    /// Object points.
    pub points: usize,
    /// Image observations.
    pub observations: usize,
    /// Distances.
    pub distances: usize,
    /// Iterations of the final adjustments.
    pub iterations: usize,
    /// Redundancy.
    pub redundancy: i64,
    /// Image points rejected by data snooping.
    pub rejected: usize,
    /// `[[distances]]` entries rejected by data snooping (a distance given wrong): each with
    /// its place in the list, its targets, the values given and adjusted, and its w.
    pub rejected_distances: Vec<crate::bundle::RejectedDistance>,
    /// Coded numbers read where the network puts no such target (named blunders), removed.
    pub coded_blunders: Vec<CodedBlunderJson>,
    /// Stereo rig, left → right camera frame.
    pub rig: Option<RigJson>,
}

/// A coded number named a blunder: read in `image` at (`x`, `y`) px where the network puts no
/// target of that number, found at `stage`, and why.
#[derive(Clone, Debug, Serialize)]
pub struct CodedBlunderJson {
    /// The image file.
    pub image: String,
    /// The number read.
    pub number: u32,
    /// Where it was read: x, px to the right of the centre of the top-left pixel.
    pub x: f64,
    /// Where it was read: y, px down from the centre of the top-left pixel.
    pub y: f64,
    /// The step that found it (`network start`, `coincident numbers`, `driveback`,
    /// `matching`, `final bundle`).
    pub stage: String,
    /// Why, with the figures.
    pub why: String,
}

/// A camera's intrinsics.
#[derive(Clone, Debug, Serialize)]
pub struct CameraJson {
    /// Camera id.
    pub id: String,
    /// The camera model, absent for the photogrammetric model (the default).
    #[serde(rename = "model", skip_serializing_if = "Option::is_none")]
    pub model_name: Option<&'static str>,
    /// The model's parameters by their keys (`c_mm`, `xp_mm`, …, `b2` for the
    /// photogrammetric model; `fx`, `fy`, `cx`, `cy`, … for the others; docs/formats.md).
    #[serde(flatten)]
    pub params: Intrinsics,
    /// σ of each parameter, by name (free parameters only; fixed ones are absent).
    pub sigma: std::collections::BTreeMap<String, f64>,
    /// Pairs of parameters correlated beyond 0.9.
    pub high_correlations: Vec<(String, String, f64)>,
    /// The same camera in OpenCV's model (pixels; see the module doc).
    pub opencv: OpenCvJson,
    /// Pixel pitch (mm), as the project gives it.
    #[serde(skip)]
    pub pixel_size_mm: f64,
}

impl CameraJson {
    /// The camera's model, built for its sensor.
    pub fn model(&self) -> std::sync::Arc<dyn pingcal_ba::camera::CameraModel> {
        self.params.model.model(
            self.opencv.image_width,
            self.opencv.image_height,
            self.pixel_size_mm,
        )
    }
}

/// OpenCV intrinsics.
#[derive(Clone, Debug, Serialize)]
pub struct OpenCvJson {
    /// fx (px).
    pub fx: f64,
    /// fy (px).
    pub fy: f64,
    /// cx (px).
    pub cx: f64,
    /// cy (px).
    pub cy: f64,
    /// The distortion coefficients: k1, k2, p1, p2, k3 (then k4, k5, k6, and s1–s4 where
    /// the model needs them), or k1–k4 of OpenCV's `fisheye`.
    pub dist: Vec<f64>,
    /// `rational_polynomial`, `thin_prism` or `fisheye` (absent: `plumb_bob`).
    #[serde(skip_serializing_if = "is_plumb_bob")]
    pub distortion_model: &'static str,
    /// B2, which OpenCV cannot hold (the photogrammetric model only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub opencv_dropped_b2: Option<f64>,
    /// Image width (px).
    pub image_width: u32,
    /// Image height (px).
    pub image_height: u32,
}

fn is_plumb_bob(s: &&'static str) -> bool {
    *s == "plumb_bob"
}

/// A ball in both frames.
#[derive(Clone, Debug, Serialize)]
pub struct BallJson {
    /// Id.
    pub id: String,
    /// Check ball.
    pub check: bool,
    /// Centre in the photogrammetric frame (mm), from the adjustment whose result is given:
    /// the joint adjustment's (a control ball's LRF beams join its image rays, a check
    /// ball has its image rays only), else the bundle adjustment's.
    pub photogrammetric_mm: [f64; 3],
    /// Its σ (mm).
    pub photogrammetric_sigma_mm: [f64; 3],
    /// Its covariance (mm², row-major), from the same adjustment.
    pub photogrammetric_cov_mm2: [[f64; 3]; 3],
    /// Centre of the matched LRF sphere in the LRF frame (mm), if any: the sphere of
    /// `cloud.ply`, found in the cloud made through `lrf_model`.
    pub lrf_mm: Option<[f64; 3]>,
    /// Its σ (mm).
    pub lrf_sigma_mm: Option<[f64; 3]>,
    /// Its covariance (mm², row-major), from the sphere fit.
    pub lrf_cov_mm2: Option<[[f64; 3]; 3]>,
    /// `R · lrf_mm + t − photogrammetric_mm` with the extrinsic of `results.json` (mm): for
    /// a check ball its check error, for a control ball its residual.
    pub residual_mm: Option<[f64; 3]>,
    /// σ of `residual_mm` as predicted by both centres' and the extrinsic's covariances
    /// (mm; for a control ball, which helped estimate the extrinsic, an upper bound).
    pub residual_sigma_mm: Option<[f64; 3]>,
    /// The two-step method's sphere centre, through the project's mount (mm): not in the
    /// frame of the extrinsic given when `lrf_model` is the joint adjustment's. Absent when it
    /// is `lrf_mm`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lrf_project_mount_mm: Option<[f64; 3]>,
    /// Images measuring the ball.
    pub rays: usize,
}

/// `results.json`.
#[derive(Clone, Debug, Serialize)]
pub struct Results {
    /// What wrote it.
    pub generator: String,
    /// Whether to trust it ([`super::verdict`]).
    pub verdict: Verdict,
    /// The project's name.
    pub project: String,
    /// Frames, axes, units, the direction of every transform and the angle orders.
    pub conventions: ConventionsJson,
    /// The extrinsic of the primary method: the joint adjustment's when it ran and
    /// succeeded, else the sphere method's, else the corner baseline's.
    pub extrinsic: ExtrinsicJson,
    /// Its check points.
    pub check_points: Vec<CheckRow>,
    /// Their mean error (mm).
    pub mean_check_error_mm: f64,
    /// Every method that ran, the primary first.
    pub methods: Vec<MethodJson>,
    /// The LRF's mount and range parameters of the joint adjustment (absent when it did not
    /// run or failed).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lrf_mount: Option<Vec<MountJson>>,
    /// The whole LRF model (mount and range) that `cloud.ply`, `balls[].lrf_mm`, the check
    /// tables and every export use: the joint adjustment's estimate when its result is the
    /// one given, else the project's (`pingcal cloud --lrf-model results.json` reads it).
    pub lrf_model: LrfModelJson,
    /// Every sensor of the head but the reference (main) camera: the cameras that follow
    /// it (`[stereo]`, `[rig]`), then the LRF, each with `camera_from_sensor` and its σ's
    /// ([`crate::head`]).
    pub sensors: Vec<sensors::SensorJson>,
    /// Every pair of `sensors`: `a_from_b` composed from their transforms, with σ's from
    /// the joint covariance.
    pub sensor_pairs: Vec<sensors::SensorPairJson>,
    /// The bundle adjustment.
    pub bundle: BundleJson,
    /// Intrinsics.
    pub cameras: Vec<CameraJson>,
    /// Balls.
    pub balls: Vec<BallJson>,
    /// Targets (label, kind, position mm, σ mm).
    pub targets: Vec<TargetRow>,
    /// Seconds per step, in order. Not written to `results.json`, so that the same input
    /// and seed give the same bytes (the step log of the report has the times).
    #[serde(skip)]
    pub time_s: Vec<(String, f64)>,
}

/// A method that failed.
fn failed(method: &str, e: &str) -> MethodJson {
    MethodJson {
        method: method.into(),
        extrinsic: None,
        check_points: Vec::new(),
        mean_check_error_mm: None,
        sd_check_error_mm: None,
        check_points_source: String::new(),
        control_points: Vec::new(),
        leave_one_out: Vec::new(),
        sigma0: None,
        variance_components: Vec::new(),
        observation_groups: Vec::new(),
        error: Some(e.to_string()),
        notes: Vec::new(),
    }
}

/// The joint adjustment's results.
fn joint_json(j: &JointOutcome, ext: &Extrinsics) -> MethodJson {
    let t = &j.camera_from_lrf;
    let sim = Sim3::new(1.0, t.rotation, t.translation);
    MethodJson {
        method: "joint".into(),
        extrinsic: Some(extrinsic_json(
            &sim,
            Some(j.sigma_translation_mm),
            Some(j.sigma_opk_deg),
        )),
        check_points: j.check.rows.clone(),
        mean_check_error_mm: Some(j.check.mean_mm),
        sd_check_error_mm: Some(j.check.sd_mm),
        check_points_source: if ext.check_ids.is_empty() {
            "none".into()
        } else {
            "check".into()
        },
        control_points: j.control.rows.clone(),
        leave_one_out: Vec::new(),
        sigma0: Some(j.sigma0),
        variance_components: j.variance_components.clone(),
        observation_groups: j.groups.clone(),
        error: None,
        notes: std::iter::once(joint_note(j))
            .chain(j.notes.iter().cloned())
            .collect(),
    }
}

/// The joint adjustment's first note: its beams on the balls, the balls, its redundancy.
fn joint_note(j: &JointOutcome) -> String {
    let b = j.ball_beams();
    format!(
        "{} LRF beams on {} control balls ({} removed as gross errors, {} grazing and {} at a ball's silhouette left out); RMS beam residual {:.2} mm; redundancy {}",
        b.used,
        j.control.rows.len(),
        b.rejected,
        b.grazing,
        b.silhouette,
        b.rms_mm,
        j.redundancy
    )
}

/// The LRF model of `results.json`'s `lrf_model`.
#[derive(Clone, Debug, Serialize)]
pub struct LrfModelJson {
    /// `joint adjustment` (estimated) or `project` (the project file's `[lrf]` mount).
    pub source: String,
    /// `fixed` for a fixed LRF (its model is its range offset and scale: no servo, no
    /// mount); absent for a rotating one.
    #[serde(skip_serializing_if = "is_rotating")]
    pub kind: pingcal_project::LrfKind,
    /// The model: `p = R_β (R_x(tilt_x) R_z(tilt_z) (r cos α, r sin α, 0) + offset)`,
    /// `β = (servo − servo_zero)(1 + servo_scale)`, `reported = r (1 + range_scale) +
    /// range_offset` (docs/lrf.md).
    #[serde(flatten)]
    pub model: pingcal_lrf::MountModel,
}

/// Whether `kind` is rotating (not written to results.json, as before fixed LRFs).
fn is_rotating(kind: &pingcal_project::LrfKind) -> bool {
    *kind == pingcal_project::LrfKind::Rotating
}

/// The LRF model the outputs use (see [`Results::lrf_model`]).
pub fn lrf_model_of(st: &Stages) -> LrfModelJson {
    let kind = st.project.file.lrf.kind();
    match st.joint {
        Some(Ok(j)) => LrfModelJson {
            source: "joint adjustment".into(),
            kind,
            model: j.mount_model,
        },
        _ => LrfModelJson {
            source: "project".into(),
            kind,
            model: st.lrf.mount,
        },
    }
}

/// One mount parameter in `results.json`.
#[derive(Clone, Debug, Serialize)]
pub struct MountJson {
    /// `offset_x`, …, `range_scale` (as `[lrf] self_calibrate` spells them), and
    /// `time_offset_s` for a continuous sweep.
    pub name: String,
    /// Value: mm for offsets, degrees for tilts, 1 for scales, seconds for the time offset.
    pub value: f64,
    /// Its σ (null when held).
    pub sigma: Option<f64>,
    /// Why it was held (null: estimated).
    pub held: Option<String>,
    /// Correlations with the extrinsic's rotation-vector components and translation
    /// (δω, δφ, δκ, tx, ty, tz); null when held.
    pub correlation_with_extrinsic: Option<[f64; 6]>,
}

/// The mount parameters, then the servo time offset where the sweep was continuous.
fn mount_json(j: &JointOutcome) -> Vec<MountJson> {
    (j.mount.iter().chain(&j.time_offset))
        .map(|m| MountJson {
            name: m.name.to_string(),
            value: m.value,
            sigma: m.sigma,
            held: m.held.clone(),
            correlation_with_extrinsic: m.corr_extrinsic,
        })
        .collect()
}

fn methods(
    ext: &Extrinsics,
    joint: &Option<std::result::Result<JointOutcome, super::joint::JointError>>,
) -> Vec<MethodJson> {
    let mut out = Vec::new();
    match joint {
        Some(Ok(j)) => out.push(joint_json(j, ext)),
        Some(Err(e)) => out.push(failed("joint", &e.message)),
        None => {}
    }
    if let Some(ev) = &ext.spheres {
        let r = &ev.registration;
        let (table, source) = if ev.check.rows.is_empty() {
            (&ev.leave_one_out, "leave_one_out")
        } else {
            (&ev.check, "check")
        };
        out.push(MethodJson {
            method: "spheres".into(),
            extrinsic: Some(extrinsic_json(
                &r.camera_from_lrf,
                Some(r.sigma_translation_mm.into()),
                Some(r.sigma_opk_deg.into()),
            )),
            check_points: table.rows.clone(),
            mean_check_error_mm: Some(table.mean_mm),
            sd_check_error_mm: Some(table.sd_mm),
            check_points_source: source.into(),
            control_points: ev.control.rows.clone(),
            leave_one_out: ev.leave_one_out.rows.clone(),
            sigma0: Some(r.sigma0),
            variance_components: Vec::new(),
            observation_groups: Vec::new(),
            error: None,
            notes: (ext.through_room.iter().cloned())
                .chain(
                    (ev.loo_skipped.iter())
                        .map(|(id, why)| format!("leave-one-out skipped {id}: {why}")),
                )
                .collect(),
        });
    }
    if let Some(c) = &ext.corner {
        out.push(match c {
            Ok(c) => MethodJson {
                method: "corner".into(),
                extrinsic: Some(extrinsic_json(&c.camera_from_lrf, None, None)),
                check_points: c.check.rows.clone(),
                mean_check_error_mm: Some(c.check.mean_mm),
                sd_check_error_mm: Some(c.check.sd_mm),
                check_points_source: if ext.check_ids.is_empty() {
                    "all_balls".into()
                } else {
                    "check".into()
                },
                control_points: Vec::new(),
                leave_one_out: Vec::new(),
                sigma0: None,
                variance_components: Vec::new(),
                observation_groups: Vec::new(),
                error: None,
                notes: c.notes.clone(),
            },
            Err(e) => failed("corner", e),
        });
    }
    out
}

/// Camera `params` of a `width × height` sensor of pitch `pixel_mm` in OpenCV's model
/// ([`pingcal_ba::camera::forms`]: the photogrammetric model in closed form, B1 to first
/// order and B2 dropped; the OpenCV and Kannala–Brandt models as they are; the others
/// fitted over the image).
pub fn opencv_of(params: &Intrinsics, width: u32, height: u32, pixel_mm: f64) -> OpenCvJson {
    let kind = params.model;
    let p = &params.values;
    let (k, dist, name) = if kind.opencv_closed_form() {
        let (k, d) = opencv_of_photogrammetric(p, width, height, pixel_mm);
        (k, d.to_vec(), "plumb_bob")
    } else {
        let model = kind.model(width, height, pixel_mm);
        let grid = GridRays::of(model.as_ref(), p, &grid_pixels(width, height));
        let src = Source {
            kind,
            params: p,
            width,
            height,
            pixel_size_mm: pixel_mm,
            grid: &grid,
        };
        match form(&src, Ecosystem::OpenCv) {
            Some(f) => (f.k(), f.coeffs.clone(), f.distortion_model),
            None => {
                let (f, c) = (model.focal_px(p), model.principal_point_px(p));
                ([f, f, c.x, c.y], vec![0.0; 5], "plumb_bob")
            }
        }
    };
    OpenCvJson {
        fx: k[0],
        fy: k[1],
        cx: k[2],
        cy: k[3],
        dist,
        distortion_model: name,
        opencv_dropped_b2: kind.opencv_closed_form().then(|| p[9]),
        image_width: width,
        image_height: height,
    }
}

fn camera_json(project: &Project, scene: &Scene, adj: &Adjusted, c: CameraId) -> CameraJson {
    let cam = &project.file.cameras[c.0];
    let p = &scene.intrinsics[c];
    let prec = adj
        .precision
        .intrinsics
        .iter()
        .find(|ip| ip.camera == cam.id);
    let mut sigma = std::collections::BTreeMap::new();
    let mut high = Vec::new();
    if let Some(ip) = prec {
        for (n, s) in ip.names.iter().zip(&ip.sigmas) {
            sigma.insert(n.clone(), *s);
        }
        high = ip
            .high_correlations
            .iter()
            .filter(|h| h.2.abs() > 0.9)
            .cloned()
            .collect();
    }
    let params = Intrinsics::new(cam.model, p.clone()).expect("the model's parameters");
    CameraJson {
        id: cam.id.clone(),
        model_name: (!cam.model.is_default()).then(|| cam.model.name()),
        sigma,
        high_correlations: high,
        opencv: opencv_of(&params, cam.width, cam.height, cam.pixel_size_mm),
        params,
        pixel_size_mm: cam.pixel_size_mm,
    }
}

fn sigma3(m: &Option<Matrix3<f64>>) -> [f64; 3] {
    match m {
        Some(m) => [m[(0, 0)].sqrt(), m[(1, 1)].sqrt(), m[(2, 2)].sqrt()],
        None => [f64::NAN; 3],
    }
}

/// Where `balls[]` takes each side from: the joint adjustment's centres and LRF spheres
/// (through its estimated model) when its result is the one given, else the bundle's and the
/// two-step method's; and the extrinsic (with its covariance) that maps one onto the other.
struct BallSides<'a> {
    /// The project's check balls.
    check: &'a [String],
    joint: Option<&'a JointOutcome>,
    lrf: &'a [PointObs],
    extrinsic: Option<(Sim3, &'a nalgebra::DMatrix<f64>)>,
}

impl<'a> BallSides<'a> {
    fn of(st: &'a Stages) -> Self {
        match st.joint {
            Some(Ok(j)) => Self {
                check: &st.project.file.balls.check,
                joint: Some(j),
                lrf: &j.lrf_points,
                extrinsic: Some((
                    Sim3::new(
                        1.0,
                        j.camera_from_lrf.rotation,
                        j.camera_from_lrf.translation,
                    ),
                    &j.extrinsic_cov,
                )),
            },
            _ => Self {
                check: &st.project.file.balls.check,
                joint: None,
                lrf: &st.ext.lrf_points,
                extrinsic: (st.ext.spheres.as_ref())
                    .map(|ev| (ev.registration.camera_from_lrf, &ev.registration.cov)),
            },
        }
    }

    /// Ball `j` (`p` in the scene, `bundle` its bundle centre) in both frames.
    fn ball(
        &self,
        j: super::ids::PointId,
        p: &super::scene::ScenePoint,
        bundle: Option<PointObs>,
        ext: &Extrinsics,
    ) -> BallJson {
        let cam = match self.joint {
            Some(jo) => (jo.ball_centres.iter())
                .find(|(q, _)| *q == j)
                .map(|(_, c)| c.clone())
                .or(bundle),
            None => bundle,
        };
        let l = self.lrf.iter().find(|l| l.id == p.name);
        let residual = match (l, &cam, &self.extrinsic) {
            (Some(l), Some(c), Some((t, tcov))) => {
                let d = t.transform(&l.xyz) - c.xyz;
                let cov = super::verdict::predicted_covariance(t, tcov, l, c);
                Some(([d.x, d.y, d.z], sigma3(&Some(cov))))
            }
            _ => None,
        };
        let first = (self.joint.is_some())
            .then(|| ext.lrf_points.iter().find(|l| l.id == p.name))
            .flatten();
        let v3 = |v: &Vector3<f64>| [v.x, v.y, v.z];
        let position = cam.as_ref().map_or(p.position, |c| c.xyz);
        BallJson {
            id: p.name.clone(),
            check: self.check.contains(&p.name),
            photogrammetric_mm: v3(&position),
            photogrammetric_sigma_mm: sigma3(&cam.as_ref().map(|c| c.cov)),
            photogrammetric_cov_mm2: cam.as_ref().map_or([[f64::NAN; 3]; 3], |c| mat(&c.cov)),
            lrf_mm: l.map(|l| v3(&l.xyz)),
            lrf_sigma_mm: l.map(|l| sigma3(&Some(l.cov))),
            lrf_cov_mm2: l.map(|l| mat(&l.cov)),
            residual_mm: residual.map(|r| r.0),
            residual_sigma_mm: residual.map(|r| r.1),
            lrf_project_mount_mm: first.map(|f| v3(&f.xyz)),
            rays: p.obs.len(),
        }
    }
}

/// `results.json` from what the steps produced.
pub fn assemble(st: &Stages, verdict: Verdict, time_s: Vec<(String, f64)>) -> Results {
    let (project, scene, adj) = (st.project, st.scene, st.adjusted);
    let methods = methods(st.ext, st.joint);
    let primary = methods
        .iter()
        .find(|m| m.extrinsic.is_some())
        .expect("the pipeline fails unless one method succeeded");
    let (balls, targets) = points_json(st);
    let extrinsic = primary.extrinsic.clone().expect("found above");
    let (sensors, sensor_pairs) = sensors::sensors_json(st, &extrinsic);
    Results {
        generator: format!("pingcal {}", env!("CARGO_PKG_VERSION")),
        verdict,
        project: project.file.name.clone(),
        conventions: conventions(project),
        extrinsic,
        check_points: primary.check_points.clone(),
        mean_check_error_mm: primary.mean_check_error_mm.unwrap_or(f64::NAN),
        methods,
        lrf_mount: match st.joint {
            Some(Ok(j)) => Some(mount_json(j)),
            _ => None,
        },
        lrf_model: lrf_model_of(st),
        sensors,
        sensor_pairs,
        bundle: bundle_json(st),
        cameras: scene
            .intrinsics
            .ids()
            .map(|c| camera_json(project, scene, adj, c))
            .collect(),
        balls,
        targets,
        time_s,
    }
}

/// The balls (with both sensors' sides, sorted naturally by name) and the targets of the
/// final bundle adjustment, with their σ's.
fn points_json(st: &Stages) -> (Vec<BallJson>, Vec<TargetRow>) {
    let (scene, adj, ext) = (st.scene, st.adjusted, st.ext);
    let mut balls = Vec::new();
    let mut targets = Vec::new();
    let side = BallSides::of(st);
    for (j, p) in scene.points.iter_enumerated() {
        let Some(k) = adj.solved.map.point(j) else {
            continue;
        };
        let sig = sigma3(&adj.precision.point_covariances[k.0]);
        let xyz = [p.position.x, p.position.y, p.position.z];
        if p.kind == PointKind::Ball {
            let bundle = adj.precision.point_covariances[k.0].map(|cov| PointObs {
                id: p.name.clone(),
                xyz: p.position,
                cov,
            });
            balls.push(side.ball(j, p, bundle, ext));
        } else {
            targets.push((p.name.clone(), p.kind.as_str().to_string(), xyz, sig));
        }
    }
    balls.sort_by_key(|b| natural(&b.id));
    (balls, targets)
}

/// A target of `results.json`: label, kind, position (mm), σ (mm).
pub type TargetRow = (String, String, [f64; 3], [f64; 3]);

/// The bundle adjustment's summary of `results.json`.
fn bundle_json(st: &Stages) -> BundleJson {
    let (project, scene, adj) = (st.project, st.scene, st.adjusted);
    let stereo = rig_cameras(project).and_then(|(_, member)| adj.rig_of(member, project));
    let rig = stereo.and_then(|(r, cov)| rig_of(project, &r, cov.as_ref()));
    BundleJson {
        sigma0: adj.sigma0_a_priori,
        variance_components: adj.variance_components.clone(),
        rms_image_px: adj.precision.rms_image_px,
        images: adj.solved.problem.images.len(),
        unoriented_images: scene
            .unoriented
            .iter()
            .map(|(i, w)| (image_file(project, *i).to_string(), w.clone()))
            .collect(),
        network_start: scene.start.clone(),
        points: adj.solved.problem.points.len(),
        observations: adj.solved.problem.observations.len(),
        distances: adj.solved.problem.distances.len(),
        iterations: adj.iterations,
        redundancy: adj.precision.redundancy,
        rejected: adj.rejected.len(),
        rejected_distances: adj.rejected_distances.clone(),
        coded_blunders: (scene.blunders.iter())
            .map(|b| {
                let t = st.dets.target(b.det);
                CodedBlunderJson {
                    image: image_file(project, b.det.image).to_string(),
                    number: b.number,
                    x: t.x,
                    y: t.y,
                    stage: b.stage.to_string(),
                    why: b.why.clone(),
                }
            })
            .collect(),
        rig,
    }
}

/// `B12` sorts after `B4`.
pub fn natural(id: &str) -> (String, u64, String) {
    let digits: String = id.chars().filter(|c| c.is_ascii_digit()).collect();
    let prefix: String = id.chars().take_while(|c| !c.is_ascii_digit()).collect();
    (prefix, digits.parse().unwrap_or(u64::MAX), id.to_string())
}

/// `cloud.ply`: the cloud as binary PLY, the balls' points coloured, the fitted spheres
/// (of `radius`) as a `sphere` element after the vertices (so the vertices are the scan
/// points alone).
pub fn cloud_ply(lrf: &LrfData, radius: f64) -> Vec<u8> {
    let comments = vec![format!(
        "pingcal calibrate: LRF cloud in the LRF frame (mm), {} points, {} spheres of radius {radius} mm",
        lrf.cloud.len(),
        lrf.found.balls.len()
    )];
    let mut bytes = Vec::new();
    pingcal_lrf::ply::write_cloud_with_spheres(
        &mut bytes,
        &lrf.cloud,
        &lrf.found.balls,
        radius,
        &comments,
    )
    .expect("writing to memory cannot fail");
    bytes
}

#[cfg(test)]
mod tests {
    use super::transforms::inverse_update_jacobian;
    use super::*;
    use nalgebra::{UnitQuaternion, Vector3};
    use pingcal_ba::camera::{CameraModel, PhotogrammetricCamera};
    use pingcal_geometry::Rigid3;

    /// OpenCV's projection (x right, y down, z forward) of a point in its camera frame.
    fn opencv_project(o: &OpenCvJson, p: &Vector3<f64>) -> [f64; 2] {
        let (x, y) = (p.x / p.z, p.y / p.z);
        let r2 = x * x + y * y;
        let [k1, k2, p1, p2, k3] = o.dist[..] else {
            panic!("five coefficients: {:?}", o.dist)
        };
        let rad = 1.0 + k1 * r2 + k2 * r2 * r2 + k3 * r2 * r2 * r2;
        let xd = x * rad + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
        let yd = y * rad + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
        [o.fx * xd + o.cx, o.fy * yd + o.cy]
    }

    /// The documented example project (docs/project.md: two cameras, `[stereo]` left and right).
    fn example_project(main_camera: &str) -> Project {
        let mut file = crate::test_support::readme_project_file();
        file.main_camera = main_camera.into();
        crate::test_support::project(file, Vec::new())
    }

    /// The inverse's update Jacobian against central differences of `plus` and `inverse`.
    #[test]
    fn the_inverse_rigs_jacobian_matches_central_differences() {
        let m = Rigid3::new(
            pingcal_geometry::from_opk_deg([0.3, -0.25, 12.0]),
            Vector3::new(-120.0, 4.0, 30.0),
        );
        let j = inverse_update_jacobian(&m);
        let inv = m.inverse();
        let h = 1e-6;
        for k in 0..6 {
            let mut d = [0.0; 6];
            d[k] = h;
            let plus = m.plus(&d).inverse();
            d[k] = -h;
            let minus = m.plus(&d).inverse();
            // the inverse's update that gives plus / minus from inv
            let up = |x: &Rigid3| {
                let w = pingcal_geometry::log_so3(&(x.rotation * inv.rotation.transpose()));
                let t = x.translation - inv.translation;
                [w.x, w.y, w.z, t.x, t.y, t.z]
            };
            let (a, b) = (up(&plus), up(&minus));
            for r in 0..6 {
                let fd = (a[r] - b[r]) / (2.0 * h);
                let tol = 1e-6 * (1.0 + j[(r, k)].abs());
                assert!(
                    (fd - j[(r, k)]).abs() < tol,
                    "({r}, {k}): {fd} vs {}",
                    j[(r, k)]
                );
            }
        }
    }

    /// `bundle.rig` is left → right whichever camera is the main one (the adjustment's rig
    /// goes from the main camera's side to the other), in both frames.
    #[test]
    fn the_rig_is_left_to_right_whichever_camera_is_main() {
        let r = pingcal_geometry::from_opk_deg([0.3, -0.25, 0.1]);
        let right_from_left = Rigid3::new(r, Vector3::new(-120.0, -0.12, 0.83));
        let p_left = Vector3::new(150.0, 2000.0, -80.0);
        let p_right = right_from_left.transform(&p_left);
        for (main, member_from_base) in [
            ("left", right_from_left),
            ("right", right_from_left.inverse()),
        ] {
            let rig = rig_of(&example_project(main), &member_from_base, None).unwrap();
            assert_eq!((rig.left.as_str(), rig.right.as_str()), ("left", "right"));
            let (rot, t) = (
                Matrix3::from(rig.rotation).transpose(),
                Vector3::from(rig.translation_mm),
            );
            assert!((rot * p_left + t - p_right).norm() < 1e-9, "main {main}");
            let c = cv_from_photogrammetric();
            let o = &rig.opencv;
            let (rc, tc) = (
                Matrix3::from(o.rotation).transpose(),
                Vector3::from(o.translation_mm),
            );
            assert!(
                (rc * c * p_left + tc - c * p_right).norm() < 1e-9,
                "main {main}"
            );
            assert!((rig.baseline_mm - 120.0).abs() < 0.01);
        }
    }

    /// A rotation of almost 180° gives the quaternion that rotates as R does, w ≥ 0, and
    /// the 4×4 holds R and t.
    #[test]
    fn quaternion_and_matrix_are_of_the_same_transform() {
        let r = pingcal_geometry::from_opk_deg([179.0, 2.0, -178.5]);
        let t = Vector3::new(1.0, -2.0, 3.0);
        let [x, y, z, w] = quaternion_xyzw(&r);
        assert!(w >= 0.0 && (x * x + y * y + z * z + w * w - 1.0).abs() < 1e-15);
        let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z));
        let v = Vector3::new(0.3, -0.4, 0.87);
        assert!((q * v - r * v).norm() < 1e-15);
        let m = matrix_4x4(&r, &t);
        let p = nalgebra::Matrix4::from_fn(|i, j| m[i][j]) * v.push(1.0);
        assert!((p.xyz() - (r * v + t)).norm() < 1e-15 && p.w == 1.0);
    }

    /// Without B1 and B2 the conversion is exact: both models put every point on the same
    /// pixel (p_cv = (X, −Z, Y) from the photogrammetric camera frame, docs/formats.md).
    #[test]
    fn opencv_conversion_projects_identically() {
        let cam = PhotogrammetricCamera::new(1280, 720, 0.00375);
        let p = [
            2.45, 0.012, -0.009, -0.021, 0.0004, -2e-6, 0.00015, -0.0001, 0.0, 0.0,
        ];
        let o = opencv_of(&Intrinsics::photogrammetric(p), 1280, 720, 0.00375);
        let mut worst: f64 = 0.0;
        for i in 0..15 {
            for j in 0..9 {
                let xc = Vector3::new(-0.75 + 0.1 * i as f64, 1.0, -0.4 + 0.1 * j as f64);
                let uv = cam.project(&p, &xc, None, None).unwrap();
                let cv = opencv_project(&o, &Vector3::new(xc.x, -xc.z, xc.y));
                worst = worst.max((uv.x - cv[0]).abs()).max((uv.y - cv[1]).abs());
            }
        }
        assert!(worst < 1e-9, "largest difference {worst} px");
    }
}
