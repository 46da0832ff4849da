//! OSM XML (`.osm`, as JOSM, the Overpass API, osmium and the OSM API write it), plain or
//! compressed with gzip (`.osm.gz`) or bzip2 (`.osm.bz2`), read by the same three passes and
//! assembly as a PBF ([`super::Passes`]).
//!
//! The format is recognised by the file's content, not its name ([`detect`]): gzip by 1f 8b,
//! bzip2 by `BZh`, then XML by a `<` after an optional byte order mark and whitespace.
//!
//! Each pass streams the file again through quick-xml (nothing of it is held but what the pass
//! keeps, as with a PBF), so an XML file costs three parses; the passes after the first stop
//! early when the first found the file in the usual order (nodes, then ways, then relations).
//! Elements may come in any order. Skipped as if absent: JOSM's deleted objects
//! (`action="delete"`) and invisible ones (`visible="false"`, history files). Negative ids
//! (JOSM's new objects) are ids like any other. Attribute values are unescaped and normalised
//! as XML says (`&amp;`, `&#10;`); entities a DOCTYPE declares are not expanded, so a value
//! using one is an error (no entity expansion attack). An osmChange file is refused with a
//! pointer to `--osc`.
//!
//! Bounds on hostile input: one event of the parser (a tag with its attributes, a run of text,
//! a comment) is at most [`MAX_EVENT`] bytes and an element has at most [`MAX_CHILDREN`]
//! children, so memory stays bounded whatever the file (a gzip bomb only takes time); the file
//! must not change between the passes. Every error names the file, the line and byte offset
//! (in the decompressed XML) and the element where one is known. Never panics.

use std::cell::Cell;
use std::fs::File;
use std::io::{self, BufRead, BufReader, Read};
use std::time::SystemTime;

use quick_xml::events::{BytesStart, Event};
use quick_xml::{Reader, XmlVersion};

use super::osc::nanodegrees;
use super::*;

/// Largest parser event (a start tag with its attributes, a text, a comment), in bytes.
pub(super) const MAX_EVENT: u64 = 4 << 20;
/// Most children (`<nd>`, `<member>`, `<tag>`) of one element (the OSM API allows 2,000 nodes
/// a way and 32,000 members a relation).
pub(super) const MAX_CHILDREN: usize = 1 << 20;
/// Kept ways per [`WayBlock`], and a bound on a block's node ids (block offsets are u32).
const BLOCK_WAYS: usize = 1 << 14;
const BLOCK_REFS: usize = 1 << 24;
/// Bytes read from the start of the file (after decompression) to tell its format.
const HEAD: usize = 256;

/// How the file is compressed, from its magic bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Compression {
    Plain,
    Gzip,
    Bzip2,
}

impl Compression {
    fn of(head: &[u8]) -> Compression {
        if head.starts_with(&[0x1f, 0x8b]) {
            Compression::Gzip
        } else if head.starts_with(b"BZh") {
            Compression::Bzip2
        } else {
            Compression::Plain
        }
    }

    /// How a byte offset's text names the stream (`""` for a plain file).
    fn stream(self) -> &'static str {
        match self {
            Compression::Plain => "",
            Compression::Gzip => " of the decompressed gzip stream",
            Compression::Bzip2 => " of the decompressed bzip2 stream",
        }
    }
}

/// An OSM XML file, read pass by pass ([`Passes`]).
pub(super) struct XmlPasses {
    path: PathBuf,
    compression: Compression,
    /// The file's length and modification time when detected: each pass checks them.
    stamp: (u64, Option<SystemTime>),
    /// Set by the first pass, which reads the whole file: every node came before every way,
    /// every way before every relation.
    sorted: Cell<bool>,
}

/// What a file is, from its first bytes after decompression.
enum Content {
    Xml,
    Json,
    Other,
}

fn content_of(head: &[u8]) -> Content {
    let text = head.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(head);
    match text.iter().find(|b| !b.is_ascii_whitespace()) {
        Some(b'<') => Content::Xml,
        Some(b'{') => Content::Json,
        _ => Content::Other,
    }
}

/// Reads up to `HEAD` bytes.
fn head_of(r: &mut impl Read) -> io::Result<Vec<u8>> {
    let mut head = Vec::with_capacity(HEAD);
    r.take(HEAD as u64).read_to_end(&mut head)?;
    Ok(head)
}

fn xml_error(path: &Path, place: String, reason: impl Into<String>) -> InputError {
    InputError::OsmXml {
        path: path.to_path_buf(),
        place,
        reason: reason.into(),
    }
}

fn stamp_of(path: &Path) -> io::Result<(u64, Option<SystemTime>)> {
    let m = std::fs::metadata(path)?;
    Ok((m.len(), m.modified().ok()))
}

/// The OSM XML reader for `path` when its content is OSM XML (plain, gzip or bzip2), `None`
/// when it is not compressed and not XML (a PBF, or something the PBF reader names). A
/// compressed file that holds something else than XML is an error, as is Overpass JSON.
pub(super) fn detect(path: &Path) -> Result<Option<XmlPasses>, InputError> {
    // What cannot be opened or read (a directory, a missing file) the PBF reader reports.
    let Ok(mut file) = File::open(path) else {
        return Ok(None);
    };
    let Ok(head) = head_of(&mut file) else {
        return Ok(None);
    };
    let compression = Compression::of(&head);
    let xml = XmlPasses {
        path: path.to_path_buf(),
        compression,
        stamp: stamp_of(path).map_err(|source| InputError::Io {
            path: path.to_path_buf(),
            source,
        })?,
        sorted: Cell::new(false),
    };
    let inner = if compression == Compression::Plain {
        head
    } else {
        head_of(&mut xml.open()?).map_err(|e| {
            xml_error(
                path,
                format!("start{}", compression.stream()),
                format!("cannot decompress: {e}"),
            )
        })?
    };
    match content_of(&inner) {
        Content::Xml => Ok(Some(xml)),
        Content::Json => Err(xml_error(
            path,
            "line 1".into(),
            "JSON: Overpass JSON is not read by --osm (ask Overpass for XML, `[out:xml]`); \
             GeoJSON footprints are read with --footprints",
        )),
        Content::Other if compression == Compression::Plain => Ok(None),
        Content::Other => Err(xml_error(
            path,
            format!("start{}", compression.stream()),
            "compressed, but not OSM XML inside: decompress it first (a compressed PBF is read \
             once decompressed)",
        )),
    }
}

/// A `BufRead` that counts the lines and bytes consumed, and refuses to give more than
/// [`MAX_EVENT`] bytes between two calls of [`Counted::mark`] (one parser event).
struct Counted<R> {
    inner: R,
    offset: u64,
    lines: u64,
    event: u64,
}

impl<R: BufRead> Counted<R> {
    fn mark(&mut self) {
        self.event = 0;
    }
}

impl<R: BufRead> Read for Counted<R> {
    fn read(&mut self, out: &mut [u8]) -> io::Result<usize> {
        let n = {
            let b = self.fill_buf()?;
            let n = b.len().min(out.len());
            out[..n].copy_from_slice(&b[..n]);
            n
        };
        self.consume(n);
        Ok(n)
    }
}

impl<R: BufRead> BufRead for Counted<R> {
    fn fill_buf(&mut self) -> io::Result<&[u8]> {
        if self.event > MAX_EVENT {
            return Err(io::Error::new(
                io::ErrorKind::InvalidData,
                format!("more than {MAX_EVENT} bytes in one tag, text or comment"),
            ));
        }
        self.inner.fill_buf()
    }

    fn consume(&mut self, amt: usize) {
        if amt > 0 {
            // The bytes consumed are still in the inner buffer: no read happens here.
            if let Ok(b) = self.inner.fill_buf() {
                let b = &b[..amt.min(b.len())];
                self.lines += b.iter().filter(|&&c| c == b'\n').count() as u64;
            }
        }
        self.offset += amt as u64;
        self.event += amt as u64;
        self.inner.consume(amt);
    }
}

/// The kind of an OSM element, in the usual file order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Kind {
    Node,
    Way,
    Relation,
}

impl Kind {
    fn of(name: &str) -> Option<Kind> {
        match name {
            "node" => Some(Kind::Node),
            "way" => Some(Kind::Way),
            "relation" => Some(Kind::Relation),
            _ => None,
        }
    }

    fn name(self) -> &'static str {
        match self {
            Kind::Node => "node",
            Kind::Way => "way",
            Kind::Relation => "relation",
        }
    }
}

/// The element being read; its lists are reused from element to element.
#[derive(Default)]
struct Elem {
    id: i64,
    /// Nanodegrees of a node.
    lon: i64,
    lat: i64,
    refs: Vec<i64>,
    /// (is a way, id, role as `text[a..b]`).
    members: Vec<(bool, i64, (usize, usize))>,
    /// Tags as `text[a..b]` = `text[b..c]`.
    tags: Vec<(usize, usize, usize)>,
    text: String,
}

impl Elem {
    fn clear(&mut self, id: i64) {
        self.id = id;
        self.refs.clear();
        self.members.clear();
        self.tags.clear();
        self.text.clear();
    }

    fn tags(&self) -> impl Iterator<Item = (&str, &str)> {
        self.tags
            .iter()
            .map(|&(a, b, c)| (&self.text[a..b], &self.text[b..c]))
    }

    fn members(&self) -> impl Iterator<Item = (bool, i64, Option<&str>)> {
        self.members
            .iter()
            .map(|&(w, id, (a, b))| (w, id, Some(&self.text[a..b])))
    }

    fn children(&self) -> usize {
        self.refs.len() + self.members.len() + self.tags.len()
    }
}

/// One streaming parse of the file: which kinds the pass reads, where it is.
struct Scan<'a, R: BufRead> {
    xml: &'a XmlPasses,
    reader: Reader<Counted<R>>,
    /// The element read (depth 2) and whether the pass keeps it: of a wanted kind, neither
    /// deleted nor invisible.
    current: Option<(Kind, bool)>,
    elem: Elem,
    /// The latest kind opened, and whether the kinds came in order so far.
    last: Option<Kind>,
    sorted: bool,
}

impl<R: BufRead> Scan<'_, R> {
    fn err(&self, reason: impl Into<String>) -> InputError {
        let c = self.reader.get_ref();
        let mut place = format!(
            "line {} (byte {}{})",
            c.lines + 1,
            c.offset,
            self.xml.compression.stream()
        );
        if let Some((k, true)) = self.current {
            place.push_str(&format!(", {}/{}", k.name(), self.elem.id));
        }
        xml_error(&self.xml.path, place, reason)
    }

    /// The attributes of `e` as (name, unescaped value); names are ASCII in OSM XML.
    fn attrs(&self, e: &BytesStart) -> Result<Vec<(String, String)>, InputError> {
        let mut out = Vec::new();
        for a in e.attributes() {
            let a = a.map_err(|err| self.err(err.to_string()))?;
            let value = a.normalized_value(XmlVersion::Implicit1_0).map_err(|err| {
                let key = a.key.as_ref();
                self.err(format!("attribute '{key}': {err}"))
            })?;
            out.push((a.key.as_ref().to_string(), value.into_owned()));
        }
        Ok(out)
    }

    fn int(&self, what: &str, v: Option<&str>) -> Result<i64, InputError> {
        let v = v.ok_or_else(|| self.err(format!("no {what} attribute")))?;
        v.trim()
            .parse::<i64>()
            .map_err(|_| self.err(format!("{what} '{}' is not an integer", clip(v))))
    }

    /// A node, way or relation opens: its id, and a node's coordinates, when the pass wants it.
    fn open_element(
        &mut self,
        kind: Kind,
        e: &BytesStart,
        want: &[Kind],
    ) -> Result<(), InputError> {
        if self.last.is_some_and(|l| kind < l) {
            self.sorted = false;
        }
        self.last = self.last.max(Some(kind));
        self.elem.clear(0);
        self.current = Some((kind, false));
        if !want.contains(&kind) {
            return Ok(());
        }
        let attrs = self.attrs(e)?;
        let get = |k: &str| attrs.iter().find(|(n, _)| n == k).map(|(_, v)| v.as_str());
        let id = self.int("id", get("id"))?;
        self.elem.clear(id);
        // Named in errors from here on.
        self.current = Some((kind, true));
        let keep = get("action").map(str::trim) != Some("delete")
            && get("visible").map(str::trim) != Some("false");
        if keep && kind == Kind::Node {
            let coord = |k: &str| -> Result<i64, InputError> {
                let v = get(k).ok_or_else(|| self.err(format!("no {k} attribute")))?;
                nanodegrees(v).ok_or_else(|| self.err(format!("{k} '{}' is not a number", clip(v))))
            };
            let (lat, lon) = (coord("lat")?, coord("lon")?);
            (self.elem.lat, self.elem.lon) = (lat, lon);
        }
        self.current = Some((kind, keep));
        Ok(())
    }

    /// A child of a kept element: a tag, a way's node or a relation's member.
    fn open_child(&mut self, kind: Kind, e: &BytesStart) -> Result<(), InputError> {
        let name = e.name();
        let name = name.as_ref();
        if !matches!(
            (name, kind),
            ("tag", _) | ("nd", Kind::Way) | ("member", Kind::Relation)
        ) {
            // Overpass's <bounds>/<center> in elements, history's extras: nothing to read.
            return Ok(());
        }
        if self.elem.children() >= MAX_CHILDREN {
            return Err(self.err(format!("more than {MAX_CHILDREN} children")));
        }
        let attrs = self.attrs(e)?;
        let get = |k: &str| attrs.iter().find(|(n, _)| n == k).map(|(_, v)| v.as_str());
        match name {
            "tag" => {
                let (Some(k), Some(v)) = (get("k"), get("v")) else {
                    return Err(self.err("<tag> without k or v"));
                };
                let t = &mut self.elem.text;
                let a = t.len();
                t.push_str(k);
                let b = t.len();
                t.push_str(v);
                self.elem.tags.push((a, b, t.len()));
            }
            "nd" => {
                let r = self.int("<nd> ref", get("ref"))?;
                self.elem.refs.push(r);
            }
            _ => {
                let r = self.int("<member> ref", get("ref"))?;
                let way = match get("type").map(str::trim) {
                    Some("way") => true,
                    Some("node" | "relation") => false,
                    other => {
                        return Err(self.err(format!(
                            "<member> of unknown type '{}'",
                            clip(other.unwrap_or_default())
                        )))
                    }
                };
                let t = &mut self.elem.text;
                let a = t.len();
                t.push_str(get("role").unwrap_or_default());
                self.elem.members.push((way, r, (a, t.len())));
            }
        }
        Ok(())
    }
}

/// `v` cut to 40 characters for a message.
fn clip(v: &str) -> String {
    match v.char_indices().nth(40) {
        Some((i, _)) => format!("{}...", &v[..i]),
        None => v.to_string(),
    }
}

/// What a pass does with each kept element of its kinds.
type Visit<'v> = dyn FnMut(&Elem) + 'v;

impl XmlPasses {
    /// The decompressed stream of the file, opened afresh.
    fn open(&self) -> Result<Box<dyn BufRead>, InputError> {
        let file = File::open(&self.path).map_err(|source| InputError::Io {
            path: self.path.clone(),
            source,
        })?;
        let file = BufReader::with_capacity(1 << 16, file);
        Ok(match self.compression {
            Compression::Plain => Box::new(file),
            Compression::Gzip => Box::new(BufReader::with_capacity(
                1 << 16,
                flate2::bufread::MultiGzDecoder::new(file),
            )),
            Compression::Bzip2 => Box::new(BufReader::with_capacity(
                1 << 16,
                bzip2::bufread::MultiBzDecoder::new(file),
            )),
        })
    }

    /// Streams the file once, calling `visit` on every kept element of a kind in `want`. With
    /// `until`, stops at the first element of that kind or a later one when the file is known
    /// to be sorted. Returns whether the kinds came in order (meaningful after a whole read).
    fn scan(
        &self,
        want: &[Kind],
        until: Option<Kind>,
        visit: &mut Visit,
    ) -> Result<bool, InputError> {
        if stamp_of(&self.path).ok() != Some(self.stamp) {
            return Err(xml_error(
                &self.path,
                "between two passes".into(),
                "the file changed while it was read",
            ));
        }
        let counted = Counted {
            inner: self.open()?,
            offset: 0,
            lines: 0,
            event: 0,
        };
        let mut reader = Reader::from_reader(counted);
        reader.config_mut().check_end_names = true;
        let mut s = Scan {
            xml: self,
            reader,
            current: None,
            elem: Elem::default(),
            last: None,
            sorted: true,
        };
        let until = until.filter(|_| self.sorted.get());
        let mut buf = Vec::new();
        let mut depth = 0usize;
        let mut root_done = false;
        loop {
            buf.clear();
            s.reader.get_mut().mark();
            let ev = match s.reader.read_event_into(&mut buf) {
                Ok(ev) => ev,
                Err(e) => return Err(s.err(e.to_string())),
            };
            match ev {
                Event::Start(ref e) | Event::Empty(ref e) => {
                    if root_done {
                        return Err(s.err("content after the root element"));
                    }
                    depth += 1;
                    let stop = open(&mut s, e, depth, want, until)?;
                    if stop {
                        return Ok(s.sorted);
                    }
                    if matches!(ev, Event::Empty(_)) {
                        close(&mut s, depth, &mut root_done, visit);
                        depth -= 1;
                    }
                }
                Event::End(_) => {
                    close(&mut s, depth, &mut root_done, visit);
                    depth = depth.saturating_sub(1);
                }
                Event::Text(ref t) if depth == 0 && !AsRef::<str>::as_ref(t).trim().is_empty() => {
                    return Err(s.err("text outside the root element"));
                }
                Event::Eof => break,
                _ => {}
            }
        }
        if depth > 0 || !root_done {
            return Err(s.err(if depth > 0 {
                "unexpected end of file (truncated?): <osm> is not closed"
            } else {
                "no <osm> element"
            }));
        }
        Ok(s.sorted)
    }
}

/// An element opens at `depth` (1 = the root); whether the pass stops here (`until`).
fn open<R: BufRead>(
    s: &mut Scan<R>,
    e: &BytesStart,
    depth: usize,
    want: &[Kind],
    until: Option<Kind>,
) -> Result<bool, InputError> {
    let name = e.name();
    let name = name.as_ref();
    match depth {
        1 if name == "osm" => {}
        1 if name == "osmChange" => {
            return Err(s.err(
                "an osmChange file, not an extract: give it with `--osc` beside the extract \
                 (`--osm`)",
            ))
        }
        1 => {
            return Err(s.err(format!(
                "not an OSM file: the root element is <{}>",
                clip(name)
            )));
        }
        2 => {
            // <bounds>, <note>, <meta>, <remark>, <changeset>: nothing to read.
            if let Some(kind) = Kind::of(name) {
                if until.is_some_and(|u| kind >= u) {
                    return Ok(true);
                }
                s.open_element(kind, e, want)?;
            }
        }
        3 => {
            if let Some((kind, true)) = s.current {
                s.open_child(kind, e)?;
            }
        }
        _ => {}
    }
    Ok(false)
}

/// The element at `depth` closes: a kept node, way or relation goes to `visit`.
fn close<R: BufRead>(s: &mut Scan<R>, depth: usize, root_done: &mut bool, visit: &mut Visit) {
    match depth {
        1 => *root_done = true,
        2 => {
            if let Some((_, true)) = s.current.take() {
                visit(&s.elem);
            }
        }
        _ => {}
    }
}

impl Passes for XmlPasses {
    fn relations(&self) -> Result<Option<Vec<Vec<RelRec>>>, InputError> {
        let mut rels = Vec::new();
        let sorted = self.scan(&[Kind::Relation], None, &mut |e| {
            rels.extend(relation_rec(e.id, || e.tags(), e.members()));
        })?;
        self.sorted.set(sorted);
        Ok(Some(vec![rels]))
    }

    fn ways(
        &self,
        member_ways: &[i64],
        interner: &TagInterner,
    ) -> Result<Option<Vec<WaysOfBlock>>, InputError> {
        let mut blocks = Vec::new();
        let mut block = WayBlock::default();
        self.scan(&[Kind::Way], Some(Kind::Relation), &mut |e| {
            let refs = e.refs.iter().copied();
            block.keep_way(e.id, || e.tags(), refs, member_ways, interner);
            if block.ways.len() >= BLOCK_WAYS || block.refs.len() >= BLOCK_REFS {
                blocks.push(std::mem::take(&mut block));
            }
        })?;
        blocks.push(block);
        Ok(Some(
            blocks
                .into_iter()
                .map(|b| {
                    let needed = b.needed();
                    (b, needed)
                })
                .collect(),
        ))
    }

    fn nodes(&self, needed: &[i64]) -> Result<Option<Vec<NodeBlock>>, InputError> {
        let mut found = Found::default();
        let mut addresses = Vec::new();
        let mut cursor = NeededCursor::new(needed);
        self.scan(&[Kind::Node], Some(Kind::Way), &mut |e| {
            if let Some(j) = cursor.find(e.id) {
                found.push(j, e.lon, e.lat);
            }
            // Address and entrance nodes (issue 45).
            if let Some(a) = addr_street_of(e.tags()) {
                addresses.push((e.lon, e.lat, a));
            }
        })?;
        found.sort();
        Ok(Some(vec![(found, addresses)]))
    }
}
