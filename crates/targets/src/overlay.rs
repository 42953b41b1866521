//! Debug overlay: the image in grey with each target's ellipse, centre and ID drawn in colour,
//! written as PNG so a person can check the detection.

use crate::ellipse::Ellipse;
use crate::image_io::GrayImage;
use crate::TargetError;
use image::{Rgb, RgbImage};

/// Colour (RGB) of a coded target with its number.
pub const GREEN: [u8; 3] = [40, 255, 40];
/// Colour (RGB) of a plain target.
pub const CYAN: [u8; 3] = [0, 220, 255];
/// Colour (RGB) of a ball.
pub const MAGENTA: [u8; 3] = [255, 60, 255];
/// Colour (RGB) of the cross at each target's centre.
pub const RED: [u8; 3] = [255, 40, 40];
/// Colour (RGB) of a coded target without a number (drawn with '?').
pub const YELLOW: [u8; 3] = [255, 230, 0];
/// Colour (RGB) of a refused candidate and the letter of its reason.
pub const ORANGE: [u8; 3] = [255, 140, 0];

/// An RGB canvas over a grey image, with integer scale-up for legibility of small images.
pub struct Overlay {
    /// The picture so far: the grey image (levels stretched so that the 99.9th percentile is
    /// white, square-root tone) with what has been drawn on it, one pixel per image pixel.
    pub img: RgbImage,
    scale: f64,
}

// 3×5 bitmap digits (rows top to bottom, 3 bits each, MSB left); index 10 is '?'.
const DIGITS: [[u8; 5]; 11] = [
    [7, 5, 5, 5, 7],
    [2, 6, 2, 2, 7],
    [7, 1, 7, 4, 7],
    [7, 1, 7, 1, 7],
    [5, 5, 7, 1, 1],
    [7, 4, 7, 1, 7],
    [7, 4, 7, 5, 7],
    [7, 1, 1, 1, 1],
    [7, 5, 7, 5, 7],
    [7, 5, 7, 1, 7],
    [7, 1, 3, 0, 2],
];

/// 3×5 bitmap letters (as the digits): those that mark refusal reasons on the overlay.
pub const LETTERS: [(char, [u8; 5]); 8] = [
    ('B', [6, 5, 6, 5, 6]),
    ('C', [7, 4, 4, 4, 7]),
    ('D', [6, 5, 5, 5, 6]),
    ('E', [7, 4, 6, 4, 7]),
    ('M', [5, 7, 7, 5, 5]),
    ('R', [6, 5, 6, 5, 5]),
    ('S', [7, 4, 7, 1, 7]),
    ('T', [7, 2, 2, 2, 2]),
];

impl Overlay {
    /// A canvas showing `img` (grey, stretched to its own 99.9th percentile so dark photographs
    /// remain visible).
    pub fn new(img: &GrayImage) -> Self {
        let mut v: Vec<f32> = img
            .data
            .iter()
            .step_by((img.data.len() / 100_000).max(1))
            .copied()
            .collect();
        v.sort_by(|a, b| a.total_cmp(b));
        let hi = v
            .get(v.len().saturating_sub(1) * 999 / 1000)
            .copied()
            .unwrap_or(1.0)
            .max(1e-3);
        let out = RgbImage::from_fn(img.width as u32, img.height as u32, |x, y| {
            let g = (img.get(x as usize, y as usize) / hi).clamp(0.0, 1.0);
            let g = (g.sqrt() * 255.0) as u8;
            Rgb([g, g, g])
        });
        Overlay {
            img: out,
            scale: 1.0,
        }
    }

    fn put(&mut self, x: f64, y: f64, c: [u8; 3]) {
        let (x, y) = ((x * self.scale).round(), (y * self.scale).round());
        if x >= 0.0 && y >= 0.0 && (x as u32) < self.img.width() && (y as u32) < self.img.height() {
            self.img.put_pixel(x as u32, y as u32, Rgb(c));
        }
    }

    /// Draws an ellipse outline.
    pub fn ellipse(&mut self, e: &Ellipse, c: [u8; 3]) {
        let n = ((2.0 * std::f64::consts::PI * e.a * 1.5) as usize).clamp(16, 4000);
        for i in 0..n {
            let (x, y) = e.point(i as f64 * 2.0 * std::f64::consts::PI / n as f64);
            self.put(x, y, c);
        }
    }

    /// Draws a small cross at (x, y).
    pub fn cross(&mut self, x: f64, y: f64, half: i32, c: [u8; 3]) {
        for d in -half..=half {
            self.put(x + d as f64, y, c);
            self.put(x, y + d as f64, c);
        }
    }

    /// Writes a number (or '?' when `None`) with its top-left corner at (x, y), `size` pixels
    /// per font dot.
    pub fn number(&mut self, x: f64, y: f64, n: Option<u64>, size: u32, c: [u8; 3]) {
        let text = n.map_or("?".to_string(), |n| n.to_string());
        self.text(x, y, &text, size, c);
    }

    /// Writes `text` (digits, '?' and the letters of [`LETTERS`]; any other character is
    /// drawn as '?') with its top-left corner at (x, y), `size` pixels per font dot.
    pub fn text(&mut self, x: f64, y: f64, text: &str, size: u32, c: [u8; 3]) {
        let glyphs: Vec<[u8; 5]> = text
            .chars()
            .map(|ch| match ch {
                '0'..='9' => DIGITS[ch as usize - '0' as usize],
                _ => LETTERS
                    .iter()
                    .find(|(l, _)| *l == ch)
                    .map_or(DIGITS[10], |(_, g)| *g),
            })
            .collect();
        for (k, glyph) in glyphs.iter().enumerate() {
            for (row, bits) in glyph.iter().enumerate() {
                for col in 0..3 {
                    if bits & (4 >> col) != 0 {
                        for sy in 0..size {
                            for sx in 0..size {
                                let px = x + ((k as u32 * 4 + col) * size + sx) as f64;
                                let py = y + (row as u32 * size + sy) as f64;
                                self.put(px, py, c);
                            }
                        }
                    }
                }
            }
        }
    }

    /// Saves as PNG.
    pub fn save(&self, path: &std::path::Path) -> Result<(), TargetError> {
        self.img
            .save_with_format(path, image::ImageFormat::Png)
            .map_err(|e| TargetError::Image {
                file: path.display().to_string(),
                what: format!("cannot write: {e}"),
            })
    }
}

/// The overlay of one image's detections: coded targets with their number in green (yellow
/// '?' when not identified), plain targets in cyan, balls in magenta; a cross at each centre.
pub fn draw_detections(img: &GrayImage, det: &crate::detect::ImageDetections) -> Overlay {
    use crate::detect::TargetKind;
    let mut ov = Overlay::new(img);
    let size = ((img.width.max(img.height) as f64 / 1000.0).round() as u32).max(1) * 2;
    for t in &det.targets {
        let c = match (t.kind, t.id) {
            (TargetKind::Coded, Some(_)) => GREEN,
            (TargetKind::Coded, None) => YELLOW,
            (TargetKind::Plain, _) => CYAN,
            (TargetKind::Ball, _) => MAGENTA,
        };
        ov.ellipse(&t.ellipse, c);
        ov.cross(t.x, t.y, 2, RED);
        if t.kind == TargetKind::Coded {
            ov.ellipse(&t.ellipse.scaled(3.0), c);
            ov.number(
                t.x + t.ellipse.a * 2.2,
                t.y - t.ellipse.a * 2.2,
                t.id.map(u64::from),
                size,
                c,
            );
        }
    }
    ov
}

/// [`draw_detections`], and the refused candidates in orange: each one's outline and the
/// letter of its reason ([`crate::refusal::RefusalReason::letter`]: S saturated, E not
/// elliptic, M too small, B at the border, T text glyph, C low contrast, R ring unreadable, D
/// number read twice) beside it.
pub fn draw_detections_and_refusals(
    img: &GrayImage,
    det: &crate::detect::ImageDetections,
) -> Overlay {
    let mut ov = draw_detections(img, det);
    let size = ((img.width.max(img.height) as f64 / 1000.0).round() as u32).max(1) * 2;
    for r in &det.refused {
        let e = &r.ellipse;
        ov.ellipse(e, ORANGE);
        let mut s = [0u8; 4];
        ov.text(
            e.cx + e.a * 1.2,
            e.cy + e.a * 1.2,
            r.reason.letter().encode_utf8(&mut s),
            size,
            ORANGE,
        );
    }
    ov
}
