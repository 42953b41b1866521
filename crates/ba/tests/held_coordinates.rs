//! Single coordinates held (`Point::fixed_axes`): on the self-calibration network of
//! `common`, a minimal datum of 3 + 3 + 1 point coordinates (no fixed image) solves with the
//! held coordinates exactly at their values; two different minimal datums give the same
//! network up to a similarity, and the same intrinsics with the same σ as a free network
//! (intrinsics are estimable); on consistent observations the distances between points are
//! those of the classical datum (4 fixed points); held coordinates have σ exactly 0; the
//! datum diagnosis counts held coordinates (too little names the open motion, too much the
//! held coordinates); and every linear solver reaches the same minimum.

mod common;

use common::{realisation, truth};
use nalgebra::{Matrix3, Vector3};
use pingcal_ba::datum::{check, Datum, DatumError};
use pingcal_ba::problem::{Distance, PointPrior, Problem};
use pingcal_ba::solver::{precision, solve, LinearSolverKind, Options, PrecisionError};

fn options(kind: LinearSolverKind) -> Options {
    Options {
        function_tolerance: 1e-14,
        gradient_tolerance: 1e-14,
        parameter_tolerance: 1e-14,
        max_iterations: 200,
        linear_solver: kind,
        threads: 1,
        ..Options::default()
    }
}

/// (point, held axes) of a minimal datum: X, Y, Z of two points and one coordinate of a
/// third.
type Holds = [(usize, [bool; 3]); 3];
const DATUM_A: Holds = [(0, [true; 3]), (40, [true; 3]), (70, [false, false, true])];
const DATUM_B: Holds = [(12, [true; 3]), (70, [true; 3]), (5, [true, false, false])];

/// The network with nothing fixed, from the noisy realisation `seed` (`None`: consistent
/// observations), started from the perturbed truth, with the coordinates `holds` held at
/// their true values.
fn network(seed: Option<u64>, holds: &[(usize, [bool; 3])]) -> Problem {
    let mut t = truth();
    t.points.iter_mut().for_each(|p| p.fixed = false);
    let mut p = realisation(&t, seed.unwrap_or(1));
    if seed.is_none() {
        for (o, ot) in p.observations.iter_mut().zip(&t.observations) {
            o.uv = ot.uv;
        }
    }
    for &(k, axes) in holds {
        p.points[k].fixed_axes = axes;
        for a in (0..3).filter(|&a| axes[a]) {
            p.points[k].position[a] = t.points[k].position[a];
        }
    }
    p
}

/// Every held coordinate is bit for bit what it was before the adjustment.
fn assert_held(before: &Problem, after: &Problem) {
    for (b, a) in before.points.iter().zip(&after.points) {
        for k in (0..3).filter(|&k| b.held()[k]) {
            assert_eq!(
                b.position[k].to_bits(),
                a.position[k].to_bits(),
                "held coordinate {k} of '{}' moved: {} → {}",
                b.name,
                b.position[k],
                a.position[k]
            );
        }
    }
}

/// The largest distance between the points of `a` and those of `b` mapped onto them by
/// the least-squares similarity (Umeyama), relative to the spread of `a`.
fn similarity_misfit(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> f64 {
    let n = a.len() as f64;
    let (ca, cb) = (
        a.iter().sum::<Vector3<f64>>() / n,
        b.iter().sum::<Vector3<f64>>() / n,
    );
    let mut cov = Matrix3::zeros();
    let mut var_b = 0.0;
    for (x, y) in a.iter().zip(b) {
        cov += (x - ca) * (y - cb).transpose();
        var_b += (y - cb).norm_squared();
    }
    let svd = cov.svd(true, true);
    let (u, vt) = (svd.u.unwrap(), svd.v_t.unwrap());
    let mut d = Matrix3::identity();
    if (u * vt).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    let r = u * d * vt;
    let s = (svd.singular_values.component_mul(&d.diagonal())).sum() / var_b;
    let spread = (a.iter().map(|x| (x - ca).norm_squared()).sum::<f64>() / n).sqrt();
    (a.iter().zip(b))
        .map(|(x, y)| (x - (ca + s * r * (y - cb))).norm())
        .fold(0.0, f64::max)
        / spread
}

fn positions(p: &Problem) -> Vec<Vector3<f64>> {
    p.points.iter().map(|x| x.position).collect()
}

fn relative(a: f64, b: f64) -> f64 {
    (a - b).abs() / a.abs().max(b.abs())
}

/// (a) Two different minimal datums of single coordinates give the same network up to a
/// similarity, the same cost and the same intrinsics; the held coordinates do not move.
#[test]
fn two_minimal_datums_agree_up_to_a_similarity() {
    let mut a = network(Some(7), &DATUM_A);
    let mut b = network(Some(7), &DATUM_B);
    let (a0, b0) = (a.clone(), b.clone());
    let sa = solve(&mut a, &options(LinearSolverKind::Sparse), |_| {}).unwrap();
    let sb = solve(&mut b, &options(LinearSolverKind::Sparse), |_| {}).unwrap();
    assert_held(&a0, &a);
    assert_held(&b0, &b);
    assert!(
        relative(sa.final_cost, sb.final_cost) < 1e-9,
        "costs {} vs {}",
        sa.final_cost,
        sb.final_cost
    );
    let misfit = similarity_misfit(&positions(&a), &positions(&b));
    println!("datum A vs B: similarity misfit {misfit:.2e} of the spread");
    assert!(misfit < 1e-6, "misfit {misfit}");
    for (x, y) in a.cameras[0].params.iter().zip(&b.cameras[0].params) {
        assert!((x - y).abs() <= 1e-6 * x.abs().max(1e-3), "{x} vs {y}");
    }
}

/// (a) On consistent observations the minimal datum gives the distances between points of
/// the classical datum (4 fixed points) to 1e-6 relative.
#[test]
fn distances_equal_those_of_the_classical_datum() {
    let mut minimal = network(None, &DATUM_A);
    let start = minimal.clone();
    solve(&mut minimal, &options(LinearSolverKind::Sparse), |_| {}).unwrap();
    assert_held(&start, &minimal);
    let t = truth();
    let mut classical = realisation(&t, 1);
    for (o, ot) in classical.observations.iter_mut().zip(&t.observations) {
        o.uv = ot.uv;
    }
    solve(&mut classical, &options(LinearSolverKind::Sparse), |_| {}).unwrap();
    let (pm, pc) = (positions(&minimal), positions(&classical));
    let mut worst: f64 = 0.0;
    for i in 0..pm.len() {
        for j in i + 1..pm.len() {
            worst = worst.max(relative((pm[i] - pm[j]).norm(), (pc[i] - pc[j]).norm()));
        }
    }
    println!("largest relative difference of the distances: {worst:.2e}");
    assert!(worst < 1e-6, "{worst}");
}

/// (b) Held coordinates have σ exactly 0 (the others of the same point not); the
/// intrinsics' σ (estimable) are the same under two minimal datums and in the free
/// network (inner constraints), as is σ0.
#[test]
fn held_coordinates_have_zero_sigma_and_intrinsics_sigma_do_not_depend_on_the_datum() {
    let solved = |holds: &[(usize, [bool; 3])]| {
        let mut p = network(Some(11), holds);
        solve(&mut p, &options(LinearSolverKind::Sparse), |_| {}).unwrap();
        let prec = precision(&p).unwrap();
        (p, prec)
    };
    let (pa, a) = solved(&DATUM_A);
    let (_, b) = solved(&DATUM_B);
    let (_, free) = solved(&[]);
    for &(k, axes) in &DATUM_A {
        // A point held whole is no unknown (no covariance, as a fixed point).
        let Some(sigma) = a.point_sigma(k) else {
            assert!(pa.points[k].is_held());
            continue;
        };
        assert!(pa.points[k].is_partly_held());
        for ax in 0..3 {
            if axes[ax] {
                assert_eq!(sigma[ax], 0.0, "held {ax} of '{}'", pa.points[k].name);
            } else {
                assert!(
                    sigma[ax] > 1e-3,
                    "free {ax} of '{}': {}",
                    pa.points[k].name,
                    sigma[ax]
                );
            }
        }
    }
    // The unknowns are 7 fewer than in the free network, which has 7 more in its datum:
    // the same redundancy.
    assert_eq!(a.redundancy, free.redundancy);
    assert_eq!(a.redundancy, b.redundancy);
    assert!(relative(a.sigma0, free.sigma0) < 1e-6);
    let mut worst: f64 = 0.0;
    for other in [&b, &free] {
        for (x, y) in a.intrinsics[0]
            .sigmas
            .iter()
            .zip(&other.intrinsics[0].sigmas)
        {
            worst = worst.max(relative(*x, *y));
        }
    }
    println!("intrinsics σ: largest relative difference {worst:.2e}");
    assert!(worst < 1e-6, "{worst}");
}

/// (c) The datum diagnosis counts held coordinates (a point held whole by its three axes
/// is a fixed control point): 6 of them leave a rotation open and say so, 7 are a minimal
/// datum, a third coordinate in the vertical plane of the first two points fixes nothing
/// more, a distance gives the scale, and held coordinates with a free network are too
/// much. The solver's precision agrees: 6 is a datum defect of 1 degree of freedom.
#[test]
fn the_datum_check_counts_held_coordinates() {
    // Two points held whole: the rotation about their line.
    let two = network(Some(3), &DATUM_A[..2]);
    let e = check(&two, false).unwrap_err();
    assert_eq!(
        e.to_string(),
        "the datum is not defined: 2 fixed control points leave the rotation about their line free: 3 not on one line are needed, or ask for a free network"
    );
    // Six single coordinates: X, Y, Z of P0, X, Y of P40, Z of P70.
    let six_holds = [
        (0, [true; 3]),
        (40, [true, true, false]),
        (70, [false, false, true]),
    ];
    let six = network(Some(3), &six_holds);
    let e = check(&six, false).unwrap_err();
    let msg = e.to_string();
    println!("{msg}");
    assert!(matches!(e, DatumError::TooLittle(_)), "{msg}");
    assert!(
        msg.contains("1 fixed control point, 3 held coordinates (X, Y of 'P40'; Z of 'P70') leave 1 degree of freedom of the network's position, orientation and scale open (")
            && msg.contains("7 independent held coordinates are needed"),
        "{msg}"
    );
    let seven = network(Some(3), &DATUM_A);
    assert_eq!(
        check(&seven, false),
        Ok(Datum::Given {
            fixed_control: 2,
            weighted_control: 0,
            fixed_images: 0,
            fixed_rigs: 0,
            held_coordinates: 1,
        })
    );
    let e = check(&seven, true).unwrap_err();
    assert!(
        matches!(e, DatumError::TooMuch(_))
            && e.to_string()
                .contains("1 held coordinate (Z of 'P70') already fix"),
        "{e}"
    );
    // Z of a point in the vertical plane through P0 and P40 does not fix the rotation about
    // their line (it moves that point horizontally).
    let mut plane = network(Some(3), &DATUM_A[..2]);
    let (x0, x1) = (plane.points[0].position, plane.points[40].position);
    let mut q = plane.points[70].clone();
    q.name = "in-plane".into();
    q.position = x0 + 0.3 * (x1 - x0) + Vector3::new(0.0, 0.0, 500.0);
    q.fixed_axes = [false, false, true];
    plane.points.push(q);
    let e = check(&plane, false).unwrap_err();
    assert!(e.to_string().contains("leave 1 degree of freedom"), "{e}");
    // The six single coordinates and a distance for the scale.
    let mut scaled = six.clone();
    scaled.distances.push(Distance {
        a: 12,
        b: 5,
        value: (scaled.points[12].position - scaled.points[5].position).norm(),
        sigma: 0.01,
    });
    assert!(check(&scaled, false).is_ok());
    // The adjustment's precision finds the same defect.
    let mut six = six;
    solve(&mut six, &options(LinearSolverKind::Sparse), |_| {}).unwrap();
    match precision(&six) {
        Err(PrecisionError::DatumDefect(m)) => {
            println!("{m}");
            assert!(m.starts_with("1 degrees of freedom"), "{m}")
        }
        other => panic!("expected a datum defect, got {:?}", other.map(|p| p.sigma0)),
    }
}

/// (d) Dense, sparse and iterative solvers reach the same minimum with held coordinates,
/// also on a partly held point that a distance joins to another and that has a prior on
/// its free coordinates; the held coordinates stay exact in every one.
#[test]
fn every_solver_reaches_the_same_minimum() {
    let mut base = network(Some(5), &DATUM_A);
    base.points[33].fixed_axes = [true, false, false];
    base.distances.push(Distance {
        a: 70,
        b: 33,
        value: (truth().points[70].position - truth().points[33].position).norm(),
        sigma: 0.05,
    });
    base.point_priors.push(PointPrior {
        point: 70,
        position: truth().points[70].position,
        sigma: Vector3::new(2.0, 2.0, 2.0),
    });
    let mut results = Vec::new();
    for kind in [
        LinearSolverKind::Dense,
        LinearSolverKind::Sparse,
        LinearSolverKind::Iterative,
    ] {
        let mut p = base.clone();
        let s = solve(&mut p, &options(kind), |_| {}).unwrap();
        assert_eq!(s.linear_solver.kind, kind);
        assert_held(&base, &p);
        results.push((kind, s.final_cost, p));
    }
    let (_, cost0, p0) = &results[0];
    let spread = 3000.0;
    for (kind, cost, p) in &results[1..] {
        assert!(relative(*cost, *cost0) < 1e-9, "{kind}: {cost} vs {cost0}");
        let worst = (p.points.iter().zip(&p0.points))
            .map(|(a, b)| (a.position - b.position).norm())
            .fold(0.0, f64::max);
        println!("{kind}: largest point difference to dense {worst:.2e} mm");
        assert!(worst < 1e-6 * spread, "{kind}: {worst}");
        for (x, y) in p.cameras[0].params.iter().zip(&p0.cameras[0].params) {
            assert!(
                (x - y).abs() <= 1e-7 * x.abs().max(1e-3),
                "{kind}: {x} vs {y}"
            );
        }
    }
}

/// Poses: X, Y, Z of the projection centres of S00 and S07 and Z of P70 are a minimal datum
/// (no point held whole, no fixed image). It solves with the held centre coordinates in
/// place to rounding (the pose is stored as (R, t), the centre recomputed), gives the point
/// datum's network up to a similarity and the same intrinsics' σ, a held centre coordinate
/// has σ 0, the datum check counts the centre coordinates, and the dense, sparse and
/// iterative solvers agree, also with a pose prior on an image whose centre is held (the
/// residual's Jacobian taken to the unknowns (δω, δC)).
#[test]
fn held_centre_coordinates_are_an_exact_datum() {
    let t = truth();
    let centred = |seed: u64, prior: bool| {
        let mut p = network(Some(seed), &[(70, [false, false, true])]);
        for (i, axes) in [
            (0usize, [true; 3]),
            (7, [true; 3]),
            (3, [false, false, true]),
        ] {
            if i == 3 && !prior {
                continue;
            }
            let pose = p.images[i].camera_from_object;
            let mut c = pose.centre();
            let ct = t.images[i].camera_from_object.centre();
            for a in (0..3).filter(|&a| axes[a]) {
                c[a] = ct[a];
            }
            p.images[i].camera_from_object =
                pingcal_geometry::Rigid3::from_rotation_and_centre(pose.rotation, c);
            p.images[i].fixed_centre = axes;
        }
        if prior {
            p.residuals
                .push(pingcal_ba::ResidualBlock::new(pingcal_ba::PosePrior {
                    image: 7,
                    camera_from_object: t.images[7].camera_from_object,
                    sigma_rotation: Vector3::repeat(1e-3),
                    sigma_centre: Vector3::repeat(f64::INFINITY),
                }));
        }
        p
    };
    let mut p = centred(13, false);
    assert_eq!(
        check(&p, false),
        Ok(Datum::Given {
            fixed_control: 0,
            weighted_control: 0,
            fixed_images: 0,
            fixed_rigs: 0,
            held_coordinates: 7,
        })
    );
    let mut six = p.clone();
    six.points[70].fixed_axes = [false; 3];
    assert!(check(&six, false)
        .unwrap_err()
        .to_string()
        .contains("6 held coordinates (X, Y, Z of the centre of 'S00'; X, Y, Z of the centre of 'S07') leave 1 degree of freedom"));
    let start = p.clone();
    solve(&mut p, &options(LinearSolverKind::Sparse), |_| {}).unwrap();
    let mut drift: f64 = 0.0;
    for i in [0usize, 7] {
        let (c0, c1) = (
            start.images[i].camera_from_object.centre(),
            p.images[i].camera_from_object.centre(),
        );
        drift = drift.max((c0 - c1).amax());
    }
    println!("largest drift of a held centre coordinate: {drift:.2e} mm");
    assert!(drift < 1e-9, "{drift}");
    assert_held(&start, &p);
    let mut a = network(Some(13), &DATUM_A);
    solve(&mut a, &options(LinearSolverKind::Sparse), |_| {}).unwrap();
    let misfit = similarity_misfit(&positions(&a), &positions(&p));
    println!("centre datum vs point datum: similarity misfit {misfit:.2e} of the spread");
    assert!(misfit < 1e-6, "{misfit}");
    let (pp, pa) = (precision(&p).unwrap(), precision(&a).unwrap());
    let s = pp.poses[0].as_ref().unwrap();
    assert_eq!(s.centre, [0.0; 3]);
    assert!(s.rotation_rad.iter().all(|v| *v > 0.0));
    assert!(pp.poses[1]
        .as_ref()
        .unwrap()
        .centre
        .iter()
        .all(|v| *v > 0.0));
    assert_eq!(pp.redundancy, pa.redundancy);
    let worst = (pp.intrinsics[0].sigmas.iter().zip(&pa.intrinsics[0].sigmas))
        .map(|(x, y)| relative(*x, *y))
        .fold(0.0, f64::max);
    println!("intrinsics σ, centre vs point datum: largest relative difference {worst:.2e}");
    assert!(worst < 1e-6, "{worst}");
    // Every solver, with a partly held centre and a prior on a held-centre image.
    let base = centred(17, true);
    let mut results = Vec::new();
    for kind in [
        LinearSolverKind::Dense,
        LinearSolverKind::Sparse,
        LinearSolverKind::Iterative,
    ] {
        let mut q = base.clone();
        let s = solve(&mut q, &options(kind), |_| {}).unwrap();
        let dz = (q.images[3].camera_from_object.centre().z
            - base.images[3].camera_from_object.centre().z)
            .abs();
        assert!(dz < 1e-9, "{kind}: held Z of S03 moved by {dz}");
        results.push((kind, s.final_cost, q));
    }
    let (_, cost0, q0) = &results[0];
    for (kind, cost, q) in &results[1..] {
        assert!(relative(*cost, *cost0) < 1e-9, "{kind}: {cost} vs {cost0}");
        let worst = (q.points.iter().zip(&q0.points))
            .map(|(a, b)| (a.position - b.position).norm())
            .fold(0.0, f64::max);
        println!("{kind} (held centres): largest point difference to dense {worst:.2e} mm");
        assert!(worst < 3e-3, "{kind}: {worst}");
    }
}
