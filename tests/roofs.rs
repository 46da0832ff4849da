//! Every footprint polygon of data/monaco and data/clifton with hipped, gabled, mansard and saltbox roofs
//! forced: each built part must pass `massing::check_part` (planar faces, roof inside the
//! footprint and covering it, walls meeting the roof, closed solid), gabled and hipped faces
//! must all have the pitch, and no roof may fall back to flat. The closed-solid check has a
//! ratchet for a known skeleton weakness (see below).

use std::path::Path;

use citygen::color::Color;
use citygen::derive::massing::{build_part, check_part, roof_geometry, Mass};
use citygen::geometry::Polygon;
use citygen::input::{osm::read_osm, shp::read_shp, shp::ShpOptions};
use citygen::model::{Lod, RoofShape};
use citygen::prepare::prepare;
use citygen::report::Report;

const PITCH: f64 = 35.0;

fn footprints(path: &Path) -> Vec<(String, Polygon)> {
    let mut report = Report::default();
    let read = if path.extension().is_some_and(|e| e == "shp") {
        read_shp(path, &ShpOptions::default(), &mut report)
    } else {
        read_osm(path, &mut report)
    };
    let read = match read {
        Ok(r) => r,
        Err(e) => panic!("{}: {e}", path.display()),
    };
    let site = prepare(read.footprints, read.source_crs, None, &mut report);
    let mut out = Vec::new();
    for lot in &site.lots {
        for p in lot
            .polygons
            .iter()
            .chain(lot.parts.iter().flat_map(|p| p.polygons.iter()))
        {
            out.push((lot.id.to_string(), p.clone()));
        }
    }
    out
}

fn run(path: &Path, not_closed: &mut Vec<String>) -> (usize, Vec<String>) {
    let polys = footprints(path);
    let mut bad = Vec::new();
    for (id, p) in &polys {
        for shape in [
            RoofShape::Hipped,
            RoofShape::Gabled,
            RoofShape::Mansard,
            RoofShape::Saltbox,
        ] {
            let m = Mass {
                footprint: p.clone(),
                base_z: 0.0,
                eave_z: 6.0,
                storeys: 2,
                roof: shape,
                roof_angle_deg: PITCH,
                roof_direction: None,
                roof_across: false,
                roof_height: None,
                wall_color: Color::WHITE,
                roof_color: Color::GREY,
            };
            let r = match roof_geometry(&m) {
                Ok(r) => r,
                Err(f) => {
                    bad.push(format!("{id} {shape:?}: flat fallback: {}", f.reason));
                    continue;
                }
            };
            let part = build_part("p0".into(), &m, &r, Lod::Lod2);
            let d = check_part(&part);
            let open = d.iter().filter(|l| l.starts_with("edge ")).count();
            if open > 0 && open == d.len() {
                // Known weakness: the skeleton sometimes emits two nodes a few millimetres
                // apart (beyond the 1e-5 × size weld), leaving an edge shared by four faces.
                not_closed.push(format!("{id} {shape:?}: {}", d[0]));
                continue;
            }
            if let Some(first) = d.first() {
                bad.push(format!(
                    "{id} {shape:?}: {} defects, first: {first}",
                    d.len()
                ));
                continue;
            }
            if matches!(shape, RoofShape::Hipped | RoofShape::Gabled) {
                for f in &r.faces {
                    let s = f.normal().z.clamp(-1.0, 1.0).acos().to_degrees();
                    if (s - PITCH).abs() > 0.01 {
                        bad.push(format!("{id} {shape:?}: face slope {s}"));
                        break;
                    }
                }
            }
        }
    }
    (polys.len(), bad)
}

#[test]
fn every_footprint_of_both_data_sets_gets_every_forced_roof() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("data");
    let mut total = 0;
    let mut bad = Vec::new();
    let mut not_closed = Vec::new();
    for f in ["monaco/monaco.osm.pbf", "clifton/clifton_test.shp"] {
        let (n, b) = run(&root.join(f), &mut not_closed);
        assert!(n > 100, "{f}: only {n} footprints");
        total += n;
        bad.extend(b);
    }
    assert!(
        bad.is_empty(),
        "{} of {} footprints × 4 shapes fail:\n{}",
        bad.len(),
        total,
        bad[..bad.len().min(30)].join("\n")
    );
    // Ratchet on the known weakness above (18 of 12,474 roofs when written): lower it as the
    // skeleton's node merging improves, never raise it.
    assert!(
        not_closed.len() <= 18,
        "{} roofs not closed:\n{}",
        not_closed.len(),
        not_closed.join("\n")
    );
}

/// The same through the whole generator: a test knowledge base whose earth zone asks for one
/// roof shape, every building of both samples (with its roof tags removed, so that the KB's roof
/// applies), and every part built must pass the part checks with no flat fallback.
#[test]
fn a_test_kb_forcing_the_roof_gives_every_building_that_roof() {
    use citygen::derive::{Generator, Rules};
    use citygen::grammar::Caps;
    use citygen::kb::KnowledgeBase;
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("data");
    for shape in ["hipped", "gabled", "mansard"] {
        let text = format!(
            r#"<earth><info rooftype="{shape}" roofangle="{PITCH}" nbfloor="3" floorsize="3"/></earth>"#
        );
        let (kb, _) = KnowledgeBase::parse_str(&text, "forced.xml").unwrap();
        let generator = Generator::new(
            kb,
            Rules::Kb,
            Lod::Lod2,
            0,
            Caps {
                facades: false,
                ..Caps::default()
            },
        );
        let mut open = 0;
        for f in ["monaco/monaco.osm.pbf", "clifton/clifton_test.shp"] {
            let path = root.join(f);
            let mut report = Report::default();
            let read = if f.ends_with(".shp") {
                read_shp(&path, &ShpOptions::default(), &mut report).unwrap()
            } else {
                read_osm(&path, &mut report).unwrap()
            };
            let mut site = prepare(read.footprints, read.source_crs, None, &mut report);
            for lot in &mut site.lots {
                for t in
                    std::iter::once(&mut lot.tags).chain(lot.parts.iter_mut().map(|p| &mut p.tags))
                {
                    let t = std::sync::Arc::make_mut(t);
                    t.roof_shape = None;
                    t.roof_height = None;
                }
            }
            for lot in &site.lots {
                let (b, notes) = generator
                    .generate(lot)
                    .unwrap_or_else(|e| panic!("{}: {e}", lot.id));
                let flat: Vec<&String> = notes
                    .iter()
                    .map(|(_, n)| n)
                    .filter(|n| n.contains("drawn flat"))
                    .collect();
                assert!(flat.is_empty(), "{} {shape}: {flat:?}", lot.id);
                for part in &b.parts {
                    let d = check_part(part);
                    if !d.is_empty() && d.iter().all(|l| l.starts_with("edge ")) {
                        open += 1; // the known skeleton weakness, ratcheted above
                        continue;
                    }
                    assert!(d.is_empty(), "{} {shape}: {d:?}", lot.id);
                    // Simple 3D Buildings keep two kinds of part flat whatever the KB says: a
                    // roof on pillars, and a part with another standing on it.
                    let is_roof = part.source.is_some_and(|s| {
                        std::iter::once((lot.id, &lot.tags))
                            .chain(lot.parts.iter().map(|p| (p.id, &p.tags)))
                            .any(|(id, t)| id == s && t.is_roof())
                    });
                    let covered = b.parts.iter().any(|q| {
                        q.base_z >= part.top_z - 0.5
                            && q.base_z > part.base_z
                            && part
                                .footprint
                                .contains(citygen::prepare::interior_point(&q.footprint))
                    });
                    if !is_roof && !covered {
                        assert_ne!(part.roof_shape, RoofShape::Flat, "{} {shape}", lot.id);
                    }
                }
            }
        }
        assert!(open <= 18, "{shape}: {open} parts not closed");
    }
}
