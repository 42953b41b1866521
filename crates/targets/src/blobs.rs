//! Connected components of a thresholded image (8-connectivity, run-length based, one pass
//! plus union-find), with the statistics the shape tests need: area, bounding box, first and
//! second moments, and whether the component touches the image border.

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
    fn empty(level: f32) -> Self {
        Blob {
            area: 0,
            x_min: usize::MAX,
            x_max: 0,
            y_min: usize::MAX,
            y_max: 0,
            sx: 0.0,
            sy: 0.0,
            sxx: 0.0,
            sxy: 0.0,
            syy: 0.0,
            level,
        }
    }

    fn add_run(&mut self, y: usize, x0: usize, x1: usize) {
        // Run covers x0..=x1 on row y.
        let n = (x1 - x0 + 1) as f64;
        let (a, b, yf) = (x0 as f64, x1 as f64, y as f64);
        let sum_x = (a + b) * n / 2.0;
        // Σ x² for x = a..=b
        let sum_xx = (b * (b + 1.0) * (2.0 * b + 1.0) - (a - 1.0) * a * (2.0 * a - 1.0)) / 6.0;
        self.area += x1 - x0 + 1;
        self.sx += sum_x;
        self.sy += yf * n;
        self.sxx += sum_xx;
        self.sxy += yf * sum_x;
        self.syy += yf * yf * n;
        self.x_min = self.x_min.min(x0);
        self.x_max = self.x_max.max(x1);
        self.y_min = self.y_min.min(y);
        self.y_max = self.y_max.max(y);
    }

    fn merge(&mut self, o: &Blob) {
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

fn find(parent: &mut [u32], mut i: u32) -> u32 {
    while parent[i as usize] != i {
        let p = parent[i as usize];
        parent[i as usize] = parent[p as usize];
        i = p;
    }
    i
}

/// Connected components (8-connected) of the pixels with value > `level`, keeping only those
/// whose area is in `min_area..=max_area`.
pub fn components_above(
    img: &GrayImage,
    level: f32,
    min_area: usize,
    max_area: usize,
) -> Vec<Blob> {
    let idx = level_index(img, &[level]);
    components_of_index(&idx, img.width, img.height, 0, level, min_area, max_area)
}

/// For a non-decreasing ladder `levels`, the number of levels each pixel is strictly above
/// (so pixel > `levels[i]` exactly when its index is > `i`). Computed once and shared by all
/// rungs of the ladder: each connected-component pass then scans bytes instead of floats.
/// At most 255 levels.
pub fn level_index(img: &GrayImage, levels: &[f32]) -> Vec<u8> {
    LevelIndex::new(img, levels).idx
}

/// Width of the blocks of [`LevelIndex::block_max`].
const BLOCK: usize = 32;

/// The level index of an image (see [`level_index`]) with, for every row, the largest index in
/// each block of [`BLOCK`] pixels: a component pass skips a block whose maximum is not above
/// its rung by reading one byte instead of 32.
#[derive(Clone, Debug)]
pub struct LevelIndex {
    pub width: usize,
    pub height: usize,
    /// Level index per pixel, row-major.
    pub idx: Vec<u8>,
    /// Per row, the maximum of `idx` over each block of 32 pixels (the last one may be shorter);
    /// `blocks_per_row()` entries per row.
    pub block_max: Vec<u8>,
}

impl LevelIndex {
    /// Computes the index and the block maxima in one pass over the image (in parallel over
    /// bands of rows).
    pub fn new(img: &GrayImage, levels: &[f32]) -> Self {
        use rayon::prelude::*;
        assert!(levels.len() <= 255, "at most 255 threshold levels");
        let sorted = levels.windows(2).all(|w| w[0] <= w[1]);
        assert!(sorted, "threshold levels must be non-decreasing");
        let (w, h) = (img.width, img.height);
        let nb = w.div_ceil(BLOCK);
        let mut idx = vec![0u8; w * h];
        let mut block_max = vec![0u8; nb * h];
        if w == 0 || h == 0 {
            return LevelIndex {
                width: w,
                height: h,
                idx,
                block_max,
            };
        }
        let rows = (1usize << 16).div_ceil(w).max(1);
        idx.par_chunks_mut(rows * w)
            .zip(block_max.par_chunks_mut(rows * nb))
            .zip(img.data.par_chunks(rows * w))
            .for_each(|((o, bm), d)| {
                for ((o, bm), d) in o.chunks_mut(w).zip(bm.chunks_mut(nb)).zip(d.chunks(w)) {
                    index_row(d, levels, o, bm);
                }
            });
        LevelIndex {
            width: w,
            height: h,
            idx,
            block_max,
        }
    }

    /// Blocks per row in [`LevelIndex::block_max`].
    pub fn blocks_per_row(&self) -> usize {
        self.width.div_ceil(BLOCK)
    }
}

/// One row of the level index: 32 pixels at a time, the per-level counts kept in registers
/// (the comparisons vectorise), then narrowed to bytes; and the maximum of each block.
#[inline]
fn index_row(d: &[f32], levels: &[f32], o: &mut [u8], bm: &mut [u8]) {
    let full = d.len() / BLOCK;
    for ((dc, oc), m) in d
        .chunks_exact(BLOCK)
        .zip(o.chunks_exact_mut(BLOCK))
        .zip(bm.iter_mut())
    {
        // Two halves of 16 (with 32 lanes the counts no longer fit the registers).
        let mut mx = 0u8;
        for (dc, oc) in dc.chunks_exact(16).zip(oc.chunks_exact_mut(16)) {
            let dc: &[f32; 16] = dc.try_into().expect("half block");
            let mut acc = [0u32; 16];
            for &l in levels {
                for j in 0..16 {
                    acc[j] += (dc[j] > l) as u32;
                }
            }
            for (o, &a) in oc.iter_mut().zip(&acc) {
                *o = a as u8;
                mx = mx.max(a as u8);
            }
        }
        *m = mx;
    }
    let rest = full * BLOCK;
    if rest < d.len() {
        let mut mx = 0u8;
        for (o, &v) in o[rest..].iter_mut().zip(&d[rest..]) {
            let c = levels.iter().filter(|&&l| v > l).count() as u8;
            *o = c;
            mx = mx.max(c);
        }
        bm[full] = mx;
    }
}

/// Connected components (8-connected) of the pixels whose level index (see [`level_index`]) is
/// greater than `k`, i.e. whose value is above `level`, keeping only those whose area is in
/// `min_area..=max_area`.
pub fn components_of_index(
    idx: &[u8],
    w: usize,
    h: usize,
    k: u8,
    level: f32,
    min_area: usize,
    max_area: usize,
) -> Vec<Blob> {
    assert_eq!(idx.len(), w * h, "index image size");
    let nb = w.div_ceil(BLOCK);
    let mut block_max = vec![0u8; nb * h];
    for (row, bm) in idx.chunks(w.max(1)).zip(block_max.chunks_mut(nb.max(1))) {
        for (c, m) in row.chunks(BLOCK).zip(bm.iter_mut()) {
            *m = c.iter().fold(0, |a, &v| a.max(v));
        }
    }
    components_with_blocks(idx, &block_max, w, h, k, level, min_area, max_area)
}

/// [`components_of_index`] on a precomputed [`LevelIndex`].
pub fn components_of_level_index(
    li: &LevelIndex,
    k: u8,
    level: f32,
    min_area: usize,
    max_area: usize,
) -> Vec<Blob> {
    components_with_blocks(
        &li.idx,
        &li.block_max,
        li.width,
        li.height,
        k,
        level,
        min_area,
        max_area,
    )
}

#[allow(clippy::too_many_arguments)]
fn components_with_blocks(
    idx: &[u8],
    block_max: &[u8],
    w: usize,
    h: usize,
    k: u8,
    level: f32,
    min_area: usize,
    max_area: usize,
) -> Vec<Blob> {
    assert_eq!(idx.len(), w * h, "index image size");
    let nb = w.div_ceil(BLOCK);
    assert_eq!(block_max.len(), nb * h, "block maxima size");
    // Runs: (x0, x1, label) per row; only the previous row is needed for connectivity.
    let mut runs_prev: Vec<(usize, usize, u32)> = Vec::new();
    let mut runs_cur: Vec<(usize, usize, u32)> = Vec::new();
    let mut parent: Vec<u32> = Vec::new();
    let mut stats: Vec<Blob> = Vec::new();
    for y in 0..h {
        runs_cur.clear();
        let row = &idx[y * w..(y + 1) * w];
        let bm = &block_max[y * nb..(y + 1) * nb];
        let mut x = 0;
        let mut j = 0; // index into runs_prev
        while x < w {
            // Skip background quickly: whole blocks whose maximum is not above the rung.
            if x % BLOCK == 0 {
                let mut b = x / BLOCK;
                while b < nb && bm[b] <= k {
                    b += 1;
                }
                x = (b * BLOCK).min(w);
                if x >= w {
                    break;
                }
            }
            if row[x] <= k {
                x += 1;
                continue;
            }
            let x0 = x;
            while x < w && row[x] > k {
                x += 1;
            }
            let x1 = x - 1;
            let mut label = u32::MAX;
            // Previous-row runs overlapping x0-1 ..= x1+1 (8-connectivity).
            while j < runs_prev.len() && runs_prev[j].1 + 1 < x0 {
                j += 1;
            }
            let mut kk = j;
            while kk < runs_prev.len() && runs_prev[kk].0 <= x1 + 1 {
                let r = find(&mut parent, runs_prev[kk].2);
                if label == u32::MAX {
                    label = r;
                } else if r != label {
                    let (lo, hi) = if r < label { (r, label) } else { (label, r) };
                    parent[hi as usize] = lo;
                    label = lo;
                }
                kk += 1;
            }
            if label == u32::MAX {
                label = parent.len() as u32;
                parent.push(label);
                stats.push(Blob::empty(level));
            }
            stats[label as usize].add_run(y, x0, x1);
            runs_cur.push((x0, x1, label));
        }
        std::mem::swap(&mut runs_prev, &mut runs_cur);
    }
    // Merge statistics into roots.
    let n = parent.len();
    for i in 0..n {
        let r = find(&mut parent, i as u32) as usize;
        if r != i {
            let s = std::mem::replace(&mut stats[i], Blob::empty(level));
            stats[r].merge(&s);
        }
    }
    (0..n)
        .filter(|&i| parent[i] as usize == i)
        .map(|i| std::mem::replace(&mut stats[i], Blob::empty(level)))
        .filter(|b| b.area >= min_area && b.area <= max_area)
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
