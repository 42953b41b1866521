//! A data set for the single-sphere calibration of a camera against a spinning lidar
//! (Tóth, Pusztai & Hajder, ICRA 2020; issue 15): one large sphere moved to N places, seen at
//! each by a 16-beam lidar and by the camera, in a room of a floor and one wall (the clutter
//! the sphere finder has to reject).
//!
//! * **Lidar** (a VLP-16-like model): 16 rings at elevations −15° … +15° in 2° steps, a
//!   full turn in 0.2° azimuth steps, rays from the origin of its own frame (x forward, y left,
//!   z up), Gaussian range noise of a [`RangeNoise`] profile (VLP-16 by default), no return
//!   beyond `max_range_mm`. Clouds are written as XYZ text in metres.
//! * **Camera**: the left camera of the default stereo head (the photogrammetric model with
//!   its true distortion; frame X right, Y forward, Z up), pose `camera_from_lidar` near
//!   "looking along the lidar's x", with a random tilt of a few degrees and a ~15 cm offset.
//! * **Image**: exact ray casting through the camera model (`unproject`), 4×4 sub-pixel rays
//!   on pixels near the sphere's outline; the sphere is uniformly bright (a matt sphere
//!   under diffuse light, as the paper's colour-segmented sphere: no limb darkening, which
//!   would move the silhouette's mid-level edge inwards), the floor and wall matt grey under
//!   a light from above. Then the renderer's blur, vignetting, photon and read noise and
//!   8-bit quantisation ([`crate::render::expose`]).
//! * **Places**: ranges stratified over `range_mm`, directions drawn so that the whole
//!   silhouette (with the edge search's margin) is in the image, the centre within ±10° of
//!   the lidar's horizontal plane, the sphere clear of floor and wall.
//!
//! Same configuration and seed ⇒ byte-identical files.

use crate::config::RenderConfig;
use crate::head::{CameraUnit, StereoRig};
use crate::project_files::{io, write_png, PoseJson};
use crate::render::{render_rays, RayTable};
use crate::sphere_clutter::{self as clutter, Clutter};
use crate::{rng_for, SimConfig, SimError};
use nalgebra::Vector3;
use pingcal_ba::camera::CameraModel;
use pingcal_geometry::{from_opk_deg, Rigid3};
use pingcal_lrf::sensor::NoiseProfile;
use pingcal_lrf::RangeNoise;
use pingcal_project::{CameraFile, SphereCalibFile, SphereCalibFrame, SphereCalibLidar};
use rand::Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::Path;

type V3 = Vector3<f64>;

/// The lidar's ring elevations, degrees: −15 … +15 in 2° steps.
pub fn vlp16_elevations_deg() -> [f64; 16] {
    std::array::from_fn(|k| -15.0 + 2.0 * k as f64)
}

/// What to simulate.
#[derive(Debug, Clone, PartialEq)]
pub struct SphereCalibConfig {
    /// Number of frames (places of the sphere).
    pub frames: usize,
    /// Sphere radius, mm.
    pub sphere_radius_mm: f64,
    /// Range of the sphere's centre from the lidar, mm.
    pub range_mm: [f64; 2],
    /// Height of the lidar above the floor, mm.
    pub lidar_height_mm: f64,
    /// Distance of the wall (the plane x = this, facing the lidar), mm.
    pub wall_mm: f64,
    /// Azimuth step, degrees.
    pub azimuth_step_deg: f64,
    /// Range noise of the lidar.
    pub noise: RangeNoise,
    /// The noise profile's name as the project file gives it; `None`: the project gives
    /// `noise` as `noise_sigma_mm` (then it must be [`RangeNoise::Linear`]).
    pub noise_name: Option<NoiseProfile>,
    /// No return beyond this range, mm.
    pub max_range_mm: f64,
    /// Image formation (blur, vignetting, noise, sub-pixel rays).
    pub render: RenderConfig,
    /// The scene: the clean one (a uniformly bright sphere, a plain room) or the harder one
    /// of real photographs ([`crate::sphere_clutter`]).
    pub scene: SphereScene,
}

/// Which scene the sphere is photographed in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SphereScene {
    /// A uniformly bright floating sphere in a room of a plain floor and wall.
    #[default]
    Clean,
    /// A shaded sphere with a highlight on a stand, a wall of bricks and a tiled floor with
    /// bright round plates, a window and a floor marking; every fourth frame puts the sphere
    /// across the image's border. [`SphereCalibConfig::cluttered`] sets it with ranges of
    /// 1.5–7 m (beyond, two or three rings of the lidar meet the sphere and the stand's seat
    /// beside them pulls the lidar's centre by centimetres).
    Cluttered,
}

impl SphereCalibConfig {
    /// The harder scene ([`SphereScene::Cluttered`]) with ranges of 1.5–7 m.
    pub fn cluttered() -> Self {
        Self {
            scene: SphereScene::Cluttered,
            range_mm: [1500.0, 7000.0],
            ..Self::default()
        }
    }
}

impl Default for SphereCalibConfig {
    fn default() -> Self {
        Self {
            frames: 10,
            sphere_radius_mm: 300.0,
            range_mm: [1000.0, 10_000.0],
            lidar_height_mm: 1100.0,
            wall_mm: 12_000.0,
            azimuth_step_deg: 0.2,
            noise: NoiseProfile::Vlp16.noise(),
            noise_name: Some(NoiseProfile::Vlp16),
            max_range_mm: 100_000.0,
            render: RenderConfig::default(),
            scene: SphereScene::Clean,
        }
    }
}

/// One place of the sphere.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SphereFrameTruth {
    /// `F01`, …
    pub id: String,
    /// The cloud file (relative to the data set).
    pub cloud: String,
    /// The image file.
    pub image: String,
    /// The sphere's centre in the lidar frame, mm.
    pub centre_lidar_mm: [f64; 3],
    /// The sphere's centre in the camera frame, mm.
    pub centre_camera_mm: [f64; 3],
    /// Points of the cloud on the sphere.
    pub sphere_points: usize,
    /// The fraction of the sphere's outline inside the image.
    #[serde(default = "one")]
    pub visible_fraction: f64,
}

fn one() -> f64 {
    1.0
}

/// `truth.json` of a sphere-calib data set.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SphereCalibTruth {
    /// The seed.
    pub seed: u64,
    /// What wrote it.
    pub generator: String,
    /// Conventions, in words.
    pub conventions: Vec<String>,
    /// `camera_from_lidar`: `p_camera = R · p_lidar + t` (results.json convention).
    pub extrinsic: PoseJson,
    /// Sphere diameter, mm.
    pub sphere_diameter_mm: f64,
    /// The range-noise profile used.
    pub noise: RangeNoise,
    /// The frames.
    pub frames: Vec<SphereFrameTruth>,
}

/// A simulated data set (everything but the rendered images and written clouds).
#[derive(Debug, Clone)]
pub struct SphereCalibSim {
    /// The configuration.
    pub config: SphereCalibConfig,
    /// The seed.
    pub seed: u64,
    /// The camera with its true parameters.
    pub camera: CameraUnit,
    /// Lidar → camera.
    pub camera_from_lidar: Rigid3,
    /// Sphere centres in the lidar frame, mm.
    pub centres_lidar: Vec<V3>,
    /// The harder scene's clutter (`None` for the clean scene).
    pub clutter: Option<Clutter>,
}

/// What was written.
#[derive(Debug, Clone, Copy)]
pub struct SphereCalibSummary {
    /// Frames.
    pub frames: usize,
    /// Points over all clouds.
    pub points: usize,
}

/// The nearest hit of the ray `o + t·d` (`d` unit) with the sphere: `t`.
fn hit_sphere(o: &V3, d: &V3, c: &V3, r: f64) -> Option<f64> {
    let oc = o - c;
    let b = oc.dot(d);
    let disc = b * b - (oc.norm_squared() - r * r);
    if disc < 0.0 {
        return None;
    }
    let t = -b - disc.sqrt();
    (t > 1e-6).then_some(t)
}

/// What a ray hits first, and where: 0 sphere, 1 floor, 2 wall, 3 the stand's seat, 4 its
/// pole (the last two in the cluttered scene only).
fn cast(sim: &SphereCalibSim, frame: usize, o: &V3, d: &V3) -> Option<(usize, f64)> {
    let cfg = &sim.config;
    let c = sim.centres_lidar[frame];
    let mut best: Option<(usize, f64)> = hit_sphere(o, d, &c, cfg.sphere_radius_mm).map(|t| (0, t));
    if sim.clutter.is_some() {
        if let Some((t, part)) =
            clutter::hit_stand(o, d, &c, cfg.sphere_radius_mm, -cfg.lidar_height_mm)
        {
            if best.is_none_or(|(_, b)| t < b) {
                best = Some((if part == clutter::Part::Seat { 3 } else { 4 }, t));
            }
        }
    }
    let mut consider = |kind: usize, t: f64| {
        if t > 1e-6 && best.is_none_or(|(_, b)| t < b) {
            best = Some((kind, t));
        }
    };
    if d.z < 0.0 {
        consider(1, (-cfg.lidar_height_mm - o.z) / d.z);
    }
    if d.x > 0.0 {
        consider(2, (cfg.wall_mm - o.x) / d.x);
    }
    best
}

/// The outline of a sphere of radius `r` at `xc` (camera frame), scaled by `k`, at `n` angles.
fn outline_points(xc: &V3, r: f64, k: f64, n: usize) -> impl Iterator<Item = V3> + '_ {
    let axis = xc.normalize();
    let e1 = axis.cross(&V3::z()).normalize();
    let e2 = axis.cross(&e1);
    (0..n).map(move |i| {
        let a = std::f64::consts::TAU * i as f64 / n as f64;
        xc + (e1 * a.cos() + e2 * a.sin()) * r * k
    })
}

/// The fraction of the outline of a sphere of radius `r` at `xc` (camera frame) that images
/// inside the camera's image (72 points of the silhouette).
pub fn visible_fraction(camera: &CameraUnit, xc: &V3, r: f64) -> f64 {
    let d = xc.norm();
    let (w, h) = (camera.model.width as f64, camera.model.height as f64);
    // points of the silhouette cone at the sphere's distance: the tangent circle
    let k = (1.0 - (r / d).powi(2)).max(0.0).sqrt();
    let ctr = xc * (1.0 - (r / d).powi(2));
    let inside = outline_points(&ctr, r, k, 72)
        .filter(|p| {
            camera
                .model
                .project(&camera.params, p, None, None)
                .is_some_and(|uv| uv.x >= 0.0 && uv.y >= 0.0 && uv.x <= w - 1.0 && uv.y <= h - 1.0)
        })
        .count();
    inside as f64 / 72.0
}

/// A place for frame `k`'s sphere: ranges stratified over the frames, a direction drawn
/// until the sphere is in both fields of view — wholly in the image with the edge search's
/// margin, or, when `cut`, across the image's border (its centre's image inside, 0.35 to
/// 0.85 of its outline in the image); every point of the outline within the distortion's
/// range either way.
fn place(
    cfg: &SphereCalibConfig,
    camera: &CameraUnit,
    camera_from_lidar: &Rigid3,
    seed: u64,
    k: usize,
    cut: bool,
) -> Option<V3> {
    let r_max = camera.max_ideal_radius_mm() * 0.98;
    let (w, h) = (camera.model.width as f64, camera.model.height as f64);
    let f_px = camera.params[0] / camera.model.pixel_size_mm;
    let r = cfg.sphere_radius_mm;
    let mut rng = rng_for(seed, "sphere-calib-place", k as u64);
    for _ in 0..10_000 {
        let u: f64 = rng.random();
        let range = cfg.range_mm[0]
            + (cfg.range_mm[1] - cfg.range_mm[0]) * (k as f64 + u) / cfg.frames as f64;
        // across the border: the image's left and right edges are 44° off its axis (the
        // lidar sees 15° up and down only)
        let (a, e): (f64, f64) = if cut { (55.0, 10.0) } else { (40.0, 10.0) };
        let az = rng.random_range(-a..a).to_radians();
        let el = rng.random_range(-e..e).to_radians();
        let c = V3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin()) * range;
        if c.z - r < -cfg.lidar_height_mm + 50.0 || c.x + r > cfg.wall_mm - 100.0 {
            continue;
        }
        let xc = camera_from_lidar.transform(&c);
        let Some(uv) = camera.project_in_view(&xc, r_max) else {
            continue;
        };
        let inside = if cut {
            let v = visible_fraction(camera, &xc, r);
            uv.x >= 0.0
                && uv.y >= 0.0
                && uv.x <= w - 1.0
                && uv.y <= h - 1.0
                && (0.35..=0.85).contains(&v)
        } else {
            // the silhouette's radius in pixels, with the edge search's margin (1.35 ×)
            let rho = f_px * (r / (xc.norm() - r).max(1.0)) * 1.35 + 6.0;
            uv.x - rho >= 0.0 && uv.x + rho <= w - 1.0 && uv.y - rho >= 0.0 && uv.y + rho <= h - 1.0
        };
        // and every point of the outline must image (inside the distortion's range)
        if inside
            && outline_points(&xc, r, 1.3, 24).all(|p| camera.project_in_view(&p, r_max).is_some())
        {
            return Some(c);
        }
    }
    None
}

impl SphereCalibSim {
    /// Draws the extrinsic and the sphere's places for `cfg` and `seed`.
    pub fn new(cfg: &SphereCalibConfig, seed: u64) -> Result<Self, SimError> {
        let bad = |what: String| SimError::Config {
            file: "sphere-calib simulation".into(),
            what,
        };
        if cfg.noise_name.is_none() && !matches!(cfg.noise, RangeNoise::Linear { .. }) {
            return Err(bad(
                "a range-noise profile without a name must be linear (σ = a + b·r)".into(),
            ));
        }
        if cfg.frames < 3 {
            return Err(bad(format!(
                "frames = {}: at least 3 are needed",
                cfg.frames
            )));
        }
        if !(cfg.sphere_radius_mm > 0.0 && cfg.range_mm[0] > 2.0 * cfg.sphere_radius_mm)
            || cfg.range_mm[1] < cfg.range_mm[0]
            || cfg.range_mm[1] + cfg.sphere_radius_mm >= cfg.wall_mm
        {
            return Err(bad(format!(
                "sphere radius {} mm, ranges {:?} mm, wall at {} mm: the sphere must fit between the sensors and the wall",
                cfg.sphere_radius_mm, cfg.range_mm, cfg.wall_mm
            )));
        }
        let camera = StereoRig::from_config(&SimConfig::default()).cameras[0].clone();
        let mut rng = rng_for(seed, "sphere-calib-extrinsic", 0);
        // lidar x forward, y left, z up → camera X right, Y forward, Z up
        let base = nalgebra::Matrix3::new(0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0);
        let tilt = from_opk_deg([
            rng.random_range(-4.0..4.0),
            rng.random_range(-4.0..4.0),
            rng.random_range(-4.0..4.0),
        ]);
        let centre_in_lidar = V3::new(
            60.0 + rng.random_range(-20.0..20.0),
            -120.0 + rng.random_range(-20.0..20.0),
            -90.0 + rng.random_range(-20.0..20.0),
        );
        let camera_from_lidar = Rigid3::from_rotation_and_centre(tilt * base, centre_in_lidar);
        let mut centres = Vec::with_capacity(cfg.frames);
        for k in 0..cfg.frames {
            let cut = cfg.scene == SphereScene::Cluttered && k % 4 == 3;
            let c = place(cfg, &camera, &camera_from_lidar, seed, k, cut).ok_or_else(|| {
                bad(format!(
                    "frame {}: no place for the sphere in both fields of view",
                    k + 1
                ))
            })?;
            centres.push(c);
        }
        let clutter = (cfg.scene == SphereScene::Cluttered).then(|| {
            Clutter::new(
                seed,
                cfg.wall_mm,
                -cfg.lidar_height_mm,
                cfg.sphere_radius_mm,
            )
        });
        Ok(Self {
            config: cfg.clone(),
            seed,
            camera,
            camera_from_lidar,
            centres_lidar: centres,
            clutter,
        })
    }

    /// The lidar's cloud of frame `k` (mm, lidar frame) and the number of its points on
    /// the sphere.
    pub fn cloud(&self, k: usize) -> (Vec<V3>, usize) {
        let cfg = &self.config;
        let n_az = (360.0 / cfg.azimuth_step_deg).round() as usize;
        let els = vlp16_elevations_deg();
        let rows: Vec<(Vec<V3>, usize)> = els
            .par_iter()
            .enumerate()
            .map(|(ring, el)| {
                let mut rng = rng_for(self.seed, "sphere-calib-lidar", (k * 16 + ring) as u64);
                let el = el.to_radians();
                let mut pts = Vec::with_capacity(n_az);
                let mut on = 0;
                for i in 0..n_az {
                    let az = (i as f64 * cfg.azimuth_step_deg).to_radians();
                    let d = V3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin());
                    let Some((kind, t)) = cast(self, k, &V3::zeros(), &d) else {
                        continue;
                    };
                    if t > cfg.max_range_mm {
                        continue;
                    }
                    let rr = cfg.noise.perturb(t, &mut rng);
                    if rr <= 0.0 {
                        continue;
                    }
                    on += usize::from(kind == 0);
                    pts.push(d * rr);
                }
                (pts, on)
            })
            .collect();
        let on = rows.iter().map(|r| r.1).sum();
        (rows.into_iter().flat_map(|r| r.0).collect(), on)
    }

    fn radiance_of(&self, k: usize, o: &V3, d: &V3) -> f64 {
        if let Some(cl) = &self.clutter {
            return self.cluttered_radiance(cl, k, o, d);
        }
        match cast(self, k, o, d) {
            None => 0.05,
            Some((0, _)) => 0.78,
            Some((kind, t)) => {
                let p = o + d * t;
                let (albedo, normal) = if kind == 1 {
                    (0.32, V3::z())
                } else {
                    (0.45, -V3::x())
                };
                // a light from above and behind the sensors, plus ambient; a faint
                // large-scale texture so the background is not flat
                let light = V3::new(-0.3, 0.2, 1.0).normalize();
                let tex = 1.0 + 0.04 * (p.x * 7e-4).sin() * (p.y * 9e-4 + p.z * 5e-4).cos();
                albedo * (0.35 + 0.55 * normal.dot(&light).max(0.0)) * tex
            }
        }
    }

    /// The radiance of the harder scene ([`crate::sphere_clutter`]) along `o + t·d`.
    fn cluttered_radiance(&self, cl: &Clutter, k: usize, o: &V3, d: &V3) -> f64 {
        let c = self.centres_lidar[k];
        let light = V3::from(clutter::LIGHT).normalize();
        match cast(self, k, o, d) {
            None => 0.05,
            Some((0, t)) => clutter::sphere_radiance(&(o + d * t), &c, o),
            Some((3, _)) => clutter::stand_radiance(clutter::Part::Seat),
            Some((4, _)) => clutter::stand_radiance(clutter::Part::Pole),
            Some((1, t)) => clutter::floor_radiance(cl, &(o + d * t), 0.35 + 0.55 * light.z),
            Some((_, t)) => {
                clutter::wall_radiance(cl, &(o + d * t), 0.35 + 0.55 * (-light.x).max(0.0))
            }
        }
    }

    /// The 8-bit image of frame `k`.
    pub fn image(&self, k: usize, table: &RayTable) -> image::GrayImage {
        let cam = &self.camera;
        let lidar_from_camera = self.camera_from_lidar.inverse();
        let origin = lidar_from_camera.translation;
        let rot = lidar_from_camera.rotation;
        let c_cam = self.camera_from_lidar.transform(&self.centres_lidar[k]);
        let axis = c_cam.normalize();
        let alpha = (self.config.sphere_radius_mm / c_cam.norm()).asin();
        let px_angle = cam.model.pixel_size_mm / cam.params[0];
        let near_edge = |ray: &V3| {
            (ray.dot(&axis).clamp(-1.0, 1.0).acos() - alpha).abs()
                < 3.0 * px_angle / ray.y.max(0.1).powi(2)
        };
        let at = (self.seed, k as u64);
        render_rays(cam, table, &self.config.render, at, near_edge, |d| {
            self.radiance_of(k, &origin, &(rot * d))
        })
    }

    /// The camera file of the data set (the true intrinsics).
    pub fn camera_file(&self) -> CameraFile {
        CameraFile::photogrammetric(
            self.camera.model.width,
            self.camera.model.height,
            self.camera.model.pixel_size_mm,
            pingcal_project::CameraParams::from_slice(
                self.camera.params[..]
                    .try_into()
                    .expect("the sphere-calib simulation's camera is photogrammetric"),
            ),
        )
    }

    fn frame_files(k: usize) -> (String, String, String) {
        let id = format!("F{:02}", k + 1);
        (format!("clouds/{id}.xyz"), format!("images/{id}.png"), id)
    }

    /// The project file of the data set.
    pub fn project_file(&self) -> SphereCalibFile {
        SphereCalibFile {
            version: 1,
            name: Some(format!("simulated sphere calibration, seed {}", self.seed)),
            camera: "camera.toml".into(),
            camera_entry: None,
            sphere_diameter_mm: 2.0 * self.config.sphere_radius_mm,
            lidar: SphereCalibLidar {
                unit: pingcal_lrf::cloud_file::CloudUnit::M,
                noise: self.config.noise_name,
                noise_sigma_mm: match (&self.config.noise_name, self.config.noise) {
                    (None, RangeNoise::Linear { a_mm, b }) => Some([a_mm, b]),
                    _ => None,
                },
                model: Some("16-beam spinning lidar (VLP-16-like), simulated".into()),
            },
            frames: (0..self.config.frames)
                .map(|k| {
                    let (cloud, image, id) = Self::frame_files(k);
                    SphereCalibFrame {
                        id: Some(id),
                        cloud,
                        image,
                    }
                })
                .collect(),
        }
    }
}

/// Renders and writes the data set into `dir` (created if needed): `sphere-calib.toml`,
/// `camera.toml`, `clouds/F01.xyz` … (metres), `images/F01.png` …, `truth.json`. Callers
/// that must not leave a partial data set looking complete write into a temporary folder
/// and rename it (as `pingcal simulate` does).
pub fn write_sphere_calib(
    sim: &SphereCalibSim,
    dir: &Path,
) -> Result<SphereCalibSummary, SimError> {
    for sub in ["clouds", "images"] {
        std::fs::create_dir_all(dir.join(sub)).map_err(|e| io(&dir.join(sub), e))?;
    }
    let table = RayTable::new(&sim.camera);
    let mut frames = Vec::new();
    let mut points = 0;
    for k in 0..sim.config.frames {
        let (cloud_rel, image_rel, id) = SphereCalibSim::frame_files(k);
        let (cloud, on) = sim.cloud(k);
        points += cloud.len();
        let mut text = String::with_capacity(cloud.len() * 28);
        text.push_str("# x y z, metres, lidar frame (simulated 16-beam lidar)\n");
        for p in &cloud {
            use std::fmt::Write;
            let _ = writeln!(
                text,
                "{:.5} {:.5} {:.5}",
                p.x * 1e-3,
                p.y * 1e-3,
                p.z * 1e-3
            );
        }
        let cloud_path = dir.join(&cloud_rel);
        std::fs::write(&cloud_path, text).map_err(|e| io(&cloud_path, e))?;
        let img = sim.image(k, &table);
        write_png(&dir.join(&image_rel), &img)?;
        let c = sim.centres_lidar[k];
        let cc = sim.camera_from_lidar.transform(&c);
        frames.push(SphereFrameTruth {
            id,
            cloud: cloud_rel,
            image: image_rel,
            centre_lidar_mm: [c.x, c.y, c.z],
            centre_camera_mm: [cc.x, cc.y, cc.z],
            sphere_points: on,
            visible_fraction: visible_fraction(&sim.camera, &cc, sim.config.sphere_radius_mm),
        });
    }
    let camera_path = dir.join("camera.toml");
    std::fs::write(
        &camera_path,
        format!(
            "# the simulated camera's true intrinsics (photogrammetric model, docs/formats.md)\n{}",
            sim.camera_file().to_toml_string()
        ),
    )
    .map_err(|e| io(&camera_path, e))?;
    let project_path = dir.join("sphere-calib.toml");
    std::fs::write(
        &project_path,
        format!(
            "# pingcal sphere-calib project, written by `pingcal simulate --kind sphere-calib --seed {}`.\n# Paths are relative to this file.\n\n{}",
            sim.seed,
            sim.project_file().to_toml_string()
        ),
    )
    .map_err(|e| io(&project_path, e))?;
    let truth = SphereCalibTruth {
        seed: sim.seed,
        generator: format!("pingcal-sim {} sphere_calib", env!("CARGO_PKG_VERSION")),
        conventions: vec![
            "extrinsic: camera_from_lidar, p_camera = R · p_lidar + t, mm".into(),
            "camera frame: X image right, Y optical axis (forward), Z image up".into(),
            "lidar frame: x forward (azimuth 0), y left, z up (the spin axis)".into(),
            "angles: ω φ κ in degrees, R = R_ω R_φ R_κ".into(),
        ],
        extrinsic: PoseJson::from_pose(&sim.camera_from_lidar),
        sphere_diameter_mm: 2.0 * sim.config.sphere_radius_mm,
        noise: sim.config.noise,
        frames,
    };
    let truth_path = dir.join("truth.json");
    let json = serde_json::to_string_pretty(&truth).map_err(|e| io(&truth_path, e))?;
    std::fs::write(&truth_path, json + "\n").map_err(|e| io(&truth_path, e))?;
    Ok(SphereCalibSummary {
        frames: sim.config.frames,
        points,
    })
}

/// Reads a sphere-calib `truth.json`.
pub fn read_sphere_calib_truth(path: &Path) -> Result<SphereCalibTruth, SimError> {
    let text = std::fs::read_to_string(path).map_err(|e| io(path, e))?;
    serde_json::from_str(&text).map_err(|e| io(path, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn places_are_in_both_fields_of_view_and_the_lidar_sees_the_sphere() {
        let sim = SphereCalibSim::new(&SphereCalibConfig::default(), 3).unwrap();
        assert_eq!(sim.centres_lidar.len(), 10);
        for (k, c) in sim.centres_lidar.iter().enumerate() {
            let range = c.norm();
            assert!((1000.0..=10_000.0).contains(&range), "{range}");
            let (pts, on) = sim.cloud(k);
            assert!(
                on >= 10,
                "frame {k}: {on} points on the sphere at {range:.0} mm"
            );
            // noise-free geometry: points on the sphere are within a few σ of its surface
            assert!(pts.len() > 20_000);
        }
    }
}
