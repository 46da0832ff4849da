//! Library side of `citygen kb check | compile | explain`: what the commands print, computed
//! here so that the CLI only formats arguments and exit codes.
//!
//! [`explain`] runs exactly the generator's code path ([`KnowledgeBase::locate`], then
//! [`KnowledgeBase::style_for`] with `Rng::new(seed, seed_value)`), so what it says is what
//! citygen builds for that footprint.

use std::fmt;
use std::path::Path;

use super::compile::{color_word, ruleset_text};
use super::{proba_weights, KbError, KbRepair, KnowledgeBase, ReadMode, Style, Values, ZoneMatch};
use crate::input::BuildingTags;
use crate::rng::Rng;

/// The result of `kb check`: counts, repairs, problems and warnings. Loading errors are the
/// `Err` of `check_report` instead.
#[derive(Clone, Debug, PartialEq)]
pub struct CheckReport {
    /// The file as given.
    pub file: String,
    /// How the file was read: [`ReadMode::Strict`] with `kb check --strict`, else lenient.
    pub mode: ReadMode,
    /// Zones including earth.
    pub zones: usize,
    /// Deepest zone depth (earth is 0).
    pub max_depth: usize,
    /// `<appearance>` elements in all zones.
    pub appearances: usize,
    /// `<polygon>` rings in all zones.
    pub polygons: usize,
    /// What the lenient reader repaired, by line (always empty in strict mode).
    pub repairs: Vec<KbRepair>,
    /// Problems that make the KB unusable as is although it reads: a `<ruleset file>` outside
    /// the KB's folder when external rulesets are not allowed. `kb check` should exit non-zero
    /// when this is not empty.
    pub errors: Vec<KbRepair>,
    /// Things that read but are probably not what the author meant.
    pub warnings: Vec<KbRepair>,
}

impl CheckReport {
    /// Whether `kb check` should fail: errors found (repairs and warnings do not fail it).
    pub(crate) fn has_errors(&self) -> bool {
        !self.errors.is_empty()
    }
}

impl fmt::Display for CheckReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mode = match self.mode {
            ReadMode::Lenient => "lenient",
            ReadMode::Strict => "strict",
        };
        writeln!(
            f,
            "{}: {} zones (depth {}), {} appearances, {} polygons ({mode} reading)",
            self.file, self.zones, self.max_depth, self.appearances, self.polygons
        )?;
        for (title, list) in [
            ("repair", &self.repairs),
            ("error", &self.errors),
            ("warning", &self.warnings),
        ] {
            for r in list.iter() {
                writeln!(f, "{}:{}: {title}: {}", self.file, r.line, r.what)?;
            }
        }
        write!(
            f,
            "{} repairs, {} errors, {} warnings",
            self.repairs.len(),
            self.errors.len(),
            self.warnings.len()
        )
    }
}

/// Reads a KB file and reports on it (`kb check`). Rulesets outside the KB's folder are
/// errors; see [`check_report_with`] to allow them.
pub(crate) fn check_report(path: &Path, mode: ReadMode) -> Result<CheckReport, KbError> {
    check_report_with(path, mode, false)
}

/// [`check_report`], with `allow_external` rulesets (`--allow-external-rulesets`).
pub(crate) fn check_report_with(
    path: &Path,
    mode: ReadMode,
    allow_external: bool,
) -> Result<CheckReport, KbError> {
    let (kb, repairs) = KnowledgeBase::load_with(path, mode)?;
    Ok(report_for(&kb, mode, repairs, allow_external))
}

/// What a run says about the `<ruleset file>`s a knowledge base names, one note each (for the
/// report): a refused path (outside the KB's folder) says why (the appearance's values compile
/// into its rules), and every other that the appearance's buildings are derived with it (a file
/// that cannot be read or parsed gets a second note from `derive::Generator::load_rulesets`).
/// Empty when the KB names none.
pub(crate) fn ruleset_notes(kb: &KnowledgeBase) -> Vec<String> {
    let mut notes = Vec::new();
    for (i, z) in kb.zones().iter().enumerate() {
        for (k, a) in z.appearances.iter().enumerate() {
            let Some(file) = a.ruleset.as_deref() else {
                continue;
            };
            let at = format!(
                "{}:{}: appearance {}#{}",
                kb.source(),
                a.line,
                z.path,
                k + 1
            );
            notes.push(match kb.ruleset_file(i, k, false) {
                Err(e) => {
                    let why = match e {
                        KbError::Structure { message, .. } => message,
                        other => other.to_string(),
                    };
                    format!("{at}: ruleset refused: {why}; its values are used")
                }
                Ok(_) => format!(
                    "{at} names ruleset file \"{file}\": its buildings are derived with it (the \
                     values give the axiom's attributes)"
                ),
            });
        }
    }
    notes
}

/// Reads, parses and lints the ruleset an appearance names (at KB line `line`), and lists as
/// warnings a file that cannot be read or does not parse and every lint finding (a rule that
/// can never terminate, probabilities above 1, ...), each with the ruleset's own file:line:col.
/// Warnings, not errors: a run derives an appearance whose ruleset cannot be read or parsed
/// from its values (with a note), and applies one with lint findings as it is, so none of
/// these stops a run.
fn check_ruleset(
    kb: &KnowledgeBase,
    path: &Path,
    allow_external: bool,
    line: usize,
    warnings: &mut Vec<KbRepair>,
) {
    let name = path.display().to_string();
    // At most grammar::MAX_SOURCE_BYTES are read (rule files are a few kilobytes), and only
    // inside the KB's folder unless outside rulesets are allowed.
    let text = if allow_external {
        crate::grammar::read_source(path)
    } else {
        kb.read_appearance_file(path)
    };
    let text = text.map_err(|e| e.to_string());
    let text = match text {
        Ok(t) => t,
        Err(why) => {
            warnings.push(KbRepair {
                line,
                what: format!("ruleset file {name} cannot be read: {why}"),
            });
            return;
        }
    };
    let rules = match crate::grammar::parse(&text, &name) {
        Ok(r) => r,
        Err(e) => {
            let first = e.to_string().lines().next().unwrap_or_default().to_string();
            warnings.push(KbRepair {
                line,
                what: format!("ruleset does not parse: {first}"),
            });
            return;
        }
    };
    for d in crate::grammar::lint::lint(&rules, &text) {
        warnings.push(KbRepair {
            line,
            what: format!(
                "ruleset {}:{}:{}: {}[{}]: {}",
                d.file, d.line, d.col, d.severity, d.code, d.message
            ),
        });
    }
}

/// Reads and parses the SELEX program an appearance names (at KB line `line`): a file that
/// cannot be read or does not parse is an error (a run refuses it before any work), and the
/// parser's warnings (`selex check`'s static ones) are warnings, each with the program's own
/// file:line:col.
fn check_selex(
    kb: &KnowledgeBase,
    path: &Path,
    line: usize,
    errors: &mut Vec<KbRepair>,
    warnings: &mut Vec<KbRepair>,
) {
    let name = path.display().to_string();
    let text = match kb.read_appearance_file(path) {
        Ok(t) => t,
        Err(why) => {
            errors.push(KbRepair {
                line,
                what: format!("selex file {name} cannot be read: {why}"),
            });
            return;
        }
    };
    match crate::selex::parser::parse(&text, &name) {
        Ok(program) => {
            for w in crate::selex::parser::check(&program, &text, &name) {
                let first = w.to_string().lines().next().unwrap_or_default().to_string();
                warnings.push(KbRepair { line, what: first });
            }
        }
        Err(e) => {
            let first = e.to_string().lines().next().unwrap_or_default().to_string();
            errors.push(KbRepair {
                line,
                what: format!("selex program does not parse: {first}"),
            });
        }
    }
}

/// The report for an already loaded KB (what [`check_report_with`] does after loading).
pub(crate) fn report_for(
    kb: &KnowledgeBase,
    mode: ReadMode,
    repairs: Vec<KbRepair>,
    allow_external: bool,
) -> CheckReport {
    let mut errors = Vec::new();
    let mut warnings = Vec::new();
    let zones = kb.zones();
    for (i, z) in zones.iter().enumerate() {
        let has_children = zones.iter().any(|c| c.parent == Some(i));
        if i > 0 && z.circle.is_none() && z.polygons.is_empty() {
            warnings.push(KbRepair {
                line: z.line,
                what: format!(
                    "zone '{}' has no circle and no polygon: no footprint is ever placed in it \
                     (only its sub-zones match)",
                    z.path
                ),
            });
        }
        if i > 0 && z.info == Values::default() && z.appearances.is_empty() && !has_children {
            warnings.push(KbRepair {
                line: z.line,
                what: format!(
                    "zone '{}' is empty: no values, no appearance, no sub-zone; it only \
                     inherits",
                    z.path
                ),
            });
        }
        // The probas of one group (the appearances with the same `building` list) sum to 1.
        let mut groups: Vec<&[String]> = Vec::new();
        for a in &z.appearances {
            if !groups.contains(&a.buildings.as_slice()) {
                groups.push(&a.buildings);
            }
        }
        for g in groups {
            let probas = z
                .appearances
                .iter()
                .filter(|a| a.buildings == g)
                .map(|a| a.proba);
            let sum: f64 = probas.clone().flatten().sum();
            let all_given = probas.clone().all(|p| p.is_some());
            if (all_given && (sum - 1.0).abs() > 1e-6) || sum > 1.0 + 1e-6 {
                let w = proba_weights(probas);
                let shares: Vec<String> = w.iter().map(|x| format!("{x:.3}")).collect();
                let of = if g.is_empty() {
                    String::new()
                } else {
                    format!(" for building={}", g.join(","))
                };
                warnings.push(KbRepair {
                    line: z.line,
                    what: format!(
                        "appearance probas of '{}'{of} sum to {sum}, not 1: normalised to {}",
                        z.path,
                        shares.join(", ")
                    ),
                });
            }
        }
        for (k, a) in z.appearances.iter().enumerate() {
            let v = &a.values;
            if let (Some(lo), Some(hi)) = (v.min_floors, v.max_floors) {
                if lo > hi {
                    warnings.push(KbRepair {
                        line: a.line,
                        what: format!(
                            "{}#{}: minFloors {lo} > maxFloors {hi} (swapped when drawn)",
                            z.path,
                            k + 1
                        ),
                    });
                }
            }
            if let (Some(lo), Some(hi)) = (v.min_height, v.max_height) {
                if lo > hi {
                    warnings.push(KbRepair {
                        line: a.line,
                        what: format!(
                            "{}#{}: minHeight {lo} > maxHeight {hi} (swapped when drawn)",
                            z.path,
                            k + 1
                        ),
                    });
                }
            }
            match kb.ruleset_file(i, k, allow_external) {
                Err(e) => {
                    let what = match e {
                        KbError::Structure { message, .. } => message,
                        other => other.to_string(),
                    };
                    errors.push(KbRepair { line: a.line, what });
                }
                Ok(Some(path)) => {
                    check_ruleset(kb, &path, allow_external, a.line, &mut warnings);
                }
                Ok(None) => {}
            }
            match kb.selex_file(i, k) {
                Err(e) => {
                    let what = match e {
                        KbError::Structure { message, .. } => message,
                        other => other.to_string(),
                    };
                    errors.push(KbRepair { line: a.line, what });
                }
                Ok(Some(path)) => check_selex(kb, &path, a.line, &mut errors, &mut warnings),
                Ok(None) => {}
            }
        }
    }
    errors.sort_by_key(|r| r.line);
    warnings.sort_by_key(|r| r.line);
    CheckReport {
        file: kb.source().to_string(),
        mode,
        zones: zones.len(),
        max_depth: zones.iter().map(|z| z.depth).max().unwrap_or(0),
        appearances: zones.iter().map(|z| z.appearances.len()).sum(),
        polygons: zones.iter().map(|z| z.polygons.len()).sum(),
        repairs,
        errors,
        warnings,
    }
}

/// Finds a zone by path: `France/Occitanie/Toulouse` or `earth/France/...`, case-insensitive,
/// surrounding slashes and spaces ignored; `earth` or an empty path is earth. The first zone in
/// document order wins when two have the same path. A path that names no zone from earth down
/// may leave out the first levels (`France/Occitanie/Toulouse` for
/// `earth/Western Europe/France/Occitanie/Toulouse`): it then finds the one zone whose path
/// ends with it at a `/`, and nothing when several do.
pub(crate) fn find_zone(kb: &KnowledgeBase, zone_path: &str) -> Option<usize> {
    if let Some(i) = find_zone_from_earth(kb, zone_path) {
        return Some(i);
    }
    let tail = format!("/{}", zone_path.trim().trim_matches('/')).to_ascii_lowercase();
    let mut hits = kb
        .zones()
        .iter()
        .enumerate()
        .filter(|(_, z)| z.path.to_ascii_lowercase().ends_with(&tail))
        .map(|(i, _)| i);
    match (hits.next(), hits.next()) {
        (Some(i), None) => Some(i),
        _ => None,
    }
}

/// [`find_zone`]'s exact part: the zone with this path from earth down.
fn find_zone_from_earth(kb: &KnowledgeBase, zone_path: &str) -> Option<usize> {
    let p = zone_path.trim().trim_matches('/');
    let full = if p.is_empty() || p.eq_ignore_ascii_case("earth") {
        "earth".to_string()
    } else if p.len() > 6 && p[..6].eq_ignore_ascii_case("earth/") {
        format!("earth/{}", &p[6..])
    } else {
        format!("earth/{p}")
    };
    kb.zones()
        .iter()
        .position(|z| z.path.eq_ignore_ascii_case(&full))
}

/// The grammar rules generated for each appearance that applies to a zone (`kb compile
/// --zone`): its own appearances or, when it has none, those it inherits
/// ([`KnowledgeBase::appearances_for`]); the zone's info values alone when no zone up to earth
/// has any. Each entry is (appearance label `zone path#n` as in [`Style::appearance_label`],
/// rule text as the generator compiles it, without OSM tags). The text is what
/// [`crate::grammar::parse`] reads.
pub(crate) fn compile_zone(
    kb: &KnowledgeBase,
    zone_path: &str,
) -> Result<Vec<(String, String)>, KbError> {
    let Some(zone) = find_zone(kb, zone_path) else {
        let known: Vec<&str> = kb
            .zones()
            .iter()
            .skip(1)
            .map(|z| z.path.trim_start_matches("earth/"))
            .take(6)
            .collect();
        return Err(KbError::UnknownZone {
            file: kb.source().to_string(),
            path: zone_path.to_string(),
            examples: known.join(", "),
        });
    };
    let (owner, apps) = kb.appearances_for(zone);
    let tags = BuildingTags::default();
    let picks: Vec<Option<(usize, usize)>> = if apps.is_empty() {
        vec![None]
    } else {
        (0..apps.len()).map(|i| Some((owner, i))).collect()
    };
    Ok(picks
        .into_iter()
        .map(|pick| {
            // The rule text does not depend on the drawn heights (they are axiom attributes).
            let mut rng = Rng::new(0, 0);
            let (style, _) = kb.style_with_appearance(zone, pick, &tags, &mut rng);
            (style.appearance_label.clone(), ruleset_text(&style))
        })
        .collect())
}

/// One zone of the chain from earth to the matched zone, and how the point relates to it.
#[derive(Clone, Debug, PartialEq)]
pub struct ChainLink {
    /// Index of the zone in [`KnowledgeBase::zones`].
    pub zone: usize,
    /// The zone's path, e.g. `earth/France/Occitanie/Toulouse`.
    pub path: String,
    /// Depth in the tree: 0 for earth.
    pub depth: usize,
    /// How the point relates to this zone's own shapes (`KnowledgeBase::zone_match`).
    pub matched: ZoneMatch,
}

/// One value of the resolved style and where it came from.
#[derive(Clone, Debug, PartialEq)]
pub struct ValueSource {
    /// The attribute name as written in a KB (`nbfloor`, `roofColor`, ...).
    pub attribute: &'static str,
    /// The value as `kb explain` prints it: colours as CSS names or `#rrggbb`, numbers in their
    /// shortest form, roof shapes by their OSM name.
    pub value: String,
    /// The zone path whose `<info>` set it, or `<zone path>#n` for the chosen appearance.
    pub from: String,
}

/// One appearance candidate for the footprint.
#[derive(Clone, Debug, PartialEq)]
pub struct Candidate {
    /// `<owner zone path>#<1-based appearance index>`, as in [`Style::appearance_label`].
    pub label: String,
    /// `proba` as written (`None`: empty or absent).
    pub proba: Option<f64>,
    /// The normalised weight the draw uses (`proba_weights` over the eligible
    /// appearances); 0 for an appearance this building's kind may not take.
    pub weight: f64,
    /// The appearance's `building` list (empty: any kind).
    pub buildings: Vec<String>,
    /// Whether the building's kind may take this appearance
    /// (`KnowledgeBase::eligible_appearances`).
    pub eligible: bool,
    /// Whether this is the appearance drawn for the building with this seed.
    pub chosen: bool,
}

/// Everything `kb explain` prints for one footprint; see [`explain`].
#[derive(Clone, Debug, PartialEq)]
pub struct Explanation {
    /// Longitude of the point explained, WGS84 degrees (for `kb explain`, the building's
    /// representative point as a run computes it).
    pub lon: f64,
    /// Latitude of the point explained, WGS84 degrees.
    pub lat: f64,
    /// The run's seed (`--seed`).
    pub seed: u64,
    /// The building's [`SourceId::seed_value`](crate::model::SourceId::seed_value); with `seed` it
    /// seeds the building's random stream.
    pub seed_value: u64,
    /// The matched zone (what [`KnowledgeBase::locate`] returns, or, where the input's admin
    /// boundaries decided, the zone they gave).
    pub zone: usize,
    /// The input's admin boundary the zone came through, when one did: its id, name and level
    /// and the zone it matched by name (the zone is then the deepest of that zone's subtree
    /// containing the point).
    pub boundary: Option<String>,
    /// Earth down to the matched zone.
    pub chain: Vec<ChainLink>,
    /// Other zones at the matched depth that also contain the point and lost the tie.
    pub tied: Vec<(String, ZoneMatch)>,
    /// Values inherited through the zones' `<info>` and then the chosen appearance, in a fixed
    /// attribute order.
    pub values: Vec<ValueSource>,
    /// The appearances that apply to the zone (its own, or the nearest ancestor's), in document
    /// order with their weights; empty when no zone up to earth has any.
    pub candidates: Vec<Candidate>,
    /// OSM tags that override the KB, as `key=value`.
    pub overrides: Vec<String>,
    /// Notes of [`KnowledgeBase::style_for`] (inconsistencies fixed).
    pub notes: Vec<String>,
    /// What the building took from its tagged neighbours ([`crate::prepare`]'s inference, set
    /// by `kb explain`, which runs it as a run does), one phrase per value; these values are
    /// among `overrides`, used like tags.
    pub inferred: Vec<String>,
    /// Where the storeys, height and roof drawn come from, with their uncertainty
    /// (`Style::provenance` of these tags: what a run writes for a building of one part).
    pub provenance: crate::model::Provenance,
    /// The style citygen uses.
    pub style: Style,
}

/// Explains the style citygen gives a footprint at (lon, lat) with these tags, for the
/// building whose `SourceId::seed_value` is `seed_value`, under `--seed seed`.
///
/// Uses the generator's own calls: `kb.locate(lon, lat)` then
/// `kb.style_for(zone, tags, &mut Rng::new(seed, seed_value))`; the chosen appearance is read
/// from the resulting style, never recomputed differently. Without the input's admin
/// boundaries: `kb explain` on an extract goes through `explain_at` with them.
pub fn explain(
    kb: &KnowledgeBase,
    lon: f64,
    lat: f64,
    tags: &BuildingTags,
    seed_value: u64,
    seed: u64,
) -> Explanation {
    let none = super::BoundaryZones::default();
    explain_at(kb, &none, lon, lat, tags, seed_value, seed)
}

/// [`explain`] with the input's matched admin boundaries tried first, as the generator tries
/// them ([`KnowledgeBase::locate_with`]).
pub(crate) fn explain_at(
    kb: &KnowledgeBase,
    boundaries: &super::BoundaryZones,
    lon: f64,
    lat: f64,
    tags: &BuildingTags,
    seed_value: u64,
    seed: u64,
) -> Explanation {
    let located = kb.locate_with(boundaries, lon, lat);
    let zone = located.zone;
    let boundary = located
        .boundary
        .and_then(|m| boundaries.matched().get(m))
        .map(|m| {
            format!(
                "{} \"{}\" (admin_level {}), matched by name to {}",
                m.id,
                m.name,
                m.admin_level,
                kb.zone_path(m.zone)
            )
        });
    let mut rng = Rng::new(seed, seed_value);
    let (style, notes) = kb.style_for(zone, tags, &mut rng);

    let chain: Vec<ChainLink> = kb
        .lineage(zone)
        .into_iter()
        .filter_map(|i| {
            let z = kb.zone(i)?;
            Some(ChainLink {
                zone: i,
                path: z.path.clone(),
                depth: z.depth,
                matched: kb.zone_match(i, lon, lat),
            })
        })
        .collect();
    let depth = kb.zone(zone).map_or(0, |z| z.depth);
    let tied = if zone == 0 {
        Vec::new()
    } else {
        kb.zones()
            .iter()
            .enumerate()
            .filter(|(i, z)| *i != zone && z.depth == depth)
            .filter_map(|(i, z)| {
                let m = kb.zone_match(i, lon, lat);
                m.area_km2().map(|_| (z.path.clone(), m))
            })
            .collect()
    };

    // Who set each value: the deepest zone whose <info> sets it, then the appearance.
    let mut values: Vec<ValueSource> = Vec::new();
    let mut set = |v: &Values, from: &str| {
        for (attribute, value) in value_fields(v) {
            match values.iter_mut().find(|s| s.attribute == attribute) {
                Some(s) => {
                    s.value = value;
                    s.from = from.to_string();
                }
                None => values.push(ValueSource {
                    attribute,
                    value,
                    from: from.to_string(),
                }),
            }
        }
    };
    for link in &chain {
        if let Some(z) = kb.zone(link.zone) {
            set(&z.info, &z.path);
        }
    }
    let (owner, apps) = kb.appearances_for(zone);
    let owner_path = kb.zone_path(owner).to_string();
    let ids = super::eligible(apps, tags.building.as_deref());
    let weights = proba_weights(ids.iter().map(|&i| apps[i].proba));
    let candidates: Vec<Candidate> = apps
        .iter()
        .enumerate()
        .map(|(i, a)| {
            let label = format!("{owner_path}#{}", i + 1);
            let at = ids.iter().position(|&j| j == i);
            Candidate {
                chosen: label == style.appearance_label,
                label,
                proba: a.proba,
                weight: at.and_then(|k| weights.get(k).copied()).unwrap_or(0.0),
                buildings: a.buildings.clone(),
                eligible: at.is_some(),
            }
        })
        .collect();
    if let Some((i, app)) = candidates
        .iter()
        .position(|c| c.chosen)
        .and_then(|i| Some((i, apps.get(i)?)))
    {
        set(&app.values, &format!("{owner_path}#{}", i + 1));
    }
    let order: Vec<&str> = ATTRIBUTE_ORDER.to_vec();
    values.sort_by_key(|v| order.iter().position(|a| *a == v.attribute));

    Explanation {
        lon,
        lat,
        seed,
        seed_value,
        zone,
        boundary,
        chain,
        tied,
        values,
        candidates,
        overrides: tag_overrides(tags),
        notes,
        inferred: Vec::new(),
        provenance: style.provenance(tags),
        style,
    }
}

/// The values a zone resolves to from its own and its ancestors' `<info>` (no appearance),
/// each with the path of the zone that set it: what [`explain`] lists before the appearance,
/// for the zone itself (the editor shows it beside the zone's own values). Empty for an
/// unknown zone.
pub(crate) fn zone_values(kb: &KnowledgeBase, zone: usize) -> Vec<ValueSource> {
    let mut values: Vec<ValueSource> = Vec::new();
    if kb.zone(zone).is_none() {
        return values;
    }
    for i in kb.lineage(zone) {
        let Some(z) = kb.zone(i) else { continue };
        for (attribute, value) in value_fields(&z.info) {
            match values.iter_mut().find(|s| s.attribute == attribute) {
                Some(s) => {
                    s.value = value;
                    s.from = z.path.clone();
                }
                None => values.push(ValueSource {
                    attribute,
                    value,
                    from: z.path.clone(),
                }),
            }
        }
    }
    values.sort_by_key(|v| ATTRIBUTE_ORDER.iter().position(|a| *a == v.attribute));
    values
}

/// A provenance in words: `storeys kb ±1, height kb ±3 m, roof kb (p 0.667)`.
fn provenance_text(p: &crate::model::Provenance) -> String {
    let with = |source: crate::model::ValueSource, v: Option<f64>, fmt: &dyn Fn(f64) -> String| {
        let mut s = source.name().to_string();
        if let Some(v) = v {
            s.push(' ');
            s.push_str(&fmt(v));
        }
        s
    };
    format!(
        "storeys {}, height {}, roof {}",
        with(p.storeys, p.storeys_error, &|v| format!("±{v}")),
        with(p.height, p.height_error, &|v| format!("±{v} m")),
        with(p.roof, p.roof_probability, &|v| format!("(p {v})")),
    )
}

/// KB attribute names in the order [`value_fields`] lists them.
const ATTRIBUTE_ORDER: [&str; 26] = [
    "color",
    "material",
    "nbfloor",
    "minFloors",
    "maxFloors",
    "minHeight",
    "maxHeight",
    "floorsize",
    "rooftype",
    "roofangle",
    "roofColor",
    "doorCol",
    "openingCol",
    "windowfcolor",
    "windowheight",
    "windowwidth",
    "doorwidth",
    "doorheight",
    "minopeningwidth",
    "windowstyle",
    "windowmaterial",
    "maxrotation",
    "cornice",
    "corniceheight",
    "eaves",
    "infer",
];

/// The values a [`Values`] sets, by KB attribute name.
fn value_fields(v: &Values) -> Vec<(&'static str, String)> {
    let c = |x: Option<crate::color::Color>| x.map(color_word);
    let n = |x: Option<f64>| x.map(|x| format!("{x}"));
    let u = |x: Option<u32>| x.map(|x| x.to_string());
    let fields: [(&'static str, Option<String>); 26] = [
        ("color", c(v.wall_color)),
        ("material", v.material.clone()),
        ("nbfloor", u(v.storeys)),
        ("minFloors", u(v.min_floors)),
        ("maxFloors", u(v.max_floors)),
        ("minHeight", n(v.min_height)),
        ("maxHeight", n(v.max_height)),
        ("floorsize", n(v.floor_height)),
        ("rooftype", v.roof.map(|r| r.osm_name().to_string())),
        ("roofangle", n(v.roof_angle)),
        ("roofColor", c(v.roof_color)),
        ("doorCol", c(v.door_color)),
        ("openingCol", c(v.window_color)),
        ("windowfcolor", c(v.frame_color)),
        (
            "windowheight",
            v.window_height.map(|h| h.as_str().to_string()),
        ),
        ("windowwidth", n(v.window_width)),
        ("doorwidth", n(v.door_width)),
        ("doorheight", n(v.door_height)),
        ("minopeningwidth", n(v.min_opening_width)),
        ("windowstyle", v.window_style.clone()),
        ("windowmaterial", v.window_material.clone()),
        ("maxrotation", n(v.max_rotation)),
        ("cornice", n(v.cornice)),
        ("corniceheight", n(v.cornice_height)),
        ("eaves", n(v.eaves)),
        ("infer", v.infer.map(|i| i.as_string())),
    ];
    fields
        .into_iter()
        .filter_map(|(k, v)| v.map(|v| (k, v)))
        .collect()
}

/// The OSM tags that [`KnowledgeBase::style_for`] applies over the KB, as `key=value`, in
/// precedence-list order.
fn tag_overrides(t: &BuildingTags) -> Vec<String> {
    let mut out = Vec::new();
    let mut num = |k: &str, v: Option<f64>| {
        if let Some(v) = v {
            out.push(format!("{k}={v}"));
        }
    };
    num("height", t.height);
    num("roof:height", t.roof_height);
    num("building:levels", t.levels);
    num("building:min_level", t.min_level);
    num("min_height", t.min_height);
    num("roof:angle", t.roof_angle);
    if let Some(r) = t.roof_shape {
        out.push(format!("roof:shape={}", r.osm_name()));
    }
    if let Some(c) = t.colour {
        out.push(format!("building:colour={}", color_word(c)));
    }
    if let Some(c) = t.roof_colour {
        out.push(format!("roof:colour={}", color_word(c)));
    }
    if let Some(m) = &t.material {
        out.push(format!("building:material={m}"));
    }
    out
}

impl fmt::Display for ZoneMatch {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ZoneMatch::Circle {
                distance_km,
                radius_km,
            } => write!(
                f,
                "inside its circle: {distance_km:.3} km from the centre <= radius {radius_km} km"
            ),
            ZoneMatch::Polygon { index, area_km2 } => {
                write!(f, "inside its polygon #{} ({area_km2:.3} km²)", index + 1)
            }
            ZoneMatch::Outside {
                circle_distance_km: Some(d),
            } => write!(
                f,
                "outside its shapes ({d:.3} km from its circle's centre); on the chain as an ancestor"
            ),
            ZoneMatch::Outside { .. } => {
                write!(f, "outside its shapes; on the chain as an ancestor")
            }
            ZoneMatch::NoShape => write!(f, "no circle or polygon; on the chain as an ancestor"),
        }
    }
}

impl fmt::Display for Explanation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "point lon {:.6} lat {:.6}, seed {}, building seed value {}",
            self.lon, self.lat, self.seed, self.seed_value
        )?;
        writeln!(
            f,
            "zone chain (deepest containing zone wins; ties: smaller area, then document order):"
        )?;
        if let Some(b) = &self.boundary {
            writeln!(
                f,
                "  from the input's admin boundary {b}: the zone is the deepest of its subtree \
                 containing the point, whatever the shapes above it say"
            )?;
        }
        for l in &self.chain {
            let why = if l.zone == 0 && self.zone == 0 {
                "no zone contains the point: earth".to_string()
            } else if l.zone == 0 {
                "root".to_string()
            } else {
                l.matched.to_string()
            };
            writeln!(f, "  {}{}: {why}", "  ".repeat(l.depth), l.path)?;
        }
        for (p, m) in &self.tied {
            writeln!(
                f,
                "  also contains the point at the same depth (lost the tie): {p}: {m}"
            )?;
        }
        writeln!(f, "inherited values (most specific wins):")?;
        for v in &self.values {
            writeln!(f, "  {} = {}  (from {})", v.attribute, v.value, v.from)?;
        }
        if self.candidates.is_empty() {
            writeln!(
                f,
                "appearances: none up to earth; the info values alone apply"
            )?;
        } else {
            writeln!(f, "appearance candidates (normalised weights):")?;
            for c in &self.candidates {
                let p = c.proba.map_or("(empty)".to_string(), |p| format!("{p}"));
                let kinds = if c.buildings.is_empty() {
                    String::new()
                } else {
                    format!("  building={}", c.buildings.join(","))
                };
                let not = if c.eligible {
                    ""
                } else {
                    "  (not for this building's kind)"
                };
                writeln!(
                    f,
                    "  {} {}  proba {p} -> weight {:.4}{kinds}{not}",
                    if c.chosen { "*" } else { " " },
                    c.label,
                    c.weight
                )?;
            }
        }
        writeln!(f, "chosen with this seed: {}", self.style.appearance_label)?;
        if self.overrides.is_empty() {
            writeln!(f, "OSM tag overrides: none")?;
        } else {
            writeln!(f, "OSM tag overrides: {}", self.overrides.join(", "))?;
        }
        if self.inferred.is_empty() {
            writeln!(f, "inferred from neighbours or estimated: nothing")?;
        } else {
            for i in &self.inferred {
                writeln!(f, "inferred or estimated (used as a tag): {i}")?;
            }
        }
        for n in &self.notes {
            writeln!(f, "note: {n}")?;
        }
        writeln!(f, "provenance: {}", provenance_text(&self.provenance))?;
        let s = &self.style;
        writeln!(f, "style:")?;
        writeln!(
            f,
            "  walls {:.2}..{:.2} m, {} storeys of {} m{}",
            s.min_height,
            s.eave_height,
            s.storeys,
            s.floor_height,
            s.total_height
                .map_or(String::new(), |h| format!(", total height {h} m"))
        )?;
        writeln!(
            f,
            "  roof {} at {}°{}, colour {}",
            s.roof.osm_name(),
            s.roof_angle_deg,
            s.roof_height
                .map_or(String::new(), |h| format!(", height {h} m")),
            color_word(s.roof_color)
        )?;
        writeln!(
            f,
            "  walls {}{}, door {}",
            color_word(s.wall_color),
            s.material
                .as_deref()
                .map_or(String::new(), |m| format!(" ({m})")),
            color_word(s.door_color)
        )?;
        write!(
            f,
            "  windows {} m wide, {}, {} {}, glass {}, frames {}{}",
            s.window_width,
            s.window_height.as_str(),
            s.window_style,
            s.window_material,
            color_word(s.window_color),
            color_word(s.frame_color),
            s.opening.as_ref().map_or(String::new(), |o| format!(
                ", drawn opening with {} panes",
                o.terms.len()
            ))
        )
    }
}
