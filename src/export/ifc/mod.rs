//! IFC writer (STEP Part 21), streaming one [`Building`] at a time: IFC4 by default, IFC2X3
//! or IFC4X3_ADD2 with [`IfcWriter::with_schema`] (what differs is in `schema`; the layout
//! below is IFC4's).
//!
//! Layout of a file:
//!
//! - `IfcProject` (SI units: metre, square metre, cubic metre, radian) with a 3D `Model` context,
//!   its `Body` (MODEL_VIEW) and `Axis` (GRAPH_VIEW) sub-contexts, and an `IfcMapConversion`
//!   from the project's engineering frame to an `IfcProjectedCRS` named `EPSG:n`: the model's
//!   (0, 0, 0) is at [`OutputContext::origin`] in that CRS, its height the map conversion's
//!   `OrthogonalHeight`. When the run states a vertical datum
//!   ([`OutputContext::vertical_datum`]), the CRS's `VerticalDatum` is its `EPSG:n` (its name
//!   when the code is unknown) and its description `<horizontal name> + <vertical name>`: the
//!   heights, `OrthogonalHeight` included, are in that datum.
//! - One `IfcSite` at the local origin, with `RefLatitude`/`RefLongitude` from
//!   [`OutputContext::origin_lonlat`].
//! - Per building, an `IfcBuilding` placed (relative to the site) at the first vertex of its first
//!   part's footprint, at the building's base height. A building with one part holds its storeys
//!   directly; a building with several parts aggregates one partial `IfcBuilding`
//!   (`.PARTIAL.`) per part, each holding its own storeys, and carries no geometry itself.
//! - Per part: `IfcBuildingStorey`s (one per storey, equally spaced between the part's base and
//!   eave; `Storey 0` at the base). All elements of the part are contained in `Storey 0`: walls
//!   span the full height.
//! - Walls are `IfcWallStandardCase`: placed at the wall start with X along the wall, an `Axis`
//!   (`Curve2D` polyline from (0,0) to (length,0)) and a `Body`. A rectangular wall is an
//!   `IfcRectangleProfileDef` (length x thickness) extruded up; the body lies on the +Y side of
//!   the axis, which is the inside of the footprint since the model puts the outside on the right
//!   of start->end. A gable wall (any other outline) is its outline, as an
//!   `IfcArbitraryClosedProfileDef` in the wall's vertical plane, extruded by the thickness
//!   towards the inside. Every wall is associated to an `IfcMaterialLayerSetUsage`
//!   (AXIS2, POSITIVE, offset 0) of a one-layer set of its thickness, shared file-wide per
//!   thickness.
//! - The ground is an `IfcSlab` `.BASESLAB.`: the footprint (with courtyards as voids) extruded
//!   **downwards** by 0.2 m, so that its top face is the model's ground surface and it does not
//!   overlap the walls.
//! - The roof is an `IfcRoof`. A sloped roof whose faces, closed by the footprint at eave height,
//!   form a closed shell is one `IfcFacetedBrep` (`Brep`). Flat roof faces become thin closed
//!   prisms (0.2 m, or less for very low parts) hanging below the roof surface, also
//!   `IfcFacetedBrep`. Any other roof (e.g. gabled roofs, whose gable triangles belong to the
//!   walls) is an `IfcShellBasedSurfaceModel` of an `IfcOpenShell` (`SurfaceModel`).
//! - Colours and materials: one `IfcSurfaceStyle` per distinct (colour, surface material) in the
//!   file, applied through `IfcStyledItem` to wall and roof bodies: an `IfcSurfaceStyleShading`
//!   of the colour when no material is known, else an `IfcSurfaceStyleRendering` of the colour
//!   with the material's `SpecularHighlight` (`IfcSpecularRoughness`, its PBR roughness) and
//!   `ReflectanceMethod` (`METAL`, `GLASS`, `MATT`), named `#rrggbb <material>` — the table of
//!   `crate::color::material` that the glTF's `pbrMetallicRoughness` comes from (walls: the
//!   part's `wall_material`, roofs its `roof_material`).
//! - Per building, property sets `Citygen_Source` (SourceId, Zone, Appearance, MeasuredHeight,
//!   Lod, RoofShape, and the provenance of storeys, height and roof: StoreysSource,
//!   HeightSource, RoofSource as `IfcLabel`s `tag`/`neighbours`/`fitted`/`model`/`kb`,
//!   StoreysError `IfcReal` ± storeys, HeightError `IfcLengthMeasure` ± metres, RoofProbability
//!   `IfcNormalisedRatioMeasure`, each uncertainty left out when unknown) and `Pset_BuildingCommon` (NumberOfStoreys), per partial
//!   building a `Citygen_Part` (Height and MinHeight above the building's ground, NumberOfStoreys,
//!   RoofShape, and SourceId and SourceRole where the part is traced), and per building a
//!   `Pset_WallCommon` with IsExternal true on its walls and false on those wholly against a
//!   neighbour (`Wall::party` 1, LOD3), and `Citygen_Wall` (PartyWallShare, one set per
//!   share) on every wall that faces a neighbour.
//! - Base quantities (`quantities`): `Qto_BuildingBaseQuantities` (Height, EavesHeight,
//!   FootprintArea, GrossFloorArea, GrossVolume) on every building and
//!   `Qto_BuildingStoreyBaseQuantities` (GrossHeight, GrossPerimeter, GrossFloorArea,
//!   GrossVolume) on every storey, measured on the model; LOD4 spaces have
//!   `Qto_SpaceBaseQuantities`.
//!
//! At LOD3 (`OutputContext::lod >= Lod3`) a part is written differently (LOD1/LOD2 files are
//! unchanged):
//!
//! - One `IfcBuildingStorey` per entry of [`Part::levels`](crate::model::Part::levels) (`Storey i`, Elevation relative to
//!   the building's placement). Each wall is placed in, and contained in, the storey
//!   [`Wall::storey`](crate::model::Wall::storey) names; the base slab is in the first storey, the roof in the top one.
//! - Each [`Opening`](crate::model::Opening) is an `IfcOpeningElement` `.OPENING.` placed relative to its wall (at
//!   (u0, -tolerance, z0 - wall base) in the wall's frame: X along the wall, Y into the wall
//!   body, Z up), whose body is the opening's rectangle extruded across the wall, 1 cm past
//!   each face; `IfcRelVoidsElement(wall, opening)`. It is filled (`IfcRelFillsElement`) by an
//!   `IfcWindow` `.WINDOW.` or `IfcDoor` `.DOOR.` (OverallHeight/OverallWidth = the
//!   opening's) placed relative to the opening, centred in it and in the wall's depth, and
//!   contained in the wall's storey.
//! - Windows and doors of one kind (kind, size floored to the cm, frame depth, glazed, framed,
//!   colours) share one `IfcWindowType`/`IfcDoorType` holding one `IfcRepresentationMap`: a
//!   frame (`IfcRectangleHollowProfileDef` extruded 8 cm deep) and a glass pane or door panel,
//!   or a single pane/panel when unframed, styled with `IfcSurfaceStyleRendering` (glass 65 %
//!   transparent, with glass's `SpecularHighlight` and `ReflectanceMethod` `GLASS`; styles
//!   cached per colour, transparency and material). Every occurrence references the
//!   same `IfcProductDefinitionShape` (one `IfcMappedItem` of the map), so a window costs its
//!   placement and relationships only. The `IfcRelDefinesByType` of each type (a type has at
//!   most one) and an `IfcRelDeclares` of all types in the project are written by `finish`.
//!   Opening bodies are shared the same way per (width, height, wall thickness).
//! - A [`Balcony`](crate::model::Balcony) is an `IfcSlab` `.FLOOR.` named `Balcony` (its rectangle, 15 cm thick, top
//!   at the balcony's floor height, outside the wall) and an `IfcRailing` `.BALUSTRADE.` (1 m
//!   high, 5 cm thick, on the three free edges), both contained in the wall's storey.
//! - A wall's window sills (`crate::export::lod3geom::sills`: a box under each raised window,
//!   6 cm out of the wall, 5 cm thick, its top at the window's bottom edge) are one
//!   `IfcBuildingElementProxy` named `Window sills` (IFC4 and later `.USERDEFINED.` with
//!   ObjectType `WindowSill`; IFC has no sill entity, and a sill in the window type's body would
//!   make a type per wall thickness), one `IfcExtrudedAreaSolid` per sill, contained in the
//!   wall's storey.
//! - Glazed facades are not written as `IfcCurtainWall`: windows only.
//!
//! At LOD4 a part's interiors are added to its LOD3 storeys (spaces, partition walls, interior
//! doors, stairs, upper floor slabs) by the child module `lod4` (see there).
//!
//! A context with a terrain gets it as an `IfcGeographicElement` `.TERRAIN.` in the site, its
//! body an `IfcTriangulatedFaceSet` (`terrain`), written by `finish`.
//!
//! GlobalIds are deterministic (`global_id`) from the building key and the element's path, so
//! equal inputs give byte-identical files. Memory held between buildings: the list of top-level
//! building ids (8 bytes each), the hashes of the building keys seen (16 bytes each), the caches of shared styles and material
//! usages, and at LOD3 the shared opening shapes and fill offsets (at most
//! `SHARED_CACHE_LIMIT` each) and the window/door types with the ids of their occurrences
//! (8 bytes per window or door, for the final `IfcRelDefinesByType`: IFC4 allows one such
//! relation per type, so they cannot be flushed per building).
//!
//! Code layout: this module holds the writer, its state and the constants; the child modules
//! add to the open file's `impl` what they write: `spatial` (project, site, buildings, storeys,
//! parts), `walls` (walls, balconies), `openings` (openings, windows, doors and their types),
//! `roofs` (base slab, roof), `styles` (styles, materials, property sets), `shapes` (points,
//! placements, profiles, breps), `lod4` (interiors) and `schema` (what differs between the
//! schemas).

use std::collections::{BTreeMap, BTreeSet};
use std::io::Write;

use glam::DVec3;

use rayon::prelude::*;

use crate::color::material::Material;
use crate::export::step::{hash128, Id, StepBuf, StepWriter};
use crate::export::{BuildingWriter, Checked, ExportError, OutputContext, PARALLEL_BATCH};
use crate::model::{Building, RoofShape};

use cache::{Cache, Log, View};
use openings::TypeKey;
pub use schema::{IfcSchema, UnknownSchema};

mod cache;
mod lod4;
mod openings;
mod quantities;
mod roofs;
mod schema;
mod shapes;
mod spatial;
mod styles;
mod terrain;
mod trim;
mod walls;

/// Thickness of the base slab, extruded down from the ground surface (metres).
const SLAB_THICKNESS: f64 = 0.2;
/// Thickness of flat roof slabs, hanging below the roof surface (metres).
const FLAT_ROOF_THICKNESS: f64 = 0.2;
/// Lengths below this are treated as zero (metres); matches the context precision order.
const EPS: f64 = 1e-4;
/// A part never gets more storeys than this, whatever its `storeys` says.
const MAX_STOREYS: u32 = 200;
/// How far an opening's body reaches past each face of its wall (metres), so that the boolean
/// cut never leaves a skin of wall behind.
const OPENING_TOLERANCE: f64 = 0.01;
/// Depth of a window or door frame across the wall (metres; less in thinner walls).
const FRAME_DEPTH: f64 = 0.08;
/// Width of a window or door frame in the wall's plane (metres; less for tiny openings).
const FRAME_WIDTH: f64 = 0.06;
/// Thickness of a glass pane (metres).
const GLASS_THICKNESS: f64 = 0.02;
/// Thickness of a door panel (metres).
const PANEL_THICKNESS: f64 = 0.04;
/// Transparency of glass in its surface style (1 = invisible).
const GLASS_TRANSPARENCY: f64 = 0.65;
/// Thickness of a balcony slab, hanging below its floor height (metres).
const BALCONY_THICKNESS: f64 = 0.15;
/// Height of a balcony railing above the slab (metres).
const RAILING_HEIGHT: f64 = 1.0;
/// Thickness of a balcony railing (metres).
const RAILING_THICKNESS: f64 = 0.05;

/// Streaming IFC writer (IFC4 unless [`IfcWriter::with_schema`] says otherwise). See the module documentation for what it writes.
///
/// ```no_run
/// use citygen::export::{AtomicFile, BuildingWriter, ifc::IfcWriter};
/// # fn f(ctx: &citygen::export::OutputContext, buildings: &[citygen::model::Building]) -> Result<(), Box<dyn std::error::Error>> {
/// let file = AtomicFile::create(std::path::Path::new("out.ifc"))?;
/// let mut w = IfcWriter::new(file.writer()?).with_file_name("out.ifc");
/// w.begin(ctx)?;
/// for b in buildings { w.write(b)?; }
/// w.finish()?;
/// drop(w);
/// file.commit()?;
/// # Ok(()) }
/// ```
pub struct IfcWriter<W: Write + Send> {
    state: State<W>,
    file_name: String,
    /// [`SHARED_CACHE_LIMIT`], smaller in tests.
    cache_limit: usize,
    /// The most bytes the file may have ([`IfcWriter::with_max_bytes`]).
    max_bytes: Option<u64>,
    schema: IfcSchema,
}

enum State<W: Write + Send> {
    New(W),
    Open(Box<Open<W>>),
    Done(W),
    /// Transient, while moving between states (also left behind by a failed `finish`).
    Gone,
}

impl<W: Write + Send> IfcWriter<W> {
    /// A writer onto `out`. Nothing is written before [`BuildingWriter::begin`].
    pub fn new(out: W) -> IfcWriter<W> {
        IfcWriter {
            state: State::New(out),
            file_name: "citygen.ifc".to_string(),
            cache_limit: SHARED_CACHE_LIMIT,
            max_bytes: None,
            schema: IfcSchema::Ifc4,
        }
    }

    /// Sets the schema written (default IFC4).
    pub fn with_schema(mut self, schema: IfcSchema) -> IfcWriter<W> {
        self.schema = schema;
        self
    }

    /// Caps the file at `max` bytes (`--ifc-max-mb`): `IfcWriter::write_fitting` then
    /// writes a building only if the file, finished, would stay within `max` (the file's first
    /// building always, however large), and the file's terrain goes first, after the project,
    /// so that its bytes count from the start. Without a cap every byte is as before.
    pub fn with_max_bytes(mut self, max: u64) -> IfcWriter<W> {
        self.max_bytes = Some(max);
        self
    }

    /// Writes the leading buildings of `finite` (buildings a [`Checked`] found finite, in
    /// order) that fit under the cap of [`IfcWriter::with_max_bytes`] (all of them without
    /// one) and returns how many it wrote: fewer than `finite.len()` when the next would
    /// take the finished file past the cap. The file's first building is always written.
    pub(crate) fn write_fitting(&mut self, finite: &[Building]) -> Result<usize, ExportError> {
        match &mut self.state {
            State::Open(open) => {
                let mut done = 0;
                for batch in crate::export::batches(finite) {
                    let n = open.write_batch(batch)?;
                    done += n;
                    if n < batch.len() {
                        break;
                    }
                }
                Ok(done)
            }
            _ => Err(ExportError::Invalid(
                "IFC writer: write called outside begin..finish".into(),
            )),
        }
    }

    /// Sets the name written in the header's FILE_NAME (default `citygen.ifc`).
    pub fn with_file_name(mut self, name: &str) -> IfcWriter<W> {
        self.file_name = name.to_string();
        self
    }

    /// Hands the output back after [`BuildingWriter::finish`] (e.g. to commit an
    /// [`crate::export::AtomicFile`]). Fails if `finish` did not complete.
    pub fn into_inner(self) -> Result<W, ExportError> {
        match self.state {
            State::Done(w) => Ok(w),
            _ => Err(ExportError::Invalid(
                "IFC writer: into_inner called before finish completed".into(),
            )),
        }
    }
}

impl<W: Write + Send> BuildingWriter for IfcWriter<W> {
    fn begin(&mut self, ctx: &OutputContext) -> Result<(), ExportError> {
        let out = match std::mem::replace(&mut self.state, State::Gone) {
            State::New(out) => out,
            other => {
                self.state = other;
                return Err(ExportError::Invalid(
                    "IFC writer: begin called twice".into(),
                ));
            }
        };
        let mut open = Open::begin(out, ctx, &self.file_name, self.schema)?;
        open.caches.opening_shapes.set_limit(self.cache_limit);
        open.caches.fill_offsets.set_limit(self.cache_limit);
        open.max_bytes = self.max_bytes;
        if self.max_bytes.is_some() {
            // Under a cap the terrain's bytes are counted before any building's.
            if let Some(t) = open.terrain.take() {
                open.terrain(&t)?;
            }
        }
        self.state = State::Open(Box::new(open));
        Ok(())
    }

    fn write(&mut self, building: &Building) -> Result<(), ExportError> {
        self.write_all(std::slice::from_ref(building))
    }

    /// Renders a batch of buildings at a time in parallel (`crate::export::batches`: at most
    /// `PARALLEL_BATCH`, fewer when they are large), each against the shared
    /// caches as the batch found them (see `cache`), and appends them in order; a building
    /// whose rendering did not see the caches as the buildings before it left them is rendered
    /// again. The same bytes as `write` on each.
    fn write_all(&mut self, buildings: &[Building]) -> Result<(), ExportError> {
        self.write_checked(&Checked::check(buildings))
    }

    fn write_checked(&mut self, checked: &Checked<'_>) -> Result<(), ExportError> {
        match &mut self.state {
            State::Open(open) => {
                for batch in crate::export::batches(checked.finite()) {
                    if open.write_batch(batch)? < batch.len() {
                        return Err(ExportError::Invalid(
                            "IFC writer: the file is full (--ifc-max-mb); write_fitting writes a \
                             capped file"
                                .into(),
                        ));
                    }
                }
                checked.refused("IFC writer")
            }
            _ => Err(ExportError::Invalid(
                "IFC writer: write called outside begin..finish".into(),
            )),
        }
    }

    fn finish(&mut self) -> Result<(), ExportError> {
        match std::mem::replace(&mut self.state, State::Gone) {
            State::Open(open) => {
                let out = open.finish()?;
                self.state = State::Done(out);
                Ok(())
            }
            other => {
                self.state = other;
                Err(ExportError::Invalid(
                    "IFC writer: finish called without begin, or twice".into(),
                ))
            }
        }
    }
}

impl<W: Write> Open<W> {
    /// Writes `batch` (at most [`PARALLEL_BATCH`] buildings, checked finite): the same bytes
    /// and first error as writing them one by one. Returns how many it wrote: all, unless the
    /// file has a cap ([`Open::max_bytes`]) that the next building would pass.
    fn write_batch(&mut self, batch: &[Building]) -> Result<usize, ExportError> {
        // GlobalId keys, in order.
        let keys: Vec<(String, u128)> = batch.iter().map(|b| self.claim_key(b)).collect();
        let start = self.w.next_number();
        let scratch: Vec<Scratch> = (0..batch.len())
            .map(|_| self.pool.pop().unwrap_or_default())
            .collect();
        let (g, caches) = (&self.g, &self.caches);
        // The first building sees the caches as they are and knows its first number.
        let rendered: Vec<Rendered> = if batch.len() > 1 {
            batch
                .par_iter()
                .zip(&keys)
                .zip(scratch)
                .enumerate()
                .map(|(i, ((b, k), s))| render(g, caches, b, &k.0, (i == 0).then_some(start), s))
                .collect()
        } else {
            batch
                .iter()
                .zip(&keys)
                .zip(scratch)
                .map(|((b, k), s)| render(g, caches, b, &k.0, Some(start), s))
                .collect()
        };
        for (i, r) in rendered.into_iter().enumerate() {
            let r = if r.inexact || !r.logs.holds(&self.caches) {
                let start = Some(self.w.next_number());
                let again = render(
                    &self.g,
                    &self.caches,
                    &batch[i],
                    &keys[i].0,
                    start,
                    Scratch::default(),
                );
                self.keep(r.into_scratch());
                again
            } else {
                r
            };
            if self
                .max_bytes
                .is_some_and(|cap| !self.buildings.is_empty() && self.bytes_with(&r) > cap)
            {
                // Full: this building and the ones after it go to another file.
                for (_, h) in &keys[i..] {
                    self.keys.remove(h);
                }
                self.keep(r.into_scratch());
                return Ok(i);
            }
            if let Err(e) = self.append(r) {
                // The buildings after it were not written: their keys are free again.
                for (_, h) in &keys[i + 1..] {
                    self.keys.remove(h);
                }
                return Err(e.for_building(&batch[i]));
            }
        }
        Ok(batch.len())
    }

    /// At least the bytes of the file finished after appending `r`: those written, `r`'s
    /// text, and what `finish` writes (the site's aggregation of every building, a
    /// `IfcRelDefinesByType` per window and door type listing its occurrences, the
    /// declaration of the types, the trailer), each reference counted at the digits of the
    /// largest number it can get.
    fn bytes_with(&self, r: &Rendered) -> u64 {
        use crate::export::step::{decimal_digits, TRAILER_LEN};
        // An entity's text apart from its list of references: its number, keyword,
        // GlobalId and the few single references.
        const ENTITY: u64 = 200;
        let start = self.w.next_number();
        let text = r.w.appended_len_bound(start);
        // Every new type has an occurrence in `r`.
        let types = (self.caches.types.map.len() + r.occurrences.len()) as u64;
        let last = start + r.w.len() + types + 3;
        // `#n,` per reference in a list.
        let reference = decimal_digits(last) + 2;
        let references = self.buildings.len() as u64
            + 1
            + self.occurrence_count
            + r.occurrences.len() as u64
            + types;
        self.w.bytes_written() + text + ENTITY * (2 + types) + reference * references + TRAILER_LEN
    }

    /// The GlobalId key of `b` (its [`Building::key`], with a suffix when a building before
    /// had the same, so that ids stay unique) and its hash, now taken.
    fn claim_key(&mut self, b: &Building) -> (String, u128) {
        let first = b.key();
        let mut key = first.clone();
        let mut n = 1;
        loop {
            let h = hash128("building key", &key);
            if self.keys.insert(h) {
                return (key, h);
            }
            n += 1;
            key = format!("{first}~{n}");
        }
    }

    /// Writes a rendered building and applies its cache insertions; its error if it had one
    /// (after the entities before the failure).
    fn append(&mut self, mut r: Rendered) -> Result<(), ExportError> {
        let start = self.w.append(&r.w)?;
        r.logs.commit(&mut self.caches, start);
        for &(k, id) in &r.occurrences {
            self.occurrences
                .entry(k)
                .or_default()
                .push(id.relocate(start));
        }
        self.occurrence_count += r.occurrences.len() as u64;
        let done = std::mem::replace(&mut r.done, Ok(Id(0)));
        self.keep(r.into_scratch());
        let building = done?;
        self.buildings.push(building.relocate(start));
        Ok(())
    }

    /// Keeps the storage of a rendered building for reuse, unless it is large.
    fn keep(&mut self, s: Scratch) {
        if s.w.capacity() <= SCRATCH_KEPT && self.pool.len() < PARALLEL_BATCH {
            self.pool.push(s);
        }
    }
}

impl Rendered {
    fn into_scratch(self) -> Scratch {
        Scratch {
            w: self.w,
            logs: self.logs,
            occurrences: self.occurrences,
        }
    }
}

impl ExportError {
    /// An error of the IFC writer on building `b`: an entity that would break a schema rule (a
    /// zero length) ends the file with an error naming the building, never as an invalid file.
    fn for_building(self, b: &Building) -> ExportError {
        match self {
            ExportError::Io(io) => match crate::export::step::broken_rule(&io) {
                Some(rule) => {
                    ExportError::Invalid(format!("IFC writer: building {}: {rule}", b.id))
                }
                None => ExportError::Io(io),
            },
            other => other,
        }
    }
}

/// Renders building `b` (checked finite, GlobalId key `key`) against the caches as they are,
/// its first entity numbered `start` if known.
/// `scratch` is storage to reuse (of a building appended before).
fn render(
    g: &Globals,
    caches: &Caches,
    b: &Building,
    key: &str,
    start: Option<u64>,
    scratch: Scratch,
) -> Rendered {
    let Scratch {
        mut w,
        logs: l,
        mut occurrences,
    } = scratch;
    w.clear();
    occurrences.clear();
    let mut r = Render {
        g,
        w,
        usages: caches.usages.view(l.usages),
        styles: caches.styles.view(l.styles),
        shared: Lod3Views {
            vertical: caches.vertical.view(l.vertical),
            identity_op: caches.identity_op.view(l.identity_op),
            opening_shapes: caches.opening_shapes.view(l.opening_shapes),
            fill_offsets: caches.fill_offsets.view(l.fill_offsets),
            renderings: caches.renderings.view(l.renderings),
            types: caches.types.view(l.types),
        },
        occurrences,
        start,
        inexact: false,
    };
    let done = r.building(b, key);
    let s = r.shared;
    Rendered {
        w: r.w,
        logs: Logs {
            usages: r.usages.into_log(),
            styles: r.styles.into_log(),
            vertical: s.vertical.into_log(),
            identity_op: s.identity_op.into_log(),
            opening_shapes: s.opening_shapes.into_log(),
            fill_offsets: s.fill_offsets.into_log(),
            renderings: s.renderings.into_log(),
            types: s.types.into_log(),
        },
        occurrences: r.occurrences,
        inexact: r.inexact,
        done,
    }
}

/// The IFC4 `IfcRoofTypeEnum` value for a roof shape.
pub(crate) fn roof_type(shape: RoofShape) -> &'static str {
    match shape {
        RoofShape::Flat => "FLAT_ROOF",
        RoofShape::Skillion => "SHED_ROOF",
        RoofShape::Gabled
        | RoofShape::Saltbox
        | RoofShape::GabledHeightMoved
        | RoofShape::BellcastGable
        | RoofShape::ApseGabled => "GABLE_ROOF",
        RoofShape::Hipped | RoofShape::SideHipped => "HIP_ROOF",
        RoofShape::HalfHipped | RoofShape::SideHalfHipped | RoofShape::HippedAndGabled => {
            "HIPPED_GABLE_ROOF"
        }
        RoofShape::Butterfly => "BUTTERFLY_ROOF",
        RoofShape::Pyramidal => "PAVILION_ROOF",
        RoofShape::Mansard => "MANSARD_ROOF",
        RoofShape::Gambrel => "GAMBREL_ROOF",
        RoofShape::Dome => "DOME_ROOF",
        RoofShape::Round => "BARREL_ROOF",
        RoofShape::Onion | RoofShape::Cone | RoofShape::Crosspitched | RoofShape::Sawtooth => {
            "FREEFORM"
        }
    }
}

/// An angle in decimal degrees as an `IfcCompoundPlaneAngleMeasure`: degrees, minutes, seconds,
/// millionths of a second, all carrying the sign of the angle (as the schema's WHERE rule wants).
/// `None` for a non-finite angle or one outside (-360, 360).
pub(crate) fn compound_angle(deg: f64) -> Option<[i64; 4]> {
    if !deg.is_finite() || deg.abs() >= 360.0 {
        return None;
    }
    let total = (deg.abs() * 3600.0 * 1e6).round() as i64;
    let sign = if deg < 0.0 { -1 } else { 1 };
    let micro = total % 1_000_000;
    let secs = total / 1_000_000;
    let parts = [secs / 3600, secs / 60 % 60, secs % 60, micro];
    if parts[0] >= 360 {
        return None; // rounding carried it to 360
    }
    Some(parts.map(|v| v * sign))
}

/// The state of an open file: the STEP writer, shared entities, caches and what `finish` needs.
struct Open<W: Write> {
    w: StepWriter<W>,
    g: Globals,
    site: Id,
    project: Id,
    caches: Caches,
    /// The occurrences of each window and door type, for the final `IfcRelDefinesByType`s.
    occurrences: BTreeMap<TypeKey, Vec<Id>>,
    /// Top-level buildings, for the final site aggregation.
    buildings: Vec<Id>,
    /// Storage of rendered buildings for the next batches to reuse (at most a batch of
    /// buffers of at most [`SCRATCH_KEPT`] bytes each).
    pool: Vec<Scratch>,
    /// 128-bit hashes of the building keys already written, to keep GlobalIds unique if a key
    /// repeats (16 bytes a building rather than the key's string).
    keys: BTreeSet<u128>,
    /// The file's terrain, written by `finish` (`terrain`; by `begin` in a capped file).
    terrain: Option<std::sync::Arc<crate::model::Terrain>>,
    /// The cap of [`IfcWriter::with_max_bytes`].
    max_bytes: Option<u64>,
    /// Window and door occurrences written (the entries of `occurrences`).
    occurrence_count: u64,
}

/// The entities and settings of the file that every building refers to, written by `begin`.
struct Globals {
    /// GlobalId namespace of project-level objects (the source name).
    ns: String,
    origin3: Id,
    origin2: Id,
    dir_x: Id,
    dir_z: Id,
    dir_neg_y: Id,
    dir_neg_z: Id,
    /// `IfcAxis2Placement3D(origin, $, $)`.
    identity: Id,
    body_ctx: Id,
    axis_ctx: Id,
    site_placement: Id,
    wall_material: Id,
    /// `OutputContext::origin.z`: the datum height of the local frame's z = 0.
    origin_z: f64,
    /// Whether the run is LOD3 or more (storeys per level, openings, windows, doors, balconies).
    lod3: bool,
    /// The schema written.
    schema: IfcSchema,
    /// The `IfcOwnerHistory` of rooted entities (IFC2X3's is mandatory; `$` otherwise).
    owner: Option<Id>,
    /// The `Position` of swept solids written `$` in IFC4: the identity placement in IFC2X3,
    /// where it is mandatory.
    position: Option<Id>,
}

/// Most entries kept in each of the caches of shared opening bodies and fill offsets, whose keys
/// are sizes in micrometres: real walls give nearly every building sizes of its own (about 8 new
/// bodies a building on the benchmark's tiled input), so unbounded caches would grow with the
/// city. A full cache is emptied and starts again: sizes repeat mostly within a building and
/// among its neighbours, so little sharing is lost, memory stays flat (about 6 MB per cache),
/// and the output stays deterministic. Files of fewer distinct sizes (every sample, every 100 m
/// LOD4 tile) are unchanged.
const SHARED_CACHE_LIMIT: usize = 100_000;

/// The file-wide caches of shared entities, each created on first use (the LOD3 ones only by
/// LOD3 elements, so LOD1/LOD2 files do not change).
struct Caches {
    /// Material layer set usage per wall thickness (micrometres).
    usages: Cache<i64, Id>,
    /// Surface style per colour.
    styles: Cache<([u16; 4], Material), Id>,
    /// `IfcAxis2Placement3D(origin, -Y, X)`: maps a profile's (x, y) to (X, Z), extruding along
    /// its -Z goes to +Y (into the wall).
    vertical: Cache<(), Id>,
    /// `IfcCartesianTransformationOperator3D` at the origin (mapped items are placed by their
    /// product's placement).
    identity_op: Cache<(), Id>,
    /// Product shape of an opening body per (width, height, depth) in micrometres and rounding
    /// (corner bits, radius and profile in micrometres or millionths, segments; zeros for a
    /// rectangle) (at most [`SHARED_CACHE_LIMIT`] entries).
    opening_shapes: Cache<[i64; 7], Id>,
    /// `IfcAxis2Placement3D` of a window/door in its opening, per offset in micrometres (at
    /// most [`SHARED_CACHE_LIMIT`] entries).
    fill_offsets: Cache<[i64; 3], Id>,
    /// Rendering surface style per (colour, transparency in thousandths).
    renderings: Cache<([u16; 4], u16, Material), Id>,
    /// Window and door types (the type and the product shape of one `IfcMappedItem` of its
    /// representation map), by what makes two openings the same kind.
    types: Cache<TypeKey, (Id, Id)>,
}

impl Caches {
    fn new(limit: usize) -> Caches {
        Caches {
            usages: Cache::new(usize::MAX),
            styles: Cache::new(usize::MAX),
            vertical: Cache::new(usize::MAX),
            identity_op: Cache::new(usize::MAX),
            opening_shapes: Cache::new(limit),
            fill_offsets: Cache::new(limit),
            renderings: Cache::new(usize::MAX),
            types: Cache::new(usize::MAX),
        }
    }
}

/// One building being rendered ([`render`]): its entities, numbered locally, and its views of
/// the caches.
struct Render<'a> {
    g: &'a Globals,
    w: StepBuf,
    usages: View<'a, i64, Id>,
    styles: View<'a, ([u16; 4], Material), Id>,
    shared: Lod3Views<'a>,
    /// The window and door occurrences of the building, by type.
    occurrences: Vec<(TypeKey, Id)>,
    /// The number of the building's first entity, when known.
    start: Option<u64>,
    /// Whether something written needed `start` unknown (the rendering must be redone).
    inexact: bool,
}

/// The views of the LOD3 caches ([`Caches`]).
struct Lod3Views<'a> {
    vertical: View<'a, (), Id>,
    identity_op: View<'a, (), Id>,
    opening_shapes: View<'a, [i64; 7], Id>,
    fill_offsets: View<'a, [i64; 3], Id>,
    renderings: View<'a, ([u16; 4], u16, Material), Id>,
    types: View<'a, TypeKey, (Id, Id)>,
}

/// Storage of a rendered building, kept for the next ones (see [`Open::pool`]).
#[derive(Default)]
struct Scratch {
    w: StepBuf,
    logs: Logs,
    occurrences: Vec<(TypeKey, Id)>,
}

/// Scratch storage of at most this many bytes of entities is kept for reuse.
const SCRATCH_KEPT: usize = 1 << 20;

/// A rendered building, to be checked against the caches and appended.
struct Rendered {
    w: StepBuf,
    logs: Logs,
    occurrences: Vec<(TypeKey, Id)>,
    inexact: bool,
    /// The top-level `IfcBuilding`, or the error that stopped the rendering.
    done: Result<Id, ExportError>,
}

/// What a rendered building did with each cache.
#[derive(Default)]
struct Logs {
    usages: Log<i64, Id>,
    styles: Log<([u16; 4], Material), Id>,
    vertical: Log<(), Id>,
    identity_op: Log<(), Id>,
    opening_shapes: Log<[i64; 7], Id>,
    fill_offsets: Log<[i64; 3], Id>,
    renderings: Log<([u16; 4], u16, Material), Id>,
    types: Log<TypeKey, (Id, Id)>,
}

impl Logs {
    /// Whether the rendering is what the caches as they are now would give.
    fn holds(&self, c: &Caches) -> bool {
        self.usages.holds(&c.usages)
            && self.styles.holds(&c.styles)
            && self.vertical.holds(&c.vertical)
            && self.identity_op.holds(&c.identity_op)
            && self.opening_shapes.holds(&c.opening_shapes)
            && self.fill_offsets.holds(&c.fill_offsets)
            && self.renderings.holds(&c.renderings)
            && self.types.holds(&c.types)
    }

    /// Applies the insertions, the building's first entity numbered `start`.
    fn commit(&self, c: &mut Caches, start: u64) {
        self.usages.commit(&mut c.usages, start);
        self.styles.commit(&mut c.styles, start);
        self.vertical.commit(&mut c.vertical, start);
        self.identity_op.commit(&mut c.identity_op, start);
        self.opening_shapes.commit(&mut c.opening_shapes, start);
        self.fill_offsets.commit(&mut c.fill_offsets, start);
        self.renderings.commit(&mut c.renderings, start);
        self.types.commit(&mut c.types, start);
    }
}

/// Where a part's elements are placed: the frame of its `Storey 0`, in local-frame coordinates.
struct ElementFrame {
    origin: DVec3,
    placement: Id,
}

#[cfg(test)]
mod tests;
