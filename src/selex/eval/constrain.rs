//! Constraints: the violations an element would make, checked as it is placed and again once
//! the program has run.

use super::rects::{overlap, too_close};
use super::{same, RunError, Runner, ShapeId};
use crate::selex::ast::{ConstraintAxis, ConstraintKind, Expr};
use crate::selex::grid::Rect;

impl Runner<'_> {
    fn constraint_label(&self, e: &Expr) -> Result<String, RunError> {
        self.string(e)
    }

    /// Why a constraint term does not hold on the shape `s` now, or `None`.
    pub(super) fn violation(
        &self,
        s: ShapeId,
        c: &ConstraintKind,
    ) -> Result<Option<String>, RunError> {
        let face_size = self.d.frame(s).map(|f| (f.width, f.height));
        Ok(match c {
            ConstraintKind::Align { a, b, axis } => {
                let (la, lb) = (self.constraint_label(a)?, self.constraint_label(b)?);
                let (ea, eb) = (self.labelled(s, Some(&la)), self.labelled(s, Some(&lb)));
                let key = |r: &Rect| match axis {
                    ConstraintAxis::Vertical => r.x + r.w / 2.0,
                    ConstraintAxis::Horizontal => r.y + r.h / 2.0,
                };
                ea.iter()
                    .find(|(_, ra)| !eb.iter().any(|(_, rb)| same(key(ra), key(rb))))
                    .map(|(_, r)| {
                        format!(
                            "no {lb} lies on the line of the {la} at ({:.2}, {:.2})",
                            r.x, r.y
                        )
                    })
            }
            ConstraintKind::Symmetric { label, axis } => {
                let l = self.constraint_label(label)?;
                let Some((w, h)) = face_size else {
                    return Ok(Some("symmetry needs a face to mirror about".into()));
                };
                let rects: Vec<Rect> = self
                    .labelled(s, Some(&l))
                    .into_iter()
                    .map(|e| e.1)
                    .collect();
                let mirror = |r: &Rect| match axis {
                    ConstraintAxis::Vertical => Rect {
                        x: w - r.x - r.w,
                        ..*r
                    },
                    ConstraintAxis::Horizontal => Rect {
                        y: h - r.y - r.h,
                        ..*r
                    },
                };
                rects
                    .iter()
                    .find(|r| {
                        let m = mirror(r);
                        !rects.iter().any(|o| {
                            same(o.x, m.x) && same(o.y, m.y) && same(o.w, m.w) && same(o.h, m.h)
                        })
                    })
                    .map(|r| format!("the {l} at ({:.2}, {:.2}) has no mirror image", r.x, r.y))
            }
            ConstraintKind::BoundaryDistance { label, min } => {
                let l = self.constraint_label(label)?;
                let min = self.number(min)?;
                let Some((w, h)) = face_size else {
                    return Ok(Some("a boundary distance needs a face".into()));
                };
                self.labelled(s, Some(&l))
                    .into_iter()
                    .find(|(_, r)| too_close(r, w, h, min))
                    .map(|(_, r)| {
                        format!(
                            "the {l} at ({:.2}, {:.2}) is closer than {min} m to the edge",
                            r.x, r.y
                        )
                    })
            }
            ConstraintKind::NoIntersection { labels } => {
                let labels: Vec<String> = labels
                    .iter()
                    .map(|e| self.constraint_label(e))
                    .collect::<Result<_, _>>()?;
                let rects: Vec<(ShapeId, Rect)> = if labels.is_empty() {
                    self.labelled(s, None)
                } else {
                    labels
                        .iter()
                        .flat_map(|l| self.labelled(s, Some(l)))
                        .collect()
                };
                let mut found = None;
                'outer: for (i, (ia, a)) in rects.iter().enumerate() {
                    for (ib, b) in &rects[i + 1..] {
                        if ia != ib && overlap(a, b) {
                            found = Some(format!(
                                "{} and {} overlap",
                                self.d.shapes[*ia].label, self.d.shapes[*ib].label
                            ));
                            break 'outer;
                        }
                    }
                }
                found
            }
        })
    }

    /// Why a new element `label` at `rect` on `face` would break a kept `noIntersection` or
    /// `boundaryDistance` term set on the face or above it.
    pub(super) fn breaks_kept(&self, face: ShapeId, label: &str, rect: &Rect) -> Option<String> {
        let size = self.d.frame(face).map(|f| (f.width, f.height))?;
        for (s, c) in &self.d.constraints {
            if !self.is_at_or_above(*s, face) {
                continue;
            }
            match &c.kind {
                ConstraintKind::BoundaryDistance { label: l, min } => {
                    let (Ok(l), Ok(min)) = (self.string(l), self.number(min)) else {
                        continue;
                    };
                    if l == label && too_close(rect, size.0, size.1, min) {
                        return Some(format!(
                            "closer than {min} m to the edge (a kept constraint)"
                        ));
                    }
                }
                ConstraintKind::NoIntersection { labels } => {
                    let labels: Vec<String> =
                        labels.iter().filter_map(|e| self.string(e).ok()).collect();
                    if !labels.is_empty() && !labels.iter().any(|l| l == label) {
                        continue;
                    }
                    let others = if labels.is_empty() {
                        self.labelled(face, None)
                    } else {
                        labels
                            .iter()
                            .flat_map(|l| self.labelled(face, Some(l)))
                            .collect()
                    };
                    if let Some((o, _)) = others.iter().find(|(_, r)| overlap(r, rect)) {
                        return Some(format!(
                            "it would overlap {} (a kept noIntersection)",
                            self.d.shapes[*o].label
                        ));
                    }
                }
                _ => {}
            }
        }
        None
    }

    fn is_at_or_above(&self, s: ShapeId, mut below: ShapeId) -> bool {
        loop {
            if below == s {
                return true;
            }
            match self.d.shapes[below].parent {
                Some(p) => below = p,
                None => return false,
            }
        }
    }

    /// `align` and `symmetric` again on the finished layout.
    pub(super) fn final_checks(&mut self) {
        let kept = self.d.constraints.clone();
        for (s, c) in kept {
            if matches!(
                c.kind,
                ConstraintKind::Align { .. } | ConstraintKind::Symmetric { .. }
            ) {
                if let Ok(Some(why)) = self.violation(s, &c.kind) {
                    self.warn(c.span, format!("constraint broken by later rules: {why}"));
                }
            }
        }
    }
}
