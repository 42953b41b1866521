//! Diagnostic: the Fan et al. 2019 corner baseline ([`fan_baseline`]) on a simulated project
//! (`pingcal simulate --out DIR`), fed with the TRUE target coordinates and their exact
//! normalised projections, compared step by step with `DIR/truth.json`.
//!
//! `cargo run -p pingcal-lrf --release --example corner_on_project -- DIR [--all] [--quiet]`
//!
//! Prints: the extrinsic error; the corner frame vs the truth (world frame = corner frame:
//! X along wall 1's floor edge, Y along wall 2's, Z up; wall 1 is the plane y ≈ 0, wall 2 the
//! plane x ≈ 0); the DLT camera pose vs the truth; the LRF pose in the corner vs the truth;
//! the chosen scan's three lines (inliers, rms to their true plane, points of other surfaces
//! they took) and the edge points vs their true positions (the true edges are the
//! intersections of the true planes, which pass through the vertex). With `--all`: every
//! usable scan's P3P pose error vs its line supports, and what other choice rules would give.
//! The last line `SUMMARY dt da chk` is for scripts.

use pingcal_geometry::rotation_angle;
use pingcal_geometry::Sim3;
use pingcal_lrf::corner::{lrf_pose_in_corner, pose_uncertainty, scan_lines, Line2};
use pingcal_lrf::corner_baseline::{fan_baseline, BaselineInput, BaselineResult};
use pingcal_lrf::nalgebra::{Matrix3, Vector2, Vector3};
use pingcal_lrf::scan::{open_scan_file, ScanHeader, ScanLine};
use pingcal_lrf::MountModel;
use serde_json::Value;
use std::path::Path;

fn v3(v: &Value) -> Vector3<f64> {
    Vector3::new(
        v[0].as_f64().unwrap(),
        v[1].as_f64().unwrap(),
        v[2].as_f64().unwrap(),
    )
}

fn pose(v: &Value) -> Sim3 {
    let r = &v["rotation"];
    Sim3 {
        rotation: Matrix3::from_fn(|i, j| r[i][j].as_f64().unwrap()),
        translation: v3(&v["translation_mm"]),
        scale: 1.0,
    }
}

fn ang(a: &Matrix3<f64>, b: &Matrix3<f64>) -> f64 {
    rotation_angle(&(a * b.transpose())).to_degrees()
}

fn f3(v: &Vector3<f64>) -> String {
    format!("({:8.1}, {:8.1}, {:8.1})", v.x, v.y, v.z)
}

/// Point where the scan plane (through `o`, normal `n`) cuts the edge through the vertex
/// with direction `d`.
fn edge_hit(o: &Vector3<f64>, n: &Vector3<f64>, d: &Vector3<f64>) -> Vector3<f64> {
    d * (n.dot(o) / n.dot(d))
}

/// The simulated project read back: its first scan file and the truth it is compared with.
struct Project {
    header: ScanHeader,
    scans: Vec<ScanLine>,
    /// p_cam = ext · p_lrf.
    ext: Sim3,
    /// p_photo = w2p · p_world.
    w2p: Sim3,
    lrf_in_world: Sim3,
    targets: Vec<(String, Vector3<f64>)>,
    /// The targets' exact normalised projections.
    image: Vec<(String, Vector2<f64>)>,
    /// The normals of the corner's faces x = 0, y = 0, z = 0 (wall2, wall1, floor).
    nf: [Vector3<f64>; 3],
    mount: MountModel,
    seed: u64,
}

const FACE_NAMES: [&str; 3] = ["wall2 (x=0)", "wall1 (y=0)", "floor (z=0)"];

/// One scan's LRF pose in the corner frame (= the world frame), checked against the truth.
#[derive(Clone, Copy)]
struct ScanPose {
    scan: usize,
    corner_from_lrf: Sim3,
    inliers: [usize; 3],
    /// Error of the edge point on each axis, mm (NaN where two lines do not meet).
    edge_err: [f64; 3],
}

/// A consistent scan for the choice rules, with its predicted pose uncertainty.
#[derive(Clone, Copy)]
struct Candidate {
    scan: usize,
    corner_from_lrf: Sim3,
    inliers: [usize; 3],
    predicted_mm: f64,
    predicted_deg: f64,
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let dir = Path::new(args.first().expect("usage: corner_on_project DIR [--all]"));
    let all = args.iter().any(|a| a == "--all");
    let quiet = args.iter().any(|a| a == "--quiet");
    let p = load(dir);
    let (header, scans, mount, seed) = (&p.header, &p.scans, &p.mount, p.seed);
    let (ext, targets, image) = (p.ext, &p.targets, &p.image);
    let input = BaselineInput {
        header,
        scans,
        mount,
        range_sigma_mm: 10.0,
        targets,
        main_image: image,
        seed,
        rough_camera_from_lrf: nalgebra::Matrix3::identity(),
    };
    let t0 = std::time::Instant::now();
    let r = fan_baseline(&input).unwrap();
    let el = t0.elapsed().as_secs_f64();
    let dt = r.camera_from_lrf.translation - ext.translation;
    let da = ang(&r.camera_from_lrf.rotation, &ext.rotation);
    let e_from_t = r.camera_from_lrf.compose(&ext.inverse());
    let chk = targets
        .iter()
        .map(|(_, q)| (e_from_t.transform(q) - q).norm())
        .sum::<f64>()
        / targets.len() as f64;
    println!(
        "== {}: fan_baseline in {el:.2} s; extrinsic error |Δt| = {:.1} mm, Δt = {} (camera frame), \
         rotation {da:.3}°, mean at the targets {chk:.1} mm",
        dir.display(),
        dt.norm(),
        f3(&dt)
    );
    if !quiet {
        for n in &r.notes {
            println!("  note: {n}");
        }
    }
    print_parts(&p, &r);
    let prior = r.camera_from_dlt.rotation.transpose();
    let k = scans
        .iter()
        .position(|s| s.servo_deg == r.servo_deg)
        .unwrap();
    println!("chosen scan #{} servo {:.3}°:", k + 1, r.servo_deg);
    analyse(&p, &prior, k, true);
    if all {
        every_scan(&p, &prior);
        choice_rules(&p, &r, &prior);
    }
    println!("SUMMARY {:.2} {:.3} {:.2}", dt.norm(), da, chk);
}

/// Reads `DIR/truth.json` and `DIR/scans/S00.csv`.
fn load(dir: &Path) -> Project {
    let truth: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("truth.json")).unwrap()).unwrap();
    let mut rd = open_scan_file(&dir.join("scans/S00.csv")).unwrap();
    let header: ScanHeader = rd.header();
    let scans: Vec<ScanLine> = rd.by_ref().map(|s| s.unwrap()).collect();
    let ext = pose(&truth["extrinsic"]); // p_cam = T p_lrf
                                         // p_photo = T p_world, p_lrf = T p_world (named world_to_… in files written before)
    let key = |new: &str, old: &str| {
        if truth[new].is_null() {
            pose(&truth[old])
        } else {
            pose(&truth[new])
        }
    };
    let w2p = key("photogrammetric_from_world", "world_to_photogrammetric");
    let w2l = key("lrf_from_world", "world_to_lrf");
    let lrf_in_world = w2l.inverse();
    let mut targets = Vec::new();
    let mut image = Vec::new();
    let mut surf_of = Vec::new();
    for t in truth["targets"].as_array().unwrap() {
        let id = t["id"].to_string();
        let p = v3(&t["photogrammetric_mm"]);
        targets.push((id.clone(), p));
        surf_of.push(t["surface"].as_str().unwrap().to_string());
        if p.y > 0.0 {
            image.push((id, Vector2::new(p.x / p.y, p.z / p.y)));
        }
    }
    let mut normal = std::collections::HashMap::new();
    for s in truth["surfaces"].as_array().unwrap() {
        normal.insert(
            s["name"].as_str().unwrap().to_string(),
            (v3(&s["normal_world"]), s["bulge_mm"].as_f64().unwrap()),
        );
    }
    // corner faces x = 0, y = 0, z = 0 are wall2, wall1, floor
    let nf = [normal["wall2"].0, normal["wall1"].0, normal["floor"].0];
    Project {
        header,
        scans,
        ext,
        w2p,
        lrf_in_world,
        targets,
        image,
        nf,
        mount: MountModel::default(),
        seed: truth["seed"].as_u64().unwrap_or(1),
    }
}

/// The baseline's parts against the truth: the corner frame, the DLT camera pose, the LRF
/// in the corner, and the extrinsic error each part alone would leave.
fn print_parts(p: &Project, r: &BaselineResult) {
    let (ext, w2p, lrf_in_world) = (p.ext, p.w2p, p.lrf_in_world);
    // 1. corner frame (p_photo = T p_corner) vs truth (p_photo = w2p p_world)
    let dc = r.camera_from_corner.translation - w2p.translation;
    println!(
        "corner frame vs truth: rotation {:.3}°, origin {:.2} mm {}",
        ang(&r.camera_from_corner.rotation, &w2p.rotation),
        dc.norm(),
        f3(&dc)
    );
    // 2. DLT camera pose (p_cam = T p_corner) vs truth (same: the photo frame is the camera's)
    let dd = r.camera_from_dlt.inverse().translation - w2p.inverse().translation;
    println!(
        "DLT camera pose vs truth: rotation {:.3}°, centre {:.2} mm {}",
        ang(&r.camera_from_dlt.rotation, &w2p.rotation),
        dd.norm(),
        f3(&dd)
    );
    // 3. LRF pose in the corner
    let dl = r.corner_from_lrf.translation - lrf_in_world.translation;
    println!(
        "LRF in corner vs truth: rotation {:.3}°, position {:.1} mm {} (true position {})",
        ang(&r.corner_from_lrf.rotation, &lrf_in_world.rotation),
        dl.norm(),
        f3(&dl),
        f3(&lrf_in_world.translation)
    );
    // error budget: extrinsic error from each part alone
    let only_dlt = r.camera_from_dlt.compose(&lrf_in_world);
    let only_lrf = w2p.compose(&r.corner_from_lrf);
    println!(
        "  extrinsic with the true LRF-in-corner: {:.1} mm {:.3}°; with the true camera pose: \
         {:.1} mm {:.3}°",
        (only_dlt.translation - ext.translation).norm(),
        ang(&only_dlt.rotation, &ext.rotation),
        (only_lrf.translation - ext.translation).norm(),
        ang(&only_lrf.rotation, &ext.rotation)
    );
}

/// One scan's LRF pose in the corner and its edge points' errors; with `verbose`, the
/// edge points, the lines and their support printed.
fn analyse(p: &Project, prior: &Matrix3<f64>, k: usize, verbose: bool) -> Option<ScanPose> {
    let (header, scans, mount, seed) = (&p.header, &p.scans, &p.mount, p.seed);
    let (lrf_in_world, nf) = (p.lrf_in_world, p.nf);
    let scan = &scans[k];
    let s = seed
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add(k as u64);
    let lines = scan_lines(header, scan, 30.0, s).ok()?;
    let inl = lines.map(|l| l.inliers);
    let est = lrf_pose_in_corner(&lines, scan.servo_deg, mount, prior).ok()?;
    // which line is on which face: the one whose points are nearest the true plane
    let rb = pingcal_lrf::cloud::servo_rotation(scan.servo_deg.to_radians());
    let to_w = |p: Vector2<f64>| lrf_in_world.transform(&(rb * Vector3::new(p.x, p.y, 0.0)));
    let o = lrf_in_world.translation;
    let n_scan = lrf_in_world.rotation * rb * Vector3::z();
    let mut face_of_line = [usize::MAX; 3];
    for (li, l) in lines.iter().enumerate() {
        let c = to_w(l.point);
        let f = (0..3)
            .min_by(|&a, &b| nf[a].dot(&c).abs().total_cmp(&nf[b].dot(&c).abs()))
            .unwrap();
        face_of_line[li] = f;
    }
    // edge points: where lines of faces f, g meet lies on the edge along the third axis
    let mut edge_err = [f64::NAN; 3];
    for axis in 0..3 {
        let (f, g) = ((axis + 1) % 3, (axis + 2) % 3);
        let lf = face_of_line.iter().position(|&x| x == f);
        let lg = face_of_line.iter().position(|&x| x == g);
        let (Some(a), Some(b)) = (lf, lg) else {
            continue;
        };
        let Some(p) = lines[a].intersect(&lines[b]) else {
            continue;
        };
        let pw = to_w(p);
        let d = nf[f].cross(&nf[g]).normalize();
        let tru = edge_hit(&o, &n_scan, &d);
        edge_err[axis] = (pw - tru).norm();
        if verbose {
            println!(
                "    edge point on the {} axis: measured {} true {} error {:.1} mm \
                 ({:.0} mm from the LRF)",
                ["X", "Y", "Z"][axis],
                f3(&pw),
                f3(&tru),
                (pw - tru).norm(),
                (tru - o).norm()
            );
        }
    }
    if verbose {
        print_lines(p, k, &lines, &face_of_line, &to_w);
    }
    Some(ScanPose {
        scan: k,
        corner_from_lrf: est,
        inliers: inl,
        edge_err,
    })
}

/// Scan `k`'s three lines: inliers, face, and the points near each against its true plane.
fn print_lines(
    p: &Project,
    k: usize,
    lines: &[Line2; 3],
    face_of_line: &[usize; 3],
    to_w: &dyn Fn(Vector2<f64>) -> Vector3<f64>,
) {
    let (header, scan, nf) = (&p.header, &p.scans[k], p.nf);
    for (li, l) in lines.iter().enumerate() {
        let f = face_of_line[li];
        println!(
            "    line {li}: {} inliers, on {}, centroid {:.0} mm from the LRF, direction \
             {:.3},{:.3}",
            l.inliers,
            FACE_NAMES[f],
            l.point.norm(),
            l.dir.x,
            l.dir.y
        );
    }
    // points near each fitted line: distance to the true plane (clutter = far from it)
    let pts = pingcal_lrf::corner::scan_plane_points(header, scan);
    for (li, l) in lines.iter().enumerate() {
        let nrm = Vector2::new(-l.dir.y, l.dir.x);
        let near: Vec<&Vector2<f64>> = pts
            .iter()
            .filter(|p| nrm.dot(&(*p - l.point)).abs() < 30.0)
            .collect();
        let f = face_of_line[li];
        let dists: Vec<f64> = near.iter().map(|p| nf[f].dot(&to_w(**p))).collect();
        let off = dists.iter().filter(|d| d.abs() > 30.0).count();
        let rms = (dists.iter().map(|d| d * d).sum::<f64>() / dists.len() as f64).sqrt();
        let mean = dists.iter().sum::<f64>() / dists.len() as f64;
        // the fitted line's offset from the true plane at its centroid
        println!(
            "    line {li}: {} points within 30 mm, {} of them > 30 mm off its true \
             plane; mean {mean:.1} rms {rms:.1} mm from the true plane; fitted centroid \
             {:.1} mm off it",
            near.len(),
            off,
            nf[f].dot(&to_w(l.point))
        );
    }
}

/// Every usable scan's LRF pose error against its lines' support.
fn every_scan(p: &Project, prior: &Matrix3<f64>) {
    let (scans, lrf_in_world) = (&p.scans, p.lrf_in_world);
    let res: Vec<ScanPose> = (0..scans.len())
        .filter_map(|k| analyse(p, prior, k, false))
        .filter(|c| {
            ang(&c.corner_from_lrf.rotation, prior) < 30.0 && c.inliers.iter().all(|&n| n >= 20)
        })
        .collect();
    let err = |c: &ScanPose| (c.corner_from_lrf.translation - lrf_in_world.translation).norm();
    let rot = |c: &ScanPose| ang(&c.corner_from_lrf.rotation, &lrf_in_world.rotation);
    let mut e: Vec<f64> = res.iter().map(err).collect();
    e.sort_by(f64::total_cmp);
    println!(
        "{} usable scans: LRF position error median {:.1} mm, 10 % {:.1}, 90 % {:.1}",
        res.len(),
        e[e.len() / 2],
        e[e.len() / 10],
        e[9 * e.len() / 10]
    );
    for step in (0..res.len()).step_by((res.len() / 40).max(1)) {
        let c = &res[step];
        println!(
            "  scan #{:4} servo {:7.2}°: inliers {:?} sum {} min {}; edge errors {:.1} {:.1} \
             {:.1}; pose {:.1} mm {:.2}°",
            c.scan + 1,
            scans[c.scan].servo_deg,
            c.inliers,
            c.inliers.iter().sum::<usize>(),
            c.inliers.iter().min().unwrap(),
            c.edge_err[0],
            c.edge_err[1],
            c.edge_err[2],
            err(c),
            rot(c)
        );
    }
}

/// What other choice rules than the baseline's would pick among the consistent scans.
fn choice_rules(p: &Project, r: &BaselineResult, prior: &Matrix3<f64>) {
    let (header, scans, mount, seed) = (&p.header, &p.scans, &p.mount, p.seed);
    let (ext, w2p, lrf_in_world) = (p.ext, p.w2p, p.lrf_in_world);
    // the choice rules on the same consistent scans (gates as in fan_baseline)
    let mut c: Vec<Candidate> = Vec::new();
    for (k, scan) in scans.iter().enumerate() {
        let s = seed
            .wrapping_mul(0x9E37_79B9_7F4A_7C15)
            .wrapping_add(k as u64);
        let Ok(lines) = scan_lines(header, scan, 30.0, s) else {
            continue;
        };
        if lines.iter().any(|l| l.inliers < 20) {
            continue;
        }
        let Ok(t) = lrf_pose_in_corner(&lines, scan.servo_deg, mount, prior) else {
            continue;
        };
        if ang(&t.rotation, prior) >= 30.0 {
            continue;
        }
        let (up, ur) = pose_uncertainty(&lines, scan.servo_deg, mount, prior, 10.0)
            .unwrap_or((f64::INFINITY, f64::INFINITY));
        c.push(Candidate {
            scan: k,
            corner_from_lrf: t,
            inliers: lines.map(|l| l.inliers),
            predicted_mm: up,
            predicted_deg: ur,
        });
    }
    let med = |v: Vec<f64>| {
        let mut v = v;
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let position = |x: &Candidate| x.corner_from_lrf.translation;
    let m = Vector3::from_fn(|i, _| med(c.iter().map(|x| position(x)[i]).collect()));
    let gate = (5.0 * med(c.iter().map(|x| (position(x) - m).norm()).collect())).max(50.0);
    c.retain(|x| (position(x) - m).norm() <= gate);
    let report = |name: &str, x: &Candidate| {
        // with the true camera pose: the LRF-in-corner part
        let e = w2p.compose(&x.corner_from_lrf);
        let ee = r.camera_from_dlt.compose(&x.corner_from_lrf);
        println!(
            "RULE {name:8} scan #{:4} servo {:7.2}° inliers {:?} predicted {:.1} mm {:.2}°: \
             LRF-in-corner {:.1} mm {:.2}°; extrinsic {:.1} mm {:.3}°",
            x.scan + 1,
            scans[x.scan].servo_deg,
            x.inliers,
            x.predicted_mm,
            x.predicted_deg,
            (e.translation - ext.translation).norm(),
            ang(&e.rotation, &ext.rotation),
            (ee.translation - ext.translation).norm(),
            ang(&ee.rotation, &ext.rotation)
        );
    };
    let by =
        |f: &dyn Fn(&Candidate) -> f64| *c.iter().min_by(|a, b| f(a).total_cmp(&f(b))).unwrap();
    report("sum", &by(&|x| -(x.inliers.iter().sum::<usize>() as f64)));
    report("min", &by(&|x| -(*x.inliers.iter().min().unwrap() as f64)));
    report("pred_pos", &by(&|x| x.predicted_mm));
    report("pred_rot", &by(&|x| x.predicted_deg));
    // how well the prediction ranks the scans: true error of the best-predicted 10 %
    let mut sorted = c.clone();
    sorted.sort_by(|a, b| a.predicted_mm.total_cmp(&b.predicted_mm));
    let err = |x: &Candidate| (position(x) - lrf_in_world.translation).norm();
    let top: Vec<f64> = sorted[..(sorted.len() / 10).max(1)]
        .iter()
        .map(err)
        .collect();
    println!(
        "best-predicted 10 % of {} scans: predicted {:.1}…{:.1} mm, true error median {:.1} \
         mm, all scans median {:.1}",
        sorted.len(),
        sorted[0].predicted_mm,
        sorted[top.len() - 1].predicted_mm,
        med(top.clone()),
        med(c.iter().map(err).collect())
    );
}
