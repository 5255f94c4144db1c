//! Where each value of a JSON text starts, by its path (`mission.items[3].params[4]`), so that a
//! reader of well-formed JSON whose content is wrong can say `LINE:COL` as the XML readers do:
//! serde_json reports positions for syntax errors only, and its `Value` carries none.
//!
//! The text must already have been read by serde_json (its syntax and nesting depth are
//! checked there); on anything else the scan stops early and the missing paths fall back to
//! their nearest recorded parent. The scan is made at the first question only: a file read
//! without a problem or a warning never pays for it (`armor-bench qgc_import_10k_ms`).

use std::cell::OnceCell;
use std::collections::HashMap;

use armor_module_api::xml::Pos;

type Starts = HashMap<String, Pos, foldhash::fast::RandomState>;

/// The start of every value of a JSON text, by path, found when first asked.
#[derive(Debug)]
pub(crate) struct JsonPositions<'a> {
    text: &'a str,
    starts: OnceCell<Starts>,
}

impl<'a> JsonPositions<'a> {
    pub(crate) fn of(text: &'a str) -> Self {
        Self {
            text,
            starts: OnceCell::new(),
        }
    }

    fn scan(text: &str) -> Starts {
        let mut scanner = Scanner {
            bytes: text.as_bytes(),
            index: 0,
            pos: Pos { line: 1, col: 1 },
            starts: Starts::default(),
        };
        scanner.skip_whitespace();
        scanner.value(String::new());
        scanner.starts
    }

    /// Where the value at `path` starts, else where its nearest parent does, else 1:1.
    pub(crate) fn at(&self, path: &str) -> Pos {
        let starts = self.starts.get_or_init(|| Self::scan(self.text));
        let mut path = path;
        loop {
            if let Some(pos) = starts.get(path) {
                return *pos;
            }
            match path.rfind(['.', '[']) {
                Some(cut) => path = &path[..cut],
                None => {
                    return starts.get("").copied().unwrap_or(Pos { line: 1, col: 1 });
                }
            }
        }
    }
}

/// `parent.key`, or `key` at the top.
pub(crate) fn key_path(parent: &str, key: &str) -> String {
    if parent.is_empty() {
        key.to_owned()
    } else {
        format!("{parent}.{key}")
    }
}

/// `parent[index]`.
pub(crate) fn index_path(parent: &str, index: usize) -> String {
    format!("{parent}[{index}]")
}

struct Scanner<'a> {
    bytes: &'a [u8],
    index: usize,
    pos: Pos,
    starts: Starts,
}

impl Scanner<'_> {
    fn peek(&self) -> Option<u8> {
        self.bytes.get(self.index).copied()
    }

    fn bump(&mut self) {
        let Some(byte) = self.peek() else { return };
        self.index += 1;
        if byte == b'\n' {
            self.pos.line += 1;
            self.pos.col = 1;
        } else if byte & 0xC0 != 0x80 {
            // A column per character: UTF-8 continuation bytes do not count.
            self.pos.col += 1;
        }
    }

    fn skip_whitespace(&mut self) {
        while matches!(self.peek(), Some(b' ' | b'\t' | b'\n' | b'\r')) {
            self.bump();
        }
    }

    /// Reads the value that starts here, recording it and everything inside it.
    fn value(&mut self, path: String) {
        let Some(first) = self.peek() else { return };
        self.starts.insert(path.clone(), self.pos);
        match first {
            b'{' => self.object(&path),
            b'[' => self.array(&path),
            b'"' => {
                self.string();
            }
            _ => {
                while self.peek().is_some_and(|b| {
                    !matches!(b, b',' | b']' | b'}' | b' ' | b'\t' | b'\n' | b'\r')
                }) {
                    self.bump();
                }
            }
        }
    }

    fn object(&mut self, path: &str) {
        self.bump();
        self.skip_whitespace();
        if self.peek() == Some(b'}') {
            self.bump();
            return;
        }
        while self.peek() == Some(b'"') {
            let key = self.string();
            self.skip_whitespace();
            if self.peek() != Some(b':') {
                return;
            }
            self.bump();
            self.skip_whitespace();
            self.value(key_path(path, &key));
            self.skip_whitespace();
            match self.peek() {
                Some(b',') => {
                    self.bump();
                    self.skip_whitespace();
                }
                Some(b'}') => {
                    self.bump();
                    return;
                }
                _ => return,
            }
        }
    }

    fn array(&mut self, path: &str) {
        self.bump();
        self.skip_whitespace();
        if self.peek() == Some(b']') {
            self.bump();
            return;
        }
        let mut index = 0;
        while self.peek().is_some() {
            self.value(index_path(path, index));
            index += 1;
            self.skip_whitespace();
            match self.peek() {
                Some(b',') => {
                    self.bump();
                    self.skip_whitespace();
                }
                Some(b']') => {
                    self.bump();
                    return;
                }
                _ => return,
            }
        }
    }

    /// Reads a string and returns its text as written (escapes kept: keys that need them are
    /// not keys any reader here looks for).
    fn string(&mut self) -> String {
        self.bump();
        let start = self.index;
        while let Some(byte) = self.peek() {
            if byte == b'"' {
                let text = String::from_utf8_lossy(&self.bytes[start..self.index]).into_owned();
                self.bump();
                return text;
            }
            if byte == b'\\' {
                self.bump();
            }
            self.bump();
        }
        String::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_value_is_found_by_its_path() {
        let text = "{\n  \"a\": [1, {\"b\": \"é\\\"x\", \"c\": null}],\n  \"d\": {}\n}";
        let positions = JsonPositions::of(text);
        let at = |path: &str| positions.at(path).to_string();
        assert_eq!(at(""), "1:1");
        assert_eq!(at("a"), "2:8");
        assert_eq!(at("a[0]"), "2:9");
        assert_eq!(at("a[1]"), "2:12");
        assert_eq!(at("a[1].b"), "2:18");
        // After a two-byte character and an escaped quote.
        assert_eq!(at("a[1].c"), "2:31");
        assert_eq!(at("d"), "3:8");
        // A path that is not there: its nearest parent.
        assert_eq!(at("a[1].missing"), "2:12");
        assert_eq!(at("a[7]"), "2:8");
        assert_eq!(at("nothing.at.all"), "1:1");
    }

    #[test]
    fn broken_text_stops_the_scan_without_a_panic() {
        for text in [
            "",
            "{",
            "{\"a\"",
            "{\"a\":",
            "[1,",
            "\"abc",
            "{\"a\" 1}",
            "[1 2]",
        ] {
            let positions = JsonPositions::of(text);
            let _ = positions.at("a[0].b");
        }
    }
}
