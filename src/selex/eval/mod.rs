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

use super::ast::{ActionKind, Command, Constraint, Program, Span};
use super::grid::{self, CellRect, CellSet, Grid, Rect};

mod act;
mod constrain;
mod rects;
mod select;
mod values;

pub(crate) use rects::cover;

/// The storey height `createStoreyGrid` assumes on a face that has no storeys of its own (a
/// box made by `createShape`), metres.
pub(crate) const DEFAULT_STOREY: f64 = 3.0;

/// Index of a shape in [`Derivation::shapes`]; the root is 0.
pub(crate) type ShapeId = usize;

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
    pub(crate) fn type_name(&self) -> &'static str {
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
    pub(crate) fn to_text(&self) -> String {
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
pub(crate) fn run_on_box(
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
            by_label: HashMap::from([("root".to_string(), vec![0])]),
            children_by_label: HashMap::new(),
            walk_only: false,
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
    run_indexed(program, src, file, lot, true)
}

/// [`run`] (`lot` `None`) or [`run_on_box`] with every selection made by walking the tree, as
/// before the label indexes: tests compare the two.
#[cfg(test)]
pub(crate) fn run_walking(
    program: &Program,
    src: &str,
    file: &str,
    lot: Option<(f64, f64, f64)>,
) -> Result<Derivation, RunError> {
    run_indexed(program, src, file, lot, false)
}

fn run_indexed(
    program: &Program,
    src: &str,
    file: &str,
    lot: Option<(f64, f64, f64)>,
    indexed: bool,
) -> Result<Derivation, RunError> {
    let mut r = Runner::new(src, file);
    r.walk_only = !indexed;
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
    /// The shapes of each label, in creation order (labels never change), for the selections
    /// `descendant() [label == "x"]` and `[label == "x"]` ([`select`]): a program of many
    /// rules then does not walk the whole tree once per rule.
    by_label: HashMap<String, Vec<ShapeId>>,
    /// The children of each shape by label, in creation order (which is their order).
    children_by_label: HashMap<(ShapeId, String), Vec<ShapeId>>,
    /// Selections walk the tree without the label indexes (tests compare the two).
    walk_only: bool,
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
        self.by_label.entry(label.to_string()).or_default().push(id);
        self.children_by_label
            .entry((parent, label.to_string()))
            .or_default()
            .push(id);
        id
    }
}
