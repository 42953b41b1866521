//! Image loading: any TIFF / PNG / JPEG (8 or 16 bit, grey or colour) to an `f32` grey image
//! with values in [0, 1]. Errors name the file and what is wrong; nothing here panics on
//! malformed input (decoding runs under size limits, and the decoder is guarded). Grey strip
//! TIFFs and grey PNGs go fast paths ([`tiff_strips`](crate::tiff_strips),
//! [`png_rows`](crate::png_rows)) with the same values.

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

    /// [`GrayImage::sample`] for points the caller knows to be inside the image (at least a
    /// pixel from the right and bottom edges): no border handling, no `floor` fix-up (the
    /// coordinates are non-negative). The same value as `sample` bit for bit; a point that is
    /// not inside after all goes the general way.
    #[inline(always)]
    pub fn sample_inside(&self, x: f64, y: f64) -> f32 {
        // `as usize` saturates (negative and NaN → 0), so the test below is exact.
        let xi = x as usize;
        let yi = y as usize;
        if x >= 0.0 && y >= 0.0 && xi + 1 < self.width && yi + 1 < self.height {
            let fx = (x - xi as f64) as f32;
            let fy = (y - yi as f64) as f32;
            let i = yi * self.width + xi;
            let r0 = &self.data[i..i + 2];
            let r1 = &self.data[i + self.width..i + self.width + 2];
            let top = r0[0] + (r0[1] - r0[0]) * fx;
            let bot = r1[0] + (r1[1] - r1[0]) * fx;
            top + (bot - top) * fy
        } else {
            self.sample(x, y)
        }
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
pub(crate) const MAX_SIDE: u32 = 40_000;
pub(crate) const MAX_ALLOC: u64 = 1 << 30;

/// Decodes an encoded image (format guessed from the bytes) to grey `f32`.
/// `name` is used in error messages.
pub fn decode_image(bytes: &[u8], name: &str) -> Result<GrayImage, TargetError> {
    // Grey strip TIFFs (the usual photogrammetric images) go the fast way; anything it does not
    // handle, or finds damaged, goes on to the general decoder, which has the last word.
    if let Ok(img) = crate::tiff_strips::decode_grey_strips(bytes) {
        return Ok(img);
    }
    decode_general(bytes, name, true)
}

/// [`decode_image`] past the TIFF fast path; `try_png`: whether to try the PNG one.
fn decode_general(bytes: &[u8], name: &str, try_png: bool) -> Result<GrayImage, TargetError> {
    let bad = |what: String| TargetError::Image {
        file: name.to_string(),
        what,
    };
    if bytes.is_empty() {
        return Err(bad("empty file".into()));
    }
    // Grey PNGs likewise.
    if try_png {
        if let Ok(img) = crate::png_rows::decode_grey_png(bytes) {
            return Ok(img);
        }
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
    let data = match &decoded {
        // Grey 8 and 16 bit (the usual photogrammetric TIFFs): one table look-up per pixel, in
        // parallel; the table is the `image` crate's own conversion, so the values are the
        // same as `to_luma32f`'s.
        image::DynamicImage::ImageLuma8(b) => convert_with(b.as_raw(), lut_u8()),
        image::DynamicImage::ImageLuma16(b) => convert_with(b.as_raw(), lut_u16()),
        _ => {
            let mut data = decoded.to_luma32f().into_raw();
            for v in &mut data {
                if !v.is_finite() {
                    *v = 0.0;
                }
            }
            data
        }
    };
    Ok(GrayImage {
        width: w,
        height: h,
        data,
    })
}

/// `src` mapped through `lut` (in parallel over blocks).
fn convert_with<T: Copy + Into<usize> + Sync>(src: &[T], lut: &[f32]) -> Vec<f32> {
    use rayon::prelude::*;
    let mut out = zeroed_f32(src.len());
    out.par_chunks_mut(1 << 16)
        .zip(src.par_chunks(1 << 16))
        .for_each(|(o, s)| {
            for (o, &v) in o.iter_mut().zip(s) {
                *o = lut[v.into()];
            }
        });
    out
}

/// `n` zeros, for an image to be written: a big buffer goes in memory the kernel is asked to
/// back with 2 MB pages. The pages of a fresh allocation are only mapped when first written,
/// one page fault each, and on 4 kB pages that was the most expensive part of decoding a big
/// image: writing a fresh 96 MB buffer (a 24-megapixel `f32` image) takes 33 ms of one thread
/// in page faults, 5 ms on 2 MB pages (Linux 6.18 in a VM, transparent huge pages on
/// `madvise`); written from two threads at once, the 4 kB faults take no less time.
pub(crate) fn zeroed_f32(n: usize) -> Vec<f32> {
    let mut v = vec![0.0f32; n];
    advise_huge_pages(&mut v);
    v
}

/// Asks the kernel to back `buf` with huge pages where it covers whole 2 MB pages (a hint,
/// which changes neither the contents nor their addresses; nothing elsewhere).
#[cfg(target_os = "linux")]
fn advise_huge_pages<T>(buf: &mut [T]) {
    const HUGE: usize = 2 << 20;
    let start = buf.as_mut_ptr() as usize;
    let end = start + std::mem::size_of_val(buf);
    let first = start.next_multiple_of(HUGE);
    let last = end - end % HUGE;
    if first < last {
        // SAFETY: the range lies inside `buf`, which we borrow mutably, and is page aligned;
        // MADV_HUGEPAGE only tells the kernel which page size to use for it and leaves the
        // memory as it is. A failure (no transparent huge pages) changes nothing.
        unsafe {
            libc::madvise(
                first as *mut libc::c_void,
                last - first,
                libc::MADV_HUGEPAGE,
            );
        }
    }
}

#[cfg(not(target_os = "linux"))]
fn advise_huge_pages<T>(_buf: &mut [T]) {}

/// Grey value of every 8-bit (16-bit) level as `to_luma32f` gives it, non-finite values as 0.
pub(crate) fn lut_u8() -> &'static [f32] {
    static LUT: std::sync::OnceLock<Vec<f32>> = std::sync::OnceLock::new();
    LUT.get_or_init(|| {
        let b = image::GrayImage::from_fn(256, 1, |x, _| image::Luma([x as u8]));
        finite(image::DynamicImage::ImageLuma8(b).to_luma32f().into_raw())
    })
}

pub(crate) fn lut_u16() -> &'static [f32] {
    static LUT: std::sync::OnceLock<Vec<f32>> = std::sync::OnceLock::new();
    LUT.get_or_init(|| {
        let b = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_fn(65536, 1, |x, _| {
            image::Luma([x as u16])
        });
        finite(image::DynamicImage::ImageLuma16(b).to_luma32f().into_raw())
    })
}

fn finite(mut v: Vec<f32>) -> Vec<f32> {
    for x in &mut v {
        if !x.is_finite() {
            *x = 0.0;
        }
    }
    v
}

/// Loads an image file to grey `f32`.
pub fn load_image(path: &Path) -> Result<GrayImage, TargetError> {
    let name = path.display().to_string();
    // A PNG is decoded as it is read (see `png_rows`); if that path does not take it, the file
    // is read again and goes the general way (which then skips the PNG fast path).
    let png_tried = match load_grey_png(path) {
        Some(Ok(img)) => return Ok(img),
        Some(Err(_)) => true,
        None => false,
    };
    let bytes = std::fs::read(path).map_err(|e| TargetError::Image {
        file: name.clone(),
        what: match e.kind() {
            std::io::ErrorKind::NotFound => "no such file".to_string(),
            _ => format!("cannot read: {e}"),
        },
    })?;
    if png_tried {
        decode_general(&bytes, &name, false)
    } else {
        decode_image(&bytes, &name)
    }
}

/// The PNG fast path on the file, streamed: `None` when it is not a PNG (or cannot be read).
fn load_grey_png(path: &Path) -> Option<Result<GrayImage, crate::tiff_strips::NotDecoded>> {
    use std::io::{Read, Seek};
    let mut file = std::fs::File::open(path).ok()?;
    let mut head = [0u8; 8];
    file.read_exact(&mut head).ok()?;
    if head != crate::png_rows::SIGNATURE {
        return None;
    }
    file.rewind().ok()?;
    Some(crate::png_rows::decode_grey_png_from(
        std::io::BufReader::with_capacity(1 << 16, file),
    ))
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Huge-page advice or not, the buffer is `n` zeros, writable everywhere.
    #[test]
    fn zeroed_buffers_are_zeros() {
        for n in [0, 1, 1000, (2 << 20) / 4 - 3, 5 << 20] {
            let mut v = zeroed_f32(n);
            assert_eq!(v.len(), n);
            assert!(v.iter().all(|&x| x.to_bits() == 0));
            for (i, x) in v.iter_mut().enumerate() {
                *x = i as f32;
            }
            assert!(v.iter().enumerate().all(|(i, &x)| x == i as f32));
        }
    }

    /// The table conversion of grey 8 and 16-bit images gives exactly `to_luma32f`'s values.
    #[test]
    fn grey_tables_match_the_image_crate() {
        let l8 = image::GrayImage::from_fn(256, 3, |x, y| image::Luma([(x as u8) ^ (y as u8)]));
        let l16 = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_fn(512, 128, |x, y| {
            image::Luma([(y * 512 + x) as u16])
        });
        for dynimg in [
            image::DynamicImage::ImageLuma8(l8),
            image::DynamicImage::ImageLuma16(l16),
        ] {
            let mut png = Vec::new();
            dynimg
                .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
                .unwrap();
            let got = decode_image(&png, "t.png").unwrap();
            let want = dynimg.to_luma32f().into_raw();
            assert_eq!(got.data.len(), want.len());
            assert!(got
                .data
                .iter()
                .zip(&want)
                .all(|(a, b)| a.to_bits() == b.to_bits()));
        }
    }
}
