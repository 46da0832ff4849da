//! The SELEX lexer and recursive-descent parser, and `check`'s warnings.
//!
//! The grammar is in the [`ast`](super::ast) module docs. [`parse`] checks everything that can be
//! checked without a shape tree: the names of selectors, attributes, groupings, actions and
//! constraint terms (with a did-you-mean), the place of topology selectors, the arity and the
//! argument kinds of every action (messages name the parameter), literal indices (whole,
//! non-zero), and it caps the input's size ([`MAX_SOURCE_BYTES`]) and nesting
//! ([`MAX_NESTING`]). Every error is `file:line:col: message`, the offending line and a caret;
//! the parser never panics. [`check`] lists what parses but is suspicious.
//!
//! Identifiers are variables when an assignment before them bound that name. A bare identifier
//! that names no variable is, as a value on its own, the string of its text (Jiang's
//! `[label == main]`; [`check`] warns), and in arithmetic an error.

use std::collections::BTreeMap;
use std::fmt;

use super::ast::{
    Action, ActionKind, Arrow, Attr, BinOp, Cmp, Command, Constraint, ConstraintAxis,
    ConstraintKind, Expr, ExprKind, Filter, Grouping, IndexSet, Param, ParamKind, Program, Rule,
    Selection, Span, Step, Topo, ValueKind, CORNERS,
};
use crate::grammar::lint::{suggest, MAX_NAME_CHARS};
use crate::grammar::parser::fmt_located;

/// The longest program [`parse`] takes, in bytes: the rule files' cap (programs are a few
/// kilobytes; parsing holds tens of bytes per byte of input).
pub const MAX_SOURCE_BYTES: usize = crate::grammar::MAX_SOURCE_BYTES;

/// The deepest nesting of a value: each `(`, `[`, unary `-` and binary operator on the way
/// down counts one. Real programs nest a few levels; the cap bounds the parser's recursion and
/// every later walk of an expression.
pub const MAX_NESTING: usize = 128;

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
    /// An attribute other than those of [`Attr`].
    UnknownAttribute,
    /// A selection function other than `pattern` (or `in` followed by an unknown range).
    UnknownSelector,
    /// A grouping function other than groupRegions, groupRows, groupCols, groupPairs,
    /// groupEach.
    UnknownGrouping,
    /// An action not among [`ActionKind`].
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
    /// A value nested deeper than [`MAX_NESTING`].
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

#[derive(Clone, Debug, PartialEq)]
enum Tok {
    Ident(String),
    Num(f64),
    Str(String),
    Arrow,
    Lt,
    Le,
    Gt,
    Ge,
    EqEq,
    Ne,
    Assign,
    LBrace,
    RBrace,
    LParen,
    RParen,
    LBracket,
    RBracket,
    ColonColon,
    Comma,
    Semi,
    Slash,
    Plus,
    Minus,
    Star,
    Ellipsis,
    Eof,
}

impl Tok {
    fn describe(&self) -> String {
        let s = match self {
            Tok::Ident(s) => return format!("`{}`", clip(s)),
            Tok::Num(v) => return format!("number {v}"),
            Tok::Str(s) => return format!("string \"{}\"", clip(s)),
            Tok::Arrow => "->",
            Tok::Lt => "<",
            Tok::Le => "<=",
            Tok::Gt => ">",
            Tok::Ge => ">=",
            Tok::EqEq => "==",
            Tok::Ne => "!=",
            Tok::Assign => "=",
            Tok::LBrace => "{",
            Tok::RBrace => "}",
            Tok::LParen => "(",
            Tok::RParen => ")",
            Tok::LBracket => "[",
            Tok::RBracket => "]",
            Tok::ColonColon => "::",
            Tok::Comma => ",",
            Tok::Semi => ";",
            Tok::Slash => "/",
            Tok::Plus => "+",
            Tok::Minus => "-",
            Tok::Star => "*",
            Tok::Ellipsis => "...",
            Tok::Eof => return "end of file".into(),
        };
        format!("`{s}`")
    }
}

/// A name or string cut for a message (a hostile file may hold megabyte-long ones).
fn clip(s: &str) -> String {
    if s.chars().count() <= MAX_NAME_CHARS {
        s.to_string()
    } else {
        let head: String = s.chars().take(MAX_NAME_CHARS).collect();
        format!("{head}…")
    }
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

struct Lexer<'a> {
    src: &'a str,
    pos: usize,
    line: u32,
    col: u32,
}

impl Lexer<'_> {
    fn peek(&self) -> Option<char> {
        self.src[self.pos..].chars().next()
    }
    fn byte(&self, k: usize) -> Option<u8> {
        self.src.as_bytes().get(self.pos + k).copied()
    }
    fn bump(&mut self) {
        if let Some(c) = self.peek() {
            self.pos += c.len_utf8();
            if c == '\n' {
                self.line += 1;
                self.col = 1;
            } else {
                self.col += 1;
            }
        }
    }
    fn here(&self) -> Span {
        Span {
            line: self.line,
            col: self.col,
            offset: self.pos,
            len: self.peek().map_or(0, char::len_utf8),
        }
    }
}

fn lex(ctx: &Ctx<'_>) -> Result<Vec<(Tok, Span)>, SelexError> {
    let mut lx = Lexer {
        src: ctx.src,
        pos: 0,
        line: 1,
        col: 1,
    };
    let mut out: Vec<(Tok, Span)> = Vec::new();
    while let Some(c) = lx.peek() {
        if c.is_whitespace() {
            lx.bump();
            continue;
        }
        if c == '#' {
            while lx.peek().is_some_and(|ch| ch != '\n') {
                lx.bump();
            }
            continue;
        }
        let start = lx.here();
        let tok = if c.is_ascii_alphabetic() || c == '_' {
            while lx
                .byte(0)
                .is_some_and(|b| b.is_ascii_alphanumeric() || b == b'_')
            {
                lx.bump();
            }
            Tok::Ident(ctx.src[start.offset..lx.pos].to_string())
        } else if c.is_ascii_digit() || (c == '.' && lx.byte(1).is_some_and(|b| b.is_ascii_digit()))
        {
            while lx.byte(0).is_some_and(|b| b.is_ascii_digit()) {
                lx.bump();
            }
            if lx.byte(0) == Some(b'.') && lx.byte(1) != Some(b'.') {
                lx.bump();
                while lx.byte(0).is_some_and(|b| b.is_ascii_digit()) {
                    lx.bump();
                }
            }
            if matches!(lx.byte(0), Some(b'e' | b'E')) {
                let k = usize::from(matches!(lx.byte(1), Some(b'+' | b'-')));
                if lx.byte(1 + k).is_some_and(|b| b.is_ascii_digit()) {
                    for _ in 0..=k {
                        lx.bump();
                    }
                    while lx.byte(0).is_some_and(|b| b.is_ascii_digit()) {
                        lx.bump();
                    }
                }
            }
            // A number glued to letters (`2D`, `3x`) is not a number.
            if lx
                .byte(0)
                .is_some_and(|b| b.is_ascii_alphabetic() || b == b'_')
            {
                while lx
                    .byte(0)
                    .is_some_and(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'.')
                {
                    lx.bump();
                }
            }
            let text = &ctx.src[start.offset..lx.pos];
            match text.parse::<f64>() {
                Ok(v) if v.is_finite() => Tok::Num(v),
                _ => {
                    let span = Span {
                        len: lx.pos - start.offset,
                        ..start
                    };
                    return Err(ctx.err(
                        span,
                        ParseErrorKind::BadCharacter,
                        format!(
                            "malformed number `{}` (write text in double quotes)",
                            clip(text)
                        ),
                    ));
                }
            }
        } else if c == '"' {
            lx.bump();
            let from = lx.pos;
            loop {
                match lx.peek() {
                    Some('"') => break,
                    Some('\n') | None => {
                        return Err(ctx.err(
                            start,
                            ParseErrorKind::Unclosed,
                            "unclosed string: a string ends with `\"` on its own line",
                        ));
                    }
                    Some(_) => lx.bump(),
                }
            }
            let s = ctx.src[from..lx.pos].to_string();
            lx.bump();
            Tok::Str(s)
        } else {
            let two = (c, lx.byte(1));
            let (t, n) = match two {
                ('-', Some(b'>')) => (Tok::Arrow, 2),
                ('<', Some(b'=')) => (Tok::Le, 2),
                ('>', Some(b'=')) => (Tok::Ge, 2),
                ('=', Some(b'=')) => (Tok::EqEq, 2),
                ('!', Some(b'=')) => (Tok::Ne, 2),
                (':', Some(b':')) => (Tok::ColonColon, 2),
                ('.', Some(b'.')) if lx.byte(2) == Some(b'.') => (Tok::Ellipsis, 3),
                ('<', _) => (Tok::Lt, 1),
                ('>', _) => (Tok::Gt, 1),
                ('=', _) => (Tok::Assign, 1),
                ('{', _) => (Tok::LBrace, 1),
                ('}', _) => (Tok::RBrace, 1),
                ('(', _) => (Tok::LParen, 1),
                (')', _) => (Tok::RParen, 1),
                ('[', _) => (Tok::LBracket, 1),
                (']', _) => (Tok::RBracket, 1),
                (',', _) => (Tok::Comma, 1),
                (';', _) => (Tok::Semi, 1),
                ('/', _) => (Tok::Slash, 1),
                ('+', _) => (Tok::Plus, 1),
                ('-', _) => (Tok::Minus, 1),
                ('*', _) => (Tok::Star, 1),
                _ => {
                    let hint = match c {
                        ':' => " (a grouping is written `[::groupRegions()]`)",
                        '\'' => " (strings are written in double quotes)",
                        '!' => " (`!=` compares)",
                        _ => "",
                    };
                    return Err(ctx.err(
                        start,
                        ParseErrorKind::BadCharacter,
                        format!("unexpected character `{c}`{hint}"),
                    ));
                }
            };
            for _ in 0..n {
                lx.bump();
            }
            t
        };
        out.push((
            tok,
            Span {
                len: lx.pos - start.offset,
                ..start
            },
        ));
    }
    // End of file is reported just after the last token, on its line.
    let eof = match out.last() {
        Some((_, last)) => {
            let chars = ctx.src[last.offset..last.end()].chars().count() as u32;
            Span {
                col: last.col + chars,
                offset: last.end(),
                len: 0,
                ..*last
            }
        }
        None => Span {
            line: 1,
            col: 1,
            offset: 0,
            len: 0,
        },
    };
    out.push((Tok::Eof, eof));
    Ok(out)
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

    fn program(&mut self) -> PResult<Program> {
        let mut commands = Vec::new();
        loop {
            match self.peek() {
                Tok::Eof => break,
                Tok::LBrace => commands.push(Command::Rule(self.rule()?)),
                Tok::Ident(_) => commands.push(self.assignment()?),
                _ => {
                    return Err(self.unexpected(
                        "a rule `{< selection > -> actions}` or an assignment `name = value;`",
                    ))
                }
            }
        }
        Ok(Program { commands })
    }

    fn assignment(&mut self) -> PResult<Command> {
        let (name, start) = match self.peek().clone() {
            Tok::Ident(s) => (s, self.bump().1),
            _ => return Err(self.unexpected("a variable name")),
        };
        if *self.peek() == Tok::EqEq {
            return Err(self.err(
                self.span(),
                ParseErrorKind::UnexpectedToken,
                "an assignment is written with `=`, not `==`",
            ));
        }
        self.expect(
            Tok::Assign,
            &format!("`=` after `{}` (an assignment)", clip(&name)),
        )?;
        let value = self.value()?;
        let end = self.expect(Tok::Semi, "`;` after the assignment")?;
        let kind = self.kind_of(&value);
        self.vars.insert(name.clone(), kind);
        Ok(Command::Assign {
            name,
            value,
            span: start.to(end),
        })
    }

    fn rule(&mut self) -> PResult<Rule> {
        let open = self.expect(Tok::LBrace, "`{`")?;
        if *self.peek() != Tok::Lt {
            return Err(self.unexpected("`<` and a selection path"));
        }
        let selection = self.selection()?;
        let (arrow, arrow_span) = match self.peek() {
            Tok::Arrow => (Arrow::Arrow, self.bump().1),
            Tok::Gt => (Arrow::Gt, self.bump().1),
            _ => return Err(self.unexpected("`->` after the selection")),
        };
        let mut actions = Vec::new();
        let close = loop {
            if matches!(self.peek(), Tok::Eof | Tok::LBrace) && !actions.is_empty() {
                return Err(self.unclosed_or(open, "{", "}", &[Tok::LBrace]));
            }
            actions.push(self.action()?);
            match self.peek() {
                Tok::Semi => {
                    self.bump();
                    if *self.peek() == Tok::RBrace {
                        break self.bump().1;
                    }
                }
                Tok::RBrace => break self.bump().1,
                Tok::Eof | Tok::LBrace => {
                    return Err(self.unclosed_or(open, "{", "}", &[Tok::LBrace]))
                }
                _ => return Err(self.unexpected("`;` or `}` after an action")),
            }
        };
        if *self.peek() == Tok::Semi {
            self.bump();
        }
        Ok(Rule {
            selection,
            arrow,
            arrow_span,
            actions,
            span: open.to(close),
        })
    }

    fn selection(&mut self) -> PResult<Selection> {
        let open = self.expect(Tok::Lt, "`<`")?;
        let mut steps = Vec::new();
        if *self.peek() == Tok::Gt {
            let close = self.bump().1;
            return Ok(Selection {
                steps,
                span: open.to(close),
            });
        }
        let stops = [Tok::Arrow, Tok::LBrace, Tok::RBrace, Tok::Semi];
        loop {
            if stops.contains(self.peek()) || *self.peek() == Tok::Eof {
                return Err(self.unclosed_or(open, "<", ">", &stops));
            }
            steps.push(self.step()?);
            match self.peek() {
                Tok::Slash => {
                    self.bump();
                }
                Tok::Gt => {
                    let close = self.bump().1;
                    return Ok(Selection {
                        steps,
                        span: open.to(close),
                    });
                }
                _ => {
                    if stops.contains(self.peek()) || *self.peek() == Tok::Eof {
                        return Err(self.unclosed_or(open, "<", ">", &stops));
                    }
                    return Err(self.unexpected("`/`, `[` or `>`"));
                }
            }
        }
    }

    /// A topology selector `name()`, the parser standing on its name.
    fn topo(&mut self) -> PResult<(Topo, Span)> {
        let (name, sp) = match self.peek().clone() {
            Tok::Ident(s) => (s, self.bump().1),
            _ => return Err(self.unexpected("a topology selector such as `child()`")),
        };
        let Some(t) = Topo::from_name(&name) else {
            let msg = if let Some(a) = Attr::from_name(&name) {
                format!(
                    "`{name}` is an attribute, not a topology selector: write it in brackets, \
                     `[{} == ...]`",
                    a.name()
                )
            } else if Grouping::from_name(&name).is_some() {
                format!("`{name}` is a grouping: write it `[::{name}()]`")
            } else if name == "pattern" {
                "`pattern` is a selection function: write it in brackets, `[pattern(regex, pat)]`"
                    .to_string()
            } else if let Some(a) = ActionKind::from_name(&name) {
                format!(
                    "`{}` is an action: it goes after `->`, outside the selection",
                    a.name()
                )
            } else {
                let dym = self.did_you_mean(&name, &topo_names());
                format!(
                    "unknown topology selector `{}` (known: {}){dym}",
                    clip(&name),
                    topo_names().join(", ")
                )
            };
            return Err(self.err(sp, ParseErrorKind::UnknownTopology, msg));
        };
        if *self.peek() != Tok::LParen {
            return Err(self.unexpected(&format!(
                "`(` after `{name}`: a topology selector is written `{name}()`"
            )));
        }
        let open = self.bump().1;
        if *self.peek() != Tok::RParen {
            if matches!(self.peek(), Tok::Eof | Tok::Gt | Tok::Slash | Tok::LBracket) {
                return Err(self.unclosed_or(
                    open,
                    "(",
                    ")",
                    &[Tok::Gt, Tok::Slash, Tok::LBracket],
                ));
            }
            return Err(self.err(
                self.span(),
                ParseErrorKind::WrongArgCount,
                format!("`{name}()` takes no argument"),
            ));
        }
        let close = self.bump().1;
        Ok((t, sp.to(close)))
    }

    fn step(&mut self) -> PResult<Step> {
        let start = self.span();
        let mut topo = None;
        let mut topo_span = None;
        if matches!(self.peek(), Tok::Ident(_)) {
            let (t, sp) = self.topo()?;
            topo = Some(t);
            topo_span = Some(sp);
        }
        let mut filters: Vec<Filter> = Vec::new();
        loop {
            match self.peek() {
                Tok::LBracket => {
                    let f = self.filter()?;
                    if let Filter::Group { grouping, span } = &f {
                        let dup = filters.iter().any(
                            |g| matches!(g, Filter::Group { grouping: h, .. } if h == grouping),
                        );
                        if dup {
                            return Err(self.err(
                                *span,
                                ParseErrorKind::DuplicateGrouping,
                                format!(
                                    "`{}` appears twice in this step; group once",
                                    grouping.name()
                                ),
                            ));
                        }
                    }
                    filters.push(f);
                }
                Tok::Ident(name) => {
                    let name = name.clone();
                    let sp = self.span();
                    let what = if Topo::from_name(&name).is_some() {
                        format!("topology selector `{name}()`")
                    } else {
                        format!("`{}`", clip(&name))
                    };
                    let msg = if topo.is_some() && filters.is_empty() {
                        format!(
                            "{what} after another topology selector: a step has at most one, \
                             first; start a new step with `/` before it"
                        )
                    } else {
                        format!(
                            "{what} after a filter: a topology selector comes first in its \
                             step; start a new step with `/` before it"
                        )
                    };
                    return Err(self.err(sp, ParseErrorKind::TopologyNotFirst, msg));
                }
                _ => break,
            }
        }
        if topo.is_none() && filters.is_empty() {
            return Err(self.unexpected("a step: a topology selector such as `child()` or `[`"));
        }
        Ok(Step {
            topo,
            topo_span,
            filters,
            span: start.to(self.prev_span()),
        })
    }

    /// `]` closing the filter opened at `open`.
    fn close_bracket(&mut self, open: Span) -> PResult<Span> {
        if *self.peek() == Tok::RBracket {
            return Ok(self.bump().1);
        }
        Err(self.unclosed_or(
            open,
            "[",
            "]",
            &[
                Tok::Slash,
                Tok::Gt,
                Tok::LBracket,
                Tok::RBrace,
                Tok::LBrace,
                Tok::Arrow,
                Tok::Semi,
            ],
        ))
    }

    fn filter(&mut self) -> PResult<Filter> {
        let open = self.expect(Tok::LBracket, "`[`")?;
        match self.peek().clone() {
            Tok::ColonColon => {
                self.bump();
                let (name, sp) = match self.peek().clone() {
                    Tok::Ident(s) => (s, self.bump().1),
                    _ => return Err(self.unexpected("a grouping function such as `groupRegions`")),
                };
                let Some(grouping) = Grouping::from_name(&name) else {
                    let names: Vec<&str> = Grouping::ALL.iter().map(|g| g.name()).collect();
                    let dym = self.did_you_mean(&name, &names);
                    return Err(self.err(
                        sp,
                        ParseErrorKind::UnknownGrouping,
                        format!(
                            "unknown grouping `{}` (known: {}){dym}",
                            clip(&name),
                            names.join(", ")
                        ),
                    ));
                };
                if *self.peek() == Tok::LParen {
                    let p = self.bump().1;
                    if *self.peek() != Tok::RParen {
                        if matches!(self.peek(), Tok::RBracket) {
                            return Err(self.unclosed_or(p, "(", ")", &[Tok::RBracket]));
                        }
                        return Err(self.err(
                            self.span(),
                            ParseErrorKind::WrongArgCount,
                            format!("`{}()` takes no argument", grouping.name()),
                        ));
                    }
                    self.bump();
                }
                let close = self.close_bracket(open)?;
                Ok(Filter::Group {
                    grouping,
                    span: open.to(close),
                })
            }
            Tok::Ident(name) if *self.peek_at(1) == Tok::LParen => {
                let sp = self.span();
                if name == "pattern" {
                    return self.pattern(open);
                }
                let msg = if let Some(g) = Grouping::from_name(&name) {
                    return Err(self.err(
                        sp,
                        ParseErrorKind::GroupingWithoutColons,
                        format!("a grouping is written with `::`: `[::{}()]`", g.name()),
                    ));
                } else if Topo::from_name(&name).is_some() {
                    format!(
                        "`{name}()` is a topology selector: write it without brackets, first in \
                         its step (`{name}()[...]`)"
                    )
                } else {
                    let dym = self.did_you_mean(&name, &["pattern"]);
                    format!(
                        "unknown selection function `{}` (the only one is `pattern`){dym}",
                        clip(&name)
                    )
                };
                Err(self.err(sp, ParseErrorKind::UnknownSelector, msg))
            }
            Tok::Ident(name) => {
                let sp = self.bump().1;
                let Some(attr) = Attr::from_name(&name) else {
                    if let Some(g) = Grouping::from_name(&name) {
                        return Err(self.err(
                            sp,
                            ParseErrorKind::GroupingWithoutColons,
                            format!("a grouping is written with `::`: `[::{}()]`", g.name()),
                        ));
                    }
                    let names: Vec<&str> = Attr::ALL.iter().map(|a| a.name()).collect();
                    let dym = self.did_you_mean(&name, &names);
                    return Err(self.err(
                        sp,
                        ParseErrorKind::UnknownAttribute,
                        format!(
                            "unknown attribute `{}` (known: {}){dym}",
                            clip(&name),
                            names.join(", ")
                        ),
                    ));
                };
                self.attr_filter(open, attr)
            }
            _ => Err(self.unexpected("an attribute, `pattern(...)` or `::grouping`")),
        }
    }

    fn attr_filter(&mut self, open: Span, attr: Attr) -> PResult<Filter> {
        let op_span = self.span();
        let op = match self.peek() {
            Tok::EqEq => Cmp::Eq,
            Tok::Ne => Cmp::Ne,
            Tok::Lt => Cmp::Lt,
            Tok::Le => Cmp::Le,
            Tok::Gt => Cmp::Gt,
            Tok::Ge => Cmp::Ge,
            Tok::Assign => {
                return Err(self.err(
                    op_span,
                    ParseErrorKind::UnexpectedToken,
                    "write `==` to compare (the thesis's prose writes `=`)",
                ))
            }
            Tok::Ident(s) if s == "in" => {
                self.bump();
                let set = self.index_set(attr)?;
                let close = self.close_bracket(open)?;
                return Ok(Filter::In {
                    attr,
                    set,
                    span: open.to(close),
                });
            }
            _ => {
                return Err(self.unexpected(&format!(
                    "a comparison (`==`, `!=`, `<`, `<=`, `>`, `>=`) or `in` after `{}`",
                    attr.name()
                )))
            }
        };
        self.bump();
        if !attr.is_index() && !matches!(op, Cmp::Eq | Cmp::Ne) {
            return Err(self.err(
                op_span,
                ParseErrorKind::BadComparison,
                format!(
                    "`{}` is a string: compare it with `==` or `!=`, not `{}`",
                    attr.name(),
                    op.symbol()
                ),
            ));
        }
        let value = self.value()?;
        self.selector_value(attr, &value, matches!(op, Cmp::Eq | Cmp::Ne))?;
        let close = self.close_bracket(open)?;
        Ok(Filter::Compare {
            attr,
            op,
            value,
            span: open.to(close),
        })
    }

    /// Checks a value an attribute is compared with: a number for the indices (whole and, when
    /// `exact`, not 0, if it is a constant), a string otherwise.
    fn selector_value(&self, attr: Attr, v: &Expr, exact: bool) -> PResult<()> {
        let kind = self.kind_of(v);
        if attr.is_index() {
            if kind != ValueKind::Number {
                return Err(self.err(
                    v.span,
                    ParseErrorKind::WrongValueKind,
                    format!(
                        "`{}` is an index: compare it with a number, found {}",
                        attr.name(),
                        describe_expr(v, &self.vars)
                    ),
                ));
            }
            if let Some(c) = v.constant() {
                if c.fract() != 0.0 {
                    return Err(self.err(
                        v.span,
                        ParseErrorKind::NonIntegerIndex,
                        format!(
                            "`{}` {c} is not a whole number: rows and columns are counted 1, 2, \
                             ... (negative from the end)",
                            attr.name()
                        ),
                    ));
                }
                if exact && c == 0.0 {
                    return Err(self.err(
                        v.span,
                        ParseErrorKind::ZeroIndex,
                        format!(
                            "`{}` 0: indices are 1-based (1 is the first, -1 the last)",
                            attr.name()
                        ),
                    ));
                }
            }
        } else if kind != ValueKind::Str {
            return Err(self.err(
                v.span,
                ParseErrorKind::WrongValueKind,
                format!(
                    "`{}` is a string: compare it with a string, found {}",
                    attr.name(),
                    describe_expr(v, &self.vars)
                ),
            ));
        }
        Ok(())
    }

    fn index_set(&mut self, attr: Attr) -> PResult<IndexSet> {
        match self.peek().clone() {
            Tok::LParen => {
                let open = self.bump().1;
                let mut items = Vec::new();
                if *self.peek() == Tok::RParen {
                    return Err(self.err(
                        open,
                        ParseErrorKind::EmptyList,
                        format!(
                            "`{} in ()`: the list is empty, so nothing would be selected",
                            attr.name()
                        ),
                    ));
                }
                loop {
                    let v = self.value()?;
                    self.selector_value(attr, &v, true)?;
                    items.push(v);
                    match self.peek() {
                        Tok::Comma => {
                            self.bump();
                        }
                        Tok::RParen => {
                            self.bump();
                            break;
                        }
                        _ => {
                            return Err(self.unclosed_or(
                                open,
                                "(",
                                ")",
                                &[Tok::RBracket, Tok::Slash, Tok::Gt, Tok::LBracket],
                            ))
                        }
                    }
                }
                Ok(IndexSet::List(items))
            }
            Tok::Ident(name) if name == "indexRange" || name == "rowRange" => {
                let sp = self.bump().1;
                if !attr.is_index() {
                    return Err(self.err(
                        sp,
                        ParseErrorKind::BadComparison,
                        format!(
                            "`{name}` is a range of indices: it applies to rowIdx and colIdx, \
                             not `{}`",
                            attr.name()
                        ),
                    ));
                }
                let args = self.call_args(&name, |p| p.value())?;
                let found = args.len();
                let [a, b]: [Expr; 2] = args.try_into().map_err(|_| {
                    self.err(
                        sp,
                        ParseErrorKind::WrongArgCount,
                        format!("`{name}(first, last)` takes 2 arguments, found {found}"),
                    )
                })?;
                for v in [&a, &b] {
                    self.selector_value(attr, v, true)?;
                }
                Ok(if name == "indexRange" {
                    IndexSet::IndexRange(a, b)
                } else {
                    IndexSet::RowRange(a, b)
                })
            }
            Tok::Ident(name) => {
                let dym = self.did_you_mean(&name, &["indexRange", "rowRange"]);
                Err(self.err(
                    self.span(),
                    ParseErrorKind::UnknownSelector,
                    format!(
                        "after `in`: a list `(a, b, ...)`, `indexRange(a, b)` or `rowRange(a, b)`, \
                         found `{}`{dym}",
                        clip(&name)
                    ),
                ))
            }
            _ => {
                Err(self.unexpected("a list `(a, b, ...)`, `indexRange(a, b)` or `rowRange(a, b)`"))
            }
        }
    }

    /// `(` item, ... `)` after a function name, the parser standing on `(`; `...` is refused.
    fn call_args<T>(
        &mut self,
        name: &str,
        mut item: impl FnMut(&mut Self) -> PResult<T>,
    ) -> PResult<Vec<T>> {
        if *self.peek() != Tok::LParen {
            return Err(self.unexpected(&format!("`(` after `{}`", clip(name))));
        }
        let open = self.bump().1;
        let mut out = Vec::new();
        if *self.peek() == Tok::RParen {
            self.bump();
            return Ok(out);
        }
        let stops = [
            Tok::Semi,
            Tok::RBrace,
            Tok::LBrace,
            Tok::Arrow,
            Tok::RBracket,
            Tok::Gt,
        ];
        loop {
            if *self.peek() == Tok::Ellipsis {
                return Err(self.err(
                    self.span(),
                    ParseErrorKind::Elided,
                    format!(
                        "arguments elided with `...` (as the seed prints Fig. 13): write the \
                         arguments of `{}`",
                        clip(name)
                    ),
                ));
            }
            if stops.contains(self.peek()) || *self.peek() == Tok::Eof {
                return Err(self.unclosed_or(open, "(", ")", &stops));
            }
            out.push(item(self)?);
            match self.peek() {
                Tok::Comma => {
                    self.bump();
                }
                Tok::RParen => {
                    self.bump();
                    return Ok(out);
                }
                _ => {
                    if stops.contains(self.peek()) || *self.peek() == Tok::Eof {
                        return Err(self.unclosed_or(open, "(", ")", &stops));
                    }
                    return Err(self.unexpected("`,` or `)`"));
                }
            }
        }
    }

    /// `pattern("regex", "pat")`, the parser standing on `pattern`.
    fn pattern(&mut self, open: Span) -> PResult<Filter> {
        let sp = self.bump().1;
        let args = self.call_args("pattern", |p| p.value())?;
        if args.len() != 2 {
            return Err(self.err(
                sp,
                ParseErrorKind::WrongArgCount,
                format!(
                    "`pattern(regex, pat)` takes 2 arguments, found {}",
                    args.len()
                ),
            ));
        }
        let mut strs = Vec::new();
        for (i, (a, pname)) in args.iter().zip(["regex", "pat"]).enumerate() {
            match &a.kind {
                ExprKind::Str(s) => strs.push((
                    s.clone(),
                    Span {
                        line: a.span.line,
                        col: a.span.col + 1,
                        offset: a.span.offset + 1,
                        len: a.span.len.saturating_sub(2),
                    },
                )),
                _ => {
                    return Err(self.err(
                        a.span,
                        ParseErrorKind::WrongArgKind,
                        format!(
                            "pattern: argument {} `{pname}` must be a string in double quotes, \
                             found {}",
                            i + 1,
                            describe_expr(a, &self.vars)
                        ),
                    ))
                }
            }
        }
        let close = self.close_bracket(open)?;
        let Ok([(regex, regex_span), (pat, pat_span)]) = <[(String, Span); 2]>::try_from(strs)
        else {
            return Err(self.err(
                sp,
                ParseErrorKind::WrongArgCount,
                "pattern takes 2 arguments",
            ));
        };
        Ok(Filter::Pattern {
            regex,
            pat,
            regex_span,
            pat_span,
            span: open.to(close),
        })
    }

    fn action(&mut self) -> PResult<Action> {
        let (name, sp) = match self.peek().clone() {
            Tok::Ident(s) => (s, self.bump().1),
            _ => return Err(self.unexpected("an action such as `addFacade(...)`")),
        };
        let Some(kind) = ActionKind::from_name(&name) else {
            let names: Vec<&str> = ActionKind::ALL.iter().map(|a| a.name()).collect();
            let hint = match name.as_str() {
                "attachShape" | "connectShape" | "finalRoof" => {
                    " (the seed names it but never specifies it)"
                }
                _ => "",
            };
            let dym = self.did_you_mean(&name, &names);
            return Err(self.err(
                sp,
                ParseErrorKind::UnknownAction,
                format!(
                    "unknown action `{}`{hint} (known: {}){dym}",
                    clip(&name),
                    names.join(", ")
                ),
            ));
        };
        if kind == ActionKind::Constrain {
            let constraints = self.call_args(&name, |p| p.constraint())?;
            if constraints.is_empty() {
                return Err(self.err(
                    self.prev_span(),
                    ParseErrorKind::WrongArgCount,
                    "constrain takes one or more constraints (align, symmetric, \
                     boundaryDistance, noIntersection), found none",
                ));
            }
            return Ok(Action {
                name: kind,
                args: Vec::new(),
                constraints,
                span: sp.to(self.prev_span()),
            });
        }
        let args = self.call_args(&name, |p| p.value())?;
        let close = self.prev_span();
        self.check_args(kind.name(), kind.params(), &args, close)?;
        Ok(Action {
            name: kind,
            args,
            constraints: Vec::new(),
            span: sp.to(close),
        })
    }

    /// Arity and kinds of `args` against `params`; `close` is the `)` (for missing arguments).
    fn check_args(&self, fname: &str, params: &[Param], args: &[Expr], close: Span) -> PResult<()> {
        let required = params.iter().filter(|p| !p.optional).count();
        if args.len() < required || args.len() > params.len() {
            let names: Vec<String> = params
                .iter()
                .map(|p| format!("{}{}", p.name, if p.optional { "?" } else { "" }))
                .collect();
            let count = if required == params.len() {
                format!(
                    "{required} argument{}",
                    if required == 1 { "" } else { "s" }
                )
            } else {
                format!("{required} to {} arguments", params.len())
            };
            let at = args.get(params.len()).map_or(close, |a| a.span);
            let found = args.len();
            return Err(self.err(
                at,
                ParseErrorKind::WrongArgCount,
                format!(
                    "{fname} takes {count} ({}), found {found}",
                    names.join(", ")
                ),
            ));
        }
        for (i, (a, p)) in args.iter().zip(params).enumerate() {
            self.check_arg(fname, i + 1, p, a)?;
        }
        Ok(())
    }

    fn check_arg(&self, fname: &str, n: usize, p: &Param, a: &Expr) -> PResult<()> {
        let kind = self.kind_of(a);
        let constant = a.constant();
        let expected: String = match p.kind {
            ParamKind::Str => "a string (a label)".into(),
            ParamKind::Number => "a number".into(),
            ParamKind::Unit => "a number between 0 and 1".into(),
            ParamKind::Count => "a whole number of at least 1".into(),
            ParamKind::CountOrLabels => {
                "a whole number of at least 1 or a list of labels, one per row or column".into()
            }
            ParamKind::Corners => format!("a list of corner names ({})", CORNERS.join(", ")),
            ParamKind::Choice(c) => format!("one of {}", quoted_list(c)),
            ParamKind::Labels(k) => format!("a list of {k} labels"),
            ParamKind::Constraint => "a constraint".into(),
        };
        let bad = |what: String| {
            self.err(
                a.span,
                ParseErrorKind::WrongArgKind,
                format!(
                    "{fname}: argument {n} `{}` must be {expected}, found {what}",
                    p.name
                ),
            )
        };
        let found = || describe_expr(a, &self.vars);
        let count_ok = |c: Option<f64>| c.is_none_or(|v| v >= 1.0 && v.fract() == 0.0);
        match p.kind {
            ParamKind::Str => {
                if kind != ValueKind::Str {
                    return Err(bad(found()));
                }
            }
            ParamKind::Number => {
                if kind != ValueKind::Number {
                    return Err(bad(found()));
                }
            }
            ParamKind::Unit => {
                if kind != ValueKind::Number || constant.is_some_and(|v| !(0.0..=1.0).contains(&v))
                {
                    return Err(bad(found()));
                }
            }
            ParamKind::Count => {
                if kind != ValueKind::Number || !count_ok(constant) {
                    return Err(bad(found()));
                }
            }
            ParamKind::CountOrLabels => match (&a.kind, kind) {
                (_, ValueKind::Number) if count_ok(constant) => {}
                (ExprKind::List(items), _) => {
                    if items.is_empty() {
                        return Err(bad("an empty list".into()));
                    }
                    for it in items {
                        if self.kind_of(it) != ValueKind::Str {
                            return Err(self.err(
                                it.span,
                                ParseErrorKind::WrongArgKind,
                                format!(
                                    "{fname}: argument {n} `{}` must be {expected}, found {} in \
                                     the list",
                                    p.name,
                                    describe_expr(it, &self.vars)
                                ),
                            ));
                        }
                    }
                }
                (ExprKind::Var(_), ValueKind::List) => {}
                _ => return Err(bad(found())),
            },
            ParamKind::Corners => match &a.kind {
                ExprKind::List(items) => {
                    if items.is_empty() {
                        return Err(bad("an empty list".into()));
                    }
                    let mut seen: Vec<&str> = Vec::new();
                    for it in items {
                        let name = it.as_str();
                        match name {
                            Some(c) if CORNERS.contains(&c) => {
                                if seen.contains(&c) {
                                    return Err(self.err(
                                        it.span,
                                        ParseErrorKind::WrongArgKind,
                                        format!(
                                            "{fname}: argument {n} `{}` names \"{c}\" twice",
                                            p.name
                                        ),
                                    ));
                                }
                                seen.push(c);
                            }
                            _ => {
                                let mut budget = 10_000;
                                let with_len: Vec<(&str, usize)> =
                                    CORNERS.iter().map(|c| (*c, c.len())).collect();
                                let dym = name
                                    .and_then(|s| suggest(s, &with_len, &mut budget))
                                    .map_or(String::new(), |c| format!("; did you mean \"{c}\"?"));
                                return Err(self.err(
                                    it.span,
                                    ParseErrorKind::WrongArgKind,
                                    format!(
                                        "{fname}: argument {n} `{}` must be {expected}, found {} \
                                         in the list{dym}",
                                        p.name,
                                        describe_expr(it, &self.vars)
                                    ),
                                ));
                            }
                        }
                    }
                }
                ExprKind::Var(_) if kind == ValueKind::List => {}
                _ => return Err(bad(found())),
            },
            ParamKind::Choice(choices) => match a.as_str() {
                Some(s) if choices.contains(&s) => {}
                Some(s) => {
                    let mut budget = 10_000;
                    let with_len: Vec<(&str, usize)> =
                        choices.iter().map(|c| (*c, c.chars().count())).collect();
                    let dym = suggest(s, &with_len, &mut budget)
                        .map_or(String::new(), |c| format!("; did you mean \"{c}\"?"));
                    return Err(bad(format!("{}{dym}", found())));
                }
                None if matches!(a.kind, ExprKind::Var(_)) && kind == ValueKind::Str => {}
                None => return Err(bad(found())),
            },
            ParamKind::Labels(k) => match &a.kind {
                ExprKind::List(items) => {
                    if items.len() != k {
                        return Err(bad(found()));
                    }
                    for it in items {
                        if self.kind_of(it) != ValueKind::Str {
                            return Err(self.err(
                                it.span,
                                ParseErrorKind::WrongArgKind,
                                format!(
                                    "{fname}: argument {n} `{}` must be {expected}, found {} in \
                                     the list",
                                    p.name,
                                    describe_expr(it, &self.vars)
                                ),
                            ));
                        }
                    }
                }
                ExprKind::Var(_) if kind == ValueKind::List => {}
                _ => return Err(bad(found())),
            },
            ParamKind::Constraint => return Err(bad(found())),
        }
        Ok(())
    }

    /// One term of `constrain(...)`.
    fn constraint(&mut self) -> PResult<Constraint> {
        let (name, sp) = match self.peek().clone() {
            Tok::Ident(s) if *self.peek_at(1) == Tok::LParen => (s, self.bump().1),
            _ => {
                let v = self.value()?;
                return Err(self.err(
                    v.span,
                    ParseErrorKind::WrongArgKind,
                    format!(
                        "constrain: each argument must be a constraint ({}(...)), found {}",
                        ConstraintKind::NAMES.join("(...), "),
                        describe_expr(&v, &self.vars)
                    ),
                ));
            }
        };
        if !ConstraintKind::NAMES.contains(&name.as_str()) {
            let dym = self.did_you_mean(&name, &ConstraintKind::NAMES);
            return Err(self.err(
                sp,
                ParseErrorKind::UnknownConstraint,
                format!(
                    "unknown constraint `{}` (known: {}){dym}",
                    clip(&name),
                    ConstraintKind::NAMES.join(", ")
                ),
            ));
        }
        let args = self.call_args(&name, |p| p.value())?;
        let close = self.prev_span();
        const AXIS: ParamKind = ParamKind::Choice(&["vertical", "horizontal"]);
        let params: &[Param] = match name.as_str() {
            "align" => &[
                Param {
                    name: "a",
                    kind: ParamKind::Str,
                    optional: false,
                },
                Param {
                    name: "b",
                    kind: ParamKind::Str,
                    optional: false,
                },
                Param {
                    name: "axis",
                    kind: AXIS,
                    optional: false,
                },
            ],
            "symmetric" => &[
                Param {
                    name: "label",
                    kind: ParamKind::Str,
                    optional: false,
                },
                Param {
                    name: "axis",
                    kind: AXIS,
                    optional: false,
                },
            ],
            "boundaryDistance" => &[
                Param {
                    name: "label",
                    kind: ParamKind::Str,
                    optional: false,
                },
                Param {
                    name: "min",
                    kind: ParamKind::Number,
                    optional: false,
                },
            ],
            _ => &[],
        };
        if name == "noIntersection" {
            for (i, a) in args.iter().enumerate() {
                let p = Param {
                    name: "label",
                    kind: ParamKind::Str,
                    optional: true,
                };
                self.check_arg(&name, i + 1, &p, a)?;
            }
        } else {
            self.check_args(&name, params, &args, close)?;
        }
        let axis_of = |e: &Expr| -> PResult<ConstraintAxis> {
            match e.as_str() {
                Some("vertical") => Ok(ConstraintAxis::Vertical),
                Some("horizontal") => Ok(ConstraintAxis::Horizontal),
                _ => Err(self.err(
                    e.span,
                    ParseErrorKind::WrongArgKind,
                    format!(
                        "{name}: the axis must be written \"vertical\" or \"horizontal\", found {}",
                        describe_expr(e, &self.vars)
                    ),
                )),
            }
        };
        let mut it = args.into_iter();
        let mut next = || {
            it.next()
                .ok_or_else(|| self.err(close, ParseErrorKind::WrongArgCount, "missing argument"))
        };
        let kind = match name.as_str() {
            "align" => {
                let (a, b, ax) = (next()?, next()?, next()?);
                ConstraintKind::Align {
                    a,
                    b,
                    axis: axis_of(&ax)?,
                }
            }
            "symmetric" => {
                let (label, ax) = (next()?, next()?);
                ConstraintKind::Symmetric {
                    label,
                    axis: axis_of(&ax)?,
                }
            }
            "boundaryDistance" => {
                let (label, min) = (next()?, next()?);
                ConstraintKind::BoundaryDistance { label, min }
            }
            _ => ConstraintKind::NoIntersection {
                labels: it.collect(),
            },
        };
        Ok(Constraint {
            kind,
            span: sp.to(close),
        })
    }

    /// The kind an expression evaluates to (variables by their assigned kind).
    fn kind_of(&self, e: &Expr) -> ValueKind {
        match &e.kind {
            ExprKind::Number(_) | ExprKind::Neg(_) | ExprKind::Binary(..) => ValueKind::Number,
            ExprKind::Str(_) | ExprKind::BareWord(_) => ValueKind::Str,
            ExprKind::List(_) => ValueKind::List,
            ExprKind::Var(v) => self.vars.get(v).copied().unwrap_or(ValueKind::Str),
        }
    }

    /// A value: an expression; a lone unknown identifier is a bare word.
    fn value(&mut self) -> PResult<Expr> {
        self.expr()
    }

    /// Checks that `e` is a number, as an operand of arithmetic.
    fn numeric(&mut self, e: &Expr) -> PResult<()> {
        if let ExprKind::BareWord(w) = &e.kind {
            let names: Vec<&str> = self.vars.keys().map(String::as_str).collect();
            let names: Vec<String> = names.iter().map(|s| s.to_string()).collect();
            let refs: Vec<&str> = names.iter().map(String::as_str).collect();
            let dym = self.did_you_mean(w, &refs);
            return Err(self.err(
                e.span,
                ParseErrorKind::UnknownVariable,
                format!(
                    "`{}` is not a variable assigned before this line{dym}",
                    clip(w)
                ),
            ));
        }
        if self.kind_of(e) != ValueKind::Number {
            return Err(self.err(
                e.span,
                ParseErrorKind::NotANumber,
                format!(
                    "arithmetic needs numbers, found {}",
                    describe_expr(e, &self.vars)
                ),
            ));
        }
        Ok(())
    }

    fn expr(&mut self) -> PResult<Expr> {
        let mut lhs = self.term()?;
        let depth = self.nesting;
        while matches!(self.peek(), Tok::Plus | Tok::Minus) {
            let (t, sp) = self.bump();
            self.enter(sp)?;
            let rhs = self.term()?;
            self.numeric(&lhs)?;
            self.numeric(&rhs)?;
            let op = if t == Tok::Plus {
                BinOp::Add
            } else {
                BinOp::Sub
            };
            let span = lhs.span.to(rhs.span);
            lhs = Expr {
                kind: ExprKind::Binary(op, Box::new(lhs), Box::new(rhs)),
                span,
            };
        }
        self.nesting = depth;
        Ok(lhs)
    }

    fn term(&mut self) -> PResult<Expr> {
        let mut lhs = self.unary()?;
        let depth = self.nesting;
        // A `/` before `[`, or after a string or a list, is no division but a step separator
        // after a filter whose `]` is missing (`[label=="a" / [label=="b"]`): the caller then
        // reports the unclosed `[`.
        while matches!(self.peek(), Tok::Star)
            || (*self.peek() == Tok::Slash
                && *self.peek_at(1) != Tok::LBracket
                && !matches!(lhs.kind, ExprKind::Str(_) | ExprKind::List(_)))
        {
            let (t, sp) = self.bump();
            self.enter(sp)?;
            let rhs = self.unary()?;
            self.numeric(&lhs)?;
            self.numeric(&rhs)?;
            let op = if t == Tok::Star {
                BinOp::Mul
            } else {
                BinOp::Div
            };
            let span = lhs.span.to(rhs.span);
            lhs = Expr {
                kind: ExprKind::Binary(op, Box::new(lhs), Box::new(rhs)),
                span,
            };
        }
        self.nesting = depth;
        Ok(lhs)
    }

    fn unary(&mut self) -> PResult<Expr> {
        let sp = self.span();
        match self.peek().clone() {
            Tok::Minus => {
                self.bump();
                self.enter(sp)?;
                let e = self.unary();
                self.nesting -= 1;
                let e = e?;
                self.numeric(&e)?;
                let span = sp.to(e.span);
                Ok(Expr {
                    kind: ExprKind::Neg(Box::new(e)),
                    span,
                })
            }
            Tok::Num(v) => {
                self.bump();
                Ok(Expr {
                    kind: ExprKind::Number(v),
                    span: sp,
                })
            }
            Tok::Str(s) => {
                self.bump();
                Ok(Expr {
                    kind: ExprKind::Str(s),
                    span: sp,
                })
            }
            Tok::Ident(s) => {
                self.bump();
                if *self.peek() == Tok::LParen {
                    return Err(self.err(
                        sp,
                        ParseErrorKind::UnexpectedToken,
                        format!("`{}(...)` is not a value here", clip(&s)),
                    ));
                }
                let kind = if self.vars.contains_key(&s) {
                    ExprKind::Var(s)
                } else {
                    ExprKind::BareWord(s)
                };
                Ok(Expr { kind, span: sp })
            }
            Tok::LParen => {
                self.bump();
                self.enter(sp)?;
                let e = self.expr();
                self.nesting -= 1;
                let e = e?;
                if *self.peek() != Tok::RParen {
                    return Err(self.unclosed_or(
                        sp,
                        "(",
                        ")",
                        &[
                            Tok::Semi,
                            Tok::RBrace,
                            Tok::LBrace,
                            Tok::RBracket,
                            Tok::Arrow,
                        ],
                    ));
                }
                let close = self.bump().1;
                Ok(Expr {
                    kind: e.kind,
                    span: sp.to(close),
                })
            }
            Tok::LBracket => {
                self.bump();
                self.enter(sp)?;
                let r = self.list_rest(sp);
                self.nesting -= 1;
                r
            }
            Tok::Ellipsis => Err(self.err(
                sp,
                ParseErrorKind::Elided,
                "a value elided with `...` (as the seed prints Fig. 13): write it",
            )),
            _ => Err(self.unexpected("a value (a number, a string, a variable or a list)")),
        }
    }

    /// The items and `]` of a list whose `[` is at `open`.
    fn list_rest(&mut self, open: Span) -> PResult<Expr> {
        let mut items = Vec::new();
        if *self.peek() == Tok::RBracket {
            let close = self.bump().1;
            return Ok(Expr {
                kind: ExprKind::List(items),
                span: open.to(close),
            });
        }
        let stops = [Tok::Semi, Tok::RBrace, Tok::LBrace, Tok::RParen, Tok::Arrow];
        loop {
            items.push(self.expr()?);
            match self.peek() {
                Tok::Comma => {
                    self.bump();
                }
                Tok::RBracket => {
                    let close = self.bump().1;
                    return Ok(Expr {
                        kind: ExprKind::List(items),
                        span: open.to(close),
                    });
                }
                _ => return Err(self.unclosed_or(open, "[", "]", &stops)),
            }
        }
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

/// Lists what parses but is suspicious in `program` (parsed from `src`, named `file`): the `>`
/// arrow, bare words taken as strings, groupings in steps that select no cells, two groupings
/// in one step, a `roundShape` not right after an `addVolume`, `type`/`dim`/`side` compared with
/// values they never take, a program without rules. In file order.
pub fn check(program: &Program, src: &str, file: &str) -> Vec<Warning> {
    let mut out = Vec::new();
    let mut warn = |span: Span, kind: WarningKind, message: String| {
        out.push(Warning {
            file: file.to_string(),
            line: span.line,
            col: span.col,
            kind,
            message,
            line_text: line_at(src, span.offset),
        });
    };
    let mut last_action: Option<ActionKind> = None;
    let mut any_rule = false;
    for c in &program.commands {
        match c {
            Command::Assign { value, .. } => bare_words(value, &mut warn),
            Command::Rule(r) => {
                any_rule = true;
                for step in &r.selection.steps {
                    let cells = step.topo == Some(Topo::Cell)
                        || step.filters.iter().any(|f| {
                            matches!(f, Filter::Compare { attr: Attr::Type, op: Cmp::Eq, value, .. }
                                if value.as_str() == Some("cell"))
                        });
                    let groups: Vec<(Grouping, Span)> = step
                        .filters
                        .iter()
                        .filter_map(|f| match f {
                            Filter::Group { grouping, span } => Some((*grouping, *span)),
                            _ => None,
                        })
                        .collect();
                    for f in &step.filters {
                        match f {
                            Filter::Compare { attr, value, .. } => {
                                bare_words(value, &mut warn);
                                let known: &[&str] = match attr {
                                    Attr::Type => &["virtual", "construction", "cell"],
                                    Attr::Dim => &["2D", "3D"],
                                    Attr::Side => &["front", "back", "left", "right", "side"],
                                    _ => &[],
                                };
                                if let Some(s) = value.as_str() {
                                    if !known.is_empty() && !known.contains(&s) {
                                        warn(
                                            value.span,
                                            WarningKind::UnknownValue,
                                            format!(
                                                "`{}` is never \"{}\" (it is one of {}): this \
                                                 selector selects nothing",
                                                attr.name(),
                                                clip(s),
                                                quoted_list(known)
                                            ),
                                        );
                                    }
                                }
                            }
                            Filter::In { set, .. } => match set {
                                IndexSet::List(items) => {
                                    for i in items {
                                        bare_words(i, &mut warn);
                                    }
                                }
                                IndexSet::IndexRange(a, b) | IndexSet::RowRange(a, b) => {
                                    bare_words(a, &mut warn);
                                    bare_words(b, &mut warn);
                                }
                            },
                            _ => {}
                        }
                    }
                    if let Some(&(g, sp)) = groups.first() {
                        if !cells {
                            warn(
                                sp,
                                WarningKind::GroupingOutsideCells,
                                format!(
                                    "`{}` groups the cells of a virtual grid, but this step \
                                     selects no cells: add `[type == \"cell\"]` or start it with \
                                     `cell()`",
                                    g.name()
                                ),
                            );
                        }
                    }
                    if let Some(&(g, sp)) = groups.get(1) {
                        warn(
                            sp,
                            WarningKind::SeveralGroupings,
                            format!(
                                "a second grouping `{}` in one step, after `{}`: each regroups \
                                 the cells the previous one made",
                                g.name(),
                                groups[0].0.name()
                            ),
                        );
                    }
                }
                if r.arrow == Arrow::Gt {
                    warn(
                        r.arrow_span,
                        WarningKind::LegacyArrow,
                        "`>` separates the selection from the actions as Brito's listing \
                         prints it; write `->`"
                            .into(),
                    );
                }
                for a in &r.actions {
                    for e in &a.args {
                        bare_words(e, &mut warn);
                    }
                    for c in &a.constraints {
                        match &c.kind {
                            ConstraintKind::Align { a, b, .. } => {
                                bare_words(a, &mut warn);
                                bare_words(b, &mut warn);
                            }
                            ConstraintKind::Symmetric { label, .. } => bare_words(label, &mut warn),
                            ConstraintKind::BoundaryDistance { label, min } => {
                                bare_words(label, &mut warn);
                                bare_words(min, &mut warn);
                            }
                            ConstraintKind::NoIntersection { labels } => {
                                for l in labels {
                                    bare_words(l, &mut warn);
                                }
                            }
                        }
                    }
                    if a.name == ActionKind::RoundShape
                        && last_action != Some(ActionKind::AddVolume)
                    {
                        warn(
                            a.span,
                            WarningKind::RoundShapeWithoutVolume,
                            "roundShape rounds the volume made by the `addVolume` right before \
                             it, and the previous action is not an addVolume"
                                .into(),
                        );
                    }
                    last_action = Some(a.name);
                }
            }
        }
    }
    if !any_rule {
        warn(
            Span {
                line: 1,
                col: 1,
                offset: 0,
                len: 0,
            },
            WarningKind::NoRules,
            "the program has no rule `{< selection > -> actions}`".into(),
        );
    }
    out
}

/// Warns on every bare word of `e` (walks lists; arithmetic holds none).
fn bare_words(e: &Expr, warn: &mut impl FnMut(Span, WarningKind, String)) {
    match &e.kind {
        ExprKind::BareWord(w) => warn(
            e.span,
            WarningKind::BareWord,
            format!(
                "`{0}` is no variable assigned before this line: taken as the string \"{0}\"; \
                 write it in double quotes",
                clip(w)
            ),
        ),
        ExprKind::List(items) => {
            for i in items {
                bare_words(i, warn);
            }
        }
        _ => {}
    }
}
