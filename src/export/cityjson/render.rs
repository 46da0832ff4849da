//! One building as CityJSON CityObjects: the text of its objects with a mark wherever a vertex
//! index goes, and the building's own vertices (integer millimetres, each once), so that the
//! writers can render buildings in parallel and number their vertices afterwards, in order.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

use glam::DVec3;

use crate::export::ids::{id_fragment, part_ids};

use crate::color::material::{Material, ALL};
use crate::color::Color;
use crate::export::format::{push_fixed3, push_uint};
use crate::export::lod3geom::{
    balcony_faces, cornice_solids, eaves_solids, opening_face, seated_changes, sills, trim_color,
    wall_sill_faces, SILL_COLOR,
};
use crate::export::lod4geom::{prism_faces, room_shell, stair_steps, wall_body};
use crate::export::texture::{roof_map, wall_maps, Texture, Texturing, UvMap};
use crate::geometry::ring::{dedup_by, remove_spikes_by};
use crate::model::{grid_key, Building, Face, Lod, OpeningKind, Part, Provenance, RoofShape, Wall};

/// A mark whose index has this bit set names a material (of [`Frag::mats`]), not a vertex.
pub(super) const MATERIAL: u32 = 1 << 31;

/// A mark whose index has this bit set names a texture (of [`Frag::texs`], `--textures`).
pub(super) const TEXTURE: u32 = 1 << 30;

/// A mark whose index has this bit set names a texture vertex (of [`Frag::sts`]).
pub(super) const ST: u32 = 1 << 29;

/// The appearance theme of the materials (the CityGML writer's theme).
pub(super) const THEME: &str = "citygen";

/// `transparency` of glazed windows' material (as the CityGML writer's glass).
const GLASS_TRANSPARENCY: f32 = 0.6;

/// A colour and a surface material as a material key: the material's index above RGBA, 8 bits
/// each.
pub(super) fn material_key(c: Color, m: Material) -> u64 {
    let q = |x: f32| (x.clamp(0.0, 1.0) * 255.0).round() as u64;
    ((m as u64) << 32) | (q(c.r) << 24) | (q(c.g) << 16) | (q(c.b) << 8) | q(c.a)
}

/// A material object (`{"name":"#rrggbb","diffuseColor":[r,g,b],...}`) of key `k`.
pub(super) fn push_material(out: &mut Vec<u8>, k: u64) {
    let c = |shift: u32| ((k >> shift) & 0xff) as u32;
    let unit = |v: u32| format!("{:.4}", f64::from(v) / 255.0);
    let material = ALL
        .get((k >> 32) as usize)
        .copied()
        .unwrap_or(Material::Unspecified);
    let name = match material {
        Material::Unspecified => String::new(),
        m => format!(" {}", m.name()),
    };
    let mut s = format!(
        "{{\"name\":\"#{:02x}{:02x}{:02x}{name}\",\"diffuseColor\":[{},{},{}],\"isSmooth\":false",
        c(24),
        c(16),
        c(8),
        unit(c(24)),
        unit(c(16)),
        unit(c(8))
    );
    if material != Material::Unspecified {
        s.push_str(&format!(",\"shininess\":{:.2}", material.shininess()));
    }
    if c(0) < 255 {
        s.push_str(&format!(",\"transparency\":{}", unit(255 - c(0))));
    }
    s.push('}');
    out.extend_from_slice(s.as_bytes());
}

/// A vertex as the file holds it: whole millimetres from the transform's translate (the local
/// origin), [`grid_key`].
pub(super) type Vertex = (i64, i64, i64);

/// A fast hasher for [`Vertex`] keys (a multiply-rotate mix per coordinate and a final
/// avalanche): the maps are only looked up, never iterated, so the output does not depend on it.
#[derive(Default, Clone, Copy)]
pub(super) struct VertexHasher(u64);

impl Hasher for VertexHasher {
    fn write(&mut self, bytes: &[u8]) {
        for b in bytes {
            self.write_u64(u64::from(*b));
        }
    }

    fn write_i64(&mut self, v: i64) {
        self.write_u64(v as u64);
    }

    fn write_u64(&mut self, v: u64) {
        self.0 = (self.0.rotate_left(23) ^ v).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    }

    fn finish(&self) -> u64 {
        let h = self.0 ^ (self.0 >> 31);
        h.wrapping_mul(0xBF58_476D_1CE4_E5B9) ^ (h >> 29)
    }
}

/// A map keyed by vertices.
pub(super) type VertexMap<V> = HashMap<Vertex, V, BuildHasherDefault<VertexHasher>>;

/// One rendered building: the text of its CityObjects (`"id":{...}` pairs joined by commas,
/// without the vertex indices) and where each index goes.
#[derive(Default)]
pub(super) struct Frag {
    /// The objects' text, vertex indices left out.
    pub(super) text: Vec<u8>,
    /// (byte offset in `text`, index into `verts`, or [`MATERIAL`] and an index into `mats`):
    /// an index to insert there.
    pub(super) marks: Vec<(usize, u32)>,
    /// The building's distinct materials ([`material_key`]) in first-use order.
    pub(super) mats: Vec<u64>,
    /// The building's distinct vertices in first-use order.
    pub(super) verts: Vec<Vertex>,
    /// `verts` by value (scratch, emptied per building).
    index: VertexMap<u32>,
    /// The building's pictures (`--textures`) in first-use order.
    pub(super) texs: Vec<Texture>,
    /// Its distinct texture vertices ([`UvMap::st`]) in first-use order.
    pub(super) sts: Vec<[i64; 2]>,
    /// `sts` by value (scratch).
    st_index: HashMap<[i64; 2], u32>,
    /// What the building's surfaces are textured with (`--textures`).
    tex: Texturing,
    /// The building's id (`B_way_1`), the CityJSONFeature's `id`.
    pub(super) id: String,
}

impl Frag {
    pub(super) fn clear(&mut self) {
        self.text.clear();
        self.marks.clear();
        self.verts.clear();
        self.mats.clear();
        self.index.clear();
        self.id.clear();
        self.texs.clear();
        self.sts.clear();
        self.st_index.clear();
    }

    /// The index of picture `t`, marked at the end of the text.
    fn texture(&mut self, t: Texture) {
        let i = match self.texs.iter().position(|&k| k == t) {
            Some(i) => i,
            None => {
                self.texs.push(t);
                self.texs.len() - 1
            }
        } as u32;
        self.marks.push((self.text.len(), TEXTURE | i));
    }

    /// The index of texture vertex `st`, marked at the end of the text.
    fn st(&mut self, st: [i64; 2]) {
        let next = self.sts.len() as u32;
        let i = *self.st_index.entry(st).or_insert(next);
        if i == next {
            self.sts.push(st);
        }
        self.marks.push((self.text.len(), ST | i));
    }

    /// A surface's texture values: per written ring (as [`Frag::surface`] writes them)
    /// `[t,i,j,...]`, the picture's index and a texture vertex per ring vertex; `[[null]]`
    /// without a picture.
    fn surface_texture(&mut self, f: &Face, tex: Option<(Texture, UvMap)>) {
        let Some((t, map)) = tex else {
            self.s("[[null]]");
            return;
        };
        self.s("[");
        let rings = ring(&f.outer)
            .into_iter()
            .chain(f.holes.iter().filter_map(|h| ring(h)));
        self.comma(rings, |w, r| {
            w.s("[");
            w.texture(t);
            for (_, p) in written(r) {
                w.s(",");
                w.st(map.st(p));
            }
            w.s("]");
        });
        self.s("]");
    }

    /// The index of the material of colour and surface material `c`, marked at the end of the
    /// text (`null` for none).
    fn material(&mut self, c: Option<(Color, Material)>) {
        let Some((c, m)) = c else {
            self.s("null");
            return;
        };
        let k = material_key(c, m);
        let i = match self.mats.iter().position(|&m| m == k) {
            Some(i) => i,
            None => {
                self.mats.push(k);
                self.mats.len() - 1
            }
        } as u32;
        self.marks.push((self.text.len(), MATERIAL | i));
    }

    /// The items, comma-separated, each written by `each`.
    fn comma<T>(&mut self, items: impl IntoIterator<Item = T>, mut each: impl FnMut(&mut Self, T)) {
        for (i, x) in items.into_iter().enumerate() {
            if i > 0 {
                self.s(",");
            }
            each(self, x);
        }
    }

    fn s(&mut self, s: &str) {
        self.text.extend_from_slice(s.as_bytes());
    }

    /// A JSON string (quoted and escaped).
    fn string(&mut self, s: &str) {
        // Writing a &str to a Vec cannot fail.
        let _ = serde_json::to_writer(&mut self.text, s);
    }

    fn uint(&mut self, v: u64) {
        push_uint(&mut self.text, v);
    }

    fn fixed3(&mut self, v: f64) {
        push_fixed3(&mut self.text, v);
    }

    /// The index of vertex `v`, marked at the end of the text.
    fn vertex(&mut self, v: Vertex) {
        let next = self.verts.len() as u32;
        let i = *self.index.entry(v).or_insert(next);
        if i == next {
            self.verts.push(v);
        }
        self.marks.push((self.text.len(), i));
    }

    /// A ring `[i,j,k,...]` of the points as written: millimetres, without consecutive repeats
    /// (the closing one included) and spikes that the rounding makes; a ring that would keep
    /// fewer than 3 points is written as it was (as the CityGML writer does).
    fn ring(&mut self, points: &[DVec3]) {
        self.s("[");
        self.comma(written(points), |w, (k, _)| w.vertex(k));
        self.s("]");
    }

    /// A surface `[[outer],[hole],...]`.
    fn surface(&mut self, f: &Face) {
        self.s("[");
        if let Some(outer) = ring(&f.outer) {
            self.ring(outer);
        }
        for h in f.holes.iter().filter_map(|h| ring(h)) {
            self.s(",");
            self.ring(h);
        }
        self.s("]");
    }

    /// `"boundaries":[[s,s,...]]` of a solid's one shell, `,"semantics":{...}` when given, and
    /// `,"material":{"citygen":{"values":[[..]]}}` with a colour (or none) per face when given.
    fn solid(
        &mut self,
        lod: &str,
        faces: &[&Face],
        sem: Option<&Semantics>,
        colours: Option<&[Option<(Color, Material)>]>,
        textures: &[Option<(Texture, UvMap)>],
    ) {
        self.s("{\"type\":\"Solid\",\"lod\":\"");
        self.s(lod);
        self.s("\",\"boundaries\":[[");
        self.comma(faces, |w, f| w.surface(f));
        self.s("]]");
        if let Some(sem) = sem {
            self.s(",\"semantics\":");
            sem.write(self, true);
        }
        if let Some(colours) = colours.filter(|c| c.iter().any(Option::is_some)) {
            self.s(",\"material\":{\"");
            self.s(THEME);
            self.s("\":{\"values\":[[");
            self.comma(colours, |w, c| w.material(*c));
            self.s("]]}}");
        }
        if textures.iter().any(Option::is_some) {
            self.s(",\"texture\":{\"");
            self.s(THEME);
            self.s("\":{\"values\":[[");
            self.comma(faces.iter().zip(textures), |w, (f, t)| {
                w.surface_texture(f, *t)
            });
            self.s("]]}}");
        }
        self.s("}");
    }

    /// A MultiSurface of the faces, without semantics, each face in its colour (issue 49's
    /// cornices and eaves).
    fn multi_surface_colored(&mut self, lod: &str, faces: &[&Face], colours: &[(Color, Material)]) {
        self.s("{\"type\":\"MultiSurface\",\"lod\":\"");
        self.s(lod);
        self.s("\",\"boundaries\":[");
        self.comma(faces, |w, f| w.surface(f));
        self.s("],\"material\":{\"");
        self.s(THEME);
        self.s("\":{\"values\":[");
        self.comma(colours, |w, c| w.material(Some(*c)));
        self.s("]}}}");
    }

    /// A MultiSurface of the faces, without semantics.
    fn multi_surface(&mut self, lod: &str, faces: &[&Face]) {
        self.s("{\"type\":\"MultiSurface\",\"lod\":\"");
        self.s(lod);
        self.s("\",\"boundaries\":[");
        self.comma(faces, |w, f| w.surface(f));
        self.s("]}");
    }

    /// `"id":{"type":"T","parents":[..],"children":[..],` — the caller writes the rest and `}`.
    fn open_object(&mut self, id: &str, kind: &str, parent: Option<&str>, children: &[String]) {
        self.string(id);
        self.s(":{\"type\":\"");
        self.s(kind);
        self.s("\"");
        if let Some(p) = parent {
            self.s(",\"parents\":[");
            self.string(p);
            self.s("]");
        }
        if !children.is_empty() {
            self.s(",\"children\":[");
            self.comma(children, |w, c| w.string(c));
            self.s("]");
        }
    }

    fn attr_str(&mut self, first: &mut bool, name: &str, value: &str) {
        self.attr_name(first, name);
        self.string(value);
    }

    fn attr_name(&mut self, first: &mut bool, name: &str) {
        if !*first {
            self.s(",");
        }
        *first = false;
        self.string(name);
        self.s(":");
    }
}

/// The points of a ring as written ([`Frag::ring`]), each with its millimetre key: without
/// consecutive repeats (the closing one included) and spikes that the rounding makes; a ring
/// that would keep fewer than 3 points as it was. A texture's coordinates are those of these
/// points, one each.
fn written(points: &[DVec3]) -> Vec<(Vertex, DVec3)> {
    let raw: Vec<(Vertex, DVec3)> = points.iter().map(|p| (grid_key(*p), *p)).collect();
    let mut keys = raw.clone();
    dedup_by(&mut keys, |a, b| a.0 == b.0);
    remove_spikes_by(&mut keys, |a, b| a.0 == b.0);
    if keys.len() < 3 {
        keys = raw;
    }
    keys
}

/// The ring without a closing duplicate of its first vertex, or `None` if fewer than 3 remain
/// (the faces the CityGML writer leaves out, left out here too).
pub(super) fn ring(points: &[DVec3]) -> Option<&[DVec3]> {
    let mut r = points;
    while r.len() > 1 && r.first() == r.last() {
        r = &r[..r.len() - 1];
    }
    (r.len() >= 3).then_some(r)
}

/// A semantic object: its type, its parent's and children's indices in the list, and the
/// share of a wall that faces a neighbour (`partyWallShare`).
struct SemObject {
    kind: &'static str,
    parent: Option<usize>,
    children: Vec<usize>,
    party: Option<f64>,
}

/// A geometry's `semantics`: the objects and one value per surface.
#[derive(Default)]
struct Semantics {
    objects: Vec<SemObject>,
    values: Vec<usize>,
}

impl Semantics {
    fn object(&mut self, kind: &'static str) -> usize {
        self.objects.push(SemObject {
            kind,
            parent: None,
            children: Vec::new(),
            party: None,
        });
        self.objects.len() - 1
    }

    /// A child of `parent` (a Window or Door of a wall surface).
    fn child(&mut self, kind: &'static str, parent: usize) -> usize {
        let i = self.object(kind);
        self.objects[i].parent = Some(parent);
        self.objects[parent].children.push(i);
        i
    }

    /// `{"surfaces":[...],"values":[...]}`, the values in one shell (`[[...]]`) for a solid.
    fn write(&self, f: &mut Frag, solid: bool) {
        f.s("{\"surfaces\":[");
        f.comma(&self.objects, |f, o| {
            f.s("{\"type\":\"");
            f.s(o.kind);
            f.s("\"");
            if let Some(p) = o.parent {
                f.s(",\"parent\":");
                f.uint(p as u64);
            }
            if !o.children.is_empty() {
                f.s(",\"children\":[");
                f.comma(&o.children, |f, c| f.uint(*c as u64));
                f.s("]");
            }
            if let Some(share) = o.party {
                f.s(",\"partyWallShare\":");
                f.s(&format!("{:.2}", share.min(1.0)));
            }
            f.s("}");
        });
        f.s(if solid {
            "],\"values\":[["
        } else {
            "],\"values\":["
        });
        f.comma(&self.values, |f, v| f.uint(*v as u64));
        f.s(if solid { "]]}" } else { "]}" });
    }
}

/// A file's terrain as its `TINRelief` object (`"id":{...}`): attribute `tolerance` (metres,
/// [`crate::model::Terrain::tolerance`]) and one `CompositeSurface` of lod `lod` (CityJSON has no `TIN`
/// geometry: its schema gives `TINRelief` a `CompositeSurface`), a triangle per
/// surface.
pub(super) fn terrain(f: &mut Frag, t: &crate::model::Terrain, id: &str, lod: &str) {
    f.clear();
    f.id = id.to_string();
    f.string(id);
    f.s(":{\"type\":\"TINRelief\",\"attributes\":{\"tolerance\":");
    f.fixed3(t.tolerance);
    f.s("},\"geometry\":[{\"type\":\"CompositeSurface\",\"lod\":");
    f.string(lod);
    f.s(",\"boundaries\":[");
    for (k, tri) in t.triangles.iter().enumerate() {
        f.s(if k > 0 { ",[[" } else { "[[" });
        f.comma(tri, |f, &v| {
            let p = t.vertices.get(v as usize).copied().unwrap_or_default();
            f.vertex(grid_key(p));
        });
        f.s("]]");
    }
    f.s("]}]}");
}

/// The building's id: `B_` and its source key (`B_way_123`), as in the CityGML.
pub(super) fn building_id(b: &Building) -> String {
    format!("B_{}", id_fragment(&b.key()))
}

/// What a part's exterior polygons are.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Kind {
    Ground,
    Wall(usize),
    Roof,
}

/// The writable polygons of a part: ground, walls, roof faces (those with 3 points or more).
fn surfaces(part: &Part) -> impl Iterator<Item = (Kind, &Face)> {
    std::iter::once((Kind::Ground, &part.ground))
        .chain(
            part.walls
                .iter()
                .enumerate()
                .map(|(i, w)| (Kind::Wall(i), &w.outline)),
        )
        .chain(part.roof.iter().map(|f| (Kind::Roof, f)))
        .filter(|(_, f)| ring(&f.outer).is_some())
}

/// An object hanging under a part's geometry holder (LOD3 and LOD4).
enum Extra<'a> {
    /// A balcony of wall `wall`.
    Balcony {
        wall: &'a Wall,
        index: usize,
        id: String,
    },
    /// The window sills of wall `wall` (`crate::export::lod3geom::sills`), one object.
    Sills { wall: &'a Wall, id: String },
    /// The part's cornice (`eaves` false) or eaves (`crate::export::lod3geom::cornice_solids`,
    /// `eaves_solids`), one object.
    Trim { eaves: bool, id: String },
    /// Room `room` of storey `storey` (index in the part's interior).
    Room {
        storey: usize,
        room: usize,
        id: String,
    },
    /// Interior wall `wall` of storey `storey`.
    InteriorWall {
        storey: usize,
        wall: usize,
        id: String,
    },
    /// The stair of storey `storey`.
    Stair { storey: usize, id: String },
}

impl Extra<'_> {
    fn id(&self) -> &str {
        match self {
            Extra::Balcony { id, .. }
            | Extra::Sills { id, .. }
            | Extra::Trim { id, .. }
            | Extra::Room { id, .. }
            | Extra::InteriorWall { id, .. }
            | Extra::Stair { id, .. } => id,
        }
    }
}

/// The objects under a part: its balconies (LOD3+), then per storey its rooms, interior walls
/// and stair (LOD4), those with a geometry to write.
fn extras<'a>(part: &'a Part, pid: &str, lod: Lod) -> Vec<Extra<'a>> {
    let mut out = Vec::new();
    if lod < Lod::Lod3 {
        return out;
    }
    for (kind, _) in surfaces(part) {
        let Kind::Wall(wi) = kind else { continue };
        let wall = &part.walls[wi];
        for (k, b) in wall.balconies.iter().enumerate() {
            if balcony_faces(wall, b).is_some() {
                out.push(Extra::Balcony {
                    wall,
                    index: k,
                    id: format!("{pid}_w{wi}_b{k}"),
                });
            }
        }
        if !sills(wall).is_empty() {
            out.push(Extra::Sills {
                wall,
                id: format!("{pid}_w{wi}_sills"),
            });
        }
    }
    if !cornice_solids(part).is_empty() {
        out.push(Extra::Trim {
            eaves: false,
            id: format!("{pid}_cornice"),
        });
    }
    if !eaves_solids(part).is_empty() {
        out.push(Extra::Trim {
            eaves: true,
            id: format!("{pid}_eaves"),
        });
    }
    if lod < Lod::Lod4 {
        return out;
    }
    for (k, s) in part.interior.iter().enumerate() {
        // A storey whose heights are not finite is left out, as every writer does.
        if !(s.floor_z.is_finite() && s.ceiling_z.is_finite()) {
            continue;
        }
        for r in 0..s.rooms.len() {
            if room_shell(s, r).is_some() {
                out.push(Extra::Room {
                    storey: k,
                    room: r,
                    id: format!("{pid}_s{k}_r{r}"),
                });
            }
        }
        for w in 0..s.walls.len() {
            if wall_body(s, w).is_some() {
                out.push(Extra::InteriorWall {
                    storey: k,
                    wall: w,
                    id: format!("{pid}_s{k}_iw{w}"),
                });
            }
        }
        if s.stair
            .as_ref()
            .is_some_and(|st| !stair_steps(s, st).is_empty())
        {
            out.push(Extra::Stair {
                storey: k,
                id: format!("{pid}_s{k}_stair"),
            });
        }
    }
    out
}

/// Renders building `b` at `lod` into `f` (cleared first).
pub(super) fn building(f: &mut Frag, b: &Building, lod: Lod, tex: Texturing) {
    f.clear();
    f.tex = tex;
    let id = building_id(b);
    let pids = part_ids(&id, &b.parts);
    f.id.clone_from(&id);
    let single = b.parts.len() == 1;
    // The building's children: its parts, or (one part) the part's extras.
    let part_extras: Vec<Vec<Extra<'_>>> = b
        .parts
        .iter()
        .zip(&pids)
        .map(|(p, pid)| extras(p, if single { &id } else { pid }, lod))
        .collect();
    let children: Vec<String> = if single {
        part_extras[0].iter().map(|e| e.id().to_string()).collect()
    } else {
        pids.clone()
    };
    f.open_object(&id, "Building", None, &children);
    f.s(",\"attributes\":{");
    let mut first = true;
    f.attr_str(&mut first, "sourceId", &b.id.to_string());
    if let Some(name) = &b.name {
        f.attr_str(&mut first, "name", name);
    }
    if !b.zone.is_empty() {
        f.attr_str(&mut first, "zone", &b.zone);
    }
    if !b.appearance.is_empty() {
        f.attr_str(&mut first, "appearance", &b.appearance);
    }
    provenance(f, &mut first, &b.provenance);
    if let [part] = b.parts.as_slice() {
        if let Some(source) = part.traced_source(b.id) {
            f.attr_str(&mut first, "partSourceId", &source.to_string());
        }
        if let Some(class) = part.structure {
            f.attr_str(&mut first, "structure", class.name());
        }
    }
    building_attributes(
        f,
        &mut first,
        b.roof_shape,
        b.measured_height,
        b.storeys_above_ground,
    );
    if let Some(a) = &b.attributes {
        input_attributes(f, &mut first, a);
    }
    f.s("}");
    if single {
        geometry(f, &b.parts[0], lod);
        f.s("}");
        extra_objects(f, &b.parts[0], &id, &part_extras[0]);
        return;
    }
    f.s("}");
    for ((part, pid), ex) in b.parts.iter().zip(&pids).zip(&part_extras) {
        let kids: Vec<String> = ex.iter().map(|e| e.id().to_string()).collect();
        f.s(",");
        f.open_object(pid, "BuildingPart", Some(&id), &kids);
        f.s(",\"attributes\":{");
        let mut first = true;
        if let Some(source) = part.traced_source(b.id) {
            f.attr_str(&mut first, "sourceId", &source.to_string());
        }
        if let Some(role) = part.role.name() {
            f.attr_str(&mut first, "sourceRole", role);
        }
        if let Some(class) = part.structure {
            f.attr_str(&mut first, "structure", class.name());
        }
        // Its top above the building's ground, as the building's own.
        building_attributes(
            f,
            &mut first,
            part.roof_shape,
            part.height_above(b.ground_z),
            part.storeys,
        );
        f.s("}");
        geometry(f, part, lod);
        f.s("}");
        extra_objects(f, part, pid, ex);
    }
}

/// The building's provenance: `storeysSource`, `heightSource`, `roofSource` (strings) and
/// `storeysError`, `heightError` (metres), `roofProbability` (numbers, left out when unknown),
/// as the CityGML writer's generic attributes.
fn provenance(f: &mut Frag, first: &mut bool, p: &Provenance) {
    let values = [
        ("storeysSource", p.storeys, "storeysError", p.storeys_error),
        ("heightSource", p.height, "heightError", p.height_error),
        ("roofSource", p.roof, "roofProbability", p.roof_probability),
    ];
    for (name, source, value_name, value) in values {
        f.attr_str(first, name, source.name());
        if let Some(v) = value {
            f.attr_name(first, value_name);
            f.fixed3(v);
        }
    }
}

/// The attribute names citygen writes on a building itself: an input attribute of the same
/// name is left out (a JSON object holds each name once).
const OWN_NAMES: [&str; 14] = [
    "sourceId",
    "name",
    "zone",
    "appearance",
    "storeysSource",
    "storeysError",
    "heightSource",
    "heightError",
    "roofSource",
    "roofProbability",
    "partSourceId",
    "structure",
    "measuredHeight",
    "storeysAboveGround",
];

/// The input file's other attributes (issue 47), typed as JSON: strings, integers, numbers,
/// booleans, dates as ISO 8601 strings. One named as citygen's own (or `roofType`) is left
/// out.
fn input_attributes(f: &mut Frag, first: &mut bool, a: &crate::model::Attributes) {
    use crate::model::AttrValue;
    for (name, value) in a.iter() {
        if OWN_NAMES.contains(&&**name) || &**name == "roofType" {
            continue;
        }
        f.attr_name(first, name);
        match value {
            AttrValue::Text(t) | AttrValue::Date(t) => f.string(t),
            AttrValue::Int(i) => f.s(&i.to_string()),
            // Finite by construction; serde_json writes the shortest round trip.
            AttrValue::Real(r) => {
                f.s(&serde_json::Number::from_f64(*r).map_or("null".into(), |n| n.to_string()))
            }
            AttrValue::Bool(b) => f.s(if *b { "true" } else { "false" }),
        }
    }
}

/// `measuredHeight`, `storeysAboveGround` and `roofType` (the CityGML code, as the CityGML
/// writer's `bldg:roofType`).
fn building_attributes(f: &mut Frag, first: &mut bool, roof: RoofShape, height: f64, storeys: u32) {
    f.attr_name(first, "measuredHeight");
    f.fixed3(height);
    f.attr_name(first, "storeysAboveGround");
    f.uint(u64::from(storeys));
    f.attr_str(first, "roofType", roof.citygml_code());
}

/// `,"geometry":[...]` of a part at the LOD (nothing for a part without surfaces).
fn geometry(f: &mut Frag, part: &Part, lod: Lod) {
    if surfaces(part).next().is_none() {
        return;
    }
    f.s(",\"geometry\":[");
    match lod {
        Lod::Lod1 => {
            let faces: Vec<&Face> = surfaces(part).map(|(_, f)| f).collect();
            let colours: Vec<Option<(Color, Material)>> =
                surfaces(part).map(|(k, _)| colour_of(part, k)).collect();
            let tex: Vec<_> = surfaces(part)
                .map(|(k, face)| texture_of(part, k, face, f.tex))
                .collect();
            f.solid("1", &faces, None, Some(&colours), &tex);
        }
        Lod::Lod2 => {
            let mut sem = Semantics::default();
            let (g, w, r) = (
                sem.object("GroundSurface"),
                sem.object("WallSurface"),
                sem.object("RoofSurface"),
            );
            let mut faces = Vec::new();
            let mut colours = Vec::new();
            let mut tex = Vec::new();
            for (kind, face) in surfaces(part) {
                tex.push(texture_of(part, kind, face, f.tex));
                sem.values.push(match kind {
                    Kind::Ground => g,
                    Kind::Wall(_) => w,
                    Kind::Roof => r,
                });
                faces.push(face);
                colours.push(colour_of(part, kind));
            }
            f.solid("2.2", &faces, Some(&sem), Some(&colours), &tex);
        }
        Lod::Lod3 | Lod::Lod4 => lod3_solid(f, part),
    }
    f.s("]");
}

/// The colour and material of a part's surface: its wall or roof colour and material; none
/// for the ground.
fn colour_of(part: &Part, kind: Kind) -> Option<(Color, Material)> {
    match kind {
        Kind::Ground => None,
        Kind::Wall(_) => Some((part.wall_color, part.wall_material)),
        Kind::Roof => Some((part.roof_color, part.roof_material)),
    }
}

/// The picture and map of a part's surface `face` of `kind` under `tex` (`--textures`): a
/// wall's ([`crate::export::texture::WallMaps::whole`]) or a roof's, as the glTF writer's; none
/// for the ground or without textures.
fn texture_of(part: &Part, kind: Kind, face: &Face, tex: Texturing) -> Option<(Texture, UvMap)> {
    if tex == Texturing::Off {
        return None;
    }
    match kind {
        Kind::Ground => None,
        Kind::Wall(i) => {
            let w = part.walls.get(i)?;
            let maps = wall_maps(part, w, !face.holes.is_empty(), tex);
            let (t, map) = maps.whole(face);
            Some((t, *map))
        }
        Kind::Roof => Some(roof_map(part, face.normal())),
    }
}

/// An opening's material colour and material: its own colour, glazed windows' transparent
/// glass.
fn opening_colour(o: &crate::model::Opening) -> (Color, Material) {
    if o.kind == OpeningKind::Window && o.glazed {
        let c = Color {
            a: 1.0 - GLASS_TRANSPARENCY,
            ..o.color
        };
        (c, Material::of_pane(true))
    } else {
        (Color { a: 1.0, ..o.color }, Material::Unspecified)
    }
}

/// The LOD3 solid: ground and walls as [`seated_changes`] gives them, walls with their
/// openings' holes, roofs, then every opening's polygon (filling its hole); semantics with one
/// WallSurface per wall that has openings or faces a neighbour (its Windows and Doors its
/// children), one shared by the others.
fn lod3_solid(f: &mut Frag, part: &Part) {
    let seated = seated_changes(part);
    let mut sem = Semantics::default();
    let (g, w, r) = (
        sem.object("GroundSurface"),
        sem.object("WallSurface"),
        sem.object("RoofSurface"),
    );
    let mut faces: Vec<&Face> = Vec::new();
    let mut colours: Vec<Option<(Color, Material)>> = Vec::new();
    let mut openings: Vec<(Face, usize, (Color, Material))> = Vec::new();
    let mut tex: Vec<Option<(Texture, UvMap)>> = Vec::new();
    for (kind, face) in surfaces(part) {
        let fi = match kind {
            Kind::Ground => Some(0),
            Kind::Wall(i) => Some(i + 1),
            Kind::Roof => None,
        };
        let face = fi
            .and_then(|fi| seated.iter().find(|c| c.0 == fi))
            .map_or(face, |c| &c.1);
        faces.push(face);
        colours.push(colour_of(part, kind));
        tex.push(texture_of(part, kind, face, f.tex));
        let value = match kind {
            Kind::Ground => g,
            Kind::Roof => r,
            Kind::Wall(i) => {
                let wall = &part.walls[i];
                let ops: Vec<(Face, OpeningKind, (Color, Material))> = wall
                    .openings
                    .iter()
                    .filter_map(|o| {
                        opening_face(wall, o, 0.0).map(|face| (face, o.kind, opening_colour(o)))
                    })
                    .collect();
                if ops.is_empty() && wall.party < 0.005 {
                    w
                } else {
                    let own = sem.object("WallSurface");
                    if wall.party >= 0.005 {
                        sem.objects[own].party = Some(wall.party);
                    }
                    for (face, kind, colour) in ops {
                        let k = sem.child(
                            match kind {
                                OpeningKind::Window => "Window",
                                OpeningKind::Door => "Door",
                            },
                            own,
                        );
                        openings.push((face, k, colour));
                    }
                    own
                }
            }
        };
        sem.values.push(value);
    }
    for (face, k, colour) in &openings {
        faces.push(face);
        sem.values.push(*k);
        colours.push(Some(*colour));
        tex.push(None);
    }
    f.solid("3", &faces, Some(&sem), Some(&colours), &tex);
}

/// Every face of a part's cornice (`eaves` false) or eaves solids with its colour and material:
/// a cornice in its own colour; the eaves' top and fascia in the roof's, the rest (the soffit
/// and the board's ends) in the soffit's. Every writer colours them so.
fn trim_colors<'a>(
    part: &Part,
    eaves: bool,
    solids: &'a [crate::export::lod3geom::TrimSolid],
) -> Vec<(&'a Face, (Color, Material))> {
    let mut out = Vec::new();
    for s in solids {
        for (i, f) in s.faces.iter().enumerate() {
            out.push((f, trim_color(part, eaves, i)));
        }
    }
    out
}

/// The part's extras as CityObjects (`,\n"id":{...}` each).
fn extra_objects(f: &mut Frag, part: &Part, parent: &str, extras: &[Extra<'_>]) {
    for e in extras {
        match e {
            Extra::Balcony { wall, index, id } => {
                let Some(faces) = balcony_faces(wall, &wall.balconies[*index]) else {
                    continue;
                };
                f.s(",");
                f.open_object(id, "BuildingInstallation", Some(parent), &[]);
                f.s(",\"attributes\":{\"function\":\"balcony\"},\"geometry\":[");
                // Each face in its colour, as the CityGML and glTF writers draw it.
                let (all, colours): (Vec<&Face>, Vec<(Color, Material)>) = faces
                    .colored(&wall.balconies[*index])
                    .map(|(face, c)| (face, (c, Material::Unspecified)))
                    .unzip();
                f.multi_surface_colored("3", &all, &colours);
                f.s("]}");
            }
            Extra::Sills { wall, id } => {
                let boxes = wall_sill_faces(wall);
                if boxes.is_empty() {
                    continue;
                }
                f.s(",");
                f.open_object(id, "BuildingInstallation", Some(parent), &[]);
                f.s(",\"attributes\":{\"function\":\"window sills\"},\"geometry\":[");
                let all: Vec<&Face> = boxes.iter().collect();
                let colours = vec![(SILL_COLOR, Material::Unspecified); all.len()];
                f.multi_surface_colored("3", &all, &colours);
                f.s("]}");
            }
            Extra::Trim { eaves, id } => {
                let (solids, function) = if *eaves {
                    (eaves_solids(part), "eaves")
                } else {
                    (cornice_solids(part), "cornice")
                };
                let colored = trim_colors(part, *eaves, &solids);
                f.s(",");
                f.open_object(id, "BuildingInstallation", Some(parent), &[]);
                f.s(",\"attributes\":{\"function\":\"");
                f.s(function);
                f.s("\"},\"geometry\":[");
                let (faces, colours): (Vec<&Face>, Vec<_>) = colored.into_iter().unzip();
                f.multi_surface_colored("3", &faces, &colours);
                f.s("]}");
            }
            Extra::Room { storey, room, id } => {
                let s = &part.interior[*storey];
                let Some(shell) = room_shell(s, *room) else {
                    continue;
                };
                let rm = &s.rooms[*room];
                f.s(",");
                f.open_object(id, "BuildingRoom", Some(parent), &[]);
                f.s(",\"attributes\":{");
                let mut first = true;
                f.attr_str(&mut first, "name", &rm.name);
                f.attr_str(&mut first, "usage", &rm.usage);
                f.attr_name(&mut first, "storey");
                f.uint(s.storey as u64);
                f.s("},\"geometry\":[");
                let mut sem = Semantics::default();
                let (fl, ce, iw) = (
                    sem.object("FloorSurface"),
                    sem.object("CeilingSurface"),
                    sem.object("InteriorWallSurface"),
                );
                let mut faces: Vec<&Face> = vec![&shell.floor, &shell.ceiling];
                sem.values.extend([fl, ce]);
                let mut doors: Vec<(&Face, usize)> = Vec::new();
                for side in &shell.sides {
                    faces.push(&side.face);
                    if side.door_faces.is_empty() {
                        sem.values.push(iw);
                        continue;
                    }
                    let own = sem.object("InteriorWallSurface");
                    sem.values.push(own);
                    for d in &side.door_faces {
                        doors.push((d, sem.child("Door", own)));
                    }
                }
                for (d, k) in doors {
                    faces.push(d);
                    sem.values.push(k);
                }
                f.solid("3", &faces, Some(&sem), None, &[]);
                f.s("]}");
            }
            Extra::InteriorWall { storey, wall, id } => {
                let s = &part.interior[*storey];
                let Some(body) = wall_body(s, *wall) else {
                    continue;
                };
                f.s(",");
                f.open_object(id, "BuildingConstructiveElement", Some(parent), &[]);
                f.s(",\"attributes\":{\"function\":\"interior wall\",\"storey\":");
                f.uint(s.storey as u64);
                f.s("},\"geometry\":[");
                let faces: Vec<&Face> = body.iter().collect();
                f.solid("3", &faces, None, None, &[]);
                f.s("]}");
            }
            Extra::Stair { storey, id } => {
                let s = &part.interior[*storey];
                let steps = s
                    .stair
                    .as_ref()
                    .map(|st| stair_steps(s, st))
                    .unwrap_or_default();
                f.s(",");
                f.open_object(id, "BuildingInstallation", Some(parent), &[]);
                f.s(",\"attributes\":{\"function\":\"stairs\",\"storey\":");
                f.uint(s.storey as u64);
                f.s("},\"geometry\":[");
                let blocks: Vec<Face> = steps
                    .iter()
                    .flat_map(|st| prism_faces(&st.ring, st.z0, st.z1))
                    .collect();
                let faces: Vec<&Face> = blocks.iter().collect();
                f.multi_surface("3", &faces);
                f.s("]}");
            }
        }
    }
}
