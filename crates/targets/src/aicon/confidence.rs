//! The margins of a coded read and its confidence: whether a number read from a ring
//! ([`crate::aicon`]) can be trusted. A wrong number costs far more than a missing one (it
//! pulls the network's start and the bundle until data snooping finds it, if it does), so a
//! number is given only when every margin clears its bound; otherwise the ring is refused
//! ("ring unreadable", with the number and margins that were refused).
//!
//! **The ring model.** The sector means `y_k` the reading used (a sector's mean brightness over
//! its central 60 %, minus the dot's mid level) are fitted, for the pattern read (x_k = 1 for a
//! bright sector), as α + β (M_ε x)_k: a dark level α, a ring contrast β and the blur's spill
//! ε ≤ 0.12 into each neighbour (M_ε: 1 − 2ε on the diagonal, ε beside it; see
//! [`crate::aicon`]). Undoing the spill, x̂ = M_ε⁻¹ (y − α) / β puts every sector on the scale
//! of the ring's own dark (0) and bright (1) level, whichever reading (sharp thresholds or the
//! blurred-ring model) gave it.
//!
//! **The margins:**
//!
//! - `sector`: the smallest distance of a sector from the decision level ½, on the side the
//!   pattern reads it, on the inner and on the outer half of the ring's band separately (each
//!   half fitted on its own): how near the weakest sector came to being read the other way
//!   somewhere across the band. A sector cut obliquely (by the edge of something over the ring)
//!   is bright on one half and dark on the other, and has a small or negative margin.
//! - `hamming`: how many sectors differ between the pattern read and the nearest pattern of
//!   another number, at any rotation (the tables' parity makes it at least 2, and almost every
//!   pattern of even weight is a code, so it is 2 for nearly every read).
//! - `code`: the smallest Σ |x̂_k − ½| over the sectors that differ from another number's
//!   pattern: how far, in all, the sectors would have to move to read another number.
//! - `levels`: the largest |x̂_k − x_k|: a ring whose sectors are not two clean levels (a
//!   shadow over part of it, a sector partly covered) is doubted.
//! - `profile`: the deepest sample of the ring's angular profile on the wrong side of the ring's
//!   mid level α + β/2, over β, away from the changes of polarity (3 samples of 16 a sector next
//!   to them for the sharp reading, 6 for the blurred one): a bright sliver in a dark run.
//! - `surround`: how unevenly dark the ring's surround is: on two circles in the gap between dot
//!   and ring and one a quarter of a dot radius outside it, the 90th percentile of each over its
//!   median, over the dot's contrast (the largest of the three). Something across the target
//!   shows on part of a circle; blur and shading raise a whole circle evenly.
//! - `ring_fit`: how well the ring fits the dot's ellipse: on three rays through the middle 40 %
//!   of every bright sector (averaged), the ring's inner and outer edges (where the profile
//!   crosses the dot's mid level) are compared with the printed ring's circles (2 and 3 dot
//!   radii for AICON's) scaled by one common factor (0.85 to 1.25: blur shrinks a small dot's
//!   measured edge); `ring_fit` is the RMS distance, in dot radii, an edge not found counting one
//!   ring width. A ring that belongs to another dot, or is cut, does not fit.
//! - `fragment`: as `profile`, but on each of five radii across the band on its own (three
//!   neighbouring samples averaged) instead of on the band's mean: the piece of a bright sector
//!   left beside something that hides the rest of it is narrower than the band and vanishes in
//!   the mean over its radii; on one radius it shows.
//! - `outline`: the share of directions around the target in which its dark print reaches
//!   beyond its printed square (AICON's and `pingcal targets`': 4 dot radii from the centre),
//!   when the target lies on uniform paper (`outline`; 0 on a dark or textured background).
//!   Something as black as the target's own square laid over its ring (another target's
//!   square, a bar, a shadow) hides whole bright sectors and can leave another number's
//!   pattern, clean to every margin above; what it cannot hide is itself: where it leaves the
//!   square, the square's outline on the paper is no longer a square.
//!
//! **The confidence** is the weakest margin over its bound: min(sector / [`MIN_SECTOR`],
//! code / [`MIN_CODE`], [`MAX_LEVELS`] / levels, [`MAX_PROFILE`] / profile,
//! [`MAX_SURROUND`] / surround, [`MAX_RING_FIT`] / ring_fit, [`MAX_FRAGMENT`] / fragment,
//! [`MAX_OUTLINE`] / outline). A
//! read of confidence 1 or more is given; under 1 it is refused. The fifth figure of a read, its centre's σ, is judged by the
//! detector against the image's other reads ([`crate::detect::SIGMA_RATIO_MAX`]).
//!
//! **Why these bounds.** Measured on three populations of reads: the 20 real AICON panel
//! photographs (1,051 reads, every one right: `tests/real_panel.rs` prints their weakest
//! margins), the simulator's projects (`pingcal simulate`, sharp, blurred by 0.9 and 1.2 px,
//! four times the photon noise: about 2,000 reads, all right) and the false-read stress scenes
//! of `tests/synthetic.rs` (rings partly covered, overlapping targets, half-shadowed rings,
//! printed text, checkerboards: about 1,700 right reads and 60 wrong). Most wrong reads there
//! are clean to every margin (a ring partly hidden by something as black as the target's own
//! square shows another number's pattern, sharp and whole); the bounds refuse the wrong reads
//! that are not (a fifth of them) while keeping every read of the panel, whose weakest reads
//! keep 26 % (sector) to 5 times (ring fit) their bounds, and all but 1 to 4 % of the
//! simulator's. The `fragment` bound (0.1, twice `profile`'s: one radius is noisier than the
//! band's mean) is 0 on every panel read; on 600 stress scenes it refuses 9 of 53 wrong reads
//! and 8 of 1,605 right ones. The detector also refuses reads whose ring overlaps another
//! ring ([`crate::detect::RING_OVERLAP_MAX`]).
//!
//! The `outline` bound (one direction of 72) is 0 on every panel read (the panel's carbon is
//! dark and textured: no read sees uniform paper). On 600 stress scenes it refuses 34 of the
//! 39 wrong reads left by the other margins, and 544 of 1,585 right ones: a target whose square
//! meets another dark thing on the paper (the upper of two overlapping targets, a bar over
//! only dark sectors, a line of text touching it) is refused with the others, since from the
//! image alone the dark thing may as well lie over its ring; on rendered targets alone on
//! paper (`tests/synthetic.rs`, dot radii 3 to 20 px, blur to 2 px) it refuses none.

use crate::aicon::{blurred_sxx, Reading, RingReader, EPS_MAX, SAMPLES_PER_SECTOR, SPILLS};
use crate::ellipse::Ellipse;
use crate::image_io::GrayImage;
use serde::Serialize;

/// Smallest accepted `sector` margin (fraction of the ring's contrast).
pub const MIN_SECTOR: f32 = 0.2;
/// Smallest accepted `code` margin (fractions of the ring's contrast, summed).
pub const MIN_CODE: f32 = 0.5;
/// Largest accepted `levels` deviation (fraction of the ring's contrast).
pub const MAX_LEVELS: f32 = 0.3;
/// Largest accepted `profile` break (fraction of the ring's contrast).
pub const MAX_PROFILE: f32 = 0.05;
/// Largest accepted `surround` spread (fraction of the dot's contrast).
pub const MAX_SURROUND: f32 = 0.4;
/// Largest accepted `ring_fit` RMS (dot radii).
pub const MAX_RING_FIT: f32 = 0.2;
/// Largest accepted `fragment` (fraction of the ring's contrast).
pub const MAX_FRAGMENT: f32 = 0.1;
/// Largest accepted `outline` (share of the directions around the target).
pub const MAX_OUTLINE: f32 = 0.02;

/// How a ring was read.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ReadMethod {
    /// Sector thresholds at the dot's mid level (sharp images).
    Thresholds,
    /// The blurred-ring model ([`crate::aicon`], "Through blur").
    Model,
}

/// The margins that decided a coded read, and its confidence (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ReadMargins {
    /// How the ring was read: sharp thresholds or the blurred-ring model.
    pub method: ReadMethod,
    /// The weakest sector's distance from the decision level ½, on the side read, on either
    /// half of the band (fraction of the ring's contrast; at least [`MIN_SECTOR`]).
    pub sector: f32,
    /// Sectors that differ between the pattern read and the nearest other number's, at any
    /// rotation.
    pub hamming: u32,
    /// Σ |x̂ₖ − ½| over the sectors that differ from the nearest other number's pattern: how
    /// far, in all, the sectors would have to move to read it (at least [`MIN_CODE`]).
    pub code: f32,
    /// The largest |x̂ₖ − xₖ|: how far a sector lies from the two clean levels (fraction of
    /// the ring's contrast; at most [`MAX_LEVELS`]).
    pub levels: f32,
    /// The deepest break of the ring's angular profile on the wrong side of its mid level,
    /// away from the polarity changes (fraction of the ring's contrast; at most
    /// [`MAX_PROFILE`]).
    pub profile: f32,
    /// How unevenly dark the ring's surround is: 90th percentile over median on the gap and
    /// outer circles (fraction of the dot's contrast; at most [`MAX_SURROUND`]).
    pub surround: f32,
    /// RMS distance of the ring's found edges from the printed ring's circles scaled by one
    /// factor, in dot radii (at most [`MAX_RING_FIT`]).
    pub ring_fit: f32,
    /// As `profile`, on each of five radii across the band on its own (at most
    /// [`MAX_FRAGMENT`]).
    pub fragment: f32,
    /// The share of directions around the target in which its dark surround reaches beyond
    /// its printed square, when paper is seen around it (at most [`MAX_OUTLINE`]).
    pub outline: f32,
    /// The weakest margin over its bound: 1 or more gives the number, under 1 refuses it.
    pub confidence: f32,
}

/// The margins of `reading`, a ring read around `dot` (dot level `fg`, surround `bg`).
pub(crate) fn assess(
    img: &GrayImage,
    dot: &Ellipse,
    fg: f32,
    bg: f32,
    reader: &RingReader,
    reading: &Reading,
) -> ReadMargins {
    let n = reader.table.bits as usize;
    let y = &reading.y[..n];
    let fit = fit_levels(y, reading.mask);
    let x = sector_values(y, &fit);
    let sector = radial_sectors(img, dot, fg, bg, reader, reading)
        .iter()
        .map(|yr| {
            let xr = sector_values(&yr[..n], &fit_levels(&yr[..n], reading.mask));
            (0..n).fold(f32::INFINITY, |m, k| {
                let side = if reading.mask >> k & 1 == 1 {
                    1.0
                } else {
                    -1.0
                };
                m.min(side * (xr[k] - 0.5))
            })
        })
        .fold(f32::INFINITY, f32::min);
    let (hamming, code) = nearest_other(&x[..n], reading, reader);
    let levels = x[..n].iter().enumerate().fold(0.0f32, |w, (k, v)| {
        w.max((v - (reading.mask >> k & 1) as f32).abs())
    });

    let profile = profile_breaks(reading, n, &fit);
    let surround = surround_spread(img, dot, fg, bg, reader, reading);
    let ring_fit = ring_fit(img, dot, fg, bg, reader, reading);
    let fragment = fragments(img, dot, fg, bg, reader, reading, &fit);
    let outline = outline(img, dot, fg, bg, reader, reading);
    let confidence = (sector / MIN_SECTOR)
        .min(code / MIN_CODE)
        .min(MAX_LEVELS / levels.max(1e-6))
        .min(MAX_PROFILE / profile.max(1e-6))
        .min(MAX_SURROUND / surround.max(1e-6))
        .min(MAX_RING_FIT / ring_fit.max(1e-6))
        .min(MAX_FRAGMENT / fragment.max(1e-6))
        .min(MAX_OUTLINE / outline.max(1e-6));
    ReadMargins {
        method: reading.method,
        sector,
        hamming,
        code,
        levels,
        profile,
        surround,
        ring_fit,
        fragment,
        outline,
        confidence,
    }
}

/// Directions around the target in which [`outline`] looks for the end of its dark print.
const OUTLINE_RAYS: usize = 72;
/// The paper around a target, for [`outline`]: its median level over the dark surround's at
/// least this fraction of the dot's contrast ...
const PAPER_LEVEL: f32 = 0.2;
/// ... and its 90th percentile at most this fraction of the dot's contrast above its median
/// (uniform paper).
const PAPER_SPREAD: f32 = 0.08;
/// How far (dot radii, and one pixel more) the dark print may end beyond the fitted square's
/// edge.
const OUTLINE_TOLERANCE: f64 = 0.25;

/// The share of [`OUTLINE_RAYS`] directions around the target (in the dot's unit frame, where
/// the printed square is a square) in which its dark print reaches beyond its square, when it
/// lies on uniform paper; 0 otherwise (on a dark or textured background, such as the real
/// panel's carbon, nothing can be told).
///
/// The paper is looked for on a band beyond the square's corners (√2 times its half side and
/// a quarter more, to one dot radius further): on each ray, the mean of five samples across
/// the band. The target lies on uniform paper when the median of those means is at least
/// [`PAPER_LEVEL`] of the dot's contrast above the dark surround and their 90th percentile
/// within [`PAPER_SPREAD`] of the median. Then along each ray from 0.3 dot radii outside the
/// ring the dark print ends at the first sample half way from the surround to the paper (a
/// ray bright from its start, where a small dot's ring spills over its surround, tells
/// nothing); the square whose edge the most ends fit is found ([`square_fit`]), and a ray
/// whose print ends more than [`OUTLINE_TOLERANCE`] beyond its edge, or not before the band,
/// crosses something dark over or beside the target that is not its square, and that may
/// hide bright sectors of its ring.
fn outline(
    img: &GrayImage,
    dot: &Ellipse,
    fg: f32,
    bg: f32,
    reader: &RingReader,
    reading: &Reading,
) -> f32 {
    let scale = reading.scale;
    let r_from = (reader.geometry.1 + 0.3) * scale;
    let r_paper = reader.square_half * std::f64::consts::SQRT_2 * 1.25 * scale;
    let r_far = r_paper + scale;
    let fr = dot.frame();
    let at = |r: f64, (c, s): (f64, f64)| {
        let (x, y) = fr.map(r * c, r * s);
        img.sample_inside(x, y)
    };
    let rays: Vec<(f64, f64)> = crate::ellipse::unit_circle(OUTLINE_RAYS)
        .iter()
        .copied()
        .filter(|&(c, s)| {
            let (x, y) = fr.map(r_far * c, r_far * s);
            img.inside(x, y, 1.0)
        })
        .collect();
    if rays.len() < OUTLINE_RAYS / 2 {
        return 0.0;
    }
    let mut paper: Vec<f32> = rays
        .iter()
        .map(|&t| {
            let sum: f32 = (0..5)
                .map(|i| at(r_paper + (r_far - r_paper) * i as f64 / 4.0, t))
                .sum();
            (sum / 5.0 - bg) / (fg - bg)
        })
        .collect();
    paper.sort_by(|a, b| a.total_cmp(b));
    let q = |f: f64| paper[((paper.len() - 1) as f64 * f).round() as usize];
    let median = q(0.5);
    if !(median >= PAPER_LEVEL && q(0.9) - median <= PAPER_SPREAD) {
        return 0.0;
    }
    let level = bg + 0.5 * median * (fg - bg);
    let step = (0.5 / dot.radius()).clamp(0.02, 0.1);
    let steps = ((r_paper - r_from) / step).ceil() as usize;
    let ends: Vec<(f64, Option<f64>)> = rays
        .iter()
        .map(|&(c, s)| {
            let end = (0..=steps)
                .map(|i| r_from + (r_paper - r_from) * i as f64 / steps as f64)
                .find(|&r| at(r, (c, s)) > level);
            (s.atan2(c), end)
        })
        .filter(|(_, end)| end.is_none_or(|e| e > r_from))
        .collect();
    let half = reader.square_half * scale;
    let tol = OUTLINE_TOLERANCE * scale + 1.0 / dot.radius();
    square_fit(&ends, half, tol) as f32 / rays.len() as f32
}

/// The rays of `ends` (angle in the dot's unit frame, and where the dark print ends on it,
/// None: not within the search) whose print ends beyond the edge of the square that fits
/// the most ends within `tol`: the square's rotation in steps of 1°, its half side from 0.85
/// to 1.3 of the printed `half` (blur shrinks a small dot's measured radius, and so the dot
/// radius the square is measured in) in steps of 0.025; among the squares that leave the
/// fewest ends off their edge, the one with the fewest beyond it.
fn square_fit(ends: &[(f64, Option<f64>)], half: f64, tol: f64) -> usize {
    let edge = |phi: f64, theta: f64, h: f64| {
        let d = phi - theta;
        h / d.cos().abs().max(d.sin().abs())
    };
    let mut best = (usize::MAX, usize::MAX);
    for t in 0..90 {
        let theta = (t as f64).to_radians();
        for k in 0..=18 {
            let h = half * (0.85 + 0.025 * k as f64);
            let (mut off, mut beyond) = (0, 0);
            for &(phi, end) in ends {
                let e = edge(phi, theta, h);
                match end {
                    Some(r) if (r - e).abs() <= tol => {}
                    Some(r) if r < e => off += 1,
                    _ => {
                        off += 1;
                        beyond += 1;
                    }
                }
            }
            best = best.min((off, beyond));
        }
    }
    best.1
}

/// The deepest run of three samples on the wrong side of the ring's mid level, over β, on
/// any one of five radii across the band the reading sampled (not averaged over them),
/// away from the changes of polarity as in `profile_breaks`: the piece of a bright sector
/// left beside something that hides the rest of it, or a dark bite out of a bright one.
fn fragments(
    img: &GrayImage,
    dot: &Ellipse,
    fg: f32,
    bg: f32,
    reader: &RingReader,
    reading: &Reading,
    fit: &LevelFit,
) -> f32 {
    const S: usize = SAMPLES_PER_SECTOR;
    let n = reader.table.bits as usize;
    let m = n * S;
    let mid = bg + 0.5 * (fg - bg);
    let (lo, hi) = band(reader, reading);
    let zone = match reading.method {
        ReadMethod::Thresholds => S / 5,
        ReadMethod::Model => 6,
    };
    let ring_mid = fit.alpha + 0.5 * fit.beta;
    let bright = |k: usize| reading.mask >> (k % n) & 1 == 1;
    let trig = crate::ellipse::unit_circle(m);
    let fr = dot.frame();
    let mut v = vec![0.0f32; m];
    let mut worst = 0.0f32;
    for i in 0..5 {
        let r = lo + (hi - lo) * i as f64 / 4.0;
        for (vj, &(c, s)) in v.iter_mut().zip(trig.iter()) {
            let (x, y) = fr.map(r * c, r * s);
            *vj = img.sample_inside(x, y) - mid;
        }
        for j in 0..m {
            let rel = (j + m - reading.phi % m) % m;
            let (k, pos) = (rel / S, rel % S);
            let near_change = (pos < zone + 1 && bright(k + n - 1) != bright(k))
                || (pos + zone + 1 >= S && bright(k + 1) != bright(k));
            if near_change {
                continue;
            }
            let d = (v[(j + m - 1) % m] + v[j] + v[(j + 1) % m]) / 3.0 - ring_mid;
            if (d > 0.0) != bright(k) {
                worst = worst.max(d.abs() / fit.beta);
            }
        }
    }
    worst
}

/// The band of radii (unit frame of the dot) the reading sampled.
fn band(reader: &RingReader, reading: &Reading) -> (f64, f64) {
    match reading.method {
        ReadMethod::Thresholds => reader.ring,
        ReadMethod::Model => {
            let (inner, outer) = reader.geometry;
            let (rho, step) = (
                reading.scale * 0.5 * (inner + outer),
                0.15 * (outer - inner),
            );
            (rho - step, rho + step)
        }
    }
}

/// The sector means (over the central 60 % of each sector, brightness − the dot's mid level) on
/// the inner and the outer half of the band the reading sampled (each on two radii: its edge
/// and a quarter of the band in).
fn radial_sectors(
    img: &GrayImage,
    dot: &Ellipse,
    fg: f32,
    bg: f32,
    reader: &RingReader,
    reading: &Reading,
) -> Vec<[f32; 24]> {
    const S: usize = SAMPLES_PER_SECTOR;
    let n = reader.table.bits as usize;
    let m = n * S;
    let mid = bg + 0.5 * (fg - bg);
    // the band the reading sampled, from `lo` to `hi`, cut in an inner and an outer half
    let (lo, hi) = band(reader, reading);
    let quarter = 0.25 * (hi - lo);
    let trig = crate::ellipse::unit_circle(m);
    let fr = dot.frame();
    let (q0, q1) = (S / 5, S - S / 5);
    [[lo, lo + quarter], [hi - quarter, hi]]
        .iter()
        .map(|half| {
            let mut y = [0.0f32; 24];
            for (k, yk) in y[..n].iter_mut().enumerate() {
                let mut acc = 0.0;
                for q in q0..q1 {
                    let (c, s) = trig[(reading.phi + k * S + q) % m];
                    for &r in half {
                        let (x, y) = fr.map(r * c, r * s);
                        acc += img.sample_inside(x, y) - mid;
                    }
                }
                *yk = acc / (2 * (q1 - q0)) as f32;
            }
            y
        })
        .collect()
}

/// Each sector's value on the scale of the ring's dark (0) and bright (1) levels, the blur's
/// spill undone: x̂ = M_ε⁻¹ (y − α) / β, M_ε the circulant matrix of 1 − 2ε on the diagonal and
/// ε to each neighbour (solved by Jacobi iterations, which converge as ε ≤ 0.12 < 1/4).
fn sector_values(y: &[f32], fit: &LevelFit) -> [f32; 24] {
    let n = y.len();
    let mut b = [0.0f32; 24];
    for (bk, yk) in b.iter_mut().zip(y) {
        *bk = (yk - fit.alpha) / fit.beta;
    }
    let eps = fit.eps;
    let mut x = b;
    // the error shrinks by 2ε / (1 − 2ε) ≤ 0.32 an iteration: 16 leave under 1e-7 of it
    let iterations = if eps > 0.0 { 16 } else { 0 };
    for _ in 0..iterations {
        let prev = x;
        for k in 0..n {
            x[k] = (b[k] - eps * (prev[(k + n - 1) % n] + prev[(k + 1) % n])) / (1.0 - 2.0 * eps);
        }
    }
    x
}

/// The Hamming distance from the pattern read to the nearest pattern of another number, and
/// the smallest Σ |x̂_k − ½| over the differing sectors (any other number, any rotation).
/// Every pattern of the table has an even number of bright sectors, so the patterns that
/// differ in d sectors are enumerated for d = 2, 4, …, until the d smallest |x̂_k − ½| alone
/// add up to more than the best found (no pattern farther away can be nearer in Σ).
fn nearest_other(x: &[f32], reading: &Reading, reader: &RingReader) -> (u32, f32) {
    let n = x.len();
    let w: Vec<f32> = x.iter().map(|v| (v - 0.5).abs()).collect();
    let mut sorted = w.clone();
    sorted.sort_by(|a, b| a.total_cmp(b));
    let (mut hamming, mut code) = (u32::MAX, f32::INFINITY);
    let mut d = 2;
    while d <= n && sorted[..d].iter().sum::<f32>() < code {
        // every set of d sectors, as the increasing indices in `idx`
        let mut idx: Vec<usize> = (0..d).collect();
        loop {
            let diff = idx.iter().fold(0u32, |m, &k| m | 1 << k);
            let sum: f32 = idx.iter().map(|&k| w[k]).sum();
            if sum < code
                && reader
                    .number_of_mask(reading.mask ^ diff)
                    .is_some_and(|id| id != reading.id)
            {
                code = sum;
                hamming = hamming.min(d as u32);
            }
            // the next set: the rightmost index that can move, moved, the rest after it
            let Some(i) = (0..d).rev().find(|&i| idx[i] < n - d + i) else {
                break;
            };
            idx[i] += 1;
            for j in i + 1..d {
                idx[j] = idx[j - 1] + 1;
            }
        }
        d += 2;
    }
    (hamming, code)
}

/// The fit of the ring model to the sector means: y_k ≈ α + β (M_ε x)_k.
struct LevelFit {
    alpha: f32,
    beta: f32,
    eps: f32,
}

/// The least-squares fit α + β (M_ε x) of `y`, x the sectors `mask`, at the spill ε ≤
/// [`EPS_MAX`] of the smallest residual (β infinite when no fit has β > 0).
fn fit_levels(y: &[f32], mask: u32) -> LevelFit {
    let n = y.len();
    let ybar = y.iter().sum::<f32>() / n as f32;
    let syy: f32 = y.iter().map(|v| (v - ybar).powi(2)).sum();
    let x = |k: usize| ((mask >> (k % n)) & 1) as f32;
    let mut best = (
        f32::INFINITY,
        LevelFit {
            alpha: 0.0,
            beta: f32::INFINITY,
            eps: 0.0,
        },
    );
    for eps in SPILLS.into_iter().filter(|&e| e <= EPS_MAX) {
        let xt: Vec<f32> = (0..n)
            .map(|k| (1.0 - 2.0 * eps) * x(k) + eps * (x(k + n - 1) + x(k + 1)))
            .collect();
        let xbar = xt.iter().sum::<f32>() / n as f32;
        let sxy: f32 = xt.iter().zip(y).map(|(a, b)| a * (b - ybar)).sum();
        let beta = sxy / blurred_sxx(mask, n, eps);
        if !(beta > 0.0) {
            continue;
        }
        let ssr = (syy - beta * sxy).max(0.0);
        if ssr < best.0 {
            let alpha = ybar - beta * xbar;
            best = (ssr, LevelFit { alpha, beta, eps });
        }
    }
    best.1
}

/// The deepest sample of the ring's profile on the wrong side of the ring's mid level α + β/2,
/// over β, leaving out the samples next to a change of polarity (3 of a sector's 16 for the
/// thresholds' reading, 6 for the model's, whose rings are blurred): a bright sliver in a dark
/// run or a dark gap in a bright one is a sector cut by something, not a ring.
fn profile_breaks(reading: &Reading, n: usize, fit: &LevelFit) -> f32 {
    const S: usize = SAMPLES_PER_SECTOR;
    let m = n * S;
    let zone = match reading.method {
        ReadMethod::Thresholds => S / 5,
        ReadMethod::Model => 6,
    };
    let mid = fit.alpha + 0.5 * fit.beta;
    let bright = |k: usize| reading.mask >> (k % n) & 1 == 1;
    let mut worst = 0.0f32;
    for j in 0..m {
        let rel = (j + m - reading.phi % m) % m;
        let (k, pos) = (rel / S, rel % S);
        let near_change = (pos < zone && bright(k + n - 1) != bright(k))
            || (pos >= S - zone && bright(k + 1) != bright(k));
        if near_change {
            continue;
        }
        let d = reading.profile[j] - mid;
        if (d > 0.0) != bright(k) {
            worst = worst.max(d.abs() / fit.beta);
        }
    }
    worst
}

/// How unevenly dark the surround of the ring is: on each of three circles, two in the gap
/// between dot and ring (0.3 and 0.6 of the way out) and one just outside the ring (a quarter
/// of a dot radius out), at the reading's scale, how far its 90th percentile lies above its
/// median, over the dot's contrast; the largest of the three. Something across the target (a
/// cable, a finger, another target's square or ring) shows on part of a circle; blur and
/// shading raise a whole circle evenly, which does not count.
fn surround_spread(
    img: &GrayImage,
    dot: &Ellipse,
    fg: f32,
    bg: f32,
    reader: &RingReader,
    reading: &Reading,
) -> f32 {
    const K: usize = 64;
    let trig = crate::ellipse::unit_circle(K);
    let fr = dot.frame();
    let (inner, outer) = reader.geometry;
    let mut worst = 0.0f32;
    for rho in [
        1.0 + 0.3 * (inner - 1.0),
        1.0 + 0.6 * (inner - 1.0),
        outer + 0.25,
    ] {
        let rho = rho * reading.scale;
        let mut v = [0.0f32; K];
        for (vk, &(c, s)) in v.iter_mut().zip(trig.iter()) {
            let (x, y) = fr.map(rho * c, rho * s);
            *vk = img.sample_inside(x, y);
        }
        v.sort_by(|a, b| a.total_cmp(b));
        worst = worst.max((v[K * 9 / 10] - v[K / 2]) / (fg - bg));
    }
    worst
}

/// The RMS distance (dot radii) of the ring's edges from the printed ring's circles, on the
/// rays through the middle of the bright sectors (see the module doc).
fn ring_fit(
    img: &GrayImage,
    dot: &Ellipse,
    fg: f32,
    bg: f32,
    reader: &RingReader,
    reading: &Reading,
) -> f32 {
    const S: usize = SAMPLES_PER_SECTOR;
    let n = reader.table.bits as usize;
    let m = n * S;
    let mid = bg + 0.5 * (fg - bg);
    let (inner, outer) = reader.geometry;
    let width = outer - inner;
    let (r_from, r_to) = (
        reader.gap_radius() * reading.scale,
        (outer + 0.55) * reading.scale,
    );
    // half a pixel a step, 0.01 to 0.05 dot radii
    let step = (0.5 / dot.radius()).clamp(0.01, 0.05);
    let steps = ((r_to - r_from) / step).ceil() as usize;
    let trig = crate::ellipse::unit_circle(m);
    let fr = dot.frame();
    let mut edges: Vec<(Option<f64>, Option<f64>)> = Vec::new();
    for k in (0..n).filter(|&k| reading.mask >> k & 1 == 1) {
        // three rays through the middle 40 % of the sector, averaged
        let rays =
            [S / 2 - S / 5, S / 2, S / 2 + S / 5].map(|q| trig[(reading.phi + k * S + q) % m]);
        let at = |r: f64| {
            rays.iter()
                .map(|&(c, s)| {
                    let (x, y) = fr.map(r * c, r * s);
                    img.sample_inside(x, y)
                })
                .sum::<f32>()
                / 3.0
                - mid
        };
        let profile: Vec<(f64, f32)> = (0..=steps)
            .map(|i| {
                let r = r_from + (r_to - r_from) * i as f64 / steps as f64;
                (r, at(r))
            })
            .collect();
        let cross = |a: (f64, f32), b: (f64, f32)| a.0 + (b.0 - a.0) * (a.1 / (a.1 - b.1)) as f64;
        // the inner edge: the first rise through the mid level from a dark start; the outer
        // edge: the last fall through it to a dark end
        let rise = (profile[0].1 < 0.0)
            .then(|| profile.windows(2).find(|w| w[0].1 < 0.0 && w[1].1 >= 0.0))
            .flatten()
            .map(|w| cross(w[0], w[1]));
        let fall = (profile[steps].1 < 0.0)
            .then(|| {
                profile
                    .windows(2)
                    .rev()
                    .find(|w| w[0].1 >= 0.0 && w[1].1 < 0.0)
            })
            .flatten()
            .map(|w| cross(w[0], w[1]));
        edges.push((rise, fall));
    }
    if edges.is_empty() {
        return f32::INFINITY;
    }
    // the common scale of the edges found, by least squares, within 0.85 to 1.25
    let (mut num, mut den) = (0.0, 0.0);
    for (a, b) in &edges {
        if let Some(a) = a {
            num += a * inner;
            den += inner * inner;
        }
        if let Some(b) = b {
            num += b * outer;
            den += outer * outer;
        }
    }
    let scale = if den > 0.0 {
        (num / den).clamp(0.85, 1.25)
    } else {
        1.0
    };
    let mut ss = 0.0;
    for (a, b) in &edges {
        ss += a.map_or(width * width, |a| (a - scale * inner).powi(2));
        ss += b.map_or(width * width, |b| (b - scale * outer).powi(2));
    }
    (ss / (2 * edges.len()) as f64).sqrt() as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A target of number 77 (dot radius 8 px, square of 4 dot radii) at the middle of a
    /// 200 px image of `paper`, with a black bar of 8 px from x = `bar.0` to `bar.1` (px from
    /// the centre) along its middle row, 4 × 4 supersampled.
    fn render(paper: f32, bar: (f64, f64)) -> GrayImage {
        let code = crate::aicon::CodeTable::generate(14)
            .unwrap()
            .code(77)
            .unwrap();
        let (w, c, rad) = (200usize, 100.0, 8.0);
        let mut img = GrayImage::new(w, w, paper);
        for y in 0..w {
            for x in 0..w {
                let mut acc = 0.0;
                for sy in 0..4 {
                    for sx in 0..4 {
                        let px = x as f64 - 0.5 + (sx as f64 + 0.5) / 4.0 - c;
                        let py = y as f64 - 0.5 + (sy as f64 + 0.5) / 4.0 - c;
                        let (u, v) = (px / rad, py / rad);
                        acc += if u.abs() <= 4.0 && v.abs() <= 4.0 {
                            if crate::printable::target_is_white(code, 14, u, v) {
                                0.8
                            } else {
                                0.05
                            }
                        } else if (bar.0..=bar.1).contains(&px) && py.abs() <= 4.0 {
                            0.03
                        } else {
                            paper
                        };
                    }
                }
                img.data[y * w + x] = acc / 16.0;
            }
        }
        img
    }

    /// The number and `outline` margin read at the target of [`render`] (or of its refusal).
    fn outline_of(img: &GrayImage) -> (Option<u32>, f32) {
        let det = crate::detect::Detector::new(crate::detect::DetectParams {
            balls: crate::detect::BallMode::Off,
            ..Default::default()
        })
        .unwrap();
        let found = det.detect(img);
        if let Some(t) = found.targets.iter().find(|t| t.id.is_some()) {
            return (t.id, t.read.unwrap().outline);
        }
        let r = found.refused.iter().find_map(|r| r.refused_read);
        (None, r.map_or(f32::NAN, |(_, m)| m.outline))
    }

    /// A target alone on paper has its square's outline; a black bar against its square on
    /// the paper makes it reach beyond, and the number is refused; on a black background (a
    /// dark panel) the same bar cannot be told from the background and nothing is refused.
    #[test]
    fn a_dark_print_beyond_the_square_on_paper_is_refused() {
        for paper in [0.35, 0.8] {
            assert_eq!(outline_of(&render(paper, (0.0, 0.0))), (Some(77), 0.0));
            let (id, outline) = outline_of(&render(paper, (30.0, 60.0)));
            assert_eq!(id, None, "paper {paper}: outline {outline}");
            assert!(
                outline > 2.0 * MAX_OUTLINE,
                "paper {paper}: outline {outline}"
            );
        }
        assert_eq!(outline_of(&render(0.03, (30.0, 60.0))), (Some(77), 0.0));
    }

    /// The blur's spill is undone exactly: sector means made by the ring model α + β (M_ε x)
    /// from a pattern x give back x, at every spill the model knows, and the fit finds α, β.
    #[test]
    fn the_sector_values_undo_the_blur_of_the_ring_model() {
        let n = 14;
        let mask: u32 = 0b10_1100_1110_0100;
        let x = |k: usize| ((mask >> (k % n)) & 1) as f32;
        for eps in SPILLS.into_iter().filter(|&e| e <= EPS_MAX) {
            let (alpha, beta) = (-0.3f32, 0.7f32);
            let y: Vec<f32> = (0..n)
                .map(|k| {
                    alpha + beta * ((1.0 - 2.0 * eps) * x(k) + eps * (x(k + n - 1) + x(k + 1)))
                })
                .collect();
            let fit = fit_levels(&y, mask);
            assert!((fit.alpha - alpha).abs() < 1e-5 && (fit.beta - beta).abs() < 1e-5);
            assert_eq!(fit.eps, eps);
            let v = sector_values(&y, &fit);
            for (k, vk) in v[..n].iter().enumerate() {
                assert!((vk - x(k)).abs() < 1e-4, "ε {eps}, sector {k}: {vk}");
            }
        }
    }
}
