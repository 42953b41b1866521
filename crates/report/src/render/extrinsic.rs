//! The *Extrinsic calibration* section (`extrinsic`): for every method, the rotation R and
//! the translation t (mm) of `p_camera = R · p_lrf + t`, ω φ κ (deg), each with its σ where
//! estimated, and the method's mean check-point error; or why the method failed.

use super::checks::check_stats;
use crate::fmt::{escape, num, opt_num};
use crate::section::{h2, none};
use crate::ReportData;
use std::fmt::Write;

fn with_sigma(v: f64, s: Option<f64>, decimals: usize, sdec: usize) -> String {
    match s {
        Some(s) if s.is_finite() => format!("{} ± {}", num(v, decimals), num(s, sdec)),
        _ => num(v, decimals),
    }
}

pub(crate) fn extrinsic(o: &mut String, d: &ReportData) {
    h2(o, "extrinsic");
    if d.methods.is_empty() {
        none(o, "no extrinsic calibration");
    } else {
        o.push_str(
            "<p class=\"note\"><code>p_camera = R · p_lrf + t</code>; t in mm, ω φ κ in degrees, ± one σ where estimated.</p>\n<div class=\"tables\">\n",
        );
    }
    for m in &d.methods {
        let _ = writeln!(o, "<div>\n<h3>{}</h3>", escape(&m.name));
        if let Some(e) = &m.error {
            let _ = writeln!(o, "<p class=\"err\">failed: {}</p>\n</div>", escape(e));
            continue;
        }
        o.push_str("<table>\n<tr><th class=\"l\">R</th><th>1</th><th>2</th><th>3</th></tr>\n");
        for (i, row) in m.rotation.iter().enumerate() {
            let _ = write!(o, "<tr><th class=\"l\">{}</th>", i + 1);
            for v in row {
                let _ = write!(o, "<td>{}</td>", num(*v, 6));
            }
            o.push_str("</tr>\n");
        }
        o.push_str("</table>\n<table>\n<tr><th></th><th>X / ω</th><th>Y / φ</th><th>Z / κ</th></tr>\n<tr><th class=\"l\">t (mm)</th>");
        for i in 0..3 {
            let s = m.sigma_translation_mm.map(|s| s[i]);
            let _ = write!(o, "<td>{}</td>", with_sigma(m.translation_mm[i], s, 2, 2));
        }
        o.push_str("</tr>\n<tr><th class=\"l\">ω φ κ (deg)</th>");
        for i in 0..3 {
            let s = m.sigma_rotation_deg.map(|s| s[i]);
            let _ = write!(o, "<td>{}</td>", with_sigma(m.opk_deg[i], s, 4, 4));
        }
        o.push_str("</tr>\n</table>\n");
        let (mean, sd, role) = check_stats(m);
        if role.is_some() || m.mean_check_error_mm.is_some() {
            let _ = writeln!(
                o,
                "<p>mean {} error {} mm (sd {} mm)</p>",
                role.unwrap_or("check"),
                opt_num(mean, 2),
                opt_num(sd, 2)
            );
        }
        o.push_str("</div>\n");
    }
    if !d.methods.is_empty() {
        o.push_str("</div>\n");
    }
    o.push_str("</section>\n");
}
