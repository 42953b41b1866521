//! Step 9: the LRF drawn on the images — the check a person makes first. Every point of
//! the output cloud (the one `cloud.ply` holds, [`Stages::lrf_out`]) is carried into the
//! photogrammetric frame by the calibration's extrinsic, `X = T_object←lrf · p`, and
//! projected into every oriented image with that image's orientation and its camera's
//! intrinsics ([`Scene::project_into`]). The points of a sphere that the cloud's ball
//! finder fitted are drawn as that ball's (its label is the ball it was matched to, else
//! `L<k>` as in the report's cloud section); every other point is coloured by its range
//! from the LRF, on one scale for all images (the 2nd to 98th percentile of the whole
//! cloud's ranges), so a colour means the same distance in every picture.
//!
//! The extrinsic is the result's (the joint adjustment's when it ran, else the two-step
//! sphere method's); the image orientations are the bundle adjustment's (the joint
//! adjustment moves them by far less than a pixel). With no extrinsic there is nothing to
//! draw. Points are not tested for occlusion: a point the camera cannot see (behind a
//! ball, under a table) is drawn where it would be.
//!
//! Outputs: each image in which at least one point lands, at full resolution, as
//! `overlays/<image>.png` in the output folder; and for the report a thumbnail of each
//! (the main image [`MAIN_WIDTH`] px wide, the others [`THUMB_WIDTH`] px). The work is
//! `O(images · points)` plus the pixels of the images drawn.

use super::ids::{ImageId, SphereId};
use super::scene::{self, Scene};
use crate::progress::Reporter;
use crate::stages::Stages;
use pingcal_geometry::Sim3;
use pingcal_report::overlay::{render_png, GreyImage, OverlayOptions, OverlayPoint, PointKind};
use pingcal_report::Overlay;
use rayon::prelude::*;
use std::collections::BTreeSet;

/// Width of the main image's thumbnail in the report, px.
pub const MAIN_WIDTH: u32 = 960;

/// Width of the other images' thumbnails in the report, px.
pub const THUMB_WIDTH: u32 = 360;

/// The overlays of a calibration.
#[derive(Debug, Default)]
pub struct Drawn {
    /// `overlays/<image>.png` (path below the output folder) and its bytes.
    pub files: Vec<(String, Vec<u8>)>,
    /// The report's thumbnails, the main image first.
    pub report: Vec<Overlay>,
}

/// The result's LRF → photogrammetric frame transform: the joint adjustment's when it ran,
/// else the sphere method's.
fn object_from_lrf(st: &Stages) -> Option<Sim3> {
    match st.joint {
        Some(Ok(j)) => Some(Sim3::new(
            1.0,
            j.camera_from_lrf.rotation,
            j.camera_from_lrf.translation,
        )),
        _ => st
            .ext
            .spheres
            .as_ref()
            .map(|ev| ev.registration.camera_from_lrf),
    }
}

/// The label of each cloud point that lies on a fitted sphere (`None`: any other point).
fn ball_labels(st: &Stages) -> Vec<Option<String>> {
    let lrf = st.lrf_out;
    let mut labels = vec![None; lrf.cloud.points.len()];
    for (k, b) in lrf.found.balls.iter().enumerate() {
        let matched = (st.pairs_out.iter())
            .find(|(s, _)| *s == SphereId(k))
            .map(|(_, j)| st.scene.points[*j].name.clone());
        let label = matched.unwrap_or_else(|| format!("L{}", k + 1));
        for &i in &b.inliers {
            if let Some(l) = labels.get_mut(i) {
                *l = Some(label.clone());
            }
        }
    }
    labels
}

/// The 2nd and 98th percentiles of the points' ranges (mm), the colour scale of every
/// image.
fn range_scale(ranges: &[f64]) -> Option<(f64, f64)> {
    let mut r: Vec<f64> = ranges.iter().copied().filter(|v| v.is_finite()).collect();
    if r.is_empty() {
        return None;
    }
    r.sort_by(f64::total_cmp);
    let q = |p: f64| r[((r.len() - 1) as f64 * p).round() as usize];
    let (lo, hi) = (q(0.02), q(0.98));
    Some(if hi > lo {
        (lo, hi)
    } else {
        (lo - 0.5, lo + 0.5)
    })
}

/// The points of the cloud that land in image `i`: the object points `xs`, their labels
/// and ranges. Also the number that do not (behind the camera or outside the frame).
fn projected(
    scene: &Scene,
    i: ImageId,
    xs: &[nalgebra::Vector3<f64>],
    labels: &[Option<String>],
    ranges: &[f64],
) -> (Vec<OverlayPoint>, usize) {
    let mut out = Vec::new();
    let mut unseen = 0;
    for ((x, label), &range_mm) in xs.iter().zip(labels).zip(ranges) {
        let Some(uv) = scene.project_into(i, x) else {
            unseen += 1;
            continue;
        };
        let kind = match label {
            Some(l) => PointKind::Ball { label: l.clone() },
            None => PointKind::Range { range_mm },
        };
        out.push(OverlayPoint {
            x: uv.x,
            y: uv.y,
            kind,
        });
    }
    (out, unseen)
}

/// The image file of `i` decoded to 8-bit grey.
fn grey(st: &Stages, i: ImageId) -> Result<GreyImage, String> {
    let path = &st.project.image_paths[i.0];
    let img = pingcal_targets::load_image(path).map_err(|e| e.to_string())?;
    Ok(GreyImage {
        width: img.width as u32,
        height: img.height as u32,
        pixels: (img.data.iter())
            .map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8)
            .collect(),
    })
}

/// `overlays/<stem>.png` for each image, the stem made unique by the image's number where
/// two files share it.
fn file_names(st: &Stages, images: &[ImageId]) -> Vec<String> {
    let stem = |i: &ImageId| {
        let f = scene::image_file(st.project, *i);
        let name = std::path::Path::new(f)
            .file_stem()
            .map_or_else(|| f.to_string(), |s| s.to_string_lossy().into_owned());
        name.chars()
            .map(|c| {
                if c.is_alphanumeric() || "-_.".contains(c) {
                    c
                } else {
                    '_'
                }
            })
            .collect::<String>()
    };
    let stems: Vec<String> = images.iter().map(stem).collect();
    let mut seen = BTreeSet::new();
    let dup: BTreeSet<&String> = stems.iter().filter(|s| !seen.insert(*s)).collect();
    (images.iter().zip(&stems))
        .map(|(i, s)| match dup.contains(s) {
            true => format!("overlays/{s}_{}.png", i.0 + 1),
            false => format!("overlays/{s}.png"),
        })
        .collect()
}

/// One image drawn: its file (path below the output folder, bytes) and its report entry.
type OneDrawn = ((String, Vec<u8>), Overlay);

/// One image drawn, or `None` when no point lands in it.
fn draw_one(
    st: &Stages,
    i: ImageId,
    file: &str,
    points: (Vec<OverlayPoint>, usize),
    range_mm: Option<(f64, f64)>,
) -> Option<Result<OneDrawn, String>> {
    let (points, unseen) = points;
    if points.is_empty() {
        return None;
    }
    let img = match grey(st, i) {
        Ok(img) => img,
        Err(e) => return Some(Err(e)),
    };
    let main = i == scene::main_image(st.project);
    let opts = |max_width: Option<u32>| OverlayOptions {
        max_width,
        range_mm,
        small_file: max_width.is_some(),
        ..OverlayOptions::default()
    };
    let full = render_png(&img, &points, &opts(None));
    let width = if main { MAIN_WIDTH } else { THUMB_WIDTH };
    let thumb = render_png(&img, &points, &opts(Some(width)));
    let im = &st.project.file.images[i.0];
    let caption = format!(
        "camera {}, station {}{}",
        im.camera,
        im.station,
        if main { " (the main image)" } else { "" }
    );
    let name = scene::image_file(st.project, i);
    let mut entry = Overlay::of(name, &caption, main, &thumb);
    entry.outside += unseen;
    Some(Ok(((file.to_string(), full.png), entry)))
}

/// The overlays of the calibration `st` (see the module doc). An image that cannot be read
/// again is left out with a log line.
pub fn draw(st: &Stages, rep: &Reporter) -> Drawn {
    let Some(t) = object_from_lrf(st) else {
        rep.log("overlays: no extrinsic, nothing drawn on the images");
        return Drawn::default();
    };
    let cloud = &st.lrf_out.cloud.points;
    let xs: Vec<_> = cloud.iter().map(|p| t.transform(p)).collect();
    let ranges: Vec<f64> = cloud.iter().map(|p| p.norm()).collect();
    let labels = ball_labels(st);
    let range_mm = range_scale(&ranges);
    let mut images = st.scene.oriented();
    let main = scene::main_image(st.project);
    images.sort_by_key(|&i| (i != main, i.0));
    let files = file_names(st, &images);
    let pb = rep.task("drawing the LRF on the images", images.len() as u64);
    let drawn: Vec<_> = (images.par_iter().zip(&files))
        .map(|(&i, file)| {
            let pts = projected(st.scene, i, &xs, &labels, &ranges);
            let r = draw_one(st, i, file, pts, range_mm);
            pb.advance(1);
            r
        })
        .collect();
    pb.finish();
    let mut out = Drawn::default();
    for r in drawn.into_iter().flatten() {
        match r {
            Ok((file, entry)) => {
                out.files.push(file);
                out.report.push(entry);
            }
            Err(e) => rep.log(format!("overlays: {e}: not drawn")),
        }
    }
    rep.log(format!(
        "overlays: the LRF's {} points drawn on {} of {} oriented images",
        cloud.len(),
        out.files.len(),
        images.len()
    ));
    out
}
