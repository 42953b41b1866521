//! What ChArUco boards and AprilGrids share once their markers are read: the markers that
//! agree on the board's plane ([`agreeing`]), a corner refined and checked to be an x-corner
//! ([`refined_corner`]), and the corners that agree with their neighbours ([`consistent`]).

use super::markers::Marker;
use super::refine::refine_in;
use super::{BoardCorner, MarkerMiss};
use crate::homography::{fit_homography, ransac_homography};
use crate::raster::GrayImage;

/// At least this many markers, agreeing on the board's plane.
const MIN_MARKERS: usize = 2;

/// Neighbours a corner needs for [`consistent`] to check it.
const MIN_NEIGHBOURS: usize = 4;

/// The corners that agree with their neighbours: each corner's position predicted by the
/// homography of the corners within `radius_mm` of it on the board (itself left out) must
/// lie within max(0.5 px, 4 σ) of it. The worst corner off its prediction is dropped and the
/// rest checked again; a corner with fewer than [`MIN_NEIGHBOURS`] neighbours is dropped
/// (a refinement drawn to a marker's edge must not pass as the corner).
pub(crate) fn consistent(
    mut corners: Vec<BoardCorner>,
    point: impl Fn(usize) -> [f64; 3],
    radius_mm: f64,
) -> Vec<BoardCorner> {
    loop {
        let mut worst: Option<(usize, f64)> = None;
        for (i, c) in corners.iter().enumerate() {
            let p = point(c.id);
            let (src, dst): (Vec<[f64; 2]>, Vec<[f64; 2]>) = corners
                .iter()
                .filter(|o| o.id != c.id)
                .filter(|o| {
                    let q = point(o.id);
                    (q[0] - p[0]).hypot(q[1] - p[1]) <= radius_mm
                })
                .map(|o| {
                    let q = point(o.id);
                    ([q[0], q[1]], o.uv)
                })
                .unzip();
            let off = if src.len() < MIN_NEIGHBOURS {
                f64::INFINITY
            } else {
                fit_homography(&src, &dst)
                    .and_then(|h| h.apply([p[0], p[1]]))
                    .map_or(f64::INFINITY, |q| (q[0] - c.uv[0]).hypot(q[1] - c.uv[1]))
            };
            let excess = off / (4.0 * c.sigma_px).max(0.5);
            if excess > 1.0 && worst.is_none_or(|(_, e)| excess > e) {
                worst = Some((i, excess));
            }
        }
        match worst {
            Some((i, _)) => {
                corners.remove(i);
            }
            None => return corners,
        }
    }
}

/// A corner refined from `start` with a window of half width `half`, kept when its window
/// lies in the image, the fit converged within the window, and the corner is an x-corner
/// on a ring of radius `ring` px around it.
pub(crate) fn refined_corner(
    img: &GrayImage,
    start: [f64; 2],
    half: i64,
    ring: f64,
) -> Option<([f64; 2], f64)> {
    let margin = half as f64 + 2.0;
    if !img.inside(start[0], start[1], margin) {
        return None;
    }
    let fit = refine_in(img, start, half);
    let moved = ((fit.uv[0] - start[0]).powi(2) + (fit.uv[1] - start[1]).powi(2)).sqrt();
    if fit.uv == start || moved > half as f64 || !img.inside(fit.uv[0], fit.uv[1], margin) {
        return None;
    }
    x_corner(img, fit.uv, ring.max(2.0)).then_some((fit.uv, fit.sigma_px))
}

/// Whether `p` is an x-corner: on a ring of radius `r`, the brightness changes sign four
/// times around the ring's mean, with at least 0.05 between its bright and dark halves.
fn x_corner(img: &GrayImage, p: [f64; 2], r: f64) -> bool {
    let n = 32;
    let ring: Vec<f64> = (0..n)
        .map(|i| {
            let a = std::f64::consts::TAU * i as f64 / n as f64;
            img.sample(p[0] + r * a.cos(), p[1] + r * a.sin()) as f64
        })
        .collect();
    let mut sorted = ring.clone();
    sorted.sort_by(f64::total_cmp);
    let (lo, hi) = (sorted[n / 4], sorted[3 * n / 4]);
    let mid = 0.5 * (lo + hi);
    let changes = (0..n)
        .filter(|&i| (ring[i] > mid) != (ring[(i + 1) % n] > mid))
        .count();
    changes == 4 && hi - lo > 0.05
}

/// The mean side of the markers (px).
pub(crate) fn marker_side_px(markers: &[Marker]) -> f64 {
    let sides: f64 = markers
        .iter()
        .map(|m| {
            (0..4)
                .map(|i| {
                    let (a, b) = (m.corners[i], m.corners[(i + 1) % 4]);
                    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()
                })
                .sum::<f64>()
                / 4.0
        })
        .sum();
    sides / markers.len().max(1) as f64
}

/// The markers whose corners agree with one homography of the board's plane (RANSAC over
/// the markers' corners, a threshold of a quarter of a square's side in the image, at least
/// 3 px); at least [`MIN_MARKERS`] of them.
pub(crate) fn agreeing(
    read: Vec<Marker>,
    plane: impl Fn(usize) -> [[f64; 2]; 4],
    square_mm: f64,
    dictionary: &'static str,
) -> Result<Vec<Marker>, MarkerMiss> {
    if read.len() < MIN_MARKERS {
        return Err(MarkerMiss::TooFewMarkers {
            dictionary,
            found: read.len(),
            needed: MIN_MARKERS,
        });
    }
    let (src, dst): (Vec<[f64; 2]>, Vec<[f64; 2]>) = read
        .iter()
        .flat_map(|m| plane(m.id).into_iter().zip(m.corners))
        .unzip();
    let side_px = marker_side_px(&read);
    let side_mm = {
        let c = plane(read[0].id);
        ((c[1][0] - c[0][0]).powi(2) + (c[1][1] - c[0][1]).powi(2)).sqrt()
    };
    let threshold = (0.25 * square_mm * side_px / side_mm).max(3.0);
    let fit =
        ransac_homography(&src, &dst, threshold, 200, 51).ok_or(MarkerMiss::TooFewMarkers {
            dictionary,
            found: 0,
            needed: MIN_MARKERS,
        })?;
    let kept: Vec<Marker> = read
        .into_iter()
        .enumerate()
        .filter(|(i, _)| (0..4).all(|k| fit.inliers[4 * i + k]))
        .map(|(_, m)| m)
        .collect();
    if kept.len() < MIN_MARKERS {
        return Err(MarkerMiss::Disagreeing {
            dictionary,
            found: kept.len(),
            needed: MIN_MARKERS,
        });
    }
    Ok(kept)
}
