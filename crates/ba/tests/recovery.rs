//! Recovery of known truth by a self-calibrating bundle adjustment with the
//! photogrammetric camera model: a room-corner test field photographed by a convergent
//! network with 90° rolls, image noise σ, datum from four fixed control points.
//!
//! Monte Carlo over noise realisations: the RMS image residual matches σ scaled by the
//! redundancy, and the truth lies within 3 Monte Carlo standard deviations of the
//! estimates of every intrinsic parameter and point coordinate (with the rate that a
//! normal distribution allows), with no significant bias.

use nalgebra::{Matrix3, Vector2, Vector3};
use pingcal_ba::camera::{CameraModel, PhotogrammetricCamera};
use pingcal_ba::pose::Pose;
use pingcal_ba::problem::{Camera, Image, Observation, Point, Problem};
use pingcal_ba::rotation::exp_so3;
use pingcal_ba::solver::{solve, Options};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use std::sync::Arc;

const SIGMA_PX: f64 = 0.3;

fn look_at(centre: Vector3<f64>, target: Vector3<f64>, roll: f64) -> Pose {
    let f = (target - centre).normalize();
    let r0 = f.cross(&Vector3::z()).normalize();
    let u0 = r0.cross(&f);
    let (s, c) = roll.sin_cos();
    let (r, u) = (r0 * c + u0 * s, u0 * c - r0 * s);
    let rot = Matrix3::from_rows(&[r.transpose(), f.transpose(), u.transpose()]);
    Pose::from_rotation_and_centre(rot, centre)
}

/// The true network: intrinsics of a MYNT-like wide-angle camera, 14 stations, ~80 points.
fn truth() -> Problem {
    let model = Arc::new(PhotogrammetricCamera::new(1280, 720, 0.00375));
    let params = vec![
        2.45, 0.012, -0.008, -0.021, 4.0e-4, -1.0e-5, 1.5e-4, -1.0e-4, 2.0e-4, -1.0e-4,
    ];
    let camera = Camera::new("left", model.clone(), params.clone());
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
            camera: 0,
            pose: look_at(centre, target, roll),
            fixed: false,
        });
    }
    let mut observations = Vec::new();
    for (i, im) in images.iter().enumerate() {
        for (p, x) in points.iter().enumerate() {
            let xc = im.pose.transform(x);
            if let Some(uv) = model.project(&params, &xc, None, None) {
                if uv.x > 5.0 && uv.x < 1274.0 && uv.y > 5.0 && uv.y < 714.0 {
                    observations.push(Observation {
                        image: i,
                        point: p,
                        uv,
                        sigma: SIGMA_PX,
                    });
                }
            }
        }
    }
    let mut pts: Vec<Point> = points
        .iter()
        .enumerate()
        .map(|(p, x)| Point {
            name: format!("P{p}"),
            position: *x,
            fixed: false,
        })
        .collect();
    // Datum: four well-spread control points held fixed.
    for &p in &[0usize, 12, 40, 70] {
        pts[p].fixed = true;
    }
    Problem {
        cameras: vec![camera],
        images,
        points: pts,
        observations,
        ..Default::default()
    }
}

/// One noisy realisation, started from a perturbed truth.
fn realisation(truth: &Problem, seed: u64) -> Problem {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let n = Normal::new(0.0, 1.0).unwrap();
    let mut p = truth.clone();
    for o in &mut p.observations {
        o.uv += Vector2::new(n.sample(&mut rng), n.sample(&mut rng)) * SIGMA_PX;
    }
    for im in &mut p.images {
        let dw = Vector3::new(n.sample(&mut rng), n.sample(&mut rng), n.sample(&mut rng)) * 0.01;
        let dc = Vector3::new(n.sample(&mut rng), n.sample(&mut rng), n.sample(&mut rng)) * 30.0;
        im.pose =
            Pose::from_rotation_and_centre(exp_so3(&dw) * im.pose.rotation, im.pose.centre() + dc);
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

#[test]
fn monte_carlo_recovers_truth_within_its_spread() {
    let truth = truth();
    assert!(
        truth.observations.len() > 600,
        "{} observations",
        truth.observations.len()
    );
    let free_points: Vec<usize> = (0..truth.points.len())
        .filter(|&p| !truth.points[p].fixed)
        .collect();
    let runs = 40;
    let options = Options {
        function_tolerance: 1e-12,
        parameter_tolerance: 1e-12,
        max_iterations: 200,
        threads: 1,
        ..Options::default()
    };
    let n_unknowns = 6 * truth.images.len() + 10 + 3 * free_points.len();
    let redundancy = (2 * truth.observations.len() - n_unknowns) as f64;
    // Estimates minus truth, per run: 10 intrinsics then the free point coordinates.
    let mut errors: Vec<Vec<f64>> = Vec::new();
    let mut chi2_sum = 0.0;
    for run in 0..runs {
        let mut p = realisation(&truth, 1000 + run);
        solve(&mut p, &options, |_| {}).unwrap();
        // 2·cost/σ² ~ χ²(redundancy) (cost in σ units is ½Σ(r/σ)²).
        let rms = p.rms_px();
        chi2_sum += rms * rms * (2 * p.observations.len()) as f64 / (SIGMA_PX * SIGMA_PX);
        let mut e: Vec<f64> = (0..10)
            .map(|k| p.cameras[0].params[k] - truth.cameras[0].params[k])
            .collect();
        for &q in &free_points {
            e.extend((p.points[q].position - truth.points[q].position).iter());
        }
        errors.push(e);
    }
    // (1) The mean χ² over the runs: expected `redundancy`, sd √(2·redundancy/runs); 5 sd.
    let chi2_mean = chi2_sum / runs as f64;
    let tol = 5.0 * (2.0 * redundancy / runs as f64).sqrt();
    assert!(
        (chi2_mean - redundancy).abs() < tol,
        "mean χ² {chi2_mean:.1}, redundancy {redundancy}, tol {tol:.1}"
    );
    let rms_expected = SIGMA_PX * (redundancy / (2 * truth.observations.len()) as f64).sqrt();
    println!(
        "RMS image residual: {:.4} px, expected {rms_expected:.4} px",
        (chi2_mean / (2 * truth.observations.len()) as f64).sqrt() * SIGMA_PX
    );

    // (2) Every parameter: the truth within 3 Monte Carlo sd of each estimate, at the
    // normal rate: P(|z| > 3) = 0.27 %; over m·runs trials allow that rate + 5 binomial sd.
    // (3) No bias: |mean error| < 4.5 sd/√runs for every parameter (Bonferroni over m
    // parameters keeps the family-wise false-alarm rate near 1e-3).
    let m = errors[0].len();
    let mut outside = 0usize;
    let mut worst_bias: f64 = 0.0;
    for k in 0..m {
        let xs: Vec<f64> = errors.iter().map(|e| e[k]).collect();
        let mean = xs.iter().sum::<f64>() / runs as f64;
        let sd = (xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (runs as f64 - 1.0)).sqrt();
        assert!(sd > 0.0);
        outside += xs.iter().filter(|x| x.abs() > 3.0 * sd).count();
        worst_bias = worst_bias.max(mean.abs() / (sd / (runs as f64).sqrt()));
        if k < 10 {
            println!(
                "{:>3}: bias {:+.3e}, MC sd {:.3e}",
                ["c", "xp", "yp", "K1", "K2", "K3", "P1", "P2", "B1", "B2"][k],
                mean,
                sd
            );
        }
    }
    let trials = (m * runs as usize) as f64;
    let allowed = 0.0027 * trials + 5.0 * (0.0027 * trials).sqrt();
    println!("truth outside 3 MC sd: {outside} of {trials} (allowed {allowed:.0}); worst normalised bias {worst_bias:.2}");
    assert!(
        (outside as f64) <= allowed,
        "{outside} of {trials} outside 3 sd"
    );
    assert!(worst_bias < 4.5, "worst normalised bias {worst_bias}");
}
