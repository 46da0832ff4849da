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

    /// A finite number with exactly 3 decimals, never `-0.000` (the digits of
    /// [`format::push_fixed3`], without its general cases where they cannot arise).
    pub(super) fn fixed3(&mut self, v: f64) {
        let mut buf = [0u8; FIXED3_MAX];
        match fixed3_put(&mut buf, v) {
            Some(len) => self.0.extend_from_slice(&buf[..len]),
            None => format::push_fixed3(&mut self.0, v),
        }
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
            SurfaceKind::Sill { wall } => {
                self.s("_w");
                self.uint(wall as u64);
                self.s("_sill");
                self.uint(index as u64);
            }
            SurfaceKind::Trim { eaves } => {
                self.s(if eaves { "_eaves" } else { "_cornice" });
                self.uint(index as u64);
            }
        }
    }

    /// A `gml:Polygon` with its id, exterior and interiors; rings closed by repeating the first
    /// point, coordinates `origin + p`.
    pub(super) fn polygon(&mut self, part_id: &str, s: &Surface<'_>, origin: DVec3) {
        self.polygon_rings(part_id, s, origin, false);
    }

    /// [`Xml::polygon`], with `ring_ids` each ring with a `gml:id`: the polygon's and `_e` for
    /// the exterior, `_h0`, `_h1` ... for the interiors (the rings a texture's coordinates
    /// name, `--textures`).
    pub(super) fn polygon_rings(
        &mut self,
        part_id: &str,
        s: &Surface<'_>,
        origin: DVec3,
        ring_ids: bool,
    ) {
        self.s("<gml:Polygon gml:id=\"");
        self.polygon_id(part_id, s.kind, s.index);
        self.s("\">\n");
        if let Some(outer) = ring(&s.face.outer) {
            self.s("<gml:exterior>\n");
            if ring_ids {
                self.s("<gml:LinearRing gml:id=\"");
                self.ring_id(part_id, s.kind, s.index, None);
                self.s("\">");
            } else {
                self.s("<gml:LinearRing>");
            }
            self.ring_points(outer, origin);
            self.s("</gml:exterior>\n");
        }
        for (k, hole) in s.face.holes.iter().filter_map(|h| ring(h)).enumerate() {
            self.s("<gml:interior>\n");
            if ring_ids {
                self.s("<gml:LinearRing gml:id=\"");
                self.ring_id(part_id, s.kind, s.index, Some(k));
                self.s("\">");
            } else {
                self.s("<gml:LinearRing>");
            }
            self.ring_points(hole, origin);
            self.s("</gml:interior>\n");
        }
        self.s("</gml:Polygon>\n");
    }

    /// The id of a ring of a polygon ([`Xml::polygon_rings`]): its exterior (`hole` none) or
    /// its interior `hole` (counting the written ones).
    pub(super) fn ring_id(
        &mut self,
        part_id: &str,
        kind: SurfaceKind,
        index: usize,
        hole: Option<usize>,
    ) {
        self.polygon_id(part_id, kind, index);
        match hole {
            None => self.s("_e"),
            Some(k) => {
                self.s("_h");
                self.uint(k as u64);
            }
        }
    }

    /// A ring as written: millimetres, closed. The rounding can make neighbouring points one
    /// (a point 0.4 mm from the next) or fold a ring back on itself (`x, y, x`): those are
    /// written once ([`written_ring`]), so no ring of the file repeats a point or has a spike.
    pub(super) fn linear_ring(&mut self, points: &[DVec3], origin: DVec3) {
        self.s("<gml:LinearRing>");
        self.ring_points(points, origin);
    }

    /// The `gml:posList` of a ring ([`written_points`]) and the ring's end tag.
    fn ring_points(&mut self, points: &[DVec3], origin: DVec3) {
        let points = written_points(points, origin);
        let points: &[DVec3] = &points;
        self.s("<gml:posList srsDimension=\"3\">");
        // The digits go straight into the buffer: it is grown (zeroed) a few points ahead of
        // what is written, and cut back to what was written at the end.
        let total = points.len() + 1;
        let mut len = self.0.len();
        for (i, p) in points.iter().chain(points.first()).enumerate() {
            if self.0.len() < len + POINT_TEXT {
                let ahead = (total - i).min(RING_AHEAD);
                self.0.resize(len + ahead * POINT_TEXT, 0);
            }
            if i > 0 {
                self.0[len] = b' ';
                len += 1;
            }
            let q = origin + *p;
            for (k, v) in [q.x, q.y, q.z].into_iter().enumerate() {
                if k > 0 {
                    self.0[len] = b' ';
                    len += 1;
                }
                match fixed3_put(&mut self.0[len..], v) {
                    Some(n) => len += n,
                    None => {
                        // Beyond a million kilometres: the general formatter, point by point.
                        self.0.truncate(len);
                        format::push_fixed3(&mut self.0, v);
                        len = self.0.len();
                        let ahead = (total - i).min(RING_AHEAD);
                        self.0.resize(len + ahead * POINT_TEXT, 0);
                    }
                }
            }
        }
        self.0.truncate(len);
        self.s("</gml:posList></gml:LinearRing>\n");
    }
}

/// `v` rounded to the nearest integer, halves away from zero, as `f64::round` (which is a libm
/// call without SSE4.1), for `|v| < 1e18`; `None` beyond.
#[inline]
fn round_i64(v: f64) -> Option<i64> {
    if v.is_nan() || v.abs() >= 1e18 {
        return None;
    }
    // Exact: below 2^63 the cast truncates, and `v - t` is exact for a `t` that only clears
    // `v`'s fraction bits.
    let t = v as i64;
    let frac = v - t as f64;
    Some(if frac >= 0.5 {
        t + 1
    } else if frac <= -0.5 {
        t - 1
    } else {
        t
    })
}

/// Two-digit groups for [`fixed3_put`].
const DIGIT_PAIRS: &[u8; 200] = b"00010203040506070809101112131415161718192021222324252627282930313233343536373839404142434445464748495051525354555657585960616263646566676869707172737475767778798081828384858687888990919293949596979899";

/// Bytes one point of a ring can take (three numbers of at most [`FIXED3_MAX`] bytes, their
/// separators and the one before the point), for [`Xml::linear_ring`].
const POINT_TEXT: usize = 3 * (FIXED3_MAX + 1);

/// Points of a ring the buffer is grown ahead of what is written.
const RING_AHEAD: usize = 32;

/// The most bytes [`fixed3_put`] writes: a sign, 15 digits (`|v| < 1e15` after scaling by
/// 1000 is below 1e18), the point and 3 decimals.
const FIXED3_MAX: usize = 24;

/// Writes `v` with exactly 3 decimals (as [`format::push_fixed3`]: `(v * 1000).round()`
/// millimetres, never `-0.000`) at the start of `out` (at least [`FIXED3_MAX`] bytes long);
/// returns its length. `None` when `|v * 1000|` reaches 1e18, which the general formatter
/// handles.
#[inline]
fn fixed3_put(out: &mut [u8], v: f64) -> Option<usize> {
    let n = round_i64(v * 1000.0)?;
    let mut m = n.unsigned_abs();
    let frac = (m % 1000) as usize;
    m /= 1000;
    let digits = m.checked_ilog10().unwrap_or(0) as usize + 1;
    let len = usize::from(n < 0) + digits + 4;
    let out = &mut out[..len];
    if n < 0 {
        out[0] = b'-';
    }
    let mut i = len;
    out[i - 3] = b'0' + (frac / 100) as u8;
    out[i - 2..i].copy_from_slice(&DIGIT_PAIRS[2 * (frac % 100)..2 * (frac % 100) + 2]);
    out[i - 4] = b'.';
    i -= 4;
    while m >= 100 {
        let d = (m % 100) as usize;
        m /= 100;
        out[i - 2..i].copy_from_slice(&DIGIT_PAIRS[2 * d..2 * d + 2]);
        i -= 2;
    }
    if m >= 10 {
        let d = m as usize;
        out[i - 2..i].copy_from_slice(&DIGIT_PAIRS[2 * d..2 * d + 2]);
    } else {
        out[i - 1] = b'0' + m as u8;
    }
    Some(len)
}

/// Whether the ring, as written, has no repeated consecutive point and no `x, y, x` spike
/// (nearly every ring): then [`written_ring`] would return it unchanged.
fn written_clean(points: &[DVec3], origin: DVec3) -> bool {
    let key = |p: &DVec3| {
        let g = (origin + *p) * 1000.0;
        let r = |v: f64| round_i64(v).unwrap_or(v.round() as i64);
        (r(g.x), r(g.y), r(g.z))
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

/// The points a ring is written with: [`written_ring`] when the rounding to millimetres makes
/// repeats or spikes (and it keeps 3 points), else the ring as it is. A texture's coordinates
/// are those of these points, one each.
pub(super) fn written_points(points: &[DVec3], origin: DVec3) -> std::borrow::Cow<'_, [DVec3]> {
    if written_clean(points, origin) {
        return std::borrow::Cow::Borrowed(points);
    }
    let cleaned = written_ring(points, origin);
    if cleaned.len() >= 3 {
        std::borrow::Cow::Owned(cleaned)
    } else {
        std::borrow::Cow::Borrowed(points)
    }
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

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn general(v: f64) -> Vec<u8> {
        let mut out = Vec::new();
        format::push_fixed3(&mut out, v);
        out
    }

    fn fast(v: f64) -> Vec<u8> {
        let mut x = Xml(Vec::new());
        x.fixed3(v);
        x.0
    }

    #[test]
    fn fixed3_writes_the_general_formatters_digits() {
        for v in [
            0.0,
            -0.0,
            -0.0004,
            0.0005,
            -0.0005,
            1.2345,
            -1.2346,
            0.5,
            999.9995,
            574_321.5,
            6_279_000.123_456,
            -42.0,
            1e14,
            9.99e14,
            1e15,
            1e30,
            -1e30,
        ] {
            assert_eq!(fast(v), general(v), "{v}");
        }
    }

    /// The ring's text as the general formatter writes it.
    fn ring_text(points: &[DVec3], origin: DVec3) -> Vec<u8> {
        let mut out = b"<gml:LinearRing><gml:posList srsDimension=\"3\">".to_vec();
        for (i, p) in points.iter().chain(points.first()).enumerate() {
            let q = origin + *p;
            for (k, v) in [q.x, q.y, q.z].into_iter().enumerate() {
                if i > 0 || k > 0 {
                    out.push(b' ');
                }
                format::push_fixed3(&mut out, v);
            }
        }
        out.extend_from_slice(b"</gml:posList></gml:LinearRing>\n");
        out
    }

    #[test]
    fn long_rings_and_huge_coordinates_are_written_as_the_general_formatter() {
        let origin = DVec3::new(574_321.25, 6_279_000.5, 12.0);
        // 100 points on a circle (more than `RING_AHEAD`), then one far beyond a million km.
        let mut points: Vec<DVec3> = (0..100)
            .map(|k| {
                let a = k as f64 * std::f64::consts::TAU / 100.0;
                DVec3::new(30.0 * a.cos(), -30.0 * a.sin(), 0.001 * k as f64)
            })
            .collect();
        let mut x = Xml(b"<a>".to_vec());
        x.linear_ring(&points, origin);
        assert_eq!(x.0[3..], ring_text(&points, origin)[..]);
        points[40] = DVec3::new(1e30, -2e31, 5.0);
        points[41] = DVec3::new(3.0, -1e25, 5.0);
        let mut x = Xml(Vec::new());
        x.linear_ring(&points, origin);
        assert_eq!(x.0, ring_text(&points, origin));
    }

    proptest! {
        #[test]
        fn fixed3_matches_push_fixed3(v in -1e16f64..1e16, m in -10_000_000i64..10_000_000) {
            prop_assert_eq!(fast(v), general(v));
            // Halves of a millimetre, where rounding ties.
            let t = m as f64 / 1000.0 + 0.0005;
            prop_assert_eq!(fast(t), general(t));
        }
    }
}
