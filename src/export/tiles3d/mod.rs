//! OGC 3D Tiles 1.1: one GLB content per tile of a run (`Tiles3dWriter`) and the
//! `tileset.json` over them (`tileset_json`).
//!
//! A run writes two contents per tile (three with a terrain: [`Detail::Terrain`], the file's
//! terrain in the same frame, shown beside both): [`Detail::Full`], the buildings as derived (the glTF
//! writer's faces: `export::gltf::building_groups`), and [`Detail::Blocks`], a coarse LOD1 of
//! them for the upper levels of the tree (`blocks`). The tileset makes each tile a node whose
//! content is its Blocks, refined (REPLACE) by one child whose content is its Full, under a
//! quadtree over the tile grid.
//!
//! A content is a glTF 2.0 binary in the tile's east-north-up frame (glTF's y-up axes: x east,
//! y up, z south, which 3D Tiles turns to z-up), placed on the earth by the tile's `transform`
//! (ENU to ECEF, EPSG:4978). The frame's origin is the centre of the plan bounding box of the
//! tile's footprints (all parts), at the lowest base: the same for both details of a tile, so
//! the Full child needs no transform of its own. Model points go to ECEF through the output CRS
//! (`frame`: the model z plus the origin's is taken as the ellipsoidal height; when the run
//! states a vertical datum, [`OutputContext::vertical_datum`], that height is orthometric and
//! each building is lifted by the EGM96 geoid undulation at its middle, h = H + N, so contents,
//! regions and the `baseHeight` column are ellipsoidal either way).
//!
//! Every building is a feature: all its vertices carry its row in the property table
//! (`EXT_mesh_features`, `_FEATURE_ID_0`), whose columns (`EXT_structural_metadata`,
//! `metadata`) are its source id, name, zone, appearance, height, base height, storeys, roof
//! shape, and the provenance of storeys, height and roof (`storeysSource`, `heightSource`,
//! `roofSource` strings; `storeysError`, `heightError`, `roofProbability` FLOAT32 with noData
//! -1). The buildings' triangles are batched into one primitive per kind of material (the
//! surface's material of `crate::color::material` — matte when none is known, brick, slate,
//! metal, ..., glass — each opaque or blended, with that material's metallic and roughness
//! factors), coloured per vertex (`content`), so a tile is a handful of
//! draw calls whatever its number of colours.
//!
//! The two building contents of a tile are best written by a pair of writers
//! (`Tiles3dWriter::pair`): the Full writer then encodes every building for both, through
//! one map to ECEF and one property-table row (the same in both contents), and the Blocks
//! writer, given the same buildings, only checks them; the bytes are those of two writers on
//! their own (`Tiles3dWriter::new`).
//!
//! The writer keeps the tile in memory (about 45 bytes a vertex, twice that while the GLB is
//! assembled: a LOD3 tile of 150 m in Monaco-Ville is 50,000 triangles, 4 MB of GLB) and writes
//! the GLB in [`BuildingWriter::finish`], when the frame is known. It then gives the content's facts ([`ContentInfo`]: placement, bounding
//! volumes, counts) through the `ContentInfoHandle` it was made with, for the tileset. A tile
//! with nothing to draw (no building, or no triangle) is a valid GLB of an empty scene, and its
//! [`ContentInfo::placement`] is `None`: the tileset then references no content for it.
//! Output is a pure function of the context and the buildings.

mod blocks;
mod content;
mod frame;
mod glb;
mod metadata;
mod terrain;
pub mod tileset;

#[cfg(test)]
mod tests;

use std::io::Write;
use std::sync::{Arc, Mutex};

use glam::{DVec2, DVec3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use serde_json::{json, Value};

use crate::export::gltf::{building_groups, Texturing};
use crate::export::{check_finite, BuildingWriter, Checked, ExportError, OutputContext};
use crate::model::{Building, Lod};

use content::{Batch, EncodedBuilding};
use frame::{BuildingMap, EnuFrame, ModelFrame};

pub(crate) use tileset::{tileset_json, TileContent, TileEntry};

/// Which geometry a content holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Detail {
    /// The buildings as derived, at the run's LOD.
    Full,
    /// Every part's footprint extruded from its base to its top: a coarse LOD1 for the upper
    /// levels of the tileset.
    Blocks,
    /// The terrain of the tile ([`OutputContext::terrain`]), in the frame of the other two
    /// (`terrain`): shown beside Blocks and beside Full.
    Terrain,
}

/// What the tileset needs to know of a content, without opening it: given by the writer after
/// [`BuildingWriter::finish`]. Serialisable, so that a shard's manifest can carry it to the
/// merge step.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ContentInfo {
    /// Which geometry the content holds.
    pub detail: Detail,
    /// Buildings written (the property table's rows).
    pub buildings: usize,
    /// Triangles drawn.
    pub triangles: u64,
    /// Length of the GLB in bytes.
    pub bytes: u64,
    /// The geometric error of this tile's Blocks content (metres): how far the blocks stray
    /// from the buildings (the highest roof above its eaves, the facade relief at LOD3 and
    /// above), at least 0.5 m. The same in both contents of a tile.
    pub blocks_error: f64,
    /// Where the content lies; `None` when it draws nothing.
    pub placement: Option<Placement>,
}

/// Where a content lies on the earth.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Placement {
    /// The content's frame (east-north-up at its origin) to ECEF: a column-major 4×4 matrix, the
    /// 3D Tiles tile `transform`.
    pub transform: [f64; 16],
    /// The WGS84 origin of that frame: longitude and latitude in degrees, ellipsoidal height.
    pub origin: [f64; 3],
    /// 3D Tiles `region` holding the content: west, south, east, north (radians), lowest and
    /// highest ellipsoidal height (metres), with a 5 cm margin.
    pub region: [f64; 6],
    /// 3D Tiles `box` holding the content, in its frame (apply `transform`): centre, then the
    /// east, north and up half-axes; the exact bounds of its positions.
    #[serde(rename = "box")]
    pub bounding_box: [f64; 12],
}

/// Where a writer leaves its [`ContentInfo`]: a shared slot, empty until `finish` succeeds.
#[derive(Clone, Debug, Default)]
pub(crate) struct ContentInfoHandle(Arc<Mutex<Option<ContentInfo>>>);

impl ContentInfoHandle {
    /// The content's facts, once its writer has finished.
    pub(crate) fn get(&self) -> Option<ContentInfo> {
        self.0
            .lock()
            .map(|g| g.clone())
            .unwrap_or_else(|p| p.into_inner().clone())
    }

    fn set(&self, info: ContentInfo) {
        match self.0.lock() {
            Ok(mut g) => *g = Some(info),
            Err(p) => *p.into_inner() = Some(info),
        }
    }
}

/// Where the writer is in its `begin` / `write` / `finish` life.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    New,
    Open,
    Finished,
}

/// The most buildings of one content: feature ids are f32 vertex attributes, exact to 2^24.
const MAX_FEATURES: usize = 1 << 24;

/// Buildings encoded in parallel at a time by `write_all`: a bound on the encoded buildings
/// held besides the tile.
const PARALLEL_CHUNK: usize = 256;

/// What the building contents of one tile hold: the primitives of each, and what they share
/// (every building's anchor, property-table row, the plan and the blocks' error).
#[derive(Default)]
struct Tile {
    /// The primitives of [`Detail::Full`] (`[0]`) and [`Detail::Blocks`] (`[1]`).
    prims: [content::Batches; 2],
    /// Each building's anchor in ECEF, by feature id.
    anchors: Vec<DVec3>,
    rows: metadata::Rows,
    /// The plan bounding box of every part's footprint and the lowest part base (model frame).
    plan: Option<(DVec2, DVec2, f64)>,
    blocks_error: f64,
    /// The schema and the property table of `rows`, made by the first content finished (the
    /// rows are the same in both).
    metadata: Option<Arc<(Value, metadata::Table)>>,
}

/// Which primitives of a [`Tile`] a writer's `write` fills.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Role {
    /// Its own content's (a writer made by [`Tiles3dWriter::new`]).
    Alone,
    /// Both, Full and Blocks (the Full writer of a [`Tiles3dWriter::pair`]).
    Both,
    /// None: the other writer of its pair fills them (the Blocks writer of a pair).
    Fed,
}

/// Writes one 3D Tiles content (a GLB) of one tile (see the module documentation).
pub(crate) struct Tiles3dWriter<W: Write + Send> {
    out: W,
    detail: Detail,
    state: State,
    model: Option<ModelFrame>,
    /// The run's origin height: a model z plus it is an ellipsoidal height.
    origin_z: f64,
    /// LOD3 and above: openings and balconies are drawn.
    detailed: bool,
    /// `--textures` ([`Tiles3dWriter::with_textures`]).
    textures: bool,
    /// What the buildings are textured with (from `textures` and the LOD, at `begin`).
    tex: Texturing,
    /// The tile, shared with the other writer of a pair.
    tile: Arc<Mutex<Tile>>,
    role: Role,
    info: ContentInfoHandle,
    /// The terrain a [`Detail::Terrain`] writer draws.
    terrain: Option<Arc<crate::model::Terrain>>,
}

/// The tile, whatever a panicking writer left it in (the run then fails anyway).
fn lock(tile: &Mutex<Tile>) -> std::sync::MutexGuard<'_, Tile> {
    tile.lock().unwrap_or_else(|p| p.into_inner())
}

/// The index of a building content's primitives in [`Tile::prims`].
fn slot(detail: Detail) -> usize {
    match detail {
        Detail::Blocks => 1,
        Detail::Full | Detail::Terrain => 0,
    }
}

impl<W: Write + Send> Tiles3dWriter<W> {
    /// A writer of `detail` to `out` (nothing is written before `finish`), and the handle that
    /// gives its [`ContentInfo`] after `finish`.
    pub(crate) fn new(out: W, detail: Detail) -> (Tiles3dWriter<W>, ContentInfoHandle) {
        Self::with_tile(out, detail, Arc::default(), Role::Alone)
    }

    /// The writers of a tile's two building contents, Full to `full` and Blocks to `blocks`
    /// (with the handles of their facts), that encode each building once for both: give both
    /// the same buildings (`begin` with the same context, and `finish` the Blocks writer after
    /// the Full writer has written every building). They write the bytes that
    /// [`Tiles3dWriter::new`]'s writers would.
    pub(crate) fn pair(full: W, blocks: W) -> [(Tiles3dWriter<W>, ContentInfoHandle); 2] {
        let tile: Arc<Mutex<Tile>> = Arc::default();
        [
            Self::with_tile(full, Detail::Full, Arc::clone(&tile), Role::Both),
            Self::with_tile(blocks, Detail::Blocks, tile, Role::Fed),
        ]
    }

    fn with_tile(
        out: W,
        detail: Detail,
        tile: Arc<Mutex<Tile>>,
        role: Role,
    ) -> (Tiles3dWriter<W>, ContentInfoHandle) {
        let info = ContentInfoHandle::default();
        let w = Tiles3dWriter {
            out,
            detail,
            state: State::New,
            model: None,
            origin_z: 0.0,
            detailed: false,
            textures: false,
            tex: Texturing::Off,
            tile,
            role,
            info: info.clone(),
            terrain: None,
        };
        (w, info)
    }

    /// With `on`, a Full content's walls and roofs carry procedural textures (`--textures`,
    /// as the glTF writer's: `crate::export::texture`). Off by default.
    pub(crate) fn with_textures(mut self, on: bool) -> Tiles3dWriter<W> {
        self.textures = on;
        self
    }

    /// Gives back the output (complete after a successful `finish`).
    #[cfg(test)]
    pub(crate) fn into_inner(self) -> W {
        self.out
    }

    fn open(&self, what: &str) -> Result<ModelFrame, ExportError> {
        match (self.state, self.model) {
            (State::Open, Some(m)) => Ok(m),
            (State::New, _) => Err(ExportError::Invalid(format!(
                "3D Tiles writer: {what} called before begin"
            ))),
            _ => Err(ExportError::Invalid(format!(
                "3D Tiles writer: {what} called after finish"
            ))),
        }
    }

    /// Appends one encoded building to `tile`: its primitives of this writer's content, and
    /// with [`Role::Both`] its Blocks too.
    fn add(&self, tile: &mut Tile, b: &Building, e: Encoded) -> Result<(), ExportError> {
        let feature = tile.rows.len();
        if feature >= MAX_FEATURES {
            return Err(ExportError::Invalid(format!(
                "3D Tiles writer: more than {MAX_FEATURES} buildings in one tile: use smaller tiles (--tile)"
            )));
        }
        let mut contents = vec![(slot(self.detail), e.prims)];
        if let Some(blocks) = e.blocks {
            contents.push((slot(Detail::Blocks), blocks));
        }
        let empty = Batch::default();
        let fits = contents.iter().all(|(i, prims)| {
            prims
                .iter()
                .all(|(k, p)| tile.prims[*i].get(k).unwrap_or(&empty).fits(p))
        });
        if !fits {
            return Err(ExportError::Invalid(format!(
                "3D Tiles writer: building {}: the tile passes 2^32 vertices: use smaller tiles (--tile)",
                b.id
            )));
        }
        for (i, prims) in contents {
            for (k, p) in prims {
                tile.prims[i].entry(k).or_default().push(p, feature as u32);
            }
        }
        tile.anchors.push(e.anchor_ecef);
        let base = b.base_z + self.origin_z;
        tile.rows.push(
            b,
            match e.lift {
                Some(n) => base + n,
                None => base,
            },
        );
        self.track(tile, b);
        Ok(())
    }

    /// Grows the plan bounding box and the lowest base by `b`'s parts, and the blocks' error.
    fn track(&self, tile: &mut Tile, b: &Building) {
        for p in &b.parts {
            let (lo, hi) = footprint_bounds(p);
            let (plo, phi, base) = tile.plan.get_or_insert((lo, hi, p.base_z));
            *plo = plo.min(lo);
            *phi = phi.max(hi);
            *base = base.min(p.base_z);
        }
        tile.blocks_error = tile
            .blocks_error
            .max(blocks::blocks_error(b, self.detailed));
    }

    /// Writes the GLB and publishes the content's facts.
    fn write_content(&mut self) -> Result<(), ExportError> {
        let shared = Arc::clone(&self.tile);
        let mut tile = lock(&shared);
        // This content's primitives are not needed after it (the other content has its own).
        let prims = std::mem::take(&mut tile.prims[slot(self.detail)]);
        let triangles: u64 = match (self.detail, &self.terrain) {
            (Detail::Terrain, Some(t)) => t.triangles.len() as u64,
            (Detail::Terrain, None) => 0,
            _ => prims.values().map(Batch::triangles).sum(),
        };
        let blocks_error = tile.blocks_error.max(blocks::MIN_BLOCKS_ERROR);
        let buildings = tile.rows.len();
        let generator = concat!("citygen ", env!("CARGO_PKG_VERSION"));
        let (model, plan) = match (self.model, tile.plan) {
            (Some(m), Some(p)) if triangles > 0 => (m, p),
            _ => {
                let doc = json!({
                    "asset": {"version": "2.0", "generator": generator},
                    "scene": 0,
                    "scenes": [{}]
                });
                let bytes = glb::write_glb(&mut self.out, &doc, &[])?;
                self.info.set(ContentInfo {
                    detail: self.detail,
                    buildings,
                    triangles: 0,
                    bytes,
                    blocks_error,
                    placement: None,
                });
                return Ok(());
            }
        };
        let (lo, hi, base) = plan;
        let centre = ((lo + hi) / 2.0).extend(base);
        let (lon, lat, h) = model.to_wgs84(centre);
        let h = match model.lift_at(centre) {
            Some(n) => h + n,
            None => h,
        };
        let frame = EnuFrame::at(lon, lat, h);
        let mut bin = glb::Bin::default();
        // The primitives' views, and about a hundred bytes a row for the property table.
        bin.bytes
            .reserve(content::laid_bytes(&prims) + 128 * (tile.rows.len() + 1));
        if let (Detail::Terrain, Some(t)) = (self.detail, self.terrain.clone()) {
            let (parts, lo, hi) = terrain::lay_out(&t, &model, &frame, &mut bin);
            let mut doc = json!({
                "asset": {"version": "2.0", "generator": generator},
                "scene": 0,
                "scenes": [{"nodes": [0]}],
                "bufferViews": bin.views,
                "buffers": [{"byteLength": bin.bytes.len()}]
            });
            for key in ["nodes", "meshes", "materials", "accessors"] {
                doc[key] = parts[key].clone();
            }
            let bytes = glb::write_glb(&mut self.out, &doc, &bin.bytes)?;
            self.set_info(ContentFacts {
                buildings,
                triangles,
                bytes,
                blocks_error,
                frame: (&frame, [lon, lat, h]),
                lo,
                hi,
            });
            return Ok(());
        }
        let laid = content::lay_out(&prims, &tile.anchors, &frame, &mut bin);
        let made = match &tile.metadata {
            Some(m) => Arc::clone(m),
            None => {
                let m = Arc::new((metadata::schema(&tile.rows), metadata::table(&tile.rows)));
                tile.metadata = Some(Arc::clone(&m));
                m
            }
        };
        let (schema, table) = &*made;
        let table = metadata::property_table(table, &mut bin);
        let mut doc = json!({
            "asset": {"version": "2.0", "generator": generator},
            "extensionsUsed": ["EXT_mesh_features", "EXT_structural_metadata"],
            "extensions": {
                "EXT_structural_metadata": {
                    "schema": schema,
                    "propertyTables": [table]
                }
            },
            "scene": 0,
            "scenes": [{"nodes": [0]}],
            "nodes": [{"name": "buildings", "mesh": 0}],
            "meshes": [{"primitives": laid.primitives}],
            "materials": laid.materials,
            "accessors": laid.accessors,
            "bufferViews": bin.views,
            "buffers": [{"byteLength": bin.bytes.len()}]
        });
        if !laid.textures.is_empty() {
            // The pictures as PNG images in the buffer, a texture each, one repeating sampler.
            let (mut images, mut textures) = (Vec::new(), Vec::new());
            for (i, t) in laid.textures.iter().enumerate() {
                let view = bin.view(&t.png(), None);
                images.push(json!({"bufferView": view, "mimeType": "image/png", "name": t.name()}));
                textures.push(json!({"sampler": 0, "source": i, "name": t.name()}));
            }
            doc["textures"] = json!(textures);
            doc["images"] = json!(images);
            doc["samplers"] =
                json!([{"magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 10497}]);
            doc["bufferViews"] = json!(bin.views);
            doc["buffers"] = json!([{"byteLength": bin.bytes.len()}]);
        }
        let bytes = glb::write_glb(&mut self.out, &doc, &bin.bytes)?;
        self.set_info(ContentFacts {
            buildings,
            triangles,
            bytes,
            blocks_error,
            frame: (&frame, [lon, lat, h]),
            lo: laid.lo,
            hi: laid.hi,
        });
        Ok(())
    }

    /// Publishes the facts of a content that draws something.
    fn set_info(&self, f: ContentFacts<'_>) {
        let (c, half) = ((f.lo + f.hi) / 2.0, (f.hi - f.lo) / 2.0);
        self.info.set(ContentInfo {
            detail: self.detail,
            buildings: f.buildings,
            triangles: f.triangles,
            bytes: f.bytes,
            blocks_error: f.blocks_error,
            placement: Some(Placement {
                transform: f.frame.0.transform(),
                origin: f.frame.1,
                region: frame::region_of_box(f.frame.0, f.lo, f.hi),
                bounding_box: [
                    c.x, c.y, c.z, half.x, 0.0, 0.0, 0.0, half.y, 0.0, 0.0, 0.0, half.z,
                ],
            }),
        });
    }
}

/// What [`Tiles3dWriter::set_info`] publishes: counts, and the frame and bounds of the
/// positions in it.
struct ContentFacts<'a> {
    buildings: usize,
    triangles: u64,
    bytes: u64,
    blocks_error: f64,
    frame: (&'a EnuFrame, [f64; 3]),
    lo: DVec3,
    hi: DVec3,
}

/// The plan bounding box of a part's footprint.
fn footprint_bounds(p: &crate::model::Part) -> (DVec2, DVec2) {
    p.footprint
        .outer
        .iter()
        .fold((DVec2::INFINITY, DVec2::NEG_INFINITY), |(lo, hi), q| {
            (lo.min(*q), hi.max(*q))
        })
}

/// One building encoded for a writer: its primitives of the writer's content, and of Blocks
/// too for a writer of [`Role::Both`].
struct Encoded {
    anchor_ecef: DVec3,
    /// What lifts the building's heights to ellipsoidal ones (`BuildingMap::lift`).
    lift: Option<f64>,
    prims: content::Prims,
    blocks: Option<content::Prims>,
}

/// Encodes one building (a pure function of it, run in parallel) for a writer of `detail`
/// and `role`: through one map to ECEF whatever the contents.
fn encode(
    b: &Building,
    model: &ModelFrame,
    (detail, role): (Detail, Role),
    (detailed, tex): (bool, Texturing),
) -> Encoded {
    // The anchor: the middle of the building's plan, at its base.
    let (lo, hi) = b.parts.iter().map(footprint_bounds).fold(
        (DVec2::INFINITY, DVec2::NEG_INFINITY),
        |(lo, hi), (a, c)| (lo.min(a), hi.max(c)),
    );
    let anchor = if lo.x <= hi.x && lo.y <= hi.y {
        ((lo + hi) / 2.0).extend(b.base_z)
    } else {
        DVec3::new(0.0, 0.0, b.base_z)
    };
    let map = BuildingMap::at(model, anchor);
    let groups = |detail: Detail| match detail {
        Detail::Full => building_groups(b, detailed, tex),
        Detail::Blocks => blocks::block_groups(b, tex),
        Detail::Terrain => Vec::new(),
    };
    let EncodedBuilding {
        anchor_ecef,
        lift,
        prims,
    } = content::encode(&groups(detail), &map);
    let blocks = (role == Role::Both).then(|| content::encode(&groups(Detail::Blocks), &map).prims);
    Encoded {
        anchor_ecef,
        lift,
        prims,
        blocks,
    }
}

impl<W: Write + Send> BuildingWriter for Tiles3dWriter<W> {
    fn begin(&mut self, ctx: &OutputContext) -> Result<(), ExportError> {
        if self.state != State::New {
            return Err(ExportError::Invalid(
                "3D Tiles writer: begin called twice".into(),
            ));
        }
        if ctx.crs.is_geographic() {
            return Err(ExportError::Invalid(
                "3D Tiles writer: the output CRS must be projected (metres), not EPSG:4326".into(),
            ));
        }
        self.model = Some(ModelFrame::new(ctx));
        self.origin_z = ctx.origin.z;
        self.detailed = ctx.lod >= Lod::Lod3;
        self.tex = Texturing::of(self.textures, ctx.lod);
        if self.detail == Detail::Terrain {
            self.terrain = ctx.terrain.clone();
        }
        self.state = State::Open;
        Ok(())
    }

    fn write(&mut self, building: &Building) -> Result<(), ExportError> {
        let model = self.open("write")?;
        check_finite("3D Tiles writer", building)?;
        let shared = Arc::clone(&self.tile);
        let mut tile = lock(&shared);
        match (self.detail, self.role) {
            (_, Role::Fed) => Ok(()),
            (Detail::Terrain, _) => {
                self.track(&mut tile, building);
                Ok(())
            }
            (detail, role) => {
                let e = encode(building, &model, (detail, role), (self.detailed, self.tex));
                self.add(&mut tile, building, e)
            }
        }
    }

    /// Encodes the buildings in parallel and appends them in order: the same bytes as `write`
    /// on each.
    fn write_all(&mut self, buildings: &[Building]) -> Result<(), ExportError> {
        self.write_checked(&Checked::check(buildings))
    }

    fn write_checked(&mut self, checked: &Checked<'_>) -> Result<(), ExportError> {
        let model = self.open("write")?;
        let (detail, role, detailed) = (self.detail, self.role, (self.detailed, self.tex));
        if role == Role::Fed {
            return checked.refused("3D Tiles writer");
        }
        let shared = Arc::clone(&self.tile);
        if detail == Detail::Terrain {
            // Only the frame is needed: the buildings' plan and lowest base.
            let mut tile = lock(&shared);
            checked
                .finite()
                .iter()
                .for_each(|b| self.track(&mut tile, b));
            return checked.refused("3D Tiles writer");
        }
        for chunk in checked.finite().chunks(PARALLEL_CHUNK) {
            let encoded: Vec<Encoded> = chunk
                .par_iter()
                .map(|b| encode(b, &model, (detail, role), detailed))
                .collect();
            // Locked only while appending: not across the parallel encoding above.
            let mut tile = lock(&shared);
            for (b, e) in chunk.iter().zip(encoded) {
                self.add(&mut tile, b, e)?;
            }
        }
        checked.refused("3D Tiles writer")
    }

    fn finish(&mut self) -> Result<(), ExportError> {
        self.open("finish")?;
        self.state = State::Finished;
        self.write_content()
    }
}
