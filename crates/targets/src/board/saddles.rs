//! X-corner candidates: saddle points of the smoothed image whose surround is two dark and
//! two light sectors.

use crate::raster::GrayImage;

/// The smoothing of the saddle response (px).
const SMOOTHING_PX: f64 = 1.5;
/// Radius of the ring that checks a candidate's four sectors (px).
const RING_PX: f64 = 4.0;
/// Samples on the ring.
const RING_SAMPLES: usize = 32;
/// The fewest samples of one sector.
const MIN_SECTOR: usize = 3;
/// The smallest contrast of a corner's ring (max − min, in the image's 0–1 scale).
const MIN_CONTRAST: f32 = 0.08;
/// The largest mean difference between opposite ring samples, as a fraction of the ring's
/// contrast.
const MAX_ASYMMETRY: f32 = 0.25;
/// The smallest saddle response, σ⁴-normalised, as a fraction of the strongest one.
const MIN_RELATIVE_RESPONSE: f32 = 0.02;

/// A candidate x-corner.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Saddle {
    /// Position (px), to the pixel.
    pub uv: [f64; 2],
    /// The σ⁴-normalised saddle response.
    pub response: f32,
    /// The two edge directions through it (radians, in `[0, π)`).
    pub edges: [f64; 2],
}

/// Every x-corner candidate of `img`, strongest first.
pub fn find(img: &GrayImage) -> Vec<Saddle> {
    let (w, h) = (img.width, img.height);
    if w < 16 || h < 16 {
        return Vec::new();
    }
    let smooth = gaussian(img, SMOOTHING_PX);
    let response = saddle_response(&smooth);
    let strongest = response.iter().cloned().fold(0.0f32, f32::max);
    if strongest <= 0.0 {
        return Vec::new();
    }
    let floor = strongest * MIN_RELATIVE_RESPONSE;
    let margin = (RING_PX.ceil() as usize) + 2;
    let mut out = Vec::new();
    for y in margin..h - margin {
        for x in margin..w - margin {
            let r = response[y * w + x];
            if r <= floor || !is_local_max(&response, w, x, y, 2) {
                continue;
            }
            if let Some(edges) = ring_edges(&smooth, x as f64, y as f64) {
                out.push(Saddle {
                    uv: [x as f64, y as f64],
                    response: r,
                    edges,
                });
            }
        }
    }
    out.sort_by(|a, b| b.response.total_cmp(&a.response));
    out
}

/// `f_xy² − f_xx f_yy` (positive at a saddle), times σ⁴.
fn saddle_response(s: &GrayImage) -> Vec<f32> {
    let (w, h) = (s.width, s.height);
    let mut out = vec![0.0f32; w * h];
    let norm = SMOOTHING_PX.powi(4) as f32;
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let c = s.get(x, y);
            let fxx = s.get(x + 1, y) - 2.0 * c + s.get(x - 1, y);
            let fyy = s.get(x, y + 1) - 2.0 * c + s.get(x, y - 1);
            let fxy = 0.25
                * (s.get(x + 1, y + 1) - s.get(x - 1, y + 1) - s.get(x + 1, y - 1)
                    + s.get(x - 1, y - 1));
            out[y * w + x] = (fxy * fxy - fxx * fyy).max(0.0) * norm;
        }
    }
    out
}

fn is_local_max(r: &[f32], w: usize, x: usize, y: usize, radius: usize) -> bool {
    let c = r[y * w + x];
    for yy in y - radius..=y + radius {
        for xx in x - radius..=x + radius {
            let v = r[yy * w + xx];
            // Ties go to the first pixel in reading order.
            if v > c || (v == c && (yy, xx) < (y, x)) {
                return false;
            }
        }
    }
    true
}

/// The two edge directions at (x, y) when a ring around it has exactly two light and two
/// dark sectors, each of at least [`MIN_SECTOR`] samples, with enough contrast.
fn ring_edges(s: &GrayImage, x: f64, y: f64) -> Option<[f64; 2]> {
    let step = std::f64::consts::TAU / RING_SAMPLES as f64;
    let ring: Vec<f32> = (0..RING_SAMPLES)
        .map(|k| {
            let a = k as f64 * step;
            s.sample(x + RING_PX * a.cos(), y + RING_PX * a.sin())
        })
        .collect();
    let (lo, hi) = ring
        .iter()
        .fold((f32::MAX, f32::MIN), |(l, h), &v| (l.min(v), h.max(v)));
    if hi - lo < MIN_CONTRAST {
        return None;
    }
    // A chessboard corner is point-symmetric: each sample is like the one opposite it (a
    // T-junction at the board's border, against its frame, is not).
    let half = RING_SAMPLES / 2;
    let asymmetry = (0..half)
        .map(|k| (ring[k] - ring[k + half]).abs())
        .sum::<f32>()
        / half as f32;
    if asymmetry > MAX_ASYMMETRY * (hi - lo) {
        return None;
    }
    let mid = 0.5 * (lo + hi);
    let light: Vec<bool> = ring.iter().map(|&v| v > mid).collect();
    // Sign changes: between samples k and k + 1, at the interpolated angle.
    let mut changes = Vec::new();
    for k in 0..RING_SAMPLES {
        let k1 = (k + 1) % RING_SAMPLES;
        if light[k] != light[k1] {
            let t = ((mid - ring[k]) / (ring[k1] - ring[k])) as f64;
            changes.push((k, (k as f64 + t) * step));
        }
    }
    if changes.len() != 4 {
        return None;
    }
    for i in 0..4 {
        let (a, b) = (changes[i].0, changes[(i + 1) % 4].0);
        let len = (b + RING_SAMPLES - a) % RING_SAMPLES;
        if len < MIN_SECTOR {
            return None;
        }
    }
    let pi = std::f64::consts::PI;
    let e1 = circular_mean_mod_pi(changes[0].1, changes[2].1);
    let e2 = circular_mean_mod_pi(changes[1].1, changes[3].1);
    // The two edges of a chessboard corner are far from parallel even in steep views.
    let between = (e1 - e2).rem_euclid(pi);
    if between.min(pi - between) < 0.35 {
        return None;
    }
    Some([e1, e2])
}

/// The mean of two directions taken modulo π, in `[0, π)`.
fn circular_mean_mod_pi(a: f64, b: f64) -> f64 {
    let (sa, ca) = ((2.0 * a).sin(), (2.0 * a).cos());
    let (sb, cb) = ((2.0 * b).sin(), (2.0 * b).cos());
    let m = 0.5 * (sa + sb).atan2(ca + cb);
    m.rem_euclid(std::f64::consts::PI)
}

/// The image smoothed by a Gaussian of `sigma` px (separable, edges clamped).
pub(crate) fn gaussian(img: &GrayImage, sigma: f64) -> GrayImage {
    let radius = (3.0 * sigma).ceil() as isize;
    let kernel: Vec<f32> = (-radius..=radius)
        .map(|k| (-(k * k) as f64 / (2.0 * sigma * sigma)).exp() as f32)
        .collect();
    let sum: f32 = kernel.iter().sum();
    let kernel: Vec<f32> = kernel.iter().map(|k| k / sum).collect();
    let (w, h) = (img.width as isize, img.height as isize);
    let pass = |src: &[f32], horizontal: bool| -> Vec<f32> {
        let mut out = vec![0.0f32; src.len()];
        for y in 0..h {
            for x in 0..w {
                let mut acc = 0.0f32;
                for (i, k) in kernel.iter().enumerate() {
                    let d = i as isize - radius;
                    let (xx, yy) = if horizontal {
                        ((x + d).clamp(0, w - 1), y)
                    } else {
                        (x, (y + d).clamp(0, h - 1))
                    };
                    acc += k * src[(yy * w + xx) as usize];
                }
                out[(y * w + x) as usize] = acc;
            }
        }
        out
    };
    let data = pass(&pass(&img.data, true), false);
    GrayImage {
        width: img.width,
        height: img.height,
        data,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_mean_of_two_directions_wraps_at_pi() {
        let m = circular_mean_mod_pi(0.05, std::f64::consts::PI - 0.05);
        assert!(m.min(std::f64::consts::PI - m) < 1e-9, "{m}");
        assert!((circular_mean_mod_pi(0.2, 0.4) - 0.3).abs() < 1e-12);
    }
}
