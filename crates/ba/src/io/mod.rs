//! Reading and writing measurements: pingcal's own JSON format ([`measurements`]) and
//! DBAT's mark-point and control files ([`dbat`]).

pub mod dbat;
pub mod measurements;

/// `s` with control characters (a raw `\r`, an escape sequence) and byte-order marks
/// written as escapes, so that a value echoed from a file into a message cannot move the
/// terminal's cursor or hide itself.
pub fn printable(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        if c.is_control() || c == '\u{feff}' {
            out.extend(c.escape_debug());
        } else {
            out.push(c);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    #[test]
    fn control_characters_are_escaped_and_the_rest_kept() {
        assert_eq!(super::printable("a\rb\u{1b}[2J'é'"), "a\\rb\\u{1b}[2J'é'");
    }
}
