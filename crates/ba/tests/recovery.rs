//! Recovery of known truth by a self-calibrating bundle adjustment with the
//! photogrammetric camera model: a room-corner test field photographed by a convergent
//! network with 90° rolls, image noise σ, datum from four fixed control points.
//!
//! Monte Carlo over noise realisations: the RMS image residual matches σ scaled by the
//! redundancy, and the truth lies within 3 Monte Carlo standard deviations of the
//! estimates of every intrinsic parameter and point coordinate (with the rate that a
//! normal distribution allows), with no significant bias.

use crate::common;

use common::{realisation, to_convergence, truth, SIGMA_PX};
use pingcal_ba::solver::solve;

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
    let options = to_convergence();
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
