//! The *Rejected* section (`rejected`): what the pipeline rejected, and why.

use crate::fmt::escape;
use crate::section::{h2, none};
use crate::ReportData;
use std::fmt::Write;

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
