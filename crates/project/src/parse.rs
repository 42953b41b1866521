//! # Reading the text of `project.toml`
//!
//! [`ProjectFile::parse`] hands the text to the toml crate and, when it refuses it, turns the
//! error into one line: the file, the line the error's span starts on, the entry and value
//! there, and the parser's message, e.g.
//!
//! ```text
//! project.toml: line 3: method = "joint2": expected one of spheres, corner, both
//! project.toml: line 23: width = "wide": invalid type: string "wide", expected u32
//! project.toml: line 24: free: "K9": expected one of c, xp, yp, K1, K2, K3, P1, P2, B1, B2
//! project.toml: line 62: unknown field `colour`, expected one of `model`, …
//! ```
//!
//! The entry is found on the span's line by [`entry_at`]: `key = value` when the span is
//! the whole value after `key =`, `key: value` when it is inside it (an element of an
//! array), the span's text alone otherwise (a key, or an element of an array written over
//! several lines) unless the message already quotes it. A missing top-level key has no
//! line: ``project.toml: missing field `method` ``.

use crate::schema::ProjectFile;
use crate::ProjectError;
use std::ops::Range;

impl ProjectFile {
    /// Parses the text of a project file; `file` names it in errors.
    pub fn parse(text: &str, file: &str) -> Result<Self, ProjectError> {
        toml::from_str(text).map_err(|e| ProjectError::Syntax {
            path: file.to_string(),
            what: describe(text, &e),
        })
    }

    /// The text of the file (as `pingcal simulate` writes it).
    pub fn to_toml_string(&self) -> String {
        toml::to_string(self).expect("a project file always serialises")
    }
}

/// The error of file `file` (text `text`) that is not valid TOML or not of its schema.
pub(crate) fn syntax(file: &str, text: &str, e: toml::de::Error) -> ProjectError {
    ProjectError::Syntax {
        path: file.to_string(),
        what: describe(text, &e),
    }
}

/// The error of file `file` whose values are refused, saying `what`.
pub(crate) fn invalid(file: &str, what: String) -> ProjectError {
    ProjectError::Invalid {
        path: file.to_string(),
        what,
    }
}

/// "line N: entry: message", or the message alone when the error has no place.
pub(crate) fn describe(text: &str, e: &toml::de::Error) -> String {
    let message = one_line(e.message());
    // An empty span at the start is the whole document (a missing top-level key).
    let Some(span) = e
        .span()
        .filter(|s| text.get(s.clone()).is_some() && *s != (0..0))
    else {
        return message;
    };
    let line = 1 + text[..span.start].matches('\n').count();
    match entry_at(text, span) {
        Some(entry) if !message.contains(&format!("`{entry}`")) => {
            format!("line {line}: {entry}: {message}")
        }
        _ => format!("line {line}: {message}"),
    }
}

/// The entry at `span` (valid in `text`), as the error names it: `key = value`,
/// `key: value` or `value` (see the module's documentation); `None` for an empty span or
/// one over several lines.
fn entry_at(text: &str, span: Range<usize>) -> Option<String> {
    let value = &text[span.clone()];
    if value.trim().is_empty() || value.contains('\n') {
        return None;
    }
    let line_start = text[..span.start].rfind('\n').map_or(0, |i| i + 1);
    let before = &text[line_start..span.start];
    let Some((key, between)) = last_key(before) else {
        return Some(value.to_string());
    };
    Some(if between.trim().is_empty() {
        format!("{key} = {value}")
    } else {
        format!("{key}: {value}")
    })
}

/// In the text of a line before a value: the key of the last `=` outside quotes whose
/// value the span is in, and what lies between that `=` and the span; `None` when there is
/// no such `=` (the span is a key, or the line holds no `=`) or its key is empty. A `{` or
/// a `,` directly inside an inline table starts a new key.
fn last_key(before: &str) -> Option<(&str, &str)> {
    let mut quote = None;
    let mut escaped = false;
    let mut open = Vec::new();
    let mut key_start = 0;
    let mut eq = None;
    for (i, ch) in before.char_indices() {
        match (quote, ch) {
            _ if escaped => escaped = false,
            (Some('"'), '\\') => escaped = true,
            (Some(q), c) if c == q => quote = None,
            (Some(_), _) => {}
            (None, '"' | '\'') => quote = Some(ch),
            (None, '=') => eq = Some((key_start, i)),
            (None, '[') => open.push('['),
            (None, ']' | '}') => {
                open.pop();
            }
            (None, '{') => {
                open.push('{');
                (key_start, eq) = (i + 1, None);
            }
            (None, ',') if open.last() == Some(&'{') => (key_start, eq) = (i + 1, None),
            _ => {}
        }
    }
    let (start, at) = eq?;
    let key = before[start..at].trim();
    (!key.is_empty()).then(|| (key, &before[at + 1..]))
}

/// A message flattened to one line.
pub(crate) fn one_line(s: &str) -> String {
    s.lines()
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect::<Vec<_>>()
        .join(" ")
}
