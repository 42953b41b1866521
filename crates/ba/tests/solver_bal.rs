//! The solver on synthetic BAL problems: convergence to the least-squares optimum, whose
//! cost follows the χ² distribution of the image noise; agreement of the dense and sparse
//! paths and of 1 and 2 threads.

use pingcal_ba::solver::{solve, LinearSolverKind, Options, Termination};
use pingcal_ba::synthetic::SyntheticBal;

fn tight(kind: LinearSolverKind, threads: usize) -> Options {
    Options {
        max_iterations: 100,
        function_tolerance: 1e-12,
        gradient_tolerance: 1e-12,
        parameter_tolerance: 1e-12,
        linear_solver: kind,
        threads,
        ..Options::default()
    }
}

/// Degrees of freedom of the residual: 2·observations − (parameters − 7 gauge freedoms of
/// a free network: rotation, translation, scale).
fn dof(p: &pingcal_ba::problem::Problem) -> f64 {
    (2 * p.observations.len()) as f64 - (9 * p.images.len() + 3 * p.points.len() - 7) as f64
}

#[test]
fn final_cost_is_the_chi_square_of_the_noise() {
    let sigma = 0.5;
    let s = SyntheticBal {
        cameras: 40,
        points: 3000,
        obs_per_point: 5,
        noise_px: sigma,
        perturbation: 1.0,
        seed: 3,
    };
    let mut p = s.generate().unwrap().problem;
    let summary = solve(&mut p, &tight(LinearSolverKind::Sparse, 2), |_| {}).unwrap();
    assert!(!summary.dense);
    // 2·cost/σ² ~ χ²(dof): mean dof, standard deviation √(2 dof). A 5-sd band has a false
    // alarm probability below 1e-6.
    let n = dof(&p);
    let chi2 = 2.0 * summary.final_cost / (sigma * sigma);
    assert!(
        (chi2 - n).abs() < 5.0 * (2.0 * n).sqrt(),
        "χ² {chi2} vs dof {n}: {summary:?}"
    );
    assert!(
        summary.initial_cost > 10.0 * summary.final_cost,
        "{summary:?}"
    );
    assert!(matches!(
        summary.termination,
        Termination::FunctionTolerance
            | Termination::GradientTolerance
            | Termination::ParameterTolerance
    ));
}

#[test]
fn dense_and_sparse_paths_and_thread_counts_reach_the_same_cost() {
    let s = SyntheticBal {
        cameras: 25,
        points: 1500,
        obs_per_point: 4,
        noise_px: 1.0,
        perturbation: 1.0,
        seed: 9,
    };
    let base = s.generate().unwrap().problem;
    let mut costs = Vec::new();
    for (kind, threads) in [
        (LinearSolverKind::Dense, 1),
        (LinearSolverKind::Sparse, 1),
        (LinearSolverKind::Sparse, 2),
    ] {
        let mut p = base.clone();
        let summary = solve(&mut p, &tight(kind, threads), |_| {}).unwrap();
        assert_eq!(summary.dense, kind == LinearSolverKind::Dense);
        costs.push(summary.final_cost);
    }
    for c in &costs[1..] {
        // Same minimum: the cost is flat there, so its relative difference is far below the
        // relative step tolerance.
        assert!((c - costs[0]).abs() <= 1e-9 * costs[0], "{costs:?}");
    }
}

#[test]
fn a_point_behind_a_camera_is_named() {
    let s = SyntheticBal {
        cameras: 3,
        points: 20,
        obs_per_point: 2,
        noise_px: 0.0,
        perturbation: 0.0,
        seed: 1,
    };
    let mut p = s.generate().unwrap().problem;
    // Move point 7 onto the projection plane of its first camera: the BAL model cannot
    // image it there.
    let o = *p.observations.iter().find(|o| o.point == 7).unwrap();
    let pose = p.images[o.image].camera_from_object;
    let xc = pose.transform(&p.points[7].position);
    let on_plane = nalgebra::Vector3::new(xc.x, xc.y, 0.0);
    p.points[7].position = pose.inverse().transform(&on_plane);
    let err = solve(&mut p, &Options::default(), |_| {})
        .unwrap_err()
        .to_string();
    assert_eq!(
        err,
        format!(
            "point '7' cannot be projected into image 'image{}' (behind the camera?)",
            o.image
        )
    );
}
