//! The whole calibration of one project, one file per step, in the order they run:
//!
//! | step | file | what it does |
//! |---|---|---|
//! | 1 | [`detect`] | targets (coded, plain) and ball silhouettes in every image, in parallel; image sizes checked against their cameras |
//! | 2 | [`network`] | the coded targets' image points → initial orientation of every image (relative start, resection, intersection, bundle), scaled by the distances, moved into the main image's frame |
//! | 3 | [`matching`] | plain targets and balls: known points projected into every image ("driveback"), new points by multi-image epipolar matching; balls told from targets by their size in millimetres |
//! | 4 | [`bundle`] | the final self-calibrating adjustment: distances, stereo rig, main image as datum, ball centres corrected for the sphere's eccentricity, data snooping, precision |
//! | 5 | [`lrf`] | the LRF cloud from the scans and the spheres fitted to the balls |
//! | 6 | [`extrinsic`] | spheres ↔ balls by distance invariants, the 3D conformal transform with σ, control / check / leave-one-out tables; the Fan et al. 2019 corner baseline |
//! | 7 | [`joint`] | the joint adjustment: image points, distances and the LRF beams on the balls together, the extrinsic and the LRF's mount and range errors among the unknowns, what the data cannot determine held and named |
//! | 7b | [`final_lrf`] | the LRF as the calibration's own model sees it: the cloud made again through the joint adjustment's estimated mount and range model, its spheres found and matched by the estimated extrinsic, the check tables from them; every output's LRF side uses it |
//! | 7c | [`verdict`] | whether to trust the calibration: `ok`, `doubtful` or `failed`, by statistical tests of every adjustment and of the check points |
//! | 8 | [`conventions`], [`results`], then [`report`] | `results.json` (SPEC.md; its `conventions` block names every frame and transform) and `cloud.ply`, then the data of `report.html` |
//! | 9 | [`rectify`], [`exports`] | the same numbers for ROS (tf commands, launch files, URDF joint), OpenCV (FileStorage YAML, stereo rectification as `stereoRectify` gives it) and Kalibr (camchain) |
//!
//! Below the steps lie the modules they share, lowest first: [`ids`] (typed ids and the
//! vector they index), [`progress`] (the [`Reporter`] and the [`Progress`] trait through
//! which the caller shows the progress: the library never prints), [`scene`] (the
//! [`scene::Scene`] that the steps pass along and refine, and the helpers they share) and
//! [`adjust`] (the scene as a bundle-adjustment problem and back, for every step that
//! adjusts). Each module uses only those before it, shared modules first, then the steps in
//! their order (`tests/pipeline_layers.rs` checks it).
//!
//! Every failure is a [`PipelineError`]: one line that names the file, image, target or ball
//! concerned and what was expected. Nothing is written until every step has succeeded.

pub mod adjust;
pub mod bundle;
pub mod conventions;
pub mod detect;
pub mod exports;
pub mod extrinsic;
pub mod final_lrf;
pub mod ids;
pub mod joint;
pub mod lrf;
pub mod matching;
pub mod network;
pub mod overlays;
pub mod progress;
pub mod rectify;
pub mod report;
pub mod results;
pub mod scene;
pub mod sphere_calib;
#[cfg(test)]
mod test_support;
pub mod verdict;

use pingcal_project::Project;
pub use progress::{Progress, Reporter, Task};

/// Why a calibration failed: one line.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct PipelineError(pub String);

impl PipelineError {
    /// An error from a message.
    pub fn new(msg: impl Into<String>) -> Self {
        Self(msg.into())
    }
}

/// Result of a pipeline step.
pub type Result<T> = std::result::Result<T, PipelineError>;

/// Settings of a run.
#[derive(Clone, Debug)]
pub struct Options {
    /// Seed of every random choice (RANSAC in the LRF steps).
    pub seed: u64,
    /// Worker threads of the bundle adjustments (0: all cores).
    pub threads: usize,
    /// Baarda's critical value for data snooping of image points (3.29: α = 0.1 %).
    pub snoop_critical: f64,
    /// How the initial network starts.
    pub start: network::Start,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            seed: 1,
            threads: 0,
            snoop_critical: 3.29,
            start: network::Start::Auto,
        }
    }
}

/// Everything a calibration produces.
pub struct Outcome {
    /// `results.json`.
    pub results: results::Results,
    /// The data of `report.html`.
    pub report: pingcal_report::ReportData,
    /// `cloud.ply` (the LRF cloud, and the fitted spheres as an element of their own).
    pub cloud_ply: Vec<u8>,
    /// The files of `ros/`, `opencv/` and `kalibr/` ([`exports`]): path below the output
    /// folder, text.
    pub exports: Vec<exports::OutputFile>,
    /// The mean check error the reported covariances predict
    /// ([`verdict::expected_check_error_mm`]; not in `results.json`): what `pingcal plan`
    /// averages.
    pub expected_check_error_mm: Option<f64>,
    /// The LRF drawn on the images ([`overlays`]): `overlays/<image>.png` below the output
    /// folder, and its bytes.
    pub overlays: Vec<(String, Vec<u8>)>,
}

/// Runs the whole calibration of `project`.
pub fn calibrate(project: &Project, opts: &Options, rep: &Reporter) -> Result<Outcome> {
    lrf::check_mount(project)?;
    let t0 = std::time::Instant::now();
    let dets = detect::detect_all(project, rep)?;
    let mut timing = vec![("detection".to_string(), t0.elapsed().as_secs_f64())];
    let t = std::time::Instant::now();
    let mut scene = network::initial_network(project, &dets, opts, rep)?;
    timing.push(("initial orientation".into(), t.elapsed().as_secs_f64()));
    let t = std::time::Instant::now();
    matching::add_points(project, &dets, &mut scene, opts, rep)?;
    timing.push(("matching".into(), t.elapsed().as_secs_f64()));
    let t = std::time::Instant::now();
    let mut adjusted = bundle::final_adjustment(project, &dets, &mut scene, opts, rep)?;
    adjusted.lens_doubt = verdict::lens_doubt(project, &adjusted);
    if let Some(w) = &adjusted.lens_doubt {
        rep.log(format!("warning: {w}"));
        scene.warnings.push(w.clone());
    }
    timing.push(("bundle adjustment".into(), t.elapsed().as_secs_f64()));
    // A step after the bundle that fails while the camera model cannot hold the lens most
    // likely fails because of it: the error says so.
    let blame_lens = |e: PipelineError| match &adjusted.lens_doubt {
        Some(d) => PipelineError(format!("{e}; but first: {d}")),
        None => e,
    };
    let t = std::time::Instant::now();
    let lrf = lrf::lrf_spheres(project, opts, rep).map_err(blame_lens)?;
    timing.push(("LRF spheres".into(), t.elapsed().as_secs_f64()));
    let t = std::time::Instant::now();
    let ext = extrinsic::extrinsics(project, &scene, &adjusted, &lrf, &dets, opts, rep)
        .map_err(blame_lens)?;
    timing.push(("extrinsic".into(), t.elapsed().as_secs_f64()));
    let t = std::time::Instant::now();
    let mut joint = if project.file.method.joint() {
        let r = run_joint(project, (&dets, &scene, &adjusted), &lrf, &ext, opts, rep);
        if let Err(e) = &r {
            rep.log(format!("joint adjustment failed: {e}"));
        }
        timing.push(("joint adjustment".into(), t.elapsed().as_secs_f64()));
        Some(r)
    } else {
        None
    };
    let remade = match &mut joint {
        Some(Ok(j)) => {
            let t = std::time::Instant::now();
            let check = &project.file.balls.check;
            let r = final_lrf::through_estimate(project, &lrf, &scene, check, j, opts, rep);
            timing.push(("LRF through the estimate".into(), t.elapsed().as_secs_f64()));
            r
        }
        _ => None,
    };
    let (lrf_out, pairs_out) = match &remade {
        Some(r) => (&r.lrf, &r.pairs[..]),
        None => (&lrf, &ext.pairs[..]),
    };
    let line = timing
        .iter()
        .map(|(n, s)| format!("{n} {s:.2} s"))
        .collect::<Vec<_>>()
        .join(", ");
    rep.log(format!("time: {line}"));
    let stages = Stages {
        project,
        dets: &dets,
        scene: &scene,
        adjusted: &adjusted,
        lrf: &lrf,
        ext: &ext,
        joint: &joint,
        lrf_out,
        pairs_out,
    };
    let verdict = verdict::judge(&stages);
    let expected_check_error_mm = verdict::expected_check_error_mm(&stages);
    rep.log(format!(
        "verdict: {}{}",
        verdict.status.as_str(),
        if verdict.reasons.is_empty() {
            String::new()
        } else {
            format!(" ({})", verdict.reasons.join("; "))
        }
    ));
    let t = std::time::Instant::now();
    let drawn = overlays::draw(&stages, rep);
    let secs = t.elapsed().as_secs_f64();
    rep.log(format!("time: overlays {secs:.2} s"));
    timing.push(("overlays".into(), secs));
    let results = results::assemble(&stages, verdict, timing);
    let losses: Vec<_> = results.cameras.iter().map(exports::export_loss).collect();
    let loss_rows = exports::report_rows(&results, &losses);
    let report = report::build(&stages, &results, drawn.report, loss_rows, rep);
    let cloud_ply = results::cloud_ply(lrf_out, 0.5 * project.file.balls.diameter_mm);
    let exports = exports::exports(&results, &losses);
    Ok(Outcome {
        results,
        report,
        cloud_ply,
        exports,
        expected_check_error_mm,
        overlays: drawn.files,
    })
}

/// What the steps produced, for the results and the report.
pub struct Stages<'a> {
    /// The project.
    pub project: &'a Project,
    /// Step 1.
    pub dets: &'a scene::Detections,
    /// Steps 2–4 (the final scene).
    pub scene: &'a scene::Scene,
    /// Step 4.
    pub adjusted: &'a bundle::Adjusted,
    /// Step 5.
    pub lrf: &'a lrf::LrfData,
    /// Step 6.
    pub ext: &'a extrinsic::Extrinsics,
    /// Step 7 (None when the method does not ask for it), or why it failed.
    pub joint: &'a Option<std::result::Result<joint::JointOutcome, String>>,
    /// The LRF side every output uses (step 7b): the cloud through the joint adjustment's
    /// estimated model when its result is the one given, else [`Self::lrf`].
    pub lrf_out: &'a lrf::LrfData,
    /// The spheres of [`Self::lrf_out`] matched to balls of the scene.
    pub pairs_out: &'a [(ids::SphereId, ids::PointId)],
}

/// Passes of the joint adjustment that look at the LRF again through the mount the pass
/// before estimated, at most.
pub const JOINT_REFINEMENTS: usize = 3;

/// Step 7 from the outcomes of the steps before it: the sphere method's extrinsic is the
/// start, the project's mount the start of the mount.
///
/// When the joint adjustment finds the mount significantly off its start (an estimate more
/// than 3σ from it), or the cloud it saw shows a mount error (a fifth or more of the beams
/// judged grazing, balls seen twice, spheres that match no ball), the cloud the spheres were
/// found in was distorted by it: a ball seen twice, a ball missed, grazing judged at a wrong
/// centre. So the cloud is made again from the readings through the estimated mount, its
/// spheres found and matched again, and the joint adjustment run again from its own
/// estimate (grazing judged there; its priors still at the project's mount), until a pass
/// needs neither or after [`JOINT_REFINEMENTS`] such passes. The two-step method's results
/// stay those of the project's mount: they are the paper's method as the user gave it.
fn run_joint(
    project: &Project,
    (dets, scene, adjusted): (&scene::Detections, &scene::Scene, &bundle::Adjusted),
    lrf: &lrf::LrfData,
    ext: &extrinsic::Extrinsics,
    opts: &Options,
    rep: &Reporter,
) -> std::result::Result<joint::JointOutcome, String> {
    let Some(ev) = &ext.spheres else {
        return Err("it starts from the sphere method, which did not run".into());
    };
    let pass = |lrf: &lrf::LrfData,
                ext: &extrinsic::Extrinsics,
                start: pingcal_geometry::Rigid3,
                pass: usize| {
        let input = joint::JointInput {
            project,
            dets,
            scene,
            adj: adjusted,
            lrf,
            ext,
            start,
            mount0: lrf.mount,
            prior: lrf::mount_of(project),
            pass,
            noise: lrf.noise,
        };
        joint::joint_adjustment(&input, rep).map_err(|e| e.0)
    };
    let mut out = pass(lrf, ext, ev.registration.camera_from_lrf.rigid(), 1)?;
    let mut start_mount = lrf.mount;
    for k in 1..=JOINT_REFINEMENTS {
        let why = match out.distorted_cloud() {
            Some(why) => why,
            None if out.moved_mount(&start_mount, 3.0) => {
                "the mount is off its start by more than 3σ".to_string()
            }
            None => break,
        };
        rep.log(format!(
            "joint: {why}: the LRF spheres again through the estimated mount (pass {})",
            k + 1
        ));
        let Some(lrf2) = lrf::through_mount(project, lrf, out.mount_model, opts, rep) else {
            break;
        };
        let again = extrinsic::spheres_only(project, scene, adjusted, &lrf2, dets, opts, rep)
            .map_err(|e| e.0)
            .and_then(|ext2| pass(&lrf2, &ext2, out.camera_from_lrf, k + 1));
        match again {
            Ok(o) => {
                start_mount = lrf2.mount;
                out = o;
            }
            Err(e) => {
                rep.log(format!(
                    "joint: pass {} failed ({e}): the pass before stands",
                    k + 1
                ));
                break;
            }
        }
    }
    Ok(out)
}
