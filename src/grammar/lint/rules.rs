//! Checks on the rules themselves: undefined symbols, unreachable rules, probability sums,
//! duplicates.

use std::collections::BTreeSet;

use super::names::{cut, fmt_num, list_names, plural, quote, suggest};
use super::{
    Cx, Severity, Sink, KNOWN_TERMINALS, MAX_LISTED, MAX_NAME_CHARS, MAX_PER_CODE, PROB_EPS,
    SUGGEST_BUDGET,
};
use crate::grammar::ast::{Rule, SymbolId};

impl Cx<'_> {
    /// Successor symbols with no rule that are not known terminals.
    pub(super) fn undefined_symbols(&self, out: &mut Sink) {
        // The names a suggestion can be, with their lengths in characters, in the order ties
        // are broken: defined symbols (interned order), then the known terminals.
        let candidates: Vec<(&str, usize)> = (0..self.names.len() as SymbolId)
            .filter(|&id| self.has_rules(id))
            .map(|id| self.name(id))
            .chain(KNOWN_TERMINALS.iter().copied())
            .filter(|c| c.len() <= 4 * MAX_NAME_CHARS)
            .map(|c| (c, c.chars().count()))
            .collect();
        let mut budget = SUGGEST_BUDGET;
        for r in self.rules.rules() {
            for s in &r.succs {
                let name = self.name(s.symbol);
                if self.has_rules(s.symbol) || KNOWN_TERMINALS.contains(&name) {
                    continue;
                }
                let mut msg = format!(
                    "{} has no rule and is not a known terminal ({}): it becomes a leaf of the \
                     shape tree with no element kind",
                    quote(name),
                    KNOWN_TERMINALS.join(", ")
                );
                // Successors come in source order, which is the output order: past the listed
                // ones a suggestion would not be shown.
                if out.count("undefined-symbol") < MAX_PER_CODE {
                    if let Some(s) = suggest(name, &candidates, &mut budget) {
                        msg.push_str(&format!("; did you mean {}?", quote(s)));
                    }
                }
                out.push(self.diag(Severity::Warning, "undefined-symbol", s.span, msg));
            }
        }
    }

    /// Symbols reachable from the axiom through the successors of any rule.
    pub(super) fn reachable(&self) -> Vec<bool> {
        let mut seen = vec![false; self.names.len()];
        let mut stack: Vec<SymbolId> = self.axiom.into_iter().collect();
        while let Some(s) = stack.pop() {
            let Some(slot) = seen.get_mut(s as usize) else {
                continue;
            };
            if *slot {
                continue;
            }
            *slot = true;
            for &i in &self.by_pred[s as usize] {
                stack.extend(self.rule(i).succs.iter().map(|x| x.symbol));
            }
        }
        seen
    }

    /// One warning per unreachable predecessor, at its first rule.
    pub(super) fn unreachable_rules(&self, out: &mut Sink) {
        let seen = self.reachable();
        // The predecessors of the rules that use each unreachable symbol, in source order,
        // once each (one pass over the rules, not one per symbol).
        let mut users: Vec<Vec<SymbolId>> = vec![Vec::new(); self.names.len()];
        let mut pairs: BTreeSet<(SymbolId, SymbolId)> = BTreeSet::new();
        for u in self.rules.rules() {
            for x in &u.succs {
                let t = x.symbol as usize;
                if t < users.len()
                    && !seen[t]
                    && x.symbol != u.pred
                    && pairs.insert((x.symbol, u.pred))
                {
                    users[t].push(u.pred);
                }
            }
        }
        for (id, list) in self.by_pred.iter().enumerate() {
            let Some(&first) = list.first() else {
                continue;
            };
            if seen[id] {
                continue;
            }
            let r = self.rule(first);
            let n = list.len();
            // Name the unreachable rules that do use it, so that the author finds the root.
            let by = if users[id].is_empty() {
                String::new()
            } else {
                let names: Vec<String> = users[id]
                    .iter()
                    .take(MAX_LISTED)
                    .map(|&u| self.q(u))
                    .collect();
                format!(
                    " (only used by the unreachable {})",
                    list_names(&names, users[id].len())
                )
            };
            let pred = self.q(id as SymbolId);
            let msg = format!(
                "rule{} for {pred} {} never used: {pred} is not reachable from the axiom {}{by}",
                plural(n),
                if n == 1 { "is" } else { "are" },
                quote(self.rules.axiom())
            );
            out.push(self.diag(Severity::Warning, "unreachable-rule", r.span, msg));
        }
    }

    /// Probability sums per predecessor, judged by the parser's resolution: explicit `= p`
    /// weigh `p`, the others share `1 − Σp` (nothing if Σp ≥ 1), and selection normalises.
    pub(super) fn probabilities(&self, out: &mut Sink) {
        for (id, list) in self.by_pred.iter().enumerate() {
            let pred = cut(self.name(id as SymbolId));
            let explicit: Vec<usize> = list
                .iter()
                .copied()
                .filter(|&i| self.rule(i).prob.is_some())
                .collect();
            if explicit.is_empty() {
                continue;
            }
            let implicit: Vec<usize> = list
                .iter()
                .copied()
                .filter(|&i| self.rule(i).prob.is_none())
                .collect();
            let first = self.rule(list[0]);
            for &i in &explicit {
                let r = self.rule(i);
                if let Some(p) = r.prob.filter(|p| p.is_nan() || *p < 0.0) {
                    out.push(self.diag(
                        Severity::Error,
                        "probability-sum",
                        r.span,
                        format!("probability {p} of a rule for `{pred}` is negative"),
                    ));
                }
            }
            let sum: f64 = explicit.iter().filter_map(|&i| self.rule(i).prob).sum();
            let lines = |v: &[usize]| {
                let shown: Vec<String> = v
                    .iter()
                    .take(MAX_LISTED)
                    .map(|&i| self.rule(i).span.line.to_string())
                    .collect();
                list_names(&shown, v.len())
            };
            if sum > 1.0 + PROB_EPS {
                let mut msg = format!(
                    "the probabilities of the rules for `{pred}` sum to {} > 1 (lines {})",
                    fmt_num(sum),
                    lines(&explicit)
                );
                if !implicit.is_empty() {
                    msg.push_str(&format!(
                        "; the rule{} without probability (line{} {}) get weight 0 and are never \
                         chosen",
                        plural(implicit.len()),
                        plural(implicit.len()),
                        lines(&implicit)
                    ));
                }
                msg.push_str("; make them sum to 1");
                out.push(self.diag(Severity::Error, "probability-sum", first.span, msg));
            } else if implicit.is_empty() && sum < 1.0 - PROB_EPS {
                let how = if sum > 0.0 {
                    format!(
                        "they are normalised (each divided by {}) at selection",
                        fmt_num(sum)
                    )
                } else {
                    "all weights are 0, so one is chosen uniformly at random".to_string()
                };
                out.push(self.diag(
                    Severity::Warning,
                    "probability-sum",
                    first.span,
                    format!(
                        "the probabilities of the rules for `{pred}` sum to {} < 1 (line{} {}); \
                         {how}",
                        fmt_num(sum),
                        plural(explicit.len()),
                        lines(&explicit)
                    ),
                ));
            } else if !implicit.is_empty() && sum >= 1.0 - PROB_EPS {
                let r = self.rule(implicit[0]);
                out.push(self.diag(
                    Severity::Warning,
                    "probability-sum",
                    r.span,
                    format!(
                        "the explicit probabilities of the rules for `{pred}` already sum to 1: \
                         the rule{} without probability (line{} {}) get weight 0 and are never \
                         chosen",
                        plural(implicit.len()),
                        plural(implicit.len()),
                        lines(&implicit)
                    ),
                ));
            }
        }
    }

    /// Two or more rules for one predecessor without `= p`: by the parser's resolution they
    /// share what the explicit alternatives leave, so none shadows another: they are drawn at
    /// random (or never, when the explicit ones reach 1). Reported at each rule after the first.
    pub(super) fn duplicate_rules(&self, out: &mut Sink) {
        for (id, list) in self.by_pred.iter().enumerate() {
            let pred = cut(self.name(id as SymbolId));
            let implicit: Vec<usize> = list
                .iter()
                .copied()
                .filter(|&i| self.rule(i).prob.is_none())
                .collect();
            if implicit.len() < 2 {
                continue;
            }
            let total: f64 = list.iter().map(|&i| self.weights[i]).sum();
            let first = self.rule(implicit[0]);
            for &i in &implicit[1..] {
                let r = self.rule(i);
                let w = self.weights[i];
                let how = if total <= 0.0 {
                    format!(
                        "all {} rules for `{pred}` have weight 0, so one is chosen uniformly at \
                         random",
                        list.len()
                    )
                } else if w > 0.0 {
                    format!(
                        "the {} rules without probability are not shadowed: each is chosen at \
                         random with probability {}",
                        implicit.len(),
                        fmt_num(w / total)
                    )
                } else {
                    format!(
                        "the {} rules without probability get weight 0 (the explicit ones \
                         already sum to 1) and are never chosen",
                        implicit.len()
                    )
                };
                let same = if same_body(first, r) {
                    " and is identical to it"
                } else {
                    ""
                };
                out.push(self.diag(
                    Severity::Error,
                    "duplicate-rule",
                    r.span,
                    format!(
                        "second deterministic rule for `{pred}` (the first is at line {}){same}: \
                         {how}; give each alternative `= p` or remove all but one",
                        first.span.line
                    ),
                ));
            }
        }
    }
}

/// Whether two rules do the same thing (ignoring where they are written).
fn same_body(a: &Rule, b: &Rule) -> bool {
    a.op == b.op
        && a.succs.len() == b.succs.len()
        && a.succs
            .iter()
            .zip(&b.succs)
            .all(|(x, y)| x.selector == y.selector && x.symbol == y.symbol && x.attrs == y.attrs)
}
