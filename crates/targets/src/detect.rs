//! The top-level detector: candidates → sub-pixel centres → code rings → kinds and IDs, and
//! the candidates refused, each with its reason ([`crate::refusal`]).

use crate::aicon::{read_ring, RingRead, RingReader};
use crate::candidates::{find_candidates_and_refusals, BlobRefusal, CandidateParams, RefusedBlob};
use crate::centre::{refine, CentreParams, Refined, Reject};
use crate::confidence::ReadMargins;
use crate::ellipse::{Ellipse, Frame};
use crate::image_io::{load_image, GrayImage};
use crate::refusal::{Refusal, RefusalReason, GLYPH_INK, GLYPH_PAPER, GLYPH_RADIUS, GLYPH_STROKE};
use crate::refusal::{GLYPH_BRIGHT_REACH, GLYPH_PAPER_REACH};
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
    /// Coded, plain or ball.
    pub kind: TargetKind,
    /// The coded target's number (1-based, as printed), when its ring was read and trusted.
    pub id: Option<u32>,
    /// Centre, x (the edge-ellipse centre), pixels.
    pub x: f64,
    /// Centre, y (the edge-ellipse centre), pixels.
    pub y: f64,
    /// Estimated σ of the centre, pixels (three times the edge fit's for a saturated target).
    pub sigma_px: f64,
    /// The edge ellipse.
    pub ellipse: Ellipse,
    /// Intensity-weighted centroid (x, y), pixels: a second centre estimate beside the edge
    /// ellipse's.
    pub centroid: [f64; 2],
    /// Estimated σ of the centroid, pixels.
    pub sigma_centroid_px: f64,
    /// Foreground − background grey contrast (image in [0, 1]).
    pub contrast: f32,
    /// The margins of the read that gave `id` ([`crate::confidence`]).
    pub read: Option<ReadMargins>,
    /// Measured although saturated (only when [`DetectParams::measure_saturated`] asks): its
    /// σ is tripled.
    pub saturated: bool,
}

/// How balls are told from targets.
#[derive(Clone, Debug)]
pub enum BallMode {
    /// No balls in these images.
    Off,
    /// A plain blob whose diameter is at least `ratio` × the median diameter of the image's
    /// targets (and at least `min_px`) is a ball (38 mm balls vs ≤ 10 mm targets).
    Auto {
        /// Smallest ball diameter over the median target diameter.
        ratio: f64,
        /// Smallest ball diameter, pixels.
        min_px: f64,
    },
    /// Blobs with diameters in this range (pixels) are balls.
    Diameter {
        /// Smallest ball diameter, pixels.
        min_px: f64,
        /// Largest ball diameter, pixels.
        max_px: f64,
    },
}

/// Settings of [`detect_image`].
#[derive(Clone, Debug)]
pub struct DetectParams {
    /// How blobs become candidates (thresholds, sizes, shapes).
    pub candidates: CandidateParams,
    /// How a candidate's centre is measured (edge ellipse, saturation limit).
    pub centre: CentreParams,
    /// Ring-code bit counts to try (AICON: 14, or 12).
    pub code_bits: Vec<u32>,
    /// The printed code ring, inner and outer radius in dot radii (AICON: 2 and 3).
    pub ring: (f64, f64),
    /// How balls are told from targets.
    pub balls: BallMode,
    /// Measure targets with more than `centre.max_saturated_fraction` of their samples
    /// saturated instead of refusing them: they are flagged ([`Target::saturated`]) and their
    /// σ is tripled (a ninth of the weight), as their edges may be biased outward.
    pub measure_saturated: bool,
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
            measure_saturated: false,
        }
    }
}

/// The detections of one image.
#[derive(Clone, Debug, Serialize)]
pub struct ImageDetections {
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// The targets (and balls) found, in position order.
    pub targets: Vec<Target>,
    /// The candidates refused, with their reasons ([`crate::refusal`]), in position order.
    pub refused: Vec<Refusal>,
}

/// A detector with its code tables built once (reuse it for many images).
#[derive(Clone, Debug)]
pub struct Detector {
    /// The settings it detects with.
    pub params: DetectParams,
    /// One ring reader per code bit count of `params.code_bits`, tables built.
    pub readers: Vec<RingReader>,
}

/// The σ of a saturated target measured on request is its fit's times this.
pub const SATURATED_SIGMA_FACTOR: f64 = 3.0;

/// A coded read whose centre σ is more than this many times the median σ of the image's
/// coded reads (and over [`SIGMA_FLOOR_PX`]) is refused: its dot is not the clean ellipse
/// the others are (partly covered, merged with something), so its ring is doubted too.
pub const SIGMA_RATIO_MAX: f64 = 5.0;
/// Centre σ under which no read is refused for its σ (pixels).
pub const SIGMA_FLOOR_PX: f64 = 0.05;

/// A measured candidate: its refinement and its share of saturated samples.
struct Measured {
    r: Refined,
    saturated: f64,
}

/// What the code rings said of a measured candidate: its kind (coded when a ring was seen),
/// the number given and its margins, or the refusal of the number.
struct RingOutcome {
    coded: bool,
    id: Option<u32>,
    margins: Option<ReadMargins>,
    refusal: Option<Refusal>,
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
        let (cands, blobs) = find_candidates_and_refusals(img, &p.candidates, true);
        let mut refused: Vec<Refusal> = blobs.iter().map(|b| self.blob_refusal(img, b)).collect();
        let measured: Vec<Result<Measured, Box<Refusal>>> = cands
            .par_iter()
            .map(|c| self.measure(img, &c.seed))
            .collect();
        let mut ok: Vec<Measured> = Vec::with_capacity(measured.len());
        for m in measured {
            match m {
                Ok(m) => ok.push(m),
                Err(r) => refused.push(*r),
            }
        }
        let keep = without_duplicates(ok, p.centre.max_saturated_fraction);
        let rings: Vec<RingOutcome> = keep.par_iter().map(|m| self.read_rings(img, m)).collect();
        let (mut targets, saturated_rings) = self.targets_of(img, &keep, rings, &mut refused);
        refuse_doubtful_sigma(&mut targets, &mut refused);
        refuse_overlapping_rings(&mut targets, &mut refused, p.ring.1);
        refuse_numbers_read_twice(&mut targets, &mut refused);
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
        let refused = without_pieces(refused, &targets, &saturated_rings);
        ImageDetections {
            width: img.width,
            height: img.height,
            targets,
            refused,
        }
    }

    /// The refusal of a blob that failed the shape tests (a text glyph when it is one).
    fn blob_refusal(&self, img: &GrayImage, b: &RefusedBlob) -> Refusal {
        let (reason, detail) = match b.why {
            BlobRefusal::AtBorder => (RefusalReason::AtBorder, "touches the image border"),
            BlobRefusal::TooSmall => (RefusalReason::TooSmall, "under the smallest diameter"),
            BlobRefusal::NotElliptic => (
                RefusalReason::NotElliptic,
                "its fill or axis ratio is not an ellipse's",
            ),
        };
        // the blob's level: the median of its centre and four points 0.4 radii out
        let p = &self.params.centre;
        let fr = b.seed.frame();
        let mut v = [(0.0, 0.0), (0.4, 0.0), (-0.4, 0.0), (0.0, 0.4), (0.0, -0.4)].map(|(u, w)| {
            let (x, y) = fr.map(u, w);
            img.sample(x, y)
        });
        v.sort_by(|a, b| a.total_cmp(b));
        let saturated = v.iter().filter(|&&x| x >= p.saturation).count() as f64 / 5.0;
        if reason != RefusalReason::AtBorder
            && self.is_glyph(img, &b.seed, v[2], saturated > p.max_saturated_fraction)
        {
            return glyph_refusal(b.seed);
        }
        Refusal::new(
            reason,
            b.seed,
            format!("{detail} ({:.1} px across)", 2.0 * b.seed.radius()),
        )
    }

    /// Whether the blob outlined by `seed` is the inside of a printed glyph (see
    /// [`crate::refusal`]): on the circle of [`GLYPH_RADIUS`] radii, more than half the samples
    /// (a quarter or more when the stroke is ink) are at least half way from the darkest sample of the
    /// circle at 1.3 radii (the stroke) to the blob's middle; and either the blob is
    /// `saturated` (in a flat render the paper and the inside of the letters both are), or the
    /// paper (the upper eighth of the bright samples, each ray's brightest out to
    /// [`GLYPH_PAPER_REACH`] radii) is the blob's own level to within [`GLYPH_PAPER`] of the stroke's
    /// contrast (the paper around a letter is the paper inside it) and the stroke is ink, as
    /// dark as [`GLYPH_INK`] of the paper or darker, or (with more than half the circle bright)
    /// at least [`GLYPH_STROKE`] radii wide (the median over 32 rays of where the profile
    /// climbs back to the half-way level).
    fn is_glyph(&self, img: &GrayImage, seed: &Ellipse, fg: f32, saturated: bool) -> bool {
        const K: usize = 32;
        let outer = seed.scaled(GLYPH_PAPER_REACH + 0.1);
        if !img.inside(outer.cx - outer.a, outer.cy - outer.a, 1.0)
            || !img.inside(outer.cx + outer.a, outer.cy + outer.a, 1.0)
        {
            return false;
        }
        let fr = seed.frame();
        let trig = crate::ellipse::unit_circle(K);
        let at = |rho: f64, (c, s): (f64, f64)| {
            let (x, y) = fr.map(rho * c, rho * s);
            img.sample_inside(x, y)
        };
        let stroke = trig.iter().fold(f32::INFINITY, |m, &t| m.min(at(1.3, t)));
        if !(fg - stroke > self.params.centre.min_contrast) {
            return false;
        }
        let level = stroke + 0.5 * (fg - stroke);
        // each ray's brighter sample of the two at GLYPH_RADIUS and GLYPH_BRIGHT_REACH radii: a
        // circle at one radius may run along the anti-aliased outer edge of a thin stroke (a
        // digit's bowl at 150 dpi)
        let mut v = [0.0f32; K];
        for (vk, &t) in v.iter_mut().zip(trig.iter()) {
            *vk = at(GLYPH_RADIUS, t).max(at(GLYPH_BRIGHT_REACH, t));
        }
        // A letter's stem or tail beside its bowl ('b', 'g', 'e' at 300 dpi) hides up to
        // three quarters of the circle: with an ink stroke, a quarter of it bright will do.
        let bright = v.iter().filter(|&&x| x >= level).count();
        let ink = stroke <= GLYPH_INK * fg;
        if bright * 2 <= K && !(ink && bright * 4 >= K) {
            return false;
        }
        if saturated {
            return true;
        }
        // the paper: the upper eighth of the bright samples, each ray's brightest out to
        // GLYPH_PAPER_REACH radii (the circle at GLYPH_RADIUS crosses the anti-aliased edges
        // of the neighbouring letters, and of a narrow counter's own stroke: a '0' whose
        // inside is twice as tall as wide)
        let mut w = v;
        for (wk, &t) in w.iter_mut().zip(trig.iter()) {
            for rho in [GLYPH_RADIUS + 0.25, GLYPH_PAPER_REACH] {
                *wk = wk.max(at(rho, t));
            }
        }
        v.sort_by(|a, b| a.total_cmp(b));
        w.sort_by(|a, b| a.total_cmp(b));
        let paper = w[K - 1 - bright / 8];
        if (paper - fg).abs() > GLYPH_PAPER * (fg - stroke) {
            return false;
        }
        if ink {
            return true;
        }
        if bright * 2 <= K {
            return false;
        }
        // where the stroke ends on each ray, in steps of 0.025 radii from 1.15 out
        let mut ends = [f64::INFINITY; K];
        for (e, &t) in ends.iter_mut().zip(trig.iter()) {
            *e = (0..=24)
                .map(|i| 1.15 + 0.025 * i as f64)
                .find(|&r| at(r, t) >= level)
                .unwrap_or(f64::INFINITY);
        }
        ends.sort_by(|a, b| a.total_cmp(b));
        ends[K / 2] >= GLYPH_STROKE
    }

    /// The sub-pixel measurement of a candidate, or why it was refused. Saturated candidates
    /// are measured too (the caller refuses them, after their rings have told where their
    /// pieces are, unless asked to keep them).
    fn measure(&self, img: &GrayImage, seed: &Ellipse) -> Result<Measured, Box<Refusal>> {
        let p = &self.params;
        let centre = CentreParams {
            max_saturated_fraction: 1.0,
            ..p.centre.clone()
        };
        match refine(img, seed, &centre) {
            Ok(r) => Ok(Measured {
                saturated: r.saturated,
                r,
            }),
            Err(e) => {
                let (reason, detail) = match e {
                    Reject::Saturated => (RefusalReason::Saturated, "saturated"),
                    Reject::Clipped => (
                        RefusalReason::AtBorder,
                        "the window its edge is looked for in leaves the image",
                    ),
                    Reject::LowContrast => (
                        RefusalReason::LowContrast,
                        "less than the smallest contrast brighter than its surround",
                    ),
                    Reject::FewEdges => (RefusalReason::NotElliptic, "too few edge points"),
                    Reject::BadFit => (
                        RefusalReason::NotElliptic,
                        "its edge points do not fit an ellipse",
                    ),
                };
                Err(Box::new(Refusal::new(reason, *seed, detail)))
            }
        }
    }

    /// Reads the code rings of a measured candidate with every reader.
    fn read_rings(&self, img: &GrayImage, m: &Measured) -> RingOutcome {
        let r = &m.r;
        let mut out = RingOutcome {
            coded: false,
            id: None,
            margins: None,
            refusal: None,
        };
        let mut conflict = false;
        for reader in &self.readers {
            match read_ring(img, &r.ellipse, r.fg, r.bg, reader) {
                RingRead::Code { id, margins, .. } => {
                    out.coded = true;
                    if out.id.is_some_and(|f| f != id) {
                        conflict = true;
                    }
                    out.id = Some(id);
                    out.margins = Some(margins);
                }
                RingRead::Doubtful { id, margins, .. } => {
                    out.coded = true;
                    let mut refusal = Refusal::new(
                        RefusalReason::RingUnreadable,
                        r.ellipse,
                        format!(
                            "read as {id} but refused: confidence {:.2} (sector {:.2}, code {:.2}, levels {:.3}, ring fit {:.3} dot radii, outline {:.3})",
                            margins.confidence, margins.sector, margins.code, margins.levels, margins.ring_fit, margins.outline
                        ),
                    );
                    refusal.refused_read = Some((id, margins));
                    out.refusal.get_or_insert(refusal);
                }
                RingRead::Unreadable { reason } => {
                    if reason != "surround of the ring is not dark" {
                        out.coded = true;
                        out.refusal.get_or_insert(Refusal::new(
                            RefusalReason::RingUnreadable,
                            r.ellipse,
                            reason,
                        ));
                    }
                }
                RingRead::NoRing => {}
            }
        }
        if conflict {
            out.refusal = Some(Refusal::new(
                RefusalReason::RingUnreadable,
                r.ellipse,
                "the readers of two bit counts read different numbers",
            ));
            (out.id, out.margins) = (None, None);
        }
        if out.id.is_some() {
            out.refusal = None;
        }
        out
    }

    /// The targets of the measured candidates: the pieces of code rings dropped (blobs inside
    /// the ring zone of a coded target, first around decoded targets, then around the
    /// unidentified ones that remain; the distance test skips rings further away than 3.6 major
    /// semi-axes), text glyphs and saturated ones (unless asked to measure them) moved to
    /// `refused`. Returns
    /// the targets and the outlines of the saturated coded targets refused.
    fn targets_of(
        &self,
        img: &GrayImage,
        keep: &[Measured],
        rings: Vec<RingOutcome>,
        refused: &mut Vec<Refusal>,
    ) -> (Vec<Target>, Vec<Ellipse>) {
        let p = &self.params;
        let frames = |f: &dyn Fn(usize) -> bool| -> Vec<(Ellipse, Frame)> {
            (0..keep.len())
                .filter(|&i| f(i))
                .map(|i| (keep[i].r.ellipse, keep[i].r.ellipse.frame()))
                .collect()
        };
        let decoded = frames(&|i| rings[i].id.is_some());
        let survivors: Vec<usize> = (0..keep.len())
            .filter(|&i| rings[i].id.is_some() || !in_ring_of(&keep[i].r.ellipse, &decoded))
            .collect();
        let unread = frames(&|i| survivors.contains(&i) && rings[i].coded && rings[i].id.is_none());
        let (mut targets, mut saturated_rings) = (Vec::new(), Vec::new());
        for (i, ring) in rings.into_iter().enumerate() {
            let (m, r) = (&keep[i], &keep[i].r);
            if !survivors.contains(&i) || (!ring.coded && in_ring_of(&r.ellipse, &unread)) {
                continue;
            }
            let saturated = m.saturated > p.centre.max_saturated_fraction;
            if !ring.coded && self.is_glyph(img, &r.ellipse, r.fg, saturated) {
                refused.push(glyph_refusal(r.ellipse));
                continue;
            }
            if saturated && !p.measure_saturated {
                let mut s = Refusal::new(
                    RefusalReason::Saturated,
                    r.ellipse,
                    format!(
                        "{:.0} % of its samples are saturated ({}): expose darker",
                        100.0 * m.saturated,
                        match (ring.coded, ring.id) {
                            (true, Some(id)) => format!("a coded target, its ring reads {id}"),
                            (true, None) => "a coded target".into(),
                            (false, _) => "a plain target".into(),
                        }
                    ),
                );
                s.saturated_share = Some(m.saturated);
                refused.push(s);
                if ring.coded {
                    saturated_rings.push(r.ellipse);
                }
                continue;
            }
            refused.extend(ring.refusal);
            let factor = if saturated {
                SATURATED_SIGMA_FACTOR
            } else {
                1.0
            };
            targets.push(Target {
                kind: if ring.coded {
                    TargetKind::Coded
                } else {
                    TargetKind::Plain
                },
                id: ring.id,
                x: r.ellipse.cx,
                y: r.ellipse.cy,
                sigma_px: factor * r.sigma_ellipse,
                ellipse: r.ellipse,
                centroid: [r.centroid.0, r.centroid.1],
                sigma_centroid_px: factor * r.sigma_centroid,
                contrast: r.fg - r.bg,
                read: ring.margins,
                saturated,
            });
        }
        (targets, saturated_rings)
    }
}

/// The refusal of a text glyph outlined by `e`.
fn glyph_refusal(e: Ellipse) -> Refusal {
    Refusal::new(
        RefusalReason::TextGlyph,
        e,
        format!(
            "bright paper beyond a thin dark stroke ({:.1} px across)",
            2.0 * e.radius()
        ),
    )
}

/// Whether the centre of `e` lies in the ring zone of one of `rings` (between 0.5 and 3.6 of
/// its radii in its unit frame).
fn in_ring_of(e: &Ellipse, rings: &[(Ellipse, Frame)]) -> bool {
    let (x, y) = (e.cx, e.cy);
    rings.iter().any(|(c, f)| {
        let reach = 3.6 * c.a;
        if (x - c.cx).abs() >= reach || (y - c.cy).abs() >= reach {
            return false;
        }
        let (u, v) = f.unmap(x, y);
        let d2 = u * u + v * v;
        d2 > 0.25 && d2 < 3.6 * 3.6
    })
}

/// Different candidates can converge on one target: keep the first (in position order) of any
/// pair closer than half the smaller radius. The candidates with more than `max_saturated` of
/// their samples saturated come after all the others (a target's clean measurement is never
/// displaced by a saturated one of it), then all are put in position order.
fn without_duplicates(measured: Vec<Measured>, max_saturated: f64) -> Vec<Measured> {
    let by_position = |a: &Measured, b: &Measured| {
        (a.r.ellipse.cy, a.r.ellipse.cx)
            .partial_cmp(&(b.r.ellipse.cy, b.r.ellipse.cx))
            .unwrap_or(std::cmp::Ordering::Equal)
    };
    let close = |k: &Ellipse, r: &Ellipse| {
        let d = ((k.cx - r.cx).powi(2) + (k.cy - r.cy).powi(2)).sqrt();
        d < 0.5 * k.radius().min(r.radius())
    };
    let (mut clean, mut saturated): (Vec<Measured>, Vec<Measured>) = measured
        .into_iter()
        .partition(|m| m.saturated <= max_saturated);
    clean.sort_by(by_position);
    saturated.sort_by(by_position);
    let mut keep: Vec<Measured> = Vec::with_capacity(clean.len() + saturated.len());
    for m in clean {
        let r = &m.r.ellipse;
        if !keep.iter().rev().take(64).any(|k| close(&k.r.ellipse, r)) {
            keep.push(m);
        }
    }
    // the saturated ones against every kept one: the clean ones are not in their order
    let n_clean = keep.len();
    let reach = |k: &Ellipse, r: &Ellipse| (k.cy - r.cy).abs() < k.a.max(r.a);
    for m in saturated {
        let r = &m.r.ellipse;
        let dup = keep[..n_clean]
            .iter()
            .chain(keep[n_clean..].iter().rev().take(64))
            .any(|k| reach(&k.r.ellipse, r) && close(&k.r.ellipse, r));
        if !dup {
            keep.push(m);
        }
    }
    keep.sort_by(by_position);
    keep
}

/// Coded reads whose centre σ is over [`SIGMA_RATIO_MAX`] times the median of the image's
/// coded reads (and over [`SIGMA_FLOOR_PX`]) lose their number, with a refusal.
fn refuse_doubtful_sigma(targets: &mut [Target], refused: &mut Vec<Refusal>) {
    let mut s: Vec<f64> = targets
        .iter()
        .filter(|t| t.id.is_some())
        .map(|t| t.sigma_px)
        .collect();
    if s.len() < 3 {
        return;
    }
    s.sort_by(|a, b| a.total_cmp(b));
    let median = s[s.len() / 2];
    for t in targets.iter_mut().filter(|t| t.id.is_some()) {
        if t.sigma_px > SIGMA_FLOOR_PX && t.sigma_px > SIGMA_RATIO_MAX * median {
            let mut r = Refusal::new(
                RefusalReason::RingUnreadable,
                t.ellipse,
                format!(
                    "read as {} but refused: centre σ {:.3} px, {:.0} times the image's median {:.3} px",
                    t.id.unwrap_or(0),
                    t.sigma_px,
                    t.sigma_px / median,
                    median
                ),
            );
            r.refused_read = t.id.zip(t.read);
            refused.push(r);
            (t.id, t.read) = (None, None);
        }
    }
}

/// Two code rings overlap when `outer / D_a + outer / D_b` exceeds this (see
/// `refuse_overlapping_rings`): the real panel's closest pairs, printed with their rings
/// nearly touching, reach 1.015 in perspective.
pub const RING_OVERLAP_MAX: f64 = 1.05;

/// Coded reads whose ring overlaps the ring of another read ring (a number given, or read and
/// refused) lose their number, with a refusal: one target lies over the other (two printed
/// targets overlapping), and the one beneath can show another number's pattern, clean to every
/// margin. With D_a the other centre's distance in this dot's unit frame and D_b this centre's
/// in the other's, the other dot's radius is about D_a / D_b of this one's, and the rings'
/// outer circles (`outer` dot radii each) meet when outer / D_a + outer / D_b > 1; a read is
/// refused over [`RING_OVERLAP_MAX`]. Both of the pair are refused (which one is on top is not
/// known).
fn refuse_overlapping_rings(targets: &mut [Target], refused: &mut Vec<Refusal>, outer: f64) {
    let rings: Vec<Ellipse> = targets
        .iter()
        .filter(|t| t.id.is_some())
        .map(|t| t.ellipse)
        .chain(
            refused
                .iter()
                .filter(|r| r.refused_read.is_some())
                .map(|r| r.ellipse),
        )
        .collect();
    for t in targets.iter_mut().filter(|t| t.id.is_some()) {
        let fr = t.ellipse.frame();
        let reach = 8.0 * outer * t.ellipse.a;
        let worst = rings
            .iter()
            .filter(|e| (e.cx - t.x).abs() < reach && (e.cy - t.y).abs() < reach)
            .filter(|e| (e.cx - t.x).hypot(e.cy - t.y) > 0.5 * t.ellipse.b.min(e.b))
            .map(|e| {
                let (u, v) = fr.unmap(e.cx, e.cy);
                let (p, q) = e.frame().unmap(t.x, t.y);
                (outer / u.hypot(v) + outer / p.hypot(q), e)
            })
            .fold(None::<(f64, &Ellipse)>, |b, c| match b {
                Some(b) if b.0 >= c.0 => Some(b),
                _ => Some(c),
            });
        if let Some((s, e)) = worst.filter(|w| w.0 > RING_OVERLAP_MAX) {
            let mut r = Refusal::new(
                RefusalReason::RingUnreadable,
                t.ellipse,
                format!(
                    "read as {} but refused: its ring overlaps the ring of the target at ({:.1}, {:.1}) (overlap {s:.2} > {RING_OVERLAP_MAX}): one covers the other",
                    t.id.unwrap_or(0),
                    e.cx,
                    e.cy
                ),
            );
            r.refused_read = t.id.zip(t.read);
            refused.push(r);
            (t.id, t.read) = (None, None);
        }
    }
}

/// Two targets must not carry the same number: if they do, neither keeps it.
fn refuse_numbers_read_twice(targets: &mut [Target], refused: &mut Vec<Refusal>) {
    let mut ids: Vec<u32> = targets.iter().filter_map(|t| t.id).collect();
    ids.sort_unstable();
    let dups: Vec<u32> = ids
        .windows(2)
        .filter(|w| w[0] == w[1])
        .map(|w| w[0])
        .collect();
    for t in targets.iter_mut() {
        if let Some(id) = t.id.filter(|i| dups.contains(i)) {
            let mut r = Refusal::new(
                RefusalReason::NumberReadTwice,
                t.ellipse,
                format!("{id} is read at two or more targets of the image"),
            );
            r.refused_read = t.id.zip(t.read);
            refused.push(r);
            (t.id, t.read) = (None, None);
        }
    }
}

/// The refusals that are not pieces of a target: a refusal of the blob itself on a target
/// (within 1.5 of its radii), or any in the ring zone of a coded target or of a saturated coded
/// target refused (`saturated_rings`), is a piece of it; of refusals at one spot (within half
/// the smaller radius), the first is kept. Sorted by position.
fn without_pieces(
    refused: Vec<Refusal>,
    targets: &[Target],
    saturated_rings: &[Ellipse],
) -> Vec<Refusal> {
    let coded: Vec<(Ellipse, Frame)> = targets
        .iter()
        .filter(|t| t.kind == TargetKind::Coded)
        .map(|t| t.ellipse)
        .chain(saturated_rings.iter().copied())
        .map(|e| (e, e.frame()))
        .collect();
    let frames: Vec<(Ellipse, Frame)> = targets
        .iter()
        .map(|t| (t.ellipse, t.ellipse.frame()))
        .collect();
    let on_target = |e: &Ellipse| {
        frames.iter().any(|(t, f)| {
            let reach = 1.5 * t.a;
            if (e.cx - t.cx).abs() >= reach || (e.cy - t.cy).abs() >= reach {
                return false;
            }
            let (u, v) = f.unmap(e.cx, e.cy);
            u * u + v * v < 1.5 * 1.5
        })
    };
    let of_the_target_itself = |r: &Refusal| {
        matches!(
            r.reason,
            RefusalReason::RingUnreadable | RefusalReason::NumberReadTwice
        )
    };
    let mut kept: Vec<Refusal> = refused
        .into_iter()
        .filter(|r| {
            let piece = if of_the_target_itself(r) {
                false
            } else {
                on_target(&r.ellipse) || in_ring_of(&r.ellipse, &coded)
            };
            !piece
        })
        .collect();
    kept.sort_by(|a, b| {
        (a.ellipse.cy, a.ellipse.cx)
            .partial_cmp(&(b.ellipse.cy, b.ellipse.cx))
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    let mut out: Vec<Refusal> = Vec::with_capacity(kept.len());
    for r in kept {
        let e = &r.ellipse;
        let dup = out.iter().rev().take(64).any(|k| {
            let k = &k.ellipse;
            (k.cx - e.cx).hypot(k.cy - e.cy) < 0.5 * k.radius().min(e.radius())
        });
        if !dup {
            out.push(r);
        }
    }
    out
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

#[cfg(test)]
mod tests {
    use super::*;

    fn coded(x: f64, id: u32, sigma_px: f64) -> Target {
        Target {
            kind: TargetKind::Coded,
            id: Some(id),
            x,
            y: 50.0,
            sigma_px,
            ellipse: Ellipse::circle(x, 50.0, 4.0),
            centroid: [x, 50.0],
            sigma_centroid_px: sigma_px,
            contrast: 0.5,
            read: None,
            saturated: false,
        }
    }

    /// The false read of issue 38: a number whose centre σ (0.078 px) is ten times the
    /// image's others' loses it, with a refusal that names it; a σ under the floor never does.
    #[test]
    fn a_read_with_a_centre_sigma_far_above_the_others_is_refused() {
        let mut targets: Vec<Target> = (0..6).map(|k| coded(20.0 * k as f64, k, 0.008)).collect();
        targets.push(coded(200.0, 40, 0.078));
        targets.push(coded(220.0, 41, 0.039));
        let mut refused = Vec::new();
        refuse_doubtful_sigma(&mut targets, &mut refused);
        let ids: Vec<Option<u32>> = targets.iter().map(|t| t.id).collect();
        assert_eq!(ids[6], None, "0.078 px, 9.75 times the median");
        assert_eq!(ids[7], Some(41), "0.039 px is under the 0.05 px floor");
        assert!(ids[..6].iter().all(Option::is_some));
        assert_eq!(refused.len(), 1);
        assert_eq!(refused[0].reason, RefusalReason::RingUnreadable);
        assert!(
            refused[0].detail.starts_with("read as 40 but refused"),
            "{}",
            refused[0].detail
        );
    }

    /// Two reads whose rings overlap (dots 5.5 radii apart: 3/5.5 + 3/5.5 = 1.09) both lose
    /// their number; dots 7 radii apart (0.86: the rings 1 dot radius apart) keep theirs, and so
    /// does a read beside a plain dot (no ring); a ring read and refused counts as a ring.
    #[test]
    fn reads_whose_rings_overlap_are_refused() {
        let mut targets = vec![
            coded(0.0, 1, 0.01),
            coded(22.0, 2, 0.01),
            coded(100.0, 3, 0.01),
            coded(128.0, 4, 0.01),
            coded(200.0, 5, 0.01),
            Target {
                kind: TargetKind::Plain,
                id: None,
                ..coded(216.0, 0, 0.01)
            },
            coded(300.0, 6, 0.01),
        ];
        let mut beside = Refusal::new(
            RefusalReason::RingUnreadable,
            Ellipse::circle(320.0, 50.0, 4.0),
            "read as 9 but refused",
        );
        let margins = ReadMargins {
            method: crate::confidence::ReadMethod::Thresholds,
            sector: 0.1,
            hamming: 2,
            code: 1.0,
            levels: 0.0,
            profile: 0.0,
            surround: 0.0,
            ring_fit: 0.0,
            fragment: 0.0,
            outline: 0.0,
            confidence: 0.5,
        };
        beside.refused_read = Some((9, margins));
        let mut refused = vec![beside];
        refuse_overlapping_rings(&mut targets, &mut refused, 3.0);
        let ids: Vec<Option<u32>> = targets.iter().map(|t| t.id).collect();
        assert_eq!(ids, [None, None, Some(3), Some(4), Some(5), None, None]);
        assert_eq!(refused.len(), 4);
        assert!(
            refused[1].detail.contains("overlaps the ring"),
            "{}",
            refused[1].detail
        );
    }

    /// A number read at two targets of one image is kept by neither.
    #[test]
    fn a_number_read_twice_is_kept_by_neither() {
        let mut targets = vec![
            coded(10.0, 7, 0.01),
            coded(40.0, 7, 0.01),
            coded(70.0, 8, 0.01),
        ];
        let mut refused = Vec::new();
        refuse_numbers_read_twice(&mut targets, &mut refused);
        let ids: Vec<Option<u32>> = targets.iter().map(|t| t.id).collect();
        assert_eq!(ids, [None, None, Some(8)]);
        assert_eq!(refused.len(), 2);
        assert!(refused
            .iter()
            .all(|r| r.reason == RefusalReason::NumberReadTwice));
    }
}
