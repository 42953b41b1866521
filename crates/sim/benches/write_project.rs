//! Benchmark: the whole default project directory (paper-sized field, all stations, the
//! full servo sweep), written to a temporary folder. Run with
//! `cargo bench -p pingcal-sim --bench write_project` (release). Target: under 30 s on 2 cores.

use std::time::Instant;

fn main() {
    let seed = std::env::var("PINGCAL_SIM_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1);
    let runs: usize = std::env::var("PINGCAL_SIM_RUNS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1);
    let cfg = pingcal_sim::SimConfig::default();
    for run in 0..runs {
        let dir =
            std::env::temp_dir().join(format!("pingcal-sim-bench-{}-{run}", std::process::id()));
        let t0 = Instant::now();
        let sim = pingcal_sim::Simulation::new(&cfg, seed).expect("simulation");
        let t1 = Instant::now();
        let s = pingcal_sim::write_project(&sim, &dir).expect("write");
        let t2 = Instant::now();
        println!(
            "write_project: {:.2} s total ({:.2} s scene + {} LRF scans, {:.2} s {} images + files), {} targets ({} coded), {} balls, {} threads",
            (t2 - t0).as_secs_f64(),
            (t1 - t0).as_secs_f64(),
            s.scans,
            (t2 - t1).as_secs_f64(),
            s.images,
            s.targets,
            s.coded,
            s.balls,
            rayon::current_num_threads()
        );
        if std::env::var("PINGCAL_SIM_KEEP").is_err() {
            let _ = std::fs::remove_dir_all(&dir);
        } else {
            println!("kept {}", dir.display());
        }
    }
}
