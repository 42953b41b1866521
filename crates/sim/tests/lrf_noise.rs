//! The LRF's ranges on a flat wall have the mean and the spread of the noise model.
//!
//! A wall is the plane y = 700 mm of the LRF frame (perpendicular to the servo shaft), so a
//! beam at angle α has the true range 700 / sin α at every servo angle, from 0.7 m (α = 90°)
//! to 5.6 m: both regimes of the URG-04LX datasheet (±30 mm under 1 m, ±3 % beyond, taken
//! as 3σ). For every return, z = (r_measured − r_true) / σ(r_true) should be N(0, 1)
//! apart from the 1 mm rounding (variance 1/12 mm², negligible against σ ≥ 10 mm).
//!
//! Tolerances: with N returns per regime, the sample mean of z has SE 1/√N and the sample
//! standard deviation SE ≈ 1/√(2N); we allow 5 SE. The beam footprint (five sub-rays
//! averaged by received power) biases the range on a slanted wall by second-order terms,
//! ≲ 0.4 mm at α = 10° (≈ 0.01 σ there), inside the tolerance and accounted for in it.

use nalgebra::Vector3;
use pingcal_sim::config::LrfConfig;
use pingcal_sim::lrf::simulate_scans;
use pingcal_sim::scene::{Scene, Surface};

/// A single flat wall 14 m × 14 m, 700 mm in front of the LRF, of the given albedo.
fn flat_wall(albedo: f64) -> Scene {
    let wall = Surface::new(
        "wall",
        Vector3::new(-7000.0, 700.0, -7000.0),
        Vector3::x(),
        Vector3::z(),
        Vector3::new(0.0, -1.0, 0.0),
        14000.0,
        14000.0,
        0.0,
        albedo,
        0.0,
        0,
    );
    Scene {
        surfaces: vec![wall],
        targets: vec![],
        balls: vec![],
        distances: vec![],
        black_albedo: 0.04,
        retro_gain: 3.0,
        ball_albedo: 0.9,
        stem_albedo: 0.3,
    }
}

#[test]
fn ranges_on_a_flat_wall_have_the_datasheet_mean_and_spread() {
    let scene = flat_wall(0.5);
    let cfg = LrfConfig {
        servo_start_deg: -40.0,
        servo_end_deg: 40.0,
        servo_step_deg: 1.0,
        ..LrfConfig::default()
    };
    let scans = simulate_scans(&scene, &cfg, 42);
    // (regime, z values, raw residuals)
    let mut near: Vec<(f64, f64)> = Vec::new();
    let mut far: Vec<(f64, f64)> = Vec::new();
    for s in &scans {
        for (i, &r) in s.ranges_mm.iter().enumerate() {
            let alpha = (cfg.angle_min_deg + i as f64 * cfg.angle_increment_deg).to_radians();
            if alpha.sin() <= 0.0 {
                assert_eq!(r, 0, "a beam pointing away from the wall returned {r}");
                continue;
            }
            let truth = 700.0 / alpha.sin();
            // Stay clear of the 1 m switch (σ jumps there) and of max range.
            if truth > 5000.0 || (truth > 950.0 && truth < 1050.0) {
                continue;
            }
            assert!(
                r > 0,
                "no return at α = {:.2}° (true range {truth:.0} mm)",
                alpha.to_degrees()
            );
            let sigma = cfg.range_sigma_mm(truth);
            let z = (r as f64 - truth) / sigma;
            if truth < 1000.0 {
                near.push((z, r as f64 - truth));
            } else {
                far.push((z, r as f64 - truth));
            }
        }
    }
    for (name, v, sigma_raw) in [("under 1 m", &near, Some(10.0)), ("beyond 1 m", &far, None)] {
        let n = v.len() as f64;
        assert!(n > 3000.0, "{name}: only {n} returns");
        let mean = v.iter().map(|x| x.0).sum::<f64>() / n;
        let sd = (v.iter().map(|x| (x.0 - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        println!("{name}: {n} returns, mean z = {mean:.4} (tolerance {:.4}), sd z = {sd:.4} (tolerance {:.4})", 5.0 / n.sqrt(), 5.0 / (2.0 * n).sqrt());
        assert!(mean.abs() < 5.0 / n.sqrt(), "{name}: mean of z = {mean}");
        assert!(
            (sd - 1.0).abs() < 5.0 / (2.0 * n).sqrt(),
            "{name}: sd of z = {sd}"
        );
        if let Some(s) = sigma_raw {
            let m = v.iter().map(|x| x.1).sum::<f64>() / n;
            let sd_raw = (v.iter().map(|x| (x.1 - m).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
            println!("{name}: raw mean {m:.3} mm, raw sd {sd_raw:.3} mm (model {s} mm)");
            assert!(
                (sd_raw - s).abs() < 5.0 * s / (2.0 * n).sqrt() + 0.05,
                "{name}: raw sd {sd_raw}"
            );
        }
    }
}

#[test]
fn dark_surfaces_give_no_return_and_servo_angles_are_encoder_steps() {
    let scene = flat_wall(0.05);
    let cfg = LrfConfig {
        servo_start_deg: -5.0,
        servo_end_deg: 5.0,
        servo_step_deg: 1.0,
        ..LrfConfig::default()
    };
    let scans = simulate_scans(&scene, &cfg, 1);
    for s in &scans {
        assert!(
            s.ranges_mm.iter().all(|&r| r == 0),
            "a return from a 5 % albedo wall"
        );
        let ticks = s.servo_deg / cfg.servo_resolution_deg;
        assert!((ticks - ticks.round()).abs() < 1e-9);
        assert!((s.servo_deg - s.true_servo_deg).abs() < 0.2);
    }
}
