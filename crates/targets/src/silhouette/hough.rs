//! Circle candidates from edge points: a Hough transform of the centre along each edge
//! point's gradient axis, then the radius at each centre.
//!
//! Every edge point of an [`EdgeMap`] votes for the centres at distances `d ∈ [r_min, r_max]`
//! (the scale's pixels, one vote per pixel of `d`) on both sides along its gradient axis (a
//! ball may be brighter or darker than what is behind it, and both on one outline), each
//! vote weighing `1/d`: the edge points of a whole circle of any radius then add up to 2π at
//! its centre, so small and large circles compete fairly, while texture spreads its votes.
//! The accumulator, smoothed by a 3 × 3 box, gives the peaks; at each, the radius is the one
//! whose ring of ±1 px holds the most edge points pointing at the centre (within 25°), as a
//! fraction of the ring's length inside the image: the circle's support.
//!
//! Work: `O(edge points · (r_max − r_min))` for the votes and `O(peaks · edge points)` for
//! the radii, whatever the image shows.

use super::edges::EdgeMap;

/// A circle of the image, pixels (origin at the centre of the top-left pixel).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Circle {
    /// Centre, column.
    pub cx: f64,
    /// Centre, row.
    pub cy: f64,
    /// Radius.
    pub r: f64,
    /// The fraction of its length inside the image that edge points cover (about 1 for a
    /// whole clean outline).
    pub support: f64,
}

/// Where to look: centres within `reach` px of (`cx`, `cy`), radii in `radius_px`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Search {
    /// The radii of the outlines looked for, image px.
    pub radius_px: (f64, f64),
    /// The centre of the window looked in and its radius, image px (`None`: anywhere a
    /// centre can be, up to a quarter of the largest radius beyond the border).
    pub window: Option<(f64, f64, f64)>,
}

/// Cosine of the largest angle between an edge point's axis and its direction to a centre.
const RADIAL_COS: f32 = 0.906; // 25°

/// The candidate circles of `edges` within `search`, at most `max`, by decreasing support.
pub fn circles(edges: &EdgeMap, search: &Search, max: usize) -> Vec<Circle> {
    let s = edges.scale as f64;
    let (r0, r1) = (search.radius_px.0 / s, search.radius_px.1 / s);
    if !(r1 >= r0 && r0 >= 2.0) || edges.points.is_empty() {
        return Vec::new();
    }
    // centre of a scale pixel x in image pixels: x·s + (s − 1)/2
    let off = (s - 1.0) / 2.0;
    let to_scale = |v: f64| (v - off) / s;
    let margin = (0.25 * r1).ceil() as isize;
    let (w, h) = (
        edges.width as isize + 2 * margin,
        edges.height as isize + 2 * margin,
    );
    let window = search
        .window
        .map(|(x, y, reach)| (to_scale(x), to_scale(y), reach / s + 1.0));
    let mut acc = vec![0.0f32; (w * h) as usize];
    let (d0, d1) = (r0.floor().max(1.0) as usize, r1.ceil() as usize);
    for p in &edges.points {
        if let Some((wx, wy, reach)) = window {
            let dist = ((p.x as f64 - wx).powi(2) + (p.y as f64 - wy).powi(2)).sqrt();
            if dist > reach + r1 + 1.0 || dist < r0 - reach - 1.0 {
                continue;
            }
        }
        for d in d0..=d1 {
            let wgt = 1.0 / d as f32;
            for sign in [-1.0f32, 1.0] {
                let x = (p.x + sign * d as f32 * p.ux).round() as isize + margin;
                let y = (p.y + sign * d as f32 * p.uy).round() as isize + margin;
                if x >= 0 && y >= 0 && x < w && y < h {
                    acc[(y * w + x) as usize] += wgt;
                }
            }
        }
    }
    let acc = box3(&box3(&acc, w as usize, h as usize), w as usize, h as usize);
    let peaks = peaks(&acc, w as usize, h as usize, (r0 / 2.0).max(2.0), 3 * max);
    let mut out: Vec<Circle> = peaks
        .into_iter()
        .filter_map(|(x, y)| {
            let (cx, cy) = ((x as isize - margin) as f64, (y as isize - margin) as f64);
            if let Some((wx, wy, reach)) = window {
                if (cx - wx).powi(2) + (cy - wy).powi(2) > reach * reach {
                    return None;
                }
            }
            let (r, support) = radius_at(edges, cx, cy, d0, d1)?;
            Some(Circle {
                cx: cx * s + off,
                cy: cy * s + off,
                r: r * s,
                support,
            })
        })
        .collect();
    out.sort_by(|a, b| b.support.total_cmp(&a.support));
    out.truncate(max);
    out
}

/// A 3 × 3 box filter (the border as if repeated).
fn box3(a: &[f32], w: usize, h: usize) -> Vec<f32> {
    let mut tmp = vec![0.0f32; w * h];
    for y in 0..h {
        let row = &a[y * w..(y + 1) * w];
        for x in 0..w {
            let l = row[x.saturating_sub(1)];
            let r = row[(x + 1).min(w - 1)];
            tmp[y * w + x] = l + row[x] + r;
        }
    }
    let mut out = vec![0.0f32; w * h];
    for y in 0..h {
        let (u, d) = (y.saturating_sub(1), (y + 1).min(h - 1));
        for x in 0..w {
            out[y * w + x] = (tmp[u * w + x] + tmp[y * w + x] + tmp[d * w + x]) / 9.0;
        }
    }
    out
}

/// The highest cells, each at least `sep` cells from a higher one kept, at most `n`.
fn peaks(acc: &[f32], w: usize, _h: usize, sep: f64, n: usize) -> Vec<(usize, usize)> {
    // candidates: cells above the 99.5th percentile of a sample, at most 50 000
    let step = (acc.len() / 20_000).max(1);
    let mut sample: Vec<f32> = acc.iter().step_by(step).copied().collect();
    if sample.is_empty() {
        return Vec::new();
    }
    let k = (sample.len() * 995 / 1000).min(sample.len() - 1);
    let level = *sample.select_nth_unstable_by(k, |a, b| a.total_cmp(b)).1;
    let mut cells: Vec<(f32, usize)> = acc
        .iter()
        .enumerate()
        .filter(|(_, v)| **v > level && **v > 0.0)
        .map(|(i, v)| (*v, i))
        .collect();
    cells.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    cells.truncate(50_000);
    let mut kept: Vec<(usize, usize)> = Vec::new();
    let sep2 = sep * sep;
    for (_, i) in cells {
        let (x, y) = (i % w, i / w);
        let near = kept.iter().any(|&(a, b)| {
            let (dx, dy) = (a as f64 - x as f64, b as f64 - y as f64);
            dx * dx + dy * dy < sep2
        });
        if !near {
            kept.push((x, y));
            if kept.len() >= n {
                break;
            }
        }
    }
    kept
}

/// The radius (scale px) at centre (cx, cy) whose ring of ±1 px holds the most edge points
/// pointing at the centre, as a fraction of the ring's length inside the image; `None`
/// when no ring has any.
fn radius_at(edges: &EdgeMap, cx: f64, cy: f64, d0: usize, d1: usize) -> Option<(f64, f64)> {
    let mut hist = vec![0.0f64; d1 + 3];
    let mut sum_d = vec![0.0f64; d1 + 3];
    for p in &edges.points {
        let (dx, dy) = (p.x as f64 - cx, p.y as f64 - cy);
        let d = (dx * dx + dy * dy).sqrt();
        if d < d0 as f64 - 1.0 || d > d1 as f64 + 1.0 || d < 1.0 {
            continue;
        }
        let cos = ((p.ux as f64 * dx + p.uy as f64 * dy) / d).abs();
        if cos < RADIAL_COS as f64 {
            continue;
        }
        let b = d.round() as usize;
        hist[b] += 1.0;
        sum_d[b] += d;
    }
    let mut best: Option<(f64, f64)> = None;
    for d in d0.max(1)..=d1 {
        let n = hist[d - 1] + hist[d] + hist[d + 1];
        if n < 6.0 {
            continue;
        }
        let inside = visible_fraction(cx, cy, d as f64, edges.width, edges.height);
        if inside < 0.25 {
            continue;
        }
        // an 8-connected digital circle of radius d has about 4√2·d pixels
        let support = n / (4.0 * std::f64::consts::SQRT_2 * d as f64 * inside);
        if best.is_none_or(|(_, s)| support > s) {
            let r = (sum_d[d - 1] + sum_d[d] + sum_d[d + 1]) / n;
            best = Some((r, support));
        }
    }
    best
}

/// The fraction of the circle (cx, cy, r) inside a `w × h` image (64 points).
pub fn visible_fraction(cx: f64, cy: f64, r: f64, w: usize, h: usize) -> f64 {
    let n = 64;
    let inside = (0..n)
        .filter(|&k| {
            let t = std::f64::consts::TAU * k as f64 / n as f64;
            let (x, y) = (cx + r * t.cos(), cy + r * t.sin());
            x >= 0.0 && y >= 0.0 && x <= w as f64 - 1.0 && y <= h as f64 - 1.0
        })
        .count();
    inside as f64 / n as f64
}

#[cfg(test)]
mod tests {
    use super::super::edges::{edge_map, ColourImage};
    use super::*;
    use crate::raster::GrayImage;

    fn disc(img: &mut GrayImage, cx: f64, cy: f64, r: f64, v: f32) {
        for y in 0..img.height {
            for x in 0..img.width {
                let d = ((x as f64 - cx).powi(2) + (y as f64 - cy).powi(2)).sqrt();
                let a = (r + 0.5 - d).clamp(0.0, 1.0) as f32;
                let o = &mut img.data[y * img.width + x];
                *o = *o * (1.0 - a) + v * a;
            }
        }
    }

    #[test]
    fn two_discs_of_different_sizes_and_contrasts_are_both_found() {
        let mut img = GrayImage::new(320, 240, 0.4);
        disc(&mut img, 90.4, 110.2, 48.0, 0.8);
        disc(&mut img, 240.7, 80.3, 17.0, 0.1);
        // a straight edge and a square as clutter
        for y in 150..240 {
            for x in 180..300 {
                img.data[y * 320 + x] = 0.7;
            }
        }
        let e = edge_map(&ColourImage::grey(img), 1);
        let c = circles(
            &e,
            &Search {
                radius_px: (10.0, 60.0),
                window: None,
            },
            6,
        );
        for (x, y, r) in [(90.4, 110.2, 48.0), (240.7, 80.3, 17.0)] {
            let hit = c
                .iter()
                .find(|k| (k.cx - x).abs() < 1.5 && (k.cy - y).abs() < 1.5);
            let hit = hit.unwrap_or_else(|| panic!("no circle at ({x}, {y}): {c:?}"));
            assert!((hit.r - r).abs() < 1.5 && hit.support > 0.7, "{hit:?}");
        }
        // at scale 2 too
        let mut img = GrayImage::new(320, 240, 0.4);
        disc(&mut img, 150.0, 120.0, 60.0, 0.8);
        let e = edge_map(&ColourImage::grey(img), 2);
        let c = circles(
            &e,
            &Search {
                radius_px: (30.0, 100.0),
                window: None,
            },
            3,
        );
        assert!(
            (c[0].cx - 150.0).abs() < 2.0 && (c[0].r - 60.0).abs() < 2.5,
            "{c:?}"
        );
    }

    #[test]
    fn the_visible_fraction_of_a_circle_cut_by_the_border() {
        assert_eq!(visible_fraction(50.0, 50.0, 10.0, 100, 100), 1.0);
        let half = visible_fraction(0.0, 50.0, 10.0, 100, 100);
        assert!((half - 0.5).abs() < 0.04, "{half}");
    }
}
