//! Reading a cloud from a file, whatever its kind: a `pingcal-scan` CSV (through the mount
//! model, [`crate::cloud::Cloud::from_scans`]), a PLY ([`crate::ply`]) or a text cloud
//! ([`crate::xyz`]), chosen by the file's extension.

use crate::cloud::{Cloud, MountModel};
use crate::error::{LrfError, Result};
use crate::scan::Masked;

/// Reads one file into a cloud: `.ply` (ascii or binary), `.pcd` ([`crate::pcd`]), `.xyz`/`.txt`/`.pts` (text
/// columns) or, for anything else, the `pingcal-scan` CSV.
pub fn read_cloud_file(path: &std::path::Path, mount: &MountModel) -> Result<Cloud> {
    read_cloud_file_masked(path, file_kind(path), mount).map(|(c, _)| c)
}

/// [`read_cloud_file`] of a file of kind `kind`, with the ranges of a scan file masked for
/// being beyond any range finder ([`crate::scan::ScanReader::masked`]).
fn read_cloud_file_masked(
    path: &std::path::Path,
    kind: CloudFileKind,
    mount: &MountModel,
) -> Result<(Cloud, Masked)> {
    let none = Masked::default();
    match kind {
        CloudFileKind::Ply => Ok((crate::ply::read_ply_file(path)?, none)),
        CloudFileKind::Xyz => Ok((crate::xyz::read_xyz_file(path)?, none)),
        CloudFileKind::Pcd => Ok((crate::pcd::read_pcd_file(path)?, none)),
        CloudFileKind::Scans => {
            let mut reader = crate::scan::open_scan_file(path)?;
            let header = reader.header();
            let c = Cloud::from_scans(&header, reader.by_ref(), mount)?;
            crate::scan::check_units(&reader)?;
            let masked = reader.masked();
            if c.is_empty() && masked.count > 0 {
                return Err(LrfError::Empty {
                    file: path.display().to_string(),
                    msg: format!(
                        "no valid ranges in any scan: {}",
                        masked.describe(&format!("beyond {:e} mm", crate::scan::MAX_RANGE_MM))
                    ),
                });
            }
            Ok((non_empty(c, path)?, masked))
        }
    }
}

/// The warning for ranges of `path` masked for being beyond any range finder, if any.
pub fn masked_warning(path: &std::path::Path, masked: &Masked) -> Option<String> {
    (masked.count > 0).then(|| {
        format!(
            "{}: {}",
            path.display(),
            masked.describe(&format!(
                "beyond {:e} mm (no range finder reaches that: a corrupt value?)",
                crate::scan::MAX_RANGE_MM
            ))
        )
    })
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

/// A file of LRF data and its kind, told once from its extension ([`file_kind`]) and
/// carried with it: a project's `[lrf] scans` entries are classified as they are loaded.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CloudPath {
    /// The file.
    pub path: std::path::PathBuf,
    /// What it is read as.
    pub kind: CloudFileKind,
}

impl CloudPath {
    /// `path`, classified by its extension.
    pub fn new(path: std::path::PathBuf) -> Self {
        let kind = file_kind(&path);
        CloudPath { path, kind }
    }

    /// Whether it is a `pingcal-scan` file (the scans as the LRF reported them).
    pub fn is_scans(&self) -> bool {
        self.kind == CloudFileKind::Scans
    }

    /// The cloud of the file ([`read_cloud_file_in`]).
    pub fn read_in(&self, mount: &MountModel, unit: CloudUnit) -> Result<(Cloud, Vec<String>)> {
        read_kind_in(&self.path, self.kind, mount, unit)
    }
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

/// The unit of a cloud file's coordinates (PLY, PCD, XYZ). Scan files are always mm.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum CloudUnit {
    /// Millimetres: the default, as pingcal always read clouds.
    #[default]
    Mm,
    /// Metres (what PCL, ROS and most scanners write).
    M,
}

impl CloudUnit {
    /// Millimetres per unit.
    pub fn to_mm(self) -> f64 {
        match self {
            CloudUnit::Mm => 1.0,
            CloudUnit::M => 1000.0,
        }
    }
    /// The unit's name, as parsed.
    pub fn name(self) -> &'static str {
        match self {
            CloudUnit::Mm => "mm",
            CloudUnit::M => "m",
        }
    }
}

impl CloudUnit {
    /// Every unit, as the files spell them.
    pub const NAMES: [&'static str; 2] = ["mm", "m"];

    /// The unit spelled `word`, if any.
    pub fn from_word(word: &str) -> Option<Self> {
        [CloudUnit::Mm, CloudUnit::M]
            .into_iter()
            .find(|u| u.name() == word)
    }
}

impl serde::Serialize for CloudUnit {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

impl<'de> serde::Deserialize<'de> for CloudUnit {
    /// `mm` or `m`, anything else refused with the words allowed.
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        crate::words::deserialize(d, &Self::NAMES, Self::from_word)
    }
}

impl std::str::FromStr for CloudUnit {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "mm" => Ok(CloudUnit::Mm),
            "m" => Ok(CloudUnit::M),
            _ => Err(format!("unknown unit {s:?} (expected m or mm)")),
        }
    }
}

/// A cloud below this extent (bounding-box diagonal) read as mm is probably metres.
pub const SMALL_EXTENT_MM: f64 = 50.0;
/// A cloud above this extent read as metres is probably mm (10 km).
pub const LARGE_EXTENT_MM: f64 = 1e7;

/// The diagonal of the cloud's bounding box, mm (0 for an empty cloud).
pub fn extent_mm(c: &Cloud) -> f64 {
    let Some(first) = c.points.first() else {
        return 0.0;
    };
    let (mut lo, mut hi) = (*first, *first);
    for p in &c.points {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    (hi - lo).norm()
}

/// [`read_cloud_file`] with the unit of a cloud file's coordinates (ignored for scan files,
/// always mm), converted to mm; with the warnings for the caller to show: a cloud whose
/// extent says the unit is probably wrong. Coordinates beyond ±1e7 mm after the conversion
/// are refused.
pub fn read_cloud_file_in(
    path: &std::path::Path,
    mount: &MountModel,
    unit: CloudUnit,
) -> Result<(Cloud, Vec<String>)> {
    read_kind_in(path, file_kind(path), mount, unit)
}

/// [`read_cloud_file_in`] of a file already classified as `kind`.
fn read_kind_in(
    path: &std::path::Path,
    kind: CloudFileKind,
    mount: &MountModel,
    unit: CloudUnit,
) -> Result<(Cloud, Vec<String>)> {
    let (mut c, masked) = read_cloud_file_masked(path, kind, mount)?;
    let mut warnings = Vec::new();
    if kind == CloudFileKind::Scans {
        warnings.extend(masked_warning(path, &masked));
        return Ok((c, warnings));
    }
    let k = unit.to_mm();
    if k != 1.0 {
        for p in &mut c.points {
            *p *= k;
        }
        if let Some(o) = &mut c.origins {
            for p in o {
                *p *= k;
            }
        }
    }
    let max = crate::xyz::MAX_COORDINATE_MM;
    if let Some(i) = c.points.iter().position(|p| p.amax() > max) {
        return Err(LrfError::Invalid(format!(
            "{}: point {} is beyond ±{max:e} mm (10 km) in {}",
            path.display(),
            i + 1,
            unit.name()
        )));
    }
    let e = extent_mm(&c);
    if unit == CloudUnit::Mm && e < SMALL_EXTENT_MM {
        warnings.push(format!(
            "{}: the cloud is {e:.3} mm across, read as mm: probably metres (--unit m, or [lrf] cloud_unit = \"m\")",
            path.display()
        ));
    } else if unit == CloudUnit::M && e > LARGE_EXTENT_MM {
        warnings.push(format!(
            "{}: the cloud is {:.1} km across, read as metres: probably mm (--unit mm)",
            path.display(),
            e / 1e6
        ));
    }
    Ok((c, warnings))
}

/// The `lrf_model` block of a file (the `results.json` of `pingcal calibrate`, the
/// `mount.json` of `pingcal lrf-mount`, or a file that is that block alone): the whole
/// mount and range model, checked (finite values, scale errors that are small fractions).
/// An error names the file and what is missing.
pub fn read_lrf_model(path: &std::path::Path) -> Result<crate::sensor::MountModel> {
    let file = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|e| LrfError::io(&file, e))?;
    let invalid = |msg: String| LrfError::Invalid(format!("{file}: {msg}"));
    let v: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| invalid(format!("not JSON ({e})")))?;
    let block = v.get("lrf_model").unwrap_or(&v);
    if block.get("offset_mm").is_none() {
        return Err(invalid(
            "no `lrf_model` block (offset_mm, tilt_x_deg, …): expected the results.json of `pingcal calibrate` or the mount.json of `pingcal lrf-mount`".into(),
        ));
    }
    let m: crate::sensor::MountModel =
        serde_json::from_value(block.clone()).map_err(|e| invalid(format!("lrf_model: {e}")))?;
    m.check([
        "offset_mm",
        "tilt_x_deg",
        "tilt_z_deg",
        "servo_zero_deg",
        "servo_scale",
        "range_offset_mm",
        "range_scale",
    ])
    .map_err(|e| invalid(format!("lrf_model: {e}")))?;
    Ok(m)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn units_parse_and_a_metre_cloud_read_as_mm_warns() {
        assert_eq!("m".parse::<CloudUnit>(), Ok(CloudUnit::M));
        assert!("cm"
            .parse::<CloudUnit>()
            .unwrap_err()
            .contains("expected m or mm"));
        let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data/pcd/cloud_binary.pcd");
        let (c, w) = read_cloud_file_in(&p, &MountModel::default(), CloudUnit::Mm).unwrap();
        assert_eq!(w.len(), 1);
        assert!(
            w[0].contains("cloud_binary.pcd: the cloud is") && w[0].contains("probably metres"),
            "{w:?}"
        );
        let (m, w) = read_cloud_file_in(&p, &MountModel::default(), CloudUnit::M).unwrap();
        assert!(w.is_empty(), "{w:?}");
        assert!((m.points[0] - c.points[0] * 1000.0).norm() < 1e-9);
    }
}
