//! A corpus of Simple 3D Buildings cases written in code (the OSM wiki's Simple 3D Buildings
//! and Key:building:part pages are the reference): outlines with parts, a church mapped with
//! domes and towers as parts, `building=roof`, stacked parts, floating parts, parts outside
//! their outline, a relation with parts, every `roof:shape` on a part, levels and heights.
//!
//! Each case is an OSM file written with the test PBF writer near Monaco (so the shipped
//! knowledge base's zone applies), read and derived through the library as the binary does.
//! Every building's parts carry their source ids, which is how the checks find the part of
//! each tagged way. The last test measures, per tag, the share of tagged units honoured over
//! the whole corpus: it must be 100 %.

use std::collections::BTreeMap;
use std::fs::File;
use std::path::Path;

use citygen::derive::{Generator, Rules};
use citygen::grammar::Caps;
use citygen::kb::KnowledgeBase;
use citygen::model::{Building, Lod, Part, RoofShape, SourceId};
use citygen::report::Report;
use citygen::testkit::pbf_write::PbfWriter;

mod structures;

const KB: &str = "knowledge_base/kb.xml";
const LON0: f64 = 7.4200;
const LAT0: f64 = 43.7300;

type Tags = Vec<(String, String)>;
type Members = Vec<(i64, String)>;

/// An OSM data set in metres east/north of (LON0, LAT0).
#[derive(Default)]
struct Osm {
    nodes: Vec<(i64, f64, f64)>,
    ways: Vec<(i64, Vec<i64>, Tags)>,
    rels: Vec<(i64, Members, Tags)>,
}

fn owned(tags: &[(&str, &str)]) -> Vec<(String, String)> {
    tags.iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect()
}

impl Osm {
    /// A closed way on the ring (metres) with these tags.
    fn way(&mut self, id: i64, ring: &[(f64, f64)], tags: &[(&str, &str)]) {
        let m_lon = 111_320.0 * LAT0.to_radians().cos();
        let mut refs: Vec<i64> = ring
            .iter()
            .map(|&(x, y)| {
                let nid = 1 + self.nodes.len() as i64;
                self.nodes
                    .push((nid, LON0 + x / m_lon, LAT0 + y / 110_574.0));
                nid
            })
            .collect();
        refs.push(refs[0]);
        self.ways.push((id, refs, owned(tags)));
    }

    /// An open way through the points (metres) with these tags (a street).
    fn line(&mut self, id: i64, pts: &[(f64, f64)], tags: &[(&str, &str)]) {
        self.way(id, pts, tags);
        self.ways.last_mut().unwrap().1.pop();
    }

    fn relation(&mut self, id: i64, members: &[(i64, &str)], tags: &[(&str, &str)]) {
        let m = members.iter().map(|&(w, r)| (w, r.to_string())).collect();
        self.rels.push((id, m, owned(tags)));
    }

    fn write(&self, path: &Path) {
        let mut w = PbfWriter::new(File::create(path).unwrap()).unwrap();
        for &(id, lon, lat) in &self.nodes {
            w.node(id, lon, lat, &[]).unwrap();
        }
        for (id, refs, tags) in &self.ways {
            let t: Vec<(&str, &str)> = tags.iter().map(|(k, v)| (k.as_str(), v.as_str())).collect();
            w.way(*id, refs, &t).unwrap();
        }
        for (id, members, tags) in &self.rels {
            let t: Vec<(&str, &str)> = tags.iter().map(|(k, v)| (k.as_str(), v.as_str())).collect();
            let m: Vec<(citygen::testkit::pbf_write::MemberKind, i64, &str)> = members
                .iter()
                .map(|(i, r)| (citygen::testkit::pbf_write::MemberKind::Way, *i, r.as_str()))
                .collect();
            w.relation(*id, &m, &t).unwrap();
        }
        w.finish().unwrap();
    }
}

/// An axis-aligned rectangle, counter-clockwise.
fn rect(x: f64, y: f64, w: f64, h: f64) -> Vec<(f64, f64)> {
    vec![(x, y), (x + w, y), (x + w, y + h), (x, y + h)]
}

/// What a case gave: the buildings, the report, and every input element's tags by id.
struct Derived {
    buildings: Vec<Building>,
    report: Report,
    tags: BTreeMap<SourceId, Vec<(String, String)>>,
}

impl Derived {
    /// The parts derived from `id` (a building:part or an outline's own piece), over every
    /// building.
    fn parts_of(&self, id: SourceId) -> Vec<&Part> {
        self.buildings
            .iter()
            .flat_map(|b| b.parts.iter())
            .filter(|p| p.source == Some(id))
            .collect()
    }

    fn one_part(&self, id: SourceId) -> &Part {
        let p = self.parts_of(id);
        assert_eq!(p.len(), 1, "{id}: {} parts", p.len());
        p[0]
    }

    fn notes(&self, id: SourceId) -> Vec<String> {
        let id = id.to_string();
        self.report
            .entries
            .iter()
            .filter(|e| e.id == id)
            .map(|e| e.reason.clone())
            .collect()
    }
}

fn derive(osm: &Osm) -> Derived {
    let dir = tempfile::tempdir().unwrap();
    let pbf = dir.path().join("case.osm.pbf");
    osm.write(&pbf);
    let mut report = Report::default();
    let read = citygen::input::osm::read_osm(&pbf, &mut report).unwrap();
    let site = citygen::prepare::prepare(read.footprints, None, None, &mut report);
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let (kb, _) = KnowledgeBase::load(&root.join(KB)).unwrap();
    let gen = Generator::new(kb, Rules::Kb, Lod::Lod2, 0, Caps::default());
    let mut buildings = Vec::new();
    for lot in &site.lots {
        match gen.generate(lot) {
            Ok((b, notes)) => {
                for (o, n) in notes {
                    report.add(Some(lot.id), o, n);
                }
                buildings.push(b);
            }
            Err(e) => report.add(Some(lot.id), citygen::report::Outcome::Skipped, e),
        }
    }
    let mut tags = BTreeMap::new();
    for (id, _, t) in &osm.ways {
        tags.insert(SourceId::Way(*id), t.clone());
    }
    for (id, _, t) in &osm.rels {
        tags.insert(SourceId::Relation(*id), t.clone());
    }
    Derived {
        buildings,
        report,
        tags,
    }
}

fn way(i: i64) -> SourceId {
    SourceId::Way(i)
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 0.1
}

/// The plan area two parts' footprints share (m²), by sampling a 0.25 m grid.
fn shared_area(a: &Part, b: &Part) -> f64 {
    let (lo_a, hi_a) = a.footprint.bounds();
    let (lo_b, hi_b) = b.footprint.bounds();
    let lo = lo_a.max(lo_b);
    let hi = hi_a.min(hi_b);
    if lo.x >= hi.x || lo.y >= hi.y {
        return 0.0;
    }
    let step = 0.25;
    let mut n = 0;
    let mut y = lo.y + step / 2.0;
    while y < hi.y {
        let mut x = lo.x + step / 2.0;
        while x < hi.x {
            let p = glam::DVec2::new(x, y);
            if a.footprint.contains(p) && b.footprint.contains(p) {
                n += 1;
            }
            x += step;
        }
        y += step;
    }
    n as f64 * step * step
}

/// The pairs of parts of `b` that fill one volume: their plans overlap (more than 0.5 m²)
/// where their height ranges do too (a part standing on another only touches it).
fn volume_overlaps(b: &Building) -> Vec<String> {
    let mut out = Vec::new();
    for (i, p) in b.parts.iter().enumerate() {
        for q in &b.parts[i + 1..] {
            let z = p.top_z.min(q.top_z) - p.base_z.max(q.base_z);
            if z > 0.05 {
                let a = shared_area(p, q);
                if a >= 0.5 {
                    out.push(format!(
                        "{}: parts {:?} and {:?} share {a} m² over {z} m",
                        b.id, p.source, q.source
                    ));
                }
            }
        }
    }
    out
}

/// No two parts of one building fill the same volume ([`volume_overlaps`]).
fn assert_no_volume_overlap(d: &Derived) {
    let all: Vec<String> = d.buildings.iter().flat_map(volume_overlaps).collect();
    assert!(all.is_empty(), "{all:?}");
}

#[test]
fn the_wiki_example_an_outline_covered_by_two_stacked_parts() {
    let mut o = Osm::default();
    o.way(1, &rect(0.0, 0.0, 20.0, 20.0), &[("building", "yes")]);
    o.way(
        2,
        &rect(0.0, 0.0, 20.0, 20.0),
        &[
            ("building:part", "yes"),
            ("height", "10"),
            ("roof:shape", "flat"),
        ],
    );
    o.way(
        3,
        &rect(5.0, 5.0, 10.0, 10.0),
        &[
            ("building:part", "yes"),
            ("min_height", "10"),
            ("height", "15"),
            ("roof:shape", "pyramidal"),
        ],
    );
    let d = derive(&o);
    assert_eq!(d.buildings.len(), 1);
    let b = &d.buildings[0];
    assert_eq!(b.id, way(1));
    assert_eq!(b.parts.len(), 2, "the covered outline is not drawn");
    let base = d.one_part(way(2));
    assert!(close(base.base_z, 0.0) && close(base.top_z, 10.0));
    assert_eq!(base.roof_shape, RoofShape::Flat);
    let top = d.one_part(way(3));
    assert!(
        close(top.base_z, 10.0) && close(top.top_z, 15.0),
        "{}..{}",
        top.base_z,
        top.top_z
    );
    assert_eq!(top.roof_shape, RoofShape::Pyramidal);
    assert_no_volume_overlap(&d);
}

#[test]
fn a_church_with_domes_tagged_building_and_part_is_one_building() {
    // The usual mapping: the outline; the nave and domes tagged building=church +
    // building:part=yes; a tower as a part inside a dome's drum.
    let mut o = Osm::default();
    o.way(1, &rect(0.0, 0.0, 40.0, 20.0), &[("building", "church")]);
    o.way(
        2,
        &rect(0.0, 0.0, 40.0, 20.0),
        &[
            ("building", "church"),
            ("building:part", "yes"),
            ("height", "18"),
            ("roof:shape", "flat"),
        ],
    );
    o.way(
        3,
        &rect(12.0, 2.0, 16.0, 16.0),
        &[
            ("building", "church"),
            ("building:part", "yes"),
            ("min_height", "18"),
            ("height", "38"),
            ("roof:shape", "dome"),
        ],
    );
    o.way(
        4,
        &rect(1.0, 1.0, 5.0, 5.0),
        &[
            ("building:part", "tower"),
            ("min_height", "18"),
            ("height", "30"),
            ("roof:shape", "pyramidal"),
        ],
    );
    let d = derive(&o);
    assert_eq!(d.buildings.len(), 1, "the domes are parts, not buildings");
    assert_eq!(d.buildings[0].parts.len(), 3);
    let dome = d.one_part(way(3));
    assert_eq!(dome.roof_shape, RoofShape::Dome);
    assert!(close(dome.base_z, 18.0) && close(dome.top_z, 38.0));
    let tower = d.one_part(way(4));
    assert!(close(tower.base_z, 18.0) && close(tower.top_z, 30.0));
    assert_no_volume_overlap(&d);
}

#[test]
fn a_part_tagged_building_in_no_outline_holds_the_parts_inside_it() {
    let mut o = Osm::default();
    o.way(
        1,
        &rect(0.0, 0.0, 30.0, 20.0),
        &[
            ("building", "church"),
            ("building:part", "yes"),
            ("height", "15"),
            ("roof:shape", "flat"),
        ],
    );
    o.way(
        2,
        &rect(10.0, 5.0, 10.0, 10.0),
        &[
            ("building:part", "yes"),
            ("min_height", "15"),
            ("height", "27"),
            ("roof:shape", "onion"),
        ],
    );
    let d = derive(&o);
    assert_eq!(d.buildings.len(), 1);
    assert_eq!(d.buildings[0].id, way(1));
    assert!(close(d.one_part(way(1)).top_z, 15.0));
    let onion = d.one_part(way(2));
    assert_eq!(onion.roof_shape, RoofShape::Onion);
    assert!(close(onion.base_z, 15.0) && close(onion.top_z, 27.0));
    assert!(d.notes(way(2)).is_empty(), "{:?}", d.notes(way(2)));
}

#[test]
fn building_roof_is_a_roof_on_pillars_not_a_house() {
    let mut o = Osm::default();
    o.way(
        1,
        &rect(0.0, 0.0, 20.0, 10.0),
        &[("building", "roof"), ("min_height", "16"), ("height", "18")],
    );
    o.way(2, &rect(40.0, 0.0, 12.0, 8.0), &[("building", "roof")]);
    o.way(
        3,
        &rect(80.0, 0.0, 12.0, 8.0),
        &[
            ("building", "roof"),
            ("height", "5"),
            ("roof:shape", "gabled"),
            ("roof:height", "1.5"),
        ],
    );
    let d = derive(&o);
    let high = d.one_part(way(1));
    assert!(
        close(high.base_z, 16.0) && close(high.top_z, 18.0),
        "{}..{}",
        high.base_z,
        high.top_z
    );
    assert_eq!(high.roof_shape, RoofShape::Flat);
    assert_eq!(high.storeys, 1);
    // No heights: a canopy of one storey's height, a slab under its top.
    let canopy = d.one_part(way(2));
    assert!(canopy.top_z - canopy.base_z <= 0.5 + 1e-9 && canopy.base_z > 1.0);
    assert_eq!(canopy.roof_shape, RoofShape::Flat);
    let gabled = d.one_part(way(3));
    assert_eq!(gabled.roof_shape, RoofShape::Gabled);
    assert!(close(gabled.top_z, 5.0) && close(gabled.top_z - gabled.eave_z, 1.5));
    // A roof on pillars floats by nature: no note says so.
    assert!(d.notes(way(1)).iter().all(|n| !n.contains("floating")));
}

#[test]
fn a_part_under_another_has_a_flat_top_and_only_the_top_takes_the_zones_roof() {
    let mut o = Osm::default();
    o.way(1, &rect(0.0, 0.0, 16.0, 12.0), &[("building", "yes")]);
    o.way(
        2,
        &rect(0.0, 0.0, 16.0, 12.0),
        &[("building:part", "yes"), ("height", "10")],
    );
    o.way(
        3,
        &rect(0.0, 0.0, 16.0, 12.0),
        &[
            ("building:part", "yes"),
            ("min_height", "10"),
            ("height", "20"),
        ],
    );
    let d = derive(&o);
    let lower = d.one_part(way(2));
    assert_eq!(
        lower.roof_shape,
        RoofShape::Flat,
        "a roof would run up through the part above"
    );
    assert!(close(lower.top_z, 10.0));
    let upper = d.one_part(way(3));
    assert!(close(upper.base_z, 10.0) && close(upper.top_z, 20.0));
    assert_no_volume_overlap(&d);
}

#[test]
fn a_building_whose_parts_all_start_above_the_ground_gets_a_note() {
    let mut o = Osm::default();
    o.way(1, &rect(0.0, 0.0, 10.0, 10.0), &[("building", "yes")]);
    o.way(
        2,
        &rect(0.0, 0.0, 10.0, 10.0),
        &[
            ("building:part", "yes"),
            ("building:min_level", "1"),
            ("building:levels", "3"),
        ],
    );
    let d = derive(&o);
    let p = d.one_part(way(2));
    assert!(p.base_z > 2.0);
    assert!(
        d.notes(way(1)).iter().any(|n| n.contains("floating")),
        "{:?}",
        d.notes(way(1))
    );
}

#[test]
fn a_part_outside_every_outline_is_a_building_with_a_note() {
    let mut o = Osm::default();
    o.way(1, &rect(0.0, 0.0, 10.0, 10.0), &[("building", "yes")]);
    o.way(
        2,
        &rect(30.0, 0.0, 8.0, 8.0),
        &[("building:part", "yes"), ("height", "6")],
    );
    let d = derive(&o);
    assert_eq!(d.buildings.len(), 2);
    assert!(close(d.one_part(way(2)).top_z, 6.0));
    assert!(d
        .notes(way(2))
        .iter()
        .any(|n| n.contains("lies in no building outline")));
}

#[test]
fn a_relation_outline_holds_its_parts_and_its_uncovered_rest_is_drawn() {
    let mut o = Osm::default();
    // A courtyard building as a multipolygon; a tall part on its west wing only.
    o.way(10, &rect(0.0, 0.0, 30.0, 30.0), &[]);
    o.way(11, &rect(10.0, 10.0, 10.0, 10.0), &[]);
    o.relation(
        1,
        &[(10, "outer"), (11, "inner")],
        &[
            ("type", "multipolygon"),
            ("building", "yes"),
            ("height", "9"),
            ("roof:shape", "flat"),
        ],
    );
    o.way(
        2,
        &rect(0.0, 0.0, 10.0, 30.0),
        &[
            ("building:part", "yes"),
            ("height", "21"),
            ("roof:shape", "flat"),
        ],
    );
    let d = derive(&o);
    assert_eq!(d.buildings.len(), 1);
    let b = &d.buildings[0];
    assert_eq!(b.id, SourceId::Relation(1));
    assert!(close(d.one_part(way(2)).top_z, 21.0));
    // The rest of the outline (900 − 100 − 300 = 500 m² as drawn in metres; the projection
    // makes it a little more) with the outline's own height.
    let rest = d.parts_of(SourceId::Relation(1));
    let area: f64 = rest.iter().map(|p| p.footprint.area()).sum();
    let wing = d.one_part(way(2)).footprint.area();
    assert!(
        (area / wing - 5.0 / 3.0).abs() < 0.01,
        "rest {area} m², wing {wing} m²"
    );
    assert!(rest.iter().all(|p| close(p.top_z, 9.0)));
    assert_no_volume_overlap(&d);
}

#[test]
fn every_roof_shape_on_a_part_is_drawn_as_tagged() {
    let shapes = [
        ("flat", RoofShape::Flat),
        ("skillion", RoofShape::Skillion),
        ("gabled", RoofShape::Gabled),
        ("hipped", RoofShape::Hipped),
        ("half-hipped", RoofShape::HalfHipped),
        ("side_hipped", RoofShape::SideHipped),
        ("pyramidal", RoofShape::Pyramidal),
        ("mansard", RoofShape::Mansard),
        ("gambrel", RoofShape::Gambrel),
        ("saltbox", RoofShape::Saltbox),
        ("dome", RoofShape::Dome),
        ("onion", RoofShape::Onion),
        ("round", RoofShape::Round),
        ("cone", RoofShape::Cone),
        ("gabled_height_moved", RoofShape::GabledHeightMoved),
        ("side_half-hipped", RoofShape::SideHalfHipped),
        ("hipped-and-gabled", RoofShape::HippedAndGabled),
        ("bellcast_gable", RoofShape::BellcastGable),
        ("crosspitched", RoofShape::Crosspitched),
        ("sawtooth", RoofShape::Sawtooth),
        ("butterfly", RoofShape::Butterfly),
        ("apse_gabled", RoofShape::ApseGabled),
    ];
    let mut o = Osm::default();
    for (i, (tag, _)) in shapes.iter().enumerate() {
        let x = 40.0 * i as f64;
        let id = 100 + 2 * i as i64;
        o.way(id, &rect(x, 0.0, 14.0, 10.0), &[("building", "yes")]);
        o.way(
            id + 1,
            &rect(x, 0.0, 14.0, 10.0),
            &[
                ("building:part", "yes"),
                ("height", "12"),
                ("roof:height", "4"),
                ("roof:shape", tag),
            ],
        );
    }
    let d = derive(&o);
    for (i, (tag, shape)) in shapes.iter().enumerate() {
        let p = d.one_part(way(101 + 2 * i as i64));
        assert_eq!(p.roof_shape, *shape, "roof:shape={tag}");
        assert!(close(p.top_z, 12.0), "roof:shape={tag}: top {}", p.top_z);
        if *shape != RoofShape::Flat {
            assert!(
                close(p.top_z - p.eave_z, 4.0),
                "roof:shape={tag}: roof {}",
                p.top_z - p.eave_z
            );
        }
    }
}

#[test]
fn levels_win_over_the_zones_storey_height_and_fractions_are_kept() {
    let mut o = Osm::default();
    o.way(
        1,
        &rect(0.0, 0.0, 20.0, 20.0),
        &[
            ("building", "yes"),
            ("height", "70"),
            ("building:levels", "13"),
            ("roof:shape", "flat"),
        ],
    );
    o.way(
        2,
        &rect(40.0, 0.0, 12.0, 10.0),
        &[
            ("building", "yes"),
            ("building:levels", "3.5"),
            ("roof:shape", "flat"),
        ],
    );
    let d = derive(&o);
    let tower = d.one_part(way(1));
    assert_eq!(tower.storeys, 13);
    assert!(close(tower.top_z, 70.0));
    let half = d.one_part(way(2));
    let b = d.buildings.iter().find(|b| b.id == way(2)).unwrap();
    assert_eq!(
        b.storeys_above_ground, 4,
        "3.5 levels: three and a half storey"
    );
    // The walls are 3.5 storeys of the zone's height, not 3.
    let storey = tower.top_z / 13.0;
    assert!(
        half.eave_z > 3.2 * 2.5 && storey > 5.0,
        "{} {}",
        half.eave_z,
        storey
    );
}

#[test]
fn a_guessed_roof_is_no_taller_than_its_walls() {
    // A deep footprint with a zone roof and no roof tags: the pitch alone over 40 m would be
    // a roof higher than the two storeys under it.
    let mut o = Osm::default();
    o.way(
        1,
        &rect(0.0, 0.0, 60.0, 40.0),
        &[
            ("building", "yes"),
            ("building:levels", "2"),
            ("roof:shape", "hipped"),
        ],
    );
    let d = derive(&o);
    let p = d.one_part(way(1));
    let walls = p.eave_z - p.base_z;
    assert!(
        p.top_z - p.eave_z <= walls + 1e-6,
        "roof {} on walls {walls}",
        p.top_z - p.eave_z
    );
    assert_eq!(p.roof_shape, RoofShape::Hipped);
}

/// Per tag, the share of tagged units (building:part, or outline drawn itself) whose derived
/// part honours it, over every case above built again in one file: 100 % each.
#[test]
fn every_tag_of_the_corpus_is_honoured() {
    let mut o = Osm::default();
    let cases: [&[(&str, &str)]; 8] = [
        &[
            ("height", "12"),
            ("roof:shape", "gabled"),
            ("roof:height", "3"),
        ],
        &[("height", "9"), ("min_height", "3"), ("roof:shape", "flat")],
        &[
            ("building:levels", "4"),
            ("roof:shape", "hipped"),
            ("building:colour", "#aa3311"),
        ],
        &[
            ("height", "20"),
            ("building:levels", "5"),
            ("roof:colour", "#102030"),
        ],
        &[
            ("min_height", "6"),
            ("height", "16"),
            ("roof:shape", "dome"),
        ],
        &[
            ("building:levels", "2.5"),
            ("roof:shape", "skillion"),
            ("roof:height", "2"),
        ],
        &[("height", "30"), ("roof:shape", "pyramidal")],
        &[
            ("height", "7"),
            ("roof:shape", "mansard"),
            ("roof:height", "2.5"),
        ],
    ];
    for (i, tags) in cases.iter().enumerate() {
        let x = 50.0 * i as f64;
        let id = 10 * (i as i64 + 1);
        o.way(id, &rect(x, 0.0, 24.0, 14.0), &[("building", "yes")]);
        let mut t = vec![("building:part", "yes")];
        t.extend_from_slice(tags);
        o.way(id + 1, &rect(x, 0.0, 12.0, 14.0), &t);
        let mut t = vec![("building", "yes")];
        t.extend_from_slice(tags);
        o.way(id + 2, &rect(x, 30.0, 12.0, 14.0), &t);
    }
    let d = derive(&o);
    let mut honoured: BTreeMap<&str, (usize, usize)> = BTreeMap::new();
    for (id, tags) in &d.tags {
        let get = |k: &str| tags.iter().find(|(kk, _)| kk == k).map(|(_, v)| v.as_str());
        let parts = d.parts_of(*id);
        if parts.is_empty() {
            continue;
        }
        let mut count = |key: &'static str, ok: bool| {
            let e = honoured.entry(key).or_default();
            e.1 += 1;
            if ok {
                e.0 += 1;
            }
        };
        let top = parts
            .iter()
            .map(|p| p.top_z)
            .fold(f64::NEG_INFINITY, f64::max);
        let base = parts.iter().map(|p| p.base_z).fold(f64::INFINITY, f64::min);
        if let Some(h) = get("height") {
            count("height", close(top, h.parse().unwrap()));
        }
        if let Some(m) = get("min_height") {
            count("min_height", close(base, m.parse().unwrap()));
        }
        if let Some(r) = get("roof:shape") {
            let want = RoofShape::parse(r).unwrap();
            count("roof:shape", parts.iter().all(|p| p.roof_shape == want));
        }
        if let Some(l) = get("building:levels") {
            let l: f64 = l.parse().unwrap();
            count(
                "building:levels",
                parts.iter().all(|p| p.storeys == l.round() as u32),
            );
        }
        if let Some(c) = get("building:colour") {
            let want = citygen::color::Color::parse(c).unwrap();
            count(
                "building:colour",
                parts.iter().all(|p| p.wall_color == want),
            );
        }
        if let Some(c) = get("roof:colour") {
            let want = citygen::color::Color::parse(c).unwrap();
            count("roof:colour", parts.iter().all(|p| p.roof_color == want));
        }
    }
    let mut lines = Vec::new();
    for (k, (ok, n)) in &honoured {
        lines.push(format!("{k}: {ok} of {n}"));
    }
    eprintln!("honoured per tag: {}", lines.join(", "));
    assert!(honoured.len() >= 6, "{lines:?}");
    for (k, (ok, n)) in &honoured {
        assert_eq!(ok, n, "{k} honoured on {ok} of {n} units: {lines:?}");
    }
    assert_no_volume_overlap(&d);
}

#[test]
fn a_roof_with_levels_stands_that_many_storeys_high() {
    let mut o = Osm::default();
    o.way(
        1,
        &rect(0.0, 0.0, 10.0, 10.0),
        &[("building", "roof"), ("building:levels", "2")],
    );
    let d = derive(&o);
    let p = d.one_part(way(1));
    assert!(
        p.top_z > 5.0 && p.top_z < 8.0 && p.top_z - p.base_z <= 0.5 + 1e-9,
        "{}..{}",
        p.base_z,
        p.top_z
    );
}

/// Every way and multipolygon relation of the Monaco sample tagged `building` or
/// `building:part` (other than `no`), counted by a plain osmpbf pass, is written (as a
/// building or as a part's source id) or has a report entry.
#[test]
fn every_building_and_part_of_monaco_is_written_or_reported() {
    use osmpbf::{Element, ElementReader};
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let pbf = root.join("data/monaco/monaco.osm.pbf");
    let mut tagged = std::collections::BTreeSet::new();
    let is_building = |tags: &[(&str, &str)]| {
        tags.iter()
            .any(|(k, v)| (*k == "building" || *k == "building:part") && *v != "no")
    };
    ElementReader::from_path(&pbf)
        .unwrap()
        .for_each(|e| match e {
            Element::Way(w) => {
                let t: Vec<_> = w.tags().collect();
                if is_building(&t) {
                    tagged.insert(SourceId::Way(w.id()));
                }
            }
            Element::Relation(r) => {
                let t: Vec<_> = r.tags().collect();
                if t.contains(&("type", "multipolygon")) && is_building(&t) {
                    tagged.insert(SourceId::Relation(r.id()));
                }
            }
            _ => {}
        })
        .unwrap();
    let mut report = Report::default();
    let read = citygen::input::osm::read_osm(&pbf, &mut report).unwrap();
    let site = citygen::prepare::prepare(read.footprints, None, None, &mut report);
    let (kb, _) = KnowledgeBase::load(&root.join(KB)).unwrap();
    let gen = Generator::new(kb, Rules::Kb, Lod::Lod1, 0, Caps::default());
    let mut written = std::collections::BTreeSet::new();
    for lot in &site.lots {
        match gen.generate(lot) {
            Ok((b, _)) => {
                written.insert(b.id);
                written.extend(b.parts.iter().filter_map(|p| p.source));
            }
            Err(e) => report.add(Some(lot.id), citygen::report::Outcome::Skipped, e),
        }
    }
    let reported: std::collections::BTreeSet<String> =
        report.entries.iter().map(|e| e.id.clone()).collect();
    let lost: Vec<String> = tagged
        .iter()
        .filter(|id| !written.contains(id) && !reported.contains(&id.to_string()))
        .map(|id| id.to_string())
        .collect();
    assert!(tagged.len() > 1100, "{} tagged", tagged.len());
    assert!(
        lost.is_empty(),
        "{} of {} lost: {lost:?}",
        lost.len(),
        tagged.len()
    );
    // Drawn, not merely reported (issue 45: at least 99 % of the tagged elements).
    let drawn = tagged.iter().filter(|id| written.contains(id)).count();
    let undrawn: Vec<String> = tagged
        .iter()
        .filter(|id| !written.contains(id))
        .take(20)
        .map(|id| id.to_string())
        .collect();
    assert!(
        drawn as f64 >= 0.99 * tagged.len() as f64,
        "{drawn} of {} drawn; not drawn: {undrawn:?}",
        tagged.len()
    );
}

/// Every building's vertical extent, with its parts, is the same in the glTF as in the
/// CityJSON, whose heights the tests above check against the tags (issue 45: parts' heights
/// right in every format; 3D Tiles contents are written by the same glTF writer).
#[test]
fn every_buildings_height_is_the_same_in_gltf_and_cityjson() {
    let dir = tempfile::tempdir().unwrap();
    let glb = dir.path().join("m.glb");
    let cj = dir.path().join("m.city.json");
    let out = crate::common::citygen(&[
        "--osm",
        "data/monaco/monaco.osm.pbf",
        "--kb",
        KB,
        "--lod",
        "2",
        "--gltf",
        &glb.display().to_string(),
        "--cityjson",
        &cj.display().to_string(),
        "--quiet",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let doc: serde_json::Value = serde_json::from_slice(&std::fs::read(&cj).unwrap()).unwrap();
    let (scale, shift) = (
        doc["transform"]["scale"][2].as_f64().unwrap(),
        doc["transform"]["translate"][2].as_f64().unwrap(),
    );
    let z: Vec<f64> = doc["vertices"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v[2].as_f64().unwrap() * scale + shift)
        .collect();
    fn indices(v: &serde_json::Value, out: &mut Vec<usize>) {
        match v {
            serde_json::Value::Number(n) => out.push(n.as_u64().unwrap() as usize),
            serde_json::Value::Array(a) => a.iter().for_each(|x| indices(x, out)),
            _ => {}
        }
    }
    let objects = doc["CityObjects"].as_object().unwrap();
    let mut cityjson: BTreeMap<String, (f64, f64)> = BTreeMap::new();
    for o in objects.values().filter(|o| o["type"] == "Building") {
        let mut idx = Vec::new();
        let children = o["children"].as_array().cloned().unwrap_or_default();
        for part in
            std::iter::once(o).chain(children.iter().filter_map(|c| objects.get(c.as_str()?)))
        {
            for g in part["geometry"].as_array().into_iter().flatten() {
                indices(&g["boundaries"], &mut idx);
            }
        }
        if idx.is_empty() {
            continue;
        }
        let lo = idx.iter().map(|i| z[*i]).fold(f64::MAX, f64::min);
        let hi = idx.iter().map(|i| z[*i]).fold(f64::MIN, f64::max);
        let id = o["attributes"]["sourceId"].as_str().unwrap().to_string();
        cityjson.insert(id, (lo, hi));
    }
    let (g, _) = crate::common::glb_json(&glb);
    let mut compared = 0;
    let mut differ = Vec::new();
    for node in g["nodes"].as_array().unwrap() {
        let (Some(id), Some(children)) =
            (node["extras"]["id"].as_str(), node["children"].as_array())
        else {
            continue;
        };
        let (mut lo, mut hi) = (f64::MAX, f64::MIN);
        for c in children {
            let child = &g["nodes"][c.as_u64().unwrap() as usize];
            assert!(child.get("translation").is_none() && child.get("matrix").is_none());
            let Some(mesh) = child["mesh"].as_u64() else {
                continue;
            };
            for p in g["meshes"][mesh as usize]["primitives"].as_array().unwrap() {
                let a = &g["accessors"][p["attributes"]["POSITION"].as_u64().unwrap() as usize];
                // glTF is y-up.
                lo = lo.min(a["min"][1].as_f64().unwrap());
                hi = hi.max(a["max"][1].as_f64().unwrap());
            }
        }
        let Some(&(clo, chi)) = cityjson.get(id) else {
            continue;
        };
        compared += 1;
        if ((hi - lo) - (chi - clo)).abs() > 0.01 {
            differ.push(format!(
                "{id}: glTF {:.3} m, CityJSON {:.3} m",
                hi - lo,
                chi - clo
            ));
        }
    }
    assert!(compared > 1100, "{compared} buildings compared");
    assert!(
        differ.is_empty(),
        "{} differ: {:?}",
        differ.len(),
        &differ[..differ.len().min(10)]
    );
}

/// Per tag, the share of tagged units of both samples honoured at LOD2 (a unit is a
/// `building:part`, or an outline drawn itself): at least 99.5 % each; and no two parts of a
/// building share a volume.
#[test]
fn the_tags_of_both_samples_are_honoured() {
    for sample in [
        "data/monaco/monaco.osm.pbf",
        "data/clifton/clifton_test.shp",
    ] {
        tags_honoured(sample);
    }
}

fn tags_honoured(sample: &str) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let path = root.join(sample);
    let mut report = Report::default();
    let read = if sample.ends_with(".shp") {
        let o = citygen::input::shp::ShpOptions::default();
        citygen::input::shp::read_shp(&path, &o, &mut report).unwrap()
    } else {
        citygen::input::osm::read_osm(&path, &mut report).unwrap()
    };
    let site = citygen::prepare::prepare(read.footprints, read.source_crs, None, &mut report);
    let (kb, _) = KnowledgeBase::load(&root.join(KB)).unwrap();
    let gen = Generator::new(kb, Rules::Kb, Lod::Lod2, 0, Caps::default());
    let mut honoured: BTreeMap<&str, (usize, usize, Vec<String>)> = BTreeMap::new();
    let mut overlaps = Vec::new();
    for lot in &site.lots {
        let Ok((b, _)) = gen.generate(lot) else {
            continue;
        };
        overlaps.extend(volume_overlaps(&b));
        let mut units: Vec<(SourceId, &citygen::input::BuildingTags)> = Vec::new();
        if !lot.drawn_outline().is_empty() {
            units.push((lot.id, &lot.tags));
        }
        units.extend(lot.parts.iter().map(|p| (p.id, &*p.tags)));
        for (id, t) in units {
            let parts: Vec<&Part> = b.parts.iter().filter(|p| p.source == Some(id)).collect();
            if parts.is_empty() {
                continue;
            }
            let mut count = |key: &'static str, ok: bool| {
                let e = honoured.entry(key).or_default();
                e.1 += 1;
                if ok {
                    e.0 += 1;
                } else if e.2.len() < 5 {
                    e.2.push(id.to_string());
                }
            };
            let top = parts
                .iter()
                .map(|p| p.top_z)
                .fold(f64::NEG_INFINITY, f64::max);
            let base = parts.iter().map(|p| p.base_z).fold(f64::INFINITY, f64::min);
            if let Some(h) = t.height {
                count("height", close(top, h));
            }
            if let Some(m) = t.min_height {
                count("min_height", close(base, m));
            }
            if let Some(r) = t.roof_shape {
                count("roof:shape", parts.iter().all(|p| p.roof_shape == r));
            }
            // A roof on pillars has no storeys: its levels say how high it stands. A part drawn
            // in bands (a smaller part stands in it over some of its heights) shares its
            // storeys among them: summed over its bands.
            if let (Some(l), false) = (t.levels, t.is_roof()) {
                let want = (l - t.min_level.unwrap_or(0.0)).round().max(1.0) as u32;
                let mut bands: BTreeMap<(i64, i64), u32> = BTreeMap::new();
                for p in &parts {
                    let band = (
                        (p.base_z * 1e3).round() as i64,
                        (p.eave_z * 1e3).round() as i64,
                    );
                    bands.insert(band, p.storeys);
                }
                count("building:levels", bands.values().sum::<u32>() == want);
            }
            if let Some(c) = t.colour {
                count("building:colour", parts.iter().all(|p| p.wall_color == c));
            }
            if let Some(c) = t.roof_colour {
                count("roof:colour", parts.iter().all(|p| p.roof_color == c));
            }
        }
    }
    let lines: Vec<String> = honoured
        .iter()
        .map(|(k, (ok, n, bad))| {
            format!(
                "{k}: {ok} of {n} ({:.1} %) e.g. {bad:?}",
                100.0 * *ok as f64 / *n as f64
            )
        })
        .collect();
    eprintln!("{sample}:\n{}", lines.join("\n"));
    assert!(!honoured.is_empty(), "{sample}: no tag");
    assert!(
        overlaps.is_empty(),
        "{sample}: parts sharing a volume: {overlaps:?}"
    );
    for (k, (ok, n, _)) in &honoured {
        assert!(*ok as f64 >= 0.995 * *n as f64, "{sample}: {k}: {lines:?}");
    }
}

#[test]
fn a_tower_mapped_inside_the_part_around_it_is_cut_out_of_it() {
    // Both from the ground: the base (20 m) and a round-ish tower (60 m) inside it, and a
    // second part that duplicates the tower's plan and heights.
    let mut o = Osm::default();
    o.way(
        1,
        &rect(0.0, 0.0, 40.0, 30.0),
        &[
            ("building", "yes"),
            ("building:part", "yes"),
            ("height", "20"),
            ("roof:shape", "flat"),
        ],
    );
    o.way(
        2,
        &rect(10.0, 10.0, 10.0, 10.0),
        &[
            ("building:part", "yes"),
            ("height", "60"),
            ("roof:shape", "flat"),
        ],
    );
    o.way(
        3,
        &rect(10.0, 10.0, 10.0, 10.0),
        &[
            ("building:part", "yes"),
            ("height", "60"),
            ("roof:shape", "flat"),
        ],
    );
    let d = derive(&o);
    assert_eq!(d.buildings.len(), 1);
    assert_no_volume_overlap(&d);
    let base: f64 = d.parts_of(way(1)).iter().map(|p| p.footprint.area()).sum();
    let tower = d.one_part(way(3));
    assert!(
        (base / tower.footprint.area() - 11.0).abs() < 0.05,
        "base {base} m²"
    );
    assert!(close(tower.top_z, 60.0));
    // The duplicate is drawn once, with a note on the one left out.
    assert!(d.parts_of(way(2)).is_empty());
    assert!(
        d.notes(way(1))
            .iter()
            .any(|n| n.contains("way/2 lies inside")),
        "{:?}",
        d.notes(way(1))
    );
}

/// A regular 16-gon of `area` m² (as drawn in metres) around (x, y), counter-clockwise.
fn disc(x: f64, y: f64, area: f64) -> Vec<(f64, f64)> {
    let n = 16.0_f64;
    let r = (2.0 * area / (n * (std::f64::consts::TAU / n).sin())).sqrt();
    (0..16)
        .map(|k| {
            let a = std::f64::consts::TAU * f64::from(k) / n;
            (x + r * a.cos(), y + r * a.sin())
        })
        .collect()
}

/// What the binary wrote for a case (issue 45): CityJSON, CityGML, IFC, glTF and the report,
/// at LOD2, in a temporary folder.
struct Written {
    dir: tempfile::TempDir,
    city: serde_json::Value,
    report: serde_json::Value,
}

impl Written {
    fn run(osm: &Osm) -> Written {
        let dir = tempfile::tempdir().unwrap();
        let p = |n: &str| dir.path().join(n).display().to_string();
        osm.write(&dir.path().join("case.osm.pbf"));
        let out = crate::common::citygen(&[
            "--osm",
            &p("case.osm.pbf"),
            "--kb",
            KB,
            "--lod",
            "2",
            "--cityjson",
            &p("out.city.json"),
            "--citygml",
            &p("out.gml"),
            "--ifc",
            &p("out.ifc"),
            "--gltf",
            &p("out.glb"),
            "--report",
            &p("report.json"),
            "--quiet",
        ]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let read = |n: &str| serde_json::from_slice(&std::fs::read(dir.path().join(n)).unwrap());
        Written {
            city: read("out.city.json").unwrap(),
            report: read("report.json").unwrap(),
            dir,
        }
    }

    /// The CityJSON objects traced to `id`: the parts whose `sourceId` it is, and a building of
    /// one part whose `partSourceId` it is.
    fn objects_of(&self, id: SourceId) -> Vec<&serde_json::Value> {
        let id = id.to_string();
        self.city["CityObjects"]
            .as_object()
            .unwrap()
            .values()
            .filter(|o| {
                let a = &o["attributes"];
                if o["type"] == "BuildingPart" {
                    a["sourceId"] == id.as_str()
                } else {
                    a["partSourceId"] == id.as_str()
                }
            })
            .collect()
    }

    /// The `measuredHeight` of the one CityJSON part traced to `id`.
    fn height_of(&self, id: SourceId) -> f64 {
        let o = self.objects_of(id);
        assert_eq!(o.len(), 1, "{id}: {o:?}");
        o[0]["attributes"]["measuredHeight"].as_f64().unwrap()
    }

    /// The report's reasons for `id`.
    fn notes(&self, id: SourceId) -> Vec<String> {
        let id = id.to_string();
        self.report["entries"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|e| e["id"] == id.as_str())
            .map(|e| e["reason"].as_str().unwrap().to_string())
            .collect()
    }

    /// The IFC's `Citygen_Part` property sets: per set, its properties' names and values as
    /// written.
    fn ifc_part_psets(&self) -> Vec<BTreeMap<String, String>> {
        let e = crate::common::step_entities(&self.dir.path().join("out.ifc"));
        e.values()
            .filter(|(k, a)| k == "IFCPROPERTYSET" && a.contains("'Citygen_Part'"))
            .map(|(_, a)| {
                crate::common::step_refs(a)
                    .into_iter()
                    .map(|r| {
                        let args = &e[&r].1;
                        let name = args.split('\'').nth(1).unwrap().to_string();
                        let value = args[args.find('(').unwrap() + 1..args.rfind(')').unwrap()]
                            .trim_matches('\'')
                            .to_string();
                        (name, value)
                    })
                    .collect()
            })
            .collect()
    }

    /// Runs the reference validators (IFC with the geometry kernel) on the outputs; `false`
    /// when they are not installed (outside CI).
    fn validate(&self, what: &str) -> bool {
        let Some(tool) = citygen::testkit::validators::validate_outputs(what) else {
            return false;
        };
        let files =
            ["out.ifc", "out.gml", "out.glb", "out.city.json"].map(|f| self.dir.path().join(f));
        let res = std::process::Command::new(tool)
            .arg("--geometry")
            .args(files)
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&res.stdout);
        assert!(
            res.status.success() && text.contains("4 passed, 0 failed"),
            "{what}: {text}{}",
            String::from_utf8_lossy(&res.stderr)
        );
        true
    }
}

/// Issue 45: a monument of many small tagged parts, a plinth, a column, two gilded rings
/// around the column standing out a few centimetres, and 12 drums of 0.5 down to 0.02 m²
/// stacked from 24 to 48 m: every part is drawn, in every format, with its heights.
#[test]
fn a_monument_of_small_parts_draws_every_part() {
    let mut o = Osm::default();
    o.way(
        1,
        &rect(0.0, 0.0, 10.0, 10.0),
        &[("building", "yes"), ("historic", "monument")],
    );
    o.way(
        2,
        &rect(0.0, 0.0, 10.0, 10.0),
        &[
            ("building:part", "yes"),
            ("height", "4"),
            ("roof:shape", "flat"),
        ],
    );
    o.way(
        3,
        &disc(5.0, 5.0, 1.0),
        &[
            ("building:part", "column"),
            ("min_height", "4"),
            ("height", "24"),
            ("roof:shape", "flat"),
        ],
    );
    // Rings around the column: 1.3 m² discs over 1 m each, 8 cm proud of it.
    for (id, z) in [(4, 10), (5, 16)] {
        let (lo, hi) = (z.to_string(), (z + 1).to_string());
        o.way(
            id,
            &disc(5.0, 5.0, 1.3),
            &[
                ("building:part", "yes"),
                ("min_height", &lo),
                ("height", &hi),
                ("roof:shape", "flat"),
                ("building:colour", "gold"),
            ],
        );
    }
    // The drums: 0.5 m² at 24 m down to 0.02 m² at 46-48 m.
    let drums: Vec<(i64, f64, f64)> = (0..12)
        .map(|k| {
            let area = 0.5 * (0.04f64).powf(f64::from(k) / 11.0);
            (10 + i64::from(k), area, 24.0 + 2.0 * f64::from(k))
        })
        .collect();
    for &(id, area, z) in &drums {
        let (lo, hi) = (z.to_string(), (z + 2.0).to_string());
        o.way(
            id,
            &disc(5.0, 5.0, area),
            &[
                ("building:part", "yes"),
                ("min_height", &lo),
                ("height", &hi),
                ("roof:shape", "flat"),
            ],
        );
    }
    let d = derive(&o);
    assert_eq!(d.buildings.len(), 1);
    for &(id, area, z) in &drums {
        let p = d.one_part(way(id));
        assert!(close(p.base_z, z) && close(p.top_z, z + 2.0), "{id}");
        assert!(
            (p.footprint.area() / area - 1.0).abs() < 0.05,
            "{id}: {}",
            p.footprint.area()
        );
        assert!(d.notes(way(id)).is_empty(), "{id}: {:?}", d.notes(way(id)));
    }
    // The rings keep what stands out of the column; the column stays whole.
    for id in [4, 5] {
        let p = d.one_part(way(id));
        assert!(
            (p.footprint.area() - 0.3).abs() < 0.03,
            "{}",
            p.footprint.area()
        );
    }
    assert!((d.one_part(way(3)).footprint.area() - 1.0).abs() < 0.05);
    assert!(d
        .report
        .entries
        .iter()
        .all(|e| !e.reason.contains("degenerate")));
    assert_no_volume_overlap(&d);

    // As written: a CityJSON part per tagged part, its measuredHeight its top above the
    // ground; an IFC partial building per part with its numbers.
    let w = Written::run(&o);
    for &(id, _, z) in &drums {
        assert!((w.height_of(way(id)) - (z + 2.0)).abs() < 0.1, "{id}");
        assert!(w.notes(way(id)).is_empty(), "{id}: {:?}", w.notes(way(id)));
    }
    assert!((w.height_of(way(4)) - 11.0).abs() < 0.1);
    assert!((w.height_of(way(3)) - 24.0).abs() < 0.1);
    let psets = w.ifc_part_psets();
    assert_eq!(psets.len(), 16, "{psets:?}");
    let top_drum = psets
        .iter()
        .find(|p| p.get("SourceId").map(String::as_str) == Some("way/21"))
        .expect("the top drum in the IFC");
    assert_eq!(top_drum["RoofShape"], "flat");
    assert_eq!(top_drum["NumberOfStoreys"], "1");
    assert!(
        (top_drum["Height"].parse::<f64>().unwrap() - 48.0).abs() < 0.1,
        "{top_drum:?}"
    );
    assert!(
        (top_drum["MinHeight"].parse::<f64>().unwrap() - 46.0).abs() < 0.1,
        "{top_drum:?}"
    );
    w.validate("a monument of small parts");
}

/// Issue 45: a colonnade of 16 columns (0-6 m) under a deck (6-7 m), and a pillar with a
/// band part inside its plan over 1 m of its 6: every column is drawn (the deck fills none of
/// their heights), and the pillar is drawn around the band where the band stands and whole
/// elsewhere.
#[test]
fn a_colonnade_under_a_deck_draws_every_column() {
    let mut o = Osm::default();
    o.way(1, &rect(0.0, 0.0, 40.0, 10.0), &[("building", "yes")]);
    o.way(
        2,
        &rect(0.0, 0.0, 40.0, 10.0),
        &[
            ("building:part", "yes"),
            ("min_height", "6"),
            ("height", "7"),
            ("roof:shape", "flat"),
        ],
    );
    let columns: Vec<i64> = (0..16).map(|k| 10 + k).collect();
    for (k, &id) in columns.iter().enumerate() {
        let (x, y) = (2.5 + 5.0 * (k % 8) as f64, if k < 8 { 1.5 } else { 8.5 });
        o.way(
            id,
            &disc(x, y, 0.4),
            &[
                ("building:part", "column"),
                ("height", "6"),
                ("roof:shape", "flat"),
            ],
        );
    }
    // A pillar apart, with a band part inside its plan from 2 to 3 m.
    o.way(40, &rect(60.0, 0.0, 4.0, 4.0), &[("building", "yes")]);
    o.way(
        41,
        &rect(61.0, 1.0, 1.0, 1.0),
        &[
            ("building:part", "yes"),
            ("height", "6"),
            ("roof:shape", "flat"),
        ],
    );
    o.way(
        42,
        &rect(61.1, 1.1, 0.8, 0.8),
        &[
            ("building:part", "yes"),
            ("min_height", "2"),
            ("height", "3"),
            ("roof:shape", "flat"),
        ],
    );
    let d = derive(&o);
    for &id in &columns {
        let p = d.one_part(way(id));
        assert!(close(p.base_z, 0.0) && close(p.top_z, 6.0), "{id}");
        assert!((p.footprint.area() - 0.4).abs() < 0.02, "{id}");
        assert!(d.notes(way(id)).is_empty(), "{id}: {:?}", d.notes(way(id)));
    }
    let deck = d.one_part(way(2));
    assert!(close(deck.base_z, 6.0) && close(deck.top_z, 7.0));
    // The pillar: whole below 2 m and above 3 m, a frame around the band between.
    let mut pillar: Vec<(f64, f64, f64)> = d
        .parts_of(way(41))
        .iter()
        .map(|p| (p.base_z, p.top_z, p.footprint.area()))
        .collect();
    pillar.sort_by(|a, b| a.0.total_cmp(&b.0));
    assert_eq!(pillar.len(), 3, "{pillar:?}");
    assert!(close(pillar[0].1, 2.0) && close(pillar[1].1, 3.0) && close(pillar[2].1, 6.0));
    assert!((pillar[0].2 - 1.0).abs() < 0.02 && (pillar[2].2 - 1.0).abs() < 0.02);
    assert!((pillar[1].2 - 0.36).abs() < 0.02, "{pillar:?}");
    assert!(d.notes(way(41)).is_empty() && d.notes(way(40)).iter().all(|n| !n.contains("inside")));
    assert!(close(d.one_part(way(42)).top_z, 3.0));
    assert_no_volume_overlap(&d);

    let w = Written::run(&o);
    for &id in &columns {
        assert!((w.height_of(way(id)) - 6.0).abs() < 0.1, "{id}");
    }
    // The deck: its top above the ground, not its thickness.
    assert!((w.height_of(way(2)) - 7.0).abs() < 0.1);
    assert_eq!(w.objects_of(way(41)).len(), 3);
    w.validate("a colonnade under a deck");
}

/// Issue 45: a church whose nave part leaves the porch of its outline uncovered: the porch is
/// drawn with the outline's own tags (height, colour, roof), traced to the outline with the
/// role `outline-rest` in every format; and where the outline has no height, the rest is
/// what the outline's tags alone give, never the estimator's height for the whole church.
#[test]
fn a_churchs_uncovered_rest_takes_the_outlines_own_tags_and_is_traced() {
    let mut o = Osm::default();
    let church = |o: &mut Osm, x: f64, id: i64, outline: &[(&str, &str)]| {
        o.way(id, &rect(x, 0.0, 30.0, 12.0), outline);
        o.way(
            id + 1,
            &rect(x + 6.0, 0.0, 24.0, 12.0),
            &[
                ("building:part", "yes"),
                ("height", "18"),
                ("roof:shape", "gabled"),
                ("building:material", "brick"),
                ("building:colour", "#8b3a3a"),
            ],
        );
    };
    church(
        &mut o,
        0.0,
        1,
        &[
            ("building", "church"),
            ("height", "5"),
            ("roof:shape", "flat"),
            ("building:colour", "#8b3a3a"),
        ],
    );
    church(&mut o, 60.0, 11, &[("building", "church")]);
    let d = derive(&o);
    let rest = d.one_part(way(1));
    assert!(close(rest.top_z, 5.0), "{}", rest.top_z);
    assert_eq!(rest.roof_shape, RoofShape::Flat);
    assert_eq!(
        rest.wall_color,
        citygen::color::Color::parse("#8b3a3a").unwrap()
    );
    assert_eq!(rest.role, citygen::model::PartRole::OutlineRest);
    assert_eq!(d.one_part(way(2)).role, citygen::model::PartRole::Own);
    // The untagged outline's rest as its own tags alone give it (no estimator here).
    let bare = d.one_part(way(11)).top_z;

    let w = Written::run(&o);
    for (id, top) in [(1, 5.0), (11, bare)] {
        let o = w.objects_of(way(id));
        let rests: Vec<_> = o.iter().filter(|o| o["type"] == "BuildingPart").collect();
        assert_eq!(rests.len(), 1, "{id}: {o:?}");
        let a = &rests[0]["attributes"];
        assert_eq!(a["sourceRole"], "outline-rest", "{a}");
        assert!(
            (a["measuredHeight"].as_f64().unwrap() - top).abs() < 0.1,
            "{id}: {a}"
        );
    }
    let gml = std::fs::read_to_string(w.dir.path().join("out.gml")).unwrap();
    assert_eq!(
        gml.matches(">outline-rest<").count(),
        2,
        "CityGML sourceRole"
    );
    let rests: Vec<_> = w
        .ifc_part_psets()
        .into_iter()
        .filter(|p| p.get("SourceRole").map(String::as_str) == Some("outline-rest"))
        .collect();
    assert_eq!(rests.len(), 2, "{rests:?}");
    assert_eq!(rests[0]["SourceId"], "way/1");
    assert!((rests[0]["Height"].parse::<f64>().unwrap() - 5.0).abs() < 0.1);
    let (glb, _) = crate::common::glb_json(&w.dir.path().join("out.glb"));
    let roles = glb["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|n| n["extras"]["parts"].as_array())
        .flatten()
        .filter(|p| p["role"] == "outline-rest")
        .count();
    assert_eq!(roles, 2, "glTF extras.parts role");
}

/// The 22 documented roof shapes, one building each in a row 30 m apart (a church with an
/// apse for `apse_gabled`), 12 m high with a 4 m roof: (roof:shape, way id, CityGML code).
fn roof_catalogue() -> (Osm, Vec<(&'static str, i64, &'static str)>) {
    let shapes = [
        ("flat", "1000"),
        ("skillion", "1010"),
        ("gabled", "1030"),
        ("gabled_height_moved", "1030"),
        ("saltbox", "1030"),
        ("hipped", "1040"),
        ("half-hipped", "1050"),
        ("side_hipped", "1040"),
        ("side_half-hipped", "1050"),
        ("hipped-and-gabled", "1050"),
        ("mansard", "1060"),
        ("gambrel", "1060"),
        ("bellcast_gable", "1030"),
        ("pyramidal", "1070"),
        ("crosspitched", "1130"),
        ("sawtooth", "1100"),
        ("butterfly", "1020"),
        ("cone", "1080"),
        ("dome", "1090"),
        ("onion", "1090"),
        ("round", "1110"),
        ("apse_gabled", "1030"),
    ];
    let mut o = Osm::default();
    let mut out = Vec::new();
    for (i, (tag, code)) in shapes.iter().enumerate() {
        let x = 30.0 * i as f64;
        let id = 500 + i as i64;
        let ring = if *tag == "apse_gabled" {
            // A 16 × 10 m nave and a semicircular apse of eight sides at its east end.
            let mut r = vec![(x, 0.0), (x + 16.0, 0.0)];
            for k in 1..8 {
                let a = -std::f64::consts::FRAC_PI_2 + k as f64 / 8.0 * std::f64::consts::PI;
                r.push((x + 16.0 + 5.0 * a.cos(), 5.0 + 5.0 * a.sin()));
            }
            r.extend([(x + 16.0, 10.0), (x, 10.0)]);
            r
        } else if ["dome", "onion", "cone", "pyramidal"].contains(tag) {
            rect(x, 0.0, 14.0, 14.0)
        } else {
            rect(x, 0.0, 20.0, 12.0)
        };
        let roof_height = if *tag == "flat" { "0" } else { "4" };
        o.way(
            id,
            &ring,
            &[
                ("building", "yes"),
                ("height", "12"),
                ("roof:height", roof_height),
                ("roof:shape", tag),
            ],
        );
        out.push((*tag, id, *code));
    }
    (o, out)
}

#[test]
fn every_documented_roof_shape_is_written_with_its_type_as_a_valid_solid() {
    // Run through the binary: CityGML and CityJSON carry each building's roof type, and every
    // solid passes the ISO 19107 checks of `iso19107`.
    let (o, cases) = roof_catalogue();
    let dir = tempfile::tempdir().unwrap();
    let pbf = dir.path().join("roofs.osm.pbf");
    o.write(&pbf);
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let (gml, json) = (
        dir.path().join("roofs.gml"),
        dir.path().join("roofs.city.json"),
    );
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_citygen"))
        .arg("--osm")
        .arg(&pbf)
        .arg("--kb")
        .arg(root.join(KB))
        .args(["--lod", "2", "--quiet", "--citygml"])
        .arg(&gml)
        .arg("--cityjson")
        .arg(&json)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&gml).unwrap();
    let cj: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let objects = cj["CityObjects"].as_object().unwrap();
    for (tag, id, code) in &cases {
        // The building's element in CityGML, up to the next building.
        let at = text
            .find(&format!(">way/{id}<"))
            .unwrap_or_else(|| panic!("roof:shape={tag}: way/{id} not written"));
        let rest = &text[at..];
        let end = rest[1..]
            .find("<bldg:Building ")
            .map_or(rest.len(), |e| e + 1);
        let roof_type = format!(">{code}</bldg:roofType>");
        assert!(
            rest[..end].contains(&roof_type),
            "roof:shape={tag}: no {roof_type}"
        );
        let obj = objects
            .iter()
            .find(|(_, v)| v["attributes"]["sourceId"].as_str() == Some(&format!("way/{id}")))
            .unwrap_or_else(|| panic!("roof:shape={tag}: way/{id} not in CityJSON"));
        assert_eq!(
            obj.1["attributes"]["roofType"].as_str(),
            Some(*code),
            "roof:shape={tag}"
        );
    }
    let (n, defects) = crate::iso19107::file_defects(&gml);
    assert!(n >= cases.len(), "{n} solids");
    assert!(defects.is_empty(), "{defects:#?}");
}
