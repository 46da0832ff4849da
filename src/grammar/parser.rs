//! Lexer and recursive-descent parser for rule files.
//!
//! Grammar (whitespace and newlines are free; `#` and `//` start a comment to end of line,
//! except that a `#` right after `=` starts a hex colour such as `#a0b0c0`):
//!
//! ```text
//! file      := rule*
//! rule      := IDENT '->' body ('=' NUMBER)?
//! body      := op '(' args ')' '{' succs '}'       -- an operation
//!            | '{' succs '}'                        -- relabel, with attributes
//!            | succ                                 -- relabel: `gback -> wall`
//! succs     := succ ('|' succ)*
//! succ      := (SELECTOR ':')? IDENT (':' attr (',' attr)*)?   -- SELECTOR only for comp
//! attr      := IDENT '=' (IDENT | NUMBER | '-' NUMBER | HEX | STRING)
//! op        := extrude | split | rsplit | repeat | comp | S | T | R   (s, t, r also accepted)
//! expr      := term (('+'|'-') term)* ; term := unary (('*'|'/') unary)*
//! unary     := '-' unary | NUMBER | 'sx' | 'sy' | 'sz' | 'rand' '(' expr ',' expr ')'
//!            | IDENT (a numeric attribute) | '(' expr ')'
//! ```
//!
//! A rule therefore ends where the next `IDENT ->` begins, or at end of file. Numbers use a dot
//! as the decimal separator: a comma always separates arguments.

use std::collections::HashMap;
use std::fmt;
use std::sync::Arc;

use super::ast::{
    AttrValue, Axis, BinOp, Expr, Op, Rule, RuleSet, Selector, Span, SplitKind, Successor,
};

/// What went wrong while parsing, for programmatic checks (the message says it in words).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ParseErrorKind {
    /// A character that starts no token.
    BadCharacter,
    /// A token where another was expected.
    UnexpectedToken,
    /// An operation name that is not one of extrude, split, rsplit, repeat, comp, S, T, R.
    UnknownOperation,
    /// A function in an expression other than `rand`.
    UnknownFunction,
    /// An operation or function called with the wrong number of arguments.
    WrongArgCount,
    /// An axis argument that is not X, Y or Z (or not allowed for that operation).
    BadAxis,
    /// A comp selector that is not one of front back left right side others top bottom.
    BadSelector,
    /// The number of sizes of a split/rsplit/repeat differs from the number of successors.
    SizeCountMismatch,
    /// `= prob` not followed by a number in [0, 1].
    BadProbability,
    /// A `{` or `(` never closed.
    Unclosed,
    /// A file with no rule.
    NoRules,
    /// An expression nested deeper than [`MAX_EXPR_DEPTH`] (parentheses, unary minus, `rand`
    /// and chains of binary operators together).
    TooDeep,
    /// A rule file longer than [`MAX_SOURCE_BYTES`].
    TooLarge,
}

/// The deepest expression a rule file may hold: its tree depth, counting each `(`, unary `-`,
/// `rand(...)` and binary operator on the way down. Real rules nest a few levels. The cap bounds
/// the parser's recursion and every later walk of an expression (evaluation, lint, drop), so a
/// hostile or generated file gets an error at its place instead of a stack overflow.
pub const MAX_EXPR_DEPTH: usize = 128;

/// The longest rule file [`parse`] (and [`read_source`]) takes, in bytes. Rule files are a few
/// kilobytes; parsing holds about 100 bytes per byte of input (tokens, spans, symbols), so the
/// cap keeps one file under half a gigabyte however it is written (a 40 MB file of `|a` ran out
/// of a 2 GiB address space while lexing). `kb check` reads the rulesets a KB names with the
/// same cap.
pub const MAX_SOURCE_BYTES: usize = 4 * 1024 * 1024;

/// Reads a rule file, refusing one over [`MAX_SOURCE_BYTES`] without reading past the cap (an
/// `InvalidData` error that says so); an unreadable or non-UTF-8 file is the same error as
/// `std::fs::read_to_string` gives.
pub fn read_source(path: &std::path::Path) -> std::io::Result<String> {
    read_capped(std::fs::File::open(path)?)
}

/// [`read_source`] of an open file (or any reader): at most [`MAX_SOURCE_BYTES`].
pub(crate) fn read_capped(r: impl std::io::Read) -> std::io::Result<String> {
    use std::io::Read;
    let mut text = String::new();
    r.take(MAX_SOURCE_BYTES as u64 + 1)
        .read_to_string(&mut text)?;
    if text.len() > MAX_SOURCE_BYTES {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!(
                "more than {MAX_SOURCE_BYTES} bytes, the cap on rule files (rule files are a few \
                 kilobytes)"
            ),
        ));
    }
    Ok(text)
}

/// A parse error: `file:line:col: message`, then the offending line and a caret under the place.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub struct GrammarError {
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

/// Characters of the offending line shown on each side of the place when the line is long.
const CONTEXT_CHARS: usize = 80;

impl fmt::Display for GrammarError {
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

/// Writes `file:line:col: message`, then the offending line (a window around the place when the
/// line is long) and a caret under the place: the layout of every located message of the
/// languages (the grammar's and SELEX's errors and warnings).
pub(crate) fn fmt_located(
    f: &mut fmt::Formatter<'_>,
    file: &str,
    line: u32,
    col: u32,
    message: &str,
    line_text: &str,
) -> fmt::Result {
    writeln!(f, "{file}:{line}:{col}: {message}")?;
    // A long line (a generated file, a hostile one) is shown as a window around the place.
    let chars: Vec<char> = line_text.chars().collect();
    let at = (col.saturating_sub(1) as usize).min(chars.len());
    let (from, to) = if chars.len() > 2 * CONTEXT_CHARS {
        let from = at.saturating_sub(CONTEXT_CHARS);
        (from, (at + CONTEXT_CHARS).min(chars.len()))
    } else {
        (0, chars.len())
    };
    let (head, tail) = (
        if from > 0 { "…" } else { "" },
        if to < chars.len() { "…" } else { "" },
    );
    let shown: String = chars[from..to].iter().collect();
    writeln!(f, "{head}{shown}{tail}")?;
    // The caret line reproduces tabs so that it lines up under the offending character.
    let pad: String = std::iter::repeat_n(' ', head.chars().count())
        .chain(
            chars[from..at]
                .iter()
                .map(|&c| if c == '\t' { '\t' } else { ' ' }),
        )
        .collect();
    write!(f, "{pad}^")
}

#[derive(Clone, Debug, PartialEq)]
enum Tok {
    Ident(String),
    Num(f64),
    Hex(String),
    Str(String),
    Arrow,
    LParen,
    RParen,
    LBrace,
    RBrace,
    Pipe,
    Colon,
    Comma,
    Eq,
    Plus,
    Minus,
    Star,
    Slash,
    Eof,
}

impl Tok {
    fn describe(&self) -> String {
        match self {
            Tok::Ident(s) => format!("`{s}`"),
            Tok::Num(v) => format!("number {v}"),
            Tok::Hex(s) => format!("`{s}`"),
            Tok::Str(s) => format!("string \"{s}\""),
            Tok::Arrow => "`->`".into(),
            Tok::LParen => "`(`".into(),
            Tok::RParen => "`)`".into(),
            Tok::LBrace => "`{`".into(),
            Tok::RBrace => "`}`".into(),
            Tok::Pipe => "`|`".into(),
            Tok::Colon => "`:`".into(),
            Tok::Comma => "`,`".into(),
            Tok::Eq => "`=`".into(),
            Tok::Plus => "`+`".into(),
            Tok::Minus => "`-`".into(),
            Tok::Star => "`*`".into(),
            Tok::Slash => "`/`".into(),
            Tok::Eof => "end of file".into(),
        }
    }
}

struct Ctx<'a> {
    src: &'a str,
    file: &'a str,
}

impl Ctx<'_> {
    fn err(&self, span: Span, kind: ParseErrorKind, message: impl Into<String>) -> GrammarError {
        let line_text = self
            .src
            .lines()
            .nth(span.line.saturating_sub(1) as usize)
            .unwrap_or("");
        GrammarError {
            file: self.file.to_string(),
            line: span.line,
            col: span.col,
            kind,
            message: message.into(),
            line_text: line_text.trim_end_matches('\r').to_string(),
        }
    }
}

fn lex(ctx: &Ctx<'_>) -> Result<Vec<(Tok, Span)>, GrammarError> {
    let src = ctx.src;
    let mut out: Vec<(Tok, Span)> = Vec::new();
    let mut it = src.char_indices().peekable();
    let (mut line, mut col) = (1u32, 1u32);
    while let Some(&(off, c)) = it.peek() {
        let start = Span {
            line,
            col,
            offset: off,
            len: c.len_utf8(),
        };
        let prev_is_eq = matches!(out.last(), Some((Tok::Eq, _)));
        // Advances one character, keeping line/column up to date.
        macro_rules! bump {
            () => {{
                let (_, ch) = it.next().unwrap_or((0, '\0'));
                if ch == '\n' {
                    line += 1;
                    col = 1;
                } else {
                    col += 1;
                }
                ch
            }};
        }
        let peek2 = |i: usize| src[i..].chars().nth(1);
        if c.is_whitespace() {
            bump!();
            continue;
        }
        if (c == '#' && !prev_is_eq) || (c == '/' && peek2(off) == Some('/')) {
            while let Some(&(_, ch)) = it.peek() {
                if ch == '\n' {
                    break;
                }
                bump!();
            }
            continue;
        }
        let tok = if c.is_ascii_alphabetic() || c == '_' {
            let mut s = String::new();
            while let Some(&(_, ch)) = it.peek() {
                if ch.is_ascii_alphanumeric() || ch == '_' {
                    s.push(ch);
                    bump!();
                } else {
                    break;
                }
            }
            Tok::Ident(s)
        } else if c.is_ascii_digit() || (c == '.' && peek2(off).is_some_and(|d| d.is_ascii_digit()))
        {
            let mut end = off;
            while let Some(&(i, ch)) = it.peek() {
                let exp_sign =
                    (ch == '+' || ch == '-') && matches!(src[..i].chars().last(), Some('e' | 'E'));
                if ch.is_ascii_digit() || ch == '.' || ch == 'e' || ch == 'E' || exp_sign {
                    end = i + ch.len_utf8();
                    bump!();
                } else {
                    break;
                }
            }
            let text = &src[off..end];
            match text.parse::<f64>() {
                Ok(v) if v.is_finite() => Tok::Num(v),
                _ => {
                    let span = Span {
                        len: end - off,
                        ..start
                    };
                    return Err(ctx.err(
                        span,
                        ParseErrorKind::BadCharacter,
                        format!("malformed number `{text}`"),
                    ));
                }
            }
        } else if c == '#' {
            bump!();
            let mut s = String::from("#");
            while let Some(&(_, ch)) = it.peek() {
                if ch.is_ascii_alphanumeric() {
                    s.push(ch);
                    bump!();
                } else {
                    break;
                }
            }
            Tok::Hex(s)
        } else if c == '"' {
            bump!();
            let mut s = String::new();
            loop {
                match it.peek() {
                    Some(&(_, '"')) => {
                        bump!();
                        break;
                    }
                    Some(&(_, '\n')) | None => {
                        return Err(ctx.err(start, ParseErrorKind::Unclosed, "unclosed string"));
                    }
                    Some(&(_, ch)) => {
                        s.push(ch);
                        bump!();
                    }
                }
            }
            Tok::Str(s)
        } else {
            let t = match c {
                '-' if peek2(off) == Some('>') => {
                    bump!();
                    Tok::Arrow
                }
                '(' => Tok::LParen,
                ')' => Tok::RParen,
                '{' => Tok::LBrace,
                '}' => Tok::RBrace,
                '|' => Tok::Pipe,
                ':' => Tok::Colon,
                ',' => Tok::Comma,
                '=' => Tok::Eq,
                '+' => Tok::Plus,
                '-' => Tok::Minus,
                '*' => Tok::Star,
                '/' => Tok::Slash,
                _ => {
                    return Err(ctx.err(
                        start,
                        ParseErrorKind::BadCharacter,
                        format!("unexpected character `{c}`"),
                    ));
                }
            };
            bump!();
            t
        };
        let end = it.peek().map_or(src.len(), |&(i, _)| i);
        out.push((
            tok,
            Span {
                len: end - off,
                ..start
            },
        ));
    }
    // End of file is reported just after the last token, on its line.
    let eof = match out.last() {
        Some((_, last)) => {
            let chars = src[last.offset..last.offset + last.len].chars().count() as u32;
            Span {
                col: last.col + chars,
                offset: last.offset + last.len,
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

struct Parser<'a> {
    ctx: Ctx<'a>,
    toks: Vec<(Tok, Span)>,
    pos: usize,
    rs: RuleSet,
    /// Unary levels open (`-`, `(`, `rand(`): the parser's recursion depth.
    nesting: usize,
}

type PResult<T> = Result<T, GrammarError>;

impl Parser<'_> {
    fn peek(&self) -> &Tok {
        &self.toks[self.pos.min(self.toks.len() - 1)].0
    }
    fn peek_at(&self, k: usize) -> &Tok {
        &self.toks[(self.pos + k).min(self.toks.len() - 1)].0
    }
    fn span(&self) -> Span {
        self.toks[self.pos.min(self.toks.len() - 1)].1
    }
    fn bump(&mut self) -> (Tok, Span) {
        let t = self.toks[self.pos.min(self.toks.len() - 1)].clone();
        if self.pos < self.toks.len() - 1 {
            self.pos += 1;
        }
        t
    }
    fn unexpected(&self, expected: &str) -> GrammarError {
        let msg = format!("expected {expected}, found {}", self.peek().describe());
        self.ctx
            .err(self.span(), ParseErrorKind::UnexpectedToken, msg)
    }
    fn expect(&mut self, t: Tok, what: &str) -> PResult<Span> {
        if *self.peek() == t {
            Ok(self.bump().1)
        } else {
            Err(self.unexpected(what))
        }
    }
    /// Whether the parser stands at the start of a rule (`IDENT ->`).
    fn at_rule_start(&self) -> bool {
        matches!(self.peek(), Tok::Ident(_)) && *self.peek_at(1) == Tok::Arrow
    }

    fn ident(&mut self, what: &str) -> PResult<(String, Span)> {
        match self.peek().clone() {
            Tok::Ident(s) => {
                let sp = self.bump().1;
                Ok((s, sp))
            }
            _ => Err(self.unexpected(what)),
        }
    }

    fn file(&mut self) -> PResult<()> {
        while *self.peek() != Tok::Eof {
            if !self.at_rule_start() {
                return Err(self.unexpected("a rule `name -> ...`"));
            }
            self.rule()?;
            if !(self.at_rule_start() || *self.peek() == Tok::Eof) {
                return Err(self
                    .unexpected("`|`, `}`, `= probability`, a new rule `name ->` or end of file"));
            }
        }
        if self.rs.rules.is_empty() {
            return Err(self.ctx.err(
                self.span(),
                ParseErrorKind::NoRules,
                "the rule file has no rule",
            ));
        }
        Ok(())
    }

    fn rule(&mut self) -> PResult<()> {
        let (pred, span) = self.ident("a predecessor symbol")?;
        self.expect(Tok::Arrow, "`->`")?;
        let pred = self.rs.intern(&pred);
        let (op, succs) = match (self.peek().clone(), self.peek_at(1).clone()) {
            (Tok::Ident(name), Tok::LParen) => {
                let op_span = self.bump().1;
                let open = self.bump().1;
                let args = self.args(open)?;
                let op = self.make_op(&name, op_span, args)?;
                let is_comp = op == Op::Comp;
                if *self.peek() != Tok::LBrace {
                    return Err(self.unexpected("`{` and the successors"));
                }
                let brace = self.span();
                let succs = self.braced_succs(is_comp)?;
                if let Op::Split { kind, sizes, .. } = &op {
                    if sizes.len() != succs.len() {
                        let msg = format!(
                            "{} has {} size(s) but {} successor(s); give one size per successor",
                            kind.name(),
                            sizes.len(),
                            succs.len()
                        );
                        return Err(self.ctx.err(brace, ParseErrorKind::SizeCountMismatch, msg));
                    }
                }
                (op, succs)
            }
            (Tok::LBrace, _) => (Op::Relabel, self.braced_succs(false)?),
            (Tok::Ident(_), _) => (Op::Relabel, vec![self.succ(false)?]),
            _ => return Err(self.unexpected("an operation, `{` or a successor symbol")),
        };
        let prob = if *self.peek() == Tok::Eq {
            self.bump();
            let sp = self.span();
            match self.peek().clone() {
                Tok::Num(v) if (0.0..=1.0).contains(&v) => {
                    self.bump();
                    Some(v)
                }
                Tok::Num(v) => {
                    return Err(self.ctx.err(
                        sp,
                        ParseErrorKind::BadProbability,
                        format!("probability {v} is not in [0, 1]"),
                    ))
                }
                t => {
                    return Err(self.ctx.err(
                        sp,
                        ParseErrorKind::BadProbability,
                        format!(
                            "expected a probability (a number in [0, 1]), found {}",
                            t.describe()
                        ),
                    ))
                }
            }
        } else {
            None
        };
        self.rs.rules.push(Rule {
            pred,
            op,
            succs,
            prob,
            span,
        });
        Ok(())
    }

    /// Parses comma-separated arguments after `(` up to the matching `)`.
    fn args(&mut self, open: Span) -> PResult<Vec<(Expr, Span)>> {
        Ok(self
            .args_with_depth(open)?
            .into_iter()
            .map(|(e, sp, _)| (e, sp))
            .collect())
    }

    /// The arguments of a call, each with its tree depth.
    fn args_with_depth(&mut self, open: Span) -> PResult<Vec<(Expr, Span, usize)>> {
        let mut args = Vec::new();
        if *self.peek() == Tok::RParen {
            self.bump();
            return Ok(args);
        }
        loop {
            let sp = self.span();
            let (e, d) = self.expr(open)?;
            args.push((e, sp, d));
            match self.peek() {
                Tok::Comma => {
                    self.bump();
                }
                Tok::RParen => {
                    self.bump();
                    return Ok(args);
                }
                _ => return Err(self.unclosed_or(open, "`(`", "`,` or `)`")),
            }
        }
    }

    /// At a token that cannot continue a bracketed list: reports the bracket as unclosed when
    /// the list ran into the next rule or the end of file, else an unexpected token.
    fn unclosed_or(&self, open: Span, bracket: &str, expected: &str) -> GrammarError {
        if *self.peek() == Tok::Eof || self.at_rule_start() {
            self.ctx.err(
                open,
                ParseErrorKind::Unclosed,
                format!("unclosed {bracket}"),
            )
        } else {
            self.unexpected(expected)
        }
    }

    fn axis_of(&self, e: &Expr, sp: Span, allowed: &[Axis], op: &str) -> PResult<Axis> {
        let axis = match e {
            Expr::Attr(name, _) => match &**name {
                "X" | "x" => Some(Axis::X),
                "Y" | "y" => Some(Axis::Y),
                "Z" | "z" => Some(Axis::Z),
                _ => None,
            },
            _ => None,
        };
        match axis {
            Some(a) if allowed.contains(&a) => Ok(a),
            Some(a) => Err(self.ctx.err(
                sp,
                ParseErrorKind::BadAxis,
                format!(
                    "{op} does not support axis {} yet (allowed: {})",
                    a.name(),
                    names(allowed)
                ),
            )),
            None => Err(self.ctx.err(
                sp,
                ParseErrorKind::BadAxis,
                format!(
                    "{op} expects an axis ({}) as its first argument",
                    names(allowed)
                ),
            )),
        }
    }

    fn make_op(&mut self, name: &str, sp: Span, args: Vec<(Expr, Span)>) -> PResult<Op> {
        let n = args.len();
        let count_err = |p: &Self, expect: &str| {
            p.ctx.err(
                sp,
                ParseErrorKind::WrongArgCount,
                format!(
                    "{name} expects {expect}, got {n} argument{}",
                    if n == 1 { "" } else { "s" }
                ),
            )
        };
        let three = |p: &Self, args: Vec<(Expr, Span)>| -> PResult<[Expr; 3]> {
            let mut it = args.into_iter().map(|a| a.0);
            match (it.next(), it.next(), it.next(), it.next()) {
                (Some(a), Some(b), Some(c), None) => Ok([a, b, c]),
                _ => Err(count_err(p, "3 arguments (x, y, z)")),
            }
        };
        Ok(match name {
            "extrude" => {
                if n != 1 {
                    return Err(count_err(self, "1 argument (the height)"));
                }
                Op::Extrude(args.into_iter().map(|a| a.0).next().unwrap_or(Expr::Num(0.0)))
            }
            "split" | "rsplit" | "repeat" => {
                let kind = match name {
                    "split" => SplitKind::Absolute,
                    "rsplit" => SplitKind::Relative,
                    _ => SplitKind::Repeat,
                };
                if n < 2 {
                    return Err(count_err(self, "an axis and at least one size"));
                }
                let mut it = args.into_iter();
                let (ae, asp) = it.next().unwrap_or((Expr::Num(0.0), sp));
                let axis = self.axis_of(&ae, asp, &[Axis::X, Axis::Y, Axis::Z], name)?;
                Op::Split { kind, axis, sizes: it.map(|a| a.0).collect() }
            }
            "comp" => {
                if n != 0 {
                    return Err(count_err(self, "no argument"));
                }
                Op::Comp
            }
            "S" | "s" => Op::Scale(three(self, args)?),
            "T" | "t" => Op::Translate(three(self, args)?),
            "R" | "r" => {
                if n != 2 {
                    return Err(count_err(self, "2 arguments (axis, degrees)"));
                }
                let mut it = args.into_iter();
                let (ae, asp) = it.next().unwrap_or((Expr::Num(0.0), sp));
                let axis = self.axis_of(&ae, asp, &[Axis::Z], "R")?;
                Op::Rotate(axis, it.next().map_or(Expr::Num(0.0), |a| a.0))
            }
            _ => {
                return Err(self.ctx.err(
                    sp,
                    ParseErrorKind::UnknownOperation,
                    format!("unknown operation `{name}` (known: extrude, split, rsplit, repeat, comp, S, T, R)"),
                ))
            }
        })
    }

    fn braced_succs(&mut self, comp: bool) -> PResult<Vec<Successor>> {
        let open = self.expect(Tok::LBrace, "`{`")?;
        let mut out = Vec::new();
        loop {
            if *self.peek() == Tok::Eof || self.at_rule_start() {
                return Err(self.ctx.err(open, ParseErrorKind::Unclosed, "unclosed `{`"));
            }
            out.push(self.succ(comp)?);
            match self.peek() {
                Tok::Pipe => {
                    self.bump();
                }
                Tok::RBrace => {
                    self.bump();
                    return Ok(out);
                }
                _ => return Err(self.unclosed_or(open, "`{`", "`|`, `,` or `}`")),
            }
        }
    }

    fn succ(&mut self, comp: bool) -> PResult<Successor> {
        let selector = if comp {
            let (name, sp) = self
                .ident("a comp selector (front, back, left, right, side, others, top, bottom)")?;
            let sel = Selector::from_name(&name).ok_or_else(|| {
                self.ctx.err(
                    sp,
                    ParseErrorKind::BadSelector,
                    format!("unknown comp selector `{name}` (known: front, back, left, right, side, others, top, bottom)"),
                )
            })?;
            self.expect(Tok::Colon, "`:` after the selector")?;
            Some(sel)
        } else {
            None
        };
        let (sym, span) = self.ident("a successor symbol")?;
        let symbol = self.rs.intern(&sym);
        let mut attrs = Vec::new();
        if *self.peek() == Tok::Colon {
            self.bump();
            loop {
                let (key, _) = self.ident("an attribute name")?;
                self.expect(Tok::Eq, "`=` after the attribute name")?;
                let value = match self.peek().clone() {
                    Tok::Ident(s) | Tok::Hex(s) | Tok::Str(s) => {
                        self.bump();
                        AttrValue::Str(Arc::from(s))
                    }
                    Tok::Num(v) => {
                        self.bump();
                        AttrValue::Num(v)
                    }
                    Tok::Minus => match self.peek_at(1).clone() {
                        Tok::Num(v) => {
                            self.bump();
                            self.bump();
                            AttrValue::Num(-v)
                        }
                        _ => return Err(self.unexpected("an attribute value")),
                    },
                    _ => return Err(self.unexpected("an attribute value")),
                };
                attrs.push((Arc::from(key), value));
                // A comma continues the list unless it is followed by something that is not
                // `name =` (then it is an error reported by the caller).
                if *self.peek() == Tok::Comma {
                    self.bump();
                } else {
                    break;
                }
            }
        }
        Ok(Successor {
            selector,
            symbol,
            attrs,
            span,
        })
    }

    /// An error at the current token when an expression of tree depth `depth` would be too
    /// deep.
    fn check_depth(&self, depth: usize) -> PResult<()> {
        if depth > MAX_EXPR_DEPTH {
            return Err(self.ctx.err(
                self.span(),
                ParseErrorKind::TooDeep,
                format!("expression nested more than {MAX_EXPR_DEPTH} levels deep"),
            ));
        }
        Ok(())
    }

    /// A sum of products, with its tree depth.
    fn expr(&mut self, open: Span) -> PResult<(Expr, usize)> {
        let (mut lhs, mut depth) = self.term(open)?;
        loop {
            let op = match self.peek() {
                Tok::Plus => BinOp::Add,
                Tok::Minus => BinOp::Sub,
                _ => return Ok((lhs, depth)),
            };
            self.check_depth(depth + 1)?;
            self.bump();
            let (rhs, d) = self.term(open)?;
            depth = 1 + depth.max(d);
            self.check_depth(depth)?;
            lhs = Expr::Bin(op, Box::new(lhs), Box::new(rhs));
        }
    }

    /// A product of unary expressions, with its tree depth.
    fn term(&mut self, open: Span) -> PResult<(Expr, usize)> {
        let (mut lhs, mut depth) = self.unary(open)?;
        loop {
            let op = match self.peek() {
                Tok::Star => BinOp::Mul,
                Tok::Slash => BinOp::Div,
                _ => return Ok((lhs, depth)),
            };
            self.check_depth(depth + 1)?;
            self.bump();
            let (rhs, d) = self.unary(open)?;
            depth = 1 + depth.max(d);
            self.check_depth(depth)?;
            lhs = Expr::Bin(op, Box::new(lhs), Box::new(rhs));
        }
    }

    /// A unary expression, with its tree depth. The parser recurses here for `-`, `(` and
    /// `rand(`, so `nesting` counts the levels open and stops at [`MAX_EXPR_DEPTH`] before the
    /// recursion can exhaust the stack.
    fn unary(&mut self, open: Span) -> PResult<(Expr, usize)> {
        self.nesting += 1;
        let r = match self.check_depth(self.nesting) {
            Ok(()) => self.unary_inner(open),
            Err(e) => Err(e),
        };
        self.nesting -= 1;
        r
    }

    fn unary_inner(&mut self, open: Span) -> PResult<(Expr, usize)> {
        match self.peek().clone() {
            Tok::Minus => {
                self.bump();
                let (e, d) = self.unary(open)?;
                self.check_depth(d + 1)?;
                Ok((Expr::Neg(Box::new(e)), d + 1))
            }
            Tok::Num(v) => {
                self.bump();
                Ok((Expr::Num(v), 1))
            }
            Tok::LParen => {
                let o = self.bump().1;
                let e = self.expr(o)?;
                if *self.peek() != Tok::RParen {
                    return Err(self.unclosed_or(o, "`(`", "`)`"));
                }
                self.bump();
                Ok(e)
            }
            Tok::Ident(name) => {
                let sp = self.bump().1;
                if *self.peek() == Tok::LParen {
                    let o = self.bump().1;
                    let args = self.args_with_depth(o)?;
                    if name != "rand" {
                        return Err(self.ctx.err(
                            sp,
                            ParseErrorKind::UnknownFunction,
                            format!("unknown function `{name}` (known: rand)"),
                        ));
                    }
                    let n = args.len();
                    let depth = 1 + args.iter().map(|a| a.2).max().unwrap_or(0);
                    self.check_depth(depth)?;
                    let mut it = args.into_iter().map(|a| a.0);
                    return match (it.next(), it.next(), it.next()) {
                        (Some(a), Some(b), None) => {
                            Ok((Expr::Rand(Box::new(a), Box::new(b)), depth))
                        }
                        _ => Err(self.ctx.err(
                            sp,
                            ParseErrorKind::WrongArgCount,
                            format!("rand expects 2 arguments (min, max), got {n}"),
                        )),
                    };
                }
                Ok((
                    match name.as_str() {
                        "sx" => Expr::ScopeSize(Axis::X),
                        "sy" => Expr::ScopeSize(Axis::Y),
                        "sz" => Expr::ScopeSize(Axis::Z),
                        _ => Expr::Attr(Arc::from(name), sp),
                    },
                    1,
                ))
            }
            _ => {
                if *self.peek() == Tok::Eof || self.at_rule_start() {
                    Err(self.ctx.err(open, ParseErrorKind::Unclosed, "unclosed `(`"))
                } else {
                    Err(self.unexpected(
                        "a number, `sx`, `sy`, `sz`, `rand(a, b)`, an attribute name or `(`",
                    ))
                }
            }
        }
    }
}

fn names(axes: &[Axis]) -> String {
    axes.iter().map(|a| a.name()).collect::<Vec<_>>().join(", ")
}

/// Parses a rule file. `file` is used only in error messages.
///
/// The axiom is the predecessor of the first rule. Probabilities: a rule with `= p` has weight
/// `p`; the rules of the same predecessor without one share `1 − Σ p` equally (0 if the explicit
/// ones already reach 1). Selection normalises the weights, so a set that does not sum to 1
/// still derives (the linter of a later issue warns about it). A source longer than
/// [`MAX_SOURCE_BYTES`] is refused before it is read ([`ParseErrorKind::TooLarge`], at 1:1).
pub fn parse(src: &str, file: &str) -> Result<RuleSet, GrammarError> {
    let ctx = Ctx { src, file };
    if src.len() > MAX_SOURCE_BYTES {
        return Err(ctx.err(
            Span {
                line: 1,
                col: 1,
                offset: 0,
                len: 0,
            },
            ParseErrorKind::TooLarge,
            format!(
                "the rule file is {} bytes, more than {MAX_SOURCE_BYTES}, the cap on rule files \
                 (rule files are a few kilobytes)",
                src.len()
            ),
        ));
    }
    let toks = lex(&ctx)?;
    let rs = RuleSet {
        file: Arc::from(file),
        symbols: Vec::new(),
        index: HashMap::new(),
        rules: Vec::new(),
        by_pred: Vec::new(),
        weights: Vec::new(),
        axiom: 0,
    };
    let mut p = Parser {
        ctx,
        toks,
        pos: 0,
        rs,
        nesting: 0,
    };
    p.file()?;
    let mut rs = p.rs;
    for (i, r) in rs.rules.iter().enumerate() {
        rs.by_pred[r.pred as usize].push(i);
    }
    let mut weights = vec![0.0; rs.rules.len()];
    for list in &rs.by_pred {
        let explicit: f64 = list.iter().filter_map(|&i| rs.rules[i].prob).sum();
        let implicit = list.iter().filter(|&&i| rs.rules[i].prob.is_none()).count();
        let share = if implicit > 0 {
            (1.0 - explicit).max(0.0) / implicit as f64
        } else {
            0.0
        };
        for &i in list {
            weights[i] = rs.rules[i].prob.unwrap_or(share);
        }
    }
    rs.weights = weights;
    rs.axiom = rs.rules[0].pred;
    Ok(rs)
}
