//! `check`: what parses but is suspicious.

use super::lexer::clip;
use super::{line_at, quoted_list, Warning, WarningKind};
use crate::selex::ast::{
    ActionKind, Arrow, Attr, Cmp, Command, ConstraintKind, Expr, ExprKind, Filter, Grouping,
    IndexSet, Program, Span, Topo,
};

/// Lists what parses but is suspicious in `program` (parsed from `src`, named `file`): the `>`
/// arrow, bare words taken as strings, groupings in steps that select no cells, two groupings
/// in one step, a `roundShape` not right after an `addVolume`, `type`/`dim`/`side` compared with
/// values they never take, a program without rules. In file order.
pub fn check(program: &Program, src: &str, file: &str) -> Vec<Warning> {
    let mut out = Vec::new();
    let mut warn = |span: Span, kind: WarningKind, message: String| {
        out.push(Warning {
            file: file.to_string(),
            line: span.line,
            col: span.col,
            kind,
            message,
            line_text: line_at(src, span.offset),
        });
    };
    let mut last_action: Option<ActionKind> = None;
    let mut any_rule = false;
    for c in &program.commands {
        match c {
            Command::Assign { value, .. } => bare_words(value, &mut warn),
            Command::Rule(r) => {
                any_rule = true;
                for step in &r.selection.steps {
                    let cells = step.topo == Some(Topo::Cell)
                        || step.filters.iter().any(|f| {
                            matches!(f, Filter::Compare { attr: Attr::Type, op: Cmp::Eq, value, .. }
                                if value.as_str() == Some("cell"))
                        });
                    let groups: Vec<(Grouping, Span)> = step
                        .filters
                        .iter()
                        .filter_map(|f| match f {
                            Filter::Group { grouping, span } => Some((*grouping, *span)),
                            _ => None,
                        })
                        .collect();
                    for f in &step.filters {
                        match f {
                            Filter::Compare { attr, value, .. } => {
                                bare_words(value, &mut warn);
                                let known: &[&str] = match attr {
                                    Attr::Type => &["virtual", "construction", "cell"],
                                    Attr::Dim => &["2D", "3D"],
                                    Attr::Side => &["front", "back", "left", "right", "side"],
                                    _ => &[],
                                };
                                if let Some(s) = value.as_str() {
                                    if !known.is_empty() && !known.contains(&s) {
                                        warn(
                                            value.span,
                                            WarningKind::UnknownValue,
                                            format!(
                                                "`{}` is never \"{}\" (it is one of {}): this \
                                                 selector selects nothing",
                                                attr.name(),
                                                clip(s),
                                                quoted_list(known)
                                            ),
                                        );
                                    }
                                }
                            }
                            Filter::In { set, .. } => match set {
                                IndexSet::List(items) => {
                                    for i in items {
                                        bare_words(i, &mut warn);
                                    }
                                }
                                IndexSet::IndexRange(a, b) | IndexSet::RowRange(a, b) => {
                                    bare_words(a, &mut warn);
                                    bare_words(b, &mut warn);
                                }
                            },
                            _ => {}
                        }
                    }
                    if let Some(&(g, sp)) = groups.first() {
                        if !cells {
                            warn(
                                sp,
                                WarningKind::GroupingOutsideCells,
                                format!(
                                    "`{}` groups the cells of a virtual grid, but this step \
                                     selects no cells: add `[type == \"cell\"]` or start it with \
                                     `cell()`",
                                    g.name()
                                ),
                            );
                        }
                    }
                    if let Some(&(g, sp)) = groups.get(1) {
                        warn(
                            sp,
                            WarningKind::SeveralGroupings,
                            format!(
                                "a second grouping `{}` in one step, after `{}`: each regroups \
                                 the cells the previous one made",
                                g.name(),
                                groups[0].0.name()
                            ),
                        );
                    }
                }
                if r.arrow == Arrow::Gt {
                    warn(
                        r.arrow_span,
                        WarningKind::LegacyArrow,
                        "`>` separates the selection from the actions as Brito's listing \
                         prints it; write `->`"
                            .into(),
                    );
                }
                for a in &r.actions {
                    for e in &a.args {
                        bare_words(e, &mut warn);
                    }
                    for c in &a.constraints {
                        match &c.kind {
                            ConstraintKind::Align { a, b, .. } => {
                                bare_words(a, &mut warn);
                                bare_words(b, &mut warn);
                            }
                            ConstraintKind::Symmetric { label, .. } => bare_words(label, &mut warn),
                            ConstraintKind::BoundaryDistance { label, min } => {
                                bare_words(label, &mut warn);
                                bare_words(min, &mut warn);
                            }
                            ConstraintKind::NoIntersection { labels } => {
                                for l in labels {
                                    bare_words(l, &mut warn);
                                }
                            }
                        }
                    }
                    if a.name == ActionKind::RoundShape
                        && last_action != Some(ActionKind::AddVolume)
                    {
                        warn(
                            a.span,
                            WarningKind::RoundShapeWithoutVolume,
                            "roundShape rounds the volume made by the `addVolume` right before \
                             it, and the previous action is not an addVolume"
                                .into(),
                        );
                    }
                    last_action = Some(a.name);
                }
            }
        }
    }
    if !any_rule {
        warn(
            Span {
                line: 1,
                col: 1,
                offset: 0,
                len: 0,
            },
            WarningKind::NoRules,
            "the program has no rule `{< selection > -> actions}`".into(),
        );
    }
    out
}

/// Warns on every bare word of `e` (walks lists; arithmetic holds none).
fn bare_words(e: &Expr, warn: &mut impl FnMut(Span, WarningKind, String)) {
    match &e.kind {
        ExprKind::BareWord(w) => warn(
            e.span,
            WarningKind::BareWord,
            format!(
                "`{0}` is no variable assigned before this line: taken as the string \"{0}\"; \
                 write it in double quotes",
                clip(w)
            ),
        ),
        ExprKind::List(items) => {
            for i in items {
                bare_words(i, warn);
            }
        }
        _ => {}
    }
}
