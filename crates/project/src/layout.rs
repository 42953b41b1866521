//! # The coded targets' layout file
//!
//! A test field is often surveyed, or at least laid out to a plan: the project may then name
//! a file with the approximate coordinates of its coded targets (`[targets] layout`). The
//! pipeline uses them only to *start* the network (every image resected from the targets it
//! reads, no relative orientation needed); the adjustment itself takes its shape from the
//! images and its scale from the measured distances, so a layout good to a few centimetres
//! is enough, and a layout point the images place elsewhere is named in a warning.
//!
//! The file is plain CSV, one target per line, in millimetres, in any right-handed frame:
//!
//! ```text
//! # pingcal-layout v1        (optional; lines starting with # are comments)
//! id,x_mm,y_mm,z_mm          (optional header)
//! 17,0.0,1200.5,300.0
//! 18,400.0,1200.5,300.0
//! ```
//!
//! Every line is refused with its file and line number when it does not have four fields,
//! an id that is not a target number, a coordinate that is not a finite number, or an id
//! already given.

use std::collections::BTreeMap;
use std::fmt;

/// The approximate coordinates of coded targets, by target number (mm).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Layout {
    /// Target number → (x, y, z), mm.
    pub points: BTreeMap<u32, [f64; 3]>,
}

/// Why a layout file cannot be read: the file, the line and what was expected.
#[derive(Debug, Clone, PartialEq)]
pub struct LayoutError {
    /// The file as named to the reader.
    pub file: String,
    /// 1-based line number (0: the file as a whole).
    pub line: usize,
    /// What was found and what was expected.
    pub what: String,
}

impl fmt::Display for LayoutError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.line {
            0 => write!(f, "{}: {}", self.file, self.what),
            n => write!(f, "{}:{n}: {}", self.file, self.what),
        }
    }
}

impl std::error::Error for LayoutError {}

/// The longest coordinate accepted (mm): 1 km. A field larger than that is a unit mistake.
const MAX_COORDINATE_MM: f64 = 1e6;

impl Layout {
    /// Reads the text of a layout file; `file` names it in errors.
    pub fn parse(text: &str, file: &str) -> Result<Self, LayoutError> {
        let mut points = BTreeMap::new();
        let err = |line: usize, what: String| LayoutError {
            file: file.to_string(),
            line,
            what,
        };
        for (k, raw) in text.lines().enumerate() {
            let line = raw.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let fields: Vec<&str> = line.split(',').map(str::trim).collect();
            if points.is_empty() && fields.first().is_some_and(|f| f.eq_ignore_ascii_case("id")) {
                continue; // the header
            }
            let (id, xyz) = parse_line(&fields).map_err(|w| err(k + 1, w))?;
            if points.insert(id, xyz).is_some() {
                return Err(err(k + 1, format!("target {id} is given twice")));
            }
        }
        if points.is_empty() {
            return Err(err(
                0,
                "no target in the layout: expected lines id,x_mm,y_mm,z_mm".into(),
            ));
        }
        Ok(Layout { points })
    }
}

/// One data line: `id,x,y,z`.
fn parse_line(fields: &[&str]) -> Result<(u32, [f64; 3]), String> {
    if fields.len() != 4 {
        return Err(format!(
            "{} fields: expected 4 (id,x_mm,y_mm,z_mm)",
            fields.len()
        ));
    }
    let id: u32 = fields[0]
        .parse()
        .map_err(|_| format!("id \"{}\": expected a target number", fields[0]))?;
    let mut xyz = [0.0; 3];
    for (v, (name, s)) in xyz
        .iter_mut()
        .zip(["x_mm", "y_mm", "z_mm"].iter().zip(&fields[1..]))
    {
        let x: f64 = s
            .parse()
            .map_err(|_| format!("target {id} {name} \"{s}\": expected a number"))?;
        if !(x.is_finite() && x.abs() <= MAX_COORDINATE_MM) {
            return Err(format!(
                "target {id} {name} = {s}: expected a finite coordinate within 1 km (mm)"
            ));
        }
        *v = x;
    }
    Ok((id, xyz))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn a_layout_with_comments_and_header_is_read() {
        let l = Layout::parse(
            "# pingcal-layout v1\nid,x_mm,y_mm,z_mm\n17, 0.0,1200.5,300\n\n18,400,1200.5,-3e2\n",
            "f.csv",
        )
        .unwrap();
        assert_eq!(l.points.len(), 2);
        assert_eq!(l.points[&18], [400.0, 1200.5, -300.0]);
    }

    #[test]
    fn bad_lines_are_named_with_file_and_line() {
        let cases = [
            ("17,0,0\n", "f:1: 3 fields: expected 4 (id,x_mm,y_mm,z_mm)"),
            ("x17,0,0,0\n", "f:1: id \"x17\": expected a target number"),
            ("1,0,0,0\n1,1,1,1\n", "f:2: target 1 is given twice"),
            (
                "1,0,nan,0\n",
                "f:1: target 1 y_mm = nan: expected a finite coordinate within 1 km (mm)",
            ),
            (
                "1,0,0,2e6\n",
                "f:1: target 1 z_mm = 2e6: expected a finite coordinate within 1 km (mm)",
            ),
            (
                "1,0,0,one\n",
                "f:1: target 1 z_mm \"one\": expected a number",
            ),
            (
                "# empty\n",
                "f: no target in the layout: expected lines id,x_mm,y_mm,z_mm",
            ),
        ];
        for (text, want) in cases {
            assert_eq!(
                Layout::parse(text, "f").unwrap_err().to_string(),
                want,
                "{text:?}"
            );
        }
    }

    proptest! {
        /// Any text is read or refused with one line naming the file; never a panic.
        #[test]
        fn any_text_is_read_or_refused_in_one_line(text in "[0-9a-z,.#\\-+e \n]{0,200}") {
            match Layout::parse(&text, "f") {
                Ok(l) => prop_assert!(!l.points.is_empty()),
                Err(e) => {
                    let s = e.to_string();
                    prop_assert!(s.starts_with("f:") && !s.contains('\n'));
                }
            }
        }

        /// A layout written back as text reads as itself.
        #[test]
        fn written_layouts_read_back(pts in proptest::collection::btree_map(0u32..5000, [-1e5f64..1e5, -1e5f64..1e5, -1e5f64..1e5], 1..30)) {
            let text: String = pts.iter().map(|(id, p)| format!("{id},{},{},{}\n", p[0], p[1], p[2])).collect();
            prop_assert_eq!(Layout::parse(&text, "f").unwrap().points, pts);
        }
    }
}
