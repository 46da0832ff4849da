//! The program, its assignments and rules, and a rule's selection: steps, topology selectors,
//! filters, index sets and patterns.

use super::lexer::{clip, Tok};
use super::{describe_expr, topo_names, PResult, ParseErrorKind, Parser};
use crate::selex::ast::{
    ActionKind, Arrow, Attr, Cmp, Command, Expr, ExprKind, Filter, Grouping, IndexSet, Program,
    Rule, Selection, Span, Step, Topo, ValueKind,
};

impl Parser<'_> {
    pub(super) fn program(&mut self) -> PResult<Program> {
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
    pub(super) fn call_args<T>(
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
}
