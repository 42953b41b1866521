//! The accuracy study of issue 7: simulate the paper-matched test field with seeds
//! FIRST..=LAST, calibrate each, and compare both methods with the truth.
//!
//! ```text
//! cargo run --release -p pingcal --example seed_study -- [FIRST] [LAST] [--keep DIR]
//! ```
//!
//! Per seed: mean check-point error of the sphere method and of the corner baseline, the
//! extrinsic's translation error (mm) and rotation error (degrees) against the truth, and the
//! normalised errors (error / reported σ) of the sphere method's translation components and
//! Euler angles. At the end: means and standard deviations over the seeds, the RMS of the
//! normalised errors (≈ 1 when the reported σ is honest) and the fraction within 2σ.

use nalgebra::{Matrix3, Vector3};
use pingcal_geometry::rotation_angle;
use pingcal_geometry::to_opk_deg;
use pingcal_pipeline::{self as pipeline, Reporter};

fn mean_sd(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let m = v.iter().sum::<f64>() / n;
    let s = (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0).max(1.0)).sqrt();
    (m, s)
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let keep = args
        .iter()
        .position(|a| a == "--keep")
        .and_then(|k| args.get(k + 1).cloned());
    let nums: Vec<u64> = args.iter().filter_map(|a| a.parse().ok()).collect();
    let first = nums.first().copied().unwrap_or(1);
    let last = nums.get(1).copied().unwrap_or(first + 19);
    let cfg = pingcal_sim::SimConfig::default();
    println!(
        "{:>4} {:>9} {:>9} {:>8} {:>8} {:>8} {:>8} {:>22} {:>22} {:>7}",
        "seed",
        "spheres",
        "corner",
        "|dt| sph",
        "dR sph",
        "|dt| cor",
        "dR cor",
        "t err/σ (x y z)",
        "angle err/σ (ω φ κ)",
        "time s"
    );
    let (mut sph, mut cor, mut dts, mut drs, mut dtc, mut drc, mut zs) =
        (vec![], vec![], vec![], vec![], vec![], vec![], vec![]);
    let mut failures = Vec::new();
    for seed in first..=last {
        let t0 = std::time::Instant::now();
        let dir = match &keep {
            Some(k) => std::path::PathBuf::from(k).join(format!("seed{seed}")),
            None => {
                std::env::temp_dir().join(format!("pingcal-study-{}-{seed}", std::process::id()))
            }
        };
        let _ = std::fs::remove_dir_all(&dir);
        let sim = pingcal_sim::Simulation::new(&cfg, seed).expect("default config");
        pingcal_sim::write_project(&sim, &dir).expect("write project");
        let truth = pingcal_sim::read_truth(&dir.join("truth.json")).expect("truth");
        let opts = pipeline::Options {
            seed,
            ..pipeline::Options::default()
        };
        let res = pingcal::commands::calibrate::calibrate_one(
            &dir.join("project.toml"),
            &opts,
            &Reporter::silent(),
        );
        if keep.is_none() {
            let _ = std::fs::remove_dir_all(&dir);
        }
        let o = match res {
            Ok(o) => o,
            Err(e) => {
                println!("{seed:>4} failed: {e}");
                failures.push(seed);
                continue;
            }
        };
        let tp = truth.extrinsic_as_calibrated().to_pose();
        let mut line = format!("{seed:>4}");
        let mut row = |m: &pipeline::results::MethodJson| -> Option<(f64, f64, f64, [f64; 6])> {
            let e = m.extrinsic.as_ref()?;
            let t = Vector3::from(e.translation_mm);
            let r = Matrix3::from_row_slice(&e.rotation.concat());
            let dt = t - tp.translation;
            let dr = rotation_angle(&(r * tp.rotation.transpose())).to_degrees();
            let mut z = [f64::NAN; 6];
            if let (Some(st), Some(sr)) = (e.sigma_translation_mm, e.sigma_rotation_deg) {
                let de = Vector3::from(to_opk_deg(&r)) - Vector3::from(to_opk_deg(&tp.rotation));
                for k in 0..3 {
                    z[k] = dt[k] / st[k];
                    z[3 + k] = de[k] / sr[k];
                }
            }
            Some((m.mean_check_error_mm?, dt.norm(), dr, z))
        };
        let s = o
            .results
            .methods
            .iter()
            .find(|m| m.method == "spheres")
            .and_then(&mut row);
        let c = o
            .results
            .methods
            .iter()
            .find(|m| m.method == "corner")
            .and_then(&mut row);
        match s {
            Some((e, dt, dr, _)) => {
                sph.push(e);
                dts.push(dt);
                drs.push(dr);
                line += &format!(" {e:>9.2}");
            }
            None => line += &format!(" {:>9}", "—"),
        }
        match c {
            Some((e, dt, dr, _)) => {
                cor.push(e);
                dtc.push(dt);
                drc.push(dr);
                line += &format!(" {e:>9.2}");
            }
            None => line += &format!(" {:>9}", "failed"),
        }
        let f = |v: Option<f64>, p: usize| v.map(|x| format!("{x:.p$}")).unwrap_or("—".into());
        line += &format!(
            " {:>8} {:>8} {:>8} {:>8}",
            f(s.map(|x| x.1), 2),
            f(s.map(|x| x.2), 3),
            f(c.map(|x| x.1), 1),
            f(c.map(|x| x.2), 2)
        );
        if let Some((_, _, _, z)) = s {
            line += &format!(
                " {:>22} {:>22}",
                format!("{:.2} {:.2} {:.2}", z[0], z[1], z[2]),
                format!("{:.2} {:.2} {:.2}", z[3], z[4], z[5])
            );
            zs.push(z);
        }
        line += &format!(" {:>7.1}", t0.elapsed().as_secs_f64());
        println!("{line}");
    }
    println!();
    let (ms, ss) = mean_sd(&sph);
    let (mc, sc) = mean_sd(&cor);
    println!(
        "spheres: mean check error {ms:.2} mm (sd over seeds {ss:.2}); |dt| {:.2} ± {:.2} mm; rotation error {:.3} ± {:.3}°  [{} seeds]",
        mean_sd(&dts).0,
        mean_sd(&dts).1,
        mean_sd(&drs).0,
        mean_sd(&drs).1,
        sph.len()
    );
    println!(
        "corner:  mean check error {mc:.2} mm (sd over seeds {sc:.2}); |dt| {:.1} ± {:.1} mm; rotation error {:.2} ± {:.2}°  [{} seeds]",
        mean_sd(&dtc).0,
        mean_sd(&dtc).1,
        mean_sd(&drc).0,
        mean_sd(&drc).1,
        cor.len()
    );
    let names = ["tx", "ty", "tz", "ω", "φ", "κ"];
    let mut s = String::from("spheres, error/σ per component: ");
    for (k, n) in names.iter().enumerate() {
        let v: Vec<f64> = zs.iter().map(|z| z[k]).filter(|x| x.is_finite()).collect();
        let rms = (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt();
        let within2 = v.iter().filter(|x| x.abs() <= 2.0).count();
        s += &format!("{n} rms {rms:.2} ({within2}/{} within 2σ); ", v.len());
    }
    println!("{s}");
    println!("paper (real data): spheres 10.4 mm (sd 4.5), corner 15.5 mm (sd 4.0)");
    if !failures.is_empty() {
        println!("failed seeds: {failures:?}");
    }
}
