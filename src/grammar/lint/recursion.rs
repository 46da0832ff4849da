//! Recursions only a cap stops: the rule graph, its strongly connected components, growth
//! (a Perron bound) and non-termination.

use std::collections::{BTreeMap, BTreeSet};

use super::kinds::op_label;
use super::names::{fmt_num, list_names};
use super::{Cx, Kinds, Severity, Sink, EPS_SIZE, FACE, LOT, MAX_LISTED, PROB_EPS, VOLUME};
use crate::grammar::ast::{Axis, BinOp, Expr, Op, Rule, Selector, SplitKind, SymbolId};

impl Cx<'_> {
    /// Recursions that only the caps stop: `exponential-growth` and `non-terminating`.
    ///
    /// The rule graph has an edge from a rule's predecessor to each of its successor entries.
    /// A recursion is a cycle of it (a strongly connected component); only cycles are looked at,
    /// so the shipped rulesets and every ruleset the KB compiler writes (which are trees) are
    /// never reported. Each edge of a cycle is classed by what its operation does to the piece
    /// it makes, following the interpreter's rules ([`crate::grammar::interp`]):
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
    pub(super) fn recursion(&self, out: &mut Sink) {
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
        let caps = crate::grammar::interp::Caps::default();
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
        let caps = crate::grammar::interp::Caps::default();
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
