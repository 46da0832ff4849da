//! `split`: the 1D layout of a split along an axis, and the footprint or face cut into its slabs.

use super::{face_scope, h2, polygon_points, Ctx, DeriveError, Piece, FIT_TOL};
use crate::geometry::clip::clip_slab;
use crate::geometry::Polygon;
use crate::grammar::ast::{Axis, SplitKind};
use crate::grammar::shape::{Geometry, Scope, EPS};

/// A 1D layout: (successor or wall, start, length) along an axis of length `len`.
fn layout(
    ctx: &Ctx<'_>,
    kind: SplitKind,
    sizes: &[f64],
    len: f64,
    face: bool,
) -> Result<Vec<(Option<usize>, f64, f64)>, DeriveError> {
    let name = kind.name();
    // A negative size (e.g. `sx/2 - bay/2` on a facade narrower than the bay) counts as zero:
    // the piece is not made and the remainder rules apply, so a narrow facade stays closed.
    let clamped: Vec<f64> = sizes.iter().map(|s| s.max(0.0)).collect();
    let sizes = &clamped[..];
    let mut out: Vec<(Option<usize>, f64, f64)> = Vec::new();
    match kind {
        SplitKind::Absolute => {
            let mut cum = 0.0;
            let mut overflow = None;
            for (i, &s) in sizes.iter().enumerate() {
                if s <= EPS {
                    continue;
                }
                if cum + s <= len + FIT_TOL {
                    ctx.room(
                        (out.len() + 1) as f64,
                        0.0,
                        format_args!("split would make at least"),
                    )?;
                    out.push((Some(i), cum, s.min(len - cum)));
                    cum += s;
                } else {
                    overflow = Some(i);
                    break;
                }
            }
            let rest = len - cum;
            if rest > FIT_TOL {
                if face {
                    out.push((overflow, cum, rest));
                } else if let Some(last) = out.last_mut() {
                    last.2 += rest;
                } else if let Some(o) = overflow {
                    out.push((Some(o), 0.0, len));
                } else {
                    return Err(ctx.bad(format!("{name}: all sizes are zero")));
                }
            }
        }
        SplitKind::Relative => {
            let total: f64 = sizes.iter().sum();
            if total <= EPS {
                return Err(ctx.bad(format!("{name}: the fractions sum to zero")));
            }
            let mut cum = 0.0;
            for (i, &s) in sizes.iter().enumerate() {
                let l = s / total * len;
                if l > EPS {
                    ctx.room(
                        (out.len() + 1) as f64,
                        0.0,
                        format_args!("rsplit would make at least"),
                    )?;
                    out.push((Some(i), cum, l));
                }
                cum += l;
            }
        }
        SplitKind::Repeat => {
            let pattern: f64 = sizes.iter().sum();
            if pattern <= EPS {
                return Err(ctx.bad(format!("{name}: the sizes sum to zero")));
            }
            // The copies are counted, not made, first: `repeat(X, 1e-300)` on a long lot would
            // make more pieces than there are bytes.
            let copies = ((len + FIT_TOL) / pattern).floor();
            ctx.room(
                copies.max(1.0) * sizes.len() as f64,
                0.0,
                format_args!("repeat would make"),
            )?;
            let (copies, factor) = if copies < 1.0 {
                if face {
                    return Ok(vec![(None, 0.0, len)]);
                }
                (1, len / pattern)
            } else {
                (copies as usize, len / (copies * pattern))
            };
            let mut cum = 0.0;
            for _ in 0..copies {
                for (i, &s) in sizes.iter().enumerate() {
                    let l = s * factor;
                    if l > EPS {
                        out.push((Some(i), cum, l));
                    }
                    cum += l;
                }
            }
        }
    }
    ctx.room(out.len() as f64, 0.0, format_args!("{name} would make"))?;
    Ok(out)
}

pub(super) fn split(
    ctx: &Ctx<'_>,
    kind: SplitKind,
    axis: Axis,
    sizes: &[f64],
    geom: &Geometry,
    scope: &Scope,
) -> Result<Vec<Piece>, DeriveError> {
    let op = kind.name();
    match geom {
        Geometry::Lot { polygon, z } => {
            if axis == Axis::Z {
                return Err(ctx.unsupported(op, "lot", " along Z (a lot is flat: extrude first)"));
            }
            let segs = layout(ctx, kind, sizes, scope.size[axis.index()], false)?;
            let mut out = Vec::new();
            for (k, p) in clip_pieces(ctx, polygon, scope, axis, &segs)? {
                let s = Scope::around(&p, scope.x2(), *z, 0.0);
                out.push(Piece {
                    succ: k,
                    geom: Geometry::Lot { polygon: p, z: *z },
                    scope: s,
                });
            }
            Ok(out)
        }
        Geometry::Volume {
            footprint,
            z0,
            height,
            ..
        } => {
            let segs = layout(ctx, kind, sizes, scope.size[axis.index()], false)?;
            if axis == Axis::Z {
                // Every storey keeps its own copy of the footprint.
                ctx.room(
                    segs.len() as f64,
                    segs.len() as f64 * polygon_points(footprint) as f64,
                    format_args!("{op} would make"),
                )?;
                return Ok(segs
                    .into_iter()
                    .map(|(k, start, l)| {
                        let mut s = *scope;
                        s.origin.z = z0 + start;
                        s.size.z = l;
                        Piece {
                            succ: k,
                            geom: Geometry::Volume {
                                footprint: footprint.clone(),
                                z0: z0 + start,
                                height: l,
                                scope: s,
                            },
                            scope: s,
                        }
                    })
                    .collect());
            }
            let mut out = Vec::new();
            for (k, p) in clip_pieces(ctx, footprint, scope, axis, &segs)? {
                let s = Scope::around(&p, scope.x2(), *z0, *height);
                out.push(Piece {
                    succ: k,
                    geom: Geometry::Volume {
                        footprint: p,
                        z0: *z0,
                        height: *height,
                        scope: s,
                    },
                    scope: s,
                });
            }
            Ok(out)
        }
        Geometry::Face {
            kind: fk,
            origin,
            x_axis,
            z_axis,
            width,
            height,
            polygon,
        } => {
            let (dir, len) = match axis {
                Axis::X => (*x_axis, *width),
                Axis::Z => (*z_axis, *height),
                Axis::Y => {
                    return Err(ctx.unsupported(
                        op,
                        "face",
                        " along Y (a face has no depth: split along X or Z)",
                    ))
                }
            };
            let segs = layout(ctx, kind, sizes, len, true)?;
            let mut out = Vec::new();
            let mut points = 0;
            for (k, start, l) in segs {
                let o = *origin + dir * start;
                let (w, h) = if axis == Axis::X {
                    (l, *height)
                } else {
                    (*width, l)
                };
                let polys: Vec<Option<Polygon>> = match polygon {
                    None => vec![None],
                    Some(p) => clip_slab(p, h2(*origin), h2(dir), start, start + l)
                        .into_iter()
                        .map(Some)
                        .collect(),
                };
                points += polys.iter().flatten().map(polygon_points).sum::<usize>();
                ctx.room(
                    (out.len() + polys.len()) as f64,
                    points as f64,
                    format_args!("{op} would make at least"),
                )?;
                for poly in polys {
                    let g = Geometry::Face {
                        kind: *fk,
                        origin: o,
                        x_axis: *x_axis,
                        z_axis: *z_axis,
                        width: w,
                        height: h,
                        polygon: poly,
                    };
                    out.push(Piece {
                        succ: k,
                        geom: g,
                        scope: face_scope(o, *x_axis, *z_axis, w, h),
                    });
                }
            }
            Ok(out)
        }
    }
}

/// Clips a footprint to the slabs of a layout along the scope's X or Y. The first and last
/// slabs are open-ended so that no sliver of the footprint is lost to rounding. A slab of a
/// concave footprint may hold many pieces (a comb cut across its teeth), so the pieces and
/// their points are counted against the caps slab by slab, before the next slab is cut.
fn clip_pieces(
    ctx: &Ctx<'_>,
    poly: &Polygon,
    scope: &Scope,
    axis: Axis,
    segs: &[(Option<usize>, f64, f64)],
) -> Result<Vec<(Option<usize>, Polygon)>, DeriveError> {
    let op = ctx.rules.rules[ctx.rule].op.name();
    let mut points = 0;
    let dir = if axis == Axis::X {
        scope.x2()
    } else {
        scope.y2()
    };
    let o = scope.origin2();
    let mut out = Vec::new();
    for (j, &(k, start, l)) in segs.iter().enumerate() {
        let lo = if j == 0 { f64::NEG_INFINITY } else { start };
        let hi = if j + 1 == segs.len() {
            f64::INFINITY
        } else {
            start + l
        };
        let pieces = clip_slab(poly, o, dir, lo, hi);
        points += pieces.iter().map(polygon_points).sum::<usize>();
        ctx.room(
            (out.len() + pieces.len()) as f64,
            points as f64,
            format_args!("{op} would make at least"),
        )?;
        out.extend(pieces.into_iter().map(|p| (k, p)));
    }
    Ok(out)
}
