//! The input's admin boundaries matched to the knowledge base's zones: the zone lookup tries
//! them before the KB's own, simplified shapes (a microstate's 1:50m border puts a tenth of
//! its buildings in its neighbours; the extract's own boundary relation does not).
//!
//! **Matching.** A boundary matches a zone when one of its names (`name`, `name:en`,
//! `int_name`) equals the zone's `designation` ignoring case, diacritics and punctuation
//! ([`fold_name`]). When several zones bear the name:
//! - a country boundary (`admin_level` 2) takes the `<country>` zones among them if any, a
//!   deeper one the other zones if any;
//! - a zone below a `<country>` is taken only when that country is on the chain of the zone
//!   found at the boundary's centre (its bounding box's centre, located with the boundaries
//!   matched so far, shallower levels first): a "Neustadt" of the KB is not another country's;
//! - then the zone sharing the longest chain with that centre's zone, then document order.
//!
//! **Lookup** ([`KnowledgeBase::locate_with`]). Among the matched boundaries containing the
//! point, the deepest (highest `admin_level`; equal levels: the first by level and id) gives
//! its zone Z, and the building's zone is the deepest zone of Z's subtree containing the point
//! (a town circle inside the country still wins), or Z itself. No matched boundary: the KB's
//! own lookup ([`KnowledgeBase::locate`]). The boundaries' boxes are in an R-tree and
//! containment looks at one latitude band of edges, so a run without matched boundaries pays
//! nothing and one with them a tree query and a few band scans per building.

use std::collections::HashMap;

use rstar::primitives::{GeomWithData, Rectangle};
use rstar::RTree;

use super::polygon::RingSet;
use super::{KnowledgeBase, ZoneKind};
use crate::input::AdminBoundary;
use crate::model::SourceId;

/// One input boundary matched to a zone.
#[derive(Clone, Debug)]
pub(crate) struct Matched {
    /// The boundary (`relation/45`).
    pub(crate) id: SourceId,
    /// Its first name (`name`, else `name:en`, else `int_name`).
    pub(crate) name: String,
    /// Its `admin_level`.
    pub(crate) admin_level: u8,
    /// The zone it matched.
    pub(crate) zone: usize,
    /// Its polygons with their holes.
    polygons: Vec<RingSet>,
}

/// A box of one polygon of a matched boundary: (boundary, polygon).
type BoundaryBox = GeomWithData<Rectangle<[f64; 2]>, (u32, u32)>;

/// The input's boundaries that matched a zone of one knowledge base, in order of level then
/// input order, with an R-tree of their polygons' boxes. Empty (and free to query) for an input
/// without boundaries, or whose boundaries name no zone.
#[derive(Debug, Default)]
pub(crate) struct BoundaryZones {
    matched: Vec<Matched>,
    index: RTree<BoundaryBox>,
}

/// Where a point is: its zone, and the matched boundary (an index of
/// [`BoundaryZones::matched`]) the zone came through, if one did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Located {
    /// The zone.
    pub(crate) zone: usize,
    /// The boundary that decided it, if any.
    pub(crate) boundary: Option<usize>,
}

impl BoundaryZones {
    /// Matches `input` (lon/lat boundaries, as the OSM reader gives them) to `kb`'s zones; see
    /// the module docs.
    pub(crate) fn new(kb: &KnowledgeBase, input: &[AdminBoundary]) -> BoundaryZones {
        let mut out = BoundaryZones::default();
        if input.is_empty() {
            return out;
        }
        let mut by_name: HashMap<String, Vec<usize>> = HashMap::new();
        for (i, z) in kb.zones().iter().enumerate().skip(1) {
            by_name.entry(fold_name(&z.name)).or_default().push(i);
        }
        let mut order: Vec<usize> = (0..input.len()).collect();
        order.sort_by_key(|&i| input[i].admin_level);
        for i in order {
            let b = &input[i];
            let mut candidates: Vec<usize> = b
                .names
                .iter()
                .filter_map(|n| by_name.get(&fold_name(n)))
                .flatten()
                .copied()
                .collect();
            if candidates.is_empty() {
                continue;
            }
            candidates.sort_unstable();
            candidates.dedup();
            let polygons: Vec<RingSet> = b
                .polygons
                .iter()
                .filter_map(|p| {
                    let ring = |r: &Vec<(f64, f64)>| r.iter().map(|&(x, y)| [x, y]).collect();
                    RingSet::new(
                        std::iter::once(&p.outer)
                            .chain(&p.holes)
                            .map(ring)
                            .collect(),
                    )
                })
                .collect();
            let Some(centre) = centre_of(&polygons) else {
                continue;
            };
            let context = kb.locate_with(&out, centre[0], centre[1]).zone;
            let Some(zone) = choose(kb, &candidates, b.admin_level, context) else {
                continue;
            };
            out.matched.push(Matched {
                id: b.id,
                name: b.names.first().cloned().unwrap_or_default(),
                admin_level: b.admin_level,
                zone,
                polygons,
            });
            // The tree is rebuilt once at the end; until then lookups scan `matched`.
        }
        let boxes = out
            .matched
            .iter()
            .enumerate()
            .flat_map(|(m, b)| {
                b.polygons.iter().enumerate().map(move |(p, r)| {
                    GeomWithData::new(
                        Rectangle::from_corners(r.bbox.0, r.bbox.1),
                        (m as u32, p as u32),
                    )
                })
            })
            .collect();
        out.index = RTree::bulk_load(boxes);
        out
    }

    /// The matched boundaries, by level then input order.
    pub(crate) fn matched(&self) -> &[Matched] {
        &self.matched
    }

    /// The deepest matched boundary containing (lon, lat): highest level, then first.
    fn deepest_at(&self, lon: f64, lat: f64) -> Option<usize> {
        if self.matched.is_empty() || !lon.is_finite() || !lat.is_finite() {
            return None;
        }
        let better = |m: usize, best: Option<usize>| {
            best.is_none_or(|b| {
                let (lm, lb) = (self.matched[m].admin_level, self.matched[b].admin_level);
                lm > lb || (lm == lb && m < b)
            })
        };
        let mut best = None;
        if self.index.size() == 0 {
            // While matching: the boundaries matched so far, not yet in the tree.
            for (m, b) in self.matched.iter().enumerate() {
                if better(m, best) && b.polygons.iter().any(|p| p.contains(lon, lat)) {
                    best = Some(m);
                }
            }
            return best;
        }
        for hit in self.index.locate_all_at_point([lon, lat]) {
            let (m, p) = (hit.data.0 as usize, hit.data.1 as usize);
            if better(m, best) && self.matched[m].polygons[p].contains(lon, lat) {
                best = Some(m);
            }
        }
        best
    }
}

impl KnowledgeBase {
    /// The zone of (lon, lat) with the input's matched boundaries tried first (see
    /// [`boundaries`](self)); with none, [`KnowledgeBase::locate`]'s. The one lookup of a
    /// building's zone: the run, inference, `kb explain` and `kb edit` all go through it.
    pub(crate) fn locate_with(&self, boundaries: &BoundaryZones, lon: f64, lat: f64) -> Located {
        match boundaries.deepest_at(lon, lat) {
            Some(m) => Located {
                zone: self.locate_within(boundaries.matched[m].zone, lon, lat),
                boundary: Some(m),
            },
            None => Located {
                zone: self.locate(lon, lat),
                boundary: None,
            },
        }
    }
}

/// The centre of the bounding box of the polygon with the largest box.
fn centre_of(polygons: &[RingSet]) -> Option<[f64; 2]> {
    let area = |r: &RingSet| (r.bbox.1[0] - r.bbox.0[0]) * (r.bbox.1[1] - r.bbox.0[1]);
    let big = polygons.iter().max_by(|a, b| area(a).total_cmp(&area(b)))?;
    Some([
        (big.bbox.0[0] + big.bbox.1[0]) / 2.0,
        (big.bbox.0[1] + big.bbox.1[1]) / 2.0,
    ])
}

/// The zone a boundary of `level` named like `candidates` (sorted, document order) matches,
/// `context` being the zone at its centre; see the module docs.
fn choose(kb: &KnowledgeBase, candidates: &[usize], level: u8, context: usize) -> Option<usize> {
    let is_country = |i: usize| kb.zone(i).is_some_and(|z| z.kind == ZoneKind::Country);
    let wanted = |i: &usize| is_country(*i) == (level <= 2);
    let preferred: Vec<usize> = if candidates.iter().any(wanted) {
        candidates.iter().copied().filter(wanted).collect()
    } else {
        candidates.to_vec()
    };
    let chain = kb.lineage(context);
    let plausible = |&c: &usize| {
        let country = kb.lineage(c).into_iter().rev().find(|&a| is_country(a));
        match country {
            Some(k) if k != c => chain.contains(&k),
            _ => true,
        }
    };
    let shared = |c: usize| {
        kb.lineage(c)
            .iter()
            .zip(&chain)
            .take_while(|(a, b)| a == b)
            .count()
    };
    // The longest shared chain; of equals, the first in document order.
    preferred
        .into_iter()
        .filter(plausible)
        .min_by_key(|&c| (std::cmp::Reverse(shared(c)), c))
}

/// A name folded for comparison: lower case, Latin diacritics dropped (`é` → `e`, `ß` → `ss`,
/// `æ` → `ae`), every run of characters that are not letters or digits one space, trimmed.
pub(crate) fn fold_name(name: &str) -> String {
    let mut out = String::with_capacity(name.len());
    let mut gap = false;
    for c in name.chars().flat_map(char::to_lowercase) {
        if !c.is_alphanumeric() {
            gap = true;
            continue;
        }
        if gap && !out.is_empty() {
            out.push(' ');
        }
        gap = false;
        match fold_char(c) {
            Some(s) => out.push_str(s),
            None => out.push(c),
        }
    }
    out
}

/// The plain letters of a lower-case Latin letter with a diacritic (Latin-1 and Latin
/// Extended-A, and the comma-below letters of Romanian); `None` for any other character.
fn fold_char(c: char) -> Option<&'static str> {
    Some(match c {
        'à' | 'á' | 'â' | 'ã' | 'ä' | 'å' | 'ā' | 'ă' | 'ą' => "a",
        'æ' => "ae",
        'ç' | 'ć' | 'ĉ' | 'ċ' | 'č' => "c",
        'ď' | 'đ' | 'ð' => "d",
        'è' | 'é' | 'ê' | 'ë' | 'ē' | 'ĕ' | 'ė' | 'ę' | 'ě' => "e",
        'ĝ' | 'ğ' | 'ġ' | 'ģ' => "g",
        'ĥ' | 'ħ' => "h",
        'ì' | 'í' | 'î' | 'ï' | 'ĩ' | 'ī' | 'ĭ' | 'į' | 'ı' => "i",
        'ĵ' => "j",
        'ķ' => "k",
        'ĺ' | 'ļ' | 'ľ' | 'ŀ' | 'ł' => "l",
        'ñ' | 'ń' | 'ņ' | 'ň' => "n",
        'ò' | 'ó' | 'ô' | 'õ' | 'ö' | 'ø' | 'ō' | 'ŏ' | 'ő' => "o",
        'œ' => "oe",
        'ŕ' | 'ŗ' | 'ř' => "r",
        'ś' | 'ŝ' | 'ş' | 'š' | 'ș' => "s",
        'ß' => "ss",
        'ţ' | 'ť' | 'ŧ' | 'ț' => "t",
        'ù' | 'ú' | 'û' | 'ü' | 'ũ' | 'ū' | 'ŭ' | 'ů' | 'ű' | 'ų' => "u",
        'ŵ' => "w",
        'ý' | 'ÿ' | 'ŷ' => "y",
        'ź' | 'ż' | 'ž' => "z",
        'þ' => "th",
        _ => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input::SourcePolygon;

    /// Two countries split at lon 10 (A west, B east), a town circle in A reaching east of
    /// the split, and a country "Twin" with a town "Twin" inside it.
    const KB: &str = r#"<earth>
  <country designation="Åland">
    <polygon points="9.9 46.9, 10.0 46.9, 10.0 47.1, 9.9 47.1"/>
    <town designation="Atown"><info lat="47.0" lon="10.005" dist="0.15"/></town>
  </country>
  <country designation="Bland">
    <polygon points="10.0 46.9, 10.1 46.9, 10.1 47.1, 10.0 47.1"/>
  </country>
  <country designation="Twin">
    <polygon points="20.0 46.9, 20.1 46.9, 20.1 47.1, 20.0 47.1"/>
    <town designation="Twin"><info lat="47.0" lon="20.05" dist="1"/></town>
  </country>
</earth>"#;

    /// One kilometre of longitude at lat 47, degrees.
    const KM: f64 = 1.0 / (111.195 * 0.682);

    fn kb() -> KnowledgeBase {
        KnowledgeBase::parse_str(KB, "test").unwrap().0
    }

    fn square(id: i64, level: u8, name: &str, lo: (f64, f64), hi: (f64, f64)) -> AdminBoundary {
        AdminBoundary {
            id: SourceId::Relation(id),
            admin_level: level,
            names: vec![name.to_string()],
            iso3166_1: None,
            iso3166_2: None,
            polygons: vec![SourcePolygon {
                outer: vec![lo, (hi.0, lo.1), hi, (lo.0, hi.1)],
                holes: Vec::new(),
            }],
        }
    }

    fn path(kb: &KnowledgeBase, at: Located) -> &str {
        kb.zone_path(at.zone)
    }

    #[test]
    fn names_fold_case_diacritics_and_punctuation() {
        assert_eq!(
            fold_name("Provence-Alpes-Côte d'Azur"),
            "provence alpes cote d azur"
        );
        assert_eq!(fold_name("  ÅLAND "), "aland");
        assert_eq!(fold_name("Straße"), "strasse");
        assert_eq!(fold_name("Monaco-Ville"), fold_name("monaco ville"));
        assert_ne!(fold_name("Monaco"), fold_name("Monaco-Ville"));
    }

    /// The input's country A reaches 1 km into the KB's B: buildings there go to A, the town
    /// circle inside A still wins, B stays B beyond, and without a match nothing changes.
    #[test]
    fn an_input_boundary_moves_the_border_and_towns_still_win() {
        let kb = kb();
        let a = square(1, 2, "Aland", (9.9, 46.9), (10.0 + KM, 47.1));
        let zones = BoundaryZones::new(&kb, std::slice::from_ref(&a));
        assert_eq!(zones.matched().len(), 1);
        let at = |x: f64| kb.locate_with(&zones, x, 47.0);
        assert_eq!(path(&kb, at(10.0 + 0.8 * KM)), "earth/Åland");
        assert_eq!(at(10.0 + 0.8 * KM).boundary, Some(0));
        assert_eq!(
            kb.zone_path(kb.locate(10.0 + 0.8 * KM, 47.0)),
            "earth/Bland"
        );
        // The town's circle (150 m around 10.005) is inside A's boundary.
        assert_eq!(path(&kb, at(10.005)), "earth/Åland/Atown");
        assert_eq!(path(&kb, at(9.95)), "earth/Åland");
        // Beyond the boundary: the KB's own shapes.
        let beyond = at(10.0 + 1.5 * KM);
        assert_eq!((path(&kb, beyond), beyond.boundary), ("earth/Bland", None));
        // A boundary named like no zone matches nothing and changes nothing.
        let other = square(2, 4, "Nowhere", (9.0, 46.0), (11.0, 48.0));
        let none = BoundaryZones::new(&kb, &[other]);
        assert!(none.matched().is_empty());
        for x in [9.95, 10.0 + 0.8 * KM, 10.005, 10.05] {
            assert_eq!(kb.locate_with(&none, x, 47.0).zone, kb.locate(x, 47.0));
        }
    }

    /// The deepest matching boundary decides; a country boundary takes the country of a name
    /// shared with a town, a deeper one the town; a town of another country is not taken.
    #[test]
    fn the_deepest_boundary_and_the_plausible_zone_win() {
        let kb = kb();
        let country = square(1, 2, "Twin", (20.0, 46.9), (20.1, 47.1));
        let town = square(2, 8, "Twin", (20.04, 46.99), (20.06, 47.01));
        let zones = BoundaryZones::new(&kb, &[town.clone(), country]);
        let m: Vec<(u8, &str)> = zones
            .matched()
            .iter()
            .map(|m| (m.admin_level, kb.zone_path(m.zone)))
            .collect();
        assert_eq!(m, [(2, "earth/Twin"), (8, "earth/Twin/Twin")]);
        // Inside the town boundary but outside the town's 1 km circle: the town.
        assert_eq!(
            path(&kb, kb.locate_with(&zones, 20.059, 47.0)),
            "earth/Twin/Twin"
        );
        assert_eq!(path(&kb, kb.locate_with(&zones, 20.09, 47.0)), "earth/Twin");
        // An "Atown" boundary far from Åland: Atown's country is not where it lies.
        let stray = square(3, 8, "Atown", (20.07, 46.95), (20.09, 46.97));
        assert!(BoundaryZones::new(&kb, &[stray]).matched().is_empty());
    }

    /// A hole (an enclave) is not in the boundary.
    #[test]
    fn holes_are_outside() {
        let kb = kb();
        let mut a = square(1, 2, "Aland", (9.9, 46.9), (10.0 + KM, 47.1));
        a.polygons[0].holes = vec![vec![
            (9.94, 46.94),
            (9.94, 46.96),
            (9.96, 46.96),
            (9.96, 46.94),
        ]];
        a.polygons[0].outer.push((9.9, 46.9));
        let zones = BoundaryZones::new(&kb, &[a]);
        assert_eq!(kb.locate_with(&zones, 9.95, 46.95).boundary, None);
        assert_eq!(kb.locate_with(&zones, 9.93, 46.95).boundary, Some(0));
    }

    /// Monaco's extract: its country relation runs out to sea past the extract (dropped), its
    /// quarters are whole and four of them are towns of the shipped KB; the commune "Monaco"
    /// (level 8) keeps one islet ring and matches the country. Every building whose zone
    /// changes stays in Monaco.
    #[test]
    fn monaco_quarters_rezone_buildings_within_monaco_only() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        let mut report = crate::report::Report::default();
        let read =
            crate::input::read_osm(&root.join("data/monaco/monaco.osm.pbf"), &mut report).unwrap();
        let section = report.boundaries.clone().unwrap();
        assert!(section.incomplete.contains(&"relation/1124039".to_string()));
        let (kb, _) = KnowledgeBase::load(&root.join("knowledge_base/kb.xml")).unwrap();
        let zones = BoundaryZones::new(&kb, &read.boundaries);
        let mut matched: Vec<&str> = zones
            .matched()
            .iter()
            .map(|m| kb.zone_path(m.zone))
            .collect();
        matched.sort_unstable();
        let monaco = kb.find("earth/Mediterranean Europe/Monaco").unwrap();
        for m in zones.matched() {
            assert!(kb.is_within(m.zone, monaco), "{}", kb.zone_path(m.zone));
        }
        assert_eq!(matched.len(), 5, "{matched:?}");
        let site = crate::prepare::prepare(read.footprints, None, None, &mut report);
        let (mut changed, mut through) = (0, 0);
        for l in &site.lots {
            let (old, new) = (
                kb.locate(l.lonlat.0, l.lonlat.1),
                kb.locate_with(&zones, l.lonlat.0, l.lonlat.1),
            );
            through += usize::from(new.boundary.is_some());
            if old != new.zone {
                changed += 1;
                assert!(kb.is_within(new.zone, monaco), "{}", l.id);
            }
        }
        eprintln!(
            "Monaco: {} lots, {through} through a boundary, {changed} re-zoned",
            site.lots.len()
        );
        assert!(changed > 0 && through >= changed);
    }
}
