//! CityGML 2.0 writer: one `core:cityObjectMember` per building, streamed.
//!
//! The file is a `core:CityModel` in the output CRS. Coordinates are `origin + local point`,
//! written in metres with 3 decimals (millimetres). What each LOD gets:
//!
//! - **LOD1**: `bldg:lod1Solid` whose `gml:CompositeSurface` holds the ground, wall and roof
//!   polygons inline.
//! - **LOD2**: `bldg:boundedBy` with one `bldg:GroundSurface` per part, one `bldg:WallSurface`
//!   per wall and one `bldg:RoofSurface` per roof face, each holding its polygon in a
//!   `bldg:lod2MultiSurface`; `bldg:lod2Solid` references those polygons with `xlink:href="#id"`
//!   so every coordinate is written once.
//! - **LOD3**: the same boundary
//!   surfaces in `bldg:lod3MultiSurface`, wall polygons keeping their interior rings (the
//!   openings' holes). Each wall surface lists its openings as `bldg:opening` with a
//!   `bldg:Window` or `bldg:Door` whose `bldg:lod3MultiSurface` holds the opening's rectangle in
//!   the wall plane, facing outward like the wall, so that it fills the hole exactly. Balconies
//!   are `bldg:outerBuildingInstallation` / `bldg:BuildingInstallation` (named `balcony`) whose
//!   `bldg:lod3Geometry` is a `gml:MultiSurface` of the slab (a closed box) and the railing
//!   panels. `bldg:lod3Solid` references the ground, wall, roof and opening polygons, which
//!   together close the shell. Elements follow the schema's order: installations, boundary
//!   surfaces, then the solid. Glazed windows get their glass colour with `app:transparency`
//!   0.6, doors and opaque windows their colour, balconies theirs.
//! - **LOD4**: the LOD3 exterior in the `lod4` properties (the code is shared, parameterised by
//!   the LOD number), plus stairs (`bldg:interiorBuildingInstallation`) and rooms
//!   (`bldg:interiorRoom`), written by the child module `citygml_lod4.rs` (see there).
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

use std::io::Write;

use glam::DVec3;
use rayon::prelude::*;

use crate::color::Color;
use crate::export::lod3geom::{balcony_faces, opening_face};
use crate::export::{BuildingWriter, ExportError, OutputContext};
use crate::model::{Building, Face, Lod, OpeningKind, Part, RoofShape, Wall};

mod lod4;

/// Code list of `bldg:roofType` values ([`RoofShape::citygml_code`]).
const ROOF_TYPE_CODESPACE: &str =
    "http://www.sig3d.org/codelists/standard/building/2.0/_AbstractBuilding_roofType.xml";

/// Theme of the appearance that carries the colours.
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
        }
    }

    /// A writer to `out` that writes `srs_name` verbatim as every `srsName` (e.g. a compound
    /// `urn:ogc:def:crs,crs:EPSG::25832,crs:EPSG::5783`) instead of `EPSG:<code>`.
    pub fn with_srs_name(out: W, srs_name: impl Into<String>) -> CityGmlWriter<W> {
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

/// `EPSG:<code>` of the context's CRS.
fn epsg_srs_name(ctx: &OutputContext) -> String {
    format!("EPSG:{}", ctx.crs.epsg())
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

        let x = &mut self.buf;
        x.0.clear();
        x.s("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
        x.s(HEADER_NAMESPACES);
        x.s("<gml:description>Generated by citygen from ");
        x.escaped(&ctx.source_name, false);
        x.s(", seed ");
        x.uint(ctx.seed);
        x.s(", LOD");
        x.s(self.lod.digit());
        x.s(" geometry</gml:description>\n");
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
        check_finite(building)?;
        self.buf.0.clear();
        let mut r = Renderer {
            x: &mut self.buf,
            origin: self.origin,
            srs: &self.srs_attr,
            lod: self.lod,
        };
        r.building(building);
        self.out.write_all(&self.buf.0)?;
        Ok(())
    }

    /// Renders the buildings in parallel, [`super::PARALLEL_BATCH`] at a time, each into its
    /// own buffer, and writes them in order: the same bytes as `write` on each.
    fn write_all(&mut self, buildings: &[Building]) -> Result<(), ExportError> {
        self.check_state(State::Open, "write()")?;
        let (origin, srs, lod) = (self.origin, self.srs_attr.as_str(), self.lod);
        for batch in buildings.chunks(super::PARALLEL_BATCH) {
            let rendered: Vec<Result<Xml, ExportError>> = batch
                .par_iter()
                .map(|b| {
                    check_finite(b)?;
                    let mut x = Xml(Vec::with_capacity(64 * 1024));
                    Renderer {
                        x: &mut x,
                        origin,
                        srs,
                        lod,
                    }
                    .building(b);
                    Ok(x)
                })
                .collect();
            for x in rendered {
                self.out.write_all(&x?.0)?;
            }
        }
        Ok(())
    }

    fn finish(&mut self) -> Result<(), ExportError> {
        self.check_state(State::Open, "finish()")?;
        self.state = State::Finished;
        self.out.write_all(b"</core:CityModel>\n")?;
        self.out.flush()?;
        self.buf = Xml(Vec::new());
        Ok(())
    }
}

/// Rejects a building with a non-finite coordinate or height, naming the building and part.
fn check_finite(b: &Building) -> Result<(), ExportError> {
    let bad = |what: &str| {
        ExportError::Invalid(format!(
            "CityGML writer: building {}: {what} is not finite",
            b.id
        ))
    };
    if !b.measured_height.is_finite() || !b.base_z.is_finite() {
        return Err(bad("the measured height"));
    }
    for p in &b.parts {
        if !(p.base_z.is_finite() && p.top_z.is_finite()) {
            return Err(bad(&format!("the height of part {}", p.key)));
        }
        let faces = std::iter::once(&p.ground)
            .chain(p.walls.iter().map(|w| &w.outline))
            .chain(p.roof.iter());
        for f in faces {
            let finite = f
                .outer
                .iter()
                .chain(f.holes.iter().flatten())
                .all(|v| v.is_finite());
            if !finite {
                return Err(bad(&format!("a coordinate of part {}", p.key)));
            }
        }
        for (i, w) in p.walls.iter().enumerate() {
            let openings = w.openings.iter().flat_map(|o| [o.u0, o.u1, o.z0, o.z1]);
            let balconies = w.balconies.iter().flat_map(|b| [b.u0, b.u1, b.z, b.depth]);
            if !openings.chain(balconies).all(f64::is_finite) {
                return Err(bad(&format!(
                    "an opening or balcony of wall {i} of part {}",
                    p.key
                )));
            }
        }
    }
    Ok(())
}

/// What a polygon is in the building's semantics.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum SurfaceKind {
    Ground,
    Wall,
    Roof,
    /// An opening of wall `wall` (the surface's index is the opening's).
    Opening {
        wall: usize,
    },
    /// A face of balcony `balcony` of wall `wall` (the surface's index is the face's).
    Balcony {
        wall: usize,
        balcony: usize,
    },
}

/// One polygon to write: its kind, its index in the model's list (for openings and balcony
/// faces, in the wall's or the balcony's list), and its face.
struct Surface<'a> {
    kind: SurfaceKind,
    index: usize,
    face: &'a Face,
}

/// The writable polygons of a part in output order: ground, walls, roof faces.
fn surfaces(part: &Part) -> impl Iterator<Item = Surface<'_>> {
    let ground = std::iter::once(Surface {
        kind: SurfaceKind::Ground,
        index: 0,
        face: &part.ground,
    });
    let walls = part.walls.iter().enumerate().map(|(i, w)| Surface {
        kind: SurfaceKind::Wall,
        index: i,
        face: &w.outline,
    });
    let roofs = part.roof.iter().enumerate().map(|(i, f)| Surface {
        kind: SurfaceKind::Roof,
        index: i,
        face: f,
    });
    ground
        .chain(walls)
        .chain(roofs)
        .filter(|s| ring(&s.face.outer).is_some())
}

/// The ring without a closing duplicate of its first vertex, or `None` if fewer than 3 remain.
fn ring(points: &[DVec3]) -> Option<&[DVec3]> {
    let mut r = points;
    while r.len() > 1 && r.first() == r.last() {
        r = &r[..r.len() - 1];
    }
    (r.len() >= 3).then_some(r)
}

/// Keeps ASCII letters, digits, `_`, `-` and `.` (NCName-safe after a letter prefix), replacing
/// anything else by `_`.
fn id_fragment(s: &str) -> String {
    s.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.') {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// The id prefixes of the parts: `<building id>_<part key>`, or `<building id>_p<index>` for all
/// parts when the keys are empty or not unique (ids must be unique in the file).
fn part_ids(building_id: &str, parts: &[Part]) -> Vec<String> {
    let keys: Vec<String> = parts.iter().map(|p| id_fragment(&p.key)).collect();
    let usable = keys
        .iter()
        .enumerate()
        .all(|(i, k)| !k.is_empty() && !keys[..i].contains(k));
    keys.iter()
        .enumerate()
        .map(|(i, k)| {
            if usable {
                format!("{building_id}_{k}")
            } else {
                format!("{building_id}_p{i}")
            }
        })
        .collect()
}

/// A colour quantised as written (4 decimals), used to merge equal materials.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct ColorKey {
    rgb: [u16; 3],
    /// Transparency (1 - alpha) in 1/10000.
    transparency: u16,
}

impl ColorKey {
    fn of(c: Color) -> ColorKey {
        let q = |v: f32| {
            if v.is_finite() {
                (v.clamp(0.0, 1.0) * 10_000.0).round() as u16
            } else {
                0
            }
        };
        let alpha = if c.a.is_finite() { c.a } else { 1.0 };
        ColorKey {
            rgb: [q(c.r), q(c.g), q(c.b)],
            transparency: 10_000 - q(alpha),
        }
    }
}

/// A polygon an appearance targets: (part index, kind, index in the part's list).
type Target = (usize, SurfaceKind, usize);

/// Adds `target` to the material of `color`, creating it (last) on first use.
fn add_target(materials: &mut Vec<(ColorKey, Vec<Target>)>, color: Color, target: Target) {
    let key = ColorKey::of(color);
    match materials.iter_mut().find(|(k, _)| *k == key) {
        Some((_, targets)) => targets.push(target),
        None => materials.push((key, vec![target])),
    }
}

/// The walls that are written (see [`surfaces`]) with their indices: only their openings and
/// balconies are.
fn written_walls(part: &Part) -> impl Iterator<Item = (usize, &Wall)> {
    surfaces(part)
        .filter(|s| s.kind == SurfaceKind::Wall)
        .filter_map(|s| part.walls.get(s.index).map(|w| (s.index, w)))
}

/// Renders one building into the scratch buffer.
struct Renderer<'a> {
    x: &'a mut Xml,
    origin: DVec3,
    srs: &'a str,
    lod: GeometryLod,
}

impl Renderer<'_> {
    fn building(&mut self, b: &Building) {
        let id = format!("B_{}", id_fragment(&b.key()));
        let parts = part_ids(&id, &b.parts);
        let x = &mut *self.x;
        x.s("<core:cityObjectMember>\n<bldg:Building gml:id=\"");
        x.s(&id);
        x.s("\">\n");
        if let Some(name) = &b.name {
            x.s("<gml:name>");
            x.escaped(name, false);
            x.s("</gml:name>\n");
        }
        self.envelope(b);
        self.string_attribute("sourceId", &b.id.to_string());
        if !b.zone.is_empty() {
            self.string_attribute("zone", &b.zone);
        }
        if !b.appearance.is_empty() {
            self.string_attribute("appearance", &b.appearance);
        }
        self.appearance(&id, b, &parts);
        self.building_attributes(b.roof_shape, b.measured_height, b.storeys_above_ground);
        match b.parts.as_slice() {
            [part] => self.geometry(part, &parts[0]),
            _ => {
                for (part, pid) in b.parts.iter().zip(&parts) {
                    let x = &mut *self.x;
                    x.s("<bldg:consistsOfBuildingPart>\n<bldg:BuildingPart gml:id=\"");
                    x.s(pid);
                    x.s("\">\n");
                    self.building_attributes(
                        part.roof_shape,
                        part.top_z - part.base_z,
                        part.storeys,
                    );
                    self.geometry(part, pid);
                    self.x
                        .s("</bldg:BuildingPart>\n</bldg:consistsOfBuildingPart>\n");
                }
            }
        }
        self.x.s("</bldg:Building>\n</core:cityObjectMember>\n");
    }

    /// `gml:boundedBy` of the building's written polygons; nothing when it has none.
    fn envelope(&mut self, b: &Building) {
        let mut points = b
            .parts
            .iter()
            .flat_map(|p| surfaces(p).flat_map(|s| s.face.outer.iter()));
        let Some(&first) = points.next() else {
            return;
        };
        let (mut lo, mut hi) = points.fold((first, first), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
        if self.lod >= GeometryLod::Lod3 {
            // Balconies stand out of the walls.
            for part in &b.parts {
                for (_, wall) in written_walls(part) {
                    for f in wall
                        .balconies
                        .iter()
                        .filter_map(|bc| balcony_faces(wall, bc))
                    {
                        for p in f.all().flat_map(|f| f.outer.iter()) {
                            lo = lo.min(*p);
                            hi = hi.max(*p);
                        }
                    }
                }
            }
        }
        let x = &mut *self.x;
        x.s("<gml:boundedBy>\n<gml:Envelope srsName=\"");
        x.s(self.srs);
        x.s("\" srsDimension=\"3\">\n<gml:lowerCorner>");
        x.point(self.origin + lo);
        x.s("</gml:lowerCorner>\n<gml:upperCorner>");
        x.point(self.origin + hi);
        x.s("</gml:upperCorner>\n</gml:Envelope>\n</gml:boundedBy>\n");
    }

    fn string_attribute(&mut self, name: &str, value: &str) {
        let x = &mut *self.x;
        x.s("<gen:stringAttribute name=\"");
        x.escaped(name, true);
        x.s("\">\n<gen:value>");
        x.escaped(value, false);
        x.s("</gen:value>\n</gen:stringAttribute>\n");
    }

    /// The local appearance: one X3DMaterial per distinct colour, in order of first use.
    fn appearance(&mut self, building_id: &str, b: &Building, part_ids: &[String]) {
        // (colour, [(part index, kind, index)]) in first-use order: deterministic, and the few
        // colours of a building make a linear search cheaper than hashing.
        let mut materials: Vec<(ColorKey, Vec<Target>)> = Vec::new();
        for (pi, part) in b.parts.iter().enumerate() {
            for s in surfaces(part) {
                let color = match s.kind {
                    SurfaceKind::Ground => Color::GREY,
                    SurfaceKind::Roof => part.roof_color,
                    // `surfaces` yields no openings or balconies.
                    SurfaceKind::Wall
                    | SurfaceKind::Opening { .. }
                    | SurfaceKind::Balcony { .. } => part.wall_color,
                };
                add_target(&mut materials, color, (pi, s.kind, s.index));
            }
            if self.lod < GeometryLod::Lod3 {
                continue;
            }
            for (wi, wall) in written_walls(part) {
                for (k, o) in wall.openings.iter().enumerate() {
                    if opening_face(wall, o, 0.0).is_none() {
                        continue;
                    }
                    let color = match o.kind {
                        OpeningKind::Window if o.glazed => Color {
                            a: 1.0 - GLASS_TRANSPARENCY,
                            ..o.color
                        },
                        _ => Color { a: 1.0, ..o.color },
                    };
                    add_target(
                        &mut materials,
                        color,
                        (pi, SurfaceKind::Opening { wall: wi }, k),
                    );
                }
                for (k, bc) in wall.balconies.iter().enumerate() {
                    let Some(f) = balcony_faces(wall, bc) else {
                        continue;
                    };
                    for i in 0..f.all().count() {
                        let kind = SurfaceKind::Balcony {
                            wall: wi,
                            balcony: k,
                        };
                        add_target(&mut materials, bc.color, (pi, kind, i));
                    }
                }
            }
        }
        if materials.is_empty() {
            return;
        }
        let x = &mut *self.x;
        x.s("<app:appearance>\n<app:Appearance>\n<app:theme>");
        x.s(APPEARANCE_THEME);
        x.s("</app:theme>\n");
        for (mi, (key, targets)) in materials.iter().enumerate() {
            x.s("<app:surfaceDataMember>\n<app:X3DMaterial gml:id=\"");
            x.s(building_id);
            x.s("_m");
            x.uint(mi as u64);
            x.s("\">\n<app:diffuseColor>");
            for (i, c) in key.rgb.iter().enumerate() {
                if i > 0 {
                    x.s(" ");
                }
                x.fixed4(*c);
            }
            x.s("</app:diffuseColor>\n");
            if key.transparency > 0 {
                x.s("<app:transparency>");
                x.fixed4(key.transparency);
                x.s("</app:transparency>\n");
            }
            for &(pi, kind, index) in targets {
                x.s("<app:target>#");
                x.polygon_id(&part_ids[pi], kind, index);
                x.s("</app:target>\n");
            }
            x.s("</app:X3DMaterial>\n</app:surfaceDataMember>\n");
        }
        if self.lod == GeometryLod::Lod4 {
            lod4::materials(x, building_id, b, part_ids);
        }
        x.s("</app:Appearance>\n</app:appearance>\n");
    }

    fn building_attributes(&mut self, roof: RoofShape, height: f64, storeys: u32) {
        let x = &mut *self.x;
        x.s("<bldg:roofType codeSpace=\"");
        x.s(ROOF_TYPE_CODESPACE);
        x.s("\">");
        x.s(roof.citygml_code());
        x.s("</bldg:roofType>\n<bldg:measuredHeight uom=\"m\">");
        x.fixed3(height);
        x.s("</bldg:measuredHeight>\n<bldg:storeysAboveGround>");
        x.uint(u64::from(storeys));
        x.s("</bldg:storeysAboveGround>\n");
    }

    /// The part's geometry properties, in the schema's order (`lodXSolid` before `boundedBy`).
    fn geometry(&mut self, part: &Part, pid: &str) {
        if surfaces(part).next().is_none() {
            // A solid needs at least one surface member; a part without any writes none.
            return;
        }
        if self.lod >= GeometryLod::Lod3 {
            self.geometry_lod3(part, pid);
            return;
        }
        let x = &mut *self.x;
        let lod = self.lod.digit();
        x.s("<bldg:lod");
        x.s(lod);
        x.s("Solid>\n<gml:Solid srsName=\"");
        x.s(self.srs);
        x.s("\">\n<gml:exterior>\n<gml:CompositeSurface>\n");
        for s in surfaces(part) {
            match self.lod {
                GeometryLod::Lod1 => {
                    x.s("<gml:surfaceMember>\n");
                    x.polygon(pid, &s, self.origin);
                    x.s("</gml:surfaceMember>\n");
                }
                GeometryLod::Lod2 | GeometryLod::Lod3 | GeometryLod::Lod4 => {
                    x.s("<gml:surfaceMember xlink:href=\"#");
                    x.polygon_id(pid, s.kind, s.index);
                    x.s("\"/>\n");
                }
            }
        }
        x.s("</gml:CompositeSurface>\n</gml:exterior>\n</gml:Solid>\n</bldg:lod");
        x.s(lod);
        x.s("Solid>\n");
        if self.lod == GeometryLod::Lod1 {
            return;
        }
        for s in surfaces(part) {
            let element = boundary_element(s.kind);
            x.s("<bldg:boundedBy>\n<");
            x.s(element);
            x.s(" gml:id=\"");
            x.polygon_id(pid, s.kind, s.index);
            x.s("_s\">\n<bldg:lod2MultiSurface>\n<gml:MultiSurface srsName=\"");
            x.s(self.srs);
            x.s("\">\n<gml:surfaceMember>\n");
            x.polygon(pid, &s, self.origin);
            x.s("</gml:surfaceMember>\n</gml:MultiSurface>\n</bldg:lod2MultiSurface>\n</");
            x.s(element);
            x.s(">\n</bldg:boundedBy>\n");
        }
    }
}

impl Renderer<'_> {
    /// LOD3 geometry in the schema's order: balconies (`outerBuildingInstallation`), boundary
    /// surfaces with their openings, then `lod3Solid` referencing the closed shell's polygons.
    fn geometry_lod3(&mut self, part: &Part, pid: &str) {
        let (origin, srs, d) = (self.origin, self.srs, self.lod.digit());
        let x = &mut *self.x;
        for (wi, wall) in written_walls(part) {
            for (k, bc) in wall.balconies.iter().enumerate() {
                let Some(faces) = balcony_faces(wall, bc) else {
                    continue;
                };
                x.s("<bldg:outerBuildingInstallation>\n<bldg:BuildingInstallation gml:id=\"");
                x.polygon_id(pid, SurfaceKind::Wall, wi);
                x.s("_b");
                x.uint(k as u64);
                x.s("\">\n<gml:name>balcony</gml:name>\n<bldg:lod");
                x.s(d);
                x.s("Geometry>\n<gml:MultiSurface srsName=\"");
                x.s(srs);
                x.s("\">\n");
                let kind = SurfaceKind::Balcony {
                    wall: wi,
                    balcony: k,
                };
                for (i, face) in faces.all().enumerate() {
                    x.s("<gml:surfaceMember>\n");
                    x.polygon(
                        pid,
                        &Surface {
                            kind,
                            index: i,
                            face,
                        },
                        origin,
                    );
                    x.s("</gml:surfaceMember>\n");
                }
                x.s("</gml:MultiSurface>\n</bldg:lod");
                x.s(d);
                x.s("Geometry>\n</bldg:BuildingInstallation>\n</bldg:outerBuildingInstallation>\n");
            }
        }
        if self.lod == GeometryLod::Lod4 {
            lod4::stairs(x, part, pid, origin, srs);
        }
        // Opening polygons of the written walls, kept for the solid's references.
        let mut opening_refs: Vec<(usize, usize)> = Vec::new();
        for s in surfaces(part) {
            let element = boundary_element(s.kind);
            x.s("<bldg:boundedBy>\n<");
            x.s(element);
            x.s(" gml:id=\"");
            x.polygon_id(pid, s.kind, s.index);
            x.s("_s\">\n<bldg:lod");
            x.s(d);
            x.s("MultiSurface>\n<gml:MultiSurface srsName=\"");
            x.s(srs);
            x.s("\">\n<gml:surfaceMember>\n");
            x.polygon(pid, &s, origin);
            x.s("</gml:surfaceMember>\n</gml:MultiSurface>\n</bldg:lod");
            x.s(d);
            x.s("MultiSurface>\n");
            if s.kind == SurfaceKind::Wall {
                if let Some(wall) = part.walls.get(s.index) {
                    for (k, o) in wall.openings.iter().enumerate() {
                        let Some(face) = opening_face(wall, o, 0.0) else {
                            continue;
                        };
                        opening_refs.push((s.index, k));
                        let element = match o.kind {
                            OpeningKind::Window => "bldg:Window",
                            OpeningKind::Door => "bldg:Door",
                        };
                        x.s("<bldg:opening>\n<");
                        x.s(element);
                        x.s(" gml:id=\"");
                        x.polygon_id(pid, SurfaceKind::Wall, s.index);
                        x.s("_o");
                        x.uint(k as u64);
                        x.s("\">\n<bldg:lod");
                        x.s(d);
                        x.s("MultiSurface>\n<gml:MultiSurface srsName=\"");
                        x.s(srs);
                        x.s("\">\n<gml:surfaceMember>\n");
                        let kind = SurfaceKind::Opening { wall: s.index };
                        x.polygon(
                            pid,
                            &Surface {
                                kind,
                                index: k,
                                face: &face,
                            },
                            origin,
                        );
                        x.s("</gml:surfaceMember>\n</gml:MultiSurface>\n</bldg:lod");
                        x.s(d);
                        x.s("MultiSurface>\n</");
                        x.s(element);
                        x.s(">\n</bldg:opening>\n");
                    }
                }
            }
            x.s("</");
            x.s(element);
            x.s(">\n</bldg:boundedBy>\n");
        }
        x.s("<bldg:lod");
        x.s(d);
        x.s("Solid>\n<gml:Solid srsName=\"");
        x.s(srs);
        x.s("\">\n<gml:exterior>\n<gml:CompositeSurface>\n");
        let shell = surfaces(part).map(|s| (s.kind, s.index)).chain(
            opening_refs
                .iter()
                .map(|&(wall, k)| (SurfaceKind::Opening { wall }, k)),
        );
        for (kind, index) in shell {
            x.s("<gml:surfaceMember xlink:href=\"#");
            x.polygon_id(pid, kind, index);
            x.s("\"/>\n");
        }
        x.s("</gml:CompositeSurface>\n</gml:exterior>\n</gml:Solid>\n</bldg:lod");
        x.s(d);
        x.s("Solid>\n");
        if self.lod == GeometryLod::Lod4 {
            lod4::rooms(x, part, pid, origin, srs);
        }
    }
}

/// The boundary surface element of a part's own polygon kind.
fn boundary_element(kind: SurfaceKind) -> &'static str {
    match kind {
        SurfaceKind::Ground => "bldg:GroundSurface",
        SurfaceKind::Roof => "bldg:RoofSurface",
        // Openings and balconies are not boundary surfaces; never asked for.
        SurfaceKind::Wall | SurfaceKind::Opening { .. } | SurfaceKind::Balcony { .. } => {
            "bldg:WallSurface"
        }
    }
}

/// An output buffer with the few XML writing primitives the writer needs.
struct Xml(Vec<u8>);

impl Xml {
    #[inline]
    fn s(&mut self, s: &str) {
        self.0.extend_from_slice(s.as_bytes());
    }

    /// Writes `s` escaped for element content (`attr == false`) or a double-quoted attribute.
    /// Characters XML 1.0 cannot carry at all (most C0 controls, U+FFFE, U+FFFF) become U+FFFD,
    /// so any name gives a well-formed file; in attributes tabs and line breaks are written as
    /// character references so that attribute normalisation keeps them.
    fn escaped(&mut self, s: &str, attr: bool) {
        let mut start = 0;
        for (i, c) in s.char_indices() {
            let replacement = match c {
                '&' => "&amp;",
                '<' => "&lt;",
                '>' => "&gt;",
                '"' => "&quot;",
                '\'' => "&apos;",
                '\r' => "&#13;",
                '\t' if attr => "&#9;",
                '\n' if attr => "&#10;",
                '\t' | '\n' => continue,
                c if c < ' ' || c == '\u{FFFE}' || c == '\u{FFFF}' => "\u{FFFD}",
                _ => continue,
            };
            self.s(&s[start..i]);
            self.s(replacement);
            start = i + c.len_utf8();
        }
        self.s(&s[start..]);
    }

    fn uint(&mut self, mut v: u64) {
        let mut digits = [0u8; 20];
        let mut i = digits.len();
        loop {
            i -= 1;
            digits[i] = b'0' + (v % 10) as u8;
            v /= 10;
            if v == 0 {
                break;
            }
        }
        self.0.extend_from_slice(&digits[i..]);
    }

    /// A finite number with exactly 3 decimals, never `-0.000`.
    fn fixed3(&mut self, v: f64) {
        let scaled = (v * 1000.0).round();
        if scaled.abs() >= 1e18 {
            // Beyond u64 millimetres (never a real coordinate): let the formatter do it.
            let _ = write!(self.0, "{v:.3}");
            return;
        }
        let n = scaled as i64;
        if n < 0 {
            self.0.push(b'-');
        }
        let m = n.unsigned_abs();
        self.uint(m / 1000);
        let frac = m % 1000;
        self.0.extend_from_slice(&[
            b'.',
            b'0' + (frac / 100) as u8,
            b'0' + (frac / 10 % 10) as u8,
            b'0' + (frac % 10) as u8,
        ]);
    }

    /// A value in 1/10000 as a decimal with 4 places (`5020` -> `0.5020`).
    fn fixed4(&mut self, v: u16) {
        let v = u64::from(v);
        self.uint(v / 10_000);
        let f = v % 10_000;
        self.0.extend_from_slice(&[
            b'.',
            b'0' + (f / 1000) as u8,
            b'0' + (f / 100 % 10) as u8,
            b'0' + (f / 10 % 10) as u8,
            b'0' + (f % 10) as u8,
        ]);
    }

    fn point(&mut self, p: DVec3) {
        self.fixed3(p.x);
        self.0.push(b' ');
        self.fixed3(p.y);
        self.0.push(b' ');
        self.fixed3(p.z);
    }

    fn polygon_id(&mut self, part_id: &str, kind: SurfaceKind, index: usize) {
        self.s(part_id);
        match kind {
            SurfaceKind::Ground => self.s("_g"),
            SurfaceKind::Wall => {
                self.s("_w");
                self.uint(index as u64);
            }
            SurfaceKind::Roof => {
                self.s("_r");
                self.uint(index as u64);
            }
            SurfaceKind::Opening { wall } => {
                self.s("_w");
                self.uint(wall as u64);
                self.s("_o");
                self.uint(index as u64);
                self.s("_p");
            }
            SurfaceKind::Balcony { wall, balcony } => {
                self.s("_w");
                self.uint(wall as u64);
                self.s("_b");
                self.uint(balcony as u64);
                self.s("_");
                self.uint(index as u64);
            }
        }
    }

    /// A `gml:Polygon` with its id, exterior and interiors; rings closed by repeating the first
    /// point, coordinates `origin + p`.
    fn polygon(&mut self, part_id: &str, s: &Surface<'_>, origin: DVec3) {
        self.s("<gml:Polygon gml:id=\"");
        self.polygon_id(part_id, s.kind, s.index);
        self.s("\">\n");
        if let Some(outer) = ring(&s.face.outer) {
            self.s("<gml:exterior>\n");
            self.linear_ring(outer, origin);
            self.s("</gml:exterior>\n");
        }
        for hole in s.face.holes.iter().filter_map(|h| ring(h)) {
            self.s("<gml:interior>\n");
            self.linear_ring(hole, origin);
            self.s("</gml:interior>\n");
        }
        self.s("</gml:Polygon>\n");
    }

    fn linear_ring(&mut self, points: &[DVec3], origin: DVec3) {
        self.s("<gml:LinearRing><gml:posList srsDimension=\"3\">");
        for (i, p) in points.iter().chain(points.first()).enumerate() {
            if i > 0 {
                self.0.push(b' ');
            }
            self.point(origin + *p);
        }
        self.s("</gml:posList></gml:LinearRing>\n");
    }
}

#[cfg(test)]
mod tests {
    use std::collections::{BTreeMap, BTreeSet};

    use glam::{DVec2, DVec3};
    use quick_xml::events::Event;
    use quick_xml::XmlVersion;

    use super::*;
    use crate::crs::Crs;
    use crate::export::lod3geom::samples;
    use crate::geometry::Polygon;
    use crate::model::SourceId;
    use crate::model::Wall;

    const ORIGIN: DVec3 = DVec3::new(574_321.5, 6_279_876.25, 146.0);

    fn ctx(lod: Lod) -> OutputContext {
        OutputContext {
            crs: Crs::Lambert93,
            origin: ORIGIN,
            origin_lonlat: (1.44, 43.6),
            lod,
            source_name: "tiny <&> \"town\".osm.pbf".into(),
            seed: 42,
        }
    }

    fn at(v: DVec2, z: f64) -> DVec3 {
        v.extend(z)
    }

    /// An extruded footprint with a flat roof: one wall per ring edge, roof and ground with the
    /// footprint's holes.
    fn prism(
        key: &str,
        outer: Vec<DVec2>,
        holes: Vec<Vec<DVec2>>,
        base: f64,
        top: f64,
        wall: Color,
        roof: Color,
    ) -> Part {
        let footprint = Polygon::new(outer, holes);
        let mut walls = Vec::new();
        for r in footprint.rings() {
            for i in 0..r.len() {
                let (a, b) = (r[i], r[(i + 1) % r.len()]);
                walls.push(Wall {
                    start: a,
                    end: b,
                    base_z: base,
                    top_z: top,
                    thickness: 0.3,
                    outline: Face::new(vec![at(a, base), at(b, base), at(b, top), at(a, top)]),
                    storey: 0,
                    openings: Vec::new(),
                    balconies: Vec::new(),
                });
            }
        }
        let lift = |r: &Vec<DVec2>, z: f64| r.iter().map(|&p| at(p, z)).collect::<Vec<_>>();
        let roof_face = Face {
            outer: lift(&footprint.outer, top),
            holes: footprint.holes.iter().map(|h| lift(h, top)).collect(),
        };
        let rev = |mut v: Vec<DVec3>| {
            v.reverse();
            v
        };
        let ground = Face {
            outer: rev(lift(&footprint.outer, base)),
            holes: footprint.holes.iter().map(|h| rev(lift(h, base))).collect(),
        };
        Part {
            key: key.into(),
            footprint,
            base_z: base,
            eave_z: top,
            top_z: top,
            storeys: ((top - base) / 3.0).round().max(1.0) as u32,
            levels: vec![base],
            wall_color: wall,
            roof_color: roof,
            roof_shape: RoofShape::Flat,
            walls,
            roof: vec![roof_face],
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

    const BEIGE: Color = Color::rgb(0.96, 0.96, 0.86);
    const RED: Color = Color::rgb(0.7, 0.2, 0.1);

    fn building(id: SourceId, parts: Vec<Part>) -> Building {
        let base = parts.iter().map(|p| p.base_z).fold(f64::INFINITY, f64::min);
        let tallest = parts
            .iter()
            .max_by(|a, b| a.top_z.total_cmp(&b.top_z))
            .cloned();
        let top = tallest.as_ref().map_or(base, |p| p.top_z);
        Building {
            id,
            name: None,
            zone: "earth/France/Occitanie/Toulouse".into(),
            appearance: "Toulouse#1".into(),
            base_z: base,
            measured_height: top - base,
            storeys_above_ground: tallest.as_ref().map_or(1, |p| p.storeys),
            roof_shape: tallest.as_ref().map_or(RoofShape::Flat, |p| p.roof_shape),
            parts,
            lod: Lod::Lod2,
        }
    }

    /// The 10 x 6 m box, 9 m high: 4 walls, a flat roof, a ground.
    fn simple_box() -> Building {
        let mut b = building(
            SourceId::Way(123),
            vec![prism(
                "p0",
                rect(0.0, 0.0, 10.0, 6.0),
                vec![],
                0.0,
                9.0,
                BEIGE,
                RED,
            )],
        );
        b.name = Some("Café \"<Chez Marie & Fils>\" l'été".into());
        b
    }

    fn two_parts() -> Building {
        building(
            SourceId::Relation(45),
            vec![
                prism(
                    "p0",
                    rect(0.0, 0.0, 10.0, 6.0),
                    vec![],
                    0.0,
                    12.0,
                    BEIGE,
                    RED,
                ),
                prism(
                    "p1",
                    rect(10.0, 0.0, 16.0, 6.0),
                    vec![],
                    0.0,
                    6.0,
                    Color::WHITE,
                    RED,
                ),
            ],
        )
    }

    fn courtyard() -> Building {
        let hole = vec![
            DVec2::new(5.0, 5.0),
            DVec2::new(5.0, 15.0),
            DVec2::new(15.0, 15.0),
            DVec2::new(15.0, 5.0),
        ];
        building(
            SourceId::Shape(7),
            vec![prism(
                "p0",
                rect(0.0, 0.0, 20.0, 20.0),
                vec![hole],
                2.0,
                14.0,
                BEIGE,
                RED,
            )],
        )
    }

    /// The box with a hipped roof: ridge from (3,3) to (7,3), 3 m above the eave.
    fn hipped() -> Building {
        let (e, r) = (6.0, 9.0);
        let mut part = prism("p0", rect(0.0, 0.0, 10.0, 6.0), vec![], 0.0, e, BEIGE, RED);
        let p = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
        part.roof = vec![
            Face::new(vec![
                p(0.0, 0.0, e),
                p(10.0, 0.0, e),
                p(7.0, 3.0, r),
                p(3.0, 3.0, r),
            ]),
            Face::new(vec![p(10.0, 0.0, e), p(10.0, 6.0, e), p(7.0, 3.0, r)]),
            Face::new(vec![
                p(10.0, 6.0, e),
                p(0.0, 6.0, e),
                p(3.0, 3.0, r),
                p(7.0, 3.0, r),
            ]),
            Face::new(vec![p(0.0, 6.0, e), p(0.0, 0.0, e), p(3.0, 3.0, r)]),
        ];
        part.top_z = r;
        part.roof_shape = RoofShape::Hipped;
        building(SourceId::Way(-9), vec![part])
    }

    fn all_buildings() -> Vec<Building> {
        vec![simple_box(), two_parts(), courtyard(), hipped()]
    }

    pub(super) fn write_all(lod: Lod, buildings: &[Building]) -> Vec<u8> {
        let mut w = CityGmlWriter::with_srs_name(Vec::new(), "EPSG:2154");
        w.begin(&ctx(lod)).unwrap();
        for b in buildings {
            w.write(b).unwrap();
        }
        w.finish().unwrap();
        w.into_inner()
    }

    /// A parsed element: enough of a DOM to check structure.
    #[derive(Debug, Default)]
    pub(super) struct El {
        pub(super) name: String,
        pub(super) attrs: BTreeMap<String, String>,
        pub(super) text: String,
        pub(super) children: Vec<El>,
    }

    impl El {
        pub(super) fn attr(&self, k: &str) -> Option<&str> {
            self.attrs.get(k).map(String::as_str)
        }
        pub(super) fn child(&self, name: &str) -> Option<&El> {
            self.children.iter().find(|c| c.name == name)
        }
        pub(super) fn children_named<'a>(
            &'a self,
            name: &'a str,
        ) -> impl Iterator<Item = &'a El> + 'a {
            self.children.iter().filter(move |c| c.name == name)
        }
        pub(super) fn descendants(&self) -> Vec<&El> {
            let mut out = vec![self];
            let mut i = 0;
            while i < out.len() {
                out.extend(out[i].children.iter());
                i += 1;
            }
            out
        }
        pub(super) fn count(&self, name: &str) -> usize {
            self.descendants().iter().filter(|e| e.name == name).count()
        }
        pub(super) fn find_all(&self, name: &str) -> Vec<&El> {
            self.descendants()
                .into_iter()
                .filter(|e| e.name == name)
                .collect()
        }
    }

    /// Parses the whole document with quick-xml, failing on any well-formedness error.
    pub(super) fn parse(bytes: &[u8]) -> El {
        let text = std::str::from_utf8(bytes).expect("UTF-8");
        let mut reader = quick_xml::Reader::from_str(text);
        let mut stack = vec![El::default()];
        let element = |e: &quick_xml::events::BytesStart<'_>| {
            let mut el = El {
                name: e.name().as_ref().to_string(),
                ..El::default()
            };
            for a in e.attributes() {
                let a = a.expect("attribute");
                let v = a
                    .normalized_value(XmlVersion::Implicit1_0)
                    .expect("attribute value");
                assert!(
                    el.attrs
                        .insert(a.key.as_ref().to_string(), v.into_owned())
                        .is_none(),
                    "duplicate attribute"
                );
            }
            el
        };
        loop {
            match reader.read_event().expect("well-formed XML") {
                Event::Start(e) => stack.push(element(&e)),
                Event::Empty(e) => {
                    let el = element(&e);
                    stack.last_mut().unwrap().children.push(el);
                }
                Event::End(_) => {
                    let el = stack.pop().unwrap();
                    stack.last_mut().unwrap().children.push(el);
                }
                Event::Text(t) => stack.last_mut().unwrap().text.push_str(&t.xml10_content()),
                Event::GeneralRef(r) => {
                    let c = match r.resolve_char_ref().expect("char ref") {
                        Some(c) => c,
                        None => match &*r {
                            "amp" => '&',
                            "lt" => '<',
                            "gt" => '>',
                            "quot" => '"',
                            "apos" => '\'',
                            other => panic!("unknown entity {other}"),
                        },
                    };
                    stack.last_mut().unwrap().text.push(c);
                }
                Event::Eof => break,
                _ => {}
            }
        }
        assert_eq!(stack.len(), 1, "unclosed elements");
        let mut doc = stack.pop().unwrap();
        assert_eq!(doc.children.len(), 1, "one root element");
        doc.children.pop().unwrap()
    }

    fn buildings_of(root: &El) -> Vec<&El> {
        root.children_named("core:cityObjectMember")
            .map(|m| m.child("bldg:Building").expect("Building"))
            .collect()
    }

    fn numbers(s: &str) -> Vec<f64> {
        s.split_whitespace()
            .map(|t| t.parse().expect("number"))
            .collect()
    }

    /// Every gml:id is unique and every local reference (xlink:href, app:target) resolves.
    fn check_ids(root: &El) -> BTreeSet<String> {
        let mut ids = BTreeSet::new();
        for e in root.descendants() {
            if let Some(id) = e.attr("gml:id") {
                assert!(ids.insert(id.to_string()), "duplicate gml:id {id}");
                let first = id.chars().next().unwrap();
                assert!(
                    first.is_ascii_alphabetic() || first == '_',
                    "{id} is not an NCName"
                );
                assert!(
                    id.chars()
                        .all(|c| c.is_ascii_alphanumeric() || "_-.".contains(c)),
                    "{id} is not an NCName"
                );
            }
        }
        for e in root.descendants() {
            let reference = match (e.attr("xlink:href"), e.name.as_str()) {
                (Some(h), _) => h.to_string(),
                (None, "app:target") => e.text.clone(),
                _ => continue,
            };
            let target = reference.strip_prefix('#').expect("local reference");
            assert!(ids.contains(target), "dangling reference {reference}");
        }
        ids
    }

    #[test]
    fn header_namespaces_and_root() {
        let root = parse(&write_all(Lod::Lod2, &[]));
        assert_eq!(root.name, "core:CityModel");
        for (p, ns) in [
            ("core", "http://www.opengis.net/citygml/2.0"),
            ("bldg", "http://www.opengis.net/citygml/building/2.0"),
            ("gml", "http://www.opengis.net/gml"),
            ("app", "http://www.opengis.net/citygml/appearance/2.0"),
            ("gen", "http://www.opengis.net/citygml/generics/2.0"),
            ("xlink", "http://www.w3.org/1999/xlink"),
            ("xsi", "http://www.w3.org/2001/XMLSchema-instance"),
        ] {
            assert_eq!(root.attr(&format!("xmlns:{p}")), Some(ns), "namespace {p}");
        }
        let loc = root.attr("xsi:schemaLocation").unwrap();
        assert!(loc.contains("http://schemas.opengis.net/citygml/building/2.0/building.xsd"));
        assert!(loc.contains("http://schemas.opengis.net/citygml/appearance/2.0/appearance.xsd"));
        assert_eq!(
            root.child("gml:name").unwrap().text,
            "tiny <&> \"town\".osm.pbf"
        );
        assert!(root
            .child("gml:description")
            .unwrap()
            .text
            .contains("seed 42"));
        assert_eq!(root.children_named("core:cityObjectMember").count(), 0);
    }

    #[test]
    fn lod2_counts_ids_and_references() {
        let buildings = all_buildings();
        let root = parse(&write_all(Lod::Lod2, &buildings));
        check_ids(&root);
        let written = buildings_of(&root);
        assert_eq!(written.len(), buildings.len());
        assert_eq!(root.count("bldg:Building"), 4);
        assert_eq!(root.count("bldg:BuildingPart"), 2);
        let walls: usize = buildings
            .iter()
            .flat_map(|b| &b.parts)
            .map(|p| p.walls.len())
            .sum();
        let roofs: usize = buildings
            .iter()
            .flat_map(|b| &b.parts)
            .map(|p| p.roof.len())
            .sum();
        let parts: usize = buildings.iter().map(|b| b.parts.len()).sum();
        assert_eq!(root.count("bldg:WallSurface"), walls);
        assert_eq!(root.count("bldg:RoofSurface"), roofs);
        assert_eq!(root.count("bldg:GroundSurface"), parts);
        assert_eq!(root.count("bldg:lod2Solid"), parts);
        assert_eq!(root.count("bldg:lod1Solid"), 0);
        let polygons: usize = buildings.iter().map(Building::polygon_count).sum();
        assert_eq!(root.count("gml:Polygon"), polygons);
        // The solids reference every polygon once and hold none inline.
        let refs: Vec<&El> = root
            .find_all("gml:surfaceMember")
            .into_iter()
            .filter(|e| e.attr("xlink:href").is_some())
            .collect();
        assert_eq!(refs.len(), polygons);
        for s in root.find_all("gml:Solid") {
            assert_eq!(s.count("gml:Polygon"), 0);
        }

        // Identifiers come from the source id and the part keys.
        let b0 = written[0];
        assert_eq!(b0.attr("gml:id"), Some("B_way_123"));
        assert!(b0
            .find_all("bldg:WallSurface")
            .iter()
            .any(|w| w.attr("gml:id") == Some("B_way_123_p0_w3_s")));
        assert!(b0
            .find_all("gml:Polygon")
            .iter()
            .any(|w| w.attr("gml:id") == Some("B_way_123_p0_w3")));
        assert_eq!(written[1].attr("gml:id"), Some("B_relation_45"));
        assert_eq!(written[3].attr("gml:id"), Some("B_way_-9"));

        // The hipped roof: 4 RoofSurfaces, roofType 1040, measuredHeight 9.
        let hip = written[3];
        assert_eq!(hip.count("bldg:RoofSurface"), 4);
        assert_eq!(hip.child("bldg:roofType").unwrap().text, "1040");
        assert_eq!(hip.child("bldg:measuredHeight").unwrap().text, "9.000");
        assert_eq!(
            hip.child("bldg:measuredHeight").unwrap().attr("uom"),
            Some("m")
        );
    }

    #[test]
    fn lod1_solids_hold_polygons_inline() {
        let buildings = all_buildings();
        let root = parse(&write_all(Lod::Lod1, &buildings));
        check_ids(&root);
        let parts: usize = buildings.iter().map(|b| b.parts.len()).sum();
        assert_eq!(root.count("bldg:lod1Solid"), parts);
        assert_eq!(
            root.count("bldg:lod2Solid")
                + root.count("bldg:boundedBy")
                + root.count("bldg:WallSurface"),
            0
        );
        let polygons: usize = buildings.iter().map(Building::polygon_count).sum();
        assert_eq!(root.count("gml:Polygon"), polygons);
        for s in root.find_all("gml:Solid") {
            assert_eq!(s.attr("srsName"), Some("EPSG:2154"));
            let cs = s
                .child("gml:exterior")
                .and_then(|e| e.child("gml:CompositeSurface"))
                .expect("CompositeSurface");
            assert!(cs
                .children_named("gml:surfaceMember")
                .all(|m| m.child("gml:Polygon").is_some()));
        }
    }

    #[test]
    fn single_part_geometry_on_building_several_parts_in_building_parts() {
        let root = parse(&write_all(Lod::Lod2, &[simple_box(), two_parts()]));
        let b = buildings_of(&root);
        assert!(b[0].child("bldg:lod2Solid").is_some());
        assert_eq!(b[0].children_named("bldg:boundedBy").count(), 6);
        assert!(b[0].child("bldg:consistsOfBuildingPart").is_none());

        assert!(b[1].child("bldg:lod2Solid").is_none());
        assert!(b[1].child("bldg:boundedBy").is_none());
        let parts: Vec<&El> = b[1]
            .children_named("bldg:consistsOfBuildingPart")
            .map(|c| c.child("bldg:BuildingPart").unwrap())
            .collect();
        assert_eq!(parts.len(), 2);
        assert_eq!(parts[0].attr("gml:id"), Some("B_relation_45_p0"));
        assert_eq!(parts[1].child("bldg:measuredHeight").unwrap().text, "6.000");
        assert_eq!(parts[1].child("bldg:storeysAboveGround").unwrap().text, "2");
        assert_eq!(parts[0].child("bldg:roofType").unwrap().text, "1000");
        for p in parts {
            assert!(p.child("bldg:lod2Solid").is_some());
            assert_eq!(p.children_named("bldg:boundedBy").count(), 6);
        }
        // The building itself carries the overall values.
        assert_eq!(b[1].child("bldg:measuredHeight").unwrap().text, "12.000");
        assert_eq!(b[1].child("bldg:storeysAboveGround").unwrap().text, "4");
    }

    #[test]
    fn element_order_follows_the_schema() {
        let root = parse(&write_all(Lod::Lod2, &[simple_box()]));
        let b = buildings_of(&root)[0];
        let names: Vec<&str> = b.children.iter().map(|c| c.name.as_str()).collect();
        let rank = |n: &str| match n {
            "gml:name" => 0,
            "gml:boundedBy" => 1,
            "gen:stringAttribute" | "app:appearance" => 2,
            "bldg:roofType" => 3,
            "bldg:measuredHeight" => 4,
            "bldg:storeysAboveGround" => 5,
            "bldg:lod2Solid" => 6,
            "bldg:boundedBy" => 7,
            other => panic!("unexpected {other}"),
        };
        assert!(
            names.windows(2).all(|w| rank(w[0]) <= rank(w[1])),
            "{names:?}"
        );
        assert_eq!(
            b.child("gml:name").unwrap().text,
            "Café \"<Chez Marie & Fils>\" l'été"
        );
        let attrs: BTreeMap<&str, &str> = b
            .children_named("gen:stringAttribute")
            .map(|a| {
                (
                    a.attr("name").unwrap(),
                    a.child("gen:value").unwrap().text.as_str(),
                )
            })
            .collect();
        assert_eq!(attrs["sourceId"], "way/123");
        assert_eq!(attrs["zone"], "earth/France/Occitanie/Toulouse");
        assert_eq!(attrs["appearance"], "Toulouse#1");
    }

    #[test]
    fn courtyard_has_interiors() {
        let root = parse(&write_all(Lod::Lod2, &[courtyard()]));
        let b = buildings_of(&root)[0];
        // 4 outer + 4 courtyard walls.
        assert_eq!(b.count("bldg:WallSurface"), 8);
        for name in ["bldg:RoofSurface", "bldg:GroundSurface"] {
            let s = b.find_all(name);
            assert_eq!(s.len(), 1);
            let interiors = s[0].find_all("gml:interior");
            assert_eq!(interiors.len(), 1, "{name}");
            let pos = numbers(&interiors[0].find_all("gml:posList")[0].text);
            assert_eq!(pos.len(), 5 * 3, "closed hole ring");
        }
        for w in b.find_all("bldg:WallSurface") {
            assert_eq!(w.count("gml:interior"), 0);
        }
    }

    #[test]
    fn coordinates_are_origin_plus_local_and_rings_closed() {
        let src = hipped();
        let root = parse(&write_all(Lod::Lod2, std::slice::from_ref(&src)));
        let b = buildings_of(&root)[0];
        let polygons: BTreeMap<&str, &El> = b
            .find_all("gml:Polygon")
            .into_iter()
            .map(|p| (p.attr("gml:id").unwrap(), p))
            .collect();
        let check = |id: &str, face: &Face| {
            let list = polygons[id]
                .child("gml:exterior")
                .unwrap()
                .find_all("gml:posList")[0];
            assert_eq!(list.attr("srsDimension"), Some("3"));
            let v = numbers(&list.text);
            assert_eq!(v.len(), (face.outer.len() + 1) * 3);
            for (i, p) in face.outer.iter().chain(face.outer.first()).enumerate() {
                let w = ORIGIN + *p;
                for (k, c) in [w.x, w.y, w.z].into_iter().enumerate() {
                    assert!(
                        (v[i * 3 + k] - c).abs() < 5e-4,
                        "{id} point {i}: {} vs {c}",
                        v[i * 3 + k]
                    );
                }
            }
        };
        let part = &src.parts[0];
        check("B_way_-9_p0_g", &part.ground);
        for (i, w) in part.walls.iter().enumerate() {
            check(&format!("B_way_-9_p0_w{i}"), &w.outline);
        }
        for (i, f) in part.roof.iter().enumerate() {
            check(&format!("B_way_-9_p0_r{i}"), f);
        }
        // The envelope is the bounds of the building in the output CRS.
        let env = b
            .child("gml:boundedBy")
            .unwrap()
            .child("gml:Envelope")
            .unwrap();
        assert_eq!(env.attr("srsName"), Some("EPSG:2154"));
        assert_eq!(env.attr("srsDimension"), Some("3"));
        let lo = numbers(&env.child("gml:lowerCorner").unwrap().text);
        let hi = numbers(&env.child("gml:upperCorner").unwrap().text);
        assert_eq!(lo, vec![574_321.5, 6_279_876.25, 146.0]);
        assert_eq!(hi, vec![574_331.5, 6_279_882.25, 155.0]);
    }

    #[test]
    fn appearance_one_material_per_colour() {
        let root = parse(&write_all(Lod::Lod2, &[two_parts()]));
        let b = buildings_of(&root)[0];
        let app = b
            .child("app:appearance")
            .unwrap()
            .child("app:Appearance")
            .unwrap();
        assert_eq!(app.child("app:theme").unwrap().text, "citygen");
        let mats: Vec<&El> = app
            .children_named("app:surfaceDataMember")
            .map(|m| m.child("app:X3DMaterial").unwrap())
            .collect();
        // Ground grey, beige walls, red roofs (shared by both parts), white walls.
        let colours: Vec<&str> = mats
            .iter()
            .map(|m| m.child("app:diffuseColor").unwrap().text.as_str())
            .collect();
        assert_eq!(
            colours,
            vec![
                "0.5000 0.5000 0.5000",
                "0.9600 0.9600 0.8600",
                "0.7000 0.2000 0.1000",
                "1.0000 1.0000 1.0000"
            ]
        );
        let targets: Vec<usize> = mats
            .iter()
            .map(|m| m.children_named("app:target").count())
            .collect();
        assert_eq!(targets, vec![2, 4, 2, 4]);
        // Every polygon is coloured exactly once.
        let mut all: Vec<&str> = mats
            .iter()
            .flat_map(|m| m.children_named("app:target").map(|t| t.text.as_str()))
            .collect();
        all.sort_unstable();
        let n = all.len();
        all.dedup();
        assert_eq!(all.len(), n);
        assert_eq!(n, root.count("gml:Polygon"));
        assert!(mats.iter().all(|m| m.child("app:transparency").is_none()));
    }

    /// FNV-1a 64: a dependency-free fingerprint of an output.
    fn fnv1a(bytes: &[u8]) -> u64 {
        bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
            (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
        })
    }

    /// LOD1 and LOD2 output is byte-identical to the writer before LOD3 support (fingerprints
    /// taken from that writer on the same samples).
    #[test]
    fn lod1_lod2_output_unchanged_by_lod3_support() {
        let b = all_buildings();
        assert_eq!(
            fnv1a(&write_all(Lod::Lod1, &b)),
            3_655_589_629_691_104_898,
            "LOD1"
        );
        assert_eq!(
            fnv1a(&write_all(Lod::Lod2, &b)),
            11_241_214_483_957_492_289,
            "LOD2"
        );
    }

    #[test]
    fn output_is_deterministic() {
        let b = all_buildings();
        assert_eq!(write_all(Lod::Lod2, &b), write_all(Lod::Lod2, &b));
        assert_eq!(write_all(Lod::Lod1, &b), write_all(Lod::Lod1, &b));
    }

    #[test]
    fn number_formatting() {
        let f = |v: f64| {
            let mut x = Xml(Vec::new());
            x.fixed3(v);
            String::from_utf8(x.0).unwrap()
        };
        assert_eq!(f(0.0), "0.000");
        assert_eq!(f(-0.0), "0.000");
        assert_eq!(f(-0.0004), "0.000");
        assert_eq!(f(-0.0006), "-0.001");
        assert_eq!(f(1.5), "1.500");
        assert_eq!(f(-12.3456), "-12.346");
        assert_eq!(f(5_432_109.012_5), "5432109.013");
        assert_eq!(f(1e300), format!("{:.3}", 1e300));
    }

    #[test]
    fn escaping_keeps_any_text_well_formed() {
        let mut b = simple_box();
        b.name = Some("a&b<c>d\"e'f\u{1}g\u{FFFF}h\ti\nj\rk".into());
        b.zone = "z\"one\t<1>".into();
        let root = parse(&write_all(Lod::Lod1, &[b]));
        let bl = buildings_of(&root)[0];
        assert_eq!(
            bl.child("gml:name").unwrap().text,
            "a&b<c>d\"e'f\u{FFFD}g\u{FFFD}h\ti\nj\rk"
        );
        let zone = bl
            .children_named("gen:stringAttribute")
            .find(|a| a.attr("name") == Some("zone"))
            .unwrap();
        assert_eq!(zone.child("gen:value").unwrap().text, "z\"one\t<1>");
        let mut x = Xml(Vec::new());
        x.escaped("a\tb\n\"", true);
        assert_eq!(x.0, b"a&#9;b&#10;&quot;");
    }

    #[test]
    fn odd_part_keys_and_degenerate_faces() {
        let mut b = two_parts();
        b.parts[0].key = "same key".into();
        b.parts[1].key = "same key".into();
        // A closed ring is accepted, a two-point face is left out.
        let mut closed = b.parts[0].roof[0].outer.clone();
        closed.push(closed[0]);
        b.parts[0].roof[0].outer = closed;
        b.parts[1].roof.push(Face::new(vec![DVec3::ZERO, DVec3::X]));
        let root = parse(&write_all(Lod::Lod2, &[b.clone()]));
        check_ids(&root);
        let parts = root.find_all("bldg:BuildingPart");
        assert_eq!(parts[0].attr("gml:id"), Some("B_relation_45_p0"));
        assert_eq!(parts[1].attr("gml:id"), Some("B_relation_45_p1"));
        assert_eq!(root.count("bldg:RoofSurface"), 2);
        assert_eq!(root.count("gml:Polygon"), b.polygon_count() - 1);
        let roof = root.find_all("bldg:RoofSurface")[0];
        assert_eq!(numbers(&roof.find_all("gml:posList")[0].text).len(), 5 * 3);
    }

    #[test]
    fn rejects_non_finite_geometry_without_writing_it() {
        let mut bad = simple_box();
        bad.parts[0].walls[2].outline.outer[1].z = f64::NAN;
        let mut w = CityGmlWriter::with_srs_name(Vec::new(), "EPSG:2154");
        w.begin(&ctx(Lod::Lod2)).unwrap();
        let err = w.write(&bad).unwrap_err();
        assert!(err.to_string().contains("way/123"), "{err}");
        assert!(err.to_string().contains("p0"), "{err}");
        w.write(&hipped()).unwrap();
        w.finish().unwrap();
        let root = parse(&w.into_inner());
        assert_eq!(buildings_of(&root).len(), 1);
    }

    #[test]
    fn call_order_is_enforced() {
        let mut w = CityGmlWriter::with_srs_name(Vec::new(), "EPSG:2154");
        assert!(w.write(&simple_box()).is_err());
        assert!(w.finish().is_err());
        w.begin(&ctx(Lod::Lod1)).unwrap();
        assert!(w.begin(&ctx(Lod::Lod1)).is_err());
        w.finish().unwrap();
        assert!(w.write(&simple_box()).is_err());
        assert!(w.finish().is_err());
    }

    // ---- LOD3 ----

    /// Points of a polygon's rings, each ring without its closing point.
    fn rings_of(polygon: &El) -> Vec<Vec<DVec3>> {
        polygon
            .find_all("gml:posList")
            .iter()
            .map(|l| {
                let v = numbers(&l.text);
                let mut pts: Vec<DVec3> = v
                    .chunks_exact(3)
                    .map(|c| DVec3::new(c[0], c[1], c[2]) - ORIGIN)
                    .collect();
                assert_eq!(pts.first(), pts.last(), "closed ring");
                pts.pop();
                pts
            })
            .collect()
    }

    #[test]
    fn lod3_openings_per_building_match_the_model() {
        let buildings = samples::all();
        let root = parse(&write_all(Lod::Lod3, &buildings));
        check_ids(&root);
        assert!(root
            .child("gml:description")
            .unwrap()
            .text
            .contains("LOD3 geometry"));
        for (el, b) in buildings_of(&root).into_iter().zip(&buildings) {
            let (windows, doors) = samples::counts(b);
            assert_eq!(el.count("bldg:Window"), windows, "{}", b.id);
            assert_eq!(el.count("bldg:Door"), doors, "{}", b.id);
            assert_eq!(el.count("bldg:opening"), windows + doors);
            let walls: usize = b.parts.iter().map(|p| p.walls.len()).sum();
            assert_eq!(el.count("bldg:WallSurface"), walls);
            // LOD3 properties only.
            for name in ["bldg:lod2Solid", "bldg:lod2MultiSurface", "bldg:lod1Solid"] {
                assert_eq!(el.count(name), 0, "{name}");
            }
            assert_eq!(el.count("bldg:lod3Solid"), b.parts.len());
            let balconies: usize = b
                .parts
                .iter()
                .flat_map(|p| &p.walls)
                .map(|w| w.balconies.len())
                .sum();
            assert_eq!(el.count("bldg:BuildingInstallation"), balconies);
        }
        let house = buildings_of(&root)[0];
        assert_eq!(house.count("bldg:Window"), 4);
        assert_eq!(house.count("bldg:Door"), 1);
        let ids: Vec<&str> = house
            .find_all("bldg:Window")
            .iter()
            .chain(house.find_all("bldg:Door").iter())
            .map(|e| e.attr("gml:id").unwrap())
            .collect();
        assert_eq!(
            ids,
            [
                "B_way_301_p0_w0_o0",
                "B_way_301_p0_w0_o2",
                "B_way_301_p0_w4_o0",
                "B_way_301_p0_w4_o1",
                "B_way_301_p0_w0_o1"
            ]
        );
    }

    #[test]
    fn lod3_walls_keep_holes_filled_by_opening_polygons() {
        let buildings = samples::all();
        let root = parse(&write_all(Lod::Lod3, &buildings));
        for (el, b) in buildings_of(&root).into_iter().zip(&buildings) {
            let model_walls: Vec<&Wall> = b.parts.iter().flat_map(|p| &p.walls).collect();
            let surfaces = el.find_all("bldg:WallSurface");
            assert_eq!(surfaces.len(), model_walls.len());
            for (s, w) in surfaces.iter().zip(&model_walls) {
                // Schema order inside a boundary surface: geometry, then openings.
                let names: Vec<&str> = s.children.iter().map(|c| c.name.as_str()).collect();
                let first_opening = names.iter().position(|n| *n == "bldg:opening");
                assert_eq!(names[0], "bldg:lod3MultiSurface");
                assert!(
                    first_opening.is_none_or(|i| names[i..].iter().all(|n| *n == "bldg:opening"))
                );
                let wall_poly = s
                    .child("bldg:lod3MultiSurface")
                    .unwrap()
                    .find_all("gml:Polygon")[0];
                assert_eq!(wall_poly.count("gml:interior"), w.openings.len());
                let rings = rings_of(wall_poly);
                let normal = w.outline.normal();
                let openings: Vec<&El> = s
                    .children_named("bldg:opening")
                    .map(|o| &o.children[0])
                    .collect();
                assert_eq!(openings.len(), w.openings.len());
                for (k, (o_el, o)) in openings.iter().zip(&w.openings).enumerate() {
                    let name = match o.kind {
                        OpeningKind::Window => "bldg:Window",
                        OpeningKind::Door => "bldg:Door",
                    };
                    assert_eq!(o_el.name, name);
                    let poly = o_el.find_all("gml:Polygon")[0];
                    let pts = &rings_of(poly)[0];
                    // Faces outward like the wall ...
                    let n = crate::geometry::newell_normal(pts).normalize();
                    assert!((n - normal).length() < 1e-3, "{n} vs {normal}");
                    assert!(
                        (crate::geometry::newell_normal(pts).length() / 2.0
                            - o.width() * o.height())
                        .abs()
                            < 1e-2
                    );
                    // ... and has the corners of the wall's hole k.
                    let hole = &rings[k + 1];
                    for p in pts {
                        assert!(
                            hole.iter().any(|q| q.distance(*p) < 1e-3),
                            "{p} not in hole"
                        );
                    }
                    // Holes run against the outline.
                    let hn = crate::geometry::newell_normal(hole).normalize();
                    assert!((hn + normal).length() < 1e-3);
                }
            }
        }
    }

    #[test]
    fn lod3_solid_references_the_closed_shell() {
        let buildings = samples::all();
        let root = parse(&write_all(Lod::Lod3, &buildings));
        for (el, b) in buildings_of(&root).into_iter().zip(&buildings) {
            let solids = el.find_all("bldg:lod3Solid");
            for (solid, part) in solids.iter().zip(&b.parts) {
                let refs: Vec<&str> = solid
                    .find_all("gml:surfaceMember")
                    .iter()
                    .map(|m| m.attr("xlink:href").unwrap())
                    .collect();
                let openings: usize = part.walls.iter().map(|w| w.openings.len()).sum();
                assert_eq!(
                    refs.len(),
                    1 + part.walls.len() + part.roof.len() + openings
                );
                assert_eq!(solid.count("gml:Polygon"), 0);
                assert_eq!(refs.iter().filter(|r| r.ends_with("_p")).count(), openings);
            }
            // Closed shell: the area vectors of the referenced polygons (outer rings minus holes,
            // plus the opening polygons) cancel out.
            let polygons: BTreeMap<&str, &El> = el
                .find_all("gml:Polygon")
                .into_iter()
                .map(|p| (p.attr("gml:id").unwrap(), p))
                .collect();
            for solid in solids {
                let mut sum = DVec3::ZERO;
                for m in solid.find_all("gml:surfaceMember") {
                    let id = m.attr("xlink:href").unwrap().trim_start_matches('#');
                    for r in rings_of(polygons[id]) {
                        sum += crate::geometry::newell_normal(&r);
                    }
                }
                assert!(sum.length() < 1e-2, "{} open shell: {sum}", b.id);
            }
        }
    }

    #[test]
    fn lod3_element_order_and_balconies() {
        let b = samples::with_balcony();
        let root = parse(&write_all(Lod::Lod3, std::slice::from_ref(&b)));
        check_ids(&root);
        let parts = root.find_all("bldg:BuildingPart");
        assert_eq!(parts.len(), 2);
        let rank = |n: &str| match n {
            "gml:name" | "gml:boundedBy" | "gen:stringAttribute" | "app:appearance" => 0,
            "bldg:roofType" | "bldg:measuredHeight" | "bldg:storeysAboveGround" => 1,
            "bldg:outerBuildingInstallation" => 2,
            "bldg:boundedBy" => 3,
            "bldg:lod3Solid" => 4,
            other => panic!("unexpected {other}"),
        };
        for p in &parts {
            let names: Vec<&str> = p.children.iter().map(|c| c.name.as_str()).collect();
            assert!(
                names.windows(2).all(|w| rank(w[0]) <= rank(w[1])),
                "{names:?}"
            );
        }
        let inst = parts[0].find_all("bldg:BuildingInstallation");
        assert_eq!(inst.len(), 1);
        assert_eq!(inst[0].attr("gml:id"), Some("B_way_303_p0_w4_b0"));
        assert_eq!(inst[0].child("gml:name").unwrap().text, "balcony");
        let geom = inst[0].child("bldg:lod3Geometry").unwrap();
        assert_eq!(
            geom.count("gml:Polygon"),
            9,
            "slab box and three railing panels"
        );
        // The slab stands 1.2 m out of the wall (y = 0, outside is -y); the envelope covers it.
        let ys: Vec<f64> = geom
            .find_all("gml:Polygon")
            .iter()
            .flat_map(|p| rings_of(p).concat())
            .map(|p| p.y)
            .collect();
        let min_y = ys.iter().copied().fold(f64::INFINITY, f64::min);
        assert!((min_y + 1.2).abs() < 1e-3, "{min_y}");
        let env = buildings_of(&root)[0]
            .child("gml:boundedBy")
            .unwrap()
            .child("gml:Envelope")
            .unwrap();
        let lo = numbers(&env.child("gml:lowerCorner").unwrap().text);
        assert!((lo[1] - (ORIGIN.y - 1.2)).abs() < 1e-3);
        assert_eq!(parts[1].count("bldg:BuildingInstallation"), 0);
        assert_eq!(parts[1].count("bldg:Door"), 1);
    }

    #[test]
    fn lod3_appearance_glass_doors_balconies() {
        let buildings = samples::all();
        let root = parse(&write_all(Lod::Lod3, &buildings));
        let all_ids = check_ids(&root);
        for el in buildings_of(&root) {
            let mats = el.find_all("app:X3DMaterial");
            let mut targets: Vec<&str> = mats
                .iter()
                .flat_map(|m| m.children_named("app:target").map(|t| t.text.as_str()))
                .collect();
            let n = targets.len();
            targets.sort_unstable();
            targets.dedup();
            assert_eq!(targets.len(), n, "a polygon coloured twice");
            assert_eq!(n, el.count("gml:Polygon"), "every polygon coloured");
            let colour_of = |id: &str| {
                let m = mats
                    .iter()
                    .find(|m| {
                        m.children_named("app:target")
                            .any(|t| t.text == format!("#{id}"))
                    })
                    .unwrap();
                (
                    m.child("app:diffuseColor").unwrap().text.clone(),
                    m.child("app:transparency").map(|t| t.text.clone()),
                )
            };
            for w in el.find_all("bldg:Window") {
                let poly = w.find_all("gml:Polygon")[0].attr("gml:id").unwrap();
                let (_, t) = colour_of(poly);
                if poly == "B_relation_302_p0_w4_o1_p" {
                    assert_eq!(t, None, "opaque window");
                } else {
                    assert_eq!(t.as_deref(), Some("0.6000"), "{poly}");
                }
            }
            for d in el.find_all("bldg:Door") {
                let poly = d.find_all("gml:Polygon")[0].attr("gml:id").unwrap();
                assert_eq!(colour_of(poly), ("0.4000 0.2500 0.1000".to_string(), None));
            }
            for i in el.find_all("bldg:BuildingInstallation") {
                for p in i.find_all("gml:Polygon") {
                    let (c, _) = colour_of(p.attr("gml:id").unwrap());
                    assert_eq!(c, "0.6000 0.6000 0.6000");
                }
            }
        }
        assert!(all_ids.contains("B_way_304_p0_w1_o0"), "gable window");
    }

    #[test]
    fn lod3_deterministic_lod4_as_lod3_lod2_without_details() {
        let b = samples::all();
        assert_eq!(write_all(Lod::Lod3, &b), write_all(Lod::Lod3, &b));
        // LOD4 runs write the LOD3 exterior in the lod4 properties.
        let lod4 = parse(&write_all(Lod::Lod4, &b));
        assert_eq!(lod4.count("bldg:lod3MultiSurface"), 0);
        assert_eq!(
            lod4.count("bldg:Window"),
            b.iter().map(|x| samples::counts(x).0).sum::<usize>()
        );
        // At LOD2 the same walls are written without openings.
        let lod2 = parse(&write_all(Lod::Lod2, &b));
        assert_eq!(
            lod2.count("bldg:opening") + lod2.count("bldg:BuildingInstallation"),
            0
        );
    }

    #[test]
    fn lod3_rejects_non_finite_openings() {
        let mut bad = samples::house();
        bad.parts[0].walls[0].openings[1].z1 = f64::INFINITY;
        let mut w = CityGmlWriter::with_srs_name(Vec::new(), "EPSG:2154");
        w.begin(&ctx(Lod::Lod3)).unwrap();
        let err = w.write(&bad).unwrap_err().to_string();
        assert!(err.contains("way/301") && err.contains("wall 0"), "{err}");
        // A degenerate opening is left out, the rest is written.
        let mut odd = samples::house();
        odd.parts[0].walls[0].openings[0].u1 = odd.parts[0].walls[0].openings[0].u0;
        w.write(&odd).unwrap();
        w.finish().unwrap();
        let root = parse(&w.into_inner());
        check_ids(&root);
        assert_eq!(root.count("bldg:Window"), 3);
    }

    #[test]
    #[ignore = "writes /tmp/c3.gml for manual validation"]
    fn dump_lod3_sample() {
        std::fs::write("/tmp/c3.gml", write_all(Lod::Lod3, &samples::all())).unwrap();
    }

    /// Runs the reference validator (OGC CityGML 2.0 XSDs) on LOD1, LOD2 and LOD3 output when it
    /// is installed; skipped otherwise so that the suite runs anywhere.
    #[test]
    fn validates_against_citygml_schemas() {
        let Some(validator) = installed_validator() else {
            eprintln!(
                "skipped: validate-outputs is not installed (set CITYGEN_VALIDATOR to its path)"
            );
            return;
        };
        let dir = tempfile::tempdir().unwrap();
        let mut files = Vec::new();
        for lod in [Lod::Lod1, Lod::Lod2] {
            let path = dir.path().join(format!("lod{}.gml", lod.number()));
            std::fs::write(&path, write_all(lod, &all_buildings())).unwrap();
            files.push(path);
        }
        let path = dir.path().join("lod3.gml");
        let mut lod3 = all_buildings();
        lod3.extend(samples::all());
        std::fs::write(&path, write_all(Lod::Lod3, &lod3)).unwrap();
        files.push(path);
        let out = std::process::Command::new(validator)
            .args(&files)
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success() && text.contains("3 passed, 0 failed"),
            "{text}\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }

    /// The validator wrapper, when it and its already-installed environment exist (the wrapper
    /// would otherwise try to install its dependencies from the network).
    fn installed_validator() -> Option<std::path::PathBuf> {
        let home = std::env::var_os("HOME").map(std::path::PathBuf::from)?;
        let venv = std::env::var_os("CITYGEN_VALIDATE_HOME")
            .map_or(home.join(".cache/citygen-validate"), Into::into);
        if !venv.join("venv/bin/python").exists() {
            return None;
        }
        let manifest = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        let candidates = [
            std::env::var_os("CITYGEN_VALIDATOR").map(Into::into),
            Some(manifest.join("../shared/tools/validate-outputs")),
            Some(manifest.join("../../shared/tools/validate-outputs")),
        ];
        candidates.into_iter().flatten().find(|p| p.is_file())
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(256))]

        /// Millimetre rounding: within half a millimetre, three decimals, never a negative zero.
        #[test]
        fn fixed3_rounds_to_millimetres(v in -1.0e9f64..1.0e9) {
            let mut x = Xml(Vec::new());
            x.fixed3(v);
            let s = String::from_utf8(x.0).unwrap();
            let back: f64 = s.parse().unwrap();
            proptest::prop_assert!((back - v).abs() <= 0.000_5 + v.abs() * 1e-15, "{} -> {}", v, s);
            proptest::prop_assert_eq!(s.split('.').nth(1).map(str::len), Some(3));
            proptest::prop_assert!(s != "-0.000");
        }

        /// Any name survives a round trip through the file (XML-forbidden characters aside).
        #[test]
        fn any_name_round_trips(name in "\\PC*") {
            let mut b = simple_box();
            b.name = Some(name.clone());
            let root = parse(&write_all(Lod::Lod1, &[b]));
            let text = buildings_of(&root)[0].child("gml:name").unwrap().text.clone();
            proptest::prop_assert_eq!(text, name);
        }
    }
}
