//! Tables of the network's precision, as Australis prints them: exterior orientation,
//! point precision, distance residuals, the stereo rig, and the cameras in OpenCV's model.

use crate::fmt::{escape, num, sig, DASH, DEG, MM, PX, RATIO, SIGMA_MM};
use crate::section::{h2, id_cmp, none};
use crate::{NetworkPoint, ReportData};
use std::fmt::Write;

/// A cell per value of `v` (or dashes when `v` is `None`).
fn cells(o: &mut String, v: Option<[f64; 3]>, decimals: usize) {
    for i in 0..3 {
        let _ = write!(
            o,
            "<td>{}</td>",
            v.map_or(DASH.to_string(), |v| num(v[i], decimals))
        );
    }
}

/// The exterior orientation of every image, with σ where the adjustment gives it.
pub(crate) fn exterior(o: &mut String, d: &ReportData) {
    h2(o, "exterior");
    if d.exterior.is_empty() {
        none(o, "no exterior orientation");
        o.push_str("</section>\n");
        return;
    }
    o.push_str("<p class=\"note\">Projection centre X Y Z in mm in the photogrammetric frame (the main image's camera frame: X right, Y forward, Z up); ω φ κ in degrees of the rotation object → camera. The σ of the rotation are those of the small rotations θx θy θz about the camera's own axes, which is what the adjustment's precision gives (not σ of ω φ κ). No σ for an image the adjustment holds (the datum) or derives (a rig member).</p>\n<table>\n<tr><th class=\"l\">image</th><th>X (mm)</th><th>Y (mm)</th><th>Z (mm)</th><th>ω (°)</th><th>φ (°)</th><th>κ (°)</th><th>σX (mm)</th><th>σY (mm)</th><th>σZ (mm)</th><th>σθx (°)</th><th>σθy (°)</th><th>σθz (°)</th><th class=\"l\"></th></tr>\n");
    for e in &d.exterior {
        let _ = write!(o, "<tr><td class=\"l\">{}</td>", escape(&e.name));
        cells(o, Some(e.centre_mm), MM);
        cells(o, Some(e.opk_deg), DEG);
        cells(o, e.sigma_centre_mm, SIGMA_MM);
        cells(o, e.sigma_rotation_deg, DEG);
        let _ = writeln!(o, "<td class=\"l\">{}</td></tr>", escape(&e.note));
    }
    o.push_str("</table>\n</section>\n");
}

/// RMS over the points of each σ component, of their mean, and the field's extent.
struct PointStats {
    rms: [f64; 3],
    mean_sigma: f64,
    extent: f64,
}

fn sigma_ok(p: &NetworkPoint) -> bool {
    p.sigma.iter().all(|s| s.is_finite() && *s > 0.0)
}

fn point_stats(pts: &[&NetworkPoint]) -> PointStats {
    let n = pts.len().max(1) as f64;
    let rms = [0, 1, 2].map(|i| (pts.iter().map(|p| p.sigma[i].powi(2)).sum::<f64>() / n).sqrt());
    let mean_sigma = pts
        .iter()
        .map(|p| (p.sigma.iter().map(|s| s * s).sum::<f64>() / 3.0).sqrt())
        .sum::<f64>()
        / n;
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for p in pts.iter().filter(|p| p.xyz.iter().all(|v| v.is_finite())) {
        for i in 0..3 {
            lo[i] = lo[i].min(p.xyz[i]);
            hi[i] = hi[i].max(p.xyz[i]);
        }
    }
    let extent = (0..3).map(|i| (hi[i] - lo[i]).powi(2)).sum::<f64>().sqrt();
    PointStats {
        rms,
        mean_sigma,
        extent,
    }
}

/// σX σY σZ of every point (naturally sorted), their RMS, and the relative precision.
pub(crate) fn points(o: &mut String, d: &ReportData) {
    h2(o, "points");
    let mut pts: Vec<&NetworkPoint> = d.network.points.iter().filter(|p| sigma_ok(p)).collect();
    if pts.is_empty() {
        none(
            o,
            "no point precision (the adjustment's precision was not computed)",
        );
        o.push_str("</section>\n");
        return;
    }
    pts.sort_by(|a, b| id_cmp(&a.label, &b.label));
    let s = point_stats(&pts);
    let ratio = s.extent / s.mean_sigma;
    let _ = writeln!(
        o,
        "<p>Relative precision <b>1 : {}</b> (field extent {} mm, the diagonal of the points' bounding box, over the mean σ {} mm, σ = √((σX² + σY² + σZ²)/3) per point). Photogrammetric frame, mm.</p>",
        if ratio.is_finite() { format!("{:.0}", ratio) } else { DASH.to_string() },
        num(s.extent, MM),
        num(s.mean_sigma, SIGMA_MM)
    );
    o.push_str("<table>\n<tr><th class=\"l\">point</th><th class=\"l\">kind</th><th>X (mm)</th><th>Y (mm)</th><th>Z (mm)</th><th>σX (mm)</th><th>σY (mm)</th><th>σZ (mm)</th></tr>\n");
    for p in &pts {
        let _ = write!(
            o,
            "<tr><td class=\"l\">{}</td><td class=\"l\">{}</td>",
            escape(&p.label),
            escape(&p.kind)
        );
        cells(o, Some(p.xyz), MM);
        cells(o, Some(p.sigma), SIGMA_MM);
        o.push_str("</tr>\n");
    }
    let _ = write!(
        o,
        "<tr class=\"sum\"><td class=\"l\">RMS</td><td class=\"l\">{} points</td><td></td><td></td><td></td>",
        pts.len()
    );
    cells(o, Some(s.rms), SIGMA_MM);
    o.push_str("</tr>\n</table>\n</section>\n");
}

/// Measured and adjusted distances, the residual and the residual over the a-priori σ.
pub(crate) fn distances(o: &mut String, d: &ReportData) {
    h2(o, "distances");
    if d.distances.is_empty() {
        none(o, "no distances in the adjustment");
        o.push_str("</section>\n");
        return;
    }
    o.push_str("<p class=\"note\">v = adjusted − measured; v/σ uses the measurement's a-priori σ (the standardized residual with its redundancy number is not computed for distances). |v/σ| &gt; 3 is highlighted.</p>\n<table>\n<tr><th class=\"l\">from</th><th class=\"l\">to</th><th>measured (mm)</th><th>adjusted (mm)</th><th>v (mm)</th><th>σ (mm)</th><th>v/σ</th></tr>\n");
    let mut rows: Vec<_> = d.distances.iter().collect();
    rows.sort_by(|a, b| id_cmp(&a.from, &b.from).then(id_cmp(&a.to, &b.to)));
    for r in rows {
        let v = r.adjusted_mm - r.measured_mm;
        let w = v / r.sigma_mm;
        let hi = if w.abs() > 3.0 { " class=\"hi\"" } else { "" };
        let _ = writeln!(
            o,
            "<tr{hi}><td class=\"l\">{}</td><td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            escape(&r.from),
            escape(&r.to),
            num(r.measured_mm, MM),
            num(r.adjusted_mm, MM),
            num(v, SIGMA_MM),
            num(r.sigma_mm, SIGMA_MM),
            num(w, RATIO)
        );
    }
    o.push_str("</table>\n</section>\n");
}

/// The stereo rig's relative orientation, with σ when computed (else said so).
pub(crate) fn rig(o: &mut String, d: &ReportData) {
    h2(o, "rig");
    let Some(r) = &d.rig else {
        none(o, "no stereo rig in this project");
        o.push_str("</section>\n");
        return;
    };
    let _ = writeln!(
        o,
        "<p class=\"note\"><code>p_{r} = R · p_{l} + t</code> (camera frames {l} → {r}: X right, Y forward, Z up); t in mm, ω φ κ of R in degrees; baseline {} mm.</p>",
        num(r.baseline_mm, MM),
        l = escape(&r.left),
        r = escape(&r.right)
    );
    o.push_str("<table>\n<tr><th></th><th>X / ω</th><th>Y / φ</th><th>Z / κ</th></tr>\n<tr><th class=\"l\">t (mm)</th>");
    cells(o, Some(r.translation_mm), MM);
    o.push_str("</tr>\n<tr><th class=\"l\">σ t (mm)</th>");
    cells(o, r.sigma_translation_mm, SIGMA_MM);
    o.push_str("</tr>\n<tr><th class=\"l\">ω φ κ (°)</th>");
    cells(o, Some(r.opk_deg), DEG);
    o.push_str("</tr>\n<tr><th class=\"l\">σ rotation about the right camera's X, Y, Z (°)</th>");
    cells(o, r.sigma_rotation_deg, DEG);
    o.push_str("</tr>\n</table>\n");
    if r.sigma_translation_mm.is_none() || r.sigma_rotation_deg.is_none() {
        none(
            o,
            "σ of the rig not computed: the rig was held fixed or the adjustment gave no precision",
        );
    }
    o.push_str("</section>\n");
}

/// Every sensor's pose to the main camera and every pair's, with σ's (results.json's
/// `sensors` and `sensor_pairs`).
pub(crate) fn sensors(o: &mut String, d: &ReportData) {
    h2(o, "sensors");
    if d.sensors.is_empty() {
        none(o, "no sensor of the head but the main camera");
        o.push_str("</section>\n");
        return;
    }
    o.push_str("<p class=\"note\">Each sensor's <code>p_main = R · p_sensor + t</code> in the main camera's photogrammetric frame (X right, Y forward, Z up; a camera's own frame likewise, the LRF's its own), then each pair's <code>p_a = R · p_b + t</code>; t in mm, ω φ κ of R in degrees, with σ's from the joint adjustment's covariance (a pair's with the two sensors' cross-covariance; — where they came from separate adjustments).</p>\n<table>\n<tr><th class=\"l\">sensor</th><th class=\"l\">kind</th><th>X (mm)</th><th>Y (mm)</th><th>Z (mm)</th><th>ω (°)</th><th>φ (°)</th><th>κ (°)</th><th>σX (mm)</th><th>σY (mm)</th><th>σZ (mm)</th><th>σω (°)</th><th>σφ (°)</th><th>σκ (°)</th></tr>\n");
    for r in d.sensors.iter().chain(&d.sensor_pairs) {
        let _ = write!(
            o,
            "<tr><td class=\"l\">{}</td><td class=\"l\">{}</td>",
            escape(&r.name),
            escape(&r.kind)
        );
        cells(o, Some(r.translation_mm), MM);
        cells(o, Some(r.opk_deg), DEG);
        cells(o, r.sigma_translation_mm, SIGMA_MM);
        cells(o, r.sigma_opk_deg, DEG);
        o.push_str("</tr>\n");
    }
    o.push_str("</table>\n</section>\n");
}

/// Every camera in OpenCV's pinhole model with (k1, k2, p1, p2, k3).
pub(crate) fn opencv(o: &mut String, d: &ReportData) {
    h2(o, "opencv");
    let cams: Vec<_> = d
        .intrinsics
        .iter()
        .filter_map(|c| c.opencv.as_ref().map(|cv| (c.camera.as_str(), cv)))
        .collect();
    if cams.is_empty() {
        none(o, "no OpenCV parameters");
        o.push_str("</section>\n");
        return;
    }
    o.push_str("<p class=\"note\">OpenCV's camera frame (x right, y down, z forward) and pixel convention (the centre of the top-left pixel is (0, 0)); fx fy cx cy in px; the distortion coefficients <code>distCoeffs</code> in OpenCV's order for each camera's model, as in <code>opencv/</code>'s files.</p>\n<table>\n<tr><th class=\"l\">camera</th><th>width</th><th>height</th><th>fx (px)</th><th>fy (px)</th><th>cx (px)</th><th>cy (px)</th><th class=\"l\">model</th><th class=\"l\">distCoeffs</th></tr>\n");
    for (name, cv) in cams {
        let _ = write!(
            o,
            "<tr><td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td class=\"l\">{}</td>",
            escape(name),
            cv.width,
            cv.height,
            num(cv.fx, PX),
            num(cv.fy, PX),
            num(cv.cx, PX),
            num(cv.cy, PX),
            escape(&cv.distortion_model)
        );
        let dist: Vec<String> = cv.dist.iter().map(|k| sig(*k)).collect();
        let _ = write!(o, "<td class=\"l\">({})</td>", dist.join(", "));
        o.push_str("</tr>\n");
    }
    o.push_str("</table>\n");
    export_losses(o, d);
    o.push_str("</section>\n");
}

/// A loss beyond this many pixels is highlighted.
const NOTED_LOSS_PX: f64 = 0.05;

/// What each export's model loses against pingcal's over the whole image.
fn export_losses(o: &mut String, d: &ReportData) {
    if d.export_losses.is_empty() {
        return;
    }
    let _ = writeln!(o, "<table>\n<caption>What each export loses against pingcal's model: the distance between a pixel and the projection of pingcal's ray of it through the exported model, over a grid of the whole image (rows over {NOTED_LOSS_PX} px highlighted: use pingcal's model where that matters)</caption>\n<tr><th class=\"l\">camera</th><th class=\"l\">files</th><th class=\"l\">model</th><th>largest (px)</th><th>RMS (px)</th></tr>");
    for r in &d.export_losses {
        let hi = if r.max_px > NOTED_LOSS_PX {
            " class=\"hi\""
        } else {
            ""
        };
        let _ = writeln!(
            o,
            "<tr{hi}><td class=\"l\">{}</td><td class=\"l\">{}</td><td class=\"l\">{}</td><td>{}</td><td>{}</td></tr>",
            escape(&r.camera),
            escape(&r.files),
            escape(&r.model),
            num(r.max_px, 3),
            num(r.rms_px, 3)
        );
    }
    o.push_str("</table>\n");
}
