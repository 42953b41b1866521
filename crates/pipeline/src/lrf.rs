//! Step 5: the LRF cloud and its spheres.
//!
//! Every scan file of `[lrf] scans` is read (`pingcal-scan` CSV through the mount model of
//! the project, or a PLY / XYZ cloud already in the LRF frame) into one cloud; the balls are
//! found and fitted by [`pingcal_lrf::ball_finder`] with the ball diameter of the project and
//! the URG noise model from the datasheet accuracies (taken as 3σ). Scan files are read once:
//! their lines make the cloud and are kept for the corner baseline. The bags of
//! `[lrf.bag]` are read as `pingcal scans` reads them ([`pingcal_rosbag::assemble`]), and
//! their scans join the cloud in the same way. Ranges beyond the sensor's `[lrf]
//! max_range_mm` (and a scan file's ranges beyond any range finder) are masked as no return
//! and counted in a warning naming the file and the first line.

use crate::context::{Options, PipelineError, Result};
use crate::progress::Reporter;
use pingcal_lrf::ball_finder::{find_balls, find_walls, FindResult, FinderOptions};
use pingcal_lrf::cloud::{Cloud, MountModel};
use pingcal_lrf::cloud_file::{
    file_kind, masked_warning, non_empty, read_cloud_file_in, read_lrf_model, CloudFileKind,
    CloudUnit,
};
use pingcal_lrf::room::{mount_from_room_refinding, RoomMount, RoomOptions};
use pingcal_lrf::scan::{mask_lines_beyond, open_scan_file, ScanHeader, ScanLine};
use pingcal_lrf::sensor::{MountParam, RangeNoise};
use pingcal_project::{Project, ProjectBag, ProjectLrf};
use pingcal_rosbag::assemble::{read_scans, ServoMotion, ServoSource, Topics};

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

/// Refuses a mount of `[lrf]` beyond the bounds of any mount ([`MountModel::check`]), before
/// any work: a value such as 1e308 would otherwise run the whole pipeline into an unrelated
/// failure.
pub fn check_mount(project: &Project) -> Result<()> {
    check_lrf_mount(&project.file.lrf)
        .map_err(|e| PipelineError::Input(format!("{}: {e}", project.path.display())))
}

/// [`check_mount`] of an `[lrf]` table: the error names the entry, not the file.
pub fn check_lrf_mount(l: &ProjectLrf) -> std::result::Result<(), pingcal_lrf::LrfError> {
    mount_of_lrf(l)
        .check([
            "mount_offset_mm",
            "mount_tilt_x_deg",
            "mount_tilt_z_deg",
            "servo_zero_deg",
            "servo_scale",
            "range_offset_mm",
            "range_scale",
        ])
        .map_err(|e| pingcal_lrf::LrfError::Invalid(format!("[lrf] {e}")))
}

/// The mount model of the project: its `[lrf] lrf_model` file's, or its `mount_*` and
/// `servo_zero_deg` keys'.
pub fn mount_of(project: &Project) -> Result<MountModel> {
    if let Some(path) = &project.lrf_model_path {
        return read_lrf_model(path).map_err(|e| {
            PipelineError::Input(format!("{}: [lrf] lrf_model: {e}", project.path.display()))
        });
    }
    Ok(mount_of_lrf(&project.file.lrf))
}

/// The mount model of an `[lrf]` table.
fn mount_of_lrf(l: &ProjectLrf) -> MountModel {
    MountModel {
        offset_mm: l.mount_offset_mm,
        tilt_x_deg: l.mount_tilt_x_deg,
        tilt_z_deg: l.mount_tilt_z_deg,
        servo_zero_deg: l.servo_zero_deg,
        ..MountModel::default()
    }
}

/// The scans of the `[lrf.bag]` bags, with the servo held or interpolated as `servo_motion`
/// says (absent: told from the data), in runs of one beam geometry (a driver may change it
/// between messages: each scan keeps its own); what was skipped or masked, and the motion
/// used, are in the log.
fn bag_scans(
    project: &Project,
    bag: &ProjectBag,
    rep: &Reporter,
) -> Result<Vec<(ScanHeader, Vec<ScanLine>)>> {
    let err = |e: pingcal_rosbag::RosbagError| PipelineError::Input(e.to_string());
    let mut bags = Vec::new();
    for p in &project.bag_paths {
        for f in pingcal_rosbag::bag_files(p).map_err(err)? {
            bags.push(pingcal_rosbag::Bag::open(&f).map_err(err)?);
        }
    }
    let source = match (&bag.servo_joint, &bag.servo_tf_child) {
        (Some(j), _) => ServoSource::Joint(j.clone()),
        (None, Some(child)) => {
            let a = bag.servo_axis.unwrap_or([0.0, 1.0, 0.0]);
            let n = a.iter().map(|v| v * v).sum::<f64>().sqrt();
            ServoSource::Tf {
                child: child.clone(),
                axis: a.map(|v| v / n),
            }
        }
        (None, None) => ServoSource::Numeric {
            scale: bag.servo_scale.unwrap_or(1.0),
            offset: bag.servo_offset.unwrap_or(0.0),
        },
    };
    let topics = Topics {
        scan: bag.scan_topic.clone(),
        servo: bag.servo_topic.clone(),
        source,
    };
    let motion = ServoMotion::parse(bag.servo_motion.as_deref().unwrap_or("auto"))
        .map_err(|e| PipelineError::Input(format!("[lrf.bag] {e}")))?;
    let mut runs: Vec<(ScanHeader, Vec<ScanLine>)> = Vec::new();
    let done = read_scans(&bags, &topics, motion, &mut |h, l| {
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
    let mount = mount_of(project)?;
    let pb = rep.task("LRF cloud and spheres", project.scan_paths.len() as u64 + 1);
    let mut cloud = Cloud::default();
    let mut scans = None;
    for path in &project.scan_paths {
        let err = |e: pingcal_lrf::LrfError| PipelineError::Input(e.to_string());
        if file_kind(path) == CloudFileKind::Scans {
            // read once: the lines make the cloud and are kept for the corner baseline
            let mut reader = open_scan_file(path).map_err(err)?;
            let header = reader.header();
            let mut lines = reader
                .by_ref()
                .collect::<std::result::Result<Vec<_>, _>>()
                .map_err(err)?;
            if let Some(w) = masked_warning(path, &reader.masked()) {
                rep.log(format!("warning: {w}"));
            }
            let masked = mask_lines_beyond(&mut lines, l.max_range_mm);
            if masked.count > 0 {
                rep.log(format!(
                    "warning: {}: {}",
                    path.display(),
                    masked.describe(&beyond(l.max_range_mm))
                ));
            }
            let mut c = Cloud::default();
            for line in &lines {
                c.push_scan(&header, line, &mount);
            }
            cloud.extend(non_empty(c, path).map_err(err)?);
            if scans.is_none() {
                scans = Some((header, lines));
            }
        } else {
            let unit: CloudUnit = match l.cloud_unit.as_deref() {
                Some(u) => u
                    .parse()
                    .map_err(|e| PipelineError::Input(format!("[lrf] cloud_unit: {e}")))?,
                None => CloudUnit::default(),
            };
            let (mut c, warnings) = read_cloud_file_in(path, &mount, unit).map_err(err)?;
            for w in warnings {
                rep.log(format!("warning: {w}"));
            }
            let n = c.mask_beyond(l.max_range_mm);
            if n > 0 {
                rep.log(format!(
                    "warning: {}: {n} point(s) {} masked",
                    path.display(),
                    beyond(l.max_range_mm)
                ));
            }
            cloud.extend(c);
        }
        pb.advance(1);
    }
    if let Some(bag) = &l.bag {
        for (header, mut lines) in bag_scans(project, bag, rep)? {
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
    let noise = match (&l.noise, l.noise_sigma_mm) {
        (Some(n), _) => {
            RangeNoise::named(n).map_err(|e| PipelineError::Input(format!("[lrf] noise: {e}")))?
        }
        (None, Some([a, b])) => RangeNoise::linear(a, b)
            .map_err(|e| PipelineError::Input(format!("[lrf] noise_sigma_mm: {e}")))?,
        (None, None) => {
            RangeNoise::from_datasheet(l.accuracy_near_mm, l.accuracy_far_fraction, 3.0)
        }
    };
    pb.finish();
    Ok(spheres_in(project, cloud, scans, mount, noise, opts, rep))
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
    let find = |c: &Cloud| find_walls(c, &finder);
    match mount_from_room_refinding(&lrf.cloud, &lrf.found.planes, &lrf.mount, &opts, find) {
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
        project.scan_paths.len(),
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
        }
    }

    /// `[lrf.bag]` with the servo from tf (the fixture's `servo_link` turns about y as the
    /// joint does) gives the JointState's scans; a geometry change keeps every scan.
    #[test]
    fn a_project_bag_reads_the_servo_from_tf_and_keeps_each_geometry() {
        let rep = Reporter::silent();
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
        let (a, b) = (
            bag_scans(&joint, joint.file.lrf.bag.as_ref().unwrap(), &rep).unwrap(),
            bag_scans(&tf, tf.file.lrf.bag.as_ref().unwrap(), &rep).unwrap(),
        );
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
        let runs = bag_scans(&g, g.file.lrf.bag.as_ref().unwrap(), &rep).unwrap();
        let sizes: Vec<(usize, usize)> = runs
            .iter()
            .map(|(_, l)| (l.len(), l[0].ranges_mm.len()))
            .collect();
        assert_eq!(sizes, [(2, 10), (1, 11), (1, 10), (1, 10)]);
        assert_eq!(runs[3].0.angle_min_deg, -5.0);
    }
}
