//! The *Pipeline steps* section (`steps`): the pipeline's log, collapsed.

use crate::fmt::escape;
use crate::section::{h2, none};
use crate::ReportData;
use std::fmt::Write;

pub(super) fn steps(o: &mut String, d: &ReportData) {
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
