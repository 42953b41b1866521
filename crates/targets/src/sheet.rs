//! Printable sheets of targets: pages of a paper size with as many coded and plain targets
//! as fit, each page with its header and a 100 mm scale bar, drawn once as [`Shape`]s and
//! written as PDF ([`to_pdf`]) or SVG ([`to_svg`]) from the same shapes.
//!
//! Page coordinates are millimetres from the page's top-left corner, y down. A coded target
//! is the AICON geometry of [`crate::printable`] (in dot radii R: a white dot of radius 1, the
//! code ring between `ring.0` and `ring.1`, on a black square of side 8, its number under the
//! square); a plain target is the white dot on a black square of side 4. The scale bar is a
//! black bar of exactly 100 × 2 mm with a tick every 10 mm: measured on the print, it tells
//! whether the printer scaled the page (print at 100 %, no fit-to-page).

use crate::aicon::CodeTable;
use crate::glyphs::Segment;
use crate::printable::SQUARE_HALF;
use crate::TargetError;
use std::f64::consts::PI;
use std::fmt::Write;

/// A paper size.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PageSize {
    /// ISO A4, 210 × 297 mm.
    A4,
    /// ISO A3, 297 × 420 mm.
    A3,
    /// US Letter, 8.5 × 11 in.
    Letter,
}

impl PageSize {
    /// Width and height (mm), portrait.
    pub fn mm(self) -> (f64, f64) {
        match self {
            PageSize::A4 => (210.0, 297.0),
            PageSize::A3 => (297.0, 420.0),
            PageSize::Letter => (215.9, 279.4),
        }
    }

    /// The size named `a4`, `a3` or `letter` (any case).
    pub fn parse(s: &str) -> Result<Self, TargetError> {
        match s.to_ascii_lowercase().as_str() {
            "a4" => Ok(PageSize::A4),
            "a3" => Ok(PageSize::A3),
            "letter" => Ok(PageSize::Letter),
            _ => Err(TargetError::Invalid(format!(
                "page size '{s}': expected a4, a3 or letter"
            ))),
        }
    }

    pub(crate) fn name(self) -> &'static str {
        match self {
            PageSize::A4 => "A4",
            PageSize::A3 => "A3",
            PageSize::Letter => "Letter",
        }
    }
}

/// What to print.
#[derive(Clone, Debug, PartialEq)]
pub struct SheetSpec {
    /// Ring sectors of the coded targets (14 or 12).
    pub bits: u32,
    /// Numbers of the coded targets, in print order (each once).
    pub ids: Vec<u32>,
    /// How many plain targets after them.
    pub plain: usize,
    /// Radius of the central dot (mm): the project's `dot_radius_mm`.
    pub dot_radius_mm: f64,
    /// The code ring's inner and outer radius, in dot radii: the project's `ring_inner`,
    /// `ring_outer`.
    pub ring: (f64, f64),
    /// The paper.
    pub page: PageSize,
}

/// One thing drawn, in page millimetres (y down); `white` fills white, else black.
#[derive(Clone, Debug, PartialEq)]
pub enum Shape {
    /// An axis-aligned rectangle from its top-left corner.
    Rect {
        /// Left edge.
        x: f64,
        /// Top edge.
        y: f64,
        /// Width.
        w: f64,
        /// Height.
        h: f64,
        /// Fill.
        white: bool,
    },
    /// A disc.
    Disc {
        /// Centre x.
        cx: f64,
        /// Centre y.
        cy: f64,
        /// Radius.
        r: f64,
        /// Fill.
        white: bool,
    },
    /// An annular sector between radii `r0 < r1` and page angles `a0 < a1` (radians,
    /// measured from +x towards +y, that is clockwise on the page).
    Sector {
        /// Centre x.
        cx: f64,
        /// Centre y.
        cy: f64,
        /// Inner radius.
        r0: f64,
        /// Outer radius.
        r1: f64,
        /// Start angle.
        a0: f64,
        /// End angle.
        a1: f64,
        /// Fill.
        white: bool,
    },
    /// Black text with its baseline at `y`, drawn as the outlines of the font pingcal embeds
    /// ([`crate::glyphs`]); centred on `x` when `centred`, else starting at `x`.
    Text {
        /// Anchor x.
        x: f64,
        /// Baseline y.
        y: f64,
        /// Font size (mm, the em height).
        size: f64,
        /// The text (printable ASCII).
        text: String,
        /// Centred on x.
        centred: bool,
    },
}

/// One page: its shapes, in drawing order.
#[derive(Clone, Debug, PartialEq)]
pub struct Page {
    /// Shapes.
    pub shapes: Vec<Shape>,
}

/// Margin on every side (mm): inside what office printers can print.
pub(crate) const MARGIN: f64 = 10.0;
/// Height of the header (mm).
pub(crate) const HEADER: f64 = 8.0;
/// Height of the footer with the scale bar (mm).
pub(crate) const FOOTER: f64 = 16.0;
/// The scale bar's length (mm).
pub const SCALE_BAR_MM: f64 = 100.0;
/// The scale bar's height (mm).
pub const SCALE_BAR_HEIGHT_MM: f64 = 2.0;

/// A target to place: its size and how to draw it at a centre.
enum Item {
    Coded { id: u32, code: u32 },
    Plain,
}

impl Item {
    /// Half the side of its black square, in dot radii.
    fn half(&self) -> f64 {
        match self {
            Item::Coded { .. } => SQUARE_HALF,
            Item::Plain => 2.0,
        }
    }
}

/// The pages of `spec`. Refused: no target, a code number outside the table, a dot radius
/// that is not a positive length, a ring that is not 1 < inner < outer ≤ 4, a target that
/// does not fit on the page.
pub fn layout(spec: &SheetSpec) -> Result<Vec<Page>, TargetError> {
    let items = items(spec)?;
    let r = spec.dot_radius_mm;
    let (pw, ph) = spec.page.mm();
    let gap = r.max(3.0);
    let label = 1.5 * r;
    let cell = |it: &Item| {
        let side = 2.0 * it.half() * r;
        let h = side
            + if matches!(it, Item::Coded { .. }) {
                1.3 * label
            } else {
                0.0
            };
        (side + gap, h + gap)
    };
    let (x0, y0) = (MARGIN, MARGIN + HEADER);
    let (x1, y1) = (pw - MARGIN, ph - MARGIN - FOOTER);
    let big = items
        .iter()
        .map(&cell)
        .fold((0.0f64, 0.0f64), |a, c| (a.0.max(c.0), a.1.max(c.1)));
    if big.0 - gap > x1 - x0 || big.1 - gap > y1 - y0 {
        return Err(TargetError::Invalid(format!(
            "a target with a dot radius of {r} mm is {:.0} mm wide: it does not fit on an {} page; a larger page or a smaller dot",
            big.0 - gap,
            spec.page.name()
        )));
    }
    let mut pages: Vec<Vec<Shape>> = vec![Vec::new()];
    let (mut x, mut y, mut row_h) = (x0, y0, 0.0f64);
    for it in &items {
        let (w, h) = cell(it);
        if x + w - gap > x1 + 1e-9 {
            (x, y, row_h) = (x0, y + row_h, 0.0);
        }
        if y + h - gap > y1 + 1e-9 {
            pages.push(Vec::new());
            (x, y, row_h) = (x0, y0, 0.0);
        }
        let half = it.half() * r;
        let shapes = pages.last_mut().expect("one page at least");
        draw_item(shapes, it, x + half, y + half, r, spec);
        x += w;
        row_h = row_h.max(h);
    }
    let n = pages.len();
    Ok(pages
        .into_iter()
        .enumerate()
        .map(|(k, shapes)| {
            let mut all = header_and_scale_bar(spec, k + 1, n);
            all.extend(shapes);
            Page { shapes: all }
        })
        .collect())
}

/// The coded targets of `spec` with their codes, then its plain targets.
fn items(spec: &SheetSpec) -> Result<Vec<Item>, TargetError> {
    let r = spec.dot_radius_mm;
    if !(r > 0.0 && r < 500.0) {
        return Err(TargetError::Invalid(format!(
            "dot radius must be a positive number of mm below 500, not {r}"
        )));
    }
    let (ri, ro) = spec.ring;
    if !(ri > 1.0 && ro > ri && ro <= SQUARE_HALF) {
        return Err(TargetError::Invalid(format!(
            "ring {ri}–{ro} dot radii: expected 1 < inner < outer ≤ {SQUARE_HALF}"
        )));
    }
    let table = CodeTable::generate(spec.bits)?;
    let mut items = Vec::with_capacity(spec.ids.len() + spec.plain);
    for &id in &spec.ids {
        let code = table.code(id).ok_or_else(|| {
            TargetError::Invalid(format!(
                "{}-bit codes are numbered 1 to {}; {id} does not exist",
                spec.bits,
                table.codes.len()
            ))
        })?;
        items.push(Item::Coded { id, code });
    }
    items.extend((0..spec.plain).map(|_| Item::Plain));
    if items.is_empty() {
        return Err(TargetError::Invalid(
            "nothing to print: no coded target and no plain target".into(),
        ));
    }
    Ok(items)
}

/// A target centred on (cx, cy).
fn draw_item(out: &mut Vec<Shape>, it: &Item, cx: f64, cy: f64, r: f64, spec: &SheetSpec) {
    let half = it.half() * r;
    out.push(Shape::Rect {
        x: cx - half,
        y: cy - half,
        w: 2.0 * half,
        h: 2.0 * half,
        white: false,
    });
    out.push(Shape::Disc {
        cx,
        cy,
        r,
        white: true,
    });
    let Item::Coded { id, code } = it else {
        return;
    };
    // Runs of set bits are drawn as one sector each. Bit i spans page angles
    // [−(i+1)·step, −i·step] (counter-clockwise on the page, as `printable` reads them).
    let step = 2.0 * PI / spec.bits as f64;
    let mut i = 0;
    while i < spec.bits {
        if code >> i & 1 == 0 {
            i += 1;
            continue;
        }
        let mut j = i;
        while j + 1 < spec.bits && code >> (j + 1) & 1 == 1 {
            j += 1;
        }
        out.push(Shape::Sector {
            cx,
            cy,
            r0: spec.ring.0 * r,
            r1: spec.ring.1 * r,
            a0: -((j + 1) as f64) * step,
            a1: -(i as f64) * step,
            white: true,
        });
        i = j + 1;
    }
    let label = 1.5 * r;
    out.push(Shape::Text {
        x: cx,
        y: cy + half + 1.1 * label,
        size: label,
        text: id.to_string(),
        centred: true,
    });
}

/// The header (what is printed and how to print it) and the scale bar of page `k` of `n`.
fn header_and_scale_bar(spec: &SheetSpec, k: usize, n: usize) -> Vec<Shape> {
    let (_, ph) = spec.page.mm();
    let mut out = vec![Shape::Text {
        x: MARGIN,
        y: MARGIN + 3.5,
        size: 3.5,
        text: format!(
            "pingcal targets - AICON {}-bit - dot_radius_mm = {} - ring {} to {} - page {k} of {n} - print at 100 %, no fit to page",
            spec.bits, spec.dot_radius_mm, spec.ring.0, spec.ring.1
        ),
        centred: false,
    }];
    out.extend(scale_bar(ph));
    out
}

/// The 100 mm scale bar at the foot of a page `ph` mm high, with its ticks and labels.
pub(crate) fn scale_bar(ph: f64) -> Vec<Shape> {
    let mut out = Vec::new();
    let (x, y) = (MARGIN, ph - MARGIN - SCALE_BAR_HEIGHT_MM - 4.0);
    out.push(Shape::Rect {
        x,
        y,
        w: SCALE_BAR_MM,
        h: SCALE_BAR_HEIGHT_MM,
        white: false,
    });
    for t in 0..=10 {
        let tx = x + 10.0 * t as f64;
        let tick = if t % 5 == 0 { 3.0 } else { 1.5 };
        // ticks centred on their mark, kept inside the bar's 100 mm at both ends
        let left = (tx - 0.15).clamp(x, x + SCALE_BAR_MM - 0.3);
        out.push(Shape::Rect {
            x: left,
            y: y - tick,
            w: 0.3,
            h: tick,
            white: false,
        });
    }
    for (t, label) in [(0.0, "0"), (50.0, "50"), (100.0, "100 mm")] {
        out.push(Shape::Text {
            x: x + t,
            y: y + SCALE_BAR_HEIGHT_MM + 3.5,
            size: 3.0,
            text: label.into(),
            centred: true,
        });
    }
    out.push(Shape::Text {
        x: x + SCALE_BAR_MM + 6.0,
        y: y + SCALE_BAR_HEIGHT_MM,
        size: 3.0,
        text: "this bar is 100 mm long: measure it on the print".into(),
        centred: false,
    });
    out
}

/// An SVG document of one page.
pub fn to_svg(page: &Page, size: PageSize) -> String {
    let (w, h) = size.mm();
    let mut s = String::new();
    let _ = writeln!(s, r#"<?xml version="1.0" encoding="UTF-8"?>"#);
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}mm" height="{h}mm" viewBox="0 0 {w} {h}">"#
    );
    let _ = writeln!(
        s,
        r#"<rect x="0" y="0" width="{w}" height="{h}" fill="white"/>"#
    );
    let fill = |white: bool| if white { "white" } else { "black" };
    for sh in &page.shapes {
        let _ = match sh {
            Shape::Rect { x, y, w, h, white } => writeln!(
                s,
                r#"<rect x="{x:.4}" y="{y:.4}" width="{w:.4}" height="{h:.4}" fill="{}"/>"#,
                fill(*white)
            ),
            Shape::Disc { cx, cy, r, white } => writeln!(
                s,
                r#"<circle cx="{cx:.4}" cy="{cy:.4}" r="{r:.4}" fill="{}"/>"#,
                fill(*white)
            ),
            Shape::Sector {
                cx,
                cy,
                r0,
                r1,
                a0,
                a1,
                white,
            } => writeln!(
                s,
                r#"<path d="{}" fill="{}"/>"#,
                svg_sector(*cx, *cy, *r0, *r1, *a0, *a1),
                fill(*white)
            ),
            Shape::Text {
                x,
                y,
                size,
                text,
                centred,
            } => {
                let mut d = String::new();
                for seg in text_outline(*x, *y, *size, text, *centred) {
                    let _ = match seg {
                        Segment::Move(x, y) => write!(d, "M{x:.4} {y:.4}"),
                        Segment::Line(x, y) => write!(d, "L{x:.4} {y:.4}"),
                        Segment::Cubic(p) => write!(
                            d,
                            "C{:.4} {:.4} {:.4} {:.4} {:.4} {:.4}",
                            p[0], p[1], p[2], p[3], p[4], p[5]
                        ),
                        Segment::Close => write!(d, "Z"),
                    };
                }
                // the text itself for readers and search, the outline for the eye
                writeln!(
                    s,
                    r#"<path d="{d}" fill="black"><title>{}</title></path>"#,
                    xml_escape(text)
                )
            }
        };
    }
    let _ = writeln!(s, "</svg>");
    s
}

fn xml_escape(t: &str) -> String {
    t.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// The SVG path of an annular sector.
fn svg_sector(cx: f64, cy: f64, r0: f64, r1: f64, a0: f64, a1: f64) -> String {
    let p = |r: f64, a: f64| (cx + r * a.cos(), cy + r * a.sin());
    let large = u8::from(a1 - a0 > PI);
    let (x0, y0) = p(r1, a0);
    let (x1, y1) = p(r1, a1);
    let (x2, y2) = p(r0, a1);
    let (x3, y3) = p(r0, a0);
    format!(
        "M{x0:.4} {y0:.4} A{r1:.4} {r1:.4} 0 {large} 1 {x1:.4} {y1:.4} L{x2:.4} {y2:.4} A{r0:.4} {r0:.4} 0 {large} 0 {x3:.4} {y3:.4} Z"
    )
}

/// Points per millimetre (PDF's unit is 1/72 in).
const PT_PER_MM: f64 = 72.0 / 25.4;

/// A PDF document of `pages` (vector shapes, the text as outlines of the font pingcal embeds,
/// [`crate::glyphs`]: the same on every machine).
pub fn to_pdf(pages: &[Page], size: PageSize) -> Vec<u8> {
    use pdf_writer::{Content, Finish, Pdf, Rect, Ref};
    let (w, h) = size.mm();
    let (wpt, hpt) = ((w * PT_PER_MM) as f32, (h * PT_PER_MM) as f32);
    let mut pdf = Pdf::new();
    let (catalog, tree) = (Ref::new(1), Ref::new(2));
    let page_ref = |k: usize| Ref::new(4 + 2 * k as i32);
    let content_ref = |k: usize| Ref::new(5 + 2 * k as i32);
    pdf.catalog(catalog).pages(tree);
    pdf.pages(tree)
        .kids((0..pages.len()).map(page_ref))
        .count(pages.len() as i32);
    for (k, page) in pages.iter().enumerate() {
        let mut p = pdf.page(page_ref(k));
        p.media_box(Rect::new(0.0, 0.0, wpt, hpt));
        p.parent(tree);
        p.contents(content_ref(k));
        p.finish();
        let mut c = Content::new();
        // page millimetres, y down → points, y up
        c.transform([PT_PER_MM as f32, 0.0, 0.0, -PT_PER_MM as f32, 0.0, hpt]);
        for sh in &page.shapes {
            pdf_shape(&mut c, sh);
        }
        pdf.stream(content_ref(k), &c.finish());
    }
    pdf.finish()
}

/// One shape into a content stream whose user space is page millimetres, y down.
fn pdf_shape(c: &mut pdf_writer::Content, sh: &Shape) {
    let gray = |white: bool| if white { 1.0 } else { 0.0 };
    match sh {
        Shape::Rect { x, y, w, h, white } => {
            c.set_fill_gray(gray(*white));
            c.rect(*x as f32, *y as f32, *w as f32, *h as f32);
            c.fill_nonzero();
        }
        Shape::Disc { cx, cy, r, white } => {
            c.set_fill_gray(gray(*white));
            arc(c, *cx, *cy, *r, 0.0, 2.0 * PI, true);
            c.close_path();
            c.fill_nonzero();
        }
        Shape::Sector {
            cx,
            cy,
            r0,
            r1,
            a0,
            a1,
            white,
        } => {
            c.set_fill_gray(gray(*white));
            arc(c, *cx, *cy, *r1, *a0, *a1, true);
            arc(c, *cx, *cy, *r0, *a1, *a0, false);
            c.close_path();
            c.fill_nonzero();
        }
        Shape::Text {
            x,
            y,
            size,
            text,
            centred,
        } => {
            c.set_fill_gray(0.0);
            let mut any = false;
            for seg in text_outline(*x, *y, *size, text, *centred) {
                any = true;
                match seg {
                    Segment::Move(x, y) => c.move_to(x as f32, y as f32),
                    Segment::Line(x, y) => c.line_to(x as f32, y as f32),
                    Segment::Cubic(p) => c.cubic_to(
                        p[0] as f32,
                        p[1] as f32,
                        p[2] as f32,
                        p[3] as f32,
                        p[4] as f32,
                        p[5] as f32,
                    ),
                    Segment::Close => c.close_path(),
                };
            }
            if any {
                c.fill_nonzero();
            }
        }
    }
}

/// The outline of a text shape: `text` at `size` on the baseline `y`, centred on `x` or
/// starting at it ([`crate::glyphs`]).
fn text_outline(x: f64, y: f64, size: f64, text: &str, centred: bool) -> Vec<Segment> {
    let left = if centred {
        x - crate::glyphs::width(text, size) / 2.0
    } else {
        x
    };
    crate::glyphs::outline(text, left, y, size)
}

/// The arc of radius `r` about (cx, cy) from angle `a0` to `a1` as cubic Béziers of at most
/// 90° each (radial error under 3·10⁻⁴ r); `start` moves to its first point, else draws a
/// line to it.
fn arc(c: &mut pdf_writer::Content, cx: f64, cy: f64, r: f64, a0: f64, a1: f64, start: bool) {
    let n = ((a1 - a0).abs() / (PI / 2.0)).ceil().max(1.0) as usize;
    let da = (a1 - a0) / n as f64;
    let k = 4.0 / 3.0 * (da / 4.0).tan();
    let p = |a: f64| (cx + r * a.cos(), cy + r * a.sin());
    let (x, y) = p(a0);
    if start {
        c.move_to(x as f32, y as f32);
    } else {
        c.line_to(x as f32, y as f32);
    }
    for i in 0..n {
        let (s, e) = (a0 + i as f64 * da, a0 + (i + 1) as f64 * da);
        let (p0, p3) = (p(s), p(e));
        let c1 = (p0.0 - k * r * s.sin(), p0.1 + k * r * s.cos());
        let c2 = (p3.0 + k * r * e.sin(), p3.1 - k * r * e.cos());
        c.cubic_to(
            c1.0 as f32,
            c1.1 as f32,
            c2.0 as f32,
            c2.1 as f32,
            p3.0 as f32,
            p3.1 as f32,
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(ids: Vec<u32>, plain: usize, r: f64, page: PageSize) -> SheetSpec {
        SheetSpec {
            bits: 14,
            ids,
            plain,
            dot_radius_mm: r,
            ring: (2.0, 3.0),
            page,
        }
    }

    fn targets_on(p: &Page) -> usize {
        p.shapes
            .iter()
            .filter(|s| matches!(s, Shape::Disc { .. }))
            .count()
    }

    #[test]
    fn as_many_targets_per_page_as_fit_and_every_page_has_its_scale_bar() {
        // dot radius 4 mm: a 32 mm square + 4 mm gap → 5 columns in 190 mm
        let pages = layout(&spec((1..=60).collect(), 10, 4.0, PageSize::A4)).unwrap();
        assert!(pages.len() >= 2, "{} pages", pages.len());
        let total: usize = pages.iter().map(targets_on).sum();
        assert_eq!(total, 70, "every target printed once");
        for (k, p) in pages.iter().enumerate() {
            let bar = p.shapes.iter().any(|s| matches!(s, Shape::Rect { w, h, .. } if *w == SCALE_BAR_MM && *h == SCALE_BAR_HEIGHT_MM));
            assert!(bar, "page {k} has its scale bar");
            let head = format!("page {} of {}", k + 1, pages.len());
            assert!(p
                .shapes
                .iter()
                .any(|s| matches!(s, Shape::Text { text, .. } if text.contains(&head))));
            // everything inside the page's margins
            let (w, h) = PageSize::A4.mm();
            for s in &p.shapes {
                if let Shape::Rect {
                    x, y, w: rw, h: rh, ..
                } = s
                {
                    assert!(
                        *x >= MARGIN - 1e-9
                            && *y >= MARGIN
                            && x + rw <= w - MARGIN + 1e-9
                            && y + rh <= h - MARGIN,
                        "{s:?}"
                    );
                }
            }
        }
        // a bigger page holds more
        let a3 = layout(&spec((1..=60).collect(), 10, 4.0, PageSize::A3)).unwrap();
        assert!(a3.len() < pages.len());
    }

    #[test]
    fn bad_sheets_are_refused_with_the_reason() {
        let e = |s: SheetSpec| layout(&s).unwrap_err().to_string();
        assert!(e(spec(vec![], 0, 4.0, PageSize::A4)).contains("nothing to print"));
        assert!(e(spec(vec![517], 0, 4.0, PageSize::A4)).contains("517 does not exist"));
        assert!(e(spec(vec![2], 0, 0.0, PageSize::A4)).contains("dot radius"));
        assert!(e(spec(vec![2], 0, 30.0, PageSize::A4)).contains("does not fit on an A4 page"));
        let mut s = spec(vec![2], 0, 4.0, PageSize::A4);
        s.ring = (3.0, 2.0);
        assert!(e(s).contains("ring"));
        assert!(PageSize::parse("A5").is_err());
        assert_eq!(PageSize::parse("Letter").unwrap(), PageSize::Letter);
    }

    #[test]
    fn the_pdf_has_one_page_per_page_and_the_svg_the_same_shapes() {
        let pages = layout(&spec((1..=60).collect(), 0, 4.0, PageSize::A4)).unwrap();
        let pdf = to_pdf(&pages, PageSize::A4);
        assert!(pdf.starts_with(b"%PDF-"));
        let text = String::from_utf8_lossy(&pdf);
        assert_eq!(
            text.matches("/Type /Page\n").count()
                + text.matches("/Type /Page ").count()
                + text.matches("/Type /Page/").count(),
            pages.len(),
            "pages in the PDF"
        );
        let svg = to_svg(&pages[0], PageSize::A4);
        assert_eq!(svg.matches("<circle").count(), targets_on(&pages[0]));
        assert!(svg.contains(r#"width="210mm" height="297mm""#));
    }

    #[test]
    fn bezier_arcs_stay_on_their_circle() {
        // the 90° cubic's largest radial error is 2.7e-4 r
        let k = 4.0 / 3.0 * (PI / 8.0).tan();
        let (p0, c1, c2, p3) = ((1.0, 0.0), (1.0, k), (k, 1.0), (0.0, 1.0));
        let max = (0..=100)
            .map(|i| {
                let t = i as f64 / 100.0;
                let b = |a: f64, b: f64, c: f64, d: f64| {
                    (1.0 - t).powi(3) * a
                        + 3.0 * (1.0 - t).powi(2) * t * b
                        + 3.0 * (1.0 - t) * t * t * c
                        + t.powi(3) * d
                };
                let (x, y) = (b(p0.0, c1.0, c2.0, p3.0), b(p0.1, c1.1, c2.1, p3.1));
                ((x * x + y * y).sqrt() - 1.0).abs()
            })
            .fold(0.0, f64::max);
        assert!(max < 3e-4, "{max}");
    }
}
