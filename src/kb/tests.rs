//! Tests of the zone tree, lookup, inheritance and styles, on the 21-zone KB that was shipped
//! before the world KB (tests/data/kb-21-zones.xml: small, its zones known by heart), the
//! shipped world KB and the thesis's.

use super::choice::appearance_weights;
use super::*;
use crate::input::BuildingTags;
use crate::rng::Rng;

/// The 21-zone KB shipped before the world KB (France, Monaco, UK), kept as a fixture.
fn shipped() -> KnowledgeBase {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/kb-21-zones.xml");
    match KnowledgeBase::load(&path) {
        Ok((kb, repairs)) => {
            assert!(
                repairs.is_empty(),
                "the shipped KB needs no repair: {repairs:?}"
            );
            kb
        }
        Err(e) => panic!("{e}"),
    }
}

fn path_of(kb: &KnowledgeBase, i: usize) -> &str {
    kb.zone(i).map_or("?", |z| z.path.as_str())
}

/// Thesis annex, clean reconstruction (seed 003 notes §5.3).
const ANNEX: &str = r#"<earth>
  <info color="1;1;1" material="BricksBasic" nbfloor="1" roofangle="15" rooftype="flat"/>
  <country designation="France">
    <info color="pink" dist="5" lat="47.3833300" lon="0.6833300" material="BricksBasic" nbfloor="1" roofangle="15" rooftype="gabbled"/>
    <region designation="Midi-Pyrenees">
      <info color="grey" dist="1.1" lat="43.600000" lon="1.433333" material="BricksBasic" nbfloor="1" roofangle="15" rooftype="flat"/>
      <town designation="Toulouse">
        <info color="yellow" dist="0.8" lat="43.600000" lon="1.433333" material="BricksBasic" nbfloor="3" roofangle="15" rooftype="flat"/>
        <district designation="UPS">
          <info color="blue" dist="0.03" lat="43.560397" lon="1.468820" material="OfficeGlasses" nbfloor="4" roofangle="0" rooftype="flat"/>
        </district>
        <district designation="Centre-Ville">
          <info color="white" dist="0.03" lat="43.603236" lon="1.444659" material="BricksBasic" nbfloor="3" roofangle="15" rooftype="hipped"/>
        </district>
        <appearance>
          <values bdRooftype="mansard" color="black" doorCol="brown" floorsize="4" maxFloors="1" maxHeight="5" maxrotation="" minFloors="1" minHeight="5" openingCol="black" proba="" roofColor="black" windowfcolor="black" windowheight="tall" windowmaterial="glass" windowstyle="simple" windowwidth="2"/>
          <opening>
            <split axis="Z" children="nt4547681976|nt4629111416" parent="nt4547681752" splitvalues="0.34523809523809523,0.6547619047619048"/>
            <elements parent="nt4547681752" terms="nt4547681976,nt4629111416,"/>
          </opening>
          <ruleset file="data.xml"/>
        </appearance>
        <appearance>
          <values bdRooftype="hip" color="floralwhite" doorCol="brown" floorsize="4" maxFloors="1" maxHeight="23" maxrotation="" minFloors="1" minHeight="5" openingCol="white" proba="" roofColor="lightslategray" windowfcolor="seashell" windowheight="short" windowmaterial="glass" windowstyle="framed" windowwidth="3"/>
          <opening>
            <split axis="X" children="nt140350002036184|nt140350002036632" parent="nt140350002035064" splitvalues="0.3261904761904762,0.6738095238095239"/>
            <elements parent="nt140350002035064" terms="nt140350002036184,nt140350002036632,"/>
          </opening>
          <ruleset file="data.xml"/>
        </appearance>
      </town>
      <town designation="Paris">
        <info color="red" dist="0.8" lat="48.8534" lon="2.3488" material="BricksBasic" nbfloor="1" roofangle="15" rooftype="flat"/>
      </town>
    </region>
  </country>
  <country designation="Madagascar">
    <region designation="Analamanga">
      <town designation="Antananarivo"/>
      <town designation="Antsirabe"/>
    </region>
    <region designation="Nord">
      <town designation="Antsiranana"/>
      <town designation="Mahajanga"/>
    </region>
    <appearance>
      <values bdRoofType="mansard" color="black" doorCol="brown" floorsize="4" maxFloors="1" maxHeight="5" maxrotation=" " minFloors="1" minHeight="5" openingCol="black" proba="" roofColor="black" windowColor="black" windowHeight="tall" windowMaterial="glass" windowStyle="simple" windowWidth="2"/>
      <ruleset file="data.xml"/>
    </appearance>
    <appearance>
      <values bdRoofType="mansard" color="black" doorCol="brown" floorsize="4" maxFloors="1" maxHeight="5" maxrotation="" minFloors="1" minHeight="5" openingCol="black" proba="" roofColor="black" windowColor="black" windowHeight="tall" windowMaterial="glass" windowStyle="simple" windowWidth="2"/>
      <ruleset file="data.xml"/>
    </appearance>
  </country>
</earth>"#;

/// Thesis §3.6.2 excerpt (L1099-1136) as printed, missing quote included.
const ANTANANARIVO: &str = r#"<earth><country designation="Madagascar"><region designation="Analamanga">
<town designation="Antananarivo">
<location lat="-18,9333" lon=47,5167" dist="0,3"/>
<appearance>
<values proba="0,5" bdRooftype="gabled" color="peru" doorCol="
  ivory" floorsize="5" maxHeight="20" maxrotation="0" minHeight
  ="5" openingCol="paleturquoise" roofColor="darkred"
  windowfcolor="ivory" windowheight="tall" windowmaterial="
  glass" windowstyle="framed" windowwidth="2" />
<opening>
<split axis="X" children="nt4582467848|nt4582467288" parent="
  nt4582467064" splitvalues
  ="0.5023809523809524,0.4976190476190476" />
<split axis="Z" children="nt4582467512|nt4582468296" parent="
  nt4582467848" splitvalues
  ="0.4595238095238095,0.5404761904761906" />
<split axis="Z" children="nt4582467736|nt4582468856" parent="
  nt4582467288" splitvalues
  ="0.4595238095238095,0.5404761904761906" />
<elements parent="nt4582467064" terms="nt4582468856 ,nt4582467736
  ,nt4582467512 ,nt4582468296" />
</opening>
</appearance>
</town></region></country></earth>"#;

#[test]
fn shipped_kb_locates_the_sample_places() {
    let kb = shipped();
    assert_eq!(kb.zones()[0].kind, ZoneKind::Earth);
    // Capitole square.
    let cap = kb.locate(1.4433, 43.6045);
    assert_eq!(
        path_of(&kb, cap),
        "earth/France/Occitanie/Toulouse/Capitole"
    );
    // Les Carmes lies inside Centre-Ville's larger circle: the smaller one wins at equal depth.
    assert_eq!(
        path_of(&kb, kb.locate(1.4450, 43.5963)),
        "earth/France/Occitanie/Toulouse/Les Carmes"
    );
    // Toulouse outside every district.
    assert_eq!(
        path_of(&kb, kb.locate(1.40, 43.63)),
        "earth/France/Occitanie/Toulouse"
    );
    assert_eq!(
        path_of(&kb, kb.locate(7.4206, 43.7308)),
        "earth/Monaco/Monaco-Ville"
    );
    assert_eq!(
        path_of(&kb, kb.locate(7.4275, 43.7396)),
        "earth/Monaco/Monte-Carlo"
    );
    assert_eq!(
        path_of(&kb, kb.locate(-1.18, 52.92)),
        "earth/United Kingdom/England/Nottingham"
    );
    assert_eq!(
        path_of(&kb, kb.locate(-1.18, 52.905)),
        "earth/United Kingdom/England/Nottingham/Clifton"
    );
    assert_eq!(
        path_of(&kb, kb.locate(2.35, 48.86)),
        "earth/France/Ile-de-France/Paris"
    );
    assert_eq!(kb.locate(0.0, 0.0), 0);
    assert_eq!(kb.locate(f64::NAN, 1.0), 0);
    // Longitudes are normalised.
    assert_eq!(
        kb.locate(7.4206 + 360.0, 43.7308),
        kb.locate(7.4206, 43.7308)
    );
}

#[test]
fn locate_matches_a_brute_force_scan() {
    let kb = shipped();
    let mut rng = Rng::new(3, 3);
    for _ in 0..2000 {
        let (lon, lat) = (rng.range(-3.0, 8.0), rng.range(42.0, 55.0));
        let brute = kb
            .zones()
            .iter()
            .enumerate()
            .filter(|(_, z)| z.circle.is_some_and(|c| c.contains(lon, lat)))
            .min_by(|(i, a), (j, b)| {
                let (ra, rb) = (
                    a.circle.map_or(0.0, |c| c.radius_km),
                    b.circle.map_or(0.0, |c| c.radius_km),
                );
                b.depth.cmp(&a.depth).then(ra.total_cmp(&rb)).then(i.cmp(j))
            })
            .map_or(0, |(i, _)| i);
        assert_eq!(kb.locate(lon, lat), brute, "({lon}, {lat})");
    }
}

/// The world KB (polygons and circles): `locate` agrees with a scan of every zone's
/// [`KnowledgeBase::zone_match`] (deepest, then smaller area, then first).
#[test]
fn world_locate_matches_a_brute_force_scan() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("knowledge_base/kb.xml");
    let (kb, _) = KnowledgeBase::load(&path).unwrap();
    let mut rng = Rng::new(5, 5);
    for k in 0..600 {
        // Half over Europe, half anywhere.
        let (lon, lat) = if k % 2 == 0 {
            (rng.range(-10.0, 30.0), rng.range(36.0, 62.0))
        } else {
            (rng.range(-180.0, 180.0), rng.range(-60.0, 75.0))
        };
        let brute = (0..kb.zones().len())
            .filter_map(|i| Some((i, kb.zone_match(i, lon, lat).area_km2()?)))
            .min_by(|&(i, a), &(j, b)| {
                let (da, db) = (kb.zones()[i].depth, kb.zones()[j].depth);
                db.cmp(&da).then(a.total_cmp(&b)).then(i.cmp(&j))
            })
            .map_or(0, |(i, _)| i);
        assert_eq!(kb.locate(lon, lat), brute, "({lon}, {lat})");
    }
}

#[test]
fn circles_near_the_antimeridian_and_poles_are_found() {
    let t = r#"<earth><country designation="Fiji"><info lat="-17" lon="179.9" dist="100"/></country>
        <country designation="North"><info lat="89.5" lon="0" dist="200"/></country></earth>"#;
    let (kb, _) = KnowledgeBase::parse_str(t, "t.xml").unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(path_of(&kb, kb.locate(-179.9, -17.0)), "earth/Fiji");
    assert_eq!(path_of(&kb, kb.locate(179.5, -17.2)), "earth/Fiji");
    assert_eq!(path_of(&kb, kb.locate(120.0, 89.8)), "earth/North");
}

#[test]
fn inheritance_most_specific_wins() {
    let kb = shipped();
    let sc = kb
        .find("earth/France/Occitanie/Toulouse/Saint-Cyprien")
        .unwrap_or(usize::MAX);
    let v = kb.resolved(sc);
    assert_eq!(kb.zone(sc).and_then(|z| z.info.storeys), None);
    assert_eq!(v.storeys, Some(4), "Toulouse's nbfloor");
    assert_eq!(v.wall_color, Color::parse("#cf7b62"), "own colour");
    assert_eq!(v.roof, Some(RoofShape::Hipped), "from Toulouse");
    assert_eq!(v.window_material.as_deref(), Some("glass"), "from earth");
    assert_eq!(kb.resolved(0).storeys, Some(2));
    // Appearances: Saint-Cyprien has none, Toulouse's apply.
    let (owner, apps) = kb.appearances_for(sc);
    assert_eq!(path_of(&kb, owner), "earth/France/Occitanie/Toulouse");
    assert_eq!(apps.len(), 3);
    // La Condamine has none, Monaco's apply.
    let lc = kb.find("earth/Monaco/La Condamine").unwrap_or(usize::MAX);
    assert_eq!(path_of(&kb, kb.appearances_for(lc).0), "earth/Monaco");
    assert!(kb.resolved(usize::MAX) == Values::default());
}

/// The shipped world KB: each building-type group's probas sum to 1, and every zone's
/// appearances draw without an inconsistency note.
#[test]
fn world_probas_sum_to_one_per_building_group() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("knowledge_base/kb.xml");
    let (kb, repairs) = KnowledgeBase::load(&path).unwrap();
    assert!(repairs.is_empty(), "{repairs:?}");
    let mut groups = 0;
    for z in kb.zones() {
        let mut lists: Vec<&Vec<String>> = Vec::new();
        for a in &z.appearances {
            if !lists.contains(&&a.buildings) {
                lists.push(&a.buildings);
            }
        }
        for l in lists {
            let s: f64 = z
                .appearances
                .iter()
                .filter(|a| &a.buildings == l)
                .filter_map(|a| a.proba)
                .sum();
            assert!((s - 1.0).abs() < 1e-6, "{} {l:?}: {s}", z.path);
            groups += 1;
        }
    }
    assert!(groups > 500, "{groups} groups");
    for i in 0..kb.zones().len() {
        for (seed, kind) in [(0, None), (1, Some("house")), (2, Some("industrial"))] {
            let tags = BuildingTags {
                building: kind.map(str::to_string),
                ..Default::default()
            };
            let (_, notes) = kb.style_for(i, &tags, &mut Rng::new(seed, 0));
            assert!(notes.is_empty(), "{}: {notes:?}", path_of(&kb, i));
        }
    }
}

#[test]
fn shipped_probas_sum_to_one() {
    let kb = shipped();
    for z in kb.zones() {
        if !z.appearances.is_empty() {
            let s: f64 = z.appearances.iter().filter_map(|a| a.proba).sum();
            assert!((s - 1.0).abs() < 1e-9, "{}: {s}", z.path);
        }
    }
    // Floors and height ranges of every shipped appearance agree.
    for i in 0..kb.zones().len() {
        for seed in 0..50 {
            let (_, notes) = kb.style_for(i, &BuildingTags::default(), &mut Rng::new(seed, 0));
            assert!(notes.is_empty(), "{}: {notes:?}", path_of(&kb, i));
        }
    }
}

#[test]
fn appearance_picks_follow_proba() {
    let kb = shipped();
    let cap = kb
        .find("earth/France/Occitanie/Toulouse/Capitole")
        .unwrap_or(usize::MAX);
    let mut counts = [0usize; 2];
    let n = 20_000;
    for seed in 0..n {
        let mut rng = Rng::new(seed, 99);
        if let Some((owner, i)) = kb.pick_appearance(cap, None, None, &mut rng) {
            assert_eq!(owner, cap);
            counts[i] += 1;
        }
    }
    assert_eq!(counts[0] + counts[1], n as usize);
    assert!(
        (counts[0] as f64 / n as f64 - 0.7).abs() < 0.02,
        "{counts:?}"
    );
}

#[test]
fn absent_probas_share_the_remainder() {
    let app = |p: Option<f64>| Appearance {
        proba: p,
        values: Values::default(),
        opening: None,
        ruleset: None,
        selex: None,
        buildings: Vec::new(),
        when: Default::default(),
        line: 1,
    };
    assert_eq!(appearance_weights(&[app(None), app(None)]), vec![0.5, 0.5]);
    let w = appearance_weights(&[app(Some(0.5)), app(None), app(None)]);
    assert!(
        (w[1] - 0.25).abs() < 1e-12 && (w[2] - 0.25).abs() < 1e-12,
        "{w:?}"
    );
    // Over-full: the given ones are normalised, the absent get nothing.
    assert_eq!(
        appearance_weights(&[app(Some(1.0)), app(Some(1.0)), app(None)]),
        vec![0.5, 0.5, 0.0]
    );
    assert!(appearance_weights(&[]).is_empty());
}

#[test]
fn styles_are_deterministic_and_within_ranges() {
    let kb = shipped();
    let mc = kb.locate(7.4275, 43.7396);
    let tags = BuildingTags::default();
    for seed in 0..200 {
        let (a, _) = kb.style_for(mc, &tags, &mut Rng::new(seed, 7));
        let (b, _) = kb.style_for(mc, &tags, &mut Rng::new(seed, 7));
        assert_eq!(a, b);
        assert_eq!(a.zone_path, "earth/Monaco/Monte-Carlo");
        assert!(
            a.appearance_label.starts_with("earth/Monaco/Monte-Carlo#"),
            "{}",
            a.appearance_label
        );
        assert!((6..=12).contains(&a.storeys), "{}", a.storeys);
        assert!((a.eave_height - f64::from(a.storeys) * a.floor_height).abs() < 1e-9);
        if a.roof == RoofShape::Flat {
            assert_eq!(a.roof_height, Some(0.0));
        }
    }
    // Over many seeds, all three Monte-Carlo appearances occur.
    let labels: std::collections::BTreeSet<String> = (0..200)
        .map(|s| {
            kb.style_for(mc, &tags, &mut Rng::new(s, 1))
                .0
                .appearance_label
        })
        .collect();
    assert_eq!(labels.len(), 3, "{labels:?}");
}

#[test]
fn osm_tags_override_the_kb() {
    let kb = shipped();
    let not = kb.locate(-1.15, 52.95);
    let tags = BuildingTags {
        levels: Some(5.0),
        roof_shape: Some(RoofShape::Flat),
        colour: Color::parse("navy"),
        roof_colour: Color::parse("black"),
        ..BuildingTags::default()
    };
    let (s, notes) = kb.style_for(not, &tags, &mut Rng::new(1, 1));
    assert_eq!(s.storeys, 5);
    assert!(s.storeys_from_tags);
    assert!((s.eave_height - 5.0 * 2.7).abs() < 1e-9);
    assert_eq!(s.roof, RoofShape::Flat);
    assert_eq!(s.wall_color, Color::parse("navy").unwrap_or(Color::WHITE));
    assert_eq!(s.roof_color, Color::parse("black").unwrap_or(Color::WHITE));
    // Plain overrides are not worth a report entry: only conflicts and repairs are.
    assert!(notes.is_empty(), "{notes:?}");

    // height with a tagged roof height: eave = height - roof height.
    let tags = BuildingTags {
        height: Some(12.0),
        roof_height: Some(3.0),
        ..BuildingTags::default()
    };
    let (s, _) = kb.style_for(not, &tags, &mut Rng::new(1, 1));
    assert_eq!(s.total_height, Some(12.0));
    assert!((s.eave_height - 9.0).abs() < 1e-9);
    assert_eq!(s.storeys, 3);

    // height with a pitched roof of unknown height: the caller fits it.
    let tags = BuildingTags {
        height: Some(20.0),
        roof_shape: Some(RoofShape::Gabled),
        ..BuildingTags::default()
    };
    let (mut s, _) = kb.style_for(not, &tags, &mut Rng::new(1, 1));
    assert_eq!(s.roof_height, None);
    s.fit_total_height(4.0);
    assert!((s.eave_height - 16.0).abs() < 1e-9);
    assert_eq!(s.storeys, 6);

    // min_height raises the base; a base above the walls is fixed and noted.
    let tags = BuildingTags {
        min_height: Some(30.0),
        height: Some(10.0),
        roof_shape: Some(RoofShape::Flat),
        ..BuildingTags::default()
    };
    let (s, notes) = kb.style_for(not, &tags, &mut Rng::new(1, 1));
    assert!(s.eave_height > s.min_height && s.min_height == 30.0);
    assert!(
        notes.iter().any(|n| n.contains("not above base")),
        "{notes:?}"
    );
}

#[test]
fn defaults_apply_on_an_empty_kb() {
    let (kb, _) = KnowledgeBase::parse_str("<earth/>", "e.xml").unwrap_or_else(|e| panic!("{e}"));
    let (s, _) = kb.style_for(0, &BuildingTags::default(), &mut Rng::new(0, 0));
    assert_eq!(s.floor_height, defaults::FLOOR_HEIGHT);
    assert_eq!(s.storeys, defaults::STOREYS);
    assert_eq!(s.roof, defaults::ROOF);
    assert_eq!(s.roof_angle_deg, 30.0);
    assert_eq!(s.wall_color, Color::WHITE);
    assert_eq!(
        s.roof_color,
        Color::parse("darkred").unwrap_or(Color::WHITE)
    );
    assert_eq!(s.appearance_label, "earth#info");
    // Out-of-range zone index: earth.
    assert_eq!(
        kb.style_for(42, &BuildingTags::default(), &mut Rng::new(0, 0))
            .0
            .zone_path,
        "earth"
    );
}

#[test]
fn thesis_annex_reconstruction_reads() {
    let (kb, repairs) =
        KnowledgeBase::parse_str(ANNEX, "annex.xml").unwrap_or_else(|e| panic!("{e}"));
    let paths: Vec<&str> = kb.zones().iter().map(|z| z.path.as_str()).collect();
    assert_eq!(
        paths,
        [
            "earth",
            "earth/France",
            "earth/France/Midi-Pyrenees",
            "earth/France/Midi-Pyrenees/Toulouse",
            "earth/France/Midi-Pyrenees/Toulouse/UPS",
            "earth/France/Midi-Pyrenees/Toulouse/Centre-Ville",
            "earth/France/Midi-Pyrenees/Paris",
            "earth/Madagascar",
            "earth/Madagascar/Analamanga",
            "earth/Madagascar/Analamanga/Antananarivo",
            "earth/Madagascar/Analamanga/Antsirabe",
            "earth/Madagascar/Nord",
            "earth/Madagascar/Nord/Antsiranana",
            "earth/Madagascar/Nord/Mahajanga",
        ]
    );
    assert_eq!(kb.zones()[0].info.wall_color, Some(Color::WHITE), "1;1;1");
    assert_eq!(kb.zones()[1].info.roof, Some(RoofShape::Gabled), "gabbled");
    let ups = kb
        .find("earth/France/Midi-Pyrenees/Toulouse/UPS")
        .unwrap_or(usize::MAX);
    assert_eq!(
        kb.zone(ups).map(|z| z.kind.clone()),
        Some(ZoneKind::District)
    );
    // dist is read as km: 0.03 km = 30 m around the UPS centre.
    assert_eq!(kb.locate(1.468820, 43.560397), ups);
    assert_ne!(kb.locate(1.4700, 43.5610), ups);
    // UPS has no appearances: Toulouse's two apply, uniformly (empty probas).
    let (owner, apps) = kb.appearances_for(ups);
    assert_eq!(path_of(&kb, owner), "earth/France/Midi-Pyrenees/Toulouse");
    assert_eq!(appearance_weights(apps), vec![0.5, 0.5]);
    assert_eq!(apps[1].values.roof, Some(RoofShape::Hipped), "hip");
    assert_eq!(apps[0].opening.as_ref().map(|o| o.terms.len()), Some(2));
    assert!(repairs.iter().any(|r| r.what.contains("trailing comma")));
    // Madagascar: windowColor read as the frame colour; maxrotation=" " absent.
    let mg = kb.find("earth/Madagascar").unwrap_or(usize::MAX);
    let a = kb
        .zone(mg)
        .map(|z| z.appearances[0].values.clone())
        .unwrap_or_default();
    assert_eq!(a.frame_color, Color::parse("black"));
    assert_eq!(a.max_rotation, None);
    assert_eq!(a.window_height, Some(WindowHeight::Tall));
}

#[test]
fn thesis_excerpt_with_decimal_commas_reads() {
    let (kb, repairs) =
        KnowledgeBase::parse_str(ANTANANARIVO, "s362.xml").unwrap_or_else(|e| panic!("{e}"));
    let tana = kb
        .find("earth/Madagascar/Analamanga/Antananarivo")
        .unwrap_or(usize::MAX);
    let z = kb.zone(tana).unwrap_or_else(|| panic!("no zone"));
    let c = z.circle.unwrap_or_else(|| panic!("no circle"));
    assert!(
        (c.lat + 18.9333).abs() < 1e-12
            && (c.lon - 47.5167).abs() < 1e-12
            && (c.radius_km - 0.3).abs() < 1e-12
    );
    assert_eq!(z.appearances[0].proba, Some(0.5));
    assert_eq!(z.appearances[0].values.door_color, Color::parse("ivory"));
    assert_eq!(z.appearances[0].values.min_height, Some(5.0));
    let o = z.appearances[0]
        .opening
        .clone()
        .unwrap_or_else(|| panic!("no opening"));
    assert_eq!(o.root, "nt4582467064");
    assert_eq!(o.splits.len(), 3);
    assert_eq!(o.terms.len(), 4);
    assert!(
        repairs
            .iter()
            .any(|r| r.line == 3 && r.what.contains("quotes")),
        "{repairs:?}"
    );
    // The style compiles to three opening rsplit rules.
    assert_eq!(kb.locate(47.5167, -18.9333), tana);
    let (s, _) = kb.style_for(tana, &BuildingTags::default(), &mut Rng::new(5, 5));
    assert_eq!(
        s.appearance_label,
        "earth/Madagascar/Analamanga/Antananarivo#1"
    );
    assert_eq!(s.floor_height, 5.0);
    let text = compile::ruleset_text(&s);
    assert_eq!(
        text.lines()
            .filter(|l| l.starts_with("opening") || l.starts_with("nt"))
            .count(),
        3,
        "{text}"
    );
}

#[test]
fn ruleset_paths_stay_inside_the_kb_folder() {
    let t = r#"<earth><appearance><ruleset file="rules/a.txt"/></appearance><appearance><ruleset file="../../etc/passwd"/></appearance></earth>"#;
    let (kb, _) = KnowledgeBase::parse_str(t, "r.xml").unwrap_or_else(|e| panic!("{e}"));
    assert!(matches!(kb.ruleset_path(0, 0, false), Ok(Some(_))));
    assert!(kb.ruleset_path(0, 1, false).is_err());
    assert!(matches!(kb.ruleset_path(0, 1, true), Ok(Some(_))));
    assert!(matches!(kb.ruleset_path(0, 5, false), Ok(None)));
}

#[test]
fn load_names_the_file_on_errors() {
    let err = KnowledgeBase::load(Path::new("/nonexistent/kb.xml"))
        .err()
        .map(|e| e.to_string())
        .unwrap_or_default();
    assert!(err.contains("/nonexistent/kb.xml"), "{err}");
}

/// Thesis annex as printed (seed 003 notes §5.1, L1605-1710), the PDF page breaks removed, with
/// all its markup slips: missing '<', a lost closing quote, whitespace after '<', ...
const ANNEX_VERBATIM: &str = include_str!("../../tests/data/thesis_annex.xml");

#[test]
fn thesis_annex_as_printed_reads_with_repairs() {
    let (kb, repairs) =
        KnowledgeBase::parse_str(ANNEX_VERBATIM, "annex.xml").unwrap_or_else(|e| panic!("{e}"));
    let (clean, _) = KnowledgeBase::parse_str(ANNEX, "clean.xml").unwrap_or_else(|e| panic!("{e}"));
    let paths = |k: &KnowledgeBase| k.zones().iter().map(|z| z.path.clone()).collect::<Vec<_>>();
    assert_eq!(paths(&kb), paths(&clean));
    for (a, b) in kb.zones().iter().zip(clean.zones()) {
        assert_eq!(a.info, b.info, "{}", a.path);
        assert_eq!(a.circle, b.circle, "{}", a.path);
        let strip = |z: &Zone| {
            z.appearances
                .iter()
                .map(|a| {
                    (
                        a.proba,
                        a.values.clone(),
                        a.opening.clone(),
                        a.ruleset.clone(),
                    )
                })
                .collect::<Vec<_>>()
        };
        assert_eq!(strip(a), strip(b), "{}", a.path);
    }
    let has = |line: usize, what: &str| {
        repairs
            .iter()
            .any(|r| r.line == line && r.what.contains(what))
    };
    assert!(has(38, "lost its closing quote"), "{repairs:?}");
    assert!(has(49, "missing '<' before element 'ruleset'"));
    assert!(has(74, "missing '<' before element 'country'"));
    assert!(has(75, "missing '<' before element 'region'"));
    assert!(has(46, "whitespace between '<'"));
    assert!(
        repairs.windows(2).all(|w| w[0].line <= w[1].line),
        "sorted by line"
    );
}

#[test]
fn every_shipped_style_derives_with_the_grammar() {
    use crate::geometry::Polygon;
    use crate::grammar::{derive, parse, Caps};
    use glam::DVec2;
    let kb = shipped();
    let lot = Polygon::new(
        vec![
            DVec2::new(0.0, 0.0),
            DVec2::new(14.0, 0.0),
            DVec2::new(14.0, 10.0),
            DVec2::new(0.0, 10.0),
        ],
        Vec::new(),
    );
    for i in 0..kb.zones().len() {
        for seed in 0..4 {
            let (s, _) = kb.style_for(i, &BuildingTags::default(), &mut Rng::new(seed, 11));
            let text = compile::ruleset_text(&s);
            let rules = parse(&text, "kb.rules").unwrap_or_else(|e| panic!("{e}\n{text}"));
            let tree = derive(
                &rules,
                &lot,
                compile::axiom_attrs(&s),
                &mut Rng::new(seed, 12),
                &Caps::default(),
            )
            .unwrap_or_else(|e| panic!("{}: {e}\n{text}", s.appearance_label));
            assert!(tree.nodes.len() > 10, "{}", s.appearance_label);
        }
    }
}

#[test]
fn invalid_roof_shape_tag_draws_flat_with_a_note() {
    let kb = shipped();
    let zone = kb.locate(-1.15, 52.95);
    for v in ["9.0", "many"] {
        let tags = BuildingTags::from_pairs([("building", "yes"), ("roof:shape", v)]);
        assert_eq!(tags.roof_shape, None);
        let (s, notes) = kb.style_for(zone, &tags, &mut Rng::new(1, 1));
        assert_eq!(s.roof, RoofShape::Flat, "{v}");
        assert_eq!(s.roof_height, Some(0.0));
        assert!(
            notes.iter().any(|n| n.contains(&format!("roof:shape={v}"))),
            "{notes:?}"
        );
    }
}

#[test]
fn shipped_kb_reads_strictly_with_no_repair() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("knowledge_base/kb.xml");
    match KnowledgeBase::load_with(&path, ReadMode::Strict) {
        Ok((kb, repairs)) => {
            assert!(repairs.is_empty());
            assert!(kb.zones().len() > 20);
        }
        Err(e) => panic!("{e}"),
    }
}

// ---- polygon zones -------------------------------------------------------------------------

/// A town circle (r = 2 km) with a square polygon district well inside it, a circle district,
/// and two sibling polygon districts of different sizes overlapping at one corner.
const POLYGONS: &str = r#"<earth>
  <info nbfloor="1"/>
  <town designation="T">
    <info lat="43.6000" lon="1.4400" dist="2" nbfloor="3"/>
    <district designation="Square">
      <info nbfloor="5"/>
      <polygon points="1.4400 43.6000, 1.4450 43.6000, 1.4450 43.6030, 1.4400 43.6030"/>
    </district>
    <district designation="Big">
      <info nbfloor="6"/>
      <polygon points="1.4300 43.5900, 1.4380 43.5900, 1.4380 43.5980, 1.4300 43.5980"/>
    </district>
    <district designation="Small">
      <info nbfloor="7"/>
      <polygon points="1.4370 43.5970, 1.4390 43.5970, 1.4390 43.5990, 1.4370 43.5990"/>
    </district>
    <district designation="Twin">
      <info nbfloor="8"/>
      <polygon points="1.4370 43.5970, 1.4390 43.5970, 1.4390 43.5990, 1.4370 43.5990"/>
    </district>
    <district designation="Both">
      <info nbfloor="9"/>
      <location lat="43.6100" lon="1.4300" dist="0.2"/>
      <polygon points="1.4500 43.6100, 1.4510 43.6100, 1.4510 43.6110"/>
    </district>
  </town>
</earth>"#;

fn polygons_kb() -> KnowledgeBase {
    for mode in [ReadMode::Lenient, ReadMode::Strict] {
        if let Err(e) = KnowledgeBase::parse_str_with(POLYGONS, "poly.xml", mode) {
            panic!("{mode:?}: {e}");
        }
    }
    match KnowledgeBase::parse_str_with(POLYGONS, "poly.xml", ReadMode::Strict) {
        Ok((kb, _)) => kb,
        Err(e) => panic!("{e}"),
    }
}

#[test]
fn polygon_zone_inside_a_circle_zone() {
    let kb = polygons_kb();
    let square = kb.locate(1.4425, 43.6015);
    assert_eq!(path_of(&kb, square), "earth/T/Square");
    assert_eq!(kb.resolved(square).storeys, Some(5));
    assert!(matches!(
        kb.zone_match(square, 1.4425, 43.6015),
        ZoneMatch::Polygon { index: 0, .. }
    ));
    // In the town's circle, outside the square: the town.
    let t = kb.locate(1.4460, 43.6015);
    assert_eq!(path_of(&kb, t), "earth/T");
    assert_eq!(kb.resolved(t).storeys, Some(3));
    assert!(matches!(
        kb.zone_match(t, 1.4460, 43.6015),
        ZoneMatch::Circle { .. }
    ));
    // Outside everything: earth.
    assert_eq!(kb.locate(2.0, 44.0), 0);
    // A zone with a circle and a triangle: both shapes match.
    assert_eq!(path_of(&kb, kb.locate(1.4300, 43.6100)), "earth/T/Both");
    assert_eq!(path_of(&kb, kb.locate(1.4508, 43.6102)), "earth/T/Both");
    // Outside the triangle (above its hypotenuse) but inside its bounding box.
    assert_eq!(path_of(&kb, kb.locate(1.4502, 43.6108)), "earth/T");
}

#[test]
fn polygon_ties_go_to_the_smaller_area_then_document_order() {
    let kb = polygons_kb();
    // In Big only.
    assert_eq!(path_of(&kb, kb.locate(1.4340, 43.5940)), "earth/T/Big");
    // In Big, Small and Twin (same depth): Small and Twin are smaller than Big, and equal to
    // each other: Small comes first in the document.
    assert_eq!(path_of(&kb, kb.locate(1.4375, 43.5975)), "earth/T/Small");
    // In Small and Twin but not Big.
    assert_eq!(path_of(&kb, kb.locate(1.4385, 43.5985)), "earth/T/Small");
    let e = tools::explain(&kb, 1.4375, 43.5975, &BuildingTags::default(), 1, 1);
    let lost: Vec<&str> = e.tied.iter().map(|(p, _)| p.as_str()).collect();
    assert_eq!(lost, vec!["earth/T/Big", "earth/T/Twin"]);
}

#[test]
fn locate_with_polygons_matches_a_brute_force_scan() {
    let kb = polygons_kb();
    for k in 0..400 {
        let lon = 1.425 + (k % 20) as f64 * 0.0015;
        let lat = 43.585 + (k / 20) as f64 * 0.0015;
        let mut best: Option<(usize, f64, usize)> = None;
        for (i, z) in kb.zones().iter().enumerate() {
            let Some(a) = kb.zone_match(i, lon, lat).area_km2() else {
                continue;
            };
            if best.is_none_or(|(d, ba, _)| z.depth > d || (z.depth == d && a < ba)) {
                best = Some((z.depth, a, i));
            }
        }
        assert_eq!(kb.locate(lon, lat), best.map_or(0, |b| b.2), "{lon} {lat}");
    }
}

#[test]
fn bad_polygons_are_repaired_leniently_and_refused_strictly() {
    let t =
        "<earth>\n<town designation=\"T\">\n<polygon points=\"1 1, 2 2, 3 3\"/>\n</town>\n</earth>";
    let (kb, rep) = KnowledgeBase::parse_str(t, "p.xml").unwrap_or_else(|e| panic!("{e}"));
    assert!(kb.zones()[1].polygons.is_empty());
    assert!(
        rep.iter()
            .any(|r| r.line == 3 && r.what.contains("crosses itself")),
        "{rep:?}"
    );
    match KnowledgeBase::parse_str_with(t, "p.xml", ReadMode::Strict) {
        Err(KbError::Strict {
            line: 3,
            col: 10,
            message,
            ..
        }) => {
            assert!(message.contains("crosses itself"), "{message}")
        }
        other => panic!("{other:?}"),
    }
}

// ---- strict reader -------------------------------------------------------------------------

#[test]
fn strict_rejects_what_lenient_repairs_with_file_line_col() {
    let cases: [(&str, usize, usize, &str); 9] = [
        ("<earth>\n<country designation=\"F\">\n  <info lat=\"1,5\" lon=\"2\" dist=\"3\"/>\n</country>\n</earth>", 3, 9, "decimal comma"),
        ("<earth>\n<country designation=\"F\">\n  <info lat=\"1.5\" lon=\"2\" dist=\"3\" colour=\"red\"/>\n</country>\n</earth>", 3, 36, "unknown attribute 'colour'"),
        ("<earth>\n<country designation=\"F\">\n  <info lat=\"1.5\" lon=\"2\" dist=\"3\" roofcolor=\"red\"/>\n</country>\n</earth>", 3, 36, "did you mean 'roofColor'"),
        ("<earth>\n<Country designation=\"F\"/>\n</earth>", 2, 1, "did you mean <country>"),
        ("<earth>\n<country designation=\"F\">\n  <info lat=1.5 lon=\"2\" dist=\"3\"/>\n</country>\n</earth>", 3, 3, ""),
        ("<earth>\n<country designation=\"\"/>\n</earth>", 2, 10, "empty value"),
        ("<earth>\n<country designation=\"F\">\n  <appearance><values proba=\"\"/></appearance>\n</country>\n</earth>", 3, 23, "empty value"),
        ("<earth>\n  <info rooftype=\"gabbled\"/>\n</earth>", 2, 9, "OSM roof:shape"),
        ("<earth>\ncountry designation=\"F\"/>\n</earth>", 2, 1, "lost '<'"),
    ];
    for (text, line, col, want) in cases {
        assert!(
            KnowledgeBase::parse_str(text, "s.xml").is_ok(),
            "lenient reads {text}"
        );
        match KnowledgeBase::parse_str_with(text, "s.xml", ReadMode::Strict) {
            Err(e @ (KbError::Strict { .. } | KbError::Xml { .. })) => {
                let msg = e.to_string();
                assert!(
                    msg.starts_with(&format!("s.xml:{line}:{col}: ")),
                    "{text}\n{msg}"
                );
                assert!(msg.contains(want), "{msg}");
            }
            other => panic!("{text}: {other:?}"),
        }
    }
}

#[test]
fn strict_enforces_the_schema_order_and_counts() {
    let bad = [
        "<earth><country designation=\"F\"><appearance><values/></appearance><info nbfloor=\"1\"/></country></earth>",
        "<earth><info/><info/></earth>",
        "<earth><appearance><opening><split axis=\"X\" parent=\"a\" children=\"b|c\" splitvalues=\"0.5,0.5\"/></opening></appearance></earth>",
        "<earth><appearance><values/><opening><split axis=\"x\" parent=\"a\" children=\"b|c\" splitvalues=\"0.5,0.5\"/></opening></appearance></earth>",
        "<earth><appearance><values/><opening><split axis=\"X\" parent=\"a\" children=\"b|c\" splitvalues=\"0.5,0.5\"/><elements parent=\"a\" terms=\"b,c,\"/></opening></appearance></earth>",
        "<earth><country designation=\"F\"><location lat=\"1\" lon=\"2\"/></country></earth>",
        "<earth><appearance><values color=\"Red\"/></appearance></earth>",
        "<earth><appearance><values color=\"1;1;1\"/></appearance></earth>",
        "<earth><appearance><values windowColor=\"red\"/></appearance></earth>",
    ];
    for t in bad {
        assert!(
            matches!(
                KnowledgeBase::parse_str_with(t, "o.xml", ReadMode::Strict),
                Err(KbError::Strict { .. })
            ),
            "{t}"
        );
    }
    let good = "<earth><info nbfloor=\"1\"/><appearance><values proba=\"1\" color=\"#aabbcc\"/><opening><split axis=\"X\" parent=\"a\" children=\"b|c\" splitvalues=\"0.5,0.5\"/><elements parent=\"a\" terms=\"b,c\"/></opening><ruleset file=\"r.cga\"/></appearance><zone designation=\"Z\"><location lat=\"1\" lon=\"2\" dist=\"3\"/></zone></earth>";
    if let Err(e) = KnowledgeBase::parse_str_with(good, "g.xml", ReadMode::Strict) {
        panic!("{e}");
    }
}

#[test]
fn the_thesis_annex_is_refused_strictly() {
    assert!(matches!(
        KnowledgeBase::parse_str_with(ANNEX_VERBATIM, "annex.xml", ReadMode::Strict),
        Err(KbError::Strict { .. } | KbError::Xml { .. })
    ));
}

// ---- safety --------------------------------------------------------------------------------

const BILLION_LAUGHS: &str = r#"<?xml version="1.0"?>
<!DOCTYPE earth [
  <!ENTITY lol "lol">
  <!ENTITY lol1 "&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;">
  <!ENTITY lol2 "&lol1;&lol1;&lol1;&lol1;&lol1;&lol1;&lol1;&lol1;&lol1;&lol1;">
  <!ENTITY lol3 "&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;">
  <!ENTITY lol4 "&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;">
  <!ENTITY lol5 "&lol4;&lol4;&lol4;&lol4;&lol4;&lol4;&lol4;&lol4;&lol4;&lol4;">
  <!ENTITY lol6 "&lol5;&lol5;&lol5;&lol5;&lol5;&lol5;&lol5;&lol5;&lol5;&lol5;">
  <!ENTITY lol7 "&lol6;&lol6;&lol6;&lol6;&lol6;&lol6;&lol6;&lol6;&lol6;&lol6;">
  <!ENTITY lol8 "&lol7;&lol7;&lol7;&lol7;&lol7;&lol7;&lol7;&lol7;&lol7;&lol7;">
  <!ENTITY lol9 "&lol8;&lol8;&lol8;&lol8;&lol8;&lol8;&lol8;&lol8;&lol8;&lol8;">
]>
<earth><country designation="&lol9;"/></earth>"#;

const EXTERNAL_ENTITY: &str = r#"<?xml version="1.0"?>
<!DOCTYPE earth [ <!ENTITY x SYSTEM "file:///etc/passwd"> ]>
<earth><country designation="&x;"/></earth>"#;

#[test]
fn billion_laughs_and_external_entities_are_refused_quickly() {
    for (name, text) in [("laughs.xml", BILLION_LAUGHS), ("xxe.xml", EXTERNAL_ENTITY)] {
        for mode in [ReadMode::Lenient, ReadMode::Strict] {
            let t0 = std::time::Instant::now();
            let r = KnowledgeBase::parse_str_with(text, name, mode);
            assert!(
                t0.elapsed().as_secs_f64() < 1.0,
                "{name} {mode:?} took too long"
            );
            match r {
                Err(
                    e @ KbError::Doctype {
                        line: 2, col: 1, ..
                    },
                ) => {
                    let msg = e.to_string();
                    assert!(msg.starts_with(&format!("{name}:2:1: ")), "{msg}");
                    assert!(msg.contains("never expanded"), "{msg}");
                }
                other => panic!("{name} {mode:?}: {other:?}"),
            }
        }
    }
    // Without a DOCTYPE an entity reference is an undefined entity, not a file read.
    let r = KnowledgeBase::parse_str(r#"<earth><country designation="&x;"/></earth>"#, "u.xml");
    assert!(matches!(r, Err(KbError::Xml { line: 1, .. })), "{r:?}");
}

#[test]
fn depth_attribute_and_size_caps() {
    let deep = format!(
        "<earth>{}{}</earth>",
        "<zone designation=\"z\">".repeat(dom::MAX_DEPTH),
        "</zone>".repeat(dom::MAX_DEPTH)
    );
    match KnowledgeBase::parse_str(&deep, "deep.xml") {
        Err(e @ KbError::Limit { line: 1, .. }) => {
            assert!(e.to_string().contains("nested more than 64"), "{e}")
        }
        other => panic!("{other:?}"),
    }
    let ok_depth = format!(
        "<earth>{}{}</earth>",
        "<zone designation=\"z\">".repeat(dom::MAX_DEPTH - 1),
        "</zone>".repeat(dom::MAX_DEPTH - 1)
    );
    assert!(KnowledgeBase::parse_str_with(&ok_depth, "ok.xml", ReadMode::Strict).is_ok());

    let attrs: String = (0..=dom::MAX_ATTRIBUTES)
        .map(|i| format!(" a{i}=\"1\""))
        .collect();
    let many = format!("<earth>\n  <info{attrs}/></earth>");
    match KnowledgeBase::parse_str(&many, "attrs.xml") {
        Err(KbError::Limit {
            line: 2,
            col: 3,
            message,
            ..
        }) => {
            assert!(message.contains("more than 256 attributes"), "{message}")
        }
        other => panic!("{other:?}"),
    }

    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let big = dir.path().join("big.xml");
    let f = std::fs::File::create(&big).unwrap_or_else(|e| panic!("{e}"));
    // A sparse file: no 64 MiB written to disk.
    f.set_len(dom::MAX_FILE_BYTES + 1)
        .unwrap_or_else(|e| panic!("{e}"));
    match KnowledgeBase::load(&big) {
        Err(e @ KbError::Limit { .. }) => assert!(e.to_string().contains("cap"), "{e}"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn rulesets_outside_the_folder_are_check_errors_unless_allowed() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let kb = dir.path().join("kb.xml");
    let text = "<earth>\n<appearance><values/><ruleset file=\"../x.cga\"/></appearance>\n<appearance><values/><ruleset file=\"/etc/x.cga\"/></appearance>\n<appearance><values/><ruleset file=\"rules/ok.cga\"/></appearance>\n</earth>";
    std::fs::write(&kb, text).unwrap_or_else(|e| panic!("{e}"));
    let r = tools::check_report(&kb, ReadMode::Strict).unwrap_or_else(|e| panic!("{e}"));
    assert!(r.has_errors());
    let lines: Vec<usize> = r.errors.iter().map(|e| e.line).collect();
    assert_eq!(lines, vec![2, 3]);
    assert!(r.errors[0].what.contains("../x.cga") && r.errors[0].what.contains("outside"));
    let shown = r.to_string();
    assert!(shown.contains(":2: error: "), "{shown}");
    let r = tools::check_report_with(&kb, ReadMode::Strict, true).unwrap_or_else(|e| panic!("{e}"));
    assert!(!r.has_errors());
    // The resolved paths: inside the KB folder for the relative one.
    let (k, _) = KnowledgeBase::load(&kb).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(
        k.ruleset_path(0, 2, false).ok().flatten(),
        Some(dir.path().join("rules/ok.cga"))
    );
}

// ---- tools: check, compile, explain --------------------------------------------------------

#[test]
fn check_of_the_thesis_annex_repairs_with_lines_and_gives_the_zone_tree() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/thesis_annex.xml");
    let r = tools::check_report(&path, ReadMode::Lenient).unwrap_or_else(|e| panic!("{e}"));
    assert!(!r.has_errors(), "{r}");
    assert!(r.repairs.len() > 20, "{r}");
    assert!(
        r.repairs.iter().all(|x| x.line >= 1 && x.line <= 110),
        "{r}"
    );
    let shown = r.to_string();
    assert!(
        shown.contains(
            "thesis_annex.xml:38: repair: attribute 'maxrotation' lost its closing quote"
        ),
        "{shown}"
    );
    assert!(
        shown.contains(":74: repair: added the missing '<' before element 'country'"),
        "{shown}"
    );

    let (kb, _) = KnowledgeBase::load(&path).unwrap_or_else(|e| panic!("{e}"));
    let tree: Vec<(&str, usize)> = kb
        .zones()
        .iter()
        .map(|z| (z.path.as_str(), z.depth))
        .collect();
    assert_eq!(
        &tree[..8],
        &[
            ("earth", 0),
            ("earth/France", 1),
            ("earth/France/Midi-Pyrenees", 2),
            ("earth/France/Midi-Pyrenees/Toulouse", 3),
            ("earth/France/Midi-Pyrenees/Toulouse/UPS", 4),
            ("earth/France/Midi-Pyrenees/Toulouse/Centre-Ville", 4),
            ("earth/France/Midi-Pyrenees/Paris", 3),
            ("earth/Madagascar", 1),
        ]
    );
    assert_eq!(r.zones, kb.zones().len());
    let z = |p: &str| kb.zone(kb.find(p).unwrap_or(usize::MAX)).cloned();
    let france = z("earth/France").unwrap_or_else(|| panic!("France"));
    assert_eq!(france.info.roof, Some(RoofShape::Gabled)); // "\n gabbled"
    assert_eq!(france.info.wall_color, Color::parse("pink"));
    assert_eq!(
        france.circle.map(|c| (c.lat, c.lon, c.radius_km)),
        Some((47.38333, 0.68333, 5.0))
    );
    let ups = z("earth/France/Midi-Pyrenees/Toulouse/UPS").unwrap_or_else(|| panic!("UPS"));
    assert_eq!(ups.info.material.as_deref(), Some("OfficeGlasses")); // "\n OfficeGlasses"
    assert_eq!(ups.info.roof, Some(RoofShape::Flat)); // "flat "
    assert_eq!(ups.info.storeys, Some(4));
    let cv = z("earth/France/Midi-Pyrenees/Toulouse/Centre-Ville").unwrap_or_else(|| panic!("CV"));
    assert_eq!(cv.info.roof, Some(RoofShape::Hipped));
    assert_eq!(cv.info.material.as_deref(), Some("BricksBasic"));
    let toulouse = z("earth/France/Midi-Pyrenees/Toulouse").unwrap_or_else(|| panic!("T"));
    assert_eq!(toulouse.appearances.len(), 2);
    assert_eq!(toulouse.appearances[0].proba, None); // proba=""
    assert_eq!(
        toulouse.appearances[0].values.roof,
        Some(RoofShape::Mansard)
    );
    assert_eq!(toulouse.appearances[1].values.roof, Some(RoofShape::Hipped)); // "hip"
    assert_eq!(toulouse.appearances[0].ruleset.as_deref(), Some("data.xml"));
    // Inherited: UPS has its own nbfloor; Centre-Ville inherits nothing it does not set.
    assert_eq!(
        kb.resolved(
            kb.find("earth/France/Midi-Pyrenees/Toulouse/UPS")
                .unwrap_or(0)
        )
        .storeys,
        Some(4)
    );
}

#[test]
fn compile_zone_output_parses_for_every_appearance_of_the_default_kb() {
    let kb = shipped();
    let mut n = 0;
    for z in kb.zones() {
        let rel = z.path.trim_start_matches("earth").trim_start_matches('/');
        let out = tools::compile_zone(&kb, rel).unwrap_or_else(|e| panic!("{e}"));
        let (owner, apps) = kb.appearances_for(kb.find(&z.path).unwrap_or(0));
        assert_eq!(out.len(), apps.len().max(1), "{}", z.path);
        for (k, (label, text)) in out.iter().enumerate() {
            if !apps.is_empty() {
                assert_eq!(label, &format!("{}#{}", kb.zone_path(owner), k + 1));
            }
            if let Err(e) = crate::grammar::parse(text, label) {
                panic!("{label}: {e}\n{text}");
            }
            n += 1;
        }
    }
    assert!(n > 30);
    // Paths: with or without earth/, any case.
    let a = tools::compile_zone(&kb, "France/Occitanie/Toulouse/Centre-Ville");
    let b = tools::compile_zone(&kb, "EARTH/france/occitanie/toulouse/centre-ville/");
    assert!(a.is_ok());
    assert_eq!(a.ok(), b.ok());
    // Centre-Ville has no appearance of its own: Toulouse's three apply.
    let labels: Vec<String> = tools::compile_zone(&kb, "France/Occitanie/Toulouse/Centre-Ville")
        .unwrap_or_default()
        .into_iter()
        .map(|(l, _)| l)
        .collect();
    assert_eq!(
        labels,
        vec![
            "earth/France/Occitanie/Toulouse#1",
            "earth/France/Occitanie/Toulouse#2",
            "earth/France/Occitanie/Toulouse#3"
        ]
    );
    assert!(matches!(
        tools::compile_zone(&kb, "France/Nowhere"),
        Err(KbError::UnknownZone { .. })
    ));
}

#[test]
fn explain_agrees_with_the_generator_for_a_district_a_town_and_nowhere() {
    let kb = shipped();
    let tags = BuildingTags::default();
    // (lon, lat, expected zone, expected candidates' owner)
    let places = [
        // Compans-Caffarelli: its own single appearance (proba 1).
        (
            1.4330,
            43.6110,
            "earth/France/Occitanie/Toulouse/Compans-Caffarelli",
            "earth/France/Occitanie/Toulouse/Compans-Caffarelli",
        ),
        // In Toulouse's circle, in no district: Toulouse's appearances.
        (
            1.4000,
            43.6300,
            "earth/France/Occitanie/Toulouse",
            "earth/France/Occitanie/Toulouse",
        ),
        // The Atlantic: earth, no appearance.
        (-30.0, 40.0, "earth", ""),
    ];
    for (lon, lat, zone, owner) in places {
        for seed in [1u64, 7, 42] {
            let e = tools::explain(&kb, lon, lat, &tags, 12345, seed);
            assert_eq!(kb.zone_path(e.zone), zone);
            assert_eq!(e.chain.last().map(|l| l.path.as_str()), Some(zone));
            // Exactly what the generator computes.
            let z = kb.locate(lon, lat);
            let (style, _) = kb.style_for(z, &tags, &mut Rng::new(seed, 12345));
            assert_eq!(e.style, style);
            let chosen: Vec<&str> = e
                .candidates
                .iter()
                .filter(|c| c.chosen)
                .map(|c| c.label.as_str())
                .collect();
            if owner.is_empty() {
                assert!(e.candidates.is_empty());
                assert_eq!(e.style.appearance_label, "earth#info");
            } else {
                assert_eq!(chosen, vec![style.appearance_label.as_str()]);
                assert!(style.appearance_label.starts_with(&format!("{owner}#")));
                let sum: f64 = e.candidates.iter().map(|c| c.weight).sum();
                assert!((sum - 1.0).abs() < 1e-9);
            }
        }
    }
    let from = |e: &tools::Explanation, a: &str| {
        e.values
            .iter()
            .find(|v| v.attribute == a)
            .map(|v| (v.value.clone(), v.from.clone()))
    };
    // District: the appearance sets the wall colour, the district's info the nbfloor, earth
    // the material (France and Occitanie do not set it; Toulouse does).
    let e = tools::explain(&kb, 1.4330, 43.6110, &tags, 1, 1);
    assert_eq!(
        e.style.appearance_label,
        "earth/France/Occitanie/Toulouse/Compans-Caffarelli#1"
    );
    assert_eq!(
        from(&e, "color"),
        Some((
            "#e6ddd0".into(),
            "earth/France/Occitanie/Toulouse/Compans-Caffarelli#1".into()
        ))
    );
    assert_eq!(
        from(&e, "nbfloor"),
        Some((
            "6".into(),
            "earth/France/Occitanie/Toulouse/Compans-Caffarelli".into()
        ))
    );
    assert_eq!(
        from(&e, "material"),
        Some((
            "BricksBasic".into(),
            "earth/France/Occitanie/Toulouse".into()
        ))
    );
    assert_eq!(
        from(&e, "windowmaterial"),
        Some((
            "glass".into(),
            "earth/France/Occitanie/Toulouse/Compans-Caffarelli#1".into()
        ))
    );
    assert_eq!(e.style.roof, RoofShape::Flat);
    assert!((5..=8).contains(&e.style.storeys));
    // Town only: roofangle from Toulouse's info, windowstyle from the chosen appearance.
    let e = tools::explain(&kb, 1.4000, 43.6300, &tags, 1, 1);
    assert_eq!(
        from(&e, "roofangle"),
        Some(("30".into(), "earth/France/Occitanie/Toulouse".into()))
    );
    assert_eq!(
        from(&e, "windowstyle").map(|v| v.1),
        Some(e.style.appearance_label.clone())
    );
    // Nowhere: earth's info only.
    let e = tools::explain(&kb, -30.0, 40.0, &tags, 1, 1);
    assert!(e.values.iter().all(|v| v.from == "earth"));
    assert_eq!(from(&e, "nbfloor"), Some(("2".into(), "earth".into())));
    assert_eq!(e.style.storeys, 2);
    assert_eq!(e.style.wall_color, Color::WHITE);
    let shown = e.to_string();
    assert!(
        shown.contains("no zone contains the point: earth"),
        "{shown}"
    );
    assert!(
        shown.contains("chosen with this seed: earth#info"),
        "{shown}"
    );
}

#[test]
fn explain_lists_tag_overrides_and_the_chain_reasons() {
    let kb = shipped();
    let tags = BuildingTags {
        levels: Some(3.0),
        colour: Color::parse("blue"),
        ..BuildingTags::default()
    };
    let e = tools::explain(&kb, 1.4433, 43.6045, &tags, 99, 3);
    assert_eq!(
        kb.zone_path(e.zone),
        "earth/France/Occitanie/Toulouse/Capitole"
    );
    assert_eq!(
        e.overrides,
        vec!["building:levels=3", "building:colour=blue"]
    );
    assert_eq!(e.style.storeys, 3);
    assert_eq!(
        e.style.wall_color,
        Color::parse("blue").unwrap_or(Color::WHITE)
    );
    let shown = e.to_string();
    assert!(
        shown.contains("Capitole: inside its circle: 0.0"),
        "{shown}"
    );
    assert!(
        shown.contains("OSM tag overrides: building:levels=3, building:colour=blue"),
        "{shown}"
    );
    assert!(shown.contains("weight 0.7000"), "{shown}");
}

#[test]
fn check_of_the_shipped_kb_is_clean() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("knowledge_base/kb.xml");
    let r = tools::check_report(&path, ReadMode::Strict).unwrap_or_else(|e| panic!("{e}"));
    assert!(r.repairs.is_empty() && !r.has_errors(), "{r}");
    assert!(r.appearances >= 20 && r.zones >= 20, "{r}");
    // Probas of each zone sum to 1: no such warning.
    assert!(!r.warnings.iter().any(|w| w.what.contains("probas")), "{r}");
}

#[test]
fn check_warns_on_probas_and_shapeless_zones() {
    let t = "<earth>\n<country designation=\"A\">\n<appearance><values proba=\"0.5\"/></appearance>\n<appearance><values proba=\"0.2\"/></appearance>\n</country>\n</earth>";
    let (kb, rep) = KnowledgeBase::parse_str(t, "w.xml").unwrap_or_else(|e| panic!("{e}"));
    let r = tools::report_for(&kb, ReadMode::Lenient, rep, false);
    assert!(
        r.warnings
            .iter()
            .any(|w| w.line == 2 && w.what.contains("sum to 0.7")),
        "{r}"
    );
    assert!(
        r.warnings
            .iter()
            .any(|w| w.line == 2 && w.what.contains("no circle")),
        "{r}"
    );
}

#[test]
fn roof_direction_tag_reaches_the_style() {
    let kb = shipped();
    let zone = kb.locate(-1.15, 52.95);
    let tags = BuildingTags::from_pairs([
        ("building", "yes"),
        ("roof:shape", "skillion"),
        ("roof:direction", "E"),
    ]);
    let (s, _) = kb.style_for(zone, &tags, &mut Rng::new(1, 1));
    assert_eq!(s.roof, RoofShape::Skillion);
    assert_eq!(s.roof_direction, Some(90.0));
    let tags = BuildingTags::from_pairs([("building", "yes"), ("roof:direction", "-90")]);
    let (s, _) = kb.style_for(zone, &tags, &mut Rng::new(1, 1));
    assert_eq!(s.roof_direction, Some(270.0));
    assert!(!s.roof_across);
    // roof:orientation reaches it too (issue 45: it was parsed and then dropped).
    for (o, across) in [("across", true), ("along", false)] {
        let tags = BuildingTags::from_pairs([("building", "yes"), ("roof:orientation", o)]);
        let (s, _) = kb.style_for(zone, &tags, &mut Rng::new(1, 1));
        assert_eq!(s.roof_across, across, "{o}");
    }
}

#[test]
fn roof_levels_and_materials_reach_the_style() {
    let kb = shipped();
    let zone = kb.locate(-1.15, 52.95);
    let tags = BuildingTags::from_pairs([
        ("building", "yes"),
        ("roof:shape", "gabled"),
        ("roof:levels", "2"),
        ("roof:material", "slate"),
        ("building:material", "brick"),
    ]);
    let (s, _) = kb.style_for(zone, &tags, &mut Rng::new(1, 1));
    assert_eq!(s.roof_height, Some(2.0 * s.floor_height));
    assert_eq!(Some(s.roof_color), crate::kb::material_color("slate"));
    assert_eq!(Some(s.wall_color), crate::kb::material_color("brick"));
    // A colour tag wins over the material.
    let tags = BuildingTags::from_pairs([
        ("building", "yes"),
        ("roof:material", "slate"),
        ("roof:colour", "red"),
    ]);
    let (s, _) = kb.style_for(zone, &tags, &mut Rng::new(1, 1));
    assert_eq!(Some(s.roof_color), Color::parse("red"));
    assert_eq!(crate::kb::material_color("unobtainium"), None);
}

#[test]
fn kb_check_reads_parses_and_lints_every_ruleset_the_kb_names() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    std::fs::create_dir(dir.path().join("rules")).unwrap_or_else(|e| panic!("{e}"));
    let w = |name: &str, text: &str| {
        std::fs::write(dir.path().join("rules").join(name), text).unwrap_or_else(|e| panic!("{e}"))
    };
    w("broken.cga", "lot -> extrude(3){a\n");
    w(
        "unreachable.cga",
        "lot -> extrude(3){wall}\nb -> extrude(1){wall}\n",
    );
    w("good.cga", "lot -> extrude(3){wall}\n");
    let kb = dir.path().join("kb.xml");
    let apps: String = ["missing", "broken", "unreachable", "good"]
        .iter()
        .map(|r| format!("<appearance><values/><ruleset file=\"rules/{r}.cga\"/></appearance>\n"))
        .collect();
    std::fs::write(&kb, format!("<earth>\n{apps}</earth>")).unwrap_or_else(|e| panic!("{e}"));
    let r = tools::check_report(&kb, ReadMode::Strict).unwrap_or_else(|e| panic!("{e}"));
    let said: Vec<(usize, &str)> = r
        .warnings
        .iter()
        .map(|w| (w.line, w.what.as_str()))
        .collect();
    let about = |line: usize, needle: &str| {
        assert!(
            said.iter().any(|&(l, w)| l == line && w.contains(needle)),
            "no warning at line {line} with {needle:?}: {said:?}"
        )
    };
    about(2, "missing.cga cannot be read");
    about(3, "ruleset does not parse");
    about(3, "broken.cga:1:");
    about(4, "unreachable.cga:2:");
    about(4, "unreachable-rule");
    assert!(
        !said.iter().any(|&(l, _)| l == 5),
        "the good ruleset: {said:?}"
    );
    // A run falls back to the values for a ruleset it cannot use, so none of it is an error.
    assert!(!r.has_errors(), "{}", r);
}

#[test]
fn roof_tags_beyond_sane_limits_are_bounded_with_a_note() {
    let (kb, _) = KnowledgeBase::parse_str("<earth/>", "e.xml").unwrap_or_else(|e| panic!("{e}"));
    let style = |pairs: &[(&str, &str)]| {
        let tags = BuildingTags::from_pairs(pairs.iter().copied());
        kb.style_for(0, &tags, &mut Rng::new(0, 0))
    };
    // roof:angle allows up to 90°; near it the pitch gives a roof of any height.
    let (s, notes) = style(&[("roof:shape", "gabled"), ("roof:angle", "89.9999")]);
    assert_eq!(s.roof_angle_deg, MAX_TAGGED_PITCH_DEG);
    assert!(
        notes.iter().any(|n| n.contains("roof:angle=89.9999")),
        "{notes:?}"
    );
    // At the bound and below it, the tag is drawn as it is, without a note.
    let (s, notes) = style(&[("roof:shape", "gabled"), ("roof:angle", "85")]);
    assert_eq!(s.roof_angle_deg, 85.0);
    assert!(notes.iter().all(|n| !n.contains("roof:angle")), "{notes:?}");
    let (s, notes) = style(&[("roof:shape", "pyramidal"), ("roof:height", "900")]);
    assert_eq!(s.roof_height, Some(MAX_TAGGED_ROOF_HEIGHT_M));
    assert!(
        notes.iter().any(|n| n.contains("roof:height=900")),
        "{notes:?}"
    );
    let (s, notes) = style(&[("roof:shape", "gabled"), ("roof:levels", "150")]);
    assert_eq!(s.roof_height, Some(MAX_TAGGED_ROOF_HEIGHT_M));
    assert!(
        notes.iter().any(|n| n.contains("roof:levels=150")),
        "{notes:?}"
    );
    let (s, _) = style(&[("roof:shape", "gabled"), ("roof:height", "12")]);
    assert_eq!(s.roof_height, Some(12.0));
}

#[test]
fn an_appearance_for_some_building_kinds_is_drawn_only_for_them() {
    let text = r#"<earth>
      <appearance building="house,detached"><values proba="1" nbfloor="2"/></appearance>
      <appearance building="industrial"><values proba="1" nbfloor="1"/></appearance>
      <appearance><values proba="0.5" nbfloor="5"/></appearance>
      <appearance><values proba="0.5" nbfloor="6"/></appearance>
    </earth>"#;
    let (kb, repairs) = KnowledgeBase::parse_str(text, "t.xml").unwrap();
    assert!(repairs.is_empty(), "{repairs:?}");
    assert_eq!(
        kb.zones()[0].appearances[0].buildings,
        ["house", "detached"]
    );
    assert_eq!(kb.eligible_appearances(0, Some("detached")).1, [0]);
    assert_eq!(kb.eligible_appearances(0, Some("industrial")).1, [1]);
    assert_eq!(
        kb.eligible_appearances(0, None).1,
        [2, 3],
        "untagged: the open ones"
    );
    assert_eq!(kb.eligible_appearances(0, Some("yes")).1, [2, 3]);
    assert_eq!(kb.eligible_appearances(0, Some("church")).1, [2, 3]);
    for s in 0..50 {
        let mut rng = Rng::new(s, 7);
        assert_eq!(
            kb.pick_appearance(0, Some("house"), None, &mut rng),
            Some((0, 0))
        );
        let mut rng = Rng::new(s, 7);
        let (_, i) = kb
            .pick_appearance(0, Some("apartments"), None, &mut rng)
            .unwrap();
        assert!(i == 2 || i == 3);
    }
    // Every appearance listed and none names the kind: all of them.
    let only = r#"<earth><appearance building="house"><values/></appearance>
      <appearance building="shed"><values/></appearance></earth>"#;
    let (kb, _) = KnowledgeBase::parse_str(only, "t.xml").unwrap();
    assert_eq!(kb.eligible_appearances(0, Some("office")).1, [0, 1]);
    // The strict reader takes the attribute; the style of a house is the house appearance's.
    assert!(KnowledgeBase::parse_str_with(text, "t.xml", ReadMode::Strict).is_ok());
    let tags = BuildingTags {
        building: Some("house".into()),
        ..Default::default()
    };
    let (kb, _) = KnowledgeBase::parse_str(text, "t.xml").unwrap();
    let (style, _) = kb.style_for(0, &tags, &mut Rng::new(1, 1));
    assert_eq!(style.storeys, 2);
}

#[test]
fn infer_is_inherited_and_read_in_both_modes() {
    let text = r#"<earth><info infer="levels,roof"/>
      <country designation="A"><info lat="10" lon="10" dist="100" infer="none"/>
        <town designation="B"><info lat="10" lon="10" dist="5"/></town></country>
      <country designation="C"><info lat="-10" lon="10" dist="100" infer="all"/></country>
    </earth>"#;
    let (kb, repairs) = KnowledgeBase::parse_str(text, "t.xml").unwrap();
    assert!(repairs.is_empty(), "{repairs:?}");
    assert!(KnowledgeBase::parse_str_with(text, "t.xml", ReadMode::Strict).is_ok());
    let by = kb.inference_by_zone();
    let lr = Inference {
        levels: true,
        roof: true,
        colour: false,
    };
    assert_eq!(by, [lr, Inference::NONE, Inference::NONE, Inference::ALL]);
    let bad = r#"<earth><info infer="levels,walls"/></earth>"#;
    assert!(KnowledgeBase::parse_str_with(bad, "t.xml", ReadMode::Strict).is_err());
    let (kb, repairs) = KnowledgeBase::parse_str(bad, "t.xml").unwrap();
    assert_eq!(repairs.len(), 1, "{repairs:?}");
    assert_eq!(kb.inference_by_zone(), [Inference::NONE]);
}

#[test]
fn selex_programs_are_read_and_checked_and_kept_inside_the_kb_folder() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("good.slx"),
        "{< descendant() [label == facade] > -> createStoreyGrid(\"g\", 3)};\n",
    )
    .unwrap();
    std::fs::write(
        dir.path().join("bad.slx"),
        "{< cell() [rowIdz == 1] > -> addFacade(\"d\")};\n",
    )
    .unwrap();
    let kb_text = r#"<earth><appearance><values/><selex file="good.slx"/></appearance><appearance><values/><selex file="bad.slx"/></appearance><appearance><values/><selex file="../out.slx"/></appearance></earth>"#;
    let path = dir.path().join("kb.xml");
    std::fs::write(&path, kb_text).unwrap();
    let (kb, _) = KnowledgeBase::load(&path).unwrap();
    assert_eq!(
        kb.selex_path(0, 0).unwrap(),
        Some(dir.path().join("good.slx"))
    );
    assert!(kb.selex_path(0, 2).is_err());
    let report = tools::check_report(&path, ReadMode::Lenient).unwrap();
    let errors: Vec<&str> = report.errors.iter().map(|e| e.what.as_str()).collect();
    assert_eq!(errors.len(), 2, "{errors:?}");
    assert!(errors
        .iter()
        .any(|e| e.contains("bad.slx:1:12: unknown attribute `rowIdz`")));
    assert!(errors
        .iter()
        .any(|e| e.contains("selex file \"../out.slx\" lies outside")));
    // The bare word `facade` of the good program is a warning.
    assert!(
        report.warnings.iter().any(
            |w| w.what.contains("good.slx:1:") && w.what.contains("bare")
                || w.what.contains("taken as the string")
        ),
        "{:?}",
        report.warnings
    );
}

#[test]
fn colours_spelt_otherwise_than_the_clean_format_are_listed_as_repairs() {
    // `#rrggbb` and lower-case names read as they are; `#rgb`, other case and thesis triples
    // are read too, each listed with the colour it became (a strict save writes that one).
    let clean = r##"<earth><info color="#aa2222" roofColor="peru"/></earth>"##;
    let (_, repairs) = KnowledgeBase::parse_str(clean, "t.xml").unwrap();
    assert!(repairs.is_empty(), "{repairs:?}");
    let text = r##"<earth><info color="#FFF" roofColor="AliceBlue" doorCol="1;0;0"/></earth>"##;
    let (kb, repairs) = KnowledgeBase::parse_str(text, "t.xml").unwrap();
    let said: Vec<String> = repairs.iter().map(|r| r.to_string()).collect();
    assert_eq!(said.len(), 3, "{said:?}");
    for (attr, hex) in [
        ("color", "#ffffff"),
        ("roofColor", "#f0f8ff"),
        ("doorCol", "#ff0000"),
    ] {
        assert!(
            said.iter()
                .any(|s| s.contains(&format!("'{attr}'")) && s.contains(hex)),
            "{attr} -> {hex} in {said:?}"
        );
    }
    assert_eq!(kb.zones[0].info.wall_color, Color::parse("#ffffff"));
}

/// The KB's uncertainty in a style: half the drawn appearance's floor range (and that times the
/// floor height for the height), the eligible weight of the drawn roof's family; tags and a
/// provenance on the tags win.
#[test]
fn a_style_carries_the_kbs_uncertainty_and_the_tags_provenance() {
    use crate::model::{Provenance, ValueSource};
    let t = r#"<earth><info floorsize="3"/>
        <appearance><values proba="0.75" rooftype="flat" minFloors="2" maxFloors="5"/></appearance>
        <appearance><values proba="0.25" rooftype="gabled" nbfloor="2"/></appearance>
        </earth>"#;
    let (kb, _) = KnowledgeBase::parse_str(t, "t.xml").unwrap_or_else(|e| panic!("{e}"));
    let untagged = BuildingTags::default();
    let mut seen = [false; 2];
    for seed in 0..40 {
        let (s, _) = kb.style_for(0, &untagged, &mut Rng::new(seed, 7));
        let p = s.provenance(&untagged);
        assert_eq!(
            (p.storeys, p.height, p.roof),
            (ValueSource::Kb, ValueSource::Kb, ValueSource::Kb)
        );
        if s.roof == RoofShape::Flat {
            seen[0] = true;
            assert_eq!(s.storeys_error, 1.5);
            assert_eq!((p.storeys_error, p.height_error), (Some(1.5), Some(4.5)));
            assert_eq!(p.roof_probability, Some(0.75));
        } else {
            seen[1] = true;
            assert_eq!((p.storeys_error, p.height_error), (Some(0.0), Some(0.0)));
            assert_eq!(p.roof_probability, Some(0.25));
        }
    }
    assert_eq!(seen, [true, true], "both appearances drawn");

    // Tagged levels: storeys and height from the tag, the roof still the KB's.
    let levels = BuildingTags {
        levels: Some(3.0),
        ..Default::default()
    };
    let (s, _) = kb.style_for(0, &levels, &mut Rng::new(1, 7));
    let p = s.provenance(&levels);
    assert_eq!((p.storeys, p.storeys_error), (ValueSource::Tag, None));
    assert_eq!((p.height, p.height_error), (ValueSource::Tag, None));
    assert_eq!(p.roof, ValueSource::Kb);
    assert!(p.roof_probability.is_some());
    // A tagged roof (even an unreadable one) and height.
    let roofed = BuildingTags {
        height: Some(9.0),
        invalid_roof_shape: Some("many".into()),
        ..Default::default()
    };
    let (s, _) = kb.style_for(0, &roofed, &mut Rng::new(1, 7));
    let p = s.provenance(&roofed);
    assert_eq!(
        p,
        Provenance {
            storeys: ValueSource::Tag,
            height: ValueSource::Tag,
            roof: ValueSource::Tag,
            ..Default::default()
        }
    );

    // The estimator's provenance is kept, its numbers rounded to 0.001; a KB value it leaves
    // without uncertainty gets the KB's.
    let estimated = BuildingTags {
        height: Some(7.5),
        provenance: Some(Provenance {
            storeys: ValueSource::Model,
            storeys_error: Some(0.61234),
            height: ValueSource::Model,
            height_error: Some(1.8),
            roof: ValueSource::Kb,
            roof_probability: None,
        }),
        ..Default::default()
    };
    let (s, _) = kb.style_for(0, &estimated, &mut Rng::new(1, 7));
    let p = s.provenance(&estimated);
    assert_eq!(
        (p.storeys, p.storeys_error),
        (ValueSource::Model, Some(0.612))
    );
    assert_eq!((p.height, p.height_error), (ValueSource::Model, Some(1.8)));
    assert_eq!(p.roof, ValueSource::Kb);
    assert_eq!(p.roof_probability, s.roof_probability);

    // building=roof: one storey and a flat roof by its kind.
    let canopy = BuildingTags {
        building: Some("roof".into()),
        ..Default::default()
    };
    let (s, _) = kb.style_for(0, &canopy, &mut Rng::new(1, 7));
    let p = s.provenance(&canopy);
    assert_eq!(
        (p.storeys_error, p.roof_probability),
        (Some(0.0), Some(1.0))
    );
}

/// The height estimator's regional level (issue 42): a town's `nbfloor` stands, a country's
/// is held to 3 (it describes the cities' blocks, not the villages), and town zones say so.
#[test]
fn the_storey_level_of_a_zone_is_its_towns_and_at_most_3_outside_them() {
    let t = r#"<earth>
  <info nbfloor="2" rooftype="gabled"/>
  <country designation="C">
    <info lat="10" lon="10" dist="500" nbfloor="8"/>
    <town designation="T">
      <info lat="10" lon="10" dist="5" nbfloor="6" floorsize="3.2"/>
    </town>
  </country>
</earth>"#;
    let (kb, _) = KnowledgeBase::parse_str(t, "s.xml").unwrap_or_else(|e| panic!("{e}"));
    let town = kb.locate(10.0, 10.0);
    let country = kb.locate(12.0, 12.0);
    assert_eq!(path_of(&kb, town), "earth/C/T");
    assert_eq!(path_of(&kb, country), "earth/C");
    let (t, c, e) = (
        kb.roof_mix(town, None),
        kb.roof_mix(country, None),
        kb.roof_mix(0, None),
    );
    assert_eq!((t.storeys, t.urban, t.floor_height), (6.0, true, 3.2));
    assert_eq!((c.storeys, c.urban), (3.0, false));
    assert_eq!((e.storeys, e.urban), (2.0, false));
}

/// Issue 42 step 4: an appearance is drawn among those whose storey range fits the building.
#[test]
fn a_tall_building_is_drawn_among_the_appearances_that_fit_its_storeys() {
    let t = r#"<earth>
  <info nbfloor="2" floorsize="3"/>
  <appearance><values proba="0.5" material="wood" minFloors="1" maxFloors="2"/></appearance>
  <appearance><values proba="0.5" material="concrete" minFloors="5" maxFloors="10"/></appearance>
  <appearance><values proba="0.2" material="brick" minHeight="6" maxHeight="12"/></appearance>
</earth>"#;
    let (kb, _) = KnowledgeBase::parse_str(t, "f.xml").unwrap_or_else(|e| panic!("{e}"));
    let mut rng = Rng::new(7, 0);
    let mut seen = std::collections::BTreeSet::new();
    for _ in 0..200 {
        assert_eq!(
            kb.pick_appearance(0, None, Some(9.0), &mut rng),
            Some((0, 1))
        );
        assert_eq!(
            kb.pick_appearance(0, None, Some(1.0), &mut rng),
            Some((0, 0))
        );
        // 3 storeys: the brick one (6-12 m of eaves at 3 m a storey is 2-4 storeys).
        assert_eq!(
            kb.pick_appearance(0, None, Some(3.0), &mut rng),
            Some((0, 2))
        );
        // 30 storeys: the nearest range.
        assert_eq!(
            kb.pick_appearance(0, None, Some(30.0), &mut rng),
            Some((0, 1))
        );
        seen.extend(kb.pick_appearance(0, None, None, &mut rng).map(|p| p.1));
    }
    assert_eq!(seen.len(), 3, "unknown storeys draw from all");
    // Through the style: a tagged 9-storey building is concrete.
    let tags = BuildingTags {
        levels: Some(9.0),
        ..Default::default()
    };
    for _ in 0..50 {
        let (style, _) = kb.style_for(0, &tags, &mut rng);
        assert_eq!(style.material.as_deref(), Some("concrete"));
    }
}

/// Issue 42 step 4: appearances conditioned on the footprint's area, attachment and the
/// density around it; read by both readers, written back, and drawn where they hold.
#[test]
fn appearances_are_drawn_where_their_footprint_conditions_hold() {
    use crate::model::{Density, Form};
    let t = r#"<earth>
  <info nbfloor="2" floorsize="3"/>
  <appearance area="-60"><values proba="0.3" material="wood"/></appearance>
  <appearance area="60-" attached="no" density="low,medium"><values proba="0.3" material="plaster"/></appearance>
  <appearance attached="yes" density="high"><values proba="0.3" material="brick"/></appearance>
</earth>"#;
    for mode in [ReadMode::Lenient, ReadMode::Strict] {
        let (kb, _) =
            KnowledgeBase::parse_str_with(t, "c.xml", mode).unwrap_or_else(|e| panic!("{e}"));
        let apps = &kb.zones()[0].appearances;
        assert_eq!(apps[0].when.area, Some((0.0, 60.0)));
        assert_eq!(apps[1].when.area, Some((60.0, f64::INFINITY)));
        assert_eq!(apps[1].when.attached, Some(false));
        assert_eq!(apps[1].when.density, vec![Density::Low, Density::Medium]);
        assert_eq!(apps[2].when.attached, Some(true));
        assert!(kb.has_conditions());
        // Written back by the strict writer and read again: the same conditions.
        let text = super::write::to_strict(&kb).text;
        assert!(
            text.contains(r#"area="60-" attached="no" density="low,medium""#),
            "{text}"
        );
        let (again, _) = KnowledgeBase::parse_str_with(&text, "c.xml", ReadMode::Strict)
            .unwrap_or_else(|e| panic!("{e}\n{text}"));
        let whens = |k: &KnowledgeBase| -> Vec<_> {
            k.zones()[0]
                .appearances
                .iter()
                .map(|a| a.when.clone())
                .collect()
        };
        assert_eq!(whens(&again), whens(&kb));

        let mut rng = Rng::new(3, 0);
        let village = Form {
            attached: false,
            density: Density::Low,
        };
        let centre = Form {
            attached: true,
            density: Density::High,
        };
        let town = Form {
            attached: true,
            density: Density::Medium,
        };
        for _ in 0..100 {
            let pick = |area: f64, form: Form, rng: &mut Rng| {
                kb.pick_appearance_for(0, None, None, (Some(area), Some(form)), rng)
                    .map(|p| p.1)
            };
            assert_eq!(
                pick(40.0, village, &mut rng),
                Some(0),
                "a shed in a village"
            );
            assert_eq!(
                pick(120.0, village, &mut rng),
                Some(1),
                "a house in a village"
            );
            assert_eq!(
                pick(120.0, centre, &mut rng),
                Some(2),
                "a block in a centre"
            );
            // A 120 m² row house in a medium town meets no condition: drawn among all.
            assert!(pick(120.0, town, &mut rng).is_some());
        }
        let seen: std::collections::BTreeSet<usize> = (0..100)
            .filter_map(|_| {
                kb.pick_appearance_for(0, None, None, (Some(120.0), Some(town)), &mut rng)
            })
            .map(|p| p.1)
            .collect();
        assert_eq!(seen.len(), 3, "no appearance holds: all are drawn");
    }
    // The strict reader names a bad condition at its place.
    let bad = "<earth>\n  <appearance area=\"250-60\"><values proba=\"1\"/></appearance>\n</earth>";
    match KnowledgeBase::parse_str_with(bad, "s.xml", ReadMode::Strict) {
        Err(e) => assert!(e.to_string().contains("s.xml:2:"), "{e}"),
        Ok(_) => panic!("250-60 is not a range"),
    }
    for (attr, want) in [
        ("attached=\"maybe\"", "yes or no"),
        ("density=\"dense\"", "low, medium, high"),
    ] {
        let text =
            format!("<earth>\n  <appearance {attr}><values proba=\"1\"/></appearance>\n</earth>");
        match KnowledgeBase::parse_str_with(&text, "s.xml", ReadMode::Strict) {
            Err(e) => assert!(e.to_string().contains(want), "{e}"),
            Ok(_) => panic!("{attr} accepted"),
        }
        // The lenient reader keeps the appearance and notes the bad condition.
        let (kb, repairs) = KnowledgeBase::parse_str(&text, "s.xml").unwrap();
        assert!(kb.zones()[0].appearances[0].when.is_empty());
        assert!(!repairs.is_empty());
    }
}
