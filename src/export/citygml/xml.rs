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

    /// A ring as written: millimetres, closed. The rounding can make neighbouring points one
    /// (a point 0.4 mm from the next) or fold a ring back on itself (`x, y, x`): those are
    /// written once ([`written_ring`]), so no ring of the file repeats a point or has a spike.
    pub(super) fn linear_ring(&mut self, points: &[DVec3], origin: DVec3) {
        let cleaned;
        let points: &[DVec3] = if written_clean(points, origin) {
            points
        } else {
            cleaned = written_ring(points, origin);
            if cleaned.len() >= 3 {
                &cleaned
            } else {
                points
            }
        };
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

/// Whether the ring, as written, has no repeated consecutive point and no `x, y, x` spike
/// (nearly every ring): then [`written_ring`] would return it unchanged.
fn written_clean(points: &[DVec3], origin: DVec3) -> bool {
    let key = |p: &DVec3| {
        let g = (origin + *p) * 1000.0;
        (g.x.round() as i64, g.y.round() as i64, g.z.round() as i64)
    };
    let n = points.len();
    if n < 3 {
        return false;
    }
    let (mut a, mut b) = (key(&points[n - 2]), key(&points[n - 1]));
    for p in points {
        let c = key(p);
        if b == c || a == c {
            return false;
        }
        (a, b) = (b, c);
    }
    true
}

/// The points of a ring as the file holds them (millimetres of `origin + p`), without
/// consecutive repeats (the closing one included) and spikes (`x, y, x` becomes `x`); the
/// points are the ring's own, not moved. May return fewer than 3 points: the caller then keeps
/// the ring as it was (a polygon is never dropped, the solid refers to it).
pub(super) fn written_ring(points: &[DVec3], origin: DVec3) -> Vec<DVec3> {
    let key = |p: &DVec3| {
        let g = (origin + *p) * 1000.0;
        (g.x.round() as i64, g.y.round() as i64, g.z.round() as i64)
    };
    let mut r: Vec<(_, DVec3)> = points.iter().map(|p| (key(p), *p)).collect();
    loop {
        let before = r.len();
        r.dedup_by_key(|(k, _)| *k);
        while r.len() > 1 && r.first().map(|x| x.0) == r.last().map(|x| x.0) {
            r.pop();
        }
        let n = r.len();
        if n >= 3 {
            if let Some(i) = (0..n).find(|&i| r[(i + n - 1) % n].0 == r[(i + 1) % n].0) {
                // x, y, x: drop y and the second x.
                let next = (i + 1) % n;
                let (a, b) = if i < next { (i, next) } else { (next, i) };
                r.remove(b);
                r.remove(a);
            }
        }
        if r.len() == before || r.len() < 3 {
            break;
        }
    }
    r.into_iter().map(|(_, p)| p).collect()
}
