//! The operations that move or grow a shape: extrude, S (scale), T (translate), R (rotate).

use glam::{DVec2, DVec3};

use super::{face_scope, h2, Ctx, DeriveError};
use crate::geometry::clip::map_polygon;
use crate::geometry::Polygon;
use crate::grammar::shape::{FaceKind, Geometry, Scope, EPS};

pub(super) fn extrude(geom: &Geometry, scope: &Scope, h: f64) -> (Geometry, Scope) {
    match geom {
        Geometry::Lot { polygon, z } => {
            let mut s = *scope;
            s.origin.z = *z;
            s.size.z = h;
            (
                Geometry::Volume {
                    footprint: polygon.clone(),
                    z0: *z,
                    height: h,
                    scope: s,
                },
                s,
            )
        }
        Geometry::Volume { footprint, z0, .. } => {
            let mut s = *scope;
            s.size.z = h;
            (
                Geometry::Volume {
                    footprint: footprint.clone(),
                    z0: *z0,
                    height: h,
                    scope: s,
                },
                s,
            )
        }
        Geometry::Face {
            kind,
            origin,
            x_axis,
            z_axis,
            width,
            height,
            polygon,
        } => {
            let normal = x_axis.cross(*z_axis);
            let (footprint, z0, vh) = match (kind, polygon) {
                (FaceKind::Side, _) | (_, None) => {
                    let (o, x, n) = (h2(*origin), h2(*x_axis), h2(normal));
                    let fp = Polygon::new(
                        vec![o, o + x * *width, o + x * *width + n * h, o + n * h],
                        Vec::new(),
                    );
                    (fp, origin.z, *height)
                }
                (FaceKind::Top, Some(p)) => (p.clone(), origin.z, h),
                (FaceKind::Bottom, Some(p)) => (p.clone(), origin.z - h, h),
            };
            let s = Scope::around(&footprint, h2(*x_axis), z0, vh);
            (
                Geometry::Volume {
                    footprint,
                    z0,
                    height: vh,
                    scope: s,
                },
                s,
            )
        }
    }
}

pub(super) fn scale(
    ctx: &Ctx<'_>,
    geom: &Geometry,
    scope: &Scope,
    v: [f64; 3],
) -> Result<(Geometry, Scope), DeriveError> {
    let check = |val: f64, name: &str| {
        if val <= EPS {
            Err(ctx.bad(format!("S: size {name} = {val} is not positive")))
        } else {
            Ok(())
        }
    };
    // Scales 2D points about the scope origin along the scope's X and Y.
    let scale2 = |poly: &Polygon, fx: f64, fy: f64| {
        if fx == 1.0 && fy == 1.0 {
            return poly.clone();
        }
        let (o, x, y) = (scope.origin2(), scope.x2(), scope.y2());
        map_polygon(poly, |p| {
            let d = p - o;
            o + x * (d.dot(x) * fx) + y * (d.dot(y) * fy)
        })
    };
    let ratio = |new: f64, old: f64| if old > EPS { new / old } else { 1.0 };
    match geom {
        Geometry::Lot { polygon, z } => {
            check(v[0], "x")?;
            check(v[1], "y")?;
            let p = scale2(
                polygon,
                ratio(v[0], scope.size.x),
                ratio(v[1], scope.size.y),
            );
            let mut s = *scope;
            s.size.x = v[0];
            s.size.y = v[1];
            Ok((Geometry::Lot { polygon: p, z: *z }, s))
        }
        Geometry::Volume { footprint, z0, .. } => {
            check(v[0], "x")?;
            check(v[1], "y")?;
            check(v[2], "z")?;
            let p = scale2(
                footprint,
                ratio(v[0], scope.size.x),
                ratio(v[1], scope.size.y),
            );
            let mut s = *scope;
            s.size = DVec3::from(v);
            Ok((
                Geometry::Volume {
                    footprint: p,
                    z0: *z0,
                    height: v[2],
                    scope: s,
                },
                s,
            ))
        }
        Geometry::Face {
            kind,
            origin,
            x_axis,
            z_axis,
            width,
            height,
            polygon,
        } => {
            check(v[0], "x")?;
            check(v[2], "z")?;
            let (fx, fz) = (ratio(v[0], *width), ratio(v[2], *height));
            let polygon = polygon.as_ref().map(|p| {
                let (o, x, z) = (h2(*origin), h2(*x_axis), h2(*z_axis));
                map_polygon(p, |q| {
                    let d = q - o;
                    o + x * (d.dot(x) * fx) + z * (d.dot(z) * fz)
                })
            });
            let g = Geometry::Face {
                kind: *kind,
                origin: *origin,
                x_axis: *x_axis,
                z_axis: *z_axis,
                width: v[0],
                height: v[2],
                polygon,
            };
            Ok((g, face_scope(*origin, *x_axis, *z_axis, v[0], v[2])))
        }
    }
}

pub(super) fn translate(geom: &Geometry, scope: &Scope, v: [f64; 3]) -> (Geometry, Scope) {
    match geom {
        Geometry::Lot { polygon, z } => {
            let d = scope.x2() * v[0] + scope.y2() * v[1];
            let mut s = *scope;
            s.origin += DVec3::new(d.x, d.y, v[2]);
            (
                Geometry::Lot {
                    polygon: polygon.translated(d),
                    z: z + v[2],
                },
                s,
            )
        }
        Geometry::Volume {
            footprint,
            z0,
            height,
            ..
        } => {
            let d = scope.x2() * v[0] + scope.y2() * v[1];
            let mut s = *scope;
            s.origin += DVec3::new(d.x, d.y, v[2]);
            (
                Geometry::Volume {
                    footprint: footprint.translated(d),
                    z0: z0 + v[2],
                    height: *height,
                    scope: s,
                },
                s,
            )
        }
        Geometry::Face {
            kind,
            origin,
            x_axis,
            z_axis,
            width,
            height,
            polygon,
        } => {
            let d = *x_axis * v[0] + x_axis.cross(*z_axis) * v[1] + *z_axis * v[2];
            let o = *origin + d;
            let polygon = polygon.as_ref().map(|p| p.translated(h2(d)));
            let g = Geometry::Face {
                kind: *kind,
                origin: o,
                x_axis: *x_axis,
                z_axis: *z_axis,
                width: *width,
                height: *height,
                polygon,
            };
            (g, face_scope(o, *x_axis, *z_axis, *width, *height))
        }
    }
}

pub(super) fn rotate(geom: &Geometry, scope: &Scope, deg: f64) -> (Geometry, Scope) {
    let rot = DVec2::from_angle(deg.to_radians());
    let o = scope.origin2();
    let turn = |p: &Polygon| map_polygon(p, |q| o + rot.rotate(q - o));
    let mut s = *scope;
    let (x, y) = (rot.rotate(scope.x2()), rot.rotate(scope.y2()));
    s.x = DVec3::new(x.x, x.y, 0.0);
    s.y = DVec3::new(y.x, y.y, 0.0);
    match geom {
        Geometry::Lot { polygon, z } => (
            Geometry::Lot {
                polygon: turn(polygon),
                z: *z,
            },
            s,
        ),
        Geometry::Volume {
            footprint,
            z0,
            height,
            ..
        } => (
            Geometry::Volume {
                footprint: turn(footprint),
                z0: *z0,
                height: *height,
                scope: s,
            },
            s,
        ),
        Geometry::Face {
            kind,
            origin,
            z_axis,
            width,
            height,
            ..
        } => {
            // A side face turns about its vertical left edge (a hinge): it stays vertical and
            // keeps its size; its outward normal turns by the same angle.
            let x_axis = s.x;
            let g = Geometry::Face {
                kind: *kind,
                origin: *origin,
                x_axis,
                z_axis: *z_axis,
                width: *width,
                height: *height,
                polygon: None,
            };
            (g, face_scope(*origin, x_axis, *z_axis, *width, *height))
        }
    }
}
