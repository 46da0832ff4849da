//! One lot to one building: zone, appearance, grammar derivation, masses, model.
//!
//! [`Generator::generate`] is a pure function of the lot, the rules and the seed: it runs on
//! any rayon thread and gives the same building whatever the thread count.

pub(crate) mod facade;
pub(crate) mod frontage;
pub mod interior;
pub mod massing;
mod overlaps;
pub mod roof;
pub mod selex;
pub mod selex_lot;
pub mod selex_place;
pub mod surroundings;
pub(crate) mod trim;

use self::massing::Mass;

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use crate::color::material::Material;
use crate::color::Color;
use crate::geometry::Polygon;
use crate::grammar::{self, AttrValue, Attrs, Caps, Geometry, Label, RuleSet, ShapeTree};
use crate::input::BuildingTags;
use crate::kb::{self, compile, KnowledgeBase, Style};
use crate::model::SourceId;
use crate::model::{Building, Lod, Part, RoofShape};
use crate::prepare::{Lot, LotPiece};
use crate::report::Outcome;
use crate::rng::Rng;

/// Mixed into the seed of the interiors' random stream ("LOD4").
const INTERIOR_STREAM: u64 = 0x4c4f_4434;

/// What the derivation of one piece of a lot (its outline or a `building:part`) works with.
#[derive(Clone, Copy)]
struct Piece<'a> {
    id: SourceId,
    /// The lot's street direction ([`Lot::front`]).
    front: Option<glam::DVec2>,
    /// The lot's ground ([`Lot::ground`]): the neighbours' heights are seen from it.
    ground: f64,
    style: &'a Style,
    rules: &'a RuleSet,
}

/// Where the rules come from.
pub enum Rules {
    /// Compiled per appearance from the knowledge base.
    Kb,
    /// One ruleset file for every building.
    File(Arc<RuleSet>),
}

/// Everything needed to turn lots into buildings.
pub struct Generator {
    /// The knowledge base that gives every lot its zone and style (`--kb`, or
    /// `KnowledgeBase::earth_only` when none is given).
    pub kb: KnowledgeBase,
    /// Where each building's grammar rules come from.
    pub rules: Rules,
    /// The LOD every building is cut at: from LOD3 the facades are read from the shape tree, at
    /// LOD4 the interiors are planned too.
    pub lod: Lod,
    /// The run's seed (`--seed`, default 0). Each piece of a lot draws from its own stream, seeded
    /// by this and the piece's [`SourceId::seed_value`], so a building's random choices depend on
    /// the seed and its id only, never on the thread count or the other buildings.
    pub seed: u64,
    /// Limits of every derivation (`--max-depth`, `--max-shapes`) and whether `comp` rules run
    /// (`facades`, which the pipeline turns on from LOD3).
    pub caps: Caps,
    /// Rulesets compiled from appearances.
    compiled: Mutex<RuleCache>,
    /// The SELEX programs the knowledge base's appearances name, by resolved path
    /// (`selex::load_all`; empty until `Generator::load_selex`). At LOD3 an appearance with
    /// one has its facades laid out by it.
    pub selex: HashMap<std::path::PathBuf, Arc<selex::SelexProgram>>,
    /// The ruleset files the knowledge base's appearances name, by resolved path, parsed
    /// (`Generator::load_rulesets`; empty until then). An appearance with one is derived with
    /// it instead of the rules compiled from its values.
    pub rulesets: HashMap<std::path::PathBuf, Arc<RuleSet>>,
    /// The other buildings around each lot, for party walls at LOD3 and above (empty: every
    /// building stands alone). See [`Generator::surroundings`].
    pub surroundings: surroundings::Surroundings,
    /// The input's admin boundaries matched to the knowledge base's zones
    /// ([`Generator::match_boundaries`]; empty until then): tried before the KB's own shapes.
    boundaries: kb::BoundaryZones,
}

/// Rulesets compiled from the knowledge base: by rule text, and by the styles' inputs to it
/// (hash, then [`compile::RulesInputs::matches`]), which spares writing the text again.
#[derive(Default)]
struct RuleCache {
    by_text: HashMap<String, Arc<RuleSet>>,
    by_inputs: HashMap<u64, Vec<(compile::RulesInputs, Arc<RuleSet>)>>,
}

/// A per-building remark for the report.
pub type Note = (Outcome, String);

impl Generator {
    /// A generator with an empty cache of rulesets compiled from the knowledge base. `caps` is used
    /// as given: set `caps.facades` for LOD3 and above, as [`crate::pipeline::run`] does.
    pub fn new(kb: KnowledgeBase, rules: Rules, lod: Lod, seed: u64, caps: Caps) -> Generator {
        Generator {
            kb,
            rules,
            lod,
            seed,
            caps,
            compiled: Mutex::new(RuleCache::default()),
            selex: HashMap::new(),
            rulesets: HashMap::new(),
            surroundings: Default::default(),
            boundaries: Default::default(),
        }
    }

    /// Matches the input's admin boundaries to the knowledge base's zones
    /// ([`kb::BoundaryZones`]): from then on [`Generator::zone_of`] tries them first.
    pub(crate) fn match_boundaries(&mut self, input: &[crate::input::AdminBoundary]) {
        self.boundaries = kb::BoundaryZones::new(&self.kb, input);
    }

    /// The matched boundaries ([`Generator::match_boundaries`]).
    pub(crate) fn boundaries(&self) -> &kb::BoundaryZones {
        &self.boundaries
    }

    /// Where a lot is: its zone ([`KnowledgeBase::locate_with`] at its representative point,
    /// the input's matched boundaries first) and the boundary it came through, if any.
    pub(crate) fn zone_of(&self, lot: &Lot) -> kb::Located {
        self.kb
            .locate_with(&self.boundaries, lot.lonlat.0, lot.lonlat.1)
    }

    /// Reads and parses the SELEX programs of the knowledge base ([`selex::load_all`]): an
    /// error names the file and the place.
    pub(crate) fn load_selex(&mut self) -> Result<(), selex::ProgramError> {
        self.selex = selex::load_all(&self.kb)?;
        Ok(())
    }

    /// Reads and parses the ruleset files the knowledge base's appearances name (inside its
    /// folder), once each. Returns a note for each one that cannot be read or does not parse
    /// (its appearance is then derived from its values, as `kb check` warns); the others are
    /// applied to their appearances' buildings.
    pub(crate) fn load_rulesets(&mut self) -> Vec<String> {
        let mut notes = Vec::new();
        let mut seen = std::collections::BTreeSet::new();
        for (z, zone) in self.kb.zones().iter().enumerate() {
            for (a, app) in zone.appearances.iter().enumerate() {
                // A refused file (outside the folder, not a file) is said by the report's
                // ruleset notes; it is never read.
                let Ok(Some(path)) = self.kb.ruleset_file(z, a, false) else {
                    continue;
                };
                if !seen.insert(path.clone()) {
                    continue;
                }
                let file = path.display().to_string();
                let at = format!("{}:{}", self.kb.source(), app.line);
                let parsed = self
                    .kb
                    .read_appearance_file(&path)
                    .map_err(|e| format!("{file}: {e}"))
                    .and_then(|text| grammar::parse(&text, &file).map_err(|e| e.to_string()));
                match parsed {
                    Ok(r) => {
                        self.rulesets.insert(path, Arc::new(r));
                    }
                    Err(e) => notes.push(format!(
                        "{at}: ruleset not applied ({e}): the appearance's values compile into \
                         its rules"
                    )),
                }
            }
        }
        notes
    }

    /// The ruleset file `style`'s appearance names, when it was loaded
    /// ([`Generator::load_rulesets`]).
    fn file_rules(&self, style: &Style) -> Option<Arc<RuleSet>> {
        style
            .ruleset
            .as_ref()
            .and_then(|p| self.rulesets.get(p))
            .cloned()
    }

    /// The parts of every lot `keep` selects, derived at LOD2 (their footprints, bases and tops:
    /// what a neighbour needs), for [`Generator::surroundings`]. Each lot on its own random
    /// stream, as [`Generator::generate`] derives it, so the heights are those it will have;
    /// lots that fail are left out (they are not written either).
    pub fn neighbours_of(
        &self,
        lots: &[Lot],
        keep: impl Fn(usize) -> bool + Sync,
    ) -> surroundings::Surroundings {
        use rayon::prelude::*;
        let parts: Vec<Vec<surroundings::Neighbour>> = lots
            .par_iter()
            .enumerate()
            .map(|(i, lot)| {
                if !keep(i) {
                    return Vec::new();
                }
                let derived =
                    crate::guard::caught(|| "deriving a neighbour", || self.derive(lot, Lod::Lod2));
                match derived {
                    Ok(Ok((b, _))) => b
                        .parts
                        .iter()
                        .map(|p| surroundings::Neighbour::of_part(lot.id, p))
                        .collect(),
                    _ => Vec::new(),
                }
            })
            .collect();
        surroundings::Surroundings::new(parts.into_iter().flatten().collect())
    }

    /// Builds one lot. `Err` carries the reason the building is skipped. A panic while
    /// deriving it (a bug, in citygen or in a geometry crate, that one footprint sets off) is
    /// caught and becomes that reason, so it costs one building, not the whole run.
    pub fn generate(&self, lot: &Lot) -> Result<(Building, Vec<Note>), String> {
        crate::guard::caught(|| "deriving the building", || self.derive(lot, self.lod))
            .unwrap_or_else(|e| Err(e.to_string()))
    }

    /// The building of `lot` at `lod` (the generator's own, or LOD2 for its neighbours).
    fn derive(&self, lot: &Lot, lod: Lod) -> Result<(Building, Vec<Note>), String> {
        let zone = self.zone_of(lot).zone;
        let mut notes = Vec::new();
        let mut pieces: Vec<&LotPiece> = lot.parts.iter().collect();
        let outline;
        if !lot.drawn_outline().is_empty() {
            // An outline's rest is drawn with the outline's own tags (issue 45), not with what
            // the estimator or the neighbours lent the outline.
            outline = LotPiece {
                id: lot.id,
                polygons: lot.drawn_outline().to_vec(),
                tags: lot.rest_tags.clone().unwrap_or_else(|| lot.tags.clone()),
            };
            pieces.insert(0, &outline);
        }
        let rest_role = if lot.rest_tags.is_some() {
            crate::model::PartRole::OutlineRest
        } else {
            crate::model::PartRole::Own
        };
        let mut label = None;
        // Every piece's style first: whether a piece's roof is drawn depends on the pieces
        // stacked on it.
        let mut styled = Vec::with_capacity(pieces.len());
        // The building's footprint for the KB's appearance conditions (issue 42).
        let footprint = (
            Some(lot.polygons.iter().map(Polygon::area).sum::<f64>()),
            lot.tags.form,
        );
        for piece in pieces {
            let mut rng = Rng::new(self.seed, piece.id.seed_value());
            let tags = merged_tags(&piece.tags, &lot.tags, piece.id != lot.id);
            let (style, style_notes) = self
                .kb
                .style_for_footprint(zone, &tags, footprint, &mut rng);
            notes.extend(style_notes.into_iter().map(|n| (Outcome::Note, n)));
            if label.is_none() {
                label = Some(style.appearance_label.clone());
            }
            styled.push((piece, tags, style, rng));
        }
        flatten_covered_roofs(&mut styled);
        if let Some(note) = floating_note(&styled) {
            notes.push((Outcome::Note, note));
        }
        let plans = overlaps::resolve_overlaps(&styled, &mut notes);
        // Every part first (at LOD3, with the openings its rules found): the facade rules look
        // at the whole building.
        let mut drafts: Vec<(Part, Option<facade::Facades>, usize)> = Vec::new();
        let mut styles: Vec<(Style, BuildingTags)> = Vec::with_capacity(styled.len());
        // The rule files that drew the parts, for a message when they drew nothing.
        let mut files: Vec<Arc<str>> = Vec::new();
        for ((piece, tags, style, mut rng), plan) in styled.into_iter().zip(plans) {
            let rules = self.rules_for(&style)?;
            if !files.contains(&rules.file) {
                files.push(rules.file.clone());
            }
            for (polygon, band) in plan
                .iter()
                .flat_map(|p| p.polygons.iter().map(move |q| (q, p.band)))
            {
                let banded = band.map(|b| overlaps::banded(&style, b));
                // A band below the top is flat: its own rules, not the whole part's roof.
                let band_rules = match &banded {
                    Some(b) => Some(self.rules_for(b)?),
                    None => None,
                };
                let on = Piece {
                    id: piece.id,
                    front: lot.front,
                    ground: lot.ground,
                    style: banded.as_ref().unwrap_or(&style),
                    rules: band_rules.as_ref().unwrap_or(&rules),
                };
                let masses = self.masses(&on, polygon, lod, &mut rng, &mut notes)?;
                for (mass, facades) in masses {
                    let key = format!("p{}", drafts.len());
                    let (mut part, roof_notes) =
                        massing::part_with_roof(key, &mass, lod, &piece.id.to_string(), |m| {
                            massing::roof_geometry(m).map(|r| cap_guessed_roof(r, m, &style))
                        });
                    notes.extend(roof_notes.into_iter().map(|n| (Outcome::Note, n)));
                    part.source = Some(piece.id);
                    part.structure = tags.structure;
                    part.wall_material = Material::of(style.material.as_deref());
                    part.roof_material = Material::of(style.roof_material.as_deref());
                    // The rhythm the KB's rules give the walls (issue 49): a LOD2 facade
                    // texture draws it; a ruleset file's facades are its own.
                    if part.structure.is_none()
                        && matches!(self.rules, Rules::Kb)
                        && self.file_rules(&style).is_none()
                    {
                        part.rhythm = Some(rhythm_of(&style));
                    }
                    if piece.id == lot.id {
                        part.role = rest_role;
                    }
                    drafts.push((part, facades, styles.len()));
                }
            }
            styles.push((style, tags));
        }
        let mut counts = crate::model::FacadeCounts::default();
        let mut entrance = None;
        let mut spans = Vec::new();
        if lod >= Lod::Lod3 {
            let mut views: Vec<frontage::Draft<'_>> = Vec::new();
            let mut index = Vec::new();
            for (i, (part, facades, s)) in drafts.iter_mut().enumerate() {
                if let Some(f) = facades.as_mut() {
                    let structure = part.structure;
                    views.push(frontage::Draft {
                        part,
                        facades: f,
                        style: &styles[*s].0,
                        structure,
                    });
                    index.push(i);
                }
            }
            // Facades from the knowledge base's values are arranged over the building; those
            // of a ruleset file (--rules, or an appearance's) are kept as its rules made them.
            let from_style = matches!(self.rules, Rules::Kb)
                && !styles.iter().any(|(s, _)| self.file_rules(s).is_some());
            let slope = lot
                .terrain
                .as_deref()
                .map(|g| frontage::Slope::new(g, lot.ground));
            let a = frontage::arrange(
                &mut views,
                (lot.id, lot.ground),
                lot.front,
                &self.surroundings,
                from_style,
                slope,
            );
            if let Some(n) = a.note {
                notes.push((Outcome::Note, n));
            }
            notes.extend(a.slope_notes.into_iter().map(|n| (Outcome::Note, n)));
            counts = a.counts;
            entrance = a.entrance.map(|(v, n)| (index[v], n));
            spans = index.into_iter().zip(a.spans).collect::<Vec<_>>();
        }
        let mut parts: Vec<Part> = Vec::with_capacity(drafts.len());
        let mut part_styles = Vec::with_capacity(drafts.len());
        for (i, (mut part, facades, s)) in drafts.into_iter().enumerate() {
            part_styles.push(s);
            let (style, tags) = &styles[s];
            if let Some(f) = facades {
                let colors = facade::OpeningColors {
                    window: style.window_color,
                    frame: style.frame_color,
                    door: style.door_color,
                    min_width: style.min_opening_width,
                };
                let dropped = facade::apply(&mut part, &f, &colors);
                if dropped > 0 {
                    notes.push((
                        Outcome::Note,
                        format!("{dropped} opening(s) too small or overlapping were left out"),
                    ));
                }
                // `spans` is in draft order: found by halves, not by a walk over every part.
                if let Some((_, sp)) = spans
                    .binary_search_by_key(&i, |(j, _)| *j)
                    .ok()
                    .and_then(|k| spans.get(k))
                {
                    frontage::mark_party_walls(&mut part, sp, &mut counts);
                }
            }
            // A structure has no rooms (issue 45).
            if lod >= Lod::Lod4 && part.structure.is_none() {
                // The entrance's wall is the plan's front; other parts face the street.
                let front = match entrance {
                    Some((j, n)) if j == i => Some(n),
                    _ => lot.front,
                };
                part.interior = self.interior(
                    &part,
                    tags,
                    style.programme,
                    front,
                    part.source.unwrap_or(lot.id),
                    i,
                );
            }
            parts.push(part);
        }
        // Cornices and eaves where the knowledge base asks (issue 49), against the neighbours.
        if lod >= Lod::Lod3 {
            let of: Vec<&Style> = part_styles.iter().map(|&s| &styles[s].0).collect();
            trim::apply(&mut parts, &of, (lot.id, lot.ground), &self.surroundings);
        }
        if parts.is_empty() {
            return Err(format!(
                "the rules produced no building mass ({}: no rule extrudes the lot)",
                files.join(", ")
            ));
        }
        if let Some(note) = structure_note(&parts) {
            notes.push((Outcome::Note, note));
        }
        let base_z = parts.iter().map(|p| p.base_z).fold(f64::INFINITY, f64::min);
        let top = parts
            .iter()
            .map(|p| p.top_z)
            .fold(f64::NEG_INFINITY, f64::max);
        // The building's storeys, roof and their provenance are its tallest part's.
        let tallest = (0..parts.len()).max_by(|&a, &b| parts[a].top_z.total_cmp(&parts[b].top_z));
        let (storeys, roof_shape) = tallest.map_or((1, RoofShape::Flat), |i| {
            (parts[i].storeys, parts[i].roof_shape)
        });
        let provenance = tallest
            .and_then(|i| styles.get(part_styles[i]))
            .map(|(style, tags)| style.provenance(tags))
            .unwrap_or_default();
        let mut building = Building {
            id: lot.id,
            name: lot.tags.name.clone(),
            zone: self.kb.zone_path(zone).to_string(),
            appearance: match &self.rules {
                Rules::Kb => label.unwrap_or_default(),
                Rules::File(r) => format!("rules:{}", r.file()),
            },
            base_z,
            // Derived on the ground at z = 0 (raised below): the top is above the ground, as
            // OSM's `height`, also for a building whose every part floats.
            ground_z: 0.0,
            measured_height: top,
            storeys_above_ground: storeys,
            roof_shape,
            parts,
            lod,
            facade: counts,
            provenance,
            attributes: None,
        };
        // Seated on its ground (issue 44): derived on z = 0, then raised whole.
        if lot.ground != 0.0 {
            building.raise(lot.ground);
        }
        Ok((building, notes))
    }

    /// The LOD4 interior of a finished part: floor plans on its footprint, one per storey.
    /// Its own random stream (seeded by the piece and the part), so that interiors never change
    /// the exterior's choices.
    fn interior(
        &self,
        part: &Part,
        tags: &BuildingTags,
        kb_programme: Option<interior::Programme>,
        front: Option<glam::DVec2>,
        id: SourceId,
        index: usize,
    ) -> Vec<crate::model::StoreyInterior> {
        // The knowledge base's programme is a default for buildings of no declared type: a
        // `building=office` tag is a fact about the building, the zone's programme a guess.
        let untyped = tags
            .building
            .as_deref()
            .is_none_or(|b| matches!(b.trim().to_ascii_lowercase().as_str(), "" | "yes"));
        let storeys = part.levels.len().max(1) as u32;
        let input = interior::PlanInput {
            footprint: &part.footprint,
            storeys,
            storey_height: (part.eave_z - part.base_z) / f64::from(storeys),
            building: tags.building.as_deref(),
            programme: kb_programme.filter(|_| untyped),
            front,
            wall_thickness: massing::WALL_THICKNESS,
        };
        let mut rng = Rng::new(self.seed ^ INTERIOR_STREAM, id.seed_value() ^ index as u64);
        let plan = interior::plan_building(&input, &mut rng);
        interior::to_model::storeys_of(part, &plan)
    }

    fn rules_for(&self, style: &Style) -> Result<Arc<RuleSet>, String> {
        match &self.rules {
            Rules::File(r) => Ok(r.clone()),
            Rules::Kb => {
                if let Some(r) = self.file_rules(style) {
                    return Ok(r);
                }
                // By the style's inputs to the rule text first: most buildings share them, and
                // then the text is not written again.
                let h = compile::RulesInputs::hash_of(style);
                // A cache poisoned by a caught panic in another building still holds only
                // fully parsed rulesets (an entry is inserted after its parse), so it is used.
                let mut cache = self.compiled.lock().unwrap_or_else(|e| e.into_inner());
                if let Some((_, r)) = cache
                    .by_inputs
                    .get(&h)
                    .and_then(|b| b.iter().find(|(i, _)| i.matches(style)))
                {
                    return Ok(r.clone());
                }
                let text = compile::ruleset_text(style);
                let r = match cache.by_text.get(&text) {
                    Some(r) => r.clone(),
                    None => {
                        let parsed =
                            grammar::parse(&text, &format!("<kb {}>", style.appearance_label))
                                .map_err(|e| {
                                    format!(
                                "rules compiled from the knowledge base {} do not parse: {e}",
                                self.kb.source()
                            )
                                })?;
                        let r = Arc::new(parsed);
                        cache.by_text.insert(text, r.clone());
                        r
                    }
                };
                let inputs = compile::RulesInputs::of(style);
                cache
                    .by_inputs
                    .entry(h)
                    .or_default()
                    .push((inputs, r.clone()));
                Ok(r)
            }
        }
    }

    /// Derives one footprint polygon and returns the masses of the tree. `front` is the lot's
    /// street direction ([`Lot::front`]): every piece of the lot turns its front towards it.
    fn masses(
        &self,
        piece: &Piece<'_>,
        polygon: &Polygon,
        lod: Lod,
        rng: &mut Rng,
        notes: &mut Vec<Note>,
    ) -> Result<Vec<(Mass, Option<facade::Facades>)>, String> {
        let Piece {
            id,
            front,
            ground,
            style,
            rules,
        } = *piece;
        let mut style = style.clone();
        // A total height with a pitched roof of unknown height: the eave is what is left under
        // the roof at the zone's pitch.
        if let (Some(total), None, true) = (
            style.total_height,
            style.roof_height,
            style.roof != RoofShape::Flat,
        ) {
            let probe = Mass {
                footprint: polygon.clone(),
                base_z: 0.0,
                eave_z: 0.0,
                storeys: 1,
                roof: style.roof,
                roof_angle_deg: style.roof_angle_deg,
                roof_direction: style.roof_direction,
                roof_across: style.roof_across,
                roof_height: None,
                wall_color: style.wall_color,
                roof_color: style.roof_color,
            };
            match massing::roof_geometry(&probe) {
                Ok(r) => {
                    let usable = (total - style.min_height).max(0.0);
                    style.fit_total_height(r.height.min(0.5 * usable));
                }
                // The roof will be drawn flat: the walls take the whole height.
                Err(f) => {
                    notes.push((
                        Outcome::Note,
                        format!("{} roof drawn flat: {}", f.asked.osm_name(), f.reason),
                    ));
                    style.roof = RoofShape::Flat;
                    style.fit_total_height(0.0);
                }
            }
        }
        // building:levels wins over the zone's storey height: the walls are shared out evenly
        // among the tagged storeys (13 levels in 70 m are 13 storeys of 5.4 m, not 23 of 3).
        let walls = style.eave_height - style.min_height;
        if style.storeys_from_tags && style.storeys > 0 && walls > 0.0 {
            style.floor_height = walls / f64::from(style.storeys);
        }
        let attrs: Attrs = compile::axiom_attrs(&style);
        let caps = Caps {
            facades: self.caps.facades && lod >= Lod::Lod3,
            ..self.caps
        };
        let tree =
            grammar::derive_facing(rules, polygon, front, attrs, rng, &caps).map_err(|e| {
                // Rules the KB compiled are named by their appearance: say which KB file.
                let kb = if rules.file.starts_with("<kb ") {
                    format!(" (rules compiled from {})", self.kb.source())
                } else {
                    String::new()
                };
                format!("derivation failed for {id}: {e}{kb}")
            })?;
        let masses = masses_of(&tree, &style);
        if lod < Lod::Lod3 {
            grammar::recycle(tree);
            return Ok(masses.into_iter().map(|m| (m, None)).collect());
        }
        let nodes = mass_nodes(&tree);
        let footprints: Vec<Polygon> = masses.iter().map(|m| m.footprint.clone()).collect();
        let mut out = Vec::with_capacity(masses.len());
        for (m, i) in masses.into_iter().zip(nodes) {
            let mut f = facade::facades_of(
                &tree,
                i,
                &m.footprint,
                (m.base_z, m.eave_z),
                style.floor_height,
            );
            let mut bays = Vec::new();
            if let Some(program) = style.selex.as_ref().and_then(|p| self.selex.get(p)) {
                match selex::apply(program, &m.footprint, m.base_z, front, &mut f) {
                    Ok(applied) => {
                        notes.extend(
                            applied
                                .warnings
                                .into_iter()
                                .map(|w| (Outcome::Note, format!("facade program: {w}"))),
                        );
                        bays = applied.bays;
                    }
                    Err(why) => notes.push((
                        Outcome::Note,
                        format!("facade program not applied ({why}): the rules' facades kept"),
                    )),
                }
            }
            let bay_masses = self.bay_masses((id, ground), &m, bays, &footprints, notes);
            out.push((m, Some(f)));
            out.extend(bay_masses);
        }
        grammar::recycle(tree);
        Ok(out)
    }

    /// The bays a SELEX program pushed out of mass `m`'s walls as masses of their own (flat
    /// roofs, `m`'s colours), each with its facades. A bay that would overlap another mass of
    /// the piece (`footprints`) or a neighbouring building is left out, with a note; one whose
    /// rounding cannot be drawn (`selex::Bay::rounded`) is drawn square, with a note.
    fn bay_masses(
        &self,
        (owner, ground): (SourceId, f64),
        m: &Mass,
        bays: Vec<selex::Bay>,
        footprints: &[Polygon],
        notes: &mut Vec<Note>,
    ) -> Vec<(Mass, Option<facade::Facades>)> {
        let mut out = Vec::new();
        let mut taken: Vec<Polygon> = Vec::new();
        for b in bays {
            let (lo, hi) = b.footprint.bounds();
            let near = self.surroundings.near(owner, lo, hi);
            let neighbours = near
                .iter()
                .filter(|n| n.z0 - ground < b.z1 && b.z0 < n.z1 - ground)
                .filter_map(|n| {
                    let (outer, holes) = n.rings.split_first()?;
                    Some(Polygon::new(outer.clone(), holes.to_vec()))
                });
            let blocked = footprints
                .iter()
                .chain(taken.iter())
                .cloned()
                .chain(neighbours)
                .any(|p| overlap_area(&b.footprint, &p) > 0.01);
            if blocked {
                notes.push((
                    Outcome::Note,
                    format!(
                        "facade program: bay `{}` left out: it would stand in another building or part",
                        b.label
                    ),
                ));
                continue;
            }
            if b.rounded {
                notes.push((
                    Outcome::Note,
                    format!(
                        "facade program: bay `{}` drawn square: its roundShape is not on its front about a vertical axis",
                        b.label
                    ),
                ));
            }
            taken.push(b.footprint.clone());
            let storeys = b.facades.levels.len().max(1) as u32;
            out.push((
                Mass {
                    footprint: b.footprint,
                    base_z: b.z0,
                    eave_z: b.z1,
                    storeys,
                    roof: RoofShape::Flat,
                    roof_height: None,
                    ..m.clone()
                },
                Some(b.facades),
            ));
        }
        out
    }
}

/// A roof whose height nothing on the map gives (no `roof:height`, `roof:levels`, `roof:angle`
/// or `height`: the knowledge base's pitch over the footprint alone) is no taller than the
/// walls under it, so that a deep footprint does not get a roof higher than the building (a
/// 30° roof over 40 m of depth is 11.5 m). Tagged roofs are drawn as tagged.
/// The facade rhythm `kb::compile` writes for `style` (a bay of pier, window, pier; the first
/// of its window rows' sill and height shares).
fn rhythm_of(style: &Style) -> crate::model::Rhythm {
    let rows = kb::compile::window_rows(style.window_height);
    let [sill, height, _] = rows.first().map_or([0.25, 0.6, 0.15], |r| r.0);
    crate::model::Rhythm {
        bay: kb::compile::bay_width(style),
        window: style.window_width,
        sill,
        height,
    }
}

fn cap_guessed_roof(
    roof: crate::derive::roof::RoofGeometry,
    mass: &Mass,
    style: &Style,
) -> crate::derive::roof::RoofGeometry {
    let walls = mass.eave_z - mass.base_z;
    let guessed = mass.roof_height.is_none() && !style.pitch_from_tags;
    if guessed && walls > 0.0 && roof.height > walls {
        roof.scaled_to_height(walls)
    } else {
        roof
    }
}

/// A piece whose base is this close below the top of another's walls (metres), or higher,
/// stands on it.
const STACK_TOLERANCE: f64 = 0.5;

/// Simple 3D Buildings: a piece with no `roof:shape` of its own on which another piece stands
/// (the other's base at or above this one's eave, and their plans overlapping) has a flat top;
/// the knowledge base's roof is for untagged outlines and the top pieces only. Without this,
/// each roof of a stack of parts runs up through the parts above it.
fn flatten_covered_roofs(styled: &mut [(&LotPiece, BuildingTags, Style, Rng)]) {
    let near = boxes_meeting(styled);
    let covered: Vec<bool> = (0..styled.len())
        .map(|i| {
            let (below, tags, style, _) = &styled[i];
            if tags.roof_shape.is_some() || style.roof == RoofShape::Flat {
                return false;
            }
            near[i].iter().any(|&j| {
                let (above, _, s, _) = &styled[j];
                j != i
                    && s.min_height > style.min_height
                    && s.min_height >= style.eave_height - STACK_TOLERANCE
                    && plans_overlap(&below.polygons, &above.polygons)
            })
        })
        .collect();
    for ((_, _, style, _), flat) in styled.iter_mut().zip(covered) {
        if flat {
            style.make_flat();
        }
    }
}

/// Up to this many pieces, [`boxes_meeting`] gives every piece as a candidate of every other.
const FEW_PIECES: usize = 16;

/// For each piece, the pieces (itself included, in order) whose plan's bounding box meets its
/// own, closed: the only ones its plan can overlap. An R-tree of the boxes, so that a building
/// of 10,000 parts asks each about its neighbours, not about every other part. A piece with a
/// coordinate that is not finite has no box and meets every piece. Up to [`FEW_PIECES`]
/// pieces, every piece is given (a superset: the callers test the plans).
fn boxes_meeting(styled: &[(&LotPiece, BuildingTags, Style, Rng)]) -> Vec<Vec<usize>> {
    use rstar::primitives::{GeomWithData, Rectangle};
    use rstar::{RTree, RTreeObject};
    let n = styled.len();
    if n <= FEW_PIECES {
        // Every piece is a candidate (the callers test the plans themselves, as they did for
        // every pair before the index): nearly every building has one piece or a few.
        return (0..n).map(|_| (0..n).collect()).collect();
    }
    let bounds = |ps: &[Polygon]| {
        let (mut lo, mut hi) = (glam::DVec2::INFINITY, glam::DVec2::NEG_INFINITY);
        for p in ps.iter().flat_map(|p| p.rings()).flatten() {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        (lo, hi)
    };
    let boxes: Vec<Option<(glam::DVec2, glam::DVec2)>> = styled
        .iter()
        .map(|(p, ..)| {
            let all_finite = p
                .polygons
                .iter()
                .flat_map(|p| p.rings())
                .flatten()
                .all(|q| q.is_finite());
            let (lo, hi) = bounds(&p.polygons);
            (all_finite && lo.x <= hi.x && lo.y <= hi.y).then_some((lo, hi))
        })
        .collect();
    let unboxed: Vec<usize> = (0..n).filter(|&i| boxes[i].is_none()).collect();
    let tree = RTree::bulk_load(
        boxes
            .iter()
            .enumerate()
            .filter_map(|(i, b)| {
                b.map(|(lo, hi)| {
                    GeomWithData::new(Rectangle::from_corners(lo.to_array(), hi.to_array()), i)
                })
            })
            .collect::<Vec<_>>(),
    );
    (0..n)
        .map(|i| {
            let mut near: Vec<usize> = match boxes[i] {
                Some((lo, hi)) => {
                    let env = Rectangle::from_corners(lo.to_array(), hi.to_array()).envelope();
                    tree.locate_in_envelope_intersecting(env)
                        .map(|g| g.data)
                        .chain(unboxed.iter().copied())
                        .collect()
                }
                None => (0..n).collect(),
            };
            near.sort_unstable();
            near
        })
        .collect()
}

/// Whether two pieces' plans overlap: a point inside one of them lies in the other.
/// The area two polygons share, square metres (0 for polygons that only touch).
fn overlap_area(a: &Polygon, b: &Polygon) -> f64 {
    let left: f64 =
        crate::geometry::clip::difference(std::slice::from_ref(a), std::slice::from_ref(b))
            .iter()
            .map(|p| p.area())
            .sum();
    (a.area() - left).max(0.0)
}

fn plans_overlap(a: &[Polygon], b: &[Polygon]) -> bool {
    let inside = |p: &[Polygon], q: &[Polygon]| {
        p.iter()
            .map(crate::prepare::interior_point)
            .any(|pt| q.iter().any(|poly| poly.contains(pt)))
    };
    inside(a, b) || inside(b, a)
}

/// A note when every piece of a building starts above the ground (nothing is drawn under it),
/// unless the building is a roof on pillars (`building=roof`), which does by nature.
fn floating_note(styled: &[(&LotPiece, BuildingTags, Style, Rng)]) -> Option<String> {
    let lowest = styled
        .iter()
        .map(|(_, _, s, _)| s.min_height)
        .fold(f64::INFINITY, f64::min);
    let roofs = styled.iter().all(|(_, t, _, _)| t.is_roof());
    (lowest.is_finite() && lowest > 0.0 && !roofs).then(|| {
        format!(
            "every part starts above the ground (the lowest at {lowest} m, from min_height or building:min_level): the building is drawn floating, with nothing under it"
        )
    })
}

/// The report's note on a building with structures (issue 45): how many parts of each class,
/// drawn without a house's openings and rooms. `None` when no part is a structure.
fn structure_note(parts: &[Part]) -> Option<String> {
    let mut counts: Vec<(crate::model::Structure, usize)> = Vec::new();
    for class in parts.iter().filter_map(|p| p.structure) {
        match counts.iter_mut().find(|(c, _)| *c == class) {
            Some((_, n)) => *n += 1,
            None => counts.push((class, 1)),
        }
    }
    if counts.is_empty() {
        return None;
    }
    let list: Vec<String> = counts
        .iter()
        .map(|(c, n)| format!("{} {n}", c.name()))
        .collect();
    Some(format!(
        "structure: {} of {} part(s) ({}): no windows, doors, balconies or rooms (a tower's top storey keeps its windows, a tower standing alone its base door)",
        counts.iter().map(|(_, n)| n).sum::<usize>(),
        parts.len(),
        list.join(", ")
    ))
}

/// Part tags take precedence; a part without colours takes its outline's.
pub(crate) fn merged_tags(
    piece: &BuildingTags,
    outline: &BuildingTags,
    is_part: bool,
) -> BuildingTags {
    let mut t = piece.clone();
    if is_part {
        t.colour = t.colour.or(outline.colour);
        t.roof_colour = t.roof_colour.or(outline.roof_colour);
        t.material = t.material.clone().or(outline.material.clone());
    }
    t
}

/// Indices of the masses of a derived tree, in tree order: volumes labelled building or
/// building part that contain no other such volume (seed 003 §3.5: "each shape marked building
/// part that contains no building part becomes an IfcBuilding").
pub(crate) fn mass_nodes(tree: &ShapeTree) -> Vec<usize> {
    let is_mass = |i: usize| {
        matches!(tree.nodes[i].label, Label::Building | Label::BuildingPart)
            && matches!(tree.nodes[i].geometry, Geometry::Volume { .. })
    };
    // Children come after their parents, so one backward pass marks every ancestor of a mass.
    let mut has_mass_below = vec![false; tree.nodes.len()];
    for i in (0..tree.nodes.len()).rev() {
        if is_mass(i) || has_mass_below[i] {
            if let Some(p) = tree.nodes[i].parent {
                has_mass_below[p] = true;
            }
        }
    }
    (0..tree.nodes.len())
        .filter(|&i| is_mass(i) && !has_mass_below[i])
        .collect()
}

/// Storeys of the mass at node `mass`: the finest partition of its horizontal cuts
/// ([`crate::derive::facade::levels`]); 0 when the rules cut none.
fn storey_count(tree: &ShapeTree, mass: usize, z0: f64, z1: f64) -> u32 {
    let mut found = Vec::new();
    let mut stack = vec![mass];
    while let Some(i) = stack.pop() {
        let node = &tree.nodes[i];
        if i != mass && matches!(node.label, Label::Building | Label::BuildingPart) {
            continue;
        }
        if matches!(node.label, Label::Storey | Label::Room) {
            if let Geometry::Volume { z0, height, .. } = node.geometry {
                found.push(facade::Level {
                    z0,
                    z1: z0 + height,
                });
            }
        }
        stack.extend(node.children.clone());
    }
    if found.is_empty() {
        return 0;
    }
    facade::levels(found, z0, z1).len() as u32
}

/// The masses of a derived tree (see [`mass_nodes`]) with their heights, roofs and colours.
pub(crate) fn masses_of(tree: &ShapeTree, style: &Style) -> Vec<Mass> {
    let mut out = Vec::new();
    for i in mass_nodes(tree) {
        let node = &tree.nodes[i];
        let Geometry::Volume {
            footprint,
            z0,
            height,
            ..
        } = &node.geometry
        else {
            continue;
        };
        let storeys = storey_count(tree, i, *z0, z0 + height);
        let text = |k: &str| match node.attrs.get(k) {
            Some(AttrValue::Str(s)) => Some(s.to_string()),
            Some(AttrValue::Num(n)) => Some(n.to_string()),
            None => None,
        };
        let num = |k: &str| match node.attrs.get(k) {
            Some(AttrValue::Num(n)) if n.is_finite() => Some(*n),
            Some(AttrValue::Str(s)) => s.trim().parse::<f64>().ok().filter(|v| v.is_finite()),
            _ => None,
        };
        let roof = text("roof")
            .and_then(|r| RoofShape::parse(&r))
            .unwrap_or(style.roof);
        // On the output grid from the start, so that the roof is built on the footprint the
        // walls stand on (a footprint a millimetre from touching itself stays as it is).
        let footprint =
            massing::grid::polygon_on_grid(footprint).unwrap_or_else(|| footprint.clone());
        out.push(Mass {
            footprint,
            base_z: *z0,
            eave_z: z0 + height,
            storeys: if storeys > 0 { storeys } else { style.storeys },
            roof,
            roof_angle_deg: num("roofangle").unwrap_or(style.roof_angle_deg),
            roof_direction: style.roof_direction,
            roof_across: style.roof_across,
            roof_height: num("roofheight").or(style.roof_height),
            wall_color: text("color")
                .and_then(|c| Color::parse(&c))
                .unwrap_or(style.wall_color),
            roof_color: text("roofcolor")
                .and_then(|c| Color::parse(&c))
                .unwrap_or(style.roof_color),
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use glam::DVec2;

    use super::*;
    use crate::input::Streets;
    use crate::model::OpeningKind;
    use crate::prepare::{assign_fronts, single_lot};
    use crate::report::Report;

    /// Outward normals of the walls that hold a door.
    fn door_normals(b: &Building) -> Vec<DVec2> {
        b.parts
            .iter()
            .flat_map(|p| p.walls.iter())
            .filter(|w| w.openings.iter().any(|o| o.kind == OpeningKind::Door))
            .map(|w| {
                let d = (w.end - w.start).normalize();
                DVec2::new(d.y, -d.x)
            })
            .collect()
    }

    /// A building's provenance is its tags' (the estimator's, when it set one) with the KB's
    /// uncertainty where the KB drew the value.
    #[test]
    fn a_part_carries_the_rhythm_its_kb_rules_give_its_walls() {
        // What the LOD2 facade textures draw: the bay and window kb::compile writes.
        let gen = Generator::new(
            KnowledgeBase::earth_only(),
            Rules::Kb,
            Lod::Lod2,
            0,
            Caps::default(),
        );
        let ring = vec![
            DVec2::new(0.0, 0.0),
            DVec2::new(12.0, 0.0),
            DVec2::new(12.0, 9.0),
            DVec2::new(0.0, 9.0),
        ];
        let mut report = Report::default();
        let site = single_lot(Polygon::new(ring, vec![]), (7.42, 43.73), None, &mut report);
        let lot = site.unwrap().lots.pop().unwrap();
        let (b, _) = gen.generate(&lot).unwrap();
        let r = b.parts[0].rhythm.expect("the KB's rules give a rhythm");
        assert!(
            (r.bay - (r.window + 2.0 * compile::PIER_WIDTH)).abs() < 1e-9,
            "{r:?}"
        );
        assert!(r.window > 0.3 && r.window < r.bay, "{r:?}");
        assert!(r.sill > 0.0 && r.sill + r.height < 1.0, "{r:?}");
    }

    #[test]
    fn a_building_carries_the_provenance_of_its_values() {
        use crate::model::{Provenance, ValueSource};
        let gen = Generator::new(
            KnowledgeBase::earth_only(),
            Rules::Kb,
            Lod::Lod2,
            0,
            Caps::default(),
        );
        let ring = vec![
            DVec2::new(0.0, 0.0),
            DVec2::new(12.0, 0.0),
            DVec2::new(12.0, 9.0),
            DVec2::new(0.0, 9.0),
        ];
        let mut report = Report::default();
        let site = single_lot(Polygon::new(ring, vec![]), (7.42, 43.73), None, &mut report);
        let mut lot = site.unwrap().lots.pop().unwrap();
        let (b, _) = gen.generate(&lot).unwrap();
        let p = b.provenance;
        assert_eq!(
            (p.storeys, p.height, p.roof),
            (ValueSource::Kb, ValueSource::Kb, ValueSource::Kb)
        );
        assert!(
            p.storeys_error.is_some() && p.height_error.is_some(),
            "{p:?}"
        );

        let model = Provenance {
            storeys: ValueSource::Model,
            storeys_error: Some(0.5),
            height: ValueSource::Model,
            height_error: Some(1.25),
            roof: ValueSource::Fitted,
            roof_probability: Some(0.9),
        };
        lot.tags = std::sync::Arc::new(crate::input::BuildingTags {
            height: Some(7.0),
            roof_shape: Some(RoofShape::Flat),
            provenance: Some(model),
            ..Default::default()
        });
        let (b, _) = gen.generate(&lot).unwrap();
        assert_eq!(b.provenance, model);
        assert!((b.measured_height - 7.0).abs() < 1e-6);
    }

    /// A street along the north side turns the door north, whichever way the footprint lies;
    /// without it the thesis front stays (south of an east-west block, east of a north-south
    /// one).
    #[test]
    fn the_door_faces_a_street_on_the_north_side() {
        let gen = Generator::new(
            KnowledgeBase::earth_only(),
            Rules::Kb,
            Lod::Lod3,
            0,
            Caps::default(),
        );
        for (w, h, thesis) in [(20.0, 10.0, -DVec2::Y), (10.0, 20.0, DVec2::X)] {
            let ring = vec![
                DVec2::new(0.0, 0.0),
                DVec2::new(w, 0.0),
                DVec2::new(w, h),
                DVec2::new(0.0, h),
            ];
            let mut report = Report::default();
            let mut site =
                single_lot(Polygon::new(ring, vec![]), (7.42, 43.73), None, &mut report).unwrap();
            let (b, _) = gen.generate(&site.lots[0]).unwrap();
            let doors = door_normals(&b);
            assert!(!doors.is_empty(), "{w}x{h}: no door");
            assert!(
                doors.iter().all(|n| n.dot(thesis) > 0.999),
                "{w}x{h}: {doors:?}"
            );

            // A street 6 m north of the block, in output-CRS coordinates.
            let o = site.origin;
            let mut streets = Streets::default();
            streets.push(&[(o.x - 30.0, o.y + h + 6.0), (o.x + w + 30.0, o.y + h + 6.0)]);
            let crs = site.crs;
            assign_fronts(&mut site, &streets, Some(crs));
            assert_eq!(site.lots[0].front, Some(DVec2::Y));
            let (b, _) = gen.generate(&site.lots[0]).unwrap();
            let doors = door_normals(&b);
            assert!(!doors.is_empty(), "{w}x{h}: no door");
            assert!(
                doors.iter().all(|n| n.dot(DVec2::Y) > 0.999),
                "{w}x{h}: {doors:?}"
            );
        }
    }

    /// Three terraced houses in a row, a street 6 m north, the middle one taller: their shared
    /// walls are blank up to the lower neighbour's top and have windows above it; each has one
    /// door, on the street.
    #[test]
    fn a_terrace_has_blank_party_walls_and_one_door_each_on_the_street() {
        let mut gen = Generator::new(
            KnowledgeBase::earth_only(),
            Rules::Kb,
            Lod::Lod3,
            0,
            Caps::default(),
        );
        let mut report = Report::default();
        let mut lots = Vec::new();
        let mut site = None;
        for i in 0..3 {
            let x = 8.0 * i as f64;
            let ring = vec![
                DVec2::new(x, 0.0),
                DVec2::new(x + 8.0, 0.0),
                DVec2::new(x + 8.0, 10.0),
                DVec2::new(x, 10.0),
            ];
            let mut s =
                single_lot(Polygon::new(ring, vec![]), (7.42, 43.73), None, &mut report).unwrap();
            let mut lot = s.lots.pop().unwrap();
            lot.id = SourceId::Lot(i);
            let tags = crate::input::BuildingTags {
                levels: Some(if i == 1 { 5.0 } else { 2.0 }),
                ..Default::default()
            };
            lot.tags = std::sync::Arc::new(tags);
            lots.push(lot);
            site = Some(s);
        }
        let mut site = site.unwrap();
        site.lots = lots;
        let o = site.origin;
        let mut streets = Streets::default();
        streets.push(&[(o.x - 30.0, o.y + 16.0), (o.x + 54.0, o.y + 16.0)]);
        let crs = site.crs;
        assign_fronts(&mut site, &streets, Some(crs));
        gen.surroundings = gen.neighbours_of(&site.lots, |_| true);
        assert_eq!(gen.surroundings.len(), 3);
        let low_top = site
            .lots
            .iter()
            .take(1)
            .map(|l| gen.generate(l).unwrap().0.parts[0].top_z)
            .sum::<f64>();
        for (i, lot) in site.lots.iter().enumerate() {
            let (b, _) = gen.generate(lot).unwrap();
            assert_eq!(door_normals(&b), vec![DVec2::Y], "house {i}");
            assert_eq!(b.facade.entrances, 1);
            let x = |w: &crate::model::Wall| 0.5 * (w.start.x + w.end.x);
            for p in &b.parts {
                for w in &p.walls {
                    let vertical = (w.start.x - w.end.x).abs() < 1e-9;
                    let shared =
                        vertical && ((x(w) - 8.0).abs() < 0.01 || (x(w) - 16.0).abs() < 0.01);
                    let outer_gable = vertical && !shared;
                    if shared {
                        for o in &w.openings {
                            assert!(o.z0 >= low_top - 1e-9, "house {i}: {o:?} under {low_top}");
                        }
                        // Above the neighbours' roofs a wall of the taller house is a facade.
                        assert_eq!(
                            w.party > 0.0,
                            w.base_z < low_top - 1e-9,
                            "house {i}: party share {} at {}..{}",
                            w.party,
                            w.base_z,
                            w.top_z
                        );
                    }
                    if outer_gable && w.storey == 0 {
                        assert!(!w.openings.is_empty(), "house {i}: a blank end wall");
                    }
                }
            }
            if i == 1 {
                // The taller house has windows on its side walls above its neighbours.
                let high = p_side_windows(&b);
                assert!(high > 0, "no window above the neighbours");
            }
        }
        assert!(report.entries.is_empty(), "{:?}", report.entries);
    }

    /// Windows on the walls of `b` that run north-south.
    fn p_side_windows(b: &Building) -> usize {
        b.parts
            .iter()
            .flat_map(|p| p.walls.iter())
            .filter(|w| (w.start.x - w.end.x).abs() < 1e-9)
            .map(|w| w.openings.len())
            .sum()
    }

    #[test]
    fn a_rule_cache_poisoned_by_a_caught_panic_still_serves_the_next_building() {
        let gen = Generator::new(
            KnowledgeBase::earth_only(),
            Rules::Kb,
            Lod::Lod2,
            0,
            Caps::default(),
        );
        let _ = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            let _held = gen.compiled.lock().unwrap();
            panic!("poison the cache");
        }));
        assert!(gen.compiled.is_poisoned());
        let ring = vec![
            DVec2::new(0.0, 0.0),
            DVec2::new(12.0, 0.0),
            DVec2::new(12.0, 9.0),
            DVec2::new(0.0, 9.0),
        ];
        let mut report = Report::default();
        let site =
            single_lot(Polygon::new(ring, vec![]), (7.42, 43.73), None, &mut report).unwrap();
        let (b, _) = gen.generate(&site.lots[0]).unwrap();
        assert!(b.polygon_count() > 0);
    }
}
