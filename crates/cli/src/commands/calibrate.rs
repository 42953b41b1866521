//! `pingcal calibrate PROJECT.toml... [--out DIR] [--quiet] [--json] [--seed N]`: the whole
//! pipeline ([`crate::pipeline`]) on one or many projects.
//!
//! Writes `results.json`, `report.html` and `cloud.ply` into DIR (default: `results/` beside
//! the project file; with several projects and `--out`, one sub-folder per project, named
//! after the project's folder). Several projects run in parallel. Nothing is written for a
//! project that fails, and the outputs of an earlier run in DIR are removed first; each
//! output file is written atomically, `results.json` last.

use super::progress::reporter;
use super::{write_atomic, CmdResult};
use crate::pipeline::{self, Outcome, Reporter};
use indicatif::MultiProgress;
use pingcal_project::Project;
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// Arguments of `pingcal calibrate`.
#[derive(clap::Args)]
pub struct Args {
    /// Project files (project.toml); several run in parallel.
    #[arg(required = true)]
    pub projects: Vec<PathBuf>,
    /// Output folder (one project) or parent of one folder per project (several).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// No progress bars and no step log; only the summary line (and errors).
    #[arg(long)]
    pub quiet: bool,
    /// Print one JSON object per project on stdout instead of the summary line.
    #[arg(long)]
    pub json: bool,
    /// Seed of every random choice.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Worker threads of each bundle adjustment (0: all cores).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
}

/// Where a project's outputs go.
pub fn out_dir(project: &Path, out: Option<&Path>, several: bool) -> PathBuf {
    let dir = project
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    match out {
        None => dir.join("results"),
        Some(o) if !several => o.to_path_buf(),
        Some(o) => {
            let name = std::fs::canonicalize(dir)
                .ok()
                .and_then(|d| d.file_name().map(|n| n.to_string_lossy().into_owned()))
                .unwrap_or_else(|| "project".into());
            o.join(name)
        }
    }
}

/// The files a calibration writes into its output folder.
pub const OUTPUTS: [&str; 3] = ["results.json", "report.html", "cloud.ply"];

/// Removes the outputs of an earlier run from `dir`, so that a run that fails never leaves
/// older results looking like its own.
pub fn clear_outputs(dir: &Path) -> Result<(), String> {
    for name in OUTPUTS {
        let p = dir.join(name);
        if p.exists() {
            std::fs::remove_file(&p)
                .map_err(|e| format!("{}: cannot remove the earlier result: {e}", p.display()))?;
        }
    }
    Ok(())
}

/// Writes the three outputs of a calibration into `dir`.
pub fn write_outputs(dir: &Path, outcome: &Outcome) -> CmdResult {
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: cannot create: {e}", dir.display()))?;
    let json = serde_json::to_string_pretty(&outcome.results)? + "\n";
    write_atomic(&dir.join("cloud.ply"), &outcome.cloud_ply)?;
    write_atomic(
        &dir.join("report.html"),
        pingcal_report::render_html(&outcome.report).as_bytes(),
    )?;
    // results.json last: its presence means the run finished
    write_atomic(&dir.join("results.json"), json.as_bytes())?;
    Ok(())
}

/// Loads and calibrates one project.
pub fn calibrate_one(
    path: &Path,
    opts: &pipeline::Options,
    rep: &Reporter,
) -> Result<Outcome, String> {
    let project = Project::load(path).map_err(|e| e.to_string())?;
    pipeline::calibrate(&project, opts, rep).map_err(|e| e.to_string())
}

/// The one-line summary of a finished project.
pub fn summary_line(path: &Path, dir: &Path, o: &Outcome, secs: f64) -> String {
    let r = &o.results;
    let mut methods = Vec::new();
    for m in &r.methods {
        match (m.mean_check_error_mm, &m.error) {
            (Some(e), _) => methods.push(format!(
                "{} {:.2} mm on {} {}",
                m.method,
                e,
                m.check_points.len(),
                match m.check_points_source.as_str() {
                    "leave_one_out" => "balls left out one at a time",
                    "all_balls" => "balls",
                    _ => "check balls",
                }
            )),
            (None, Some(_)) => methods.push(format!("{} failed", m.method)),
            _ => {}
        }
    }
    format!(
        "calibrate: {}: sigma0 {:.3}, RMS {:.3} px, {} images; mean check error: {}; t = ({:.1}, {:.1}, {:.1}) mm; wrote {} in {:.1} s",
        path.display(),
        r.bundle.sigma0,
        r.bundle.rms_image_px,
        r.bundle.images,
        methods.join(", "),
        r.extrinsic.translation_mm[0],
        r.extrinsic.translation_mm[1],
        r.extrinsic.translation_mm[2],
        dir.display(),
        secs
    )
}

/// Runs the command.
pub fn run(args: Args) -> CmdResult {
    let several = args.projects.len() > 1;
    let multi = (!args.quiet && !args.json).then(MultiProgress::new);
    let opts = pipeline::Options {
        seed: args.seed,
        threads: args.threads,
        ..pipeline::Options::default()
    };
    let results: Vec<(PathBuf, Result<String, String>)> = args
        .projects
        .par_iter()
        .map(|path| {
            let t0 = std::time::Instant::now();
            let prefix = if several {
                format!("[{}] ", path.display())
            } else {
                String::new()
            };
            let rep = reporter(multi.as_ref(), prefix);
            let dir = out_dir(path, args.out.as_deref(), several);
            let r = clear_outputs(&dir)
                .and_then(|_| calibrate_one(path, &opts, &rep))
                .and_then(|o| {
                    write_outputs(&dir, &o).map_err(|e| e.to_string())?;
                    let secs = t0.elapsed().as_secs_f64();
                    Ok(if args.json {
                        serde_json::json!({
                            "project": path.display().to_string(),
                            "ok": true,
                            "out": dir.display().to_string(),
                            "mean_check_error_mm": o.results.mean_check_error_mm,
                            "methods": o.results.methods.iter().map(|m| serde_json::json!({
                                "method": m.method,
                                "mean_check_error_mm": m.mean_check_error_mm,
                                "error": m.error,
                            })).collect::<Vec<_>>(),
                            "translation_mm": o.results.extrinsic.translation_mm,
                            "sigma_translation_mm": o.results.extrinsic.sigma_translation_mm,
                            "sigma0": o.results.bundle.sigma0,
                            "time_s": secs,
                        })
                        .to_string()
                    } else {
                        summary_line(path, &dir, &o, secs)
                    })
                });
            (path.clone(), r)
        })
        .collect();
    let mut failed = Vec::new();
    for (path, r) in &results {
        match r {
            Ok(line) => println!("{line}"),
            Err(e) => {
                if args.json {
                    println!(
                        "{}",
                        serde_json::json!({"project": path.display().to_string(), "ok": false, "error": e})
                    );
                }
                failed.push(e.clone());
            }
        }
    }
    match failed.len() {
        0 => Ok(()),
        1 if !several => Err(failed.remove(0).into()),
        n => {
            for e in &failed {
                eprintln!("pingcal: error: {e}");
            }
            Err(format!("{n} of {} projects failed", results.len()).into())
        }
    }
}
