//! A building's `Style`: the zone's values and the drawn appearance resolved, heights drawn,
//! OSM tags applied over them.

use std::path::PathBuf;

use super::{
    defaults, KnowledgeBase, OpeningTree, Values, WindowHeight, MAX_TAGGED_PITCH_DEG,
    MAX_TAGGED_ROOF_HEIGHT_M,
};
use crate::color::Color;
use crate::input::BuildingTags;
use crate::model::{Provenance, RoofShape, ValueSource};
use crate::rng::Rng;

/// Everything one building needs, resolved from the KB, the chosen appearance and the tags.
///
/// Heights are metres above the ground the footprint stands on. The walls run from `min_height`
/// to `eave_height`; the roof sits on top.
#[derive(Clone, Debug, PartialEq)]
pub struct Style {
    /// Top of the walls.
    pub eave_height: f64,
    /// OSM `height` when given: the top of the roof. When it is `Some` and `roof_height` is
    /// `None` on a pitched roof, `eave_height` is only a bound: the caller computes the roof
    /// height from the footprint and calls `Style::fit_total_height`.
    pub total_height: Option<f64>,
    /// Storey height in metres: the KB's `floorsize`, default 3 m. Turns `building:levels`,
    /// `building:min_level` and `roof:levels` into heights, and is the grammar's `floorsize`.
    pub floor_height: f64,
    /// Storeys between `min_height` and `eave_height` (at least 1).
    pub storeys: u32,
    /// Roof shape: OSM `roof:shape` when it is tagged and known (an unknown value gives
    /// [`RoofShape::Flat`]), else the KB's `rooftype`, else gabled.
    pub roof: RoofShape,
    /// Roof pitch in degrees, 0 ≤ angle < 90: OSM `roof:angle` (at most `MAX_TAGGED_PITCH_DEG`),
    /// else the KB's `roofangle`, else 30.
    pub roof_angle_deg: f64,
    /// OSM `roof:direction`: the compass bearing (degrees from north) the main roof face looks
    /// towards, i.e. the way a skillion slopes down. `None`: chosen from the footprint.
    pub roof_direction: Option<f64>,
    /// OSM `roof:orientation=across`: a gabled roof's ridge runs parallel to the short side.
    pub roof_across: bool,
    /// `roof:height` when tagged (0 for a flat roof); `None`: computed from the angle later.
    pub roof_height: Option<f64>,
    /// Base of the walls (OSM `min_height` / `building:min_level`), 0 by default.
    pub min_height: f64,
    /// Wall colour: OSM `building:colour`, else the usual colour of `building:material`
    /// ([`material_color`]), else the KB's `color`, else white.
    pub wall_color: Color,
    /// Roof colour: OSM `roof:colour`, else the usual colour of `roof:material`, else the KB's
    /// `roofColor`, else CSS `darkred`.
    pub roof_color: Color,
    /// Glass / opening colour.
    pub window_color: Color,
    /// Window frame colour: the KB's `windowfcolor`, else white.
    pub frame_color: Color,
    /// Front door colour: the KB's `doorCol`, else CSS `saddlebrown`.
    pub door_color: Color,
    /// Window width, metres.
    pub window_width: f64,
    /// Main entrance door width, metres: the KB's `doorwidth` within
    /// `defaults::DOOR_WIDTH_RANGE`, else `defaults::DOOR_WIDTH`.
    pub door_width: f64,
    /// Main entrance door height, metres: the KB's `doorheight` within
    /// `defaults::DOOR_HEIGHT_RANGE`, else `defaults::DOOR_HEIGHT`.
    pub door_height: f64,
    /// The narrowest window or door drawn, metres (issue 45): the KB's `minopeningwidth`, else
    /// `defaults::MIN_OPENING_WIDTH`.
    pub min_opening_width: f64,
    /// Share (0..1) of upper-floor bays with a balcony (appearance value `balconies`).
    pub balconies: f64,
    /// The cornice of a flat-roofed building's walls, (depth, height) in metres (issue 49):
    /// the KB's `cornice` within 0.05-1.0 m and `corniceheight` within 0.1-1.5 m (default
    /// 1.2 times the depth); `None` without a `cornice`.
    pub cornice: Option<(f64, f64)>,
    /// The eaves overhang of a pitched roof, metres in plan (issue 49): the KB's `eaves`
    /// within 0.1-1.5 m; `None` without one.
    pub eaves: Option<f64>,
    /// LOD4 programme for buildings whose `building=*` names no type (value `programme`).
    pub programme: Option<crate::model::Programme>,
    /// Window height class: the KB's `windowheight`, else tall.
    pub window_height: WindowHeight,
    /// `framed`, `simple`, ... (lower-case).
    pub window_style: String,
    /// `glass`, ... (lower-case).
    pub window_material: String,
    /// Wall material (`BricksBasic`, OSM `building:material`, ...), when known.
    pub material: Option<String>,
    /// Roof material (OSM `roof:material`), when known.
    pub roof_material: Option<String>,
    /// The chosen appearance's drawn window subdivision; `None`: one pane per window (zones'
    /// `<info>` have none).
    pub opening: Option<OpeningTree>,
    /// Path of the matched zone.
    pub zone_path: String,
    /// `<owner zone path>#<1-based appearance index>`, or `<zone path>#info` with no appearance.
    pub appearance_label: String,
    /// The chosen appearance's SELEX program (`KnowledgeBase::selex_path`): it lays out the
    /// facades at LOD3 instead of the rules' windows and doors. `None` when it names none (or
    /// names one outside the KB's folder, which `kb check` and the run's start refuse).
    pub selex: Option<PathBuf>,
    /// The chosen appearance's ruleset file (`KnowledgeBase::ruleset_path`, inside the KB's
    /// folder): its buildings are derived with it instead of the rules compiled from the
    /// values (which still give the axiom's attributes: `eave`, `floorsize`, ...). `None` when
    /// it names none or names one outside the folder.
    pub ruleset: Option<PathBuf>,
    /// Whether `storeys` came from `building:levels` (then `Style::fit_total_height` keeps it).
    pub storeys_from_tags: bool,
    /// The uncertainty of the storeys drawn from the knowledge base, ± storeys: half the
    /// appearance's floor range (`(maxFloors - minFloors) / 2`), or half its height range over
    /// the floor height; 0 when the storeys are fixed (`nbfloor`, one floor count, a
    /// `building=roof`). Written as the KB's `storeysError` (`Style::provenance`).
    pub storeys_error: f64,
    /// The share of the weight of the appearances this building could have been drawn from
    /// (the zone's eligible ones) whose roof has the drawn roof's family, flat or pitched: the
    /// KB's own odds for its roof. `None` when no appearance applies (the zone's values alone).
    pub roof_probability: Option<f64>,
    /// Whether the pitch came from `roof:angle`. A roof whose height follows from the
    /// knowledge base's pitch alone is capped at the height of its walls (the caller applies
    /// it: see `derive`); a tagged pitch is drawn as tagged.
    pub pitch_from_tags: bool,
}

impl Style {
    /// Where the storeys, height and roof drawn with this style come from, for a piece with
    /// these tags ([`BuildingTags::provenance`]), every value from the knowledge base given
    /// its uncertainty: `storeys_error`, the height's as that times the floor height, and
    /// `roof_probability` (each only where the tags' provenance leaves it unknown).
    pub(crate) fn provenance(&self, tags: &BuildingTags) -> Provenance {
        let mut p = tags.provenance();
        if p.storeys == ValueSource::Kb && p.storeys_error.is_none() {
            p.storeys_error = Some(self.storeys_error);
        }
        if p.height == ValueSource::Kb && p.height_error.is_none() {
            p.height_error = Some(self.storeys_error * self.floor_height);
        }
        if p.roof == ValueSource::Kb && p.roof_probability.is_none() {
            p.roof_probability = self.roof_probability;
        }
        p.rounded()
    }

    /// Draws the roof flat (a piece that another stands on): the walls take the whole height
    /// when `total_height` is known, and the storeys follow unless `building:levels` fixed them.
    pub(crate) fn make_flat(&mut self) {
        self.roof = RoofShape::Flat;
        self.roof_height = Some(0.0);
        if let Some(total) = self.total_height {
            self.eave_height = total.max(self.min_height + 0.1);
            if !self.storeys_from_tags {
                self.storeys = storeys_for(self.eave_height - self.min_height, self.floor_height);
            }
        }
    }

    /// Sets the roof height once known and, when `total_height` is set, moves the eave to
    /// `total_height - roof_height` (never below `min_height` + 1 m, or + half the height below
    /// 2 m), recomputing `storeys` from
    /// the floor height unless `building:levels` fixed them.
    pub(crate) fn fit_total_height(&mut self, roof_height: f64) {
        if !roof_height.is_finite() || roof_height < 0.0 {
            return;
        }
        self.roof_height = Some(roof_height);
        if let Some(total) = self.total_height {
            // Walls of at least 1 m, or half the height of a unit lower than 2 m (a 1 m shed
            // keeps its 1 m: 0.5 m of walls under 0.5 m of roof).
            let least = (0.5 * (total - self.min_height)).clamp(0.0, 1.0);
            self.eave_height = (total - roof_height).max(self.min_height + least);
            if !self.storeys_from_tags {
                self.storeys = storeys_for(self.eave_height - self.min_height, self.floor_height);
            }
        }
    }
}

/// `v` brought within `range` (a KB value out of bounds is drawn at the nearest bound), `or`
/// without a finite positive value.
fn within(v: Option<f64>, range: (f64, f64), or: f64) -> f64 {
    v.filter(|x| x.is_finite() && *x > 0.0)
        .map_or(or, |x| x.clamp(range.0, range.1))
}

fn storeys_for(wall_height: f64, floor_height: f64) -> u32 {
    let n = (wall_height / floor_height).round();
    if n.is_finite() && n >= 1.0 {
        n.min(1000.0) as u32
    } else {
        1
    }
}

impl KnowledgeBase {
    /// Resolves the style of one building in `zone`.
    ///
    /// Precedence, lowest first: [`defaults`]; the zone's [`KnowledgeBase::resolved`] info
    /// (`nbfloor`, `floorsize`, `rooftype`, `roofangle`, colours, ...); the chosen appearance's
    /// `<values>` (its ranges drawn with `rng`); then the OSM tags, which always win:
    /// - `height` (total, roof included) sets `total_height`; the eave is `height - roof:height`
    ///   when `roof:height` is tagged or the roof is flat, else the caller fits it
    ///   (`Style::fit_total_height`); without `height`, `building:levels` L sets the eave to
    ///   L × floor height;
    /// - `building:levels` L sets `storeys` (minus `building:min_level`);
    /// - `min_height` (else `building:min_level` × floor height) sets the base;
    /// - `roof:shape`, `roof:angle`, `roof:height`, `building:colour`, `roof:colour`,
    ///   `building:material`.
    ///
    /// Height drawing from the appearance: floors in `minFloors..=maxFloors` when given, the
    /// eave being floors × floor height clamped into `minHeight..=maxHeight`; otherwise an eave
    /// in `minHeight..maxHeight` and the storeys that fit; otherwise `nbfloor` storeys.
    /// Every override and every inconsistency fixed is described in the returned notes.
    pub fn style_for(
        &self,
        zone: usize,
        tags: &BuildingTags,
        rng: &mut Rng,
    ) -> (Style, Vec<String>) {
        self.style_for_footprint(zone, tags, (None, None), rng)
    }

    /// [`KnowledgeBase::style_for`] for a footprint of this area (m²) and form among its
    /// neighbours: the appearance is drawn among those whose conditions hold
    /// ([`super::Conditions`]). The same draws from `rng`.
    pub fn style_for_footprint(
        &self,
        zone: usize,
        tags: &BuildingTags,
        footprint: (Option<f64>, Option<crate::model::Form>),
        rng: &mut Rng,
    ) -> (Style, Vec<String>) {
        let zone = if zone < self.zones.len() { zone } else { 0 };
        // The storeys the building has (tagged or estimated), for an appearance that fits.
        let storeys = tags.levels.or_else(|| {
            let floor = self
                .resolved(zone)
                .floor_height
                .filter(|f| (2.0..8.0).contains(f))
                .unwrap_or(3.0);
            tags.height
                .map(|h| ((h - tags.min_height.unwrap_or(0.0)) / floor).round())
        });
        let pick =
            self.pick_appearance_for(zone, tags.building.as_deref(), storeys, footprint, rng);
        self.style_with_appearance(zone, pick, tags, rng)
    }

    /// [`KnowledgeBase::style_for`] with the appearance already chosen: `pick` is (owner zone,
    /// appearance index) as [`KnowledgeBase::pick_appearance`] returns it, or `None` for the
    /// zone's info values alone. Draws the heights from `rng` as `style_for` does. An
    /// out-of-range `zone` is earth; an out-of-range `pick` is ignored (info values alone).
    pub(crate) fn style_with_appearance(
        &self,
        zone: usize,
        pick: Option<(usize, usize)>,
        tags: &BuildingTags,
        rng: &mut Rng,
    ) -> (Style, Vec<String>) {
        let mut notes = Vec::new();
        let zone = if zone < self.zones.len() { zone } else { 0 };
        let zone_path = self
            .zones
            .get(zone)
            .map(|z| z.path.clone())
            .unwrap_or_else(|| "earth".into());
        let mut v = self.resolved(zone);
        let info_roof = v.roof;
        let mut opening = None;
        let app = pick.and_then(|(owner, i)| {
            let z = self.zones.get(owner)?;
            Some((z, i, z.appearances.get(i)?))
        });
        let appearance_label = match app {
            Some((owner, i, app)) => {
                v.overlay(&app.values);
                opening = app.opening.clone();
                format!("{}#{}", owner.path, i + 1)
            }
            None => format!("{zone_path}#info"),
        };

        let floor_height = v
            .floor_height
            .filter(|h| h.is_finite() && *h > 0.0)
            .unwrap_or(defaults::FLOOR_HEIGHT);
        let (storeys, wall_height, storeys_error) = draw_heights(&v, floor_height, rng, &mut notes);

        let mut style = Style {
            eave_height: wall_height,
            total_height: None,
            floor_height,
            storeys,
            roof: v.roof.unwrap_or(defaults::ROOF),
            roof_direction: None,
            roof_across: false,
            roof_angle_deg: v
                .roof_angle
                .filter(|a| a.is_finite() && (0.0..90.0).contains(a))
                .unwrap_or(defaults::ROOF_ANGLE_DEG),
            roof_height: None,
            min_height: 0.0,
            wall_color: v.wall_color.unwrap_or(defaults::WALL_COLOR),
            roof_color: v.roof_color.unwrap_or(defaults::ROOF_COLOR),
            window_color: v.window_color.unwrap_or(defaults::WINDOW_COLOR),
            frame_color: v.frame_color.unwrap_or(defaults::FRAME_COLOR),
            door_color: v.door_color.unwrap_or(defaults::DOOR_COLOR),
            window_width: v
                .window_width
                .filter(|w| w.is_finite() && *w > 0.0)
                .unwrap_or(defaults::WINDOW_WIDTH),
            door_width: within(
                v.door_width,
                defaults::DOOR_WIDTH_RANGE,
                defaults::DOOR_WIDTH,
            ),
            door_height: within(
                v.door_height,
                defaults::DOOR_HEIGHT_RANGE,
                defaults::DOOR_HEIGHT,
            ),
            min_opening_width: v
                .min_opening_width
                .filter(|w| w.is_finite() && *w > 0.0)
                .unwrap_or(defaults::MIN_OPENING_WIDTH),
            balconies: v
                .balconies
                .filter(|b| b.is_finite())
                .map_or(0.0, |b| b.clamp(0.0, 1.0)),
            cornice: v.cornice.filter(|d| d.is_finite() && *d > 0.0).map(|d| {
                let d = d.clamp(0.05, 1.0);
                let h = v
                    .cornice_height
                    .filter(|h| h.is_finite() && *h > 0.0)
                    .unwrap_or(1.2 * d);
                (d, h.clamp(0.1, 1.5))
            }),
            eaves: v
                .eaves
                .filter(|o| o.is_finite() && *o > 0.0)
                .map(|o| o.clamp(0.1, 1.5)),
            programme: v.programme,
            window_height: v.window_height.unwrap_or(WindowHeight::Tall),
            window_style: v
                .window_style
                .clone()
                .unwrap_or_else(|| "framed".into())
                .to_ascii_lowercase(),
            window_material: v
                .window_material
                .clone()
                .unwrap_or_else(|| "glass".into())
                .to_ascii_lowercase(),
            material: v.material.clone(),
            roof_material: None,
            opening,
            zone_path,
            appearance_label,
            selex: pick.and_then(|(owner, i)| self.selex_path(owner, i).ok().flatten()),
            ruleset: pick.and_then(|(owner, i)| self.ruleset_path(owner, i, false).ok().flatten()),
            storeys_from_tags: false,
            storeys_error,
            roof_probability: None,
            pitch_from_tags: false,
        };
        style.roof_probability = pick.and_then(|(owner, _)| {
            self.roof_share(owner, tags.building.as_deref(), info_roof, style.roof)
        });
        apply_tags(&mut style, tags, &mut notes);
        (style, notes)
    }
}

impl KnowledgeBase {
    /// The share of the weight of `owner`'s appearances eligible for this `building=*` kind
    /// whose roof (their own `rooftype`, else `info_roof`, else the default) is flat exactly
    /// when `drawn` is: see [`Style::roof_probability`]. `None` without eligible appearances.
    fn roof_share(
        &self,
        owner: usize,
        kind: Option<&str>,
        info_roof: Option<RoofShape>,
        drawn: RoofShape,
    ) -> Option<f64> {
        let apps = &self.zones.get(owner)?.appearances;
        let ids = super::choice::eligible(apps, kind);
        if ids.is_empty() {
            return None;
        }
        let mut weights = super::choice::proba_weights(ids.iter().map(|&i| apps[i].proba));
        if weights.iter().sum::<f64>() <= 0.0 {
            // Every weight zero: the draw is uniform.
            weights = vec![1.0; ids.len()];
        }
        let flat =
            |r: Option<RoofShape>| r.or(info_roof).unwrap_or(defaults::ROOF) == RoofShape::Flat;
        let (mut same, mut total) = (0.0, 0.0);
        for (&i, w) in ids.iter().zip(&weights) {
            total += w;
            if flat(apps[i].values.roof) == (drawn == RoofShape::Flat) {
                same += w;
            }
        }
        Some(same / total)
    }
}

/// Draws (storeys, eave height, ± storeys of the draw) from the merged values; see
/// [`KnowledgeBase::style_for`] and [`Style::storeys_error`].
fn draw_heights(v: &Values, fh: f64, rng: &mut Rng, notes: &mut Vec<String>) -> (u32, f64, f64) {
    let ok = |x: &f64| x.is_finite() && *x > 0.0;
    let (min_h, max_h) = (v.min_height.filter(ok), v.max_height.filter(ok));
    let height_range = match (min_h, max_h) {
        (Some(a), Some(b)) => Some((a.min(b), a.max(b))),
        (Some(a), None) | (None, Some(a)) => Some((a, a)),
        (None, None) => None,
    };
    let floors = match (
        v.min_floors.filter(|f| *f > 0),
        v.max_floors.filter(|f| *f > 0),
    ) {
        (Some(a), Some(b)) => Some((a.min(b), a.max(b))),
        (Some(a), None) | (None, Some(a)) => Some((a, a)),
        (None, None) => None,
    };
    match (floors, height_range) {
        (Some((f0, f1)), hr) => {
            let n = draw_int(rng, f0, f1);
            let mut h = f64::from(n) * fh;
            if let Some((a, b)) = hr {
                let c = h.clamp(a, b);
                // A millimetre of rounding (3 x 3.3 = 9.899999...) is not a disagreement.
                if (c - h).abs() > 1e-3 {
                    notes.push(format!(
                        "appearance floors ({n} x {fh} m) and heights ({a}..{b} m) disagree: eave {c} m"
                    ));
                    h = c;
                }
            }
            (n, h, f64::from(f1 - f0) / 2.0)
        }
        (None, Some((a, b))) => {
            let h = if b > a { rng.range(a, b) } else { a };
            (storeys_for(h, fh), h, (b - a) / 2.0 / fh)
        }
        (None, None) => {
            let n = v.storeys.filter(|n| *n > 0).unwrap_or(defaults::STOREYS);
            (n, f64::from(n) * fh, 0.0)
        }
    }
}

/// Uniform integer in a..=b.
fn draw_int(rng: &mut Rng, a: u32, b: u32) -> u32 {
    if b <= a {
        return a;
    }
    let span = u64::from(b - a) + 1;
    a + (rng.next_u64() % span) as u32
}

/// Applies the OSM overrides; see [`KnowledgeBase::style_for`].
fn apply_tags(s: &mut Style, t: &BuildingTags, notes: &mut Vec<String>) {
    let fh = s.floor_height;
    if let Some(shape) = t.roof_shape {
        s.roof = shape;
    } else if let Some(v) = &t.invalid_roof_shape {
        // An unreadable roof:shape says the mapper saw some roof we cannot name: flat is the
        // honest drawing, not the zone's default roof.
        s.roof = RoofShape::Flat;
        notes.push(format!(
            "roof:shape={v} is not a known roof shape: roof drawn flat"
        ));
    }
    if let Some(a) = t
        .roof_angle
        .filter(|a| a.is_finite() && (0.0..90.0).contains(a))
    {
        s.pitch_from_tags = true;
        s.roof_angle_deg = if a > MAX_TAGGED_PITCH_DEG {
            notes.push(format!(
                "roof:angle={a} is steeper than {MAX_TAGGED_PITCH_DEG}°: roof drawn at {MAX_TAGGED_PITCH_DEG}°"
            ));
            MAX_TAGGED_PITCH_DEG
        } else {
            a
        };
    }
    s.roof_direction = t
        .roof_direction
        .filter(|d| d.is_finite())
        .map(|d| d.rem_euclid(360.0));
    // roof:orientation=across (parsed, but until issue 45 never reached the style).
    if let Some(o) = &t.roof_orientation {
        s.roof_across = o == "across";
    }
    let bounded = |what: String, h: f64, notes: &mut Vec<String>| {
        if h > MAX_TAGGED_ROOF_HEIGHT_M {
            notes.push(format!(
                "{what} gives a roof {h} m high, above {MAX_TAGGED_ROOF_HEIGHT_M} m: roof drawn {MAX_TAGGED_ROOF_HEIGHT_M} m high"
            ));
            MAX_TAGGED_ROOF_HEIGHT_M
        } else {
            h
        }
    };
    // A flat roof has no height, whatever roof:height says: `height` is then the top of the
    // walls.
    if s.roof == RoofShape::Flat {
        s.roof_height = Some(0.0);
    } else if let Some(h) = t.roof_height.filter(|h| h.is_finite() && *h >= 0.0) {
        s.roof_height = Some(bounded(format!("roof:height={h}"), h, notes));
    } else if let Some(l) = t.roof_levels.filter(|l| l.is_finite() && *l > 0.0) {
        // S3DB: without roof:height, roof:levels storeys of the zone's height.
        s.roof_height = Some(bounded(format!("roof:levels={l}"), l * fh, notes));
    }
    let min_level = t.min_level.filter(|l| l.is_finite() && *l >= 0.0);
    if let Some(m) = t.min_height.filter(|m| m.is_finite() && *m >= 0.0) {
        s.min_height = m;
    } else if let Some(l) = min_level {
        s.min_height = l * fh;
    }
    let levels = t.levels.filter(|l| l.is_finite() && *l > 0.0);
    if let Some(l) = levels {
        let above = (l - min_level.unwrap_or(0.0)).round();
        s.storeys = if above >= 1.0 {
            above.min(1000.0) as u32
        } else {
            1
        };
        s.storeys_from_tags = true;
        s.eave_height = l * fh;
    } else if s.min_height > 0.0 {
        // The KB height is a wall height: stand it on the base.
        s.eave_height += s.min_height;
    }
    if let Some(h) = t.height.filter(|h| h.is_finite() && *h > 0.0) {
        s.total_height = Some(h);
        match s.roof_height {
            Some(rh) => {
                s.eave_height = h - rh;
                if levels.is_none() {
                    s.storeys = storeys_for(s.eave_height - s.min_height, fh);
                }
            }
            // Pitched roof of unknown height: an upper bound until the caller fits it.
            None => s.eave_height = s.eave_height.min(h),
        }
    }
    if s.eave_height <= s.min_height {
        notes.push(format!(
            "eave {} m not above base {} m (check height, roof:height and min_height): walls set to one storey of {fh} m",
            s.eave_height, s.min_height
        ));
        s.eave_height = s.min_height + fh;
        s.storeys = 1;
        if let Some(h) = s.total_height {
            if h <= s.eave_height {
                s.total_height = None;
            }
        }
    }
    // A colour tag wins; else a material tag gives its usual colour.
    if let Some(c) = t
        .colour
        .or_else(|| t.material.as_deref().and_then(material_color))
    {
        s.wall_color = c;
    }
    if let Some(c) = t
        .roof_colour
        .or_else(|| t.roof_material.as_deref().and_then(material_color))
    {
        s.roof_color = c;
    }
    if let Some(m) = &t.material {
        s.material = Some(m.clone());
    }
    if let Some(m) = &t.roof_material {
        s.roof_material = Some(m.clone());
    }
    if t.is_roof() {
        roof_on_pillars(s, t);
    }
}

/// Thickness of a `building=roof` drawn without `min_height` (metres): the roof slab.
pub const ROOF_SLAB_M: f64 = 0.5;

/// `building=roof` / `building:part=roof` (Simple 3D Buildings): a roof with no walls under it,
/// such as a canopy or a roof on pillars. It is drawn as a slab up to `height` (else
/// `building:levels` storeys, else one storey; with `min_height` alone, [`ROOF_SLAB_M`] above
/// it), under the tagged roof if any,
/// from `min_height` (else [`ROOF_SLAB_M`] thick): flat unless `roof:shape` says otherwise,
/// never the zone's roof and storeys.
fn roof_on_pillars(s: &mut Style, t: &BuildingTags) {
    let fh = s.floor_height;
    let base_tag = t
        .min_height
        .filter(|m| m.is_finite() && *m >= 0.0)
        .or_else(|| {
            t.min_level
                .filter(|l| l.is_finite() && *l >= 0.0)
                .map(|l| l * fh)
        });
    let top = t
        .height
        .filter(|h| h.is_finite() && *h > 0.0)
        .or_else(|| {
            t.levels
                .filter(|l| l.is_finite() && *l > 0.0)
                .map(|l| l * fh)
        })
        .filter(|h| base_tag.is_none_or(|b| *h > b))
        .unwrap_or_else(|| base_tag.map_or(fh, |b| b + ROOF_SLAB_M));
    s.storeys = 1;
    s.storeys_from_tags = true;
    s.storeys_error = 0.0;
    if t.roof_shape.is_none() {
        s.roof = RoofShape::Flat;
        s.roof_height = Some(0.0);
        // Flat by the kind, whatever the zone's appearances say.
        s.roof_probability = Some(1.0);
    }
    // The slab's top: under a roof of known height, that much lower; under one of unknown
    // height, the slab's own thickness above its base, the roof fitted into the rest.
    let eave = match s.roof_height {
        Some(rh) if rh < top => top - rh,
        Some(_) => top,
        None => top - ROOF_SLAB_M,
    };
    let base = base_tag
        .filter(|b| *b < eave)
        .unwrap_or((eave - ROOF_SLAB_M).max(0.0));
    s.min_height = base;
    s.eave_height = eave.max(base + 0.05);
    s.total_height = (top > s.eave_height + 0.05 || s.roof == RoofShape::Flat).then_some(top);
    if s.roof == RoofShape::Flat {
        s.eave_height = top;
    }
}

/// The usual colour of an OSM `building:material` / `roof:material` value, when it has one
/// ([`crate::color::material::usual_color`]: the one table of materials).
pub fn material_color(material: &str) -> Option<Color> {
    crate::color::material::usual_color(material)
}
