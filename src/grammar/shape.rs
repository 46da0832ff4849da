//! Shapes, their geometry and scope, the shape tree, and the planar helpers derivation needs
//! (oriented frames of footprints, clipping a footprint to a slab).

use std::ops::Range;
use std::sync::Arc;

use geo::BooleanOps;
use glam::{DVec2, DVec3};

use super::ast::Attrs;
use crate::geometry::Polygon;

/// Lengths below this (metres) are treated as zero: empty split pieces, degenerate edges.
pub const EPS: f64 = 1e-9;
/// Pieces of a clipped footprint smaller than this (m²) are slivers and are dropped.
pub const MIN_AREA: f64 = 1e-6;

/// An oriented box: origin (its minimum corner), three orthonormal axes, and sizes along them.
///
/// In this core the axes are always X and Y horizontal and Z up (R rotates about Z only), but
/// they are stored as full 3D vectors so that a later issue can add X/Y rotations.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scope {
    /// The minimum corner of the box.
    pub origin: DVec3,
    /// Unit X axis.
    pub x: DVec3,
    /// Unit Y axis (`z × x`).
    pub y: DVec3,
    /// Unit Z axis.
    pub z: DVec3,
    /// Sizes along X, Y, Z (sx, sy, sz).
    pub size: DVec3,
}

impl Scope {
    /// The smallest box with horizontal X axis `x_dir` (normalised here), Y = Z × X, Z up, that
    /// holds `poly` between heights `z0` and `z0 + height`.
    pub fn around(poly: &Polygon, x_dir: DVec2, z0: f64, height: f64) -> Scope {
        let x2 = x_dir.try_normalize().unwrap_or(DVec2::X);
        let y2 = x2.perp();
        let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
        for p in &poly.outer {
            let q = DVec2::new(p.dot(x2), p.dot(y2));
            lo = lo.min(q);
            hi = hi.max(q);
        }
        if !lo.x.is_finite() {
            lo = DVec2::ZERO;
            hi = DVec2::ZERO;
        }
        let o = x2 * lo.x + y2 * lo.y;
        Scope {
            origin: DVec3::new(o.x, o.y, z0),
            x: DVec3::new(x2.x, x2.y, 0.0),
            y: DVec3::new(y2.x, y2.y, 0.0),
            z: DVec3::Z,
            size: DVec3::new(hi.x - lo.x, hi.y - lo.y, height),
        }
    }

    /// The horizontal X direction as a 2D vector.
    pub fn x2(&self) -> DVec2 {
        DVec2::new(self.x.x, self.x.y)
    }

    /// The horizontal Y direction as a 2D vector.
    pub fn y2(&self) -> DVec2 {
        DVec2::new(self.y.x, self.y.y)
    }

    /// The origin projected on the ground plane.
    pub fn origin2(&self) -> DVec2 {
        DVec2::new(self.origin.x, self.origin.y)
    }
}

/// The place of a shape in the spatial hierarchy (§3.3.1.3), which the exporters read.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Label {
    /// The 2D axiom (a footprint) and anything derived from it without extrusion.
    Lot,
    /// The result of `extrude`.
    Building,
    /// A vertical (X or Y) cut of a building or building part.
    BuildingPart,
    /// A horizontal (Z) cut of a building or building part.
    Storey,
    /// Any cut of a storey (or of a room).
    Room,
    /// A face made by `comp` (see [`FaceKind`] for side/top/bottom).
    Facade,
    /// Any subdivision of a facade or facade part.
    FacadePart,
}

/// The kind of a terminal (leaf) shape.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Terminal {
    /// `wall`, also made for facade remainders and faces no comp selector took.
    Wall,
    /// `window`.
    Window,
    /// `door`.
    Door,
    /// `balcony`.
    Balcony,
    /// Any other symbol without rules.
    Other,
}

impl Terminal {
    /// The terminal kind of a symbol name.
    pub fn of(symbol: &str) -> Terminal {
        match symbol {
            "wall" => Terminal::Wall,
            "window" => Terminal::Window,
            "door" => Terminal::Door,
            "balcony" => Terminal::Balcony,
            _ => Terminal::Other,
        }
    }
}

/// Which face of a `comp` a face shape is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FaceKind {
    /// A vertical face, made from one footprint edge.
    Side,
    /// The horizontal top face (z0 + height).
    Top,
    /// The horizontal bottom face (z0).
    Bottom,
}

/// The geometry of a shape.
#[derive(Clone, Debug, PartialEq)]
pub enum Geometry {
    /// A 2D lot in the local frame at height `z`.
    Lot {
        /// The footprint.
        polygon: Polygon,
        /// Its height (0, or the `base` attribute of the axiom).
        z: f64,
    },
    /// A vertical prism.
    Volume {
        /// The footprint, local metres.
        footprint: Polygon,
        /// Base height.
        z0: f64,
        /// Height above `z0`.
        height: f64,
        /// The oriented box that split/S/T/R/comp refer to.
        scope: Scope,
    },
    /// A planar face. Its local frame: `origin` is its lower-left corner seen from outside,
    /// `x_axis` runs along its width, `z_axis` along its height, and the outward normal is
    /// `x_axis × z_axis`. For a side face `z_axis` is up; for a top face it is the parent's
    /// scope Y, for a bottom face the parent's −Y (so the normals are +Z and −Z).
    Face {
        /// Side, top or bottom.
        kind: FaceKind,
        /// The lower-left corner.
        origin: DVec3,
        /// Unit vector along the width.
        x_axis: DVec3,
        /// Unit vector along the height (up for side faces).
        z_axis: DVec3,
        /// Size along `x_axis`.
        width: f64,
        /// Size along `z_axis`.
        height: f64,
        /// The exact outline of a top/bottom face (or a piece of one), in plan; `None` for side
        /// faces, which are rectangles.
        polygon: Option<Polygon>,
    },
}

impl Geometry {
    /// The outward normal of a face (`None` for other geometries).
    pub fn face_normal(&self) -> Option<DVec3> {
        match self {
            Geometry::Face { x_axis, z_axis, .. } => Some(x_axis.cross(*z_axis)),
            _ => None,
        }
    }
}

/// One node of the shape tree.
#[derive(Clone, Debug)]
pub struct ShapeNode {
    /// The symbol this shape carries.
    pub symbol: Arc<str>,
    /// Its place in the spatial hierarchy.
    pub label: Label,
    /// Its attributes, inherited and overridden. Nodes without overrides share their parent's
    /// map.
    pub attrs: Arc<Attrs>,
    /// Its geometry.
    pub geometry: Geometry,
    /// `Some` for leaves: the terminal kind of the symbol.
    pub terminal: Option<Terminal>,
    /// The parent's index (`None` for the axiom).
    pub parent: Option<usize>,
    /// The children's indices: contiguous, in the order the operation made them. A
    /// non-terminal may have none when its operation made no piece (a split of a zero-size
    /// scope, a slab that misses a concave footprint).
    pub children: Range<usize>,
    /// Depth in the tree (the axiom is 0).
    pub depth: usize,
    /// The index of the rule applied to this shape (into [`super::RuleSet::rules`]), if any.
    pub rule: Option<usize>,
}

/// The derivation result: `nodes[0]` is the axiom; every node's children are contiguous.
#[derive(Clone, Debug, Default)]
pub struct ShapeTree {
    /// All nodes, parents before children.
    pub nodes: Vec<ShapeNode>,
}

impl ShapeTree {
    /// The children of node `i`.
    pub fn children(&self, i: usize) -> &[ShapeNode] {
        self.nodes
            .get(i)
            .map_or(&[], |n| &self.nodes[n.children.clone()])
    }

    /// The leaves (terminal shapes), in index order.
    pub fn leaves(&self) -> impl Iterator<Item = &ShapeNode> {
        self.nodes.iter().filter(|n| n.terminal.is_some())
    }

    /// The nearest ancestor of node `i` (itself included) with `label`.
    pub fn ancestor_with(&self, mut i: usize, label: Label) -> Option<usize> {
        loop {
            let n = self.nodes.get(i)?;
            if n.label == label {
                return Some(i);
            }
            i = n.parent?;
        }
    }
}

/// A deterministic X direction for a footprint's scope: the longer side of its minimum-area
/// bounding rectangle (rotating calipers over the convex hull of the outer ring). Of the four
/// directions along that side, the one closest to world +X is taken (ties: closest to +Y), so
/// that an east-west rectangle gets X = east, Y = north and its south facade is `front`.
pub fn dominant_direction(poly: &Polygon) -> DVec2 {
    let Some((d, square)) = min_area_rectangle(poly) else {
        return DVec2::X;
    };
    // Only the two directions along the long side compete, all four for a square.
    let cands = [d, -d, d.perp(), -d.perp()];
    let cands = if square { &cands[..] } else { &cands[..2] };
    let r = cands
        .iter()
        .copied()
        .max_by(|a, b| {
            (a.x, a.y)
                .partial_cmp(&(b.x, b.y))
                .unwrap_or(std::cmp::Ordering::Equal)
        })
        .unwrap_or(DVec2::X);
    // Snap tiny numerical noise so that axis-aligned footprints get exact axes.
    DVec2::new(snap(r.x), snap(r.y))
}

/// The X direction of a footprint's scope when the building's front is known: the scope's −Y
/// (the `front` of `comp`) is the one of the four directions along the sides of the minimum-area
/// rectangle closest to `front` (a unit vector pointing from the building to its street), and
/// X = that direction turned a quarter counter-clockwise. Without `front`, or when that choice
/// is the thesis one, this is exactly [`dominant_direction`].
///
/// Why the rectangle's directions and not the street edge's own normal: the closest of four
/// directions 90° apart is within 45° of `front`, so the edge that faces the street is always a
/// `front` face of `comp` (ties at 45° go to front, see [`super::interp`]), while the scope stays
/// aligned with the building's main axes, so that X/Y splits of rule files, `repeat`s and top
/// faces keep following the mass and differ from the thesis only by a quarter or half turn.
pub fn scope_direction(poly: &Polygon, front: Option<DVec2>) -> DVec2 {
    let thesis = dominant_direction(poly);
    let Some(front) = front.and_then(DVec2::try_normalize) else {
        return thesis;
    };
    let Some((d, _)) = min_area_rectangle(poly) else {
        return thesis;
    };
    // −Y of the thesis scope first, so that a tie keeps the thesis front.
    let thesis_front = -thesis.perp();
    let cands = [thesis_front, d, -d, d.perp(), -d.perp()];
    let best = cands
        .iter()
        .copied()
        .rev()
        .max_by(|a, b| a.dot(front).total_cmp(&b.dot(front)))
        .unwrap_or(thesis_front);
    if best.dot(front) <= thesis_front.dot(front) + 1e-12 {
        return thesis;
    }
    // −Y = best  ⇔  Y = −best  ⇔  X = best turned a quarter counter-clockwise.
    let x = best.perp();
    DVec2::new(snap(x.x), snap(x.y))
}

/// The direction of one side of the minimum-area bounding rectangle of the outer ring
/// (rotating calipers over its convex hull): the longer side, and whether the rectangle is a
/// square. `None` for fewer than two distinct points.
fn min_area_rectangle(poly: &Polygon) -> Option<(DVec2, bool)> {
    let hull = convex_hull(&poly.outer);
    if hull.len() < 2 {
        return None;
    }
    let mut best: Option<(f64, DVec2, bool)> = None;
    for i in 0..hull.len() {
        let Some(u) = (hull[(i + 1) % hull.len()] - hull[i]).try_normalize() else {
            continue;
        };
        let v = u.perp();
        let (mut lu, mut hu, mut lv, mut hv) = (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        );
        for p in &hull {
            let (a, b) = (p.dot(u), p.dot(v));
            lu = lu.min(a);
            hu = hu.max(a);
            lv = lv.min(b);
            hv = hv.max(b);
        }
        let (wu, wv) = (hu - lu, hv - lv);
        let area = wu * wv;
        let square = (wu - wv).abs() <= 1e-9 * wu.max(wv);
        let long = if wv > wu { v } else { u };
        if best.is_none_or(|(a, _, _)| area < a * (1.0 - 1e-9)) {
            best = Some((area, long, square));
        }
    }
    best.map(|(_, d, square)| (d, square))
}

fn snap(v: f64) -> f64 {
    if v.abs() < 1e-12 {
        0.0
    } else if (v.abs() - 1.0).abs() < 1e-12 {
        v.signum()
    } else {
        v
    }
}

/// Andrew's monotone chain; counter-clockwise, without collinear points.
pub fn convex_hull(pts: &[DVec2]) -> Vec<DVec2> {
    let mut p: Vec<DVec2> = pts.iter().copied().filter(|q| q.is_finite()).collect();
    p.sort_by(|a, b| {
        (a.x, a.y)
            .partial_cmp(&(b.x, b.y))
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    p.dedup();
    if p.len() < 3 {
        return p;
    }
    let cross = |o: DVec2, a: DVec2, b: DVec2| (a - o).perp_dot(b - o);
    let mut h: Vec<DVec2> = Vec::with_capacity(p.len() * 2);
    for &q in &p {
        while h.len() >= 2 && cross(h[h.len() - 2], h[h.len() - 1], q) <= 0.0 {
            h.pop();
        }
        h.push(q);
    }
    let lower = h.len() + 1;
    for &q in p.iter().rev().skip(1) {
        while h.len() >= lower && cross(h[h.len() - 2], h[h.len() - 1], q) <= 0.0 {
            h.pop();
        }
        h.push(q);
    }
    h.pop();
    h
}

/// Whether a ring is convex (counter-clockwise, collinear vertices allowed).
fn is_convex(ring: &[DVec2]) -> bool {
    let n = ring.len();
    if n < 3 {
        return false;
    }
    (0..n).all(|i| {
        let (a, b, c) = (ring[i], ring[(i + 1) % n], ring[(i + 2) % n]);
        (b - a).perp_dot(c - b) >= -1e-12 * (b - a).length() * (c - b).length()
    })
}

/// The parts of `poly` whose points `p` satisfy `lo <= (p - origin)·axis <= hi` (`axis` unit).
///
/// Convex footprints without holes (most buildings) are clipped by Sutherland–Hodgman against
/// the two half-planes; anything else goes through `geo`'s boolean intersection with a large
/// rectangle, which is exact for concave outlines and holes and may return several polygons.
/// Slivers under [`MIN_AREA`] are dropped.
pub fn clip_slab(poly: &Polygon, origin: DVec2, axis: DVec2, lo: f64, hi: f64) -> Vec<Polygon> {
    let proj = |p: &DVec2| (*p - origin).dot(axis);
    let (mut pmin, mut pmax) = (f64::INFINITY, f64::NEG_INFINITY);
    for p in &poly.outer {
        let t = proj(p);
        pmin = pmin.min(t);
        pmax = pmax.max(t);
    }
    if pmin >= lo - EPS && pmax <= hi + EPS {
        return vec![poly.clone()];
    }
    if pmax <= lo + EPS || pmin >= hi - EPS {
        return Vec::new();
    }
    let out = if poly.holes.is_empty() && is_convex(&poly.outer) {
        let a = half_plane(&poly.outer, |p| proj(p) - lo);
        let b = half_plane(&a, |p| hi - proj(p));
        vec![Polygon::new(b, Vec::new())]
    } else {
        let perp = axis.perp();
        let (mut qmin, mut qmax) = (f64::INFINITY, f64::NEG_INFINITY);
        for p in &poly.outer {
            let t = (*p - origin).dot(perp);
            qmin = qmin.min(t);
            qmax = qmax.max(t);
        }
        let (qmin, qmax) = (qmin - 1.0, qmax + 1.0);
        let lo = lo.max(pmin - 1.0);
        let hi = hi.min(pmax + 1.0);
        let corner = |s: f64, t: f64| {
            let p = origin + axis * s + perp * t;
            geo::Coord { x: p.x, y: p.y }
        };
        let rect = geo::Polygon::new(
            geo::LineString::from(vec![
                corner(lo, qmin),
                corner(hi, qmin),
                corner(hi, qmax),
                corner(lo, qmax),
            ]),
            Vec::new(),
        );
        let g = to_geo(poly);
        g.intersection(&rect)
            .0
            .into_iter()
            .map(|gp| from_geo(&gp))
            .collect()
    };
    out.into_iter()
        .filter(|p| p.outer.len() >= 3 && p.area() > MIN_AREA)
        .collect()
}

/// One Sutherland–Hodgman pass: keeps the part of a ring where `f >= 0`.
fn half_plane(ring: &[DVec2], f: impl Fn(&DVec2) -> f64) -> Vec<DVec2> {
    let n = ring.len();
    let mut out = Vec::with_capacity(n + 2);
    for i in 0..n {
        let (a, b) = (ring[i], ring[(i + 1) % n]);
        let (fa, fb) = (f(&a), f(&b));
        if fa >= 0.0 {
            out.push(a);
        }
        if (fa >= 0.0) != (fb >= 0.0) {
            let t = fa / (fa - fb);
            out.push(a + (b - a) * t);
        }
    }
    out.dedup_by(|a, b| a.distance_squared(*b) < EPS * EPS);
    if out.len() > 1 && out[0].distance_squared(out[out.len() - 1]) < EPS * EPS {
        out.pop();
    }
    out
}

fn to_geo(poly: &Polygon) -> geo::Polygon<f64> {
    let ring = |r: &Vec<DVec2>| {
        geo::LineString::from(
            r.iter()
                .map(|p| geo::Coord { x: p.x, y: p.y })
                .collect::<Vec<_>>(),
        )
    };
    geo::Polygon::new(ring(&poly.outer), poly.holes.iter().map(ring).collect())
}

fn from_geo(p: &geo::Polygon<f64>) -> Polygon {
    let ring =
        |l: &geo::LineString<f64>| l.0.iter().map(|c| DVec2::new(c.x, c.y)).collect::<Vec<_>>();
    Polygon::new(ring(p.exterior()), p.interiors().iter().map(ring).collect())
}

/// Applies `f` to every vertex of a polygon, then restores the orientation convention.
pub fn map_polygon(poly: &Polygon, f: impl Fn(DVec2) -> DVec2) -> Polygon {
    Polygon::new(
        poly.outer.iter().map(|p| f(*p)).collect(),
        poly.holes
            .iter()
            .map(|h| h.iter().map(|p| f(*p)).collect())
            .collect(),
    )
}
