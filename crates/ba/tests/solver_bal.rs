//! The solver on synthetic BAL problems: convergence to the least-squares optimum, whose
//! cost follows the χ² distribution of the image noise; agreement of the dense and sparse
//! paths and of 1 and 2 threads.

use pingcal_ba::solver::{
    solve, CgOptions, LinearSolverKind, Options, Preconditioner, SchurProduct, Termination,
};
use pingcal_ba::synthetic::{SyntheticBal, Visibility};
use pingcal_ba::PointKey;

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
    let o = *p
        .observations
        .iter()
        .find(|o| o.point == PointKey(7))
        .unwrap();
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

/// The iterative solver (inexact steps, Ceres' forcing rule), with either preconditioner,
/// reaches the minimum the factorization reaches, on a banded and on a dense
/// (random-visibility) camera graph.
#[test]
fn iterative_solver_reaches_the_factorizations_minimum() {
    let preconditioners = [
        Preconditioner::SchurJacobi,
        Preconditioner::ClusterJacobi { max_dim: 90 },
    ];
    let products = [SchurProduct::Implicit, SchurProduct::Explicit];
    for (visibility, preconditioner, product) in [Visibility::Banded, Visibility::Random]
        .into_iter()
        .flat_map(|v| preconditioners.map(|p| (v, p)))
        .flat_map(|(v, p)| products.map(|q| (v, p, q)))
    {
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
        let cg = CgOptions {
            preconditioner,
            product,
            ..CgOptions::default()
        };
        let mut iterative = base.clone();
        let i = solve(
            &mut iterative,
            &Options {
                cg,
                ..tight(LinearSolverKind::Iterative, 2)
            },
            |_| {},
        )
        .unwrap();
        assert_eq!(i.linear_solver.kind, LinearSolverKind::Iterative);
        assert_eq!(i.schur_product.as_ref().map(|p| p.product), Some(product));
        assert!(i.linear_iterations > 0, "{i:?}");
        // The cost near the minimum is flat: a step within the forcing rule's relative
        // model decrease of the exact one changes it by far less than 1e-8 of itself.
        assert!(
            (i.final_cost - d.final_cost).abs() <= 1e-8 * d.final_cost,
            "{visibility:?}, {preconditioner:?}, {product}: iterative {} vs sparse {} ({} LM iterations, {} CG)",
            i.final_cost,
            d.final_cost,
            i.iterations,
            i.linear_iterations
        );
        // With Ceres' default tolerances too (what `pingcal ba` runs).
        let mut default = base.clone();
        let opts = Options {
            linear_solver: LinearSolverKind::Iterative,
            cg,
            ..Options::default()
        };
        let i = solve(&mut default, &opts, |_| {}).unwrap();
        assert!(
            (i.final_cost - d.final_cost).abs() <= 1e-4 * d.final_cost,
            "{visibility:?}, {preconditioner:?}, {product}, default tolerances: {} vs {}",
            i.final_cost,
            d.final_cost
        );
    }
}

/// Cluster-Jacobi along a street: the images are cut into runs of neighbours, none larger
/// than asked, and the conjugate gradients need far fewer iterations than with
/// Schur–Jacobi for the same minimum; clusters too large for the memory are not used. On
/// a dense random camera graph no two images are
/// similar enough: every image stays alone and the adjustment is Schur–Jacobi's, to the
/// last bit.
#[test]
fn cluster_jacobi_clusters_a_street_and_leaves_a_random_graph_alone() {
    let run = |visibility, preconditioner, memory_limit_bytes| {
        let cg = CgOptions {
            preconditioner,
            // The preconditioner is built from the observations, whatever the memory.
            product: SchurProduct::Implicit,
            ..CgOptions::default()
        };
        iterative_on_120_images(visibility, cg, memory_limit_bytes).unwrap()
    };
    let cluster = Preconditioner::ClusterJacobi { max_dim: 180 };
    let sj = run(Visibility::Banded, Preconditioner::SchurJacobi, None);
    let cj = run(Visibility::Banded, cluster, None);
    assert!(sj.clusters.is_none());
    let stats = cj.clusters.expect("cluster statistics");
    assert_eq!(stats.blocks, 120);
    assert!(stats.largest_dim <= 180, "{stats:?}");
    // 120 images of 9 unknowns in clusters of at most 20: at least 6, and single linkage
    // leaves few fragments.
    assert!((6..=12).contains(&stats.clusters), "{stats:?}");
    assert!(stats.captured > 0.5, "{stats:?}");
    assert!(
        (cj.final_cost - sj.final_cost).abs() <= 1e-8 * sj.final_cost,
        "{} vs {}",
        cj.final_cost,
        sj.final_cost
    );
    println!(
        "street of 120 images: {} clusters (largest {} unknowns, {:.0} % of the similarity); CG iterations cluster-Jacobi {}, Schur–Jacobi {}",
        stats.clusters,
        stats.largest_dim,
        100.0 * stats.captured,
        cj.linear_iterations,
        sj.linear_iterations
    );
    // Iteration counts are deterministic for a given problem; the bound leaves room for a
    // change of the forcing rule's rounding.
    assert!(
        (cj.linear_iterations as f64) < 0.6 * sj.linear_iterations as f64,
        "cluster-Jacobi {} CG iterations, Schur–Jacobi {}",
        cj.linear_iterations,
        sj.linear_iterations
    );
    // Clusters whose matrices do not fit in the memory: Schur–Jacobi, said in the summary.
    // (120 blocks of 81 values and their 3 copies fit in 1 MB; 8 clusters of 180² do not.)
    let small = run(Visibility::Banded, cluster, Some(1e6));
    let stats = small.clusters.expect("cluster statistics");
    assert!(stats.too_large_bytes > 1e6, "{stats:?}");
    assert_eq!(small.final_cost.to_bits(), sj.final_cost.to_bits());
    assert_eq!(small.linear_iterations, sj.linear_iterations);
    let sj = run(Visibility::Random, Preconditioner::SchurJacobi, None);
    let cj = run(Visibility::Random, cluster, None);
    let stats = cj.clusters.expect("cluster statistics");
    assert_eq!(stats.clusters, stats.blocks, "{stats:?}");
    assert_eq!(stats.captured, 0.0);
    assert_eq!(cj.final_cost.to_bits(), sj.final_cost.to_bits());
    assert_eq!(cj.linear_iterations, sj.linear_iterations);
}

/// The conjugate gradients multiply by S explicitly along a street (few neighbours per
/// image: a sparse S, and clusters that would cost the assembly's work anyway) and
/// implicitly on a dense random camera graph (a dense S), by default; both forms take the
/// same iterations to the same minimum. An explicit product that does not fit in the memory
/// is refused by name, and `Auto` then keeps the implicit one.
#[test]
fn the_schur_product_is_explicit_along_a_street_and_implicit_on_a_dense_graph() {
    let run = |visibility, product, memory_limit_bytes| {
        let cg = CgOptions {
            product,
            ..CgOptions::default()
        };
        iterative_on_120_images(visibility, cg, memory_limit_bytes)
    };
    let product = |s: &pingcal_ba::solver::Summary| s.schur_product.as_ref().unwrap().product;
    let street = run(Visibility::Banded, SchurProduct::Auto, None).unwrap();
    assert_eq!(
        product(&street),
        SchurProduct::Explicit,
        "{:?}",
        street.schur_product
    );
    let implicit = run(Visibility::Banded, SchurProduct::Implicit, None).unwrap();
    assert!(
        (street.final_cost - implicit.final_cost).abs() <= 1e-10 * implicit.final_cost,
        "explicit {} vs implicit {}",
        street.final_cost,
        implicit.final_cost
    );
    // The same operator in another order of sums: the forcing rule stops at the same
    // iteration but for a rounding tie now and then.
    let (a, b) = (street.linear_iterations, implicit.linear_iterations);
    assert!(
        a.abs_diff(b) * 100 <= b,
        "CG iterations explicit {a}, implicit {b}"
    );
    let dense = run(Visibility::Random, SchurProduct::Auto, None).unwrap();
    assert_eq!(
        product(&dense),
        SchurProduct::Implicit,
        "{:?}",
        dense.schur_product
    );
    // S of 120 images along a street needs ~1 MB to assemble.
    let err = run(Visibility::Banded, SchurProduct::Explicit, Some(1e5))
        .unwrap_err()
        .to_string();
    assert!(
        err.starts_with("the explicit Schur product needs about ")
            && err.contains("1080 unknowns")
            && err.contains("--schur-product implicit"),
        "{err}"
    );
    let kept = run(Visibility::Banded, SchurProduct::Auto, Some(1e5)).unwrap();
    let choice = kept.schur_product.unwrap();
    assert_eq!(choice.product, SchurProduct::Implicit);
    assert!(choice.reason.contains("does not fit"), "{}", choice.reason);
}

/// The iterative solver with `cg` on 120 images and 12,000 points (a street or a dense
/// random graph), 2 threads, function tolerance 1e-10.
fn iterative_on_120_images(
    visibility: Visibility,
    cg: CgOptions,
    memory_limit_bytes: Option<f64>,
) -> Result<pingcal_ba::solver::Summary, pingcal_ba::solver::SolveError> {
    let s = SyntheticBal {
        cameras: 120,
        points: 12000,
        obs_per_point: 6,
        visibility,
        ..Default::default()
    };
    let mut p = s.generate().unwrap().problem;
    let opts = Options {
        linear_solver: LinearSolverKind::Iterative,
        function_tolerance: 1e-10,
        cg,
        threads: 2,
        memory_limit_bytes,
        ..Options::default()
    };
    solve(&mut p, &opts, |_| {})
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
