//! Issue 15: a 38 mm ball's centre from the rotating URG-04LX against distance (0.5–2 m),
//! on simulated sweeps with truth (`pingcal_lrf::simulate`: its noise and mixed pixels):
//! how often it is found, its bias (radial, along the view, and lateral), and the reported
//! σ against the Monte Carlo spread of the errors, per axis of the view frame.
//!
//! `cargo test --release -p pingcal-lrf --test lrf ball_range_study:: -- --nocapture`.
//!
//! The ball hangs 150 mm in front of a wall (the plane behind it, facing the sensor), in a
//! random direction of the half sweep. Tolerance of the σ ratio from statistics: the 99 %
//! interval of RMS/σ for n honest errors, √(χ²₀.₀₀₅(n)/n) … √(χ²₀.₉₉₅(n)/n).

use nalgebra::Vector3;
use pingcal_lrf::ball_finder::{find_balls, FinderOptions};
use pingcal_lrf::simulate::{LrfScene, SimulatedLrf};
use rand::Rng;

use pingcal_geometry::stats::chi2_quantile;

#[test]
fn ball_centre_bias_and_sigma_against_distance() {
    println!("range m  found   bias radial/lateral/lateral mm   RMS error mm         RMS σ mm             error/σ");
    for d in [500.0, 1000.0, 1500.0, 2000.0] {
        let (mut err, mut sig, mut found_n, mut tried) = (Vec::new(), Vec::new(), 0, 0);
        for seed in 0..12u64 {
            let mut rng = pingcal_geometry::consensus::rng(77_000 + seed);
            // a direction the half sweep sees (x ≥ 0), away from the servo axis (+Y)
            let az: f64 = rng.random_range(-60f64..60.0).to_radians();
            let el: f64 = rng.random_range(-30f64..30.0).to_radians();
            let u = Vector3::new(az.cos() * el.cos(), az.sin() * el.cos(), el.sin());
            let c = u * d;
            let scene = LrfScene {
                planes: vec![(u, d + 150.0 + 19.0)],
                balls: vec![c],
                radius: 19.0,
                clutter: Vec::new(),
            };
            let cloud = scene.half_sweep_cloud(512, &SimulatedLrf::default(), &mut rng);
            let found = find_balls(&cloud, &FinderOptions::default());
            tried += 1;
            let Some(b) = found.balls.iter().find(|b| (b.centre - c).norm() < 38.0) else {
                continue;
            };
            assert_eq!(found.balls.len(), 1, "{d} mm, seed {seed}: a false ball");
            found_n += 1;
            let h = u.cross(&Vector3::z()).normalize();
            let v = h.cross(&u);
            let e = b.centre - c;
            let axes = [u, h, v];
            err.push(axes.map(|a| e.dot(&a)));
            sig.push(axes.map(|a| (a.transpose() * b.cov * a)[0].max(0.0).sqrt()));
        }
        let n = err.len();
        let mean = |f: &dyn Fn(&[f64; 3]) -> f64, v: &[[f64; 3]]| {
            v.iter().map(f).sum::<f64>() / n.max(1) as f64
        };
        let bias: [f64; 3] = std::array::from_fn(|a| mean(&|e| e[a], &err));
        let rms: [f64; 3] = std::array::from_fn(|a| mean(&|e| e[a] * e[a], &err).sqrt());
        let sg: [f64; 3] = std::array::from_fn(|a| mean(&|s| s[a] * s[a], &sig).sqrt());
        let ratio: [f64; 3] = std::array::from_fn(|a| rms[a] / sg[a]);
        println!(
            "{:5.1}    {found_n:2}/{tried:2}   {:+6.2} {:+6.2} {:+6.2}       {:5.2} {:5.2} {:5.2}     {:5.2} {:5.2} {:5.2}     {:4.2} {:4.2} {:4.2}",
            d / 1000.0, bias[0], bias[1], bias[2], rms[0], rms[1], rms[2], sg[0], sg[1], sg[2], ratio[0], ratio[1], ratio[2]
        );
        if d <= 1000.0 {
            assert_eq!(
                found_n, tried,
                "{d} mm: the ball was not found in every sweep"
            );
        }
        if n >= 8 {
            let k = n as f64;
            let hi = (chi2_quantile(k, 2.576) / k).sqrt();
            for (a, what) in ["radial", "lateral 1", "lateral 2"].iter().enumerate() {
                assert!(
                    ratio[a] <= hi,
                    "{d} mm, {what}: RMS error / σ = {:.2} over the 99 % bound {hi:.2} of {n} honest errors",
                    ratio[a]
                );
            }
        }
    }
}
