//! `tileset.json` (3D Tiles 1.1) over a run's tiles, from their contents' [`ContentInfo`]
//! alone (the GLBs are not opened, so `citygen merge` can write it from shards' manifests).
//!
//! The tree: a quadtree over the tile grid's cells (the root's square of cells, a power of two
//! wide, halved at each level; empty quarters dropped, a node with one child replaced by that
//! child), whose leaves are the grid tiles. A grid tile's node has its Blocks content and its
//! `transform`, and one child, refined by REPLACE, with the Full content (in the same frame, so
//! without a transform of its own when both contents share it, as the writer makes them).
//!
//! Bounding volumes are regions (never transformed, so a child's is compared with its parent's
//! directly): a content's own, a grid tile's the union of its two, an inner node's the union of
//! its children's. Geometric errors: 0 for Full (the leaves), the tile's
//! [`ContentInfo::blocks_error`] for its Blocks, and for an inner node, which draws nothing,
//! the larger of its region's diagonal and twice its children's largest (so it is refined
//! before it covers more than the screen-space error, and errors halve at least at each level
//! down); the tileset's is the root's, or the root's diagonal if that is larger.
//!
//! Output is deterministic: tiles in cell order, numbers in Rust's shortest round-trip form.

use std::collections::BTreeMap;
#[cfg(test)]
use std::io::Write;
#[cfg(test)]
use std::path::Path;

use serde::{Deserialize, Serialize};
use serde_json::{json, Value};

use crate::crs::wgs84_to_ecef;
use crate::export::ExportError;
#[cfg(test)]
use crate::fsio::AtomicFile;

use super::blocks::MIN_BLOCKS_ERROR;
use super::frame::{in_range, region_union};
use super::{ContentInfo, Placement};

/// One content of a tile: where it is and what it holds.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub(crate) struct TileContent {
    /// The GLB's URI relative to the folder of `tileset.json`, e.g. `content/574000_6279000.glb`.
    pub uri: String,
    /// What its writer reported ([`super::ContentInfoHandle::get`]).
    pub info: ContentInfo,
}

/// One tile of the run's grid.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub(crate) struct TileEntry {
    /// The tile's cell in the grid: its lower-left corner's easting and northing (metres of the
    /// output CRS) divided by the tile size; `(0, 0)` for an untiled run (one tile).
    pub cell: (i64, i64),
    /// The buildings as derived ([`super::Detail::Full`]).
    pub full: TileContent,
    /// Their blocks ([`super::Detail::Blocks`]).
    pub blocks: TileContent,
    /// The tile's terrain ([`super::Detail::Terrain`]), when the run writes one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub terrain: Option<TileContent>,
}

/// The widest grid a tileset covers, in cells (2^32: tiles of a metre over the whole earth
/// are fewer).
const MAX_SPAN: u64 = 1 << 32;

impl TileEntry {
    /// Every content of the tile, to change (Full, Blocks, then the terrain's).
    pub(crate) fn contents_mut(&mut self) -> impl Iterator<Item = &mut TileContent> {
        [&mut self.full, &mut self.blocks]
            .into_iter()
            .chain(self.terrain.as_mut())
    }

    /// The cell of the tile whose lower-left corner is `corner` (easting, northing in metres, as
    /// `prepare::Tile::corner`) in a grid of `size` metres (floored, so a corner off the grid
    /// still has its cell).
    pub(crate) fn cell_of(corner: (i64, i64), size: u32) -> (i64, i64) {
        let size = i64::from(size.max(1));
        (corner.0.div_euclid(size), corner.1.div_euclid(size))
    }
}

/// A node of the tree being built.
struct Node {
    region: [f64; 6],
    error: f64,
    json: Value,
}

/// The `tileset.json` text over `tiles` (see the module documentation). Tiles whose contents
/// draw nothing are left out. Errors: two entries for one cell, an empty URI, no tile with
/// anything to draw.
pub(crate) fn tileset_json(tiles: &[TileEntry]) -> Result<String, ExportError> {
    let mut cells: BTreeMap<(i64, i64), Node> = BTreeMap::new();
    let mut seen = std::collections::BTreeSet::new();
    for t in tiles {
        if !seen.insert(t.cell) {
            return Err(ExportError::Invalid(format!(
                "3D Tiles tileset: the tile of cell {:?} is given twice ({} and another)",
                t.cell, t.full.uri
            )));
        }
        for c in [&t.full, &t.blocks].into_iter().chain(t.terrain.as_ref()) {
            if c.uri.trim().is_empty() {
                return Err(ExportError::Invalid(format!(
                    "3D Tiles tileset: the tile of cell {:?} has a content without a URI",
                    t.cell
                )));
            }
        }
        if let Some(n) = grid_node(t) {
            cells.insert(t.cell, n);
        }
    }
    let Some(&(mut x0, mut y0)) = cells.keys().next() else {
        return Err(ExportError::Invalid(
            "3D Tiles tileset: no tile has anything to draw".into(),
        ));
    };
    let (mut x1, mut y1) = (x0, y0);
    for &(x, y) in cells.keys() {
        (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x), y1.max(y));
    }
    let span = x1.abs_diff(x0).max(y1.abs_diff(y0)) + 1;
    if span > MAX_SPAN {
        return Err(ExportError::Invalid(format!(
            "3D Tiles tileset: the tiles span {span} cells of the grid, more than {MAX_SPAN}"
        )));
    }
    let size = span.next_power_of_two() as i64;
    let root = quad(cells.into_iter().collect(), x0, y0, size).ok_or_else(|| {
        ExportError::Invalid("3D Tiles tileset: no tile has anything to draw".into())
    })?;
    let mut root_json = root.json;
    root_json["refine"] = json!("REPLACE");
    let doc = json!({
        "asset": {
            "version": "1.1",
            "extras": {"generator": concat!("citygen ", env!("CARGO_PKG_VERSION"))}
        },
        "geometricError": root.error.max(diagonal(&root.region)),
        "root": root_json
    });
    serde_json::to_string_pretty(&doc).map_err(|e| ExportError::Invalid(e.to_string()))
}

/// Writes [`tileset_json`] of `tiles` to `path` atomically ([`AtomicFile`]: the path holds the
/// old file or the complete new one, never a part).
#[cfg(test)]
pub(crate) fn write_tileset(path: &Path, tiles: &[TileEntry]) -> Result<(), ExportError> {
    let text = tileset_json(tiles)?;
    let file = AtomicFile::create(path)?;
    let mut w = file.writer()?;
    w.write_all(text.as_bytes())?;
    w.write_all(b"\n")?;
    w.flush()?;
    drop(w);
    file.commit()?;
    Ok(())
}

/// The node over `cells` (all in the square of `size` cells, a power of two, from (`x`, `y`),
/// in cell order).
fn quad(cells: Vec<((i64, i64), Node)>, x: i64, y: i64, size: i64) -> Option<Node> {
    if size <= 1 || cells.len() <= 1 {
        // Cells are distinct: a square of one cell holds at most one.
        return cells.into_iter().next().map(|(_, n)| n);
    }
    let h = size / 2;
    let mut quarters: [Vec<((i64, i64), Node)>; 4] = Default::default();
    for (c, n) in cells {
        let q = usize::from(c.0 - x >= h) + 2 * usize::from(c.1 - y >= h);
        quarters[q].push((c, n));
    }
    // (Saturating: past i64 there is no cell, only an empty quarter.)
    let (xh, yh) = (x.saturating_add(h), y.saturating_add(h));
    let origins = [(x, y), (xh, y), (x, yh), (xh, yh)];
    let children: Vec<Node> = quarters
        .into_iter()
        .zip(origins)
        .filter_map(|(q, (qx, qy))| quad(q, qx, qy, h))
        .collect();
    match children.len() {
        0 => None,
        1 => children.into_iter().next(),
        _ => {
            let region = children
                .iter()
                .map(|c| c.region)
                .reduce(|a, b| region_union(&a, &b))
                .unwrap_or_default();
            let largest = children.iter().map(|c| c.error).fold(0.0, f64::max);
            let error = diagonal(&region).max(2.0 * largest);
            let json = json!({
                "boundingVolume": {"region": region},
                "geometricError": error,
                "children": children.into_iter().map(|c| c.json).collect::<Vec<_>>()
            });
            Some(Node {
                region,
                error,
                json,
            })
        }
    }
}

/// A grid tile's node: Blocks, refined by Full (see the module documentation); `None` when
/// neither content draws anything.
fn grid_node(t: &TileEntry) -> Option<Node> {
    // Regions as a shard's manifest gives them (perhaps from before they were held in range).
    let held = |p: &Placement| Placement {
        region: in_range(p.region),
        ..p.clone()
    };
    let blocks = t.blocks.info.placement.as_ref().map(held);
    let full = t.full.info.placement.as_ref().map(held);
    let (blocks, full) = (blocks.as_ref(), full.as_ref());
    // The terrain, in the frame of the tile's other contents (it has none without them).
    let terrain = t.terrain.as_ref().and_then(|c| {
        let p = held(c.info.placement.as_ref()?);
        let same = blocks.or(full).is_some_and(|o| o.transform == p.transform);
        same.then(|| (c.uri.clone(), p.region))
    });
    let with_terrain = |content: Value, region: [f64; 6]| match &terrain {
        Some((uri, r)) => (
            json!({"contents": [content, {"uri": uri, "boundingVolume": {"region": r}}]}),
            region_union(&region, r),
        ),
        None => (json!({ "content": content }), region),
    };
    let blocks_error = t.blocks.info.blocks_error.max(MIN_BLOCKS_ERROR);
    let full_node = full.map(|f| {
        let (contents, region) = with_terrain(
            json!({"uri": t.full.uri, "boundingVolume": {"region": f.region}}),
            f.region,
        );
        let mut n = json!({
            "boundingVolume": {"region": region},
            "geometricError": 0.0,
        });
        merge_into(&mut n, contents);
        match blocks {
            Some(b) if b.transform != f.transform => {
                n["transform"] = json!(relative(b, f));
            }
            Some(_) => {}
            None => n["transform"] = json!(f.transform),
        }
        n
    });
    let (mut region, error) = match (blocks, full) {
        (Some(b), Some(f)) => (region_union(&b.region, &f.region), blocks_error),
        (Some(b), None) => (b.region, blocks_error),
        (None, Some(f)) => (f.region, blocks_error),
        (None, None) => return None,
    };
    if let Some((_, r)) = &terrain {
        region = region_union(&region, r);
    }
    let mut n = json!({
        "boundingVolume": {"region": region},
        "geometricError": error,
        "refine": "REPLACE"
    });
    if let Some(b) = blocks {
        n["transform"] = json!(b.transform);
        let (contents, _) = with_terrain(
            json!({"uri": t.blocks.uri, "boundingVolume": {"region": b.region}}),
            b.region,
        );
        merge_into(&mut n, contents);
    }
    if let Some(f) = full_node {
        n["children"] = json!([f]);
    }
    Some(Node {
        region,
        error,
        json: n,
    })
}

/// Adds the members of the object `more` to the object `n`.
fn merge_into(n: &mut Value, more: Value) {
    if let (Some(n), Value::Object(more)) = (n.as_object_mut(), more) {
        n.extend(more);
    }
}

/// The transform of `child`'s frame relative to `parent`'s: parent⁻¹ · child, both rigid
/// (rotation and translation) column-major 4×4 matrices.
fn relative(parent: &Placement, child: &Placement) -> [f64; 16] {
    let p = glam::DMat4::from_cols_array(&parent.transform);
    let c = glam::DMat4::from_cols_array(&child.transform);
    (p.inverse() * c).to_cols_array()
}

/// The straight-line length (metres) between a region's south-west-bottom and
/// north-east-top corners.
fn diagonal(r: &[f64; 6]) -> f64 {
    let a = glam::DVec3::from(wgs84_to_ecef(r[0].to_degrees(), r[1].to_degrees(), r[4]));
    let b = glam::DVec3::from(wgs84_to_ecef(r[2].to_degrees(), r[3].to_degrees(), r[5]));
    a.distance(b)
}
