//! Connected components of thresholded images (8-connectivity, run-length based, one pass
//! plus union-find), with the statistics the shape tests need: area, bounding box, first and
//! second moments, and whether the component touches the image border.
//!
//! [`components_at_levels`] labels the components above every rung of a threshold ladder in
//! one pass over the image. Per row, each block of 32 pixels is first tested against the lowest
//! rung (one vector comparison per 4 pixels); only blocks with a pixel above it get a bit mask
//! per rung, rung after rung until a mask is empty (a pixel above a rung is above every lower
//! one). The masks give the runs of the row for every rung, and each rung's runs are labelled
//! against that rung's runs of the previous row. Nothing per pixel is stored, and on these
//! images (a few bright targets on a dark background) most blocks cost one test.

use crate::ellipse::Ellipse;
use crate::image_io::GrayImage;

/// Statistics of one connected component. Coordinates are pixel centres (x right, y down).
#[derive(Clone, Debug)]
pub struct Blob {
    pub area: usize,
    pub x_min: usize,
    pub x_max: usize,
    pub y_min: usize,
    pub y_max: usize,
    sx: f64,
    sy: f64,
    sxx: f64,
    sxy: f64,
    syy: f64,
    /// The threshold at which the component was extracted.
    pub level: f32,
}

impl Blob {
    /// Centroid (unweighted).
    pub fn centroid(&self) -> (f64, f64) {
        let n = self.area as f64;
        (self.sx / n, self.sy / n)
    }

    /// Ellipse with the same second moments (the pixel-quantisation variance 1/12 removed).
    pub fn moment_ellipse(&self) -> Option<Ellipse> {
        let n = self.area as f64;
        let (cx, cy) = self.centroid();
        let mxx = self.sxx / n - cx * cx + 1.0 / 12.0;
        let myy = self.syy / n - cy * cy + 1.0 / 12.0;
        let mxy = self.sxy / n - cx * cy;
        Ellipse::from_moments(cx, cy, mxx, mxy, myy)
    }

    /// Area over the area of the moment ellipse: 1 for a filled ellipse, smaller for arcs,
    /// rings and ragged shapes.
    pub fn fill_ratio(&self) -> f64 {
        match self.moment_ellipse() {
            Some(e) => self.area as f64 / (std::f64::consts::PI * e.a * e.b),
            None => 0.0,
        }
    }

    /// True when the component touches the outermost pixels of a `w`×`h` image.
    pub fn touches_border(&self, w: usize, h: usize) -> bool {
        self.x_min == 0 || self.y_min == 0 || self.x_max + 1 >= w || self.y_max + 1 >= h
    }
}

/// Area, bounding box and the moment sums Σx, Σy, Σx², Σxy, Σy² of a set of pixels, as
/// integers: exact (for any component of an image with w·h·max(w, h)² < 2⁶⁴, e.g. up to
/// 60 000 × 60 000 px), so the order in which runs and partial components are added up does
/// not matter, and a [`Blob`]'s `f64` sums, converted at the end, are the exact sums rounded
/// once (the exact sums themselves below 2⁵³).
#[derive(Clone, Copy, Debug)]
struct Sums {
    area: u64,
    sx: u64,
    sy: u64,
    sxx: u64,
    sxy: u64,
    syy: u64,
    x_min: u32,
    x_max: u32,
    y_min: u32,
    y_max: u32,
}

impl Sums {
    #[inline]
    fn add(&mut self, o: &Sums) {
        self.area += o.area;
        self.sx += o.sx;
        self.sy += o.sy;
        self.sxx += o.sxx;
        self.sxy += o.sxy;
        self.syy += o.syy;
        self.x_min = self.x_min.min(o.x_min);
        self.x_max = self.x_max.max(o.x_max);
        self.y_min = self.y_min.min(o.y_min);
        self.y_max = self.y_max.max(o.y_max);
    }

    fn blob(&self, level: f32) -> Blob {
        Blob {
            area: self.area as usize,
            x_min: self.x_min as usize,
            x_max: self.x_max as usize,
            y_min: self.y_min as usize,
            y_max: self.y_max as usize,
            sx: self.sx as f64,
            sy: self.sy as f64,
            sxx: self.sxx as f64,
            sxy: self.sxy as f64,
            syy: self.syy as f64,
            level,
        }
    }
}

fn find(parent: &mut [u32], mut i: u32) -> u32 {
    while parent[i as usize] != i {
        let p = parent[i as usize];
        parent[i as usize] = parent[p as usize];
        i = p;
    }
    i
}

/// Makes the roots of `a` and `b` one set, rooted at the smaller label.
#[inline]
fn union(parent: &mut [u32], a: u32, b: u32) {
    let (ra, rb) = (find(parent, a), find(parent, b));
    if ra != rb {
        let (lo, hi) = if ra < rb { (ra, rb) } else { (rb, ra) };
        parent[hi as usize] = lo;
    }
}

/// Connected components (8-connected) of the pixels with value > `level`, keeping only those
/// whose area is in `min_area..=max_area`, in the order of their first pixel (row-major).
pub fn components_above(
    img: &GrayImage,
    level: f32,
    min_area: usize,
    max_area: usize,
) -> Vec<Blob> {
    components_at_levels(img, &[level], min_area, max_area)
        .pop()
        .unwrap_or_default()
}

/// For each level of the non-decreasing ladder `levels`, the connected components
/// (8-connected) of the pixels with value > that level (NaN is above no level), keeping those
/// whose area is in `min_area..=max_area`, each rung's in the order of their first pixel
/// (row-major); every [`Blob`] carries its rung's level. The image is cut into horizontal
/// bands labelled in parallel (as many as rayon has threads) and joined; see
/// [`components_at_levels_banded`].
pub fn components_at_levels(
    img: &GrayImage,
    levels: &[f32],
    min_area: usize,
    max_area: usize,
) -> Vec<Vec<Blob>> {
    let bands = rayon::current_num_threads();
    components_at_levels_banded(img, levels, min_area, max_area, bands)
}

/// [`components_at_levels`] with the image cut into `bands` horizontal bands of (nearly) equal
/// height (at least one, at most one per row), labelled independently in parallel and joined
/// across the cuts. The result does not depend on `bands`: labels are numbered band after band,
/// so a component's root is still its first run in row-major order, and its sums are exact.
pub fn components_at_levels_banded(
    img: &GrayImage,
    levels: &[f32],
    min_area: usize,
    max_area: usize,
    bands: usize,
) -> Vec<Vec<Blob>> {
    use rayon::prelude::*;
    let sorted = levels.windows(2).all(|w| w[0] <= w[1]);
    assert!(sorted, "threshold levels must be non-decreasing");
    let (w, h) = (img.width, img.height);
    assert_eq!(img.data.len(), w * h, "image size");
    assert!(
        w <= u32::MAX as usize / 2 && h <= u32::MAX as usize,
        "image too large"
    );
    if w == 0 || h == 0 || levels.is_empty() {
        return vec![Vec::new(); levels.len()];
    }
    let nb = bands.clamp(1, h);
    let band_rows = |b: usize| (b * h / nb, (b + 1) * h / nb);
    let mut labelled: Vec<Vec<Labels>> = (0..nb)
        .into_par_iter()
        .map(|b| {
            let (y0, y1) = band_rows(b);
            label_band(img, levels, y0, y1)
        })
        .collect();
    // Per rung: the bands' labels one after the other, the cuts joined.
    let mut per_rung: Vec<Vec<Labels>> = (0..levels.len()).map(|_| Vec::new()).collect();
    for band in labelled.iter_mut() {
        for (k, l) in band.drain(..).enumerate() {
            per_rung[k].push(l);
        }
    }
    per_rung
        .into_par_iter()
        .zip(levels.par_iter())
        .map(|(bands, &level)| join_bands(bands, level, min_area, max_area))
        .collect()
}

/// One run x0..=x1 of a row and its label.
#[derive(Clone, Copy, Debug)]
struct Run {
    x0: u32,
    x1: u32,
    label: u32,
}

/// The labelling of one rung over a band of rows: union-find forest and sums per label, the
/// runs of the band's first row and of the row last labelled.
#[derive(Default)]
struct Labels {
    parent: Vec<u32>,
    sums: Vec<Sums>,
    first: Vec<Run>,
    prev: Vec<Run>,
    cur: Vec<Run>,
}

impl Labels {
    /// Labels row y given its foreground as (block, mask) pairs in increasing block order (bit
    /// i of the mask of block b is pixel 32·b + i): each run is joined to every run of the
    /// previous row it touches (8-connectivity: x ranges overlapping or diagonally adjacent),
    /// or gets a new label; the run's pixels are added to its label's sums (`px`: the prefix
    /// sums of x over the row).
    fn row(&mut self, y: u32, blocks: &[(u32, u32)], px: &PrefixSums) {
        let Labels {
            parent,
            sums,
            prev,
            cur,
            ..
        } = self;
        cur.clear();
        // The runs (a run crossing a block boundary is one run).
        for &(b, m) in blocks {
            let base = b * BLOCK as u32;
            let mut m = u64::from(m);
            while m != 0 {
                let s = m.trailing_zeros();
                let len = (!(m >> s)).trailing_zeros();
                let (x0, x1) = (base + s, base + s + len - 1);
                match cur.last_mut() {
                    Some(r) if r.x1 + 1 == x0 => r.x1 = x1,
                    _ => cur.push(Run { x0, x1, label: 0 }),
                }
                // Clear the lowest run of ones.
                m &= m + (m & m.wrapping_neg());
            }
        }
        // Their labels. `j`: the first previous-row run that can touch this or a later run.
        let above: &[Run] = prev;
        let (y64, mut j) = (u64::from(y), 0);
        for r in cur.iter_mut() {
            let (x0, x1) = (r.x0, r.x1);
            while j < above.len() && above[j].x1 + 1 < x0 {
                j += 1;
            }
            let mut label = u32::MAX;
            let mut kk = j;
            while kk < above.len() && above[kk].x0 <= x1 + 1 {
                let l = find(parent, above[kk].label);
                if label == u32::MAX {
                    label = l;
                } else if l != label {
                    let (lo, hi) = if l < label { (l, label) } else { (label, l) };
                    parent[hi as usize] = lo;
                    label = lo;
                }
                kk += 1;
            }
            let (n, sx, sxx) = px.run(x0, x1);
            if label == u32::MAX {
                label = parent.len() as u32;
                parent.push(label);
                sums.push(Sums {
                    area: n,
                    sx,
                    sy: y64 * n,
                    sxx,
                    sxy: y64 * sx,
                    syy: y64 * y64 * n,
                    x_min: x0,
                    x_max: x1,
                    y_min: y,
                    y_max: y,
                });
            } else {
                let t = &mut sums[label as usize];
                t.area += n;
                t.sx += sx;
                t.sy += y64 * n;
                t.sxx += sxx;
                t.sxy += y64 * sx;
                t.syy += y64 * y64 * n;
                t.x_min = t.x_min.min(x0);
                t.x_max = t.x_max.max(x1);
                t.y_max = y;
            }
            r.label = label;
        }
        std::mem::swap(prev, cur);
    }
}

/// Σ x and Σ x² over x < i, for i = 0..=w: the sums over a run x0..=x1 are two differences.
struct PrefixSums {
    s1: Vec<u64>,
    s2: Vec<u64>,
}

impl PrefixSums {
    fn new(w: usize) -> Self {
        let (mut s1, mut s2) = (Vec::with_capacity(w + 1), Vec::with_capacity(w + 1));
        let (mut a, mut b) = (0u64, 0u64);
        for x in 0..=w as u64 {
            s1.push(a);
            s2.push(b);
            a += x;
            b += x * x;
        }
        PrefixSums { s1, s2 }
    }

    /// (number of pixels, Σ x, Σ x²) over x0..=x1.
    #[inline(always)]
    fn run(&self, x0: u32, x1: u32) -> (u64, u64, u64) {
        let (a, b) = (x0 as usize, x1 as usize + 1);
        (
            u64::from(x1 - x0 + 1),
            self.s1[b] - self.s1[a],
            self.s2[b] - self.s2[a],
        )
    }
}

/// Width of the blocks the foreground masks are made of.
const BLOCK: usize = 32;

/// Bit i set when `d[i] > l` (at most 32 values).
#[inline(always)]
fn mask_above(d: &[f32], l: f32) -> u32 {
    d.iter()
        .enumerate()
        .fold(0u32, |m, (i, &v)| m | (u32::from(v > l) << i))
}

/// [`mask_above`] of a full block: four comparisons of 4 lanes packed to the 16 bytes of one
/// `pmovmskb`, twice (SSE2, part of the x86-64 baseline).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn mask_above_block(d: &[f32; BLOCK], l: f32) -> u32 {
    use std::arch::x86_64::*;
    // SAFETY: SSE2 is always present on x86-64; every load reads 4 floats inside `d`.
    unsafe {
        let lv = _mm_set1_ps(l);
        let p = d.as_ptr();
        let c = |i: usize| _mm_castps_si128(_mm_cmpgt_ps(_mm_loadu_ps(p.add(4 * i)), lv));
        let lo = _mm_packs_epi16(_mm_packs_epi32(c(0), c(1)), _mm_packs_epi32(c(2), c(3)));
        let hi = _mm_packs_epi16(_mm_packs_epi32(c(4), c(5)), _mm_packs_epi32(c(6), c(7)));
        (_mm_movemask_epi8(lo) as u32) | ((_mm_movemask_epi8(hi) as u32) << 16)
    }
}

#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
fn mask_above_block(d: &[f32; BLOCK], l: f32) -> u32 {
    mask_above(d, l)
}

/// Whether any of 32 values is above `l`.
#[inline(always)]
fn any_above(d: &[f32; BLOCK], l: f32) -> bool {
    d.iter().fold(false, |a, &v| a | (v > l))
}

/// Appends block `b`'s mask `mask(level)` to `masks[k]` for the rungs k = 0, 1, … up to the
/// first empty mask (the masks of the higher rungs are empty too).
#[inline(always)]
fn push_masks(levels: &[f32], masks: &mut [Vec<(u32, u32)>], b: usize, mask: impl Fn(f32) -> u32) {
    for (ms, &l) in masks.iter_mut().zip(levels) {
        let m = mask(l);
        if m == 0 {
            break;
        }
        ms.push((b as u32, m));
    }
}

/// Labels rows `y0..y1` of `img` for every rung of `levels` (non-empty, non-decreasing).
fn label_band(img: &GrayImage, levels: &[f32], y0: usize, y1: usize) -> Vec<Labels> {
    let w = img.width;
    let l0 = levels[0];
    let px = PrefixSums::new(w);
    let mut labels: Vec<Labels> = (0..levels.len()).map(|_| Labels::default()).collect();
    // Per rung, the (block, mask) pairs of the current row.
    let mut masks: Vec<Vec<(u32, u32)>> = vec![Vec::new(); levels.len()];
    for y in y0..y1 {
        let row = &img.data[y * w..(y + 1) * w];
        let mut chunks = row.chunks_exact(BLOCK);
        for (b, d) in chunks.by_ref().enumerate() {
            let d: &[f32; BLOCK] = d.try_into().expect("block");
            if any_above(d, l0) {
                push_masks(levels, &mut masks, b, |l| mask_above_block(d, l));
            }
        }
        let tail = chunks.remainder();
        if !tail.is_empty() {
            push_masks(levels, &mut masks, w / BLOCK, |l| mask_above(tail, l));
        }
        for (l, m) in labels.iter_mut().zip(masks.iter_mut()) {
            l.row(y as u32, m, &px);
            m.clear();
            if y == y0 {
                l.first.clone_from(&l.prev);
            }
        }
    }
    labels
}

/// One rung's labellings of consecutive bands made one (the labels of band i offset by the
/// label counts of the bands above it; runs of a band's last row joined to the touching runs
/// of the next band's first row), then the components with area in `min_area..=max_area`, in
/// label order.
fn join_bands(bands: Vec<Labels>, level: f32, min_area: usize, max_area: usize) -> Vec<Blob> {
    let mut bands = bands.into_iter();
    let Some(mut all) = bands.next() else {
        return Vec::new();
    };
    for b in bands {
        let off = all.parent.len() as u32;
        all.parent.extend(b.parent.iter().map(|&p| p + off));
        all.sums.extend_from_slice(&b.sums);
        // `all.prev`: the runs of the row above this band's first row.
        let mut j = 0;
        for r in &b.first {
            while j < all.prev.len() && all.prev[j].x1 + 1 < r.x0 {
                j += 1;
            }
            let mut kk = j;
            while kk < all.prev.len() && all.prev[kk].x0 <= r.x1 + 1 {
                union(&mut all.parent, all.prev[kk].label, r.label + off);
                kk += 1;
            }
        }
        all.prev.clear();
        all.prev.extend(b.prev.iter().map(|r| Run {
            label: r.label + off,
            ..*r
        }));
    }
    let Labels {
        mut parent,
        mut sums,
        ..
    } = all;
    // Sums into roots (a root is its set's smallest label, so it precedes its members).
    let n = parent.len();
    for i in 0..n {
        let r = find(&mut parent, i as u32) as usize;
        if r != i {
            let s = sums[i];
            sums[r].add(&s);
        }
    }
    (0..n)
        .filter(|&i| parent[i] as usize == i)
        .map(|i| &sums[i])
        .filter(|s| s.area >= min_area as u64 && s.area <= max_area as u64)
        .map(|s| s.blob(level))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn disc_and_ring_components() {
        let mut img = GrayImage::new(64, 48, 0.0);
        for y in 0..48 {
            for x in 0..64 {
                let (dx, dy) = (x as f64 - 20.0, y as f64 - 24.0);
                if dx * dx + dy * dy <= 64.0 {
                    img.data[y * 64 + x] = 1.0;
                }
                // A U shape that joins two arms only at the bottom (tests label merging).
                if (x == 50 || x == 56) && (5..20).contains(&y)
                    || (y == 20 && (50..=56).contains(&x))
                {
                    img.data[y * 64 + x] = 1.0;
                }
            }
        }
        let mut b = components_above(&img, 0.5, 1, 10_000);
        b.sort_by_key(|b| b.x_min);
        assert_eq!(b.len(), 2);
        let (cx, cy) = b[0].centroid();
        assert!((cx - 20.0).abs() < 1e-9 && (cy - 24.0).abs() < 1e-9);
        let e = b[0].moment_ellipse().unwrap();
        assert!((e.a - 8.0).abs() < 0.3 && (e.b - 8.0).abs() < 0.3, "{e:?}");
        assert!(b[0].fill_ratio() > 0.95);
        assert_eq!(b[1].area, 15 * 2 + 7);
        assert!(b[1].fill_ratio() < 0.5);
    }
}
