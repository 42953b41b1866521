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
    /// The scans as read (ranges beyond the sensor's maximum masked).
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
        let origin = object_from_camera.transform(&e.translation);
        (self.beams.iter())
            .map(|b| BeamRay {
                origin,
                dir: object_from_camera.rotation * (e.rotation * b.direction()),
                range: (b.range_mm - range[0]) / (1.0 + range[1]),
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
        let name = path.path.display().to_string();
        let (header, lines) = crate::lrf::scan_file(&path.path, l.max_range_mm, rep)?;
        let beams = beams_of(&header, &lines, noise);
        if beams.is_empty() {
            return Err(PipelineError::Input(format!(
                "{name}: no beam with a return in any scan"
            )));
        }
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
