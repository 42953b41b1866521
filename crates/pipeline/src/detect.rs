//! Step 1: targets and ball silhouettes in every image.
//!
//! Images are decoded and measured in parallel (one image per worker). The detector runs
//! with ball classification off: whether a round blob is a flat target or a ball is decided
//! later, in millimetres, once the blob has been triangulated ([`super::matching`]). For
//! every plain blob the silhouette is also refitted with the ball settings
//! ([`pingcal_targets::ball::fit_ball_silhouette`]), so that no image needs to be kept in
//! memory for the eccentricity correction of the balls.

use super::scene::{silhouette_is_ellipse, BallFit, Detections, ImageDetections};
use super::{PipelineError, Reporter, Result};
use pingcal_project::Project;
use pingcal_targets::detect::BallMode;
use pingcal_targets::ellipse::Ellipse;
use pingcal_targets::refusal::{counts, why_nothing, Refusal};
use pingcal_targets::{load_image, DetectParams, Detector, GrayImage, TargetKind};
use rayon::prelude::*;

/// Detects every image of the project; an image of the wrong size for its camera is an error.
pub fn detect_all(project: &Project, rep: &Reporter) -> Result<Detections> {
    let f = &project.file;
    let bits = f.targets.family.code_bits();
    let detector = Detector::new(DetectParams {
        code_bits: vec![bits],
        ring: (f.targets.ring_inner, f.targets.ring_outer),
        balls: BallMode::Off,
        ..DetectParams::default()
    })
    .map_err(|e| PipelineError::new(format!("{}: [targets] {e}", project.path.display())))?;
    let pb = rep.task("detecting targets", project.image_paths.len() as u64);
    let out: Vec<Result<(ImageDetections, Vec<Refusal>)>> = project
        .image_paths
        .par_iter()
        .zip(&f.images)
        .map(|(path, im)| {
            let img = load_image(path).map_err(|e| PipelineError::new(e.to_string()))?;
            let cam = f
                .cameras
                .iter()
                .find(|c| c.id == im.camera)
                .expect("validated camera");
            if img.width != cam.width as usize || img.height != cam.height as usize {
                return Err(PipelineError::new(format!(
                    "{}: the image is {}×{} pixels, but camera '{}' is {}×{} (project.toml [[cameras]])",
                    path.display(),
                    img.width,
                    img.height,
                    cam.id,
                    cam.width,
                    cam.height
                )));
            }
            let d = detector.detect(&img);
            let keep_edges = !silhouette_is_ellipse(cam.model.kind());
            let ball_fits = d
                .targets
                .iter()
                .map(|t| {
                    (t.kind == TargetKind::Plain && t.ellipse.radius() >= 2.0)
                        .then(|| ball_fit(&img, &t.ellipse, keep_edges))
                        .flatten()
                })
                .collect();
            pb.advance(1);
            let dets = ImageDetections {
                width: d.width,
                height: d.height,
                targets: d.targets.into(),
                ball_fits,
            };
            Ok((dets, d.refused))
        })
        .collect();
    pb.finish();
    let (dets, refused): (Vec<ImageDetections>, Vec<Vec<Refusal>>) = out
        .into_iter()
        .collect::<Result<Vec<_>>>()?
        .into_iter()
        .unzip();
    let dets: Detections = dets.into();
    let (mut coded, mut ids, mut plain) = (0, 0, 0);
    for d in &dets {
        for t in &d.targets {
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
        "detected in {} images: {coded} coded targets ({ids} numbers read), {plain} round blobs (plain targets or balls); candidates refused: {} (`pingcal detect --why` lists them)",
        dets.len(),
        if refused.is_empty() { "none".into() } else { refused.join(", ") }
    ));
    Ok(dets)
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
