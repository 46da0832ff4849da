//! The XML output buffer of the CityGML writer: text, escaping, numbers, polygon ids, polygons and
//! linear rings.

use glam::DVec3;

use crate::export::format;

use super::surfaces::{ring, Surface, SurfaceKind};

/// An output buffer with the few XML writing primitives the writer needs.
pub(super) struct Xml(pub(super) Vec<u8>);

impl Xml {
    #[inline]
    pub(super) fn s(&mut self, s: &str) {
        self.0.extend_from_slice(s.as_bytes());
    }

    /// Writes `s` escaped for element content (`attr == false`) or a double-quoted attribute.
    /// Characters XML 1.0 cannot carry at all (most C0 controls, U+FFFE, U+FFFF) become U+FFFD,
    /// so any name gives a well-formed file; in attributes tabs and line breaks are written as
    /// character references so that attribute normalisation keeps them.
    pub(super) fn escaped(&mut self, s: &str, attr: bool) {
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

    pub(super) fn uint(&mut self, v: u64) {
        format::push_uint(&mut self.0, v);
    }

    /// A finite number with exactly 3 decimals, never `-0.000`.
    pub(super) fn fixed3(&mut self, v: f64) {
        format::push_fixed3(&mut self.0, v);
    }

    /// A value in 1/10000 as a decimal with 4 places (`5020` -> `0.5020`).
    pub(super) fn fixed4(&mut self, v: u16) {
        format::push_fixed4(&mut self.0, v);
    }

    pub(super) fn point(&mut self, p: DVec3) {
        self.fixed3(p.x);
        self.0.push(b' ');
        self.fixed3(p.y);
        self.0.push(b' ');
        self.fixed3(p.z);
    }

    pub(super) fn polygon_id(&mut self, part_id: &str, kind: SurfaceKind, index: usize) {
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
    pub(super) fn polygon(&mut self, part_id: &str, s: &Surface<'_>, origin: DVec3) {
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

    pub(super) fn linear_ring(&mut self, points: &[DVec3], origin: DVec3) {
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
