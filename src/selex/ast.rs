//! The typed syntax tree of a SELEX program, as [`parse`](super::parser::parse) builds it.
//!
//! Every node carries a [`Span`] (byte range plus 1-based line and column) so that the
//! interpreter, the pattern language and `selex check` can point their messages into the file.
//!
//! ```text
//! program   := command*
//! command   := IDENT '=' expr ';'                                  -- an assignment
//!            | '{' '<' [step ('/' step)*] '>' arrow action (';' action)* [';'] '}' [';']
//! arrow     := '->' | '>'                     -- '>' only for Brito's listing (check warns)
//! step      := [topo] (filter)*               -- topology first, filters in any order
//! topo      := ('child'|'descendant'|'parent'|'root'|'neighbor'|'contained'|'cell') '(' ')'
//! filter    := '[' ATTR cmp expr ']'
//!            | '[' ATTR 'in' ( '(' expr (',' expr)* ')' | 'indexRange' '(' expr ',' expr ')'
//!                            | 'rowRange' '(' expr ',' expr ')' ) ']'
//!            | '[' 'pattern' '(' STRING ',' STRING ')' ']'
//!            | '[' '::' GROUPING ['(' ')'] ']'
//! cmp       := '==' | '!=' | '<' | '<=' | '>' | '>='
//! action    := ACTION '(' [arg (',' arg)*] ')'     -- arguments checked against `params`
//! expr      := term (('+'|'-') term)* ;  term := unary (('*'|'/') unary)*
//! unary     := '-' unary | NUMBER | STRING | IDENT | '[' [expr (',' expr)*] ']' | '(' expr ')'
//! ```
//!
//! Comments run from `#` to the end of the line (`#C1:` and `##C1:` alike). Strings are written
//! in double quotes, have no escapes and do not cross a line, so a string's text is exactly the
//! bytes between its quotes (the pattern language relies on this to point into the file).
//!
//! # Constraints
//!
//! `constrain(c1, c2, ...)` takes one or more constraint terms, one per constraint kind of the
//! seed (alignment, symmetry, distance to the boundary, no intersection). Labels name the
//! elements (construction shapes) the constraint applies to, inside the selected shape:
//!
//! ```text
//! constrain(align("win1", "win2", "vertical"),   -- win1 and win2 on one vertical line
//!           symmetric("win3", "vertical"),       -- win3 elements mirror about the vertical
//!                                                --   centre line of the selected shape
//!           boundaryDistance("door", 0.5),       -- every door at least 0.5 m from the edge
//!           noIntersection("win1", "ledge"))     -- those never overlap; no label = all elements
//! ```
//!
//! Axes are `"vertical"` (a vertical line: same horizontal centre, or mirrored left/right) and
//! `"horizontal"` (a horizontal line: same height, or mirrored top/bottom). The seed's conflict
//! rule (a constraint incompatible with the ones already kept is dropped) is the interpreter's.

use std::fmt;

/// A place in the source: the grammar's span (1-based line and column in characters, and the
/// byte range), which the diagnostics share.
pub use crate::grammar::ast::Span;

/// A whole program: assignments and rules, executed one at a time in file order.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Program {
    /// The commands in file order.
    pub commands: Vec<Command>,
}

impl Program {
    /// The rules, in file order (assignments left out).
    pub fn rules(&self) -> impl Iterator<Item = &Rule> {
        self.commands.iter().filter_map(|c| match c {
            Command::Rule(r) => Some(r),
            Command::Assign { .. } => None,
        })
    }
}

/// One command of a program.
#[derive(Clone, Debug, PartialEq)]
pub enum Command {
    /// `name = value;`: binds (or rebinds) a variable for the commands after it.
    Assign {
        /// The variable.
        name: String,
        /// Its value.
        value: Expr,
        /// From the name to the `;`.
        span: Span,
    },
    /// `{< selection > -> actions}`.
    Rule(Rule),
}

/// How a rule's selection and actions were separated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Arrow {
    /// `->`, the language's arrow.
    Arrow,
    /// `>`, as Brito's mass-model listing prints it (accepted; `check` warns).
    Gt,
}

/// `{< selection > -> action; action}`: the actions run on each shape the selection picks.
#[derive(Clone, Debug, PartialEq)]
pub struct Rule {
    /// The left side.
    pub selection: Selection,
    /// How the two sides were separated.
    pub arrow: Arrow,
    /// Where the arrow is.
    pub arrow_span: Span,
    /// The right side, in order (at least one).
    pub actions: Vec<Action>,
    /// From `{` to `}`.
    pub span: Span,
}

/// `< step / step / ... >`. No step (`<>`) selects the input, in practice the root.
#[derive(Clone, Debug, PartialEq)]
pub struct Selection {
    /// The steps, applied in order, each to every shape the previous one returned.
    pub steps: Vec<Step>,
    /// From `<` to `>`.
    pub span: Span,
}

/// One step of a selection path: an optional topology selector, then filters in any order.
#[derive(Clone, Debug, PartialEq)]
pub struct Step {
    /// The topology selector; without one, a step looks at the children of each input shape
    /// (the seed's label paths `[label=="building"] / [label=="building_front"]`).
    pub topo: Option<Topo>,
    /// Where the topology selector is, when there is one.
    pub topo_span: Option<Span>,
    /// Attribute selectors, `pattern` and grouping selectors, in source order.
    pub filters: Vec<Filter>,
    /// The whole step.
    pub span: Span,
}

/// A topology selector: which shapes stand in that relation to each input shape.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Topo {
    /// `child()`: the children.
    Child,
    /// `descendant()`: every shape below.
    Descendant,
    /// `parent()`: the parent.
    Parent,
    /// `root()`: the root of the shape tree.
    Root,
    /// `neighbor()`: the shapes of the neighbour list.
    Neighbor,
    /// `contained()`: the shapes contained in a (virtual) shape.
    Contained,
    /// `cell()`: the cells of the current virtual grid (Jiang's Fig. 13).
    Cell,
}

impl Topo {
    /// Every topology selector, in documentation order.
    pub const ALL: [Topo; 7] = [
        Topo::Child,
        Topo::Descendant,
        Topo::Parent,
        Topo::Root,
        Topo::Neighbor,
        Topo::Contained,
        Topo::Cell,
    ];

    /// The function name, as written before `()`.
    pub fn name(self) -> &'static str {
        match self {
            Topo::Child => "child",
            Topo::Descendant => "descendant",
            Topo::Parent => "parent",
            Topo::Root => "root",
            Topo::Neighbor => "neighbor",
            Topo::Contained => "contained",
            Topo::Cell => "cell",
        }
    }

    /// The selector of that name.
    pub(crate) fn from_name(s: &str) -> Option<Topo> {
        Topo::ALL.into_iter().find(|t| t.name() == s)
    }
}

/// A selector in brackets.
#[derive(Clone, Debug, PartialEq)]
pub enum Filter {
    /// `[attr op value]`: keeps the shapes whose attribute compares so.
    Compare {
        /// The attribute.
        attr: Attr,
        /// The comparison.
        op: Cmp,
        /// The value compared with (a number for the index attributes, a string otherwise).
        value: Expr,
        /// From `[` to `]`.
        span: Span,
    },
    /// `[attr in set]`: keeps the shapes whose attribute is in the set. On cells,
    /// `[rowIdx in R][colIdx in C]` selects the Cartesian product R × C.
    In {
        /// The attribute.
        attr: Attr,
        /// The set.
        set: IndexSet,
        /// From `[` to `]`.
        span: Span,
    },
    /// `[pattern(regex, pat)]`: the cells whose character in the expanded pattern is in `pat`.
    /// The strings are kept raw; `selex::pattern` parses `regex`.
    Pattern {
        /// The pattern text, exactly as written between its quotes.
        regex: String,
        /// The characters that select a cell.
        pat: String,
        /// The text between the quotes of `regex`: its character `n` is at column
        /// `regex_span.col + n` of line `regex_span.line` (strings have no escapes).
        regex_span: Span,
        /// The text between the quotes of `pat`.
        pat_span: Span,
        /// From `[` to `]`.
        span: Span,
    },
    /// `[::groupRegions()]` and the other grouping selectors (virtual shapes only).
    Group {
        /// Which grouping.
        grouping: Grouping,
        /// From `[` to `]`.
        span: Span,
    },
}

impl Filter {
    /// From `[` to `]`.
    pub fn span(&self) -> Span {
        match self {
            Filter::Compare { span, .. }
            | Filter::In { span, .. }
            | Filter::Pattern { span, .. }
            | Filter::Group { span, .. } => *span,
        }
    }
}

/// A shape attribute an attribute selector tests.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Attr {
    /// `label`: the shape's name, e.g. `"window"`.
    Label,
    /// `type`: `"virtual"`, `"construction"` or `"cell"`.
    Type,
    /// `dim`: `"2D"` or `"3D"`.
    Dim,
    /// `rowIdx`: a cell's row, 1-based from the ground floor; negative counts from the top.
    RowIdx,
    /// `colIdx`: a cell's column, 1-based from the left seen from outside; negative from the
    /// right.
    ColIdx,
    /// `rowLabel`: the name of a cell's row (`"gnd"`, `"top"`, ...).
    RowLabel,
    /// `colLabel`: the name of a cell's column (`"left"`, `"mid"`, `"right"`, ...).
    ColLabel,
    /// `side`: which side of the building a facade faces (`"front"`, `"back"`, `"left"`,
    /// `"right"`, `"side"`).
    Side,
}

impl Attr {
    /// Every attribute, in documentation order.
    pub const ALL: [Attr; 8] = [
        Attr::Label,
        Attr::Type,
        Attr::Dim,
        Attr::RowIdx,
        Attr::ColIdx,
        Attr::RowLabel,
        Attr::ColLabel,
        Attr::Side,
    ];

    /// The name as written in a selector.
    pub(crate) fn name(self) -> &'static str {
        match self {
            Attr::Label => "label",
            Attr::Type => "type",
            Attr::Dim => "dim",
            Attr::RowIdx => "rowIdx",
            Attr::ColIdx => "colIdx",
            Attr::RowLabel => "rowLabel",
            Attr::ColLabel => "colLabel",
            Attr::Side => "side",
        }
    }

    /// The attribute of that name.
    pub(crate) fn from_name(s: &str) -> Option<Attr> {
        Attr::ALL.into_iter().find(|a| a.name() == s)
    }

    /// Whether the attribute is a grid index (an integer, compared with numbers, allowed in
    /// `indexRange`/`rowRange`); the others are strings.
    pub(crate) fn is_index(self) -> bool {
        matches!(self, Attr::RowIdx | Attr::ColIdx)
    }
}

/// A comparison of an attribute selector.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Cmp {
    /// `==`
    Eq,
    /// `!=`
    Ne,
    /// `<`
    Lt,
    /// `<=`
    Le,
    /// `>`
    Gt,
    /// `>=`
    Ge,
}

impl Cmp {
    /// The operator as written.
    pub(crate) fn symbol(self) -> &'static str {
        match self {
            Cmp::Eq => "==",
            Cmp::Ne => "!=",
            Cmp::Lt => "<",
            Cmp::Le => "<=",
            Cmp::Gt => ">",
            Cmp::Ge => ">=",
        }
    }
}

/// The right side of `in`. Ranges are inclusive at both ends; a negative bound counts from the
/// end (-1 is the last row or column).
#[derive(Clone, Debug, PartialEq)]
pub enum IndexSet {
    /// `(a, b, c)`: these values (never empty).
    List(Vec<Expr>),
    /// `indexRange(a, b)` (Brito, Anchiêta): a to b inclusive.
    IndexRange(Expr, Expr),
    /// `rowRange(a, b)` (Jiang): a to b inclusive.
    RowRange(Expr, Expr),
}

/// A grouping selector: how the selected cells are merged into shapes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Grouping {
    /// `groupRegions`: one shape per connected region of selected cells.
    Regions,
    /// `groupRows`: one shape per row of selected cells.
    Rows,
    /// `groupCols` (also `groupColumns`): one shape per column of selected cells.
    Cols,
    /// `groupPairs`: adjacent cells two by two along the row.
    Pairs,
    /// `groupEach`: one shape per cell (the default without a grouping).
    Each,
}

impl Grouping {
    /// Every grouping, in documentation order.
    pub const ALL: [Grouping; 5] = [
        Grouping::Regions,
        Grouping::Rows,
        Grouping::Cols,
        Grouping::Pairs,
        Grouping::Each,
    ];

    /// The function name.
    pub fn name(self) -> &'static str {
        match self {
            Grouping::Regions => "groupRegions",
            Grouping::Rows => "groupRows",
            Grouping::Cols => "groupCols",
            Grouping::Pairs => "groupPairs",
            Grouping::Each => "groupEach",
        }
    }

    /// The grouping of that name (`groupColumns` is `groupCols`).
    pub(crate) fn from_name(s: &str) -> Option<Grouping> {
        if s == "groupColumns" {
            return Some(Grouping::Cols);
        }
        Grouping::ALL.into_iter().find(|g| g.name() == s)
    }
}

/// A value: a number, a string, a variable, a list or arithmetic on numbers.
#[derive(Clone, Debug, PartialEq)]
pub struct Expr {
    /// What it is.
    pub kind: ExprKind,
    /// Where it is.
    pub span: Span,
}

/// The forms of [`Expr`].
#[derive(Clone, Debug, PartialEq)]
pub enum ExprKind {
    /// A number literal.
    Number(f64),
    /// A string in double quotes.
    Str(String),
    /// A bare identifier that names no variable assigned before it (`[label == main]`): it
    /// stands for the string of the same text, and `check` warns.
    BareWord(String),
    /// A reference to a variable assigned earlier in the program.
    Var(String),
    /// `[a, b, ...]` (corner lists, side labels, row or column labels).
    List(Vec<Expr>),
    /// `-e`.
    Neg(Box<Expr>),
    /// `a op b`.
    Binary(BinOp, Box<Expr>, Box<Expr>),
}

/// An arithmetic operator.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BinOp {
    /// `+`
    Add,
    /// `-`
    Sub,
    /// `*`
    Mul,
    /// `/`
    Div,
}

/// What an expression evaluates to, as far as the parser knows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) enum ValueKind {
    /// A number.
    Number,
    /// A string.
    Str,
    /// A list.
    List,
}

impl fmt::Display for ValueKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ValueKind::Number => "a number",
            ValueKind::Str => "a string",
            ValueKind::List => "a list",
        })
    }
}

impl Expr {
    /// The value of an expression made of literals only (no variable), or `None`. Division by
    /// zero and other non-finite results are `None` too.
    pub(crate) fn constant(&self) -> Option<f64> {
        let v = match &self.kind {
            ExprKind::Number(v) => *v,
            ExprKind::Neg(e) => -e.constant()?,
            ExprKind::Binary(op, a, b) => {
                let (a, b) = (a.constant()?, b.constant()?);
                match op {
                    BinOp::Add => a + b,
                    BinOp::Sub => a - b,
                    BinOp::Mul => a * b,
                    BinOp::Div => a / b,
                }
            }
            _ => return None,
        };
        v.is_finite().then_some(v)
    }

    /// The text of a string literal or bare word, or `None`.
    pub fn as_str(&self) -> Option<&str> {
        match &self.kind {
            ExprKind::Str(s) | ExprKind::BareWord(s) => Some(s),
            _ => None,
        }
    }
}

/// An action of a rule's right side: a call checked against [`ActionKind::params`].
#[derive(Clone, Debug, PartialEq)]
pub struct Action {
    /// Which action.
    pub name: ActionKind,
    /// The arguments, in order (at most `params().len()`, at least the required ones). Empty
    /// for `constrain`, whose terms are in `constraints`.
    pub args: Vec<Expr>,
    /// The terms of a `constrain(...)` (empty for every other action).
    pub constraints: Vec<Constraint>,
    /// From the name to `)`.
    pub span: Span,
}

/// The kind of value a parameter takes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ParamKind {
    /// A string (a label).
    Str,
    /// A number.
    Number,
    /// A number in [0, 1].
    Unit,
    /// A whole number, at least 1.
    Count,
    /// A count, or a non-empty list of labels, one per row or column (its length is the count).
    CountOrLabels,
    /// A non-empty list of distinct corner names among `CORNERS`.
    Corners,
    /// One of these strings.
    Choice(&'static [&'static str]),
    /// A list of exactly this many strings.
    Labels(usize),
    /// A constraint term (`constrain` only).
    Constraint,
}

/// The corner names of `addRoundFacade`'s `corners`.
pub(crate) const CORNERS: [&str; 4] = ["top_left", "top_right", "bottom_right", "bottom_left"];

/// One parameter of an action.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Param {
    /// Its name, as messages and docs write it.
    pub name: &'static str,
    /// What it takes.
    pub kind: ParamKind,
    /// Whether it may be left out (only trailing parameters are).
    pub optional: bool,
}

const fn p(name: &'static str, kind: ParamKind) -> Param {
    Param {
        name,
        kind,
        optional: false,
    }
}

const fn opt(name: &'static str, kind: ParamKind) -> Param {
    Param {
        name,
        kind,
        optional: true,
    }
}

const EDGE_EXTRUSION: ParamKind = ParamKind::Choice(&["all", "frame", "none"]);

/// The actions of the language.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ActionKind {
    /// `createShape(label, width, depth, height)`: a box centred at the origin, with the side
    /// shapes `<label>_front`, `_left`, `_right`, `_back` (Brito).
    CreateShape,
    /// `createGrid(label, rows, cols)`: a virtual grid on a 2D construction shape. `rows` and
    /// `cols` are counts or lists of row/column labels (`["gnd", "mid", "top"]`, bottom to top;
    /// columns left to right).
    CreateGrid,
    /// `createStoreyGrid(label, bayWidth)`: a metric grid on a facade, one row per storey and
    /// bays of about `bayWidth` metres (issue 23: a grid that fits a real wall).
    CreateStoreyGrid,
    /// `updateGrid(rows, cols)`: re-divides the selected grid in place.
    UpdateGrid,
    /// `setHeadNode()`: makes the selected shape the working node (Jiang).
    SetHeadNode,
    /// `addShape(label, width?, height?, depth?)`: a construction shape in the selected
    /// shape or cell region (Jiang); sizes left out are the region's.
    AddShape,
    /// `addFacade(label)`: a flat element on the selected cells.
    AddFacade,
    /// `addRoundFacade(label, corners, offset, segments, profile)`.
    AddRoundFacade,
    /// `addFacadeWithFrame(label, edgeExtrusion, thickness, width)`.
    AddFacadeWithFrame,
    /// `addRoundFacadeWithFrame(label, corners, offset, segments, profile, edgeExtrusion,
    /// thickness, width)`.
    AddRoundFacadeWithFrame,
    /// `addVolume(label, parentSideLabel, extrusionSize, [front, left, right])`: the selected
    /// cell region pushed out of the wall.
    AddVolume,
    /// `roundShape(type, direction, roundingDegree, segments, sideReference, axis?,
    /// insideDegree?)`: rounds the volume the previous `addVolume` made.
    RoundShape,
    /// `coverShape()`: the wall around the elements (Jiang).
    CoverShape,
    /// `constrain(term, ...)`: see the module docs for the terms.
    Constrain,
}

impl ActionKind {
    /// Every action, in documentation order.
    pub const ALL: [ActionKind; 14] = [
        ActionKind::CreateShape,
        ActionKind::CreateGrid,
        ActionKind::CreateStoreyGrid,
        ActionKind::UpdateGrid,
        ActionKind::SetHeadNode,
        ActionKind::AddShape,
        ActionKind::AddFacade,
        ActionKind::AddRoundFacade,
        ActionKind::AddFacadeWithFrame,
        ActionKind::AddRoundFacadeWithFrame,
        ActionKind::AddVolume,
        ActionKind::RoundShape,
        ActionKind::CoverShape,
        ActionKind::Constrain,
    ];

    /// The name as written.
    pub fn name(self) -> &'static str {
        match self {
            ActionKind::CreateShape => "createShape",
            ActionKind::CreateGrid => "createGrid",
            ActionKind::CreateStoreyGrid => "createStoreyGrid",
            ActionKind::UpdateGrid => "updateGrid",
            ActionKind::SetHeadNode => "setHeadNode",
            ActionKind::AddShape => "addShape",
            ActionKind::AddFacade => "addFacade",
            ActionKind::AddRoundFacade => "addRoundFacade",
            ActionKind::AddFacadeWithFrame => "addFacadeWithFrame",
            ActionKind::AddRoundFacadeWithFrame => "addRoundFacadeWithFrame",
            ActionKind::AddVolume => "addVolume",
            ActionKind::RoundShape => "roundShape",
            ActionKind::CoverShape => "coverShape",
            ActionKind::Constrain => "constrain",
        }
    }

    /// The action of that name.
    pub(crate) fn from_name(s: &str) -> Option<ActionKind> {
        ActionKind::ALL.into_iter().find(|a| a.name() == s)
    }

    /// The parameters, in order. `constrain` has one [`ParamKind::Constraint`] parameter that
    /// repeats (one or more terms).
    pub fn params(self) -> &'static [Param] {
        use ParamKind::*;
        match self {
            ActionKind::CreateShape => {
                const {
                    &[
                        p("label", Str),
                        p("width", Number),
                        p("depth", Number),
                        p("height", Number),
                    ]
                }
            }
            ActionKind::CreateGrid => {
                const {
                    &[
                        p("label", Str),
                        p("rows", CountOrLabels),
                        p("cols", CountOrLabels),
                    ]
                }
            }
            ActionKind::CreateStoreyGrid => const { &[p("label", Str), p("bayWidth", Number)] },
            ActionKind::UpdateGrid => {
                const { &[p("rows", CountOrLabels), p("cols", CountOrLabels)] }
            }
            ActionKind::SetHeadNode | ActionKind::CoverShape => const { &[] },
            ActionKind::AddShape => {
                const {
                    &[
                        p("label", Str),
                        opt("width", Number),
                        opt("height", Number),
                        opt("depth", Number),
                    ]
                }
            }
            ActionKind::AddFacade => const { &[p("label", Str)] },
            ActionKind::AddRoundFacade => {
                const {
                    &[
                        p("label", Str),
                        p("corners", Corners),
                        p("offset", Number),
                        p("segments", Count),
                        p("profile", Unit),
                    ]
                }
            }
            ActionKind::AddFacadeWithFrame => {
                const {
                    &[
                        p("label", Str),
                        p("edgeExtrusion", EDGE_EXTRUSION),
                        p("thickness", Number),
                        p("width", Number),
                    ]
                }
            }
            ActionKind::AddRoundFacadeWithFrame => {
                const {
                    &[
                        p("label", Str),
                        p("corners", Corners),
                        p("offset", Number),
                        p("segments", Count),
                        p("profile", Unit),
                        p("edgeExtrusion", EDGE_EXTRUSION),
                        p("thickness", Number),
                        p("width", Number),
                    ]
                }
            }
            ActionKind::AddVolume => {
                const {
                    &[
                        p("label", Str),
                        p("parentSideLabel", Str),
                        p("extrusionSize", Number),
                        p("sideLabels", Labels(3)),
                    ]
                }
            }
            ActionKind::RoundShape => {
                const {
                    &[
                        p("type", Choice(&["front", "left", "right", "top", "bottom"])),
                        p("direction", Choice(&["outside", "inside"])),
                        p("roundingDegree", Number),
                        p("segments", Count),
                        p(
                            "sideReference",
                            Choice(&["main_front", "main_back", "main_left", "main_right"]),
                        ),
                        opt("axis", Choice(&["vertical", "horizontal"])),
                        opt("insideDegree", Number),
                    ]
                }
            }
            ActionKind::Constrain => const { &[p("constraint", Constraint)] },
        }
    }

    /// The signature as docs write it: `addFacade(label)`, optional parameters with `?`.
    #[cfg(test)]
    pub(crate) fn signature(self) -> String {
        let params: Vec<String> = self
            .params()
            .iter()
            .map(|p| format!("{}{}", p.name, if p.optional { "?" } else { "" }))
            .collect();
        let more = if self == ActionKind::Constrain {
            ", ..."
        } else {
            ""
        };
        format!("{}({}{more})", self.name(), params.join(", "))
    }
}

/// One term of `constrain(...)`.
#[derive(Clone, Debug, PartialEq)]
pub struct Constraint {
    /// What it asks.
    pub kind: ConstraintKind,
    /// From its name to `)`.
    pub span: Span,
}

/// The seed's four constraint kinds. Labels are expressions of string kind.
#[derive(Clone, Debug, PartialEq)]
pub enum ConstraintKind {
    /// `align(a, b, axis)`: the elements labelled `a` and `b` lie on one line along `axis`.
    Align {
        /// First label.
        a: Expr,
        /// Second label.
        b: Expr,
        /// The line's direction.
        axis: ConstraintAxis,
    },
    /// `symmetric(label, axis)`: the elements labelled so mirror about the selected shape's
    /// centre line along `axis`.
    Symmetric {
        /// The elements.
        label: Expr,
        /// The mirror line's direction.
        axis: ConstraintAxis,
    },
    /// `boundaryDistance(label, min)`: each element labelled so stays at least `min` metres
    /// inside the selected shape's boundary.
    BoundaryDistance {
        /// The elements.
        label: Expr,
        /// The distance in metres (a number).
        min: Expr,
    },
    /// `noIntersection(label, ...)`: those elements never overlap (no label: all elements).
    NoIntersection {
        /// The labels (possibly none).
        labels: Vec<Expr>,
    },
}

impl ConstraintKind {
    /// The term names, in documentation order.
    pub(crate) const NAMES: [&'static str; 4] =
        ["align", "symmetric", "boundaryDistance", "noIntersection"];
}

/// The direction of an alignment line or a mirror line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ConstraintAxis {
    /// `"vertical"`: a vertical line.
    Vertical,
    /// `"horizontal"`: a horizontal line.
    Horizontal,
}
