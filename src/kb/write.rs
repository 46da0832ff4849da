//! The strict writer: a knowledge base, as either reader gives it, written in the clean format
//! of docs/knowledge-base.md and `schemas/kb.xsd`, so that the strict reader reads it back to
//! the same zones, shapes, values, appearances and openings (`to_strict`).
//!
//! **From the model, not from the element tree.** The lenient reader's repairs are made in
//! three places: the textual pre-pass, the element tree, and the zone reader (decimal commas,
//! duplicate `<info>` or `<values>` merged, attribute spellings, a roof `gabbled`, splitvalues
//! normalised, inconsistent splits dropped, trimmed values...). Only the model
//! ([`super::Zone`], [`super::Values`], [`super::Appearance`]) holds the result of all of
//! them; rewriting the repaired tree would mean doing the zone reader's repairs a second time,
//! in a second place that could drift from the first. Writing the model also makes the
//! round trip exact by construction: every field is written in the one spelling the strict
//! reader takes, numbers in Rust's shortest form that reads back to the same `f64`.
//!
//! **What is lost.** The model keeps no comments, no processing instructions and no layout, so
//! the output has none of the input's comments (the conversion says so in its notes when the
//! editor saves). The order of zones, of each zone's polygons and appearances, and of each
//! opening's splits (the tree's pre-order, as the reader keeps them) is kept. Elements are
//! written in the schema's order, two spaces per level, every zone on a line of its own.
//!
//! **What the clean format cannot hold** is dropped or changed, each with a [`KbRepair`] note
//! at the line of the input: unknown attributes (`Values::extra`), a circle or polygon on
//! `<earth>`, `balconies` in a zone's `<info>`, `infer` in `<values>`, a `maxrotation` outside
//! −360..360 or a `balconies` outside 0..1, an `<opening>` without splits (one pane per window
//! either way), a zone element that is none of the clean names (written `<zone>`), a second
//! zone of the same path (renamed `name (2)`), line breaks or tabs inside a name (spaces) and a
//! thesis `r;g;b` colour that is not on the 8-bit grid (rounded to `#rrggbb`).

use super::{Appearance, Color, KbRepair, KnowledgeBase, OpeningTree, Values, Zone};
use crate::model::Programme;

/// A knowledge base written in the clean format, and what the writing changed.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct StrictText {
    /// The clean-format XML (UTF-8, ends with a line break).
    pub text: String,
    /// What the clean format could not hold and how it was written instead, each at the line of
    /// the zone or appearance in the input; empty when the strict reading of `text` gives the
    /// same model.
    pub notes: Vec<KbRepair>,
}

/// Writes `kb` in the clean format. The strict reader reads the result (a property the tests
/// check on the thesis annex, hand-made lenient inputs and the world KB) to the same zones,
/// shapes, values, appearances and openings as `kb`, except for what [`StrictText::notes`]
/// lists.
pub(crate) fn to_strict(kb: &KnowledgeBase) -> StrictText {
    let zones = kb.zones();
    let mut children: Vec<Vec<usize>> = vec![Vec::new(); zones.len()];
    for (i, z) in zones.iter().enumerate() {
        if let Some(p) = z.parent.filter(|p| *p < i) {
            if let Some(list) = children.get_mut(p) {
                list.push(i);
            }
        }
    }
    let mut w = Writer {
        out: String::from("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"),
        notes: Vec::new(),
        children,
        paths: vec![String::new(); zones.len()],
    };
    if let Some(earth) = zones.first() {
        if let Some(p) = w.paths.first_mut() {
            *p = "earth".into();
        }
        w.zone(zones, 0, earth, 0);
    } else {
        w.out.push_str("<earth/>\n");
    }
    w.notes.sort_by_key(|n| n.line);
    StrictText {
        text: w.out,
        notes: w.notes,
    }
}

struct Writer {
    out: String,
    notes: Vec<KbRepair>,
    /// Each zone's sub-zones, in document order.
    children: Vec<Vec<usize>>,
    /// Each written zone's path (after any renaming), to find duplicates.
    paths: Vec<String>,
}

/// The clean names of zone elements below earth.
const ZONE_NAMES: [&str; 6] = super::strict::ZONE_ELEMENTS;

/// Escapes an attribute value for `"`-quoted XML: the five markup characters, and line
/// breaks and tabs as character references (attribute normalisation would turn them into
/// spaces otherwise).
fn escape(v: &str) -> String {
    let mut s = String::with_capacity(v.len());
    for c in v.chars() {
        match c {
            '&' => s.push_str("&amp;"),
            '<' => s.push_str("&lt;"),
            '>' => s.push_str("&gt;"),
            '"' => s.push_str("&quot;"),
            '\n' => s.push_str("&#10;"),
            '\r' => s.push_str("&#13;"),
            '\t' => s.push_str("&#9;"),
            c => s.push(c),
        }
    }
    s
}

/// A decimal in the shortest form that reads back to the same `f64` (Rust's `Display` never
/// uses an exponent, which xs:decimal does not allow).
fn num(x: f64) -> String {
    format!("{x}")
}

fn programme_name(p: Programme) -> &'static str {
    match p {
        Programme::House => "house",
        Programme::Apartments => "apartments",
        Programme::Office => "office",
        Programme::Retail => "retail",
        Programme::OpenPlan => "openplan",
    }
}

impl Writer {
    fn note(&mut self, line: usize, what: String) {
        self.notes.push(KbRepair { line, what });
    }

    fn indent(&mut self, level: usize) {
        for _ in 0..level {
            self.out.push_str("  ");
        }
    }

    /// One empty element on its own line: `<name a="v" .../>`.
    fn empty(&mut self, level: usize, name: &str, attrs: &[(&str, String)]) {
        self.indent(level);
        self.out.push('<');
        self.out.push_str(name);
        for (k, v) in attrs {
            self.out.push(' ');
            self.out.push_str(k);
            self.out.push_str("=\"");
            self.out.push_str(&escape(v));
            self.out.push('"');
        }
        self.out.push_str("/>\n");
    }

    /// A text value the clean format takes as a token (no line break or tab, no surrounding
    /// spaces): line breaks and tabs become spaces, with a note.
    fn token(&mut self, line: usize, what: &str, v: &str) -> String {
        if v.contains(['\n', '\r', '\t']) || v.trim() != v {
            let t = v.replace(['\n', '\r', '\t'], " ").trim().to_string();
            self.note(
                line,
                format!("line breaks or tabs in {what} {v:?} written as spaces: {t:?}"),
            );
            return t;
        }
        v.to_string()
    }

    fn color(&mut self, line: usize, key: &str, c: Color) -> String {
        if let Some(name) = c.css_name().filter(|n| Color::parse(n) == Some(c)) {
            return name.to_string();
        }
        let hex = c.to_hex();
        if Color::parse(&hex) != Some(c) {
            self.note(
                line,
                format!("colour '{key}' is not on the 8-bit grid: written as the nearest, {hex}"),
            );
        }
        hex
    }

    /// The descriptor attributes of `v` in the schema's order; `info` for a zone's `<info>`
    /// (`rooftype`, `infer`), else an appearance's `<values>` (`bdRooftype`, `balconies`).
    fn descriptors(
        &mut self,
        v: &Values,
        info: bool,
        line: usize,
        at: &str,
    ) -> Vec<(&'static str, String)> {
        let mut a: Vec<(&'static str, String)> = Vec::new();
        if let Some(c) = v.wall_color {
            let s = self.color(line, "color", c);
            a.push(("color", s));
        }
        if let Some(m) = &v.material {
            let s = self.token(line, "material", m);
            if !s.is_empty() {
                a.push(("material", s));
            }
        }
        if let Some(n) = v.storeys {
            a.push(("nbfloor", n.to_string()));
        }
        if let Some(x) = v.floor_height {
            a.push(("floorsize", num(x)));
        }
        if let Some(x) = v.roof_angle {
            a.push(("roofangle", num(x)));
        }
        let colours = [
            ("roofColor", v.roof_color),
            ("doorCol", v.door_color),
            ("openingCol", v.window_color),
            ("windowfcolor", v.frame_color),
        ];
        for (k, c) in colours {
            if let Some(c) = c {
                let s = self.color(line, k, c);
                a.push((k, s));
            }
        }
        if let Some(h) = v.window_height {
            a.push(("windowheight", h.as_str().to_string()));
        }
        for (k, x) in [
            ("windowwidth", v.window_width),
            ("doorwidth", v.door_width),
            ("doorheight", v.door_height),
            ("minopeningwidth", v.min_opening_width),
            ("cornice", v.cornice),
            ("corniceheight", v.cornice_height),
            ("eaves", v.eaves),
        ] {
            if let Some(x) = x {
                a.push((k, num(x)));
            }
        }
        for (k, t) in [
            ("windowstyle", &v.window_style),
            ("windowmaterial", &v.window_material),
        ] {
            if let Some(t) = t {
                let s = self.token(line, k, t);
                if !s.is_empty() {
                    a.push((k, s));
                }
            }
        }
        if let Some(n) = v.min_floors {
            a.push(("minFloors", n.to_string()));
        }
        if let Some(n) = v.max_floors {
            a.push(("maxFloors", n.to_string()));
        }
        if let Some(x) = v.min_height {
            a.push(("minHeight", num(x)));
        }
        if let Some(x) = v.max_height {
            a.push(("maxHeight", num(x)));
        }
        if let Some(x) = v.max_rotation {
            if (-360.0..=360.0).contains(&x) {
                a.push(("maxrotation", num(x)));
            } else {
                self.note(
                    line,
                    format!("{at}: maxrotation {x} outside -360..360 dropped"),
                );
            }
        }
        if let Some(p) = v.programme {
            a.push(("programme", programme_name(p).to_string()));
        }
        if let Some(r) = v.roof {
            a.push((
                if info { "rooftype" } else { "bdRooftype" },
                r.osm_name().to_string(),
            ));
        }
        if let Some(i) = v.infer {
            if info {
                a.push(("infer", i.as_string()));
            } else {
                self.note(
                    line,
                    format!("{at}: infer is for a zone's <info> only: dropped"),
                );
            }
        }
        if let Some(b) = v.balconies {
            if info {
                self.note(
                    line,
                    format!("{at}: balconies is for an appearance's <values> only: dropped"),
                );
            } else if (0.0..=1.0).contains(&b) {
                a.push(("balconies", num(b)));
            } else {
                self.note(line, format!("{at}: balconies {b} outside 0..1 dropped"));
            }
        }
        for k in v.extra.keys() {
            self.note(
                line,
                format!(
                    "{at}: unknown attribute '{k}' dropped (the clean format has no place for it)"
                ),
            );
        }
        a
    }

    fn zone(&mut self, zones: &[Zone], i: usize, z: &Zone, level: usize) {
        let earth = i == 0;
        let at = if earth {
            "earth".to_string()
        } else {
            format!("zone '{}'", z.path)
        };
        let mut head: Vec<(&str, String)> = Vec::new();
        let element = if earth {
            "earth"
        } else {
            let kind = z.kind.as_str();
            match ZONE_NAMES.iter().find(|n| **n == kind) {
                Some(n) => n,
                None => {
                    self.note(
                        z.line,
                        format!("{at}: element <{kind}> is not a clean zone name: written <zone>"),
                    );
                    "zone"
                }
            }
        };
        if !earth {
            let mut name = self.token(z.line, "the designation", &z.name);
            if name.contains('/') || name.is_empty() {
                name = name.replace('/', "-");
                if name.is_empty() {
                    name = format!("zone{i}");
                }
            }
            let parent_path = z
                .parent
                .and_then(|p| self.paths.get(p))
                .cloned()
                .unwrap_or_else(|| "earth".into());
            let mut path = format!("{parent_path}/{name}");
            if self.paths.contains(&path) {
                let base = name.clone();
                let mut k = 2;
                while self.paths.contains(&path) {
                    name = format!("{base} ({k})");
                    path = format!("{parent_path}/{name}");
                    k += 1;
                }
                self.note(
                    z.line,
                    format!("{at}: a second zone of this path: renamed '{name}'"),
                );
            }
            if let Some(p) = self.paths.get_mut(i) {
                *p = path;
            }
            head.push(("designation", name));
        }
        let mut info = self.descriptors(&z.info, true, z.line, &format!("{at} <info>"));
        let mut polygons = z.polygons.as_slice();
        if earth {
            if z.circle.is_some() {
                self.note(
                    z.line,
                    "earth: a circle on <earth> dropped (earth holds every point)".into(),
                );
            }
            if !z.polygons.is_empty() {
                self.note(
                    z.line,
                    "earth: polygons on <earth> dropped (earth holds every point)".into(),
                );
            }
            polygons = &[];
        } else if let Some(c) = z.circle {
            info.push(("lat", num(c.lat)));
            info.push(("lon", num(c.lon)));
            info.push(("dist", num(c.radius_km)));
        }
        let kids = self.children.get(i).cloned().unwrap_or_default();
        let has_body = !info.is_empty()
            || !polygons.is_empty()
            || !z.appearances.is_empty()
            || !kids.is_empty();
        if !has_body {
            self.empty(level, element, &head);
            return;
        }
        self.indent(level);
        self.out.push('<');
        self.out.push_str(element);
        for (k, v) in &head {
            self.out.push(' ');
            self.out.push_str(k);
            self.out.push_str("=\"");
            self.out.push_str(&escape(v));
            self.out.push('"');
        }
        self.out.push_str(">\n");
        if !info.is_empty() {
            self.empty(level + 1, "info", &info);
        }
        for p in polygons {
            let pts: Vec<String> = p
                .ring
                .iter()
                .map(|[lon, lat]| format!("{} {}", num(*lon), num(*lat)))
                .collect();
            self.empty(level + 1, "polygon", &[("points", pts.join(", "))]);
        }
        for (k, a) in z.appearances.iter().enumerate() {
            self.appearance(a, level + 1, &format!("{at} appearance {}", k + 1));
        }
        for c in kids {
            if let Some(cz) = zones.get(c) {
                self.zone(zones, c, cz, level + 1);
            }
        }
        self.indent(level);
        self.out.push_str("</");
        self.out.push_str(element);
        self.out.push_str(">\n");
    }

    fn appearance(&mut self, a: &Appearance, level: usize, at: &str) {
        let mut head: Vec<(&str, String)> = Vec::new();
        if !a.buildings.is_empty() {
            let kinds: Vec<String> = a
                .buildings
                .iter()
                .map(|b| b.replace(['\n', '\r', '\t', ','], " ").trim().to_string())
                .filter(|b| !b.is_empty())
                .collect();
            if !kinds.is_empty() {
                head.push(("building", kinds.join(",")));
            }
        }
        if let Some(area) = a.when.area_text() {
            head.push(("area", area));
        }
        if let Some(attached) = a.when.attached {
            head.push(("attached", if attached { "yes" } else { "no" }.to_string()));
        }
        if !a.when.density.is_empty() {
            let d: Vec<&str> = a.when.density.iter().map(|d| d.name()).collect();
            head.push(("density", d.join(",")));
        }
        self.indent(level);
        self.out.push_str("<appearance");
        for (k, v) in &head {
            self.out.push(' ');
            self.out.push_str(k);
            self.out.push_str("=\"");
            self.out.push_str(&escape(v));
            self.out.push('"');
        }
        self.out.push_str(">\n");
        let mut values = self.descriptors(&a.values, false, a.line, at);
        if let Some(p) = a.proba {
            values.push(("proba", num(p)));
        }
        self.empty(level + 1, "values", &values);
        match &a.opening {
            Some(o) if !o.splits.is_empty() => self.opening(o, level + 1, a.line, at),
            Some(_) => self.note(
                a.line,
                format!(
                    "{at}: an <opening> without splits dropped (one pane per window either way)"
                ),
            ),
            None => {}
        }
        if let Some(f) = &a.ruleset {
            let f = self.token(a.line, "the ruleset file", f);
            self.empty(level + 1, "ruleset", &[("file", f)]);
        }
        if let Some(f) = &a.selex {
            let f = self.token(a.line, "the selex file", f);
            self.empty(level + 1, "selex", &[("file", f)]);
        }
        self.indent(level);
        self.out.push_str("</appearance>\n");
    }

    fn opening(&mut self, o: &OpeningTree, level: usize, line: usize, at: &str) {
        self.indent(level);
        self.out.push_str("<opening>\n");
        for s in &o.splits {
            let parent = self.token(line, &format!("{at}: a split's parent"), &s.parent);
            let fractions: Vec<String> = s.fractions.iter().map(|f| num(*f)).collect();
            self.empty(
                level + 1,
                "split",
                &[
                    ("axis", s.axis.as_str().to_string()),
                    ("parent", parent),
                    ("children", s.children.join("|")),
                    ("splitvalues", fractions.join(",")),
                ],
            );
        }
        let root = self.token(line, &format!("{at}: the opening's root"), &o.root);
        let mut attrs = vec![("parent", root)];
        if !o.terms.is_empty() {
            attrs.push(("terms", o.terms.join(",")));
        }
        self.empty(level + 1, "elements", &attrs);
        self.indent(level);
        self.out.push_str("</opening>\n");
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::super::{tools, ReadMode, ZoneKind};
    use super::*;

    fn lenient(text: &str) -> (KnowledgeBase, Vec<KbRepair>) {
        KnowledgeBase::parse_str(text, "in.xml").unwrap_or_else(|e| panic!("{e}"))
    }

    /// Writes `kb` strictly and reads it back with the strict reader; the output also passes
    /// what `kb check --strict` checks (no error).
    fn round_trip(kb: &KnowledgeBase) -> (KnowledgeBase, StrictText) {
        let out = to_strict(kb);
        let (back, repairs) = KnowledgeBase::parse_str_with(&out.text, "out.xml", ReadMode::Strict)
            .unwrap_or_else(|e| panic!("{e}\n{}", out.text));
        assert!(repairs.is_empty());
        let report = tools::report_for(&back, ReadMode::Strict, repairs, false);
        assert!(!report.has_errors(), "{report}");
        (back, out)
    }

    /// A zone without its line numbers (the output's lines are its own).
    fn unlined(z: &Zone) -> Zone {
        let mut z = z.clone();
        z.line = 0;
        for a in &mut z.appearances {
            a.line = 0;
        }
        z
    }

    fn assert_same(a: &KnowledgeBase, b: &KnowledgeBase) {
        assert_eq!(a.zones().len(), b.zones().len());
        for (x, y) in a.zones().iter().zip(b.zones()) {
            assert_eq!(unlined(x), unlined(y), "zone {}", x.path);
        }
    }

    #[test]
    fn the_thesis_annex_as_printed_is_written_strictly_to_the_same_model() {
        let text = include_str!("../../tests/data/thesis_annex.xml");
        let (kb, repairs) = lenient(text);
        assert!(repairs.len() > 10, "{repairs:?}");
        assert!(KnowledgeBase::parse_str_with(text, "a.xml", ReadMode::Strict).is_err());
        let (back, out) = round_trip(&kb);
        assert_same(&kb, &back);
        assert!(out.notes.is_empty(), "{:?}", out.notes);
        // The annex's appearances, with their split windows and ruleset, are all there.
        let toulouse = back
            .find("earth/France/Midi-Pyrenees/Toulouse")
            .unwrap_or(0);
        let apps = &back.zones()[toulouse].appearances;
        assert_eq!(apps.len(), 2);
        assert!(apps
            .iter()
            .all(|a| a.opening.is_some() && a.ruleset.is_some()));
        // Written twice, the same text: the writer is a function of the model.
        assert_eq!(to_strict(&back).text, out.text);
    }

    /// What the lenient reader repairs, each kind once, with nothing the clean format lacks.
    const REPAIRED: &str = "<earth>
  <INFO color=\"1;1;1\" NbFloor=\"2\" floorsize=\"3,5\" rooftype=\"hip\"/>
  <!-- a comment the conversion loses -->
  <info roofangle=\"25\" infer=\"Roof, Levels\"/>
  country designation=\" A &amp; B \">
    <Info lat=\"43,6\" lon=1.44\" dist=\"2\" color=\"Pink\" windowheight=\"mixed\"/>
    < town designation=\"T\">
      <location lat=\"43.6\" lon=\"1.44\" dist=\"0.30000000000000004\"/>
      <polygon points=\"1.44 43.6, 1.45 43.6, 1.45 43.61, 1.44 43.6\"/>
      <appearance proba=\"0,4\" building=\"House House, villa\">
        <values bdRoofType=\"gabbled\" color=\" #ABC \" maxrotation=\"
          minFloors=\"2\" windowColor=\"ivory\" programme=\"flats\"/>
        <values maxFloors=\"4\"/>
        <opening>
          <split axis=\"x\" parent=\"w\" children=\"a|b\" splitvalues=\"1,3\"/>
          <split axis=\"Z\" parent=\"a\" children=\"c, d\" splitvalues=\"0.5;0.5\"/>
          <split axis=\"Z\" parent=\"a\" children=\"e|f\" splitvalues=\"0.5,0.5\"/>
          <split axis=\"Z\" parent=\"zz\" children=\"g|h\" splitvalues=\"0.5,0.5\"/>
          <split axis=\"Q\" parent=\"b\" children=\"i|j\" splitvalues=\"0.5,0.5\"/>
          <elements parent=\"w\" terms=\"a,b,\"/>
        </opening>
        <ruleset file=\" rules/x.cga \"/>
      </appearance>
      <appearance><values proba=\"\" balconies=\"0.25\"/>
        <opening><split axis=\"X\" parent=\"p\" children=\"q|p\" splitvalues=\"1,1\"/></opening>
      </appearance>
      <District designation=\"D\"><info nbfloor=\"\" lat=\"1\"/></District>
    </town>
  </country>
</earth>";

    #[test]
    fn lenient_repairs_are_written_in_the_clean_format_to_the_same_model() {
        let (kb, repairs) = lenient(REPAIRED);
        let said = |what: &str| repairs.iter().any(|r| r.what.contains(what));
        for what in [
            "missing '<'",
            "whitespace between '<'",
            "missing quotes",
            "lost its closing quote",
            "decimal comma",
            "second <info>",
            "second <values>",
            "roof 'hip'",
            "split twice",
            "not reachable",
            "is not X, Y or Z",
            "without <elements parent>",
            "incomplete circle",
            "empty value",
            "Madagascar spelling",
            "normalised",
        ] {
            assert!(said(what), "no repair {what:?}: {repairs:?}");
        }
        let (back, out) = round_trip(&kb);
        assert!(out.notes.is_empty(), "{:?}", out.notes);
        assert_same(&kb, &back);
        assert!(!out.text.contains("comment"), "{}", out.text);
        assert!(
            out.text.contains("designation=\"A &amp; B\""),
            "{}",
            out.text
        );
        let t = back.find("earth/A & B/T").unwrap_or(0);
        let z = &back.zones()[t];
        assert_eq!(z.circle.map(|c| c.radius_km), Some(0.30000000000000004));
        assert_eq!(z.appearances[0].buildings, ["house", "villa"]);
        let o = z.appearances[0].opening.as_ref().map(|o| o.splits.len());
        assert_eq!(o, Some(2), "{}", out.text);
        assert!(z.appearances[1].opening.is_none());
        assert_eq!(z.appearances[0].values.max_floors, Some(4));
        assert_eq!(z.appearances[0].ruleset.as_deref(), Some("rules/x.cga"));
    }

    #[test]
    fn what_the_clean_format_cannot_hold_is_noted_and_the_rest_kept() {
        let text = r#"<earth>
  <info balconies="0.5" lat="1" lon="2" dist="3"/>
  <town designation="T"><info lat="1" lon="2" dist="3" color="0.3;0.5;0.7" shade="deep"/>
    <quarter designation="Q"><info nbfloor="2"/></quarter>
  </town>
  <town designation="T"><info nbfloor="3"/>
    <appearance><values maxrotation="400" balconies="2" nbfloor="4"/>
      <opening><elements parent="w"/></opening></appearance>
  </town>
</earth>"#;
        let (kb, _) = lenient(text);
        let (back, out) = round_trip(&kb);
        let noted = |line: usize, what: &str| {
            out.notes
                .iter()
                .any(|n| n.line == line && n.what.contains(what))
        };
        assert!(noted(1, "circle on <earth>"), "{:?}", out.notes);
        assert!(noted(1, "balconies is for"), "{:?}", out.notes);
        assert!(noted(3, "8-bit grid"), "{:?}", out.notes);
        assert!(noted(3, "'shade' dropped"), "{:?}", out.notes);
        assert!(noted(4, "<quarter>"), "{:?}", out.notes);
        assert!(noted(6, "renamed 'T (2)'"), "{:?}", out.notes);
        assert!(noted(7, "maxrotation 400"), "{:?}", out.notes);
        assert!(noted(7, "balconies 2"), "{:?}", out.notes);
        assert!(noted(7, "without splits"), "{:?}", out.notes);
        assert_eq!(out.notes.len(), 9, "{:?}", out.notes);
        // Everything else is as read.
        let paths: Vec<&str> = back.zones().iter().map(|z| z.path.as_str()).collect();
        assert_eq!(paths, ["earth", "earth/T", "earth/T/Q", "earth/T (2)"]);
        assert_eq!(back.zones()[2].kind, ZoneKind::Other("zone".into()));
        assert_eq!(back.zones()[1].circle, kb.zones()[1].circle);
        assert_eq!(back.zones()[2].info, kb.zones()[2].info);
        let app = &back.zones()[3].appearances[0];
        assert_eq!(app.values.storeys, Some(4));
        assert_eq!(app.values.max_rotation, None);
        assert!(app.opening.is_none());
        let hex = |z: &Zone| z.info.wall_color.map(Color::to_hex);
        assert_eq!(hex(&back.zones()[1]), hex(&kb.zones()[1]));
    }

    #[test]
    fn the_world_kb_round_trips_to_an_equal_model() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("knowledge_base/kb.xml");
        let (kb, repairs) =
            KnowledgeBase::load_with(&path, ReadMode::Strict).unwrap_or_else(|e| panic!("{e}"));
        assert!(repairs.is_empty());
        let (zones, polygons) = kb.polygon_counts();
        assert!(kb.zones().len() >= 240 && zones > 100 && polygons > 1000);
        let (back, out) = round_trip(&kb);
        assert!(out.notes.is_empty(), "{:?}", out.notes);
        assert_same(&kb, &back);
    }

    /// Attributes as the lenient reader meets them: good, misspelt, out of range, decimal
    /// commas, markup characters.
    const ATTRS: [&str; 24] = [
        "color=\"Pink\"",
        "color=\"0.3;0.2;0.9\"",
        "roofColor=\"#ABC\"",
        "nbfloor=\"2,5\"",
        "floorsize=\" 3.25 \"",
        "rooftype=\"gabbled\"",
        "bdRooftype=\"hip\"",
        "roofangle=\"95\"",
        "maxrotation=\"-720\"",
        "balconies=\"0,3\"",
        "infer=\"Roof\"",
        "programme=\"flats\"",
        "windowheight=\"low\"",
        "windowstyle=\"A &amp; B &lt;x&gt;\"",
        "material=\"&quot;brick&quot;\"",
        "minFloors=\"1\"",
        "maxHeight=\"0.000001\"",
        "lat=\"43.6\"",
        "lon=\"1,44\"",
        "dist=\"0.1\"",
        "proba=\"0.33333333333333331\"",
        "shade=\"deep\"",
        "nbfloor=\"\"",
        "windowwidth=\"-1\"",
    ];

    fn kb_text(picks: &[(u8, u8, u8)]) -> String {
        let mut t = String::from("<earth>\n");
        let mut open: Vec<&str> = Vec::new();
        for (k, (what, a, b)) in picks.iter().enumerate() {
            let attr = |i: u8| ATTRS[usize::from(i) % ATTRS.len()];
            match what % 6 {
                0 if open.len() < 4 => {
                    let el = ["town", "Country", "district", "quarter"][usize::from(*a) % 4];
                    t.push_str(&format!("<{el} designation=\" Z{} \">\n", b % 3));
                    open.push(el);
                }
                1 if !open.is_empty() => {
                    let el = open.pop().unwrap_or("town");
                    t.push_str(&format!("</{el}>\n<!-- c -->\n"));
                }
                2 => t.push_str(&format!("<info {} {}/>\n", attr(*a), attr(*b))),
                3 => t.push_str(&format!(
                    "<appearance building=\"House, {k}\"><values {} {}/></appearance>\n",
                    attr(*a),
                    attr(*b)
                )),
                4 => t.push_str(&format!(
                    "<appearance><values {}/><opening><split axis=\"x\" parent=\"w\" children=\"a|b\" splitvalues=\"{},{}\"/><split axis=\"Z\" parent=\"{}\" children=\"c|d\" splitvalues=\"1,2\"/></opening></appearance>\n",
                    attr(*a),
                    a % 5 + 1,
                    b % 7,
                    ["a", "b", "w", "q"][usize::from(*b) % 4]
                )),
                _ => t.push_str(&format!(
                    "<polygon points=\"1.44 43.6, 1.4{} 43.6, 1.45 43.6{}\"/>\n",
                    a % 10,
                    b % 10
                )),
            }
        }
        while let Some(el) = open.pop() {
            t.push_str(&format!("</{el}>\n"));
        }
        t.push_str("</earth>\n");
        t
    }

    proptest::proptest! {
        /// Whatever the lenient reader reads, the strict reader reads the writer's output, and
        /// to the same model when the writer notes nothing.
        #[test]
        fn every_lenient_model_is_written_strictly(picks in proptest::collection::vec((0u8..6, 0u8..255, 0u8..255), 0..24)) {
            let text = kb_text(&picks);
            let Ok((kb, _)) = KnowledgeBase::parse_str(&text, "p.xml") else {
                return Ok(());
            };
            let out = to_strict(&kb);
            let back = KnowledgeBase::parse_str_with(&out.text, "out.xml", ReadMode::Strict);
            proptest::prop_assert!(back.is_ok(), "{:?}\n{text}\n{}", back.err(), out.text);
            if let (Ok((back, _)), true) = (back, out.notes.is_empty()) {
                proptest::prop_assert_eq!(kb.zones().len(), back.zones().len());
                for (x, y) in kb.zones().iter().zip(back.zones()) {
                    proptest::prop_assert_eq!(unlined(x), unlined(y));
                }
            }
        }
    }

    #[test]
    fn attribute_values_are_escaped_and_numbers_read_back_exactly() {
        assert_eq!(
            escape("a<b>&\"c\"\n\t"),
            "a&lt;b&gt;&amp;&quot;c&quot;&#10;&#9;"
        );
        for x in [0.1 + 0.2, 1e-7, 123_456_789.123_456_79, -0.0, 1e21, 5e-324] {
            let s = num(x);
            assert!(!s.contains(['e', 'E']), "{s}");
            assert_eq!(s.parse::<f64>().ok(), Some(x), "{s}");
        }
    }
}
