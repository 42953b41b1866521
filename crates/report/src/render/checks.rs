//! The *Check points* section (`checks`), the paper's Figure 7: the check-point error of every
//! ball per method as grouped bars (the leave-one-out errors when a method has no check
//! points), each method's mean as a line, and the errors in tables.

use super::legend::METHOD_COLOURS;
use crate::fmt::{c, escape, num, opt_num};
use crate::plot::{nice_step, svg_open, ticks, Frame, MARGIN_LEFT, MARGIN_TOP};
use crate::section::{h2, id_cmp, none};
use crate::{CheckRow, MethodResult, ReportData};
use std::fmt::Write;

/// The rows a method contributes to the chart: its "check" rows, or its "loo" rows when it
/// has no check rows; with the role used.
fn plotted_rows(m: &MethodResult) -> (Option<&'static str>, Vec<&CheckRow>) {
    for role in ["check", "loo"] {
        let rows: Vec<&CheckRow> = m
            .checks
            .iter()
            .filter(|r| r.role.trim().eq_ignore_ascii_case(role))
            .collect();
        if !rows.is_empty() {
            return (Some(role), rows);
        }
    }
    (None, Vec::new())
}

fn mean_sd(v: &[f64]) -> (Option<f64>, Option<f64>) {
    let v: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return (None, None);
    }
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    let sd = if v.len() > 1 {
        Some((v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt())
    } else {
        None
    };
    (Some(mean), sd)
}

/// Mean and sd of the plotted rows: the method's own numbers for check rows when given,
/// computed from the rows otherwise.
pub(super) fn check_stats(m: &MethodResult) -> (Option<f64>, Option<f64>, Option<&'static str>) {
    let (role, rows) = plotted_rows(m);
    let errs: Vec<f64> = rows.iter().map(|r| r.error_mm).collect();
    let (cm, cs) = mean_sd(&errs);
    if role == Some("check") || role.is_none() {
        (
            m.mean_check_error_mm.or(cm),
            m.sd_check_error_mm.or(cs),
            role,
        )
    } else {
        (cm, cs, role)
    }
}

pub(crate) fn checks(o: &mut String, d: &ReportData) {
    h2(o, "checks");
    struct Series<'a> {
        name: &'a str,
        role: &'static str,
        colour: &'static str,
        rows: Vec<&'a CheckRow>,
        mean: Option<f64>,
    }
    let mut series = Vec::new();
    for (i, m) in d.methods.iter().enumerate() {
        let (role, rows) = plotted_rows(m);
        if let Some(role) = role {
            let (mean, _, _) = check_stats(m);
            series.push(Series {
                name: &m.name,
                role,
                colour: METHOD_COLOURS[i % METHOD_COLOURS.len()],
                rows,
                mean,
            });
        }
    }
    if series.is_empty() {
        none(o, "no check points");
    } else {
        let mut ids: Vec<&str> = series
            .iter()
            .flat_map(|s| s.rows.iter().map(|r| r.id.as_str()))
            .collect();
        ids.sort_by(|a, b| id_cmp(a, b));
        ids.dedup();
        o.push_str("<div class=\"legend\">");
        for s in &series {
            let _ = write!(
                o,
                "<span class=\"sw bar\" style=\"background:{}\"></span>{} ({} points, mean {} mm)",
                s.colour,
                escape(s.name),
                s.role,
                opt_num(s.mean, 1)
            );
        }
        o.push_str("</div>\n");
        bar_chart(
            o,
            &ids,
            &series
                .iter()
                .map(|s| (s.name, s.colour, &s.rows[..], s.mean))
                .collect::<Vec<_>>(),
        );
        let _ = writeln!(
            o,
            "<p class=\"note\">Error = length of the difference between the transformed LRF ball centre and the photogrammetric one, per {} ball; dashed lines: the means.</p>",
            if series.iter().all(|s| s.role == "check") { "check" } else { "check (or leave-one-out)" }
        );
    }
    // Tables: every row (control, check, loo) of every method.
    let with_rows: Vec<&MethodResult> = d.methods.iter().filter(|m| !m.checks.is_empty()).collect();
    if !with_rows.is_empty() {
        o.push_str("<div class=\"tables\">\n");
        for m in with_rows {
            let _ = writeln!(
                o,
                "<table>\n<caption>{}</caption>\n<tr><th class=\"l\">id</th><th class=\"l\">role</th><th>dx (mm)</th><th>dy (mm)</th><th>dz (mm)</th><th>error (mm)</th></tr>",
                escape(&m.name)
            );
            let mut rows: Vec<&CheckRow> = m.checks.iter().collect();
            rows.sort_by(|a, b| {
                role_rank(&a.role)
                    .cmp(&role_rank(&b.role))
                    .then(id_cmp(&a.id, &b.id))
            });
            for r in rows {
                let _ = writeln!(
                    o,
                    "<tr><td class=\"l\">{}</td><td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                    escape(&r.id),
                    escape(role_label(&r.role)),
                    num(r.dx_mm, 2),
                    num(r.dy_mm, 2),
                    num(r.dz_mm, 2),
                    num(r.error_mm, 2)
                );
            }
            let (mean, sd, role) = check_stats(m);
            let role = role.unwrap_or("check");
            let _ = writeln!(
                o,
                "<tr class=\"sum\"><td class=\"l\" colspan=\"5\">mean {role} error</td><td>{}</td></tr>\n<tr class=\"sum\"><td class=\"l\" colspan=\"5\">sd {role} error</td><td>{}</td></tr>\n</table>",
                opt_num(mean, 2),
                opt_num(sd, 2)
            );
        }
        o.push_str("</div>\n");
        if d.methods
            .iter()
            .any(|m| m.checks.iter().any(|r| r.role == "loo"))
        {
            o.push_str("<p class=\"note\">left out (leave-one-out): each control ball in turn left out of the registration and transformed with the extrinsic from the others; its error says how well the rest predicts it.</p>\n");
        }
    }
    o.push_str("</section>\n");
}

/// How a row's role reads in the tables.
fn role_label(role: &str) -> &str {
    match role {
        "loo" => "left out",
        other => other,
    }
}

fn role_rank(role: &str) -> u8 {
    match role.trim().to_ascii_lowercase().as_str() {
        "check" => 0,
        "loo" => 1,
        "control" => 2,
        _ => 3,
    }
}

type BarSeries<'a> = (&'a str, &'static str, &'a [&'a CheckRow], Option<f64>);

fn bar_chart(o: &mut String, ids: &[&str], series: &[BarSeries<'_>]) {
    const LABEL_MARGIN: f64 = 96.0;
    let (f, step) = bar_frame(ids, series);
    let (w, h) = f.svg_size();
    svg_open(
        o,
        w + LABEL_MARGIN,
        h,
        "check-point error per ball and method",
    );
    y_grid(o, &f, step);
    bars(o, &f, ids, series);
    mean_lines(o, &f, series);
    let _ = write!(
        o,
        r#"<text class="axis" x="{}" y="{}" text-anchor="middle">ball id</text><text class="axis" transform="translate(14 {}) rotate(-90)" text-anchor="middle">check-point error (mm)</text>"#,
        c(f.left + 0.5 * f.w),
        c(f.top + f.h + 32.0),
        c(f.top + 0.5 * f.h)
    );
    o.push_str("</svg>\n");
}

/// The chart's frame: a group of bars per ball, up to the largest error or mean; the
/// y step.
fn bar_frame(ids: &[&str], series: &[BarSeries<'_>]) -> (Frame, f64) {
    let n = ids.len().max(1);
    let m = series.len().max(1);
    let group_px = (22.0 * m as f64 + 20.0).clamp(40.0, 140.0);
    let plot_w = (group_px * n as f64).clamp(480.0, 1000.0);
    let plot_h = 320.0;
    let mut ymax: f64 = 0.0;
    for (_, _, rows, mean) in series {
        for r in rows.iter() {
            if r.error_mm.is_finite() {
                ymax = ymax.max(r.error_mm);
            }
        }
        if let Some(mv) = mean.filter(|v| v.is_finite()) {
            ymax = ymax.max(mv);
        }
    }
    if ymax <= 0.0 {
        ymax = 1.0;
    }
    let step = nice_step(ymax * 1.08, 6);
    let y1 = (ymax * 1.08 / step).ceil() * step;
    let f = Frame {
        x0: 0.0,
        x1: n as f64,
        y0: 0.0,
        y1,
        left: MARGIN_LEFT,
        top: MARGIN_TOP,
        w: plot_w,
        h: plot_h,
    };
    (f, step)
}

/// The y grid and its labels (x is categorical), in the plot's box.
fn y_grid(o: &mut String, f: &Frame, step: f64) {
    let y1 = f.y1;
    let mut grid = String::new();
    let mut labels = String::new();
    for v in ticks(0.0, y1, step) {
        let y = f.py(v);
        let _ = write!(grid, "M{} {}H{}", c(f.left - 4.0), c(y), c(f.left + f.w));
        let _ = write!(
            labels,
            r#"<text x="{}" y="{}" text-anchor="end">{}</text>"#,
            c(f.left - 6.0),
            c(y + 3.5),
            crate::fmt::tick_label(v, step)
        );
    }
    let _ = write!(
        o,
        r##"<rect x="{}" y="{}" width="{}" height="{}" fill="#fff" stroke="#888"/><path d="{grid}" stroke="#ddd" fill="none"/><g>{labels}</g>"##,
        c(f.left),
        c(f.top),
        c(f.w),
        c(f.h)
    );
}

/// One bar per ball and method with the error in its tooltip; the balls' ids below.
fn bars(o: &mut String, f: &Frame, ids: &[&str], series: &[BarSeries<'_>]) {
    let m = series.len().max(1);
    let bw = 0.8 / m as f64;
    for (i, id) in ids.iter().enumerate() {
        for (j, (name, colour, rows, _)) in series.iter().enumerate() {
            let Some(r) = rows.iter().find(|r| r.id == *id) else {
                continue;
            };
            if !r.error_mm.is_finite() {
                continue;
            }
            let x = f.px(i as f64 + 0.1 + j as f64 * bw);
            let y = f.py(r.error_mm.max(0.0));
            let _ = write!(
                o,
                r#"<rect x="{}" y="{}" width="{}" height="{}" fill="{colour}"><title>{}: ball {} error {} mm</title></rect>"#,
                c(x),
                c(y),
                c(bw * f.scale_x() - 1.0),
                c(f.py(0.0) - y),
                escape(name),
                escape(id),
                num(r.error_mm, 2)
            );
        }
        let _ = write!(
            o,
            r#"<text class="axis" x="{}" y="{}" text-anchor="middle">{}</text>"#,
            c(f.px(i as f64 + 0.5)),
            c(f.top + f.h + 15.0),
            escape(id)
        );
    }
}

/// Each method's mean as a dashed line, labelled in the right margin, labels nudged apart
/// when close.
fn mean_lines(o: &mut String, f: &Frame, series: &[BarSeries<'_>]) {
    let mut used: Vec<f64> = Vec::new();
    for (_, colour, _, mean) in series {
        let Some(mv) = mean.filter(|v| v.is_finite()) else {
            continue;
        };
        let y = f.py(mv);
        let _ = write!(
            o,
            r#"<path d="M{} {}H{}" stroke="{colour}" stroke-width="1.6" stroke-dasharray="6 4"/>"#,
            c(f.left),
            c(y),
            c(f.left + f.w)
        );
        let mut ty = y + 4.0;
        while used.iter().any(|u| (u - ty).abs() < 13.0) {
            ty -= 13.0;
        }
        used.push(ty);
        let _ = write!(
            o,
            r#"<text x="{}" y="{}" style="fill:{colour};font-weight:bold">mean {} mm</text>"#,
            c(f.left + f.w + 6.0),
            c(ty),
            num(mv, 1)
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_sort_naturally() {
        let mut v = vec!["12", "b", "4", "a", "9", "15", "11"];
        v.sort_by(|a, b| id_cmp(a, b));
        assert_eq!(v, ["4", "9", "11", "12", "15", "a", "b"]);
        let mut w = vec!["B11", "B4", "T2", "B1", "T10"];
        w.sort_by(|a, b| id_cmp(a, b));
        assert_eq!(w, ["B1", "B4", "B11", "T2", "T10"]);
    }

    #[test]
    fn chart_uses_loo_when_no_check_rows() {
        let row = |id: &str, role: &str| CheckRow {
            id: id.into(),
            error_mm: 1.0,
            role: role.into(),
            ..Default::default()
        };
        let m = MethodResult {
            checks: vec![row("1", "control"), row("2", "loo"), row("3", "loo")],
            ..Default::default()
        };
        let (role, rows) = plotted_rows(&m);
        assert_eq!(role, Some("loo"));
        assert_eq!(rows.len(), 2);
        let m2 = MethodResult {
            checks: vec![row("1", "check"), row("2", "loo")],
            ..Default::default()
        };
        assert_eq!(plotted_rows(&m2).0, Some("check"));
    }
}
