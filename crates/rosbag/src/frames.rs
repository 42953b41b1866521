//! Frames for `pingcal sphere-calib` from a bag's clouds and images: when does the sphere
//! stand still in both?
//!
//! Each message gets a small signature: a cloud, its points in a grid of 50 mm cells; an
//! image, a grey thumbnail (the image averaged over blocks, at most 160 pixels wide). The
//! motion between two consecutive messages of a topic is the share of what changed: for
//! clouds, the points with no point of the cloud before within 50 mm; for images, the
//! thumbnail pixels whose grey level changed by more than 8. A still scene changes only
//! by its noise (almost nothing), a sphere carried to its next place changes its own points
//! and pixels and those it uncovers (a percent or so of the scene). A message is *still*
//! when its motion from the one before is at most twice the 20th percentile of the topic's
//! motions (the still level of a recording in which the sphere stands still a good part of
//! the time) or under [`MIN_STILL_CLOUD`] / [`MIN_STILL_IMAGE`]; a run of two or more
//! still messages is a moment ([`still_runs`]). A moment of the clouds and one of the
//! images that overlap in time give one frame: the cloud nearest the middle of the overlap
//! and the image nearest that cloud's stamp ([`pair_moments`]).

use crate::msgs::{CompressedImage, Image, PointCloud2};
use std::collections::HashMap;

/// A cloud point moved when no point of the cloud before is this near, in the cloud's unit
/// (metres): 50 mm.
pub const NEAR: f64 = 0.05;
/// Widest thumbnail, pixels.
pub const THUMB_WIDTH: u32 = 160;
/// A thumbnail pixel changed when its grey level changed by more than this.
pub const GREY_CHANGE: f32 = 8.0;
/// A share of moved points under this is still whatever the percentile says.
pub const MIN_STILL_CLOUD: f64 = 0.002;
/// A share of changed pixels under this is still whatever the percentile says.
pub const MIN_STILL_IMAGE: f64 = 0.002;

/// A cloud's points in a grid of [`NEAR`] cells.
#[derive(Debug, Clone, Default)]
pub struct CloudGrid {
    cells: HashMap<[i32; 3], Vec<[f64; 3]>>,
    points: usize,
}

fn cell(p: [f64; 3]) -> [i32; 3] {
    p.map(|v| (v / NEAR).floor().clamp(-1e9, 1e9) as i32)
}

/// The grid of a cloud's points.
pub fn cloud_signature(c: &PointCloud2) -> CloudGrid {
    let mut g = CloudGrid::default();
    for p in &c.points {
        g.cells.entry(cell(p.xyz)).or_default().push(p.xyz);
    }
    g.points = c.points.len();
    g
}

/// The share of `b`'s points with no point of `a` within [`NEAR`] (1 when `a` is empty
/// and `b` is not, 0 for an empty `b`).
pub fn cloud_motion(a: &CloudGrid, b: &CloudGrid) -> f64 {
    if b.points == 0 {
        return 0.0;
    }
    let near2 = NEAR * NEAR;
    let mut moved = 0usize;
    for (c, pts) in &b.cells {
        for p in pts {
            let mut found = false;
            'cells: for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        let Some(q) = a.cells.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) else {
                            continue;
                        };
                        if q.iter()
                            .any(|q| (0..3).map(|k| (p[k] - q[k]).powi(2)).sum::<f64>() <= near2)
                        {
                            found = true;
                            break 'cells;
                        }
                    }
                }
            }
            moved += usize::from(!found);
        }
    }
    moved as f64 / b.points as f64
}

/// A grey thumbnail: width, height, pixels (grey levels 0–255).
#[derive(Debug, Clone, PartialEq)]
pub struct Thumb {
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Row-major grey levels.
    pub grey: Vec<f32>,
}

/// The grey level of pixel (x, y) of a raw image, or an error for an encoding not read.
fn grey_of<'a>(img: &'a Image<'a>) -> Result<impl Fn(u32, u32) -> f32 + 'a, String> {
    let (bpp, kind) = match img.encoding.as_str() {
        "mono8" | "8UC1" => (1, 0),
        "mono16" | "16UC1" => (2, 1),
        "rgb8" | "8UC3" => (3, 2),
        "bgr8" => (3, 3),
        "rgba8" | "8UC4" => (4, 2),
        "bgra8" => (4, 3),
        e => {
            return Err(format!(
                "image encoding {e:?}: pingcal reads mono8, mono16, rgb8, bgr8, rgba8 and bgra8"
            ))
        }
    };
    let need =
        (img.height as usize).saturating_sub(1) * img.step as usize + img.width as usize * bpp;
    if img.width == 0
        || img.height == 0
        || (img.step as usize) < img.width as usize * bpp
        || img.data.len() < need
    {
        return Err(format!(
            "a {}×{} {} image with step {} and {} bytes: too few bytes",
            img.width,
            img.height,
            img.encoding,
            img.step,
            img.data.len()
        ));
    }
    let (d, step, big) = (img.data, img.step as usize, img.big_endian);
    Ok(move |x: u32, y: u32| {
        let at = y as usize * step + x as usize * bpp;
        let p = &d[at..at + bpp];
        match kind {
            0 => f32::from(p[0]),
            1 => {
                let v = if big {
                    u16::from_be_bytes([p[0], p[1]])
                } else {
                    u16::from_le_bytes([p[0], p[1]])
                };
                f32::from(v) / 257.0
            }
            2 => 0.299 * f32::from(p[0]) + 0.587 * f32::from(p[1]) + 0.114 * f32::from(p[2]),
            _ => 0.299 * f32::from(p[2]) + 0.587 * f32::from(p[1]) + 0.114 * f32::from(p[0]),
        }
    })
}

fn thumb_from(width: u32, height: u32, grey: impl Fn(u32, u32) -> f32) -> Thumb {
    let block = width.div_ceil(THUMB_WIDTH).max(1);
    let (tw, th) = (width.div_ceil(block), height.div_ceil(block));
    let mut out = vec![0f32; (tw * th) as usize];
    let mut n = vec![0u32; (tw * th) as usize];
    for y in 0..height {
        for x in 0..width {
            let k = ((y / block) * tw + x / block) as usize;
            out[k] += grey(x, y);
            n[k] += 1;
        }
    }
    for (v, c) in out.iter_mut().zip(&n) {
        *v /= (*c).max(1) as f32;
    }
    Thumb {
        width: tw,
        height: th,
        grey: out,
    }
}

/// The thumbnail of a raw image.
pub fn image_thumb(img: &Image) -> Result<Thumb, String> {
    let grey = grey_of(img)?;
    Ok(thumb_from(img.width, img.height, grey))
}

/// The thumbnail of a compressed image (JPEG or PNG, decoded).
pub fn compressed_thumb(img: &CompressedImage) -> Result<Thumb, String> {
    let dec = image::load_from_memory(img.data)
        .map_err(|e| format!("a {:?} compressed image: {e}", img.format))?
        .into_luma8();
    let (w, h) = dec.dimensions();
    Ok(thumb_from(w, h, |x, y| f32::from(dec.get_pixel(x, y).0[0])))
}

/// The share of thumbnail pixels whose grey level changed by more than [`GREY_CHANGE`];
/// 1 when the sizes differ.
pub fn image_motion(a: &Thumb, b: &Thumb) -> f64 {
    if (a.width, a.height) != (b.width, b.height) || a.grey.is_empty() {
        return 1.0;
    }
    let changed = a
        .grey
        .iter()
        .zip(&b.grey)
        .filter(|(x, y)| (*x - *y).abs() > GREY_CHANGE)
        .count();
    changed as f64 / a.grey.len() as f64
}

/// A run of still messages of one topic: the stamps (ns) of its first and last message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Moment {
    /// First message's stamp.
    pub from_ns: i64,
    /// Last message's stamp.
    pub to_ns: i64,
}

/// The still runs of a topic (module doc) from its messages' stamps and each message's
/// motion from the one before (`motions[0]` is unused: the first message has none).
pub fn still_runs(stamps: &[i64], motions: &[f64], min_still: f64) -> Vec<Moment> {
    let mut m: Vec<f64> = motions
        .iter()
        .skip(1)
        .copied()
        .filter(|v| v.is_finite())
        .collect();
    if m.is_empty() {
        return Vec::new();
    }
    m.sort_by(f64::total_cmp);
    let p20 = m[(m.len() - 1) / 5];
    let threshold = (2.0 * p20).max(min_still);
    let mut runs = Vec::new();
    let mut start: Option<usize> = None;
    for k in 1..stamps.len() {
        let still = motions[k] <= threshold;
        match (still, start) {
            (true, None) => start = Some(k - 1),
            (false, Some(s)) => {
                runs.push(Moment {
                    from_ns: stamps[s],
                    to_ns: stamps[k - 1],
                });
                start = None;
            }
            _ => {}
        }
    }
    if let Some(s) = start {
        runs.push(Moment {
            from_ns: stamps[s],
            to_ns: stamps[stamps.len() - 1],
        });
    }
    runs
}

/// One frame: the stamps of the cloud and the image chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FramePair {
    /// The cloud's stamp, ns.
    pub cloud_ns: i64,
    /// The image's stamp, ns.
    pub image_ns: i64,
}

/// The message of `stamps` (sorted) nearest `t` within `[from, to]`.
fn nearest(stamps: &[i64], t: i64, from: i64, to: i64) -> Option<i64> {
    let k = stamps.partition_point(|&s| s < t);
    [k.checked_sub(1), Some(k)]
        .into_iter()
        .flatten()
        .filter_map(|i| stamps.get(i).copied())
        .filter(|&s| s >= from && s <= to)
        .min_by_key(|&s| (s - t).unsigned_abs())
}

/// The frames: for each cloud moment overlapping an image moment, the cloud nearest the
/// overlap's middle and the image nearest that cloud (both within their moments).
pub fn pair_moments(
    clouds: &[Moment],
    cloud_stamps: &[i64],
    images: &[Moment],
    image_stamps: &[i64],
) -> Vec<FramePair> {
    let mut out = Vec::new();
    for c in clouds {
        for i in images {
            let (from, to) = (c.from_ns.max(i.from_ns), c.to_ns.min(i.to_ns));
            if from > to {
                continue;
            }
            let mid = from + (to - from) / 2;
            let Some(cloud_ns) = nearest(cloud_stamps, mid, c.from_ns, c.to_ns) else {
                continue;
            };
            let Some(image_ns) = nearest(image_stamps, cloud_ns, i.from_ns, i.to_ns) else {
                continue;
            };
            out.push(FramePair { cloud_ns, image_ns });
        }
    }
    out
}

/// The text of a frame's cloud file (`pingcal frames`): a comment naming the columns, the
/// frame and the stamp, then one point per line (`x y z` in metres, then `intensity` and
/// `ring` where the cloud has them), the message's float32 values as their shortest decimals.
pub fn cloud_text(c: &PointCloud2, topic: &str) -> String {
    use std::fmt::Write;
    let mut cols = String::from("x y z");
    if c.has_intensity {
        cols.push_str(" intensity");
    }
    if c.has_ring {
        cols.push_str(" ring");
    }
    let mut out = format!(
        "# {cols}, metres, frame {:?} (pingcal frames, topic {topic}, stamp {} ns)\n",
        c.frame_id, c.stamp_ns
    );
    for p in &c.points {
        let [x, y, z] = p.xyz;
        // the message's float32 values, as their shortest decimals
        let _ = write!(out, "{} {} {}", x as f32, y as f32, z as f32);
        for v in [p.intensity, p.ring].into_iter().flatten() {
            let _ = write!(out, " {v}");
        }
        out.push('\n');
    }
    out
}

/// An image message as a file: its extension and bytes (a raw image as PNG, big-endian for
/// 16-bit samples and RGB for BGR; a compressed one as the JPEG or PNG it is).
pub fn image_file(m: &crate::RawMessage) -> Result<(&'static str, Vec<u8>), String> {
    if m.msg_type == crate::msgs::COMPRESSED_IMAGE {
        let img = CompressedImage::decode(m.data, m.encoding)?;
        let ext = match image::guess_format(img.data) {
            Ok(image::ImageFormat::Png) => "png",
            Ok(image::ImageFormat::Jpeg) => "jpg",
            _ => return Err(format!("format {:?}: expected a JPEG or a PNG", img.format)),
        };
        return Ok((ext, img.data.to_vec()));
    }
    let img = Image::decode(m.data, m.encoding)?;
    let t = image_thumb(&img)?; // checks the encoding and the size
    drop(t);
    let (w, h, step) = (img.width, img.height, img.step as usize);
    let rows = |bpp: usize| -> Vec<u8> {
        (0..h as usize)
            .flat_map(|y| {
                img.data[y * step..y * step + w as usize * bpp]
                    .iter()
                    .copied()
            })
            .collect()
    };
    let mut png = Vec::new();
    let enc = image::codecs::png::PngEncoder::new(&mut png);
    use image::ImageEncoder;
    let done = match img.encoding.as_str() {
        "mono8" | "8UC1" => enc.write_image(&rows(1), w, h, image::ExtendedColorType::L8),
        "rgb8" | "8UC3" => enc.write_image(&rows(3), w, h, image::ExtendedColorType::Rgb8),
        "rgba8" | "8UC4" => enc.write_image(&rows(4), w, h, image::ExtendedColorType::Rgba8),
        "bgr8" | "bgra8" => {
            let bpp = if img.encoding == "bgr8" { 3 } else { 4 };
            let mut px = rows(bpp);
            px.chunks_exact_mut(bpp).for_each(|p| p.swap(0, 2));
            let ty = if bpp == 3 {
                image::ExtendedColorType::Rgb8
            } else {
                image::ExtendedColorType::Rgba8
            };
            enc.write_image(&px, w, h, ty)
        }
        _ => {
            // mono16: big-endian samples, as PNG stores them
            let mut px = rows(2);
            if !img.big_endian {
                px.chunks_exact_mut(2).for_each(|p| p.swap(0, 1));
            }
            enc.write_image(&px, w, h, image::ExtendedColorType::L16)
        }
    };
    done.map_err(|e| format!("cannot encode as PNG: {e}"))?;
    Ok(("png", png))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn still_runs_are_told_from_motion_and_paired_where_they_overlap() {
        // 3 still, 2 moving, 3 still (stamps 100 ms apart)
        let stamps: Vec<i64> = (0..8).map(|k| k * 100).collect();
        let motions = [0.0, 0.1, 0.12, 0.9, 0.95, 0.8, 0.11, 0.1];
        let runs = still_runs(&stamps, &motions, 0.02);
        assert_eq!(
            runs,
            [
                Moment {
                    from_ns: 0,
                    to_ns: 200
                },
                Moment {
                    from_ns: 500,
                    to_ns: 700
                }
            ]
        );
        // images offset by 30 ms, their second still run shorter
        let istamps: Vec<i64> = stamps.iter().map(|s| s + 30).collect();
        let imotions = [0.0, 0.3, 0.2, 9.0, 9.0, 9.0, 9.0, 0.4];
        let iruns = still_runs(&istamps, &imotions, 0.5);
        assert_eq!(iruns.len(), 2, "{iruns:?}");
        let pairs = pair_moments(&runs, &stamps, &iruns, &istamps);
        assert_eq!(
            pairs,
            [
                FramePair {
                    cloud_ns: 100,
                    image_ns: 130
                },
                FramePair {
                    cloud_ns: 700,
                    image_ns: 730
                }
            ]
        );
    }

    #[test]
    fn motions_of_clouds_and_images() {
        use crate::msgs::CloudPoint;
        let cloud = |pts: &[[f64; 3]]| PointCloud2 {
            stamp_ns: 0,
            frame_id: String::new(),
            points: pts
                .iter()
                .map(|&xyz| CloudPoint {
                    xyz,
                    intensity: None,
                    ring: None,
                })
                .collect(),
            has_intensity: false,
            has_ring: false,
        };
        let a = cloud_signature(&cloud(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 2.0, 2.0]]));
        // one point moved by 3 mm across a cell face, one by 30 mm, one by 0.3 m
        let b = cloud_signature(&cloud(&[
            [0.0, 0.0, -0.003],
            [1.03, 0.0, 0.0],
            [2.3, 2.0, 2.0],
        ]));
        assert!((cloud_motion(&a, &b) - 1.0 / 3.0).abs() < 1e-12);
        assert_eq!(cloud_motion(&a, &a), 0.0);
        assert_eq!(cloud_motion(&CloudGrid::default(), &b), 1.0);
        // a 320×2 rgb8 image: thumbnails of 160×1, blocks of 2×2
        let data: Vec<u8> = (0..320 * 2).flat_map(|i| [(i % 256) as u8, 0, 0]).collect();
        let img = Image {
            stamp_ns: 0,
            height: 2,
            width: 320,
            encoding: "rgb8".into(),
            big_endian: false,
            step: 960,
            data: &data,
        };
        let t = image_thumb(&img).unwrap();
        assert_eq!((t.width, t.height), (160, 1));
        assert!((t.grey[0] - 0.299 * (0.0 + 1.0 + 64.0 + 65.0) / 4.0).abs() < 1e-4);
        assert_eq!(image_motion(&t, &t), 0.0);
        let e = image_thumb(&Image {
            encoding: "yuv422".into(),
            ..img.clone()
        })
        .unwrap_err();
        assert!(e.contains("image encoding \"yuv422\""), "{e}");
        let e = image_thumb(&Image {
            data: &data[..100],
            ..img
        })
        .unwrap_err();
        assert!(e.contains("too few bytes"), "{e}");
    }
}
