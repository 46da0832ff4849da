//! `comp`: a volume into its faces, each with its scope and orientation.

use glam::{DVec2, DVec3};

use super::{face_scope, geometry_name, polygon_points, Ctx, DeriveError, Piece};
use crate::grammar::ast::Selector;
use crate::grammar::shape::{FaceKind, Geometry, Scope, EPS};

/// Vertical-face orientation relative to the parent scope (see the module doc of `interp`).
fn orientation(normal: DVec2, scope: &Scope) -> Selector {
    let (nx, ny) = (normal.dot(scope.x2()), normal.dot(scope.y2()));
    if ny.abs() >= nx.abs() {
        if ny < 0.0 {
            Selector::Front
        } else {
            Selector::Back
        }
    } else if nx > 0.0 {
        Selector::Right
    } else {
        Selector::Left
    }
}

pub(super) fn comp(
    ctx: &Ctx<'_>,
    geom: &Geometry,
    scope: &Scope,
) -> Result<Vec<Piece>, DeriveError> {
    let Geometry::Volume {
        footprint,
        z0,
        height,
        ..
    } = geom
    else {
        return Err(ctx.unsupported(
            "comp",
            geometry_name(geom),
            " (comp needs a volume: extrude first)",
        ));
    };
    let succs = &ctx.rules.rules[ctx.rule].succs;
    let pick = |is_side: bool, sel: Option<Selector>| -> Option<usize> {
        succs.iter().position(|s| match s.selector {
            Some(Selector::Side) | Some(Selector::Others) => is_side,
            Some(Selector::Top) => sel == Some(Selector::Top),
            Some(Selector::Bottom) => sel == Some(Selector::Bottom),
            Some(other) => is_side && sel == Some(other),
            None => false,
        })
    };
    // Counted before any face is made: one side face per edge longer than EPS, and a top and
    // a bottom face (each holding the footprint) when a selector takes them.
    let edge = |ring: &[DVec2], k: usize| ring[(k + 1) % ring.len()] - ring[k];
    let sides = footprint
        .rings()
        .map(|ring| {
            (0..ring.len())
                .filter(|&k| edge(ring, k).length() > EPS)
                .count()
        })
        .sum::<usize>();
    let caps_faces = [Selector::Top, Selector::Bottom]
        .iter()
        .filter(|&&sel| pick(false, Some(sel)).is_some())
        .count();
    ctx.room(
        (sides + caps_faces) as f64,
        (caps_faces * polygon_points(footprint)) as f64,
        format_args!("comp would make"),
    )?;
    let mut out = Vec::with_capacity(sides + caps_faces);
    for ring in footprint.rings() {
        let n = ring.len();
        for k in 0..n {
            let a = ring[k];
            let d = edge(ring, k);
            let w = d.length();
            if w <= EPS {
                continue;
            }
            let x2 = d / w;
            let normal = DVec2::new(x2.y, -x2.x);
            let sel = orientation(normal, scope);
            let origin = DVec3::new(a.x, a.y, *z0);
            let x_axis = DVec3::new(x2.x, x2.y, 0.0);
            let g = Geometry::Face {
                kind: FaceKind::Side,
                origin,
                x_axis,
                z_axis: DVec3::Z,
                width: w,
                height: *height,
                polygon: None,
            };
            out.push(Piece {
                succ: pick(true, Some(sel)),
                geom: g,
                scope: face_scope(origin, x_axis, DVec3::Z, w, *height),
            });
        }
    }
    let (sx, sy) = (scope.size.x, scope.size.y);
    let o2 = scope.origin2();
    for (kind, sel) in [
        (FaceKind::Top, Selector::Top),
        (FaceKind::Bottom, Selector::Bottom),
    ] {
        let Some(k) = pick(false, Some(sel)) else {
            continue;
        };
        let (origin, z_axis) = match kind {
            FaceKind::Top => (DVec3::new(o2.x, o2.y, z0 + height), scope.y),
            _ => {
                let o = o2 + scope.y2() * sy;
                (DVec3::new(o.x, o.y, *z0), -scope.y)
            }
        };
        let g = Geometry::Face {
            kind,
            origin,
            x_axis: scope.x,
            z_axis,
            width: sx,
            height: sy,
            polygon: Some(footprint.clone()),
        };
        out.push(Piece {
            succ: Some(k),
            geom: g,
            scope: face_scope(origin, scope.x, z_axis, sx, sy),
        });
    }
    Ok(out)
}
