//! `pingcal calibrate` of a board project (`[board]`, issue 51,
//! [`pingcal_pipeline::board_lrf`]): the camera and the fixed LRF from one board in several
//! placements; `results.json`, the overlays, the report and the exports written as one set
//! under the folder's lock, as for the room.

use super::calibrate::{error_json_line, kept_note, warnings, Done, Fate};
use pingcal_pipeline::board_lrf::{self, outputs, BoardOutcome};
use pingcal_pipeline::result_set::{write_set, FolderLock, SetFile};
use pingcal_pipeline::{Options, Reporter};
use pingcal_project::Project;
use std::path::{Path, PathBuf};

/// How the run shows a project's end.
#[derive(Clone, Copy, Debug)]
pub struct How {
    /// `--json`: a JSON line per project.
    pub json: bool,
    /// The step log went to stderr already.
    pub shown: bool,
    /// When the project's run began.
    pub t0: std::time::Instant,
}

/// Writes the board project's outputs into the locked folder, all or none.
fn write(lock: &FolderLock, o: &BoardOutcome) -> Result<(), String> {
    let out = outputs::outputs(o);
    let json =
        serde_json::to_string_pretty(&outputs::results_json(o)).map_err(|e| e.to_string())? + "\n";
    let mut set: Vec<SetFile> = (out.exports.iter())
        .map(|(rel, text)| (PathBuf::from(rel), text.as_bytes()))
        .collect();
    for (rel, bytes) in &out.overlays {
        set.push((PathBuf::from(rel), bytes.as_slice()));
    }
    set.push(("report.html".into(), out.report_html.as_bytes()));
    set.push(("results.json".into(), json.as_bytes()));
    write_set(lock, &set).map_err(|e| e.to_string())
}

/// The one-line summary of a calibrated board project.
fn summary_line(path: &Path, dir: &Path, o: &BoardOutcome, secs: f64) -> String {
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
fn json_line(path: &Path, dir: &Path, o: &BoardOutcome, secs: f64) -> String {
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
pub(crate) fn calibrate_board(
    project: &Project,
    lock: &FolderLock,
    opts: &Options,
    rep: &Reporter,
    how: How,
) -> Done {
    let (path, dir) = (project.path.as_path(), lock.dir());
    let r = match board_lrf::calibrate_board(project, opts, rep) {
        Ok(o) => write(lock, &o).map(|()| o).map_err(|e| ("output", e)),
        Err(e) => Err((e.kind(), e.to_string())),
    };
    let secs = how.t0.elapsed().as_secs_f64();
    let o = match r {
        Ok(o) => o,
        Err((kind, e)) => {
            let e = kept_note(e, dir);
            return Done {
                fate: Fate::Error,
                line: how
                    .json
                    .then(|| error_json_line(path, dir, (kind, &e), secs)),
                error: Some(e),
                stderr: match how.shown {
                    true => Vec::new(),
                    false => warnings(path, rep),
                },
            };
        }
    };
    let mut stderr = Vec::new();
    if !how.shown {
        stderr.extend(warnings(path, rep));
        for why in &o.verdict.reasons {
            stderr.push(format!(
                "{}: {}: {why}",
                path.display(),
                o.verdict.status.as_str()
            ));
        }
    }
    Done {
        fate: Fate::of(o.verdict.status),
        line: Some(match how.json {
            true => json_line(path, dir, &o, secs),
            false => summary_line(path, dir, &o, secs),
        }),
        error: None,
        stderr,
    }
}
