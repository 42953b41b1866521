//! `pingcal detect IMAGE... --board 9x6 [--out FILE]`: a chessboard of those inner corners in
//! each image instead: its corners numbered as the board's layout, with their σ, or the
//! one-line reason it was not found; `--board FILE` any board a file describes (a project
//! file's `[board]`, Kalibr's `target.yaml`: ChArUco boards and AprilGrids too).
//!
//! `pingcal detect IMAGE... [--out FILE] [--debug DIR] [--why] [--saturated]`: targets (coded,
//! plain) and balls found in images, as the JSON of docs/formats.md (pixel origin at the centre of the
//! top-left pixel, x to the right, y down), and the candidates refused by reason.
//!
//! The summary line counts the targets and, after `refused:`, the candidates refused by reason
//! (`pingcal_targets::refusal`); `--why` lists each refused candidate with its position and
//! reason in detail, then every reason's count with what to do about it; `--debug` draws the
//! refused candidates in orange with the letter of their reason. Targets refused as saturated
//! add a `warning:` line (stderr) giving their count and share of saturated samples.

use super::CmdResult;
use pingcal_targets::board::{Chessboard, PlanarBoard};
use pingcal_targets::detect::BallMode;
use pingcal_targets::refusal::{counts, Refusal, RefusalReason};
use pingcal_targets::{load_image, DetectParams, Detector, ImageDetections};
use std::path::PathBuf;

/// Arguments of `pingcal detect`.
#[derive(clap::Args)]
#[command(allow_negative_numbers = true)]
pub struct Args {
    /// Images (TIFF, PNG or JPEG; 8 or 16 bit; grey or colour).
    #[arg(required = true)]
    pub images: Vec<PathBuf>,
    /// Write the detections as JSON to this file.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Write an overlay PNG per image (ellipses, centres, IDs; refused candidates in orange
    /// with the letter of their reason) into this folder.
    #[arg(long)]
    pub debug: Option<PathBuf>,
    /// List every refused candidate: image, position, reason and its figures.
    #[arg(long)]
    pub why: bool,
    /// Measure saturated targets instead of refusing them (a flat render of a printed sheet,
    /// a scan): they are flagged and their σ tripled.
    #[arg(long)]
    pub saturated: bool,
    /// Ring-code bit counts to read, comma separated (AICON: 14 or 12).
    #[arg(long, value_delimiter = ',', default_value = "14")]
    pub bits: Vec<u32>,
    /// The printed code ring's inner and outer radius in dot radii, as `[targets]
    /// ring_inner` and `ring_outer` of project.toml (AICON: 2,3).
    #[arg(long, value_delimiter = ',', num_args = 2, default_values_t = [2.0, 3.0])]
    pub ring: Vec<f64>,
    /// Look for a board instead of targets and balls: a chessboard of these inner corners
    /// (COLSxROWS, e.g. `9x6`, as the project's `[board] inner_corners`), or any board a
    /// file describes (a project file's `[board]`, Kalibr's `target.yaml`).
    #[arg(long)]
    pub board: Option<String>,
    /// The images contain no ping-pong balls (do not classify large blobs as balls).
    #[arg(long)]
    pub no_balls: bool,
}

/// Runs the command.
pub fn run(args: Args) -> CmdResult {
    if let Some(board) = &args.board {
        return boards(board, &args);
    }
    let mut params = DetectParams {
        code_bits: args.bits.clone(),
        ring: (args.ring[0], args.ring[1]),
        measure_saturated: args.saturated,
        ..DetectParams::default()
    };
    if args.no_balls {
        params.balls = BallMode::Off;
    }
    let det = Detector::new(params)?;
    if let Some(dir) = &args.debug {
        std::fs::create_dir_all(dir)
            .map_err(|e| format!("{}: cannot create folder: {e}", dir.display()))?;
    }
    // without overlays, images are decoded and measured in parallel (decoding of one
    // overlaps detection in others); overlays need each image kept, one at a time
    let detections: Vec<ImageDetections> = match &args.debug {
        None => pingcal_targets::detect_files(&args.images, &det)
            .into_iter()
            .collect::<Result<_, _>>()?,
        Some(dir) => {
            let mut v = Vec::with_capacity(args.images.len());
            for path in &args.images {
                let img = load_image(path)?;
                let d = det.detect(&img);
                let stem = path
                    .file_stem()
                    .map(|s| s.to_string_lossy().into_owned())
                    .unwrap_or_else(|| "image".into());
                let out = dir.join(format!("{stem}.overlay.png"));
                pingcal_targets::overlay::draw_detections_and_refusals(&img, &d).save(&out)?;
                v.push(d);
            }
            v
        }
    };
    if let Some(out) = &args.out {
        let text = serde_json::to_string_pretty(&json(&args.images, &detections))?;
        super::write_atomic(out, text.as_bytes())?;
    }
    if args.why {
        print!("{}", why(&args.images, &detections));
    }
    println!("{}", summary(&args, &detections));
    for (path, d) in args.images.iter().zip(&detections) {
        if let Some(w) = nothing_found(path, d) {
            eprintln!("{w}");
        }
    }
    if let Some(w) = saturated_warning(&detections) {
        eprintln!("{w}");
    }
    Ok(())
}

/// `--board`: the chessboard in each image, a line per image, the corners in `--out`.
fn boards(spec: &str, args: &Args) -> CmdResult {
    if args.debug.is_some() || args.why || args.saturated || args.no_balls {
        return Err(
            "--board looks for a board: --debug, --why, --saturated and --no-balls are for targets"
                .into(),
        );
    }
    let (board, label) = board_spec(spec)?;
    let mut images = Vec::new();
    let mut found = 0;
    for path in &args.images {
        let img = load_image(path)?;
        let entry = match board.detect(&img) {
            Ok(d) => {
                found += 1;
                let mut sigmas: Vec<f64> = d.corners.iter().map(|c| c.sigma_px).collect();
                sigmas.sort_by(f64::total_cmp);
                println!(
                    "{}: {label}: {} corners, median σ {:.3} px{}",
                    path.display(),
                    d.corners.len(),
                    sigmas.get(sigmas.len() / 2).copied().unwrap_or(f64::NAN),
                    if d.symmetric {
                        " (symmetric board: corner 0 is the one nearer the image's top left)"
                    } else {
                        ""
                    }
                );
                let corners: Vec<serde_json::Value> = d
                    .corners
                    .iter()
                    .map(|c| {
                        serde_json::json!({"id": c.id, "col": c.col, "row": c.row,
                            "x": c.uv[0], "y": c.uv[1], "sigma_px": c.sigma_px})
                    })
                    .collect();
                serde_json::json!({"file": path.display().to_string(), "width": img.width,
                    "height": img.height, "found": true, "symmetric": d.symmetric, "corners": corners})
            }
            Err(miss) => {
                println!("{}: no {label}: {miss}", path.display());
                serde_json::json!({"file": path.display().to_string(), "width": img.width,
                    "height": img.height, "found": false, "reason": miss})
            }
        };
        images.push(entry);
    }
    if let Some(out) = &args.out {
        let doc = serde_json::json!({
            "board": label,
            "images": images,
        });
        super::write_atomic(out, serde_json::to_string_pretty(&doc)?.as_bytes())?;
    }
    println!(
        "detect: {label} found in {found} of {} images",
        args.images.len()
    );
    Ok(())
}

/// The board of `--board`: `COLSxROWS` (a chessboard of those inner corners, e.g. `9x6`), or a
/// file that describes one (a project file's `[board]`, Kalibr's `target.yaml`:
/// [`pingcal_project::board_file`]); with the words that name it in the output.
pub fn board_spec(spec: &str) -> Result<(PlanarBoard, String), String> {
    if let Ok((cols, rows)) = Chessboard::parse_inner_corners(spec) {
        let board = Chessboard {
            cols,
            rows,
            square_mm: 1.0,
        };
        return Ok((
            PlanarBoard::Chessboard(board),
            format!("chessboard {cols} × {rows}"),
        ));
    }
    let path = std::path::Path::new(spec);
    if !path.is_file() {
        let why = Chessboard::parse_inner_corners(spec).expect_err("not COLSxROWS");
        return Err(format!(
            "{why}, or a file that describes a board (a project file's [board], Kalibr's target.yaml)"
        ));
    }
    let board = pingcal_project::board_file(path)?.planar()?;
    Ok((board, board.describe()))
}

/// For an image in which no target was found, the warning that says why, on one line:
/// `warning: FILE: no targets: ` and [`pingcal_targets::refusal::why_nothing`].
fn nothing_found(path: &std::path::Path, d: &ImageDetections) -> Option<String> {
    d.targets.is_empty().then(|| {
        format!(
            "warning: {}: no targets: {}",
            path.display(),
            pingcal_targets::refusal::why_nothing(&d.refused)
        )
    })
}

/// The JSON of the detections: per image its file, size, targets (a coded read with its
/// margins and confidence, a target measured although saturated flagged) and the refused
/// candidates.
fn json(paths: &[PathBuf], detections: &[ImageDetections]) -> serde_json::Value {
    let images: Vec<serde_json::Value> = paths
        .iter()
        .zip(detections)
        .map(|(path, d)| {
            let targets: Vec<serde_json::Value> = d
                .targets
                .iter()
                .map(|t| {
                    let mut j = serde_json::json!({
                        "id": t.id,
                        "kind": t.kind,
                        "x": t.x,
                        "y": t.y,
                        "sigma_px": t.sigma_px,
                    });
                    if let Some(m) = t.read {
                        j["read"] = serde_json::json!(m);
                    }
                    if t.saturated {
                        j["saturated"] = true.into();
                    }
                    j
                })
                .collect();
            let refused: Vec<serde_json::Value> = d.refused.iter().map(refusal_json).collect();
            serde_json::json!({
                "file": path.display().to_string(),
                "width": d.width,
                "height": d.height,
                "targets": targets,
                "refused": refused,
            })
        })
        .collect();
    serde_json::json!({ "images": images })
}

fn refusal_json(r: &Refusal) -> serde_json::Value {
    let mut j = serde_json::json!({
        "reason": r.reason,
        "x": r.ellipse.cx,
        "y": r.ellipse.cy,
        "diameter_px": 2.0 * r.ellipse.radius(),
        "detail": r.detail,
    });
    if let Some(s) = r.saturated_share {
        j["saturated_share"] = s.into();
    }
    if let Some((id, m)) = r.refused_read {
        j["refused_read"] = serde_json::json!({ "id": id, "margins": m });
    }
    j
}

/// `--why`: every refused candidate, image by image, then each reason's count and advice.
fn why(paths: &[PathBuf], detections: &[ImageDetections]) -> String {
    let mut out = String::new();
    for (path, d) in paths.iter().zip(detections) {
        for r in &d.refused {
            out.push_str(&format!(
                "{}: ({:.1}, {:.1}) {:.1} px across: {}: {}\n",
                path.display(),
                r.ellipse.cx,
                r.ellipse.cy,
                2.0 * r.ellipse.radius(),
                r.reason.name(),
                r.detail
            ));
        }
    }
    let all = counts(detections.iter().flat_map(|d| &d.refused));
    if all.is_empty() {
        out.push_str("no candidate was refused\n");
    }
    for (reason, n) in all {
        out.push_str(&format!("{n} {}: {}\n", reason.name(), reason.advice()));
    }
    out
}

/// The summary line: targets by kind, then the refused candidates by reason (with the
/// saturated ones' share of saturated samples).
fn summary(args: &Args, detections: &[ImageDetections]) -> String {
    let (mut n_coded, mut n_ids, mut n_plain, mut n_balls, mut n_sat) = (0, 0, 0, 0, 0);
    for t in detections.iter().flat_map(|d| &d.targets) {
        match t.kind {
            pingcal_targets::TargetKind::Coded => {
                n_coded += 1;
                n_ids += usize::from(t.id.is_some());
            }
            pingcal_targets::TargetKind::Plain => n_plain += 1,
            pingcal_targets::TargetKind::Ball => n_balls += 1,
        }
        n_sat += usize::from(t.saturated);
    }
    let refused = counts(detections.iter().flat_map(|d| &d.refused));
    let refused = if refused.is_empty() {
        "refused: none".to_string()
    } else {
        let list: Vec<String> = refused
            .iter()
            .map(|(r, n)| match (r, share_range(detections)) {
                (RefusalReason::Saturated, Some(range)) => format!("{n} saturated ({range})"),
                _ => format!("{n} {}", r.name()),
            })
            .collect();
        format!("refused: {}", list.join(", "))
    };
    format!(
        "detect: {} images; {n_coded} coded targets ({n_ids} identified), {n_plain} plain, {n_balls} balls{}; {refused}{}",
        args.images.len(),
        if n_sat > 0 {
            format!(" ({n_sat} measured although saturated)")
        } else {
            String::new()
        },
        args.out
            .as_ref()
            .map(|p| format!("; written to {}", p.display()))
            .unwrap_or_default()
    )
}

/// The range of the saturated refusals' shares of saturated samples, in words ("85 % of
/// their samples saturated", "60–100 % of …"), or None when there is none.
fn share_range(detections: &[ImageDetections]) -> Option<String> {
    let shares: Vec<f64> = detections
        .iter()
        .flat_map(|d| &d.refused)
        .filter(|r| r.reason == RefusalReason::Saturated)
        .filter_map(|r| r.saturated_share)
        .collect();
    let lo = shares.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = shares.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if shares.is_empty() {
        return None;
    }
    let (lo, hi) = ((100.0 * lo).round(), (100.0 * hi).round());
    Some(if lo == hi {
        format!("{lo:.0} % of their samples saturated")
    } else {
        format!("{lo:.0}–{hi:.0} % of their samples saturated")
    })
}

/// The warning for targets refused as saturated: their count, share and the advice.
fn saturated_warning(detections: &[ImageDetections]) -> Option<String> {
    let n = detections
        .iter()
        .flat_map(|d| &d.refused)
        .filter(|r| r.reason == RefusalReason::Saturated)
        .count();
    (n > 0).then(|| {
        format!(
            "warning: {n} target(s) refused as saturated ({}): expose darker; for a flat render or scan of a printed sheet, --saturated measures them (flagged, σ tripled)",
            share_range(detections).unwrap_or_default()
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use pingcal_targets::ellipse::Ellipse;

    fn refusal(reason: RefusalReason, share: Option<f64>) -> Refusal {
        let mut r = Refusal::new(reason, Ellipse::circle(10.0, 20.0, 3.0), "detail");
        r.saturated_share = share;
        r
    }

    #[test]
    fn the_summary_counts_refusals_by_reason_with_the_saturated_share() {
        let d = ImageDetections {
            width: 100,
            height: 100,
            targets: Vec::new(),
            refused: vec![
                refusal(RefusalReason::Saturated, Some(0.85)),
                refusal(RefusalReason::Saturated, Some(1.0)),
                refusal(RefusalReason::TextGlyph, None),
            ],
        };
        let args = Args {
            images: vec!["a.png".into()],
            out: None,
            debug: None,
            why: false,
            saturated: false,
            bits: vec![14],
            ring: vec![2.0, 3.0],
            no_balls: false,
            board: None,
        };
        let s = summary(&args, std::slice::from_ref(&d));
        assert!(
            s.ends_with("refused: 1 text glyph, 2 saturated (85–100 % of their samples saturated)"),
            "{s}"
        );
        let w = saturated_warning(std::slice::from_ref(&d)).unwrap();
        assert!(w.contains("2 target(s) refused as saturated") && w.contains("expose darker"));
        let line = nothing_found(std::path::Path::new("a.png"), &d).unwrap();
        assert_eq!(
            line,
            format!(
                "warning: a.png: no targets: every candidate refused: 2 saturated, 1 text glyph ({})",
                RefusalReason::Saturated.advice()
            )
        );
        let none = ImageDetections {
            refused: Vec::new(),
            ..d.clone()
        };
        let line = nothing_found(std::path::Path::new("a.png"), &none).unwrap();
        assert!(
            line.starts_with("warning: a.png: no targets: no candidate: "),
            "{line}"
        );
        let why = why(&args.images, std::slice::from_ref(&d));
        assert!(
            why.contains("a.png: (10.0, 20.0) 6.0 px across: text glyph: detail"),
            "{why}"
        );
        assert!(why.contains("2 saturated: expose darker"), "{why}");
    }
}
