//! glTF 2.0 binary (`.glb`) writer.
//!
//! Layout of the output: one scene; one node per building, named by the building key
//! (`way_123`) with the source id, zone, appearance and heights in its `extras`; under it one
//! child node per surface class (`walls`, `roof`, `ground`, in LOD3 runs `windows`, `doors`,
//! `balconies`, and for parts with an interior (LOD4) `floors`, `interior walls`, `interior
//! doors`, `stairs`, `slabs`) holding one mesh, with one triangle primitive per material (usually one). Classes
//! without triangles get no node.
//!
//! LOD3 (runs at [`Lod::Lod3`] or above): walls are triangulated with their holes. Each window
//! and door is a pane in its opening's rectangle set back [`OPENING_SETBACK`] into the wall
//! (towards the inside, never deeper than the wall is thick) so it reads as recessed, plus four
//! reveal quads lining the hole up to the pane, in the frame colour when the opening is framed,
//! else the wall colour. Glazed windows' glass is transparent (alpha [`GLASS_ALPHA`], `BLEND`);
//! doors and unglazed windows are opaque in their colour. Balconies are a closed slab box and
//! three railing panels, in a double-sided material.
//!
//! LOD4 ([`crate::export::lod4geom`]): `floors` are the rooms' polygons at floor height, facing
//! up; `interior walls` are closed boxes of the walls' thickness around their centre lines,
//! floor to ceiling, with the door holes and their reveals; `interior doors` are each a leaf in
//! the wall's middle plane, one face per side; `stairs` are the steps' closed blocks; `slabs`
//! are the floor slabs above the ground storey without their top face (the floors cover it),
//! so their undersides are the ceilings below. Materials are PBR metallic-roughness, one per distinct
//! (class, colour), numbered in first-seen order. Coordinates are metres, Y up, relative to the
//! run's local origin, which `asset.extras` records with the CRS (`{"crs": "EPSG:2154",
//! "origin": [E, N, H]}`). Faces are flat shaded: every face has its own vertices and normal.
//!
//! Streaming: a GLB starts with its JSON chunk, which must know the binary chunk's length, so the
//! vertex and index bytes are spooled to a scratch file as buildings arrive and copied after the
//! JSON in [`BuildingWriter::finish`]. The JSON records of the arrays that grow with the number of
//! buildings (nodes, meshes, accessors, buffer views) are serialised as each building arrives and
//! spooled too: to scratch files beside the output with [`GltfWriter::beside`] (memory stays
//! flat however many buildings), in memory with [`GltfWriter::new`]. What stays in memory is
//! the materials and 4 bytes per building (the scene's root list). Output is a pure function of
//! the context and the buildings.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{self, BufWriter, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use glam::DVec3;
use rayon::prelude::*;
use serde::Serialize;

use crate::color::Color;
use crate::crs::Crs;
use crate::export::lod3geom::{balcony_faces, opening_face, opening_reveals};
use crate::export::lod4geom;
use crate::export::{BuildingWriter, ExportError, OutputContext};
use crate::geometry::triangulate::triangulate_face;
use crate::model::{Building, Face, Lod, OpeningKind, Part};

/// GLB magic `glTF`, little-endian.
const GLB_MAGIC: u32 = 0x4654_6C67;
/// Chunk type `JSON`.
const CHUNK_JSON: u32 = 0x4E4F_534A;
/// Chunk type `BIN\0`.
const CHUNK_BIN: u32 = 0x004E_4942;
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
/// Roughness of every material: building materials are matte.
const ROUGHNESS: f32 = 0.9;
/// Colour of ground surfaces (the model gives them none; they face down and are rarely seen).
const GROUND_COLOR: Color = Color::GREY;
/// How far window and door panes sit behind the wall's outer face (metres).
pub const OPENING_SETBACK: f64 = 0.1;
/// Opacity of glazed windows' glass.
pub const GLASS_ALPHA: f32 = 0.35;

/// Semantic class of a group of surfaces: one child node per class and building.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum SurfaceClass {
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

    fn name(self) -> &'static str {
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
    /// Bytes written to the scratch file so far (always a multiple of 4).
    bin_len: u64,
    /// The largest binary chunk accepted ([`GLB_MAX_BYTES`]; smaller in tests).
    max_bin: u64,
    state: State,
    doc: Document,
    /// Serialised records of `nodes`, `meshes`, `accessors` and `bufferViews`, in that order.
    spools: [Spool; 4],
    /// Reused buffer one record is serialised into.
    json_scratch: Vec<u8>,
    /// (class, colour bits) -> material index, for reuse across buildings.
    material_index: BTreeMap<(SurfaceClass, [u32; 4]), u32>,
    /// Whether the run is LOD3 or above (openings and balconies are written).
    detail: bool,
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

/// Index of each growing array in [`GltfWriter::spools`].
const NODES: usize = 0;
const MESHES: usize = 1;
const ACCESSORS: usize = 2;
const VIEWS: usize = 3;

/// The serialised records of one JSON array, comma-separated, without the brackets.
enum Spool {
    Mem {
        buf: Vec<u8>,
        count: u32,
    },
    File {
        w: BufWriter<File>,
        len: u64,
        count: u32,
    },
}

impl Default for Spool {
    fn default() -> Spool {
        Spool::Mem {
            buf: Vec::new(),
            count: 0,
        }
    }
}

impl Spool {
    /// Records so far (the index the next one gets).
    fn count(&self) -> u32 {
        match self {
            Spool::Mem { count, .. } | Spool::File { count, .. } => *count,
        }
    }

    /// Bytes so far.
    fn len(&self) -> u64 {
        match self {
            Spool::Mem { buf, .. } => buf.len() as u64,
            Spool::File { len, .. } => *len,
        }
    }

    /// Appends one record; returns its index.
    fn push(&mut self, rec: &impl Serialize, scratch: &mut Vec<u8>) -> io::Result<u32> {
        scratch.clear();
        if self.count() > 0 {
            scratch.push(b',');
        }
        serde_json::to_writer(&mut *scratch, rec).map_err(io::Error::from)?;
        match self {
            Spool::Mem { buf, count } => {
                buf.extend_from_slice(scratch);
                *count += 1;
                Ok(*count - 1)
            }
            Spool::File { w, len, count } => {
                w.write_all(scratch)?;
                *len += scratch.len() as u64;
                *count += 1;
                Ok(*count - 1)
            }
        }
    }

    /// Copies the records to `out`.
    fn copy_to(&mut self, out: &mut impl Write) -> io::Result<()> {
        match self {
            Spool::Mem { buf, .. } => out.write_all(buf),
            Spool::File { w, len, .. } => {
                w.flush()?;
                let f = w.get_mut();
                f.seek(SeekFrom::Start(0))?;
                let copied = io::copy(&mut (&mut *f).take(*len), out)?;
                if copied != *len {
                    return Err(io::Error::other(format!(
                        "glTF JSON scratch file is {copied} bytes, expected {len}: was it modified?"
                    )));
                }
                Ok(())
            }
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
            bin_len: 0,
            max_bin: GLB_MAX_BYTES,
            state: State::New,
            doc: Document::default(),
            spools: Default::default(),
            json_scratch: Vec::new(),
            material_index: BTreeMap::new(),
            detail: false,
            scratch_guard: ScratchGuard(Vec::new()),
        }
    }

    /// A writer whose scratch file is created next to `target` (the final output path, whose
    /// folder must exist), so that it lands on the same disk as the output rather than on a
    /// possibly small temporary file system. The scratch file is deleted when the writer is
    /// dropped (on Unix it is unlinked at once and only the open handle keeps it).
    pub fn beside(out: W, target: &Path) -> io::Result<GltfWriter<W>> {
        let dir = target
            .parent()
            .filter(|d| !d.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        let name = target
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let path = dir.join(format!(".{name}.{}.bin.tmp", std::process::id()));
        let file = File::options()
            .read(true)
            .write(true)
            .create(true)
            .truncate(true)
            .open(&path)?;
        let mut w = GltfWriter::new(out, file);
        // Unlinking an open file works on Unix; elsewhere it is removed on drop.
        if std::fs::remove_file(&path).is_err() {
            w.scratch_guard.0.push(path);
        }
        for (i, array) in ["nodes", "meshes", "accessors", "views"].iter().enumerate() {
            let path = dir.join(format!(".{name}.{}.{array}.tmp", std::process::id()));
            let file = File::options()
                .read(true)
                .write(true)
                .create(true)
                .truncate(true)
                .open(&path)?;
            if std::fs::remove_file(&path).is_err() {
                w.scratch_guard.0.push(path);
            }
            w.spools[i] = Spool::File {
                w: BufWriter::with_capacity(1 << 18, file),
                len: 0,
                count: 0,
            };
        }
        Ok(w)
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
        let scratch = self
            .scratch
            .as_mut()
            .ok_or_else(|| ExportError::Invalid("glTF writer: scratch file missing".into()))?;
        scratch.get_mut().set_len(0)?;
        scratch.seek(SeekFrom::Start(0))?;
        self.doc.asset_extras = AssetExtras {
            crs: crs_label,
            origin: [ctx.origin.x, ctx.origin.y, ctx.origin.z],
            lod: ctx.lod.number(),
            source: ctx.source_name.clone(),
        };
        self.detail = ctx.lod >= Lod::Lod3;
        self.state = State::Open;
        Ok(())
    }

    /// Appends one building: triangulates its faces, writes its binary data to the scratch file
    /// and records its nodes, meshes, accessors and buffer views.
    fn add_building(&mut self, b: &Building) -> Result<(), ExportError> {
        let e = encode(b, self.detail)?;
        self.add_encoded(b, e)
    }

    /// Spools an encoded building's bytes and serialises its records.
    fn add_encoded(&mut self, b: &Building, e: Encoded) -> Result<(), ExportError> {
        let Encoded {
            layouts,
            vertex_bytes,
            index_bytes,
        } = e;
        // Spool the bytes first: records are added only once their data is in the scratch file.
        let vertex_view_offset = self.bin_len;
        let index_view_offset = self.bin_len + vertex_bytes.len() as u64;
        if !layouts.is_empty() {
            let scratch = self
                .scratch
                .as_mut()
                .ok_or_else(|| ExportError::Invalid("glTF writer: scratch file missing".into()))?;
            let written = scratch
                .write_all(&vertex_bytes)
                .and_then(|()| scratch.write_all(&index_bytes));
            if let Err(e) = written {
                self.state = State::Failed;
                return Err(e.into());
            }
            self.bin_len = index_view_offset + index_bytes.len() as u64;
            // Fail as soon as the file cannot be a GLB any more, not hours later at the end.
            if self.bin_len > self.max_bin {
                self.state = State::Failed;
                return Err(ExportError::Invalid(format!(
                    "the glTF binary is over the GLB limit of 4 GiB ({} bytes of vertex data at \
                     building {}); write fewer buildings per file (--tile METRES or --bbox)",
                    self.bin_len, b.id
                )));
            }
        }

        let written = self.records(
            b,
            &layouts,
            vertex_view_offset,
            vertex_bytes.len() as u64,
            index_bytes.len() as u64,
        );
        written.map_err(|e| {
            self.state = State::Failed;
            e.into()
        })
    }

    /// Serialises the JSON records of one building (its data already spooled at
    /// `vertex_view_offset`..): the building node, then per class its accessors, mesh and child
    /// node; the building's children are the nodes that follow it.
    fn records(
        &mut self,
        b: &Building,
        layouts: &[Vec<PrimLayout>],
        vertex_view_offset: u64,
        vertex_len: u64,
        index_len: u64,
    ) -> io::Result<()> {
        let mut tmp = std::mem::take(&mut self.json_scratch);
        let index_view_offset = vertex_view_offset + vertex_len;
        let key = b.key();
        let classes = layouts.iter().filter(|p| !p.is_empty()).count() as u32;
        let building_node = self.spools[NODES].count();
        self.doc.roots.push(building_node);
        self.spools[NODES].push(
            &NodeRec {
                name: &key,
                children: (building_node + 1..=building_node + classes).collect(),
                mesh: None,
                extras: Some(BuildingExtras {
                    id: b.id.to_string(),
                    name: b.name.as_deref(),
                    zone: &b.zone,
                    appearance: &b.appearance,
                    height: b.measured_height,
                    base: b.base_z,
                    storeys: b.storeys_above_ground,
                    roof_shape: b.roof_shape.osm_name(),
                    lod: b.lod.number(),
                }),
            },
            &mut tmp,
        )?;
        if classes == 0 {
            self.json_scratch = tmp;
            return Ok(());
        }
        let vertex_view = self.spools[VIEWS].push(
            &ViewRec {
                buffer: 0,
                byte_offset: vertex_view_offset,
                byte_length: vertex_len,
                byte_stride: Some(VEC3_STRIDE),
                target: ARRAY_BUFFER,
            },
            &mut tmp,
        )?;
        let index_view = self.spools[VIEWS].push(
            &ViewRec {
                buffer: 0,
                byte_offset: index_view_offset,
                byte_length: index_len,
                byte_stride: None,
                target: ELEMENT_ARRAY_BUFFER,
            },
            &mut tmp,
        )?;

        for prims in layouts {
            let Some(class) = prims.first().map(|p| p.class) else {
                continue;
            };
            let mut primitives = Vec::with_capacity(prims.len());
            for p in prims {
                let material = self.material_for(p.class, p.color);
                let acc = &mut self.spools[ACCESSORS];
                let position = acc.push(
                    &AccessorRec {
                        buffer_view: vertex_view,
                        byte_offset: p.pos_offset,
                        component_type: FLOAT,
                        count: p.count,
                        kind: "VEC3",
                        min: Some(p.min),
                        max: Some(p.max),
                    },
                    &mut tmp,
                )?;
                let normal = acc.push(
                    &AccessorRec {
                        buffer_view: vertex_view,
                        byte_offset: p.nrm_offset,
                        component_type: FLOAT,
                        count: p.count,
                        kind: "VEC3",
                        min: None,
                        max: None,
                    },
                    &mut tmp,
                )?;
                let indices = acc.push(
                    &AccessorRec {
                        buffer_view: index_view,
                        byte_offset: p.idx_offset,
                        component_type: p.idx_type,
                        count: p.idx_count,
                        kind: "SCALAR",
                        min: None,
                        max: None,
                    },
                    &mut tmp,
                )?;
                primitives.push(PrimitiveRec {
                    attributes: Attributes { position, normal },
                    indices,
                    material,
                });
            }
            let mesh = self.spools[MESHES].push(
                &MeshRec {
                    name: format!("{key} {}", class.name()),
                    primitives,
                },
                &mut tmp,
            )?;
            self.spools[NODES].push(
                &NodeRec {
                    name: class.name(),
                    children: Vec::new(),
                    mesh: Some(mesh),
                    extras: None,
                },
                &mut tmp,
            )?;
        }
        self.json_scratch = tmp;
        Ok(())
    }

    /// The material of `class` in `color`, created on first use.
    fn material_for(&mut self, class: SurfaceClass, color: Color) -> u32 {
        let key = (class, color_key(color));
        if let Some(&i) = self.material_index.get(&key) {
            return i;
        }
        let i = self.doc.materials.len() as u32;
        let c = sanitize(color);
        let name = if c.a < 1.0 {
            format!("{} {} alpha {}", class.name(), c.to_hex(), c.a)
        } else {
            format!("{} {}", class.name(), c.to_hex())
        };
        self.doc.materials.push(MaterialRec {
            name,
            pbr: Pbr {
                base_color_factor: [
                    srgb_to_linear(c.r),
                    srgb_to_linear(c.g),
                    srgb_to_linear(c.b),
                    c.a,
                ],
                metallic_factor: 0.0,
                roughness_factor: ROUGHNESS,
            },
            alpha_mode: (c.a < 1.0).then_some("BLEND"),
            // Railing panels are single quads, seen from both sides.
            double_sided: (class == SurfaceClass::Balconies).then_some(true),
        });
        self.material_index.insert(key, i);
        i
    }

    /// Writes the GLB: header, JSON chunk, BIN chunk copied from the scratch file.
    fn write_glb(&mut self) -> Result<(), ExportError> {
        let scratch = self
            .scratch
            .take()
            .ok_or_else(|| ExportError::Invalid("glTF writer: scratch file missing".into()))?;
        let mut scratch = scratch.into_inner().map_err(|e| e.into_error())?;
        let bin_len = self.bin_len;
        self.doc.buffer_length = bin_len;

        let pieces = self.doc.pieces(&self.spools)?;
        let json_len: u64 = pieces
            .iter()
            .map(|p| match p {
                Piece::Text(t) => t.len() as u64,
                Piece::Spool(i) => self.spools[*i].len(),
            })
            .sum();
        let json_padded = pad4(json_len);
        let bin_padded = pad4(bin_len);
        let total = 12 + 8 + json_padded + if bin_len > 0 { 8 + bin_padded } else { 0 };
        let too_big = || {
            ExportError::Invalid(format!(
                "the glTF binary would be {total} bytes, over the GLB limit of 4 GiB; write fewer buildings per file (--tile METRES or --bbox)"
            ))
        };
        let total32 = u32::try_from(total).map_err(|_| too_big())?;

        let mut w = BufWriter::with_capacity(1 << 20, &mut self.out);
        w.write_all(&GLB_MAGIC.to_le_bytes())?;
        w.write_all(&2u32.to_le_bytes())?;
        w.write_all(&total32.to_le_bytes())?;
        w.write_all(&(json_padded as u32).to_le_bytes())?;
        w.write_all(&CHUNK_JSON.to_le_bytes())?;
        for p in &pieces {
            match p {
                Piece::Text(t) => w.write_all(t)?,
                Piece::Spool(i) => self.spools[*i].copy_to(&mut w)?,
            }
        }
        for _ in json_len..json_padded {
            w.write_all(b" ")?;
        }
        if bin_len > 0 {
            w.write_all(&(bin_padded as u32).to_le_bytes())?;
            w.write_all(&CHUNK_BIN.to_le_bytes())?;
            scratch.seek(SeekFrom::Start(0))?;
            let copied = io::copy(&mut (&mut scratch).take(bin_len), &mut w)?;
            if copied != bin_len {
                return Err(ExportError::Invalid(format!(
                    "glTF scratch file is {copied} bytes, expected {bin_len}: was it modified?"
                )));
            }
            for _ in bin_len..bin_padded {
                w.write_all(&[0])?;
            }
        }
        w.flush()?;
        drop(w);
        self.out.flush()?;
        Ok(())
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

    /// Encodes (triangulates) the buildings in parallel, [`super::PARALLEL_BATCH`] at a time, and
    /// appends them in order: the same bytes as `write` on each.
    fn write_all(&mut self, buildings: &[Building]) -> Result<(), ExportError> {
        if self.state != State::Open {
            return buildings.iter().try_for_each(|b| self.write(b));
        }
        let detail = self.detail;
        for batch in buildings.chunks(super::PARALLEL_BATCH) {
            let encoded: Vec<_> = batch.par_iter().map(|b| encode(b, detail)).collect();
            for (b, e) in batch.iter().zip(encoded) {
                self.add_encoded(b, e?)?;
            }
        }
        Ok(())
    }

    fn finish(&mut self) -> Result<(), ExportError> {
        match self.state {
            State::Open => {
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

/// `EPSG:n` for the asset's extras.
fn crs_label(crs: &Crs) -> String {
    format!("EPSG:{}", crs.epsg())
}

fn pad4(n: u64) -> u64 {
    n.div_ceil(4) * 4
}

/// Colour components clamped to 0..=1, NaN as 0 (alpha NaN as opaque).
fn sanitize(c: Color) -> Color {
    let f = |v: f32, nan: f32| if v.is_nan() { nan } else { v.clamp(0.0, 1.0) };
    Color {
        r: f(c.r, 0.0),
        g: f(c.g, 0.0),
        b: f(c.b, 0.0),
        a: f(c.a, 1.0),
    }
}

/// Bit pattern of the sanitised colour: a total, hashable key.
fn color_key(c: Color) -> [u32; 4] {
    let c = sanitize(c);
    [c.r.to_bits(), c.g.to_bits(), c.b.to_bits(), c.a.to_bits()]
}

/// sRGB transfer function inverse (IEC 61966-2-1): glTF colour factors are linear.
fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Model frame (x east, y north, z up) to glTF (y up, z towards the viewer = south). A proper
/// rotation, so windings are kept. Adding 0.0 turns -0.0 into 0.0 for tidier min/max.
fn to_gltf(p: DVec3) -> [f32; 3] {
    [p.x as f32 + 0.0, p.z as f32 + 0.0, (-p.y) as f32 + 0.0]
}

/// Faces of one surface class and one colour in one building.
struct Group {
    color: Color,
    color_key: [u32; 4],
    mesh: MeshData,
}

impl Group {
    fn add_face(&mut self, face: &Face) {
        self.mesh.add_face(face);
    }
}

/// The group of `color` in `groups`, created (last) on first use.
fn group(groups: &mut Vec<Group>, color: Color) -> &mut Group {
    let key = color_key(color);
    let i = match groups.iter().position(|g| g.color_key == key) {
        Some(i) => i,
        None => {
            groups.push(Group {
                color,
                color_key: key,
                mesh: MeshData::default(),
            });
            groups.len() - 1
        }
    };
    &mut groups[i]
}

/// Adds the panes and reveals of `part`'s openings of `kind` (see the module documentation).
fn add_openings(groups: &mut Vec<Group>, part: &Part, kind: OpeningKind) {
    for w in &part.walls {
        // Never behind the wall's inner face; no setback (and no reveals) for a wall without
        // thickness.
        let depth = if w.thickness.is_finite() && w.thickness > 0.0 {
            OPENING_SETBACK.min(w.thickness)
        } else {
            0.0
        };
        for o in w.openings.iter().filter(|o| o.kind == kind) {
            let Some(pane) = opening_face(w, o, depth) else {
                continue;
            };
            let color = if kind == OpeningKind::Window && o.glazed {
                Color {
                    a: GLASS_ALPHA,
                    ..o.color
                }
            } else {
                Color { a: 1.0, ..o.color }
            };
            group(groups, color).add_face(&pane);
            let lining = if o.framed {
                o.frame_color
            } else {
                part.wall_color
            };
            let g = group(groups, Color { a: 1.0, ..lining });
            opening_reveals(w, o, depth)
                .iter()
                .for_each(|f| g.add_face(f));
        }
    }
}

/// Adds the faces of `part`'s interiors of one LOD4 class (see the module documentation).
fn add_interior(groups: &mut Vec<Group>, part: &Part, class: SurfaceClass) {
    for (k, s) in part.interior.iter().enumerate() {
        match class {
            SurfaceClass::Floors => {
                let g = group(groups, lod4geom::FLOOR_COLOR);
                for r in &s.rooms {
                    if let Some(ring) = lod4geom::room_ring(r) {
                        g.add_face(&Face::new(
                            ring.iter().map(|p| p.extend(s.floor_z)).collect(),
                        ));
                    }
                }
            }
            SurfaceClass::InteriorWalls => {
                let g = group(groups, lod4geom::INTERIOR_WALL_COLOR);
                for w in 0..s.walls.len() {
                    lod4geom::wall_body(s, w)
                        .iter()
                        .flatten()
                        .for_each(|f| g.add_face(f));
                }
            }
            SurfaceClass::InteriorDoors => {
                let g = group(groups, lod4geom::DOOR_COLOR);
                for d in &s.doors {
                    lod4geom::door_leaf(s, d)
                        .iter()
                        .flatten()
                        .for_each(|f| g.add_face(f));
                }
            }
            SurfaceClass::Stairs => {
                let g = group(groups, lod4geom::STAIR_COLOR);
                if let Some(st) = &s.stair {
                    for step in lod4geom::stair_steps(s, st) {
                        lod4geom::prism_faces(&step.ring, step.z0, step.z1)
                            .iter()
                            .for_each(|f| g.add_face(f));
                    }
                }
            }
            SurfaceClass::Slabs => {
                let below = k
                    .checked_sub(1)
                    .and_then(|b| part.interior.get(b))
                    .filter(|b| b.storey + 1 == s.storey);
                let (pieces, thickness) = lod4geom::floor_slab(below, s);
                let g = group(groups, lod4geom::SLAB_COLOR);
                for p in &pieces {
                    // The top face is the rooms' floors: leave it out so they do not fight.
                    lod4geom::slab_faces(p, s.floor_z, thickness)
                        .iter()
                        .skip(1)
                        .for_each(|f| g.add_face(f));
                }
            }
            _ => {}
        }
    }
}

/// One building's binary data (vertex and index bytes) and primitive layout: all the work of a
/// write that needs no writer state, so a chunk of buildings can be encoded in parallel.
struct Encoded {
    layouts: Vec<Vec<PrimLayout>>,
    vertex_bytes: Vec<u8>,
    index_bytes: Vec<u8>,
}

/// Triangulates and lays out one building (`detail`: LOD3 and up classes are written).
fn encode(b: &Building, detail: bool) -> Result<Encoded, ExportError> {
    let mut classes: Vec<(SurfaceClass, Vec<Group>)> = Vec::new();
    for class in SurfaceClass::ALL {
        if class.is_detail() && !detail {
            continue;
        }
        let mut groups: Vec<Group> = Vec::new();
        for part in &b.parts {
            match class {
                SurfaceClass::Walls => {
                    let g = group(&mut groups, part.wall_color);
                    part.walls.iter().for_each(|w| g.add_face(&w.outline));
                }
                SurfaceClass::Roof => {
                    let g = group(&mut groups, part.roof_color);
                    part.roof.iter().for_each(|f| g.add_face(f));
                }
                SurfaceClass::Ground => group(&mut groups, GROUND_COLOR).add_face(&part.ground),
                SurfaceClass::Windows => add_openings(&mut groups, part, OpeningKind::Window),
                SurfaceClass::Doors => add_openings(&mut groups, part, OpeningKind::Door),
                SurfaceClass::Balconies => {
                    for w in &part.walls {
                        for bc in &w.balconies {
                            if let Some(f) = balcony_faces(w, bc) {
                                let g = group(&mut groups, bc.color);
                                f.all().for_each(|face| g.add_face(face));
                            }
                        }
                    }
                }
                SurfaceClass::Floors
                | SurfaceClass::InteriorWalls
                | SurfaceClass::InteriorDoors
                | SurfaceClass::Stairs
                | SurfaceClass::Slabs => add_interior(&mut groups, part, class),
            }
        }
        groups.retain(|g| !g.mesh.indices.is_empty());
        if !groups.is_empty() {
            classes.push((class, groups));
        }
    }

    // Binary layout of one building: one vertex view (per primitive: positions, then
    // normals) and one index view (per primitive: indices padded to 4 bytes).
    let mut vertex_bytes: Vec<u8> = Vec::new();
    let mut index_bytes: Vec<u8> = Vec::new();
    let mut layouts: Vec<Vec<PrimLayout>> = Vec::new();
    for (class, groups) in &classes {
        let mut prims = Vec::new();
        for g in groups {
            let m = &g.mesh;
            let too_big = || {
                ExportError::Invalid(format!(
                    "building {}: the {} mesh is too large for glTF ({} vertices)",
                    b.id,
                    class.name(),
                    m.positions.len()
                ))
            };
            let count = u32::try_from(m.positions.len()).map_err(|_| too_big())?;
            let idx_count = u32::try_from(m.indices.len()).map_err(|_| too_big())?;
            let pos_offset = vertex_bytes.len() as u64;
            for p in &m.positions {
                p.iter()
                    .for_each(|c| vertex_bytes.extend_from_slice(&c.to_le_bytes()));
            }
            let nrm_offset = vertex_bytes.len() as u64;
            for n in &m.normals {
                n.iter()
                    .for_each(|c| vertex_bytes.extend_from_slice(&c.to_le_bytes()));
            }
            let idx_offset = index_bytes.len() as u64;
            // 65535 is the primitive-restart value of u16 indices: never use it as an index.
            let idx_type = if count <= 65535 {
                m.indices
                    .iter()
                    .for_each(|&i| index_bytes.extend_from_slice(&(i as u16).to_le_bytes()));
                UNSIGNED_SHORT
            } else {
                m.indices
                    .iter()
                    .for_each(|&i| index_bytes.extend_from_slice(&i.to_le_bytes()));
                UNSIGNED_INT
            };
            while index_bytes.len() % 4 != 0 {
                index_bytes.push(0);
            }
            let (min, max) = m.bounds();
            prims.push(PrimLayout {
                class: *class,
                color: g.color,
                count,
                pos_offset,
                nrm_offset,
                idx_offset,
                idx_count,
                idx_type,
                min,
                max,
            });
        }
        layouts.push(prims);
    }

    Ok(Encoded {
        layouts,
        vertex_bytes,
        index_bytes,
    })
}

/// Flat-shaded triangle data of one primitive.
#[derive(Default)]
struct MeshData {
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    indices: Vec<u32>,
}

impl MeshData {
    /// Appends a face with its own vertices and normal; degenerate faces add nothing.
    fn add_face(&mut self, face: &Face) {
        let Some(t) = triangulate_face(&face.outer, &face.holes) else {
            return;
        };
        let positions: Vec<[f32; 3]> = t.vertices.iter().map(|p| to_gltf(*p)).collect();
        // Coordinates beyond f32 range (never in a local frame, but input is input).
        if positions.iter().flatten().any(|c| !c.is_finite()) {
            return;
        }
        let Ok(base) = u32::try_from(self.positions.len()) else {
            return;
        };
        if u32::try_from(self.positions.len() + positions.len()).is_err() {
            return;
        }
        let n = to_gltf(t.normal);
        self.normals.extend(std::iter::repeat_n(n, positions.len()));
        self.positions.extend(positions);
        self.indices
            .extend(t.triangles.iter().flatten().map(|i| base + i));
    }

    /// Component-wise min and max of the positions (as glTF requires for POSITION).
    fn bounds(&self) -> ([f32; 3], [f32; 3]) {
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for p in &self.positions {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        (lo, hi)
    }
}

/// Where one primitive's data lies in its building's vertex and index views.
struct PrimLayout {
    class: SurfaceClass,
    color: Color,
    count: u32,
    pos_offset: u64,
    nrm_offset: u64,
    idx_offset: u64,
    idx_count: u32,
    idx_type: u32,
    min: [f32; 3],
    max: [f32; 3],
}

// ---- JSON records, serialised with a fixed key order (struct field order) ----

#[derive(Default)]
struct Document {
    asset_extras: AssetExtras,
    /// The scene's root nodes: one per building.
    roots: Vec<u32>,
    materials: Vec<MaterialRec>,
    buffer_length: u64,
}

/// A piece of the JSON chunk: text, or the records of a spooled array.
enum Piece {
    Text(Vec<u8>),
    Spool(usize),
}

impl Document {
    /// The JSON chunk in document order (the key order of the glTF JSON is fixed: asset, scene,
    /// scenes, nodes, meshes, materials, accessors, bufferViews, buffers; empty arrays are left
    /// out), with the growing arrays as references to `spools`.
    fn pieces(&self, spools: &[Spool; 4]) -> io::Result<Vec<Piece>> {
        let head = Head {
            asset: Asset {
                version: "2.0",
                generator: concat!("citygen ", env!("CARGO_PKG_VERSION")),
                extras: &self.asset_extras,
            },
            scene: 0,
            scenes: [Scene { nodes: &self.roots }],
        };
        let mut text = serde_json::to_vec(&head).map_err(io::Error::from)?;
        text.pop(); // the closing brace, written last
        let mut pieces = Vec::new();
        let array = |pieces: &mut Vec<Piece>, text: &mut Vec<u8>, key: &str, body: Piece| {
            text.extend_from_slice(b",\"");
            text.extend_from_slice(key.as_bytes());
            text.extend_from_slice(b"\":[");
            match body {
                Piece::Text(t) => text.extend_from_slice(&t),
                Piece::Spool(i) => {
                    pieces.push(Piece::Text(std::mem::take(text)));
                    pieces.push(Piece::Spool(i));
                }
            }
            text.push(b']');
        };
        for (key, i) in [("nodes", NODES), ("meshes", MESHES)] {
            if spools[i].count() > 0 {
                array(&mut pieces, &mut text, key, Piece::Spool(i));
            }
        }
        if !self.materials.is_empty() {
            let mut m = serde_json::to_vec(&self.materials).map_err(io::Error::from)?;
            m.pop();
            m.remove(0);
            array(&mut pieces, &mut text, "materials", Piece::Text(m));
        }
        for (key, i) in [("accessors", ACCESSORS), ("bufferViews", VIEWS)] {
            if spools[i].count() > 0 {
                array(&mut pieces, &mut text, key, Piece::Spool(i));
            }
        }
        if self.buffer_length > 0 {
            let b = serde_json::to_vec(&Buffer {
                byte_length: self.buffer_length,
            })
            .map_err(io::Error::from)?;
            array(&mut pieces, &mut text, "buffers", Piece::Text(b));
        }
        text.push(b'}');
        pieces.push(Piece::Text(text));
        Ok(pieces)
    }
}

fn is_empty<T>(s: &[T]) -> bool {
    s.is_empty()
}

/// The JSON chunk's first keys.
#[derive(Serialize)]
struct Head<'a> {
    asset: Asset<'a>,
    scene: u32,
    scenes: [Scene<'a>; 1],
}

#[derive(Serialize)]
struct Asset<'a> {
    version: &'static str,
    generator: &'static str,
    extras: &'a AssetExtras,
}

#[derive(Serialize, Default)]
struct AssetExtras {
    crs: String,
    origin: [f64; 3],
    lod: u8,
    source: String,
}

#[derive(Serialize)]
struct Scene<'a> {
    #[serde(skip_serializing_if = "is_empty")]
    nodes: &'a [u32],
}

#[derive(Serialize)]
struct NodeRec<'a> {
    name: &'a str,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    children: Vec<u32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    mesh: Option<u32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    extras: Option<BuildingExtras<'a>>,
}

#[derive(Serialize)]
struct BuildingExtras<'a> {
    id: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    name: Option<&'a str>,
    zone: &'a str,
    appearance: &'a str,
    /// Measured height in metres (non-finite values serialise as null).
    height: f64,
    base: f64,
    storeys: u32,
    roof_shape: &'static str,
    lod: u8,
}

#[derive(Serialize)]
struct MeshRec {
    name: String,
    primitives: Vec<PrimitiveRec>,
}

#[derive(Serialize)]
struct PrimitiveRec {
    attributes: Attributes,
    indices: u32,
    material: u32,
}

#[derive(Serialize)]
struct Attributes {
    #[serde(rename = "POSITION")]
    position: u32,
    #[serde(rename = "NORMAL")]
    normal: u32,
}

#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
struct MaterialRec {
    name: String,
    #[serde(rename = "pbrMetallicRoughness")]
    pbr: Pbr,
    #[serde(skip_serializing_if = "Option::is_none")]
    alpha_mode: Option<&'static str>,
    #[serde(skip_serializing_if = "Option::is_none")]
    double_sided: Option<bool>,
}

#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
struct Pbr {
    base_color_factor: [f32; 4],
    metallic_factor: f32,
    roughness_factor: f32,
}

#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
struct AccessorRec {
    buffer_view: u32,
    #[serde(skip_serializing_if = "is_zero")]
    byte_offset: u64,
    component_type: u32,
    count: u32,
    #[serde(rename = "type")]
    kind: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    min: Option<[f32; 3]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    max: Option<[f32; 3]>,
}

fn is_zero(v: &u64) -> bool {
    *v == 0
}

#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
struct ViewRec {
    buffer: u32,
    #[serde(skip_serializing_if = "is_zero")]
    byte_offset: u64,
    byte_length: u64,
    #[serde(skip_serializing_if = "Option::is_none")]
    byte_stride: Option<u32>,
    target: u32,
}

#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
struct Buffer {
    byte_length: u64,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::export::lod3geom::samples;
    use crate::geometry::Polygon;
    use crate::model::SourceId;
    use crate::model::{Lod, Part, RoofShape, Wall};
    use glam::DVec2;
    use serde_json::Value;

    // ---- synthetic buildings ----

    /// A wall on footprint edge start->end, its outer face CCW seen from outside.
    fn wall(start: DVec2, end: DVec2, base: f64, top: f64) -> Wall {
        let outline = Face::new(vec![
            start.extend(base),
            end.extend(base),
            end.extend(top),
            start.extend(top),
        ]);
        Wall {
            start,
            end,
            base_z: base,
            top_z: top,
            thickness: 0.3,
            outline,
            storey: 0,
            openings: Vec::new(),
            balconies: Vec::new(),
        }
    }

    /// A part extruded from `footprint` from `base` to `eave`, with the given roof faces (a flat
    /// roof at `eave` when `roof` is empty).
    fn part(
        key: &str,
        footprint: Polygon,
        base: f64,
        eave: f64,
        roof: Vec<Face>,
        wall_color: Color,
    ) -> Part {
        let mut walls = Vec::new();
        for ring in footprint.rings() {
            for i in 0..ring.len() {
                walls.push(wall(ring[i], ring[(i + 1) % ring.len()], base, eave));
            }
        }
        let lift = |r: &Vec<DVec2>, z: f64| r.iter().map(|p| p.extend(z)).collect::<Vec<_>>();
        let (roof, shape, top) = if roof.is_empty() {
            let flat = Face {
                outer: lift(&footprint.outer, eave),
                holes: footprint.holes.iter().map(|h| lift(h, eave)).collect(),
            };
            (vec![flat], RoofShape::Flat, eave)
        } else {
            let top = roof
                .iter()
                .flat_map(|f| f.outer.iter())
                .map(|p| p.z)
                .fold(eave, f64::max);
            (roof, RoofShape::Hipped, top)
        };
        let rev = |r: &Vec<DVec2>| {
            let mut v = lift(r, base);
            v.reverse();
            v
        };
        let ground = Face {
            outer: rev(&footprint.outer),
            holes: footprint.holes.iter().map(rev).collect(),
        };
        Part {
            key: key.into(),
            footprint,
            base_z: base,
            eave_z: eave,
            top_z: top,
            storeys: 2,
            levels: vec![base, (base + eave) / 2.0],
            wall_color,
            roof_color: Color::rgb(0.7, 0.2, 0.1),
            roof_shape: shape,
            walls,
            roof,
            ground,
            interior: Vec::new(),
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

    fn building(id: i64, parts: Vec<Part>) -> Building {
        let base = parts.iter().map(|p| p.base_z).fold(f64::INFINITY, f64::min);
        let top = parts
            .iter()
            .map(|p| p.top_z)
            .fold(f64::NEG_INFINITY, f64::max);
        Building {
            id: SourceId::Way(id),
            name: Some(format!("Building {id}")),
            zone: "earth/France/Occitanie/Toulouse".into(),
            appearance: "Toulouse#1".into(),
            base_z: base,
            measured_height: top - base,
            storeys_above_ground: 2,
            roof_shape: parts[0].roof_shape,
            parts,
            lod: Lod::Lod2,
        }
    }

    /// 10 x 6 m box, 3 m high, flat roof.
    fn box_building() -> Building {
        building(
            1,
            vec![part(
                "p0",
                Polygon::new(rect(0.0, 0.0, 10.0, 6.0), vec![]),
                0.0,
                3.0,
                vec![],
                Color::WHITE,
            )],
        )
    }

    /// 20 x 20 m block with an 8 x 8 m courtyard, 9 m high.
    fn courtyard_building() -> Building {
        let fp = Polygon::new(
            rect(30.0, 0.0, 50.0, 20.0),
            vec![rect(36.0, 6.0, 44.0, 14.0)],
        );
        building(
            2,
            vec![part("p0", fp, 0.0, 9.0, vec![], Color::rgb(0.9, 0.8, 0.6))],
        )
    }

    /// Hip roof on a 10 x 6 m footprint at (x0, 0): eave 3 m, ridge 5 m from x0+3 to x0+7.
    fn hip_roof(x0: f64) -> Vec<Face> {
        let p = |x: f64, y: f64, z: f64| DVec3::new(x0 + x, y, z);
        vec![
            Face::new(vec![
                p(0.0, 0.0, 3.0),
                p(10.0, 0.0, 3.0),
                p(7.0, 3.0, 5.0),
                p(3.0, 3.0, 5.0),
            ]),
            Face::new(vec![p(10.0, 0.0, 3.0), p(10.0, 6.0, 3.0), p(7.0, 3.0, 5.0)]),
            Face::new(vec![
                p(10.0, 6.0, 3.0),
                p(0.0, 6.0, 3.0),
                p(3.0, 3.0, 5.0),
                p(7.0, 3.0, 5.0),
            ]),
            Face::new(vec![p(0.0, 6.0, 3.0), p(0.0, 0.0, 3.0), p(3.0, 3.0, 5.0)]),
        ]
    }

    /// A flat 6 m part and a hip-roofed part in another wall colour, plus a degenerate roof face.
    fn two_part_building() -> Building {
        let a = part(
            "p0",
            Polygon::new(rect(60.0, 0.0, 70.0, 6.0), vec![]),
            0.0,
            6.0,
            vec![],
            Color::WHITE,
        );
        let mut roof = hip_roof(70.0);
        roof.push(Face::new(vec![
            DVec3::new(70.0, 0.0, 3.0),
            DVec3::new(71.0, 0.0, 3.0),
        ]));
        let b = part(
            "p1",
            Polygon::new(rect(70.0, 0.0, 80.0, 6.0), vec![]),
            0.0,
            3.0,
            roof,
            Color::rgb(1.0, 1.0, 0.5),
        );
        building(3, vec![a, b])
    }

    /// A hip-roofed house whose glazing-like roof colour is translucent.
    fn translucent_building() -> Building {
        let mut p = part(
            "p0",
            Polygon::new(rect(90.0, 0.0, 100.0, 6.0), vec![]),
            2.0,
            5.0,
            vec![],
            Color::WHITE,
        );
        p.roof = hip_roof(90.0)
            .into_iter()
            .map(|f| Face::new(f.outer.iter().map(|q| *q + DVec3::Z * 2.0).collect()))
            .collect();
        p.roof_color = Color {
            r: 0.5,
            g: 0.7,
            b: 0.9,
            a: 0.4,
        };
        building(4, vec![p])
    }

    fn all_buildings() -> Vec<Building> {
        vec![
            box_building(),
            courtyard_building(),
            two_part_building(),
            translucent_building(),
        ]
    }

    fn ctx() -> OutputContext {
        OutputContext {
            crs: Crs::Lambert93,
            origin: DVec3::new(574_000.25, 6_279_000.5, 140.0),
            origin_lonlat: (1.44, 43.6),
            lod: Lod::Lod2,
            source_name: "toulouse.osm.pbf".into(),
            seed: 7,
        }
    }

    /// Writes `buildings` to a GLB in memory (without asking the CRS for its EPSG code, which
    /// another module provides).
    fn write_glb(buildings: &[Building]) -> Vec<u8> {
        write_glb_at(Lod::Lod2, buildings)
    }

    /// [`write_glb`] for a run at `lod`.
    fn write_glb_at(lod: Lod, buildings: &[Building]) -> Vec<u8> {
        let mut out = Vec::new();
        let mut w = GltfWriter::new(&mut out, tempfile::tempfile().unwrap());
        w.start(&OutputContext { lod, ..ctx() }, "EPSG:2154".into())
            .unwrap();
        for b in buildings {
            w.write(b).unwrap();
        }
        w.finish().unwrap();
        out
    }

    // ---- a GLB reader for the checks ----

    fn u32_at(b: &[u8], at: usize) -> u32 {
        u32::from_le_bytes(b[at..at + 4].try_into().unwrap())
    }

    fn f32_at(b: &[u8], at: usize) -> f32 {
        f32::from_le_bytes(b[at..at + 4].try_into().unwrap())
    }

    /// Checks the container and returns (JSON, BIN chunk data).
    fn parse_glb(glb: &[u8]) -> (Value, &[u8]) {
        assert_eq!(&glb[0..4], b"glTF");
        assert_eq!(u32_at(glb, 4), 2);
        assert_eq!(u32_at(glb, 8) as usize, glb.len());
        assert_eq!(glb.len() % 4, 0);
        let json_len = u32_at(glb, 12) as usize;
        assert_eq!(json_len % 4, 0);
        assert_eq!(&glb[16..20], b"JSON");
        let json_bytes = &glb[20..20 + json_len];
        let json: Value = serde_json::from_slice(json_bytes).expect("JSON chunk parses");
        let rest = &glb[20 + json_len..];
        if rest.is_empty() {
            return (json, rest);
        }
        let bin_len = u32_at(rest, 0) as usize;
        assert_eq!(bin_len % 4, 0);
        assert_eq!(&rest[4..8], b"BIN\0");
        assert_eq!(rest.len(), 8 + bin_len);
        (json, &rest[8..])
    }

    /// Reads accessor `i` as f32 vec3s or as indices, after checking it lies in its view and the
    /// view in the buffer.
    fn accessor_data(json: &Value, bin: &[u8], i: u64) -> (Vec<[f32; 3]>, Vec<u32>) {
        let a = &json["accessors"][i as usize];
        let view = &json["bufferViews"][a["bufferView"].as_u64().unwrap() as usize];
        let buffer_len = json["buffers"][0]["byteLength"].as_u64().unwrap() as usize;
        assert!(buffer_len <= bin.len() && bin.len() - buffer_len < 4);
        let v_off = view["byteOffset"].as_u64().unwrap_or(0) as usize;
        let v_len = view["byteLength"].as_u64().unwrap() as usize;
        assert_eq!(v_off % 4, 0, "bufferView offsets are 4-aligned");
        assert!(v_off + v_len <= buffer_len, "bufferView inside the buffer");
        if view["target"] == ARRAY_BUFFER {
            assert_eq!(view["byteStride"], 12);
        } else {
            assert!(view.get("byteStride").is_none());
        }
        let a_off = a["byteOffset"].as_u64().unwrap_or(0) as usize;
        let count = a["count"].as_u64().unwrap() as usize;
        assert!(count > 0);
        let start = v_off + a_off;
        match (
            a["type"].as_str().unwrap(),
            a["componentType"].as_u64().unwrap() as u32,
        ) {
            ("VEC3", FLOAT) => {
                assert_eq!(start % 4, 0);
                assert!(a_off + count * 12 <= v_len);
                let v = (0..count)
                    .map(|k| std::array::from_fn(|c| f32_at(bin, start + k * 12 + c * 4)))
                    .collect();
                (v, Vec::new())
            }
            ("SCALAR", UNSIGNED_SHORT) => {
                assert_eq!(start % 2, 0);
                assert!(a_off + count * 2 <= v_len);
                let v = (0..count)
                    .map(|k| {
                        u16::from_le_bytes([bin[start + 2 * k], bin[start + 2 * k + 1]]) as u32
                    })
                    .collect();
                (Vec::new(), v)
            }
            ("SCALAR", UNSIGNED_INT) => {
                assert_eq!(start % 4, 0);
                assert!(a_off + count * 4 <= v_len);
                (
                    Vec::new(),
                    (0..count).map(|k| u32_at(bin, start + 4 * k)).collect(),
                )
            }
            other => panic!("unexpected accessor {other:?}"),
        }
    }

    /// Every primitive of mesh `m`: checks min/max, normals, index range, and that every
    /// triangle faces the way its normal does. Returns the total triangle area.
    fn check_mesh(json: &Value, bin: &[u8], m: u64) -> f64 {
        let mut area = 0.0;
        for prim in json["meshes"][m as usize]["primitives"].as_array().unwrap() {
            let pos_i = prim["attributes"]["POSITION"].as_u64().unwrap();
            let (pos, _) = accessor_data(json, bin, pos_i);
            let (nrm, _) = accessor_data(json, bin, prim["attributes"]["NORMAL"].as_u64().unwrap());
            let (_, idx) = accessor_data(json, bin, prim["indices"].as_u64().unwrap());
            assert_eq!(pos.len(), nrm.len());
            let acc = &json["accessors"][pos_i as usize];
            for c in 0..3 {
                let lo = pos.iter().map(|p| p[c]).fold(f32::INFINITY, f32::min);
                let hi = pos.iter().map(|p| p[c]).fold(f32::NEG_INFINITY, f32::max);
                assert_eq!(acc["min"][c].as_f64().unwrap() as f32, lo);
                assert_eq!(acc["max"][c].as_f64().unwrap() as f32, hi);
            }
            assert!(nrm
                .iter()
                .all(|n| (DVec3::from(n.map(f64::from)).length() - 1.0).abs() < 1e-6));
            assert_eq!(idx.len() % 3, 0);
            assert!(
                idx.iter().all(|&i| (i as usize) < pos.len()),
                "indices in range"
            );
            for t in idx.chunks_exact(3) {
                let p = |k: usize| DVec3::from(pos[t[k] as usize].map(f64::from));
                let cross = (p(1) - p(0)).cross(p(2) - p(0));
                let n = DVec3::from(nrm[t[0] as usize].map(f64::from));
                assert!(
                    cross.dot(n) > 0.0,
                    "triangle winding agrees with its normal"
                );
                area += 0.5 * cross.length();
            }
            let mat = prim["material"].as_u64().unwrap() as usize;
            assert!(mat < json["materials"].as_array().unwrap().len());
        }
        area
    }

    /// The child mesh of building node `node` named `class`.
    fn class_mesh(json: &Value, node: &Value, class: &str) -> Option<u64> {
        node["children"].as_array()?.iter().find_map(|c| {
            let child = &json["nodes"][c.as_u64().unwrap() as usize];
            (child["name"] == class).then(|| child["mesh"].as_u64().unwrap())
        })
    }

    // ---- tests ----

    #[test]
    fn a_binary_chunk_over_the_limit_fails_at_that_building_not_at_the_end() {
        let buildings = all_buildings();
        let mut out = Vec::new();
        let mut w = GltfWriter::new(&mut out, tempfile::tempfile().unwrap());
        w.max_bin = 1; // any building's vertex data is over it
        w.start(&OutputContext { ..ctx() }, "EPSG:2154".into())
            .unwrap();
        let e = w.write(&buildings[0]).unwrap_err().to_string();
        assert!(
            e.contains("over the GLB limit") && e.contains("--tile"),
            "{e}"
        );
        assert!(e.contains(&buildings[0].id.to_string()), "{e}");
        assert!(w.write(&buildings[1]).is_err() && w.finish().is_err());
        drop(w);
        assert!(out.is_empty(), "nothing is written to the target");
    }

    #[test]
    fn glb_container_and_asset() {
        let glb = write_glb(&all_buildings());
        let (json, bin) = parse_glb(&glb);
        assert_eq!(json["asset"]["version"], "2.0");
        assert_eq!(
            json["asset"]["generator"],
            format!("citygen {}", env!("CARGO_PKG_VERSION"))
        );
        assert_eq!(json["asset"]["extras"]["crs"], "EPSG:2154");
        assert_eq!(
            json["asset"]["extras"]["origin"],
            serde_json::json!([574000.25, 6279000.5, 140.0])
        );
        assert_eq!(json["scene"], 0);
        assert_eq!(json["buffers"].as_array().unwrap().len(), 1);
        assert!(json["buffers"][0].get("uri").is_none());
        // Every accessor is readable and consistent.
        for i in 0..json["accessors"].as_array().unwrap().len() {
            accessor_data(&json, bin, i as u64);
        }
    }

    #[test]
    fn one_node_per_building_with_extras() {
        let buildings = all_buildings();
        let glb = write_glb(&buildings);
        let (json, _) = parse_glb(&glb);
        let roots = json["scenes"][0]["nodes"].as_array().unwrap();
        assert_eq!(roots.len(), buildings.len());
        for (r, b) in roots.iter().zip(&buildings) {
            let node = &json["nodes"][r.as_u64().unwrap() as usize];
            assert_eq!(node["name"], b.key());
            let x = &node["extras"];
            assert_eq!(x["id"], b.id.to_string());
            assert_eq!(x["zone"], "earth/France/Occitanie/Toulouse");
            assert_eq!(x["appearance"], "Toulouse#1");
            assert_eq!(x["height"].as_f64().unwrap(), b.measured_height);
            assert_eq!(x["base"].as_f64().unwrap(), b.base_z);
            let names: Vec<&str> = node["children"]
                .as_array()
                .unwrap()
                .iter()
                .map(|c| {
                    json["nodes"][c.as_u64().unwrap() as usize]["name"]
                        .as_str()
                        .unwrap()
                })
                .collect();
            assert_eq!(names, ["walls", "roof", "ground"]);
        }
    }

    #[test]
    fn box_areas_and_coordinates() {
        let glb = write_glb(&[box_building()]);
        let (json, bin) = parse_glb(&glb);
        let node = &json["nodes"][0];
        let walls = check_mesh(&json, bin, class_mesh(&json, node, "walls").unwrap());
        let roof = check_mesh(&json, bin, class_mesh(&json, node, "roof").unwrap());
        let ground = check_mesh(&json, bin, class_mesh(&json, node, "ground").unwrap());
        assert!((walls - 96.0).abs() < 1e-4);
        assert!((roof - 60.0).abs() < 1e-4);
        assert!((ground - 60.0).abs() < 1e-4);
        // Y up, north = -Z: the box spans x 0..10, y 0..3, z -6..0.
        let roof_mesh = class_mesh(&json, node, "roof").unwrap() as usize;
        let pos = json["meshes"][roof_mesh]["primitives"][0]["attributes"]["POSITION"]
            .as_u64()
            .unwrap() as usize;
        assert_eq!(
            json["accessors"][pos]["min"],
            serde_json::json!([0.0, 3.0, -6.0])
        );
        assert_eq!(
            json["accessors"][pos]["max"],
            serde_json::json!([10.0, 3.0, 0.0])
        );
        // Roof normals point up (+Y) in glTF.
        let nrm = json["meshes"][roof_mesh]["primitives"][0]["attributes"]["NORMAL"]
            .as_u64()
            .unwrap();
        let (n, _) = accessor_data(&json, bin, nrm);
        assert!(n.iter().all(|n| *n == [0.0, 1.0, 0.0]));
        // Flat shading: 4 walls x 4 + 4 + 4 vertices.
        let count = |m: u64| {
            let a = json["meshes"][m as usize]["primitives"][0]["attributes"]["POSITION"]
                .as_u64()
                .unwrap();
            json["accessors"][a as usize]["count"].as_u64().unwrap()
        };
        assert_eq!(count(class_mesh(&json, node, "walls").unwrap()), 16);
    }

    #[test]
    fn courtyard_hole_is_kept() {
        let glb = write_glb(&[courtyard_building()]);
        let (json, bin) = parse_glb(&glb);
        let node = &json["nodes"][0];
        let roof = check_mesh(&json, bin, class_mesh(&json, node, "roof").unwrap());
        let ground = check_mesh(&json, bin, class_mesh(&json, node, "ground").unwrap());
        let walls = check_mesh(&json, bin, class_mesh(&json, node, "walls").unwrap());
        assert!((roof - 336.0).abs() < 1e-3, "{roof}");
        assert!((ground - 336.0).abs() < 1e-3, "{ground}");
        assert!((walls - (80.0 + 32.0) * 9.0).abs() < 1e-3, "{walls}");
    }

    #[test]
    fn two_parts_two_wall_materials_and_hip_roof() {
        let glb = write_glb(&[two_part_building()]);
        let (json, bin) = parse_glb(&glb);
        let node = &json["nodes"][0];
        let walls_mesh = class_mesh(&json, node, "walls").unwrap();
        assert_eq!(
            json["meshes"][walls_mesh as usize]["primitives"]
                .as_array()
                .unwrap()
                .len(),
            2
        );
        let walls = check_mesh(&json, bin, walls_mesh);
        assert!((walls - (32.0 * 6.0 + 32.0 * 3.0)).abs() < 1e-3);
        let roof = check_mesh(&json, bin, class_mesh(&json, node, "roof").unwrap());
        // Flat 60 m2 plus the hip roof (trapezoids 2 x 19.80, triangles 2 x 10.82).
        let s = (9.0f64 + 4.0).sqrt();
        let expected =
            60.0 + 2.0 * (10.0 + 4.0) / 2.0 * s + 2.0 * 0.5 * 6.0 * (9.0f64 + 4.0).sqrt();
        assert!((roof - expected).abs() < 1e-3, "{roof} vs {expected}");
    }

    #[test]
    fn materials_cached_linear_and_blended() {
        let glb = write_glb(&all_buildings());
        let (json, _) = parse_glb(&glb);
        let mats = json["materials"].as_array().unwrap();
        // walls white, roof, ground, courtyard walls, yellow walls, translucent roof.
        let names: Vec<&str> = mats.iter().map(|m| m["name"].as_str().unwrap()).collect();
        assert_eq!(
            names,
            [
                "walls #ffffff",
                "roof #b3331a",
                "ground #808080",
                "walls #e6cc99",
                "walls #ffff80",
                "roof #80b3e6 alpha 0.4"
            ]
        );
        for m in mats {
            let pbr = &m["pbrMetallicRoughness"];
            assert_eq!(pbr["metallicFactor"], 0.0);
            assert!((pbr["roughnessFactor"].as_f64().unwrap() - 0.9).abs() < 1e-6);
        }
        // sRGB 0.5 -> linear 0.2140.
        let grey = mats[2]["pbrMetallicRoughness"]["baseColorFactor"][0]
            .as_f64()
            .unwrap();
        assert!((grey - 0.2140).abs() < 1e-3, "{grey}");
        assert_eq!(mats[5]["alphaMode"], "BLEND");
        assert!(mats[0].get("alphaMode").is_none());
    }

    #[test]
    #[ignore = "writes /tmp/x.glb for manual validation"]
    fn dump_sample() {
        std::fs::write("/tmp/x.glb", write_glb(&all_buildings())).unwrap();
    }

    /// FNV-1a 64: a dependency-free fingerprint of an output.
    fn fnv1a(bytes: &[u8]) -> u64 {
        bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
            (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
        })
    }

    /// LOD2 output is byte-identical to the writer before LOD3 support (fingerprint taken from
    /// that writer on the same samples).
    #[test]
    fn lod2_output_unchanged_by_lod3_support() {
        assert_eq!(
            fnv1a(&write_glb(&all_buildings())),
            13_296_349_161_037_005_596
        );
    }

    #[test]
    fn deterministic() {
        assert_eq!(write_glb(&all_buildings()), write_glb(&all_buildings()));
    }

    #[test]
    fn empty_and_degenerate_inputs() {
        let glb = write_glb(&[]);
        let (json, bin) = parse_glb(&glb);
        assert!(bin.is_empty());
        assert!(json.get("buffers").is_none() && json.get("nodes").is_none());
        // A building whose every face is degenerate still gets its node, without children.
        let mut b = box_building();
        for p in &mut b.parts {
            p.roof = vec![Face::new(vec![DVec3::ZERO, DVec3::X])];
            p.ground = Face::new(vec![DVec3::new(f64::NAN, 0.0, 0.0); 3]);
            p.walls.clear();
        }
        b.measured_height = f64::NAN;
        let glb = write_glb(&[b]);
        let (json, _) = parse_glb(&glb);
        assert_eq!(json["nodes"].as_array().unwrap().len(), 1);
        assert!(json["nodes"][0].get("children").is_none());
        assert!(json["nodes"][0]["extras"]["height"].is_null());
    }

    #[test]
    fn scratch_beside_target_is_removed() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("out.glb");
        let file = File::create(&target).unwrap();
        let mut w = GltfWriter::beside(file, &target).unwrap();
        w.start(&ctx(), "EPSG:2154".into()).unwrap();
        w.write(&box_building()).unwrap();
        w.finish().unwrap();
        drop(w);
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, ["out.glb"]);
        let glb = std::fs::read(&target).unwrap();
        let (json, bin) = parse_glb(&glb);
        check_mesh(&json, bin, 0);
    }

    #[test]
    fn call_order_is_enforced() {
        let mut out = Vec::new();
        let mut w = GltfWriter::new(&mut out, tempfile::tempfile().unwrap());
        assert!(w.write(&box_building()).is_err());
        assert!(w.finish().is_err());
        w.start(&ctx(), "EPSG:2154".into()).unwrap();
        assert!(w.start(&ctx(), "EPSG:2154".into()).is_err());
        w.finish().unwrap();
        assert!(w.finish().is_err());
        assert!(w.write(&box_building()).is_err());
    }

    #[test]
    fn large_primitive_uses_u32_indices() {
        // 17 000 small wall quads: 68 000 vertices in one primitive, more than u16 can index.
        let mut b = box_building();
        b.parts[0].walls = (0..17_000)
            .map(|k| {
                let x = k as f64 * 0.01;
                wall(DVec2::new(x, 0.0), DVec2::new(x + 0.01, 0.0), 0.0, 3.0)
            })
            .collect();
        let glb = write_glb(&[b]);
        let (json, bin) = parse_glb(&glb);
        let walls = class_mesh(&json, &json["nodes"][0], "walls").unwrap();
        let idx = json["meshes"][walls as usize]["primitives"][0]["indices"]
            .as_u64()
            .unwrap();
        assert_eq!(
            json["accessors"][idx as usize]["componentType"],
            UNSIGNED_INT
        );
        check_mesh(&json, bin, walls);
    }

    /// Runs the Khronos glTF validator through the shared script when it is installed.
    #[test]
    fn khronos_validator_accepts_output() {
        let tool = std::path::Path::new("/work/shared/tools/validate-outputs");
        let installed = std::env::var_os("HOME")
            .map(|h| {
                std::path::Path::new(&h)
                    .join(".cache/citygen-validate/node/node_modules/gltf-validator")
                    .is_dir()
            })
            .unwrap_or(false);
        if !tool.exists() || !installed {
            eprintln!(
                "skipping: glTF validator not installed ({})",
                tool.display()
            );
            return;
        }
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("citygen-test.glb");
        std::fs::write(&path, write_glb(&all_buildings())).unwrap();
        let path3 = dir.path().join("citygen-test-lod3.glb");
        std::fs::write(&path3, write_glb_at(Lod::Lod3, &samples::all())).unwrap();
        let out = std::process::Command::new(tool)
            .arg(&path)
            .arg(&path3)
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success(),
            "validator failed:\n{text}\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(text.contains("2 passed, 0 failed"), "{text}");
        assert_eq!(text.matches("warnings=0").count(), 2, "{text}");
    }

    // ---- LOD4 ----

    #[test]
    fn lod4_interior_nodes_and_areas() {
        let house = crate::export::fixtures::lod4_house();
        let glb = write_glb_at(Lod::Lod4, std::slice::from_ref(&house));
        let (json, bin) = parse_glb(&glb);
        let root = &json["nodes"][json["scenes"][0]["nodes"][0].as_u64().unwrap() as usize];
        assert_eq!(
            child_names(&json, root),
            [
                "walls",
                "roof",
                "ground",
                "windows",
                "doors",
                "floors",
                "interior walls",
                "interior doors",
                "stairs",
                "slabs"
            ]
        );
        let area = |class: &str| check_mesh(&json, bin, class_mesh(&json, root, class).unwrap());
        // Floors: the usable area on each storey.
        let usable = 11.4 * 7.4;
        assert!(
            (area("floors") - 2.0 * usable).abs() < 1e-3,
            "{}",
            area("floors")
        );
        // Door leaves: two faces per door, 4 doors of 0.9 m x (2.1 - sill).
        let leaf = 0.9 * (2.1 - lod4geom::DOOR_SILL);
        assert!((area("interior doors") - 8.0 * leaf).abs() < 1e-3);
        // Interior walls: both long faces minus the door holes dominate; at least that much.
        let walls = 2.0 * 2.8 * (3.7 + 3.7 + 7.4) * 2.0 - 2.0 * 4.0 * leaf;
        assert!(area("interior walls") > walls);
        // Slabs: only the upper storey has one: its underside is the rooms minus the well.
        let well = 1.0 * 4.5;
        assert!(area("slabs") > usable - well);
        assert!(area("stairs") > 0.0);
        // Below LOD4 a model without interiors writes none of these nodes.
        let glb = write_glb_at(Lod::Lod3, &samples::all());
        let (json, _) = parse_glb(&glb);
        for r in json["scenes"][0]["nodes"].as_array().unwrap() {
            let node = &json["nodes"][r.as_u64().unwrap() as usize];
            assert!(!child_names(&json, node).iter().any(|n| n == "floors"));
        }
    }

    #[test]
    fn lod4_validates_with_khronos() {
        let Some(tool) = crate::export::fixtures::validator() else {
            eprintln!("validate-outputs not installed: skipped");
            return;
        };
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("lod4.glb");
        let bytes = write_glb_at(Lod::Lod4, &crate::export::fixtures::lod4_all());
        if let Some(keep) = std::env::var_os("CITYGEN_GLB_LOD4_SAMPLE") {
            std::fs::write(keep, &bytes).unwrap();
        }
        std::fs::write(&path, bytes).unwrap();
        let out = std::process::Command::new(tool)
            .arg(&path)
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(out.status.success() && text.contains(" 0 failed"), "{text}");
        assert!(text.contains("warnings=0"), "{text}");
    }

    // ---- LOD3 ----

    fn child_names(json: &Value, node: &Value) -> Vec<String> {
        node["children"]
            .as_array()
            .map(|c| {
                c.iter()
                    .map(|i| json["nodes"][i.as_u64().unwrap() as usize]["name"].to_string())
                    .map(|n| n.trim_matches('"').to_string())
                    .collect()
            })
            .unwrap_or_default()
    }

    /// Positions of the primitives of mesh `m` whose material satisfies `pred`.
    fn positions_where(
        json: &Value,
        bin: &[u8],
        m: u64,
        pred: impl Fn(&Value) -> bool,
    ) -> Vec<[f32; 3]> {
        json["meshes"][m as usize]["primitives"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|p| pred(&json["materials"][p["material"].as_u64().unwrap() as usize]))
            .flat_map(|p| accessor_data(json, bin, p["attributes"]["POSITION"].as_u64().unwrap()).0)
            .collect()
    }

    #[test]
    fn lod3_nodes_per_class() {
        let buildings = samples::all();
        let glb = write_glb_at(Lod::Lod3, &buildings);
        let (json, _) = parse_glb(&glb);
        let roots: Vec<&Value> = json["scenes"][0]["nodes"]
            .as_array()
            .unwrap()
            .iter()
            .map(|r| &json["nodes"][r.as_u64().unwrap() as usize])
            .collect();
        let names = |i: usize| child_names(&json, roots[i]);
        assert_eq!(names(0), ["walls", "roof", "ground", "windows", "doors"]);
        assert_eq!(names(1), ["walls", "roof", "ground", "windows"]);
        assert_eq!(
            names(2),
            ["walls", "roof", "ground", "windows", "doors", "balconies"]
        );
        assert_eq!(names(3), ["walls", "roof", "ground", "windows"]);
        assert_eq!(roots[0]["extras"]["lod"], 3);
        // Below LOD3 the details are not written (the model has none there anyway).
        let glb = write_glb_at(Lod::Lod2, &buildings);
        let (json, _) = parse_glb(&glb);
        let first = &json["nodes"][json["scenes"][0]["nodes"][0].as_u64().unwrap() as usize];
        assert_eq!(child_names(&json, first), ["walls", "roof", "ground"]);
    }

    #[test]
    fn lod3_wall_area_is_wall_minus_openings() {
        for b in samples::all() {
            let glb = write_glb_at(Lod::Lod3, std::slice::from_ref(&b));
            let (json, bin) = parse_glb(&glb);
            let node = &json["nodes"][0];
            let walls = check_mesh(&json, bin, class_mesh(&json, node, "walls").unwrap());
            let expected = samples::net_wall_area(&b);
            assert!(
                (walls - expected).abs() < 1e-3,
                "{}: {walls} vs {expected}",
                b.id
            );
            // Panes and reveals: w*h + 2(w+h)*0.1 per opening.
            let mut expected_openings = 0.0;
            for o in b
                .parts
                .iter()
                .flat_map(|p| &p.walls)
                .flat_map(|w| &w.openings)
            {
                expected_openings += o.width() * o.height() + 2.0 * (o.width() + o.height()) * 0.1;
            }
            let mut got = 0.0;
            for class in ["windows", "doors"] {
                if let Some(m) = class_mesh(&json, node, class) {
                    got += check_mesh(&json, bin, m);
                }
            }
            assert!(
                (got - expected_openings).abs() < 1e-3,
                "{got} vs {expected_openings}"
            );
            for class in ["roof", "ground", "balconies"] {
                if let Some(m) = class_mesh(&json, node, class) {
                    check_mesh(&json, bin, m);
                }
            }
        }
    }

    #[test]
    fn lod3_panes_are_recessed_and_glass_is_transparent() {
        let glb = write_glb_at(Lod::Lod3, &[samples::house()]);
        let (json, bin) = parse_glb(&glb);
        let node = &json["nodes"][0];
        let windows = class_mesh(&json, node, "windows").unwrap();
        let doors = class_mesh(&json, node, "doors").unwrap();
        let is_glass = |m: &Value| m["alphaMode"] == "BLEND";
        // The front wall is y = 0, the inside +y: glTF z = -y, so panes sit at z = -0.1.
        let glass = positions_where(&json, bin, windows, is_glass);
        assert_eq!(glass.len(), 4 * 4);
        assert!(glass.iter().all(|p| (p[2] + 0.1).abs() < 1e-6), "{glass:?}");
        let door_pane = positions_where(&json, bin, doors, |m| {
            m["name"].as_str().unwrap().starts_with("doors #66401a")
        });
        assert_eq!(door_pane.len(), 4);
        assert!(door_pane.iter().all(|p| (p[2] + 0.1).abs() < 1e-6));
        let mats = json["materials"].as_array().unwrap();
        let glass_mat = mats.iter().find(|m| is_glass(m)).unwrap();
        assert!(glass_mat["name"]
            .as_str()
            .unwrap()
            .starts_with("windows #8cb3cc"));
        let alpha = glass_mat["pbrMetallicRoughness"]["baseColorFactor"][3]
            .as_f64()
            .unwrap();
        assert!((alpha - 0.35).abs() < 1e-6);
        // Doors opaque in their colour; frames opaque.
        for m in mats {
            let name = m["name"].as_str().unwrap();
            if name.starts_with("doors") || name.starts_with("walls") {
                assert!(m.get("alphaMode").is_none(), "{name}");
            }
        }
        let door = mats
            .iter()
            .find(|m| m["name"] == "doors #66401a")
            .expect("door material");
        let r = door["pbrMetallicRoughness"]["baseColorFactor"][0]
            .as_f64()
            .unwrap();
        assert!((r - f64::from(srgb_to_linear(0.4))).abs() < 1e-6);
    }

    #[test]
    fn lod3_balcony_box_and_railing() {
        let b = samples::with_balcony();
        let glb = write_glb_at(Lod::Lod3, std::slice::from_ref(&b));
        let (json, bin) = parse_glb(&glb);
        let m = class_mesh(&json, &json["nodes"][0], "balconies").unwrap();
        let area = check_mesh(&json, bin, m);
        // Slab 4 x 1.2 x 0.2 plus railing 4 x 1 and two 1.2 x 1 ends.
        let slab = 2.0 * (4.0 * 1.2 + 4.0 * 0.2 + 1.2 * 0.2);
        let railing = 4.0 + 2.0 * 1.2;
        assert!((area - slab - railing).abs() < 1e-3, "{area}");
        let mat = json["meshes"][m as usize]["primitives"][0]["material"]
            .as_u64()
            .unwrap() as usize;
        assert_eq!(json["materials"][mat]["doubleSided"], true);
        // Out in front of the wall (y from 0 to -1.2 is glTF z 0 to 1.2).
        let pos = positions_where(&json, bin, m, |_| true);
        let max_z = pos.iter().map(|p| p[2]).fold(f32::NEG_INFINITY, f32::max);
        assert!((max_z - 1.2).abs() < 1e-5, "{max_z}");
        // Only balcony materials are double-sided.
        for mat in json["materials"].as_array().unwrap() {
            let balcony = mat["name"].as_str().unwrap().starts_with("balconies");
            assert_eq!(mat.get("doubleSided").is_some(), balcony);
        }
    }

    #[test]
    fn lod3_deterministic() {
        let b = samples::all();
        assert_eq!(write_glb_at(Lod::Lod3, &b), write_glb_at(Lod::Lod3, &b));
    }

    #[test]
    #[ignore = "writes /tmp/c3.glb for manual validation"]
    fn dump_lod3_sample() {
        std::fs::write("/tmp/c3.glb", write_glb_at(Lod::Lod3, &samples::all())).unwrap();
    }
}
