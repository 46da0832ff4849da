//! IFC4 writer (STEP Part 21), streaming one [`Building`] at a time.
//!
//! Layout of a file:
//!
//! - `IfcProject` (SI units: metre, square metre, cubic metre, radian) with a 3D `Model` context,
//!   its `Body` (MODEL_VIEW) and `Axis` (GRAPH_VIEW) sub-contexts, and an `IfcMapConversion`
//!   from the project's engineering frame to an `IfcProjectedCRS` named `EPSG:n`: the model's
//!   (0, 0, 0) is at [`OutputContext::origin`] in that CRS.
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
//! - Colours: one `IfcSurfaceStyle` per distinct colour in the file, applied through
//!   `IfcStyledItem` to wall and roof bodies.
//! - Per building, property sets `Citygen_Source` (SourceId, Zone, Appearance, MeasuredHeight,
//!   Lod, RoofShape) and `Pset_BuildingCommon` (NumberOfStoreys), and per building a
//!   `Pset_WallCommon` with IsExternal true on its walls and false on those wholly against a
//!   neighbour (`Wall::party` 1, LOD3), and `Citygen_Wall` (PartyWallShare, one set per
//!   share) on every wall that faces a neighbour.
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
//!   transparent; styles cached per colour and transparency). Every occurrence references the
//!   same `IfcProductDefinitionShape` (one `IfcMappedItem` of the map), so a window costs its
//!   placement and relationships only. The `IfcRelDefinesByType` of each type (a type has at
//!   most one) and an `IfcRelDeclares` of all types in the project are written by `finish`.
//!   Opening bodies are shared the same way per (width, height, wall thickness).
//! - A [`Balcony`](crate::model::Balcony) is an `IfcSlab` `.FLOOR.` named `Balcony` (its rectangle, 15 cm thick, top
//!   at the balcony's floor height, outside the wall) and an `IfcRailing` `.BALUSTRADE.` (1 m
//!   high, 5 cm thick, on the three free edges), both contained in the wall's storey.
//! - Glazed facades are not written as `IfcCurtainWall`: windows only.
//!
//! At LOD4 a part's interiors are added to its LOD3 storeys (spaces, partition walls, interior
//! doors, stairs, upper floor slabs) by the child module `lod4` (see there).
//!
//! GlobalIds are deterministic ([`global_id`](crate::export::step::global_id)) from the building key and the element's path, so
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
//! placements, profiles, breps) and `lod4` (interiors).

use std::collections::{BTreeMap, BTreeSet};
use std::io::Write;

use glam::DVec3;

use crate::export::step::{Id, StepWriter};
use crate::export::{check_finite, BuildingWriter, ExportError, OutputContext};
use crate::model::{Building, RoofShape};

use openings::{FillType, TypeKey};

mod lod4;
mod openings;
mod roofs;
mod shapes;
mod spatial;
mod styles;
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

/// Streaming IFC4 writer. See the module documentation for what it writes.
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
        let mut open = Open::begin(out, ctx, &self.file_name)?;
        open.shared.limit = self.cache_limit;
        self.state = State::Open(Box::new(open));
        Ok(())
    }

    fn write(&mut self, building: &Building) -> Result<(), ExportError> {
        match &mut self.state {
            State::Open(open) => {
                check_finite("IFC writer", building)?;
                // An entity that would break a schema rule (a zero length) ends the file here
                // with an error naming the building, never as an invalid file.
                open.building(building).map_err(|e| match e {
                    ExportError::Io(io) => match crate::export::step::broken_rule(&io) {
                        Some(rule) => ExportError::Invalid(format!(
                            "IFC writer: building {}: {rule}",
                            building.id
                        )),
                        None => ExportError::Io(io),
                    },
                    other => other,
                })
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

/// The IFC4 `IfcRoofTypeEnum` value for a roof shape.
pub fn roof_type(shape: RoofShape) -> &'static str {
    match shape {
        RoofShape::Flat => "FLAT_ROOF",
        RoofShape::Skillion => "SHED_ROOF",
        RoofShape::Gabled | RoofShape::Saltbox => "GABLE_ROOF",
        RoofShape::Hipped | RoofShape::SideHipped => "HIP_ROOF",
        RoofShape::HalfHipped => "HIPPED_GABLE_ROOF",
        RoofShape::Pyramidal => "PAVILION_ROOF",
        RoofShape::Mansard => "MANSARD_ROOF",
        RoofShape::Gambrel => "GAMBREL_ROOF",
        RoofShape::Dome => "DOME_ROOF",
        RoofShape::Round => "BARREL_ROOF",
        RoofShape::Onion | RoofShape::Cone => "FREEFORM",
    }
}

/// An angle in decimal degrees as an `IfcCompoundPlaneAngleMeasure`: degrees, minutes, seconds,
/// millionths of a second, all carrying the sign of the angle (as the schema's WHERE rule wants).
/// `None` for a non-finite angle or one outside (-360, 360).
pub fn compound_angle(deg: f64) -> Option<[i64; 4]> {
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
    site: Id,
    site_placement: Id,
    wall_material: Id,
    /// `OutputContext::origin.z`: the datum height of the local frame's z = 0.
    origin_z: f64,
    /// Material layer set usage per wall thickness (micrometres).
    usages: BTreeMap<i64, Id>,
    /// Surface style per colour.
    styles: BTreeMap<[u16; 4], Id>,
    /// Top-level buildings, for the final site aggregation.
    buildings: Vec<Id>,
    /// 128-bit hashes of the building keys already written, to keep GlobalIds unique if a key
    /// repeats (16 bytes a building rather than the key's string).
    keys: BTreeSet<u128>,
    /// Whether the run is LOD3 or more (storeys per level, openings, windows, doors, balconies).
    lod3: bool,
    project: Id,
    /// LOD3 shared entities, created on first use so LOD1/LOD2 files do not change.
    shared: Lod3Shared,
}

/// Most entries kept in each of the caches of shared opening bodies and fill offsets, whose keys
/// are sizes in micrometres: real walls give nearly every building sizes of its own (about 8 new
/// bodies a building on the benchmark's tiled input), so unbounded caches would grow with the
/// city. A full cache is emptied and starts again: sizes repeat mostly within a building and
/// among its neighbours, so little sharing is lost, memory stays flat (about 6 MB per cache),
/// and the output stays deterministic. Files of fewer distinct sizes (every sample, every 100 m
/// LOD4 tile) are unchanged.
const SHARED_CACHE_LIMIT: usize = 100_000;

/// Entities shared file-wide by LOD3 elements, created lazily.
#[derive(Default)]
struct Lod3Shared {
    /// `IfcAxis2Placement3D(origin, -Y, X)`: maps a profile's (x, y) to (X, Z), extruding along
    /// its -Z goes to +Y (into the wall).
    vertical: Option<Id>,
    /// `IfcCartesianTransformationOperator3D` at the origin (mapped items are placed by their
    /// product's placement).
    identity_op: Option<Id>,
    /// Entries kept per cache before it is emptied ([`SHARED_CACHE_LIMIT`]).
    limit: usize,
    /// Product shape of an opening body per (width, height, depth) in micrometres.
    opening_shapes: BTreeMap<[i64; 3], Id>,
    /// `IfcAxis2Placement3D` of a window/door in its opening, per offset in micrometres.
    fill_offsets: BTreeMap<[i64; 3], Id>,
    /// Rendering surface style per (colour, transparency in thousandths).
    renderings: BTreeMap<([u16; 4], u16), Id>,
    /// Window and door types, by what makes two openings the same kind.
    types: BTreeMap<TypeKey, FillType>,
}

/// Where a part's elements are placed: the frame of its `Storey 0`, in local-frame coordinates.
struct ElementFrame {
    origin: DVec3,
    placement: Id,
}

#[cfg(test)]
mod tests;
