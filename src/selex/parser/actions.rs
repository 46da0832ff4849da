//! Actions and their arguments (arity and kinds, messages naming the parameter), and
//! constraint terms.

use super::lexer::{clip, Tok};
use super::{describe_expr, quoted_list, PResult, ParseErrorKind, Parser};
use crate::grammar::lint::suggest;
use crate::selex::ast::{
    Action, ActionKind, Constraint, ConstraintAxis, ConstraintKind, Expr, ExprKind, Param,
    ParamKind, Span, ValueKind, CORNERS,
};

impl Parser<'_> {
    pub(super) fn action(&mut self) -> PResult<Action> {
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
}
