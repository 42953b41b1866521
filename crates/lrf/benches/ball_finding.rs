//! Ball finding on a ~1-million-point simulated room-corner cloud (URG-04LX noise, 16 balls):
//! time and centre error. `cargo bench -p pingcal-lrf --bench ball_finding`
//! Writes the cloud as XYZ to `$PINGCAL_BENCH_XYZ` when set (for bench/lrf/run.sh, which runs
//! pyransac3d and Open3D on the same points).

use pingcal_lrf::ball_finder::{find_balls, FinderOptions};
use pingcal_lrf::cloud::{Cloud, MountModel};
use pingcal_lrf::scan::ScanHeader;
use pingcal_lrf::simulate::{room_corner_scene, SimulatedLrf};
use std::io::Write;

fn main() {
    let mut rng = pingcal_geometry::consensus::rng(42);
    let scene = room_corner_scene(16, &mut rng);
    let scans = scene.half_sweep(2150, &SimulatedLrf::default(), &mut rng);
    let cloud = Cloud::from_scans(
        &ScanHeader::URG_04LX,
        scans.into_iter().map(Ok),
        &MountModel::default(),
    )
    .unwrap();
    if let Ok(path) = std::env::var("PINGCAL_BENCH_XYZ") {
        let mut w = std::io::BufWriter::new(std::fs::File::create(&path).unwrap());
        for p in &cloud.points {
            writeln!(w, "{:.1} {:.1} {:.1}", p.x, p.y, p.z).unwrap();
        }
        let mut t = std::fs::File::create(format!("{path}.balls")).unwrap();
        for c in &scene.balls {
            writeln!(t, "{} {} {}", c.x, c.y, c.z).unwrap();
        }
    }
    let mut times = Vec::new();
    let mut found = None;
    for _ in 0..5 {
        let t0 = std::time::Instant::now();
        found = Some(find_balls(&cloud, &FinderOptions::default()));
        times.push(t0.elapsed().as_secs_f64());
    }
    times.sort_by(f64::total_cmp);
    let f = found.unwrap();
    let errs: Vec<f64> = f
        .balls
        .iter()
        .map(|b| {
            scene
                .balls
                .iter()
                .map(|c| (c - b.centre).norm())
                .fold(f64::INFINITY, f64::min)
        })
        .collect();
    let rms = (errs.iter().map(|e| e * e).sum::<f64>() / errs.len().max(1) as f64).sqrt();
    println!(
        "pingcal find_balls: {} points, median {:.3} s (min {:.3}), {} balls found ({} rejected), centre error rms {:.2} mm, max {:.2} mm",
        cloud.len(),
        times[2],
        times[0],
        f.balls.len(),
        f.rejected.len(),
        rms,
        errs.iter().cloned().fold(0.0, f64::max)
    );
}
