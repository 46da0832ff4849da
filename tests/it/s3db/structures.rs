//! Structures (issue 45, item 3): what is not a house gets none of a house's programme. Each
//! case is written as an OSM file, run through the real binary at LOD3 and LOD4, and read back
//! from its CityJSON (and report): every tagged part is drawn and says its class
//! (`structure`), no structure has a door, a balcony or a room, and a tower's windows are near
//! its top only.

use std::collections::BTreeMap;

use serde_json::Value;

use super::{rect, Osm};
use crate::common::{citygen, KB};

/// One run's CityJSON objects and report.
struct Out {
    objects: BTreeMap<String, Value>,
    /// Every vertex in metres (the transform applied).
    vertices: Vec<[f64; 3]>,
    report: Value,
}

fn run(osm: &Osm, lod: &str) -> Out {
    let dir = tempfile::tempdir().unwrap();
    let pbf = dir.path().join("case.osm.pbf");
    osm.write(&pbf);
    let p = |n: &str| dir.path().join(n).display().to_string();
    let (pbf, city, report) = (
        pbf.display().to_string(),
        p("out.city.json"),
        p("report.json"),
    );
    let gml = p("out.gml");
    let ifc = p("out.ifc");
    let args = [
        "--osm",
        &pbf,
        "--kb",
        KB,
        "--lod",
        lod,
        "--cityjson",
        &city,
        "--citygml",
        &gml,
        "--ifc",
        &ifc,
        "--report",
        &report,
        "--quiet",
    ];
    let out = citygen(&args);
    assert!(
        out.status.success(),
        "citygen failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let gml = std::fs::read_to_string(&gml).unwrap();
    let ifc = std::fs::read_to_string(&ifc).unwrap();
    let doc: Value = serde_json::from_slice(&std::fs::read(&city).unwrap()).unwrap();
    let scale = &doc["transform"]["scale"];
    let translate = &doc["transform"]["translate"];
    let vertices = doc["vertices"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| {
            let c = |i: usize| {
                v[i].as_f64().unwrap() * scale[i].as_f64().unwrap() + translate[i].as_f64().unwrap()
            };
            [c(0), c(1), c(2)]
        })
        .collect();
    let objects: BTreeMap<String, Value> = doc["CityObjects"]
        .as_object()
        .unwrap()
        .iter()
        .map(|(k, v)| (k.clone(), v.clone()))
        .collect();
    // The class is written in every format that says what a part is.
    let classes: Vec<&str> = objects
        .values()
        .filter_map(|o| o["attributes"]["structure"].as_str())
        .collect();
    for c in &classes {
        assert!(
            gml.contains(&format!(
                "<gen:stringAttribute name=\"structure\">\n<gen:value>{c}</gen:value>"
            )),
            "the CityGML names the class {c}"
        );
        assert!(
            ifc.contains(&format!(
                "IFCPROPERTYSINGLEVALUE('Structure',$,IFCLABEL('{c}'),$)"
            )),
            "the IFC names the class {c}"
        );
    }
    Out {
        objects,
        vertices,
        report: serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap(),
    }
}

impl Out {
    /// The object drawn for the tagged way `id`: the building part traced to it, or the
    /// building whose one part it is.
    fn object_of(&self, id: i64) -> &str {
        let src = format!("way/{id}");
        let found: Vec<&str> = self
            .objects
            .iter()
            .filter(|(_, o)| {
                let a = &o["attributes"];
                let part = o["type"] == "BuildingPart" && a["sourceId"] == src.as_str();
                let single = o["type"] == "Building"
                    && (a["partSourceId"] == src.as_str()
                        || (a["sourceId"] == src.as_str()
                            && !o["children"].as_array().is_some_and(|c| {
                                c.iter().any(|k| {
                                    self.objects[k.as_str().unwrap()]["type"] == "BuildingPart"
                                })
                            })));
                part || single
            })
            .map(|(k, _)| k.as_str())
            .collect();
        assert_eq!(found.len(), 1, "{src} is drawn once: {found:?}");
        found[0]
    }

    /// The structure class written on the object of `id`.
    fn class(&self, id: i64) -> Option<&str> {
        self.objects[self.object_of(id)]["attributes"]["structure"].as_str()
    }

    /// The objects under `id` (children, their children...), by type.
    fn under(&self, id: &str) -> Vec<(&str, &Value)> {
        let mut out = Vec::new();
        let mut todo = vec![id.to_string()];
        while let Some(k) = todo.pop() {
            for c in self.objects[&k]["children"]
                .as_array()
                .into_iter()
                .flatten()
            {
                let c = c.as_str().unwrap();
                let o = &self.objects[c];
                out.push((o["type"].as_str().unwrap(), o));
                todo.push(c.to_string());
            }
        }
        out
    }

    /// How many objects of `kind` are under the object of way `id` (rooms, installations:
    /// balconies and stairs), or for `Window` and `Door`, how many semantic surfaces of that
    /// type its geometry has.
    fn count(&self, id: i64, kind: &str) -> usize {
        if kind == "Window" || kind == "Door" {
            return self.openings(id).iter().filter(|(k, ..)| k == kind).count();
        }
        self.under(self.object_of(id))
            .iter()
            .filter(|(t, _)| *t == kind)
            .count()
    }

    /// The openings of the object of way `id`: the semantic surfaces of its geometry typed
    /// `Window` or `Door`, each with its lowest height and the mean of its vertices in plan.
    fn openings(&self, id: i64) -> Vec<(String, f64, [f64; 2])> {
        fn pair(values: &Value, bounds: &Value, f: &mut dyn FnMut(u64, &Value)) {
            let (Some(vs), Some(bs)) = (values.as_array(), bounds.as_array()) else {
                return;
            };
            for (v, b) in vs.iter().zip(bs) {
                match v {
                    Value::Array(_) => pair(v, b, f),
                    Value::Number(n) => f(n.as_u64().unwrap(), b),
                    _ => {}
                }
            }
        }
        let mut out = Vec::new();
        let o = &self.objects[self.object_of(id)];
        for g in o["geometry"].as_array().into_iter().flatten() {
            let surfaces = &g["semantics"]["surfaces"];
            pair(
                &g["semantics"]["values"],
                &g["boundaries"],
                &mut |v, face| {
                    let t = surfaces[v as usize]["type"].as_str().unwrap_or("");
                    if t == "Window" || t == "Door" {
                        out.push((t.to_string(), self.lowest(face), self.centre(face)));
                    }
                },
            );
        }
        out
    }

    /// The lowest height of an object's geometry (metres).
    fn min_z(&self, o: &Value) -> f64 {
        o["geometry"]
            .as_array()
            .into_iter()
            .flatten()
            .map(|g| self.lowest(&g["boundaries"]))
            .fold(f64::INFINITY, f64::min)
    }

    /// The vertices a boundary array names.
    fn points(&self, bounds: &Value) -> Vec<[f64; 3]> {
        fn walk(v: &Value, out: &mut Vec<usize>) {
            match v {
                Value::Array(a) => a.iter().for_each(|x| walk(x, out)),
                Value::Number(n) => out.push(n.as_u64().unwrap() as usize),
                _ => {}
            }
        }
        let mut idx = Vec::new();
        walk(bounds, &mut idx);
        idx.iter().map(|&i| self.vertices[i]).collect()
    }

    /// The lowest height of the vertices a boundary array names (metres).
    fn lowest(&self, bounds: &Value) -> f64 {
        self.points(bounds)
            .iter()
            .map(|p| p[2])
            .fold(f64::INFINITY, f64::min)
    }

    /// The mean in plan of the vertices a boundary array names.
    fn centre(&self, bounds: &Value) -> [f64; 2] {
        let p = self.points(bounds);
        let n = p.len().max(1) as f64;
        [
            p.iter().map(|q| q[0]).sum::<f64>() / n,
            p.iter().map(|q| q[1]).sum::<f64>() / n,
        ]
    }

    /// The report's notes on `id`.
    fn notes(&self, id: i64) -> Vec<String> {
        let id = format!("way/{id}");
        self.report["entries"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|e| e["id"] == id.as_str())
            .map(|e| e["reason"].as_str().unwrap().to_string())
            .collect()
    }
}

/// No window, door or balcony (LOD3) and no room or stair (LOD4) under the parts of `ids`.
fn nothing_of_a_house(lod3: &Out, lod4: &Out, ids: &[i64]) {
    for &id in ids {
        for kind in ["Window", "Door", "BuildingInstallation"] {
            assert_eq!(lod3.count(id, kind), 0, "way/{id}: {kind} at LOD3");
        }
        for kind in ["Window", "Door", "BuildingRoom", "BuildingInstallation"] {
            assert_eq!(lod4.count(id, kind), 0, "way/{id}: {kind} at LOD4");
        }
    }
}

/// A square of side `s` centred on (cx, cy).
fn square(cx: f64, cy: f64, s: f64) -> Vec<(f64, f64)> {
    rect(cx - s / 2.0, cy - s / 2.0, s, s)
}

#[test]
fn a_monumental_column_of_small_parts_is_drawn_whole_and_solid() {
    let mut osm = Osm::default();
    osm.way(
        1,
        &rect(0.0, 0.0, 6.0, 6.0),
        &[
            ("building", "yes"),
            ("man_made", "column"),
            ("historic", "monument"),
            ("height", "48"),
        ],
    );
    osm.way(
        10,
        &rect(0.0, 0.0, 6.0, 6.0),
        &[("building:part", "yes"), ("height", "8")],
    );
    osm.way(
        11,
        &square(3.0, 3.0, 2.4),
        &[
            ("building:part", "yes"),
            ("min_height", "8"),
            ("height", "44"),
        ],
    );
    // Rings of 0.02 to 0.5 m², stacked on the shaft from 44 to 48 m, and a band of small
    // drums around the shaft at 24 m.
    let mut ids = vec![10, 11];
    for (k, side) in [0.7, 0.5, 0.3, 0.15].into_iter().enumerate() {
        let (lo, hi) = (44.0 + k as f64, 45.0 + k as f64);
        let id = 20 + k as i64;
        osm.way(
            id,
            &square(3.0, 3.0, side),
            &[
                ("building:part", "yes"),
                ("min_height", &lo.to_string()),
                ("height", &hi.to_string()),
            ],
        );
        ids.push(id);
    }
    for (k, (cx, cy)) in [(1.45, 3.0), (4.55, 3.0), (3.0, 1.45), (3.0, 4.55)]
        .into_iter()
        .enumerate()
    {
        let id = 30 + k as i64;
        osm.way(
            id,
            &square(cx, cy, 0.6),
            &[
                ("building:part", "yes"),
                ("min_height", "24"),
                ("height", "25"),
            ],
        );
        ids.push(id);
    }
    let (l3, l4) = (run(&osm, "3"), run(&osm, "4"));
    for &id in &ids {
        assert_eq!(l3.class(id), Some("column"), "way/{id}");
        assert_eq!(l4.class(id), Some("column"), "way/{id}");
    }
    nothing_of_a_house(&l3, &l4, &ids);
    assert!(
        l3.notes(1)
            .iter()
            .any(|n| n.contains("structure: 10 of 10 part(s) (column 10)")),
        "{:?}",
        l3.notes(1)
    );
}

#[test]
fn a_colonnade_of_sixteen_columns_under_a_roof() {
    let mut osm = Osm::default();
    osm.way(
        1,
        &rect(0.0, 0.0, 34.0, 6.0),
        &[("building", "yes"), ("name", "Colonnade")],
    );
    osm.way(
        2,
        &rect(0.0, 0.0, 34.0, 6.0),
        &[
            ("building:part", "roof"),
            ("min_height", "6"),
            ("height", "7"),
        ],
    );
    let mut columns = Vec::new();
    for k in 0..16 {
        let (cx, cy) = (2.0 + 4.285 * (k % 8) as f64, if k < 8 { 1.0 } else { 5.0 });
        let id = 100 + k as i64;
        osm.way(
            id,
            &square(cx, cy, 0.6),
            &[("building:part", "column"), ("height", "6")],
        );
        columns.push(id);
    }
    let (l3, l4) = (run(&osm, "3"), run(&osm, "4"));
    for out in [&l3, &l4] {
        for &id in &columns {
            assert_eq!(out.class(id), Some("column"), "way/{id}");
        }
        assert_eq!(out.class(2), Some("roof"));
        // The roof is its slab from min_height, nothing under it.
        let roof = &out.objects[out.object_of(2)];
        assert!((out.min_z(roof) - 6.0).abs() < 0.01, "{}", out.min_z(roof));
    }
    let mut all = columns.clone();
    all.push(2);
    nothing_of_a_house(&l3, &l4, &all);
}

#[test]
fn a_canopy_and_a_carport_are_roofs_on_nothing() {
    let mut osm = Osm::default();
    osm.way(
        1,
        &rect(0.0, 0.0, 12.0, 8.0),
        &[("building", "roof"), ("min_height", "4"), ("height", "4.6")],
    );
    osm.way(2, &rect(20.0, 0.0, 6.0, 5.0), &[("building", "carport")]);
    osm.way(
        3,
        &rect(30.0, 0.0, 8.0, 5.0),
        &[("building", "canopy"), ("min_height", "3")],
    );
    let (l3, l4) = (run(&osm, "3"), run(&osm, "4"));
    for out in [&l3, &l4] {
        for id in [1, 2, 3] {
            assert_eq!(out.class(id), Some("roof"), "way/{id}");
        }
        let canopy = &out.objects[out.object_of(1)];
        assert!(
            (out.min_z(canopy) - 4.0).abs() < 0.01,
            "{}",
            out.min_z(canopy)
        );
        let on_posts = &out.objects[out.object_of(3)];
        assert!(
            (out.min_z(on_posts) - 3.0).abs() < 0.01,
            "{}",
            out.min_z(on_posts)
        );
        // A carport without heights: its roof slab, well above the ground.
        let carport = &out.objects[out.object_of(2)];
        assert!(out.min_z(carport) > 1.5, "{}", out.min_z(carport));
    }
    nothing_of_a_house(&l3, &l4, &[1, 2, 3]);
}

#[test]
fn a_tower_with_a_viewing_platform_has_windows_near_its_top_and_a_door_at_its_base() {
    let mut osm = Osm::default();
    // Its street runs along the south, 6 m off.
    osm.line(
        9,
        &[(-30.0, -6.0), (40.0, -6.0)],
        &[("highway", "residential"), ("name", "Tower Road")],
    );
    osm.way(
        1,
        &rect(0.0, 0.0, 10.0, 10.0),
        &[
            ("building", "yes"),
            ("man_made", "tower"),
            ("tower:type", "observation"),
            ("height", "62"),
        ],
    );
    osm.way(
        2,
        &square(5.0, 5.0, 4.0),
        &[("building:part", "yes"), ("height", "50")],
    );
    osm.way(
        3,
        &rect(0.0, 0.0, 10.0, 10.0),
        &[
            ("building:part", "yes"),
            ("min_height", "50"),
            ("height", "56"),
        ],
    );
    osm.way(
        4,
        &square(5.0, 5.0, 1.0),
        &[
            ("building:part", "yes"),
            ("min_height", "56"),
            ("height", "62"),
        ],
    );
    let (l3, l4) = (run(&osm, "3"), run(&osm, "4"));
    for out in [&l3, &l4] {
        for id in [2, 3, 4] {
            assert_eq!(out.class(id), Some("tower"), "way/{id}");
        }
    }
    let mut windows = 0;
    let mut doors = Vec::new();
    for id in [2, 3, 4] {
        for (t, z, at) in l3.openings(id) {
            if t == "Door" {
                doors.push((id, z, at));
                continue;
            }
            windows += 1;
            assert!(z >= 31.0, "way/{id}: a window at {z} m");
        }
        assert_eq!(l4.count(id, "BuildingRoom"), 0, "way/{id}: a room");
    }
    assert!(windows > 0, "the platform has its windows");
    // One door, at the foot of the shaft (way/2, 4 m square), on its south wall facing the
    // street.
    assert_eq!(doors.len(), 1, "one base door: {doors:?}");
    let (id, z, [x, y]) = doors[0];
    assert_eq!(id, 2, "the door is in the shaft");
    assert!(z < 0.5, "the door stands on the ground: {z} m");
    // The shaft's plan in the output's CRS.
    let shaft = &l3.objects[l3.object_of(2)];
    let pts: Vec<[f64; 3]> = shaft["geometry"]
        .as_array()
        .into_iter()
        .flatten()
        .flat_map(|g| l3.points(&g["boundaries"]))
        .collect();
    let lo = |i: usize| pts.iter().map(|p| p[i]).fold(f64::INFINITY, f64::min);
    let hi = |i: usize| pts.iter().map(|p| p[i]).fold(f64::NEG_INFINITY, f64::max);
    assert!(
        (y - lo(1)).abs() < 0.5 && lo(0) < x && x < hi(0) && hi(1) - y > 3.5,
        "on the south wall: {x}, {y} in x {}..{}, y {}..{}",
        lo(0),
        hi(0),
        lo(1),
        hi(1)
    );
}

#[test]
fn a_church_keeps_its_windows_and_its_tower_a_belfry() {
    let mut osm = Osm::default();
    let apse = [
        (30.0, 2.0),
        (32.5, 3.0),
        (34.0, 6.0),
        (32.5, 9.0),
        (30.0, 10.0),
    ];
    let mut outline = vec![(0.0, 3.0), (6.0, 3.0), (6.0, 0.0), (30.0, 0.0)];
    outline.extend(apse);
    outline.extend([(30.0, 12.0), (6.0, 12.0), (6.0, 9.0), (0.0, 9.0)]);
    osm.way(1, &outline, &[("building", "church"), ("height", "40")]);
    osm.way(
        2,
        &rect(6.0, 0.0, 24.0, 12.0),
        &[
            ("building:part", "yes"),
            ("height", "14"),
            ("roof:shape", "gabled"),
        ],
    );
    osm.way(
        3,
        &rect(0.0, 3.0, 6.0, 6.0),
        &[
            ("building:part", "tower"),
            ("height", "40"),
            ("roof:height", "6"),
            ("roof:shape", "pyramidal"),
        ],
    );
    osm.way(4, &apse, &[("building:part", "yes"), ("height", "10")]);
    let (l3, l4) = (run(&osm, "3"), run(&osm, "4"));
    for out in [&l3, &l4] {
        assert_eq!(out.class(3), Some("tower"));
        assert_eq!(out.class(2), None, "the nave is no structure");
        assert_eq!(out.class(4), None, "the apse is no structure");
    }
    // The belfry: windows on the tower's top storey only, under its 6 m roof; no door.
    let mut belfry = 0;
    for (t, z, _) in l3.openings(3) {
        assert_ne!(t, "Door", "a door in the tower");
        belfry += 1;
        assert!(z >= 25.0, "a tower window at {z} m");
    }
    assert!(belfry > 0, "the belfry has openings");
    assert!(l3.count(2, "Window") > 0, "the nave has windows");
    assert_eq!(
        l3.count(2, "Door") + l3.count(4, "Door"),
        1,
        "one entrance, not in the tower"
    );
    assert_eq!(l4.count(3, "BuildingRoom"), 0, "no room in the tower");
    assert!(l4.count(2, "BuildingRoom") > 0, "the nave has its room");
}

#[test]
fn a_deck_an_obelisk_a_statue_pillars_and_a_kiosk_are_no_houses() {
    let mut osm = Osm::default();
    // An elevated walkway deck over a street (the 1,131 windows).
    osm.way(
        1,
        &rect(0.0, 0.0, 60.0, 4.0),
        &[("building", "bridge"), ("min_height", "6"), ("height", "9")],
    );
    // An obelisk, a statue on its plinth (a memorial without storeys) and a stone column.
    osm.way(
        2,
        &square(80.0, 2.0, 3.0),
        &[
            ("building", "yes"),
            ("man_made", "obelisk"),
            ("height", "22"),
        ],
    );
    osm.way(
        3,
        &square(90.0, 2.0, 4.0),
        &[
            ("building", "yes"),
            ("historic", "memorial"),
            ("height", "7"),
        ],
    );
    // A house with two pillars carrying its porch roof, and a kiosk too small for a room.
    osm.way(
        4,
        &rect(0.0, 20.0, 12.0, 10.0),
        &[("building", "house"), ("building:levels", "2")],
    );
    osm.way(
        5,
        &rect(0.0, 20.0, 12.0, 8.0),
        &[("building:part", "yes"), ("building:levels", "2")],
    );
    osm.way(
        6,
        &square(1.0, 29.6, 0.6),
        &[("building:part", "pillar"), ("height", "3")],
    );
    osm.way(
        7,
        &square(11.0, 29.6, 0.6),
        &[("building:part", "pillar"), ("height", "3")],
    );
    osm.way(
        8,
        &rect(0.0, 28.0, 12.0, 2.0),
        &[
            ("building:part", "roof"),
            ("min_height", "3"),
            ("height", "3.3"),
        ],
    );
    osm.way(9, &rect(30.0, 20.0, 1.8, 1.9), &[("building", "kiosk")]);
    let (l3, l4) = (run(&osm, "3"), run(&osm, "4"));
    for out in [&l3, &l4] {
        assert_eq!(out.class(1), Some("bridge"));
        assert_eq!(out.class(2), Some("monument"));
        assert_eq!(out.class(3), Some("monument"));
        assert_eq!(out.class(6), Some("column"));
        assert_eq!(out.class(7), Some("column"));
        assert_eq!(out.class(8), Some("roof"));
        assert_eq!(out.class(9), Some("small"));
        assert_eq!(out.class(5), None, "the house is no structure");
        // The deck stands on nothing.
        let deck = &out.objects[out.object_of(1)];
        assert!((out.min_z(deck) - 6.0).abs() < 0.01, "{}", out.min_z(deck));
    }
    nothing_of_a_house(&l3, &l4, &[1, 2, 3, 6, 7, 8, 9]);
    // The house keeps its programme: windows, its entrance, rooms.
    assert!(l3.count(5, "Window") > 0, "the house has windows");
    assert_eq!(l3.count(5, "Door"), 1, "the house has its entrance");
    assert!(l4.count(5, "BuildingRoom") > 0, "the house has rooms");
}
