//! OSM change files: parsing ([`read_osc`]) and applying them while reading a PBF
//! ([`read_osm_with_changes`]), checked against a PBF written with the changes applied.

use super::*;
use crate::testkit::pbf_write::{MemberKind, PbfWriter};
use osmpbf::{Element, ElementReader};
use std::collections::{BTreeMap, BTreeSet};
use std::io::Write;

fn monaco() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data/monaco/monaco.osm.pbf")
}

type RawTags = Vec<(String, String)>;
type RawRelation = (Vec<(MemberKind, i64, String)>, RawTags);

/// An OSM dataset in memory: coordinates in 1e-7 degrees (lon, lat).
#[derive(Clone, Default)]
struct Data {
    nodes: BTreeMap<i64, (i64, i64)>,
    ways: BTreeMap<i64, (Vec<i64>, RawTags)>,
    rels: BTreeMap<i64, RawRelation>,
}

fn tags(pairs: &[(&str, &str)]) -> RawTags {
    pairs
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect()
}

impl Data {
    fn from_pbf(path: &Path) -> Data {
        let mut d = Data::default();
        let mut odd = 0;
        let mut node = |d: &mut Data, id: i64, lon: i64, lat: i64| {
            if lon % 100 != 0 || lat % 100 != 0 {
                odd += 1;
            }
            d.nodes.insert(id, (lon / 100, lat / 100));
        };
        ElementReader::from_path(path)
            .unwrap()
            .for_each(|e| match e {
                Element::Node(n) => node(&mut d, n.id(), n.nano_lon(), n.nano_lat()),
                Element::DenseNode(n) => node(&mut d, n.id(), n.nano_lon(), n.nano_lat()),
                Element::Way(w) => {
                    d.ways.insert(
                        w.id(),
                        (
                            w.refs().collect(),
                            w.tags()
                                .map(|(k, v)| (k.to_string(), v.to_string()))
                                .collect(),
                        ),
                    );
                }
                Element::Relation(r) => {
                    let members = r
                        .members()
                        .map(|m| {
                            let kind = match m.member_type {
                                RelMemberType::Node => MemberKind::Node,
                                RelMemberType::Way => MemberKind::Way,
                                RelMemberType::Relation => MemberKind::Relation,
                            };
                            (kind, m.member_id, m.role().unwrap().to_string())
                        })
                        .collect();
                    d.rels.insert(
                        r.id(),
                        (
                            members,
                            r.tags()
                                .map(|(k, v)| (k.to_string(), v.to_string()))
                                .collect(),
                        ),
                    );
                }
            })
            .unwrap();
        assert_eq!(odd, 0, "the sample's coordinates are whole 1e-7 degrees");
        d
    }

    /// Writes the dataset as a PBF (nodes, ways, relations in id order).
    fn write_pbf(&self, path: &Path) {
        let mut w = PbfWriter::new(Vec::new()).unwrap();
        for (&id, &(lon, lat)) in &self.nodes {
            w.node(id, lon as f64 * 1e-7, lat as f64 * 1e-7, &[])
                .unwrap();
        }
        for (&id, (nds, t)) in &self.ways {
            let t: Vec<(&str, &str)> = t.iter().map(|(k, v)| (k.as_str(), v.as_str())).collect();
            w.way(id, nds, &t).unwrap();
        }
        for (&id, (members, t)) in &self.rels {
            let t: Vec<(&str, &str)> = t.iter().map(|(k, v)| (k.as_str(), v.as_str())).collect();
            let m: Vec<(MemberKind, i64, &str)> = members
                .iter()
                .map(|(k, i, r)| (*k, *i, r.as_str()))
                .collect();
            w.relation(id, &m, &t).unwrap();
        }
        std::fs::write(path, w.finish().unwrap()).unwrap();
    }
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
        .replace('\'', "&apos;")
        .replace('\n', "&#10;")
        .replace('\t', "&#9;")
}

/// 1e-7 degrees as a decimal (`-43.7312345`), as osmium writes them.
fn deg(x: i64) -> String {
    let sign = if x < 0 { "-" } else { "" };
    let a = x.unsigned_abs();
    format!("{sign}{}.{:07}", a / 10_000_000, a % 10_000_000)
}

fn node_xml(id: i64, (lon, lat): (i64, i64)) -> String {
    format!(
        "    <node id=\"{id}\" version=\"2\" timestamp=\"2024-01-02T00:00:00Z\" lat=\"{}\" lon=\"{}\"/>\n",
        deg(lat),
        deg(lon)
    )
}

fn tags_xml(t: &RawTags) -> String {
    t.iter()
        .map(|(k, v)| format!("      <tag k=\"{}\" v=\"{}\"/>\n", esc(k), esc(v)))
        .collect()
}

fn way_xml(id: i64, (nds, t): &(Vec<i64>, RawTags)) -> String {
    let mut s = format!("    <way id=\"{id}\" version=\"2\">\n");
    for r in nds {
        s += &format!("      <nd ref=\"{r}\"/>\n");
    }
    s += &tags_xml(t);
    s + "    </way>\n"
}

fn rel_xml(id: i64, (members, t): &RawRelation) -> String {
    let mut s = format!("    <relation id=\"{id}\" version=\"2\">\n");
    for (k, r, role) in members {
        let k = match k {
            MemberKind::Node => "node",
            MemberKind::Way => "way",
            MemberKind::Relation => "relation",
        };
        s += &format!(
            "      <member type=\"{k}\" ref=\"{r}\" role=\"{}\"/>\n",
            esc(role)
        );
    }
    s += &tags_xml(t);
    s + "    </relation>\n"
}

/// The osmChange from `a` to `b`, in several blocks of each action, with decoys the last
/// occurrence overrides (an element deleted, then created again; a way first given other tags).
fn diff_osc(a: &Data, b: &Data) -> String {
    let mut create = String::new();
    let mut modify = String::new();
    let mut delete = String::new();
    let mut decoys = String::new();
    for (&id, &p) in &b.nodes {
        match a.nodes.get(&id) {
            None => create += &node_xml(id, p),
            Some(&q) if q != p => {
                decoys += &node_xml(id, (p.0 + 1000, p.1 - 1000));
                modify += &node_xml(id, p);
            }
            _ => {}
        }
    }
    for (&id, w) in &b.ways {
        match a.ways.get(&id) {
            None => create += &way_xml(id, w),
            Some(v) if v != w => {
                decoys += &way_xml(id, &(w.0.clone(), tags(&[("building", "decoy")])));
                modify += &way_xml(id, w);
            }
            _ => {}
        }
    }
    for (&id, r) in &b.rels {
        match a.rels.get(&id) {
            None => create += &rel_xml(id, r),
            Some(v) if v != r => modify += &rel_xml(id, r),
            _ => {}
        }
    }
    // Deletions as osmium writes them: no coordinates, node refs or tags.
    for id in a.rels.keys().filter(|i| !b.rels.contains_key(i)) {
        delete += &format!("    <relation id=\"{id}\" version=\"3\"/>\n");
    }
    for id in a.ways.keys().filter(|i| !b.ways.contains_key(i)) {
        delete += &format!("    <way id=\"{id}\" version=\"3\" visible=\"false\"></way>\n");
    }
    for id in a.nodes.keys().filter(|i| !b.nodes.contains_key(i)) {
        delete += &format!("    <node id=\"{id}\" version=\"3\"/>\n");
    }
    // The decoys are undone by the later blocks: a decoy node is deleted (created ones) or
    // modified (moved ones) again below; a decoy way is modified again.
    let mut decoy_deletes = String::new();
    for (&id, _) in b.nodes.iter().filter(|(i, _)| !a.nodes.contains_key(i)) {
        decoy_deletes += &format!("    <node id=\"{id}\" version=\"1\"/>\n");
    }
    format!(
        "<?xml version='1.0' encoding='UTF-8'?>\n<osmChange version=\"0.6\" generator=\"citygen test\">\n  <modify>\n{decoys_mod}  </modify>\n  <delete>\n{decoy_deletes}  </delete>\n  <create/>\n  <create>\n{create}  </create>\n  <modify>\n{modify}  </modify>\n  <delete>\n{delete}  </delete>\n</osmChange>\n",
        decoys_mod = decoys,
    )
}

fn gzip(bytes: &[u8]) -> Vec<u8> {
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    e.write_all(bytes).unwrap();
    e.finish().unwrap()
}

/// Footprints (ids, kinds, tags, rings bit for bit), streets and report of two reads are equal.
fn assert_same(got: &ReadResult, got_report: &Report, want: &ReadResult, want_report: &Report) {
    let ids = |r: &ReadResult| r.footprints.iter().map(|f| f.id).collect::<Vec<_>>();
    assert_eq!(ids(got), ids(want));
    for (g, w) in got.footprints.iter().zip(&want.footprints) {
        assert_eq!(g.kind, w.kind, "{}", g.id);
        assert_eq!(*g.tags, *w.tags, "{}", g.id);
        let bits = |f: &Footprint| -> Vec<Vec<Vec<(u64, u64)>>> {
            f.polygons
                .iter()
                .map(|p| {
                    std::iter::once(&p.outer)
                        .chain(&p.holes)
                        .map(|r| r.iter().map(|(x, y)| (x.to_bits(), y.to_bits())).collect())
                        .collect()
                })
                .collect()
        };
        assert_eq!(bits(g), bits(w), "{}", g.id);
    }
    let street_bits = |s: &crate::input::Streets| -> (Vec<(u64, u64)>, Vec<u32>) {
        (
            s.points
                .iter()
                .map(|(x, y)| (x.to_bits(), y.to_bits()))
                .collect(),
            s.ends.clone(),
        )
    };
    assert_eq!(street_bits(&got.streets), street_bits(&want.streets));
    let entries = |r: &Report| -> Vec<(String, Outcome, String)> {
        r.entries
            .iter()
            .map(|e| (e.id.clone(), e.outcome, e.reason.clone()))
            .collect()
    };
    assert_eq!(entries(got_report), entries(want_report));
    assert_eq!(
        (
            got_report.read,
            got_report.parts_read,
            got_report.skipped,
            got_report.repaired
        ),
        (
            want_report.read,
            want_report.parts_read,
            want_report.skipped,
            want_report.repaired
        )
    );
}

fn read(path: &Path, osc: Option<&Path>) -> (ReadResult, Report) {
    let mut report = Report::default();
    let r = read_osm_with_changes(path, osc, &mut report).unwrap();
    (r, report)
}

/// Reads `day1` + the change from it to `day2` (plain and gzipped) and `day2` alone: the same.
/// Returns day 2's read.
fn check_equivalent(dir: &Path, day1_pbf: &Path, day1: &Data, day2: &Data) -> ReadResult {
    let day2_pbf = dir.join("day2.osm.pbf");
    day2.write_pbf(&day2_pbf);
    let xml = diff_osc(day1, day2);
    let plain = dir.join("changes.osc");
    std::fs::write(&plain, &xml).unwrap();
    // Gzip is found by its magic bytes, whatever the name.
    let gz = dir.join("changes.xml");
    std::fs::write(&gz, gzip(xml.as_bytes())).unwrap();
    let (want, want_report) = read(&day2_pbf, None);
    for osc in [&plain, &gz] {
        let (got, got_report) = read(day1_pbf, Some(osc));
        assert_same(&got, &got_report, &want, &want_report);
    }
    want
}

fn fp(r: &ReadResult, id: SourceId) -> Option<&Footprint> {
    r.footprints.iter().find(|f| f.id == id)
}

/// On the Monaco sample: a building way's tags modified, a node of a building moved, a building
/// deleted, one created with new nodes, a multipolygon building relation's tags modified, a
/// street node moved. The change read with the PBF gives what the edited PBF gives.
#[test]
fn monaco_with_a_change_reads_as_the_changed_extract() {
    let day1 = Data::from_pbf(&monaco());
    let dir = tempfile::tempdir().unwrap();
    // The dataset written again reads as the sample does.
    let day1_pbf = dir.path().join("day1.osm.pbf");
    day1.write_pbf(&day1_pbf);
    let (base, base_report) = read(&monaco(), None);
    let (again, again_report) = read(&day1_pbf, None);
    assert_same(&again, &again_report, &base, &base_report);

    // Node uses over all ways (a closed way's last node counted once) and relation members.
    let mut uses: BTreeMap<i64, usize> = BTreeMap::new();
    for (nds, _) in day1.ways.values() {
        let distinct: BTreeSet<i64> = nds.iter().copied().collect();
        for n in distinct {
            *uses.entry(n).or_default() += 1;
        }
    }
    let rel_ways: BTreeSet<i64> = day1
        .rels
        .values()
        .flat_map(|(m, _)| m.iter().map(|x| x.1))
        .collect();
    let building_ways: Vec<i64> = base
        .footprints
        .iter()
        .filter_map(|f| match f.id {
            SourceId::Way(w) if f.kind == FootprintKind::Building && !rel_ways.contains(&w) => {
                Some(w)
            }
            _ => None,
        })
        .collect();
    let retag = building_ways[0];
    let (moved_way, moved_node) = building_ways[1..]
        .iter()
        .find_map(|w| {
            let n = day1.ways[w].0[1];
            (uses[&n] == 1).then_some((*w, n))
        })
        .expect("a building with a node of its own");
    let deleted = *building_ways
        .iter()
        .rev()
        .find(|w| **w != retag && **w != moved_way)
        .unwrap();
    let relation = base
        .footprints
        .iter()
        .find_map(|f| match f.id {
            SourceId::Relation(r) if f.kind == FootprintKind::Building => Some(r),
            _ => None,
        })
        .expect("a building relation");
    // A residential street's node of its own (a dead end).
    let street_node = day1
        .ways
        .values()
        .filter(|(_, t)| t.iter().any(|(k, v)| k == "highway" && v == "residential"))
        .find_map(|(nds, _)| nds.iter().copied().find(|n| uses[n] == 1))
        .expect("a residential street's own node");

    let mut day2 = day1.clone();
    // (a) a building way's tags
    day2.ways
        .get_mut(&retag)
        .unwrap()
        .1
        .push(("building:levels".into(), "9".into()));
    // (b) a node of a building moved by about 2 m
    let old = day2.nodes[&moved_node];
    let new = (old.0 + 200, old.1 + 150);
    day2.nodes.insert(moved_node, new);
    // (c) a building deleted (its nodes stay, as when a way alone is deleted)
    day2.ways.remove(&deleted);
    // (d) a building created with new nodes
    let next = day1.nodes.keys().last().unwrap() + 1;
    let square = [(0, 0), (3000, 0), (3000, 2000), (0, 2000)];
    let origin = (74_400_000, 437_450_000);
    for (k, (dx, dy)) in square.iter().enumerate() {
        day2.nodes
            .insert(next + k as i64, (origin.0 + dx, origin.1 + dy));
    }
    let created = day1.ways.keys().last().unwrap() + 1;
    day2.ways.insert(
        created,
        (
            vec![next, next + 1, next + 2, next + 3, next],
            tags(&[("building", "house"), ("roof:shape", "gabled")]),
        ),
    );
    // (e) a multipolygon building relation's tags
    day2.rels
        .get_mut(&relation)
        .unwrap()
        .1
        .push(("building:levels".into(), "9".into()));
    // A street's node moved.
    let p = day2.nodes[&street_node];
    day2.nodes.insert(street_node, (p.0 - 100, p.1 + 100));

    let got = check_equivalent(dir.path(), &monaco(), &day1, &day2);

    // And each edit is what the footprints show.
    let levels = |id| fp(&got, id).and_then(|f| f.tags.levels);
    assert_eq!(levels(SourceId::Way(retag)), Some(9.0));
    assert_eq!(levels(SourceId::Relation(relation)), Some(9.0));
    assert_ne!(
        fp(&base, SourceId::Relation(relation)).unwrap().tags.levels,
        Some(9.0)
    );
    let ring = |r: &ReadResult| {
        fp(r, SourceId::Way(moved_way)).unwrap().polygons[0]
            .outer
            .clone()
    };
    let at = |(x, y): (i64, i64)| (x as f64 * 1e-7, y as f64 * 1e-7);
    let near = |ring: &Ring, p: (f64, f64)| {
        ring.iter()
            .any(|q| (q.0 - p.0).abs() < 1e-9 && (q.1 - p.1).abs() < 1e-9)
    };
    assert!(near(&ring(&base), at(old)) && !near(&ring(&base), at(new)));
    assert!(near(&ring(&got), at(new)) && !near(&ring(&got), at(old)));
    assert!(fp(&base, SourceId::Way(deleted)).is_some());
    assert!(fp(&got, SourceId::Way(deleted)).is_none());
    let c = fp(&got, SourceId::Way(created)).expect("the created building");
    assert_eq!(c.polygons[0].outer.len(), 4);
    assert_eq!(c.tags.building.as_deref(), Some("house"));
    assert_eq!(got.footprints.len(), base.footprints.len());
    assert_ne!(got.streets, base.streets);
}

/// A small synthetic day 1 and day 2 (relations deleted, created and turned into buildings,
/// ways retagged into parts and out of buildings, a node deleted under a building, streets
/// moved and created): day 1 + the change reads as day 2, footprints and report alike.
#[test]
fn synthetic_day1_plus_change_reads_as_day2() {
    let mut d = Data::default();
    // Node id 1000 * i + k: corner k of square i, squares 30 m apart on a row.
    let square = |d: &mut Data, i: i64, size: i64| -> Vec<i64> {
        let (x, y) = (74_200_000 + i * 3000, 437_300_000);
        let c = [(0, 0), (size, 0), (size, size), (0, size)];
        let ids: Vec<i64> = (0..4).map(|k| 1000 * i + k).collect();
        for (k, (dx, dy)) in c.iter().enumerate() {
            d.nodes.insert(ids[k], (x + dx, y + dy));
        }
        let mut r = ids.clone();
        r.push(ids[0]);
        r
    };
    for i in 1..=6 {
        let r = square(&mut d, i, 1000);
        d.ways.insert(i, (r, tags(&[("building", "yes")])));
    }
    // A courtyard: outer way 7, inner way 8 (square 8 moved inside 7), relation 100.
    let outer = square(&mut d, 7, 2000);
    let inner = square(&mut d, 8, 400);
    for id in &inner[..4] {
        let p = d.nodes[id];
        d.nodes.insert(*id, (p.0 - 3000 + 800, p.1 + 800));
    }
    d.ways.insert(7, (outer, vec![]));
    d.ways.insert(8, (inner, vec![]));
    d.rels.insert(
        100,
        (
            vec![
                (MemberKind::Way, 7, "outer".into()),
                (MemberKind::Way, 8, "inner".into()),
            ],
            tags(&[("type", "multipolygon"), ("building", "yes")]),
        ),
    );
    // A street.
    d.nodes.insert(9001, (74_200_000, 437_299_000));
    d.nodes.insert(9002, (74_230_000, 437_299_000));
    d.ways
        .insert(50, (vec![9001, 9002], tags(&[("highway", "residential")])));
    let dir = tempfile::tempdir().unwrap();
    let day1_pbf = dir.path().join("day1.osm.pbf");
    d.write_pbf(&day1_pbf);

    let mut e = d.clone();
    // Way 1 becomes a part, way 2 no longer a building, way 3 loses a node (then a way with a
    // missing node: skipped), way 4 deleted with its nodes.
    e.ways.get_mut(&1).unwrap().1 = tags(&[("building:part", "yes"), ("height", "12")]);
    e.ways.get_mut(&2).unwrap().1 = tags(&[("amenity", "parking")]);
    e.nodes.remove(&3002);
    e.ways.remove(&4);
    for k in 0..4 {
        e.nodes.remove(&(4000 + k));
    }
    // Way 5's nodes reordered (closed on another corner) and a tag value with markup.
    e.ways.get_mut(&5).unwrap().0 = vec![5001, 5002, 5003, 5000, 5001];
    e.ways.get_mut(&5).unwrap().1 = tags(&[("building", "yes"), ("name", "Café \"<&>\"")]);
    // Relation 100 deleted: its ways are plain ways again; relation 101 made of way 6 as
    // outer and a new inner way 60; way 6 stays a building way (built by the relation).
    e.rels.remove(&100);
    let hole = [(300, 300), (600, 300), (600, 600), (300, 600)];
    let base6 = d.nodes[&6000];
    for (k, (dx, dy)) in hole.iter().enumerate() {
        e.nodes
            .insert(60_000 + k as i64, (base6.0 + dx, base6.1 + dy));
    }
    e.ways
        .insert(60, (vec![60_000, 60_001, 60_002, 60_003, 60_000], vec![]));
    e.rels.insert(
        101,
        (
            vec![
                (MemberKind::Way, 6, "outer".into()),
                (MemberKind::Way, 60, "inner".into()),
                (MemberKind::Node, 6000, "label".into()),
            ],
            tags(&[("type", "multipolygon"), ("building", "office")]),
        ),
    );
    // The street moved and a second one created on old and new nodes.
    e.nodes.insert(9002, (74_231_000, 437_298_000));
    e.nodes.insert(9003, (74_231_000, 437_310_000));
    e.ways
        .insert(51, (vec![9002, 9003], tags(&[("highway", "footway")])));

    let got = check_equivalent(dir.path(), &day1_pbf, &d, &e);
    let ids: Vec<String> = got.footprints.iter().map(|f| f.id.to_string()).collect();
    assert_eq!(
        ids,
        ["way/1", "way/5", "relation/101"],
        "way/3 skipped, way/6 built by relation/101 (report entries), way/7 untagged"
    );
    assert_eq!(got.streets.len(), 2);
}

/// The last occurrence of an element in file order wins; deletions need only ids; blocks of
/// each action in any order.
#[test]
fn the_last_occurrence_wins() {
    let xml = r#"<?xml version="1.0"?>
<osmChange version="0.6">
  <delete><node id="1"/><way id="2"/></delete>
  <create>
    <node id="1" lat="43.5" lon="7.25"><tag k="a" v="b"/></node>
    <way id="2"><nd ref="1"/><nd ref="3"/><tag k="building" v="yes"/></way>
    <relation id="4"><member type="way" ref="2" role="outer"/><tag k="type" v="multipolygon"/></relation>
  </create>
  <modify><node id="1" lat="-43.0000001" lon="-7.123456789"/></modify>
  <delete><relation id="4" version="2"/><node id="5" lat="1" lon="1"><tag k="x" v="y"/></node></delete>
</osmChange>
"#;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("c.osc");
    std::fs::write(&path, xml).unwrap();
    let c = read_osc(&path).unwrap();
    assert_eq!(
        c.nodes,
        BTreeMap::from([
            (
                1,
                Some((1e-9 * -7_123_456_789f64, 1e-9 * -43_000_000_100f64))
            ),
            (5, None)
        ])
    );
    assert_eq!(
        c.ways,
        BTreeMap::from([(2, Some((vec![1, 3], tags(&[("building", "yes")]))))])
    );
    assert_eq!(c.relations, BTreeMap::from([(4, None)]));
}

#[test]
fn decimal_coordinates_are_exact_nanodegrees() {
    for (s, n) in [
        ("43.7312345", 43_731_234_500),
        ("-7.0000001", -7_000_000_100),
        ("0", 0),
        ("+.5", 500_000_000),
        ("180", 180_000_000_000),
        ("1.0000000005", 1_000_000_001),
        ("1.00000000049", 1_000_000_000),
        ("4.3e1", 43_000_000_000),
    ] {
        assert_eq!(osc::nanodegrees(s), Some(n), "{s}");
    }
    for s in [
        "",
        "-",
        ".",
        "abc",
        "1.2.3",
        "NaN",
        "inf",
        "1e400",
        "9999999999999",
    ] {
        assert_eq!(osc::nanodegrees(s), None, "{s}");
    }
}

fn osc_err(name: &str, bytes: &[u8]) -> String {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    std::fs::write(&path, bytes).unwrap();
    let e = read_osc(&path).expect_err("an error").to_string();
    assert!(e.contains(name), "{e}");
    e
}

const VALID: &str = r#"<osmChange version="0.6">
 <create>
  <node id="7" lat="43.7" lon="7.4"/>
  <way id="8"><nd ref="7"/><tag k="building" v="yes"/></way>
  <relation id="9"><member type="way" ref="8" role=""/></relation>
 </create>
</osmChange>
"#;

#[test]
fn malformed_files_are_errors_naming_the_file_line_and_element() {
    let cases: &[(&str, &str, &[&str])] = &[
        (
            "mismatch.osc",
            "<osmChange>\n<create>\n<node id=\"1\" lat=\"1\" lon=\"1\">\n</way>\n</create></osmChange>",
            &["line 4"],
        ),
        (
            "lat.osc",
            "<osmChange>\n<modify>\n<node id=\"12\" lat=\"91.5\" lon=\"7\"/>\n</modify></osmChange>",
            &["line 3", "node/12", "lat 91.5"],
        ),
        (
            "lon.osc",
            "<osmChange><create>\n<node id=\"3\" lat=\"1\" lon=\"-180.0000001\"/></create></osmChange>",
            &["line 2", "node/3", "lon"],
        ),
        (
            "nolat.osc",
            "<osmChange><create><node id=\"3\" lon=\"1\"/></create></osmChange>",
            &["node/3", "no lat"],
        ),
        (
            "id.osc",
            "<osmChange>\n<create><way id=\"x1\"/></create></osmChange>",
            &["line 2", "way", "'x1'"],
        ),
        (
            "ref.osc",
            "<osmChange><create><way id=\"5\">\n<nd ref=\"1.5\"/></way></create></osmChange>",
            &["line 2", "way/5", "'1.5'"],
        ),
        (
            "member.osc",
            "<osmChange><create><relation id=\"6\"><member type=\"area\" ref=\"1\"/></relation></create></osmChange>",
            &["relation/6", "'area'"],
        ),
        (
            "tag.osc",
            "<osmChange><modify><way id=\"5\"><tag k=\"a\"/></way></modify></osmChange>",
            &["way/5", "<tag>"],
        ),
        ("root.osc", "<osm version=\"0.6\"></osm>", &["<osm>"]),
        ("outside.osc", "<osmChange><node id=\"1\"/></osmChange>", &["<node>"]),
        ("empty.osc", "", &["no <osmChange>"]),
        (
            "truncated.osc",
            "<osmChange><create><node id=\"1\" lat=\"1\" lon=\"1\"/>",
            &["not closed"],
        ),
        ("binary.osc", "\u{0}\u{1}", &[]),
    ];
    for (name, xml, want) in cases {
        let e = osc_err(name, xml.as_bytes());
        for w in *want {
            assert!(e.contains(w), "{name}: {e:?} lacks {w:?}");
        }
    }
    let e = osc_err(
        "latin1.osc",
        b"<osmChange>\n<create>\xe9</create></osmChange>",
    );
    assert!(e.contains("UTF-8") && e.contains("line 2"), "{e}");
    // The whole read names the change file too.
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.osc");
    std::fs::write(
        &bad,
        "<osmChange><create><node id=\"1\" lat=\"100\" lon=\"0\"/></create></osmChange>",
    )
    .unwrap();
    let e = read_osm_with_changes(&monaco(), Some(&bad), &mut Report::default())
        .expect_err("bad lat")
        .to_string();
    assert!(e.contains("bad.osc") && e.contains("node/1"), "{e}");
    let missing = dir.path().join("missing.osc.gz");
    let e = read_osm_with_changes(&monaco(), Some(&missing), &mut Report::default())
        .expect_err("missing file")
        .to_string();
    assert!(e.contains("missing.osc.gz"), "{e}");
}

#[test]
fn truncated_gzip_is_an_error_naming_the_file() {
    let gz = gzip(VALID.as_bytes());
    let e = osc_err("cut.osc.gz", &gz[..gz.len() / 2]);
    assert!(e.contains("gzip"), "{e}");
    // The trailer (CRC, size) missing.
    let e = osc_err("trailer.osc.gz", &gz[..gz.len() - 4]);
    assert!(e.contains("gzip"), "{e}");
    // A whole one reads.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ok.osc.gz");
    std::fs::write(&path, &gz).unwrap();
    assert_eq!(read_osc(&path).unwrap().ways.len(), 1);
}

/// Every truncation and many single-byte corruptions of a valid file, plain and gzipped, give
/// `Ok` or `Err`, never a panic; a truncation inside the root element is always an error.
#[test]
fn cut_and_corrupted_files_never_panic() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t.osc");
    let bytes = VALID.as_bytes();
    let close = VALID.rfind("</osmChange>").unwrap();
    for n in 0..=bytes.len() {
        std::fs::write(&path, &bytes[..n]).unwrap();
        let r = std::panic::catch_unwind(|| read_osc(&path));
        let r = r.unwrap_or_else(|_| panic!("panic on the first {n} bytes"));
        if n < close + "</osmChange>".len() {
            assert!(r.is_err(), "the first {n} bytes read as a whole file");
        } else {
            assert_eq!(r.unwrap().nodes.len(), 1);
        }
    }
    let gz = gzip(bytes);
    for n in 0..gz.len() {
        std::fs::write(&path, &gz[..n]).unwrap();
        assert!(read_osc(&path).is_err(), "{n} bytes of gzip");
    }
    for i in 0..bytes.len() {
        for b in [b'<', b'>', b'"', b'&', 0xff, b'-', b'9', b'/', b' '] {
            let mut d = bytes.to_vec();
            d[i] = b;
            std::fs::write(&path, &d).unwrap();
            let _ = read_osc(&path);
        }
    }
}

/// Without a change, the read is `read_osm`'s; an empty change changes nothing.
#[test]
fn no_change_and_an_empty_change_read_as_the_pbf() {
    let (base, base_report) = read(&monaco(), None);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("empty.osc");
    std::fs::write(
        &path,
        "<?xml version=\"1.0\"?>\n<osmChange version=\"0.6\"><create/><modify></modify></osmChange>\n",
    )
    .unwrap();
    assert!(read_osc(&path).unwrap().is_empty());
    let (got, got_report) = read(&monaco(), Some(&path));
    assert_same(&got, &got_report, &base, &base_report);
    let mut report = Report::default();
    let plain = read_osm(&monaco(), &mut report).unwrap();
    assert_same(&plain, &report, &base, &base_report);
}
