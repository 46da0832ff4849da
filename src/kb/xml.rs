//! The knowledge-base XML reader: the thesis format (seed 003 annex and §3.6.2), leniently.
//!
//! Reading runs in three steps:
//! 1. a textual pre-pass repairs the annex's markup slips that no XML parser accepts: a missing
//!    `<` before a known element name at the start of a text run, whitespace between `<` and the
//!    name, an attribute value without quotes (`lon=47,5167"`), and a value whose closing quote
//!    was lost so that it swallowed the next attribute's name (`maxrotation="\n minFloors="1"`).
//!    Line breaks are never added or removed, so line numbers stay those of the file;
//! 2. quick-xml parses the result into a small element tree. What it rejects is a [`KbError`]
//!    with `file:line:col`. DTDs are refused outright (never expanded) and only the five
//!    predefined entities and character references are understood;
//! 3. the tree is read into zones. Values are trimmed, decimal commas accepted (`0,3`), empty
//!    values mean absent, attribute names are case-insensitive, roof spellings go through
//!    [`RoofShape::parse`] and colours through [`Color::parse`].
//!
//! Every repair is returned as a [`KbRepair`] with its line; nothing is dropped silently.
//!
//! **Units.** `dist` is read as a radius in **kilometres**, as the SPEC says. The thesis never
//! states its unit, and its values (France 5, Midi-Pyrénées 1.1, Toulouse 0.8, districts 0.03)
//! look like decimal degrees at country level; a thesis KB read here therefore gets very small
//! circles. Our shipped `knowledge_base/kb.xml` gives radii in km.

use std::collections::{BTreeMap, BTreeSet};

use super::dom::{parse_tree, Elem, LineIndex, MAX_FILE_BYTES};
pub use super::dom::{KbError, KbRepair, ReadMode};
use super::polygon::ZonePolygon;
use super::{
    Appearance, Circle, OpeningSplit, OpeningTree, SplitAxis, Values, WindowHeight, Zone, ZoneKind,
};
use crate::color::Color;
use crate::model::RoofShape;

/// Element names the pre-pass may add a missing `<` in front of.
const KNOWN_ELEMENTS: [&str; 16] = [
    "earth",
    "country",
    "region",
    "town",
    "district",
    "info",
    "location",
    "appearance",
    "values",
    "opening",
    "split",
    "elements",
    "ruleset",
    "selex",
    "zone",
    "polygon",
];

fn is_name_start(c: u8) -> bool {
    c.is_ascii_alphabetic() || c == b'_' || c == b':'
}

fn is_name_char(c: u8) -> bool {
    c.is_ascii_alphanumeric() || matches!(c, b'_' | b':' | b'-' | b'.')
}

/// Step 1: textual repairs. Keeps every line break where it was.
fn prepass(text: &str, repairs: &mut Vec<KbRepair>) -> String {
    let idx = LineIndex::new(text);
    let b = text.as_bytes();
    let mut out = String::with_capacity(text.len() + 16);
    let mut i = 0;
    let mut run_start = true; // at the start of a text run (after a tag or at the start)
    while i < b.len() {
        let rest = &text[i..];
        if rest.starts_with("<!--")
            || rest.starts_with("<![CDATA[")
            || rest.starts_with("<?")
            || rest.starts_with("<!")
        {
            let end_pat = if rest.starts_with("<!--") {
                "-->"
            } else if rest.starts_with("<![CDATA[") {
                "]]>"
            } else if rest.starts_with("<?") {
                "?>"
            } else {
                ">"
            };
            let end = rest.find(end_pat).map_or(rest.len(), |e| e + end_pat.len());
            out.push_str(&rest[..end]);
            i += end;
            run_start = true;
            continue;
        }
        if b[i] == b'<' {
            // `<` or `</`, possibly followed by whitespace before the name.
            let slash = b.get(i + 1) == Some(&b'/');
            let head = if slash { 2 } else { 1 };
            let mut j = i + head;
            while j < b.len() && b[j].is_ascii_whitespace() {
                j += 1;
            }
            if j > i + head && j < b.len() && is_name_start(b[j]) {
                repairs.push(KbRepair {
                    line: idx.line(i),
                    what: "removed whitespace between '<' and the element name".into(),
                });
                out.push_str(&text[i + head..j]);
                out.push_str(&text[i..i + head]);
            } else {
                out.push_str(&text[i..j]);
            }
            i = scan_tag(text, j, &mut out, &idx, repairs);
            run_start = true;
            continue;
        }
        if run_start {
            // Start of a text run: look for `name attr=...>` missing its `<`.
            let ws = rest.len() - rest.trim_start().len();
            let body = &rest[ws..];
            let name_len = body.bytes().take_while(|c| is_name_char(*c)).count();
            let name = &body[..name_len];
            let after = body.as_bytes().get(name_len).copied();
            let run_end = body.find('<').unwrap_or(body.len());
            if name_len > 0
                && KNOWN_ELEMENTS.iter().any(|k| k.eq_ignore_ascii_case(name))
                && matches!(after, Some(c) if c.is_ascii_whitespace() || c == b'/' || c == b'>')
                && body[..run_end].contains('>')
            {
                out.push_str(&rest[..ws]);
                repairs.push(KbRepair {
                    line: idx.line(i + ws),
                    what: format!("added the missing '<' before element '{name}'"),
                });
                out.push('<');
                i = scan_tag(text, i + ws, &mut out, &idx, repairs);
                continue;
            }
            run_start = false;
        }
        let ch_len = rest.chars().next().map_or(1, char::len_utf8);
        out.push_str(&rest[..ch_len]);
        i += ch_len;
    }
    out
}

/// Copies one tag from `start` (just after `<` or `</` and any repaired whitespace) to its `>`
/// inclusive, repairing attribute quoting. Returns the offset after the tag.
fn scan_tag(
    text: &str,
    start: usize,
    out: &mut String,
    idx: &LineIndex,
    repairs: &mut Vec<KbRepair>,
) -> usize {
    let b = text.as_bytes();
    let mut i = start;
    let mut last_name = String::new();
    while i < b.len() {
        let c = b[i];
        match c {
            b'>' => {
                out.push('>');
                return i + 1;
            }
            b'<' => return i, // a new tag starts: leave it to the parser to complain
            b'"' | b'\'' => {
                let close = text[i + 1..].find(c as char).map(|e| i + 1 + e);
                let Some(close) = close else {
                    out.push_str(&text[i..]);
                    return b.len();
                };
                let value = &text[i + 1..close];
                if swallowed_name(value) {
                    // `attr="<newline> next=` : the value and its closing quote were lost.
                    repairs.push(KbRepair {
                        line: idx.line(i),
                        what: format!(
                            "attribute '{last_name}' lost its closing quote; read as empty"
                        ),
                    });
                    out.push_str("\"\"");
                    i += 1;
                    continue;
                }
                out.push_str(&text[i..=close]);
                i = close + 1;
            }
            b'=' => {
                out.push('=');
                i += 1;
                while i < b.len() && b[i].is_ascii_whitespace() {
                    out.push(b[i] as char);
                    i += 1;
                }
                if i < b.len() && b[i] != b'"' && b[i] != b'\'' {
                    let vstart = i;
                    while i < b.len()
                        && !b[i].is_ascii_whitespace()
                        && !matches!(b[i], b'"' | b'\'' | b'>' | b'<')
                    {
                        if b[i] == b'/' && b.get(i + 1) == Some(&b'>') {
                            break;
                        }
                        i += 1;
                    }
                    let value = &text[vstart..i];
                    if i < b.len() && b[i] == b'"' {
                        i += 1; // the stray closing quote
                    }
                    repairs.push(KbRepair {
                        line: idx.line(vstart),
                        what: format!("added missing quotes around the value of '{last_name}'"),
                    });
                    out.push('"');
                    out.push_str(&value.replace('&', "&amp;"));
                    out.push('"');
                }
            }
            _ if is_name_start(c) => {
                let s = i;
                while i < b.len() && is_name_char(b[i]) {
                    i += 1;
                }
                last_name = text[s..i].to_string();
                out.push_str(&text[s..i]);
            }
            _ => {
                let ch_len = text[i..].chars().next().map_or(1, char::len_utf8);
                out.push_str(&text[i..i + ch_len]);
                i += ch_len;
            }
        }
    }
    b.len()
}

/// A quoted "value" that is really whitespace with a line break, then `name=`: the closing quote
/// of the previous value was lost.
fn swallowed_name(value: &str) -> bool {
    let t = value.trim_start();
    if !value.contains('\n') || !t.ends_with('=') {
        return false;
    }
    let name = t[..t.len() - 1].trim_end();
    !name.is_empty()
        && name.bytes().next().is_some_and(is_name_start)
        && name.bytes().all(is_name_char)
}

/// Reads zones from KB text leniently: zone 0 is earth, parents before children. Used by
/// [`super::KnowledgeBase::parse_str`].
/// Whether a colour is spelt as the clean format writes it: `#rrggbb`, or a lower-case name.
fn clean_color(v: &str) -> bool {
    let hex = v
        .strip_prefix('#')
        .is_some_and(|h| h.len() == 6 && h.bytes().all(|b| b.is_ascii_hexdigit()));
    hex || (v.bytes().all(|b| b.is_ascii_lowercase()) && Color::parse(v).is_some())
}

#[cfg(test)]
pub(crate) fn read_zones(text: &str, file: &str) -> Result<(Vec<Zone>, Vec<KbRepair>), KbError> {
    read_zones_with(text, file, ReadMode::Lenient)
}

/// Reads zones from KB text in the given mode. In strict mode the repair pre-pass is skipped,
/// the element tree is checked against the clean format ([`super::strict`]) and any repair the
/// zone reader would still make is an error; the returned repairs are then always empty.
pub(crate) fn read_zones_with(
    text: &str,
    file: &str,
    mode: ReadMode,
) -> Result<(Vec<Zone>, Vec<KbRepair>), KbError> {
    if text.len() as u64 > MAX_FILE_BYTES {
        return Err(KbError::Limit {
            file: file.to_string(),
            line: 1,
            col: 1,
            message: format!(
                "{} bytes is more than the {MAX_FILE_BYTES}-byte cap on knowledge-base files",
                text.len()
            ),
        });
    }
    let mut repairs = Vec::new();
    let root = match mode {
        ReadMode::Lenient => {
            let fixed = prepass(text, &mut repairs);
            parse_tree(&fixed, file, mode)?
        }
        ReadMode::Strict => {
            let root = parse_tree(text, file, mode)?;
            super::strict::validate(&root, file)?;
            root
        }
    };
    if !root.name.eq_ignore_ascii_case("earth") {
        return Err(KbError::Structure {
            file: file.to_string(),
            line: root.line,
            message: format!("the root element must be <earth>, found <{}>", root.name),
        });
    }
    let mut r = ZoneReader {
        zones: Vec::new(),
        repairs,
    };
    r.zone(&root, None, 0, "earth".to_string());
    // Stable: repairs of one line keep the order they were found in.
    r.repairs.sort_by_key(|r| r.line);
    if mode == ReadMode::Strict {
        if let Some(first) = r.repairs.first() {
            // The checks above catch every lexical problem at its column; what remains is a
            // semantic one (an incomplete circle, an opening that is not a tree...) known by
            // line: point at the line's first non-blank character.
            let col = text
                .lines()
                .nth(first.line.saturating_sub(1))
                .map_or(1, |l| {
                    l.chars().take_while(|c| c.is_whitespace()).count() + 1
                });
            return Err(KbError::Strict {
                file: file.to_string(),
                line: first.line,
                col,
                message: first.what.clone(),
            });
        }
    }
    Ok((r.zones, r.repairs))
}

struct ZoneReader {
    zones: Vec<Zone>,
    repairs: Vec<KbRepair>,
}

/// Circle parts gathered from `<info>` and `<location>`.
#[derive(Default)]
struct CircleParts {
    lat: Option<f64>,
    lon: Option<f64>,
    dist: Option<f64>,
}

/// The kinds of an appearance's `building` attribute: comma- or space-separated OSM
/// `building=*` values, trimmed and lower-cased, duplicates and empty entries dropped, in order.
pub(crate) fn building_kinds(v: &str) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for k in v.split([',', ' ', '\t', '\n', ';']) {
        let k = k.trim().to_ascii_lowercase();
        if !k.is_empty() && !out.contains(&k) {
            out.push(k);
        }
    }
    out
}

impl ZoneReader {
    /// An appearance's `area`, `attached` and `density` conditions; an unreadable one is
    /// left out with a note (the appearance then applies there too).
    fn conditions(&mut self, el: &Elem, when: &mut super::values::Conditions) {
        if let Some((_, v, l)) = el.attr("area") {
            when.area = super::values::Conditions::parse_area(v);
            if when.area.is_none() {
                self.note(
                    *l,
                    format!("area=\"{v}\" is not lo-hi in m² (60-250, 60-, -60): ignored"),
                );
            }
        }
        if let Some((_, v, l)) = el.attr("attached") {
            when.attached = match v.trim().to_ascii_lowercase().as_str() {
                "yes" | "true" | "1" => Some(true),
                "no" | "false" | "0" => Some(false),
                _ => {
                    self.note(*l, format!("attached=\"{v}\" is not yes or no: ignored"));
                    None
                }
            };
        }
        if let Some((_, v, l)) = el.attr("density") {
            for w in v.split([',', ' ']).map(str::trim).filter(|w| !w.is_empty()) {
                match crate::model::Density::parse(&w.to_ascii_lowercase()) {
                    Some(d) if !when.density.contains(&d) => when.density.push(d),
                    Some(_) => {}
                    None => self.note(
                        *l,
                        format!("density \"{w}\" is not low, medium or high: ignored"),
                    ),
                }
            }
        }
    }

    fn note(&mut self, line: usize, what: impl Into<String>) {
        self.repairs.push(KbRepair {
            line,
            what: what.into(),
        });
    }

    fn zone(&mut self, el: &Elem, parent: Option<usize>, depth: usize, path: String) {
        let me = self.zones.len();
        let name = path.rsplit('/').next().unwrap_or("earth").to_string();
        self.zones.push(Zone {
            name,
            kind: if parent.is_none() {
                ZoneKind::Earth
            } else {
                ZoneKind::from_element(&el.name)
            },
            path: path.clone(),
            parent,
            depth,
            circle: None,
            polygons: Vec::new(),
            info: Values::default(),
            appearances: Vec::new(),
            line: el.line,
        });
        let mut info = Values::default();
        let mut circle = CircleParts::default();
        let mut seen_info = false;
        let mut appearances = Vec::new();
        let mut polygons = Vec::new();
        for child in &el.children {
            let lname = child.name.to_ascii_lowercase();
            match lname.as_str() {
                "info" | "location" => {
                    if lname == "info" {
                        if seen_info {
                            self.note(
                                child.line,
                                "second <info> in one zone: merged, later values win",
                            );
                        }
                        seen_info = true;
                    }
                    let v = self.values(child, true, &mut circle);
                    info.overlay(&v);
                }
                "appearance" => appearances.push(self.appearance(child)),
                "polygon" => match child.attr("points") {
                    Some((_, pts, line)) => match ZonePolygon::parse(pts) {
                        Ok(p) => polygons.push(p),
                        Err(e) => self.note(*line, format!("polygon ignored: {e}")),
                    },
                    None => self.note(child.line, "<polygon> without points ignored"),
                },
                _ if child.attr("designation").is_some()
                    || matches!(lname.as_str(), "country" | "region" | "town" | "district") =>
                {
                    let mut cname = child
                        .attr("designation")
                        .map(|(_, v, _)| v.trim().to_string())
                        .unwrap_or_default();
                    if cname.is_empty() {
                        cname = format!("{}{}", lname, self.zones.len());
                        self.note(
                            child.line,
                            format!("<{}> without designation: named '{cname}'", child.name),
                        );
                    }
                    if cname.contains('/') {
                        cname = cname.replace('/', "-");
                        self.note(
                            child.line,
                            format!("'/' in designation replaced: '{cname}'"),
                        );
                    }
                    let cpath = format!("{path}/{cname}");
                    if self.zones.iter().any(|z| z.path == cpath) {
                        self.note(child.line, format!("zone path '{cpath}' appears twice; the first wins in lookups by path"));
                    }
                    self.zone(child, Some(me), depth + 1, cpath);
                }
                _ => self.note(
                    child.line,
                    format!("unknown element <{}> in a zone ignored", child.name),
                ),
            }
        }
        let circle = self.circle(circle, el);
        if let Some(z) = self.zones.get_mut(me) {
            z.info = info;
            z.circle = circle;
            z.appearances = appearances;
            z.polygons = polygons;
        }
    }

    fn circle(&mut self, c: CircleParts, el: &Elem) -> Option<Circle> {
        match (c.lat, c.lon, c.dist) {
            (None, None, None) => None,
            (Some(lat), Some(lon), Some(dist)) => {
                if !(-90.0..=90.0).contains(&lat) || !(-180.0..=180.0).contains(&lon) {
                    self.note(
                        el.line,
                        format!("zone circle centre ({lat}, {lon}) out of range: circle ignored"),
                    );
                    None
                } else if dist <= 0.0 {
                    self.note(
                        el.line,
                        format!("zone radius {dist} km is not positive: circle ignored"),
                    );
                    None
                } else {
                    Some(Circle {
                        lat,
                        lon,
                        radius_km: dist,
                    })
                }
            }
            _ => {
                self.note(
                    el.line,
                    "zone circle needs lat, lon and dist: incomplete circle ignored",
                );
                None
            }
        }
    }

    fn appearance(&mut self, el: &Elem) -> Appearance {
        let mut app = Appearance {
            proba: None,
            values: Values::default(),
            opening: None,
            ruleset: None,
            selex: None,
            buildings: Vec::new(),
            when: Default::default(),
            line: el.line,
        };
        if let Some((_, v, _)) = el.attr("building") {
            app.buildings = building_kinds(v);
        }
        self.conditions(el, &mut app.when);
        let mut dummy = CircleParts::default();
        let mut proba = el.attr("proba").and_then(|(k, v, l)| self.number(k, v, *l));
        let mut seen_values = false;
        for child in &el.children {
            match child.name.to_ascii_lowercase().as_str() {
                "values" => {
                    if seen_values {
                        self.note(
                            child.line,
                            "second <values> in one appearance: merged, later values win",
                        );
                    }
                    seen_values = true;
                    if let Some((k, v, l)) = child.attr("proba") {
                        proba = self.number(k, v, *l).or(proba);
                    }
                    let v = self.values(child, false, &mut dummy);
                    app.values.overlay(&v);
                }
                "opening" => {
                    if app.opening.is_some() {
                        self.note(child.line, "second <opening> in one appearance ignored");
                    } else {
                        app.opening = self.opening(child);
                    }
                }
                "ruleset" => match child
                    .attr("file")
                    .and_then(|(k, v, l)| self.clean(k, v, *l))
                {
                    Some(f) => app.ruleset = Some(f),
                    None => self.note(child.line, "<ruleset> without a file ignored"),
                },
                "selex" => match child
                    .attr("file")
                    .and_then(|(k, v, l)| self.clean(k, v, *l))
                {
                    Some(f) if app.selex.is_none() => app.selex = Some(f),
                    Some(_) => self.note(child.line, "second <selex> in one appearance ignored"),
                    None => self.note(child.line, "<selex> without a file ignored"),
                },
                _ => self.note(
                    child.line,
                    format!("unknown element <{}> in an appearance ignored", child.name),
                ),
            }
        }
        if let Some(p) = proba {
            if (0.0..=1.0).contains(&p) {
                app.proba = Some(p);
            } else {
                self.note(
                    el.line,
                    format!("proba {p} outside 0..1 ignored (treated as absent)"),
                );
            }
        }
        app
    }

    /// Trims, and treats empty as absent; both are noted.
    fn clean(&mut self, key: &str, raw: &str, line: usize) -> Option<String> {
        let t = raw.trim();
        if t.is_empty() {
            self.note(line, format!("empty value of '{key}' treated as absent"));
            return None;
        }
        if t.len() != raw.len() {
            self.note(
                line,
                format!("trimmed spaces/line breaks around the value of '{key}'"),
            );
        }
        Some(t.to_string())
    }

    fn number(&mut self, key: &str, raw: &str, line: usize) -> Option<f64> {
        let t = self.clean(key, raw, line)?;
        let s = if !t.contains('.') && t.matches(',').count() == 1 {
            self.note(
                line,
                format!("decimal comma in '{key}'=\"{t}\" read as a point"),
            );
            t.replace(',', ".")
        } else {
            t.clone()
        };
        match s.parse::<f64>() {
            Ok(x) if x.is_finite() => Some(x),
            _ => {
                self.note(line, format!("unreadable number '{key}'=\"{t}\" ignored"));
                None
            }
        }
    }

    fn count(&mut self, key: &str, raw: &str, line: usize) -> Option<u32> {
        let x = self.number(key, raw, line)?;
        if !(0.0..=10_000.0).contains(&x) {
            self.note(line, format!("'{key}'={x} out of range ignored"));
            return None;
        }
        if x.fract() != 0.0 {
            self.note(line, format!("'{key}'={x} rounded to a whole number"));
        }
        Some(x.round() as u32)
    }

    fn positive(&mut self, key: &str, raw: &str, line: usize) -> Option<f64> {
        let x = self.number(key, raw, line)?;
        if x > 0.0 {
            Some(x)
        } else {
            self.note(line, format!("'{key}'={x} must be positive: ignored"));
            None
        }
    }

    fn color(&mut self, key: &str, raw: &str, line: usize) -> Option<Color> {
        let t = self.clean(key, raw, line)?;
        let c = Color::parse(&t);
        match c {
            None => self.note(line, format!("unknown colour '{key}'=\"{t}\" ignored")),
            // The clean format's spellings (`#rrggbb`, a lower-case name) read as they are;
            // any other (`#rgb`, `AliceBlue`, a thesis `r;g;b` triple) is a repair, listed.
            Some(c) if !clean_color(&t) => self.note(
                line,
                format!("colour '{key}'=\"{t}\" read as {}", c.to_hex()),
            ),
            Some(_) => {}
        }
        c
    }

    /// Reads the descriptor attributes of an `<info>`, `<location>` or `<values>` element.
    fn values(&mut self, el: &Elem, zone_level: bool, circle: &mut CircleParts) -> Values {
        let mut v = Values::default();
        let mut seen: BTreeSet<String> = BTreeSet::new();
        for (key, raw, line) in &el.attrs {
            let (key, line) = (key.as_str(), *line);
            let lk = key.to_ascii_lowercase();
            if !seen.insert(lk.clone()) {
                self.note(
                    line,
                    format!(
                        "attribute '{key}' given twice (names are case-insensitive): the last wins"
                    ),
                );
            }
            match lk.as_str() {
                "lat" | "lon" | "dist" if zone_level => {
                    let x = self.number(key, raw, line);
                    match lk.as_str() {
                        "lat" => circle.lat = x.or(circle.lat),
                        "lon" => circle.lon = x.or(circle.lon),
                        _ => circle.dist = x.or(circle.dist),
                    }
                }
                "designation" | "proba" => {} // read by the caller
                "color" | "colour" => v.wall_color = self.color(key, raw, line),
                "material" => v.material = self.clean(key, raw, line),
                "nbfloor" | "nbfloors" | "floors" => v.storeys = self.count(key, raw, line),
                "minfloors" => v.min_floors = self.count(key, raw, line),
                "maxfloors" => v.max_floors = self.count(key, raw, line),
                "minheight" => v.min_height = self.positive(key, raw, line),
                "maxheight" => v.max_height = self.positive(key, raw, line),
                "floorsize" | "floorheight" => v.floor_height = self.positive(key, raw, line),
                "rooftype" | "bdrooftype" | "roof" | "roofshape" => {
                    if let Some(t) = self.clean(key, raw, line) {
                        match RoofShape::parse(&t) {
                            Some(r) => {
                                if t.to_ascii_lowercase() != r.osm_name() {
                                    self.note(line, format!("roof '{t}' read as {}", r.osm_name()));
                                }
                                v.roof = Some(r);
                            }
                            None => self
                                .note(line, format!("unknown roof type '{key}'=\"{t}\" ignored")),
                        }
                    }
                }
                "roofangle" => {
                    v.roof_angle = self
                        .number(key, raw, line)
                        .filter(|a| (0.0..90.0).contains(a));
                }
                "roofcolor" | "roofcolour" => v.roof_color = self.color(key, raw, line),
                "doorcol" | "doorcolor" | "doorcolour" => v.door_color = self.color(key, raw, line),
                "openingcol" | "openingcolor" | "openingcolour" => {
                    v.window_color = self.color(key, raw, line)
                }
                "windowfcolor" | "framecolor" | "framecolour" => {
                    v.frame_color = self.color(key, raw, line)
                }
                "windowcolor" | "windowcolour" => {
                    self.note(line, format!("'{key}' (thesis Madagascar spelling) read as the frame colour windowfcolor"));
                    v.frame_color = self.color(key, raw, line);
                }
                "windowheight" => {
                    if let Some(t) = self.clean(key, raw, line) {
                        v.window_height = WindowHeight::parse(&t);
                        if v.window_height.is_none() {
                            self.note(
                                line,
                                format!(
                                    "unknown window height '{t}' ignored (tall, short, irregular)"
                                ),
                            );
                        }
                    }
                }
                "windowwidth" => v.window_width = self.positive(key, raw, line),
                "doorwidth" => v.door_width = self.positive(key, raw, line),
                "doorheight" => v.door_height = self.positive(key, raw, line),
                "minopeningwidth" => v.min_opening_width = self.positive(key, raw, line),
                "windowstyle" => {
                    v.window_style = self.clean(key, raw, line).map(|s| s.to_ascii_lowercase())
                }
                "windowmaterial" => {
                    v.window_material = self.clean(key, raw, line).map(|s| s.to_ascii_lowercase())
                }
                "maxrotation" => v.max_rotation = self.number(key, raw, line),
                "balconies" => v.balconies = self.number(key, raw, line),
                "cornice" => v.cornice = self.positive(key, raw, line),
                "corniceheight" => v.cornice_height = self.positive(key, raw, line),
                "eaves" => v.eaves = self.positive(key, raw, line),
                "infer" if zone_level => {
                    if let Some(t) = self.clean(key, raw, line) {
                        v.infer = crate::model::Inference::parse(&t);
                        if v.infer.is_none() {
                            self.note(
                                line,
                                format!(
                                    "unknown infer '{t}' ignored (none, all, or levels,roof,colour)"
                                ),
                            );
                        }
                    }
                }
                "programme" | "program" => {
                    if let Some(t) = self.clean(key, raw, line) {
                        v.programme = crate::model::Programme::parse(&t);
                        if v.programme.is_none() {
                            self.note(
                                line,
                                format!(
                                    "unknown programme '{t}' ignored (house, apartments, office, retail, openplan)"
                                ),
                            );
                        }
                    }
                }
                _ => {
                    if let Some(t) = self.clean(key, raw, line) {
                        self.note(
                            line,
                            format!("unknown attribute '{key}' kept as an extra value"),
                        );
                        v.extra.insert(lk.clone(), t);
                    }
                }
            }
        }
        if let Some(a) = el.attr("roofangle") {
            if v.roof_angle.is_none() && !a.1.trim().is_empty() {
                self.note(
                    a.2,
                    format!(
                        "roof angle \"{}\" outside 0..90 degrees ignored",
                        a.1.trim()
                    ),
                );
            }
        }
        v
    }

    /// Reads an `<opening>`; `None` (noted) when it does not form a tree.
    fn opening(&mut self, el: &Elem) -> Option<OpeningTree> {
        let mut splits: Vec<OpeningSplit> = Vec::new();
        let mut root: Option<String> = None;
        let mut listed_terms: Vec<String> = Vec::new();
        let id = |s: &str| s.trim().to_string();
        for child in &el.children {
            match child.name.to_ascii_lowercase().as_str() {
                "split" => {
                    let axis = match child
                        .attr("axis")
                        .map(|a| a.1.trim().to_ascii_uppercase())
                        .as_deref()
                    {
                        Some("X") => SplitAxis::X,
                        Some("Y") => SplitAxis::Y,
                        Some("Z") => SplitAxis::Z,
                        other => {
                            self.note(
                                child.line,
                                format!("split axis {other:?} is not X, Y or Z: split ignored"),
                            );
                            continue;
                        }
                    };
                    let parent = child.attr("parent").map(|a| id(&a.1)).unwrap_or_default();
                    let children: Vec<String> = child
                        .attr("children")
                        .map(|a| {
                            a.1.split(['|', ','])
                                .map(id)
                                .filter(|s| !s.is_empty())
                                .collect()
                        })
                        .unwrap_or_default();
                    let raw_vals = child
                        .attr("splitvalues")
                        .map(|a| a.1.clone())
                        .unwrap_or_default();
                    let sep = if raw_vals.contains(';') || raw_vals.contains('|') {
                        [';', '|']
                    } else {
                        [',', ',']
                    };
                    let vals: Vec<Option<f64>> = raw_vals
                        .split(sep)
                        .map(str::trim)
                        .filter(|s| !s.is_empty())
                        .map(|s| {
                            s.replace(',', ".")
                                .parse::<f64>()
                                .ok()
                                .filter(|x| x.is_finite() && *x > 0.0)
                        })
                        .collect();
                    if parent.is_empty()
                        || children.is_empty()
                        || vals.len() != children.len()
                        || vals.iter().any(Option::is_none)
                    {
                        self.note(
                            child.line,
                            format!(
                                "split of '{parent}' needs a parent and as many positive splitvalues as children \
                                 ({} values, {} children): split ignored",
                                vals.len(),
                                children.len()
                            ),
                        );
                        continue;
                    }
                    let mut fractions: Vec<f64> = vals.into_iter().flatten().collect();
                    let sum: f64 = fractions.iter().sum();
                    if (sum - 1.0).abs() > 1e-6 {
                        self.note(
                            child.line,
                            format!("splitvalues of '{parent}' sum to {sum}: normalised to 1"),
                        );
                        fractions.iter_mut().for_each(|f| *f /= sum);
                    }
                    if splits.iter().any(|s| s.parent == parent) {
                        self.note(
                            child.line,
                            format!("node '{parent}' split twice: the second split ignored"),
                        );
                        continue;
                    }
                    splits.push(OpeningSplit {
                        axis,
                        parent,
                        children,
                        fractions,
                    });
                }
                "elements" => {
                    if let Some(p) = child
                        .attr("parent")
                        .map(|a| id(&a.1))
                        .filter(|p| !p.is_empty())
                    {
                        root = Some(p);
                    }
                    if let Some((_, terms, line)) = child.attr("terms") {
                        let parts: Vec<&str> = terms.split(',').map(str::trim).collect();
                        if parts.iter().any(|p| p.is_empty()) {
                            self.note(*line, "empty entry (trailing comma) in terms dropped");
                        }
                        listed_terms.extend(
                            parts
                                .into_iter()
                                .filter(|p| !p.is_empty())
                                .map(String::from),
                        );
                    }
                }
                _ => self.note(
                    child.line,
                    format!("unknown element <{}> in an opening ignored", child.name),
                ),
            }
        }
        let all_children: BTreeSet<&str> = splits
            .iter()
            .flat_map(|s| s.children.iter().map(String::as_str))
            .collect();
        let root = match root {
            Some(r) => r,
            None => {
                let tops: Vec<&str> = splits
                    .iter()
                    .map(|s| s.parent.as_str())
                    .filter(|p| !all_children.contains(p))
                    .collect();
                match tops.as_slice() {
                    [one] => one.to_string(),
                    _ => {
                        self.note(el.line, "opening without <elements parent> and without a single top split: ignored");
                        return None;
                    }
                }
            }
        };
        // Walk the tree from the root, pre-order; a node met twice means a cycle or shared child.
        let by_parent: BTreeMap<&str, &OpeningSplit> =
            splits.iter().map(|s| (s.parent.as_str(), s)).collect();
        let mut ordered = Vec::new();
        let mut leaves = Vec::new();
        let mut seen = BTreeSet::new();
        let mut stack = vec![root.clone()];
        while let Some(n) = stack.pop() {
            if !seen.insert(n.clone()) {
                self.note(
                    el.line,
                    format!(
                        "opening node '{n}' reached twice (cycle or shared child): opening ignored"
                    ),
                );
                return None;
            }
            match by_parent.get(n.as_str()) {
                Some(s) => {
                    ordered.push((*s).clone());
                    stack.extend(s.children.iter().rev().cloned());
                }
                None => leaves.push(n),
            }
        }
        if ordered.len() != splits.len() {
            self.note(
                el.line,
                format!(
                    "{} opening split(s) not reachable from '{root}' dropped",
                    splits.len() - ordered.len()
                ),
            );
        }
        let listed: BTreeSet<&str> = listed_terms.iter().map(String::as_str).collect();
        let found: BTreeSet<&str> = leaves.iter().map(String::as_str).collect();
        if !listed_terms.is_empty() && listed != found {
            self.note(
                el.line,
                "opening terms differ from the leaves of the split tree: the leaves are used",
            );
        }
        Some(OpeningTree {
            root,
            splits: ordered,
            terms: leaves,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn zones(text: &str) -> (Vec<Zone>, Vec<KbRepair>) {
        match read_zones(text, "t.xml") {
            Ok(r) => r,
            Err(e) => panic!("{e}"),
        }
    }

    #[test]
    fn line_col_from_offset() {
        let t = "ab\ncdé\nf";
        let idx = LineIndex::new(t);
        assert_eq!(idx.line_col(0), (1, 1));
        assert_eq!(idx.line_col(3), (2, 1));
        assert_eq!(idx.line_col(t.find('f').unwrap_or(0)), (3, 1));
        assert_eq!(idx.line_col(t.len()), (3, 2));
    }

    #[test]
    fn malformed_xml_names_file_line_col() {
        let err = read_zones(
            "<earth>\n  <country designation=\"A\">\n</earth>",
            "bad.xml",
        )
        .err();
        let msg = err.map(|e| e.to_string()).unwrap_or_default();
        assert!(msg.starts_with("bad.xml:3:"), "{msg}");
    }

    #[test]
    fn doctype_refused() {
        let t = "<?xml version=\"1.0\"?>\n<!DOCTYPE earth [<!ENTITY x \"boom\">]>\n<earth/>";
        match read_zones(t, "d.xml") {
            Err(KbError::Doctype { line, .. }) => assert_eq!(line, 2),
            other => panic!("{other:?}"),
        }
        assert!(read_zones("<earth><info color=\"&x;\"/></earth>", "e.xml").is_err());
    }

    #[test]
    fn wrong_root_and_empty_are_errors() {
        assert!(matches!(
            read_zones("<kb/>", "k.xml"),
            Err(KbError::Structure { .. })
        ));
        assert!(matches!(
            read_zones("  ", "k.xml"),
            Err(KbError::Structure { .. })
        ));
        assert!(read_zones("<earth/><earth/>", "k.xml").is_err());
    }

    #[test]
    fn lenient_values_are_repaired_and_reported() {
        let t = "<earth>\n<country designation=\" France \">\n<info color=\"\n pink\" dist=\"0,3\" lat=\"47.3\" lon=\"0.68\" rooftype=\"\n gabbled\" nbfloor=\"\"/>\n</country>\n</earth>";
        let (z, rep) = zones(t);
        assert_eq!(z.len(), 2);
        assert_eq!(z[1].name, "France");
        assert_eq!(z[1].info.roof, Some(RoofShape::Gabled));
        assert_eq!(z[1].info.storeys, None);
        assert_eq!(z[1].circle.map(|c| c.radius_km), Some(0.3));
        assert!(
            rep.iter()
                .any(|r| r.line == 4 && r.what.contains("decimal comma")),
            "{rep:?}"
        );
        assert!(rep.iter().any(|r| r.what.contains("gabbled")), "{rep:?}");
        assert!(
            rep.iter()
                .any(|r| r.what.contains("empty value of 'nbfloor'")),
            "{rep:?}"
        );
    }

    #[test]
    fn attribute_names_are_case_insensitive() {
        let t = r#"<earth><appearance><values bdRoofType="hip" windowHeight="short" WINDOWWIDTH="3" windowColor="ivory"/></appearance></earth>"#;
        let (z, _) = zones(t);
        let v = &z[0].appearances[0].values;
        assert_eq!(v.roof, Some(RoofShape::Hipped));
        assert_eq!(v.window_height, Some(WindowHeight::Short));
        assert_eq!(v.window_width, Some(3.0));
        assert_eq!(v.frame_color, Color::parse("ivory"));
    }

    #[test]
    fn prepass_repairs_the_annex_markup_slips() {
        // Missing '<', whitespace after '<', unquoted value, swallowed attribute name.
        let t = "<earth>\ncountry designation=\"Madagascar\">\n<town designation=\"A\">\n<location lat=\"-18,9333\" lon=47,5167\" dist=\"0,3\"/>\n<appearance><values maxrotation=\"\n minFloors=\"1\" color=\"peru\" /><\n ruleset file=\"data.xml\"/></appearance>\n</town></country></earth>";
        let (z, rep) = zones(t);
        let lines: Vec<usize> = rep.iter().map(|r| r.line).collect();
        assert_eq!(z.len(), 3, "{rep:?}");
        assert_eq!(z[1].name, "Madagascar");
        let c = z[2].circle.unwrap_or(Circle {
            lat: 0.0,
            lon: 0.0,
            radius_km: 0.0,
        });
        assert!(
            (c.lat + 18.9333).abs() < 1e-9 && (c.lon - 47.5167).abs() < 1e-9 && c.radius_km == 0.3
        );
        let app = &z[2].appearances[0];
        assert_eq!(app.values.min_floors, Some(1));
        assert_eq!(app.values.wall_color, Color::parse("peru"));
        assert_eq!(app.values.max_rotation, None);
        assert_eq!(app.ruleset.as_deref(), Some("data.xml"));
        assert!(
            lines.contains(&2) && lines.contains(&4) && lines.contains(&5) && lines.contains(&6),
            "{rep:?}"
        );
    }

    #[test]
    fn opening_tree_is_validated() {
        let cyc = r#"<earth><appearance><values/><opening>
            <split axis="X" parent="a" children="b|c" splitvalues="0.5,0.5"/>
            <split axis="Z" parent="b" children="a|d" splitvalues="0.5,0.5"/>
            <elements parent="a" terms="c,d"/></opening></appearance></earth>"#;
        let (z, rep) = zones(cyc);
        assert!(z[0].appearances[0].opening.is_none());
        assert!(rep.iter().any(|r| r.what.contains("reached twice")));

        let norm = r#"<earth><appearance><opening>
            <split axis="x" parent="a" children="b|c" splitvalues="1,3"/>
            </opening></appearance></earth>"#;
        let (z, rep) = zones(norm);
        let o = z[0].appearances[0].opening.clone();
        assert_eq!(
            o.as_ref().map(|o| o.splits[0].fractions.clone()),
            Some(vec![0.25, 0.75]),
            "{rep:?}"
        );
        assert_eq!(
            o.map(|o| o.terms),
            Some(vec!["b".to_string(), "c".to_string()])
        );
    }

    #[test]
    fn unknown_zone_elements_nest_one_level_deeper() {
        let t = r#"<earth><town designation="T"><info lat="1" lon="2" dist="3"/><quarter designation="Q"><info lat="1" lon="2" dist="1"/></quarter><foo/></town></earth>"#;
        let (z, rep) = zones(t);
        assert_eq!(z.len(), 3);
        assert_eq!(z[2].kind, ZoneKind::Other("quarter".into()));
        assert_eq!(z[2].depth, 2);
        assert_eq!(z[2].path, "earth/T/Q");
        assert_eq!(z[2].parent, Some(1));
        assert!(rep.iter().any(|r| r.what.contains("<foo>")));
    }

    proptest::proptest! {
        #[test]
        fn never_panics_on_arbitrary_text(s in "\\PC{0,200}") {
            let _ = read_zones(&s, "p.xml");
        }

        #[test]
        fn never_panics_on_kb_like_text(s in "[<>/=\" a-z,;.0-9\n]{0,200}") {
            let _ = read_zones(&format!("<earth>{s}</earth>"), "p.xml");
        }
    }
}
