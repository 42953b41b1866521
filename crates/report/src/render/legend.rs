//! What the plots share: the colours of the point kinds and their legend, the colours of the
//! methods, the axes' names, and the short numbers of scale notes.

use crate::fmt::sig;
use std::fmt::Write;

/// Colours of point kinds (also used for the legend).
pub(super) const KINDS: [(&str, &str); 3] = [
    ("plain", "#2ca02c"),
    ("coded", "#1f77b4"),
    ("ball", "#ff7f0e"),
];

pub(super) const OTHER_KIND: &str = "#7f7f7f";

/// Colours of methods in the check-point chart.
pub(super) const METHOD_COLOURS: [&str; 6] = [
    "#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#8c564b", "#e377c2",
];

/// Index of a kind in drawing order (plain, coded, ball, other).
pub(super) fn kind_index(kind: &str) -> usize {
    KINDS
        .iter()
        .position(|(k, _)| k.eq_ignore_ascii_case(kind.trim()))
        .unwrap_or(KINDS.len())
}

pub(super) fn kind_legend(o: &mut String, with_camera: bool) {
    o.push_str(r#"<div class="legend">"#);
    for (k, col) in KINDS {
        let _ = write!(o, r#"<span class="sw" style="background:{col}"></span>{k}"#);
    }
    if with_camera {
        o.push_str(r#"<span class="sw" style="background:#9467bd;border-radius:0"></span>camera (wedge along the viewing direction)<span class="sw" style="background:#d62728;border-radius:0"></span>main station"#);
    }
    o.push_str("</div>\n");
}

/// A nice number printed without trailing zeros (factors and scale bars).
pub(super) fn sig_trim(v: f64) -> String {
    let s = sig(v);
    if s.contains('.') && !s.contains('e') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

pub(super) const AXIS_NAMES: [&str; 3] = ["X", "Y", "Z"];
