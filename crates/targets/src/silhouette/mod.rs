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
//!    exact), the strongest colour edge along its normal at each place, the centre fitted to
//!    those edge points' rays with a robust weight ([`cone`]), the search narrowed round by
//!    round. Edge points of a highlight, a stand or a hand are rejected by the fit; places
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
