//! The *Warnings* section (`warnings`): the pipeline's warnings, in order.

use crate::fmt::escape;
use crate::section::{h2, none};
use crate::ReportData;
use std::fmt::Write;

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
