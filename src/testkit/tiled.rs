//! Tiled benchmark inputs: the buildings of data/monaco and the Clifton shapefile's footprints
//! (converted to lon/lat and moved beside Monaco, keeping their size in metres) repeated in a
//! grid of copies with coordinate offsets and new node/way/relation ids per copy, until there are
//! `n` buildings (the last copy is partial). Every copy is turned, scaled and its nodes moved by
//! a few centimetres, so no two footprints are the same shape. The `bench` example's
//! `--make N OUT` writes one; [`super::day2`] edits one into a "day 2".
//!
//! The data files are read relative to the working directory (the repository root, as for
//! `cargo run` and `cargo test`).

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use anyhow::{anyhow, Context, Result};
use osmpbf::{Element, ElementReader, RelMemberType};

use super::pbf_write::{MemberKind, PbfWriter};
use crate::fsio::AtomicFile;

/// OSM tags as owned (key, value) pairs.
type Tags = Vec<(String, String)>;

/// Polygons of one footprint in lon/lat: (outer ring, holes).
type LonLatPolygons = Vec<(Vec<(f64, f64)>, Vec<Vec<(f64, f64)>>)>;

/// The footprints repeated per copy, with dense ids (1-based per kind) and lon/lat nodes.
#[derive(Default)]
struct Template {
    nodes: Vec<(f64, f64)>,
    /// (node indices (0-based), tags).
    ways: Vec<(Vec<usize>, Tags)>,
    /// (members as (is_way, index), roles, tags); only way members.
    relations: Vec<(Vec<(usize, String)>, Tags)>,
    /// Top-level buildings in order: (true = way, false = relation, index).
    buildings: Vec<(bool, usize)>,
    /// Extent in degrees: (min lon, min lat, max lon, max lat).
    bounds: [f64; 4],
}

fn is_building(tags: &[(String, String)]) -> bool {
    tags.iter()
        .any(|(k, v)| k == "building" && v.trim() != "no")
}

fn is_part(tags: &[(String, String)]) -> bool {
    tags.iter()
        .any(|(k, v)| k == "building:part" && v.trim() != "no")
}

/// Building ways and relations (with their member ways and nodes) of data/monaco, then the
/// Clifton footprints beside them.
fn template() -> Result<Template> {
    let monaco = Path::new("data/monaco/monaco.osm.pbf");
    let mut nodes: BTreeMap<i64, (f64, f64)> = BTreeMap::new();
    let mut ways: BTreeMap<i64, (Vec<i64>, Tags)> = BTreeMap::new();
    let mut rels: BTreeMap<i64, (Vec<(i64, String)>, Tags)> = BTreeMap::new();
    let tags_of = |it: &mut dyn Iterator<Item = (&str, &str)>| -> Vec<(String, String)> {
        it.map(|(k, v)| (k.to_string(), v.to_string())).collect()
    };
    ElementReader::from_path(monaco)
        .with_context(|| format!("{}", monaco.display()))?
        .for_each(|e| match e {
            Element::Node(n) => {
                nodes.insert(n.id(), (n.lon(), n.lat()));
            }
            Element::DenseNode(n) => {
                nodes.insert(n.id(), (n.lon(), n.lat()));
            }
            Element::Way(w) => {
                ways.insert(w.id(), (w.refs().collect(), tags_of(&mut w.tags())));
            }
            Element::Relation(r) => {
                let tags = tags_of(&mut r.tags());
                let multipolygon = tags.iter().any(|(k, v)| k == "type" && v == "multipolygon");
                if multipolygon && (is_building(&tags) || is_part(&tags)) {
                    let members = r
                        .members()
                        .filter(|m| m.member_type == RelMemberType::Way)
                        .map(|m| (m.member_id, m.role().unwrap_or("").to_string()))
                        .collect();
                    rels.insert(r.id(), (members, tags));
                }
            }
        })
        .with_context(|| format!("{}", monaco.display()))?;
    let member_ways: BTreeSet<i64> = rels
        .values()
        .flat_map(|(m, _)| m.iter().map(|(id, _)| *id))
        .collect();
    let mut t = Template::default();
    let mut node_index: BTreeMap<i64, usize> = BTreeMap::new();
    let mut way_index: BTreeMap<i64, usize> = BTreeMap::new();
    for (id, (refs, tags)) in &ways {
        let top = is_building(tags);
        if !(top || is_part(tags) || member_ways.contains(id)) {
            continue;
        }
        if refs.iter().any(|r| !nodes.contains_key(r)) {
            continue;
        }
        let idx: Vec<usize> = refs
            .iter()
            .map(|r| {
                let next = t.nodes.len();
                *node_index.entry(*r).or_insert_with(|| {
                    t.nodes.push(nodes[r]);
                    next
                })
            })
            .collect();
        way_index.insert(*id, t.ways.len());
        if top {
            t.buildings.push((true, t.ways.len()));
        }
        t.ways.push((idx, tags.clone()));
    }
    for (members, tags) in rels.values() {
        let m: Vec<(usize, String)> = members
            .iter()
            .filter_map(|(id, role)| way_index.get(id).map(|&w| (w, role.clone())))
            .collect();
        if m.is_empty() {
            continue;
        }
        if is_building(tags) {
            t.buildings.push((false, t.relations.len()));
        }
        t.relations.push((m, tags.clone()));
    }
    let monaco_bounds = bounds(&t.nodes);
    add_clifton(&mut t, monaco_bounds)?;
    t.bounds = bounds(&t.nodes);
    Ok(t)
}

fn bounds(pts: &[(f64, f64)]) -> [f64; 4] {
    pts.iter().fold(
        [
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ],
        |b, &(x, y)| [b[0].min(x), b[1].min(y), b[2].max(x), b[3].max(y)],
    )
}

/// The Clifton shapefile's footprints, to lon/lat, then moved east of `beside` keeping their
/// size in metres (longitudes scaled by the ratio of the latitudes' cosines).
fn add_clifton(t: &mut Template, beside: [f64; 4]) -> Result<()> {
    let mut report = crate::report::Report::default();
    let read = crate::input::shp::read_shp(
        Path::new("data/clifton/clifton_test.shp"),
        &Default::default(),
        &mut report,
    )
    .context("data/clifton/clifton_test.shp")?;
    let crs = read
        .source_crs
        .ok_or_else(|| anyhow!("data/clifton/clifton_test.shp: the shapefile has no CRS"))?;
    let lonlat: Vec<LonLatPolygons> = read
        .footprints
        .iter()
        .map(|f| {
            f.polygons
                .iter()
                .map(|p| {
                    let conv = |r: &Vec<(f64, f64)>| {
                        r.iter()
                            .map(|&(x, y)| crs.to_lonlat(x, y))
                            .collect::<Vec<_>>()
                    };
                    (conv(&p.outer), p.holes.iter().map(conv).collect())
                })
                .collect()
        })
        .collect();
    let all: Vec<(f64, f64)> = lonlat
        .iter()
        .flatten()
        .flat_map(|(o, _)| o.iter().copied())
        .collect();
    let b = bounds(&all);
    let src_lat = (b[1] + b[3]) / 2.0;
    let dst_lat = (beside[1] + beside[3]) / 2.0;
    let kx = src_lat.to_radians().cos() / dst_lat.to_radians().cos();
    let gap = 0.002;
    let map = |(lon, lat): (f64, f64)| {
        (
            beside[2] + gap + (lon - b[0]) * kx,
            beside[1] + (lat - b[1]),
        )
    };
    for (f, polys) in read.footprints.iter().zip(&lonlat) {
        let mut tags = vec![("building".to_string(), "yes".to_string())];
        if let Some(h) = f.tags.height {
            tags.push(("height".into(), format!("{h}")));
        }
        if let Some(l) = f.tags.levels {
            tags.push(("building:levels".into(), format!("{l}")));
        }
        let ring_way = |t: &mut Template, r: &[(f64, f64)], tags: Vec<(String, String)>| {
            let first = t.nodes.len();
            t.nodes.extend(r.iter().map(|&p| map(p)));
            let mut idx: Vec<usize> = (first..t.nodes.len()).collect();
            idx.push(first);
            t.ways.push((idx, tags));
            t.ways.len() - 1
        };
        if polys.len() == 1 && polys[0].1.is_empty() {
            let w = ring_way(t, &polys[0].0, tags);
            t.buildings.push((true, w));
        } else {
            let mut members = Vec::new();
            for (outer, holes) in polys {
                members.push((ring_way(t, outer, Vec::new()), "outer".to_string()));
                for h in holes {
                    members.push((ring_way(t, h, Vec::new()), "inner".to_string()));
                }
            }
            tags.push(("type".into(), "multipolygon".into()));
            t.buildings.push((false, t.relations.len()));
            t.relations.push((members, tags));
        }
    }
    Ok(())
}

/// What one copy holds: every object, or (last copy) the first `k` buildings only.
struct Selection {
    nodes: Vec<bool>,
    ways: Vec<bool>,
    relations: Vec<bool>,
}

fn select(t: &Template, k: Option<usize>) -> Selection {
    let Some(k) = k else {
        return Selection {
            nodes: vec![true; t.nodes.len()],
            ways: vec![true; t.ways.len()],
            relations: vec![true; t.relations.len()],
        };
    };
    let mut s = Selection {
        nodes: vec![false; t.nodes.len()],
        ways: vec![false; t.ways.len()],
        relations: vec![false; t.relations.len()],
    };
    for &(is_way, i) in t.buildings.iter().take(k) {
        if is_way {
            s.ways[i] = true;
        } else {
            s.relations[i] = true;
            for (w, _) in &t.relations[i].0 {
                s.ways[*w] = true;
            }
        }
    }
    for (w, _) in t.ways.iter().enumerate().filter(|(i, _)| s.ways[*i]) {
        for &n in &t.ways[w].0 {
            s.nodes[n] = true;
        }
    }
    s
}

/// How one copy differs from the template, so that no two footprints of a tiled input are the
/// same shape (a cache of identical footprints would flatter the bench and speed up no real
/// city): the whole copy is turned by up to 6 degrees and scaled by up to 4 % about the
/// template's centre, and every node moves by up to 3 cm on its own. Nodes shared by two
/// buildings move together, so party walls stay party walls.
struct Jitter {
    copy: u64,
    cos: f64,
    sin: f64,
    scale: f64,
}

impl Jitter {
    fn of_copy(copy: u64) -> Jitter {
        let angle = (unit(copy, 0) * 2.0 - 1.0) * 6f64.to_radians();
        Jitter {
            copy,
            cos: angle.cos(),
            sin: angle.sin(),
            scale: 1.0 + (unit(copy, 1) * 2.0 - 1.0) * 0.04,
        }
    }

    /// Node `node` at `(lon, lat)`, turned and scaled about `centre` in a frame where one unit
    /// is as long east as north (`kx`: cos of the latitude), then moved by its own few cm.
    fn apply(&self, (lon, lat): (f64, f64), centre: (f64, f64), kx: f64, node: u64) -> (f64, f64) {
        const METRE: f64 = 1.0 / 111_320.0; // degrees of latitude
        let (x, y) = ((lon - centre.0) * kx, lat - centre.1);
        let (x, y) = (
            self.scale * (x * self.cos - y * self.sin),
            self.scale * (x * self.sin + y * self.cos),
        );
        let k = (self.copy << 32) ^ node;
        let (ex, ey) = (
            (unit(k, 2) * 2.0 - 1.0) * 0.03 * METRE,
            (unit(k, 3) * 2.0 - 1.0) * 0.03 * METRE,
        );
        (centre.0 + (x + ex) / kx, centre.1 + y + ey)
    }
}

/// A number in [0, 1) from `(key, salt)` (splitmix64).
fn unit(key: u64, salt: u64) -> f64 {
    let mut z = key
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add(salt.wrapping_mul(0xBF58_476D_1CE4_E5B9))
        .wrapping_add(0x94D0_49BB_1331_11EB);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 53) as f64
}

/// What [`make_tiled`] wrote.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tiled {
    /// Buildings written (the `n` asked).
    pub buildings: usize,
    /// Copies of the template (the last one partial unless `n` is a multiple of `per_copy`).
    pub copies: usize,
    /// Top-level buildings in one full copy.
    pub per_copy: usize,
    /// Columns of the grid of copies.
    pub columns: usize,
}

/// Writes `n` buildings tiled from the template to `out` (see the module documentation),
/// atomically (`fsio::AtomicFile`: a temporary renamed at the end). `n` must be at least 1.
pub fn make_tiled(n: usize, out: &Path) -> Result<Tiled> {
    if n == 0 {
        return Err(anyhow!(
            "{}: a tiled input needs at least 1 building",
            out.display()
        ));
    }
    let tpl = template()?;
    let per = tpl.buildings.len();
    if per == 0 {
        return Err(anyhow!(
            "data/monaco, data/clifton: no buildings in the template"
        ));
    }
    let copies = n.div_ceil(per);
    let cols = (copies as f64).sqrt().ceil() as usize;
    let [x0, y0, x1, y1] = tpl.bounds;
    // Room for the copy's rotation (at most 6 degrees) and scale (at most 4 %).
    let (dx, dy) = ((x1 - x0) * 1.2, (y1 - y0) * 1.2);
    let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
    let kx = cy.to_radians().cos();
    let full = select(&tpl, None);
    let last = select(&tpl, Some(n - (copies - 1) * per));
    let sel = |c: usize| if c + 1 == copies { &last } else { &full };
    let (nn, nw, nr) = (
        tpl.nodes.len() as i64,
        tpl.ways.len() as i64,
        tpl.relations.len() as i64,
    );
    if let Some(dir) = out.parent() {
        std::fs::create_dir_all(dir).with_context(|| format!("{}", dir.display()))?;
    }
    let file = AtomicFile::create(out).with_context(|| format!("{}", out.display()))?;
    let mut w = PbfWriter::new(
        file.writer()
            .with_context(|| format!("{}", out.display()))?,
    )?;
    for c in 0..copies {
        let (ox, oy) = ((c % cols) as f64 * dx, (c / cols) as f64 * dy);
        let s = sel(c);
        let jitter = Jitter::of_copy(c as u64);
        for (i, &p) in tpl.nodes.iter().enumerate() {
            if s.nodes[i] {
                let (lon, lat) = jitter.apply(p, (cx, cy), kx, i as u64);
                w.node(c as i64 * nn + i as i64 + 1, lon + ox, lat + oy, &[])?;
            }
        }
    }
    let mut refs = Vec::new();
    for c in 0..copies {
        let s = sel(c);
        for (i, (nodes, tags)) in tpl.ways.iter().enumerate() {
            if s.ways[i] {
                refs.clear();
                refs.extend(nodes.iter().map(|&k| c as i64 * nn + k as i64 + 1));
                let tags: Vec<(&str, &str)> =
                    tags.iter().map(|(k, v)| (k.as_str(), v.as_str())).collect();
                w.way(c as i64 * nw + i as i64 + 1, &refs, &tags)?;
            }
        }
    }
    for c in 0..copies {
        let s = sel(c);
        for (i, (members, tags)) in tpl.relations.iter().enumerate() {
            if s.relations[i] {
                let m: Vec<(MemberKind, i64, &str)> = members
                    .iter()
                    .map(|(wi, role)| {
                        (
                            MemberKind::Way,
                            c as i64 * nw + *wi as i64 + 1,
                            role.as_str(),
                        )
                    })
                    .collect();
                let tags: Vec<(&str, &str)> =
                    tags.iter().map(|(k, v)| (k.as_str(), v.as_str())).collect();
                w.relation(c as i64 * nr + i as i64 + 1, &m, &tags)?;
            }
        }
    }
    w.finish()
        .with_context(|| format!("{}: writing", out.display()))?;
    file.commit()
        .with_context(|| format!("{}: renaming", out.display()))?;
    Ok(Tiled {
        buildings: n,
        copies,
        per_copy: per,
        columns: cols,
    })
}
