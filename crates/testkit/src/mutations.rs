//! The readers' mutation harness: valid files mutated the ways real files go wrong.
//!
//! A reader's test draws a [`Mutation`] from [`mutation`], applies it to a valid file with
//! [`apply`] and judges the reader's answer: a refusal with [`refused_well`] (it names the
//! file and is never for a byte-order mark), an accepted cut of a format without counts
//! with [`prefix_ok`], the rest by what the mutated text legally means for that format,
//! which only the reader's own test knows.
//!
//! ```
//! use pingcal_testkit::mutations::{apply, Mutation, Numbers};
//! let text = "1 2\n3 4\n";
//! assert_eq!(apply(text, &Mutation::Duplicate(1), &Numbers::Tokens), "1 2\n3 4\n3 4\n");
//! assert_eq!(apply(text, &Mutation::Huge(2), &Numbers::Tokens), "1 2\n1e300 4\n");
//! ```

use proptest::prelude::*;

/// One way a file goes wrong.
#[derive(Clone, Debug)]
pub enum Mutation {
    /// Line `k` (modulo the line count) written twice.
    Duplicate(usize),
    /// `text` appended after the last line.
    Append(String),
    /// The file cut after `k` bytes (modulo its length).
    Cut(usize),
    /// A UTF-8 byte-order mark in front.
    Bom,
    /// The `k`-th number of the file (modulo their count, see [`Numbers`]) replaced by
    /// `1e300`.
    Huge(usize),
}

impl Mutation {
    /// Whether this appends only white space (blank lines), which no reader may refuse
    /// or read differently.
    pub fn appends_blank(&self) -> bool {
        matches!(self, Mutation::Append(s) if s.trim().is_empty())
    }
}

/// The mutations, each of the five kinds equally likely. An appended text is one of the
/// five `appended` lines (each ending in `\n`; what the format's reader might mistake for
/// data or must pass over) or a random word line such as `ab3.;x`.
pub fn mutation(appended: [&'static str; 5]) -> impl Strategy<Value = Mutation> {
    prop_oneof![
        any::<usize>().prop_map(Mutation::Duplicate),
        prop_oneof![
            Just(appended[0].to_string()),
            Just(appended[1].to_string()),
            Just(appended[2].to_string()),
            Just(appended[3].to_string()),
            Just(appended[4].to_string()),
            "[a-z][a-z0-9.;]{0,11}".prop_map(|s| s + "\n"),
        ]
        .prop_map(Mutation::Append),
        any::<usize>().prop_map(Mutation::Cut),
        Just(Mutation::Bom),
        any::<usize>().prop_map(Mutation::Huge),
    ]
}

/// Where [`Mutation::Huge`] may put its `1e300`: the numbers of a file, in reading order.
pub enum Numbers<'a> {
    /// Every number token: a maximal run of `[0-9.eE+-]` that parses as a number, does not
    /// follow a letter or digit, and is not inside a `"string"` (JSON, XML, BAL).
    Tokens,
    /// The fields of a line format: in the lines `data_line` accepts, the fields between
    /// any of `separators` that parse as numbers (white space trimmed), from field `first`
    /// on (the ones before are ids). The mutated line is joined again with
    /// `separators[0]`.
    Fields {
        /// Which lines hold data (not a comment or a header).
        data_line: fn(&str) -> bool,
        /// What separates the fields; the first one joins them again.
        separators: &'a [char],
        /// The first field that may hold a value (0-based).
        first: usize,
    },
}

/// `text` mutated by `m`; a [`Mutation::Huge`] replaces one of `numbers`.
pub fn apply(text: &str, m: &Mutation, numbers: &Numbers) -> String {
    let lines: Vec<&str> = text.lines().collect();
    match m {
        Mutation::Duplicate(k) => {
            let k = k % lines.len();
            let mut v = lines.clone();
            v.insert(k, lines[k]);
            v.join("\n") + "\n"
        }
        Mutation::Append(s) => format!("{text}{s}"),
        Mutation::Cut(k) => text[..k % text.len()].to_string(),
        Mutation::Bom => format!("\u{feff}{text}"),
        Mutation::Huge(k) => match numbers {
            Numbers::Tokens => {
                let spots = number_tokens(text);
                let (s, e) = spots[k % spots.len()];
                format!("{}1e300{}", &text[..s], &text[e..])
            }
            Numbers::Fields {
                data_line,
                separators,
                first,
            } => huge_field(&lines, *k, *data_line, separators, *first),
        },
    }
}

/// `lines` with the `k`-th number field (see [`Numbers::Fields`]) replaced by `1e300`.
fn huge_field(
    lines: &[&str],
    k: usize,
    data_line: fn(&str) -> bool,
    separators: &[char],
    first: usize,
) -> String {
    // (line, field) of every number field.
    let mut spots = Vec::new();
    for (i, l) in lines.iter().enumerate() {
        if data_line(l) {
            for (j, t) in l.split(separators).enumerate().skip(first) {
                if t.trim().parse::<f64>().is_ok() {
                    spots.push((i, j));
                }
            }
        }
    }
    let (i, j) = spots[k % spots.len()];
    let mut v: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
    let fields: Vec<&str> = lines[i]
        .split(separators)
        .enumerate()
        .map(|(n, t)| if n == j { "1e300" } else { t })
        .collect();
    v[i] = fields.join(&separators[0].to_string());
    v.join("\n") + "\n"
}

/// The number tokens of `text` (see [`Numbers::Tokens`]) as (start, end) byte ranges.
fn number_tokens(text: &str) -> Vec<(usize, usize)> {
    let b = text.as_bytes();
    let (mut out, mut i, mut in_str) = (Vec::new(), 0, false);
    while i < b.len() {
        if b[i] == b'"' {
            in_str = !in_str;
            i += 1;
            continue;
        }
        let num = |c: u8| c.is_ascii_digit() || b".eE+-".contains(&c);
        if !in_str && num(b[i]) && (i == 0 || !b[i - 1].is_ascii_alphanumeric()) {
            let s = i;
            while i < b.len() && num(b[i]) {
                i += 1;
            }
            if text[s..i].parse::<f64>().is_ok() {
                out.push((s, i));
            }
        } else {
            i += 1;
        }
    }
    out
}

/// The line of `text` that `m` duplicates (empty for the other mutations).
pub fn duplicated_line<'a>(text: &'a str, m: &Mutation) -> &'a str {
    match m {
        Mutation::Duplicate(k) => {
            let lines: Vec<&str> = text.lines().collect();
            lines[k % lines.len()]
        }
        _ => "",
    }
}

/// Whether `m` is a cut of `text` that leaves all its data (only trailing white space cut).
pub fn whole_after_cut(text: &str, m: &Mutation) -> bool {
    matches!(m, Mutation::Cut(k) if k % text.len() >= text.trim_end().len())
}

/// The check every refusal passes: the error `e` starts with the file's name `file`, and a
/// byte-order mark is never a reason to refuse.
pub fn refused_well(file: &str, m: &Mutation, e: &str) -> Result<(), TestCaseError> {
    prop_assert!(e.starts_with(file), "error does not name {}: {}", file, e);
    prop_assert!(!matches!(m, Mutation::Bom), "BOM refused: {}", e);
    Ok(())
}

/// The check of an accepted cut in a format without counts: what was read (`got`) is a
/// prefix of the clean file's records whose last record may be cut short.
pub fn prefix_ok<T: PartialEq + std::fmt::Debug>(
    got: &[T],
    clean: &[T],
) -> Result<(), TestCaseError> {
    prop_assert!(got.len() <= clean.len());
    let n = got.len().saturating_sub(1);
    prop_assert_eq!(
        &got[..n],
        &clean[..n],
        "a cut changed more than the last record"
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn number_tokens_skip_strings_and_names() {
        let text = "{\"a1\": 2.5, \"b\": [1e3, -4]} x7 8";
        let got: Vec<&str> = number_tokens(text)
            .into_iter()
            .map(|(s, e)| &text[s..e])
            .collect();
        assert_eq!(got, ["2.5", "1e3", "-4", "8"]);
    }

    #[test]
    fn a_huge_field_skips_ids_comments_and_non_numbers() {
        let fields = Numbers::Fields {
            data_line: |l| !l.starts_with('#'),
            separators: &[','],
            first: 1,
        };
        let text = "# 1,2\n7,a,3\n8,4,5\n";
        let huge = |k| apply(text, &Mutation::Huge(k), &fields);
        assert_eq!(huge(0), "# 1,2\n7,a,1e300\n8,4,5\n");
        assert_eq!(huge(1), "# 1,2\n7,a,3\n8,1e300,5\n");
        assert_eq!(huge(3), huge(0));
    }

    #[test]
    fn cuts_duplicates_and_blank_appends() {
        let text = "a\nb\n";
        assert_eq!(apply(text, &Mutation::Cut(7), &Numbers::Tokens), "a\nb");
        assert_eq!(duplicated_line(text, &Mutation::Duplicate(3)), "b");
        assert!(whole_after_cut(text, &Mutation::Cut(3)));
        assert!(!whole_after_cut(text, &Mutation::Cut(2)));
        assert!(Mutation::Append("\n \n".into()).appends_blank());
        assert!(!Mutation::Append("7\n".into()).appends_blank());
    }
}
