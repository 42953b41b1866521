//! Drawing AICON / Schneider ring codes (docs/method.md, "AICON coded targets").
//!
//! The code tables themselves (which N-bit values are codes, and which number each one
//! has) are [`pingcal_targets::aicon::CodeTable`]: the simulator draws exactly the codes the
//! detector reads. This module only says where the bits go on a printed target.
//!
//! Sector convention (the one of the real AICON panel photographs and of
//! `pingcal_targets::printable`, read by `pingcal_targets::aicon::RingReader::aicon`):
//! with the target's in-plane axes (t1, t2), t1 × t2 along the target normal (towards the
//! viewer), sector k covers the angles `[ψ + k·360°/N, ψ + (k+1)·360°/N)` measured from t1
//! towards t2 — counter-clockwise as the viewer sees the target, ψ a random rotation of the
//! printed target — and sector k is retro-reflective iff bit k of the code value is set.
//! So on a (non-mirrored) photograph the bits follow each other counter-clockwise on
//! screen, least significant first, bright = 1.

pub use pingcal_targets::aicon::{min_rotation, CodeTable};

/// The code table of `bits`-sector rings (12 or 14 for AICON; any even count 4–24).
///
/// # Panics
/// On an odd bit count or one outside 4–24 (the configuration is validated before).
pub fn code_table(bits: u32) -> CodeTable {
    CodeTable::generate(bits).expect("ring bits must be even, 4..=24")
}

/// The sector (0 … `bits`−1) of the in-plane direction (x, y) (along t1, t2) on a ring
/// printed with rotation `rotation` (ψ, radians).
pub fn sector_at(x: f64, y: f64, rotation: f64, bits: u32) -> u32 {
    let tau = std::f64::consts::TAU;
    let phi = (y.atan2(x) - rotation).rem_euclid(tau);
    ((phi / tau * bits as f64) as u32).min(bits - 1)
}

/// Whether the ring of code value `code` printed with rotation `rotation` is
/// retro-reflective in the in-plane direction (x, y).
pub fn ring_is_retro(code: u32, bits: u32, rotation: f64, x: f64, y: f64) -> bool {
    code & (1 << sector_at(x, y, rotation, bits)) != 0
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Walking counter-clockwise (from t1 towards t2) around a drawn ring, starting at the
    /// printed rotation ψ, meets the bits of the code least significant first; any start
    /// reads a rotation of the code, whose smallest rotation is the code again.
    #[test]
    fn drawn_ring_reads_back_counter_clockwise_lsb_first() {
        let t = code_table(14);
        for id in [1u32, 2, 77, 300, 516] {
            let code = t.code(id).unwrap();
            for psi in [0.0, 0.3, 2.0, 5.9] {
                let step = std::f64::consts::TAU / 14.0;
                let read = |start: f64| -> u32 {
                    (0..14).fold(0, |acc, k| {
                        let a = start + (k as f64 + 0.5) * step;
                        acc | (ring_is_retro(code, 14, psi, a.cos(), a.sin()) as u32) << k
                    })
                };
                assert_eq!(read(psi), code, "id {id}, ψ {psi}");
                let other = read(psi + 3.0 * step);
                assert_ne!(other, code, "a rotation of a code is not the code itself");
                assert_eq!(t.id(min_rotation(other, 14)), Some(id));
            }
        }
    }
}
