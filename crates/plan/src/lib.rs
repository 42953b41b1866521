//! Pre-analysis of a planned field (`pingcal plan`): before a hole is drilled, the planned
//! field (the simulator's configuration: room, targets, balls, distances, stations, camera,
//! LRF) is simulated with `N` seeds and each simulation is calibrated by the whole pipeline
//! ([`pingcal_sim::Simulation`] written as a project, then [`pingcal_pipeline::calibrate`],
//! in a temporary folder removed at the end). [`study`] gives a [`Plan`]:
//!
//! - the **predicted σ** of the extrinsic (tx, ty, tz in mm, ω, φ, κ in degrees) and of the
//!   ball centres (camera side): the RMS over the seeds of the σ's each calibration reports,
//!   with its σ0 as estimated;
//! - beside them the **Monte Carlo** RMS of the true errors over the seeds (the simulator
//!   knows the truth), and their ratio: about 1 when the σ's are honest, with the band an
//!   honest σ gives for that many seeds ([`honest_ratio_band`]);
//! - the **check error to expect**: the mean of `E|dᵢ|` from each check ball's predicted
//!   covariance ([`pingcal_pipeline::verdict::expected_check_error_mm`]), beside the mean
//!   check error the simulations gave;
//! - **what matters most**: each non-main station and each measured distance removed in
//!   turn from the same simulated data (the first seeds, the same for every variant, so the
//!   comparison is paired), ranked by how much the extrinsic's translation σ (`√trace`)
//!   grows; a removal that breaks the calibration ranks first.
//!
//! Every random choice is seeded: the same configuration and seeds give the same [`Plan`].
//! A seed that fails is counted and its reason given. [`table`] is the plan as `pingcal
//! plan` prints it.

use pingcal_pipeline::{self as pipeline, Outcome, Reporter};
use pingcal_project::Project;
use pingcal_sim::project_files::PoseJson;
use rayon::prelude::*;
use serde::Serialize;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Why a plan could not be made: one line.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct PlanError(pub String);

/// What to study: the planned field and the seeds.
#[derive(Clone, Debug)]
pub struct PlanSpec {
    /// The planned field.
    pub config: pingcal_sim::SimConfig,
    /// The file it was read from (named in errors and in the plan); None: the paper's field.
    pub config_file: Option<PathBuf>,
    /// The seeds simulated (each simulated and calibrated).
    pub seeds: Vec<u64>,
    /// The seeds (among `seeds`) each removal is calibrated with; empty: no removals.
    pub sensitivity_seeds: Vec<u64>,
    /// Worker threads (0: all cores).
    pub threads: usize,
}

/// What one removal takes out of the project.
#[derive(Clone, Debug)]
enum Removed {
    /// Every image of a station.
    Station(String),
    /// One measured distance (its index in the project).
    Distance(usize),
}

/// One calibration of one seed, against the truth.
#[derive(Clone, Debug, Serialize)]
pub struct SeedRun {
    /// The seed.
    pub seed: u64,
    /// The method whose extrinsic is the one given (`joint`, `spheres`, `corner`).
    pub method: String,
    /// `ok`, `doubtful`, `failed`.
    pub verdict: String,
    /// Reported σ of the extrinsic's translation (mm).
    pub sigma_translation_mm: [f64; 3],
    /// Reported σ of ω, φ, κ (degrees).
    pub sigma_rotation_deg: [f64; 3],
    /// Estimated − true translation (mm).
    pub error_translation_mm: [f64; 3],
    /// Estimated − true ω, φ, κ (degrees).
    pub error_rotation_deg: [f64; 3],
    /// RMS over the balls of the reported σ of the camera-side centres, X Y Z (mm).
    pub ball_sigma_mm: [f64; 3],
    /// RMS over the balls of the camera-side centres' true errors, X Y Z (mm).
    pub ball_error_mm: [f64; 3],
    /// The mean check error the reported covariances predict (mm).
    pub expected_check_error_mm: Option<f64>,
    /// The mean check error of the calibration (mm).
    pub mean_check_error_mm: f64,
    /// Check balls in the mean.
    pub check_balls: usize,
    /// σ0 of the bundle adjustment.
    pub bundle_sigma0: f64,
}

/// A seed that did not calibrate.
#[derive(Clone, Debug, Serialize)]
pub struct SeedFailure {
    /// The seed.
    pub seed: u64,
    /// Why.
    pub error: String,
}

/// Predicted σ and Monte Carlo RMS error of one component.
#[derive(Clone, Debug, Serialize)]
pub struct Component {
    /// `tx`, `ty`, `tz` (mm), `omega`, `phi`, `kappa` (degrees), `ball X` ... (mm).
    pub name: String,
    /// RMS over the seeds of the reported σ.
    pub predicted_sigma: f64,
    /// RMS over the seeds of the true error (None with fewer than 2 seeds).
    pub monte_carlo_rms_error: Option<f64>,
    /// Monte Carlo / predicted.
    pub ratio: Option<f64>,
    /// Whether the ratio lies in the band an honest σ gives with this many seeds
    /// ([`honest_ratio_band`], 95 %); None with fewer than 2 seeds.
    pub consistent_with_honest_sigma: Option<bool>,
}

/// The central 95 % of the ratio (RMS true error / RMS predicted σ) over `n` seeds when the
/// predicted σ's are exact: `√(χ²ₙ(p) / n)` at p = 0.025 and 0.975
/// ([`pingcal_pipeline::verdict::chi2_quantile`]). With 20 seeds it is 0.69–1.31: a 20-seed
/// ratio alone cannot tell an honest σ from one 20 % off. None below 5 seeds (too few to
/// judge, and the approximation of χ² too coarse).
pub fn honest_ratio_band(n: usize) -> Option<[f64; 2]> {
    if n < 5 {
        return None;
    }
    let n = n as f64;
    let q = |z: f64| (pingcal_pipeline::verdict::chi2_quantile(n, z) / n).sqrt();
    Some([q(-1.959964), q(1.959964)])
}

/// One removal's effect, paired with the plan on the same seeds.
#[derive(Clone, Debug, Serialize)]
pub struct Sensitivity {
    /// `station S03`, `distance 2 (3–17)`.
    pub removed: String,
    /// Mean over the seeds of σ(removed)/σ(plan) of the translation (√trace).
    pub translation_sigma_growth: Option<f64>,
    /// The same for ω φ κ.
    pub rotation_sigma_growth: Option<f64>,
    /// The same for the ball centres' σ (camera side, RMS over the balls).
    pub ball_sigma_growth: Option<f64>,
    /// The same for the expected check error.
    pub check_error_growth: Option<f64>,
    /// Why a calibration without it failed (it then ranks first).
    pub failed: Option<String>,
}

/// `plan.json`.
#[derive(Clone, Debug, Serialize)]
pub struct Plan {
    /// What wrote it.
    pub generator: String,
    /// The configuration file, or `default` (the paper's field).
    pub config: String,
    /// The seeds simulated.
    pub seeds: Vec<u64>,
    /// Stations (main first), distances, balls and check balls of the first simulation.
    pub stations: Vec<String>,
    /// Measured distances.
    pub distances: usize,
    /// Balls.
    pub balls: usize,
    /// Check balls.
    pub check_balls: usize,
    /// Seeds that calibrated.
    pub calibrated: usize,
    /// Seeds that failed, with why.
    pub failures: Vec<SeedFailure>,
    /// The extrinsic: tx ty tz (mm), ω φ κ (degrees).
    pub extrinsic: Vec<Component>,
    /// The ball centres (camera side): X Y Z (mm).
    pub ball_centres: Vec<Component>,
    /// Mean over the seeds of the expected mean check error (mm).
    pub expected_check_error_mm: Option<f64>,
    /// Mean over the seeds of the calibrations' mean check error (mm).
    pub mean_check_error_mm: Option<f64>,
    /// Its standard deviation over the seeds (mm).
    pub sd_check_error_mm: Option<f64>,
    /// The seeds each removal was calibrated with.
    pub sensitivity_seeds: Vec<u64>,
    /// Removals, most harmful first.
    pub sensitivity: Vec<Sensitivity>,
    /// Every calibration of the plan as given.
    pub runs: Vec<SeedRun>,
}

/// `project` without what `removed` names (the same data otherwise).
fn without(project: &Project, removed: &Removed) -> Project {
    let mut p = project.clone();
    match removed {
        Removed::Station(id) => {
            let keep: Vec<bool> = p.file.images.iter().map(|im| &im.station != id).collect();
            let mut k = keep.iter();
            p.file
                .images
                .retain(|_| *k.next().expect("one flag per image"));
            let mut k = keep.iter();
            p.image_paths
                .retain(|_| *k.next().expect("one flag per image"));
            // a fixed LRF's scans at the station go with its images
            let lrf = &p.file.lrf;
            let keep: Vec<bool> = (lrf.scans.iter())
                .map(|s| s.station(&lrf.station) != id.as_str())
                .collect();
            let mut k = keep.iter();
            p.file
                .lrf
                .scans
                .retain(|_| *k.next().expect("one flag per scan"));
            let mut k = keep.iter();
            p.scans.retain(|_| *k.next().expect("one flag per scan"));
        }
        Removed::Distance(i) => {
            p.file.distances.remove(*i);
        }
    }
    p
}

/// The label of a removal in `project`.
fn label(project: &Project, removed: &Removed) -> String {
    match removed {
        Removed::Station(id) => format!("station {id}"),
        Removed::Distance(i) => {
            let d = &project.file.distances[*i];
            format!("distance {} ({}–{})", i + 1, d.from, d.to)
        }
    }
}

fn norm3(v: &[f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// `a − b` of two angles in degrees, in (−180, 180].
fn angle_diff(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(360.0);
    if d > 180.0 {
        d - 360.0
    } else {
        d
    }
}

/// One calibration against the truth, or why it cannot be judged.
fn judge_run(seed: u64, o: &Outcome, truth: &pingcal_sim::Truth) -> Result<SeedRun, String> {
    let r = &o.results;
    let e = &r.extrinsic;
    let (Some(st), Some(sr)) = (e.sigma_translation_mm, e.sigma_rotation_deg) else {
        return Err("the calibration reported no σ for its extrinsic".into());
    };
    let te = &truth.extrinsic_as_calibrated();
    let error_translation_mm = std::array::from_fn(|k| e.translation_mm[k] - te.translation_mm[k]);
    let error_rotation_deg = std::array::from_fn(|k| angle_diff(e.opk_deg[k], te.opk_deg[k]));
    let (mut s2, mut e2, mut n) = ([0.0; 3], [0.0; 3], 0usize);
    for b in &r.balls {
        let Some(t) = truth.balls.iter().find(|t| t.id == b.id) else {
            continue;
        };
        for k in 0..3 {
            s2[k] += b.photogrammetric_sigma_mm[k].powi(2);
            e2[k] += (b.photogrammetric_mm[k] - t.photogrammetric_mm[k]).powi(2);
        }
        n += 1;
    }
    if n == 0 {
        return Err("no ball of the calibration is in the truth".into());
    }
    let rms = |v: [f64; 3]| v.map(|x| (x / n as f64).sqrt());
    let method = r
        .methods
        .iter()
        .find(|m| m.extrinsic.as_ref().map(|x| x.translation_mm) == Some(e.translation_mm))
        .map_or_else(|| "?".into(), |m| m.method.clone());
    Ok(SeedRun {
        seed,
        method,
        verdict: r.verdict.status.as_str().into(),
        sigma_translation_mm: st,
        sigma_rotation_deg: sr,
        error_translation_mm,
        error_rotation_deg,
        ball_sigma_mm: rms(s2),
        ball_error_mm: rms(e2),
        expected_check_error_mm: o.expected_check_error_mm,
        mean_check_error_mm: r.mean_check_error_mm,
        check_balls: r.check_points.len(),
        bundle_sigma0: r.bundle.sigma0,
    })
}

/// One simulated seed: its project and truth (in `dir`), and the plan's calibration.
struct Simulated {
    seed: u64,
    project: Project,
    truth: pingcal_sim::Truth,
    run: Result<SeedRun, String>,
}

/// Simulates `seed` into `dir` and calibrates it.
fn simulate_and_calibrate(
    dir: &Path,
    cfg: &pingcal_sim::SimConfig,
    config_file: Option<&Path>,
    seed: u64,
    opts: &pipeline::Options,
) -> Result<Simulated, String> {
    let sim = pingcal_sim::Simulation::new(cfg, seed).map_err(|e| match config_file {
        Some(p) if matches!(e, pingcal_sim::SimError::Invalid(_)) => {
            format!("{}: {e}", p.display())
        }
        _ => e.to_string(),
    })?;
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: cannot create: {e}", dir.display()))?;
    pingcal_sim::write_project(&sim, dir).map_err(|e| e.to_string())?;
    let project = Project::load(&dir.join("project.toml")).map_err(|e| e.to_string())?;
    let truth = pingcal_sim::read_truth(&dir.join("truth.json")).map_err(|e| e.to_string())?;
    let opts = pipeline::Options {
        seed,
        ..opts.clone()
    };
    let run = pipeline::calibrate(&project, &opts, &Reporter::silent())
        .map_err(|e| e.to_string())
        .and_then(|o| judge_run(seed, &o, &truth));
    Ok(Simulated {
        seed,
        project,
        truth,
        run,
    })
}

/// RMS of `f` over `runs`.
fn rms_of(runs: &[&SeedRun], f: impl Fn(&SeedRun) -> f64) -> f64 {
    (runs.iter().map(|r| f(r).powi(2)).sum::<f64>() / runs.len() as f64).sqrt()
}

fn component(
    name: &str,
    runs: &[&SeedRun],
    sigma: impl Fn(&SeedRun) -> f64,
    err: impl Fn(&SeedRun) -> f64,
) -> Component {
    let predicted_sigma = rms_of(runs, sigma);
    let mc = (runs.len() >= 2).then(|| rms_of(runs, err));
    let ratio = mc.map(|m| m / predicted_sigma);
    let band = honest_ratio_band(runs.len());
    Component {
        name: name.into(),
        predicted_sigma,
        monte_carlo_rms_error: mc,
        ratio,
        consistent_with_honest_sigma: ratio.zip(band).map(|(r, [lo, hi])| (lo..=hi).contains(&r)),
    }
}

fn mean(v: &[f64]) -> Option<f64> {
    (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
}

/// Mean over the paired seeds of `f(variant) / f(plan)`.
fn growth(pairs: &[(&SeedRun, &SeedRun)], f: impl Fn(&SeedRun) -> Option<f64>) -> Option<f64> {
    let v: Vec<f64> = pairs
        .iter()
        .filter_map(|(base, var)| Some(f(var)? / f(base)?))
        .filter(|g| g.is_finite())
        .collect();
    mean(&v)
}

/// The simulations of a plan, removed with their folder when dropped.
struct TempRoot(PathBuf);

impl Drop for TempRoot {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// The planned field with `spec`'s seeds: simulated, calibrated and judged against the
/// truth ([module docs](crate)). Progress goes to `rep`.
pub fn study(spec: &PlanSpec, rep: &Reporter) -> Result<Plan, PlanError> {
    let config_name = spec.config_file.as_ref().map_or_else(
        || "the paper's field (default)".to_string(),
        |p| p.display().to_string(),
    );
    if spec.seeds.is_empty() {
        return Err(PlanError("no seeds: expected at least 1 (each seed is one simulated calibration; 2 or more for the Monte Carlo spread)".into()));
    }
    let stations = &spec.config.stations;
    if stations.convergent + stations.extra.len() == 0 {
        return Err(PlanError(format!(
            "{config_name}: stations.convergent = 0 and no stations.extra: only the main station would photograph the field, which cannot calibrate the camera nor place the balls (give three or more convergent stations, docs/field.md §6)"
        )));
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(spec.threads)
        .build()
        .map_err(|e| PlanError(format!("threads {}: {e}", spec.threads)))?;
    let root = TempRoot(std::env::temp_dir().join(format!("pingcal-plan-{}", std::process::id())));
    let _ = std::fs::remove_dir_all(&root.0);
    std::fs::create_dir_all(&root.0)
        .map_err(|e| PlanError(format!("{}: cannot create: {e}", root.0.display())))?;
    let opts = pipeline::Options {
        threads: spec.threads,
        ..pipeline::Options::default()
    };
    rep.log(format!(
        "simulating and calibrating {} seed(s) of {config_name}",
        spec.seeds.len()
    ));
    let sims = pool.install(|| simulate_all(spec, &root.0, &opts, rep));
    let (runs, failures) = split_runs(&sims);
    let Some(first) = sims.iter().find_map(|s| s.as_ref().ok()) else {
        return Err(PlanError(format!(
            "{config_name}: no seed could be simulated ({})",
            failures.first().map_or("", |f| f.error.as_str())
        )));
    };
    if runs.is_empty() {
        return Err(PlanError(format!(
            "{config_name}: none of the {} simulations calibrated, so the field as planned gives no extrinsic; seed {}: {}",
            spec.seeds.len(),
            failures[0].seed,
            failures[0].error
        )));
    }
    let bases: Vec<&Simulated> = sims
        .iter()
        .filter_map(|s| s.as_ref().ok())
        .filter(|s| spec.sensitivity_seeds.contains(&s.seed) && s.run.is_ok())
        .collect();
    let station_ids = station_ids(&first.project);
    let sensitivity =
        pool.install(|| remove_each(&first.project, &station_ids, &bases, &opts, rep));
    let sensitivity_seeds = bases.iter().map(|b| b.seed).collect();
    let distances = first.project.file.distances.len();
    let balls = first.truth.balls.len();
    let check_balls = first.truth.balls.iter().filter(|b| b.check).count();
    drop(root); // the simulations are no longer needed
    let summary = summarize(&runs);
    Ok(Plan {
        generator: format!("pingcal plan {}", env!("CARGO_PKG_VERSION")),
        config: spec
            .config_file
            .as_ref()
            .map_or_else(|| "default".into(), |p| p.display().to_string()),
        seeds: spec.seeds.clone(),
        stations: station_ids,
        distances,
        balls,
        check_balls,
        calibrated: runs.len(),
        failures,
        extrinsic: summary.extrinsic,
        ball_centres: summary.ball_centres,
        expected_check_error_mm: summary.expected_check_error_mm,
        mean_check_error_mm: summary.mean_check_error_mm,
        sd_check_error_mm: summary.sd_check_error_mm,
        sensitivity_seeds,
        sensitivity,
        runs,
    })
}

/// Every seed of `spec` simulated into `root` and calibrated, in parallel; the folders of
/// the seeds the removals need are kept.
fn simulate_all(
    spec: &PlanSpec,
    root: &Path,
    opts: &pipeline::Options,
    rep: &Reporter,
) -> Vec<Result<Simulated, SeedFailure>> {
    let bar = rep.task("simulate + calibrate", spec.seeds.len() as u64);
    let sims = spec
        .seeds
        .par_iter()
        .map(|&seed| {
            let dir = root.join(format!("seed{seed}"));
            let r =
                simulate_and_calibrate(&dir, &spec.config, spec.config_file.as_deref(), seed, opts)
                    .map_err(|error| SeedFailure { seed, error });
            if !spec.sensitivity_seeds.contains(&seed) {
                let _ = std::fs::remove_dir_all(&dir);
            }
            bar.advance(1);
            r
        })
        .collect();
    bar.finish();
    sims
}

/// The calibrations that could be judged, and the seeds that failed (with why).
fn split_runs(sims: &[Result<Simulated, SeedFailure>]) -> (Vec<SeedRun>, Vec<SeedFailure>) {
    let mut failures = Vec::new();
    let mut runs = Vec::new();
    for s in sims {
        match s {
            Ok(s) => match &s.run {
                Ok(r) => runs.push(r.clone()),
                Err(error) => failures.push(SeedFailure {
                    seed: s.seed,
                    error: error.clone(),
                }),
            },
            Err(f) => failures.push(f.clone()),
        }
    }
    (runs, failures)
}

/// The stations of `project`, the main one first, the others in order.
fn station_ids(project: &Project) -> Vec<String> {
    let main = &project.file.main_station;
    let mut stations: Vec<String> = Vec::new();
    for im in &project.file.images {
        if !stations.contains(&im.station) {
            stations.push(im.station.clone());
        }
    }
    stations.sort_by_key(|s| (s != main, s.clone()));
    stations
}

/// Each non-main station and each distance removed in turn from the `bases`' data and
/// calibrated again: the growth of the σ's, most harmful first.
fn remove_each(
    first: &Project,
    stations: &[String],
    bases: &[&Simulated],
    opts: &pipeline::Options,
    rep: &Reporter,
) -> Vec<Sensitivity> {
    if bases.is_empty() {
        return Vec::new();
    }
    let main = &first.file.main_station;
    let mut removals: Vec<Removed> = stations
        .iter()
        .filter(|s| *s != main)
        .map(|s| Removed::Station(s.clone()))
        .collect();
    removals.extend((0..first.file.distances.len()).map(Removed::Distance));
    let jobs: Vec<(usize, &Simulated)> = (0..removals.len())
        .flat_map(|k| bases.iter().map(move |b| (k, *b)))
        .collect();
    rep.log(format!(
        "removing each of {} stations and {} distances in turn (seed {})",
        stations.len() - 1,
        first.file.distances.len(),
        bases
            .iter()
            .map(|b| b.seed.to_string())
            .collect::<Vec<_>>()
            .join(", ")
    ));
    let bar = rep.task("remove each and see", jobs.len() as u64);
    let results: Vec<Result<SeedRun, String>> = jobs
        .par_iter()
        .map(|(k, s)| {
            let r = calibrate_without(s, &removals[*k], opts);
            bar.advance(1);
            r
        })
        .collect();
    bar.finish();
    let mut sensitivity: Vec<Sensitivity> = removals
        .iter()
        .enumerate()
        .map(|(k, removed)| {
            let mut pairs = Vec::new();
            let mut failed = None;
            for ((j, s), r) in jobs.iter().zip(&results) {
                if *j != k {
                    continue;
                }
                match (r, &s.run) {
                    (Ok(v), Ok(b)) => pairs.push((b, v)),
                    (Err(e), _) => failed = Some(format!("seed {}: {e}", s.seed)),
                    _ => {}
                }
            }
            Sensitivity {
                removed: label(first, removed),
                translation_sigma_growth: growth(&pairs, |r| Some(norm3(&r.sigma_translation_mm))),
                rotation_sigma_growth: growth(&pairs, |r| Some(norm3(&r.sigma_rotation_deg))),
                ball_sigma_growth: growth(&pairs, |r| Some(norm3(&r.ball_sigma_mm))),
                check_error_growth: growth(&pairs, |r| r.expected_check_error_mm),
                failed,
            }
        })
        .collect();
    // most harmful first: a removal that breaks the calibration, then by the growth of the
    // translation's σ (stable: ties keep the stations' and distances' order)
    sensitivity.sort_by(|a, b| {
        let key = |s: &Sensitivity| {
            if s.failed.is_some() {
                f64::INFINITY
            } else {
                s.translation_sigma_growth.unwrap_or(0.0)
            }
        };
        key(b).total_cmp(&key(a))
    });
    sensitivity
}

/// `s`'s data without what `removed` names, calibrated and judged.
fn calibrate_without(
    s: &Simulated,
    removed: &Removed,
    opts: &pipeline::Options,
) -> Result<SeedRun, String> {
    match removed {
        Removed::Distance(i) if *i >= s.project.file.distances.len() => {
            Err("this seed has fewer distances".to_string())
        }
        removed => {
            let p = without(&s.project, removed);
            let opts = pipeline::Options {
                seed: s.seed,
                ..opts.clone()
            };
            pipeline::calibrate(&p, &opts, &Reporter::silent())
                .map_err(|e| e.to_string())
                .and_then(|o| judge_run(s.seed, &o, &s.truth))
        }
    }
}

/// The plan's numbers over the calibrations that could be judged.
struct Summary {
    extrinsic: Vec<Component>,
    ball_centres: Vec<Component>,
    expected_check_error_mm: Option<f64>,
    mean_check_error_mm: Option<f64>,
    sd_check_error_mm: Option<f64>,
}

/// The predicted σ's beside the Monte Carlo errors, and the check errors, over `runs`.
fn summarize(runs: &[SeedRun]) -> Summary {
    let ok: Vec<&SeedRun> = runs.iter().collect();
    let names = ["tx mm", "ty mm", "tz mm", "ω deg", "φ deg", "κ deg"];
    let extrinsic: Vec<Component> = (0..6)
        .map(|k| {
            if k < 3 {
                component(
                    names[k],
                    &ok,
                    |r| r.sigma_translation_mm[k],
                    |r| r.error_translation_mm[k],
                )
            } else {
                component(
                    names[k],
                    &ok,
                    |r| r.sigma_rotation_deg[k - 3],
                    |r| r.error_rotation_deg[k - 3],
                )
            }
        })
        .collect();
    let ball_centres: Vec<Component> = ["ball X mm", "ball Y mm", "ball Z mm"]
        .iter()
        .enumerate()
        .map(|(k, n)| component(n, &ok, |r| r.ball_sigma_mm[k], |r| r.ball_error_mm[k]))
        .collect();
    let expected: Vec<f64> = ok
        .iter()
        .filter_map(|r| r.expected_check_error_mm)
        .collect();
    let checks: Vec<f64> = ok
        .iter()
        .filter(|r| r.check_balls > 0)
        .map(|r| r.mean_check_error_mm)
        .collect();
    let mean_check = mean(&checks);
    let sd_check = mean_check.filter(|_| checks.len() > 1).map(|m| {
        (checks.iter().map(|c| (c - m).powi(2)).sum::<f64>() / (checks.len() - 1) as f64).sqrt()
    });
    Summary {
        extrinsic,
        ball_centres,
        expected_check_error_mm: mean(&expected),
        mean_check_error_mm: mean_check,
        sd_check_error_mm: sd_check,
    }
}

fn opt(v: Option<f64>, p: usize) -> String {
    v.map_or_else(|| "—".into(), |x| format!("{x:.p$}"))
}

/// The plan as the table printed on stdout.
pub fn table(p: &Plan) -> String {
    let mut s = String::new();
    let f = p.failures.len();
    s += &format!(
        "plan: {}: {} seed(s) from {}, {} calibrated, {} failed; {} stations, {} distances, {} balls ({} check)\n",
        p.config,
        p.seeds.len(),
        p.seeds[0],
        p.calibrated,
        f,
        p.stations.len(),
        p.distances,
        p.balls,
        p.check_balls
    );
    for x in &p.failures {
        s += &format!("  failed: seed {}: {}\n", x.seed, x.error);
    }
    s += &format!(
        "\n{:<12} {:>12} {:>22} {:>7}\n",
        "", "predicted σ", "Monte Carlo RMS error", "ratio"
    );
    for c in p.extrinsic.iter().chain(&p.ball_centres) {
        let prec = if c.name.contains("deg") { 4 } else { 3 };
        s += &format!(
            "{:<12} {:>12} {:>22} {:>7}{}\n",
            c.name,
            format!("{:.prec$}", c.predicted_sigma),
            opt(c.monte_carlo_rms_error, prec),
            opt(c.ratio, 2),
            match c.consistent_with_honest_sigma {
                Some(false) => "  outside the honest band",
                _ => "",
            }
        );
    }
    if let Some([lo, hi]) = honest_ratio_band(p.calibrated) {
        s += &format!(
            "(with honest σ's the ratio over {} seeds lies in {lo:.2}–{hi:.2}, 95 %; more seeds narrow it)\n",
            p.calibrated
        );
    }
    s += &format!(
        "\ncheck balls: expected mean error {} mm (from the predicted covariances); the simulations gave {} mm (sd {} over {} seeds)\n",
        opt(p.expected_check_error_mm, 2),
        opt(p.mean_check_error_mm, 2),
        opt(p.sd_check_error_mm, 2),
        p.calibrated
    );
    let st = (p.extrinsic[..3]
        .iter()
        .map(|c| c.predicted_sigma.powi(2))
        .sum::<f64>())
    .sqrt();
    let sr = (p.extrinsic[3..]
        .iter()
        .map(|c| c.predicted_sigma.powi(2))
        .sum::<f64>())
    .sqrt();
    s += &format!(
        "this field should give about {} mm at the check balls (extrinsic σ {st:.2} mm, {sr:.3}°)\n",
        opt(p.expected_check_error_mm.or(p.mean_check_error_mm), 1)
    );
    if !p.sensitivity.is_empty() {
        s += &format!(
            "\nremove each and see (seed {}): σ without it / σ with it\n{:<24} {:>11} {:>9} {:>13} {:>12}\n",
            p.sensitivity_seeds
                .iter()
                .map(|x| x.to_string())
                .collect::<Vec<_>>()
                .join(", "),
            "removed",
            "translation",
            "rotation",
            "ball centres",
            "check error"
        );
        for x in &p.sensitivity {
            match &x.failed {
                Some(e) => s += &format!("{:<24} breaks the calibration: {e}\n", x.removed),
                None => {
                    s += &format!(
                        "{:<24} {:>11} {:>9} {:>13} {:>12}\n",
                        x.removed,
                        opt(x.translation_sigma_growth, 3),
                        opt(x.rotation_sigma_growth, 3),
                        opt(x.ball_sigma_growth, 3),
                        opt(x.check_error_growth, 3)
                    )
                }
            }
        }
    }
    s
}

/// The demo's tables (the paper's Table 4 of check points for every method, with the
/// check errors the true extrinsic gives on the same measured centres; each method's
/// extrinsic against the truth; the bundle and the verdict), as `pingcal demo` prints them.
/// The truth's extrinsic is the one a calibration defines
/// ([`pingcal_sim::Truth::extrinsic_as_calibrated`]).
pub fn against_truth(r: &pipeline::results::Results, truth: &pingcal_sim::Truth) -> String {
    let te: PoseJson = truth.extrinsic_as_calibrated();
    let mut s = check_table(r, &te);
    s += &extrinsic_table(r, &te);
    s += &bundle_and_verdict(r);
    s
}

/// The paper's Table 4 for every method, with the check errors the true extrinsic `te`
/// gives on the same measured centres (the floor the measurement noise sets).
fn check_table(r: &pipeline::results::Results, te: &PoseJson) -> String {
    let mut s = String::new();
    s.push('\n');
    let _ = writeln!(
        s,
        "Table 4 — check points (mm); dx = estimated − reference (photogrammetric)"
    );
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
    let _ = writeln!(s, "{header}");
    let mut sub = format!("{:<6}", "");
    for _ in &r.methods {
        sub += &format!(" | {:>7}{:>7}{:>7}{:>8}", "dx", "dy", "dz", "error");
    }
    sub += &format!(" | {:>14}", "error");
    let _ = writeln!(s, "{sub}");
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
        let _ = writeln!(s, "{line}");
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
    let _ = writeln!(s, "{mean}");
    s
}

/// Each method's extrinsic, with its σ, beside the truth `te`.
fn extrinsic_table(r: &pipeline::results::Results, te: &PoseJson) -> String {
    let mut s = String::new();
    s.push('\n');
    let _ = writeln!(s, "Extrinsic (p_camera = R p_lrf + t) against the truth (the LRF frame's origin on the servo axis at the scan plane, as a calibration defines it)");
    let _ = writeln!(
        s,
        "{:<9} {:>26} {:>22} {:>9} {:>26} {:>9} {:>14}",
        "", "t (mm)", "σ t (mm)", "|Δt| mm", "ω φ κ (°)", "ΔR (°)", "σ ω φ κ (°)"
    );
    let tt = te.translation_mm;
    let _ = writeln!(
        s,
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
            let _ = writeln!(
                s,
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
        let _ = writeln!(
            s,
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
    s
}

/// The bundle's figures and the verdict with its reasons and notes.
fn bundle_and_verdict(r: &pipeline::results::Results) -> String {
    let mut s = String::new();
    let b = &r.bundle;
    let _ = writeln!(
        s,
        "bundle: sigma0 {:.3}, RMS {:.3} px, {} images, {} points, {} image points ({} rejected)",
        b.sigma0, b.rms_image_px, b.images, b.points, b.observations, b.rejected
    );
    let v = &r.verdict;
    let _ = writeln!(s, "verdict: {}", v.status.as_str());
    for reason in &v.reasons {
        let _ = writeln!(s, "  - {reason}");
    }
    for note in &v.notes {
        let _ = writeln!(s, "  note: {note}");
    }
    s
}

#[cfg(test)]
mod tests {
    use super::honest_ratio_band;

    /// Against the exact χ² quantiles (n = 5, 10, 20, 60: 0.8312/12.833, 3.2470/20.483,
    /// 9.5908/34.170, 40.482/83.298), to 2.5 % at n = 5 and 1 % from n = 10.
    #[test]
    fn the_honest_band_matches_the_chi_square_quantiles() {
        for (n, lo, hi) in [
            (5usize, 0.831_21, 12.832_5),
            (10, 3.247_0, 20.483_2),
            (20, 9.590_8, 34.169_6),
            (60, 40.481_7, 83.297_7),
        ] {
            let [a, b] = honest_ratio_band(n).unwrap();
            let exact = [(lo / n as f64).sqrt(), (hi / n as f64).sqrt()];
            let tol = if n < 10 { 0.025 } else { 0.01 };
            assert!(
                (a / exact[0] - 1.0).abs() < tol,
                "n {n}: {a} against {}",
                exact[0]
            );
            assert!(
                (b / exact[1] - 1.0).abs() < tol,
                "n {n}: {b} against {}",
                exact[1]
            );
        }
        assert!(honest_ratio_band(4).is_none());
    }
}
