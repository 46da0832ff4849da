//! Entrances on the street side and no slit openings (issue 45, items 4 and 5), through the
//! real binary on OSM files written here near Monaco (so the shipped knowledge base's zone
//! applies): rows of terraced houses and detached houses between a named residential street
//! in front and a back lane (`highway=service`, `service=alley`) behind, nearer than the
//! street, with and without `addr:street`. Each building's ground door is read back from the
//! CityJSON output (its `Door` surfaces) and must be on the wall facing the street; no window
//! or door of any building is narrower than the knowledge base's 0.4 m minimum.

use std::fs::File;
use std::path::Path;

use crate::common::*;
use citygen::testkit::pbf_write::PbfWriter;

const LON0: f64 = 7.4200;
const LAT0: f64 = 43.7300;

type Tags = Vec<(String, String)>;

/// An OSM data set in metres east/north of (LON0, LAT0).
#[derive(Default)]
struct Osm {
    nodes: Vec<(i64, f64, f64, Tags)>,
    ways: Vec<(i64, Vec<i64>, Tags)>,
}

impl Osm {
    fn node(&mut self, (x, y): (f64, f64)) -> i64 {
        let m_lon = 111_320.0 * LAT0.to_radians().cos();
        let id = 1 + self.nodes.len() as i64;
        self.nodes
            .push((id, LON0 + x / m_lon, LAT0 + y / 110_574.0, Vec::new()));
        id
    }

    /// A tagged node at (x, y): an address or entrance node.
    fn tagged(&mut self, at: (f64, f64), tags: &[(&str, &str)]) {
        self.node(at);
        let t = &mut self.nodes.last_mut().unwrap().3;
        t.extend(tags.iter().map(|(k, v)| (k.to_string(), v.to_string())));
    }

    /// A way through `pts` (closed when `closed`) with these tags.
    fn way(&mut self, id: i64, pts: &[(f64, f64)], closed: bool, tags: &[(&str, &str)]) {
        let mut refs: Vec<i64> = pts.iter().map(|&p| self.node(p)).collect();
        if closed {
            refs.push(refs[0]);
        }
        let tags = tags
            .iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect();
        self.ways.push((id, refs, tags));
    }

    /// The same data set as OSM XML (`.osm`).
    fn write_xml(&self, path: &Path) {
        let esc = |s: &str| {
            s.replace('&', "&amp;")
                .replace('"', "&quot;")
                .replace('<', "&lt;")
        };
        let tags = |t: &Tags| {
            t.iter()
                .map(|(k, v)| format!("<tag k=\"{}\" v=\"{}\"/>", esc(k), esc(v)))
                .collect::<String>()
        };
        let mut x = String::from("<?xml version=\"1.0\"?>\n<osm version=\"0.6\">\n");
        for (id, lon, lat, t) in &self.nodes {
            x += &format!(
                "<node id=\"{id}\" lat=\"{lat:.9}\" lon=\"{lon:.9}\">{}</node>\n",
                tags(t)
            );
        }
        for (id, refs, t) in &self.ways {
            let nds: String = refs.iter().map(|r| format!("<nd ref=\"{r}\"/>")).collect();
            x += &format!("<way id=\"{id}\">{nds}{}</way>\n", tags(t));
        }
        x += "</osm>\n";
        std::fs::write(path, x).unwrap();
    }

    fn write(&self, path: &Path) {
        let mut w = PbfWriter::new(File::create(path).unwrap()).unwrap();
        for (id, lon, lat, tags) in &self.nodes {
            let t: Vec<(&str, &str)> = tags.iter().map(|(k, v)| (k.as_str(), v.as_str())).collect();
            w.node(*id, *lon, *lat, &t).unwrap();
        }
        for (id, refs, tags) in &self.ways {
            let t: Vec<(&str, &str)> = tags.iter().map(|(k, v)| (k.as_str(), v.as_str())).collect();
            w.way(*id, refs, &t).unwrap();
        }
        w.finish().unwrap();
    }
}

/// An axis-aligned rectangle, counter-clockwise.
fn rect(x: f64, y: f64, w: f64, h: f64) -> Vec<(f64, f64)> {
    vec![(x, y), (x + w, y), (x + w, y + h), (x, y + h)]
}

/// A street block at `y0`: a row of 10 terraced houses 6 m wide, 10 m deep (those of even
/// index with `addr:street`), then 4 detached houses, all with their fronts at `y0 + 10`; the
/// named street `front` metres north of the fronts, the alley `back` metres south of the backs.
/// Ways numbered from `id0`.
fn block(osm: &mut Osm, id0: i64, y0: f64, front: f64, back: f64, street: &str) {
    for i in 0..10 {
        let ring = rect(6.0 * i as f64, y0, 6.0, 10.0);
        let mut tags = vec![("building", "terrace"), ("building:levels", "2")];
        if i % 2 == 0 {
            tags.push(("addr:street", street));
        }
        osm.way(id0 + i, &ring, true, &tags);
    }
    for i in 0..4 {
        let ring = rect(70.0 + 12.0 * i as f64, y0 + 1.0, 8.0, 9.0);
        let mut tags = vec![("building", "house"), ("building:levels", "2")];
        if i % 2 == 1 {
            tags.push(("addr:street", street));
        }
        osm.way(id0 + 10 + i, &ring, true, &tags);
    }
    let (yf, yb) = (y0 + 10.0 + front, y0 - back);
    osm.way(
        id0 + 20,
        &[(-20.0, yf), (130.0, yf)],
        false,
        &[("highway", "residential"), ("name", street)],
    );
    osm.way(
        id0 + 21,
        &[(-20.0, yb), (130.0, yb)],
        false,
        &[
            ("highway", "service"),
            ("service", "alley"),
            ("name", "Back Lane"),
        ],
    );
}

/// (x, y) of CityJSON vertex `i`, in the output CRS, and its height.
fn vertex(doc: &serde_json::Value, i: u64) -> ((f64, f64), f64) {
    let v = &doc["vertices"][i as usize];
    let (s, t) = (&doc["transform"]["scale"], &doc["transform"]["translate"]);
    let c = |k: usize| v[k].as_f64().unwrap() * s[k].as_f64().unwrap() + t[k].as_f64().unwrap();
    ((c(0), c(1)), c(2))
}

/// Every vertex index of a boundary array, at any depth.
fn indices(b: &serde_json::Value, out: &mut Vec<u64>) {
    match b {
        serde_json::Value::Array(a) => a.iter().for_each(|x| indices(x, out)),
        serde_json::Value::Number(n) => out.extend(n.as_u64()),
        _ => {}
    }
}

/// Per city object with a ground door (one whose sill is within 0.5 m of the object's base):
/// (its id, its centre's y, each ground door's centre y).
type Doors = Vec<(String, f64, Vec<f64>)>;

/// The doors and the narrowest opening of a LOD3 CityJSON file.
fn doors_and_narrowest(path: &Path) -> (Doors, f64) {
    let doc: serde_json::Value = serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap();
    let mut doors = Vec::new();
    let mut narrowest = f64::INFINITY;
    for (id, o) in doc["CityObjects"].as_object().unwrap() {
        for g in o["geometry"].as_array().into_iter().flatten() {
            if g["type"] != "Solid" {
                continue;
            }
            let mut all = Vec::new();
            indices(&g["boundaries"], &mut all);
            let ys: Vec<f64> = all.iter().map(|&i| vertex(&doc, i).0 .1).collect();
            let centre = ys.iter().sum::<f64>() / ys.len() as f64;
            let base = all
                .iter()
                .map(|&i| vertex(&doc, i).1)
                .fold(f64::INFINITY, f64::min);
            let surfaces = g["semantics"]["surfaces"].as_array().unwrap();
            let mut found = Vec::new();
            for (s, shell) in g["boundaries"].as_array().unwrap().iter().enumerate() {
                for (f, face) in shell.as_array().unwrap().iter().enumerate() {
                    let Some(k) = g["semantics"]["values"][s][f].as_u64() else {
                        continue;
                    };
                    let kind = &surfaces[k as usize]["type"];
                    if kind != "Door" && kind != "Window" {
                        continue;
                    }
                    let mut v = Vec::new();
                    indices(face, &mut v);
                    let pts: Vec<(f64, f64)> = v.iter().map(|&i| vertex(&doc, i).0).collect();
                    let sill = v
                        .iter()
                        .map(|&i| vertex(&doc, i).1)
                        .fold(f64::INFINITY, f64::min);
                    // The opening's width: its horizontal extent.
                    let (mut lo, mut hi) = ((f64::MAX, f64::MAX), (f64::MIN, f64::MIN));
                    for p in &pts {
                        lo = (lo.0.min(p.0), lo.1.min(p.1));
                        hi = (hi.0.max(p.0), hi.1.max(p.1));
                    }
                    let width = (hi.0 - lo.0).hypot(hi.1 - lo.1);
                    narrowest = narrowest.min(width);
                    if kind == "Door" && sill <= base + 0.5 {
                        found.push(pts.iter().map(|p| p.1).sum::<f64>() / pts.len() as f64);
                    }
                }
            }
            if !found.is_empty() {
                doors.push((id.clone(), centre, found));
            }
        }
    }
    (doors, narrowest)
}

/// Writes the scene, runs citygen at LOD3 into CityJSON and reads the doors back.
fn run_scene(osm: &Osm, extra: &[&str]) -> (Doors, f64) {
    run_scene_as(osm, extra, false)
}

/// [`run_scene`], the scene written as OSM XML when `xml`.
fn run_scene_as(osm: &Osm, extra: &[&str], xml: bool) -> (Doors, f64) {
    let dir = tempfile::tempdir().unwrap();
    let (pbf, cj) = (
        dir.path().join(if xml { "row.osm" } else { "row.osm.pbf" }),
        dir.path().join("row.city.json"),
    );
    if xml {
        osm.write_xml(&pbf);
    } else {
        osm.write(&pbf);
    }
    let mut args = vec![
        "--osm",
        pbf.to_str().unwrap(),
        "--kb",
        KB,
        "--lod",
        "3",
        "--cityjson",
        cj.to_str().unwrap(),
        "--quiet",
    ];
    args.extend_from_slice(extra);
    let out = citygen(&args);
    assert!(
        out.status.success(),
        "citygen failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    doors_and_narrowest(&cj)
}

#[test]
fn ground_doors_face_the_street_not_the_back_lane() {
    let mut osm = Osm::default();
    // The street 8 m in front, the lane 4 m behind; then a deep front garden: the street 16 m
    // in front, the lane 3 m behind.
    block(&mut osm, 1000, 0.0, 8.0, 4.0, "Elm Street");
    block(&mut osm, 2000, 60.0, 16.0, 3.0, "Oak Avenue");
    let (doors, narrowest) = run_scene(&osm, &[]);
    // Every building drew one ground door (10 + 4 in each block), on its north (street) wall.
    let ground: Vec<(String, bool)> = doors
        .iter()
        .flat_map(|(id, centre, ds)| ds.iter().map(move |y| (id.clone(), y > centre)))
        .collect();
    let facing = ground.iter().filter(|g| g.1).count();
    let away: Vec<&String> = ground.iter().filter(|g| !g.1).map(|g| &g.0).collect();
    assert_eq!(ground.len(), 28, "{doors:?}");
    assert_eq!(facing, ground.len(), "doors facing the back lane: {away:?}");
    assert!(narrowest >= 0.4 - 1e-3, "an opening {narrowest} m wide");
}

/// A US rowhouse block at `y0` (issue 45, the district where 23 % of ground doors faced
/// away): 12 attached houses 5 m wide and 12 m deep, one way each, without `addr:street` on
/// the way; the address is on a node: inside the house near its front for the even ones, an
/// `entrance=main` node on the front wall for the odd ones. The named street 10 m in front
/// (front yards, sidewalk), an unnamed `highway=service` alley 3 m behind (no `service=alley`:
/// it does not count as a back lane), a cross street 6 m west of the corner house's side wall.
/// Then the same row mapped as one way, its 12 address nodes inside it. With `nodes`, the
/// address nodes are written; without, the same scene has none.
fn us_rowhouses(nodes: bool) -> Osm {
    let mut osm = Osm::default();
    let street = "Jefferson Street";
    for (row, y0) in [(0, 0.0), (1, 60.0)] {
        if row == 0 {
            for i in 0..12 {
                let ring = rect(5.0 * i as f64, y0, 5.0, 12.0);
                osm.way(100 + i, &ring, true, &[("building", "house")]);
            }
        } else {
            let ring = rect(0.0, y0, 60.0, 12.0);
            osm.way(200, &ring, true, &[("building", "terrace")]);
        }
        if nodes {
            for i in 0..12 {
                let x = 5.0 * i as f64 + 2.5;
                let number = (1000 + 2 * i + 100 * row).to_string();
                let addr = [
                    ("addr:street", street),
                    ("addr:housenumber", number.as_str()),
                ];
                if row == 0 && i % 2 == 1 {
                    let mut t = addr.to_vec();
                    t.push(("entrance", "main"));
                    osm.tagged((x, y0 + 12.0), &t);
                } else {
                    osm.tagged((x, y0 + 10.5), &addr);
                }
            }
        }
        osm.way(
            300 + row,
            &[(-30.0, y0 + 22.0), (90.0, y0 + 22.0)],
            false,
            &[("highway", "residential"), ("name", street)],
        );
        osm.way(
            310 + row,
            &[(-30.0, y0 - 3.0), (90.0, y0 - 3.0)],
            false,
            &[("highway", "service")],
        );
    }
    osm.way(
        320,
        &[(-6.0, -30.0), (-6.0, 110.0)],
        false,
        &[("highway", "residential"), ("name", "Pine Street")],
    );
    osm
}

/// The share of ground doors on the north (street) wall, and how many there are.
fn street_share(doors: &Doors) -> (f64, usize) {
    let ground: Vec<bool> = doors
        .iter()
        .flat_map(|(_, centre, ds)| ds.iter().map(move |y| y > centre))
        .collect();
    let facing = ground.iter().filter(|&&f| f).count();
    (facing as f64 / ground.len().max(1) as f64, ground.len())
}

#[test]
fn us_rowhouses_face_the_street_their_address_nodes_name() {
    let (doors, narrowest) = run_scene(&us_rowhouses(true), &[]);
    let (share, n) = street_share(&doors);
    // 12 houses and the row mapped as one way: one ground door each.
    assert_eq!(n, 13, "{doors:?}");
    assert!(
        share >= 0.95,
        "{share:.2} of ground doors on the street: {doors:?}"
    );
    assert!(narrowest >= 0.4 - 1e-3, "an opening {narrowest} m wide");
    // The same from OSM XML.
    let (doors, _) = run_scene_as(&us_rowhouses(true), &[], true);
    let (xml, n) = street_share(&doors);
    assert_eq!(n, 13, "{doors:?}");
    assert!(xml >= 0.95, "OSM XML: {xml:.2} on the street: {doors:?}");
    // Without the address nodes the nearer alley and the cross street win: what the nodes
    // change is what this test measures.
    let (doors, _) = run_scene(&us_rowhouses(false), &[]);
    let (without, n) = street_share(&doors);
    assert_eq!(n, 13, "{doors:?}");
    assert!(
        without < 0.5,
        "{without:.2} on the street without address nodes"
    );
}
