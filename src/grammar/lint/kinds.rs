//! Shape kinds: the kinds each symbol can meet (lot, volume, face) and the operations that do
//! not fit them.

use super::names::cut;
use super::{kind_name, Cx, Kinds, Severity, Sink, FACE, LOT, VOLUME};
use crate::grammar::ast::{Axis, Op, SymbolId};

impl Cx<'_> {
    /// The shape kinds each symbol can meet, from the axiom (a lot), to a fixpoint.
    pub(super) fn kinds(&self) -> Vec<Kinds> {
        let mut kinds = vec![0 as Kinds; self.names.len()];
        let Some(ax) = self.axiom else {
            return kinds;
        };
        kinds[ax as usize] = LOT;
        let mut work: Vec<SymbolId> = vec![ax];
        while let Some(s) = work.pop() {
            let k = kinds[s as usize];
            for &i in &self.by_pred[s as usize] {
                let r = self.rule(i);
                let mut produced = 0;
                for bit in [LOT, VOLUME, FACE] {
                    if k & bit != 0 {
                        if let Ok(o) = apply_kind(&r.op, bit) {
                            produced |= o;
                        }
                    }
                }
                for succ in &r.succs {
                    if let Some(slot) = kinds.get_mut(succ.symbol as usize) {
                        if *slot | produced != *slot {
                            *slot |= produced;
                            work.push(succ.symbol);
                        }
                    }
                }
            }
        }
        kinds
    }

    /// Operations applied to a shape kind the interpreter rejects.
    pub(super) fn shape_kinds(&self, out: &mut Sink) {
        let kinds = self.kinds();
        for r in self.rules.rules() {
            let k = kinds.get(r.pred as usize).copied().unwrap_or(0);
            let mut bad: Vec<(&str, &str)> = Vec::new();
            let mut ok = 0;
            for bit in [LOT, VOLUME, FACE] {
                if k & bit == 0 {
                    continue;
                }
                match apply_kind(&r.op, bit) {
                    Ok(_) => ok += 1,
                    Err(why) => bad.push((kind_name(bit), why)),
                }
            }
            if bad.is_empty() {
                continue;
            }
            let pred = cut(self.name(r.pred));
            let what = bad
                .iter()
                .map(|(k, why)| format!("a {k} ({why})"))
                .collect::<Vec<_>>()
                .join(" and ");
            let (sev, msg) = if ok == 0 {
                (
                    Severity::Error,
                    format!(
                        "`{pred}` is always {}, and {} cannot be applied to {what}: derivation \
                         of every building that reaches this rule fails",
                        bad.iter()
                            .map(|(k, _)| format!("a {k}"))
                            .collect::<Vec<_>>()
                            .join(" or "),
                        op_label(&r.op)
                    ),
                )
            } else {
                (
                    Severity::Warning,
                    format!(
                        "`{pred}` can be {}; {} cannot be applied to {what}: derivation fails \
                         when it meets one",
                        bad.iter()
                            .map(|(k, _)| format!("a {k}"))
                            .collect::<Vec<_>>()
                            .join(" or "),
                        op_label(&r.op)
                    ),
                )
            };
            out.push(self.diag(sev, "op-shape-mismatch", r.span, msg));
        }
    }
}

/// What an operation makes of a shape of kind `k` (one bit), or why the interpreter refuses it.
/// Mirrors [`crate::grammar::interp`]: comp needs a volume; a lot is flat (no Z split); a face has no
/// depth (no Y split) and does not rotate.
fn apply_kind(op: &Op, k: Kinds) -> Result<Kinds, &'static str> {
    match op {
        Op::Relabel | Op::Scale(_) | Op::Translate(_) => Ok(k),
        Op::Extrude(_) => Ok(VOLUME),
        Op::Rotate(..) if k == FACE => Err("only volumes and lots rotate"),
        Op::Rotate(..) => Ok(k),
        Op::Comp if k == VOLUME => Ok(FACE),
        Op::Comp => Err("comp needs a volume: extrude first"),
        Op::Split { axis, .. } => match (k, axis) {
            (LOT, Axis::Z) => Err("a lot is flat: extrude first"),
            (FACE, Axis::Y) => Err("a face has no depth: split along X or Z"),
            _ => Ok(k),
        },
    }
}

/// `comp`, `split(Z)`, ... for messages.
pub(super) fn op_label(op: &Op) -> String {
    match op {
        Op::Split { kind, axis, .. } => format!("`{}({}, ...)`", kind.name(), axis.name()),
        other => format!("`{}`", other.name()),
    }
}
