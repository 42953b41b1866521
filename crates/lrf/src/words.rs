//! Reading a word of a closed set (a noise profile, a cloud unit, a servo motion) with
//! serde: a word outside the set is refused with the words allowed ("expected one of mm,
//! m"); the project's reader puts the file, the line and the value in front.

use serde::de::{Deserializer, Error, Visitor};
use std::fmt;

/// "one of a, b, c", or the only word.
pub(crate) fn allowed(names: &[&str]) -> String {
    match names {
        [one] => one.to_string(),
        names => format!("one of {}", names.join(", ")),
    }
}

/// The value of the word `d` holds: `from_word` finds it, or the error lists `names`.
pub(crate) fn deserialize<'de, D: Deserializer<'de>, T>(
    d: D,
    names: &'static [&'static str],
    from_word: fn(&str) -> Option<T>,
) -> Result<T, D::Error> {
    d.deserialize_str(Word { names, from_word })
}

/// The visitor of [`deserialize`].
struct Word<T> {
    names: &'static [&'static str],
    from_word: fn(&str) -> Option<T>,
}

impl<T> Visitor<'_> for Word<T> {
    type Value = T;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&allowed(self.names))
    }

    fn visit_str<E: Error>(self, v: &str) -> Result<T, E> {
        (self.from_word)(v)
            .ok_or_else(|| E::custom(format_args!("expected {}", allowed(self.names))))
    }
}
