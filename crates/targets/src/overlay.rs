//! Debug overlay: the image in grey with each target's ellipse, centre and ID drawn in colour,
//! written as PNG so a person can check the detection.

use crate::ellipse::Ellipse;
use crate::image_io::GrayImage;
use crate::TargetError;
use image::{Rgb, RgbImage};

/// Colours used for the target kinds.
pub const GREEN: [u8; 3] = [40, 255, 40];
pub const CYAN: [u8; 3] = [0, 220, 255];
pub const MAGENTA: [u8; 3] = [255, 60, 255];
pub const RED: [u8; 3] = [255, 40, 40];
pub const YELLOW: [u8; 3] = [255, 230, 0];

/// An RGB canvas over a grey image, with integer scale-up for legibility of small images.
pub struct Overlay {
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
        let digits: Vec<usize> = match n {
            Some(n) => n.to_string().bytes().map(|b| (b - b'0') as usize).collect(),
            None => vec![10],
        };
        for (k, d) in digits.iter().enumerate() {
            for (row, bits) in DIGITS[*d].iter().enumerate() {
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
