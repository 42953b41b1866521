//! Sphere fits to LRF points.
//!
//! * [`fit_along_ray`]: the fixed-radius fit that minimises the range error along each beam
//!   (Franaszek, Cheok & Witzgall, "directional" error). Range noise is along the ray, so this
//!   is the maximum-likelihood fit for an LRF; the orthogonal and algebraic fits are biased
//!   towards the sensor on a small ball (docs/method.md).
//! * [`fit_orthogonal`]: fixed-radius fit of the orthogonal distances `|p − c| − R`.
//! * [`fit_free_radius`]: orthogonal fit with the radius free (what a generic tool does).
//! * [`fit_algebraic`]: the linear (Kåsa) fit, used to start the others.
//!
//! All fits are weighted by the range σ of each beam and return the a-priori covariance of
//! the centre, `(Jᵀ W J)⁻¹` with `W = diag(1/σᵢ²)`, and the a-posteriori unit-weight σ₀.
//!
//! **Along-ray model.** For a ray from `o` with unit direction `d` and centre `c`:
//! `w = c − o`, `b = d·w`, `h² = |w|² − b²`, `s = √(R² − h²)`, predicted range `ρ̂ = b − s`
//! (first intersection). Its gradient is `∂ρ̂/∂c = n / (n·d)` with `n` the unit surface
//! normal at the intersection, which equals `d + (w − b d)/s`. Near the silhouette (`s → 0`)
//! the range is ill-conditioned and the beam footprint straddles ball and background (mixed
//! pixels), so rays are only used while the incidence angle stays under `max_incidence_deg`
//! and the ray passes at least one beam half-width inside the silhouette. Inside the
//! iterations a ray past that limit uses `ρ̂ = b − s_min` (continuous, gradient `d`), and
//! after convergence the gate and a `k·σ` residual test choose the rays again and the fit is
//! repeated until the set is stable.

use crate::error::{LrfError, Result};
use nalgebra::{DMatrix, DVector, Dyn, Matrix3, Vector3};
use pingcal_geometry::least_squares::{minimize, Normal, Options, Strategy};

/// One LRF beam: origin, unit direction and measured range (mm), with its range σ (mm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ray {
    /// Ray origin (the LRF centre for this beam), mm.
    pub origin: Vector3<f64>,
    /// Unit direction.
    pub dir: Vector3<f64>,
    /// Measured range, mm.
    pub range: f64,
    /// Standard deviation of the range, mm.
    pub sigma: f64,
}

impl Ray {
    /// The ray through point `p` seen from `origin`, with range σ `sigma`.
    pub fn from_point(origin: Vector3<f64>, p: Vector3<f64>, sigma: f64) -> Ray {
        let v = p - origin;
        let range = v.norm();
        let dir = if range > 0.0 { v / range } else { Vector3::x() };
        Ray {
            origin,
            dir,
            range,
            sigma,
        }
    }
    /// The measured point.
    pub fn point(&self) -> Vector3<f64> {
        self.origin + self.dir * self.range
    }
}

/// Which sphere fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum FitMethod {
    /// Fixed radius, error along each beam (the default).
    AlongRay,
    /// Fixed radius, orthogonal distance.
    Orthogonal,
    /// Free radius, orthogonal distance.
    FreeRadius,
}

/// Options of the fits.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FitOptions {
    /// Rays meeting the sphere at a larger incidence angle are not used (along-ray fit).
    pub max_incidence_deg: f64,
    /// Beam half-width at range r is `beam_width_a_mm + beam_width_b · r`; rays passing
    /// closer than that to the silhouette may be mixed pixels and are not used (along-ray fit).
    pub beam_width_a_mm: f64,
    /// See `beam_width_a_mm`.
    pub beam_width_b: f64,
    /// Residuals beyond `outlier_k · σ` are rejected (all fits).
    pub outlier_k: f64,
    /// Maximum Levenberg–Marquardt iterations per pass.
    pub max_iter: usize,
    /// Remove the second-order (Box 1971) bias of the along-ray estimate.
    pub bias_correction: bool,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            max_incidence_deg: 70.0,
            beam_width_a_mm: 1.0,
            beam_width_b: 0.002,
            outlier_k: 3.0,
            max_iter: 50,
            bias_correction: true,
        }
    }
}

impl FitOptions {
    /// Half-width of the beam's footprint at range `r` (mm): `beam_width_a_mm +
    /// beam_width_b · r`.
    pub fn beam_half_width(&self, r: f64) -> f64 {
        self.beam_width_a_mm + self.beam_width_b * r
    }
}

/// A fitted sphere.
#[derive(Debug, Clone, PartialEq)]
pub struct SphereFit {
    /// Centre, mm.
    pub centre: Vector3<f64>,
    /// Radius, mm (the fixed one, or the estimate for [`FitMethod::FreeRadius`]).
    pub radius: f64,
    /// A-priori covariance of the centre from the range σ's, mm².
    pub cov: Matrix3<f64>,
    /// Standard deviation of the radius (free-radius fit only), mm.
    pub sigma_radius: Option<f64>,
    /// A-posteriori σ of unit weight (≈ 1 when the range σ's are right).
    pub sigma0: f64,
    /// RMS residual of the used rays, mm.
    pub rms_mm: f64,
    /// Indices (into the input) of the rays used.
    pub used: Vec<usize>,
    /// Which fit.
    pub method: FitMethod,
}

impl SphereFit {
    /// Covariance scaled by σ₀² (when the range σ's are not trusted).
    pub fn cov_posterior(&self) -> Matrix3<f64> {
        self.cov * (self.sigma0 * self.sigma0)
    }
}

/// Along-ray predicted range and its gradient w.r.t. the centre, with `s_min` the half-chord at
/// the incidence gate: past it the half-chord is continued along its tangent (C¹), so a ray
/// that misses the sphere still pulls the centre towards itself. Returns `(ρ̂, ∂ρ̂/∂c, s)`; `s` is the half-chord before clamping
/// (negative `s²` clamped to 0).
pub fn along_ray_model(
    ray: &Ray,
    c: &Vector3<f64>,
    radius: f64,
    s_min: f64,
) -> (f64, Vector3<f64>, f64) {
    let w = c - ray.origin;
    let b = ray.dir.dot(&w);
    let pw = w - ray.dir * b;
    let h2 = pw.norm_squared();
    let s = (radius * radius - h2).max(0.0).sqrt();
    let s_min = s_min.max(1e-3 * radius);
    if s >= s_min {
        (b - s, ray.dir + pw / s, s)
    } else {
        // tangent continuation past the gate: s_ext = s_min − (h_g/s_min)(h − h_g), so a ray that
        // misses the sphere still pulls the centre towards itself (C¹ at the gate)
        let h = h2.sqrt().max(1e-12);
        let hg = (radius * radius - s_min * s_min).max(0.0).sqrt();
        let k = hg / s_min;
        (b - (s_min - k * (h - hg)), ray.dir + pw * (k / h), s)
    }
}

/// Hessian `∂²ρ̂/∂c²` of the along-ray range inside the gate:
/// `H = P/s + (P w)(P w)ᵀ/s³` with `P = I − d dᵀ` (zero past the continuation limit).
pub fn along_ray_hessian(ray: &Ray, c: &Vector3<f64>, radius: f64, s_min: f64) -> Matrix3<f64> {
    let w = c - ray.origin;
    let p = Matrix3::identity() - ray.dir * ray.dir.transpose();
    let pw = p * w;
    let h2 = pw.norm_squared();
    let s = (radius * radius - h2).max(0.0).sqrt();
    if s >= s_min.max(1e-3 * radius) {
        p / s + pw * pw.transpose() / (s * s * s)
    } else {
        Matrix3::zeros()
    }
}

/// The weighted residuals `r` and their Jacobian `J` at some parameters.
type Linearized = (DVector<f64>, DMatrix<f64>);

/// Solves min Σ r² by Levenberg–Marquardt (`pingcal_geometry::least_squares`, at most
/// `max_iter` iterations, until a step is under 1e-10 of `1 + |x|` or the cost falls by less
/// than 1e-14 of `1 + cost`); `f(params) -> (r, J)` with `r` already weighted. Returns the
/// parameters and the normal equations `JᵀJ`, `Jᵀr`, `rᵀr` at them.
fn lm(
    x: DVector<f64>,
    max_iter: usize,
    f: &dyn Fn(&DVector<f64>) -> Linearized,
) -> Result<(DVector<f64>, Normal<Dyn>)> {
    let options = Options {
        strategy: Strategy::LevenbergMarquardt,
        max_iterations: max_iter,
        small_step: |s| s.length < 1e-10 * (1.0 + s.from),
        cost_tolerance: 1e-14,
    };
    let mut normal = |x: &DVector<f64>| {
        let (r, j) = f(x);
        Some(Normal::from_jacobian(&r, &j))
    };
    minimize(x, &options, &mut normal)
        .map(|s| (s.x, s.normal))
        .ok_or_else(|| LrfError::Degenerate("sphere fit diverged".into()))
}

/// The linear (Kåsa) fit: `|p|² = 2 c·p + k`. Returns (centre, radius).
pub fn fit_algebraic(points: &[Vector3<f64>]) -> Result<(Vector3<f64>, f64)> {
    if points.len() < 4 {
        return Err(LrfError::TooFewPoints {
            needed: 4,
            got: points.len(),
            ids: String::new(),
        });
    }
    let m = points.iter().sum::<Vector3<f64>>() / points.len() as f64;
    let mut a = nalgebra::Matrix4::<f64>::zeros();
    let mut rhs = nalgebra::Vector4::<f64>::zeros();
    for p in points {
        let q = p - m;
        let row = nalgebra::Vector4::new(2.0 * q.x, 2.0 * q.y, 2.0 * q.z, 1.0);
        a += row * row.transpose();
        rhs += row * q.norm_squared();
    }
    let sol = a.try_inverse().map(|ai| ai * rhs).ok_or_else(|| {
        LrfError::Degenerate("algebraic sphere fit: points are coplanar or coincident".into())
    })?;
    let c = Vector3::new(sol[0], sol[1], sol[2]);
    let r2 = sol[3] + c.norm_squared();
    if !(r2 > 0.0) || !r2.is_finite() {
        return Err(LrfError::Degenerate(
            "algebraic sphere fit: no real sphere".into(),
        ));
    }
    Ok((c + m, r2.sqrt()))
}

/// A starting centre for a fixed-radius fit: the centroid of the points pushed back along
/// the mean ray by 2R/3 (the mean depth of a uniformly sampled visible cap).
pub fn initial_centre(rays: &[Ray], radius: f64) -> Vector3<f64> {
    let n = rays.len().max(1) as f64;
    let m = rays.iter().map(|r| r.point()).sum::<Vector3<f64>>() / n;
    let d = rays.iter().map(|r| r.dir).sum::<Vector3<f64>>();
    let d = if d.norm() > 0.0 {
        d.normalize()
    } else {
        Vector3::x()
    };
    m + d * (2.0 * radius / 3.0)
}

/// What a fit estimated, before [`finish`] adds the residual statistics.
struct Estimate {
    centre: Vector3<f64>,
    radius: f64,
    sigma_radius: Option<f64>,
    cov: Matrix3<f64>,
    method: FitMethod,
    /// Indices (into the input) of the rays used…
    used: Vec<usize>,
    /// …and their residuals, mm.
    residuals: Vec<f64>,
}

/// The fit's statistics (χ², RMS, σ₀ with `n_par` unknowns); fails on a non-finite estimate.
fn finish(rays: &[Ray], est: Estimate, n_par: usize) -> Result<SphereFit> {
    let Estimate {
        centre: c,
        radius,
        sigma_radius,
        cov,
        method,
        used,
        residuals: res,
    } = est;
    let n = used.len();
    let chi2: f64 = used
        .iter()
        .zip(&res)
        .map(|(&i, r)| (r / rays[i].sigma).powi(2))
        .sum();
    let rms = (res.iter().map(|r| r * r).sum::<f64>() / n.max(1) as f64).sqrt();
    let sigma0 = if n > n_par {
        (chi2 / (n - n_par) as f64).sqrt()
    } else {
        f64::NAN
    };
    if !c.iter().all(|v| v.is_finite()) || !cov.iter().all(|v| v.is_finite()) {
        return Err(LrfError::Degenerate(
            "sphere fit gave a non-finite result".into(),
        ));
    }
    Ok(SphereFit {
        centre: c,
        radius,
        cov,
        sigma_radius,
        sigma0: if sigma0.is_finite() { sigma0 } else { 0.0 },
        rms_mm: rms,
        used,
        method,
    })
}

fn normal_matrix_inverse(rows: &[(Vector3<f64>, f64)]) -> Result<Matrix3<f64>> {
    let mut n = Matrix3::zeros();
    for (j, s) in rows {
        n += j * j.transpose() / (s * s);
    }
    n.try_inverse()
        .filter(|m| m.iter().all(|v| v.is_finite()))
        .ok_or_else(|| {
            LrfError::Degenerate(
                "sphere fit: the rays do not determine the centre (singular normal matrix)".into(),
            )
        })
}

/// Fixed-radius fit minimising the range error along each beam. `init`: starting centre
/// (e.g. from RANSAC), or `None` for [`initial_centre`].
pub fn fit_along_ray(
    rays: &[Ray],
    radius: f64,
    init: Option<Vector3<f64>>,
    opt: &FitOptions,
) -> Result<SphereFit> {
    if rays.len() < 3 {
        return Err(LrfError::TooFewPoints {
            needed: 3,
            got: rays.len(),
            ids: String::new(),
        });
    }
    // start from the orthogonal fit (robust to the mixed pixels through its kσ rejection)
    let c0 = init.unwrap_or_else(|| {
        fit_orthogonal(rays, radius, None, opt)
            .map(|f| f.centre)
            .unwrap_or_else(|_| initial_centre(rays, radius))
    });
    // The gate follows the estimate; on a few noisy rays that can collapse (each pass drops
    // the rays on one side). Then the gate is fixed at the starting centre instead.
    let fixed = along_ray_passes(rays, radius, c0, opt, true);
    match along_ray_passes(rays, radius, c0, opt, false) {
        Ok(f) if 2 * f.used.len() >= fixed.as_ref().map_or(0, |g| g.used.len()) => Ok(f),
        adaptive => fixed.or(adaptive),
    }
}

/// True when `ray` meets the sphere of centre `c` (it passes the centre at most `radius`
/// away, in front of its origin) and its range is within `k·σ` of the first intersection
/// (the true one, no continuation): the invariant of every ray a fit calls an inlier. The
/// incidence and footprint gate of [`fit_along_ray`] is a choice of the fit on top of it.
pub fn ray_on_sphere(ray: &Ray, c: &Vector3<f64>, radius: f64, k: f64) -> bool {
    let w = c - ray.origin;
    let b = ray.dir.dot(&w);
    let h2 = (w.norm_squared() - b * b).max(0.0);
    if b <= 0.0 || h2 > radius * radius {
        return false;
    }
    let s = (radius * radius - h2).sqrt();
    (ray.range - (b - s)).abs() <= k * ray.sigma
}

/// The rays of `used` that [`ray_on_sphere`] accepts at centre `c` (with `outlier_k`).
fn on_sphere(
    rays: &[Ray],
    used: &[usize],
    c: &Vector3<f64>,
    radius: f64,
    opt: &FitOptions,
) -> Vec<usize> {
    used.iter()
        .copied()
        .filter(|&i| ray_on_sphere(&rays[i], c, radius, opt.outlier_k))
        .collect()
}

/// One Levenberg–Marquardt solve of the along-ray fit on `sub`, from `c`.
fn refine_along_ray(
    sub: &[Ray],
    radius: f64,
    s_min: f64,
    c: Vector3<f64>,
    opt: &FitOptions,
) -> Result<Vector3<f64>> {
    let f = |x: &DVector<f64>| {
        let cc = Vector3::new(x[0], x[1], x[2]);
        let mut r = DVector::zeros(sub.len());
        let mut j = DMatrix::zeros(sub.len(), 3);
        for (k, ray) in sub.iter().enumerate() {
            let (rho, g, _) = along_ray_model(ray, &cc, radius, s_min);
            r[k] = (ray.range - rho) / ray.sigma;
            for q in 0..3 {
                j[(k, q)] = -g[q] / ray.sigma;
            }
        }
        (r, j)
    };
    let (x, _) = lm(DVector::from_column_slice(c.as_slice()), opt.max_iter, &f)?;
    Ok(Vector3::new(x[0], x[1], x[2]))
}

fn along_ray_passes(
    rays: &[Ray],
    radius: f64,
    c0: Vector3<f64>,
    opt: &FitOptions,
    fixed_gate: bool,
) -> Result<SphereFit> {
    let s_min = radius * opt.max_incidence_deg.to_radians().cos();
    let mut c = c0;
    // the rays a centre accepts: inside the incidence and footprint gate, residual under kσ
    let select = |c: &Vector3<f64>, k: f64| -> Vec<usize> {
        (0..rays.len())
            .filter(|&i| {
                let ray = &rays[i];
                let (rho, _, _) = along_ray_model(ray, c, radius, s_min);
                let g = if fixed_gate { &c0 } else { c };
                let (_, _, s) = along_ray_model(ray, g, radius, s_min);
                let w = ray.origin - g;
                let h = (w.norm_squared() - ray.dir.dot(&w).powi(2)).max(0.0).sqrt();
                let half_width = opt.beam_half_width(ray.range);
                s >= s_min && h <= radius - half_width && (ray.range - rho).abs() <= k * ray.sigma
            })
            .collect()
    };
    // the residual test tightens over the first passes (3k, 2k, then kσ) so that a poor
    // start does not throw away the good rays
    let k_of_pass = |pass: usize| opt.outlier_k * (3usize.saturating_sub(pass)).max(1) as f64;
    let mut used = select(&c, k_of_pass(0));
    if used.len() < 3 {
        used = (0..rays.len()).collect();
    }
    for pass in 0..10 {
        if used.len() < 3 {
            return Err(LrfError::TooFewPoints {
                needed: 3,
                got: used.len(),
                ids: "rays left after mixed-pixel and outlier rejection".into(),
            });
        }
        let sub: Vec<Ray> = used.iter().map(|&i| rays[i]).collect();
        c = refine_along_ray(&sub, radius, s_min, c, opt)?;
        let new_used = select(&c, k_of_pass(pass + 1));
        if new_used == used && pass >= 2 {
            break;
        }
        used = new_used;
    }
    // The invariant of the result: every used ray meets the sphere at the *final* centre,
    // inside the gate, within kσ. A gate held at the starting centre (or the tangent
    // continuation, which gives a finite residual to a ray that misses the sphere) would
    // otherwise let the centre walk off and keep rays that pass farther than R from it.
    if fixed_gate {
        for _ in 0..5 {
            let kept = on_sphere(rays, &used, &c, radius, opt);
            if kept.len() < 3 {
                used = kept;
                break;
            }
            let settled = kept == used;
            used = kept;
            if settled {
                break;
            }
            let sub: Vec<Ray> = used.iter().map(|&i| rays[i]).collect();
            c = refine_along_ray(&sub, radius, s_min, c, opt)?;
        }
        used = on_sphere(rays, &used, &c, radius, opt);
    }
    if used.len() < 3 {
        return Err(LrfError::TooFewPoints {
            needed: 3,
            got: used.len(),
            ids: "rays left after mixed-pixel and outlier rejection".into(),
        });
    }
    let mut rows = Vec::with_capacity(used.len());
    let mut res = Vec::with_capacity(used.len());
    for &i in &used {
        let (rho, g, _) = along_ray_model(&rays[i], &c, radius, s_min);
        rows.push((g, rays[i].sigma));
        res.push(rays[i].range - rho);
    }
    let cov = normal_matrix_inverse(&rows)?;
    if opt.bias_correction {
        // second-order bias of a nonlinear least-squares estimate (Box 1971):
        // E[ĉ − c] ≈ −½ N⁻¹ Σ wᵢ Jᵢ tr(Hᵢ N⁻¹), N = Σ wᵢ Jᵢ Jᵢᵀ. The half-chord s is concave in the
        // lateral position, so lateral noise pulls the centre towards the sensor; remove it.
        let mut acc = Vector3::zeros();
        for (&i, (g, sg)) in used.iter().zip(&rows) {
            let h = along_ray_hessian(&rays[i], &c, radius, s_min);
            acc += g * ((h * cov).trace() / (sg * sg));
        }
        let bias = -0.5 * cov * acc;
        if bias.iter().all(|v| v.is_finite()) && bias.norm() < radius {
            c -= bias;
            for (k, &i) in used.iter().enumerate() {
                res[k] = rays[i].range - along_ray_model(&rays[i], &c, radius, s_min).0;
            }
        }
    }
    let est = Estimate {
        centre: c,
        radius,
        sigma_radius: None,
        cov,
        method: FitMethod::AlongRay,
        used,
        residuals: res,
    };
    finish(rays, est, 3)
}

/// Along-ray range and its gradient w.r.t. (centre, radius) when the radius is free too;
/// the incidence gate follows the radius (`s_min = R cos θ_max`), so past it the tangent
/// continuation's derivative is `∂ρ̂/∂R = −1/cos θ_max` (and `−R/s` inside it).
pub fn along_ray_model_free(
    ray: &Ray,
    c: &Vector3<f64>,
    radius: f64,
    max_incidence_deg: f64,
) -> (f64, nalgebra::Vector4<f64>) {
    let cos_max = max_incidence_deg.to_radians().cos();
    let s_min = radius * cos_max;
    let (rho, g, s) = along_ray_model(ray, c, radius, s_min);
    let dr = if s >= s_min.max(1e-3 * radius) {
        -radius / s
    } else {
        -1.0 / cos_max
    };
    (rho, nalgebra::Vector4::new(g.x, g.y, g.z, dr))
}

/// Free-radius along-ray fit of rays already known to be on the sphere (e.g. a fixed-radius
/// fit's inliers), from `(c, radius)`; no rays are re-selected. Returns the radius and its
/// a-priori σ, and σ₀. The orthogonal free-radius fit is biased low when the range σ is a
/// good fraction of the radius (a 19 mm ball under a URG-04LX's 10 mm: 14–16 mm); along the
/// beams the model is the sensor's, and the radius comes out unbiased to a fraction of σ.
pub fn free_radius_along_ray(
    rays: &[Ray],
    c: Vector3<f64>,
    radius: f64,
    opt: &FitOptions,
) -> Result<(f64, f64, f64)> {
    if rays.len() < 5 {
        return Err(LrfError::TooFewPoints {
            needed: 5,
            got: rays.len(),
            ids: String::new(),
        });
    }
    let f = |x: &DVector<f64>| {
        let cc = Vector3::new(x[0], x[1], x[2]);
        let mut r = DVector::zeros(rays.len());
        let mut j = DMatrix::zeros(rays.len(), 4);
        for (k, ray) in rays.iter().enumerate() {
            let (rho, g) = along_ray_model_free(ray, &cc, x[3], opt.max_incidence_deg);
            r[k] = (ray.range - rho) / ray.sigma;
            for q in 0..4 {
                j[(k, q)] = -g[q] / ray.sigma;
            }
        }
        (r, j)
    };
    let (x, at) = lm(
        DVector::from_column_slice(&[c.x, c.y, c.z, radius]),
        opt.max_iter,
        &f,
    )?;
    let inv = at
        .matrix
        .try_inverse()
        .filter(|m| m.iter().all(|v| v.is_finite()) && m[(3, 3)] >= 0.0)
        .ok_or_else(|| {
            LrfError::Degenerate("free-radius fit: the rays do not determine the radius".into())
        })?;
    let sigma0 = (at.cost / (rays.len() - 4) as f64).sqrt();
    if !(x[3] > 0.0 && x[3].is_finite()) {
        return Err(LrfError::Degenerate(
            "free-radius fit: no positive radius".into(),
        ));
    }
    Ok((x[3], inv[(3, 3)].sqrt(), sigma0))
}

/// Orthogonal fits (fixed or free radius) with `k·σ` outlier rejection.
fn fit_orth(
    rays: &[Ray],
    radius: Option<f64>,
    init: Option<(Vector3<f64>, f64)>,
    opt: &FitOptions,
) -> Result<SphereFit> {
    let n_par = if radius.is_some() { 3 } else { 4 };
    if rays.len() < n_par + 1 {
        return Err(LrfError::TooFewPoints {
            needed: n_par + 1,
            got: rays.len(),
            ids: String::new(),
        });
    }
    let pts: Vec<Vector3<f64>> = rays.iter().map(|r| r.point()).collect();
    let (c, rad) = orth_start(rays, &pts, radius, init);
    let (c, rad, used) = orth_passes(rays, &pts, radius, (c, rad), opt)?;
    if used.len() < n_par {
        return Err(LrfError::TooFewPoints {
            needed: n_par,
            got: used.len(),
            ids: "points left after outlier rejection".into(),
        });
    }
    let est = orth_estimate(rays, &pts, (c, rad), used, n_par)?;
    finish(rays, est, n_par)
}

/// The start of an orthogonal fit: `init`, else the centre from the rays for a fixed
/// radius, else the algebraic fit (or a 19 mm ball's centre when it fails).
fn orth_start(
    rays: &[Ray],
    pts: &[Vector3<f64>],
    radius: Option<f64>,
    init: Option<(Vector3<f64>, f64)>,
) -> (Vector3<f64>, f64) {
    let (c, mut rad) = match init {
        Some(i) => i,
        None => match radius {
            Some(r) => (initial_centre(rays, r), r),
            None => fit_algebraic(pts).unwrap_or_else(|_| {
                let r0 = 19.0;
                (initial_centre(rays, r0), r0)
            }),
        },
    };
    if let Some(r) = radius {
        rad = r;
    }
    (c, rad)
}

/// Up to 8 passes of the fit on the points within `k·σ` of the last pass's sphere, until
/// they no longer change: the centre, the radius and the points used.
fn orth_passes(
    rays: &[Ray],
    pts: &[Vector3<f64>],
    radius: Option<f64>,
    (mut c, mut rad): (Vector3<f64>, f64),
    opt: &FitOptions,
) -> Result<(Vector3<f64>, f64, Vec<usize>)> {
    let n_par = if radius.is_some() { 3 } else { 4 };
    let mut used: Vec<usize> = (0..rays.len()).collect();
    for _pass in 0..8 {
        if used.len() < n_par {
            return Err(LrfError::TooFewPoints {
                needed: n_par,
                got: used.len(),
                ids: "points left after outlier rejection".into(),
            });
        }
        let f = |x: &DVector<f64>| {
            let cc = Vector3::new(x[0], x[1], x[2]);
            let rr = radius.unwrap_or_else(|| x[3]);
            let mut r = DVector::zeros(used.len());
            let mut j = DMatrix::zeros(used.len(), n_par);
            for (k, &i) in used.iter().enumerate() {
                let v = cc - pts[i];
                let d = v.norm().max(1e-12);
                let s = rays[i].sigma;
                r[k] = (d - rr) / s;
                for q in 0..3 {
                    j[(k, q)] = v[q] / d / s;
                }
                if n_par == 4 {
                    j[(k, 3)] = -1.0 / s;
                }
            }
            (r, j)
        };
        let mut x0 = vec![c.x, c.y, c.z];
        if n_par == 4 {
            x0.push(rad);
        }
        let (x, _) = lm(DVector::from_vec(x0), opt.max_iter, &f)?;
        c = Vector3::new(x[0], x[1], x[2]);
        if n_par == 4 {
            rad = x[3].abs();
        }
        let new_used: Vec<usize> = (0..rays.len())
            .filter(|&i| ((pts[i] - c).norm() - rad).abs() <= opt.outlier_k * rays[i].sigma)
            .collect();
        if new_used == used {
            break;
        }
        used = new_used;
    }
    Ok((c, rad, used))
}

/// The estimate from the points `used`: the centre's covariance (and the radius's σ for a
/// free radius) from the normal matrix, the residuals.
fn orth_estimate(
    rays: &[Ray],
    pts: &[Vector3<f64>],
    (c, rad): (Vector3<f64>, f64),
    used: Vec<usize>,
    n_par: usize,
) -> Result<Estimate> {
    let mut n = DMatrix::<f64>::zeros(n_par, n_par);
    let mut res = Vec::with_capacity(used.len());
    for &i in &used {
        let v = c - pts[i];
        let d = v.norm().max(1e-12);
        let mut g = DVector::zeros(n_par);
        for q in 0..3 {
            g[q] = v[q] / d;
        }
        if n_par == 4 {
            g[3] = -1.0;
        }
        n += &g * g.transpose() / rays[i].sigma.powi(2);
        res.push(d - rad);
    }
    let inv = n
        .try_inverse()
        .filter(|m| m.iter().all(|v| v.is_finite()))
        .ok_or_else(|| {
            LrfError::Degenerate(
                "sphere fit: the points do not determine the sphere (singular normal matrix)"
                    .into(),
            )
        })?;
    let cov = inv.fixed_view::<3, 3>(0, 0).into_owned();
    let sr = if n_par == 4 {
        Some(inv[(3, 3)].max(0.0).sqrt())
    } else {
        None
    };
    let method = if n_par == 4 {
        FitMethod::FreeRadius
    } else {
        FitMethod::Orthogonal
    };
    let est = Estimate {
        centre: c,
        radius: rad,
        sigma_radius: sr,
        cov,
        method,
        used,
        residuals: res,
    };
    Ok(est)
}

/// Fixed-radius orthogonal-distance fit.
pub fn fit_orthogonal(
    rays: &[Ray],
    radius: f64,
    init: Option<Vector3<f64>>,
    opt: &FitOptions,
) -> Result<SphereFit> {
    fit_orth(rays, Some(radius), init.map(|c| (c, radius)), opt)
}

/// Free-radius orthogonal-distance fit (`init`: centre and radius).
pub fn fit_free_radius(
    rays: &[Ray],
    init: Option<(Vector3<f64>, f64)>,
    opt: &FitOptions,
) -> Result<SphereFit> {
    fit_orth(rays, None, init, opt)
}

/// Runs the chosen fit.
pub fn fit(
    method: FitMethod,
    rays: &[Ray],
    radius: f64,
    init: Option<Vector3<f64>>,
    opt: &FitOptions,
) -> Result<SphereFit> {
    match method {
        FitMethod::AlongRay => fit_along_ray(rays, radius, init, opt),
        FitMethod::Orthogonal => fit_orthogonal(rays, radius, init, opt),
        FitMethod::FreeRadius => fit_free_radius(rays, init.map(|c| (c, radius)), opt),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn free_radius_gradient_matches_central_differences() {
        let ray = Ray {
            origin: Vector3::new(3.0, -2.0, 1.0),
            dir: Vector3::new(0.9, 0.1, 0.2).normalize(),
            range: 1000.0,
            sigma: 10.0,
        };
        let perp = ray.dir.cross(&Vector3::z()).normalize();
        // inside the 70° gate and past it (tangent continuation)
        for off in [0.0, 6.0, 12.0, 17.0, 18.5, 21.0] {
            let c = ray.origin + ray.dir * 1000.0 + perp * off + Vector3::new(0.3, -0.2, 0.1);
            let x0 = nalgebra::Vector4::new(c.x, c.y, c.z, 19.0);
            let (_, g) = along_ray_model_free(&ray, &c, 19.0, 70.0);
            for k in 0..4 {
                let h = 1e-6;
                let mut xp = x0;
                let mut xm = x0;
                xp[k] += h;
                xm[k] -= h;
                let at = |x: nalgebra::Vector4<f64>| {
                    along_ray_model_free(&ray, &Vector3::new(x[0], x[1], x[2]), x[3], 70.0).0
                };
                let fd = (at(xp) - at(xm)) / (2.0 * h);
                assert!(
                    (fd - g[k]).abs() < 1e-5 * (1.0 + g[k].abs()),
                    "offset {off}, parameter {k}: analytic {} vs central difference {fd}",
                    g[k]
                );
            }
        }
    }

    #[test]
    fn along_ray_gradient_matches_finite_differences() {
        let ray = Ray {
            origin: Vector3::new(3.0, -2.0, 1.0),
            dir: Vector3::new(0.9, 0.1, 0.2).normalize(),
            range: 1000.0,
            sigma: 10.0,
        };
        let radius = 19.0;
        // centres giving incidence angles from 0° to ~65°, and one past the gate
        for off in [0.0, 5.0, 10.0, 15.0, 17.0, 18.5] {
            let perp = ray.dir.cross(&Vector3::z()).normalize();
            let c = ray.origin + ray.dir * 1000.0 + perp * off + Vector3::new(0.3, -0.2, 0.1);
            let s_min = radius * 70f64.to_radians().cos();
            let (_, g, _) = along_ray_model(&ray, &c, radius, s_min);
            for k in 0..3 {
                let mut e = Vector3::zeros();
                e[k] = 1e-6;
                let fd = (along_ray_model(&ray, &(c + e), radius, s_min).0
                    - along_ray_model(&ray, &(c - e), radius, s_min).0)
                    / 2e-6;
                assert!(
                    (fd - g[k]).abs() < 1e-5 * (1.0 + g[k].abs()),
                    "off {off} k {k}: fd {fd} vs {}",
                    g[k]
                );
            }
            // the gradient is also n/(n·d) when the ray hits inside the gate
            let (rho, _, s) = along_ray_model(&ray, &c, radius, s_min);
            if s >= s_min {
                let n = (ray.origin + ray.dir * rho - c) / radius;
                assert!((n / n.dot(&ray.dir) - g).norm() < 1e-8);
            }
        }
    }

    #[test]
    fn along_ray_hessian_matches_finite_differences() {
        let ray = Ray {
            origin: Vector3::new(1.0, 2.0, -1.0),
            dir: Vector3::new(0.2, 0.9, 0.1).normalize(),
            range: 1.0,
            sigma: 1.0,
        };
        let s_min = 19.0 * 70f64.to_radians().cos();
        for off in [0.0, 6.0, 12.0, 16.0] {
            let perp = ray.dir.cross(&Vector3::x()).normalize();
            let c = ray.origin + ray.dir * 900.0 + perp * off + Vector3::new(0.5, 0.0, 0.3);
            let h = along_ray_hessian(&ray, &c, 19.0, s_min);
            for k in 0..3 {
                let mut e = Vector3::zeros();
                e[k] = 1e-5;
                let fd = (along_ray_model(&ray, &(c + e), 19.0, s_min).1
                    - along_ray_model(&ray, &(c - e), 19.0, s_min).1)
                    / 2e-5;
                for q in 0..3 {
                    assert!(
                        (fd[q] - h[(q, k)]).abs() < 1e-5 * (1.0 + h[(q, k)].abs()),
                        "off {off}: {fd} vs {h}"
                    );
                }
            }
        }
    }

    #[test]
    fn orthogonal_gradients_match_finite_differences() {
        // the orthogonal residual |c − p| − R has gradient (c − p)/|c − p|: check it inside a fit
        // by comparing the converged covariance with a finite-difference normal matrix
        let c0 = Vector3::new(10.0, 1000.0, -20.0);
        let rays: Vec<Ray> = (0..40)
            .map(|i| {
                let (t, phi) = (i as f64 * 0.7, 0.2 + 0.03 * i as f64);
                let n = Vector3::new(t.cos() * phi.sin(), -phi.cos(), t.sin() * phi.sin());
                Ray::from_point(Vector3::zeros(), c0 + n * 19.0, 2.0)
            })
            .collect();
        let f = fit_free_radius(&rays, None, &FitOptions::default()).unwrap();
        assert!((f.centre - c0).norm() < 1e-6 && (f.radius - 19.0).abs() < 1e-6);
        let mut nfd = nalgebra::Matrix4::<f64>::zeros();
        for r in &rays {
            let p = r.point();
            let res =
                |x: nalgebra::Vector4<f64>| (Vector3::new(x[0], x[1], x[2]) - p).norm() - x[3];
            let x0 = nalgebra::Vector4::new(f.centre.x, f.centre.y, f.centre.z, f.radius);
            let mut g = nalgebra::Vector4::zeros();
            for k in 0..4 {
                let mut e = nalgebra::Vector4::zeros();
                e[k] = 1e-6;
                g[k] = (res(x0 + e) - res(x0 - e)) / 2e-6;
            }
            nfd += g * g.transpose() / (r.sigma * r.sigma);
        }
        let cov_fd = nfd
            .try_inverse()
            .unwrap()
            .fixed_view::<3, 3>(0, 0)
            .into_owned();
        assert!(
            (cov_fd - f.cov).norm() < 1e-5 * f.cov.norm(),
            "{cov_fd} vs {}",
            f.cov
        );
    }

    #[test]
    fn exact_data_recovered_by_every_fit() {
        let c0 = Vector3::new(-30.0, 800.0, 40.0);
        let mut rays = Vec::new();
        for i in -8..=8 {
            for j in -8..=8 {
                let dir = (c0 + Vector3::new(i as f64 * 2.0, 0.0, j as f64 * 2.0)).normalize();
                let ray = Ray {
                    origin: Vector3::zeros(),
                    dir,
                    range: 1.0,
                    sigma: 5.0,
                };
                let (rho, _, s) = along_ray_model(&ray, &c0, 19.0, 0.0);
                if s > 0.0 {
                    rays.push(Ray { range: rho, ..ray });
                }
            }
        }
        // no bias correction: it removes the bias expected *with* noise, exact data has none
        let o = FitOptions {
            beam_width_a_mm: 0.0,
            beam_width_b: 0.0,
            max_incidence_deg: 89.0,
            bias_correction: false,
            ..Default::default()
        };
        for m in [
            FitMethod::AlongRay,
            FitMethod::Orthogonal,
            FitMethod::FreeRadius,
        ] {
            let f = fit(m, &rays, 19.0, None, &o).unwrap();
            assert!((f.centre - c0).norm() < 1e-6, "{m:?}: {}", f.centre);
            assert!(f.rms_mm < 1e-6);
        }
        let (c, r) = fit_algebraic(&rays.iter().map(|r| r.point()).collect::<Vec<_>>()).unwrap();
        assert!((c - c0).norm() < 1e-6 && (r - 19.0).abs() < 1e-6);
    }

    #[test]
    fn too_few_rays_is_an_error_not_a_panic() {
        let r = Ray::from_point(Vector3::zeros(), Vector3::new(0.0, 1000.0, 0.0), 10.0);
        assert!(matches!(
            fit_along_ray(&[r, r], 19.0, None, &FitOptions::default()),
            Err(LrfError::TooFewPoints { .. })
        ));
        // identical rays: singular, must not return NaN
        let e = fit_along_ray(&[r; 5], 19.0, None, &FitOptions::default());
        assert!(e.is_err() || e.unwrap().centre.iter().all(|v| v.is_finite()));
    }
}
