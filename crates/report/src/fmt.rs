//! Text helpers: HTML escaping and number formatting (non-finite → "—").

/// What a non-finite number prints as.
pub(crate) const DASH: &str = "—";

/// Escapes `&`, `<`, `>`, `"` and `'` so that any string is safe in HTML text and in
/// double- or single-quoted attribute values (and in XML).
pub fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for ch in s.chars() {
        match ch {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            // Control characters other than tab/newline are not allowed in XML 1.0.
            c if (c as u32) < 0x20 && c != '\t' && c != '\n' && c != '\r' => out.push('\u{fffd}'),
            c => out.push(c),
        }
    }
    out
}

/// Decimals of a length or coordinate in mm (one format per quantity, everywhere).
pub(crate) const MM: usize = 2;
/// Decimals of a σ in mm.
pub(crate) const SIGMA_MM: usize = 3;
/// Decimals of an angle or its σ in degrees.
pub(crate) const DEG: usize = 4;
/// Decimals of an image quantity in pixels.
pub(crate) const PX: usize = 3;
/// Decimals of a correlation coefficient or a normalised residual.
pub(crate) const RATIO: usize = 2;

/// Fixed decimals; "—" for NaN/inf; never "-0.00".
pub(crate) fn num(v: f64, decimals: usize) -> String {
    if !v.is_finite() {
        return DASH.to_string();
    }
    let s = format!("{v:.decimals$}");
    strip_negative_zero(s)
}

/// Optional number with fixed decimals; `None` prints as "—".
pub(crate) fn opt_num(v: Option<f64>, decimals: usize) -> String {
    v.map_or_else(|| DASH.to_string(), |v| num(v, decimals))
}

/// A general-purpose format for values of unknown magnitude (intrinsics, σ's): six
/// significant digits in fixed notation for 1e-3 ≤ |v| < 1e6, scientific otherwise.
pub(crate) fn sig(v: f64) -> String {
    if !v.is_finite() {
        return DASH.to_string();
    }
    if v == 0.0 {
        return "0".to_string();
    }
    let a = v.abs();
    if (1e-3..1e6).contains(&a) {
        let mag = a.log10().floor() as i32;
        let decimals = (5 - mag).clamp(0, 9) as usize;
        strip_negative_zero(format!("{v:.decimals$}"))
    } else {
        // Mantissa with up to 5 significant digits, trailing zeros dropped: "1.3e-4".
        let e = format!("{v:.4e}");
        match e.split_once('e') {
            Some((m, x)) if m.contains('.') => {
                format!("{}e{x}", m.trim_end_matches('0').trim_end_matches('.'))
            }
            _ => e,
        }
    }
}

fn strip_negative_zero(s: String) -> String {
    if s.starts_with('-') && s[1..].chars().all(|c| c == '0' || c == '.') {
        s[1..].to_string()
    } else {
        s
    }
}

/// An SVG coordinate: one decimal, trailing ".0" dropped, non-finite → "0" (callers skip
/// non-finite points before; this is only a last guard that keeps the SVG valid).
pub(crate) fn c(v: f64) -> String {
    if !v.is_finite() {
        return "0".to_string();
    }
    let r = (v * 10.0).round() / 10.0;
    let s = format!("{r:.1}");
    let s = s.strip_suffix(".0").map(str::to_string).unwrap_or(s);
    if s == "-0" {
        "0".to_string()
    } else {
        s
    }
}

/// Tick label for a value on an axis whose tick step is `step`.
pub(crate) fn tick_label(v: f64, step: f64) -> String {
    let decimals = if step >= 1.0 || !step.is_finite() || step <= 0.0 {
        0
    } else {
        (-step.log10().floor()) as usize
    };
    num(v, decimals.min(9))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escapes_markup_and_quotes() {
        assert_eq!(
            escape(r#"<script>alert("x" & 'y')</script>"#),
            "&lt;script&gt;alert(&quot;x&quot; &amp; &#39;y&#39;)&lt;/script&gt;"
        );
        assert_eq!(escape("σ0 — ω φ κ"), "σ0 — ω φ κ");
        assert_eq!(escape("a\u{1}b"), "a\u{fffd}b");
    }

    #[test]
    fn numbers() {
        assert_eq!(num(f64::NAN, 2), DASH);
        assert_eq!(num(f64::INFINITY, 2), DASH);
        assert_eq!(num(-0.0001, 2), "0.00");
        assert_eq!(num(1.2345, 2), "1.23");
        assert_eq!(sig(2.45), "2.45000");
        assert_eq!(sig(-1.5e-5), "-1.5e-5");
        assert_eq!(sig(1.23456e7), "1.2346e7");
        assert_eq!(sig(0.0), "0");
        assert_eq!(c(1.04), "1");
        assert_eq!(c(-0.04), "0");
        assert_eq!(c(12.35), "12.4");
        assert_eq!(c(f64::NAN), "0");
        assert_eq!(tick_label(0.5, 0.1), "0.5");
        assert_eq!(tick_label(1000.0, 500.0), "1000");
    }
}
