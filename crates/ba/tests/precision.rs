//! The reported precision is honest: over 200 simulated networks (noise realisations of
//! the self-calibration network of `common`), the errors of the intrinsics and of the
//! points, divided by their reported standard deviations, have unit variance within
//! sampling tolerance, and the truth lies within 3 reported σ at least 99 % of the time.
//! Also: a distance between two targets holds to its σ, and a network whose scale is not
//! defined is reported as a datum defect.

use crate::common;
use pingcal_ba::PointKey;

use common::{adjusted_free_network, realisation, to_convergence, truth};
use pingcal_ba::problem::Distance;
use pingcal_ba::solver::{points_covariance, precision, solve, PrecisionError};
use rayon::prelude::*;

#[test]
fn reported_sigmas_match_the_monte_carlo_errors() {
    let truth = truth();
    let runs = 200;
    let (mut sum_z2_intr, mut n_intr) = (0.0, 0usize);
    let (mut sum_z2_pts, mut n_pts) = (0.0, 0usize);
    let (mut inside, mut total) = (0usize, 0usize);
    for run in 0..runs {
        let mut p = realisation(&truth, 5000 + run);
        solve(&mut p, &to_convergence(), |_| {}).unwrap();
        let prec = precision(&p).unwrap();
        let intr = &prec.intrinsics[0];
        assert_eq!(intr.names.len(), 10);
        for (k, s) in intr.sigmas.iter().enumerate() {
            let z = (p.cameras[0].params[k] - truth.cameras[0].params[k]) / s;
            sum_z2_intr += z * z;
            n_intr += 1;
            inside += (z.abs() <= 3.0) as usize;
            total += 1;
        }
        for (q, pt) in p.points.iter().enumerate() {
            if pt.fixed {
                assert!(prec.point_covariances[q].is_none());
                continue;
            }
            let sig = prec.point_sigma(q).unwrap();
            for a in 0..3 {
                let z = (pt.position[a] - truth.points[q].position[a]) / sig[a];
                sum_z2_pts += z * z;
                n_pts += 1;
                inside += (z.abs() <= 3.0) as usize;
                total += 1;
            }
        }
    }
    // Mean of z² over N samples: 1 with sd √(2/N) for independent normal z. The z of one
    // network are correlated (its parameters share the same noise), so the effective N is
    // the number of networks for the intrinsics' 10 and smaller than the count for points;
    // 5 sd of the per-network mean keeps false alarms far below 1e-4.
    let (vi, vp) = (sum_z2_intr / n_intr as f64, sum_z2_pts / n_pts as f64);
    let tol = 5.0 * (2.0 / runs as f64).sqrt();
    println!(
        "variance of normalised errors: intrinsics {vi:.3}, points {vp:.3} (tolerance ±{tol:.3})"
    );
    assert!((vi - 1.0).abs() < tol, "intrinsics: mean z² = {vi}");
    assert!((vp - 1.0).abs() < tol, "points: mean z² = {vp}");
    let coverage = inside as f64 / total as f64;
    println!("3σ coverage: {:.4} of {total}", coverage);
    assert!(coverage >= 0.99, "3σ coverage {coverage}");
}

/// The joint covariance of all points, correlations between them included, is honest too:
/// the stacked error e of every free point gives `eᵀ Σ⁻¹ e ~ χ²(3m)` per network, whose mean
/// over the networks divided by 3m is 1 with sd `√(2 / (3m · runs))` (the networks are
/// independent). The correlations are what it adds to the per-point covariances of
/// `precision` (its diagonal blocks, checked equal): the error of the difference of two
/// points, d = e_p − e_q, judged by `Σ_pp + Σ_qq − Σ_pq − Σ_qp`, has `dᵀΣ_d⁻¹d / 3` of mean 1;
/// judged without the cross terms it is far from 1, because the points share the errors
/// of the datum and the cameras.
#[test]
fn joint_point_covariance_matches_the_monte_carlo_errors() {
    let truth = truth();
    let runs = 100;
    // One network per run, the runs in parallel (each seeded by its number); per run:
    // eᵀΣ⁻¹e of all its free points and their count, and the mean of dᵀΣ_d⁻¹d / 3 over its
    // neighbour pairs with and without the cross terms. Summed in the runs' order.
    let per_run: Vec<(f64, usize, f64, f64)> = (0..runs)
        .into_par_iter()
        .map(|run| {
            let mut p = realisation(&truth, 7000 + run);
            solve(&mut p, &to_convergence(), |_| {}).unwrap();
            let prec = precision(&p).unwrap();
            let free: Vec<usize> = (0..p.points.len())
                .filter(|&q| !p.points[q].fixed)
                .collect();
            let cov = points_covariance(&p, &free).unwrap();
            let err = |q: usize| p.points[q].position - truth.points[q].position;
            let e = nalgebra::DVector::from_iterator(
                3 * free.len(),
                free.iter()
                    .flat_map(|&q| err(q).iter().copied().collect::<Vec<_>>()),
            );
            let block = |a: usize, b: usize| cov.fixed_view::<3, 3>(3 * a, 3 * b).into_owned();
            for (k, &q) in free.iter().enumerate() {
                let c = prec.point_covariances[q].unwrap();
                let d = (block(k, k) - c).abs().max();
                assert!(
                    d <= 1e-9 * c.abs().max(),
                    "point {q}: the diagonal block differs by {d}"
                );
            }
            let ch = cov
                .clone()
                .cholesky()
                .expect("a positive definite covariance");
            let (mut w, mut o) = (0.0, 0.0);
            for k in 1..free.len() {
                let d = err(free[k]) - err(free[k - 1]);
                let own = block(k, k) + block(k - 1, k - 1);
                let cross = block(k, k - 1) + block(k - 1, k);
                let z2 = |m: nalgebra::Matrix3<f64>| d.dot(&(m.try_inverse().unwrap() * d));
                w += z2(own - cross);
                o += z2(own);
            }
            let pairs = 3.0 * (free.len() - 1) as f64;
            (e.dot(&ch.solve(&e)), e.len(), w / pairs, o / pairs)
        })
        .collect();
    let joint: f64 = per_run.iter().map(|r| r.0).sum();
    let dof: usize = per_run.iter().map(|r| r.1).sum();
    let with_cross: Vec<f64> = per_run.iter().map(|r| r.2).collect();
    let without_cross: Vec<f64> = per_run.iter().map(|r| r.3).collect();
    let vj = joint / dof as f64;
    let tol = 5.0 * (2.0 / dof as f64).sqrt();
    // The differences of one network are correlated, the networks independent: the
    // tolerance is 5 standard errors of the mean of the per-network values.
    let mean_and_se = |v: &[f64]| {
        let m = v.iter().sum::<f64>() / v.len() as f64;
        let var = v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() - 1) as f64;
        (m, (var / v.len() as f64).sqrt())
    };
    let ((vw, sw), (vo, so)) = (mean_and_se(&with_cross), mean_and_se(&without_cross));
    let tol_pairs = 5.0 * sw.max(so);
    println!(
        "χ²/dof of all points {vj:.3} (±{tol:.3}); differences of neighbours {vw:.3} with the cross terms, {vo:.3} without (±{tol_pairs:.3})"
    );
    assert!((vj - 1.0).abs() < tol, "joint covariance: χ²/dof = {vj}");
    assert!(
        (vw - 1.0).abs() < tol_pairs,
        "differences with the cross terms: {vw}"
    );
    assert!((vo - 1.0).abs() > tol_pairs, "without the cross terms the differences pass too ({vo}): the test does not see correlations");
}

#[test]
fn distances_fix_the_scale_and_their_absence_is_a_named_datum_defect() {
    let mut p = realisation(&truth(), 77);
    let t = truth();
    // Datum: the first image fixed at its true pose, scale from two measured distances.
    for pt in &mut p.points {
        pt.fixed = false;
    }
    p.images[0].camera_from_object = t.images[0].camera_from_object;
    p.images[0].fixed = true;
    let d1 = (t.points[0].position - t.points[40].position).norm();
    let d2 = (t.points[12].position - t.points[70].position).norm();
    p.distances.push(Distance {
        a: PointKey(0),
        b: PointKey(40),
        value: d1 + 0.05,
        sigma: 0.1,
    });
    p.distances.push(Distance {
        a: PointKey(12),
        b: PointKey(70),
        value: d2,
        sigma: 0.1,
    });
    solve(&mut p, &to_convergence(), |_| {}).unwrap();
    let prec = precision(&p).unwrap();
    for d in &p.distances {
        let l = (p.points[d.a].position - p.points[d.b].position).norm();
        // The adjusted distance agrees with the measurement to its σ (3σ band).
        assert!(
            (l - d.value).abs() < 3.0 * d.sigma,
            "distance {}–{}: {l} vs {}",
            d.a,
            d.b,
            d.value
        );
    }
    assert!(prec.point_sigma(0).unwrap().norm() > 0.0);

    // Without distances the scale is free: reported, not solved.
    let mut q = p.clone();
    q.distances.clear();
    let err = precision(&q).unwrap_err();
    assert!(matches!(err, PrecisionError::DatumDefect(_)), "{err}");
    assert!(err.to_string().contains("the scale is free"), "{err}");
}

#[test]
fn data_snooping_finds_gross_errors_and_only_them() {
    let t = truth();
    let mut p = realisation(&t, 4242);
    // Three gross errors of 3–5 px (10–17 σ) on different images and points.
    let bad = [(10usize, 4.0, 0.0), (200, 0.0, -3.0), (450, 3.5, 3.5)];
    let mut bad_ids = Vec::new();
    for &(o, du, dv) in &bad {
        p.observations[o].uv += nalgebra::Vector2::new(du, dv);
        let ob = p.observations[o];
        bad_ids.push((
            p.images[ob.image].name.clone(),
            p.points[ob.point].name.clone(),
        ));
    }
    let n0 = p.observations.len();
    let result =
        pingcal_ba::solver::adjust_with_snooping(&mut p, &to_convergence(), 3.29, 20).unwrap();
    let removed: Vec<(String, String)> = result
        .rejected
        .iter()
        .map(|r| (r.image.clone(), r.point.clone()))
        .collect();
    for b in &bad_ids {
        assert!(
            removed.contains(b),
            "gross error {b:?} not found; removed {removed:?}"
        );
    }
    // At a 0.1 % test on ~1000 good coordinates, about one false rejection is expected;
    // more than 4 would mean the statistic is wrong.
    assert!(removed.len() <= bad.len() + 4, "removed {removed:?}");
    assert_eq!(p.observations.len(), n0 - removed.len());
    // After cleaning, σ0 is back to about 1 (the a-priori σ is right).
    assert!(
        (result.precision.sigma0 - 1.0).abs() < 0.1,
        "σ0 = {}",
        result.precision.sigma0
    );
}

/// A free network (no fixed image, no control): the precision comes from inner
/// constraints on the points. Intrinsics are estimable, so their σ must equal those of a
/// minimal datum (one image fixed, scale from one distance held by a tiny σ); the point
/// covariance has the minimum trace of all datums.
#[test]
fn free_network_by_inner_constraints() {
    let mut free = realisation(&truth(), 31);
    for pt in &mut free.points {
        pt.fixed = false;
    }
    solve(&mut free, &to_convergence(), |_| {}).unwrap();
    let inner = precision(&free).expect("inner constraints define the datum");

    let mut minimal = free.clone();
    minimal.images[0].fixed = true;
    let l = (minimal.points[0].position - minimal.points[40].position).norm();
    minimal.distances.push(Distance {
        a: PointKey(0),
        b: PointKey(40),
        value: l,
        sigma: 1e-3,
    });
    let fixed = precision(&minimal).unwrap();

    assert_eq!(inner.redundancy, fixed.redundancy);
    assert!((inner.sigma0 - fixed.sigma0).abs() < 1e-6 * fixed.sigma0);
    for (a, b) in inner.intrinsics[0]
        .sigmas
        .iter()
        .zip(&fixed.intrinsics[0].sigmas)
    {
        assert!(
            (a - b).abs() < 1e-4 * b,
            "intrinsic σ differs with the datum: {a} vs {b}"
        );
    }
    let trace = |p: &pingcal_ba::solver::Precision| -> f64 {
        p.point_covariances
            .iter()
            .flatten()
            .map(|c| c.trace())
            .sum()
    };
    let (ti, tf) = (trace(&inner), trace(&fixed));
    println!(
        "trace of point covariance: inner constraints {ti:.4}, one image + one distance {tf:.4}"
    );
    assert!(ti < tf, "minimum trace: {ti} vs {tf}");
}

#[test]
fn a_distance_point_without_rays_is_named_undetermined_not_a_datum_defect() {
    // A point of a distance sits in the reduced system; when data snooping has taken its rays
    // down to one and then none, the distance alone leaves two of its coordinates free. That
    // is the point's own defect (the pipeline drops the point and its distance), not a datum
    // defect of the network.
    let t = truth();
    let mut p = realisation(&t, 78);
    p.images[0].camera_from_object = t.images[0].camera_from_object;
    p.images[0].fixed = true;
    for pt in &mut p.points {
        pt.fixed = false;
    }
    for (a, b) in [(0, 40), (12, 70)] {
        p.distances.push(Distance {
            a: PointKey(a),
            b: PointKey(b),
            value: (t.points[a].position - t.points[b].position).norm(),
            sigma: 0.1,
        });
    }
    solve(&mut p, &to_convergence(), |_| {}).unwrap();
    let name = p.points[40].name.clone();
    for keep in [1, 0] {
        let mut q = p.clone();
        let mut seen = 0;
        q.observations.retain(|o| {
            let lose = o.point == PointKey(40) && seen >= keep;
            seen += (o.point == PointKey(40)) as usize;
            !lose
        });
        match precision(&q) {
            Err(PrecisionError::PointUndetermined(n)) => assert_eq!(n, name),
            other => panic!(
                "{keep} ray(s) left: {:?}",
                other.map(|_| ()).map_err(|e| e.to_string())
            ),
        }
    }
}

/// Variance components: the observations of every other point are three times noisier than
/// their σ says, those of the others half as noisy as theirs (a pessimistic a-priori σ, as
/// pingcal's targets have). One σ0 for all (√((¼ + 9)/2)-ish) is wrong for both groups; each
/// group's own σ0 (its vᵀPv over its share of the redundancy) recovers 0.5 and 3, the
/// redundancy numbers add up to the redundancy, and after Förstner's re-weighting every
/// group's σ0 is 1 and the points' σ's match their Monte Carlo errors group by group.
#[test]
fn variance_components_recover_each_groups_sigma() {
    use pingcal_ba::solver::{estimate_variance_components, variance_components};
    use rand_distr::{Distribution, Normal};
    let truth = truth();
    let group_of: Vec<usize> = truth.observations.iter().map(|o| o.point.0 % 2).collect();
    let names = ["half", "thrice"];
    let n = Normal::new(0.0, 1.0).unwrap();
    let runs = 40;
    let mut s0 = [0.0; 2];
    // per network and group: the mean z² of the points' coordinates
    let mut per_network: [Vec<f64>; 2] = [Vec::new(), Vec::new()];
    for run in 0..runs {
        let mut p = realisation(&truth, 9000 + run);
        let mut rng = pingcal_geometry::consensus::rng(19000 + run);
        for (o, &g) in p.observations.iter_mut().zip(&group_of) {
            // the realisation's noise is σ; group 0 claims 2σ, group 1 gets 3σ in all
            if g == 0 {
                o.sigma *= 2.0;
            } else {
                let extra = 8.0f64.sqrt() * o.sigma;
                o.uv += nalgebra::Vector2::new(n.sample(&mut rng), n.sample(&mut rng)) * extra;
            }
        }
        solve(&mut p, &to_convergence(), |_| {}).unwrap();
        let prec = precision(&p).unwrap();
        let total: f64 = prec
            .redundancy_numbers
            .iter()
            .map(|r| r[0] + r[1])
            .sum::<f64>()
            + prec.distance_redundancy_numbers.iter().sum::<f64>();
        assert!(
            (total - prec.redundancy as f64).abs() < 1e-6 * prec.redundancy as f64,
            "redundancy numbers add up to {total}, redundancy {}",
            prec.redundancy
        );
        let first = variance_components(&p, &prec, &group_of, &names);
        assert_eq!(first.len(), 2, "{first:?}");
        let est =
            estimate_variance_components(&mut p, &to_convergence(), &group_of, &names).unwrap();
        assert!((est.sigma0_a_priori - prec.sigma0).abs() < 1e-9);
        assert!(
            (est.precision.sigma0 - 1.0).abs() < 0.01,
            "{}",
            est.precision.sigma0
        );
        for (g, c) in est.components.iter().enumerate() {
            assert!(c.reweighted);
            s0[g] += c.sigma0 / runs as f64;
        }
        let (mut z2, mut count) = ([0.0; 2], [0usize; 2]);
        for (q, pt) in p.points.iter().enumerate() {
            if pt.fixed {
                continue;
            }
            let sig = est.precision.point_sigma(q).unwrap();
            for a in 0..3 {
                z2[q % 2] += ((pt.position[a] - truth.points[q].position[a]) / sig[a]).powi(2);
                count[q % 2] += 1;
            }
        }
        for g in 0..2 {
            per_network[g].push(z2[g] / count[g] as f64);
        }
    }
    println!("variance components: {s0:?} (want 0.5, 3)");
    assert!((s0[0] / 0.5 - 1.0).abs() < 0.02, "{s0:?}");
    assert!((s0[1] / 3.0 - 1.0).abs() < 0.02, "{s0:?}");
    // the points of each group: mean z² 1 within 4 standard errors of the mean of the
    // per-network values (the networks are independent, the points of one are not); one σ0
    // for both groups would give about 0.06 and 2
    for (g, v) in per_network.iter().enumerate() {
        let m = v.iter().sum::<f64>() / v.len() as f64;
        let var = v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() - 1) as f64;
        let tol = 4.0 * (var / v.len() as f64).sqrt();
        println!(
            "group {}: mean z² of the points {m:.3} (tolerance ±{tol:.3})",
            names[g]
        );
        assert!(
            (m - 1.0).abs() < tol,
            "group {}: mean z² {m} ± {tol}",
            names[g]
        );
    }
}

/// A free network of more than 20,000 unknowns (the dense form would need a 20,000² matrix)
/// gets its precision by bordering: finite, positive σ for every pose and point, σ0 at the
/// simulated noise, and the minimum trace: no pose or point σ larger than with one image
/// held (a datum that is itself a choice of the inner constraints' family).
#[test]
fn free_network_of_twenty_thousand_unknowns() {
    let p = adjusted_free_network(20, 7000, &to_convergence());
    let unknowns = 9 * p.images.len() + 3 * p.points.len();
    assert!(unknowns > 20_000);
    let prec = precision(&p).expect("a free network of any number of points");
    assert_eq!(prec.unknowns, unknowns);
    // σ0 estimates the 0.5 px noise (observations have σ = 1): its relative sd is
    // 1/√(2·redundancy) ≈ 0.005, so 5 % is more than 10 sd.
    assert!((prec.sigma0 - 0.5).abs() < 0.025, "σ0 {}", prec.sigma0);
    assert!(prec
        .point_covariances
        .iter()
        .all(|c| c.is_some_and(|c| c.diagonal().min() > 0.0)));
    assert!(prec.poses.iter().all(|s| s
        .as_ref()
        .is_some_and(|s| s.centre.iter().all(|v| *v > 0.0 && v.is_finite()))));
    let trace: f64 = prec
        .point_covariances
        .iter()
        .flatten()
        .map(|c| c.trace())
        .sum();
    assert!(trace.is_finite() && trace > 0.0);
}
