//! Synthetic BAL problems of any size, for tests and benchmarks.
//!
//! Two scenes ([`Visibility`]):
//! - *banded*: a street, cameras in a row looking sideways at a band of points, so that
//!   each point is seen by a window of neighbouring cameras and the reduced camera system
//!   is sparse (banded), as in real sequences;
//! - *random*: cameras all around a ball of points, each looking at its centre, and every
//!   point seen by K cameras drawn at random among all of them: a dense camera graph, as
//!   in a photogrammetric network where every image sees most targets.
//!
//! Measurements are the true projections plus
//! Gaussian noise; the initial estimate is the truth perturbed, so that a solver converges
//! to the least-squares solution near the truth.

use crate::camera::BalCamera;
use crate::keys::{CameraKey, ImageKey, PointKey};
use crate::problem::{Camera, Image, Observation, Point, Problem};
use nalgebra::{Matrix3, Vector2, Vector3};
use pingcal_geometry::exp_so3;
use pingcal_geometry::Rigid3;
use rand::Rng;
use rand_distr::{Distribution, Normal};
use std::sync::Arc;

/// Size and noise of a synthetic BAL problem.
#[derive(Clone, Debug)]
pub struct SyntheticBal {
    /// Number of cameras (each with its own f, k1, k2).
    pub cameras: usize,
    /// Number of points.
    pub points: usize,
    /// Observations per point (at most the number of cameras).
    pub obs_per_point: usize,
    /// Standard deviation of the image noise, pixels.
    pub noise_px: f64,
    /// Scale of the perturbation of the initial estimate (1: rotations 2 mrad, camera
    /// centres 2 cm at 10 m depth, points 5 cm, focal length 0.5 %).
    pub perturbation: f64,
    /// Seed of the random generator.
    pub seed: u64,
    /// Which cameras see a point.
    pub visibility: Visibility,
}

/// Which cameras see a point of a [`SyntheticBal`] problem.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Visibility {
    /// K of the neighbouring cameras along a street (a banded camera graph).
    #[default]
    Banded,
    /// K cameras drawn at random among all (a dense camera graph).
    Random,
}

impl Default for SyntheticBal {
    fn default() -> Self {
        Self {
            cameras: 50,
            points: 5000,
            obs_per_point: 5,
            noise_px: 0.5,
            perturbation: 1.0,
            seed: 1,
            visibility: Visibility::Banded,
        }
    }
}

/// A synthetic problem with its truth.
#[derive(Clone, Debug)]
pub struct Synthetic {
    /// The problem, with perturbed initial values and noisy measurements.
    pub problem: Problem,
    /// The same problem at the true values (noise-free measurements are not kept).
    pub truth: Problem,
}

/// Why a synthetic problem cannot be generated as asked.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SyntheticError {
    /// Fewer than 2 cameras, no point, or fewer than 2 observations per point.
    #[error("need at least 2 cameras, 1 point and 2 observations per point")]
    TooSmall,
    /// More observations per point than cameras.
    #[error(
        "{obs_per_point} observations per point need at least as many cameras (got {cameras})"
    )]
    TooFewCameras {
        /// Observations asked per point.
        obs_per_point: usize,
        /// Cameras asked.
        cameras: usize,
    },
    /// A negative or non-finite noise, or a negative perturbation.
    #[error("noise and perturbation must be non-negative")]
    NegativeNoise,
    /// No place found for a point seen by enough cameras (in 100 tries a point).
    #[error("could not place points visible in enough cameras")]
    Unplaceable,
}

impl SyntheticBal {
    /// Generates the problem. Fails if the sizes are inconsistent.
    pub fn generate(&self) -> Result<Synthetic, SyntheticError> {
        if self.cameras < 2 || self.points == 0 || self.obs_per_point < 2 {
            return Err(SyntheticError::TooSmall);
        }
        if self.obs_per_point > self.cameras {
            return Err(SyntheticError::TooFewCameras {
                obs_per_point: self.obs_per_point,
                cameras: self.cameras,
            });
        }
        // Written as `!(ok)` so that NaN fails the comparisons and is rejected with them.
        if !(self.noise_px >= 0.0 && self.noise_px.is_finite() && self.perturbation >= 0.0) {
            return Err(SyntheticError::NegativeNoise);
        }
        let mut rng = pingcal_geometry::consensus::rng(self.seed);
        let n01 = Normal::new(0.0, 1.0).unwrap();
        let spacing = 0.5;
        let model = Arc::new(BalCamera);
        if self.visibility == Visibility::Random {
            let (cameras, images, points, observations) = self.random_scene(&mut rng, &model);
            return Ok(self.perturbed(cameras, images, points, observations, &mut rng));
        }
        // Camera frame: x = world x, y = world z, z = −world y (looks down −z, i.e. along +y).
        let base = Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -1.0, 0.0);
        let mut cameras = Vec::with_capacity(self.cameras);
        let mut images = Vec::with_capacity(self.cameras);
        for c in 0..self.cameras {
            let yaw = 0.1 * n01.sample(&mut rng);
            let tilt = 0.05 * n01.sample(&mut rng);
            let r = base * exp_so3(&Vector3::new(tilt, 0.0, yaw));
            let centre = Vector3::new(
                c as f64 * spacing,
                0.2 * n01.sample(&mut rng),
                1.5 + 0.1 * n01.sample(&mut rng),
            );
            let (camera, image) = camera_and_image(c, &model, &mut rng, (r, centre));
            cameras.push(camera);
            images.push(image);
        }
        let length = (self.cameras - 1) as f64 * spacing;
        let window = (self.obs_per_point * 2).max(12).min(self.cameras);
        let mut points = Vec::with_capacity(self.points);
        let mut observations = Vec::with_capacity(self.points * self.obs_per_point);
        let noise = Normal::new(0.0, self.noise_px.max(0.0)).unwrap();
        let mut chosen: Vec<usize> = Vec::with_capacity(window);
        let mut p = 0;
        let mut attempts = 0usize;
        while p < self.points {
            attempts += 1;
            if attempts > 100 * self.points + 1000 {
                return Err(SyntheticError::Unplaceable);
            }
            let x = Vector3::new(
                rng.random_range(-1.0..length + 1.0),
                rng.random_range(8.0..20.0),
                rng.random_range(-2.0..6.0),
            );
            let centre_cam =
                ((x.x / spacing).round() as isize).clamp(0, self.cameras as isize - 1) as usize;
            let lo = centre_cam
                .saturating_sub(window / 2)
                .min(self.cameras - window);
            chosen.clear();
            let candidates: Vec<usize> = (lo..lo + window)
                .filter(|&c| {
                    let xc = images[c].camera_from_object.transform(&x);
                    xc.z < -1.0 && (xc.x / xc.z).abs() < 1.0 && (xc.y / xc.z).abs() < 0.8
                })
                .collect();
            if candidates.len() < self.obs_per_point {
                continue;
            }
            // Partial Fisher–Yates for K distinct cameras.
            let mut pool = candidates;
            for k in 0..self.obs_per_point {
                let j = rng.random_range(k..pool.len());
                pool.swap(k, j);
                chosen.push(pool[k]);
            }
            chosen.sort_unstable();
            let seen = (&images[..], &cameras[..], &chosen[..]);
            observe(
                seen,
                &x,
                p,
                &noise,
                &mut rng,
                &mut points,
                &mut observations,
            );
            p += 1;
        }
        Ok(self.perturbed(cameras, images, points, observations, &mut rng))
    }

    /// Cameras on a sphere of radius 10 around a ball of points of radius 2, each looking
    /// at the centre with a random roll; every point seen by K cameras drawn at random.
    #[allow(clippy::type_complexity)]
    fn random_scene(
        &self,
        rng: &mut pingcal_geometry::consensus::SeededRng,
        model: &Arc<BalCamera>,
    ) -> (Vec<Camera>, Vec<Image>, Vec<Point>, Vec<Observation>) {
        let n01 = Normal::new(0.0, 1.0).unwrap();
        let unit = |rng: &mut pingcal_geometry::consensus::SeededRng| -> Vector3<f64> {
            loop {
                let v = Vector3::new(n01.sample(rng), n01.sample(rng), n01.sample(rng));
                if v.norm() > 1e-3 {
                    return v.normalize();
                }
            }
        };
        let mut cameras = Vec::with_capacity(self.cameras);
        let mut images = Vec::with_capacity(self.cameras);
        for c in 0..self.cameras {
            // BAL cameras look down −z: the camera's z axis points from the scene to it.
            let z = unit(rng);
            let helper = if z.x.abs() < 0.9 {
                Vector3::x()
            } else {
                Vector3::y()
            };
            let x0 = helper.cross(&z).normalize();
            let roll = rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
            let x = x0 * roll.cos() + z.cross(&x0) * roll.sin();
            let y = z.cross(&x);
            let r = Matrix3::from_rows(&[x.transpose(), y.transpose(), z.transpose()]);
            let (camera, image) = camera_and_image(c, model, rng, (r, z * 10.0));
            cameras.push(camera);
            images.push(image);
        }
        let noise = Normal::new(0.0, self.noise_px.max(0.0)).unwrap();
        let mut points = Vec::with_capacity(self.points);
        let mut observations = Vec::with_capacity(self.points * self.obs_per_point);
        let mut chosen: Vec<usize> = Vec::with_capacity(self.obs_per_point);
        for p in 0..self.points {
            let x = unit(rng) * (2.0 * rng.random_range(0.0f64..1.0).cbrt());
            // K distinct cameras by rejection (K ≤ C).
            chosen.clear();
            while chosen.len() < self.obs_per_point {
                let c = rng.random_range(0..self.cameras);
                if !chosen.contains(&c) {
                    chosen.push(c);
                }
            }
            chosen.sort_unstable();
            let seen = (&images[..], &cameras[..], &chosen[..]);
            observe(seen, &x, p, &noise, rng, &mut points, &mut observations);
        }
        (cameras, images, points, observations)
    }

    /// The problem at the truth, and the same perturbed as [`SyntheticBal::perturbation`]
    /// says.
    fn perturbed(
        &self,
        cameras: Vec<Camera>,
        images: Vec<Image>,
        points: Vec<Point>,
        observations: Vec<Observation>,
        rng: &mut pingcal_geometry::consensus::SeededRng,
    ) -> Synthetic {
        let n01 = Normal::new(0.0, 1.0).unwrap();
        let truth = Problem {
            cameras,
            images,
            points,
            observations,
            ..Default::default()
        };
        let mut problem = truth.clone();
        let s = self.perturbation;
        for im in &mut problem.images {
            let dw = Vector3::new(n01.sample(rng), n01.sample(rng), n01.sample(rng)) * (0.002 * s);
            let dc = Vector3::new(n01.sample(rng), n01.sample(rng), n01.sample(rng)) * (0.02 * s);
            let r = exp_so3(&dw) * im.camera_from_object.rotation;
            im.camera_from_object =
                Rigid3::from_rotation_and_centre(r, im.camera_from_object.centre() + dc);
        }
        for c in &mut problem.cameras {
            c.params[0] *= 1.0 + 0.005 * s * n01.sample(rng);
        }
        for pt in &mut problem.points {
            pt.position +=
                Vector3::new(n01.sample(rng), n01.sample(rng), n01.sample(rng)) * (0.05 * s);
        }
        Synthetic { problem, truth }
    }
}

/// Camera `c` (a BAL camera with a focal length within 10 % of 500 px and small random k1,
/// k2, drawn from `rng` in that order) and its image at rotation `r` and projection centre
/// `centre`.
fn camera_and_image(
    c: usize,
    model: &Arc<BalCamera>,
    rng: &mut pingcal_geometry::consensus::SeededRng,
    (r, centre): (Matrix3<f64>, Vector3<f64>),
) -> (Camera, Image) {
    let n01 = Normal::new(0.0, 1.0).unwrap();
    let f = 500.0 * (1.0 + 0.1 * rng.random_range(-1.0..1.0));
    let k1 = 0.02 * n01.sample(rng);
    let k2 = 0.002 * n01.sample(rng);
    let camera = Camera::new(format!("cam{c}"), model.clone(), vec![f, k1, k2]);
    let image = Image {
        name: format!("image{c}"),
        camera: CameraKey(c),
        camera_from_object: Rigid3::from_rotation_and_centre(r, centre),
        fixed: false,
        fixed_centre: [false; 3],
    };
    (camera, image)
}

/// Point `p` at `x` and its observations in the `chosen` (image, camera) pairs of
/// `(images, cameras, chosen)`: the true projections plus noise (two draws per image, u
/// then v).
fn observe(
    (images, cameras, chosen): (&[Image], &[Camera], &[usize]),
    x: &Vector3<f64>,
    p: usize,
    noise: &Normal<f64>,
    rng: &mut pingcal_geometry::consensus::SeededRng,
    points: &mut Vec<Point>,
    observations: &mut Vec<Observation>,
) {
    for &c in chosen {
        let xc = images[c].camera_from_object.transform(x);
        let uv = (cameras[c].model)
            .project(&cameras[c].params, &xc, None, None)
            .expect("in front");
        let e = Vector2::new(noise.sample(rng), noise.sample(rng));
        observations.push(Observation {
            image: ImageKey(c),
            point: PointKey(p),
            uv: uv + e,
            sigma: 1.0,
        });
    }
    points.push(Point {
        name: p.to_string(),
        position: *x,
        fixed: false,
        fixed_axes: [false; 3],
    });
}
