//! Residual kinds defined outside the crate, as a user adding a sensor would (factrs'
//! "residuals proven from outside"): a 3D scanner rigidly mounted at an unknown pose with an
//! unknown range offset measures some of the test field's points. Its pose and offset are
//! parameter blocks of the problem; the image points, the scanner's points and the pose
//! priors are adjusted together.

use crate::common;

use nalgebra::{DMatrix, Vector3};
use pingcal_ba::residual::check_residual_jacobians;
use pingcal_ba::solver::{estimate_variance_components, LinearSolverKind};
use pingcal_ba::{
    precision, solve, Block, Distance, ImageKey, Options, ParameterBlock, ParameterKey,
    ParameterValue, PointKey, PosePrior, Problem, Residual, ResidualBlock, Rigid3, Value,
};
use pingcal_geometry::{exp_so3, from_opk_deg, log_so3};
use rand_distr::{Distribution, Normal};

fn converged(s: &pingcal_ba::solver::Summary) -> bool {
    use pingcal_ba::solver::Termination::*;
    matches!(
        s.termination,
        FunctionTolerance | GradientTolerance | ParameterTolerance
    )
}

/// σ of each coordinate the scanner measures (mm).
const SCANNER_SIGMA: f64 = 0.5;

/// A point measured by the scanner: `m = x_s + o·x_s/|x_s|` with `x_s = scanner_from_object·X`
/// and `o` the range offset, whitened by σ.
#[derive(Debug)]
struct ScannerPoint {
    point: usize,
    pose: usize,
    offset: usize,
    measured: Vector3<f64>,
    sigma: f64,
}

impl Residual for ScannerPoint {
    fn dim(&self) -> usize {
        3
    }
    fn blocks(&self) -> Vec<Block> {
        vec![
            Block::Point(PointKey(self.point)),
            Block::Parameter(ParameterKey(self.pose)),
            Block::Parameter(ParameterKey(self.offset)),
        ]
    }
    fn evaluate(
        &self,
        values: &[Value],
        residual: &mut [f64],
        jacobians: pingcal_ba::Jacobians<'_>,
    ) -> bool {
        let (Some(x), Some(pose), Some(o)) =
            (values[0].point(), values[1].pose(), values[2].vector())
        else {
            return false;
        };
        let rx = pose.rotation * x;
        let xs = rx + pose.translation;
        let l = xs.norm();
        if l <= 0.0 {
            return false;
        }
        let u = xs / l;
        let f = xs + o[0] * u;
        for k in 0..3 {
            residual[k] = (f[k] - self.measured[k]) / self.sigma;
        }
        if let Some(j) = jacobians {
            // ∂f/∂x_s = I + o (I − u uᵀ)/l; ∂x_s/∂X = R, ∂x_s/∂δω = −[R X]×, ∂x_s/∂δt = I.
            let df = (nalgebra::Matrix3::identity()
                + o[0] * (nalgebra::Matrix3::identity() - u * u.transpose()) / l)
                / self.sigma;
            let jx = df * pose.rotation;
            let jw = -(df * pingcal_geometry::skew(&rx));
            for a in 0..3 {
                for b in 0..3 {
                    j[0][(a, b)] = jx[(a, b)];
                    j[1][(a, b)] = jw[(a, b)];
                    j[1][(a, 3 + b)] = df[(a, b)];
                }
                j[2][(a, 0)] = u[a] / self.sigma;
            }
        }
        true
    }
    fn group(&self) -> &str {
        "scanner"
    }
}

/// A distance written by a user: the built-in kind's equation through the same trait.
#[derive(Debug)]
struct UserDistance(Distance);

impl Residual for UserDistance {
    fn dim(&self) -> usize {
        1
    }
    fn blocks(&self) -> Vec<Block> {
        vec![Block::Point(self.0.a), Block::Point(self.0.b)]
    }
    fn evaluate(&self, v: &[Value], r: &mut [f64], j: Option<&mut [DMatrix<f64>]>) -> bool {
        let d = v[0].point().unwrap() - v[1].point().unwrap();
        r[0] = (d.norm() - self.0.value) / self.0.sigma;
        if let Some(j) = j {
            let g = d.normalize() / self.0.sigma;
            for k in 0..3 {
                j[0][(0, k)] = g[k];
                j[1][(0, k)] = -g[k];
            }
        }
        true
    }
    fn group(&self) -> &str {
        "user distances"
    }
}

fn true_scanner() -> Rigid3 {
    // Beside the cameras, looking into the field.
    Rigid3::from_rotation_and_centre(
        from_opk_deg([-88.0, 3.0, 12.0]),
        Vector3::new(-300.0, 200.0, 100.0),
    )
}

const TRUE_OFFSET: f64 = 7.5;

/// The field of `common::truth` with noisy image points, and the scanner measuring every
/// fifth point (noisy), started 1° and 20 mm off with a zero offset. Seeded.
fn scanner_network(seed: u64, scanner_sigma_given: f64) -> Problem {
    scanner_network_every(seed, scanner_sigma_given, 5)
}

/// [`scanner_network`] with the scanner measuring every `every`-th point.
fn scanner_network_every(seed: u64, scanner_sigma_given: f64, every: usize) -> Problem {
    let truth = common::truth();
    let mut p = common::realisation(&truth, seed);
    let mut rng = pingcal_geometry::consensus::rng_stream(seed, 7);
    let n = Normal::new(0.0, 1.0).unwrap();
    let scanner = true_scanner();
    let start = Rigid3::new(
        exp_so3(&Vector3::new(0.01, -0.012, 0.008)) * scanner.rotation,
        scanner.translation + Vector3::new(20.0, -10.0, 15.0),
    );
    p.parameters
        .push(ParameterBlock::pose("scanner_from_object", start));
    p.parameters
        .push(ParameterBlock::vector("range_offset", vec![0.0]));
    for (k, pt) in truth.points.iter().enumerate().step_by(every) {
        let xs = scanner.transform(&pt.position);
        let noise = Vector3::from_fn(|_, _| n.sample(&mut rng)) * SCANNER_SIGMA;
        p.residuals.push(ResidualBlock::new(ScannerPoint {
            point: k,
            pose: 0,
            offset: 1,
            measured: xs + TRUE_OFFSET * xs.normalize() + noise,
            sigma: scanner_sigma_given,
        }));
    }
    p
}

/// (estimate − truth)/σ of the scanner's rotation (3), translation (3) and offset.
fn scanner_z(p: &Problem) -> [f64; 7] {
    let prec = precision(p).expect("precision");
    let ParameterValue::Pose(est) = &p.parameters[0].value else {
        panic!("pose block")
    };
    let ParameterValue::Vector(off) = &p.parameters[1].value else {
        panic!("vector block")
    };
    let truth = true_scanner();
    // The left update: est = exp(δω) truth, δt = t_est − t_truth.
    let dw = log_so3(&(est.rotation * truth.rotation.transpose()));
    let dt = est.translation - truth.translation;
    let cov = prec.parameter_covariance(0, 0);
    let cov_o = prec.parameter_covariance(1, 1);
    let mut z = [0.0; 7];
    for k in 0..3 {
        z[k] = dw[k] / cov[(k, k)].sqrt();
        z[3 + k] = dt[k] / cov[(3 + k, 3 + k)].sqrt();
    }
    z[6] = (off[0] - TRUE_OFFSET) / cov_o[(0, 0)].sqrt();
    z
}

#[test]
fn the_scanner_residual_has_the_jacobian_of_central_differences() {
    let p = scanner_network(1, SCANNER_SIGMA);
    let r = &p.residuals[3].residual;
    let x = p.points[15].position;
    let ParameterValue::Pose(pose) = &p.parameters[0].value else {
        unreachable!()
    };
    let off = [4.0];
    let values = [Value::Point(&x), Value::Pose(pose), Value::Vector(&off)];
    let worst = check_residual_jacobians(&**r, &values, 1e-5).expect("defined");
    assert!(worst < 1e-6, "worst relative difference {worst:e}");
}

#[test]
fn a_scanner_pose_and_range_offset_are_recovered_with_honest_sigmas() {
    // 40 seeds × 7 parameters: the RMS of (estimate − truth)/σ is 1 within about
    // 1/√(2·280) ≈ 0.04 for honest σ's; [0.8, 1.2] is about 4.7 of those.
    let mut z2 = 0.0;
    let mut worst = 0.0f64;
    let seeds = 40;
    for seed in 1..=seeds {
        let mut p = scanner_network(seed, SCANNER_SIGMA);
        let s = solve(&mut p, &Options::default(), |_| {}).expect("solve");
        assert!(converged(&s), "seed {seed}: {:?}", s.termination);
        let z = scanner_z(&p);
        z2 += z.iter().map(|v| v * v).sum::<f64>();
        worst = z.iter().fold(worst, |m, v| m.max(v.abs()));
    }
    let rms = (z2 / (7 * seeds) as f64).sqrt();
    assert!((0.8..1.2).contains(&rms), "RMS z {rms}");
    assert!(worst < 4.5, "worst |z| {worst}");
}

#[test]
fn every_linear_solver_finds_the_same_minimum_with_the_new_blocks() {
    let mut costs = Vec::new();
    let mut offsets = Vec::new();
    for kind in [
        LinearSolverKind::Dense,
        LinearSolverKind::Sparse,
        LinearSolverKind::Iterative,
    ] {
        let mut p = scanner_network(3, SCANNER_SIGMA);
        let mut o = Options {
            linear_solver: kind,
            function_tolerance: 1e-14,
            parameter_tolerance: 1e-14,
            gradient_tolerance: 1e-14,
            ..Options::default()
        };
        o.cg.eta = 1e-6;
        let s = solve(&mut p, &o, |_| {}).expect("solve");
        costs.push(s.final_cost);
        let ParameterValue::Vector(v) = &p.parameters[1].value else {
            unreachable!()
        };
        offsets.push(v[0]);
    }
    for k in 1..3 {
        assert!(
            (costs[k] - costs[0]).abs() <= 1e-8 * costs[0],
            "costs {costs:?}"
        );
        assert!((offsets[k] - offsets[0]).abs() < 1e-6, "{offsets:?}");
    }
}

#[test]
fn a_distance_written_by_a_user_is_adjusted_exactly_as_the_built_in_one() {
    let truth = common::truth();
    let d = Distance {
        a: PointKey(3),
        b: PointKey(50),
        value: (truth.points[3].position - truth.points[50].position).norm() + 0.2,
        sigma: 0.1,
    };
    let mut built_in = common::realisation(&truth, 5);
    let mut user = built_in.clone();
    built_in.distances.push(d);
    user.residuals.push(ResidualBlock::new(UserDistance(d)));
    let a = solve(&mut built_in, &Options::default(), |_| {}).unwrap();
    let b = solve(&mut user, &Options::default(), |_| {}).unwrap();
    assert_eq!(a.iterations, b.iterations);
    assert!((a.final_cost - b.final_cost).abs() <= 1e-12 * a.final_cost);
    for (x, y) in built_in.points.iter().zip(&user.points) {
        assert!((x.position - y.position).norm() < 1e-9);
    }
    let (pa, pb) = (precision(&built_in).unwrap(), precision(&user).unwrap());
    assert!((pa.sigma0 - pb.sigma0).abs() < 1e-12);
    let (ra, rb) = (
        pa.distance_redundancy_numbers[0],
        pb.residual_redundancy_numbers[0][0],
    );
    assert!((ra - rb).abs() < 1e-9, "{ra} {rb}");
    for p in 0..built_in.points.len() {
        if let (Some(x), Some(y)) = (pa.point_sigma(p), pb.point_sigma(p)) {
            assert!((x - y).norm() <= 1e-9 * x.norm());
        }
    }
}

#[test]
fn a_wrong_scanner_sigma_is_found_by_its_variance_component() {
    // The scanner's σ given as half the true one: its group's σ0 is about 2. It measures
    // every point, so that its group has a redundancy of its own.
    let mut p = scanner_network_every(2, 0.5 * SCANNER_SIGMA, 1);
    let groups = vec![0; p.observations.len()];
    let est = estimate_variance_components(&mut p, &Options::default(), &groups, &["targets"])
        .expect("variance components");
    let scanner = est
        .components
        .iter()
        .find(|c| c.group == "scanner")
        .unwrap();
    // A σ0 from r degrees of freedom has a relative standard error of about 1/√(2r): 4 of
    // those.
    assert!(
        scanner.reweighted && scanner.redundancy > 30.0,
        "{scanner:?}"
    );
    let tolerance = 4.0 / (2.0 * scanner.redundancy).sqrt();
    assert!(
        (scanner.sigma0 / 2.0 - 1.0).abs() < tolerance,
        "{scanner:?}"
    );
    assert!(
        (p.residuals[0].sigma_scale / scanner.sigma0 - 1.0).abs()
            < pingcal_ba::solver::VCE_TOLERANCE,
        "the scanner's σ factor carries the estimate (to the last round's change)"
    );
}

#[test]
fn pose_priors_give_the_datum_and_are_met_within_their_sigmas() {
    // No control points: the datum is the images' GNSS-like pose priors (10 mm, 1 mrad).
    let truth = common::truth();
    let mut p = common::realisation(&truth, 9);
    let mut rng = pingcal_geometry::consensus::rng_stream(9, 3);
    let n = Normal::new(0.0, 1.0).unwrap();
    for pt in &mut p.points {
        pt.fixed = false;
    }
    let (sc, sw) = (10.0, 1e-3);
    for (i, im) in truth.images.iter().enumerate() {
        let pose = im.camera_from_object;
        let dw = Vector3::from_fn(|_, _| n.sample(&mut rng)) * sw;
        let dc = Vector3::from_fn(|_, _| n.sample(&mut rng)) * sc;
        let prior =
            Rigid3::from_rotation_and_centre(exp_so3(&dw) * pose.rotation, pose.centre() + dc);
        p.residuals.push(ResidualBlock::new(PosePrior {
            image: ImageKey(i),
            camera_from_object: prior,
            sigma_rotation: Vector3::repeat(sw),
            sigma_centre: Vector3::repeat(sc),
        }));
    }
    let s = solve(&mut p, &Options::default(), |_| {}).expect("solve");
    assert!(converged(&s), "{:?}", s.termination);
    let prec = precision(&p).expect("the priors fix the datum");
    // 14 centres averaged: the field is placed to about 10/√14 ≈ 2.7 mm.
    let mut z2 = 0.0;
    let mut n_z = 0;
    for (k, pt) in p.points.iter().enumerate() {
        let sigma = prec.point_sigma(k).unwrap();
        let e = pt.position - truth.points[k].position;
        for a in 0..3 {
            z2 += (e[a] / sigma[a]).powi(2);
            n_z += 1;
        }
    }
    // The points' errors share the datum's (so they are not independent): a loose bound.
    let rms = (z2 / n_z as f64).sqrt();
    assert!(rms < 2.5, "RMS point z {rms}");
    for (i, im) in p.images.iter().enumerate() {
        let sigma = prec.poses[i].as_ref().unwrap().centre;
        assert!(sigma.iter().all(|s| *s < sc), "image {i}: σ_C {sigma:?}");
        let e =
            (im.camera_from_object.centre() - truth.images[i].camera_from_object.centre()).norm();
        assert!(e < 5.0 * sc, "image {i}: centre off {e} mm");
    }
}

#[test]
fn a_held_component_stays_and_has_no_covariance() {
    let mut p = scanner_network(4, SCANNER_SIGMA);
    p.parameters[1].fixed[0] = true;
    p.parameters[0].fixed[2] = true; // the rotation about z
    solve(&mut p, &Options::default(), |_| {}).expect("solve");
    let ParameterValue::Vector(v) = &p.parameters[1].value else {
        unreachable!()
    };
    assert_eq!(v[0], 0.0);
    let prec = precision(&p).unwrap();
    let c = prec.parameter_covariance(0, 0);
    assert!(c.row(2).iter().all(|x| *x == 0.0) && c[(0, 0)] > 0.0);
    assert!(prec.parameter_covariance(1, 1)[(0, 0)] == 0.0);
}

#[test]
fn malformed_residuals_are_refused_by_name() {
    let mut p = scanner_network(1, SCANNER_SIGMA);
    p.parameters
        .push(ParameterBlock::vector("unused", vec![1.0, 2.0]));
    let e = solve(&mut p, &Options::default(), |_| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("'unused'") && e.contains("no residual"), "{e}");

    let mut p = scanner_network(1, SCANNER_SIGMA);
    p.residuals.push(ResidualBlock::new(ScannerPoint {
        point: 10_000,
        pose: 0,
        offset: 1,
        measured: Vector3::zeros(),
        sigma: 1.0,
    }));
    let e = solve(&mut p, &Options::default(), |_| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("scanner") && e.contains("point 10000"), "{e}");

    let mut p = scanner_network(1, SCANNER_SIGMA);
    p.residuals[0].sigma_scale = f64::NAN;
    let e = solve(&mut p, &Options::default(), |_| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("σ factor"), "{e}");
}
