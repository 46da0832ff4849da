//! Values: expressions, their kinds, arithmetic and lists.

use super::lexer::{clip, Tok};
use super::{describe_expr, PResult, ParseErrorKind, Parser};
use crate::selex::ast::{BinOp, Expr, ExprKind, Span, ValueKind};

impl Parser<'_> {
    /// The kind an expression evaluates to (variables by their assigned kind).
    pub(super) fn kind_of(&self, e: &Expr) -> ValueKind {
        match &e.kind {
            ExprKind::Number(_) | ExprKind::Neg(_) | ExprKind::Binary(..) => ValueKind::Number,
            ExprKind::Str(_) | ExprKind::BareWord(_) => ValueKind::Str,
            ExprKind::List(_) => ValueKind::List,
            ExprKind::Var(v) => self.vars.get(v).copied().unwrap_or(ValueKind::Str),
        }
    }

    /// A value: an expression; a lone unknown identifier is a bare word.
    pub(super) fn value(&mut self) -> PResult<Expr> {
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
