//! Diagnostic: ball finding on the benchmark scene at several sweep densities.
//! `cargo run -p pingcal-lrf --release --example diag_density -- N_SCANS [N_BALLS] [SEED]`
use pingcal_lrf::ball_finder::{find_balls, FinderOptions};
use pingcal_lrf::cloud::{Cloud, MountModel};
use pingcal_lrf::scan::ScanHeader;
use pingcal_lrf::simulate::{room_corner_scene, SimulatedLrf};

fn main() {
    let mut a = std::env::args().skip(1);
    let n: usize = a.next().map(|s| s.parse().unwrap()).unwrap_or(2150);
    let nb: usize = a.next().map(|s| s.parse().unwrap()).unwrap_or(16);
    let seed: u64 = a.next().map(|s| s.parse().unwrap()).unwrap_or(42);
    let mut rng = pingcal_geometry::consensus::rng(seed);
    let scene = room_corner_scene(nb, &mut rng);
    let scans = scene.half_sweep(n, &SimulatedLrf::default(), &mut rng);
    let cloud = Cloud::from_scans(
        &ScanHeader::URG_04LX,
        scans.into_iter().map(Ok),
        &MountModel::default(),
    )
    .unwrap();
    let t0 = std::time::Instant::now();
    let f = find_balls(&cloud, &FinderOptions::default());
    println!(
        "{} points, {:.2?}, {} balls, {} rejected, {} clusters",
        cloud.len(),
        t0.elapsed(),
        f.balls.len(),
        f.rejected.len(),
        f.clusters
    );
    for (k, c) in scene.balls.iter().enumerate() {
        // points within R+10 of the true centre
        let near = cloud
            .points
            .iter()
            .filter(|p| (*p - c).norm() < 29.0)
            .count();
        let ball = f.balls.iter().find(|b| (b.centre - c).norm() < 40.0);
        let rej = f
            .rejected
            .iter()
            .filter(|r| (r.centre - c).norm() < 60.0)
            .collect::<Vec<_>>();
        print!("ball {k:2}: dist {:5.0} near-pts {near:5}", c.norm());
        if let Some(b) = ball {
            let e = b.centre - c;
            let u = c.normalize();
            let ts = nalgebra::Vector3::y().cross(&u).normalize();
            let ta = u.cross(&ts);
            print!(
                "  radial {:+6.2} servo {:+5.2} alpha {:+5.2}",
                e.dot(&u),
                e.dot(&ts),
                e.dot(&ta)
            );
            print!(
                "  FOUND err {:6.2} σmax {:5.2} inl {} cl {} r {:.1}±{:.1} thr {}/{} sect {}",
                (b.centre - c).norm(),
                b.cov.symmetric_eigenvalues().max().sqrt(),
                b.inliers.len(),
                b.cluster_points,
                b.support.free_radius_mm,
                b.support.sigma_free_radius_mm,
                b.support.through,
                b.support.on_surface,
                b.support.coverage
            );
        }
        for r in rej {
            print!(
                "  REJ cl {} d {:.0}: {}",
                r.cluster_points,
                (r.centre - c).norm(),
                r.reason
            );
        }
        println!();
    }
    for b in &f.balls {
        if scene.balls.iter().all(|c| (b.centre - c).norm() >= 40.0) {
            println!("false ball at {:.0?}", b.centre.as_slice());
        }
    }
}
