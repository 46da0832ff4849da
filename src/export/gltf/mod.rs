//! glTF 2.0 binary (`.glb`) writer.
//!
//! Layout of the output: one scene; one node per building, named by the building key
//! (`way_123`) with the source id, zone, appearance, heights and the provenance of its storeys,
//! height and roof (`storeys_source`, `height_source`, `roof_source`; `storeys_error`,
//! `height_error`, `roof_probability` when known) in its `extras`; under it one
//! child node per surface class (`walls`, `roof`, `ground`, in LOD3 runs `windows`, `doors`,
//! `balconies`, and for parts with an interior (LOD4) `floors`, `interior walls`, `interior
//! doors`, `stairs`, `slabs`) holding one mesh, with one triangle primitive per material (usually one). Classes
//! without triangles get no node.
//!
//! Where two parts of a building touch, the faces of each that lie against the other (a shared
//! wall, a roof under another part's ground) are inside the building and left out, or the
//! pieces of them that the other part covers (`contact`): drawn, they speckle the seams where
//! parts meet. The CityGML and IFC solids keep them.
//!
//! LOD3 (runs at [`Lod::Lod3`] or above): walls are triangulated with their holes. Each window
//! and door is a pane in its opening's rectangle set back `OPENING_SETBACK` into the wall
//! (towards the inside, never deeper than the wall is thick) so it reads as recessed, plus four
//! reveal quads lining the hole up to the pane, in the wall colour. A framed opening
//! (`Opening::framed`, the KB's `windowstyle="framed"`) has its frame
//! (`crate::export::lod3geom::opening_frame`: the standard one `FRAME_WIDTH` wide, its front
//! halfway into the reveal; an explicit one standing out of the wall) round a smaller pane, in
//! the frame colour (the reveals take the frame colour where the opening is too small for a
//! frame). Every window whose bottom edge stands `LOW_SILL` or more above its wall's base has a
//! sill (`crate::export::lod3geom::sills`: a box `SILL_PROJECTION` out of the wall under it, in
//! `SILL_COLOR`, without its face against the wall), in the `windows` class. The shell behind a pane is hollow, so glazed windows' glass is opaque:
//! the window colour darkened (`GLASS_SHADE`), smooth and a little metallic, as glass with an
//! unlit room behind it looks from the street; only a part with an interior (LOD4) has
//! transparent glass (alpha `GLASS_ALPHA`, `BLEND`). Doors and unglazed windows are opaque in
//! their colour. Balconies (`crate::export::lod3geom::balcony_faces`) are the slab in the
//! balcony's colour, a railing of handrail and posts in dark iron, and its infill of tinted glass
//! (`BLEND`), without their faces in the wall's plane. No material is double-sided: every face
//! is the outside of a body.
//!
//! LOD4 ([`crate::export::lod4geom`]): `floors` are the rooms' polygons at floor height, facing
//! up; `interior walls` are closed boxes of the walls' thickness around their centre lines,
//! floor to ceiling, with the door holes and their reveals; `interior doors` are each a leaf in
//! the wall's middle plane, one face per side; `stairs` are the steps' closed blocks; `slabs`
//! are the floor slabs above the ground storey without their top face (the floors cover it),
//! so their undersides are the ceilings below. Materials are PBR metallic-roughness, one per distinct
//! (class, colour, material), numbered in first-seen order: `baseColorFactor` the surface's
//! colour, `roughnessFactor` and `metallicFactor` its material's (`crate::color::material`: walls
//! the part's `wall_material`, roofs its `roof_material`, glazed panes glass, the rest matte at
//! roughness 0.9); a material's name is `<class> <#rrggbb>` and the material's name when one is
//! known (`walls #a0522d brick`, `roof #4a5259 slate`). Coordinates are metres, Y up, relative to the
//! run's local origin, which `asset.extras` records with the CRS (`{"crs": "EPSG:2154",
//! "origin": [E, N, H]}`; when the run states a vertical datum, also `"verticalCrs": "EPSG:5773"`
//! when its code is known and `"verticalDatum"`, its name). Faces are flat shaded: every face has its own vertices and normal.
//!
//! Streaming: a GLB starts with its JSON chunk, which must know the binary chunk's length, so the
//! vertex and index bytes are spooled to a scratch file as buildings arrive and copied after the
//! JSON in [`BuildingWriter::finish`]. The JSON records of the arrays that grow with the number of
//! buildings (nodes, meshes, accessors, buffer views) are serialised as each building arrives and
//! spooled too: to scratch files beside the output with [`GltfWriter::beside`] (memory stays
//! flat however many buildings), in memory with [`GltfWriter::new`]. What stays in memory is
//! the materials and 4 bytes per building (the scene's root list). Output is a pure function of
//! the context and the buildings.
//!
//! A context with a terrain gets a root node `terrain` after the buildings' (`terrain`).
//!
//! Code layout: this module holds the writer, its state and the surface classes; `mesh` groups
//! and triangulates a building's faces (`lod4` its interior's, `contact` leaves out those
//! between parts), `materials` makes the PBR materials, `spool` spools the data and records and assembles the GLB, `json` holds the JSON
//! records.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{self, BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use rayon::prelude::*;

use crate::color::material::Material;
use crate::color::Color;
use crate::crs::Crs;
use crate::export::texture::Texture;
use crate::export::{vertical_datum, BuildingWriter, Checked, ExportError, OutputContext};
use crate::model::{Building, Lod};

use json::{AssetExtras, Document};
use mesh::{encode, Encoded};
use spool::Spool;

// What the 3D Tiles writer (`export::tiles3d`) shares: the faces of a building grouped and
// triangulated, and how a colour and material become a PBR material.
pub(crate) use group::{group, Group};
pub(crate) use materials::finish_params;
pub(crate) use mesh::{add_textured_edge, add_textured_roof, building_groups, Texturing};

mod contact;
mod group;
mod json;
mod lod4;
mod materials;
mod mesh;
mod spool;
mod terrain;

/// glTF component types.
const FLOAT: u32 = 5126;

const UNSIGNED_SHORT: u32 = 5123;

const UNSIGNED_INT: u32 = 5125;

/// Buffer view targets.
const ARRAY_BUFFER: u32 = 34962;

const ELEMENT_ARRAY_BUFFER: u32 = 34963;

/// Byte stride of the vertex views: tightly packed f32 VEC3. glTF requires a stride on a vertex
/// view that several accessors share (a building's positions and normals share one view).
const VEC3_STRIDE: u32 = 12;

/// Colour of ground surfaces (the model gives them none; they face down and are rarely seen).
const GROUND_COLOR: Color = Color::GREY;

/// How far window and door panes sit behind the wall's outer face (metres).
pub(crate) const OPENING_SETBACK: f64 = 0.1;

/// Opacity of glazed windows' glass in parts with an interior (LOD4); elsewhere glass is opaque.
pub(crate) const GLASS_ALPHA: f32 = 0.35;

/// Opaque glass is the window colour times this (in sRGB): dark, as a pane with an unlit room
/// behind it looks from the street.
pub(crate) const GLASS_SHADE: f32 = 0.4;

/// Semantic class of a group of surfaces: one child node per class and building.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) enum SurfaceClass {
    Walls,
    Roof,
    Ground,
    Windows,
    Doors,
    Balconies,
    /// LOD4: room floors, interior walls, their doors, stairs, upper floor slabs.
    Floors,
    InteriorWalls,
    InteriorDoors,
    Stairs,
    Slabs,
    /// The file's terrain (not a building's: never in [`SurfaceClass::ALL`]).
    Terrain,
}

impl SurfaceClass {
    /// Every class, in the order of the building's child nodes.
    const ALL: [SurfaceClass; 11] = [
        SurfaceClass::Walls,
        SurfaceClass::Roof,
        SurfaceClass::Ground,
        SurfaceClass::Windows,
        SurfaceClass::Doors,
        SurfaceClass::Balconies,
        SurfaceClass::Floors,
        SurfaceClass::InteriorWalls,
        SurfaceClass::InteriorDoors,
        SurfaceClass::Stairs,
        SurfaceClass::Slabs,
    ];

    /// The class's node name (`walls`, `interior walls`, ...).
    pub(crate) fn name(self) -> &'static str {
        match self {
            SurfaceClass::Walls => "walls",
            SurfaceClass::Roof => "roof",
            SurfaceClass::Ground => "ground",
            SurfaceClass::Windows => "windows",
            SurfaceClass::Doors => "doors",
            SurfaceClass::Balconies => "balconies",
            SurfaceClass::Floors => "floors",
            SurfaceClass::InteriorWalls => "interior walls",
            SurfaceClass::InteriorDoors => "interior doors",
            SurfaceClass::Stairs => "stairs",
            SurfaceClass::Slabs => "slabs",
            SurfaceClass::Terrain => "terrain",
        }
    }

    /// LOD3 detail classes (and the LOD4 ones, which only parts with an interior have),
    /// written only in LOD3 and LOD4 runs.
    fn is_detail(self) -> bool {
        !matches!(
            self,
            SurfaceClass::Walls | SurfaceClass::Roof | SurfaceClass::Ground
        )
    }
}

/// Where the writer is in its `begin` / `write` / `finish` life.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    New,
    Open,
    /// A write to the scratch file failed: the buffer no longer matches the records.
    Failed,
    Finished,
}

/// A GLB's length field is a `u32`: no GLB is larger, its binary chunk even less.
const GLB_MAX_BYTES: u64 = u32::MAX as u64;

/// Streaming glTF 2.0 binary writer (see the module documentation for the layout).
pub struct GltfWriter<W: Write + Send> {
    out: W,
    scratch: Option<BufWriter<File>>,
    /// A dry run's writer ([`GltfWriter::discarding`]): no scratch file, the data only counted.
    discard: bool,
    /// Bytes written to the scratch file so far (always a multiple of 4).
    bin_len: u64,
    /// The largest binary chunk accepted ([`GLB_MAX_BYTES`]; smaller in tests).
    max_bin: u64,
    state: State,
    doc: Document,
    /// Serialised records of `nodes`, `meshes`, `accessors` and `bufferViews`, in that order.
    spools: [Spool; 4],
    /// Reused buffers of the buildings being encoded (one per building of a parallel batch).
    slots: Vec<Encoded>,
    /// Reused buffer one record is serialised into.
    json_scratch: Vec<u8>,
    /// (class, colour bits, material, picture) -> material index, for reuse across buildings.
    material_index: BTreeMap<(SurfaceClass, [u32; 4], Material, Option<Texture>), u32>,
    /// `--textures`: walls and roofs carry pictures ([`GltfWriter::with_textures`]).
    textures: bool,
    /// What the run's buildings are textured with (from `textures` and the LOD, at `begin`).
    tex: Texturing,
    /// The pictures used so far, in first-use order (the file's textures and images).
    pictures: Vec<Texture>,
    /// Whether the run is LOD3 or above (openings and balconies are written).
    detail: bool,
    /// The file's terrain, written after the buildings (`terrain`).
    terrain: Option<std::sync::Arc<crate::model::Terrain>>,
    /// Deletes a scratch file this writer created (see [`GltfWriter::beside`]). Declared after
    /// `scratch` so that the file is closed before it is removed.
    scratch_guard: ScratchGuard,
}

/// Removes its paths when dropped.
struct ScratchGuard(Vec<PathBuf>);

impl Drop for ScratchGuard {
    fn drop(&mut self) {
        for path in self.0.drain(..) {
            let _ = std::fs::remove_file(path);
        }
    }
}

impl<W: Write + Send> GltfWriter<W> {
    /// A writer that writes the `.glb` to `out` and spools the binary chunk to `scratch`, a file
    /// it may truncate, read back and overwrite (an anonymous temporary file is ideal). Nothing is
    /// written to `out` before [`BuildingWriter::finish`].
    pub fn new(out: W, scratch: File) -> GltfWriter<W> {
        GltfWriter {
            out,
            scratch: Some(BufWriter::with_capacity(1 << 20, scratch)),
            discard: false,
            bin_len: 0,
            max_bin: GLB_MAX_BYTES,
            state: State::New,
            doc: Document::default(),
            spools: Default::default(),
            slots: Vec::new(),
            json_scratch: Vec::new(),
            material_index: BTreeMap::new(),
            textures: false,
            tex: Texturing::Off,
            pictures: Vec::new(),
            detail: false,
            terrain: None,
            scratch_guard: ScratchGuard(Vec::new()),
        }
    }

    /// A writer for a dry run, whose output is thrown away: it renders every building as the
    /// other writers do (triangulation, binary layout, JSON records) but stores nothing, no
    /// scratch file and no spool: the binary data and the records are only counted. The GLB it
    /// writes to `out` has the right header and length, the JSON chunk's fixed parts, and
    /// blanks (spaces, zero bytes) in place of the records and the binary data.
    pub(crate) fn discarding(out: W) -> GltfWriter<W> {
        GltfWriter {
            out,
            scratch: None,
            discard: true,
            bin_len: 0,
            max_bin: GLB_MAX_BYTES,
            state: State::New,
            doc: Document::default(),
            spools: std::array::from_fn(|_| Spool::Count { len: 0, count: 0 }),
            slots: Vec::new(),
            json_scratch: Vec::new(),
            material_index: BTreeMap::new(),
            textures: false,
            tex: Texturing::Off,
            pictures: Vec::new(),
            detail: false,
            terrain: None,
            scratch_guard: ScratchGuard(Vec::new()),
        }
    }

    /// A writer whose scratch file is created next to `target` (the final output path, whose
    /// folder must exist), so that it lands on the same disk as the output rather than on a
    /// possibly small temporary file system. The scratch file is deleted when the writer is
    /// dropped (on Unix it is unlinked at once and only the open handle keeps it).
    pub fn beside(out: W, target: &Path) -> io::Result<GltfWriter<W>> {
        let (file, left) = crate::fsio::scratch_beside(target, "bin")?;
        let mut w = GltfWriter::new(out, file);
        // Unlinking an open file works on Unix; elsewhere it is removed on drop.
        w.scratch_guard.0.extend(left);
        for (i, array) in ["nodes", "meshes", "accessors", "views"].iter().enumerate() {
            let (file, left) = crate::fsio::scratch_beside(target, array)?;
            w.scratch_guard.0.extend(left);
            w.spools[i] = Spool::File {
                w: BufWriter::with_capacity(1 << 18, file),
                len: 0,
                count: 0,
            };
        }
        Ok(w)
    }

    /// With `on`, walls and roofs carry procedural textures (`--textures`,
    /// `crate::export::texture`): the materials' patterns in metres, and at LOD2 the bays of
    /// the facades. Off by default: every byte is as without it.
    pub fn with_textures(mut self, on: bool) -> GltfWriter<W> {
        self.textures = on;
        self
    }

    /// Gives back the output (complete after a successful `finish`).
    pub fn into_inner(self) -> W {
        self.out
    }

    /// `begin` with the CRS label already computed (kept apart so that it is the only place that
    /// asks the CRS for its EPSG code).
    fn start(&mut self, ctx: &OutputContext, crs_label: String) -> Result<(), ExportError> {
        if self.state != State::New {
            return Err(ExportError::Invalid(
                "glTF writer: begin called twice".into(),
            ));
        }
        if !self.discard {
            let scratch = self
                .scratch
                .as_mut()
                .ok_or_else(|| ExportError::Invalid("glTF writer: scratch file missing".into()))?;
            scratch.get_mut().set_len(0)?;
            scratch.seek(SeekFrom::Start(0))?;
        }
        let datum = vertical_datum(ctx);
        self.doc.asset_extras = AssetExtras {
            crs: crs_label,
            vertical_crs: datum
                .and_then(|(code, _)| code)
                .map(|v| format!("EPSG:{v}")),
            vertical_datum: datum.map(|(_, name)| name.to_string()),
            origin: [ctx.origin.x, ctx.origin.y, ctx.origin.z],
            lod: ctx.lod.number(),
            source: ctx.source_name.clone(),
        };
        self.detail = ctx.lod >= Lod::Lod3;
        self.tex = Texturing::of(self.textures, ctx.lod);
        self.terrain = ctx.terrain.clone();
        self.state = State::Open;
        Ok(())
    }

    /// Appends one building: triangulates its faces, writes its binary data to the scratch file
    /// and records its nodes, meshes, accessors and buffer views.
    fn add_building(&mut self, b: &Building) -> Result<(), ExportError> {
        let mut slots = std::mem::take(&mut self.slots);
        if slots.is_empty() {
            slots.push(Encoded::default());
        }
        let r = encode(b, self.detail, self.tex, false, &mut slots[0])
            .and_then(|()| self.add_encoded(b, &slots[0]));
        self.slots = slots;
        r
    }
}

impl<W: Write + Send> BuildingWriter for GltfWriter<W> {
    fn begin(&mut self, ctx: &OutputContext) -> Result<(), ExportError> {
        let label = crs_label(&ctx.crs);
        self.start(ctx, label)
    }

    fn write(&mut self, building: &Building) -> Result<(), ExportError> {
        match self.state {
            State::Open => self.add_building(building),
            State::New => Err(ExportError::Invalid(
                "glTF writer: write called before begin".into(),
            )),
            State::Failed => Err(ExportError::Invalid(
                "glTF writer: an earlier write failed".into(),
            )),
            State::Finished => Err(ExportError::Invalid(
                "glTF writer: write called after finish".into(),
            )),
        }
    }

    /// Encodes (triangulates) the buildings in parallel, a batch at a time (`super::batches`),
    /// and appends them in order: the same bytes as `write` on each.
    fn write_all(&mut self, buildings: &[Building]) -> Result<(), ExportError> {
        self.write_checked(&Checked::check(buildings))
    }

    fn write_checked(&mut self, checked: &Checked<'_>) -> Result<(), ExportError> {
        if self.state != State::Open {
            // The error of `write` out of begin..finish.
            return checked.buildings.first().map_or(Ok(()), |b| self.write(b));
        }
        let detail = self.detail;
        let tex = self.tex;
        let mut slots = std::mem::take(&mut self.slots);
        slots.resize_with(super::PARALLEL_BATCH, Encoded::default);
        let r: Result<(), ExportError> = super::batches(checked.finite()).try_for_each(|batch| {
            let encoded: Vec<_> = batch
                .par_iter()
                .zip(slots.par_iter_mut())
                .map(|(b, slot)| encode(b, detail, tex, true, slot))
                .collect();
            for ((b, e), slot) in batch.iter().zip(encoded).zip(&mut slots) {
                e?;
                self.add_encoded(b, slot)?;
                slot.trim();
            }
            Ok(())
        });
        self.slots = slots;
        r?;
        checked.refused("glTF writer")
    }

    fn finish(&mut self) -> Result<(), ExportError> {
        match self.state {
            State::Open => {
                if let Some(t) = self.terrain.take() {
                    self.add_terrain(&t)?;
                }
                self.add_pictures()?;
                self.state = State::Finished;
                self.write_glb()
            }
            State::New => Err(ExportError::Invalid(
                "glTF writer: finish called before begin".into(),
            )),
            State::Failed => Err(ExportError::Invalid(
                "glTF writer: an earlier write failed".into(),
            )),
            State::Finished => Err(ExportError::Invalid(
                "glTF writer: finish called twice".into(),
            )),
        }
    }
}

/// A building's triangles as its GLB draws them (the same faces, triangulation and faces left
/// out between parts), for a writer that draws buildings itself (`export::preview`). `each` is
/// called once per primitive with the colour as drawn (sRGB; glazed panes darkened as their
/// material is, [`GLASS_SHADE`]), the positions in the model frame (x east, y north, z up,
/// metres, as `f32`) and the triangles' indices into them. Only what is seen from outside is
/// given: walls and roofs, and with `detail` (LOD3 and up) windows, doors and balconies; not
/// the ground (it faces down) nor the LOD4 interior.
pub(crate) fn outside_triangles<F>(
    b: &Building,
    detail: bool,
    mut each: F,
) -> Result<(), ExportError>
where
    F: FnMut(Color, &[[f32; 3]], &[u32]),
{
    let mut e = Encoded::default();
    encode(b, detail, Texturing::Off, false, &mut e)?;
    let f32_at = |bytes: &[u8], at: usize| {
        bytes
            .get(at..at + 4)
            .and_then(|s| s.try_into().ok())
            .map_or(0.0, f32::from_le_bytes)
    };
    let (mut positions, mut indices) = (Vec::new(), Vec::new());
    for p in e.layouts.iter().flatten() {
        if !matches!(
            p.class,
            SurfaceClass::Walls
                | SurfaceClass::Roof
                | SurfaceClass::Windows
                | SurfaceClass::Doors
                | SurfaceClass::Balconies
        ) {
            continue;
        }
        positions.clear();
        indices.clear();
        let at = p.pos_offset as usize;
        // glTF's frame (x, z, -y) back to the model's.
        positions.extend((0..p.count as usize).map(|i| {
            let g = |k: usize| f32_at(&e.vertex_bytes, at + 12 * i + 4 * k);
            [g(0), -g(2), g(1)]
        }));
        let at = p.idx_offset as usize;
        indices.extend((0..p.idx_count as usize).map(|i| {
            match p.idx_type {
                UNSIGNED_SHORT => e
                    .index_bytes
                    .get(at + 2 * i..at + 2 * i + 2)
                    .map_or(0, |s| u32::from(u16::from_le_bytes([s[0], s[1]]))),
                _ => e
                    .index_bytes
                    .get(at + 4 * i..at + 4 * i + 4)
                    .and_then(|s| s.try_into().ok())
                    .map_or(0, u32::from_le_bytes),
            }
        }));
        let mut color = materials::sanitize(p.color);
        if p.material == Material::Glass && color.a >= 1.0 {
            color.r *= GLASS_SHADE;
            color.g *= GLASS_SHADE;
            color.b *= GLASS_SHADE;
        }
        each(color, &positions, &indices);
    }
    Ok(())
}

/// `EPSG:n` for the asset's extras.
fn crs_label(crs: &Crs) -> String {
    format!("EPSG:{}", crs.epsg())
}

#[cfg(test)]
mod tests;
