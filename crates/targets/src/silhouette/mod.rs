//! Silhouettes of a sphere of known radius in real photographs: found from edges, not from
//! brightness, and fitted to the visible part of the outline.
//!
//! A real ball is a shaded sphere with a specular highlight, a darker lower half and a stand
//! under it, among bricks, tiles and chairs, perhaps cut by the image's border. So:
//!
//! 1. **Edge points** from the colour gradient ([`edges`]), at a scale where the outlines
//!    looked for are 8–40 px in radius (box-averaged 1, 4, 16 … times).
//! 2. **Candidate circles** by a Hough transform of the centre along each edge point's
//!    gradient axis, the radius at each peak by the edge points around it ([`hough`]).
//! 3. **The silhouette fit** of each candidate ([`refine`]): the outline of a sphere of the
//!    known radius projected through the camera's own model ([`CameraRays`], distortion
//!    exact), colour edges along its normal at each place (the strongest; in a second search
//!    the nearest of the three strongest, for a dark side weaker than the background behind
//!    it), the centre fitted to those edge points' rays with a robust weight ([`cone`]), the
//!    search narrowed round by round. Edge points of a highlight, a stand or a hand are rejected by the fit; places
//!    outside the image are not searched. The fit says how much of the outline it used
//!    ([`Fit::coverage`]) and how much was in the image ([`Fit::visible`]); its covariance
//!    comes from the edge points used, so an outline half hidden gives a larger one.
//! 4. **Acceptance**: a fit covering at least [`SilhouetteOptions::min_coverage`] of the
//!    outline with an RMS of at most [`SilhouetteOptions::max_rms_px`]; two fits of one
//!    sphere are merged. More than one may remain: choosing among them is the caller's
//!    (the lidar knows where the ball is; `pingcal_pipeline::sphere_calib`).
//!
//! [`find_silhouettes`] does all four on an image; [`refine::refine`] fits from a given
//! start (the ball predicted by another sensor). Work is bounded by the image's pixels and
//! the number of candidates, never by what the image shows.

pub mod cone;
pub mod edges;
pub mod hough;
pub mod refine;

pub use edges::ColourImage;
pub use hough::Circle;
pub use refine::Fit;

use crate::ball::{sphere_centre_from_outline, CameraRays};
use nalgebra::Vector3;

/// What [`find_silhouettes`] looks for.
#[derive(Clone, Debug, PartialEq)]
pub struct SilhouetteOptions {
    /// The sphere's radius (the unit of the centres returned).
    pub radius: f64,
    /// The radii of the outlines looked for, px.
    pub radius_px: (f64, f64),
    /// Centres within this window only: (x, y, reach), px.
    pub window: Option<(f64, f64, f64)>,
    /// Candidate circles fitted, at most.
    pub max_candidates: usize,
    /// The least fraction of the outline an accepted fit covers with edge points.
    pub min_coverage: f64,
    /// The largest RMS of an accepted fit's edge residuals: this many px, plus
    /// [`RMS_PER_RADIUS`] of the outline's radius (a real ball is not quite a sphere).
    pub max_rms_px: f64,
}

impl SilhouetteOptions {
    /// Defaults for a sphere of radius `radius` in a `width × height` image: outlines of 8 px
    /// to half the image's shorter side, anywhere.
    pub fn new(radius: f64, width: usize, height: usize) -> Self {
        SilhouetteOptions {
            radius,
            radius_px: (8.0, 0.5 * width.min(height) as f64),
            window: None,
            max_candidates: 10,
            min_coverage: 0.3,
            max_rms_px: 1.0,
        }
    }
}

/// The scales searched for outline radii in `range` px, each with its band of radii
/// (8–40 px at that scale, clipped to the range).
pub fn scales(range: (f64, f64)) -> Vec<(usize, (f64, f64))> {
    let mut out = Vec::new();
    for s in [1usize, 4, 16, 64] {
        let (lo, hi) = ((8 * s) as f64, (40 * s) as f64);
        let (a, b) = (lo.max(range.0), hi.min(range.1));
        if a <= b {
            out.push((s, (a, b)));
        }
    }
    out
}

/// The candidate circles of `img` for `opts`, each with the scale it was located at, by
/// decreasing support. A circle found at scale `s > 1` is located again at scale `s/4`
/// within `3 s` px of it (its centre and radius to a few px, not `s`).
pub fn candidates(img: &ColourImage, opts: &SilhouetteOptions) -> Vec<(Circle, usize)> {
    let bands = scales(opts.radius_px);
    let mut maps: Vec<edges::EdgeMap> = Vec::new();
    let mut all: Vec<(Circle, usize)> = Vec::new();
    for (s, band) in bands {
        let search = hough::Search {
            radius_px: band,
            window: opts.window,
        };
        let i = map_at(&mut maps, img, s);
        let coarse = hough::circles(&maps[i], &search, 6);
        for c in coarse {
            if s == 1 {
                all.push((c, 1));
                continue;
            }
            let f = s / 4;
            let j = map_at(&mut maps, img, f);
            let sf = s as f64;
            let fine = hough::Search {
                radius_px: ((c.r - 3.0 * sf).max(8.0 * f as f64), c.r + 3.0 * sf),
                window: Some((c.cx, c.cy, 3.0 * sf)),
            };
            match hough::circles(&maps[j], &fine, 1).first() {
                Some(k) => all.push((
                    Circle {
                        support: c.support,
                        ..*k
                    },
                    f,
                )),
                None => all.push((c, s)),
            }
        }
    }
    all.sort_by(|a, b| b.0.support.total_cmp(&a.0.support));
    let mut kept: Vec<(Circle, usize)> = Vec::new();
    for (c, s) in all {
        let dup = kept.iter().any(|(k, _)| {
            (k.cx - c.cx).hypot(k.cy - c.cy) < 0.3 * k.r.min(c.r) && (k.r - c.r).abs() < 0.2 * k.r
        });
        if !dup {
            kept.push((c, s));
        }
    }
    kept
}

/// The index in `maps` of the edge map of `img` at scale `s`, made if missing.
fn map_at(maps: &mut Vec<edges::EdgeMap>, img: &ColourImage, s: usize) -> usize {
    match maps.iter().position(|m| m.scale == s) {
        Some(i) => i,
        None => {
            maps.push(edges::edge_map(img, s));
            maps.len() - 1
        }
    }
}

/// The centre (camera frame) of a sphere of radius `r` whose outline is about `c`.
pub fn centre_of_circle(c: &Circle, cam: &dyn CameraRays, r: f64) -> Option<Vector3<f64>> {
    let pts: Vec<(f64, f64)> = (0..36)
        .map(|k| {
            let t = std::f64::consts::TAU * k as f64 / 36.0;
            (c.cx + c.r * t.cos(), c.cy + c.r * t.sin())
        })
        .collect();
    let s = sphere_centre_from_outline(&pts, cam, Some(r))?;
    Some(Vector3::from(s.axis) * s.distance?)
}

/// The silhouettes of spheres of radius `opts.radius` in `img` (see the module doc), by
/// decreasing coverage.
pub fn find_silhouettes(
    img: &ColourImage,
    cam: &dyn CameraRays,
    opts: &SilhouetteOptions,
) -> Vec<Fit> {
    let mut fits: Vec<Fit> = Vec::new();
    for (c, s) in candidates(img, opts).into_iter().take(opts.max_candidates) {
        let Some(c0) = centre_of_circle(&c, cam, opts.radius) else {
            continue;
        };
        let w0 = start_width(&c, s);
        let Some(f) = refine::refine(img, cam, opts.radius, c0, w0) else {
            continue;
        };
        if accepted(&f, opts) {
            fits.push(f);
        }
    }
    fits.sort_by(|a, b| b.coverage.total_cmp(&a.coverage));
    let mut kept: Vec<Fit> = Vec::new();
    for f in fits {
        let same = kept.iter().any(|k| {
            let d =
                (k.image_centre.0 - f.image_centre.0).hypot(k.image_centre.1 - f.image_centre.1);
            d < 0.3 * k.radius_px && (k.radius_px - f.radius_px).abs() < 0.2 * k.radius_px
        });
        if !same {
            kept.push(f);
        }
    }
    kept
}

/// The first search's half-width for a circle located at scale `s`, px.
pub fn start_width(c: &Circle, s: usize) -> f64 {
    2.0 * s as f64 + 0.02 * c.r + 2.0
}

/// The part of the largest accepted RMS that grows with the outline's radius.
pub const RMS_PER_RADIUS: f64 = 0.01;

/// Whether a fit passes [`SilhouetteOptions`]' tests.
pub fn accepted(f: &Fit, opts: &SilhouetteOptions) -> bool {
    f.coverage >= opts.min_coverage
        && f.rms_px <= opts.max_rms_px + RMS_PER_RADIUS * f.radius_px
        && f.radius_px >= 0.7 * opts.radius_px.0
        && f.radius_px <= 1.3 * opts.radius_px.1
}

/// A sphere's centre fitted to the rays of its silhouette's edge points.
#[derive(Clone, Debug)]
pub struct ConeCentre {
    /// The centre, in the camera frame of the [`CameraRays`], in the radius' unit.
    pub centre: Vector3<f64>,
    /// Its covariance: `s²(JᵀJ)⁻¹` of the cone fit to the inlying rays, inflated by the
    /// correlation of neighbouring residuals ([`cone::correlation_inflation`]).
    pub cov: nalgebra::Matrix3<f64>,
    /// RMS of the inliers' residuals (radians).
    pub rms_rad: f64,
    /// Edge points used.
    pub inliers: usize,
}

/// The centre of a sphere of radius `radius` from the sub-pixel edge points of its
/// silhouette (in order around the outline): each point's ray through the camera's own
/// pixel → ray map, then the silhouette cone fitted to the rays directly ([`cone`]:
/// robustly from the linear cone of [`sphere_centre_from_outline`], then by least squares
/// on the inliers), so the fit is exact whatever shape the lens gives the silhouette (an
/// ellipse only through a distortion-free lens). `floor_rad`: the smallest residual scale
/// worth telling apart (e.g. a quarter pixel's angle). `None` with fewer than 12 usable
/// points or when a fit fails.
pub fn sphere_centre_from_edges(
    points: &[(f64, f64)],
    cam: &dyn CameraRays,
    radius: f64,
    floor_rad: f64,
) -> Option<ConeCentre> {
    if points.len() < 12 {
        return None;
    }
    let start = sphere_centre_from_outline(points, cam, Some(radius))?;
    let c0 = Vector3::from(start.axis) * start.distance?;
    let rays: Vec<Vector3<f64>> = points
        .iter()
        .map(|&(x, y)| cam.pixel_to_ray(x, y).map(|r| Vector3::from(r).normalize()))
        .collect::<Option<_>>()?;
    let robust = cone::robust_fit(&rays, c0, radius, floor_rad)?;
    let inl: Vec<Vector3<f64>> = rays
        .iter()
        .zip(&robust.inlier)
        .filter(|(_, &ok)| ok)
        .map(|(q, _)| *q)
        .collect();
    if inl.len() < 12 {
        return None;
    }
    let (centre, cov, rms_rad) = cone::fit_cone(&inl, robust.centre, radius)?;
    let (res, _) = cone::cone_residuals(&inl, &centre, radius)?;
    Some(ConeCentre {
        centre,
        cov: cov * cone::correlation_inflation(&res),
        rms_rad,
        inliers: inl.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ball::{sphere_centre_from_ellipse, FnCamera};
    use crate::ellipse::fit_ellipse;
    use nalgebra::{Matrix2x3, Vector2};
    use pingcal_ba::camera::{CameraModel, FisheyeCamera};
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    /// The 190° lens of `pingcal simulate --camera-model kannala-brandt`.
    const KB: [f64; 8] = [374.0, 374.2, 641.2, 358.9, 0.02, -0.005, 0.001, -1.0e-4];

    fn rays() -> impl CameraRays {
        FnCamera(
            |x: f64, y: f64| {
                FisheyeCamera
                    .unproject(&KB, &Vector2::new(x, y))
                    .map(|r| [r.x, r.y, r.z])
            },
            |r: [f64; 3]| {
                FisheyeCamera
                    .project(&KB, &Vector3::from(r), None, None)
                    .map(|p| [p.x, p.y])
            },
        )
    }

    /// The exact silhouette of a 66 mm ball `dist` mm away, `off_deg` off the axis, through
    /// the fisheye: 200 points of its cone projected.
    fn silhouette(off_deg: f64, dist: f64) -> (Vector3<f64>, Vec<(f64, f64)>) {
        let a = off_deg.to_radians();
        let c = Vector3::new(a.sin(), a.cos(), 0.3 * a.sin()).normalize() * dist;
        let pts = cone::cone_rays(&c, 33.0, 200)
            .unwrap()
            .iter()
            .map(|q| {
                let p = FisheyeCamera.project(&KB, q, None, None).unwrap();
                (p.x, p.y)
            })
            .collect();
        (c, pts)
    }

    /// On the exact silhouette through a fisheye the edge points' cone gives the centre's
    /// image exactly; so, to a fraction of a thousandth of a pixel, does the cone through
    /// the fitted ellipse.
    #[test]
    fn edges_give_the_centre_through_a_fisheye() {
        let cam = rays();
        for (off, dist) in [
            (0.0, 450.0),
            (40.0, 450.0),
            (70.0, 450.0),
            (85.0, 450.0),
            (70.0, 120.0),
            (85.0, 120.0),
        ] {
            let (c, pts) = silhouette(off, dist);
            let truth = FisheyeCamera.project(&KB, &c, None, None).unwrap();
            let fit = sphere_centre_from_edges(&pts, &cam, 33.0, 0.25 / 374.0).unwrap();
            let p = FisheyeCamera.project(&KB, &fit.centre, None, None).unwrap();
            assert!(
                (p - truth).norm() < 1e-6,
                "{off}°: {:.2e} px",
                (p - truth).norm()
            );
            assert!((fit.centre - c).norm() < 1e-6 * c.norm(), "{off}°");
            let e = fit_ellipse(&pts).unwrap();
            let s = sphere_centre_from_ellipse(&e, &cam, Some(33.0)).unwrap();
            let err = (Vector2::new(s.x, s.y) - truth).norm();
            // measured: at most 2e-4 px (a 133 px outline 85° off the axis): the outline is
            // no ellipse, but it is symmetric about its radial line and the fitted ellipse
            // keeps the cone's axis; what the edges add is the robust fit in ray space and
            // the covariance, not a smaller bias
            assert!(
                err < 1e-3,
                "{off}° at {dist} mm: the ellipse's cone off by {err:.2e} px"
            );
        }
    }

    /// With Gaussian noise on the edge points (σ 0.1 px) the centre's covariance carried
    /// through the projection is honest: the RMS of the per-axis errors over their σ's over
    /// 200 trials is 1 (its standard error 1/√800 ≈ 0.035; bounds ±5 of them, and the
    /// inflation for correlated residuals may add a little on white noise).
    #[test]
    fn the_edge_fit_covariance_is_honest() {
        let cam = rays();
        let mut g = rand::rngs::StdRng::seed_from_u64(35);
        let noise = Normal::new(0.0, 0.1).unwrap();
        let (c, pts) = silhouette(70.0, 450.0);
        let truth = FisheyeCamera.project(&KB, &c, None, None).unwrap();
        let mut z2 = Vec::new();
        for _ in 0..200 {
            let noisy: Vec<(f64, f64)> = pts
                .iter()
                .map(|&(x, y)| (x + noise.sample(&mut g), y + noise.sample(&mut g)))
                .collect();
            let fit = sphere_centre_from_edges(&noisy, &cam, 33.0, 0.25 / 374.0).unwrap();
            let mut jac = Matrix2x3::zeros();
            let p = FisheyeCamera
                .project(&KB, &fit.centre, Some(&mut jac), None)
                .unwrap();
            let cov = jac * fit.cov * jac.transpose();
            let d = p - truth;
            z2.push(d.x * d.x / cov[(0, 0)]);
            z2.push(d.y * d.y / cov[(1, 1)]);
        }
        let rms = (z2.iter().sum::<f64>() / z2.len() as f64).sqrt();
        assert!((0.82..=1.18).contains(&rms), "rms(error/σ) {rms:.3}");
    }
}
