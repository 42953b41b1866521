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
    pub bits: u32,
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
    pub table: CodeTable,
    /// Ring sampling band, in dot radii.
    pub ring: (f64, f64),
    /// True: bright sectors are 1s.
    pub bright_is_one: bool,
    /// True: bit i is the i-th sector in the order of increasing image angle (clockwise on
    /// screen); false: the opposite direction.
    pub clockwise: bool,
    /// Smallest accepted |sector mean − mid| as a fraction of the contrast.
    pub min_margin: f32,
}

impl RingReader {
    /// The reader for AICON targets with `bits` sectors, with the conventions established on
    /// the real panel.
    pub fn aicon(bits: u32) -> Result<Self, crate::TargetError> {
        Ok(RingReader {
            table: CodeTable::generate(bits)?,
            ring: (2.2, 2.8),
            bright_is_one: true,
            clockwise: false,
            min_margin: 0.25,
        })
    }
}

/// What was read from a ring.
#[derive(Clone, Debug, PartialEq)]
pub enum RingRead {
    /// No code ring around this dot (the band is essentially all dark).
    NoRing,
    /// A ring is there but it could not be read reliably, or the code is not in the table.
    Unreadable { reason: &'static str },
    /// A code read with confidence: the code at its smallest rotation, the number, and the
    /// smallest sector margin (fraction of the contrast).
    Code { code: u32, id: u32, margin: f32 },
}

/// Fraction of `samples_per_turn` angles at unit-frame radius `rho` brighter than `mid`.
fn bright_fraction(
    img: &GrayImage,
    e: &Ellipse,
    rho: f64,
    mid: f32,
    samples_per_turn: usize,
) -> f64 {
    let mut c = 0;
    let fr = e.frame();
    for &(co, si) in crate::ellipse::unit_circle(samples_per_turn).iter() {
        let (x, y) = fr.map(rho * co, rho * si);
        if img.sample_inside(x, y) > mid {
            c += 1;
        }
    }
    c as f64 / samples_per_turn as f64
}

/// Reads the code ring around a dot whose edge ellipse is `dot`, inner (dot) level `fg` and
/// dark surround `bg`.
pub fn read_ring(
    img: &GrayImage,
    dot: &Ellipse,
    fg: f32,
    bg: f32,
    reader: &RingReader,
) -> RingRead {
    let n = reader.table.bits as usize;
    const S: usize = 16;
    let m = n * S;
    let contrast = fg - bg;
    if contrast <= 0.0 {
        return RingRead::NoRing;
    }
    let mid = bg + 0.5 * contrast;
    let outer = dot.scaled(reader.ring.1 + 0.9);
    if !img.inside(outer.cx - outer.a, outer.cy - outer.a, 1.0)
        || !img.inside(outer.cx + outer.a, outer.cy + outer.a, 1.0)
    {
        return RingRead::NoRing;
    }
    let radii: Vec<f64> = (0..5)
        .map(|i| reader.ring.0 + (reader.ring.1 - reader.ring.0) * i as f64 / 4.0)
        .collect();
    let mut v = vec![0.0f32; m];
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
    if bright_fraction(img, dot, r_mid, mid, m / 4) == 0.0 {
        return RingRead::NoRing;
    }
    for (j, vj) in v.iter_mut().enumerate() {
        *vj = ring_at(j);
    }
    let bright = v.iter().filter(|&&x| x > 0.0).count() as f64 / m as f64;
    if bright < 0.05 {
        return RingRead::NoRing;
    }
    // The gap between dot and ring and the band outside the ring must be dark.
    let gap = bright_fraction(img, dot, 1.6, mid, 180);
    let out = bright_fraction(img, dot, reader.ring.1 + 0.55, mid, 180);
    if gap > 0.1 || out > 0.15 {
        return RingRead::Unreadable {
            reason: "surround of the ring is not dark",
        };
    }
    // Sector phase. `v` is extended by one sector (wrapped round) so that the sums below need
    // no modulo.
    v.extend_from_within(..S);
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
    let phi = best.1;
    let (q0, q1) = (S / 5, S - S / 5); // central 60 %
    let mut code = 0u32;
    let mut margin = f32::INFINITY;
    for k in 0..n {
        let samples = &v[phi + k * S + q0..phi + k * S + q1];
        let mean = samples.iter().sum::<f32>() / samples.len() as f32;
        let is_bright = mean > 0.0;
        if samples.iter().any(|&s| (s > 0.0) != is_bright) {
            return RingRead::Unreadable {
                reason: "a sector is not uniform",
            };
        }
        margin = margin.min(mean.abs() / contrast);
        let bit = is_bright == reader.bright_is_one;
        let pos = if reader.clockwise { k } else { n - 1 - k };
        if bit {
            code |= 1 << pos;
        }
    }
    if margin < reader.min_margin {
        return RingRead::Unreadable {
            reason: "a sector is too close to the mid level",
        };
    }
    let code = min_rotation(code, n as u32);
    match reader.table.id(code) {
        Some(id) => RingRead::Code { code, id, margin },
        None => RingRead::Unreadable {
            reason: "code not in the table",
        },
    }
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
}
