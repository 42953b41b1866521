//! Recovery of known truth with each camera model added beside the photogrammetric one
//! (OpenCV, Kannala–Brandt fisheye, double sphere, Brown backward): the room-corner network of `common`
//! (14 convergent stations with 90° rolls, ~80 points, four fixed control points) imaged
//! through the model under test, image noise σ = 0.3 px, adjusted by
//! [`pingcal_ba::solver::solve`] from approximate intrinsics (nominal focal length,
//! principal point at the array centre, no distortion) and perturbed poses and points.
//!
//! Criteria, per model, over `RUNS` noise realisations, with z = (estimate − truth)/σ̂ for
//! every free intrinsic, σ̂ the adjustment's own standard deviation ([`precision`]):
//! * the mean of z² is 1 within 5 sd of a per-network mean (sd √(2/RUNS)), the rule of
//!   `tests/precision.rs`: the reported precision is honest for the new models too;
//! * |z| > 3 no more often than the normal rate 0.27 % plus 5 binomial sd (the rule of
//!   `tests/recovery.rs`): the truth lies within 3σ of the estimates;
//! * the mean χ² of the image residuals matches the redundancy (5 sd).

use crate::common;
use pingcal_ba::CameraKey;

use common::{observe, realisation, to_convergence, truth, SIGMA_PX};
use nalgebra::Vector3;
use pingcal_ba::camera::{
    opencv_from_photogrammetric, BrownBackwardCamera, CameraModel, DoubleSphereCamera,
    FisheyeCamera, OpenCvCamera, PhotogrammetricCamera,
};
use pingcal_ba::problem::{Camera, Image, Point, Problem};
use pingcal_ba::solver::{precision, solve};
use std::sync::Arc;

const RUNS: u64 = 50;

/// The network of `common`, imaged through `model` with `params`; `fixed` marks the
/// intrinsics held.
fn network(model: Arc<dyn CameraModel>, params: Vec<f64>, fixed: Vec<bool>) -> Problem {
    let mut p = truth();
    let mut cam = Camera::new("cam", model, params);
    cam.fixed = fixed;
    p.cameras = vec![cam];
    p.observations.clear();
    let n = p.images.len();
    observe(&mut p, 0..n);
    p
}

fn recovers_truth(truth: &Problem, approx: &[f64], seed0: u64) {
    let cam = &truth.cameras[0];
    let name = cam.model.name();
    let options = to_convergence();
    let free = cam.free_indices();
    let free_points = truth.points.iter().filter(|x| !x.fixed).count();
    let n_unknowns = 6 * truth.images.len() + free.len() + 3 * free_points;
    let n_obs = 2 * truth.observations.len();
    assert!(n_obs > 1200, "{name}: {n_obs} observations");
    let redundancy = (n_obs - n_unknowns) as f64;
    let (mut sum_z2, mut n_z, mut outside, mut chi2_sum) = (0.0, 0usize, 0usize, 0.0);
    let mut worst_z: f64 = 0.0;
    for run in 0..RUNS {
        let mut p = realisation(truth, seed0 + run);
        p.cameras[0].params = approx.to_vec();
        solve(&mut p, &options, |_| {}).unwrap();
        let rms = p.rms_px();
        chi2_sum += rms * rms * n_obs as f64 / (SIGMA_PX * SIGMA_PX);
        let prec = precision(&p).unwrap();
        let intr = &prec.intrinsics[0];
        assert_eq!(intr.names.len(), free.len(), "{name}");
        for (j, &k) in free.iter().enumerate() {
            assert_eq!(intr.names[j], cam.model.parameter_names()[k]);
            let z = (p.cameras[0].params[k] - cam.params[k]) / intr.sigmas[j];
            sum_z2 += z * z;
            n_z += 1;
            outside += (z.abs() > 3.0) as usize;
            worst_z = worst_z.max(z.abs());
        }
    }
    let chi2_mean = chi2_sum / RUNS as f64;
    let tol_chi2 = 5.0 * (2.0 * redundancy / RUNS as f64).sqrt();
    let mean_z2 = sum_z2 / n_z as f64;
    let tol_z2 = 5.0 * (2.0 / RUNS as f64).sqrt();
    let trials = n_z as f64;
    let allowed = 0.0027 * trials + 5.0 * (0.0027 * trials).sqrt();
    println!(
        "{name}: {} free intrinsics, {n_obs} observations, redundancy {redundancy}; mean χ² \
         {chi2_mean:.1} (±{tol_chi2:.1}); mean z² {mean_z2:.3} (±{tol_z2:.3}); |z| > 3: \
         {outside} of {n_z} (allowed {allowed:.1}); worst |z| {worst_z:.2}",
        free.len()
    );
    assert!(
        (chi2_mean - redundancy).abs() < tol_chi2,
        "{name}: mean χ² {chi2_mean}"
    );
    assert!((mean_z2 - 1.0).abs() < tol_z2, "{name}: mean z² {mean_z2}");
    assert!(
        outside as f64 <= allowed,
        "{name}: {outside} of {n_z} outside 3σ"
    );
}

/// The photogrammetric truth of `common` without affinity, in OpenCV's parameters, plus
/// fx ≠ fy and thin prism terms; k4…k6 held at 0.
#[test]
fn opencv_model_recovers_truth() {
    let pg = PhotogrammetricCamera::new(1280, 720, 0.00375);
    let mut params = opencv_from_photogrammetric(
        &pg,
        &[
            2.45, 0.012, -0.008, -0.021, 4.0e-4, -1.0e-5, 1.5e-4, -1.0e-4, 0.0, 0.0,
        ],
    )
    .unwrap()
    .to_vec();
    params[1] += 0.4; // fy ≠ fx
    params[12] = 2e-4; // s1
    params[14] = -1.5e-4; // s3
    let fixed = (0..16).map(|k| (9..12).contains(&k)).collect();
    let truth = network(Arc::new(OpenCvCamera), params, fixed);
    let mut approx = vec![0.0; 16];
    approx[..4].copy_from_slice(&[640.0, 640.0, 639.5, 359.5]);
    recovers_truth(&truth, &approx, 7000);
}

/// A fisheye of ~110° diagonal field on the same sensor; all eight intrinsics free.
#[test]
fn fisheye_model_recovers_truth() {
    let params = vec![560.0, 560.5, 641.0, 357.5, 0.05, -0.01, 0.002, -3e-4];
    let truth = network(Arc::new(FisheyeCamera), params, vec![false; 8]);
    let approx = [550.0, 550.0, 639.5, 359.5, 0.0, 0.0, 0.0, 0.0];
    recovers_truth(&truth, &approx, 8000);
}

/// A room (4 × 4 × 3 m, ~220 points on its six faces, four of them control) photographed
/// from 12 stations inside it, so that a fisheye sees it over its whole field: the network
/// a lens beyond 180° is calibrated in (the room corner of `common`, 2.6 m away, fills only
/// the middle of such a lens, where its ξ and α are not separable).
fn room_network(model: Arc<dyn CameraModel>, params: Vec<f64>) -> Problem {
    let mut points = Vec::new();
    let grid = |n: usize, k: usize, half: f64| -half + 2.0 * half * k as f64 / (n - 1) as f64;
    for i in 0..7 {
        for j in 0..6 {
            let (a, b) = (grid(7, i, 1800.0), grid(6, j, 1300.0));
            points.push(Vector3::new(a, 2000.0, b));
            points.push(Vector3::new(a, -2000.0, b));
            points.push(Vector3::new(2000.0, a, b));
            points.push(Vector3::new(-2000.0, a, b));
        }
    }
    for i in 0..6 {
        for j in 0..6 {
            let (a, b) = (grid(6, i, 1700.0), grid(6, j, 1700.0));
            points.push(Vector3::new(a, b, -1500.0));
            points.push(Vector3::new(a, b, 1500.0));
        }
    }
    let mut p = Problem {
        cameras: vec![Camera::new("cam", model, params)],
        ..Problem::default()
    };
    for (q, x) in points.iter().enumerate() {
        p.points.push(Point {
            name: format!("P{q}"),
            position: *x,
            fixed: [0, 50, 130, 200].contains(&q),
            fixed_axes: [false; 3],
        });
    }
    for k in 0..12 {
        let az = std::f64::consts::TAU * k as f64 / 12.0;
        let centre = Vector3::new(
            300.0 * (3.0 * az).cos(),
            300.0 * az.sin(),
            [-300.0, 0.0, 300.0][k % 3],
        );
        let look = centre + Vector3::new(az.cos(), az.sin(), [-0.4, 0.0, 0.5][k % 3]);
        let roll = [0.0, std::f64::consts::FRAC_PI_2, 0.7][k % 3];
        p.images.push(Image {
            name: format!("S{k:02}"),
            camera: CameraKey(0),
            camera_from_object: pingcal_geometry::Rigid3::looking_at(centre, look, roll),
            fixed: false,
            fixed_centre: [false; 3],
        });
    }
    let n = p.images.len();
    observe(&mut p, 0..n);
    p
}

/// A double-sphere lens of about 200° (ξ, α as Usenko et al. fit such lenses) in the room;
/// all six intrinsics free, started from the model's nominal lens of the nominal focal
/// length ([`pingcal_ba::camera::ModelKind::nominal`]).
#[test]
fn double_sphere_model_recovers_truth() {
    let params = vec![250.0, 250.4, 641.0, 357.5, -0.17, 0.59];
    let truth = room_network(Arc::new(DoubleSphereCamera), params);
    let approx = pingcal_ba::camera::ModelKind::DoubleSphere.nominal(290.0, 1280, 720, 0.00375);
    recovers_truth(&truth, &approx, 10_000);
}

/// Brown backward with the size of correction of the MYNT-like lens (K1 r² ~ 16 % at the
/// corner), affinity and shear; all ten intrinsics free.
#[test]
fn brown_backward_model_recovers_truth() {
    let model = Arc::new(BrownBackwardCamera::new(1280, 720, 0.00375));
    let params = vec![
        2.45, 0.012, -0.008, 0.021, -3.0e-4, 1.0e-5, -1.5e-4, 1.0e-4, 2.0e-4, -1.0e-4,
    ];
    let truth = network(model, params, vec![false; 10]);
    let mut approx = vec![0.0; 10];
    approx[0] = 2.4;
    recovers_truth(&truth, &approx, 9000);
}

/// The models agree with each other where they must: a fisheye with k = 0 is the
/// equidistant projection, and OpenCV with no distortion is the pinhole.
#[test]
fn undistorted_models_are_the_textbook_projections() {
    let xc = Vector3::new(0.4, 1.3, -0.25);
    let t = (0.4f64.hypot(0.25)).atan2(1.3);
    let uv = FisheyeCamera
        .project(
            &[500.0, 500.0, 640.0, 360.0, 0.0, 0.0, 0.0, 0.0],
            &xc,
            None,
            None,
        )
        .unwrap();
    let rho = 0.4f64.hypot(0.25);
    assert!((uv.x - (640.0 + 500.0 * t * 0.4 / rho)).abs() < 1e-10);
    assert!((uv.y - (360.0 + 500.0 * t * 0.25 / rho)).abs() < 1e-10);
    let mut p = [0.0; 16];
    p[..4].copy_from_slice(&[500.0, 500.0, 640.0, 360.0]);
    let uv = OpenCvCamera.project(&p, &xc, None, None).unwrap();
    assert!((uv.x - (640.0 + 500.0 * 0.4 / 1.3)).abs() < 1e-10);
    assert!((uv.y - (360.0 + 500.0 * 0.25 / 1.3)).abs() < 1e-10);
}
