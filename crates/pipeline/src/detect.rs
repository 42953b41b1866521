//! Step 1: targets and ball silhouettes in every image.
//!
//! Images are decoded and measured in parallel (one image per worker). The detector runs
//! with ball classification off: whether a round blob is a flat target or a ball is decided
//! later, in millimetres, once the blob has been triangulated ([`super::matching`]). For
//! every plain blob the silhouette is also refitted with the ball settings
//! ([`pingcal_targets::ball::fit_ball_silhouette`]), so that no image needs to be kept in
//! memory for the eccentricity correction of the balls.

use super::scene::{BallFit, Detections, ImageMeasurements};
use crate::context::{Options, PipelineError, Result};
use crate::progress::Reporter;
use pingcal_project::{Project, ProjectCamera};
use pingcal_targets::detect::BallMode;
use pingcal_targets::ellipse::Ellipse;
use pingcal_targets::refusal::{counts, why_nothing, Refusal};
use pingcal_targets::{load_image, DetectParams, Detector, GrayImage, TargetKind};
use rayon::prelude::*;
use std::path::Path;

/// The detector of `project`: its code family and ring, balls told later, saturated targets
/// measured when `[targets] measure_saturated` or `opts.measure_saturated` asks.
pub fn detector(project: &Project, opts: &Options) -> Result<Detector> {
    let t = &project.file.targets;
    Detector::new(DetectParams {
        code_bits: vec![t.family.code_bits()],
        ring: (t.ring_inner, t.ring_outer),
        balls: BallMode::Off,
        measure_saturated: t.measure_saturated || opts.measure_saturated,
        ..DetectParams::default()
    })
    .map_err(|e| PipelineError::Input(format!("{}: [targets] {e}", project.path.display())))
}

/// Detects every image of the project; an image of the wrong size for its camera is an error.
pub fn detect_all(project: &Project, opts: &Options, rep: &Reporter) -> Result<Detections> {
    let f = &project.file;
    let detector = detector(project, opts)?;
    let pb = rep.task("detecting targets", project.image_paths.len() as u64);
    let out: Vec<Result<(ImageMeasurements, Vec<Refusal>)>> = project
        .image_paths
        .par_iter()
        .zip(&f.images)
        .map(|(path, im)| {
            let img = load_image(path).map_err(|e| PipelineError::Input(e.to_string()))?;
            let cam = f
                .cameras
                .iter()
                .find(|c| c.id == im.camera)
                .expect("validated camera");
            check_size(path, &img, cam)?;
            let measured = measure(&detector, &img, cam);
            pb.advance(1);
            Ok(measured)
        })
        .collect();
    pb.finish();
    let (dets, refused): (Vec<ImageMeasurements>, Vec<Vec<Refusal>>) = out
        .into_iter()
        .collect::<Result<Vec<_>>>()?
        .into_iter()
        .unzip();
    let dets: Detections = dets.into();
    log_detections(project, &dets, &refused, rep);
    Ok(dets)
}

/// An error naming the image and its camera when `img` is not of `cam`'s size.
fn check_size(path: &Path, img: &GrayImage, cam: &ProjectCamera) -> Result<()> {
    if img.width != cam.width as usize || img.height != cam.height as usize {
        return Err(PipelineError::Input(format!(
            "{}: the image is {}×{} pixels, but camera '{}' is {}×{} (project.toml [[cameras]])",
            path.display(),
            img.width,
            img.height,
            cam.id,
            cam.width,
            cam.height
        )));
    }
    Ok(())
}

/// The targets of one image of camera `cam`, with the ball fit of every plain blob of two
/// pixels' radius or more, and the candidates the detector refused.
fn measure(
    detector: &Detector,
    img: &GrayImage,
    cam: &ProjectCamera,
) -> (ImageMeasurements, Vec<Refusal>) {
    let d = detector.detect(img);
    let keep_edges = !cam.model.silhouette_is_ellipse();
    let ball_fits = d
        .targets
        .iter()
        .map(|t| {
            (t.kind == TargetKind::Plain && t.ellipse.radius() >= 2.0)
                .then(|| ball_fit(img, &t.ellipse, keep_edges))
                .flatten()
        })
        .collect();
    let dets = ImageMeasurements {
        width: d.width,
        height: d.height,
        targets: d.targets.into(),
        ball_fits,
    };
    (dets, d.refused)
}

/// Logs what was detected: each image without targets and why, then the counts of coded
/// targets, numbers read, round blobs, saturated targets and refused candidates.
fn log_detections(project: &Project, dets: &Detections, refused: &[Vec<Refusal>], rep: &Reporter) {
    let f = &project.file;
    let (mut coded, mut ids, mut plain, mut saturated) = (0, 0, 0, 0);
    for d in dets {
        for t in &d.targets {
            saturated += usize::from(t.saturated);
            match t.kind {
                TargetKind::Coded => {
                    coded += 1;
                    ids += t.id.is_some() as usize;
                }
                _ => plain += 1,
            }
        }
    }
    for (k, d) in dets.iter().enumerate() {
        if d.targets.is_empty() {
            rep.log(format!(
                "  {}: no targets: {}",
                f.images[k].file,
                why_nothing(&refused[k])
            ));
        }
    }
    let refused: Vec<String> = counts(refused.iter().flatten())
        .iter()
        .map(|(r, n)| format!("{n} {}", r.name()))
        .collect();
    rep.log(format!(
        "detected in {} images: {coded} coded targets ({ids} numbers read), {plain} round blobs (plain targets or balls){}; candidates refused: {} (`pingcal detect --why` lists them)",
        dets.len(),
        if saturated > 0 {
            format!(", {saturated} of them measured although saturated (σ tripled)")
        } else {
            String::new()
        },
        if refused.is_empty() { "none".into() } else { refused.join(", ") }
    ));
}

/// The ball fit of a plain blob outlined by `seed`, with its edge points when `keep_edges` (none
/// when they cannot be found: the ellipse stands for the outline then). None when the
/// silhouette cannot be fitted.
fn ball_fit(img: &GrayImage, seed: &Ellipse, keep_edges: bool) -> Option<BallFit> {
    use pingcal_targets::ball::{ball_silhouette_edges, fit_ball_silhouette};
    let fit = fit_ball_silhouette(img, seed).ok()?;
    let edges = if keep_edges {
        ball_silhouette_edges(img, &fit).unwrap_or_default()
    } else {
        Vec::new()
    };
    Some(BallFit {
        ellipse: fit.ellipse,
        sigma_px: fit.sigma_ellipse,
        edges,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use pingcal_targets::printable::target_is_white;
    use pingcal_targets::GrayImage;

    /// A flat render of coded target 7 (dot radius 9 px, centre (70, 80)) on a grey ground, its
    /// white at full scale.
    fn saturated_target() -> (GrayImage, u32) {
        let table = pingcal_targets::aicon::CodeTable::generate(14).unwrap();
        let (id, n, rad) = (7, 200usize, 9.0);
        let mut img = GrayImage::new(n, n, 0.35);
        for y in 0..n {
            for x in 0..n {
                let mut acc = 0.0;
                for s in 0..9 {
                    let u = (x as f64 - 70.0 + ((s % 3) as f64 - 1.0) / 3.0) / rad;
                    let v = (y as f64 - 80.0 + ((s / 3) as f64 - 1.0) / 3.0) / rad;
                    let code = table.code(id).unwrap();
                    acc += match (
                        u.abs() <= 4.0 && v.abs() <= 4.0,
                        target_is_white(code, 14, u, v),
                    ) {
                        (false, _) => 0.35,
                        (true, true) => 1.0,
                        (true, false) => 0.05,
                    };
                }
                img.data[y * n + x] = 1.2 * acc / 9.0;
            }
        }
        // a lens's blur ([1 2 1] / 4 four times each way) and a little noise, clipped at full
        // scale as a sensor's (the white 20 % over it)
        for _ in 0..4 {
            let d = img.data.clone();
            for y in 1..n - 1 {
                for x in 1..n - 1 {
                    let at = |dx: usize, dy: usize| d[(y + dy - 1) * n + x + dx - 1];
                    img.data[y * n + x] = (4.0 * at(1, 1)
                        + 2.0 * (at(0, 1) + at(2, 1) + at(1, 0) + at(1, 2))
                        + at(0, 0)
                        + at(2, 0)
                        + at(0, 2)
                        + at(2, 2))
                        / 16.0;
                }
            }
        }
        for (k, v) in img.data.iter_mut().enumerate() {
            let noise = 0.004 * ((k * 7919 % 13) as f32 - 6.0) / 6.0;
            *v = (*v + noise).min(1.0);
        }
        (img, id)
    }

    /// A saturated target is refused, named so, unless `[targets] measure_saturated` or the
    /// option (`pingcal calibrate --saturated`) asks: then it is measured, its number read,
    /// flagged, with three times the σ of its fit.
    #[test]
    fn measure_saturated_changes_what_is_measured() {
        let (img, id) = saturated_target();
        let file = crate::test_support::readme_project_file();
        assert!(!file.targets.measure_saturated, "off by default");
        let refusing = crate::test_support::project(file.clone(), Vec::new());
        let d = detector(&refusing, &Options::default())
            .unwrap()
            .detect(&img);
        assert!(d.targets.iter().all(|t| t.id.is_none()), "{:?}", d.targets);
        assert!(
            d.refused
                .iter()
                .any(|r| r.reason == pingcal_targets::refusal::RefusalReason::Saturated),
            "{:?} {:?}",
            d.targets,
            d.refused
        );
        let mut asking = file;
        asking.targets.measure_saturated = true;
        let by_project = crate::test_support::project(asking, Vec::new());
        let by_option = Options {
            measure_saturated: true,
            ..Options::default()
        };
        for d in [
            detector(&by_project, &Options::default())
                .unwrap()
                .detect(&img),
            detector(&refusing, &by_option).unwrap().detect(&img),
        ] {
            let t = d.targets.iter().find(|t| t.id.is_some()).expect("measured");
            assert_eq!(t.id, Some(id));
            assert!(t.saturated);
            assert!(
                (t.x - 70.0).abs() < 0.2 && (t.y - 80.0).abs() < 0.2,
                "{} {}",
                t.x,
                t.y
            );
        }
    }

    /// A white disc of radius 10 px centred at (100.3, 90.6) on a grey ground, with the
    /// edge's coverage by 4 × 4 samples a pixel.
    fn disc() -> GrayImage {
        let n = 200usize;
        let mut img = GrayImage::new(n, n, 0.3);
        for y in 0..n {
            for x in 0..n {
                let inside = (0..16)
                    .filter(|s| {
                        let u = x as f64 + (f64::from(s % 4) - 1.5) / 4.0 - 100.3;
                        let v = y as f64 + (f64::from(s / 4) - 1.5) / 4.0 - 90.6;
                        u.hypot(v) <= 10.0
                    })
                    .count();
                img.data[y * n + x] = 0.3 + 0.6 * inside as f32 / 16.0;
            }
        }
        img
    }

    /// Each image's measurement has one ball fit per target: a fit of the silhouette for a
    /// plain blob (here a disc, fitted where it is), none for a coded target.
    #[test]
    fn a_plain_blob_gets_a_ball_fit_and_a_coded_target_none() {
        let project =
            crate::test_support::project(crate::test_support::readme_project_file(), Vec::new());
        let plain = detector(&project, &Options::default()).unwrap();
        let cam = &project.file.cameras[0];
        let (m, _) = measure(&plain, &disc(), cam);
        assert_eq!(m.targets.len(), 1, "{:?}", m.targets);
        let t = m.targets.iter().next().unwrap();
        assert_eq!(t.kind, TargetKind::Plain);
        let fit = m
            .ball_fits
            .iter()
            .next()
            .unwrap()
            .as_ref()
            .expect("a ball fit");
        let e = fit.ellipse;
        assert!(
            (e.cx - 100.3).abs() < 0.1 && (e.cy - 90.6).abs() < 0.1,
            "({}, {})",
            e.cx,
            e.cy
        );
        let (img, _) = saturated_target();
        let asking = Options {
            measure_saturated: true,
            ..Options::default()
        };
        let saturated = detector(&project, &asking).unwrap();
        let (m, _) = measure(&saturated, &img, cam);
        assert_eq!(m.ball_fits.len(), m.targets.len());
        for (t, f) in m.targets.iter().zip(m.ball_fits.iter()) {
            if t.kind == TargetKind::Coded {
                assert!(f.is_none(), "a coded target has no ball fit");
            }
        }
        assert!(m.targets.iter().any(|t| t.kind == TargetKind::Coded));
    }

    /// An image of another size than its camera's is refused with one line naming the file,
    /// both sizes and the camera.
    #[test]
    fn an_image_of_the_wrong_size_is_refused_naming_both_sizes() {
        let file = crate::test_support::readme_project_file();
        let cam = &file.cameras[0];
        let img = GrayImage::new(cam.width as usize + 1, cam.height as usize, 0.5);
        let e = check_size(Path::new("images/a.png"), &img, cam)
            .expect_err("one pixel wider")
            .to_string();
        let want = format!(
            "images/a.png: the image is {}×{} pixels, but camera '{}' is {}×{}",
            cam.width + 1,
            cam.height,
            cam.id,
            cam.width,
            cam.height
        );
        assert!(e.starts_with(&want), "{e}");
        let right = GrayImage::new(cam.width as usize, cam.height as usize, 0.5);
        assert!(check_size(Path::new("images/a.png"), &right, cam).is_ok());
    }
}
