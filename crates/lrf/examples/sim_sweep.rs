//! Writes a simulated URG-04LX sweep of a room corner with 16 balls, and the true ball
//! centres, for trying `pingcal cloud` and `pingcal register` and for the benchmark.
//!
//! `cargo run -p pingcal-lrf --release --example sim_sweep -- OUT_DIR [SERVO_STEP_DEG] [SEED]`
//! writes OUT_DIR/sweep.csv, OUT_DIR/balls_lrf_true.txt (id x y z, LRF frame) and
//! OUT_DIR/balls_camera.txt (the same balls under the paper's Table 1 transform).

use pingcal_geometry::from_opk;
use pingcal_lrf::scan::{write_scans, ScanHeader};
use pingcal_lrf::simulate::{room_corner_scene, SimulatedLrf};
use std::io::Write;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut a = std::env::args().skip(1);
    let dir = std::path::PathBuf::from(
        a.next()
            .ok_or("usage: sim_sweep OUT_DIR [SERVO_STEP_DEG] [SEED]")?,
    );
    let step: f64 = a
        .next()
        .map(|s| s.parse())
        .transpose()?
        .unwrap_or(0.3515625);
    let seed: u64 = a.next().map(|s| s.parse()).transpose()?.unwrap_or(42);
    std::fs::create_dir_all(&dir)?;
    let mut rng = pingcal_geometry::consensus::rng(seed);
    let scene = room_corner_scene(16, &mut rng);
    let n = (180.0 / step).round() as usize;
    let scans = scene.half_sweep(n, &SimulatedLrf::default(), &mut rng);
    write_scans(
        std::io::BufWriter::new(std::fs::File::create(dir.join("sweep.csv"))?),
        &ScanHeader::URG_04LX,
        &scans,
    )?;
    let r = from_opk(0.012, -0.016, 0.0);
    let t = nalgebra::Vector3::new(65.9, 8.4, 107.4);
    let mut f1 = std::fs::File::create(dir.join("balls_lrf_true.txt"))?;
    let mut f2 = std::fs::File::create(dir.join("balls_camera.txt"))?;
    for (k, c) in scene.balls.iter().enumerate() {
        writeln!(f1, "B{} {:.3} {:.3} {:.3}", k + 1, c.x, c.y, c.z)?;
        let q = r * c + t;
        writeln!(
            f2,
            "B{} {:.3} {:.3} {:.3} 0.5 0.5 0.5",
            k + 1,
            q.x,
            q.y,
            q.z
        )?;
    }
    println!(
        "{} scans × 682 beams → {}",
        n,
        dir.join("sweep.csv").display()
    );
    Ok(())
}
