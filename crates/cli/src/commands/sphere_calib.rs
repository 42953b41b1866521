//! `pingcal sphere-calib PROJECT.toml [--out DIR] [--overwrite] [--seed N] [--quiet]`: the
//! extrinsic of a camera against any lidar from one large sphere moved between N frames
//! ([`pingcal_pipeline::sphere_calib`], docs/sphere-calib.md).
//!
//! Writes `results.json`, `report.html`, `overlays/`, `ros/`, `opencv/` and `kalibr/` into DIR
//! (default `results/` beside the project) as calibrate writes its set: all or none, swapped
//! in at once under the folder's lock ([`super::result_set::write_outputs`]). An existing
//! `results.json` is never replaced unless `--overwrite` is given: without it the run stops
//! before any work.
//!
//! Exit codes as `pingcal calibrate`'s: 0 when the verdict is ok, 3
//! ([`super::calibrate::EXIT_DOUBTFUL`]) when it is doubtful (results written; read the
//! reasons), unless `--accept-doubtful`; 1 on an error (no results).

use super::preflight::check_out_dir;
use super::result_set::write_outputs;
use super::result_set::FolderLock;
use super::{CmdResult, Exit};
use pingcal_pipeline::sphere_calib::{calibrate, outputs::outputs, results_json, sd, Outcome};
use pingcal_pipeline::verdict::Status;
use std::path::{Path, PathBuf};

/// The exit codes, as `pingcal sphere-calib --help` prints them after the options.
const EXIT_CODES_HELP: &str = "\
Exit codes:
  0  the verdict is ok (or doubtful, with --accept-doubtful)
  3  the verdict is doubtful: results written, read the reasons
  1  the project could not be calibrated (bad input): no results
  2  usage error (an unknown option, a missing argument)";

/// Arguments of `pingcal sphere-calib`.
#[derive(clap::Args)]
#[command(after_help = EXIT_CODES_HELP)]
pub struct Args {
    /// The sphere-calib project file (docs/sphere-calib.md).
    pub project: PathBuf,
    /// Output folder (default: `results/` beside the project file).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Replace an earlier run's results in the output folder (without it they are kept and
    /// the run stops before any work).
    #[arg(long)]
    pub overwrite: bool,
    /// Seed of the random choices (the sphere finder's, the consensus').
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Only the one-line summary.
    #[arg(long)]
    pub quiet: bool,
    /// Exit 0 on a doubtful verdict (default: 3, as `pingcal calibrate`).
    #[arg(long)]
    pub accept_doubtful: bool,
}

/// The output folder of a run.
fn out_dir(args: &Args) -> PathBuf {
    match &args.out {
        Some(d) => d.clone(),
        None => args
            .project
            .parent()
            .unwrap_or(Path::new("."))
            .join("results"),
    }
}

/// One line per frame.
fn print_frames(o: &Outcome) {
    println!("frame   lidar centre (mm) ± σ                       camera centre (mm) ± σ                      outline   residual  leave-one-out");
    for f in &o.frames {
        match (&f.skipped, &f.lidar, &f.image) {
            (None, Some(l), Some(s)) => {
                let (sl, sc) = (sd(&l.cov), sd(&s.cov));
                let res = o.evaluation.control.rows.iter().find(|x| x.id == f.id);
                let loo = o
                    .evaluation
                    .leave_one_out
                    .rows
                    .iter()
                    .find(|x| x.id == f.id);
                println!(
                    "{:<6} ({:8.1} {:8.1} {:8.1}) ± ({:4.1} {:4.1} {:4.1})  ({:8.1} {:8.1} {:8.1}) ± ({:4.1} {:4.1} {:4.1})  {:5.0} %  {:6.1} mm  {:>6} mm",
                    f.id, l.centre.x, l.centre.y, l.centre.z, sl[0], sl[1], sl[2],
                    s.centre.x, s.centre.y, s.centre.z, sc[0], sc[1], sc[2],
                    100.0 * s.coverage,
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
    if let Some(cf) = &o.closed_form {
        let r = &cf.registration.camera_from_lrf;
        let (ct, ce) = (r.translation, r.opk_deg());
        println!(
            "closed form (Tóth et al., unweighted): t = ({:.1}, {:.1}, {:.1}) mm, ω φ κ = ({:.3}, {:.3}, {:.3})°; mean leave-one-out error {:.1} mm",
            ct.x, ct.y, ct.z, ce[0], ce[1], ce[2], cf.leave_one_out.mean_mm
        );
    }
}

/// Runs the command.
pub fn run(args: Args) -> CmdResult {
    let t0 = std::time::Instant::now();
    let dir = out_dir(&args);
    check_out_dir(&dir)?;
    let lock = FolderLock::take(&dir)?;
    let results = dir.join("results.json");
    if !args.overwrite && std::fs::symlink_metadata(&results).is_ok() {
        return Err(format!(
            "{}: already exists (an earlier run's results are never replaced; --overwrite to replace them, or --out DIR)",
            results.display()
        )
        .into());
    }
    let o = calibrate(&args.project, args.seed)?;
    for f in &o.frames {
        for w in &f.warnings {
            eprintln!("pingcal: warning: {w}");
        }
    }
    let out = outputs(&o);
    let json = serde_json::to_string_pretty(&results_json(&o))? + "\n";
    write_outputs(&lock, &out, &json)?;
    if !args.quiet {
        print_frames(&o);
    }
    let v = &o.verdict;
    for why in &v.reasons {
        eprintln!("pingcal: {}: {why}", v.status.as_str());
    }
    let r = &o.evaluation.registration;
    let (t, st) = (r.camera_from_lrf.translation, r.sigma_translation_mm);
    let (e, se) = (r.camera_from_lrf.opk_deg(), r.sigma_opk_deg);
    let used = o.frames.iter().filter(|f| f.skipped.is_none()).count();
    let sigma0 = match o.sigma_scale {
        Some(k) => format!("σ0 {:.2} (every σ scaled by {k:.2})", o.sensor_sigma0),
        None => format!("σ0 {:.2}", r.sigma0),
    };
    println!(
        "sphere-calib: {}: {} of {} frames; t = ({:.1}, {:.1}, {:.1}) ± ({:.1}, {:.1}, {:.1}) mm, ω φ κ = ({:.3}, {:.3}, {:.3}) ± ({:.3}, {:.3}, {:.3})°; {sigma0}; mean leave-one-out error {:.1} mm; wrote {} in {:.1} s",
        v.status.as_str(),
        used,
        o.frames.len(),
        t.x, t.y, t.z, st.x, st.y, st.z,
        e[0], e[1], e[2], se.x, se.y, se.z,
        o.evaluation.leave_one_out.mean_mm,
        dir.display(),
        t0.elapsed().as_secs_f64()
    );
    if v.status == Status::Doubtful && !args.accept_doubtful {
        return Err(Exit {
            code: super::calibrate::EXIT_DOUBTFUL,
            message: "verdict: doubtful; --accept-doubtful exits 0 on doubtful".into(),
        }
        .into());
    }
    Ok(())
}
