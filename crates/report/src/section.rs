//! The page's building blocks that every section uses: the section ids and headings in
//! document order, a section's heading, the note of an empty section, and the natural order
//! of ids (B4 before B11). Below `render`, `charts` and `tables`, which all use it.

use crate::fmt::escape;
use std::cmp::Ordering;
use std::fmt::Write;

/// Section ids and headings, in document order.
pub(crate) const SECTIONS: [(&str, &str); 22] = [
    ("summary", "Summary"),
    ("extrinsic", "Extrinsic calibration"),
    ("extrinsic_precision", "Extrinsic precision"),
    ("checks", "Check points"),
    ("images", "Image residuals"),
    ("histogram", "Residual histogram"),
    ("coverage", "Image coverage"),
    ("network", "Network"),
    ("exterior", "Exterior orientation"),
    ("points", "Point precision"),
    ("distances", "Distances"),
    ("rig", "Stereo rig"),
    ("sensors", "Sensors of the head"),
    ("cloud", "LRF cloud"),
    ("overlays", "LRF on the images"),
    ("intrinsics", "Intrinsics"),
    ("distortion", "Distortion profile"),
    ("opencv", "OpenCV parameters"),
    ("mount", "LRF mount and range"),
    ("rejected", "Rejected"),
    ("warnings", "Warnings"),
    ("steps", "Pipeline steps"),
];

/// Opens section `id` with its heading from `SECTIONS`.
pub(crate) fn h2(o: &mut String, id: &str) {
    let title = SECTIONS
        .iter()
        .find(|(i, _)| *i == id)
        .map_or(id, |(_, t)| t);
    let _ = write!(o, "<section id=\"{id}\">\n<h2>{}</h2>\n", escape(title));
}

/// The note of a section with nothing to show.
pub(crate) fn none(o: &mut String, text: &str) {
    let _ = writeln!(o, r#"<p class="none">{}</p>"#, escape(text));
}

/// Natural order of ids: by the text before the first digit, then the number its digits
/// make (B4 before B11; plain numbers first by value), then the whole id.
pub(crate) fn id_cmp(a: &str, b: &str) -> Ordering {
    natural_key(a).cmp(&natural_key(b))
}

fn natural_key(id: &str) -> (&str, u64, &str) {
    let id = id.trim();
    let start = id.find(|c: char| c.is_ascii_digit()).unwrap_or(id.len());
    let end = id[start..]
        .find(|c: char| !c.is_ascii_digit())
        .map_or(id.len(), |e| start + e);
    let n = id[start..end].parse().unwrap_or(u64::MAX);
    (&id[..start], n, id)
}
