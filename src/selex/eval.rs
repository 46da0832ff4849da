//! The SELEX interpreter: runs a program's commands one at a time, in file order, over a shape
//! tree (seed 000 §2.1, §4.1).
//!
//! # The shape tree
//!
//! - The **root** (`label == "root"`) is the first working node (the *head*). `setHeadNode()`
//!   moves the head.
//! - A **volume** is a 3D construction shape. `createShape(label, w, d, h)` makes a box centred
//!   on the origin, with Z up. `addVolume` makes a bay pushed out of a wall. A volume's children
//!   are its **faces**.
//! - A **face** is a 2D construction shape: a wall, in a frame seen from outside. The frame's
//!   origin is the wall's bottom-left corner, `u` runs to the right and `v` up. A box has the
//!   faces `<label>_front` (facing −Y), `_back` (+Y), `_left` (−X) and `_right` (+X), as in
//!   Brito's code; `addShape(label, w, h)` on the root makes a free-standing face (Jiang's
//!   facade). A face's children are its grids, elements and cover.
//! - A **grid** is a virtual shape on its face (`createGrid`, re-divided by `updateGrid`); its
//!   children are its **cells** ([`super::grid`]).
//! - An **element** is a construction shape placed on a face by `addShape`, `addFacade`,
//!   `addRoundFacade`, `addFacadeWithFrame` or `addRoundFacadeWithFrame`: one per group of
//!   selected cells, with the group's rectangle on the face.
//! - A **cover** is the part of a face left around its elements (`coverShape`), as rectangles.
//!
//! Shapes are never deleted (the seed hides them; citygen has no use for hidden shapes either).
//!
//! # Selection
//!
//! A path starts from the head. Each step applies its topology selector to every shape the
//! previous step gave; a step without one takes their **children** (the seed's label paths
//! `[label=="building"] / [label=="building_front"]`). The filters then run in order.
//!
//! - The children of a grid are its cells. `cell()` gives the cells of a grid, or of a face's
//!   latest grid.
//! - Cell selectors (`rowIdx`, `colIdx`, `rowLabel`, `colLabel`, `pattern`) narrow a selection of
//!   cells and intersect, so `[rowIdx in R][colIdx in C]` is the Cartesian product R × C. On any
//!   other shape they are an error, as is a grouping selector.
//! - `neighbor()` gives the faces that share a vertical edge with a face, the elements that touch
//!   an element on the same face, and the cells around a selection of cells.
//! - `contained()` gives the elements that lie within a grid's selected cells, or on a face.
//!
//! A rule whose path selects nothing is skipped, as the seed says (L561), with a warning.
//!
//! # Constraints
//!
//! `constrain(...)` checks each term on the elements of the selected shape, in order. A term that
//! holds is kept; one that does not (it conflicts with the layout and the terms kept so far) is
//! dropped with a warning: the seed's conflict rule. Kept `noIntersection` and
//! `boundaryDistance` terms then also apply to every later element placed on that face: an
//! element that would break one is not placed, with a warning. `align` and `symmetric` are
//! checked again once the program has run.

use std::collections::HashMap;
use std::fmt;

use glam::DVec3;

use super::ast::{
    Action, ActionKind, Attr, BinOp, Cmp, Command, Constraint, ConstraintAxis, ConstraintKind,
    Expr, ExprKind, Filter, IndexSet, Program, Selection, Span, Topo,
};
use super::grid::{self, Axis, CellRect, CellSet, CmpOp, Grid, IndexItem, Rect};
use super::pattern;

/// The storey height `createStoreyGrid` assumes on a face that has no storeys of its own (a
/// box made by `createShape`), metres.
pub const DEFAULT_STOREY: f64 = 3.0;

/// Index of a shape in [`Derivation::shapes`]; the root is 0.
pub type ShapeId = usize;

/// Where a face looks, for `[side == "front"]`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Side {
    /// Towards the street (a box's −Y side).
    Front,
    /// Away from it.
    Back,
    /// To the left seen from the front.
    Left,
    /// To the right seen from the front.
    Right,
    /// Any other wall (a bay's sides, a many-edged footprint's other walls).
    Side,
}

impl Side {
    /// The name as selectors write it.
    pub fn name(self) -> &'static str {
        match self {
            Side::Front => "front",
            Side::Back => "back",
            Side::Left => "left",
            Side::Right => "right",
            Side::Side => "side",
        }
    }
}

/// A face's frame, seen from outside: `origin` is its bottom-left corner, `u` (unit) runs to the
/// right, `v` (unit) up, and `u × v` is the outward normal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// Bottom-left corner.
    pub origin: DVec3,
    /// Unit vector to the right.
    pub u: DVec3,
    /// Unit vector up.
    pub v: DVec3,
    /// Width along `u`, metres.
    pub width: f64,
    /// Height along `v`, metres.
    pub height: f64,
}

impl Frame {
    /// The point at (x, y) metres on the face.
    pub fn at(&self, x: f64, y: f64) -> DVec3 {
        self.origin + self.u * x + self.v * y
    }

    /// The outward normal.
    pub fn normal(&self) -> DVec3 {
        self.u.cross(self.v)
    }
}

/// How a rounded element's corners are rounded (`addRoundFacade`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rounding {
    /// Which corners: top-left, top-right, bottom-right, bottom-left.
    pub corners: [bool; 4],
    /// The distance of the arc's ends from the corner, metres.
    pub offset: f64,
    /// Segments of each arc.
    pub segments: u32,
    /// 0 concave, 0.5 round, 1 convex.
    pub profile: f64,
}

/// Which part of a framed element stands out (`edgeExtrusion`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EdgeExtrusion {
    /// The whole element, inset by the frame.
    All,
    /// Only the frame's ring.
    Frame,
    /// An inset border, nothing stands out.
    None,
}

/// A frame around an element (`addFacadeWithFrame`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ElementFrame {
    /// What stands out.
    pub edge: EdgeExtrusion,
    /// The frame's width in the face's plane, metres.
    pub thickness: f64,
    /// How far it stands out, metres.
    pub width: f64,
}

/// An element on a face.
#[derive(Clone, Debug, PartialEq)]
pub struct Element {
    /// Its rectangle on the face, metres.
    pub rect: Rect,
    /// The cells it covers, when it was placed on cells.
    pub cells: Option<CellRect>,
    /// Rounded corners, if any.
    pub rounding: Option<Rounding>,
    /// A frame, if any.
    pub frame: Option<ElementFrame>,
    /// The action that placed it.
    pub action: ActionKind,
}

/// How `roundShape` rounds a bay.
#[derive(Clone, Debug, PartialEq)]
pub struct VolumeRounding {
    /// Which face is rounded (`front`, `left`, `right`, `top`, `bottom`).
    pub face: String,
    /// `outside` or `inside`.
    pub direction: String,
    /// The rounding amount.
    pub degree: f64,
    /// Segments of the arc.
    pub segments: u32,
    /// `vertical` or `horizontal` (for the front).
    pub axis: Option<String>,
    /// The inner rounding, if given.
    pub inside_degree: Option<f64>,
}

/// What a shape is.
#[derive(Clone, Debug, PartialEq)]
pub enum ShapeKind {
    /// The root of the tree.
    Root,
    /// A 3D construction shape; `rounding` once `roundShape` has rounded it.
    Volume {
        /// Its lowest corner.
        min: DVec3,
        /// Its highest corner.
        max: DVec3,
        /// Set by `roundShape`.
        rounding: Option<VolumeRounding>,
    },
    /// A 2D construction shape.
    Face {
        /// Its frame.
        frame: Frame,
        /// Where it looks.
        side: Side,
    },
    /// A virtual grid on its parent face.
    Grid(Grid),
    /// An element on its parent face.
    Element(Element),
    /// The wall around the elements of its parent face.
    Cover {
        /// The pieces, metres on the face.
        pieces: Vec<Rect>,
    },
}

/// One shape of the tree.
#[derive(Clone, Debug, PartialEq)]
pub struct Shape {
    /// Its label.
    pub label: String,
    /// What it is.
    pub kind: ShapeKind,
    /// Its parent (`None` for the root).
    pub parent: Option<ShapeId>,
    /// Its children, in creation order.
    pub children: Vec<ShapeId>,
}

impl Shape {
    /// `type`: `"construction"`, `"virtual"` or `"root"`.
    pub fn type_name(&self) -> &'static str {
        match self.kind {
            ShapeKind::Root => "root",
            ShapeKind::Grid(_) => "virtual",
            _ => "construction",
        }
    }
}

/// A message of the run with its place in the program.
#[derive(Clone, Debug, PartialEq)]
pub struct Note {
    /// 1-based line.
    pub line: u32,
    /// 1-based column.
    pub col: u32,
    /// What happened.
    pub message: String,
}

impl fmt::Display for Note {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}: {}", self.line, self.col, self.message)
    }
}

/// An error that stops the run: `file:line:col: message`, the line and a caret.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub struct RunError {
    /// The file name given to [`run`].
    pub file: String,
    /// 1-based line.
    pub line: u32,
    /// 1-based column.
    pub col: u32,
    /// What went wrong.
    pub message: String,
    /// The offending line.
    pub line_text: String,
}

impl fmt::Display for RunError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{}:{}:{}: {}",
            self.file, self.line, self.col, self.message
        )?;
        writeln!(f, "{}", self.line_text)?;
        let pad: String = self
            .line_text
            .chars()
            .take(self.col.saturating_sub(1) as usize)
            .map(|c| if c == '\t' { '\t' } else { ' ' })
            .collect();
        write!(f, "{pad}^")
    }
}

/// The result of a run: the shape tree, the constraints kept and the warnings.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Derivation {
    /// Every shape; index 0 is the root.
    pub shapes: Vec<Shape>,
    /// Constraint terms kept, with the shape they were set on.
    pub constraints: Vec<(ShapeId, Constraint)>,
    /// Warnings, in the order they arose.
    pub warnings: Vec<Note>,
}

impl Derivation {
    /// The elements, in creation order, with their face.
    pub fn elements(&self) -> impl Iterator<Item = (&Shape, &Element)> + '_ {
        self.shapes.iter().filter_map(|s| match &s.kind {
            ShapeKind::Element(e) => Some((s, e)),
            _ => None,
        })
    }

    /// How many elements have this label.
    pub fn count(&self, label: &str) -> usize {
        self.elements().filter(|(s, _)| s.label == label).count()
    }

    /// The shapes with this label.
    pub fn find(&self, label: &str) -> Vec<ShapeId> {
        (0..self.shapes.len())
            .filter(|&i| self.shapes[i].label == label)
            .collect()
    }

    /// The tree as text, one shape a line, indented under its parent: faces with their size
    /// and normal, grids with their rows and columns, elements and cover pieces with their
    /// rectangles on the face (x, y, width, height in metres from the bottom-left seen from
    /// outside); then the constraints kept. `selex derive` prints it.
    pub fn to_text(&self) -> String {
        let mut out = String::new();
        let mut stack = vec![(0usize, 0usize)];
        while let Some((id, depth)) = stack.pop() {
            let s = &self.shapes[id];
            let pad = "  ".repeat(depth);
            let r = |r: &Rect| format!("at ({:.2}, {:.2}) size {:.2} x {:.2}", r.x, r.y, r.w, r.h);
            let what = match &s.kind {
                ShapeKind::Root => "root".to_string(),
                ShapeKind::Volume { min, max, rounding } => format!(
                    "volume {:.2} x {:.2} x {:.2} m from ({:.2}, {:.2}, {:.2}){}",
                    max.x - min.x,
                    max.y - min.y,
                    max.z - min.z,
                    min.x,
                    min.y,
                    min.z,
                    if rounding.is_some() { ", rounded" } else { "" }
                ),
                ShapeKind::Face { frame, side } => {
                    let n = frame.normal();
                    format!(
                        "face {:.2} x {:.2} m, {}, normal ({:.2}, {:.2}, {:.2})",
                        frame.width,
                        frame.height,
                        side.name(),
                        n.x,
                        n.y,
                        n.z
                    )
                }
                ShapeKind::Grid(g) => format!("grid {} rows x {} columns", g.rows(), g.cols()),
                ShapeKind::Element(e) => {
                    let mut t = format!("element {}", r(&e.rect));
                    if let Some(c) = e.cells {
                        t += &format!(
                            ", rows {}-{} columns {}-{}",
                            c.row_from, c.row_to, c.col_from, c.col_to
                        );
                    }
                    if e.rounding.is_some() {
                        t += ", rounded";
                    }
                    if e.frame.is_some() {
                        t += ", framed";
                    }
                    t
                }
                ShapeKind::Cover { pieces } => {
                    let area: f64 = pieces.iter().map(|p| p.w * p.h).sum();
                    format!("cover of {} pieces, {area:.2} m²", pieces.len())
                }
            };
            out += &format!("{pad}{} — {what}\n", s.label);
            for &c in s.children.iter().rev() {
                stack.push((c, depth + 1));
            }
        }
        for (s, c) in &self.constraints {
            out += &format!(
                "constraint kept on {} (line {}:{})\n",
                self.shapes[*s].label, c.span.line, c.span.col
            );
        }
        out
    }

    /// The frame of face `id`, if it is a face.
    pub fn frame(&self, id: ShapeId) -> Option<Frame> {
        match self.shapes.get(id)?.kind {
            ShapeKind::Face { frame, .. } => Some(frame),
            _ => None,
        }
    }
}

/// Runs `program` (parsed from `src`, the file `file`) on an empty tree.
pub fn run(program: &Program, src: &str, file: &str) -> Result<Derivation, RunError> {
    run_with(program, src, file, None)
}

/// Runs `program` on a tree that already holds a box `building` of `width × depth × height`
/// metres (as `createShape("building", width, depth, height)` makes it), for programs that
/// only lay out facades: their paths start `descendant() [label == "building_front"]`.
pub fn run_on_box(
    program: &Program,
    src: &str,
    file: &str,
    (width, depth, height): (f64, f64, f64),
) -> Result<Derivation, RunError> {
    run_with(program, src, file, Some((width, depth, height)))
}

/// One facade of a real building, for [`run_on_facades`]: a footprint edge (or a run of
/// nearly collinear edges) from `start` to `end` in the local frame (metres, seen from outside
/// `start` is on the left), standing on `base_z` with its storeys' heights bottom up.
#[derive(Clone, Debug, PartialEq)]
pub struct FacadeSpec {
    /// Left end seen from outside.
    pub start: glam::DVec2,
    /// Right end seen from outside.
    pub end: glam::DVec2,
    /// Height of the facade's foot.
    pub base_z: f64,
    /// The storeys' heights, ground floor first (a metric grid takes one row from each).
    pub storeys: Vec<f64>,
    /// Where it looks relative to the street.
    pub side: Side,
}

/// The facades of a footprint for [`run_on_facades`]: one per edge of every ring (outer first,
/// in ring order, as the derivation numbers walls), each standing on `base_z` with `storeys`.
/// `front` is the unit direction from the building to its street (`None`: −Y, the grammar's
/// thesis front); each facade's side is the one its outward normal is closest to, as the
/// grammar's `comp` names faces: `front` towards the street, `back` away, `left` and `right`
/// as seen from the street. Edges shorter than a millimetre are left out.
pub fn facade_specs(
    footprint: &crate::geometry::Polygon,
    base_z: f64,
    storeys: &[f64],
    front: Option<glam::DVec2>,
) -> Vec<FacadeSpec> {
    let f = front
        .filter(|f| f.is_finite() && f.length() > 0.5)
        .map(|f| f.normalize())
        .unwrap_or(glam::DVec2::NEG_Y);
    let right = glam::DVec2::new(-f.y, f.x);
    let mut out = Vec::new();
    for ring in footprint.rings() {
        for i in 0..ring.len() {
            let (a, b) = (ring[i], ring[(i + 1) % ring.len()]);
            let d = b - a;
            let len = d.length();
            if len.is_nan() || len <= 1e-3 {
                continue;
            }
            // Outer rings run counter-clockwise and holes clockwise: the outward normal is on
            // the right of the edge either way.
            let n = glam::DVec2::new(d.y, -d.x) / len;
            let (along, across) = (n.dot(f), n.dot(right));
            let side = if along.abs() >= across.abs() {
                if along > 0.0 {
                    Side::Front
                } else {
                    Side::Back
                }
            } else if across > 0.0 {
                Side::Right
            } else {
                Side::Left
            };
            out.push(FacadeSpec {
                start: a,
                end: b,
                base_z,
                storeys: storeys.to_vec(),
                side,
            });
        }
    }
    out
}

/// Runs `program` on a building's facades: the root holds a volume `building` whose faces are
/// labelled `facade`, one per [`FacadeSpec`], with their `side`. So a program written once,
/// `< descendant() [label == "facade"] [side == "front"] / ... >`, applies to any footprint.
pub fn run_on_facades(
    program: &Program,
    src: &str,
    file: &str,
    facades: &[FacadeSpec],
) -> Result<Derivation, RunError> {
    let mut r = Runner::new(src, file);
    r.facades = true;
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for f in facades {
        let top = f.base_z + f.storeys.iter().sum::<f64>();
        for p in [f.start, f.end] {
            lo = lo.min(DVec3::new(p.x, p.y, f.base_z));
            hi = hi.max(DVec3::new(p.x, p.y, top));
        }
    }
    let building = r.add(
        0,
        "building",
        ShapeKind::Volume {
            min: lo,
            max: hi,
            rounding: None,
        },
    );
    for f in facades {
        let along = f.end - f.start;
        let (len, height) = (along.length(), f.storeys.iter().sum::<f64>());
        if !(len > 1e-6 && len.is_finite() && height > 0.0 && height.is_finite()) {
            continue;
        }
        let u = along / len;
        let id = r.add(
            building,
            "facade",
            ShapeKind::Face {
                frame: Frame {
                    origin: DVec3::new(f.start.x, f.start.y, f.base_z),
                    u: DVec3::new(u.x, u.y, 0.0),
                    v: DVec3::Z,
                    width: len,
                    height,
                },
                side: f.side,
            },
        );
        r.storeys.insert(id, f.storeys.clone());
    }
    r.exec(program)
}

impl<'a> Runner<'a> {
    fn new(src: &'a str, file: &'a str) -> Runner<'a> {
        Runner {
            d: Derivation {
                shapes: vec![Shape {
                    label: "root".into(),
                    kind: ShapeKind::Root,
                    parent: None,
                    children: Vec::new(),
                }],
                ..Derivation::default()
            },
            head: 0,
            vars: HashMap::new(),
            src,
            file,
            last_volume: None,
            storeys: HashMap::new(),
            facades: false,
            pending: Default::default(),
        }
    }

    fn exec(mut self, program: &Program) -> Result<Derivation, RunError> {
        for c in &program.commands {
            match c {
                Command::Assign { name, value, .. } => {
                    let v = self.value(value)?;
                    self.vars.insert(name.clone(), v);
                }
                Command::Rule(rule) => {
                    let items = self.select(&rule.selection)?;
                    let pending = std::mem::take(self.pending.get_mut());
                    self.d.warnings.extend(pending);
                    if items.is_empty() {
                        self.warn(
                            rule.selection.span,
                            "the selection picks no shape: the rule is skipped".into(),
                        );
                        continue;
                    }
                    for a in &rule.actions {
                        self.act(a, &items)?;
                    }
                }
            }
        }
        self.final_checks();
        Ok(self.d)
    }
}

fn run_with(
    program: &Program,
    src: &str,
    file: &str,
    lot: Option<(f64, f64, f64)>,
) -> Result<Derivation, RunError> {
    let mut r = Runner::new(src, file);
    if let Some((w, d, h)) = lot {
        if !(w > 0.0 && d > 0.0 && h > 0.0 && w.is_finite() && d.is_finite() && h.is_finite()) {
            return Err(r.err(
                Span::default(),
                format!("the lot must be positive and finite, not {w} x {d} x {h}"),
            ));
        }
        r.make_box(0, "building", w, d, h);
    }
    r.exec(program)
}

/// Row or column labels, one list per row or column.
type Labels = Vec<Vec<String>>;

/// A group of selected cells: its rectangle on the face and its cells (`None`: a whole face).
type Group = (Rect, Option<CellRect>);

/// A value of an expression.
#[derive(Clone, Debug, PartialEq)]
enum Value {
    Num(f64),
    Str(String),
    List(Vec<Value>),
}

/// One entry of a selection: a shape, or cells of a grid with how they are to be grouped.
#[derive(Clone, Debug)]
enum Item {
    Shape(ShapeId),
    Cells {
        grid: ShapeId,
        set: CellSet,
        grouping: Option<grid::Grouping>,
    },
}

struct Runner<'a> {
    d: Derivation,
    head: ShapeId,
    vars: HashMap<String, Value>,
    src: &'a str,
    file: &'a str,
    /// The volume the last `addVolume` made, for `roundShape`.
    last_volume: Option<ShapeId>,
    /// The storey heights of real facades ([`run_on_facades`]), for metric grids.
    storeys: HashMap<ShapeId, Vec<f64>>,
    /// Whether the tree holds a real building's facades ([`run_on_facades`]): a selector that
    /// does not fit one grid's size skips that grid ([`Runner::skip_grid`]) instead of failing.
    facades: bool,
    /// Warnings of the selectors (which only read the tree), moved to the derivation's after
    /// each selection.
    pending: std::cell::RefCell<Vec<Note>>,
}

/// Whether two lengths are the same to a tenth of a millimetre.
fn same(a: f64, b: f64) -> bool {
    (a - b).abs() < 1e-4
}

impl Runner<'_> {
    fn err(&self, span: Span, message: String) -> RunError {
        RunError {
            file: self.file.to_string(),
            line: span.line,
            col: span.col,
            message,
            line_text: self
                .src
                .lines()
                .nth(span.line.saturating_sub(1) as usize)
                .unwrap_or("")
                .to_string(),
        }
    }

    fn warn(&mut self, span: Span, message: String) {
        self.d.warnings.push(Note {
            line: span.line,
            col: span.col,
            message,
        });
    }

    fn add(&mut self, parent: ShapeId, label: &str, kind: ShapeKind) -> ShapeId {
        let id = self.d.shapes.len();
        self.d.shapes.push(Shape {
            label: label.to_string(),
            kind,
            parent: Some(parent),
            children: Vec::new(),
        });
        self.d.shapes[parent].children.push(id);
        id
    }

    // ---- values ----

    fn value(&self, e: &Expr) -> Result<Value, RunError> {
        Ok(match &e.kind {
            ExprKind::Number(v) => Value::Num(*v),
            ExprKind::Str(s) | ExprKind::BareWord(s) => {
                // A bare word that names a variable is the variable (the parser cannot know
                // which names a later assignment binds).
                match (&e.kind, self.vars.get(s)) {
                    (ExprKind::BareWord(_), Some(v)) => v.clone(),
                    _ => Value::Str(s.clone()),
                }
            }
            ExprKind::Var(name) => {
                self.vars.get(name).cloned().ok_or_else(|| {
                    self.err(e.span, format!("`{name}` is not assigned before here"))
                })?
            }
            ExprKind::List(items) => Value::List(
                items
                    .iter()
                    .map(|i| self.value(i))
                    .collect::<Result<_, _>>()?,
            ),
            ExprKind::Neg(inner) => Value::Num(-self.number(inner)?),
            ExprKind::Binary(op, a, b) => {
                let (a, b) = (self.number(a)?, self.number(b)?);
                let v = match op {
                    BinOp::Add => a + b,
                    BinOp::Sub => a - b,
                    BinOp::Mul => a * b,
                    BinOp::Div => a / b,
                };
                if !v.is_finite() {
                    return Err(self.err(e.span, "the arithmetic gives no finite number".into()));
                }
                Value::Num(v)
            }
        })
    }

    fn number(&self, e: &Expr) -> Result<f64, RunError> {
        match self.value(e)? {
            Value::Num(v) if v.is_finite() => Ok(v),
            other => Err(self.err(
                e.span,
                format!("a number is needed here, not {}", describe(&other)),
            )),
        }
    }

    fn positive(&self, e: &Expr, what: &str) -> Result<f64, RunError> {
        let v = self.number(e)?;
        if v > 0.0 {
            Ok(v)
        } else {
            Err(self.err(e.span, format!("{what} must be positive, not {v}")))
        }
    }

    fn string(&self, e: &Expr) -> Result<String, RunError> {
        match self.value(e)? {
            Value::Str(s) => Ok(s),
            other => Err(self.err(
                e.span,
                format!("a string is needed here, not {}", describe(&other)),
            )),
        }
    }

    fn integer(&self, e: &Expr) -> Result<i64, RunError> {
        let v = self.number(e)?;
        if v.fract() == 0.0 && v.abs() < 1e15 {
            Ok(v as i64)
        } else {
            Err(self.err(e.span, format!("an index must be a whole number, not {v}")))
        }
    }

    /// A count (`rows`, `cols`) or a list of labels whose length is the count.
    fn count_or_labels(&self, e: &Expr) -> Result<(usize, Option<Labels>), RunError> {
        match self.value(e)? {
            Value::Num(v) if v >= 1.0 && v.fract() == 0.0 && v <= grid::MAX_CELLS as f64 => {
                Ok((v as usize, None))
            }
            Value::List(items) if !items.is_empty() => {
                let labels = items
                    .iter()
                    .map(|i| match i {
                        Value::Str(s) => Ok(vec![s.clone()]),
                        other => Err(self.err(
                            e.span,
                            format!("row and column labels are strings, not {}", describe(other)),
                        )),
                    })
                    .collect::<Result<Vec<_>, _>>()?;
                Ok((labels.len(), Some(labels)))
            }
            other => Err(self.err(
                e.span,
                format!(
                    "a whole number of at least 1, or a list of labels, not {}",
                    describe(&other)
                ),
            )),
        }
    }

    // ---- selection ----

    fn select(&mut self, sel: &Selection) -> Result<Vec<Item>, RunError> {
        let mut items = vec![Item::Shape(self.head)];
        for step in &sel.steps {
            let mut next: Vec<Item> = Vec::new();
            let topo = step.topo.unwrap_or(Topo::Child);
            let span = step.topo_span.unwrap_or(step.span);
            for it in &items {
                self.topo(topo, it, span, &mut next)?;
            }
            dedup(&mut next);
            for f in &step.filters {
                next = self.filter(f, next)?;
            }
            items = next;
        }
        Ok(items)
    }

    fn cells_of(&self, grid: ShapeId) -> Option<Item> {
        match &self.d.shapes[grid].kind {
            ShapeKind::Grid(g) => Some(Item::Cells {
                grid,
                set: g.all(),
                grouping: None,
            }),
            _ => None,
        }
    }

    /// The latest grid of a face.
    fn grid_of_face(&self, face: ShapeId) -> Option<ShapeId> {
        self.d.shapes[face]
            .children
            .iter()
            .rev()
            .copied()
            .find(|&c| matches!(self.d.shapes[c].kind, ShapeKind::Grid(_)))
    }

    fn topo(&self, topo: Topo, it: &Item, span: Span, out: &mut Vec<Item>) -> Result<(), RunError> {
        let shapes = &self.d.shapes;
        match (topo, it) {
            (Topo::Root, _) => out.push(Item::Shape(0)),
            (Topo::Child, Item::Shape(s)) => match shapes[*s].kind {
                ShapeKind::Grid(_) => out.extend(self.cells_of(*s)),
                _ => out.extend(shapes[*s].children.iter().map(|&c| Item::Shape(c))),
            },
            (Topo::Child, Item::Cells { .. }) => {}
            (Topo::Descendant, Item::Shape(s)) => {
                let mut stack: Vec<ShapeId> = shapes[*s].children.iter().rev().copied().collect();
                while let Some(c) = stack.pop() {
                    out.push(Item::Shape(c));
                    if let Some(cells) = self.cells_of(c) {
                        out.push(cells);
                    }
                    stack.extend(shapes[c].children.iter().rev());
                }
            }
            (Topo::Descendant, Item::Cells { .. }) => {}
            (Topo::Parent, Item::Shape(s)) => out.extend(shapes[*s].parent.map(Item::Shape)),
            (Topo::Parent, Item::Cells { grid, .. }) => out.push(Item::Shape(*grid)),
            (Topo::Cell, Item::Shape(s)) => {
                let grid = match shapes[*s].kind {
                    ShapeKind::Grid(_) => Some(*s),
                    ShapeKind::Face { .. } => self.grid_of_face(*s),
                    _ => None,
                };
                match grid {
                    Some(g) => out.extend(self.cells_of(g)),
                    None => {
                        return Err(self.err(
                            span,
                            format!(
                                "cell() needs a grid or a face with a grid; `{}` is {}",
                                shapes[*s].label,
                                self.what(*s)
                            ),
                        ))
                    }
                }
            }
            (Topo::Cell, cells @ Item::Cells { .. }) => out.push(cells.clone()),
            (Topo::Neighbor, Item::Shape(s)) => {
                out.extend(self.neighbours(*s).into_iter().map(Item::Shape))
            }
            (Topo::Neighbor, Item::Cells { grid, set, .. }) => {
                let mut ring = set.clone();
                for (r, c) in set.iter() {
                    for (dr, dc) in [(-1i64, 0i64), (1, 0), (0, -1), (0, 1)] {
                        let (nr, nc) = (r as i64 + dr, c as i64 + dc);
                        if nr >= 1
                            && nc >= 1
                            && (nr as usize) <= set.rows()
                            && (nc as usize) <= set.cols()
                        {
                            let _ = ring.insert(nr as usize, nc as usize);
                        }
                    }
                }
                let ring = ring
                    .difference(set)
                    .map_err(|e| self.err(span, e.to_string()))?;
                out.push(Item::Cells {
                    grid: *grid,
                    set: ring,
                    grouping: None,
                });
            }
            (Topo::Contained, Item::Shape(s)) => match shapes[*s].kind {
                ShapeKind::Face { .. } => out.extend(
                    shapes[*s]
                        .children
                        .iter()
                        .filter(|&&c| matches!(shapes[c].kind, ShapeKind::Element(_)))
                        .map(|&c| Item::Shape(c)),
                ),
                ShapeKind::Grid(ref g) => {
                    let all = g.all();
                    out.extend(self.elements_within(*s, &all).into_iter().map(Item::Shape));
                }
                _ => {}
            },
            (Topo::Contained, Item::Cells { grid, set, .. }) => out.extend(
                self.elements_within(*grid, set)
                    .into_iter()
                    .map(Item::Shape),
            ),
        }
        Ok(())
    }

    /// The elements on a grid's face that lie within the union of the given cells.
    fn elements_within(&self, grid: ShapeId, set: &CellSet) -> Vec<ShapeId> {
        let shapes = &self.d.shapes;
        let (Some(face), ShapeKind::Grid(g)) = (shapes[grid].parent, &shapes[grid].kind) else {
            return Vec::new();
        };
        let cells: Vec<Rect> = set
            .iter()
            .filter_map(|(r, c)| g.cell_rect(r, c).ok())
            .collect();
        shapes[face]
            .children
            .iter()
            .copied()
            .filter(|&c| match &shapes[c].kind {
                // Inside the union: every cell the element overlaps is selected, and it overlaps
                // at least one.
                ShapeKind::Element(e) => {
                    let overlapping: Vec<(usize, usize)> = (1..=g.rows())
                        .flat_map(|r| (1..=g.cols()).map(move |c| (r, c)))
                        .filter(|&(r, c)| g.cell_rect(r, c).is_ok_and(|cr| overlap(&cr, &e.rect)))
                        .collect();
                    !overlapping.is_empty()
                        && overlapping.iter().all(|&(r, c)| set.contains(r, c))
                        && !cells.is_empty()
                }
                _ => false,
            })
            .collect()
    }

    /// Faces sharing a vertical edge with a face; elements touching an element on its face.
    fn neighbours(&self, s: ShapeId) -> Vec<ShapeId> {
        let shapes = &self.d.shapes;
        let Some(parent) = shapes[s].parent else {
            return Vec::new();
        };
        let siblings = shapes[parent].children.iter().copied().filter(|&c| c != s);
        match &shapes[s].kind {
            ShapeKind::Face { frame, .. } => {
                let edges = |f: &Frame| [f.origin, f.at(f.width, 0.0)];
                let mine = edges(frame);
                siblings
                    .filter(|&c| match &shapes[c].kind {
                        ShapeKind::Face { frame: other, .. } => edges(other)
                            .iter()
                            .any(|p| mine.iter().any(|q| p.distance(*q) < 1e-4)),
                        _ => false,
                    })
                    .collect()
            }
            ShapeKind::Element(e) => siblings
                .filter(|&c| match &shapes[c].kind {
                    ShapeKind::Element(o) => touch(&e.rect, &o.rect),
                    _ => false,
                })
                .collect(),
            _ => Vec::new(),
        }
    }

    fn what(&self, s: ShapeId) -> &'static str {
        match self.d.shapes[s].kind {
            ShapeKind::Root => "the root",
            ShapeKind::Volume { .. } => "a volume",
            ShapeKind::Face { .. } => "a face",
            ShapeKind::Grid(_) => "a grid",
            ShapeKind::Element(_) => "an element",
            ShapeKind::Cover { .. } => "a cover",
        }
    }

    fn side_of(&self, mut s: ShapeId) -> Option<Side> {
        loop {
            if let ShapeKind::Face { side, .. } = self.d.shapes[s].kind {
                return Some(side);
            }
            s = self.d.shapes[s].parent?;
        }
    }

    fn filter(&self, f: &Filter, items: Vec<Item>) -> Result<Vec<Item>, RunError> {
        let mut out = Vec::with_capacity(items.len());
        for it in items {
            if let Some(kept) = self.filter_one(f, it)? {
                out.push(kept);
            }
        }
        Ok(out)
    }

    fn filter_one(&self, f: &Filter, it: Item) -> Result<Option<Item>, RunError> {
        let span = f.span();
        match (f, it) {
            (Filter::Group { grouping, .. }, Item::Cells { grid, set, .. }) => {
                Ok(Some(Item::Cells {
                    grid,
                    set,
                    grouping: Some(match grouping {
                        super::ast::Grouping::Regions => grid::Grouping::Regions,
                        super::ast::Grouping::Rows => grid::Grouping::Rows,
                        super::ast::Grouping::Cols => grid::Grouping::Cols,
                        super::ast::Grouping::Pairs => grid::Grouping::Pairs,
                        super::ast::Grouping::Each => grid::Grouping::Each,
                    }),
                }))
            }
            (Filter::Group { grouping, .. }, Item::Shape(s)) => Err(self.err(
                span,
                format!(
                    "{} groups the cells of a virtual grid; `{}` is {}",
                    grouping.name(),
                    self.d.shapes[s].label,
                    self.what(s)
                ),
            )),
            (
                Filter::Pattern {
                    regex,
                    pat,
                    regex_span,
                    ..
                },
                Item::Cells {
                    grid,
                    set,
                    grouping,
                },
            ) => {
                let g = self.grid(grid, span)?;
                let p =
                    pattern::parse(regex).map_err(|e| self.pattern_err(*regex_span, regex, &e))?;
                let (chosen, left_out) = match p.select_allowing_short(pat, g.rows(), g.cols()) {
                    Ok(r) => r,
                    Err(e)
                        if self.facades
                            && matches!(
                                e.kind,
                                pattern::PatternErrorKind::Overflow { .. }
                                    | pattern::PatternErrorKind::StarNotDividing { .. }
                            ) =>
                    {
                        return Ok(self.skip_grid(grid, *regex_span, &e.to_string()));
                    }
                    Err(e) => return Err(self.pattern_err(*regex_span, regex, &e)),
                };
                if left_out > 0 {
                    self.pending.borrow_mut().push(Note {
                        line: regex_span.line,
                        col: regex_span.col,
                        message: format!(
                            "pattern \"{regex}\" gives {} of the {} cells of a {} x {} grid: \
                             the other {left_out} are not selected (end it with (X)* to say so)",
                            g.rows() * g.cols() - left_out,
                            g.rows() * g.cols(),
                            g.rows(),
                            g.cols()
                        ),
                    });
                }
                let set = set
                    .intersect(&chosen)
                    .map_err(|e| self.err(span, e.to_string()))?;
                Ok(Some(Item::Cells {
                    grid,
                    set,
                    grouping,
                }))
            }
            (Filter::Pattern { .. }, Item::Shape(s)) => Err(self.err(
                span,
                format!(
                    "pattern(...) selects the cells of a virtual grid; `{}` is {}",
                    self.d.shapes[s].label,
                    self.what(s)
                ),
            )),
            (
                Filter::Compare {
                    attr, op, value, ..
                },
                Item::Cells {
                    grid,
                    set,
                    grouping,
                },
            ) => {
                let g = self.grid(grid, span)?;
                let sel = match attr {
                    Attr::RowIdx | Attr::ColIdx => {
                        let v = self.integer(value)?;
                        g.select_cmp(axis(*attr), cmp(*op), v)
                    }
                    Attr::RowLabel | Attr::ColLabel => {
                        let v = self.string(value)?;
                        g.select_label(axis(*attr), cmp(*op), &v)
                    }
                    Attr::Type => {
                        let v = self.string(value)?;
                        let keep = (v == "cell") == (*op == Cmp::Eq);
                        return Ok(keep.then_some(Item::Cells {
                            grid,
                            set,
                            grouping,
                        }));
                    }
                    Attr::Dim => {
                        let keep = self.dim_matches(value, *op, 2)?;
                        return Ok(keep.then_some(Item::Cells {
                            grid,
                            set,
                            grouping,
                        }));
                    }
                    Attr::Side => {
                        let v = self.string(value)?;
                        let side = self.side_of(grid).map(Side::name);
                        let keep = (side == Some(v.as_str())) == (*op == Cmp::Eq);
                        return Ok(keep.then_some(Item::Cells {
                            grid,
                            set,
                            grouping,
                        }));
                    }
                    // Cells have no label of their own.
                    Attr::Label => {
                        return Ok((*op == Cmp::Ne).then_some(Item::Cells {
                            grid,
                            set,
                            grouping,
                        }))
                    }
                };
                let sel = match sel {
                    Ok(sel) => sel,
                    Err(e) if self.facades && e.depends_on_size() => {
                        return Ok(self.skip_grid(grid, span, &e.to_string()))
                    }
                    Err(e) => return Err(self.err(span, e.to_string())),
                };
                self.narrowed(grid, &set, grouping, &sel, span)
            }
            (
                Filter::In {
                    attr, set: list, ..
                },
                Item::Cells {
                    grid,
                    set,
                    grouping,
                },
            ) => {
                let g = self.grid(grid, span)?;
                let sel = match attr {
                    Attr::RowIdx | Attr::ColIdx => {
                        let items = self.index_items(list)?;
                        g.select_in(axis(*attr), &items)
                    }
                    Attr::RowLabel | Attr::ColLabel => {
                        let labels = self.string_list(list, span)?;
                        let refs: Vec<&str> = labels.iter().map(String::as_str).collect();
                        Ok(g.select_label_in(axis(*attr), &refs))
                    }
                    Attr::Type | Attr::Side | Attr::Label | Attr::Dim => {
                        let labels = self.string_list(list, span)?;
                        let mine = match attr {
                            Attr::Type => Some("cell"),
                            Attr::Side => self.side_of(grid).map(Side::name),
                            Attr::Dim => Some("2D"),
                            _ => None,
                        };
                        let keep = mine.is_some_and(|m| labels.iter().any(|l| l == m));
                        return Ok(keep.then_some(Item::Cells {
                            grid,
                            set,
                            grouping,
                        }));
                    }
                };
                let sel = match sel {
                    Ok(sel) => sel,
                    Err(e) if self.facades && e.depends_on_size() => {
                        return Ok(self.skip_grid(grid, span, &e.to_string()))
                    }
                    Err(e) => return Err(self.err(span, e.to_string())),
                };
                self.narrowed(grid, &set, grouping, &sel, span)
            }
            (
                Filter::Compare {
                    attr, op, value, ..
                },
                Item::Shape(s),
            ) => {
                let shape = &self.d.shapes[s];
                let keep = match attr {
                    Attr::Label => self.string_cmp(&shape.label, *op, value, span)?,
                    Attr::Type => self.string_cmp(shape.type_name(), *op, value, span)?,
                    // `side == "side"` is every wall, as the grammar's `comp` selector `side`.
                    Attr::Side => match self.side_of(s) {
                        Some(side) => {
                            let v = self.string(value)?;
                            let mine = if v == "side" { "side" } else { side.name() };
                            self.string_cmp(mine, *op, value, span)?
                        }
                        None => *op == Cmp::Ne,
                    },
                    Attr::Dim => {
                        let dim = match shape.kind {
                            ShapeKind::Volume { .. } => 3,
                            ShapeKind::Root => 3,
                            _ => 2,
                        };
                        self.dim_matches(value, *op, dim)?
                    }
                    Attr::RowIdx | Attr::ColIdx | Attr::RowLabel | Attr::ColLabel => {
                        return Err(self.not_cells(*attr, s, span))
                    }
                };
                Ok(keep.then_some(Item::Shape(s)))
            }
            (Filter::In { attr, set, .. }, Item::Shape(s)) => {
                let shape = &self.d.shapes[s];
                let mine: Option<String> = match attr {
                    Attr::Label => Some(shape.label.clone()),
                    Attr::Type => Some(shape.type_name().to_string()),
                    Attr::Side => self.side_of(s).map(|x| x.name().to_string()),
                    Attr::Dim => Some(
                        if matches!(shape.kind, ShapeKind::Volume { .. } | ShapeKind::Root) {
                            "3D"
                        } else {
                            "2D"
                        }
                        .to_string(),
                    ),
                    Attr::RowIdx | Attr::ColIdx | Attr::RowLabel | Attr::ColLabel => {
                        return Err(self.not_cells(*attr, s, span))
                    }
                };
                let list = self.string_list(set, span)?;
                let keep = mine.is_some_and(|m| list.contains(&m));
                Ok(keep.then_some(Item::Shape(s)))
            }
        }
    }

    /// On a real building's facades ([`run_on_facades`]), a selector that cannot apply to one
    /// grid's size (an index past its bays, a pattern that does not tile it) leaves that grid
    /// out of the selection, with a warning: one program serves facades of every width.
    fn skip_grid(&self, grid: ShapeId, at: Span, why: &str) -> Option<Item> {
        let face = self.d.shapes[grid].parent.unwrap_or(grid);
        let g = self.grid(grid, at).ok()?;
        self.pending.borrow_mut().push(Note {
            line: at.line,
            col: at.col,
            message: format!(
                "on the {} m facade {} ({} x {} grid): {why}; the facade is left out of this rule",
                match self.d.frame(face) {
                    Some(f) => format!("{:.1}", f.width),
                    None => "?".into(),
                },
                face,
                g.rows(),
                g.cols()
            ),
        });
        None
    }

    /// The cells of `set` that are also in `sel`, with the same grid and grouping.
    fn narrowed(
        &self,
        grid: ShapeId,
        set: &CellSet,
        grouping: Option<grid::Grouping>,
        sel: &CellSet,
        span: Span,
    ) -> Result<Option<Item>, RunError> {
        let set = set
            .intersect(sel)
            .map_err(|e| self.err(span, e.to_string()))?;
        Ok(Some(Item::Cells {
            grid,
            set,
            grouping,
        }))
    }

    fn not_cells(&self, attr: Attr, s: ShapeId, span: Span) -> RunError {
        self.err(
            span,
            format!(
                "{} applies to the cells of a virtual grid; `{}` is {} (select its cells with cell() \
                 or a step into the grid)",
                attr.name(),
                self.d.shapes[s].label,
                self.what(s)
            ),
        )
    }

    fn dim_matches(&self, value: &Expr, op: Cmp, dim: u8) -> Result<bool, RunError> {
        let want = match self.value(value)? {
            Value::Num(v) => v,
            Value::Str(s) => match s.to_ascii_uppercase().as_str() {
                "2D" | "2" => 2.0,
                "3D" | "3" => 3.0,
                _ => {
                    return Err(self.err(value.span, format!("dim is \"2D\" or \"3D\", not {s:?}")))
                }
            },
            other => {
                return Err(self.err(
                    value.span,
                    format!("dim is \"2D\" or \"3D\", not {}", describe(&other)),
                ))
            }
        };
        Ok(match op {
            Cmp::Eq => f64::from(dim) == want,
            Cmp::Ne => f64::from(dim) != want,
            _ => return Err(self.err(value.span, "dim compares only with == and !=".into())),
        })
    }

    fn string_cmp(&self, mine: &str, op: Cmp, value: &Expr, span: Span) -> Result<bool, RunError> {
        let v = self.string(value)?;
        match op {
            Cmp::Eq => Ok(mine == v),
            Cmp::Ne => Ok(mine != v),
            _ => Err(self.err(
                span,
                "labels compare only with == and != (not an ordering)".into(),
            )),
        }
    }

    fn string_list(&self, set: &IndexSet, span: Span) -> Result<Vec<String>, RunError> {
        match set {
            IndexSet::List(items) => items.iter().map(|e| self.string(e)).collect(),
            _ => Err(self.err(
                span,
                "a range selects indices (rowIdx, colIdx), not labels".into(),
            )),
        }
    }

    fn index_items(&self, set: &IndexSet) -> Result<Vec<IndexItem>, RunError> {
        Ok(match set {
            IndexSet::List(items) => items
                .iter()
                .map(|e| self.integer(e).map(IndexItem::One))
                .collect::<Result<_, _>>()?,
            IndexSet::IndexRange(a, b) | IndexSet::RowRange(a, b) => {
                vec![IndexItem::Range(self.integer(a)?, self.integer(b)?)]
            }
        })
    }

    /// The grid of a cell selection. Cells are only ever made from grids, so the error is an
    /// internal one, reported at `span` rather than a panic.
    fn grid(&self, id: ShapeId, span: Span) -> Result<&Grid, RunError> {
        match &self.d.shapes[id].kind {
            ShapeKind::Grid(g) => Ok(g),
            _ => Err(self.err(
                span,
                format!(
                    "internal: cells of `{}`, which is not a grid",
                    self.d.shapes[id].label
                ),
            )),
        }
    }

    fn pattern_err(&self, regex_span: Span, regex: &str, e: &pattern::PatternError) -> RunError {
        // Strings hold no escapes: character n of the pattern is at column col + n.
        let chars = regex[..e.offset.min(regex.len())].chars().count() as u32;
        let at = Span {
            col: regex_span.col + chars,
            ..regex_span
        };
        self.err(at, format!("pattern: {e}"))
    }

    // ---- actions ----

    fn act(&mut self, a: &Action, items: &[Item]) -> Result<(), RunError> {
        match a.name {
            ActionKind::SetHeadNode => {
                let [Item::Shape(s)] = items else {
                    return Err(self.err(
                        a.span,
                        format!(
                            "setHeadNode() needs exactly one shape; the selection gives {}",
                            items.len()
                        ),
                    ));
                };
                self.head = *s;
                Ok(())
            }
            _ => {
                for it in items {
                    self.act_on(a, it)?;
                }
                Ok(())
            }
        }
    }

    fn shape_item(&self, a: &Action, it: &Item) -> Result<ShapeId, RunError> {
        match it {
            Item::Shape(s) => Ok(*s),
            Item::Cells { grid, .. } => Err(self.err(
                a.span,
                format!(
                    "{} works on a shape, not on cells (of `{}`)",
                    a.name.name(),
                    self.d.shapes[*grid].label
                ),
            )),
        }
    }

    fn face_item(&self, a: &Action, it: &Item) -> Result<(ShapeId, Frame), RunError> {
        let s = self.shape_item(a, it)?;
        match self.d.shapes[s].kind {
            ShapeKind::Face { frame, .. } => Ok((s, frame)),
            _ => Err(self.err(
                a.span,
                format!(
                    "{} needs a 2D construction shape (a face); `{}` is {}",
                    a.name.name(),
                    self.d.shapes[s].label,
                    self.what(s)
                ),
            )),
        }
    }

    /// The groups of a selection of cells, or the whole face for a face.
    fn groups(&self, a: &Action, it: &Item) -> Result<(ShapeId, Vec<Group>), RunError> {
        match it {
            Item::Cells {
                grid,
                set,
                grouping,
            } => {
                let g = self.grid(*grid, a.span)?;
                let elements = g
                    .group(set, grouping.unwrap_or(grid::Grouping::Each))
                    .map_err(|e| self.err(a.span, e.to_string()))?;
                let face = self.d.shapes[*grid].parent.unwrap_or(0);
                Ok((
                    face,
                    elements
                        .into_iter()
                        .map(|e| (e.rect, Some(e.cells)))
                        .collect(),
                ))
            }
            Item::Shape(s) => match self.d.shapes[*s].kind {
                ShapeKind::Face { frame, .. } => Ok((
                    *s,
                    vec![(
                        Rect {
                            x: 0.0,
                            y: 0.0,
                            w: frame.width,
                            h: frame.height,
                        },
                        None,
                    )],
                )),
                _ => Err(self.err(
                    a.span,
                    format!(
                        "{} places elements on cells or on a face; `{}` is {}",
                        a.name.name(),
                        self.d.shapes[*s].label,
                        self.what(*s)
                    ),
                )),
            },
        }
    }

    fn act_on(&mut self, a: &Action, it: &Item) -> Result<(), RunError> {
        let args = &a.args;
        match a.name {
            ActionKind::SetHeadNode => Ok(()),
            ActionKind::CreateShape => {
                let s = self.shape_item(a, it)?;
                let label = self.string(&args[0])?;
                let w = self.positive(&args[1], "width")?;
                let d = self.positive(&args[2], "depth")?;
                let h = self.positive(&args[3], "height")?;
                if self.facades && s == 0 {
                    // On a real building the mass is its footprint's: the sizes are the box's
                    // the program was written for.
                    self.footprint_volume(&label);
                } else {
                    self.make_box(s, &label, w, d, h);
                }
                Ok(())
            }
            ActionKind::CreateGrid => {
                let (face, frame) = self.face_item(a, it)?;
                let label = self.string(&args[0])?;
                let g = self.make_grid(frame.width, frame.height, &args[1], &args[2], a.span)?;
                self.add(face, &label, ShapeKind::Grid(g));
                Ok(())
            }
            ActionKind::CreateStoreyGrid => {
                let (face, frame) = self.face_item(a, it)?;
                let label = self.string(&args[0])?;
                let bay = self.positive(&args[1], "bayWidth")?;
                // A real facade's storeys; on a box face, storeys of about 3 m.
                let storeys = match self.storeys.get(&face) {
                    Some(s) if !s.is_empty() => s.clone(),
                    _ => {
                        let n = (frame.height / DEFAULT_STOREY).round().max(1.0) as usize;
                        vec![frame.height / n as f64; n]
                    }
                };
                let g = Grid::metric(frame.width, &storeys, bay)
                    .map_err(|e| self.err(a.span, e.to_string()))?;
                self.add(face, &label, ShapeKind::Grid(g));
                Ok(())
            }
            ActionKind::UpdateGrid => {
                let s = match it {
                    Item::Shape(s) => *s,
                    Item::Cells { grid, .. } => *grid,
                };
                let ShapeKind::Grid(old) = &self.d.shapes[s].kind else {
                    return Err(self.err(
                        a.span,
                        format!(
                            "updateGrid re-divides a grid; `{}` is {}",
                            self.d.shapes[s].label,
                            self.what(s)
                        ),
                    ));
                };
                let (w, h) = (old.width(), old.height());
                let g = self.make_grid(w, h, &args[0], &args[1], a.span)?;
                self.d.shapes[s].kind = ShapeKind::Grid(g);
                Ok(())
            }
            ActionKind::AddShape if matches!(it, Item::Shape(s) if !matches!(self.d.shapes[*s].kind, ShapeKind::Face { .. })) =>
            {
                // On the root or a volume: a free-standing face (Jiang's facade).
                let s = self.shape_item(a, it)?;
                let label = self.string(&args[0])?;
                let (Some(w), Some(h)) = (args.get(1), args.get(2)) else {
                    return Err(self.err(
                        a.span,
                        "addShape on a shape that is not a face needs its width and height".into(),
                    ));
                };
                let (w, h) = (self.positive(w, "width")?, self.positive(h, "height")?);
                self.add(
                    s,
                    &label,
                    ShapeKind::Face {
                        frame: Frame {
                            origin: DVec3::new(-w / 2.0, 0.0, 0.0),
                            u: DVec3::X,
                            v: DVec3::Z,
                            width: w,
                            height: h,
                        },
                        side: Side::Front,
                    },
                );
                Ok(())
            }
            ActionKind::AddShape
            | ActionKind::AddFacade
            | ActionKind::AddRoundFacade
            | ActionKind::AddFacadeWithFrame
            | ActionKind::AddRoundFacadeWithFrame => {
                let label = self.string(&args[0])?;
                let (rounding, frame) = self.styles(a)?;
                let (face, groups) = self.groups(a, it)?;
                for (mut rect, cells) in groups {
                    if a.name == ActionKind::AddShape {
                        // Sizes given: centred in the group's rectangle.
                        if let Some(w) = args.get(1) {
                            let w = self.positive(w, "width")?.min(rect.w);
                            rect.x += (rect.w - w) / 2.0;
                            rect.w = w;
                        }
                        if let Some(h) = args.get(2) {
                            let h = self.positive(h, "height")?.min(rect.h);
                            rect.y += (rect.h - h) / 2.0;
                            rect.h = h;
                        }
                    }
                    if let Some(why) = self.breaks_kept(face, &label, &rect) {
                        self.warn(
                            a.span,
                            format!(
                                "{label} at ({:.2}, {:.2}) is not placed: {why}",
                                rect.x, rect.y
                            ),
                        );
                        continue;
                    }
                    self.add(
                        face,
                        &label,
                        ShapeKind::Element(Element {
                            rect,
                            cells,
                            rounding,
                            frame,
                            action: a.name,
                        }),
                    );
                }
                Ok(())
            }
            ActionKind::AddVolume => {
                let Item::Cells { grid, .. } = it else {
                    return Err(self.err(
                        a.span,
                        "addVolume pushes out selected cells of a grid".into(),
                    ));
                };
                let label = self.string(&args[0])?;
                let depth = self.positive(&args[2], "extrusionSize")?;
                let names = match self.value(&args[3])? {
                    Value::List(v) if v.len() == 3 => v,
                    other => {
                        return Err(self.err(
                            args[3].span,
                            format!("three side labels are needed, not {}", describe(&other)),
                        ))
                    }
                };
                let names: Vec<String> = names
                    .into_iter()
                    .map(|v| match v {
                        Value::Str(s) => Ok(s),
                        other => Err(self.err(
                            args[3].span,
                            format!("side labels are strings, not {}", describe(&other)),
                        )),
                    })
                    .collect::<Result<_, _>>()?;
                let grid = *grid;
                let (face, groups) = self.groups(a, it)?;
                let Some(frame) = self.d.frame(face) else {
                    return Err(self.err(a.span, "addVolume needs a grid on a face".into()));
                };
                let parent_grid = self.grid(grid, a.span)?.clone();
                for (rect, cells) in groups {
                    let n = frame.normal();
                    let base = frame.at(rect.x, rect.y);
                    let far = frame.at(rect.x + rect.w, rect.y + rect.h) + n * depth;
                    let vol = self.add(
                        face,
                        &label,
                        ShapeKind::Volume {
                            min: base.min(far),
                            max: base.max(far),
                            rounding: None,
                        },
                    );
                    let front = Frame {
                        origin: base + n * depth,
                        u: frame.u,
                        v: frame.v,
                        width: rect.w,
                        height: rect.h,
                    };
                    let left = Frame {
                        origin: base,
                        u: n,
                        v: frame.v,
                        width: depth,
                        height: rect.h,
                    };
                    let right = Frame {
                        origin: frame.at(rect.x + rect.w, rect.y) + n * depth,
                        u: -n,
                        v: frame.v,
                        width: depth,
                        height: rect.h,
                    };
                    let side = self.side_of(face).unwrap_or(Side::Side);
                    let f = self.add(vol, &names[0], ShapeKind::Face { frame: front, side });
                    self.add(
                        vol,
                        &names[1],
                        ShapeKind::Face {
                            frame: left,
                            side: Side::Side,
                        },
                    );
                    self.add(
                        vol,
                        &names[2],
                        ShapeKind::Face {
                            frame: right,
                            side: Side::Side,
                        },
                    );
                    if let Some(c) = cells {
                        let g = parent_grid
                            .crop(c)
                            .map_err(|e| self.err(a.span, e.to_string()))?;
                        self.add(f, &format!("{}_grid", names[0]), ShapeKind::Grid(g));
                    }
                    self.last_volume = Some(vol);
                }
                Ok(())
            }
            ActionKind::RoundShape => {
                let s = self.shape_item(a, it)?;
                // The volume of the selected face, or the last addVolume's.
                let vol = match self.d.shapes[s].kind {
                    ShapeKind::Volume { .. } => Some(s),
                    _ => self.d.shapes[s]
                        .parent
                        .filter(|&p| matches!(self.d.shapes[p].kind, ShapeKind::Volume { .. })),
                }
                .or(self.last_volume);
                let Some(vol) = vol else {
                    return Err(self.err(
                        a.span,
                        "roundShape rounds a volume (a bay made by addVolume)".into(),
                    ));
                };
                let r = VolumeRounding {
                    face: self.string(&args[0])?,
                    direction: self.string(&args[1])?,
                    degree: self.number(&args[2])?,
                    segments: self.integer(&args[3])?.clamp(1, 1024) as u32,
                    axis: args.get(5).map(|e| self.string(e)).transpose()?,
                    inside_degree: args.get(6).map(|e| self.number(e)).transpose()?,
                };
                if let ShapeKind::Volume { rounding, .. } = &mut self.d.shapes[vol].kind {
                    *rounding = Some(r);
                }
                Ok(())
            }
            ActionKind::CoverShape => {
                let (face, frame) = self.face_item(a, it)?;
                let holes: Vec<Rect> = self.d.shapes[face]
                    .children
                    .iter()
                    .filter_map(|&c| match &self.d.shapes[c].kind {
                        ShapeKind::Element(e) => Some(e.rect),
                        _ => None,
                    })
                    .collect();
                let pieces = cover(frame.width, frame.height, &holes);
                self.add(face, "wall", ShapeKind::Cover { pieces });
                Ok(())
            }
            ActionKind::Constrain => {
                let s = self.shape_item(a, it)?;
                for c in &a.constraints {
                    match self.violation(s, &c.kind)? {
                        None => self.d.constraints.push((s, c.clone())),
                        Some(why) => self.warn(c.span, format!("constraint dropped: {why}")),
                    }
                }
                Ok(())
            }
        }
    }

    /// A box centred on the origin with its four faces (`createShape`).
    /// `createShape(label, ...)` on a real building ([`run_on_facades`]): a volume `label`
    /// like the building's, with a copy of each of its `facade` faces labelled
    /// `<label>_<side>` (`building_front`, ... as on a box; `<label>_side` for the walls that
    /// face no side of the street), so a program written for the seed's box runs on the
    /// footprint unchanged.
    fn footprint_volume(&mut self, label: &str) {
        let Some(&building) = self.d.shapes[0].children.first() else {
            return;
        };
        let kind = self.d.shapes[building].kind.clone();
        let vol = self.add(0, label, kind);
        let faces: Vec<ShapeId> = self.d.shapes[building]
            .children
            .iter()
            .copied()
            .filter(|&c| self.d.shapes[c].label == "facade")
            .collect();
        for f in faces {
            let kind = self.d.shapes[f].kind.clone();
            let ShapeKind::Face { side, .. } = &kind else {
                continue;
            };
            let name = format!("{label}_{}", side.name());
            let id = self.add(vol, &name, kind);
            if let Some(st) = self.storeys.get(&f).cloned() {
                self.storeys.insert(id, st);
            }
        }
    }

    fn make_box(&mut self, parent: ShapeId, label: &str, w: f64, d: f64, h: f64) {
        let vol = self.add(
            parent,
            label,
            ShapeKind::Volume {
                min: DVec3::new(-w / 2.0, -d / 2.0, 0.0),
                max: DVec3::new(w / 2.0, d / 2.0, h),
                rounding: None,
            },
        );
        let (x, y) = (DVec3::X, DVec3::Y);
        let faces = [
            (
                "front",
                Side::Front,
                DVec3::new(-w / 2.0, -d / 2.0, 0.0),
                x,
                w,
            ),
            ("back", Side::Back, DVec3::new(w / 2.0, d / 2.0, 0.0), -x, w),
            (
                "left",
                Side::Left,
                DVec3::new(-w / 2.0, d / 2.0, 0.0),
                -y,
                d,
            ),
            (
                "right",
                Side::Right,
                DVec3::new(w / 2.0, -d / 2.0, 0.0),
                y,
                d,
            ),
        ];
        for (name, side, origin, u, width) in faces {
            self.add(
                vol,
                &format!("{label}_{name}"),
                ShapeKind::Face {
                    frame: Frame {
                        origin,
                        u,
                        v: DVec3::Z,
                        width,
                        height: h,
                    },
                    side,
                },
            );
        }
    }

    fn make_grid(
        &self,
        w: f64,
        h: f64,
        rows: &Expr,
        cols: &Expr,
        span: Span,
    ) -> Result<Grid, RunError> {
        let (r, row_labels) = self.count_or_labels(rows)?;
        let (c, col_labels) = self.count_or_labels(cols)?;
        let mut g = Grid::uniform(w, h, r, c).map_err(|e| self.err(span, e.to_string()))?;
        if let Some(l) = row_labels {
            g = g
                .with_row_labels(l)
                .map_err(|e| self.err(span, e.to_string()))?;
        }
        if let Some(l) = col_labels {
            g = g
                .with_col_labels(l)
                .map_err(|e| self.err(span, e.to_string()))?;
        }
        Ok(g)
    }

    fn styles(&self, a: &Action) -> Result<(Option<Rounding>, Option<ElementFrame>), RunError> {
        let args = &a.args;
        let rounding = |from: usize| -> Result<Rounding, RunError> {
            let corners = match self.value(&args[from])? {
                Value::List(v) => v,
                other => {
                    return Err(self.err(
                        args[from].span,
                        format!("corners are a list, not {}", describe(&other)),
                    ))
                }
            };
            let mut set = [false; 4];
            for c in corners {
                let Value::Str(name) = c else {
                    return Err(self.err(args[from].span, "corner names are strings".into()));
                };
                let Some(i) = super::ast::CORNERS.iter().position(|k| *k == name) else {
                    return Err(self.err(args[from].span, format!("no corner {name:?}")));
                };
                set[i] = true;
            }
            Ok(Rounding {
                corners: set,
                offset: self.positive(&args[from + 1], "offset")?,
                segments: self.integer(&args[from + 2])?.clamp(1, 1024) as u32,
                profile: self.number(&args[from + 3])?.clamp(0.0, 1.0),
            })
        };
        let frame = |from: usize| -> Result<ElementFrame, RunError> {
            let edge = match self.string(&args[from])?.as_str() {
                "all" => EdgeExtrusion::All,
                "frame" => EdgeExtrusion::Frame,
                _ => EdgeExtrusion::None,
            };
            Ok(ElementFrame {
                edge,
                thickness: self.positive(&args[from + 1], "thickness")?,
                width: self.number(&args[from + 2])?.max(0.0),
            })
        };
        Ok(match a.name {
            ActionKind::AddRoundFacade => (Some(rounding(1)?), None),
            ActionKind::AddFacadeWithFrame => (None, Some(frame(1)?)),
            ActionKind::AddRoundFacadeWithFrame => (Some(rounding(1)?), Some(frame(5)?)),
            _ => (None, None),
        })
    }

    /// Elements labelled `label` on the shape `s` or below it.
    fn labelled(&self, s: ShapeId, label: Option<&str>) -> Vec<(ShapeId, Rect)> {
        let mut out = Vec::new();
        let mut stack = vec![s];
        while let Some(c) = stack.pop() {
            if let ShapeKind::Element(e) = &self.d.shapes[c].kind {
                if label.is_none_or(|l| self.d.shapes[c].label == l) {
                    out.push((c, e.rect));
                }
            }
            stack.extend(self.d.shapes[c].children.iter().rev());
        }
        out.sort_by_key(|e| e.0);
        out
    }

    fn constraint_label(&self, e: &Expr) -> Result<String, RunError> {
        self.string(e)
    }

    /// Why a constraint term does not hold on the shape `s` now, or `None`.
    fn violation(&self, s: ShapeId, c: &ConstraintKind) -> Result<Option<String>, RunError> {
        let face_size = self.d.frame(s).map(|f| (f.width, f.height));
        Ok(match c {
            ConstraintKind::Align { a, b, axis } => {
                let (la, lb) = (self.constraint_label(a)?, self.constraint_label(b)?);
                let (ea, eb) = (self.labelled(s, Some(&la)), self.labelled(s, Some(&lb)));
                let key = |r: &Rect| match axis {
                    ConstraintAxis::Vertical => r.x + r.w / 2.0,
                    ConstraintAxis::Horizontal => r.y + r.h / 2.0,
                };
                ea.iter()
                    .find(|(_, ra)| !eb.iter().any(|(_, rb)| same(key(ra), key(rb))))
                    .map(|(_, r)| {
                        format!(
                            "no {lb} lies on the line of the {la} at ({:.2}, {:.2})",
                            r.x, r.y
                        )
                    })
            }
            ConstraintKind::Symmetric { label, axis } => {
                let l = self.constraint_label(label)?;
                let Some((w, h)) = face_size else {
                    return Ok(Some("symmetry needs a face to mirror about".into()));
                };
                let rects: Vec<Rect> = self
                    .labelled(s, Some(&l))
                    .into_iter()
                    .map(|e| e.1)
                    .collect();
                let mirror = |r: &Rect| match axis {
                    ConstraintAxis::Vertical => Rect {
                        x: w - r.x - r.w,
                        ..*r
                    },
                    ConstraintAxis::Horizontal => Rect {
                        y: h - r.y - r.h,
                        ..*r
                    },
                };
                rects
                    .iter()
                    .find(|r| {
                        let m = mirror(r);
                        !rects.iter().any(|o| {
                            same(o.x, m.x) && same(o.y, m.y) && same(o.w, m.w) && same(o.h, m.h)
                        })
                    })
                    .map(|r| format!("the {l} at ({:.2}, {:.2}) has no mirror image", r.x, r.y))
            }
            ConstraintKind::BoundaryDistance { label, min } => {
                let l = self.constraint_label(label)?;
                let min = self.number(min)?;
                let Some((w, h)) = face_size else {
                    return Ok(Some("a boundary distance needs a face".into()));
                };
                self.labelled(s, Some(&l))
                    .into_iter()
                    .find(|(_, r)| too_close(r, w, h, min))
                    .map(|(_, r)| {
                        format!(
                            "the {l} at ({:.2}, {:.2}) is closer than {min} m to the edge",
                            r.x, r.y
                        )
                    })
            }
            ConstraintKind::NoIntersection { labels } => {
                let labels: Vec<String> = labels
                    .iter()
                    .map(|e| self.constraint_label(e))
                    .collect::<Result<_, _>>()?;
                let rects: Vec<(ShapeId, Rect)> = if labels.is_empty() {
                    self.labelled(s, None)
                } else {
                    labels
                        .iter()
                        .flat_map(|l| self.labelled(s, Some(l)))
                        .collect()
                };
                let mut found = None;
                'outer: for (i, (ia, a)) in rects.iter().enumerate() {
                    for (ib, b) in &rects[i + 1..] {
                        if ia != ib && overlap(a, b) {
                            found = Some(format!(
                                "{} and {} overlap",
                                self.d.shapes[*ia].label, self.d.shapes[*ib].label
                            ));
                            break 'outer;
                        }
                    }
                }
                found
            }
        })
    }

    /// Why a new element `label` at `rect` on `face` would break a kept `noIntersection` or
    /// `boundaryDistance` term set on the face or above it.
    fn breaks_kept(&self, face: ShapeId, label: &str, rect: &Rect) -> Option<String> {
        let size = self.d.frame(face).map(|f| (f.width, f.height))?;
        for (s, c) in &self.d.constraints {
            if !self.is_at_or_above(*s, face) {
                continue;
            }
            match &c.kind {
                ConstraintKind::BoundaryDistance { label: l, min } => {
                    let (Ok(l), Ok(min)) = (self.string(l), self.number(min)) else {
                        continue;
                    };
                    if l == label && too_close(rect, size.0, size.1, min) {
                        return Some(format!(
                            "closer than {min} m to the edge (a kept constraint)"
                        ));
                    }
                }
                ConstraintKind::NoIntersection { labels } => {
                    let labels: Vec<String> =
                        labels.iter().filter_map(|e| self.string(e).ok()).collect();
                    if !labels.is_empty() && !labels.iter().any(|l| l == label) {
                        continue;
                    }
                    let others = if labels.is_empty() {
                        self.labelled(face, None)
                    } else {
                        labels
                            .iter()
                            .flat_map(|l| self.labelled(face, Some(l)))
                            .collect()
                    };
                    if let Some((o, _)) = others.iter().find(|(_, r)| overlap(r, rect)) {
                        return Some(format!(
                            "it would overlap {} (a kept noIntersection)",
                            self.d.shapes[*o].label
                        ));
                    }
                }
                _ => {}
            }
        }
        None
    }

    fn is_at_or_above(&self, s: ShapeId, mut below: ShapeId) -> bool {
        loop {
            if below == s {
                return true;
            }
            match self.d.shapes[below].parent {
                Some(p) => below = p,
                None => return false,
            }
        }
    }

    /// `align` and `symmetric` again on the finished layout.
    fn final_checks(&mut self) {
        let kept = self.d.constraints.clone();
        for (s, c) in kept {
            if matches!(
                c.kind,
                ConstraintKind::Align { .. } | ConstraintKind::Symmetric { .. }
            ) {
                if let Ok(Some(why)) = self.violation(s, &c.kind) {
                    self.warn(c.span, format!("constraint broken by later rules: {why}"));
                }
            }
        }
    }
}

fn describe(v: &Value) -> String {
    match v {
        Value::Num(x) => format!("the number {x}"),
        Value::Str(s) => format!("the string {s:?}"),
        Value::List(l) => format!("a list of {}", l.len()),
    }
}

fn axis(a: Attr) -> Axis {
    match a {
        Attr::RowIdx | Attr::RowLabel => Axis::Row,
        _ => Axis::Col,
    }
}

fn cmp(c: Cmp) -> CmpOp {
    match c {
        Cmp::Eq => CmpOp::Eq,
        Cmp::Ne => CmpOp::Ne,
        Cmp::Lt => CmpOp::Lt,
        Cmp::Le => CmpOp::Le,
        Cmp::Gt => CmpOp::Gt,
        Cmp::Ge => CmpOp::Ge,
    }
}

/// Removes repeated shapes (and merges repeated grids' cells), keeping first places.
fn dedup(items: &mut Vec<Item>) {
    let mut out: Vec<Item> = Vec::with_capacity(items.len());
    for it in items.drain(..) {
        let dup = out.iter_mut().find(|o| match (&**o, &it) {
            (Item::Shape(a), Item::Shape(b)) => a == b,
            (Item::Cells { grid: a, .. }, Item::Cells { grid: b, .. }) => a == b,
            _ => false,
        });
        match (dup, it) {
            (None, it) => out.push(it),
            (Some(Item::Cells { set, .. }), Item::Cells { set: more, .. }) => {
                if let Ok(u) = set.union(&more) {
                    *set = u;
                }
            }
            _ => {}
        }
    }
    *items = out;
}

/// Whether two rectangles share interior.
fn overlap(a: &Rect, b: &Rect) -> bool {
    let eps = 1e-6;
    a.x + eps < b.x + b.w && b.x + eps < a.x + a.w && a.y + eps < b.y + b.h && b.y + eps < a.y + a.h
}

/// Whether two rectangles touch along an edge (without overlapping).
fn touch(a: &Rect, b: &Rect) -> bool {
    let eps = 1e-6;
    let x_meet = (a.x + a.w - b.x).abs() < eps || (b.x + b.w - a.x).abs() < eps;
    let y_meet = (a.y + a.h - b.y).abs() < eps || (b.y + b.h - a.y).abs() < eps;
    let x_span = a.x + eps < b.x + b.w && b.x + eps < a.x + a.w;
    let y_span = a.y + eps < b.y + b.h && b.y + eps < a.y + a.h;
    (x_meet && y_span) || (y_meet && x_span)
}

fn too_close(r: &Rect, w: f64, h: f64, min: f64) -> bool {
    r.x < min - 1e-9
        || r.y < min - 1e-9
        || w - (r.x + r.w) < min - 1e-9
        || h - (r.y + r.h) < min - 1e-9
}

/// The rectangle `w × h` minus `holes`, as rectangles: the plane cut at every hole edge into
/// slabs, the free cells of each horizontal band merged into runs, and runs merged upwards
/// with the run directly below when they span the same columns.
pub fn cover(w: f64, h: f64, holes: &[Rect]) -> Vec<Rect> {
    let clamp = |v: f64, hi: f64| v.clamp(0.0, hi);
    let mut xs = vec![0.0, w];
    let mut ys = vec![0.0, h];
    for r in holes {
        xs.extend([clamp(r.x, w), clamp(r.x + r.w, w)]);
        ys.extend([clamp(r.y, h), clamp(r.y + r.h, h)]);
    }
    let sort = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
    };
    sort(&mut xs);
    sort(&mut ys);
    let mut out: Vec<Rect> = Vec::new();
    // Runs of the band below: (x0, x1, index in out).
    let mut below: Vec<(f64, f64, usize)> = Vec::new();
    for band in ys.windows(2) {
        let (y0, y1) = (band[0], band[1]);
        if y1 - y0 < 1e-9 {
            continue;
        }
        let mut runs: Vec<(f64, f64)> = Vec::new();
        for col in xs.windows(2) {
            let (x0, x1) = (col[0], col[1]);
            if x1 - x0 < 1e-9 {
                continue;
            }
            let cell = Rect {
                x: x0,
                y: y0,
                w: x1 - x0,
                h: y1 - y0,
            };
            if holes.iter().any(|r| overlap(r, &cell)) {
                continue;
            }
            match runs.last_mut() {
                Some(last) if (last.1 - x0).abs() < 1e-9 => last.1 = x1,
                _ => runs.push((x0, x1)),
            }
        }
        let mut now = Vec::with_capacity(runs.len());
        for (x0, x1) in runs {
            let grow = below
                .iter()
                .find(|(a, b, i)| same(*a, x0) && same(*b, x1) && same(out[*i].y + out[*i].h, y0));
            match grow {
                Some(&(_, _, i)) => {
                    out[i].h = y1 - out[i].y;
                    now.push((x0, x1, i));
                }
                None => {
                    out.push(Rect {
                        x: x0,
                        y: y0,
                        w: x1 - x0,
                        h: y1 - y0,
                    });
                    now.push((x0, x1, out.len() - 1));
                }
            }
        }
        below = now;
    }
    out
}
