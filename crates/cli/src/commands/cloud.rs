//! `pingcal cloud SCAN... [--out FILE.ply] [--diameter-mm 38] [--balls FILE]`: the LRF cloud
//! (paper eq. 2) from scan files (or PLY/XYZ clouds), the balls found and fitted in it.
//! The PLY holds the cloud in grey, each ball's inlier points and a sampled sphere surface in
//! one colour per ball; `--balls` writes the centres as `id x y z sx sy sz`, the input format
//! of `pingcal register`.

use super::CmdResult;
use pingcal_lrf::ball_finder::{find_balls, FinderOptions};
use pingcal_lrf::cloud::{read_cloud_file, Cloud, MountModel};
use std::path::PathBuf;

/// Arguments of `pingcal cloud`.
#[derive(clap::Args)]
pub struct Args {
    /// Scan files (`pingcal-scan` CSV), or PLY / XYZ clouds.
    #[arg(required = true)]
    pub scans: Vec<PathBuf>,
    /// Write the cloud with the fitted spheres as binary PLY.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Ball diameter, mm.
    #[arg(long, default_value_t = 38.0)]
    pub diameter_mm: f64,
    /// Write the ball centres with their σ's (`id x y z sx sy sz`, mm).
    #[arg(long)]
    pub balls: Option<PathBuf>,
    /// Seed of the RANSAC choices.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// Runs the command.
pub fn run(args: Args) -> CmdResult {
    if !(args.diameter_mm > 0.0 && args.diameter_mm.is_finite()) {
        return Err(format!(
            "--diameter-mm: expected a positive number, found {}",
            args.diameter_mm
        )
        .into());
    }
    let mut cloud = Cloud::default();
    for f in &args.scans {
        cloud.extend(read_cloud_file(f, &MountModel::default())?);
    }
    let opt = FinderOptions {
        diameter_mm: args.diameter_mm,
        seed: args.seed,
        ..Default::default()
    };
    let found = find_balls(&cloud, &opt);
    if let Some(out) = &args.out {
        let comments = vec![format!(
            "pingcal cloud: {} points, {} balls of {} mm",
            cloud.len(),
            found.balls.len(),
            args.diameter_mm
        )];
        let mut bytes = Vec::new();
        pingcal_lrf::ply::write_cloud_with_spheres(
            &mut bytes,
            &cloud,
            &found.balls,
            args.diameter_mm / 2.0,
            &comments,
        )?;
        super::write_atomic(out, &bytes)?;
    }
    if let Some(path) = &args.balls {
        let mut text =
            String::from("# pingcal cloud: ball centres in the LRF frame, mm: id x y z sx sy sz\n");
        for (k, b) in found.balls.iter().enumerate() {
            let c = b.centre;
            let s = b.cov.diagonal().map(|v| v.max(0.0).sqrt());
            text += &format!(
                "L{} {:.3} {:.3} {:.3} {:.3} {:.3} {:.3}\n",
                k + 1,
                c.x,
                c.y,
                c.z,
                s.x,
                s.y,
                s.z
            );
        }
        super::write_atomic(path, text.as_bytes())?;
    }
    println!(
        "cloud: {} points from {} file(s), {} plane(s), {} ball(s) of {} mm, {} candidate(s) not used{}",
        cloud.len(),
        args.scans.len(),
        found.planes.len(),
        found.balls.len(),
        args.diameter_mm,
        found.rejected.len(),
        args.out.as_ref().map_or(String::new(), |o| format!(" → {}", o.display()))
    );
    Ok(())
}
