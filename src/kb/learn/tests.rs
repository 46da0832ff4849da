//! Tests of `kb learn`: samples, grids, zones, the joint fit and the written KB.

use super::fit::{fit_joint, merge_bins, round_probas, Bin};
use super::*;
use crate::kb::{ReadMode, ZoneKind, KM_PER_DEG};

fn sample(lon: f64, lat: f64, storeys: Option<u32>, roof: Option<RoofShape>) -> Sample {
    Sample {
        lonlat: (lon, lat),
        storeys,
        roof,
        ..Sample::default()
    }
}

fn grid(metres: f64, min: usize) -> LearnOptions<'static> {
    LearnOptions {
        grouping: Grouping::Grid { metres },
        min_samples: min,
        max_appearances: DEFAULT_MAX_APPEARANCES,
        name: "test".into(),
        source: "test.osm.pbf".into(),
    }
}

fn strict(text: &str) -> KnowledgeBase {
    match KnowledgeBase::parse_str_with(text, "learned.xml", ReadMode::Strict) {
        Ok((kb, _)) => kb,
        Err(e) => panic!("{e}\n{text}"),
    }
}

/// Metres to degrees of latitude.
fn deg(m: f64) -> f64 {
    m / (KM_PER_DEG * 1000.0)
}

#[test]
fn grid_bins_points_into_the_cells_the_kb_locates_them_in() {
    // 3 x 3 points 400 m apart on a 500 m grid at 43.7° N: every point in its own cell
    // (the anchor is the south-west point), and the learned KB locates it there.
    let mut samples = Vec::new();
    for r in 0..3 {
        for c in 0..3 {
            let lat = 43.7 + deg(10.0 + 600.0 * f64::from(r));
            let lon = 7.4 + deg(10.0 + 600.0 * f64::from(c)) / 43.7f64.to_radians().cos();
            samples.push(sample(lon, lat, Some(r * 3 + c + 1), None));
        }
    }
    let l = learn(&samples, &grid(500.0, 1)).unwrap();
    assert_eq!(l.zones, 2 + 9, "{}", l.text);
    let kb = strict(&l.text);
    let mut seen = std::collections::BTreeSet::new();
    for s in &samples {
        let z = kb.locate(s.lonlat.0, s.lonlat.1);
        let zone = kb.zone(z).unwrap();
        assert_eq!(zone.kind, ZoneKind::District, "{}", zone.path);
        // Each cell has its one building's storeys as its own appearance.
        let (owner, apps) = kb.appearances_for(z);
        assert_eq!(owner, z);
        assert_eq!(apps.len(), 1);
        assert_eq!(apps[0].values.min_floors, s.storeys);
        seen.insert(z);
    }
    assert_eq!(seen.len(), 9);
    // Two points 100 m apart share a cell.
    let two = [
        sample(7.4, 43.7, Some(2), None),
        sample(7.4 + deg(100.0), 43.7, Some(3), None),
    ];
    let l = learn(&two, &grid(500.0, 1)).unwrap();
    assert_eq!(l.zones, 3);
}

#[test]
fn cells_with_too_few_samples_inherit_from_the_extract() {
    // Cell A: 30 buildings, 5 storeys, flat. Cell B (2 km east): 4 buildings, 2 storeys,
    // gabled. With min 20, B has too few of either and takes the extract's distribution.
    let mut samples = Vec::new();
    for k in 0..30 {
        samples.push(sample(
            7.4 + deg(f64::from(k)),
            43.7,
            Some(5),
            Some(RoofShape::Flat),
        ));
    }
    for k in 0..4 {
        samples.push(sample(
            7.4 + deg(2000.0 + f64::from(k)),
            43.7,
            Some(2),
            Some(RoofShape::Gabled),
        ));
    }
    let l = learn(&samples, &grid(500.0, 20)).unwrap();
    let kb = strict(&l.text);
    let town = kb.find("earth/test").unwrap();
    let a = kb.locate(samples[0].lonlat.0, samples[0].lonlat.1);
    let b = kb.locate(samples[31].lonlat.0, samples[31].lonlat.1);
    assert_ne!(a, b);
    // A: its own, one appearance 5 storeys flat.
    let (owner_a, apps_a) = kb.appearances_for(a);
    assert_eq!(owner_a, a);
    assert_eq!(apps_a.len(), 1);
    assert_eq!(apps_a[0].values.roof, Some(RoofShape::Flat));
    // B: none of its own: the town's, 30/34 and 4/34.
    let (owner_b, apps_b) = kb.appearances_for(b);
    assert_eq!(owner_b, town, "{}", l.text);
    let probas: Vec<f64> = apps_b.iter().map(|x| x.proba.unwrap()).collect();
    assert_eq!(probas, vec![0.8824, 0.1176]);
    assert_eq!(apps_b[1].values.min_floors, Some(2));
    // The info of B states the inherited values.
    assert_eq!(kb.resolved(b).storeys, Some(5));
    assert!(l.text.contains("storeys 4 (from test)"), "{}", l.text);
    // Below the minimum everywhere: built-in defaults, nothing learned.
    let l = learn(&samples, &grid(500.0, 100)).unwrap();
    assert_eq!(l.appearances, 0, "{}", l.text);
    assert!(l.text.contains("storeys 34 (built-in default)"));
    strict(&l.text);
}

#[test]
fn the_rare_tail_merges_into_ranges_and_probas_sum_to_one() {
    // 40 storeys values of one roof and a rare roof: at most 12 appearances.
    let mut joint = Joint::new();
    for s in 1..=40u32 {
        joint.insert(("flat", s), 1.0 / f64::from(s));
    }
    joint.insert(("dome", 3), 0.05);
    let total: f64 = joint.values().sum();
    joint.values_mut().for_each(|v| *v /= total);
    let (bins, notes) = merge_bins(&joint, 12);
    assert_eq!(bins.len(), 12);
    let mass: f64 = bins.iter().map(|b| b.mass).sum();
    assert!((mass - 1.0).abs() < 1e-12);
    // The common low storeys stay exact, the tail is a range.
    assert!(bins
        .iter()
        .any(|b| b.roof == "flat" && b.lo == 1 && b.hi == 1));
    assert!(bins.iter().any(|b| b.hi == 40 && b.lo < 40));
    // Ranges of one roof cover its storeys without gaps or overlaps.
    let flat: Vec<&Bin> = bins.iter().filter(|b| b.roof == "flat").collect();
    for w in flat.windows(2) {
        assert_eq!(w[0].hi + 1, w[1].lo);
    }
    assert!(
        notes[0].contains("from 41 (storeys, roof) combinations"),
        "{notes:?}"
    );
    let units = round_probas(&bins.iter().map(|b| b.mass).collect::<Vec<_>>());
    assert_eq!(units.iter().sum::<u32>(), 10_000);
    // Folding: 13 roofs of one storey each into 12 appearances folds the rarest.
    let roofs = [
        "flat",
        "gabled",
        "hipped",
        "dome",
        "onion",
        "round",
        "cone",
        "skillion",
        "pyramidal",
        "mansard",
        "gambrel",
        "saltbox",
        "half-hipped",
    ];
    let mut joint = Joint::new();
    for (k, r) in roofs.iter().enumerate() {
        joint.insert((r, 2), if k == 4 { 0.001 } else { 1.0 });
    }
    let (bins, notes) = merge_bins(&joint, 12);
    assert_eq!(bins.len(), 12);
    assert!(!bins.iter().any(|b| b.roof == "onion"));
    assert!(notes[0].contains("roof onion"), "{notes:?}");
}

#[test]
fn joint_fit_keeps_both_marginals() {
    let mut seed = BTreeMap::new();
    seed.insert((2, "gabled"), 8.0);
    seed.insert((5, "flat"), 2.0);
    let rows: BTreeMap<u32, f64> = [(2, 0.5), (5, 0.3), (9, 0.2)].into();
    let cols: BTreeMap<&'static str, f64> = [("flat", 0.6), ("gabled", 0.4)].into();
    let j = fit_joint(&seed, &rows, &cols);
    for (s, p) in &rows {
        let m: f64 = j.iter().filter(|((_, k), _)| k == s).map(|(_, v)| v).sum();
        assert!((m - p).abs() < 1e-4, "storeys {s}: {m}");
    }
    for (r, p) in &cols {
        let m: f64 = j.iter().filter(|((k, _), _)| k == r).map(|(_, v)| v).sum();
        assert!((m - p).abs() < 1e-4, "roof {r}: {m}");
    }
}

#[test]
fn learning_is_deterministic_and_strict_valid() {
    let mut samples = Vec::new();
    let roofs = [RoofShape::Flat, RoofShape::Hipped, RoofShape::Gabled];
    for k in 0..500u32 {
        let x = f64::from(k % 25) * 97.0;
        let y = f64::from(k / 25) * 83.0;
        let mut s = sample(
            7.4 + deg(x) / 0.72,
            43.7 + deg(y),
            (k % 7 != 0).then_some(1 + (k * 7919) % 23),
            (k % 3 != 0).then_some(roofs[(k as usize * 31) % 3]),
        );
        s.wall_colour = (k % 4 == 0).then(|| ["white", "#f3e5c0"][(k % 8 / 4) as usize].into());
        s.floor_height = (k % 5 == 0).then_some(2.8 + f64::from(k % 3) * 0.2);
        s.material = (k % 6 == 0).then(|| "plaster".into());
        s.kind = Some(["apartments", "yes", "house"][(k % 3) as usize].into());
        samples.push(s);
    }
    let a = learn(&samples, &grid(500.0, 20)).unwrap();
    let mut reversed = samples.clone();
    reversed.reverse();
    let b = learn(&samples, &grid(500.0, 20)).unwrap();
    assert_eq!(a.text, b.text);
    // Input order changes nothing but the order of equal-key samples.
    let c = learn(&reversed, &grid(500.0, 20)).unwrap();
    assert_eq!(a.text, c.text);
    let kb = strict(&a.text);
    let mut kind_groups = 0;
    for z in kb.zones() {
        // Per group (the appearances with one `building` list): the cap, probas summing to 1.
        let mut groups: BTreeMap<Vec<String>, Vec<f64>> = BTreeMap::new();
        for x in &z.appearances {
            groups
                .entry(x.buildings.clone())
                .or_default()
                .push(x.proba.unwrap());
        }
        for (list, probas) in &groups {
            assert!(probas.len() <= DEFAULT_MAX_APPEARANCES, "{}", z.path);
            let sum: f64 = probas.iter().sum();
            assert!((sum - 1.0).abs() < 1e-9, "{} {list:?}: {sum}", z.path);
            kind_groups += usize::from(!list.is_empty());
        }
    }
    assert_eq!(kind_groups, a.kind_groups);
    assert!(a.kind_groups > 0, "{}", a.text);
    let r = crate::kb::tools::report_for(&kb, ReadMode::Strict, Vec::new(), false);
    assert!(r.warnings.is_empty() && r.errors.is_empty(), "{r}");
}

#[test]
fn a_kind_class_with_enough_samples_gets_its_own_group() {
    // One cell: 30 houses of 2 storeys, gabled; 25 apartments of 8 storeys, flat; 5 sheds
    // of 1 storey (too few for a group); 10 `yes` of 4 storeys. With min 20: a group for
    // houses, one for flats, none for industrial; the unfiltered group from all 70 (in the
    // town and in its cell alike): the 15 outside the grouped classes are under 20.
    let mut samples = Vec::new();
    let mut add = |n: u32, kind: &str, storeys: u32, roof: RoofShape| {
        for k in 0..n {
            let mut s = sample(7.4 + deg(f64::from(k)), 43.7, Some(storeys), Some(roof));
            s.kind = Some(kind.into());
            samples.push(s);
        }
    };
    add(30, "house", 2, RoofShape::Gabled);
    add(25, "apartments", 8, RoofShape::Flat);
    add(5, "shed", 1, RoofShape::Flat);
    add(10, "yes", 4, RoofShape::Flat);
    let l = learn(&samples, &grid(500.0, 20)).unwrap();
    // The town and its one cell, two each.
    assert_eq!(l.kind_groups, 4, "{}", l.text);
    let kb = strict(&l.text);
    let z = kb.locate(samples[0].lonlat.0, samples[0].lonlat.1);
    let (owner, apps) = kb.appearances_for(z);
    let houses: Vec<String> = KIND_CLASSES[0].1.iter().map(|k| k.to_string()).collect();
    let flats: Vec<String> = KIND_CLASSES[1].1.iter().map(|k| k.to_string()).collect();
    // A house: only its class's appearance, 2 storeys gabled.
    let (_, h) = kb.eligible_appearances(z, Some("detached"));
    assert_eq!(h.len(), 1, "{}", l.text);
    assert_eq!(apps[h[0]].buildings, houses);
    assert_eq!(apps[h[0]].values.min_floors, Some(2));
    assert_eq!(apps[h[0]].values.roof, Some(RoofShape::Gabled));
    let (_, f) = kb.eligible_appearances(z, Some("office"));
    assert_eq!(apps[f[0]].buildings, flats);
    assert_eq!(apps[f[0]].values.min_floors, Some(8));
    // A shed (its class has no group) and `yes`: the unfiltered appearances, from all 70.
    let (_, s) = kb.eligible_appearances(z, Some("shed"));
    let (_, y) = kb.eligible_appearances(z, None);
    assert_eq!(s, y);
    assert!(s.iter().all(|&i| apps[i].buildings.is_empty()));
    let storeys: std::collections::BTreeSet<Option<u32>> =
        s.iter().map(|&i| apps[i].values.min_floors).collect();
    assert_eq!(storeys.len(), 4, "{}", l.text);
    // No industrial list anywhere.
    assert!(!kb
        .zones()
        .iter()
        .flat_map(|z| &z.appearances)
        .any(|a| a.buildings.iter().any(|b| b == "shed")));
    let _ = owner;
    // With 25 `yes` more (40 outside the grouped classes): the unfiltered group is learned
    // from those alone, so the houses' 2 and the flats' 8 storeys are not counted twice.
    let mut more = samples.clone();
    for k in 0..25 {
        let mut s = sample(
            7.4 + deg(f64::from(100 + k)),
            43.7,
            Some(4),
            Some(RoofShape::Flat),
        );
        s.kind = Some("yes".into());
        more.push(s);
    }
    let l = learn(&more, &grid(500.0, 20)).unwrap();
    let kb = strict(&l.text);
    let z = kb.locate(more[0].lonlat.0, more[0].lonlat.1);
    let (_, apps) = kb.appearances_for(z);
    let (_, y) = kb.eligible_appearances(z, None);
    let storeys: std::collections::BTreeSet<Option<u32>> =
        y.iter().map(|&i| apps[i].values.min_floors).collect();
    assert!(
        !storeys.contains(&Some(2)) && !storeys.contains(&Some(8)),
        "{}",
        l.text
    );
    // With min 26: only the houses (30) have enough.
    let l = learn(&samples, &grid(500.0, 26)).unwrap();
    assert_eq!(l.kind_groups, 2, "{}", l.text);
    strict(&l.text);
    assert_eq!(kind_class(Some("Terrace")), Some(0));
    assert_eq!(kind_class(Some("yes")), None);
    assert_eq!(kind_class(None), None);
}

#[test]
fn nothing_to_learn_gives_the_defaults_or_an_error() {
    assert!(learn(&[], &grid(500.0, 20)).is_err());
    let bare = [sample(7.4, 43.7, None, None)];
    let l = learn(&bare, &grid(500.0, 20)).unwrap();
    assert!(l.text.contains("nothing to"), "{}", l.text);
    let kb = strict(&l.text);
    assert_eq!(kb.zones().len(), 1);
    assert!(learn(&bare, &grid(0.0, 20)).is_err());
    let polar = [sample(7.4, 88.0, Some(2), None)];
    assert!(learn(&polar, &grid(500.0, 1)).is_err());
    let wide = [
        sample(-179.0, 10.0, Some(2), None),
        sample(179.0, 10.0, Some(2), None),
    ];
    assert!(learn(&wide, &grid(500.0, 1)).is_err());
}

#[test]
fn zones_of_a_kb_group_and_inherit_along_its_tree() {
    let kb_text = r#"<earth><town designation="A &amp; B"><info lat="43.7" lon="7.4" dist="2"/>
            <district designation="Core"><polygon points="7.39 43.69, 7.41 43.69, 7.41 43.71, 7.39 43.71"/></district>
            <district designation="Empty"><info lat="10" lon="10" dist="1"/></district>
            </town></earth>"#;
    let (zkb, _) = KnowledgeBase::parse_str(kb_text, "zones.xml").unwrap();
    let mut samples = Vec::new();
    for k in 0..25 {
        samples.push(sample(7.4, 43.7 + deg(f64::from(k)), Some(3), None));
    }
    for k in 0..5 {
        samples.push(sample(7.42, 43.7 + deg(f64::from(k)), Some(8), None));
    }
    samples.push(sample(0.0, 0.0, Some(1), None));
    let o = LearnOptions {
        grouping: Grouping::Zones(&zkb),
        ..grid(500.0, 20)
    };
    let l = learn(&samples, &o).unwrap();
    let kb = strict(&l.text);
    let paths: Vec<&str> = kb.zones().iter().map(|z| z.path.as_str()).collect();
    assert_eq!(paths, ["earth", "earth/A & B", "earth/A & B/Core"]);
    // Earth holds all 31, the town 30 (its own distribution), Core 25.
    let core = kb.find("earth/A & B/Core").unwrap();
    assert_eq!(kb.zone(core).unwrap().appearances.len(), 1);
    let town = kb.find("earth/A & B").unwrap();
    assert_eq!(kb.zone(town).unwrap().appearances.len(), 2);
    assert_eq!(kb.locate(7.42, 43.7), town);
}

#[test]
fn samples_read_the_tags_as_the_generator_does() {
    let t = BuildingTags {
        levels: Some(4.6),
        min_level: Some(1.0),
        height: Some(14.0),
        roof_shape: Some(RoofShape::Hipped),
        building: Some("apartments".into()),
        material: Some("brick & mortar".into()),
        ..BuildingTags::default()
    };
    let s = Sample::from_tags((7.4, 43.7), &t).unwrap();
    assert_eq!(s.storeys, Some(4));
    assert_eq!(s.floor_height, None, "not on the ground");
    assert_eq!(s.material, None, "not a plain word");
    let t = BuildingTags {
        levels: Some(4.0),
        height: Some(14.0),
        roof_height: Some(2.0),
        ..BuildingTags::default()
    };
    assert_eq!(
        Sample::from_tags((7.4, 43.7), &t).unwrap().floor_height,
        Some(3.0)
    );
    let roof = BuildingTags {
        building: Some("roof".into()),
        ..BuildingTags::default()
    };
    assert_eq!(Sample::from_tags((7.4, 43.7), &roof), None);
}
