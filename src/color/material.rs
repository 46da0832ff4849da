//! Surface materials (issue 49): the one table every writer draws a surface's material from —
//! glTF and 3D Tiles `pbrMetallicRoughness`, CityGML `app:X3DMaterial`, CityJSON
//! `appearance.materials`, IFC `IfcSurfaceStyleRendering` — and the one reading of the OSM
//! `building:material` / `roof:material` values and the knowledge base's `material` into it.
//!
//! A surface's colour is decided elsewhere (tags, then the material's usual colour
//! ([`usual_color`]), then the knowledge base); its material only adds how it reflects:
//! roughness and metalness (glTF's metallic-roughness model), from which the other formats'
//! parameters follow ([`Material::shininess`], [`Material::reflectance_method`]).
//!
//! **Where the values come from.** Metalness is 1 for bare metal and 0 for every dielectric
//! (glTF 2.0 specification, Appendix B, "metallic-roughness material": values between are for
//! blending at the edge of a texture, not for a material). Roughness is a judgment per
//! material within the ranges the public PBR charts give (the DONTNOD "Physically based"
//! chart as reproduced in studio-397's "PBR authoring" notes, and the Physically Based
//! database, physicallybased.info): rough and matte for mineral renders, brick, concrete,
//! earth, thatch, gravel and vegetation (0.85–1), a little smoother for cut stone, glazed clay
//! tiles, planed timber and tar (0.6–0.85), smoother still for slate (0.6) and sheet metal
//! (0.4). The usual colours are those citygen already gave the OSM material values (typical
//! albedos within those charts: clay tiles, slate, weathered zinc, copper patina, concrete,
//! brick). Glazing keeps the writers' earlier look (roughness 0.1, metalness 0.2): a stand-in
//! for the reflections of glass in a viewer without transmission; physically, glass is a
//! smooth dielectric (metalness 0), and the writers draw transparent glass with its
//! transparency.

use super::Color;

/// What a surface is made of, as far as it changes how the surface reflects light.
///
/// The order is the writers' order of materials where they sort by it (3D Tiles' primitives):
/// [`Material::Unspecified`] first and [`Material::Glass`] last, so that a run with no
/// material known is laid out as before materials existed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub enum Material {
    /// Nothing known: matte, as every surface was drawn before materials.
    #[default]
    Unspecified,
    /// Render, plaster, stucco.
    Plaster,
    /// Brick.
    Brick,
    /// Natural stone: sandstone, limestone, marble, granite, tuff.
    Stone,
    /// Concrete and cement blocks.
    Concrete,
    /// Wood, timber framing.
    Timber,
    /// Sheet metal, steel, zinc, copper.
    Metal,
    /// Mud brick, adobe, rammed earth.
    Mud,
    /// Clay roof tiles, terracotta.
    RoofTiles,
    /// Slate.
    Slate,
    /// Thatch.
    Thatch,
    /// A green roof: grass, plants.
    Green,
    /// Tar paper, asphalt, bitumen, roofing felt, fibre cement.
    Bitumen,
    /// Gravel.
    Gravel,
    /// Glass: curtain walls, glazing.
    Glass,
}

/// IFC's `IfcReflectanceMethodEnum` values citygen writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reflectance {
    /// `.MATT.`: a rough dielectric.
    Matt,
    /// `.METAL.`
    Metal,
    /// `.GLASS.`
    Glass,
    /// `.NOTDEFINED.`: nothing known.
    NotDefined,
}

impl Reflectance {
    /// The IFC enumeration literal, dots included.
    pub fn ifc(self) -> &'static str {
        match self {
            Reflectance::Matt => ".MATT.",
            Reflectance::Metal => ".METAL.",
            Reflectance::Glass => ".GLASS.",
            Reflectance::NotDefined => ".NOTDEFINED.",
        }
    }
}

/// One row of [`TABLE`]: a material's name (as the writers label it), its roughness and
/// metalness (glTF's factors, 0..=1) and its usual colour (`0xRRGGBB` sRGB).
struct Row {
    name: &'static str,
    roughness: f32,
    metallic: f32,
    color: u32,
}

const fn row(name: &'static str, roughness: f32, metallic: f32, color: u32) -> Row {
    Row {
        name,
        roughness,
        metallic,
        color,
    }
}

/// The table, in [`Material`] order (the module's doc says where the values come from).
const TABLE: [Row; 15] = [
    row("unspecified", 0.9, 0.0, 0xffffff),
    row("plaster", 0.9, 0.0, 0xe8dcc8),
    row("brick", 0.85, 0.0, 0xa0522d),
    row("stone", 0.8, 0.0, 0xa89f8f),
    row("concrete", 0.9, 0.0, 0xa8a8a0),
    row("timber", 0.75, 0.0, 0x8b5a2b),
    row("metal", 0.4, 1.0, 0x8a9197),
    row("mud", 0.95, 0.0, 0x9b7653),
    row("roof_tiles", 0.75, 0.0, 0xb5523b),
    row("slate", 0.6, 0.0, 0x4a5259),
    row("thatch", 1.0, 0.0, 0xb8a060),
    row("green", 0.95, 0.0, 0x6a8a3a),
    row("bitumen", 0.85, 0.0, 0x3c3c3c),
    row("gravel", 1.0, 0.0, 0x9a9a92),
    row("glass", 0.1, 0.2, 0xa8c8d8),
];

/// Every material, in order.
pub const ALL: [Material; 15] = [
    Material::Unspecified,
    Material::Plaster,
    Material::Brick,
    Material::Stone,
    Material::Concrete,
    Material::Timber,
    Material::Metal,
    Material::Mud,
    Material::RoofTiles,
    Material::Slate,
    Material::Thatch,
    Material::Green,
    Material::Bitumen,
    Material::Gravel,
    Material::Glass,
];

impl Material {
    fn row(self) -> &'static Row {
        &TABLE[self as usize]
    }

    /// The material's name as the writers label it (`brick`, `roof_tiles`, ...).
    pub fn name(self) -> &'static str {
        self.row().name
    }

    /// glTF `roughnessFactor`, 0..=1.
    pub fn roughness(self) -> f32 {
        self.row().roughness
    }

    /// glTF `metallicFactor`, 0..=1.
    pub fn metallic(self) -> f32 {
        self.row().metallic
    }

    /// The material's usual colour (its value's own may differ: [`usual_color`]).
    pub fn color(self) -> Color {
        Color::from_rgb24(self.row().color)
    }

    /// X3D / CityGML / CityJSON `shininess` (0..=1): one minus the roughness, rounded to
    /// 2 decimals (X3D's shininess is the specular exponent over 128, a glossiness; the
    /// usual conversion from a PBR roughness is its complement).
    pub fn shininess(self) -> f32 {
        ((1.0 - self.roughness()) * 100.0).round() / 100.0
    }

    /// IFC `IfcSpecularRoughness` (0..=1): the roughness.
    pub fn specular_roughness(self) -> f32 {
        self.roughness()
    }

    /// IFC `ReflectanceMethod`: metal, glass, matt, or not defined when nothing is known.
    pub fn reflectance_method(self) -> Reflectance {
        match self {
            Material::Unspecified => Reflectance::NotDefined,
            Material::Metal => Reflectance::Metal,
            Material::Glass => Reflectance::Glass,
            _ => Reflectance::Matt,
        }
    }

    /// The material an OSM `building:material` / `roof:material` value or a knowledge-base
    /// `material` names (case, `-` and spaces ignored; the KB's `BricksBasic` and
    /// `OfficeGlasses` included); [`Material::Unspecified`] for anything else.
    pub fn parse(value: &str) -> Material {
        lookup(value).map_or(Material::Unspecified, |(m, _)| m)
    }

    /// [`Material::parse`] of a value when there is one.
    pub fn of(value: Option<&str>) -> Material {
        value.map_or(Material::Unspecified, Material::parse)
    }

    /// The material of a window or door pane: glass when glazed, else nothing known (a door
    /// panel, an unglazed window's shutter). The one rule every writer follows for openings.
    pub fn of_pane(glazed: bool) -> Material {
        if glazed {
            Material::Glass
        } else {
            Material::Unspecified
        }
    }
}

/// The usual colour of an OSM `building:material` / `roof:material` value, when it names a
/// material ([`Material::parse`]).
pub fn usual_color(value: &str) -> Option<Color> {
    lookup(value).map(|(_, c)| Color::from_rgb24(c))
}

/// The material and usual colour (`0xRRGGBB`) of a value.
fn lookup(value: &str) -> Option<(Material, u32)> {
    use Material as M;
    let v = value.trim().to_ascii_lowercase().replace(['-', ' '], "_");
    let m = match v.as_str() {
        "roof_tiles" | "tiles" | "tile" | "clay" | "terracotta" => M::RoofTiles,
        "slate" => M::Slate,
        "metal" | "metal_sheet" | "steel" | "tin" | "zinc" | "aluminium" | "aluminum"
        | "copper" => M::Metal,
        "concrete" | "cement_block" | "reinforced_concrete" => M::Concrete,
        "glass" | "officeglasses" | "mirror" => M::Glass,
        "thatch" => M::Thatch,
        "tar_paper" | "asphalt" | "bitumen" | "eternit" | "felt" => M::Bitumen,
        "wood" | "timber" | "timber_framing" => M::Timber,
        "gravel" => M::Gravel,
        "grass" | "plants" | "green" => M::Green,
        "stone" | "sandstone" | "limestone" | "marble" | "granite" | "brownstone" | "tuff" => {
            M::Stone
        }
        "brick" | "bricks" | "bricksbasic" => M::Brick,
        "plaster" | "render" | "stucco" => M::Plaster,
        "mud" | "adobe" | "loam" | "rammed_earth" => M::Mud,
        _ => return None,
    };
    // A value's own colour where it differs from its material's.
    let color = match v.as_str() {
        "copper" => 0x6f9f8a,
        "marble" => 0xe8e6e0,
        _ => m.row().color,
    };
    Some((m, color))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table_is_in_material_order_and_physical() {
        for (i, m) in ALL.iter().enumerate() {
            assert_eq!(*m as usize, i);
            assert!((0.0..=1.0).contains(&m.roughness()), "{m:?}");
            assert!((0.0..=1.0).contains(&m.metallic()), "{m:?}");
            assert!((0.0..=1.0).contains(&m.shininess()), "{m:?}");
        }
        // Names are distinct, and metal is the one metal.
        let mut names: Vec<&str> = ALL.iter().map(|m| m.name()).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), ALL.len());
        let metals: Vec<Material> = ALL.into_iter().filter(|m| m.metallic() == 1.0).collect();
        assert_eq!(metals, [Material::Metal]);
    }

    #[test]
    fn osm_and_kb_values_name_their_material() {
        assert_eq!(Material::parse("brick"), Material::Brick);
        assert_eq!(Material::parse("BricksBasic"), Material::Brick);
        assert_eq!(Material::parse(" Roof-Tiles "), Material::RoofTiles);
        assert_eq!(Material::parse("slate"), Material::Slate);
        assert_eq!(Material::parse("OfficeGlasses"), Material::Glass);
        assert_eq!(Material::parse("timber_framing"), Material::Timber);
        assert_eq!(Material::parse("plants"), Material::Green);
        assert_eq!(Material::parse("unobtainium"), Material::Unspecified);
        assert_eq!(Material::of(None), Material::Unspecified);
        assert_eq!(usual_color("marble"), Some(Color::from_rgb24(0xe8e6e0)));
        assert_eq!(usual_color("stone"), Some(Material::Stone.color()));
        assert_eq!(usual_color("unobtainium"), None);
        assert_eq!(Material::of_pane(true), Material::Glass);
        assert_eq!(Material::Metal.reflectance_method().ifc(), ".METAL.");
    }
}
