//! The silhouette of a sphere of known radius fitted to the edges of the image: from a start
//! (a centre in the camera frame), its outline projected through the camera, the strongest
//! colour edge looked for along the outline's normal at every place, and the centre fitted
//! to those edge points' rays robustly ([`super::cone::robust_fit`]); repeated with the search
//! narrowed to what the residuals allow.
//!
//! **Along a normal**: the profile of every channel sampled every ½ px across the outline
//! (each sample the mean of three, ±1 px along the outline, weights ¼ ½ ¼); its derivative
//! by central differences 1 px apart; the colour derivative `g(s) = √Σ_c (∂I_c/∂s)²`,
//! sign-free (a ball brighter than the bricks above and darker than the floor below has one
//! outline). The edge is the local maximum of `g` within the search that is largest once
//! weighed by `exp(−s²/2(0.6 w)²)` (s its distance from the outline, w the search's
//! half-width: a near edge is preferred to a far one of about the same strength), located to a fraction of a
//! sample by the vertex of the parabola through `ln g` at the three samples about it (exact
//! for a Gaussian-blurred step), and the edge's blur `σ_b` from that parabola's curvature.
//! A place whose search leaves the image is not visible; one whose largest `g` is at the
//! search's end, or weaker than a quarter of the outline's median, has no edge.
//!
//! **Blur**: the derivative of a blurred disc peaks `σ_b²κ/2` inside its outline (κ its
//! curvature), as its half level does; every edge point is moved outward by that
//! ([`Fit::raw_edges`] keeps them unmoved), with σ_b the median over the outline.

use super::cone::{
    cone_rays, cone_residuals, correlation_inflation, fit_cone_weighted, robust_fit,
};
use super::edges::ColourImage;
use crate::ball::CameraRays;
use nalgebra::{Matrix3, Vector3};

type V3 = Vector3<f64>;

/// A silhouette fitted to the image.
#[derive(Clone, Debug)]
pub struct Fit {
    /// The sphere's centre in the camera frame of the [`CameraRays`], in the radius' unit.
    pub centre: V3,
    /// Its covariance: the fit's `s² (JᵀJ)⁻¹` over the inliers, times
    /// [`Fit::inflation`], plus that of an error common to all edge points
    /// ([`EDGE_BIAS_PX`]).
    pub cov: Matrix3<f64>,
    /// The image of the centre's direction, px.
    pub image_centre: (f64, f64),
    /// The outline's mean distance from `image_centre`, px.
    pub radius_px: f64,
    /// The fitted outline at evenly spaced places (for drawing), px.
    pub outline: Vec<(f64, f64)>,
    /// The edge points used (inliers, blur-corrected), px.
    pub edges: Vec<(f64, f64)>,
    /// The same, not corrected for the blur (the plain edge).
    pub raw_edges: Vec<(f64, f64)>,
    /// Edge points found but not used (outliers: a stand, a hand, a highlight), px.
    pub rejected: Vec<(f64, f64)>,
    /// The fraction of the whole outline that inlier edge points cover.
    pub coverage: f64,
    /// The fraction of the outline inside the image (where the search fits in it).
    pub visible: f64,
    /// RMS of the inliers' residuals, px.
    pub rms_px: f64,
    /// The edge's blur σ_b, px.
    pub sigma_blur_px: f64,
    /// The variance inflation of the residuals' correlation along the outline.
    pub inflation: f64,
}

/// One place of the outline: the projected point, its outward unit normal, the outline's
/// curvature there (1/px).
#[derive(Clone, Copy, Debug)]
struct Place {
    p: (f64, f64),
    n: (f64, f64),
    kappa: f64,
}

/// The outline of the sphere (`c`, `r`) at `k` places (`None` where a ray does not image).
fn places(
    cam: &dyn CameraRays,
    c: &V3,
    r: f64,
    k: usize,
) -> Option<(Vec<Option<Place>>, (f64, f64))> {
    let rays = cone_rays(c, r, k)?;
    let centre = cam.ray_to_pixel([c.x, c.y, c.z])?;
    let pts: Vec<Option<(f64, f64)>> = rays
        .iter()
        .map(|q| cam.ray_to_pixel([q.x, q.y, q.z]).map(|p| (p[0], p[1])))
        .collect();
    let out = (0..k)
        .map(|i| {
            let p = pts[i]?;
            let a = pts[(i + k - 1) % k]?;
            let b = pts[(i + 1) % k]?;
            let (tx, ty) = (b.0 - a.0, b.1 - a.1);
            let tn = (tx * tx + ty * ty).sqrt();
            if !(tn > 0.0) {
                return None;
            }
            let (mut nx, mut ny) = (ty / tn, -tx / tn);
            if nx * (p.0 - centre[0]) + ny * (p.1 - centre[1]) < 0.0 {
                (nx, ny) = (-nx, -ny);
            }
            // curvature of the circle through a, p, b
            let (ux, uy, vx, vy) = (a.0 - p.0, a.1 - p.1, b.0 - p.0, b.1 - p.1);
            let cross = (ux * vy - uy * vx).abs();
            let la = (ux * ux + uy * uy).sqrt();
            let lb = (vx * vx + vy * vy).sqrt();
            let kappa = 2.0 * cross / (la * lb * tn).max(1e-12);
            Some(Place {
                p,
                n: (nx, ny),
                kappa,
            })
        })
        .collect();
    Some((out, (centre[0], centre[1])))
}

/// The sample spacing along a normal, px.
const STEP: f64 = 0.5;

/// The edge along the normal of `pl` within `±w` px: (offset, g, σ_b²), or `Err(true)` when
/// the search leaves the image, `Err(false)` when there is no edge.
fn search(img: &ColourImage, pl: &Place, w: f64) -> Result<(f64, f64, f64), bool> {
    let (px, py) = pl.p;
    let (nx, ny) = pl.n;
    let (tx, ty) = (-ny, nx);
    let m = (w / STEP).ceil() as i64 + 1;
    let (wd, ht) = (img.width() as f64, img.height() as f64);
    let ends = [
        (px - (m as f64 * STEP) * nx, py - (m as f64 * STEP) * ny),
        (px + (m as f64 * STEP) * nx, py + (m as f64 * STEP) * ny),
    ];
    for (x, y) in ends {
        if !(x >= 1.5 && y >= 1.5 && x <= wd - 2.5 && y <= ht - 2.5) {
            return Err(true);
        }
    }
    let n = (2 * m + 1) as usize;
    let mut g = vec![0.0f64; n];
    let mut prof = vec![0.0f64; n];
    for plane in &img.planes {
        for (j, v) in prof.iter_mut().enumerate() {
            let s = (j as i64 - m) as f64 * STEP;
            let (x, y) = (px + s * nx, py + s * ny);
            let a = plane.sample_inside(x - tx, y - ty) as f64;
            let b = plane.sample_inside(x, y) as f64;
            let c = plane.sample_inside(x + tx, y + ty) as f64;
            *v = 0.25 * a + 0.5 * b + 0.25 * c;
        }
        for j in 1..n - 1 {
            let d = (prof[j + 1] - prof[j - 1]) / (2.0 * STEP);
            g[j] += d * d;
        }
    }
    for v in &mut g {
        *v = v.sqrt();
    }
    // the local maximum of g that is strongest once weighed by a Gaussian prior on its
    // distance from the outline (σ = 0.6 w): near edges are preferred to far ones a little
    let (mut best, mut jb, mut score) = (0.0, 0usize, 0.0);
    let sp = 0.6 * w;
    for j in 1..n - 1 {
        let s = (j as i64 - m) as f64 * STEP;
        let v = g[j];
        if s.abs() <= w && v >= g[j - 1] && v >= g[j + 1] {
            let sc = v * (-0.5 * (s / sp).powi(2)).exp();
            if sc > score {
                (best, jb, score) = (v, j, sc);
            }
        }
    }
    if jb <= 1 || jb >= n - 2 || !(best > 0.0) {
        return Err(false);
    }
    let s = (jb as i64 - m) as f64 * STEP;
    if s.abs() > w - STEP {
        return Err(false);
    }
    let (a, b, c) = (
        g[jb - 1].max(1e-9).ln(),
        best.ln(),
        g[jb + 1].max(1e-9).ln(),
    );
    let den = a - 2.0 * b + c;
    if !(den < 0.0) {
        return Err(false);
    }
    let delta = (0.5 * (a - c) / den).clamp(-0.5, 0.5);
    // the derivative over 1 px adds the variance of a 1-px box, 1/12
    let var = (-STEP * STEP / den - 1.0 / 12.0).max(0.0);
    Ok((s + delta * STEP, best, var))
}

/// Edge points of one round: per place, `Some((x, y, g, σ_b², κ))`, and the fraction of
/// places visible.
type Found = (Vec<Option<(f64, f64, f64, f64, f64)>>, f64);

fn find_edges(img: &ColourImage, pls: &[Option<Place>], w: f64) -> Found {
    let mut visible = 0usize;
    let mut out: Vec<Option<(f64, f64, f64, f64, f64)>> = pls
        .iter()
        .map(|pl| {
            let pl = pl.as_ref()?;
            match search(img, pl, w) {
                Ok((s, g, var)) => {
                    visible += 1;
                    Some((pl.p.0 + s * pl.n.0, pl.p.1 + s * pl.n.1, g, var, pl.kappa))
                }
                Err(inside) => {
                    visible += usize::from(!inside);
                    None
                }
            }
        })
        .collect();
    // an edge weaker than a quarter of the outline's median is none
    let mut gs: Vec<f64> = out.iter().flatten().map(|e| e.2).collect();
    if !gs.is_empty() {
        let mid = gs.len() / 2;
        let med = *gs.select_nth_unstable_by(mid, |a, b| a.total_cmp(b)).1;
        for e in out.iter_mut() {
            if e.is_some_and(|e| e.2 < 0.25 * med) {
                *e = None;
            }
        }
    }
    (out, visible as f64 / pls.len().max(1) as f64)
}

/// The angle one pixel subtends at image point `p` (radians).
fn pixel_angle(cam: &dyn CameraRays, p: (f64, f64)) -> Option<f64> {
    let a = V3::from(cam.pixel_to_ray(p.0, p.1)?).normalize();
    let b = V3::from(cam.pixel_to_ray(p.0 + 1.0, p.1)?).normalize();
    Some(a.angle(&b)).filter(|v| *v > 0.0)
}

fn ray(cam: &dyn CameraRays, x: f64, y: f64) -> Option<V3> {
    cam.pixel_to_ray(x, y).map(|r| V3::from(r).normalize())
}

/// Fits the silhouette of a sphere of radius `r` starting from centre `c0` (camera frame),
/// searching first `w0` px either side of the outline. `None` when fewer than 12 edge points
/// are found or the fit fails.
pub fn refine(img: &ColourImage, cam: &dyn CameraRays, r: f64, c0: V3, w0: f64) -> Option<Fit> {
    let mut c = c0;
    let mut w = w0.max(2.0);
    let mut last = None;
    for round in 0..8 {
        let centre_px = cam.ray_to_pixel([c.x, c.y, c.z])?;
        let px = pixel_angle(cam, (centre_px[0], centre_px[1]))?;
        let radius_px = (r / c.norm()).asin() / px;
        let perimeter = std::f64::consts::TAU * radius_px;
        let k = ((perimeter / 3.0).round() as usize).clamp(48, 240);
        let (pls, _) = places(cam, &c, r, k)?;
        let (found, _) = find_edges(img, &pls, w);
        let pts: Vec<(f64, f64)> = found.iter().flatten().map(|e| (e.0, e.1)).collect();
        let rays: Vec<V3> = pts.iter().filter_map(|&(x, y)| ray(cam, x, y)).collect();
        if rays.len() < 12 {
            return None;
        }
        let fit = robust_fit(&rays, c, r, 0.25 * px)?;
        let moved = cam
            .ray_to_pixel([fit.centre.x, fit.centre.y, fit.centre.z])
            .map_or(f64::INFINITY, |p| {
                (p[0] - centre_px[0]).hypot(p[1] - centre_px[1])
            });
        let grew = ((r / fit.centre.norm()).asin() / px - radius_px).abs();
        c = fit.centre;
        let next = (4.0 * fit.sigma / px + 1.5).clamp(2.0, w);
        let settled = moved < 0.05 && grew < 0.05 && next >= w * 0.9;
        w = next;
        last = Some(w);
        if settled && round >= 1 {
            break;
        }
    }
    finish(img, cam, r, c, last?)
}

/// The σ of an error common to every edge point of an outline, px: what the shading of a
/// real sphere does to where its edge is found (the derivative of a blurred step is pushed
/// towards the side whose brightness changes faster; on the simulator's shaded sphere the
/// outline's mean radius errs by about 0.03 px, `bash bench/spherecalib/run.sh cluttered`).
/// Such an error, constant or varying slowly along the outline (the shading differs from
/// the lit side to the dark one), moves the centre as offsets of the residuals do
/// ([`bias_covariance`]): little for a whole outline, much in the direction a part of one
/// leaves open.
pub const EDGE_BIAS_PX: f64 = 0.03;

/// The covariance of the centre from unknown offsets of the residuals (rows `jac`, weights
/// `w`, at angles `phi` around the outline) that vary slowly along the outline: three
/// modes, 1, cos φ and sin φ, each of σ `sigma` (radians): `σ² Σ_m N⁻¹JᵀWm mᵀWJ N⁻¹` with
/// `N⁻¹ = ni`, the weighted normal matrix's inverse. For a whole outline the first moves
/// the centre along the line of sight and the others across it; for a part of one all
/// three reach into the direction the arc leaves open.
fn bias_covariance(
    jac: &[V3],
    w: &[f64],
    phi: &[f64],
    ni: &Matrix3<f64>,
    sigma: f64,
) -> Matrix3<f64> {
    let mut g = [V3::zeros(); 3];
    for ((j, p), wi) in jac.iter().zip(phi).zip(w) {
        let (s, c) = p.sin_cos();
        g[0] += j * *wi;
        g[1] += j * (wi * c);
        g[2] += j * (wi * s);
    }
    let mut cov = Matrix3::zeros();
    for gm in g {
        let d = ni * gm;
        cov += d * d.transpose();
    }
    cov * (sigma * sigma)
}

/// One edge point of the last round: its place around the outline, the blur-corrected and
/// the plain point (px), and its strength `g`.
struct EdgePoint {
    place: usize,
    point: (f64, f64),
    raw: (f64, f64),
    g: f64,
}

/// The last round's edge points at `k` places of the outline of (`c`, `r`), each moved
/// outward by `σ_b²κ/2` (σ_b the median over the outline), with σ_b and the fraction of the
/// outline visible.
fn final_edges(
    img: &ColourImage,
    cam: &dyn CameraRays,
    r: f64,
    c: &V3,
    w: f64,
    k: usize,
) -> Option<(Vec<EdgePoint>, f64, f64)> {
    let (pls, _) = places(cam, c, r, k)?;
    let (found, visible) = find_edges(img, &pls, w);
    let mut vars: Vec<f64> = found.iter().flatten().map(|e| e.3).collect();
    if vars.len() < 12 {
        return None;
    }
    let mid = vars.len() / 2;
    let var_b = *vars.select_nth_unstable_by(mid, |a, b| a.total_cmp(b)).1;
    let pts = found
        .iter()
        .zip(&pls)
        .enumerate()
        .filter_map(|(i, (e, pl))| {
            let (e, pl) = (e.as_ref()?, pl.as_ref()?);
            let s = 0.5 * var_b * e.4;
            Some(EdgePoint {
                place: i,
                point: (e.0 + s * pl.n.0, e.1 + s * pl.n.1),
                raw: (e.0, e.1),
                g: e.2,
            })
        })
        .collect();
    Some((pts, var_b.sqrt(), visible))
}

/// The last round at full density: edge points at one place per pixel of outline (up to
/// 720), the blur correction, the robust fit, and the least squares on its inliers, each
/// weighted by its strength squared (the σ of an edge's place, from the image's noise or
/// from shading beside it, goes as one over its contrast).
fn finish(img: &ColourImage, cam: &dyn CameraRays, r: f64, c: V3, w: f64) -> Option<Fit> {
    let centre_px = cam.ray_to_pixel([c.x, c.y, c.z])?;
    let px = pixel_angle(cam, (centre_px[0], centre_px[1]))?;
    let radius_px = (r / c.norm()).asin() / px;
    let k = ((std::f64::consts::TAU * radius_px).round() as usize).clamp(64, 720);
    let (pts, sigma_blur_px, visible) = final_edges(img, cam, r, &c, w, k)?;
    let rays: Vec<V3> = pts
        .iter()
        .filter_map(|p| ray(cam, p.point.0, p.point.1))
        .collect();
    if rays.len() != pts.len() {
        return None;
    }
    let rob = robust_fit(&rays, c, r, 0.25 * px)?;
    let used: Vec<(&EdgePoint, &V3)> = pts
        .iter()
        .zip(&rays)
        .zip(&rob.inlier)
        .filter(|(_, &b)| b)
        .map(|(p, _)| p)
        .collect();
    let inl: Vec<V3> = used.iter().map(|(_, q)| **q).collect();
    let wts: Vec<f64> = used.iter().map(|(p, _)| p.g * p.g).collect();
    let (centre, cov, s, ni) = fit_cone_weighted(&inl, &wts, rob.centre, r)?;
    let (res, jac) = cone_residuals(&inl, &centre, r)?;
    let inflation = correlation_inflation(&res);
    let mean_w = wts.iter().sum::<f64>() / wts.len() as f64;
    let wn: Vec<f64> = wts.iter().map(|x| x / mean_w).collect();
    let phi: Vec<f64> = used
        .iter()
        .map(|(p, _)| std::f64::consts::TAU * p.place as f64 / k as f64)
        .collect();
    let cov = cov * inflation + bias_covariance(&jac, &wn, &phi, &ni, EDGE_BIAS_PX * px);
    let image_centre = cam.ray_to_pixel([centre.x, centre.y, centre.z])?;
    let outline: Vec<(f64, f64)> = cone_rays(&centre, r, 180)?
        .iter()
        .filter_map(|q| cam.ray_to_pixel([q.x, q.y, q.z]).map(|p| (p[0], p[1])))
        .collect();
    let radius_px = outline
        .iter()
        .map(|p| (p.0 - image_centre[0]).hypot(p.1 - image_centre[1]))
        .sum::<f64>()
        / outline.len().max(1) as f64;
    let mut rejected = Vec::new();
    for (p, ok) in pts.iter().zip(&rob.inlier) {
        if !ok {
            rejected.push(p.raw);
        }
    }
    Some(Fit {
        centre,
        cov,
        image_centre: (image_centre[0], image_centre[1]),
        radius_px,
        outline,
        coverage: used.len() as f64 / k as f64,
        edges: used.iter().map(|(p, _)| p.point).collect(),
        raw_edges: used.iter().map(|(p, _)| p.raw).collect(),
        rejected,
        visible,
        rms_px: s / px,
        sigma_blur_px,
        inflation,
    })
}
