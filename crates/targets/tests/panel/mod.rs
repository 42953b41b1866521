//! The real AICON panel data shared by the panel tests: where it is, and its reference
//! coordinates (`target-coordinates.txt`: id, X, Y, Z in mm, then columns not used here).
#![allow(dead_code)]

use std::collections::HashMap;

/// The data folder, relative to this crate.
pub const DATA: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../../shared/data/aicon-panel"
);

/// Reference coordinates by target id, or `None` when the data is absent.
pub fn reference() -> Option<HashMap<u32, [f64; 3]>> {
    let text = std::fs::read_to_string(format!("{DATA}/target-coordinates.txt")).ok()?;
    Some(
        text.lines()
            .filter_map(|l| {
                let f: Vec<&str> = l.split_whitespace().collect();
                if f.len() < 4 {
                    return None;
                }
                Some((
                    f[0].parse().ok()?,
                    [f[1].parse().ok()?, f[2].parse().ok()?, f[3].parse().ok()?],
                ))
            })
            .collect(),
    )
}
