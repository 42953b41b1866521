//! `pingcal gen-bal`: writes a synthetic BAL problem (for tests and benchmarks).

use super::{write_atomic, CmdResult};
use pingcal_ba::synthetic::{SyntheticBal, Visibility};
use std::io::Write;
use std::path::PathBuf;

/// Arguments of `pingcal gen-bal`.
#[derive(clap::Args)]
#[command(allow_negative_numbers = true)]
pub struct Args {
    /// Number of cameras.
    #[arg(long, default_value_t = 50)]
    pub cameras: usize,
    /// Number of points.
    #[arg(long, default_value_t = 5000)]
    pub points: usize,
    /// Observations per point.
    #[arg(long, default_value_t = 5)]
    pub obs_per_point: usize,
    /// Image noise σ, pixels.
    #[arg(long, allow_hyphen_values = true, default_value_t = 0.5)]
    pub noise_px: f64,
    /// Scale of the perturbation of the initial values.
    #[arg(long, allow_hyphen_values = true, default_value_t = 1.0)]
    pub perturbation: f64,
    /// Random seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Which cameras see a point: `banded` (neighbours along a street) or `random` (any
    /// K of all cameras: a dense camera graph).
    #[arg(long, value_enum, default_value_t = VisibilityArg::Banded)]
    pub visibility: VisibilityArg,
    /// Output BAL file (`.bz2` compresses).
    #[arg(long)]
    pub out: PathBuf,
}

/// The `--visibility` values.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum VisibilityArg {
    /// Neighbouring cameras along a street.
    Banded,
    /// Any cameras, drawn at random.
    Random,
}

impl From<VisibilityArg> for Visibility {
    fn from(v: VisibilityArg) -> Self {
        match v {
            VisibilityArg::Banded => Visibility::Banded,
            VisibilityArg::Random => Visibility::Random,
        }
    }
}

/// Runs the command.
pub fn run(args: Args) -> CmdResult {
    let spec = SyntheticBal {
        cameras: args.cameras,
        points: args.points,
        obs_per_point: args.obs_per_point,
        noise_px: args.noise_px,
        perturbation: args.perturbation,
        seed: args.seed,
        visibility: args.visibility.into(),
    };
    let synthetic = spec.generate()?;
    let mut text = Vec::new();
    pingcal_ba::bal::write_bal(&synthetic.problem, &mut text)?;
    let bytes = if args.out.extension().is_some_and(|e| e == "bz2") {
        let mut enc = bzip2::write::BzEncoder::new(Vec::new(), bzip2::Compression::default());
        enc.write_all(&text)?;
        enc.finish()?
    } else {
        text
    };
    write_atomic(&args.out, &bytes)?;
    let p = &synthetic.problem;
    println!(
        "pingcal gen-bal: wrote {} ({} cameras, {} points, {} observations, seed {})",
        args.out.display(),
        p.images.len(),
        p.points.len(),
        p.observations.len(),
        args.seed
    );
    Ok(())
}
