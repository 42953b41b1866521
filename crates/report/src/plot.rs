//! Minimal SVG plotting: nice numbers, data → pixel frames, axes with ticks.

use crate::fmt::{c, escape, tick_label};
use std::fmt::Write;

/// The 1-2-5 × 10^k number nearest (in log scale) to `v` (> 0); 1 for non-positive input.
pub(crate) fn nice_number(v: f64) -> f64 {
    if !v.is_finite() || v <= 0.0 {
        return 1.0;
    }
    let exp = v.log10().floor();
    let base = 10f64.powf(exp);
    let f = v / base;
    // geometric midpoints between 1, 2, 5 and 10
    let n = if f < std::f64::consts::SQRT_2 {
        1.0
    } else if f < 10f64.sqrt() {
        2.0
    } else if f < 50f64.sqrt() {
        5.0
    } else {
        10.0
    };
    n * base
}

/// A nice tick step that gives about `count` intervals over `range`.
pub(crate) fn nice_step(range: f64, count: usize) -> f64 {
    nice_number(range / count.max(1) as f64)
}

/// Tick values (multiples of `step`) inside `[lo, hi]`.
pub(crate) fn ticks(lo: f64, hi: f64, step: f64) -> Vec<f64> {
    let mut out = Vec::new();
    if !(lo.is_finite() && hi.is_finite() && step.is_finite() && step > 0.0) {
        return out;
    }
    let first = (lo / step).ceil() as i64;
    let last = (hi / step + 1e-9).floor() as i64;
    for k in first..=last.min(first + 200) {
        out.push(k as f64 * step);
    }
    out
}

/// 2D bounds of finite points.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Bounds {
    pub min: [f64; 2],
    pub max: [f64; 2],
    pub any: bool,
}

impl Bounds {
    pub fn new() -> Self {
        Bounds {
            min: [f64::INFINITY; 2],
            max: [f64::NEG_INFINITY; 2],
            any: false,
        }
    }

    /// Adds a point; non-finite points are ignored.
    pub fn add(&mut self, x: f64, y: f64) {
        if !(x.is_finite() && y.is_finite()) {
            return;
        }
        self.min[0] = self.min[0].min(x);
        self.min[1] = self.min[1].min(y);
        self.max[0] = self.max[0].max(x);
        self.max[1] = self.max[1].max(y);
        self.any = true;
    }
}

/// Maps data coordinates (y up) to SVG pixels inside a plot rectangle.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Frame {
    pub x0: f64,
    pub x1: f64,
    pub y0: f64,
    pub y1: f64,
    pub left: f64,
    pub top: f64,
    pub w: f64,
    pub h: f64,
}

/// Space around the plot rectangle for ticks and axis labels.
pub(crate) const MARGIN_LEFT: f64 = 58.0;
pub(crate) const MARGIN_RIGHT: f64 = 14.0;
pub(crate) const MARGIN_TOP: f64 = 12.0;
pub(crate) const MARGIN_BOTTOM: f64 = 40.0;

impl Frame {
    /// The SVG path data (`M x y L x y …`) of the polyline through data points `pts`.
    pub fn path(&self, pts: &[(f64, f64)]) -> String {
        pts.iter()
            .enumerate()
            .map(|(i, p)| {
                let m = if i == 0 { "M" } else { "L" };
                format!("{m}{} {}", c(self.px(p.0)), c(self.py(p.1)))
            })
            .collect()
    }

    pub fn px(&self, x: f64) -> f64 {
        self.left + (x - self.x0) / (self.x1 - self.x0) * self.w
    }

    pub fn py(&self, y: f64) -> f64 {
        self.top + (self.y1 - y) / (self.y1 - self.y0) * self.h
    }

    /// Pixels per data unit along x.
    pub fn scale_x(&self) -> f64 {
        self.w / (self.x1 - self.x0)
    }

    /// Total SVG width and height including the margins.
    pub fn svg_size(&self) -> (f64, f64) {
        (
            self.left + self.w + MARGIN_RIGHT,
            self.top + self.h + MARGIN_BOTTOM,
        )
    }

    /// An equal-aspect frame around `b` (padded by 6 %) fitting in `max_w` × `max_h` plot
    /// pixels; degenerate bounds get a minimum extent of `min_extent` data units.
    pub fn equal_aspect(b: &Bounds, max_w: f64, max_h: f64, min_extent: f64) -> Frame {
        let (mut x0, mut x1, mut y0, mut y1) = if b.any {
            (b.min[0], b.max[0], b.min[1], b.max[1])
        } else {
            (-1.0, 1.0, -1.0, 1.0)
        };
        let ext = (x1 - x0).max(y1 - y0).max(min_extent);
        let pad = 0.06 * ext;
        for (lo, hi) in [(&mut x0, &mut x1), (&mut y0, &mut y1)] {
            let span = *hi - *lo;
            if span < 0.25 * ext {
                // Keep very thin views readable: widen the short side around its centre.
                let mid = 0.5 * (*lo + *hi);
                *lo = mid - 0.125 * ext;
                *hi = mid + 0.125 * ext;
            }
            *lo -= pad;
            *hi += pad;
        }
        let s = (max_w / (x1 - x0)).min(max_h / (y1 - y0));
        Frame {
            x0,
            x1,
            y0,
            y1,
            left: MARGIN_LEFT,
            top: MARGIN_TOP,
            w: (x1 - x0) * s,
            h: (y1 - y0) * s,
        }
    }
}

/// Opens a `<figure>` holding a chart of frame `f`: its `<svg>` (labelled `label`) and its
/// axes, labelled `[x, y]`.
pub(crate) fn open_chart(out: &mut String, f: &Frame, label: &str, [x, y]: [&str; 2]) {
    let (w, h) = f.svg_size();
    out.push_str("<figure>\n");
    svg_open(out, w, h, label);
    axes(out, f, x, y);
}

/// Opens an `<svg>` element of the given size with an accessible label.
pub(crate) fn svg_open(out: &mut String, w: f64, h: f64, label: &str) {
    let _ = write!(
        out,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" viewBox="0 0 {w} {h}" role="img" aria-label="{l}">"#,
        w = c(w),
        h = c(h),
        l = escape(label)
    );
    out.push('\n');
}

/// Draws the plot rectangle, grid lines, ticks with nice numbers and the axis labels.
pub(crate) fn axes(out: &mut String, f: &Frame, xlabel: &str, ylabel: &str) {
    axes_with(out, f, xlabel, ylabel, true);
}

/// [`axes`], with the x ticks left out when `x_ticks` is false (categories on x).
pub(crate) fn axes_with(out: &mut String, f: &Frame, xlabel: &str, ylabel: &str, x_ticks: bool) {
    let nx = ((f.w / 90.0).round() as usize).clamp(2, 10);
    let ny = ((f.h / 60.0).round() as usize).clamp(2, 10);
    let sx = nice_step(f.x1 - f.x0, nx);
    let sy = nice_step(f.y1 - f.y0, ny);
    let (l, t, r, b) = (f.left, f.top, f.left + f.w, f.top + f.h);
    let mut grid = String::new();
    let mut labels = String::new();
    for v in ticks(f.x0, f.x1, sx).into_iter().filter(|_| x_ticks) {
        let x = c(f.px(v));
        let _ = write!(grid, "M{x} {}V{}", c(t), c(b + 4.0));
        let _ = write!(
            labels,
            r#"<text x="{x}" y="{}" text-anchor="middle">{}</text>"#,
            c(b + 15.0),
            tick_label(v, sx)
        );
    }
    for v in ticks(f.y0, f.y1, sy) {
        let y = c(f.py(v));
        let _ = write!(grid, "M{} {y}H{}", c(l - 4.0), c(r));
        let _ = write!(
            labels,
            r#"<text x="{}" y="{}" text-anchor="end">{}</text>"#,
            c(l - 6.0),
            c(f.py(v) + 3.5),
            tick_label(v, sy)
        );
    }
    let _ = write!(
        out,
        r##"<rect x="{}" y="{}" width="{}" height="{}" fill="#fff" stroke="#888"/><path d="{grid}" stroke="#ddd" fill="none"/><g class="tick">{labels}</g>"##,
        c(l),
        c(t),
        c(f.w),
        c(f.h)
    );
    let _ = write!(
        out,
        r#"<text class="axis" x="{}" y="{}" text-anchor="middle">{}</text>"#,
        c(l + 0.5 * f.w),
        c(b + 32.0),
        escape(xlabel)
    );
    let _ = write!(
        out,
        r#"<text class="axis" transform="translate({} {}) rotate(-90)" text-anchor="middle">{}</text>"#,
        c(14.0),
        c(t + 0.5 * f.h),
        escape(ylabel)
    );
    out.push('\n');
}

/// The p-quantile (0..1) of finite values (nearest rank); `None` when there are none.
pub(crate) fn quantile(values: &[f64], p: f64) -> Option<f64> {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let k = ((p * v.len() as f64).ceil() as usize).clamp(1, v.len()) - 1;
    Some(v[k])
}

/// Greedy placement of small point labels (10 px font) that avoids other labels and the
/// markers registered as obstacles; far placements get a thin leader line.
pub(crate) struct LabelPlacer {
    boxes: Vec<[f64; 4]>,
    clip: [f64; 4],
    pub out: String,
}

const CHAR_W: f64 = 6.0;
const TEXT_H: f64 = 10.0;

fn overlap(a: &[f64; 4], b: &[f64; 4]) -> f64 {
    let w = (a[2].min(b[2]) - a[0].max(b[0])).max(0.0);
    let h = (a[3].min(b[3]) - a[1].max(b[1])).max(0.0);
    w * h
}

impl LabelPlacer {
    /// Labels are kept inside `clip` = [x0, y0, x1, y1] (SVG px) when possible.
    pub fn new(clip: [f64; 4]) -> Self {
        LabelPlacer {
            boxes: Vec::new(),
            clip,
            out: String::new(),
        }
    }

    /// Registers a marker of radius `r` at (x, y) that labels should not cover.
    pub fn obstacle(&mut self, x: f64, y: f64, r: f64) {
        self.boxes.push([x - r, y - r, x + r, y + r]);
    }

    /// Places `text` (unescaped) next to the marker of radius `r` at (x, y).
    pub fn place(&mut self, x: f64, y: f64, r: f64, text: &str, colour: &str) {
        let w = CHAR_W * text.chars().count() as f64 + 2.0;
        let mut best: Option<(f64, [f64; 4], bool)> = None;
        for ring in [1.0, 2.4, 4.0] {
            let d = r * ring + 2.0 * ring;
            let candidates = [
                (x + d, y - d - TEXT_H),
                (x + d, y + d),
                (x - d - w, y - d - TEXT_H),
                (x - d - w, y + d),
                (x + d + 1.0, y - TEXT_H / 2.0),
                (x - d - w - 1.0, y - TEXT_H / 2.0),
                (x - w / 2.0, y - d - TEXT_H - 1.0),
                (x - w / 2.0, y + d + 1.0),
            ];
            for (bx, by) in candidates {
                let b = [bx, by, bx + w, by + TEXT_H];
                let outside = b[0] < self.clip[0]
                    || b[1] < self.clip[1]
                    || b[2] > self.clip[2]
                    || b[3] > self.clip[3];
                let cost: f64 = self.boxes.iter().map(|o| overlap(o, &b)).sum::<f64>()
                    + if outside { 1e6 } else { 0.0 }
                    + ring * 1e-3;
                if best.is_none_or(|(c0, _, _)| cost < c0) {
                    best = Some((cost, b, ring > 1.0));
                }
            }
            if best.is_some_and(|(c0, _, _)| c0 < 1.0) {
                break;
            }
        }
        let Some((_, b, leader)) = best else { return };
        if leader {
            let (lx, ly) = (x.clamp(b[0], b[2]), y.clamp(b[1], b[3]));
            let _ = write!(
                self.out,
                r#"<path d="M{} {}L{} {}" stroke="{colour}" stroke-width="0.6" fill="none"/>"#,
                c(x),
                c(y),
                c(lx),
                c(ly)
            );
        }
        let _ = write!(
            self.out,
            r#"<text class="lbl" x="{}" y="{}" style="fill:{colour}">{}</text>"#,
            c(b[0] + 1.0),
            c(b[3] - 1.5),
            escape(text)
        );
        self.boxes.push(b);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nice_numbers() {
        assert_eq!(nice_number(0.9), 1.0);
        assert_eq!(nice_number(2.9), 2.0);
        assert_eq!(nice_number(4.0), 5.0);
        assert_eq!(nice_number(80.0), 100.0);
        assert_eq!(nice_number(0.0), 1.0);
        assert_eq!(nice_number(f64::NAN), 1.0);
        assert_eq!(ticks(-120.0, 480.0, 200.0), vec![0.0, 200.0, 400.0]);
        assert!(ticks(0.0, f64::NAN, 1.0).is_empty());
    }

    #[test]
    fn quantiles() {
        let v = [5.0, 1.0, f64::NAN, 3.0, 2.0, 4.0];
        assert_eq!(quantile(&v, 0.5), Some(3.0));
        assert_eq!(quantile(&v, 0.95), Some(5.0));
        assert_eq!(quantile(&[], 0.5), None);
    }

    #[test]
    fn equal_aspect_keeps_scale() {
        let mut b = Bounds::new();
        b.add(0.0, 0.0);
        b.add(1000.0, 500.0);
        b.add(f64::NAN, 1e9);
        let f = Frame::equal_aspect(&b, 600.0, 600.0, 1.0);
        let sx = f.w / (f.x1 - f.x0);
        let sy = f.h / (f.y1 - f.y0);
        assert!((sx - sy).abs() < 1e-9);
        assert!(f.w <= 600.0 + 1e-9 && f.h <= 600.0 + 1e-9);
    }
}
