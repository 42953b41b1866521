//! Thresholding that survives flash hot spots and vignetting.
//!
//! A single global threshold fails on these photographs: inside a flash hot spot the carbon
//! background is brighter than the targets, and in the vignetted corners the targets are darker
//! than the background in the centre. What every target does have is a *local* contrast: it
//! is brighter than the dark annulus (or dark code square) just around it. So:
//!
//! 1. [`threshold_levels`] picks a ladder of grey levels spanning the image's dynamic range
//!    (geometric spacing, so dim and bright regions are both covered); every target is an
//!    isolated connected component at some rung of the ladder, whatever the brightness of the
//!    background further away (as in OpenCV's SimpleBlobDetector, but with the ladder adapted
//!    to the image).
//! 2. [`local_levels`] then sets, for each candidate, its own foreground level (robust mean
//!    inside the blob) and, per edge ray, the background level (minimum just outside), and the
//!    edge is where the profile crosses the mid level between the two. That per-ray level is
//!    the adaptive threshold that makes the sub-pixel edge independent of slow illumination
//!    gradients.

use crate::ellipse::Ellipse;
use crate::image_io::GrayImage;

/// Bins of [`sample_histogram`].
const BINS: usize = 1024;

/// Histogram of a strided sample of `data` (every `step`-th value from the first, step =
/// max(1, len / 400 000): a sample is plenty for percentiles) in [`BINS`] bins: a value's bin is
/// its [0, 1]-clamped value times BINS − 1, truncated (NaN: bin 0). Returns the counts and the
/// sample size. Counted in parallel, in as many pieces as rayon has threads.
fn sample_histogram(data: &[f32]) -> ([usize; BINS], usize) {
    sample_histogram_in(data, rayon::current_num_threads())
}

/// [`sample_histogram`] counted in `pieces` pieces (at least one) of a multiple of step values
/// each (so each piece's sample starts at its first value), their counts added up.
fn sample_histogram_in(data: &[f32], pieces: usize) -> ([usize; BINS], usize) {
    use rayon::prelude::*;
    let step = (data.len() / 400_000).max(1);
    let total = data.len().div_ceil(step);
    let per_piece = total.div_ceil(pieces.max(1)).max(1);
    let hist = data
        .par_chunks(step * per_piece)
        .fold(
            || [0usize; BINS],
            |mut hist, piece| {
                for (h, c) in hist.iter_mut().zip(piece_histogram(piece, step).iter()) {
                    *h += *c as usize;
                }
                hist
            },
        )
        .reduce(
            || [0usize; BINS],
            |mut a, b| {
                for (a, b) in a.iter_mut().zip(b.iter()) {
                    *a += b;
                }
                a
            },
        );
    (hist, total)
}

/// The histogram of every `step`-th value of `data` from the first (u32 counts: a piece has
/// fewer than 800 000 samples).
fn piece_histogram(data: &[f32], step: usize) -> [u32; BINS] {
    // The product is in 0..=1023, so the cheaper conversion to i32 gives the same number.
    let bin = |v: f32| ((v.clamp(0.0, 1.0) * (BINS - 1) as f32) as i32 as usize) & (BINS - 1);
    // Counted in four histograms in turn (consecutive samples often fall in the same bin, and
    // one histogram would make each count wait for the previous one), then added up.
    let mut hists = [[0u32; BINS]; 4];
    let mut quads = data.chunks_exact(4 * step);
    for q in quads.by_ref() {
        for (h, i) in hists.iter_mut().zip([0, step, 2 * step, 3 * step]) {
            h[bin(q[i])] += 1;
        }
    }
    for v in quads.remainder().iter().step_by(step) {
        hists[0][bin(*v)] += 1;
    }
    let mut hist = [0u32; BINS];
    for (i, h) in hist.iter_mut().enumerate() {
        *h = hists.iter().map(|s| s[i]).sum();
    }
    hist
}

/// A ladder of `n` threshold levels between the dark and bright ends of the image histogram
/// (0.5th and 99.9th percentiles), geometrically spaced above the dark end.
pub fn threshold_levels(img: &GrayImage, n: usize) -> Vec<f32> {
    let (hist, total) = sample_histogram(&img.data);
    if total == 0 || n == 0 {
        return Vec::new();
    }
    let pct = |p: f64| -> f32 {
        let target = (p * total as f64) as usize;
        let mut acc = 0;
        for (i, h) in hist.iter().enumerate() {
            acc += h;
            if acc > target {
                return i as f32 / (BINS - 1) as f32;
            }
        }
        1.0
    };
    let lo = pct(0.005);
    let hi = pct(0.999).max(lo + 0.02);
    let span = hi - lo;
    // Fractions of the span from 0.06 to 0.9, geometric.
    let (f0, f1) = (0.06f64, 0.9f64);
    (0..n)
        .map(|i| {
            let t = if n == 1 {
                0.5
            } else {
                i as f64 / (n - 1) as f64
            };
            let f = f0 * (f1 / f0).powf(t);
            lo + span * f as f32
        })
        .collect()
}

/// Foreground level of a candidate (mean of the samples inside 0.6 of its ellipse, with the
/// upper and lower 10 % trimmed) and the fraction of those samples at or above `saturation`.
pub fn foreground_level(img: &GrayImage, e: &Ellipse, saturation: f32) -> (f32, f64) {
    let mut v = Vec::with_capacity(64);
    let fr = e.frame();
    let k = 6;
    for i in -k..=k {
        for j in -k..=k {
            let (u, w) = (i as f64 / k as f64 * 0.6, j as f64 / k as f64 * 0.6);
            if u * u + w * w > 0.36 {
                continue;
            }
            let (x, y) = fr.map(u, w);
            v.push(img.sample_inside(x, y));
        }
    }
    if v.is_empty() {
        return (0.0, 0.0);
    }
    let sat = v.iter().filter(|&&s| s >= saturation).count() as f64 / v.len() as f64;
    // The t smallest and t largest are split off by two selections (no full sort needed).
    let t = v.len() / 10;
    let n = v.len();
    if t > 0 {
        v.select_nth_unstable_by(t - 1, |a, b| a.total_cmp(b));
        v[t..].select_nth_unstable_by(n - 2 * t, |a, b| a.total_cmp(b));
    }
    let inner = &v[t..n - t];
    (inner.iter().sum::<f32>() / inner.len() as f32, sat)
}

/// Per-ray local levels: for a profile sampled outward from the centre (`profile[i]` at
/// parameter `t[i]`, t = 1 on the seed ellipse), the background is the minimum of the profile
/// for t in `[t_lo, t_hi]`, and the threshold is `fg + frac·(bg − fg)`. Returns
/// (background, threshold), or `None` when the ray does not reach `t_lo`.
pub fn local_levels(
    profile: &[f32],
    t: &[f64],
    fg: f32,
    frac: f32,
    t_lo: f64,
    t_hi: f64,
) -> Option<(f32, f32)> {
    let mut bg = f32::INFINITY;
    for (p, &ti) in profile.iter().zip(t) {
        if ti >= t_lo && ti <= t_hi {
            bg = bg.min(*p);
        }
    }
    if !bg.is_finite() {
        return None;
    }
    Some((bg, fg + frac * (bg - fg)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The histogram equals a plain count of every `step`-th value, for lengths with every
    /// step from 1 to 5 and every remainder modulo 4·step, counted in 1 to 4 pieces.
    #[test]
    fn sample_histogram_counts_every_step_th_value() {
        use rand::Rng;
        let mut rng = pingcal_geometry::consensus::rng(7);
        let all: Vec<f32> = (0..2_500_000)
            .map(|_| match rng.random_range(0..8) {
                0 => f32::from_bits(rng.random()),
                1 => rng.random_range(-1.0..2.0),
                _ => rng.random_range(0.0..=1.0),
            })
            .collect();
        let mut lens: Vec<usize> = (0..40).collect();
        for step in 1..=5 {
            for r in 0..4 * step {
                lens.push(400_000 * step + 4 * step * 1000 + r);
            }
        }
        for len in lens {
            let data = &all[..len];
            let step = (len / 400_000).max(1);
            let mut want = [0usize; BINS];
            let mut total = 0;
            for v in data.iter().step_by(step) {
                want[((v.clamp(0.0, 1.0)) * (BINS - 1) as f32) as usize] += 1;
                total += 1;
            }
            for pieces in 1..=4 {
                let (got, n) = sample_histogram_in(data, pieces);
                assert_eq!(n, total, "len {len}, {pieces} pieces");
                assert!(got == want, "len {len}, {pieces} pieces");
            }
        }
    }

    #[test]
    fn ladder_spans_the_histogram() {
        let mut img = GrayImage::new(100, 100, 0.1);
        for v in img.data.iter_mut().take(5000) {
            *v = 0.8;
        }
        let l = threshold_levels(&img, 10);
        assert_eq!(l.len(), 10);
        assert!(
            l[0] > 0.1 && l[9] < 0.8 && l.windows(2).all(|w| w[0] < w[1]),
            "{l:?}"
        );
    }
}
