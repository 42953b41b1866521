//! Single coordinates held (`Point::fixed_axes`): on the self-calibration network of
//! `common`, a minimal datum of 3 + 3 + 1 point coordinates (no fixed image) solves with the
//! held coordinates exactly at their values; two different minimal datums give the same
//! network up to a similarity, and the same intrinsics with the same σ as a free network
//! (intrinsics are estimable); on consistent observations the distances between points are
//! those of the classical datum (4 fixed points); held coordinates have σ exactly 0; the
//! datum diagnosis counts held coordinates (too little names the open motion, too much the
//! held coordinates); and every linear solver reaches the same minimum.

use crate::common;

use common::{realisation, truth};
use nalgebra::{DMatrix, Matrix3, Vector3};
use pingcal_ba::datum::{check, Datum, DatumError};
use pingcal_ba::problem::{Distance, PointPrior, Problem};
use pingcal_ba::solver::{precision, solve, LinearSolverKind, Options, PrecisionError};
use pingcal_ba::{Block, ImageKey, PointKey, PosePrior, Residual, ResidualBlock, Value};
use pingcal_geometry::Rigid3;

/// Every linear solver path of the adjustment.
const SOLVERS: [LinearSolverKind; 3] = [
    LinearSolverKind::Dense,
    LinearSolverKind::Sparse,
    LinearSolverKind::Iterative,
];

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
        a: PointKey(12),
        b: PointKey(5),
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
        a: PointKey(70),
        b: PointKey(33),
        value: (truth().points[70].position - truth().points[33].position).norm(),
        sigma: 0.05,
    });
    base.point_priors.push(PointPrior {
        point: PointKey(70),
        position: truth().points[70].position,
        sigma: Vector3::new(2.0, 2.0, 2.0),
    });
    let mut results = Vec::new();
    for kind in SOLVERS {
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
        let worst = largest_point_difference(p, p0);
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
                    image: ImageKey(7),
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
    for kind in SOLVERS {
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
        let worst = largest_point_difference(q, q0);
        println!("{kind} (held centres): largest point difference to dense {worst:.2e} mm");
        assert!(worst < 3e-3, "{kind}: {worst}");
    }
}

/// A point measured in an image's camera frame (a total station or scanner set up at the
/// station): `r = (R X + t − m) / σ`, one residual on a point block and a pose block.
#[derive(Debug)]
struct PointInCamera {
    point: usize,
    image: usize,
    measured: Vector3<f64>,
    sigma: f64,
}

impl Residual for PointInCamera {
    fn dim(&self) -> usize {
        3
    }
    fn blocks(&self) -> Vec<Block> {
        vec![
            Block::Point(PointKey(self.point)),
            Block::Pose(ImageKey(self.image)),
        ]
    }
    fn evaluate(&self, v: &[Value], r: &mut [f64], j: Option<&mut [DMatrix<f64>]>) -> bool {
        let (Some(x), Some(pose)) = (v[0].point(), v[1].pose()) else {
            return false;
        };
        let rx = pose.rotation * x;
        let f = rx + pose.translation;
        for k in 0..3 {
            r[k] = (f[k] - self.measured[k]) / self.sigma;
        }
        if let Some(j) = j {
            // ∂/∂X = R, ∂/∂δω = −[R X]×, ∂/∂δt = I.
            let jw = -pingcal_geometry::skew(&rx);
            for a in 0..3 {
                for b in 0..3 {
                    j[0][(a, b)] = pose.rotation[(a, b)] / self.sigma;
                    j[1][(a, b)] = jw[(a, b)] / self.sigma;
                }
                j[1][(a, 3 + a)] = 1.0 / self.sigma;
            }
        }
        true
    }
    fn group(&self) -> &str {
        "in camera"
    }
}

/// One measured coordinate of a point (a levelled height): `r = (X_axis − m) / σ`, a
/// residual whose only block is a point.
#[derive(Debug)]
struct Coordinate {
    point: usize,
    axis: usize,
    measured: f64,
    sigma: f64,
}

impl Residual for Coordinate {
    fn dim(&self) -> usize {
        1
    }
    fn blocks(&self) -> Vec<Block> {
        vec![Block::Point(PointKey(self.point))]
    }
    fn evaluate(&self, v: &[Value], r: &mut [f64], j: Option<&mut [DMatrix<f64>]>) -> bool {
        let Some(x) = v[0].point() else {
            return false;
        };
        r[0] = (x[self.axis] - self.measured) / self.sigma;
        if let Some(j) = j {
            j[0][(0, self.axis)] = 1.0 / self.sigma;
        }
        true
    }
    fn group(&self) -> &str {
        "coordinates"
    }
}

/// σ of a coordinate held by a stiff prior instead (mm), and of one left free by it.
const STIFF: f64 = 1e-5;
impl PointInCamera {
    /// The true `point` of `truth` in the camera frame of `image`, measured with noise σ
    /// `sigma` per coordinate drawn from `seed`.
    fn simulated(truth: &Problem, point: usize, image: usize, sigma: f64, seed: u64) -> Self {
        let x = truth.images[image]
            .camera_from_object
            .transform(&truth.points[point].position);
        PointInCamera {
            point,
            image,
            measured: disturbed(x, sigma, seed),
            sigma,
        }
    }
}

const LOOSE: f64 = 1e7;

/// A measurement of `x` disturbed by `seed` (σ `sigma` per coordinate).
fn disturbed(x: Vector3<f64>, sigma: f64, seed: u64) -> Vector3<f64> {
    let mut rng = pingcal_geometry::consensus::rng(seed);
    let n = rand_distr::Normal::new(0.0, sigma).unwrap();
    x + Vector3::from_fn(|_, _| rand_distr::Distribution::sample(&n, &mut rng))
}

/// The largest difference of the point coordinates and projection centres of `a` and `b`
/// (mm).
fn largest_difference(a: &Problem, b: &Problem) -> f64 {
    let points = (a.points.iter().zip(&b.points)).map(|(x, y)| (x.position - y.position).amax());
    let centres = (a.images.iter().zip(&b.images))
        .map(|(x, y)| (x.camera_from_object.centre() - y.camera_from_object.centre()).amax());
    points.chain(centres).fold(0.0, f64::max)
}

/// The minimum `(p, cost)` that solver `kind` reached is the `reference` minimum of the
/// same problem with the held coordinates held by stiff priors instead: every point and
/// projection centre within 1e-4 mm, and the same cost to 1e-6 (the stiff priors add
/// (almost) nothing at the minimum).
fn assert_at_stiff_minimum(
    kind: LinearSolverKind,
    (p, cost): (&Problem, f64),
    (reference, reference_cost): (&Problem, f64),
) {
    let worst = largest_difference(p, reference);
    println!("{kind}: largest difference to the stiff priors' minimum {worst:.2e} mm");
    assert!(worst < 1e-4, "{kind}: {worst} mm");
    assert!(
        relative(cost, reference_cost) < 1e-6,
        "{kind}: cost {cost} vs {reference_cost}"
    );
}

/// (e) Generic residuals (a point in a camera frame: a point block and a pose block; one
/// measured coordinate: a point block alone) on partly held points give the minimum of the
/// same problem with those coordinates held by a stiff prior instead: the residuals'
/// Jacobians reach exactly the free coordinates' columns, in every solver path; the held
/// coordinates do not move at all.
#[test]
fn generic_residuals_on_partly_held_points_agree_with_a_stiff_prior() {
    let t = truth();
    let mut held = network(Some(23), &DATUM_A);
    // Point 33: X held; point 70 (Z held by DATUM_A) and 33 measured from stations 3 and 9,
    // Y of 33 and Z of 70 (held: a constant residual) measured as coordinates.
    held.points[33].fixed_axes = [true, false, false];
    held.points[33].position.x = t.points[33].position.x;
    for (k, &(point, image)) in [(33usize, 3usize), (70, 9), (33, 9), (21, 4)]
        .iter()
        .enumerate()
    {
        let measured = PointInCamera::simulated(&t, point, image, 0.3, 100 + k as u64);
        held.residuals.push(ResidualBlock::new(measured));
    }
    for (k, &(point, axis)) in [(33usize, 1usize), (70, 2), (33, 0)].iter().enumerate() {
        held.residuals.push(ResidualBlock::new(Coordinate {
            point,
            axis,
            measured: t.points[point].position[axis] + 0.4 * (k as f64 - 1.0),
            sigma: 0.5,
        }));
    }
    // The same problem with the partly held coordinates held by stiff priors instead.
    let mut stiff = held.clone();
    for p in [33usize, 70] {
        let pt = &mut stiff.points[p];
        let h = pt.held();
        pt.fixed_axes = [false; 3];
        stiff.point_priors.push(PointPrior {
            point: PointKey(p),
            position: pt.position,
            sigma: Vector3::from_fn(|a, _| if h[a] { STIFF } else { LOOSE }),
        });
    }
    let mut reference = stiff.clone();
    let sr = solve(&mut reference, &options(LinearSolverKind::Dense), |_| {}).unwrap();
    for kind in SOLVERS {
        let mut p = held.clone();
        let s = solve(&mut p, &options(kind), |_| {}).unwrap();
        assert_held(&held, &p);
        assert_at_stiff_minimum(kind, (&p, s.final_cost), (&reference, sr.final_cost));
    }
    // Without the generic residuals the minimum is a different one: they do take part.
    let mut bare = held.clone();
    bare.residuals.clear();
    solve(&mut bare, &options(LinearSolverKind::Sparse), |_| {}).unwrap();
    assert!(largest_difference(&bare, &reference) > 1e-2);
    let pr = precision(&reference).unwrap();
    let mut p = held.clone();
    solve(&mut p, &options(LinearSolverKind::Sparse), |_| {}).unwrap();
    let pp = precision(&p).unwrap();
    let c = pp.point_covariances[33].unwrap();
    assert!(c.row(0).iter().chain(c.column(0).iter()).all(|v| *v == 0.0));
    // In units of σ0: the priors count as observations, so the redundancies differ.
    let cr = pr.point_covariances[33].unwrap();
    for a in 1..3 {
        let (s, sr) = (c[(a, a)].sqrt() / pp.sigma0, cr[(a, a)].sqrt() / pr.sigma0);
        assert!(relative(s, sr) < 1e-4, "σ of axis {a} of P33: {s} vs {sr}");
    }
}

/// (f) An image with a held centre coordinate carries a pose prior on all six components
/// and a generic residual on its pose (and on a partly held point): the minimum is the one
/// of the same problem with that coordinate held by a stiff pose prior instead, in every
/// solver path, so the residuals' Jacobians are taken correctly to the unknowns (δω, δC)
/// (the prior's centre rows included).
#[test]
fn pose_residuals_on_an_image_with_a_held_centre_agree_with_a_stiff_prior() {
    let t = truth();
    let mut held = network(Some(29), &DATUM_A);
    let (image, axes) = (3usize, [false, true, true]);
    let pose = held.images[image].camera_from_object;
    let mut c = pose.centre();
    let ct = t.images[image].camera_from_object.centre();
    for a in (0..3).filter(|&a| axes[a]) {
        c[a] = ct[a];
    }
    held.images[image].camera_from_object = Rigid3::from_rotation_and_centre(pose.rotation, c);
    held.images[image].fixed_centre = axes;
    held.residuals.push(ResidualBlock::new(PosePrior {
        image: ImageKey(image),
        camera_from_object: Rigid3::from_rotation_and_centre(
            t.images[image].camera_from_object.rotation,
            disturbed(ct, 4.0, 7),
        ),
        sigma_rotation: Vector3::repeat(2e-3),
        sigma_centre: Vector3::repeat(3.0),
    }));
    for (k, point) in [33usize, 70, 21].into_iter().enumerate() {
        let measured = PointInCamera::simulated(&t, point, image, 0.5, 200 + k as u64);
        held.residuals.push(ResidualBlock::new(measured));
    }
    let mut stiff = held.clone();
    stiff.images[image].fixed_centre = [false; 3];
    stiff.residuals.push(ResidualBlock::new(PosePrior {
        image: ImageKey(image),
        camera_from_object: held.images[image].camera_from_object,
        sigma_rotation: Vector3::repeat(f64::INFINITY),
        sigma_centre: Vector3::from_fn(|a, _| if axes[a] { STIFF } else { f64::INFINITY }),
    }));
    let mut reference = stiff.clone();
    let sr = solve(&mut reference, &options(LinearSolverKind::Dense), |_| {}).unwrap();
    for kind in SOLVERS {
        let mut p = held.clone();
        let s = solve(&mut p, &options(kind), |_| {}).unwrap();
        assert_held(&held, &p);
        let (c0, c1) = (
            held.images[image].camera_from_object.centre(),
            p.images[image].camera_from_object.centre(),
        );
        for a in (0..3).filter(|&a| axes[a]) {
            assert!(
                (c0[a] - c1[a]).abs() < 1e-9,
                "{kind}: held centre {a} moved"
            );
        }
        assert_at_stiff_minimum(kind, (&p, s.final_cost), (&reference, sr.final_cost));
        let dw = pingcal_geometry::log_so3(
            &(p.images[image].camera_from_object.rotation
                * reference.images[image]
                    .camera_from_object
                    .rotation
                    .transpose()),
        )
        .norm();
        assert!(dw < 1e-8, "{kind}: rotation differs by {dw} rad");
    }
    let pp = precision(&{
        let mut p = held.clone();
        solve(&mut p, &options(LinearSolverKind::Sparse), |_| {}).unwrap();
        p
    })
    .unwrap();
    let pr = precision(&reference).unwrap();
    let (s, sr) = (
        pp.poses[image].as_ref().unwrap(),
        pr.poses[image].as_ref().unwrap(),
    );
    assert_eq!((s.centre[1], s.centre[2]), (0.0, 0.0));
    // In units of σ0: the priors count as observations, so the redundancies differ.
    let (k, kr) = (1.0 / pp.sigma0, 1.0 / pr.sigma0);
    let x = (s.centre[0] * k, sr.centre[0] * kr);
    assert!(relative(x.0, x.1) < 1e-4, "centre X σ {} vs {}", x.0, x.1);
    for a in 0..3 {
        let w = (s.rotation_rad[a] * k, sr.rotation_rad[a] * kr);
        assert!(
            relative(w.0, w.1) < 1e-4,
            "rotation σ {a}: {} vs {}",
            w.0,
            w.1
        );
    }
}

/// The largest distance between a point of `p` and the same point of `p0`.
fn largest_point_difference(p: &Problem, p0: &Problem) -> f64 {
    (p.points.iter().zip(&p0.points))
        .map(|(a, b)| (a.position - b.position).norm())
        .fold(0.0, f64::max)
}
