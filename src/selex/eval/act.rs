//! Actions: what a rule does to each shape or cell group its selection picked.

use glam::DVec3;

use super::values::describe;
use super::{
    cover, EdgeExtrusion, Element, ElementFrame, Frame, Group, Item, Rounding, RunError, Runner,
    ShapeId, ShapeKind, Side, Value, VolumeRounding, DEFAULT_STOREY,
};
use crate::selex::ast::{Action, ActionKind, Expr, Span};
use crate::selex::grid::{self, Grid, Rect};

impl Runner<'_> {
    pub(super) fn act(&mut self, a: &Action, items: &[Item]) -> Result<(), RunError> {
        match a.name {
            ActionKind::SetHeadNode => {
                let [Item::Shape(s)] = items else {
                    return Err(self.err(
                        a.span,
                        format!(
                            "setHeadNode() needs exactly one shape; the selection gives {}",
                            items.len()
                        ),
                    ));
                };
                self.head = *s;
                Ok(())
            }
            _ => {
                for it in items {
                    self.act_on(a, it)?;
                }
                Ok(())
            }
        }
    }

    fn shape_item(&self, a: &Action, it: &Item) -> Result<ShapeId, RunError> {
        match it {
            Item::Shape(s) => Ok(*s),
            Item::Cells { grid, .. } => Err(self.err(
                a.span,
                format!(
                    "{} works on a shape, not on cells (of `{}`)",
                    a.name.name(),
                    self.d.shapes[*grid].label
                ),
            )),
        }
    }

    fn face_item(&self, a: &Action, it: &Item) -> Result<(ShapeId, Frame), RunError> {
        let s = self.shape_item(a, it)?;
        match self.d.shapes[s].kind {
            ShapeKind::Face { frame, .. } => Ok((s, frame)),
            _ => Err(self.err(
                a.span,
                format!(
                    "{} needs a 2D construction shape (a face); `{}` is {}",
                    a.name.name(),
                    self.d.shapes[s].label,
                    self.what(s)
                ),
            )),
        }
    }

    /// The groups of a selection of cells, or the whole face for a face.
    fn groups(&self, a: &Action, it: &Item) -> Result<(ShapeId, Vec<Group>), RunError> {
        match it {
            Item::Cells {
                grid,
                set,
                grouping,
            } => {
                let g = self.grid(*grid, a.span)?;
                let elements = g
                    .group(set, grouping.unwrap_or(grid::Grouping::Each))
                    .map_err(|e| self.err(a.span, e.to_string()))?;
                let face = self.d.shapes[*grid].parent.unwrap_or(0);
                Ok((
                    face,
                    elements
                        .into_iter()
                        .map(|e| (e.rect, Some(e.cells)))
                        .collect(),
                ))
            }
            Item::Shape(s) => match self.d.shapes[*s].kind {
                ShapeKind::Face { frame, .. } => Ok((
                    *s,
                    vec![(
                        Rect {
                            x: 0.0,
                            y: 0.0,
                            w: frame.width,
                            h: frame.height,
                        },
                        None,
                    )],
                )),
                _ => Err(self.err(
                    a.span,
                    format!(
                        "{} places elements on cells or on a face; `{}` is {}",
                        a.name.name(),
                        self.d.shapes[*s].label,
                        self.what(*s)
                    ),
                )),
            },
        }
    }

    fn act_on(&mut self, a: &Action, it: &Item) -> Result<(), RunError> {
        let args = &a.args;
        match a.name {
            ActionKind::SetHeadNode => Ok(()),
            ActionKind::CreateShape => {
                let s = self.shape_item(a, it)?;
                let label = self.string(&args[0])?;
                let w = self.positive(&args[1], "width")?;
                let d = self.positive(&args[2], "depth")?;
                let h = self.positive(&args[3], "height")?;
                if self.facades && s == 0 {
                    // On a real building the mass is its footprint's: the sizes are the box's
                    // the program was written for.
                    self.footprint_volume(&label);
                } else {
                    self.make_box(s, &label, w, d, h);
                }
                Ok(())
            }
            ActionKind::CreateGrid => {
                let (face, frame) = self.face_item(a, it)?;
                let label = self.string(&args[0])?;
                let g = self.make_grid(frame.width, frame.height, &args[1], &args[2], a.span)?;
                self.add(face, &label, ShapeKind::Grid(g));
                Ok(())
            }
            ActionKind::CreateStoreyGrid => {
                let (face, frame) = self.face_item(a, it)?;
                let label = self.string(&args[0])?;
                let bay = self.positive(&args[1], "bayWidth")?;
                // A real facade's storeys; on a box face, storeys of about 3 m.
                let storeys = match self.storeys.get(&face) {
                    Some(s) if !s.is_empty() => s.clone(),
                    _ => {
                        let n = (frame.height / DEFAULT_STOREY).round().max(1.0) as usize;
                        vec![frame.height / n as f64; n]
                    }
                };
                let g = Grid::metric(frame.width, &storeys, bay)
                    .map_err(|e| self.err(a.span, e.to_string()))?;
                self.add(face, &label, ShapeKind::Grid(g));
                Ok(())
            }
            ActionKind::UpdateGrid => {
                let s = match it {
                    Item::Shape(s) => *s,
                    Item::Cells { grid, .. } => *grid,
                };
                let ShapeKind::Grid(old) = &self.d.shapes[s].kind else {
                    return Err(self.err(
                        a.span,
                        format!(
                            "updateGrid re-divides a grid; `{}` is {}",
                            self.d.shapes[s].label,
                            self.what(s)
                        ),
                    ));
                };
                let (w, h) = (old.width(), old.height());
                let g = self.make_grid(w, h, &args[0], &args[1], a.span)?;
                self.d.shapes[s].kind = ShapeKind::Grid(g);
                Ok(())
            }
            ActionKind::AddShape if matches!(it, Item::Shape(s) if !matches!(self.d.shapes[*s].kind, ShapeKind::Face { .. })) =>
            {
                // On the root or a volume: a free-standing face (Jiang's facade).
                let s = self.shape_item(a, it)?;
                let label = self.string(&args[0])?;
                let (Some(w), Some(h)) = (args.get(1), args.get(2)) else {
                    return Err(self.err(
                        a.span,
                        "addShape on a shape that is not a face needs its width and height".into(),
                    ));
                };
                let (w, h) = (self.positive(w, "width")?, self.positive(h, "height")?);
                self.add(
                    s,
                    &label,
                    ShapeKind::Face {
                        frame: Frame {
                            origin: DVec3::new(-w / 2.0, 0.0, 0.0),
                            u: DVec3::X,
                            v: DVec3::Z,
                            width: w,
                            height: h,
                        },
                        side: Side::Front,
                    },
                );
                Ok(())
            }
            ActionKind::AddShape
            | ActionKind::AddFacade
            | ActionKind::AddRoundFacade
            | ActionKind::AddFacadeWithFrame
            | ActionKind::AddRoundFacadeWithFrame => {
                let label = self.string(&args[0])?;
                let (rounding, frame) = self.styles(a)?;
                let (face, groups) = self.groups(a, it)?;
                for (mut rect, cells) in groups {
                    if a.name == ActionKind::AddShape {
                        // Sizes given: centred in the group's rectangle.
                        if let Some(w) = args.get(1) {
                            let w = self.positive(w, "width")?.min(rect.w);
                            rect.x += (rect.w - w) / 2.0;
                            rect.w = w;
                        }
                        if let Some(h) = args.get(2) {
                            let h = self.positive(h, "height")?.min(rect.h);
                            rect.y += (rect.h - h) / 2.0;
                            rect.h = h;
                        }
                    }
                    if let Some(why) = self.breaks_kept(face, &label, &rect) {
                        self.warn(
                            a.span,
                            format!(
                                "{label} at ({:.2}, {:.2}) is not placed: {why}",
                                rect.x, rect.y
                            ),
                        );
                        continue;
                    }
                    self.add(
                        face,
                        &label,
                        ShapeKind::Element(Element {
                            rect,
                            cells,
                            rounding,
                            frame,
                            action: a.name,
                        }),
                    );
                }
                Ok(())
            }
            ActionKind::AddVolume => {
                let Item::Cells { grid, .. } = it else {
                    return Err(self.err(
                        a.span,
                        "addVolume pushes out selected cells of a grid".into(),
                    ));
                };
                let label = self.string(&args[0])?;
                let depth = self.positive(&args[2], "extrusionSize")?;
                let names = match self.value(&args[3])? {
                    Value::List(v) if v.len() == 3 => v,
                    other => {
                        return Err(self.err(
                            args[3].span,
                            format!("three side labels are needed, not {}", describe(&other)),
                        ))
                    }
                };
                let names: Vec<String> = names
                    .into_iter()
                    .map(|v| match v {
                        Value::Str(s) => Ok(s),
                        other => Err(self.err(
                            args[3].span,
                            format!("side labels are strings, not {}", describe(&other)),
                        )),
                    })
                    .collect::<Result<_, _>>()?;
                let grid = *grid;
                let (face, groups) = self.groups(a, it)?;
                let Some(frame) = self.d.frame(face) else {
                    return Err(self.err(a.span, "addVolume needs a grid on a face".into()));
                };
                let parent_grid = self.grid(grid, a.span)?.clone();
                for (rect, cells) in groups {
                    let n = frame.normal();
                    let base = frame.at(rect.x, rect.y);
                    let far = frame.at(rect.x + rect.w, rect.y + rect.h) + n * depth;
                    let vol = self.add(
                        face,
                        &label,
                        ShapeKind::Volume {
                            min: base.min(far),
                            max: base.max(far),
                            rounding: None,
                        },
                    );
                    let front = Frame {
                        origin: base + n * depth,
                        u: frame.u,
                        v: frame.v,
                        width: rect.w,
                        height: rect.h,
                    };
                    let left = Frame {
                        origin: base,
                        u: n,
                        v: frame.v,
                        width: depth,
                        height: rect.h,
                    };
                    let right = Frame {
                        origin: frame.at(rect.x + rect.w, rect.y) + n * depth,
                        u: -n,
                        v: frame.v,
                        width: depth,
                        height: rect.h,
                    };
                    let side = self.side_of(face).unwrap_or(Side::Side);
                    let f = self.add(vol, &names[0], ShapeKind::Face { frame: front, side });
                    self.add(
                        vol,
                        &names[1],
                        ShapeKind::Face {
                            frame: left,
                            side: Side::Side,
                        },
                    );
                    self.add(
                        vol,
                        &names[2],
                        ShapeKind::Face {
                            frame: right,
                            side: Side::Side,
                        },
                    );
                    if let Some(c) = cells {
                        let g = parent_grid
                            .crop(c)
                            .map_err(|e| self.err(a.span, e.to_string()))?;
                        self.add(f, &format!("{}_grid", names[0]), ShapeKind::Grid(g));
                    }
                    self.last_volume = Some(vol);
                }
                Ok(())
            }
            ActionKind::RoundShape => {
                let s = self.shape_item(a, it)?;
                // The volume of the selected face, or the last addVolume's.
                let vol = match self.d.shapes[s].kind {
                    ShapeKind::Volume { .. } => Some(s),
                    _ => self.d.shapes[s]
                        .parent
                        .filter(|&p| matches!(self.d.shapes[p].kind, ShapeKind::Volume { .. })),
                }
                .or(self.last_volume);
                let Some(vol) = vol else {
                    return Err(self.err(
                        a.span,
                        "roundShape rounds a volume (a bay made by addVolume)".into(),
                    ));
                };
                let r = VolumeRounding {
                    face: self.string(&args[0])?,
                    direction: self.string(&args[1])?,
                    degree: self.number(&args[2])?,
                    segments: self.integer(&args[3])?.clamp(1, 1024) as u32,
                    axis: args.get(5).map(|e| self.string(e)).transpose()?,
                    inside_degree: args.get(6).map(|e| self.number(e)).transpose()?,
                };
                if let ShapeKind::Volume { rounding, .. } = &mut self.d.shapes[vol].kind {
                    *rounding = Some(r);
                }
                Ok(())
            }
            ActionKind::CoverShape => {
                let (face, frame) = self.face_item(a, it)?;
                let holes: Vec<Rect> = self.d.shapes[face]
                    .children
                    .iter()
                    .filter_map(|&c| match &self.d.shapes[c].kind {
                        ShapeKind::Element(e) => Some(e.rect),
                        _ => None,
                    })
                    .collect();
                let pieces = cover(frame.width, frame.height, &holes);
                self.add(face, "wall", ShapeKind::Cover { pieces });
                Ok(())
            }
            ActionKind::Constrain => {
                let s = self.shape_item(a, it)?;
                for c in &a.constraints {
                    match self.violation(s, &c.kind)? {
                        None => self.d.constraints.push((s, c.clone())),
                        Some(why) => self.warn(c.span, format!("constraint dropped: {why}")),
                    }
                }
                Ok(())
            }
        }
    }

    /// A box centred on the origin with its four faces (`createShape`).
    /// `createShape(label, ...)` on a real building ([`run_on_facades`]): a volume `label`
    /// like the building's, with a copy of each of its `facade` faces labelled
    /// `<label>_<side>` (`building_front`, ... as on a box; `<label>_side` for the walls that
    /// face no side of the street), so a program written for the seed's box runs on the
    /// footprint unchanged.
    fn footprint_volume(&mut self, label: &str) {
        let Some(&building) = self.d.shapes[0].children.first() else {
            return;
        };
        let kind = self.d.shapes[building].kind.clone();
        let vol = self.add(0, label, kind);
        let faces: Vec<ShapeId> = self.d.shapes[building]
            .children
            .iter()
            .copied()
            .filter(|&c| self.d.shapes[c].label == "facade")
            .collect();
        for f in faces {
            let kind = self.d.shapes[f].kind.clone();
            let ShapeKind::Face { side, .. } = &kind else {
                continue;
            };
            let name = format!("{label}_{}", side.name());
            let id = self.add(vol, &name, kind);
            if let Some(st) = self.storeys.get(&f).cloned() {
                self.storeys.insert(id, st);
            }
        }
    }

    pub(super) fn make_box(&mut self, parent: ShapeId, label: &str, w: f64, d: f64, h: f64) {
        let vol = self.add(
            parent,
            label,
            ShapeKind::Volume {
                min: DVec3::new(-w / 2.0, -d / 2.0, 0.0),
                max: DVec3::new(w / 2.0, d / 2.0, h),
                rounding: None,
            },
        );
        let (x, y) = (DVec3::X, DVec3::Y);
        let faces = [
            (
                "front",
                Side::Front,
                DVec3::new(-w / 2.0, -d / 2.0, 0.0),
                x,
                w,
            ),
            ("back", Side::Back, DVec3::new(w / 2.0, d / 2.0, 0.0), -x, w),
            (
                "left",
                Side::Left,
                DVec3::new(-w / 2.0, d / 2.0, 0.0),
                -y,
                d,
            ),
            (
                "right",
                Side::Right,
                DVec3::new(w / 2.0, -d / 2.0, 0.0),
                y,
                d,
            ),
        ];
        for (name, side, origin, u, width) in faces {
            self.add(
                vol,
                &format!("{label}_{name}"),
                ShapeKind::Face {
                    frame: Frame {
                        origin,
                        u,
                        v: DVec3::Z,
                        width,
                        height: h,
                    },
                    side,
                },
            );
        }
    }

    fn make_grid(
        &self,
        w: f64,
        h: f64,
        rows: &Expr,
        cols: &Expr,
        span: Span,
    ) -> Result<Grid, RunError> {
        let (r, row_labels) = self.count_or_labels(rows)?;
        let (c, col_labels) = self.count_or_labels(cols)?;
        let mut g = Grid::uniform(w, h, r, c).map_err(|e| self.err(span, e.to_string()))?;
        if let Some(l) = row_labels {
            g = g
                .with_row_labels(l)
                .map_err(|e| self.err(span, e.to_string()))?;
        }
        if let Some(l) = col_labels {
            g = g
                .with_col_labels(l)
                .map_err(|e| self.err(span, e.to_string()))?;
        }
        Ok(g)
    }

    fn styles(&self, a: &Action) -> Result<(Option<Rounding>, Option<ElementFrame>), RunError> {
        let args = &a.args;
        let rounding = |from: usize| -> Result<Rounding, RunError> {
            let corners = match self.value(&args[from])? {
                Value::List(v) => v,
                other => {
                    return Err(self.err(
                        args[from].span,
                        format!("corners are a list, not {}", describe(&other)),
                    ))
                }
            };
            let mut set = [false; 4];
            for c in corners {
                let Value::Str(name) = c else {
                    return Err(self.err(args[from].span, "corner names are strings".into()));
                };
                let Some(i) = crate::selex::ast::CORNERS.iter().position(|k| *k == name) else {
                    return Err(self.err(args[from].span, format!("no corner {name:?}")));
                };
                set[i] = true;
            }
            Ok(Rounding {
                corners: set,
                offset: self.positive(&args[from + 1], "offset")?,
                segments: self.integer(&args[from + 2])?.clamp(1, 1024) as u32,
                profile: self.number(&args[from + 3])?.clamp(0.0, 1.0),
            })
        };
        let frame = |from: usize| -> Result<ElementFrame, RunError> {
            let edge = match self.string(&args[from])?.as_str() {
                "all" => EdgeExtrusion::All,
                "frame" => EdgeExtrusion::Frame,
                _ => EdgeExtrusion::None,
            };
            Ok(ElementFrame {
                edge,
                thickness: self.positive(&args[from + 1], "thickness")?,
                width: self.number(&args[from + 2])?.max(0.0),
            })
        };
        Ok(match a.name {
            ActionKind::AddRoundFacade => (Some(rounding(1)?), None),
            ActionKind::AddFacadeWithFrame => (None, Some(frame(1)?)),
            ActionKind::AddRoundFacadeWithFrame => (Some(rounding(1)?), Some(frame(5)?)),
            _ => (None, None),
        })
    }

    /// Elements labelled `label` on the shape `s` or below it.
    pub(super) fn labelled(&self, s: ShapeId, label: Option<&str>) -> Vec<(ShapeId, Rect)> {
        let mut out = Vec::new();
        let mut stack = vec![s];
        while let Some(c) = stack.pop() {
            if let ShapeKind::Element(e) = &self.d.shapes[c].kind {
                if label.is_none_or(|l| self.d.shapes[c].label == l) {
                    out.push((c, e.rect));
                }
            }
            stack.extend(self.d.shapes[c].children.iter().rev());
        }
        out.sort_by_key(|e| e.0);
        out
    }
}
