//! Image loading: any TIFF / PNG / JPEG (8 or 16 bit, grey or colour) to an `f32` grey image
//! with values in [0, 1]. Errors name the file and what is wrong; nothing here panics on
//! malformed input (decoding runs under size limits, and the decoder is guarded).

use crate::TargetError;
use std::path::Path;

/// A grey image, row-major, values nominally in [0, 1] (1 = white).
#[derive(Clone, Debug)]
pub struct GrayImage {
    pub width: usize,
    pub height: usize,
    pub data: Vec<f32>,
}

impl GrayImage {
    /// An image filled with `value`.
    pub fn new(width: usize, height: usize, value: f32) -> Self {
        GrayImage {
            width,
            height,
            data: vec![value; width * height],
        }
    }

    /// Pixel value at integer coordinates (no bounds check beyond the slice's own).
    #[inline]
    pub fn get(&self, x: usize, y: usize) -> f32 {
        self.data[y * self.width + x]
    }

    /// Bilinear interpolation at (x, y), pixel centres at integer coordinates.
    /// Outside the image the nearest border value is used.
    #[inline(always)]
    pub fn sample(&self, x: f64, y: f64) -> f32 {
        let w = self.width as isize;
        let h = self.height as isize;
        if w == 0 || h == 0 || !x.is_finite() || !y.is_finite() {
            return 0.0;
        }
        // floor() without a libm call (the baseline x86-64 target has no SSE4.1 rounding).
        let xt = x as isize;
        let yt = y as isize;
        let xi = xt - ((xt as f64) > x) as isize;
        let yi = yt - ((yt as f64) > y) as isize;
        let fx = (x - xi as f64) as f32;
        let fy = (y - yi as f64) as f32;
        if xi >= 0 && yi >= 0 && xi + 1 < w && yi + 1 < h {
            let i = yi as usize * self.width + xi as usize;
            let a = self.data[i];
            let b = self.data[i + 1];
            let c = self.data[i + self.width];
            let d = self.data[i + self.width + 1];
            let top = a + (b - a) * fx;
            let bot = c + (d - c) * fx;
            return top + (bot - top) * fy;
        }
        let x0 = xi.clamp(0, w - 1) as usize;
        let y0 = yi.clamp(0, h - 1) as usize;
        let x1 = (xi + 1).clamp(0, w - 1) as usize;
        let y1 = (yi + 1).clamp(0, h - 1) as usize;
        let a = self.get(x0, y0);
        let b = self.get(x1, y0);
        let c = self.get(x0, y1);
        let d = self.get(x1, y1);
        let top = a + (b - a) * fx;
        let bot = c + (d - c) * fx;
        top + (bot - top) * fy
    }

    /// True when (x, y) is inside the image with `margin` pixels to spare.
    #[inline]
    pub fn inside(&self, x: f64, y: f64, margin: f64) -> bool {
        x >= margin
            && y >= margin
            && x <= self.width as f64 - 1.0 - margin
            && y <= self.height as f64 - 1.0 - margin
    }
}

/// Largest image side accepted (pixels) and largest decoder allocation (bytes).
const MAX_SIDE: u32 = 40_000;
const MAX_ALLOC: u64 = 1 << 30;

/// Decodes an encoded image (format guessed from the bytes) to grey `f32`.
/// `name` is used in error messages.
pub fn decode_image(bytes: &[u8], name: &str) -> Result<GrayImage, TargetError> {
    let bad = |what: String| TargetError::Image {
        file: name.to_string(),
        what,
    };
    if bytes.is_empty() {
        return Err(bad("empty file".into()));
    }
    let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| bad(format!("cannot read: {e}")))?;
    if reader.format().is_none() {
        return Err(bad("not a TIFF, PNG or JPEG image".into()));
    }
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_SIDE);
    limits.max_image_height = Some(MAX_SIDE);
    limits.max_alloc = Some(MAX_ALLOC);
    reader.limits(limits);
    // Decoders of third-party crates are not ours to trust on hostile input: a panic inside
    // one becomes an error here, never a crash of the caller.
    let decoded = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| reader.decode()))
        .map_err(|_| bad("corrupt image (decoder failed)".into()))?
        .map_err(|e| bad(format!("corrupt or unsupported image: {e}")))?;
    let (w, h) = (decoded.width() as usize, decoded.height() as usize);
    if w == 0 || h == 0 {
        return Err(bad("image has no pixels".into()));
    }
    let luma = decoded.to_luma32f();
    let mut data = luma.into_raw();
    for v in &mut data {
        if !v.is_finite() {
            *v = 0.0;
        }
    }
    Ok(GrayImage {
        width: w,
        height: h,
        data,
    })
}

/// Loads an image file to grey `f32`.
pub fn load_image(path: &Path) -> Result<GrayImage, TargetError> {
    let name = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|e| TargetError::Image {
        file: name.clone(),
        what: match e.kind() {
            std::io::ErrorKind::NotFound => "no such file".to_string(),
            _ => format!("cannot read: {e}"),
        },
    })?;
    decode_image(&bytes, &name)
}

/// Converts to an 8-bit `image` buffer (for overlays and debugging).
pub fn to_luma8(img: &GrayImage) -> image::GrayImage {
    let raw: Vec<u8> = img
        .data
        .iter()
        .map(|v| (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8)
        .collect();
    image::GrayImage::from_raw(img.width as u32, img.height as u32, raw)
        .expect("buffer length matches dimensions")
}
