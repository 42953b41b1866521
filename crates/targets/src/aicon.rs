//! AICON / Schneider ring-coded targets (12 and 14 bit).
//!
//! **Code tables.** Target number k is the k-th (1-based) of the sorted N-bit values v that
//! (a) have an even number of set bits, (b) have at least one pair of opposite sectors
//! (bits i and i + N/2) both set, (c) are the smallest of their cyclic rotations and (d) are
//! not all ones. [`CodeTable::generate`] builds it; for 12 and 14 bits it equals the AICON
//! tables shipped with MicMac (147 and 516 codes; checked in the tests against
//! `shared/data/aicon-panel/aicon-*bit-codes.txt` when present).
//!
//! **Reading.** The central dot's fitted ellipse gives the affine map from the target plane
//! (unit circle = dot outline) to the image. The ring (2.0 to 3.0 dot radii on real AICON
//! targets, measured on the panel photographs) is sampled on 16 angles per sector at five radii
//! between 2.2 and 2.8 dot radii, averaged over the radii. The sector phase is the one that
//! maximises Σ|sector mean − mid level|; each sector is read from its central 60 %. A *bright*
//! sector is a 1, and bit i is sector i in the order of *decreasing* angle in the image (x
//! right, y down: counter-clockwise on screen), least significant bit first
//! ([`RingReader::aicon`] has `clockwise: false`) — this reading was established
//! against the reference IDs of the real panel photographs (it is the one of the four
//! direction × polarity choices under which the decoded IDs agree with the panel's geometry,
//! see `tests/real_panel.rs`). The code is the smallest cyclic rotation; its table index is
//! the number.
//!
//! A dot is taken to have **no ring** when fewer than 5 % of the ring's samples are above the
//! mid level, or none of 4 samples per sector on the middle of the band (2.5 dot radii; the
//! quick test that spares plain targets the full reading).
//!
//! **Refusals.** No ID is given (a wrong ID is far worse than a missing one) when: any sector's
//! mean lies within 25 % of the contrast of the mid level; any central sample of a sector
//! disagrees with the sector; the gap between dot and ring, or the band just outside the ring,
//! is not dark; or the code is not in the table (every single-bit error breaks the parity, so
//! it is refused too).
//!
//! **Through blur.** When the thresholds cannot read a ring that is there (small dots, 3–6 px,
//! blurred by 0.75–2 px: the dot's mid-level edge moves inwards by about σ²/2r, so the ring
//! is sampled too far in, and each sector spreads into its neighbours), the ring is read
//! against a model of its blurred profile: its centre radius is found where it varies most
//! with the angle, each sector's mean is fitted, by least squares over every code of the table
//! at every rotation and neighbour spill ε, as α + β((1 − 2ε)x_k + ε(x_{k−1} + x_{k+1})), and
//! the most likely code is taken only when it fits (β near the dot's contrast, small
//! residual, ε within the model) and every other number fits at least ten times worse. On
//! rendered targets (`tests/synthetic.rs`) this reads 3.5–4 px dots through 1.2 px of blur,
//! where the thresholds read almost none, with no wrong number.

pub mod confidence;

use self::confidence::{ReadMargins, ReadMethod};
use crate::ellipse::Ellipse;
use crate::image_io::GrayImage;

/// Smallest cyclic rotation of an `n`-bit value.
pub fn min_rotation(v: u32, n: u32) -> u32 {
    let mask = if n >= 32 { u32::MAX } else { (1u32 << n) - 1 };
    let v = v & mask;
    let mut best = v;
    let mut r = v;
    for _ in 1..n {
        r = ((r >> 1) | (r << (n - 1))) & mask;
        best = best.min(r);
    }
    best
}

/// The bit order reversed (bit i ↔ bit n−1−i).
pub fn reverse_bits(v: u32, n: u32) -> u32 {
    (0..n).fold(0, |acc, i| acc | (((v >> i) & 1) << (n - 1 - i)))
}

/// The table of ring codes of one bit count: `codes[k-1]` is the code of target number k.
#[derive(Clone, Debug)]
pub struct CodeTable {
    /// Number of ring sectors, one bit each (AICON: 12 or 14).
    pub bits: u32,
    /// The codes, each at its smallest rotation, in increasing order; the code of target
    /// number k (1-based) is at index k − 1.
    pub codes: Vec<u32>,
}

impl CodeTable {
    /// Generates the table for `bits` sectors (even, 4 to 24).
    pub fn generate(bits: u32) -> Result<Self, crate::TargetError> {
        if bits % 2 != 0 || !(4..=24).contains(&bits) {
            return Err(crate::TargetError::Invalid(format!(
                "ring codes need an even bit count from 4 to 24, not {bits}"
            )));
        }
        let half = bits / 2;
        let all = (1u32 << bits) - 1;
        let half_mask = (1u32 << half) - 1;
        let codes = (0..all)
            .filter(|&v| v.count_ones() % 2 == 0)
            .filter(|&v| (v & half_mask) & (v >> half) != 0)
            .filter(|&v| min_rotation(v, bits) == v)
            .collect();
        Ok(CodeTable { bits, codes })
    }

    /// Target number of a code (already at its smallest rotation).
    pub fn id(&self, code: u32) -> Option<u32> {
        self.codes.binary_search(&code).ok().map(|i| i as u32 + 1)
    }

    /// Code of a target number.
    pub fn code(&self, id: u32) -> Option<u32> {
        if id == 0 {
            return None;
        }
        self.codes.get(id as usize - 1).copied()
    }
}

/// How a ring is read.
#[derive(Clone, Debug)]
pub struct RingReader {
    /// The codes a ring may carry, and so the bit count read.
    pub table: CodeTable,
    /// The printed ring, inner and outer radius in dot radii (AICON: 2 and 3).
    pub geometry: (f64, f64),
    /// Ring sampling band, in dot radii: the printed ring less a fifth of its width at each
    /// edge (2.2 to 2.8 for AICON's).
    pub ring: (f64, f64),
    /// The half side of the printed dark square around the ring, in dot radii (AICON's and
    /// `pingcal targets`': 4, for a ring to 3; a third beyond the ring for other rings).
    pub square_half: f64,
    /// True: bright sectors are 1s.
    pub bright_is_one: bool,
    /// True: bit i is the i-th sector in the order of increasing image angle (clockwise on
    /// screen); false: the opposite direction.
    pub clockwise: bool,
    /// Smallest accepted |sector mean − mid| as a fraction of the contrast.
    pub min_margin: f32,
    /// Every code of the table at every rotation and blur spill, as the blurred-ring model
    /// predicts its sectors ([`read_by_model`]); made from the fields above at the first
    /// ring that needs them (few do).
    patterns: std::sync::OnceLock<Patterns>,
}

/// The blurred-ring model's predictions: for every code of the table, rotation and spill ε,
/// the bright sectors x (bit k = sector k in reading order, direction and polarity applied),
/// the number, the code at its smallest rotation, the index of ε and Σ (x̃ − mean)² of the
/// blurred pattern x̃ = M_ε x (M_ε: (1 − 2ε) on the diagonal, ε to each neighbour).
#[derive(Clone, Debug, Default)]
pub(crate) struct Patterns {
    pub(crate) meta: Vec<(u32, u32, u32, usize, f32)>,
}

/// The spills ε of the blurred-ring model (a sector's share of each neighbour).
pub(crate) const SPILLS: [f32; 4] = [0.0, 0.06, 0.12, 0.18];

/// Σ (x̃ − mean)² of the bright sectors `mask` (n of them, bit k = sector k) blurred by the
/// spill `eps`: x̃_k = (1 − 2ε) x_k + ε (x_{k−1} + x_{k+1}).
pub(crate) fn blurred_sxx(mask: u32, n: usize, eps: f32) -> f32 {
    let x = |k: usize| ((mask >> k) & 1) as f32;
    let mut xs = [0.0f32; 32];
    for (k, v) in xs[..n].iter_mut().enumerate() {
        let prev = if k == 0 { n - 1 } else { k - 1 };
        let next = if k + 1 == n { 0 } else { k + 1 };
        *v = x(k) * (1.0 - 2.0 * eps) + eps * (x(prev) + x(next));
    }
    let xs = &xs[..n];
    let mean = xs.iter().sum::<f32>() / n as f32;
    xs.iter().map(|v| (v - mean).powi(2)).sum::<f32>()
}

/// The bright sectors (bit k = sector k in reading order) of `code` (bit i = code bit i).
fn sector_mask(code: u32, n: usize, clockwise: bool, bright_is_one: bool) -> u32 {
    let mut mask = 0u32;
    for k in 0..n {
        let pos = if clockwise { k } else { n - 1 - k };
        if ((code >> pos) & 1 == 1) == bright_is_one {
            mask |= 1 << k;
        }
    }
    mask
}

impl Patterns {
    /// Every code, rotation and ε of the table as the reader reads it.
    fn new(table: &CodeTable, clockwise: bool, bright_is_one: bool) -> Self {
        let n = table.bits as usize;
        let mut p = Patterns {
            meta: Vec::with_capacity(table.codes.len() * n * SPILLS.len()),
        };
        for (i, &c) in table.codes.iter().enumerate() {
            for r in 0..n as u32 {
                let code = ((c << r) | (c >> (n as u32 - r))) & ((1u32 << n) - 1);
                let mask = sector_mask(code, n, clockwise, bright_is_one);
                for (e, eps) in SPILLS.into_iter().enumerate() {
                    p.meta
                        .push((mask, i as u32 + 1, c, e, blurred_sxx(mask, n, eps)));
                }
            }
        }
        p
    }
}

impl RingReader {
    /// The radius (dot radii) of the dark gap between dot and ring where it is tested: 1.6
    /// for AICON's ring from 2.
    pub(crate) fn gap_radius(&self) -> f64 {
        1.0 + 0.6 * (self.geometry.0 - 1.0)
    }

    /// The blurred-ring model's patterns, made at the first call.
    /// The number whose code, at some rotation, has the bright sectors `mask` (bit k = sector
    /// k in reading order), if any.
    pub(crate) fn number_of_mask(&self, mask: u32) -> Option<u32> {
        let n = self.table.bits as usize;
        let mut code = 0u32;
        for k in 0..n {
            let pos = if self.clockwise { k } else { n - 1 - k };
            if ((mask >> k) & 1 == 1) == self.bright_is_one {
                code |= 1 << pos;
            }
        }
        self.table.id(min_rotation(code, n as u32))
    }

    /// The blurred-ring model's patterns, made at the first call.
    pub(crate) fn patterns(&self) -> &Patterns {
        self.patterns
            .get_or_init(|| Patterns::new(&self.table, self.clockwise, self.bright_is_one))
    }

    /// Whether the bright sectors `mask` (bit k = sector k in reading order) are a code of the
    /// table at some rotation.
    fn is_code_mask(&self, mask: u32) -> bool {
        self.number_of_mask(mask).is_some()
    }

    /// The reader for AICON targets with `bits` sectors, with the conventions established on
    /// the real panel.
    pub fn aicon(bits: u32) -> Result<Self, crate::TargetError> {
        Self::with_ring(bits, 2.0, 3.0)
    }

    /// The reader for ring-coded targets like AICON's whose printed ring spans `inner` to
    /// `outer` dot radii (`[targets] ring_inner`, `ring_outer`; 1 < inner < outer).
    pub fn with_ring(bits: u32, inner: f64, outer: f64) -> Result<Self, crate::TargetError> {
        if !(inner > 1.0 && outer > inner && outer < 20.0) {
            return Err(crate::TargetError::Invalid(format!(
                "ring from {inner} to {outer} dot radii: expected 1 < inner < outer < 20"
            )));
        }
        let w = outer - inner;
        Ok(RingReader {
            table: CodeTable::generate(bits)?,
            geometry: (inner, outer),
            ring: (inner + 0.2 * w, outer - 0.2 * w),
            square_half: outer * 4.0 / 3.0,
            bright_is_one: true,
            clockwise: false,
            min_margin: 0.25,
            patterns: std::sync::OnceLock::new(),
        })
    }
}

/// What was read from a ring.
#[derive(Clone, Debug, PartialEq)]
pub enum RingRead {
    /// No code ring around this dot (the band is essentially all dark).
    NoRing,
    /// A ring is there but it could not be read reliably, or the code is not in the table.
    Unreadable {
        /// Why, in words (e.g. "a sector is not uniform", "code not in the table").
        reason: &'static str,
    },
    /// A code read with confidence: the code at its smallest rotation, the number, and the
    /// margins that decided it ([`confidence`]; its confidence is at least 1).
    Code {
        /// The ring's bits ([`RingReader::clockwise`] gives their order), at their smallest
        /// rotation.
        code: u32,
        /// The target number, 1-based ([`CodeTable::id`]).
        id: u32,
        /// How clearly the sectors and the code were read.
        margins: ReadMargins,
    },
    /// A code was read but a margin is under its bound ([`confidence`]): no number is
    /// given; the code, number and margins say what was refused.
    Doubtful {
        /// The ring's bits as read, at their smallest rotation.
        code: u32,
        /// The target number that code would give, 1-based; not given to the target.
        id: u32,
        /// The margins, of which at least one is under its bound.
        margins: ReadMargins,
    },
}

/// A ring read to a number, before its margins are assessed (`confidence::assess`).
#[derive(Clone, Debug)]
pub(crate) struct Reading {
    /// Which reading gave it.
    pub method: ReadMethod,
    /// The code at its smallest rotation, and its number.
    pub code: u32,
    pub id: u32,
    /// The bright sectors of the code read (bit k = sector k in reading order).
    pub mask: u32,
    /// The sector means, brightness − the dot's mid level, sector k in reading order (the
    /// first `n`).
    pub y: [f32; 24],
    /// Where sector 0 starts, in samples of [`SAMPLES_PER_SECTOR`] a sector from angle 0 of
    /// the dot's unit frame.
    pub phi: usize,
    /// The ring's brightness − the dot's mid level at `n` × [`SAMPLES_PER_SECTOR`] angles
    /// from angle 0 of the dot's unit frame (the first `n` × 16), averaged over the band's
    /// radii.
    pub profile: [f32; 24 * SAMPLES_PER_SECTOR],
    /// The ring's radius over the printed ring's (1 for the thresholds' reading; ρ over the
    /// ring's middle radius for the model's).
    pub scale: f64,
}

/// Samples per sector around the ring (both readings).
pub(crate) const SAMPLES_PER_SECTOR: usize = 16;

/// Whether more than the fraction `limit` of `samples_per_turn` angles at unit-frame radius
/// `rho` are brighter than `mid` (the count stops as soon as it exceeds the limit).
fn bright_over(
    img: &GrayImage,
    e: &Ellipse,
    rho: f64,
    mid: f32,
    samples_per_turn: usize,
    limit: f64,
) -> bool {
    let mut c = 0;
    let fr = e.frame();
    for &(co, si) in crate::ellipse::unit_circle(samples_per_turn).iter() {
        let (x, y) = fr.map(rho * co, rho * si);
        if img.sample_inside(x, y) > mid {
            c += 1;
            if c as f64 / samples_per_turn as f64 > limit {
                return true;
            }
        }
    }
    false
}

/// Reads the code ring around a dot whose edge ellipse is `dot`, inner (dot) level `fg` and
/// dark surround `bg`: by sector thresholds first, and by the blurred-ring model
/// (`read_by_model`, see the module doc) when the thresholds cannot read a ring that is there;
/// then the margins of the read ([`confidence`]) decide whether its number is given
/// ([`RingRead::Code`]) or refused ([`RingRead::Doubtful`]).
pub fn read_ring(
    img: &GrayImage,
    dot: &Ellipse,
    fg: f32,
    bg: f32,
    reader: &RingReader,
) -> RingRead {
    let reading = match read_by_thresholds(img, dot, fg, bg, reader) {
        Ok(r) => r,
        Err(RingRead::Unreadable { reason }) => match read_by_model(img, dot, fg, bg, reader) {
            Some(r) => r,
            None => return RingRead::Unreadable { reason },
        },
        Err(other) => return other,
    };
    let margins = confidence::assess(img, dot, fg, bg, reader, &reading);
    let (code, id) = (reading.code, reading.id);
    if margins.confidence >= 1.0 {
        RingRead::Code { code, id, margins }
    } else {
        RingRead::Doubtful { code, id, margins }
    }
}

/// The sector phase (0..[`SAMPLES_PER_SECTOR`]) at which the `n` sectors of the ring
/// profile `v` (extended by one sector, wrapped round) are most uniform: the offset that
/// maximises the sum over the sectors of |their summed samples|.
fn sector_phase(v: &[f32], n: usize) -> usize {
    const S: usize = SAMPLES_PER_SECTOR;
    let mut best = (f32::NEG_INFINITY, 0usize);
    for phi in 0..S {
        let mut score = 0.0f32;
        for k in 0..n {
            let mut s = 0.0f32;
            for &x in &v[phi + k * S..phi + k * S + S] {
                s += x;
            }
            score += s.abs();
        }
        if score > best.0 {
            best = (score, phi);
        }
    }
    best.1
}

/// The sharp-image reading of the module doc: sector thresholds.
fn read_by_thresholds(
    img: &GrayImage,
    dot: &Ellipse,
    fg: f32,
    bg: f32,
    reader: &RingReader,
) -> Result<Reading, RingRead> {
    let n = reader.table.bits as usize;
    const S: usize = SAMPLES_PER_SECTOR;
    let m = n * S;
    let contrast = fg - bg;
    if contrast <= 0.0 {
        return Err(RingRead::NoRing);
    }
    let mid = bg + 0.5 * contrast;
    let outer = dot.scaled(reader.ring.1 + 0.9);
    if !img.inside(outer.cx - outer.a, outer.cy - outer.a, 1.0)
        || !img.inside(outer.cx + outer.a, outer.cy + outer.a, 1.0)
    {
        return Err(RingRead::NoRing);
    }
    let radii: [f64; 5] =
        std::array::from_fn(|i| reader.ring.0 + (reader.ring.1 - reader.ring.0) * i as f64 / 4.0);
    // at most 24 sectors (CodeTable::generate), plus one wrapped round below
    let mut vbuf = [0.0f32; 25 * S];
    let v = &mut vbuf[..m];
    let fr = dot.frame();
    let trig = crate::ellipse::unit_circle(m);
    let ring_at = |j: usize| {
        let (c, s) = trig[j];
        let mut acc = 0.0;
        for &r in &radii {
            let (x, y) = fr.map(r * c, r * s);
            acc += img.sample_inside(x, y);
        }
        acc / radii.len() as f32 - mid
    };
    // Most dots have no ring (plain targets): first every 4th angle (4 per sector) on the middle
    // of the band, and no ring when none of them is bright.
    let r_mid = 0.5 * (reader.ring.0 + reader.ring.1);
    if !bright_over(img, dot, r_mid, mid, m / 4, 0.0) {
        return Err(RingRead::NoRing);
    }
    for (j, vj) in v.iter_mut().enumerate() {
        *vj = ring_at(j);
    }
    let bright = v.iter().filter(|&&x| x > 0.0).count() as f64 / m as f64;
    if bright < 0.05 {
        return Err(RingRead::NoRing);
    }
    // The gap between dot and ring and the band outside the ring must be dark.
    if bright_over(img, dot, reader.gap_radius(), mid, 180, 0.1)
        || bright_over(img, dot, reader.ring.1 + 0.55, mid, 180, 0.15)
    {
        return Err(RingRead::Unreadable {
            reason: "surround of the ring is not dark",
        });
    }
    // Sector phase. `v` is extended by one sector (wrapped round) so that the sums below need
    // no modulo.
    vbuf.copy_within(..S, m);
    let v = &vbuf[..m + S];
    let phi = sector_phase(v, n);
    let (q0, q1) = (S / 5, S - S / 5); // central 60 %
    let mut code = 0u32;
    let mut margin = f32::INFINITY;
    let (mut y, mut mask) = ([0.0f32; 24], 0u32);
    for k in 0..n {
        let samples = &v[phi + k * S + q0..phi + k * S + q1];
        let mean = samples.iter().sum::<f32>() / samples.len() as f32;
        let is_bright = mean > 0.0;
        if samples.iter().any(|&s| (s > 0.0) != is_bright) {
            return Err(RingRead::Unreadable {
                reason: "a sector is not uniform",
            });
        }
        margin = margin.min(mean.abs() / contrast);
        y[k] = mean;
        mask |= u32::from(is_bright) << k;
        let bit = is_bright == reader.bright_is_one;
        let pos = if reader.clockwise { k } else { n - 1 - k };
        if bit {
            code |= 1 << pos;
        }
    }
    if margin < reader.min_margin {
        return Err(RingRead::Unreadable {
            reason: "a sector is too close to the mid level",
        });
    }
    let code = min_rotation(code, n as u32);
    match reader.table.id(code) {
        Some(id) => Ok(Reading {
            method: ReadMethod::Thresholds,
            code,
            id,
            mask,
            y,
            phi,
            profile: std::array::from_fn(|j| if j < m { v[j] } else { 0.0 }),
            scale: 1.0,
        }),
        None => Err(RingRead::Unreadable {
            reason: "code not in the table",
        }),
    }
}

/// Samples the unit-frame circle of radius `rho` at `out.len()` angles (brightness minus
/// `mid`) into `out`.
fn circle_samples(img: &GrayImage, dot: &Ellipse, rho: f64, mid: f32, out: &mut [f32]) {
    let fr = dot.frame();
    let trig = crate::ellipse::unit_circle(out.len());
    for (o, &(c, s)) in out.iter_mut().zip(trig.iter()) {
        let (x, y) = fr.map(rho * c, rho * s);
        *o = img.sample_inside(x, y) - mid;
    }
}

/// The best fit of one code: residual sum of squares, number, code, ring contrast β.
#[derive(Clone, Copy)]
struct Fit {
    ssr: f32,
    mask: u32,
    id: u32,
    code: u32,
    beta: f32,
    eps: f32,
}

/// Fits every code of the table, at every rotation and neighbour spill ε, to the sector means
/// `y` (sector k in reading order): y ≈ α + β x̃ with x̃ = M_ε x a pattern of [`Patterns`], α
/// and β by least squares: with y centred (Σ ỹ = 0), Σ x̃ ỹ = Σ x (M_ε ỹ) (M_ε is
/// symmetric), a sum of z = M_ε ỹ over the bright sectors, looked up by halves of the mask;
/// β = Σ x̃ ỹ / Σ x̃², Σ r² = Σ ỹ² − β Σ x̃ ỹ. Returns the best fit and the best fit of
/// another number.
fn fit_codes(y: &[f32], reader: &RingReader) -> (Option<Fit>, Option<Fit>) {
    let n = y.len();
    let ybar = y.iter().sum::<f32>() / n as f32;
    let yc: Vec<f32> = y.iter().map(|v| v - ybar).collect();
    let syy: f32 = yc.iter().map(|v| v * v).sum();
    let lo = n / 2;
    // per ε: the sums of z over every subset of the low `lo` and of the high n − lo sectors
    let sums: Vec<(Vec<f32>, Vec<f32>)> = SPILLS
        .iter()
        .map(|&eps| {
            let z: Vec<f32> = (0..n)
                .map(|k| (1.0 - 2.0 * eps) * yc[k] + eps * (yc[(k + n - 1) % n] + yc[(k + 1) % n]))
                .collect();
            let subset = |part: &[f32]| -> Vec<f32> {
                (0..1usize << part.len())
                    .map(|m| {
                        (0..part.len())
                            .filter(|b| m >> b & 1 == 1)
                            .map(|b| part[b])
                            .sum()
                    })
                    .collect()
            };
            (subset(&z[..lo]), subset(&z[lo..]))
        })
        .collect();
    let (mut best, mut other): (Option<Fit>, Option<Fit>) = (None, None);
    for &(mask, id, code, e, sxx) in &reader.patterns().meta {
        let (l, h) = &sums[e];
        let sxy = l[(mask & ((1 << lo) - 1)) as usize] + h[(mask >> lo) as usize];
        if sxy <= 0.0 {
            continue;
        }
        let beta = sxy / sxx;
        let ssr = syy - beta * sxy;
        if best.is_some_and(|b| ssr >= b.ssr) && other.is_some_and(|o| ssr >= o.ssr) {
            continue;
        }
        let fit = Fit {
            ssr,
            mask,
            id,
            code,
            beta,
            eps: SPILLS[e],
        };
        if best.is_none_or(|b| fit.ssr < b.ssr) {
            if best.is_some_and(|b| b.id != fit.id) {
                other = best;
            }
            best = Some(fit);
        } else if best.is_some_and(|b| b.id != fit.id) && other.is_none_or(|o| fit.ssr < o.ssr) {
            other = Some(fit);
        }
    }
    (best, other)
}

/// The acceptance limits of a model fit (`read_by_model`, (4)): β over the dot's contrast,
/// the largest spill ε, the largest RMS residual over β.
const BETA_RANGE: (f32, f32) = (0.8, 1.4);
pub(crate) const EPS_MAX: f32 = 0.12;
const RMS_MAX: f32 = 0.06;

/// Whether any code could pass the fit tests of `read_by_model` (4) on the sector means `y`
/// (β within [`BETA_RANGE`] of `contrast`, ε ≤ [`EPS_MAX`], RMS ≤ [`RMS_MAX`] β): a
/// necessary condition, checked before the fit of every code, that decides exactly. Such a
/// fit leaves no residual above RMS_MAX β √n, while it predicts at least α + (1 − 2 EPS_MAX) β
/// on its bright sectors and at most α + 2 EPS_MAX β on its dark ones; for n ≤ 18 the two
/// bands do not meet, so its bright sectors are the w largest y_k for some w, every one
/// strictly above every dark one. Only those splits that are codes are fitted (at every ε ≤
/// EPS_MAX, with 1 % of slack on the limits against rounding); beyond 18 sectors, true.
fn may_accept(y: &[f32], contrast: f32, reader: &RingReader) -> bool {
    let n = y.len();
    let reach = RMS_MAX * (n as f32).sqrt();
    if n > 32 || 1.0 - 2.0 * EPS_MAX - reach <= 2.0 * EPS_MAX + reach {
        return true;
    }
    let ybar = y.iter().sum::<f32>() / n as f32;
    let mut yc = [0.0f32; 32];
    for (c, v) in yc.iter_mut().zip(y) {
        *c = v - ybar;
    }
    let yc = &yc[..n];
    let syy: f32 = yc.iter().map(|v| v * v).sum();
    let mut order = [0usize; 32];
    for (k, o) in order[..n].iter_mut().enumerate() {
        *o = k;
    }
    let order = &mut order[..n];
    order.sort_unstable_by(|&a, &b| y[b].total_cmp(&y[a]));
    let mut mask = 0u32;
    for w in 1..n {
        mask |= 1 << order[w - 1];
        if y[order[w - 1]] <= y[order[w]] || !reader.is_code_mask(mask) {
            continue;
        }
        for eps in SPILLS.into_iter().filter(|&e| e <= EPS_MAX) {
            let sxy: f32 = (0..n)
                .filter(|&k| mask >> k & 1 == 1)
                .map(|k| (1.0 - 2.0 * eps) * yc[k] + eps * (yc[(k + n - 1) % n] + yc[(k + 1) % n]))
                .sum();
            let beta = sxy / blurred_sxx(mask, n, eps);
            let ssr = (syy - beta * sxy).max(0.0);
            if beta >= 0.99 * BETA_RANGE.0 * contrast
                && beta <= 1.01 * BETA_RANGE.1 * contrast
                && (ssr / n as f32).sqrt() <= 1.01 * RMS_MAX * beta
            {
                return true;
            }
        }
    }
    false
}

/// Reads a ring that the sector thresholds could not, against a model of the blurred ring.
///
/// Blur moves the mid-level edge of a small dot inwards (by about σ²/2r) and spreads every
/// sector into its neighbours. So (1) the ring's centre radius ρ is found where the ring
/// varies most with the angle (its variance, 4 samples a sector, over 2.0 to 3.2 fitted dot
/// radii for AICON's ring from 2 to 3: inner to outer + 0.2 of a ring of another size), and
/// the ring is sampled at ρ ± 0.15 (0.15 of the ring's width); the gap inside and the band
/// outside (at 0.64 ρ and 1.42 ρ, the sharp reading's 1.6 and 3.55 of 2.5) must be dark. (2) The sector phase is the one of the largest
/// Σ|sector mean| (as in the sharp reading) and each sector's mean over its central 60 % is
/// y_k; a ring whose sectors span less than half the dot's contrast is not read (an accepted
/// fit spans at least 0.6 of it, see (4)). (3) Every code of the table, at every rotation, predicts
/// y_k = α + β ((1 − 2ε) x_k + ε (x_{k−1} + x_{k+1})) with x_k ∈ {0, 1} its sector and ε the
/// blur's spill from the neighbours (0 to 0.18); α and β are fitted by least squares, and the
/// code of the smallest residual Σ r² (the most likely under Gaussian noise) is the reading.
/// (4) It is accepted only when it fits and is unambiguous: β within 0.8 to 1.4 of the dot's
/// contrast (the ring's white is the dot's white; a small dot loses some of its peak under
/// blur, the ring less), ε at most 0.12 (more blur than that and the model, a spill into the
/// next sectors only, no longer holds: on rendered targets every wrong best fit had ε ≥ 0.18),
/// an RMS residual under 6 % of β, and the best fit of any *other* number at least 10 times
/// worse in Σ r² and worse by at least 2 (0.25 β)² (two distinct codes differ in two or more
/// sectors: the parity of the table). A wrong number is far worse than none. The fit of every
/// code (tens of thousands of patterns for 14 bits) runs only when `may_accept` finds that a
/// fit could pass (4): on the real panel, almost never.
fn read_by_model(
    img: &GrayImage,
    dot: &Ellipse,
    fg: f32,
    bg: f32,
    reader: &RingReader,
) -> Option<Reading> {
    const S: usize = SAMPLES_PER_SECTOR;
    let n = reader.table.bits as usize;
    let m = n * S;
    let contrast = fg - bg;
    let mid = bg + 0.5 * contrast;
    let variance = |v: &[f32]| {
        let mean = v.iter().sum::<f32>() / v.len() as f32;
        v.iter().map(|x| (x - mean).powi(2)).sum::<f32>()
    };
    // every buffer on the stack: at most 24 sectors (CodeTable::generate), plus one wrapped
    let mut buf = [0.0f32; 25 * S];
    let (inner, outer) = reader.geometry;
    let (mid_radius, step) = (0.5 * (inner + outer), 0.15 * (outer - inner));
    let rho = (0..=8)
        .map(|i| inner + step * i as f64)
        .map(|r| {
            circle_samples(img, dot, r, mid, &mut buf[..m / 4]);
            (variance(&buf[..m / 4]), r)
        })
        .fold((f32::NEG_INFINITY, mid_radius), |b, c| {
            if c.0 > b.0 {
                c
            } else {
                b
            }
        })
        .1;
    // the gap and the outside at the sharp reading's radii, scaled by ρ over the ring's middle
    let scale = rho / mid_radius;
    if bright_over(img, dot, reader.gap_radius() * scale, mid, 180, 0.1)
        || bright_over(img, dot, (outer + 0.55) * scale, mid, 180, 0.15)
    {
        return None;
    }
    let mut v = [0.0f32; 25 * S];
    for r in [rho - step, rho, rho + step] {
        circle_samples(img, dot, r, mid, &mut buf[..m]);
        for (vj, s) in v.iter_mut().zip(&buf[..m]) {
            *vj += s / 3.0;
        }
    }
    v.copy_within(..S, m);
    let v = &v[..m + S];
    let sector = |phi: usize, k: usize, q: usize| {
        let s = &v[phi + k * S + q..phi + k * S + S - q];
        s.iter().sum::<f32>() / s.len() as f32
    };
    let phi = (0..S)
        .map(|phi| ((0..n).map(|k| sector(phi, k, 0).abs()).sum::<f32>(), phi))
        .fold((f32::NEG_INFINITY, 0), |b, c| if c.0 > b.0 { c } else { b })
        .1;
    let mut y = [0.0f32; 24];
    for (k, yk) in y[..n].iter_mut().enumerate() {
        *yk = sector(phi, k, S / 5);
    }
    let y = &y[..n];
    // an accepted fit has β ≥ 0.8 contrast and ε ≤ 0.12: its sectors span ≥ 0.6 contrast
    let span = y.iter().fold(f32::NEG_INFINITY, |a, &b| a.max(b))
        - y.iter().fold(f32::INFINITY, |a, &b| a.min(b));
    if span < 0.5 * contrast || !may_accept(y, contrast, reader) {
        return None;
    }
    let best = fit_and_accept(y, contrast, reader)?;
    let mut ys = [0.0f32; 24];
    ys[..n].copy_from_slice(y);
    Some(Reading {
        method: ReadMethod::Model,
        code: best.code,
        id: best.id,
        mask: best.mask,
        y: ys,
        phi,
        profile: std::array::from_fn(|j| if j < m { v[j] } else { 0.0 }),
        scale: rho / mid_radius,
    })
}

/// Steps (3) and (4) of `read_by_model`: the fit of every code to the sector means `y` and
/// the test of the best one.
fn fit_and_accept(y: &[f32], contrast: f32, reader: &RingReader) -> Option<Fit> {
    let n = y.len();
    let (Some(best), other) = fit_codes(y, reader) else {
        return None;
    };
    let gap = other.map_or(f32::INFINITY, |o| o.ssr - best.ssr);
    let ok = (BETA_RANGE.0 * contrast..=BETA_RANGE.1 * contrast).contains(&best.beta)
        && best.eps <= EPS_MAX
        && (best.ssr / n as f32).sqrt() <= RMS_MAX * best.beta
        && other.is_none_or(|o| o.ssr >= 10.0 * best.ssr)
        && gap >= 2.0 * (0.25 * best.beta).powi(2);
    ok.then_some(best)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_sizes_match_aicon() {
        assert_eq!(CodeTable::generate(12).unwrap().codes.len(), 147);
        assert_eq!(CodeTable::generate(14).unwrap().codes.len(), 516);
        let t = CodeTable::generate(14).unwrap();
        assert_eq!(t.code(1), Some(129));
        assert_eq!(t.id(135), Some(2));
        assert!(CodeTable::generate(13).is_err());
    }

    #[test]
    fn rotation_and_reversal() {
        assert_eq!(min_rotation(0b10_0000_0000_0001, 14), 0b11);
        assert_eq!(reverse_bits(0b0011, 4), 0b1100);
        for v in [5u32, 129, 1234, 9999] {
            let m = min_rotation(v, 14);
            assert_eq!(min_rotation(m, 14), m);
            assert!(m <= v);
        }
    }

    /// Sector means of a code of the table blurred as the model says, with noise, and of no
    /// code at all: the pre-check must pass every one that the full fit accepts (it decides
    /// exactly), and refuse many (it is there to save the fit).
    #[test]
    fn the_pre_check_passes_every_ring_the_model_fit_accepts() {
        let reader = RingReader::aicon(14).unwrap();
        let n = 14usize;
        let mut s = 0x2545_f491_4f6c_dd1du64;
        let mut rnd = move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 40) as f32 / (1u64 << 24) as f32
        };
        let (mut accepted, mut refused) = (0, 0);
        for trial in 0..3000 {
            let c = reader.table.codes[(rnd() * reader.table.codes.len() as f32) as usize];
            let r = (rnd() * n as f32) as u32 % n as u32;
            let code = ((c << r) | (c >> (n as u32 - r))) & ((1 << n) - 1);
            let mask = sector_mask(code, n, reader.clockwise, reader.bright_is_one);
            let x = |k: usize| ((mask >> (k % n)) & 1) as f32;
            let (eps, beta) = (0.2 * rnd(), 0.7 + 0.8 * rnd());
            let (alpha, noise) = (-0.5 * beta + 0.2 * (rnd() - 0.5), 0.3 * beta * rnd());
            let y: Vec<f32> = (0..n)
                .map(|k| {
                    let model = x(k) * (1.0 - 2.0 * eps) + eps * (x(k + n - 1) + x(k + 1));
                    let y = alpha + beta * model + noise * 2.0 * (rnd() - 0.5);
                    // every tenth: no code, the sectors at random
                    if trial % 10 == 0 {
                        rnd() - 0.5
                    } else {
                        y
                    }
                })
                .collect();
            let pre = may_accept(&y, 1.0, &reader);
            if fit_and_accept(&y, 1.0, &reader).is_some() {
                accepted += 1;
                assert!(pre, "refused before the fit, accepted by it: {y:?}");
            }
            refused += usize::from(!pre);
        }
        assert!(
            accepted > 300 && refused > 300,
            "{accepted} accepted, {refused} refused"
        );
    }
}
