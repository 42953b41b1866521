//! The report of `pingcal sphere-calib`: the same page as calibrate's ([`crate::render_html`])
//! with the sections a single-sphere calibration has, in this order:
//!
//! | id | heading | what it shows |
//! |---|---|---|
//! | (verdict) | | the σ0 test, the leave-one-out consistency, the frames left out and why |
//! | `summary` | Summary | key → value lines |
//! | `extrinsic` | Extrinsic calibration | pingcal's weighted estimate and the published closed form: R, t, ω φ κ with σ |
//! | `extrinsic_precision` | Extrinsic precision | their σ's as bars |
//! | `frames` | Frames | per frame: the lidar's and the camera's centres with σ, how much of the outline was used, the residual and the leave-one-out error, or why the frame was left out |
//! | `checks` | Check points | the leave-one-out errors per frame and method, as calibrate's Figure 7 |
//! | `overlays` | Lidar on the images | each photograph with the lidar drawn on it by the estimated extrinsic, the fitted silhouette and the edge points used |
//! | `intrinsics` | Intrinsics | the camera's parameters (known, not estimated) |
//! | `rejected` | Rejected | the frames left out, with the reason |
//! | `warnings` | Warnings | |
//!
//! [`SphereCalibReport::data`] carries what the shared sections read (title, verdict,
//! summary, methods with their leave-one-out rows, overlays, intrinsics, rejected,
//! warnings); [`SphereCalibReport::frames`] the table of frames.

use crate::fmt::{escape, num, opt_num};
use crate::section::none;
use crate::{charts, render, ReportData};
use serde::{Deserialize, Serialize};
use std::fmt::Write;

/// The sections of the sphere-calib report, in order (ids and headings).
pub(crate) const SPHERE_SECTIONS: [(&str, &str); 9] = [
    ("summary", "Summary"),
    ("extrinsic", "Extrinsic calibration"),
    ("extrinsic_precision", "Extrinsic precision"),
    ("frames", "Frames"),
    ("checks", "Check points"),
    ("overlays", "Lidar on the images"),
    ("intrinsics", "Intrinsics"),
    ("rejected", "Rejected"),
    ("warnings", "Warnings"),
];

/// One frame of the table.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct SphereFrameRow {
    /// The frame's id.
    pub id: String,
    /// Whether it was used.
    pub used: bool,
    /// The lidar's centre (lidar frame, mm) and its σ, when found.
    pub lidar_mm: Option<([f64; 3], [f64; 3])>,
    /// The camera's centre (camera frame, mm) and its σ, when chosen.
    pub camera_mm: Option<([f64; 3], [f64; 3])>,
    /// The fraction of the outline the edge points used cover, and the fraction in the image.
    pub outline: Option<(f64, f64)>,
    /// Sphere silhouettes the image showed.
    pub silhouettes: usize,
    /// How the silhouette was chosen.
    pub chosen_by: String,
    /// The residual of the registration, mm.
    pub residual_mm: Option<f64>,
    /// The leave-one-out error, mm.
    pub loo_mm: Option<f64>,
    /// Why it was left out.
    pub why: String,
}

/// Everything the sphere-calib report shows.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct SphereCalibReport {
    /// The shared sections' data.
    pub data: ReportData,
    /// The frames.
    pub frames: Vec<SphereFrameRow>,
}

fn h2(o: &mut String, id: &str) {
    let title = SPHERE_SECTIONS
        .iter()
        .find(|(i, _)| *i == id)
        .map_or(id, |(_, t)| t);
    let _ = write!(o, "<section id=\"{id}\">\n<h2>{}</h2>\n", escape(title));
}

fn xyz(v: Option<([f64; 3], [f64; 3])>) -> String {
    match v {
        Some((c, s)) => format!(
            "({}, {}, {}) ± ({}, {}, {})",
            num(c[0], 1),
            num(c[1], 1),
            num(c[2], 1),
            num(s[0], 1),
            num(s[1], 1),
            num(s[2], 1)
        ),
        None => "—".into(),
    }
}

fn frames(o: &mut String, r: &SphereCalibReport) {
    h2(o, "frames");
    if r.frames.is_empty() {
        none(o, "no frames");
        o.push_str("</section>\n");
        return;
    }
    o.push_str("<p class=\"note\">The sphere's centre in each sensor's frame (mm, ± one σ: the lidar's from its sphere fit, the camera's from the silhouette's edge points, so a half-hidden outline gives a larger one); <i>outline</i>: the part of the silhouette the edge points used cover, and the part inside the image; <i>silhouettes</i>: the round outlines of the sphere's size found in the image, of which the one consistent with one rigid transform over the frames is the ball (<i>consensus</i>), or the one found again where that transform puts the lidar's sphere (<i>predicted</i>); <i>residual</i>: the registration's; <i>left out</i>: the error when the frame is left out of the registration and predicted by the others.</p>\n");
    o.push_str("<table>\n<tr><th class=\"l\">frame</th><th class=\"l\">lidar centre (mm)</th><th class=\"l\">camera centre (mm)</th><th>outline used / visible</th><th>silhouettes</th><th class=\"l\">chosen by</th><th>residual (mm)</th><th>left out (mm)</th><th class=\"l\">not used because</th></tr>\n");
    for f in &r.frames {
        let _ = writeln!(
            o,
            "<tr{}><td class=\"l\">{}</td><td class=\"l\">{}</td><td class=\"l\">{}</td><td>{}</td><td>{}</td><td class=\"l\">{}</td><td>{}</td><td>{}</td><td class=\"l\">{}</td></tr>",
            if f.used { "" } else { " class=\"hi\"" },
            escape(&f.id),
            xyz(f.lidar_mm),
            xyz(f.camera_mm),
            f.outline.map_or("—".into(), |(u, v)| format!("{:.0} % / {:.0} %", 100.0 * u, 100.0 * v)),
            f.silhouettes,
            escape(&f.chosen_by),
            opt_num(f.residual_mm, 1),
            opt_num(f.loo_mm, 1),
            escape(&f.why)
        );
    }
    o.push_str("</table>\n</section>\n");
}

fn overlays(o: &mut String, d: &ReportData) {
    h2(o, "overlays");
    if d.overlays.is_empty() {
        none(o, "no overlays");
        o.push_str("</section>\n");
        return;
    }
    o.push_str("<p class=\"note\">Each photograph with the lidar's points projected by the estimated extrinsic: the points of the lidar's sphere fit in magenta, its centre as a magenta cross; every other point coloured by its range (turbo colour map, scale bottom right); the silhouette fitted to the photograph in green with its centre as a green cross, the edge points it used in yellow and those it rejected (a stand, a highlight) in red. With a right calibration the magenta points lie on the ball, the magenta cross on the green one, and the other points follow the floor and the walls. The images at full resolution are in the output folder's <code>overlays/</code>.</p>\n<div class=\"grid\">\n");
    for v in &d.overlays {
        crate::overlay_section::figure(o, v);
    }
    o.push_str("</div>\n</section>\n");
}

/// Renders the sphere-calib report as one self-contained HTML5 document (deterministic).
pub fn render_sphere_calib_html(r: &SphereCalibReport) -> String {
    let d = &r.data;
    let mut o = String::with_capacity(
        64 * 1024 + d.overlays.iter().map(|v| v.png_base64.len()).sum::<usize>(),
    );
    render::open_document(&mut o, d, "pingcal sphere-calib report", &SPHERE_SECTIONS);
    render::summary(&mut o, d);
    render::extrinsic(&mut o, d);
    charts::extrinsic_precision(&mut o, d);
    frames(&mut o, r);
    render::checks(&mut o, d);
    overlays(&mut o, d);
    render::intrinsics(&mut o, d);
    render::rejected(&mut o, d);
    render::warnings(&mut o, d);
    o.push_str("</body>\n</html>\n");
    o
}
