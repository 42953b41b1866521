//! The data of `report.html` ([`pingcal_report::ReportData`]) from the pipeline's results:
//! one function per part of the report (image residuals, network, cloud, methods,
//! intrinsics, rejections and warnings, summary), put together by [`build`].

use super::ids::{ImageId, SphereId};
use super::lrf::MIN_REPORTED_CLUSTER;
use super::results::Results;
use super::scene::{image_file, main_image, PointKind};
use crate::progress::Reporter;
use crate::stages::Stages;
use pingcal_ba::camera::{CameraModel, SensorCamera};
use pingcal_ba::ImageKey;
use pingcal_lrf::sensor::MountParam;
use pingcal_report as rp;

/// Most cloud points drawn in the report (an even subsample).
pub const MAX_CLOUD_POINTS: usize = 40_000;

const UNITS: [&str; 10] = [
    "mm", "mm", "mm", "mm⁻²", "mm⁻⁴", "mm⁻⁶", "mm⁻¹", "mm⁻¹", "", "",
];

/// The report's rows of a check table (`role`: `check`, `control` or `loo`), as the
/// registration computed them; calibrate's and sphere-calib's reports share it.
pub(crate) fn check_rows(
    rows: &[pingcal_lrf::registration::CheckRow],
    role: &str,
) -> Vec<rp::CheckRow> {
    rows.iter()
        .map(|r| rp::CheckRow {
            id: r.id.clone(),
            dx_mm: r.dx_mm,
            dy_mm: r.dy_mm,
            dz_mm: r.dz_mm,
            error_mm: r.error_mm,
            role: role.into(),
        })
        .collect()
}

/// Builds the report data, with the LRF drawn on the images (`overlays`, made by the
/// pipeline's `overlays` step) and what each export loses (`export_losses`, the `exports`
/// step's).
pub fn build(
    st: &Stages,
    results: &Results,
    overlays: Vec<rp::Overlay>,
    export_losses: Vec<rp::ExportLossRow>,
    rep: &Reporter,
) -> rp::ReportData {
    let f = &st.project.file;
    rp::ReportData {
        overlays,
        export_losses,
        title: format!("pingcal calibration — {}", f.name),
        generator: results.generator.clone(),
        verdict: Some(verdict(&results.verdict)),
        summary: [summary(st, results), group_lines(results)].concat(),
        steps: rep.lines(),
        images: image_residuals(st),
        network: network(st),
        cloud: cloud(st),
        methods: methods(st, results),
        intrinsics: intrinsics(st, results),
        lrf_mount: mount_rows(results),
        rejected: rejections(st),
        warnings: warnings(st, results),
        exterior: exterior(st),
        distances: distances(st),
        rig: results.bundle.rig.as_ref().map(rig),
        sensors: (results.sensors.iter())
            .map(|s| sensor_row(s.id.clone(), s.kind.clone(), &s.camera_from_sensor))
            .collect(),
        sensor_pairs: (results.sensor_pairs.iter())
            .map(|p| sensor_row(format!("{} ← {}", p.a, p.b), String::new(), &p.a_from_b))
            .collect(),
    }
}

/// A row of the report's sensors table.
fn sensor_row(name: String, kind: String, e: &crate::results::ExtrinsicJson) -> rp::SensorRow {
    rp::SensorRow {
        name,
        kind,
        translation_mm: e.translation_mm,
        opk_deg: e.opk_deg,
        sigma_translation_mm: e.sigma_translation_mm,
        sigma_opk_deg: e.sigma_rotation_deg,
    }
}

/// Why an image of the final problem has no σ of its own.
fn no_sigma_note(st: &Stages, s: usize) -> &'static str {
    let p = &st.adjusted.solved.problem;
    if p.images[s].fixed {
        "datum (held)"
    } else if p
        .rigs
        .iter()
        .any(|r| r.members.iter().any(|m| m.image == ImageKey(s)))
    {
        "rig member: follows its base image through the rig"
    } else {
        "no σ"
    }
}

/// The exterior orientation of every image of the final problem with its σ.
fn exterior(st: &Stages) -> Vec<rp::ExteriorRow> {
    let adj = st.adjusted;
    adj.solved
        .map
        .images
        .iter()
        .enumerate()
        .filter_map(|(s, &i)| {
            let pose = st.scene.poses[i]?;
            let c = pose.centre();
            let sigma = adj.precision.poses.get(s).copied().flatten();
            Some(rp::ExteriorRow {
                name: image_file(st.project, i).to_string(),
                centre_mm: [c.x, c.y, c.z],
                opk_deg: pose.opk_deg(),
                sigma_centre_mm: sigma.map(|p| p.centre),
                sigma_rotation_deg: sigma.map(|p| p.rotation_rad.map(f64::to_degrees)),
                note: if sigma.is_some() {
                    String::new()
                } else {
                    no_sigma_note(st, s).into()
                },
            })
        })
        .collect()
}

/// The measured distances of the final adjustment: measured and adjusted.
fn distances(st: &Stages) -> Vec<rp::DistanceRow> {
    let p = &st.adjusted.solved.problem;
    p.distances
        .iter()
        .map(|d| rp::DistanceRow {
            from: p.points[d.a].name.clone(),
            to: p.points[d.b].name.clone(),
            measured_mm: d.value,
            adjusted_mm: (p.points[d.a].position - p.points[d.b].position).norm(),
            sigma_mm: d.sigma,
        })
        .collect()
}

/// The stereo rig of `results.json`, with its σ from the bundle.
fn rig(r: &super::results::RigJson) -> rp::RigOrientation {
    let m = nalgebra::Matrix3::from_fn(|i, j| r.rotation[i][j]);
    rp::RigOrientation {
        left: r.left.clone(),
        right: r.right.clone(),
        translation_mm: r.translation_mm,
        opk_deg: pingcal_geometry::to_opk_deg(&m),
        baseline_mm: r.baseline_mm,
        sigma_translation_mm: r.sigma_translation_mm,
        sigma_rotation_deg: r.sigma_rotation_deg,
    }
}

/// The correlation matrix of the first six unknowns (θ, t) of a covariance matrix.
fn correlation(cov: &nalgebra::DMatrix<f64>) -> Option<Vec<Vec<f64>>> {
    if cov.nrows() < 6 || cov.ncols() < 6 {
        return None;
    }
    let s: Vec<f64> = (0..6).map(|i| cov[(i, i)].max(0.0).sqrt()).collect();
    Some(
        (0..6)
            .map(|i| (0..6).map(|j| cov[(i, j)] / (s[i] * s[j])).collect())
            .collect(),
    )
}

/// The covariance of (θ, t) of a method's extrinsic, when it has one.
fn method_correlation(st: &Stages, method: &str) -> Option<Vec<Vec<f64>>> {
    match method {
        "spheres" => correlation(&st.ext.spheres.as_ref()?.registration.cov),
        "joint" => correlation(&st.joint.as_ref()?.as_ref().ok()?.extrinsic_cov),
        _ => None,
    }
}

/// Distance from the principal point to the farthest corner of camera `c`'s sensor, mm.
fn r_max_mm(st: &Stages, c: usize, values: &[f64]) -> Option<f64> {
    let cam = st.project.file.cameras.get(c)?;
    let (hw, hh) = (
        0.5 * cam.width as f64 * cam.pixel_size_mm,
        0.5 * cam.height as f64 * cam.pixel_size_mm,
    );
    let (xp, yp) = (*values.get(1)?, *values.get(2)?);
    [(hw, hh), (-hw, hh), (hw, -hh), (-hw, -hh)]
        .iter()
        .map(|(x, y)| (x - xp).hypot(y - yp))
        .reduce(f64::max)
}

/// Per oriented image (in the order of the final problem): the residual of every image point,
/// and the image points rejected as gross errors.
fn image_residuals(st: &Stages) -> Vec<rp::ImageResiduals> {
    let (f, scene, adj) = (&st.project.file, st.scene, st.adjusted);
    let (p, map) = (&adj.solved.problem, &adj.solved.map);
    let mut images: Vec<rp::ImageResiduals> = map
        .images
        .iter()
        .map(|&i| rp::ImageResiduals {
            name: image_file(st.project, i).to_string(),
            width: st.dets[i].width as u32,
            height: st.dets[i].height as u32,
            points: Vec::new(),
        })
        .collect();
    for (o, ob) in p.observations.iter().enumerate() {
        let (j, _) = map.observations[o];
        let Some(r) = p.residual(ob) else { continue };
        images[ob.image.0].points.push(rp::ImagePoint {
            label: scene.points[j].name.clone(),
            kind: scene.points[j].kind.as_str().into(),
            x: ob.uv.x,
            y: ob.uv.y,
            dx: r.x,
            dy: r.y,
            rejected: false,
        });
    }
    for r in &adj.rejected {
        let slot = f
            .images
            .iter()
            .position(|im| im.file == r.image)
            .and_then(|i| map.image(ImageId(i)));
        if let Some(s) = slot {
            images[s.0].points.push(rp::ImagePoint {
                label: r.point.clone(),
                kind: "rejected".into(),
                x: r.uv[0],
                y: r.uv[1],
                dx: 0.0,
                dy: 0.0,
                rejected: true,
            });
        }
    }
    images
}

/// The camera stations and the adjusted points with their σ.
fn network(st: &Stages) -> rp::Network {
    let (f, scene, adj) = (&st.project.file, st.scene, st.adjusted);
    let main = main_image(st.project);
    let cameras = scene
        .poses
        .iter_enumerated()
        .filter_map(|(i, pose)| {
            let pose = (*pose)?;
            let im = &f.images[i.0];
            let c = pose.centre();
            let r = pose.rotation;
            Some(rp::CameraStation {
                name: format!("{} {}", im.station, im.camera),
                centre: [c.x, c.y, c.z],
                rotation: [
                    [r[(0, 0)], r[(0, 1)], r[(0, 2)]],
                    [r[(1, 0)], r[(1, 1)], r[(1, 2)]],
                    [r[(2, 0)], r[(2, 1)], r[(2, 2)]],
                ],
                main: i == main,
            })
        })
        .collect();
    let points = scene
        .points
        .iter_enumerated()
        .filter_map(|(j, pt)| {
            let k = adj.solved.map.point(j)?;
            let s = adj.precision.point_sigma(k.0).unwrap_or_default();
            Some(rp::NetworkPoint {
                label: pt.name.clone(),
                kind: pt.kind.as_str().into(),
                xyz: [pt.position.x, pt.position.y, pt.position.z],
                sigma: [s.x, s.y, s.z],
            })
        })
        .collect();
    rp::Network { cameras, points }
}

/// The name of the ball LRF sphere `k` was matched to, if any.
fn matched_ball(st: &Stages, k: SphereId) -> Option<String> {
    st.pairs_out
        .iter()
        .find(|(l, _)| *l == k)
        .map(|(_, j)| st.scene.points[*j].name.clone())
}

/// The LRF cloud (subsampled to at most [`MAX_CLOUD_POINTS`]) and its spheres.
fn cloud(st: &Stages) -> rp::CloudView {
    let lrf = st.lrf_out;
    let n = lrf.cloud.points.len();
    let step = n.div_ceil(MAX_CLOUD_POINTS).max(1);
    let points = lrf
        .cloud
        .points
        .iter()
        .step_by(step)
        .map(|q| [q.x as f32, q.y as f32, q.z as f32])
        .collect();
    let spheres = lrf
        .found
        .balls
        .iter()
        .enumerate()
        .map(|(k, b)| {
            let matched = matched_ball(st, SphereId(k));
            let d = b.cov.diagonal().map(|v| v.max(0.0).sqrt());
            rp::Sphere {
                label: matched.clone().unwrap_or_else(|| format!("L{}", k + 1)),
                centre: [b.centre.x, b.centre.y, b.centre.z],
                radius: 0.5 * st.project.file.balls.diameter_mm,
                sigma: [d.x, d.y, d.z],
                inliers: b.inliers.len(),
                matched_to: matched,
            }
        })
        .collect();
    rp::CloudView { points, spheres }
}

/// The joint adjustment's mount and range parameters.
fn mount_rows(results: &Results) -> Vec<rp::MountRow> {
    const COMPONENTS: [&str; 6] = ["δω", "δφ", "δκ", "tx", "ty", "tz"];
    let Some(mount) = &results.lrf_mount else {
        return Vec::new();
    };
    mount
        .iter()
        .map(|m| rp::MountRow {
            name: m.name.clone(),
            value: m.value,
            sigma: m.sigma,
            unit: match MountParam::named(&m.name) {
                Some(p) => p.unit().trim_start(),
                None if m.name == super::joint::TIME_OFFSET_NAME => "s",
                None => "mm",
            }
            .into(),
            held: m.held.clone(),
            max_corr_extrinsic: m.correlation_with_extrinsic.and_then(|c| {
                (0..6)
                    .filter(|&k| c[k].is_finite())
                    .max_by(|&a, &b| c[a].abs().total_cmp(&c[b].abs()))
                    .map(|k| (COMPONENTS[k].to_string(), c[k]))
            }),
        })
        .collect()
}

/// Each method's extrinsic and check table, or why it failed.
fn methods(st: &Stages, results: &Results) -> Vec<rp::MethodResult> {
    let mut methods = Vec::new();
    for m in &results.methods {
        let name = match m.method.as_str() {
            "joint" => "joint adjustment (LRF mount self-calibrated)".to_string(),
            "spheres" => "spheres (this paper's two steps)".to_string(),
            "corner" => "corner (Fan et al. 2019)".to_string(),
            other => other.to_string(),
        };
        let mut checks = check_rows(
            &m.check_points,
            if m.check_points_source == "leave_one_out" {
                "loo"
            } else {
                "check"
            },
        );
        checks.extend(check_rows(&m.control_points, "control"));
        if m.check_points_source != "leave_one_out" {
            // each control ball left out of the registration in turn, judged by the others
            checks.extend(check_rows(&m.leave_one_out, "loo"));
        }
        methods.push(match &m.extrinsic {
            Some(e) => rp::MethodResult {
                name,
                rotation: e.rotation,
                translation_mm: e.translation_mm,
                opk_deg: e.opk_deg,
                sigma_translation_mm: e.sigma_translation_mm,
                sigma_rotation_deg: e.sigma_rotation_deg,
                checks,
                mean_check_error_mm: m.mean_check_error_mm,
                sd_check_error_mm: m.sd_check_error_mm,
                error: None,
                correlation: method_correlation(st, &m.method),
            },
            None => rp::MethodResult {
                name,
                error: m.error.clone(),
                ..Default::default()
            },
        });
    }
    methods
}

/// The units of model `m`'s parameters, in its slice order.
fn units(m: pingcal_project::CameraModel) -> Vec<String> {
    let names = m.parameter_names();
    if m.in_mm() {
        return UNITS.iter().map(|s| s.to_string()).collect();
    }
    names
        .iter()
        .map(|n| match *n {
            "fx" | "fy" | "cx" | "cy" => "px",
            _ => "",
        })
        .map(String::from)
        .collect()
}

/// The lens curve of camera `cam` at `values` (models without K1–K3): radius (px) and
/// angle off the axis (°) of the rays along the image's longest half-diagonal from the
/// principal point, as far as the model gives rays; and its focal length (px).
fn lens_curve(cam: &SensorCamera, values: &[f64]) -> Option<(Vec<(f64, f64)>, f64)> {
    let pp = cam.model.principal_point_px(values);
    let corners = [
        (0.0, 0.0),
        (cam.width as f64 - 1.0, 0.0),
        (0.0, cam.height as f64 - 1.0),
        (cam.width as f64 - 1.0, cam.height as f64 - 1.0),
    ];
    let far = corners
        .iter()
        .map(|&(x, y)| nalgebra::Vector2::new(x, y))
        .max_by(|a, b| (a - pp).norm().total_cmp(&(b - pp).norm()))?;
    let pts: Vec<(f64, f64)> = (0..=100)
        .map_while(|i| {
            let uv = pp + (far - pp) * (i as f64 / 100.0);
            let ray = cam.unproject(values, &uv)?;
            Some(((uv - pp).norm(), ray.y.clamp(-1.0, 1.0).acos().to_degrees()))
        })
        .collect();
    Some((pts, cam.focal_px(values)))
}

/// Each camera's parameters with their units, σ, free flags and high correlations.
fn intrinsics(st: &Stages, results: &Results) -> Vec<rp::Intrinsics> {
    let f = &st.project.file;
    results
        .cameras
        .iter()
        .zip(st.scene.intrinsics.iter())
        .enumerate()
        .map(|(c, (cj, values))| {
            let cam = &f.cameras[c];
            let names = cam.model.parameter_names();
            let photogrammetric = cam.model.in_mm();
            rp::Intrinsics {
                camera: cj.id.clone(),
                names: names.iter().map(|s| s.to_string()).collect(),
                units: units(cam.model),
                values: values.clone(),
                sigmas: names
                    .iter()
                    .map(|n| cj.sigma.get(*n).copied().unwrap_or(f64::NAN))
                    .collect(),
                free: cam.free_flags(),
                high_correlations: cj.high_correlations.clone(),
                r_max_mm: photogrammetric.then(|| r_max_mm(st, c, values)).flatten(),
                opencv: Some(rp::OpenCvParams {
                    fx: cj.opencv.fx,
                    fy: cj.opencv.fy,
                    cx: cj.opencv.cx,
                    cy: cj.opencv.cy,
                    dist: cj.opencv.dist.clone(),
                    distortion_model: cj.opencv.distortion_model.into(),
                    width: cj.opencv.image_width,
                    height: cj.opencv.image_height,
                }),
                model: cam.model.name().into(),
                lens_curve: (!photogrammetric)
                    .then(|| lens_curve(&st.scene.cameras[crate::ids::CameraId(c)], values))
                    .flatten(),
            }
        })
        .collect()
}

/// What was left out and why: coded numbers named blunders, image points, LRF clusters,
/// unmatched LRF spheres.
fn rejections(st: &Stages) -> Vec<rp::Rejection> {
    let adj = st.adjusted;
    let blunders: Vec<(String, String)> = (st.scene.blunders.iter())
        .map(|b| {
            (
                image_file(st.project, b.det.image).to_string(),
                b.number.to_string(),
            )
        })
        .collect();
    let mut rejected: Vec<rp::Rejection> = (st.scene.blunders.iter())
        .zip(&blunders)
        .map(|(b, (image, number))| {
            let t = st.dets.target(b.det);
            rp::Rejection {
                what: format!(
                    "coded number {number} read in {image} at ({:.1}, {:.1}) px",
                    t.x, t.y
                ),
                why: format!("a named blunder ({}): {}; removed", b.stage, b.why),
            }
        })
        .collect();
    rejected.extend((adj.rejected_distances.iter()).map(|d| rp::Rejection {
        what: format!(
            "distances[{}]: {} – {} given as {:.3} mm",
            d.entry, d.from, d.to, d.given_mm
        ),
        why: format!(
            "the adjustment without it puts the targets {:.3} mm apart; {}: a typo? left out",
            d.adjusted_mm, d.why
        ),
    }));
    rejected.extend(
        (adj.rejected.iter())
            .filter(|r| !blunders.contains(&(r.image.clone(), r.point.clone())))
            .map(|r| rp::Rejection {
                what: format!("image point {} in {}", r.point, r.image),
                why: r.reason.clone(),
            }),
    );
    rejected.extend(lrf_rejections(st));
    rejected
}

/// The report's rows of what the LRF step left out: small clusters (counted), larger
/// clusters with their reasons, and spheres matched to no ball.
fn lrf_rejections(st: &Stages) -> Vec<rp::Rejection> {
    let lrf = st.lrf_out;
    let mut rejected = Vec::new();
    let small = lrf
        .found
        .rejected
        .iter()
        .filter(|r| r.cluster_points < MIN_REPORTED_CLUSTER)
        .count();
    if small > 0 {
        rejected.push(rp::Rejection {
            what: format!("{small} small LRF clusters (under {MIN_REPORTED_CLUSTER} points)"),
            why: "left over after the walls were removed (plane edges, target rims, stems): too few points for a ball".into(),
        });
    }
    for r in lrf
        .found
        .rejected
        .iter()
        .filter(|r| r.cluster_points >= MIN_REPORTED_CLUSTER)
    {
        rejected.push(rp::Rejection {
            what: format!(
                "LRF cluster at ({:.0}, {:.0}, {:.0}) mm, {} points",
                r.centre.x, r.centre.y, r.centre.z, r.cluster_points
            ),
            why: r.reason.clone(),
        });
    }
    for (k, b) in lrf.found.balls.iter().enumerate() {
        if !st.pairs_out.iter().any(|(l, _)| *l == SphereId(k)) {
            rejected.push(rp::Rejection {
                what: format!(
                    "LRF sphere L{} at ({:.0}, {:.0}, {:.0}) mm",
                    k + 1,
                    b.centre.x,
                    b.centre.y,
                    b.centre.z
                ),
                why: "not matched to any ball of the photographs".into(),
            });
        }
    }
    rejected
}

/// Images not oriented, the network start's doubts, distances left out, and methods that
/// failed.
fn warnings(st: &Stages, results: &Results) -> Vec<String> {
    let mut warnings: Vec<String> = st
        .scene
        .unoriented
        .iter()
        .map(|(i, w)| format!("image {} not oriented: {w}", image_file(st.project, *i)))
        .collect();
    warnings.extend(st.scene.warnings.iter().cloned());
    warnings.extend(st.adjusted.unused_distances.iter().cloned());
    for m in &results.methods {
        if let Some(e) = &m.error {
            warnings.push(format!("method {} failed: {e}", m.method));
        }
    }
    warnings
}

/// The report's box of verdict `v`: its status, reasons, notes and checks.
pub fn verdict(v: &crate::verdict::Verdict) -> rp::VerdictView {
    rp::VerdictView {
        status: v.status.as_str().into(),
        reasons: v.reasons.clone(),
        notes: v.notes.clone(),
        checks: v
            .checks
            .iter()
            .map(|c| rp::VerdictCheckView {
                name: c.name.clone(),
                value: c.value,
                bound: c.bound,
                passed: c.passed,
            })
            .collect(),
        alpha: v.alpha,
    }
}

/// The summary's line of every observation group of a method's adjustment (the joint
/// adjustment's beams on the balls, on the planes, …): its χ² with the a-priori σ's, its
/// observations, those removed and left out, its RMS.
fn group_lines(results: &Results) -> Vec<(String, String)> {
    (results.methods.iter())
        .flat_map(|m| m.observation_groups.iter().map(move |g| (m, g)))
        .map(|(m, g)| {
            let left: String = (g.left_out.iter())
                .filter(|l| l.count > 0)
                .map(|l| format!("; {} {} left out", l.count, l.reason))
                .collect();
            (
                format!("{} χ² of the {}", m.method, g.group),
                format!(
                    "{:.1} over {} observations ({} rejected{left}), RMS {:.2} {}",
                    g.chi2, g.observations, g.rejected, g.rms, g.unit
                ),
            )
        })
        .collect()
}

/// The summary table at the top of the report.
fn summary(st: &Stages, results: &Results) -> Vec<(String, String)> {
    let mut summary = headline_rows(st, results);
    if !results.bundle.variance_components.is_empty() {
        summary.push((
            "bundle σ0 per group (re-weighted by it)".to_string(),
            components(&results.bundle.variance_components),
        ));
    }
    if let Some(j) = results
        .methods
        .iter()
        .find(|m| !m.variance_components.is_empty())
    {
        summary.push((
            format!("{} σ0 of the LRF beams (re-weighted by it)", j.method),
            components(&j.variance_components),
        ));
    }
    summary.extend(ball_correction_row(st));
    summary
}

/// The summary's rows that every run has: the project, the method, the check-point error,
/// the extrinsic, the bundle's fit and size, the balls found and matched.
fn headline_rows(st: &Stages, results: &Results) -> Vec<(String, String)> {
    let f = &st.project.file;
    let balls = st
        .scene
        .points
        .iter()
        .filter(|p| p.kind == PointKind::Ball)
        .count();
    vec![
        ("project".to_string(), f.name.clone()),
        ("method".to_string(), f.method.to_string()),
        (
            "mean check-point error".to_string(),
            format!("{:.2} mm", results.mean_check_error_mm),
        ),
        (
            "extrinsic t".to_string(),
            format!(
                "({:.1}, {:.1}, {:.1}) mm",
                results.extrinsic.translation_mm[0],
                results.extrinsic.translation_mm[1],
                results.extrinsic.translation_mm[2]
            ),
        ),
        (
            "bundle σ0 / RMS".to_string(),
            format!(
                "{:.3} / {:.3} px",
                results.bundle.sigma0, results.bundle.rms_image_px
            ),
        ),
        (
            "images / points / observations".to_string(),
            format!(
                "{} / {} / {}",
                results.bundle.images, results.bundle.points, results.bundle.observations
            ),
        ),
        (
            "balls (photographs / LRF / matched)".to_string(),
            format!(
                "{} / {} / {}",
                balls,
                st.lrf_out.found.balls.len(),
                st.pairs_out.len()
            ),
        ),
    ]
}

/// Variance components as the summary shows them: group, σ0, redundancy, and whether the
/// group was re-weighted by it.
fn components(v: &[pingcal_ba::solver::VarianceComponent]) -> String {
    v.iter()
        .map(|c| {
            format!(
                "{} {:.2} (r {:.0}{})",
                c.group,
                c.sigma0,
                c.redundancy,
                if c.reweighted { "" } else { ", kept" }
            )
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// The summary's row of the balls' eccentricity correction: median and largest shift, when
/// the bundle corrected any.
fn ball_correction_row(st: &Stages) -> Option<(String, String)> {
    let shifts = &st.adjusted.solved.ball_shifts_px;
    if shifts.is_empty() {
        return None;
    }
    let mut s = shifts.clone();
    s.sort_by(|a, b| a.total_cmp(b));
    Some((
        "ball eccentricity correction".to_string(),
        format!(
            "median {:.3} px, max {:.3} px",
            s[s.len() / 2],
            s[s.len() - 1]
        ),
    ))
}
