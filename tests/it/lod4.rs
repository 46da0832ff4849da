//! LOD4 through the whole generator: the floor plans of real Monaco buildings, mapped into the
//! model the writers consume, keep their doors and their connectivity.

use crate::common::*;

use citygen::model::{Lod, StoreyInterior};

/// Rooms connected to room 0 through the storey's doors.
fn reached(s: &StoreyInterior) -> usize {
    let mut seen = vec![false; s.rooms.len()];
    let mut stack = vec![0usize];
    while let Some(r) = stack.pop() {
        if std::mem::replace(&mut seen[r], true) {
            continue;
        }
        for d in &s.doors {
            let [a, b] = s.walls[d.wall].rooms;
            if a == r && !seen[b] {
                stack.push(b);
            } else if b == r && !seen[a] {
                stack.push(a);
            }
        }
    }
    seen.iter().filter(|s| **s).count()
}

#[test]
fn monaco_ville_interiors_are_connected_and_every_upper_storey_has_the_stair() {
    let mut report = citygen::report::Report::default();
    let read = citygen::input::osm::read_osm(&root().join(MONACO), &mut report).unwrap();
    let mut site = citygen::prepare::prepare(read.footprints, None, None, &mut report);
    citygen::prepare::assign_fronts(&mut site, &read.streets, None);
    citygen::prepare::retain_in_bbox(&mut site, [7.4180, 43.7290, 7.4240, 43.7330], &mut report)
        .expect("Monaco-Ville lies in the sample");
    let (kb, _) = citygen::kb::KnowledgeBase::load(&root().join(KB)).unwrap();
    let caps = citygen::grammar::Caps {
        facades: true,
        ..Default::default()
    };
    let generator =
        citygen::derive::Generator::new(kb, citygen::derive::Rules::Kb, Lod::Lod4, 0, caps);
    let (mut parts, mut storeys, mut rooms, mut doors) = (0, 0, 0, 0);
    for lot in &site.lots {
        let Ok((b, _)) = generator.generate(lot) else {
            continue;
        };
        for p in &b.parts {
            parts += 1;
            assert!(!p.interior.is_empty(), "{} {}: no interior", b.id, p.key);
            assert!(
                p.interior.len() == 1 || p.interior.len() == p.levels.len(),
                "{} {}: {} planned storeys of {}",
                b.id,
                p.key,
                p.interior.len(),
                p.levels.len()
            );
            for s in &p.interior {
                storeys += 1;
                rooms += s.rooms.len();
                doors += s.doors.len();
                assert!(s.ceiling_z > s.floor_z);
                assert_eq!(s.floor_z, p.levels[s.storey]);
                for d in &s.doors {
                    let w = &s.walls[d.wall];
                    assert!(d.u0 > 0.0 && d.u1 < w.a.distance(w.b) && d.u1 > d.u0);
                    assert!(d.height <= s.ceiling_z - s.floor_z);
                }
                assert_eq!(
                    reached(s),
                    s.rooms.len(),
                    "{} {} storey {}: not every room is reached through doors",
                    b.id,
                    p.key,
                    s.storey
                );
                if p.interior.len() > 1 {
                    assert!(
                        s.rooms.iter().any(|r| r.usage == "stair"),
                        "{} storey {}: no stair room",
                        b.id,
                        s.storey
                    );
                }
            }
        }
    }
    eprintln!("{parts} parts, {storeys} storeys, {rooms} rooms, {doors} interior doors");
    assert!(parts > 50 && rooms > 10 * storeys / 2);
}

/// The knowledge base's `programme` is the default of buildings of no declared type: with
/// `programme="office"` on the earth zone, untagged (`building=yes`) Monaco-Ville buildings get
/// office cells, and the typed ones keep their own programme.
#[test]
fn the_knowledge_base_programme_applies_to_untyped_buildings_only() {
    let kb_text = std::fs::read_to_string(root().join(KB)).unwrap();
    let kb_text = kb_text.replacen("<info ", "<info programme=\"office\" ", 1);
    let dir = tempfile::tempdir().unwrap();
    let kb_path = dir.path().join("kb.xml");
    std::fs::write(&kb_path, kb_text).unwrap();
    let (kb, _) = citygen::kb::KnowledgeBase::load(&kb_path).unwrap();
    let mut report = citygen::report::Report::default();
    let read = citygen::input::osm::read_osm(&root().join(MONACO), &mut report).unwrap();
    let mut site = citygen::prepare::prepare(read.footprints, None, None, &mut report);
    citygen::prepare::retain_in_bbox(&mut site, [7.4180, 43.7290, 7.4240, 43.7330], &mut report)
        .expect("Monaco-Ville lies in the sample");
    let caps = citygen::grammar::Caps {
        facades: true,
        ..Default::default()
    };
    let generator =
        citygen::derive::Generator::new(kb, citygen::derive::Rules::Kb, Lod::Lod4, 0, caps);
    let (mut untyped, mut typed) = (0, 0);
    for lot in &site.lots {
        let Ok((b, _)) = generator.generate(lot) else {
            continue;
        };
        let usages: Vec<&str> = b
            .parts
            .iter()
            .flat_map(|p| &p.interior)
            .flat_map(|s| &s.rooms)
            .map(|r| r.usage.as_str())
            .collect();
        let dwelling = usages.iter().any(|u| matches!(*u, "bedroom" | "kitchen"));
        match lot.tags.building.as_deref() {
            None | Some("yes") if lot.parts.is_empty() => {
                untyped += 1;
                assert!(!dwelling, "{}: dwelling rooms {usages:?}", b.id);
            }
            Some("apartments" | "house" | "residential") if lot.parts.is_empty() => {
                typed += 1;
                assert!(dwelling, "{}: no dwelling rooms {usages:?}", b.id);
            }
            _ => {}
        }
    }
    assert!(
        untyped > 20 && typed > 0,
        "{untyped} untyped, {typed} typed"
    );
}
