//! The SELEX lexer and recursive-descent parser, and `check`'s warnings.
//!
//! The grammar is in the [`ast`](super::ast) module docs. [`parse`] checks everything that can be
//! checked without a shape tree: the names of selectors, attributes, groupings, actions and
//! constraint terms (with a did-you-mean), the place of topology selectors, the arity and the
//! argument kinds of every action (messages name the parameter), literal indices (whole,
//! non-zero), and it caps the input's size ([`MAX_SOURCE_BYTES`]) and nesting
//! (`MAX_NESTING`). Every error is `file:line:col: message`, the offending line and a caret;
//! the parser never panics. [`check`] lists what parses but is suspicious.
//!
//! Identifiers are variables when an assignment before them bound that name. A bare identifier
//! that names no variable is, as a value on its own, the string of its text (Jiang's
//! `[label == main]`; [`check`] warns), and in arithmetic an error.

use std::collections::BTreeMap;
use std::fmt;

use super::ast::{Expr, ExprKind, Program, Span, Topo, ValueKind};
use crate::grammar::lint::suggest;
use crate::grammar::parser::fmt_located;

mod actions;
mod lexer;
mod select;
mod values;
mod warnings;

use lexer::{clip, lex, Tok};
pub use warnings::check;

/// The longest program [`parse`] takes, in bytes: the rule files' cap (programs are a few
/// kilobytes; parsing holds tens of bytes per byte of input).
pub const MAX_SOURCE_BYTES: usize = crate::grammar::MAX_SOURCE_BYTES;

/// The deepest nesting of a value: each `(`, `[`, unary `-` and binary operator on the way
/// down counts one. Real programs nest a few levels; the cap bounds the parser's recursion and
/// every later walk of an expression.
pub(crate) const MAX_NESTING: usize = 128;

/// Work spent on did-you-mean suggestions in one parse (cells of edit-distance tables).
const SUGGEST_BUDGET: usize = 1_000_000;

/// What went wrong while parsing, for programmatic checks (the message says it in words).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ParseErrorKind {
    /// A character that starts no token, or a malformed number.
    BadCharacter,
    /// A token where another was expected.
    UnexpectedToken,
    /// A `{`, `<`, `(`, `[` or string never closed.
    Unclosed,
    /// A topology selector other than child, descendant, parent, root, neighbor, contained,
    /// cell.
    UnknownTopology,
    /// An attribute other than those of [`Attr`](super::ast::Attr).
    UnknownAttribute,
    /// A selection function other than `pattern` (or `in` followed by an unknown range).
    UnknownSelector,
    /// A grouping function other than groupRegions, groupRows, groupCols, groupPairs,
    /// groupEach.
    UnknownGrouping,
    /// An action not among [`ActionKind`](super::ast::ActionKind).
    UnknownAction,
    /// A constraint term other than align, symmetric, boundaryDistance, noIntersection.
    UnknownConstraint,
    /// An identifier in arithmetic that names no variable assigned before it.
    UnknownVariable,
    /// A topology selector after a filter, or a second one in the same step.
    TopologyNotFirst,
    /// A grouping function written without `::` (`[groupRegions()]`).
    GroupingWithoutColons,
    /// The same grouping twice in one step.
    DuplicateGrouping,
    /// `in ()`.
    EmptyList,
    /// An index that is not a whole number.
    NonIntegerIndex,
    /// Index 0 (indices are 1-based; -1 is the last).
    ZeroIndex,
    /// An ordering comparison (`<` ...) or a range on a string attribute.
    BadComparison,
    /// A selector value of the wrong kind (a string for `rowIdx`, a number for `label`).
    WrongValueKind,
    /// Arithmetic on a string or a list.
    NotANumber,
    /// An action, constraint or selector called with too few or too many arguments.
    WrongArgCount,
    /// An argument of the wrong kind (the message names the parameter).
    WrongArgKind,
    /// Arguments elided with `...` as the seed's Fig. 13 prints them.
    Elided,
    /// A value nested deeper than `MAX_NESTING`.
    TooDeep,
    /// A program longer than [`MAX_SOURCE_BYTES`].
    TooLarge,
}

/// A parse error: `file:line:col: message`, then the offending line and a caret under the place.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub struct SelexError {
    /// The file name given to [`parse`].
    pub file: String,
    /// 1-based line.
    pub line: u32,
    /// 1-based column (characters).
    pub col: u32,
    /// What went wrong.
    pub kind: ParseErrorKind,
    /// The explanation.
    pub message: String,
    /// The text of the offending line (without its newline).
    pub line_text: String,
}

impl fmt::Display for SelexError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt_located(
            f,
            &self.file,
            self.line,
            self.col,
            &self.message,
            &self.line_text,
        )
    }
}

/// What [`check`] found suspicious.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum WarningKind {
    /// A rule separated by `>` instead of `->` (Brito's listing).
    LegacyArrow,
    /// A bare identifier taken as a string.
    BareWord,
    /// A grouping in a step that selects no cells (neither `cell()` nor `[type == "cell"]`).
    GroupingOutsideCells,
    /// Two different groupings in one step.
    SeveralGroupings,
    /// A `roundShape` whose previous action is not an `addVolume`.
    RoundShapeWithoutVolume,
    /// A `type`, `dim` or `side` compared with a value it never takes.
    UnknownValue,
    /// A program without any rule.
    NoRules,
}

/// A warning of [`check`], displayed like [`SelexError`] with `warning:` before the message.
#[derive(Clone, Debug, PartialEq)]
pub struct Warning {
    /// The file name given to [`check`].
    pub file: String,
    /// 1-based line.
    pub line: u32,
    /// 1-based column (characters).
    pub col: u32,
    /// What it is.
    pub kind: WarningKind,
    /// The explanation.
    pub message: String,
    /// The text of the line (without its newline).
    pub line_text: String,
}

impl fmt::Display for Warning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt_located(
            f,
            &self.file,
            self.line,
            self.col,
            &format!("warning: {}", self.message),
            &self.line_text,
        )
    }
}

/// The text of the line holding byte `offset` (clamped to the source), without its newline.
fn line_at(src: &str, offset: usize) -> String {
    let mut at = offset.min(src.len());
    while !src.is_char_boundary(at) {
        at -= 1;
    }
    let start = src[..at].rfind('\n').map_or(0, |i| i + 1);
    let end = src[at..].find('\n').map_or(src.len(), |i| at + i);
    src[start..end].trim_end_matches('\r').to_string()
}

struct Ctx<'a> {
    src: &'a str,
    file: &'a str,
}

impl Ctx<'_> {
    fn err(&self, span: Span, kind: ParseErrorKind, message: impl Into<String>) -> SelexError {
        SelexError {
            file: self.file.to_string(),
            line: span.line,
            col: span.col,
            kind,
            message: message.into(),
            line_text: line_at(self.src, span.offset),
        }
    }
}

type PResult<T> = Result<T, SelexError>;

struct Parser<'a> {
    ctx: Ctx<'a>,
    toks: Vec<(Tok, Span)>,
    pos: usize,
    /// The variables assigned so far and the kind of their value.
    vars: BTreeMap<String, ValueKind>,
    /// Levels of value nesting open.
    nesting: usize,
    /// What is left of [`SUGGEST_BUDGET`].
    budget: usize,
}

/// Names of a list of topology selectors, for suggestions and messages.
fn topo_names() -> Vec<&'static str> {
    Topo::ALL.iter().map(|t| t.name()).collect()
}

fn describe_expr(e: &Expr, vars: &BTreeMap<String, ValueKind>) -> String {
    match &e.kind {
        ExprKind::Number(v) => format!("the number {v}"),
        ExprKind::Str(s) => format!("the string \"{}\"", clip(s)),
        ExprKind::BareWord(s) => format!("the word `{}`", clip(s)),
        ExprKind::Var(s) => match vars.get(s) {
            Some(k) => format!("the variable `{}` ({k})", clip(s)),
            None => format!("the variable `{}`", clip(s)),
        },
        ExprKind::List(items) => format!(
            "a list of {} item{}",
            items.len(),
            if items.len() == 1 { "" } else { "s" }
        ),
        ExprKind::Neg(_) | ExprKind::Binary(..) => match e.constant() {
            Some(v) => format!("the number {v}"),
            None => "an arithmetic expression".into(),
        },
    }
}

fn quoted_list(items: &[&str]) -> String {
    items
        .iter()
        .map(|s| format!("\"{s}\""))
        .collect::<Vec<_>>()
        .join(", ")
}

impl<'a> Parser<'a> {
    fn peek(&self) -> &Tok {
        &self.toks[self.pos.min(self.toks.len() - 1)].0
    }
    fn peek_at(&self, k: usize) -> &Tok {
        &self.toks[(self.pos + k).min(self.toks.len() - 1)].0
    }
    fn span(&self) -> Span {
        self.toks[self.pos.min(self.toks.len() - 1)].1
    }
    /// The span of the token before the current one.
    fn prev_span(&self) -> Span {
        self.toks[self.pos.saturating_sub(1).min(self.toks.len() - 1)].1
    }
    fn bump(&mut self) -> (Tok, Span) {
        let t = self.toks[self.pos.min(self.toks.len() - 1)].clone();
        if self.pos < self.toks.len() - 1 {
            self.pos += 1;
        }
        t
    }
    fn err(&self, span: Span, kind: ParseErrorKind, msg: impl Into<String>) -> SelexError {
        self.ctx.err(span, kind, msg)
    }
    fn unexpected(&self, expected: &str) -> SelexError {
        let msg = format!("expected {expected}, found {}", self.peek().describe());
        self.err(self.span(), ParseErrorKind::UnexpectedToken, msg)
    }
    fn expect(&mut self, t: Tok, what: &str) -> PResult<Span> {
        if *self.peek() == t {
            Ok(self.bump().1)
        } else {
            Err(self.unexpected(what))
        }
    }
    /// `; did you mean `x`?` or nothing.
    fn did_you_mean(&mut self, name: &str, cands: &[&str]) -> String {
        let with_len: Vec<(&str, usize)> = cands.iter().map(|c| (*c, c.chars().count())).collect();
        match suggest(name, &with_len, &mut self.budget) {
            Some(c) => format!("; did you mean `{c}`?"),
            None => String::new(),
        }
    }
    /// The error for a missing closer: `Unclosed` pointing at the opener when the parser
    /// stands where the construct cannot go on, else an unexpected token.
    fn unclosed_or(&self, open: Span, opener: &str, closer: &str, stops: &[Tok]) -> SelexError {
        if *self.peek() == Tok::Eof || stops.contains(self.peek()) {
            self.err(
                open,
                ParseErrorKind::Unclosed,
                format!(
                    "unclosed `{opener}`: expected `{closer}` before {}",
                    self.peek().describe()
                ),
            )
        } else {
            self.unexpected(&format!("`{closer}`"))
        }
    }
    fn enter(&mut self, at: Span) -> PResult<()> {
        self.nesting += 1;
        if self.nesting > MAX_NESTING {
            return Err(self.err(
                at,
                ParseErrorKind::TooDeep,
                format!("value nested more than {MAX_NESTING} levels deep"),
            ));
        }
        Ok(())
    }
}

/// Parses a SELEX program. `file` names the source in messages. A source over
/// [`MAX_SOURCE_BYTES`] is refused before it is lexed ([`ParseErrorKind::TooLarge`], at 1:1).
pub fn parse(src: &str, file: &str) -> Result<Program, SelexError> {
    let ctx = Ctx { src, file };
    if src.len() > MAX_SOURCE_BYTES {
        let mut e = ctx.err(
            Span {
                line: 1,
                col: 1,
                offset: 0,
                len: 0,
            },
            ParseErrorKind::TooLarge,
            format!(
                "the program is {} bytes, more than {MAX_SOURCE_BYTES}, the cap on SELEX \
                 programs (programs are a few kilobytes)",
                src.len()
            ),
        );
        e.line_text = clip(&e.line_text);
        return Err(e);
    }
    let toks = lex(&ctx)?;
    let mut p = Parser {
        ctx,
        toks,
        pos: 0,
        vars: BTreeMap::new(),
        nesting: 0,
        budget: SUGGEST_BUDGET,
    };
    p.program()
}
