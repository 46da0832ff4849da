//! What a zone holds: its kind in the tree, the descriptors of its `<info>` and of each
//! `<appearance>`'s `<values>` (all optional, inherited down the tree), and the drawn opening
//! subdivisions.

use std::collections::BTreeMap;

use super::*;

/// What level of the zone tree a zone is, from its element name.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ZoneKind {
    /// `<earth>`: the root element (zone 0), whose `<info>` and appearances apply everywhere no
    /// deeper zone says otherwise.
    Earth,
    /// `<country>`.
    Country,
    /// `<region>`.
    Region,
    /// `<town>`.
    Town,
    /// `<district>`.
    District,
    /// Any other element that has a `designation` (e.g. `quarter`, `block`), lower-cased.
    Other(String),
}

impl ZoneKind {
    /// The kind for an element name (case-insensitive).
    pub(crate) fn from_element(name: &str) -> ZoneKind {
        match name.to_ascii_lowercase().as_str() {
            "earth" => ZoneKind::Earth,
            "country" => ZoneKind::Country,
            "region" => ZoneKind::Region,
            "town" => ZoneKind::Town,
            "district" => ZoneKind::District,
            other => ZoneKind::Other(other.to_string()),
        }
    }

    /// The element name.
    pub(crate) fn as_str(&self) -> &str {
        match self {
            ZoneKind::Earth => "earth",
            ZoneKind::Country => "country",
            ZoneKind::Region => "region",
            ZoneKind::Town => "town",
            ZoneKind::District => "district",
            ZoneKind::Other(s) => s,
        }
    }
}

/// The thesis's window height class (`windowheight`): tall, short or irregular (a mix).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WindowHeight {
    /// Tall windows: sill, window and lintel take 0.25, 0.6 and 0.15 of the storey height.
    Tall,
    /// Short windows: sill, window and lintel take 0.4, 0.35 and 0.25 of the storey height.
    Short,
    /// A mix: each window is drawn tall or short with probability 1/2.
    Irregular,
}

impl WindowHeight {
    /// Parses `tall`, `short`, `irregular` (case-insensitive, trimmed).
    pub(crate) fn parse(s: &str) -> Option<WindowHeight> {
        match s.trim().to_ascii_lowercase().as_str() {
            "tall" | "high" => Some(WindowHeight::Tall),
            "short" | "low" => Some(WindowHeight::Short),
            "irregular" | "mixed" => Some(WindowHeight::Irregular),
            _ => None,
        }
    }

    /// The lower-case name.
    pub(crate) fn as_str(self) -> &'static str {
        match self {
            WindowHeight::Tall => "tall",
            WindowHeight::Short => "short",
            WindowHeight::Irregular => "irregular",
        }
    }
}

/// Descriptors of a zone's `<info>` or of an appearance's `<values>`, all optional.
///
/// Attribute names (case-insensitive) and their fields: `color` → `wall_color`; `material`;
/// `nbfloor` → `storeys`; `minFloors`/`maxFloors`; `minHeight`/`maxHeight` (metres, eave
/// height range of the house, not the OSM `min_height` base); `floorsize` or `floorheight` →
/// `floor_height`; `rooftype`, `bdRooftype` or `roof` → `roof`; `roofangle`; `roofColor`;
/// `doorCol`; `openingCol` → `window_color` (the glass); `windowfcolor` (or the Madagascar
/// spelling `windowColor`) → `frame_color`; `windowheight`; `windowwidth` (metres);
/// `windowstyle`; `windowmaterial`; `maxrotation` (degrees). Anything else lands in `extra`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Values {
    /// `color` (or `colour`): wall colour.
    pub wall_color: Option<Color>,
    /// `material`: the wall material's name (e.g. `BricksBasic`), kept as [`Style::material`].
    /// Unlike the OSM `building:material` tag it does not change the wall colour.
    pub material: Option<String>,
    /// `nbfloor` (or `nbfloors`, `floors`): storeys above ground, used when the values give
    /// neither a floors range nor a height range. 0 is ignored.
    pub storeys: Option<u32>,
    /// `minFloors`: lower end of the storey range drawn uniformly for each building (with
    /// `maxFloors`; one alone fixes the number). A floors range takes precedence over a height
    /// range, which then only clamps the eave.
    pub min_floors: Option<u32>,
    /// `maxFloors`: upper end of the storey range; see `min_floors`.
    pub max_floors: Option<u32>,
    /// `minHeight`, metres (positive): lower end of the eave height range (with `maxHeight`; one
    /// alone fixes the height). Without a floors range the eave is drawn uniformly in the range
    /// and the storeys are the eave height over `floor_height`, rounded (at least 1).
    pub min_height: Option<f64>,
    /// `maxHeight`, metres (positive): upper end of the eave height range; see `min_height`.
    pub max_height: Option<f64>,
    /// `floorsize` (or `floorheight`): storey height in metres (positive); default 3 m.
    pub floor_height: Option<f64>,
    /// `rooftype` (or `bdRooftype`, `roof`, `roofshape`): roof shape, read like OSM `roof:shape`
    /// with the thesis spellings (`hip`, `gabbled`, ...) accepted.
    pub roof: Option<RoofShape>,
    /// `roofangle`: roof pitch in degrees; values outside 0..90 are ignored.
    pub roof_angle: Option<f64>,
    /// `roofColor` (or `roofcolour`): roof colour.
    pub roof_color: Option<Color>,
    /// `doorCol` (or `doorcolor`, `doorcolour`): colour of the front door panel.
    pub door_color: Option<Color>,
    /// `openingCol` (or `openingcolor`, `openingcolour`): colour of the window glass, also used
    /// for the glazed balcony doors.
    pub window_color: Option<Color>,
    /// `windowfcolor` (or `framecolor`, `framecolour`, and the thesis Madagascar spelling
    /// `windowColor`): colour of the window frames.
    pub frame_color: Option<Color>,
    /// `windowheight`: `tall`, `short` or `irregular` (also `high`, `low`, `mixed`).
    pub window_height: Option<WindowHeight>,
    /// `windowwidth`: window width in metres (positive); a facade bay is this plus a 0.9 m pier
    /// on each side.
    pub window_width: Option<f64>,
    /// `doorwidth`: width of the main entrance door in metres (positive; drawn within 0.8 to
    /// 2.5 m).
    pub door_width: Option<f64>,
    /// `doorheight`: height of the main entrance door in metres (positive; drawn within 2.0 to
    /// 2.6 m, and always under its storey's lintel).
    pub door_height: Option<f64>,
    /// `minopeningwidth`: the narrowest window or door drawn, metres (positive; default 0.4,
    /// issue 45): a narrower one is left out, never drawn as a slit.
    pub min_opening_width: Option<f64>,
    /// `windowstyle`, lower-cased: `framed` gives the windows a frame; any other word (the thesis
    /// uses `simple`) none.
    pub window_style: Option<String>,
    /// `windowmaterial`, lower-cased: `glass` makes the panes transparent; any other word draws
    /// them opaque.
    pub window_material: Option<String>,
    /// `maxrotation`, degrees: read and shown by `kb explain`, but no step of the generation uses
    /// it.
    pub max_rotation: Option<f64>,
    /// `balconies`: the share (0..1) of upper-floor bays with a balcony and a balcony door.
    pub balconies: Option<f64>,
    /// `cornice`: how far a cornice along the top of a flat-roofed building's walls stands out
    /// of them, metres (positive; LOD3 and above, issue 49).
    pub cornice: Option<f64>,
    /// `corniceheight`: the cornice's height, metres (positive; default 1.2 times its depth).
    pub cornice_height: Option<f64>,
    /// `eaves`: how far a pitched roof reaches past the walls, metres in plan (positive; LOD3
    /// and above, issue 49).
    pub eaves: Option<f64>,
    /// `programme`: the LOD4 floor-plan programme of buildings whose `building=*` tag does not
    /// name a type (untagged or `yes`).
    pub programme: Option<crate::model::Programme>,
    /// `infer` (zone `<info>` only): which values citygen may infer from tagged neighbours
    /// for the buildings of this zone that lack the tags ([`crate::prepare::infer`]).
    pub infer: Option<crate::model::Inference>,
    /// Unknown attributes, lower-cased name → trimmed value, kept for rulesets that read them.
    pub extra: BTreeMap<String, String>,
}

impl Values {
    /// Lays `more_specific` over `self`: every field it sets replaces ours; `extra` entries merge
    /// with its entries winning.
    pub(crate) fn overlay(&mut self, more_specific: &Values) {
        macro_rules! over {
            ($($f:ident),*) => { $( if more_specific.$f.is_some() { self.$f = more_specific.$f.clone(); } )* };
        }
        over!(
            wall_color,
            material,
            storeys,
            min_floors,
            max_floors,
            min_height,
            max_height,
            floor_height,
            roof,
            roof_angle,
            roof_color,
            door_color,
            window_color,
            frame_color,
            window_height,
            window_width,
            door_width,
            door_height,
            min_opening_width,
            window_style,
            window_material,
            max_rotation,
            balconies,
            cornice,
            cornice_height,
            eaves,
            programme,
            infer
        );
        for (k, v) in &more_specific.extra {
            self.extra.insert(k.clone(), v.clone());
        }
    }
}

/// Axis of an opening split on a facade: X along the wall, Z up (Y accepted for completeness).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SplitAxis {
    /// Along the wall (the opening's width).
    X,
    /// Across the wall. An opening is a face with no depth, so the grammar refuses a `Y` split
    /// of it: at LOD3 and above the derivation of a building whose appearance uses one fails.
    Y,
    /// Up (the opening's height).
    Z,
}

impl SplitAxis {
    /// `X`, `Y` or `Z`.
    pub(crate) fn as_str(self) -> &'static str {
        match self {
            SplitAxis::X => "X",
            SplitAxis::Y => "Y",
            SplitAxis::Z => "Z",
        }
    }
}

/// One `<split axis parent children splitvalues/>`: the rule
/// `parent -> rsplit(axis, fractions...){children...}`. `fractions.len() == children.len()`,
/// every fraction is positive and they sum to 1 (the reader normalises and says so).
#[derive(Clone, Debug, PartialEq)]
pub struct OpeningSplit {
    /// The `axis` attribute: the direction the parent is cut along.
    pub axis: SplitAxis,
    /// The `parent` attribute: the node being split (the tree's root stands for the whole
    /// opening).
    pub parent: String,
    /// The `children` attribute (`|`- or `,`-separated), in order along `axis`; a child that is
    /// not split again is a window pane.
    pub children: Vec<String>,
    /// The `splitvalues` attribute: each child's share of the parent along `axis`, one per child.
    pub fractions: Vec<f64>,
}

/// A drawn opening subdivision (`<opening>`): a tree of relative splits whose leaves are window
/// panes. The reader guarantees it is a tree rooted at `root` (no node split twice, no cycle,
/// every split reachable from the root).
#[derive(Clone, Debug, PartialEq)]
pub struct OpeningTree {
    /// The node standing for the whole opening (`<elements parent>`).
    pub root: String,
    /// Splits in document order.
    pub splits: Vec<OpeningSplit>,
    /// Leaf nodes (`<elements terms>`), in document order, empty entries dropped.
    pub terms: Vec<String>,
}

/// One `<appearance>`: a style alternative of a zone.
#[derive(Clone, Debug, PartialEq)]
pub struct Appearance {
    /// `proba` in 0..=1, `None` when empty or absent (see `KnowledgeBase::pick_appearance`).
    pub proba: Option<f64>,
    /// The appearance's `<values>`, laid over the zone's resolved `<info>` when it is chosen.
    pub values: Values,
    /// The appearance's `<opening>`: how each window is subdivided into panes; `None` (or a tree
    /// without splits) draws one pane per window.
    pub opening: Option<OpeningTree>,
    /// `<ruleset file="..."/>` as written (see `KnowledgeBase::ruleset_path`).
    pub ruleset: Option<String>,
    /// `<selex file="..."/>` as written: a SELEX program (docs/selex.md) that lays out the
    /// facades of this appearance's buildings at LOD3 (see `KnowledgeBase::selex_path`).
    pub selex: Option<String>,
    /// The `building` attribute: the OSM `building=*` kinds (lower-case; `yes` also stands
    /// for an untagged kind) this appearance is for. Empty: any building. When a building's
    /// kind is listed by some of a zone's appearances, it is drawn among those alone;
    /// otherwise among the appearances with no list (among all when every one has a list).
    /// See `KnowledgeBase::eligible_appearances`.
    pub buildings: Vec<String>,
    /// Where the appearance applies among the eligible ones (footprint area, attached or
    /// detached, density of the surroundings); empty: everywhere. See [`Conditions`].
    pub when: Conditions,
    /// Line of the `<appearance>` element.
    pub line: usize,
}

/// An appearance's conditions on the footprint's form (issue 42): `<appearance area="60-250"
/// attached="no" density="low,medium">`. Each given condition must hold for the appearance
/// to be drawn (one without conditions holds everywhere); a building that no eligible
/// appearance fits draws among all of them (conditions narrow a draw, they never leave a
/// building without an appearance).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Conditions {
    /// Footprint area range in m², `[lo, hi)`; `area="60-"` has no upper bound, `area="-60"`
    /// a lower bound of 0.
    pub area: Option<(f64, f64)>,
    /// `attached="yes"` (shares a wall) or `"no"`.
    pub attached: Option<bool>,
    /// The density classes it applies in (`density="low,medium"`).
    pub density: Vec<crate::model::Density>,
}

impl Conditions {
    /// No condition at all.
    pub fn is_empty(&self) -> bool {
        self.area.is_none() && self.attached.is_none() && self.density.is_empty()
    }

    /// Whether a footprint of `area` m² and `form` meets every condition; a condition on
    /// what is not known (no area, no form) holds.
    pub fn hold(&self, area: Option<f64>, form: Option<crate::model::Form>) -> bool {
        let area_ok = match (self.area, area) {
            (Some((lo, hi)), Some(a)) => a >= lo && a < hi,
            _ => true,
        };
        let attached_ok = match (self.attached, form) {
            (Some(want), Some(f)) => f.attached == want,
            _ => true,
        };
        let density_ok = match form {
            Some(f) if !self.density.is_empty() => self.density.contains(&f.density),
            _ => true,
        };
        area_ok && attached_ok && density_ok
    }

    /// Parses `area="lo-hi"` (either bound may be left out): `None` for anything else.
    pub fn parse_area(v: &str) -> Option<(f64, f64)> {
        let (lo, hi) = v.split_once('-')?;
        let bound = |s: &str, empty: f64| -> Option<f64> {
            let s = s.trim();
            if s.is_empty() {
                return Some(empty);
            }
            s.parse::<f64>().ok().filter(|x| x.is_finite() && *x >= 0.0)
        };
        let (lo, hi) = (bound(lo, 0.0)?, bound(hi, f64::INFINITY)?);
        (lo < hi).then_some((lo, hi))
    }

    /// The `area` attribute as written back: `lo-hi`, `lo-`, `-hi`.
    pub fn area_text(&self) -> Option<String> {
        let (lo, hi) = self.area?;
        let n = |x: f64| {
            let s = format!("{x:.3}");
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        };
        Some(match (lo > 0.0, hi.is_finite()) {
            (true, true) => format!("{}-{}", n(lo), n(hi)),
            (true, false) => format!("{}-", n(lo)),
            (false, true) => format!("-{}", n(hi)),
            (false, false) => "0-".to_string(),
        })
    }
}
