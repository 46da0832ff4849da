//! The lexer: SELEX source to tokens with their spans.

use super::{Ctx, ParseErrorKind, SelexError};
use crate::grammar::lint::MAX_NAME_CHARS;
use crate::selex::ast::Span;

#[derive(Clone, Debug, PartialEq)]
pub(super) enum Tok {
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
    pub(super) fn describe(&self) -> String {
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
pub(super) fn clip(s: &str) -> String {
    if s.chars().count() <= MAX_NAME_CHARS {
        s.to_string()
    } else {
        let head: String = s.chars().take(MAX_NAME_CHARS).collect();
        format!("{head}…")
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

pub(super) fn lex(ctx: &Ctx<'_>) -> Result<Vec<(Tok, Span)>, SelexError> {
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
