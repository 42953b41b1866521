//! The fast path for grey strip TIFFs (`tiff_strips`) against the `image` crate's decoder: the
//! same `f32` values bit for bit, on the real panel photographs and on random small images of
//! every layout it handles; damaged files never make it panic, and it never accepts a file the
//! `image` crate refuses.

use crate::decode_reference;
use crate::panel;

use decode_reference::{reference, same_bits};
use pingcal_targets::tiff_strips::{decode_grey_strips, NotDecoded};
use pingcal_targets::{decode_image, load_image};
use proptest::prelude::*;
use std::io::Cursor;

#[test]
fn real_panel_images_are_decoded_the_fast_way_bit_identically() {
    let Some((_, files)) = panel::panel() else {
        return;
    };
    assert!(!files.is_empty());
    for f in &files {
        let bytes = std::fs::read(f).unwrap();
        let fast = decode_grey_strips(&bytes).unwrap_or_else(|e| panic!("{}: {e}", f.display()));
        let (w, h, want) = reference(&bytes).unwrap();
        assert_eq!((fast.width, fast.height), (w, h));
        assert!(same_bits(&fast.data, &want), "{}", f.display());
        let img = load_image(f).unwrap();
        assert!(same_bits(&img.data, &want), "{}", f.display());
    }
}

/// A panel image cut short: an error naming the file, as from the `image` crate, unless only
/// the end code is lost (then both decode it whole).
#[test]
fn truncated_real_panel_image_is_an_error_naming_the_file() {
    let Some((_, files)) = panel::panel() else {
        return;
    };
    let bytes = std::fs::read(&files[0]).unwrap();
    for cut in [1000, bytes.len() / 2, bytes.len() - 3, bytes.len() - 1] {
        let cut_bytes = &bytes[..cut];
        let theirs = reference(cut_bytes);
        match decode_grey_strips(cut_bytes) {
            Ok(img) => {
                let (_, _, want) = theirs.unwrap();
                assert!(same_bits(&img.data, &want));
                eprintln!("cut at {cut} of {}: decoded whole", bytes.len());
            }
            Err(e) => {
                eprintln!(
                    "cut at {cut} of {}: {e}; image crate: {:?}",
                    bytes.len(),
                    theirs.as_ref().err()
                );
                assert!(matches!(e, NotDecoded::Corrupt(_)));
                assert!(theirs.is_err());
                let e = decode_image(cut_bytes, "panel.tif")
                    .unwrap_err()
                    .to_string();
                assert!(e.starts_with("panel.tif: "), "{e}");
            }
        }
    }
}

/// A grey image and how to store it.
#[derive(Clone, Debug)]
struct Spec {
    width: u32,
    height: u32,
    sixteen: bool,
    rows_per_strip: u32,
    predictor: bool,
    lzw: bool,
    big_endian: bool,
    min_is_white: bool,
    /// Written with the tiff crate's encoder (little endian, MinIsBlack only), else by hand.
    tiff_encoder: bool,
    samples: Vec<u16>,
}

fn spec() -> impl Strategy<Value = Spec> {
    (
        1u32..48,
        1u32..48,
        any::<bool>(),
        any::<bool>(),
        any::<bool>(),
        any::<bool>(),
        any::<bool>(),
        any::<bool>(),
        any::<u64>(),
        1u32..5,
    )
        .prop_flat_map(
            |(width, height, sixteen, predictor, lzw, big_endian, min_is_white, enc, seed, k)| {
                (1..=height + 2).prop_map(move |rows_per_strip| {
                    // Smooth ramps plus noise of a few levels: LZW finds repeats, the predictor
                    // has work to do, and the full range of values shows up.
                    let mut x = seed;
                    let max = if sixteen { 65535u32 } else { 255 };
                    let samples = (0..width * height)
                        .map(|i| {
                            x = x
                                .wrapping_mul(6364136223846793005)
                                .wrapping_add(1442695040888963407);
                            let ramp = (i % width) * max / width.max(2) + (i / width) * 7;
                            let noise = (x >> 40) as u32 % (1 << (2 * k));
                            ((ramp + noise) % (max + 1)) as u16
                        })
                        .collect();
                    let tiff_encoder = enc && !big_endian && !min_is_white;
                    Spec {
                        width,
                        height,
                        sixteen,
                        rows_per_strip,
                        predictor,
                        lzw,
                        big_endian: big_endian && !tiff_encoder,
                        min_is_white: min_is_white && !tiff_encoder,
                        tiff_encoder,
                        samples,
                    }
                })
            },
        )
}

fn encode(s: &Spec) -> Vec<u8> {
    if s.tiff_encoder {
        with_tiff_encoder(s)
    } else {
        by_hand(s)
    }
}

fn with_tiff_encoder(s: &Spec) -> Vec<u8> {
    use tiff::encoder::{colortype, Compression, Predictor, TiffEncoder};
    let mut out = Cursor::new(Vec::new());
    let mut enc = TiffEncoder::new(&mut out)
        .unwrap()
        .with_predictor(if s.predictor {
            Predictor::Horizontal
        } else {
            Predictor::None
        })
        .with_compression(if s.lzw {
            Compression::Lzw
        } else {
            Compression::Uncompressed
        });
    if s.sixteen {
        let mut img = enc
            .new_image::<colortype::Gray16>(s.width, s.height)
            .unwrap();
        img.rows_per_strip(s.rows_per_strip).unwrap();
        img.write_data(&s.samples).unwrap();
    } else {
        let data: Vec<u8> = s.samples.iter().map(|&v| v as u8).collect();
        let mut img = enc
            .new_image::<colortype::Gray8>(s.width, s.height)
            .unwrap();
        img.rows_per_strip(s.rows_per_strip).unwrap();
        img.write_data(&data).unwrap();
    }
    out.into_inner()
}

/// A baseline TIFF written by hand: either byte order, MinIsWhite, LZW by weezl.
fn by_hand(s: &Spec) -> Vec<u8> {
    let be = s.big_endian;
    let u16b = |v: u16| if be { v.to_be_bytes() } else { v.to_le_bytes() };
    let u32b = |v: u32| if be { v.to_be_bytes() } else { v.to_le_bytes() };
    let (w, h, rps) = (
        s.width as usize,
        s.height as usize,
        s.rows_per_strip as usize,
    );
    // Strips.
    let mut strips: Vec<Vec<u8>> = Vec::new();
    for rows in s.samples.chunks(w * rps) {
        let mut raw = Vec::new();
        for row in rows.chunks(w) {
            let mut prev = 0u16;
            for &v in row {
                let d = if s.predictor {
                    let d = if s.sixteen {
                        v.wrapping_sub(prev)
                    } else {
                        (v as u8).wrapping_sub(prev as u8) as u16
                    };
                    prev = v;
                    d
                } else {
                    v
                };
                if s.sixteen {
                    raw.extend_from_slice(&u16b(d));
                } else {
                    raw.push(d as u8);
                }
            }
        }
        strips.push(if s.lzw {
            weezl::encode::Encoder::with_tiff_size_switch(weezl::BitOrder::Msb, 8)
                .encode(&raw)
                .unwrap()
        } else {
            raw
        });
    }
    let n = strips.len();
    let mut file = Vec::new();
    file.extend_from_slice(if be { b"MM\0*" } else { b"II*\0" });
    file.extend_from_slice(&u32b(8));
    // IFD: 10 entries, then the arrays, then the strips.
    let entries = 10usize;
    let ifd_end = 8 + 2 + entries * 12 + 4;
    let offsets_at = ifd_end;
    let counts_at = offsets_at + 4 * n;
    let mut data_at = counts_at + 4 * n;
    let mut offsets = Vec::new();
    for st in &strips {
        offsets.push(data_at as u32);
        data_at += st.len();
    }
    let counts: Vec<u32> = strips.iter().map(|st| st.len() as u32).collect();
    file.extend_from_slice(&u16b(entries as u16));
    let entry = |file: &mut Vec<u8>, tag: u16, ty: u16, count: u32, value: [u8; 4]| {
        file.extend_from_slice(&u16b(tag));
        file.extend_from_slice(&u16b(ty));
        file.extend_from_slice(&u32b(count));
        file.extend_from_slice(&value);
    };
    let short = |v: u16| {
        let b = u16b(v);
        [b[0], b[1], 0, 0]
    };
    let array = |values: &[u32], at: usize| {
        if values.len() == 1 {
            u32b(values[0])
        } else {
            u32b(at as u32)
        }
    };
    entry(&mut file, 256, 4, 1, u32b(w as u32));
    entry(&mut file, 257, 4, 1, u32b(h as u32));
    entry(&mut file, 258, 3, 1, short(if s.sixteen { 16 } else { 8 }));
    entry(&mut file, 259, 3, 1, short(if s.lzw { 5 } else { 1 }));
    entry(
        &mut file,
        262,
        3,
        1,
        short(if s.min_is_white { 0 } else { 1 }),
    );
    entry(&mut file, 273, 4, n as u32, array(&offsets, offsets_at));
    entry(&mut file, 277, 3, 1, short(1));
    entry(&mut file, 278, 4, 1, u32b(rps as u32));
    entry(&mut file, 279, 4, n as u32, array(&counts, counts_at));
    entry(&mut file, 317, 3, 1, short(if s.predictor { 2 } else { 1 }));
    file.extend_from_slice(&u32b(0));
    assert_eq!(file.len(), ifd_end);
    for v in offsets.iter().chain(&counts) {
        file.extend_from_slice(&u32b(*v));
    }
    for st in &strips {
        file.extend_from_slice(st);
    }
    file
}

/// The values the image should have: the `image` crate's conversion of the samples.
fn expected(s: &Spec) -> Vec<f32> {
    let max = if s.sixteen { 65535 } else { 255 };
    let v = |x: u16| if s.min_is_white { max - x } else { x };
    if s.sixteen {
        let b = image::ImageBuffer::<image::Luma<u16>, _>::from_raw(
            s.width,
            s.height,
            s.samples.iter().map(|&x| v(x)).collect(),
        )
        .unwrap();
        image::DynamicImage::ImageLuma16(b).to_luma32f().into_raw()
    } else {
        let b = image::GrayImage::from_raw(
            s.width,
            s.height,
            s.samples.iter().map(|&x| v(x) as u8).collect(),
        )
        .unwrap();
        image::DynamicImage::ImageLuma8(b).to_luma32f().into_raw()
    }
}

/// Damage done to a file.
#[derive(Clone, Debug)]
enum Damage {
    /// XOR a byte.
    Flip(prop::sample::Index, u8),
    /// Overwrite 4 bytes (an offset, a count, a size…).
    Word(prop::sample::Index, u32),
    /// Cut the file.
    Cut(prop::sample::Index),
}

fn damage() -> impl Strategy<Value = Damage> {
    prop_oneof![
        3 => (any::<prop::sample::Index>(), 1u8..=255).prop_map(|(i, x)| Damage::Flip(i, x)),
        2 => (any::<prop::sample::Index>(), prop_oneof![
            any::<u32>(),
            0u32..64,
            Just(u32::MAX),
            Just(40_001)
        ])
        .prop_map(|(i, x)| Damage::Word(i, x)),
        1 => any::<prop::sample::Index>().prop_map(Damage::Cut),
    ]
}

fn apply(bytes: &mut Vec<u8>, d: &Damage) {
    if bytes.is_empty() {
        return;
    }
    match d {
        Damage::Flip(i, x) => {
            let i = i.index(bytes.len());
            bytes[i] ^= x;
        }
        Damage::Word(i, x) => {
            if bytes.len() >= 4 {
                let i = i.index(bytes.len() - 3);
                bytes[i..i + 4].copy_from_slice(&x.to_le_bytes());
            }
        }
        Damage::Cut(i) => {
            let i = i.index(bytes.len());
            bytes.truncate(i);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 600, ..ProptestConfig::default() })]

    /// Every layout: the fast path takes it and gives the image crate's values bit for bit.
    #[test]
    fn random_grey_tiffs_decode_as_the_image_crate_does(s in spec()) {
        let bytes = encode(&s);
        let fast = decode_grey_strips(&bytes);
        prop_assert!(fast.is_ok(), "{:?}", fast.err());
        let fast = fast.unwrap();
        let (w, h, want) = reference(&bytes).unwrap();
        prop_assert_eq!((fast.width, fast.height), (w, h));
        prop_assert!(same_bits(&fast.data, &want));
        prop_assert!(same_bits(&want, &expected(&s)));
        let img = decode_image(&bytes, "x.tif").unwrap();
        prop_assert!(same_bits(&img.data, &want));
    }

    /// Damaged files: no panic; whatever the fast path accepts, the image crate accepts with the
    /// same values; `decode_image` gives an image of the file's size or an error naming it.
    #[test]
    fn damaged_grey_tiffs_never_panic(
        s in spec(),
        damages in proptest::collection::vec(damage(), 1..4),
    ) {
        let mut bytes = encode(&s);
        for d in &damages {
            apply(&mut bytes, d);
        }
        let theirs = reference(&bytes);
        if let Ok(img) = decode_grey_strips(&bytes) {
            prop_assert_eq!(img.data.len(), img.width * img.height);
            let (w, h, want) = theirs.clone().map_err(|e| {
                TestCaseError::fail(format!("fast path accepted what the image crate refuses: {e}"))
            })?;
            prop_assert_eq!((img.width, img.height), (w, h));
            prop_assert!(same_bits(&img.data, &want));
        }
        match decode_image(&bytes, "damaged.tif") {
            Ok(img) => {
                prop_assert_eq!(img.data.len(), img.width * img.height);
                if let Ok((w, h, _)) = theirs {
                    prop_assert_eq!((img.width, img.height), (w, h));
                }
            }
            Err(e) => prop_assert!(e.to_string().starts_with("damaged.tif: "), "{}", e),
        }
    }
}

/// Hand-made damage where it matters most: strip offsets and byte counts outside the file,
/// wrong strip counts, absurd sizes, codes beyond the table.
#[test]
fn damaged_headers_and_strips_are_errors() {
    let s = Spec {
        width: 30,
        height: 20,
        sixteen: false,
        rows_per_strip: 3,
        predictor: true,
        lzw: true,
        big_endian: false,
        min_is_white: false,
        tiff_encoder: false,
        samples: (0..600).map(|i| (i * 7 % 251) as u16).collect(),
    };
    let good = by_hand(&s);
    assert!(decode_grey_strips(&good).is_ok());
    // IFD entry i starts at 10 + 12 i; its value at + 8. Entries: width, height, bits,
    // compression, photometric, offsets, samples, rows per strip, counts, predictor.
    let value_at = |i: usize| 10 + 12 * i + 8;
    let count_at = |i: usize| 10 + 12 * i + 4;
    let offsets_array = u32::from_le_bytes(good[value_at(5)..][..4].try_into().unwrap()) as usize;
    let counts_array = u32::from_le_bytes(good[value_at(8)..][..4].try_into().unwrap()) as usize;
    let set = |b: &mut Vec<u8>, at: usize, v: u32| b[at..at + 4].copy_from_slice(&v.to_le_bytes());
    type Edit = Box<dyn Fn(&mut Vec<u8>)>;
    let cases: Vec<(&str, Edit)> = vec![
        (
            "strip offset beyond the file",
            Box::new(move |b| set(b, offsets_array + 8, 1 << 30)),
        ),
        (
            "strip offset near u32::MAX",
            Box::new(move |b| set(b, offsets_array, u32::MAX)),
        ),
        (
            "byte count beyond the file",
            Box::new(move |b| set(b, counts_array + 4, 1 << 30)),
        ),
        (
            "byte count of 0",
            Box::new(move |b| set(b, counts_array, 0)),
        ),
        ("too few strips", Box::new(move |b| set(b, count_at(5), 6))),
        (
            "too many rows per strip",
            Box::new(move |b| set(b, value_at(7), 2)),
        ),
        (
            "width beyond the limit",
            Box::new(move |b| set(b, value_at(0), 40_001)),
        ),
        (
            "huge height",
            Box::new(move |b| set(b, value_at(1), u32::MAX)),
        ),
        (
            "codes beyond the table",
            Box::new(move |b| {
                let start = b.len() - 40;
                for x in &mut b[start..] {
                    *x = 0xff;
                }
            }),
        ),
    ];
    for (what, damage) in cases {
        let mut b = good.clone();
        damage(&mut b);
        assert!(decode_grey_strips(&b).is_err(), "{what}");
        let e = decode_image(&b, "bad.tif").unwrap_err().to_string();
        assert!(e.starts_with("bad.tif: "), "{what}: {e}");
    }
}

/// Layouts the fast path leaves to the general decoder still decode (tiles would too).
#[test]
fn other_layouts_go_the_general_way() {
    let rgb = image::DynamicImage::ImageRgb8(image::RgbImage::from_fn(9, 7, |x, y| {
        image::Rgb([x as u8 * 20, y as u8 * 30, 7])
    }));
    let mut tif = Cursor::new(Vec::new());
    rgb.write_to(&mut tif, image::ImageFormat::Tiff).unwrap();
    let tif = tif.into_inner();
    assert!(matches!(
        decode_grey_strips(&tif),
        Err(NotDecoded::Unsupported(_))
    ));
    let g = decode_image(&tif, "rgb.tif").unwrap();
    assert!(same_bits(&g.data, &rgb.to_luma32f().into_raw()));
    let mut png = Cursor::new(Vec::new());
    rgb.write_to(&mut png, image::ImageFormat::Png).unwrap();
    assert!(matches!(
        decode_grey_strips(png.get_ref()),
        Err(NotDecoded::Unsupported(_))
    ));
}
