//! The *Summary* section (`summary`): the key → value lines the pipeline puts first (σ0,
//! RMS, mean check error, …), in its order.

use crate::fmt::escape;
use crate::section::{h2, none};
use crate::ReportData;
use std::fmt::Write;

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
