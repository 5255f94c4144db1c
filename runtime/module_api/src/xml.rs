//! A small element tree with source positions, read with quick-xml's event reader.
//!
//! Every ArMoR file format (describe output, system configuration, and later missions and plans)
//! must report problems as `FILE:LINE:COL: message`. quick-xml's serde layer drops positions, so
//! loaders read the whole document into this tree first and then walk it, attaching the position
//! of the element or attribute they complain about.

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

#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Attr {
    pub name: String,
    pub value: String,
    pub pos: Pos,
}

#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Element {
    pub name: String,
    pub attrs: Vec<Attr>,
    pub children: Vec<Element>,
    /// The element's own text (character data and CDATA directly inside it), untrimmed.
    pub text: String,
    pub pos: Pos,
}

impl Element {
    pub fn attr(&self, name: &str) -> Option<&Attr> {
        self.attrs.iter().find(|attr| attr.name == name)
    }

    pub fn attr_value(&self, name: &str) -> Option<&str> {
        self.attr(name).map(|attr| attr.value.as_str())
    }

    /// The attribute's value, or a problem naming the element if it is absent or empty.
    pub fn required_attr(&self, name: &str) -> Result<&Attr, Located> {
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

    pub fn children_named<'a>(&'a self, name: &'a str) -> impl Iterator<Item = &'a Element> + 'a {
        self.children.iter().filter(move |child| child.name == name)
    }
}

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

/// Documents larger than this are refused before parsing: no configuration is anywhere near it.
pub const MAX_DOCUMENT_BYTES: usize = 64 * 1024 * 1024;

/// Reads a whole document into an element tree. The error carries the position of the problem.
pub fn parse(text: &str) -> Result<Element, Located> {
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
    let mut stack: Vec<Element> = Vec::new();
    let mut root: Option<Element> = None;
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
                    return Err(Located::new(element.pos, "more than one top-level element"));
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
                let decoded = content
                    .xml_content()
                    .map_err(|err| Located::new(index.pos(start), format!("bad text: {err}")))?;
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
                let name = String::from_utf8_lossy(&reference).into_owned();
                let resolved = match reference.resolve_char_ref() {
                    Ok(Some(ch)) => ch.to_string(),
                    _ => match quick_xml::escape::resolve_predefined_entity(&name) {
                        Some(value) => value.to_owned(),
                        None => {
                            return Err(Located::new(
                                index.pos(start),
                                format!("unknown entity `&{name};`"),
                            ));
                        }
                    },
                };
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
    element: Element,
    stack: &mut [Element],
    root: &mut Option<Element>,
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
) -> Result<Element, Located> {
    let pos = index.pos(start);
    let name = String::from_utf8_lossy(tag.local_name().as_ref()).into_owned();
    let raw_tag = text.get(start..).unwrap_or_default();
    let mut attrs = Vec::new();
    for attr in tag.attributes() {
        let attr =
            attr.map_err(|err| Located::new(pos, format!("bad attribute in <{name}>: {err}")))?;
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
        // quick-xml does not give attribute offsets; find `name=` inside this tag's own text.
        let attr_pos =
            find_attr_offset(raw_tag, &attr_name).map_or(pos, |at| index.pos(start + at));
        attrs.push(Attr {
            name: attr_name,
            value,
            pos: attr_pos,
        });
    }
    Ok(Element {
        name,
        attrs,
        children: Vec::new(),
        text: String::new(),
        pos,
    })
}

fn find_attr_offset(raw_tag: &str, name: &str) -> Option<usize> {
    let tag_end = raw_tag.find('>').unwrap_or(raw_tag.len());
    let tag = &raw_tag[..tag_end];
    let mut from = 0;
    while let Some(found) = tag[from..].find(name) {
        let at = from + found;
        let before_ok = tag[..at].ends_with(|c: char| c.is_whitespace());
        let after = tag[at + name.len()..].trim_start();
        if before_ok && after.starts_with('=') {
            return Some(at);
        }
        from = at + name.len();
    }
    None
}

/// Escapes text for an attribute value or element content.
pub fn escape(text: &str) -> std::borrow::Cow<'_, str> {
    quick_xml::escape::escape(text)
}

#[cfg(test)]
mod tests {
    use super::*;

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
