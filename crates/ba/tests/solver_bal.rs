//! The solver on synthetic BAL problems: convergence to the least-squares optimum, whose
//! cost follows the χ² distribution of the image noise; agreement of the dense and sparse
//! paths and of 1 and 2 threads.

use pingcal_ba::solver::{solve, LinearSolverKind, Options, Termination};
use pingcal_ba::synthetic::{SyntheticBal, Visibility};

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
        ..Default::default()
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
        ..Default::default()
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
        ..Default::default()
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

/// The iterative solver (inexact steps, Ceres' forcing rule) reaches the minimum the
/// factorization reaches, on a banded and on a dense (random-visibility) camera graph.
#[test]
fn iterative_solver_reaches_the_factorizations_minimum() {
    for visibility in [Visibility::Banded, Visibility::Random] {
        let s = SyntheticBal {
            cameras: 30,
            points: 2000,
            obs_per_point: 5,
            noise_px: 0.5,
            perturbation: 1.0,
            seed: 4,
            visibility,
        };
        let base = s.generate().unwrap().problem;
        let mut direct = base.clone();
        let d = solve(&mut direct, &tight(LinearSolverKind::Sparse, 2), |_| {}).unwrap();
        let mut iterative = base.clone();
        let i = solve(
            &mut iterative,
            &tight(LinearSolverKind::Iterative, 2),
            |_| {},
        )
        .unwrap();
        assert_eq!(i.linear_solver.kind, LinearSolverKind::Iterative);
        assert!(i.linear_iterations > 0, "{i:?}");
        // The cost near the minimum is flat: a step within the forcing rule's relative
        // model decrease of the exact one changes it by far less than 1e-8 of itself.
        assert!(
            (i.final_cost - d.final_cost).abs() <= 1e-8 * d.final_cost,
            "{visibility:?}: iterative {} vs sparse {} ({} LM iterations, {} CG)",
            i.final_cost,
            d.final_cost,
            i.iterations,
            i.linear_iterations
        );
        // With Ceres' default tolerances too (what `pingcal ba` runs).
        let mut default = base.clone();
        let opts = Options {
            linear_solver: LinearSolverKind::Iterative,
            ..Options::default()
        };
        let i = solve(&mut default, &opts, |_| {}).unwrap();
        assert!(
            (i.final_cost - d.final_cost).abs() <= 1e-4 * d.final_cost,
            "{visibility:?} default tolerances: {} vs {}",
            i.final_cost,
            d.final_cost
        );
    }
}

/// A factorization that would not fit in the memory is refused before anything of its
/// size is allocated, with what it needs; `Auto` takes the iterative solver instead.
#[test]
fn a_reduced_system_too_large_for_the_memory_is_refused_or_solved_iteratively() {
    let s = SyntheticBal {
        cameras: 60,
        points: 2000,
        obs_per_point: 6,
        visibility: Visibility::Random,
        ..Default::default()
    };
    let base = s.generate().unwrap().problem;
    for kind in [LinearSolverKind::Dense, LinearSolverKind::Sparse] {
        let opts = Options {
            linear_solver: kind,
            memory_limit_bytes: Some(1e5),
            ..Options::default()
        };
        let err = solve(&mut base.clone(), &opts, |_| {})
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with(&format!("the {kind} solver needs about "))
                && err.contains("for a reduced system of 540 unknowns, but 0 MB is available")
                && err.contains("--solver iterative"),
            "{err}"
        );
    }
    let opts = Options {
        memory_limit_bytes: Some(1e5),
        ..Options::default()
    };
    let summary = solve(&mut base.clone(), &opts, |_| {}).unwrap();
    assert_eq!(summary.linear_solver.kind, LinearSolverKind::Iterative);
    assert!(
        summary.linear_solver.reason.contains("memory limit"),
        "{}",
        summary.linear_solver.reason
    );
    assert!(summary.final_cost < 0.1 * summary.initial_cost);
}

/// When `Auto` took the iterative solver and a step needs more conjugate-gradient
/// iterations than `switch_after` (here 3, with a forcing constant of 1e-6), it moves to
/// the factorization for the rest of the adjustment, says so, and reaches the same minimum.
#[test]
fn auto_moves_to_the_factorization_when_the_conjugate_gradients_struggle() {
    let s = SyntheticBal {
        cameras: 80,
        points: 3000,
        obs_per_point: 6,
        visibility: Visibility::Random,
        ..Default::default()
    };
    let base = s.generate().unwrap().problem;
    let mut plain = base.clone();
    let chosen = solve(&mut plain, &Options::default(), |_| {}).unwrap();
    assert_eq!(
        chosen.linear_solver.kind,
        LinearSolverKind::Iterative,
        "{}",
        chosen.linear_solver.reason
    );
    let fallback = chosen.linear_solver.fallback.expect("a factorization fits");
    let mut struggling = base.clone();
    let opts = Options {
        cg: pingcal_ba::solver::CgOptions {
            eta: 1e-6,
            switch_after: 3,
            ..Default::default()
        },
        ..Options::default()
    };
    let moved = solve(&mut struggling, &opts, |_| {}).unwrap();
    assert_eq!(moved.linear_solver.kind, fallback);
    assert!(
        moved
            .linear_solver
            .reason
            .contains(&format!("moved to {fallback} at step 1")),
        "{}",
        moved.linear_solver.reason
    );
    let mut direct = base.clone();
    let d = solve(&mut direct, &tight(fallback, 2), |_| {}).unwrap();
    assert!((moved.final_cost - d.final_cost).abs() <= 1e-4 * d.final_cost);
}
