//! Why a candidate was refused: what [`crate::Detector::detect`] found and did not take, by
//! reason, so that a user can tell why an image gave fewer targets than it shows.
//!
//! A candidate is a bright blob seen at two or more rungs of the threshold ladder
//! ([`crate::candidates`]). The reasons, in the order they are tested:
//!
//! - **at the border**: the blob touches the image border, or the window the edge is looked
//!   for in leaves the image.
//! - **not elliptic**: its outline is not an ellipse (its fill or axis ratio, too few edge
//!   points, or edge points that no ellipse fits: partly covered, merged, ragged).
//! - **too small**: an elliptic blob under the smallest diameter measured (5 px).
//! - **text glyph**: a bright blob closed by a dark stroke with paper beyond it, the inside of a
//!   printed letter or digit (o, e, a, 0, 6, 8, 9, …): on the circle of [`GLYPH_RADIUS`] times
//!   its radius, more than half of the image is bright, and there either both the blob and the
//!   paper are saturated (a flat render), or the paper is as bright as the blob (within
//!   [`GLYPH_PAPER`] of the stroke's contrast) and the stroke is ink (at most [`GLYPH_INK`] of
//!   the paper's level) or at least [`GLYPH_STROKE`] radii wide. A printed target has a dark surround out to 2 dot radii at least (the black square
//!   of a plain target, the gap of a coded one); a retro-reflective target in a flash's hot
//!   spot, whose thin black rim has bright carbon beyond it, has a narrower and greyer rim. Coded
//!   targets (a ring seen) are never glyphs.
//! - **saturated**: more than a fifth of the samples inside the blob are at the saturation
//!   level (0.995 of full scale): the edge of a clipped profile is biased outward, by an
//!   amount nobody knows. The share is given; the advice is to expose darker (or, for a flat
//!   render of a printed sheet, to ask for saturated targets to be measured: they are then
//!   kept, flagged, with three times their σ).
//! - **low contrast**: the blob is less than 0.03 of full scale brighter than its surround.
//! - **ring unreadable**: a coded target whose ring was seen but whose number was not given:
//!   the ring could not be read (a sector not uniform, too close to the mid level, a pattern
//!   not in the table), or it was read but a margin is under its bound
//!   ([`crate::confidence`]), or its centre's σ is far above the other targets'. The target
//!   itself is kept, as a coded target without a number.
//! - **number read twice**: two targets of the image read the same number; neither keeps it.
//!
//! Blobs inside the code ring of a coded target, or on a target, are pieces of it and are not
//! listed.

use crate::confidence::ReadMargins;
use crate::ellipse::Ellipse;
use serde::Serialize;

/// On the circle of this many radii of a blob, the glyph test looks for bright paper.
pub const GLYPH_RADIUS: f64 = 1.75;
/// The stroke around a glyph's inside is at least this wide, in the inside's radii, measured
/// from its centre (on the real AICON panel, the black rim of a retro-reflective target in a
/// flash's hot spot ends at 1.33 to 1.40; the strokes of printed Helvetica letters and digits
/// end at 1.45 to 1.73 of their insides' radii, 1.58 in the median).
pub const GLYPH_STROKE: f64 = 1.42;
/// Printed ink is at most this fraction of the paper's level (the black rim of a
/// retro-reflective target in a flash's hot spot is 0.2 to 0.27 of its dot's, on the panel).
pub const GLYPH_INK: f32 = 0.12;
/// The glyph test looks for bright paper out to this many radii (a printed plain target's
/// black square reaches 2 radii: the test must stay inside it).
pub const GLYPH_BRIGHT_REACH: f64 = 1.9;
/// The glyph test takes the paper around a glyph from out to this many radii of its inside
/// (a printed plain target's black disc reaches farther, and the test does not get this far
/// for it: its circle at [`GLYPH_RADIUS`] is dark all round).
pub const GLYPH_PAPER_REACH: f64 = 2.25;
/// The paper around a glyph is the paper inside it: their levels differ by at most this
/// fraction of the stroke's contrast.
pub const GLYPH_PAPER: f32 = 0.12;

/// Why a candidate was refused (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RefusalReason {
    /// The blob touches the image border, or the window its edge is looked for in leaves the
    /// image.
    AtBorder,
    /// Its outline is not an ellipse (fill or axis ratio, too few edge points, or edge points
    /// no ellipse fits: partly covered, merged, ragged).
    NotElliptic,
    /// An elliptic blob under the smallest diameter measured, 5 px.
    TooSmall,
    /// The inside of a printed letter or digit (the glyph test of the module doc).
    TextGlyph,
    /// More than a fifth of the samples inside the blob at the saturation level; the share is
    /// in [`Refusal::saturated_share`].
    Saturated,
    /// Less than 0.03 of full scale brighter than its surround.
    LowContrast,
    /// A coded target whose ring was seen but whose number was not given (unreadable, a
    /// margin under its bound, or a σ far above the other targets'); the target is kept
    /// without a number, and a number read and refused is in [`Refusal::refused_read`].
    RingUnreadable,
    /// Two targets of the image read the same number; neither keeps it.
    NumberReadTwice,
}

impl RefusalReason {
    /// Every reason, in the order of the module doc.
    pub const ALL: [RefusalReason; 8] = [
        RefusalReason::AtBorder,
        RefusalReason::NotElliptic,
        RefusalReason::TooSmall,
        RefusalReason::TextGlyph,
        RefusalReason::Saturated,
        RefusalReason::LowContrast,
        RefusalReason::RingUnreadable,
        RefusalReason::NumberReadTwice,
    ];

    /// The reason in words, as the summary and `--why` give it.
    pub fn name(self) -> &'static str {
        match self {
            RefusalReason::AtBorder => "at the border",
            RefusalReason::NotElliptic => "not elliptic",
            RefusalReason::TooSmall => "too small",
            RefusalReason::TextGlyph => "text glyph",
            RefusalReason::Saturated => "saturated",
            RefusalReason::LowContrast => "low contrast",
            RefusalReason::RingUnreadable => "ring unreadable",
            RefusalReason::NumberReadTwice => "number read twice",
        }
    }

    /// The letter that marks it on the debug overlay.
    pub fn letter(self) -> char {
        match self {
            RefusalReason::AtBorder => 'B',
            RefusalReason::NotElliptic => 'E',
            RefusalReason::TooSmall => 'M',
            RefusalReason::TextGlyph => 'T',
            RefusalReason::Saturated => 'S',
            RefusalReason::LowContrast => 'C',
            RefusalReason::RingUnreadable => 'R',
            RefusalReason::NumberReadTwice => 'D',
        }
    }

    /// What the user can do about it.
    pub fn advice(self) -> &'static str {
        match self {
            RefusalReason::AtBorder => "keep the targets inside the frame",
            RefusalReason::NotElliptic => {
                "targets partly covered or merged with their neighbours are not measured"
            }
            RefusalReason::TooSmall => {
                "targets under 5 px across are not measured: come closer or use larger targets"
            }
            RefusalReason::TextGlyph => "the insides of printed letters and digits are not targets",
            RefusalReason::Saturated => {
                "expose darker (or, for a flat render of a printed sheet, measure saturated targets: `pingcal detect --saturated`)"
            }
            RefusalReason::LowContrast => "light the targets better or expose brighter",
            RefusalReason::RingUnreadable => {
                "a wrong number costs more than a missing one: sharper, larger or less tilted targets are read"
            }
            RefusalReason::NumberReadTwice => "each coded number may be printed only once",
        }
    }
}

/// A refused candidate: why, where (its outline: the fitted ellipse where there is one, else
/// the blob's moment ellipse), and the figures of its reason.
#[derive(Clone, Debug, Serialize)]
pub struct Refusal {
    /// Why it was refused.
    pub reason: RefusalReason,
    /// Its outline in the image, px: the fitted ellipse where there is one, else the blob's
    /// moment ellipse.
    pub ellipse: Ellipse,
    /// Saturated: the share of the samples inside the blob at the saturation level.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub saturated_share: Option<f64>,
    /// Ring unreadable: the number that was read and refused, with its margins (none when the
    /// ring could not be read to a number at all).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub refused_read: Option<(u32, ReadMargins)>,
    /// The reason in detail, in words.
    pub detail: String,
}

impl Refusal {
    /// A refusal for `reason` of the blob outlined by `ellipse`, with `detail`.
    pub fn new(reason: RefusalReason, ellipse: Ellipse, detail: impl Into<String>) -> Self {
        Refusal {
            reason,
            ellipse,
            saturated_share: None,
            refused_read: None,
            detail: detail.into(),
        }
    }
}

/// How many refusals of each reason, in the order of [`RefusalReason::ALL`], leaving out the
/// reasons with none.
pub fn counts<'a>(refusals: impl IntoIterator<Item = &'a Refusal>) -> Vec<(RefusalReason, usize)> {
    let mut n = [0usize; RefusalReason::ALL.len()];
    for r in refusals {
        n[r.reason as usize] += 1;
    }
    RefusalReason::ALL
        .iter()
        .zip(n)
        .filter(|(_, c)| *c > 0)
        .map(|(r, c)| (*r, c))
        .collect()
}

/// Why an image gave no target, on one line: the candidates refused by reason, the most
/// frequent first but text glyphs last (they are not targets), with the advice of the first
/// (`every candidate refused: 38 saturated, 96 text glyph (expose darker …)`), or that there
/// was no candidate at all.
pub fn why_nothing(refusals: &[Refusal]) -> String {
    let mut by_reason = counts(refusals);
    by_reason.sort_by_key(|&(r, n)| (r == RefusalReason::TextGlyph, std::cmp::Reverse(n)));
    match by_reason.first() {
        None => {
            "no candidate: no bright blob stands out of its surround at two or more \
                 threshold levels (targets too small, too faint, out of focus, or not in the image)"
                .to_string()
        }
        Some((first, _)) => {
            let list: Vec<String> = by_reason
                .iter()
                .map(|(r, n)| format!("{n} {}", r.name()))
                .collect();
            format!(
                "every candidate refused: {} ({})",
                list.join(", "),
                first.advice()
            )
        }
    }
}
