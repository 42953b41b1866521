//! Issue 4, "Must show": the 3D accuracy of the real AICON panel (`shared/data/aicon-panel`,
//! 20 photographs, reference coordinates of all 239 targets) after detection, a
//! self-calibrating bundle adjustment and a 7-parameter similarity onto the reference.
//!
//! * Detection: all 20 images. Coded targets are named by their decoded ID. Plain targets
//!   are named by the reference ID they match through a RANSAC homography from the coded
//!   targets' reference (X, Y) to the image (the panel is flat except 72–74, which are left
//!   out of the homography): a plain detection gets an ID only when the nearest projected
//!   plain reference target is within `MATCH_PX`, every other one is at least 3 × as far
//!   (and ≥ 1.5 × `MATCH_PX`), and no other detection in the image claims the same ID.
//! * σ of each image coordinate: the detector's own estimate (σ0 shows how right it is).
//! * Initial values: the reference coordinates enter only as *approximate* coordinates,
//!   as weighted control with σ = 10 mm, for the initialiser (resection, intersection).
//! * Datum of the final adjustment: those priors are removed; the pose of the image with
//!   the most rays is held where the initialiser put it and the scale comes from ONE
//!   reference distance (the two coded targets farthest apart, ~911 mm). That is exactly
//!   7 datum parameters, so the reference does not constrain the shape at all.
//! * Self-calibration of c, xp, yp, K1, K2, K3, P1, P2; data snooping at 3.29 (Baarda,
//!   0.1 %, τ test when σ0 > 1) removes bad detections one at a time.
//! * Then a 7-parameter similarity (Umeyama) of all adjusted points onto the reference and
//!   the RMS / max of the 3D differences, separately for coded and plain targets.
//!
//! Run `cargo test -p pingcal-targets --release --test targets panel_bundle:: -- --nocapture`.

use crate::panel;
use pingcal_ba::{ImageKey, PointKey};

use nalgebra::Vector3;
use panel::panel;
use pingcal_ba::initial::incremental::{initialise, IncrementalOptions};
use pingcal_ba::io::measurements::{CameraSpec, ControlPoint, ImagePoint, ImageSpec, Measurements};
use pingcal_ba::solver::{adjust_with_snooping, Options};
use pingcal_targets::homography::ransac_homography;
use pingcal_targets::{detect_file, DetectParams, Detector, TargetKind};
use std::collections::HashMap;

/// Homography inlier threshold and plain-target matching radius (a homography misses the
/// lens distortion: up to ~4.6 px in the corners, see tests/real_panel.rs).
const MATCH_PX: f64 = 8.0;
const PRIOR_SIGMA_MM: f64 = 10.0;
/// Bound on the 3D RMS after the similarity, mm (reasoning at the assertion).
const BOUND_MM: f64 = 0.05;

/// Plain detections → reference IDs through the homography `h`, unambiguous matches only.
fn match_plain(
    h: &pingcal_targets::homography::Homography,
    refs: &HashMap<u32, [f64; 3]>,
    dets: &[[f64; 2]],
) -> Vec<Option<u32>> {
    let proj: Vec<(u32, [f64; 2])> = refs
        .iter()
        .filter(|(id, p)| **id >= 1000 && p[2].abs() < 1.0)
        .filter_map(|(id, p)| h.apply([p[0], p[1]]).map(|q| (*id, q)))
        .collect();
    let mut out: Vec<Option<u32>> = dets
        .iter()
        .map(|d| {
            let mut best = (f64::INFINITY, 0u32);
            let mut second = f64::INFINITY;
            for (id, q) in &proj {
                let e = ((q[0] - d[0]).powi(2) + (q[1] - d[1]).powi(2)).sqrt();
                if e < best.0 {
                    second = best.0;
                    best = (e, *id);
                } else if e < second {
                    second = e;
                }
            }
            // Nearest within MATCH_PX and every other reference target at least 3 × as far.
            (best.0 < MATCH_PX && second > 3.0 * best.0.max(MATCH_PX / 2.0)).then_some(best.1)
        })
        .collect();
    // An ID claimed by two detections is ambiguous: drop both.
    let mut count: HashMap<u32, usize> = HashMap::new();
    for id in out.iter().flatten() {
        *count.entry(*id).or_default() += 1;
    }
    for o in out.iter_mut() {
        if o.is_some_and(|id| count[&id] > 1) {
            *o = None;
        }
    }
    out
}

#[test]
fn panel_3d_rms_after_self_calibrating_bundle_and_similarity() {
    let Some((refs, files)) = panel() else {
        return;
    };
    let t0 = std::time::Instant::now();
    let det = Detector::new(DetectParams::default()).unwrap();

    let mut image_points = Vec::new();
    let mut images = Vec::new();
    let (mut n_coded, mut n_plain) = (0usize, 0usize);
    for f in &files {
        let d = detect_file(f, &det).expect("real image loads");
        let name = f.file_stem().unwrap().to_string_lossy().to_string();
        let mut push = |id: u32, x: f64, y: f64, s: f64| {
            image_points.push(ImagePoint {
                image: name.clone(),
                point: id.to_string(),
                x,
                y,
                // Guard against a degenerate (0 or NaN) detector σ.
                sigma_px: if s.is_finite() {
                    s.clamp(0.01, 1.0)
                } else {
                    0.1
                },
            });
        };
        let coded: Vec<_> = d
            .targets
            .iter()
            .filter(|t| t.id.is_some_and(|id| refs.contains_key(&id)))
            .collect();
        for t in &coded {
            push(t.id.unwrap(), t.x, t.y, t.sigma_px);
            n_coded += 1;
        }
        let flat: Vec<_> = coded
            .iter()
            .filter(|t| refs[&t.id.unwrap()][2].abs() < 1.0)
            .collect();
        let src: Vec<[f64; 2]> = flat
            .iter()
            .map(|t| {
                let p = refs[&t.id.unwrap()];
                [p[0], p[1]]
            })
            .collect();
        let dst: Vec<[f64; 2]> = flat.iter().map(|t| [t.x, t.y]).collect();
        let r = ransac_homography(&src, &dst, MATCH_PX, 1000, 42).expect("homography");
        let plain: Vec<_> = d
            .targets
            .iter()
            .filter(|t| t.kind == TargetKind::Plain && t.id.is_none())
            .collect();
        let xy: Vec<[f64; 2]> = plain.iter().map(|t| [t.x, t.y]).collect();
        for (t, id) in plain.iter().zip(match_plain(&r.h, &refs, &xy)) {
            if let Some(id) = id {
                push(id, t.x, t.y, t.sigma_px);
                n_plain += 1;
            }
        }
        images.push(ImageSpec {
            name,
            camera: "d5600".into(),
            pose: None,
            fixed: false,
            fixed_centre_axes: None,
        });
    }
    println!(
        "detection: {} images, {n_coded} coded and {n_plain} plain observations ({:.1} s)",
        files.len(),
        t0.elapsed().as_secs_f64()
    );

    let pixel = 23.5 / 2000.0;
    let meas = Measurements {
        format: None,
        cameras: vec![CameraSpec {
            name: "d5600".into(),
            model: "photogrammetric".into(),
            width: 2000,
            height: 1333,
            pixel_size_mm: pixel,
            intrinsics: [("c".to_string(), 24.0)].into_iter().collect(),
            calibrate: ["c", "xp", "yp", "K1", "K2", "K3", "P1", "P2"]
                .map(String::from)
                .to_vec(),
        }],
        images,
        image_points,
        distances: vec![],
        control_points: refs
            .iter()
            .map(|(id, p)| ControlPoint {
                id: id.to_string(),
                xyz: *p,
                sigma_mm: Some([PRIOR_SIGMA_MM; 3]),
                fixed: false,
                fixed_axes: None,
            })
            .collect(),
    };
    let built = meas.to_problem().expect("a valid problem");
    for w in &built.warnings {
        println!("warning: {w:?}");
    }
    let options = IncrementalOptions {
        resection: pingcal_ba::initial::resection::ResectionOptions {
            threshold_px: 30.0,
            ..Default::default()
        },
        intersection: pingcal_ba::initial::intersection::IntersectionOptions {
            min_angle_deg: 2.0,
            max_rms_px: 30.0,
        },
        ..IncrementalOptions::default()
    };
    let init = initialise(
        &built.problem,
        &built.known_points,
        &built.known_poses,
        &options,
    )
    .expect("initial values");
    assert!(init.in_control_frame);
    assert!(
        init.unoriented_images.is_empty(),
        "{:?}",
        init.unoriented_images
    );
    println!(
        "initialiser: {} observations rejected as gross errors, {} points undetermined",
        init.rejected_observations.len(),
        init.undetermined_points.len()
    );

    let mut p = init.problem.clone();
    // Datum: replace the weighted control by the pose of the image with the most rays
    // (fixed where the initialiser put it) and ONE reference distance, between the two
    // coded targets farthest apart: 7 datum parameters, none of which constrains the shape.
    p.point_priors.clear();
    let busiest = (0..p.images.len())
        .max_by_key(|&k| {
            p.observations
                .iter()
                .filter(|o| o.image == ImageKey(k))
                .count()
        })
        .unwrap();
    p.images[busiest].fixed = true;
    let coded_pts: Vec<(usize, Vector3<f64>)> = p
        .points
        .iter()
        .enumerate()
        .filter_map(|(k, pt)| {
            let id: u32 = pt.name.parse().ok()?;
            let r = refs.get(&id)?;
            (id < 1000).then_some((k, Vector3::new(r[0], r[1], r[2])))
        })
        .collect();
    let mut far = (0, 0, 0.0);
    for (i, a) in &coded_pts {
        for (j, b) in &coded_pts {
            let d = (a - b).norm();
            if d > far.2 {
                far = (*i, *j, d);
            }
        }
    }
    p.distances.push(pingcal_ba::problem::Distance {
        a: PointKey(far.0),
        b: PointKey(far.1),
        value: far.2,
        sigma: 0.001,
    });
    println!(
        "datum: pose of {} fixed, scale from the reference distance {}–{} = {:.3} mm",
        p.images[busiest].name, p.points[far.0].name, p.points[far.1].name, far.2
    );
    let solver = Options {
        max_iterations: 100,
        function_tolerance: 1e-12,
        gradient_tolerance: 1e-12,
        parameter_tolerance: 1e-12,
        ..Options::default()
    };
    let snoop = adjust_with_snooping(&mut p, &solver, 3.29, 500).expect("bundle adjustment");
    let prec = &snoop.precision;
    let cam = &p.cameras[0].params;
    println!(
        "bundle: σ0 {:.3}, RMS image residual {:.4} px, {} images, {} points, {} image observations, redundancy {}, {} rejected by data snooping",
        prec.sigma0,
        prec.rms_image_px,
        p.images.len(),
        p.points.len(),
        p.observations.len(),
        prec.redundancy,
        snoop.rejected.len()
    );
    println!(
        "camera: c {:.4} mm, xp {:.4}, yp {:.4}, K1 {:.3e}, K2 {:.3e}, K3 {:.3e}, P1 {:.3e}, P2 {:.3e}",
        cam[0], cam[1], cam[2], cam[3], cam[4], cam[5], cam[6], cam[7]
    );

    // 7-parameter similarity of the adjusted points onto the reference (all points).
    let pairs: Vec<(u32, Vector3<f64>, Vector3<f64>)> = p
        .points
        .iter()
        .filter_map(|pt| {
            let id: u32 = pt.name.parse().ok()?;
            let r = refs.get(&id)?;
            Some((id, pt.position, Vector3::new(r[0], r[1], r[2])))
        })
        .collect();
    let a: Vec<_> = pairs.iter().map(|x| x.1).collect();
    let b: Vec<_> = pairs.iter().map(|x| x.2).collect();
    let sim = pingcal_geometry::umeyama(&a, &b, None, true).expect("a similarity of the panel");
    println!("similarity: scale 1 + {:.2e}", sim.scale - 1.0);
    let stats = |coded: bool| {
        let d: Vec<f64> = pairs
            .iter()
            .filter(|x| (x.0 < 1000) == coded)
            .map(|(_, a, b)| (sim.transform(a) - b).norm())
            .collect();
        let rms = (d.iter().map(|e| e * e).sum::<f64>() / d.len() as f64).sqrt();
        let max = d.iter().cloned().fold(0.0, f64::max);
        (d.len(), rms, max)
    };
    let (nc, rms_c, max_c) = stats(true);
    let (np, rms_p, max_p) = stats(false);
    println!("coded: {nc} points, 3D RMS {rms_c:.4} mm, max {max_c:.4} mm");
    println!("plain: {np} points, 3D RMS {rms_p:.4} mm, max {max_p:.4} mm");
    // Predicted 3D point σ (σ0-scaled) in the datum of the adjustment; it includes the
    // datum's share (fixed pose, one distance), so it is an upper estimate of the
    // shape-only precision that the similarity leaves.
    let sig: Vec<f64> = (0..p.points.len())
        .filter_map(|k| prec.point_sigma(k).map(|v| v.norm()))
        .collect();
    let sig_rms = (sig.iter().map(|e| e * e).sum::<f64>() / sig.len() as f64).sqrt();
    println!(
        "predicted 3D point σ: RMS {sig_rms:.4} mm over {} points",
        sig.len()
    );
    println!("total {:.1} s", t0.elapsed().as_secs_f64());

    // Counts: all 73 coded and nearly all 166 plain targets are in the network, and data
    // snooping removed only a few per cent of the observations.
    assert!(nc >= 70 && np >= 150, "{nc} coded, {np} plain points");
    assert!(
        snoop.rejected.len() * 20 < p.observations.len(),
        "{} rejected",
        snoop.rejected.len()
    );
    // The bound: BOUND_MM = 0.05 mm, the upper end of the "few hundredths of a mm RMS" that
    // the data's README gives for a good system (MicMac's own result on these images). It is
    // ~3× what this pipeline reaches (0.015 mm coded, 0.017 mm plain when written) and
    // equal to the RMS predicted point σ printed above (0.053 mm, which includes the
    // datum's share of a fixed pose and one distance and so over-states the shape error
    // that survives the similarity). A regression in the centres (a bias of a few
    // hundredths of a pixel), the matching or the camera model fails it, while run-to-run
    // noise cannot (RANSAC is seeded; the adjustment is deterministic).
    assert!(
        rms_c < BOUND_MM,
        "coded 3D RMS {rms_c:.4} mm ≥ {BOUND_MM} mm"
    );
    assert!(
        rms_p < BOUND_MM,
        "plain 3D RMS {rms_p:.4} mm ≥ {BOUND_MM} mm"
    );
}
