//! The reference for the decoders' fast paths (`tiff_strips`, `png_rows`): what the general
//! path makes of a file.

use std::io::Cursor;

/// What the general path makes of `bytes`: the `image` crate's decode, under the limits of
/// `decode_image`, and `to_luma32f` (a panic inside it counts as an error).
pub fn reference(bytes: &[u8]) -> Result<(usize, usize, Vec<f32>), String> {
    std::panic::catch_unwind(|| {
        let mut reader = image::ImageReader::new(Cursor::new(bytes))
            .with_guessed_format()
            .map_err(|e| e.to_string())?;
        let mut limits = image::Limits::default();
        limits.max_image_width = Some(40_000);
        limits.max_image_height = Some(40_000);
        limits.max_alloc = Some(1 << 30);
        reader.limits(limits);
        let img = reader.decode().map_err(|e| e.to_string())?;
        Ok((
            img.width() as usize,
            img.height() as usize,
            img.to_luma32f().into_raw(),
        ))
    })
    .unwrap_or_else(|_| Err("panic".into()))
}

/// The same `f32` values bit for bit.
pub fn same_bits(a: &[f32], b: &[f32]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}
