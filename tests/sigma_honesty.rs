//! Are the reported σ's honest? `pingcal plan` simulates a field with many seeds, calibrates
//! each and gives, per component of the extrinsic and of the ball centres, the RMS over the
//! seeds of the true errors beside the RMS of the σ's each calibration reported (issue 18:
//! within 20 %; issue 13: RMS of error/σ in 0.8–1.25).
//!
//! The bounds are statistics, not a tuning: for honest σ's, `n·z²` with `z` the RMS over n
//! seeds of error/σ is about χ²(n), so `z` lies in `[√(χ²_{α/2}(n)/n), √(χ²_{1−α/2}(n)/n)]`
//! with probability 1 − α. Per component that interval is wide for a handful of seeds (its
//! relative standard error is `1/√(2n)`, 16 % for 20 seeds, so even perfectly honest σ's
//! leave a 20-seed component outside 0.8–1.25 one time in six); pooled over the six
//! extrinsic components of every seed (6n values, the components of one seed taken as
//! independent, which they nearly are after whitening by their own σ) it is narrow enough to
//! tell the σ's before the variance components (the pooled ratio was 1.36 on the paper's
//! field) from honest ones.
//!
//! `fast` (run always, about two minutes on two busy cores): 10 seeds of a small field
//! (seed 5 of which finds no ball in two images and is left out), α = 1 %.
//! `paper_field_20_seeds` (ignored: about 6 minutes on two idle cores) is issue 18's own
//! measurement, `bash bench/plan/run.sh 20` as a test:
//! `cargo test --release -p pingcal --test cli sigma_honesty:: -- --ignored`. It does not pass yet:
//! per component it does (tx 1.11, ty 1.17, tz 1.30, ω 1.36, φ 1.03, κ 1.10 against
//! [0.61, 1.41]), pooled it gives 1.185 against [0.79, 1.17] (1.40 before the variance
//! components): what is left is on the LRF side (some balls' sphere centres are off by more
//! than their σ in every seed, an error of the fit that the beams' scatter does not show).

use pingcal_pipeline::verdict::chi2_quantile;
use serde_json::Value;
use std::path::PathBuf;
use std::process::Command;
use std::sync::OnceLock;

// The small field: five convergent stations, half the supersampling, a 0.35° servo step.
use crate::common::SMALL_FIELD;

/// Standard normal quantile of 0.995 (two-sided α = 1 %).
const Z: f64 = 2.575_829_303_549;

/// The interval of the RMS of `n` standard normal values that holds with probability 99 %.
fn rms_bounds(n: usize) -> (f64, f64) {
    let k = n as f64;
    (
        (chi2_quantile(k, -Z) / k).sqrt(),
        (chi2_quantile(k, Z) / k).sqrt(),
    )
}

fn num(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

/// Seeds of `fast`'s plan of the small field.
pub(crate) const FAST_SEEDS: usize = 10;

/// `pingcal plan --seeds 10 --no-sensitivity` of the small field, made once per test binary:
/// `fast`'s sample, and the planner test's evidence that a seed's calibration is the same in
/// any plan (`crate::plan`).
pub(crate) fn small_plan() -> &'static Value {
    static PLAN: OnceLock<Value> = OnceLock::new();
    PLAN.get_or_init(|| plan("small", Some(SMALL_FIELD), FAST_SEEDS))
}

/// Runs `pingcal plan --seeds n --no-sensitivity` (with `config`, None: the paper's field)
/// and returns plan.json.
fn plan(name: &str, config: Option<&str>, seeds: usize) -> Value {
    let d: PathBuf = std::env::temp_dir().join(format!(
        "pingcal-sigma-honesty-{name}-{}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    let mut args = vec!["plan".to_string()];
    if let Some(c) = config {
        std::fs::write(d.join("field.toml"), c).unwrap();
        args.extend(["--config".into(), "field.toml".into()]);
    }
    let seeds = seeds.to_string();
    args.extend(
        [
            "--seeds",
            &seeds,
            "--no-sensitivity",
            "--quiet",
            "--out",
            "plan.json",
        ]
        .map(String::from),
    );
    let out = Command::new(env!("CARGO_BIN_EXE_pingcal"))
        .args(&args)
        .current_dir(&d)
        .output()
        .expect("run pingcal");
    assert!(
        out.status.success(),
        "plan failed\nstdout: {}\nstderr: {}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let p: Value = serde_json::from_str(&std::fs::read_to_string(d.join("plan.json")).unwrap())
        .expect("plan.json is JSON");
    let _ = std::fs::remove_dir_all(&d);
    p
}

/// Every error / σ of the extrinsic (6 per seed).
fn whitened_errors(p: &Value) -> Vec<[f64; 6]> {
    p["runs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| {
            let e = |k: &str, s: &str, i: usize| num(&r[k][i]) / num(&r[s][i]);
            std::array::from_fn(|i| {
                if i < 3 {
                    e("error_translation_mm", "sigma_translation_mm", i)
                } else {
                    e("error_rotation_deg", "sigma_rotation_deg", i - 3)
                }
            })
        })
        .collect()
}

/// Checks per component and pooled that the RMS of error/σ of the extrinsic is within its
/// 99 % interval (the table is printed, and named on failure).
fn check(p: &Value, seeds: usize) {
    let runs = whitened_errors(p);
    // a seed of the small field may fail to calibrate (seed 5: no ball intersected), which
    // says nothing about the σ's of the others
    assert!(
        runs.len() + 1 >= seeds,
        "more than one seed failed: {}",
        p["failures"]
    );
    let seeds = runs.len();
    let names = ["tx", "ty", "tz", "ω", "φ", "κ"];
    let rms = |v: &mut dyn Iterator<Item = f64>| {
        let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x * x, n + 1));
        (s / n as f64).sqrt()
    };
    let per: Vec<f64> = (0..6)
        .map(|k| rms(&mut runs.iter().map(|r| r[k])))
        .collect();
    let pooled = rms(&mut runs.iter().flat_map(|r| r.iter().copied()));
    let table = format!(
        "RMS(error/σ) over {seeds} seeds: {}; pooled {pooled:.3}; ball centres (RMS error / RMS σ) {}",
        names
            .iter()
            .zip(&per)
            .map(|(n, z)| format!("{n} {z:.3}"))
            .collect::<Vec<_>>()
            .join(", "),
        p["ball_centres"]
            .as_array()
            .unwrap()
            .iter()
            .map(|c| format!("{} {:.3}", c["name"].as_str().unwrap(), num(&c["ratio"])))
            .collect::<Vec<_>>()
            .join(", ")
    );
    eprintln!("{table}");
    let (lo, hi) = rms_bounds(seeds);
    for (n, z) in names.iter().zip(&per) {
        assert!(
            (lo..=hi).contains(z),
            "{n}: RMS(error/σ) {z:.3} outside the 99 % interval [{lo:.3}, {hi:.3}] of honest σ's\n{table}"
        );
    }
    let (lo, hi) = rms_bounds(6 * seeds);
    assert!(
        (lo..=hi).contains(&pooled),
        "pooled RMS(error/σ) {pooled:.3} outside the 99 % interval [{lo:.3}, {hi:.3}] of honest σ's\n{table}"
    );
    // The ball centres' camera-side σ's are printed, not judged: their true errors are
    // still 1.2–1.7 times their σ (20 seeds of the paper's field: X 1.68, Y 1.68, Z 1.16)
    // though the balls' image group is weighted by its own σ0, because the error is
    // systematic (the depth Y of the centres comes out short in most balls of a seed: the
    // silhouette's eccentricity model, not its weight). It is 0.1–0.2 mm against the
    // extrinsic's 0.7–1 mm, so the extrinsic's σ's above hold regardless.
}

#[test]
fn wilson_hilferty_matches_tabulated_quantiles() {
    // tabulated χ² quantiles (k, p, value): within 1 % from 20 degrees of freedom, 3 % at 10
    for (k, z, want, tol) in [
        (20.0, -Z, 7.434, 0.01),
        (20.0, Z, 39.997, 0.01),
        (60.0, -Z, 35.534, 0.01),
        (120.0, Z, 163.648, 0.01),
        (10.0, -Z, 2.156, 0.03),
        (10.0, Z, 25.188, 0.01),
    ] {
        let got = chi2_quantile(k, z);
        assert!(
            (got / want - 1.0).abs() < tol,
            "χ²({k}) at z {z}: {got} against {want}"
        );
    }
}

#[test]
fn fast() {
    check(small_plan(), FAST_SEEDS);
}

#[test]
#[ignore = "about 6 minutes on two idle cores: cargo test --release -p pingcal --test cli sigma_honesty:: -- --ignored"]
fn paper_field_20_seeds() {
    let seeds = 20;
    check(&plan("paper", None, seeds), seeds);
}
