//! Procedural textures (issue 49, `--textures`): small tileable pictures that citygen draws
//! itself (no image asset), one per surface material and one per kind of facade bay, and the
//! texture coordinates that lay them on a face in metres.
//!
//! **What a texture is.** A [`Texture::Surface`] is the pattern of a material (brick bond,
//! render with noise, stone courses, timber boards, concrete formwork, standing-seam metal,
//! clay tile rows, slate rows, thatch, green roof, bitumen, gravel) covering
//! [`Texture::size`] metres of a surface, tileable in both directions (the writers' sampler
//! repeats it). A [`Texture::Bay`] is one bay of a LOD2 facade, one storey high: the wall's
//! pattern with a window between two piers and a storey line at the floor, the window's width,
//! sill and height the shares that the knowledge base's rules give it at LOD3
//! ([`crate::model::Rhythm`]), rounded to [`BAY_STEP`] so that a file holds a few bay pictures,
//! not one per building. A wall's coordinates make one picture one bay wide, the wall holding
//! as many bays as the rules' `repeat` gives it (its length over the bay width, rounded), and
//! one storey high, counted from the part's ground.
//!
//! **Colour.** Every picture is grey: a pattern of luminance near 1 that the writers multiply
//! by the surface's colour (glTF's `baseColorFactor`, 3D Tiles' vertex colours), so that the
//! map's and the knowledge base's colours still show, and one picture serves every colour.
//!
//! **Determinism.** A picture is a pure function of its [`Texture`]: its noise is hashed from
//! the material and the pixel, never from a clock or a thread; the PNG encoder
//! (`export::png`) writes no metadata.

use glam::{DVec2, DVec3};

use crate::color::material::Material;
use crate::model::{Face, Part, Rhythm, Wall};

/// Side of every texture picture, pixels.
pub(crate) const SIDE: u32 = 128;

/// Bay shares (window width, sill, window height) are rounded to this many hundredths.
pub(crate) const BAY_STEP: u8 = 5;

/// Luminance levels a picture is quantised to (fewer levels, smaller PNG).
const LEVELS: f32 = 24.0;

/// A texture picture.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub(crate) enum Texture {
    /// The pattern of a surface material, [`Texture::size`] metres a picture.
    Surface(Material),
    /// One bay of a facade, one storey high: the wall material's pattern and a window whose
    /// width, sill and height are percentages of the bay and of the storey (multiples of
    /// [`BAY_STEP`]).
    Bay {
        /// The wall's material.
        material: Material,
        /// Window width, percent of the bay.
        window: u8,
        /// Sill height, percent of the storey.
        sill: u8,
        /// Window height, percent of the storey.
        height: u8,
    },
}

/// `x` (a share) as a percentage rounded to [`BAY_STEP`], within `lo..=hi`.
fn percent(x: f64, lo: u8, hi: u8) -> u8 {
    let step = f64::from(BAY_STEP);
    let p = if x.is_finite() {
        (x * 100.0 / step).round() * step
    } else {
        f64::from(lo)
    };
    p.clamp(f64::from(lo), f64::from(hi)) as u8
}

impl Texture {
    /// The bay picture of a wall of `material` with the rhythm `r`.
    pub(crate) fn bay(material: Material, r: &Rhythm) -> Texture {
        let window = if r.bay > 0.0 { r.window / r.bay } else { 0.4 };
        let sill = percent(r.sill, 5, 60);
        let height = percent(r.height, 10, 90).min(95 - sill);
        Texture::Bay {
            material,
            window: percent(window, 10, 80),
            sill,
            height,
        }
    }

    /// The material whose pattern the picture shows.
    pub(crate) fn material(self) -> Material {
        match self {
            Texture::Surface(m) | Texture::Bay { material: m, .. } => m,
        }
    }

    /// Width and height (metres) one picture of a material's pattern covers: a whole number
    /// of its bricks, courses, boards or tile rows, so that it tiles.
    pub(crate) fn size(material: Material) -> (f64, f64) {
        match material {
            // 4 bricks of 25 cm by 8 courses of 7.5 cm.
            Material::Brick => (1.0, 0.6),
            // 3 blocks of 80 cm by 4 courses of 40 cm.
            Material::Stone => (2.4, 1.6),
            // A formwork panel.
            Material::Concrete => (2.4, 1.2),
            // 8 boards of 15 cm.
            Material::Timber => (1.2, 1.2),
            // 2 standing-seam trays of 50 cm.
            Material::Metal => (1.0, 1.0),
            // 4 tiles of 25 cm by 4 rows of 30 cm.
            Material::RoofTiles => (1.0, 1.2),
            // 4 slates of 30 cm by 4 rows of 25 cm.
            Material::Slate => (1.2, 1.0),
            Material::Thatch | Material::Bitumen | Material::Gravel => (1.0, 1.0),
            _ => (2.0, 2.0),
        }
    }

    /// The picture's name in a file (`brick`, `bay plaster w40 s25 h60`).
    pub(crate) fn name(self) -> String {
        match self {
            Texture::Surface(m) => m.name().to_string(),
            Texture::Bay {
                material,
                window,
                sill,
                height,
            } => format!("bay {} w{window} s{sill} h{height}", material.name()),
        }
    }

    /// The picture's file name (`brick.png`, `bay_plaster_w40_s25_h60.png`): its
    /// [`Texture::name`], every character but an ASCII letter or digit made `_`.
    pub(crate) fn file_name(self) -> String {
        let name: String = self
            .name()
            .chars()
            .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
            .collect();
        format!("{name}.png")
    }

    /// The picture's luminance, [`SIDE`] x [`SIDE`] values in 0..=1, rows from the top.
    pub(crate) fn luminance(self) -> Vec<f32> {
        let n = SIDE as usize;
        let mut out = Vec::with_capacity(n * n);
        let m = self.material();
        let (w, h) = Texture::size(m);
        // A bay picture shows about 3 m by 3 m of wall: a whole number of pattern pictures.
        let (bw, bh) = match self {
            Texture::Surface(_) => (w, h),
            Texture::Bay { .. } => (
                (3.0 / w).round().max(1.0) * w,
                (3.0 / h).round().max(1.0) * h,
            ),
        };
        for row in 0..n {
            for col in 0..n {
                // Shares of the picture: x to the right, y up from its bottom.
                let fx = (col as f64 + 0.5) / n as f64;
                let fy = 1.0 - (row as f64 + 0.5) / n as f64;
                let (x, y) = ((fx * bw).rem_euclid(w), (fy * bh).rem_euclid(h));
                // Contrast eased towards 1: the surface's colour, multiplied, stays near
                // its own (a viewer decodes the sRGB picture to linear, which darkens).
                let mut l = 1.0 - 0.7 * (1.0 - pattern(m, x, y, w, h));
                if let Texture::Bay {
                    window,
                    sill,
                    height,
                    ..
                } = self
                {
                    l = bay(l, fx, fy, window, sill, height);
                }
                out.push((l.clamp(0.0, 1.0) * LEVELS).round() / LEVELS);
            }
        }
        out
    }

    /// The picture as a PNG file (grey, stored as RGB): deterministic bytes.
    pub(crate) fn png(self) -> Vec<u8> {
        let rgb: Vec<u8> = self
            .luminance()
            .into_iter()
            .flat_map(|l| {
                let v = (l * 255.0).round() as u8;
                [v, v, v]
            })
            .collect();
        super::png::encode_rgb(SIDE, SIDE, &rgb).unwrap_or_default()
    }
}

/// A face's texture coordinates, in pictures: `u` along the face's horizontal direction
/// (to the right seen from outside), `v` up it (glTF's `v` runs down a picture, so it is
/// written negated), each from `origin` and scaled by pictures a metre.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct UvMap {
    origin: DVec3,
    u: DVec3,
    v: DVec3,
}

impl UvMap {
    /// The map of a plane facing `normal` (unit), from `origin`: `u` horizontal in the plane,
    /// `v` up its slope (on a flat face, east and north), `per_u` and `per_v` pictures a metre.
    pub(crate) fn plane(normal: DVec3, origin: DVec3, per_u: f64, per_v: f64) -> UvMap {
        let horizontal = DVec3::Z.cross(normal);
        let u = if horizontal.length() < 0.05 {
            DVec3::X
        } else {
            horizontal.normalize()
        };
        let v = normal.cross(u).normalize_or(DVec3::Y);
        UvMap {
            origin,
            u: u * per_u,
            v: v * per_v,
        }
    }

    /// The map of a wall from `start` to `end` (seen from outside, `start` on the left) whose
    /// pictures start at `start` on the height `base`: `per_u` and `per_v` pictures a metre
    /// along it and up it.
    pub(crate) fn wall(start: DVec2, end: DVec2, base: f64, per_u: f64, per_v: f64) -> UvMap {
        let d = (end - start).normalize_or(DVec2::X);
        UvMap {
            origin: start.extend(base),
            u: d.extend(0.0) * per_u,
            v: DVec3::Z * per_v,
        }
    }

    /// The coordinates of `p` as glTF has them (`v` down the picture).
    pub(crate) fn uv(&self, p: DVec3) -> [f32; 2] {
        let d = p - self.origin;
        let (u, v) = (d.dot(self.u), d.dot(self.v));
        [u as f32 + 0.0, -(v as f32) + 0.0]
    }

    /// The coordinates of `p` as CityGML and CityJSON have them (`s`, `t` from the picture's
    /// bottom left, `t` up it: glTF's `v` negated), in [`ST_UNIT`]s: the same picture on the
    /// same place of the face as [`UvMap::uv`].
    pub(crate) fn st(&self, p: DVec3) -> [i64; 2] {
        let d = p - self.origin;
        let q = |x: f64| {
            let x = (x * ST_UNIT).round();
            if x.is_finite() && x.abs() < 1e15 {
                x as i64
            } else {
                0
            }
        };
        [q(d.dot(self.u)), q(d.dot(self.v))]
    }
}

/// Texture coordinates in CityGML and CityJSON are written to 1/10000 of a picture (1/78 of
/// a pixel of [`SIDE`]): [`UvMap::st`] counts in these units, `export::format::push_fixed4_i64` writes them.
pub(crate) const ST_UNIT: f64 = 10_000.0;

/// What a writer textures (`--textures`): nothing, the walls and roofs with their materials'
/// patterns, or also (LOD2) the walls with the bays of their facades.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub(crate) enum Texturing {
    /// No texture: every byte as without `--textures`.
    #[default]
    Off,
    /// Walls and roofs carry their materials' patterns, in metres.
    Materials,
    /// As `Materials`, and a wall of a part with a rhythm (LOD2) carries the picture of its
    /// bays, storey by storey, up to the eaves.
    Facades,
}

impl Texturing {
    /// The texturing of a run at `lod` with or without `--textures`.
    pub(crate) fn of(textures: bool, lod: crate::model::Lod) -> Texturing {
        match (textures, lod) {
            (false, _) => Texturing::Off,
            (true, crate::model::Lod::Lod2) => Texturing::Facades,
            (true, _) => Texturing::Materials,
        }
    }
}

/// The pictures and coordinates of one wall ([`wall_maps`]), shared by every writer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct WallMaps {
    /// The material's pattern, in metres from the wall's start and the part's ground.
    pub(crate) plain: (Texture, UvMap),
    /// With [`Texturing::Facades`] and a rhythm: the bay picture, a picture a bay wide (as
    /// many bays as the rules' `repeat` fits) and a storey high from the part's ground, for
    /// the wall below the eaves.
    pub(crate) bay: Option<(Texture, UvMap)>,
    /// The part's eaves: the bay picture stops there (a gable above keeps the pattern).
    pub(crate) eave_z: f64,
}

impl WallMaps {
    /// The picture and map of a face that a format keeps whole (CityGML, CityJSON: one
    /// texture a polygon): the bay picture when the face is wholly below the eaves (1 cm
    /// tolerance, as the glTF writer's cut), else the plain pattern (a gable wall, which the
    /// glTF writer cuts at the eaves and textures in two).
    pub(crate) fn whole(&self, f: &Face) -> (Texture, &UvMap) {
        let top = f
            .outer
            .iter()
            .map(|p| p.z)
            .fold(f64::NEG_INFINITY, f64::max);
        match &self.bay {
            Some((t, m)) if top <= self.eave_z + 0.01 => (*t, m),
            _ => (self.plain.0, &self.plain.1),
        }
    }
}

/// The pictures and maps of wall `w` of `part` under `tex` (not [`Texturing::Off`]): the
/// plain pattern, and the bay picture when the texturing is [`Texturing::Facades`], the part
/// has a rhythm and a storey over 0.5 m, the wall a length, and its face (`holes`) no hole.
pub(crate) fn wall_maps(part: &Part, w: &Wall, holes: bool, tex: Texturing) -> WallMaps {
    edge_maps(part, w.start, w.end, holes, tex)
}

/// As [`wall_maps`], for a wall of `part` along `start` -> `end` (a footprint edge, as the
/// Blocks of 3D Tiles draw it).
pub(crate) fn edge_maps(
    part: &Part,
    start: DVec2,
    end: DVec2,
    holes: bool,
    tex: Texturing,
) -> WallMaps {
    let m = part.wall_material;
    let base = part.levels.first().copied().unwrap_or(part.base_z);
    let (sw, sh) = Texture::size(m);
    let plain = UvMap::wall(start, end, base, 1.0 / sw, 1.0 / sh);
    let storey = (part.eave_z - base) / f64::from(part.storeys.max(1));
    let length = start.distance(end);
    let bay = match (tex, part.rhythm) {
        (Texturing::Facades, Some(r)) if storey > 0.5 && length > 0.01 && !holes => {
            let map = UvMap::wall(start, end, base, bays(length, r.bay) / length, 1.0 / storey);
            Some((Texture::bay(m, &r), map))
        }
        _ => None,
    };
    WallMaps {
        plain: (Texture::Surface(m), plain),
        bay,
        eave_z: part.eave_z,
    }
}

/// The picture and map of a roof face of `part` facing `normal`: the roof material's pattern,
/// rows along the eaves counted from the eaves' height.
pub(crate) fn roof_map(part: &Part, normal: DVec3) -> (Texture, UvMap) {
    let m = part.roof_material;
    let (w, h) = Texture::size(m);
    let origin = DVec3::new(0.0, 0.0, part.eave_z);
    (
        Texture::Surface(m),
        UvMap::plane(normal, origin, 1.0 / w, 1.0 / h),
    )
}

/// The pictures an output's surfaces use (`--textures`), gathered by its writer as it writes
/// (in parallel: a set, so the order of writing does not matter) for the run to write them
/// beside the output once it is complete.
pub(crate) type TextureSet = std::sync::Arc<std::sync::Mutex<std::collections::BTreeSet<Texture>>>;

/// Adds `t` to `set`.
pub(crate) fn note_used(set: &TextureSet, t: impl IntoIterator<Item = Texture>) {
    set.lock().unwrap_or_else(|p| p.into_inner()).extend(t);
}

/// How a writer textures: what ([`Texturing`], from `--textures` and the LOD at `begin`), the
/// folder of the pictures relative to the output (`out_textures/`, [`folder_name`]), and the
/// set it notes the pictures it uses in.
#[derive(Clone, Debug, Default)]
pub(crate) struct TextureOut {
    /// What is textured.
    pub(crate) tex: Texturing,
    /// The pictures' folder as a URI prefix, ending in `/`.
    pub(crate) folder: String,
    /// The pictures used.
    pub(crate) used: TextureSet,
}

impl TextureOut {
    /// The URI of picture `t` relative to the output: `out_textures/brick.png`.
    pub(crate) fn uri(&self, t: Texture) -> String {
        format!("{}{}", self.folder, t.file_name())
    }
}

/// The folder of an output's pictures (`--textures`), beside it: the output's file name
/// without its format's extension (`out.gml`, `out.city.json`, `out.city.jsonl` give `out`,
/// `out_0.5_1.gml` gives `out_0.5_1`) and `_textures`. A CityGML and a CityJSON output of one name share it (the same pictures).
pub(crate) fn folder_name(output: &std::path::Path) -> String {
    let name = output
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let known = [
        ".city.jsonl",
        ".city.json",
        ".jsonl",
        ".json",
        ".gml",
        ".xml",
    ];
    let stem = known
        .iter()
        .find_map(|e| name.strip_suffix(e))
        .or_else(|| name.rsplit_once('.').map(|(s, _)| s))
        .filter(|s| !s.is_empty())
        .unwrap_or(&name);
    format!("{stem}_textures")
}

/// The bays a wall of `length` metres holds with bays of `bay` metres, as the grammar's
/// `repeat` fits them: the length over the bay, rounded, at least 1.
pub(crate) fn bays(length: f64, bay: f64) -> f64 {
    if bay > 0.0 && length.is_finite() {
        (length / bay).round().max(1.0)
    } else {
        1.0
    }
}

/// A hash of `(seed, a, b)` in 0..1.
fn hash(seed: u32, a: i64, b: i64) -> f32 {
    let mut x = u64::from(seed)
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add((a as u64).wrapping_mul(0xBF58_476D_1CE4_E5B9))
        .wrapping_add((b as u64).wrapping_mul(0x94D0_49BB_1331_11EB));
    x ^= x >> 31;
    x = x.wrapping_mul(0xD6E8_FEB8_6659_FD93);
    x ^= x >> 32;
    (x >> 40) as f32 / (1u64 << 24) as f32
}

/// Value noise of period `px` by `py` cells over `x`, `y` in cells: smooth, tileable.
fn noise(seed: u32, x: f64, y: f64, px: i64, py: i64) -> f32 {
    let (x0, y0) = (x.floor(), y.floor());
    let (tx, ty) = ((x - x0) as f32, (y - y0) as f32);
    let (sx, sy) = (tx * tx * (3.0 - 2.0 * tx), ty * ty * (3.0 - 2.0 * ty));
    let (i, j) = (x0 as i64, y0 as i64);
    let at = |a: i64, b: i64| hash(seed, a.rem_euclid(px.max(1)), b.rem_euclid(py.max(1)));
    let top = at(i, j) + (at(i + 1, j) - at(i, j)) * sx;
    let bottom = at(i, j + 1) + (at(i + 1, j + 1) - at(i, j + 1)) * sx;
    top + (bottom - top) * sy
}

/// Two octaves of [`noise`] over a `w` by `h` metre picture with cells of about `cell`
/// metres: tileable on the picture.
fn fbm(seed: u32, x: f64, y: f64, w: f64, h: f64, cell: f64) -> f32 {
    let (px, py) = ((w / cell).round().max(1.0), (h / cell).round().max(1.0));
    let (cx, cy) = (x / w * px, y / h * py);
    let a = noise(seed, cx, cy, px as i64, py as i64);
    let b = noise(seed + 1, 2.0 * cx, 2.0 * cy, 2 * px as i64, 2 * py as i64);
    (2.0 * a + b) / 3.0
}

/// The luminance of `material`'s pattern at `x`, `y` metres in its `w` by `h` picture (`y`
/// up from its bottom).
fn pattern(material: Material, x: f64, y: f64, w: f64, h: f64) -> f32 {
    let seed = material as u32 * 7919 + 17;
    let fine = fbm(seed, x, y, w, h, 0.05) - 0.5;
    match material {
        Material::Brick => {
            // Stretcher bond: 25 cm bricks, courses of 7.5 cm, 1 cm joints.
            let course = (y / 0.075).floor();
            let offset = if course as i64 % 2 == 0 { 0.0 } else { 0.125 };
            let along = (x + offset).rem_euclid(w);
            let brick = (along / 0.25).floor();
            let (ja, jc) = (along - brick * 0.25, y - course * 0.075);
            if ja < 0.012 || jc < 0.012 {
                1.0 + 0.05 * fine
            } else {
                let id = hash(seed, brick as i64 % 4, course as i64);
                0.72 + 0.2 * id + 0.12 * fine
            }
        }
        Material::Stone => {
            let course = (y / 0.4).floor();
            let along = (x + 0.4 * course).rem_euclid(w);
            let block = (along / 0.8).floor();
            let (ja, jc) = (along - block * 0.8, y - course * 0.4);
            if ja < 0.02 || jc < 0.02 {
                0.62
            } else {
                let id = hash(seed, block as i64 % 3, course as i64);
                0.8 + 0.15 * id + 0.2 * fine
            }
        }
        Material::Concrete => {
            let tie = [
                (0.3, 0.3),
                (0.3, 0.9),
                (1.2, 0.3),
                (1.2, 0.9),
                (2.1, 0.3),
                (2.1, 0.9),
            ]
            .iter()
            .any(|(tx, ty)| (x - tx).hypot(y - ty) < 0.025);
            if x < 0.015 || y < 0.015 {
                0.78
            } else if tie {
                0.6
            } else {
                0.9 + 0.12 * fine
            }
        }
        Material::Timber => {
            let board = (x / 0.15).floor();
            let a = x - board * 0.15;
            if a < 0.008 {
                0.5
            } else {
                let id = hash(seed, board as i64 % 8, 0);
                let grain = fbm(seed + 3, a * 4.0, y, 2.4, h, 0.06) - 0.5;
                0.74 + 0.18 * id + 0.3 * grain
            }
        }
        Material::Metal => {
            let a = x.rem_euclid(0.5);
            if a < 0.012 {
                1.0
            } else if a < 0.025 {
                0.7
            } else {
                0.88 + 0.04 * fine
            }
        }
        Material::RoofTiles => {
            // Pan tiles: rows of 30 cm, each tile rounded across, the row's lower edge in shade.
            let row = (y / 0.3).floor();
            let r = (y - row * 0.3) / 0.3;
            let offset = if row as i64 % 2 == 0 { 0.0 } else { 0.125 };
            let a = ((x + offset).rem_euclid(0.25)) / 0.25;
            let round = (std::f64::consts::PI * a).sin() as f32;
            let shade = if r < 0.1 { 0.55 } else { 1.0 };
            let id = hash(seed, ((x + offset).rem_euclid(w) / 0.25) as i64, row as i64);
            shade * (0.66 + 0.22 * round + 0.12 * id + 0.1 * fine)
        }
        Material::Slate => {
            let row = (y / 0.25).floor();
            let offset = if row as i64 % 2 == 0 { 0.0 } else { 0.15 };
            let along = (x + offset).rem_euclid(w);
            let slate = (along / 0.3).floor();
            let (ja, jr) = (along - slate * 0.3, y - row * 0.25);
            if ja < 0.01 || jr < 0.015 {
                0.55
            } else {
                let id = hash(seed, slate as i64 % 4, row as i64);
                0.78 + 0.16 * id + 0.1 * fine
            }
        }
        Material::Thatch => {
            let streak = fbm(seed + 5, x * 8.0, y, 8.0 * w, h, 0.25) - 0.5;
            let row = (y / 0.25).fract() as f32;
            0.8 + 0.35 * streak - 0.12 * (1.0 - row)
        }
        Material::Green => 0.8 + 0.4 * (fbm(seed, x, y, w, h, 0.15) - 0.5) + 0.15 * fine,
        Material::Gravel => 0.7 + 0.3 * hash(seed, (x / 0.015) as i64, (y / 0.015) as i64),
        Material::Bitumen => {
            if y < 0.01 {
                0.7
            } else {
                0.88 + 0.12 * fine
            }
        }
        Material::Mud => 0.86 + 0.25 * (fbm(seed, x, y, w, h, 0.25) - 0.5) + 0.1 * fine,
        Material::Glass => 1.0,
        // Render, plaster and anything unknown: a fine noise and broad patches.
        Material::Plaster | Material::Unspecified => {
            0.93 + 0.07 * fine + 0.08 * (fbm(seed + 9, x, y, w, h, 0.5) - 0.5)
        }
    }
}

/// The bay picture's luminance at shares `fx`, `fy` (`fy` up from the floor) over the wall's
/// luminance `l`: a window of `window` percent of the bay in its middle, from `sill` to
/// `sill + height` percent of the storey, a single pane in a light frame as LOD3 draws its
/// windows (no mullion or transom: the derivation splits no window), a sill ledge, and a
/// storey line at the floor.
fn bay(l: f32, fx: f64, fy: f64, window: u8, sill: u8, height: u8) -> f32 {
    let px = 1.0 / f64::from(SIDE);
    let w = f64::from(window) / 100.0;
    let (x0, x1) = (0.5 - w / 2.0, 0.5 + w / 2.0);
    let (y0, y1) = (f64::from(sill) / 100.0, f64::from(sill + height) / 100.0);
    if fy < 3.0 * px {
        // The storey line: a band at the floor.
        return l * 0.82;
    }
    let inside = fx >= x0 && fx < x1 && fy >= y0 && fy < y1;
    if inside {
        let frame = 3.0 * px;
        let edge = fx < x0 + frame || fx >= x1 - frame || fy < y0 + frame || fy >= y1 - frame;
        if edge {
            return 0.95;
        }
        // Glass: dark, a little lighter towards the top (the sky it reflects).
        return 0.16 + 0.12 * ((fy - y0) / (y1 - y0)) as f32;
    }
    // The sill ledge under the window, a little wider than it.
    if fy >= y0 - 3.0 * px && fy < y0 && fx >= x0 - 3.0 * px && fx < x1 + 3.0 * px {
        return 0.97;
    }
    // The window's shadow on the wall below the ledge.
    if fy >= y0 - 5.0 * px && fy < y0 - 3.0 * px && fx >= x0 && fx < x1 {
        return l * 0.8;
    }
    l
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_picture_is_a_function_of_its_texture() {
        // Every material but glass, which is drawn untextured.
        let all: Vec<Material> = crate::color::material::ALL
            .into_iter()
            .filter(|m| *m != Material::Glass)
            .collect();
        let mut seen = Vec::new();
        for &m in &all {
            let png = Texture::Surface(m).png();
            assert_eq!(png, Texture::Surface(m).png(), "{m:?}");
            assert_eq!(&png[..8], &crate::export::png::SIGNATURE);
            assert!(png.len() < 24_000, "{m:?}: {} bytes", png.len());
            seen.push(png);
        }
        seen.sort();
        seen.dedup();
        assert_eq!(seen.len(), all.len(), "every material has its own picture");
    }

    #[test]
    fn pictures_tile_and_keep_the_colour() {
        for m in [
            Material::Brick,
            Material::Stone,
            Material::Slate,
            Material::Plaster,
        ] {
            let (w, h) = Texture::size(m);
            // The pattern is periodic: one picture further along, and up, it is the same.
            for (x, y) in [(0.013, 0.02), (0.4, 0.31), (0.77, 0.05)] {
                let a = pattern(m, x, y, w, h);
                let b = pattern(m, (x + w).rem_euclid(w), (y + h).rem_euclid(h), w, h);
                assert_eq!(a, b, "{m:?}");
            }
            let l = Texture::Surface(m).luminance();
            let mean = l.iter().sum::<f32>() / l.len() as f32;
            assert!((0.7..=1.0).contains(&mean), "{m:?}: mean {mean}");
        }
    }

    #[test]
    fn a_bay_shows_its_window_where_the_rules_put_it() {
        let r = Rhythm {
            bay: 3.0,
            window: 1.2,
            sill: 0.25,
            height: 0.6,
        };
        let t = Texture::bay(Material::Brick, &r);
        assert_eq!(
            t,
            Texture::Bay {
                material: Material::Brick,
                window: 40,
                sill: 25,
                height: 60
            }
        );
        let l = t.luminance();
        let n = SIDE as usize;
        let at = |fx: f64, fy: f64| {
            let col = (fx * n as f64) as usize;
            let row = ((1.0 - fy) * n as f64) as usize;
            l[row.min(n - 1) * n + col.min(n - 1)]
        };
        // Glass in the window's middle, in one pane; wall beside and under it.
        assert!(at(0.42, 0.45) < 0.35);
        assert!(at(0.5, 0.45) < 0.35);
        assert!(at(0.42, 0.682) < 0.35);
        assert!(at(0.1, 0.5) > 0.6);
        assert!(at(0.42, 0.15) > 0.6);
        assert!(at(0.42, 0.92) > 0.6);
    }

    #[test]
    fn coordinates_are_in_metres() {
        // A wall 6 m long facing south; 1 m a picture: u counts metres along it to the right,
        // v metres up it (negated, glTF's v runs down the picture).
        let m = UvMap::wall(DVec2::new(10.0, 5.0), DVec2::new(16.0, 5.0), 2.0, 1.0, 1.0);
        assert_eq!(m.uv(DVec3::new(13.0, 5.0, 4.5)), [3.0, -2.5]);
        // A roof sloping up to the north: v up the slope, in metres along it.
        let n = DVec3::new(0.0, -1.0, 1.0).normalize();
        let r = UvMap::plane(n, DVec3::ZERO, 1.0, 1.0);
        let [u, v] = r.uv(DVec3::new(2.0, 3.0, 3.0));
        assert!(
            (u - 2.0).abs() < 1e-6 && (v + 18f32.sqrt()).abs() < 1e-5,
            "{u} {v}"
        );
        assert_eq!(bays(10.0, 3.0), 3.0);
        let f = |p: &str| folder_name(std::path::Path::new(p));
        assert_eq!(f("d/out.gml"), "out_textures");
        assert_eq!(f("out.city.json"), f("out.city.jsonl"));
        assert_eq!(f("m_371000.5_1.gml"), "m_371000.5_1_textures");
        assert_eq!(
            Texture::Surface(Material::RoofTiles).file_name(),
            "roof_tiles.png"
        );
        assert_eq!(bays(1.0, 3.0), 1.0);
    }
}
