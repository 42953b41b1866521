//! The part of YAML that camera files use: ROS's `camera_info` (as
//! `camera_calibration_parsers` writes it), OpenCV's FileStorage YAML and Kalibr's
//! camchain. Block mappings by indentation (`key: value`, `key:` and a deeper block), block
//! sequences (`- value`), flow sequences (`[1, 2, 3]`, also over several lines), plain and
//! quoted scalars, comments, the `%YAML` directive, `---`, and tags (`!!opencv-matrix`),
//! which are skipped. Anchors, aliases, flow mappings and multi-line scalars are not
//! camera files' and are refused with the line.
//!
//! Errors are `line N: what` (the caller adds the file's name).

/// A YAML node.
#[derive(Clone, Debug, PartialEq)]
pub enum Yaml {
    /// A mapping, in file order.
    Map(Vec<(String, Yaml)>),
    /// A sequence.
    List(Vec<Yaml>),
    /// A scalar, unquoted.
    Scalar(String),
}

impl Yaml {
    /// The value of `key` in a mapping.
    pub fn get(&self, key: &str) -> Option<&Yaml> {
        match self {
            Yaml::Map(m) => m.iter().find(|(k, _)| k == key).map(|(_, v)| v),
            _ => None,
        }
    }

    /// The keys of a mapping.
    pub fn keys(&self) -> Vec<&str> {
        match self {
            Yaml::Map(m) => m.iter().map(|(k, _)| k.as_str()).collect(),
            _ => Vec::new(),
        }
    }

    /// A scalar's text.
    pub fn str(&self) -> Option<&str> {
        match self {
            Yaml::Scalar(s) => Some(s),
            _ => None,
        }
    }

    /// A scalar as a finite number.
    pub fn num(&self) -> Option<f64> {
        self.str()?
            .trim()
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
    }

    /// A sequence of numbers.
    pub fn nums(&self) -> Option<Vec<f64>> {
        match self {
            Yaml::List(v) => v.iter().map(Yaml::num).collect(),
            _ => None,
        }
    }
}

/// One content line: its number (1-based), indentation and text without the comment.
struct Line<'a> {
    no: usize,
    indent: usize,
    text: &'a str,
}

/// `text` up to a comment (`#` at the start or after a space, outside quotes).
fn strip_comment(text: &str) -> &str {
    let (mut quote, mut prev) = (None, ' ');
    for (i, c) in text.char_indices() {
        match quote {
            Some(q) if c == q => quote = None,
            Some(_) => {}
            None if c == '"' || c == '\'' => quote = Some(c),
            None if c == '#' && prev.is_whitespace() => return &text[..i],
            None => {}
        }
        prev = c;
    }
    text
}

/// Parses `text`.
pub fn parse(text: &str) -> Result<Yaml, String> {
    let mut lines = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        if raw.contains('\t') && raw.trim_start().len() < raw.len() && raw.starts_with('\t') {
            return Err(format!("line {}: a tab in the indentation", i + 1));
        }
        let body = strip_comment(raw).trim_end();
        let trimmed = body.trim_start();
        if trimmed.is_empty() || trimmed.starts_with('%') || trimmed == "---" || trimmed == "..." {
            continue;
        }
        lines.push(Line {
            no: i + 1,
            indent: body.len() - trimmed.len(),
            text: trimmed,
        });
    }
    let mut at = 0;
    let node = block(&lines, &mut at, 0)?;
    match lines.get(at) {
        Some(l) => Err(format!("line {}: unexpected indentation", l.no)),
        None => Ok(node.unwrap_or(Yaml::Map(Vec::new()))),
    }
}

/// The block starting at `lines[*at]` whose lines are indented at least `min`.
fn block(lines: &[Line], at: &mut usize, min: usize) -> Result<Option<Yaml>, String> {
    let Some(first) = lines.get(*at) else {
        return Ok(None);
    };
    if first.indent < min {
        return Ok(None);
    }
    let indent = first.indent;
    if first.text == "-" || first.text.starts_with("- ") {
        let mut items = Vec::new();
        while let Some(l) = lines.get(*at) {
            if l.indent != indent || !(l.text == "-" || l.text.starts_with("- ")) {
                break;
            }
            *at += 1;
            let rest = l.text[1..].trim_start();
            if rest.is_empty() {
                items.push(block(lines, at, indent + 1)?.unwrap_or(Yaml::Scalar(String::new())));
            } else if key_of(rest).is_some() {
                return Err(format!(
                    "line {}: a mapping inside a sequence item is not supported in a camera file",
                    l.no
                ));
            } else {
                items.push(value(rest, lines, at, l.no)?);
            }
        }
        return Ok(Some(Yaml::List(items)));
    }
    let mut map: Vec<(String, Yaml)> = Vec::new();
    while let Some(l) = lines.get(*at) {
        if l.indent < indent {
            break;
        }
        if l.indent > indent {
            return Err(format!("line {}: unexpected indentation", l.no));
        }
        let Some((key, rest)) = key_of(l.text) else {
            return Err(format!(
                "line {}: expected `key: value`, found {:?}",
                l.no, l.text
            ));
        };
        *at += 1;
        let rest = skip_tag(rest);
        let v = if rest.is_empty() {
            // a nested block (a sequence may sit at the key's own indentation)
            let next_list = lines
                .get(*at)
                .is_some_and(|n| n.indent == indent && n.text.starts_with('-'));
            let min = if next_list { indent } else { indent + 1 };
            block(lines, at, min)?.unwrap_or(Yaml::Scalar(String::new()))
        } else {
            value(rest, lines, at, l.no)?
        };
        if map.iter().any(|(k, _)| *k == key) {
            return Err(format!("line {}: {key} given twice", l.no));
        }
        map.push((key, v));
    }
    Ok(Some(Yaml::Map(map)))
}

/// `key: rest` of a mapping line (the key unquoted), or `None`.
fn key_of(text: &str) -> Option<(String, &str)> {
    let (key, rest) = if let Some(q) = text.chars().next().filter(|c| *c == '"' || *c == '\'') {
        let end = text[1..].find(q)? + 1;
        let after = text[end + 1..].trim_start();
        (text[1..end].to_string(), after.strip_prefix(':')?)
    } else {
        let i = text
            .find(": ")
            .or_else(|| text.ends_with(':').then(|| text.len() - 1))?;
        let key = text[..i].trim();
        if key.is_empty() || key.starts_with('[') || key.starts_with('{') {
            return None;
        }
        (key.to_string(), &text[i + 1..])
    };
    Some((key, rest.trim()))
}

/// `rest` without a leading tag (`!!opencv-matrix`, `!foo`).
fn skip_tag(rest: &str) -> &str {
    if rest.starts_with('!') {
        rest.find(' ').map_or("", |i| rest[i..].trim_start())
    } else {
        rest
    }
}

/// An inline value: a flow sequence (continued on the next lines until its brackets close)
/// or a scalar.
fn value(rest: &str, lines: &[Line], at: &mut usize, no: usize) -> Result<Yaml, String> {
    let rest = skip_tag(rest);
    if rest.starts_with('{')
        || rest.starts_with('&')
        || rest.starts_with('*')
        || rest.starts_with('|')
        || rest.starts_with('>')
    {
        return Err(format!("line {no}: {rest:?}: flow mappings, anchors, aliases and block scalars are not supported in a camera file"));
    }
    if !rest.starts_with('[') {
        return Ok(Yaml::Scalar(unquote(rest)));
    }
    let mut text = rest.to_string();
    while depth(&text) > 0 {
        let Some(l) = lines.get(*at) else {
            return Err(format!("line {no}: a [ without its ]"));
        };
        *at += 1;
        text.push(' ');
        text.push_str(l.text);
    }
    let mut chars = text.chars().peekable();
    let v = flow(&mut chars, no)?;
    if chars.any(|c| !c.is_whitespace()) {
        return Err(format!("line {no}: text after the closing ]"));
    }
    Ok(v)
}

/// The bracket depth at the end of `text` (outside quotes).
fn depth(text: &str) -> i64 {
    let (mut d, mut quote) = (0i64, None);
    for c in text.chars() {
        match quote {
            Some(q) if c == q => quote = None,
            Some(_) => {}
            None if c == '"' || c == '\'' => quote = Some(c),
            None if c == '[' => d += 1,
            None if c == ']' => d -= 1,
            None => {}
        }
    }
    d
}

/// A flow sequence from `[` (nested ones too).
fn flow(chars: &mut std::iter::Peekable<std::str::Chars>, no: usize) -> Result<Yaml, String> {
    if chars.next() != Some('[') {
        return Err(format!("line {no}: expected ["));
    }
    let mut items = Vec::new();
    let mut cur = String::new();
    loop {
        match chars.peek().copied() {
            None => return Err(format!("line {no}: a [ without its ]")),
            Some('[') => {
                items.push(flow(chars, no)?);
                cur.clear();
            }
            Some(c @ (',' | ']')) => {
                chars.next();
                let t = cur.trim();
                if !t.is_empty() {
                    items.push(Yaml::Scalar(unquote(t)));
                }
                cur.clear();
                if c == ']' {
                    return Ok(Yaml::List(items));
                }
            }
            Some(c) => {
                chars.next();
                cur.push(c);
            }
        }
    }
}

/// A scalar without its quotes.
fn unquote(s: &str) -> String {
    let s = s.trim();
    for q in ['"', '\''] {
        if s.len() >= 2 && s.starts_with(q) && s.ends_with(q) {
            return s[1..s.len() - 1].to_string();
        }
    }
    s.to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ros_camera_info_opencv_filestorage_and_kalibr_camchain_read() {
        let ros = "image_width: 1280\nimage_height: 1024\ncamera_name: \"cam2\"\ncamera_matrix:\n  rows: 3\n  cols: 3\n  data: [4548.4, 0, 703.2,\n         0, 4544.4, 609.2, 0, 0, 1]  # K\ndistortion_model: plumb_bob\ndistortion_coefficients:\n  rows: 1\n  cols: 5\n  data: [0, 0, 0, 0, 0]\n";
        let y = parse(ros).unwrap();
        assert_eq!(y.get("image_width").unwrap().num(), Some(1280.0));
        assert_eq!(y.get("camera_name").unwrap().str(), Some("cam2"));
        let k = y
            .get("camera_matrix")
            .unwrap()
            .get("data")
            .unwrap()
            .nums()
            .unwrap();
        assert_eq!(
            k,
            vec![4548.4, 0.0, 703.2, 0.0, 4544.4, 609.2, 0.0, 0.0, 1.0]
        );
        let cv = "%YAML:1.0\n---\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 1.0, 0.0, 2.0, 0.0, 1.0, 3.0, 0.0, 0.0, 1.0 ]\n";
        let y = parse(cv).unwrap();
        assert_eq!(
            y.get("camera_matrix").unwrap().get("dt").unwrap().str(),
            Some("d")
        );
        let kal = "cam0:\n  T_cn_cnm1:\n  - [1.0, 0.0, 0.0, 0.1]\n  - [0.0, 1.0, 0.0, 0.0]\n  camera_model: pinhole\n  intrinsics: [461.6, 460.2, 362.7, 246.0]\n  distortion_model: radtan\n  distortion_coeffs: [-0.28, 0.07, 0.0009, 0.0001]\n  resolution: [752, 480]\n  rostopic: /cam0/image_raw\ncam1:\n  camera_model: pinhole\n";
        let y = parse(kal).unwrap();
        assert_eq!(y.keys(), vec!["cam0", "cam1"]);
        let c0 = y.get("cam0").unwrap();
        assert_eq!(
            c0.get("resolution").unwrap().nums(),
            Some(vec![752.0, 480.0])
        );
        match c0.get("T_cn_cnm1").unwrap() {
            Yaml::List(rows) => assert_eq!(rows[0].nums(), Some(vec![1.0, 0.0, 0.0, 0.1])),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn what_a_camera_file_never_holds_is_refused_with_the_line() {
        assert_eq!(
            parse("a: 1\nb: [1, 2\n").unwrap_err(),
            "line 2: a [ without its ]"
        );
        assert!(parse("a: 1\n   b: 2\n")
            .unwrap_err()
            .starts_with("line 2: unexpected indentation"));
        assert!(parse("a: &x 1\n").unwrap_err().starts_with("line 1:"));
        assert_eq!(parse("a: 1\na: 2\n").unwrap_err(), "line 2: a given twice");
        assert!(parse("just text\n")
            .unwrap_err()
            .starts_with("line 1: expected `key: value`"));
    }
}
