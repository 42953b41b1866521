//! The HTML document: its head and style, the verdict, the table of contents, then one
//! section after the other, each drawn by its own module (charts and tables that share their
//! drawing live in [`crate::charts`] and [`crate::tables`]):
//!
//! | section | module |
//! |---|---|
//! | Summary | [`summary`](mod@summary) |
//! | Extrinsic calibration | [`extrinsic`](mod@extrinsic) |
//! | Extrinsic precision | [`crate::charts`] |
//! | Check points | [`checks`](mod@checks) |
//! | Image residuals | [`images`](mod@images) |
//! | Residual histogram, Image coverage | [`crate::charts`] |
//! | Network | [`network`](mod@network) |
//! | Exterior orientation, Point precision, Distances, Stereo rig | [`crate::tables`] |
//! | LRF cloud | [`cloud`](mod@cloud) |
//! | LRF on the images | [`crate::overlay_section`] |
//! | Intrinsics | [`intrinsics`](mod@intrinsics) |
//! | Distortion profile | [`crate::charts`] |
//! | OpenCV parameters | [`crate::tables`] |
//! | LRF mount and range | [`mount`](mod@mount) |
//! | Rejected | [`rejected`](mod@rejected) |
//! | Warnings | [`warnings`](mod@warnings) |
//! | Pipeline steps | [`steps`](mod@steps) |
//!
//! [`legend`] holds what the plots share (colours, legends, axis names).

mod checks;
mod cloud;
mod extrinsic;
mod images;
mod intrinsics;
mod legend;
mod mount;
mod network;
mod rejected;
mod steps;
mod summary;
mod warnings;

use crate::fmt::{escape, num};
use crate::section::SECTIONS;
use crate::{charts, tables, ReportData};
pub(crate) use checks::checks;
use cloud::cloud;
pub(crate) use extrinsic::extrinsic;
use images::images;
pub(crate) use intrinsics::intrinsics;
use mount::mount;
use network::network;
pub(crate) use rejected::rejected;
use std::fmt::Write;
use steps::steps;
pub(crate) use summary::summary;
pub(crate) use warnings::warnings;

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
    tables::sensors(&mut o, d);
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

/// The verdict box: status, reasons, and the tests with their bounds.
fn verdict(o: &mut String, v: &crate::VerdictView) {
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
