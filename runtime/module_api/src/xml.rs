//! A small element tree with source positions, read with quick-xml's event reader.
//!
//! Every ArMoR file format (describe output, system configuration, and later missions and plans)
//! must report problems as `FILE:LINE:COL: message`. quick-xml's serde layer drops positions, so
//! loaders read the whole document into this tree first and then walk it, attaching the position
//! of the element or attribute they complain about.
//!
//! The tree borrows its names and values from the text (only values with entities are copied),
//! and positions are counted forwards as the reader goes: loading stays a small multiple of
//! quick-xml's own time.

use std::borrow::Cow;
use std::fmt;

use quick_xml::events::{BytesStart, Event};

/// A 1-based line and column in a text.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord)]
pub struct Pos {
    pub line: u32,
    pub col: u32,
}

impl fmt::Display for Pos {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}", self.line, self.col)
    }
}

/// A problem found at a place in a text.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{pos}: {message}")]
pub struct Located {
    pub pos: Pos,
    pub message: String,
}

impl Located {
    pub fn new(pos: Pos, message: impl Into<String>) -> Self {
        Self {
            pos,
            message: message.into(),
        }
    }
}

/// A name or a value read from a document: borrowed from the text when it is written there as
/// is, owned when it had to be unescaped. It reads like a `&str` (`as_str`, `Deref`, `==` with
/// strings, `Display`); `into_owned` or `as_str().to_owned()` give a `String`.
#[derive(Clone, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct XmlStr<'a>(Cow<'a, str>);

impl<'a> XmlStr<'a> {
    pub fn as_str(&self) -> &str {
        &self.0
    }

    pub fn into_owned(self) -> String {
        self.0.into_owned()
    }
}

impl std::ops::Deref for XmlStr<'_> {
    type Target = str;
    fn deref(&self) -> &str {
        &self.0
    }
}

impl AsRef<str> for XmlStr<'_> {
    fn as_ref(&self) -> &str {
        &self.0
    }
}

impl std::borrow::Borrow<str> for XmlStr<'_> {
    fn borrow(&self) -> &str {
        &self.0
    }
}

impl fmt::Display for XmlStr<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(&*self.0, f)
    }
}

impl fmt::Debug for XmlStr<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Debug::fmt(&*self.0, f)
    }
}

impl<'a> From<&'a str> for XmlStr<'a> {
    fn from(text: &'a str) -> Self {
        XmlStr(Cow::Borrowed(text))
    }
}

impl From<String> for XmlStr<'_> {
    fn from(text: String) -> Self {
        XmlStr(Cow::Owned(text))
    }
}

impl<'a> From<Cow<'a, str>> for XmlStr<'a> {
    fn from(text: Cow<'a, str>) -> Self {
        XmlStr(text)
    }
}

impl From<XmlStr<'_>> for String {
    fn from(text: XmlStr<'_>) -> Self {
        text.into_owned()
    }
}

macro_rules! xml_str_eq {
    ($($other:ty),*) => {$(
        impl PartialEq<$other> for XmlStr<'_> {
            fn eq(&self, other: &$other) -> bool {
                self.as_str() == AsRef::<str>::as_ref(other)
            }
        }
        impl PartialEq<XmlStr<'_>> for $other {
            fn eq(&self, other: &XmlStr<'_>) -> bool {
                AsRef::<str>::as_ref(self) == other.as_str()
            }
        }
    )*};
}
xml_str_eq!(str, &str, String);

/// An attribute: its name (with its prefix, if any), its unescaped value and the position of its
/// name.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Attr<'a> {
    pub name: XmlStr<'a>,
    pub value: XmlStr<'a>,
    pub pos: Pos,
}

/// An element of a document read by [`parse`]; names and values borrow from the document's text.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Element<'a> {
    /// The local name (without the prefix).
    pub name: XmlStr<'a>,
    pub attrs: Vec<Attr<'a>>,
    pub children: Vec<Element<'a>>,
    /// The element's own text (character data and CDATA directly inside it), untrimmed.
    pub text: String,
    pub pos: Pos,
}

impl<'a> Element<'a> {
    pub fn attr(&self, name: &str) -> Option<&Attr<'a>> {
        self.attrs.iter().find(|attr| attr.name == name)
    }

    pub fn attr_value(&self, name: &str) -> Option<&str> {
        self.attr(name).map(|attr| attr.value.as_str())
    }

    /// The attribute's value, or a problem naming the element if it is absent or empty.
    pub fn required_attr(&self, name: &str) -> Result<&Attr<'a>, Located> {
        match self.attr(name) {
            Some(attr) if !attr.value.trim().is_empty() => Ok(attr),
            Some(attr) => Err(Located::new(
                attr.pos,
                format!("attribute `{name}` of <{}> must not be empty", self.name),
            )),
            None => Err(Located::new(
                self.pos,
                format!("<{}> needs the attribute `{name}`", self.name),
            )),
        }
    }

    /// Problems for every attribute not in `allowed`.
    pub fn unknown_attrs(&self, allowed: &[&str]) -> Vec<Located> {
        self.attrs
            .iter()
            .filter(|attr| {
                !allowed.contains(&attr.name.as_str()) && !attr.name.starts_with("xmlns")
            })
            .map(|attr| {
                Located::new(
                    attr.pos,
                    format!(
                        "unknown attribute `{}` on <{}> (expected one of: {})",
                        attr.name,
                        self.name,
                        allowed.join(", ")
                    ),
                )
            })
            .collect()
    }

    /// Problems for every child element whose name is not in `allowed`.
    pub fn unknown_children(&self, allowed: &[&str]) -> Vec<Located> {
        self.children
            .iter()
            .filter(|child| !allowed.contains(&child.name.as_str()))
            .map(|child| {
                Located::new(
                    child.pos,
                    format!(
                        "unknown element <{}> inside <{}> (expected one of: {})",
                        child.name,
                        self.name,
                        allowed.join(", ")
                    ),
                )
            })
            .collect()
    }

    pub fn children_named<'b>(
        &'b self,
        name: &'b str,
    ) -> impl Iterator<Item = &'b Element<'a>> + 'b {
        self.children.iter().filter(move |child| child.name == name)
    }
}

/// A place in the text reached by walking forwards: a byte offset (on a character boundary), its
/// line (from 0) and its column in characters (from 0). Positions of elements and attributes come
/// in increasing order, so each is found by counting only the bytes since the previous one.
#[derive(Clone, Copy, Debug, Default)]
struct Cursor {
    offset: usize,
    line: usize,
    col: usize,
}

impl Cursor {
    /// The cursor moved forwards to `offset`, or `None` when `offset` is behind it or not on a
    /// character boundary.
    fn advanced(self, text: &str, offset: usize) -> Option<Cursor> {
        if offset < self.offset || !text.is_char_boundary(offset) {
            return None;
        }
        let (mut line, mut col) = (self.line, self.col);
        // Characters are counted by their first bytes (those that do not continue a character).
        for &b in &text.as_bytes()[self.offset..offset] {
            if b == b'\n' {
                line += 1;
                col = 0;
            } else {
                col += usize::from((b as i8) >= -0x40);
            }
        }
        Some(Cursor { offset, line, col })
    }

    fn pos(self) -> Pos {
        Pos {
            line: self.line as u32 + 1,
            col: self.col as u32 + 1,
        }
    }
}

/// How many of `bytes` are `wanted`, counted in blocks that the compiler vectorizes well.
fn count_bytes(bytes: &[u8], wanted: impl Fn(u8) -> bool + Copy) -> usize {
    bytes
        .chunks(255)
        .map(|block| usize::from(block.iter().fold(0u8, |n, &b| n + u8::from(wanted(b)))))
        .sum()
}

fn count_newlines(bytes: &[u8]) -> usize {
    count_bytes(bytes, |b| b == b'\n')
}

/// The position of any offset, counted from the start of the text (for the rare offsets behind
/// the cursor, like those of errors). Columns count characters, or bytes when the offset is not
/// on a character boundary.
fn pos_from_start(text: &str, offset: usize) -> Pos {
    let offset = offset.min(text.len());
    let before = &text.as_bytes()[..offset];
    let start = before
        .iter()
        .rposition(|&b| b == b'\n')
        .map_or(0, |last| last + 1);
    let col = text
        .get(start..offset)
        .map_or(offset - start, |s| s.chars().count());
    Pos {
        line: count_newlines(before) as u32 + 1,
        col: col as u32 + 1,
    }
}

/// Documents larger than this are refused before parsing: no configuration is anywhere near it.
pub const MAX_DOCUMENT_BYTES: usize = 64 * 1024 * 1024;

/// Reads a document whose top element must be `<root>`: another is the one problem reported,
/// at that element. Every format of ours (system, mission, plan, PNML, GPX, KML) starts so.
pub fn parse_document<'a>(text: &'a str, root: &str) -> Result<Element<'a>, Vec<Located>> {
    let element = parse(text).map_err(|err| vec![err])?;
    if &*element.name != root {
        return Err(vec![Located::new(
            element.pos,
            format!("expected <{root}> at the top, found <{}>", element.name),
        )]);
    }
    Ok(element)
}

/// Reads a whole document into an element tree. The error carries the position of the problem.
pub fn parse(text: &str) -> Result<Element<'_>, Located> {
    if text.len() > MAX_DOCUMENT_BYTES {
        return Err(Located::new(
            Pos { line: 1, col: 1 },
            format!(
                "document is {} bytes, more than the {} bytes allowed",
                text.len(),
                MAX_DOCUMENT_BYTES
            ),
        ));
    }
    let mut builder = Builder {
        text,
        cursor: Cursor::default(),
        tag_cursor: Cursor::default(),
        open: Vec::new(),
        // Room for every element (each starts with a `<`, up to a limit), so that the list is
        // not copied as it grows; the part never used is never touched.
        children: Vec::with_capacity(count_bytes(text.as_bytes(), |b| b == b'<').min(1 << 16)),
        attrs: Vec::new(),
        root: None,
    };
    let mut reader = quick_xml::Reader::from_str(text);
    reader.config_mut().check_end_names = true;
    loop {
        let start = reader.buffer_position() as usize;
        let event = match reader.read_event() {
            Ok(event) => event,
            Err(err) => {
                return Err(Located::new(
                    builder.pos_at(reader.error_position() as usize),
                    format!("malformed XML: {err}"),
                ));
            }
        };
        match event {
            Event::Start(tag) => {
                let element = builder.open_element(&tag, start)?;
                if builder.root.is_some() && builder.open.is_empty() {
                    return Err(Located::new(element.pos, "more than one top-level element"));
                }
                builder.open.push((element, builder.children.len()));
            }
            Event::Empty(tag) => {
                let element = builder.open_element(&tag, start)?;
                builder.close_element(element)?;
            }
            Event::End(_) => {
                // quick-xml has already checked that the end name matches.
                if let Some((mut element, first_child)) = builder.open.pop() {
                    if builder.open.is_empty() {
                        // The children of the top element: the whole list, without a copy.
                        element.children = std::mem::take(&mut builder.children);
                    } else if first_child < builder.children.len() {
                        element.children = builder.children.split_off(first_child);
                    }
                    builder.close_element(element)?;
                }
            }
            Event::Text(content) => {
                let decoded = content.xml_content().map_err(|err| {
                    Located::new(builder.pos_at(start), format!("bad text: {err}"))
                })?;
                match builder.open.last_mut() {
                    Some((parent, _)) => parent.text.push_str(&decoded),
                    None if decoded.trim().is_empty() => {}
                    None => {
                        return Err(Located::new(
                            builder.pos_at(start),
                            "text outside the top-level element",
                        ));
                    }
                }
            }
            Event::GeneralRef(reference) => {
                let resolved = resolve_reference(&reference)
                    .map_err(|message| Located::new(builder.pos_at(start), message))?;
                if let Some((parent, _)) = builder.open.last_mut() {
                    parent.text.push_str(&resolved);
                }
            }
            Event::CData(data) => {
                if let Some((parent, _)) = builder.open.last_mut() {
                    parent.text.push_str(&String::from_utf8_lossy(&data));
                }
            }
            Event::Eof => break,
            Event::Decl(_) | Event::PI(_) | Event::Comment(_) | Event::DocType(_) => {}
        }
    }
    if let Some((open, _)) = builder.open.last() {
        let (name, line) = (open.name.clone(), open.pos.line);
        return Err(Located::new(
            builder.pos_at(text.len()),
            format!("document ends before <{name}> (line {line}) is closed"),
        ));
    }
    match builder.root.take() {
        Some(root) => Ok(root),
        None => Err(Located::new(
            builder.pos_at(text.len()),
            "document has no element",
        )),
    }
}

/// The tree being built.
struct Builder<'t> {
    text: &'t str,
    /// The last position given.
    cursor: Cursor,
    /// The start of the tag being read.
    tag_cursor: Cursor,
    /// The open elements, each with the index in `children` where its children begin.
    open: Vec<(Element<'t>, usize)>,
    /// The children read so far of every open element, one after the other.
    children: Vec<Element<'t>>,
    /// The attributes of the tag being read.
    attrs: Vec<Attr<'t>>,
    root: Option<Element<'t>>,
}

impl<'t> Builder<'t> {
    /// The line and column of a byte offset.
    fn pos_at(&mut self, offset: usize) -> Pos {
        let offset = offset.min(self.text.len());
        if let Some(cursor) = self.cursor.advanced(self.text, offset) {
            self.cursor = cursor;
            cursor.pos()
        } else if let Some(cursor) = self.tag_cursor.advanced(self.text, offset) {
            cursor.pos()
        } else {
            pos_from_start(self.text, offset)
        }
    }

    /// Where `bytes` lie in the text, when they are a part of it (quick-xml borrows from it).
    fn offset_of(&self, bytes: &[u8]) -> Option<usize> {
        let offset = (bytes.as_ptr() as usize).checked_sub(self.text.as_ptr() as usize)?;
        (offset + bytes.len() <= self.text.len()).then_some(offset)
    }

    /// The part of the text that `bytes` are, if they are one.
    fn slice_of(&self, bytes: &[u8]) -> Option<&'t str> {
        let text = self.text;
        self.offset_of(bytes)
            .and_then(|offset| text.get(offset..offset + bytes.len()))
    }

    /// `bytes` as text: the part of the text they are, else decoded.
    fn text_of(&self, bytes: &[u8]) -> XmlStr<'t> {
        match self.slice_of(bytes) {
            Some(text) => XmlStr::from(text),
            None => XmlStr::from(String::from_utf8_lossy(bytes).into_owned()),
        }
    }

    fn close_element(&mut self, element: Element<'t>) -> Result<(), Located> {
        if !self.open.is_empty() {
            self.children.push(element);
        } else if self.root.is_some() {
            return Err(Located::new(element.pos, "more than one top-level element"));
        } else {
            self.root = Some(element);
        }
        Ok(())
    }

    fn open_element(&mut self, tag: &BytesStart<'_>, start: usize) -> Result<Element<'t>, Located> {
        let pos = self.pos_at(start);
        self.tag_cursor = self.cursor;
        let name = self.text_of(tag.local_name().as_ref());
        self.attrs.clear();
        // Duplicates are looked for here, without the list quick-xml would allocate per tag.
        let mut attributes = tag.attributes();
        attributes.with_checks(false);
        for attr in attributes {
            let attr = match attr {
                Ok(attr) => attr,
                Err(err) => {
                    return Err(attr_error(tag, pos, &name).unwrap_or_else(|| {
                        Located::new(pos, format!("bad attribute in <{name}>: {err}"))
                    }));
                }
            };
            let key = attr.key.as_ref();
            if self.attrs.iter().any(|seen| seen.name.as_bytes() == key) {
                return Err(attr_error(tag, pos, &name).unwrap_or_else(|| {
                    Located::new(
                        pos,
                        format!("bad attribute in <{name}>: duplicated attribute"),
                    )
                }));
            }
            let attr_name = self.text_of(key);
            let raw_value = self.slice_of(&attr.value);
            let value = match raw_value {
                Some(raw) if !raw.contains('&') => XmlStr::from(raw),
                _ => attr
                    .unescape_value()
                    .map_err(|err| {
                        Located::new(
                            pos,
                            format!("bad value of `{attr_name}` in <{name}>: {err}"),
                        )
                    })?
                    .into_owned()
                    .into(),
            };
            // quick-xml borrows names from the text, so where the name lies is where the
            // attribute is, whatever the values before it hold.
            let attr_pos = self
                .offset_of(key)
                .map_or(pos, |offset| self.pos_at(offset));
            self.attrs.push(Attr {
                name: attr_name,
                value,
                pos: attr_pos,
            });
        }
        Ok(Element {
            name,
            attrs: self.attrs.drain(..).collect(),
            children: Vec::new(),
            text: String::new(),
            pos,
        })
    }
}

/// The text an entity or character reference in element content stands for.
fn resolve_reference(reference: &quick_xml::events::BytesRef<'_>) -> Result<String, String> {
    if let Ok(Some(ch)) = reference.resolve_char_ref() {
        return Ok(ch.to_string());
    }
    let name = String::from_utf8_lossy(reference);
    quick_xml::escape::resolve_predefined_entity(&name)
        .map(str::to_owned)
        .ok_or_else(|| format!("unknown entity `&{name};`"))
}

/// The first problem quick-xml finds in the attributes of `tag` (checking for duplicates).
fn attr_error(tag: &BytesStart<'_>, pos: Pos, name: &str) -> Option<Located> {
    tag.attributes().find_map(|attr| {
        attr.err()
            .map(|err| Located::new(pos, format!("bad attribute in <{name}>: {err}")))
    })
}

/// Escapes text for an attribute value or element content.
pub fn escape(text: &str) -> std::borrow::Cow<'_, str> {
    quick_xml::escape::escape(text)
}

#[cfg(test)]
mod tests {
    use super::*;

    mod reference {
        //! The element tree as it was read before positions were counted forwards.

        use quick_xml::events::{BytesStart, Event};

        use super::super::{Attr, Element, Located, MAX_DOCUMENT_BYTES, Pos, resolve_reference};

        /// Turns byte offsets into line and column (columns count characters, not bytes).
        struct LineIndex<'a> {
            text: &'a str,
            line_starts: Vec<usize>,
        }

        impl<'a> LineIndex<'a> {
            fn new(text: &'a str) -> Self {
                let mut line_starts = vec![0];
                line_starts.extend(text.match_indices('\n').map(|(i, _)| i + 1));
                Self { text, line_starts }
            }

            fn pos(&self, offset: usize) -> Pos {
                let offset = offset.min(self.text.len());
                let line = self.line_starts.partition_point(|&start| start <= offset) - 1;
                let start = self.line_starts[line];
                let col = self
                    .text
                    .get(start..offset)
                    .map_or(offset - start, |s| s.chars().count());
                Pos {
                    line: line as u32 + 1,
                    col: col as u32 + 1,
                }
            }
        }

        /// The position of an offset as it was found before positions were counted forwards.
        pub(super) fn slow_pos(text: &str, offset: usize) -> Pos {
            LineIndex::new(text).pos(offset)
        }

        /// The parser as it was before positions were counted forwards: the reference for the tests.
        pub(super) fn slow_parse(text: &str) -> Result<Element<'static>, Located> {
            if text.len() > MAX_DOCUMENT_BYTES {
                return Err(Located::new(
                    Pos { line: 1, col: 1 },
                    format!(
                        "document is {} bytes, more than the {} bytes allowed",
                        text.len(),
                        MAX_DOCUMENT_BYTES
                    ),
                ));
            }
            let index = LineIndex::new(text);
            let mut reader = quick_xml::Reader::from_str(text);
            reader.config_mut().check_end_names = true;
            let mut stack: Vec<Element<'static>> = Vec::new();
            let mut root: Option<Element<'static>> = None;
            loop {
                let start = reader.buffer_position() as usize;
                let event = reader.read_event().map_err(|err| {
                    Located::new(
                        index.pos(reader.error_position() as usize),
                        format!("malformed XML: {err}"),
                    )
                })?;
                match event {
                    Event::Start(tag) => {
                        let element = open_element(&tag, start, text, &index)?;
                        if root.is_some() && stack.is_empty() {
                            return Err(Located::new(
                                element.pos,
                                "more than one top-level element",
                            ));
                        }
                        stack.push(element);
                    }
                    Event::Empty(tag) => {
                        let element = open_element(&tag, start, text, &index)?;
                        close_element(element, &mut stack, &mut root)?;
                    }
                    Event::End(_) => {
                        // quick-xml has already checked that the end name matches.
                        if let Some(element) = stack.pop() {
                            close_element(element, &mut stack, &mut root)?;
                        }
                    }
                    Event::Text(content) => {
                        let decoded = content.xml_content().map_err(|err| {
                            Located::new(index.pos(start), format!("bad text: {err}"))
                        })?;
                        match stack.last_mut() {
                            Some(parent) => parent.text.push_str(&decoded),
                            None if decoded.trim().is_empty() => {}
                            None => {
                                return Err(Located::new(
                                    index.pos(start),
                                    "text outside the top-level element",
                                ));
                            }
                        }
                    }
                    Event::GeneralRef(reference) => {
                        let resolved = resolve_reference(&reference)
                            .map_err(|message| Located::new(index.pos(start), message))?;
                        if let Some(parent) = stack.last_mut() {
                            parent.text.push_str(&resolved);
                        }
                    }
                    Event::CData(data) => {
                        if let Some(parent) = stack.last_mut() {
                            parent.text.push_str(&String::from_utf8_lossy(&data));
                        }
                    }
                    Event::Eof => break,
                    Event::Decl(_) | Event::PI(_) | Event::Comment(_) | Event::DocType(_) => {}
                }
            }
            if let Some(open) = stack.last() {
                return Err(Located::new(
                    index.pos(text.len()),
                    format!(
                        "document ends before <{}> (line {}) is closed",
                        open.name, open.pos.line
                    ),
                ));
            }
            root.ok_or_else(|| Located::new(index.pos(text.len()), "document has no element"))
        }

        fn close_element(
            element: Element<'static>,
            stack: &mut [Element<'static>],
            root: &mut Option<Element<'static>>,
        ) -> Result<(), Located> {
            match stack.last_mut() {
                Some(parent) => parent.children.push(element),
                None if root.is_some() => {
                    return Err(Located::new(element.pos, "more than one top-level element"));
                }
                None => *root = Some(element),
            }
            Ok(())
        }

        fn open_element(
            tag: &BytesStart<'_>,
            start: usize,
            text: &str,
            index: &LineIndex<'_>,
        ) -> Result<Element<'static>, Located> {
            let pos = index.pos(start);
            let name = String::from_utf8_lossy(tag.local_name().as_ref()).into_owned();
            let raw_tag = text.get(start..).unwrap_or_default();
            let offsets = attr_offsets(raw_tag);
            let mut attrs = Vec::new();
            for (k, attr) in tag.attributes().enumerate() {
                let attr = attr.map_err(|err| {
                    Located::new(pos, format!("bad attribute in <{name}>: {err}"))
                })?;
                let attr_name = String::from_utf8_lossy(attr.key.as_ref()).into_owned();
                let value = attr
                    .unescape_value()
                    .map_err(|err| {
                        Located::new(
                            pos,
                            format!("bad value of `{attr_name}` in <{name}>: {err}"),
                        )
                    })?
                    .into_owned();
                let attr_pos = match offsets.get(k) {
                    Some(&(found, at)) if found == attr_name => index.pos(start + at),
                    _ => pos,
                };
                attrs.push(Attr {
                    name: attr_name.into(),
                    value: value.into(),
                    pos: attr_pos,
                });
            }
            Ok(Element {
                name: name.into(),
                attrs,
                children: Vec::new(),
                text: String::new(),
                pos,
            })
        }

        /// Where each attribute's name starts in the text of a tag (`<b x="1" y='2'/>`), read
        /// byte by byte as quick-xml reads it: the tag ends at the first `>` outside quotes
        /// (less a `/` before it), the element's name at a space, an attribute's name is its first
        /// byte and what follows up to a space or `=`, and a value ends at its closing quote.
        fn attr_offsets(raw_tag: &str) -> Vec<(&str, usize)> {
            let mut quote = None;
            let end = raw_tag
                .bytes()
                .position(|b| match quote {
                    Some(q) if b == q => {
                        quote = None;
                        false
                    }
                    Some(_) => false,
                    None if b == b'"' || b == b'\'' => {
                        quote = Some(b);
                        false
                    }
                    None => b == b'>',
                })
                .unwrap_or(raw_tag.len());
            let tag = raw_tag[..end].strip_suffix('/').unwrap_or(&raw_tag[..end]);
            let bytes = tag.as_bytes();
            let space = |i: usize| bytes.get(i).is_some_and(|b| b" \t\r\n".contains(b));
            let in_name = |i: usize| bytes.get(i).is_some_and(|b| !b" \t\r\n=".contains(b));
            let skip_spaces = |mut i: usize| {
                while space(i) {
                    i += 1;
                }
                i
            };
            let mut found = Vec::new();
            let mut i = 1;
            while i < bytes.len() && !space(i) {
                i += 1;
            }
            loop {
                i = skip_spaces(i);
                if i >= bytes.len() {
                    return found;
                }
                let name_start = i;
                i += 1;
                while in_name(i) {
                    i += 1;
                }
                found.push((&tag[name_start..i], name_start));
                i = skip_spaces(i);
                if bytes.get(i) != Some(&b'=') {
                    return found;
                }
                i = skip_spaces(i + 1);
                let Some(&quote) = bytes.get(i).filter(|b| matches!(b, b'"' | b'\'')) else {
                    return found;
                };
                match bytes[i + 1..].iter().position(|&b| b == quote) {
                    Some(len) => i += len + 2,
                    None => return found,
                }
            }
        }
    }

    /// The tree and the error of `text` are those the reference parser gives.
    fn same_as_reference(text: &str) {
        assert_eq!(parse(text), reference::slow_parse(text), "for:\n{text}");
    }

    #[test]
    fn positions_are_those_of_the_slow_method() {
        let documents = [
            // Non-ASCII before elements and attributes, on the same line and on earlier ones.
            "<a é=\"ü\" b='→'>\n  <b x=\"🤖\" y=\"1\"/>été <c z=\"2\"/>\n\t<d\n\tw=\"3\"\n  v = 'x'\n  u\n=\n\"y\"/>\n</a>",
            // Attributes on several lines, CRLF line ends, tabs, comments, CDATA, entities.
            "<?xml version=\"1.0\"?>\r\n<!-- é\nà -->\r\n<root\r\n  name=\"r\"\r\n\tkind='k'>\r\n  <![CDATA[ x\ny ]]>\n  <e a=\"&lt;&#233;&gt;\"\n     b=\"2\"/>&amp;<f/>\n</root>\n",
            // Values holding spaces, `>` or the name of a later attribute, and no space between
            // attributes: each attribute is where its name is.
            "<a>\n<b x=\" y=1\" y=\"2\"/>\n<b x=\"a>b\" y=\"3\"/>\n<b x=\"é y=\" y=\"4\" z=\"5\"/>\n<b x=\"1\"y=\"2\"/>\n<b x=\"1\"\ty=\"2\"/>\n<b x=\"q\u{a0}y=\" y=\"2\"/>\n</a>",
            // Namespaced names.
            "<n:a xmlns:n=\"urn:x\" n:b=\"1\">\n  <n:c n:d='2' xml:lang=\"fr\"/>\n</n:a>",
            // A long line, then elements after it.
            &format!("<a>{}<b c=\"1\"/>\n<d e=\"2\"/></a>", "ü".repeat(300)),
            // Errors, with and after non-ASCII text.
            "<a>\n  é<b x=\"1\" x=\"2\"/>\n</a>",
            "<a>\n  é<b x=\"&bogus;\" x=\"2\"/>\n</a>",
            "<a>\n  é<b x=\"1\" x=/>\n</a>",
            "<a>\n  é<b x=\"1\" y/>\n</a>",
            "<a>\n  é<b x='1' y=\"2/>\n</a>",
            "<a>\n  é<b>&unknown;</b>\n</a>",
            "<a>\n  ü<b></c>\n</a>",
            "<a>ü\n  ü<b>ü",
            "<a/>ü<b/>",
            "é <a/>",
            "<a/>\n<!-- é -->\n",
            "",
        ];
        for document in documents {
            same_as_reference(document);
        }
        // Generated documents: every element and attribute at a known place.
        let mut generated = String::from("<root>\n");
        for i in 0..200 {
            let pad = "é".repeat(i % 7);
            generated.push_str(&format!(
                "{pad}<item n=\"{i}\"{}label=\"é{pad}\"\n  v='{}'>{pad}<x a=\"1\"/></item>\n",
                if i % 3 == 0 { "\n  " } else { " " },
                i * 7
            ));
        }
        generated.push_str("</root>\n");
        same_as_reference(&generated);
        let tree = parse(&generated).expect("valid");
        assert_eq!(tree.children[2].attrs[1].pos, Pos { line: 7, col: 15 });
    }

    #[test]
    fn damaged_documents_read_like_with_the_slow_method() {
        let base = "<?xml version=\"1.0\"?>\n<a é=\"1\">\n  <b x=\"1 y\" y='&amp;'\n     z=\"2\"/>t&lt;é\n  <c><![CDATA[c]]></c><!-- d -->\n</a>\n";
        let chars: Vec<(usize, char)> = base.char_indices().collect();
        for &(at, ch) in &chars {
            let removed = format!("{}{}", &base[..at], &base[at + ch.len_utf8()..]);
            same_as_reference(&removed);
            for inserted in [' ', '"', '\'', '>', '<', '=', '\n', 'é', '&', 'y', '/'] {
                same_as_reference(&format!("{}{inserted}{}", &base[..at], &base[at..]));
            }
        }
    }

    #[test]
    fn cursor_counts_like_the_slow_method() {
        let text = "ab\nçé→🤖x\n\n  z";
        let mut cursor = Cursor::default();
        for offset in 0..=text.len() + 1 {
            let expected = reference::slow_pos(text, offset);
            assert_eq!(pos_from_start(text, offset), expected, "offset {offset}");
            let offset = offset.min(text.len());
            if text.is_char_boundary(offset) {
                let from_start = Cursor::default().advanced(text, offset).expect("forwards");
                assert_eq!(from_start.pos(), expected, "offset {offset}");
                cursor = cursor.advanced(text, offset).expect("forwards");
                assert_eq!(cursor.pos(), expected, "offset {offset}");
            } else {
                assert!(cursor.advanced(text, offset).is_none());
            }
        }
        assert!(cursor.advanced(text, 1).is_none(), "never backwards");
    }

    fn check_error(text: &str, expected: &str) {
        let err = parse(text).expect_err("document should be refused");
        assert_eq!(err.to_string(), expected);
    }

    #[test]
    fn positions_of_elements_and_attributes() {
        let doc = parse("<a>\n  <b x=\"1\"\n     y='2'/>\n  text &amp; more\n</a>").expect("valid");
        assert_eq!(doc.pos, Pos { line: 1, col: 1 });
        let b = &doc.children[0];
        assert_eq!(b.pos, Pos { line: 2, col: 3 });
        assert_eq!(b.attr("x").map(|a| a.pos), Some(Pos { line: 2, col: 6 }));
        assert_eq!(
            b.attr("y").map(|a| (a.pos, a.value.as_str())),
            Some((Pos { line: 3, col: 6 }, "2"))
        );
        assert!(doc.text.contains("text & more"));
        // A value that holds ` y=` or `>` does not move the attributes after it.
        let doc =
            parse("<a>\n<b x=\" y=1\" y=\"2\"/><c x=\"a>b\"\ty=\"3\"/>\n</a>").expect("valid");
        let [b, c] = &doc.children[..] else {
            panic!("two children: {doc:?}");
        };
        assert_eq!(b.attr("y").map(|a| a.pos), Some(Pos { line: 2, col: 13 }));
        assert_eq!(c.attr("y").map(|a| a.pos), Some(Pos { line: 2, col: 31 }));
    }

    #[test]
    fn broken_documents_name_the_place() {
        check_error(
            "<a>\n<b></c>\n</a>",
            "2:4: malformed XML: ill-formed document: expected `</b>`, but `</c>` was found",
        );
        check_error(
            "<a>\n  <b>",
            "2:6: document ends before <b> (line 2) is closed",
        );
        check_error("", "1:1: document has no element");
        check_error("<a/><b/>", "1:5: more than one top-level element");
        check_error("<a>&bogus;</a>", "1:4: unknown entity `&bogus;`");
    }
}
