//! The *Intrinsics* section (`intrinsics`): every camera's parameters with value, σ, unit,
//! free or fixed, and its high correlations.

use crate::fmt::{escape, num, sig, DASH};
use crate::section::{h2, none};
use crate::ReportData;
use std::fmt::Write;

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
