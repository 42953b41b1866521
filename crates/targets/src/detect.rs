//! The top-level detector: candidates → sub-pixel centres → code rings → kinds and IDs.

use crate::aicon::{read_ring, RingRead, RingReader};
use crate::candidates::{find_candidates, CandidateParams};
use crate::centre::{refine, CentreParams, Refined};
use crate::ellipse::{Ellipse, Frame};
use crate::image_io::{load_image, GrayImage};
use crate::TargetError;
use rayon::prelude::*;
use serde::Serialize;

/// Kind of a detected target.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum TargetKind {
    /// A ring-coded target (`id` is its number when the ring was read).
    Coded,
    /// A plain circular target.
    Plain,
    /// A ping-pong-ball silhouette (its `x`, `y` is the silhouette ellipse's centre, *not yet*
    /// corrected for the sphere's eccentricity: see [`crate::ball`]).
    Ball,
}

/// One detected target. Pixel coordinates: origin at the centre of the top-left pixel, x to the
/// right, y down.
#[derive(Clone, Debug, Serialize)]
pub struct Target {
    pub kind: TargetKind,
    pub id: Option<u32>,
    /// Centre (the edge-ellipse centre).
    pub x: f64,
    pub y: f64,
    /// Estimated σ of the centre, pixels.
    pub sigma_px: f64,
    /// The edge ellipse.
    pub ellipse: Ellipse,
    /// Intensity-weighted centroid and its σ.
    pub centroid: [f64; 2],
    pub sigma_centroid_px: f64,
    /// Foreground − background grey contrast (image in [0, 1]).
    pub contrast: f32,
}

/// How balls are told from targets.
#[derive(Clone, Debug)]
pub enum BallMode {
    /// No balls in these images.
    Off,
    /// A plain blob whose diameter is at least `ratio` × the median diameter of the image's
    /// targets (and at least `min_px`) is a ball (38 mm balls vs ≤ 10 mm targets).
    Auto { ratio: f64, min_px: f64 },
    /// Blobs with diameters in this range (pixels) are balls.
    Diameter { min_px: f64, max_px: f64 },
}

/// Settings of [`detect_image`].
#[derive(Clone, Debug)]
pub struct DetectParams {
    pub candidates: CandidateParams,
    pub centre: CentreParams,
    /// Ring-code bit counts to try (AICON: 14, or 12).
    pub code_bits: Vec<u32>,
    /// The printed code ring, inner and outer radius in dot radii (AICON: 2 and 3).
    pub ring: (f64, f64),
    pub balls: BallMode,
}

impl Default for DetectParams {
    fn default() -> Self {
        DetectParams {
            candidates: CandidateParams::default(),
            centre: CentreParams::default(),
            code_bits: vec![14],
            ring: (2.0, 3.0),
            balls: BallMode::Auto {
                ratio: 2.5,
                min_px: 12.0,
            },
        }
    }
}

/// The detections of one image.
#[derive(Clone, Debug, Serialize)]
pub struct ImageDetections {
    pub width: usize,
    pub height: usize,
    pub targets: Vec<Target>,
}

/// A detector with its code tables built once (reuse it for many images).
#[derive(Clone, Debug)]
pub struct Detector {
    pub params: DetectParams,
    pub readers: Vec<RingReader>,
}

impl Detector {
    /// Builds the detector (code tables) for `params`.
    pub fn new(params: DetectParams) -> Result<Self, TargetError> {
        let readers = params
            .code_bits
            .iter()
            .map(|&b| RingReader::with_ring(b, params.ring.0, params.ring.1))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Detector { params, readers })
    }

    /// Detects targets in an image.
    pub fn detect(&self, img: &GrayImage) -> ImageDetections {
        let p = &self.params;
        let cands = find_candidates(img, &p.candidates);
        let mut refined: Vec<Refined> = cands
            .par_iter()
            .filter_map(|c| refine(img, &c.seed, &p.centre).ok())
            .collect();
        // Different candidates can converge on one target: keep the first of any pair closer
        // than half the smaller radius.
        refined.sort_by(|a, b| {
            (a.ellipse.cy, a.ellipse.cx)
                .partial_cmp(&(b.ellipse.cy, b.ellipse.cx))
                .unwrap_or(std::cmp::Ordering::Equal)
        });
        let mut keep: Vec<Refined> = Vec::with_capacity(refined.len());
        for r in refined {
            let dup = keep.iter().rev().take(64).any(|k| {
                let d = ((k.ellipse.cx - r.ellipse.cx).powi(2)
                    + (k.ellipse.cy - r.ellipse.cy).powi(2))
                .sqrt();
                d < 0.5 * k.ellipse.radius().min(r.ellipse.radius())
            });
            if !dup {
                keep.push(r);
            }
        }
        // Code rings.
        let reads: Vec<(Option<TargetKind>, Option<u32>)> = keep
            .par_iter()
            .map(|r| {
                let mut found: Option<u32> = None;
                let mut ring = false;
                let mut conflict = false;
                for reader in &self.readers {
                    match read_ring(img, &r.ellipse, r.fg, r.bg, reader) {
                        RingRead::Code { id, .. } => {
                            ring = true;
                            if found.is_some_and(|f| f != id) {
                                conflict = true;
                            }
                            found = Some(id);
                        }
                        RingRead::Unreadable { reason } => {
                            if reason != "surround of the ring is not dark" {
                                ring = true;
                            }
                        }
                        RingRead::NoRing => {}
                    }
                }
                if conflict {
                    found = None;
                }
                if ring {
                    (Some(TargetKind::Coded), found)
                } else {
                    (None, None)
                }
            })
            .collect();
        // Blobs inside the ring zone of a coded target are its ring segments: drop them
        // (first around decoded targets, then around the unidentified ones that remain).
        // (The distance test skips the rings further away than 3.6 major semi-axes.)
        let in_ring_of = |r: &Refined, rings: &[(&Ellipse, Frame)]| {
            let (x, y) = (r.ellipse.cx, r.ellipse.cy);
            rings.iter().any(|(c, f)| {
                let reach = 3.6 * c.a;
                if (x - c.cx).abs() >= reach || (y - c.cy).abs() >= reach {
                    return false;
                }
                let (u, v) = f.unmap(x, y);
                let d2 = u * u + v * v;
                d2 > 0.25 && d2 < 3.6 * 3.6
            })
        };
        let decoded: Vec<(&Ellipse, Frame)> = keep
            .iter()
            .zip(&reads)
            .filter(|(_, r)| r.1.is_some())
            .map(|(k, _)| (&k.ellipse, k.ellipse.frame()))
            .collect();
        let survivors: Vec<usize> = (0..keep.len())
            .filter(|&i| reads[i].1.is_some() || !in_ring_of(&keep[i], &decoded))
            .collect();
        let unread: Vec<(&Ellipse, Frame)> = survivors
            .iter()
            .filter(|&&i| reads[i].0 == Some(TargetKind::Coded) && reads[i].1.is_none())
            .map(|&i| (&keep[i].ellipse, keep[i].ellipse.frame()))
            .collect();
        let mut targets = Vec::new();
        for &i in &survivors {
            let (r, (kind, id)) = (&keep[i], &reads[i]);
            if kind.is_none() && in_ring_of(r, &unread) {
                continue;
            }
            targets.push(Target {
                kind: kind.unwrap_or(TargetKind::Plain),
                id: *id,
                x: r.ellipse.cx,
                y: r.ellipse.cy,
                sigma_px: r.sigma_ellipse,
                ellipse: r.ellipse,
                centroid: [r.centroid.0, r.centroid.1],
                sigma_centroid_px: r.sigma_centroid,
                contrast: r.fg - r.bg,
            });
        }
        // Two targets must not carry the same ID: if they do, neither keeps it.
        let mut ids: Vec<u32> = targets.iter().filter_map(|t| t.id).collect();
        ids.sort_unstable();
        let dups: Vec<u32> = ids
            .windows(2)
            .filter(|w| w[0] == w[1])
            .map(|w| w[0])
            .collect();
        for t in &mut targets {
            if t.id.is_some_and(|i| dups.contains(&i)) {
                t.id = None;
            }
        }
        classify_balls(&mut targets, &p.balls);
        targets.sort_by(|a, b| {
            let ka = (
                a.kind != TargetKind::Coded,
                a.id.is_none(),
                a.id,
                a.kind as u8,
            );
            let kb = (
                b.kind != TargetKind::Coded,
                b.id.is_none(),
                b.id,
                b.kind as u8,
            );
            ka.cmp(&kb).then(
                (a.y, a.x)
                    .partial_cmp(&(b.y, b.x))
                    .unwrap_or(std::cmp::Ordering::Equal),
            )
        });
        ImageDetections {
            width: img.width,
            height: img.height,
            targets,
        }
    }
}

fn classify_balls(targets: &mut [Target], mode: &BallMode) {
    let (lo, hi) = match *mode {
        BallMode::Off => return,
        BallMode::Diameter { min_px, max_px } => (min_px, max_px),
        BallMode::Auto { ratio, min_px } => {
            let mut d: Vec<f64> = targets.iter().map(|t| 2.0 * t.ellipse.radius()).collect();
            if d.len() < 3 {
                return;
            }
            d.sort_by(|a, b| a.total_cmp(b));
            let med = d[d.len() / 2];
            ((ratio * med).max(min_px), f64::INFINITY)
        }
    };
    for t in targets.iter_mut() {
        let d = 2.0 * t.ellipse.radius();
        if t.kind == TargetKind::Plain && d >= lo && d <= hi {
            t.kind = TargetKind::Ball;
        }
    }
}

/// Detects targets in an image with the given settings.
pub fn detect_image(
    img: &GrayImage,
    params: &DetectParams,
) -> Result<ImageDetections, TargetError> {
    Ok(Detector::new(params.clone())?.detect(img))
}

/// Loads and detects one image file.
pub fn detect_file(
    path: &std::path::Path,
    detector: &Detector,
) -> Result<ImageDetections, TargetError> {
    let img = load_image(path)?;
    Ok(detector.detect(&img))
}

/// Loads and detects many image files, in parallel over the images as well as within each one
/// (rayon's current pool: `RAYON_NUM_THREADS`, or the caller's `ThreadPool::install`), so that
/// the decoding of one image — single-threaded inside the decoders — overlaps with the
/// detection in others. The results are in the order of `paths`, each the same as
/// [`detect_file`]'s.
pub fn detect_files<P: AsRef<std::path::Path> + Sync>(
    paths: &[P],
    detector: &Detector,
) -> Vec<Result<ImageDetections, TargetError>> {
    paths
        .par_iter()
        .with_max_len(1)
        .map(|p| detect_file(p.as_ref(), detector))
        .collect()
}
