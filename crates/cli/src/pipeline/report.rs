//! The data of `report.html` ([`pingcal_report::ReportData`]) from the pipeline's results.

use super::results::Results;
use super::{PointKind, Reporter, Stages};
use pingcal_report as rp;

/// Most cloud points drawn in the report (an even subsample).
pub const MAX_CLOUD_POINTS: usize = 40_000;

const UNITS: [&str; 10] = [
    "mm", "mm", "mm", "mm⁻²", "mm⁻⁴", "mm⁻⁶", "mm⁻¹", "mm⁻¹", "", "",
];

fn check_rows(rows: &[pingcal_lrf::registration::CheckRow], role: &str) -> Vec<rp::CheckRow> {
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

/// Builds the report data.
pub fn build(st: &Stages, results: &Results, rep: &Reporter) -> rp::ReportData {
    let (project, dets, model, adj, lrf, ext) =
        (st.project, st.dets, st.model, st.adjusted, st.lrf, st.ext);
    let f = &project.file;
    let p = &adj.problem;
    // image residuals
    let mut images: Vec<rp::ImageResiduals> = f
        .images
        .iter()
        .enumerate()
        .filter(|(i, _)| adj.image_index[*i].is_some())
        .map(|(i, im)| rp::ImageResiduals {
            name: im.file.clone(),
            width: dets[i].width as u32,
            height: dets[i].height as u32,
            points: Vec::new(),
        })
        .collect();
    let slot: Vec<Option<usize>> = {
        let mut n = 0;
        adj.image_index
            .iter()
            .map(|x| {
                x.map(|_| {
                    n += 1;
                    n - 1
                })
            })
            .collect()
    };
    for (o, ob) in p.observations.iter().enumerate() {
        let (j, i, _) = adj.obs_map[o];
        let Some(r) = p.residual(ob) else { continue };
        if let Some(s) = slot[i] {
            images[s].points.push(rp::ImagePoint {
                label: model.points[j].name.clone(),
                kind: model.points[j].kind.as_str().into(),
                x: ob.uv.x,
                y: ob.uv.y,
                dx: r.x,
                dy: r.y,
                rejected: false,
            });
        }
    }
    for r in &adj.rejected {
        if let Some(i) = f.images.iter().position(|im| im.file == r.image) {
            if let Some(s) = slot[i] {
                images[s].points.push(rp::ImagePoint {
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
    }
    // network
    let main = project.main_image();
    let cameras = f
        .images
        .iter()
        .enumerate()
        .filter_map(|(i, im)| {
            let pose = model.poses[i]?;
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
    let points = model
        .points
        .iter()
        .enumerate()
        .filter_map(|(j, pt)| {
            let k = adj.point_index[j]?;
            let s = adj.precision.point_sigma(k).unwrap_or_default();
            Some(rp::NetworkPoint {
                label: pt.name.clone(),
                kind: pt.kind.as_str().into(),
                xyz: [pt.position.x, pt.position.y, pt.position.z],
                sigma: [s.x, s.y, s.z],
            })
        })
        .collect();
    // cloud
    let n = lrf.cloud.points.len();
    let step = n.div_ceil(MAX_CLOUD_POINTS).max(1);
    let cloud_points = lrf
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
            let matched = ext
                .pairs
                .iter()
                .find(|(l, _)| *l == k)
                .map(|(_, j)| model.points[*j].name.clone());
            let d = b.cov.diagonal().map(|v| v.max(0.0).sqrt());
            rp::Sphere {
                label: matched.clone().unwrap_or_else(|| format!("L{}", k + 1)),
                centre: [b.centre.x, b.centre.y, b.centre.z],
                radius: 0.5 * f.balls.diameter_mm,
                sigma: [d.x, d.y, d.z],
                inliers: b.inliers.len(),
                matched_to: matched,
            }
        })
        .collect();
    // methods
    let mut methods = Vec::new();
    for m in &results.methods {
        let name = match m.method.as_str() {
            "spheres" => "spheres (this paper's method)".to_string(),
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
            },
            None => rp::MethodResult {
                name,
                error: m.error.clone(),
                ..Default::default()
            },
        });
    }
    // intrinsics
    let intrinsics = results
        .cameras
        .iter()
        .enumerate()
        .map(|(c, cj)| {
            let cam = &f.cameras[c];
            rp::Intrinsics {
                camera: cj.id.clone(),
                names: pingcal_project::PARAMETER_NAMES
                    .iter()
                    .map(|s| s.to_string())
                    .collect(),
                units: UNITS.iter().map(|s| s.to_string()).collect(),
                values: model.intrinsics[c].clone(),
                sigmas: pingcal_project::PARAMETER_NAMES
                    .iter()
                    .map(|n| cj.sigma.get(*n).copied().unwrap_or(f64::NAN))
                    .collect(),
                free: pingcal_project::Parameter::ALL
                    .iter()
                    .map(|p| cam.free.contains(p))
                    .collect(),
                high_correlations: cj.high_correlations.clone(),
            }
        })
        .collect();
    // rejections and warnings
    let mut rejected: Vec<rp::Rejection> = adj
        .rejected
        .iter()
        .map(|r| rp::Rejection {
            what: format!("image point {} in {}", r.point, r.image),
            why: r.reason.clone(),
        })
        .collect();
    let small = lrf
        .found
        .rejected
        .iter()
        .filter(|r| r.cluster_points < super::lrf::MIN_REPORTED_CLUSTER)
        .count();
    if small > 0 {
        rejected.push(rp::Rejection {
            what: format!(
                "{small} small LRF clusters (under {} points)",
                super::lrf::MIN_REPORTED_CLUSTER
            ),
            why: "left over after the walls were removed (plane edges, target rims, stems): too few points for a ball".into(),
        });
    }
    for r in lrf
        .found
        .rejected
        .iter()
        .filter(|r| r.cluster_points >= super::lrf::MIN_REPORTED_CLUSTER)
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
        if !ext.pairs.iter().any(|(l, _)| *l == k) {
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
    let mut warnings: Vec<String> = model
        .unoriented
        .iter()
        .map(|(i, w)| format!("image {} not oriented: {w}", f.images[*i].file))
        .collect();
    for m in &results.methods {
        if let Some(e) = &m.error {
            warnings.push(format!("method {} failed: {e}", m.method));
        }
    }
    let mut summary = vec![
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
                model
                    .points
                    .iter()
                    .filter(|p| p.kind == PointKind::Ball)
                    .count(),
                lrf.found.balls.len(),
                ext.pairs.len()
            ),
        ),
    ];
    if !adj.ball_shifts_px.is_empty() {
        let mut s = adj.ball_shifts_px.clone();
        s.sort_by(|a, b| a.total_cmp(b));
        summary.push((
            "ball eccentricity correction".to_string(),
            format!(
                "median {:.3} px, max {:.3} px",
                s[s.len() / 2],
                s[s.len() - 1]
            ),
        ));
    }
    rp::ReportData {
        title: format!("pingcal calibration — {}", f.name),
        generator: results.generator.clone(),
        summary,
        steps: rep.lines(),
        images,
        network: rp::Network { cameras, points },
        cloud: rp::Cloud {
            points: cloud_points,
            spheres,
        },
        methods,
        intrinsics,
        rejected,
        warnings,
    }
}
