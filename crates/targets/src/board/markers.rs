//! Square markers (ArUco, AprilTag): dark quadrilaterals found in the image, their cells
//! read and looked up in a dictionary.
//!
//! 1. Candidates: the image thresholded against its local mean (boxes of 15 and 41 px, a
//!    pixel dark when 0.03 below the mean), as it is and opened by a 3 × 3 square (which
//!    cuts the bridges where two dark squares touch at a corner); 4-connected dark
//!    components, the convex hull of each, and the hull's quadrilateral (the two
//!    farthest-apart hull points and the farthest on each side of their line), kept when it
//!    fills ≥ 80 % of the hull; its sides then fitted to the component's outline (a line
//!    through the middle 70 % of each) and its corners the lines' crossings.
//! 2. Reading: the quad's `n + 2b` cells a side (`b` border cells) sampled at 3 × 3 points
//!    each through the homography of the quad; black is the border's mean, white the
//!    brightest inner cell's, and a cell is white above their middle. At most one border
//!    cell in ten may read white, and white must be 0.08 above black.
//! 3. Lookup: the inner cells read from each of the quad's four corners in turn, matched
//!    against every code of the dictionary; taken when the nearest code is within
//!    `⌊0.6 · maxCorrectionBits⌋` bits (OpenCV's `errorCorrectionRate` default), and no
//!    other id is as near.

use super::codes::tables;
use crate::homography::fit_homography;
use crate::raster::GrayImage;

/// A dictionary of square markers: OpenCV's predefined ArUco dictionaries and the AprilTag
/// library's tag36h11 (`codes/tables.rs` says where the codes come from).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MarkerDictionary {
    name: &'static str,
    codes: &'static [u64],
    bits: usize,
    max_correction: usize,
}

impl MarkerDictionary {
    /// The dictionary of OpenCV's name (`DICT_4X4_50` … `DICT_7X7_1000`,
    /// `DICT_ARUCO_ORIGINAL`) or the AprilTag family `tag36h11`; other names refused with the
    /// names known.
    pub fn named(name: &str) -> Result<Self, String> {
        tables::NAMED
            .iter()
            .find(|e| e.0 == name)
            .map(|&(name, table, bits, count, max_correction)| Self {
                name,
                codes: &table[..count],
                bits,
                max_correction,
            })
            .ok_or_else(|| {
                let known: Vec<&str> = tables::NAMED.iter().map(|e| e.0).collect();
                format!(
                    "marker dictionary '{name}': not one pingcal reads (it reads {})",
                    known.join(", ")
                )
            })
    }

    /// Its name.
    pub fn name(&self) -> &'static str {
        self.name
    }

    /// Cells a side of a marker's code (inside its black border).
    pub fn bits(&self) -> usize {
        self.bits
    }

    /// Number of markers.
    pub fn len(&self) -> usize {
        self.codes.len()
    }

    /// Whether it has no marker (never, for the named ones).
    pub fn is_empty(&self) -> bool {
        self.codes.is_empty()
    }

    /// Whether cell (`row`, `col`) of marker `id`'s code is white (row 0 at the top of the
    /// upright marker). Marker `id` must be below [`MarkerDictionary::len`].
    pub fn is_white(&self, id: usize, row: usize, col: usize) -> bool {
        let n = self.bits;
        (self.codes[id] >> (n * n - 1 - (row * n + col))) & 1 == 1
    }

    /// Bits a read code may differ from its marker's: `⌊0.6 · maxCorrectionBits⌋`.
    fn tolerance(&self) -> u32 {
        (self.max_correction * 3 / 5) as u32
    }

    /// The id within the tolerance of `code`, when one alone is nearest.
    fn identify(&self, code: u64) -> Option<usize> {
        let mut best = (u32::MAX, usize::MAX, false);
        for (id, &c) in self.codes.iter().enumerate() {
            let d = (c ^ code).count_ones();
            if d < best.0 {
                best = (d, id, false);
            } else if d == best.0 {
                best.2 = true;
            }
        }
        (best.0 <= self.tolerance() && !best.2).then_some(best.1)
    }
}

/// A marker read in the image: its id and its corners (px), in the order of the upright
/// marker: top-left, top-right, bottom-right, bottom-left (OpenCV's order).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Marker {
    /// Its id in the dictionary.
    pub id: usize,
    /// Corners (px), top-left first, clockwise on the upright marker.
    pub corners: [[f64; 2]; 4],
}

/// Every marker of `dict` in `img`, drawn with `border` black cells a side (1 for ArUco, 2
/// for Kalibr's AprilGrid tags). Each id at most once: an id read twice is dropped.
pub fn find_markers(img: &GrayImage, dict: &MarkerDictionary, border: usize) -> Vec<Marker> {
    let mut found: Vec<Marker> = Vec::new();
    for quad in quads(img) {
        if let Some(m) = read(img, &quad, dict, border) {
            let same_place = found.iter().any(|f| near(f, &m));
            if !same_place {
                found.push(m);
            }
        }
    }
    let mut ids: Vec<usize> = found.iter().map(|m| m.id).collect();
    ids.sort_unstable();
    let twice: Vec<usize> = ids
        .windows(2)
        .filter(|w| w[0] == w[1])
        .map(|w| w[0])
        .collect();
    found.retain(|m| !twice.contains(&m.id));
    found.sort_by_key(|m| m.id);
    found
}

/// The same marker (found at two thresholds): same id, centres within a fifth of a side.
fn near(a: &Marker, b: &Marker) -> bool {
    let c = |m: &Marker| {
        let s = m
            .corners
            .iter()
            .fold([0.0, 0.0], |s, p| [s[0] + p[0], s[1] + p[1]]);
        [s[0] / 4.0, s[1] / 4.0]
    };
    let (ca, cb) = (c(a), c(b));
    let side = dist(a.corners[0], a.corners[1]);
    a.id == b.id && dist(ca, cb) < 0.2 * side
}

fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()
}

/// Twice the signed area of a polygon (positive: clockwise in the image, y down).
fn area2(p: &[[f64; 2]]) -> f64 {
    (0..p.len())
        .map(|i| {
            let (a, b) = (p[i], p[(i + 1) % p.len()]);
            a[0] * b[1] - b[0] * a[1]
        })
        .sum()
}

/// Reads `quad` (clockwise) as a marker of `dict`: each of its corners tried as the
/// upright marker's top-left.
fn read(
    img: &GrayImage,
    quad: &[[f64; 2]; 4],
    dict: &MarkerDictionary,
    border: usize,
) -> Option<Marker> {
    (0..4).find_map(|k| {
        let corners = [
            quad[k],
            quad[(k + 1) % 4],
            quad[(k + 2) % 4],
            quad[(k + 3) % 4],
        ];
        let code = read_code(img, &corners, dict.bits, border)?;
        dict.identify(code).map(|id| Marker { id, corners })
    })
}

/// The inner cells of the marker whose corners are `c` (top-left first, clockwise) as a
/// code (row-major, first cell the most significant bit, 1 = white); `None` when its
/// border is not black or it has no contrast.
fn read_code(img: &GrayImage, c: &[[f64; 2]; 4], bits: usize, border: usize) -> Option<u64> {
    let cells = bits + 2 * border;
    let unit = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
    let h = fit_homography(&unit, c)?;
    let mut means = vec![0.0f64; cells * cells];
    for r in 0..cells {
        for col in 0..cells {
            let mut s = 0.0;
            for dy in [-0.22, 0.0, 0.22] {
                for dx in [-0.22, 0.0, 0.22] {
                    let u = (col as f64 + 0.5 + dx) / cells as f64;
                    let v = (r as f64 + 0.5 + dy) / cells as f64;
                    let p = h.apply([u, v])?;
                    if !img.inside(p[0], p[1], 1.0) {
                        return None;
                    }
                    s += img.sample(p[0], p[1]) as f64;
                }
            }
            means[r * cells + col] = s / 9.0;
        }
    }
    let is_border =
        |r: usize, c: usize| r < border || c < border || r >= cells - border || c >= cells - border;
    let (mut black, mut nb, mut white) = (0.0, 0usize, f64::MIN);
    for r in 0..cells {
        for col in 0..cells {
            let m = means[r * cells + col];
            if is_border(r, col) {
                black += m;
                nb += 1;
            } else {
                white = white.max(m);
            }
        }
    }
    let black = black / nb as f64;
    if white - black < 0.08 {
        return None;
    }
    let mid = 0.5 * (black + white);
    let mut wrong = 0;
    let mut code = 0u64;
    for r in 0..cells {
        for col in 0..cells {
            let light = means[r * cells + col] > mid;
            if is_border(r, col) {
                wrong += usize::from(light);
            } else {
                code = (code << 1) | u64::from(light);
            }
        }
    }
    (wrong * 10 <= nb).then_some(code)
}

/// Local-mean windows (px, odd).
const WINDOWS: [usize; 2] = [15, 41];
/// A pixel is dark this far below its window's mean.
const DARK_BELOW_MEAN: f32 = 0.03;
/// The smallest quad side (px) worth reading.
const MIN_SIDE_PX: f64 = 10.0;

/// Dark quadrilaterals of `img`, each clockwise in the image (y down), at every window.
pub(crate) fn quads(img: &GrayImage) -> Vec<[[f64; 2]; 4]> {
    let integral = Integral::of(img);
    let mut out = Vec::new();
    for win in WINDOWS {
        let dark = dark_mask(img, &integral, win);
        let open = opened(&dark, img.width, img.height);
        for mask in [&dark, &open] {
            for comp in components(mask, img.width, img.height) {
                if let Some(q) = quad_of(&comp, img.width, img.height) {
                    out.push(q);
                }
            }
        }
    }
    out
}

/// Summed-area table of an image, `(w + 1) × (h + 1)`.
struct Integral {
    w: usize,
    sums: Vec<f64>,
}

impl Integral {
    fn of(img: &GrayImage) -> Self {
        let (w, h) = (img.width, img.height);
        let mut sums = vec![0.0; (w + 1) * (h + 1)];
        for y in 0..h {
            let mut row = 0.0;
            for x in 0..w {
                row += img.get(x, y) as f64;
                sums[(y + 1) * (w + 1) + x + 1] = sums[y * (w + 1) + x + 1] + row;
            }
        }
        Self { w, sums }
    }

    /// Sum over `[x0, x1) × [y0, y1)`.
    fn sum(&self, x0: usize, y0: usize, x1: usize, y1: usize) -> f64 {
        let s = |x: usize, y: usize| self.sums[y * (self.w + 1) + x];
        s(x1, y1) - s(x0, y1) - s(x1, y0) + s(x0, y0)
    }
}

fn dark_mask(img: &GrayImage, integral: &Integral, win: usize) -> Vec<bool> {
    let (w, h) = (img.width, img.height);
    let r = win / 2;
    let mut dark = vec![false; w * h];
    for y in 0..h {
        let (y0, y1) = (y.saturating_sub(r), (y + r + 1).min(h));
        for x in 0..w {
            let (x0, x1) = (x.saturating_sub(r), (x + r + 1).min(w));
            let mean = integral.sum(x0, y0, x1, y1) / ((x1 - x0) * (y1 - y0)) as f64;
            dark[y * w + x] = img.get(x, y) < mean as f32 - DARK_BELOW_MEAN;
        }
    }
    dark
}

/// `mask` opened by a 3 × 3 square (eroded, then dilated): the one- and two-pixel bridges
/// where two dark squares touch at a corner (a ChArUco marker's black square, an
/// AprilGrid's tag and its corner square) cut, the squares themselves kept.
fn opened(mask: &[bool], w: usize, h: usize) -> Vec<bool> {
    let apply = |src: &[bool], all: bool| {
        let mut out = vec![false; w * h];
        for y in 1..h.saturating_sub(1) {
            for x in 1..w.saturating_sub(1) {
                let mut n =
                    (y - 1..=y + 1).flat_map(|yy| (x - 1..=x + 1).map(move |xx| src[yy * w + xx]));
                out[y * w + x] = if all { n.all(|v| v) } else { n.any(|v| v) };
            }
        }
        out
    };
    apply(&apply(mask, true), false)
}

/// The 4-connected components of `mask` not touching the image's edge, as pixel lists, of
/// 30 pixels up to a quarter of the image.
fn components(mask: &[bool], w: usize, h: usize) -> Vec<Vec<(usize, usize)>> {
    let mut seen = vec![false; w * h];
    let mut out = Vec::new();
    let mut stack = Vec::new();
    for start in 0..w * h {
        if !mask[start] || seen[start] {
            continue;
        }
        seen[start] = true;
        stack.push(start);
        let mut comp = Vec::new();
        let mut edge = false;
        while let Some(i) = stack.pop() {
            let (x, y) = (i % w, i / w);
            comp.push((x, y));
            edge |= x == 0 || y == 0 || x + 1 == w || y + 1 == h;
            let mut visit = |j: usize| {
                if mask[j] && !seen[j] {
                    seen[j] = true;
                    stack.push(j);
                }
            };
            if x > 0 {
                visit(i - 1);
            }
            if x + 1 < w {
                visit(i + 1);
            }
            if y > 0 {
                visit(i - w);
            }
            if y + 1 < h {
                visit(i + w);
            }
        }
        if !edge && comp.len() >= 30 && comp.len() <= w * h / 4 {
            out.push(comp);
        }
    }
    out
}

/// The quadrilateral of a component: its pixels' outline's convex hull, reduced to the four
/// hull points spanning the most, when they fill ≥ 90 % of the hull; clockwise.
fn quad_of(comp: &[(usize, usize)], w: usize, h: usize) -> Option<[[f64; 2]; 4]> {
    let set: std::collections::HashSet<(usize, usize)> = comp.iter().copied().collect();
    let mut pts = Vec::new();
    let mut outline = Vec::new();
    for &(x, y) in comp {
        let inner = x > 0
            && y > 0
            && x + 1 < w
            && y + 1 < h
            && set.contains(&(x - 1, y))
            && set.contains(&(x + 1, y))
            && set.contains(&(x, y - 1))
            && set.contains(&(x, y + 1));
        if !inner {
            let (fx, fy) = (x as f64, y as f64);
            outline.push([fx, fy]);
            pts.extend([
                [fx - 0.5, fy - 0.5],
                [fx + 0.5, fy - 0.5],
                [fx + 0.5, fy + 0.5],
                [fx - 0.5, fy + 0.5],
            ]);
        }
    }
    let hull = convex_hull(pts);
    if hull.len() < 4 {
        return None;
    }
    let far = |from: [f64; 2]| {
        hull.iter()
            .copied()
            .max_by(|a, b| dist(*a, from).total_cmp(&dist(*b, from)))
    };
    let n = hull.len() as f64;
    let centroid = hull
        .iter()
        .fold([0.0, 0.0], |s, p| [s[0] + p[0] / n, s[1] + p[1] / n]);
    let p0 = far(centroid)?;
    let p2 = far(p0)?;
    let side = |p: &[f64; 2]| (p2[0] - p0[0]) * (p[1] - p0[1]) - (p2[1] - p0[1]) * (p[0] - p0[0]);
    let p1 = hull
        .iter()
        .copied()
        .max_by(|a, b| side(a).total_cmp(&side(b)))?;
    let p3 = hull
        .iter()
        .copied()
        .min_by(|a, b| side(a).total_cmp(&side(b)))?;
    let mut q = [p0, p1, p2, p3];
    if area2(&q) < 0.0 {
        q.swap(1, 3);
    }
    let quad_area = area2(&q);
    let hull_area = area2(&hull).abs();
    let sides_ok = (0..4).all(|i| dist(q[i], q[(i + 1) % 4]) >= MIN_SIDE_PX);
    if !(sides_ok && quad_area >= 0.8 * hull_area) {
        return None;
    }
    let lines: Vec<[f64; 3]> = (0..4)
        .map(|i| edge_line(&outline, q[i], q[(i + 1) % 4]))
        .collect::<Option<_>>()?;
    let mut fitted = [[0.0; 2]; 4];
    for i in 0..4 {
        let (a, b) = (lines[(i + 3) % 4], lines[i]);
        let det = a[0] * b[1] - a[1] * b[0];
        if det.abs() < 1e-9 {
            return None;
        }
        let p = [
            (-a[2] * b[1] + b[2] * a[1]) / det,
            (-a[0] * b[2] + b[0] * a[2]) / det,
        ];
        if dist(p, q[i]) > 0.25 * dist(q[i], q[(i + 1) % 4]) {
            return None;
        }
        fitted[i] = p;
    }
    Some(fitted)
}

/// The line `[a, b, c]` (`a x + b y + c = 0`, unit normal pointing out of the clockwise quad)
/// of the outline pixels along the side from `p` to `q` (the middle 70 % of it, within 3 px),
/// moved half a pixel out (the dark pixels' centres lie inside the edge).
fn edge_line(outline: &[[f64; 2]], p: [f64; 2], q: [f64; 2]) -> Option<[f64; 3]> {
    let len = dist(p, q);
    let d = [(q[0] - p[0]) / len, (q[1] - p[1]) / len];
    let near: Vec<[f64; 2]> = outline
        .iter()
        .copied()
        .filter(|o| {
            let v = [o[0] - p[0], o[1] - p[1]];
            let t = (v[0] * d[0] + v[1] * d[1]) / len;
            let off = (v[0] * d[1] - v[1] * d[0]).abs();
            (0.15..=0.85).contains(&t) && off < 3.0
        })
        .collect();
    if near.len() < 4 {
        return None;
    }
    let n = near.len() as f64;
    let m = near
        .iter()
        .fold([0.0, 0.0], |s, o| [s[0] + o[0] / n, s[1] + o[1] / n]);
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for o in &near {
        let (x, y) = (o[0] - m[0], o[1] - m[1]);
        sxx += x * x;
        sxy += x * y;
        syy += y * y;
    }
    let angle = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    let dir = [angle.cos(), angle.sin()];
    // Outward normal of a clockwise (y down) quad: the direction turned by −90°.
    let mut normal = [dir[1], -dir[0]];
    if normal[0] * d[1] - normal[1] * d[0] < 0.0 {
        normal = [-normal[0], -normal[1]];
    }
    let c = -(normal[0] * m[0] + normal[1] * m[1]) - 0.5;
    Some([normal[0], normal[1], c])
}

/// The convex hull of `pts` (Andrew's monotone chain), counter-clockwise in x-right y-up
/// terms.
fn convex_hull(mut pts: Vec<[f64; 2]>) -> Vec<[f64; 2]> {
    pts.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    pts.dedup();
    if pts.len() < 3 {
        return pts;
    }
    let cross = |o: [f64; 2], a: [f64; 2], b: [f64; 2]| {
        (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
    };
    let mut hull: Vec<[f64; 2]> = Vec::with_capacity(2 * pts.len());
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &[f64; 2]>> = if pass == 0 {
            Box::new(pts.iter())
        } else {
            Box::new(pts.iter().rev())
        };
        for &p in iter {
            while hull.len() >= start + 2
                && cross(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0
            {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
    }
    hull
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dictionaries_are_found_by_name_and_others_refused_in_one_line() {
        let d = MarkerDictionary::named("DICT_5X5_100").unwrap();
        assert_eq!((d.bits(), d.len(), d.tolerance()), (5, 100, 1));
        let t = MarkerDictionary::named("tag36h11").unwrap();
        assert_eq!((t.bits(), t.len()), (6, 587));
        let e = MarkerDictionary::named("tag25h9").unwrap_err();
        assert!(e.contains("tag25h9") && e.contains("DICT_4X4_50") && !e.contains('\n'));
    }

    #[test]
    fn every_code_is_identified_as_itself_and_a_code_beyond_the_tolerance_is_not() {
        for name in ["DICT_4X4_50", "DICT_5X5_1000", "DICT_6X6_250", "tag36h11"] {
            let d = MarkerDictionary::named(name).unwrap();
            for id in 0..d.len() {
                assert_eq!(d.identify(d.codes[id]), Some(id), "{name} {id}");
            }
            // Flipping more bits than the tolerance allows lands on no id or another one
            // only if the dictionary's distance says so; at the tolerance + 1 from marker 0
            // the nearest must not be marker 0.
            let flipped = d.codes[0] ^ ((1u64 << (d.tolerance() + 1)) - 1);
            assert_ne!(d.identify(flipped), Some(0), "{name}");
        }
    }
}
