//! From scans to a 3D cloud: the paper's eq. 2 plus an optional mount model.
//!
//! Paper eq. 2 (Y along the servo shaft, X along the beam at α = 0 when β = 0):
//! `x = r cos α cos β,  y = r sin α,  z = r cos α sin β`, i.e. `p = R_β · (r cos α, r sin α, 0)`
//! with `R_β = [[cos β, 0, −sin β], [0, 1, 0], [sin β, 0, cos β]]`.
//!
//! The mount model (zero by default, which is exactly eq. 2):
//! `p = R_β · (R_x(tilt_x) · R_z(tilt_z) · (r cos α, r sin α, 0) + offset)`, with
//! `β = servo − servo_zero`. `offset` is the 2D LRF centre seen from the servo axis (in the
//! frame that turns with the servo), the tilts turn the scan plane. With a non-zero offset
//! the frame origin is the point of the servo axis, and each beam starts at `R_β · offset`:
//! the cloud keeps these ray origins, because the along-ray sphere fit needs them.

use crate::error::{LrfError, Result};
use crate::scan::{ScanHeader, ScanLine};
use nalgebra::{Matrix3, Vector3};

/// The geometry of the LRF on its servo. All zero: paper eq. 2.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MountModel {
    /// 2D LRF centre relative to the servo axis, in the turning frame, mm.
    pub offset_mm: [f64; 3],
    /// Tilt of the scan plane about X (the α = 0 beam), degrees.
    pub tilt_x_deg: f64,
    /// Tilt of the scan plane about Z, degrees.
    pub tilt_z_deg: f64,
    /// Servo reading at which the scan plane is the XY plane, degrees.
    pub servo_zero_deg: f64,
}

/// `R_β` of eq. 2 (β in radians).
pub fn servo_rotation(beta: f64) -> Matrix3<f64> {
    let (s, c) = beta.sin_cos();
    Matrix3::new(c, 0.0, -s, 0.0, 1.0, 0.0, s, 0.0, c)
}

impl MountModel {
    fn tilt(&self) -> Matrix3<f64> {
        let (sx, cx) = self.tilt_x_deg.to_radians().sin_cos();
        let (sz, cz) = self.tilt_z_deg.to_radians().sin_cos();
        let rx = Matrix3::new(1.0, 0.0, 0.0, 0.0, cx, -sx, 0.0, sx, cx);
        let rz = Matrix3::new(cz, -sz, 0.0, sz, cz, 0.0, 0.0, 0.0, 1.0);
        rx * rz
    }

    /// True when the model is eq. 2 exactly (every ray starts at the origin).
    pub fn is_identity(&self) -> bool {
        *self == MountModel::default()
    }

    /// The 3D point and the ray origin of one beam: range `r` (mm), beam angle α and servo
    /// reading, both in degrees.
    pub fn beam(&self, r: f64, alpha_deg: f64, servo_deg: f64) -> (Vector3<f64>, Vector3<f64>) {
        let rb = servo_rotation((servo_deg - self.servo_zero_deg).to_radians());
        let (sa, ca) = alpha_deg.to_radians().sin_cos();
        let p2 = Vector3::new(r * ca, r * sa, 0.0);
        let o = rb * Vector3::from(self.offset_mm);
        (rb * (self.tilt() * p2) + o, o)
    }
}

/// A point cloud in the LRF frame (mm), with the ray origin of each point when it is not
/// the frame origin.
#[derive(Debug, Clone, Default)]
pub struct Cloud {
    /// The points, mm.
    pub points: Vec<Vector3<f64>>,
    /// Ray origin of each point; `None` means every ray starts at (0, 0, 0).
    pub origins: Option<Vec<Vector3<f64>>>,
}

impl Cloud {
    /// A cloud of points seen from the origin (PLY/XYZ files).
    pub fn from_points(points: Vec<Vector3<f64>>) -> Self {
        Cloud {
            points,
            origins: None,
        }
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// True when there are no points.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The ray origin of point `i`.
    pub fn origin(&self, i: usize) -> Vector3<f64> {
        self.origins.as_ref().map_or(Vector3::zeros(), |o| o[i])
    }

    /// Appends the valid beams of one scan (eq. 2 + mount).
    pub fn push_scan(&mut self, header: &ScanHeader, scan: &ScanLine, mount: &MountModel) {
        let keep_origins = !mount.is_identity();
        if keep_origins && self.origins.is_none() {
            self.origins = Some(vec![Vector3::zeros(); self.points.len()]);
        }
        for (i, &r) in scan.ranges_mm.iter().enumerate() {
            if r <= 0.0 {
                continue;
            }
            let (p, o) = mount.beam(r, header.beam_angle_deg(i), scan.servo_deg);
            self.points.push(p);
            if let Some(os) = self.origins.as_mut() {
                os.push(o);
            }
        }
    }

    /// Builds a cloud from a stream of scans.
    pub fn from_scans<I>(header: &ScanHeader, scans: I, mount: &MountModel) -> Result<Cloud>
    where
        I: IntoIterator<Item = Result<ScanLine>>,
    {
        let mut c = Cloud::default();
        for s in scans {
            c.push_scan(header, &s?, mount);
        }
        Ok(c)
    }

    /// Appends another cloud.
    pub fn extend(&mut self, other: Cloud) {
        match (self.origins.as_mut(), other.origins) {
            (None, None) => {}
            (Some(a), Some(b)) => a.extend(b),
            (Some(a), None) => a.extend(std::iter::repeat_n(Vector3::zeros(), other.points.len())),
            (None, Some(b)) => {
                let mut a = vec![Vector3::zeros(); self.points.len()];
                a.extend(b);
                self.origins = Some(a);
            }
        }
        self.points.extend(other.points);
    }
}

/// Reads one file into a cloud: `.ply` (ascii or binary), `.xyz`/`.txt`/`.pts` (text
/// columns) or, for anything else, the `pingcal-scan` CSV.
pub fn read_cloud_file(path: &std::path::Path, mount: &MountModel) -> Result<Cloud> {
    match file_kind(path) {
        CloudFileKind::Ply => crate::ply::read_ply_file(path),
        CloudFileKind::Xyz => crate::xyz::read_xyz_file(path),
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eq2_exactly_with_default_mount() {
        let m = MountModel::default();
        for &(r, a, b) in &[
            (1000.0f64, 30.0f64, 20.0f64),
            (2500.0, -100.0, -45.0),
            (700.0, 0.0, 90.0),
        ] {
            let (p, o) = m.beam(r, a, b);
            let (ar, br) = (f64::to_radians(a), f64::to_radians(b));
            let want = Vector3::new(
                r * ar.cos() * br.cos(),
                r * ar.sin(),
                r * ar.cos() * br.sin(),
            );
            assert!((p - want).norm() < 1e-9, "{p} vs {want}");
            assert_eq!(o, Vector3::zeros());
        }
    }

    #[test]
    fn mount_offset_moves_ray_origin_and_range_is_kept() {
        let m = MountModel {
            offset_mm: [10.0, -5.0, 30.0],
            tilt_x_deg: 1.0,
            tilt_z_deg: -0.5,
            servo_zero_deg: 2.0,
        };
        let (p, o) = m.beam(1234.0, 17.0, 33.0);
        assert!(((p - o).norm() - 1234.0).abs() < 1e-9);
        assert!((o.norm() - Vector3::<f64>::new(10.0, -5.0, 30.0).norm()).abs() < 1e-9);
        // servo_zero shifts β
        let m0 = MountModel {
            servo_zero_deg: 2.0,
            ..Default::default()
        };
        let (p0, _) = m0.beam(1000.0, 10.0, 12.0);
        let (p1, _) = MountModel::default().beam(1000.0, 10.0, 10.0);
        assert!((p0 - p1).norm() < 1e-9);
    }

    #[test]
    fn cloud_from_scans_skips_no_returns() {
        let h = ScanHeader {
            angle_min_deg: -10.0,
            angle_increment_deg: 10.0,
            mm_per_unit: 1.0,
        };
        let s = ScanLine {
            line: 1,
            stamp_s: 0.0,
            servo_deg: 0.0,
            ranges_mm: vec![1000.0, 0.0, 1000.0],
        };
        let c = Cloud::from_scans(&h, vec![Ok(s)], &MountModel::default()).unwrap();
        assert_eq!(c.len(), 2);
        assert!((c.points[1].y - 1000.0 * 10f64.to_radians().sin()).abs() < 1e-9);
    }
}
