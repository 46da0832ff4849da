//! Rectangles on a face: overlap, contact, distance to the edge, and the cover of a face
//! minus its holes.

use super::same;
use crate::selex::grid::Rect;

/// Whether two rectangles share interior.
pub(super) fn overlap(a: &Rect, b: &Rect) -> bool {
    let eps = 1e-6;
    a.x + eps < b.x + b.w && b.x + eps < a.x + a.w && a.y + eps < b.y + b.h && b.y + eps < a.y + a.h
}

/// Whether two rectangles touch along an edge (without overlapping).
pub(super) fn touch(a: &Rect, b: &Rect) -> bool {
    let eps = 1e-6;
    let x_meet = (a.x + a.w - b.x).abs() < eps || (b.x + b.w - a.x).abs() < eps;
    let y_meet = (a.y + a.h - b.y).abs() < eps || (b.y + b.h - a.y).abs() < eps;
    let x_span = a.x + eps < b.x + b.w && b.x + eps < a.x + a.w;
    let y_span = a.y + eps < b.y + b.h && b.y + eps < a.y + a.h;
    (x_meet && y_span) || (y_meet && x_span)
}

pub(super) fn too_close(r: &Rect, w: f64, h: f64, min: f64) -> bool {
    r.x < min - 1e-9
        || r.y < min - 1e-9
        || w - (r.x + r.w) < min - 1e-9
        || h - (r.y + r.h) < min - 1e-9
}

/// The rectangle `w × h` minus `holes`, as rectangles: the plane cut at every hole edge into
/// slabs, the free cells of each horizontal band merged into runs, and runs merged upwards
/// with the run directly below when they span the same columns.
pub(crate) fn cover(w: f64, h: f64, holes: &[Rect]) -> Vec<Rect> {
    let clamp = |v: f64, hi: f64| v.clamp(0.0, hi);
    let mut xs = vec![0.0, w];
    let mut ys = vec![0.0, h];
    for r in holes {
        xs.extend([clamp(r.x, w), clamp(r.x + r.w, w)]);
        ys.extend([clamp(r.y, h), clamp(r.y + r.h, h)]);
    }
    let sort = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
    };
    sort(&mut xs);
    sort(&mut ys);
    let mut out: Vec<Rect> = Vec::new();
    // Runs of the band below: (x0, x1, index in out).
    let mut below: Vec<(f64, f64, usize)> = Vec::new();
    for band in ys.windows(2) {
        let (y0, y1) = (band[0], band[1]);
        if y1 - y0 < 1e-9 {
            continue;
        }
        let mut runs: Vec<(f64, f64)> = Vec::new();
        for col in xs.windows(2) {
            let (x0, x1) = (col[0], col[1]);
            if x1 - x0 < 1e-9 {
                continue;
            }
            let cell = Rect {
                x: x0,
                y: y0,
                w: x1 - x0,
                h: y1 - y0,
            };
            if holes.iter().any(|r| overlap(r, &cell)) {
                continue;
            }
            match runs.last_mut() {
                Some(last) if (last.1 - x0).abs() < 1e-9 => last.1 = x1,
                _ => runs.push((x0, x1)),
            }
        }
        let mut now = Vec::with_capacity(runs.len());
        for (x0, x1) in runs {
            let grow = below
                .iter()
                .find(|(a, b, i)| same(*a, x0) && same(*b, x1) && same(out[*i].y + out[*i].h, y0));
            match grow {
                Some(&(_, _, i)) => {
                    out[i].h = y1 - out[i].y;
                    now.push((x0, x1, i));
                }
                None => {
                    out.push(Rect {
                        x: x0,
                        y: y0,
                        w: x1 - x0,
                        h: y1 - y0,
                    });
                    now.push((x0, x1, out.len() - 1));
                }
            }
        }
        below = now;
    }
    out
}
