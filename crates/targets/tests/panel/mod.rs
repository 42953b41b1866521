//! The real AICON panel data shared by the panel tests: where it is, and its reference
//! coordinates (`target-coordinates.txt`: id, X, Y, Z in mm, then columns not used here).
#![allow(dead_code)]

use std::collections::HashMap;
use std::path::PathBuf;

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

/// The panel's reference coordinates (by code) and its sorted TIFF images.
pub type Panel = (HashMap<u32, [f64; 3]>, Vec<PathBuf>);

/// The reference coordinates and the sorted TIFF images of the panel, or `None` (with the
/// reason printed) when the data is absent and the calling test should skip.
pub fn panel() -> Option<Panel> {
    let Some(refs) = reference() else {
        println!("SKIP: {DATA} not found (real AICON panel data absent)");
        return None;
    };
    let Ok(dir) = std::fs::read_dir(format!("{DATA}/images")) else {
        println!("SKIP: {DATA}/images not found");
        return None;
    };
    let mut files: Vec<PathBuf> = dir
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "tif"))
        .collect();
    files.sort();
    Some((refs, files))
}
