//! A ring split by a level into the pieces below and above, each cut point computed so that the
//! two faces sharing a segment get the same bits.

use glam::{DVec2, DVec3};

/// Splits a simple ring of points `(x, y, t)` by the level `t = l` (no vertex on it) into the
/// pieces below and above. Pieces keep the ring's orientation.
pub(super) fn split_ring(ring: &[DVec3], l: f64) -> (Vec<Vec<DVec3>>, Vec<Vec<DVec3>>) {
    let n = ring.len();
    let below = |p: &DVec3| p.z < l;
    if ring.iter().all(below) {
        return (vec![ring.to_vec()], Vec::new());
    }
    if !ring.iter().any(below) {
        return (Vec::new(), vec![ring.to_vec()]);
    }
    // Ring with crossings inserted; `cross[k]` is Some(order along the line) for crossings.
    let mut pts: Vec<DVec3> = Vec::with_capacity(n + 4);
    let mut is_cross: Vec<bool> = Vec::with_capacity(n + 4);
    for i in 0..n {
        let (p, q) = (ring[i], ring[(i + 1) % n]);
        pts.push(p);
        is_cross.push(false);
        if below(&p) != below(&q) {
            pts.push(cross(p, q, l));
            is_cross.push(true);
        }
    }
    let m = pts.len();
    // Direction along the line: any, as long as both sides use the same; take the direction of
    // the first crossing pair's chord by sorting on the dominant axis of the crossings' spread.
    let xs: Vec<usize> = (0..m).filter(|&k| is_cross[k]).collect();
    let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
    for &k in &xs {
        lo = lo.min(pts[k].truncate());
        hi = hi.max(pts[k].truncate());
    }
    let axis = if hi.x - lo.x >= hi.y - lo.y {
        DVec2::X
    } else {
        DVec2::Y
    };
    let mut order = xs.clone();
    order.sort_by(|&u, &v| {
        pts[u]
            .truncate()
            .dot(axis)
            .total_cmp(&pts[v].truncate().dot(axis))
    });
    let mut partner = vec![usize::MAX; m];
    for c in order.chunks(2) {
        if let [u, v] = c {
            partner[*u] = *v;
            partner[*v] = *u;
        }
    }
    let mut used = vec![false; m];
    let mut pieces_below = Vec::new();
    let mut pieces_above = Vec::new();
    for start in 0..m {
        if is_cross[start] || used[start] {
            continue;
        }
        let side = below(&pts[start]);
        let mut piece = Vec::new();
        let mut k = start;
        let mut guard = 0;
        loop {
            guard += 1;
            if guard > 4 * m + 8 {
                break;
            }
            used[k] = true;
            piece.push(pts[k]);
            let nk = (k + 1) % m;
            if is_cross[nk] {
                // Leaving the side: take the chord to the partner, then carry on from there.
                piece.push(pts[nk]);
                let p = partner[nk];
                if p == usize::MAX {
                    break;
                }
                piece.push(pts[p]);
                k = (p + 1) % m;
            } else {
                k = nk;
            }
            if k == start {
                break;
            }
        }
        if piece.len() >= 3 {
            if side {
                pieces_below.push(piece);
            } else {
                pieces_above.push(piece);
            }
        }
    }
    (pieces_below, pieces_above)
}

/// The point of segment `p q` at `t = l`, computed from the endpoints in a canonical order so
/// that the two faces sharing the segment get the same bits.
fn cross(p: DVec3, q: DVec3, l: f64) -> DVec3 {
    let key = |v: DVec3| (v.x.to_bits(), v.y.to_bits(), v.z.to_bits());
    let (p, q) = if key(p) <= key(q) { (p, q) } else { (q, p) };
    let s = ((l - p.z) / (q.z - p.z)).clamp(0.0, 1.0);
    let g = p.truncate() + (q.truncate() - p.truncate()) * s;
    g.extend(l)
}
