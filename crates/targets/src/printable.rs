//! The printed geometry of AICON-style coded targets, and target number lists; the pages
//! themselves are [`crate::sheet`]'s.
//!
//! Geometry, in units of the central dot's radius R (as measured on the real AICON panel): a
//! white dot of radius 1, a ring of N equal white/black sectors from 2 to 3, all on a black
//! square of side 8, the target number printed under the square. Sector i (bit i of the code)
//! is the i-th sector counter-clockwise as seen on the page — the reading convention
//! [`crate::aicon`] established on the real photographs, so printed targets decode to their
//! numbers (tested by rendering [`target_is_white`] and detecting it).

use crate::TargetError;

/// Half side of the black square, in dot radii.
pub const SQUARE_HALF: f64 = 4.0;
/// Ring band, in dot radii.
pub const RING: (f64, f64) = (2.0, 3.0);

/// Whether the point (u, v) of a target (units of the dot radius, origin at the centre, v down
/// the page) is white, for a ring code `code` of `bits` sectors.
pub fn target_is_white(code: u32, bits: u32, u: f64, v: f64) -> bool {
    target_is_white_with_ring(code, bits, u, v, RING)
}

/// [`target_is_white`] for a code ring from `ring.0` to `ring.1` dot radii.
pub fn target_is_white_with_ring(code: u32, bits: u32, u: f64, v: f64, ring: (f64, f64)) -> bool {
    let r = (u * u + v * v).sqrt();
    if r <= 1.0 {
        return true;
    }
    if !(ring.0..=ring.1).contains(&r) {
        return false;
    }
    // Counter-clockwise on the page (v down) is decreasing atan2(v, u).
    let step = 2.0 * std::f64::consts::PI / bits as f64;
    let a = (-v.atan2(u)).rem_euclid(2.0 * std::f64::consts::PI);
    let i = ((a / step).floor() as u32).min(bits - 1);
    code >> i & 1 == 1
}

/// Parses an ID list such as `2-80`, `5,7,9-12`.
pub fn parse_id_list(s: &str) -> Result<Vec<u32>, TargetError> {
    let bad = || TargetError::Invalid(format!("bad ID list '{s}': expected e.g. 2-80 or 5,7,9-12"));
    let mut out = Vec::new();
    for part in s.split(',').map(str::trim).filter(|p| !p.is_empty()) {
        if let Some((a, b)) = part.split_once('-') {
            let (a, b): (u32, u32) = (
                a.trim().parse().map_err(|_| bad())?,
                b.trim().parse().map_err(|_| bad())?,
            );
            if a > b || b - a > 100_000 {
                return Err(bad());
            }
            out.extend(a..=b);
        } else {
            out.push(part.parse().map_err(|_| bad())?);
        }
    }
    if out.is_empty() {
        return Err(bad());
    }
    let mut seen = std::collections::BTreeSet::new();
    if let Some(twice) = out.iter().find(|&&id| !seen.insert(id)) {
        return Err(TargetError::Invalid(format!(
            "ID list '{s}': {twice} is given twice (each target is printed once)"
        )));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn id_lists() {
        assert_eq!(parse_id_list("2-4,9").unwrap(), vec![2, 3, 4, 9]);
        assert!(parse_id_list("4-2").is_err());
        assert!(parse_id_list("x").is_err());
        assert!(parse_id_list("").is_err());
        let e = parse_id_list("2,2,2").unwrap_err().to_string();
        assert!(
            e.contains("'2,2,2'") && e.contains("2 is given twice"),
            "{e}"
        );
        let e = parse_id_list("2-5,4").unwrap_err().to_string();
        assert!(e.contains("4 is given twice"), "{e}");
    }
}
