//! The `overlays` section ("LRF on the images"): each image with the LRF's points drawn on
//! it ([`crate::overlay`]), those of the main station large and first, the others as a grid
//! of thumbnails, each with its caption and counts.

use crate::fmt::{escape, num};
use crate::section::{h2, none};
use crate::{Overlay, ReportData};
use std::fmt::Write;

/// One overlay as a figure: the PNG as a `data:` URI, its caption and counts.
pub(crate) fn figure(o: &mut String, v: &Overlay) {
    let _ = writeln!(
        o,
        "<figure><img src=\"data:image/png;base64,{}\" width=\"{}\" height=\"{}\" alt=\"LRF points on {}\" style=\"max-width:100%;height:auto\"/>",
        escape(&v.png_base64),
        v.width,
        v.height,
        escape(&v.name)
    );
    let _ = writeln!(
        o,
        "<figcaption><b>{}</b>: {}; {} ball points, {} other points{} (range {}–{} mm), {} outside the image</figcaption>\n</figure>",
        escape(&v.name),
        escape(&v.caption),
        v.ball_points,
        v.range_points,
        match v.range_points_skipped {
            0 => String::new(),
            n => format!(" of {} (evenly thinned)", n + v.range_points),
        },
        num(v.range_mm[0], 0),
        num(v.range_mm[1], 0),
        v.outside
    );
}

/// The section.
pub(crate) fn overlays(o: &mut String, d: &ReportData) {
    h2(o, "overlays");
    if d.overlays.is_empty() {
        none(o, "no LRF points drawn on the images");
        o.push_str("</section>\n");
        return;
    }
    o.push_str("<p class=\"note\">Every LRF point projected into the images with the calibration's extrinsic, the LRF's model and each camera's orientation and intrinsics: a ball's points in magenta with its label, the others coloured by their range from the LRF (turbo colour map, scale bottom right; far points drawn first). With a right calibration a ball's points lie on its image and the others follow the walls, the floor and the edges of the room; a shift or shear against the picture is an error of the extrinsic or the LRF's mount. The images at full resolution are in the output folder's <code>overlays/</code>.</p>\n");
    let (main, other): (Vec<&Overlay>, Vec<&Overlay>) = d.overlays.iter().partition(|v| v.main);
    if !main.is_empty() {
        o.push_str("<div class=\"plots\">\n");
        for v in main {
            figure(o, v);
        }
        o.push_str("</div>\n");
    }
    if !other.is_empty() {
        o.push_str("<div class=\"grid\">\n");
        for v in other {
            figure(o, v);
        }
        o.push_str("</div>\n");
    }
    o.push_str("</section>\n");
}
