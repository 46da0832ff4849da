//! Selection: a path's topology steps and filters over the shape tree and its grids.

use std::collections::HashMap;

use super::rects::{overlap, touch};
use super::values::describe;
use super::{Frame, Item, Note, RunError, Runner, ShapeId, ShapeKind, Side, Value};
use crate::selex::ast::{Attr, Cmp, Expr, Filter, IndexSet, Selection, Span, Step, Topo};
use crate::selex::grid::{self, Axis, CellSet, CmpOp, Grid, IndexItem, Rect};
use crate::selex::pattern;

impl Runner<'_> {
    pub(super) fn select(&mut self, sel: &Selection) -> Result<Vec<Item>, RunError> {
        let mut items = vec![Item::Shape(self.head)];
        for step in &sel.steps {
            let topo = step.topo.unwrap_or(Topo::Child);
            let (mut next, filters) = match self.by_label(topo, step, &items) {
                Some(next) => (next, step.filters.get(1..).unwrap_or_default()),
                None => {
                    let mut next: Vec<Item> = Vec::new();
                    let span = step.topo_span.unwrap_or(step.span);
                    for it in &items {
                        self.topo(topo, it, span, &mut next)?;
                    }
                    dedup(&mut next);
                    (next, &step.filters[..])
                }
            };
            for f in filters {
                next = self.filter(f, next)?;
            }
            items = next;
        }
        Ok(items)
    }

    /// A step `[label == "x"] ...` or `descendant() [label == "x"] ...` answered from the label
    /// indexes: the shapes the topology and its first filter give, in the order the walk
    /// would give them (children in creation order, descendants in pre-order), without
    /// walking the tree. `None` when the step is not of that form, when the label is not a
    /// string (the walk then reports it as before), or when the shapes so labelled are too
    /// many or too deep for the index to beat the walk.
    fn by_label(&self, topo: Topo, step: &Step, items: &[Item]) -> Option<Vec<Item>> {
        let Some(Filter::Compare {
            attr: Attr::Label,
            op: Cmp::Eq,
            value,
            ..
        }) = step.filters.first()
        else {
            return None;
        };
        if self.walk_only || !matches!(topo, Topo::Child | Topo::Descendant) {
            return None;
        }
        let label = self.string(value).ok()?;
        let shapes = &self.d.shapes;
        let mut out = Vec::new();
        // Cells have no label: the cells a walk gives never pass `label == "x"`.
        let inputs = items.iter().filter_map(|it| match it {
            Item::Shape(s) => Some(*s),
            Item::Cells { .. } => None,
        });
        if topo == Topo::Child {
            for s in inputs {
                if matches!(shapes[s].kind, ShapeKind::Grid(_)) {
                    continue;
                }
                if let Some(c) = self.children_by_label.get(&(s, label.clone())) {
                    out.extend(c.iter().map(|&c| Item::Shape(c)));
                }
            }
        } else {
            let candidates = self.by_label.get(&label).map_or(&[][..], Vec::as_slice);
            let mut budget = 8 * shapes.len() + 64;
            for s in inputs {
                // (the path from s down to c, c) for each c below s.
                let mut below: Vec<(Vec<ShapeId>, ShapeId)> = Vec::new();
                for &c in candidates {
                    let mut path = vec![c];
                    let mut at = c;
                    while let Some(p) = shapes[at].parent {
                        budget = budget.checked_sub(1)?;
                        if p == s {
                            path.reverse();
                            below.push((path, c));
                            break;
                        }
                        path.push(p);
                        at = p;
                    }
                }
                // Children come in creation order, so a path's ids order the walk.
                below.sort_unstable();
                out.extend(below.into_iter().map(|(_, c)| Item::Shape(c)));
            }
        }
        dedup(&mut out);
        Some(out)
    }

    fn cells_of(&self, grid: ShapeId) -> Option<Item> {
        match &self.d.shapes[grid].kind {
            ShapeKind::Grid(g) => Some(Item::Cells {
                grid,
                set: g.all(),
                grouping: None,
            }),
            _ => None,
        }
    }

    /// The latest grid of a face.
    fn grid_of_face(&self, face: ShapeId) -> Option<ShapeId> {
        self.d.shapes[face]
            .children
            .iter()
            .rev()
            .copied()
            .find(|&c| matches!(self.d.shapes[c].kind, ShapeKind::Grid(_)))
    }

    fn topo(&self, topo: Topo, it: &Item, span: Span, out: &mut Vec<Item>) -> Result<(), RunError> {
        let shapes = &self.d.shapes;
        match (topo, it) {
            (Topo::Root, _) => out.push(Item::Shape(0)),
            (Topo::Child, Item::Shape(s)) => match shapes[*s].kind {
                ShapeKind::Grid(_) => out.extend(self.cells_of(*s)),
                _ => out.extend(shapes[*s].children.iter().map(|&c| Item::Shape(c))),
            },
            (Topo::Child, Item::Cells { .. }) => {}
            (Topo::Descendant, Item::Shape(s)) => {
                let mut stack: Vec<ShapeId> = shapes[*s].children.iter().rev().copied().collect();
                while let Some(c) = stack.pop() {
                    out.push(Item::Shape(c));
                    if let Some(cells) = self.cells_of(c) {
                        out.push(cells);
                    }
                    stack.extend(shapes[c].children.iter().rev());
                }
            }
            (Topo::Descendant, Item::Cells { .. }) => {}
            (Topo::Parent, Item::Shape(s)) => out.extend(shapes[*s].parent.map(Item::Shape)),
            (Topo::Parent, Item::Cells { grid, .. }) => out.push(Item::Shape(*grid)),
            (Topo::Cell, Item::Shape(s)) => {
                let grid = match shapes[*s].kind {
                    ShapeKind::Grid(_) => Some(*s),
                    ShapeKind::Face { .. } => self.grid_of_face(*s),
                    _ => None,
                };
                match grid {
                    Some(g) => out.extend(self.cells_of(g)),
                    None => {
                        return Err(self.err(
                            span,
                            format!(
                                "cell() needs a grid or a face with a grid; `{}` is {}",
                                shapes[*s].label,
                                self.what(*s)
                            ),
                        ))
                    }
                }
            }
            (Topo::Cell, cells @ Item::Cells { .. }) => out.push(cells.clone()),
            (Topo::Neighbor, Item::Shape(s)) => {
                out.extend(self.neighbours(*s).into_iter().map(Item::Shape))
            }
            (Topo::Neighbor, Item::Cells { grid, set, .. }) => {
                let mut ring = set.clone();
                for (r, c) in set.iter() {
                    for (dr, dc) in [(-1i64, 0i64), (1, 0), (0, -1), (0, 1)] {
                        let (nr, nc) = (r as i64 + dr, c as i64 + dc);
                        if nr >= 1
                            && nc >= 1
                            && (nr as usize) <= set.rows()
                            && (nc as usize) <= set.cols()
                        {
                            let _ = ring.insert(nr as usize, nc as usize);
                        }
                    }
                }
                let ring = ring
                    .difference(set)
                    .map_err(|e| self.err(span, e.to_string()))?;
                out.push(Item::Cells {
                    grid: *grid,
                    set: ring,
                    grouping: None,
                });
            }
            (Topo::Contained, Item::Shape(s)) => match shapes[*s].kind {
                ShapeKind::Face { .. } => out.extend(
                    shapes[*s]
                        .children
                        .iter()
                        .filter(|&&c| matches!(shapes[c].kind, ShapeKind::Element(_)))
                        .map(|&c| Item::Shape(c)),
                ),
                ShapeKind::Grid(ref g) => {
                    let all = g.all();
                    out.extend(self.elements_within(*s, &all).into_iter().map(Item::Shape));
                }
                _ => {}
            },
            (Topo::Contained, Item::Cells { grid, set, .. }) => out.extend(
                self.elements_within(*grid, set)
                    .into_iter()
                    .map(Item::Shape),
            ),
        }
        Ok(())
    }

    /// The elements on a grid's face that lie within the union of the given cells.
    fn elements_within(&self, grid: ShapeId, set: &CellSet) -> Vec<ShapeId> {
        let shapes = &self.d.shapes;
        let (Some(face), ShapeKind::Grid(g)) = (shapes[grid].parent, &shapes[grid].kind) else {
            return Vec::new();
        };
        let cells: Vec<Rect> = set
            .iter()
            .filter_map(|(r, c)| g.cell_rect(r, c).ok())
            .collect();
        shapes[face]
            .children
            .iter()
            .copied()
            .filter(|&c| match &shapes[c].kind {
                // Inside the union: every cell the element overlaps is selected, and it overlaps
                // at least one.
                ShapeKind::Element(e) => {
                    let overlapping: Vec<(usize, usize)> = (1..=g.rows())
                        .flat_map(|r| (1..=g.cols()).map(move |c| (r, c)))
                        .filter(|&(r, c)| g.cell_rect(r, c).is_ok_and(|cr| overlap(&cr, &e.rect)))
                        .collect();
                    !overlapping.is_empty()
                        && overlapping.iter().all(|&(r, c)| set.contains(r, c))
                        && !cells.is_empty()
                }
                _ => false,
            })
            .collect()
    }

    /// Faces sharing a vertical edge with a face; elements touching an element on its face.
    fn neighbours(&self, s: ShapeId) -> Vec<ShapeId> {
        let shapes = &self.d.shapes;
        let Some(parent) = shapes[s].parent else {
            return Vec::new();
        };
        let siblings = shapes[parent].children.iter().copied().filter(|&c| c != s);
        match &shapes[s].kind {
            ShapeKind::Face { frame, .. } => {
                let edges = |f: &Frame| [f.origin, f.at(f.width, 0.0)];
                let mine = edges(frame);
                siblings
                    .filter(|&c| match &shapes[c].kind {
                        ShapeKind::Face { frame: other, .. } => edges(other)
                            .iter()
                            .any(|p| mine.iter().any(|q| p.distance(*q) < 1e-4)),
                        _ => false,
                    })
                    .collect()
            }
            ShapeKind::Element(e) => siblings
                .filter(|&c| match &shapes[c].kind {
                    ShapeKind::Element(o) => touch(&e.rect, &o.rect),
                    _ => false,
                })
                .collect(),
            _ => Vec::new(),
        }
    }

    pub(super) fn what(&self, s: ShapeId) -> &'static str {
        match self.d.shapes[s].kind {
            ShapeKind::Root => "the root",
            ShapeKind::Volume { .. } => "a volume",
            ShapeKind::Face { .. } => "a face",
            ShapeKind::Grid(_) => "a grid",
            ShapeKind::Element(_) => "an element",
            ShapeKind::Cover { .. } => "a cover",
        }
    }

    pub(super) fn side_of(&self, mut s: ShapeId) -> Option<Side> {
        loop {
            if let ShapeKind::Face { side, .. } = self.d.shapes[s].kind {
                return Some(side);
            }
            s = self.d.shapes[s].parent?;
        }
    }

    fn filter(&self, f: &Filter, items: Vec<Item>) -> Result<Vec<Item>, RunError> {
        let mut out = Vec::with_capacity(items.len());
        for it in items {
            if let Some(kept) = self.filter_one(f, it)? {
                out.push(kept);
            }
        }
        Ok(out)
    }

    fn filter_one(&self, f: &Filter, it: Item) -> Result<Option<Item>, RunError> {
        let span = f.span();
        match (f, it) {
            (Filter::Group { grouping, .. }, Item::Cells { grid, set, .. }) => {
                Ok(Some(Item::Cells {
                    grid,
                    set,
                    grouping: Some(match grouping {
                        crate::selex::ast::Grouping::Regions => grid::Grouping::Regions,
                        crate::selex::ast::Grouping::Rows => grid::Grouping::Rows,
                        crate::selex::ast::Grouping::Cols => grid::Grouping::Cols,
                        crate::selex::ast::Grouping::Pairs => grid::Grouping::Pairs,
                        crate::selex::ast::Grouping::Each => grid::Grouping::Each,
                    }),
                }))
            }
            (Filter::Group { grouping, .. }, Item::Shape(s)) => Err(self.err(
                span,
                format!(
                    "{} groups the cells of a virtual grid; `{}` is {}",
                    grouping.name(),
                    self.d.shapes[s].label,
                    self.what(s)
                ),
            )),
            (
                Filter::Pattern {
                    regex,
                    pat,
                    regex_span,
                    ..
                },
                Item::Cells {
                    grid,
                    set,
                    grouping,
                },
            ) => {
                let g = self.grid(grid, span)?;
                let p =
                    pattern::parse(regex).map_err(|e| self.pattern_err(*regex_span, regex, &e))?;
                let (chosen, left_out) = match p.select_allowing_short(pat, g.rows(), g.cols()) {
                    Ok(r) => r,
                    Err(e)
                        if self.facades
                            && matches!(
                                e.kind,
                                pattern::PatternErrorKind::Overflow { .. }
                                    | pattern::PatternErrorKind::StarNotDividing { .. }
                            ) =>
                    {
                        return Ok(self.skip_grid(grid, *regex_span, &e.to_string()));
                    }
                    Err(e) => return Err(self.pattern_err(*regex_span, regex, &e)),
                };
                if left_out > 0 {
                    self.pending.borrow_mut().push(Note {
                        line: regex_span.line,
                        col: regex_span.col,
                        message: format!(
                            "pattern \"{regex}\" gives {} of the {} cells of a {} x {} grid: \
                             the other {left_out} are not selected (end it with (X)* to say so)",
                            g.rows() * g.cols() - left_out,
                            g.rows() * g.cols(),
                            g.rows(),
                            g.cols()
                        ),
                    });
                }
                let set = set
                    .intersect(&chosen)
                    .map_err(|e| self.err(span, e.to_string()))?;
                Ok(Some(Item::Cells {
                    grid,
                    set,
                    grouping,
                }))
            }
            (Filter::Pattern { .. }, Item::Shape(s)) => Err(self.err(
                span,
                format!(
                    "pattern(...) selects the cells of a virtual grid; `{}` is {}",
                    self.d.shapes[s].label,
                    self.what(s)
                ),
            )),
            (
                Filter::Compare {
                    attr, op, value, ..
                },
                Item::Cells {
                    grid,
                    set,
                    grouping,
                },
            ) => {
                let g = self.grid(grid, span)?;
                let sel = match attr {
                    Attr::RowIdx | Attr::ColIdx => {
                        let v = self.integer(value)?;
                        g.select_cmp(axis(*attr), cmp(*op), v)
                    }
                    Attr::RowLabel | Attr::ColLabel => {
                        let v = self.string(value)?;
                        g.select_label(axis(*attr), cmp(*op), &v)
                    }
                    Attr::Type => {
                        let v = self.string(value)?;
                        let keep = (v == "cell") == (*op == Cmp::Eq);
                        return Ok(keep.then_some(Item::Cells {
                            grid,
                            set,
                            grouping,
                        }));
                    }
                    Attr::Dim => {
                        let keep = self.dim_matches(value, *op, 2)?;
                        return Ok(keep.then_some(Item::Cells {
                            grid,
                            set,
                            grouping,
                        }));
                    }
                    Attr::Side => {
                        let v = self.string(value)?;
                        let side = self.side_of(grid).map(Side::name);
                        let keep = (side == Some(v.as_str())) == (*op == Cmp::Eq);
                        return Ok(keep.then_some(Item::Cells {
                            grid,
                            set,
                            grouping,
                        }));
                    }
                    // Cells have no label of their own.
                    Attr::Label => {
                        return Ok((*op == Cmp::Ne).then_some(Item::Cells {
                            grid,
                            set,
                            grouping,
                        }))
                    }
                };
                let sel = match sel {
                    Ok(sel) => sel,
                    Err(e) if self.facades && e.depends_on_size() => {
                        return Ok(self.skip_grid(grid, span, &e.to_string()))
                    }
                    Err(e) => return Err(self.err(span, e.to_string())),
                };
                self.narrowed(grid, &set, grouping, &sel, span)
            }
            (
                Filter::In {
                    attr, set: list, ..
                },
                Item::Cells {
                    grid,
                    set,
                    grouping,
                },
            ) => {
                let g = self.grid(grid, span)?;
                let sel = match attr {
                    Attr::RowIdx | Attr::ColIdx => {
                        let items = self.index_items(list)?;
                        g.select_in(axis(*attr), &items)
                    }
                    Attr::RowLabel | Attr::ColLabel => {
                        let labels = self.string_list(list, span)?;
                        let refs: Vec<&str> = labels.iter().map(String::as_str).collect();
                        Ok(g.select_label_in(axis(*attr), &refs))
                    }
                    Attr::Type | Attr::Side | Attr::Label | Attr::Dim => {
                        let labels = self.string_list(list, span)?;
                        let mine = match attr {
                            Attr::Type => Some("cell"),
                            Attr::Side => self.side_of(grid).map(Side::name),
                            Attr::Dim => Some("2D"),
                            _ => None,
                        };
                        let keep = mine.is_some_and(|m| labels.iter().any(|l| l == m));
                        return Ok(keep.then_some(Item::Cells {
                            grid,
                            set,
                            grouping,
                        }));
                    }
                };
                let sel = match sel {
                    Ok(sel) => sel,
                    Err(e) if self.facades && e.depends_on_size() => {
                        return Ok(self.skip_grid(grid, span, &e.to_string()))
                    }
                    Err(e) => return Err(self.err(span, e.to_string())),
                };
                self.narrowed(grid, &set, grouping, &sel, span)
            }
            (
                Filter::Compare {
                    attr, op, value, ..
                },
                Item::Shape(s),
            ) => {
                let shape = &self.d.shapes[s];
                let keep = match attr {
                    Attr::Label => self.string_cmp(&shape.label, *op, value, span)?,
                    Attr::Type => self.string_cmp(shape.type_name(), *op, value, span)?,
                    // `side == "side"` is every wall, as the grammar's `comp` selector `side`.
                    Attr::Side => match self.side_of(s) {
                        Some(side) => {
                            let v = self.string(value)?;
                            let mine = if v == "side" { "side" } else { side.name() };
                            self.string_cmp(mine, *op, value, span)?
                        }
                        None => *op == Cmp::Ne,
                    },
                    Attr::Dim => {
                        let dim = match shape.kind {
                            ShapeKind::Volume { .. } => 3,
                            ShapeKind::Root => 3,
                            _ => 2,
                        };
                        self.dim_matches(value, *op, dim)?
                    }
                    Attr::RowIdx | Attr::ColIdx | Attr::RowLabel | Attr::ColLabel => {
                        return Err(self.not_cells(*attr, s, span))
                    }
                };
                Ok(keep.then_some(Item::Shape(s)))
            }
            (Filter::In { attr, set, .. }, Item::Shape(s)) => {
                let shape = &self.d.shapes[s];
                let mine: Option<String> = match attr {
                    Attr::Label => Some(shape.label.clone()),
                    Attr::Type => Some(shape.type_name().to_string()),
                    Attr::Side => self.side_of(s).map(|x| x.name().to_string()),
                    Attr::Dim => Some(
                        if matches!(shape.kind, ShapeKind::Volume { .. } | ShapeKind::Root) {
                            "3D"
                        } else {
                            "2D"
                        }
                        .to_string(),
                    ),
                    Attr::RowIdx | Attr::ColIdx | Attr::RowLabel | Attr::ColLabel => {
                        return Err(self.not_cells(*attr, s, span))
                    }
                };
                let list = self.string_list(set, span)?;
                let keep = mine.is_some_and(|m| list.contains(&m));
                Ok(keep.then_some(Item::Shape(s)))
            }
        }
    }

    /// On a real building's facades ([`run_on_facades`]), a selector that cannot apply to one
    /// grid's size (an index past its bays, a pattern that does not tile it) leaves that grid
    /// out of the selection, with a warning: one program serves facades of every width.
    fn skip_grid(&self, grid: ShapeId, at: Span, why: &str) -> Option<Item> {
        let face = self.d.shapes[grid].parent.unwrap_or(grid);
        let g = self.grid(grid, at).ok()?;
        self.pending.borrow_mut().push(Note {
            line: at.line,
            col: at.col,
            message: format!(
                "on the {} m facade {} ({} x {} grid): {why}; the facade is left out of this rule",
                match self.d.frame(face) {
                    Some(f) => format!("{:.1}", f.width),
                    None => "?".into(),
                },
                face,
                g.rows(),
                g.cols()
            ),
        });
        None
    }

    /// The cells of `set` that are also in `sel`, with the same grid and grouping.
    fn narrowed(
        &self,
        grid: ShapeId,
        set: &CellSet,
        grouping: Option<grid::Grouping>,
        sel: &CellSet,
        span: Span,
    ) -> Result<Option<Item>, RunError> {
        let set = set
            .intersect(sel)
            .map_err(|e| self.err(span, e.to_string()))?;
        Ok(Some(Item::Cells {
            grid,
            set,
            grouping,
        }))
    }

    fn not_cells(&self, attr: Attr, s: ShapeId, span: Span) -> RunError {
        self.err(
            span,
            format!(
                "{} applies to the cells of a virtual grid; `{}` is {} (select its cells with cell() \
                 or a step into the grid)",
                attr.name(),
                self.d.shapes[s].label,
                self.what(s)
            ),
        )
    }

    fn dim_matches(&self, value: &Expr, op: Cmp, dim: u8) -> Result<bool, RunError> {
        let want = match self.value(value)? {
            Value::Num(v) => v,
            Value::Str(s) => match s.to_ascii_uppercase().as_str() {
                "2D" | "2" => 2.0,
                "3D" | "3" => 3.0,
                _ => {
                    return Err(self.err(value.span, format!("dim is \"2D\" or \"3D\", not {s:?}")))
                }
            },
            other => {
                return Err(self.err(
                    value.span,
                    format!("dim is \"2D\" or \"3D\", not {}", describe(&other)),
                ))
            }
        };
        Ok(match op {
            Cmp::Eq => f64::from(dim) == want,
            Cmp::Ne => f64::from(dim) != want,
            _ => return Err(self.err(value.span, "dim compares only with == and !=".into())),
        })
    }

    fn string_cmp(&self, mine: &str, op: Cmp, value: &Expr, span: Span) -> Result<bool, RunError> {
        let v = self.string(value)?;
        match op {
            Cmp::Eq => Ok(mine == v),
            Cmp::Ne => Ok(mine != v),
            _ => Err(self.err(
                span,
                "labels compare only with == and != (not an ordering)".into(),
            )),
        }
    }

    fn string_list(&self, set: &IndexSet, span: Span) -> Result<Vec<String>, RunError> {
        match set {
            IndexSet::List(items) => items.iter().map(|e| self.string(e)).collect(),
            _ => Err(self.err(
                span,
                "a range selects indices (rowIdx, colIdx), not labels".into(),
            )),
        }
    }

    fn index_items(&self, set: &IndexSet) -> Result<Vec<IndexItem>, RunError> {
        Ok(match set {
            IndexSet::List(items) => items
                .iter()
                .map(|e| self.integer(e).map(IndexItem::One))
                .collect::<Result<_, _>>()?,
            IndexSet::IndexRange(a, b) | IndexSet::RowRange(a, b) => {
                vec![IndexItem::Range(self.integer(a)?, self.integer(b)?)]
            }
        })
    }

    /// The grid of a cell selection. Cells are only ever made from grids, so the error is an
    /// internal one, reported at `span` rather than a panic.
    pub(super) fn grid(&self, id: ShapeId, span: Span) -> Result<&Grid, RunError> {
        match &self.d.shapes[id].kind {
            ShapeKind::Grid(g) => Ok(g),
            _ => Err(self.err(
                span,
                format!(
                    "internal: cells of `{}`, which is not a grid",
                    self.d.shapes[id].label
                ),
            )),
        }
    }

    fn pattern_err(&self, regex_span: Span, regex: &str, e: &pattern::PatternError) -> RunError {
        // Strings hold no escapes: character n of the pattern is at column col + n.
        let chars = regex[..e.offset.min(regex.len())].chars().count() as u32;
        let at = Span {
            col: regex_span.col + chars,
            ..regex_span
        };
        self.err(at, format!("pattern: {e}"))
    }
}

pub(super) fn axis(a: Attr) -> Axis {
    match a {
        Attr::RowIdx | Attr::RowLabel => Axis::Row,
        _ => Axis::Col,
    }
}

pub(super) fn cmp(c: Cmp) -> CmpOp {
    match c {
        Cmp::Eq => CmpOp::Eq,
        Cmp::Ne => CmpOp::Ne,
        Cmp::Lt => CmpOp::Lt,
        Cmp::Le => CmpOp::Le,
        Cmp::Gt => CmpOp::Gt,
        Cmp::Ge => CmpOp::Ge,
    }
}

/// Removes repeated shapes (and merges repeated grids' cells), keeping first places. Linear:
/// a map from each shape or grid to its place in the output (a `descendant()` step from the
/// root gives every shape of the tree, and a program of many rules runs one per rule).
pub(super) fn dedup(items: &mut Vec<Item>) {
    let mut out: Vec<Item> = Vec::with_capacity(items.len());
    // (is a cell selection, shape id) -> index in `out`.
    let mut at: HashMap<(bool, ShapeId), usize> = HashMap::with_capacity(items.len());
    for it in items.drain(..) {
        let key = match &it {
            Item::Shape(s) => (false, *s),
            Item::Cells { grid, .. } => (true, *grid),
        };
        match at.get(&key) {
            None => {
                at.insert(key, out.len());
                out.push(it);
            }
            Some(&k) => {
                if let (Item::Cells { set, .. }, Item::Cells { set: more, .. }) = (&mut out[k], it)
                {
                    if let Ok(u) = set.union(&more) {
                        *set = u;
                    }
                }
            }
        }
    }
    *items = out;
}
