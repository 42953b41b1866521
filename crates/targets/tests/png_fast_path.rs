//! The fast path for grey PNGs (`png_rows`) against the `image` crate's decoder: the same `f32`
//! values bit for bit on random images of every grey layout (1 to 16 bits, every filter, IDAT
//! cut anywhere, one or several threads); interlaced, palette, alpha and colour PNGs go the
//! general way with its values; damaged files never make it panic, and it never accepts a file
//! the `image` crate refuses. `load_image` (which streams PNG files) agrees with
//! `decode_image`, errors included.

use crate::decode_reference;

use decode_reference::{reference, same_bits};
use pingcal_targets::png_rows::{decode_grey_png, SIGNATURE};
use pingcal_targets::tiff_strips::NotDecoded;
use pingcal_targets::{decode_image, load_image};
use proptest::prelude::*;

/// Deterministic bytes: smooth runs (which the filters turn into small numbers) and noise.
fn pixels(seed: u64, len: usize) -> Vec<u8> {
    let mut x = seed ^ 0x9e37_79b9_7f4a_7c15;
    let mut rnd = move || {
        x = x
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (x >> 33) as u32
    };
    let mut v = Vec::with_capacity(len);
    let mut level = 0u8;
    while v.len() < len {
        if rnd() % 8 == 0 {
            level = rnd() as u8;
        }
        v.push(if rnd() % 4 == 0 {
            rnd() as u8
        } else {
            level.wrapping_add((rnd() % 3) as u8)
        });
    }
    v
}

const DEPTHS: [png::BitDepth; 5] = [
    png::BitDepth::One,
    png::BitDepth::Two,
    png::BitDepth::Four,
    png::BitDepth::Eight,
    png::BitDepth::Sixteen,
];

const FILTERS: [png::Filter; 6] = [
    png::Filter::NoFilter,
    png::Filter::Sub,
    png::Filter::Up,
    png::Filter::Avg,
    png::Filter::Paeth,
    png::Filter::Adaptive,
];

/// A PNG written by the `png` crate's encoder.
fn encode(
    w: u32,
    h: u32,
    color: png::ColorType,
    depth: png::BitDepth,
    filter: png::Filter,
    extra: impl FnOnce(&mut png::Encoder<'_, &mut Vec<u8>>),
    seed: u64,
) -> Vec<u8> {
    let samples = color.samples();
    let row = (w as usize * samples * depth as usize).div_ceil(8);
    let data = pixels(seed, row * h as usize);
    let mut out = Vec::new();
    let mut enc = png::Encoder::new(&mut out, w, h);
    enc.set_color(color);
    enc.set_depth(depth);
    enc.set_filter(filter);
    extra(&mut enc);
    let mut wr = enc.write_header().unwrap();
    wr.write_image_data(&data).unwrap();
    wr.finish().unwrap();
    out
}

fn grey(w: u32, h: u32, depth: png::BitDepth, filter: png::Filter, seed: u64) -> Vec<u8> {
    encode(w, h, png::ColorType::Grayscale, depth, filter, |_| {}, seed)
}

fn crc32(parts: &[&[u8]]) -> u32 {
    let mut c = !0u32;
    for p in parts {
        for &b in *p {
            c ^= u32::from(b);
            for _ in 0..8 {
                c = if c & 1 != 0 {
                    (c >> 1) ^ 0xedb8_8320
                } else {
                    c >> 1
                };
            }
        }
    }
    !c
}

/// The chunks of a PNG: (type, data), as far as they are whole.
fn chunks(png: &[u8]) -> Vec<([u8; 4], Vec<u8>)> {
    let mut out = Vec::new();
    let mut p = 8;
    while p + 12 <= png.len() {
        let n = u32::from_be_bytes(png[p..p + 4].try_into().unwrap()) as usize;
        if n > png.len() - p - 12 {
            break;
        }
        let t: [u8; 4] = png[p + 4..p + 8].try_into().unwrap();
        out.push((t, png[p + 8..p + 8 + n].to_vec()));
        p += 12 + n;
    }
    out
}

fn assemble(chunks: &[([u8; 4], Vec<u8>)]) -> Vec<u8> {
    let mut out = SIGNATURE.to_vec();
    for (t, d) in chunks {
        out.extend_from_slice(&(d.len() as u32).to_be_bytes());
        out.extend_from_slice(t);
        out.extend_from_slice(d);
        out.extend_from_slice(&crc32(&[t, d]).to_be_bytes());
    }
    out
}

/// The same PNG with its image data cut into IDAT chunks of the given sizes (cycled; 0 = an
/// empty chunk; all 0: one chunk).
fn resplit(png: &[u8], sizes: &[usize]) -> Vec<u8> {
    let sizes = if sizes.iter().all(|&n| n == 0) {
        &[usize::MAX][..]
    } else {
        sizes
    };
    let cs = chunks(png);
    let data: Vec<u8> = cs
        .iter()
        .filter(|(t, _)| t == b"IDAT")
        .flat_map(|(_, d)| d.clone())
        .collect();
    let mut out = Vec::new();
    let mut idat_done = false;
    for (t, d) in cs {
        if &t != b"IDAT" {
            out.push((t, d));
        } else if !idat_done {
            idat_done = true;
            let mut rest = &data[..];
            let mut i = 0;
            loop {
                let n = sizes[i % sizes.len()].min(rest.len());
                out.push((*b"IDAT", rest[..n].to_vec()));
                rest = &rest[n..];
                i += 1;
                if rest.is_empty() {
                    break;
                }
            }
        }
    }
    assemble(&out)
}

/// zlib stream of stored (uncompressed) blocks.
fn zlib_stored(data: &[u8]) -> Vec<u8> {
    let mut out = vec![0x78, 0x01];
    let mut blocks = data.chunks(65535).peekable();
    if blocks.peek().is_none() {
        out.extend_from_slice(&[1, 0, 0, 0xff, 0xff]);
    }
    while let Some(b) = blocks.next() {
        out.push(u8::from(blocks.peek().is_none()));
        out.extend_from_slice(&(b.len() as u16).to_le_bytes());
        out.extend_from_slice(&(!(b.len() as u16)).to_le_bytes());
        out.extend_from_slice(b);
    }
    let (mut a, mut b) = (1u32, 0u32);
    for &x in data {
        a = (a + u32::from(x)) % 65521;
        b = (b + a) % 65521;
    }
    out.extend_from_slice(&((b << 16) | a).to_be_bytes());
    out
}

/// An Adam7-interlaced grey PNG, made by hand (the encoder does not interlace): every pass row
/// unfiltered.
fn grey_interlaced(w: u32, h: u32, bits: u8, seed: u64) -> Vec<u8> {
    let passes = [
        (0, 0, 8, 8),
        (4, 0, 8, 8),
        (0, 4, 4, 8),
        (2, 0, 4, 4),
        (0, 2, 2, 4),
        (1, 0, 2, 2),
        (0, 1, 1, 2),
    ];
    let bytes_per_sample = usize::from(bits).div_ceil(8);
    let samples = pixels(seed, w as usize * h as usize * bytes_per_sample);
    let mut raw = Vec::new();
    for (x0, y0, dx, dy) in passes {
        let cols: Vec<u32> = (x0..w).step_by(dx).collect();
        if cols.is_empty() {
            continue;
        }
        for y in (y0..h).step_by(dy) {
            raw.push(0);
            let mut acc = (0u32, 0u32);
            for &x in &cols {
                let i = (y * w + x) as usize * bytes_per_sample;
                if bits >= 8 {
                    raw.extend_from_slice(&samples[i..i + bytes_per_sample]);
                } else {
                    acc.0 = (acc.0 << bits) | (u32::from(samples[i]) & ((1 << bits) - 1));
                    acc.1 += u32::from(bits);
                    if acc.1 == 8 {
                        raw.push(acc.0 as u8);
                        acc = (0, 0);
                    }
                }
            }
            if acc.1 > 0 {
                raw.push((acc.0 << (8 - acc.1)) as u8);
            }
        }
    }
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&w.to_be_bytes());
    ihdr.extend_from_slice(&h.to_be_bytes());
    ihdr.extend_from_slice(&[bits, 0, 0, 0, 1]);
    assemble(&[
        (*b"IHDR", ihdr),
        (*b"IDAT", zlib_stored(&raw)),
        (*b"IEND", Vec::new()),
    ])
}

/// `decode_image` gives the reference values; the fast path takes the file (with the same
/// values) exactly when `fast` says so.
fn check(bytes: &[u8], fast: bool, what: &str) {
    let (w, h, want) = reference(bytes).unwrap_or_else(|e| panic!("{what}: {e}"));
    match decode_grey_png(bytes) {
        Ok(img) => {
            assert!(fast, "{what}: taken by the fast path");
            assert_eq!((img.width, img.height), (w, h), "{what}");
            assert!(same_bits(&img.data, &want), "{what}");
        }
        Err(e) => assert!(!fast, "{what}: {e}"),
    }
    let img = decode_image(bytes, "t.png").unwrap();
    assert_eq!((img.width, img.height), (w, h), "{what}");
    assert!(same_bits(&img.data, &want), "{what}");
}

#[test]
fn every_grey_layout_is_decoded_the_fast_way_bit_identically() {
    let mut seed = 1u64;
    for depth in DEPTHS {
        for filter in FILTERS {
            for (w, h) in [(1, 1), (1, 7), (9, 1), (2, 3), (17, 5), (50, 50), (33, 41)] {
                seed += 1;
                let png = grey(w, h, depth, filter, seed);
                let what = format!("{depth:?} {filter:?} {w}×{h}");
                check(&png, true, &what);
                // The image data in IDAT chunks of odd sizes, some empty.
                check(&resplit(&png, &[1, 0, 7, 3]), true, &what);
                check(&resplit(&png, &[13]), true, &what);
            }
        }
    }
    // Random sizes 1..50.
    for i in 0..200u64 {
        let w = 1 + (i * 7919 % 50) as u32;
        let h = 1 + (i * 104_729 % 50) as u32;
        let depth = DEPTHS[i as usize % 5];
        let filter = FILTERS[(i / 5) as usize % 6];
        check(&grey(w, h, depth, filter, 1000 + i), true, &format!("{i}"));
    }
}

#[test]
fn interlaced_grey_pngs_go_the_general_way() {
    for bits in [1, 2, 4, 8, 16] {
        for (w, h) in [(1, 1), (3, 2), (8, 8), (9, 17), (50, 31)] {
            let png = grey_interlaced(w, h, bits, u64::from(w * h + u32::from(bits)));
            check(&png, false, &format!("interlaced {bits} bit {w}×{h}"));
        }
    }
}

#[test]
fn other_layouts_go_the_general_way() {
    use png::{BitDepth as B, ColorType as C, Filter as F};
    let none = |_: &mut png::Encoder<'_, &mut Vec<u8>>| {};
    for (w, h) in [(1, 1), (13, 9), (40, 33)] {
        for filter in [F::NoFilter, F::Paeth] {
            let s = u64::from(w * h);
            for (color, depth) in [
                (C::GrayscaleAlpha, B::Eight),
                (C::GrayscaleAlpha, B::Sixteen),
                (C::Rgb, B::Eight),
                (C::Rgb, B::Sixteen),
                (C::Rgba, B::Eight),
            ] {
                let png = encode(w, h, color, depth, filter, none, s);
                check(&png, false, &format!("{color:?} {depth:?}"));
            }
            // A grey image with a transparent level: grey + alpha for the `image` crate.
            for depth in [B::Eight, B::Sixteen, B::Four] {
                let png = encode(
                    w,
                    h,
                    C::Grayscale,
                    depth,
                    filter,
                    |e| e.set_trns(vec![0, 3]),
                    s,
                );
                check(&png, false, &format!("grey with tRNS {depth:?}"));
            }
            // Palette images: the `image` crate expands them to RGB.
            let palette: Vec<u8> = (0..=255u8).flat_map(|i| [i, 255 - i, i / 2]).collect();
            let png = encode(
                w,
                h,
                C::Indexed,
                B::Eight,
                filter,
                |e| e.set_palette(palette),
                s,
            );
            check(&png, false, "palette");
        }
    }
}

/// Big enough for several blocks of rows: the pipelined decoding in pools of 1 to 4 threads
/// (and with the other thread busy, so that the decoding thread converts blocks itself).
#[test]
fn several_blocks_in_any_pool_give_the_same_values() {
    let images = [
        grey(1500, 400, png::BitDepth::Eight, png::Filter::Sub, 1),
        grey(700, 333, png::BitDepth::Eight, png::Filter::Adaptive, 2),
        grey(301, 500, png::BitDepth::Sixteen, png::Filter::Paeth, 3),
        grey(30_000, 3, png::BitDepth::Sixteen, png::Filter::Up, 4),
        grey(999, 200, png::BitDepth::Four, png::Filter::Avg, 5),
    ];
    for png in &images {
        let (w, h, want) = reference(png).unwrap();
        for threads in 1..=4 {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let img = pool.install(|| decode_grey_png(png)).unwrap();
            assert_eq!((img.width, img.height), (w, h));
            assert!(same_bits(&img.data, &want), "{w}×{h}, {threads} threads");
            let busy = pool.scope(|s| {
                s.spawn(|_| std::thread::sleep(std::time::Duration::from_millis(100)));
                decode_grey_png(png)
            });
            assert!(same_bits(&busy.unwrap().data, &want), "{w}×{h} busy");
            // Cut short: refused, and `decode_image` gives the `image` crate's error.
            for cut in [png.len() / 2, png.len() - 30] {
                let cut = &png[..cut];
                assert!(pool.install(|| decode_grey_png(cut)).is_err());
                let e = reference(cut).unwrap_err();
                let got = pool.install(|| decode_image(cut, "t.png")).unwrap_err();
                assert!(got.to_string().contains(&e), "{got} vs {e}");
            }
        }
    }
}

/// The 24-megapixel benchmark image, if it is there.
#[test]
fn benchmark_image_is_decoded_the_fast_way_bit_identically() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../bench/targets/out/synthetic24mp.png");
    let Ok(bytes) = std::fs::read(&path) else {
        return;
    };
    let (w, h, want) = reference(&bytes).unwrap();
    let img = decode_grey_png(&bytes).unwrap();
    assert_eq!((img.width, img.height), (w, h));
    assert!(same_bits(&img.data, &want));
    assert!(same_bits(&load_image(&path).unwrap().data, &want));
}

fn temp_file(name: &str, bytes: &[u8]) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("pingcal-png-fast-path-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

/// `load_image` streams PNG files through the fast path: the same image as `decode_image`,
/// and the same error (naming the file) for damaged ones.
#[test]
fn load_image_agrees_with_decode_image() {
    let good = grey(640, 300, png::BitDepth::Eight, png::Filter::Paeth, 7);
    let rgb = encode(
        30,
        20,
        png::ColorType::Rgb,
        png::BitDepth::Eight,
        png::Filter::Sub,
        |_| {},
        8,
    );
    let mut flipped = good.clone();
    let n = flipped.len();
    flipped[n / 2] ^= 0x55;
    let cases = [
        ("good.png", good.clone()),
        ("rgb.png", rgb),
        ("interlaced.png", grey_interlaced(20, 20, 8, 9)),
        ("cut.png", good[..good.len() / 3].to_vec()),
        ("flipped.png", flipped),
        ("signature-only.png", SIGNATURE.to_vec()),
        ("short.png", SIGNATURE[..5].to_vec()),
    ];
    for (name, bytes) in cases {
        let path = temp_file(name, &bytes);
        let loaded = load_image(&path);
        let decoded = decode_image(&bytes, &path.display().to_string());
        match (loaded, decoded) {
            (Ok(a), Ok(b)) => {
                assert_eq!((a.width, a.height), (b.width, b.height), "{name}");
                assert!(same_bits(&a.data, &b.data), "{name}");
            }
            (Err(a), Err(b)) => {
                assert_eq!(a.to_string(), b.to_string(), "{name}");
                assert!(a.to_string().contains(name), "{a}");
            }
            (a, b) => panic!("{name}: load {:?} decode {:?}", a.err(), b.err()),
        }
        std::fs::remove_file(&path).unwrap();
    }
}

#[test]
fn what_the_fast_path_refuses_and_why() {
    assert!(matches!(
        decode_grey_png(b"GIF89a"),
        Err(NotDecoded::Unsupported(_))
    ));
    let rgb = encode(
        3,
        2,
        png::ColorType::Rgb,
        png::BitDepth::Eight,
        png::Filter::Sub,
        |_| {},
        1,
    );
    assert!(matches!(
        decode_grey_png(&rgb),
        Err(NotDecoded::Unsupported(_))
    ));
    let good = grey(30, 20, png::BitDepth::Eight, png::Filter::Sub, 1);
    assert!(matches!(
        decode_grey_png(&good[..good.len() - 40]),
        Err(NotDecoded::Corrupt(_))
    ));
}

/// Damage to a file: (what, where, value).
#[derive(Clone, Debug)]
enum Damage {
    Flip(proptest::sample::Index, u8),
    Truncate(proptest::sample::Index),
    Insert(proptest::sample::Index, u8),
    Delete(proptest::sample::Index),
    /// A byte of the data of one chunk changed, its CRC made right again (so that the damage
    /// reaches the zlib stream, the filters or the header's fields).
    ChunkByte(proptest::sample::Index, proptest::sample::Index, u8),
}

fn damage_strategy() -> impl Strategy<Value = Damage> {
    use proptest::sample::Index;
    prop_oneof![
        (any::<Index>(), 1u8..=255).prop_map(|(i, x)| Damage::Flip(i, x)),
        any::<Index>().prop_map(Damage::Truncate),
        (any::<Index>(), any::<u8>()).prop_map(|(i, x)| Damage::Insert(i, x)),
        any::<Index>().prop_map(Damage::Delete),
        (any::<Index>(), any::<Index>(), 1u8..=255)
            .prop_map(|(c, i, x)| Damage::ChunkByte(c, i, x)),
        (any::<Index>(), any::<Index>(), 1u8..=255)
            .prop_map(|(c, i, x)| Damage::ChunkByte(c, i, x)),
    ]
}

fn apply(png: &mut Vec<u8>, d: &Damage) {
    if png.is_empty() {
        return;
    }
    match d {
        Damage::Flip(i, x) => {
            let i = i.index(png.len());
            png[i] ^= x;
        }
        Damage::Truncate(i) => png.truncate(i.index(png.len())),
        Damage::Insert(i, x) => png.insert(i.index(png.len() + 1), *x),
        Damage::Delete(i) => {
            png.remove(i.index(png.len()));
        }
        Damage::ChunkByte(c, i, x) => {
            let mut cs = chunks(png);
            let with_data: Vec<usize> = (0..cs.len()).filter(|&k| !cs[k].1.is_empty()).collect();
            if with_data.is_empty() {
                return;
            }
            let k = with_data[c.index(with_data.len())];
            let j = i.index(cs[k].1.len());
            cs[k].1[j] ^= x;
            *png = assemble(&cs);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 1024, ..ProptestConfig::default() })]

    /// A damaged grey PNG: never a panic; the fast path accepts it only if the `image` crate
    /// does, with the same values; `decode_image` accepts it exactly when the `image` crate
    /// does and its header agrees with its data (`image_checks`), with its values.
    #[test]
    fn damaged_files_never_accepted_where_the_image_crate_refuses(
        seed in any::<u64>(),
        w in 1u32..40,
        h in 1u32..40,
        depth in 0usize..5,
        filter in 0usize..6,
        split in proptest::collection::vec(0usize..40, 1..4),
        damage in proptest::collection::vec(damage_strategy(), 1..4),
    ) {
        let mut png = resplit(&grey(w, h, DEPTHS[depth], FILTERS[filter], seed), &split);
        for d in &damage {
            apply(&mut png, d);
        }
        let want = reference(&png);
        let fast = decode_grey_png(&png);
        if let Ok(img) = &fast {
            let (ww, wh, wv) = want.as_ref().map_err(|e| TestCaseError::fail(format!("fast path accepts what the image crate refuses: {e}")))?;
            prop_assert_eq!((img.width, img.height), (*ww, *wh));
            prop_assert!(same_bits(&img.data, wv));
        }
        // decode_image also refuses what the image crate decodes from data that disagree
        // with the header (image_checks: more or less image data than the IHDR says)
        let got = decode_image(&png, "t.png");
        let checked = pingcal_targets::image_checks::check_bytes(&png).is_ok();
        prop_assert_eq!(got.is_ok(), want.is_ok() && checked, "decode_image {:?} image crate {:?}", got.as_ref().err(), want.as_ref().err());
        if let (Ok(img), Ok((_, _, wv))) = (&got, &want) {
            prop_assert!(same_bits(&img.data, wv));
        }
    }

    /// Arbitrary bytes after the signature: never a panic, never accepted where the `image`
    /// crate refuses.
    #[test]
    fn arbitrary_bytes_after_the_signature(tail in proptest::collection::vec(any::<u8>(), 0..600)) {
        let mut png = SIGNATURE.to_vec();
        png.extend_from_slice(&tail);
        let fast = decode_grey_png(&png);
        let want = reference(&png);
        prop_assert!(fast.is_err() || want.is_ok());
        let checked = pingcal_targets::image_checks::check_bytes(&png).is_ok();
        prop_assert_eq!(decode_image(&png, "t.png").is_ok(), want.is_ok() && checked);
    }
}
