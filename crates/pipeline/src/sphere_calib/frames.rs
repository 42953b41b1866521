//! One frame read: its cloud and the lidar's sphere in it, its photograph and every
//! silhouette of the sphere in it. Which silhouette is the ball is decided over all frames
//! ([`super::select`]).

use super::camera::Camera;
use super::image::{self, ImageSphere};
use crate::context::PipelineError;
use nalgebra::{Matrix3, Vector3};
use pingcal_lrf::ball_finder::{find_balls, FinderOptions};
use pingcal_lrf::cloud_file::{read_cloud_file_in, CloudUnit};
use pingcal_lrf::{MountModel, RangeNoise};
use std::path::{Path, PathBuf};

type V3 = Vector3<f64>;

/// The lidar's sphere of a frame.
#[derive(Debug, Clone)]
pub struct LidarSphere {
    /// Centre in the lidar frame, mm.
    pub centre: V3,
    /// Its covariance, mm².
    pub cov: Matrix3<f64>,
    /// Points of the fit.
    pub inliers: usize,
    /// σ₀ of the fit.
    pub sigma0: f64,
}

/// One frame's outcome.
#[derive(Debug, Clone)]
pub struct Frame {
    /// Its id.
    pub id: String,
    /// The photograph.
    pub image_path: PathBuf,
    /// The cloud.
    pub cloud_path: PathBuf,
    /// The lidar's sphere.
    pub lidar: Option<LidarSphere>,
    /// The ball's silhouette in the image (when chosen).
    pub image: Option<ImageSphere>,
    /// How many sphere silhouettes the image showed (before the choice).
    pub silhouettes: usize,
    /// How the silhouette was chosen: `consensus` (one of those found, the one consistent with
    /// one rigid transform over the frames) or `predicted` (found again where that transform
    /// puts the lidar's sphere).
    pub chosen_by: Option<&'static str>,
    /// Why the frame is not used (`None`: used).
    pub skipped: Option<String>,
    /// Warnings (cloud unit, a second silhouette, …).
    pub warnings: Vec<String>,
    /// The cloud, lidar frame, mm (for the overlays).
    pub cloud: Vec<V3>,
    /// The indices of the cloud's points on the lidar's sphere.
    pub sphere_points: Vec<usize>,
    /// Every silhouette the image showed, best first.
    pub candidates: Vec<ImageSphere>,
}

impl Frame {
    /// Adds a reason to leave the frame out.
    pub fn skip(&mut self, why: String) {
        self.skipped = Some(match self.skipped.take() {
            Some(prev) => format!("{prev}; {why}"),
            None => why,
        });
    }
}

/// What reading a frame needs.
#[derive(Debug, Clone, Copy)]
pub struct Setup<'a> {
    /// The camera.
    pub cam: &'a Camera,
    /// Its file, for errors.
    pub cam_name: &'a str,
    /// The sphere's diameter, mm.
    pub diameter_mm: f64,
    /// The lidar's noise.
    pub noise: RangeNoise,
    /// The clouds' unit.
    pub unit: CloudUnit,
    /// The seed of the sphere finder.
    pub seed: u64,
}

/// The lidar side of a frame: the one sphere of the cloud, or why there is none.
fn lidar_side(f: &mut Frame, cloud: &pingcal_lrf::Cloud, s: &Setup) {
    if cloud.points.is_empty() {
        f.skip(format!(
            "{}: no points (an empty cloud): record the frame again",
            f.cloud_path.display()
        ));
        return;
    }
    let found = find_balls(
        cloud,
        &FinderOptions {
            diameter_mm: s.diameter_mm,
            noise: s.noise,
            seed: s.seed,
            ..Default::default()
        },
    );
    match found.balls.as_slice() {
        [b] => {
            f.lidar = Some(LidarSphere {
                centre: b.centre,
                cov: b.cov,
                inliers: b.inliers.len(),
                sigma0: b.sigma0,
            });
            f.sphere_points = b.inliers.clone();
        }
        [] => f.skip(format!(
            "{}: no sphere of {} mm found ({} candidates rejected{})",
            f.cloud_path.display(),
            s.diameter_mm,
            found.rejected.len(),
            found
                .rejected
                .first()
                .map_or(String::new(), |r| format!(", e.g. {}", r.reason))
        )),
        many => f.skip(format!(
            "{}: {} spheres of {} mm found, one expected: at {} mm (take the other ball out of the scene, or out of the cloud)",
            f.cloud_path.display(),
            many.len(),
            s.diameter_mm,
            many.iter()
                .map(|b| format!("({:.0}, {:.0}, {:.0})", b.centre.x, b.centre.y, b.centre.z))
                .collect::<Vec<_>>()
                .join(", ")
        )),
    }
}

/// Reads frame `id` (its cloud and image, relative to `dir`): the lidar's sphere and every
/// silhouette of the image. `Err` for a file that cannot be read or an image of another
/// size than the camera's (one line naming the file).
pub fn read_frame(
    dir: &Path,
    cloud: &str,
    image: &str,
    id: &str,
    s: &Setup,
) -> Result<Frame, PipelineError> {
    let cloud_path = dir.join(cloud);
    let image_path = dir.join(image);
    // errors name the frame and say what to do
    let (points, warnings) = read_cloud_file_in(&cloud_path, &MountModel::default(), s.unit)
        .map_err(|e| {
            PipelineError::Input(format!(
                "{e} (frame {id}'s cloud: give its points, or take the frame out of the project)"
            ))
        })?;
    let img = pingcal_targets::load_colour(&image_path)
        .map_err(|e| PipelineError::Input(format!("{e} (frame {id}'s photograph)")))?;
    let (cw, ch) = (s.cam.sensor.width as usize, s.cam.sensor.height as usize);
    if (img.width(), img.height()) != (cw, ch) {
        return Err(PipelineError::Input(format!(
            "{}: {} × {} pixels, but the camera {} is {cw} × {ch} (frame {id}): give the camera file of the camera that took these images",
            image_path.display(),
            img.width(),
            img.height(),
            s.cam_name,
        )));
    }
    let mut f = Frame {
        id: id.to_string(),
        image_path,
        cloud_path,
        lidar: None,
        image: None,
        silhouettes: 0,
        chosen_by: None,
        skipped: None,
        warnings,
        cloud: Vec::new(),
        sphere_points: Vec::new(),
        candidates: Vec::new(),
    };
    lidar_side(&mut f, &points, s);
    f.cloud = points.points;
    f.candidates = image::candidates(&img, s.cam, s.diameter_mm / 2.0);
    f.silhouettes = f.candidates.len();
    Ok(f)
}
