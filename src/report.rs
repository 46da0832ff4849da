//! The run report: counts and one entry per skipped or repaired footprint, with its reason.
//! Written as JSON by `--report`; nothing is ever dropped silently.

use serde::{Deserialize, Serialize};

use crate::model::{Provenance, SourceId, ValueSource};

/// What happened to one input record.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Outcome {
    /// Not in the outputs.
    Skipped,
    /// In the outputs, after a repair.
    Repaired,
    /// In the outputs; the entry notes a value that was ignored or a fallback taken.
    Note,
}

/// One report line about one record.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Entry {
    /// `way/123`, `relation/45`, `shp/7`, a text id as it is, or empty for file-level notes.
    pub id: String,
    /// What happened to the record; `skipped`, `repaired` or `note` in the JSON.
    pub outcome: Outcome,
    /// Why, in words for people, e.g. `coordinates cannot be projected to the output CRS`.
    pub reason: String,
}

/// Counts and entries of one run.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct Report {
    /// Building footprints read (outlines and multipolygons).
    pub read: usize,
    /// `building:part` footprints read.
    pub parts_read: usize,
    /// Buildings written to every output.
    pub generated: usize,
    /// Footprints not written (each has an entry).
    pub skipped: usize,
    /// Footprints written after a repair (each has an entry).
    pub repaired: usize,
    /// What the LOD3 facade rules did, summed over the buildings written (zero below LOD3):
    /// openings and balconies left out on party walls, entrances placed, doors made windows,
    /// windows on curved runs, wall and party-wall areas.
    pub facades: crate::model::FacadeCounts,
    /// Where the buildings written got their storeys, height and roof from: per value, the
    /// count of buildings per source (`tag`, `neighbours`, `fitted`, `model`, `kb`).
    #[serde(default)]
    pub provenance: ProvenanceCounts,
    /// One entry per skipped or repaired record and per note, in the order they were found:
    /// reading the input, loading the knowledge base, preparing, then deriving in lot order.
    pub entries: Vec<Entry>,
    /// What changed since the run given by `--previous` (absent without it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub changes: Option<Changes>,
    /// The input's admin boundaries and the buildings that took their zone from one (absent
    /// when the input has none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub boundaries: Option<Boundaries>,
    /// The ground the buildings stand on (issue 44): the `--dem` files, the `--ground-height`
    /// constant, or `no terrain: buildings stand on z = 0`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub terrain: Option<String>,
}

/// [`Report::terrain`] of a run without `--dem` or `--ground-height`.
pub const NO_TERRAIN: &str = "no terrain: buildings stand on z = 0";

/// The input's administrative boundaries (OSM `boundary=administrative`, `admin_level`
/// 2..=10), and what the knowledge base's zone lookup took from them.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Boundaries {
    /// Boundaries assembled (relations and closed ways).
    pub read: usize,
    /// Boundary relations assembled without some of their members (an extract cut by a box):
    /// only their rings that close are used, by id.
    pub partial: Vec<String>,
    /// Boundaries dropped because the extract lacks members or nodes of theirs and no ring of
    /// theirs closes (or an inner ring is lost), by id.
    pub incomplete: Vec<String>,
    /// Per boundary that matched a zone of the knowledge base, the buildings located through
    /// it, in boundary order (admin level, then id).
    pub zones: Vec<BoundaryZone>,
}

/// One input boundary matched to a zone, and how many buildings it placed.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct BoundaryZone {
    /// The boundary's id, `relation/45`.
    pub boundary: String,
    /// Its name (`name`, else `name:en`, else `int_name`).
    pub name: String,
    /// Its `admin_level`.
    pub admin_level: u8,
    /// The path of the KB zone it matched; a building in it takes the deepest zone of that
    /// zone's subtree containing it, or this one.
    pub zone: String,
    /// Buildings of the run whose zone came through this boundary.
    pub buildings: usize,
}

/// What changed since a previous run (`--previous DIR`), by source id, sorted.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Changes {
    /// The previous run's folder, as given.
    pub previous: String,
    /// Why nothing could be reused, when so (another seed, LOD, knowledge base...).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub not_reused: Option<String>,
    /// Buildings in this run and not in the previous one.
    pub added: Vec<String>,
    /// Buildings in the previous run and not in this one.
    pub removed: Vec<String>,
    /// Buildings whose own data changed: geometry, parts or tags as read.
    pub changed: Vec<String>,
    /// Buildings unchanged themselves whose output may change through what they take from
    /// others: a neighbour's values inferred, a street (their front), at LOD3 a neighbour they
    /// touch; or the run's context (another seed, knowledge base, citygen...).
    pub affected: Vec<String>,
    /// Tiles whose files were reused (copied from the previous run, checked by SHA-256).
    pub tiles_reused: usize,
    /// Tiles derived and written again, by suffix.
    pub tiles_rewritten: Vec<String>,
    /// Tiles of the previous run that this run no longer has, by suffix.
    pub tiles_removed: Vec<String>,
    /// Why each tile derived again was not reused, by suffix: a new tile, its buildings
    /// (added, removed, edited, affected), the run's context, or a previous file missing, not a
    /// regular file inside the folder, or not what its manifest lists.
    #[serde(default, skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub tiles_not_reused: std::collections::BTreeMap<String, String>,
}

impl Report {
    /// Adds an entry about a record.
    pub fn add(&mut self, id: Option<SourceId>, outcome: Outcome, reason: impl Into<String>) {
        self.entries.push(Entry {
            id: id.map(|i| i.to_string()).unwrap_or_default(),
            outcome,
            reason: reason.into(),
        });
    }
}

/// Buildings counted by where one of their values came from ([`ValueSource`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct SourceCounts {
    /// From the building's own tags.
    pub tag: usize,
    /// From its tagged neighbours.
    pub neighbours: usize,
    /// From the estimator fitted on the run's tagged buildings.
    pub fitted: usize,
    /// From the model shipped with the knowledge base.
    pub model: usize,
    /// From the knowledge base's appearance.
    pub kb: usize,
}

impl SourceCounts {
    fn count(&mut self, s: ValueSource) {
        *match s {
            ValueSource::Tag => &mut self.tag,
            ValueSource::Neighbours => &mut self.neighbours,
            ValueSource::Fitted => &mut self.fitted,
            ValueSource::Model => &mut self.model,
            ValueSource::Kb => &mut self.kb,
        } += 1;
    }

    fn add(&mut self, o: &SourceCounts) {
        self.tag += o.tag;
        self.neighbours += o.neighbours;
        self.fitted += o.fitted;
        self.model += o.model;
        self.kb += o.kb;
    }
}

/// The provenance of a run's buildings ([`crate::model::Building::provenance`]), counted:
/// `provenance: {storeys: {tag: n, neighbours: n, fitted: n, model: n, kb: n}, height: {..},
/// roof: {..}}` in the report's JSON.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct ProvenanceCounts {
    /// Sources of the storey counts.
    pub storeys: SourceCounts,
    /// Sources of the heights.
    pub height: SourceCounts,
    /// Sources of the roof shapes.
    pub roof: SourceCounts,
}

impl ProvenanceCounts {
    /// Counts one building's provenance.
    pub(crate) fn count(&mut self, p: &Provenance) {
        self.storeys.count(p.storeys);
        self.height.count(p.height);
        self.roof.count(p.roof);
    }

    /// Adds another set of counts (a tile's, a shard's) to these.
    pub(crate) fn add(&mut self, o: &ProvenanceCounts) {
        self.storeys.add(&o.storeys);
        self.height.add(&o.height);
        self.roof.add(&o.roof);
    }
}
