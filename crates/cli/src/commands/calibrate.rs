//! `pingcal calibrate PROJECT.toml... [--out DIR] [--quiet] [--json] [--accept-doubtful]
//! [--seed N]`: the whole pipeline ([`pingcal_pipeline`]) on one or many projects.
//!
//! Each project ends with a line on stdout, in the order given: the summary, starting with
//! the verdict, or with `--json` a JSON object ([`json_line`]) whose `verdict` is that of
//! `results.json` (`ok`, `doubtful`, `failed`) or `error` when the project could not be
//! calibrated. The exit code is the worst project's ([`Fate`]): 0 ok, [`EXIT_DOUBTFUL`],
//! [`EXIT_FAILED`], [`EXIT_ERROR`] (docs/batch.md).
//!
//! Writes `results.json`, `report.html`, `cloud.ply` and the folders `ros/`, `opencv/` and
//! `kalibr/` ([`pingcal_pipeline::exports`]) into DIR (default: `results/` beside
//! the project file; with several projects and `--out`, one sub-folder per project, named
//! after the project's folder, made distinct by [`out_dirs`] when two would collide).
//! Several projects run in parallel. Before any work the output folders are created and
//! probed ([`super::preflight`]). Nothing is written for a project that fails, and the
//! outputs of an earlier run in DIR stay as they were until a run succeeds; then the whole
//! set is swapped in at once ([`super::result_set`]).

use super::preflight::{check_out_dir, check_threads};
use super::progress::reporter;
use super::result_set;
use super::{CmdError, CmdResult, Exit};
use indicatif::MultiProgress;
use pingcal_pipeline::board_lrf::{self, outputs as board_outputs, BoardOutcome};
use pingcal_pipeline::network::Start;
use pingcal_pipeline::result_set::FolderLock;
use pingcal_pipeline::verdict::Status;
use pingcal_pipeline::{self as pipeline, Options, Outcome, Reporter};
use pingcal_project::Project;
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// Exit code of a run whose worst project has a `doubtful` verdict.
pub const EXIT_DOUBTFUL: i32 = 3;
/// Exit code of a run whose worst project has a `failed` verdict (results written, not to be
/// trusted).
pub const EXIT_FAILED: i32 = 4;
/// Exit code of a run with a project that could not be calibrated (no results).
pub const EXIT_ERROR: i32 = 1;

/// The exit codes, as `pingcal calibrate --help` prints them after the options.
const EXIT_CODES_HELP: &str = "\
Exit codes (with several projects the worst one decides, 1 > 4 > 3 > 0):
  0  every project's verdict is ok (or doubtful, with --accept-doubtful)
  3  at least one verdict is doubtful: results written, read the reasons
  4  at least one verdict is failed: results written, not to be trusted
  1  at least one project could not be calibrated (bad input, pipeline error): no results
  2  usage error (an unknown option, a missing argument)";

/// Arguments of `pingcal calibrate`.
#[derive(clap::Args)]
#[command(allow_negative_numbers = true, after_help = EXIT_CODES_HELP)]
pub struct Args {
    /// Project files (project.toml); several run in parallel.
    #[arg(required = true)]
    pub projects: Vec<PathBuf>,
    /// Output folder (one project) or parent of one folder per project (several).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// No progress bars and no step log; the summary line, and on stderr the warnings, the
    /// verdict's reasons and the errors, still print.
    #[arg(long)]
    pub quiet: bool,
    /// Print one JSON object per project on stdout (in the order given) instead of the
    /// summary line: `verdict`, `reasons`, `out`, ... (docs/batch.md).
    #[arg(long)]
    pub json: bool,
    /// Exit 0, not 3, when the worst verdict is `doubtful`.
    #[arg(long)]
    pub accept_doubtful: bool,
    /// Seed of every random choice.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Worker threads of each bundle adjustment (0: all cores).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// How the initial network starts: `auto` tries the layout's resection (when
    /// `[targets] layout` is given), the relative orientation, then the stereo head's nominal
    /// pose, until one works.
    #[arg(long, value_enum, default_value_t = StartArg::Auto)]
    pub start: StartArg,
    /// Measure saturated targets instead of refusing them (a flat render or scan of a target
    /// sheet): flagged, with three times their σ; as `[targets] measure_saturated = true`.
    #[arg(long)]
    pub saturated: bool,
}

/// `--start`: [`Start`] as the command line names it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum StartArg {
    /// Every start the project allows, until one works.
    Auto,
    /// Every image resected from the coded targets' layout (`[targets] layout`).
    Layout,
    /// The relative orientation of the best-conditioned image pair.
    Relative,
    /// One station's stereo pair at the head's nominal pose.
    Stereo,
}

impl From<StartArg> for Start {
    fn from(a: StartArg) -> Start {
        match a {
            StartArg::Auto => Start::Auto,
            StartArg::Layout => Start::Layout,
            StartArg::Relative => Start::Relative,
            StartArg::Stereo => Start::Stereo,
        }
    }
}

pub use pingcal_pipeline::out_folders::{out_dir, out_dirs};

/// Writes the outputs of a calibration into its folder, all or none, under the folder's
/// lock ([`result_set::write_outcome`]).
pub fn write_outputs(lock: &result_set::FolderLock, outcome: &Outcome) -> CmdResult {
    Ok(result_set::write_outcome(lock, outcome)?)
}

/// Loads and calibrates one project.
pub fn calibrate_one(
    path: &Path,
    opts: &pipeline::Options,
    rep: &Reporter,
) -> Result<Outcome, CmdError> {
    let project = Project::load(path)?;
    Ok(pipeline::calibrate(&project, opts, rep)?)
}

/// What became of one project of a run, from best to worst (the order of the exit codes:
/// the worst project of a batch decides).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Fate {
    /// Calibrated, verdict `ok`.
    Ok,
    /// Calibrated, verdict `doubtful`.
    Doubtful,
    /// Calibrated, verdict `failed`: results written, not to be trusted.
    Failed,
    /// Not calibrated (bad input, pipeline error): no results.
    Error,
}

impl Fate {
    /// The fate of a calibration with verdict `status`.
    pub fn of(status: Status) -> Self {
        match status {
            Status::Ok => Fate::Ok,
            Status::Doubtful => Fate::Doubtful,
            Status::Failed => Fate::Failed,
        }
    }

    /// The `verdict` of the JSON line: `ok`, `doubtful`, `failed` or `error`.
    pub fn as_str(self) -> &'static str {
        match self {
            Fate::Ok => "ok",
            Fate::Doubtful => "doubtful",
            Fate::Failed => "failed",
            Fate::Error => "error",
        }
    }

    /// The exit code of a run whose worst project has this fate.
    pub fn exit_code(self, accept_doubtful: bool) -> i32 {
        match self {
            Fate::Ok => 0,
            Fate::Doubtful if accept_doubtful => 0,
            Fate::Doubtful => EXIT_DOUBTFUL,
            Fate::Failed => EXIT_FAILED,
            Fate::Error => EXIT_ERROR,
        }
    }
}

/// One project's end: its fate, its stdout line (summary or JSON) and its stderr lines.
pub(crate) struct Done {
    pub(crate) fate: Fate,
    /// The summary or JSON line (none for a project that errored without `--json`).
    pub(crate) line: Option<String>,
    /// Why it could not be calibrated (fate [`Fate::Error`]).
    pub(crate) error: Option<String>,
    /// What stderr must carry when the step log was not shown: the warnings and the
    /// verdict's reasons, each starting with the project's path.
    pub(crate) stderr: Vec<String>,
}

/// The one-line summary of a finished project: its verdict first.
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
    let verdict = match r.verdict.reasons.len() {
        0 => r.verdict.status.as_str().to_string(),
        n => format!(
            "{} ({n} reason{} in results.json)",
            r.verdict.status.as_str(),
            if n == 1 { "" } else { "s" }
        ),
    };
    // each of [[lrfs]]: its translation, or why it has none (its verdict is in the main one)
    let others: String = (o.range_sensors.iter())
        .map(|x| match &x.outcome {
            Ok(xo) => {
                let t = xo.results.extrinsic.translation_mm;
                format!("; {} t = ({:.1}, {:.1}, {:.1}) mm", x.id, t[0], t[1], t[2])
            }
            Err(_) => format!("; {} not calibrated", x.id),
        })
        .collect();
    format!(
        "calibrate: {}: verdict {verdict}; sigma0 {:.3}, RMS {:.3} px, {} images; mean check error: {}; t = ({:.1}, {:.1}, {:.1}) mm{others}; wrote {} in {:.1} s",
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

/// The JSON line of a calibrated project (docs/batch.md): `ok` and `results_written` say
/// that the run completed and wrote its results, `verdict` whether to trust them.
pub fn json_line(path: &Path, dir: &Path, o: &Outcome, secs: f64) -> String {
    let r = &o.results;
    serde_json::json!({
        "project": path.display().to_string(),
        "verdict": r.verdict.status.as_str(),
        "reasons": r.verdict.reasons,
        "ok": true,
        "results_written": true,
        "out": dir.display().to_string(),
        "mean_check_error_mm": r.mean_check_error_mm,
        "methods": r.methods.iter().map(|m| serde_json::json!({
            "method": m.method,
            "mean_check_error_mm": m.mean_check_error_mm,
            "error": m.error,
        })).collect::<Vec<_>>(),
        "translation_mm": r.extrinsic.translation_mm,
        "sigma_translation_mm": r.extrinsic.sigma_translation_mm,
        "sigma0": r.bundle.sigma0,
        "range_sensors": o.range_sensors.iter().map(|x| match &x.outcome {
            Ok(xo) => serde_json::json!({
                "id": x.id,
                "kind": x.kind,
                "verdict": xo.results.verdict.status.as_str(),
                "translation_mm": xo.results.extrinsic.translation_mm,
                "sigma_translation_mm": xo.results.extrinsic.sigma_translation_mm,
                "error": null,
            }),
            Err(e) => serde_json::json!({
                "id": x.id,
                "kind": x.kind,
                "verdict": "error",
                "translation_mm": null,
                "sigma_translation_mm": null,
                "error": e,
            }),
        }).collect::<Vec<_>>(),
        "time_s": secs,
    })
    .to_string()
}

/// The JSON line of a project that could not be calibrated: `verdict` `error`, the message
/// in `error` (and as the one reason) and its kind in `error_kind` (the pipeline's, `input`
/// for a project file that does not load, `output` for results that could not be written:
/// docs/batch.md), nothing written into `out`.
pub(crate) fn error_json_line(
    path: &Path,
    dir: &Path,
    (kind, e): (&str, &str),
    secs: f64,
) -> String {
    serde_json::json!({
        "project": path.display().to_string(),
        "verdict": Fate::Error.as_str(),
        "reasons": [e],
        "error": e,
        "error_kind": kind,
        "ok": false,
        "results_written": false,
        "out": dir.display().to_string(),
        "time_s": secs,
    })
    .to_string()
}

/// The warnings of the step log of the project at `path`, each naming it, for stderr.
pub(crate) fn warnings(path: &Path, rep: &Reporter) -> Vec<String> {
    (rep.lines().iter())
        .filter(|l| l.starts_with("warning: "))
        .map(|w| format!("{}: {w}", path.display()))
        .collect()
}

/// Calibrates one project of the run into `dir` and says how it ended. `shown`: the step log
/// (with its warnings and verdict line) went to stderr already.
fn calibrate_project(
    path: &Path,
    lock: &result_set::FolderLock,
    args: &Args,
    opts: &pipeline::Options,
    rep: &Reporter,
    shown: bool,
) -> Done {
    let t0 = std::time::Instant::now();
    let dir = lock.dir();
    // a board project (`[board]`) takes the board's calibration
    if let Ok(project) = Project::load(path).map(Box::new) {
        if project.file.board.is_some() {
            let how = How {
                json: args.json,
                shown,
                t0,
            };
            return calibrate_board(&project, lock, opts, rep, how);
        }
    }
    let r = match calibrate_one(path, opts, rep) {
        Ok(o) => match write_outputs(lock, &o) {
            Ok(()) => Ok(o),
            Err(e) => Err(("output", e.to_string())),
        },
        // the pipeline's kind of error; a project file that does not load is an input's
        Err(CmdError::Pipeline(e)) => Err((e.kind(), e.to_string())),
        Err(e) => Err(("input", e.to_string())),
    };
    let secs = t0.elapsed().as_secs_f64();
    let o = match r {
        Ok(o) => o,
        Err((kind, e)) => {
            return Done::error((path, dir), (kind, e), secs, (args.json, shown), rep)
        }
    };
    let line = match args.json {
        true => json_line(path, dir, &o, secs),
        false => summary_line(path, dir, &o, secs),
    };
    Done::calibrated(path, &o.results.verdict, line, shown, rep)
}

impl Done {
    /// A project not calibrated (`kind` of error `e`, a note added when `dir` holds an
    /// earlier run's results), its JSON line with `json`; the warnings logged before the
    /// failure (ranges masked, files beside the project's) often say why: a run that did not
    /// show the log (`shown`) gives them too.
    fn error(
        (path, dir): (&Path, &Path),
        (kind, e): (&str, String),
        secs: f64,
        (json, shown): (bool, bool),
        rep: &Reporter,
    ) -> Done {
        let e = kept_note(e, dir);
        Done {
            fate: Fate::Error,
            line: json.then(|| error_json_line(path, dir, (kind, &e), secs)),
            error: Some(e),
            stderr: match shown {
                true => Vec::new(),
                false => warnings(path, rep),
            },
        }
    }

    /// A calibrated project of verdict `v` and stdout `line`; a run that did not show the
    /// log (`shown`) gives the warnings and the verdict's reasons on stderr.
    fn calibrated(
        path: &Path,
        v: &pipeline::verdict::Verdict,
        line: String,
        shown: bool,
        rep: &Reporter,
    ) -> Done {
        let mut stderr = Vec::new();
        if !shown {
            let name = path.display();
            stderr.extend(warnings(path, rep));
            for why in &v.reasons {
                stderr.push(format!("{name}: {}: {why}", v.status.as_str()));
            }
        }
        Done {
            fate: Fate::of(v.status),
            line: Some(line),
            error: None,
            stderr,
        }
    }
}

// A board project (`[board]`, issue 51, [`pingcal_pipeline::board_lrf`]): the camera and
// the fixed LRF from one board in several placements; its outputs written as one set under
// the folder's lock, as the room's.

/// How the run shows a project's end.
#[derive(Clone, Copy, Debug)]
struct How {
    /// `--json`: a JSON line per project.
    json: bool,
    /// The step log went to stderr already.
    shown: bool,
    /// When the project's run began.
    t0: std::time::Instant,
}

/// Writes the board project's outputs into the locked folder, all or none.
fn write_board(lock: &FolderLock, o: &BoardOutcome) -> Result<(), String> {
    let out = board_outputs::outputs(o);
    let json = serde_json::to_string_pretty(&board_outputs::results_json(o))
        .map_err(|e| e.to_string())?
        + "\n";
    result_set::write_outputs(lock, &out, &json).map_err(|e| e.to_string())
}

/// The one-line summary of a calibrated board project.
fn board_summary_line(path: &Path, dir: &Path, o: &BoardOutcome, secs: f64) -> String {
    let (t, st) = (o.camera_from_lrf.translation, o.sigma_translation_mm);
    let scale = match o.adjustment.board_scale() {
        Some((s, sd)) => format!("; board scale {s:.4} ± {sd:.4}"),
        None => String::new(),
    };
    format!(
        "calibrate: {}: verdict {}; board in {} of {} photographs, its beams in {} scans; t = ({:.1}, {:.1}, {:.1}) ± ({:.1}, {:.1}, {:.1}) mm{scale}; wrote {} in {:.1} s",
        path.display(),
        o.verdict.status.as_str(),
        o.views.len(),
        o.placements.len(),
        o.adjustment.on_board.iter().filter(|b| !b.is_empty()).count(),
        t.x,
        t.y,
        t.z,
        st[0],
        st[1],
        st[2],
        dir.display(),
        secs
    )
}

/// The JSON line of a calibrated board project (docs/batch.md's keys).
fn board_json_line(path: &Path, dir: &Path, o: &BoardOutcome, secs: f64) -> String {
    let t = o.camera_from_lrf.translation;
    serde_json::json!({
        "project": path.display().to_string(),
        "verdict": o.verdict.status.as_str(),
        "reasons": o.verdict.reasons,
        "ok": true,
        "results_written": true,
        "out": dir.display().to_string(),
        "translation_mm": [t.x, t.y, t.z],
        "sigma_translation_mm": o.sigma_translation_mm,
        "sigma0": o.adjustment.precision.sigma0,
        "board_scale": o.adjustment.board_scale().map(|s| s.0),
        "time_s": secs,
    })
    .to_string()
}

/// Calibrates the board project into the locked folder and says how it ended.
fn calibrate_board(
    project: &Project,
    lock: &FolderLock,
    opts: &Options,
    rep: &Reporter,
    how: How,
) -> Done {
    let (path, dir) = (project.path.as_path(), lock.dir());
    let r = match board_lrf::calibrate_board(project, opts, rep) {
        Ok(o) => write_board(lock, &o).map(|()| o).map_err(|e| ("output", e)),
        Err(e) => Err((e.kind(), e.to_string())),
    };
    let secs = how.t0.elapsed().as_secs_f64();
    let o = match r {
        Ok(o) => o,
        Err((kind, e)) => {
            return Done::error((path, dir), (kind, e), secs, (how.json, how.shown), rep)
        }
    };
    let line = match how.json {
        true => board_json_line(path, dir, &o, secs),
        false => board_summary_line(path, dir, &o, secs),
    };
    Done::calibrated(path, &o.verdict, line, how.shown, rep)
}

/// Runs the command.
pub fn run(args: Args) -> CmdResult {
    let several = args.projects.len() > 1;
    check_threads(args.threads)?;
    let dirs = out_dirs(&args.projects, args.out.as_deref())?;
    for d in &dirs {
        check_out_dir(d)?;
    }
    let locks = (dirs.iter())
        .map(|d| result_set::FolderLock::take(d))
        .collect::<Result<Vec<_>, _>>()?;
    let multi = (!args.quiet && !args.json).then(MultiProgress::new);
    let opts = pipeline::Options {
        seed: args.seed,
        threads: args.threads,
        start: args.start.into(),
        measure_saturated: args.saturated,
        ..pipeline::Options::default()
    };
    let done: Vec<Done> = args
        .projects
        .par_iter()
        .zip(&locks)
        .map(|(path, lock)| {
            let prefix = match several {
                true => format!("[{}] ", path.display()),
                false => String::new(),
            };
            let rep = reporter(multi.as_ref(), prefix);
            calibrate_project(path, lock, &args, &opts, &rep, multi.is_some())
        })
        .collect();
    finish(&done, args.accept_doubtful)
}

/// Prints every project's line (stdout) and its stderr lines, in the order given, and ends
/// the run with the exit code of the worst project.
fn finish(done: &[Done], accept_doubtful: bool) -> CmdResult {
    let mut errors = Vec::new();
    for d in done {
        if let Some(line) = &d.line {
            println!("{line}");
        }
        for l in &d.stderr {
            eprintln!("pingcal: {l}");
        }
        errors.extend(d.error.clone());
    }
    let worst = done.iter().map(|d| d.fate).max().unwrap_or(Fate::Ok);
    let count = |f: Fate| done.iter().filter(|d| d.fate == f).count();
    match worst {
        Fate::Error if done.len() == 1 => Err(errors.remove(0).into()),
        Fate::Error => {
            for e in &errors {
                eprintln!("pingcal: error: {e}");
            }
            Err(format!(
                "{} of {} projects could not be calibrated",
                errors.len(),
                done.len()
            )
            .into())
        }
        Fate::Ok => Ok(()),
        _ if worst.exit_code(accept_doubtful) == 0 => Ok(()),
        _ => {
            let (failed, doubtful) = (count(Fate::Failed), count(Fate::Doubtful));
            let mut parts = Vec::new();
            if failed > 0 {
                parts.push(format!("{failed} failed"));
            }
            if doubtful > 0 {
                parts.push(format!("{doubtful} doubtful"));
            }
            let message = format!(
                "verdict: {} of {} project{}{}",
                parts.join(", "),
                done.len(),
                if done.len() == 1 { "" } else { "s" },
                match worst {
                    Fate::Doubtful => "; --accept-doubtful exits 0 on doubtful",
                    _ => "",
                }
            );
            Err(Exit {
                code: worst.exit_code(accept_doubtful),
                message,
            }
            .into())
        }
    }
}

/// A failure's message, with a note when `dir` holds the results of an earlier run (left
/// as they were: they are not this run's).
pub(crate) fn kept_note(e: String, dir: &Path) -> String {
    if dir.join("results.json").is_file() {
        format!(
            "{e} (the earlier results in {} are left as they were)",
            dir.display()
        )
    } else {
        e
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The worst project decides (not calibrated > failed > doubtful > ok), and
    /// `--accept-doubtful` changes only a doubtful worst.
    #[test]
    fn the_worst_fate_gives_the_exit_code() {
        use Fate::*;
        let worst = |fates: &[Fate]| fates.iter().copied().max().expect("a project");
        for (fates, code, accepted) in [
            (&[Ok, Ok][..], 0, 0),
            (&[Ok, Doubtful, Ok][..], 3, 0),
            (&[Doubtful, Failed, Ok][..], 4, 4),
            (&[Failed, Error, Doubtful][..], 1, 1),
            (&[Error][..], 1, 1),
        ] {
            assert_eq!(worst(fates).exit_code(false), code, "{fates:?}");
            assert_eq!(worst(fates).exit_code(true), accepted, "{fates:?}");
        }
        assert_eq!(Fate::of(Status::Doubtful), Doubtful);
        assert_eq!(
            [Ok, Doubtful, Failed, Error].map(Fate::as_str),
            ["ok", "doubtful", "failed", "error"]
        );
    }
}
