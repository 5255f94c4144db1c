//! What the fuzz targets share: comparing parsed values while ignoring where they were read from.

use std::fmt::Debug;

/// The `Debug` text of `value` with every `Pos { line: L, col: C }` replaced by `Pos`: two values
/// read from different texts compare equal this way when only their positions differ. (`Debug`
/// rather than `PartialEq`, so that it also sees every field added later, and tells `-0.0` from
/// `0.0`.)
pub fn without_positions(value: &impl Debug) -> String {
    const MARK: &str = "Pos { line: ";
    let text = format!("{value:?}");
    let mut out = String::with_capacity(text.len());
    let mut rest = text.as_str();
    while let Some(at) = rest.find(MARK) {
        out.push_str(&rest[..at]);
        out.push_str("Pos");
        let after = &rest[at + MARK.len()..];
        rest = after.find('}').map_or("", |end| &after[end + 1..]);
    }
    out.push_str(rest);
    out
}

/// Asserts that `again` (read back from what was written from `first`) is `first`, positions aside.
pub fn assert_same<T: Debug>(first: &T, again: &T, written: &str) {
    let (a, b) = (without_positions(first), without_positions(again));
    assert!(
        a == b,
        "round trip changed the value\nfirst: {a}\nagain: {b}\nwritten:\n{written}"
    );
}
