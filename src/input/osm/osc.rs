//! OSM change files (osmChange XML, `.osc`, plain or gzip-compressed `.osc.gz`), as published by
//! the planet.openstreetmap.org replication and written by osmium and osmosis.
//!
//! [`read_osc`] reads a change file into a [`Change`]: the final state of every element it names,
//! or its deletion. The file is a sequence: elements come in `<create>`, `<modify>` and
//! `<delete>` blocks, several of each in any order, and when one element appears several times
//! the last one in file order wins. [`super::read_osm_with_changes`] applies a `Change` to a PBF
//! extract while reading it, so the footprints are those of the extract with the changes applied.
//!
//! Gzip is recognised by its magic bytes (1f 8b), not by the file name. Every error names the
//! file, the line and the element (`node/12`) where one is known. Never panics.

use std::collections::BTreeMap;
use std::io::Read;
use std::path::Path;

use quick_xml::events::{BytesStart, Event};
use quick_xml::{Reader, XmlVersion};

use super::InputError;

/// Largest change file read, after decompression (8 GiB; a daily planet diff is about 1.5 GiB).
/// Bounds memory on a hostile or mistaken input (a gzip bomb).
pub(crate) const MAX_OSC_BYTES: u64 = 8 << 30;

/// The type of a relation member in a change file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum MemberType {
    /// `type="node"`.
    Node,
    /// `type="way"`.
    Way,
    /// `type="relation"`.
    Relation,
}

/// Raw OSM tags, (key, value) in file order.
pub(crate) type OscTags = Vec<(String, String)>;

/// A way's new state: its node ids in order and its tags.
pub(crate) type OscWay = (Vec<i64>, OscTags);

/// A relation's new state: its members as (type, id, role) in order and its tags.
pub(crate) type OscRelation = (Vec<(MemberType, i64, String)>, OscTags);

/// The final state of every element a change file names: `Some` = created or modified to this,
/// `None` = deleted. An element the file names several times has the last one's state.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct Change {
    /// Node id → (lon, lat) in degrees, as the PBF reader gives coordinates (the file's decimal
    /// value to the nanodegree, `1e-9 * nanodegrees`).
    pub nodes: BTreeMap<i64, Option<(f64, f64)>>,
    /// Way id → (node ids, tags).
    pub ways: BTreeMap<i64, Option<OscWay>>,
    /// Relation id → (members, tags).
    pub relations: BTreeMap<i64, Option<OscRelation>>,
}

impl Change {
    /// Whether the change names no element.
    #[cfg(test)]
    pub(crate) fn is_empty(&self) -> bool {
        self.nodes.is_empty() && self.ways.is_empty() && self.relations.is_empty()
    }
}

/// Reads an osmChange file (plain XML, or gzip-compressed: recognised by its first two bytes).
///
/// Errors ([`InputError::Io`], [`InputError::OsmChange`]) name the file and, for a parse or
/// validation error, the line and the element (`way/7`): malformed XML, a root element other
/// than `<osmChange>`, an element outside `<create>`/`<modify>`/`<delete>`, an id that is not
/// an integer, a created or modified node without a valid `lat` (-90..=90) and `lon`
/// (-180..=180), a way's `nd` or a relation's `member` without a valid `ref`, a member of
/// unknown type, a tag without `k` or `v`, a truncated file or gzip stream. Elements inside
/// `<delete>` need only their id. Never panics.
pub(crate) fn read_osc(path: &Path) -> Result<Change, InputError> {
    let io = |source| InputError::Io {
        path: path.to_path_buf(),
        source,
    };
    let raw = std::fs::read(path).map_err(io)?;
    let data = if raw.starts_with(&[0x1f, 0x8b]) {
        let mut out = Vec::new();
        let mut dec = flate2::read::MultiGzDecoder::new(raw.as_slice()).take(MAX_OSC_BYTES + 1);
        if let Err(e) = dec.read_to_end(&mut out) {
            return Err(osc_error(
                path,
                format!("gzip stream, after {} decompressed bytes", out.len()),
                format!("cannot decompress: {e}"),
            ));
        }
        drop(raw);
        out
    } else {
        raw
    };
    if data.len() as u64 > MAX_OSC_BYTES {
        return Err(osc_error(
            path,
            "the whole file".into(),
            format!("larger than {MAX_OSC_BYTES} bytes"),
        ));
    }
    parse(path, &data)
}

fn osc_error(path: &Path, place: String, reason: String) -> InputError {
    InputError::OsmChange {
        path: path.to_path_buf(),
        place,
        reason,
    }
}

/// 1-based line of byte `offset` of `data`.
fn line_of(data: &[u8], offset: u64) -> usize {
    let end = usize::try_from(offset)
        .unwrap_or(usize::MAX)
        .min(data.len());
    data[..end].iter().filter(|&&b| b == b'\n').count() + 1
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Action {
    Create,
    Modify,
    Delete,
}

impl Action {
    fn name(self) -> &'static str {
        match self {
            Action::Create => "create",
            Action::Modify => "modify",
            Action::Delete => "delete",
        }
    }
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Kind {
    Node,
    Way,
    Relation,
}

impl Kind {
    fn name(self) -> &'static str {
        match self {
            Kind::Node => "node",
            Kind::Way => "way",
            Kind::Relation => "relation",
        }
    }
}

/// The element being read (inside an action block).
struct Current {
    kind: Kind,
    id: i64,
    /// (lon, lat) of a node (not in `<delete>`).
    pos: Option<(f64, f64)>,
    refs: Vec<i64>,
    members: Vec<(MemberType, i64, String)>,
    tags: OscTags,
}

struct Parser<'a> {
    path: &'a Path,
    data: &'a [u8],
    change: Change,
    action: Option<Action>,
    current: Option<Current>,
}

impl Parser<'_> {
    fn err(&self, offset: u64, element: Option<String>, reason: String) -> InputError {
        let mut place = format!("line {}", line_of(self.data, offset));
        if let Some(e) = element {
            place.push_str(&format!(", {e}"));
        }
        osc_error(self.path, place, reason)
    }

    /// The element being read, as errors name it.
    fn current_name(&self) -> Option<String> {
        self.current
            .as_ref()
            .map(|c| format!("{}/{}", c.kind.name(), c.id))
    }

    /// The attributes of `e` as (name, unescaped value).
    fn attrs(&self, e: &BytesStart, at: u64) -> Result<Vec<(String, String)>, InputError> {
        let mut out = Vec::new();
        for a in e.attributes() {
            let a = a.map_err(|err| self.err(at, self.current_name(), err.to_string()))?;
            let key = a.key.as_ref().to_string();
            let value = a.normalized_value(XmlVersion::Implicit1_0).map_err(|err| {
                self.err(at, self.current_name(), format!("attribute '{key}': {err}"))
            })?;
            out.push((key, value.into_owned()));
        }
        Ok(out)
    }

    /// An element opened at `at` (`empty`: it closes itself) at `depth` (1 = the root).
    fn open(
        &mut self,
        e: &BytesStart,
        empty: bool,
        depth: usize,
        at: u64,
    ) -> Result<(), InputError> {
        let name = e.name().as_ref().to_string();
        match depth {
            1 => {
                if name != "osmChange" {
                    return Err(self.err(
                        at,
                        None,
                        format!("not an osmChange file: the root element is <{name}>"),
                    ));
                }
            }
            2 => {
                self.action = match name.as_str() {
                    "create" => Some(Action::Create),
                    "modify" => Some(Action::Modify),
                    "delete" => Some(Action::Delete),
                    // osmosis and some tools write a <bounds>; it changes no element.
                    "bounds" => None,
                    _ => {
                        return Err(self.err(
                            at,
                            None,
                            format!("unexpected <{name}> in <osmChange> (expected <create>, <modify> or <delete>)"),
                        ))
                    }
                };
                if empty {
                    self.action = None;
                }
            }
            3 => {
                let Some(action) = self.action else {
                    return Err(self.err(at, None, format!("unexpected <{name}> in <bounds>")));
                };
                let kind = match name.as_str() {
                    "node" => Kind::Node,
                    "way" => Kind::Way,
                    "relation" => Kind::Relation,
                    _ => {
                        return Err(self.err(
                            at,
                            None,
                            format!(
                            "unexpected <{name}> in <{}> (expected <node>, <way> or <relation>)",
                            action.name()
                        ),
                        ))
                    }
                };
                let attrs = self.attrs(e, at)?;
                let get = |k: &str| attrs.iter().find(|(n, _)| n == k).map(|(_, v)| v.as_str());
                let id = match get("id") {
                    None => {
                        return Err(self.err(at, Some(name), "no id attribute".into()));
                    }
                    Some(v) => v.trim().parse::<i64>().map_err(|_| {
                        self.err(
                            at,
                            Some(name.clone()),
                            format!("id '{v}' is not an integer"),
                        )
                    })?,
                };
                let mut cur = Current {
                    kind,
                    id,
                    pos: None,
                    refs: Vec::new(),
                    members: Vec::new(),
                    tags: Vec::new(),
                };
                if kind == Kind::Node && action != Action::Delete {
                    let elem = || Some(format!("node/{id}"));
                    let coord = |k: &str, max: i64| -> Result<f64, InputError> {
                        let v = get(k)
                            .ok_or_else(|| self.err(at, elem(), format!("no {k} attribute")))?;
                        let nano = nanodegrees(v).ok_or_else(|| {
                            self.err(at, elem(), format!("{k} '{v}' is not a number"))
                        })?;
                        if nano.abs() > max * 1_000_000_000 {
                            return Err(self.err(
                                at,
                                elem(),
                                format!("{k} {v} is outside -{max}..{max}"),
                            ));
                        }
                        Ok(super::records::degrees(nano))
                    };
                    let lat = coord("lat", 90)?;
                    let lon = coord("lon", 180)?;
                    cur.pos = Some((lon, lat));
                }
                self.current = Some(cur);
                if empty {
                    self.close_element();
                }
            }
            4 => {
                let Some(action) = self.action else {
                    return Err(self.err(at, None, format!("unexpected <{name}> in <bounds>")));
                };
                let elem = self.current_name();
                let Some(kind) = self.current.as_ref().map(|c| c.kind) else {
                    return Err(self.err(at, None, format!("unexpected <{name}>")));
                };
                if action == Action::Delete {
                    // A deletion needs only the id; what else it carries is not read.
                    return Ok(());
                }
                let attrs = self.attrs(e, at)?;
                let get = |k: &str| attrs.iter().find(|(n, _)| n == k).map(|(_, v)| v.as_str());
                let id_ref = || -> Result<i64, InputError> {
                    let v = get("ref").ok_or_else(|| {
                        self.err(at, elem.clone(), format!("<{name}> without ref"))
                    })?;
                    v.trim().parse::<i64>().map_err(|_| {
                        self.err(
                            at,
                            elem.clone(),
                            format!("<{name}> ref '{v}' is not an integer"),
                        )
                    })
                };
                match (name.as_str(), kind) {
                    ("tag", _) => {
                        let (Some(k), Some(v)) = (get("k"), get("v")) else {
                            return Err(self.err(at, elem, "<tag> without k or v".into()));
                        };
                        let tag = (k.to_string(), v.to_string());
                        if let Some(c) = &mut self.current {
                            c.tags.push(tag);
                        }
                    }
                    ("nd", Kind::Way) => {
                        let r = id_ref()?;
                        if let Some(c) = &mut self.current {
                            c.refs.push(r);
                        }
                    }
                    ("member", Kind::Relation) => {
                        let r = id_ref()?;
                        let t = match get("type") {
                            Some("node") => MemberType::Node,
                            Some("way") => MemberType::Way,
                            Some("relation") => MemberType::Relation,
                            other => {
                                return Err(self.err(
                                    at,
                                    elem,
                                    format!(
                                        "<member> of unknown type '{}'",
                                        other.unwrap_or_default()
                                    ),
                                ))
                            }
                        };
                        let role = get("role").unwrap_or_default().to_string();
                        if let Some(c) = &mut self.current {
                            c.members.push((t, r, role));
                        }
                    }
                    _ => {
                        return Err(self.err(
                            at,
                            elem,
                            format!("unexpected <{name}> in <{}>", kind.name()),
                        ))
                    }
                }
            }
            _ => {
                if self.action != Some(Action::Delete) {
                    return Err(self.err(
                        at,
                        self.current_name(),
                        format!("unexpected <{name}> nested inside another element"),
                    ));
                }
            }
        }
        Ok(())
    }

    /// The element being read is complete: it replaces what came before it.
    fn close_element(&mut self) {
        let (Some(c), Some(action)) = (self.current.take(), self.action) else {
            return;
        };
        let delete = action == Action::Delete;
        match c.kind {
            Kind::Node => {
                self.change
                    .nodes
                    .insert(c.id, if delete { None } else { c.pos });
            }
            Kind::Way => {
                self.change
                    .ways
                    .insert(c.id, (!delete).then_some((c.refs, c.tags)));
            }
            Kind::Relation => {
                self.change
                    .relations
                    .insert(c.id, (!delete).then_some((c.members, c.tags)));
            }
        }
    }
}

fn parse(path: &Path, data: &[u8]) -> Result<Change, InputError> {
    let mut p = Parser {
        path,
        data,
        change: Change::default(),
        action: None,
        current: None,
    };
    let text = std::str::from_utf8(data).map_err(|e| {
        p.err(
            e.valid_up_to() as u64,
            None,
            format!("not UTF-8 text (byte offset {})", e.valid_up_to()),
        )
    })?;
    let mut reader = Reader::from_str(text);
    reader.config_mut().check_end_names = true;
    let mut depth = 0usize;
    let mut root_done = false;
    loop {
        let before = reader.buffer_position();
        let ev = reader
            .read_event()
            .map_err(|e| p.err(reader.error_position(), p.current_name(), e.to_string()))?;
        match ev {
            Event::Start(ref e) | Event::Empty(ref e) => {
                if root_done {
                    return Err(p.err(before, None, "content after the root element".into()));
                }
                let empty = matches!(ev, Event::Empty(_));
                p.open(e, empty, depth + 1, before)?;
                if empty {
                    if depth == 0 {
                        root_done = true;
                    }
                } else {
                    depth += 1;
                }
            }
            Event::End(_) => {
                match depth {
                    3 => p.close_element(),
                    2 => p.action = None,
                    1 => root_done = true,
                    _ => {}
                }
                depth = depth.saturating_sub(1);
            }
            Event::Text(t) if depth == 0 && !AsRef::<str>::as_ref(&t).trim().is_empty() => {
                return Err(p.err(before, None, "text outside the root element".into()));
            }
            Event::Eof => break,
            _ => {}
        }
    }
    if depth > 0 || !root_done {
        return Err(p.err(
            data.len() as u64,
            p.current_name(),
            if root_done || depth > 0 {
                "unexpected end of file (truncated?): <osmChange> is not closed".into()
            } else {
                "not an osmChange file: no <osmChange> element".into()
            },
        ));
    }
    Ok(p.change)
}

/// A decimal coordinate (`-43.7312345`) in nanodegrees, exactly (digits past the ninth decimal
/// round half away from zero); other number forms (`4.3e1`) through f64. `None` when it is not
/// a finite number or overflows.
pub(super) fn nanodegrees(s: &str) -> Option<i64> {
    let s = s.trim();
    let (neg, digits) = match s.as_bytes().first() {
        Some(b'-') => (true, s.get(1..)?),
        Some(b'+') => (false, s.get(1..)?),
        _ => (false, s),
    };
    let (int, frac) = digits.split_once('.').unwrap_or((digits, ""));
    let plain = !(int.is_empty() && frac.is_empty())
        && int.bytes().all(|b| b.is_ascii_digit())
        && frac.bytes().all(|b| b.is_ascii_digit());
    if !plain {
        let x: f64 = s.parse().ok()?;
        let n = (x * 1e9).round();
        return (x.is_finite() && n.abs() < 9e18).then_some(n as i64);
    }
    let int = int.trim_start_matches('0');
    if int.len() > 9 {
        return None;
    }
    let whole: i64 = if int.is_empty() { 0 } else { int.parse().ok()? };
    let mut f = 0i64;
    let fb = frac.as_bytes();
    for k in 0..9 {
        f = f * 10 + fb.get(k).map_or(0, |b| i64::from(b - b'0'));
    }
    if fb.get(9).is_some_and(|&b| b >= b'5') {
        f += 1;
    }
    let n = whole * 1_000_000_000 + f;
    Some(if neg { -n } else { n })
}
