//! The rule linter behind `citygen rules check FILE` (issue 3 item 6).
//!
//! `lint` inspects a parsed [`RuleSet`] for mistakes that parse fine but derive something the
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
//! `CONTEXT_CHARS` characters on each side of its column (not its whole line), at most
//! `MAX_PER_CODE` diagnostics of one code are listed (then one saying how many more there
//! are), name lists in messages stop after a few names, long symbol names are cut, and the
//! "did you mean" search has a fixed budget.

use std::collections::{BTreeMap, BinaryHeap};
use std::fmt;

use super::ast::{Rule, RuleSet, Span, SymbolId};

mod kinds;
mod names;
mod recursion;
mod rules;

use names::quote;
pub(crate) use names::suggest;

/// The symbols that the model builder and the exporters turn into building elements; a
/// successor with one of these names and no rule is a deliberate leaf, not a typo.
pub(crate) const KNOWN_TERMINALS: [&str; 4] = ["wall", "window", "door", "balcony"];

/// Tolerance on probability sums (`0.4 + 0.2 + 0.2 + 0.2` is not exactly 1 in binary).
const PROB_EPS: f64 = 1e-9;

/// Characters of a long source line a [`Diagnostic`] keeps on each side of its column (the
/// parser's errors show the same window).
pub(crate) const CONTEXT_CHARS: usize = 80;

/// The most diagnostics of one code [`lint`] lists; past it, one more diagnostic of that code
/// says how many were left out.
pub(crate) const MAX_PER_CODE: usize = 100;

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
    /// that line. A line longer than 2 × `CONTEXT_CHARS` characters is cut to the
    /// `CONTEXT_CHARS` characters on each side of `col`, with `…` where it is cut.
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
pub(crate) fn has_errors(d: &[Diagnostic]) -> bool {
    d.iter().any(|d| d.severity == Severity::Error)
}

/// Lints a parsed rule set. `source` must be the text `rules` was parsed from: it provides the
/// line shown under each diagnostic (a mismatching source gives empty lines, never a panic).
///
/// Returns every finding, sorted by (line, col, code, message), at most [`MAX_PER_CODE`] of
/// each code (then one more of that code counting the rest); empty for a clean file.
pub(crate) fn lint(rules: &RuleSet, source: &str) -> Vec<Diagnostic> {
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
    /// The axiom's id, if it is interned.
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
}

#[cfg(test)]
mod tests;
