//! `pingcal plan [--config simulation.toml] [--seeds N] [--seed BASE] [--out plan.json]`:
//! pre-analysis of a planned field (issue 18): the study is [`pingcal_plan::study`]; this
//! command reads the options, shows the progress, prints [`pingcal_plan::table`] and
//! writes `plan.json` (only when the plan finished; times are printed, not written).

use super::preflight::{check_out_file, check_threads};
use super::progress::reporter;
use super::CmdResult;
use indicatif::MultiProgress;
use pingcal_plan::PlanSpec;
use std::path::PathBuf;

/// Arguments of `pingcal plan`.
#[derive(clap::Args)]
#[command(allow_negative_numbers = true)]
pub struct Args {
    /// The planned field: a simulator configuration (TOML, as `pingcal simulate --config`;
    /// keys not given keep the paper's defaults). Default: the paper's field.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Simulations (each simulated and calibrated) of the plan.
    #[arg(long, default_value_t = 5)]
    pub seeds: u64,
    /// Seed of the first simulation (the others follow: BASE, BASE+1, ...).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// How many of the seeds (the first ones) each removal is calibrated with.
    #[arg(long, default_value_t = 1)]
    pub sensitivity_seeds: u64,
    /// No "remove each and see" (only the predicted σ's and the Monte Carlo spread).
    #[arg(long)]
    pub no_sensitivity: bool,
    /// Write the plan's numbers as JSON into this file (written only when the plan finished).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Worker threads (0: all cores).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
    /// Write the whole configuration (every key, the defaults filled in) into this file and
    /// stop: a `simulation.toml` to edit into your plan. An existing file is not replaced.
    #[arg(long)]
    pub write_config: Option<PathBuf>,
    /// The head's lenses, as `pingcal simulate --camera-model`: a camera model's name (a
    /// 120° wide-angle lens, 190° fisheyes); replaces `[camera]` of `--config` with that
    /// lens's defaults (docs/formats.md, "Camera models").
    #[arg(long)]
    pub camera_model: Option<String>,
}

/// Runs the command.
pub fn run(args: Args) -> CmdResult {
    let t0 = std::time::Instant::now();
    check_threads(args.threads)?;
    let cfg = match &args.config {
        Some(p) => pingcal_sim::SimConfig::from_toml_file(p)?,
        None => pingcal_sim::SimConfig::default(),
    };
    let cfg = super::simulate::with_camera_model(cfg, args.camera_model.as_deref())?;
    if let Some(path) = &args.write_config {
        check_out_file("--write-config", path)?;
        if path.exists() {
            return Err(format!(
                "--write-config {}: already exists (not replaced: remove it or choose another name)",
                path.display()
            )
            .into());
        }
        super::write_atomic(path, cfg.to_toml_string().as_bytes())?;
        println!("plan: wrote the configuration into {}", path.display());
        return Ok(());
    }
    if args.seeds == 0 {
        return Err("--seeds 0: expected at least 1 (each seed is one simulated calibration; 2 or more for the Monte Carlo spread)".into());
    }
    if let Some(out) = &args.out {
        check_out_file("--out", out)?;
    }
    let seeds: Vec<u64> = (0..args.seeds)
        .map(|k| args.seed.checked_add(k))
        .collect::<Option<_>>()
        .ok_or_else(|| {
            format!(
                "--seed {} --seeds {}: the last seed would pass {}",
                args.seed,
                args.seeds,
                u64::MAX
            )
        })?;
    let sensitivity_seeds = if args.no_sensitivity {
        Vec::new()
    } else {
        seeds
            .iter()
            .copied()
            .take(args.sensitivity_seeds as usize)
            .collect()
    };
    let spec = PlanSpec {
        config: cfg,
        config_file: args.config.clone(),
        seeds,
        sensitivity_seeds,
        threads: args.threads,
    };
    let multi = (!args.quiet).then(MultiProgress::new);
    let rep = reporter(multi.as_ref(), "plan: ");
    let plan = pingcal_plan::study(&spec, &rep)?;
    drop(rep);
    drop(multi);
    print!("{}", pingcal_plan::table(&plan));
    if let Some(out) = &args.out {
        let json = serde_json::to_string_pretty(&plan)? + "\n";
        super::write_atomic(out, json.as_bytes())?;
        println!("plan: wrote {}", out.display());
    }
    let removals = plan.sensitivity.len() * plan.sensitivity_seeds.len();
    println!(
        "plan: {} calibration(s) in {:.1} s",
        plan.seeds.len() + removals,
        t0.elapsed().as_secs_f64()
    );
    Ok(())
}
