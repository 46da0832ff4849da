//! CityJSON 2.0 writers: one `.city.json` file (`CityJsonWriter`) and a CityJSONSeq stream
//! (`CityJsonSeqWriter`, `.city.jsonl`), both streamed.
//!
//! Both write the same CityObjects. Vertices are integers: whole millimetres from the
//! `transform`'s `translate`, the run's local origin ([`OutputContext::origin`]), with `scale`
//! 0.001, so a vertex is `translate + 0.001 * v` in the output CRS, within 0.5 mm of the model
//! point (`crate::model::grid_key`). `metadata.referenceSystem` names the output CRS as an
//! OGC URL (`https://www.opengis.net/def/crs/EPSG/0/<code>`, the EPSG code the CityGML writer
//! names). When the run states a vertical datum ([`OutputContext::vertical_datum`]) the title
//! names it, and with its EPSG code `metadata.verticalReferenceSystem` gives it as an OGC URL
//! too (a member the CityJSON 2.0 schema allows; `referenceSystem` keeps the horizontal code:
//! cjval 0.10 refuses OGC's compound form `https://www.opengis.net/def/crs-compound?1=…&2=…`,
//! its pattern wants `…/def/crs/`). The model's faces already follow CityJSON's orientation: an outer ring is
//! counter-clockwise seen from outside the solid (its normal points out), holes run the other
//! way.
//!
//! What each building gets (ids as the CityGML writer's: `B_way_123`, its parts
//! `B_way_123_p0`):
//!
//! - a `Building` with `attributes` `sourceId`, `name` (when it has one), `zone`,
//!   `appearance`, the provenance of its storeys, height and roof (`storeysSource`,
//!   `heightSource`, `roofSource`: `tag`, `neighbours`, `fitted`, `model` or `kb`;
//!   `storeysError`, `heightError` in metres and `roofProbability`, numbers left out when
//!   unknown), `partSourceId` (one part traced to another footprint), `measuredHeight`,
//!   `storeysAboveGround` and `roofType` (the SIG3D code the CityGML writer's `bldg:roofType`
//!   holds). A building of several parts has one `BuildingPart` per part (`parents`/`children`
//!   linked; attributes `sourceId` where the part comes from its own footprint or is its
//!   outline's uncovered rest, `sourceRole` `outline-rest` on the rest, `measuredHeight` (its
//!   top above the building's ground, as the building's), `storeysAboveGround`, `roofType`)
//!   and the parts carry the geometry;
//!   otherwise the building does.
//! - **LOD1**: one `Solid` of lod `"1"`: ground, walls, flat top.
//! - **LOD2**: one `Solid` of lod `"2.2"` with semantics `GroundSurface`, `WallSurface`,
//!   `RoofSurface`.
//! - **LOD3**: one `Solid` of lod `"3"`: walls with a hole per opening, and each opening's
//!   polygon (which fills its hole, `crate::export::lod3geom::opening_face` at depth 0) in the
//!   same shell; the `Window` and `Door` semantic objects are `children` of their wall's own
//!   `WallSurface` object (and name it as `parent`); a wall against a neighbour has its own
//!   `WallSurface` with `partyWallShare` (as the CityGML). Ground and walls are those of
//!   `crate::export::lod3geom::seated_changes` (a vertex under each jamb of a low opening),
//!   as the CityGML's solid. Balconies are `BuildingInstallation` children (`function`
//!   `balcony`) with a `MultiSurface` of lod `"3"` (slab, railing, infill, each face with the
//!   material of its colour, as in CityGML and glTF); so are a wall's window sills (`function`
//!   `window sills`, id `<part>_w<wall>_sills`: each sill's closed box,
//!   `crate::export::lod3geom::sills`, in `SILL_COLOR`).
//! - **LOD4**: CityJSON 2.0 has no LOD4; as CityGML 3.0 does, the interior is written at LOD3
//!   in the objects CityJSON 2.0 has for it. The exterior is the LOD3 one; under the building
//!   (or its part) each room is a `BuildingRoom` (attributes `name`, `usage`, `storey`: the
//!   storey's index from the ground) with a closed `Solid` of lod `"3"`, semantics
//!   `FloorSurface`, `CeilingSurface`, `InteriorWallSurface` and `Door` (an interior door's
//!   polygon, in each of its two rooms' shells, a child of that side's own
//!   `InteriorWallSurface`); each interior wall a `BuildingConstructiveElement` (`function`
//!   `interior wall`, `storey`) with its body as a `Solid` of lod `"3"` (door holes lined by
//!   their reveals); each stair a `BuildingInstallation` (`function` `stairs`, `storey`) with a
//!   `MultiSurface` of lod `"3"` of its steps. All of them name the building or part as
//!   `parents` and are in its `children`.
//!
//! A context with a terrain ([`OutputContext::terrain`]) gets it after the buildings as a
//! `TINRelief` object (id `TIN_<E>_<N>`, attribute `tolerance`) with one `CompositeSurface` of
//! triangles; in CityJSONSeq its own `CityJSONFeature` line, the last.
//!
//! **Colours** are materials of the appearance theme `citygen` (the CityGML writer's theme):
//! each building solid has `"material":{"citygen":{"values":[[..]]}}`, one index per surface
//! (walls: the part's wall colour, roofs: its roof colour, LOD3 openings: their own colour,
//! glazed windows 0.6 transparent as in the CityGML; the ground `null`). A material is
//! `{"name":"#rrggbb","diffuseColor":[r,g,b],"isSmooth":false}` (with `transparency` when not
//! opaque), one per distinct (colour, surface material); when the surface's material is known
//! (`crate::color::material`: the part's `wall_material` / `roof_material`, glass for glazed
//! windows) its name follows the colour's (`"#a0522d brick"`) and `shininess` (one minus its
//! PBR roughness) comes after the colour, as in the CityGML's X3D materials. The `.city.json` numbers them in first-use order over
//! the file and writes `"appearance":{"materials":[..]}` after the CityObjects; each
//! CityJSONSeq feature carries its own `appearance` with its own materials.
//!
//! **The extent:** the `.city.json`'s `metadata` comes last, with `geographicalExtent` (the
//! written vertices' bounds in the output CRS); the CityJSONSeq's first line has the metadata
//! without it (the extent is known only at the end).
//!
//! **The `.city.json` file** (`CityJsonWriter`) is `{"type":"CityJSON","version":"2.0",
//! "transform":..,"CityObjects":{..},"appearance":..,"vertices":[..],"metadata":..}`: the buildings' objects
//! go to the output as they come, the vertices are appended to a scratch file as they are
//! first used and copied after the objects at the end. A building's vertices are each written
//! once; across buildings a vertex is shared through a table of the vertices written so far,
//! emptied when it holds `SHARED_VERTICES` (so memory does not grow with the city: past that,
//! a vertex two buildings far apart in the input share may be written twice, which CityJSON
//! allows and cjval notes as a warning).
//!
//! **The CityJSONSeq stream** (`CityJsonSeqWriter`): a first line, the CityJSON object with
//! the transform and metadata and empty `CityObjects` and `vertices`, then one line per
//! building: a `CityJSONFeature` whose `id` is the building's, with its objects and its own
//! vertices.
//!
//! Both render `super::PARALLEL_BATCH` buildings at a time in parallel, each into its own
//! buffer with its own vertices, then number the vertices in order: the bytes do not depend on
//! the thread count.

use std::fs::File;
use std::io::{self, BufWriter, Seek, Write};
use std::path::Path;

use rayon::prelude::*;

use crate::export::format::{push_fixed4_i64, push_uint};
use crate::export::texture::{note_used, Texture, TextureOut, Texturing};
use crate::export::{
    check_finite, vertical_datum, BuildingWriter, Checked, ExportError, OutputContext,
};
use crate::model::{Building, Lod};

use render::{Frag, Vertex, VertexMap};

mod render;

/// The most vertices the `.city.json` writer remembers to share them between buildings: 7/8
/// of 2^20, what a hash table of 2^20 buckets of 33 bytes (35 MB) holds; the table is emptied
/// when full.
pub(crate) const SHARED_VERTICES: usize = 917_504;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    New,
    Open,
    Finished,
}

fn check_state(writer: &str, state: State, expected: State, call: &str) -> Result<(), ExportError> {
    if state == expected {
        return Ok(());
    }
    let why = match state {
        State::New => "before begin()",
        State::Open => "after begin()",
        State::Finished => "after finish()",
    };
    Err(ExportError::Invalid(format!(
        "{writer}: {call} called {why}"
    )))
}

/// The file's start, `{"type":"CityJSON","version":"2.0","transform":{..},`, and the members
/// of its `metadata` (reference systems and title, without braces).
fn header(ctx: &OutputContext, writer: &str) -> Result<(Vec<u8>, Vec<u8>), ExportError> {
    if !ctx.origin.is_finite() {
        return Err(ExportError::Invalid(format!(
            "{writer}: the local origin {:?} is not finite",
            ctx.origin
        )));
    }
    let o = ctx.origin;
    let mut title = format!(
        "Generated by citygen from {}, seed {}, LOD{} geometry",
        ctx.source_name,
        ctx.seed,
        ctx.lod.number()
    );
    let datum = vertical_datum(ctx);
    if let Some((epsg, name)) = datum {
        title.push_str("; heights: ");
        title.push_str(name);
        if let Some(v) = epsg {
            title.push_str(&format!(" (EPSG:{v})"));
        }
    }
    let vertical = match datum {
        Some((Some(v), _)) => {
            format!("\"verticalReferenceSystem\":\"https://www.opengis.net/def/crs/EPSG/0/{v}\",")
        }
        _ => String::new(),
    };
    let start = format!(
        "{{\"type\":\"CityJSON\",\"version\":\"2.0\",\"transform\":{{\"scale\":[0.001,0.001,0.001],\"translate\":[{},{},{}]}},",
        o.x, o.y, o.z
    )
    .into_bytes();
    let mut meta = format!(
        "\"referenceSystem\":\"https://www.opengis.net/def/crs/EPSG/0/{}\",{vertical}\"title\":",
        ctx.crs.epsg()
    )
    .into_bytes();
    serde_json::to_writer(&mut meta, &title).map_err(io::Error::other)?;
    Ok((start, meta))
}

/// `"appearance":{"materials":[..]}` of these material keys.
fn appearance(out: &mut Vec<u8>, mats: &[u64]) {
    out.extend_from_slice(b"\"appearance\":{");
    materials(out, mats);
    out.push(b'}');
}

/// `"materials":[..]` of these material keys.
fn materials(out: &mut Vec<u8>, mats: &[u64]) {
    out.extend_from_slice(b"\"materials\":[");
    for (i, &k) in mats.iter().enumerate() {
        if i > 0 {
            out.push(b',');
        }
        render::push_material(out, k);
    }
    out.push(b']');
}

/// `"textures":[..]` of these pictures (`--textures`): PNG files in `tex`'s folder, relative
/// to the output, repeated (`wrap`), typical of their material.
fn textures(out: &mut Vec<u8>, texs: &[Texture], tex: &TextureOut) {
    out.extend_from_slice(b"\"textures\":[");
    for (i, &t) in texs.iter().enumerate() {
        if i > 0 {
            out.push(b',');
        }
        out.extend_from_slice(b"{\"type\":\"PNG\",\"image\":");
        // Writing a &str to a Vec cannot fail.
        let _ = serde_json::to_writer(&mut *out, &tex.uri(t));
        out.extend_from_slice(b",\"wrapMode\":\"wrap\",\"textureType\":\"typical\"}");
    }
    out.push(b']');
}

/// Appends a texture vertex `[s,t]` ([`UvMap::st`](crate::export::texture::UvMap::st)).
fn push_st_vertex(out: &mut Vec<u8>, st: [i64; 2]) {
    out.push(b'[');
    push_fixed4_i64(out, st[0]);
    out.push(b',');
    push_fixed4_i64(out, st[1]);
    out.push(b']');
}

/// Appends `[x,y,z]` (formatted on the stack, appended at once).
fn push_vertex(out: &mut Vec<u8>, v: Vertex) {
    let mut buf = [0u8; 64];
    let mut n = 0;
    let mut put = |b: u8| {
        buf[n] = b;
        n += 1;
    };
    put(b'[');
    for (k, c) in [v.0, v.1, v.2].into_iter().enumerate() {
        if k > 0 {
            put(b',');
        }
        if c < 0 {
            put(b'-');
        }
        let mut digits = [0u8; 20];
        let mut m = c.unsigned_abs();
        let mut d = digits.len();
        loop {
            d -= 1;
            digits[d] = b'0' + (m % 10) as u8;
            m /= 10;
            if m == 0 {
                break;
            }
        }
        for &b in &digits[d..] {
            put(b);
        }
    }
    put(b']');
    out.extend_from_slice(&buf[..n]);
}

/// The frag's text with every mark replaced by `index(local vertex)` or, for a material mark,
/// `material(local material)`, for a texture mark `texture(local texture)`, for a texture
/// vertex's `st_base` plus its local index.
fn splice(
    frag: &Frag,
    index: impl Fn(u32) -> u64,
    material: impl Fn(u32) -> u64,
    (texture, st_base): (&dyn Fn(u32) -> u64, u64),
    out: &mut Vec<u8>,
) {
    let mut at = 0;
    for &(pos, li) in &frag.marks {
        out.extend_from_slice(&frag.text[at..pos]);
        if li & render::MATERIAL != 0 {
            push_uint(out, material(li & !render::MATERIAL));
        } else if li & render::TEXTURE != 0 {
            push_uint(out, texture(li & !render::TEXTURE));
        } else if li & render::ST != 0 {
            push_uint(out, st_base + u64::from(li & !render::ST));
        } else {
            push_uint(out, index(li));
        }
        at = pos;
    }
    out.extend_from_slice(&frag.text[at..]);
}

/// Where the `.city.json` writer keeps the vertices until the end.
enum Spool {
    /// A scratch file (its bytes copied to the output by `finish`).
    File(BufWriter<File>),
    /// In memory (tests, small outputs).
    Memory(Vec<u8>),
}

impl Spool {
    fn write_all(&mut self, b: &[u8]) -> io::Result<()> {
        match self {
            Spool::File(w) => w.write_all(b),
            Spool::Memory(v) => {
                v.extend_from_slice(b);
                Ok(())
            }
        }
    }
}

/// Removes scratch files that could not be unlinked while open (not on Unix).
struct ScratchGuard(Option<std::path::PathBuf>);

impl Drop for ScratchGuard {
    fn drop(&mut self) {
        if let Some(p) = self.0.take() {
            let _ = std::fs::remove_file(p);
        }
    }
}

/// Streaming CityJSON 2.0 writer of one `.city.json` file (see the module documentation).
pub(crate) struct CityJsonWriter<W: Write + Send> {
    out: W,
    state: State,
    lod: Lod,
    spool: Spool,
    _guard: ScratchGuard,
    /// The vertices written so far (up to [`SHARED_VERTICES`]), by value.
    shared: VertexMap<u64>,
    /// Vertices written.
    count: u64,
    /// No building written yet.
    first: bool,
    slots: Vec<Frag>,
    bufs: Vec<Vec<u8>>,
    tables: Vec<Vec<u64>>,
    /// New vertices of a batch, as text (scratch).
    vtext: Vec<u8>,
    /// The file's terrain and its id, written after the buildings.
    terrain: Option<(std::sync::Arc<crate::model::Terrain>, String)>,
    /// The file's materials ([`render::material_key`]) in first-use order, and their indices.
    materials: Vec<u64>,
    material_index: std::collections::HashMap<u64, u64>,
    /// Each slot's materials' file indices (scratch).
    mat_tables: Vec<Vec<u64>>,
    /// `--textures` ([`CityJsonWriter::with_textures`]): what is textured (set at `begin`),
    /// where the pictures are, the pictures used.
    textures: bool,
    tex: TextureOut,
    /// The file's pictures in first-use order, and their indices.
    texs: Vec<Texture>,
    tex_index: std::collections::HashMap<Texture, u64>,
    /// Each slot's pictures' file indices (scratch).
    tex_tables: Vec<Vec<u64>>,
    /// The texture vertices written so far, and where they wait until `finish` (each
    /// building's own, after the previous building's).
    st_count: u64,
    st_spool: Spool,
    _st_guard: ScratchGuard,
    /// The vertices' extent (millimetres from the translate): minimum and maximum.
    extent: Option<(Vertex, Vertex)>,
    /// The transform's translate and the `metadata` members (written at the end with the
    /// extent).
    translate: glam::DVec3,
    metadata: Vec<u8>,
}

impl<W: Write + Send> CityJsonWriter<W> {
    /// A writer to `out` that keeps the vertices in memory until `finish` (tests, small files).
    #[cfg(test)]
    pub(crate) fn new(out: W) -> CityJsonWriter<W> {
        CityJsonWriter::with_spool(out, Spool::Memory(Vec::new()), ScratchGuard(None))
    }

    /// A writer to `out` whose vertices wait in a scratch file beside `target` (the final
    /// output path, whose folder must exist), deleted when the writer is dropped (on Unix it is
    /// unlinked at once and only the open handle keeps it).
    pub(crate) fn beside(out: W, target: &Path) -> io::Result<CityJsonWriter<W>> {
        let (file, left) = crate::export::scratch_beside(target, "vertices")?;
        let guard = ScratchGuard(left);
        Ok(CityJsonWriter::with_spool(
            out,
            Spool::File(BufWriter::with_capacity(1 << 20, file)),
            guard,
        ))
    }

    fn with_spool(out: W, spool: Spool, guard: ScratchGuard) -> CityJsonWriter<W> {
        CityJsonWriter {
            out,
            state: State::New,
            lod: Lod::Lod2,
            spool,
            _guard: guard,
            shared: VertexMap::default(),
            count: 0,
            first: true,
            slots: Vec::new(),
            bufs: Vec::new(),
            tables: Vec::new(),
            vtext: Vec::new(),
            terrain: None,
            materials: Vec::new(),
            material_index: std::collections::HashMap::new(),
            mat_tables: Vec::new(),
            textures: false,
            tex: TextureOut::default(),
            texs: Vec::new(),
            tex_index: std::collections::HashMap::new(),
            tex_tables: Vec::new(),
            st_count: 0,
            st_spool: Spool::Memory(Vec::new()),
            _st_guard: ScratchGuard(None),
            extent: None,
            translate: glam::DVec3::ZERO,
            metadata: Vec::new(),
        }
    }

    /// With `Some((folder, used))`, walls and roofs carry the procedural textures
    /// (`--textures`, `crate::export::texture`): `appearance.textures` (PNG files in `folder`,
    /// relative to the output), `appearance.vertices-texture` and each solid's `texture` of
    /// theme `citygen`; the pictures are noted in `used` for the run to write. The texture
    /// vertices wait in a scratch file beside `target` (`None`: in memory).
    pub(crate) fn with_textures(
        mut self,
        on: Option<(String, crate::export::texture::TextureSet)>,
        target: Option<&Path>,
    ) -> io::Result<CityJsonWriter<W>> {
        let Some((folder, used)) = on else {
            return Ok(self);
        };
        self.textures = true;
        self.tex.folder = folder;
        self.tex.used = used;
        if let Some(target) = target {
            let (file, left) = crate::export::scratch_beside(target, "uv")?;
            self._st_guard = ScratchGuard(left);
            self.st_spool = Spool::File(BufWriter::with_capacity(1 << 20, file));
        }
        Ok(self)
    }

    /// Gives the sink back (complete after [`BuildingWriter::finish`]).
    #[cfg(test)]
    pub(crate) fn into_inner(self) -> W {
        self.out
    }

    /// Writes the buildings already rendered into `slots[..n]`: their vertices numbered in
    /// order (new ones spooled), their text spliced in parallel, then appended in order.
    fn append(&mut self, n: usize) -> Result<(), ExportError> {
        self.tables.resize_with(n.max(self.tables.len()), Vec::new);
        self.bufs.resize_with(n.max(self.bufs.len()), Vec::new);
        self.mat_tables
            .resize_with(n.max(self.mat_tables.len()), Vec::new);
        self.tex_tables
            .resize_with(n.max(self.tex_tables.len()), Vec::new);
        self.vtext.clear();
        let mut st_bases = Vec::with_capacity(n);
        for (frag, tt) in self.slots[..n].iter().zip(&mut self.tex_tables) {
            tt.clear();
            for &t in &frag.texs {
                let next = self.texs.len() as u64;
                let i = *self.tex_index.entry(t).or_insert(next);
                if i == next {
                    self.texs.push(t);
                }
                tt.push(i);
            }
            st_bases.push(self.st_count);
            for &st in &frag.sts {
                if self.st_count > 0 {
                    self.vtext.push(b',');
                }
                push_st_vertex(&mut self.vtext, st);
                self.st_count += 1;
            }
        }
        if !self.vtext.is_empty() {
            self.st_spool.write_all(&self.vtext)?;
            self.vtext.clear();
        }
        for (frag, mt) in self.slots[..n].iter().zip(&mut self.mat_tables) {
            mt.clear();
            for &k in &frag.mats {
                let next = self.materials.len() as u64;
                let i = *self.material_index.entry(k).or_insert(next);
                if i == next {
                    self.materials.push(k);
                }
                mt.push(i);
            }
        }
        for (frag, table) in self.slots[..n].iter().zip(&mut self.tables) {
            table.clear();
            let mut fresh = true;
            for &v in &frag.verts {
                if self.shared.len() >= SHARED_VERTICES {
                    self.shared.clear();
                }
                let next = self.count;
                let i = *self.shared.entry(v).or_insert(next);
                if i == next {
                    if self.count > 0 {
                        self.vtext.push(b',');
                    }
                    if fresh {
                        self.vtext.push(b'\n');
                        fresh = false;
                    }
                    push_vertex(&mut self.vtext, v);
                    self.count += 1;
                    self.extent = Some(match self.extent {
                        None => (v, v),
                        Some((lo, hi)) => (
                            (lo.0.min(v.0), lo.1.min(v.1), lo.2.min(v.2)),
                            (hi.0.max(v.0), hi.1.max(v.1), hi.2.max(v.2)),
                        ),
                    });
                }
                table.push(i);
            }
        }
        self.spool.write_all(&self.vtext)?;
        let first = self.first;
        let tex_tables = &self.tex_tables;
        self.slots[..n]
            .par_iter()
            .zip(self.tables[..n].par_iter())
            .zip(self.mat_tables[..n].par_iter())
            .zip(self.bufs[..n].par_iter_mut())
            .enumerate()
            .for_each(|(k, (((frag, table), mt), buf))| {
                buf.clear();
                buf.extend_from_slice(if first && k == 0 { b"\n" } else { b",\n" });
                let tt = &tex_tables[k];
                let texture = |ti: u32| tt[ti as usize];
                splice(
                    frag,
                    |li| table[li as usize],
                    |mi| mt[mi as usize],
                    (&texture, st_bases[k]),
                    buf,
                );
            });
        for buf in &self.bufs[..n] {
            self.out.write_all(buf)?;
        }
        self.first &= n == 0;
        Ok(())
    }
}

impl<W: Write + Send> BuildingWriter for CityJsonWriter<W> {
    fn begin(&mut self, ctx: &OutputContext) -> Result<(), ExportError> {
        check_state("CityJSON writer", self.state, State::New, "begin()")?;
        let (mut h, meta) = header(ctx, "CityJSON writer")?;
        h.extend_from_slice(b"\"CityObjects\":{");
        self.lod = ctx.lod;
        self.tex.tex = Texturing::of(self.textures, ctx.lod);
        self.terrain = terrain_of(ctx);
        self.translate = ctx.origin;
        self.metadata = meta;
        self.out.write_all(&h)?;
        self.state = State::Open;
        Ok(())
    }

    fn write(&mut self, building: &Building) -> Result<(), ExportError> {
        check_state("CityJSON writer", self.state, State::Open, "write()")?;
        check_finite("CityJSON writer", building)?;
        if self.slots.is_empty() {
            self.slots.push(Frag::default());
        }
        render::building(&mut self.slots[0], building, self.lod, self.tex.tex);
        self.append(1)
    }

    fn write_all(&mut self, buildings: &[Building]) -> Result<(), ExportError> {
        self.write_checked(&Checked::check(buildings))
    }

    /// Renders a batch (`super::batches`: at most `super::PARALLEL_BATCH` buildings) at a time in parallel and appends them in
    /// order: the same bytes as `write` on each.
    fn write_checked(&mut self, checked: &Checked<'_>) -> Result<(), ExportError> {
        check_state("CityJSON writer", self.state, State::Open, "write()")?;
        let (lod, tex) = (self.lod, self.tex.tex);
        for batch in super::batches(checked.finite()) {
            if self.slots.len() < batch.len() {
                self.slots.resize_with(batch.len(), Frag::default);
            }
            batch
                .par_iter()
                .zip(self.slots.par_iter_mut())
                .for_each(|(b, f)| render::building(f, b, lod, tex));
            self.append(batch.len())?;
        }
        checked.refused("CityJSON writer")
    }

    fn finish(&mut self) -> Result<(), ExportError> {
        check_state("CityJSON writer", self.state, State::Open, "finish()")?;
        if let Some((t, id)) = self.terrain.take() {
            if self.slots.is_empty() {
                self.slots.push(Frag::default());
            }
            render::terrain(&mut self.slots[0], &t, &id, terrain_lod(self.lod));
            self.append(1)?;
        }
        self.state = State::Finished;
        self.out.write_all(b"\n},")?;
        if !self.texs.is_empty() {
            let mut a = b"\"appearance\":{".to_vec();
            if !self.materials.is_empty() {
                materials(&mut a, &self.materials);
                a.push(b',');
            }
            textures(&mut a, &self.texs, &self.tex);
            a.extend_from_slice(b",\"vertices-texture\":[");
            self.out.write_all(&a)?;
            match std::mem::replace(&mut self.st_spool, Spool::Memory(Vec::new())) {
                Spool::Memory(v) => self.out.write_all(&v)?,
                Spool::File(w) => {
                    let mut file = w.into_inner().map_err(|e| e.into_error())?;
                    file.rewind()?;
                    io::copy(&mut file, &mut self.out)?;
                }
            }
            self.out.write_all(b"]},")?;
            note_used(&self.tex.used, self.texs.iter().copied());
        } else if !self.materials.is_empty() {
            let mut a = Vec::new();
            appearance(&mut a, &self.materials);
            a.push(b',');
            self.out.write_all(&a)?;
        }
        self.out.write_all(b"\"vertices\":[")?;
        match std::mem::replace(&mut self.spool, Spool::Memory(Vec::new())) {
            Spool::Memory(v) => self.out.write_all(&v)?,
            Spool::File(w) => {
                let mut file = w.into_inner().map_err(|e| e.into_error())?;
                file.rewind()?;
                io::copy(&mut file, &mut self.out)?;
            }
        }
        self.out.write_all(b"\n],\"metadata\":{")?;
        if let Some((lo, hi)) = self.extent {
            let t = self.translate;
            let at = |v: Vertex| [v.0, v.1, v.2].map(|c| c as f64 * 0.001);
            let (lo, hi) = (at(lo), at(hi));
            let e = format!(
                "\"geographicalExtent\":[{:.3},{:.3},{:.3},{:.3},{:.3},{:.3}],",
                t.x + lo[0],
                t.y + lo[1],
                t.z + lo[2],
                t.x + hi[0],
                t.y + hi[1],
                t.z + hi[2]
            );
            self.out.write_all(e.as_bytes())?;
        }
        self.out.write_all(&self.metadata)?;
        self.out.write_all(b"}}\n")?;
        self.out.flush()?;
        self.shared = VertexMap::default();
        self.slots = Vec::new();
        self.bufs = Vec::new();
        self.tables = Vec::new();
        Ok(())
    }
}

/// Streaming CityJSONSeq writer (`.city.jsonl`, see the module documentation): the header
/// line, then one `CityJSONFeature` line per building with its own vertices.
pub(crate) struct CityJsonSeqWriter<W: Write + Send> {
    out: W,
    state: State,
    lod: Lod,
    slots: Vec<(Frag, Vec<u8>)>,
    /// The file's terrain and its id, its own feature after the buildings'.
    terrain: Option<(std::sync::Arc<crate::model::Terrain>, String)>,
    /// `--textures` ([`CityJsonSeqWriter::with_textures`]) and how.
    textures: bool,
    tex: TextureOut,
}

impl<W: Write + Send> CityJsonSeqWriter<W> {
    /// A writer to `out`.
    pub(crate) fn new(out: W) -> CityJsonSeqWriter<W> {
        CityJsonSeqWriter {
            out,
            state: State::New,
            lod: Lod::Lod2,
            slots: Vec::new(),
            terrain: None,
            textures: false,
            tex: TextureOut::default(),
        }
    }

    /// With `Some((folder, used))`, walls and roofs carry the procedural textures
    /// (`--textures`) as in [`CityJsonWriter::with_textures`], each feature with its own
    /// pictures and texture vertices in its own `appearance`.
    pub(crate) fn with_textures(
        mut self,
        on: Option<(String, crate::export::texture::TextureSet)>,
    ) -> CityJsonSeqWriter<W> {
        if let Some((folder, used)) = on {
            self.textures = true;
            self.tex.folder = folder;
            self.tex.used = used;
        }
        self
    }

    /// Gives the sink back (complete after [`BuildingWriter::finish`]).
    #[cfg(test)]
    pub(crate) fn into_inner(self) -> W {
        self.out
    }
}

/// The terrain the context gives, with its id.
fn terrain_of(ctx: &OutputContext) -> Option<(std::sync::Arc<crate::model::Terrain>, String)> {
    let t = ctx.terrain.clone()?;
    let id = crate::export::ids::terrain_id(&t, ctx.origin);
    Some((t, id))
}

/// The lod of the terrain's surface: the run's (CityJSON has none past 3).
fn terrain_lod(lod: Lod) -> &'static str {
    match lod {
        Lod::Lod1 => "1",
        Lod::Lod2 => "2",
        Lod::Lod3 | Lod::Lod4 => "3",
    }
}

/// One building's `CityJSONFeature` line into `buf`.
fn feature(frag: &mut Frag, buf: &mut Vec<u8>, b: &Building, lod: Lod, tex: &TextureOut) {
    render::building(frag, b, lod, tex.tex);
    feature_line(frag, buf, tex);
}

/// The `CityJSONFeature` line of a rendered fragment into `buf`, with its own vertices and
/// appearance (materials, and with `--textures` its pictures and texture vertices: the
/// appearance of a CityJSONFeature is its own, local, as its vertices).
fn feature_line(frag: &Frag, buf: &mut Vec<u8>, tex: &TextureOut) {
    buf.clear();
    buf.extend_from_slice(b"{\"type\":\"CityJSONFeature\",\"id\":");
    // Writing a &str to a Vec cannot fail.
    let _ = serde_json::to_writer(&mut *buf, &frag.id);
    buf.extend_from_slice(b",\"CityObjects\":{");
    splice(frag, u64::from, u64::from, (&u64::from, 0), buf);
    buf.extend_from_slice(b"},");
    if !frag.texs.is_empty() {
        buf.extend_from_slice(b"\"appearance\":{");
        if !frag.mats.is_empty() {
            materials(buf, &frag.mats);
            buf.push(b',');
        }
        textures(buf, &frag.texs, tex);
        buf.extend_from_slice(b",\"vertices-texture\":[");
        for (i, st) in frag.sts.iter().enumerate() {
            if i > 0 {
                buf.push(b',');
            }
            push_st_vertex(buf, *st);
        }
        buf.extend_from_slice(b"]},");
    } else if !frag.mats.is_empty() {
        appearance(buf, &frag.mats);
        buf.push(b',');
    }
    buf.extend_from_slice(b"\"vertices\":[");
    for (i, v) in frag.verts.iter().enumerate() {
        if i > 0 {
            buf.push(b',');
        }
        push_vertex(buf, *v);
    }
    buf.extend_from_slice(b"]}\n");
}

impl<W: Write + Send> BuildingWriter for CityJsonSeqWriter<W> {
    fn begin(&mut self, ctx: &OutputContext) -> Result<(), ExportError> {
        check_state("CityJSONSeq writer", self.state, State::New, "begin()")?;
        let (mut h, meta) = header(ctx, "CityJSONSeq writer")?;
        h.extend_from_slice(b"\"metadata\":{");
        h.extend_from_slice(&meta);
        h.extend_from_slice(b"},\"CityObjects\":{},\"vertices\":[]}\n");
        self.lod = ctx.lod;
        self.tex.tex = Texturing::of(self.textures, ctx.lod);
        self.terrain = terrain_of(ctx);
        self.out.write_all(&h)?;
        self.state = State::Open;
        Ok(())
    }

    fn write(&mut self, building: &Building) -> Result<(), ExportError> {
        check_state("CityJSONSeq writer", self.state, State::Open, "write()")?;
        check_finite("CityJSONSeq writer", building)?;
        if self.slots.is_empty() {
            self.slots.push(Default::default());
        }
        let (frag, buf) = &mut self.slots[0];
        feature(frag, buf, building, self.lod, &self.tex);
        note_used(&self.tex.used, frag.texs.iter().copied());
        self.out.write_all(buf)?;
        Ok(())
    }

    fn write_all(&mut self, buildings: &[Building]) -> Result<(), ExportError> {
        self.write_checked(&Checked::check(buildings))
    }

    /// Renders a batch (`super::batches`: at most `super::PARALLEL_BATCH` buildings) at a time in parallel and writes them in
    /// order: the same bytes as `write` on each.
    fn write_checked(&mut self, checked: &Checked<'_>) -> Result<(), ExportError> {
        check_state("CityJSONSeq writer", self.state, State::Open, "write()")?;
        let (lod, tex) = (self.lod, &self.tex);
        for batch in super::batches(checked.finite()) {
            if self.slots.len() < batch.len() {
                self.slots.resize_with(batch.len(), Default::default);
            }
            batch
                .par_iter()
                .zip(self.slots.par_iter_mut())
                .for_each(|(b, (frag, buf))| feature(frag, buf, b, lod, tex));
            for (frag, buf) in &self.slots[..batch.len()] {
                if !frag.texs.is_empty() {
                    note_used(&self.tex.used, frag.texs.iter().copied());
                }
                self.out.write_all(buf)?;
            }
        }
        checked.refused("CityJSONSeq writer")
    }

    fn finish(&mut self) -> Result<(), ExportError> {
        check_state("CityJSONSeq writer", self.state, State::Open, "finish()")?;
        if let Some((t, id)) = self.terrain.take() {
            let (mut frag, mut buf) = (Frag::default(), Vec::new());
            render::terrain(&mut frag, &t, &id, terrain_lod(self.lod));
            feature_line(&frag, &mut buf, &self.tex);
            self.out.write_all(&buf)?;
        }
        self.state = State::Finished;
        self.out.flush()?;
        self.slots = Vec::new();
        Ok(())
    }
}

#[cfg(test)]
mod tests;
