//! Hip ends turned into gables or half-hips (see the documentation of `shapes`).

use glam::{DVec2, DVec3};

use super::{Ends, TFace, GABLE_APEX_CLUSTER, GABLE_MIN_OPPOSITE_DEG};

/// Most faces one end of a wing may be made of: a side whose vertex is a little off straight
/// (beyond the skeleton's collinear tolerance, within [`GABLE_MAX_KINK_DEG`]) has a face on
/// each part, and the two together are the end.
pub(crate) const GABLE_MAX_CHAIN: usize = 3;

/// Most turn (degrees) between the parts of one end of a wing (see [`GABLE_MAX_CHAIN`]).
pub(crate) const GABLE_MAX_KINK_DEG: f64 = 1.0;

/// Turns hip ends into gables or half-hips in place (see the documentation of `shapes`).
///
/// A hip end is a face — or a run of up to [`GABLE_MAX_CHAIN`] faces of consecutive sides that
/// turn by less than [`GABLE_MAX_KINK_DEG`] from each other (one side with a vertex a little
/// off straight) — whose vertices other than its base `a → … → b` (its *top*) lie within
/// [`GABLE_APEX_CLUSTER`] of the base's length of each other — one apex, or the few nodes a
/// nearly antiparallel pair of sides leaves where the exact skeleton has one (a rectangle
/// skewed by hundredths of a degree) — and touch no face but the end's two neighbours, whose
/// sides run roughly opposite. Each neighbour's run of top vertices is replaced by the gable
/// point `p` (or the half-hip's points), which lies exactly on both neighbours' planes, so they
/// stay planar and share their new ridge end; a kink of the base between `a` and `p` is lifted
/// onto the first neighbour's plane (the roof line over it), one between `p` and `b` onto the
/// second's. A square's four hips meet in one apex: two opposite ones become the gables.
pub(super) fn make_gables(faces: &mut Vec<Option<TFace>>, ends: Ends, tol: f64) {
    let mut skipped_first = false;
    let mut side_done = false;
    // The next face of the same ring, in ring order.
    let next_of = |faces: &[Option<TFace>], i: usize| -> Option<usize> {
        let e = faces[i].as_ref()?.edge;
        let same: Vec<usize> = (0..faces.len())
            .filter(|&j| faces[j].as_ref().is_some_and(|f| f.edge.0 == e.0))
            .collect();
        let k = same.iter().position(|&j| j == i)?;
        Some(same[(k + 1) % same.len()])
    };
    for i in 0..faces.len() {
        if faces[i].is_none() {
            continue;
        }
        let mut chain = vec![i];
        for _ in 0..GABLE_MAX_CHAIN {
            // A side-half-hipped roof: its first end half-hipped, the others gables.
            let this = match ends {
                Ends::SideHalfHipped(c) if !side_done => Ends::HalfHipped(c),
                Ends::SideHalfHipped(_) => Ends::Gabled,
                e => e,
            };
            if let Some(done) = gable_chain(faces, &chain, this, tol, &mut skipped_first) {
                side_done |= done;
                break;
            }
            let Some(n) = next_of(faces, *chain.last().unwrap_or(&i)) else {
                break;
            };
            if chain.contains(&n) || !kinked(faces, *chain.last().unwrap_or(&i), n) {
                break;
            }
            chain.push(n);
        }
    }
    if !matches!(ends, Ends::Gabled | Ends::HalfHipped(_)) {
        return;
    }
    for i in 0..faces.len() {
        square_gables(faces, i, ends, tol);
    }
}

/// Whether face `j`'s side follows face `i`'s with a turn under [`GABLE_MAX_KINK_DEG`].
fn kinked(faces: &[Option<TFace>], i: usize, j: usize) -> bool {
    let (Some(f), Some(g)) = (&faces[i], &faces[j]) else {
        return false;
    };
    if f.pts.len() < 2 || g.pts.len() < 2 {
        return false;
    }
    let (rf, rg) = (base_run(f, 0.0), base_run(g, 0.0));
    let (f0, f1) = (rf[rf.len() - 2], rf[rf.len() - 1]);
    if f1.distance(g.pts[0]) > 1e-9 {
        return false;
    }
    let d1 = (f1 - f0).truncate().normalize_or_zero();
    let d2 = (rg[1] - rg[0]).truncate().normalize_or_zero();
    d1.dot(d2) >= GABLE_MAX_KINK_DEG.to_radians().cos()
}

/// The face's side: its first vertices, as long as they are on the footprint (`t` within
/// `tol` of 0), at least its first two. A side with collinear vertices (the corners of parts
/// drawn along it) is one face whose side has them all.
fn base_run(f: &TFace, tol: f64) -> &[DVec3] {
    let n = f
        .pts
        .iter()
        .take_while(|p| p.z.abs() <= tol)
        .count()
        .clamp(2.min(f.pts.len()), f.pts.len());
    &f.pts[..n]
}

/// The two faces holding `a → top` (before `a` in its ring) and `top → b`, with every face
/// touching the top outside `chain`; `None` unless they are exactly two and distinct.
fn end_neighbours(
    faces: &[Option<TFace>],
    chain: &[usize],
    a: DVec3,
    b: DVec3,
    in_top: &impl Fn(DVec3) -> bool,
    tol: f64,
) -> Option<(usize, usize)> {
    let touching: Vec<usize> = (0..faces.len())
        .filter(|j| !chain.contains(j))
        .filter(|&j| {
            faces[j]
                .as_ref()
                .is_some_and(|g| g.pts.iter().any(|q| in_top(*q)))
        })
        .collect();
    if touching.len() != 2 {
        return None;
    }
    let (mut prev, mut next) = (None, None);
    for &j in &touching {
        let g = faces[j].as_ref()?;
        let n = g.pts.len();
        for k in 0..n {
            let (u, v) = (g.pts[k], g.pts[(k + 1) % n]);
            if u.distance(a) <= tol && in_top(v) {
                prev = Some(j);
            }
            if in_top(u) && v.distance(b) <= tol {
                next = Some(j);
            }
        }
    }
    let (jp, jn) = (prev?, next?);
    (jp != jn).then_some((jp, jn))
}

/// The line of face `j`'s edge: origin and unit inward normal (the distance `t = n·(x - o)`),
/// when it runs roughly opposite to the other one's ([`GABLE_MIN_OPPOSITE_DEG`]).
fn opposite_lines(fp: &TFace, fnx: &TFace) -> Option<((DVec2, DVec2), (DVec2, DVec2))> {
    let dp = (fp.pts[1] - fp.pts[0]).truncate().normalize_or_zero();
    let dn = (fnx.pts[1] - fnx.pts[0]).truncate().normalize_or_zero();
    let min_cos = GABLE_MIN_OPPOSITE_DEG.to_radians().cos();
    if dp.dot(dn) > min_cos || dp == DVec2::ZERO || dn == DVec2::ZERO {
        return None;
    }
    Some((
        (fp.pts[0].truncate(), dp.perp()),
        (fnx.pts[0].truncate(), dn.perp()),
    ))
}

/// Makes the end made of the faces `chain` (consecutive sides) a gable or half-hip if it is a
/// hip end (see [`make_gables`]): `Some(true)` when it did, `Some(false)` when the end is one
/// but was left hipped on purpose (the first end of a side-hipped roof), `None` when the chain
/// is no hip end.
fn gable_chain(
    faces: &mut Vec<Option<TFace>>,
    chain: &[usize],
    ends: Ends,
    tol: f64,
    skipped_first: &mut bool,
) -> Option<bool> {
    // The base polyline a = q0, …, qm = b, and the top: every other vertex of the chain.
    let mut base: Vec<DVec3> = Vec::new();
    for &k in chain {
        let f = faces[k].as_ref()?;
        if f.pts.len() < 3 {
            return None;
        }
        let run = base_run(f, tol);
        if base.is_empty() {
            base.push(run[0]);
        }
        base.extend_from_slice(&run[1..]);
    }
    let (a, b) = (base[0], base[base.len() - 1]);
    let on_base = |q: DVec3| base.iter().any(|m| m.distance(q) <= tol);
    let mut top: Vec<DVec3> = Vec::new();
    for &k in chain {
        for q in &faces[k].as_ref()?.pts {
            if !on_base(*q) && !top.iter().any(|m| m.distance(*q) <= tol) {
                top.push(*q);
            }
        }
    }
    if top.is_empty() {
        return None;
    }
    // One apex: the top's highest vertex and those near it. A vertex clearly lower may be
    // there too, where a short face of a kinked side closed before the apex (a side drawn
    // in two pieces a few millimetres off straight); the end's neighbours hold it, and it
    // goes with the end. Two vertices far apart at the same height are a ridge: a long
    // side, no end.
    let width = (b - a).truncate().length();
    let cluster = GABLE_APEX_CLUSTER * width;
    let apex = top
        .iter()
        .copied()
        .max_by(|p, q| p.z.total_cmp(&q.z))
        .unwrap_or(a);
    if !top
        .iter()
        .all(|q| q.distance(apex) <= cluster || q.z < apex.z - cluster)
    {
        return None;
    }
    let in_top = |q: DVec3| top.iter().any(|m| m.distance(q) <= tol);
    let (jp, jn) = end_neighbours(faces, chain, a, b, &in_top, tol)?;
    let ((op, np), (on, nn)) = opposite_lines(faces[jp].as_ref()?, faces[jn].as_ref()?)?;
    let tp = |x: DVec2| np.dot(x - op);
    let tn = |x: DVec2| nn.dot(x - on);
    // The gable point: where the base is as far from both neighbours' lines.
    let f = |x: DVec2| tp(x) - tn(x);
    let mut at = None;
    for k in 0..base.len() - 1 {
        let (u, v) = (base[k].truncate(), base[k + 1].truncate());
        let (fu, fv) = (f(u), f(v));
        if fu <= 0.0 && fv > 0.0 {
            let s = -fu / (fv - fu);
            at = Some((k, u + (v - u) * s));
            break;
        }
    }
    let (k, p2) = at?;
    let t_p = tp(p2);
    if !(t_p.is_finite() && t_p > tol && p2.distance(a.truncate()) > 1e-3 * width)
        || p2.distance(b.truncate()) <= 1e-3 * width
    {
        return None;
    }
    if ends == Ends::AllButOne && !*skipped_first {
        *skipped_first = true;
        return Some(false);
    }
    let p = p2.extend(t_p);
    // The kinks of the base lifted onto the neighbour's plane on their side of p.
    let before: Vec<DVec3> = base[1..=k]
        .iter()
        .map(|q| q.truncate().extend(tp(q.truncate())))
        .collect();
    let after: Vec<DVec3> = base[k + 1..base.len() - 1]
        .iter()
        .map(|q| q.truncate().extend(tn(q.truncate())))
        .collect();
    let mut extra = None;
    let (with_prev, with_next, hip) = match ends {
        Ends::HipAndGable(c, steep) => {
            let (hip, wp, wn, gable) =
                hip_and_gable(faces, chain, &base, (jp, jn), (p, np - nn), c, steep, tol)?;
            extra = Some(gable);
            (wp, wn, Some(hip))
        }
        Ends::HalfHipped(c) => {
            let c = c.clamp(0.05, 0.95);
            // The half-hip's base cuts the gable at c of its height, above every kink (a kink
            // higher up would put the hip's base off the wall).
            let cut = c * t_p;
            if before.iter().chain(&after).any(|q| q.z >= cut) {
                return None;
            }
            let last_a = before.last().copied().unwrap_or(a);
            let first_b = after.first().copied().unwrap_or(b);
            let xa = last_a + (p - last_a) * ((cut - last_a.z) / (t_p - last_a.z));
            let xb = first_b + (p - first_b) * ((cut - first_b.z) / (t_p - first_b.z));
            // The hip's top on the ridge (the line both neighbours' planes share), a
            // horizontal (1 - c)·tp from p, so the small hip keeps about the roof's pitch,
            // and no farther than the old apex.
            let apex = top.iter().copied().sum::<DVec3>() / top.len() as f64;
            let mut d = (np - nn).perp().normalize_or_zero();
            if d.dot(apex.truncate() - p2) < 0.0 {
                d = -d;
            }
            let run = ((1.0 - c) * t_p).min((apex.truncate() - p2).dot(d));
            if !(run.is_finite() && run > tol) {
                return None;
            }
            let r = (p2 + d * run).extend(t_p + np.dot(d) * run);
            let mut wp = before.clone();
            wp.extend([xa, r]);
            let mut wn = vec![r, xb];
            wn.extend(after.iter().copied());
            (wp, wn, Some(vec![xa, xb, r]))
        }
        _ => {
            let mut wp = before.clone();
            wp.push(p);
            let mut wn = vec![p];
            wn.extend(after.iter().copied());
            (wp, wn, None)
        }
    };
    let edge = faces[chain[0]].as_ref()?.edge;
    for &c in chain {
        faces[c] = None;
    }
    if let Some(pts) = hip {
        faces[chain[0]] = Some(TFace { edge, pts });
    }
    if let Some(pts) = extra {
        faces.push(Some(TFace { edge, pts }));
    }
    for (j, with) in [(jp, with_prev), (jn, with_next)] {
        if let Some(g) = faces[j].as_mut() {
            g.pts = replace_runs(&g.pts, &in_top, &with);
            g.pts.dedup_by(|x, y| x.distance(*y) <= tol);
        }
    }
    Some(true)
}

/// A hipped-and-gabled end (see [`Ends::HipAndGable`]) of the one face `chain` on `base`
/// between the neighbours `jp` (before it) and `jn`: the hip up to the fraction `c` of its
/// lines to the top (`xa`, `xb`), and the small gable `xa, xb, r` rising `steep` in `t` per
/// metre to the point `r` of the ridge (the line through the gable point `p` across
/// `normals`, the difference of the neighbours' unit normals), which both neighbours reach
/// instead of the old top. Returns the hip, the neighbours' new runs and the gable, or `None`
/// when the gable would not stand between the hip and the old top.
#[allow(clippy::too_many_arguments)]
fn hip_and_gable(
    faces: &[Option<TFace>],
    chain: &[usize],
    base: &[DVec3],
    (jp, jn): (usize, usize),
    (p, normals): (DVec3, DVec2),
    c: f64,
    steep: f64,
    tol: f64,
) -> Option<HipAndGable> {
    if chain.len() != 1 || base.len() < 2 || !(steep.is_finite() && steep > 0.0) {
        return None;
    }
    let (a, b) = (base[0], base[base.len() - 1]);
    // The hip lines: a → ta (the vertex after a in jp), tb → b (the one before b in jn).
    let g = faces[jp].as_ref()?;
    let ia = g.pts.iter().position(|q| q.distance(a) <= tol)?;
    let ta = g.pts[(ia + 1) % g.pts.len()];
    let h = faces[jn].as_ref()?;
    let ib = h.pts.iter().position(|q| q.distance(b) <= tol)?;
    let tb = h.pts[(ib + h.pts.len() - 1) % h.pts.len()];
    let c = c.clamp(0.05, 0.95);
    let (xa, xb) = (a + (ta - a) * c, b + (tb - b) * c);
    let e = (xb - xa).truncate().normalize_or_zero();
    if e == DVec2::ZERO {
        return None;
    }
    let inward = e.perp();
    let dist = |x: DVec2| (x - xa.truncate()).dot(inward);
    // Along the ridge from p, inwards: t rises as the first neighbour's plane does.
    let mut d = normals.perp().normalize_or_zero();
    if d.dot(inward) < 0.0 {
        d = -d;
    }
    let np = {
        // The first neighbour's inward normal: its side runs from its first vertex.
        let dir = (g.pts[1] - g.pts[0]).truncate().normalize_or_zero();
        dir.perp()
    };
    let rise = np.dot(d);
    let tx = 0.5 * (xa.z + xb.z);
    let p2 = p.truncate();
    // t(s) - tx = steep · dist(s), both linear in s.
    let den = rise - steep * d.dot(inward);
    if den.abs() < 1e-12 {
        return None;
    }
    let s = (steep * dist(p2) - (p.z - tx)) / den;
    let r2 = p2 + d * s;
    let r = r2.extend(p.z + rise * s);
    let width = (b - a).truncate().length();
    let room = dist(ta.truncate()).min(dist(tb.truncate()));
    if !(s.is_finite()
        && dist(r2) > 1e-3 * width
        && dist(r2) < room - 1e-3 * width
        && r.z > xa.z.max(xb.z) + tol)
    {
        return None;
    }
    let mut hip = base.to_vec();
    hip.extend([xb, xa]);
    Some((hip, vec![xa, r], vec![r, xb], vec![xa, xb, r]))
}

/// What [`hip_and_gable`] makes: the hip, the two neighbours' new runs and the gable.
type HipAndGable = (Vec<DVec3>, Vec<DVec3>, Vec<DVec3>, Vec<DVec3>);

/// A square's roof (four hips meeting in one apex) made gabled: face `i` and the face opposite
/// it become the gables, the two others meet along a ridge between their gable points. Does
/// nothing unless face `i`'s top is one point shared by exactly three other faces: the one
/// before it, the one after it (whose sides run opposite) and one whose side runs opposite to
/// `i`'s.
fn square_gables(faces: &mut [Option<TFace>], i: usize, ends: Ends, tol: f64) {
    let Some(f) = &faces[i] else { return };
    if f.pts.len() != 3 {
        return;
    }
    let (a, b, apex) = (f.pts[0], f.pts[1], f.pts[2]);
    let at_apex = |q: DVec3| q.distance(apex) <= tol;
    let touching: Vec<usize> = (0..faces.len())
        .filter(|&j| j != i)
        .filter(|&j| {
            faces[j]
                .as_ref()
                .is_some_and(|g| g.pts.iter().any(|q| at_apex(*q)))
        })
        .collect();
    if touching.len() != 3 {
        return;
    }
    let side = |j: usize| -> Option<(DVec3, DVec3)> {
        let g = faces[j].as_ref()?;
        (g.pts.len() == 3).then(|| (g.pts[0], g.pts[1]))
    };
    let mut prev = None;
    let mut next = None;
    let mut opposite = None;
    for &j in &touching {
        let Some((u, v)) = side(j) else { return };
        if v.distance(a) <= tol {
            prev = Some(j);
        } else if u.distance(b) <= tol {
            next = Some(j);
        } else {
            opposite = Some(j);
        }
    }
    let (Some(jp), Some(jn), Some(jo)) = (prev, next, opposite) else {
        return;
    };
    let (Some(fp), Some(fnx)) = (&faces[jp], &faces[jn]) else {
        return;
    };
    let Some(((op, np), (on, nn))) = opposite_lines(fp, fnx) else {
        return;
    };
    let Some((c, d)) = side(jo) else { return };
    // The gable points: on each end's side, as far from both neighbours' lines.
    let gable_point = |u: DVec3, v: DVec3| -> Option<DVec3> {
        let (u, v) = (u.truncate(), v.truncate());
        let f = |x: DVec2| np.dot(x - op) - nn.dot(x - on);
        let (fu, fv) = (f(u), f(v));
        if (fu - fv).abs() < 1e-12 {
            return None;
        }
        let s = fu / (fu - fv);
        if !(s > 1e-3 && s < 1.0 - 1e-3) {
            return None;
        }
        let x = u + (v - u) * s;
        let t = np.dot(x - op);
        (t > tol).then(|| x.extend(t))
    };
    let (ab, cd) = ((b - a).truncate(), (d - c).truncate());
    if ab.normalize_or_zero().dot(cd.normalize_or_zero()) > -std::f64::consts::FRAC_1_SQRT_2 {
        return;
    }
    let (Some(p), Some(q)) = (gable_point(a, b), gable_point(c, d)) else {
        return;
    };
    let edge_i = f.edge;
    let edge_o = faces[jo].as_ref().map(|g| g.edge);
    let (with_prev, with_next, hips) = match ends {
        Ends::HalfHipped(frac) => {
            // Each gable stops at `frac` of its height, and a small hip rises from there to
            // the ridge (the segment p q, on both neighbours' planes), a horizontal
            // (1 - frac)·t from the gable point, at most half-way.
            let frac = frac.clamp(0.05, 0.95);
            let cut = |u: DVec3, g: DVec3| u + (g - u) * frac;
            let len = (q - p).truncate().length();
            let run = ((1.0 - frac) * p.z.min(q.z)).min(0.5 * len);
            if !(run > tol && len > tol) {
                return;
            }
            let (rp, rq) = (p + (q - p) * (run / len), q + (p - q) * (run / len));
            let (xa, xb, xc, xd) = (cut(a, p), cut(b, p), cut(c, q), cut(d, q));
            (
                vec![xa, rp, rq, xd],
                vec![xc, rq, rp, xb],
                Some((vec![xa, xb, rp], vec![xc, xd, rq])),
            )
        }
        _ => (vec![p, q], vec![q, p], None),
    };
    faces[i] = None;
    faces[jo] = None;
    if let (Some((hi, ho)), Some(eo)) = (hips, edge_o) {
        faces[i] = Some(TFace {
            edge: edge_i,
            pts: hi,
        });
        faces[jo] = Some(TFace { edge: eo, pts: ho });
    }
    // Before `i` the ridge runs from i's gable to the opposite one; after it, back.
    for (j, with) in [(jp, with_prev), (jn, with_next)] {
        if let Some(g) = faces[j].as_mut() {
            g.pts = replace_runs(&g.pts, &at_apex, &with);
            g.pts.dedup_by(|x, y| x.distance(*y) <= tol);
        }
    }
}

/// The ring with every maximal (cyclic) run of the points `hit` marks replaced by `with`.
fn replace_runs(ring: &[DVec3], hit: &impl Fn(DVec3) -> bool, with: &[DVec3]) -> Vec<DVec3> {
    let n = ring.len();
    let Some(start) = (0..n).find(|&k| !hit(ring[k])) else {
        return with.to_vec();
    };
    let mut out = Vec::with_capacity(n + with.len());
    let mut in_run = false;
    for k in 0..n {
        let q = ring[(start + k) % n];
        if hit(q) {
            if !in_run {
                out.extend_from_slice(with);
                in_run = true;
            }
        } else {
            out.push(q);
            in_run = false;
        }
    }
    out
}
