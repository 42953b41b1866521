//! `pingcal targets --bits 14 --ids 2-80 --dot-mm 8 --out targets.svg`: AICON-style coded
//! targets at true size, with their numbers, ready to print (at 100 % scale).

use super::CmdResult;
use std::path::PathBuf;

/// Arguments of `pingcal targets`.
#[derive(clap::Args)]
#[command(allow_negative_numbers = true)]
pub struct Args {
    /// Number of ring sectors (14 or 12 for AICON codes).
    #[arg(long, default_value_t = 14)]
    pub bits: u32,
    /// Target numbers, e.g. `2-80` or `5,7,9-12`.
    #[arg(long, default_value = "1-20")]
    pub ids: String,
    /// Diameter of the central dot in mm (the ring spans 2 to 3 dot radii, the square 8).
    #[arg(long, allow_hyphen_values = true, default_value_t = 8.0)]
    pub dot_mm: f64,
    /// Targets per row.
    #[arg(long, default_value_t = 5)]
    pub columns: usize,
    /// Output SVG file.
    #[arg(long)]
    pub out: PathBuf,
}

/// Runs the command.
pub fn run(args: Args) -> CmdResult {
    let ids = pingcal_targets::printable::parse_id_list(&args.ids)?;
    super::preflight::check_out_file("--out", &args.out)?;
    let svg = pingcal_targets::printable::targets_svg(args.bits, &ids, args.dot_mm, args.columns)?;
    super::write_atomic(&args.out, svg.as_bytes())?;
    println!(
        "targets: {} {}-bit coded targets, dot {} mm, written to {} (print at 100 % scale)",
        ids.len(),
        args.bits,
        args.dot_mm,
        args.out.display()
    );
    Ok(())
}
