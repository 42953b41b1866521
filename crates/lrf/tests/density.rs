//! The same simulated room swept at 240k and ~1M points: ball finding must not degrade with
//! density (all 16 balls found at both). In a dense sweep the ~1 % of wall points beyond the plane gate (the Gaussian
//! tail) come closer together than the cluster link distance and chained the balls in front
//! of a wall into one wall-sized cluster, which was dropped as too large (9 balls at 240k,
//! 8 at 1M, 6 at 2M). Too-large clusters are now split with a shorter link.

use pingcal_lrf::ball_finder::{find_balls, FinderOptions};
use pingcal_lrf::cloud::{Cloud, MountModel};
use pingcal_lrf::scan::ScanHeader;
use pingcal_lrf::simulate::{room_corner_scene, UrgNoise};
use rand::SeedableRng;

fn check(n_scans: usize) {
    let mut rng = rand::rngs::StdRng::seed_from_u64(42);
    let scene = room_corner_scene(16, &mut rng);
    let servo: Vec<f64> = (0..n_scans)
        .map(|k| -90.0 + k as f64 * 180.0 / n_scans as f64)
        .collect();
    let h = ScanHeader::URG_04LX;
    let noise = UrgNoise::default();
    let scans = scene.scan(&h, 682, &servo, &MountModel::default(), &noise, &mut rng);
    let cloud = Cloud::from_scans(&h, scans.into_iter().map(Ok), &MountModel::default()).unwrap();
    let found = find_balls(&cloud, &FinderOptions::default());
    println!("{} points: {} balls", cloud.len(), found.balls.len());
    let mut hit = vec![false; scene.balls.len()];
    for b in &found.balls {
        let (k, d) = scene
            .balls
            .iter()
            .enumerate()
            .map(|(k, c)| (k, (c - b.centre).norm()))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap();
        let sd = b.cov.symmetric_eigenvalues().max().sqrt();
        println!(
            "  ball {k}: range {:.0} mm, error {d:.2} mm, σmax {sd:.2}",
            b.range_mm
        );
        // Bound: 4 σ of the largest covariance axis (a 3D Gaussian error exceeds it with
        // probability < 0.2 % when the covariance is elongated along the view, as it is on a
        // visible cap) plus 0.5 mm for the fit's model bias (the bias goal at 1 m).
        assert!(
            d < 4.0 * sd + 0.5,
            "{n_scans} scans: ball {k} off by {d:.2} mm (σ {sd:.2}): false or biased ball"
        );
        hit[k] = true;
    }
    // the scene's balls are 0.85–1.35 m away, as the paper's (σ of a range ≤ 13.5 mm, under
    // three quarters of the radius), all in the sweep: every one must be found at any density
    for (k, c) in scene.balls.iter().enumerate() {
        assert!(
            hit[k],
            "{n_scans} scans: ball {k} at {:.0} mm not found",
            c.norm()
        );
    }
}

#[test]
fn all_balls_found_at_240k_points() {
    check(512);
}

#[test]
fn all_balls_found_at_1m_points() {
    check(2150);
}
