//! Reading a cloud from a file, whatever its kind: a `pingcal-scan` CSV (through the mount
//! model, [`crate::cloud::Cloud::from_scans`]), a PLY ([`crate::ply`]) or a text cloud
//! ([`crate::xyz`]), chosen by the file's extension.

use crate::cloud::{Cloud, MountModel};
use crate::error::{LrfError, Result};

/// Reads one file into a cloud: `.ply` (ascii or binary), `.pcd` ([`crate::pcd`]), `.xyz`/`.txt`/`.pts` (text
/// columns) or, for anything else, the `pingcal-scan` CSV.
pub fn read_cloud_file(path: &std::path::Path, mount: &MountModel) -> Result<Cloud> {
    match file_kind(path) {
        CloudFileKind::Ply => crate::ply::read_ply_file(path),
        CloudFileKind::Xyz => crate::xyz::read_xyz_file(path),
        CloudFileKind::Pcd => crate::pcd::read_pcd_file(path),
        CloudFileKind::Scans => {
            let reader = crate::scan::open_scan_file(path)?;
            let header = reader.header();
            non_empty(Cloud::from_scans(&header, reader, mount)?, path)
        }
    }
}

/// What [`read_cloud_file`] reads a file as, by its extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CloudFileKind {
    /// `.ply`.
    Ply,
    /// `.pcd` (ascii, binary or binary_compressed).
    Pcd,
    /// `.xyz`, `.txt`, `.pts`.
    Xyz,
    /// Anything else: `pingcal-scan` CSV.
    Scans,
}

/// The kind of a cloud file, by its extension.
pub fn file_kind(path: &std::path::Path) -> CloudFileKind {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    match ext.as_str() {
        "ply" => CloudFileKind::Ply,
        "pcd" => CloudFileKind::Pcd,
        "xyz" | "txt" | "pts" => CloudFileKind::Xyz,
        _ => CloudFileKind::Scans,
    }
}

/// `c`, or the error naming `path` when no scan had a valid range.
pub fn non_empty(c: Cloud, path: &std::path::Path) -> Result<Cloud> {
    if c.is_empty() {
        return Err(LrfError::Empty {
            file: path.display().to_string(),
            msg: "no valid ranges in any scan".into(),
        });
    }
    Ok(c)
}
