//! Edits of a knowledge-base file's text that keep everything else of it byte for byte
//! (comments, order, spacing): appearances added to a zone (`citygen evolve --into-kb`).
//!
//! The file is read with quick-xml only to find places: the zone's element (by the line its
//! start tag is on, [`super::Zone::line`]), its direct `<appearance>` children and their
//! `<values>` attributes, and where new appearances go (after the zone's last appearance, or
//! after its `info`, `location` and `polygon` children when it has none: the order the format
//! asks for). The caller checks the result with the strict reader before writing it.

use quick_xml::events::attributes::AttrError;
use quick_xml::events::Event;
use quick_xml::Reader;

/// Why an edit of a knowledge base's text is refused: the text does not read, or the edit names
/// a zone, polygon or appearance it does not have.
#[derive(Debug, thiserror::Error)]
pub enum EditError {
    /// The XML does not read.
    #[error("line {line}: {source}")]
    Syntax {
        /// The line of the error.
        line: usize,
        /// quick-xml's error.
        source: quick_xml::Error,
    },
    /// A start tag's attributes do not read.
    #[error("{0}")]
    Attribute(#[from] AttrError),
    /// An end tag with no start tag.
    #[error("line {line}: unmatched end tag")]
    UnmatchedEnd {
        /// Its line.
        line: usize,
    },
    /// No element at all.
    #[error("no root element")]
    NoRoot,
    /// The line given starts no zone.
    #[error("no zone element starts on line {line}")]
    NoZone {
        /// The line.
        line: usize,
    },
    /// A new zone's element is not a zone element.
    #[error("{element:?} is not a zone element (one of {})", ZONE_ELEMENTS.join(", "))]
    NotAZoneElement {
        /// The element asked for.
        element: String,
    },
    /// The root zone cannot be deleted.
    #[error("earth cannot be deleted")]
    DeleteEarth,
    /// The zone has no polygon of that index.
    #[error("the zone has no polygon {}", .index + 1)]
    NoPolygon {
        /// The 0-based index asked for.
        index: usize,
    },
    /// The zone has no appearance of that index.
    #[error("the zone has no appearance {}", .index + 1)]
    NoAppearance {
        /// The 0-based index asked for.
        index: usize,
    },
}

/// An appearance to add.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct NewAppearance {
    /// Its `proba`.
    pub proba: f64,
    /// Its `<values>` attributes besides `proba`, in order (raw attribute values, escaped as
    /// in XML).
    pub values: Vec<(String, String)>,
    /// Its `<ruleset file>`, relative to the KB's folder.
    pub ruleset: String,
    /// A comment written above it (without `--`).
    pub comment: Option<String>,
    /// Its `building` list (raw), or `None` for an appearance that serves every kind without
    /// a group of its own (`building=yes` among them).
    pub building: Option<String>,
}

/// A zone's direct `<appearance>` children as the text has them.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct ZoneAppearances {
    /// Each appearance's `<values>` attributes (raw), in order, with `proba` among them.
    pub values: Vec<Vec<(String, String)>>,
    /// Each appearance's `building` attribute (raw), if any.
    pub buildings: Vec<Option<String>>,
}

/// Where things are in the zone's element.
struct Places {
    /// Byte offset of the zone's start tag.
    start: usize,
    /// For an empty element (`<town .../>`): the offset of its `/>`.
    empty_close: Option<usize>,
    /// Byte offset right after the last child that new appearances follow (or after the
    /// zone's start tag).
    insert_at: usize,
    /// The zone's own indentation (spaces and tabs before its start tag on its line).
    indent: String,
    /// The zone's element name.
    name: String,
    found: ZoneAppearances,
}

/// Whether an element is a zone: every element but the format's others (any element with a
/// `designation` is a zone, [`super::ZoneKind::Other`]).
fn is_zone(name: &str) -> bool {
    !matches!(
        name.to_ascii_lowercase().as_str(),
        "info"
            | "location"
            | "polygon"
            | "appearance"
            | "values"
            | "opening"
            | "split"
            | "elements"
            | "ruleset"
            | "selex"
    )
}

/// The next event of `reader` (reading `text`), where it starts (for a tag, its `<`: the
/// whitespace before a tag belongs to the text event before it) and where it ends. A syntax
/// error names its line.
fn next_event<'a>(
    reader: &mut Reader<&'a [u8]>,
    text: &str,
) -> Result<(Event<'a>, usize, usize), EditError> {
    let before = usize::try_from(reader.buffer_position()).unwrap_or(usize::MAX);
    let ev = reader.read_event().map_err(|source| EditError::Syntax {
        line: line_of(text, usize::try_from(reader.error_position()).unwrap_or(0)),
        source,
    })?;
    let after = usize::try_from(reader.buffer_position()).unwrap_or(usize::MAX);
    let at = text
        .get(before..after)
        .and_then(|s| s.find('<'))
        .map_or(before, |i| before + i);
    Ok((ev, at, after))
}

fn line_of(text: &str, offset: usize) -> usize {
    1 + text
        .as_bytes()
        .iter()
        .take(offset)
        .filter(|&&b| b == b'\n')
        .count()
}

fn attrs(e: &quick_xml::events::BytesStart<'_>) -> Result<Vec<(String, String)>, EditError> {
    e.attributes()
        .map(|a| {
            let a = a?;
            let key = AsRef::<str>::as_ref(&a.key).to_string();
            let value = a.value.to_string();
            Ok((key, value))
        })
        .collect()
}

fn places(text: &str, zone_line: usize) -> Result<Places, EditError> {
    let mut reader = Reader::from_str(text);
    let mut depth = 0usize;
    // (depth of the zone's children, zone start, name, indent)
    let mut zone: Option<(usize, usize, String, String)> = None;
    let mut insert_at = 0usize;
    let mut after_shapes = true;
    let mut found = ZoneAppearances::default();
    let mut in_appearance = false;
    // The line of `tag_at`, counted on from the last tag's (one pass over the text in all).
    let (mut counted_to, mut line) = (0usize, 1usize);
    loop {
        let (ev, tag_at, after) = next_event(&mut reader, text)?;
        match &ev {
            Event::Start(e) | Event::Empty(e) => {
                let name = AsRef::<str>::as_ref(&e.name()).to_string();
                let empty = matches!(ev, Event::Empty(_));
                if let Some(skipped) = text.get(counted_to..tag_at) {
                    line += skipped.bytes().filter(|&b| b == b'\n').count();
                    counted_to = tag_at;
                }
                match &zone {
                    None if line == zone_line && is_zone(&name) => {
                        let line_start = text[..tag_at].rfind('\n').map_or(0, |i| i + 1);
                        let indent: String = text[line_start..tag_at]
                            .chars()
                            .take_while(|c| *c == ' ' || *c == '\t')
                            .collect();
                        if empty {
                            let close = text[..after].rfind("/>").unwrap_or(after);
                            return Ok(Places {
                                start: tag_at,
                                empty_close: Some(close),
                                insert_at: after,
                                indent,
                                name,
                                found,
                            });
                        }
                        zone = Some((depth + 1, tag_at, name, indent));
                        insert_at = after;
                    }
                    Some((d, ..)) if depth == *d => {
                        if name == "appearance" {
                            found.values.push(Vec::new());
                            found.buildings.push(
                                attrs(e)?
                                    .into_iter()
                                    .find(|(k, _)| k == "building")
                                    .map(|(_, v)| v),
                            );
                            in_appearance = !empty;
                            if empty {
                                insert_at = after;
                            }
                            after_shapes = false;
                        } else if after_shapes
                            && matches!(name.as_str(), "info" | "location" | "polygon")
                            && empty
                        {
                            insert_at = after;
                        } else if is_zone(&name) {
                            // Child zones come after the appearances.
                            after_shapes = false;
                        }
                    }
                    Some((d, ..)) if depth == *d + 1 && in_appearance && name == "values" => {
                        if let Some(v) = found.values.last_mut() {
                            *v = attrs(e)?;
                        }
                    }
                    _ => {}
                }
                if !empty {
                    depth += 1;
                }
            }
            Event::End(e) => {
                depth = depth.saturating_sub(1);
                let name = AsRef::<str>::as_ref(&e.name()).to_string();
                if let Some((d, start, zname, indent)) = &zone {
                    if depth == *d && in_appearance && name == "appearance" {
                        in_appearance = false;
                        insert_at = after;
                    } else if depth == *d
                        && after_shapes
                        && matches!(name.as_str(), "info" | "location" | "polygon")
                    {
                        insert_at = after;
                    } else if depth + 1 == *d {
                        // The zone's own end tag.
                        return Ok(Places {
                            start: *start,
                            empty_close: None,
                            insert_at,
                            indent: indent.clone(),
                            name: zname.clone(),
                            found,
                        });
                    }
                }
            }
            Event::Eof => break,
            _ => {}
        }
    }
    Err(EditError::NoZone { line: zone_line })
}

/// The direct appearances of the zone whose start tag is on `zone_line`.
pub(crate) fn zone_appearances(text: &str, zone_line: usize) -> Result<ZoneAppearances, EditError> {
    places(text, zone_line).map(|p| p.found)
}

fn escape_attr(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('"', "&quot;")
}

/// `text` with `new` appearances added to the zone whose start tag is on `zone_line`, after
/// its last appearance (or its shapes), indented one step (two spaces) deeper than the zone.
pub(crate) fn add_appearances(
    text: &str,
    zone_line: usize,
    new: &[NewAppearance],
) -> Result<String, EditError> {
    let p = places(text, zone_line)?;
    let inner = format!("{}  ", p.indent);
    let mut add = String::new();
    for a in new {
        if let Some(c) = &a.comment {
            add.push_str(&format!(
                "\n{inner}<!-- {} -->",
                c.replace("--", "- -").trim()
            ));
        }
        let mut values = format!("<values proba=\"{}\"", fmt_proba(a.proba));
        for (k, v) in &a.values {
            if k != "proba" {
                values.push_str(&format!(" {k}=\"{}\"", escape_attr(v)));
            }
        }
        values.push_str("/>");
        let building = a
            .building
            .as_ref()
            .map(|b| format!(" building=\"{}\"", escape_attr(b)))
            .unwrap_or_default();
        add.push_str(&format!(
            "\n{inner}<appearance{building}>{values}<ruleset file=\"{}\"/></appearance>",
            escape_attr(&a.ruleset)
        ));
    }
    let mut out = String::with_capacity(text.len() + add.len() + 64);
    match p.empty_close {
        Some(close) => {
            // <town .../> becomes <town ...> + appearances + </town>.
            out.push_str(text[..close].trim_end());
            out.push('>');
            out.push_str(&add);
            out.push_str(&format!("\n{}</{}>", p.indent, p.name));
            out.push_str(&text[p.insert_at..]);
        }
        None => {
            out.push_str(&text[..p.insert_at]);
            out.push_str(&add);
            out.push_str(&text[p.insert_at..]);
        }
    }
    let _ = p.start;
    Ok(out)
}

/// A probability as the KB writes it: at most 6 decimals, no trailing zeros.
fn fmt_proba(p: f64) -> String {
    let s = format!("{:.6}", p.clamp(0.0, 1.0));
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s.is_empty() {
        "0".into()
    } else {
        s.to_string()
    }
}

// ---------------------------------------------------------------------------------------------
// The editor's edits (`citygen kb edit`): zones, shapes, values, appearances and openings.
//
// Each reads the text into a tree of element spans ([`Element`]), changes the smallest range
// it can (one attribute value, one element) and leaves every other byte as it was. Zones are
// found by the line their start tag is on, as above.

/// One element of the text, with its byte span.
#[derive(Clone, Debug)]
struct Element {
    name: String,
    /// Offset of its `<`.
    start: usize,
    /// Offset just past the `>` of its start tag.
    tag_end: usize,
    /// Offset just past its end tag (`tag_end` for an empty element).
    end: usize,
    empty: bool,
    line: usize,
    children: Vec<Element>,
}

impl Element {
    fn child(&self, name: &str) -> Option<&Element> {
        self.children.iter().find(|c| c.name == name)
    }

    fn children_named<'a>(&'a self, name: &'a str) -> impl Iterator<Item = &'a Element> + 'a {
        self.children.iter().filter(move |c| c.name == name)
    }

    fn find_line(&self, line: usize) -> Option<&Element> {
        if self.line == line && is_zone(&self.name) {
            return Some(self);
        }
        self.children.iter().find_map(|c| c.find_line(line))
    }
}

/// The element tree of `text` (its root element).
fn element_tree(text: &str) -> Result<Element, EditError> {
    let mut reader = Reader::from_str(text);
    let mut stack: Vec<Element> = Vec::new();
    let mut root: Option<Element> = None;
    // Lines counted as the reader goes (one count from the start per tag is quadratic).
    let (mut seen, mut line) = (0usize, 1usize);
    let mut line_at = |offset: usize| {
        if offset > seen {
            line += text.as_bytes()[seen..offset.min(text.len())]
                .iter()
                .filter(|&&b| b == b'\n')
                .count();
            seen = offset.min(text.len());
        }
        line
    };
    loop {
        let (ev, tag_at, after) = next_event(&mut reader, text)?;
        match &ev {
            Event::Start(e) | Event::Empty(e) => {
                let empty = matches!(ev, Event::Empty(_));
                let el = Element {
                    name: AsRef::<str>::as_ref(&e.name()).to_string(),
                    start: tag_at,
                    tag_end: after,
                    end: after,
                    empty,
                    line: line_at(tag_at),
                    children: Vec::new(),
                };
                if empty {
                    match stack.last_mut() {
                        Some(parent) => parent.children.push(el),
                        None => root = Some(el),
                    }
                } else {
                    stack.push(el);
                }
            }
            Event::End(_) => {
                let Some(mut el) = stack.pop() else {
                    return Err(EditError::UnmatchedEnd {
                        line: line_of(text, tag_at),
                    });
                };
                el.end = after;
                match stack.last_mut() {
                    Some(parent) => parent.children.push(el),
                    None => root = Some(el),
                }
            }
            Event::Eof => break,
            _ => {}
        }
    }
    root.ok_or(EditError::NoRoot)
}

/// One attribute of a start tag: its name, raw value, the span of the whole `name="value"`
/// and of the value between the quotes.
struct RawAttr {
    name: String,
    value: String,
    span: (usize, usize),
    value_span: (usize, usize),
}

/// The attributes of the start tag at `el` (the text is well-formed: the tree read it).
fn raw_attrs(text: &str, el: &Element) -> Vec<RawAttr> {
    let b = text.as_bytes();
    let end = if el.empty {
        el.tag_end.saturating_sub(2)
    } else {
        el.tag_end.saturating_sub(1)
    };
    let mut i = el.start + 1 + el.name.len();
    let mut out = Vec::new();
    while i < end {
        while i < end && b[i].is_ascii_whitespace() {
            i += 1;
        }
        let name_start = i;
        while i < end && b[i] != b'=' && !b[i].is_ascii_whitespace() {
            i += 1;
        }
        let name = text.get(name_start..i).unwrap_or("").to_string();
        while i < end && (b[i] == b'=' || b[i].is_ascii_whitespace()) {
            i += 1;
        }
        if i >= end || name.is_empty() {
            break;
        }
        let quote = b[i];
        let value_start = i + 1;
        let mut j = value_start;
        while j < end && b[j] != quote {
            j += 1;
        }
        out.push(RawAttr {
            name,
            value: text.get(value_start..j).unwrap_or("").to_string(),
            span: (name_start, (j + 1).min(end)),
            value_span: (value_start, j),
        });
        i = j + 1;
    }
    out
}

/// The unescaped value of a raw attribute (the five XML entities and character references).
fn unescape(raw: &str) -> String {
    quick_xml::escape::unescape(raw).map_or_else(|_| raw.to_string(), |c| c.into_owned())
}

/// A zone's start tag by line, or an error naming the line.
fn zone_at(root: &Element, zone_line: usize) -> Result<&Element, EditError> {
    root.find_line(zone_line)
        .ok_or(EditError::NoZone { line: zone_line })
}

/// The indentation of the line `offset` is on (spaces and tabs at its start).
fn indent_at(text: &str, offset: usize) -> String {
    let line_start = text[..offset].rfind('\n').map_or(0, |i| i + 1);
    text[line_start..]
        .chars()
        .take_while(|c| *c == ' ' || *c == '\t')
        .collect()
}

/// The indentation of `el`'s children: that of its first child element, else one step (two
/// spaces) deeper than its own.
fn child_indent(text: &str, el: &Element) -> String {
    match el.children.first() {
        Some(c) if text[..c.start].ends_with([' ', '\t', '\n']) => indent_at(text, c.start),
        _ => format!("{}  ", indent_at(text, el.start)),
    }
}

/// `text` with `content` (one or more lines, without leading newline or indentation of its
/// first line) inserted as a child of `el` right after offset `at` (the end of a child, or
/// `el.tag_end` for the first place). An empty element is opened and closed around it.
fn insert_child(text: &str, el: &Element, at: usize, content: &str) -> String {
    let inner = child_indent(text, el);
    let add = format!("\n{inner}{content}");
    let mut out = String::with_capacity(text.len() + add.len() + 32);
    if el.empty {
        let close = text[..el.tag_end].rfind("/>").unwrap_or(el.tag_end);
        out.push_str(text[..close].trim_end());
        out.push('>');
        out.push_str(&add);
        out.push_str(&format!("\n{}</{}>", indent_at(text, el.start), el.name));
        out.push_str(&text[el.tag_end..]);
    } else {
        out.push_str(&text[..at]);
        out.push_str(&add);
        out.push_str(&text[at..]);
    }
    out
}

/// `text` without `el`: with the whitespace before it on its line and that line's newline when
/// nothing else precedes it there.
fn remove_element(text: &str, el: &Element) -> String {
    let line_start = text[..el.start].rfind('\n').map_or(0, |i| i + 1);
    let from = if text[line_start..el.start].trim().is_empty() {
        line_start.saturating_sub(1)
    } else {
        el.start
    };
    format!("{}{}", &text[..from], &text[el.end..])
}

/// `text` with the attributes of `el`'s start tag changed: each `(name, Some(value))` set (in
/// place when present, appended otherwise), each `(name, None)` removed. Values are given
/// unescaped and escaped here; untouched attributes keep their bytes.
fn set_attrs(text: &str, el: &Element, changes: &[(String, Option<String>)]) -> String {
    let attrs = raw_attrs(text, el);
    // (span, replacement), applied from the end.
    let mut edits: Vec<((usize, usize), String)> = Vec::new();
    let mut appended = String::new();
    for (name, value) in changes {
        match (attrs.iter().find(|a| &a.name == name), value) {
            (Some(a), Some(v)) => {
                if unescape(&a.value) != *v {
                    edits.push((a.value_span, escape_attr(v)));
                }
            }
            (Some(a), None) => {
                // The attribute and the whitespace before it.
                let mut from = a.span.0;
                while from > el.start && text.as_bytes()[from - 1].is_ascii_whitespace() {
                    from -= 1;
                }
                edits.push(((from, a.span.1), String::new()));
            }
            (None, Some(v)) => appended.push_str(&format!(" {name}=\"{}\"", escape_attr(v))),
            (None, None) => {}
        }
    }
    if !appended.is_empty() {
        // After the last attribute (or the name), before `/>` or `>`.
        let at = attrs
            .last()
            .map_or(el.start + 1 + el.name.len(), |a| a.span.1);
        edits.push(((at, at), appended));
    }
    edits.sort_by_key(|(span, _)| std::cmp::Reverse(span.0));
    let mut out = text.to_string();
    for ((a, b), r) in edits {
        out.replace_range(a..b, &r);
    }
    out
}

/// The element names a zone may have in the clean format.
pub(crate) const ZONE_ELEMENTS: [&str; 6] =
    ["continent", "country", "region", "town", "district", "zone"];

/// A zone's circle: centre in degrees and radius in kilometres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CircleText {
    /// Latitude of the centre.
    pub lat: f64,
    /// Longitude of the centre.
    pub lon: f64,
    /// Radius, km.
    pub dist: f64,
}

/// A number written short: at most `decimals` decimals, no trailing zeros.
pub(crate) fn fmt_number(x: f64, decimals: usize) -> String {
    let s = format!("{x:.decimals$}");
    let s = if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    };
    if s == "-0" || s.is_empty() {
        "0".into()
    } else {
        s
    }
}

/// A ring as the `points` attribute writes it: `lon lat, lon lat, ...` at 7 decimals (1 cm).
pub(crate) fn points_text(points: &[(f64, f64)]) -> String {
    points
        .iter()
        .map(|(lon, lat)| format!("{} {}", fmt_number(*lon, 7), fmt_number(*lat, 7)))
        .collect::<Vec<_>>()
        .join(", ")
}

/// A zone's shape when it is made.
#[derive(Clone, Debug, PartialEq)]
pub enum NewShape {
    /// A circle on `<info lat lon dist>`.
    Circle(CircleText),
    /// A `<polygon>` ring of (lon, lat) points.
    Polygon(Vec<(f64, f64)>),
}

/// `text` with a new zone `<element designation=...>` holding `shape` added as the last child
/// of the zone whose start tag is on `parent_line` (after its appearances and sub-zones).
pub fn add_zone(
    text: &str,
    parent_line: usize,
    element: &str,
    designation: &str,
    shape: &NewShape,
) -> Result<String, EditError> {
    if !ZONE_ELEMENTS.contains(&element) {
        return Err(EditError::NotAZoneElement {
            element: element.to_string(),
        });
    }
    let root = element_tree(text)?;
    let parent = zone_at(&root, parent_line)?;
    let inner = format!("{}  ", child_indent(text, parent));
    let shape = match shape {
        NewShape::Circle(c) => format!(
            "<info lat=\"{}\" lon=\"{}\" dist=\"{}\"/>",
            fmt_number(c.lat, 7),
            fmt_number(c.lon, 7),
            fmt_number(c.dist, 4)
        ),
        NewShape::Polygon(p) => format!("<polygon points=\"{}\"/>", points_text(p)),
    };
    let outer = child_indent(text, parent);
    let content = format!(
        "<{element} designation=\"{}\">\n{inner}{shape}\n{outer}</{element}>",
        escape_attr(designation)
    );
    let at = parent.children.last().map_or(parent.tag_end, |c| c.end);
    Ok(insert_child(text, parent, at, &content))
}

/// `text` without the zone whose start tag is on `zone_line` (and its sub-zones). Earth cannot
/// be deleted.
pub fn delete_zone(text: &str, zone_line: usize) -> Result<String, EditError> {
    let root = element_tree(text)?;
    let zone = zone_at(&root, zone_line)?;
    if zone.start == root.start {
        return Err(EditError::DeleteEarth);
    }
    Ok(remove_element(text, zone))
}

/// `text` with the `<info>` of the zone on `zone_line` changed: each `(name, Some(value))` set,
/// each `(name, None)` removed. An `<info/>` is made (first child) when the zone has none, and
/// removed when it is left without attributes.
pub fn set_info(
    text: &str,
    zone_line: usize,
    changes: &[(String, Option<String>)],
) -> Result<String, EditError> {
    let root = element_tree(text)?;
    let zone = zone_at(&root, zone_line)?;
    match zone.child("info") {
        Some(info) => {
            let out = set_attrs(text, info, changes);
            // An <info/> without attributes says nothing: remove it.
            let root2 = element_tree(&out)?;
            let zone2 = zone_at(&root2, zone_line)?;
            if let Some(info2) = zone2.child("info") {
                if info2.empty && raw_attrs(&out, info2).is_empty() {
                    return Ok(remove_element(&out, info2));
                }
            }
            Ok(out)
        }
        None => {
            let set: Vec<String> = changes
                .iter()
                .filter_map(|(k, v)| v.as_ref().map(|v| format!(" {k}=\"{}\"", escape_attr(v))))
                .collect();
            if set.is_empty() {
                return Ok(text.to_string());
            }
            Ok(insert_child(
                text,
                zone,
                zone.tag_end,
                &format!("<info{}/>", set.concat()),
            ))
        }
    }
}

/// `text` with the circle of the zone on `zone_line` set (or removed: `None`): on its
/// `<location>` when it has one, else on its `<info>`.
pub fn set_circle(
    text: &str,
    zone_line: usize,
    circle: Option<CircleText>,
) -> Result<String, EditError> {
    let root = element_tree(text)?;
    let zone = zone_at(&root, zone_line)?;
    if let Some(loc) = zone.child("location") {
        return Ok(match circle {
            Some(c) => set_attrs(text, loc, &circle_changes(Some(c))),
            None => remove_element(text, loc),
        });
    }
    set_info(text, zone_line, &circle_changes(circle))
}

fn circle_changes(c: Option<CircleText>) -> Vec<(String, Option<String>)> {
    vec![
        ("lat".into(), c.map(|c| fmt_number(c.lat, 7))),
        ("lon".into(), c.map(|c| fmt_number(c.lon, 7))),
        ("dist".into(), c.map(|c| fmt_number(c.dist, 4))),
    ]
}

/// `text` with polygon `index` (0-based, document order) of the zone on `zone_line` replaced
/// by `points` (or removed: `None`); `index` `None` adds a polygon after the zone's shapes.
pub fn set_polygon(
    text: &str,
    zone_line: usize,
    index: Option<usize>,
    points: Option<&[(f64, f64)]>,
) -> Result<String, EditError> {
    let root = element_tree(text)?;
    let zone = zone_at(&root, zone_line)?;
    match index {
        Some(i) => {
            let Some(poly) = zone.children_named("polygon").nth(i) else {
                return Err(EditError::NoPolygon { index: i });
            };
            Ok(match points {
                Some(p) => set_attrs(text, poly, &[("points".into(), Some(points_text(p)))]),
                None => remove_element(text, poly),
            })
        }
        None => {
            let Some(p) = points else {
                return Ok(text.to_string());
            };
            let at = zone
                .children
                .iter()
                .take_while(|c| matches!(c.name.as_str(), "info" | "location" | "polygon"))
                .last()
                .map_or(zone.tag_end, |c| c.end);
            Ok(insert_child(
                text,
                zone,
                at,
                &format!("<polygon points=\"{}\"/>", points_text(p)),
            ))
        }
    }
}

/// An opening subdivision as the editor sends it: `<split>`s from the root node down.
#[derive(Clone, Debug, PartialEq)]
pub struct OpeningText {
    /// The node standing for the whole window (`<elements parent>`).
    pub root: String,
    /// `(axis, parent, children, shares)`: one `<split>` each.
    pub splits: Vec<(String, String, Vec<String>, Vec<f64>)>,
    /// The leaves (`<elements terms>`).
    pub terms: Vec<String>,
}

/// An appearance as the editor sends it.
#[derive(Clone, Debug, PartialEq)]
pub struct AppearanceText {
    /// The `building` attribute (`None`: any kind).
    pub building: Option<String>,
    /// The `<values>` attributes (unescaped), `proba` among them, in order.
    pub values: Vec<(String, String)>,
    /// The `<opening>` (`None`: one pane per window).
    pub opening: Option<OpeningText>,
    /// The `<ruleset file>` (`None`: none).
    pub ruleset: Option<String>,
}

fn opening_xml(o: &OpeningText, indent: &str) -> String {
    let inner = format!("{indent}  ");
    let mut s = String::from("<opening>");
    for (axis, parent, children, shares) in &o.splits {
        s.push_str(&format!(
            "\n{inner}<split axis=\"{}\" parent=\"{}\" children=\"{}\" splitvalues=\"{}\"/>",
            escape_attr(axis),
            escape_attr(parent),
            escape_attr(&children.join("|")),
            shares
                .iter()
                .map(|x| fmt_number(*x, 4))
                .collect::<Vec<_>>()
                .join(",")
        ));
    }
    s.push_str(&format!(
        "\n{inner}<elements parent=\"{}\" terms=\"{}\"/>",
        escape_attr(&o.root),
        escape_attr(&o.terms.join(","))
    ));
    s.push_str(&format!("\n{indent}</opening>"));
    s
}

fn appearance_xml(a: &AppearanceText, indent: &str) -> String {
    let inner = format!("{indent}  ");
    let building = a
        .building
        .as_ref()
        .map(|b| format!(" building=\"{}\"", escape_attr(b)))
        .unwrap_or_default();
    let values: String = a
        .values
        .iter()
        .map(|(k, v)| format!(" {k}=\"{}\"", escape_attr(v)))
        .collect();
    let mut s = format!("<appearance{building}>\n{inner}<values{values}/>");
    if let Some(o) = &a.opening {
        s.push_str(&format!("\n{inner}{}", opening_xml(o, &inner)));
    }
    if let Some(r) = &a.ruleset {
        s.push_str(&format!("\n{inner}<ruleset file=\"{}\"/>", escape_attr(r)));
    }
    s.push_str(&format!("\n{indent}</appearance>"));
    s
}

/// `text` with appearance `a` added to the zone on `zone_line`, after its last appearance (or
/// its shapes).
pub fn add_appearance(
    text: &str,
    zone_line: usize,
    a: &AppearanceText,
) -> Result<String, EditError> {
    let root = element_tree(text)?;
    let zone = zone_at(&root, zone_line)?;
    let at = zone
        .children
        .iter()
        .take_while(|c| {
            matches!(
                c.name.as_str(),
                "info" | "location" | "polygon" | "appearance"
            )
        })
        .last()
        .map_or(zone.tag_end, |c| c.end);
    let indent = child_indent(text, zone);
    Ok(insert_child(text, zone, at, &appearance_xml(a, &indent)))
}

fn nth_appearance(zone: &Element, index: usize) -> Result<&Element, EditError> {
    zone.children_named("appearance")
        .nth(index)
        .ok_or(EditError::NoAppearance { index })
}

/// `text` with the `proba` of the zone's appearances set: each `(index, proba)` (0-based
/// appearance index) changes that appearance's `<values proba>` in place (added when absent);
/// everything else keeps its bytes.
pub(crate) fn set_probas(
    text: &str,
    zone_line: usize,
    probas: &[(usize, f64)],
) -> Result<String, EditError> {
    let mut out = text.to_string();
    for &(index, proba) in probas {
        let root = element_tree(&out)?;
        let zone = zone_at(&root, zone_line)?;
        let app = nth_appearance(zone, index)?;
        let change = [("proba".to_string(), Some(fmt_proba(proba)))];
        out = match app.child("values") {
            Some(v) => set_attrs(&out, v, &change),
            None => insert_child(
                &out,
                app,
                app.tag_end,
                &format!("<values proba=\"{}\"/>", fmt_proba(proba)),
            ),
        };
    }
    Ok(out)
}

/// `text` without appearance `index` (0-based) of the zone on `zone_line`.
pub fn delete_appearance(text: &str, zone_line: usize, index: usize) -> Result<String, EditError> {
    let root = element_tree(text)?;
    let zone = zone_at(&root, zone_line)?;
    Ok(remove_element(text, nth_appearance(zone, index)?))
}

/// `text` with appearance `index` (0-based) of the zone on `zone_line` set to `a`: its
/// `building` and `<values>` attributes changed in place (attributes `a` does not have are
/// removed), its `<opening>` and `<ruleset>` replaced, added or removed; a `<selex>` and
/// everything else of the element kept.
pub(crate) fn set_appearance(
    text: &str,
    zone_line: usize,
    index: usize,
    a: &AppearanceText,
) -> Result<String, EditError> {
    // Each step re-reads the text: the spans move.
    let step = |text: &str, f: &dyn Fn(&str, &Element) -> Result<String, EditError>| {
        let root = element_tree(text)?;
        let zone = zone_at(&root, zone_line)?;
        f(text, nth_appearance(zone, index)?)
    };
    let mut out = step(text, &|t, app| {
        Ok(set_attrs(
            t,
            app,
            &[("building".into(), a.building.clone())],
        ))
    })?;
    out = step(&out, &|t, app| match app.child("values") {
        Some(v) => {
            let mut changes: Vec<(String, Option<String>)> = raw_attrs(t, v)
                .into_iter()
                .filter(|r| !a.values.iter().any(|(k, _)| *k == r.name))
                .map(|r| (r.name, None))
                .collect();
            changes.extend(a.values.iter().map(|(k, v)| (k.clone(), Some(v.clone()))));
            Ok(set_attrs(t, v, &changes))
        }
        None => {
            let values: String = a
                .values
                .iter()
                .map(|(k, v)| format!(" {k}=\"{}\"", escape_attr(v)))
                .collect();
            Ok(insert_child(
                t,
                app,
                app.tag_end,
                &format!("<values{values}/>"),
            ))
        }
    })?;
    for (name, make) in [
        (
            "opening",
            a.opening.as_ref().map(|o| {
                Box::new(move |ind: &str| opening_xml(o, ind)) as Box<dyn Fn(&str) -> String>
            }),
        ),
        (
            "ruleset",
            a.ruleset.as_ref().map(|r| {
                Box::new(move |_: &str| format!("<ruleset file=\"{}\"/>", escape_attr(r)))
                    as Box<dyn Fn(&str) -> String>
            }),
        ),
    ] {
        out = step(&out, &|t, app| {
            let existing = app.child(name);
            match (existing, &make) {
                (Some(el), None) => Ok(remove_element(t, el)),
                (Some(el), Some(make)) => {
                    let indent = indent_at(t, el.start);
                    Ok(format!(
                        "{}{}{}",
                        &t[..el.start],
                        make(&indent),
                        &t[el.end..]
                    ))
                }
                (None, Some(make)) => {
                    // After <values> (and <opening> for a ruleset).
                    let at = app
                        .children
                        .iter()
                        .take_while(|c| {
                            c.name == "values" || (name == "ruleset" && c.name == "opening")
                        })
                        .last()
                        .map_or(app.tag_end, |c| c.end);
                    let indent = child_indent(t, app);
                    Ok(insert_child(t, app, at, &make(&indent)))
                }
                (None, None) => Ok(t.to_string()),
            }
        })?;
    }
    Ok(out)
}

/// What the editor shows of a zone's own text: its `<info>` attributes and its appearances'
/// `building`, `<values>`, `<opening>` and files, all unescaped, in document order.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct ZoneText {
    /// The `<info>` attributes.
    pub info: Vec<(String, String)>,
    /// `<location>`'s attributes when the zone has one.
    pub location: Option<Vec<(String, String)>>,
    /// The appearances.
    pub appearances: Vec<AppearanceView>,
}

/// One appearance as written.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct AppearanceView {
    /// The `building` attribute.
    pub building: Option<String>,
    /// The `<values>` attributes.
    pub values: Vec<(String, String)>,
    /// The `<split>`s' attributes, in order.
    pub splits: Vec<Vec<(String, String)>>,
    /// The `<elements>` attributes.
    pub elements: Option<Vec<(String, String)>>,
    /// `<ruleset file>`.
    pub ruleset: Option<String>,
    /// `<selex file>`.
    pub selex: Option<String>,
}

/// The own text of every zone, by the line its start tag is on.
pub(crate) fn zone_texts(
    text: &str,
) -> Result<std::collections::BTreeMap<usize, ZoneText>, EditError> {
    let root = element_tree(text)?;
    let mut out = std::collections::BTreeMap::new();
    let attrs_of = |el: &Element| -> Vec<(String, String)> {
        raw_attrs(text, el)
            .into_iter()
            .map(|a| (a.name, unescape(&a.value)))
            .collect()
    };
    let mut stack = vec![&root];
    while let Some(z) = stack.pop() {
        let mut zt = ZoneText {
            info: z.child("info").map(attrs_of).unwrap_or_default(),
            location: z.child("location").map(attrs_of),
            appearances: Vec::new(),
        };
        for app in z.children_named("appearance") {
            let file = |n: &str| {
                app.child(n).and_then(|e| {
                    attrs_of(e)
                        .into_iter()
                        .find(|(k, _)| k == "file")
                        .map(|(_, v)| v)
                })
            };
            let opening = app.child("opening");
            zt.appearances.push(AppearanceView {
                building: attrs_of(app)
                    .into_iter()
                    .find(|(k, _)| k == "building")
                    .map(|(_, v)| v),
                values: app.child("values").map(attrs_of).unwrap_or_default(),
                splits: opening
                    .map(|o| o.children_named("split").map(attrs_of).collect())
                    .unwrap_or_default(),
                elements: opening.and_then(|o| o.child("elements")).map(attrs_of),
                ruleset: file("ruleset"),
                selex: file("selex"),
            });
        }
        out.insert(z.line, zt);
        stack.extend(z.children.iter().filter(|c| is_zone(&c.name)));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    const KB: &str = r##"<earth>
  <!-- a comment kept -->
  <info nbfloor="2"/>
  <country designation="X">
    <info lat="1" lon="2" dist="3"/>
    <appearance building="house"><values proba="0.7" color="red"/></appearance>
    <appearance>
      <values proba="0.3" color="#fff" bdRooftype="flat"/>
    </appearance>
    <town designation="T"/>
    <town designation="U">
      <info lat="1" lon="2" dist="1"/>
    </town>
  </country>
</earth>
"##;

    fn new(p: f64) -> NewAppearance {
        NewAppearance {
            proba: p,
            values: vec![
                ("color".into(), "#fff".into()),
                ("proba".into(), "9".into()),
            ],
            ruleset: "evolved/a.cga".into(),
            comment: Some("evolved -- hsym".into()),
            building: None,
        }
    }

    #[test]
    fn a_zones_appearances_are_read_with_their_values() {
        let z = zone_appearances(KB, 4).unwrap();
        assert_eq!(z.values.len(), 2);
        assert_eq!(z.values[1][1], ("color".into(), "#fff".into()));
        assert_eq!(z.buildings, vec![Some("house".into()), None]);
        assert_eq!(zone_appearances(KB, 10).unwrap().values.len(), 0);
        assert!(zone_appearances(KB, 3).is_err(), "line 3 starts no zone");
    }

    #[test]
    fn appearances_go_after_the_last_one_and_the_rest_is_kept() {
        let out = add_appearances(KB, 4, &[new(0.25)]).unwrap();
        let at = out
            .find("</appearance>\n    <!-- evolved - - hsym -->")
            .unwrap();
        assert!(at > out.find("bdRooftype=\"flat\"").unwrap());
        assert!(out.contains(
            "\n    <appearance><values proba=\"0.25\" color=\"#fff\"/><ruleset file=\"evolved/a.cga\"/></appearance>\n    <town designation=\"T\"/>"
        ));
        // Everything else byte for byte.
        let removed = out.replace(
            "\n    <!-- evolved - - hsym -->\n    <appearance><values proba=\"0.25\" color=\"#fff\"/><ruleset file=\"evolved/a.cga\"/></appearance>",
            "",
        );
        assert_eq!(removed, KB);
        let (kb, _) = crate::kb::KnowledgeBase::parse_str(&out, "kb.xml").unwrap();
        let x = crate::kb::tools::find_zone(&kb, "earth/X").unwrap();
        assert_eq!(kb.zones()[x].appearances.len(), 3);
    }

    #[test]
    fn a_zone_without_appearances_or_an_empty_element_takes_them_too() {
        let out = add_appearances(KB, 11, &[new(1.0)]).unwrap();
        assert!(out.contains("dist=\"1\"/>\n      <!--"), "{out}");
        let out = add_appearances(KB, 10, &[new(0.5), new(0.5)]).unwrap();
        assert!(
            out.contains("<town designation=\"T\">\n      <!--"),
            "{out}"
        );
        assert!(out.contains("</appearance>\n    </town>\n    <town designation=\"U\">"));
        let (kb, _) = crate::kb::KnowledgeBase::parse_str(&out, "kb.xml").unwrap();
        let t = crate::kb::tools::find_zone(&kb, "earth/X/T").unwrap();
        assert_eq!(kb.zones()[t].appearances.len(), 2);
        assert_eq!(
            kb.zones()[t].appearances[0].ruleset.as_deref(),
            Some("evolved/a.cga")
        );
    }

    #[test]
    fn probabilities_are_written_short() {
        assert_eq!(fmt_proba(0.25), "0.25");
        assert_eq!(fmt_proba(1.0), "1");
        assert_eq!(fmt_proba(1.0 / 3.0), "0.333333");
        assert_eq!(fmt_proba(0.0), "0");
    }

    /// `text` read strictly (the test KB's `#fff` written long, which strict reading asks).
    fn strict(text: &str) -> crate::kb::KnowledgeBase {
        let text = text.replace("color=\"#fff\"", "color=\"#ffffff\"");
        match crate::kb::KnowledgeBase::parse_str_with(&text, "kb.xml", crate::kb::ReadMode::Strict)
        {
            Ok((kb, _)) => kb,
            Err(e) => panic!("{e}\n{text}"),
        }
    }

    /// What is left of `out` once `added` is taken out of it, at one place.
    fn without(out: &str, added: &str) -> String {
        assert_eq!(out.matches(added).count(), 1, "{added:?} in\n{out}");
        out.replacen(added, "", 1)
    }

    #[test]
    fn a_zone_is_added_last_and_deleted_with_its_line() {
        let ring = [(2.0, 1.0), (2.01, 1.0), (2.01, 1.01)];
        let out = add_zone(
            KB,
            11,
            "district",
            "D & E",
            &NewShape::Polygon(ring.to_vec()),
        )
        .unwrap();
        let added = "\n      <district designation=\"D &amp; E\">\n        <polygon points=\"2 1, 2.01 1, 2.01 1.01\"/>\n      </district>";
        assert_eq!(without(&out, added), KB);
        let kb = strict(&out);
        let d = kb.find("earth/X/U/D & E").unwrap();
        assert_eq!(kb.zones()[d].polygons.len(), 1);
        assert_eq!(delete_zone(&out, kb.zones()[d].line).unwrap(), KB);
        // Into an empty element, with a circle.
        let c = CircleText {
            lat: 1.5,
            lon: 2.25,
            dist: 0.5,
        };
        let out = add_zone(KB, 10, "zone", "B", &NewShape::Circle(c)).unwrap();
        assert!(out.contains("<town designation=\"T\">\n      <zone designation=\"B\">\n        <info lat=\"1.5\" lon=\"2.25\" dist=\"0.5\"/>\n      </zone>\n    </town>"), "{out}");
        strict(&out);
        assert!(add_zone(KB, 10, "info", "B", &NewShape::Circle(c)).is_err());
        assert!(delete_zone(KB, 1).is_err(), "earth stays");
        assert!(delete_zone(KB, 3).is_err(), "line 3 starts no zone");
    }

    #[test]
    fn circles_and_polygons_change_in_place() {
        let c = CircleText {
            lat: -1.25,
            lon: 3.0,
            dist: 2.0,
        };
        let out = set_circle(KB, 11, Some(c)).unwrap();
        assert_eq!(
            out.replace(
                "<info lat=\"-1.25\" lon=\"3\" dist=\"2\"/>",
                "<info lat=\"1\" lon=\"2\" dist=\"1\"/>"
            ),
            KB
        );
        // Removed: the info is left without attributes and goes.
        let out = set_circle(KB, 11, None).unwrap();
        assert_eq!(
            out,
            KB.replace("\n      <info lat=\"1\" lon=\"2\" dist=\"1\"/>", "")
        );
        // On a <location>.
        let loc = KB.replace("<town designation=\"T\"/>", "<town designation=\"T\">\n      <location lat=\"1\" lon=\"2\" dist=\"3\"/>\n    </town>");
        let out = set_circle(&loc, 10, Some(c)).unwrap();
        assert!(out.contains("<location lat=\"-1.25\" lon=\"3\" dist=\"2\"/>"));
        strict(&out);
        // Polygons: added after the shapes, replaced, removed.
        let ring = [(2.0, 1.0), (2.01, 1.0), (2.01, 1.01)];
        let out = set_polygon(KB, 4, None, Some(&ring)).unwrap();
        assert_eq!(
            without(&out, "\n    <polygon points=\"2 1, 2.01 1, 2.01 1.01\"/>"),
            KB
        );
        assert!(out.contains("dist=\"3\"/>\n    <polygon"));
        let moved = [(2.0, 1.0), (2.02, 1.0), (2.02, 1.02)];
        let out2 = set_polygon(&out, 4, Some(0), Some(&moved)).unwrap();
        assert_eq!(
            out2,
            out.replace("2 1, 2.01 1, 2.01 1.01", "2 1, 2.02 1, 2.02 1.02")
        );
        assert_eq!(set_polygon(&out2, 4, Some(0), None).unwrap(), KB);
        assert!(set_polygon(KB, 4, Some(0), None).is_err());
    }

    #[test]
    fn info_values_are_set_and_removed_keeping_the_others() {
        let ch = |k: &str, v: Option<&str>| (k.to_string(), v.map(str::to_string));
        let out = set_info(KB, 4, &[ch("color", Some("#aabbcc")), ch("dist", None)]).unwrap();
        assert_eq!(
            out,
            KB.replace(
                "<info lat=\"1\" lon=\"2\" dist=\"3\"/>",
                "<info lat=\"1\" lon=\"2\" color=\"#aabbcc\"/>"
            )
        );
        let out = set_info(KB, 10, &[ch("nbfloor", Some("3"))]).unwrap();
        assert!(
            out.contains("<town designation=\"T\">\n      <info nbfloor=\"3\"/>\n    </town>"),
            "{out}"
        );
        strict(&out);
        let texts = zone_texts(&out).unwrap();
        assert_eq!(
            texts[&10].info,
            vec![("nbfloor".to_string(), "3".to_string())]
        );
    }

    #[test]
    fn appearances_are_added_set_and_deleted_with_their_openings() {
        let a = AppearanceText {
            building: None,
            values: vec![("proba".into(), "1".into()), ("color".into(), "red".into())],
            opening: Some(OpeningText {
                root: "w".into(),
                splits: vec![
                    (
                        "X".into(),
                        "w".into(),
                        vec!["a".into(), "b".into()],
                        vec![0.5, 0.5],
                    ),
                    (
                        "Z".into(),
                        "a".into(),
                        vec!["a1".into(), "a2".into()],
                        vec![0.3, 0.7],
                    ),
                ],
                terms: vec!["a1".into(), "a2".into(), "b".into()],
            }),
            ruleset: None,
        };
        let out = add_appearance(KB, 11, &a).unwrap();
        let added = "\n      <appearance>\n        <values proba=\"1\" color=\"red\"/>\n        <opening>\n          <split axis=\"X\" parent=\"w\" children=\"a|b\" splitvalues=\"0.5,0.5\"/>\n          <split axis=\"Z\" parent=\"a\" children=\"a1|a2\" splitvalues=\"0.3,0.7\"/>\n          <elements parent=\"w\" terms=\"a1,a2,b\"/>\n        </opening>\n      </appearance>";
        assert_eq!(without(&out, added), KB);
        let kb = strict(&out);
        let u = kb.find("earth/X/U").unwrap();
        let o = kb.zones()[u].appearances[0].opening.as_ref().unwrap();
        assert_eq!(o.splits.len(), 2);
        assert_eq!(o.terms, vec!["a1", "a2", "b"]);
        let texts = zone_texts(&out).unwrap();
        assert_eq!(texts[&11].appearances[0].splits.len(), 2);
        // Set: values changed in place, an attribute dropped, the opening removed.
        let b = AppearanceText {
            building: Some("house".into()),
            values: vec![
                ("proba".into(), "0.7".into()),
                ("bdRooftype".into(), "flat".into()),
            ],
            opening: None,
            ruleset: Some("rules/x.cga".into()),
        };
        let out = set_appearance(KB, 4, 1, &b).unwrap();
        assert_eq!(
            out,
            KB.replace(
                "<appearance>\n      <values proba=\"0.3\" color=\"#fff\" bdRooftype=\"flat\"/>\n    </appearance>",
                "<appearance building=\"house\">\n      <values proba=\"0.7\" bdRooftype=\"flat\"/>\n      <ruleset file=\"rules/x.cga\"/>\n    </appearance>"
            ),
            "{out}"
        );
        // The other appearance and everything around them are kept.
        assert!(out.contains(
            "<appearance building=\"house\"><values proba=\"0.7\" color=\"red\"/></appearance>"
        ));
        let back = set_appearance(
            &out,
            4,
            1,
            &AppearanceText {
                building: None,
                values: vec![
                    ("proba".into(), "0.3".into()),
                    ("color".into(), "#fff".into()),
                    ("bdRooftype".into(), "flat".into()),
                ],
                opening: None,
                ruleset: None,
            },
        )
        .unwrap();
        // A value given back comes after the ones kept.
        assert_eq!(
            back,
            KB.replace(
                "proba=\"0.3\" color=\"#fff\" bdRooftype=\"flat\"",
                "proba=\"0.3\" bdRooftype=\"flat\" color=\"#fff\""
            )
        );
        let out = delete_appearance(KB, 4, 0).unwrap();
        assert_eq!(out, KB.replace("\n    <appearance building=\"house\"><values proba=\"0.7\" color=\"red\"/></appearance>", ""));
        assert!(delete_appearance(KB, 4, 2).is_err());
    }
}
