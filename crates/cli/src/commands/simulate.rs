//! `pingcal simulate --out DIR [--seed N] [--config FILE]`: a complete simulated project
//! (project.toml, PNG images, pingcal-scan CSV, truth.json) of the paper's test field and
//! sensors (issue 6, crate `pingcal-sim`).
//!
//! `pingcal simulate --kind sphere-calib --out DIR [--seed N] [--frames N] [--lidar-sigma-mm S] [--azimuth-step-deg A] [--scene clean|cluttered]`:
//! a data set for
//! `pingcal sphere-calib` (issue 15, `pingcal_sim::sphere_calib`): a 16-beam lidar's clouds
//! and the camera's images of one large sphere moved to N places, `sphere-calib.toml`,
//! `camera.toml` and `truth.json`.
//!
//! `pingcal simulate --config sim.toml` with `[field] kind = "board"`: a board field
//! (issue 51, `pingcal_sim::board_field`): a chessboard in `[field] placements` before the
//! head's left camera and a fixed 2D LRF, `project.toml`, `images/P1.png` …, `lasers/P1.pcd`
//! … and `truth.json`.
//!
//! The project is written into a hidden temporary folder beside DIR and renamed to DIR at
//! the end, so an interrupted run never leaves a partial project looking complete.

use super::CmdResult;
use std::path::PathBuf;

/// Arguments of `pingcal simulate`.
#[derive(clap::Args)]
#[command(allow_negative_numbers = true)]
pub struct Args {
    /// Output folder (must not exist, or be empty).
    #[arg(long)]
    out: PathBuf,
    /// Seed of every random choice (same seed and config ⇒ identical files).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Simulator configuration (TOML; keys not given keep the paper's defaults).
    #[arg(long)]
    config: Option<PathBuf>,
    /// What to simulate: `field` (the paper's test field, the default) or `sphere-calib`
    /// (one large sphere seen by a 16-beam lidar and the camera, for `pingcal sphere-calib`).
    #[arg(long, value_enum, default_value_t = Kind::Field)]
    kind: Kind,
    /// Number of frames (places of the sphere) of `--kind sphere-calib` (default 10).
    #[arg(long)]
    frames: Option<usize>,
    /// The lidar's range σ of `--kind sphere-calib`, mm (constant over range; default the
    /// VLP-16 profile, 10 mm).
    #[arg(long)]
    lidar_sigma_mm: Option<f64>,
    /// The lidar's azimuth step of `--kind sphere-calib`, degrees (default 0.2, a VLP-16 at
    /// 600 rpm; 0.042 gives a frame of about 100k points).
    #[arg(long)]
    azimuth_step_deg: Option<f64>,
    /// The scene of `--kind sphere-calib`: `clean` (a uniformly bright floating sphere in a
    /// plain room, the default) or `cluttered` (a shaded sphere with a highlight on a stand,
    /// bricks, tiles, bright round plates, every fourth frame across the image's border).
    #[arg(long, value_enum)]
    scene: Option<SphereScene>,
    /// The stereo head's lenses: a camera model's name (a word not one lists them), each
    /// with its sample lens (the default MYNT-like ~90° lens, a 120° wide-angle lens, 190°
    /// fisheyes); replaces `[camera]` of `--config` with that lens's defaults and grows the
    /// target dots as much as the lens is wider (docs/formats.md, "Camera models").
    #[arg(long)]
    camera_model: Option<String>,
}

/// The scene of `--kind sphere-calib`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum SphereScene {
    /// A uniformly bright floating sphere in a plain room.
    Clean,
    /// What real photographs show (`pingcal_sim::sphere_clutter`).
    Cluttered,
}

/// `cfg` seen through the lenses `--camera-model` names (unchanged without it).
pub fn with_camera_model(
    cfg: pingcal_sim::SimConfig,
    name: Option<&str>,
) -> Result<pingcal_sim::SimConfig, String> {
    let Some(m) = name else { return Ok(cfg) };
    let model = pingcal_project::CameraModel::from_name(m).ok_or_else(|| {
        format!(
            "--camera-model {m}: expected one of {}",
            pingcal_project::CameraModel::NAMES.join(", ")
        )
    })?;
    Ok(cfg.with_camera_model(model))
}

/// What `pingcal simulate` writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Kind {
    /// The paper's test field: a project for `pingcal calibrate`.
    Field,
    /// One large sphere at N places: a data set for `pingcal sphere-calib`.
    SphereCalib,
}

/// Runs the command.
pub fn run(args: Args) -> CmdResult {
    let t0 = std::time::Instant::now();
    if args.kind == Kind::SphereCalib {
        if args.config.is_some() {
            return Err(
                "--config: not used by --kind sphere-calib (its options are --frames, --lidar-sigma-mm, --azimuth-step-deg, --scene and --seed)"
                    .into(),
            );
        }
        let base = match args.scene {
            Some(SphereScene::Cluttered) => {
                pingcal_sim::sphere_calib::SphereCalibConfig::cluttered()
            }
            _ => pingcal_sim::sphere_calib::SphereCalibConfig::default(),
        };
        let mut cfg = pingcal_sim::sphere_calib::SphereCalibConfig {
            frames: args.frames.unwrap_or(10),
            ..base
        };
        if let Some(a) = args.azimuth_step_deg {
            if !(0.01..=10.0).contains(&a) {
                return Err(format!(
                    "--azimuth-step-deg {a}: expected a step between 0.01 and 10 degrees"
                )
                .into());
            }
            cfg.azimuth_step_deg = a;
        }
        if let Some(s) = args.lidar_sigma_mm {
            cfg.noise = pingcal_lrf::RangeNoise::linear(s, 0.0)
                .map_err(|e| format!("--lidar-sigma-mm: {e}"))?;
            cfg.noise_name = None;
        }
        let s = pingcal_sim::place::simulate_sphere_calib_into(&args.out, &cfg, args.seed)?;
        println!(
            "simulate: wrote {} ({} frames of a {} mm sphere, {} lidar points; seed {}) in {:.1} s",
            args.out.join("sphere-calib.toml").display(),
            s.frames,
            2.0 * cfg.sphere_radius_mm,
            s.points,
            args.seed,
            t0.elapsed().as_secs_f64()
        );
        return Ok(());
    }
    if args.frames.is_some()
        || args.lidar_sigma_mm.is_some()
        || args.azimuth_step_deg.is_some()
        || args.scene.is_some()
    {
        return Err(
            "--frames, --lidar-sigma-mm, --azimuth-step-deg, --scene: only for --kind sphere-calib"
                .into(),
        );
    }
    let mut cfg = match &args.config {
        Some(p) => pingcal_sim::SimConfig::from_toml_file(p)?,
        None => pingcal_sim::SimConfig::default(),
    };
    cfg = with_camera_model(cfg, args.camera_model.as_deref())?;
    let out = &args.out;
    if cfg.field.kind == pingcal_sim::config::FieldKind::Board {
        let s = pingcal_sim::place::simulate_board_field_into(
            out,
            &cfg,
            args.seed,
            args.config.as_deref(),
        )?;
        println!(
            "simulate: wrote {} (a board field: {} placements of the board, {} LRF points, at least {} beams on the board in every scan; seed {}) in {:.1} s",
            out.join("project.toml").display(),
            s.placements,
            s.points,
            s.min_board_beams,
            args.seed,
            t0.elapsed().as_secs_f64()
        );
        return Ok(());
    }
    let (summary, sim, _) =
        pingcal_sim::place::simulate_into(out, &cfg, args.seed, args.config.as_deref())?;
    println!(
        "simulate: wrote {} ({} images, {} LRF scans, {} targets of which {} coded, {} balls, {} distances; seed {}) in {:.1} s",
        out.join("project.toml").display(),
        summary.images,
        summary.scans,
        summary.targets,
        summary.coded,
        summary.balls,
        sim.scene.distances.len(),
        args.seed,
        t0.elapsed().as_secs_f64()
    );
    Ok(())
}
