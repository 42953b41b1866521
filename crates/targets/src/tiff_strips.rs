//! Fast path of [`decode_image`](crate::decode_image) for the usual photogrammetric TIFF: one
//! grey sample of 8 or 16 bits (MinIsBlack, or MinIsWhite), in strips, uncompressed or LZW,
//! with or without the horizontal predictor, little or big endian. The strips are decoded in
//! parallel, each straight into its rows of the `f32` image through the grey tables of
//! [`image_io`](crate::image_io), so the values are bit for bit those of the `image` crate's
//! `to_luma32f`. Anything else (tiles, colour, other compressions, PNG, JPEG) and any file this
//! path finds damaged goes the general way, whose decoder then has the last word (and reports
//! its own error): this path never accepts a file with other pixel values than the general one.
//!
//! The LZW decoder is our own (`Lzw` below, about 100 lines), not weezl's, because measurement
//! justified it. On the 20 real panel images (2000 × 1333, 8 bit, one LZW strip per row with
//! the predictor), one thread, this whole path takes 3.0 ms per image with it against 10.3 ms
//! with weezl 0.1.12 used directly (one decoder per task, `reset()` per strip, the tiff crate's
//! configuration): 3.4 times faster. Weezl was no faster here than the `image` crate's whole
//! decode (10 ms), on these short strips (2000 bytes each). The table of (offset, length) into
//! the output needs no setup per strip and decodes every code with one look-up and a 16-byte
//! copy. The decode step of `bench_stages` (file read included) went from 11.8 to 3.7 ms per
//! image. The decoder behaves as weezl does under the tiff crate: the tests below compare the
//! two on valid, random and damaged streams.
//!
//! The header and the tags are read by the `tiff` crate (the same code, with the same default
//! limits, that the `image` crate runs first), so a header it refuses is refused here too.

pub use crate::raster::NotDecoded;
use crate::raster::{lut_u16, lut_u8, zeroed_f32, GrayImage, MAX_ALLOC, MAX_SIDE};
use rayon::prelude::*;
use std::io::Cursor;
use tiff::decoder::{ChunkType, Decoder};
use tiff::tags::Tag;

fn unsupported(s: impl Into<String>) -> NotDecoded {
    NotDecoded::Unsupported(s.into())
}

fn corrupt(s: impl Into<String>) -> NotDecoded {
    NotDecoded::Corrupt(s.into())
}

/// Where and how the pixels are stored.
#[derive(Debug)]
struct Layout {
    width: usize,
    height: usize,
    /// 1 or 2.
    bytes_per_sample: usize,
    big_endian: bool,
    lzw: bool,
    /// Horizontal differencing (TIFF predictor 2).
    predictor: bool,
    /// MinIsWhite.
    invert: bool,
    rows_per_strip: usize,
    /// Byte range of each strip's data in the file: for LZW the stored data cut at the end of
    /// the file, for uncompressed strips exactly the bytes the strip's rows take.
    strips: Vec<std::ops::Range<usize>>,
}

/// Decodes `bytes` if it is a grey strip TIFF this path handles (see the module doc).
pub fn decode_grey_strips(bytes: &[u8]) -> Result<GrayImage, NotDecoded> {
    let l = layout(bytes)?;
    let mut data = zeroed_f32(l.width * l.height);
    let lut = Lut::new(&l);
    if l.lzw {
        let rows = l.rows_per_strip * l.width;
        data.par_chunks_mut(rows)
            .zip(l.strips.par_iter())
            .enumerate()
            .try_for_each_init(Scratch::default, |scratch, (i, (out, range))| {
                decode_lzw_strip(&l, &lut, &bytes[range.clone()], out, scratch)
                    .map_err(|e| corrupt(format!("strip {i}: {e}")))
            })?;
    } else {
        // Uncompressed rows are independent whatever the strips: parallel over blocks of rows.
        let row_bytes = l.width * l.bytes_per_sample;
        data.par_chunks_mut(l.width)
            .enumerate()
            .with_min_len(16)
            .for_each(|(y, out)| {
                let range = &l.strips[y / l.rows_per_strip];
                let start = range.start + (y % l.rows_per_strip) * row_bytes;
                row_to_f32(&l, &lut, &bytes[start..start + row_bytes], out);
            });
    }
    Ok(GrayImage {
        width: l.width,
        height: l.height,
        data,
    })
}

/// Reads the header and the tags and checks that everything this path relies on holds.
fn layout(bytes: &[u8]) -> Result<Layout, NotDecoded> {
    // Only what the `image` crate itself recognises as TIFF (no BigTIFF).
    if !(bytes.starts_with(b"II*\0") || bytes.starts_with(b"MM\0*")) {
        return Err(unsupported("not a TIFF"));
    }
    // The `tiff` crate is not ours to trust on hostile input: a panic in it means "not here".
    std::panic::catch_unwind(|| tags(bytes))
        .unwrap_or_else(|_| Err(unsupported("the tiff crate failed on the header")))
}

fn tags(bytes: &[u8]) -> Result<Layout, NotDecoded> {
    let tiff_err = |e: tiff::TiffError| match e {
        tiff::TiffError::UnsupportedError(_) => unsupported(format!("header: {e}")),
        _ => corrupt(format!("header: {e}")),
    };
    let mut dec = Decoder::new(Cursor::new(bytes)).map_err(tiff_err)?;
    let (w, h) = dec.dimensions().map_err(tiff_err)?;
    let bytes_per_sample = match dec.colortype().map_err(tiff_err)? {
        tiff::ColorType::Gray(8) => 1usize,
        tiff::ColorType::Gray(16) => 2,
        c => return Err(unsupported(format!("colour type {c:?}"))),
    };
    if dec.get_chunk_type() != ChunkType::Strip {
        return Err(unsupported("tiled"));
    }
    let mut tag_u16 = |tag: Tag, default: u16| -> Result<u16, NotDecoded> {
        Ok(dec
            .find_tag_unsigned::<u16>(tag)
            .map_err(tiff_err)?
            .unwrap_or(default))
    };
    let lzw = match tag_u16(Tag::Compression, 1)? {
        1 => false,
        5 => true,
        c => return Err(unsupported(format!("compression {c}"))),
    };
    let predictor = match tag_u16(Tag::Predictor, 1)? {
        1 => false,
        2 => true,
        p => return Err(unsupported(format!("predictor {p}"))),
    };
    let invert = match tag_u16(Tag::PhotometricInterpretation, u16::MAX)? {
        0 => true,
        1 => false,
        p => return Err(unsupported(format!("photometric interpretation {p}"))),
    };
    if tag_u16(Tag::SamplesPerPixel, 1)? != 1 {
        return Err(unsupported("more than one sample per pixel"));
    }
    let formats = dec
        .find_tag_unsigned_vec::<u16>(Tag::SampleFormat)
        .map_err(tiff_err)?;
    if formats.is_some_and(|f| f.iter().any(|&f| f != 1)) {
        return Err(unsupported("sample format other than unsigned integer"));
    }
    let rows_per_strip = dec
        .find_tag_unsigned::<u32>(Tag::RowsPerStrip)
        .map_err(tiff_err)?
        .unwrap_or(h);
    let offsets = dec
        .find_tag_unsigned_vec::<u64>(Tag::StripOffsets)
        .map_err(tiff_err)?
        .ok_or_else(|| unsupported("no strip offsets"))?;
    let counts = dec
        .find_tag_unsigned_vec::<u64>(Tag::StripByteCounts)
        .map_err(tiff_err)?
        .ok_or_else(|| unsupported("no strip byte counts"))?;

    // The `image` crate's limits (see `decode_image`): it reserves the decoded bytes twice
    // (once for its image, once for the tiff crate's buffer) and allows a strip's stored data
    // what is left.
    if w == 0 || h == 0 || w > MAX_SIDE || h > MAX_SIDE {
        return Err(unsupported(format!("size {w} × {h}")));
    }
    let total = u64::from(w) * u64::from(h) * bytes_per_sample as u64;
    let Some(strip_limit) = MAX_ALLOC.checked_sub(2 * total) else {
        return Err(unsupported(format!(
            "size {w} × {h} beyond the allocation limit"
        )));
    };
    let (width, height) = (w as usize, h as usize);
    if rows_per_strip == 0 {
        return Err(corrupt("0 rows per strip"));
    }
    let rows_per_strip = (rows_per_strip as usize).min(height);
    let n_strips = height.div_ceil(rows_per_strip);
    if offsets.len() != n_strips || counts.len() != n_strips {
        return Err(corrupt(format!(
            "{} strip offsets and {} byte counts for {n_strips} strips",
            offsets.len(),
            counts.len()
        )));
    }
    let row_bytes = width * bytes_per_sample;
    let file_len = bytes.len() as u64;
    let mut strips = Vec::with_capacity(n_strips);
    for (i, (&off, &count)) in offsets.iter().zip(&counts).enumerate() {
        if count > strip_limit {
            return Err(corrupt(format!("strip {i}: {count} bytes")));
        }
        let rows = rows_per_strip.min(height - i * rows_per_strip);
        let range = if lzw {
            // The tiff crate reads the stored bytes up to the end of the file.
            off.min(file_len)..off.saturating_add(count).min(file_len)
        } else {
            // The tiff crate reads the rows' bytes from the offset whatever the byte count.
            let end = off.saturating_add((rows * row_bytes) as u64);
            if end > file_len {
                return Err(corrupt(format!(
                    "strip {i}: data beyond the end of the file"
                )));
            }
            off..end
        };
        strips.push(range.start as usize..range.end as usize);
    }
    Ok(Layout {
        width,
        height,
        bytes_per_sample,
        big_endian: bytes.starts_with(b"MM"),
        lzw,
        predictor,
        invert,
        rows_per_strip,
        strips,
    })
}

/// The grey table of the image's sample size, inverted for MinIsWhite.
enum Lut {
    U8(Box<[f32; 256]>),
    U16(std::borrow::Cow<'static, [f32]>),
}

impl Lut {
    fn new(l: &Layout) -> Lut {
        if l.bytes_per_sample == 1 {
            let src = lut_u8();
            Lut::U8(Box::new(std::array::from_fn(|v| {
                src[if l.invert { 255 - v } else { v }]
            })))
        } else if l.invert {
            Lut::U16(lut_u16().iter().rev().copied().collect())
        } else {
            Lut::U16(lut_u16().into())
        }
    }
}

/// One row of stored samples (`src`, `out.len()` samples) to `f32`: byte order, predictor,
/// table.
#[inline]
fn row_to_f32(l: &Layout, lut: &Lut, src: &[u8], out: &mut [f32]) {
    match lut {
        Lut::U8(lut) => {
            if l.predictor {
                let mut acc = 0u8;
                for (o, &b) in out.iter_mut().zip(src) {
                    acc = acc.wrapping_add(b);
                    *o = lut[acc as usize];
                }
            } else {
                for (o, &b) in out.iter_mut().zip(src) {
                    *o = lut[b as usize];
                }
            }
        }
        Lut::U16(lut) => {
            let lut: &[f32; 65536] = lut.as_ref().try_into().expect("16-bit table");
            let get = |b: &[u8]| {
                let b = [b[0], b[1]];
                if l.big_endian {
                    u16::from_be_bytes(b)
                } else {
                    u16::from_le_bytes(b)
                }
            };
            let samples = src.chunks_exact(2).map(get);
            if l.predictor {
                let mut acc = 0u16;
                for (o, v) in out.iter_mut().zip(samples) {
                    acc = acc.wrapping_add(v);
                    *o = lut[acc as usize];
                }
            } else {
                for (o, v) in out.iter_mut().zip(samples) {
                    *o = lut[v as usize];
                }
            }
        }
    }
}

/// Per-task buffers, reused from strip to strip.
#[derive(Default)]
struct Scratch {
    bytes: Vec<u8>,
    lzw: Option<Box<Lzw>>,
}

fn decode_lzw_strip(
    l: &Layout,
    lut: &Lut,
    input: &[u8],
    out: &mut [f32],
    scratch: &mut Scratch,
) -> Result<(), String> {
    let rows = out.len() / l.width;
    let row_bytes = l.width * l.bytes_per_sample;
    let need = rows * row_bytes;
    scratch.bytes.resize(Lzw::BASE + need + Lzw::SLACK, 0);
    let lzw = scratch.lzw.get_or_insert_with(Default::default);
    lzw.decode(input, &mut scratch.bytes, need)?;
    for (src, o) in scratch.bytes[Lzw::BASE..Lzw::BASE + need]
        .chunks_exact(row_bytes)
        .zip(out.chunks_exact_mut(l.width))
    {
        row_to_f32(l, lut, src, o);
    }
    Ok(())
}

/// TIFF LZW decoding (MSB-first codes of 9 to 12 bits, Clear 256, EOI 257, the code size
/// growing one code early). Every table entry is a previous string followed by one byte, and
/// that byte is the first of the string decoded right after it, so each entry's string lies
/// contiguously in the output already decoded: the table holds (offset, length) into it. The
/// output buffer starts with the 256 one-byte strings, so that literals are entries like the
/// others.
struct Lzw {
    table: [(u32, u32); 4096],
}

impl Default for Lzw {
    fn default() -> Self {
        Lzw {
            table: std::array::from_fn(|i| if i < 256 { (i as u32, 1) } else { (0, 0) }),
        }
    }
}

impl Lzw {
    /// Where the strip's bytes start in the buffer (after the 256 one-byte strings).
    const BASE: usize = 256;
    /// Room the buffer needs beyond the bytes wanted: the last string may run past them (by
    /// less than 4096 bytes), and strings are copied in blocks of 16.
    const SLACK: usize = 4096 + 32;

    /// Decodes `input` until at least `need` bytes are in `buf[BASE..]` (`buf` must hold
    /// `BASE + need + SLACK` bytes), as the tiff crate does: what follows is not read; an end
    /// code or the end of the data before that is an error, and so is a code not in the table.
    fn decode(&mut self, input: &[u8], buf: &mut [u8], need: usize) -> Result<(), String> {
        debug_assert!(buf.len() >= Self::BASE + need + Self::SLACK);
        for (i, b) in buf[..256].iter_mut().enumerate() {
            *b = i as u8;
        }
        let short = |p: usize| format!("LZW data end after {} of {need} bytes", p - Self::BASE);
        let table = &mut self.table;
        let mut bits = BitReader::new(input);
        let mut p = Self::BASE;
        let end = Self::BASE + need;
        // At the start and after each Clear code: 9-bit codes, the first one a literal.
        'clear: loop {
            let first = loop {
                match bits.read(9) {
                    None => return Err(short(p)),
                    Some(256) => continue,
                    Some(257) => {
                        return Err(format!(
                            "LZW end code after {} of {need} bytes",
                            p - Self::BASE
                        ))
                    }
                    Some(c) if c < 256 => break c,
                    Some(c) => return Err(format!("LZW code {c} right after a clear code")),
                };
            };
            buf[p] = first as u8;
            let (mut prev_start, mut prev_len) = (p, 1usize);
            p += 1;
            let (mut width, mut next, mut bump_at) = (9u32, 258usize, 510usize);
            while p < end {
                let Some(code) = bits.read(width) else {
                    return Err(short(p));
                };
                let code = code as usize & 4095;
                let len;
                if code < next && code.wrapping_sub(256) >= 2 {
                    let (s, n) = table[code];
                    copy_string(buf, s as usize, n as usize, p);
                    len = n as usize;
                } else if code == next {
                    // The new entry is the previous string followed by its own first byte.
                    copy_string(buf, prev_start, prev_len, p);
                    buf[p + prev_len] = buf[prev_start];
                    len = prev_len + 1;
                } else if code == 256 {
                    continue 'clear;
                } else if code == 257 {
                    return Err(format!(
                        "LZW end code after {} of {need} bytes",
                        p - Self::BASE
                    ));
                } else {
                    return Err(format!("LZW code {code} not in the table ({next} entries)"));
                }
                if next < 4096 {
                    table[next] = (prev_start as u32, prev_len as u32 + 1);
                    if next == bump_at && width < 12 {
                        width += 1;
                        bump_at = (1 << width) - 2;
                    }
                    next += 1;
                }
                prev_start = p;
                prev_len = len;
                p += len;
            }
            return Ok(());
        }
    }
}

/// Copies `out[s..s + n]` to `out[p..p + n]` where `s + n <= p` (may write up to 16 bytes of
/// rubbish after `p + n`, inside the slack).
#[inline(always)]
fn copy_string(out: &mut [u8], s: usize, n: usize, p: usize) {
    let mut k = 0;
    loop {
        let block: [u8; 16] = out[s + k..s + k + 16].try_into().expect("16 bytes");
        out[p + k..p + k + 16].copy_from_slice(&block);
        k += 16;
        if k >= n {
            break;
        }
    }
}

/// MSB-first bit reader.
struct BitReader<'a> {
    input: &'a [u8],
    pos: usize,
    /// The next bits, from the top; bits below the first `n` are either zero or the right
    /// following bits.
    buf: u64,
    n: u32,
}

impl<'a> BitReader<'a> {
    fn new(input: &'a [u8]) -> Self {
        BitReader {
            input,
            pos: 0,
            buf: 0,
            n: 0,
        }
    }

    #[inline(always)]
    fn read(&mut self, width: u32) -> Option<u32> {
        if self.n < width {
            if let Some(b) = self.input.get(self.pos..self.pos + 8) {
                let v = u64::from_be_bytes(b.try_into().expect("8 bytes"));
                self.buf |= v >> self.n;
                let take = (63 - self.n) / 8;
                self.pos += take as usize;
                self.n += take * 8;
            } else {
                while self.n <= 56 && self.pos < self.input.len() {
                    self.buf |= u64::from(self.input[self.pos]) << (56 - self.n);
                    self.pos += 1;
                    self.n += 8;
                }
                if self.n < width {
                    return None;
                }
            }
        }
        let code = (self.buf >> (64 - width)) as u32;
        self.buf <<= width;
        self.n -= width;
        Some(code)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// `need` bytes from the LZW `input` with weezl, as the tiff crate's reader gets them (its
    /// configuration, stopping when the buffer is full).
    fn weezl_decode(input: &[u8], need: usize) -> Result<Vec<u8>, String> {
        let mut dec = weezl::decode::Configuration::with_tiff_size_switch(weezl::BitOrder::Msb, 8)
            .with_yield_on_full_buffer(true)
            .build();
        let mut out = vec![0u8; need];
        let (mut i, mut o) = (0, 0);
        // As the tiff crate's `LZWReader::read` under `read_exact` (bounded, lest weezl never
        // ended: it does).
        for _ in 0..10_000_000 {
            if o == need {
                break;
            }
            let r = dec.decode_bytes(&input[i..], &mut out[o..]);
            i += r.consumed_in;
            o += r.consumed_out;
            match r.status {
                Ok(weezl::LzwStatus::Ok) => {}
                Ok(_) => break,
                Err(e) => return Err(e.to_string()),
            }
        }
        if o < need {
            return Err(format!("short: {o} of {need}"));
        }
        Ok(out)
    }

    fn ours(input: &[u8], need: usize) -> Result<Vec<u8>, String> {
        let mut buf = vec![0u8; Lzw::BASE + need + Lzw::SLACK];
        Lzw::default().decode(input, &mut buf, need)?;
        Ok(buf[Lzw::BASE..Lzw::BASE + need].to_vec())
    }

    fn encode(data: &[u8]) -> Vec<u8> {
        weezl::encode::Encoder::with_tiff_size_switch(weezl::BitOrder::Msb, 8)
            .encode(data)
            .expect("weezl encodes")
    }

    /// Bytes with long repeats (long strings, the KwKwK case, full tables) and noise.
    fn text(seed: u64, len: usize, alphabet: u8) -> Vec<u8> {
        let mut x = seed;
        let mut rnd = move || {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (x >> 33) as u32
        };
        let mut v = Vec::with_capacity(len);
        while v.len() < len {
            match rnd() % 4 {
                0 if v.len() > 40 => {
                    let back = 1 + rnd() as usize % v.len().min(300);
                    for _ in 0..(1 + rnd() as usize % 60) {
                        v.push(v[v.len() - back]);
                    }
                }
                _ => v.push((rnd() % u32::from(alphabet.max(1))) as u8),
            }
        }
        v.truncate(len);
        v
    }

    /// Packs codes MSB first at the widths the decoder expects, keeping track of its table as
    /// weezl does: `picks` are turned into codes (mostly in the table, sometimes the next
    /// code, a Clear, an EOI or one beyond the table).
    /// Without `specials`, no Clear, EOI or codes beyond the table (so that the table fills up).
    fn code_stream(picks: &[(u8, u16)], specials: bool) -> Vec<u8> {
        let (mut acc, mut nacc, mut out) = (0u64, 0u32, Vec::new());
        let (mut width, mut next, mut fresh) = (9u32, 258u32, true);
        for &(kind, r) in picks {
            let r = u32::from(r);
            let kind = if specials { kind % 16 } else { 4 + kind % 12 };
            let code = match kind {
                0 => 256,
                1 => 257,
                2 => next,
                3 => next + 1 + r % 8,
                4..=8 => r % 256,
                _ => match r % next {
                    256 | 257 => r % 256,
                    c => c,
                },
            };
            let code = code.min((1 << width) - 1);
            acc = (acc << width) | u64::from(code);
            nacc += width;
            while nacc >= 8 {
                out.push((acc >> (nacc - 8)) as u8);
                nacc -= 8;
            }
            if code == 256 {
                (width, next, fresh) = (9, 258, true);
            } else if fresh {
                fresh = false;
            } else if next < 4096 {
                if next + 2 >= 1 << width && width < 12 {
                    width += 1;
                }
                next += 1;
            }
        }
        if nacc > 0 {
            out.push((acc << (8 - nacc)) as u8);
        }
        out
    }

    /// A table that fills up (4096 entries, no Clear code): codes stay 12 bits, no new entries.
    #[test]
    fn full_table_as_weezl() {
        let mut x = 7u32;
        let picks: Vec<(u8, u16)> = (0..9000)
            .map(|_| {
                x = x.wrapping_mul(1664525).wrapping_add(1013904223);
                ((x >> 24) as u8, (x >> 8) as u16 | 1)
            })
            .collect();
        let stream = code_stream(&picks, false);
        let mut buf = Vec::new();
        let mut dec =
            weezl::decode::Configuration::with_tiff_size_switch(weezl::BitOrder::Msb, 8).build();
        // The whole stream (weezl stops at its end without an EOI code).
        let _ = dec.into_vec(&mut buf).decode(&stream);
        assert!(buf.len() > 15_000, "{}", buf.len());
        assert_eq!(ours(&stream, buf.len()).unwrap(), buf);
        assert!(ours(&stream, buf.len() + 1).is_err());
    }

    #[test]
    fn decodes_what_weezl_encodes() {
        for (seed, len, alphabet) in [
            (1, 1, 255),
            (2, 3000, 4),
            (3, 200_000, 2),
            (4, 100_000, 255),
            (5, 50_000, 1),
            (6, 70_000, 16),
        ] {
            let data = text(seed, len, alphabet);
            let enc = encode(&data);
            for need in [1, len / 2 + 1, len] {
                assert_eq!(ours(&enc, need).unwrap(), data[..need], "{seed} {need}");
            }
            // Asking for more than there is: an error (the end code comes first).
            assert!(ours(&enc, len + 1).is_err());
            // Cut data: an error, or the bytes wanted if they are complete.
            for cut in [0, 1, enc.len() / 3, enc.len() - 1] {
                assert_eq!(
                    ours(&enc[..cut], len).is_ok(),
                    weezl_decode(&enc[..cut], len).is_ok()
                );
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

        /// Any code stream, valid or not: the same bytes as weezl, or an error where it errs.
        #[test]
        fn same_as_weezl_on_any_code_stream(
            picks in proptest::collection::vec((any::<u8>(), any::<u16>()), 0..6000),
            specials in any::<bool>(),
            need in any::<proptest::sample::Index>(),
        ) {
            let stream = code_stream(&picks, specials);
            // Up to a little more than all there is.
            let mut all = Vec::new();
            let _ = weezl::decode::Configuration::with_tiff_size_switch(weezl::BitOrder::Msb, 8)
                .build()
                .into_vec(&mut all)
                .decode(&stream);
            let need = 1 + need.index(all.len() + 3);
            let a = ours(&stream, need);
            let b = weezl_decode(&stream, need);
            prop_assert_eq!(a.is_ok(), b.is_ok(), "ours {:?} weezl {:?}", a.as_ref().err(), b.as_ref().err());
            if let (Ok(a), Ok(b)) = (a, b) {
                prop_assert!(a == b);
            }
        }

        #[test]
        fn same_as_weezl_on_any_bytes(
            input in proptest::collection::vec(any::<u8>(), 0..3000),
            need in 1usize..5000,
        ) {
            let a = ours(&input, need);
            let b = weezl_decode(&input, need);
            prop_assert_eq!(a.is_ok(), b.is_ok());
            if let (Ok(a), Ok(b)) = (a, b) {
                prop_assert!(a == b);
            }
        }

        #[test]
        fn same_as_weezl_on_damaged_streams(
            seed in any::<u64>(),
            len in 1usize..20_000,
            alphabet in 1u8..=255,
            flips in proptest::collection::vec((any::<proptest::sample::Index>(), 1u8..=255), 1..4),
        ) {
            let data = text(seed, len, alphabet);
            let mut enc = encode(&data);
            for (i, x) in flips {
                let i = i.index(enc.len());
                enc[i] ^= x;
            }
            let a = ours(&enc, len);
            let b = weezl_decode(&enc, len);
            prop_assert_eq!(a.is_ok(), b.is_ok());
            if let (Ok(a), Ok(b)) = (a, b) {
                prop_assert!(a == b);
            }
        }
    }
}
