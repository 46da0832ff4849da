//! SELEX programs on real footprints: the facades of Monaco's buildings, each with its side
//! towards the street (issue 23). Programs written for real buildings name `facade` and
//! `side`; the seed's printed programs, written for its box, also run unchanged (their
//! `createShape` becomes the building's mass: tested in `derive::selex`).

use crate::common::*;
use citygen::report::Report;
use citygen::selex::eval::{facade_specs, run_on_facades, Side};
use citygen::selex::parser::parse;

const MONACO: &str = "data/monaco/monaco.osm.pbf";

/// The lots of Monaco with a street in front, largest first.
fn monaco_lots() -> Vec<citygen::prepare::Lot> {
    let mut report = Report::default();
    let read = citygen::input::osm::read_osm(&root().join(MONACO), &mut report).unwrap();
    let mut site = citygen::prepare::prepare(read.footprints, None, None, &mut report);
    citygen::prepare::assign_fronts(&mut site, &read.streets, None);
    let mut lots: Vec<_> = site
        .lots
        .into_iter()
        .filter(|l| l.front.is_some())
        .collect();
    lots.sort_by(|a, b| {
        let area = |l: &citygen::prepare::Lot| l.polygons.iter().map(|p| p.area()).sum::<f64>();
        area(b)
            .total_cmp(&area(a))
            .then(a.id.to_string().cmp(&b.id.to_string()))
    });
    lots
}

/// Anchiêta's framed windows (Código-fonte 9) and rounded door (Código-fonte 4), on the
/// facades facing the street, with storey grids instead of the seed's uniform ones.
const ON_FACADES: &str = r#"
{< descendant() [label == "facade"] > -> createStoreyGrid("g", 3.0)};
{< descendant() [label == "facade"] [side == "front"] / [label == "g"] / [type == "cell"] [rowIdx == 1] [colIdx == 2] [::groupRegions] > -> addRoundFacade("door", ["top_left", "top_right"], 0.4, 5, 0.5)};
{< descendant() [label == "facade"] [side != "front"] / [label == "g"] / [type == "cell"] [rowIdx > 1] > -> addFacadeWithFrame("windows", "frame", 0.2, 0.1)};
{< descendant() [label == "facade"] [side == "front"] / [label == "g"] / [type == "cell"] [rowIdx > 1] [pattern("(XA)*X", "A")] > -> addFacadeWithFrame("windows", "frame", 0.2, 0.1)};
{< descendant() [label == "facade"] > -> coverShape()};
"#;

#[test]
fn the_seeds_facade_rules_run_on_every_facade_of_real_monaco_buildings() {
    let program = parse(ON_FACADES, "facades.slx").unwrap();
    let lots = monaco_lots();
    assert!(lots.len() > 100, "{} lots with a front", lots.len());
    let storeys = [3.5, 3.0, 3.0, 3.0];
    let (mut tried, mut skipped) = (0, 0);
    for lot in lots.iter().take(40) {
        for polygon in &lot.polygons {
            let specs = facade_specs(polygon, 0.0, &storeys, lot.front);
            assert_eq!(
                specs.len(),
                polygon.rings().map(Vec::len).sum::<usize>(),
                "{}: one facade per edge",
                lot.id
            );
            // The street side exists: the edge whose normal is the front is a front facade.
            assert!(specs.iter().any(|s| s.side == Side::Front), "{}", lot.id);
            // A selector that does not fit one facade's grid (no second bay, a pattern that
            // does not tile its cells) leaves that facade out of the rule, with a warning.
            let d = run_on_facades(&program, ON_FACADES, "facades.slx", &specs)
                .unwrap_or_else(|e| panic!("{}: {e}", lot.id));
            skipped += d
                .warnings
                .iter()
                .filter(|w| w.message.contains("left out of this rule"))
                .count();
            tried += 1;
            let faces = d.find("facade");
            assert_eq!(faces.len(), specs.len());
            for (face, spec) in faces.iter().zip(&specs) {
                let frame = d.frame(*face).unwrap();
                // Each facade stands on its footprint edge and looks out of the building.
                let n = frame.normal().truncate();
                let mid = (spec.start + spec.end) / 2.0;
                assert!(
                    !polygon.contains(mid + 0.05 * n),
                    "{}: facade looks in",
                    lot.id
                );
                for &c in &d.shapes[*face].children {
                    if let citygen::selex::eval::ShapeKind::Element(e) = &d.shapes[c].kind {
                        // Inside its facade, doors on the ground floor only.
                        assert!(e.rect.x >= -1e-9 && e.rect.x + e.rect.w <= frame.width + 1e-9);
                        assert!(e.rect.y + e.rect.h <= frame.height + 1e-9);
                        if d.shapes[c].label == "door" {
                            assert!(e.rect.y.abs() < 1e-9 && spec.side == Side::Front);
                            assert!(e.rounding.is_some());
                        }
                    }
                }
            }
            // Every front facade wide enough for two bays has its door.
            let fronts = specs
                .iter()
                .filter(|s| s.side == Side::Front && s.start.distance(s.end) >= 4.5)
                .count();
            assert_eq!(d.count("door"), fronts, "{}", lot.id);
        }
    }
    assert!(tried >= 40, "only {tried} buildings ran");
    assert!(
        skipped > 0,
        "no facade too narrow or too odd for the rules?"
    );
}

/// A knowledge base whose Monaco-Ville appearance names `selex` (or none).
fn rock_kb(dir: &std::path::Path, selex: bool) -> std::path::PathBuf {
    std::fs::write(
        dir.join("rock.slx"),
        r#"# Monaco-Ville: bays of about 2.6 m; a porch 1.5 m deep, one storey high, in the second
# bay of every street facade, with an arched door; windows of 1.1 x 1.6 m centred in the bays
# of the middle storeys; arched windows with a frame standing 5 cm out filling the bays of the
# top storey.
{< descendant() [label == "facade"] > -> createStoreyGrid("g", 2.6)};
{< descendant() [label == "facade"] [side == "front"] / [label == "g"] / [type == "cell"] [rowIdx == 1] [colIdx == 2] [::groupRegions] > -> addVolume("porch", "facade", 1.5, ["porch_front", "porch_left", "porch_right"])};
{< descendant() [label == "porch_front"] / [label == "porch_front_grid"] / [type == "cell"] [::groupRegions] > -> addRoundFacade("door", ["top_left", "top_right"], 1.3, 8, 0.5)};
{< descendant() [label == "facade"] / [label == "g"] / [rowIdx in rowRange(2, -2)] > -> addShape("window", 1.1, 1.6)};
{< descendant() [label == "facade"] / [label == "g"] / [rowIdx == -1] > -> addRoundFacadeWithFrame("window", ["top_left", "top_right"], 1.3, 8, 0.5, "frame", 0.08, 0.05)};
"#,
    )
    .unwrap();
    let kb = dir.join(if selex { "kb.xml" } else { "plain.xml" });
    std::fs::write(
        &kb,
        format!(
            r##"<earth>
  <country designation="Monaco">
    <info lat="43.7384" lon="7.4246" dist="3" nbfloor="4"/>
    <town designation="Monaco-Ville">
      <info lat="43.7308" lon="7.4206" dist="0.5" nbfloor="4"/>
      <appearance>
        <values bdRooftype="hipped" color="#d8a05a" roofColor="#c0653f" floorsize="3" minFloors="3" maxFloors="5"/>
        {}
      </appearance>
    </town>
  </country>
</earth>
"##,
            if selex { r#"<selex file="rock.slx"/>"# } else { "" }
        ),
    )
    .unwrap();
    kb
}

#[test]
fn a_kb_appearance_with_selex_lays_out_the_facades_of_its_district() {
    let dir = tempfile::tempdir().unwrap();
    let run = |kb: &std::path::Path, tag: &str, bbox: &str| {
        let out = |ext: &str| dir.path().join(format!("{tag}.{ext}"));
        let o = citygen(&[
            "--osm",
            MONACO,
            "--kb",
            kb.to_str().unwrap(),
            "--lod",
            "3",
            "--bbox",
            bbox,
            "--ifc",
            out("ifc").to_str().unwrap(),
            "--citygml",
            out("gml").to_str().unwrap(),
            "--gltf",
            out("glb").to_str().unwrap(),
            "--report",
            out("json").to_str().unwrap(),
            "--quiet",
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        (
            std::fs::read_to_string(out("gml")).unwrap(),
            std::fs::read_to_string(out("json")).unwrap(),
            [out("ifc"), out("gml"), out("glb")],
        )
    };
    // Monaco-Ville: its 72 buildings for the counts.
    let ville = "7.4180,43.7290,7.4240,43.7330";
    let (with, report, files) = run(&rock_kb(dir.path(), true), "selex", ville);
    let (without, _, _) = run(&rock_kb(dir.path(), false), "rules", ville);
    let count = |gml: &str, what: &str| gml.matches(what).count();
    let (doors, windows) = (count(&with, "<bldg:Door"), count(&with, "<bldg:Window"));
    eprintln!("SELEX district: {doors} doors, {windows} windows");
    assert!(doors > 10, "{doors} doors");
    assert!(windows > 100, "{windows} windows");
    assert_ne!(
        (doors, windows),
        (
            count(&without, "<bldg:Door"),
            count(&without, "<bldg:Window")
        ),
        "the program changed nothing"
    );
    // The porches are parts of their buildings, each with its arched door (the entrances).
    let parts = count(&with, "<bldg:BuildingPart ");
    let porch_doors = with
        .split("<bldg:BuildingPart ")
        .skip(1)
        .filter(|p| {
            p.split("</bldg:BuildingPart>")
                .next()
                .unwrap_or("")
                .contains("<bldg:Door")
        })
        .count();
    eprintln!("{parts} building parts, {porch_doors} with a door");
    assert!(porch_doors > 50, "{porch_doors} porches with a door");
    assert!(report.contains("\"entrances\": ") && !report.contains("\"entrances\": 0,"));
    // Rounded and framed openings are typed IFC windows and doors carrying their parameters.
    let ifc = std::fs::read_to_string(&files[0]).unwrap();
    let arched_doors = ifc
        .lines()
        .filter(|l| l.contains("IFCDOORTYPE(") && l.contains("rounded top_left,top_right"))
        .count();
    let framed_windows = ifc
        .lines()
        .filter(|l| l.contains("IFCWINDOWTYPE(") && l.contains(" frame 80mm+50mm"))
        .count();
    eprintln!("{arched_doors} arched door types, {framed_windows} framed arched window types");
    assert!(arched_doors > 0 && framed_windows > 0);
    assert!(ifc.contains("IFCWINDOWLININGPROPERTIES(") && ifc.contains("'Citygen_OpeningShape'"));
    // CityGML's windows and doors have the arched outline: polygons of more than 4 corners.
    let rounded = with
        .split("<bldg:Door")
        .skip(1)
        .filter(|d| {
            let ring = d.split("<gml:posList").nth(1).unwrap_or_default();
            let ring = &ring[..ring.find("</gml:posList>").unwrap_or(0)];
            ring.split_whitespace().count() > 3 * 6
        })
        .count();
    assert!(rounded > 10, "{rounded} arched doors in CityGML");
    // Its south-east corner (14 buildings) through the validators, IFC with the geometry
    // kernel: the whole quarter took them 5 minutes of `cargo test` (CI validates it, drawn by
    // the shipped KB, in its sample step).
    let (_, _, corner) = run(
        &rock_kb(dir.path(), true),
        "corner",
        "7.4225,43.7300,7.4240,43.7312",
    );
    if let Some(tool) = citygen::testkit::validators::validate_outputs("a SELEX district") {
        let v = std::process::Command::new(tool)
            .arg("--geometry")
            .args(&corner)
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&v.stdout);
        assert!(v.status.success() && text.contains(" 0 failed"), "{text}");
    }
}

#[test]
fn a_selex_program_that_does_not_parse_stops_the_run_naming_its_place() {
    let dir = tempfile::tempdir().unwrap();
    let kb = rock_kb(dir.path(), true);
    std::fs::write(
        dir.path().join("rock.slx"),
        "{< cell() [rowIdz == 1] > -> addFacade(\"d\")};\n",
    )
    .unwrap();
    let out = dir.path().join("x.ifc");
    let o = citygen(&[
        "--osm",
        MONACO,
        "--kb",
        kb.to_str().unwrap(),
        "--lod",
        "3",
        "--ifc",
        out.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("rock.slx:1:12: unknown attribute `rowIdz`"),
        "{err}"
    );
    assert!(!out.exists());
}

/// The seed's printed programs (tests/data/selex) written as buildings by `selex derive`: valid
/// IFC (with `--geometry`), CityGML and glTF, with the openings and parts each program makes.
#[test]
fn the_seeds_programs_are_written_as_valid_buildings() {
    let dir = tempfile::tempdir().unwrap();
    let mut files = Vec::new();
    // (program, parts, windows, doors) as the CityGML counts them.
    for (name, parts, windows, doors) in [
        ("clock_tower", 0, 7, 0),
        ("rounded_door", 2, 0, 1),
        ("framed", 2, 2, 0),
        ("brito", 2, 0, 0),
        ("jiang", 0, 18, 1),
    ] {
        let out = |ext: &str| dir.path().join(format!("{name}.{ext}"));
        let program = format!("tests/data/selex/{name}.slx");
        let o = citygen(&[
            "selex",
            "derive",
            &program,
            "--ifc",
            out("ifc").to_str().unwrap(),
            "--citygml",
            out("gml").to_str().unwrap(),
            "--gltf",
            out("glb").to_str().unwrap(),
            "--report",
            out("json").to_str().unwrap(),
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{name}: {err}");
        assert!(err.contains("citygen: 1 building(s)"), "{name}: {err}");
        let gml = std::fs::read_to_string(out("gml")).unwrap();
        let count = |what: &str| gml.matches(what).count();
        assert_eq!(count("<bldg:BuildingPart "), parts, "{name}");
        assert_eq!(count("<bldg:Window"), windows, "{name}");
        assert_eq!(count("<bldg:Door"), doors, "{name}");
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out("json")).unwrap()).unwrap();
        assert_eq!(report["generated"], 1, "{name}");
        files.extend([out("ifc"), out("gml"), out("glb")]);
    }
    if let Some(tool) = citygen::testkit::validators::validate_outputs("the seed's programs") {
        let v = std::process::Command::new(tool)
            .arg("--geometry")
            .args(&files)
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&v.stdout);
        assert!(v.status.success() && text.contains(" 0 failed"), "{text}");
    }
}
