//! The choice of each frame's silhouette: the consensus over the frames
//! ([`super::consensus`]), then, where it found none (or two), a search at the place its
//! transform predicts ([`super::image::at_prediction`]); a frame whose choice stays open is
//! left out, named, never guessed.

use super::camera::Camera;
use super::consensus::{consensus, tolerance, Consensus, NoConsensus, Pick, MIN_HEIGHT_MM};
use super::frames::Frame;
use super::image::{at_prediction, ImageSphere};
use nalgebra::Vector3;
use pingcal_geometry::Sim3;
use rayon::prelude::*;

type V3 = Vector3<f64>;

/// The part of a prediction's σ the consensus transform adds, mm (a transform from three or
/// more frames whose centres agree within a few mm).
pub const PREDICTION_SIGMA_MM: f64 = 5.0;

/// Where in the image a silhouette is, for messages.
fn at(s: &ImageSphere) -> String {
    format!("({:.0}, {:.0}) px", s.image_centre.0, s.image_centre.1)
}

/// Chooses every frame's silhouette (sets `image`, `chosen_by`, or `skipped`); returns the
/// consensus transform, if there is one, and an error naming the line when the sphere's
/// positions lie too near one to give a rotation ([`NoConsensus::OnALine`]).
pub fn choose(
    frames: &mut [Frame],
    cam: &Camera,
    radius: f64,
    seed: u64,
) -> Result<Option<Sim3>, String> {
    let lidar: Vec<Option<V3>> = frames
        .iter()
        .map(|f| {
            f.lidar
                .as_ref()
                .filter(|_| f.skipped.is_none())
                .map(|l| l.centre)
        })
        .collect();
    let cams: Vec<Vec<V3>> = frames
        .iter()
        .map(|f| f.candidates.iter().map(|c| c.centre).collect())
        .collect();
    let c = match consensus(&lidar, &cams, seed) {
        Ok(c) => c,
        Err(why) => {
            skip_without_consensus(frames, &why);
            return match why {
                NoConsensus::OnALine { .. } => Err(on_a_line(frames, &why)),
                _ => Ok(None),
            };
        }
    };
    let t = c.camera_from_lidar;
    let again = search_again(frames, &c, cam, radius);
    for (i, f) in frames.iter_mut().enumerate() {
        if f.skipped.is_some() {
            continue;
        }
        match &c.picks[i] {
            Pick::Chosen(k) => chosen_by_consensus(f, *k),
            Pick::NoLidar => {}
            pick => {
                let again = again
                    .iter()
                    .find(|(j, _)| *j == i)
                    .and_then(|(_, s)| s.clone());
                open_pick(f, pick, again, &t, cam);
            }
        }
    }
    Ok(Some(t))
}

/// The refusal of positions near a line ([`NoConsensus::OnALine`]), one line naming the
/// line, the distance and what to do.
fn on_a_line(frames: &[Frame], why: &NoConsensus) -> String {
    let NoConsensus::OnALine {
        positions,
        within_mm,
        ends,
    } = why
    else {
        return String::new();
    };
    format!(
        "the sphere's {positions} positions lie within {within_mm:.0} mm of a line (the lidar's centres, the line through frames {} and {}), under the {MIN_HEIGHT_MM:.0} mm off it a rotation needs: move it up and down as well as across",
        frames[ends[0]].id, frames[ends[1]].id
    )
}

/// Without a consensus, every frame not yet skipped is skipped: no silhouette, or no
/// consensus to choose among its silhouettes, for the reason `cause` gives.
fn skip_without_consensus(frames: &mut [Frame], cause: &NoConsensus) {
    let because = match cause {
        NoConsensus::TooFewFrames(n) => format!(
            "only {n} frame{} have both a lidar sphere and a silhouette, and 3 are needed to choose",
            if *n == 1 { "" } else { "s" }
        ),
        NoConsensus::OnALine { .. } => on_a_line(frames, cause),
        NoConsensus::NoAgreement => {
            "in no three frames do the silhouettes' distances agree with the lidar's spheres' (a wrong diameter, or not the same ball)".into()
        }
    };
    for f in frames.iter_mut().filter(|f| f.skipped.is_none()) {
        let why = match f.candidates.len() {
            0 => format!("{}: no sphere silhouette found", f.image_path.display()),
            n => format!(
                "{}: {n} sphere silhouette{} found, but there is no consensus to choose: {because}",
                f.image_path.display(),
                if n == 1 { "" } else { "s" }
            ),
        };
        f.skip(why);
    }
}

/// The frames whose choice the consensus `c` left open, searched again where its transform
/// puts the lidar's sphere: per frame index, the silhouette found nearest the prediction
/// within the tolerance, if any.
fn search_again(
    frames: &[Frame],
    c: &Consensus,
    cam: &Camera,
    radius: f64,
) -> Vec<(usize, Option<ImageSphere>)> {
    let t = c.camera_from_lidar;
    frames
        .par_iter()
        .enumerate()
        .filter(|(i, f)| {
            f.skipped.is_none() && !matches!(c.picks[*i], Pick::Chosen(_) | Pick::NoLidar)
        })
        .map(|(i, f)| {
            let l = f.lidar.as_ref().expect("a lidar sphere");
            let p = t.transform(&l.centre);
            // the prediction's σ: the lidar centre's, and as much again for the transform
            let sigma = 2.0 * l.cov.trace().max(0.0).sqrt() + PREDICTION_SIGMA_MM;
            let found = pingcal_targets::load_colour(&f.image_path)
                .map(|img| at_prediction(&img, cam, radius, &p, sigma))
                .unwrap_or_default();
            // the nearest of those within the tolerance
            let near = found
                .into_iter()
                .filter(|s| (s.centre - p).norm() <= tolerance(&p))
                .min_by(|a, b| (a.centre - p).norm().total_cmp(&(b.centre - p).norm()));
            (i, near)
        })
        .collect()
}

/// Frame `f` takes its candidate `k`, which the consensus chose; the other round outlines
/// are a warning.
fn chosen_by_consensus(f: &mut Frame, k: usize) {
    f.image = Some(f.candidates[k].clone());
    f.chosen_by = Some("consensus");
    let others = f.candidates.len() - 1;
    if others > 0 {
        f.warnings.push(format!(
            "{}: {others} other round outline{} than the ball's, which the lidar tells apart",
            f.image_path.display(),
            if others == 1 { "" } else { "s" }
        ));
    }
}

/// Frame `f`, whose choice the consensus left open (`pick`), takes the silhouette the search
/// at the prediction found (`again`), or is skipped with the reason: two silhouettes where
/// the lidar's sphere is, or none there (where `t` puts it in the image).
fn open_pick(f: &mut Frame, pick: &Pick, again: Option<ImageSphere>, t: &Sim3, cam: &Camera) {
    match (pick, again) {
        (Pick::Ambiguous(ks), _) => f.skip(format!(
            "{}: {} silhouettes where the lidar's sphere is, at {}: which one is the ball is not known (take the other ball out of the scene)",
            f.image_path.display(),
            ks.len(),
            ks.iter().map(|&k| at(&f.candidates[k])).collect::<Vec<_>>().join(" and ")
        )),
        (_, Some(s)) => {
            f.image = Some(s);
            f.chosen_by = Some("predicted");
        }
        (Pick::Missing(near), None) => {
            let p = t.transform(&f.lidar.as_ref().expect("a lidar sphere").centre);
            let where_ = cam.project(&p).map_or("outside the image".into(), |(x, y)| format!("at ({x:.0}, {y:.0}) px"));
            f.skip(format!(
                "{}: no sphere silhouette where the lidar's sphere is ({where_}){}",
                f.image_path.display(),
                near.map_or(String::new(), |d| format!("; the nearest silhouette is {d:.0} mm from it"))
            ))
        }
        _ => {}
    }
}
