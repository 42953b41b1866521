//! The *LRF cloud* section (`cloud`): the LRF's points in X–Y and X–Z with the fitted spheres
//! drawn at true scale.

use super::legend::AXIS_NAMES;
use crate::fmt::{c, escape, num, DASH};
use crate::plot::{axes, svg_open, Bounds, Frame, LabelPlacer};
use crate::section::{h2, id_cmp, none};
use crate::ReportData;
use std::fmt::Write;

pub(super) fn cloud(o: &mut String, d: &ReportData) {
    h2(o, "cloud");
    let cl = &d.cloud;
    let finite_pts = cl
        .points
        .iter()
        .filter(|p| p.iter().all(|v| v.is_finite()))
        .count();
    if finite_pts == 0 && cl.spheres.is_empty() {
        none(o, "no LRF cloud");
        o.push_str("</section>\n");
        return;
    }
    let matched = cl.spheres.iter().filter(|s| s.matched_to.is_some()).count();
    let _ = writeln!(
        o,
        "<p class=\"note\">{} points (subsampled), {} spheres ({} matched to photogrammetric balls); LRF frame, mm (Y is the servo shaft). Spheres drawn at true scale (filled) with a ring to find them; matched in red, unmatched in grey.</p>",
        finite_pts,
        cl.spheres.len(),
        matched
    );
    o.push_str("<div class=\"plots\">\n");
    for (a, b, title) in [(0usize, 1usize, "X–Y"), (0, 2, "X–Z")] {
        cloud_view(o, d, a, b, title);
    }
    o.push_str("</div>\n");
    if !cl.spheres.is_empty() {
        o.push_str("<table>\n<tr><th class=\"l\">sphere</th><th class=\"l\">matched to</th><th>X (mm)</th><th>Y (mm)</th><th>Z (mm)</th><th>r (mm)</th><th>σX</th><th>σY</th><th>σZ</th><th>inliers</th></tr>\n");
        let mut spheres: Vec<_> = cl.spheres.iter().collect();
        spheres.sort_by(|a, b| id_cmp(&a.label, &b.label));
        for s in spheres {
            let _ = writeln!(
                o,
                "<tr><td class=\"l\">{}</td><td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                escape(&s.label),
                s.matched_to.as_deref().map_or(DASH.to_string(), escape),
                num(s.centre[0], 1),
                num(s.centre[1], 1),
                num(s.centre[2], 1),
                num(s.radius, 2),
                num(s.sigma[0], 2),
                num(s.sigma[1], 2),
                num(s.sigma[2], 2),
                s.inliers
            );
        }
        o.push_str("</table>\n");
    }
    o.push_str("</section>\n");
}

fn cloud_view(o: &mut String, d: &ReportData, a: usize, b: usize, title: &str) {
    let cl = &d.cloud;
    let mut bounds = Bounds::new();
    for p in &cl.points {
        if p.iter().all(|v| v.is_finite()) {
            bounds.add(p[a] as f64, p[b] as f64);
        }
    }
    for s in &cl.spheres {
        bounds.add(s.centre[a], s.centre[b]);
    }
    let f = Frame::equal_aspect(&bounds, 560.0, 520.0, 100.0);
    let (w, h) = f.svg_size();
    o.push_str("<figure>\n");
    svg_open(o, w, h, &format!("LRF cloud {title}"));
    axes(
        o,
        &f,
        &format!("{} (mm)", AXIS_NAMES[a]),
        &format!("{} (mm)", AXIS_NAMES[b]),
    );
    // Points rounded to 0.1 px, duplicates dropped, one path.
    let mut keys: Vec<(i32, i32)> = cl
        .points
        .iter()
        .filter(|p| p.iter().all(|v| v.is_finite()))
        .map(|p| {
            (
                (f.px(p[a] as f64) * 10.0).round() as i32,
                (f.py(p[b] as f64) * 10.0).round() as i32,
            )
        })
        .collect();
    keys.sort_unstable();
    keys.dedup();
    if !keys.is_empty() {
        let mut dpath = String::with_capacity(keys.len() * 14);
        for (x, y) in keys {
            let _ = write!(dpath, "M{} {}h0", c(x as f64 / 10.0), c(y as f64 / 10.0));
        }
        let _ = write!(
            o,
            r##"<path d="{dpath}" stroke="#666" stroke-opacity="0.55" stroke-width="1.1" stroke-linecap="round" fill="none"/>"##
        );
    }
    let mut placer = LabelPlacer::new([f.left, f.top, f.left + f.w, f.top + f.h]);
    let mut to_label = Vec::new();
    for s in &cl.spheres {
        if !(s.centre[a].is_finite() && s.centre[b].is_finite()) {
            continue;
        }
        let (x, y) = (f.px(s.centre[a]), f.py(s.centre[b]));
        let r = if s.radius.is_finite() {
            s.radius.abs() * f.scale_x()
        } else {
            0.0
        };
        let col = if s.matched_to.is_some() {
            "#d62728"
        } else {
            "#7f7f7f"
        };
        let label = match &s.matched_to {
            Some(m) if *m != s.label => format!("{}→{}", s.label, m),
            _ => s.label.clone(),
        };
        let _ = write!(
            o,
            r#"<circle cx="{x}" cy="{y}" r="{}" fill="{col}" fill-opacity="0.6"/><circle cx="{x}" cy="{y}" r="{}" fill="none" stroke="{col}" stroke-width="1.3"><title>{}</title></circle>"#,
            c(r.max(0.5)),
            c(r.max(5.0)),
            escape(&label),
            x = c(x),
            y = c(y)
        );
        placer.obstacle(x, y, r.max(5.0));
        to_label.push((x, y, r.max(5.0), label, col));
    }
    for (x, y, r, label, col) in to_label {
        placer.place(x, y, r, &label, col);
    }
    o.push_str(&placer.out);
    o.push_str("</svg>\n");
    let _ = writeln!(
        o,
        "<figcaption>LRF cloud, {}</figcaption>\n</figure>",
        escape(title)
    );
}
