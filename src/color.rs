//! Colours: CSS/X11 colour names, `#rgb`/`#rrggbb` hex, and the thesis's `r;g;b` float triples.

/// A linear RGBA colour with components in 0..=1 (sRGB encoded, as CSS gives them).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Color {
    pub r: f32,
    pub g: f32,
    pub b: f32,
    pub a: f32,
}

impl Color {
    pub const WHITE: Color = Color::rgb(1.0, 1.0, 1.0);
    pub const GREY: Color = Color::rgb(0.5, 0.5, 0.5);

    /// An opaque colour.
    pub const fn rgb(r: f32, g: f32, b: f32) -> Color {
        Color { r, g, b, a: 1.0 }
    }

    /// Parses a CSS colour name (all 148 of CSS Color 4, case-insensitive, `grey`/`gray`
    /// spellings), `#rgb`, `#rrggbb`, or a thesis triple `r;g;b` of floats in 0..=1 (or 0..=255
    /// integers). Returns `None` for anything else.
    pub fn parse(s: &str) -> Option<Color> {
        todo!("color::parse {s}")
    }

    /// `#rrggbb`.
    pub fn to_hex(self) -> String {
        let c = |v: f32| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
        format!("#{:02x}{:02x}{:02x}", c(self.r), c(self.g), c(self.b))
    }
}
