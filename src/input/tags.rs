//! Simple 3D Buildings tags, parsed leniently (`12 m`, `12;15`, `12,5`, `40'`).
//!
//! Real OSM values are messy. The rule here: take what can be read without guessing (a unit, a
//! decimal comma, the first value of a `;` list), and put everything else in
//! [`BuildingTags::ignored`] with the reason, so the run report can show it.

use crate::color::Color;
use crate::model::{Provenance, RoofShape, Structure, ValueSource};

/// Lengths above this (metres) are rejected as absurd: the tallest building stands at 828 m.
pub(crate) const MAX_LENGTH_M: f64 = 1000.0;

/// Level counts above this are rejected as absurd (the tallest building has 163 floors).
pub(crate) const MAX_LEVELS: f64 = 300.0;

const FOOT_M: f64 = 0.3048;
const INCH_M: f64 = 0.0254;

/// The building tags citygen honours. `None` when absent or unusable; every unusable value is
/// listed in `ignored` as `(key, value, reason)` for the report.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BuildingTags {
    /// `building=*` or `building:part=*` value (e.g. `yes`, `house`, `apartments`), trimmed and
    /// lower-cased. `building` wins over `building:part`, and a value other than `no` wins over
    /// `no`.
    pub building: Option<String>,
    /// `building:part=*` value (other than `no`), trimmed and lower-cased: what the part is
    /// (`roof`, `tower`, ...), which for a way tagged both says more about the part than
    /// `building` does.
    pub building_part: Option<String>,
    /// Whether `building=*` (other than `no`) is present: a `building:part` that carries it too
    /// is a building when no outline holds it (Simple 3D Buildings).
    pub has_building: bool,
    /// OSM `name`, trimmed (a blank value is ignored). Only OSM input sets it: the shapefile
    /// reader maps no name field.
    pub name: Option<String>,
    /// `height` in metres, total height including the roof. Always > 0.
    pub height: Option<f64>,
    /// `min_height` in metres (>= 0).
    pub min_height: Option<f64>,
    /// `building:levels` (above ground, without roof levels), >= 0.
    pub levels: Option<f64>,
    /// `building:min_level`, >= 0.
    pub min_level: Option<f64>,
    /// `roof:shape` (the first value of a `;` list), read by [`RoofShape::parse`], so the thesis
    /// spellings are accepted too. An unknown value leaves this `None` and sets
    /// `invalid_roof_shape`.
    pub roof_shape: Option<RoofShape>,
    /// A `roof:shape` value that is present but unknown or invalid (`9.0`, `many`): the roof is
    /// drawn flat (issue 4) rather than taking the knowledge base's roof.
    pub invalid_roof_shape: Option<String>,
    /// `roof:height` in metres (>= 0).
    pub roof_height: Option<f64>,
    /// `roof:angle` in degrees, in 0..=90.
    pub roof_angle: Option<f64>,
    /// `roof:levels`, >= 0.
    pub roof_levels: Option<f64>,
    /// `roof:orientation` = `along` / `across` (lower case; other values are ignored).
    pub roof_orientation: Option<String>,
    /// `roof:direction` in degrees clockwise from north, in 0..360 (cardinal letters accepted).
    pub roof_direction: Option<f64>,
    /// `building:colour` (or `building:color`).
    pub colour: Option<Color>,
    /// `roof:colour` (or `roof:color`).
    pub roof_colour: Option<Color>,
    /// `building:material`, trimmed and lower-cased.
    pub material: Option<String>,
    /// `roof:material`, trimmed and lower-cased.
    pub roof_material: Option<String>,
    /// Values that were present but could not be used: (key, value, reason).
    pub ignored: Vec<(String, String, String)>,
    /// Set when some of `height`, `building:levels` or `roof:shape` were estimated rather
    /// than read (`prepare::estimate`, `prepare::infer`): where each came from. `None`: every
    /// value above is the input's own.
    pub provenance: Option<Provenance>,
    /// The footprint's form among its neighbours (attached, density), set by `prepare` when
    /// the knowledge base's appearances have conditions on it; `None` otherwise.
    pub form: Option<crate::model::Form>,
    /// `man_made=*`, trimmed and lower-cased (`column`, `obelisk`, `tower`, ...): read for
    /// the structure class.
    pub man_made: Option<String>,
    /// `historic=*`, trimmed and lower-cased (`monument`, `memorial`, ...): read for the
    /// structure class.
    pub historic: Option<String>,
    /// `tower:type=*`, trimmed and lower-cased (`bell_tower`, `observation`, ...): read for
    /// the structure class.
    pub tower_type: Option<String>,
    /// What the footprint is when it is not a house (issue 45), set by `prepare` from the
    /// tags above and the footprint's size (`prepare::structure`); `None` as read.
    pub structure: Option<Structure>,
}

/// Parsed tags shared by every footprint that has the same ones: most buildings of a region
/// carry one of a few tag sets (`building=yes`, `building=house` with a level count), so a
/// city of a million buildings holds a few thousand [`BuildingTags`] instead of a million
/// (each is about 350 bytes).
pub type SharedTags = std::sync::Arc<BuildingTags>;

/// Number of independently locked parts of a [`TagInterner`].
const INTERN_SHARDS: usize = 16;

/// Hands out one [`SharedTags`] per distinct tag set. Thread-safe (sharded locks), for the
/// readers' parallel passes. Two tag sets are the same only when they are equal bit for bit
/// (`0.0` and `-0.0` are different), so which footprint's copy is kept never shows in an
/// output: runs stay byte-identical whatever the thread count.
pub struct TagInterner {
    shards: Vec<std::sync::Mutex<std::collections::HashMap<u64, Vec<SharedTags>>>>,
    /// The raw pairs already parsed (only the keys [`BuildingTags::from_pairs`] reads), by a
    /// hash of their bytes: a repeated tag set is neither parsed nor hashed field by field
    /// again.
    raw: Vec<std::sync::Mutex<RawShard>>,
}

/// Raw known pairs and their shared parsed tags, by a hash of the pairs' bytes.
type RawShard = std::collections::HashMap<u64, Vec<(Box<[(Box<str>, Box<str>)]>, SharedTags)>>;

impl Default for TagInterner {
    fn default() -> Self {
        TagInterner {
            shards: (0..INTERN_SHARDS).map(|_| Default::default()).collect(),
            raw: (0..INTERN_SHARDS).map(|_| Default::default()).collect(),
        }
    }
}

/// A fast hash of the bytes of `pairs` (a word at a time; not for untrusted keys of a hash
/// table that an attacker fills, but here a collision only costs a comparison).
fn pairs_hash(pairs: &[(&str, &str)]) -> u64 {
    const K: u64 = 0x517c_c1b7_2722_0a95;
    let mut h = 0u64;
    let mut mix = |bytes: &[u8]| {
        let mut chunks = bytes.chunks_exact(8);
        for c in &mut chunks {
            let w = u64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]);
            h = (h.rotate_left(5) ^ w).wrapping_mul(K);
        }
        let mut last = [0u8; 8];
        last[..chunks.remainder().len()].copy_from_slice(chunks.remainder());
        h = (h.rotate_left(5) ^ u64::from_le_bytes(last) ^ (bytes.len() as u64) << 56)
            .wrapping_mul(K);
    };
    for (k, v) in pairs {
        mix(k.as_bytes());
        mix(v.as_bytes());
    }
    h
}

impl TagInterner {
    /// The shared copy of `tags`: an existing one equal bit for bit, or `tags` itself, kept.
    pub(crate) fn intern(&self, tags: BuildingTags) -> SharedTags {
        let h = tags.bits_hash();
        let shard = &self.shards[(h % INTERN_SHARDS as u64) as usize];
        // A poisoned lock only means another thread panicked mid-insert; the map is still a
        // valid cache (every entry was pushed whole).
        let mut map = shard.lock().unwrap_or_else(|e| e.into_inner());
        let bucket = map.entry(h).or_default();
        if let Some(t) = bucket.iter().find(|t| t.same_bits(&tags)) {
            return t.clone();
        }
        let t = SharedTags::new(tags);
        bucket.push(t.clone());
        t
    }

    /// The shared parsed tags of raw key/value pairs: [`Self::intern`] of
    /// [`BuildingTags::from_pairs`], parsing each distinct set of the pairs it reads once.
    pub(crate) fn intern_pairs(&self, pairs: &[(&str, &str)]) -> SharedTags {
        let filtered: Vec<(&str, &str)>;
        let known = if pairs.iter().all(|(k, _)| is_known_key(k)) {
            pairs
        } else {
            filtered = pairs
                .iter()
                .copied()
                .filter(|(k, _)| is_known_key(k))
                .collect();
            &filtered
        };
        let h = pairs_hash(known);
        let shard = &self.raw[(h % INTERN_SHARDS as u64) as usize];
        let same = |stored: &[(Box<str>, Box<str>)]| {
            stored.len() == known.len()
                && stored
                    .iter()
                    .zip(known)
                    .all(|((a, b), (c, d))| **a == **c && **b == **d)
        };
        {
            // Poisoned: see `intern`.
            let map = shard.lock().unwrap_or_else(|e| e.into_inner());
            if let Some((_, t)) = map.get(&h).and_then(|b| b.iter().find(|(s, _)| same(s))) {
                return t.clone();
            }
        }
        let t = self.intern(BuildingTags::from_pairs(known.iter().copied()));
        let mut map = shard.lock().unwrap_or_else(|e| e.into_inner());
        let bucket = map.entry(h).or_default();
        if !bucket.iter().any(|(s, _)| same(s)) {
            let stored = known.iter().map(|&(k, v)| (k.into(), v.into())).collect();
            bucket.push((stored, t.clone()));
        }
        t
    }

    /// Number of distinct tag sets handed out.
    pub fn len(&self) -> usize {
        self.shards
            .iter()
            .map(|s| {
                s.lock()
                    .unwrap_or_else(|e| e.into_inner())
                    .values()
                    .map(Vec::len)
                    .sum::<usize>()
            })
            .sum()
    }

    /// Whether no tag set was handed out yet.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

impl BuildingTags {
    /// Where this footprint's storeys, height and roof come from: `provenance` when the
    /// estimator or the neighbours' inference set it; otherwise read off the tags themselves:
    /// storeys [`ValueSource::Tag`] when `building:levels` or `height` is tagged (the storeys
    /// then follow the tagged height), height `Tag` when `height` is tagged and else the
    /// storeys' source (levels times the floor height), roof `Tag` when `roof:shape` is
    /// present (an unknown value is drawn flat, still the tag's doing); everything else
    /// [`ValueSource::Kb`] with its uncertainty unknown here (`None`): the style drawn from the
    /// knowledge base fills it (`kb::Style::provenance`).
    pub(crate) fn provenance(&self) -> Provenance {
        if let Some(p) = self.provenance {
            return p;
        }
        let tagged = |x: Option<f64>, least: f64| x.is_some_and(|v| v.is_finite() && v > least);
        let by = |t: bool| if t { ValueSource::Tag } else { ValueSource::Kb };
        let height = tagged(self.height, 0.0);
        let storeys = by(height || tagged(self.levels, 0.0));
        Provenance {
            storeys,
            height: if height { ValueSource::Tag } else { storeys },
            roof: by(self.roof_shape.is_some() || self.invalid_roof_shape.is_some()),
            ..Provenance::default()
        }
    }

    /// `building=roof|carport|canopy`, or `building:part=roof|canopy` (a roof with no walls
    /// under it: a canopy, a carport, a roof on pillars). A part's own `building:part` value
    /// decides over `building`.
    pub fn is_roof(&self) -> bool {
        let roof = |v: &str| matches!(v, "roof" | "carport" | "canopy");
        match &self.building_part {
            Some(p) => roof(p),
            None => self.building.as_deref().is_some_and(roof),
        }
    }

    /// Every field, floats by their bits: the identity [`TagInterner`] shares tags by. The
    /// destructuring names every field, so a new field cannot be forgotten here.
    fn bits_key(&self) -> impl PartialEq + std::hash::Hash + '_ {
        let BuildingTags {
            building,
            building_part,
            has_building,
            name,
            height,
            min_height,
            levels,
            min_level,
            roof_shape,
            invalid_roof_shape,
            roof_height,
            roof_angle,
            roof_levels,
            roof_orientation,
            roof_direction,
            colour,
            roof_colour,
            material,
            roof_material,
            ignored,
            provenance,
            form,
            man_made,
            historic,
            tower_type,
            structure,
        } = self;
        let f = |x: &Option<f64>| x.map(f64::to_bits);
        let p = provenance.map(|p| {
            (
                [p.storeys, p.height, p.roof],
                [p.storeys_error, p.height_error, p.roof_probability].map(|x| x.map(f64::to_bits)),
            )
        });
        let c = |x: &Option<Color>| x.map(|c| [c.r, c.g, c.b, c.a].map(f32::to_bits));
        (
            (building, building_part, has_building, name),
            (invalid_roof_shape, roof_orientation),
            (material, roof_material, ignored, roof_shape),
            [
                f(height),
                f(min_height),
                f(levels),
                f(min_level),
                f(roof_height),
                f(roof_angle),
                f(roof_levels),
                f(roof_direction),
            ],
            [c(colour), c(roof_colour)],
            (p, form),
            (man_made, historic, tower_type, structure),
        )
    }

    /// A hash of [`Self::bits_key`] with fixed keys (the same in every run).
    fn bits_hash(&self) -> u64 {
        use std::hash::{Hash, Hasher};
        let mut h = std::collections::hash_map::DefaultHasher::new();
        self.bits_key().hash(&mut h);
        h.finish()
    }

    /// Equal bit for bit (unlike `==`, which takes `0.0` for `-0.0`).
    pub fn same_bits(&self, other: &BuildingTags) -> bool {
        self.bits_key() == other.bits_key()
    }
}

impl BuildingTags {
    /// Builds the parsed tags from raw key/value pairs (OSM tags or shapefile attributes mapped
    /// to OSM keys). Unknown keys are ignored silently; known keys with bad values go to `ignored`.
    /// Never panics. When a key appears twice, the last usable value wins.
    pub(crate) fn from_pairs<'a>(
        pairs: impl IntoIterator<Item = (&'a str, &'a str)>,
    ) -> BuildingTags {
        let mut t = BuildingTags::default();
        let mut part: Option<String> = None;
        for (key, value) in pairs {
            let v = value.trim();
            let known = is_known_key(key);
            if !known {
                continue;
            }
            if v.is_empty() {
                t.ignore(key, value, "empty value");
                continue;
            }
            let res: Result<(), TagError> = match key {
                "building" => {
                    t.building = Some(v.to_ascii_lowercase());
                    Ok(())
                }
                "building:part" => {
                    part = Some(v.to_ascii_lowercase());
                    Ok(())
                }
                "name" => {
                    t.name = Some(v.to_string());
                    Ok(())
                }
                "height" => parse_length_checked(v).and_then(|h| {
                    if h > 0.0 {
                        t.height = Some(h);
                        Ok(())
                    } else {
                        Err(TagError::ZeroHeight)
                    }
                }),
                "min_height" => parse_length_checked(v).map(|h| t.min_height = Some(h)),
                "roof:height" => parse_length_checked(v).map(|h| t.roof_height = Some(h)),
                "building:levels" => parse_levels(v).map(|n| t.levels = Some(n)),
                "building:min_level" => parse_levels(v).map(|n| t.min_level = Some(n)),
                "roof:levels" => parse_levels(v).map(|n| t.roof_levels = Some(n)),
                "roof:shape" => match RoofShape::parse(first_value(v)) {
                    Some(s) => {
                        t.roof_shape = Some(s);
                        Ok(())
                    }
                    None => {
                        t.invalid_roof_shape = Some(v.to_string());
                        Err(TagError::UnknownRoofShape)
                    }
                },
                "roof:angle" => parse_angle(v).map(|a| t.roof_angle = Some(a)),
                "roof:orientation" => {
                    let o = first_value(v).to_ascii_lowercase();
                    if o == "along" || o == "across" {
                        t.roof_orientation = Some(o);
                        Ok(())
                    } else {
                        Err(TagError::RoofOrientation)
                    }
                }
                "roof:direction" => parse_direction(v).map(|d| t.roof_direction = Some(d)),
                "building:colour" | "building:color" => match Color::parse(first_value(v)) {
                    Some(c) => {
                        t.colour = Some(c);
                        Ok(())
                    }
                    None => Err(TagError::UnknownColour),
                },
                "roof:colour" | "roof:color" => match Color::parse(first_value(v)) {
                    Some(c) => {
                        t.roof_colour = Some(c);
                        Ok(())
                    }
                    None => Err(TagError::UnknownColour),
                },
                "building:material" => {
                    t.material = Some(first_value(v).to_ascii_lowercase());
                    Ok(())
                }
                "roof:material" => {
                    t.roof_material = Some(first_value(v).to_ascii_lowercase());
                    Ok(())
                }
                "man_made" => {
                    t.man_made = Some(first_value(v).to_ascii_lowercase());
                    Ok(())
                }
                "historic" => {
                    t.historic = Some(first_value(v).to_ascii_lowercase());
                    Ok(())
                }
                "tower:type" => {
                    t.tower_type = Some(first_value(v).to_ascii_lowercase());
                    Ok(())
                }
                _ => Ok(()),
            };
            if let Err(reason) = res {
                t.ignore(key, value, &reason.to_string());
            }
        }
        t.has_building = t.building.as_deref().is_some_and(|b| b != "no");
        t.building_part = part.clone().filter(|p| p != "no");
        // `building:part` fills `building` only when `building` says nothing better.
        match (&t.building, part) {
            (None, Some(p)) => t.building = Some(p),
            (Some(b), Some(p)) if b == "no" && p != "no" => t.building = Some(p),
            _ => {}
        }
        t
    }

    fn ignore(&mut self, key: &str, value: &str, reason: &str) {
        self.ignored
            .push((key.to_string(), value.to_string(), reason.to_string()));
    }
}

/// Whether [`BuildingTags::from_pairs`] reads `key` (it ignores every other key, so the parsed
/// tags depend only on the pairs with these keys, in their order).
pub(crate) fn is_known_key(key: &str) -> bool {
    matches!(
        key,
        "building"
            | "building:part"
            | "name"
            | "height"
            | "min_height"
            | "building:levels"
            | "building:min_level"
            | "roof:shape"
            | "roof:height"
            | "roof:angle"
            | "roof:levels"
            | "roof:orientation"
            | "roof:direction"
            | "building:colour"
            | "building:color"
            | "roof:colour"
            | "roof:color"
            | "building:material"
            | "roof:material"
            | "man_made"
            | "historic"
            | "tower:type"
    )
}

/// The first value of an OSM `;`-separated list, trimmed.
fn first_value(s: &str) -> &str {
    s.split(';').next().unwrap_or("").trim()
}

/// Why a known tag's value is ignored (the reason [`BuildingTags::ignored`] lists).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub(crate) enum TagError {
    /// A number was expected and the value is blank.
    #[error("no number")]
    NoNumber,
    /// Not a plain decimal number.
    #[error("not a number")]
    NotANumber,
    /// Two decimal commas, or a comma and a point.
    #[error("ambiguous decimal separators")]
    AmbiguousSeparators,
    /// NaN or an infinity.
    #[error("not a finite number")]
    NotFinite,
    /// A length with `'` or `"` that does not read as feet and inches.
    #[error("cannot read feet and inches")]
    FeetAndInches,
    /// A negative length.
    #[error("negative length")]
    NegativeLength,
    /// A length unit not known.
    #[error("unknown unit `{unit}`")]
    UnknownUnit {
        /// The unit as written (lower case).
        unit: String,
    },
    /// A length over [`MAX_LENGTH_M`].
    #[error("absurd length (over {} m)", MAX_LENGTH_M)]
    AbsurdLength,
    /// `height=0`.
    #[error("a height of zero is no height")]
    ZeroHeight,
    /// A negative level count.
    #[error("negative level count")]
    NegativeLevels,
    /// A level count over [`MAX_LEVELS`].
    #[error("absurd level count (over {})", MAX_LEVELS)]
    AbsurdLevels,
    /// `roof:shape` not known.
    #[error("unknown roof shape")]
    UnknownRoofShape,
    /// `roof:angle` outside 0..90.
    #[error("roof angle outside 0..90 degrees")]
    AngleOutOfRange,
    /// `roof:orientation` other than `along` or `across`.
    #[error("roof:orientation must be along or across")]
    RoofOrientation,
    /// `roof:direction` neither degrees nor a compass point.
    #[error("not a direction (degrees or N, NE, E...)")]
    NotADirection,
    /// A colour that does not parse.
    #[error("unknown colour")]
    UnknownColour,
}

/// Parses a plain decimal number, accepting one decimal comma (`12,5`). Rejects NaN and
/// infinities (Rust's float parser would accept `inf` and `NaN`).
fn parse_number(s: &str) -> Result<f64, TagError> {
    let s = s.trim();
    if s.is_empty() {
        return Err(TagError::NoNumber);
    }
    // Only digits, one sign, one separator and an exponent are numbers here: this rejects
    // `inf`, `NaN` and `0x10` before the float parser sees them.
    if !s
        .chars()
        .all(|c| c.is_ascii_digit() || matches!(c, '.' | ',' | '+' | '-' | 'e' | 'E'))
    {
        return Err(TagError::NotANumber);
    }
    let normalised;
    let s = if s.contains(',') {
        if s.matches(',').count() > 1 || s.contains('.') {
            return Err(TagError::AmbiguousSeparators);
        }
        normalised = s.replace(',', ".");
        normalised.as_str()
    } else {
        s
    };
    let v: f64 = s.parse().map_err(|_| TagError::NotANumber)?;
    if !v.is_finite() {
        return Err(TagError::NotFinite);
    }
    Ok(v)
}

/// Parses a length in metres leniently: `12`, `12 m`, `12m`, `12,5`, `12;15` (first value),
/// `40'` or `40 ft` (feet), `12'6"`. Rejects NaN, infinities, negative values and absurd ones
/// (over [`MAX_LENGTH_M`]), with the reason.
pub(crate) fn parse_length_checked(s: &str) -> Result<f64, TagError> {
    let s = first_value(s);
    let lower = s.to_ascii_lowercase();
    let lower = lower.trim();
    // Feet and inches: `12'`, `12'6"`, `12' 6"`, `6"`.
    if lower.contains('\'') || lower.ends_with('"') {
        let (feet_str, rest) = match lower.split_once('\'') {
            Some((f, r)) => (f, r.trim()),
            None => ("0", lower),
        };
        let feet = parse_number(feet_str)?;
        let inches = match rest.strip_suffix('"') {
            Some(i) => parse_number(i)?,
            None if rest.is_empty() => 0.0,
            None => return Err(TagError::FeetAndInches),
        };
        if feet < 0.0 || inches < 0.0 {
            return Err(TagError::NegativeLength);
        }
        return check_length(feet * FOOT_M + inches * INCH_M);
    }
    let (num, factor) = split_unit(lower)?;
    let v = parse_number(num)?;
    check_length(v * factor)
}

/// Splits a trailing unit off a length and gives the factor to metres.
fn split_unit(s: &str) -> Result<(&str, f64), TagError> {
    const UNITS: [(&str, f64); 12] = [
        ("metres", 1.0),
        ("meters", 1.0),
        ("metre", 1.0),
        ("meter", 1.0),
        ("feet", FOOT_M),
        ("foot", FOOT_M),
        ("ft", FOOT_M),
        ("km", 1000.0),
        ("cm", 0.01),
        ("mm", 0.001),
        ("m", 1.0),
        ("in", INCH_M),
    ];
    let end = s.trim_end_matches(|c: char| c.is_ascii_alphabetic());
    let unit = s[end.len()..].trim();
    if unit.is_empty() {
        return Ok((s, 1.0));
    }
    match UNITS.iter().find(|(u, _)| *u == unit) {
        Some((_, f)) => Ok((end.trim(), *f)),
        None => Err(TagError::UnknownUnit {
            unit: unit.to_string(),
        }),
    }
}

fn check_length(v: f64) -> Result<f64, TagError> {
    if !v.is_finite() {
        Err(TagError::NotFinite)
    } else if v < 0.0 {
        Err(TagError::NegativeLength)
    } else if v > MAX_LENGTH_M {
        Err(TagError::AbsurdLength)
    } else {
        Ok(v)
    }
}

/// [`parse_length_checked`] without the reason.
#[cfg(test)]
fn parse_length(s: &str) -> Option<f64> {
    parse_length_checked(s).ok()
}

/// A level count: a non-negative number, first of a list, decimal comma accepted.
fn parse_levels(s: &str) -> Result<f64, TagError> {
    let v = parse_number(first_value(s))?;
    if v < 0.0 {
        Err(TagError::NegativeLevels)
    } else if v > MAX_LEVELS {
        Err(TagError::AbsurdLevels)
    } else {
        Ok(v)
    }
}

/// A roof angle in degrees (`30`, `30°`, `30 deg`), in 0..=90.
fn parse_angle(s: &str) -> Result<f64, TagError> {
    let s = first_value(s);
    let s = s
        .trim_end_matches('°')
        .trim_end_matches("degrees")
        .trim_end_matches("deg")
        .trim();
    let v = parse_number(s)?;
    if (0.0..=90.0).contains(&v) {
        Ok(v)
    } else {
        Err(TagError::AngleOutOfRange)
    }
}

/// A direction in degrees from north (wrapped into 0..360), or a 16-wind compass point.
fn parse_direction(s: &str) -> Result<f64, TagError> {
    const WINDS: [&str; 16] = [
        "N", "NNE", "NE", "ENE", "E", "ESE", "SE", "SSE", "S", "SSW", "SW", "WSW", "W", "WNW",
        "NW", "NNW",
    ];
    let s = first_value(s);
    let up = s.to_ascii_uppercase();
    if let Some(i) = WINDS.iter().position(|w| *w == up) {
        return Ok(i as f64 * 22.5);
    }
    let v = parse_number(s.trim_end_matches('°').trim()).map_err(|_| TagError::NotADirection)?;
    let d = v.rem_euclid(360.0);
    // rem_euclid rounds tiny negative values up to exactly 360.
    Ok(if d >= 360.0 { 0.0 } else { d })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interner_shares_equal_tags_and_only_equal_ones() {
        use rayon::prelude::*;
        let i = TagInterner::default();
        let parse = |pairs: &[(&str, &str)]| BuildingTags::from_pairs(pairs.iter().copied());
        let a = i.intern(parse(&[("building", "yes")]));
        let b = i.intern(parse(&[("building", "yes"), ("source", "survey")]));
        assert!(
            std::sync::Arc::ptr_eq(&a, &b),
            "unknown keys do not make a new tag set"
        );
        let c = i.intern(parse(&[("building", "house")]));
        let d = i.intern(parse(&[("building", "yes"), ("height", "x")]));
        assert!(!std::sync::Arc::ptr_eq(&a, &c) && !std::sync::Arc::ptr_eq(&a, &d));
        assert_eq!(i.len(), 3);
        // 0.0 == -0.0, but they are written differently: never shared.
        let mut zero = parse(&[("building", "yes")]);
        zero.min_height = Some(0.0);
        let mut minus = zero.clone();
        minus.min_height = Some(-0.0);
        assert_eq!(zero, minus);
        let (z, m) = (i.intern(zero), i.intern(minus));
        assert!(!std::sync::Arc::ptr_eq(&z, &m));
        assert_eq!(m.min_height.map(f64::to_bits), Some((-0.0f64).to_bits()));
        // From many threads at once: still one copy per tag set.
        let many: Vec<SharedTags> = (0..2000)
            .into_par_iter()
            .map(|k| {
                i.intern(parse(&[
                    ("building", "yes"),
                    ("building:levels", ["2", "3"][k % 2]),
                ]))
            })
            .collect();
        assert_eq!(i.len(), 7);
        assert!(many
            .iter()
            .all(|t| t.levels == Some(2.0) || t.levels == Some(3.0)));
        assert!(many
            .iter()
            .step_by(2)
            .all(|t| std::sync::Arc::ptr_eq(t, &many[0])));
    }

    fn close(a: Option<f64>, b: f64) -> bool {
        a.is_some_and(|a| (a - b).abs() < 1e-9)
    }

    #[test]
    fn lengths_plain_and_metres() {
        assert!(close(parse_length("12"), 12.0));
        assert!(close(parse_length("12 m"), 12.0));
        assert!(close(parse_length("12m"), 12.0));
        assert!(close(parse_length(" 12.5 m "), 12.5));
        assert!(close(parse_length("12,5"), 12.5));
        assert!(close(parse_length("12.5 metres"), 12.5));
        assert!(close(parse_length("0"), 0.0));
    }

    #[test]
    fn lengths_lists_take_the_first() {
        assert!(close(parse_length("12;15"), 12.0));
        assert!(close(parse_length("12 m;15 m"), 12.0));
    }

    #[test]
    fn lengths_in_feet() {
        assert!(close(parse_length("40'"), 40.0 * 0.3048));
        assert!(close(parse_length("40 ft"), 40.0 * 0.3048));
        assert!(close(parse_length("40ft"), 40.0 * 0.3048));
        assert!(close(parse_length("12'6\""), 12.0 * 0.3048 + 6.0 * 0.0254));
        assert!(close(parse_length("12' 6\""), 12.0 * 0.3048 + 6.0 * 0.0254));
    }

    #[test]
    fn lengths_rejected() {
        for bad in [
            "NaN",
            "nan",
            "inf",
            "-inf",
            "infinity",
            "-3",
            "-3 m",
            "",
            "abc",
            "12 parsecs",
            "1001",
            "5000 m",
            "1e400",
            "1,2,3",
            "1.2,3",
            "12'x\"",
            "m",
        ] {
            assert_eq!(parse_length(bad), None, "{bad:?} should be rejected");
        }
        assert!(parse_length_checked("2000")
            .unwrap_err()
            .to_string()
            .contains("absurd"));
        assert!(parse_length_checked("-1")
            .unwrap_err()
            .to_string()
            .contains("negative"));
    }

    #[test]
    fn tags_heights_and_levels() {
        let t = BuildingTags::from_pairs([
            ("building", "Apartments"),
            ("height", "12 m"),
            ("min_height", "3"),
            ("building:levels", "4;5"),
            ("building:min_level", "1"),
            ("roof:height", "2,5"),
            ("roof:levels", "1"),
            ("name", " Villa "),
            ("wikidata", "Q1"),
        ]);
        assert_eq!(t.building.as_deref(), Some("apartments"));
        assert_eq!(t.name.as_deref(), Some("Villa"));
        assert_eq!(t.height, Some(12.0));
        assert_eq!(t.min_height, Some(3.0));
        assert_eq!(t.levels, Some(4.0));
        assert_eq!(t.min_level, Some(1.0));
        assert_eq!(t.roof_height, Some(2.5));
        assert_eq!(t.roof_levels, Some(1.0));
        assert!(t.ignored.is_empty(), "{:?}", t.ignored);
    }

    #[test]
    fn tags_bad_values_are_reported() {
        let t = BuildingTags::from_pairs([
            ("building", "yes"),
            ("height", "tall"),
            ("min_height", "-2"),
            ("building:levels", "-1"),
            ("roof:levels", "500"),
            ("roof:shape", "9.0"),
            ("roof:angle", "120"),
            ("roof:orientation", "sideways"),
            ("roof:direction", "up"),
            ("name", "   "),
        ]);
        assert_eq!(t.height, None);
        assert_eq!(t.min_height, None);
        assert_eq!(t.levels, None);
        assert_eq!(t.roof_levels, None);
        assert_eq!(t.roof_shape, None);
        assert_eq!(t.invalid_roof_shape.as_deref(), Some("9.0"));
        assert_eq!(t.roof_angle, None);
        assert_eq!(t.roof_orientation, None);
        assert_eq!(t.roof_direction, None);
        assert_eq!(t.name, None);
        let keys: Vec<&str> = t.ignored.iter().map(|(k, _, _)| k.as_str()).collect();
        assert_eq!(
            keys,
            [
                "height",
                "min_height",
                "building:levels",
                "roof:levels",
                "roof:shape",
                "roof:angle",
                "roof:orientation",
                "roof:direction",
                "name"
            ]
        );
        assert!(t.ignored.iter().all(|(_, _, r)| !r.is_empty()));
        assert_eq!(t.ignored[4].1, "9.0");
        assert_eq!(t.ignored[4].2, "unknown roof shape");
    }

    #[test]
    fn tags_zero_and_absurd_height() {
        let t = BuildingTags::from_pairs([("height", "0")]);
        assert_eq!(t.height, None);
        assert_eq!(t.ignored.len(), 1);
        let t = BuildingTags::from_pairs([("height", "1200")]);
        assert_eq!(t.height, None);
        assert!(t.ignored[0].2.contains("absurd"));
    }

    #[test]
    fn tags_roof_shapes() {
        for (v, s) in [
            ("half_hipped", RoofShape::HalfHipped),
            ("half-hipped", RoofShape::HalfHipped),
            ("Gabled", RoofShape::Gabled),
            ("hipped;gabled", RoofShape::Hipped),
            ("pyramid", RoofShape::Pyramidal),
        ] {
            let t = BuildingTags::from_pairs([("roof:shape", v)]);
            assert_eq!(t.roof_shape, Some(s), "{v}");
            assert!(t.ignored.is_empty());
        }
        let t = BuildingTags::from_pairs([("roof:shape", "many")]);
        assert_eq!(t.roof_shape, None);
        assert_eq!(t.ignored.len(), 1);
    }

    #[test]
    fn tags_roof_direction_and_orientation() {
        let t =
            BuildingTags::from_pairs([("roof:direction", "NE"), ("roof:orientation", "Across")]);
        assert_eq!(t.roof_direction, Some(45.0));
        assert_eq!(t.roof_orientation.as_deref(), Some("across"));
        let t = BuildingTags::from_pairs([("roof:direction", "-90")]);
        assert_eq!(t.roof_direction, Some(270.0));
        let t = BuildingTags::from_pairs([("roof:direction", "400°")]);
        assert_eq!(t.roof_direction, Some(40.0));
        let t = BuildingTags::from_pairs([("roof:direction", "wsw")]);
        assert_eq!(t.roof_direction, Some(247.5));
        let t = BuildingTags::from_pairs([("roof:angle", "30°")]);
        assert_eq!(t.roof_angle, Some(30.0));
    }

    #[test]
    fn tags_building_part_and_materials() {
        let t = BuildingTags::from_pairs([("building:part", "yes"), ("roof:material", "Tiles")]);
        assert_eq!(t.building.as_deref(), Some("yes"));
        assert_eq!(t.roof_material.as_deref(), Some("tiles"));
        let t = BuildingTags::from_pairs([("building", "no"), ("building:part", "roof")]);
        assert_eq!(t.building.as_deref(), Some("roof"));
        let t = BuildingTags::from_pairs([("building", "house"), ("building:part", "roof")]);
        assert_eq!(t.building.as_deref(), Some("house"));
        assert_eq!(t.building_part.as_deref(), Some("roof"));
        assert!(t.has_building);
        let t = BuildingTags::from_pairs([("building", "no"), ("building:part", "yes")]);
        assert!(!t.has_building);
        let t = BuildingTags::from_pairs([("building:material", "brick;stone")]);
        assert_eq!(t.material.as_deref(), Some("brick"));
    }

    proptest::proptest! {
        #[test]
        fn parse_length_never_panics_and_is_sane(s in ".{0,16}") {
            if let Some(v) = parse_length(&s) {
                proptest::prop_assert!(v.is_finite() && (0.0..=MAX_LENGTH_M).contains(&v));
            }
            let t = BuildingTags::from_pairs([("height", s.as_str()), ("roof:direction", s.as_str()),
                ("building:levels", s.as_str()), ("roof:angle", s.as_str())]);
            if let Some(d) = t.roof_direction { proptest::prop_assert!((0.0..360.0).contains(&d)); }
        }
    }
}
