//! Evaluation of argument expressions against the current shape.

use glam::DVec3;

use super::ast::{Attrs, BinOp, Expr};
use crate::rng::Rng;

/// Why an expression could not be evaluated (the interpreter adds the rule's place).
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum EvalError {
    /// An identifier that is neither `sx`/`sy`/`sz` nor an attribute of the shape.
    MissingAttribute(String),
    /// An attribute used in an expression whose value is text.
    NotANumber(String, String),
    /// A division by zero or another non-finite result.
    NonFinite,
}

/// Evaluates `e` with the shape's scope sizes and attributes; `rand` draws from `rng`.
/// The result is always finite.
pub fn eval(e: &Expr, size: DVec3, attrs: &Attrs, rng: &mut Rng) -> Result<f64, EvalError> {
    let v = match e {
        Expr::Num(v) => *v,
        Expr::ScopeSize(a) => size[a.index()],
        Expr::Attr(name, _) => match attrs.get(&**name) {
            Some(v) => v
                .as_f64()
                .ok_or_else(|| EvalError::NotANumber(name.to_string(), v.to_string()))?,
            None => return Err(EvalError::MissingAttribute(name.to_string())),
        },
        Expr::Rand(a, b) => {
            let a = eval(a, size, attrs, rng)?;
            let b = eval(b, size, attrs, rng)?;
            rng.range(a, b)
        }
        Expr::Neg(a) => -eval(a, size, attrs, rng)?,
        Expr::Bin(op, a, b) => {
            let a = eval(a, size, attrs, rng)?;
            let b = eval(b, size, attrs, rng)?;
            match op {
                BinOp::Add => a + b,
                BinOp::Sub => a - b,
                BinOp::Mul => a * b,
                BinOp::Div => a / b,
            }
        }
    };
    if v.is_finite() {
        Ok(v)
    } else {
        Err(EvalError::NonFinite)
    }
}
