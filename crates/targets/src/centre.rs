//! Sub-pixel centre of a circular target: sub-pixel edge points along rays, a robust ellipse
//! fit to them, and the intensity-weighted centroid, each with an estimate of its σ in pixels.

use crate::ellipse::{fit_ellipse, sampson, unit_circle, Ellipse};
use crate::image_io::GrayImage;
use crate::threshold::foreground_level;

/// Why a candidate was not accepted as a target.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reject {
    /// Too many samples at the saturation level: the edge would be biased outward.
    Saturated,
    /// Edge rays leave the image: the target is cut by the border.
    Clipped,
    /// The target is not brighter than its surroundings by enough.
    LowContrast,
    /// Too few edge points were found.
    FewEdges,
    /// The edge points are not an ellipse (partly covered, merged, ragged).
    BadFit,
}

/// Settings of the centre refinement.
#[derive(Clone, Debug)]
pub struct CentreParams {
    /// Minimum foreground − background contrast (grey units, image in [0, 1]).
    pub min_contrast: f32,
    /// Grey level treated as saturated.
    pub saturation: f32,
    /// Largest accepted fraction of saturated samples inside the target.
    pub max_saturated_fraction: f64,
    /// Where on the edge ramp the edge is put: 0.5 = half way between inside and outside.
    pub edge_fraction: f32,
    /// Background search window, in units of the seed ellipse's radius.
    pub bg_window: (f64, f64),
    /// Largest accepted fraction of rejected edge rays.
    pub max_outlier_fraction: f64,
    /// Largest accepted RMS of edge residuals, pixels, plus this fraction of the radius.
    pub max_rms: (f64, f64),
}

impl Default for CentreParams {
    fn default() -> Self {
        CentreParams {
            min_contrast: 0.03,
            saturation: 0.995,
            max_saturated_fraction: 0.2,
            edge_fraction: 0.5,
            bg_window: (0.8, 1.6),
            max_outlier_fraction: 0.2,
            max_rms: (0.35, 0.03),
        }
    }
}

/// A refined target centre.
#[derive(Clone, Debug)]
pub struct Refined {
    /// Ellipse fitted to the sub-pixel edge points.
    pub ellipse: Ellipse,
    /// σ of the ellipse centre, pixels (from the edge residuals).
    pub sigma_ellipse: f64,
    /// Intensity-weighted centroid.
    pub centroid: (f64, f64),
    /// σ of the centroid, pixels (from the image noise).
    pub sigma_centroid: f64,
    /// Foreground level: the target's brightness, in the image's [0, 1] grey scale.
    pub fg: f32,
    /// Background level: the mean over the edge rays of the dark surround, same scale.
    pub bg: f32,
    /// Number of edge points the ellipse fit kept (its inliers).
    pub n_edges: usize,
    /// RMS of those edge points' residuals to the ellipse, pixels.
    pub rms_edge: f64,
    /// The share of the samples inside the seed outline at the saturation level.
    pub saturated: f64,
}

/// Which of the two refinement rounds [`edge_points`] serves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Round {
    /// From the rough seed outline (a moment ellipse): one ray per 2 px of perimeter (at least
    /// 24), the edge searched from 0.45 of the way out. Only the next round's outline comes of it.
    Seed,
    /// From an ellipse already fitted to edges: one ray per pixel of perimeter (24 to 256), the
    /// edge searched from [`EDGE_SEARCH_INSIDE_PX`] inside the outline (or 0.45 of the way out,
    /// whichever is further out).
    Final,
}

/// How far inside the previous round's outline the final round starts looking for the edge,
/// pixels: more than the half-width of the edge ramp of a target blurred by σ = 1.5 px, so the
/// upper shoulder of the ramp is always searched.
pub const EDGE_SEARCH_INSIDE_PX: f64 = 3.0;

/// Sampling step along a ray where the edge is located, pixels.
const EDGE_STEP_PX: f64 = 0.25;

/// The edge is first bracketed with steps of this many [`EDGE_STEP_PX`] (1 px).
const EDGE_STEPS_PER_PX: usize = 4;

/// Largest sampling step along a ray in the background window, pixels (the window is sampled at
/// least 8 times).
const BG_STEP_PX: f64 = 1.0;

/// Sub-pixel edge points along rays from the centre of `seed` through its outline, where the
/// profile crosses the level between `fg` and the per-ray background.
///
/// Per ray, at parameter t (t = 1 on the outline): the background is the minimum of the
/// bilinearly interpolated profile sampled every ≤ 1 px over t ∈ `p.bg_window`; the level is
/// `fg + p.edge_fraction·(bg − fg)` (the per-ray adaptive threshold of [`crate::threshold`]);
/// the edge is the first downward crossing of that level going outward from the round's start
/// (see [`Round`]): bracketed by 1-px steps (a dip below the level narrower than a pixel before
/// the edge is stepped over), then located by 0.25-px steps inside the bracket and interpolated
/// linearly between the two samples either side of it. Rays with less than `p.min_contrast` or without a crossing
/// before the end of the background window give no point.
/// Returns the points and the mean background, or a rejection.
pub fn edge_points(
    img: &GrayImage,
    seed: &Ellipse,
    fg: f32,
    p: &CentreParams,
    round: Round,
) -> Result<(Vec<(f64, f64)>, f32), Reject> {
    let r = seed.radius();
    let perimeter = 2.0 * std::f64::consts::PI * r;
    let k = match round {
        Round::Seed => ((perimeter / 2.0).round() as usize).clamp(24, 128),
        Round::Final => (perimeter.round() as usize).clamp(24, 256),
    };
    let (t_lo, t_hi) = p.bg_window;
    if !img.inside(seed.cx - seed.a * t_hi, seed.cy - seed.a * t_hi, 1.0)
        || !img.inside(seed.cx + seed.a * t_hi, seed.cy + seed.a * t_hi, 1.0)
    {
        return Err(Reject::Clipped);
    }
    let mut pts = Vec::with_capacity(k);
    let mut bg_sum = 0.0f64;
    let trig = unit_circle(k);
    let fr = seed.frame();
    for &(u, v) in trig.iter() {
        let (ex, ey) = fr.map(u, v);
        let (dx, dy) = (ex - seed.cx, ey - seed.cy);
        let len = (dx * dx + dy * dy).sqrt();
        if !(len > 0.0) {
            continue;
        }
        // The whole ray is inside the image (checked above).
        let at = |t: f64| img.sample_inside(seed.cx + t * dx, seed.cy + t * dy);
        let n_bg = (((t_hi - t_lo) * len / BG_STEP_PX).ceil() as usize).max(8);
        let mut bg = f32::INFINITY;
        for i in 0..=n_bg {
            bg = bg.min(at(t_lo + (t_hi - t_lo) * i as f64 / n_bg as f64));
        }
        if !(fg - bg >= p.min_contrast) {
            continue;
        }
        let level = fg + p.edge_fraction * (bg - fg);
        let t0 = match round {
            Round::Seed => 0.45,
            Round::Final => (1.0 - EDGE_SEARCH_INSIDE_PX / len).max(0.45),
        };
        // First downward crossing of `level` going outward: 1-px steps until a sample is
        // below the level, then 0.25-px steps from the last sample above it.
        let dt = EDGE_STEP_PX / len;
        let coarse = EDGE_STEPS_PER_PX as f64 * dt;
        let mut t = t0;
        let mut prev = at(t);
        let mut found = None;
        'search: while t < t_hi {
            let tc = (t + coarse).min(t_hi);
            let sc = at(tc);
            if prev >= level && sc >= level {
                (t, prev) = (tc, sc);
                continue;
            }
            // A crossing lies in (t, tc] (or, when `prev` is already below the level, the
            // profile may rise and fall again there).
            while t < tc {
                let tn = (t + dt).min(tc);
                let s = if tn == tc { sc } else { at(tn) };
                if prev >= level && s < level {
                    let f = (prev - level) / (prev - s);
                    found = Some(t + f as f64 * (tn - t));
                    break 'search;
                }
                (t, prev) = (tn, s);
            }
        }
        if let Some(te) = found {
            pts.push((seed.cx + te * dx, seed.cy + te * dy));
            bg_sum += bg as f64;
        }
    }
    if pts.len() < 12 || pts.len() * 10 < k * 6 {
        return Err(Reject::FewEdges);
    }
    let bg = (bg_sum / pts.len() as f64) as f32;
    Ok((pts, bg))
}

/// Robust ellipse fit: fit, drop points whose residual exceeds max(3·1.48·MAD, 0.25 px), refit.
/// Returns the ellipse, the inlier residual RMS and the number of inliers.
pub fn robust_ellipse_fit(pts: &[(f64, f64)]) -> Option<(Ellipse, f64, usize)> {
    let e = fit_ellipse(pts)?;
    let k = e.conic();
    let res: Vec<f64> = pts.iter().map(|p| sampson(&k, p.0, p.1)).collect();
    let mut abs: Vec<f64> = res.iter().map(|r| r.abs()).collect();
    let mid = abs.len() / 2;
    let mad = *abs.select_nth_unstable_by(mid, |a, b| a.total_cmp(b)).1;
    let lim = (3.0 * 1.4826 * mad).max(0.25);
    let inl: Vec<(f64, f64)> = pts
        .iter()
        .zip(&res)
        .filter(|(_, r)| r.abs() <= lim)
        .map(|(p, _)| *p)
        .collect();
    let e2 = if inl.len() < pts.len() {
        fit_ellipse(&inl)?
    } else {
        e
    };
    let k2 = e2.conic();
    let ss: f64 = inl.iter().map(|p| sampson(&k2, p.0, p.1).powi(2)).sum();
    let rms = (ss / (inl.len().saturating_sub(5).max(1)) as f64).sqrt();
    Some((e2, rms, inl.len()))
}

/// Refines a candidate whose rough outline is `seed`: two rounds of edge points + robust
/// ellipse fit, then the intensity-weighted centroid.
pub fn refine(img: &GrayImage, seed: &Ellipse, p: &CentreParams) -> Result<Refined, Reject> {
    let (fg, sat) = foreground_level(img, seed, p.saturation);
    if sat > p.max_saturated_fraction {
        return Err(Reject::Saturated);
    }
    let mut cur = *seed;
    let mut out = None;
    for round in [Round::Seed, Round::Final] {
        let (pts, bg) = edge_points(img, &cur, fg, p, round)?;
        if fg - bg < p.min_contrast {
            return Err(Reject::LowContrast);
        }
        let (e, rms, n_in) = robust_ellipse_fit(&pts).ok_or(Reject::BadFit)?;
        let moved = ((e.cx - cur.cx).powi(2) + (e.cy - cur.cy).powi(2)).sqrt();
        if !(e.b > 0.3)
            || e.b / e.a < 0.15
            || moved > 0.5 * cur.radius() + 1.0
            || e.a > 2.0 * cur.a + 2.0
        {
            return Err(Reject::BadFit);
        }
        let outliers = 1.0 - n_in as f64 / pts.len() as f64;
        if outliers > p.max_outlier_fraction || rms > p.max_rms.0 + p.max_rms.1 * e.radius() {
            return Err(Reject::BadFit);
        }
        cur = e;
        out = Some((e, rms, n_in, bg));
    }
    let (e, rms, n_in, bg) = out.ok_or(Reject::BadFit)?;
    // Centre σ of an ellipse fitted to n points with independent radial errors σ_e is about
    // σ_e·√(2/n); edge points closer than a pixel along the outline are not independent, so n is
    // capped by the perimeter in pixels.
    let perim = 2.0 * std::f64::consts::PI * e.radius();
    let n_eff = (n_in as f64).min(perim).max(1.0);
    let sigma_ellipse = rms * (2.0 / n_eff).sqrt();
    let (centroid, sigma_centroid) = weighted_centroid(img, &e, bg, fg);
    Ok(Refined {
        ellipse: e,
        sigma_ellipse,
        centroid,
        sigma_centroid,
        fg,
        bg,
        n_edges: n_in,
        rms_edge: rms,
        saturated: sat,
    })
}

/// The pixel columns `x0..=x1` of row `y` whose centres lie inside the ellipse (none when the
/// row misses it), clipped to `0..width`.
fn row_span(e: &Ellipse, y: usize, width: usize) -> Option<(usize, usize)> {
    // (x, y) is inside when u² + v² ≤ 1 (see `Ellipse::unmap`); with dx = x − cx and dy fixed
    // that is the quadratic α·dx² + β·dx + γ ≤ 0.
    let (s, c) = e.theta.sin_cos();
    let (ia2, ib2) = (1.0 / (e.a * e.a), 1.0 / (e.b * e.b));
    let dy = y as f64 - e.cy;
    let alpha = c * c * ia2 + s * s * ib2;
    let beta = 2.0 * dy * c * s * (ia2 - ib2);
    let gamma = dy * dy * (s * s * ia2 + c * c * ib2) - 1.0;
    let disc = beta * beta - 4.0 * alpha * gamma;
    if !(disc >= 0.0) || !(alpha > 0.0) {
        return None;
    }
    let r = disc.sqrt();
    let lo = e.cx + (-beta - r) / (2.0 * alpha);
    let hi = e.cx + (-beta + r) / (2.0 * alpha);
    let x0 = lo.ceil().max(0.0);
    let x1 = hi.floor().min(width as f64 - 1.0);
    (x0 <= x1).then_some((x0 as usize, x1 as usize))
}

/// Intensity-weighted centroid over the pixels whose centres lie within 1.15× the ellipse,
/// weights max(I − bg, 0). σ from the noise of the foreground (MAD of horizontal neighbour
/// differences inside 0.6× the ellipse).
pub fn weighted_centroid(img: &GrayImage, e: &Ellipse, bg: f32, fg: f32) -> ((f64, f64), f64) {
    let ext = e.scaled(1.15);
    let y0 = ((e.cy - ext.a).floor().max(0.0)) as usize;
    let y1 = ((e.cy + ext.a).ceil().max(0.0) as usize).min(img.height.saturating_sub(1));
    let (mut sw, mut sx, mut sy) = (0.0f64, 0.0f64, 0.0f64);
    // Unweighted sums over the same pixels, for the spread Σ(x − cx)² below.
    let (mut n, mut px, mut py, mut pxx, mut pyy) = (0.0f64, 0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for y in y0..=y1 {
        let Some((x0, x1)) = row_span(&ext, y, img.width) else {
            continue;
        };
        let row = &img.data[y * img.width..(y + 1) * img.width];
        let yf = y as f64;
        let (mut rw, mut rx) = (0.0f64, 0.0f64);
        for (x, &v) in row.iter().enumerate().take(x1 + 1).skip(x0) {
            let w = (v - bg).max(0.0) as f64;
            rw += w;
            rx += w * x as f64;
        }
        sw += rw;
        sx += rx;
        sy += rw * yf;
        let (a, b) = (x0 as f64, x1 as f64);
        let k = b - a + 1.0;
        n += k;
        px += (a + b) * k / 2.0;
        pxx += (b * (b + 1.0) * (2.0 * b + 1.0) - (a - 1.0) * a * (2.0 * a - 1.0)) / 6.0;
        py += yf * k;
        pyy += yf * yf * k;
    }
    if sw <= 0.0 {
        return ((e.cx, e.cy), f64::INFINITY);
    }
    let (cx, cy) = (sx / sw, sy / sw);
    // Noise: MAD of horizontal neighbour differences inside the inner 0.6 (flat region),
    // divided by √2 for the difference of two samples.
    let inner = e.scaled(0.6);
    let mut d = Vec::new();
    for y in y0..=y1 {
        let Some((x0, x1)) = row_span(&inner, y, img.width.saturating_sub(1)) else {
            continue;
        };
        let row = &img.data[y * img.width..(y + 1) * img.width];
        for x in x0..=x1 {
            d.push((row[x + 1] - row[x]).abs() as f64);
        }
    }
    let sigma_n = if d.len() >= 5 {
        let mid = d.len() / 2;
        let (_, m, _) = d.select_nth_unstable_by(mid, |a, b| a.total_cmp(b));
        1.4826 * *m / std::f64::consts::SQRT_2
    } else {
        0.0
    };
    // Var(cx) = σ_n² Σ (x − cx)² / (Σw)², plus the same for y; report the mean of both.
    let sxx = pxx - 2.0 * cx * px + n * cx * cx;
    let syy = pyy - 2.0 * cy * py + n * cy * cy;
    let s = sigma_n * ((sxx.max(0.0) + syy.max(0.0)) / 2.0).sqrt() / sw;
    let _ = fg;
    ((cx, cy), s)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The centroid and its σ by testing every pixel of the bounding box (the definition).
    fn centroid_by_pixels(img: &GrayImage, e: &Ellipse, bg: f32) -> ((f64, f64), f64) {
        let (ext, inner) = (e.scaled(1.15), e.scaled(0.6));
        let inside = |el: &Ellipse, x: usize, y: usize| {
            let (u, v) = el.unmap(x as f64, y as f64);
            u * u + v * v <= 1.0
        };
        let (mut sw, mut sx, mut sy, mut pix, mut d) = (0.0, 0.0, 0.0, vec![], vec![]);
        for y in 0..img.height {
            for x in 0..img.width {
                if inside(&ext, x, y) {
                    let w = (img.get(x, y) - bg).max(0.0) as f64;
                    (sw, sx, sy) = (sw + w, sx + w * x as f64, sy + w * y as f64);
                    pix.push((x, y));
                }
                if inside(&inner, x, y) && x + 1 < img.width {
                    d.push((img.get(x + 1, y) - img.get(x, y)).abs() as f64);
                }
            }
        }
        let (cx, cy) = (sx / sw, sy / sw);
        d.sort_by(|a, b| a.total_cmp(b));
        let sn = if d.len() >= 5 {
            1.4826 * d[d.len() / 2] / std::f64::consts::SQRT_2
        } else {
            0.0
        };
        let ss: f64 = pix
            .iter()
            .map(|&(x, y)| (x as f64 - cx).powi(2) + (y as f64 - cy).powi(2))
            .sum();
        ((cx, cy), sn * (ss / 2.0).sqrt() / sw)
    }

    #[test]
    fn weighted_centroid_by_row_spans_equals_the_pixel_definition() {
        let mut seed = 7u64;
        let mut rnd = move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        for _ in 0..200 {
            let (w, h) = (64, 48);
            let mut img = GrayImage::new(w, h, 0.0);
            for v in img.data.iter_mut() {
                *v = 0.1 + 0.8 * rnd() as f32;
            }
            let a = 2.0 + 12.0 * rnd();
            let e = Ellipse {
                cx: 4.0 + 56.0 * rnd(),
                cy: 4.0 + 40.0 * rnd(),
                a,
                b: a * (0.2 + 0.8 * rnd()),
                theta: 3.2 * rnd(),
            };
            let ((x, y), s) = weighted_centroid(&img, &e, 0.3, 0.9);
            let ((xr, yr), sr) = centroid_by_pixels(&img, &e, 0.3);
            assert!((x - xr).abs() < 1e-9 && (y - yr).abs() < 1e-9, "{e:?}");
            assert!(
                (s - sr).abs() <= 1e-9 * sr.max(1e-9),
                "{e:?}: σ {s} vs {sr}"
            );
        }
    }
}
