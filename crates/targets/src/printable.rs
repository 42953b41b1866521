//! Printable AICON-style coded targets, as SVG at true size (millimetres).
//!
//! Geometry, in units of the central dot's radius R (as measured on the real AICON panel): a
//! white dot of radius 1, a ring of N equal white/black sectors from 2 to 3, all on a black
//! square of side 8, the target number printed under the square. Sector i (bit i of the code)
//! is the i-th sector counter-clockwise as seen on the page — the reading convention
//! [`crate::aicon`] established on the real photographs, so printed targets decode to their
//! numbers (tested by rendering [`target_is_white`] and detecting it).

use crate::aicon::CodeTable;
use crate::TargetError;
use std::fmt::Write;

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

fn sector_path(cx: f64, cy: f64, r0: f64, r1: f64, a0: f64, a1: f64) -> String {
    // Angles in the page frame (y down), a0 < a1, drawn as an annular sector.
    let p = |r: f64, a: f64| (cx + r * a.cos(), cy + r * a.sin());
    let large = if a1 - a0 > std::f64::consts::PI { 1 } else { 0 };
    let (x0, y0) = p(r1, a0);
    let (x1, y1) = p(r1, a1);
    let (x2, y2) = p(r0, a1);
    let (x3, y3) = p(r0, a0);
    format!(
        "M{x0:.4} {y0:.4} A{r1:.4} {r1:.4} 0 {large} 1 {x1:.4} {y1:.4} L{x2:.4} {y2:.4} A{r0:.4} {r0:.4} 0 {large} 0 {x3:.4} {y3:.4} Z"
    )
}

/// An SVG page (millimetres) with the coded targets `ids` of `bits` sectors, central dot
/// diameter `dot_mm`, laid out in `columns` columns.
pub fn targets_svg(
    bits: u32,
    ids: &[u32],
    dot_mm: f64,
    columns: usize,
) -> Result<String, TargetError> {
    let table = CodeTable::generate(bits)?;
    if !(dot_mm > 0.0 && dot_mm < 1000.0) {
        return Err(TargetError::Invalid(format!(
            "dot diameter must be a positive number of mm, not {dot_mm}"
        )));
    }
    let codes: Vec<(u32, u32)> = ids
        .iter()
        .map(|&id| {
            table.code(id).map(|c| (id, c)).ok_or_else(|| {
                TargetError::Invalid(format!(
                    "{bits}-bit codes are numbered 1 to {}; {id} does not exist",
                    table.codes.len()
                ))
            })
        })
        .collect::<Result<_, _>>()?;
    let r = dot_mm / 2.0;
    let side = 2.0 * SQUARE_HALF * r;
    let margin = 10.0f64.max(r);
    let label = 1.5 * r;
    let cell_w = side + r * 2.0;
    let cell_h = side + label + r * 2.0;
    let columns = columns.max(1).min(codes.len().max(1));
    let rows = codes.len().div_ceil(columns);
    let width = 2.0 * margin + columns as f64 * cell_w;
    let height = 2.0 * margin + rows as f64 * cell_h;
    let mut s = String::new();
    let _ = writeln!(s, r#"<?xml version="1.0" encoding="UTF-8"?>"#);
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{width:.3}mm" height="{height:.3}mm" viewBox="0 0 {width:.3} {height:.3}">"#
    );
    let _ = writeln!(
        s,
        r#"<!-- pingcal: AICON-style {bits}-bit coded targets, dot diameter {dot_mm} mm, print at 100 % scale (no fit-to-page) -->"#
    );
    let _ = writeln!(
        s,
        r#"<rect x="0" y="0" width="{width:.3}" height="{height:.3}" fill="white"/>"#
    );
    let step = 2.0 * std::f64::consts::PI / bits as f64;
    for (k, (id, code)) in codes.iter().enumerate() {
        let (col, row) = (k % columns, k / columns);
        let cx = margin + col as f64 * cell_w + cell_w / 2.0;
        let cy = margin + row as f64 * cell_h + r + side / 2.0;
        let _ = writeln!(s, r#"<g id="target-{id}">"#);
        let _ = writeln!(
            s,
            r#"<rect x="{:.4}" y="{:.4}" width="{side:.4}" height="{side:.4}" fill="black"/>"#,
            cx - side / 2.0,
            cy - side / 2.0
        );
        let _ = writeln!(
            s,
            r#"<circle cx="{cx:.4}" cy="{cy:.4}" r="{r:.4}" fill="white"/>"#
        );
        // Runs of set bits are drawn as one sector each. Bit i spans page angles
        // [−(i+1)·step, −i·step] (counter-clockwise on the page).
        let mut i = 0;
        while i < bits {
            if code >> i & 1 == 1 {
                let mut j = i;
                while j + 1 < bits && code >> (j + 1) & 1 == 1 {
                    j += 1;
                }
                let (a0, a1) = (-((j + 1) as f64) * step, -(i as f64) * step);
                let _ = writeln!(
                    s,
                    r#"<path d="{}" fill="white"/>"#,
                    sector_path(cx, cy, RING.0 * r, RING.1 * r, a0, a1)
                );
                i = j + 1;
            } else {
                i += 1;
            }
        }
        let _ = writeln!(
            s,
            r#"<text x="{cx:.4}" y="{:.4}" font-family="sans-serif" font-size="{:.4}" text-anchor="middle">{id}</text>"#,
            cy + side / 2.0 + label,
            label
        );
        let _ = writeln!(s, "</g>");
    }
    let _ = writeln!(s, "</svg>");
    Ok(s)
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

    #[test]
    fn svg_has_every_target() {
        let s = targets_svg(14, &[2, 3, 80], 8.0, 5).unwrap();
        assert_eq!(s.matches("<g id=\"target-").count(), 3);
        assert!(s.contains(">80</text>"));
        assert!(targets_svg(14, &[517], 8.0, 5).is_err());
        assert!(targets_svg(13, &[2], 8.0, 5).is_err());
    }
}
