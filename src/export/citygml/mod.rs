//! CityGML 2.0 writer: one `core:cityObjectMember` per building, streamed.
//!
//! The file is a `core:CityModel` in the output CRS. Coordinates are `origin + local point`,
//! written in metres with 3 decimals (millimetres). Every `srsName` is `EPSG:<code>`; when the
//! run states a vertical datum ([`OutputContext::vertical_datum`]) of known EPSG code, it is the
//! compound `urn:ogc:def:crs,crs:EPSG::<horizontal>,crs:EPSG::<vertical>`, and the header's
//! `gml:description` names the datum (its only statement when the code is unknown). What each LOD gets:
//!
//! - **LOD1**: `bldg:lod1Solid` whose `gml:CompositeSurface` holds the ground, wall and roof
//!   polygons inline.
//! - **LOD2**: `bldg:boundedBy` with one `bldg:GroundSurface` per part, one `bldg:WallSurface`
//!   per wall and one `bldg:RoofSurface` per roof face, each holding its polygon in a
//!   `bldg:lod2MultiSurface`; `bldg:lod2Solid` references those polygons with `xlink:href="#id"`
//!   so every coordinate is written once.
//! - **LOD3**: the same boundary
//!   surfaces in `bldg:lod3MultiSurface`, wall polygons keeping their interior rings (the
//!   openings' holes). A wall that faces a neighbour carries `gen:doubleAttribute`
//!   `partyWallShare` (its `Wall::party`, to the hundredth). Each wall surface lists its openings as `bldg:opening` with a
//!   `bldg:Window` or `bldg:Door` whose `bldg:lod3MultiSurface` holds the opening's rectangle in
//!   the wall plane, facing outward like the wall, so that it fills the hole exactly. Balconies
//!   are `bldg:outerBuildingInstallation` / `bldg:BuildingInstallation` (named `balcony`) whose
//!   `bldg:lod3Geometry` is a `gml:MultiSurface` of the slab (a closed box) and the railing
//!   (handrail, posts and infill panel, `crate::export::lod3geom::balcony_faces`). A wall's
//!   window sills (`crate::export::lod3geom::sills`) are one more installation (named `window
//!   sills`, id `<wall polygon id>_sills`) whose `gml:MultiSurface` holds each sill's closed box
//!   (six polygons, ids `<part>_w<wall>_sill<k>`), coloured light stone.
//!   `bldg:lod3Solid` references the ground, wall, roof and opening polygons, which
//!   together close the shell. Elements follow the schema's order: installations, boundary
//!   surfaces, then the solid. Glazed windows get their glass colour with `app:transparency`
//!   0.6, doors and opaque windows their colour, balcony slabs theirs, railings dark iron and their
//!   infill tinted glass with `app:transparency` 0.5.
//! - **LOD4**: the LOD3 exterior in the `lod4` properties (the code is shared, parameterised by
//!   the LOD number), plus stairs (`bldg:interiorBuildingInstallation`) and rooms
//!   (`bldg:interiorRoom`), written by the child module `lod4` (see there).
//!
//! Every `bldg:Building` carries generic attributes: `sourceId`, `zone`, `appearance`, and the
//! provenance of its storeys, height and roof ([`crate::model::Provenance`]):
//! `gen:stringAttribute`s `storeysSource`, `heightSource` and `roofSource` (`tag`,
//! `neighbours`, `fitted`, `model` or `kb`) and `gen:doubleAttribute`s `storeysError` (±
//! storeys), `heightError` (± metres) and `roofProbability` (0..1), each double left out when
//! unknown.
//!
//! A building with one part carries its geometry itself; with several parts each part becomes a
//! `bldg:BuildingPart` (with its own roof type, height, storeys and geometry) under
//! `bldg:consistsOfBuildingPart`. Colours are a local `app:appearance` per building (theme
//! `citygen`): one `app:X3DMaterial` per distinct colour, targeting its polygons by id.
//!
//! Because the file is streamed, the extent of the whole model is not known when the header is
//! written, so the `core:CityModel` has no `gml:boundedBy`; each `bldg:Building` has one (an
//! envelope with the CRS), and every top-level geometry names the CRS too.
//!
//! Identifiers are built from the source id only (`way/123` gives `B_way_123`, its part `p0`
//! gives `B_way_123_p0`, that part's polygons `B_way_123_p0_g`, `..._w3`, `..._r0`, their
//! boundary surfaces `..._w3_s`, the building's materials `B_way_123_m0`; at LOD3 that wall's
//! openings `..._w3_o0` with polygons `..._w3_o0_p`, its balconies `..._w3_b0` with polygons
//! `..._w3_b0_0` ...), so they are stable from run to run. The caller must not write two buildings with the same source id: their ids
//! would clash.
//!
//! Faces whose outer ring has fewer than 3 distinct vertices are left out (a ring that repeats its
//! first vertex at the end is accepted), as are such holes; any non-finite coordinate or height
//! rejects the whole building with [`ExportError::Invalid`] and nothing of it is written. Openings
//! or balconies with an empty extent (or on a wall without length) are left out.
//!
//! A context with a terrain ([`OutputContext::terrain`]) gets it after the buildings as one
//! `dem:ReliefFeature` (`relief`), the relief namespace and schema added to the root; without
//! one the file is as it was.
//!
//! Code layout: this module holds the writer and the per-building renderer; `building` writes
//! the building element and its parts, `surfaces` the boundary surfaces and LOD1/LOD2 solids,
//! `openings` the LOD3 openings, balconies and solid, `appearance` the X3D materials, `lod4` the
//! stairs and rooms, on the XML buffer of `xml`.

use std::io::Write;

use glam::DVec3;
use rayon::prelude::*;

use crate::export::{
    check_finite, vertical_datum, BuildingWriter, Checked, ExportError, OutputContext,
};
use crate::model::{Building, Lod};

use xml::Xml;

use crate::export::texture::{TextureOut, Texturing};

mod appearance;
pub(crate) mod building;
mod lod4;
mod material;
mod openings;
mod relief;
mod surfaces;
mod xml;

/// Code list of `bldg:roofType` values ([`RoofShape::citygml_code`]).
const ROOF_TYPE_CODESPACE: &str =
    "http://www.sig3d.org/codelists/standard/building/2.0/_AbstractBuilding_roofType.xml";

/// Theme of the appearance that carries the colours.
/// The most elements an XML document may have for the reference schema validator (xmlschema's
/// `MAX_XML_ELEMENTS`, which `validate-outputs` uses): a larger file is refused unread. The run
/// counts each CityGML file's elements and warns past it ([`count_elements`]).
pub(crate) const VALIDATOR_MAX_ELEMENTS: u64 = 1_000_000;

/// Counts the element start tags (`<name`, `<name/>`; not `</`, `<?`, `<!`) in `bytes`, a
/// piece of a CityGML stream; `after_lt` carries a `<` that ended the previous piece. The
/// writer escapes `<` in text and attributes, so every other `<` opens an element.
pub(crate) fn count_elements(bytes: &[u8], after_lt: &mut bool) -> u64 {
    let Some(&first) = bytes.first() else {
        return 0;
    };
    let opens = |b: u8| !matches!(b, b'/' | b'?' | b'!');
    let mut n = u64::from(*after_lt && opens(first));
    // Every `<` that `/`, `?` or `!` does not follow, in one branch-free pass over the byte
    // pairs that the compiler vectorises (byte counters, emptied every 255 pairs).
    let pairs = bytes.len() - 1;
    for (ca, cb) in bytes[..pairs].chunks(255).zip(bytes[1..].chunks(255)) {
        let mut acc: u8 = 0;
        for (&x, &y) in ca.iter().zip(cb) {
            acc += u8::from(x == b'<')
                & u8::from(y != b'/')
                & u8::from(y != b'?')
                & u8::from(y != b'!');
        }
        n += u64::from(acc);
    }
    // A `<` at the very end is decided by the next piece.
    *after_lt = bytes[pairs] == b'<';
    n
}

const APPEARANCE_THEME: &str = "citygen";

/// `app:transparency` of glazed windows' glass.
const GLASS_TRANSPARENCY: f32 = 0.6;

const HEADER_NAMESPACES: &str = concat!(
    "<core:CityModel",
    " xmlns:core=\"http://www.opengis.net/citygml/2.0\"",
    " xmlns:bldg=\"http://www.opengis.net/citygml/building/2.0\"",
    " xmlns:app=\"http://www.opengis.net/citygml/appearance/2.0\"",
    " xmlns:gen=\"http://www.opengis.net/citygml/generics/2.0\"",
    " xmlns:gml=\"http://www.opengis.net/gml\"",
    " xmlns:xlink=\"http://www.w3.org/1999/xlink\"",
    " xmlns:xsi=\"http://www.w3.org/2001/XMLSchema-instance\"",
    " xsi:schemaLocation=\"",
    "http://www.opengis.net/citygml/building/2.0 http://schemas.opengis.net/citygml/building/2.0/building.xsd",
    " http://www.opengis.net/citygml/appearance/2.0 http://schemas.opengis.net/citygml/appearance/2.0/appearance.xsd",
    " http://www.opengis.net/citygml/generics/2.0 http://schemas.opengis.net/citygml/generics/2.0/generics.xsd",
    "\">\n",
);

/// The relief module's namespace declaration, added to the root of a file with terrain.
const RELIEF_NAMESPACE: &str = " xmlns:dem=\"http://www.opengis.net/citygml/relief/2.0\"";

/// The relief module's schema location, added to a file with terrain.
const RELIEF_SCHEMA: &str =
    " http://www.opengis.net/citygml/relief/2.0 http://schemas.opengis.net/citygml/relief/2.0/relief.xsd";

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    New,
    Open,
    Finished,
}

/// Which geometry representation the run writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum GeometryLod {
    /// Inline polygons in `lod1Solid`.
    Lod1,
    /// Semantic boundary surfaces plus an `lod2Solid` of references.
    Lod2,
    /// LOD2's structure in `lod3` properties, with openings and balconies.
    Lod3,
    /// LOD3's structure in `lod4` properties, with rooms and stairs.
    Lod4,
}

impl GeometryLod {
    fn digit(self) -> &'static str {
        match self {
            GeometryLod::Lod1 => "1",
            GeometryLod::Lod2 => "2",
            GeometryLod::Lod3 => "3",
            GeometryLod::Lod4 => "4",
        }
    }
}

/// Streaming CityGML 2.0 writer (see the module documentation for what it writes).
///
/// Call [`BuildingWriter::begin`], then [`BuildingWriter::write`] per building, then
/// [`BuildingWriter::finish`]; [`CityGmlWriter::into_inner`] gives the sink back afterwards
/// (e.g. to commit an [`crate::export::AtomicFile`]). Each building is rendered into an internal
/// buffer and handed to the sink in one `write_all`, so a rejected building leaves no trace in
/// the output. The output is a pure function of the context and the buildings.
pub struct CityGmlWriter<W: Write + Send> {
    out: W,
    state: State,
    /// `srsName` given by [`CityGmlWriter::with_srs_name`]; `None` means `EPSG:<code>`.
    srs_override: Option<String>,
    /// The `srsName` value, already escaped for an attribute.
    srs_attr: String,
    origin: DVec3,
    lod: GeometryLod,
    /// Scratch buffer one building is rendered into.
    buf: Xml,
    /// Buffers of the buildings [`BuildingWriter::write_all`] renders in parallel, reused.
    slots: Vec<Xml>,
    /// The file's terrain and its id, written after the buildings (`relief`).
    terrain: Option<(std::sync::Arc<crate::model::Terrain>, String)>,
    /// `--textures` ([`CityGmlWriter::with_textures`]).
    textures: bool,
    /// What is textured (from `textures` and the LOD at `begin`), where and with what.
    tex: TextureOut,
}

impl<W: Write + Send> CityGmlWriter<W> {
    /// A writer to `out` whose `srsName` is `EPSG:<code>` of the context's CRS.
    pub fn new(out: W) -> CityGmlWriter<W> {
        CityGmlWriter {
            out,
            state: State::New,
            srs_override: None,
            srs_attr: String::new(),
            origin: DVec3::ZERO,
            lod: GeometryLod::Lod2,
            buf: Xml(Vec::with_capacity(64 * 1024)),
            slots: Vec::new(),
            terrain: None,
            textures: false,
            tex: TextureOut::default(),
        }
    }

    /// With `Some((folder, used))`, walls and roofs carry the procedural textures
    /// (`--textures`, `crate::export::texture`): an `app:ParameterizedTexture` per picture in
    /// each building's appearance, its `app:imageURI` the picture in `folder` (relative to the
    /// output, `out_textures/`), the pictures noted in `used` for the run to write.
    pub(crate) fn with_textures(
        mut self,
        on: Option<(String, crate::export::texture::TextureSet)>,
    ) -> CityGmlWriter<W> {
        if let Some((folder, used)) = on {
            self.textures = true;
            self.tex.folder = folder;
            self.tex.used = used;
        }
        self
    }

    /// A writer to `out` that writes `srs_name` verbatim as every `srsName` (e.g. a compound
    /// `urn:ogc:def:crs,crs:EPSG::25832,crs:EPSG::5783`) instead of `EPSG:<code>`.
    #[cfg(test)]
    pub(crate) fn with_srs_name(out: W, srs_name: impl Into<String>) -> CityGmlWriter<W> {
        let mut w = CityGmlWriter::new(out);
        w.srs_override = Some(srs_name.into());
        w
    }

    /// Gives the sink back. Call it after [`BuildingWriter::finish`]; before, the document is
    /// incomplete.
    pub fn into_inner(self) -> W {
        self.out
    }

    fn check_state(&self, expected: State, call: &str) -> Result<(), ExportError> {
        if self.state == expected {
            return Ok(());
        }
        let why = match self.state {
            State::New => "before begin()",
            State::Open => "after begin()",
            State::Finished => "after finish()",
        };
        Err(ExportError::Invalid(format!(
            "CityGML writer: {call} called {why}"
        )))
    }
}

/// `EPSG:<code>` of the context's CRS; with a stated vertical datum of known code, the compound
/// of both in OGC's URN form (`urn:ogc:def:crs,crs:EPSG::32632,crs:EPSG::5773`, as CityGML 2.0's
/// own examples and 3DCityDB write it).
fn epsg_srs_name(ctx: &OutputContext) -> String {
    match vertical_datum(ctx) {
        Some((Some(v), _)) => format!("urn:ogc:def:crs,crs:EPSG::{},crs:EPSG::{v}", ctx.crs.epsg()),
        _ => format!("EPSG:{}", ctx.crs.epsg()),
    }
}

impl<W: Write + Send> BuildingWriter for CityGmlWriter<W> {
    fn begin(&mut self, ctx: &OutputContext) -> Result<(), ExportError> {
        self.check_state(State::New, "begin()")?;
        if !ctx.origin.is_finite() {
            return Err(ExportError::Invalid(format!(
                "CityGML writer: the local origin {:?} is not finite",
                ctx.origin
            )));
        }
        let srs_name = match &self.srs_override {
            Some(s) => s.clone(),
            None => epsg_srs_name(ctx),
        };
        let mut attr = Xml(Vec::new());
        attr.escaped(&srs_name, true);
        self.srs_attr = String::from_utf8_lossy(&attr.0).into_owned();
        self.origin = ctx.origin;
        self.lod = match ctx.lod {
            Lod::Lod1 => GeometryLod::Lod1,
            Lod::Lod2 => GeometryLod::Lod2,
            Lod::Lod3 => GeometryLod::Lod3,
            Lod::Lod4 => GeometryLod::Lod4,
        };
        self.tex.tex = Texturing::of(self.textures, ctx.lod);

        let x = &mut self.buf;
        x.0.clear();
        x.s("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
        self.terrain = ctx.terrain.clone().map(|t| {
            let id = crate::export::ids::terrain_id(&t, ctx.origin);
            (t, id)
        });
        if self.terrain.is_some() {
            // The relief module's namespace and schema beside the others.
            let (head, locations) = HEADER_NAMESPACES
                .split_once(" xsi:schemaLocation=\"")
                .unwrap_or((HEADER_NAMESPACES, "\">\n"));
            x.s(head);
            x.s(RELIEF_NAMESPACE);
            x.s(" xsi:schemaLocation=\"");
            x.s(locations.trim_end_matches("\">\n"));
            x.s(RELIEF_SCHEMA);
            x.s("\">\n");
        } else {
            x.s(HEADER_NAMESPACES);
        }
        x.s("<gml:description>Generated by citygen from ");
        x.escaped(&ctx.source_name, false);
        x.s(", seed ");
        x.uint(ctx.seed);
        x.s(", LOD");
        x.s(self.lod.digit());
        x.s(" geometry");
        if let Some((epsg, name)) = vertical_datum(ctx) {
            // The datum by name too: the only statement of it when its code is unknown.
            x.s("; heights: ");
            x.escaped(name, false);
            if let Some(v) = epsg {
                x.s(" (EPSG:");
                x.uint(u64::from(v));
                x.s(")");
            }
        }
        x.s("</gml:description>\n");
        if !ctx.source_name.is_empty() {
            x.s("<gml:name>");
            x.escaped(&ctx.source_name, false);
            x.s("</gml:name>\n");
        }
        self.out.write_all(&x.0)?;
        self.state = State::Open;
        Ok(())
    }

    fn write(&mut self, building: &Building) -> Result<(), ExportError> {
        self.check_state(State::Open, "write()")?;
        check_finite("CityGML writer", building)?;
        self.buf.0.clear();
        let mut r = Renderer {
            x: &mut self.buf,
            origin: self.origin,
            srs: &self.srs_attr,
            lod: self.lod,
            tex: &self.tex,
        };
        r.building(building);
        self.out.write_all(&self.buf.0)?;
        Ok(())
    }

    /// Renders the buildings in parallel, a batch at a time (`super::batches`: at most
    /// `super::PARALLEL_BATCH` buildings, fewer when they are large), each into its own
    /// buffer (kept from batch to batch unless it grew past `super::SLOT_KEPT`), and writes
    /// them in order: the same bytes as `write` on each.
    fn write_all(&mut self, buildings: &[Building]) -> Result<(), ExportError> {
        self.write_checked(&Checked::check(buildings))
    }

    fn write_checked(&mut self, checked: &Checked<'_>) -> Result<(), ExportError> {
        self.check_state(State::Open, "write()")?;
        let (origin, srs, lod) = (self.origin, self.srs_attr.as_str(), self.lod);
        let tex = &self.tex;
        let slots = &mut self.slots;
        slots.resize_with(super::PARALLEL_BATCH, || Xml(Vec::new()));
        for batch in super::batches(checked.finite()) {
            batch
                .par_iter()
                .zip(slots.par_iter_mut())
                .for_each(|(b, x)| {
                    x.0.clear();
                    // Room for the building at once: a tower's tens of MB are not grown by
                    // doubling (a copy and fresh pages each time).
                    x.0.reserve(b.polygon_count().saturating_mul(BYTES_PER_POLYGON));
                    Renderer {
                        x,
                        origin,
                        srs,
                        lod,
                        tex,
                    }
                    .building(b);
                });
            for x in &mut slots[..batch.len()] {
                self.out.write_all(&x.0)?;
                if x.0.capacity() > super::SLOT_KEPT {
                    // A tower's buffer: not kept for the next batch.
                    x.0 = Vec::new();
                }
            }
        }
        checked.refused("CityGML writer")
    }

    fn finish(&mut self) -> Result<(), ExportError> {
        self.check_state(State::Open, "finish()")?;
        self.state = State::Finished;
        if let Some((t, id)) = self.terrain.take() {
            let at = (self.origin, self.srs_attr.as_str(), self.lod.digit());
            relief::relief(&mut self.buf, &mut self.out, &t, &id, at)?;
        }
        self.out.write_all(b"</core:CityModel>\n")?;
        self.out.flush()?;
        self.buf = Xml(Vec::new());
        self.slots = Vec::new();
        Ok(())
    }
}

/// About the bytes of CityGML a polygon of a building takes at LOD3 (1,424 in the 10k bench
/// input: 1.99 GB for 1.40 M polygons), reserved for a building before it is rendered.
const BYTES_PER_POLYGON: usize = 1_400;

/// Renders one building into the scratch buffer.
struct Renderer<'a> {
    x: &'a mut Xml,
    origin: DVec3,
    srs: &'a str,
    lod: GeometryLod,
    /// The textures (`--textures`; [`Texturing::Off`] without).
    tex: &'a TextureOut,
}

/// Whether polygons of `kind` carry a texture under `tex` (walls and roofs, with
/// `--textures`): their rings then have ids.
fn textured(tex: Texturing, kind: surfaces::SurfaceKind) -> bool {
    tex != Texturing::Off
        && matches!(
            kind,
            surfaces::SurfaceKind::Wall | surfaces::SurfaceKind::Roof
        )
}

#[cfg(test)]
mod tests;
