//! Fast path of [`decode_image`](crate::decode_image) and [`load_image`](crate::load_image) for
//! grey PNGs (8 or 16 bits, or fewer bits, which the `png` crate expands to 8, as for the
//! `image` crate): the rows are inflated one block at a time into small byte buffers, and each
//! finished block is converted to `f32` through the grey tables of
//! [`image_io`](crate::image_io) by another thread while the next one is inflated, straight into
//! the final image. The whole 8-bit image and its copy that the `image` crate makes never exist.
//! Interlaced, animated, palette, grey + alpha (also a grey image with a transparent colour) and
//! colour PNGs go the general way, and so does any file this path finds damaged: the general
//! decoder then has the last word (and reports its own error).
//!
//! The decoder is the `png` crate, the version and the configuration the `image` crate uses
//! (limits, text chunks, the `EXPAND` transformation), read row by row with
//! [`png::Reader::read_row`], which is what its `next_frame` does for a non-interlaced image,
//! including the check of the rest of the image data at the end. So this path accepts exactly
//! the grey PNGs the `image` crate accepts, with the same bytes, and the tables make the values
//! `to_luma32f`'s bit for bit (tests/png_fast_path.rs).
//!
//! Measured on the 24-megapixel synthetic image of `bench/targets` (6000 × 4000, 8 bit, zlib
//! level 1, every row with the Sub filter), fresh process each time, best of 10 alternating
//! runs: the decode step of `bench_stages` (file read included) went from 85 to 43 ms on one
//! thread and from 67 to 35 ms on two, which is about the time of inflating and unfiltering
//! the rows alone (33 ms of one thread), the part that cannot be spread. Of the old 85 ms,
//! reading the file took 5 ms, the `image` crate's decode 40 ms (inflate and unfilter, then
//! the copy and the page faults on the fresh 24 MB image), and the conversion to `f32` 40 ms,
//! 35 ms of it page faults on the fresh 96 MB `f32` image (now on huge pages, see
//! `image_io::zeroed_f32`).

use crate::raster::{lut_u16, lut_u8, zeroed_f32, GrayImage, NotDecoded, MAX_ALLOC, MAX_SIDE};
use std::io::{BufRead, Seek};

/// The eight bytes every PNG file starts with (the `image` crate recognises PNG by them).
pub const SIGNATURE: [u8; 8] = [0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1a, b'\n'];

/// Inflated bytes per block of rows handed to the conversion (at least one row).
const BLOCK_BYTES: usize = 1 << 17;

/// Blocks of rows in flight at most; beyond that the decoding thread converts the block itself
/// (it never waits for another thread, so it cannot wait for itself).
const MAX_BLOCKS: usize = 8;

/// Decodes `bytes` if it is a grey PNG this path handles (see the module doc).
pub fn decode_grey_png(bytes: &[u8]) -> Result<GrayImage, NotDecoded> {
    if !bytes.starts_with(&SIGNATURE) {
        return Err(NotDecoded::Unsupported("not a PNG".into()));
    }
    decode_grey_png_from(std::io::Cursor::new(bytes))
}

/// [`decode_grey_png`] reading the file from `r` as it goes (for [`load_image`](crate::load_image):
/// the encoded file then never is in memory as a whole).
pub fn decode_grey_png_from<R: BufRead + Seek + Send>(r: R) -> Result<GrayImage, NotDecoded> {
    // The `png` crate is not ours to trust on hostile input: a panic in it means "not here".
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| decode(r)))
        .unwrap_or_else(|_| Err(corrupt("the png crate failed")))
}

fn unsupported(s: impl Into<String>) -> NotDecoded {
    NotDecoded::Unsupported(s.into())
}

fn corrupt(s: impl Into<String>) -> NotDecoded {
    NotDecoded::Corrupt(s.into())
}

fn png_err(e: png::DecodingError) -> NotDecoded {
    match e {
        png::DecodingError::LimitsExceeded => unsupported(format!("{e}")),
        _ => corrupt(format!("{e}")),
    }
}

/// The grey table of the output's sample size.
#[derive(Clone, Copy)]
enum Lut {
    U8(&'static [f32; 256]),
    /// Samples as the `png` crate gives them: big endian.
    U16(&'static [f32; 65536]),
}

fn decode<R: BufRead + Seek + Send>(r: R) -> Result<GrayImage, NotDecoded> {
    // The `image` crate's `PngDecoder::with_limits` under the limits of `decode_image`.
    let mut dec = png::Decoder::new_with_limits(
        r,
        png::Limits {
            bytes: MAX_ALLOC as usize,
        },
    );
    dec.set_ignore_text_chunk(false);
    let info = dec.read_header_info().map_err(png_err)?;
    let (w, h) = (info.width, info.height);
    if w == 0 || h == 0 || w > MAX_SIDE || h > MAX_SIDE {
        return Err(unsupported(format!("size {w} × {h}")));
    }
    if info.interlaced {
        return Err(unsupported("interlaced"));
    }
    dec.set_transformations(png::Transformations::EXPAND);
    let mut reader = dec.read_info().map_err(png_err)?;
    let info = reader.info();
    if info.animation_control.is_some() || info.frame_control.is_some() {
        return Err(unsupported("animated"));
    }
    let lut = match reader.output_color_type() {
        (png::ColorType::Grayscale, png::BitDepth::Eight) => {
            Lut::U8(lut_u8().try_into().expect("256 levels"))
        }
        (png::ColorType::Grayscale, png::BitDepth::Sixteen) => {
            Lut::U16(lut_u16().try_into().expect("65536 levels"))
        }
        (c, b) => return Err(unsupported(format!("{c:?} {b:?}"))),
    };
    let (width, height) = (w as usize, h as usize);
    let bytes_per_sample = if matches!(lut, Lut::U8(_)) { 1 } else { 2 };
    let line = width * bytes_per_sample;
    // The `image` crate reserves the decoded bytes against its allocation limit.
    if (line * height) as u64 > MAX_ALLOC {
        return Err(unsupported(format!(
            "size {w} × {h} beyond the allocation limit"
        )));
    }
    if reader.output_line_size(w) != Some(line) {
        return Err(unsupported("unexpected row size"));
    }
    let mut data = zeroed_f32(width * height);
    decode_rows(&mut reader, lut, width, line, &mut data)?;
    // The end of the image data (the rest of it, its checksum), as `next_frame` checks it.
    match reader.read_row(&mut vec![0u8; line]).map_err(png_err)? {
        None => Ok(GrayImage {
            width,
            height,
            data,
        }),
        Some(_) => Err(corrupt("more rows than the height")),
    }
}

/// Reads the next rows into `buf` (a whole number of rows of `line` bytes).
fn read_rows<R: BufRead + Seek>(
    reader: &mut png::Reader<R>,
    buf: &mut [u8],
    line: usize,
) -> Result<(), NotDecoded> {
    for row in buf.chunks_exact_mut(line) {
        if reader.read_row(row).map_err(png_err)?.is_none() {
            return Err(corrupt("fewer rows than the height"));
        }
    }
    Ok(())
}

/// Inflated rows (`src`) to `f32` (`out`, as many samples).
fn convert(lut: Lut, src: &[u8], out: &mut [f32]) {
    match lut {
        Lut::U8(lut) => {
            for (o, &v) in out.iter_mut().zip(src) {
                *o = lut[v as usize];
            }
        }
        Lut::U16(lut) => {
            for (o, v) in out.iter_mut().zip(src.chunks_exact(2)) {
                *o = lut[u16::from_be_bytes([v[0], v[1]]) as usize];
            }
        }
    }
}

/// All rows of the image into `data`: this thread inflates, rayon converts.
fn decode_rows<R: BufRead + Seek + Send>(
    reader: &mut png::Reader<R>,
    lut: Lut,
    width: usize,
    line: usize,
    data: &mut [f32],
) -> Result<(), NotDecoded> {
    let block_rows = (BLOCK_BYTES / line).max(1);
    if rayon::current_num_threads() == 1 || data.len() <= block_rows * width {
        let mut buf = vec![0u8; line];
        for out in data.chunks_exact_mut(width) {
            read_rows(reader, &mut buf, line)?;
            convert(lut, &buf, out);
        }
        return Ok(());
    }
    // Buffers come back from the conversion tasks through the channel.
    let (tx, rx) = std::sync::mpsc::channel::<Vec<u8>>();
    rayon::scope(move |s| {
        let mut own = vec![0u8; block_rows * line];
        let mut allocated = 0;
        for out in data.chunks_mut(block_rows * width) {
            let n = out.len() / width * line;
            let free = rx.try_recv().ok().or_else(|| {
                (allocated < MAX_BLOCKS).then(|| {
                    allocated += 1;
                    vec![0u8; block_rows * line]
                })
            });
            match free {
                Some(mut buf) => {
                    read_rows(reader, &mut buf[..n], line)?;
                    let tx = tx.clone();
                    s.spawn(move |_| {
                        convert(lut, &buf[..n], out);
                        // The receiver is gone once the decoding has stopped.
                        let _ = tx.send(buf);
                    });
                }
                None => {
                    read_rows(reader, &mut own[..n], line)?;
                    convert(lut, &own[..n], out);
                }
            }
        }
        Ok(())
    })
}
