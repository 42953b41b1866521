//! The *Image residuals* section (`images`): every image with its residual vectors magnified
//! by one factor for all (rejected observations as red ×), a scale bar, and a table of the
//! RMS per image and over all.

use super::legend::{kind_index, kind_legend, sig_trim, KINDS, OTHER_KIND};
use crate::fmt::{c, escape, num, DASH};
use crate::plot::{nice_number, quantile, svg_open};
use crate::section::{h2, none};
use crate::{ImageResiduals, ReportData};
use std::fmt::Write;

fn image_size(img: &ImageResiduals) -> (f64, f64) {
    let max = |f: fn(&crate::ImagePoint) -> f64| {
        img.points
            .iter()
            .map(f)
            .filter(|v| v.is_finite())
            .fold(1.0f64, f64::max)
    };
    let w = if img.width > 0 {
        img.width as f64
    } else {
        max(|p| p.x).ceil()
    };
    let h = if img.height > 0 {
        img.height as f64
    } else {
        max(|p| p.y).ceil()
    };
    (w, h)
}

fn residual_ok(p: &crate::ImagePoint) -> bool {
    !p.rejected && p.dx.is_finite() && p.dy.is_finite()
}

pub(super) fn images(o: &mut String, d: &ReportData) {
    h2(o, "images");
    if d.images.is_empty() {
        none(o, "no image residuals");
        o.push_str("</section>\n");
        return;
    }
    let mags: Vec<f64> = d
        .images
        .iter()
        .flat_map(|i| i.points.iter())
        .filter(|p| residual_ok(p))
        .map(|p| p.dx.hypot(p.dy))
        .collect();
    let mut widths: Vec<f64> = d.images.iter().map(|i| image_size(i).0).collect();
    widths.sort_by(f64::total_cmp);
    let width = widths[widths.len() / 2];
    let p95 = quantile(&mags, 0.95).filter(|v| *v > 0.0);
    let factor = p95.map_or(1.0, |p| nice_number(0.03 * width / p));
    let bar_px = nice_number(0.1 * width / factor);
    let _ = writeln!(
        o,
        "<p class=\"note\">Residual vectors (observed − computed) magnified <b>×{}</b>, chosen so that the 95th-percentile residual ({} px) is about 3 % of the image width; scale bar: {} px of residual. Rejected observations: red ×, not in the RMS.</p>",
        sig_trim(factor),
        p95.map_or(DASH.to_string(), |p| num(p, 3)),
        sig_trim(bar_px)
    );
    kind_legend(o, false);
    // RMS table
    o.push_str("<table>\n<tr><th class=\"l\">image</th><th>points</th><th>rejected</th><th>RMS x (px)</th><th>RMS y (px)</th><th>RMS (px)</th><th>max (px)</th></tr>\n");
    let mut all = (0usize, 0usize, 0.0f64, 0.0f64, 0.0f64);
    for img in &d.images {
        let st = image_stats(img);
        all.0 += img.points.len();
        all.1 += st.rejected;
        all.2 += st.sxx;
        all.3 += st.syy;
        all.4 = all.4.max(st.max);
        let _ = writeln!(
            o,
            "<tr><td class=\"l\">{}</td><td>{}</td><td>{}</td>{}</tr>",
            escape(&img.name),
            img.points.len(),
            st.rejected,
            rms_cells(st.n, st.sxx, st.syy, st.max)
        );
    }
    let n_all: usize = d.images.iter().map(|i| image_stats(i).n).sum();
    let _ = writeln!(
        o,
        "<tr class=\"sum\"><td class=\"l\">all</td><td>{}</td><td>{}</td>{}</tr>\n</table>",
        all.0,
        all.1,
        rms_cells(n_all, all.2, all.3, all.4)
    );
    o.push_str("<div class=\"grid\">\n");
    for img in &d.images {
        image_svg(o, img, factor, bar_px);
    }
    o.push_str("</div>\n</section>\n");
}

struct ImageStats {
    n: usize,
    rejected: usize,
    sxx: f64,
    syy: f64,
    max: f64,
}

fn image_stats(img: &ImageResiduals) -> ImageStats {
    let mut s = ImageStats {
        n: 0,
        rejected: 0,
        sxx: 0.0,
        syy: 0.0,
        max: 0.0,
    };
    for p in &img.points {
        if p.rejected {
            s.rejected += 1;
        } else if residual_ok(p) {
            s.n += 1;
            s.sxx += p.dx * p.dx;
            s.syy += p.dy * p.dy;
            s.max = s.max.max(p.dx.hypot(p.dy));
        }
    }
    s
}

fn rms_cells(n: usize, sxx: f64, syy: f64, max: f64) -> String {
    if n == 0 {
        return format!("<td>{DASH}</td><td>{DASH}</td><td>{DASH}</td><td>{DASH}</td>");
    }
    let nf = n as f64;
    format!(
        "<td>{}</td><td>{}</td><td>{}</td><td>{}</td>",
        num((sxx / nf).sqrt(), 3),
        num((syy / nf).sqrt(), 3),
        num(((sxx + syy) / nf).sqrt(), 3),
        num(max, 3)
    )
}

fn image_svg(o: &mut String, img: &ImageResiduals, factor: f64, bar_px: f64) {
    const W: f64 = 300.0;
    const M: f64 = 6.0;
    let (iw, ih) = image_size(img);
    let s = W / iw;
    let hh = (ih * s).min(3.0 * W);
    let (sw, sh) = (W + 2.0 * M, hh + 2.0 * M + 20.0);
    let st = image_stats(img);
    o.push_str("<figure>\n");
    svg_open(o, sw, sh, &format!("residuals of {}", img.name));
    let _ = write!(
        o,
        r##"<rect x="{M}" y="{M}" width="{}" height="{}" fill="#fff" stroke="#666"/>"##,
        c(W),
        c(hh)
    );
    let mut dots = vec![String::new(); KINDS.len() + 1];
    let mut vecs = String::new();
    let mut crosses = String::new();
    for p in &img.points {
        if !(p.x.is_finite() && p.y.is_finite()) {
            continue;
        }
        let (x, y) = (M + p.x * s, M + p.y * s);
        if p.rejected {
            let _ = write!(crosses, "M{} {}l6 6m0-6l-6 6", c(x - 3.0), c(y - 3.0));
            continue;
        }
        let _ = write!(dots[kind_index(&p.kind)], "M{} {}h0", c(x), c(y));
        if residual_ok(p) {
            let (vx, vy) = (p.dx * factor * s, p.dy * factor * s);
            if vx.hypot(vy) >= 0.05 {
                let _ = write!(vecs, "M{} {}l{} {}", c(x), c(y), c(vx), c(vy));
            }
        }
    }
    for (k, d) in dots.iter().enumerate() {
        if !d.is_empty() {
            let col = KINDS.get(k).map_or(OTHER_KIND, |(_, col)| col);
            let _ = write!(
                o,
                r#"<path d="{d}" stroke="{col}" stroke-width="3.4" stroke-linecap="round" fill="none"/>"#
            );
        }
    }
    if !vecs.is_empty() {
        let _ = write!(
            o,
            r##"<path d="{vecs}" stroke="#000" stroke-width="0.9" fill="none"/>"##
        );
    }
    if !crosses.is_empty() {
        let _ = write!(
            o,
            r##"<path d="{crosses}" stroke="#e00" stroke-width="1.5" fill="none"/>"##
        );
    }
    // scale bar
    let bl = (bar_px * factor * s).min(W * 0.6);
    let by = M + hh + 13.0;
    let _ = write!(
        o,
        r##"<path d="M{M} {}v-4M{M} {}h{}v-4" stroke="#000" stroke-width="1.2" fill="none"/><text x="{}" y="{}">{} px</text><text x="{}" y="{}" text-anchor="end">{} × {} px, vectors ×{}</text>"##,
        c(by),
        c(by),
        c(bl),
        c(M + bl + 4.0),
        c(by + 3.0),
        sig_trim(bar_px),
        c(M + W),
        c(by + 3.0),
        iw,
        ih,
        sig_trim(factor)
    );
    o.push_str("</svg>\n");
    let rms = if st.n > 0 {
        num(((st.sxx + st.syy) / st.n as f64).sqrt(), 3)
    } else {
        DASH.to_string()
    };
    let _ = writeln!(
        o,
        "<figcaption><b>{}</b> — {} points, {} rejected, RMS {} px</figcaption>\n</figure>",
        escape(&img.name),
        img.points.len(),
        st.rejected,
        rms
    );
}
