//! Colours: CSS/X11 colour names, `#rgb`/`#rrggbb` hex, and the thesis's `r;g;b` float triples;
//! and surface materials ([`material`]).

pub mod material;

/// A linear RGBA colour with components in 0..=1 (sRGB encoded, as CSS gives them).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Color {
    /// Red component, 0..=1.
    pub r: f32,
    /// Green component, 0..=1.
    pub g: f32,
    /// Blue component, 0..=1.
    pub b: f32,
    /// Opacity, 0..=1 (1 opaque). Every parsed colour is opaque; the writers lower it for glazed
    /// windows.
    pub a: f32,
}

impl Color {
    /// Opaque white, `#ffffff`: the knowledge base's default wall and window-frame colour.
    pub const WHITE: Color = Color::rgb(1.0, 1.0, 1.0);
    /// Opaque mid grey, `#808080` (0.5 in each component).
    pub const GREY: Color = Color::rgb(0.5, 0.5, 0.5);

    /// An opaque colour.
    pub const fn rgb(r: f32, g: f32, b: f32) -> Color {
        Color { r, g, b, a: 1.0 }
    }

    /// Parses a CSS colour name (all 148 of CSS Color 4, case-insensitive, `grey`/`gray`
    /// spellings), `#rgb`, `#rrggbb`, or a thesis triple `r;g;b` of floats in 0..=1 (or 0..=255
    /// integers). Returns `None` for anything else.
    pub fn parse(s: &str) -> Option<Color> {
        let s = s.trim();
        if let Some(hex) = s.strip_prefix('#') {
            return parse_hex(hex);
        }
        if s.contains(';') {
            return parse_triple(s);
        }
        let lower = s.to_ascii_lowercase();
        CSS_NAMES
            .binary_search_by(|(name, _)| name.cmp(&lower.as_str()))
            .ok()
            .and_then(|i| CSS_NAMES.get(i))
            .map(|&(_, v)| Color::from_rgb24(v))
    }

    /// An opaque colour from a packed `0xRRGGBB` value.
    pub(crate) const fn from_rgb24(v: u32) -> Color {
        Color::rgb(
            ((v >> 16) & 0xff) as f32 / 255.0,
            ((v >> 8) & 0xff) as f32 / 255.0,
            (v & 0xff) as f32 / 255.0,
        )
    }

    /// The CSS Color 4 name of this colour when it is exactly one (after rounding each
    /// component to 8 bits; `gray` is preferred over `grey`, the first name in alphabetical
    /// order otherwise), else `None`.
    pub(crate) fn css_name(self) -> Option<&'static str> {
        let [r, g, b] = self.bytes();
        let v = u32::from(r) << 16 | u32::from(g) << 8 | u32::from(b);
        CSS_NAMES.iter().find(|(_, c)| *c == v).map(|(n, _)| *n)
    }

    /// `#rrggbb`.
    pub(crate) fn to_hex(self) -> String {
        const DIGITS: &[u8; 16] = b"0123456789abcdef";
        let mut s = String::with_capacity(7);
        s.push('#');
        for v in self.bytes() {
            s.push(char::from(DIGITS[usize::from(v >> 4)]));
            s.push(char::from(DIGITS[usize::from(v & 15)]));
        }
        s
    }

    /// Red, green and blue as 0..=255, as `#rrggbb` writes them.
    fn bytes(self) -> [u8; 3] {
        let c = |v: f32| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
        [c(self.r), c(self.g), c(self.b)]
    }
}

/// `rgb` or `rrggbb` without the `#`.
/// sRGB transfer function inverse (IEC 61966-2-1): an sRGB component, 0 to 1, as linear light
/// (glTF colour factors are linear). The one sRGB decoding of the writers and the preview.
pub(crate) fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// An 8-bit sRGB component as linear light, 0..=1 ([`srgb_to_linear`] of `c / 255`).
pub(crate) fn srgb_u8_to_linear(c: u8) -> f32 {
    srgb_to_linear(f32::from(c) / 255.0)
}

fn parse_hex(hex: &str) -> Option<Color> {
    if !hex.bytes().all(|b| b.is_ascii_hexdigit()) {
        return None;
    }
    match hex.len() {
        3 => {
            let v = u32::from_str_radix(hex, 16).ok()?;
            // Each digit d stands for dd.
            let (r, g, b) = ((v >> 8) & 0xf, (v >> 4) & 0xf, v & 0xf);
            Some(Color::from_rgb24((r * 17) << 16 | (g * 17) << 8 | (b * 17)))
        }
        6 => u32::from_str_radix(hex, 16).ok().map(Color::from_rgb24),
        _ => None,
    }
}

/// The thesis triple `r;g;b` (its earth colour is `1;1;1`). Components are floats in 0..=1,
/// or, when any component is above 1, integers in 0..=255. Decimal commas are accepted.
fn parse_triple(s: &str) -> Option<Color> {
    let parts: Vec<&str> = s.split(';').map(str::trim).collect();
    if parts.len() != 3 {
        return None;
    }
    let mut v = [0f64; 3];
    for (slot, p) in v.iter_mut().zip(&parts) {
        let x: f64 = p.replace(',', ".").parse().ok()?;
        if !x.is_finite() || x < 0.0 {
            return None;
        }
        *slot = x;
    }
    let scale = if v.iter().any(|&x| x > 1.0) {
        // 0..=255 integers: reject fractions and out-of-range values rather than guess.
        if v.iter().any(|&x| x > 255.0 || x.fract() != 0.0) {
            return None;
        }
        255.0
    } else {
        1.0
    };
    Some(Color::rgb(
        (v[0] / scale) as f32,
        (v[1] / scale) as f32,
        (v[2] / scale) as f32,
    ))
}

/// The 148 named colours of CSS Color Module Level 4, sorted by name (binary-searched).
const CSS_NAMES: [(&str, u32); 148] = [
    ("aliceblue", 0xf0f8ff),
    ("antiquewhite", 0xfaebd7),
    ("aqua", 0x00ffff),
    ("aquamarine", 0x7fffd4),
    ("azure", 0xf0ffff),
    ("beige", 0xf5f5dc),
    ("bisque", 0xffe4c4),
    ("black", 0x000000),
    ("blanchedalmond", 0xffebcd),
    ("blue", 0x0000ff),
    ("blueviolet", 0x8a2be2),
    ("brown", 0xa52a2a),
    ("burlywood", 0xdeb887),
    ("cadetblue", 0x5f9ea0),
    ("chartreuse", 0x7fff00),
    ("chocolate", 0xd2691e),
    ("coral", 0xff7f50),
    ("cornflowerblue", 0x6495ed),
    ("cornsilk", 0xfff8dc),
    ("crimson", 0xdc143c),
    ("cyan", 0x00ffff),
    ("darkblue", 0x00008b),
    ("darkcyan", 0x008b8b),
    ("darkgoldenrod", 0xb8860b),
    ("darkgray", 0xa9a9a9),
    ("darkgreen", 0x006400),
    ("darkgrey", 0xa9a9a9),
    ("darkkhaki", 0xbdb76b),
    ("darkmagenta", 0x8b008b),
    ("darkolivegreen", 0x556b2f),
    ("darkorange", 0xff8c00),
    ("darkorchid", 0x9932cc),
    ("darkred", 0x8b0000),
    ("darksalmon", 0xe9967a),
    ("darkseagreen", 0x8fbc8f),
    ("darkslateblue", 0x483d8b),
    ("darkslategray", 0x2f4f4f),
    ("darkslategrey", 0x2f4f4f),
    ("darkturquoise", 0x00ced1),
    ("darkviolet", 0x9400d3),
    ("deeppink", 0xff1493),
    ("deepskyblue", 0x00bfff),
    ("dimgray", 0x696969),
    ("dimgrey", 0x696969),
    ("dodgerblue", 0x1e90ff),
    ("firebrick", 0xb22222),
    ("floralwhite", 0xfffaf0),
    ("forestgreen", 0x228b22),
    ("fuchsia", 0xff00ff),
    ("gainsboro", 0xdcdcdc),
    ("ghostwhite", 0xf8f8ff),
    ("gold", 0xffd700),
    ("goldenrod", 0xdaa520),
    ("gray", 0x808080),
    ("green", 0x008000),
    ("greenyellow", 0xadff2f),
    ("grey", 0x808080),
    ("honeydew", 0xf0fff0),
    ("hotpink", 0xff69b4),
    ("indianred", 0xcd5c5c),
    ("indigo", 0x4b0082),
    ("ivory", 0xfffff0),
    ("khaki", 0xf0e68c),
    ("lavender", 0xe6e6fa),
    ("lavenderblush", 0xfff0f5),
    ("lawngreen", 0x7cfc00),
    ("lemonchiffon", 0xfffacd),
    ("lightblue", 0xadd8e6),
    ("lightcoral", 0xf08080),
    ("lightcyan", 0xe0ffff),
    ("lightgoldenrodyellow", 0xfafad2),
    ("lightgray", 0xd3d3d3),
    ("lightgreen", 0x90ee90),
    ("lightgrey", 0xd3d3d3),
    ("lightpink", 0xffb6c1),
    ("lightsalmon", 0xffa07a),
    ("lightseagreen", 0x20b2aa),
    ("lightskyblue", 0x87cefa),
    ("lightslategray", 0x778899),
    ("lightslategrey", 0x778899),
    ("lightsteelblue", 0xb0c4de),
    ("lightyellow", 0xffffe0),
    ("lime", 0x00ff00),
    ("limegreen", 0x32cd32),
    ("linen", 0xfaf0e6),
    ("magenta", 0xff00ff),
    ("maroon", 0x800000),
    ("mediumaquamarine", 0x66cdaa),
    ("mediumblue", 0x0000cd),
    ("mediumorchid", 0xba55d3),
    ("mediumpurple", 0x9370db),
    ("mediumseagreen", 0x3cb371),
    ("mediumslateblue", 0x7b68ee),
    ("mediumspringgreen", 0x00fa9a),
    ("mediumturquoise", 0x48d1cc),
    ("mediumvioletred", 0xc71585),
    ("midnightblue", 0x191970),
    ("mintcream", 0xf5fffa),
    ("mistyrose", 0xffe4e1),
    ("moccasin", 0xffe4b5),
    ("navajowhite", 0xffdead),
    ("navy", 0x000080),
    ("oldlace", 0xfdf5e6),
    ("olive", 0x808000),
    ("olivedrab", 0x6b8e23),
    ("orange", 0xffa500),
    ("orangered", 0xff4500),
    ("orchid", 0xda70d6),
    ("palegoldenrod", 0xeee8aa),
    ("palegreen", 0x98fb98),
    ("paleturquoise", 0xafeeee),
    ("palevioletred", 0xdb7093),
    ("papayawhip", 0xffefd5),
    ("peachpuff", 0xffdab9),
    ("peru", 0xcd853f),
    ("pink", 0xffc0cb),
    ("plum", 0xdda0dd),
    ("powderblue", 0xb0e0e6),
    ("purple", 0x800080),
    ("rebeccapurple", 0x663399),
    ("red", 0xff0000),
    ("rosybrown", 0xbc8f8f),
    ("royalblue", 0x4169e1),
    ("saddlebrown", 0x8b4513),
    ("salmon", 0xfa8072),
    ("sandybrown", 0xf4a460),
    ("seagreen", 0x2e8b57),
    ("seashell", 0xfff5ee),
    ("sienna", 0xa0522d),
    ("silver", 0xc0c0c0),
    ("skyblue", 0x87ceeb),
    ("slateblue", 0x6a5acd),
    ("slategray", 0x708090),
    ("slategrey", 0x708090),
    ("snow", 0xfffafa),
    ("springgreen", 0x00ff7f),
    ("steelblue", 0x4682b4),
    ("tan", 0xd2b48c),
    ("teal", 0x008080),
    ("thistle", 0xd8bfd8),
    ("tomato", 0xff6347),
    ("turquoise", 0x40e0d0),
    ("violet", 0xee82ee),
    ("wheat", 0xf5deb3),
    ("white", 0xffffff),
    ("whitesmoke", 0xf5f5f5),
    ("yellow", 0xffff00),
    ("yellowgreen", 0x9acd32),
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_is_sorted_and_complete() {
        assert!(CSS_NAMES.windows(2).all(|w| w[0].0 < w[1].0));
        assert_eq!(CSS_NAMES.len(), 148);
    }

    #[test]
    fn names_case_insensitive_and_trimmed() {
        assert_eq!(
            Color::parse(" AliceBlue\n").map(Color::to_hex).as_deref(),
            Some("#f0f8ff")
        );
        assert_eq!(
            Color::parse("yellowgreen").map(Color::to_hex).as_deref(),
            Some("#9acd32")
        );
        assert_eq!(Color::parse("grey"), Color::parse("gray"));
        assert_eq!(
            Color::parse("lightslategrey"),
            Color::parse("LightSlateGray")
        );
        assert_eq!(
            Color::parse("darkred").map(Color::to_hex).as_deref(),
            Some("#8b0000")
        );
        assert_eq!(
            Color::parse("rebeccapurple").map(Color::to_hex).as_deref(),
            Some("#663399")
        );
        assert_eq!(Color::parse("notacolour"), None);
        assert_eq!(Color::parse(""), None);
    }

    #[test]
    fn every_thesis_name_parses() {
        for n in [
            "pink",
            "grey",
            "yellow",
            "blue",
            "white",
            "red",
            "black",
            "floralwhite",
            "lightslategray",
            "seashell",
            "peru",
            "ivory",
            "paleturquoise",
            "darkred",
            "tomato",
            "brown",
            "indianred",
            "gold",
            "sandybrown",
            "green",
            "turquoise",
            "lightblue",
            "blanchedalmond",
            "silver",
            "lightsalmon",
            "darksalmon",
            "palegoldenrod",
            "lightgrey",
        ] {
            assert!(Color::parse(n).is_some(), "{n}");
        }
    }

    #[test]
    fn hex_forms() {
        assert_eq!(Color::parse("#fff"), Some(Color::WHITE));
        assert_eq!(
            Color::parse("#A52A2A").map(Color::to_hex).as_deref(),
            Some("#a52a2a")
        );
        assert_eq!(
            Color::parse("#1a2").map(Color::to_hex).as_deref(),
            Some("#11aa22")
        );
        assert_eq!(Color::parse("#12345"), None);
        assert_eq!(Color::parse("#ggg"), None);
        assert_eq!(Color::parse("#"), None);
    }

    #[test]
    fn thesis_triples() {
        assert_eq!(Color::parse("1;1;1"), Some(Color::WHITE));
        assert_eq!(Color::parse(" 0.5 ; 0,5 ;0.5 "), Some(Color::GREY));
        assert_eq!(Color::parse("255;0;0"), Color::parse("red"));
        assert_eq!(Color::parse("255;0.5;0"), None);
        assert_eq!(Color::parse("256;0;0"), None);
        assert_eq!(Color::parse("1;1"), None);
        assert_eq!(Color::parse("-1;0;0"), None);
        assert_eq!(Color::parse("nan;0;0"), None);
    }

    #[test]
    fn css_name_round_trips() {
        assert_eq!(
            Color::parse("darkred").and_then(Color::css_name),
            Some("darkred")
        );
        assert_eq!(
            Color::parse("#808080").and_then(Color::css_name),
            Some("gray")
        );
        assert_eq!(Color::parse("#808081").and_then(Color::css_name), None);
    }
}
