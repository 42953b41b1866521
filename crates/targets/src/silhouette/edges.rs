//! Edge points from the gradient of a grey or colour image, at a coarser scale when the
//! silhouettes looked for are large.
//!
//! Per pixel of the image box-averaged over `s × s` (the scale), the gradient of every
//! channel by the Sobel operator, and their colour gradient in Di Zenzo's sense: the
//! largest eigenvalue λ of the structure tensor `Σ_c ∇I_c ∇I_cᵀ` and its eigenvector, so that
//! an outline where one channel rises and another falls (a grey ball on red bricks) is as
//! strong as a grey step, and a ball darker than its background below and brighter above
//! gives an edge all round. The gradient's sign is not kept: the direction is an axis.
//!
//! Edge points are the pixels whose magnitude `√λ` is a local maximum across the edge
//! (non-maximum suppression along the direction quantised to 45°) and above a threshold:
//! [`EDGE_MEDIAN_FACTOR`] times the median magnitude of the image (its texture and noise),
//! and at least [`EDGE_MIN`] grey levels per pixel. Work: a few operations per pixel and
//! channel.

pub use crate::raster::ColourImage;
use crate::raster::GrayImage;

/// An edge point must be this many times the median gradient magnitude.
pub const EDGE_MEDIAN_FACTOR: f32 = 3.0;

/// The least gradient magnitude of an edge point, grey levels (image in [0, 1]) per pixel
/// of the scale's image.
pub const EDGE_MIN: f32 = 0.01;

/// One edge point at a scale: position and unit gradient axis in that scale's pixels, and
/// the magnitude.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EdgePixel {
    /// Column and row of the scale's image.
    pub x: f32,
    /// Row.
    pub y: f32,
    /// Unit direction across the edge (its sign is arbitrary).
    pub ux: f32,
    /// Second component.
    pub uy: f32,
    /// Colour gradient magnitude, grey levels per pixel of the scale.
    pub mag: f32,
}

/// The edge points of an image at one scale.
#[derive(Clone, Debug)]
pub struct EdgeMap {
    /// The scale: one pixel here is `scale × scale` pixels of the image.
    pub scale: usize,
    /// Width of the scale's image.
    pub width: usize,
    /// Height of the scale's image.
    pub height: usize,
    /// The edge points, row by row.
    pub points: Vec<EdgePixel>,
    /// The threshold used.
    pub threshold: f32,
}

/// `img` box-averaged over `s × s` (the last partial row and column dropped).
pub fn downsample(img: &GrayImage, s: usize) -> GrayImage {
    if s <= 1 {
        return img.clone();
    }
    let (w, h) = (img.width / s, img.height / s);
    let mut out = GrayImage::new(w, h, 0.0);
    let k = 1.0 / (s * s) as f32;
    for y in 0..h {
        let row = &mut out.data[y * w..(y + 1) * w];
        for yy in y * s..(y + 1) * s {
            let src = &img.data[yy * img.width..yy * img.width + w * s];
            for (x, o) in row.iter_mut().enumerate() {
                *o += src[x * s..(x + 1) * s].iter().sum::<f32>();
            }
        }
        for o in row.iter_mut() {
            *o *= k;
        }
    }
    out
}

/// The structure tensor `(Σ gx², Σ gx gy, Σ gy²)` over the channels, per pixel (Sobel, /8 so
/// that a unit ramp gives 1; zero on the border).
fn structure_tensor(planes: &[GrayImage]) -> Vec<[f32; 3]> {
    let (w, h) = (planes[0].width, planes[0].height);
    let mut t = vec![[0.0f32; 3]; w * h];
    if w < 3 || h < 3 {
        return t;
    }
    for p in planes {
        let d = &p.data;
        for y in 1..h - 1 {
            let (r0, r1, r2) = (
                &d[(y - 1) * w..y * w],
                &d[y * w..(y + 1) * w],
                &d[(y + 1) * w..(y + 2) * w],
            );
            let out = &mut t[y * w..(y + 1) * w];
            for x in 1..w - 1 {
                let gx = (r0[x + 1] - r0[x - 1])
                    + 2.0 * (r1[x + 1] - r1[x - 1])
                    + (r2[x + 1] - r2[x - 1]);
                let gy = (r2[x - 1] - r0[x - 1]) + 2.0 * (r2[x] - r0[x]) + (r2[x + 1] - r0[x + 1]);
                let (gx, gy) = (gx * 0.125, gy * 0.125);
                let o = &mut out[x];
                o[0] += gx * gx;
                o[1] += gx * gy;
                o[2] += gy * gy;
            }
        }
    }
    t
}

/// The largest eigenvalue of the 2×2 tensor and its unit eigenvector.
#[inline]
fn dominant(t: &[f32; 3]) -> (f32, f32, f32) {
    let (a, b, c) = (t[0], t[1], t[2]);
    let half = 0.5 * (a - c);
    let disc = (half * half + b * b).sqrt();
    let lambda = 0.5 * (a + c) + disc;
    // eigenvector of λ: (b, λ − a) or (λ − c, b), whichever is longer
    let (v1, v2) = if a >= c {
        (lambda - c, b)
    } else {
        (b, lambda - a)
    };
    let n = (v1 * v1 + v2 * v2).sqrt();
    if n > 0.0 {
        (lambda, v1 / n, v2 / n)
    } else {
        (lambda, 1.0, 0.0)
    }
}

/// The edge points of `img` at scale `s` (see the module doc).
pub fn edge_map(img: &ColourImage, s: usize) -> EdgeMap {
    let s = s.max(1);
    let planes: Vec<GrayImage> = img.planes.iter().map(|p| downsample(p, s)).collect();
    let (w, h) = (planes[0].width, planes[0].height);
    let tensor = structure_tensor(&planes);
    let mut mag = vec![0.0f32; w * h];
    let mut dir = vec![(0.0f32, 0.0f32); w * h];
    for (i, t) in tensor.iter().enumerate() {
        let (l, ux, uy) = dominant(t);
        mag[i] = l.max(0.0).sqrt();
        dir[i] = (ux, uy);
    }
    let threshold = median_threshold(&mag, w, h);
    let mut points = Vec::new();
    for y in 2..h.saturating_sub(2) {
        for x in 2..w - 2 {
            let i = y * w + x;
            let m = mag[i];
            if m < threshold {
                continue;
            }
            let (ux, uy) = dir[i];
            // neighbours across the edge, the direction quantised to 45°
            let (dx, dy) = quantise(ux, uy);
            let a = mag[(y as isize + dy) as usize * w + (x as isize + dx) as usize];
            let b = mag[(y as isize - dy) as usize * w + (x as isize - dx) as usize];
            if m >= a && m > b {
                points.push(EdgePixel {
                    x: x as f32,
                    y: y as f32,
                    ux,
                    uy,
                    mag: m,
                });
            }
        }
    }
    EdgeMap {
        scale: s,
        width: w,
        height: h,
        points,
        threshold,
    }
}

/// The step to the neighbour along (ux, uy), quantised to 45°.
#[inline]
fn quantise(ux: f32, uy: f32) -> (isize, isize) {
    const T: f32 = 0.382_683_43; // sin 22.5°
    let dx = if ux > T {
        1
    } else if ux < -T {
        -1
    } else {
        0
    };
    let dy = if uy > T {
        1
    } else if uy < -T {
        -1
    } else {
        0
    };
    (dx, dy)
}

/// [`EDGE_MEDIAN_FACTOR`] × the median magnitude over the image's interior (sampled on a
/// grid of at most ~65 000 pixels), at least [`EDGE_MIN`].
fn median_threshold(mag: &[f32], w: usize, h: usize) -> f32 {
    let step = ((w * h) as f64 / 65_536.0).sqrt().ceil().max(1.0) as usize;
    let mut v: Vec<f32> = (2..h.saturating_sub(2))
        .step_by(step)
        .flat_map(|y| {
            (2..w.saturating_sub(2))
                .step_by(step)
                .map(move |x| mag[y * w + x])
        })
        .collect();
    if v.is_empty() {
        return EDGE_MIN;
    }
    let mid = v.len() / 2;
    let med = *v.select_nth_unstable_by(mid, |a, b| a.total_cmp(b)).1;
    (EDGE_MEDIAN_FACTOR * med).max(EDGE_MIN)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_disc_gives_edge_points_on_its_outline_with_radial_directions() {
        let (w, h, r) = (160usize, 120usize, 30.0f64);
        let (cx, cy) = (70.3f64, 58.6f64);
        let mut img = GrayImage::new(w, h, 0.2);
        for y in 0..h {
            for x in 0..w {
                let d = ((x as f64 - cx).powi(2) + (y as f64 - cy).powi(2)).sqrt();
                // a ramp of 1 px across the outline
                img.data[y * w + x] = 0.2 + 0.6 * (r + 0.5 - d).clamp(0.0, 1.0) as f32;
            }
        }
        // a colour version: the disc rises in one channel and falls in another
        let mut inv = img.clone();
        for v in &mut inv.data {
            *v = 1.0 - *v;
        }
        for im in [
            ColourImage::grey(img.clone()),
            ColourImage {
                planes: vec![img, inv],
            },
        ] {
            let e = edge_map(&im, 1);
            assert!(e.points.len() > 150, "{}", e.points.len());
            for p in &e.points {
                let (dx, dy) = (p.x as f64 - cx, p.y as f64 - cy);
                let d = (dx * dx + dy * dy).sqrt();
                assert!((d - r).abs() < 1.6, "edge at distance {d}");
                let cos = ((p.ux as f64 * dx + p.uy as f64 * dy) / d).abs();
                assert!(cos > 0.95, "direction off by acos {cos}");
            }
        }
    }

    #[test]
    fn downsampling_averages_blocks() {
        let img = GrayImage {
            width: 4,
            height: 2,
            data: vec![0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0],
        };
        let d = downsample(&img, 2);
        assert_eq!((d.width, d.height), (2, 1));
        assert_eq!(d.data, vec![2.5, 4.5]);
    }
}
