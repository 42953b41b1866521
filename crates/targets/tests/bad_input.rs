//! Bad and unusual input: never a panic; a clear error naming the file, or an empty result.

use pingcal_targets::{decode_image, detect_image, load_image, DetectParams};
use proptest::prelude::*;
use std::io::Cursor;

fn encode(img: &image::DynamicImage, fmt: image::ImageFormat) -> Vec<u8> {
    let mut buf = Cursor::new(Vec::new());
    img.write_to(&mut buf, fmt).expect("encode");
    buf.into_inner()
}

/// A 120×90 image with a bright disc (r = 10) at (60, 45) on a dark background.
fn disc_rgb16() -> image::DynamicImage {
    let img = image::ImageBuffer::from_fn(120, 90, |x, y| {
        let d = ((x as f64 - 60.0).powi(2) + (y as f64 - 45.0).powi(2)).sqrt();
        let v = if d < 10.0 { 50000u16 } else { 4000 };
        image::Rgb([v, v / 2 + 100, v])
    });
    image::DynamicImage::ImageRgb16(img)
}

#[test]
fn missing_file_is_a_clear_error() {
    let e = load_image(std::path::Path::new("/nonexistent/dir/photo.tif"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("/nonexistent/dir/photo.tif") && e.contains("no such file"),
        "{e}"
    );
}

#[test]
fn empty_and_garbage_files_are_errors() {
    let e = decode_image(&[], "empty.png").unwrap_err().to_string();
    assert!(e.contains("empty.png") && e.contains("empty"), "{e}");
    let e = decode_image(b"this is not an image at all", "notes.jpg")
        .unwrap_err()
        .to_string();
    assert!(e.contains("notes.jpg"), "{e}");
}

#[test]
fn truncated_images_do_not_panic() {
    let img = disc_rgb16();
    for fmt in [
        image::ImageFormat::Png,
        image::ImageFormat::Tiff,
        image::ImageFormat::Jpeg,
    ] {
        let src = if fmt == image::ImageFormat::Jpeg {
            image::DynamicImage::ImageRgb8(img.to_rgb8())
        } else {
            img.clone()
        };
        let bytes = encode(&src, fmt);
        for cut in [8, bytes.len() / 3, bytes.len() / 2, bytes.len() - 3] {
            match decode_image(&bytes[..cut], "cut") {
                Ok(g) => assert!(g.width == 120 && g.height == 90),
                Err(e) => assert!(e.to_string().starts_with("cut: "), "{e}"),
            }
        }
        // Corrupted middle.
        let mut bad = bytes.clone();
        for b in bad.iter_mut().skip(bytes.len() / 4).step_by(7) {
            *b ^= 0x5a;
        }
        let _ = decode_image(&bad, "corrupt");
    }
}

#[test]
fn sixteen_bit_and_colour_images_are_converted() {
    let img = disc_rgb16();
    for (fmt, src) in [
        (image::ImageFormat::Png, img.clone()),
        (image::ImageFormat::Tiff, img.clone()),
        (
            image::ImageFormat::Png,
            image::DynamicImage::ImageLuma16(img.to_luma16()),
        ),
        (
            image::ImageFormat::Tiff,
            image::DynamicImage::ImageLuma16(img.to_luma16()),
        ),
        (
            image::ImageFormat::Jpeg,
            image::DynamicImage::ImageRgb8(img.to_rgb8()),
        ),
        (
            image::ImageFormat::Png,
            image::DynamicImage::ImageLumaA8(img.to_luma_alpha8()),
        ),
    ] {
        let g = decode_image(&encode(&src, fmt), "x").unwrap();
        assert_eq!((g.width, g.height), (120, 90));
        assert!(g.data.iter().all(|v| (0.0..=1.0).contains(v)));
        let d = detect_image(&g, &DetectParams::default()).unwrap();
        assert_eq!(d.targets.len(), 1, "{fmt:?} {:?}", src.color());
        let t = &d.targets[0];
        // JPEG blocks shift the edge a little; the others are exact to the pixel grid.
        assert!(
            (t.x - 60.0).abs() < 0.1 && (t.y - 45.0).abs() < 0.1,
            "{fmt:?}: {} {}",
            t.x,
            t.y
        );
    }
}

#[test]
fn flat_images_give_no_targets() {
    for v in [0.0f32, 0.5, 1.0] {
        let g = pingcal_targets::GrayImage::new(200, 100, v);
        assert!(detect_image(&g, &DetectParams::default())
            .unwrap()
            .targets
            .is_empty());
    }
    let tiny = pingcal_targets::GrayImage::new(1, 1, 1.0);
    assert!(detect_image(&tiny, &DetectParams::default())
        .unwrap()
        .targets
        .is_empty());
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..2048)) {
        let _ = decode_image(&bytes, "fuzz");
    }

    #[test]
    fn arbitrary_bytes_after_a_real_header_never_panic(which in 0usize..4, tail in proptest::collection::vec(any::<u8>(), 0..2048)) {
        let head: &[u8] = match which {
            0 => b"\x89PNG\r\n\x1a\n",
            1 => b"II*\x00",
            2 => b"MM\x00*",
            _ => b"\xff\xd8\xff\xe0",
        };
        let mut bytes = head.to_vec();
        bytes.extend_from_slice(&tail);
        if let Ok(g) = decode_image(&bytes, "fuzz") {
            let _ = detect_image(&g, &DetectParams::default());
        }
    }
}

/// Issue 14: a grey and a colour image in each format, cut anywhere, with bytes appended
/// or a UTF-8 byte-order mark in front, 1,000 cases. A cut image is refused naming the file
/// (or, where the decoder has all it needs, decoded to the same pixels); appended bytes
/// after a complete image change nothing or are refused; a byte-order mark is refused
/// (no image format starts with one).
mod mutations {
    use super::*;

    fn encoded(which: usize) -> Vec<u8> {
        let grey = image::DynamicImage::ImageLuma8(image::GrayImage::from_fn(40, 30, |x, y| {
            image::Luma([(x * 5 + y * 3) as u8])
        }));
        let colour = image::DynamicImage::ImageRgb8(disc_rgb16().to_rgb8());
        let fmts = [
            image::ImageFormat::Png,
            image::ImageFormat::Tiff,
            image::ImageFormat::Jpeg,
        ];
        let img = if which % 2 == 0 { grey } else { colour };
        encode(&img, fmts[(which / 2) % 3])
    }

    fn pixels(bytes: &[u8], name: &str) -> Result<Vec<u32>, String> {
        decode_image(bytes, name)
            .map(|g| g.data.iter().map(|v| v.to_bits()).collect())
            .map_err(|e| e.to_string())
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 1000, ..ProptestConfig::default() })]

        #[test]
        fn cut_appended_or_marked_images_are_refused_or_unchanged(
            which in 0usize..6,
            cut in any::<usize>(),
            tail in proptest::collection::vec(any::<u8>(), 1..16),
        ) {
            let bytes = encoded(which);
            let clean = pixels(&bytes, "clean").unwrap();
            let at = cut % bytes.len();
            match pixels(&bytes[..at], "cut.img") {
                Err(e) => prop_assert!(e.starts_with("cut.img: "), "{}", e),
                Ok(p) => prop_assert_eq!(p, clean.clone(), "a cut image decoded to other pixels"),
            }
            let mut longer = bytes.clone();
            longer.extend_from_slice(&tail);
            match pixels(&longer, "long.img") {
                Err(e) => prop_assert!(e.starts_with("long.img: "), "{}", e),
                Ok(p) => prop_assert_eq!(p, clean.clone(), "appended bytes changed the pixels"),
            }
            let mut marked = "\u{feff}".as_bytes().to_vec();
            marked.extend_from_slice(&bytes);
            let e = pixels(&marked, "bom.img").unwrap_err();
            prop_assert!(e.starts_with("bom.img: "), "{}", e);
        }
    }
}
