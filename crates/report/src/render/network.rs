//! The *Network* section (`network`): the cameras (wedges along their viewing direction) and
//! the object points in plan (X–Y) and elevation (X–Z), the points' σ ellipses magnified by
//! one factor.

use super::legend::{kind_index, kind_legend, sig_trim, AXIS_NAMES, KINDS, OTHER_KIND};
use crate::fmt::{c, escape};
use crate::plot::{axes, nice_number, quantile, svg_open, Bounds, Frame, LabelPlacer};
use crate::section::{h2, none};
use crate::{Network, NetworkPoint, ReportData};
use std::fmt::Write;

pub(super) fn network(o: &mut String, d: &ReportData) {
    h2(o, "network");
    let net = &d.network;
    if net.points.is_empty() && net.cameras.is_empty() {
        none(o, "no network");
        o.push_str("</section>\n");
        return;
    }
    // σ magnification from the plan extent and the 95th-percentile σ.
    let mut plan = Bounds::new();
    for p in &net.points {
        plan.add(p.xyz[0], p.xyz[1]);
    }
    for cam in &net.cameras {
        plan.add(cam.centre[0], cam.centre[1]);
    }
    let ext = if plan.any {
        (plan.max[0] - plan.min[0]).max(plan.max[1] - plan.min[1])
    } else {
        1.0
    };
    let sigmas: Vec<f64> = net
        .points
        .iter()
        .flat_map(|p| p.sigma.iter().copied())
        .filter(|s| s.is_finite() && *s > 0.0)
        .collect();
    let sfactor = quantile(&sigmas, 0.95).map(|p| nice_number(0.008 * ext.max(1.0) / p));
    let _ = writeln!(
        o,
        "<p class=\"note\">{} cameras, {} points; photogrammetric frame, mm.{}</p>",
        net.cameras.len(),
        net.points.len(),
        sfactor.map_or(String::new(), |f| format!(
            " Ellipses: ±1σ of the point coordinates magnified <b>×{}</b>.",
            sig_trim(f)
        ))
    );
    kind_legend(o, true);
    o.push_str("<div class=\"plots\">\n");
    for (a, b, title) in [
        (0usize, 1usize, "plan (X–Y, looking down Z)"),
        (0, 2, "elevation (X–Z, looking along +Y)"),
    ] {
        network_view(o, d, a, b, title, sfactor);
    }
    o.push_str("</div>\n</section>\n");
}

fn network_view(
    o: &mut String,
    d: &ReportData,
    a: usize,
    b: usize,
    title: &str,
    sfactor: Option<f64>,
) {
    let net = &d.network;
    let mut bounds = Bounds::new();
    for p in &net.points {
        bounds.add(p.xyz[a], p.xyz[b]);
    }
    for cam in &net.cameras {
        bounds.add(cam.centre[a], cam.centre[b]);
    }
    let f = Frame::equal_aspect(&bounds, 560.0, 520.0, 100.0);
    let (w, h) = f.svg_size();
    o.push_str("<figure>\n");
    svg_open(o, w, h, &format!("network {title}"));
    axes(
        o,
        &f,
        &format!("{} (mm)", AXIS_NAMES[a]),
        &format!("{} (mm)", AXIS_NAMES[b]),
    );
    ellipses(o, &f, net, (a, b), sfactor);
    points(o, &f, net, (a, b));
    cameras(o, &f, net, (a, b));
    o.push_str("</svg>\n");
    let _ = writeln!(o, "<figcaption>{}</figcaption>\n</figure>", escape(title));
}

/// Whether point `p` has finite coordinates on axes `a` and `b`.
fn finite(p: &NetworkPoint, (a, b): (usize, usize)) -> bool {
    p.xyz[a].is_finite() && p.xyz[b].is_finite()
}

/// The points' σ ellipses on axes `ab`, magnified by `sfactor` (none without it).
fn ellipses(
    o: &mut String,
    f: &Frame,
    net: &Network,
    (a, b): (usize, usize),
    sfactor: Option<f64>,
) {
    if let Some(sf) = sfactor {
        let mut ell = String::new();
        for p in net.points.iter().filter(|p| finite(p, (a, b))) {
            let (sa, sb) = (p.sigma[a], p.sigma[b]);
            if !(sa.is_finite() && sb.is_finite() && sa > 0.0 && sb > 0.0) {
                continue;
            }
            let rx = (sa * sf * f.scale_x()).min(60.0);
            let ry = (sb * sf * f.scale_x()).min(60.0);
            if rx < 0.3 && ry < 0.3 {
                continue;
            }
            let (x, y) = (f.px(p.xyz[a]), f.py(p.xyz[b]));
            let _ = write!(
                ell,
                "M{} {}a{} {} 0 1 0 {} 0a{} {} 0 1 0 {} 0",
                c(x - rx),
                c(y),
                c(rx),
                c(ry),
                c(2.0 * rx),
                c(rx),
                c(ry),
                c(-2.0 * rx)
            );
        }
        if !ell.is_empty() {
            let _ = write!(
                o,
                r##"<path d="{ell}" stroke="#555" stroke-width="0.7" fill="#000" fill-opacity="0.06"/>"##
            );
        }
    }
}

/// The points as dots coloured by kind, the balls labelled.
fn points(o: &mut String, f: &Frame, net: &Network, (a, b): (usize, usize)) {
    let mut dots = vec![String::new(); KINDS.len() + 1];
    let mut placer = LabelPlacer::new([f.left, f.top, f.left + f.w, f.top + f.h]);
    let mut balls = Vec::new();
    for p in net.points.iter().filter(|p| finite(p, (a, b))) {
        let (x, y) = (f.px(p.xyz[a]), f.py(p.xyz[b]));
        let k = kind_index(&p.kind);
        let _ = write!(dots[k], "M{} {}h0", c(x), c(y));
        if k == 2 {
            placer.obstacle(x, y, 2.5);
            balls.push((x, y, p.label.as_str()));
        }
    }
    for (x, y, label) in balls {
        placer.place(x, y, 2.5, label, "#000");
    }
    for (k, dpath) in dots.iter().enumerate() {
        if !dpath.is_empty() {
            let col = KINDS.get(k).map_or(OTHER_KIND, |(_, col)| col);
            let _ = write!(
                o,
                r#"<path d="{dpath}" stroke="{col}" stroke-width="4.5" stroke-linecap="round" fill="none"/>"#
            );
        }
    }
    o.push_str(&placer.out);
}

/// The cameras as wedges along their forward axis (row 1 of the rotation), the main
/// station red and named.
fn cameras(o: &mut String, f: &Frame, net: &Network, (a, b): (usize, usize)) {
    let mut wedges = String::new();
    let mut main = String::new();
    for cam in &net.cameras {
        if !(cam.centre[a].is_finite() && cam.centre[b].is_finite()) {
            continue;
        }
        let (x, y) = (f.px(cam.centre[a]), f.py(cam.centre[b]));
        let fwd = cam.rotation[1];
        let (ux, uy) = (fwd[a], -fwd[b]);
        let l = ux.hypot(uy);
        let glyph = if !(l.is_finite() && l > 0.15) {
            format!("M{} {}h7v7h-7z", c(x - 3.5), c(y - 3.5))
        } else {
            let (ux, uy) = (ux / l, uy / l);
            let len = 18.0 * l.min(1.0);
            let (px, py) = (-uy * 6.0, ux * 6.0);
            format!(
                "M{} {}L{} {}L{} {}Z",
                c(x),
                c(y),
                c(x + ux * len + px),
                c(y + uy * len + py),
                c(x + ux * len - px),
                c(y + uy * len - py)
            )
        };
        if cam.main {
            let _ = write!(
                main,
                r##"<path d="{glyph}" fill="#d62728" fill-opacity="0.8" stroke="#800" stroke-width="1.2"><title>{n}</title></path><text class="lbl" x="{}" y="{}" style="fill:#b00;font-weight:bold">{n}</text>"##,
                c(x + 8.0),
                c(y + 12.0),
                n = escape(&cam.name)
            );
        } else {
            let _ = write!(
                wedges,
                r##"<path d="{glyph}" fill="#9467bd" fill-opacity="0.45" stroke="#5b3a8c" stroke-width="0.8"><title>{}</title></path>"##,
                escape(&cam.name)
            );
        }
    }
    o.push_str(&wedges);
    o.push_str(&main);
}
