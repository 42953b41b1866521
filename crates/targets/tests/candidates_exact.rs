//! The candidate search gives exactly the results of its first implementation (kept below as
//! `reference`: a per-pixel level index over the whole image, then one run-based labelling
//! pass per threshold rung): the same components with the same statistics in the same order on
//! random images (any finite or NaN values, values equal to the levels, any band count), and the
//! same candidates, bit for bit, on the 20 real panel photographs and the 24 MP synthetic image
//! of the benchmark (each part skipped, with the reason printed, when its data is absent).
//!
//! Run `cargo test -p pingcal-targets --release --test targets candidates_exact:: -- --nocapture`.

use crate::panel;

use pingcal_targets::blobs::{components_at_levels, components_at_levels_banded, Blob};
use pingcal_targets::candidates::{find_candidates, Candidate, CandidateParams};
use pingcal_targets::threshold::threshold_levels;
use pingcal_targets::{load_image, GrayImage};
use proptest::prelude::*;

/// The candidate search as it was before the single-pass labelling (threshold ladder, level
/// index, components per rung, shape tests, grouping), in its plainest form: the level index
/// by scalar comparisons, the rungs one after the other.
mod reference {
    use pingcal_targets::candidates::{Candidate, CandidateParams};
    use pingcal_targets::ellipse::Ellipse;
    use pingcal_targets::GrayImage;

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
            let n = (x1 - x0 + 1) as f64;
            let (a, b, yf) = (x0 as f64, x1 as f64, y as f64);
            let sum_x = (a + b) * n / 2.0;
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

        pub fn centroid(&self) -> (f64, f64) {
            let n = self.area as f64;
            (self.sx / n, self.sy / n)
        }

        pub fn moment_ellipse(&self) -> Option<Ellipse> {
            let n = self.area as f64;
            let (cx, cy) = self.centroid();
            let mxx = self.sxx / n - cx * cx + 1.0 / 12.0;
            let myy = self.syy / n - cy * cy + 1.0 / 12.0;
            let mxy = self.sxy / n - cx * cy;
            Ellipse::from_moments(cx, cy, mxx, mxy, myy)
        }

        pub fn fill_ratio(&self) -> f64 {
            match self.moment_ellipse() {
                Some(e) => self.area as f64 / (std::f64::consts::PI * e.a * e.b),
                None => 0.0,
            }
        }

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

    /// Per pixel, the number of `levels` (non-decreasing) the value is strictly above.
    pub fn level_index(img: &GrayImage, levels: &[f32]) -> Vec<u8> {
        assert!(levels.len() <= 255);
        assert!(levels.windows(2).all(|w| w[0] <= w[1]));
        img.data
            .iter()
            .map(|&v| levels.iter().filter(|&&l| v > l).count() as u8)
            .collect()
    }

    const BLOCK: usize = 32;

    /// Components of the pixels whose index is above `k`, with block maxima as the skip test.
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
        let mut runs_prev: Vec<(usize, usize, u32)> = Vec::new();
        let mut runs_cur: Vec<(usize, usize, u32)> = Vec::new();
        let mut parent: Vec<u32> = Vec::new();
        let mut stats: Vec<Blob> = Vec::new();
        for y in 0..h {
            runs_cur.clear();
            let row = &idx[y * w..(y + 1) * w];
            let bm = &block_max[y * nb..(y + 1) * nb];
            let mut x = 0;
            let mut j = 0;
            while x < w {
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

    /// Components above every level of a non-decreasing ladder, one index for all.
    pub fn components_at_levels(
        img: &GrayImage,
        levels: &[f32],
        min_area: usize,
        max_area: usize,
    ) -> Vec<Vec<Blob>> {
        let idx = level_index(img, levels);
        levels
            .iter()
            .enumerate()
            .map(|(i, &l)| {
                components_of_index(&idx, img.width, img.height, i as u8, l, min_area, max_area)
            })
            .collect()
    }

    pub fn threshold_levels(img: &GrayImage, n: usize) -> Vec<f32> {
        const BINS: usize = 1024;
        let mut hist = [0usize; BINS];
        let step = (img.data.len() / 400_000).max(1);
        let mut total = 0usize;
        for v in img.data.iter().step_by(step) {
            let b = ((v.clamp(0.0, 1.0)) * (BINS - 1) as f32) as usize;
            hist[b] += 1;
            total += 1;
        }
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

    fn shape_ok(b: &Blob, w: usize, h: usize, p: &CandidateParams) -> Option<Ellipse> {
        if b.touches_border(w, h) {
            return None;
        }
        let e = b.moment_ellipse()?;
        if e.b / e.a < p.min_axis_ratio {
            return None;
        }
        let d = 2.0 * e.radius();
        let min_fill = if d < 10.0 {
            p.min_fill - 0.1
        } else {
            p.min_fill
        };
        let fill = b.fill_ratio();
        if fill < min_fill || fill > 1.15 {
            return None;
        }
        Some(e)
    }

    pub fn find_candidates(img: &GrayImage, p: &CandidateParams) -> Vec<Candidate> {
        let levels = threshold_levels(img, p.levels);
        let min_area = (std::f64::consts::PI * (p.min_diameter_px / 2.0).powi(2) * 0.7)
            .floor()
            .max(3.0) as usize;
        let max_area =
            (std::f64::consts::PI * (p.max_diameter_px / 2.0).powi(2) * 1.3).ceil() as usize;
        let (w, h) = (img.width, img.height);
        let per_level: Vec<Vec<(Ellipse, usize)>> =
            components_at_levels(img, &levels, min_area, max_area)
                .into_iter()
                .map(|blobs| {
                    blobs
                        .into_iter()
                        .filter_map(|b| shape_ok(&b, w, h, p).map(|e| (e, b.area)))
                        .collect()
                })
                .collect();
        struct Group {
            members: Vec<(Ellipse, usize)>,
            cx: f64,
            cy: f64,
            r: f64,
        }
        let cell = 16.0;
        let mut grid: std::collections::HashMap<(i64, i64), Vec<usize>> =
            std::collections::HashMap::new();
        let mut groups: Vec<Group> = Vec::new();
        for lvl in per_level {
            for (e, area) in lvl {
                let key = ((e.cx / cell).floor() as i64, (e.cy / cell).floor() as i64);
                let mut hit = None;
                'search: for dx in -1..=1 {
                    for dy in -1..=1 {
                        if let Some(v) = grid.get(&(key.0 + dx, key.1 + dy)) {
                            for &gi in v {
                                let g = &groups[gi];
                                let d = ((g.cx - e.cx).powi(2) + (g.cy - e.cy).powi(2)).sqrt();
                                if d <= (0.5 * g.r.min(e.radius())).max(1.0) {
                                    hit = Some(gi);
                                    break 'search;
                                }
                            }
                        }
                    }
                }
                match hit {
                    Some(gi) => groups[gi].members.push((e, area)),
                    None => {
                        grid.entry(key).or_default().push(groups.len());
                        groups.push(Group {
                            members: vec![(e, area)],
                            cx: e.cx,
                            cy: e.cy,
                            r: e.radius(),
                        });
                    }
                }
            }
        }
        let mut out: Vec<Candidate> = groups
            .into_iter()
            .filter(|g| g.members.len() >= p.min_repeat)
            .map(|g| {
                let (seed, area) = g.members[g.members.len() / 2];
                let d = 2.0 * seed.radius();
                (
                    Candidate {
                        seed,
                        repeats: g.members.len(),
                        area,
                    },
                    d,
                )
            })
            .filter(|(_, d)| *d >= p.min_diameter_px && *d <= p.max_diameter_px)
            .map(|(c, _)| c)
            .collect();
        out.sort_by(|a, b| {
            (a.seed.cy, a.seed.cx)
                .partial_cmp(&(b.seed.cy, b.seed.cx))
                .unwrap_or(std::cmp::Ordering::Equal)
        });
        out
    }
}

/// Everything a component exposes, floats as bits (NaN-safe equality).
type BlobKey = (usize, [usize; 4], u32, [u64; 2], Option<[u64; 5]>, u64);

fn ellipse_bits(e: &pingcal_targets::ellipse::Ellipse) -> [u64; 5] {
    [e.cx, e.cy, e.a, e.b, e.theta].map(f64::to_bits)
}

fn key(b: &Blob) -> BlobKey {
    let (cx, cy) = b.centroid();
    (
        b.area,
        [b.x_min, b.x_max, b.y_min, b.y_max],
        b.level.to_bits(),
        [cx.to_bits(), cy.to_bits()],
        b.moment_ellipse().as_ref().map(ellipse_bits),
        b.fill_ratio().to_bits(),
    )
}

fn ref_key(b: &reference::Blob) -> BlobKey {
    let (cx, cy) = b.centroid();
    (
        b.area,
        [b.x_min, b.x_max, b.y_min, b.y_max],
        b.level.to_bits(),
        [cx.to_bits(), cy.to_bits()],
        b.moment_ellipse().as_ref().map(ellipse_bits),
        b.fill_ratio().to_bits(),
    )
}

fn keys(levels: Vec<Vec<Blob>>) -> Vec<Vec<BlobKey>> {
    levels.iter().map(|l| l.iter().map(key).collect()).collect()
}

fn ref_keys(levels: Vec<Vec<reference::Blob>>) -> Vec<Vec<BlobKey>> {
    levels
        .iter()
        .map(|l| l.iter().map(ref_key).collect())
        .collect()
}

type CandKey = ([u64; 5], usize, usize);

fn cand_keys(c: &[Candidate]) -> Vec<CandKey> {
    c.iter()
        .map(|c| (ellipse_bits(&c.seed), c.repeats, c.area))
        .collect()
}

/// The float next to the finite `v`, above it (`up`) or below.
fn neighbour(v: f32, up: bool) -> f32 {
    if v == 0.0 {
        let tiny = f32::from_bits(1);
        return if up { tiny } else { -tiny };
    }
    let b = v.to_bits();
    f32::from_bits(if (v > 0.0) == up { b + 1 } else { b - 1 })
}

/// A grey value for the random images: one of the levels, a neighbour of one (one ulp away),
/// a value from [0, 1], any finite float, or NaN.
fn value(levels: Vec<f32>) -> impl Strategy<Value = f32> {
    let n = levels.len();
    let l1 = levels.clone();
    let l2 = levels;
    prop_oneof![
        3 => (0..n).prop_map(move |i| l1[i]),
        2 => ((0..n), any::<bool>()).prop_map(move |(i, up)| neighbour(l2[i], up)),
        3 => 0.0f32..=1.0,
        1 => any::<f32>().prop_filter("finite", |v| v.is_finite()),
        1 => Just(f32::NAN),
        1 => prop_oneof![Just(0.0f32), Just(-0.0), Just(1.0), Just(-1.0), Just(2.0)],
    ]
}

/// A random ladder (sorted, possibly with repeated levels, some outside [0, 1]) and an image
/// whose pixels take a few of the `value`s, in patches so that components are large and
/// touch each other; image widths cross the 32- and 64-pixel block boundaries.
fn case() -> impl Strategy<Value = (Vec<f32>, GrayImage, usize, usize, usize)> {
    proptest::collection::vec(
        prop_oneof![
            4 => 0.0f32..=1.0,
            1 => -2.0f32..3.0,
            1 => prop_oneof![Just(0.0f32), Just(0.5), Just(1.0)],
        ],
        1..7,
    )
    .prop_flat_map(|mut levels| {
        levels.sort_by(f32::total_cmp);
        let palette = proptest::collection::vec(value(levels.clone()), 1..6);
        (Just(levels), palette, 1usize..100, 1usize..40)
    })
    .prop_flat_map(|(levels, palette, w, h)| {
        let np = palette.len();
        (
            Just(levels),
            Just(palette),
            Just(w),
            Just(h),
            proptest::collection::vec((0..np, 1usize..12), 1..(w * h).min(400) + 1),
            1usize..6,
            0usize..8,
            1usize..200,
        )
    })
    .prop_map(
        |(levels, palette, w, h, runs, bands, min_area, max_extra)| {
            // The image is a sequence of runs (palette entry, length), cycled to fill it.
            let mut data = Vec::with_capacity(w * h);
            'fill: loop {
                for &(p, len) in &runs {
                    for _ in 0..len {
                        if data.len() == w * h {
                            break 'fill;
                        }
                        data.push(palette[p]);
                    }
                }
            }
            let img = GrayImage {
                width: w,
                height: h,
                data,
            };
            (levels, img, bands, min_area, min_area + max_extra)
        },
    )
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

    #[test]
    fn components_equal_the_reference((levels, img, bands, min_area, max_area) in case()) {
        let want = ref_keys(reference::components_at_levels(&img, &levels, min_area, max_area));
        let got = keys(components_at_levels_banded(&img, &levels, min_area, max_area, bands));
        prop_assert_eq!(&got, &want);
        let got = keys(components_at_levels(&img, &levels, min_area, max_area));
        prop_assert_eq!(&got, &want);
    }

    #[test]
    fn ladder_equals_the_reference(
        data in proptest::collection::vec(
            prop_oneof![4 => 0.0f32..=1.0, 1 => any::<f32>(), 1 => -1.0f32..2.0],
            0..3000,
        ),
        n in 0usize..12,
    ) {
        let img = GrayImage { width: data.len(), height: 1, data };
        let got: Vec<u32> = threshold_levels(&img, n).iter().map(|v| v.to_bits()).collect();
        let want: Vec<u32> =
            reference::threshold_levels(&img, n).iter().map(|v| v.to_bits()).collect();
        prop_assert_eq!(got, want);
    }
}

/// Components per rung and candidates of `img` against the reference, with the image cut into
/// 1, 2, 3 and 7 bands.
fn check_image(name: &str, img: &GrayImage) -> usize {
    let p = CandidateParams::default();
    let want = cand_keys(&reference::find_candidates(img, &p));
    let got = cand_keys(&find_candidates(img, &p));
    assert_eq!(got.len(), want.len(), "{name}: candidate count");
    assert_eq!(got, want, "{name}: candidates");
    let count = got.len();
    let levels = reference::threshold_levels(img, p.levels);
    let want = ref_keys(reference::components_at_levels(img, &levels, 10, 50_000));
    for bands in [1, 2, 3, 7] {
        let got = keys(components_at_levels_banded(img, &levels, 10, 50_000, bands));
        assert_eq!(got, want, "{name}: components in {bands} bands");
    }
    count
}

#[test]
fn panel_candidates_equal_the_reference() {
    let Some((_, files)) = panel::panel() else {
        return;
    };
    assert!(!files.is_empty(), "no panel images");
    for f in &files {
        let img = load_image(f).expect("panel image loads");
        let n = check_image(&f.display().to_string(), &img);
        println!("{}: {n} candidates, identical", f.display());
    }
}

#[test]
fn synthetic_24mp_candidates_equal_the_reference() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../bench/targets/out/synthetic24mp.png"
    );
    if !std::path::Path::new(path).exists() {
        println!("SKIP: {path} not found (made by bench/targets/run.sh)");
        return;
    }
    let img = load_image(std::path::Path::new(path)).expect("synthetic image loads");
    let n = check_image(path, &img);
    println!("{path}: {n} candidates, identical");
}
