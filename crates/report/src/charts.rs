//! Plots of the precision and of the image measurements: the extrinsic's σ and correlations,
//! the image-residual histogram, the image coverage and the radial distortion profile.

use crate::fmt::{c, escape, num, DEG, PX, RATIO, SIGMA_MM};
use crate::plot::{axes_with, nice_step, open_chart, svg_open, Frame, MARGIN_LEFT, MARGIN_TOP};
use crate::section::{h2, none};
use crate::{ImageResiduals, Intrinsics, MethodResult, ReportData};
use pingcal_camera::ModelKind;
use std::fmt::Write;

/// Colours of series (methods, cameras).
const COLOURS: [&str; 6] = [
    "#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#8c564b", "#e377c2",
];

/// The names of the extrinsic's six unknowns, in the order of its covariance.
const EXTRINSIC_NAMES: [&str; 6] = ["θx", "θy", "θz", "tx", "ty", "tz"];

/// A plot frame of `w` × `h` pixels over `[x0, x1] × [y0, y1]` (any aspect).
fn frame(x: [f64; 2], y: [f64; 2], w: f64, h: f64) -> Frame {
    Frame {
        x0: x[0],
        x1: x[1],
        y0: y[0],
        y1: y[1],
        left: MARGIN_LEFT,
        top: MARGIN_TOP,
        w,
        h,
    }
}

/// A y range from 0 (or the data's minimum) to a nice number above the maximum.
fn nice_range(lo: f64, hi: f64) -> [f64; 2] {
    let (lo, hi) = (lo.min(0.0), hi.max(0.0));
    let step = nice_step((hi - lo).max(1e-12), 5);
    [
        (lo / step).floor() * step,
        ((hi / step).ceil() * step).max(lo + step),
    ]
}

/// Grouped bars: one group per category, one bar per series (name, colour, values).
fn bars(o: &mut String, cats: &[&str], series: &[(&str, &str, [f64; 3])], ylabel: &str) {
    let max = series
        .iter()
        .flat_map(|s| s.2)
        .filter(|v| v.is_finite())
        .fold(0.0f64, f64::max);
    let f = frame([0.0, cats.len() as f64], nice_range(0.0, max), 300.0, 200.0);
    let (w, h) = f.svg_size();
    svg_open(o, w, h, ylabel);
    axes_with(
        o,
        &f,
        "component (camera frame: X right, Y forward, Z up)",
        ylabel,
        false,
    );
    let bw = 0.8 / series.len().max(1) as f64;
    for (k, (name, col, vals)) in series.iter().enumerate() {
        for (i, v) in vals.iter().enumerate().filter(|(_, v)| v.is_finite()) {
            let x = i as f64 + 0.1 + k as f64 * bw;
            let _ = write!(
                o,
                r#"<rect x="{}" y="{}" width="{}" height="{}" fill="{col}"><title>{} {}: {}</title></rect>"#,
                c(f.px(x)),
                c(f.py(*v)),
                c(bw * f.scale_x()),
                c(f.py(0.0) - f.py(*v)),
                escape(name),
                cats[i],
                num(*v, DEG)
            );
        }
    }
    for (i, cat) in cats.iter().enumerate() {
        let _ = write!(
            o,
            r#"<text class="lbl" x="{}" y="{}" text-anchor="middle">{cat}</text>"#,
            c(f.px(i as f64 + 0.5)),
            c(f.top + f.h + 14.0)
        );
    }
    o.push_str("</svg>\n");
}

/// The methods with σ of the extrinsic, with their colour.
fn with_sigma(d: &ReportData) -> Vec<(&MethodResult, &'static str)> {
    d.methods
        .iter()
        .enumerate()
        .filter(|(_, m)| {
            m.error.is_none()
                && (m.sigma_translation_mm.is_some() || m.sigma_rotation_deg.is_some())
        })
        .map(|(i, m)| (m, COLOURS[i % COLOURS.len()]))
        .collect()
}

/// Bar plots of the extrinsic's σ per method, and each method's correlation matrix.
pub(crate) fn extrinsic_precision(o: &mut String, d: &ReportData) {
    h2(o, "extrinsic_precision");
    let ms = with_sigma(d);
    if ms.is_empty() {
        none(o, "no method estimated the σ of its extrinsic");
        o.push_str("</section>\n");
        return;
    }
    o.push_str("<p class=\"note\">σ of t (mm, along the camera frame's X right, Y forward, Z up) and of ω φ κ (degrees), per method.</p>\n<div class=\"legend\">");
    for (m, col) in &ms {
        let _ = write!(
            o,
            r#"<span class="sw bar" style="background:{col}"></span>{}"#,
            escape(&m.name)
        );
    }
    o.push_str("</div>\n<div class=\"plots\">\n");
    let nan = [f64::NAN; 3];
    let st: Vec<_> = ms
        .iter()
        .map(|(m, col)| (m.name.as_str(), *col, m.sigma_translation_mm.unwrap_or(nan)))
        .collect();
    let sr: Vec<_> = ms
        .iter()
        .map(|(m, col)| (m.name.as_str(), *col, m.sigma_rotation_deg.unwrap_or(nan)))
        .collect();
    o.push_str("<figure>\n");
    bars(o, &["tX", "tY", "tZ"], &st, "σ of t (mm)");
    o.push_str(
        "<figcaption>σ of the translation, camera frame</figcaption>\n</figure>\n<figure>\n",
    );
    bars(o, &["ω", "φ", "κ"], &sr, "σ of ω φ κ (°)");
    o.push_str("<figcaption>σ of the rotation angles</figcaption>\n</figure>\n</div>\n<div class=\"tables\">\n");
    for (m, _) in &ms {
        correlation_table(o, m);
    }
    o.push_str("</div>\n</section>\n");
}

/// The 6 × 6 correlation matrix of one method's extrinsic, |r| > 0.9 highlighted.
fn correlation_table(o: &mut String, m: &MethodResult) {
    let _ = writeln!(
        o,
        "<table>\n<caption>{}: correlations of (θ, t)</caption>",
        escape(&m.name)
    );
    let Some(r) = m.correlation.as_ref().filter(|r| r.len() == 6) else {
        o.push_str("<tr><td class=\"none\">correlations not computed for this method</td></tr>\n</table>\n");
        return;
    };
    o.push_str("<tr><th></th>");
    for n in EXTRINSIC_NAMES {
        let _ = write!(o, "<th>{n}</th>");
    }
    o.push_str("</tr>\n");
    for (i, row) in r.iter().enumerate() {
        let _ = write!(o, "<tr><th class=\"l\">{}</th>", EXTRINSIC_NAMES[i]);
        for (j, v) in row.iter().enumerate() {
            let style = if i != j && v.abs() > 0.9 {
                " style=\"background:#fde0dd;font-weight:bold\""
            } else {
                ""
            };
            let _ = write!(o, "<td{style}>{}</td>", num(*v, RATIO));
        }
        o.push_str("</tr>\n");
    }
    o.push_str("</table>\n");
}

/// The residual components (x and y, px) of the accepted observations.
fn residual_components(d: &ReportData) -> Vec<f64> {
    d.images
        .iter()
        .flat_map(|i| i.points.iter())
        .filter(|p| !p.rejected && p.dx.is_finite() && p.dy.is_finite())
        .flat_map(|p| [p.dx, p.dy])
        .collect()
}

/// Counts of `v` in bins of width `step` from `lo`.
fn bin_counts(v: &[f64], lo: f64, step: f64, n: usize) -> Vec<usize> {
    let mut counts = vec![0; n];
    for x in v {
        let k = ((x - lo) / step).floor();
        if k >= 0.0 && (k as usize) < n {
            counts[k as usize] += 1;
        }
    }
    counts
}

/// Histogram of the image residual components with the normal density of their RMS.
pub(crate) fn histogram(o: &mut String, d: &ReportData) {
    h2(o, "histogram");
    let v = residual_components(d);
    if v.len() < 2 {
        none(o, "no image residuals");
        o.push_str("</section>\n");
        return;
    }
    let rms = (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt();
    let half = (4.0 * rms)
        .max(v.iter().fold(0.0f64, |m, x| m.max(x.abs())).min(6.0 * rms))
        .max(1e-6);
    let step = nice_step(2.0 * half, 30);
    let lo = (-half / step).floor() * step;
    let n = ((2.0 * -lo) / step).round().max(1.0) as usize;
    let counts = bin_counts(&v, lo, step, n);
    let outside = v.len() - counts.iter().sum::<usize>();
    let max = *counts.iter().max().unwrap_or(&1) as f64;
    let f = frame([lo, -lo], nice_range(0.0, max), 560.0, 240.0);
    open_chart(
        o,
        &f,
        "image residual histogram",
        [
            "residual component (px; image x right and y down together)",
            "count",
        ],
    );
    let mut path = String::new();
    for (k, n) in counts.iter().enumerate().filter(|(_, n)| **n > 0) {
        let x = lo + k as f64 * step;
        let _ = write!(
            path,
            "M{} {}H{}V{}H{}Z",
            c(f.px(x)),
            c(f.py(0.0)),
            c(f.px(x + step)),
            c(f.py(*n as f64)),
            c(f.px(x))
        );
    }
    let _ = write!(
        o,
        r##"<path d="{path}" fill="#1f77b4" fill-opacity="0.6" stroke="#1f77b4"/>"##
    );
    normal_curve(o, &f, v.len() as f64 * step, rms);
    o.push_str("</svg>\n");
    let _ = writeln!(
        o,
        "<figcaption>{} residual components (x and y of every accepted observation), bins of {} px; red: the normal density with σ = RMS = {} px; {} beyond the axis.</figcaption>\n</figure>",
        v.len(),
        num(step, PX),
        num(rms, PX),
        outside
    );
    o.push_str("</section>\n");
}

/// The normal density of σ `s`, scaled by `area` (count × bin width).
fn normal_curve(o: &mut String, f: &Frame, area: f64, s: f64) {
    let mut path = String::new();
    for k in 0..=120 {
        let x = f.x0 + (f.x1 - f.x0) * k as f64 / 120.0;
        let y = area / (s * (2.0 * std::f64::consts::PI).sqrt()) * (-0.5 * (x / s).powi(2)).exp();
        let _ = write!(
            path,
            "{}{} {}",
            if k == 0 { "M" } else { "L" },
            c(f.px(x)),
            c(f.py(y.min(f.y1)))
        );
    }
    let _ = write!(
        o,
        r##"<path d="{path}" fill="none" stroke="#d62728" stroke-width="1.5"/>"##
    );
}

/// Cells of a `G` × `G` grid over the image.
const G: usize = 5;

/// Which cells of the grid hold an accepted point.
fn cells_hit(img: &ImageResiduals, w: f64, h: f64) -> [[bool; G]; G] {
    let mut hit = [[false; G]; G];
    for p in img
        .points
        .iter()
        .filter(|p| !p.rejected && p.x.is_finite() && p.y.is_finite())
    {
        let (i, j) = ((p.x / w * G as f64).floor(), (p.y / h * G as f64).floor());
        if (0.0..G as f64).contains(&i) && (0.0..G as f64).contains(&j) {
            hit[j as usize][i as usize] = true;
        }
    }
    hit
}

/// One image's thumbnail: the grid (hit cells shaded) and the points.
fn coverage_svg(o: &mut String, img: &ImageResiduals) {
    let (w, h) = (img.width.max(1) as f64, img.height.max(1) as f64);
    let s = 180.0 / w;
    let (tw, th) = (180.0, h * s);
    let hit = cells_hit(img, w, h);
    let n_hit = hit.iter().flatten().filter(|b| **b).count();
    o.push_str("<figure>\n");
    svg_open(o, tw + 2.0, th + 2.0, &format!("coverage of {}", img.name));
    let _ = write!(
        o,
        r##"<rect x="1" y="1" width="{}" height="{}" fill="#fff" stroke="#888"/>"##,
        c(tw),
        c(th)
    );
    for (j, row) in hit.iter().enumerate() {
        for (i, _) in row.iter().enumerate().filter(|(_, b)| **b) {
            let _ = write!(
                o,
                r##"<rect x="{}" y="{}" width="{}" height="{}" fill="#2ca02c" fill-opacity="0.15"/>"##,
                c(1.0 + i as f64 * tw / G as f64),
                c(1.0 + j as f64 * th / G as f64),
                c(tw / G as f64),
                c(th / G as f64)
            );
        }
    }
    let mut dots = String::new();
    for p in img
        .points
        .iter()
        .filter(|p| !p.rejected && p.x.is_finite() && p.y.is_finite())
    {
        let _ = write!(dots, "M{} {}h0", c(1.0 + p.x * s), c(1.0 + p.y * s));
    }
    let _ = write!(
        o,
        r##"<path d="{dots}" stroke="#1f77b4" stroke-width="3" stroke-linecap="round" fill="none"/>"##
    );
    o.push_str("</svg>\n");
    let _ = writeln!(
        o,
        "<figcaption>{}: {} points, {}/{} cells</figcaption>\n</figure>",
        escape(&img.name),
        img.points.iter().filter(|p| !p.rejected).count(),
        n_hit,
        G * G
    );
}

/// Per image, where its accepted points fell, and how many cells of a 5 × 5 grid they hit.
pub(crate) fn coverage(o: &mut String, d: &ReportData) {
    h2(o, "coverage");
    if d.images.is_empty() {
        none(o, "no images");
        o.push_str("</section>\n");
        return;
    }
    let _ = writeln!(o, "<p class=\"note\">Each image at its aspect ratio: pixel x to the right, y down, origin at the top-left corner. Shaded: the cells of a {G} × {G} grid that hold at least one accepted point (distortion is determined only where there are points; the corners matter most).</p>");
    o.push_str("<div class=\"plots\">\n");
    for img in &d.images {
        coverage_svg(o, img);
    }
    o.push_str("</div>\n</section>\n");
}

/// Δr in µm at radius `r` (mm) of the model's radial terms.
fn delta_r_um(k: [f64; 3], r: f64) -> f64 {
    let r2 = r * r;
    1000.0 * r * r2 * (k[0] + r2 * (k[1] + r2 * k[2]))
}

/// K1 K2 K3 of a camera of a model in mm (the photogrammetric ones) and its largest
/// radius, when it has both.
fn radial(cam: &Intrinsics) -> Option<([f64; 3], f64)> {
    let kind = match cam.model.as_str() {
        "" => Some(ModelKind::DEFAULT),
        name => ModelKind::from_name(name),
    };
    if !kind.is_some_and(ModelKind::in_mm) {
        return None;
    }
    let get = |n: &str| {
        cam.names
            .iter()
            .position(|x| x.eq_ignore_ascii_case(n))
            .and_then(|i| cam.values.get(i).copied())
    };
    let k = [
        get("K1")?,
        get("K2").unwrap_or(0.0),
        get("K3").unwrap_or(0.0),
    ];
    let r = cam.r_max_mm.filter(|r| r.is_finite() && *r > 0.0)?;
    k.iter().all(|v| v.is_finite()).then_some((k, r))
}

/// The lens curves of the cameras that have one: the angle off the optical axis against
/// the radius in the image, beside the pinhole's (f tan θ) and the equidistant lens's (f θ)
/// of the same focal length.
/// A camera's name, its lens curve's points and its focal length (px).
type LensCurve<'a> = (&'a str, &'a Vec<(f64, f64)>, f64);

fn lens_curves(o: &mut String, d: &ReportData) -> bool {
    let cams: Vec<LensCurve> = d
        .intrinsics
        .iter()
        .filter_map(|c| {
            let (pts, f) = c.lens_curve.as_ref()?;
            (pts.len() > 1 && *f > 0.0).then_some((c.camera.as_str(), pts, *f))
        })
        .collect();
    if cams.is_empty() {
        return false;
    }
    let rmax = cams
        .iter()
        .flat_map(|c| c.1.iter().map(|p| p.0))
        .fold(0.0, f64::max);
    let tmax = cams
        .iter()
        .flat_map(|c| c.1.iter().map(|p| p.1))
        .fold(0.0, f64::max);
    let f = frame(
        [0.0, nice_range(0.0, rmax)[1]],
        nice_range(0.0, tmax.max(10.0)),
        560.0,
        260.0,
    );
    open_chart(
        o,
        &f,
        "lens curve",
        [
            "r (px): radius from the principal point in the image",
            "θ (°) off the optical axis",
        ],
    );
    let path = |pts: &[(f64, f64)]| f.path(pts);
    for (k, (_, pts, fl)) in cams.iter().enumerate() {
        let colour = COLOURS[k % COLOURS.len()];
        let r_end = pts.last().map_or(0.0, |p| p.0);
        let refs: [Vec<(f64, f64)>; 2] = [
            (0..=50)
                .map(|i| {
                    let r = r_end * i as f64 / 50.0;
                    (r, (r / fl).atan().to_degrees())
                })
                .collect(),
            (0..=50)
                .map(|i| {
                    let r = r_end * i as f64 / 50.0;
                    (r, (r / fl).to_degrees())
                })
                .filter(|p| p.1 <= f.y1)
                .collect(),
        ];
        for (r, dash) in refs.iter().zip(["6 4", "2 3"]) {
            let _ = write!(
                o,
                r##"<path d="{}" fill="none" stroke="{colour}" stroke-width="1" stroke-dasharray="{dash}"/>"##,
                path(r)
            );
        }
        let _ = write!(
            o,
            r##"<path d="{}" fill="none" stroke="{colour}" stroke-width="2"/>"##,
            path(pts)
        );
    }
    o.push_str("</svg>\n<figcaption>");
    for (k, (name, pts, fl)) in cams.iter().enumerate() {
        let end = pts.last().copied().unwrap_or_default();
        let _ = write!(
            o,
            r#"<span class="sw bar" style="background:{}"></span>{}: θ = {}° at r = {} px (f = {} px) "#,
            COLOURS[k % COLOURS.len()],
            escape(name),
            num(end.1, 1),
            num(end.0, 0),
            num(*fl, 1)
        );
    }
    o.push_str("</figcaption>\n</figure>\n<p class=\"note\">Solid: the camera model's angle θ of the ray through each radius r along the image's longest half-diagonal; dashed: a pinhole of the same focal length (r = f tan θ); dotted: an equidistant lens (r = f θ). A wide-angle lens lies between the two; a fisheye near or beyond the dotted line.</p>\n");
    true
}

/// The radial distortion profile Δr(r) of every camera, to its sensor corner; the lens
/// curve of cameras whose model has no K1–K3.
pub(crate) fn distortion(o: &mut String, d: &ReportData) {
    h2(o, "distortion");
    let curves = lens_curves(o, d);
    let cams: Vec<(&str, [f64; 3], f64)> = d
        .intrinsics
        .iter()
        .filter_map(|c| radial(c).map(|(k, r)| (c.camera.as_str(), k, r)))
        .collect();
    if cams.is_empty() {
        if !curves {
            none(
                o,
                "no radial distortion profile (K1 or the sensor size unknown)",
            );
        }
        o.push_str("</section>\n");
        return;
    }
    let rmax = cams.iter().map(|c| c.2).fold(0.0, f64::max);
    let samples: Vec<Vec<(f64, f64)>> = cams
        .iter()
        .map(|(_, k, r)| {
            (0..=100)
                .map(|i| {
                    let x = r * i as f64 / 100.0;
                    (x, delta_r_um(*k, x))
                })
                .collect()
        })
        .collect();
    let (lo, hi) = samples
        .iter()
        .flatten()
        .fold((0.0f64, 0.0f64), |(a, b), p| (a.min(p.1), b.max(p.1)));
    let f = frame(
        [0.0, nice_range(0.0, rmax)[1]],
        nice_range(lo, hi),
        560.0,
        260.0,
    );
    open_chart(
        o,
        &f,
        "radial distortion profile",
        [
            "r (mm): radial distance from the principal point on the sensor",
            "Δr (µm)",
        ],
    );
    for (k, pts) in samples.iter().enumerate() {
        let path = f.path(pts);
        let _ = write!(
            o,
            r##"<path d="{path}" fill="none" stroke="{}" stroke-width="2"/>"##,
            COLOURS[k % COLOURS.len()]
        );
    }
    o.push_str("</svg>\n<figcaption>");
    for (k, (name, kk, r)) in cams.iter().enumerate() {
        let _ = write!(
            o,
            r#"<span class="sw bar" style="background:{}"></span>{}: Δr = {} µm at the corner (r = {} mm) "#,
            COLOURS[k % COLOURS.len()],
            escape(name),
            num(delta_r_um(*kk, *r), 1),
            num(*r, SIGMA_MM)
        );
    }
    o.push_str("</figcaption>\n</figure>\n<p class=\"note\">Δr = K1 r³ + K2 r⁵ + K3 r⁷, the radial term of the camera model applied forward to the ideal image point (positive: outwards). Australis writes the same terms as corrections to measured coordinates, with roughly the opposite sign.</p>\n</section>\n");
}
