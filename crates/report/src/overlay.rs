//! The LRF's points drawn on a photograph: the check every lidar–camera tool offers
//! (MATLAB's Lidar Camera Calibrator, SphereCalib's back-projections). If the calibration is
//! right, the points that hit a ball lie on the ball's image and the points on a wall, a
//! floor or an edge follow that wall, floor or edge; an error of the extrinsic or of the
//! LRF's mount shows as a shift or a shear of the points against the picture.
//!
//! [`render_png`] draws them as an RGB PNG: the photograph in grey with its contrast lowered
//! (`g' = 40 + 0.6 g`, so that colours stand out and dark pixels are not black), every
//! other LRF point as a small disc coloured by its range on the turbo colour map
//! ([`range_colour`]) (far points
//! first, so near ones are on top), a colour bar of that range in the bottom-right corner,
//! at most one range point per [`PIXELS_PER_POINT`] output pixels (an even stride through
//! them, so a dense cloud does not hide the photograph), and the points of each ball
//! last, all of them, in [`BALL_RGB`] (magenta, a colour the turbo map does
//! not have) with the ball's label beside them. Marks ([`PointKind::Mark`]: a fitted
//! outline, edge points, a projected centre) go over everything, in their own colours.
//!
//! **Pixel coordinates** are those of the bundle adjustment: x right, y down, (0, 0) the
//! centre of the top-left pixel, so the image covers `[−½, W − ½] × [−½, H − ½]`. Points
//! outside that (or not finite) are skipped and counted ([`Rendered::outside`]).
//!
//! **Downscaling** (`max_width`) averages the source pixels whose centres fall in each
//! output pixel (area average, so a thumbnail of a textured scene stays legible, not
//! aliased); a point at source `x` lands at `(x + ½) s − ½` for the scale `s`. The discs are
//! drawn at the output's resolution, so they keep their size in pixels.
//!
//! The work is `O(pixels + points · disc area)` whatever the coordinates, and the bytes are
//! the same for the same input (fixed PNG settings, a stable sort).

use serde::{Deserialize, Serialize};

/// An 8-bit grey image, row-major, `pixels.len() == width · height`.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct GreyImage {
    /// Width, px.
    pub width: u32,
    /// Height, px.
    pub height: u32,
    /// The grey values, row by row from the top.
    pub pixels: Vec<u8>,
}

/// What an LRF point is.
#[derive(Debug, Clone, PartialEq)]
pub enum PointKind {
    /// A point of a ball's sphere fit; `label` is the ball's id (or the sphere's, when it
    /// was not matched to a ball).
    Ball {
        /// The ball's label, drawn beside its points.
        label: String,
    },
    /// Any other point, coloured by its range.
    Range {
        /// Its range from the LRF, mm.
        range_mm: f64,
    },
    /// A mark drawn over the points in a colour of its own (a fitted outline, an edge point,
    /// a projected centre), not counted among them.
    Mark {
        /// Its colour.
        rgb: [u8; 3],
        /// Its radius in output pixels (at least 0.5: one pixel).
        size_px: f64,
        /// A plus-shaped cross (arms of `size_px`, two pixels wide) instead of a disc.
        cross: bool,
    },
}

/// One LRF point projected into the image.
#[derive(Debug, Clone, PartialEq)]
pub struct OverlayPoint {
    /// Column, px (x right; 0 is the centre of the first column).
    pub x: f64,
    /// Row, px (y down; 0 is the centre of the first row).
    pub y: f64,
    /// Ball point or range point.
    pub kind: PointKind,
}

/// How to draw.
#[derive(Debug, Clone, PartialEq)]
pub struct OverlayOptions {
    /// Disc radius of a range point in output pixels (`None`: `max(1, W'/800)` for an
    /// output `W'` wide).
    pub radius_px: Option<f64>,
    /// The output's largest width, px (`None`: the image's own width). The image is never
    /// enlarged.
    pub max_width: Option<u32>,
    /// The range at the colour map's two ends, mm (`None`: the 2nd and 98th percentiles of
    /// the range points that are drawn).
    pub range_mm: Option<(f64, f64)>,
    /// Whether to write each ball's label beside its points.
    pub labels: bool,
    /// The most range points drawn (`None`: one per [`PIXELS_PER_POINT`] output pixels),
    /// taken at an even stride through the input order, so a dense cloud does not hide the
    /// photograph. Ball points are all drawn.
    pub max_range_points: Option<usize>,
    /// Compress harder (about 35 % fewer bytes for three times the time): for what goes
    /// into the report.
    pub small_file: bool,
}

/// Output pixels per range point drawn, when [`OverlayOptions::max_range_points`] is not
/// given.
pub const PIXELS_PER_POINT: usize = 60;

impl Default for OverlayOptions {
    fn default() -> Self {
        OverlayOptions {
            radius_px: None,
            max_width: None,
            range_mm: None,
            labels: true,
            max_range_points: None,
            small_file: false,
        }
    }
}

/// A drawn overlay.
#[derive(Debug, Clone, PartialEq)]
pub struct Rendered {
    /// The PNG (RGB, 8 bit).
    pub png: Vec<u8>,
    /// Its width, px.
    pub width: u32,
    /// Its height, px.
    pub height: u32,
    /// Range points drawn.
    pub range_points: usize,
    /// Range points inside the image that the stride left out.
    pub range_points_skipped: usize,
    /// Ball points drawn.
    pub ball_points: usize,
    /// Points outside the image (or not finite), not drawn.
    pub outside: usize,
    /// The range at the colour map's ends, mm.
    pub range_mm: (f64, f64),
}

/// The colour of a ball's points and label.
pub const BALL_RGB: [u8; 3] = [255, 40, 220];

/// One overlay of the report: an image with the LRF's points on it.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Overlay {
    /// The image's name (file name).
    pub name: String,
    /// What it shows (camera, station, counts), one line.
    pub caption: String,
    /// True for the image(s) of the main station: shown large, first.
    pub main: bool,
    /// The drawn thumbnail, a PNG in base64 ([`crate::base64`]).
    pub png_base64: String,
    /// The thumbnail's width, px.
    pub width: u32,
    /// The thumbnail's height, px.
    pub height: u32,
    /// Range points drawn.
    pub range_points: usize,
    /// Range points inside the image left out to keep the photograph visible
    /// ([`OverlayOptions::max_range_points`]).
    #[serde(default)]
    pub range_points_skipped: usize,
    /// Ball points drawn.
    pub ball_points: usize,
    /// LRF points that fall outside the image.
    pub outside: usize,
    /// The colour map's range, mm.
    pub range_mm: [f64; 2],
}

impl Overlay {
    /// The report's entry of a drawn image.
    pub fn of(name: &str, caption: &str, main: bool, r: &Rendered) -> Self {
        Overlay {
            name: name.into(),
            caption: caption.into(),
            main,
            png_base64: base64(&r.png),
            width: r.width,
            height: r.height,
            range_points: r.range_points,
            range_points_skipped: r.range_points_skipped,
            ball_points: r.ball_points,
            outside: r.outside,
            range_mm: [r.range_mm.0, r.range_mm.1],
        }
    }
}

/// An RGB canvas.
struct Canvas {
    w: usize,
    h: usize,
    rgb: Vec<u8>,
}

impl Canvas {
    fn set(&mut self, x: i64, y: i64, c: [u8; 3]) {
        if x >= 0 && y >= 0 && (x as usize) < self.w && (y as usize) < self.h {
            let k = 3 * (y as usize * self.w + x as usize);
            self.rgb[k..k + 3].copy_from_slice(&c);
        }
    }

    /// A filled disc: the pixels whose centres are within `r` of (x, y).
    fn disc(&mut self, x: f64, y: f64, r: f64, c: [u8; 3]) {
        let (x0, x1) = ((x - r).ceil() as i64, (x + r).floor() as i64);
        let (y0, y1) = ((y - r).ceil() as i64, (y + r).floor() as i64);
        for py in y0.max(0)..=y1.min(self.h as i64 - 1) {
            for px in x0.max(0)..=x1.min(self.w as i64 - 1) {
                let (dx, dy) = (px as f64 - x, py as f64 - y);
                if dx * dx + dy * dy <= r * r {
                    self.set(px, py, c);
                }
            }
        }
    }

    fn rect(&mut self, x: i64, y: i64, w: i64, h: i64, c: [u8; 3]) {
        for py in y.max(0)..(y + h).min(self.h as i64) {
            for px in x.max(0)..(x + w).min(self.w as i64) {
                self.set(px, py, c);
            }
        }
    }

    /// `text` in the 5 × 7 font at `scale` px per font pixel, top-left at (x, y), with a
    /// one-pixel dark outline so it reads on any background.
    fn text(&mut self, x: i64, y: i64, text: &str, scale: i64, c: [u8; 3]) {
        for (pass, colour) in [(0, [0, 0, 0]), (1, c)] {
            for (k, ch) in text.chars().enumerate() {
                let g = glyph(ch);
                let gx = x + k as i64 * 6 * scale;
                for (row, bits) in g.iter().enumerate() {
                    for col in 0..5 {
                        if bits & (0x10 >> col) == 0 {
                            continue;
                        }
                        let (px, py) = (gx + col * scale, y + row as i64 * scale);
                        if pass == 0 {
                            self.rect(px - 1, py - 1, scale + 2, scale + 2, colour);
                        } else {
                            self.rect(px, py, scale, scale, colour);
                        }
                    }
                }
            }
        }
    }
}

/// The width of `text` in the font at `scale`, px.
fn text_width(text: &str, scale: i64) -> i64 {
    (text.chars().count() as i64 * 6 - 1).max(0) * scale
}

/// The image averaged down to `w × h` (each output pixel the mean of the source pixels
/// whose centres fall in it), then dimmed: `g' = 40 + 0.6 g`.
fn background(img: &GreyImage, w: usize, h: usize) -> Canvas {
    let (sw, sh) = (img.width as usize, img.height as usize);
    let span = |i: usize, n: usize, src: usize| {
        let a = i * src / n;
        let b = ((i + 1) * src / n).max(a + 1).min(src);
        a..b
    };
    let mut rgb = vec![0u8; 3 * w * h];
    for y in 0..h {
        let ys = span(y, h, sh);
        for x in 0..w {
            let xs = span(x, w, sw);
            let (mut sum, mut n) = (0u64, 0u64);
            for yy in ys.clone() {
                let row = &img.pixels[yy * sw..(yy + 1) * sw];
                for v in &row[xs.clone()] {
                    sum += u64::from(*v);
                    n += 1;
                }
            }
            let g = sum as f64 / n.max(1) as f64;
            let d = (40.0 + 0.6 * g).round().clamp(0.0, 255.0) as u8;
            rgb[3 * (y * w + x)..3 * (y * w + x) + 3].copy_from_slice(&[d, d, d]);
        }
    }
    Canvas { w, h, rgb }
}

/// Turbo (Google's perceptual rainbow; the polynomial fit of Mikhailov's map) at
/// `t ∈ [0, 1]`: dark blue, cyan, green, yellow, red, dark red.
pub fn turbo(t: f64) -> [u8; 3] {
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.5
    };
    let poly = |c: [f64; 6]| {
        let v = c[0] + t * (c[1] + t * (c[2] + t * (c[3] + t * (c[4] + t * c[5]))));
        (v.clamp(0.0, 1.0) * 255.0).round() as u8
    };
    [
        poly([
            0.13572138,
            4.61539260,
            -42.66032258,
            132.13108234,
            -152.94239396,
            59.28637943,
        ]),
        poly([
            0.09140261,
            2.19418839,
            4.84296658,
            -14.18503333,
            4.27729857,
            2.82956604,
        ]),
        poly([
            0.10667330,
            12.64194608,
            -60.58204836,
            110.36276771,
            -89.90310912,
            27.34824973,
        ]),
    ]
}

/// The colour of a range point at `t ∈ [0, 1]` of the colour map's range:
/// `turbo(0.1 + 0.85 t)`, the map without its near-black ends, which a dark photograph
/// would hide.
pub fn range_colour(t: f64) -> [u8; 3] {
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.5
    };
    turbo(0.1 + 0.85 * t)
}

/// The `q`-quantile of sorted `v` (nearest rank).
fn quantile_sorted(v: &[f64], q: f64) -> f64 {
    v[((v.len() - 1) as f64 * q).round() as usize]
}

/// The range at the colour map's ends: `given`, else the 2nd and 98th percentiles of
/// `ranges` (widened to 1 mm when they coincide).
fn range_limits(given: Option<(f64, f64)>, ranges: &mut [f64]) -> (f64, f64) {
    if let Some((a, b)) = given.filter(|(a, b)| a.is_finite() && b.is_finite() && b > a) {
        return (a, b);
    }
    if ranges.is_empty() {
        return (0.0, 1.0);
    }
    ranges.sort_by(f64::total_cmp);
    let (a, b) = (quantile_sorted(ranges, 0.02), quantile_sorted(ranges, 0.98));
    if b > a {
        (a, b)
    } else {
        (a - 0.5, a + 0.5)
    }
}

/// The colour bar of the range `(lo, hi)` in the bottom-right corner.
fn colour_bar(cv: &mut Canvas, lo: f64, hi: f64, scale: i64) {
    let (w, h) = (cv.w as i64, cv.h as i64);
    let bar_w = (w / 4).max(40);
    let bar_h = 5 * scale;
    let (x0, y0) = (w - bar_w - 6 * scale, h - bar_h - 13 * scale);
    cv.rect(
        x0 - 3 * scale,
        y0 - 3 * scale,
        bar_w + 6 * scale,
        bar_h + 15 * scale,
        [20, 20, 20],
    );
    for i in 0..bar_w {
        let c = range_colour(i as f64 / (bar_w - 1).max(1) as f64);
        cv.rect(x0 + i, y0, 1, bar_h, c);
    }
    let white = [235, 235, 235];
    let lo_t = format!("{lo:.0}");
    let hi_t = format!("{hi:.0} mm");
    cv.text(x0, y0 + bar_h + 3 * scale, &lo_t, scale, white);
    let hx = x0 + bar_w - text_width(&hi_t, scale);
    cv.text(hx, y0 + bar_h + 3 * scale, &hi_t, scale, white);
}

/// The output size for `max_width`: the scale `s ≤ 1` and `W' × H'`.
fn output_size(img: &GreyImage, max_width: Option<u32>) -> (f64, usize, usize) {
    let (w, h) = (img.width.max(1), img.height.max(1));
    let s = max_width.map_or(1.0, |m| (f64::from(m.max(1)) / f64::from(w)).min(1.0));
    let ow = ((f64::from(w) * s).round() as usize).max(1);
    let oh = ((f64::from(h) * s).round() as usize).max(1);
    (s, ow, oh)
}

/// Draws `points` on `img` (see the module doc). An image whose `pixels` do not match its
/// size is drawn as mid-grey.
pub fn render_png(img: &GreyImage, points: &[OverlayPoint], opts: &OverlayOptions) -> Rendered {
    let fixed;
    let img = if img.pixels.len() == img.width as usize * img.height as usize {
        img
    } else {
        fixed = GreyImage {
            width: img.width.max(1),
            height: img.height.max(1),
            pixels: vec![128; img.width.max(1) as usize * img.height.max(1) as usize],
        };
        &fixed
    };
    let (s, w, h) = output_size(img, opts.max_width);
    let mut cv = background(img, w, h);
    let inside = |p: &OverlayPoint| {
        p.x.is_finite()
            && p.y.is_finite()
            && p.x >= -0.5
            && p.y >= -0.5
            && p.x <= f64::from(img.width) - 0.5
            && p.y <= f64::from(img.height) - 0.5
    };
    let at = |p: &OverlayPoint| ((p.x + 0.5) * s - 0.5, (p.y + 0.5) * s - 0.5);
    let mut outside = 0;
    let mut range: Vec<(f64, f64, f64)> = Vec::new();
    let mut balls: Vec<(&str, f64, f64)> = Vec::new();
    let mut marks: Vec<(f64, f64, [u8; 3], f64, bool)> = Vec::new();
    for p in points {
        if !inside(p) {
            outside += 1;
            continue;
        }
        let (x, y) = at(p);
        match &p.kind {
            PointKind::Range { range_mm } => range.push((*range_mm, x, y)),
            PointKind::Ball { label } => balls.push((label, x, y)),
            PointKind::Mark {
                rgb,
                size_px,
                cross,
            } => marks.push((x, y, *rgb, size_px.clamp(0.5, 50.0), *cross)),
        }
    }
    let budget = opts
        .max_range_points
        .unwrap_or(w * h / PIXELS_PER_POINT)
        .max(1);
    let inside_range = range.len();
    if range.len() > budget {
        let stride = range.len().div_ceil(budget);
        range = range.into_iter().step_by(stride).collect();
    }
    let mut ranges: Vec<f64> = range
        .iter()
        .map(|r| r.0)
        .filter(|r| r.is_finite())
        .collect();
    let (lo, hi) = range_limits(opts.range_mm, &mut ranges);
    let r = opts
        .radius_px
        .filter(|r| r.is_finite() && *r > 0.0)
        .unwrap_or((w as f64 / 800.0).max(1.0))
        .min(50.0);
    // Far first, so that near points are drawn over them.
    range.sort_by(|a, b| {
        b.0.total_cmp(&a.0)
            .then(a.1.total_cmp(&b.1))
            .then(a.2.total_cmp(&b.2))
    });
    for &(rng, x, y) in &range {
        cv.disc(x, y, r, range_colour((rng - lo) / (hi - lo)));
    }
    for &(_, x, y) in &balls {
        cv.disc(x, y, r, BALL_RGB);
    }
    for &(x, y, c, size, cross) in &marks {
        if cross {
            let a = size.round() as i64;
            let (cx, cy) = (x.round() as i64, y.round() as i64);
            cv.rect(cx - a, cy - 1, 2 * a + 1, 3, [0, 0, 0]);
            cv.rect(cx - 1, cy - a, 3, 2 * a + 1, [0, 0, 0]);
            cv.rect(cx - a, cy, 2 * a + 1, 1, c);
            cv.rect(cx, cy - a, 1, 2 * a + 1, c);
        } else {
            cv.disc(x, y, size, c);
        }
    }
    let scale = if h >= 600 { 2 } else { 1 };
    if opts.labels {
        ball_labels(&mut cv, &balls, r, scale);
    }
    if !range.is_empty() {
        colour_bar(&mut cv, lo, hi, scale);
    }
    Rendered {
        png: encode_rgb(&cv, opts.small_file),
        width: w as u32,
        height: h as u32,
        range_points: range.len(),
        range_points_skipped: inside_range - range.len(),
        ball_points: balls.len(),
        outside,
        range_mm: (lo, hi),
    }
}

/// Each ball's label to the right of its points, at their mean height.
fn ball_labels(cv: &mut Canvas, balls: &[(&str, f64, f64)], r: f64, scale: i64) {
    let mut labels: Vec<&str> = balls.iter().map(|b| b.0).collect();
    labels.sort_unstable();
    labels.dedup();
    for label in labels {
        let (mut xmax, mut ysum, mut n) = (f64::NEG_INFINITY, 0.0, 0.0);
        for &(_, x, y) in balls.iter().filter(|b| b.0 == label) {
            xmax = xmax.max(x);
            ysum += y;
            n += 1.0;
        }
        let tx = (xmax + r + 3.0).round() as i64;
        let ty = (ysum / n).round() as i64 - 3 * scale;
        let tw = text_width(label, scale);
        let tx = tx.min(cv.w as i64 - tw - 1).max(1);
        cv.text(
            tx,
            ty.clamp(1, (cv.h as i64 - 8 * scale).max(1)),
            label,
            scale,
            BALL_RGB,
        );
    }
}

/// The canvas as an RGB PNG with fixed settings (the same bytes for the same pixels),
/// compressed harder when `small`.
fn encode_rgb(cv: &Canvas, small: bool) -> Vec<u8> {
    let mut out = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut out, cv.w as u32, cv.h as u32);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_compression(if small {
            png::Compression::Balanced
        } else {
            png::Compression::Fast
        });
        let mut writer = enc.write_header().expect("writing to memory cannot fail");
        writer
            .write_image_data(&cv.rgb)
            .expect("the buffer has the header's size");
    }
    out
}

/// The 5 × 7 glyph of `c` (rows top to bottom, 5 bits each, the leftmost the highest):
/// digits, letters (lower case as upper, but `m`), `-`, `.`, `_`, `+`, space, and a box for
/// any other character.
fn glyph(c: char) -> [u8; 7] {
    const DIGITS: [[u8; 7]; 10] = [
        [0x0E, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0E],
        [0x04, 0x0C, 0x04, 0x04, 0x04, 0x04, 0x0E],
        [0x0E, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1F],
        [0x1F, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0E],
        [0x02, 0x06, 0x0A, 0x12, 0x1F, 0x02, 0x02],
        [0x1F, 0x10, 0x1E, 0x01, 0x01, 0x11, 0x0E],
        [0x06, 0x08, 0x10, 0x1E, 0x11, 0x11, 0x0E],
        [0x1F, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08],
        [0x0E, 0x11, 0x11, 0x0E, 0x11, 0x11, 0x0E],
        [0x0E, 0x11, 0x11, 0x0F, 0x01, 0x02, 0x0C],
    ];
    const LETTERS: [[u8; 7]; 26] = [
        [0x0E, 0x11, 0x11, 0x11, 0x1F, 0x11, 0x11],
        [0x1E, 0x11, 0x11, 0x1E, 0x11, 0x11, 0x1E],
        [0x0E, 0x11, 0x10, 0x10, 0x10, 0x11, 0x0E],
        [0x1C, 0x12, 0x11, 0x11, 0x11, 0x12, 0x1C],
        [0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x1F],
        [0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x10],
        [0x0E, 0x11, 0x10, 0x17, 0x11, 0x11, 0x0F],
        [0x11, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11],
        [0x0E, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0E],
        [0x07, 0x02, 0x02, 0x02, 0x02, 0x12, 0x0C],
        [0x11, 0x12, 0x14, 0x18, 0x14, 0x12, 0x11],
        [0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x1F],
        [0x11, 0x1B, 0x15, 0x15, 0x11, 0x11, 0x11],
        [0x11, 0x11, 0x19, 0x15, 0x13, 0x11, 0x11],
        [0x0E, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E],
        [0x1E, 0x11, 0x11, 0x1E, 0x10, 0x10, 0x10],
        [0x0E, 0x11, 0x11, 0x11, 0x15, 0x12, 0x0D],
        [0x1E, 0x11, 0x11, 0x1E, 0x14, 0x12, 0x11],
        [0x0F, 0x10, 0x10, 0x0E, 0x01, 0x01, 0x1E],
        [0x1F, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04],
        [0x11, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E],
        [0x11, 0x11, 0x11, 0x11, 0x11, 0x0A, 0x04],
        [0x11, 0x11, 0x11, 0x15, 0x15, 0x15, 0x0A],
        [0x11, 0x11, 0x0A, 0x04, 0x0A, 0x11, 0x11],
        [0x11, 0x11, 0x11, 0x0A, 0x04, 0x04, 0x04],
        [0x1F, 0x01, 0x02, 0x04, 0x08, 0x10, 0x1F],
    ];
    match c {
        '0'..='9' => DIGITS[c as usize - '0' as usize],
        'm' => [0x00, 0x00, 0x1A, 0x15, 0x15, 0x11, 0x11],
        'a'..='z' => LETTERS[c as usize - 'a' as usize],
        'A'..='Z' => LETTERS[c as usize - 'A' as usize],
        '-' => [0, 0, 0, 0x1F, 0, 0, 0],
        '+' => [0, 0x04, 0x04, 0x1F, 0x04, 0x04, 0],
        '.' => [0, 0, 0, 0, 0, 0x0C, 0x0C],
        '_' => [0, 0, 0, 0, 0, 0, 0x1F],
        ' ' => [0; 7],
        _ => [0x1F, 0x11, 0x11, 0x11, 0x11, 0x11, 0x1F],
    }
}

/// Standard base64 (RFC 4648, with padding) of `bytes`, for `data:` URIs.
pub fn base64(bytes: &[u8]) -> String {
    const ABC: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            *chunk.get(1).unwrap_or(&0),
            *chunk.get(2).unwrap_or(&0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(ABC[(n >> (18 - 6 * k)) as usize & 63] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_of_rfc4648_vectors() {
        for (raw, enc) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(base64(raw.as_bytes()), enc);
        }
        assert_eq!(base64(&[0xfb, 0xff, 0xbf]), "+/+/");
    }

    #[test]
    fn turbo_runs_from_blue_to_red() {
        let (a, m, b) = (range_colour(0.0), range_colour(0.5), range_colour(1.0));
        assert!(a[2] > a[0] && a[2] > 150, "{a:?}");
        assert!(m[1] > 200, "{m:?}");
        assert!(b[0] > b[2] && b[0] > 150, "{b:?}");
        assert_eq!(turbo(f64::NAN), turbo(0.5));
    }

    #[test]
    fn every_glyph_fits_five_columns() {
        for c in (' '..='~').chain(['é']) {
            assert!(glyph(c).iter().all(|r| r & !0x1F == 0), "{c}");
        }
    }
}
