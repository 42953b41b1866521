//! The simulated self-calibration network shared by the recovery and precision tests: a
//! room-corner test field (back wall, left wall, floor; ~80 points, mm) photographed by a
//! convergent network of 14 stations with 90° rolls; a MYNT-like wide-angle camera.
#![allow(dead_code)]

use nalgebra::{Vector2, Vector3};
use pingcal_ba::camera::PhotogrammetricCamera;
use pingcal_ba::problem::{Camera, Image, Observation, Point, Problem};
use pingcal_ba::solver::Options;
use pingcal_ba::CameraKey;
use pingcal_ba::{ImageKey, PointKey};
use pingcal_geometry::exp_so3;
use pingcal_geometry::Rigid3;
use rand_distr::{Distribution, Normal};
use std::sync::Arc;

pub const SIGMA_PX: f64 = 0.3;

pub fn look_at(centre: Vector3<f64>, target: Vector3<f64>, roll: f64) -> Rigid3 {
    Rigid3::looking_at(centre, target, roll)
}

/// The true network: intrinsics of a MYNT-like wide-angle camera, 14 stations, ~80 points.
pub fn truth() -> Problem {
    let model = Arc::new(PhotogrammetricCamera::new(1280, 720, 0.00375));
    let params = vec![
        2.45, 0.012, -0.008, -0.021, 4.0e-4, -1.0e-5, 1.5e-4, -1.0e-4, 2.0e-4, -1.0e-4,
    ];
    let camera = Camera::new("left", model, params);
    let mut points = Vec::new();
    for i in 0..6 {
        for j in 0..5 {
            let (a, b) = (-1250.0 + 500.0 * i as f64, -900.0 + 450.0 * j as f64);
            points.push(Vector3::new(a, 3000.0, b)); // back wall
            points.push(Vector3::new(-1500.0, 1700.0 + 250.0 * i as f64, b)); // left wall
            if j < 3 {
                points.push(Vector3::new(a, 1800.0 + 400.0 * j as f64, -1000.0));
                // floor
            }
        }
    }
    let target = Vector3::new(-500.0, 2500.0, -500.0);
    let mut images = Vec::new();
    for k in 0..14 {
        let az = -0.9 + 1.1 * (k as f64) / 13.0;
        let height = [-600.0, 0.0, 600.0][k % 3];
        let centre = target + Vector3::new(2600.0 * az.sin(), -2600.0 * az.cos(), height);
        let roll = [
            0.0,
            std::f64::consts::FRAC_PI_2,
            0.0,
            -std::f64::consts::FRAC_PI_2,
        ][k % 4];
        images.push(Image {
            name: format!("S{k:02}"),
            camera: CameraKey(0),
            camera_from_object: look_at(centre, target, roll),
            fixed: false,
            fixed_centre: [false; 3],
        });
    }
    let mut pts: Vec<Point> = points
        .iter()
        .enumerate()
        .map(|(p, x)| Point {
            name: format!("P{p}"),
            position: *x,
            fixed: false,
            fixed_axes: [false; 3],
        })
        .collect();
    // Datum: four well-spread control points held fixed.
    for &p in &[0usize, 12, 40, 70] {
        pts[p].fixed = true;
    }
    let mut p = Problem {
        cameras: vec![camera],
        images,
        points: pts,
        ..Default::default()
    };
    let n = p.images.len();
    observe(&mut p, 0..n);
    p
}

/// Observes, exactly (σ [`SIGMA_PX`]), every point that each of `images` (indices into
/// `p.images`) sees through its own camera's model inside a 5 px margin of the 1280 × 720
/// sensor; appended in image then point order.
pub fn observe(p: &mut Problem, images: std::ops::Range<usize>) {
    for i in images {
        let im = &p.images[i];
        let cam = &p.cameras[im.camera];
        for (q, pt) in p.points.iter().enumerate() {
            let xc = im.camera_from_object.transform(&pt.position);
            if let Some(uv) = cam.model.project(&cam.params, &xc, None, None) {
                if uv.x > 5.0 && uv.x < 1274.0 && uv.y > 5.0 && uv.y < 714.0 {
                    p.observations.push(Observation {
                        image: ImageKey(i),
                        point: PointKey(q),
                        uv,
                        sigma: SIGMA_PX,
                    });
                }
            }
        }
    }
}

/// Solver options that run an adjustment to convergence (function and parameter
/// tolerances 1e-12, at most 200 iterations) on one thread, the same result every run.
pub fn to_convergence() -> Options {
    Options {
        function_tolerance: 1e-12,
        parameter_tolerance: 1e-12,
        max_iterations: 200,
        threads: 1,
        ..Options::default()
    }
}

/// One noisy realisation, started from a perturbed truth.
pub fn realisation(truth: &Problem, seed: u64) -> Problem {
    let mut rng = pingcal_geometry::consensus::rng(seed);
    let n = Normal::new(0.0, 1.0).unwrap();
    let mut p = truth.clone();
    for o in &mut p.observations {
        o.uv += Vector2::new(n.sample(&mut rng), n.sample(&mut rng)) * SIGMA_PX;
    }
    for im in &mut p.images {
        let dw = Vector3::new(n.sample(&mut rng), n.sample(&mut rng), n.sample(&mut rng)) * 0.01;
        let dc = Vector3::new(n.sample(&mut rng), n.sample(&mut rng), n.sample(&mut rng)) * 30.0;
        im.camera_from_object = Rigid3::from_rotation_and_centre(
            exp_so3(&dw) * im.camera_from_object.rotation,
            im.camera_from_object.centre() + dc,
        );
    }
    for pt in p.points.iter_mut().filter(|x| !x.fixed) {
        pt.position +=
            Vector3::new(n.sample(&mut rng), n.sample(&mut rng), n.sample(&mut rng)) * 20.0;
    }
    // Approximate intrinsics only: nominal c, everything else zero.
    let c = &mut p.cameras[0].params;
    c[0] = 2.4;
    c[1..].iter_mut().for_each(|v| *v = 0.0);
    p
}

/// A synthetic free network (BAL cameras of 9 unknowns, `points` points seen 5 times each,
/// observations of σ = 1 with 0.5 px noise), adjusted with `options`.
pub fn adjusted_free_network(cameras: usize, points: usize, options: &Options) -> Problem {
    let spec = pingcal_ba::synthetic::SyntheticBal {
        cameras,
        points,
        obs_per_point: 5,
        noise_px: 0.5,
        ..Default::default()
    };
    let mut p = spec.generate().unwrap().problem;
    pingcal_ba::solver::solve(&mut p, options, |_| {}).unwrap();
    p
}
