//! The rule linter behind `citygen rules check FILE` (issue 3 item 6).
//!
//! [`lint`] inspects a parsed [`RuleSet`] for mistakes that parse fine but derive something the
//! author did not mean. Each finding is a [`Diagnostic`] with a stable `code`:
//!
//! | code | severity | what |
//! |------|----------|------|
//! | `undefined-symbol` | warning | a successor with no rule that is not a known terminal (wall, window, door, balcony): it becomes a bare leaf |
//! | `unreachable-rule` | warning | a predecessor that no derivation from the axiom can reach |
//! | `probability-sum` | error / warning | the `= p` of a predecessor's alternatives sum above 1 or below 0 (error), or all alternatives are explicit and sum below 1, or the explicit ones reach 1 so the others never fire (warning) |
//! | `duplicate-rule` | error | two or more rules for one predecessor without `= p` |
//! | `op-shape-mismatch` | error / warning | an operation the shape it meets cannot take (`comp` on a lot or face, `split(Z)` on a lot, `split(Y)` or `R` on a face); error when every shape kind the rule can meet fails, warning when only some do |
//! | `non-terminating` | warning | recursion through operations that never drop the shape (relabel, `S`, `T`, `R`, `extrude`, a `repeat` that keeps a copy, a one-entry split, a `comp` face of a box): only `max_depth` stops it |
//! | `exponential-growth` | warning | unbounded recursion whose shapes multiply (on average ≥ 1 per shape, with a rule making two or more): about ρ^depth shapes, stopped by `max_shapes` |
//!
//! The two recursion lints and what counts as bounded are specified on `Cx::recursion` (in the
//! source) and summed up in docs/grammar.md; each message says what the derivation will do
//! (which cap stops it, and for growth about how many levels down).
//!
//! The shape-kind inference is a small abstract interpretation that follows the interpreter's
//! rules (see [`super::interp`]): the axiom meets a lot; `extrude` yields a volume from anything;
//! `comp` yields faces from a volume; splits, relabels, `S`, `T` and `R` keep the kind.
//!
//! Output is deterministic: diagnostics are sorted by (line, col, code, message) and no hash
//! map order reaches them.
//!
//! **Bounded work.** A generated or hostile file (a split with 50,000 successors, each a new
//! symbol) must not make the linter itself the rule bomb. Every pass is linear in the size of
//! the file, or bounded by a constant: cycles are found with one strongly-connected-component
//! pass (not a symbol × symbol table), each diagnostic keeps a window of
//! [`CONTEXT_CHARS`] characters on each side of its column (not its whole line), at most
//! [`MAX_PER_CODE`] diagnostics of one code are listed (then one saying how many more there
//! are), name lists in messages stop after a few names, long symbol names are cut, and the
//! "did you mean" search has a fixed budget.

use std::collections::{BTreeMap, BTreeSet, BinaryHeap};
use std::fmt;

use super::ast::{Axis, BinOp, Expr, Op, Rule, RuleSet, Selector, Span, SplitKind, SymbolId};

/// The symbols that the model builder and the exporters turn into building elements; a
/// successor with one of these names and no rule is a deliberate leaf, not a typo.
pub const KNOWN_TERMINALS: [&str; 4] = ["wall", "window", "door", "balcony"];

/// Tolerance on probability sums (`0.4 + 0.2 + 0.2 + 0.2` is not exactly 1 in binary).
const PROB_EPS: f64 = 1e-9;

/// Characters of a long source line a [`Diagnostic`] keeps on each side of its column (the
/// parser's errors show the same window).
pub const CONTEXT_CHARS: usize = 80;

/// The most diagnostics of one code [`lint`] lists; past it, one more diagnostic of that code
/// says how many were left out.
pub const MAX_PER_CODE: usize = 100;

/// Symbol names longer than this many characters are cut (with `…`) in messages.
pub(crate) const MAX_NAME_CHARS: usize = 64;

/// Sizes at most this are skipped by the interpreter (`shape::EPS`).
const EPS_SIZE: f64 = 1e-9;

/// Names listed in one message (cycle members, users of a symbol, line numbers) before
/// "and N more".
const MAX_LISTED: usize = 8;

/// Edit-distance cells the "did you mean" suggestions of one file may cost in total; once
/// spent, later undefined symbols get no suggestion.
const SUGGEST_BUDGET: usize = 20_000_000;

/// How bad a [`Diagnostic`] is: errors make `citygen rules check` exit non-zero.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Severity {
    /// The rule set is wrong: derivation will fail or silently ignore rules the author wrote.
    Error,
    /// The rule set derives, but probably not as the author meant.
    Warning,
}

impl Severity {
    /// `error` or `warning`, as printed.
    pub fn name(self) -> &'static str {
        match self {
            Severity::Error => "error",
            Severity::Warning => "warning",
        }
    }
}

impl fmt::Display for Severity {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// One lint finding, located at a place in the rule source.
///
/// `Display` prints `file:line:col: warning[code]: message`, then the source line and a caret
/// under `col` (tabs are reproduced so that the caret lines up), like a parse error.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Diagnostic {
    /// Error or warning.
    pub severity: Severity,
    /// A stable, kebab-case identifier of the lint (see the module table), for tests and
    /// filters.
    pub code: &'static str,
    /// The rule file name, as given to [`crate::grammar::parse`].
    pub file: String,
    /// 1-based line.
    pub line: u32,
    /// 1-based column, in characters.
    pub col: u32,
    /// The explanation, with a hint at the fix where there is one.
    pub message: String,
    /// The text of the source line (without its newline); empty when `source` did not have
    /// that line. A line longer than 2 × [`CONTEXT_CHARS`] characters is cut to the
    /// [`CONTEXT_CHARS`] characters on each side of `col`, with `…` where it is cut.
    pub line_text: String,
    /// The 1-based character column of `line_text` the caret goes under: `col`, unless the
    /// line was cut.
    pub text_col: u32,
}

impl fmt::Display for Diagnostic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{}:{}:{}: {}[{}]: {}",
            self.file, self.line, self.col, self.severity, self.code, self.message
        )?;
        writeln!(f, "{}", self.line_text)?;
        write!(f, "{}^", caret_pad(&self.line_text, self.text_col))
    }
}

/// The window of `line` shown under a diagnostic whose place is byte `pos` of the line (a
/// char boundary, at most `line.len()`), and the caret's 1-based character column in it: the
/// whole line when it is at most 2 × [`CONTEXT_CHARS`] characters, else [`CONTEXT_CHARS`]
/// characters on each side of the place with `…` where it is cut. The cost is bounded by the
/// window, not the line (a megabyte line with thousands of diagnostics stays linear).
fn line_window(line: &str, pos: usize) -> (String, u32) {
    let (head, tail) = line.split_at(pos);
    // Byte where the window starts: CONTEXT_CHARS characters back, or the line's start.
    let from = head
        .char_indices()
        .rev()
        .nth(CONTEXT_CHARS - 1)
        .map_or(0, |(i, _)| i);
    // Byte where it ends: CONTEXT_CHARS characters on, or the line's end.
    let to = tail
        .char_indices()
        .nth(CONTEXT_CHARS)
        .map_or(line.len(), |(i, _)| pos + i);
    // At most 2 × CONTEXT_CHARS characters (counting stops there): the whole line.
    if line.chars().nth(2 * CONTEXT_CHARS).is_none() {
        return (line.to_string(), head.chars().count() as u32 + 1);
    }
    let cut_head = from > 0;
    let mut shown = String::with_capacity(to - from + 6);
    if cut_head {
        shown.push('…');
    }
    shown.push_str(&line[from..to]);
    if to < line.len() {
        shown.push('…');
    }
    let col = line[from..pos].chars().count() + 1 + usize::from(cut_head);
    (shown, col as u32)
}

/// The blanks that put a caret under 1-based character column `col` of `line`: a tab where the
/// line has a tab, a space elsewhere (so the caret lines up whatever the tab width).
fn caret_pad(line: &str, col: u32) -> String {
    line.chars()
        .take(col.saturating_sub(1) as usize)
        .map(|c| if c == '\t' { '\t' } else { ' ' })
        .collect()
}

/// Whether any diagnostic is an error (then `citygen rules check` exits non-zero).
pub fn has_errors(d: &[Diagnostic]) -> bool {
    d.iter().any(|d| d.severity == Severity::Error)
}

/// Lints a parsed rule set. `source` must be the text `rules` was parsed from: it provides the
/// line shown under each diagnostic (a mismatching source gives empty lines, never a panic).
///
/// Returns every finding, sorted by (line, col, code, message), at most [`MAX_PER_CODE`] of
/// each code (then one more of that code counting the rest); empty for a clean file.
pub fn lint(rules: &RuleSet, source: &str) -> Vec<Diagnostic> {
    let cx = Cx::new(rules, source);
    let mut out = Sink::default();
    cx.undefined_symbols(&mut out);
    cx.unreachable_rules(&mut out);
    cx.probabilities(&mut out);
    cx.duplicate_rules(&mut out);
    cx.shape_kinds(&mut out);
    cx.recursion(&mut out);
    out.finish()
}

/// A diagnostic ordered by (line, col, code, message, severity): the order of [`lint`]'s output.
struct Ranked(Diagnostic);

impl Ranked {
    fn key(&self) -> (u32, u32, &'static str, &str, Severity) {
        let d = &self.0;
        (d.line, d.col, d.code, &d.message, d.severity)
    }
}

impl PartialEq for Ranked {
    fn eq(&self, other: &Self) -> bool {
        self.key() == other.key()
    }
}
impl Eq for Ranked {}
impl PartialOrd for Ranked {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Ranked {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.key().cmp(&other.key())
    }
}

/// The diagnostics of one code: the first [`MAX_PER_CODE`] in output order, and what was left
/// out.
#[derive(Default)]
struct Bucket {
    /// A max-heap, so that the last kept one is evicted when an earlier one comes.
    kept: BinaryHeap<Ranked>,
    dropped: usize,
    /// The first (in output order) of the ones left out.
    first_dropped: Option<Ranked>,
    /// Whether any left out is an error.
    dropped_error: bool,
}

/// Where the passes put their findings: memory stays bounded by [`MAX_PER_CODE`] per code
/// however many a file has.
#[derive(Default)]
struct Sink {
    buckets: BTreeMap<&'static str, Bucket>,
}

impl Sink {
    fn push(&mut self, d: Diagnostic) {
        let b = self.buckets.entry(d.code).or_default();
        b.kept.push(Ranked(d));
        if b.kept.len() > MAX_PER_CODE {
            if let Some(last) = b.kept.pop() {
                b.dropped += 1;
                b.dropped_error |= last.0.severity == Severity::Error;
                if b.first_dropped.as_ref().is_none_or(|f| last < *f) {
                    b.first_dropped = Some(last);
                }
            }
        }
    }

    /// How many diagnostics of `code` were pushed.
    fn count(&self, code: &str) -> usize {
        self.buckets
            .get(code)
            .map_or(0, |b| b.kept.len() + b.dropped)
    }

    /// Everything kept, sorted, with one "N more" diagnostic per code that was cut, at the
    /// place of the first one left out.
    fn finish(self) -> Vec<Diagnostic> {
        let mut out = Vec::new();
        for (code, b) in self.buckets {
            out.extend(b.kept.into_iter().map(|r| r.0));
            if let Some(Ranked(first)) = b.first_dropped {
                let kind = if b.dropped_error {
                    "findings (some are errors)"
                } else {
                    "findings"
                };
                out.push(Diagnostic {
                    severity: if b.dropped_error {
                        Severity::Error
                    } else {
                        first.severity
                    },
                    message: format!(
                        "{} more `{code}` {kind} from here on are not shown: rules check lists at \
                         most {MAX_PER_CODE} of each kind",
                        b.dropped
                    ),
                    ..first
                });
            }
        }
        out.sort_by(|a, b| {
            (a.line, a.col, a.code, &a.message, a.severity)
                .cmp(&(b.line, b.col, b.code, &b.message, b.severity))
        });
        out
    }
}

/// Shape kinds as a bit set, mirroring [`super::Geometry`]'s variants.
type Kinds = u8;
const LOT: Kinds = 1;
const VOLUME: Kinds = 2;
const FACE: Kinds = 4;

fn kind_name(k: Kinds) -> &'static str {
    match k {
        LOT => "lot",
        VOLUME => "volume",
        _ => "face",
    }
}

/// The lint context: the rule set seen through its public API, indexed once.
struct Cx<'a> {
    rules: &'a RuleSet,
    source: &'a str,
    /// Byte offset of the start of each line of `source`.
    line_starts: Vec<usize>,
    /// Symbol names by id (ids are dense from 0).
    names: Vec<&'a str>,
    /// Rule indices (into `rules.rules()`) per predecessor id, in source order.
    by_pred: Vec<Vec<usize>>,
    /// The resolved selection weight of each rule, as the interpreter uses it.
    weights: Vec<f64>,
    /// The axiom's id, if it is interned (a `set_axiom` to an unknown name is not).
    axiom: Option<SymbolId>,
}

impl<'a> Cx<'a> {
    fn new(rules: &'a RuleSet, source: &'a str) -> Cx<'a> {
        let mut names = Vec::new();
        while let Some(n) = rules.symbol(names.len() as SymbolId) {
            names.push(n);
        }
        let all = rules.rules();
        let mut by_pred = vec![Vec::new(); names.len()];
        for (i, r) in all.iter().enumerate() {
            if let Some(list) = by_pred.get_mut(r.pred as usize) {
                list.push(i);
            }
        }
        // Weights come from `rules_for`, the same resolution the interpreter selects with;
        // rules are matched back to their index by address (the slice is in memory order, so
        // a binary search finds each).
        let mut weights = vec![0.0; all.len()];
        for (id, name) in names.iter().enumerate() {
            if by_pred[id].is_empty() {
                continue;
            }
            for (rule, w) in rules.rules_for(name) {
                let at = all.binary_search_by(|r| (r as *const Rule).cmp(&(rule as *const Rule)));
                if let Ok(i) = at {
                    weights[i] = w;
                }
            }
        }
        let axiom = names
            .iter()
            .position(|n| *n == rules.axiom())
            .map(|i| i as SymbolId);
        let line_starts = std::iter::once(0)
            .chain(source.match_indices('\n').map(|(i, _)| i + 1))
            .collect();
        Cx {
            rules,
            source,
            line_starts,
            names,
            by_pred,
            weights,
            axiom,
        }
    }

    fn name(&self, id: SymbolId) -> &'a str {
        self.names.get(id as usize).copied().unwrap_or("?")
    }

    /// `` `name` `` for messages, cut to [`MAX_NAME_CHARS`] characters.
    fn q(&self, id: SymbolId) -> String {
        quote(self.name(id))
    }

    fn has_rules(&self, id: SymbolId) -> bool {
        self.by_pred.get(id as usize).is_some_and(|l| !l.is_empty())
    }

    fn rule(&self, i: usize) -> &'a Rule {
        &self.rules.rules()[i]
    }

    /// A diagnostic at `span` (its line and column; the byte offset finds the place in the
    /// line without counting characters from its start).
    fn diag(
        &self,
        severity: Severity,
        code: &'static str,
        span: Span,
        message: String,
    ) -> Diagnostic {
        let at = span.line.saturating_sub(1) as usize;
        let (line_text, text_col) = match self.line_starts.get(at) {
            Some(&start) => {
                // The line ends before the next line's start (its `\n`), or at the end.
                let end = self
                    .line_starts
                    .get(at + 1)
                    .map_or(self.source.len(), |&next| next - 1);
                let line = self.source[start..end].trim_end_matches('\r');
                let pos = span.offset.wrapping_sub(start);
                let pos = if pos <= line.len() && line.is_char_boundary(pos) {
                    pos
                } else {
                    // A source that is not the one parsed: find the column by counting.
                    line.char_indices()
                        .nth(span.col.saturating_sub(1) as usize)
                        .map_or(line.len(), |(i, _)| i)
                };
                line_window(line, pos)
            }
            None => (String::new(), span.col),
        };
        Diagnostic {
            severity,
            code,
            file: self.rules.file().to_string(),
            line: span.line,
            col: span.col,
            message,
            line_text,
            text_col,
        }
    }

    /// Successor symbols with no rule that are not known terminals.
    fn undefined_symbols(&self, out: &mut Sink) {
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
    fn reachable(&self) -> Vec<bool> {
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
    fn unreachable_rules(&self, out: &mut Sink) {
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
    fn probabilities(&self, out: &mut Sink) {
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
    fn duplicate_rules(&self, out: &mut Sink) {
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

    /// The shape kinds each symbol can meet, from the axiom (a lot), to a fixpoint.
    fn kinds(&self) -> Vec<Kinds> {
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
    fn shape_kinds(&self, out: &mut Sink) {
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

    /// Recursions that only the caps stop: `exponential-growth` and `non-terminating`.
    ///
    /// The rule graph has an edge from a rule's predecessor to each of its successor entries.
    /// A recursion is a cycle of it (a strongly connected component); only cycles are looked at,
    /// so the shipped rulesets and every ruleset the KB compiler writes (which are trees) are
    /// never reported. Each edge of a cycle is classed by what its operation does to the piece
    /// it makes, following the interpreter's rules ([`super::interp`]):
    ///
    /// * **Shrinking, by a fixed amount** (the recursion is *bounded*): a `split` (absolute sizes)
    ///   along an axis that no rule of the cycle can enlarge, whose entry either comes after an
    ///   entry of positive constant size `c` (the piece is then at most the parent's length
    ///   minus `c`, or not made at all), or, on a shape that is always a face, has a size written
    ///   `E - c` with `E` at most the axis size (`sx`, `sx/2`, `sx*0.5`; a face's last piece is
    ///   never stretched to the rest, a volume's is). Every trip round the cycle through such an
    ///   edge takes at least `c` metres off an axis that never grows back, so the recursion ends
    ///   after at most length/`c` trips, and (the pieces of a split sharing their parent's
    ///   length) with at most about length/`c` shapes: `a -> split(X, 1, sx-1){wall | a}` is
    ///   not reported. This holds only when no rule of the cycle copies the shape into it twice
    ///   or more (a relabel, `S`, `T`, `R`, `extrude` or `comp` with two successors in it: the
    ///   copies do not share the length, and the count doubles at each trip within the bounded
    ///   depth), so in such a cycle no edge counts as shrinking. The axes that can grow back:
    ///   `S` whose size is not visibly at most the current one, `extrude` (Y and Z), `comp` (a
    ///   face's width may be the volume's depth). The depth of a bounded recursion still grows
    ///   with the scope (about one level per `c` metres), which this lint does not check.
    /// * **Never dropping**: relabel, `S`, `T`, `R` and `extrude` make the whole shape again; a
    ///   `repeat` with a one-size pattern makes pieces between one and two sizes long, which
    ///   repeat once, unchanged, for ever (a volume narrower than the size gets one copy of its
    ///   own length); the first entry of a `split` with a positive constant size (every entry
    ///   before it being 0) is always made, of that size (or the whole length when it does not
    ///   fit), again and again; a `split` or `rsplit` with one entry gives its piece the whole
    ///   length (on a lot or volume; `rsplit` on anything); a `comp` entry that takes a face of a
    ///   box (a face extruded is a box) makes it every time.
    /// * **Others**: `split` and `rsplit` pieces that can be dropped or that shrink by a factor,
    ///   and the pieces of a `repeat` of two or more sizes (each a share of the parent, as in
    ///   `rsplit`): they may end the recursion, or shrink it until pieces are thinner than
    ///   1e-9 m, which takes tens of levels; not judged either way.
    ///
    /// The shrinking edges removed, a cycle left is **unbounded**. For it, the expected number
    /// of shapes of the cycle that one shape makes per level is the largest eigenvalue ρ of the
    /// mean matrix (rule probabilities times the pieces each entry makes: one per entry; a
    /// `comp` entry's faces of a box; a `repeat` entry one copy, or two when a rule of the cycle
    /// can enlarge the repeat's axis, since its count is then renewed every trip). ρ > 1 is
    /// **exponential growth**: about ρ^depth shapes, so `max_shapes` stops the derivation after
    /// ln(max_shapes)/ln ρ levels (`a -> split(X, sx/2, sx/2){a | a}`: 2^depth, 17 levels). ρ = 1
    /// with a rule making two or more is a critical branching process: most derivations end,
    /// some reach the caps. ρ < 1 ends quickly (almost surely) and is not reported. Otherwise, a
    /// cycle of never-dropping edges is **non-terminating**: nothing in it can end the recursion
    /// except another alternative, so `max_depth` stops it (`a -> repeat(X, 1){a}`).
    ///
    /// Only recursions the axiom reaches are looked at. One warning per cycle, at the first rule
    /// (in the file) that makes two or more shapes of it (growth) or that stays in it
    /// (non-termination). The work is linear in the rule set
    /// (three strongly-connected-component passes) plus a bounded number of power iterations.
    fn recursion(&self, out: &mut Sink) {
        let n = self.names.len();
        let kinds = self.kinds();
        // Unknown (unreachable) symbols can be anything.
        let kind = |s: usize| match kinds.get(s).copied().unwrap_or(0) {
            0 => LOT | VOLUME | FACE,
            k => k,
        };
        // Only what a derivation can reach: a never-used rule cannot reach a cap (and is
        // reported as unreachable).
        let reachable = self.reachable();
        let mut edges = self.rule_edges(&kind);
        edges.retain(|e| reachable.get(e.from).copied().unwrap_or(false));
        let adj = |keep: &dyn Fn(&Edge) -> bool| {
            let mut adj: Vec<Vec<usize>> = vec![Vec::new(); n];
            for e in edges.iter().filter(|e| keep(e)) {
                adj[e.from].push(e.to);
            }
            adj
        };
        // 1. The recursions; per recursion, the axes its rules can enlarge, and whether a rule
        // copies the shape (not a split's share of it) into it twice or more.
        let comp1 = sccs(&adj(&|_| true));
        let mut enlarged: BTreeMap<usize, [bool; 3]> = BTreeMap::new();
        let mut copies: BTreeMap<usize, f64> = BTreeMap::new();
        for e in &edges {
            if comp1[e.from] == comp1[e.to] {
                let op = &self.rule(e.rule).op;
                let slot = enlarged.entry(comp1[e.from]).or_default();
                for (ax, grows) in enlarges(op).iter().enumerate() {
                    slot[ax] |= grows;
                }
                if !matches!(op, Op::Split { .. }) {
                    *copies.entry(e.rule).or_default() += e.pieces;
                }
            }
        }
        let mut duplicating: BTreeSet<usize> = BTreeSet::new();
        for (&r, &n) in &copies {
            if n >= 2.0 {
                duplicating.insert(comp1[self.rule(r).pred as usize]);
            }
        }
        let grows_in = |e: &Edge, axis: Axis| {
            enlarged
                .get(&comp1[e.from])
                .is_some_and(|g| g[axis.index()])
        };
        // 2. Without the bounded edges: the unbounded recursions, with their growth.
        let unbounded = |e: &Edge| match e.shrinks {
            Some(axis) => grows_in(e, axis) || duplicating.contains(&comp1[e.from]),
            None => true,
        };
        let comp2 = sccs(&adj(&|e| unbounded(e)));
        let mut groups: BTreeMap<usize, Vec<&Edge>> = BTreeMap::new();
        for e in edges.iter().filter(|e| unbounded(e)) {
            if comp2[e.from] == comp2[e.to] {
                groups.entry(comp2[e.from]).or_default().push(e);
            }
        }
        let mut growing: BTreeSet<usize> = BTreeSet::new();
        for (&c, inner) in &groups {
            if self.growth(inner, &|e| grows_in(e, self.repeat_axis(e)), out) {
                growing.insert(c);
            }
        }
        // 3. Never-dropping cycles, where no growth was reported.
        let stays = |e: &Edge| unbounded(e) && e.never_drops && !growing.contains(&comp2[e.from]);
        let comp3 = sccs(&adj(&|e| stays(e)));
        let mut loops: BTreeMap<usize, Vec<&Edge>> = BTreeMap::new();
        for e in edges.iter().filter(|e| stays(e)) {
            if comp3[e.from] == comp3[e.to] {
                loops.entry(comp3[e.from]).or_default().push(e);
            }
        }
        for inner in loops.values() {
            self.never_ends(inner, out);
        }
    }

    /// The axis of a `repeat` edge (X for any other: unused).
    fn repeat_axis(&self, e: &Edge) -> Axis {
        match &self.rule(e.rule).op {
            Op::Split { axis, .. } => *axis,
            _ => Axis::X,
        }
    }

    /// Every (predecessor → successor entry) edge of the rule set, classed (see
    /// [`Cx::recursion`]).
    fn rule_edges(&self, kind: &dyn Fn(usize) -> Kinds) -> Vec<Edge> {
        let n = self.names.len();
        let mut edges = Vec::new();
        for (i, r) in self.rules.rules().iter().enumerate() {
            let from = r.pred as usize;
            if from >= n {
                continue;
            }
            let k = kind(from);
            let solid = k & (LOT | VOLUME) != 0;
            let faces_only = k == FACE;
            let boxed = match r.op {
                Op::Comp => box_faces(r),
                _ => Vec::new(),
            };
            for (j, x) in r.succs.iter().enumerate() {
                let to = x.symbol as usize;
                if to >= n {
                    continue;
                }
                let (pieces, never_drops, shrinks) = match &r.op {
                    Op::Relabel
                    | Op::Scale(_)
                    | Op::Translate(_)
                    | Op::Rotate(..)
                    | Op::Extrude(_) => (1.0, true, None),
                    Op::Comp => {
                        let b = boxed.get(j).copied().unwrap_or(0);
                        (b as f64, b > 0, None)
                    }
                    // One size: a piece 1-2 sizes long is one copy of the same length, for ever.
                    // More: each piece is a share of the parent, like rsplit's.
                    Op::Split {
                        kind: SplitKind::Repeat,
                        sizes,
                        ..
                    } => (1.0, sizes.len() == 1, None),
                    Op::Split {
                        kind: SplitKind::Relative,
                        sizes,
                        ..
                    } => (1.0, sizes.len() == 1, None),
                    Op::Split {
                        kind: SplitKind::Absolute,
                        axis,
                        sizes,
                    } => {
                        let before = &sizes[..j.min(sizes.len())];
                        let positive = |e: &Expr| const_range(e).is_some_and(|(lo, _)| lo > 1e-6);
                        let after_fixed = before.iter().any(positive);
                        let cut =
                            faces_only && sizes.get(j).and_then(|e| shrink_by(e, *axis)).is_some();
                        let shrinks = (after_fixed || cut).then_some(*axis);
                        // The first piece of positive constant size is always made (whole, or as
                        // the overflow: a volume's whole length, a face's truncated one), of that
                        // size again and again; a lone piece of a lot or volume gets the whole
                        // length.
                        let skipped =
                            |e: &Expr| const_range(e).is_some_and(|(_, hi)| hi <= EPS_SIZE);
                        let first_fixed =
                            sizes.get(j).is_some_and(positive) && before.iter().all(skipped);
                        let lone = sizes.len() == 1 && solid;
                        (1.0, shrinks.is_none() && (first_fixed || lone), shrinks)
                    }
                };
                edges.push(Edge {
                    from,
                    to,
                    rule: i,
                    pieces,
                    never_drops,
                    shrinks,
                });
            }
        }
        edges
    }

    /// The growth of one unbounded recursion (its edges `inner`, all inside it): reports
    /// `exponential-growth` and returns true when the expected shapes per level are ≥ 1 with
    /// a rule that makes two or more. `renewed` tells whether a `repeat` edge's count is renewed
    /// (its axis can be enlarged in the cycle).
    fn growth(&self, inner: &[&Edge], renewed: &dyn Fn(&Edge) -> bool, out: &mut Sink) -> bool {
        // Local numbering of the cycle's symbols.
        let mut local: BTreeMap<usize, usize> = BTreeMap::new();
        for e in inner {
            let next = local.len();
            local.entry(e.from).or_insert(next);
        }
        let is_repeat = |e: &Edge| {
            matches!(
                self.rule(e.rule).op,
                Op::Split {
                    kind: SplitKind::Repeat,
                    ..
                }
            )
        };
        let pieces = |e: &Edge| {
            if is_repeat(e) && renewed(e) {
                2.0 * e.pieces
            } else {
                e.pieces
            }
        };
        // Pieces of the cycle per rule, and the rules that make two or more.
        let mut per_rule: BTreeMap<usize, f64> = BTreeMap::new();
        for e in inner {
            *per_rule.entry(e.rule).or_default() += pieces(e);
        }
        let Some((&first, &most)) = per_rule
            .iter()
            .filter(|(_, &m)| m >= 2.0)
            .min_by_key(|(&r, _)| self.rule(r).span.offset)
        else {
            return false;
        };
        // The mean matrix, as weighted edges between local indices.
        let weighted: Vec<(usize, usize, f64)> = inner
            .iter()
            .filter_map(|e| {
                let p = self.choice_probability(e.rule);
                Some((*local.get(&e.from)?, *local.get(&e.to)?, p * pieces(e)))
            })
            .collect();
        let (lo, hi) = perron_bounds(local.len(), &weighted);
        if hi < 1.0 - 1e-9 {
            return false;
        }
        let r = self.rule(first);
        let renewed_repeat = inner
            .iter()
            .any(|e| e.rule == first && is_repeat(e) && renewed(e));
        let cycle = self.cycle_names(local.keys().copied());
        let caps = super::interp::Caps::default();
        let renewed_any = inner.iter().any(|e| is_repeat(e) && renewed(e));
        let makes = if renewed_repeat {
            "whose count of copies is renewed at every trip (an extrude, S or comp of the \
             recursion restores the length it divides)"
                .to_string()
        } else {
            format!(
                "which makes {} shapes of the recursion from one",
                fmt_num(most)
            )
        };
        let head = format!(
            "the rules for {cycle} recurse through {}, {makes}",
            op_label(&r.op)
        );
        let lod = lod_note(inner.iter().map(|e| e.rule), self);
        let rho = 0.5 * (lo + hi);
        // Growth when the lower bound is above 1, or (bounds not converged) the estimate is.
        let grows = lo > 1.0 + 1e-9 || (hi - lo > 1e-6 && rho > 1.0 + 1e-6);
        let chosen = inner
            .iter()
            .any(|e| self.choice_probability(e.rule) < 1.0 - PROB_EPS);
        let msg = if grows && renewed_any {
            format!(
                "{head}: the shape count may multiply by a repeat's count at every trip; the \
                 derivation stops at the shape cap (max_shapes, {} by default){lod}",
                caps.max_shapes
            )
        } else if grows {
            let levels = ((caps.max_shapes as f64).ln() / rho.ln()).ceil();
            format!(
                "{head}: the shape count grows {}× per level{} and may reach {}^depth shapes; \
                 the derivation stops at the shape cap (max_shapes, {} by default) about \
                 {levels} levels down{lod}",
                fmt_rho(rho),
                if chosen {
                    " on average (with the other alternatives' probabilities)"
                } else {
                    ""
                },
                fmt_rho(rho),
                caps.max_shapes,
            )
        } else {
            format!(
                "{head}, but with the other alternatives 1 on average: a critical branching \
                 process, which ends for most buildings but reaches the shape cap (max_shapes, \
                 {} by default) or the depth cap (max_depth, {}) for some{lod}",
                caps.max_shapes, caps.max_depth,
            )
        };
        out.push(self.diag(Severity::Warning, "exponential-growth", r.span, msg));
        true
    }

    /// A cycle of never-dropping edges (`inner`, all inside it): `non-terminating`, at its
    /// first rule in the file.
    fn never_ends(&self, inner: &[&Edge], out: &mut Sink) {
        let syms: BTreeSet<usize> = inner.iter().map(|e| e.from).collect();
        let Some(first) = inner
            .iter()
            .map(|e| e.rule)
            .min_by_key(|&r| self.rule(r).span.offset)
        else {
            return;
        };
        let staying: BTreeSet<usize> = inner.iter().map(|e| e.rule).collect();
        // Another alternative of a symbol of the cycle that does not stay in it.
        let escapes = syms
            .iter()
            .any(|&s| self.by_pred[s].iter().any(|i| !staying.contains(i)));
        let mut ops: Vec<&str> = Vec::new();
        let mut by_place: Vec<usize> = staying.iter().copied().collect();
        by_place.sort_by_key(|&r| self.rule(r).span.offset);
        for &r in &by_place {
            let name = self.rule(r).op.name();
            if !ops.contains(&name) {
                ops.push(name);
            }
        }
        let why = if ops.contains(&"repeat") {
            "; a one-size repeat makes one copy of the same length again"
        } else {
            ""
        };
        let caps = super::interp::Caps::default();
        let msg = format!(
            "the rules for {} recurse through operations that never drop the shape ({}{why}){}: \
             may not terminate; the derivation stops at the depth cap (max_depth, {} by \
             default){}",
            self.cycle_names(syms.iter().copied()),
            ops.join(", "),
            if escapes {
                " unless another alternative is chosen"
            } else {
                ""
            },
            caps.max_depth,
            lod_note(staying.iter().copied(), self)
        );
        out.push(self.diag(
            Severity::Warning,
            "non-terminating",
            self.rule(first).span,
            msg,
        ));
    }

    /// The probability that the interpreter picks rule `i` among its predecessor's rules
    /// (weights ≤ 0 never, unless all are: then uniformly).
    fn choice_probability(&self, i: usize) -> f64 {
        let list = &self.by_pred[self.rule(i).pred as usize];
        let w = |j: usize| {
            let x = self.weights[j];
            if x.is_finite() && x > 0.0 {
                x
            } else {
                0.0
            }
        };
        let total: f64 = list.iter().map(|&j| w(j)).sum();
        if total > 0.0 {
            w(i) / total
        } else {
            1.0 / list.len().max(1) as f64
        }
    }

    /// `` `a`, `b` and 3 more `` for the symbols of a cycle, in the order of their first rule.
    fn cycle_names(&self, syms: impl Iterator<Item = usize>) -> String {
        let mut ordered: Vec<usize> = syms.filter(|&t| !self.by_pred[t].is_empty()).collect();
        ordered.sort_by_key(|&t| self.rule(self.by_pred[t][0]).span.offset);
        let names: Vec<String> = ordered
            .iter()
            .take(MAX_LISTED)
            .map(|&t| self.q(t as SymbolId))
            .collect();
        list_names(&names, ordered.len())
    }
}

/// One edge of the rule graph: a rule's predecessor to one of its successor entries.
struct Edge {
    from: usize,
    to: usize,
    /// The rule (index into the rule set).
    rule: usize,
    /// Pieces of `to` the entry makes per application in the sustained regime (one; a comp
    /// entry's faces of a box; a repeat entry's one copy, doubled by the caller when renewed).
    pieces: f64,
    /// Whether the piece is always made, whatever the size (see [`Cx::recursion`]).
    never_drops: bool,
    /// The axis on which the piece is at least a fixed amount shorter than its parent.
    shrinks: Option<Axis>,
}

/// The faces of a box (a volume with one face per direction, a top and a bottom) each entry of
/// a `comp` rule takes, by the interpreter's first-match rule.
fn box_faces(r: &Rule) -> Vec<usize> {
    let mut taken = vec![0; r.succs.len()];
    let sides = [
        Selector::Front,
        Selector::Back,
        Selector::Left,
        Selector::Right,
    ];
    for face in sides.iter().chain(&[Selector::Top, Selector::Bottom]) {
        let side = sides.contains(face);
        let first = r.succs.iter().position(|x| match x.selector {
            Some(Selector::Side) | Some(Selector::Others) => side,
            Some(sel) => sel == *face,
            None => false,
        });
        if let Some(k) = first {
            taken[k] += 1;
        }
    }
    taken
}

/// The scope axes (X, Y, Z) an operation can make larger than its parent's: `S` unless its
/// size is visibly at most the current one, `extrude` (Z, and Y for a face pushed out), `comp`
/// (a face's width may be the volume's depth, a top face's height its depth). Splits, relabel,
/// `T` and `R` never do.
fn enlarges(op: &Op) -> [bool; 3] {
    match op {
        Op::Scale(e) => [
            !non_enlarging(&e[0], Axis::X),
            !non_enlarging(&e[1], Axis::Y),
            !non_enlarging(&e[2], Axis::Z),
        ],
        Op::Extrude(_) => [false, true, true],
        Op::Comp => [true, false, true],
        _ => [false; 3],
    }
}

/// The range of a constant expression (numbers, arithmetic, `rand` of constants), or `None`
/// when it reads a scope size or an attribute.
fn const_range(e: &Expr) -> Option<(f64, f64)> {
    let r = match e {
        Expr::Num(v) => (*v, *v),
        Expr::ScopeSize(_) | Expr::Attr(..) => return None,
        Expr::Rand(a, b) => {
            let (a, b) = (const_range(a)?, const_range(b)?);
            (a.0.min(b.0), a.1.max(b.1))
        }
        Expr::Neg(a) => {
            let a = const_range(a)?;
            (-a.1, -a.0)
        }
        Expr::Bin(op, a, b) => {
            let (a, b) = (const_range(a)?, const_range(b)?);
            match op {
                BinOp::Add => (a.0 + b.0, a.1 + b.1),
                BinOp::Sub => (a.0 - b.1, a.1 - b.0),
                BinOp::Mul | BinOp::Div => {
                    let b = if *op == BinOp::Div {
                        if b.0 <= 0.0 && b.1 >= 0.0 {
                            return None;
                        }
                        (1.0 / b.1, 1.0 / b.0)
                    } else {
                        b
                    };
                    let p = [a.0 * b.0, a.0 * b.1, a.1 * b.0, a.1 * b.1];
                    (
                        p.iter().copied().fold(f64::INFINITY, f64::min),
                        p.iter().copied().fold(f64::NEG_INFINITY, f64::max),
                    )
                }
            }
        }
    };
    (r.0.is_finite() && r.1.is_finite()).then_some(r)
}

/// Whether `e` is visibly at most the shape's size along `axis` (call it x ≥ 0): `x`, `x * c`
/// or `c * x` with 0 ≤ c ≤ 1, `x / c` with c ≥ 1, `x - c` with c ≥ 0, `x + c` with c ≤ 0, of
/// such forms.
fn non_enlarging(e: &Expr, axis: Axis) -> bool {
    let within =
        |c: &Expr, lo: f64, hi: f64| const_range(c).is_some_and(|r| r.0 >= lo && r.1 <= hi);
    match e {
        Expr::ScopeSize(a) => *a == axis,
        Expr::Bin(BinOp::Mul, a, b) => {
            (non_enlarging(a, axis) && within(b, 0.0, 1.0))
                || (non_enlarging(b, axis) && within(a, 0.0, 1.0))
        }
        Expr::Bin(BinOp::Div, a, b) => non_enlarging(a, axis) && within(b, 1.0, f64::INFINITY),
        Expr::Bin(BinOp::Sub, a, b) => non_enlarging(a, axis) && within(b, 0.0, f64::INFINITY),
        Expr::Bin(BinOp::Add, a, b) => {
            (non_enlarging(a, axis) && within(b, f64::NEG_INFINITY, 0.0))
                || (non_enlarging(b, axis) && within(a, f64::NEG_INFINITY, 0.0))
        }
        _ => false,
    }
}

/// The fixed amount `c > 0` by which `e` is visibly below the size along `axis`: `E - c` (or
/// `E + (-c)`) with `E` non-enlarging ([`non_enlarging`]) or itself such a form.
fn shrink_by(e: &Expr, axis: Axis) -> Option<f64> {
    let (base, c) = match e {
        Expr::Bin(BinOp::Sub, a, b) => (a, const_range(b)?.0),
        Expr::Bin(BinOp::Add, a, b) => (a, -const_range(b)?.1),
        _ => return None,
    };
    if c <= 1e-6 {
        return None;
    }
    if non_enlarging(base, axis) {
        Some(c)
    } else {
        shrink_by(base, axis).map(|d| d + c)
    }
}

/// Bounds [lo, hi] on the largest eigenvalue ρ of the non-negative `n` × `n` matrix given as
/// weighted edges (row, column, weight): Collatz–Wielandt bounds of a power iteration on
/// M + I (whose largest eigenvalue is ρ + 1 and which is aperiodic, so the iteration
/// converges on a cycle too). The iterations stop at a relative gap of 1e-9, or when 50 million
/// edge visits are spent.
fn perron_bounds(n: usize, edges: &[(usize, usize, f64)]) -> (f64, f64) {
    if n == 0 {
        return (0.0, 0.0);
    }
    let mut v = vec![1.0; n];
    let (mut lo, mut hi) = (0.0, f64::INFINITY);
    let rounds = (50_000_000 / (edges.len() + n)).clamp(1, 10_000);
    for _ in 0..rounds {
        let mut w = v.clone();
        for &(i, j, x) in edges {
            w[i] += x * v[j];
        }
        let (mut l, mut h) = (f64::INFINITY, 0.0_f64);
        for (a, b) in w.iter().zip(&v) {
            let q = a / b;
            l = l.min(q);
            h = h.max(q);
        }
        lo = f64::max(lo, l - 1.0);
        hi = f64::min(hi, h - 1.0);
        let top = w.iter().copied().fold(0.0, f64::max);
        if !(top.is_finite() && top > 0.0) || hi - lo <= 1e-9 * hi.abs().max(1.0) {
            break;
        }
        v = w.iter().map(|x| (x / top).max(1e-300)).collect();
    }
    (lo, hi)
}

/// A growth factor for messages: an integer as is, else two decimals.
fn fmt_rho(r: f64) -> String {
    if (r - r.round()).abs() < 1e-6 {
        format!("{}", r.round())
    } else {
        format!("{r:.2}")
    }
}

/// `, at LOD3 and LOD4 (where comp is applied)` when one of the rules is a `comp`: below LOD3 a
/// shape whose rule is `comp` stays a leaf, and the recursion ends there.
fn lod_note(rules: impl Iterator<Item = usize>, cx: &Cx<'_>) -> &'static str {
    let mut rules = rules;
    if rules.any(|r| matches!(cx.rule(r).op, Op::Comp)) {
        ", at LOD3 and LOD4 (where comp is applied)"
    } else {
        ""
    }
}

/// The strongly connected components of the graph on `0..adj.len()` whose edges are
/// `v -> adj[v][..]`: the component id of each vertex. Tarjan's algorithm with an explicit
/// stack, so a chain of 100,000 symbols costs time and memory linear in the graph and never
/// overflows the call stack.
fn sccs(adj: &[Vec<usize>]) -> Vec<usize> {
    const UNSEEN: usize = usize::MAX;
    let n = adj.len();
    let mut index = vec![UNSEEN; n];
    let mut low = vec![0; n];
    let mut on_stack = vec![false; n];
    let mut comp = vec![UNSEEN; n];
    let mut stack: Vec<usize> = Vec::new();
    // (vertex, next edge to look at)
    let mut call: Vec<(usize, usize)> = Vec::new();
    let (mut next_index, mut next_comp) = (0, 0);
    for root in 0..n {
        if index[root] != UNSEEN {
            continue;
        }
        call.push((root, 0));
        index[root] = next_index;
        low[root] = next_index;
        next_index += 1;
        stack.push(root);
        on_stack[root] = true;
        while let Some(&mut (v, ref mut e)) = call.last_mut() {
            if let Some(&w) = adj[v].get(*e) {
                *e += 1;
                if w >= n {
                    continue;
                }
                if index[w] == UNSEEN {
                    index[w] = next_index;
                    low[w] = next_index;
                    next_index += 1;
                    stack.push(w);
                    on_stack[w] = true;
                    call.push((w, 0));
                } else if on_stack[w] {
                    low[v] = low[v].min(index[w]);
                }
                continue;
            }
            call.pop();
            if let Some(&(parent, _)) = call.last() {
                low[parent] = low[parent].min(low[v]);
            }
            if low[v] == index[v] {
                while let Some(w) = stack.pop() {
                    on_stack[w] = false;
                    comp[w] = next_comp;
                    if w == v {
                        break;
                    }
                }
                next_comp += 1;
            }
        }
    }
    comp
}

/// What an operation makes of a shape of kind `k` (one bit), or why the interpreter refuses it.
/// Mirrors [`super::interp`]: comp needs a volume; a lot is flat (no Z split); a face has no
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
fn op_label(op: &Op) -> String {
    match op {
        Op::Split { kind, axis, .. } => format!("`{}({}, ...)`", kind.name(), axis.name()),
        other => format!("`{}`", other.name()),
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

/// `` `name` ``, cut to [`MAX_NAME_CHARS`] characters with `…` (a generated file may have
/// megabyte names).
fn quote(name: &str) -> String {
    format!("`{}`", cut(name))
}

/// `name`, cut to [`MAX_NAME_CHARS`] characters with `…`.
fn cut(name: &str) -> String {
    match name.char_indices().nth(MAX_NAME_CHARS) {
        Some((i, _)) => format!("{}…", &name[..i]),
        None => name.to_string(),
    }
}

/// `a, b, c`, or `a, b, c and 5 more` when `total` is more than the names shown.
fn list_names(shown: &[String], total: usize) -> String {
    let mut s = shown.join(", ");
    if total > shown.len() {
        s.push_str(&format!(" and {} more", total - shown.len()));
    }
    s
}

/// The candidate closest to `name`, if within 2 edits (and fewer edits than `name` has
/// characters, so `a` does not suggest `b`); ties go to the earlier candidate. Candidates
/// whose length differs by more than 2 are skipped unmeasured; each distance measured costs
/// its table's cells from `budget`, and a spent budget gives no suggestion (so that a file of
/// thousands of similar names stays fast). Names longer than [`MAX_NAME_CHARS`] get none.
pub(crate) fn suggest<'c>(
    name: &str,
    candidates: &[(&'c str, usize)],
    budget: &mut usize,
) -> Option<&'c str> {
    let len = name.chars().count();
    if len > MAX_NAME_CHARS {
        return None;
    }
    let mut best: Option<(usize, &str)> = None;
    for &(c, clen) in candidates {
        if c == name || clen.abs_diff(len) > 2 {
            continue;
        }
        let cost = (len + 1) * (clen + 1);
        if cost > *budget {
            return None;
        }
        *budget -= cost;
        let d = edit_distance(name, c);
        if d <= 2 && d < len && best.is_none_or(|(b, _)| d < b) {
            best = Some((d, c));
        }
    }
    best.map(|(_, c)| c)
}

fn plural(n: usize) -> &'static str {
    if n == 1 {
        ""
    } else {
        "s"
    }
}

/// A probability for messages: at most 6 decimals, trailing zeros trimmed (`1.2`, not
/// `1.2000000000000002`).
fn fmt_num(v: f64) -> String {
    let s = format!("{v:.6}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s.is_empty() || s == "-" {
        "0".to_string()
    } else {
        s.to_string()
    }
}

/// Levenshtein distance in characters (insert, delete, substitute each cost 1).
pub(crate) fn edit_distance(a: &str, b: &str) -> usize {
    let a: Vec<char> = a.chars().collect();
    let b: Vec<char> = b.chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    let mut cur = vec![0; b.len() + 1];
    for (i, ca) in a.iter().enumerate() {
        cur[0] = i + 1;
        for (j, cb) in b.iter().enumerate() {
            let sub = prev[j] + usize::from(ca != cb);
            cur[j + 1] = sub.min(prev[j + 1] + 1).min(cur[j] + 1);
        }
        std::mem::swap(&mut prev, &mut cur);
    }
    prev[b.len()]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grammar::parse;

    const FIG_3_19: &str = include_str!("../../knowledge_base/rules/fig3_19.cga");
    const TOULOUSE: &str = include_str!("../../knowledge_base/rules/toulouse_downtown.cga");

    fn run(src: &str) -> Vec<Diagnostic> {
        let rules = parse(src, "t.cga").unwrap_or_else(|e| panic!("{e}"));
        lint(&rules, src)
    }

    /// (code, line, col) of each diagnostic, in output order.
    fn codes(d: &[Diagnostic]) -> Vec<(&'static str, u32, u32)> {
        d.iter().map(|d| (d.code, d.line, d.col)).collect()
    }

    #[test]
    fn undefined_successor_warns_with_terminals_and_suggestion() {
        let d = run("a -> split(X,1,1,1){windowarae|windowarea|zzz}\n\
                     windowarea -> {wall|window|door|balcony}\n");
        assert_eq!(
            codes(&d),
            [("undefined-symbol", 1, 21), ("undefined-symbol", 1, 43)]
        );
        assert!(d.iter().all(|d| d.severity == Severity::Warning));
        assert!(d[0].message.contains("(wall, window, door, balcony)"));
        assert!(
            d[0].message.ends_with("did you mean `windowarea`?"),
            "{}",
            d[0].message
        );
        // Nothing within 2 edits of `zzz`: no suggestion.
        assert!(!d[1].message.contains("did you mean"), "{}", d[1].message);
        assert!(!has_errors(&d));
    }

    #[test]
    fn undefined_successor_suggests_a_terminal_but_not_for_one_letter_names() {
        let d = run("a -> split(X,1,1){windw|b}\n");
        assert_eq!(
            codes(&d),
            [("undefined-symbol", 1, 19), ("undefined-symbol", 1, 25)]
        );
        assert!(d[0].message.ends_with("did you mean `window`?"));
        // `b` is one edit from the defined `a`, but that is the whole name: no suggestion.
        assert!(!d[1].message.contains("did you mean"), "{}", d[1].message);
    }

    #[test]
    fn unreachable_rules_are_reported_once_per_predecessor_with_their_user() {
        let d = run("a -> b\nb -> wall\nc -> d = 0.5\nc -> wall = 0.5\nd -> window\n");
        assert_eq!(
            codes(&d),
            [("unreachable-rule", 3, 1), ("unreachable-rule", 5, 1)]
        );
        assert!(
            d[0].message.starts_with("rules for `c` are never used"),
            "{}",
            d[0].message
        );
        assert!(d[0].message.contains("axiom `a`"));
        assert!(
            d[1].message.ends_with("(only used by the unreachable `c`)"),
            "{}",
            d[1].message
        );
    }

    #[test]
    fn probabilities_above_one_are_an_error() {
        let d = run("a -> b = 0.7\na -> c = 0.5\nb -> wall\nc -> wall\n");
        assert_eq!(codes(&d), [("probability-sum", 1, 1)]);
        assert_eq!(d[0].severity, Severity::Error);
        assert!(
            d[0].message.contains("sum to 1.2 > 1 (lines 1, 2)"),
            "{}",
            d[0].message
        );
        assert!(has_errors(&d));
    }

    #[test]
    fn explicit_probabilities_above_one_starve_the_implicit_rules() {
        let d = run("a -> b = 0.7\na -> wall\na -> c = 0.5\nb -> wall\nc -> wall\n");
        assert_eq!(codes(&d), [("probability-sum", 1, 1)]);
        assert_eq!(d[0].severity, Severity::Error);
        assert!(
            d[0].message
                .contains("without probability (line 2) get weight 0"),
            "{}",
            d[0].message
        );
    }

    #[test]
    fn explicit_probabilities_below_one_are_normalised_with_a_warning() {
        let d = run("a -> b = 0.3\na -> c = 0.3\nb -> wall\nc -> wall\n");
        assert_eq!(codes(&d), [("probability-sum", 1, 1)]);
        assert_eq!(d[0].severity, Severity::Warning);
        assert!(d[0].message.contains("sum to 0.6 < 1"), "{}", d[0].message);
        assert!(d[0].message.contains("normalised"), "{}", d[0].message);
        // All zero: selection falls back to uniform, and says so.
        let d = run("a -> wall = 0\na -> window = 0\n");
        assert_eq!(codes(&d), [("probability-sum", 1, 1)]);
        assert!(d[0].message.contains("uniformly"), "{}", d[0].message);
    }

    #[test]
    fn implicit_rule_after_explicit_ones_reaching_one_is_never_chosen() {
        let d = run("a -> wall = 0.5\na -> window = 0.5\na -> door\n");
        assert_eq!(codes(&d), [("probability-sum", 3, 1)]);
        assert_eq!(d[0].severity, Severity::Warning);
        assert!(d[0].message.contains("never chosen"), "{}", d[0].message);
        // An implicit rule that takes the remainder is the normal way to write a default.
        assert!(run("a -> wall = 0.3\na -> window\n").is_empty());
    }

    #[test]
    fn negative_probability_is_an_error() {
        // The parser refuses `= -0.1`; a rule set built otherwise is still checked.
        let src = "a -> wall = 0.5\na -> window = 0.5\n";
        let mut rules = parse(src, "t.cga").unwrap_or_else(|e| panic!("{e}"));
        rules.rules[1].prob = Some(-0.1);
        let d = lint(&rules, src);
        assert!(
            d.iter().any(|d| d.code == "probability-sum"
                && d.line == 2
                && d.severity == Severity::Error),
            "{d:?}"
        );
    }

    #[test]
    fn duplicate_deterministic_rules_are_an_error_that_says_they_are_drawn() {
        let d = run("a -> b\nb -> wall\nb -> window\nb -> wall\n");
        assert_eq!(
            codes(&d),
            [("duplicate-rule", 3, 1), ("duplicate-rule", 4, 1)]
        );
        assert!(d.iter().all(|d| d.severity == Severity::Error));
        // The parser shares the weight equally: 1/3 each, no shadowing.
        assert!(
            d[0].message
                .contains("each is chosen at random with probability 0.333333"),
            "{}",
            d[0].message
        );
        assert!(d[0].message.contains("the first is at line 2"));
        assert!(!d[0].message.contains("identical"));
        assert!(d[1].message.contains("identical"), "{}", d[1].message);
        // Cross-check against the parser's resolution.
        let rules = parse("a -> wall\na -> window\n", "t.cga").unwrap_or_else(|e| panic!("{e}"));
        let w: Vec<f64> = rules.rules_for("a").iter().map(|x| x.1).collect();
        assert_eq!(w, [0.5, 0.5]);
    }

    #[test]
    fn duplicate_rules_starved_by_explicit_ones_say_never_chosen() {
        let d = run("a -> wall = 1\na -> window\na -> door\n");
        let dup: Vec<_> = d.iter().filter(|d| d.code == "duplicate-rule").collect();
        assert_eq!(dup.len(), 1);
        assert_eq!(dup[0].line, 3);
        assert!(
            dup[0].message.contains("never chosen"),
            "{}",
            dup[0].message
        );
    }

    #[test]
    fn operation_on_the_wrong_shape_kind() {
        // comp on the lot itself: always fails.
        let d = run("lot -> comp(){side:wall}\n");
        assert_eq!(codes(&d), [("op-shape-mismatch", 1, 1)]);
        assert_eq!(d[0].severity, Severity::Error);
        assert!(d[0].message.contains("extrude first"), "{}", d[0].message);
        // split(Y) and R on facades, split(Z) on a lot.
        let d = run("lot -> extrude(9){v}\nv -> comp(){side:f|top:r}\n\
                     f -> split(Y,1){wall}\nr -> R(Z,10){wall}\n");
        assert_eq!(
            codes(&d),
            [("op-shape-mismatch", 3, 1), ("op-shape-mismatch", 4, 1)]
        );
        assert!(d[0].message.contains("`split(Y, ...)`"), "{}", d[0].message);
        let d = run("lot -> split(Z,3){wall}\n");
        assert_eq!(codes(&d), [("op-shape-mismatch", 1, 1)]);
        // A symbol met both as a lot and as a volume: warning only.
        let d = run("lot -> m = 0.5\nlot -> extrude(3){m} = 0.5\nm -> comp(){side:wall}\n");
        assert_eq!(codes(&d), [("op-shape-mismatch", 3, 1)]);
        assert_eq!(d[0].severity, Severity::Warning);
        assert!(d[0].message.contains("can be a lot"), "{}", d[0].message);
        // extrude of a facade is supported (a balcony-like volume): no finding.
        assert!(
            run("lot -> extrude(9){v}\nv -> comp(){side:f}\nf -> extrude(1){wall}\n").is_empty()
        );
    }

    #[test]
    fn recursion_without_shrinking_may_not_terminate() {
        let d = run("a -> S(sx,sy,sz){a}\n");
        assert_eq!(codes(&d), [("non-terminating", 1, 1)]);
        assert_eq!(d[0].severity, Severity::Warning);
        assert_eq!(
            d[0].message,
            "the rules for `a` recurse through operations that never drop the shape (S): may not \
             terminate; the derivation stops at the depth cap (max_depth, 64 by default)"
        );
        // A two-symbol cycle: one finding, at its first rule, naming both.
        let d = run("a -> T(0,0,1){b}\nb -> {a:color=red}\n");
        assert_eq!(codes(&d), [("non-terminating", 1, 1)]);
        assert!(d[0].message.contains("`a`, `b`"), "{}", d[0].message);
        assert!(d[0].message.contains("(T, relabel)"), "{}", d[0].message);
        // An alternative way out.
        let d = run("a -> S(sx,sy,sz){a} = 0.5\na -> wall = 0.5\n");
        assert_eq!(codes(&d), [("non-terminating", 1, 1)]);
        assert!(d[0]
            .message
            .contains("unless another alternative is chosen"));
        // A split that drops the recursive piece once it no longer fits is fine.
        assert!(run("a -> split(X,1,sx-1){wall|a}\n").is_empty());
    }

    /// The message of the only finding of `src`, which must be a warning `code` at line:col.
    fn only(src: &str, code: &'static str, line: u32, col: u32) -> String {
        let d = run(src);
        assert_eq!(codes(&d), [(code, line, col)], "{src}: {d:?}");
        assert_eq!(d[0].severity, Severity::Warning);
        d[0].message.clone()
    }

    #[test]
    fn a_repeat_that_reproduces_itself_never_terminates() {
        // The bomb: each copy of a 1 m pattern on a piece 1-2 m long is one copy of the
        // same length, for ever (on a lot and a volume; a face too, the pattern being one size).
        let m = only("a -> repeat(X, 1){a}\n", "non-terminating", 1, 1);
        assert_eq!(
            m,
            "the rules for `a` recurse through operations that never drop the shape (repeat; a \
             one-size repeat makes one copy of the same length again): may not terminate; the \
             derivation stops at the depth cap (max_depth, 64 by default)"
        );
        only(
            "lot -> extrude(9){v}\nv -> comp(){side:f}\nf -> repeat(X, 1){f}\n",
            "non-terminating",
            3,
            1,
        );
        // On a face, a two-size pattern drops its pieces once the face is narrower than it.
        assert!(
            run("lot -> extrude(9){v}\nv -> comp(){side:f}\nf -> repeat(X, 2, 1){f|wall}\n")
                .is_empty()
        );
        // ... and on a volume, a two-size pattern makes a share of the parent (2/3 here),
        // which shrinks until it is thinner than 1e-9 m: not judged.
        assert!(run("lot -> extrude(9){v}\nv -> repeat(X, 2, 1){v|wall}\n").is_empty());
        // The first piece of a constant size: 1 m, then 1 m again, for ever (the second piece
        // comes after it, so it shrinks).
        let m = only(
            "lot -> extrude(9){a}\na -> split(Z, 1, 1){a|a}\n",
            "non-terminating",
            2,
            1,
        );
        assert!(m.contains("(split)"), "{m}");
        only(
            "lot -> extrude(9){a}\na -> split(X, 0, 1, sx - 1){wall|a|wall}\n",
            "non-terminating",
            2,
            1,
        );
        // A recursion the axiom never reaches is only an unreachable rule.
        let d = run("lot -> extrude(9){wall}\nz -> {z|z}\n");
        assert_eq!(codes(&d), [("unreachable-rule", 2, 1)]);
        // A one-entry split of a volume gives the piece the whole length again.
        only(
            "lot -> extrude(9){v}\nv -> split(X, sx - 1){v}\n",
            "non-terminating",
            2,
            1,
        );
        // A box's front is always there: comp and extrude make a recursion of one face.
        let m = only(
            "lot -> extrude(9){v}\nv -> comp(){front:f}\nf -> extrude(1){v}\n",
            "non-terminating",
            2,
            1,
        );
        assert!(
            m.ends_with("(max_depth, 64 by default), at LOD3 and LOD4 (where comp is applied)"),
            "{m}"
        );
    }

    #[test]
    fn recursion_that_multiplies_the_shapes_is_exponential_growth() {
        let m = only(
            "a -> split(X, sx/2, sx/2){a|a}\n",
            "exponential-growth",
            1,
            1,
        );
        assert_eq!(
            m,
            "the rules for `a` recurse through `split(X, ...)`, which makes 2 shapes of the \
             recursion from one: the shape count grows 2× per level and may reach 2^depth \
             shapes; the derivation stops at the shape cap (max_shapes, 100000 by default) about \
             17 levels down"
        );
        // A relabel to two copies of itself: growth, reported once (not also non-terminating).
        let m = only("a -> {a|a}\n", "exponential-growth", 1, 1);
        assert!(m.contains("through `relabel`, which makes 2 shapes"), "{m}");
        // A three-way repeat pattern, at the rule that branches.
        let m = only(
            "lot -> extrude(9){v}\nv -> repeat(X, 1, 1, 1){v|w|v}\nw -> {v}\n",
            "exponential-growth",
            2,
            1,
        );
        assert!(
            m.contains("`v`, `w`") && m.contains("makes 3 shapes"),
            "{m}"
        );
        // comp's four side faces of a box, each extruded back into a volume: 4 every 2 levels.
        let m = only(
            "lot -> extrude(3){v}\nv -> comp(){side:f}\nf -> extrude(1){v}\n",
            "exponential-growth",
            2,
            1,
        );
        assert!(
            m.contains("makes 4 shapes") && m.contains("grows 2× per level"),
            "{m}"
        );
        assert!(
            m.ends_with(", at LOD3 and LOD4 (where comp is applied)"),
            "{m}"
        );
        // A repeat whose length an extrude restores: its count is renewed at every trip.
        let m = only(
            "lot -> extrude(10){b}\nb -> repeat(Z, 1){c}\nc -> extrude(10){b}\n",
            "exponential-growth",
            2,
            1,
        );
        assert!(
            m.contains("whose count of copies is renewed at every trip"),
            "{m}"
        );
        assert!(m.contains("may multiply by a repeat's count"), "{m}");
        // Probabilities: 3 pieces with p = 0.5 is 1.5 per level on average.
        let m = only(
            "a -> rsplit(X, 1, 1, 1){a|a|a} = 0.5\na -> wall = 0.5\n",
            "exponential-growth",
            1,
            1,
        );
        assert!(
            m.contains(
                "grows 1.50× per level on average (with the other alternatives' probabilities)"
            ),
            "{m}"
        );
        assert!(m.contains("about 29 levels down"), "{m}");
    }

    #[test]
    fn critical_and_subcritical_branching() {
        // Two copies half the time: on average one, but a fat tail (with an extrude in front,
        // 7 of 300 seeds reached max_depth through `rules derive`).
        let m = only(
            "a -> {a|a} = 0.5\na -> wall = 0.5\n",
            "exponential-growth",
            1,
            1,
        );
        assert!(m.contains("a critical branching process"), "{m}");
        // 0.6 per level on average: ends quickly, not reported.
        assert!(run("a -> rsplit(X, 0.5, 0.5){a|a} = 0.3\na -> wall = 0.7\n").is_empty());
    }

    #[test]
    fn bounded_recursion_is_not_reported() {
        // Each trip takes a fixed metre off an axis that nothing in the recursion enlarges.
        for src in [
            "a -> split(X, 1, sx - 1){wall|a}\n",
            "a -> split(X, 1, sx/2 - 1, sx/2){wall|a|a}\n",
            // On faces: `E - c` shrinks (the rest is a wall, never given to the last piece).
            "lot -> extrude(9){v}\nv -> comp(){side:f}\nf -> split(X, sx - 1){f}\n",
            "lot -> extrude(9){v}\nv -> comp(){side:f}\nf -> split(X, sx/2 - 0.5, sx/2 - 0.5){f|f}\n",
            // rand of constants is a positive constant.
            "a -> split(Y, rand(0.5, 1), sy - 1){wall|a}\n",
        ] {
            let d = run(src);
            assert!(d.is_empty(), "{src}: {d:?}");
        }
        // A split piece that only shrinks by a factor, or on a volume whose last piece takes
        // the rest, is not bounded by this rule: growth through two of them is reported.
        only(
            "a -> split(X, sx/2, sx/2){a|a}\n",
            "exponential-growth",
            1,
            1,
        );
        only(
            "lot -> extrude(9){v}\nv -> split(X, sx/2 - 0.5, sx/2 - 0.5){v|v}\n",
            "exponential-growth",
            2,
            1,
        );
        // A fixed piece does not bound the recursion when the recursion can grow that axis
        // back: S scales X up again.
        only(
            "a -> split(X, 1, sx - 1){wall|b}\nb -> S(sx*2, sy, sz){a|a}\n",
            "exponential-growth",
            2,
            1,
        );
        // ... nor does an S that keeps or shrinks the axis when it makes two copies: the copies
        // do not share the length, so the count doubles at every trip within the bounded depth.
        only(
            "a -> split(X, 1, sx - 1){wall|b}\nb -> S(sx*rand(0.5,1), sy, sz){a|a}\n",
            "exponential-growth",
            2,
            1,
        );
        // One copy is fine.
        assert!(
            run("a -> split(X, 1, sx - 1){wall|b}\nb -> S(sx*rand(0.5,1), sy, sz){a}\n").is_empty()
        );
    }

    #[test]
    fn shipped_and_compiled_rulesets_have_no_recursion_findings() {
        for (name, src) in [
            ("fig3_19.cga", FIG_3_19),
            ("toulouse_downtown.cga", TOULOUSE),
        ] {
            let rules = parse(src, name).unwrap_or_else(|e| panic!("{e}"));
            let d = lint(&rules, src);
            assert!(
                !d.iter()
                    .any(|d| d.code == "exponential-growth" || d.code == "non-terminating"),
                "{name}: {d:?}"
            );
        }
        // Every appearance of every zone of the shipped KB, as `kb compile` prints it, and the
        // compiler's variants (balconies, irregular and short windows).
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("knowledge_base/kb.xml");
        let (kb, _) = crate::kb::KnowledgeBase::load(&path).unwrap_or_else(|e| panic!("{e}"));
        let mut texts: Vec<(String, String)> = Vec::new();
        for z in kb.zones() {
            texts.extend(
                crate::kb::tools::compile_zone(&kb, &z.path).unwrap_or_else(|e| panic!("{e}")),
            );
        }
        let tags = crate::input::tags::BuildingTags::default();
        let (style, _) = kb.style_for(0, &tags, &mut crate::rng::Rng::new(1, 1));
        for balconies in [0.0, 0.5, 1.0] {
            for wh in [
                crate::kb::WindowHeight::Tall,
                crate::kb::WindowHeight::Short,
                crate::kb::WindowHeight::Irregular,
            ] {
                let s = crate::kb::Style {
                    balconies,
                    window_height: wh,
                    ..style.clone()
                };
                texts.push((
                    format!("{balconies} {wh:?}"),
                    crate::kb::compile::ruleset_text(&s),
                ));
            }
        }
        assert!(texts.len() > 20, "{}", texts.len());
        for (label, text) in &texts {
            let rules = parse(text, label).unwrap_or_else(|e| panic!("{label}: {e}"));
            let d = lint(&rules, text);
            assert!(d.is_empty(), "{label}: {d:?}\n{text}");
        }
    }

    #[test]
    fn toulouse_downtown_reports_exactly_the_floor2_branch() {
        let rules = parse(TOULOUSE, "toulouse_downtown.cga").unwrap_or_else(|e| panic!("{e}"));
        let d = lint(&rules, TOULOUSE);
        assert!(!has_errors(&d), "{d:?}");
        let got: Vec<(&str, u32, &str)> = d
            .iter()
            .map(|d| {
                let sym = d.line_text.split(" ->").next().unwrap_or("");
                (d.code, d.line, sym)
            })
            .collect();
        assert_eq!(
            got,
            [
                ("unreachable-rule", 14, "floor2"),
                ("unreachable-rule", 16, "face2"),
                ("unreachable-rule", 18, "upper_face2"),
                ("unreachable-rule", 21, "windowarea2"),
                ("unreachable-rule", 23, "vwindow2"),
                ("unreachable-rule", 26, "bwindow2"),
            ]
        );
        assert!(d.iter().all(|d| d.severity == Severity::Warning));
        assert!(d[0]
            .message
            .contains("`floor2` is not reachable from the axiom `lot`"));
        assert!(d[1]
            .message
            .ends_with("(only used by the unreachable `floor2`)"));
    }

    #[test]
    fn figure_3_19_is_clean() {
        let rules = parse(FIG_3_19, "fig3_19.cga").unwrap_or_else(|e| panic!("{e}"));
        let d = lint(&rules, FIG_3_19);
        assert!(!has_errors(&d));
        assert!(d.is_empty(), "{d:?}");
    }

    #[test]
    fn errors_and_warnings_together_sorted_by_place() {
        let src = "a -> b\na -> c\nb -> windw\nc -> wall\n";
        let d = run(src);
        assert_eq!(
            codes(&d),
            [("duplicate-rule", 2, 1), ("undefined-symbol", 3, 6)]
        );
        assert_eq!(d[0].severity, Severity::Error);
        assert_eq!(d[1].severity, Severity::Warning);
        assert!(has_errors(&d));
        assert!(!has_errors(&d[1..]));
        assert_eq!(d, run(src), "deterministic");
    }

    #[test]
    fn display_has_location_code_source_line_and_caret() {
        let src = "a -> b = 0.5\r\n\ta -> c = 0.6\r\nb -> wall\nc -> winow\n";
        let d = run(src);
        assert_eq!(
            codes(&d),
            [("probability-sum", 1, 1), ("undefined-symbol", 4, 6)]
        );
        assert_eq!(
            d[1].to_string(),
            "t.cga:4:6: warning[undefined-symbol]: `winow` has no rule and is not a known \
             terminal (wall, window, door, balcony): it becomes a leaf of the shape tree with no \
             element kind; did you mean `window`?\nc -> winow\n     ^"
        );
        assert!(d[0]
            .to_string()
            .starts_with("t.cga:1:1: error[probability-sum]: "));
        assert!(d[0].to_string().ends_with("\na -> b = 0.5\n^"));
        // Tabs are kept in the caret line so that it lines up; CR is not shown.
        let d = run("b -> wall\n\tb -> window\n");
        assert_eq!(codes(&d), [("duplicate-rule", 2, 2)]);
        assert!(
            d[0].to_string().ends_with("\n\tb -> window\n\t^"),
            "{:?}",
            d[0].to_string()
        );
    }

    #[test]
    fn mismatched_source_gives_empty_lines_not_a_panic() {
        let rules = parse("a -> b\na -> c\n", "t.cga").unwrap_or_else(|e| panic!("{e}"));
        let d = lint(&rules, "");
        assert!(!d.is_empty());
        assert!(d.iter().all(|d| d.line_text.is_empty()));
        assert!(d[0].to_string().ends_with("\n\n^"));
    }

    #[test]
    fn findings_past_the_cap_are_counted_and_long_lines_are_windowed() {
        // One line of 300 undefined successors (about 2,000 characters).
        let succ: Vec<String> = (0..300).map(|i| format!("u{i}")).collect();
        let sizes = vec!["1"; 300].join(",");
        let src = format!("lot -> split(X,{sizes}){{{}}}\n", succ.join("|"));
        let d = run(&src);
        assert_eq!(d.len(), MAX_PER_CODE + 1, "{:?}", codes(&d));
        assert!(d.iter().all(|d| d.code == "undefined-symbol"));
        // The first 100 in file order are listed, then one diagnostic at the 101st.
        let line = src.lines().next().unwrap_or_default();
        let col_of = |name: &str| {
            line.find(&format!("{{{name}|"))
                .or_else(|| line.find(&format!("|{name}|")))
                .map(|i| i as u32 + 2)
        };
        assert_eq!(Some(d[0].col), col_of("u0"));
        assert_eq!(Some(d[99].col), col_of("u99"));
        assert_eq!(Some(d[100].col), col_of("u100"));
        assert_eq!(
            d[100].message,
            "200 more `undefined-symbol` findings from here on are not shown: rules check lists \
             at most 100 of each kind"
        );
        for x in &d {
            // 80 characters each side, two ellipses: never the whole 2,000-character line.
            assert!(
                x.line_text.chars().count() <= 2 * CONTEXT_CHARS + 2,
                "{}",
                x.line_text
            );
            // The caret is under the successor's first character.
            let under: String = x
                .line_text
                .chars()
                .skip(x.text_col as usize - 1)
                .take(2)
                .collect();
            assert!(under.starts_with('u'), "{under:?} in {:?}", x.line_text);
            let shown = x.to_string();
            let caret = shown.lines().last().unwrap_or_default();
            assert_eq!(caret.chars().count() as u32, x.text_col, "{shown}");
        }
        assert!(d[50].line_text.starts_with('…') && d[50].line_text.ends_with('…'));
        // A short line is kept whole, with the caret at its column.
        let d = run("lot -> {zz}\n");
        assert_eq!((d[0].line_text.as_str(), d[0].text_col), ("lot -> {zz}", 9));
    }

    #[test]
    fn line_window_cuts_at_characters_not_bytes() {
        let line = format!("{}X{}", "é".repeat(200), "ü".repeat(200));
        let pos = line.find('X').unwrap_or_default();
        let (shown, col) = line_window(&line, pos);
        assert_eq!(shown.chars().count(), 1 + 2 * CONTEXT_CHARS + 1);
        assert_eq!(shown.chars().nth(col as usize - 1), Some('X'));
        assert!(shown.starts_with("…é") && shown.ends_with("ü…"));
        // At the start of a long line: no leading ellipsis.
        let (shown, col) = line_window(&line, 0);
        assert_eq!(col, 1);
        assert!(shown.starts_with('é') && shown.ends_with('…'));
        assert_eq!(line_window("", 0), (String::new(), 1));
    }

    #[test]
    fn generated_files_with_thousands_of_symbols_lint_in_linear_work() {
        // A cycle of 20,000 symbols through T: one finding, with a bounded list of names.
        let n = 20_000;
        let mut src = String::from("lot -> s0\n");
        for i in 0..n {
            src.push_str(&format!("s{i} -> T(0,0,1){{s{}}}\n", (i + 1) % n));
        }
        let d = run(&src);
        assert_eq!(codes(&d), [("non-terminating", 2, 1)]);
        assert!(
            d[0].message
                .contains("`s0`, `s1`, `s2`, `s3`, `s4`, `s5`, `s6`, `s7` and 19992 more"),
            "{}",
            d[0].message
        );
        // A chain of 20,000 unreachable rules: each names its one user; 100 listed.
        let mut src = String::from("lot -> wall\n");
        for i in 0..n {
            src.push_str(&format!("c{i} -> c{}\n", i + 1));
        }
        let d: Vec<Diagnostic> = run(&src)
            .into_iter()
            .filter(|d| d.code == "unreachable-rule")
            .collect();
        assert_eq!(d.len(), MAX_PER_CODE + 1);
        assert!(
            d[1].message
                .ends_with("(only used by the unreachable `c0`)"),
            "{}",
            d[1].message
        );
        assert!(d[MAX_PER_CODE]
            .message
            .starts_with("19900 more `unreachable-rule` findings"));
        // 50,000 probabilities of one predecessor: one error listing 8 lines.
        let src = "lot -> wall = 0.00004\n".repeat(50_000);
        let d = run(&src);
        assert_eq!(codes(&d), [("probability-sum", 1, 1)]);
        assert!(
            d[0].message
                .contains("(lines 1, 2, 3, 4, 5, 6, 7, 8 and 49992 more)"),
            "{}",
            d[0].message
        );
    }

    #[test]
    fn long_names_are_cut_in_messages_and_get_no_suggestion() {
        let long = "x".repeat(10_000);
        let src = format!("lot -> {{{long}|{long}y}}\n{long}z -> wall\n");
        let d = run(&src);
        assert_eq!(
            codes(&d),
            [
                ("undefined-symbol", 1, 9),
                ("undefined-symbol", 1, 10_010),
                ("unreachable-rule", 2, 1)
            ]
        );
        for x in &d {
            assert!(x.message.len() < 400, "{}", x.message);
            assert!(!x.message.contains("did you mean"), "{}", x.message);
        }
        assert!(d[0]
            .message
            .starts_with(&format!("`{}…` has no rule", "x".repeat(MAX_NAME_CHARS))));
    }

    #[test]
    fn suggestions_stop_when_their_budget_is_spent() {
        let candidates = [("window", 6), ("wall", 4)];
        let mut budget = 1_000;
        assert_eq!(suggest("windw", &candidates, &mut budget), Some("window"));
        assert_eq!(
            budget,
            1_000 - 6 * 7 - 6 * 5,
            "one table per measured candidate"
        );
        // Not enough left for the first table: no suggestion, nothing spent.
        let mut budget = 10;
        assert_eq!(suggest("windw", &candidates, &mut budget), None);
        assert_eq!(budget, 10);
        // A file of thousands of similar names still lints, and the first ones get suggestions.
        let succ: Vec<String> = (0..5_000).map(|i| format!("d{i:04}x")).collect();
        let mut src = format!("lot -> {{{}}}\n", succ.join("|"));
        for i in 0..5_000 {
            src.push_str(&format!("d{i:04} -> wall\n"));
        }
        let d = run(&src);
        assert!(
            d[0].message.ends_with("did you mean `d0000`?"),
            "{}",
            d[0].message
        );
    }

    #[test]
    fn edit_distance_counts_characters() {
        assert_eq!(edit_distance("windowarae", "windowarea"), 2);
        assert_eq!(edit_distance("windw", "window"), 1);
        assert_eq!(edit_distance("", "abc"), 3);
        assert_eq!(edit_distance("façade", "facade"), 1);
        assert_eq!(edit_distance("same", "same"), 0);
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]
        /// Any rule file assembled from valid pieces lints without panicking, sorted and
        /// deterministically, with every diagnostic on a line of the file.
        #[test]
        fn lint_is_total_sorted_and_deterministic(
            lines in proptest::collection::vec(
                (0usize..5, 0usize..7, 0usize..5, 0usize..5, proptest::option::of(0u8..=10)),
                1..10,
            )
        ) {
            let syms = ["a", "b", "c", "wall", "windw"];
            let mut src = String::new();
            for (p, op, s1, s2, prob) in &lines {
                let (p, s1, s2) = (syms[*p], syms[*s1], syms[*s2]);
                let body = match op {
                    0 => s1.to_string(),
                    1 => format!("extrude(3){{{s1}}}"),
                    2 => format!("comp(){{side:{s1}|top:{s2}}}"),
                    3 => format!("split(Z,1,1){{{s1}|{s2}}}"),
                    4 => format!("split(Y,1){{{s1}}}"),
                    5 => format!("S(sx,sy,sz){{{s1}}}"),
                    _ => format!("R(Z,5){{{s1}|{s2}}}"),
                };
                let prob = prob.map_or(String::new(), |q| format!(" = {}", f64::from(q) / 10.0));
                src.push_str(&format!("{p} -> {body}{prob}\n"));
            }
            let rules = parse(&src, "p.cga").unwrap_or_else(|e| panic!("{e}\n{src}"));
            let d = lint(&rules, &src);
            let n = src.lines().count() as u32;
            for w in d.windows(2) {
                proptest::prop_assert!((w[0].line, w[0].col, w[0].code) <= (w[1].line, w[1].col, w[1].code));
            }
            for x in &d {
                proptest::prop_assert!(x.line >= 1 && x.line <= n && !x.line_text.is_empty());
            }
            proptest::prop_assert_eq!(d, lint(&rules, &src));
        }
    }
}
