//! The parsed form of a rule file: rules, operations, expressions, successors.
//!
//! Symbols are interned at parse time into [`SymbolId`]s so that derivation never hashes or
//! allocates a symbol name per shape.

use std::collections::{BTreeMap, HashMap};
use std::sync::Arc;

/// A place in the rule source: 1-based line and column (in characters) and the byte range.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Span {
    /// 1-based line.
    pub line: u32,
    /// 1-based column, counted in characters.
    pub col: u32,
    /// Byte offset of the first character.
    pub offset: usize,
    /// Length in bytes (at least 1 for a caret, 0 at end of file).
    pub len: usize,
}

impl Span {
    /// The span from the start of `self` to the end of `other` (line and column of `self`).
    pub fn to(self, other: Span) -> Span {
        let end = (other.offset + other.len).max(self.offset + self.len);
        Span {
            len: end - self.offset.min(end),
            ..self
        }
    }

    /// One past the last byte.
    pub fn end(self) -> usize {
        self.offset + self.len
    }
}

/// A scope axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Axis {
    /// The scope's X axis (along the facade / dominant footprint direction).
    X,
    /// The scope's Y axis (perpendicular, horizontal; the normal of a facade, size 0 there).
    Y,
    /// Up.
    Z,
}

impl Axis {
    /// Index 0, 1, 2.
    pub(crate) fn index(self) -> usize {
        match self {
            Axis::X => 0,
            Axis::Y => 1,
            Axis::Z => 2,
        }
    }

    /// The axis name as written in rules.
    pub(crate) fn name(self) -> &'static str {
        match self {
            Axis::X => "X",
            Axis::Y => "Y",
            Axis::Z => "Z",
        }
    }
}

/// A binary arithmetic operator.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
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

/// A numeric expression in an operation argument, evaluated per shape at derive time.
#[derive(Clone, Debug, PartialEq)]
pub enum Expr {
    /// A literal.
    Num(f64),
    /// `sx`, `sy` or `sz`: the current shape's scope size along that axis.
    ScopeSize(Axis),
    /// Any other identifier: the current shape's numeric attribute of that name (inherited).
    Attr(Arc<str>, Span),
    /// `rand(a, b)`: uniform in [a, b) from the derivation's generator.
    Rand(Box<Expr>, Box<Expr>),
    /// Unary minus.
    Neg(Box<Expr>),
    /// A binary operation.
    Bin(BinOp, Box<Expr>, Box<Expr>),
}

/// How the sizes of a subdividing operation are read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SplitKind {
    /// `split`: absolute sizes in metres.
    Absolute,
    /// `rsplit`: fractions of the parent (normalised when they do not sum to 1).
    Relative,
    /// `repeat`: the pattern of sizes repeated as many whole times as it fits.
    Repeat,
}

impl SplitKind {
    /// The operation name as written in rules.
    pub(crate) fn name(self) -> &'static str {
        match self {
            SplitKind::Absolute => "split",
            SplitKind::Relative => "rsplit",
            SplitKind::Repeat => "repeat",
        }
    }
}

/// The operation of a rule.
#[derive(Clone, Debug, PartialEq)]
pub enum Op {
    /// No operation: the successors are relabelled copies of the predecessor shape.
    Relabel,
    /// `extrude(h)`.
    Extrude(Expr),
    /// `split`, `rsplit`, `repeat` along an axis; one size per successor.
    Split {
        /// Which of the three.
        kind: SplitKind,
        /// Along which scope axis.
        axis: Axis,
        /// One size expression per successor.
        sizes: Vec<Expr>,
    },
    /// `comp()`: decomposition of a volume into faces.
    Comp,
    /// `S(x, y, z)`: set the scope size.
    Scale([Expr; 3]),
    /// `T(x, y, z)`: translate in the scope frame.
    Translate([Expr; 3]),
    /// `R(axis, degrees)`: rotate the scope (only about Z for now).
    Rotate(Axis, Expr),
}

impl Op {
    /// A short name for messages.
    pub(crate) fn name(&self) -> &'static str {
        match self {
            Op::Relabel => "relabel",
            Op::Extrude(_) => "extrude",
            Op::Split { kind, .. } => kind.name(),
            Op::Comp => "comp",
            Op::Scale(_) => "S",
            Op::Translate(_) => "T",
            Op::Rotate(..) => "R",
        }
    }
}

/// A `comp()` face selector.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Selector {
    /// Vertical face whose outward normal is dominantly along −Y of the parent scope.
    Front,
    /// ... along +Y.
    Back,
    /// ... along −X.
    Left,
    /// ... along +X.
    Right,
    /// Every vertical face.
    Side,
    /// Every vertical face not taken by an earlier selector of the same `comp`.
    Others,
    /// The top face.
    Top,
    /// The bottom face.
    Bottom,
}

impl Selector {
    /// Parses a selector keyword.
    pub(crate) fn from_name(s: &str) -> Option<Selector> {
        Some(match s {
            "front" => Selector::Front,
            "back" => Selector::Back,
            "left" => Selector::Left,
            "right" => Selector::Right,
            "side" => Selector::Side,
            "others" => Selector::Others,
            "top" => Selector::Top,
            "bottom" => Selector::Bottom,
            _ => return None,
        })
    }
}

/// An attribute value: a number, or anything else as text (identifiers, colour names, `#hex`).
#[derive(Clone, Debug, PartialEq)]
pub enum AttrValue {
    /// A number (`2`, `0.5`, `-3`).
    Num(f64),
    /// Text: an identifier, a colour name, `#a0b0c0`, or a quoted string without its quotes.
    Str(Arc<str>),
}

impl AttrValue {
    /// The number, if this is one.
    pub fn as_f64(&self) -> Option<f64> {
        match self {
            AttrValue::Num(v) => Some(*v),
            AttrValue::Str(_) => None,
        }
    }

    /// The text, if this is text.
    pub fn as_str(&self) -> Option<&str> {
        match self {
            AttrValue::Num(_) => None,
            AttrValue::Str(s) => Some(s),
        }
    }
}

impl std::fmt::Display for AttrValue {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            AttrValue::Num(v) => write!(f, "{v}"),
            AttrValue::Str(s) => f.write_str(s),
        }
    }
}

/// A shape's attributes. Keys are shared `Arc<str>` so that copying a map along the tree costs
/// reference counts, not string allocations; look up with `attrs.get("color")`.
pub type Attrs = BTreeMap<Arc<str>, AttrValue>;

/// An interned symbol: an index into the rule set's symbol table.
pub type SymbolId = u32;

/// One successor of a rule: `symbol : attr=val, ...`, with a selector for `comp`.
#[derive(Clone, Debug, PartialEq)]
pub struct Successor {
    /// The comp selector (`Some` exactly when the rule's operation is `comp`).
    pub selector: Option<Selector>,
    /// The successor symbol.
    pub symbol: SymbolId,
    /// Attribute overrides, in source order (a later duplicate wins).
    pub attrs: Vec<(Arc<str>, AttrValue)>,
    /// Where the successor symbol is written.
    pub span: Span,
}

/// One production rule.
#[derive(Clone, Debug, PartialEq)]
pub struct Rule {
    /// The predecessor symbol.
    pub pred: SymbolId,
    /// The operation.
    pub op: Op,
    /// The successors, in order.
    pub succs: Vec<Successor>,
    /// The probability as written, if any.
    pub prob: Option<f64>,
    /// Where the predecessor is written (the rule's start).
    pub span: Span,
}

/// A parsed rule file. Built by [`crate::grammar::parse`].
#[derive(Clone, Debug)]
pub struct RuleSet {
    pub(crate) file: Arc<str>,
    pub(crate) symbols: Vec<Arc<str>>,
    pub(crate) index: HashMap<Arc<str>, SymbolId>,
    pub(crate) rules: Vec<Rule>,
    /// Rule indices per symbol id.
    pub(crate) by_pred: Vec<Vec<usize>>,
    /// Resolved selection weight per rule (explicit probability or share of the remainder).
    pub(crate) weights: Vec<f64>,
    pub(crate) axiom: SymbolId,
}

impl RuleSet {
    /// The file name given to [`crate::grammar::parse`], used in messages.
    pub fn file(&self) -> &str {
        &self.file
    }

    /// The axiom symbol: the predecessor of the first rule.
    pub fn axiom(&self) -> &str {
        &self.symbols[self.axiom as usize]
    }

    /// All rules in source order.
    pub fn rules(&self) -> &[Rule] {
        &self.rules
    }

    /// The name of an interned symbol (`None` for an id not from this rule set).
    pub fn symbol(&self, id: SymbolId) -> Option<&str> {
        self.symbols.get(id as usize).map(|s| &**s)
    }

    /// The rules (with their resolved probabilities) whose predecessor is `symbol`, in source
    /// order. Empty for a terminal.
    pub(crate) fn rules_for(&self, symbol: &str) -> Vec<(&Rule, f64)> {
        match self.index.get(symbol) {
            Some(&id) => self.by_pred[id as usize]
                .iter()
                .map(|&i| (&self.rules[i], self.weights[i]))
                .collect(),
            None => Vec::new(),
        }
    }

    /// `file:line:col (pred -> op)` for messages about a rule.
    pub(crate) fn describe(&self, rule: usize) -> String {
        let r = &self.rules[rule];
        format!(
            "{}:{}:{} ({} -> {})",
            self.file,
            r.span.line,
            r.span.col,
            self.symbols[r.pred as usize],
            r.op.name()
        )
    }

    pub(crate) fn intern(&mut self, name: &str) -> SymbolId {
        if let Some(&id) = self.index.get(name) {
            return id;
        }
        let id = self.symbols.len() as SymbolId;
        let a: Arc<str> = Arc::from(name);
        self.symbols.push(a.clone());
        self.index.insert(a, id);
        self.by_pred.push(Vec::new());
        id
    }
}
