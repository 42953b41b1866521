//! Issue 3's acceptance test on real data: DBAT's camera-calibration demo (`camcaldemo`,
//! 21 images of a flat PhotoModeler calibration sheet from an Olympus C4040Z, 2074 image
//! points, 4 fixed control points at the sheet's corners), started from no exterior
//! orientation at all, reproduces DBAT's published self-calibration.
//!
//! Run with `cargo test -p pingcal-ba --release --test dbat_camcal -- --nocapture` to see
//! the DBAT vs pingcal table.
//!
//! # Comparing the two
//! * σ0 is the same quantity in both: sqrt(vᵀPv / r) with the 0.1 px prior, r = 4148 − 423.
//! * c is comparable directly: DBAT's y pixel pitch is the sensor height / 1704 = 3.1911 µm
//!   (its aspect parameter scales x only), which is pingcal's pixel size here, and B1
//!   scales x only in pingcal too.
//! * The principal point: DBAT measures it in mm from the image corner with y down, x in
//!   units scaled by its aspect (1 + as); pingcal's (xp, yp) is relative to the array centre
//!   with y up: `xp = px/(1 + as) − (W/2)·ps`, `yp = (H/2)·ps − py`
//!   ([`pingcal_ba::io::dbat::dbat_principal_point`]; DBAT's corner origin puts the array
//!   centre at (W/2, H/2) pixels).
//! * The remaining differences come from the distortion model: DBAT's model 3 is
//!   *backward* (it corrects the measured points: x_corr = x_meas − Δ(x_meas), with the
//!   aspect applied to the measurements before the correction), pingcal's is *forward*
//!   (Δ is added to the ideal point). The two families are not the same function of the
//!   image position: with ~0.37 mm (116 px) of distortion at the corner, the forward K1..K3
//!   polynomial fits DBAT's backward one only to a fraction of a pixel, which moves c and
//!   the principal point by a few µm and σ0 by a few per cent. K and P values are therefore
//!   not compared (roughly opposite in sign, and of different meaning beyond first order).

use pingcal_ba::initial::incremental::{initialise, IncrementalOptions, Step};
use pingcal_ba::io::dbat::{dbat_principal_point, read_dbat, DbatCamera};
use pingcal_ba::solver::{solve, Options};
use std::path::PathBuf;

const DBAT_SIGMA0: f64 = 1.6148;
const DBAT_C: f64 = 7.45699532273933752;
const DBAT_PX: f64 = 3.61546239970888994;
const DBAT_PY: f64 = 2.61329279848268081;
const DBAT_AS: f64 = 0.000389598;
const DBAT_ITERATIONS: usize = 8;
const DBAT_OBSERVATIONS: usize = 4148; // image coordinates (2 per mark point)
const DBAT_REDUNDANCY: usize = 3725;
const DBAT_UNKNOWNS: usize = 423;

fn data_dir() -> PathBuf {
    PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../../shared/data/dbat-camcal"
    ))
}

#[test]
fn reproduces_dbat_camcal_from_no_exterior_orientation() {
    let dir = data_dir();
    let marks = dir.join("measurements/markpts.txt");
    let control = dir.join("reference/camcal-fixed.txt");
    if !marks.exists() || !control.exists() {
        println!(
            "skipped: DBAT's camcal data set not found at {} (shared data absent)",
            dir.display()
        );
        return;
    }
    let camera = DbatCamera::c4040z();
    // DBAT's object unit is the metre; pingcal's is the millimetre.
    let mut meas = read_dbat(&marks, &control, &camera, 1000.0).expect("DBAT files");
    // Self-calibrate c, xp, yp, K1–K3, P1, P2 and B1 (DBAT's aspect); B2 (DBAT's skew) fixed.
    meas.cameras[0].calibrate = ["c", "xp", "yp", "K1", "K2", "K3", "P1", "P2", "B1"]
        .map(String::from)
        .to_vec();
    let built = meas.to_problem().expect("a valid problem");
    assert!(built.warnings.is_empty(), "{:?}", built.warnings);
    let problem = &built.problem;
    assert_eq!(problem.images.len(), 21);
    assert_eq!(2 * problem.observations.len(), DBAT_OBSERVATIONS);

    // No exterior orientation, no object points: only the 4 control points are known.
    let t0 = std::time::Instant::now();
    let options = IncrementalOptions {
        // The approximate camera has no distortion while the lens has up to 116 px: a
        // generous resection threshold for the first poses (4 control points each).
        resection: pingcal_ba::initial::resection::ResectionOptions {
            threshold_px: 60.0,
            ..Default::default()
        },
        intersection: pingcal_ba::initial::intersection::IntersectionOptions {
            min_angle_deg: 2.0,
            max_rms_px: 30.0,
        },
        ..IncrementalOptions::default()
    };
    let init = initialise(problem, &built.known_points, &built.known_poses, &options)
        .expect("initial values");
    println!("initialiser ({:.2} s):", t0.elapsed().as_secs_f64());
    for s in &init.steps {
        println!("  {s}");
    }
    assert!(
        init.unoriented_images.is_empty(),
        "{:?}",
        init.unoriented_images
    );
    assert!(
        init.undetermined_points.is_empty(),
        "{:?}",
        init.undetermined_points
    );
    assert!(init
        .steps
        .iter()
        .all(|s| !matches!(s, Step::BundleFailed { .. })));

    // The self-calibrating bundle adjustment itself.
    let mut p = init.problem;
    assert_eq!(2 * p.observations.len(), DBAT_OBSERVATIONS);
    let summary = solve(
        &mut p,
        &Options {
            max_iterations: 100,
            function_tolerance: 1e-12,
            gradient_tolerance: 1e-12,
            parameter_tolerance: 1e-12,
            ..Options::default()
        },
        |_| {},
    )
    .expect("bundle adjustment");
    let free_intrinsics: usize = p.cameras.iter().map(|c| c.free_indices().len()).sum();
    let unknowns = free_intrinsics
        + 6 * p.images.iter().filter(|i| !i.fixed).count()
        + 3 * p.points.iter().filter(|x| !x.fixed).count();
    let redundancy = 2 * p.observations.len() - unknowns;
    let sigma0 = (2.0 * summary.final_cost / redundancy as f64).sqrt();
    let par = &p.cameras[0].params;
    let (c, xp, yp, b1) = (par[0], par[1], par[2], par[8]);
    let (dbat_xp, dbat_yp) = dbat_principal_point(DBAT_PX, DBAT_PY, DBAT_AS, &camera);

    println!();
    println!("| quantity | DBAT 0.9.2.0 | pingcal |");
    println!("|---|---|---|");
    println!("| σ0 (0.1 px prior) | {DBAT_SIGMA0:.4} | {sigma0:.4} |");
    println!("| σ0 px | {:.4} | {:.4} |", DBAT_SIGMA0 * 0.1, sigma0 * 0.1);
    println!("| c mm | {DBAT_C:.5} | {c:.5} |");
    println!("| xp mm (centre, y up) | {dbat_xp:.5} | {xp:.5} |");
    println!("| yp mm (centre, y up) | {dbat_yp:.5} | {yp:.5} |");
    println!("| aspect / B1 | as = {DBAT_AS:.6} | B1 = {b1:.6} |");
    println!(
        "| iterations | {DBAT_ITERATIONS} | {} ({}) |",
        summary.iterations, summary.termination
    );
    println!(
        "| observations | {DBAT_OBSERVATIONS} | {} |",
        2 * p.observations.len()
    );
    println!("| unknowns | {DBAT_UNKNOWNS} | {unknowns} |");
    println!("| redundancy | {DBAT_REDUNDANCY} | {redundancy} |");
    println!("| RMS px | 0.216 (all residuals) | {:.4} |", p.rms_px());
    println!(
        "| K1 K2 K3 | {:.4e} {:.4e} {:.4e} (backward) | {:.4e} {:.4e} {:.4e} (forward) |",
        0.00458860662755811253,
        -4.51350997187018702e-05,
        -2.05253370760761127e-06,
        par[3],
        par[4],
        par[5]
    );

    assert_eq!(2 * p.observations.len(), DBAT_OBSERVATIONS);
    assert_eq!(unknowns, DBAT_UNKNOWNS);
    assert_eq!(redundancy, DBAT_REDUNDANCY);
    assert!(
        (sigma0 / DBAT_SIGMA0 - 1.0).abs() < 0.05,
        "σ0 {sigma0} vs DBAT {DBAT_SIGMA0}"
    );
    assert!((c - DBAT_C).abs() < 0.01, "c {c} vs DBAT {DBAT_C}");
    assert!(
        (xp - dbat_xp).abs() < 0.02 && (yp - dbat_yp).abs() < 0.02,
        "principal point ({xp}, {yp}) vs DBAT's ({dbat_xp}, {dbat_yp})"
    );
}
