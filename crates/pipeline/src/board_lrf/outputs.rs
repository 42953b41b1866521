//! What a board project writes, as calibrate writes it for the room:
//!
//! - `results.json` ([`results_json`]): the board, the camera with σ, the extrinsic
//!   `camera_from_lrf` with σ in the room's keys (`extrinsic`), what was held and why, the
//!   board's scale where the LRF's ranges fix it (`board_scale`, 1 = as given), per station
//!   the board's corners and the beams on it (`board_beams`, their RMS off the board
//!   `board_beams_rms_mm`, the leave-one-placement-out RMS `loo_rms_mm`), the verdict;
//! - `overlays/<station>.png`: each photograph with its scan drawn through the extrinsic (the
//!   beams on the board in magenta, the rest by range) and the board's corners;
//! - `report.html`, and `ros/`, `opencv/`, `kalibr/` ([`crate::exports`]): the tf from the
//!   camera's optical frame to the LRF's, the camera in OpenCV's and Kalibr's models.

use super::BoardOutcome;
use crate::conventions::ConventionsJson;
use crate::exports::{
    export_loss, kalibr_camchain, opencv_camera_yaml, ros_camera_info, ros_files, OutputFile,
    RosRectification,
};
use crate::results::{extrinsic_json, opencv_of, CameraJson, ExtrinsicJson};
use crate::sphere_calib::outputs::{conventions as sphere_conventions, drawn, TF_CAMERA};
use pingcal_report as rp;
use pingcal_report::overlay::{OverlayPoint, PointKind};
use pingcal_targets::board::PlanarBoard;
use rayon::prelude::*;
use serde_json::json;

/// The tf frame of the LRF.
pub const TF_LRF: &str = "lrf";

/// Everything written besides `results.json`: sphere-calib's kind of outputs (its overlays
/// `overlays/<station>.png`).
pub use crate::sphere_calib::outputs::Outputs;

/// `results.json`'s `conventions`: the sphere-calib run's (one camera, one range sensor),
/// the range sensor being the LRF (its scan plane the XY plane of its frame).
pub fn conventions() -> ConventionsJson {
    let mut c = sphere_conventions();
    c.frames.remove("lidar");
    c.frames.insert(
        "lrf".into(),
        "the LRF's frame: origin at the scanner's centre, its scan plane the XY plane, a beam of angle α along (cos α, sin α, 0); mm; the tf frame 'lrf'".into(),
    );
    for v in c.transforms.values_mut() {
        *v = v.replace("lidar", "lrf");
    }
    c.transforms.retain(|k, _| !k.starts_with("frames[]"));
    c.transforms.insert(
        "stations[].camera_from_board".into(),
        "p_photogrammetric = R p_board + t: the board's frame (origin at inner corner 0, X along its columns, Y along its rows, Z its normal; mm at the LRF's metric scale) in the camera's".into(),
    );
    c.tf_lrf_frame = TF_LRF.into();
    c
}

/// The extrinsic in the forms other programs read.
pub fn extrinsic(o: &BoardOutcome) -> ExtrinsicJson {
    extrinsic_json(
        &o.camera_from_lrf.into(),
        Some(o.sigma_translation_mm),
        Some(o.sigma_opk_deg),
    )
}

/// The camera at the joint adjustment's solution, in `results.json`'s form.
pub fn camera_json(o: &BoardOutcome) -> CameraJson {
    let p = &o.adjustment.problem;
    let names = o.camera.model.parameter_names();
    let sigmas = crate::board_camera::intrinsic_sigmas(p, &o.adjustment.precision);
    let model = o.camera.kind;
    let params = pingcal_project::Intrinsics {
        model,
        values: p.cameras[0].params.clone(),
    };
    CameraJson {
        id: o.camera_id.clone(),
        model_name: (!model.is_default()).then(|| model.name()),
        opencv: opencv_of(
            &params,
            o.camera.width,
            o.camera.height,
            o.camera.pixel_size_mm,
        ),
        params,
        sigma: (names.iter().zip(&sigmas).zip(&o.fixed))
            .filter(|(_, held)| !**held)
            .map(|((n, s), _)| (n.to_string(), *s))
            .collect(),
        high_correlations: Vec::new(),
        pixel_size_mm: o.camera.pixel_size_mm,
    }
}

/// A station's entry of `results.json`.
fn station_json(o: &BoardOutcome, p: &super::Placement) -> serde_json::Value {
    let a = &o.adjustment;
    let Some(v) = p.view else {
        return json!({"station": p.station, "image": p.image, "scan": p.scan, "used": false, "why": p.note});
    };
    let e = &o.errors[v];
    let rms =
        (!e.is_empty()).then(|| (e.iter().map(|e| e * e).sum::<f64>() / e.len() as f64).sqrt());
    let scale = 1.0 + a.range_model()[1];
    let pose = a.problem.images[v].camera_from_object;
    let metric = pingcal_geometry::Rigid3::new(pose.rotation, pose.translation * scale);
    json!({
        "station": p.station,
        "image": p.image,
        "scan": p.scan,
        "used": true,
        "board_corners": o.views[v].detection.corners.len(),
        "corners_rms_px": o.camera_only.placements[v].rms_px,
        "board_beams": a.on_board[v].len(),
        "board_beams_rms_mm": rms,
        "board_beams_rejected": a.rejected[v],
        "loo_rms_mm": o.leave_one_out[v].map(|l| l.rms_mm),
        "loo_chi2": o.leave_one_out[v].map(|l| l.chi2),
        "camera_from_board": extrinsic_json(&metric.into(), None, None),
        "note": p.note,
    })
}

/// The board in `[board]`'s keys.
fn board_json(b: &PlanarBoard) -> serde_json::Value {
    match b {
        PlanarBoard::Chessboard(b) => json!({
            "kind": "chessboard",
            "inner_corners": [b.cols, b.rows],
            "square_mm": b.square_mm,
        }),
        PlanarBoard::Charuco(b) => json!({
            "kind": "charuco",
            "inner_corners": [b.cols, b.rows],
            "square_mm": b.square_mm,
            "marker_mm": b.marker_mm,
            "dictionary": b.dictionary.name(),
        }),
        PlanarBoard::Aprilgrid(b) => json!({
            "kind": "aprilgrid",
            "tags": [b.cols, b.rows],
            "tag_mm": b.tag_mm,
            "tag_spacing": b.spacing,
            "tag_family": b.family.name(),
        }),
    }
}

/// `results.json` of a board project.
pub fn results_json(o: &BoardOutcome) -> serde_json::Value {
    let a = &o.adjustment;
    let names = [
        "omega",
        "phi",
        "kappa",
        "tx",
        "ty",
        "tz",
        "range_offset",
        "range_scale",
    ];
    let held: Vec<_> = (a.held.iter().zip(names))
        .filter_map(|(h, n)| h.as_ref().map(|why| json!({"unknown": n, "why": why})))
        .collect();
    let prec = &a.precision;
    let mut out = json!({
        "pingcal_version": env!("CARGO_PKG_VERSION"),
        "project": o.name,
        "method": "board",
        "conventions": conventions(),
        "board": board_json(&o.board),
        "cameras": [camera_json(o)],
        "extrinsic": extrinsic(o),
        "held": held,
        "range_offset_mm": a.range_model()[0],
        "stations": o.placements.iter().map(|p| station_json(o, p)).collect::<Vec<_>>(),
        "adjustment": {
            "sigma0": prec.sigma0,
            "redundancy": prec.redundancy,
            "observations": prec.observations,
            "unknowns": prec.unknowns,
            "rms_image_px": prec.rms_image_px,
            "variance_components": {"corners": a.scales[0], "beams": a.scales[1]},
        },
        "camera_from_board_only": {
            "rms_px": o.camera_only.rms_px,
            "sigma0": o.camera_only.sigma0,
            "corners": o.camera_only.corners,
        },
        "verdict": o.verdict,
        "warnings": o.warnings,
    });
    if let Some((scale, sigma)) = a.board_scale() {
        let m = out.as_object_mut().expect("an object");
        m.insert("board_scale".into(), json!(scale));
        m.insert("board_scale_sigma".into(), json!(sigma));
    }
    out
}

/// Every file of `ros/`, `opencv/` and `kalibr/`.
pub fn exports(o: &BoardOutcome) -> Vec<OutputFile> {
    let mut out = ros_files(&extrinsic(o), TF_CAMERA, TF_LRF);
    let c = camera_json(o);
    let Some(loss) = export_loss(&c) else {
        return out;
    };
    let id = &o.camera_id;
    out.push((
        format!("opencv/camera_{id}.yaml"),
        opencv_camera_yaml(&c, &loss),
    ));
    out.push((
        format!("ros/camera_info_{id}.yaml"),
        ros_camera_info(&c, &RosRectification::mono(&loss.ros), &loss),
    ));
    out.push((
        "kalibr/camchain.yaml".into(),
        kalibr_camchain(&[(&c, &loss)], None),
    ));
    out
}

/// The points drawn on view `v`'s photograph: its scan through the extrinsic (the beams on
/// the board as the board's, the rest by range; beams behind the camera left out) and the
/// board's corners.
fn overlay_points(o: &BoardOutcome, p: &super::Placement, v: usize) -> Vec<OverlayPoint> {
    let a = &o.adjustment;
    let params = &a.problem.cameras[0].params;
    let k = a.range_model()[0];
    let on: std::collections::BTreeSet<usize> = a.on_board[v].iter().copied().collect();
    let mut pts = Vec::with_capacity(p.beams.len() + o.views[v].detection.corners.len());
    for (i, b) in p.beams.iter().enumerate() {
        let q = o.camera_from_lrf.transform(&b.point_at(b.range_mm - k));
        let Some((x, y)) = (q.y > 0.0).then(|| o.camera.pixel(params, &q)).flatten() else {
            continue;
        };
        let kind = match on.contains(&i) {
            true => PointKind::Ball {
                label: "board".into(),
            },
            false => PointKind::Range {
                range_mm: b.range_mm,
            },
        };
        pts.push(OverlayPoint { x, y, kind });
    }
    for c in &o.views[v].detection.corners {
        pts.push(OverlayPoint {
            x: c.uv[0],
            y: c.uv[1],
            kind: PointKind::Mark {
                rgb: [40, 230, 60],
                size_px: 5.0,
                cross: true,
            },
        });
    }
    pts
}

/// The overlays: per placement with a board, the full-resolution PNG and the report's
/// thumbnail; a photograph that cannot be read again is skipped.
pub fn overlays(o: &BoardOutcome) -> (Vec<(String, Vec<u8>)>, Vec<rp::Overlay>) {
    let drawn: Vec<_> = (o.placements.par_iter())
        .filter_map(|p| {
            let v = p.view?;
            let caption = format!(
                "{}: {} beams on the board (magenta), {} corners (green)",
                p.station,
                o.adjustment.on_board[v].len(),
                o.views[v].detection.corners.len()
            );
            drawn(
                &p.image_path,
                &overlay_points(o, p, v),
                &p.station,
                &caption,
            )
        })
        .collect();
    let mut files = Vec::new();
    let mut report = Vec::new();
    for (name, png, ov) in drawn {
        files.push((name, png));
        report.push(ov);
    }
    (files, report)
}

/// The report's summary lines.
fn summary(o: &BoardOutcome) -> Vec<(String, String)> {
    let a = &o.adjustment;
    let (t, st) = (o.camera_from_lrf.translation, o.sigma_translation_mm);
    let (e, se) = (o.camera_from_lrf.opk_deg(), o.sigma_opk_deg);
    let used = a.on_board.iter().filter(|b| !b.is_empty()).count();
    let mut rows = vec![
        ("board".into(), o.board.describe()),
        (
            "placements with the board / its beams".into(),
            format!("{} / {used} of {}", o.views.len(), o.placements.len()),
        ),
        (
            "t (mm)".into(),
            format!(
                "({:.1}, {:.1}, {:.1}) ± ({:.1}, {:.1}, {:.1})",
                t.x, t.y, t.z, st[0], st[1], st[2]
            ),
        ),
        (
            "ω φ κ (deg)".into(),
            format!(
                "({:.3}, {:.3}, {:.3}) ± ({:.3}, {:.3}, {:.3})",
                e[0], e[1], e[2], se[0], se[1], se[2]
            ),
        ),
        (
            "σ0 of the joint adjustment".into(),
            format!(
                "{:.2} ({} degrees of freedom)",
                a.precision.sigma0, a.precision.redundancy
            ),
        ),
    ];
    if let Some((s, sd)) = a.board_scale() {
        rows.push((
            "board's scale against the LRF".into(),
            format!("{s:.4} ± {sd:.4}"),
        ));
    }
    for why in a.held.iter().flatten() {
        rows.push(("held".into(), why.clone()));
    }
    rows.extend(
        o.placements
            .iter()
            .map(|p| (format!("station {}", p.station), station_line(o, p))),
    );
    rows
}

/// A station's line of the report: its corners, its beams on the board and their RMS, the
/// leave-one-out RMS and χ²; or why it was left out.
fn station_line(o: &BoardOutcome, p: &super::Placement) -> String {
    let Some(v) = p.view else {
        return format!("left out: {}", p.note.clone().unwrap_or_default());
    };
    let e = &o.errors[v];
    let rms = (e.iter().map(|e| e * e).sum::<f64>() / e.len().max(1) as f64).sqrt();
    let loo = match o.leave_one_out[v] {
        Some(l) => format!(
            "; left out, its beams miss the board by {:.1} mm RMS (χ² {:.0} over {})",
            l.rms_mm, l.chi2, l.beams
        ),
        None => String::new(),
    };
    format!(
        "{} corners (RMS {:.3} px), {} beams on the board (RMS {rms:.1} mm){loo}",
        o.views[v].detection.corners.len(),
        o.camera_only.placements[v].rms_px,
        o.adjustment.on_board[v].len()
    )
}

/// The report's data.
pub fn report(o: &BoardOutcome, overlays: Vec<rp::Overlay>) -> rp::ReportData {
    let names = o.camera.model.parameter_names();
    let c = camera_json(o);
    let m = o.camera_from_lrf.rotation;
    let method = rp::MethodResult {
        name: "pingcal (board corners and LRF beams in one adjustment)".into(),
        rotation: [0, 1, 2].map(|i| [m[(i, 0)], m[(i, 1)], m[(i, 2)]]),
        translation_mm: [0, 1, 2].map(|i| o.camera_from_lrf.translation[i]),
        opk_deg: o.camera_from_lrf.opk_deg(),
        sigma_translation_mm: Some(o.sigma_translation_mm),
        sigma_rotation_deg: Some(o.sigma_opk_deg),
        ..Default::default()
    };
    rp::ReportData {
        title: format!("pingcal calibration — {} (board)", o.name),
        generator: format!("pingcal {}", env!("CARGO_PKG_VERSION")),
        verdict: Some(crate::report::verdict(&o.verdict)),
        summary: summary(o),
        methods: vec![method],
        intrinsics: vec![rp::Intrinsics {
            camera: format!("{} ({})", o.camera_id, o.camera.model.name()),
            names: names.iter().map(|s| s.to_string()).collect(),
            units: vec![String::new(); names.len()],
            values: c.params.values.clone(),
            sigmas: names
                .iter()
                .map(|n| c.sigma.get(*n).copied().unwrap_or(f64::NAN))
                .collect(),
            free: o.fixed.iter().map(|f| !f).collect(),
            ..Default::default()
        }],
        rejected: (o.placements.iter())
            .filter(|p| p.view.is_none())
            .map(|p| rp::Rejection {
                what: format!("station {}", p.station),
                why: p.note.clone().unwrap_or_default(),
            })
            .collect(),
        warnings: o.warnings.clone(),
        overlays,
        ..Default::default()
    }
}

/// Everything a run writes besides `results.json`.
pub fn outputs(o: &BoardOutcome) -> Outputs {
    let (overlays, thumbs) = overlays(o);
    Outputs {
        exports: exports(o),
        overlays,
        report_html: rp::render_html(&report(o, thumbs)),
    }
}
