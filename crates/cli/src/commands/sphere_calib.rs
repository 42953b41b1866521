//! `pingcal sphere-calib PROJECT.toml [--out DIR] [--overwrite] [--seed N] [--quiet]`: the
//! extrinsic of a camera against any lidar from one large sphere moved between N frames
//! ([`pingcal_pipeline::sphere_calib`], docs/sphere-calib.md).
//!
//! `results.json` goes to `DIR` (default `results/` beside the project), written
//! atomically; an existing `results.json` is never replaced unless `--overwrite` is given.

use super::CmdResult;
use pingcal_pipeline::sphere_calib::{calibrate, results_json, sd};
use std::path::{Path, PathBuf};

/// Arguments of `pingcal sphere-calib`.
#[derive(clap::Args)]
pub struct Args {
    /// The sphere-calib project file (docs/sphere-calib.md).
    pub project: PathBuf,
    /// Output folder for results.json (default: `results/` beside the project file).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Replace an existing results.json (without it an earlier run's file is kept and the
    /// run stops before any work).
    #[arg(long)]
    pub overwrite: bool,
    /// Seed of the sphere finder's random choices.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Only the one-line summary.
    #[arg(long)]
    pub quiet: bool,
}

/// The results file of a run into `dir`.
fn results_path(args: &Args) -> PathBuf {
    match &args.out {
        Some(d) => d.join("results.json"),
        None => args
            .project
            .parent()
            .unwrap_or(Path::new("."))
            .join("results")
            .join("results.json"),
    }
}

/// Runs the command.
pub fn run(args: Args) -> CmdResult {
    let t0 = std::time::Instant::now();
    let out = results_path(&args);
    if !args.overwrite && std::fs::symlink_metadata(&out).is_ok() {
        return Err(format!(
            "{}: already exists (an earlier run's results are never replaced; --overwrite to replace it, or --out DIR)",
            out.display()
        )
        .into());
    }
    let dir = out.parent().unwrap_or(Path::new("."));
    if dir.exists() && !dir.is_dir() {
        return Err(format!("{}: not a folder", dir.display()).into());
    }
    let o = calibrate(&args.project, args.seed)?;
    for f in &o.frames {
        for w in &f.warnings {
            eprintln!("pingcal: warning: {w}");
        }
    }
    let text = serde_json::to_string_pretty(&results_json(&o))? + "\n";
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: cannot create: {e}", dir.display()))?;
    super::write_atomic(&out, text.as_bytes())?;
    let r = &o.evaluation.registration;
    let t = r.camera_from_lrf.translation;
    let st = r.sigma_translation_mm;
    let e = r.camera_from_lrf.opk_deg();
    let se = r.sigma_opk_deg;
    let used = o.frames.iter().filter(|f| f.skipped.is_none()).count();
    if !args.quiet {
        println!("frame   lidar centre (mm) ± σ                       camera centre (mm) ± σ                      residual  leave-one-out");
        for f in &o.frames {
            match (&f.skipped, f.lidar, &f.image) {
                (None, Some((c, cov, _, _)), Some(s)) => {
                    let (sl, sc) = (sd(&cov), sd(&s.cov));
                    let res = o.evaluation.control.rows.iter().find(|x| x.id == f.id);
                    let loo = o
                        .evaluation
                        .leave_one_out
                        .rows
                        .iter()
                        .find(|x| x.id == f.id);
                    println!(
                        "{:<6} ({:8.1} {:8.1} {:8.1}) ± ({:4.1} {:4.1} {:4.1})  ({:8.1} {:8.1} {:8.1}) ± ({:4.1} {:4.1} {:4.1})  {:6.1} mm  {:>6} mm",
                        f.id, c.x, c.y, c.z, sl[0], sl[1], sl[2],
                        s.centre.x, s.centre.y, s.centre.z, sc[0], sc[1], sc[2],
                        res.map_or(f64::NAN, |x| x.error_mm),
                        loo.map_or("-".into(), |x| format!("{:.1}", x.error_mm)),
                    );
                }
                (skip, _, _) => println!(
                    "{:<6} not used: {}",
                    f.id,
                    skip.as_deref().unwrap_or("incomplete")
                ),
            }
        }
        let cf = &o.closed_form.registration;
        let ct = cf.camera_from_lrf.translation;
        let ce = cf.camera_from_lrf.opk_deg();
        println!(
            "closed form (Tóth et al., unweighted): t = ({:.1}, {:.1}, {:.1}) mm, ω φ κ = ({:.3}, {:.3}, {:.3})°; mean leave-one-out error {:.1} mm",
            ct.x, ct.y, ct.z, ce[0], ce[1], ce[2], o.closed_form.leave_one_out.mean_mm
        );
    }
    println!(
        "sphere-calib: {} of {} frames; t = ({:.1}, {:.1}, {:.1}) ± ({:.1}, {:.1}, {:.1}) mm, ω φ κ = ({:.3}, {:.3}, {:.3}) ± ({:.3}, {:.3}, {:.3})°; σ0 {:.2}; mean leave-one-out error {:.1} mm; wrote {} in {:.1} s",
        used,
        o.frames.len(),
        t.x, t.y, t.z, st.x, st.y, st.z,
        e[0], e[1], e[2], se.x, se.y, se.z,
        r.sigma0,
        o.evaluation.leave_one_out.mean_mm,
        out.display(),
        t0.elapsed().as_secs_f64()
    );
    Ok(())
}
