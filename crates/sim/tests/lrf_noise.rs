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
use pingcal_sim::config::{LrfConfig, SimConfig};
use pingcal_sim::lrf::simulate_scans;
use pingcal_sim::scene::{Surface, TestField};

/// A single flat wall 14 m × 14 m, 700 mm in front of the LRF, of the given albedo.
fn flat_wall(albedo: f64) -> TestField {
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
    TestField {
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
        // the ideal mount: these tests compare the readings with the scene's geometry
        mount_errors: false,
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
        // the ideal mount: these tests compare the readings with the scene's geometry
        mount_errors: false,
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

/// A continuous sweep (issue 16): the servo turns while the LRF scans, each beam at its own
/// angle. Written as `pingcal-scan` v2 and read back by the calibration's reader, each beam's
/// servo angle (`ScanLine::servo_deg_at`) puts its point on the wall z = 700 mm of the LRF
/// frame (eq. 2: z = r cos α sin β) to within the encoder's half step and the footprint's
/// bias; the one angle per scan that a v1 file keeps misplaces the same points by the servo's
/// travel during the scan.
#[test]
fn a_continuous_sweep_reads_back_with_each_beam_at_its_own_servo_angle() {
    let wall = Surface::new(
        "wall",
        Vector3::new(-7000.0, -7000.0, 700.0),
        Vector3::x(),
        Vector3::y(),
        Vector3::new(0.0, 0.0, -1.0),
        14000.0,
        14000.0,
        0.0,
        0.5,
        0.0,
        0,
    );
    let scene = TestField {
        surfaces: vec![wall],
        ..flat_wall(0.5)
    };
    let cfg = LrfConfig {
        servo_start_deg: 30.0,
        servo_end_deg: 60.0,
        servo_step_deg: 5.0, // 50°/s: 3.3° of travel over a scan's 682 beams
        continuous_sweep: true,
        noise: false,
        // the ideal mount: these tests compare the readings with the scene's geometry
        mount_errors: false,
        ..LrfConfig::default()
    };
    let scans = simulate_scans(&scene, &cfg, 7);
    let csv = pingcal_sim::lrf::write_scans_csv(Vec::new(), &scans, &cfg).unwrap();
    assert!(csv.starts_with(b"# pingcal-scan v2\n"));
    let reader = pingcal_lrf::scan::ScanReader::new(&csv[..], "sweep.csv").unwrap();
    let (mut worst_v2, mut worst_v1, mut n) = (0.0f64, 0.0f64, 0);
    for line in reader {
        let line = line.unwrap();
        for (i, &r) in line.ranges_mm.iter().enumerate() {
            let alpha = (cfg.angle_min_deg + i as f64 * cfg.angle_increment_deg).to_radians();
            if !(20.0..=3000.0).contains(&r) {
                continue;
            }
            let z = |beta_deg: f64| r * alpha.cos() * beta_deg.to_radians().sin();
            // the encoder's half step and 1 mm of footprint bias, at this beam's lever arm
            let x = r * alpha.cos();
            let allowed = x * (0.5 * cfg.servo_resolution_deg).to_radians() + 1.5;
            let e2 = (z(line.servo_deg_at(i)) - 700.0).abs();
            assert!(
                e2 <= allowed,
                "beam {i}: z off the wall by {e2:.2} mm (allowed {allowed:.2})"
            );
            worst_v2 = worst_v2.max(e2);
            worst_v1 = worst_v1.max((z(line.servo_deg) - 700.0).abs());
            n += 1;
        }
    }
    println!("{n} returns: worst |z − 700| {worst_v2:.2} mm per beam, {worst_v1:.1} mm with one angle per scan");
    assert!(n > 1000, "only {n} returns");
    assert!(
        worst_v1 > 10.0 * worst_v2,
        "the per-scan angle is not worse: {worst_v1} vs {worst_v2}"
    );
}

/// Issue 37: `servo_passes = 2` sweeps forward then back, and `servo_time_offset_s` makes
/// each scan's servo angle in the file the one the servo had that much earlier: off by
/// −speed · offset, with the sign of the direction; the ranges do not change.
#[test]
fn the_servo_time_offset_shifts_the_reported_angle_against_the_direction_of_the_sweep() {
    let scene = flat_wall(0.5);
    let base = LrfConfig {
        servo_start_deg: -10.0,
        servo_end_deg: 10.0,
        servo_step_deg: 1.0,
        continuous_sweep: true,
        servo_passes: 2,
        servo_resolution_deg: 1e-6,
        noise: false,
        mount_errors: false,
        ..LrfConfig::default()
    };
    let valid = |lrf: &LrfConfig| {
        SimConfig {
            lrf: lrf.clone(),
            ..SimConfig::default()
        }
        .validate()
    };
    valid(&base).unwrap();
    let late = LrfConfig {
        servo_time_offset_s: 0.02,
        ..base.clone()
    };
    valid(&late).unwrap();
    let (a, b) = (
        simulate_scans(&scene, &base, 3),
        simulate_scans(&scene, &late, 3),
    );
    assert_eq!((a.len(), b.len()), (42, 42));
    let speed = 1.0 / 0.1; // degrees per second
    for (k, (x, y)) in a.iter().zip(&b).enumerate() {
        let direction = if k < 21 { 1.0 } else { -1.0 };
        let shift = y.servo_deg - x.servo_deg;
        assert!(
            (shift + direction * speed * 0.02).abs() < 2e-6,
            "scan {k}: {shift}"
        );
        let (ex, ey) = (x.servo_end_deg.unwrap(), y.servo_end_deg.unwrap());
        assert!((ey - ex - shift).abs() < 1e-9, "scan {k}");
        assert!(
            (ex - x.servo_deg) * direction > 0.0,
            "scan {k} turns the wrong way"
        );
        assert_eq!(x.ranges_mm, y.ranges_mm, "scan {k}");
        assert_eq!(x.true_servo_deg, y.true_servo_deg, "scan {k}");
    }
    // the second pass comes back over the first pass's angles
    assert!(
        (a[21].true_servo_deg - 10.0).abs() < 1e-9 && (a[41].true_servo_deg + 10.0).abs() < 1e-9
    );
    // an offset only a continuous sweep shows, and passes within reason
    let e = valid(&LrfConfig {
        continuous_sweep: false,
        ..late.clone()
    })
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("lrf.servo_time_offset_s = 0.02: only a continuous sweep shows it"),
        "{e}"
    );
    let e = valid(&LrfConfig {
        servo_passes: 0,
        ..base.clone()
    })
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("lrf.servo_passes = 0: expected 1 to 16 passes"),
        "{e}"
    );
}
