//! The field helpers of every XML format this crate reads and writes (systems, missions, PNML,
//! plans, GPX): an attribute with its position, names, required and optional attributes,
//! elements that must hold nothing, escaping, and the sorted list of problems a reader returns.

use armor_module_api::describe::is_identifier;
use armor_module_api::xml::{Element, Located, Pos};

pub(crate) const NAME_RULE: &str = "use letters, digits, `_` or `-`, starting with a letter or `_`";

/// An attribute or a text: its value and where it is.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Field<'a> {
    pub value: &'a str,
    pub pos: Pos,
}

impl<'a> Field<'a> {
    pub(crate) fn new(value: &'a str, pos: Pos) -> Self {
        Self { value, pos }
    }
}

/// A name, which must be an identifier; the message says "`what` `value` of `of`".
pub(crate) fn read_identifier(field: Field<'_>, what: &str, of: &str) -> Result<String, Located> {
    if is_identifier(field.value) {
        Ok(field.value.to_owned())
    } else {
        Err(Located::new(
            field.pos,
            format!(
                "{what} `{}` of {of} is not valid ({NAME_RULE})",
                field.value
            ),
        ))
    }
}

/// A decimal number as XSD's `xs:decimal` writes it: no exponent, no `inf` or `NaN`.
pub(crate) fn is_decimal(text: &str) -> bool {
    let digits = text.strip_prefix(['+', '-']).unwrap_or(text);
    let (whole, fraction) = digits.split_once('.').unwrap_or((digits, ""));
    let all_digits = |s: &str| s.bytes().all(|b| b.is_ascii_digit());
    (!whole.is_empty() || !fraction.is_empty())
        && digits != "."
        && all_digits(whole)
        && all_digits(fraction)
}

/// Escapes an attribute value or a text so that any XML reader gives it back unchanged
/// (whitespace characters other than the space would otherwise be normalized to spaces).
pub(crate) fn escape(value: &str) -> String {
    armor_module_api::xml::escape(value)
        .replace('\t', "&#9;")
        .replace('\n', "&#10;")
        .replace('\r', "&#13;")
}

/// `a, b, c`, or `none`.
pub(crate) fn listing<'a>(names: impl IntoIterator<Item = &'a str>) -> String {
    let names: Vec<&str> = names.into_iter().collect();
    if names.is_empty() {
        "none".to_owned()
    } else {
        names.join(", ")
    }
}

/// Sorted problems, or the value when there are none.
pub(crate) fn finish<T>(value: T, mut problems: Vec<Located>) -> Result<T, Vec<Located>> {
    if problems.is_empty() {
        Ok(value)
    } else {
        problems.sort_by_key(|problem| problem.pos);
        Err(problems)
    }
}

/// The attribute, which must be present and not blank.
pub(crate) fn required<'a>(
    element: &'a Element,
    name: &str,
    problems: &mut Vec<Located>,
) -> Option<Field<'a>> {
    element
        .required_attr(name)
        .map(|attr| Field::new(&attr.value, attr.pos))
        .map_err(|err| problems.push(err))
        .ok()
}

pub(crate) fn identifier(
    element: &Element,
    name: &str,
    what: &str,
    problems: &mut Vec<Located>,
) -> Option<String> {
    let field = required(element, name, problems)?;
    if is_identifier(field.value) {
        return Some(field.value.to_owned());
    }
    read_identifier(field, what, &format!("<{}>", element.name))
        .map_err(|err| problems.push(err))
        .ok()
}

/// The attribute read by `read` when present; `None` when absent or wrong (reported).
pub(crate) fn optional<T>(
    element: &Element,
    name: &str,
    read: fn(Field<'_>) -> Result<T, Located>,
    problems: &mut Vec<Located>,
) -> Option<T> {
    let attr = element.attr(name)?;
    read(Field::new(&attr.value, attr.pos))
        .map_err(|err| problems.push(err))
        .ok()
}

pub(crate) fn no_children(element: &Element, problems: &mut Vec<Located>) {
    for child in &element.children {
        problems.push(Located::new(
            child.pos,
            format!(
                "unknown element <{}> inside <{}> (it has no elements)",
                child.name, element.name
            ),
        ));
    }
}

pub(crate) fn no_text(element: &Element, problems: &mut Vec<Located>) {
    let text = element.text.trim();
    if !text.is_empty() {
        let shown: String = text.chars().take(40).collect();
        let more = if shown.len() < text.len() { "..." } else { "" };
        problems.push(Located::new(
            element.pos,
            format!(
                "<{}> must not contain text (found `{shown}{more}`)",
                element.name
            ),
        ));
    }
}
