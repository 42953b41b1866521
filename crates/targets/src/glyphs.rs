//! The sheets' text as outlines: every character drawn from one font embedded in pingcal
//! (DejaVu Sans, its printable ASCII subset; `fonts/LICENSE-DejaVu.txt`), so that a printed
//! sheet looks the same on every machine. A PDF's standard Helvetica was not embedded: each
//! renderer put its own font in its place (URW's Nimbus Sans where Ghostscript's fonts are
//! installed, Liberation or DejaVu elsewhere), and the insides of Nimbus's digits read as 17
//! plain targets where the detector had been tried on the others.
//!
//! [`outline`] gives a text's outline in page millimetres (y down) as path segments, quadratic
//! curves raised to cubic ones (`c₁ = p₀ + ⅔(q − p₀)`, `c₂ = p + ⅔(q − p)`), to be filled with
//! the nonzero rule as TrueType outlines are.

/// The embedded font.
const FONT: &[u8] = include_bytes!("../fonts/DejaVuSans-ascii.ttf");

/// One segment of an outline (page millimetres, y down).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Segment {
    /// Starts a contour.
    Move(f64, f64),
    /// A straight line to.
    Line(f64, f64),
    /// A cubic Bézier: two control points and the end.
    Cubic([f64; 6]),
    /// Closes the contour.
    Close,
}

fn face() -> ttf_parser::Face<'static> {
    ttf_parser::Face::parse(FONT, 0).expect("the embedded font parses")
}

/// The advance width of `text` at `size` (mm per em); characters the font lacks (outside
/// printable ASCII) count as a space.
pub fn width(text: &str, size: f64) -> f64 {
    let f = face();
    let em = f64::from(f.units_per_em());
    let space = f.glyph_index(' ');
    text.chars()
        .filter_map(|c| f.glyph_index(c).or(space))
        .filter_map(|g| f.glyph_hor_advance(g))
        .map(|a| f64::from(a) / em * size)
        .sum()
}

/// The outline of `text` at `size` (mm per em) starting at `left` on the baseline `y`.
pub fn outline(text: &str, left: f64, y: f64, size: f64) -> Vec<Segment> {
    let f = face();
    let s = size / f64::from(f.units_per_em());
    let space = f.glyph_index(' ');
    let mut b = Builder {
        out: Vec::new(),
        origin: (left, y),
        scale: s,
        last: (0.0, 0.0),
    };
    for c in text.chars() {
        let Some(g) = f.glyph_index(c).or(space) else {
            continue;
        };
        f.outline_glyph(g, &mut b);
        b.origin.0 += f64::from(f.glyph_hor_advance(g).unwrap_or(0)) * s;
    }
    b.out
}

/// Collects a glyph's outline in page millimetres.
struct Builder {
    out: Vec<Segment>,
    /// The glyph's origin on the page.
    origin: (f64, f64),
    /// Millimetres per font unit.
    scale: f64,
    /// The current point (page).
    last: (f64, f64),
}

impl Builder {
    fn at(&self, x: f32, y: f32) -> (f64, f64) {
        (
            self.origin.0 + f64::from(x) * self.scale,
            self.origin.1 - f64::from(y) * self.scale,
        )
    }
}

impl ttf_parser::OutlineBuilder for Builder {
    fn move_to(&mut self, x: f32, y: f32) {
        self.last = self.at(x, y);
        self.out.push(Segment::Move(self.last.0, self.last.1));
    }

    fn line_to(&mut self, x: f32, y: f32) {
        self.last = self.at(x, y);
        self.out.push(Segment::Line(self.last.0, self.last.1));
    }

    fn quad_to(&mut self, x1: f32, y1: f32, x: f32, y: f32) {
        let (p0, q, p) = (self.last, self.at(x1, y1), self.at(x, y));
        let c1 = (
            p0.0 + 2.0 / 3.0 * (q.0 - p0.0),
            p0.1 + 2.0 / 3.0 * (q.1 - p0.1),
        );
        let c2 = (p.0 + 2.0 / 3.0 * (q.0 - p.0), p.1 + 2.0 / 3.0 * (q.1 - p.1));
        self.out
            .push(Segment::Cubic([c1.0, c1.1, c2.0, c2.1, p.0, p.1]));
        self.last = p;
    }

    fn curve_to(&mut self, x1: f32, y1: f32, x2: f32, y2: f32, x: f32, y: f32) {
        let (c1, c2, p) = (self.at(x1, y1), self.at(x2, y2), self.at(x, y));
        self.out
            .push(Segment::Cubic([c1.0, c1.1, c2.0, c2.1, p.0, p.1]));
        self.last = p;
    }

    fn close(&mut self) {
        self.out.push(Segment::Close);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every printable ASCII character is in the font; a digit's outline spans its em's
    /// height above the baseline and its advance; the width of a text is its glyphs'.
    #[test]
    fn the_embedded_font_draws_every_printable_character() {
        let f = face();
        for c in (0x20u8..0x7f).map(char::from) {
            assert!(f.glyph_index(c).is_some(), "{c:?} missing");
        }
        let o = outline("8", 10.0, 20.0, 5.0);
        let ys: Vec<f64> = (o.iter())
            .filter_map(|s| match s {
                Segment::Move(_, y) | Segment::Line(_, y) => Some(*y),
                Segment::Cubic(c) => Some(c[5]),
                Segment::Close => None,
            })
            .collect();
        let top = ys.iter().cloned().fold(f64::INFINITY, f64::min);
        let bottom = ys.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
        // DejaVu's digits stand 0.73 em above the baseline
        assert!((20.0 - top - 0.73 * 5.0).abs() < 0.1, "top {top}");
        assert!((bottom - 20.0).abs() < 0.15, "bottom {bottom}");
        assert!((width("88", 5.0) - 2.0 * width("8", 5.0)).abs() < 1e-12);
        assert!(
            o.iter().filter(|s| **s == Segment::Close).count() >= 3,
            "8 has three contours"
        );
    }
}
