//! Generates a synthetic BAL problem and solves it, printing where the time goes.
//!
//! `cargo run --release -p pingcal-ba --example solve_synthetic -- CAMERAS POINTS OBS_PER_POINT THREADS [dense|sparse|iterative|auto] [banded|random]`

use pingcal_ba::solver::{solve, LinearSolverKind, Options};
use pingcal_ba::synthetic::SyntheticBal;

fn main() {
    let a: Vec<String> = std::env::args().collect();
    let num = |i: usize, d: usize| a.get(i).and_then(|s| s.parse().ok()).unwrap_or(d);
    let spec = SyntheticBal {
        cameras: num(1, 200),
        points: num(2, 30000),
        obs_per_point: num(3, 6),
        visibility: match a.get(6).map(String::as_str) {
            Some("random") => pingcal_ba::synthetic::Visibility::Random,
            _ => pingcal_ba::synthetic::Visibility::Banded,
        },
        ..Default::default()
    };
    let kind = match a.get(5).map(String::as_str) {
        Some("dense") => LinearSolverKind::Dense,
        Some("sparse") => LinearSolverKind::Sparse,
        Some("iterative") => LinearSolverKind::Iterative,
        _ => LinearSolverKind::Auto,
    };
    let mut p = spec.generate().expect("valid sizes").problem;
    let opts = Options {
        threads: num(4, 1),
        linear_solver: kind,
        ..Options::default()
    };
    let cpu0 = cpu_time();
    let s = solve(&mut p, &opts, |_| {}).expect("solves");
    println!(
        "{} cams {} pts {} obs: cost {:.6e} -> {:.6e}, {} iterations, total {:.3} s (cpu {:.3} s): evaluation {:.3}, schur {:.3}, linear {:.3} ({})",
        p.images.len(),
        p.points.len(),
        p.observations.len(),
        s.initial_cost,
        s.final_cost,
        s.iterations,
        s.time_s,
        cpu_time() - cpu0,
        s.evaluation_time_s,
        s.schur_time_s,
        s.linear_solver_time_s,
        s.linear_solver.kind
    );
}

/// User + system CPU time of this process, seconds (from /proc, Linux only; 0 elsewhere).
fn cpu_time() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return 0.0;
    };
    let fields: Vec<&str> = stat
        .rsplit(')')
        .next()
        .unwrap_or("")
        .split_whitespace()
        .collect();
    let ticks = |i: usize| {
        fields
            .get(i)
            .and_then(|s| s.parse::<f64>().ok())
            .unwrap_or(0.0)
    };
    (ticks(11) + ticks(12)) / 100.0
}
