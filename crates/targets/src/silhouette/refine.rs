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
//! outline). The edge is the largest `g` within the search, located to a fraction of a
//! sample by the vertex of the parabola through `ln g` at the three samples about it (exact
//! for a Gaussian-blurred step), and the edge's blur `σ_b` from that parabola's curvature.
//! A place whose search leaves the image is not visible; one whose largest `g` is at the
//! search's end, or weaker than a quarter of the outline's median, has no edge.
//!
//! **Blur**: the derivative of a blurred disc peaks `σ_b²κ/2` inside its outline (κ its
//! curvature), as its half level does; every edge point is moved outward by that
//! ([`Fit::raw_edges`] keeps them unmoved), with σ_b the median over the outline.

use super::cone::{cone_rays, cone_residuals, correlation_inflation, fit_cone, robust_fit};
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
    /// [`Fit::inflation`].
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

/// The places of an outline and the image of the sphere's centre, px.
type Outline = (Vec<Option<Place>>, (f64, f64));

/// The outline of the sphere (`c`, `r`) at `k` places (`None` where a ray does not image).
fn places(cam: &dyn CameraRays, c: &V3, r: f64, k: usize) -> Option<Outline> {
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
    let (mut best, mut jb) = (0.0, 0usize);
    for (j, &v) in g.iter().enumerate().take(n - 1).skip(1) {
        let s = (j as i64 - m) as f64 * STEP;
        if s.abs() <= w && v > best {
            (best, jb) = (v, j);
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
type Found = (Vec<Option<Edge>>, f64);

/// An edge point: x, y (px), its strength g, the blur σ_b² and the outline's curvature κ.
type Edge = (f64, f64, f64, f64, f64);

fn find_edges(img: &ColourImage, pls: &[Option<Place>], w: f64) -> Found {
    let mut visible = 0usize;
    let mut out: Vec<Option<Edge>> = pls
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

/// The last round at full density: edge points at one place per pixel of outline (up to
/// 720), the blur correction, the robust fit, and the least squares on its inliers.
fn finish(img: &ColourImage, cam: &dyn CameraRays, r: f64, c: V3, w: f64) -> Option<Fit> {
    let centre_px = cam.ray_to_pixel([c.x, c.y, c.z])?;
    let px = pixel_angle(cam, (centre_px[0], centre_px[1]))?;
    let radius_px = (r / c.norm()).asin() / px;
    let k = ((std::f64::consts::TAU * radius_px).round() as usize).clamp(64, 720);
    let (pls, _) = places(cam, &c, r, k)?;
    let (found, visible) = find_edges(img, &pls, w);
    let mut vars: Vec<f64> = found.iter().flatten().map(|e| e.3).collect();
    if vars.len() < 12 {
        return None;
    }
    let mid = vars.len() / 2;
    let var_b = *vars.select_nth_unstable_by(mid, |a, b| a.total_cmp(b)).1;
    // (place index, corrected point, raw point)
    let mut pts = Vec::new();
    for (i, (e, pl)) in found.iter().zip(&pls).enumerate() {
        let (Some(e), Some(pl)) = (e, pl) else {
            continue;
        };
        let s = 0.5 * var_b * e.4;
        pts.push((i, (e.0 + s * pl.n.0, e.1 + s * pl.n.1), (e.0, e.1)));
    }
    let rays: Vec<V3> = pts
        .iter()
        .filter_map(|p| ray(cam, p.1 .0, p.1 .1))
        .collect();
    if rays.len() != pts.len() {
        return None;
    }
    let rob = robust_fit(&rays, c, r, 0.25 * px)?;
    let inl: Vec<V3> = rays
        .iter()
        .zip(&rob.inlier)
        .filter(|(_, &b)| b)
        .map(|(q, _)| *q)
        .collect();
    let (centre, cov, s) = fit_cone(&inl, rob.centre, r)?;
    let (res, _) = cone_residuals(&inl, &centre, r)?;
    let inflation = correlation_inflation(&res);
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
    let (mut edges, mut raw_edges, mut rejected) = (Vec::new(), Vec::new(), Vec::new());
    for (p, ok) in pts.iter().zip(&rob.inlier) {
        if *ok {
            edges.push(p.1);
            raw_edges.push(p.2);
        } else {
            rejected.push(p.2);
        }
    }
    Some(Fit {
        centre,
        cov: cov * inflation,
        image_centre: (image_centre[0], image_centre[1]),
        radius_px,
        outline,
        coverage: edges.len() as f64 / k as f64,
        edges,
        raw_edges,
        rejected,
        visible,
        rms_px: s / px,
        sigma_blur_px: var_b.sqrt(),
        inflation,
    })
}
