//! The strict reader's check of the element tree against our clean format, the same rules as
//! `schemas/kb.xsd` (kept in step with it by hand; the tests validate the shipped KB with both).
//!
//! Exact, case-sensitive element and attribute names; children in the schema's order; no empty
//! value; numbers with a decimal point (never a comma) and in range; colours `#rrggbb` or a
//! lower-case CSS name; roof shapes by their OSM name. Where this check is stricter than the XSD
//! can say (surrounding spaces in numbers, which XSD collapses; unknown CSS colour names, which
//! the XSD only checks as lower-case words), it is stricter, never looser.

use super::dom::{Elem, KbError};
use super::polygon::{PolygonError, ZonePolygon};
use crate::color::Color;
use crate::model::RoofShape;

/// The value type of an attribute.
#[derive(Clone, Copy)]
enum Ty {
    /// An appearance's footprint area range: `lo-hi`, `lo-` or `-hi`, m², decimals.
    AreaRange,
    /// `yes` or `no`.
    YesNo,
    /// A comma-separated list of `low`, `medium`, `high`.
    Densities,
    /// Decimal in a closed range.
    Dec(f64, f64),
    /// Decimal > 0.
    Pos,
    /// Decimal in `0..90` (90 excluded).
    Angle,
    /// Whole number in 0..=10000.
    Count,
    Color,
    Roof,
    WindowHeight,
    /// A LOD4 programme: house, apartments, office, retail or openplan.
    Programme,
    /// `none`, `all` or a list of `levels`, `roof`, `colour`.
    Infer,
    /// A word or phrase: no surrounding spaces.
    Token,
    /// A zone name: a token without `/`.
    Designation,
    Points,
    Axis,
    /// `a|b|c` node names.
    Children,
    /// `0.5,0.5` positive decimals.
    SplitValues,
    /// `a,b,c` node names.
    Terms,
}

const DESCRIPTORS: [(&str, Ty); 25] = [
    ("color", Ty::Color),
    ("material", Ty::Token),
    ("nbfloor", Ty::Count),
    ("floorsize", Ty::Pos),
    ("roofangle", Ty::Angle),
    ("roofColor", Ty::Color),
    ("doorCol", Ty::Color),
    ("openingCol", Ty::Color),
    ("windowfcolor", Ty::Color),
    ("windowheight", Ty::WindowHeight),
    ("windowwidth", Ty::Pos),
    ("doorwidth", Ty::Pos),
    ("doorheight", Ty::Pos),
    ("minopeningwidth", Ty::Pos),
    ("windowstyle", Ty::Token),
    ("windowmaterial", Ty::Token),
    ("minFloors", Ty::Count),
    ("maxFloors", Ty::Count),
    ("minHeight", Ty::Pos),
    ("maxHeight", Ty::Pos),
    ("maxrotation", Ty::Dec(-360.0, 360.0)),
    ("programme", Ty::Programme),
    ("cornice", Ty::Pos),
    ("corniceheight", Ty::Pos),
    ("eaves", Ty::Pos),
];

const CIRCLE: [(&str, Ty); 3] = [
    ("lat", Ty::Dec(-90.0, 90.0)),
    ("lon", Ty::Dec(-180.0, 180.0)),
    ("dist", Ty::Pos),
];

/// Zone elements below earth (`continent`: a continent or cultural region of the world KB,
/// holding countries).
pub(crate) const ZONE_ELEMENTS: [&str; 6] =
    ["continent", "country", "region", "town", "district", "zone"];

struct Ctx<'a> {
    file: &'a str,
}

impl Ctx<'_> {
    fn err(&self, line: usize, col: usize, message: String) -> KbError {
        KbError::Strict {
            file: self.file.to_string(),
            line,
            col,
            message,
        }
    }

    /// Checks `el`'s attributes: `allowed` may appear, `required` must.
    fn attrs(&self, el: &Elem, allowed: &[(&str, Ty)], required: &[&str]) -> Result<(), KbError> {
        for (k, (name, value, line)) in el.attrs.iter().enumerate() {
            let col = el.attr_cols.get(k).copied().unwrap_or(el.col);
            if name.starts_with("xmlns") || name.starts_with("xsi:") {
                continue;
            }
            let Some((_, ty)) = allowed.iter().find(|(n, _)| n == name) else {
                let hint = allowed
                    .iter()
                    .find(|(n, _)| n.eq_ignore_ascii_case(name))
                    .map_or(String::new(), |(n, _)| format!(" (did you mean '{n}'?)"));
                return Err(self.err(
                    *line,
                    col,
                    format!("unknown attribute '{name}' on <{}>{hint}", el.name),
                ));
            };
            check_value(*ty, value).map_err(|m| {
                self.err(*line, col, format!("<{}> {name}=\"{value}\": {m}", el.name))
            })?;
        }
        for r in required {
            if !el.attrs.iter().any(|(n, _, _)| n == r) {
                return Err(self.err(
                    el.line,
                    el.col,
                    format!("<{}> needs the attribute '{r}'", el.name),
                ));
            }
        }
        Ok(())
    }

    /// Checks that the children follow `groups` in order: (element names, min, max).
    fn children(&self, el: &Elem, groups: &[(&[&str], usize, usize)]) -> Result<(), KbError> {
        let mut g = 0;
        let mut count = 0;
        for c in &el.children {
            loop {
                let Some((names, min, max)) = groups.get(g) else {
                    let expected: Vec<&str> = groups
                        .iter()
                        .flat_map(|(n, _, _)| n.iter().copied())
                        .collect();
                    let hint = expected
                        .iter()
                        .find(|n| n.eq_ignore_ascii_case(&c.name))
                        .map_or(String::new(), |n| {
                            if *n == c.name {
                                " here (out of order: the schema's order is ".to_string()
                                    + &expected.join(", ")
                                    + ")"
                            } else {
                                format!(" (did you mean <{n}>?)")
                            }
                        });
                    return Err(self.err(
                        c.line,
                        c.col,
                        format!("<{}> is not allowed in <{}>{hint}", c.name, el.name),
                    ));
                };
                if names.contains(&c.name.as_str()) {
                    if count >= *max {
                        return Err(self.err(
                            c.line,
                            c.col,
                            format!("more than {max} <{}> in <{}>", c.name, el.name),
                        ));
                    }
                    count += 1;
                    break;
                }
                if count < *min {
                    return Err(self.err(
                        c.line,
                        c.col,
                        format!("<{}> needs a <{}> before <{}>", el.name, names[0], c.name),
                    ));
                }
                g += 1;
                count = 0;
            }
        }
        // Remaining groups must allow zero.
        if let Some((names, min, _)) = groups.get(g) {
            if count < *min {
                return Err(self.err(
                    el.line,
                    el.col,
                    format!("<{}> needs a <{}>", el.name, names[0]),
                ));
            }
        }
        for (names, min, _) in groups.iter().skip(g + 1) {
            if *min > 0 {
                return Err(self.err(
                    el.line,
                    el.col,
                    format!("<{}> needs a <{}>", el.name, names[0]),
                ));
            }
        }
        Ok(())
    }

    fn zone(&self, el: &Elem, is_earth: bool) -> Result<(), KbError> {
        if is_earth {
            self.attrs(el, &[], &[])?;
            self.children(
                el,
                &[
                    (&["info"], 0, 1),
                    (&["appearance"], 0, usize::MAX),
                    (&ZONE_ELEMENTS, 0, usize::MAX),
                ],
            )?;
        } else {
            self.attrs(el, &[("designation", Ty::Designation)], &["designation"])?;
            self.children(
                el,
                &[
                    (&["info"], 0, 1),
                    (&["location"], 0, 1),
                    (&["polygon"], 0, usize::MAX),
                    (&["appearance"], 0, usize::MAX),
                    (&ZONE_ELEMENTS, 0, usize::MAX),
                ],
            )?;
        }
        let info: Vec<(&str, Ty)> = DESCRIPTORS
            .iter()
            .chain(CIRCLE.iter())
            .copied()
            .chain([("rooftype", Ty::Roof), ("infer", Ty::Infer)])
            .collect();
        for c in &el.children {
            match c.name.as_str() {
                "info" => {
                    let allowed = if is_earth {
                        &info[..DESCRIPTORS.len()]
                    } else {
                        &info[..]
                    };
                    let mut allowed = allowed.to_vec();
                    if is_earth {
                        allowed.push(("rooftype", Ty::Roof));
                        allowed.push(("infer", Ty::Infer));
                    }
                    self.attrs(c, &allowed, &[])?;
                    self.children(c, &[])?;
                }
                "location" => {
                    self.attrs(c, &CIRCLE, &["lat", "lon", "dist"])?;
                    self.children(c, &[])?;
                }
                "polygon" => {
                    self.attrs(c, &[("points", Ty::Points)], &["points"])?;
                    self.children(c, &[])?;
                }
                "appearance" => self.appearance(c)?,
                _ => self.zone(c, false)?,
            }
        }
        Ok(())
    }

    fn appearance(&self, el: &Elem) -> Result<(), KbError> {
        self.attrs(
            el,
            &[
                ("building", Ty::Terms),
                ("area", Ty::AreaRange),
                ("attached", Ty::YesNo),
                ("density", Ty::Densities),
            ],
            &[],
        )?;
        self.children(
            el,
            &[
                (&["values"], 1, 1),
                (&["opening"], 0, 1),
                (&["ruleset"], 0, 1),
                (&["selex"], 0, 1),
            ],
        )?;
        let values: Vec<(&str, Ty)> = DESCRIPTORS
            .iter()
            .copied()
            .chain([
                ("bdRooftype", Ty::Roof),
                ("proba", Ty::Dec(0.0, 1.0)),
                ("balconies", Ty::Dec(0.0, 1.0)),
            ])
            .collect();
        for c in &el.children {
            match c.name.as_str() {
                "values" => {
                    self.attrs(c, &values, &[])?;
                    self.children(c, &[])?;
                }
                "opening" => {
                    self.attrs(c, &[], &[])?;
                    self.children(c, &[(&["split"], 1, usize::MAX), (&["elements"], 0, 1)])?;
                    for s in &c.children {
                        if s.name == "split" {
                            self.attrs(
                                s,
                                &[
                                    ("axis", Ty::Axis),
                                    ("parent", Ty::Token),
                                    ("children", Ty::Children),
                                    ("splitvalues", Ty::SplitValues),
                                ],
                                &["axis", "parent", "children", "splitvalues"],
                            )?;
                        } else {
                            self.attrs(
                                s,
                                &[("parent", Ty::Token), ("terms", Ty::Terms)],
                                &["parent"],
                            )?;
                        }
                        self.children(s, &[])?;
                    }
                }
                _ => {
                    self.attrs(c, &[("file", Ty::Token)], &["file"])?;
                    self.children(c, &[])?;
                }
            }
        }
        Ok(())
    }
}

/// Why an attribute's value is refused by the strict reader (the end of its message, after
/// `<element> name="value": `).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub(crate) enum ValueError {
    #[error("decimal comma: write the number with a point")]
    DecimalComma,
    #[error("not a decimal number (digits with an optional '.', no exponent)")]
    NotDecimal,
    /// Decimal digits that are not a finite number.
    #[error("not a decimal number")]
    NotFinite,
    #[error("empty value (leave the attribute out instead)")]
    Empty,
    #[error("spaces or line breaks around the value")]
    Padded,
    #[error("empty or space-padded entry in the '{sep}'-separated list")]
    ListEntry { sep: char },
    #[error("out of range {lo}..{hi}")]
    OutOfRange { lo: f64, hi: f64 },
    #[error("must be positive")]
    NotPositive,
    #[error("an angle in degrees from 0 to below 90")]
    Angle,
    #[error("not a whole number")]
    NotWhole,
    #[error("out of range 0..10000")]
    Count,
    #[error("a colour is #rrggbb or a lower-case CSS colour name")]
    Colour,
    #[error("a roof shape by its OSM roof:shape name (flat, gabled, hipped, ...)")]
    Roof,
    #[error("tall, short or irregular")]
    WindowHeight,
    #[error("an area range in m²: lo-hi, lo- or -hi (e.g. 60-250), lo below hi")]
    AreaRange,
    #[error("yes or no")]
    YesNo,
    #[error("a comma-separated list of low, medium, high")]
    Densities,
    #[error("none, all, or a comma-separated list of levels, roof, colour")]
    Infer,
    #[error("house, apartments, office, retail or openplan")]
    Programme,
    #[error("line break or tab in the value")]
    LineBreak,
    #[error("a zone name has no '/' and no line break")]
    Designation,
    #[error("{0}")]
    Polygon(#[from] PolygonError),
    #[error("X, Y or Z")]
    Axis,
    #[error("split values must be positive")]
    SplitValues,
}

/// `[+-]?(d+(.d*)?|.d+)`: the xs:decimal lexical space.
fn decimal(s: &str) -> Result<f64, ValueError> {
    let body = s.strip_prefix(['+', '-']).unwrap_or(s);
    let (int, frac) = body.split_once('.').unwrap_or((body, ""));
    let digits = |t: &str| t.bytes().all(|b| b.is_ascii_digit());
    if (int.is_empty() && frac.is_empty())
        || !digits(int)
        || !digits(frac)
        || (int.is_empty() && body.ends_with('.'))
    {
        if s.contains(',') && !s.contains('.') {
            return Err(ValueError::DecimalComma);
        }
        return Err(ValueError::NotDecimal);
    }
    s.parse::<f64>()
        .ok()
        .filter(|x| x.is_finite())
        .ok_or(ValueError::NotFinite)
}

fn check_value(ty: Ty, v: &str) -> Result<(), ValueError> {
    if v.is_empty() {
        return Err(ValueError::Empty);
    }
    if v.trim() != v {
        return Err(ValueError::Padded);
    }
    let names = |list: &str, sep: char| -> Result<(), ValueError> {
        if list.split(sep).any(|p| p.is_empty() || p.trim() != p) {
            return Err(ValueError::ListEntry { sep });
        }
        Ok(())
    };
    match ty {
        Ty::Dec(lo, hi) => {
            let x = decimal(v)?;
            if !(lo..=hi).contains(&x) {
                return Err(ValueError::OutOfRange { lo, hi });
            }
        }
        Ty::Pos => {
            if decimal(v)? <= 0.0 {
                return Err(ValueError::NotPositive);
            }
        }
        Ty::Angle => {
            let x = decimal(v)?;
            if !(0.0..90.0).contains(&x) {
                return Err(ValueError::Angle);
            }
        }
        Ty::Count => {
            let digits = v.strip_prefix('+').unwrap_or(v);
            if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
                return Err(ValueError::NotWhole);
            }
            if digits.len() > 5 || digits.parse::<u32>().map_or(true, |n| n > 10_000) {
                return Err(ValueError::Count);
            }
        }
        Ty::Color => {
            let hex = v
                .strip_prefix('#')
                .is_some_and(|h| h.len() == 6 && h.bytes().all(|b| b.is_ascii_hexdigit()));
            let name = v.bytes().all(|b| b.is_ascii_lowercase()) && Color::parse(v).is_some();
            if !hex && !name {
                return Err(ValueError::Colour);
            }
        }
        Ty::Roof => {
            if RoofShape::parse(v).map(RoofShape::osm_name) != Some(v) {
                return Err(ValueError::Roof);
            }
        }
        Ty::WindowHeight => {
            if !matches!(v, "tall" | "short" | "irregular") {
                return Err(ValueError::WindowHeight);
            }
        }
        Ty::Infer => {
            let ok = matches!(v, "none" | "all")
                || v.split(',')
                    .all(|w| matches!(w, "levels" | "roof" | "colour"));
            if !ok {
                return Err(ValueError::Infer);
            }
        }
        Ty::Programme => {
            if !matches!(v, "house" | "apartments" | "office" | "retail" | "openplan") {
                return Err(ValueError::Programme);
            }
        }
        Ty::Token => {
            if v.contains(['\n', '\r', '\t']) {
                return Err(ValueError::LineBreak);
            }
        }
        Ty::Designation => {
            if v.contains('/') || v.contains(['\n', '\r', '\t']) {
                return Err(ValueError::Designation);
            }
        }
        Ty::Points => {
            ZonePolygon::parse(v)?;
        }
        Ty::Axis => {
            if !matches!(v, "X" | "Y" | "Z") {
                return Err(ValueError::Axis);
            }
        }
        Ty::Children => names(v, '|')?,
        Ty::Terms => names(v, ',')?,
        Ty::AreaRange => {
            let (lo, hi) = v.split_once('-').ok_or(ValueError::AreaRange)?;
            for b in [lo, hi].into_iter().filter(|b| !b.is_empty()) {
                decimal(b)?;
            }
            if super::values::Conditions::parse_area(v).is_none() {
                return Err(ValueError::AreaRange);
            }
        }
        Ty::YesNo => {
            if !matches!(v, "yes" | "no") {
                return Err(ValueError::YesNo);
            }
        }
        Ty::Densities => {
            names(v, ',')?;
            if !v
                .split(',')
                .all(|w| crate::model::Density::parse(w).is_some())
            {
                return Err(ValueError::Densities);
            }
        }
        Ty::SplitValues => {
            for p in v.split(',') {
                if decimal(p)? <= 0.0 {
                    return Err(ValueError::SplitValues);
                }
            }
        }
    }
    Ok(())
}

/// Checks the whole tree; the first problem is the error.
pub(crate) fn validate(root: &Elem, file: &str) -> Result<(), KbError> {
    let ctx = Ctx { file };
    if root.name != "earth" {
        return Err(ctx.err(
            root.line,
            root.col,
            format!("the root element must be <earth>, found <{}>", root.name),
        ));
    }
    ctx.zone(root, true)
}
