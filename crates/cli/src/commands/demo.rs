//! `pingcal demo [--out DIR] [--seed N] [--quiet]`: the embedded default. Simulates the
//! paper's test field and sensors (`pingcal simulate`), calibrates it (`pingcal calibrate`),
//! and prints the paper's Table 4 (check-point errors, dx = estimated − reference) for the
//! sphere method and the Fan et al. 2019 corner baseline beside the truth, which a simulation
//! knows: the extrinsic's true error, and the check errors the true extrinsic would give on
//! the same measurements (the floor set by the measurement noise).

use super::calibrate::{calibrate_one, write_outputs};
use super::progress::reporter;
use super::CmdResult;
use indicatif::MultiProgress;
use pingcal_pipeline as pipeline;
use std::path::PathBuf;

/// Arguments of `pingcal demo`.
#[derive(clap::Args)]
#[command(allow_negative_numbers = true)]
pub struct Args {
    /// Folder for the simulated project and the results (default: a folder in the system's
    /// temporary directory, replaced on every run).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Seed of the simulation and of every random choice.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// No progress bars and no step log.
    #[arg(long)]
    pub quiet: bool,
}

/// Runs the command.
pub fn run(args: Args) -> CmdResult {
    let t0 = std::time::Instant::now();
    let out = match &args.out {
        Some(o) => o.clone(),
        None => {
            let d = std::env::temp_dir().join(format!("pingcal-demo-seed{}", args.seed));
            if d.exists() {
                std::fs::remove_dir_all(&d)
                    .map_err(|e| format!("{}: cannot replace: {e}", d.display()))?;
            }
            d
        }
    };
    let multi = (!args.quiet).then(MultiProgress::new);
    let rep = match &multi {
        Some(m) => reporter(Some(m), ""),
        None => super::progress::quiet_reporter(""),
    };
    rep.log(format!(
        "demo: simulating the paper's test field (seed {}) into {}",
        args.seed,
        out.display()
    ));
    let cfg = pingcal_sim::SimConfig::default();
    let (summary, _, [t_scene, t_write]) =
        pingcal_sim::place::simulate_into(&out, &cfg, args.seed, None)?;
    let t_sim = t0.elapsed().as_secs_f64();
    rep.log(format!(
        "demo: {} images, {} LRF scans, {} targets ({} coded), {} balls simulated in {t_sim:.1} s (scene and LRF sweep {t_scene:.1} s, rendering and writing {t_write:.1} s)",
        summary.images, summary.scans, summary.targets, summary.coded, summary.balls
    ));
    let opts = pipeline::Options {
        seed: args.seed,
        ..pipeline::Options::default()
    };
    let project = out.join("project.toml");
    let results_dir = out.join("results");
    std::fs::create_dir_all(&results_dir)
        .map_err(|e| format!("{}: cannot create: {e}", results_dir.display()))?;
    let lock = super::result_set::FolderLock::take(&results_dir)?;
    let outcome = calibrate_one(&project, &opts, &rep)?;
    write_outputs(&lock, &outcome)?;
    let truth = pingcal_sim::read_truth(&out.join("truth.json"))?;
    let t_all = t0.elapsed().as_secs_f64();
    print!("{}", pingcal_plan::against_truth(&outcome.results, &truth));
    println!(
        "demo: simulated in {t_sim:.1} s, calibrated in {:.1} s; report {}",
        t_all - t_sim,
        results_dir.join("report.html").display()
    );
    Ok(())
}
