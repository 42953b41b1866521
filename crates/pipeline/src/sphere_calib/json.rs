//! `results.json` of `pingcal sphere-calib`.

use super::frames::Frame;
use super::{sd, Outcome};
use nalgebra::Vector3;

type V3 = Vector3<f64>;

/// The coordinates of `x`.
pub fn v(x: &V3) -> [f64; 3] {
    [x.x, x.y, x.z]
}

/// `results.json` of a run.
pub fn results_json(o: &Outcome) -> serde_json::Value {
    let mut main = o.evaluation.to_json();
    let frames: Vec<serde_json::Value> = o.frames.iter().map(|f| frame_json(o, f)).collect();
    let obj = main.as_object_mut().expect("an object");
    obj.insert(
        "conventions".into(),
        serde_json::to_value(super::outputs::conventions()).unwrap_or_default(),
    );
    obj.insert(
        "extrinsic_forms".into(),
        serde_json::to_value(super::outputs::extrinsic(o)).unwrap_or_default(),
    );
    obj.insert(
        "verdict".into(),
        serde_json::to_value(&o.verdict).unwrap_or_default(),
    );
    obj.insert("camera".into(), camera_json(o));
    obj.insert("method".into(), "sphere-calib".into());
    obj.insert("sigma0_sensors".into(), serde_json::json!(o.sensor_sigma0));
    obj.insert("sigma_scale".into(), serde_json::json!(o.sigma_scale));
    obj.insert(
        "noise".into(),
        serde_json::to_value(o.noise).unwrap_or_default(),
    );
    obj.insert("frames".into(), serde_json::Value::Array(frames));
    obj.insert("closed_form".into(), closed_form_json(o));
    obj.insert(
        "sigma_rotation_vector_deg".into(),
        serde_json::json!(v(&o.evaluation.registration.sigma_rotation_vector_deg)),
    );
    main
}

/// A frame's entry of `results.json`: whether it was used (else why not), its lidar and
/// camera spheres, its residual and leave-one-out error.
fn frame_json(o: &Outcome, f: &Frame) -> serde_json::Value {
    let residual = o.evaluation.control.rows.iter().find(|r| r.id == f.id);
    let loo = o
        .evaluation
        .leave_one_out
        .rows
        .iter()
        .find(|r| r.id == f.id);
    serde_json::json!({
        "id": f.id,
        "used": f.skipped.is_none(),
        "skipped": f.skipped,
        "warnings": f.warnings,
        "lidar": f.lidar.as_ref().map(|l| serde_json::json!({
            "centre_mm": v(&l.centre), "sigma_mm": sd(&l.cov), "inliers": l.inliers, "sigma0": l.sigma0,
        })),
        "camera": f.image.as_ref().map(|s| serde_json::json!({
            "centre_mm": v(&s.centre), "sigma_mm": sd(&s.cov),
            "image_centre_px": [s.image_centre.0, s.image_centre.1], "radius_px": s.radius_px,
            "outline_coverage": s.coverage, "outline_visible": s.visible,
            "edge_points": s.edges, "edge_rms_px": s.rms_px, "edge_blur_sigma_px": s.sigma_blur_px, "edge_correlation_inflation": s.inflation,
            "ellipse_px": s.ellipse.map(|e| serde_json::json!({"cx": e.cx, "cy": e.cy, "a": e.a, "b": e.b, "theta_rad": e.theta})),
            "closed_form_centre_mm": s.closed_form.map(|c| v(&c)),
            "chosen_by": f.chosen_by,
        })),
        "silhouettes_found": f.silhouettes,
        "residual": residual,
        "leave_one_out": loo,
    })
}

/// The camera's entry of `results.json`: its file, model, parameters and size.
fn camera_json(o: &Outcome) -> serde_json::Value {
    serde_json::json!({
        "file": o.camera_path,
        "model": o.camera.sensor.model.name(),
        "parameters": o.camera.sensor.model.parameter_names().iter().zip(&o.camera.params).map(|(n, p)| (n.to_string(), *p)).collect::<std::collections::BTreeMap<String, f64>>(),
        "width": o.camera.sensor.width,
        "height": o.camera.sensor.height,
    })
}

/// The closed-form baseline's entry of `results.json` (null without one).
fn closed_form_json(o: &Outcome) -> serde_json::Value {
    let cf = o.closed_form.as_ref().map(|c| {
        let r = &c.registration;
        let m = r.camera_from_lrf.rotation;
        serde_json::json!({
            "method": "Tóth, Pusztai & Hajder 2020: centre from the ellipse's major axis in closed form, unweighted SVD registration",
            "rotation": [[m[(0,0)], m[(0,1)], m[(0,2)]], [m[(1,0)], m[(1,1)], m[(1,2)]], [m[(2,0)], m[(2,1)], m[(2,2)]]],
            "translation_mm": v(&r.camera_from_lrf.translation),
            "opk_deg": r.camera_from_lrf.opk_deg(),
            "sigma_translation_mm": v(&r.sigma_translation_mm),
            "sigma_rotation_deg": v(&r.sigma_opk_deg),
            "sigma_rotation_vector_deg": v(&r.sigma_rotation_vector_deg),
            "rms_residual_mm": r.sigma0,
            "leave_one_out": c.leave_one_out.rows,
            "mean_leave_one_out_error_mm": c.leave_one_out.mean_mm,
        })
    });
    cf.unwrap_or(serde_json::Value::Null)
}
