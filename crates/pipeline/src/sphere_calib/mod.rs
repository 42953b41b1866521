//! The extrinsic of a camera against any lidar from one large sphere moved between N frames
//! (Tóth, Pusztai & Hajder, ICRA 2020; issue 15). The project file is
//! `pingcal_project::sphere_calib` (docs/sphere-calib.md).
//!
//! Per frame:
//! * **lidar**: the sphere's centre by [`pingcal_lrf::ball_finder::find_balls`] at the
//!   project's diameter and noise profile; exactly one sphere is expected, a frame with none
//!   or several is reported and left out;
//! * **camera**: the silhouette found as the one round bright blob of the image, its
//!   sub-pixel edge points and ellipse by the targets crate (`centre::refine`,
//!   `centre::edge_points`), the centre seeded by the cone through the ellipse
//!   (`ball::sphere_centre_from_ellipse`, NOTES.md "Projection of a sphere"), then fitted
//!   to the edge points directly: the three coordinates of the centre of a sphere of the
//!   known radius whose silhouette cone passes through the edge rays (each ray from the
//!   camera model's own `unproject`, so distortion is exact), by Gauss–Newton with one
//!   robust trim, its covariance `s² (JᵀJ)⁻¹` from the edge residuals.
//!
//! Then the 3D conformal transform of `pingcal_lrf::registration` (weighted by both
//! covariances) with σ, per-frame residuals and leave-one-out errors, and beside it the
//! published closed form for comparison ([`closed_form_centre`] + unweighted SVD).
//!
//! [`calibrate`] runs it on a project file, [`results_json`] gives its `results.json`
//! (`pingcal sphere-calib` writes it).

use nalgebra::{Matrix3, Vector3};
use pingcal_ba::camera::{CameraModel, PhotogrammetricCamera};
use pingcal_lrf::ball_finder::{find_balls, FinderOptions};
use pingcal_lrf::cloud_file::{read_cloud_file_in, CloudUnit};
use pingcal_lrf::registration::{self, PointObs, RegistrationOptions};
use pingcal_lrf::{MountModel, RangeNoise};
use pingcal_project::{CameraFile, SphereCalibFile};
use pingcal_targets::ball::{sphere_centre_from_ellipse, sphere_centre_major_axis, FnCamera};
use pingcal_targets::centre::{refine, robust_ellipse_fit, CentreParams};
use pingcal_targets::ellipse::Ellipse;
use pingcal_targets::GrayImage;
use std::path::{Path, PathBuf};

type V3 = Vector3<f64>;
/// An image point, pixels.
type Pixel = (f64, f64);

/// The camera of the project: the photogrammetric model with known parameters.
#[derive(Debug, Clone)]
pub struct Camera {
    /// Sensor geometry.
    pub model: PhotogrammetricCamera,
    /// `[c, xp, yp, K1, K2, K3, P1, P2, B1, B2]`.
    pub params: [f64; 10],
}

impl Camera {
    /// From a camera file.
    pub fn from_file(c: &CameraFile) -> Self {
        Camera {
            model: PhotogrammetricCamera::new(c.width, c.height, c.pixel_size_mm),
            params: c.params.to_slice(),
        }
    }

    /// The unit ray through a pixel.
    pub fn ray(&self, x: f64, y: f64) -> Option<V3> {
        self.model
            .unproject(&self.params, &nalgebra::Vector2::new(x, y))
            .map(|r| r.normalize())
    }

    /// Principal distance in pixels.
    pub fn f_px(&self) -> f64 {
        self.params[0] / self.model.pixel_size_mm
    }
}

/// The sphere's centre in the camera frame from its silhouette.
#[derive(Debug, Clone)]
pub struct ImageSphere {
    /// The ellipse fitted to the edge points (pixels).
    pub ellipse: Ellipse,
    /// Edge points used by the centre fit.
    pub edges: usize,
    /// RMS of their residuals, pixels.
    pub rms_px: f64,
    /// The edge's blur (σ of a Gaussian, pixels) measured from its profile.
    pub sigma_blur_px: f64,
    /// Centre, mm (camera frame).
    pub centre: V3,
    /// Its covariance, mm² (the fit's, times the variance inflation of the edge residuals'
    /// correlation along the outline).
    pub cov: Matrix3<f64>,
    /// That inflation factor.
    pub inflation: f64,
    /// The published closed form's centre (ellipse of the undistorted half-level edge points,
    /// without the blur correction, the bisector of its major axis' end rays,
    /// d = √2·r/√(1 − q₁·q₂)), mm.
    pub closed_form: V3,
}

/// Residuals (radians) and Jacobian rows of the silhouette cone of a sphere of radius `r`
/// centred at `c` against unit rays `q`: `acos(q·ĉ) − asin(r/|c|)`.
fn cone_residuals(q: &[V3], c: &V3, r: f64) -> Option<(Vec<f64>, Vec<V3>)> {
    let d = c.norm();
    if !(d > r * 1.0001) {
        return None;
    }
    let u = c / d;
    let alpha = (r / d).asin();
    let dalpha = u * (-r / (d * d * (1.0 - (r / d).powi(2)).sqrt()));
    let mut res = Vec::with_capacity(q.len());
    let mut jac = Vec::with_capacity(q.len());
    for qi in q {
        let cos = qi.dot(&u).clamp(-1.0, 1.0);
        let theta = cos.acos();
        let sin = theta.sin().max(1e-12);
        let dtheta = -(qi - u * cos) / (d * sin);
        res.push(theta - alpha);
        jac.push(dtheta - dalpha);
    }
    Some((res, jac))
}

/// Gauss–Newton fit of the centre to the rays; returns the centre and its covariance
/// `s²(JᵀJ)⁻¹` with s² the residuals' mean square over n − 3.
fn fit_cone(q: &[V3], c0: V3, r: f64) -> Option<(V3, Matrix3<f64>, f64)> {
    let mut c = c0;
    for _ in 0..30 {
        let (res, jac) = cone_residuals(q, &c, r)?;
        let mut n = Matrix3::zeros();
        let mut g = V3::zeros();
        for (e, j) in res.iter().zip(&jac) {
            n += j * j.transpose();
            g += j * *e;
        }
        let dx = n.try_inverse()? * (-g);
        c += dx;
        if dx.norm() < 1e-9 * c.norm() {
            break;
        }
    }
    let (res, jac) = cone_residuals(q, &c, r)?;
    let mut n = Matrix3::zeros();
    for j in &jac {
        n += j * j.transpose();
    }
    let dof = res.len().checked_sub(3).filter(|&d| d > 0)?;
    let s2 = res.iter().map(|e| e * e).sum::<f64>() / dof as f64;
    let cov = n.try_inverse()? * s2;
    c.iter()
        .all(|v| v.is_finite())
        .then_some((c, cov, s2.sqrt()))
}

/// The variance inflation of a mean of the correlated series `res` (ordered around the
/// outline, cyclic): `1 + 2 Σ ρ_l` over lags 1–4, at least 1.
fn correlation_inflation(res: &[f64]) -> f64 {
    let n = res.len();
    if n < 16 {
        return 1.0;
    }
    let m = res.iter().sum::<f64>() / n as f64;
    let c0 = res.iter().map(|e| (e - m).powi(2)).sum::<f64>();
    if !(c0 > 0.0) {
        return 1.0;
    }
    let rho: f64 = (1..=4)
        .map(|l| {
            (0..n)
                .map(|i| (res[i] - m) * (res[(i + l) % n] - m))
                .sum::<f64>()
                / c0
        })
        .sum();
    (1.0 + 2.0 * rho).max(1.0)
}

/// The closed form of Tóth et al. (NOTES.md "Projection of a sphere"): an ellipse fitted to
/// the undistorted edge points, the two ends of its major axis as unit rays q₁, q₂,
/// w = normalize(q₁ + q₂), d = √2·r/√(1 − q₁·q₂), C = d·w. Camera frame of `cam`.
pub fn closed_form_centre(edges: &[(f64, f64)], cam: &Camera, r: f64) -> Option<V3> {
    let f = cam.f_px();
    // the ideal pinhole image (x right, y down, in pixels of focal length f) of each edge ray
    let ideal: Vec<(f64, f64)> = edges
        .iter()
        .filter_map(|&(x, y)| {
            let q = cam.ray(x, y)?;
            (q.y > 0.0).then(|| (f * q.x / q.y, -f * q.z / q.y))
        })
        .collect();
    let (e, _, _) = robust_ellipse_fit(&ideal)?;
    let pin = FnCamera(
        move |x: f64, y: f64| Some([x / f, 1.0, -y / f]),
        move |q: [f64; 3]| (q[1] > 0.0).then(|| [f * q[0] / q[1], -f * q[2] / q[1]]),
    );
    let s = sphere_centre_major_axis(&e, &pin, Some(r))?;
    Some(V3::from(s.axis) * s.distance?)
}

/// The one sphere-like silhouette of an image: a bright round blob (fill ratio above 0.85,
/// area 40 px or more, clear of the border). `Err` says what was seen instead.
fn find_silhouette(img: &GrayImage) -> Result<Ellipse, String> {
    let mut v: Vec<f32> = img.data.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return Err("an empty image".into());
    }
    let n = v.len();
    let median = *v.select_nth_unstable_by(n / 2, |a, b| a.total_cmp(b)).1;
    let top = *v
        .select_nth_unstable_by((n - 1).min(n - n / 10_000 - 1), |a, b| a.total_cmp(b))
        .1;
    if !(top - median > 0.05) {
        return Err(format!(
            "no bright silhouette (brightest 0.01 % of the pixels at {top:.2}, median {median:.2})"
        ));
    }
    let level = median + 0.5 * (top - median);
    let blobs = pingcal_targets::blobs::components_above(img, level, 40, usize::MAX);
    let round: Vec<Ellipse> = blobs
        .iter()
        .filter(|b| !b.touches_border(img.width, img.height) && b.fill_ratio() > 0.85)
        .filter_map(|b| b.moment_ellipse())
        .collect();
    match round.len() {
        0 => Err(format!(
            "no round bright silhouette clear of the border ({} bright blobs, none round)",
            blobs.len()
        )),
        1 => Ok(round[0]),
        k => Err(format!(
            "{k} round bright silhouettes, one expected: at {}",
            round
                .iter()
                .map(|e| format!("({:.0}, {:.0})", e.cx, e.cy))
                .collect::<Vec<_>>()
                .join(", ")
        )),
    }
}

/// Sub-pixel edge points of a silhouette whose outline is about `e`: along the outline's
/// normal at `k` places, the crossing of the level half way between the mean inside
/// (4–8 px in) and the mean outside (4–8 px out), each moved outward by `σ_b²·κ/2`, the
/// inward shift of the half level of a uniform disc blurred by a Gaussian of σ_b (κ the
/// outline's curvature, px⁻¹: 0.01 px at 20 px radius and σ_b = 0.66 px, 4.5 mm of range at
/// 9 m for a 600 mm sphere). σ_b is the median over the normals of the 25–75 % width of the
/// edge / 1.349. Returns the corrected points, the uncorrected ones (the half level itself,
/// what a plain edge detector gives) and σ_b.
pub fn silhouette_edges(img: &GrayImage, e: &Ellipse) -> Option<(Vec<Pixel>, Vec<Pixel>, f64)> {
    let perimeter = std::f64::consts::TAU * (e.a * e.b).sqrt();
    let k = (perimeter.round() as usize).clamp(64, 720);
    let (sn, cs) = e.theta.sin_cos();
    const STEP: f64 = 0.125;
    let samples: Vec<f64> = (-64..=64).map(|i| i as f64 * STEP).collect();
    let mut found = Vec::with_capacity(k);
    for i in 0..k {
        let t = std::f64::consts::TAU * i as f64 / k as f64;
        let (p0, p1) = e.point(t);
        // outward normal: the gradient of the ellipse's implicit form at (p0, p1)
        let (u, v) = (t.cos() / e.a, t.sin() / e.b);
        let (nx, ny) = (cs * u - sn * v, sn * u + cs * v);
        let nn = (nx * nx + ny * ny).sqrt();
        let (nx, ny) = (nx / nn, ny / nn);
        if !img.inside(p0 - 9.0 * nx, p1 - 9.0 * ny, 1.0)
            || !img.inside(p0 + 9.0 * nx, p1 + 9.0 * ny, 1.0)
        {
            continue;
        }
        let prof: Vec<f64> = samples
            .iter()
            .map(|&s| img.sample(p0 + s * nx, p1 + s * ny) as f64)
            .collect();
        let mean = |lo: f64, hi: f64| {
            let sel: Vec<f64> = samples
                .iter()
                .zip(&prof)
                .filter(|(s, _)| **s >= lo && **s <= hi)
                .map(|(_, v)| *v)
                .collect();
            sel.iter().sum::<f64>() / sel.len() as f64
        };
        let (fg, bg) = (mean(-8.0, -4.0), mean(4.0, 8.0));
        if !(fg - bg > 0.05) {
            continue;
        }
        // the first downward crossing of `frac` of the way from bg to fg, from 4 px inside
        let crossing = |frac: f64| -> Option<f64> {
            let level = bg + frac * (fg - bg);
            let start = samples.iter().position(|&s| s >= -4.0)?;
            (start..samples.len() - 1).find_map(|j| {
                (prof[j] >= level && prof[j + 1] < level)
                    .then(|| samples[j] + STEP * (prof[j] - level) / (prof[j] - prof[j + 1]))
            })
        };
        let (Some(s50), Some(s75), Some(s25)) = (crossing(0.5), crossing(0.75), crossing(0.25))
        else {
            continue;
        };
        if s50.abs() > 4.0 {
            continue;
        }
        let a2s = e.a * e.a * t.sin().powi(2) + e.b * e.b * t.cos().powi(2);
        let kappa = e.a * e.b / a2s.powf(1.5);
        found.push((p0, p1, nx, ny, s50, (s25 - s75) / 1.349, kappa));
    }
    if found.len() < 12 {
        return None;
    }
    let mut widths: Vec<f64> = found.iter().map(|f| f.5).collect();
    let mid = widths.len() / 2;
    let sigma_b = *widths.select_nth_unstable_by(mid, |a, b| a.total_cmp(b)).1;
    let pts = found
        .iter()
        .map(|&(p0, p1, nx, ny, s50, _, kappa)| {
            let s = s50 + 0.5 * sigma_b * sigma_b * kappa;
            (p0 + s * nx, p1 + s * ny)
        })
        .collect();
    let raw = found
        .iter()
        .map(|&(p0, p1, nx, ny, s50, _, _)| (p0 + s50 * nx, p1 + s50 * ny))
        .collect();
    Some((pts, raw, sigma_b))
}

/// The sphere's centre in the camera frame from its silhouette in `img`.
pub fn image_sphere(img: &GrayImage, cam: &Camera, radius_mm: f64) -> Result<ImageSphere, String> {
    let seed = find_silhouette(img)?;
    let p = CentreParams {
        min_contrast: 0.05,
        bg_window: (0.8, 1.3),
        max_rms: (0.5, 0.04),
        ..CentreParams::default()
    };
    let refined = refine(img, &seed, &p)
        .map_err(|e| format!("the silhouette at ({:.0}, {:.0}): {e:?}", seed.cx, seed.cy))?;
    let (pts, raw, sigma_blur_px) = silhouette_edges(img, &refined.ellipse).ok_or_else(|| {
        format!(
            "the silhouette at ({:.0}, {:.0}): too few edge points along its outline",
            refined.ellipse.cx, refined.ellipse.cy
        )
    })?;
    let rays: Vec<V3> = pts.iter().filter_map(|&(x, y)| cam.ray(x, y)).collect();
    if rays.len() < 12 {
        return Err(format!(
            "only {} edge points of the silhouette image through the camera model",
            rays.len()
        ));
    }
    let rays_fn = FnCamera(
        |x: f64, y: f64| cam.ray(x, y).map(|r| [r.x, r.y, r.z]),
        |q: [f64; 3]| {
            cam.model
                .project(&cam.params, &V3::from(q), None, None)
                .map(|p| [p.x, p.y])
        },
    );
    let s0 = sphere_centre_from_ellipse(&refined.ellipse, &rays_fn, Some(radius_mm))
        .ok_or("the silhouette's cone has no sphere of the given radius")?;
    let c0 = V3::from(s0.axis) * s0.distance.unwrap_or(radius_mm * 10.0);
    let (c1, _, _) =
        fit_cone(&rays, c0, radius_mm).ok_or("the sphere fit to the silhouette diverged")?;
    // one robust trim: residuals beyond 3 robust σ (at least 0.25 px) are edge outliers
    let (res, _) = cone_residuals(&rays, &c1, radius_mm).ok_or("the sphere fit diverged")?;
    let mut abs: Vec<f64> = res.iter().map(|e| e.abs()).collect();
    let mid = abs.len() / 2;
    let mad = *abs.select_nth_unstable_by(mid, |a, b| a.total_cmp(b)).1;
    let px = 1.0 / cam.f_px();
    let lim = (3.0 * 1.4826 * mad).max(0.25 * px);
    let kept: Vec<V3> = rays
        .iter()
        .zip(&res)
        .filter(|(_, e)| e.abs() <= lim)
        .map(|(q, _)| *q)
        .collect();
    let (centre, cov, s) =
        fit_cone(&kept, c1, radius_mm).ok_or("the sphere fit to the silhouette diverged")?;
    // neighbouring edge points share pixels (the blur, the bilinear samples): their errors
    // are correlated, so the centre's variance is that of fewer independent points
    let (res, _) = cone_residuals(&kept, &centre, radius_mm).ok_or("the sphere fit diverged")?;
    let inflation = correlation_inflation(&res);
    let cov = cov * inflation;
    // the published method has no blur correction: its ellipse is fitted to the half level
    let closed_form = closed_form_centre(&raw, cam, radius_mm)
        .ok_or("the closed form has no solution on this silhouette")?;
    Ok(ImageSphere {
        ellipse: refined.ellipse,
        edges: kept.len(),
        rms_px: s / px,
        sigma_blur_px,
        centre,
        cov,
        inflation,
        closed_form,
    })
}

/// One frame's outcome.
#[derive(Debug, Clone)]
pub struct Frame {
    /// Its id.
    pub id: String,
    /// Centre in the lidar frame with its covariance, and the fit's inliers and σ₀.
    pub lidar: Option<(V3, Matrix3<f64>, usize, f64)>,
    /// Centre in the camera frame.
    pub image: Option<ImageSphere>,
    /// Why the frame is not used (`None`: used).
    pub skipped: Option<String>,
    /// Warnings (cloud unit, …).
    pub warnings: Vec<String>,
}

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
#[derive(Debug, Clone)]
pub struct Outcome {
    /// Per frame, in project order.
    pub frames: Vec<Frame>,
    /// pingcal's estimate: weighted registration, residuals and leave-one-out.
    pub evaluation: registration::Evaluation,
    /// The published closed form on the same frames.
    pub closed_form: ClosedForm,
    /// The noise profile used.
    pub noise: RangeNoise,
}

fn resolve(dir: &Path, rel: &str) -> PathBuf {
    dir.join(rel)
}

/// Runs the calibration of one project (no output written).
pub fn calibrate(project: &Path, seed: u64) -> Result<Outcome, String> {
    let name = project.display().to_string();
    let text = std::fs::read_to_string(project).map_err(|e| format!("{name}: cannot read: {e}"))?;
    let file = SphereCalibFile::parse(&text, &name).map_err(|e| e.to_string())?;
    let dir = project.parent().unwrap_or(Path::new("."));
    let cam_path = resolve(dir, &file.camera);
    let cam_name = cam_path.display().to_string();
    let cam_text =
        std::fs::read_to_string(&cam_path).map_err(|e| format!("{cam_name}: cannot read: {e}"))?;
    let cam =
        Camera::from_file(&CameraFile::parse(&cam_text, &cam_name).map_err(|e| e.to_string())?);
    let noise = match (&file.lidar.noise, file.lidar.noise_sigma_mm) {
        (Some(n), _) => RangeNoise::named(n).map_err(|e| format!("{name}: [lidar] noise: {e}"))?,
        (None, Some([a, b])) => {
            RangeNoise::linear(a, b).map_err(|e| format!("{name}: [lidar] noise_sigma_mm: {e}"))?
        }
        (None, None) => {
            return Err(format!(
                "{name}: [lidar]: give the sensor's noise (a profile name, e.g. noise = \"VLP-16\") or noise_sigma_mm = [a, b]"
            ))
        }
    };
    let unit: CloudUnit = file
        .lidar
        .unit
        .parse()
        .map_err(|e| format!("{name}: [lidar] unit: {e}"))?;
    let radius = file.sphere_diameter_mm / 2.0;
    let ids = file.frame_ids();
    let mut frames = Vec::with_capacity(ids.len());
    for (fr, id) in file.frames.iter().zip(&ids) {
        let cloud_path = resolve(dir, &fr.cloud);
        let image_path = resolve(dir, &fr.image);
        let (cloud, warnings) = read_cloud_file_in(&cloud_path, &MountModel::default(), unit)
            .map_err(|e| e.to_string())?;
        let img = pingcal_targets::load_image(&image_path).map_err(|e| e.to_string())?;
        if (img.width, img.height) != (cam.model.width as usize, cam.model.height as usize) {
            return Err(format!(
                "{}: {} × {} pixels, but the camera {cam_name} is {} × {}",
                image_path.display(),
                img.width,
                img.height,
                cam.model.width,
                cam.model.height
            ));
        }
        let found = find_balls(
            &cloud,
            &FinderOptions {
                diameter_mm: file.sphere_diameter_mm,
                noise,
                seed,
                ..Default::default()
            },
        );
        let mut f = Frame {
            id: id.clone(),
            lidar: None,
            image: None,
            skipped: None,
            warnings,
        };
        match found.balls.as_slice() {
            [b] => f.lidar = Some((b.centre, b.cov, b.inliers.len(), b.sigma0)),
            [] => {
                f.skipped = Some(format!(
                    "{}: no sphere of {} mm found ({} candidates rejected{})",
                    cloud_path.display(),
                    file.sphere_diameter_mm,
                    found.rejected.len(),
                    found
                        .rejected
                        .first()
                        .map_or(String::new(), |r| format!(", e.g. {}", r.reason))
                ))
            }
            many => {
                f.skipped = Some(format!(
                    "{}: {} spheres of {} mm found, one expected: at {} mm",
                    cloud_path.display(),
                    many.len(),
                    file.sphere_diameter_mm,
                    many.iter()
                        .map(|b| format!(
                            "({:.0}, {:.0}, {:.0})",
                            b.centre.x, b.centre.y, b.centre.z
                        ))
                        .collect::<Vec<_>>()
                        .join(", ")
                ))
            }
        }
        match image_sphere(&img, &cam, radius) {
            Ok(s) => f.image = Some(s),
            Err(e) => {
                let msg = format!("{}: {e}", image_path.display());
                f.skipped = Some(match f.skipped.take() {
                    Some(prev) => format!("{prev}; {msg}"),
                    None => msg,
                });
            }
        }
        frames.push(f);
    }
    let used: Vec<&Frame> = frames.iter().filter(|f| f.skipped.is_none()).collect();
    if used.len() < 3 {
        return Err(format!(
            "{name}: {} of {} frames have the sphere in both the cloud and the image, at least 3 are needed: {}",
            used.len(),
            frames.len(),
            frames
                .iter()
                .filter_map(|f| f.skipped.as_ref().map(|s| format!("{}: {s}", f.id)))
                .collect::<Vec<_>>()
                .join("; ")
        ));
    }
    let lidar: Vec<PointObs> = used
        .iter()
        .map(|f| {
            let (c, cov, _, _) = f.lidar.expect("used frames have both");
            PointObs {
                id: f.id.clone(),
                xyz: c,
                cov,
            }
        })
        .collect();
    let camera: Vec<PointObs> = used
        .iter()
        .map(|f| {
            let s = f.image.as_ref().expect("used frames have both");
            PointObs {
                id: f.id.clone(),
                xyz: s.centre,
                cov: s.cov,
            }
        })
        .collect();
    let opt = RegistrationOptions::default();
    let evaluation = registration::evaluate(&lidar, &camera, &[], &[], &opt)
        .map_err(|e| format!("{name}: registration: {e}"))?;
    // the published method: its own camera centres, unit weights, SVD (Umeyama) closed form
    let unit_obs = |p: &[PointObs], pick: &dyn Fn(&Frame) -> V3| -> Vec<PointObs> {
        p.iter()
            .zip(&used)
            .map(|(o, f)| PointObs::new(o.id.clone(), pick(f), 1.0))
            .collect()
    };
    let cf_lidar = unit_obs(&lidar, &|f| f.lidar.expect("both").0);
    let cf_cam = unit_obs(&camera, &|f| f.image.as_ref().expect("both").closed_form);
    let svd = registration::umeyama(
        &cf_lidar.iter().map(|p| p.xyz).collect::<Vec<_>>(),
        &cf_cam.iter().map(|p| p.xyz).collect::<Vec<_>>(),
        None,
        false,
    )
    .map_err(|e| format!("{name}: closed form: {e}"))?;
    let cf_opt = RegistrationOptions {
        posterior: true,
        ..Default::default()
    };
    let mut cf_reg = registration::register(&cf_lidar, &cf_cam, &cf_opt)
        .map_err(|e| format!("{name}: closed form: {e}"))?;
    // unweighted least squares and the SVD are the same estimate: keep the SVD's numbers
    debug_assert!((cf_reg.camera_from_lrf.translation - svd.translation).norm() < 1e-6);
    cf_reg.camera_from_lrf = svd;
    let (cf_loo, _) = registration::leave_one_out(&cf_lidar, &cf_cam, &cf_opt);
    Ok(Outcome {
        frames,
        evaluation,
        closed_form: ClosedForm {
            registration: cf_reg,
            leave_one_out: cf_loo,
        },
        noise,
    })
}

/// The coordinates of `x`.
pub fn v(x: &V3) -> [f64; 3] {
    [x.x, x.y, x.z]
}

/// The standard deviations on the diagonal of covariance `c`.
pub fn sd(c: &Matrix3<f64>) -> [f64; 3] {
    [0, 1, 2].map(|k| c[(k, k)].max(0.0).sqrt())
}

/// `results.json` of a run.
pub fn results_json(o: &Outcome) -> serde_json::Value {
    let mut main = o.evaluation.to_json();
    let frames: Vec<serde_json::Value> = o
        .frames
        .iter()
        .map(|f| {
            let residual = o
                .evaluation
                .control
                .rows
                .iter()
                .find(|r| r.id == f.id);
            let loo = o
                .evaluation
                .leave_one_out
                .rows
                .iter()
                .find(|r| r.id == f.id);
            serde_json::json!({
                "id": f.id,
                "used": f.skipped.is_none(),
                "skipped": f.skipped,
                "warnings": f.warnings,
                "lidar": f.lidar.map(|(c, cov, n, s0)| serde_json::json!({
                    "centre_mm": v(&c), "sigma_mm": sd(&cov), "inliers": n, "sigma0": s0,
                })),
                "camera": f.image.as_ref().map(|s| serde_json::json!({
                    "centre_mm": v(&s.centre), "sigma_mm": sd(&s.cov),
                    "edge_points": s.edges, "edge_rms_px": s.rms_px, "edge_blur_sigma_px": s.sigma_blur_px, "edge_correlation_inflation": s.inflation,
                    "ellipse_px": {"cx": s.ellipse.cx, "cy": s.ellipse.cy, "a": s.ellipse.a, "b": s.ellipse.b, "theta_rad": s.ellipse.theta},
                    "closed_form_centre_mm": v(&s.closed_form),
                })),
                "residual": residual,
                "leave_one_out": loo,
            })
        })
        .collect();
    let cf = &o.closed_form.registration;
    let m = cf.camera_from_lrf.rotation;
    let obj = main.as_object_mut().expect("an object");
    obj.insert(
        "conventions".into(),
        serde_json::json!({
            "extrinsic": "camera_from_lidar: p_camera = R · p_lidar + t, mm",
            "camera_frame": "photogrammetric: X image right, Y optical axis (forward), Z image up",
            "lidar_frame": "the clouds' own frame",
            "angles": "opk_deg: ω φ κ with R = R_ω R_φ R_κ (passive elementary rotations)",
        }),
    );
    obj.insert("method".into(), "sphere-calib".into());
    obj.insert(
        "noise".into(),
        serde_json::to_value(o.noise).unwrap_or_default(),
    );
    obj.insert("frames".into(), serde_json::Value::Array(frames));
    obj.insert(
        "closed_form".into(),
        serde_json::json!({
            "method": "Tóth, Pusztai & Hajder 2020: centre from the ellipse's major axis in closed form, unweighted SVD registration",
            "rotation": [[m[(0,0)], m[(0,1)], m[(0,2)]], [m[(1,0)], m[(1,1)], m[(1,2)]], [m[(2,0)], m[(2,1)], m[(2,2)]]],
            "translation_mm": v(&cf.camera_from_lrf.translation),
            "opk_deg": cf.camera_from_lrf.opk_deg(),
            "sigma_translation_mm": v(&cf.sigma_translation_mm),
            "sigma_rotation_deg": v(&cf.sigma_opk_deg),
            "sigma_rotation_vector_deg": v(&cf.sigma_rotation_vector_deg),
            "rms_residual_mm": cf.sigma0,
            "leave_one_out": o.closed_form.leave_one_out.rows,
            "mean_leave_one_out_error_mm": o.closed_form.leave_one_out.mean_mm,
        }),
    );
    obj.insert(
        "sigma_rotation_vector_deg".into(),
        serde_json::json!(v(&o.evaluation.registration.sigma_rotation_vector_deg)),
    );
    main
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The camera of `pingcal simulate` (its distortion is strong: −15 % at the corner).
    fn camera() -> Camera {
        Camera {
            model: PhotogrammetricCamera::new(1280, 720, 0.00375),
            params: [
                2.45, 0.012, -0.009, -0.021, 4.0e-4, -2.0e-6, 1.5e-4, -1.0e-4, 1.0e-4, 0.0,
            ],
        }
    }

    /// The exact outline of a sphere: unit rays on its silhouette cone and their pixels.
    fn outline(cam: &Camera, c: &V3, r: f64, n: usize) -> (Vec<V3>, Vec<Pixel>) {
        let u = c.normalize();
        let e1 = u.cross(&V3::z()).normalize();
        let e2 = u.cross(&e1);
        let alpha = (r / c.norm()).asin();
        (0..n)
            .map(|i| {
                let phi = std::f64::consts::TAU * i as f64 / n as f64;
                let q = u * alpha.cos() + (e1 * phi.cos() + e2 * phi.sin()) * alpha.sin();
                let p = cam.model.project(&cam.params, &q, None, None).unwrap();
                (q, (p.x, p.y))
            })
            .unzip()
    }

    #[test]
    fn cone_fit_and_closed_form_recover_an_exact_outline_through_the_distortion() {
        let cam = camera();
        let r = 300.0;
        for c in [
            V3::new(0.0, 1500.0, 0.0),
            V3::new(-1400.0, 3000.0, 500.0),
            V3::new(2500.0, 8000.0, -900.0),
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

    #[test]
    fn correlated_residuals_inflate_the_variance() {
        // xorshift64: independent uniform values
        let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
        let white: Vec<f64> = (0..400)
            .map(|_| {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                (x >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            })
            .collect();
        assert!(correlation_inflation(&white) < 1.3);
        let smooth: Vec<f64> = (0..400)
            .map(|i| (i as f64 * 0.2).sin() + 0.1 * white[i])
            .collect();
        assert!(correlation_inflation(&smooth) > 5.0);
    }
}
