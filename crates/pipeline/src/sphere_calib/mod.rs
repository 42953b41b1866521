//! The extrinsic of a camera against any lidar from one large sphere moved between N frames
//! (Tóth, Pusztai & Hajder, ICRA 2020; issues 15 and 36). The project file is
//! `pingcal_project::sphere_calib` (docs/sphere-calib.md).
//!
//! Per frame ([`frames`]):
//! * **lidar**: the sphere's centre by [`pingcal_lrf::ball_finder::find_balls`] at the
//!   project's diameter and noise profile; exactly one sphere is expected, a frame with none
//!   or several is reported and left out;
//! * **camera**: every silhouette of a sphere of the known radius in the photograph
//!   ([`pingcal_targets::silhouette`]: edges from the colour gradient, candidate circles,
//!   the silhouette cone fitted robustly to the visible part of the outline through the
//!   camera model's own `project` and `unproject`, [`camera`], so any of pingcal's camera
//!   models and any distortion), each with its centre in the camera frame and that
//!   centre's covariance `s² (JᵀJ)⁻¹` from the edge points used.
//!
//! Then which silhouette is the ball ([`select`]): the one consistent with one rigid
//! transform over the frames ([`consensus`]), and where none (or two) is, a search again
//! at the place that transform predicts; a frame whose choice stays open is left out,
//! named. Then the 3D conformal transform of `pingcal_lrf::registration` (weighted by both
//! covariances) with σ, per-frame residuals and leave-one-out errors, and beside it the
//! published closed form for comparison ([`image::closed_form_centre`] + unweighted SVD).
//!
//! [`calibrate`] runs it on a project file, [`json::results_json`] gives its `results.json`,
//! [`outputs::outputs`] the rest of what `pingcal sphere-calib` writes (the exports, the
//! overlays, the report).

pub mod camera;
pub mod consensus;
pub mod frames;
pub mod image;
pub mod json;
pub mod outputs;
pub mod select;
pub mod verdict;

pub use camera::Camera;
pub use frames::{Frame, LidarSphere};
pub use image::{closed_form_centre, ImageSphere};
pub use json::{results_json, v};

use crate::context::PipelineError;
use frames::{read_frame, Setup};
use nalgebra::{Matrix3, Vector3};
use pingcal_lrf::cloud_file::CloudUnit;
use pingcal_lrf::registration::{self, PointObs, RegistrationOptions};
use pingcal_lrf::RangeNoise;
use pingcal_project::{CameraFile, SphereCalibFile};
use rayon::prelude::*;
use std::path::Path;

type V3 = Vector3<f64>;

/// The closed form's result: unweighted SVD registration of its centres, with σ from the
/// residuals (unit weights, scaled by σ₀², as an unweighted least squares reports it).
#[derive(Debug, Clone)]
pub struct ClosedForm {
    /// The transform and its σ's.
    pub registration: registration::Registration,
    /// Leave-one-out table.
    pub leave_one_out: registration::CheckTable,
}

/// Everything one run computes.
#[derive(Debug)]
pub struct Outcome {
    /// The project's name (or its file's).
    pub name: String,
    /// Per frame, in project order.
    pub frames: Vec<Frame>,
    /// pingcal's estimate: weighted registration, residuals and leave-one-out.
    pub evaluation: registration::Evaluation,
    /// The published closed form on the same frames (`None` when a frame used has no closed
    /// form: its outline gave no ellipse).
    pub closed_form: Option<ClosedForm>,
    /// The noise profile used.
    pub noise: RangeNoise,
    /// The camera.
    pub camera: Camera,
    /// The camera file, as the project names it.
    pub camera_path: String,
    /// The sphere's diameter, mm.
    pub diameter_mm: f64,
    /// The verdict.
    pub verdict: crate::verdict::Verdict,
    /// σ0 of the registration against the sensors' own σ's (the centres' covariances from
    /// the sphere fit and the silhouette fit); `evaluation`'s σ0 is this one unless the σ's
    /// were scaled.
    pub sensor_sigma0: f64,
    /// The factor every centre's σ was scaled by when `sensor_sigma0` failed its test (the
    /// variance factor σ0² estimated from the residuals, as its square root: the centres
    /// scatter this many times more than their σ's say); then in every σ of `evaluation`.
    pub sigma_scale: Option<f64>,
}

/// The project, its camera and its lidar's noise and unit.
struct Loaded {
    file: SphereCalibFile,
    cam: Camera,
    cam_name: String,
    noise: RangeNoise,
    unit: CloudUnit,
}

fn load(project: &Path) -> Result<Loaded, String> {
    let name = project.display().to_string();
    let text = std::fs::read_to_string(project).map_err(|e| format!("{name}: cannot read: {e}"))?;
    let (file, noise) = SphereCalibFile::read(&text, &name).map_err(|e| e.to_string())?;
    let dir = project.parent().unwrap_or(Path::new("."));
    let cam_path = dir.join(&file.camera);
    let cam_name = cam_path.display().to_string();
    let cam_bytes =
        std::fs::read(&cam_path).map_err(|e| format!("{cam_name}: cannot read: {e}"))?;
    let cam_text = String::from_utf8(cam_bytes).map_err(|_| {
        format!(
            "{cam_name}: not a camera file pingcal reads (not text): expected {}",
            pingcal_project::camera_file::formats()
        )
    })?;
    let cam = Camera::from_file(
        &CameraFile::read(&cam_text, &cam_name, file.camera_entry.as_deref())
            .map_err(|e| e.to_string())?,
    );
    let unit = file.lidar.unit;
    Ok(Loaded {
        file,
        cam,
        cam_name,
        noise,
        unit,
    })
}

/// The registration's point lists of the frames used: (lidar, camera).
fn point_lists(frames: &[Frame]) -> (Vec<PointObs>, Vec<PointObs>) {
    frames
        .iter()
        .filter(|f| f.skipped.is_none())
        .filter_map(|f| {
            let (l, s) = (f.lidar.as_ref()?, f.image.as_ref()?);
            Some((
                PointObs {
                    id: f.id.clone(),
                    xyz: l.centre,
                    cov: l.cov,
                },
                PointObs {
                    id: f.id.clone(),
                    xyz: s.centre,
                    cov: s.cov,
                },
            ))
        })
        .unzip()
}

/// The published method on the frames used: its own camera centres, unit weights, SVD.
fn closed_form(frames: &[Frame], name: &str) -> Result<Option<ClosedForm>, PipelineError> {
    let mut lidar = Vec::new();
    let mut cam = Vec::new();
    for f in frames.iter().filter(|f| f.skipped.is_none()) {
        let (Some(l), Some(s)) = (&f.lidar, &f.image) else {
            continue;
        };
        let Some(c) = s.closed_form else {
            return Ok(None);
        };
        lidar.push(PointObs::new(f.id.clone(), l.centre, 1.0));
        cam.push(PointObs::new(f.id.clone(), c, 1.0));
    }
    let xyz = |p: &[PointObs]| p.iter().map(|p| p.xyz).collect::<Vec<V3>>();
    let svd = registration::umeyama(&xyz(&lidar), &xyz(&cam), None, false)
        .map_err(|e| registration_error(name, "closed form", e))?;
    let opt = RegistrationOptions {
        posterior: true,
        ..Default::default()
    };
    let mut reg = registration::register(&lidar, &cam, &opt)
        .map_err(|e| registration_error(name, "closed form", e))?;
    // unweighted least squares and the SVD are the same estimate: keep the SVD's numbers
    debug_assert!((reg.camera_from_lrf.translation - svd.translation).norm() < 1e-6);
    reg.camera_from_lrf = svd;
    let (loo, _) = registration::leave_one_out(&lidar, &cam, &opt);
    Ok(Some(ClosedForm {
        registration: reg,
        leave_one_out: loo,
    }))
}

/// Runs the calibration of one project (no output written).
pub fn calibrate(project: &Path, seed: u64) -> Result<Outcome, PipelineError> {
    let name = project.display().to_string();
    let l = load(project).map_err(PipelineError::Input)?;
    let dir = project.parent().unwrap_or(Path::new("."));
    let setup = Setup {
        cam: &l.cam,
        cam_name: &l.cam_name,
        diameter_mm: l.file.sphere_diameter_mm,
        noise: l.noise,
        unit: l.unit,
        seed,
    };
    let ids = l.file.frame_ids();
    let mut frames = l
        .file
        .frames
        .par_iter()
        .zip(&ids)
        .map(|(fr, id)| read_frame(dir, &fr.cloud, &fr.image, id, &setup))
        .collect::<Result<Vec<Frame>, PipelineError>>()?;
    let radius = l.file.sphere_diameter_mm / 2.0;
    select::choose(&mut frames, &l.cam, radius, seed)
        .map_err(|why| PipelineError::Data(format!("{name}: {why}")))?;
    let (lidar, camera) = point_lists(&frames);
    if lidar.len() < 3 {
        return Err(PipelineError::Data(format!(
            "{name}: {} of {} frames have the sphere in both the cloud and the image, at least 3 are needed: {}",
            lidar.len(),
            frames.len(),
            frames
                .iter()
                .filter_map(|f| f.skipped.as_ref().map(|s| format!("{}: {s}", f.id)))
                .collect::<Vec<_>>()
                .join("; ")
        )));
    }
    let opt = RegistrationOptions::default();
    let sensors = registration::evaluate(&lidar, &camera, &[], &[], &opt)
        .map_err(|e| registration_error(&name, "registration", e))?;
    let sensor_sigma0 = sensors.registration.sigma0;
    // the a-posteriori variance factor when the sensors' σ's fail: the estimate is the same
    // (the weights only scale), every σ and the leave-one-out test take the data's scatter
    let sigma_scale = (!verdict::sigma0_passes(&sensors.registration)).then_some(sensor_sigma0);
    let (evaluation, lidar, camera) = match sigma_scale {
        Some(k) => {
            let (lidar, camera) = (scaled(&lidar, k), scaled(&camera, k));
            // the geometry passed its test on the sensors' σ's: the same points, the same
            // estimate (the scaled σ's would call an honest spread "collinear")
            let opt = RegistrationOptions {
                collinear_tol_mm: Some(0.0),
                ..opt
            };
            let ev = registration::evaluate(&lidar, &camera, &[], &[], &opt)
                .map_err(|e| registration_error(&name, "registration", e))?;
            (ev, lidar, camera)
        }
        None => (sensors, lidar, camera),
    };
    let closed_form = closed_form(&frames, &name)?;
    let verdict = verdict::judge(
        &frames,
        &evaluation,
        (&lidar, &camera),
        sensor_sigma0,
        sigma_scale,
    );
    Ok(Outcome {
        name: l.file.name.clone().unwrap_or(name),
        frames,
        evaluation,
        closed_form,
        noise: l.noise,
        camera: l.cam,
        camera_path: l.file.camera.clone(),
        diameter_mm: l.file.sphere_diameter_mm,
        verdict,
        sensor_sigma0,
        sigma_scale,
    })
}

/// A registration's (`what`) failure as the pipeline's: too few or collinear centres are
/// the data's (take more frames, spread the sphere), anything else the adjustment's.
fn registration_error(name: &str, what: &str, e: pingcal_lrf::LrfError) -> PipelineError {
    use pingcal_lrf::LrfError::{Collinear, TooFewPoints};
    let message = format!("{name}: {what}: {e}");
    match e {
        Collinear { .. } | TooFewPoints { .. } => PipelineError::Data(message),
        _ => PipelineError::Adjustment(message),
    }
}

/// The centres with every σ times `k`.
fn scaled(points: &[PointObs], k: f64) -> Vec<PointObs> {
    points
        .iter()
        .map(|p| PointObs {
            cov: p.cov * (k * k),
            ..p.clone()
        })
        .collect()
}

/// The standard deviations on the diagonal of covariance `c`.
pub fn sd(c: &Matrix3<f64>) -> [f64; 3] {
    [0, 1, 2].map(|k| c[(k, k)].max(0.0).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;
    use pingcal_ba::camera::CameraModel;

    /// The camera of `pingcal simulate` (its distortion is strong: −15 % at the corner).
    fn camera() -> Camera {
        let text = "model = \"photogrammetric\"\nwidth = 1280\nheight = 720\npixel_size_mm = 0.00375\n[params]\nc_mm = 2.45\nxp_mm = 0.012\nyp_mm = -0.009\nk1 = -0.021\nk2 = 4.0e-4\nk3 = -2.0e-6\np1 = 1.5e-4\np2 = -1.0e-4\nb1 = 1.0e-4\n";
        Camera::from_file(&CameraFile::parse(text, "camera.toml").unwrap())
    }

    /// The exact outline of a sphere: unit rays on its silhouette cone and their pixels.
    fn outline(cam: &Camera, c: &V3, r: f64, n: usize) -> (Vec<V3>, Vec<(f64, f64)>) {
        let u = c.normalize();
        let e1 = u.cross(&V3::z()).normalize();
        let e2 = u.cross(&e1);
        let alpha = (r / c.norm()).asin();
        (0..n)
            .map(|i| {
                let phi = std::f64::consts::TAU * i as f64 / n as f64;
                let q = u * alpha.cos() + (e1 * phi.cos() + e2 * phi.sin()) * alpha.sin();
                let p = cam.sensor.project(&cam.params, &q, None, None).unwrap();
                (q, (p.x, p.y))
            })
            .unzip()
    }

    #[test]
    fn cone_fit_and_closed_form_recover_an_exact_outline_through_the_distortion() {
        use pingcal_targets::silhouette::cone::fit_cone;
        let cam = camera();
        let r = 300.0;
        for c in [
            Vector3::new(0.0, 1500.0, 0.0),
            Vector3::new(-1400.0, 3000.0, 500.0),
            Vector3::new(2500.0, 8000.0, -900.0),
        ] {
            let (rays, px) = outline(&cam, &c, r, 180);
            // the pixel → ray map inverts the projection
            let back: Vec<V3> = px.iter().map(|&(x, y)| cam.ray(x, y).unwrap()).collect();
            assert!(back.iter().zip(&rays).all(|(a, b)| (a - b).norm() < 1e-9));
            let (fit, cov, _) = fit_cone(&back, c * 1.05 + V3::new(30.0, 0.0, -20.0), r).unwrap();
            assert!((fit - c).norm() < 1e-6 * c.norm(), "{fit} vs {c}");
            assert!(cov.norm() < 1e-9);
            let cf = closed_form_centre(&px, &cam, r).unwrap();
            assert!((cf - c).norm() < 1e-6 * c.norm(), "{cf} vs {c}");
        }
    }
}
