//! Step 5: the LRF cloud and its spheres.
//!
//! Every scan file of `[lrf] scans` is read (`pingcal-scan` CSV through the mount model of
//! the project, or a PLY / XYZ cloud already in the LRF frame) into one cloud; the balls are
//! found and fitted by [`pingcal_lrf::ball_finder`] with the ball diameter of the project and
//! the range noise the project resolved at load ([`pingcal_project::LrfSettings`]: a named
//! profile, σ = a + b·r, or the datasheet accuracies taken as 3σ). Every file of `scans` was
//! classified at load (scan file or cloud) and is read as such. Scan files are read once:
//! their lines make the cloud and are kept for the corner baseline. The bags of
//! `[lrf.bag]` are read as `pingcal scans` reads them ([`pingcal_rosbag::assemble`]), and
//! their scans join the cloud in the same way. Ranges beyond the sensor's `[lrf]
//! max_range_mm` (and a scan file's ranges beyond any range finder) are masked as no return
//! and counted in a warning naming the file and the first line.

use crate::context::{Options, PipelineError, Result};
use crate::progress::Reporter;
use pingcal_lrf::ball_finder::{find_balls, find_walls, FindResult, FinderOptions};
use pingcal_lrf::cloud::{Cloud, MountModel};
use pingcal_lrf::cloud_file::{masked_warning, non_empty, CloudPath};
use pingcal_lrf::room::{mount_from_room_refinding, room_finder, RoomMount, RoomOptions};
use pingcal_lrf::scan::{mask_lines_beyond, open_scan_file, ScanHeader, ScanLine};
use pingcal_lrf::sensor::{MountParam, RangeNoise};
use pingcal_project::{BagServo, Project, ProjectBag};
use pingcal_rosbag::assemble::{read_scans, Topics};

/// Rejected clusters smaller than this are counted, not listed one by one (a 38 mm ball
/// at 1.5 m gives well over 100 points in a slow sweep).
pub const MIN_REPORTED_CLUSTER: usize = 20;

/// The LRF side.
pub struct LrfData {
    /// The cloud (LRF frame, mm).
    pub cloud: Cloud,
    /// The spheres found, and what was rejected.
    pub found: FindResult,
    /// The scan lines of the first CSV scan file (for the corner baseline), if any.
    pub scans: Option<(ScanHeader, Vec<ScanLine>)>,
    /// The mount model used.
    pub mount: MountModel,
    /// The noise model used.
    pub noise: RangeNoise,
}

/// "beyond the sensor's max_range_mm = …", for the warnings of masked ranges.
fn beyond(max_range_mm: f64) -> String {
    format!("beyond the sensor's [lrf] max_range_mm = {max_range_mm}")
}

/// The scans of the `[lrf.bag]` bags, with the servo held or interpolated as `servo_motion`
/// says (absent: told from the data), in runs of one beam geometry (a driver may change it
/// between messages: each scan keeps its own); what was skipped or masked, and the motion
/// used, are in the log.
fn bag_scans(
    project: &Project,
    bag: &ProjectBag,
    servo: &BagServo,
    rep: &Reporter,
) -> Result<Vec<(ScanHeader, Vec<ScanLine>)>> {
    let err = |e: pingcal_rosbag::RosbagError| PipelineError::Input(e.to_string());
    let mut bags = Vec::new();
    for p in &project.bag_paths {
        for f in pingcal_rosbag::bag_files(p).map_err(err)? {
            bags.push(pingcal_rosbag::Bag::open(&f).map_err(err)?);
        }
    }
    let topics = Topics {
        scan: bag.scan_topic.clone(),
        servo: bag.servo_topic.clone(),
        source: servo.source.clone(),
        stamps: servo.stamps,
    };
    let mut runs: Vec<(ScanHeader, Vec<ScanLine>)> = Vec::new();
    let done = read_scans(&bags, &topics, servo.motion, &mut |h, l| {
        match runs.last_mut() {
            Some((last, lines)) if last == h && lines[0].ranges_mm.len() == l.ranges_mm.len() => {
                lines.push(l)
            }
            _ => runs.push((*h, vec![l])),
        }
        Ok(())
    })
    .map_err(err)?;
    for note in done.notes() {
        rep.log(format!("[lrf.bag] topic {}: {note}", topics.scan));
    }
    if runs.is_empty() {
        return Err(PipelineError::Input(format!(
            "[lrf.bag] topic {}: no scan lies within the servo messages",
            topics.scan
        )));
    }
    Ok(runs)
}

/// Reads the scans and finds the spheres.
pub fn lrf_spheres(project: &Project, opts: &Options, rep: &Reporter) -> Result<LrfData> {
    let l = &project.file.lrf;
    let mount = project.lrf.mount;
    let pb = rep.task("LRF cloud and spheres", project.scans.len() as u64 + 1);
    let mut cloud = Cloud::default();
    let mut scans = None;
    for file in &project.scans {
        if file.is_scans() {
            // read once: the lines make the cloud and are kept for the corner baseline
            let (header, lines) = scan_file(&file.path, l.max_range_mm, rep)?;
            let mut c = Cloud::default();
            for line in &lines {
                c.push_scan(&header, line, &mount);
            }
            let err = |e: pingcal_lrf::LrfError| PipelineError::Input(e.to_string());
            cloud.extend(non_empty(c, &file.path).map_err(err)?);
            if scans.is_none() {
                scans = Some((header, lines));
            }
        } else {
            cloud.extend(cloud_file(file, project, rep)?);
        }
        pb.advance(1);
    }
    if let (Some(bag), Some(servo)) = (&l.bag, &project.lrf.bag) {
        for (header, mut lines) in bag_scans(project, bag, servo, rep)? {
            let masked = mask_lines_beyond(&mut lines, l.max_range_mm);
            if masked.count > 0 {
                rep.log(format!(
                    "warning: [lrf.bag] topic {}: {} ranges {} masked as no return",
                    bag.scan_topic,
                    masked.count,
                    beyond(l.max_range_mm)
                ));
            }
            for line in &lines {
                cloud.push_scan(&header, line, &mount);
            }
            // the corner baseline reads one geometry: the first run's
            if scans.is_none() {
                scans = Some((header, lines));
            }
        }
    }
    pb.finish();
    let noise = project.lrf.noise;
    Ok(spheres_in(project, cloud, scans, mount, noise, opts, rep))
}

/// The header and lines of the scan file `path`, its ranges beyond `max_range_mm` (and
/// beyond any range finder) masked, with warnings.
pub(crate) fn scan_file(
    path: &std::path::Path,
    max_range_mm: f64,
    rep: &Reporter,
) -> Result<(ScanHeader, Vec<ScanLine>)> {
    let err = |e: pingcal_lrf::LrfError| PipelineError::Input(e.to_string());
    let mut reader = open_scan_file(path).map_err(err)?;
    let header = reader.header();
    let mut lines = reader
        .by_ref()
        .collect::<std::result::Result<Vec<_>, _>>()
        .map_err(err)?;
    if let Some(w) = masked_warning(path, &reader.masked()) {
        rep.log(format!("warning: {w}"));
    }
    let masked = mask_lines_beyond(&mut lines, max_range_mm);
    if masked.count > 0 {
        rep.log(format!(
            "warning: {}: {}",
            path.display(),
            masked.describe(&beyond(max_range_mm))
        ));
    }
    Ok((header, lines))
}

/// The cloud of a cloud file of `[lrf] scans` (PLY, PCD, XYZ) in the project's unit, its
/// points beyond `max_range_mm` masked, with warnings.
fn cloud_file(file: &CloudPath, project: &Project, rep: &Reporter) -> Result<Cloud> {
    let err = |e: pingcal_lrf::LrfError| PipelineError::Input(e.to_string());
    let (mut c, warnings) = file
        .read_in(&project.lrf.mount, project.lrf.cloud_unit)
        .map_err(err)?;
    for w in warnings {
        rep.log(format!("warning: {w}"));
    }
    let max = project.file.lrf.max_range_mm;
    let n = c.mask_beyond(max);
    if n > 0 {
        rep.log(format!(
            "warning: {}: {n} point(s) {} masked",
            file.path.display(),
            beyond(max)
        ));
    }
    Ok(c)
}

/// The LRF's mount from the room's planes ([`pingcal_lrf::room`]): the walls the ball finder
/// removed from `lrf`'s cloud, seen from both half-sweeps, fitted so that each is one
/// plane, starting from the project's mount; the parameters the project asks for, those the
/// room does not determine held and named. None (and the reason in the log) when the
/// project turns it off (`[lrf] room_planes = false`), asks for no mount parameter, the
/// cloud has no readings, or the room determines none of them.
pub fn room_mount(
    project: &Project,
    lrf: &LrfData,
    seed: u64,
    rep: &Reporter,
) -> Option<RoomMount> {
    let l = &project.file.lrf;
    if l.room_planes == Some(false) || lrf.cloud.readings.is_none() {
        return None;
    }
    let mut estimate = [false; 8];
    for p in l.self_calibrated() {
        estimate[p.index()] = true;
    }
    if !estimate.iter().any(|&e| e) {
        return None;
    }
    let opts = RoomOptions {
        noise: lrf.noise,
        estimate,
        ..RoomOptions::default()
    };
    let finder = FinderOptions {
        diameter_mm: project.file.balls.diameter_mm,
        noise: lrf.noise,
        seed,
        ..FinderOptions::default()
    };
    // the planes the ball finder removed; where it found none (a nodding scanner's sweep
    // holds each wall in a band, narrower than the ball finder's walls), the room's own
    // search ([`room_finder`]), as `pingcal lrf-mount` searches
    let (walls, finder) = if lrf.found.planes.is_empty() {
        let room = room_finder(finder);
        (find_walls(&lrf.cloud, &room), room)
    } else {
        (lrf.found.planes.clone(), finder)
    };
    let find = |c: &Cloud| find_walls(c, &finder);
    match mount_from_room_refinding(&lrf.cloud, &walls, &lrf.mount, &opts, find) {
        Ok(r) => {
            rep.log(format!("LRF mount from the room: {}", describe_room(&r)));
            r.parameters.iter().any(|p| p.sigma.is_some()).then_some(r)
        }
        Err(e) => {
            rep.log(format!("LRF mount from the room: not found ({e})"));
            None
        }
    }
}

/// One line: the planes, the fit, every parameter with its σ or why it is held.
pub fn describe_room(r: &RoomMount) -> String {
    let params: Vec<String> = r
        .parameters
        .iter()
        .map(|p| {
            let u = MountParam::named(p.name).map_or(" mm", MountParam::unit);
            match p.sigma {
                Some(s) => format!("{} {:.4} ± {:.4}{u}", p.name, p.value, s),
                None => format!("{} held", p.name),
            }
        })
        .collect();
    format!(
        "{} planes{}, {} beams ({} rejected), sigma0 {:.3}; {}",
        r.planes.len(),
        if r.wall_searches > 1 {
            format!(
                " (found again through the estimate, search {})",
                r.wall_searches
            )
        } else {
            String::new()
        },
        r.beams,
        r.rejected,
        r.sigma0,
        params.join(", ")
    )
}

/// The spheres of `lrf`'s beams seen through another mount (the joint adjustment's
/// estimate): the cloud made again from the readings, and the balls found in it. None for a
/// cloud without readings.
pub fn through_mount(
    project: &Project,
    lrf: &LrfData,
    mount: MountModel,
    opts: &Options,
    rep: &Reporter,
) -> Option<LrfData> {
    let cloud = lrf.cloud.through(&mount)?;
    Some(spheres_in(
        project,
        cloud,
        lrf.scans.clone(),
        mount,
        lrf.noise,
        opts,
        rep,
    ))
}

/// The balls found in `cloud` (made through `mount`), logged.
fn spheres_in(
    project: &Project,
    cloud: Cloud,
    scans: Option<(ScanHeader, Vec<ScanLine>)>,
    mount: MountModel,
    noise: RangeNoise,
    opts: &Options,
    rep: &Reporter,
) -> LrfData {
    let found = find_balls(
        &cloud,
        &FinderOptions {
            diameter_mm: project.file.balls.diameter_mm,
            noise,
            seed: opts.seed,
            // the joint adjustment estimates the mount: a ball that a wrong mount shows
            // twice is kept for its beams to correct it
            keep_seen_twice: project.file.method.joint(),
            ..FinderOptions::default()
        },
    );
    let mut s0: Vec<f64> = found.balls.iter().map(|b| b.sigma0).collect();
    s0.sort_by(|a, b| a.total_cmp(b));
    let mut inl: Vec<usize> = found.balls.iter().map(|b| b.inliers.len()).collect();
    inl.sort_unstable();
    rep.log(format!(
        "LRF: {} points from {} file(s); {} spheres fitted ({} to {} beams each, fit sigma0 {:.2} to {:.2}, median {:.2}), {} clusters rejected",
        cloud.len(),
        project.scans.len(),
        found.balls.len(),
        inl.first().copied().unwrap_or(0),
        inl.last().copied().unwrap_or(0),
        s0.first().copied().unwrap_or(f64::NAN),
        s0.last().copied().unwrap_or(f64::NAN),
        s0.get(s0.len() / 2).copied().unwrap_or(f64::NAN),
        found.rejected.len()
    ));
    // small clusters (plane-removal leftovers at edges and targets) are many and dull:
    // the log names only those large enough to have been a ball; the report lists all
    for r in found
        .rejected
        .iter()
        .filter(|r| r.cluster_points >= MIN_REPORTED_CLUSTER)
    {
        rep.log(format!(
            "  LRF cluster of {} points at ({:.0}, {:.0}, {:.0}) mm rejected: {}",
            r.cluster_points, r.centre.x, r.centre.y, r.centre.z, r.reason
        ));
    }
    LrfData {
        cloud,
        found,
        scans,
        mount,
        noise,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A project reading the rosbags-written fixture `name` of `crates/rosbag/tests/data`.
    fn project_with_bag(name: &str, bag: ProjectBag) -> Project {
        let mut file = crate::test_support::readme_project_file();
        file.lrf.bag = Some(bag);
        let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../rosbag/tests/data");
        crate::test_support::project(file, vec![data.join(name)])
    }

    /// The scans of the bags of `p`.
    fn scans_of(p: &Project) -> Vec<(ScanHeader, Vec<ScanLine>)> {
        let (bag, servo) = (p.file.lrf.bag.as_ref(), p.lrf.bag.as_ref());
        bag_scans(p, bag.unwrap(), servo.unwrap(), &Reporter::silent()).unwrap()
    }

    fn bag(servo_topic: &str) -> ProjectBag {
        ProjectBag {
            files: vec!["fixture".into()],
            scan_topic: "/scan".into(),
            servo_topic: servo_topic.into(),
            servo_joint: None,
            servo_scale: None,
            servo_offset: None,
            servo_tf_child: None,
            servo_axis: None,
            servo_motion: None,
            stamps: None,
        }
    }

    /// `[lrf.bag]` with the servo from tf (the fixture's `servo_link` turns about y as the
    /// joint does) gives the JointState's scans; a geometry change keeps every scan.
    #[test]
    fn a_project_bag_reads_the_servo_from_tf_and_keeps_each_geometry() {
        let joint = project_with_bag(
            "ros1.bag",
            ProjectBag {
                servo_joint: Some("servo".into()),
                ..bag("/joint_states")
            },
        );
        let tf = project_with_bag(
            "ros1.bag",
            ProjectBag {
                servo_tf_child: Some("servo_link".into()),
                servo_axis: Some([0.0, 2.0, 0.0]),
                ..bag("/tf")
            },
        );
        let (a, b) = (scans_of(&joint), scans_of(&tf));
        assert_eq!((a.len(), b.len()), (1, 1));
        assert_eq!(a[0].0, b[0].0);
        assert_eq!(a[0].1.len(), 5);
        for (x, y) in a[0].1.iter().zip(&b[0].1) {
            assert_eq!(x.ranges_mm, y.ranges_mm);
            assert!(
                (x.servo_deg - y.servo_deg).abs() < 1e-6,
                "{} {}",
                x.servo_deg,
                y.servo_deg
            );
        }
        let g = project_with_bag(
            "geometry.bag",
            ProjectBag {
                servo_joint: Some("servo".into()),
                ..bag("/joint_states")
            },
        );
        let runs = scans_of(&g);
        let sizes: Vec<(usize, usize)> = runs
            .iter()
            .map(|(_, l)| (l.len(), l[0].ranges_mm.len()))
            .collect();
        assert_eq!(sizes, [(2, 10), (1, 11), (1, 10), (1, 10)]);
        assert_eq!(runs[3].0.angle_min_deg, -5.0);
    }
}
