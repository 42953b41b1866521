//! A fixed LRF's stations: each scan file of `[lrf] scans` with its station, the station's
//! main-camera image (whose pose orients the head there) and the scans' beams.

use super::planes::BeamRay;
use crate::adjust::SceneProblem;
use crate::context::{PipelineError, Result};
use crate::ids::ImageId;
use crate::progress::Reporter;
use crate::scene::Scene;
use nalgebra::Vector3;
use pingcal_ba::ImageKey;
use pingcal_geometry::Rigid3;
use pingcal_lrf::fixed::FixedBeam;
use pingcal_lrf::scan::{ScanHeader, ScanLine};
use pingcal_lrf::sensor::RangeNoise;
use pingcal_project::Project;

/// One station of the fixed LRF: its scans and where the head stood.
#[derive(Clone, Debug)]
pub struct Station {
    /// The station's id (`[[images]] station`).
    pub id: String,
    /// The station's image of the main camera.
    pub image: ImageId,
    /// Its pose in the bundle's problem.
    pub key: ImageKey,
    /// Its `camera_from_object` at the bundle's solution.
    pub pose: Rigid3,
    /// The scans' beam geometry.
    pub header: ScanHeader,
    /// The scans as read (ranges beyond the sensor's maximum masked); none when the station's
    /// file is a cloud of 2D points (its `header` then holds no geometry).
    pub lines: Vec<ScanLine>,
    /// Every beam with a return, with its σ at the measured range.
    pub beams: Vec<FixedBeam>,
    /// The sensor's range noise (σ at a range).
    pub noise: RangeNoise,
}

impl Station {
    /// The beams' points in the object frame through the extrinsic `e` and the range model.
    pub fn object_points(&self, e: &Rigid3, range: [f64; 2]) -> Vec<Vector3<f64>> {
        (self.beams.iter())
            .map(|b| b.object_point(&self.pose, e, range))
            .collect()
    }

    /// Its beams' rays in the object frame through the extrinsic `e`, their ranges with the
    /// range model `[k, s]` taken out.
    pub fn rays(&self, e: &Rigid3, range: [f64; 2]) -> Vec<BeamRay> {
        let object_from_camera = self.pose.inverse();
        (self.beams.iter())
            .map(|b| {
                let r = (b.range_mm - range[0]) / (1.0 + range[1]);
                BeamRay::of(&object_from_camera, e, &b.direction(), r)
            })
            .collect()
    }
}

/// The station of every scan file, in the order of `[lrf] scans`, with its beams (σ from
/// `noise`; what was masked is in the log); an error names a scan file whose station's main image the bundle did not
/// orient, or that holds no return.
pub fn read_stations(
    project: &Project,
    scene: &Scene,
    solved: &SceneProblem,
    noise: &RangeNoise,
    rep: &Reporter,
) -> Result<Vec<Station>> {
    let l = &project.file.lrf;
    let mut out = Vec::new();
    for ((entry, path), station) in (l.scans.iter().zip(&project.scans)).zip(l.scan_stations()) {
        let image = station_image(project, station)?;
        let key = solved.map.image(image);
        let (Some(key), Some(pose)) = (key, scene.poses[image]) else {
            return Err(PipelineError::Data(format!(
                "[lrf] scans \"{entry}\": station {station}'s image {} is not oriented: the fixed LRF's scans there cannot be placed",
                project.file.images[image.0].file
            )));
        };
        let (header, lines, beams) = read_beams(project, path, noise, rep)?;
        out.push(Station {
            id: station.to_string(),
            image,
            key,
            pose,
            header,
            lines,
            beams,
            noise: *noise,
        });
    }
    Ok(out)
}

/// The beams of one scan file of `[lrf] scans` (`path`, as the project resolved it): a
/// `pingcal-scan` file's scans, or a cloud's 2D points (its `header` then holds no
/// geometry); each with its σ from `noise`. An error names the file that holds no return.
pub fn read_beams(
    project: &Project,
    path: &pingcal_lrf::cloud_file::CloudPath,
    noise: &RangeNoise,
    rep: &Reporter,
) -> Result<(ScanHeader, Vec<ScanLine>, Vec<FixedBeam>)> {
    let l = &project.file.lrf;
    let name = path.path.display().to_string();
    let (header, lines, beams) = if path.is_scans() {
        let (header, lines) = crate::lrf::scan_file(&path.path, l.max_range_mm, rep)?;
        let beams = beams_of(&header, &lines, noise);
        (header, lines, beams)
    } else {
        // the 2D points of a cloud: beams without the scans' order (no corner there)
        let (cloud, warnings) = (path.read_in(&Default::default(), project.lrf.cloud_unit))
            .map_err(|e| PipelineError::Input(e.to_string()))?;
        for w in warnings {
            rep.log(format!("warning: {w}"));
        }
        let beams = beams_of_points(&cloud, l.max_range_mm, noise)
            .map_err(|why| PipelineError::Input(format!("{name}: {why}")))?;
        let none = ScanHeader {
            angle_min_deg: 0.0,
            angle_increment_deg: 0.0,
            mm_per_unit: 1.0,
            time_increment_s: None,
        };
        (none, Vec::new(), beams)
    };
    if beams.is_empty() {
        return Err(PipelineError::Input(format!(
            "{name}: no beam with a return in any scan"
        )));
    }
    Ok((header, lines, beams))
}

/// The image of the main camera at `station`.
fn station_image(project: &Project, station: &str) -> Result<ImageId> {
    let f = &project.file;
    (f.images.iter())
        .position(|im| im.station == station && im.camera == f.main_camera)
        .map(ImageId)
        .ok_or_else(|| {
            PipelineError::Input(format!(
                "{}: station {station} has no image of the main camera",
                project.path.display()
            ))
        })
}

/// How far a fixed LRF's cloud point may lie off its scan plane (mm): the plane is `z = 0`
/// of the scanner's frame, and a 2D scan's points lie in it exactly (a driver's projection
/// writes z = 0) but for the file's rounding.
pub const SCAN_PLANE_TOLERANCE_MM: f64 = 1.0;

/// The beams of a fixed LRF's cloud of 2D points (the scanner's frame, mm): each point's
/// angle and range in the scan plane, those beyond `max_range_mm` left out; why not when a
/// point lies off the scan plane or a ray does not start at the scanner.
fn beams_of_points(
    cloud: &pingcal_lrf::cloud::Cloud,
    max_range_mm: f64,
    noise: &RangeNoise,
) -> std::result::Result<Vec<FixedBeam>, String> {
    if let Some(origins) = &cloud.origins {
        if let Some((k, o)) =
            (origins.iter().enumerate()).find(|(_, o)| o.norm() > SCAN_PLANE_TOLERANCE_MM)
        {
            return Err(format!(
                "point {} has its ray start at ({:.1}, {:.1}, {:.1}) mm: a fixed LRF's cloud is one station's scans in the scanner's frame, every ray from its centre",
                k + 1, o.x, o.y, o.z
            ));
        }
    }
    let mut beams = Vec::new();
    for (k, x) in cloud.points.iter().enumerate() {
        if x.z.abs() > SCAN_PLANE_TOLERANCE_MM {
            return Err(format!(
                "point {} lies {:.1} mm off the scan plane (z = 0 of the scanner's frame, within {SCAN_PLANE_TOLERANCE_MM} mm): a fixed LRF's cloud holds its scans' 2D points in the scanner's frame",
                k + 1,
                x.z
            ));
        }
        let r = x.x.hypot(x.y);
        if r > 0.0 && r <= max_range_mm {
            beams.push(FixedBeam {
                alpha_rad: x.y.atan2(x.x),
                range_mm: r,
                sigma: noise.sigma(r).max(1.0),
            });
        }
    }
    if beams.is_empty() {
        return Err("no point with a range (every one at the scanner's centre or beyond [lrf] max_range_mm)".into());
    }
    Ok(beams)
}

/// The beams with a return of `lines`, each with its σ.
fn beams_of(header: &ScanHeader, lines: &[ScanLine], noise: &RangeNoise) -> Vec<FixedBeam> {
    let mut beams = Vec::new();
    for line in lines {
        // a v4 file's scan may have a geometry of its own
        let geometry = line.geometry_or(header);
        for (i, &r) in line.ranges_mm.iter().enumerate() {
            if r > 0.0 && r.is_finite() {
                beams.push(FixedBeam {
                    alpha_rad: geometry.beam_angle_deg(i).to_radians(),
                    range_mm: r,
                    sigma: noise.sigma(r).max(1.0),
                });
            }
        }
    }
    beams
}

#[cfg(test)]
mod tests {
    use super::*;
    use pingcal_lrf::cloud::Cloud;

    fn cloud(points: &[[f64; 3]]) -> Cloud {
        Cloud {
            points: points.iter().map(|p| Vector3::from(*p)).collect(),
            origins: None,
            readings: None,
        }
    }

    /// A cloud's 2D points become beams of their angle and range; a point off the scan
    /// plane, or a ray that does not start at the scanner, is refused naming the point.
    #[test]
    fn a_clouds_points_in_the_scan_plane_are_its_beams() {
        let noise = RangeNoise::urg_04lx();
        let beams = beams_of_points(
            &cloud(&[[1000.0, 1000.0, 0.4], [0.0, -500.0, 0.0], [9e9, 0.0, 0.0]]),
            5600.0,
            &noise,
        )
        .expect("beams");
        assert_eq!(
            beams.len(),
            2,
            "the one beyond the maximum range is left out"
        );
        assert!((beams[0].alpha_rad - std::f64::consts::FRAC_PI_4).abs() < 1e-12);
        assert!((beams[0].range_mm - 2f64.sqrt() * 1000.0).abs() < 1e-9);
        assert!((beams[1].alpha_rad + std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        let off = beams_of_points(
            &cloud(&[[1000.0, 0.0, 0.0], [800.0, 10.0, 25.0]]),
            5600.0,
            &noise,
        )
        .expect_err("off the plane");
        assert!(
            off.contains("point 2 lies 25.0 mm off the scan plane"),
            "{off}"
        );
        let mut moved = cloud(&[[1000.0, 0.0, 0.0]]);
        moved.origins = Some(vec![Vector3::new(0.0, 0.0, 300.0)]);
        let why = beams_of_points(&moved, 5600.0, &noise).expect_err("a ray elsewhere");
        assert!(why.contains("point 1 has its ray start"), "{why}");
    }
}
