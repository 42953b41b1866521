//! The precision of networks too large to invert S densely: the sparse selected inversion
//! (networks with a datum) and the S-transformation of a minimal datum's cofactors (free
//! networks) give the same figures as the dense forms where both can be computed, and
//! figures at all above the dense limit.
//!
//! Tolerance: both forms compute the same exact quantities from the same S; they differ by
//! rounding only, which the Jacobi-scaled systems here (condition below ~1e8) keep under
//! ~1e-8 relative. 1e-6 relative (the figure) leaves a margin of 100.

use crate::common;
use pingcal_ba::PointKey;

use common::{adjusted_free_network, realisation, to_convergence, truth};
use pingcal_ba::problem::{Distance, Problem};
use pingcal_ba::solver::{
    free_network_precision_bordered, points_covariance_with, precision, precision_with, solve,
    CofactorMethod, Options, Precision, PrecisionError, MAX_DENSE_PRECISION,
};

const REL: f64 = 1e-6;

thread_local! {
    /// The largest relative difference met by [`close`] (printed with `--nocapture`).
    static WORST: std::cell::Cell<f64> = const { std::cell::Cell::new(0.0) };
}

fn close(a: f64, b: f64, scale: f64, what: &str) {
    let rel = (a - b).abs() / scale.abs().max(1e-300);
    WORST.set(WORST.get().max(rel));
    assert!(rel <= REL, "{what}: sparse {a} vs dense {b}");
}

/// Every figure of two precisions of the same network, to [`REL`].
fn same_precision(sparse: &Precision, dense: &Precision) {
    assert_eq!(sparse.redundancy, dense.redundancy);
    assert_eq!(sparse.unknowns, dense.unknowns);
    close(sparse.sigma0, dense.sigma0, dense.sigma0, "σ0");
    for (a, b) in sparse.intrinsics.iter().zip(&dense.intrinsics) {
        for (x, y) in a.sigmas.iter().zip(&b.sigmas) {
            close(*x, *y, *y, "intrinsic σ");
        }
        for (ra, rb) in a.correlation.iter().zip(&b.correlation) {
            for (x, y) in ra.iter().zip(rb) {
                close(*x, *y, 1.0, "intrinsic correlation");
            }
        }
    }
    for (a, b) in sparse.poses.iter().zip(&dense.poses) {
        assert_eq!(a.is_some(), b.is_some());
        if let (Some(a), Some(b)) = (a, b) {
            for k in 0..3 {
                close(
                    a.rotation_rad[k],
                    b.rotation_rad[k],
                    b.rotation_rad[k],
                    "rotation σ",
                );
                close(a.centre[k], b.centre[k], b.centre[k], "centre σ");
            }
        }
    }
    for (a, b) in sparse
        .point_covariances
        .iter()
        .zip(&dense.point_covariances)
    {
        assert_eq!(a.is_some(), b.is_some());
        if let (Some(a), Some(b)) = (a, b) {
            let scale = b.diagonal().max();
            for (x, y) in a.iter().zip(b.iter()) {
                close(*x, *y, scale, "point covariance");
            }
        }
    }
    for (a, b) in sparse
        .redundancy_numbers
        .iter()
        .zip(&dense.redundancy_numbers)
    {
        for k in 0..2 {
            close(a[k], b[k], 1.0, "redundancy number");
        }
    }
    for (a, b) in (sparse.standardized_residuals.iter()).zip(&dense.standardized_residuals) {
        for k in 0..2 {
            if b[k].is_finite() {
                close(a[k], b[k], b[k], "standardized residual");
            } else {
                assert!(!a[k].is_finite());
            }
        }
    }
    for (a, b) in
        (sparse.distance_redundancy_numbers.iter()).zip(&dense.distance_redundancy_numbers)
    {
        close(*a, *b, 1.0, "distance redundancy number");
    }
    eprintln!("largest relative difference: {:.1e}", WORST.get());
}

fn with_distance(mut p: Problem, a: usize, b: usize) -> Problem {
    let l = (p.points[a].position - p.points[b].position).norm();
    p.distances.push(Distance {
        a: PointKey(a),
        b: PointKey(b),
        value: l,
        sigma: 0.05 * l,
    });
    p
}

/// The selected inversion and the dense Cholesky inverse of a network with a datum give
/// every figure of the dense eigen-inverse.
fn every_form_equals_the_dense_inverse(p: &Problem) {
    let dense = precision_with(p, CofactorMethod::Dense).expect("dense");
    for (method, name) in [
        (CofactorMethod::Sparse, "selected inversion"),
        (CofactorMethod::DenseCholesky, "dense Cholesky inverse"),
    ] {
        let other = precision_with(p, method).unwrap_or_else(|e| panic!("{method:?}: {e}"));
        same_precision(&other, &dense);
        assert_eq!(other.cofactors, name);
    }
    assert_eq!(dense.cofactors, "dense inverse");
}

/// A self-calibration network with a datum (four control points) and a measured distance
/// (two points kept in the reduced system, a constraint's cofactors): the selected inverse
/// and the dense Cholesky inverse (Auto's form for a camera graph too dense for the sparse
/// factor) give every figure of the dense eigen-inverse.
#[test]
fn selected_inversion_equals_the_dense_inverse() {
    let mut p = with_distance(realisation(&truth(), 5), 3, 50);
    solve(&mut p, &to_convergence(), |_| {}).unwrap();
    every_form_equals_the_dense_inverse(&p);
}

/// A street of `cameras` BAL cameras (each point seen by 5 neighbours: a banded camera
/// graph, whose factor is sparse) with a minimal datum: the first image fixed and one
/// coordinate of the last point held.
fn street(cameras: usize, points: usize) -> Problem {
    let mut p = adjusted_free_network(cameras, points, &to_convergence());
    p.images[0].fixed = true;
    let far = p.points.len() - 1;
    let d = p.points[far].position - p.images[0].camera_from_object.centre();
    p.points[far].fixed_axes[d.iamax()] = true;
    solve(&mut p, &to_convergence(), |_| {}).unwrap();
    p
}

/// On a banded camera graph (the factor sparse, most pairs of cameras outside it) the
/// selected inverse gives every figure of the dense inverse.
#[test]
fn selected_inversion_of_a_street_equals_the_dense_inverse() {
    let p = street(60, 3000);
    every_form_equals_the_dense_inverse(&p);
}

/// The joint covariance of points at both ends of the street (no image sees two of them:
/// outside the factor's pattern, computed by solves) equals the dense one.
#[test]
fn joint_covariance_of_far_points_equals_the_dense() {
    let p = street(60, 3000);
    let n = p.points.len();
    let pick = [0, n / 2, n - 2];
    let dense = points_covariance_with(&p, &pick, CofactorMethod::Dense).unwrap();
    let sparse = points_covariance_with(&p, &pick, CofactorMethod::Sparse).unwrap();
    let scale = dense.diagonal().max();
    for (a, b) in sparse.iter().zip(dense.iter()) {
        close(*a, *b, scale, "joint covariance");
    }
    // The far blocks are there to compare (the datum correlates the whole street).
    assert!(dense.view((0, 6), (3, 3)).amax() > 1e-3 * scale);
    eprintln!("largest relative difference: {:.1e}", WORST.get());
}

/// Free networks (no datum; with and without a distance fixing the scale): the reduced
/// system bordered by the inner constraints and inverted densely, and the S-transformation
/// of the selected inverse under a minimal datum, both equal the dense inner-constraint
/// solution (formed from the whole normal matrix, not from S).
#[test]
fn schur_forms_of_a_free_network_equal_the_dense_inner_constraints() {
    for distance in [false, true] {
        let mut free = realisation(&truth(), 31);
        for pt in &mut free.points {
            pt.fixed = false;
        }
        if distance {
            free = with_distance(free, 0, 40);
        }
        solve(&mut free, &to_convergence(), |_| {}).unwrap();
        let dense = precision_with(&free, CofactorMethod::Dense).expect("dense inner constraints");
        let bordered = free_network_precision_bordered(&free).expect("bordered");
        same_precision(&bordered, &dense);
        let sparse = precision_with(&free, CofactorMethod::Sparse).expect("S-transformation");
        same_precision(&sparse, &dense);
        let cholesky = precision_with(&free, CofactorMethod::DenseCholesky).expect("dense base");
        same_precision(&cholesky, &dense);
    }
}

/// A defect the datum leaves open is named by the sparse path too: without a distance, one
/// fixed image leaves the scale free.
#[test]
fn the_sparse_path_names_a_datum_defect() {
    let t = truth();
    let mut p = realisation(&t, 77);
    for pt in &mut p.points {
        pt.fixed = false;
    }
    p.images[0].fixed = true;
    // The adjustment of a network with a free scale may stop anywhere along it; the
    // precision is what is tested.
    let _ = solve(&mut p, &to_convergence(), |_| {});
    let err = precision_with(&p, CofactorMethod::Sparse).unwrap_err();
    assert!(matches!(err, PrecisionError::DatumDefect(_)), "{err}");
    assert!(err.to_string().contains("do not determine"), "{err}");
}

/// A free network above the dense limit (800 cameras of 9 unknowns: 7,200 reduced
/// unknowns, 67,200 in all) gets its precision: σ0 at the simulated noise, finite positive
/// σ for every pose and point.
#[test]
fn free_network_above_the_dense_limit() {
    let p = adjusted_free_network(800, 20_000, &Options::default());
    let reduced = 9 * p.images.len();
    assert!(reduced > MAX_DENSE_PRECISION);
    let dense = precision_with(&p, CofactorMethod::Dense).unwrap_err();
    assert!(matches!(dense, PrecisionError::TooLarge(_)), "{dense}");
    let prec = precision(&p).expect("the S-transformation at any size");
    assert_eq!(prec.unknowns, reduced + 3 * p.points.len());
    // σ0 estimates the 0.5 px noise: relative sd 1/√(2·redundancy) ≈ 0.003, 3 % is 10 sd.
    assert!((prec.sigma0 - 0.5).abs() < 0.015, "σ0 {}", prec.sigma0);
    assert!(prec
        .point_covariances
        .iter()
        .all(|c| c.is_some_and(|c| c.diagonal().min() > 0.0 && c.iter().all(|v| v.is_finite()))));
    assert!(prec.poses.iter().all(|s| s.as_ref().is_some_and(|s| s
        .centre
        .iter()
        .chain(&s.rotation_rad)
        .all(|v| *v > 0.0 && v.is_finite()))));
}
