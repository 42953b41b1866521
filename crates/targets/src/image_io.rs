//! Image loading: any TIFF / PNG / JPEG (8 or 16 bit, grey or colour) to an `f32` grey image
//! with values in [0, 1]. Errors name the file and what is wrong; nothing here panics on
//! malformed input (decoding runs under size limits, and the decoder is guarded). Grey strip
//! TIFFs and grey PNGs go fast paths ([`tiff_strips`](crate::tiff_strips),
//! [`png_rows`](crate::png_rows)) with the same values.
//!
//! A truncated file is an error. The PNG and TIFF decoders refuse one themselves; the JPEG
//! decoder under the `image` crate (zune-jpeg, run with `strict_mode(false)`) only logs
//! "Premature end of buffer" and fills the missing blocks with grey, so a JPEG is first
//! walked marker by marker ([`jpeg_truncation`]) and refused when it ends before its
//! end-of-image marker.
//!
//! Before any decoder runs, [`image_checks`](crate::image_checks) holds the header against
//! the data (a PNG's IHDR against its inflated IDAT, a JPEG's SOF against its coded data, a
//! TIFF's strip offsets against its header) and refuses an image too large to hold, naming
//! its size.

pub use crate::raster::GrayImage;
use crate::raster::{lut_u16, lut_u8, zeroed_f32, NotDecoded, MAX_ALLOC, MAX_SIDE};
use crate::TargetError;
use std::path::Path;

/// Decodes an encoded image (format guessed from the bytes) to grey `f32`.
/// `name` is used in error messages.
pub fn decode_image(bytes: &[u8], name: &str) -> Result<GrayImage, TargetError> {
    crate::image_checks::check_bytes(bytes).map_err(|what| TargetError::Image {
        file: name.to_string(),
        what,
    })?;
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
    if reader.format() == Some(image::ImageFormat::Jpeg) {
        if let Some(at) = jpeg_truncation(bytes) {
            return Err(bad(format!(
                "truncated JPEG: the data ends at byte {at} of {} before the end-of-image marker (an incomplete copy?)",
                bytes.len()
            )));
        }
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

/// Where a JPEG's data runs out before its end-of-image marker (EOI, `FF D9`), or `None`
/// when the marker is reached (or the bytes are not a JPEG). Segments are skipped by their
/// length (so an EXIF thumbnail's own EOI does not count) and entropy-coded data up to the
/// next marker that is neither a stuffed `FF 00` nor a restart marker.
pub fn jpeg_truncation(bytes: &[u8]) -> Option<usize> {
    if !bytes.starts_with(&[0xFF, 0xD8]) {
        return None;
    }
    let n = bytes.len();
    let mut i = 2;
    loop {
        // Skip anything up to the next marker, and fill bytes.
        while i < n && bytes[i] != 0xFF {
            i += 1;
        }
        while i + 1 < n && bytes[i + 1] == 0xFF {
            i += 1;
        }
        if i + 1 >= n {
            return Some(n);
        }
        let marker = bytes[i + 1];
        match marker {
            0xD9 => return None,
            0x01 | 0xD0..=0xD7 => {
                i += 2;
                continue;
            }
            _ => {}
        }
        if i + 4 > n {
            return Some(n);
        }
        let len = u16::from_be_bytes([bytes[i + 2], bytes[i + 3]]) as usize;
        i += 2 + len;
        if i > n {
            return Some(n);
        }
        if marker == 0xDA {
            // Entropy-coded data: up to a marker that is not FF 00 or a restart.
            loop {
                while i < n && bytes[i] != 0xFF {
                    i += 1;
                }
                if i + 1 >= n {
                    return Some(n);
                }
                match bytes[i + 1] {
                    0x00 | 0xD0..=0xD7 => i += 2,
                    0xFF => i += 1,
                    _ => break,
                }
            }
        }
    }
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

/// Loads an image file to grey `f32`.
pub fn load_image(path: &Path) -> Result<GrayImage, TargetError> {
    let name = path.display().to_string();
    let refused = |what: String| TargetError::Image {
        file: name.clone(),
        what,
    };
    if let Ok(f) = std::fs::File::open(path) {
        crate::image_checks::check_png(std::io::BufReader::with_capacity(1 << 16, f))
            .map_err(refused)?;
    }
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
        crate::image_checks::check_bytes(&bytes).map_err(refused)?;
        decode_image(&bytes, &name)
    }
}

/// The PNG fast path on the file, streamed: `None` when it is not a PNG (or cannot be read).
fn load_grey_png(path: &Path) -> Option<Result<GrayImage, NotDecoded>> {
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

/// Loads an image file as its channels: one for a grey image (as [`load_image`] gives it),
/// red, green and blue for a colour one (alpha dropped), each `f32` in [0, 1]. Errors as
/// [`load_image`]'s, naming the file.
pub fn load_colour(path: &Path) -> Result<crate::raster::ColourImage, TargetError> {
    use crate::raster::ColourImage;
    let name = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|e| TargetError::Image {
        file: name.clone(),
        what: match e.kind() {
            std::io::ErrorKind::NotFound => "no such file".to_string(),
            _ => format!("cannot read: {e}"),
        },
    })?;
    let bad = |what: String| TargetError::Image {
        file: name.clone(),
        what,
    };
    let colour = image::ImageReader::new(std::io::Cursor::new(&bytes))
        .with_guessed_format()
        .ok()
        .and_then(|r| r.into_decoder().ok())
        .map(|d| {
            use image::ImageDecoder;
            !matches!(
                d.color_type(),
                image::ColorType::L8
                    | image::ColorType::L16
                    | image::ColorType::La8
                    | image::ColorType::La16
            )
        })
        .unwrap_or(false);
    if !colour {
        return decode_image(&bytes, &name).map(ColourImage::grey);
    }
    // the general decoder's checks (truncation, limits, a guarded decoder) first
    let grey = decode_general(&bytes, &name, false)?;
    let mut reader = image::ImageReader::new(std::io::Cursor::new(&bytes))
        .with_guessed_format()
        .map_err(|e| bad(format!("cannot read: {e}")))?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_SIDE);
    limits.max_image_height = Some(MAX_SIDE);
    limits.max_alloc = Some(MAX_ALLOC);
    reader.limits(limits);
    let decoded = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| reader.decode()))
        .map_err(|_| bad("corrupt image (decoder failed)".into()))?
        .map_err(|e| bad(format!("corrupt or unsupported image: {e}")))?;
    let rgb = decoded.to_rgb32f();
    let (w, h) = (grey.width, grey.height);
    let mut planes = vec![GrayImage::new(w, h, 0.0); 3];
    for (i, px) in rgb.pixels().enumerate() {
        for (c, plane) in planes.iter_mut().enumerate() {
            let v = px.0[c];
            plane.data[i] = if v.is_finite() { v } else { 0.0 };
        }
    }
    Ok(ColourImage { planes })
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

    fn jpeg() -> Vec<u8> {
        let img = image::GrayImage::from_fn(64, 48, |x, y| image::Luma([(x * 3 + y) as u8]));
        let mut out = Vec::new();
        image::DynamicImage::ImageLuma8(img)
            .write_to(
                &mut std::io::Cursor::new(&mut out),
                image::ImageFormat::Jpeg,
            )
            .unwrap();
        out
    }

    #[test]
    fn a_truncated_jpeg_is_refused_naming_the_file() {
        let bytes = jpeg();
        assert_eq!(jpeg_truncation(&bytes), None);
        assert!(decode_image(&bytes, "ok.jpg").is_ok());
        let cut = &bytes[..bytes.len() - 40];
        let e = decode_image(cut, "cut.jpg").unwrap_err().to_string();
        assert!(
            e.starts_with("cut.jpg: truncated JPEG: the data ends at byte"),
            "{e}"
        );
        // Only the end-of-image marker missing: still truncated.
        assert!(jpeg_truncation(&bytes[..bytes.len() - 2]).is_some());
    }

    #[test]
    fn the_truncated_jpeg_of_the_bad_inputs_is_refused() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../../shared/data/bad-inputs/jpeg_truncated_accepted_0315baa11a.jpg");
        if !path.exists() {
            println!("skipped: {} is absent", path.display());
            return;
        }
        let e = load_image(&path).unwrap_err().to_string();
        assert!(
            e.contains("jpeg_truncated_accepted_0315baa11a.jpg: truncated JPEG"),
            "{e}"
        );
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
