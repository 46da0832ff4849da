use std::collections::{BTreeMap, BTreeSet};

use glam::{DVec2, DVec3};
use quick_xml::events::Event;
use quick_xml::XmlVersion;

use super::*;
use crate::color::Color;
use crate::crs::Crs;
use crate::export::lod3geom::samples;
use crate::geometry::Polygon;
use crate::model::{Face, OpeningKind, Part, PartRole, RoofShape, SourceId, Wall};

const ORIGIN: DVec3 = DVec3::new(574_321.5, 6_279_876.25, 146.0);

fn ctx(lod: Lod) -> OutputContext {
    OutputContext {
        crs: Crs::Lambert93,
        origin: ORIGIN,
        origin_lonlat: (1.44, 43.6),
        lod,
        source_name: "tiny <&> \"town\".osm.pbf".into(),
        seed: 42,
        vertical_datum: None,
        terrain: None,
    }
}

fn at(v: DVec2, z: f64) -> DVec3 {
    v.extend(z)
}

/// An extruded footprint with a flat roof: one wall per ring edge, roof and ground with the
/// footprint's holes.
fn prism(
    key: &str,
    outer: Vec<DVec2>,
    holes: Vec<Vec<DVec2>>,
    base: f64,
    top: f64,
    wall: Color,
    roof: Color,
) -> Part {
    let footprint = Polygon::new(outer, holes);
    let mut walls = Vec::new();
    for r in footprint.rings() {
        for i in 0..r.len() {
            let (a, b) = (r[i], r[(i + 1) % r.len()]);
            walls.push(Wall {
                start: a,
                end: b,
                base_z: base,
                top_z: top,
                thickness: 0.3,
                outline: Face::new(vec![at(a, base), at(b, base), at(b, top), at(a, top)]),
                storey: 0,
                openings: Vec::new(),
                balconies: Vec::new(),
                party: 0.0,
            });
        }
    }
    let lift = |r: &Vec<DVec2>, z: f64| r.iter().map(|&p| at(p, z)).collect::<Vec<_>>();
    let roof_face = Face {
        outer: lift(&footprint.outer, top),
        holes: footprint.holes.iter().map(|h| lift(h, top)).collect(),
    };
    let rev = |mut v: Vec<DVec3>| {
        v.reverse();
        v
    };
    let ground = Face {
        outer: rev(lift(&footprint.outer, base)),
        holes: footprint.holes.iter().map(|h| rev(lift(h, base))).collect(),
    };
    Part {
        key: key.into(),
        footprint,
        base_z: base,
        eave_z: top,
        top_z: top,
        storeys: ((top - base) / 3.0).round().max(1.0) as u32,
        levels: vec![base],
        wall_color: wall,
        roof_color: roof,
        wall_material: Default::default(),
        roof_material: Default::default(),
        roof_shape: RoofShape::Flat,
        walls,
        roof: vec![roof_face],
        ground,
        interior: Vec::new(),
        source: None,
        role: PartRole::Own,
        structure: None,
        rhythm: None,
        cornice: None,
        eaves: None,
    }
}

fn rect(x0: f64, y0: f64, x1: f64, y1: f64) -> Vec<DVec2> {
    vec![
        DVec2::new(x0, y0),
        DVec2::new(x1, y0),
        DVec2::new(x1, y1),
        DVec2::new(x0, y1),
    ]
}

const BEIGE: Color = Color::rgb(0.96, 0.96, 0.86);
const RED: Color = Color::rgb(0.7, 0.2, 0.1);

fn building(id: SourceId, parts: Vec<Part>) -> Building {
    let base = parts.iter().map(|p| p.base_z).fold(f64::INFINITY, f64::min);
    let tallest = parts
        .iter()
        .max_by(|a, b| a.top_z.total_cmp(&b.top_z))
        .cloned();
    let top = tallest.as_ref().map_or(base, |p| p.top_z);
    Building {
        id,
        name: None,
        zone: "earth/France/Occitanie/Toulouse".into(),
        appearance: "Toulouse#1".into(),
        base_z: base,
        ground_z: base,
        measured_height: top - base,
        storeys_above_ground: tallest.as_ref().map_or(1, |p| p.storeys),
        roof_shape: tallest.as_ref().map_or(RoofShape::Flat, |p| p.roof_shape),
        parts,
        lod: Lod::Lod2,
        facade: Default::default(),
        provenance: Default::default(),
        attributes: None,
    }
}

/// The 10 x 6 m box, 9 m high: 4 walls, a flat roof, a ground.
fn simple_box() -> Building {
    let mut b = building(
        SourceId::Way(123),
        vec![prism(
            "p0",
            rect(0.0, 0.0, 10.0, 6.0),
            vec![],
            0.0,
            9.0,
            BEIGE,
            RED,
        )],
    );
    b.name = Some("Café \"<Chez Marie & Fils>\" l'été".into());
    b
}

fn two_parts() -> Building {
    building(
        SourceId::Relation(45),
        vec![
            prism(
                "p0",
                rect(0.0, 0.0, 10.0, 6.0),
                vec![],
                0.0,
                12.0,
                BEIGE,
                RED,
            ),
            prism(
                "p1",
                rect(10.0, 0.0, 16.0, 6.0),
                vec![],
                0.0,
                6.0,
                Color::WHITE,
                RED,
            ),
        ],
    )
}

fn courtyard() -> Building {
    let hole = vec![
        DVec2::new(5.0, 5.0),
        DVec2::new(5.0, 15.0),
        DVec2::new(15.0, 15.0),
        DVec2::new(15.0, 5.0),
    ];
    building(
        SourceId::Shape(7),
        vec![prism(
            "p0",
            rect(0.0, 0.0, 20.0, 20.0),
            vec![hole],
            2.0,
            14.0,
            BEIGE,
            RED,
        )],
    )
}

/// The box with a hipped roof: ridge from (3,3) to (7,3), 3 m above the eave.
fn hipped() -> Building {
    let (e, r) = (6.0, 9.0);
    let mut part = prism("p0", rect(0.0, 0.0, 10.0, 6.0), vec![], 0.0, e, BEIGE, RED);
    let p = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    part.roof = vec![
        Face::new(vec![
            p(0.0, 0.0, e),
            p(10.0, 0.0, e),
            p(7.0, 3.0, r),
            p(3.0, 3.0, r),
        ]),
        Face::new(vec![p(10.0, 0.0, e), p(10.0, 6.0, e), p(7.0, 3.0, r)]),
        Face::new(vec![
            p(10.0, 6.0, e),
            p(0.0, 6.0, e),
            p(3.0, 3.0, r),
            p(7.0, 3.0, r),
        ]),
        Face::new(vec![p(0.0, 6.0, e), p(0.0, 0.0, e), p(3.0, 3.0, r)]),
    ];
    part.top_z = r;
    part.roof_shape = RoofShape::Hipped;
    building(SourceId::Way(-9), vec![part])
}

fn all_buildings() -> Vec<Building> {
    vec![simple_box(), two_parts(), courtyard(), hipped()]
}

pub(super) fn write_all(lod: Lod, buildings: &[Building]) -> Vec<u8> {
    let mut w = CityGmlWriter::with_srs_name(Vec::new(), "EPSG:2154");
    w.begin(&ctx(lod)).unwrap();
    for b in buildings {
        w.write(b).unwrap();
    }
    w.finish().unwrap();
    w.into_inner()
}

/// A parsed element: enough of a DOM to check structure.
#[derive(Debug, Default)]
pub(super) struct El {
    pub(super) name: String,
    pub(super) attrs: BTreeMap<String, String>,
    pub(super) text: String,
    pub(super) children: Vec<El>,
}

impl El {
    pub(super) fn attr(&self, k: &str) -> Option<&str> {
        self.attrs.get(k).map(String::as_str)
    }
    pub(super) fn child(&self, name: &str) -> Option<&El> {
        self.children.iter().find(|c| c.name == name)
    }
    pub(super) fn children_named<'a>(&'a self, name: &'a str) -> impl Iterator<Item = &'a El> + 'a {
        self.children.iter().filter(move |c| c.name == name)
    }
    pub(super) fn descendants(&self) -> Vec<&El> {
        let mut out = vec![self];
        let mut i = 0;
        while i < out.len() {
            out.extend(out[i].children.iter());
            i += 1;
        }
        out
    }
    pub(super) fn count(&self, name: &str) -> usize {
        self.descendants().iter().filter(|e| e.name == name).count()
    }
    pub(super) fn find_all(&self, name: &str) -> Vec<&El> {
        self.descendants()
            .into_iter()
            .filter(|e| e.name == name)
            .collect()
    }
}

/// Parses the whole document with quick-xml, failing on any well-formedness error.
pub(super) fn parse(bytes: &[u8]) -> El {
    let text = std::str::from_utf8(bytes).expect("UTF-8");
    let mut reader = quick_xml::Reader::from_str(text);
    let mut stack = vec![El::default()];
    let element = |e: &quick_xml::events::BytesStart<'_>| {
        let mut el = El {
            name: e.name().as_ref().to_string(),
            ..El::default()
        };
        for a in e.attributes() {
            let a = a.expect("attribute");
            let v = a
                .normalized_value(XmlVersion::Implicit1_0)
                .expect("attribute value");
            assert!(
                el.attrs
                    .insert(a.key.as_ref().to_string(), v.into_owned())
                    .is_none(),
                "duplicate attribute"
            );
        }
        el
    };
    loop {
        match reader.read_event().expect("well-formed XML") {
            Event::Start(e) => stack.push(element(&e)),
            Event::Empty(e) => {
                let el = element(&e);
                stack.last_mut().unwrap().children.push(el);
            }
            Event::End(_) => {
                let el = stack.pop().unwrap();
                stack.last_mut().unwrap().children.push(el);
            }
            Event::Text(t) => stack.last_mut().unwrap().text.push_str(&t.xml10_content()),
            Event::GeneralRef(r) => {
                let c = match r.resolve_char_ref().expect("char ref") {
                    Some(c) => c,
                    None => match &*r {
                        "amp" => '&',
                        "lt" => '<',
                        "gt" => '>',
                        "quot" => '"',
                        "apos" => '\'',
                        other => panic!("unknown entity {other}"),
                    },
                };
                stack.last_mut().unwrap().text.push(c);
            }
            Event::Eof => break,
            _ => {}
        }
    }
    assert_eq!(stack.len(), 1, "unclosed elements");
    let mut doc = stack.pop().unwrap();
    assert_eq!(doc.children.len(), 1, "one root element");
    doc.children.pop().unwrap()
}

fn buildings_of(root: &El) -> Vec<&El> {
    root.children_named("core:cityObjectMember")
        .map(|m| m.child("bldg:Building").expect("Building"))
        .collect()
}

fn numbers(s: &str) -> Vec<f64> {
    s.split_whitespace()
        .map(|t| t.parse().expect("number"))
        .collect()
}

/// Every gml:id is unique and every local reference (xlink:href, app:target) resolves.
fn check_ids(root: &El) -> BTreeSet<String> {
    let mut ids = BTreeSet::new();
    for e in root.descendants() {
        if let Some(id) = e.attr("gml:id") {
            assert!(ids.insert(id.to_string()), "duplicate gml:id {id}");
            let first = id.chars().next().unwrap();
            assert!(
                first.is_ascii_alphabetic() || first == '_',
                "{id} is not an NCName"
            );
            assert!(
                id.chars()
                    .all(|c| c.is_ascii_alphanumeric() || "_-.".contains(c)),
                "{id} is not an NCName"
            );
        }
    }
    for e in root.descendants() {
        let reference = match (e.attr("xlink:href"), e.name.as_str()) {
            (Some(h), _) => h.to_string(),
            (None, "app:target") => e.text.clone(),
            _ => continue,
        };
        let target = reference.strip_prefix('#').expect("local reference");
        assert!(ids.contains(target), "dangling reference {reference}");
    }
    ids
}

#[test]
fn header_namespaces_and_root() {
    let root = parse(&write_all(Lod::Lod2, &[]));
    assert_eq!(root.name, "core:CityModel");
    for (p, ns) in [
        ("core", "http://www.opengis.net/citygml/2.0"),
        ("bldg", "http://www.opengis.net/citygml/building/2.0"),
        ("gml", "http://www.opengis.net/gml"),
        ("app", "http://www.opengis.net/citygml/appearance/2.0"),
        ("gen", "http://www.opengis.net/citygml/generics/2.0"),
        ("xlink", "http://www.w3.org/1999/xlink"),
        ("xsi", "http://www.w3.org/2001/XMLSchema-instance"),
    ] {
        assert_eq!(root.attr(&format!("xmlns:{p}")), Some(ns), "namespace {p}");
    }
    let loc = root.attr("xsi:schemaLocation").unwrap();
    assert!(loc.contains("http://schemas.opengis.net/citygml/building/2.0/building.xsd"));
    assert!(loc.contains("http://schemas.opengis.net/citygml/appearance/2.0/appearance.xsd"));
    assert_eq!(
        root.child("gml:name").unwrap().text,
        "tiny <&> \"town\".osm.pbf"
    );
    assert!(root
        .child("gml:description")
        .unwrap()
        .text
        .contains("seed 42"));
    assert_eq!(root.children_named("core:cityObjectMember").count(), 0);
}

#[test]
fn lod2_counts_ids_and_references() {
    let buildings = all_buildings();
    let root = parse(&write_all(Lod::Lod2, &buildings));
    check_ids(&root);
    let written = buildings_of(&root);
    assert_eq!(written.len(), buildings.len());
    assert_eq!(root.count("bldg:Building"), 4);
    assert_eq!(root.count("bldg:BuildingPart"), 2);
    let walls: usize = buildings
        .iter()
        .flat_map(|b| &b.parts)
        .map(|p| p.walls.len())
        .sum();
    let roofs: usize = buildings
        .iter()
        .flat_map(|b| &b.parts)
        .map(|p| p.roof.len())
        .sum();
    let parts: usize = buildings.iter().map(|b| b.parts.len()).sum();
    assert_eq!(root.count("bldg:WallSurface"), walls);
    assert_eq!(root.count("bldg:RoofSurface"), roofs);
    assert_eq!(root.count("bldg:GroundSurface"), parts);
    assert_eq!(root.count("bldg:lod2Solid"), parts);
    assert_eq!(root.count("bldg:lod1Solid"), 0);
    let polygons: usize = buildings.iter().map(Building::polygon_count).sum();
    assert_eq!(root.count("gml:Polygon"), polygons);
    // The solids reference every polygon once and hold none inline.
    let refs: Vec<&El> = root
        .find_all("gml:surfaceMember")
        .into_iter()
        .filter(|e| e.attr("xlink:href").is_some())
        .collect();
    assert_eq!(refs.len(), polygons);
    for s in root.find_all("gml:Solid") {
        assert_eq!(s.count("gml:Polygon"), 0);
    }

    // Identifiers come from the source id and the part keys.
    let b0 = written[0];
    assert_eq!(b0.attr("gml:id"), Some("B_way_123"));
    assert!(b0
        .find_all("bldg:WallSurface")
        .iter()
        .any(|w| w.attr("gml:id") == Some("B_way_123_p0_w3_s")));
    assert!(b0
        .find_all("gml:Polygon")
        .iter()
        .any(|w| w.attr("gml:id") == Some("B_way_123_p0_w3")));
    assert_eq!(written[1].attr("gml:id"), Some("B_relation_45"));
    assert_eq!(written[3].attr("gml:id"), Some("B_way_-9"));

    // The hipped roof: 4 RoofSurfaces, roofType 1040, measuredHeight 9.
    let hip = written[3];
    assert_eq!(hip.count("bldg:RoofSurface"), 4);
    assert_eq!(hip.child("bldg:roofType").unwrap().text, "1040");
    assert_eq!(hip.child("bldg:measuredHeight").unwrap().text, "9.000");
    assert_eq!(
        hip.child("bldg:measuredHeight").unwrap().attr("uom"),
        Some("m")
    );
}

#[test]
fn lod1_solids_hold_polygons_inline() {
    let buildings = all_buildings();
    let root = parse(&write_all(Lod::Lod1, &buildings));
    check_ids(&root);
    let parts: usize = buildings.iter().map(|b| b.parts.len()).sum();
    assert_eq!(root.count("bldg:lod1Solid"), parts);
    assert_eq!(
        root.count("bldg:lod2Solid")
            + root.count("bldg:boundedBy")
            + root.count("bldg:WallSurface"),
        0
    );
    let polygons: usize = buildings.iter().map(Building::polygon_count).sum();
    assert_eq!(root.count("gml:Polygon"), polygons);
    for s in root.find_all("gml:Solid") {
        assert_eq!(s.attr("srsName"), Some("EPSG:2154"));
        let cs = s
            .child("gml:exterior")
            .and_then(|e| e.child("gml:CompositeSurface"))
            .expect("CompositeSurface");
        assert!(cs
            .children_named("gml:surfaceMember")
            .all(|m| m.child("gml:Polygon").is_some()));
    }
}

#[test]
fn single_part_geometry_on_building_several_parts_in_building_parts() {
    let root = parse(&write_all(Lod::Lod2, &[simple_box(), two_parts()]));
    let b = buildings_of(&root);
    assert!(b[0].child("bldg:lod2Solid").is_some());
    assert_eq!(b[0].children_named("bldg:boundedBy").count(), 6);
    assert!(b[0].child("bldg:consistsOfBuildingPart").is_none());

    assert!(b[1].child("bldg:lod2Solid").is_none());
    assert!(b[1].child("bldg:boundedBy").is_none());
    let parts: Vec<&El> = b[1]
        .children_named("bldg:consistsOfBuildingPart")
        .map(|c| c.child("bldg:BuildingPart").unwrap())
        .collect();
    assert_eq!(parts.len(), 2);
    assert_eq!(parts[0].attr("gml:id"), Some("B_relation_45_p0"));
    assert_eq!(parts[1].child("bldg:measuredHeight").unwrap().text, "6.000");
    assert_eq!(parts[1].child("bldg:storeysAboveGround").unwrap().text, "2");
    assert_eq!(parts[0].child("bldg:roofType").unwrap().text, "1000");
    for p in parts {
        assert!(p.child("bldg:lod2Solid").is_some());
        assert_eq!(p.children_named("bldg:boundedBy").count(), 6);
    }
    // The building itself carries the overall values.
    assert_eq!(b[1].child("bldg:measuredHeight").unwrap().text, "12.000");
    assert_eq!(b[1].child("bldg:storeysAboveGround").unwrap().text, "4");
}

#[test]
fn element_order_follows_the_schema() {
    let root = parse(&write_all(Lod::Lod2, &[simple_box()]));
    let b = buildings_of(&root)[0];
    let names: Vec<&str> = b.children.iter().map(|c| c.name.as_str()).collect();
    let rank = |n: &str| match n {
        "gml:name" => 0,
        "gml:boundedBy" => 1,
        "gen:stringAttribute" | "gen:doubleAttribute" | "app:appearance" => 2,
        "bldg:roofType" => 3,
        "bldg:measuredHeight" => 4,
        "bldg:storeysAboveGround" => 5,
        "bldg:lod2Solid" => 6,
        "bldg:boundedBy" => 7,
        other => panic!("unexpected {other}"),
    };
    assert!(
        names.windows(2).all(|w| rank(w[0]) <= rank(w[1])),
        "{names:?}"
    );
    assert_eq!(
        b.child("gml:name").unwrap().text,
        "Café \"<Chez Marie & Fils>\" l'été"
    );
    let attrs: BTreeMap<&str, &str> = b
        .children_named("gen:stringAttribute")
        .map(|a| {
            (
                a.attr("name").unwrap(),
                a.child("gen:value").unwrap().text.as_str(),
            )
        })
        .collect();
    assert_eq!(attrs["sourceId"], "way/123");
    assert_eq!(attrs["zone"], "earth/France/Occitanie/Toulouse");
    assert_eq!(attrs["appearance"], "Toulouse#1");
}

#[test]
fn courtyard_has_interiors() {
    let root = parse(&write_all(Lod::Lod2, &[courtyard()]));
    let b = buildings_of(&root)[0];
    // 4 outer + 4 courtyard walls.
    assert_eq!(b.count("bldg:WallSurface"), 8);
    for name in ["bldg:RoofSurface", "bldg:GroundSurface"] {
        let s = b.find_all(name);
        assert_eq!(s.len(), 1);
        let interiors = s[0].find_all("gml:interior");
        assert_eq!(interiors.len(), 1, "{name}");
        let pos = numbers(&interiors[0].find_all("gml:posList")[0].text);
        assert_eq!(pos.len(), 5 * 3, "closed hole ring");
    }
    for w in b.find_all("bldg:WallSurface") {
        assert_eq!(w.count("gml:interior"), 0);
    }
}

#[test]
fn coordinates_are_origin_plus_local_and_rings_closed() {
    let src = hipped();
    let root = parse(&write_all(Lod::Lod2, std::slice::from_ref(&src)));
    let b = buildings_of(&root)[0];
    let polygons: BTreeMap<&str, &El> = b
        .find_all("gml:Polygon")
        .into_iter()
        .map(|p| (p.attr("gml:id").unwrap(), p))
        .collect();
    let check = |id: &str, face: &Face| {
        let list = polygons[id]
            .child("gml:exterior")
            .unwrap()
            .find_all("gml:posList")[0];
        assert_eq!(list.attr("srsDimension"), Some("3"));
        let v = numbers(&list.text);
        assert_eq!(v.len(), (face.outer.len() + 1) * 3);
        for (i, p) in face.outer.iter().chain(face.outer.first()).enumerate() {
            let w = ORIGIN + *p;
            for (k, c) in [w.x, w.y, w.z].into_iter().enumerate() {
                assert!(
                    (v[i * 3 + k] - c).abs() < 5e-4,
                    "{id} point {i}: {} vs {c}",
                    v[i * 3 + k]
                );
            }
        }
    };
    let part = &src.parts[0];
    check("B_way_-9_p0_g", &part.ground);
    for (i, w) in part.walls.iter().enumerate() {
        check(&format!("B_way_-9_p0_w{i}"), &w.outline);
    }
    for (i, f) in part.roof.iter().enumerate() {
        check(&format!("B_way_-9_p0_r{i}"), f);
    }
    // The envelope is the bounds of the building in the output CRS.
    let env = b
        .child("gml:boundedBy")
        .unwrap()
        .child("gml:Envelope")
        .unwrap();
    assert_eq!(env.attr("srsName"), Some("EPSG:2154"));
    assert_eq!(env.attr("srsDimension"), Some("3"));
    let lo = numbers(&env.child("gml:lowerCorner").unwrap().text);
    let hi = numbers(&env.child("gml:upperCorner").unwrap().text);
    assert_eq!(lo, vec![574_321.5, 6_279_876.25, 146.0]);
    assert_eq!(hi, vec![574_331.5, 6_279_882.25, 155.0]);
}

#[test]
fn appearance_one_material_per_colour() {
    let root = parse(&write_all(Lod::Lod2, &[two_parts()]));
    let b = buildings_of(&root)[0];
    let app = b
        .child("app:appearance")
        .unwrap()
        .child("app:Appearance")
        .unwrap();
    assert_eq!(app.child("app:theme").unwrap().text, "citygen");
    let mats: Vec<&El> = app
        .children_named("app:surfaceDataMember")
        .map(|m| m.child("app:X3DMaterial").unwrap())
        .collect();
    // Ground grey, beige walls, red roofs (shared by both parts), white walls.
    let colours: Vec<&str> = mats
        .iter()
        .map(|m| m.child("app:diffuseColor").unwrap().text.as_str())
        .collect();
    assert_eq!(
        colours,
        vec![
            "0.5000 0.5000 0.5000",
            "0.9600 0.9600 0.8600",
            "0.7000 0.2000 0.1000",
            "1.0000 1.0000 1.0000"
        ]
    );
    let targets: Vec<usize> = mats
        .iter()
        .map(|m| m.children_named("app:target").count())
        .collect();
    assert_eq!(targets, vec![2, 4, 2, 4]);
    // Every polygon is coloured exactly once.
    let mut all: Vec<&str> = mats
        .iter()
        .flat_map(|m| m.children_named("app:target").map(|t| t.text.as_str()))
        .collect();
    all.sort_unstable();
    let n = all.len();
    all.dedup();
    assert_eq!(all.len(), n);
    assert_eq!(n, root.count("gml:Polygon"));
    assert!(mats.iter().all(|m| m.child("app:transparency").is_none()));
}

/// FNV-1a 64: a dependency-free fingerprint of an output.
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    })
}

/// The output without the attributes of a default provenance (every source `kb`, no
/// uncertainty), which every building has carried since issue 42.
fn without_kb_provenance(bytes: Vec<u8>) -> Vec<u8> {
    let mut text = String::from_utf8(bytes).unwrap();
    for name in ["storeysSource", "heightSource", "roofSource"] {
        text = text.replace(
            &format!(
                "<gen:stringAttribute name=\"{name}\">\n<gen:value>kb</gen:value>\n</gen:stringAttribute>\n"
            ),
            "",
        );
    }
    text.into_bytes()
}

/// LOD1 and LOD2 output is byte-identical to the writer before LOD3 support (fingerprints
/// taken from that writer on the same samples), but for the provenance attributes added since.
#[test]
fn lod1_lod2_output_unchanged_by_lod3_support() {
    let b = all_buildings();
    assert_eq!(
        fnv1a(&without_kb_provenance(write_all(Lod::Lod1, &b))),
        3_655_589_629_691_104_898,
        "LOD1"
    );
    assert_eq!(
        fnv1a(&without_kb_provenance(write_all(Lod::Lod2, &b))),
        11_241_214_483_957_492_289,
        "LOD2"
    );
}

#[test]
fn output_is_deterministic() {
    let b = all_buildings();
    assert_eq!(write_all(Lod::Lod2, &b), write_all(Lod::Lod2, &b));
    assert_eq!(write_all(Lod::Lod1, &b), write_all(Lod::Lod1, &b));
}

#[test]
fn number_formatting() {
    let f = |v: f64| {
        let mut x = Xml(Vec::new());
        x.fixed3(v);
        String::from_utf8(x.0).unwrap()
    };
    assert_eq!(f(0.0), "0.000");
    assert_eq!(f(-0.0), "0.000");
    assert_eq!(f(-0.0004), "0.000");
    assert_eq!(f(-0.0006), "-0.001");
    assert_eq!(f(1.5), "1.500");
    assert_eq!(f(-12.3456), "-12.346");
    assert_eq!(f(5_432_109.012_5), "5432109.013");
    assert_eq!(f(1e300), format!("{:.3}", 1e300));
}

#[test]
fn escaping_keeps_any_text_well_formed() {
    let mut b = simple_box();
    b.name = Some("a&b<c>d\"e'f\u{1}g\u{FFFF}h\ti\nj\rk".into());
    b.zone = "z\"one\t<1>".into();
    let root = parse(&write_all(Lod::Lod1, &[b]));
    let bl = buildings_of(&root)[0];
    assert_eq!(
        bl.child("gml:name").unwrap().text,
        "a&b<c>d\"e'f\u{FFFD}g\u{FFFD}h\ti\nj\rk"
    );
    let zone = bl
        .children_named("gen:stringAttribute")
        .find(|a| a.attr("name") == Some("zone"))
        .unwrap();
    assert_eq!(zone.child("gen:value").unwrap().text, "z\"one\t<1>");
    let mut x = Xml(Vec::new());
    x.escaped("a\tb\n\"", true);
    assert_eq!(x.0, b"a&#9;b&#10;&quot;");
}

#[test]
fn odd_part_keys_and_degenerate_faces() {
    let mut b = two_parts();
    b.parts[0].key = "same key".into();
    b.parts[1].key = "same key".into();
    // A closed ring is accepted, a two-point face is left out.
    let mut closed = b.parts[0].roof[0].outer.clone();
    closed.push(closed[0]);
    b.parts[0].roof[0].outer = closed;
    b.parts[1].roof.push(Face::new(vec![DVec3::ZERO, DVec3::X]));
    let root = parse(&write_all(Lod::Lod2, &[b.clone()]));
    check_ids(&root);
    let parts = root.find_all("bldg:BuildingPart");
    assert_eq!(parts[0].attr("gml:id"), Some("B_relation_45_p0"));
    assert_eq!(parts[1].attr("gml:id"), Some("B_relation_45_p1"));
    assert_eq!(root.count("bldg:RoofSurface"), 2);
    assert_eq!(root.count("gml:Polygon"), b.polygon_count() - 1);
    let roof = root.find_all("bldg:RoofSurface")[0];
    assert_eq!(numbers(&roof.find_all("gml:posList")[0].text).len(), 5 * 3);
}

#[test]
fn rejects_non_finite_geometry_without_writing_it() {
    let mut bad = simple_box();
    bad.parts[0].walls[2].outline.outer[1].z = f64::NAN;
    let mut w = CityGmlWriter::with_srs_name(Vec::new(), "EPSG:2154");
    w.begin(&ctx(Lod::Lod2)).unwrap();
    let err = w.write(&bad).unwrap_err();
    assert!(err.to_string().contains("way/123"), "{err}");
    assert!(err.to_string().contains("p0"), "{err}");
    w.write(&hipped()).unwrap();
    w.finish().unwrap();
    let root = parse(&w.into_inner());
    assert_eq!(buildings_of(&root).len(), 1);
}

#[test]
fn call_order_is_enforced() {
    let mut w = CityGmlWriter::with_srs_name(Vec::new(), "EPSG:2154");
    assert!(w.write(&simple_box()).is_err());
    assert!(w.finish().is_err());
    w.begin(&ctx(Lod::Lod1)).unwrap();
    assert!(w.begin(&ctx(Lod::Lod1)).is_err());
    w.finish().unwrap();
    assert!(w.write(&simple_box()).is_err());
    assert!(w.finish().is_err());
}

// ---- LOD3 ----

/// Points of a polygon's rings, each ring without its closing point.
fn rings_of(polygon: &El) -> Vec<Vec<DVec3>> {
    polygon
        .find_all("gml:posList")
        .iter()
        .map(|l| {
            let v = numbers(&l.text);
            let mut pts: Vec<DVec3> = v
                .chunks_exact(3)
                .map(|c| DVec3::new(c[0], c[1], c[2]) - ORIGIN)
                .collect();
            assert_eq!(pts.first(), pts.last(), "closed ring");
            pts.pop();
            pts
        })
        .collect()
}

#[test]
fn lod3_openings_per_building_match_the_model() {
    let buildings = samples::all();
    let root = parse(&write_all(Lod::Lod3, &buildings));
    check_ids(&root);
    assert!(root
        .child("gml:description")
        .unwrap()
        .text
        .contains("LOD3 geometry"));
    for (el, b) in buildings_of(&root).into_iter().zip(&buildings) {
        let (windows, doors) = samples::counts(b);
        assert_eq!(el.count("bldg:Window"), windows, "{}", b.id);
        assert_eq!(el.count("bldg:Door"), doors, "{}", b.id);
        assert_eq!(el.count("bldg:opening"), windows + doors);
        let walls: usize = b.parts.iter().map(|p| p.walls.len()).sum();
        assert_eq!(el.count("bldg:WallSurface"), walls);
        // LOD3 properties only.
        for name in ["bldg:lod2Solid", "bldg:lod2MultiSurface", "bldg:lod1Solid"] {
            assert_eq!(el.count(name), 0, "{name}");
        }
        assert_eq!(el.count("bldg:lod3Solid"), b.parts.len());
        let balconies: usize = b
            .parts
            .iter()
            .flat_map(|p| &p.walls)
            .map(|w| w.balconies.len())
            .sum();
        // A wall's window sills are one installation.
        let sills = b
            .parts
            .iter()
            .flat_map(|p| &p.walls)
            .filter(|w| !crate::export::lod3geom::sills(w).is_empty())
            .count();
        assert_eq!(el.count("bldg:BuildingInstallation"), balconies + sills);
    }
    let house = buildings_of(&root)[0];
    assert_eq!(house.count("bldg:Window"), 4);
    assert_eq!(house.count("bldg:Door"), 1);
    let ids: Vec<&str> = house
        .find_all("bldg:Window")
        .iter()
        .chain(house.find_all("bldg:Door").iter())
        .map(|e| e.attr("gml:id").unwrap())
        .collect();
    assert_eq!(
        ids,
        [
            "B_way_301_p0_w0_o0",
            "B_way_301_p0_w0_o2",
            "B_way_301_p0_w4_o0",
            "B_way_301_p0_w4_o1",
            "B_way_301_p0_w0_o1"
        ]
    );
}

#[test]
fn lod3_walls_keep_holes_filled_by_opening_polygons() {
    let buildings = samples::all();
    let root = parse(&write_all(Lod::Lod3, &buildings));
    for (el, b) in buildings_of(&root).into_iter().zip(&buildings) {
        let model_walls: Vec<&Wall> = b.parts.iter().flat_map(|p| &p.walls).collect();
        let surfaces = el.find_all("bldg:WallSurface");
        assert_eq!(surfaces.len(), model_walls.len());
        for (s, w) in surfaces.iter().zip(&model_walls) {
            // Schema order inside a boundary surface: geometry, then openings.
            let names: Vec<&str> = s.children.iter().map(|c| c.name.as_str()).collect();
            let first_opening = names.iter().position(|n| *n == "bldg:opening");
            assert_eq!(names[0], "bldg:lod3MultiSurface");
            assert!(first_opening.is_none_or(|i| names[i..].iter().all(|n| *n == "bldg:opening")));
            let wall_poly = s
                .child("bldg:lod3MultiSurface")
                .unwrap()
                .find_all("gml:Polygon")[0];
            assert_eq!(wall_poly.count("gml:interior"), w.openings.len());
            let rings = rings_of(wall_poly);
            let normal = w.outline.normal();
            let openings: Vec<&El> = s
                .children_named("bldg:opening")
                .map(|o| &o.children[0])
                .collect();
            assert_eq!(openings.len(), w.openings.len());
            for (k, (o_el, o)) in openings.iter().zip(&w.openings).enumerate() {
                let name = match o.kind {
                    OpeningKind::Window => "bldg:Window",
                    OpeningKind::Door => "bldg:Door",
                };
                assert_eq!(o_el.name, name);
                let poly = o_el.find_all("gml:Polygon")[0];
                let pts = &rings_of(poly)[0];
                // Faces outward like the wall ...
                let n = crate::geometry::newell_normal(pts).normalize();
                assert!((n - normal).length() < 1e-3, "{n} vs {normal}");
                assert!(
                    (crate::geometry::newell_normal(pts).length() / 2.0 - o.width() * o.height())
                        .abs()
                        < 1e-2
                );
                // ... and has the corners of the wall's hole k.
                let hole = &rings[k + 1];
                for p in pts {
                    assert!(
                        hole.iter().any(|q| q.distance(*p) < 1e-3),
                        "{p} not in hole"
                    );
                }
                // Holes run against the outline.
                let hn = crate::geometry::newell_normal(hole).normalize();
                assert!((hn + normal).length() < 1e-3);
            }
        }
    }
}

#[test]
fn lod3_solid_references_the_closed_shell() {
    let buildings = samples::all();
    let root = parse(&write_all(Lod::Lod3, &buildings));
    for (el, b) in buildings_of(&root).into_iter().zip(&buildings) {
        let solids = el.find_all("bldg:lod3Solid");
        for (solid, part) in solids.iter().zip(&b.parts) {
            let refs: Vec<&str> = solid
                .find_all("gml:surfaceMember")
                .iter()
                .map(|m| m.attr("xlink:href").unwrap())
                .collect();
            let openings: usize = part.walls.iter().map(|w| w.openings.len()).sum();
            assert_eq!(
                refs.len(),
                1 + part.walls.len() + part.roof.len() + openings
            );
            assert_eq!(solid.count("gml:Polygon"), 0);
            assert_eq!(refs.iter().filter(|r| r.ends_with("_p")).count(), openings);
        }
        // Closed shell: the area vectors of the referenced polygons (outer rings minus holes,
        // plus the opening polygons) cancel out.
        let polygons: BTreeMap<&str, &El> = el
            .find_all("gml:Polygon")
            .into_iter()
            .map(|p| (p.attr("gml:id").unwrap(), p))
            .collect();
        for solid in solids {
            let mut sum = DVec3::ZERO;
            for m in solid.find_all("gml:surfaceMember") {
                let id = m.attr("xlink:href").unwrap().trim_start_matches('#');
                for r in rings_of(polygons[id]) {
                    sum += crate::geometry::newell_normal(&r);
                }
            }
            assert!(sum.length() < 1e-2, "{} open shell: {sum}", b.id);
        }
    }
}

#[test]
fn lod3_element_order_and_balconies() {
    let b = samples::with_balcony();
    let root = parse(&write_all(Lod::Lod3, std::slice::from_ref(&b)));
    check_ids(&root);
    let parts = root.find_all("bldg:BuildingPart");
    assert_eq!(parts.len(), 2);
    let rank = |n: &str| match n {
        "gml:name" | "gml:boundedBy" | "gen:stringAttribute" | "app:appearance" => 0,
        "bldg:roofType" | "bldg:measuredHeight" | "bldg:storeysAboveGround" => 1,
        "bldg:outerBuildingInstallation" => 2,
        "bldg:boundedBy" => 3,
        "bldg:lod3Solid" => 4,
        other => panic!("unexpected {other}"),
    };
    for p in &parts {
        let names: Vec<&str> = p.children.iter().map(|c| c.name.as_str()).collect();
        assert!(
            names.windows(2).all(|w| rank(w[0]) <= rank(w[1])),
            "{names:?}"
        );
    }
    let inst = parts[0].find_all("bldg:BuildingInstallation");
    assert_eq!(inst.len(), 1);
    assert_eq!(inst[0].attr("gml:id"), Some("B_way_303_p0_w4_b0"));
    assert_eq!(inst[0].child("gml:name").unwrap().text, "balcony");
    let geom = inst[0].child("bldg:lod3Geometry").unwrap();
    assert_eq!(
        geom.count("gml:Polygon"),
        6 + 10 + 5 * 4 + 10,
        "slab box, handrail, five posts' sides and the infill"
    );
    // The slab stands 1.2 m out of the wall (y = 0, outside is -y); the envelope covers it.
    let ys: Vec<f64> = geom
        .find_all("gml:Polygon")
        .iter()
        .flat_map(|p| rings_of(p).concat())
        .map(|p| p.y)
        .collect();
    let min_y = ys.iter().copied().fold(f64::INFINITY, f64::min);
    assert!((min_y + 1.2).abs() < 1e-3, "{min_y}");
    let env = buildings_of(&root)[0]
        .child("gml:boundedBy")
        .unwrap()
        .child("gml:Envelope")
        .unwrap();
    let lo = numbers(&env.child("gml:lowerCorner").unwrap().text);
    assert!((lo[1] - (ORIGIN.y - 1.2)).abs() < 1e-3);
    assert_eq!(parts[1].count("bldg:BuildingInstallation"), 0);
    assert_eq!(parts[1].count("bldg:Door"), 1);
}

#[test]
fn lod3_appearance_glass_doors_balconies() {
    let buildings = samples::all();
    let root = parse(&write_all(Lod::Lod3, &buildings));
    let all_ids = check_ids(&root);
    for el in buildings_of(&root) {
        let mats = el.find_all("app:X3DMaterial");
        let mut targets: Vec<&str> = mats
            .iter()
            .flat_map(|m| m.children_named("app:target").map(|t| t.text.as_str()))
            .collect();
        let n = targets.len();
        targets.sort_unstable();
        targets.dedup();
        assert_eq!(targets.len(), n, "a polygon coloured twice");
        assert_eq!(n, el.count("gml:Polygon"), "every polygon coloured");
        let colour_of = |id: &str| {
            let m = mats
                .iter()
                .find(|m| {
                    m.children_named("app:target")
                        .any(|t| t.text == format!("#{id}"))
                })
                .unwrap();
            (
                m.child("app:diffuseColor").unwrap().text.clone(),
                m.child("app:transparency").map(|t| t.text.clone()),
            )
        };
        for w in el.find_all("bldg:Window") {
            let poly = w.find_all("gml:Polygon")[0].attr("gml:id").unwrap();
            let (_, t) = colour_of(poly);
            if poly == "B_relation_302_p0_w4_o1_p" {
                assert_eq!(t, None, "opaque window");
            } else {
                assert_eq!(t.as_deref(), Some("0.6000"), "{poly}");
            }
        }
        for d in el.find_all("bldg:Door") {
            let poly = d.find_all("gml:Polygon")[0].attr("gml:id").unwrap();
            assert_eq!(colour_of(poly), ("0.4000 0.2500 0.1000".to_string(), None));
        }
        for i in el.find_all("bldg:BuildingInstallation") {
            let polygons = i.find_all("gml:Polygon");
            if i.attr("gml:id").unwrap().ends_with("_sills") {
                for p in &polygons {
                    let colour = colour_of(p.attr("gml:id").unwrap());
                    assert_eq!(colour, ("0.8300 0.8100 0.7600".to_string(), None));
                }
                continue;
            }
            let n = polygons.len();
            for (k, p) in polygons.iter().enumerate() {
                let colour = colour_of(p.attr("gml:id").unwrap());
                let expected = match k {
                    0..6 => ("0.6000 0.6000 0.6000", None),
                    _ if k < n - 10 => ("0.2000 0.2100 0.2300", None),
                    _ => ("0.5500 0.6500 0.6500", Some("0.5000")),
                };
                assert_eq!(
                    (colour.0.as_str(), colour.1.as_deref()),
                    expected,
                    "slab, railing, infill"
                );
            }
        }
    }
    assert!(all_ids.contains("B_way_304_p0_w1_o0"), "gable window");
}

#[test]
fn lod3_deterministic_lod4_as_lod3_lod2_without_details() {
    let b = samples::all();
    assert_eq!(write_all(Lod::Lod3, &b), write_all(Lod::Lod3, &b));
    // LOD4 runs write the LOD3 exterior in the lod4 properties.
    let lod4 = parse(&write_all(Lod::Lod4, &b));
    assert_eq!(lod4.count("bldg:lod3MultiSurface"), 0);
    assert_eq!(
        lod4.count("bldg:Window"),
        b.iter().map(|x| samples::counts(x).0).sum::<usize>()
    );
    // At LOD2 the same walls are written without openings.
    let lod2 = parse(&write_all(Lod::Lod2, &b));
    assert_eq!(
        lod2.count("bldg:opening") + lod2.count("bldg:BuildingInstallation"),
        0
    );
}

#[test]
fn lod3_rejects_non_finite_openings() {
    let mut bad = samples::house();
    bad.parts[0].walls[0].openings[1].z1 = f64::INFINITY;
    let mut w = CityGmlWriter::with_srs_name(Vec::new(), "EPSG:2154");
    w.begin(&ctx(Lod::Lod3)).unwrap();
    let err = w.write(&bad).unwrap_err().to_string();
    assert!(err.contains("way/301") && err.contains("wall 0"), "{err}");
    // A degenerate opening is left out, the rest is written.
    let mut odd = samples::house();
    odd.parts[0].walls[0].openings[0].u1 = odd.parts[0].walls[0].openings[0].u0;
    w.write(&odd).unwrap();
    w.finish().unwrap();
    let root = parse(&w.into_inner());
    check_ids(&root);
    assert_eq!(root.count("bldg:Window"), 3);
}

#[test]
#[ignore = "writes c3.gml in the temporary folder for manual validation"]
fn dump_lod3_sample() {
    std::fs::write(
        std::env::temp_dir().join("c3.gml"),
        write_all(Lod::Lod3, &samples::all()),
    )
    .unwrap();
}

/// Runs the reference validator (OGC CityGML 2.0 XSDs) on LOD1, LOD2 and LOD3 output when it
/// is installed; skipped otherwise so that the suite runs anywhere.
#[test]
fn validates_against_citygml_schemas() {
    let Some(validator) = crate::testkit::validators::validate_outputs("CityGML LOD1-3 schemas")
    else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let mut files = Vec::new();
    for lod in [Lod::Lod1, Lod::Lod2] {
        let path = dir.path().join(format!("lod{}.gml", lod.number()));
        std::fs::write(&path, write_all(lod, &all_buildings())).unwrap();
        files.push(path);
    }
    let path = dir.path().join("lod3.gml");
    let mut lod3 = all_buildings();
    lod3.extend(samples::all());
    std::fs::write(&path, write_all(Lod::Lod3, &lod3)).unwrap();
    files.push(path);
    let out = std::process::Command::new(validator)
        .args(&files)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && text.contains("3 passed, 0 failed"),
        "{text}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(256))]

    /// Millimetre rounding: within half a millimetre, three decimals, never a negative zero.
    #[test]
    fn fixed3_rounds_to_millimetres(v in -1.0e9f64..1.0e9) {
        let mut x = Xml(Vec::new());
        x.fixed3(v);
        let s = String::from_utf8(x.0).unwrap();
        let back: f64 = s.parse().unwrap();
        proptest::prop_assert!((back - v).abs() <= 0.000_5 + v.abs() * 1e-15, "{} -> {}", v, s);
        proptest::prop_assert_eq!(s.split('.').nth(1).map(str::len), Some(3));
        proptest::prop_assert!(s != "-0.000");
    }

    /// Any name survives a round trip through the file (XML-forbidden characters aside).
    #[test]
    fn any_name_round_trips(name in "\\PC*") {
        let mut b = simple_box();
        b.name = Some(name.clone());
        let root = parse(&write_all(Lod::Lod1, &[b]));
        let text = buildings_of(&root)[0].child("gml:name").unwrap().text.clone();
        proptest::prop_assert_eq!(text, name);
    }
}

/// The LOD4 additions ([`super::lod4`]): stairs and rooms.
mod lod4 {
    use std::collections::{BTreeMap, BTreeSet};

    use super::{parse, write_all, El};
    use crate::export::fixtures;
    use crate::model::Lod;

    /// The posList of a polygon's rings as rounded points (mm).
    fn rings(poly: &El) -> Vec<Vec<[i64; 3]>> {
        poly.find_all("gml:posList")
            .iter()
            .map(|p| {
                let v: Vec<f64> = p
                    .text
                    .split_whitespace()
                    .map(|n| n.parse().unwrap())
                    .collect();
                let mut pts: Vec<[i64; 3]> = v
                    .chunks(3)
                    .map(|c| [0, 1, 2].map(|k| (c[k] * 1000.0).round() as i64))
                    .collect();
                assert_eq!(pts.first(), pts.last(), "closed ring");
                pts.pop();
                pts
            })
            .collect()
    }

    #[test]
    fn rooms_are_closed_solids_with_doors_and_the_stair_is_an_installation() {
        let bs = fixtures::lod4_all();
        let doc = parse(&write_all(Lod::Lod4, &bs));
        assert_eq!(doc.count("bldg:lod3MultiSurface"), 0);
        let house = &doc.find_all("bldg:Building")[0];
        // Schema order of the building's properties.
        let order: Vec<&str> = house
            .children
            .iter()
            .map(|c| c.name.as_str())
            .filter(|n| {
                n.starts_with("bldg:")
                    && !n.ends_with("Height")
                    && *n != "bldg:roofType"
                    && *n != "bldg:storeysAboveGround"
            })
            .collect();
        let first = |n: &str| order.iter().position(|x| *x == n).unwrap();
        let last = |n: &str| order.iter().rposition(|x| *x == n).unwrap();
        assert!(last("bldg:interiorBuildingInstallation") < first("bldg:boundedBy"));
        assert!(last("bldg:boundedBy") < first("bldg:lod4Solid"));
        assert!(first("bldg:lod4Solid") < first("bldg:interiorRoom"));
        let stairs = house.find_all("bldg:IntBuildingInstallation");
        assert_eq!(stairs.len(), 1);
        assert_eq!(stairs[0].child("bldg:class").unwrap().text, "stairs");
        assert_eq!(stairs[0].count("gml:Polygon"), 17 * 6);

        // Every polygon by id.
        let polys: BTreeMap<&str, &El> = doc
            .find_all("gml:Polygon")
            .into_iter()
            .map(|p| (p.attr("gml:id").unwrap(), p))
            .collect();
        let rooms = house.find_all("bldg:Room");
        assert_eq!(rooms.len(), 6);
        let mut doors = BTreeSet::new();
        let mut holes = 0;
        for room in &rooms {
            assert!(room.child("gml:name").is_some() && room.child("bldg:usage").is_some());
            let kinds: Vec<&str> = room
                .children_named("bldg:boundedBy")
                .map(|b| b.children[0].name.as_str())
                .collect();
            assert_eq!(kinds[..2], ["bldg:FloorSurface", "bldg:CeilingSurface"]);
            assert!(kinds[2..].iter().all(|k| *k == "bldg:InteriorWallSurface"));
            // The solid's members, resolved (reversed for "-"), close: every directed edge has
            // its reverse exactly once.
            let solid = room.child("bldg:lod4Solid").unwrap();
            let mut edges: BTreeMap<([i64; 3], [i64; 3]), i32> = BTreeMap::new();
            for m in solid.find_all("gml:surfaceMember") {
                let (href, reversed) = match m.attr("xlink:href") {
                    Some(h) => (h, false),
                    None => {
                        let o = m.child("gml:OrientableSurface").unwrap();
                        assert_eq!(o.attr("orientation"), Some("-"));
                        (
                            o.child("gml:baseSurface")
                                .unwrap()
                                .attr("xlink:href")
                                .unwrap(),
                            true,
                        )
                    }
                };
                for mut r in rings(polys[href.trim_start_matches('#')]) {
                    if reversed {
                        r.reverse();
                    }
                    for i in 0..r.len() {
                        *edges.entry((r[i], r[(i + 1) % r.len()])).or_default() += 1;
                    }
                }
            }
            for ((a, b), n) in &edges {
                assert_eq!(*n, 1, "edge used once per direction");
                assert_eq!(
                    edges.get(&(*b, *a)),
                    Some(&1),
                    "edge {a:?}-{b:?} not closed"
                );
            }
            for w in room.find_all("bldg:InteriorWallSurface") {
                holes += w.count("gml:interior")
                    - w.find_all("bldg:Door")
                        .iter()
                        .map(|d| d.count("gml:interior"))
                        .sum::<usize>();
                for o in w.children_named("bldg:opening") {
                    let id = match o.attr("xlink:href") {
                        Some(h) => h.trim_start_matches('#').to_string(),
                        None => o
                            .child("bldg:Door")
                            .unwrap()
                            .attr("gml:id")
                            .unwrap()
                            .to_string(),
                    };
                    doors.insert(id);
                }
            }
        }
        // 2 doors per storey, each cutting both its rooms.
        assert_eq!(doors.len(), 4);
        assert_eq!(
            house.count("bldg:Door"),
            4 + 1,
            "interior doors once, plus the front door"
        );
        assert_eq!(holes, 8);
        // Materials target only polygons that exist.
        for t in doc.find_all("app:target") {
            assert!(
                polys.contains_key(t.text.trim_start_matches('#')),
                "{}",
                t.text
            );
        }
    }

    /// The reference validator (CityGML 2.0 XSDs) on the LOD4 sample, when installed.
    /// `CITYGEN_GML_LOD4_SAMPLE=path` keeps the file.
    #[test]
    fn lod4_sample_validates() {
        let bytes = write_all(Lod::Lod4, &fixtures::lod4_all());
        if let Some(keep) = std::env::var_os("CITYGEN_GML_LOD4_SAMPLE") {
            std::fs::write(keep, &bytes).unwrap();
        }
        let Some(tool) = fixtures::validator("CityGML LOD4 sample") else {
            return;
        };
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("lod4.gml");
        std::fs::write(&path, bytes).unwrap();
        let out = std::process::Command::new(tool)
            .arg(&path)
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(out.status.success() && text.contains(" 0 failed"), "{text}");
        assert!(text.contains("Room=6"), "{text}");
    }
}

#[test]
fn element_count_is_the_same_however_the_stream_is_cut() {
    let xml = b"<?xml version=\"1.0\"?><!-- c --><a x=\"1\"><b/><c>t</c><d><e/></d></a><";
    // a, b, c, d, e, and the trailing `<` whose next byte never comes: 5.
    let whole = count_elements(xml, &mut false);
    assert_eq!(whole, 5);
    for cut in 0..=xml.len() {
        let mut after_lt = false;
        let n = count_elements(&xml[..cut], &mut after_lt)
            + count_elements(&[], &mut after_lt)
            + count_elements(&xml[cut..], &mut after_lt);
        assert_eq!(n, whole, "cut at {cut}");
    }
    // A `<` at the end of one piece and `/` at the start of the next is a closing tag.
    let mut after_lt = false;
    assert_eq!(count_elements(b"<a><", &mut after_lt), 1);
    assert!(after_lt);
    assert_eq!(count_elements(b"/a>", &mut after_lt), 0);
}

#[test]
fn rings_are_written_without_repeats_or_spikes_after_rounding() {
    use super::xml::written_ring;
    let o = DVec3::new(500_000.0, 4_000_000.0, 0.0);
    let p = |x: f64, y: f64| DVec3::new(x, y, 3.0);
    // 0.3 mm apart (one point once rounded), a spike out and back, the closing repeat.
    let ring = vec![
        p(0.0, 0.0),
        p(0.0003, 0.0),
        p(10.0, 0.0),
        p(10.0, 5.0),
        p(12.0, 5.0),
        p(10.0, 5.0),
        p(10.0, 10.0),
        p(0.0, 10.0),
        p(0.0, 0.0),
    ];
    let w = written_ring(&ring, o);
    assert_eq!(
        w,
        vec![
            p(0.0, 0.0),
            p(10.0, 0.0),
            p(10.0, 5.0),
            p(10.0, 10.0),
            p(0.0, 10.0)
        ]
    );
    // A ring that rounds to nothing keeps its points (the polygon is referenced elsewhere).
    let tiny = vec![p(0.0, 0.0), p(0.0001, 0.0), p(0.0, 0.0001)];
    assert!(written_ring(&tiny, o).len() < 3);
}

/// Provenance is written as generic attributes: sources as strings, uncertainties as doubles,
/// an unknown uncertainty left out.
#[test]
fn provenance_is_written_as_generic_attributes() {
    let mut b = simple_box();
    b.provenance = crate::export::fixtures::model_provenance();
    let mut tagged = two_parts();
    tagged.provenance = crate::model::Provenance {
        storeys: crate::model::ValueSource::Tag,
        height: crate::model::ValueSource::Tag,
        roof: crate::model::ValueSource::Tag,
        ..Default::default()
    };
    let root = parse(&write_all(Lod::Lod2, &[b, tagged]));
    let of = |el: &El, kind: &str| -> BTreeMap<String, String> {
        el.children_named(kind)
            .map(|a| {
                let v = a.child("gen:value").unwrap().text.clone();
                (a.attr("name").unwrap().to_string(), v)
            })
            .collect()
    };
    let bs = buildings_of(&root);
    let strings = of(bs[0], "gen:stringAttribute");
    assert_eq!(strings["storeysSource"], "model");
    assert_eq!(strings["heightSource"], "model");
    assert_eq!(strings["roofSource"], "kb");
    let doubles = of(bs[0], "gen:doubleAttribute");
    assert_eq!(doubles["storeysError"], "0.750");
    assert_eq!(doubles["heightError"], "2.250");
    assert_eq!(doubles["roofProbability"], "0.800");
    let strings = of(bs[1], "gen:stringAttribute");
    assert_eq!(
        ["storeysSource", "heightSource", "roofSource"].map(|k| strings[k].as_str()),
        ["tag"; 3]
    );
    assert!(of(bs[1], "gen:doubleAttribute").is_empty());
}
