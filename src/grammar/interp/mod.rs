//! The derivation: applies rules to shapes, breadth first, until only terminals are left.
//!
//! Decisions of this core (written up, with an example each that is also a test, in
//! docs/grammar.md; `doc_tests.rs` keeps the two in step):
//!
//! * **Order and determinism.** Shapes are expanded breadth first in creation order; all random
//!   draws (rule choice, `rand`) come from the one `Rng`, so the same seed gives the same tree.
//! * **Rule choice.** Among a predecessor's rules, by weight (see [`super::parse`]).
//! * **`split` (absolute sizes).** Pieces are laid from the scope's minimum along the axis.
//!   A size ≤ 0 gives no piece. A piece that does not fit whole is the *overflow*: on a face it
//!   is truncated at the face's edge and the pieces after it are dropped; on a volume (any axis)
//!   or a lot it is dropped, and the space left after the last whole piece is added to that
//!   piece (the top storey gets taller), so a volume split never loses or invents matter. When
//!   the sizes do not reach the end, a face gets a `wall` shape for the rest (facades stay
//!   closed) and a volume or lot extends its last piece.
//!   This is how Figure 3.19 gets "two and four storeys": b3 is 20 m × rand(0.6, 0.8), i.e.
//!   12–16 m, so `split(Z,4,4,4,4,4)` keeps 3 whole levels (ground floor + 2 floors, the
//!   top one taller); b2 is 20 m, so `repeat(Z,4)` gives 5 levels. The thesis counts *étages*
//!   in the French way, above the ground floor (rez-de-chaussée): 2 and 4.
//! * **`rsplit`.** Fractions ≥ 0, normalised to sum 1; a zero fraction gives no piece.
//! * **`repeat`.** The pattern of sizes fits `n = floor(L / Σ sizes)` times and every piece is
//!   scaled by `L / (n Σ sizes)` so that the copies fill the parent exactly. When it does not fit
//!   once (`n = 0`), a face becomes one `wall` (no squeezed windows) and a volume gets one copy
//!   of the pattern scaled down to fit.
//! * **Pieces of a concave footprint.** Cutting a volume or lot along X or Y clips its footprint
//!   to a slab; a slab may hold several disjoint polygons: each becomes a shape with the same
//!   successor. A split piece keeps the parent's axes; its scope is its bounding box in them.
//! * **`comp()`.** One vertical face per footprint edge (outer ring and holes), then `top`
//!   and `bottom`. A face goes to the *first* successor whose selector matches it; `side`
//!   matches every vertical face and `others` every vertical face not taken by an earlier
//!   selector. front/back/left/right: the face's outward normal is expressed in the parent
//!   scope's frame; when |n·Y| ≥ |n·X| it is `front` (n·Y < 0) or `back`, otherwise `right`
//!   (n·X > 0) or `left` — so on a 45° tie front/back win. This matches the thesis's "dot
//!   product of the parent's X axis with the face's X axis" for front/back (x_face·X = −n·Y);
//!   left/right also use the normal (not the side of the centroid) so that courtyard walls
//!   and inner edges of concave footprints are classified by the direction they face. A vertical face no selector takes
//!   still becomes a `wall` (facades stay closed); a top or bottom face no selector takes is not
//!   created (roofs and slabs are built from the building's footprint and roof attribute).
//! * **extrude** of a lot gives a `Building`; of a volume, it re-extrudes the footprint to the
//!   new height (same label); of a side face, it pushes the face outward along its normal (a
//!   balcony-like `FacadePart`); of a top/bottom face, it extrudes its outline up/down.
//! * **S(x, y, z)** sets the scope size: a volume's footprint is scaled about the scope origin
//!   by x/sx, y/sy and its height set to z; a face's width and height become x and z.
//!   **T(x, y, z)** moves along the scope axes (for a face: x along the width, y along the
//!   outward normal, z along the height). **R(Z, deg)** rotates a volume or lot (footprint and
//!   scope) counter-clockwise (seen from above) about the vertical through the scope origin; a
//!   side face turns about its left vertical edge like a hinge (it stays a vertical rectangle,
//!   its normal turns by `deg`); a top or bottom face cannot (its scope Z is horizontal):
//!   derive-time [`DeriveError::Unsupported`]. `R(X, ..)` and `R(Y, ..)` are rejected at parse
//!   time ([`super::ParseErrorKind::BadAxis`]): every shape keeps a vertical Z axis, which the
//!   storey/facade model and the exporters rely on.
//! * **Labels** (§3.3.1.3): extrude → `Building`; X/Y cut of a Building/BuildingPart →
//!   `BuildingPart`, Z cut → `Storey`; a cut of a Storey or Room → `Room`; comp → `Facade`
//!   (the face kind says side/top/bottom); cuts of a Facade/FacadePart → `FacadePart`; relabel,
//!   S, T, R keep the label.
//! * **Attributes** are inherited: a child shares its parent's map unless its successor sets
//!   attributes, in which case it gets a copy with those overridden.

use std::rc::Rc;

use glam::{DVec2, DVec3};

use super::ast::{AttrValue, Attrs, Axis, Expr, Op, RuleSet, SymbolId};
use super::expr::{eval, EvalError};
use super::shape::{
    FaceKind, Geometry, Label, Scope, ShapeNode, ShapeTree, Terminal, EPS, MIN_AREA,
};
use crate::geometry::hull::scope_direction;
use crate::geometry::Polygon;
use crate::rng::Rng;

mod comp;
mod split;
mod transform;

use comp::comp;
use split::split;
use transform::{extrude, rotate, scale, translate};

/// Lengths within this tolerance count as "fits" in split layouts (metres).
const FIT_TOL: f64 = 1e-6;

/// Most successor attribute maps a derivation remembers for reuse (see `derive_facing`): rule
/// sets whose attributes differ from node to node make new maps past it, as they would anyway.
const ATTR_MEMO: usize = 64;

/// Limits that keep a runaway rule set from hanging or exhausting memory.
///
/// Every cap is checked *before* the memory it guards is spent: an operation counts the pieces
/// it is about to make (a `repeat`'s copies arithmetically, from the scope length and the
/// pattern; a split's pieces as they are laid out; a clip's pieces slab by slab; `comp`'s faces
/// from the footprint's edges; a relabel's successors) and the points their polygons will hold,
/// and refuses with [`DeriveError::Cap`] when they would not fit. So a `repeat(X, 1e-300)` on a
/// 50 km lot, or a concave footprint cut into thousands of slabs of a thousand pieces each,
/// costs a message, not the address space.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Caps {
    /// Deepest allowed shape (the axiom has depth 0).
    pub max_depth: usize,
    /// Most shapes in one tree.
    pub max_shapes: usize,
    /// Most pieces one operation may make (guards `repeat(X, 0.0001)`).
    pub max_pieces: usize,
    /// Most polygon vertices the shapes of one tree may hold together (lots, volume footprints,
    /// top and bottom faces; a side face holds none). Each volume piece keeps its own copy of
    /// its footprint, so a 5,000-vertex footprint cut into 10,000 storeys would hold 50 million
    /// points (800 MB) with only 10,000 shapes: `max_shapes` alone does not bound the memory.
    pub max_points: usize,
    /// Whether `comp` rules are applied. LOD1 and LOD2 need only the masses, so they derive
    /// without facades: a shape whose chosen rule is a `comp` stays a leaf.
    pub facades: bool,
}

impl Default for Caps {
    /// 64 levels, 100 000 shapes, 10 000 pieces per operation, 1 000 000 points (16 MB of
    /// coordinates: a 2,000-vertex footprint, the most an OSM way has, in 500 volumes).
    fn default() -> Caps {
        Caps {
            max_depth: 64,
            max_shapes: 100_000,
            max_pieces: 10_000,
            max_points: 1_000_000,
            facades: true,
        }
    }
}

/// Why a derivation failed. `rule` is `file:line (pred -> op)` of the rule being applied.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum DeriveError {
    /// A cap of [`Caps`] was hit (or would be by the operation being applied: it is refused
    /// before it makes its pieces).
    #[error("{rule}: derivation exceeds {cap} = {limit}{detail} (recursive or too fine rules?)")]
    Cap {
        /// Which cap: `max_depth`, `max_shapes`, `max_pieces` or `max_points`.
        cap: &'static str,
        /// Its value.
        limit: usize,
        /// The rule being applied.
        rule: String,
        /// What the operation would have made, starting with a separator (`: repeat would
        /// make 2000000000 pieces`), or empty.
        detail: String,
    },
    /// An expression used a missing or non-numeric attribute, or gave a non-finite value.
    #[error("{rule}: {message}")]
    Eval {
        /// The rule being applied.
        rule: String,
        /// What went wrong.
        message: String,
    },
    /// An operation was applied to a geometry it does not handle (e.g. `comp` on a face).
    #[error("{rule}: {op} cannot be applied to a {geometry}{detail}")]
    Unsupported {
        /// The rule being applied.
        rule: String,
        /// The operation name.
        op: &'static str,
        /// `lot`, `volume`, `face`.
        geometry: &'static str,
        /// More context, starting with a separator, or empty.
        detail: String,
    },
    /// Sizes that make no shape: negative sizes, all-zero fractions, a non-positive height.
    #[error("{rule}: {message}")]
    BadSize {
        /// The rule being applied.
        rule: String,
        /// What went wrong.
        message: String,
    },
    /// The lot polygon is empty or degenerate.
    #[error("the lot has no area (fewer than 3 vertices or zero area)")]
    EmptyLot,
}

/// A piece made by an operation: the successor it belongs to (`None`: a `wall` made to keep a
/// facade closed), its geometry and scope.
struct Piece {
    succ: Option<usize>,
    geom: Geometry,
    scope: Scope,
}

struct Ctx<'a> {
    rules: &'a RuleSet,
    rule: usize,
    caps: &'a Caps,
    /// Shapes the tree may still take (`max_shapes` minus the shapes made so far).
    shapes_left: usize,
    /// Points the tree may still take (`max_points` minus the points held so far).
    points_left: usize,
}

impl Ctx<'_> {
    fn rule_name(&self) -> String {
        self.rules.describe(self.rule)
    }
    fn eval(
        &self,
        e: &Expr,
        size: DVec3,
        attrs: &Attrs,
        rng: &mut Rng,
    ) -> Result<f64, DeriveError> {
        eval(e, size, attrs, rng).map_err(|err| DeriveError::Eval {
            rule: self.rule_name(),
            message: match err {
                EvalError::MissingAttribute(n) => {
                    format!("`{n}` is neither sx/sy/sz nor an attribute of the shape")
                }
                EvalError::NotANumber(n, v) => format!("attribute `{n}` = `{v}` is not a number"),
                EvalError::NonFinite => {
                    "expression gives a non-finite value (division by zero?)".into()
                }
            },
        })
    }
    fn bad(&self, message: String) -> DeriveError {
        DeriveError::BadSize {
            rule: self.rule_name(),
            message,
        }
    }
    fn unsupported(&self, op: &'static str, geometry: &'static str, detail: &str) -> DeriveError {
        DeriveError::Unsupported {
            rule: self.rule_name(),
            op,
            geometry,
            detail: detail.to_string(),
        }
    }
    fn cap(&self, cap: &'static str, limit: usize) -> DeriveError {
        self.cap_with(cap, limit, String::new())
    }
    fn cap_with(&self, cap: &'static str, limit: usize, detail: String) -> DeriveError {
        DeriveError::Cap {
            cap,
            limit,
            rule: self.rule_name(),
            detail,
        }
    }
    /// Whether the operation may make `pieces` pieces holding `points` points in all (counts
    /// as `f64`, so that an astronomical count is compared, not overflowed): `max_pieces`, then
    /// the shapes and the points the tree has left. `what` names the pieces for the message
    /// (`repeat would make`).
    fn room(
        &self,
        pieces: f64,
        points: f64,
        what: std::fmt::Arguments<'_>,
    ) -> Result<(), DeriveError> {
        let caps = self.caps;
        if pieces > caps.max_pieces as f64 {
            return Err(self.cap_with(
                "max_pieces",
                caps.max_pieces,
                format!(": {what} {}", count_pieces(pieces)),
            ));
        }
        if pieces > self.shapes_left as f64 {
            return Err(self.cap_with(
                "max_shapes",
                caps.max_shapes,
                format!(
                    ": {what} {}, and the tree has {} shapes",
                    count_pieces(pieces),
                    caps.max_shapes.saturating_sub(self.shapes_left)
                ),
            ));
        }
        if points > self.points_left as f64 {
            return Err(self.cap_with(
                "max_points",
                caps.max_points,
                format!(
                    ": {what} {} holding {} points, and the tree holds {}",
                    count_pieces(pieces),
                    count(points),
                    caps.max_points.saturating_sub(self.points_left)
                ),
            ));
        }
        Ok(())
    }
}

/// A count for messages: an integer, or in scientific notation past 10^15.
fn count(n: f64) -> String {
    if n < 1e15 {
        format!("{}", n as u64)
    } else {
        format!("{n:.2e}")
    }
}

/// `1 piece`, `3 pieces`.
fn count_pieces(n: f64) -> String {
    if n == 1.0 {
        "1 piece".to_string()
    } else {
        format!("{} pieces", count(n))
    }
}

/// The polygon vertices a geometry holds (what [`Caps::max_points`] counts).
fn points_of(g: &Geometry) -> usize {
    let poly = match g {
        Geometry::Lot { polygon, .. } => Some(polygon),
        Geometry::Volume { footprint, .. } => Some(footprint),
        Geometry::Face { polygon, .. } => polygon.as_ref(),
    };
    poly.map_or(0, polygon_points)
}

fn polygon_points(p: &Polygon) -> usize {
    p.rings().map(Vec::len).sum()
}

fn geometry_name(g: &Geometry) -> &'static str {
    match g {
        Geometry::Lot { .. } => "lot",
        Geometry::Volume { .. } => "volume",
        Geometry::Face { .. } => "face",
    }
}

/// Derives one building: the axiom shape is `lot` (local metres) carrying `attrs` and the rule
/// set's axiom symbol, at z = the numeric `base` attribute (0 if absent).
///
/// Deterministic for a given `rng` state. Never panics; fails with [`DeriveError`] when a cap
/// is hit or a rule cannot be applied to the shape it meets.
pub fn derive(
    rules: &RuleSet,
    lot: &Polygon,
    attrs: Attrs,
    rng: &mut Rng,
    caps: &Caps,
) -> Result<ShapeTree, DeriveError> {
    derive_facing(rules, lot, None, attrs, rng, caps)
}

/// [`derive()`] for a lot whose front is known: `front` (a unit vector in the local frame,
/// pointing from the building to its street) turns the axiom's scope so that its −Y, the
/// `front` selector of `comp`, is the direction along the lot's minimum-area rectangle closest
/// to it (`geometry::hull::scope_direction`). `None` is exactly [`derive()`] (the thesis scope).
pub fn derive_facing(
    rules: &RuleSet,
    lot: &Polygon,
    front: Option<DVec2>,
    attrs: Attrs,
    rng: &mut Rng,
    caps: &Caps,
) -> Result<ShapeTree, DeriveError> {
    if lot.outer.len() < 3
        || lot.area().abs() <= MIN_AREA
        || lot.outer.iter().any(|p| !p.is_finite())
    {
        return Err(DeriveError::EmptyLot);
    }
    let z = attrs
        .get("base")
        .and_then(AttrValue::as_f64)
        .filter(|v| v.is_finite())
        .unwrap_or(0.0);
    let scope = Scope::around(lot, scope_direction(lot, front), z, 0.0);
    let wall: Option<SymbolId> = rules.index.get("wall").copied();
    // This derivation's own copies of the symbol names (counted without atomics, as the
    // attribute maps are: a tree stays on the thread that derives it; the rule set's names are
    // shared by every thread, whose counting would make the threads contend).
    let mut names: Vec<Option<Rc<str>>> = vec![None; rules.symbols.len()];
    let mut name_of = |id: SymbolId| -> Rc<str> {
        names[id as usize]
            .get_or_insert_with(|| Rc::from(&*rules.symbols[id as usize]))
            .clone()
    };
    let wall_name: Rc<str> = wall.map_or_else(|| Rc::from("wall"), &mut name_of);
    // The buffers of this thread's last trees (see [`recycle`]): a tree of thousands of nodes
    // grown from nothing copies itself at every doubling, onto freshly mapped pages.
    let (nodes, mut syms, mut scopes) = SPARE.with(|s| std::mem::take(&mut *s.borrow_mut()));
    let mut tree = ShapeTree { nodes };
    // Per node: the symbol id (None for a `wall` the rule set never names) and the scope.
    debug_assert!(tree.nodes.is_empty() && syms.is_empty() && scopes.is_empty());
    tree.nodes.push(ShapeNode {
        symbol: name_of(rules.axiom),
        label: Label::Lot,
        attrs: Rc::new(attrs),
        geometry: Geometry::Lot {
            polygon: lot.clone(),
            z,
        },
        terminal: None,
        parent: None,
        children: 0..0,
        depth: 0,
        rule: None,
    });
    syms.push(Some(rules.axiom));
    scopes.push(scope);

    let mut i = 0;
    // The attributes of a successor that sets some, by the parent's attributes (the address
    // of the map, held here so it stays that map's), rule and successor: the nodes that share
    // their attributes and a rule give their pieces one map.
    let mut attr_memo: Vec<(Rc<Attrs>, usize, usize, Rc<Attrs>)> = Vec::new();
    // Polygon vertices held by the tree (Caps::max_points).
    let mut points = polygon_points(lot);
    while i < tree.nodes.len() {
        let candidates: &[usize] = match syms[i] {
            Some(s) => &rules.by_pred[s as usize],
            None => &[],
        };
        if candidates.is_empty() {
            let n = &mut tree.nodes[i];
            n.terminal = Some(Terminal::of(&n.symbol));
            i += 1;
            continue;
        }
        let rule_idx = if candidates.len() == 1 {
            candidates[0]
        } else {
            let w: Vec<f64> = candidates.iter().map(|&r| rules.weights[r]).collect();
            candidates[rng.pick_weighted(&w).unwrap_or(0)]
        };
        let ctx = Ctx {
            rules,
            rule: rule_idx,
            caps,
            shapes_left: caps.max_shapes.saturating_sub(tree.nodes.len()),
            points_left: caps.max_points.saturating_sub(points),
        };
        if !caps.facades && matches!(rules.rules[rule_idx].op, Op::Comp) {
            i += 1;
            continue;
        }
        let depth = tree.nodes[i].depth;
        if depth + 1 > caps.max_depth {
            return Err(ctx.cap("max_depth", caps.max_depth));
        }
        let rule = &rules.rules[rule_idx];
        let parent_attrs = tree.nodes[i].attrs.clone();
        let parent_label = tree.nodes[i].label;
        let pieces = apply(
            &ctx,
            &rule.op,
            &tree.nodes[i].geometry,
            &scopes[i],
            parent_label,
            &parent_attrs,
            rng,
        )?;
        // `apply` counted before making them; these are the same caps, checked once more on
        // what was made.
        if tree.nodes.len() + pieces.len() > caps.max_shapes {
            return Err(ctx.cap("max_shapes", caps.max_shapes));
        }
        points += pieces.iter().map(|p| points_of(&p.geom)).sum::<usize>();
        if points > caps.max_points {
            return Err(ctx.cap("max_points", caps.max_points));
        }
        let label = child_label(&rule.op, parent_label, &tree.nodes[i].geometry);
        let first = tree.nodes.len();
        tree.nodes.reserve(pieces.len());
        for p in pieces {
            let (sym, name, attrs) = match p.succ {
                Some(k) => {
                    let s = &rule.succs[k];
                    let a = if s.attrs.is_empty() {
                        parent_attrs.clone()
                    } else {
                        let known = attr_memo.iter().find(|(from, r, j, _)| {
                            *r == rule_idx && *j == k && Rc::ptr_eq(from, &parent_attrs)
                        });
                        match known {
                            Some((.., a)) => a.clone(),
                            None => {
                                let mut m = (*parent_attrs).clone();
                                for (key, v) in &s.attrs {
                                    m.insert(key.clone(), v.clone());
                                }
                                let a = Rc::new(m);
                                if attr_memo.len() < ATTR_MEMO {
                                    attr_memo.push((parent_attrs.clone(), rule_idx, k, a.clone()));
                                }
                                a
                            }
                        }
                    };
                    (Some(s.symbol), name_of(s.symbol), a)
                }
                None => (wall, wall_name.clone(), parent_attrs.clone()),
            };
            tree.nodes.push(ShapeNode {
                symbol: name,
                label,
                attrs,
                geometry: p.geom,
                terminal: None,
                parent: Some(i),
                children: 0..0,
                depth: depth + 1,
                rule: None,
            });
            syms.push(sym);
            scopes.push(p.scope);
        }
        let end = tree.nodes.len();
        let n = &mut tree.nodes[i];
        n.children = first..end;
        n.rule = Some(rule_idx);
        i += 1;
    }
    syms.clear();
    scopes.clear();
    SPARE.with(|s| {
        let mut s = s.borrow_mut();
        s.1 = syms;
        s.2 = scopes;
    });
    Ok(tree)
}

/// Buffers kept for this thread's next derivation: the nodes of a recycled tree, the symbol
/// ids and the scopes.
type Spare = (Vec<ShapeNode>, Vec<Option<SymbolId>>, Vec<Scope>);

thread_local! {
    static SPARE: std::cell::RefCell<Spare> = Default::default();
}

/// Gives a tree that is no longer needed back to this thread's next [`derive_facing`], which
/// reuses its node buffer (emptied here). Only a cost saving: dropping the tree is as good.
pub fn recycle(tree: ShapeTree) {
    let mut nodes = tree.nodes;
    nodes.clear();
    SPARE.with(|s| {
        let mut s = s.borrow_mut();
        if nodes.capacity() > s.0.capacity() {
            s.0 = nodes;
        }
    });
}

fn child_label(op: &Op, parent: Label, geom: &Geometry) -> Label {
    match op {
        Op::Relabel | Op::Scale(_) | Op::Translate(_) | Op::Rotate(..) => parent,
        Op::Comp => Label::Facade,
        Op::Extrude(_) => match geom {
            Geometry::Lot { .. } => Label::Building,
            Geometry::Volume { .. } => parent,
            Geometry::Face { .. } => Label::FacadePart,
        },
        Op::Split { axis, .. } => match parent {
            Label::Building | Label::BuildingPart => match (axis, geom) {
                (_, Geometry::Face { .. }) => Label::FacadePart,
                (Axis::Z, _) => Label::Storey,
                _ => Label::BuildingPart,
            },
            Label::Storey | Label::Room => Label::Room,
            Label::Facade | Label::FacadePart => Label::FacadePart,
            Label::Lot => Label::Lot,
        },
    }
}

fn apply(
    ctx: &Ctx<'_>,
    op: &Op,
    geom: &Geometry,
    scope: &Scope,
    _label: Label,
    attrs: &Attrs,
    rng: &mut Rng,
) -> Result<Vec<Piece>, DeriveError> {
    let rule = &ctx.rules.rules[ctx.rule];
    let size = scope.size;
    match op {
        Op::Relabel => all_succs(ctx, rule.succs.len(), geom.clone(), *scope),
        Op::Extrude(h) => {
            let h = ctx.eval(h, size, attrs, rng)?;
            if h <= EPS {
                return Err(ctx.bad(format!("extrude height {h} is not positive")));
            }
            let (g, s) = extrude(geom, scope, h);
            all_succs(ctx, rule.succs.len(), g, s)
        }
        Op::Scale(e) => {
            let v = [
                ctx.eval(&e[0], size, attrs, rng)?,
                ctx.eval(&e[1], size, attrs, rng)?,
                ctx.eval(&e[2], size, attrs, rng)?,
            ];
            let (g, s) = scale(ctx, geom, scope, v)?;
            all_succs(ctx, rule.succs.len(), g, s)
        }
        Op::Translate(e) => {
            let v = [
                ctx.eval(&e[0], size, attrs, rng)?,
                ctx.eval(&e[1], size, attrs, rng)?,
                ctx.eval(&e[2], size, attrs, rng)?,
            ];
            let (g, s) = translate(geom, scope, v);
            all_succs(ctx, rule.succs.len(), g, s)
        }
        Op::Rotate(_, e) => {
            let deg = ctx.eval(e, size, attrs, rng)?;
            let (g, s) = match geom {
                Geometry::Face {
                    kind: FaceKind::Top | FaceKind::Bottom,
                    ..
                } => {
                    // The scope Z of a top/bottom face is horizontal: turning about it would
                    // tilt the face out of its plane, which a plan outline cannot hold.
                    return Err(ctx.unsupported(
                        "R",
                        "face",
                        " (a top or bottom face cannot turn about its scope Z, which is \
                         horizontal; rotate the volume before comp)",
                    ));
                }
                _ => rotate(geom, scope, deg),
            };
            all_succs(ctx, rule.succs.len(), g, s)
        }
        Op::Comp => comp(ctx, geom, scope),
        Op::Split { kind, axis, sizes } => {
            let mut v = Vec::with_capacity(sizes.len());
            for e in sizes {
                v.push(ctx.eval(e, size, attrs, rng)?);
            }
            split(ctx, *kind, *axis, &v, geom, scope)
        }
    }
}

/// One copy of `g` per successor, once the caps allow `n` copies.
fn all_succs(ctx: &Ctx<'_>, n: usize, g: Geometry, s: Scope) -> Result<Vec<Piece>, DeriveError> {
    ctx.room(
        n as f64,
        n as f64 * points_of(&g) as f64,
        format_args!("its successors would make"),
    )?;
    Ok((0..n)
        .map(|k| Piece {
            succ: Some(k),
            geom: g.clone(),
            scope: s,
        })
        .collect())
}

fn face_scope(origin: DVec3, x_axis: DVec3, z_axis: DVec3, width: f64, height: f64) -> Scope {
    Scope {
        origin,
        x: x_axis,
        y: z_axis.cross(x_axis),
        z: z_axis,
        size: DVec3::new(width, 0.0, height),
    }
}

fn h2(v: DVec3) -> DVec2 {
    DVec2::new(v.x, v.y)
}
