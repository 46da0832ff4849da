//! The bench's "day 2" input (`bench --make-day2`, `citygen::testkit::day2`): day 2 is day 1
//! with exactly the edits of `edits.json` as citygen's reader sees them, the osmChange turns
//! day 1 into day 2, and the same seed gives the same bytes.

use std::collections::{BTreeMap, BTreeSet};
use std::io::Read;
use std::path::Path;

use citygen::input::{read_osm, Footprint, FootprintKind, SourceId};
use citygen::report::Report;
use citygen::testkit::day2::{self, Day2, EditList, ADDED_CLEARANCE_M};
use osmpbf::{Element, ElementReader};
use quick_xml::events::Event;
use quick_xml::XmlVersion;

/// Buildings of the small day 1 (a part of one copy of the template).
const N: usize = 1500;

fn make(dir: &Path, seed: u64) -> Day2 {
    day2::make_day2(N, dir, seed).unwrap()
}

fn footprints(path: &Path) -> BTreeMap<SourceId, Footprint> {
    let r = read_osm(path, &mut Report::default()).unwrap();
    let mut m = BTreeMap::new();
    for f in r.footprints {
        assert!(m.insert(f.id, f).is_none(), "a footprint read twice");
    }
    m
}

fn edit_list(dir: &Path) -> EditList {
    serde_json::from_str(&std::fs::read_to_string(dir.join("edits.json")).unwrap()).unwrap()
}

fn ids(list: &[String]) -> BTreeSet<SourceId> {
    list.iter().map(|s| SourceId::parse(s).unwrap()).collect()
}

fn bits(f: &Footprint) -> Vec<Vec<(u64, u64)>> {
    f.polygons
        .iter()
        .flat_map(|p| std::iter::once(&p.outer).chain(&p.holes))
        .map(|r| r.iter().map(|p| (p.0.to_bits(), p.1.to_bits())).collect())
        .collect()
}

#[test]
fn day2_edit_list_is_what_citygen_reads() {
    let dir = tempfile::tempdir().unwrap();
    let made = make(dir.path(), 1);
    let edits = edit_list(dir.path());
    let (added, removed, changed) = (ids(&edits.added), ids(&edits.removed), ids(&edits.changed));
    // The asked shares of N, within one building.
    let near = |got: usize, pct: f64| (got as f64 - N as f64 * pct / 100.0).abs() <= 1.0;
    assert!(near(changed.len(), 1.0), "{} changed", changed.len());
    assert!(near(added.len(), 0.5), "{} added", added.len());
    assert!(near(removed.len(), 0.5), "{} removed", removed.len());
    assert!(added.is_disjoint(&removed) && added.is_disjoint(&changed));
    assert!(removed.is_disjoint(&changed));
    // Sorted by number, in SourceId display form.
    for list in [&edits.added, &edits.removed, &edits.changed] {
        let parsed: Vec<SourceId> = list.iter().map(|s| SourceId::parse(s).unwrap()).collect();
        assert!(parsed.windows(2).all(|w| w[0] < w[1]), "{list:?}");
        assert!(list.iter().all(|s| s.starts_with("way/")), "{list:?}");
    }
    let way_ids =
        |v: &[i64]| -> BTreeSet<SourceId> { v.iter().map(|&i| SourceId::Way(i)).collect() };
    assert_eq!(way_ids(&made.added), added);
    assert_eq!(way_ids(&made.removed), removed);
    assert_eq!(way_ids(&made.changed), changed);

    let d1 = footprints(&dir.path().join("day1.osm.pbf"));
    let d2 = footprints(&dir.path().join("day2.osm.pbf"));
    let expected: BTreeSet<SourceId> = d1
        .keys()
        .filter(|id| !removed.contains(id))
        .chain(&added)
        .copied()
        .collect();
    assert_eq!(d2.keys().copied().collect::<BTreeSet<_>>(), expected);
    assert!(removed
        .iter()
        .all(|id| d1[id].kind == FootprintKind::Building));
    assert!(added
        .iter()
        .all(|id| d2[id].kind == FootprintKind::Building));
    let (mut tags_differ, mut rings_differ) = (0, 0);
    for (id, f1) in &d1 {
        let Some(f2) = d2.get(id) else { continue };
        let same_tags = f1.tags.same_bits(&f2.tags);
        let same_rings = bits(f1) == bits(f2);
        if changed.contains(id) {
            assert!(
                !same_tags || !same_rings,
                "{id} is listed as changed but is not"
            );
            tags_differ += usize::from(!same_tags);
            rings_differ += usize::from(!same_rings);
        } else {
            assert!(
                same_tags && same_rings && f1.kind == f2.kind,
                "{id} differs"
            );
        }
    }
    // Every changed building has new tags; about half of them a new ring too.
    assert_eq!(tags_differ, changed.len());
    assert_eq!(rings_differ, made.moved.len());
    assert!(
        rings_differ.abs_diff(changed.len() / 2) <= 1,
        "{rings_differ} rings"
    );

    let v = day2::verify_day2(dir.path()).unwrap();
    assert_eq!(
        (v.tags_changed, v.rings_changed),
        (tags_differ, rings_differ)
    );
}

/// Every element of a PBF: nodes (lon, lat in 1e-7 degrees), ways (refs, tags), relations
/// (members as text, tags).
type Tags = Vec<(String, String)>;

#[derive(Debug, Default, PartialEq)]
struct Elements {
    nodes: BTreeMap<i64, (i32, i32)>,
    ways: BTreeMap<i64, (Vec<i64>, Tags)>,
    relations: BTreeMap<i64, (Vec<String>, Tags)>,
}

fn elements(path: &Path) -> Elements {
    let mut e = Elements::default();
    let tags = |it: &mut dyn Iterator<Item = (&str, &str)>| -> Vec<(String, String)> {
        it.map(|(k, v)| (k.to_string(), v.to_string())).collect()
    };
    ElementReader::from_path(path)
        .unwrap()
        .for_each(|el| match el {
            Element::Node(n) => {
                e.nodes
                    .insert(n.id(), (n.decimicro_lon(), n.decimicro_lat()));
            }
            Element::DenseNode(n) => {
                e.nodes
                    .insert(n.id(), (n.decimicro_lon(), n.decimicro_lat()));
            }
            Element::Way(w) => {
                e.ways
                    .insert(w.id(), (w.refs().collect(), tags(&mut w.tags())));
            }
            Element::Relation(r) => {
                let m = r
                    .members()
                    .map(|m| format!("{:?} {} {}", m.member_type, m.member_id, m.role().unwrap()))
                    .collect();
                e.relations.insert(r.id(), (m, tags(&mut r.tags())));
            }
        })
        .unwrap();
    e
}

/// "43.7353272" to 437353272; the text must have exactly 7 decimals.
fn e7(s: &str) -> i32 {
    let (int, frac) = s.split_once('.').unwrap();
    assert_eq!(frac.len(), 7, "{s}");
    let v = int.trim_start_matches('-').parse::<i64>().unwrap() * 10_000_000
        + frac.parse::<i64>().unwrap();
    (if s.starts_with('-') { -v } else { v }) as i32
}

#[test]
fn day2_osc_turns_day1_into_day2() {
    let dir = tempfile::tempdir().unwrap();
    let made = make(dir.path(), 1);
    let mut xml = String::new();
    flate2::read::GzDecoder::new(std::fs::File::open(dir.path().join("changes.osc.gz")).unwrap())
        .read_to_string(&mut xml)
        .unwrap();
    let mut day = elements(&dir.path().join("day1.osm.pbf"));
    let day2 = elements(&dir.path().join("day2.osm.pbf"));
    let mut reader = quick_xml::Reader::from_str(&xml);
    let (mut block, mut root) = (String::new(), String::new());
    let mut counts: BTreeMap<String, usize> = BTreeMap::new();
    // The way being read: (id, refs, tags).
    let mut way: Option<(i64, Vec<i64>, Tags)> = None;
    let attr = |e: &quick_xml::events::BytesStart, name: &str| -> Option<String> {
        e.try_get_attribute(name).unwrap().map(|a| {
            a.normalized_value(XmlVersion::Implicit1_0)
                .unwrap()
                .into_owned()
        })
    };
    loop {
        let ev = reader.read_event().unwrap();
        let (start, empty) = match &ev {
            Event::Start(e) => (Some(e.clone()), false),
            Event::Empty(e) => (Some(e.clone()), true),
            _ => (None, false),
        };
        if let Some(e) = start {
            let name = e.name().into_inner().to_string();
            match name.as_str() {
                "osmChange" => {
                    root = format!(
                        "{} {}",
                        attr(&e, "version").unwrap(),
                        attr(&e, "generator").unwrap()
                    );
                }
                "create" | "modify" | "delete" => block = name.clone(),
                "node" | "way" | "relation" => {
                    *counts.entry(block.clone()).or_default() += 1;
                    let id: i64 = attr(&e, "id").unwrap().parse().unwrap();
                    match (name.as_str(), block.as_str()) {
                        ("node", "delete") => assert!(day.nodes.remove(&id).is_some(), "node {id}"),
                        ("way", "delete") => assert!(day.ways.remove(&id).is_some(), "way {id}"),
                        ("node", _) => {
                            let p = (e7(&attr(&e, "lon").unwrap()), e7(&attr(&e, "lat").unwrap()));
                            let old = day.nodes.insert(id, p);
                            assert_eq!(old.is_some(), block == "modify", "node {id}");
                        }
                        ("way", _) => way = Some((id, Vec::new(), Vec::new())),
                        _ => panic!("unexpected {name} in {block}"),
                    }
                    if name == "way" && empty && block != "delete" {
                        panic!("way {id} without nodes");
                    }
                }
                "nd" => way
                    .as_mut()
                    .unwrap()
                    .1
                    .push(attr(&e, "ref").unwrap().parse().unwrap()),
                "tag" => way
                    .as_mut()
                    .unwrap()
                    .2
                    .push((attr(&e, "k").unwrap(), attr(&e, "v").unwrap())),
                other => panic!("unexpected element {other}"),
            }
        }
        match ev {
            Event::End(e) if e.name().into_inner() == "way" => {
                let (id, refs, tags) = way.take().unwrap();
                let old = day.ways.insert(id, (refs, tags));
                assert_eq!(old.is_some(), block == "modify", "way {id}");
            }
            Event::Eof => break,
            _ => {}
        }
    }
    assert_eq!(root, "0.6 citygen bench");
    let (create, modify, delete) = made.osc_counts();
    let count = |b: &str| counts.get(b).copied().unwrap_or(0);
    assert_eq!(
        (count("create"), count("modify"), count("delete")),
        (create, modify, delete)
    );
    assert_eq!(
        create,
        made.created_nodes + made.added.len(),
        "create: new nodes and ways"
    );
    assert!(made.created_nodes > 0 && made.deleted_nodes > 0);
    assert!(day == day2, "day 1 with the osmChange applied is not day 2");
}

/// Metres east and north of (0, 0) at Monaco's latitude.
fn metres((lon, lat): (i32, i32)) -> (f64, f64) {
    let k = 43.73f64.to_radians().cos();
    (
        lon as f64 * 1e-7 * 111_320.0 * k,
        lat as f64 * 1e-7 * 111_320.0,
    )
}

#[test]
fn day2_new_rings_move_under_a_metre_and_added_buildings_stand_clear() {
    let dir = tempfile::tempdir().unwrap();
    let made = make(dir.path(), 7);
    let d1 = elements(&dir.path().join("day1.osm.pbf"));
    let d2 = elements(&dir.path().join("day2.osm.pbf"));
    let max_node = *d1.nodes.keys().max().unwrap();
    let max_way = *d1.ways.keys().max().unwrap();
    // Moved rings: same vertex count, new nodes, every vertex 0.3 to 1 m away.
    for id in &made.moved {
        let (old, _) = &d1.ways[id];
        let (new, _) = &d2.ways[id];
        assert_eq!(old.len(), new.len(), "way/{id}");
        assert!(new
            .iter()
            .all(|n| *n > max_node && !d1.nodes.contains_key(n)));
        assert!(
            old.iter().all(|n| !d2.nodes.contains_key(n)),
            "way/{id}: old nodes kept"
        );
        for (a, b) in old.iter().zip(new) {
            let (p, q) = (metres(d1.nodes[a]), metres(d2.nodes[b]));
            let d = (p.0 - q.0).hypot(p.1 - q.1);
            assert!((0.29..=1.0).contains(&d), "way/{id}: a vertex moved {d} m");
        }
    }
    // Day 1's other nodes do not move.
    for (id, p) in &d2.nodes {
        if let Some(q) = d1.nodes.get(id) {
            assert_eq!(p, q, "node {id}");
        }
    }
    // Added buildings: new ids, clear of every other way by the clearance, spread out.
    let boxes: BTreeMap<i64, [f64; 4]> = d2
        .ways
        .iter()
        .map(|(id, (refs, _))| {
            let b = refs
                .iter()
                .map(|r| metres(d2.nodes[r]))
                .fold([f64::MAX, f64::MAX, f64::MIN, f64::MIN], |b, (x, y)| {
                    [b[0].min(x), b[1].min(y), b[2].max(x), b[3].max(y)]
                });
            (*id, b)
        })
        .collect();
    let all = boxes
        .values()
        .fold([f64::MAX, f64::MAX, f64::MIN, f64::MIN], |a, b| {
            [
                a[0].min(b[0]),
                a[1].min(b[1]),
                a[2].max(b[2]),
                a[3].max(b[3]),
            ]
        });
    let mut centres = Vec::new();
    for id in &made.added {
        assert!(*id > max_way);
        let (refs, tags) = &d2.ways[id];
        assert_eq!(refs.first(), refs.last());
        assert!(
            (5..=7).contains(&refs.len()),
            "way/{id}: {} refs",
            refs.len()
        );
        assert!(tags.contains(&("building".into(), "yes".into())));
        let b = boxes[id];
        let m = ADDED_CLEARANCE_M - 0.05;
        for (other, o) in &boxes {
            let meets =
                b[0] - m <= o[2] && o[0] <= b[2] + m && b[1] - m <= o[3] && o[1] <= b[3] + m;
            assert!(
                other == id || !meets,
                "way/{id} is within 3 m of way/{other}"
            );
        }
        centres.push(((b[0] + b[2]) / 2.0, (b[1] + b[3]) / 2.0));
    }
    let spread = |f: fn(&(f64, f64)) -> f64, lo: f64, hi: f64| {
        let v: Vec<f64> = centres.iter().map(f).collect();
        let span =
            v.iter().copied().fold(f64::MIN, f64::max) - v.iter().copied().fold(f64::MAX, f64::min);
        span / (hi - lo)
    };
    assert!(
        spread(|c| c.0, all[0], all[2]) > 0.3,
        "added buildings bunched east-west"
    );
    assert!(
        spread(|c| c.1, all[1], all[3]) > 0.3,
        "added buildings bunched north-south"
    );
}

#[test]
fn day2_is_deterministic_and_day1_is_the_tiled_input() {
    let (a, b, c) = (
        tempfile::tempdir().unwrap(),
        tempfile::tempdir().unwrap(),
        tempfile::tempdir().unwrap(),
    );
    make(a.path(), 1);
    make(b.path(), 1);
    for (x, y) in day2::day2_files(a.path())
        .iter()
        .zip(day2::day2_files(b.path()))
    {
        assert_eq!(
            std::fs::read(x).unwrap(),
            std::fs::read(&y).unwrap(),
            "{}",
            x.display()
        );
    }
    let tiled = c.path().join("tiled.osm.pbf");
    citygen::testkit::tiled::make_tiled(N, &tiled).unwrap();
    assert_eq!(
        std::fs::read(&tiled).unwrap(),
        std::fs::read(a.path().join("day1.osm.pbf")).unwrap()
    );
    make(c.path(), 2);
    assert_ne!(
        edit_list(a.path()),
        edit_list(c.path()),
        "seed 2 gave seed 1's edits"
    );
}

#[test]
fn day2_of_no_building_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let e = day2::make_day2(0, dir.path(), 1).unwrap_err();
    assert!(e.to_string().contains("at least 1 building"), "{e}");
}
