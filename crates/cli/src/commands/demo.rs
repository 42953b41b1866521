//! `pingcal demo [--out DIR] [--seed N] [--quiet]`: the embedded default. Simulates the
//! paper's test field and sensors (`pingcal simulate`), calibrates it (`pingcal calibrate`),
//! and prints the paper's Table 4 (check-point errors, dx = estimated − reference) for the
//! sphere method and the Fan et al. 2019 corner baseline beside the truth, which a simulation
//! knows: the extrinsic's true error, and the check errors the true extrinsic would give on
//! the same measurements (the floor set by the measurement noise).

use super::calibrate::{calibrate_one, write_outputs};
use super::progress::reporter;
use super::CmdResult;
use indicatif::MultiProgress;
use pingcal_pipeline as pipeline;
use pingcal_sim::project_files::PoseJson;
use std::path::PathBuf;

/// Arguments of `pingcal demo`.
#[derive(clap::Args)]
#[command(allow_negative_numbers = true)]
pub struct Args {
    /// Folder for the simulated project and the results (default: a folder in the system's
    /// temporary directory, replaced on every run).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Seed of the simulation and of every random choice.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// No progress bars and no step log.
    #[arg(long)]
    pub quiet: bool,
}

/// Runs the command.
pub fn run(args: Args) -> CmdResult {
    let t0 = std::time::Instant::now();
    let out = match &args.out {
        Some(o) => o.clone(),
        None => {
            let d = std::env::temp_dir().join(format!("pingcal-demo-seed{}", args.seed));
            if d.exists() {
                std::fs::remove_dir_all(&d)
                    .map_err(|e| format!("{}: cannot replace: {e}", d.display()))?;
            }
            d
        }
    };
    let multi = (!args.quiet).then(MultiProgress::new);
    let rep = match &multi {
        Some(m) => reporter(Some(m), ""),
        None => super::progress::quiet_reporter(""),
    };
    rep.log(format!(
        "demo: simulating the paper's test field (seed {}) into {}",
        args.seed,
        out.display()
    ));
    let cfg = pingcal_sim::SimConfig::default();
    let (summary, _, [t_scene, t_write]) =
        super::simulate::simulate_into(&out, &cfg, args.seed, None)?;
    let t_sim = t0.elapsed().as_secs_f64();
    rep.log(format!(
        "demo: {} images, {} LRF scans, {} targets ({} coded), {} balls simulated in {t_sim:.1} s (scene and LRF sweep {t_scene:.1} s, rendering and writing {t_write:.1} s)",
        summary.images, summary.scans, summary.targets, summary.coded, summary.balls
    ));
    let opts = pipeline::Options {
        seed: args.seed,
        ..pipeline::Options::default()
    };
    let project = out.join("project.toml");
    let results_dir = out.join("results");
    std::fs::create_dir_all(&results_dir)
        .map_err(|e| format!("{}: cannot create: {e}", results_dir.display()))?;
    let lock = super::result_set::FolderLock::take(&results_dir)?;
    let outcome = calibrate_one(&project, &opts, &rep)?;
    write_outputs(&lock, &outcome)?;
    let truth = pingcal_sim::read_truth(&out.join("truth.json"))?;
    let t_all = t0.elapsed().as_secs_f64();
    print_table(&outcome.results, &truth);
    println!(
        "demo: simulated in {t_sim:.1} s, calibrated in {:.1} s; report {}",
        t_all - t_sim,
        results_dir.join("report.html").display()
    );
    Ok(())
}

fn print_table(r: &pipeline::results::Results, truth: &pingcal_sim::Truth) {
    let te: PoseJson = truth.extrinsic_as_calibrated();
    println!();
    println!("Table 4 — check points (mm); dx = estimated − reference (photogrammetric)");
    let mut header = format!("{:<6}", "ball");
    for m in &r.methods {
        header += &format!(
            " | {:^29}",
            match m.method.as_str() {
                "joint" => "joint (mount self-calibrated)",
                "spheres" => "spheres (paper's two steps)",
                _ => "corner (Fan et al. 2019)",
            }
        );
    }
    header += " | true extrinsic";
    println!("{header}");
    let mut sub = format!("{:<6}", "");
    for _ in &r.methods {
        sub += &format!(" | {:>7}{:>7}{:>7}{:>8}", "dx", "dy", "dz", "error");
    }
    sub += &format!(" | {:>14}", "error");
    println!("{sub}");
    let ids: Vec<String> = r
        .methods
        .iter()
        .find(|m| !m.check_points.is_empty())
        .map(|m| m.check_points.iter().map(|c| c.id.clone()).collect())
        .unwrap_or_default();
    let mut floor = Vec::new();
    for id in &ids {
        let mut line = format!("{id:<6}");
        for m in &r.methods {
            match m.check_points.iter().find(|c| &c.id == id) {
                Some(c) => {
                    line += &format!(
                        " | {:>7.2}{:>7.2}{:>7.2}{:>8.2}",
                        c.dx_mm, c.dy_mm, c.dz_mm, c.error_mm
                    )
                }
                None => line += &format!(" | {:>29}", "—"),
            }
        }
        // the check error the true extrinsic gives on the same measured centres
        let b = r.balls.iter().find(|b| &b.id == id);
        match b.and_then(|b| b.lrf_mm.map(|l| (l, b.photogrammetric_mm))) {
            Some((l, p)) => {
                let e = te.misfit_mm(l, p);
                floor.push(e);
                line += &format!(" | {e:>14.2}");
            }
            None => line += &format!(" | {:>14}", "—"),
        }
        println!("{line}");
    }
    let mut mean = format!("{:<6}", "mean");
    for m in &r.methods {
        match (m.mean_check_error_mm, m.sd_check_error_mm) {
            (Some(e), Some(s)) => mean += &format!(" | {:>21}{:>8.2}", format!("(sd {s:.2})"), e),
            _ => {
                mean += &format!(
                    " | {:>29}",
                    m.error.as_deref().map(|_| "failed").unwrap_or("—")
                )
            }
        }
    }
    if !floor.is_empty() {
        mean += &format!(
            " | {:>14.2}",
            floor.iter().sum::<f64>() / floor.len() as f64
        );
    }
    println!("{mean}");
    println!();
    println!("Extrinsic (p_camera = R p_lrf + t) against the truth (the LRF frame's origin on the servo axis at the scan plane, as a calibration defines it)");
    println!(
        "{:<9} {:>26} {:>22} {:>9} {:>26} {:>9} {:>14}",
        "", "t (mm)", "σ t (mm)", "|Δt| mm", "ω φ κ (°)", "ΔR (°)", "σ ω φ κ (°)"
    );
    let tt = te.translation_mm;
    println!(
        "{:<9} {:>26} {:>22} {:>9} {:>26}",
        "truth",
        format!("({:.1}, {:.1}, {:.1})", tt[0], tt[1], tt[2]),
        "",
        "",
        format!(
            "({:.3}, {:.3}, {:.3})",
            te.opk_deg[0], te.opk_deg[1], te.opk_deg[2]
        )
    );
    for m in &r.methods {
        let Some(e) = &m.extrinsic else {
            println!(
                "{:<9} failed: {}",
                m.method,
                m.error.as_deref().unwrap_or("")
            );
            continue;
        };
        let t = e.translation_mm;
        let dt = ((t[0] - tt[0]).powi(2) + (t[1] - tt[1]).powi(2) + (t[2] - tt[2]).powi(2)).sqrt();
        let dr = te.angle_to_deg(&e.rotation);
        let st = e
            .sigma_translation_mm
            .map(|s| format!("({:.2}, {:.2}, {:.2})", s[0], s[1], s[2]))
            .unwrap_or_else(|| "—".into());
        let sr = e
            .sigma_rotation_deg
            .map(|s| format!("({:.3}, {:.3}, {:.3})", s[0], s[1], s[2]))
            .unwrap_or_else(|| "—".into());
        println!(
            "{:<9} {:>26} {:>22} {:>9.2} {:>26} {:>9.3} {:>14}",
            m.method,
            format!("({:.1}, {:.1}, {:.1})", t[0], t[1], t[2]),
            st,
            dt,
            format!(
                "({:.3}, {:.3}, {:.3})",
                e.opk_deg[0], e.opk_deg[1], e.opk_deg[2]
            ),
            dr,
            sr
        );
    }
    println!(
        "bundle: sigma0 {:.3}, RMS {:.3} px, {} images, {} points, {} image points ({} rejected)",
        r.bundle.sigma0,
        r.bundle.rms_image_px,
        r.bundle.images,
        r.bundle.points,
        r.bundle.observations,
        r.bundle.rejected
    );
    let v = &r.verdict;
    println!("verdict: {}", v.status.as_str());
    for reason in &v.reasons {
        println!("  - {reason}");
    }
    for note in &v.notes {
        println!("  note: {note}");
    }
}
