//! Issue 15: the large sphere's centre from a 16-beam lidar against distance, on simulated
//! frames with truth (`pingcal_sim::sphere_calib`: a VLP-16-like lidar, a 600 mm sphere, a
//! floor and a wall), 1.5–10 m (nearer, the data set's camera cannot see the whole sphere). For each distance: how often the one sphere is found, the centre's
//! bias (radial, i.e. along the view, and lateral), and the reported σ against the Monte
//! Carlo spread of the errors, per axis of the view frame.
//!
//! `cargo test --release -p pingcal-sim --test sim sphere_range_study:: -- --nocapture` (fast: 8
//! seeds × 3 frames per distance); the 20-seed table of the closing note:
//! `… -- --ignored --nocapture`.
//!
//! Tolerance of the σ ratio, from statistics: the RMS of n standard-normal errors has a
//! relative standard error of 1/√(2n); the 99 % interval of RMS/σ for n samples is
//! √(χ²₀.₀₀₅(n)/n) … √(χ²₀.₉₉₅(n)/n) (Wilson–Hilferty), which the test uses per axis.

use nalgebra::Vector3;
use pingcal_lrf::ball_finder::{find_balls, FinderOptions};
use pingcal_lrf::cloud::Cloud;
use pingcal_lrf::RangeNoise;
use pingcal_sim::sphere_calib::{SphereCalibConfig, SphereCalibSim};

use pingcal_geometry::stats::chi2_quantile;

struct Row {
    range_m: f64,
    tried: usize,
    found: usize,
    /// Errors and reported σ in the view frame (radial, horizontal, vertical), mm.
    err: Vec<[f64; 3]>,
    sig: Vec<[f64; 3]>,
    why: std::collections::BTreeMap<String, usize>,
}

fn study(seeds: u64) -> Vec<Row> {
    let noise = RangeNoise::named("VLP-16").unwrap();
    let opt = FinderOptions {
        diameter_mm: 600.0,
        noise,
        ..Default::default()
    };
    let mut rows = Vec::new();
    for d in [1500.0, 2000.0, 4000.0, 6000.0, 8000.0, 10_000.0] {
        let cfg = SphereCalibConfig {
            frames: 3,
            range_mm: [d, d + 1.0],
            ..Default::default()
        };
        let mut row = Row {
            range_m: d / 1000.0,
            tried: 0,
            found: 0,
            err: Vec::new(),
            sig: Vec::new(),
            why: Default::default(),
        };
        for seed in 0..seeds {
            // a place where the camera sees the whole sphere too may not exist for a seed
            let Ok(sim) = SphereCalibSim::new(&cfg, 1000 + seed) else {
                continue;
            };
            for k in 0..cfg.frames {
                let (pts, _) = sim.cloud(k);
                let truth = sim.centres_lidar[k];
                let found = find_balls(&Cloud::from_points(pts), &opt);
                row.tried += 1;
                if found.balls.len() != 1 {
                    // why the sphere itself was not taken
                    if let Some(r) = found
                        .rejected
                        .iter()
                        .find(|r| (r.centre - truth).norm() < 300.0)
                    {
                        *row.why
                            .entry(r.reason.split(':').next().unwrap_or("").to_string())
                            .or_default() += 1;
                    }
                    continue;
                }
                let b = &found.balls[0];
                assert!(
                    (b.centre - truth).norm() < 300.0,
                    "{d} mm, seed {seed}, frame {k}: a false sphere at {:?} (truth {truth:?})",
                    b.centre
                );
                row.found += 1;
                let r = truth.normalize();
                let h = r.cross(&Vector3::z()).normalize();
                let v = h.cross(&r);
                let e = b.centre - truth;
                let axes = [r, h, v];
                row.err.push(axes.map(|a| e.dot(&a)));
                row.sig
                    .push(axes.map(|a| (a.transpose() * b.cov * a)[0].max(0.0).sqrt()));
            }
        }
        rows.push(row);
    }
    rows
}

fn report_and_check(rows: &[Row]) {
    println!("range m  found     bias radial/horiz/vert mm   RMS error mm          RMS σ mm              error/σ");
    for row in rows {
        let n = row.err.len();
        let mean = |f: &dyn Fn(&[f64; 3]) -> f64, v: &[[f64; 3]]| {
            v.iter().map(f).sum::<f64>() / n.max(1) as f64
        };
        let bias: [f64; 3] = std::array::from_fn(|a| mean(&|e| e[a], &row.err));
        let rms: [f64; 3] = std::array::from_fn(|a| mean(&|e| e[a] * e[a], &row.err).sqrt());
        let sig: [f64; 3] = std::array::from_fn(|a| mean(&|s| s[a] * s[a], &row.sig).sqrt());
        let ratio: [f64; 3] = std::array::from_fn(|a| rms[a] / sig[a]);
        println!(
            "{:5.1}    {:2}/{:2}   {:+6.2} {:+6.2} {:+6.2}      {:5.2} {:5.2} {:5.2}     {:5.2} {:5.2} {:5.2}     {:4.2} {:4.2} {:4.2}",
            row.range_m, row.found, row.tried, bias[0], bias[1], bias[2], rms[0], rms[1], rms[2], sig[0], sig[1], sig[2],
            ratio[0], ratio[1], ratio[2]
        );
        for (why, n) in &row.why {
            println!("         not taken {n}×: {why}");
        }
        // the sphere is found wherever two rings or more cross it (all but the farthest)
        if row.range_m <= 6.0 {
            assert_eq!(
                row.found, row.tried,
                "{} m: the sphere was not found in every frame",
                row.range_m
            );
        }
        if n >= 10 {
            let k = n as f64;
            let (lo, hi) = (
                (chi2_quantile(k, -2.576) / k).sqrt(),
                (chi2_quantile(k, 2.576) / k).sqrt(),
            );
            for (a, what) in ["radial", "horizontal", "vertical"].iter().enumerate() {
                // error/σ includes the bias: an honest σ with no bias lies in [lo, hi]
                assert!(
                    ratio[a] >= lo && ratio[a] <= hi,
                    "{} m, {what}: RMS error / σ = {:.2} outside the 99 % interval [{lo:.2}, {hi:.2}] of {n} honest errors",
                    row.range_m,
                    ratio[a]
                );
            }
        }
    }
}

#[test]
fn sphere_centre_bias_and_sigma_against_distance() {
    report_and_check(&study(8));
}

#[test]
#[ignore = "the 20-seed table of the closing note (about a minute)"]
fn sphere_centre_bias_and_sigma_against_distance_20_seeds() {
    report_and_check(&study(20));
}
