//! The values of expressions: variables, numbers, strings, lists, and what a value is called in
//! an error.

use super::{Labels, RunError, Runner, Value};
use crate::selex::ast::{BinOp, Expr, ExprKind};
use crate::selex::grid::{self};

impl Runner<'_> {
    pub(super) fn value(&self, e: &Expr) -> Result<Value, RunError> {
        Ok(match &e.kind {
            ExprKind::Number(v) => Value::Num(*v),
            ExprKind::Str(s) | ExprKind::BareWord(s) => {
                // A bare word that names a variable is the variable (the parser cannot know
                // which names a later assignment binds).
                match (&e.kind, self.vars.get(s)) {
                    (ExprKind::BareWord(_), Some(v)) => v.clone(),
                    _ => Value::Str(s.clone()),
                }
            }
            ExprKind::Var(name) => {
                self.vars.get(name).cloned().ok_or_else(|| {
                    self.err(e.span, format!("`{name}` is not assigned before here"))
                })?
            }
            ExprKind::List(items) => Value::List(
                items
                    .iter()
                    .map(|i| self.value(i))
                    .collect::<Result<_, _>>()?,
            ),
            ExprKind::Neg(inner) => Value::Num(-self.number(inner)?),
            ExprKind::Binary(op, a, b) => {
                let (a, b) = (self.number(a)?, self.number(b)?);
                let v = match op {
                    BinOp::Add => a + b,
                    BinOp::Sub => a - b,
                    BinOp::Mul => a * b,
                    BinOp::Div => a / b,
                };
                if !v.is_finite() {
                    return Err(self.err(e.span, "the arithmetic gives no finite number".into()));
                }
                Value::Num(v)
            }
        })
    }

    pub(super) fn number(&self, e: &Expr) -> Result<f64, RunError> {
        match self.value(e)? {
            Value::Num(v) if v.is_finite() => Ok(v),
            other => Err(self.err(
                e.span,
                format!("a number is needed here, not {}", describe(&other)),
            )),
        }
    }

    pub(super) fn positive(&self, e: &Expr, what: &str) -> Result<f64, RunError> {
        let v = self.number(e)?;
        if v > 0.0 {
            Ok(v)
        } else {
            Err(self.err(e.span, format!("{what} must be positive, not {v}")))
        }
    }

    pub(super) fn string(&self, e: &Expr) -> Result<String, RunError> {
        match self.value(e)? {
            Value::Str(s) => Ok(s),
            other => Err(self.err(
                e.span,
                format!("a string is needed here, not {}", describe(&other)),
            )),
        }
    }

    pub(super) fn integer(&self, e: &Expr) -> Result<i64, RunError> {
        let v = self.number(e)?;
        if v.fract() == 0.0 && v.abs() < 1e15 {
            Ok(v as i64)
        } else {
            Err(self.err(e.span, format!("an index must be a whole number, not {v}")))
        }
    }

    /// A count (`rows`, `cols`) or a list of labels whose length is the count.
    pub(super) fn count_or_labels(&self, e: &Expr) -> Result<(usize, Option<Labels>), RunError> {
        match self.value(e)? {
            Value::Num(v) if v >= 1.0 && v.fract() == 0.0 && v <= grid::MAX_CELLS as f64 => {
                Ok((v as usize, None))
            }
            Value::List(items) if !items.is_empty() => {
                let labels = items
                    .iter()
                    .map(|i| match i {
                        Value::Str(s) => Ok(vec![s.clone()]),
                        other => Err(self.err(
                            e.span,
                            format!("row and column labels are strings, not {}", describe(other)),
                        )),
                    })
                    .collect::<Result<Vec<_>, _>>()?;
                Ok((labels.len(), Some(labels)))
            }
            other => Err(self.err(
                e.span,
                format!(
                    "a whole number of at least 1, or a list of labels, not {}",
                    describe(&other)
                ),
            )),
        }
    }
}

pub(super) fn describe(v: &Value) -> String {
    match v {
        Value::Num(x) => format!("the number {x}"),
        Value::Str(s) => format!("the string {s:?}"),
        Value::List(l) => format!("a list of {}", l.len()),
    }
}
