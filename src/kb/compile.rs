//! Appearance → grammar rules (seed 003 L815: "XML appearance data will be transformed into
//! grammar rules before being interpreted").
//!
//! [`ruleset_text`] writes rules in the thesis syntax
//! (`pred -> op(args){succ : attr=val, ... | succ} = p`). Per-building numbers are not written
//! into the text: the identifiers `eave`, `floorsize` and `bay` in expressions are numeric
//! attributes of the axiom shape, listed by [`axiom_attributes`], which the interpreter resolves
//! (an identifier in an expression that is not `sx`/`sy`/`sz` reads the current shape's numeric
//! attribute). So every building of one appearance gets the same text, and the text can be
//! parsed once and cached.
//!
//! The rules, top-down:
//! ```text
//! lot -> extrude(eave){building : color=C, roof=R, roofcolor=RC, roofangle=A}
//! building -> split(Z, floorsize, sz - floorsize){groundfloor | upperfloors}
//! upperfloors -> repeat(Z, floorsize){floor}
//! groundfloor -> comp(){front : groundfacade | others : facade}
//! floor -> comp(){side : facade}
//! facade -> repeat(X, bay){bay}
//! groundfacade -> split(X, sx/2 - bay/2, bay, sx/2 - bay/2){facade | doorbay | facade}
//! doorbay -> rsplit(X, p, w, p){wall | door : color=D | wall}
//! bay -> rsplit(X, p, w, p){wall | windowcol | wall}
//! windowcol -> rsplit(Z, sill, h, lintel){wall | opening | wall}
//! opening -> {window : style=.., framecolor=.., material=.., color=..}   (or the drawn tree)
//! ```
//! The split sizes add up to the parent exactly, so no truncation rule of the interpreter is
//! relied on; a size ≤ 0 gives no piece (a one-storey building has no `upperfloors`, a facade
//! narrower than a bay gets only the door bay). `repeat` scales its copies to fill the parent,
//! and a face too narrow for one bay becomes a plain wall.

use std::sync::Arc;

use crate::color::Color;
use crate::model::RoofShape;

use super::{OpeningTree, Style, WindowHeight};

/// Width of the wall piers on each side of a window, metres (a bay is window + 2 piers).
pub(crate) const PIER_WIDTH: f64 = 0.9;

/// A per-building value of the axiom shape: a number or a word.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum AxiomValue {
    Num(f64),
    Text(String),
}

/// The per-building attributes the axiom (`lot`) carries, in a fixed order:
/// `eave` (wall height of the extrusion, `eave_height - min_height`), `base` (`min_height`),
/// `floorsize`, `storeys`, `bay` (bay width, m), `roof`, `roofangle`, `roofheight` (when known),
/// `totalheight` (when known), `color`, `roofcolor`, `windowcolor`, `framecolor`, `doorcolor`.
pub fn axiom_attributes(style: &Style) -> Vec<(&'static str, AxiomValue)> {
    use AxiomValue::{Num, Text};
    let mut v = vec![
        ("eave", Num((style.eave_height - style.min_height).max(0.0))),
        ("base", Num(style.min_height)),
        ("floorsize", Num(style.floor_height)),
        ("storeys", Num(f64::from(style.storeys))),
        ("bay", Num(bay_width(style))),
        ("roof", Text(roof_word(style.roof))),
        ("roofangle", Num(style.roof_angle_deg)),
    ];
    if let Some(h) = style.roof_height {
        v.push(("roofheight", Num(h)));
    }
    if let Some(h) = style.total_height {
        v.push(("totalheight", Num(h)));
    }
    for (k, c) in [
        ("color", style.wall_color),
        ("roofcolor", style.roof_color),
        ("windowcolor", style.window_color),
        ("framecolor", style.frame_color),
        ("doorcolor", style.door_color),
    ] {
        v.push((k, Text(color_word(c))));
    }
    v
}

/// [`axiom_attributes`] as the grammar's attribute map, ready for [`crate::grammar::derive`].
pub(crate) fn axiom_attrs(style: &Style) -> crate::grammar::Attrs {
    use crate::grammar::AttrValue;
    // The keys are shared by every building (the map holds `Arc<str>` keys).
    static KEYS: std::sync::OnceLock<std::collections::HashMap<&'static str, Arc<str>>> =
        std::sync::OnceLock::new();
    let keys = KEYS.get_or_init(|| {
        AXIOM_KEYS
            .iter()
            .map(|k| (*k, Arc::<str>::from(*k)))
            .collect()
    });
    axiom_attributes(style)
        .into_iter()
        .map(|(k, v)| {
            let v = match v {
                AxiomValue::Num(x) => AttrValue::Num(x),
                AxiomValue::Text(t) => AttrValue::Str(t.into()),
            };
            let k = keys.get(k).cloned().unwrap_or_else(|| k.into());
            (k, v)
        })
        .collect()
}

/// Every key [`axiom_attributes`] may give.
const AXIOM_KEYS: [&str; 14] = [
    "eave",
    "base",
    "floorsize",
    "storeys",
    "bay",
    "roof",
    "roofangle",
    "roofheight",
    "totalheight",
    "color",
    "roofcolor",
    "windowcolor",
    "framecolor",
    "doorcolor",
];

/// Bay width: the window plus a pier on each side.
pub(crate) fn bay_width(style: &Style) -> f64 {
    style.window_width + 2.0 * PIER_WIDTH
}

/// A colour as the grammar writes it: its CSS name when it has one, else `#rrggbb`.
pub(crate) fn color_word(c: Color) -> String {
    c.css_name().map_or_else(|| c.to_hex(), str::to_string)
}

/// A roof shape as a grammar word: the OSM name with `-` written `_` (so `half_hipped` is one
/// identifier; [`RoofShape::parse`] reads it back).
pub(crate) fn roof_word(r: RoofShape) -> String {
    r.osm_name().replace('-', "_")
}

/// Compact, deterministic number formatting (at most 6 decimals, no trailing zeros).
fn num(x: f64) -> String {
    let s = format!("{x:.6}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" {
        "0".to_string()
    } else {
        s.to_string()
    }
}

/// Sill, window and lintel fractions of a storey for a window height class.
pub(crate) fn window_rows(h: WindowHeight) -> Vec<([f64; 3], Option<f64>)> {
    const TALL: [f64; 3] = [0.25, 0.6, 0.15];
    const SHORT: [f64; 3] = [0.4, 0.35, 0.25];
    match h {
        WindowHeight::Tall => vec![(TALL, None)],
        WindowHeight::Short => vec![(SHORT, None)],
        // A stochastic mix: half tall, half short.
        WindowHeight::Irregular => vec![(TALL, Some(0.5)), (SHORT, Some(0.5))],
    }
}

/// The grammar rules of a style, one rule per line, axiom `lot`. Same style → same text; styles
/// that differ only in heights, storeys or base give the same text (see the module docs).
pub(crate) fn ruleset_text(style: &Style) -> String {
    let mut out = Vec::new();
    out.push(format!(
        "lot -> extrude(eave){{building : color={}, roof={}, roofcolor={}, roofangle={}}}",
        color_word(style.wall_color),
        roof_word(style.roof),
        color_word(style.roof_color),
        num(style.roof_angle_deg)
    ));
    out.push(
        "building -> split(Z, floorsize, sz - floorsize){groundfloor | upperfloors}".to_string(),
    );
    out.push("upperfloors -> repeat(Z, floorsize){floor}".to_string());
    out.push("groundfloor -> comp(){front : groundfacade | others : facade}".to_string());
    if style.balconies > 0.0 {
        // Upper floors: a share of the bays get a balcony (a thin strip at the floor, which
        // LOD3 turns into a slab with a railing) and a balcony door instead of a window.
        let b = num(style.balconies);
        out.push("floor -> comp(){side : upperfacade}".to_string());
        out.push("upperfacade -> repeat(X, bay){upperbay}".to_string());
        if style.balconies < 1.0 {
            out.push(format!("upperbay -> bay = {}", num(1.0 - style.balconies)));
        }
        out.push(format!("upperbay -> balconybay = {b}"));
        out.push("balconybay -> split(Z, 0.05, sz - 0.05){balcony | balconyface}".to_string());
    } else {
        out.push("floor -> comp(){side : facade}".to_string());
    }
    out.push("facade -> repeat(X, bay){bay}".to_string());
    out.push(
        "groundfacade -> split(X, sx/2 - bay/2, bay, sx/2 - bay/2){facade | doorbay | facade}"
            .to_string(),
    );
    let bay = bay_width(style);
    let p = num(PIER_WIDTH / bay);
    let w = num(style.window_width / bay);
    out.push(format!(
        "doorbay -> rsplit(X, {p}, {w}, {p}){{wall | door : color={} | wall}}",
        color_word(style.door_color)
    ));
    out.push(format!(
        "bay -> rsplit(X, {p}, {w}, {p}){{wall | windowcol | wall}}"
    ));
    if style.balconies > 0.0 {
        out.push(format!(
            "balconyface -> rsplit(X, {p}, {w}, {p}){{wall | balconydoor | wall}}"
        ));
        out.push(format!(
            "balconydoor -> rsplit(Z, 0.8, 0.2){{door : color={}, material=glass | wall}}",
            color_word(style.window_color)
        ));
    }
    for (rows, prob) in window_rows(style.window_height) {
        let suffix = prob.map(|q| format!(" = {}", num(q))).unwrap_or_default();
        out.push(format!(
            "windowcol -> rsplit(Z, {}, {}, {}){{wall | opening | wall}}{suffix}",
            num(rows[0]),
            num(rows[1]),
            num(rows[2])
        ));
    }
    let window = window_successor(style);
    match &style.opening {
        Some(tree) if !tree.splits.is_empty() => out.extend(opening_rules(tree, &window)),
        _ => out.push(format!("opening -> {{{window}}}")),
    }
    let mut text = out.join("\n");
    text.push('\n');
    text
}

/// What [`ruleset_text`] reads of a style. Two styles whose inputs are the same bit for bit
/// get the same text, so a ruleset compiled for one serves the other without writing the text
/// again ([`RulesInputs::matches`]).
#[derive(Clone, Debug)]
pub(crate) struct RulesInputs {
    colors: [Color; 5],
    roof: RoofShape,
    numbers: [f64; 3],
    window_height: WindowHeight,
    window_style: String,
    window_material: String,
    opening: Option<OpeningTree>,
}

impl RulesInputs {
    /// The inputs of `style`.
    pub(crate) fn of(style: &Style) -> RulesInputs {
        RulesInputs {
            colors: rules_colors(style),
            roof: style.roof,
            numbers: rules_numbers(style),
            window_height: style.window_height,
            window_style: style.window_style.clone(),
            window_material: style.window_material.clone(),
            opening: style.opening.clone(),
        }
    }

    /// Whether `style` has exactly these inputs (numbers and colours compared bit for bit).
    pub(crate) fn matches(&self, style: &Style) -> bool {
        let colors = rules_colors(style);
        let numbers = rules_numbers(style);
        self.roof == style.roof
            && self.window_height == style.window_height
            && self
                .colors
                .iter()
                .zip(&colors)
                .all(|(a, b)| color_bits(*a) == color_bits(*b))
            && self
                .numbers
                .iter()
                .zip(&numbers)
                .all(|(a, b)| a.to_bits() == b.to_bits())
            && self.window_style == style.window_style
            && self.window_material == style.window_material
            && opening_same(self.opening.as_ref(), style.opening.as_ref())
    }

    /// A hash of the inputs of `style` (the same for styles that [`RulesInputs::matches`]
    /// tells apart from none), cheap: the opening tree counts by its root and size only.
    pub(crate) fn hash_of(style: &Style) -> u64 {
        use std::hash::{Hash, Hasher};
        let mut h = std::collections::hash_map::DefaultHasher::new();
        rules_colors(style).map(color_bits).hash(&mut h);
        style.roof.hash(&mut h);
        rules_numbers(style).map(f64::to_bits).hash(&mut h);
        (style.window_height as u8).hash(&mut h);
        style.window_style.hash(&mut h);
        style.window_material.hash(&mut h);
        if let Some(t) = &style.opening {
            (&t.root, t.splits.len(), t.terms.len()).hash(&mut h);
        }
        h.finish()
    }
}

fn rules_colors(style: &Style) -> [Color; 5] {
    [
        style.wall_color,
        style.roof_color,
        style.door_color,
        style.window_color,
        style.frame_color,
    ]
}

fn rules_numbers(style: &Style) -> [f64; 3] {
    [style.roof_angle_deg, style.balconies, style.window_width]
}

fn color_bits(c: Color) -> [u32; 4] {
    [c.r, c.g, c.b, c.a].map(f32::to_bits)
}

/// Opening trees equal, their fractions bit for bit.
fn opening_same(a: Option<&OpeningTree>, b: Option<&OpeningTree>) -> bool {
    match (a, b) {
        (None, None) => true,
        (Some(a), Some(b)) => {
            a.root == b.root
                && a.terms == b.terms
                && a.splits.len() == b.splits.len()
                && a.splits.iter().zip(&b.splits).all(|(x, y)| {
                    x.axis == y.axis
                        && x.parent == y.parent
                        && x.children == y.children
                        && x.fractions.len() == y.fractions.len()
                        && x.fractions
                            .iter()
                            .zip(&y.fractions)
                            .all(|(p, q)| p.to_bits() == q.to_bits())
                })
        }
        _ => false,
    }
}

/// `window : style=.., framecolor=.., material=.., color=..` for the style.
fn window_successor(style: &Style) -> String {
    format!(
        "window : style={}, framecolor={}, material={}, color={}",
        ident(&style.window_style),
        color_word(style.frame_color),
        ident(&style.window_material),
        color_word(style.window_color)
    )
}

/// A safe grammar identifier: letters, digits and `_` kept, anything else `_`; never empty and
/// never starting with a digit.
fn ident(s: &str) -> String {
    let mut o: String = s
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect();
    if o.is_empty() || o.starts_with(|c: char| c.is_ascii_digit()) {
        o.insert(0, 'n');
    }
    o
}

/// The rules of a drawn opening: the root is the non-terminal `opening`, each split
/// `parent -> rsplit(axis, f...){child | ...}`, and every leaf the `window` successor.
pub(crate) fn opening_rules(tree: &OpeningTree, window: &str) -> Vec<String> {
    let split_parents: std::collections::BTreeSet<&str> =
        tree.splits.iter().map(|s| s.parent.as_str()).collect();
    let name = |n: &str| {
        if n == tree.root {
            "opening".to_string()
        } else {
            ident(n)
        }
    };
    tree.splits
        .iter()
        .map(|s| {
            let fr: Vec<String> = s.fractions.iter().map(|f| num(*f)).collect();
            let succ: Vec<String> = s
                .children
                .iter()
                .map(|c| {
                    if split_parents.contains(c.as_str()) {
                        name(c)
                    } else {
                        window.to_string()
                    }
                })
                .collect();
            format!(
                "{} -> rsplit({}, {}){{{}}}",
                name(&s.parent),
                s.axis.as_str(),
                fr.join(", "),
                succ.join(" | ")
            )
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kb::{OpeningSplit, SplitAxis};

    fn style() -> Style {
        Style {
            eave_height: 12.0,
            total_height: None,
            floor_height: 3.0,
            storeys: 4,
            roof: RoofShape::HalfHipped,
            roof_angle_deg: 30.0,
            roof_direction: None,
            roof_across: false,
            roof_height: None,
            min_height: 0.0,
            wall_color: Color::from_rgb24(0xe9967a),
            roof_color: Color::from_rgb24(0xb5651d),
            window_color: Color::from_rgb24(0xafeeee),
            frame_color: Color::WHITE,
            door_color: Color::from_rgb24(0x8b4513),
            window_width: 1.2,
            door_width: 1.0,
            door_height: 2.2,
            min_opening_width: 0.4,
            balconies: 0.0,
            cornice: None,
            eaves: None,
            programme: None,
            window_height: WindowHeight::Tall,
            window_style: "framed".into(),
            window_material: "glass".into(),
            material: None,
            roof_material: None,
            opening: None,
            zone_path: "earth/X".into(),
            appearance_label: "earth/X#1".into(),
            selex: None,
            ruleset: None,
            storeys_from_tags: false,
            storeys_error: 0.0,
            roof_probability: None,
            pitch_from_tags: false,
        }
    }

    /// The §3.6.2 Antananarivo opening: a 2×2 pane window.
    fn two_by_two() -> OpeningTree {
        let s = |axis, p: &str, a: &str, b: &str, f: [f64; 2]| OpeningSplit {
            axis,
            parent: p.into(),
            children: vec![a.into(), b.into()],
            fractions: f.to_vec(),
        };
        OpeningTree {
            root: "nt4582467064".into(),
            splits: vec![
                s(
                    SplitAxis::X,
                    "nt4582467064",
                    "nt4582467848",
                    "nt4582467288",
                    [0.5023809523809524, 0.4976190476190476],
                ),
                s(
                    SplitAxis::Z,
                    "nt4582467848",
                    "nt4582467512",
                    "nt4582468296",
                    [0.4595238095238095, 0.5404761904761906],
                ),
                s(
                    SplitAxis::Z,
                    "nt4582467288",
                    "nt4582467736",
                    "nt4582468856",
                    [0.4595238095238095, 0.5404761904761906],
                ),
            ],
            terms: vec![
                "nt4582467512".into(),
                "nt4582468296".into(),
                "nt4582467736".into(),
                "nt4582468856".into(),
            ],
        }
    }

    #[test]
    fn text_is_stable_and_mentions_each_value() {
        let a = ruleset_text(&style());
        assert_eq!(a, ruleset_text(&style()));
        for needle in [
            "darksalmon",
            "#b5651d",
            "half_hipped",
            "roofangle=30",
            "paleturquoise",
            "saddlebrown",
            "framecolor=white",
            "material=glass",
            "style=framed",
            "extrude(eave)",
            "repeat(Z, floorsize)",
            "repeat(X, bay)",
        ] {
            assert!(a.contains(needle), "{needle} missing in\n{a}");
        }
        // Heights are axiom attributes, not text.
        let mut taller = style();
        taller.eave_height = 30.0;
        taller.storeys = 10;
        assert_eq!(a, ruleset_text(&taller));
        let mut other = style();
        other.roof = RoofShape::Flat;
        assert_ne!(a, ruleset_text(&other));
        // Window fractions: 0.9 / 3.0 and 1.2 / 3.0.
        assert!(
            a.contains("bay -> rsplit(X, 0.3, 0.4, 0.3){wall | windowcol | wall}"),
            "{a}"
        );
    }

    #[test]
    fn axiom_attributes_carry_the_numbers() {
        let mut s = style();
        s.min_height = 3.0;
        s.roof_height = Some(2.5);
        let attrs = axiom_attributes(&s);
        let get = |k: &str| attrs.iter().find(|(n, _)| *n == k).map(|(_, v)| v.clone());
        assert_eq!(get("eave"), Some(AxiomValue::Num(9.0)));
        assert_eq!(get("floorsize"), Some(AxiomValue::Num(3.0)));
        assert_eq!(get("bay"), Some(AxiomValue::Num(3.0)));
        assert_eq!(get("roofheight"), Some(AxiomValue::Num(2.5)));
        assert_eq!(get("totalheight"), None);
        assert_eq!(get("roof"), Some(AxiomValue::Text("half_hipped".into())));
        assert_eq!(RoofShape::parse("half_hipped"), Some(RoofShape::HalfHipped));
        assert_eq!(get("color"), Some(AxiomValue::Text("darksalmon".into())));
    }

    #[test]
    fn opening_tree_gives_one_rsplit_per_split() {
        let mut s = style();
        s.opening = Some(two_by_two());
        let text = ruleset_text(&s);
        let rules: Vec<&str> = text
            .lines()
            .filter(|l| l.starts_with("opening") || l.starts_with("nt"))
            .collect();
        assert_eq!(rules.len(), 3, "{text}");
        assert!(rules.iter().all(|r| r.contains("rsplit(")));
        assert!(
            rules[0].starts_with(
                "opening -> rsplit(X, 0.502381, 0.497619){nt4582467848 | nt4582467288}"
            ),
            "{}",
            rules[0]
        );
        assert_eq!(text.matches("window : style=framed").count(), 4);
        assert!(!text.contains("opening -> {window"));
    }

    #[test]
    fn irregular_windows_are_stochastic_rules_summing_to_one() {
        let mut s = style();
        s.window_height = WindowHeight::Irregular;
        let text = ruleset_text(&s);
        let alts: Vec<&str> = text
            .lines()
            .filter(|l| l.starts_with("windowcol ->"))
            .collect();
        assert_eq!(alts.len(), 2);
        assert!(alts.iter().all(|l| l.ends_with("= 0.5")));
    }

    /// The generated text goes through the real grammar: it parses, and derives a building with
    /// one door, windows on every storey and the drawn panes.
    #[test]
    fn text_parses_and_derives_with_the_grammar() {
        use crate::geometry::Polygon;
        use crate::grammar::{derive, parse, Caps, Terminal};
        use glam::DVec2;
        let lot = Polygon::new(
            vec![
                DVec2::new(0.0, 0.0),
                DVec2::new(12.0, 0.0),
                DVec2::new(12.0, 9.0),
                DVec2::new(0.0, 9.0),
            ],
            Vec::new(),
        );
        for (storeys, opening, wh) in [
            (4, None, WindowHeight::Tall),
            (1, Some(two_by_two()), WindowHeight::Irregular),
            (3, Some(two_by_two()), WindowHeight::Short),
        ] {
            let mut s = style();
            s.storeys = storeys;
            s.eave_height = f64::from(storeys) * s.floor_height;
            s.opening = opening.clone();
            s.window_height = wh;
            let text = ruleset_text(&s);
            let rules = parse(&text, "kb.rules").unwrap_or_else(|e| panic!("{e}\n{text}"));
            let tree = derive(
                &rules,
                &lot,
                axiom_attrs(&s),
                &mut crate::rng::Rng::new(1, 2),
                &Caps::default(),
            )
            .unwrap_or_else(|e| panic!("{e}\n{text}"));
            let count = |t: Terminal| tree.nodes.iter().filter(|n| n.terminal == Some(t)).count();
            assert_eq!(count(Terminal::Door), 1, "{text}");
            let panes = if opening.is_some() { 4 } else { 1 };
            let windows = count(Terminal::Window);
            assert!(
                windows > 0 && windows % panes == 0,
                "{windows} windows\n{text}"
            );
            // 12 m and 9 m facades hold 4 and 3 bays of 3 m; the ground floor front has a door bay.
            let per_storey_bays = 2 * 4 + 2 * 3;
            assert!(
                windows / panes >= per_storey_bays * storeys as usize - 2 * 4,
                "{windows}"
            );
            let window_attrs = tree
                .nodes
                .iter()
                .find(|n| n.terminal == Some(Terminal::Window))
                .map(|n| n.attrs.clone());
            let framecolor = window_attrs
                .as_ref()
                .and_then(|a| a.get("framecolor").map(|v| v.to_string()));
            assert_eq!(framecolor.as_deref(), Some("white"));
        }
    }

    #[test]
    fn numbers_are_compact() {
        assert_eq!(num(3.0), "3");
        assert_eq!(num(0.25), "0.25");
        assert_eq!(num(-0.0), "0");
        assert_eq!(num(1.0 / 3.0), "0.333333");
    }
}
