//! The HTML document and its sections.

use crate::fmt::{c, escape, num, opt_num, sig, DASH};
use crate::plot::{
    axes, nice_number, nice_step, quantile, svg_open, ticks, Bounds, Frame, LabelPlacer,
    MARGIN_LEFT, MARGIN_TOP,
};
use crate::section::{h2, id_cmp, none, SECTIONS};
use crate::{charts, tables, CheckRow, ImageResiduals, MethodResult, NetworkPoint, ReportData};
use std::fmt::Write;

const STYLE: &str = r#"
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,"Helvetica Neue",Arial,sans-serif;margin:0 auto;max-width:1360px;padding:0 18px 40px;color:#222;line-height:1.4;background:#fff}
h1{font-size:1.55em;margin:.7em 0 .1em}
h2{font-size:1.25em;border-bottom:2px solid #ccc;padding-bottom:2px;margin-top:1.8em}
h3{font-size:1.05em;margin:1em 0 .3em}
p.gen{color:#666;margin:0 0 .8em}
div.verdict{border:2px solid #999;padding:4px 14px;margin:.6em 0;display:inline-block}
div.verdict.ok{border-color:#2a8a2a;background:#f0faf0}
div.verdict.doubtful{border-color:#c88a00;background:#fff8e6}
div.verdict.failed{border-color:#b22;background:#fdeeee}
nav.toc{background:#f6f6f6;border:1px solid #ddd;padding:4px 14px;display:inline-block}
nav.toc ol{margin:.3em 0;padding-left:1.4em;columns:2;column-gap:3em}
table{border-collapse:collapse;margin:.4em 0 1em;font-size:13px}
caption{text-align:left;font-weight:bold;padding:2px 0}
th,td{border:1px solid #ccc;padding:2px 7px;text-align:right;font-variant-numeric:tabular-nums;vertical-align:top}
th{background:#f2f2f2}
.l{text-align:left}
.err{color:#b00;font-weight:bold}
tr.hi td{background:#fde0dd;font-weight:bold}
tr.sum td{background:#f7f7f7;font-weight:bold}
ul.warn li{color:#8a4b00}
.none{color:#777;font-style:italic}
.note{color:#444;font-size:13px;max-width:70em}
.grid{display:grid;grid-template-columns:repeat(auto-fill,minmax(320px,1fr));gap:10px}
.plots{display:flex;flex-wrap:wrap;gap:18px;align-items:flex-start}
.tables{display:flex;flex-wrap:wrap;gap:24px;align-items:flex-start}
figure{margin:0;border:1px solid #ddd;padding:4px;background:#fafafa}
figcaption{font-size:12px;color:#333}
svg{max-width:100%;height:auto;display:block}
svg text{font-size:11px;fill:#333}
svg text.axis{font-size:12px;fill:#000}
svg text.lbl{font-size:10px;fill:#000}
.legend{font-size:13px;margin:.2em 0 .4em}
.sw{display:inline-block;width:11px;height:11px;border-radius:50%;margin:0 4px 0 12px;vertical-align:-1px}
.bar{border-radius:0}
details{margin:.4em 0}
ol.steps{font-family:ui-monospace,Menlo,Consolas,monospace;font-size:12px}
"#;

/// Colours of point kinds (also used for the legend).
const KINDS: [(&str, &str); 3] = [
    ("plain", "#2ca02c"),
    ("coded", "#1f77b4"),
    ("ball", "#ff7f0e"),
];
const OTHER_KIND: &str = "#7f7f7f";
/// Colours of methods in the check-point chart.
const METHOD_COLOURS: [&str; 6] = [
    "#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#8c564b", "#e377c2",
];

/// Index of a kind in drawing order (plain, coded, ball, other).
fn kind_index(kind: &str) -> usize {
    KINDS
        .iter()
        .position(|(k, _)| k.eq_ignore_ascii_case(kind.trim()))
        .unwrap_or(KINDS.len())
}

fn kind_legend(o: &mut String, with_camera: bool) {
    o.push_str(r#"<div class="legend">"#);
    for (k, col) in KINDS {
        let _ = write!(o, r#"<span class="sw" style="background:{col}"></span>{k}"#);
    }
    if with_camera {
        o.push_str(r#"<span class="sw" style="background:#9467bd;border-radius:0"></span>camera (wedge along the viewing direction)<span class="sw" style="background:#d62728;border-radius:0"></span>main station"#);
    }
    o.push_str("</div>\n");
}

pub(crate) fn document(d: &ReportData) -> String {
    let mut o = String::with_capacity(64 * 1024 + d.cloud.points.len() * 32);
    open_document(&mut o, d, "pingcal calibration report", &SECTIONS);
    summary(&mut o, d);
    extrinsic(&mut o, d);
    charts::extrinsic_precision(&mut o, d);
    checks(&mut o, d);
    images(&mut o, d);
    charts::histogram(&mut o, d);
    charts::coverage(&mut o, d);
    network(&mut o, d);
    tables::exterior(&mut o, d);
    tables::points(&mut o, d);
    tables::distances(&mut o, d);
    tables::rig(&mut o, d);
    cloud(&mut o, d);
    crate::overlay_section::overlays(&mut o, d);
    intrinsics(&mut o, d);
    charts::distortion(&mut o, d);
    tables::opencv(&mut o, d);
    mount(&mut o, d);
    rejected(&mut o, d);
    warnings(&mut o, d);
    steps(&mut o, d);
    o.push_str("</body>\n</html>\n");
    o
}

/// The document's head, its title, the verdict and the table of contents of `sections`
/// (ids and headings, in order); `fallback`: the title when `d` has none.
pub(crate) fn open_document(
    o: &mut String,
    d: &ReportData,
    fallback: &str,
    sections: &[(&str, &str)],
) {
    let title = if d.title.trim().is_empty() {
        fallback
    } else {
        d.title.as_str()
    };
    o.push_str("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\"/>\n");
    o.push_str("<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\"/>\n");
    if !d.generator.is_empty() {
        let _ = writeln!(
            o,
            "<meta name=\"generator\" content=\"{}\"/>",
            escape(&d.generator)
        );
    }
    let _ = writeln!(o, "<title>{}</title>", escape(title));
    let _ = writeln!(o, "<style>{STYLE}</style>\n</head>\n<body>");
    let _ = writeln!(o, "<header>\n<h1>{}</h1>", escape(title));
    if !d.generator.is_empty() {
        let _ = writeln!(
            o,
            r#"<p class="gen">Generated by {}</p>"#,
            escape(&d.generator)
        );
    }
    if let Some(v) = &d.verdict {
        verdict(o, v);
    }
    toc(o, d, sections);
    o.push_str("</header>\n");
}

fn toc(o: &mut String, d: &ReportData, sections: &[(&str, &str)]) {
    o.push_str("<nav class=\"toc\"><ol>\n");
    for &(id, title) in sections {
        let count = match id {
            "images" => Some(d.images.len()),
            "overlays" => Some(d.overlays.len()),
            "rejected" => Some(d.rejected.len()),
            "warnings" => Some(d.warnings.len()),
            "steps" => Some(d.steps.len()),
            _ => None,
        };
        let count = count.map_or(String::new(), |n| format!(" ({n})"));
        let _ = writeln!(o, "<li><a href=\"#{id}\">{title}</a>{count}</li>");
    }
    o.push_str("</ol></nav>\n");
}

pub(crate) fn summary(o: &mut String, d: &ReportData) {
    h2(o, "summary");
    if d.summary.is_empty() {
        none(o, "no summary");
    } else {
        o.push_str("<table>\n");
        for (k, v) in &d.summary {
            let _ = writeln!(
                o,
                "<tr><th class=\"l\">{}</th><td class=\"l\">{}</td></tr>",
                escape(k),
                escape(v)
            );
        }
        o.push_str("</table>\n");
    }
    o.push_str("</section>\n");
}

// ---------------------------------------------------------------------------------------
// Extrinsic

/// The verdict box: status, reasons, and the tests with their bounds.
fn verdict(o: &mut String, v: &crate::Verdict) {
    let _ = writeln!(
        o,
        r#"<div class="verdict {s}" id="verdict"><p><b>Verdict: {s}</b></p>"#,
        s = escape(&v.status)
    );
    if !v.reasons.is_empty() {
        o.push_str("<ul>\n");
        for r in &v.reasons {
            let _ = writeln!(o, "<li>{}</li>", escape(r));
        }
        o.push_str("</ul>\n");
    }
    if !v.notes.is_empty() {
        o.push_str(
            "<p class=\"note\">Notes (they do not change the verdict):</p><ul class=\"note\">\n",
        );
        for r in &v.notes {
            let _ = writeln!(o, "<li>{}</li>", escape(r));
        }
        o.push_str("</ul>\n");
    }
    let _ = writeln!(
        o,
        "<table><tr><th class=\"l\">test (level {})</th><th>value</th><th>bound</th><th>passed</th></tr>",
        num(v.alpha, 2)
    );
    for c in &v.checks {
        let _ = writeln!(
            o,
            "<tr><td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            escape(&c.name),
            num(c.value, 3),
            num(c.bound, 3),
            if c.passed { "yes" } else { "no" }
        );
    }
    o.push_str("</table></div>\n");
}

fn with_sigma(v: f64, s: Option<f64>, decimals: usize, sdec: usize) -> String {
    match s {
        Some(s) if s.is_finite() => format!("{} ± {}", num(v, decimals), num(s, sdec)),
        _ => num(v, decimals),
    }
}

pub(crate) fn extrinsic(o: &mut String, d: &ReportData) {
    h2(o, "extrinsic");
    if d.methods.is_empty() {
        none(o, "no extrinsic calibration");
    } else {
        o.push_str(
            "<p class=\"note\"><code>p_camera = R · p_lrf + t</code>; t in mm, ω φ κ in degrees, ± one σ where estimated.</p>\n<div class=\"tables\">\n",
        );
    }
    for m in &d.methods {
        let _ = writeln!(o, "<div>\n<h3>{}</h3>", escape(&m.name));
        if let Some(e) = &m.error {
            let _ = writeln!(o, "<p class=\"err\">failed: {}</p>\n</div>", escape(e));
            continue;
        }
        o.push_str("<table>\n<tr><th class=\"l\">R</th><th>1</th><th>2</th><th>3</th></tr>\n");
        for (i, row) in m.rotation.iter().enumerate() {
            let _ = write!(o, "<tr><th class=\"l\">{}</th>", i + 1);
            for v in row {
                let _ = write!(o, "<td>{}</td>", num(*v, 6));
            }
            o.push_str("</tr>\n");
        }
        o.push_str("</table>\n<table>\n<tr><th></th><th>X / ω</th><th>Y / φ</th><th>Z / κ</th></tr>\n<tr><th class=\"l\">t (mm)</th>");
        for i in 0..3 {
            let s = m.sigma_translation_mm.map(|s| s[i]);
            let _ = write!(o, "<td>{}</td>", with_sigma(m.translation_mm[i], s, 2, 2));
        }
        o.push_str("</tr>\n<tr><th class=\"l\">ω φ κ (deg)</th>");
        for i in 0..3 {
            let s = m.sigma_rotation_deg.map(|s| s[i]);
            let _ = write!(o, "<td>{}</td>", with_sigma(m.opk_deg[i], s, 4, 4));
        }
        o.push_str("</tr>\n</table>\n");
        let (mean, sd, role) = check_stats(m);
        if role.is_some() || m.mean_check_error_mm.is_some() {
            let _ = writeln!(
                o,
                "<p>mean {} error {} mm (sd {} mm)</p>",
                role.unwrap_or("check"),
                opt_num(mean, 2),
                opt_num(sd, 2)
            );
        }
        o.push_str("</div>\n");
    }
    if !d.methods.is_empty() {
        o.push_str("</div>\n");
    }
    o.push_str("</section>\n");
}

// ---------------------------------------------------------------------------------------
// Check points (the paper's Figure 7)

/// The rows a method contributes to the chart: its "check" rows, or its "loo" rows when it
/// has no check rows; with the role used.
fn plotted_rows(m: &MethodResult) -> (Option<&'static str>, Vec<&CheckRow>) {
    for role in ["check", "loo"] {
        let rows: Vec<&CheckRow> = m
            .checks
            .iter()
            .filter(|r| r.role.trim().eq_ignore_ascii_case(role))
            .collect();
        if !rows.is_empty() {
            return (Some(role), rows);
        }
    }
    (None, Vec::new())
}

fn mean_sd(v: &[f64]) -> (Option<f64>, Option<f64>) {
    let v: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return (None, None);
    }
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    let sd = if v.len() > 1 {
        Some((v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt())
    } else {
        None
    };
    (Some(mean), sd)
}

/// Mean and sd of the plotted rows: the method's own numbers for check rows when given,
/// computed from the rows otherwise.
fn check_stats(m: &MethodResult) -> (Option<f64>, Option<f64>, Option<&'static str>) {
    let (role, rows) = plotted_rows(m);
    let errs: Vec<f64> = rows.iter().map(|r| r.error_mm).collect();
    let (cm, cs) = mean_sd(&errs);
    if role == Some("check") || role.is_none() {
        (
            m.mean_check_error_mm.or(cm),
            m.sd_check_error_mm.or(cs),
            role,
        )
    } else {
        (cm, cs, role)
    }
}

pub(crate) fn checks(o: &mut String, d: &ReportData) {
    h2(o, "checks");
    struct Series<'a> {
        name: &'a str,
        role: &'static str,
        colour: &'static str,
        rows: Vec<&'a CheckRow>,
        mean: Option<f64>,
    }
    let mut series = Vec::new();
    for (i, m) in d.methods.iter().enumerate() {
        let (role, rows) = plotted_rows(m);
        if let Some(role) = role {
            let (mean, _, _) = check_stats(m);
            series.push(Series {
                name: &m.name,
                role,
                colour: METHOD_COLOURS[i % METHOD_COLOURS.len()],
                rows,
                mean,
            });
        }
    }
    if series.is_empty() {
        none(o, "no check points");
    } else {
        let mut ids: Vec<&str> = series
            .iter()
            .flat_map(|s| s.rows.iter().map(|r| r.id.as_str()))
            .collect();
        ids.sort_by(|a, b| id_cmp(a, b));
        ids.dedup();
        o.push_str("<div class=\"legend\">");
        for s in &series {
            let _ = write!(
                o,
                "<span class=\"sw bar\" style=\"background:{}\"></span>{} ({} points, mean {} mm)",
                s.colour,
                escape(s.name),
                s.role,
                opt_num(s.mean, 1)
            );
        }
        o.push_str("</div>\n");
        bar_chart(
            o,
            &ids,
            &series
                .iter()
                .map(|s| (s.name, s.colour, &s.rows[..], s.mean))
                .collect::<Vec<_>>(),
        );
        let _ = writeln!(
            o,
            "<p class=\"note\">Error = length of the difference between the transformed LRF ball centre and the photogrammetric one, per {} ball; dashed lines: the means.</p>",
            if series.iter().all(|s| s.role == "check") { "check" } else { "check (or leave-one-out)" }
        );
    }
    // Tables: every row (control, check, loo) of every method.
    let with_rows: Vec<&MethodResult> = d.methods.iter().filter(|m| !m.checks.is_empty()).collect();
    if !with_rows.is_empty() {
        o.push_str("<div class=\"tables\">\n");
        for m in with_rows {
            let _ = writeln!(
                o,
                "<table>\n<caption>{}</caption>\n<tr><th class=\"l\">id</th><th class=\"l\">role</th><th>dx (mm)</th><th>dy (mm)</th><th>dz (mm)</th><th>error (mm)</th></tr>",
                escape(&m.name)
            );
            let mut rows: Vec<&CheckRow> = m.checks.iter().collect();
            rows.sort_by(|a, b| {
                role_rank(&a.role)
                    .cmp(&role_rank(&b.role))
                    .then(id_cmp(&a.id, &b.id))
            });
            for r in rows {
                let _ = writeln!(
                    o,
                    "<tr><td class=\"l\">{}</td><td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                    escape(&r.id),
                    escape(role_label(&r.role)),
                    num(r.dx_mm, 2),
                    num(r.dy_mm, 2),
                    num(r.dz_mm, 2),
                    num(r.error_mm, 2)
                );
            }
            let (mean, sd, role) = check_stats(m);
            let role = role.unwrap_or("check");
            let _ = writeln!(
                o,
                "<tr class=\"sum\"><td class=\"l\" colspan=\"5\">mean {role} error</td><td>{}</td></tr>\n<tr class=\"sum\"><td class=\"l\" colspan=\"5\">sd {role} error</td><td>{}</td></tr>\n</table>",
                opt_num(mean, 2),
                opt_num(sd, 2)
            );
        }
        o.push_str("</div>\n");
        if d.methods
            .iter()
            .any(|m| m.checks.iter().any(|r| r.role == "loo"))
        {
            o.push_str("<p class=\"note\">left out (leave-one-out): each control ball in turn left out of the registration and transformed with the extrinsic from the others; its error says how well the rest predicts it.</p>\n");
        }
    }
    o.push_str("</section>\n");
}

/// How a row's role reads in the tables.
fn role_label(role: &str) -> &str {
    match role {
        "loo" => "left out",
        other => other,
    }
}

fn role_rank(role: &str) -> u8 {
    match role.trim().to_ascii_lowercase().as_str() {
        "check" => 0,
        "loo" => 1,
        "control" => 2,
        _ => 3,
    }
}

type BarSeries<'a> = (&'a str, &'static str, &'a [&'a CheckRow], Option<f64>);

fn bar_chart(o: &mut String, ids: &[&str], series: &[BarSeries<'_>]) {
    let n = ids.len().max(1);
    let m = series.len().max(1);
    let group_px = (22.0 * m as f64 + 20.0).clamp(40.0, 140.0);
    let plot_w = (group_px * n as f64).clamp(480.0, 1000.0);
    let plot_h = 320.0;
    const LABEL_MARGIN: f64 = 96.0;
    let mut ymax: f64 = 0.0;
    for (_, _, rows, mean) in series {
        for r in rows.iter() {
            if r.error_mm.is_finite() {
                ymax = ymax.max(r.error_mm);
            }
        }
        if let Some(mv) = mean.filter(|v| v.is_finite()) {
            ymax = ymax.max(mv);
        }
    }
    if ymax <= 0.0 {
        ymax = 1.0;
    }
    let step = nice_step(ymax * 1.08, 6);
    let y1 = (ymax * 1.08 / step).ceil() * step;
    let f = Frame {
        x0: 0.0,
        x1: n as f64,
        y0: 0.0,
        y1,
        left: MARGIN_LEFT,
        top: MARGIN_TOP,
        w: plot_w,
        h: plot_h,
    };
    let (w, h) = f.svg_size();
    svg_open(
        o,
        w + LABEL_MARGIN,
        h,
        "check-point error per ball and method",
    );
    // y grid and ticks only (x is categorical)
    let mut grid = String::new();
    let mut labels = String::new();
    for v in ticks(0.0, y1, step) {
        let y = f.py(v);
        let _ = write!(grid, "M{} {}H{}", c(f.left - 4.0), c(y), c(f.left + f.w));
        let _ = write!(
            labels,
            r#"<text x="{}" y="{}" text-anchor="end">{}</text>"#,
            c(f.left - 6.0),
            c(y + 3.5),
            crate::fmt::tick_label(v, step)
        );
    }
    let _ = write!(
        o,
        r##"<rect x="{}" y="{}" width="{}" height="{}" fill="#fff" stroke="#888"/><path d="{grid}" stroke="#ddd" fill="none"/><g>{labels}</g>"##,
        c(f.left),
        c(f.top),
        c(f.w),
        c(f.h)
    );
    let bw = 0.8 / m as f64;
    for (i, id) in ids.iter().enumerate() {
        for (j, (name, colour, rows, _)) in series.iter().enumerate() {
            let Some(r) = rows.iter().find(|r| r.id == *id) else {
                continue;
            };
            if !r.error_mm.is_finite() {
                continue;
            }
            let x = f.px(i as f64 + 0.1 + j as f64 * bw);
            let y = f.py(r.error_mm.max(0.0));
            let _ = write!(
                o,
                r#"<rect x="{}" y="{}" width="{}" height="{}" fill="{colour}"><title>{}: ball {} error {} mm</title></rect>"#,
                c(x),
                c(y),
                c(bw * f.scale_x() - 1.0),
                c(f.py(0.0) - y),
                escape(name),
                escape(id),
                num(r.error_mm, 2)
            );
        }
        let _ = write!(
            o,
            r#"<text class="axis" x="{}" y="{}" text-anchor="middle">{}</text>"#,
            c(f.px(i as f64 + 0.5)),
            c(f.top + f.h + 15.0),
            escape(id)
        );
    }
    // Mean lines, labelled in the right margin, labels nudged apart when close.
    let mut used: Vec<f64> = Vec::new();
    for (_, colour, _, mean) in series {
        let Some(mv) = mean.filter(|v| v.is_finite()) else {
            continue;
        };
        let y = f.py(mv);
        let _ = write!(
            o,
            r#"<path d="M{} {}H{}" stroke="{colour}" stroke-width="1.6" stroke-dasharray="6 4"/>"#,
            c(f.left),
            c(y),
            c(f.left + f.w)
        );
        let mut ty = y + 4.0;
        while used.iter().any(|u| (u - ty).abs() < 13.0) {
            ty -= 13.0;
        }
        used.push(ty);
        let _ = write!(
            o,
            r#"<text x="{}" y="{}" style="fill:{colour};font-weight:bold">mean {} mm</text>"#,
            c(f.left + f.w + 6.0),
            c(ty),
            num(mv, 1)
        );
    }
    let _ = write!(
        o,
        r#"<text class="axis" x="{}" y="{}" text-anchor="middle">ball id</text><text class="axis" transform="translate(14 {}) rotate(-90)" text-anchor="middle">check-point error (mm)</text>"#,
        c(f.left + 0.5 * f.w),
        c(f.top + f.h + 32.0),
        c(f.top + 0.5 * f.h)
    );
    o.push_str("</svg>\n");
}

// ---------------------------------------------------------------------------------------
// Image residuals

fn image_size(img: &ImageResiduals) -> (f64, f64) {
    let max = |f: fn(&crate::ImagePoint) -> f64| {
        img.points
            .iter()
            .map(f)
            .filter(|v| v.is_finite())
            .fold(1.0f64, f64::max)
    };
    let w = if img.width > 0 {
        img.width as f64
    } else {
        max(|p| p.x).ceil()
    };
    let h = if img.height > 0 {
        img.height as f64
    } else {
        max(|p| p.y).ceil()
    };
    (w, h)
}

fn residual_ok(p: &crate::ImagePoint) -> bool {
    !p.rejected && p.dx.is_finite() && p.dy.is_finite()
}

fn images(o: &mut String, d: &ReportData) {
    h2(o, "images");
    if d.images.is_empty() {
        none(o, "no image residuals");
        o.push_str("</section>\n");
        return;
    }
    let mags: Vec<f64> = d
        .images
        .iter()
        .flat_map(|i| i.points.iter())
        .filter(|p| residual_ok(p))
        .map(|p| p.dx.hypot(p.dy))
        .collect();
    let mut widths: Vec<f64> = d.images.iter().map(|i| image_size(i).0).collect();
    widths.sort_by(f64::total_cmp);
    let width = widths[widths.len() / 2];
    let p95 = quantile(&mags, 0.95).filter(|v| *v > 0.0);
    let factor = p95.map_or(1.0, |p| nice_number(0.03 * width / p));
    let bar_px = nice_number(0.1 * width / factor);
    let _ = writeln!(
        o,
        "<p class=\"note\">Residual vectors (observed − computed) magnified <b>×{}</b>, chosen so that the 95th-percentile residual ({} px) is about 3 % of the image width; scale bar: {} px of residual. Rejected observations: red ×, not in the RMS.</p>",
        sig_trim(factor),
        p95.map_or(DASH.to_string(), |p| num(p, 3)),
        sig_trim(bar_px)
    );
    kind_legend(o, false);
    // RMS table
    o.push_str("<table>\n<tr><th class=\"l\">image</th><th>points</th><th>rejected</th><th>RMS x (px)</th><th>RMS y (px)</th><th>RMS (px)</th><th>max (px)</th></tr>\n");
    let mut all = (0usize, 0usize, 0.0f64, 0.0f64, 0.0f64);
    for img in &d.images {
        let st = image_stats(img);
        all.0 += img.points.len();
        all.1 += st.rejected;
        all.2 += st.sxx;
        all.3 += st.syy;
        all.4 = all.4.max(st.max);
        let _ = writeln!(
            o,
            "<tr><td class=\"l\">{}</td><td>{}</td><td>{}</td>{}</tr>",
            escape(&img.name),
            img.points.len(),
            st.rejected,
            rms_cells(st.n, st.sxx, st.syy, st.max)
        );
    }
    let n_all: usize = d.images.iter().map(|i| image_stats(i).n).sum();
    let _ = writeln!(
        o,
        "<tr class=\"sum\"><td class=\"l\">all</td><td>{}</td><td>{}</td>{}</tr>\n</table>",
        all.0,
        all.1,
        rms_cells(n_all, all.2, all.3, all.4)
    );
    o.push_str("<div class=\"grid\">\n");
    for img in &d.images {
        image_svg(o, img, factor, bar_px);
    }
    o.push_str("</div>\n</section>\n");
}

/// A nice number printed without trailing zeros (factors and scale bars).
fn sig_trim(v: f64) -> String {
    let s = sig(v);
    if s.contains('.') && !s.contains('e') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

struct ImageStats {
    n: usize,
    rejected: usize,
    sxx: f64,
    syy: f64,
    max: f64,
}

fn image_stats(img: &ImageResiduals) -> ImageStats {
    let mut s = ImageStats {
        n: 0,
        rejected: 0,
        sxx: 0.0,
        syy: 0.0,
        max: 0.0,
    };
    for p in &img.points {
        if p.rejected {
            s.rejected += 1;
        } else if residual_ok(p) {
            s.n += 1;
            s.sxx += p.dx * p.dx;
            s.syy += p.dy * p.dy;
            s.max = s.max.max(p.dx.hypot(p.dy));
        }
    }
    s
}

fn rms_cells(n: usize, sxx: f64, syy: f64, max: f64) -> String {
    if n == 0 {
        return format!("<td>{DASH}</td><td>{DASH}</td><td>{DASH}</td><td>{DASH}</td>");
    }
    let nf = n as f64;
    format!(
        "<td>{}</td><td>{}</td><td>{}</td><td>{}</td>",
        num((sxx / nf).sqrt(), 3),
        num((syy / nf).sqrt(), 3),
        num(((sxx + syy) / nf).sqrt(), 3),
        num(max, 3)
    )
}

fn image_svg(o: &mut String, img: &ImageResiduals, factor: f64, bar_px: f64) {
    const W: f64 = 300.0;
    const M: f64 = 6.0;
    let (iw, ih) = image_size(img);
    let s = W / iw;
    let hh = (ih * s).min(3.0 * W);
    let (sw, sh) = (W + 2.0 * M, hh + 2.0 * M + 20.0);
    let st = image_stats(img);
    o.push_str("<figure>\n");
    svg_open(o, sw, sh, &format!("residuals of {}", img.name));
    let _ = write!(
        o,
        r##"<rect x="{M}" y="{M}" width="{}" height="{}" fill="#fff" stroke="#666"/>"##,
        c(W),
        c(hh)
    );
    let mut dots = vec![String::new(); KINDS.len() + 1];
    let mut vecs = String::new();
    let mut crosses = String::new();
    for p in &img.points {
        if !(p.x.is_finite() && p.y.is_finite()) {
            continue;
        }
        let (x, y) = (M + p.x * s, M + p.y * s);
        if p.rejected {
            let _ = write!(crosses, "M{} {}l6 6m0-6l-6 6", c(x - 3.0), c(y - 3.0));
            continue;
        }
        let _ = write!(dots[kind_index(&p.kind)], "M{} {}h0", c(x), c(y));
        if residual_ok(p) {
            let (vx, vy) = (p.dx * factor * s, p.dy * factor * s);
            if vx.hypot(vy) >= 0.05 {
                let _ = write!(vecs, "M{} {}l{} {}", c(x), c(y), c(vx), c(vy));
            }
        }
    }
    for (k, d) in dots.iter().enumerate() {
        if !d.is_empty() {
            let col = KINDS.get(k).map_or(OTHER_KIND, |(_, col)| col);
            let _ = write!(
                o,
                r#"<path d="{d}" stroke="{col}" stroke-width="3.4" stroke-linecap="round" fill="none"/>"#
            );
        }
    }
    if !vecs.is_empty() {
        let _ = write!(
            o,
            r##"<path d="{vecs}" stroke="#000" stroke-width="0.9" fill="none"/>"##
        );
    }
    if !crosses.is_empty() {
        let _ = write!(
            o,
            r##"<path d="{crosses}" stroke="#e00" stroke-width="1.5" fill="none"/>"##
        );
    }
    // scale bar
    let bl = (bar_px * factor * s).min(W * 0.6);
    let by = M + hh + 13.0;
    let _ = write!(
        o,
        r##"<path d="M{M} {}v-4M{M} {}h{}v-4" stroke="#000" stroke-width="1.2" fill="none"/><text x="{}" y="{}">{} px</text><text x="{}" y="{}" text-anchor="end">{} × {} px, vectors ×{}</text>"##,
        c(by),
        c(by),
        c(bl),
        c(M + bl + 4.0),
        c(by + 3.0),
        sig_trim(bar_px),
        c(M + W),
        c(by + 3.0),
        iw,
        ih,
        sig_trim(factor)
    );
    o.push_str("</svg>\n");
    let rms = if st.n > 0 {
        num(((st.sxx + st.syy) / st.n as f64).sqrt(), 3)
    } else {
        DASH.to_string()
    };
    let _ = writeln!(
        o,
        "<figcaption><b>{}</b> — {} points, {} rejected, RMS {} px</figcaption>\n</figure>",
        escape(&img.name),
        img.points.len(),
        st.rejected,
        rms
    );
}

// ---------------------------------------------------------------------------------------
// Network

const AXIS_NAMES: [&str; 3] = ["X", "Y", "Z"];

fn network(o: &mut String, d: &ReportData) {
    h2(o, "network");
    let net = &d.network;
    if net.points.is_empty() && net.cameras.is_empty() {
        none(o, "no network");
        o.push_str("</section>\n");
        return;
    }
    // σ magnification from the plan extent and the 95th-percentile σ.
    let mut plan = Bounds::new();
    for p in &net.points {
        plan.add(p.xyz[0], p.xyz[1]);
    }
    for cam in &net.cameras {
        plan.add(cam.centre[0], cam.centre[1]);
    }
    let ext = if plan.any {
        (plan.max[0] - plan.min[0]).max(plan.max[1] - plan.min[1])
    } else {
        1.0
    };
    let sigmas: Vec<f64> = net
        .points
        .iter()
        .flat_map(|p| p.sigma.iter().copied())
        .filter(|s| s.is_finite() && *s > 0.0)
        .collect();
    let sfactor = quantile(&sigmas, 0.95).map(|p| nice_number(0.008 * ext.max(1.0) / p));
    let _ = writeln!(
        o,
        "<p class=\"note\">{} cameras, {} points; photogrammetric frame, mm.{}</p>",
        net.cameras.len(),
        net.points.len(),
        sfactor.map_or(String::new(), |f| format!(
            " Ellipses: ±1σ of the point coordinates magnified <b>×{}</b>.",
            sig_trim(f)
        ))
    );
    kind_legend(o, true);
    o.push_str("<div class=\"plots\">\n");
    for (a, b, title) in [
        (0usize, 1usize, "plan (X–Y, looking down Z)"),
        (0, 2, "elevation (X–Z, looking along +Y)"),
    ] {
        network_view(o, d, a, b, title, sfactor);
    }
    o.push_str("</div>\n</section>\n");
}

fn network_view(
    o: &mut String,
    d: &ReportData,
    a: usize,
    b: usize,
    title: &str,
    sfactor: Option<f64>,
) {
    let net = &d.network;
    let mut bounds = Bounds::new();
    for p in &net.points {
        bounds.add(p.xyz[a], p.xyz[b]);
    }
    for cam in &net.cameras {
        bounds.add(cam.centre[a], cam.centre[b]);
    }
    let f = Frame::equal_aspect(&bounds, 560.0, 520.0, 100.0);
    let (w, h) = f.svg_size();
    o.push_str("<figure>\n");
    svg_open(o, w, h, &format!("network {title}"));
    axes(
        o,
        &f,
        &format!("{} (mm)", AXIS_NAMES[a]),
        &format!("{} (mm)", AXIS_NAMES[b]),
    );
    let finite = |p: &NetworkPoint| p.xyz[a].is_finite() && p.xyz[b].is_finite();
    // σ ellipses
    if let Some(sf) = sfactor {
        let mut ell = String::new();
        for p in net.points.iter().filter(|p| finite(p)) {
            let (sa, sb) = (p.sigma[a], p.sigma[b]);
            if !(sa.is_finite() && sb.is_finite() && sa > 0.0 && sb > 0.0) {
                continue;
            }
            let rx = (sa * sf * f.scale_x()).min(60.0);
            let ry = (sb * sf * f.scale_x()).min(60.0);
            if rx < 0.3 && ry < 0.3 {
                continue;
            }
            let (x, y) = (f.px(p.xyz[a]), f.py(p.xyz[b]));
            let _ = write!(
                ell,
                "M{} {}a{} {} 0 1 0 {} 0a{} {} 0 1 0 {} 0",
                c(x - rx),
                c(y),
                c(rx),
                c(ry),
                c(2.0 * rx),
                c(rx),
                c(ry),
                c(-2.0 * rx)
            );
        }
        if !ell.is_empty() {
            let _ = write!(
                o,
                r##"<path d="{ell}" stroke="#555" stroke-width="0.7" fill="#000" fill-opacity="0.06"/>"##
            );
        }
    }
    // points by kind
    let mut dots = vec![String::new(); KINDS.len() + 1];
    let mut placer = LabelPlacer::new([f.left, f.top, f.left + f.w, f.top + f.h]);
    let mut balls = Vec::new();
    for p in net.points.iter().filter(|p| finite(p)) {
        let (x, y) = (f.px(p.xyz[a]), f.py(p.xyz[b]));
        let k = kind_index(&p.kind);
        let _ = write!(dots[k], "M{} {}h0", c(x), c(y));
        if k == 2 {
            placer.obstacle(x, y, 2.5);
            balls.push((x, y, p.label.as_str()));
        }
    }
    for (x, y, label) in balls {
        placer.place(x, y, 2.5, label, "#000");
    }
    for (k, dpath) in dots.iter().enumerate() {
        if !dpath.is_empty() {
            let col = KINDS.get(k).map_or(OTHER_KIND, |(_, col)| col);
            let _ = write!(
                o,
                r#"<path d="{dpath}" stroke="{col}" stroke-width="4.5" stroke-linecap="round" fill="none"/>"#
            );
        }
    }
    o.push_str(&placer.out);
    // cameras: wedges along the forward axis (row 1 of the rotation)
    let mut wedges = String::new();
    let mut main = String::new();
    for cam in &net.cameras {
        if !(cam.centre[a].is_finite() && cam.centre[b].is_finite()) {
            continue;
        }
        let (x, y) = (f.px(cam.centre[a]), f.py(cam.centre[b]));
        let fwd = cam.rotation[1];
        let (ux, uy) = (fwd[a], -fwd[b]);
        let l = ux.hypot(uy);
        let glyph = if !(l.is_finite() && l > 0.15) {
            format!("M{} {}h7v7h-7z", c(x - 3.5), c(y - 3.5))
        } else {
            let (ux, uy) = (ux / l, uy / l);
            let len = 18.0 * l.min(1.0);
            let (px, py) = (-uy * 6.0, ux * 6.0);
            format!(
                "M{} {}L{} {}L{} {}Z",
                c(x),
                c(y),
                c(x + ux * len + px),
                c(y + uy * len + py),
                c(x + ux * len - px),
                c(y + uy * len - py)
            )
        };
        if cam.main {
            let _ = write!(
                main,
                r##"<path d="{glyph}" fill="#d62728" fill-opacity="0.8" stroke="#800" stroke-width="1.2"><title>{n}</title></path><text class="lbl" x="{}" y="{}" style="fill:#b00;font-weight:bold">{n}</text>"##,
                c(x + 8.0),
                c(y + 12.0),
                n = escape(&cam.name)
            );
        } else {
            let _ = write!(
                wedges,
                r##"<path d="{glyph}" fill="#9467bd" fill-opacity="0.45" stroke="#5b3a8c" stroke-width="0.8"><title>{}</title></path>"##,
                escape(&cam.name)
            );
        }
    }
    o.push_str(&wedges);
    o.push_str(&main);
    o.push_str("</svg>\n");
    let _ = writeln!(o, "<figcaption>{}</figcaption>\n</figure>", escape(title));
}

// ---------------------------------------------------------------------------------------
// LRF cloud

fn cloud(o: &mut String, d: &ReportData) {
    h2(o, "cloud");
    let cl = &d.cloud;
    let finite_pts = cl
        .points
        .iter()
        .filter(|p| p.iter().all(|v| v.is_finite()))
        .count();
    if finite_pts == 0 && cl.spheres.is_empty() {
        none(o, "no LRF cloud");
        o.push_str("</section>\n");
        return;
    }
    let matched = cl.spheres.iter().filter(|s| s.matched_to.is_some()).count();
    let _ = writeln!(
        o,
        "<p class=\"note\">{} points (subsampled), {} spheres ({} matched to photogrammetric balls); LRF frame, mm (Y is the servo shaft). Spheres drawn at true scale (filled) with a ring to find them; matched in red, unmatched in grey.</p>",
        finite_pts,
        cl.spheres.len(),
        matched
    );
    o.push_str("<div class=\"plots\">\n");
    for (a, b, title) in [(0usize, 1usize, "X–Y"), (0, 2, "X–Z")] {
        cloud_view(o, d, a, b, title);
    }
    o.push_str("</div>\n");
    if !cl.spheres.is_empty() {
        o.push_str("<table>\n<tr><th class=\"l\">sphere</th><th class=\"l\">matched to</th><th>X (mm)</th><th>Y (mm)</th><th>Z (mm)</th><th>r (mm)</th><th>σX</th><th>σY</th><th>σZ</th><th>inliers</th></tr>\n");
        let mut spheres: Vec<_> = cl.spheres.iter().collect();
        spheres.sort_by(|a, b| id_cmp(&a.label, &b.label));
        for s in spheres {
            let _ = writeln!(
                o,
                "<tr><td class=\"l\">{}</td><td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                escape(&s.label),
                s.matched_to.as_deref().map_or(DASH.to_string(), escape),
                num(s.centre[0], 1),
                num(s.centre[1], 1),
                num(s.centre[2], 1),
                num(s.radius, 2),
                num(s.sigma[0], 2),
                num(s.sigma[1], 2),
                num(s.sigma[2], 2),
                s.inliers
            );
        }
        o.push_str("</table>\n");
    }
    o.push_str("</section>\n");
}

fn cloud_view(o: &mut String, d: &ReportData, a: usize, b: usize, title: &str) {
    let cl = &d.cloud;
    let mut bounds = Bounds::new();
    for p in &cl.points {
        if p.iter().all(|v| v.is_finite()) {
            bounds.add(p[a] as f64, p[b] as f64);
        }
    }
    for s in &cl.spheres {
        bounds.add(s.centre[a], s.centre[b]);
    }
    let f = Frame::equal_aspect(&bounds, 560.0, 520.0, 100.0);
    let (w, h) = f.svg_size();
    o.push_str("<figure>\n");
    svg_open(o, w, h, &format!("LRF cloud {title}"));
    axes(
        o,
        &f,
        &format!("{} (mm)", AXIS_NAMES[a]),
        &format!("{} (mm)", AXIS_NAMES[b]),
    );
    // Points rounded to 0.1 px, duplicates dropped, one path.
    let mut keys: Vec<(i32, i32)> = cl
        .points
        .iter()
        .filter(|p| p.iter().all(|v| v.is_finite()))
        .map(|p| {
            (
                (f.px(p[a] as f64) * 10.0).round() as i32,
                (f.py(p[b] as f64) * 10.0).round() as i32,
            )
        })
        .collect();
    keys.sort_unstable();
    keys.dedup();
    if !keys.is_empty() {
        let mut dpath = String::with_capacity(keys.len() * 14);
        for (x, y) in keys {
            let _ = write!(dpath, "M{} {}h0", c(x as f64 / 10.0), c(y as f64 / 10.0));
        }
        let _ = write!(
            o,
            r##"<path d="{dpath}" stroke="#666" stroke-opacity="0.55" stroke-width="1.1" stroke-linecap="round" fill="none"/>"##
        );
    }
    let mut placer = LabelPlacer::new([f.left, f.top, f.left + f.w, f.top + f.h]);
    let mut to_label = Vec::new();
    for s in &cl.spheres {
        if !(s.centre[a].is_finite() && s.centre[b].is_finite()) {
            continue;
        }
        let (x, y) = (f.px(s.centre[a]), f.py(s.centre[b]));
        let r = if s.radius.is_finite() {
            s.radius.abs() * f.scale_x()
        } else {
            0.0
        };
        let col = if s.matched_to.is_some() {
            "#d62728"
        } else {
            "#7f7f7f"
        };
        let label = match &s.matched_to {
            Some(m) if *m != s.label => format!("{}→{}", s.label, m),
            _ => s.label.clone(),
        };
        let _ = write!(
            o,
            r#"<circle cx="{x}" cy="{y}" r="{}" fill="{col}" fill-opacity="0.6"/><circle cx="{x}" cy="{y}" r="{}" fill="none" stroke="{col}" stroke-width="1.3"><title>{}</title></circle>"#,
            c(r.max(0.5)),
            c(r.max(5.0)),
            escape(&label),
            x = c(x),
            y = c(y)
        );
        placer.obstacle(x, y, r.max(5.0));
        to_label.push((x, y, r.max(5.0), label, col));
    }
    for (x, y, r, label, col) in to_label {
        placer.place(x, y, r, &label, col);
    }
    o.push_str(&placer.out);
    o.push_str("</svg>\n");
    let _ = writeln!(
        o,
        "<figcaption>LRF cloud, {}</figcaption>\n</figure>",
        escape(title)
    );
}

// ---------------------------------------------------------------------------------------
// Intrinsics, rejected, warnings, steps

pub(crate) fn intrinsics(o: &mut String, d: &ReportData) {
    h2(o, "intrinsics");
    if d.intrinsics.is_empty() {
        none(o, "no intrinsics");
    } else {
        o.push_str("<div class=\"tables\">\n");
    }
    for cam in &d.intrinsics {
        let _ = writeln!(
            o,
            "<div>\n<h3>{}</h3>\n<table>\n<tr><th class=\"l\">parameter</th><th>value</th><th>σ</th><th class=\"l\">unit</th><th class=\"l\"></th></tr>",
            escape(&cam.camera)
        );
        for (i, name) in cam.names.iter().enumerate() {
            let free = cam.free.get(i).copied().unwrap_or(false);
            let sigma = cam.sigmas.get(i).copied().unwrap_or(f64::NAN);
            let _ = writeln!(
                o,
                "<tr><td class=\"l\">{}</td><td>{}</td><td>{}</td><td class=\"l\">{}</td><td class=\"l\">{}</td></tr>",
                escape(name),
                sig(cam.values.get(i).copied().unwrap_or(f64::NAN)),
                if free && sigma > 0.0 { sig(sigma) } else { DASH.to_string() },
                escape(cam.units.get(i).map_or("", String::as_str)),
                if free { "free" } else { "fixed" }
            );
        }
        o.push_str("</table>\n");
        if cam.high_correlations.is_empty() {
            o.push_str("<p class=\"none\">no high correlations</p>\n");
        } else {
            o.push_str("<p class=\"note\">correlations (|r| &gt; 0.9 highlighted)</p>\n<table>\n<tr><th class=\"l\">parameter</th><th class=\"l\">parameter</th><th>r</th></tr>\n");
            for (p, q, r) in &cam.high_correlations {
                let hi = if r.abs() > 0.9 { " class=\"hi\"" } else { "" };
                let _ = writeln!(
                    o,
                    "<tr{hi}><td class=\"l\">{}</td><td class=\"l\">{}</td><td>{}</td></tr>",
                    escape(p),
                    escape(q),
                    num(*r, 3)
                );
            }
            o.push_str("</table>\n");
        }
        o.push_str("</div>\n");
    }
    if !d.intrinsics.is_empty() {
        o.push_str("</div>\n");
    }
    o.push_str("</section>\n");
}

fn mount(o: &mut String, d: &ReportData) {
    h2(o, "mount");
    if d.lrf_mount.is_empty() {
        none(
            o,
            "the joint adjustment did not run: the project's mount values were used as given",
        );
        o.push_str("</section>\n");
        return;
    }
    o.push_str("<p class=\"note\">estimated with the extrinsic in the joint adjustment; a held parameter keeps the project's value</p>\n<table>\n<tr><th class=\"l\">parameter</th><th>value</th><th>σ</th><th class=\"l\">unit</th><th class=\"l\">largest correlation with the extrinsic</th><th class=\"l\"></th></tr>\n");
    for m in &d.lrf_mount {
        let corr = m
            .max_corr_extrinsic
            .as_ref()
            .map_or(DASH.to_string(), |(c, r)| {
                format!("{} {}", escape(c), num(*r, 3))
            });
        let hi = if m
            .max_corr_extrinsic
            .as_ref()
            .is_some_and(|(_, r)| r.abs() > 0.9)
        {
            " class=\"hi\""
        } else {
            ""
        };
        let _ = writeln!(
            o,
            "<tr{hi}><td class=\"l\">{}</td><td>{}</td><td>{}</td><td class=\"l\">{}</td><td class=\"l\">{}</td><td class=\"l\">{}</td></tr>",
            escape(&m.name),
            sig(m.value),
            m.sigma.map_or(DASH.to_string(), sig),
            escape(&m.unit),
            corr,
            m.held.as_deref().map_or("estimated".to_string(), |h| format!("held: {}", escape(h)))
        );
    }
    o.push_str("</table>\n</section>\n");
}

pub(crate) fn rejected(o: &mut String, d: &ReportData) {
    h2(o, "rejected");
    if d.rejected.is_empty() {
        none(o, "nothing rejected");
    } else {
        o.push_str("<table>\n<tr><th class=\"l\">what</th><th class=\"l\">why</th></tr>\n");
        for r in &d.rejected {
            let _ = writeln!(
                o,
                "<tr><td class=\"l\">{}</td><td class=\"l\">{}</td></tr>",
                escape(&r.what),
                escape(&r.why)
            );
        }
        o.push_str("</table>\n");
    }
    o.push_str("</section>\n");
}

pub(crate) fn warnings(o: &mut String, d: &ReportData) {
    h2(o, "warnings");
    if d.warnings.is_empty() {
        none(o, "no warnings");
    } else {
        o.push_str("<ul class=\"warn\">\n");
        for w in &d.warnings {
            let _ = writeln!(o, "<li>{}</li>", escape(w));
        }
        o.push_str("</ul>\n");
    }
    o.push_str("</section>\n");
}

fn steps(o: &mut String, d: &ReportData) {
    h2(o, "steps");
    if d.steps.is_empty() {
        none(o, "no steps logged");
    } else {
        let _ = writeln!(
            o,
            "<details>\n<summary>{} steps (click to expand)</summary>\n<ol class=\"steps\">",
            d.steps.len()
        );
        for s in &d.steps {
            let _ = writeln!(o, "<li>{}</li>", escape(s));
        }
        o.push_str("</ol>\n</details>\n");
    }
    o.push_str("</section>\n");
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_sort_naturally() {
        let mut v = vec!["12", "b", "4", "a", "9", "15", "11"];
        v.sort_by(|a, b| id_cmp(a, b));
        assert_eq!(v, ["4", "9", "11", "12", "15", "a", "b"]);
        let mut w = vec!["B11", "B4", "T2", "B1", "T10"];
        w.sort_by(|a, b| id_cmp(a, b));
        assert_eq!(w, ["B1", "B4", "B11", "T2", "T10"]);
    }

    #[test]
    fn chart_uses_loo_when_no_check_rows() {
        let row = |id: &str, role: &str| CheckRow {
            id: id.into(),
            error_mm: 1.0,
            role: role.into(),
            ..Default::default()
        };
        let m = MethodResult {
            checks: vec![row("1", "control"), row("2", "loo"), row("3", "loo")],
            ..Default::default()
        };
        let (role, rows) = plotted_rows(&m);
        assert_eq!(role, Some("loo"));
        assert_eq!(rows.len(), 2);
        let m2 = MethodResult {
            checks: vec![row("1", "check"), row("2", "loo")],
            ..Default::default()
        };
        assert_eq!(plotted_rows(&m2).0, Some("check"));
    }
}
