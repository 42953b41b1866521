//! The *LRF mount and range* section (`mount`): the joint adjustment's LRF mount and range
//! parameters with value, σ, unit, the largest correlation with the extrinsic, and why any
//! was held.

use crate::fmt::{escape, num, sig, DASH};
use crate::section::{h2, none};
use crate::ReportData;
use std::fmt::Write;

pub(super) fn mount(o: &mut String, d: &ReportData) {
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
