//! What `pingcal sphere-calib` writes beside `results.json`, as calibrate writes it:
//!
//! - `ros/`, `opencv/`, `kalibr/` ([`crate::exports`]): the tf from the camera's optical
//!   frame `camera_optical` to the lidar's frame `lidar`, and the camera's intrinsics in
//!   OpenCV's and Kalibr's models with what each loses against the camera file's own model;
//! - `overlays/<frame>.png` ([`overlays`]): each photograph with the lidar's cloud drawn by
//!   the estimated extrinsic (the sphere's points and centre in magenta, the rest by
//!   range), the fitted silhouette, its centre and the edge points it used;
//! - `report.html` ([`report`], `pingcal_report::render_sphere_calib_html`).
//!
//! The `conventions` block of `results.json` says which frame is which ([`conventions`]).

use super::camera::Camera;
use super::sd;
use super::{Frame, Outcome};
use crate::conventions::ConventionsJson;
use crate::exports::{
    export_loss, kalibr_camchain, opencv_camera_yaml, ros_camera_info, ros_files, ExportLoss,
    OutputFile, RosRectification,
};
use crate::report::check_rows;
use crate::results::{extrinsic_json, opencv_of, CameraJson, ExtrinsicJson};
use pingcal_report as rp;
use pingcal_report::overlay::{render_png, GreyImage, OverlayOptions, OverlayPoint, PointKind};
use rayon::prelude::*;
use std::collections::BTreeMap;

/// The tf frame of the camera's optical frame (x right, y down, z forward).
pub const TF_CAMERA: &str = "camera_optical";
/// The tf frame of the lidar (its clouds' frame).
pub const TF_LIDAR: &str = "lidar";
/// The camera's id in the exports' file names.
pub const CAMERA_ID: &str = "camera";
/// Width of each overlay's thumbnail in the report, px.
pub const THUMB_WIDTH: u32 = 480;

/// Everything written besides `results.json`.
#[derive(Debug)]
pub struct Outputs {
    /// `ros/`, `opencv/`, `kalibr/` files.
    pub exports: Vec<OutputFile>,
    /// `overlays/<frame>.png` and their bytes.
    pub overlays: Vec<(String, Vec<u8>)>,
    /// `report.html`.
    pub report_html: String,
}

fn map(pairs: &[(&str, &str)]) -> BTreeMap<String, String> {
    pairs
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect()
}

/// `results.json`'s `conventions`.
pub fn conventions() -> ConventionsJson {
    ConventionsJson {
        frames: map(&[
            ("photogrammetric", "the camera's frame: origin at its projection centre, X to image right, Y forward along the optical axis, Z to image up; right-handed; mm"),
            ("opencv", "the same camera in OpenCV's camera frame: x right, y down, z forward; p_opencv = C p_photogrammetric = (X, -Z, Y), C = [[1,0,0],[0,0,-1],[0,1,0]]; the ROS optical frame 'camera_optical' (REP 103) has these axes"),
            ("lidar", "the frame of the clouds as given (the lidar's own frame), in mm; the tf frame 'lidar'"),
        ]),
        transforms: map(&[
            ("extrinsic", "p_photogrammetric = R p_lidar + t (rotation, translation_mm, opk_deg); the same in extrinsic_forms (matrix_4x4, quaternion_xyzw)"),
            ("extrinsic_forms.opencv", "p_opencv = R_cv p_lidar + t_cv, R_cv = C R, t_cv = C t (mm)"),
            ("ros/", "tf from parent 'camera_optical' to child 'lidar': the child's pose in the parent, i.e. p_camera_optical = R_cv p_lidar + t_cv / 1000 (m)"),
            ("frames[].lidar.centre_mm, frames[].camera.centre_mm", "the sphere's centre in the lidar frame and in the photogrammetric frame (mm)"),
        ]),
        angles: map(&[
            ("opk_deg", "omega, phi, kappa in degrees, R = R_omega R_phi R_kappa with the passive elementary rotations of photogrammetry, i.e. R = R_x(-omega) R_y(-phi) R_z(-kappa) with active (counter-clockwise) ones: scipy Rotation.from_euler('XYZ', [-omega, -phi, -kappa], degrees=True); sigma_rotation_deg their sigma"),
            ("ros rpy", "roll, pitch, yaw in radians, R = R_z(yaw) R_y(pitch) R_x(roll), active (URDF origin rpy, tf2 setRPY): scipy Rotation.from_euler('xyz', [roll, pitch, yaw])"),
        ]),
        quaternion: "(x, y, z, w): unit, Hamilton, active (it rotates vectors as R does; scipy Rotation.from_quat and tf2/ROS order), w >= 0".into(),
        matrix_4x4: "row-major [[R, t], [0, 0, 0, 1]] of the same transform, t in mm".into(),
        units: "mm in results.json and opencv/; m in ros/ and kalibr/; pixels for OpenCV and Kalibr intrinsics and for image points (origin at the centre of the top-left pixel, x right, y down)".into(),
        main_camera: CAMERA_ID.into(),
        tf_camera_frame: TF_CAMERA.into(),
        tf_lrf_frame: TF_LIDAR.into(),
    }
}

/// The extrinsic in the forms other programs read.
pub fn extrinsic(o: &Outcome) -> ExtrinsicJson {
    let r = &o.evaluation.registration;
    extrinsic_json(
        &r.camera_from_lrf,
        Some([
            r.sigma_translation_mm.x,
            r.sigma_translation_mm.y,
            r.sigma_translation_mm.z,
        ]),
        Some([r.sigma_opk_deg.x, r.sigma_opk_deg.y, r.sigma_opk_deg.z]),
    )
}

/// The camera as calibrate's exports take it (its own model and parameters, in
/// `results.json`'s form), and what each ecosystem's file of it holds and loses
/// ([`export_loss`]); `None` when the model gives no ray on the image.
pub fn camera_export(cam: &Camera) -> Option<(CameraJson, ExportLoss)> {
    let i = &cam.file.intrinsics;
    let c = CameraJson {
        id: CAMERA_ID.into(),
        model_name: (!i.model.is_default()).then(|| i.model.name()),
        params: i.clone(),
        sigma: BTreeMap::new(),
        high_correlations: Vec::new(),
        opencv: opencv_of(
            i,
            cam.sensor.width,
            cam.sensor.height,
            cam.file.pixel_size_mm,
        ),
        pixel_size_mm: cam.file.pixel_size_mm,
    };
    let loss = export_loss(&c)?;
    Some((c, loss))
}

/// Every file of `ros/`, `opencv/` and `kalibr/` of a run (the camera's files only when its
/// model gives rays on the image).
pub fn exports(o: &Outcome) -> Vec<OutputFile> {
    let mut out = ros_files(&extrinsic(o), TF_CAMERA, TF_LIDAR);
    let Some((c, loss)) = camera_export(&o.camera) else {
        return out;
    };
    out.push((
        format!("opencv/camera_{CAMERA_ID}.yaml"),
        opencv_camera_yaml(&c, &loss),
    ));
    out.push((
        format!("ros/camera_info_{CAMERA_ID}.yaml"),
        ros_camera_info(&c, &RosRectification::mono(&loss.ros), &loss),
    ));
    out.push((
        "kalibr/camchain.yaml".into(),
        kalibr_camchain(&[(&c, &loss)], None),
    ));
    for (_, text) in &mut out {
        *text = text.replace("pingcal calibrate", "pingcal sphere-calib");
    }
    out
}

/// The outline `pts` (closed) with points added so that neighbours are at most 1 px apart.
fn dense(pts: &[(f64, f64)]) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    for (i, a) in pts.iter().enumerate() {
        let b = pts[(i + 1) % pts.len()];
        let n = ((b.0 - a.0).hypot(b.1 - a.1).ceil() as usize).clamp(1, 1000);
        for k in 0..n {
            let t = k as f64 / n as f64;
            out.push((a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1)));
        }
    }
    out
}

fn mark(p: (f64, f64), rgb: [u8; 3], size_px: f64, cross: bool) -> OverlayPoint {
    OverlayPoint {
        x: p.0,
        y: p.1,
        kind: PointKind::Mark {
            rgb,
            size_px,
            cross,
        },
    }
}

/// The points drawn on frame `f`'s photograph: its cloud through the extrinsic (points
/// behind the camera left out), the silhouette (chosen, else the best found), its centre,
/// its edge points, and the lidar sphere's centre.
fn overlay_points(o: &Outcome, f: &Frame) -> Vec<OverlayPoint> {
    let t = &o.evaluation.registration.camera_from_lrf;
    let on_sphere: std::collections::BTreeSet<usize> = f.sphere_points.iter().copied().collect();
    let mut pts = Vec::with_capacity(f.cloud.len() + 4000);
    for (i, p) in f.cloud.iter().enumerate() {
        let q = t.transform(p);
        let Some(uv) = (q.y > 0.0).then(|| o.camera.project(&q)).flatten() else {
            continue;
        };
        let kind = if on_sphere.contains(&i) {
            PointKind::Ball {
                label: f.id.clone(),
            }
        } else {
            PointKind::Range { range_mm: p.norm() }
        };
        pts.push(OverlayPoint {
            x: uv.0,
            y: uv.1,
            kind,
        });
    }
    if let Some(s) = f.image.as_ref().or(f.candidates.first()) {
        pts.extend(
            dense(&s.outline)
                .into_iter()
                .map(|p| mark(p, [40, 230, 60], 0.5, false)),
        );
        pts.extend(
            s.rejected
                .iter()
                .map(|&p| mark(p, [255, 60, 40], 1.0, false)),
        );
        pts.extend(
            s.edge_points
                .iter()
                .map(|&p| mark(p, [255, 235, 0], 1.0, false)),
        );
        pts.push(mark(s.image_centre, [40, 230, 60], 9.0, true));
    }
    if let Some(l) = &f.lidar {
        if let Some(uv) = Some(t.transform(&l.centre))
            .filter(|q| q.y > 0.0)
            .and_then(|q| o.camera.project(&q))
        {
            pts.push(mark(uv, rp::overlay::BALL_RGB, 7.0, true));
        }
    }
    pts
}

/// The overlays of a run: per frame, the full-resolution PNG (`overlays/<id>.png`) and the
/// report's thumbnail. A frame whose photograph cannot be read again is skipped.
pub fn overlays(o: &Outcome) -> (Vec<(String, Vec<u8>)>, Vec<rp::Overlay>) {
    let drawn: Vec<Option<(String, Vec<u8>, rp::Overlay)>> = o
        .frames
        .par_iter()
        .map(|f| {
            let caption = match (&f.skipped, &f.image) {
                (None, Some(s)) => format!(
                    "used; silhouette at ({:.0}, {:.0}) px, r {:.0} px, {:.0} % of its outline used",
                    s.image_centre.0,
                    s.image_centre.1,
                    s.radius_px,
                    100.0 * s.coverage
                ),
                (Some(why), _) => format!("left out: {why}"),
                _ => "not used".into(),
            };
            drawn(&f.image_path, &overlay_points(o, f), &f.id, &caption)
        })
        .collect();
    let mut files = Vec::new();
    let mut report = Vec::new();
    for (name, png, ov) in drawn.into_iter().flatten() {
        files.push((name, png));
        report.push(ov);
    }
    (files, report)
}

/// The photograph at `path` with the points `pts` drawn: `overlays/<id>.png` at full
/// resolution and the report's thumbnail of [`THUMB_WIDTH`] with `caption`; None when the
/// photograph cannot be read again.
pub fn drawn(
    path: &std::path::Path,
    pts: &[OverlayPoint],
    id: &str,
    caption: &str,
) -> Option<(String, Vec<u8>, rp::Overlay)> {
    let img = pingcal_targets::load_image(path).ok()?;
    let grey = GreyImage {
        width: img.width as u32,
        height: img.height as u32,
        pixels: pingcal_targets::image_io::to_luma8(&img).into_raw(),
    };
    let full = render_png(&grey, pts, &OverlayOptions::default());
    let small = OverlayOptions {
        max_width: Some(THUMB_WIDTH),
        labels: false,
        small_file: true,
        ..Default::default()
    };
    let thumb = render_png(&grey, pts, &small);
    let name = format!("overlays/{}.png", file_stem(id));
    Some((name, full.png, rp::Overlay::of(id, caption, false, &thumb)))
}

/// A file name made of a frame id (letters, digits, `_ - .`; anything else becomes `_`).
fn file_stem(id: &str) -> String {
    id.replace(
        |c: char| !(c.is_ascii_alphanumeric() || "_-.".contains(c)),
        "_",
    )
}

fn method(
    name: &str,
    r: &pingcal_lrf::registration::Registration,
    control: &[rp::CheckRow],
    loo: &[rp::CheckRow],
) -> rp::MethodResult {
    let m = r.camera_from_lrf.rotation;
    let corr = (r.cov.nrows() >= 6).then(|| {
        let s: Vec<f64> = (0..6).map(|i| r.cov[(i, i)].max(0.0).sqrt()).collect();
        (0..6)
            .map(|i| (0..6).map(|j| r.cov[(i, j)] / (s[i] * s[j])).collect())
            .collect()
    });
    rp::MethodResult {
        name: name.into(),
        rotation: [0, 1, 2].map(|i| [m[(i, 0)], m[(i, 1)], m[(i, 2)]]),
        translation_mm: super::v(&r.camera_from_lrf.translation),
        opk_deg: r.camera_from_lrf.opk_deg(),
        sigma_translation_mm: Some(super::v(&r.sigma_translation_mm)),
        sigma_rotation_deg: Some(super::v(&r.sigma_opk_deg)),
        checks: loo.iter().chain(control).cloned().collect(),
        mean_check_error_mm: None,
        sd_check_error_mm: None,
        error: None,
        correlation: corr,
    }
}

fn frame_rows(o: &Outcome) -> Vec<rp::SphereFrameRow> {
    let ev = &o.evaluation;
    o.frames
        .iter()
        .map(|f| rp::SphereFrameRow {
            id: f.id.clone(),
            used: f.skipped.is_none(),
            lidar_mm: f.lidar.as_ref().map(|l| (super::v(&l.centre), sd(&l.cov))),
            camera_mm: f.image.as_ref().map(|s| (super::v(&s.centre), sd(&s.cov))),
            outline: f.image.as_ref().map(|s| (s.coverage, s.visible)),
            silhouettes: f.silhouettes,
            chosen_by: f.chosen_by.unwrap_or("—").into(),
            residual_mm: ev
                .control
                .rows
                .iter()
                .find(|r| r.id == f.id)
                .map(|r| r.error_mm),
            loo_mm: ev
                .leave_one_out
                .rows
                .iter()
                .find(|r| r.id == f.id)
                .map(|r| r.error_mm),
            why: f.skipped.clone().unwrap_or_default(),
        })
        .collect()
}

fn summary(o: &Outcome) -> Vec<(String, String)> {
    let r = &o.evaluation.registration;
    let (t, st) = (r.camera_from_lrf.translation, r.sigma_translation_mm);
    let (e, se) = (r.camera_from_lrf.opk_deg(), r.sigma_opk_deg);
    let used = o.frames.iter().filter(|f| f.skipped.is_none()).count();
    vec![
        (
            "frames used".into(),
            format!("{used} of {}", o.frames.len()),
        ),
        (
            "t (mm)".into(),
            format!(
                "({:.1}, {:.1}, {:.1}) ± ({:.1}, {:.1}, {:.1})",
                t.x, t.y, t.z, st.x, st.y, st.z
            ),
        ),
        (
            "ω φ κ (deg)".into(),
            format!(
                "({:.3}, {:.3}, {:.3}) ± ({:.3}, {:.3}, {:.3})",
                e[0], e[1], e[2], se.x, se.y, se.z
            ),
        ),
        (
            "σ0 of the registration".into(),
            match o.sigma_scale {
                Some(k) => format!(
                    "{:.2} against the sensors' σ's; every σ scaled by {k:.2}, the scatter of the centres ({} degrees of freedom)",
                    o.sensor_sigma0, r.dof
                ),
                None => format!("{:.2} ({} degrees of freedom)", r.sigma0, r.dof),
            },
        ),
        (
            "mean leave-one-out error".into(),
            format!("{:.1} mm", o.evaluation.leave_one_out.mean_mm),
        ),
        ("sphere diameter".into(), format!("{} mm", o.diameter_mm)),
        (
            "camera".into(),
            format!(
                "{} ({} model, {} × {} px)",
                o.camera_path,
                o.camera.sensor.model.name(),
                o.camera.sensor.width,
                o.camera.sensor.height
            ),
        ),
        ("lidar noise".into(), format!("{:?}", o.noise)),
    ]
}

/// The report's data.
pub fn report(o: &Outcome, overlays: Vec<rp::Overlay>) -> rp::SphereCalibReport {
    let ev = &o.evaluation;
    let mut methods = vec![method(
        "pingcal (silhouette cone fit, weighted registration)",
        &ev.registration,
        &check_rows(&ev.control.rows, "control"),
        &check_rows(&ev.leave_one_out.rows, "loo"),
    )];
    if let Some(cf) = &o.closed_form {
        methods.push(method(
            "closed form (Tóth et al. 2020, unweighted SVD)",
            &cf.registration,
            &[],
            &check_rows(&cf.leave_one_out.rows, "loo"),
        ));
    }
    let names = o.camera.sensor.model.parameter_names();
    let data = rp::ReportData {
        title: format!("pingcal sphere-calib — {}", o.name),
        generator: format!("pingcal {}", env!("CARGO_PKG_VERSION")),
        verdict: Some(crate::report::verdict(&o.verdict)),
        summary: summary(o),
        methods,
        intrinsics: vec![rp::Intrinsics {
            camera: format!("{} ({})", o.camera_path, o.camera.sensor.model.name()),
            names: names.iter().map(|s| s.to_string()).collect(),
            units: vec![String::new(); names.len()],
            values: o.camera.params.clone(),
            sigmas: vec![f64::NAN; names.len()],
            free: vec![false; names.len()],
            ..Default::default()
        }],
        rejected: o
            .frames
            .iter()
            .filter_map(|f| {
                f.skipped.as_ref().map(|why| rp::Rejection {
                    what: format!("frame {}", f.id),
                    why: why.clone(),
                })
            })
            .collect(),
        warnings: o.frames.iter().flat_map(|f| f.warnings.clone()).collect(),
        overlays,
        ..Default::default()
    };
    rp::SphereCalibReport {
        data,
        frames: frame_rows(o),
    }
}

/// Everything a run writes besides `results.json`.
pub fn outputs(o: &Outcome) -> Outputs {
    let (overlays, thumbs) = overlays(o);
    Outputs {
        exports: exports(o),
        overlays,
        report_html: rp::render_sphere_calib_html(&report(o, thumbs)),
    }
}
