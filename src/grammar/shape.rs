//! Shapes, their geometry and scope, and the shape tree. The planar operations they use
//! (oriented frames of footprints, clipping a footprint to a slab) are in [`crate::geometry`].

use std::ops::Range;
use std::rc::Rc;

use glam::{DVec2, DVec3};

use super::ast::Attrs;
use crate::geometry::Polygon;

pub(crate) use crate::geometry::clip::{EPS, MIN_AREA};

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
    pub(crate) fn around(poly: &Polygon, x_dir: DVec2, z0: f64, height: f64) -> Scope {
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
    pub(crate) fn x2(&self) -> DVec2 {
        DVec2::new(self.x.x, self.x.y)
    }

    /// The horizontal Y direction as a 2D vector.
    pub(crate) fn y2(&self) -> DVec2 {
        DVec2::new(self.y.x, self.y.y)
    }

    /// The origin projected on the ground plane.
    pub(crate) fn origin2(&self) -> DVec2 {
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
    pub(crate) fn of(symbol: &str) -> Terminal {
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
    pub(crate) fn face_normal(&self) -> Option<DVec3> {
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
    pub symbol: Rc<str>,
    /// Its place in the spatial hierarchy.
    pub label: Label,
    /// Its attributes, inherited and overridden. Nodes without overrides share their parent's
    /// map.
    pub attrs: Rc<Attrs>,
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
    #[cfg(test)]
    pub(crate) fn ancestor_with(&self, mut i: usize, label: Label) -> Option<usize> {
        loop {
            let n = self.nodes.get(i)?;
            if n.label == label {
                return Some(i);
            }
            i = n.parent?;
        }
    }
}
