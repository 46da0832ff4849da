use std::collections::BTreeMap;

use glam::{DVec2, DVec3};

use super::roofs::is_closed_shell;
use super::*;
use crate::color::Color;
use crate::crs::Crs;
use crate::export::step::global_id;
use crate::geometry::Polygon;
use crate::model::{Balcony, Face, Lod, Opening, OpeningKind, Part, PartRole, SourceId, Wall};

const RED: Color = Color::rgb(0.8, 0.2, 0.1);
const BEIGE: Color = Color::rgb(0.96, 0.96, 0.86);

fn ctx() -> OutputContext {
    OutputContext {
        crs: Crs::Lambert93,
        origin: DVec3::new(574_000.0, 6_280_000.0, 150.0),
        origin_lonlat: (1.444, -43.6045),
        lod: Lod::Lod2,
        source_name: "test.osm.pbf".into(),
        seed: 7,
        vertical_datum: None,
        terrain: None,
    }
}

fn rect(x0: f64, y0: f64, w: f64, h: f64) -> Vec<DVec2> {
    vec![
        DVec2::new(x0, y0),
        DVec2::new(x0 + w, y0),
        DVec2::new(x0 + w, y0 + h),
        DVec2::new(x0, y0 + h),
    ]
}

/// One rectangular wall per footprint edge, `base`..`eave`, 0.3 m thick.
fn walls(fp: &Polygon, base: f64, eave: f64) -> Vec<Wall> {
    let mut out = Vec::new();
    for ring in fp.rings() {
        for i in 0..ring.len() {
            let (a, b) = (ring[i], ring[(i + 1) % ring.len()]);
            out.push(Wall {
                start: a,
                end: b,
                base_z: base,
                top_z: eave,
                thickness: 0.3,
                outline: Face::new(vec![
                    a.extend(base),
                    b.extend(base),
                    b.extend(eave),
                    a.extend(eave),
                ]),
                storey: 0,
                openings: Vec::new(),
                balconies: Vec::new(),
                party: 0.0,
            });
        }
    }
    out
}

fn lift(r: &[DVec2], z: f64) -> Vec<DVec3> {
    r.iter().map(|p| p.extend(z)).collect()
}

fn ground(fp: &Polygon, base: f64) -> Face {
    let rev = |r: &Vec<DVec2>| r.iter().rev().map(|p| p.extend(base)).collect::<Vec<_>>();
    Face {
        outer: rev(&fp.outer),
        holes: fp.holes.iter().map(rev).collect(),
    }
}

fn flat_part(key: &str, fp: Polygon, base: f64, top: f64, storeys: u32) -> Part {
    let roof = Face {
        outer: lift(&fp.outer, top),
        holes: fp.holes.iter().map(|h| lift(h, top)).collect(),
    };
    Part {
        key: key.into(),
        walls: walls(&fp, base, top),
        ground: ground(&fp, base),
        interior: Vec::new(),
        source: None,
        role: PartRole::Own,
        structure: None,
        rhythm: None,
        cornice: None,
        eaves: None,
        footprint: fp,
        base_z: base,
        eave_z: top,
        top_z: top,
        storeys,
        levels: crate::derive::massing::even_levels(base, top, storeys),
        wall_color: BEIGE,
        roof_color: RED,
        wall_material: Default::default(),
        roof_material: Default::default(),
        roof_shape: RoofShape::Flat,
        roof: vec![roof],
    }
}

fn building(id: SourceId, name: Option<&str>, parts: Vec<Part>) -> Building {
    let base = parts.iter().map(|p| p.base_z).fold(f64::INFINITY, f64::min);
    let top = parts
        .iter()
        .map(|p| p.top_z)
        .fold(f64::NEG_INFINITY, f64::max);
    Building {
        id,
        name: name.map(String::from),
        zone: "earth/France/Occitanie/Toulouse".into(),
        appearance: "Toulouse#1".into(),
        base_z: base,
        ground_z: base,
        measured_height: top - base,
        storeys_above_ground: parts.iter().map(|p| p.storeys).max().unwrap_or(1),
        roof_shape: parts[0].roof_shape,
        parts,
        lod: Lod::Lod2,
        facade: Default::default(),
        provenance: Default::default(),
        attributes: None,
    }
}

/// A box, a two-part building, a courtyard, a hipped roof and a gabled roof with gable walls.
fn sample() -> Vec<Building> {
    let boxb = building(
        SourceId::Way(1),
        Some("Capitole d'Été"),
        vec![flat_part(
            "p0",
            Polygon::new(rect(0.0, 0.0, 10.0, 6.0), vec![]),
            0.0,
            9.0,
            3,
        )],
    );
    let two = building(
        SourceId::Way(2),
        None,
        vec![
            flat_part(
                "p0",
                Polygon::new(rect(20.0, 0.0, 10.0, 6.0), vec![]),
                0.0,
                6.0,
                2,
            ),
            flat_part(
                "p1",
                Polygon::new(rect(30.0, 0.0, 5.0, 6.0), vec![]),
                2.0,
                12.0,
                3,
            ),
        ],
    );
    let court = building(
        SourceId::Relation(3),
        None,
        vec![flat_part(
            "p0",
            Polygon::new(
                rect(0.0, 20.0, 20.0, 20.0),
                vec![rect(5.0, 25.0, 10.0, 10.0)],
            ),
            1.0,
            7.0,
            2,
        )],
    );

    // Hipped: 10 x 6, eave 6, ridge (3,3)-(7,3) at 9.
    let fp = Polygon::new(rect(40.0, 0.0, 10.0, 6.0), vec![]);
    let p = |x: f64, y: f64, z: f64| DVec3::new(40.0 + x, y, z);
    let mut hip = flat_part("p0", fp, 0.0, 6.0, 2);
    hip.top_z = 9.0;
    hip.roof_shape = RoofShape::Hipped;
    hip.roof = vec![
        Face::new(vec![
            p(0.0, 0.0, 6.0),
            p(10.0, 0.0, 6.0),
            p(7.0, 3.0, 9.0),
            p(3.0, 3.0, 9.0),
        ]),
        Face::new(vec![p(10.0, 0.0, 6.0), p(10.0, 6.0, 6.0), p(7.0, 3.0, 9.0)]),
        Face::new(vec![
            p(10.0, 6.0, 6.0),
            p(0.0, 6.0, 6.0),
            p(3.0, 3.0, 9.0),
            p(7.0, 3.0, 9.0),
        ]),
        Face::new(vec![p(0.0, 6.0, 6.0), p(0.0, 0.0, 6.0), p(3.0, 3.0, 9.0)]),
    ];
    let hip = building(SourceId::Way(4), None, vec![hip]);

    // Gabled: 10 x 6, eave 6, ridge along x at y = 3, z = 8; east and west walls are gables.
    let fp = Polygon::new(rect(60.0, 0.0, 10.0, 6.0), vec![]);
    let p = |x: f64, y: f64, z: f64| DVec3::new(60.0 + x, y, z);
    let mut gab = flat_part("p0", fp, 0.0, 6.0, 2);
    gab.top_z = 8.0;
    gab.roof_shape = RoofShape::Gabled;
    gab.roof = vec![
        Face::new(vec![
            p(0.0, 0.0, 6.0),
            p(10.0, 0.0, 6.0),
            p(10.0, 3.0, 8.0),
            p(0.0, 3.0, 8.0),
        ]),
        Face::new(vec![
            p(10.0, 6.0, 6.0),
            p(0.0, 6.0, 6.0),
            p(0.0, 3.0, 8.0),
            p(10.0, 3.0, 8.0),
        ]),
    ];
    for w in &mut gab.walls {
        if (w.start.x - w.end.x).abs() < 1e-9 {
            let (a, b) = (w.start, w.end);
            let apex = (a + b) / 2.0;
            w.outline = Face::new(vec![
                a.extend(0.0),
                b.extend(0.0),
                b.extend(6.0),
                apex.extend(8.0),
                a.extend(6.0),
            ]);
        }
    }
    let gab = building(SourceId::Way(5), Some("Gable"), vec![gab]);

    // Skillion: 8 x 5, eave 3 on the south, 5 on the north; east and west walls trapezoids.
    let fp = Polygon::new(rect(80.0, 0.0, 8.0, 5.0), vec![]);
    let p = |x: f64, y: f64, z: f64| DVec3::new(80.0 + x, y, z);
    let mut shed = flat_part("p0", fp, 0.0, 3.0, 1);
    shed.top_z = 5.0;
    shed.roof_shape = RoofShape::Skillion;
    shed.roof = vec![Face::new(vec![
        p(0.0, 0.0, 3.0),
        p(8.0, 0.0, 3.0),
        p(8.0, 5.0, 5.0),
        p(0.0, 5.0, 5.0),
    ])];
    let height_at = |q: DVec2| 3.0 + 2.0 * q.y / 5.0;
    for w in &mut shed.walls {
        let (a, b) = (w.start, w.end);
        w.top_z = height_at(a).min(height_at(b));
        w.outline = Face::new(vec![
            a.extend(0.0),
            b.extend(0.0),
            b.extend(height_at(b)),
            a.extend(height_at(a)),
        ]);
    }
    let shed = building(SourceId::Way(6), None, vec![shed]);
    vec![boxb, two, court, hip, gab, shed]
}

fn write_all(buildings: &[Building]) -> Vec<u8> {
    write_all_named(buildings, "sample.ifc")
}

fn write_all_named(buildings: &[Building], name: &str) -> Vec<u8> {
    let mut w = IfcWriter::new(Vec::new()).with_file_name(name);
    w.begin(&ctx()).unwrap();
    for b in buildings {
        w.write(b).unwrap();
    }
    w.finish().unwrap();
    w.into_inner().unwrap()
}

/// The DATA section as id -> (keyword, raw arguments).
fn parse(bytes: &[u8]) -> BTreeMap<u64, (String, String)> {
    let text = std::str::from_utf8(bytes).unwrap();
    assert!(text.is_ascii(), "STEP files are 7-bit");
    let data = text.split("DATA;\n").nth(1).unwrap();
    let mut out = BTreeMap::new();
    for line in data.lines().take_while(|l| *l != "ENDSEC;") {
        let (id, rest) = line.split_once('=').unwrap();
        let id: u64 = id.trim_start_matches('#').parse().unwrap();
        let (kw, args) = rest.split_once('(').unwrap();
        let args = args.strip_suffix(");").unwrap();
        assert!(
            out.insert(id, (kw.to_string(), args.to_string())).is_none(),
            "#{id} defined twice"
        );
    }
    out
}

/// `#n` references in an argument string (outside string literals).
fn refs(args: &str) -> Vec<u64> {
    let mut out = Vec::new();
    let mut in_str = false;
    let b = args.as_bytes();
    let mut i = 0;
    while i < b.len() {
        match b[i] {
            b'\'' => in_str = !in_str,
            b'#' if !in_str => {
                let j = b[i + 1..]
                    .iter()
                    .position(|c| !c.is_ascii_digit())
                    .map_or(b.len(), |k| i + 1 + k);
                out.push(args[i + 1..j].parse().unwrap());
                i = j;
                continue;
            }
            _ => {}
        }
        i += 1;
    }
    out
}

fn count(m: &BTreeMap<u64, (String, String)>, kw: &str) -> usize {
    m.values().filter(|(k, _)| k == kw).count()
}

#[test]
fn structure_and_references() {
    let bs = sample();
    let bytes = write_all(&bs);
    let m = parse(&bytes);
    for (id, (_, args)) in &m {
        for r in refs(args) {
            assert!(m.contains_key(&r), "#{id} refers to undefined #{r}");
            assert!(r < *id, "#{id} refers forward to #{r}");
        }
    }
    let total_walls: usize = bs
        .iter()
        .flat_map(|b| &b.parts)
        .map(|p| p.walls.len())
        .sum();
    assert_eq!(count(&m, "IFCWALLSTANDARDCASE"), total_walls);
    // 6 buildings + 2 partial.
    assert_eq!(count(&m, "IFCBUILDING"), 8);
    assert_eq!(
        m.values()
            .filter(|(k, a)| k == "IFCBUILDING" && a.contains(".PARTIAL."))
            .count(),
        2
    );
    // Every building, partial ones too, carries its base quantities.
    for (id, _) in m.iter().filter(|(_, (k, _))| k == "IFCBUILDING") {
        let n = m
            .values()
            .filter(|(k, a)| k == "IFCRELDEFINESBYPROPERTIES" && refs(a).contains(id))
            .filter(|(_, a)| {
                let q = &m[refs(a).last().unwrap()];
                q.0 == "IFCELEMENTQUANTITY" && q.1.contains("'Qto_BuildingBaseQuantities'")
            })
            .count();
        assert_eq!(n, 1, "building #{id}");
    }
    let storeys: u32 = bs.iter().flat_map(|b| &b.parts).map(|p| p.storeys).sum();
    assert_eq!(count(&m, "IFCBUILDINGSTOREY"), storeys as usize);
    assert_eq!(count(&m, "IFCSLAB"), 7);
    assert_eq!(count(&m, "IFCROOF"), 7);
    assert_eq!(count(&m, "IFCPROJECT"), 1);
    assert_eq!(count(&m, "IFCSITE"), 1);
    // Hipped roof closes into one brep; gabled and skillion stay surface models.
    assert_eq!(count(&m, "IFCSHELLBASEDSURFACEMODEL"), 2);
    // Gable and skillion side walls are extruded outline profiles; 6 slabs have no voids.
    assert_eq!(count(&m, "IFCARBITRARYCLOSEDPROFILEDEF"), 4 + 6);
    assert_eq!(count(&m, "IFCARBITRARYPROFILEDEFWITHVOIDS"), 1);
    // Shared styles and material usages: 2 colours, 1 thickness.
    assert_eq!(count(&m, "IFCSURFACESTYLE"), 2);
    assert_eq!(count(&m, "IFCMATERIALLAYERSETUSAGE"), 1);
    // Every wall has exactly one material layer set usage.
    for (id, _) in m.iter().filter(|(_, (k, _))| k == "IFCWALLSTANDARDCASE") {
        let n = m
            .values()
            .filter(|(k, a)| k == "IFCRELASSOCIATESMATERIAL" && refs(a).contains(id))
            .filter(|(_, a)| m[refs(a).last().unwrap()].0 == "IFCMATERIALLAYERSETUSAGE")
            .count();
        assert_eq!(n, 1, "wall #{id}");
    }
    // GlobalIds: unique, 22 characters.
    let mut gids = BTreeSet::new();
    for (k, a) in m.values() {
        if k.starts_with("IFCREL")
            || [
                "IFCPROJECT",
                "IFCSITE",
                "IFCBUILDING",
                "IFCWALLSTANDARDCASE",
            ]
            .contains(&k.as_str())
        {
            let g = a.split(',').next().unwrap();
            assert_eq!(g.len(), 24, "{k} {g}");
            assert!(gids.insert(g.to_string()), "duplicate GlobalId {g}");
        }
    }
    let text = String::from_utf8(bytes).unwrap();
    assert!(text.contains("'Capitole d''\\X2\\00C9\\X0\\t\\X2\\00E9\\X0\\'"));
    assert!(
        text.contains("IFCMAPCONVERSION(") && text.contains(",574000.,6280000.,150.,1.,0.,1.);")
    );
    assert!(text.contains("'EPSG:2154'"));
    // Latitude -43.6045 = -43 deg 36' 16.2".
    assert!(text.contains("(-43,-36,-16,-200000)"), "{text}");
    assert!(text.contains("FILE_SCHEMA(('IFC4'));"));
}

/// Hash of a file's DATA section (the header carries a time stamp and the crate version),
/// to pin LOD1/LOD2 output byte for byte.
fn file_hash(bytes: &[u8]) -> String {
    let text = std::str::from_utf8(bytes).unwrap();
    let data = text.split_once("DATA;").unwrap().1;
    format!("{:032x}", crate::export::step::hash128("file", data))
}

/// LOD1 and LOD2 files are byte-identical to those written before LOD3 was added (hashes
/// of the sample taken at that commit; taken again when every building got its provenance
/// properties, issue 42: without them the files differed only in the GlobalIds of the
/// material associations, which follow entity numbers; and again when every partial building
/// got its `Citygen_Part` numbers, issue 45, and buildings and storeys their base quantities,
/// issue 47, and the partial buildings theirs).
#[test]
fn lod1_and_lod2_output_is_unchanged() {
    let bs = sample();
    let mut got = Vec::new();
    for lod in [Lod::Lod1, Lod::Lod2] {
        let mut w = IfcWriter::new(Vec::new()).with_file_name("sample.ifc");
        w.begin(&OutputContext { lod, ..ctx() }).unwrap();
        for b in &bs {
            w.write(b).unwrap();
        }
        w.finish().unwrap();
        got.push(file_hash(&w.into_inner().unwrap()));
    }
    assert_eq!(
        got,
        [
            "a87e50381aeffa02aa6323d7d00c1aaa",
            "a3ec373b6e45cb68c92bde0bd89712bf"
        ]
    );
}

#[test]
fn output_is_deterministic() {
    let bs = sample();
    assert_eq!(write_all(&bs), write_all(&bs));
}

#[test]
fn repeated_keys_still_get_unique_global_ids() {
    let b = sample().remove(0);
    let bytes = write_all(&[b.clone(), b]);
    let m = parse(&bytes);
    let gids: Vec<&str> = m
        .values()
        .filter(|(k, _)| k == "IFCWALLSTANDARDCASE")
        .map(|(_, a)| a.split(',').next().unwrap())
        .collect();
    assert_eq!(gids.len(), 8);
    assert_eq!(gids.iter().collect::<BTreeSet<_>>().len(), 8);
}

#[test]
fn misuse_and_bad_geometry_are_errors() {
    let mut w = IfcWriter::new(Vec::new());
    let b = sample().remove(0);
    assert!(w.write(&b).is_err());
    assert!(w.finish().is_err());
    w.begin(&ctx()).unwrap();
    assert!(w.begin(&ctx()).is_err());
    let mut bad = b.clone();
    bad.parts[0].walls[0].top_z = f64::NAN;
    let err = w.write(&bad).unwrap_err().to_string();
    assert!(err.contains("way/1"), "{err}");
    w.write(&b).unwrap();
    w.finish().unwrap();
    assert!(w.write(&b).is_err());
    let m = parse(&w.into_inner().unwrap());
    assert_eq!(
        count(&m, "IFCWALLSTANDARDCASE"),
        4,
        "nothing of the bad building was written"
    );
}

#[test]
fn empty_file_is_complete() {
    let bytes = write_all(&[]);
    let m = parse(&bytes);
    assert_eq!(count(&m, "IFCBUILDING"), 0);
    assert!(String::from_utf8(bytes)
        .unwrap()
        .ends_with("ENDSEC;\nEND-ISO-10303-21;\n"));
}

#[test]
fn compound_angles_carry_the_sign() {
    assert_eq!(compound_angle(43.6045), Some([43, 36, 16, 200_000]));
    assert_eq!(compound_angle(-0.5), Some([0, -30, 0, 0]));
    assert_eq!(compound_angle(0.0), Some([0, 0, 0, 0]));
    assert_eq!(compound_angle(359.999_999_999_9), None);
    assert_eq!(compound_angle(f64::NAN), None);
}

#[test]
fn closed_shell_detection() {
    let p = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    // A tetrahedron, outward faces.
    let (a, b, c, d) = (
        p(0.0, 0.0, 0.0),
        p(1.0, 0.0, 0.0),
        p(0.0, 1.0, 0.0),
        p(0.0, 0.0, 1.0),
    );
    let tet = vec![
        vec![vec![a, c, b]],
        vec![vec![a, b, d]],
        vec![vec![b, c, d]],
        vec![vec![c, a, d]],
    ];
    assert!(is_closed_shell(&tet));
    assert!(!is_closed_shell(&tet[..3]));
    let mut flipped = tet.clone();
    flipped[0][0].reverse();
    assert!(!is_closed_shell(&flipped));
}

/// Runs the reference validator (schema, WHERE rules and, with `--geometry`, the geometry
/// kernel on every product) on the sample when it is installed; skipped otherwise.
#[test]
fn sample_passes_the_reference_validator() {
    let Some(tool) = crate::testkit::validators::validate_outputs("IFC sample") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sample.ifc");
    std::fs::write(&path, write_all(&sample())).unwrap();
    let out = std::process::Command::new(tool)
        .arg("--geometry")
        .arg(&path)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success() && text.contains(" 0 failed"), "{text}");
    assert!(text.contains("WallStandardCase=32"), "{text}");
}

#[test]
fn writes_through_an_atomic_file() {
    let dir = tempfile::tempdir().unwrap();
    let target = dir.path().join("out.ifc");
    let file = crate::export::AtomicFile::create(&target).unwrap();
    let mut w = Box::new(IfcWriter::new(file.writer().unwrap()).with_file_name("out.ifc"));
    w.begin(&ctx()).unwrap();
    for b in sample() {
        w.write(&b).unwrap();
    }
    w.finish().unwrap();
    drop(w);
    file.commit().unwrap();
    assert_eq!(
        std::fs::read(&target).unwrap(),
        write_all_named(&sample(), "out.ifc")
    );
    // The writer is usable as a trait object, as the pipeline holds it.
    let _: Box<dyn BuildingWriter> = Box::new(IfcWriter::new(Vec::new()));
}

// ---- LOD3 ----

fn lod3_ctx() -> OutputContext {
    OutputContext {
        lod: Lod::Lod3,
        ..ctx()
    }
}

/// Turns a LOD2-style part (one wall per edge) into LOD3 walls: one per storey and edge,
/// storey i from `levels[i]` to the next level (the top one keeps the full wall's outline,
/// its base raised), like the model does.
fn storeyed(mut part: Part, levels: &[f64]) -> Part {
    let mut walls = Vec::new();
    for (s, &lo) in levels.iter().enumerate() {
        let top = s + 1 == levels.len();
        for full in &part.walls {
            let mut w = full.clone();
            w.storey = s;
            w.base_z = lo;
            if top {
                for p in &mut w.outline.outer {
                    if (p.z - full.base_z).abs() < 1e-9 {
                        p.z = lo;
                    }
                }
            } else {
                let hi = levels[s + 1];
                w.top_z = hi;
                let (a, b) = (w.start, w.end);
                w.outline = Face::new(vec![a.extend(lo), b.extend(lo), b.extend(hi), a.extend(hi)]);
            }
            walls.push(w);
        }
    }
    part.walls = walls;
    part.levels = levels.to_vec();
    part.storeys = levels.len() as u32;
    part
}

/// Adds an opening to wall `i` of `part`, with its hole in the outline.
fn open(part: &mut Part, i: usize, kind: OpeningKind, u: (f64, f64), z: (f64, f64)) {
    let w = &mut part.walls[i];
    let dir = (w.end - w.start).normalize();
    let p = |u: f64, z: f64| (w.start + dir * u).extend(z);
    w.outline
        .holes
        .push(vec![p(u.0, z.0), p(u.0, z.1), p(u.1, z.1), p(u.1, z.0)]);
    w.openings.push(Opening {
        kind,
        u0: u.0,
        u1: u.1,
        z0: z.0,
        z1: z.1,
        color: match kind {
            OpeningKind::Window => Color::rgb(0.6, 0.8, 1.0),
            OpeningKind::Door => Color::rgb(0.4, 0.25, 0.1),
        },
        frame_color: Color::rgb(1.0, 1.0, 1.0),
        glazed: kind == OpeningKind::Window,
        framed: true,
        frame_size: None,
        rounding: None,
    });
}

fn lod3(mut b: Building) -> Building {
    b.lod = Lod::Lod3;
    b
}

/// A 10 x 6 m box with 2 storeys, 4 windows and a door on the front (south) wall; a
/// courtyard building with windows on the outer and the courtyard walls; a building with a
/// balcony and a balcony door; a gabled house with a window in a gable wall.
fn lod3_sample() -> Vec<Building> {
    use OpeningKind::{Door, Window};
    let fp = Polygon::new(rect(0.0, 0.0, 10.0, 6.0), vec![]);
    let mut p = storeyed(flat_part("p0", fp, 0.0, 6.0, 2), &[0.0, 3.0]);
    // Walls 0..4 are storey 0 (south, east, north, west), 4..8 storey 1.
    open(&mut p, 0, Window, (1.0, 2.2), (0.9, 2.4));
    open(&mut p, 0, Door, (4.4, 5.6), (0.05, 2.3));
    open(&mut p, 0, Window, (7.8, 9.0), (0.9, 2.4));
    open(&mut p, 4, Window, (1.0, 2.2), (3.9, 5.4));
    open(&mut p, 4, Window, (7.8, 9.0), (3.9, 5.4));
    let boxb = lod3(building(SourceId::Way(1), Some("Box"), vec![p]));

    let fp = Polygon::new(
        rect(0.0, 20.0, 20.0, 20.0),
        vec![rect(5.0, 25.0, 10.0, 10.0)],
    );
    let mut p = storeyed(flat_part("p0", fp, 1.0, 7.0, 2), &[1.0, 4.0]);
    // 8 walls per storey: 4 outer, then 4 of the courtyard (clockwise).
    open(&mut p, 0, Window, (2.0, 3.2), (2.0, 3.5));
    open(&mut p, 4, Window, (4.0, 5.2), (2.0, 3.5));
    open(&mut p, 8 + 5, Window, (4.0, 5.2), (5.0, 6.5));
    open(&mut p, 8 + 6, Door, (1.0, 2.0), (4.05, 6.2));
    let court = lod3(building(SourceId::Relation(3), None, vec![p]));

    let fp = Polygon::new(rect(30.0, 0.0, 8.0, 5.0), vec![]);
    let mut p = storeyed(flat_part("p0", fp, 0.0, 6.0, 2), &[0.0, 3.0]);
    open(&mut p, 4, Door, (3.4, 4.4), (3.05, 5.2));
    open(&mut p, 4, Window, (5.0, 6.2), (3.9, 5.4));
    p.walls[4].balconies.push(Balcony {
        u0: 2.0,
        u1: 7.0,
        z: 3.0,
        depth: 1.2,
        color: Color::rgb(0.5, 0.5, 0.5),
    });
    let balc = lod3(building(SourceId::Way(7), None, vec![p]));

    // The gabled house of `sample()`: the east wall of the top storey is a pentagon.
    let mut gab = sample().remove(4);
    let part = gab.parts.remove(0);
    let mut p = storeyed(part, &[0.0, 3.0]);
    assert_eq!(p.walls[5].outline.outer.len(), 5, "east gable of storey 1");
    open(&mut p, 5, Window, (2.4, 3.6), (3.6, 5.4));
    open(&mut p, 1, Window, (2.4, 3.6), (0.9, 2.4));
    gab.parts.push(p);
    vec![boxb, court, balc, lod3(gab)]
}

fn write_lod3(buildings: &[Building]) -> Vec<u8> {
    write_lod3_limited(buildings, SHARED_CACHE_LIMIT)
}

fn write_lod3_limited(buildings: &[Building], limit: usize) -> Vec<u8> {
    let mut w = IfcWriter::new(Vec::new()).with_file_name("lod3.ifc");
    w.cache_limit = limit;
    w.begin(&lod3_ctx()).unwrap();
    for b in buildings {
        w.write(b).unwrap();
    }
    w.finish().unwrap();
    w.into_inner().unwrap()
}

/// Ids of the entities of keyword `kw`.
fn ids_of(m: &BTreeMap<u64, (String, String)>, kw: &str) -> Vec<u64> {
    m.iter()
        .filter(|(_, (k, _))| k == kw)
        .map(|(id, _)| *id)
        .collect()
}

/// The GlobalId (first argument) of an entity.
fn gid_of(m: &BTreeMap<u64, (String, String)>, id: u64) -> String {
    m[&id]
        .1
        .split(',')
        .next()
        .unwrap()
        .trim_matches('\'')
        .to_string()
}

#[test]
fn lod3_openings_are_voided_filled_and_typed() {
    let bs = lod3_sample();
    let m = parse(&write_lod3(&bs));
    for (id, (_, args)) in &m {
        for r in refs(args) {
            assert!(m.contains_key(&r) && r < *id, "#{id} -> #{r}");
        }
    }
    let (windows, doors) = bs
        .iter()
        .flat_map(|b| &b.parts)
        .flat_map(|p| &p.walls)
        .flat_map(|w| &w.openings)
        .fold((0, 0), |(w, d), o| match o.kind {
            OpeningKind::Window => (w + 1, d),
            OpeningKind::Door => (w, d + 1),
        });
    assert_eq!((windows, doors), (10, 3));
    assert_eq!(count(&m, "IFCWINDOW"), windows);
    assert_eq!(count(&m, "IFCDOOR"), doors);
    let openings = ids_of(&m, "IFCOPENINGELEMENT");
    assert_eq!(openings.len(), windows + doors);
    let rels = |kw: &str| -> Vec<Vec<u64>> {
        m.values()
            .filter(|(k, _)| k == kw)
            .map(|(_, a)| refs(a))
            .collect()
    };
    let voids = rels("IFCRELVOIDSELEMENT");
    let fills = rels("IFCRELFILLSELEMENT");
    for o in &openings {
        assert!(m[o].1.ends_with(".OPENING."), "{}", m[o].1);
        let v: Vec<_> = voids.iter().filter(|r| r[1] == *o).collect();
        assert_eq!(v.len(), 1, "opening #{o} voids one wall");
        assert_eq!(m[&v[0][0]].0, "IFCWALLSTANDARDCASE");
        let f: Vec<_> = fills.iter().filter(|r| r[0] == *o).collect();
        assert_eq!(f.len(), 1, "opening #{o} is filled once");
        assert!(["IFCWINDOW", "IFCDOOR"].contains(&m[&f[0][1]].0.as_str()));
        // Placements: the opening relative to its wall's, the filler relative to the
        // opening's.
        let pl = |id: u64| refs(&m[&id].1)[0];
        let rel_to = |pl: u64| refs(&m[&pl].1)[0];
        assert_eq!(rel_to(pl(*o)), pl(v[0][0]));
        assert_eq!(rel_to(pl(f[0][1])), pl(*o));
    }
    // Every window and door is filled once and typed once, by a type of its kind that has
    // one representation map, used through a mapped item.
    let by_type = rels("IFCRELDEFINESBYTYPE");
    for kw in ["IFCWINDOW", "IFCDOOR"] {
        for id in ids_of(&m, kw) {
            assert_eq!(fills.iter().filter(|r| r[1] == id).count(), 1);
            let t: Vec<_> = by_type.iter().filter(|r| r.contains(&id)).collect();
            assert_eq!(t.len(), 1, "{kw} #{id} has one type");
            let ty = *t[0].last().unwrap();
            assert_eq!(m[&ty].0, format!("{kw}TYPE"));
            let maps = refs(&m[&ty].1);
            assert_eq!(maps.len(), 1, "one representation map");
            assert_eq!(m[&maps[0]].0, "IFCREPRESENTATIONMAP");
            let shape = refs(&m[&id].1)[1];
            let rep = refs(&m[&shape].1)[0];
            assert!(m[&rep].1.contains("'MappedRepresentation'"));
            let item = *refs(&m[&rep].1).last().unwrap();
            assert_eq!(m[&item].0, "IFCMAPPEDITEM");
            assert_eq!(refs(&m[&item].1)[0], maps[0]);
        }
    }
    // One type per kind: windows 1.2 x 1.5 (in all four buildings) and 1.2 x 1.8 (the
    // gable); doors 1.2 x 2.25 (the box) and 1.0 x 2.15 (courtyard and balcony).
    assert_eq!(count(&m, "IFCWINDOWTYPE"), 2);
    assert_eq!(count(&m, "IFCDOORTYPE"), 2);
    assert_eq!(count(&m, "IFCREPRESENTATIONMAP"), 4);
    assert_eq!(by_type.len(), 4);
    assert_eq!(count(&m, "IFCRELDECLARES"), 1);
    // Glass is transparent.
    assert!(m
        .values()
        .any(|(k, a)| k == "IFCSURFACESTYLERENDERING" && a.contains(",0.65,")));
}

#[test]
fn lod3_storeys_per_level_with_walls_in_their_storey() {
    let bs = lod3_sample();
    let m = parse(&write_lod3(&bs));
    let levels: usize = bs
        .iter()
        .flat_map(|b| &b.parts)
        .map(|p| p.levels.len())
        .sum();
    assert_eq!(count(&m, "IFCBUILDINGSTOREY"), levels);
    let by_gid: BTreeMap<String, u64> = m.keys().map(|&id| (gid_of(&m, id), id)).collect();
    let contained: Vec<Vec<u64>> = m
        .values()
        .filter(|(k, _)| k == "IFCRELCONTAINEDINSPATIALSTRUCTURE")
        .map(|(_, a)| refs(a))
        .collect();
    let storey_of = |id: u64| -> u64 {
        let c: Vec<_> = contained
            .iter()
            .filter(|r| r[..r.len() - 1].contains(&id))
            .collect();
        assert_eq!(c.len(), 1, "#{id} is contained once");
        *c[0].last().unwrap()
    };
    for b in &bs {
        let key = b.key();
        for part in &b.parts {
            for (s, level) in part.levels.iter().enumerate() {
                let st = by_gid[&global_id(&key, &format!("p0/storey/{s}"))];
                let elev: f64 = m[&st].1.rsplit(',').next().unwrap().parse().unwrap();
                assert!(
                    (elev - (level - b.base_z)).abs() < 1e-9,
                    "{elev} vs {level}"
                );
            }
            for (i, wall) in part.walls.iter().enumerate() {
                let id = by_gid[&global_id(&key, &format!("p0/wall/{i}"))];
                let st = by_gid[&global_id(&key, &format!("p0/storey/{}", wall.storey))];
                assert_eq!(storey_of(id), st, "{key} wall {i}");
                for j in 0..wall.openings.len() {
                    let f = by_gid[&global_id(&key, &format!("p0/wall/{i}/opening/{j}/fill"))];
                    assert_eq!(storey_of(f), st, "{key} wall {i} opening {j}");
                }
            }
            let top = part.levels.len() - 1;
            let roof = by_gid[&global_id(&key, "p0/roof")];
            let top_st = by_gid[&global_id(&key, &format!("p0/storey/{top}"))];
            assert_eq!(storey_of(roof), top_st);
        }
    }
    // The balcony: a floor slab and a balustrade in storey 1 of way/7.
    let slab = by_gid[&global_id("way_7", "p0/wall/4/balcony/0")];
    let railing = by_gid[&global_id("way_7", "p0/wall/4/balcony/0/railing")];
    assert!(m[&slab].0 == "IFCSLAB" && m[&slab].1.contains("'Balcony'"));
    assert!(m[&slab].1.ends_with(".FLOOR."));
    assert!(m[&railing].0 == "IFCRAILING" && m[&railing].1.ends_with(".BALUSTRADE."));
    let st1 = by_gid[&global_id("way_7", "p0/storey/1")];
    assert_eq!(storey_of(slab), st1);
    assert_eq!(storey_of(railing), st1);
}

#[test]
fn lod3_output_is_deterministic_and_light() {
    let bs = lod3_sample();
    let a = write_lod3(&bs);
    assert_eq!(a, write_lod3(&bs));
    // Sharing: one opening body per size and wall thickness, one mapped shape per type.
    let m = parse(&a);
    assert_eq!(count(&m, "IFCMAPPEDITEM"), 4);
    let opening_shapes: BTreeSet<u64> = ids_of(&m, "IFCOPENINGELEMENT")
        .iter()
        .map(|o| refs(&m[o].1)[1])
        .collect();
    assert_eq!(opening_shapes.len(), 4);
}

/// With caches of one entry, sharing is lost but nothing else: every opening still has a
/// body of its own size, the file has the same elements, and it stays deterministic.
#[test]
fn full_shared_caches_are_emptied_not_grown() {
    let bs = lod3_sample();
    let full = parse(&write_lod3(&bs));
    let small = write_lod3_limited(&bs, 1);
    assert_eq!(small, write_lod3_limited(&bs, 1));
    let m = parse(&small);
    for kw in [
        "IFCOPENINGELEMENT",
        "IFCWINDOW",
        "IFCDOOR",
        "IFCRELVOIDSELEMENT",
    ] {
        assert_eq!(count(&m, kw), count(&full, kw), "{kw}");
    }
    let body = |m: &BTreeMap<u64, (String, String)>, o: u64| {
        // Opening -> product shape -> representation -> extruded solid -> profile.
        let rep = refs(&m[&refs(&m[&o].1)[1]].1)[0];
        let solid = *refs(&m[&rep].1).last().unwrap();
        let profile = refs(&m[&solid].1)[0];
        // Width and height: the last two arguments (the profile's placement id differs).
        let args: Vec<&str> = m[&profile].1.rsplitn(3, ',').collect();
        format!("{} x {}", args[1], args[0])
    };
    let sizes = |m: &BTreeMap<u64, (String, String)>| -> Vec<String> {
        ids_of(m, "IFCOPENINGELEMENT")
            .iter()
            .map(|&o| body(m, o))
            .collect()
    };
    assert_eq!(sizes(&m), sizes(&full));
    let shapes = |m: &BTreeMap<u64, (String, String)>| -> usize {
        ids_of(m, "IFCOPENINGELEMENT")
            .iter()
            .map(|o| refs(&m[o].1)[1])
            .collect::<BTreeSet<_>>()
            .len()
    };
    assert!(
        shapes(&m) > shapes(&full),
        "{} vs {}",
        shapes(&m),
        shapes(&full)
    );
}

/// Runs the reference validator with the geometry kernel on the LOD3 sample when it is
/// installed (every wall is built with its openings cut, every window and door from its
/// mapped type); skipped otherwise. `CITYGEN_IFC_LOD3_SAMPLE=path` also keeps the file.
#[test]
fn lod3_sample_passes_the_reference_validator() {
    let bytes = write_lod3(&lod3_sample());
    if let Some(keep) = std::env::var_os("CITYGEN_IFC_LOD3_SAMPLE") {
        std::fs::write(keep, &bytes).unwrap();
    }
    let Some(tool) = crate::testkit::validators::validate_outputs("IFC LOD3 sample (geometry)")
    else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("lod3.ifc");
    std::fs::write(&path, bytes).unwrap();
    let out = std::process::Command::new(tool)
        .arg("--geometry")
        .arg(&path)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success() && text.contains(" 0 failed"), "{text}");
    assert!(
        // 63 shapes, and 7 `Window sills` proxies: the 10 windows stand on 7 walls.
        text.contains("OpeningElement=13 Window=10 Door=3 shapes=70/70"),
        "{text}"
    );
}

/// A box with SELEX's shapes: an arched door (top corners rounded), an arched window with an
/// explicit frame standing 5 cm out, a round (all corners) framed window and a plain
/// rectangle, on the front wall.
fn shaped_sample() -> Building {
    use crate::model::{FrameSize, Rounding};
    use OpeningKind::{Door, Window};
    let fp = Polygon::new(rect(0.0, 0.0, 12.0, 6.0), vec![]);
    let mut p = storeyed(flat_part("p0", fp, 0.0, 4.0, 1), &[0.0]);
    let arch = |r: f64, all: bool| Rounding {
        corners: [true, true, all, all],
        radius: r,
        segments: 6,
        profile: 0.5,
    };
    let frame = FrameSize {
        width: 0.08,
        protrusion: 0.05,
    };
    let shapes = [
        (Door, (1.0, 2.4), (0.02, 3.0), Some(arch(0.7, false)), None),
        (
            Window,
            (4.0, 5.2),
            (1.0, 3.0),
            Some(arch(0.6, false)),
            Some(frame),
        ),
        (
            Window,
            (6.5, 8.5),
            (1.0, 3.0),
            Some(arch(1.0, true)),
            Some(frame),
        ),
        (Window, (9.5, 10.7), (1.0, 2.6), None, Some(frame)),
    ];
    for (kind, u, z, rounding, frame_size) in shapes {
        let w = &mut p.walls[0];
        let o = Opening {
            kind,
            u0: u.0,
            u1: u.1,
            z0: z.0,
            z1: z.1,
            color: Color::rgb(0.6, 0.8, 1.0),
            frame_color: Color::rgb(1.0, 1.0, 1.0),
            glazed: kind == Window,
            framed: frame_size.is_some(),
            frame_size,
            rounding,
        };
        let dir = (w.end - w.start).normalize();
        let mut ring = o.outline();
        ring[1..].reverse();
        w.outline.holes.push(
            ring.iter()
                .map(|q| (w.start + dir * q.x).extend(q.y))
                .collect(),
        );
        w.openings.push(o);
    }
    lod3(building(SourceId::Way(11), Some("Shapes"), vec![p]))
}

#[test]
fn rounded_and_framed_openings_are_typed_windows_and_doors_with_their_parameters() {
    let bytes = write_lod3(&[shaped_sample()]);
    let m = parse(&bytes);
    let text = String::from_utf8_lossy(&bytes);
    // The rounded openings void their wall with their outline; the rectangle with a rectangle.
    assert_eq!(ids_of(&m, "IFCOPENINGELEMENT").len(), 4);
    let plain = parse(&write_lod3(&[{
        let mut b = shaped_sample();
        for w in &mut b.parts[0].walls {
            w.openings.clear();
            w.outline.holes.clear();
        }
        b
    }]));
    let closed =
        |m: &BTreeMap<u64, (String, String)>| ids_of(m, "IFCARBITRARYCLOSEDPROFILEDEF").len();
    assert_eq!(closed(&m) - closed(&plain), 3 + 3, "3 voids, 3 panes");
    // Three framed types draw their frame from the outlines (with the pane's as a void).
    assert_eq!(ids_of(&m, "IFCARBITRARYPROFILEDEFWITHVOIDS").len(), 3);
    // The types carry the parameters: lining properties for the frames, and the shape set.
    assert_eq!(ids_of(&m, "IFCWINDOWLININGPROPERTIES").len(), 3);
    assert!(
        ids_of(&m, "IFCDOORLININGPROPERTIES").is_empty(),
        "the door has no frame"
    );
    let types: Vec<&String> = ids_of(&m, "IFCWINDOWTYPE")
        .into_iter()
        .chain(ids_of(&m, "IFCDOORTYPE"))
        .map(|id| &m[&id].1)
        .collect();
    assert_eq!(types.len(), 4);
    assert!(
        types.iter().all(|t| !t.contains(",$,$,$,(#")),
        "every type has its psets"
    );
    assert!(types
        .iter()
        .any(|t| t.contains("rounded top_left,top_right r700mm s6 p500")));
    assert!(types.iter().any(|t| t.contains(
        "rounded top_left,top_right,bottom_right,bottom_left r1000mm s6 p500 frame 80mm+50mm"
    )));
    assert_eq!(text.matches("'Citygen_OpeningShape'").count(), 4);
    for p in [
        "'RoundedCorners'",
        "'CornerRadius'",
        "'ArcSegments'",
        "'CornerProfile'",
    ] {
        assert_eq!(text.matches(p).count(), 3, "{p}");
    }
    assert_eq!(text.matches("'FrameProtrusion'").count(), 3);
    // A window with an explicit frame stands at the wall's outer face (its frame 5 cm out).
    let Some(tool) =
        crate::testkit::validators::validate_outputs("IFC rounded and framed openings")
    else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("shapes.ifc");
    std::fs::write(&path, &bytes).unwrap();
    let out = std::process::Command::new(tool)
        .arg("--geometry")
        .arg(&path)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success() && text.contains(" 0 failed"), "{text}");
    assert!(text.contains("OpeningElement=4 Window=3 Door=1"), "{text}");
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(24))]
    /// Rotated and shifted boxes: the file stays well-formed, every wall keeps its length,
    /// and no non-finite or exponent-formatted number slips in.
    #[test]
    fn rotated_boxes_are_well_formed(
        angle in 0.0f64..std::f64::consts::TAU,
        x in -5000.0f64..5000.0,
        y in -5000.0f64..5000.0,
        w in 0.5f64..80.0,
        h in 0.5f64..80.0,
    ) {
        let (sin, cos) = angle.sin_cos();
        let ring: Vec<DVec2> = rect(0.0, 0.0, w, h)
            .into_iter()
            .map(|p| DVec2::new(x + p.x * cos - p.y * sin, y + p.x * sin + p.y * cos))
            .collect();
        let b = building(SourceId::Way(9), None, vec![flat_part("p0", Polygon::new(ring, vec![]), 0.0, 7.5, 2)]);
        let bytes = write_all(&[b]);
        let m = parse(&bytes);
        for (id, (_, args)) in &m {
            for r in refs(args) {
                proptest::prop_assert!(m.contains_key(&r), "#{} -> #{}", id, r);
            }
            // Outside string literals, only digits, '.', '-', refs, enums and punctuation.
            let bare: String = args.split('\'').step_by(2).collect();
            proptest::prop_assert!(!bare.contains("NaN") && !bare.contains("inf") && !bare.contains('e'), "{}", bare);
        }
        let mut lengths: Vec<f64> = m
            .values()
            .filter(|(k, _)| k == "IFCRECTANGLEPROFILEDEF")
            .map(|(_, a)| a.split(',').nth(3).unwrap().parse().unwrap())
            .collect();
        lengths.sort_by(f64::total_cmp);
        let (lo, hi) = (w.min(h), w.max(h));
        proptest::prop_assert_eq!(lengths.len(), 4);
        for (got, want) in lengths.iter().zip([lo, lo, hi, hi]) {
            proptest::prop_assert!((got - want).abs() < 1e-5, "{} vs {}", got, want);
        }
    }

    /// LOD3 rotated boxes with a random row of windows and doors on the front of each
    /// storey: one opening element per opening, each voiding its wall and filled once, and
    /// one type per distinct (kind, size in cm).
    #[test]
    fn lod3_rotated_boxes_keep_one_opening_per_window_or_door(
        angle in 0.0f64..std::f64::consts::TAU,
        widths in proptest::collection::vec((0.3f64..1.6, proptest::bool::ANY), 1..6),
        storeys in 1usize..4,
    ) {
        let (sin, cos) = angle.sin_cos();
        let ring: Vec<DVec2> = rect(0.0, 0.0, 12.0, 6.0)
            .into_iter()
            .map(|p| DVec2::new(p.x * cos - p.y * sin, p.x * sin + p.y * cos))
            .collect();
        let levels: Vec<f64> = (0..storeys).map(|i| 3.0 * i as f64).collect();
        let top = 3.0 * storeys as f64;
        let part = flat_part("p0", Polygon::new(ring, vec![]), 0.0, top, storeys as u32);
        let mut part = storeyed(part, &levels);
        let mut kinds = BTreeSet::new();
        for (s, z) in levels.iter().enumerate() {
            let mut u = 0.1;
            for &(w, door) in &widths {
                let kind = if door { OpeningKind::Door } else { OpeningKind::Window };
                open(&mut part, 4 * s, kind, (u, u + w), (z + 0.1, z + 2.2));
                kinds.insert((door, (w * 100.0 + 1e-6).floor() as i64));
                u += w + 0.5;
            }
        }
        let n = widths.len() * storeys;
        let b = lod3(building(SourceId::Way(9), None, vec![part]));
        let m = parse(&write_lod3(&[b]));
        let openings = ids_of(&m, "IFCOPENINGELEMENT");
        proptest::prop_assert_eq!(openings.len(), n);
        proptest::prop_assert_eq!(count(&m, "IFCWINDOW") + count(&m, "IFCDOOR"), n);
        for o in &openings {
            let voids = m.values().filter(|(k, a)| k == "IFCRELVOIDSELEMENT" && refs(a)[1] == *o).count();
            let fills = m.values().filter(|(k, a)| k == "IFCRELFILLSELEMENT" && refs(a)[0] == *o).count();
            proptest::prop_assert_eq!((voids, fills), (1, 1));
        }
        proptest::prop_assert_eq!(count(&m, "IFCWINDOWTYPE") + count(&m, "IFCDOORTYPE"), kinds.len());
        proptest::prop_assert_eq!(count(&m, "IFCBUILDINGSTOREY"), storeys);
    }
}

/// The LOD4 additions ([`super::lod4`]): interiors.
mod lod4 {
    use std::collections::BTreeMap;

    use super::super::IfcWriter;
    use crate::crs::Crs;
    use crate::export::{fixtures, BuildingWriter, OutputContext};
    use crate::model::{Building, Lod};
    use glam::DVec3;

    fn ctx() -> OutputContext {
        OutputContext {
            crs: Crs::Lambert93,
            origin: DVec3::new(574_000.0, 6_280_000.0, 150.0),
            origin_lonlat: (1.444, 43.6045),
            lod: Lod::Lod4,
            source_name: "lod4.osm.pbf".into(),
            seed: 7,
            vertical_datum: None,
            terrain: None,
        }
    }

    fn write(buildings: &[Building]) -> Vec<u8> {
        let mut w = IfcWriter::new(Vec::new()).with_file_name("lod4.ifc");
        w.begin(&ctx()).unwrap();
        for b in buildings {
            w.write(b).unwrap();
        }
        w.finish().unwrap();
        w.into_inner().unwrap()
    }

    /// id -> (keyword, arguments split at top-level commas).
    fn parse(bytes: &[u8]) -> BTreeMap<u64, (String, Vec<String>)> {
        let text = std::str::from_utf8(bytes).unwrap();
        let data = text.split("DATA;\n").nth(1).unwrap();
        let mut out = BTreeMap::new();
        for line in data.lines().take_while(|l| *l != "ENDSEC;") {
            let (id, rest) = line.split_once('=').unwrap();
            let (kw, args) = rest.split_once('(').unwrap();
            let args = args.strip_suffix(");").unwrap();
            let (mut parts, mut cur, mut depth, mut in_str) = (Vec::new(), String::new(), 0, false);
            for c in args.chars() {
                match c {
                    '\'' => in_str = !in_str,
                    '(' if !in_str => depth += 1,
                    ')' if !in_str => depth -= 1,
                    ',' if !in_str && depth == 0 => {
                        parts.push(std::mem::take(&mut cur));
                        continue;
                    }
                    _ => {}
                }
                cur.push(c);
            }
            parts.push(cur);
            let id: u64 = id.trim_start_matches('#').parse().unwrap();
            out.insert(id, (kw.to_string(), parts));
        }
        out
    }

    /// The ids `#n` in an argument (a reference or a list of them).
    fn ids(arg: &str) -> Vec<u64> {
        arg.trim_matches(|c| c == '(' || c == ')')
            .split(',')
            .filter_map(|s| s.trim().strip_prefix('#'))
            .map(|s| s.parse().unwrap())
            .collect()
    }

    #[test]
    fn spaces_partitions_doors_stair_and_floor_per_storey() {
        let bs = fixtures::lod4_all();
        let m = parse(&write(&bs));
        let of = |kw: &str| -> Vec<u64> {
            m.iter()
                .filter(|(_, (k, _))| k == kw)
                .map(|(id, _)| *id)
                .collect()
        };
        let storey_name = |id: u64| m[&id].1[2].clone();
        // Spaces: aggregated under a storey, three per storey of the house.
        let spaces = of("IFCSPACE");
        assert_eq!(spaces.len(), 6);
        let mut per_storey: BTreeMap<String, usize> = BTreeMap::new();
        for s in &spaces {
            let rels: Vec<&(String, Vec<String>)> = m
                .values()
                .filter(|(k, a)| k == "IFCRELAGGREGATES" && ids(&a[5]).contains(s))
                .collect();
            assert_eq!(rels.len(), 1, "space #{s} aggregated once");
            let storey = ids(&rels[0].1[4])[0];
            assert_eq!(m[&storey].0, "IFCBUILDINGSTOREY");
            *per_storey.entry(storey_name(storey)).or_default() += 1;
            assert!(["'Hall'", "'Living room'", "'Bedroom 1'"].contains(&m[s].1[2].as_str()));
        }
        assert_eq!(per_storey.values().copied().collect::<Vec<_>>(), [3, 3]);
        assert_eq!(
            m.values()
                .filter(|(k, a)| k == "IFCELEMENTQUANTITY" && a[2] == "'Qto_SpaceBaseQuantities'")
                .count(),
            6
        );
        let area = m
            .values()
            .find(|(k, a)| k == "IFCQUANTITYAREA" && a[0] == "'NetFloorArea'")
            .map(|(_, a)| a[3].parse::<f64>().unwrap())
            .unwrap();
        assert!((area - 4.0 * 7.4).abs() < 1e-9, "hall area {area}");

        // Partitions: 3 per storey, contained in their storey.
        let partitions: Vec<u64> = of("IFCWALLSTANDARDCASE")
            .into_iter()
            .filter(|w| m[w].1[8] == ".PARTITIONING.")
            .collect();
        assert_eq!(partitions.len(), 6);
        let container = |e: u64| -> Vec<u64> {
            m.values()
                .filter(|(k, a)| {
                    k == "IFCRELCONTAINEDINSPATIALSTRUCTURE" && ids(&a[4]).contains(&e)
                })
                .map(|(_, a)| ids(&a[5])[0])
                .collect()
        };
        for w in &partitions {
            let c = container(*w);
            assert_eq!(c.len(), 1);
            assert_eq!(m[&c[0]].0, "IFCBUILDINGSTOREY");
        }
        // Interior doors: each in an opening voiding a partition, filled by a typed door.
        let mut interior_doors = 0;
        for (_, a) in m.values().filter(|(k, _)| k == "IFCRELVOIDSELEMENT") {
            let (wall, opening) = (ids(&a[4])[0], ids(&a[5])[0]);
            if !partitions.contains(&wall) {
                continue;
            }
            interior_doors += 1;
            let fills: Vec<u64> = m
                .values()
                .filter(|(k, f)| k == "IFCRELFILLSELEMENT" && ids(&f[4]) == [opening])
                .map(|(_, f)| ids(&f[5])[0])
                .collect();
            assert_eq!(fills.len(), 1);
            assert_eq!(m[&fills[0]].0, "IFCDOOR");
            assert_eq!(
                container(fills[0]),
                container(wall),
                "door in its wall's storey"
            );
            let typed = m.values().any(|(k, t)| {
                k == "IFCRELDEFINESBYTYPE"
                    && ids(&t[4]).contains(&fills[0])
                    && m[&ids(&t[5])[0]].0 == "IFCDOORTYPE"
            });
            assert!(typed);
        }
        assert_eq!(interior_doors, 4);
        // One stair (ground storey) with 17 steps; one upper floor slab with the well as a void.
        let stairs = of("IFCSTAIR");
        assert_eq!(stairs.len(), 1);
        assert_eq!(storey_name(container(stairs[0])[0]), "'Storey 0'");
        let floors: Vec<u64> = of("IFCSLAB")
            .into_iter()
            .filter(|s| m[s].1[2] == "'Floor 1'")
            .collect();
        assert_eq!(floors.len(), 1);
        assert_eq!(storey_name(container(floors[0])[0]), "'Storey 1'");
        // The courtyard sample's base slab, and the upper hall minus the stair well.
        assert_eq!(of("IFCARBITRARYPROFILEDEFWITHVOIDS").len(), 2);
    }

    #[test]
    fn lod4_output_is_deterministic() {
        let bs = fixtures::lod4_all();
        assert_eq!(write(&bs), write(&bs));
    }

    /// The reference validator with the geometry kernel, when installed: every space, wall,
    /// door, stair and slab builds. `CITYGEN_IFC_LOD4_SAMPLE=path` keeps the file.
    #[test]
    fn lod4_sample_passes_the_reference_validator() {
        let bytes = write(&fixtures::lod4_all());
        if let Some(keep) = std::env::var_os("CITYGEN_IFC_LOD4_SAMPLE") {
            std::fs::write(keep, &bytes).unwrap();
        }
        let Some(tool) = fixtures::validator("IFC LOD4 sample (geometry)") else {
            return;
        };
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("lod4.ifc");
        std::fs::write(&path, bytes).unwrap();
        let out = std::process::Command::new(tool)
            .arg("--geometry")
            .arg(&path)
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(out.status.success() && text.contains(" 0 failed"), "{text}");
        assert!(text.contains("Space=6"), "{text}");
        let shapes = text.split("shapes=").nth(1).unwrap_or("");
        let (ok, all) = shapes.split_once('/').unwrap();
        assert_eq!(ok, all.split_whitespace().next().unwrap(), "{text}");
    }
}

/// The arguments of `args` (top level, split at commas outside parentheses).
fn top_args(args: &str) -> Vec<&str> {
    let (mut out, mut depth, mut start) = (Vec::new(), 0, 0);
    for (i, c) in args.char_indices() {
        match c {
            '(' => depth += 1,
            ')' => depth -= 1,
            ',' if depth == 0 => {
                out.push(&args[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    out.push(&args[start..]);
    out
}

#[test]
fn degenerate_dimensions_never_reach_the_file_as_zero_lengths() {
    // Each mutation is either left out by the writer (the file stays valid) or an error naming
    // the building; never a profile or extrusion with a length of 0 (IfcPositiveLengthMeasure).
    type Mutation = fn(&mut Building);
    let cases: [(&str, Mutation); 7] = [
        ("wall thickness 0", |b| b.parts[0].walls[0].thickness = 0.0),
        ("wall thickness 0.1 µm", |b| {
            b.parts[0].walls[0].thickness = 1e-7
        }),
        ("negative wall thickness", |b| {
            b.parts[0].walls[0].thickness = -0.3
        }),
        ("wall of no height", |b| {
            let w = &mut b.parts[0].walls[0];
            w.top_z = w.base_z;
        }),
        ("wall of no length", |b| {
            let w = &mut b.parts[0].walls[0];
            w.end = w.start;
        }),
        ("opening of no width", |b| {
            let w = &mut b.parts[0].walls[0];
            w.openings = vec![
                crate::export::lod3geom::samples::window(1.0, 1.0, 1.0, 2.0),
                crate::export::lod3geom::samples::door(2.0, 2.0, 0.0, 2.0),
            ];
        }),
        ("opening 0.1 µm high", |b| {
            let w = &mut b.parts[0].walls[0];
            w.openings = vec![crate::export::lod3geom::samples::window(
                1.0,
                2.0,
                1.0,
                1.0 + 1e-7,
            )];
        }),
    ];
    // (keyword, 1-based arguments that are positive lengths)
    let positive: [(&str, &[usize]); 3] = [
        ("IFCRECTANGLEPROFILEDEF", &[4, 5]),
        ("IFCRECTANGLEHOLLOWPROFILEDEF", &[4, 5, 6]),
        ("IFCEXTRUDEDAREASOLID", &[4]),
    ];
    let lod3 = OutputContext {
        lod: Lod::Lod3,
        ..ctx()
    };
    let write3 = |b: &Building| {
        let mut w = IfcWriter::new(Vec::new());
        w.begin(&lod3).unwrap();
        let done = w.write(b);
        (w, done)
    };
    // The harness writes openings: a sound window gets its IfcWindow.
    let mut sound = sample().remove(0);
    sound.lod = Lod::Lod3;
    sound.parts[0].walls[0].openings =
        vec![crate::export::lod3geom::samples::window(1.0, 2.0, 1.0, 2.0)];
    let (mut w, done) = write3(&sound);
    done.unwrap();
    w.finish().unwrap();
    assert_eq!(count(&parse(&w.into_inner().unwrap()), "IFCWINDOW"), 1);
    for (what, mutate) in cases {
        let mut b = sample().remove(0);
        b.lod = Lod::Lod3;
        mutate(&mut b);
        let (mut w, done) = write3(&b);
        match done {
            Err(e) => {
                let msg = e.to_string();
                assert!(msg.contains("building way/1"), "{what}: {msg}");
                continue;
            }
            Ok(()) => w.finish().unwrap(),
        }
        for (kw, args) in parse(&w.into_inner().unwrap()).values() {
            let Some((_, idx)) = positive.iter().find(|(k, _)| k == kw) else {
                continue;
            };
            let a = top_args(args);
            for &i in *idx {
                let v: f64 = a[i - 1].parse().unwrap_or(f64::NAN);
                assert!(v > 0.0, "{what}: {kw}({args}) argument {i} is {}", a[i - 1]);
            }
        }
    }
}

#[test]
fn write_all_writes_the_bytes_of_one_write_per_building() {
    // Several batches of LOD4 buildings (new styles, usages, types and opening shapes in the
    // middle of batches; repeated keys), with the shared caches at full size and tiny (emptied
    // within batches).
    let all = crate::export::fixtures::lod4_all();
    let buildings: Vec<Building> = (0..3 * PARALLEL_BATCH + 5)
        .map(|i| {
            let mut b = all[i % all.len()].clone();
            if i % 7 != 3 {
                b.id = SourceId::Way(1000 + i as i64);
            }
            b
        })
        .collect();
    let ctx = OutputContext {
        lod: Lod::Lod4,
        ..ctx()
    };
    for limit in [SHARED_CACHE_LIMIT, 5, 1] {
        let run = |all: bool| {
            let mut w = IfcWriter::new(Vec::new());
            w.cache_limit = limit;
            w.begin(&ctx).unwrap();
            if all {
                w.write_all(&buildings).unwrap();
            } else {
                for b in &buildings {
                    w.write(b).unwrap();
                }
            }
            w.finish().unwrap();
            w.into_inner().unwrap()
        };
        let one = run(false);
        assert!(one.len() > 100_000);
        assert!(
            one == run(true),
            "limit {limit}: write_all differs from write"
        );
    }
}

/// Provenance is in `Citygen_Source`: sources as `IfcLabel`s, the storeys' uncertainty an
/// `IfcReal`, the height's an `IfcLengthMeasure`, the roof's probability an
/// `IfcNormalisedRatioMeasure`; an unknown uncertainty is left out.
#[test]
fn provenance_is_in_the_source_property_set() {
    let mut bs = sample();
    bs[0].provenance = crate::export::fixtures::model_provenance();
    bs[1].provenance = crate::model::Provenance {
        storeys: crate::model::ValueSource::Tag,
        height: crate::model::ValueSource::Fitted,
        height_error: Some(1.5),
        ..Default::default()
    };
    let m = parse(&write_all(&bs[..2]));
    let props: Vec<&str> = m
        .values()
        .filter(|(k, _)| k == "IFCPROPERTYSINGLEVALUE")
        .map(|(_, a)| a.as_str())
        .collect();
    let has = |p: &str| props.contains(&p);
    for p in [
        "'StoreysSource',$,IFCLABEL('model'),$",
        "'StoreysError',$,IFCREAL(0.75),$",
        "'HeightSource',$,IFCLABEL('model'),$",
        "'HeightError',$,IFCLENGTHMEASURE(2.25),$",
        "'RoofSource',$,IFCLABEL('kb'),$",
        "'RoofProbability',$,IFCNORMALISEDRATIOMEASURE(0.8),$",
        "'StoreysSource',$,IFCLABEL('tag'),$",
        "'HeightSource',$,IFCLABEL('fitted'),$",
        "'HeightError',$,IFCLENGTHMEASURE(1.5),$",
    ] {
        assert!(has(p), "{p} not in {props:#?}");
    }
    let count = |name: &str| props.iter().filter(|p| p.starts_with(name)).count();
    assert_eq!(count("'StoreysSource'"), 2);
    assert_eq!(count("'StoreysError'"), 1, "a tag has no uncertainty");
    assert_eq!(count("'RoofProbability'"), 1);
    // All in the Citygen_Source set, with the building's other values.
    let pset = m
        .values()
        .find(|(k, a)| k == "IFCPROPERTYSET" && a.contains("'Citygen_Source'"))
        .map(|(_, a)| refs(a))
        .unwrap();
    assert_eq!(pset.len(), 6 + 6);
}

/// Every building and storey has its base quantities: the building's footprint, floor area,
/// volume and heights, each storey's height, perimeter, floor area and volume (issue 47).
#[test]
fn buildings_and_storeys_carry_their_base_quantities() {
    for lod in [Lod::Lod2, Lod::Lod3] {
        let bs = sample();
        let mut w = IfcWriter::new(Vec::new()).with_file_name("sample.ifc");
        w.begin(&OutputContext { lod, ..ctx() }).unwrap();
        for b in &bs {
            w.write(b).unwrap();
        }
        w.finish().unwrap();
        let bytes = w.into_inner().unwrap();
        let m = parse(&bytes);
        let qtos: Vec<&(String, String)> = m
            .values()
            .filter(|(k, _)| k == "IFCELEMENTQUANTITY")
            .collect();
        let named = |n: &str| qtos.iter().filter(|(_, a)| a.contains(n)).count();
        // Partial buildings (one per part of a building of several) too.
        assert_eq!(
            named("'Qto_BuildingBaseQuantities'"),
            count(&m, "IFCBUILDING"),
            "LOD{}",
            lod.number()
        );
        assert_eq!(
            named("'Qto_BuildingStoreyBaseQuantities'"),
            count(&m, "IFCBUILDINGSTOREY"),
            "LOD{}",
            lod.number()
        );
        // The first building's numbers: height and footprint as the model has them.
        let text = String::from_utf8(bytes).unwrap();
        let b = &bs[0];
        let area: f64 = b
            .parts
            .iter()
            .filter(|p| (p.base_z - b.base_z).abs() < 0.01)
            .map(super::quantities::footprint_area)
            .sum();
        let find = |name: &str| -> f64 {
            let at = text
                .find(&format!("('{name}',$,$,"))
                .unwrap_or_else(|| panic!("{name}"));
            let rest = &text[at + name.len() + 8..];
            rest[..rest.find(',').unwrap()].parse().unwrap()
        };
        assert!((find("Height") - b.measured_height).abs() < 1e-6);
        assert!((find("FootprintArea") - area).abs() < 1e-6);
        assert!(find("GrossVolume") > 0.0 && find("GrossFloorArea") >= area - 1e-6);
    }
}
