//! `pingcal targets --ids 2-80 --plain 40 --dot-radius-mm 4 --out targets.pdf`: AICON-style
//! coded targets and plain targets at true size on A4, A3 or Letter pages, each page with a
//! 100 mm scale bar; PDF or SVG by the file's extension (one SVG file per page).
//! `pingcal targets --board 9x6 --square-mm 25 --out board.pdf`: a chessboard at true size
//! on one page instead, with the same scale bar.

use super::CmdResult;
use pingcal_targets::board::printable::{aprilgrid_page, charuco_page, chessboard_page};
use pingcal_targets::board::{Chessboard, PlanarBoard};
use pingcal_targets::sheet::{self, PageSize, SheetSpec};
use std::path::{Path, PathBuf};

/// Arguments of `pingcal targets`.
#[derive(clap::Args)]
#[command(allow_negative_numbers = true)]
pub struct Args {
    /// Number of ring sectors (14 or 12 for AICON codes): the project's `family`.
    #[arg(long, default_value_t = 14)]
    pub bits: u32,
    /// Coded target numbers, e.g. `2-80` or `5,7,9-12` (each once).
    #[arg(long, default_value = "1-20")]
    pub ids: String,
    /// Plain targets (a dot on a black square) after the coded ones.
    #[arg(long, default_value_t = 0)]
    pub plain: usize,
    /// Radius of the central dot (mm), as the project's `[targets] dot_radius_mm`.
    #[arg(long, allow_hyphen_values = true, default_value_t = 4.0)]
    pub dot_radius_mm: f64,
    /// Inner radius of the code ring, in dot radii (the project's `ring_inner`).
    #[arg(long, default_value_t = 2.0)]
    pub ring_inner: f64,
    /// Outer radius of the code ring, in dot radii (the project's `ring_outer`).
    #[arg(long, default_value_t = 3.0)]
    pub ring_outer: f64,
    /// Paper: a4, a3 or letter.
    #[arg(long, default_value = "a4")]
    pub page: String,
    /// No longer accepted: it was the dot's diameter, which the project calls a radius.
    #[arg(long, hide = true, allow_hyphen_values = true)]
    pub dot_mm: Option<f64>,
    /// A board instead of targets: a chessboard's inner corners as COLSxROWS (e.g. `9x6`, as
    /// the project's `[board] inner_corners`, with `--square-mm`), or a file that describes a
    /// board (a project file's `[board]`, Kalibr's `target.yaml`: ChArUco boards and AprilGrids
    /// too).
    #[arg(long)]
    pub board: Option<String>,
    /// The chessboard's square side (mm), as the project's `[board] square_mm` (with
    /// `--board`).
    #[arg(long, allow_hyphen_values = true)]
    pub square_mm: Option<f64>,
    /// Output file: `.pdf`, or `.svg` (with more than one page, `NAME-1.svg`, `NAME-2.svg`, …).
    #[arg(long)]
    pub out: PathBuf,
}

/// Runs the command.
pub fn run(args: Args) -> CmdResult {
    if let Some(d) = args.dot_mm {
        return Err(format!(
            "--dot-mm {d}: --dot-mm was the dot's diameter; give --dot-radius-mm {} (the project's dot_radius_mm)",
            d / 2.0
        )
        .into());
    }
    if let Some(board) = &args.board {
        return print_board(board, &args);
    }
    if args.square_mm.is_some() {
        return Err("--square-mm is the chessboard's square: give it with --board".into());
    }
    let spec = SheetSpec {
        bits: args.bits,
        ids: pingcal_targets::printable::parse_id_list(&args.ids)?,
        plain: args.plain,
        dot_radius_mm: args.dot_radius_mm,
        ring: (args.ring_inner, args.ring_outer),
        page: PageSize::parse(&args.page)?,
    };
    let pdf = match args.out.extension().and_then(|e| e.to_str()) {
        Some(e) if e.eq_ignore_ascii_case("pdf") => true,
        Some(e) if e.eq_ignore_ascii_case("svg") => false,
        _ => {
            return Err(format!(
                "--out {}: expected a .pdf or .svg file name",
                args.out.display()
            )
            .into())
        }
    };
    let pages = sheet::layout(&spec)?;
    let files = if pdf || pages.len() == 1 {
        vec![args.out.clone()]
    } else {
        (1..=pages.len()).map(|k| numbered(&args.out, k)).collect()
    };
    for f in &files {
        super::preflight::check_out_file("--out", f)?;
    }
    if pdf {
        super::write_atomic(&args.out, &sheet::to_pdf(&pages, spec.page))?;
    } else {
        for (page, f) in pages.iter().zip(&files) {
            super::write_atomic(f, sheet::to_svg(page, spec.page).as_bytes())?;
        }
    }
    println!(
        "targets: {} {}-bit coded and {} plain targets, dot radius {} mm, on {} {} page{}, written to {} (print at 100 %, then measure the 100 mm scale bar)",
        spec.ids.len(),
        spec.bits,
        spec.plain,
        spec.dot_radius_mm,
        pages.len(),
        args.page.to_uppercase(),
        if pages.len() == 1 { "" } else { "s" },
        files
            .iter()
            .map(|f| f.display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
    );
    Ok(())
}

/// `--board`: one page with the board at true size: a chessboard of `COLSxROWS` inner
/// corners and `--square-mm`, or the board a file describes.
fn print_board(spec: &str, args: &Args) -> CmdResult {
    let board = match Chessboard::parse_inner_corners(spec) {
        Ok((cols, rows)) => {
            let Some(square_mm) = args.square_mm else {
                return Err("--board needs --square-mm, the side of a square as printed (mm)".into());
            };
            PlanarBoard::Chessboard(Chessboard {
                cols,
                rows,
                square_mm,
            })
        }
        Err(_) if Path::new(spec).is_file() => {
            if args.square_mm.is_some() {
                return Err(format!("--square-mm is for --board COLSxROWS: {spec} gives the board's sizes").into());
            }
            pingcal_project::board_file(Path::new(spec))?.planar()?
        }
        Err(why) => {
            return Err(format!(
                "{why}, or a file that describes a board (a project file's [board], Kalibr's target.yaml)"
            )
            .into())
        }
    };
    let size = PageSize::parse(&args.page)?;
    let page = match &board {
        PlanarBoard::Chessboard(b) => chessboard_page(b, size)?,
        PlanarBoard::Charuco(b) => charuco_page(b, size)?,
        PlanarBoard::Aprilgrid(b) => aprilgrid_page(b, size)?,
    };
    let bytes = match args.out.extension().and_then(|e| e.to_str()) {
        Some(e) if e.eq_ignore_ascii_case("pdf") => sheet::to_pdf(&[page], size),
        Some(e) if e.eq_ignore_ascii_case("svg") => sheet::to_svg(&page, size).into_bytes(),
        _ => {
            return Err(format!(
                "--out {}: expected a .pdf or .svg file name",
                args.out.display()
            )
            .into())
        }
    };
    super::preflight::check_out_file("--out", &args.out)?;
    super::write_atomic(&args.out, &bytes)?;
    println!(
        "targets: a {}, on one {} page, written to {} (print at 100 %, then measure the 100 mm scale bar)",
        board.describe(),
        args.page.to_uppercase(),
        args.out.display()
    );
    Ok(())
}

/// `dir/NAME-k.svg` for `dir/NAME.svg`.
fn numbered(out: &Path, k: usize) -> PathBuf {
    let stem = out
        .file_stem()
        .map(|s| s.to_string_lossy())
        .unwrap_or_default();
    out.with_file_name(format!("{stem}-{k}.svg"))
}
