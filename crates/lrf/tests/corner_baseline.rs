//! The whole Fan et al. 2019 baseline on a simulated room corner: targets on the two walls
//! and the floor, the main image, and an LRF sweep simulated with the URG-04LX noise model.

use pingcal_geometry::rotation_angle;
use pingcal_geometry::{from_opk, Sim3};
use pingcal_lrf::corner_baseline::{fan_baseline, BaselineInput};
use pingcal_lrf::nalgebra::{Matrix3, Vector2, Vector3};
use pingcal_lrf::scan::{ScanHeader, ScanLine};
use pingcal_lrf::simulate::{LrfScene, SimulatedLrf};
use pingcal_lrf::MountModel;
use rand::Rng;
use rand_distr::{Distribution, Normal};

/// Focal length in pixels (MYNT EYE D1000: 2.45 mm / 3.75 µm) and the image half-size.
const F_PX: f64 = 653.0;
const HALF_W_PX: f64 = 640.0;
const HALF_H_PX: f64 = 360.0;

struct Field {
    scans: Vec<ScanLine>,
    targets: Vec<(String, Vector3<f64>)>,
    image: Vec<(String, Vector2<f64>)>,
    /// p_camera = T p_lrf
    truth: Sim3,
    /// p_photo = T p_corner
    camera_from_corner: Sim3,
}

/// The default mount (eq. 2), shared by every input.
static MOUNT: std::sync::LazyLock<MountModel> = std::sync::LazyLock::new(MountModel::default);

impl Field {
    /// The baseline's input for this field, URG-04LX header and σ 10 mm.
    fn input(&self, seed: u64) -> BaselineInput<'_> {
        BaselineInput {
            header: &ScanHeader::URG_04LX,
            scans: &self.scans,
            mount: &MOUNT,
            range_sigma_mm: 10.0,
            targets: &self.targets,
            main_image: &self.image,
            seed,
            rough_camera_from_lrf: nalgebra::Matrix3::identity(),
        }
    }
}

/// The room corner (walls x = 0, y = 0, floor z = 0 in the corner frame), ~70 targets, the
/// camera at (1150, 1100, 700) looking at (250, 230, 520), the LRF rigidly offset from it.
fn field(seed: u64, with_floor: bool) -> Field {
    let mut rng = pingcal_geometry::consensus::rng(seed);
    // camera: Y forward, X right, Z up (photogrammetric frame = this camera's frame)
    let c = Vector3::new(1150.0, 1100.0, 700.0);
    let y = (Vector3::new(250.0, 230.0, 520.0) - c).normalize();
    let x = y.cross(&Vector3::z()).normalize();
    let z = x.cross(&y);
    let world_from_cam = Sim3 {
        rotation: Matrix3::from_columns(&[x, y, z]),
        translation: c,
        scale: 1.0,
    };
    let cam_from_world = world_from_cam.inverse();
    // extrinsic: p_camera = R p_lrf + t
    let d = |v: f64| v.to_radians();
    let truth = Sim3 {
        rotation: from_opk(d(0.8), d(-1.2), d(0.6)),
        translation: Vector3::new(72.0, 12.0, 91.0),
        scale: 1.0,
    };
    let world_from_lrf = world_from_cam.compose(&truth);
    // targets: a jittered 5 × 5 grid per face, a few dropped; bundle-adjustment noise 0.3 mm
    let ba = Normal::new(0.0, 0.3).unwrap();
    let mut targets = Vec::new();
    let mut exact = Vec::new();
    for face in 0..3 {
        if face == 2 && !with_floor {
            continue;
        }
        for i in 0..5 {
            for j in 0..5 {
                if rng.random_range(0.0..1.0) < 0.07 {
                    continue;
                }
                let a = 150.0 + 200.0 * i as f64 + rng.random_range(-40.0..40.0);
                let b = 120.0 + 200.0 * j as f64 + rng.random_range(-40.0..40.0);
                let p = match face {
                    0 => Vector3::new(0.0, a, b),
                    1 => Vector3::new(a, 0.0, b),
                    _ => Vector3::new(a, b, 0.0),
                };
                let q = cam_from_world.transform(&p);
                let noisy = q + Vector3::from_fn(|_, _| ba.sample(&mut rng));
                targets.push((format!("T{}{}{}", face, i, j), noisy));
                exact.push(q);
            }
        }
    }
    // main image: projection of the true target + 0.3 px noise, inside the frame
    let px = Normal::new(0.0, 0.3 / F_PX).unwrap();
    let mut image = Vec::new();
    for ((id, _), q) in targets.iter().zip(&exact) {
        let u = Vector2::new(q.x / q.y, q.z / q.y);
        if q.y > 0.0 && u.x.abs() < HALF_W_PX / F_PX && u.y.abs() < HALF_H_PX / F_PX {
            image.push((
                id.clone(),
                u + Vector2::new(px.sample(&mut rng), px.sample(&mut rng)),
            ));
        }
    }
    // LRF sweep: the three corner planes in the LRF frame, servo −60° … 60° in 0.5° steps
    let planes = (0..3)
        .map(|k| {
            let n = Vector3::ith(k, 1.0);
            (
                world_from_lrf.rotation.transpose() * n,
                -n.dot(&world_from_lrf.translation),
            )
        })
        .collect();
    let scene = LrfScene {
        planes,
        balls: vec![],
        radius: 19.0,
        clutter: Vec::new(),
    };
    let servo: Vec<f64> = (0..=240).map(|k| -60.0 + 0.5 * k as f64).collect();
    let mut scans = scene.scan(&servo, &SimulatedLrf::default(), &mut rng);
    for (k, s) in scans.iter_mut().enumerate() {
        s.line = k + 1;
    }
    Field {
        scans,
        targets,
        image,
        truth,
        camera_from_corner: cam_from_world,
    }
}

/// (translation error mm, rotation error deg, mean error at the targets mm) of one seed.
fn run(seed: u64) -> (f64, f64, f64) {
    let f = field(seed, true);
    let input = f.input(seed);
    let r = fan_baseline(&input).unwrap_or_else(|e| panic!("seed {seed}: {e}"));
    assert_eq!(r.face_sizes.iter().sum::<usize>(), f.targets.len());
    // the corner frame from the target planes is nearly exact (0.3 mm target noise)
    let dc = (r.camera_from_corner.translation - f.camera_from_corner.translation).norm();
    let ac = rotation_angle(
        &(r.camera_from_corner.rotation * f.camera_from_corner.rotation.transpose()),
    )
    .to_degrees();
    assert!(
        dc < 3.0 && ac < 0.2,
        "seed {seed}: corner frame {dc} mm {ac}°"
    );
    let dt = (r.camera_from_lrf.translation - f.truth.translation).norm();
    let da =
        rotation_angle(&(r.camera_from_lrf.rotation * f.truth.rotation.transpose())).to_degrees();
    // like the paper's check error: the extrinsic's error at points 1–2 m from the rig (the
    // targets, in the camera frame)
    let est_from_true = r.camera_from_lrf.compose(&f.truth.inverse());
    let chk = f
        .targets
        .iter()
        .map(|(_, q)| (est_from_true.transform(q) - q).norm())
        .sum::<f64>()
        / f.targets.len() as f64;
    if seed == 0 {
        for n in &r.notes {
            println!("note: {n}");
        }
    }
    println!(
        "seed {seed}: servo {:.1}°, faces {:?}, {} image points: |Δt| = {dt:.1} mm, rotation {da:.3}°, \
         at the targets {chk:.1} mm",
        r.servo_deg,
        r.face_sizes,
        f.image.len()
    );
    (dt, da, chk)
}

// Tolerances, from the noise: `sixty_seeds` (ignored; `cargo test -p pingcal-lrf --release
// --test lrf corner_baseline:: -- --ignored --nocapture`) ran seeds 0–59 once with these noise
// levels (ranges: URG model, σ = 10 mm under 1 m, 1 % beyond; image 0.3 px; targets 0.3 mm),
// with the scan chosen by the smallest predicted LRF position σ:
//   translation error: mean 8.3 mm, sd 5.4, max 27.5  → mean + 4 sd = 30.0 mm
//   rotation error:    mean 0.49°,  sd 0.40, max 1.89° → mean + 4 sd = 2.10°
//   error at the targets (1–2 m, like the paper's check points): mean 7.7 mm, sd 4.7, max
//   23.0 (the paper reports 15.5 mm for this baseline with real data, whose walls are
//   neither flat nor orthogonal to the millimetre).
// (The earlier choice, the most points on the three lines, gave 8.8 ± 4.5 mm (max 18.8) and
// 0.56 ± 0.31° (max 1.65°) here, but 44 ± 23 mm / 2.1 ± 1.0° on the full simulator of
// `pingcal simulate`, where it kept picking a scan with a short far wall line; the new
// choice gives 12 ± 6 mm / 0.66 ± 0.25° there (23 seeds, examples/corner_on_project.rs).)
const MAX_DT_MM: f64 = 30.0;
const MAX_DA_DEG: f64 = 2.1;

#[test]
fn fan_baseline_recovers_the_extrinsic_of_a_simulated_rig() {
    for seed in 0..20 {
        let (dt, da, _) = run(seed);
        assert!(
            dt < MAX_DT_MM && da < MAX_DA_DEG,
            "seed {seed}: |Δt| {dt:.1} mm, rotation {da:.3}°"
        );
    }
}

#[test]
#[ignore]
fn sixty_seeds() {
    let from: u64 = std::env::var("FROM").map_or(0, |v| v.parse().unwrap());
    let v: Vec<(f64, f64, f64)> = (from..from + 60).map(run).collect();
    let stats = |k: usize| {
        let x: Vec<f64> = v.iter().map(|p| [p.0, p.1, p.2][k]).collect();
        let m = x.iter().sum::<f64>() / x.len() as f64;
        let sd = (x.iter().map(|a| (a - m).powi(2)).sum::<f64>() / (x.len() - 1) as f64).sqrt();
        let max = x.iter().cloned().fold(0.0, f64::max);
        (m, sd, max)
    };
    let (mt, st, xt) = stats(0);
    let (ma, sa, xa) = stats(1);
    println!(
        "translation: mean {mt:.2} mm sd {st:.2} max {xt:.2} → mean+4sd {:.1}",
        mt + 4.0 * st
    );
    let (mc, sc, xc) = stats(2);
    println!("at the targets: mean {mc:.2} mm sd {sc:.2} max {xc:.2}");
    println!(
        "rotation: mean {ma:.3}° sd {sa:.3} max {xa:.3} → mean+4sd {:.2}",
        ma + 4.0 * sa
    );
}

#[test]
fn targets_on_two_planes_are_an_error_naming_the_planes() {
    let f = field(3, false);
    let input = f.input(3);
    let e = fan_baseline(&input).unwrap_err().to_string();
    println!("{e}");
    assert!(e.contains("only 2 plane(s)"), "{e}");
    assert!(e.contains("plane 1:") && e.contains("plane 2:"), "{e}");
}

#[test]
fn no_usable_scan_and_bad_input_are_errors() {
    let f = field(4, true);
    // a sweep that only sees the walls (horizontal scan planes far above the floor)
    let flat: Vec<ScanLine> = f
        .scans
        .iter()
        .filter(|s| s.servo_deg.abs() < 1.0)
        .cloned()
        .collect();
    let mut input = BaselineInput {
        header: &ScanHeader::URG_04LX,
        scans: &flat,
        mount: &MountModel::default(),
        range_sigma_mm: 10.0,
        targets: &f.targets,
        main_image: &f.image,
        seed: 4,
        rough_camera_from_lrf: nalgebra::Matrix3::identity(),
    };
    let e = fan_baseline(&input).unwrap_err().to_string();
    assert!(e.contains("no scan line shows three corner faces"), "{e}");
    input.scans = &f.scans;
    input.range_sigma_mm = f64::NAN;
    assert!(fan_baseline(&input).is_err());
    input.range_sigma_mm = 10.0;
    let few = &f.image[..5];
    input.main_image = few;
    let e = fan_baseline(&input).unwrap_err().to_string();
    assert!(e.contains("DLT"), "{e}");
    input.scans = &[];
    assert!(fan_baseline(&input).is_err());
}
