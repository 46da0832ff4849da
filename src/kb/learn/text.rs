//! The KB text: its header, and the zones with their values and appearances.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use super::fit::{merge_bins, round_probas, Bin};
use super::format::{comment_text, coord, escape, num};
use super::{Attr, Grouping, LearnOptions, Shape, Writer, ATTRS, KIND_CLASSES, MIN_PER_APPEARANCE};
use crate::kb::compile::color_word;
use crate::kb::defaults;

impl Writer<'_> {
    fn line(&mut self, indent: usize, text: &str) {
        for _ in 0..indent {
            self.out.push_str("  ");
        }
        self.out.push_str(text);
        self.out.push('\n');
    }

    pub(super) fn header(&mut self, o: &LearnOptions<'_>, any: bool) {
        self.out
            .push_str("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<!--\n");
        let grouping = match o.grouping {
            Grouping::Grid { metres } => format!(
                "a grid of {} m cells (rows of {} m of latitude, each cut into columns of {} m \
                 at its middle latitude: lon/lat rectangles), the extract being one town",
                num(metres, 3),
                num(metres, 3),
                num(metres, 3)
            ),
            Grouping::Zones(kb) => format!("the zones of {}", kb.source()),
        };
        let lines = [
            format!(
                "Learned by `citygen kb learn` from {} ({}): {} buildings.",
                o.name,
                o.source,
                self.samples.len()
            ),
            format!("Grouping: {grouping}."),
            format!(
                "A zone with fewer than {} tagged values of an attribute takes it from its parent \
                 (up to the built-in defaults, where the attribute is not written).",
                self.min
            ),
            "Each <info> states the values in force in its zone (its own or its parent's): \
             nbfloor the median storeys (building:levels), rooftype the most frequent \
             roof:shape, floorsize the median of (height - roof:height) / building:levels, \
             color, roofColor and material the most frequent building:colour, roof:colour and \
             building:material."
                .into(),
            format!(
                "Appearances, drawn by proba, reproduce the distribution of (storeys, roof \
                 shape); at most {} per zone and group, the rare tail merged as each zone says. Colours \
                 and floorsize per appearance from its own buildings when {} or more are \
                 tagged (in a zone where they are its own), else the zone's. A zone without appearances uses its parent's.",
                self.max_apps, MIN_PER_APPEARANCE
            ),
            format!(
                "Per building=* kind class (houses; flats and commercial; industrial): where a \
                 zone's buildings of one class have {} or more tagged values of their own, the \
                 class has its own appearances, with building=\"...\" naming the class's kinds, \
                 learned from that class's buildings only (what it has too few of: the zone's). \
                 The appearances without a building list are learned from all buildings and \
                 serve building=yes, other kinds and the classes without their own.",
                self.min
            ),
            "Edit freely, then check it with citygen's kb check in strict mode.".into(),
        ];
        for l in lines {
            let text = comment_text(&l);
            let _ = writeln!(self.out, "  {text}");
        }
        if !any {
            let _ = writeln!(
                self.out,
                "  {}",
                comment_text(
                    "No building of the extract is tagged with building:levels, roof:shape, \
                     height, building:colour, roof:colour or building:material: nothing to \
                     learn. The earth below holds the built-in defaults."
                )
            );
        }
        self.out.push_str("-->\n");
    }

    /// The KB when nothing was learned: earth with the built-in defaults.
    pub(super) fn defaults_only(&mut self) {
        self.zones = 1;
        let info = format!(
            "<info color=\"{}\" nbfloor=\"{}\" floorsize=\"{}\" rooftype=\"{}\" roofColor=\"{}\"/>",
            color_word(defaults::WALL_COLOR),
            defaults::STOREYS,
            num(defaults::FLOOR_HEIGHT, 2),
            defaults::ROOF.osm_name(),
            color_word(defaults::ROOF_COLOR)
        );
        self.line(0, "<earth>");
        self.line(1, &info);
        self.line(0, "</earth>");
    }

    pub(super) fn group(&mut self, g: usize, indent: usize) {
        self.zones += 1;
        let groups = self.groups;
        let grp = &groups[g];
        let element = grp.element;
        let src: Vec<Option<usize>> = ATTRS.iter().map(|&a| self.source(g, a)).collect();
        let src_of = |a: Attr| src[ATTRS.iter().position(|&x| x == a).unwrap_or(0)];
        let own_any = ATTRS[..5].iter().any(|&a| src_of(a) == Some(g));
        if ATTRS.iter().any(|&a| src_of(a) == Some(g)) {
            self.own += 1;
        }
        // The comment: counts, sources, kinds.
        let mut parts = Vec::new();
        for &a in &ATTRS {
            let n = self.count(g, a);
            let from = match src_of(a) {
                Some(s) if s == g && self.rest[g][Self::index(a)] => format!(
                    " (values from the {} outside sub-zones of their own)",
                    self.data[g][Self::index(a)].len()
                ),
                Some(s) if s == g => String::new(),
                Some(s) => format!(" (from {})", self.groups[s].name),
                None => " (built-in default)".into(),
            };
            parts.push(format!("{} {n}{from}", a.name()));
        }
        let mut kinds: BTreeMap<&str, usize> = BTreeMap::new();
        for &k in &grp.members {
            *kinds
                .entry(self.samples[k].kind.as_deref().unwrap_or("(none)"))
                .or_default() += 1;
        }
        let mut kinds: Vec<(&str, usize)> = kinds.into_iter().collect();
        kinds.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(b.0)));
        let kind_list: Vec<String> = kinds
            .iter()
            .take(6)
            .map(|(k, n)| format!("{k} {n}"))
            .collect();
        let more = if kinds.len() > 6 {
            format!(", {} more kinds", kinds.len() - 6)
        } else {
            String::new()
        };
        let open = if element == "earth" {
            "<earth>".to_string()
        } else {
            format!("<{element} designation=\"{}\">", escape(&grp.name))
        };
        self.line(indent, &open);
        let inner = indent + 1;
        if grp.members.is_empty() {
            self.line(inner, "<!-- Built-in defaults: no building of its own. -->");
        }
        let comment = format!(
            "<!-- {}: {} buildings; tagged: {}. Kinds (building=*): {}{}. -->",
            comment_text(&grp.name),
            grp.members.len(),
            parts.join(", "),
            comment_text(&kind_list.join(", ")),
            comment_text(&more)
        );
        if !grp.members.is_empty() {
            self.line(inner, &comment);
        }
        // <info>: shape and the values in force.
        let mut info = String::from("<info");
        if let Shape::Kept {
            circle: Some((lat, lon, km)),
            ..
        } = &grp.shape
        {
            let _ = write!(
                info,
                " lat=\"{}\" lon=\"{}\" dist=\"{}\"",
                coord(*lat),
                coord(*lon),
                num(*km, 6)
            );
        }
        let ss = src_of(Attr::Storeys);
        let sr = src_of(Attr::Roof);
        if let Some(s) = ss {
            let d = self.storeys_dist(s);
            let mut acc = 0.0;
            let med = d
                .iter()
                .find(|(_, p)| {
                    acc += *p;
                    acc >= 0.5 - 1e-9
                })
                .map(|(n, _)| *n);
            if let Some(n) = med {
                let _ = write!(info, " nbfloor=\"{n}\"");
            }
        }
        if let Some(f) = self.floor_for(g, src_of(Attr::FloorHeight), None) {
            let _ = write!(info, " floorsize=\"{}\"", num(f, 2));
        }
        if let Some(r) = sr {
            let d = self.roof_dist(r);
            let mut best: Option<(&str, f64)> = None;
            for (k, p) in d {
                if best.is_none_or(|(_, b)| p > b) {
                    best = Some((k, p));
                }
            }
            if let Some((k, _)) = best {
                let _ = write!(info, " rooftype=\"{k}\"");
            }
        }
        for (attr, a) in [
            ("color", Attr::WallColour),
            ("roofColor", Attr::RoofColour),
            ("material", Attr::Material),
        ] {
            if let Some(c) = self.colour_for(g, src_of(a), a, None) {
                let _ = write!(info, " {attr}=\"{}\"", escape(&c));
            }
        }
        info.push_str("/>");
        if info != "<info/>" {
            self.line(inner, &info);
        }
        match &grp.shape {
            Shape::Rect([w, s, e, n]) => {
                let (w, s, e, n) = (coord(*w), coord(*s), coord(*e), coord(*n));
                let p = format!("<polygon points=\"{w} {s}, {e} {s}, {e} {n}, {w} {n}\"/>");
                self.line(inner, &p);
            }
            Shape::Kept { polygons, .. } => {
                for ring in polygons {
                    let pts: Vec<String> = ring
                        .iter()
                        .map(|[lon, lat]| format!("{} {}", coord(*lon), coord(*lat)))
                        .collect();
                    let p = format!("<polygon points=\"{}\"/>", pts.join(", "));
                    self.line(inner, &p);
                }
            }
            Shape::Earth => {}
        }
        // Appearances.
        if own_any {
            self.appearances_of(g, &src, inner, None);
            for (ci, v) in self.classes[g].clone() {
                let class_src: Vec<Option<usize>> = ATTRS
                    .iter()
                    .enumerate()
                    .map(|(ai, _)| {
                        if self.counts[v][ai] >= self.min {
                            Some(v)
                        } else {
                            src[ai]
                        }
                    })
                    .collect();
                self.appearances_of(v, &class_src, inner, Some(ci));
                self.kind_groups += 1;
            }
        } else if grp.parent.is_some() {
            self.line(
                inner,
                "<!-- No attribute of its own (too few tags): the appearances above apply. -->",
            );
        }
        for c in self.children[g].clone() {
            self.group(c, inner);
        }
        if element == "earth" {
            self.line(indent, "</earth>");
        } else {
            self.line(indent, &format!("</{element}>"));
        }
    }

    /// Writes the appearances of `g` (a zone, or a per-kind group for `class`), whose values
    /// come from `src` (per attribute).
    fn appearances_of(
        &mut self,
        g: usize,
        src: &[Option<usize>],
        indent: usize,
        class: Option<usize>,
    ) {
        let at = |a: Attr| src[ATTRS.iter().position(|&x| x == a).unwrap_or(0)];
        let (joint, how) = self.joint(at(Attr::Storeys), at(Attr::Roof));
        let (mut bins, notes) = if joint.is_empty() {
            // Colours or floor heights alone: one appearance.
            (
                vec![Bin {
                    roof: "",
                    lo: 0,
                    hi: 0,
                    mass: 1.0,
                }],
                Vec::new(),
            )
        } else {
            merge_bins(&joint, self.max_apps)
        };
        let units = round_probas(&bins.iter().map(|b| b.mass).collect::<Vec<_>>());
        let mut dropped = 0;
        let mut kept: Vec<(Bin, u32)> = Vec::new();
        for (b, u) in bins.drain(..).zip(units) {
            if u == 0 {
                dropped += 1;
            } else {
                kept.push((b, u));
            }
        }
        kept.sort_by(|(a, ua), (b, ub)| ub.cmp(ua).then(a.roof.cmp(b.roof)).then(a.lo.cmp(&b.lo)));
        let mut about = Vec::new();
        if let Some(ci) = class {
            let own: Vec<String> = ATTRS[..5]
                .iter()
                .enumerate()
                .filter(|&(ai, _)| src[ai] == Some(g))
                .map(|(ai, a)| format!("{} {}", a.name(), self.counts[g][ai]))
                .collect();
            about.push(format!(
                "for {} (building={}), from their tagged values: {}; the rest as the zone's",
                KIND_CLASSES[ci].0,
                KIND_CLASSES[ci].1.join(","),
                own.join(", ")
            ));
        }
        if !how.is_empty() {
            about.push(how);
        }
        about.extend(notes);
        if dropped > 0 {
            about.push(format!("{dropped} combinations under 0.00005 left out"));
        }
        if !about.is_empty() {
            let c = format!("<!-- Appearances: {}. -->", comment_text(&about.join("; ")));
            self.line(indent, &c);
        }
        for (b, u) in kept {
            let with_bin = (!joint.is_empty()).then_some(&b);
            let mut v = format!("<values proba=\"{}\"", num(f64::from(u) / 10_000.0, 4));
            if !b.roof.is_empty() {
                let _ = write!(v, " bdRooftype=\"{}\"", b.roof);
            }
            if b.hi > 0 {
                let _ = write!(v, " minFloors=\"{}\" maxFloors=\"{}\"", b.lo, b.hi);
            }
            if let Some(f) = self.floor_for(g, at(Attr::FloorHeight), with_bin) {
                let _ = write!(v, " floorsize=\"{}\"", num(f, 2));
            }
            for (attr, a) in [("color", Attr::WallColour), ("roofColor", Attr::RoofColour)] {
                if let Some(c) = self.colour_for(g, at(a), a, with_bin) {
                    let _ = write!(v, " {attr}=\"{}\"", escape(&c));
                }
            }
            v.push_str("/>");
            let open = match class {
                Some(ci) => format!("<appearance building=\"{}\">", KIND_CLASSES[ci].1.join(",")),
                None => "<appearance>".to_string(),
            };
            self.line(indent, &open);
            self.line(indent + 1, &v);
            self.line(indent, "</appearance>");
            self.appearances += 1;
        }
    }
}
