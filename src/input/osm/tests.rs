use super::*;
use osmpbf::Element;
use std::collections::BTreeSet;

fn monaco() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data/monaco/monaco.osm.pbf")
}

// ---- synthetic data through `assemble` ------------------------------------------------------

/// Nodes on a grid: node id `100 * x + y` sits at (x, y).
fn grid_nodes(max: i64) -> Nodes {
    let mut pts = Vec::new();
    for x in 0..=max {
        for y in 0..=max {
            pts.push((100 * x + y, x as f64, y as f64));
        }
    }
    let mut nodes = Nodes::new(pts.iter().map(|p| p.0).collect());
    for (i, (_, x, y)) in pts.into_iter().enumerate() {
        nodes.set_exact(i, x, y);
    }
    nodes.finish();
    nodes
}

fn n(x: i64, y: i64) -> i64 {
    100 * x + y
}

/// [`assemble`] with an interner of its own.
fn assemble_fresh(
    ways: &mut Vec<WayBlock>,
    rels: &[RelRec],
    nodes: &Nodes,
    report: &mut Report,
) -> ReadResult {
    let mut ways = Ways::from_blocks(std::mem::take(ways));
    assemble(&mut ways, rels, nodes, &TagInterner::default(), report)
}

#[test]
fn needed_ids_are_the_sorted_union() {
    let cases: Vec<Vec<Vec<i64>>> = vec![
        vec![],
        vec![vec![], vec![1, 2], vec![], vec![3]],
        vec![vec![1, 5, 9], vec![2, 5, 10, 11], vec![12], vec![0, 11, 13]],
        vec![vec![4, 5, 6, 4], vec![7, 8, 9, 7], vec![6, 10, 3, 6, 10]],
        // Runs out of order: the merge falls back to a sort.
        (0..50).map(|i| ((50 - i)..(60 - i)).collect()).collect(),
    ];
    for runs in cases {
        let mut want = runs.concat();
        want.sort_unstable();
        want.dedup();
        // As one block's ways.
        let mut block = WayBlock::default();
        for (i, r) in runs.iter().enumerate() {
            let start = block.refs.len();
            block.refs.extend(r);
            let w = way(i as i64, Vec::new(), &[]).ways.remove(0);
            block.push(w, start);
        }
        assert_eq!(block.needed(), want);
        // As sorted runs of blocks.
        let runs = runs
            .into_iter()
            .map(|mut r| {
                r.sort_unstable();
                r.dedup();
                r
            })
            .collect();
        assert_eq!(merge_runs(runs), want);
    }
}

/// A block of one way.
fn way(id: i64, refs: Vec<i64>, tags: &[(&str, &str)]) -> WayBlock {
    let kind = kind_of(tags.iter().copied());
    let mut b = WayBlock {
        refs,
        ..WayBlock::default()
    };
    let w = WayRec {
        id,
        block: 0,
        start: 0,
        end: 0,
        kind,
        street: street_of(tags.iter().copied()).map(|s| s.0),
        name: None,
        tags: kind.map(|_| std::sync::Arc::new(BuildingTags::from_pairs(tags.iter().copied()))),
    };
    b.push(w, 0);
    b
}

fn rel(id: i64, kind: RelKind, members: &[(i64, Role)], tags: &[(&str, &str)]) -> RelRec {
    RelRec {
        id,
        kind,
        tags: owned(tags.iter().copied()),
        members: members
            .iter()
            .map(|&(way, role)| Member { way, role })
            .collect(),
        other_members: 0,
    }
}

fn square_refs(x: i64, y: i64, s: i64) -> Vec<i64> {
    vec![n(x, y), n(x + s, y), n(x + s, y + s), n(x, y + s), n(x, y)]
}

fn entries_for(report: &Report, id: &str) -> Vec<(Outcome, String)> {
    report
        .entries
        .iter()
        .filter(|e| e.id == id)
        .map(|e| (e.outcome, e.reason.clone()))
        .collect()
}

#[test]
fn courtyard_from_open_segments_with_a_reversed_piece() {
    let nodes = grid_nodes(10);
    // Outer 0..10 square split in two open ways, the second one reversed.
    let mut ways = vec![
        way(1, vec![n(0, 0), n(10, 0), n(10, 10)], &[]),
        way(2, vec![n(0, 0), n(0, 10), n(10, 10)], &[]),
        way(3, square_refs(3, 3, 4), &[]),
    ];
    let rels = vec![rel(
        50,
        RelKind::Building,
        &[(1, Role::Outer), (2, Role::Outer), (3, Role::Inner)],
        &[
            ("type", "multipolygon"),
            ("building", "yes"),
            ("height", "9"),
        ],
    )];
    let mut report = Report::default();
    let r = assemble_fresh(&mut ways, &rels, &nodes, &mut report);
    assert_eq!(r.footprints.len(), 1);
    let fp = &r.footprints[0];
    assert_eq!(fp.id, SourceId::Relation(50));
    assert_eq!(fp.kind, FootprintKind::Building);
    assert_eq!(fp.tags.height, Some(9.0));
    assert_eq!(fp.polygons.len(), 1);
    assert_eq!(fp.polygons[0].outer.len(), 4);
    assert_eq!(fp.polygons[0].holes.len(), 1);
    assert!(super::super::rings::signed_area(&fp.polygons[0].outer) > 0.0);
    assert!(super::super::rings::signed_area(&fp.polygons[0].holes[0]) < 0.0);
    assert_eq!(report.read, 1);
    assert!(report.entries.is_empty(), "{:?}", report.entries);
}

#[test]
fn wrong_roles_are_corrected_by_containment() {
    let nodes = grid_nodes(20);
    let mut ways = vec![
        way(1, square_refs(0, 0, 10), &[]),
        way(2, square_refs(2, 2, 3), &[]),
        way(3, square_refs(15, 15, 3), &[]),
    ];
    // The courtyard says "outer", the separate block says nothing.
    let rels = vec![rel(
        7,
        RelKind::Building,
        &[(1, Role::Outer), (2, Role::Outer), (3, Role::Unknown)],
        &[("type", "multipolygon"), ("building", "yes")],
    )];
    let mut report = Report::default();
    let r = assemble_fresh(&mut ways, &rels, &nodes, &mut report);
    let fp = &r.footprints[0];
    assert_eq!(fp.polygons.len(), 2);
    assert_eq!(fp.polygons[0].holes.len(), 1);
    assert_eq!(fp.polygons[1].holes.len(), 0);
    let e = entries_for(&report, "relation/7");
    assert_eq!(e.len(), 1);
    assert_eq!(e[0].0, Outcome::Repaired);
    assert!(e[0].1.contains("1 ring role(s) corrected"), "{}", e[0].1);
    assert_eq!(report.repaired, 1);
}

#[test]
fn missing_members_repair_or_skip() {
    let nodes = grid_nodes(10);
    let mut ways = vec![
        way(1, square_refs(0, 0, 10), &[]),
        // Half of a ring whose other half is missing.
        way(4, vec![n(2, 2), n(4, 2), n(4, 4)], &[]),
    ];
    let rels = vec![
        rel(
            8,
            RelKind::Building,
            &[(1, Role::Outer), (4, Role::Inner), (99, Role::Inner)],
            &[("type", "multipolygon"), ("building", "yes")],
        ),
        rel(
            9,
            RelKind::Part,
            &[(4, Role::Outer), (98, Role::Outer)],
            &[("type", "multipolygon"), ("building:part", "yes")],
        ),
    ];
    let mut report = Report::default();
    let r = assemble_fresh(&mut ways, &rels, &nodes, &mut report);
    assert_eq!(r.footprints.len(), 1);
    assert_eq!(r.footprints[0].polygons[0].holes.len(), 0);
    let e8 = entries_for(&report, "relation/8");
    assert_eq!(e8.len(), 1);
    assert_eq!(e8[0].0, Outcome::Repaired);
    assert!(e8[0].1.contains("1 member way(s) missing"), "{}", e8[0].1);
    assert!(e8[0].1.contains("way/99"));
    assert!(e8[0].1.contains("cannot be closed"));
    let e9 = entries_for(&report, "relation/9");
    assert_eq!(e9.len(), 1);
    assert_eq!(e9[0].0, Outcome::Skipped);
    assert_eq!((report.read, report.parts_read, report.skipped), (1, 1, 1));
}

#[test]
fn old_style_outer_way_gets_the_holes_once() {
    let nodes = grid_nodes(10);
    let mut ways = vec![
        way(
            1,
            square_refs(0, 0, 10),
            &[("building", "yes"), ("height", "20")],
        ),
        way(2, square_refs(3, 3, 4), &[]),
    ];
    let rels = vec![rel(
        5,
        RelKind::Untagged,
        &[(1, Role::Outer), (2, Role::Inner)],
        &[("type", "multipolygon")],
    )];
    let mut report = Report::default();
    let r = assemble_fresh(&mut ways, &rels, &nodes, &mut report);
    assert_eq!(
        r.footprints.len(),
        1,
        "the way once, the relation not at all"
    );
    let fp = &r.footprints[0];
    assert_eq!(fp.id, SourceId::Way(1));
    assert_eq!(fp.tags.height, Some(20.0));
    assert_eq!(fp.polygons[0].holes.len(), 1);
    assert_eq!(report.read, 1);
    let e = entries_for(&report, "way/1");
    assert_eq!(e.len(), 1);
    assert_eq!(e[0].0, Outcome::Note);
    assert!(e[0].1.contains("relation/5"));
}

#[test]
fn outer_way_tagged_like_its_relation_is_built_once() {
    let nodes = grid_nodes(10);
    let mut ways = vec![
        way(1, square_refs(0, 0, 10), &[("building", "yes")]),
        way(2, square_refs(3, 3, 4), &[]),
    ];
    let rels = vec![rel(
        6,
        RelKind::Building,
        &[(1, Role::Outer), (2, Role::Inner)],
        &[("type", "multipolygon"), ("building", "yes")],
    )];
    let mut report = Report::default();
    let r = assemble_fresh(&mut ways, &rels, &nodes, &mut report);
    assert_eq!(r.footprints.len(), 1);
    assert_eq!(r.footprints[0].id, SourceId::Relation(6));
    let e = entries_for(&report, "way/1");
    assert_eq!(e[0].0, Outcome::Skipped);
    assert!(e[0].1.contains("relation/6"));
    assert_eq!((report.read, report.skipped), (2, 1));
}

#[test]
fn streets_are_the_listed_highways_outside_tunnels() {
    let t = |tags: &[(&str, &str)]| is_street(tags.iter().copied());
    assert!(t(&[("highway", "residential")]));
    assert!(t(&[("highway", "steps"), ("name", "Rampe Major")]));
    assert!(t(&[("highway", "service"), ("tunnel", "no")]));
    assert!(!t(&[("highway", "motorway")]));
    assert!(!t(&[("highway", "primary"), ("tunnel", "yes")]));
    assert!(!t(&[
        ("tunnel", "building_passage"),
        ("highway", "footway")
    ]));
    assert!(!t(&[("highway", "service"), ("service", "parking_aisle")]));
    assert!(!t(&[("building", "yes")]));
}

#[test]
fn streets_keep_runs_of_known_nodes_in_way_order() {
    let nodes = grid_nodes(4);
    let ways = vec![
        way(1, vec![n(0, 0), n(1, 0)], &[("building", "yes")]),
        // A missing node (id 9999) splits the street; a lone node before it is no segment.
        way(
            3,
            vec![n(0, 1), 9999, n(1, 1), n(2, 1), n(3, 1)],
            &[("highway", "footway")],
        ),
        way(2, vec![n(0, 4), n(4, 4)], &[("highway", "primary")]),
    ];
    let s = streets_of(&Ways::from_blocks(ways), &[], &nodes);
    let lines: Vec<&[(f64, f64)]> = s.lines().collect();
    assert_eq!(s.len(), 2);
    assert_eq!(lines[0], &[(0.0, 4.0), (4.0, 4.0)][..]);
    assert_eq!(lines[1], &[(1.0, 1.0), (2.0, 1.0), (3.0, 1.0)][..]);
}

#[test]
fn broken_ways_are_reported() {
    let nodes = grid_nodes(5);
    let b = [("building", "yes")];
    let mut ways = vec![
        way(1, vec![n(0, 0), n(1, 0), n(1, 1)], &b), // unclosed
        way(2, vec![n(0, 0), n(1, 0), 999_999, n(0, 0)], &b), // missing node
        way(3, vec![n(0, 0), n(1, 0), n(1, 0), n(0, 0)], &b), // 2 distinct
        way(
            4,
            vec![n(0, 0), n(0, 0), n(2, 0), n(2, 2), n(0, 0)],
            &[("building:part", "yes"), ("roof:shape", "many")],
        ),
        way(5, vec![n(0, 0)], &b),
        way(6, vec![n(0, 0), n(1, 1), n(2, 2), n(0, 0)], &b), // zero area
        way(7, square_refs(0, 0, 1), &[("building", "no")]),
    ];
    let mut report = Report::default();
    let r = assemble_fresh(&mut ways, &[], &nodes, &mut report);
    assert_eq!(r.footprints.len(), 1);
    assert_eq!(r.footprints[0].kind, FootprintKind::Part);
    assert_eq!(
        r.footprints[0].polygons[0].outer.len(),
        3,
        "duplicate node dropped"
    );
    assert_eq!((report.read, report.parts_read, report.skipped), (5, 1, 5));
    assert!(entries_for(&report, "way/1")[0].1.contains("unclosed"));
    assert!(entries_for(&report, "way/2")[0]
        .1
        .contains("1 of 4 nodes missing"));
    assert!(entries_for(&report, "way/3")[0].1.contains("fewer than 3"));
    assert!(entries_for(&report, "way/5")[0].1.contains("1 node"));
    assert!(entries_for(&report, "way/6")[0].1.contains("zero area"));
    let e4 = entries_for(&report, "way/4");
    assert_eq!(
        e4,
        vec![(
            Outcome::Note,
            "tag roof:shape=many ignored: unknown roof shape".to_string()
        )]
    );
    assert!(entries_for(&report, "way/7").is_empty());
}

// ---- Monaco -------------------------------------------------------------------------------

/// Independent count with a plain osmpbf pass: building ways and multipolygon relations,
/// buildings and parts separately (a way tagged both is a part).
fn independent_counts(path: &Path) -> (BTreeSet<SourceId>, BTreeSet<SourceId>) {
    let mut buildings = BTreeSet::new();
    let mut parts = BTreeSet::new();
    let classify = |tags: Vec<(&str, &str)>| {
        let get = |k: &str| tags.iter().find(|(kk, _)| *kk == k).map(|(_, v)| *v);
        // Simple 3D Buildings: building:part wins over building (a dome tagged both is a part).
        if get("building:part").is_some_and(|v| v != "no") {
            Some(false)
        } else if get("building").is_some_and(|v| v != "no") {
            Some(true)
        } else {
            None
        }
    };
    osmpbf::ElementReader::from_path(path)
        .unwrap()
        .for_each(|e| {
            let (id, c) = match e {
                Element::Way(w) => (SourceId::Way(w.id()), classify(w.tags().collect())),
                Element::Relation(r) => {
                    let tags: Vec<_> = r.tags().collect();
                    if !tags.contains(&("type", "multipolygon")) {
                        return;
                    }
                    (SourceId::Relation(r.id()), classify(tags))
                }
                _ => return,
            };
            match c {
                Some(true) => buildings.insert(id),
                Some(false) => parts.insert(id),
                None => false,
            };
        })
        .unwrap();
    (buildings, parts)
}

#[test]
fn monaco_reconciles_with_an_independent_count() {
    let path = monaco();
    let mut report = Report::default();
    let r = read_osm(&path, &mut report).unwrap();
    let (buildings, parts) = independent_counts(&path);
    assert_eq!(report.read, buildings.len());
    // Streets come along, inside the extract (Monaco: lon 7.40-7.44, lat 43.72-43.76).
    assert!(r.streets.len() > 500, "{} streets", r.streets.len());
    assert!(r
        .streets
        .points
        .iter()
        .all(|&(lon, lat)| (7.3..7.5).contains(&lon) && (43.6..43.8).contains(&lat)));
    assert_eq!(report.parts_read, parts.len());

    let skipped: BTreeSet<String> = report
        .entries
        .iter()
        .filter(|e| e.outcome == Outcome::Skipped)
        .map(|e| e.id.clone())
        .collect();
    assert_eq!(
        skipped.len(),
        report.skipped,
        "one skip entry per skipped object"
    );
    let out_b: BTreeSet<SourceId> = r
        .footprints
        .iter()
        .filter(|f| f.kind == FootprintKind::Building)
        .map(|f| f.id)
        .collect();
    let out_p: BTreeSet<SourceId> = r
        .footprints
        .iter()
        .filter(|f| f.kind == FootprintKind::Part)
        .map(|f| f.id)
        .collect();
    for (expected, got) in [(&buildings, &out_b), (&parts, &out_p)] {
        for id in expected {
            let built = got.contains(id);
            let is_skipped = skipped.contains(&id.to_string());
            assert!(
                built != is_skipped,
                "{id}: built {built}, skipped {is_skipped}"
            );
        }
        assert!(got.is_subset(expected));
    }
    assert_eq!(
        out_b.len() + out_p.len(),
        r.footprints.len(),
        "no duplicate ids"
    );
    assert_eq!(
        r.footprints.len() + report.skipped,
        buildings.len() + parts.len()
    );

    // Sorted: ways by id, then relations by id.
    let ids: Vec<SourceId> = r.footprints.iter().map(|f| f.id).collect();
    let mut sorted = ids.clone();
    sorted.sort();
    assert_eq!(ids, sorted);

    // Every ring is usable and oriented.
    for f in &r.footprints {
        assert!(!f.polygons.is_empty());
        for p in &f.polygons {
            assert!(
                super::super::rings::ring_problem(&p.outer).is_none(),
                "{}",
                f.id
            );
            assert!(super::super::rings::signed_area(&p.outer) > 0.0, "{}", f.id);
            for h in &p.holes {
                assert!(super::super::rings::signed_area(h) < 0.0, "{}", f.id);
            }
            for &(x, y) in p.outer.iter() {
                assert!(
                    (7.3..7.5).contains(&x) && (43.6..43.8).contains(&y),
                    "{}",
                    f.id
                );
            }
        }
    }

    // A courtyard multipolygon keeps its hole.
    let courtyard = r.footprints.iter().find(|f| {
        matches!(f.id, SourceId::Relation(_)) && f.polygons.iter().any(|p| !p.holes.is_empty())
    });
    assert!(
        courtyard.is_some(),
        "Monaco has building multipolygons with courtyards"
    );
    let holes_of = |id: i64| {
        r.footprints
            .iter()
            .find(|f| f.id == SourceId::Relation(id))
            .map(|f| f.polygons.iter().map(|p| p.holes.len()).collect::<Vec<_>>())
    };
    assert_eq!(holes_of(393226), Some(vec![1]));
    assert_eq!(holes_of(8280869), Some(vec![4]));

    // Tags came through.
    let with = |f: fn(&BuildingTags) -> bool| r.footprints.iter().filter(|fp| f(&fp.tags)).count();
    let (h, l, rs) = (
        with(|t| t.height.is_some()),
        with(|t| t.levels.is_some()),
        with(|t| t.roof_shape.is_some()),
    );
    eprintln!("monaco tags: height {h}, levels {l}, roof:shape {rs}");
    assert!(h > 0 && l > 0 && rs > 0);
    assert!(r.footprints.iter().all(|f| f.tags.building.is_some()));

    // Deterministic: a second read gives the same.
    let mut report2 = Report::default();
    let r2 = read_osm(&path, &mut report2).unwrap();
    assert_eq!(r.footprints, r2.footprints);
    assert_eq!(report.entries, report2.entries);

    // Print the numbers for the record (visible with --nocapture).
    let rel_b = out_b
        .iter()
        .filter(|i| matches!(i, SourceId::Relation(_)))
        .count();
    eprintln!(
        "monaco: building objects {} (relations {}), parts {}, footprints {} ({} building ways, {} building relations), skipped {}, repaired {}",
        buildings.len(),
        buildings.iter().filter(|i| matches!(i, SourceId::Relation(_))).count(),
        parts.len(),
        r.footprints.len(),
        out_b.len() - rel_b,
        rel_b,
        report.skipped,
        report.repaired
    );
    for e in &report.entries {
        eprintln!("  {} {:?} {}", e.id, e.outcome, e.reason);
    }
    for f in r
        .footprints
        .iter()
        .filter(|f| matches!(f.id, SourceId::Relation(_)))
    {
        let holes: usize = f.polygons.iter().map(|p| p.holes.len()).sum();
        eprintln!("  {} polygons {} holes {}", f.id, f.polygons.len(), holes);
    }
    // The project notes count 1,160 `building` and 12 `building:part` tags; one way is
    // `building=no` and one `building:part=no` (not buildings), and one way carries both
    // `building` and `building:part` (read as a part, Simple 3D Buildings).
    assert_eq!((out_b.len() - rel_b, rel_b, out_p.len()), (1142, 16, 11));
}

// ---- file errors --------------------------------------------------------------------------

fn expect_err_naming(path: &Path) -> String {
    let mut report = Report::default();
    let err = read_osm(path, &mut report).expect_err("must fail");
    let msg = err.to_string();
    assert!(
        msg.contains(&path.display().to_string()),
        "message names the file: {msg}"
    );
    msg
}

#[test]
fn missing_empty_and_text_files_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("nope.osm.pbf");
    assert!(expect_err_naming(&missing).contains("cannot read"));

    let empty = dir.path().join("empty.osm.pbf");
    std::fs::write(&empty, b"").unwrap();
    assert!(expect_err_naming(&empty).contains("not an OSM PBF"));

    let text = dir.path().join("text.osm.pbf");
    // (OSM XML is read: xml_tests.)
    std::fs::write(&text, b"name,height\nA,12\n").unwrap();
    assert!(expect_err_naming(&text).contains("not an OSM PBF"));

    let tiny = dir.path().join("tiny.osm.pbf");
    std::fs::write(&tiny, [0u8, 0]).unwrap();
    expect_err_naming(&tiny);

    assert!(expect_err_naming(dir.path()).contains("directory"));
}

#[test]
fn truncated_and_corrupted_copies_are_errors() {
    let data = std::fs::read(monaco()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    // Cut at several places: inside the header, inside a blob, 2 bytes into a length prefix
    // (osmpbf itself takes the last case for a clean end of file).
    let last_blob = BlobReader::from_path(monaco())
        .unwrap()
        .filter_map(|b| b.ok().and_then(|b| b.offset()))
        .last()
        .unwrap()
        .0 as usize;
    for cut in [10, 200, data.len() / 2, data.len() - 1, last_blob + 2] {
        let p = dir.path().join(format!("cut{cut}.osm.pbf"));
        std::fs::write(&p, &data[..cut]).unwrap();
        let msg = expect_err_naming(&p);
        eprintln!("{msg}");
        assert!(msg.contains("block"), "{msg}");
    }
    // Trailing garbage after the last block.
    let p = dir.path().join("trailing.osm.pbf");
    let mut d = data.clone();
    d.extend_from_slice(&[0, 0]);
    std::fs::write(&p, &d).unwrap();
    assert!(expect_err_naming(&p).contains("2 bytes after the last complete block"));
    // Flipped bytes in the middle of a block.
    let p = dir.path().join("flipped.osm.pbf");
    let mut d = data.clone();
    let mid = d.len() / 2;
    for b in &mut d[mid..mid + 64] {
        *b = !*b;
    }
    std::fs::write(&p, &d).unwrap();
    let mut report = Report::default();
    // Either an error naming the file or (if the flip hit a tolerant spot) a result: never a
    // panic.
    if let Err(e) = read_osm(&p, &mut report) {
        assert!(e.to_string().contains(&p.display().to_string()));
    }
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(12))]
    /// Corrupted or random PBF bytes give a result or an error naming the file, never a panic.
    #[test]
    fn corrupted_pbf_never_panics(
        edits in proptest::collection::vec((proptest::num::usize::ANY, proptest::num::u8::ANY), 1..8),
        random in proptest::collection::vec(proptest::num::u8::ANY, 0..64),
    ) {
        let dir = tempfile::tempdir().unwrap();
        let mut d = std::fs::read(monaco()).unwrap();
        let n = d.len();
        for (at, byte) in edits {
            d[at % n] = byte;
        }
        for (name, bytes) in [("edited.osm.pbf", d), ("random.osm.pbf", random)] {
            let p = dir.path().join(name);
            std::fs::write(&p, &bytes).unwrap();
            if let Err(e) = read_osm(&p, &mut Report::default()) {
                proptest::prop_assert!(e.to_string().contains(&p.display().to_string()));
            }
        }
    }
}

// ---- direct decoding (wire.rs) against osmpbf ----------------------------------------------

/// Inflated data blocks with the kind the sweep saw.
type Blocks = Vec<(BlobKind, Vec<u8>)>;

/// The inflated data blocks of Monaco with the kind the sweep saw.
fn monaco_blocks() -> Blocks {
    let pbf = Pbf::open(&monaco()).unwrap();
    let file = std::fs::read(monaco()).unwrap();
    let locs = pbf.sweep().unwrap();
    locs.iter()
        .map(|l| {
            let start = l.start as usize;
            let frame = frame_of(l.index, &file[start..start + l.len]);
            let mut scratch = Scratch::default();
            let block = inflated(&frame, &mut scratch)
                .expect("a zlib data blob")
                .to_vec();
            (l.kind, block)
        })
        .collect()
}

/// The bytes of a data frame holding `block` uncompressed (see [`frame_of`]).
fn raw_frame(block: &[u8]) -> Vec<u8> {
    fn varint_to(out: &mut Vec<u8>, mut v: u64) {
        while v >= 0x80 {
            out.push(v as u8 | 0x80);
            v >>= 7;
        }
        out.push(v as u8);
    }
    let mut blob = vec![0x0a];
    varint_to(&mut blob, block.len() as u64);
    blob.extend_from_slice(block);
    let mut header = vec![0x0a, 7];
    header.extend_from_slice(b"OSMData");
    header.push(0x18);
    varint_to(&mut header, blob.len() as u64);
    let mut bytes = (header.len() as u32).to_be_bytes().to_vec();
    bytes.extend_from_slice(&header);
    bytes.extend_from_slice(&blob);
    bytes
}

fn frame_of(index: usize, bytes: &[u8]) -> Frame<'_> {
    Frame {
        index,
        start: 0,
        data: 0,
        bytes,
        data_blob: true,
    }
}

/// What a way block gives, comparably: (id, refs, kind, street, tags).
type WayView = (
    i64,
    Vec<i64>,
    Option<FootprintKind>,
    Option<StreetKind>,
    Option<BuildingTags>,
);

fn way_view(b: WayBlock) -> Vec<WayView> {
    b.ways
        .iter()
        .map(|w| {
            let refs = b.refs_of(w).to_vec();
            (
                w.id,
                refs,
                w.kind,
                w.street,
                w.tags.clone().map(|t| (*t).clone()),
            )
        })
        .collect()
}

/// The direct decoder gives osmpbf's result on `frame`, or leaves the block to osmpbf; it
/// never accepts a block osmpbf refuses. Returns whether it decoded the block itself.
fn same_as_osmpbf(frame: &Frame, kind: BlobKind, needed: &[i64]) -> bool {
    let pbf = Pbf::open(&monaco()).unwrap();
    let interner = TagInterner::default();
    let mut scratch = Scratch::default();
    let members = [needed.first().copied().unwrap_or(0)];
    match kind {
        BlobKind::Ways => {
            let fast = fast_ways(frame, &mut scratch, &members, &interner);
            let slow = pbf.decode(frame, |b| {
                (
                    ways_of_block(b, &members, &interner),
                    holds_other_than(b, BlobKind::Ways),
                )
            });
            match (fast, slow) {
                (Some(f), Ok(Some((s, false)))) => {
                    assert_eq!(way_view(f), way_view(s));
                    true
                }
                (Some(_), other) => panic!("decoded a block osmpbf gives {:?}", other.is_ok()),
                (None, _) => false,
            }
        }
        _ => {
            let fast = fast_nodes(frame, &mut scratch, needed);
            let slow = pbf.decode(frame, |b| {
                (
                    nodes_of_block(b, needed),
                    holds_other_than(b, BlobKind::Nodes),
                )
            });
            match (fast, slow) {
                (Some(f), Ok(Some((s, false)))) => {
                    assert_eq!(f, s);
                    true
                }
                (Some(_), other) => panic!("decoded a block osmpbf gives {:?}", other.is_ok()),
                (None, _) => false,
            }
        }
    }
}

/// Every third node id of the node blocks, as the nodes pass would need them.
fn some_node_ids(blocks: &[(BlobKind, Vec<u8>)]) -> Vec<i64> {
    let pbf = Pbf::open(&monaco()).unwrap();
    let mut ids: Vec<i64> = blocks
        .iter()
        .filter(|(k, _)| *k == BlobKind::Nodes)
        .flat_map(|(_, b)| {
            pbf.decode(&frame_of(1, &raw_frame(b)), |b| {
                b.groups()
                    .flat_map(|g| g.dense_nodes().map(|n| n.id()).collect::<Vec<_>>())
                    .collect::<Vec<_>>()
            })
            .unwrap()
            .unwrap()
        })
        .step_by(3)
        .collect();
    ids.sort_unstable();
    ids
}

#[test]
fn direct_decoding_matches_osmpbf() {
    let blocks = monaco_blocks();
    let needed = some_node_ids(&blocks);
    let mut seen = [0, 0];
    for (kind, block) in &blocks {
        if *kind == BlobKind::Relations {
            continue;
        }
        assert!(same_as_osmpbf(
            &frame_of(1, &raw_frame(block)),
            *kind,
            &needed
        ));
        seen[usize::from(*kind == BlobKind::Ways)] += 1;
    }
    assert!(seen[0] > 0 && seen[1] > 0, "{seen:?}");
    // Monaco's address and entrance nodes (issue 45) were among what both decoders agreed on,
    // each at its own node's place.
    let mut scratch = Scratch::default();
    let addresses: Vec<AddrNode> = blocks
        .iter()
        .filter(|(kind, _)| *kind == BlobKind::Nodes)
        .flat_map(|(_, b)| {
            fast_nodes(&frame_of(1, &raw_frame(b)), &mut scratch, &needed)
                .unwrap()
                .1
        })
        .collect();
    assert!(addresses.len() > 100, "{} address nodes", addresses.len());
    let (lo, hi) = (
        (7.40e9 as i64, 43.71e9 as i64),
        (7.45e9 as i64, 43.76e9 as i64),
    );
    assert!(addresses
        .iter()
        .all(|a| (lo.0..hi.0).contains(&a.0) && (lo.1..hi.1).contains(&a.1) && !a.2.is_empty()));
    // A ways block read by the nodes pass and the other way round: left to osmpbf.
    for (kind, block) in &blocks {
        let other = if *kind == BlobKind::Ways {
            BlobKind::Nodes
        } else {
            BlobKind::Ways
        };
        assert!(!same_as_osmpbf(
            &frame_of(1, &raw_frame(block)),
            other,
            &needed
        ));
    }
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]
    /// Edited blocks: the direct decoder agrees with osmpbf or leaves the block to it.
    #[test]
    fn edited_blocks_decode_as_osmpbf_does(
        which in proptest::num::usize::ANY,
        edits in proptest::collection::vec((proptest::num::usize::ANY, proptest::num::u8::ANY), 1..6),
    ) {
        static BLOCKS: std::sync::OnceLock<(Blocks, Vec<i64>)> = std::sync::OnceLock::new();
        let (blocks, needed) = BLOCKS.get_or_init(|| {
            let b = monaco_blocks();
            let n = some_node_ids(&b);
            (b, n)
        });
        let (kind, block) = &blocks[which % blocks.len()];
        let mut b = block.clone();
        let n = b.len();
        for (at, byte) in edits {
            b[at % n] = byte;
        }
        same_as_osmpbf(&frame_of(1, &raw_frame(&b)), *kind, needed);
    }
}

/// A block holding two kinds of element makes the reader read the file again: what the first
/// read noted (a relation given twice) is noted once, and the mixed block's elements are read.
#[test]
fn a_mixed_block_reads_again_and_notes_each_duplicate_once() {
    use crate::testkit::pbf_write::{MemberKind, PbfWriter};
    let mut w = PbfWriter::new(Vec::new()).unwrap();
    let square = |x: f64| [(x, 0.0), (x + 1e-4, 0.0), (x + 1e-4, 1e-4), (x, 1e-4)];
    let mut id = 0;
    let mut rings = Vec::new();
    for x in [7.0, 7.001, 7.002] {
        let mut refs = Vec::new();
        for (lon, lat) in square(x) {
            id += 1;
            w.node(id, lon, 43.7 + lat, &[]).unwrap();
            refs.push(id);
        }
        refs.push(refs[0]);
        rings.push(refs);
    }
    w.way(10, &rings[0], &[("building", "yes")]).unwrap();
    // One block: a way group, then a relation group.
    w.join_groups().unwrap();
    w.way(11, &rings[1], &[("building", "yes")]).unwrap();
    w.way(12, &rings[2], &[]).unwrap();
    let mp = [("type", "multipolygon"), ("building", "yes")];
    w.relation(21, &[(MemberKind::Way, 12, "outer")], &mp)
        .unwrap();
    w.end_join().unwrap();
    // A relation given twice, in a block of relations.
    w.relation(20, &[(MemberKind::Way, 12, "outer")], &mp)
        .unwrap();
    w.relation(20, &[(MemberKind::Way, 12, "outer")], &mp)
        .unwrap();
    let bytes = w.finish().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("mixed.osm.pbf");
    std::fs::write(&path, bytes).unwrap();
    let mut report = Report::default();
    let r = read_osm(&path, &mut report).unwrap();
    let twice: Vec<_> = report
        .entries
        .iter()
        .filter(|e| e.id == "relation/20" && e.reason.contains("appears 2 times"))
        .collect();
    assert_eq!(twice.len(), 1, "{:?}", report.entries);
    // Both ways and the relation of the mixed block are read.
    let ids: Vec<String> = r.footprints.iter().map(|f| f.id.to_string()).collect();
    for id in ["way/10", "way/11", "relation/21"] {
        assert!(ids.iter().any(|i| i == id), "{id} not read: {ids:?}");
    }
}

/// Admin boundaries: a closed boundary way, a whole relation with a hole, a relation cut by
/// the extract that keeps its closed ring (partial), one that loses its hole and one with no
/// closed ring (both dropped, listed as incomplete).
#[test]
fn admin_boundaries_keep_what_closes_and_count_the_rest() {
    let nodes = grid_nodes(20);
    let admin = |level: &'static str, name: &'static str| {
        vec![("admin_level", level), ("name", name), ("ISO3166-1", "XA")]
    };
    let mut closed = way(1, square_refs(0, 0, 2), &[]);
    closed
        .boundaries
        .push((1, owned(admin("8", "Closed").into_iter())));
    let mut blocks = vec![
        closed,
        way(2, square_refs(4, 4, 8), &[]),
        way(3, square_refs(6, 6, 2), &[]),
        way(4, square_refs(14, 14, 2), &[]),
        // Half a ring: an open line.
        way(5, vec![n(0, 10), n(3, 10), n(3, 13)], &[]),
    ];
    let ways = Ways::from_blocks(std::mem::take(&mut blocks));
    let t = |level, name| admin(level, name);
    let rels = vec![
        rel(
            10,
            RelKind::Boundary,
            &[(2, Role::Outer), (3, Role::Inner)],
            &t("2", "Whole"),
        ),
        // Way 99 is not in the file: the island (way 4) still closes.
        rel(
            11,
            RelKind::Boundary,
            &[(4, Role::Outer), (99, Role::Outer)],
            &t("4", "Cut"),
        ),
        rel(
            12,
            RelKind::Boundary,
            &[(2, Role::Outer), (98, Role::Inner)],
            &t("6", "Holeless"),
        ),
        rel(13, RelKind::Boundary, &[(5, Role::Outer)], &t("6", "Open")),
    ];
    let mut report = Report::default();
    let got = boundaries::admin_boundaries(&ways, &rels, &nodes, &mut report);
    let ids: Vec<String> = got.iter().map(|b| b.id.to_string()).collect();
    assert_eq!(ids, ["way/1", "relation/10", "relation/11"]);
    assert_eq!(got[0].names, ["Closed"]);
    assert_eq!(got[0].admin_level, 8);
    assert_eq!(got[0].iso3166_1.as_deref(), Some("XA"));
    assert_eq!(got[1].polygons.len(), 1);
    assert_eq!(got[1].polygons[0].holes.len(), 1);
    let counts = report.boundaries.unwrap();
    assert_eq!(counts.read, 3);
    assert_eq!(counts.partial, ["relation/11"]);
    assert_eq!(counts.incomplete, ["relation/12", "relation/13"]);
    // No footprint and no report entry: boundaries are not buildings.
    assert!(report.entries.is_empty());
}

/// What pass 1 keeps: boundary relations of levels 2..=10 with their naming tags only.
#[test]
fn boundary_relations_are_kept_with_their_naming_tags_only() {
    let keep = |tags: &[(&'static str, &'static str)]| {
        relation_rec(7, || tags.iter().copied(), std::iter::empty())
    };
    let r = keep(&[
        ("type", "boundary"),
        ("boundary", "administrative"),
        ("admin_level", "2"),
        ("name", "X"),
        ("wikidata", "Q1"),
    ])
    .unwrap();
    assert_eq!(r.kind, RelKind::Boundary);
    assert_eq!(
        r.tags,
        owned([("admin_level", "2"), ("name", "X")].into_iter())
    );
    for level in ["1", "11", "x"] {
        let tags = [
            ("type", "boundary"),
            ("boundary", "administrative"),
            ("admin_level", level),
        ];
        assert!(keep(&tags).is_none(), "{level}");
    }
    assert!(keep(&[
        ("type", "boundary"),
        ("boundary", "political"),
        ("admin_level", "2")
    ])
    .is_none());
}
