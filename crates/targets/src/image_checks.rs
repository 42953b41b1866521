//! Checks of an image's header against its data, before it is decoded. The decoders under
//! [`decode_image`](crate::decode_image) believe the header and decode what it says from
//! whatever bytes are there, without a word when the two disagree: a PNG whose IHDR was made
//! smaller decodes the first rows of the larger image, a JPEG whose SOF says 1 × 720 decodes
//! one column of it, a TIFF whose StripOffsets point into its header decodes the header's
//! bytes as pixels. Each gives fewer targets and exit 0. These checks refuse such a file,
//! naming what disagrees, and refuse an image too large to hold before anything is
//! allocated, naming its size:
//!
//! - **size**: at most 40000 pixels a side and [`MAX_PIXELS`] pixels (the grey `f32`
//!   copy of [`GrayImage`](crate::GrayImage) within the decoders' 1 GiB);
//! - **PNG**: the IDAT chunks inflate to exactly the bytes the IHDR's size, depth, colour type
//!   and interlacing take (inflated as they stream by, 96 kB of memory, stopping as soon as
//!   they are longer);
//! - **JPEG**: the entropy-coded data (stuffed bytes and restart markers not counted) is no
//!   longer than the SOF's blocks can hold: 256 bytes per 8 × 8 block (64 coefficients of at
//!   most 16 code bits and 16 value bits each), twice that for a progressive JPEG;
//! - **TIFF**: no strip's or tile's data overlaps the 8-byte header or the first IFD.
//!
//! A check that cannot read its format (not a PNG, an inflate error, no SOF, a header the
//! `tiff` crate refuses) passes the file on: the decoder then reports its own error.

use crate::raster::{MAX_ALLOC, MAX_SIDE};
use std::io::Read;

/// The most pixels an image may have: its grey `f32` copy within the decoders' limit.
pub const MAX_PIXELS: u64 = MAX_ALLOC / 4;

/// Refuses a `width` × `height` image beyond 40000 pixels a side or [`MAX_PIXELS`], naming its size.
pub fn check_size(width: u64, height: u64) -> Result<(), String> {
    let pixels = width.saturating_mul(height);
    if width > u64::from(MAX_SIDE) || height > u64::from(MAX_SIDE) || pixels > MAX_PIXELS {
        return Err(format!(
            "{width} × {height} pixels ({:.0} megapixels): larger than an image may be ({MAX_SIDE} pixels a side, {} megapixels)",
            pixels as f64 / 1e6,
            MAX_PIXELS / 1_000_000
        ));
    }
    Ok(())
}

/// The checks of the module doc on an encoded image held in memory.
pub fn check_bytes(bytes: &[u8]) -> Result<(), String> {
    if bytes.starts_with(&crate::png_rows::SIGNATURE) {
        check_png(bytes)
    } else if bytes.starts_with(&[0xFF, 0xD8]) {
        check_jpeg(bytes)
    } else if bytes.starts_with(b"II*\0") || bytes.starts_with(b"MM\0*") {
        check_tiff(bytes)
    } else {
        Ok(())
    }
}

/// The PNG check, reading the file from `r` (its signature included).
pub fn check_png<R: Read>(mut r: R) -> Result<(), String> {
    let mut head = [0u8; 8];
    if r.read_exact(&mut head).is_err() || head != crate::png_rows::SIGNATURE {
        return Ok(());
    }
    let mut expected = None;
    let mut inflate = Counter::new();
    loop {
        let mut h = [0u8; 8];
        if r.read_exact(&mut h).is_err() {
            break; // the decoder reports a file cut short
        }
        let len = u32::from_be_bytes([h[0], h[1], h[2], h[3]]) as u64;
        let kind = [h[4], h[5], h[6], h[7]];
        match &kind {
            b"IHDR" => {
                let mut d = [0u8; 13];
                if len != 13 || r.read_exact(&mut d).is_err() {
                    return Ok(());
                }
                let w = u32::from_be_bytes([d[0], d[1], d[2], d[3]]);
                let ht = u32::from_be_bytes([d[4], d[5], d[6], d[7]]);
                check_size(w.into(), ht.into())?;
                expected = png_data_bytes(w, ht, d[8], d[9], d[12] == 1);
                skip(&mut r, 4)?;
            }
            b"IDAT" => {
                let Some(want) = expected else { return Ok(()) };
                let mut left = len;
                let mut buf = vec![0u8; 1 << 16];
                while left > 0 {
                    let n = left.min(buf.len() as u64) as usize;
                    if r.read_exact(&mut buf[..n]).is_err() {
                        return Ok(());
                    }
                    left -= n as u64;
                    if inflate.feed(&buf[..n]).is_err() {
                        return Ok(());
                    }
                    if inflate.total > want {
                        return Err(png_mismatch(want, "more"));
                    }
                }
                skip(&mut r, 4)?;
            }
            b"IEND" => break,
            _ => skip(&mut r, len + 4)?,
        }
    }
    match expected {
        Some(want) if inflate.done && inflate.total != want => {
            Err(png_mismatch(want, &format!("{} bytes", inflate.total)))
        }
        _ => Ok(()),
    }
}

fn png_mismatch(want: u64, found: &str) -> String {
    format!(
        "the IHDR's size and format take {want} bytes of image data, the IDAT chunks hold {found}: the header disagrees with the data"
    )
}

/// Skips `n` bytes of `r` (an error-free end of file is left to the decoder).
fn skip<R: Read>(r: &mut R, n: u64) -> Result<(), String> {
    let _ = std::io::copy(&mut r.take(n), &mut std::io::sink());
    Ok(())
}

/// The bytes of filtered image data a PNG of this size and format holds, or `None` for a
/// format the PNG standard does not have (the decoder refuses it).
fn png_data_bytes(w: u32, h: u32, depth: u8, colour: u8, interlaced: bool) -> Option<u64> {
    let channels: u64 = match colour {
        0 | 3 => 1,
        2 => 3,
        4 => 2,
        6 => 4,
        _ => return None,
    };
    if !matches!(depth, 1 | 2 | 4 | 8 | 16) {
        return None;
    }
    let bits = channels * u64::from(depth);
    let rows = |pw: u64, ph: u64| {
        if pw == 0 || ph == 0 {
            0
        } else {
            ph * (1 + (pw * bits).div_ceil(8))
        }
    };
    let (w, h) = (u64::from(w), u64::from(h));
    if !interlaced {
        return Some(rows(w, h));
    }
    // Adam7: (x start, y start, x step, y step) of the seven passes
    const PASSES: [(u64, u64, u64, u64); 7] = [
        (0, 0, 8, 8),
        (4, 0, 8, 8),
        (0, 4, 4, 8),
        (2, 0, 4, 4),
        (0, 2, 2, 4),
        (1, 0, 2, 2),
        (0, 1, 1, 2),
    ];
    Some(
        PASSES
            .iter()
            .map(|&(x0, y0, dx, dy)| {
                rows(
                    w.saturating_sub(x0).div_ceil(dx),
                    h.saturating_sub(y0).div_ceil(dy),
                )
            })
            .sum(),
    )
}

/// A zlib stream inflated only to count its bytes: a 32 kB window kept for back-references.
struct Counter {
    dec: fdeflate::Decompressor,
    out: Vec<u8>,
    pos: usize,
    total: u64,
    done: bool,
}

impl Counter {
    const WINDOW: usize = 32 << 10;

    fn new() -> Self {
        Counter {
            dec: fdeflate::Decompressor::new(),
            out: vec![0; 3 * Self::WINDOW],
            pos: 0,
            total: 0,
            done: false,
        }
    }

    fn feed(&mut self, mut input: &[u8]) -> Result<(), fdeflate::DecompressionError> {
        loop {
            if self.done {
                return Ok(());
            }
            if self.pos == self.out.len() {
                self.out.copy_within(self.pos - Self::WINDOW..self.pos, 0);
                self.pos = Self::WINDOW;
            }
            let (used, made) = self.dec.read(input, &mut self.out, self.pos, false)?;
            input = &input[used..];
            self.pos += made;
            self.total += made as u64;
            self.done = self.dec.is_done();
            if input.is_empty() && self.pos < self.out.len() {
                return Ok(());
            }
        }
    }
}

/// The JPEG check (see the module doc), and the SOF's size.
pub fn check_jpeg(bytes: &[u8]) -> Result<(), String> {
    let n = bytes.len();
    let mut i = 2;
    let mut sof: Option<(u64, u8)> = None; // (bound in bytes, marker)
    let mut coded: u64 = 0;
    while i + 4 <= n {
        if bytes[i] != 0xFF {
            return Ok(());
        }
        let marker = bytes[i + 1];
        if marker == 0xFF {
            i += 1;
            continue;
        }
        if marker == 0xD9 {
            break;
        }
        if marker == 0x01 || (0xD0..=0xD7).contains(&marker) {
            i += 2;
            continue;
        }
        let len = u16::from_be_bytes([bytes[i + 2], bytes[i + 3]]) as usize;
        let seg = &bytes[(i + 4).min(n)..(i + 2 + len).min(n)];
        if is_sof(marker) && sof.is_none() {
            match sof_bound(seg, marker)? {
                Some(b) => sof = Some((b, marker)),
                None => return Ok(()),
            }
        }
        i += 2 + len;
        if marker == 0xDA {
            // entropy-coded data up to the next marker that is not FF 00 or a restart
            while i < n {
                if bytes[i] != 0xFF {
                    coded += 1;
                    i += 1;
                    continue;
                }
                match bytes.get(i + 1) {
                    Some(0x00) => {
                        coded += 1;
                        i += 2;
                    }
                    Some(0xD0..=0xD7) | Some(0xFF) => i += if bytes[i + 1] == 0xFF { 1 } else { 2 },
                    _ => break,
                }
            }
        }
    }
    match sof {
        Some((bound, _)) if coded > bound => Err(format!(
            "the SOF's size holds at most {bound} bytes of coded data, the file has {coded}: the header disagrees with the data (a damaged SOF?)"
        )),
        _ => Ok(()),
    }
}

/// Start-of-frame markers (C0–CF but DHT C4, JPG C8 and DAC CC).
fn is_sof(m: u8) -> bool {
    (0xC0..=0xCF).contains(&m) && !matches!(m, 0xC4 | 0xC8 | 0xCC)
}

/// The size check of a SOF segment (precision, height, width, components and their
/// sampling), and the most coded bytes its blocks can hold; `None` when the height is left to
/// a DNL marker or the segment is short (the decoder decides).
fn sof_bound(seg: &[u8], marker: u8) -> Result<Option<u64>, String> {
    if seg.len() < 6 {
        return Ok(None);
    }
    let h = u64::from(u16::from_be_bytes([seg[1], seg[2]]));
    let w = u64::from(u16::from_be_bytes([seg[3], seg[4]]));
    check_size(w, h)?;
    let nc = seg[5] as usize;
    if h == 0 || w == 0 || seg.len() < 6 + 3 * nc || nc == 0 {
        return Ok(None);
    }
    let samp: Vec<(u64, u64)> = (0..nc)
        .map(|k| {
            let s = seg[6 + 3 * k + 1];
            (u64::from(s >> 4).max(1), u64::from(s & 15).max(1))
        })
        .collect();
    let lossless = matches!(marker, 0xC3 | 0xC7 | 0xCB | 0xCF);
    if lossless {
        // at most 16 code bits and 16 value bits per sample
        return Ok(Some(w * h * nc as u64 * 4 + 1024));
    }
    let hmax = samp.iter().map(|s| s.0).max().unwrap_or(1);
    let vmax = samp.iter().map(|s| s.1).max().unwrap_or(1);
    let (mx, my) = (w.div_ceil(8 * hmax), h.div_ceil(8 * vmax));
    let blocks: u64 = samp.iter().map(|(hs, vs)| mx * hs * my * vs).sum();
    let progressive = matches!(marker, 0xC2 | 0xC6 | 0xCA | 0xCE);
    Ok(Some(blocks * 256 * if progressive { 2 } else { 1 } + 1024))
}

/// The TIFF check (see the module doc), and the first image's size.
pub fn check_tiff(bytes: &[u8]) -> Result<(), String> {
    std::panic::catch_unwind(|| tiff_layout(bytes)).unwrap_or(Ok(()))
}

fn tiff_layout(bytes: &[u8]) -> Result<(), String> {
    use tiff::tags::Tag;
    let Ok(mut dec) = tiff::decoder::Decoder::new(std::io::Cursor::new(bytes)) else {
        return Ok(());
    };
    let Ok((w, h)) = dec.dimensions() else {
        return Ok(());
    };
    check_size(w.into(), h.into())?;
    let le = bytes.starts_with(b"II");
    let u16_at = |at: usize| {
        let b = [bytes[at], bytes[at + 1]];
        u64::from(if le {
            u16::from_le_bytes(b)
        } else {
            u16::from_be_bytes(b)
        })
    };
    let ifd = {
        let b = [bytes[4], bytes[5], bytes[6], bytes[7]];
        u64::from(if le {
            u32::from_le_bytes(b)
        } else {
            u32::from_be_bytes(b)
        })
    };
    if ifd + 2 > bytes.len() as u64 {
        return Ok(());
    }
    let ifd_end = ifd + 2 + 12 * u16_at(ifd as usize) + 4;
    let (offsets, counts, what) = match dec.get_chunk_type() {
        tiff::decoder::ChunkType::Strip => (Tag::StripOffsets, Tag::StripByteCounts, "strip"),
        tiff::decoder::ChunkType::Tile => (Tag::TileOffsets, Tag::TileByteCounts, "tile"),
    };
    let (Ok(Some(offsets)), Ok(Some(counts))) = (
        dec.find_tag_unsigned_vec::<u64>(offsets),
        dec.find_tag_unsigned_vec::<u64>(counts),
    ) else {
        return Ok(());
    };
    for (k, (&off, &count)) in offsets.iter().zip(&counts).enumerate() {
        let end = off.saturating_add(count.max(1));
        let overlaps = |a: u64, b: u64| off < b && a < end;
        let part = if overlaps(0, 8) {
            "the file's 8-byte header"
        } else if overlaps(ifd, ifd_end) {
            "the image file directory (its tags)"
        } else {
            continue;
        };
        return Err(format!(
            "{what} {k}'s data (bytes {off}–{end}) lies in {part}: the {what} offsets disagree with the data"
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A zlib stream of `data` in stored (uncompressed) blocks.
    fn zlib_stored(data: &[u8]) -> Vec<u8> {
        let mut z = vec![0x78, 0x01];
        let chunks: Vec<&[u8]> = data.chunks(65535).collect();
        for (k, c) in chunks.iter().enumerate() {
            z.push(u8::from(k + 1 == chunks.len()));
            let n = c.len() as u16;
            z.extend_from_slice(&n.to_le_bytes());
            z.extend_from_slice(&(!n).to_le_bytes());
            z.extend_from_slice(c);
        }
        let (mut a, mut b) = (1u32, 0u32);
        for &x in data {
            a = (a + u32::from(x)) % 65521;
            b = (b + a) % 65521;
        }
        z.extend_from_slice(&((b << 16) | a).to_be_bytes());
        z
    }

    fn chunk(kind: &[u8; 4], data: &[u8]) -> Vec<u8> {
        let mut c = (data.len() as u32).to_be_bytes().to_vec();
        c.extend_from_slice(kind);
        c.extend_from_slice(data);
        c.extend_from_slice(&[0; 4]); // the CRC is not this check's business
        c
    }

    /// A grey 8-bit PNG whose IHDR says `w` × `h` and whose data is that of `dw` × `dh`.
    fn png(w: u32, h: u32, dw: usize, dh: usize, interlaced: bool) -> Vec<u8> {
        let mut p = crate::png_rows::SIGNATURE.to_vec();
        let mut ihdr = w.to_be_bytes().to_vec();
        ihdr.extend_from_slice(&h.to_be_bytes());
        ihdr.extend_from_slice(&[8, 0, 0, 0, u8::from(interlaced)]);
        p.extend(chunk(b"IHDR", &ihdr));
        let raw = vec![0u8; dh * (1 + dw)];
        let z = zlib_stored(&raw);
        for part in z.chunks(1000) {
            p.extend(chunk(b"IDAT", part));
        }
        p.extend(chunk(b"IEND", &[]));
        p
    }

    #[test]
    fn a_png_whose_header_disagrees_with_its_data_is_refused() {
        assert_eq!(check_png(&png(300, 200, 300, 200, false)[..]), Ok(()));
        let e = check_png(&png(300, 100, 300, 200, false)[..]).unwrap_err();
        assert!(e.starts_with("the IHDR's size and format take 30100 bytes of image data, the IDAT chunks hold more"), "{e}");
        let e = check_png(&png(300, 200, 300, 100, false)[..]).unwrap_err();
        assert!(e.contains("the IDAT chunks hold 30100 bytes"), "{e}");
        // Adam7: 7 passes of a 16 × 16 grey image
        let want = png_data_bytes(16, 16, 8, 0, true).unwrap();
        assert_eq!(want, 2 * 3 + 2 * 3 + 2 * 5 + 4 * 5 + 4 * 9 + 8 * 9 + 8 * 17);
        assert_eq!(png_data_bytes(3, 1, 1, 0, false), Some(2));
        assert_eq!(png_data_bytes(3, 2, 16, 6, false), Some(2 * 25));
    }

    /// An uncompressed grey 64 × 50 TIFF, its one strip at `strip` (its own place: `None`).
    fn tiff(strip: Option<u32>) -> Vec<u8> {
        let (w, h) = (64u32, 50u32);
        let entries: [(u16, u16, u32); 9] = [
            (256, 3, w),
            (257, 3, h),
            (258, 3, 8),
            (259, 3, 1),
            (262, 3, 1),
            (273, 4, 0),
            (277, 3, 1),
            (278, 3, h),
            (279, 4, w * h),
        ];
        let data_at = 8 + 2 + 12 * entries.len() as u32 + 4;
        let mut t = b"II*\0".to_vec();
        t.extend_from_slice(&8u32.to_le_bytes());
        t.extend_from_slice(&(entries.len() as u16).to_le_bytes());
        for (tag, ty, v) in entries {
            let v = if tag == 273 {
                strip.unwrap_or(data_at)
            } else {
                v
            };
            t.extend_from_slice(&tag.to_le_bytes());
            t.extend_from_slice(&ty.to_le_bytes());
            t.extend_from_slice(&1u32.to_le_bytes());
            t.extend_from_slice(&v.to_le_bytes());
        }
        t.extend_from_slice(&0u32.to_le_bytes());
        t.extend((0..w * h).map(|k| (k % 251) as u8));
        t
    }

    #[test]
    fn a_tiff_whose_strips_lie_in_its_header_is_refused() {
        assert_eq!(check_tiff(&tiff(None)), Ok(()));
        assert!(crate::decode_image(&tiff(None), "ok.tif").is_ok());
        let e = check_tiff(&tiff(Some(8))).unwrap_err();
        assert_eq!(
            e,
            "strip 0's data (bytes 8–3208) lies in the image file directory (its tags): the strip offsets disagree with the data"
        );
        let e = crate::decode_image(&tiff(Some(0)), "h.tif")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("h.tif: strip 0's data (bytes 0–3200) lies in the file's 8-byte header"),
            "{e}"
        );
    }

    #[test]
    fn a_huge_image_is_refused_with_its_size_before_decoding() {
        let e = check_png(&png(30_000, 30_000, 1, 1, false)[..]).unwrap_err();
        assert_eq!(
            e,
            "30000 × 30000 pixels (900 megapixels): larger than an image may be (40000 pixels a side, 268 megapixels)"
        );
        assert!(check_size(6000, 4000).is_ok());
    }

    /// A baseline grey JPEG's frame: SOI, SOF0 of `w` × `h`, SOS, `coded` bytes, EOI.
    fn jpeg(w: u16, h: u16, coded: usize) -> Vec<u8> {
        let mut j = vec![0xFF, 0xD8, 0xFF, 0xC0, 0, 11, 8];
        j.extend_from_slice(&h.to_be_bytes());
        j.extend_from_slice(&w.to_be_bytes());
        j.extend_from_slice(&[1, 1, 0x11, 0]);
        j.extend_from_slice(&[0xFF, 0xDA, 0, 8, 1, 1, 0, 0, 63, 0]);
        j.extend((0..coded).map(|k| if k % 100 == 99 { 0xFF } else { 0x55 }));
        // every 0xFF of the data stuffed
        let mut out = Vec::new();
        for (k, &b) in j.iter().enumerate() {
            out.push(b);
            if b == 0xFF && k > 20 {
                out.push(0);
            }
        }
        out.extend_from_slice(&[0xFF, 0xD9]);
        out
    }

    #[test]
    fn a_jpeg_whose_sof_cannot_hold_its_data_is_refused() {
        assert_eq!(check_jpeg(&jpeg(1280, 720, 49_000)), Ok(()));
        // 1 × 720: 90 blocks of at most 256 bytes
        let e = check_jpeg(&jpeg(1, 720, 49_000)).unwrap_err();
        assert_eq!(
            e,
            "the SOF's size holds at most 24064 bytes of coded data, the file has 49000: the header disagrees with the data (a damaged SOF?)"
        );
        let e = check_jpeg(&jpeg(30_000, 30_000, 10)).unwrap_err();
        assert!(e.starts_with("30000 × 30000 pixels"), "{e}");
    }
}
