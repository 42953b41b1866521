//! From scans to a 3D cloud: each valid beam becomes a point through the sensor's beam
//! geometry (paper eq. 2 plus the mount model, [`crate::sensor`]).
//!
//! With a non-zero mount offset the frame origin is the point of the servo axis and each
//! beam starts at `R_β · offset`: the cloud keeps these ray origins, because the along-ray
//! sphere fit needs them. Reading a cloud from a file (scans, PLY or XYZ) is
//! [`crate::cloud_file`].

use crate::error::Result;
use crate::scan::{ScanHeader, ScanLine};
use crate::sensor::ScannerPose;
pub use crate::sensor::{servo_rotation, MountModel};
use nalgebra::Vector3;
use rayon::prelude::*;

/// Readings per parallel task of [`Cloud::through`].
pub const THROUGH_CHUNK: usize = 1 << 14;

/// A point cloud in the LRF frame (mm), with the ray origin of each point when it is not
/// the frame origin.
#[derive(Debug, Clone, Default)]
pub struct Cloud {
    /// The points, mm.
    pub points: Vec<Vector3<f64>>,
    /// Ray origin of each point; `None` means every ray starts at (0, 0, 0).
    pub origins: Option<Vec<Vector3<f64>>>,
    /// The reading each point came from, when the cloud was made from scans (`None` for
    /// PLY / XYZ clouds): what the joint adjustment re-projects through an estimated mount.
    pub readings: Option<Vec<BeamReading>>,
}

/// One beam as the sensor reported it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BeamReading {
    /// Servo reading, degrees.
    pub servo_deg: f64,
    /// Beam angle α, radians.
    pub alpha_rad: f64,
    /// Reported range, mm.
    pub range_mm: f64,
    /// How fast the servo turned at this beam, degrees per second: 0 in a stop-and-go
    /// sweep, and where the scan file does not give the time between beams
    /// (`# time_increment_s=`); see [`BeamReading::servo_deg_through`].
    pub servo_rate_deg_s: f64,
}

impl BeamReading {
    /// A beam of a servo at rest.
    pub fn at_rest(servo_deg: f64, alpha_rad: f64, range_mm: f64) -> Self {
        BeamReading {
            servo_deg,
            alpha_rad,
            range_mm,
            servo_rate_deg_s: 0.0,
        }
    }

    /// The servo angle at this beam through the mount's servo time offset
    /// ([`MountModel::servo_time_offset_s`]): the reading plus the rate times the offset
    /// (the reading is the angle the servo had that much earlier). The reading itself in a
    /// stop-and-go sweep.
    pub fn servo_deg_through(&self, mount: &MountModel) -> f64 {
        let turn = self.servo_rate_deg_s * mount.servo_time_offset_s;
        // the reading itself, to the bit, where nothing turns it (a −0° stays −0°)
        if turn == 0.0 {
            self.servo_deg
        } else {
            self.servo_deg + turn
        }
    }
}

/// The servo's rate during a continuous-sweep scan (degrees per second): its advance from
/// the first beam to the last over the time between them; 0 for a stop-and-go scan or when
/// the header does not give the time between beams.
fn servo_rate_deg_s(header: &ScanHeader, scan: &ScanLine) -> f64 {
    let (Some(end), Some(dt)) = (scan.servo_end_deg, header.time_increment_s) else {
        return 0.0;
    };
    // a negative time between beams (v4: measured from the last beam to the first) gives
    // the rate its sign
    let span_s = dt * scan.ranges_mm.len().saturating_sub(1) as f64;
    if span_s != 0.0 {
        (end - scan.servo_deg) / span_s
    } else {
        0.0
    }
}

impl Cloud {
    /// A cloud of points seen from the origin (PLY/XYZ files).
    pub fn from_points(points: Vec<Vector3<f64>>) -> Self {
        Cloud {
            points,
            origins: None,
            readings: None,
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

    /// Appends the valid beams of one scan (eq. 2 + mount), each at its own servo angle
    /// ([`ScanLine::servo_deg_at`]: constant for a stop-and-go scan), in the scan's own beam
    /// geometry where it has one ([`ScanLine::geometry`]), else the file's `header`.
    pub fn push_scan(&mut self, header: &ScanHeader, scan: &ScanLine, mount: &MountModel) {
        let header = &scan.geometry_or(header);
        if self.readings.is_none() && self.points.is_empty() {
            self.readings = Some(Vec::new());
        }
        let keep_origins = !mount.is_identity();
        if keep_origins && self.origins.is_none() {
            self.origins = Some(vec![Vector3::zeros(); self.points.len()]);
        }
        let sweep = scan.is_sweep();
        let rate = servo_rate_deg_s(header, scan);
        let mut pose = mount.scanner_at(scan.servo_deg);
        for (i, &r) in scan.ranges_mm.iter().enumerate() {
            if r <= 0.0 {
                continue;
            }
            let reading = BeamReading {
                servo_deg: scan.servo_deg_at(i),
                alpha_rad: header.beam_angle_deg(i).to_radians(),
                range_mm: r,
                servo_rate_deg_s: rate,
            };
            if sweep {
                pose = mount.scanner_at(reading.servo_deg_through(mount));
            }
            self.points.push(pose.point(r, reading.alpha_rad));
            if let Some(rs) = self.readings.as_mut() {
                rs.push(reading);
            }
            if let Some(os) = self.origins.as_mut() {
                os.push(pose.origin());
            }
        }
    }

    /// The same beams through another mount (an estimated one): each reading's point and
    /// ray origin again. None for a cloud without readings (PLY, PCD, XYZ files).
    ///
    /// The beams of a scan share a servo reading, so the scanner's pose is computed once
    /// per run of equal readings (bit for bit the pose each beam would get on its own), and
    /// the readings are split into chunks of [`THROUGH_CHUNK`] worked on in parallel: a
    /// million-beam cloud is made again several times per calibration.
    pub fn through(&self, mount: &MountModel) -> Option<Cloud> {
        let readings = self.readings.as_ref()?;
        let (points, origins) = readings
            .par_chunks(THROUGH_CHUNK)
            .flat_map_iter(|chunk| {
                let mut last: Option<(u64, ScannerPose)> = None;
                chunk.iter().map(move |r| {
                    let servo = r.servo_deg_through(mount);
                    let pose = match last {
                        Some((bits, pose)) if bits == servo.to_bits() => pose,
                        _ => {
                            let pose = mount.scanner_at(servo);
                            last = Some((servo.to_bits(), pose));
                            pose
                        }
                    };
                    (pose.point(r.range_mm, r.alpha_rad), pose.origin())
                })
            })
            .unzip();
        Some(Cloud {
            points,
            origins: Some(origins),
            readings: Some(readings.clone()),
        })
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

    /// Removes every point whose range (the reading's, or the distance from its ray's
    /// origin for a cloud without readings) is beyond `max_range_mm`, the sensor's maximum;
    /// how many were removed.
    pub fn mask_beyond(&mut self, max_range_mm: f64) -> usize {
        let keep: Vec<bool> = (0..self.len())
            .map(|i| {
                let r = match &self.readings {
                    Some(rs) => rs[i].range_mm,
                    None => (self.points[i] - self.origin(i)).norm(),
                };
                r <= max_range_mm
            })
            .collect();
        let removed = keep.iter().filter(|k| !**k).count();
        if removed > 0 {
            let mut k = keep.iter();
            self.points
                .retain(|_| *k.next().expect("one flag per point"));
            if let Some(o) = &mut self.origins {
                let mut k = keep.iter();
                o.retain(|_| *k.next().expect("one flag per point"));
            }
            if let Some(r) = &mut self.readings {
                let mut k = keep.iter();
                r.retain(|_| *k.next().expect("one flag per point"));
            }
        }
        removed
    }

    /// Appends another cloud.
    pub fn extend(&mut self, other: Cloud) {
        self.readings = match (self.readings.take(), other.readings) {
            (Some(mut a), Some(b)) => {
                a.extend(b);
                Some(a)
            }
            (a, None) if other.points.is_empty() => a,
            (None, b) if self.points.is_empty() => b,
            _ => None,
        };
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cloud_from_scans_skips_no_returns() {
        let h = ScanHeader {
            angle_min_deg: -10.0,
            angle_increment_deg: 10.0,
            mm_per_unit: 1.0,
            time_increment_s: None,
        };
        let s = ScanLine {
            line: 1,
            stamp_s: 0.0,
            servo_deg: 0.0,
            servo_end_deg: None,
            ranges_mm: vec![1000.0, 0.0, 1000.0],
            intensities: vec![],
            geometry: None,
        };
        let c = Cloud::from_scans(&h, vec![Ok(s)], &MountModel::default()).unwrap();
        assert_eq!(c.len(), 2);
        assert!((c.points[1].y - 1000.0 * 10f64.to_radians().sin()).abs() < 1e-9);
    }

    /// A continuous sweep's beams carry the servo's rate (its advance over the scan's time
    /// between first and last beam), and a mount's servo time offset turns each by rate ×
    /// offset, in the cloud made from the scans and in the cloud made again through it.
    #[test]
    fn a_servo_time_offset_turns_a_continuous_sweeps_beams_by_the_rate_times_it() {
        let h = ScanHeader {
            angle_min_deg: -10.0,
            angle_increment_deg: 10.0,
            mm_per_unit: 1.0,
            time_increment_s: Some(0.01),
        };
        let s = ScanLine {
            line: 1,
            stamp_s: 0.0,
            servo_deg: 10.0,
            servo_end_deg: Some(10.5),
            ranges_mm: vec![1000.0, 1200.0, 1400.0],
            intensities: vec![],
            geometry: None,
        };
        let mount = MountModel {
            offset_mm: [5.0, 1.0, -3.0],
            servo_time_offset_s: 0.02,
            ..MountModel::default()
        };
        let c = Cloud::from_scans(&h, vec![Ok(s.clone())], &mount).unwrap();
        let readings = c.readings.as_ref().unwrap();
        for (i, r) in readings.iter().enumerate() {
            // 0.5° over the 0.02 s from the first beam to the last: 25°/s, so 0.5° later
            assert!((r.servo_rate_deg_s - 25.0).abs() < 1e-12, "{r:?}");
            let turned = s.servo_deg_at(i) + 0.5;
            let want = mount.scanner_at(turned).point(r.range_mm, r.alpha_rad);
            assert!((c.points[i] - want).norm() < 1e-9, "beam {i}");
        }
        let again = Cloud::from_scans(&h, vec![Ok(s)], &MountModel::default())
            .unwrap()
            .through(&mount)
            .unwrap();
        for (a, b) in again.points.iter().zip(&c.points) {
            assert!((a - b).norm() < 1e-9);
        }
        // a stop-and-go scan has no rate: the offset changes nothing
        let rest = ScanLine {
            line: 2,
            stamp_s: 0.1,
            servo_deg: 11.0,
            servo_end_deg: None,
            ranges_mm: vec![1000.0],
            intensities: vec![],
            geometry: None,
        };
        let c = Cloud::from_scans(&h, vec![Ok(rest)], &mount).unwrap();
        let p0 = mount.scanner_at(11.0).point(1000.0, (-10f64).to_radians());
        assert!((c.points[0] - p0).norm() < 1e-12);
    }

    /// The cloud made again through a mount is, bit for bit, each beam's point and origin
    /// through that mount on its own: across chunk boundaries, with runs of equal servo
    /// readings cut by a chunk, and with beams of a continuous sweep (each at its own angle)
    /// between those of a stop-and-go one.
    #[test]
    fn a_cloud_made_again_is_each_beams_own_point_bit_for_bit() {
        let mount = crate::sensor::tests::random_mount(&mut pingcal_geometry::consensus::rng(7));
        let n = 2 * THROUGH_CHUNK + 777;
        let readings: Vec<BeamReading> = (0..n)
            .map(|i| BeamReading {
                // runs of 500 beams at one servo reading, a chunk boundary inside some
                servo_deg: (i / 500) as f64 * 0.35,
                alpha_rad: ((i % 500) as f64 * 0.5 - 120.0).to_radians(),
                range_mm: 800.0 + (i % 97) as f64 * 13.0,
                // every third run a continuous sweep
                servo_rate_deg_s: if (i / 500) % 3 == 0 { 20.0 } else { 0.0 },
            })
            .collect();
        let cloud = Cloud {
            points: vec![Vector3::zeros(); n],
            origins: None,
            readings: Some(readings.clone()),
        };
        let again = cloud.through(&mount).unwrap();
        let origins = again.origins.as_ref().unwrap();
        assert_eq!((again.points.len(), origins.len()), (n, n));
        for (i, r) in readings.iter().enumerate() {
            let pose = mount.scanner_at(r.servo_deg_through(&mount));
            assert_eq!(
                again.points[i],
                pose.point(r.range_mm, r.alpha_rad),
                "beam {i}"
            );
            assert_eq!(origins[i], pose.origin(), "beam {i}");
        }
        assert_eq!(again.readings.as_deref(), Some(&readings[..]));
    }

    #[test]
    fn points_beyond_the_maximum_range_are_removed_with_their_origins_and_readings() {
        let h = ScanHeader {
            angle_min_deg: -10.0,
            angle_increment_deg: 10.0,
            mm_per_unit: 1.0,
            time_increment_s: None,
        };
        let s = ScanLine {
            line: 1,
            stamp_s: 0.0,
            servo_deg: 30.0,
            servo_end_deg: None,
            ranges_mm: vec![1000.0, 9000.0, 2000.0],
            intensities: Vec::new(),
            geometry: None,
        };
        let mount = MountModel {
            offset_mm: [5.0, 0.0, 0.0],
            ..MountModel::default()
        };
        let mut c = Cloud::from_scans(&h, vec![Ok(s)], &mount).unwrap();
        let (p0, p2) = (c.points[0], c.points[2]);
        assert_eq!(c.mask_beyond(5600.0), 1);
        assert_eq!(c.points, vec![p0, p2]);
        assert_eq!(c.origins.as_ref().unwrap().len(), 2);
        let r: Vec<f64> = c.readings.unwrap().iter().map(|r| r.range_mm).collect();
        assert_eq!(r, vec![1000.0, 2000.0]);
        let mut p = Cloud::from_points(vec![Vector3::new(3000.0, 4000.0, 0.0), Vector3::x()]);
        assert_eq!(p.mask_beyond(4999.0), 1);
        assert_eq!(p.points, vec![Vector3::x()]);
    }

    #[test]
    fn a_sweep_gives_each_beam_its_own_servo_angle() {
        let h = ScanHeader {
            angle_min_deg: 0.0,
            angle_increment_deg: 0.0001,
            mm_per_unit: 1.0,
            time_increment_s: None,
        };
        let s = ScanLine {
            line: 1,
            stamp_s: 0.0,
            servo_deg: 0.0,
            servo_end_deg: Some(90.0),
            ranges_mm: vec![1000.0, 1000.0, 1000.0],
            intensities: vec![],
            geometry: None,
        };
        let mount = MountModel::default();
        let c = Cloud::from_scans(&h, vec![Ok(s.clone())], &mount).unwrap();
        let servo: Vec<f64> = c.readings.unwrap().iter().map(|r| r.servo_deg).collect();
        assert_eq!(servo, vec![0.0, 45.0, 90.0]);
        for (i, p) in c.points.iter().enumerate() {
            let one = ScanLine {
                servo_deg: s.servo_deg_at(i),
                servo_end_deg: None,
                ranges_mm: (0..3).map(|k| if k == i { 1000.0 } else { 0.0 }).collect(),
                intensities: vec![],
                geometry: None,
                ..s.clone()
            };
            let q = Cloud::from_scans(&h, vec![Ok(one)], &mount).unwrap().points[0];
            assert_eq!(*p, q);
        }
        assert!((c.points[0] - c.points[2]).norm() > 1000.0);
    }
}
