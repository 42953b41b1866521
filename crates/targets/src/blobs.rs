//! Connected components of thresholded images (8-connectivity, run-length based, one pass
//! plus union-find), with the statistics the shape tests need: area, bounding box, first and
//! second moments, and whether the component touches the image border.
//!
//! [`components_at_levels`] labels the components above every rung of a threshold ladder in
//! one pass over the image. Per row, each block of 32 pixels gets its bit mask of the pixels
//! above the lowest rung (vector comparisons, one `pmovmskb` per 16 pixels), and a block with a
//! pixel above it the masks of the next rungs, rung after rung until a mask is empty (a pixel
//! above a rung is above every lower one). The masks give the runs of the row for every rung,
//! and each rung's runs are labelled against that rung's runs of the previous row. Nothing per
//! pixel is stored, and on these images (a few bright targets on a dark background) most blocks
//! cost one mask. A component's statistics are kept only while it is open: once it has no run
//! in the last two rows they are moved to the output (or dropped, by area), and their slot is
//! reused, so the memory follows the number of components open at a time, not the thousands of
//! specks of noise met over the image.

use crate::ellipse::Ellipse;
use crate::image_io::GrayImage;

/// Statistics of one connected component. Coordinates are pixel centres (x right, y down).
#[derive(Clone, Debug)]
pub struct Blob {
    /// Number of pixels in the component.
    pub area: usize,
    /// Leftmost column, inclusive, px.
    pub x_min: usize,
    /// Rightmost column, inclusive, px.
    pub x_max: usize,
    /// Top row, inclusive, px.
    pub y_min: usize,
    /// Bottom row, inclusive, px.
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
#[derive(Clone, Copy, Debug, Default)]
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
    /// Adds the pixels of `o` (disjoint from these): sums added, bounding boxes joined.
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

    /// The [`Blob`] of these pixels, extracted at `level`.
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

/// In a union-find forest (see [`Labels::parent`]), marks a root: its entry is `ROOT | data`.
const ROOT: u32 = 1 << 31;
/// With [`ROOT`]: the data is an index into [`Labels::pending`], not an open slot.
const PENDING: u32 = 1 << 30;
/// The data bits of a root's entry.
const DATA: u32 = PENDING - 1;

/// The root of label `i` in the forest `parent` (entries: the parent label, or `ROOT | data`
/// for a root), halving the path.
#[inline]
fn find(parent: &mut [u32], mut i: u32) -> u32 {
    loop {
        let p = parent[i as usize];
        if p & ROOT != 0 {
            return i;
        }
        let g = parent[p as usize];
        if g & ROOT != 0 {
            return p;
        }
        parent[i as usize] = g;
        i = g;
    }
}

/// The root of `i` in a plain forest (a root is its own parent), halving the path.
fn find_plain(parent: &mut [u32], mut i: u32) -> u32 {
    while parent[i as usize] != i {
        let p = parent[i as usize];
        parent[i as usize] = parent[p as usize];
        i = p;
    }
    i
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
            label_band(img, levels, y0, y1, min_area, max_area)
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

/// One run x0..=x1 of a row and its label ([`NONE`]: a run not labelled yet).
#[derive(Clone, Copy, Debug)]
struct Run {
    x0: u32,
    x1: u32,
    label: u32,
}

/// [`Run::label`] of a run that touches no run of the row above and is too small to be a
/// component by itself: it gets a label only if a run of the row below touches it.
const NONE: u32 = u32::MAX;

/// Slots of [`Labels::open`] before the first collection of finished components.
const MIN_SLOTS: usize = 64;

/// The order of components: (row << 32) | column of their first pixel in row-major order.
type Key = u64;

/// The sums of the run x0..=x1 of row y (`px`: the prefix sums of x over a row).
#[inline(always)]
fn run_sums(y: u32, x0: u32, x1: u32, px: &PrefixSums) -> Sums {
    let (n, sx, sxx) = px.run(x0, x1);
    let y64 = u64::from(y);
    Sums {
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
    }
}

/// The labelling of one rung over a band of rows. Each open component has a slot for its
/// sums, its root label and its [`Key`]; when the slots run out, the components without a run
/// in the previous or the current row (finished: nothing can join them any more) are collected
/// and their slots reused, so memory grows only by the 4 bytes of `parent` per label. A run
/// that touches nothing above and is smaller than `min_area` waits for a run below to touch it
/// before it is labelled (most specks of noise are never labelled).
#[derive(Default)]
struct Labels {
    /// Union-find forest over the labels: the parent label, or for a root `ROOT | slot` (an
    /// open component) or `ROOT | PENDING | i` (a component in `pending[i]`).
    parent: Vec<u32>,
    /// Per slot: the sums of its component (area 0: slot not in use; `y_max` is the last row
    /// the component has a run in),
    open: Vec<Sums>,
    /// its root label
    owner: Vec<u32>,
    /// and its key.
    key: Vec<Key>,
    /// Slots not in use.
    free: Vec<u32>,
    /// Number of slots at which finished components are collected.
    collect_at: usize,
    /// (key, sums) of the finished components with area in `min_area..=max_area`.
    done: Vec<(Key, Sums)>,
    /// (key, sums) of the components that touch the band's first row (above it, another band
    /// may continue them) and, once the band is labelled, its last row.
    pending: Vec<(Key, Sums)>,
    /// The band's first row when another band is above it (else `u32::MAX`): components with
    /// a run in it (`y_min` equal to it) may continue above, and its runs are all labelled.
    top: u32,
    first: Vec<Run>,
    prev: Vec<Run>,
    cur: Vec<Run>,
    min_area: u64,
    max_area: u64,
}

impl Labels {
    /// No rows labelled yet; `top`: see [`Labels::top`].
    fn new(top: u32, min_area: usize, max_area: usize) -> Self {
        Labels {
            min_area: min_area as u64,
            max_area: max_area as u64,
            collect_at: MIN_SLOTS,
            top,
            ..Labels::default()
        }
    }

    /// A new component: the run x0..=x1 of row y (`y` is the current row or the one before).
    #[inline]
    fn start(&mut self, y: u32, x0: u32, x1: u32, px: &PrefixSums) -> u32 {
        let label = self.parent.len() as u32;
        assert!(label < PENDING, "too many components");
        let slot = self.slot(y);
        self.open[slot] = run_sums(y, x0, x1, px);
        self.owner[slot] = label;
        self.key[slot] = (Key::from(y) << 32) | Key::from(x0);
        self.parent.push(ROOT | slot as u32);
        label
    }

    /// Labels row y given its foreground as (block, mask) pairs in increasing block order (bit
    /// i of the mask of block b is pixel 32·b + i): each run is joined to every run of the
    /// previous row it touches (8-connectivity: x ranges overlapping or diagonally adjacent),
    /// or starts a component; the run's pixels are added to its component's sums (`px`: the
    /// prefix sums of x over the row).
    fn row(&mut self, y: u32, blocks: &[(u32, u32)], px: &PrefixSums) {
        self.cur.clear();
        // The runs (a run crossing a block boundary is one run).
        for &(b, m) in blocks {
            let base = b * BLOCK as u32;
            let mut m = u64::from(m);
            while m != 0 {
                let s = m.trailing_zeros();
                let len = (!(m >> s)).trailing_zeros();
                let (x0, x1) = (base + s, base + s + len - 1);
                match self.cur.last_mut() {
                    Some(r) if r.x1 + 1 == x0 => r.x1 = x1,
                    _ => self.cur.push(Run {
                        x0,
                        x1,
                        label: NONE,
                    }),
                }
                // Clear the lowest run of ones.
                m &= m + (m & m.wrapping_neg());
            }
        }
        // Their labels. `j`: the first previous-row run that can touch this or a later run.
        let mut cur = std::mem::take(&mut self.cur);
        let mut above = std::mem::take(&mut self.prev);
        let mut j = 0;
        for r in cur.iter_mut() {
            let (x0, x1) = (r.x0, r.x1);
            while j < above.len() && above[j].x1 + 1 < x0 {
                j += 1;
            }
            let mut label = NONE;
            let mut kk = j;
            while kk < above.len() && above[kk].x0 <= x1 + 1 {
                let a = &mut above[kk];
                if a.label == NONE {
                    a.label = self.start(y - 1, a.x0, a.x1, px);
                }
                let l = find(&mut self.parent, a.label);
                if label == NONE {
                    label = l;
                } else if l != label {
                    // Two open components meet: the one with the larger root joins the other.
                    let parent = &mut self.parent;
                    let (lo, hi) = if l < label { (l, label) } else { (label, l) };
                    let (sl, sh) = (
                        (parent[lo as usize] & DATA) as usize,
                        (parent[hi as usize] & DATA) as usize,
                    );
                    let oh = self.open[sh];
                    self.open[sl].add(&oh);
                    self.key[sl] = self.key[sl].min(self.key[sh]);
                    self.open[sh].area = 0;
                    self.free.push(sh as u32);
                    parent[hi as usize] = lo;
                    label = lo;
                }
                kk += 1;
            }
            if label != NONE {
                let slot = (self.parent[label as usize] & DATA) as usize;
                self.open[slot].add(&run_sums(y, x0, x1, px));
            } else if u64::from(x1 - x0 + 1) >= self.min_area || y == self.top {
                label = self.start(y, x0, x1, px);
            }
            r.label = label;
        }
        self.prev = cur;
        self.cur = above;
    }

    /// A free slot for a component with a run in row y: a free one, else (with enough slots)
    /// one freed by collecting the finished components, else a new one.
    #[inline]
    fn slot(&mut self, y: u32) -> usize {
        if self.free.is_empty() && self.open.len() >= self.collect_at {
            // Finished: no run in row y − 1 or later.
            self.collect(y.saturating_sub(1));
            let live = self.open.len() - self.free.len();
            self.collect_at = MIN_SLOTS.max(2 * live);
        }
        match self.free.pop() {
            Some(s) => s as usize,
            None => {
                self.open.push(Sums::default());
                self.owner.push(0);
                self.key.push(0);
                self.open.len() - 1
            }
        }
    }

    /// Ends every open component whose last run is in a row before `row`.
    fn collect(&mut self, row: u32) {
        for slot in 0..self.open.len() {
            let s = &self.open[slot];
            if s.area != 0 && s.y_max < row {
                self.end(slot, false);
            }
        }
    }

    /// Ends the component in `slot`: pending if `pending` or it touches the band's first row,
    /// else done (when its area is in range); the slot is freed.
    fn end(&mut self, slot: usize, pending: bool) {
        let (l, k, s) = (self.owner[slot], self.key[slot], self.open[slot]);
        if pending || s.y_min == self.top {
            self.parent[l as usize] = ROOT | PENDING | self.pending.len() as u32;
            self.pending.push((k, s));
        } else if s.area >= self.min_area && s.area <= self.max_area {
            self.done.push((k, s));
        }
        self.open[slot].area = 0;
        self.free.push(slot as u32);
    }

    /// After the band's last row `y`: its runs are all labelled, and the components still open
    /// are ended, those with a run in that row as pending (for the band below).
    fn close(&mut self, y: u32, px: &PrefixSums) {
        let mut last = std::mem::take(&mut self.prev);
        for r in last.iter_mut().filter(|r| r.label == NONE) {
            r.label = self.start(y, r.x0, r.x1, px);
        }
        self.prev = last;
        for slot in 0..self.open.len() {
            let s = &self.open[slot];
            if s.area != 0 {
                self.end(slot, s.y_max == y);
            }
        }
    }

    /// The index in `pending` of the component of label `l` (of the band's first or last
    /// row).
    fn pending_of(&mut self, l: u32) -> u32 {
        let r = find(&mut self.parent, l);
        let v = self.parent[r as usize];
        debug_assert!(v & PENDING != 0);
        v & DATA
    }
}

/// Σ x and Σ x² over x < i, for i = 0..=w: the sums over a run x0..=x1 are two differences.
struct PrefixSums {
    s1: Vec<u64>,
    s2: Vec<u64>,
}

impl PrefixSums {
    /// The prefix sums of a row of `w` pixels.
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

/// [`mask_above`] of a full block.
#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
fn mask_above_block(d: &[f32; BLOCK], l: f32) -> u32 {
    mask_above(d, l)
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

/// Labels rows `y0..y1` of `img` for every rung of `levels` (non-empty, non-decreasing): one
/// closed [`Labels`] per rung (finished components in range done, the others pending).
fn label_band(
    img: &GrayImage,
    levels: &[f32],
    y0: usize,
    y1: usize,
    min_area: usize,
    max_area: usize,
) -> Vec<Labels> {
    let w = img.width;
    let px = PrefixSums::new(w);
    let top = if y0 > 0 { y0 as u32 } else { u32::MAX };
    let mut labels: Vec<Labels> = (0..levels.len())
        .map(|_| Labels::new(top, min_area, max_area))
        .collect();
    // Per rung, the (block, mask) pairs of the current row.
    let mut masks: Vec<Vec<(u32, u32)>> = vec![Vec::new(); levels.len()];
    for y in y0..y1 {
        let row = &img.data[y * w..(y + 1) * w];
        let mut chunks = row.chunks_exact(BLOCK);
        for (b, d) in chunks.by_ref().enumerate() {
            let d: &[f32; BLOCK] = d.try_into().expect("block");
            push_masks(levels, &mut masks, b, |l| mask_above_block(d, l));
        }
        let tail = chunks.remainder();
        if !tail.is_empty() {
            push_masks(levels, &mut masks, w / BLOCK, |l| mask_above(tail, l));
        }
        for (l, m) in labels.iter_mut().zip(masks.iter_mut()) {
            l.row(y as u32, m, &px);
            m.clear();
            if y == y0 && y0 > 0 {
                l.first.clone_from(&l.prev);
            }
        }
    }
    for l in labels.iter_mut() {
        l.close((y1 - 1) as u32, &px);
    }
    labels
}

/// One rung's labellings of consecutive bands made one: the pending components of each band's
/// last row joined to those of the next band's first row they touch. Returns the finished and
/// joined components with area in `min_area..=max_area` in the order of their first pixel.
fn join_bands(mut bands: Vec<Labels>, level: f32, min_area: usize, max_area: usize) -> Vec<Blob> {
    // (key, sums) of the pending components, band after band.
    let mut pend: Vec<(Key, Sums)> = Vec::new();
    let mut pend_off = Vec::with_capacity(bands.len());
    let mut out: Vec<(Key, Sums)> = Vec::new();
    for b in &bands {
        pend_off.push(pend.len() as u32);
        pend.extend_from_slice(&b.pending);
        out.extend_from_slice(&b.done);
    }
    // Union-find over the pending components: runs of a band's last row and of the next
    // band's first row that touch.
    let mut parent: Vec<u32> = (0..pend.len() as u32).collect();
    for i in 1..bands.len() {
        let (upper, lower) = bands.split_at_mut(i);
        let (a, b) = (&mut upper[i - 1], &mut lower[0]);
        let (oa, ob) = (pend_off[i - 1], pend_off[i]);
        let last = std::mem::take(&mut a.prev);
        let first = std::mem::take(&mut b.first);
        let mut j = 0;
        for r in &first {
            while j < last.len() && last[j].x1 + 1 < r.x0 {
                j += 1;
            }
            let mut kk = j;
            while kk < last.len() && last[kk].x0 <= r.x1 + 1 {
                let pa = find_plain(&mut parent, oa + a.pending_of(last[kk].label));
                let pb = find_plain(&mut parent, ob + b.pending_of(r.label));
                if pa != pb {
                    let (lo, hi) = if pa < pb { (pa, pb) } else { (pb, pa) };
                    parent[hi as usize] = lo;
                }
                kk += 1;
            }
        }
    }
    // Sums and smallest key into the roots (a root is its set's smallest index, so it
    // precedes its members).
    for i in 0..pend.len() {
        let r = find_plain(&mut parent, i as u32) as usize;
        if r != i {
            let (l, s) = pend[i];
            pend[r].0 = pend[r].0.min(l);
            pend[r].1.add(&s);
        }
    }
    out.extend(
        pend.iter()
            .enumerate()
            .filter(|&(i, (_, s))| {
                parent[i] as usize == i && s.area >= min_area as u64 && s.area <= max_area as u64
            })
            .map(|(_, p)| *p),
    );
    // By first pixel: sort (key, index) pairs, not the 72-byte entries.
    let mut order: Vec<(Key, u32)> = out
        .iter()
        .enumerate()
        .map(|(i, &(k, _))| (k, i as u32))
        .collect();
    order.sort_unstable();
    order
        .iter()
        .map(|&(_, i)| out[i as usize].1.blob(level))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The SSE2 mask of a block is the plain comparison, lane for lane (NaN is above nothing).
    #[test]
    fn block_mask_is_the_plain_comparison() {
        use rand::Rng;
        let mut rng = pingcal_geometry::consensus::rng(3);
        let levels = [0.0f32, 0.25, 0.5, 1.0, -0.0, f32::MIN_POSITIVE];
        for _ in 0..20_000 {
            let l = if rng.random_bool(0.5) {
                levels[rng.random_range(0..levels.len())]
            } else {
                rng.random_range(-0.5..1.5)
            };
            let d: [f32; BLOCK] = std::array::from_fn(|_| match rng.random_range(0..6) {
                0 => l,
                1 => f32::NAN,
                2 => f32::from_bits(rng.random()),
                _ => rng.random_range(-0.5..1.5),
            });
            let want = d
                .iter()
                .enumerate()
                .fold(0u32, |m, (i, &v)| if v > l { m | 1 << i } else { m });
            assert_eq!(mask_above_block(&d, l), want, "{d:?} > {l}");
            assert_eq!(mask_above(&d, l), want);
        }
    }

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
