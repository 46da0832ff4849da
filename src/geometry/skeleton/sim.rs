//! The propagation: wavefront vertices moving along their bisectors, edge and split events
//! processed in time order, and the faces traced from the nodes they leave.

use super::*;

/// A wavefront edge or a run of vertices meeting at an event point.
#[derive(Clone, Copy, Debug)]
pub(super) struct Pass {
    /// Vertex before the pass (not at the point).
    pub(super) entry: usize,
    /// Vertex after the pass.
    pub(super) exit: usize,
    pub(super) in_edge: usize,
    pub(super) out_edge: usize,
    /// First and last vertex of the run; `None` for an edge passing through the point.
    pub(super) run: Option<(usize, usize)>,
}

pub(super) struct Sim {
    pub(super) edges: Vec<Edge>,
    pub(super) nodes: Vec<Node>,
    pub(super) verts: Vec<Vert>,
    /// Directed boundary segments (node ids) of each edge's face.
    pub(super) segs: Vec<Vec<(usize, usize)>>,
    /// Base segment (start node, end node) of each edge.
    pub(super) base: Vec<(usize, usize)>,
    pub(super) eps: f64,
    pub(super) t: f64,
    pub(super) size: f64,
    /// Events found at the current time whose handling changed nothing (a vertex and the edge
    /// it was to meet, `usize::MAX` for its own edge's collapse): skipped until time moves on,
    /// so that an event the point handling cannot resolve never stalls the propagation.
    pub(super) stale: Vec<(usize, usize)>,
    /// Buffers reused from event to event.
    pub(super) scratch: Scratch,
}

/// Buffers of [`Sim`]'s steps, kept between them (their contents are rebuilt every time).
#[derive(Default)]
pub(super) struct Scratch {
    alive: Vec<usize>,
    member: Vec<bool>,
    visited: Vec<bool>,
    pos: Vec<DVec2>,
    fronts: Vec<(usize, usize, DVec2, DVec2)>,
    /// The wavefront edges' starts and normals by coordinate (x, y of the start, x, y of the
    /// normal), and which of them a vertex may meet.
    front_xy: [Vec<f64>; 4],
    keep: Vec<bool>,
}

impl Sim {
    pub(super) fn new(edges: Vec<Edge>, ring_starts: &[usize], size: f64) -> Sim {
        let ne = edges.len();
        let mut sim = Sim {
            nodes: Vec::with_capacity(4 * ne),
            verts: Vec::with_capacity(4 * ne),
            segs: vec![Vec::new(); ne],
            base: vec![(0, 0); ne],
            eps: EVENT_REL * size,
            t: 0.0,
            size,
            edges,
            stale: Vec::new(),
            scratch: Scratch::default(),
        };
        for r in 0..ring_starts.len() - 1 {
            let (s, e) = (ring_starts[r], ring_starts[r + 1]);
            for i in s..e {
                let prev = if i == s { e - 1 } else { i - 1 };
                let next = if i + 1 == e { s } else { i + 1 };
                let node = sim.nodes.len();
                sim.nodes.push(Node {
                    p: sim.edges[i].a,
                    t: 0.0,
                });
                let (vel, degenerate) = sim.velocity(prev, i);
                sim.verts.push(Vert {
                    l: prev,
                    r: i,
                    node,
                    t0: 0.0,
                    p0: sim.edges[i].a,
                    vel,
                    degenerate,
                    prev,
                    next,
                    alive: true,
                });
            }
            for i in s..e {
                let next = if i + 1 == e { s } else { i + 1 };
                sim.base[i] = (i, next);
                sim.segs[i].push((i, next));
            }
        }
        sim
    }

    pub(super) fn velocity(&self, l: usize, r: usize) -> (DVec2, bool) {
        let (nl, nr) = (self.edges[l].n, self.edges[r].n);
        let den = 1.0 + nl.dot(nr);
        if den < ANTIPARALLEL_DEN {
            (DVec2::ZERO, true)
        } else {
            ((nl + nr) / den, false)
        }
    }

    pub(super) fn pos(&self, v: usize, t: f64) -> DVec2 {
        let v = &self.verts[v];
        v.p0 + v.vel * (t - v.t0)
    }

    pub(super) fn alive(&self) -> Vec<usize> {
        (0..self.verts.len())
            .filter(|&i| self.verts[i].alive)
            .collect()
    }

    /// [`Sim::alive`] into `out`.
    fn alive_into(&self, out: &mut Vec<usize>) {
        out.clear();
        out.extend((0..self.verts.len()).filter(|&i| self.verts[i].alive));
    }

    pub(super) fn run(&mut self) -> Result<(), SkeletonError> {
        let budget = 40 * self.edges.len() + 100;
        for _ in 0..budget {
            let mut alive = std::mem::take(&mut self.scratch.alive);
            self.alive_into(&mut alive);
            if alive.is_empty() {
                return Ok(());
            }
            let before = self.t;
            let events = self.next_events(&alive);
            self.scratch.alive = alive;
            let (points, found) = events?;
            if self.t > before + self.eps {
                self.stale.clear();
            }
            let mut changed = false;
            for p in points {
                changed |= self.handle_point(p)?;
            }
            changed |= self.resolve_degenerate()?;
            if !changed {
                // An edge due to collapse now whose ends are farther apart than the event
                // radius (events a rounding error apart left them so): its end is brought onto
                // its start, and the point is handled again.
                for &(v, with) in &found {
                    if with != usize::MAX || !self.verts[v].alive || self.verts[v].degenerate {
                        continue;
                    }
                    let w = self.verts[v].next;
                    if w == v || !self.verts[w].alive || self.verts[w].degenerate {
                        continue;
                    }
                    let t = self.t;
                    let (pv, pw) = (self.pos(v, t), self.pos(w, t));
                    if pv.distance(pw) > 1e-6 * self.size {
                        continue;
                    }
                    let ww = &mut self.verts[w];
                    ww.p0 += pv - pw;
                    if self.handle_point(pv)? {
                        changed = true;
                        break;
                    }
                }
            }
            if !changed {
                self.stale.extend(found);
            }
        }
        Err(SkeletonError::NoConvergence { events: budget })
    }

    /// Finds the earliest event time, advances to it and returns the event points, with the
    /// events found there (see [`Sim::stale`]).
    #[allow(clippy::type_complexity)]
    pub(super) fn next_events(
        &mut self,
        alive: &[usize],
    ) -> Result<(Vec<DVec2>, Vec<(usize, usize)>), SkeletonError> {
        let t = self.t;
        let eps = self.eps;
        let mut best = f64::INFINITY;
        let mut cands: Vec<(f64, usize, usize)> = Vec::new();
        let mut pos_now = std::mem::take(&mut self.scratch.pos);
        let mut fronts = std::mem::take(&mut self.scratch.fronts);
        let is_stale = |v: usize, with: usize| self.stale.contains(&(v, with));
        pos_now.clear();
        pos_now.extend((0..self.verts.len()).map(|i| self.pos(i, t)));
        // The wavefront edges (the edge leaving each alive vertex u), gathered once: u, the
        // vertex after it, and the edge's start and inward normal.
        fronts.clear();
        fronts.extend(alive.iter().map(|&u| {
            let uu = &self.verts[u];
            let f = &self.edges[uu.r];
            (u, uu.next, f.a, f.n)
        }));
        let [mut ax, mut ay, mut nx, mut ny] = std::mem::take(&mut self.scratch.front_xy);
        let mut keep = std::mem::take(&mut self.scratch.keep);
        for c in [&mut ax, &mut ay, &mut nx, &mut ny] {
            c.clear();
        }
        for &(_, _, a, n) in &fronts {
            ax.push(a.x);
            ay.push(a.y);
            nx.push(n.x);
            ny.push(n.y);
        }
        let no_stale = self.stale.is_empty();
        // `h / r > lim(best)` (h ≥ 0, r > 0) is checked as `h > r * lim(best)` first, which
        // spares the division for most pairs: `lim` is `best + eps - t` widened by relative
        // margins of 1e-12 and two units in the last place of `best + eps`, so that whenever
        // the product says so, `t + h / r` computed in floating point exceeds `best + eps`
        // (the test below, which decides). Infinite while `best` is.
        let lim = |best: f64| {
            let b = best + eps;
            ((b - t) * (1.0 + 1e-12) + b * 4.5e-16) * (1.0 + 1e-12)
        };
        let mut best_lim = f64::INFINITY;
        for &v in alive {
            let vv = &self.verts[v];
            if vv.degenerate {
                continue;
            }
            let w = vv.next;
            // Edge event on v -> w.
            let e = &self.edges[vv.r];
            let len = (pos_now[w] - pos_now[v]).dot(e.d);
            let rate = (self.verts[w].vel - vv.vel).dot(e.d);
            if rate < -1e-12 && !is_stale(v, usize::MAX) {
                let dt = (len / -rate).max(0.0);
                if t + dt <= best + eps {
                    best = best.min(t + dt);
                    best_lim = lim(best);
                    cands.push((t + dt, v, usize::MAX));
                }
            }
            // Split events of v against every non-incident edge. First, without branches, the
            // edges v may meet before `best` as it stands now (it only comes down): the tests
            // of the loop below, on the same values.
            let (pv_now, vel) = (pos_now[v], vv.vel);
            let lim0 = best_lim;
            keep.clear();
            // Negated as the loop's tests are, so that a NaN goes on to them as it would.
            #[allow(clippy::neg_cmp_op_on_partial_ord)]
            keep.extend(ax.iter().zip(&ay).zip(nx.iter().zip(&ny)).map(
                |((&ax, &ay), (&nx, &ny))| {
                    let h = (pv_now.x - ax) * nx + (pv_now.y - ay) * ny - t;
                    let rate = vel.x * nx + vel.y * ny - 1.0;
                    !(rate >= -1e-12 || h < -eps) & !(h.max(0.0) > -rate * lim0)
                },
            ));
            for (&(u, next, fa, fnorm), &kept) in fronts.iter().zip(&keep) {
                if !kept || u == v || next == v {
                    continue;
                }
                let h = (pv_now - fa).dot(fnorm) - t;
                let rate = vel.dot(fnorm) - 1.0;
                if rate >= -1e-12 || h < -eps {
                    continue;
                }
                if !no_stale && is_stale(v, u) {
                    continue;
                }
                if h.max(0.0) > -rate * best_lim {
                    continue;
                }
                let dt = h.max(0.0) / -rate;
                let te = t + dt;
                if te > best + eps {
                    continue;
                }
                let uu = &self.verts[u];
                let f = &self.edges[uu.r];
                let pv = self.pos(v, te);
                let pa = self.pos(u, te);
                let pb = self.pos(uu.next, te);
                let s = (pv - pa).dot(f.d);
                let l = (pb - pa).dot(f.d);
                // At an end of the edge, the vertex must be moving onto the edge, not away
                // from it (two vertices born at one point and moving apart are no event).
                let vb = self.verts[uu.next].vel;
                let onto_start = s > eps || (vv.vel - uu.vel).dot(f.d) >= -1e-9;
                let onto_end = s < l - eps || (vv.vel - vb).dot(f.d) <= 1e-9;
                // A vertex already on the line at an end of the edge met that end at this
                // very time, and that point has been handled.
                let rad = 4.0 * eps;
                let stale = h <= eps && (s <= rad || s >= l - rad);
                if s >= -eps && s <= l + eps && onto_start && onto_end && !stale {
                    best = best.min(te);
                    best_lim = lim(best);
                    cands.push((te, v, u));
                }
            }
        }
        self.scratch.pos = pos_now;
        self.scratch.fronts = fronts;
        self.scratch.front_xy = [ax, ay, nx, ny];
        self.scratch.keep = keep;
        if !best.is_finite() {
            return Err(SkeletonError::Inconsistent(
                "a wavefront ring has no further event",
            ));
        }
        self.t = best.max(t);
        // Cluster the event vertices; the slowest vertex of a cluster gives its point, as its
        // position is the most precise (see `Sim::tol`).
        let cands: Vec<(f64, usize, usize)> = cands
            .into_iter()
            .filter(|&(te, ..)| te <= best + eps)
            .collect();
        let found: Vec<(usize, usize)> = cands.iter().map(|&(_, v, w)| (v, w)).collect();
        let mut cands: Vec<usize> = cands.into_iter().map(|(_, v, _)| v).collect();
        cands.sort_unstable();
        cands.dedup();
        cands.sort_by(|&a, &b| {
            let (sa, sb) = (self.verts[a].vel.length(), self.verts[b].vel.length());
            sa.total_cmp(&sb).then(a.cmp(&b))
        });
        let mut pts: Vec<DVec2> = Vec::new();
        for v in cands {
            let p = self.pos(v, self.t);
            if !pts.iter().any(|q| q.distance(p) <= self.tol(v)) {
                pts.push(p);
            }
        }
        Ok((pts, found))
    }

    /// Cluster radius: a little larger than the event tolerance to absorb rounding.
    pub(super) fn radius(&self) -> f64 {
        4.0 * self.eps
    }

    /// Distance within which vertex `v` is at an event point. Events closer than `eps` in time
    /// are simultaneous, and in that time a vertex moves `eps × speed`: a vertex between nearly
    /// antiparallel edges moves at about 2 / angle (10⁴ or more on real footprints), so its
    /// position at an event is only known to that precision.
    pub(super) fn tol(&self, v: usize) -> f64 {
        self.radius() + self.verts[v].vel.length() * self.eps
    }

    /// Handles everything at point `x` at the current time.
    pub(super) fn handle_point(&mut self, x: DVec2) -> Result<bool, SkeletonError> {
        self.handle_point_at(x, None)
    }

    /// [`Sim::handle_point`], with the node of the event given (a slid vertex's meeting node).
    /// Returns whether the wavefront changed.
    pub(super) fn handle_point_at(
        &mut self,
        x: DVec2,
        at: Option<usize>,
    ) -> Result<bool, SkeletonError> {
        let mut alive = std::mem::take(&mut self.scratch.alive);
        let mut member = std::mem::take(&mut self.scratch.member);
        let mut visited = std::mem::take(&mut self.scratch.visited);
        let r = self.handle_point_with(x, at, &mut alive, &mut member, &mut visited);
        self.scratch.alive = alive;
        self.scratch.member = member;
        self.scratch.visited = visited;
        r
    }

    /// [`Sim::handle_point_at`] with its buffers (contents rebuilt here).
    fn handle_point_with(
        &mut self,
        x: DVec2,
        at: Option<usize>,
        alive: &mut Vec<usize>,
        member: &mut Vec<bool>,
        visited: &mut Vec<bool>,
    ) -> Result<bool, SkeletonError> {
        let t = self.t;
        let rad = self.radius();
        self.alive_into(alive);
        let alive = &*alive;
        // Vertices this close take part (see [`RADIUS_REL`]): two reflex corners meeting
        // head-on pass a little apart once the footprint is rounded.
        let reach = RADIUS_REL * self.size;
        member.clear();
        member.resize(self.verts.len(), false);
        for &v in alive {
            member[v] = self.pos(v, t).distance(x) <= self.tol(v).max(reach);
        }
        let member = &*member;
        let members: Vec<usize> = alive.iter().copied().filter(|&v| member[v]).collect();
        if members.is_empty() {
            return Ok(false);
        }
        let mut passes: Vec<Pass> = Vec::new();
        visited.clear();
        visited.resize(self.verts.len(), false);
        for &m in &members {
            if member[self.verts[m].prev] {
                continue;
            }
            let mut last = m;
            visited[m] = true;
            let mut guard = 0;
            while member[self.verts[last].next] {
                last = self.verts[last].next;
                visited[last] = true;
                guard += 1;
                if guard > self.verts.len() {
                    return Err(SkeletonError::Inconsistent("wavefront ring is not a cycle"));
                }
            }
            passes.push(Pass {
                entry: self.verts[m].prev,
                exit: self.verts[last].next,
                in_edge: self.verts[m].l,
                out_edge: self.verts[last].r,
                run: Some((m, last)),
            });
        }
        // Rings that lie entirely at the point vanish there.
        let vanished: Vec<usize> = members.iter().copied().filter(|&m| !visited[m]).collect();
        for &u in alive {
            let w = self.verts[u].next;
            if member[u] || member[w] {
                continue;
            }
            if point_seg_dist(x, self.pos(u, t), self.pos(w, t)) <= rad.max(reach) {
                let e = self.verts[u].r;
                passes.push(Pass {
                    entry: u,
                    exit: w,
                    in_edge: e,
                    out_edge: e,
                    run: None,
                });
            }
        }
        let trivial = vanished.is_empty()
            && passes
                .iter()
                .all(|p| matches!(p.run, Some((a, b)) if a == b))
            && passes.len() <= 1;
        if trivial {
            return Ok(false);
        }
        let pairs = self.match_passes(&passes)?;
        let changed = !vanished.is_empty()
            || pairs
                .iter()
                .enumerate()
                .any(|(i, &j)| i != j || matches!(passes[i].run, Some((a, b)) if a != b));
        if !changed {
            return Ok(false);
        }
        // The node: reuse one already at this place and time, unless the caller gives it.
        let node = match at {
            Some(n) => n,
            None => self.node_at(x, &members),
        };
        // Retire the vertices of runs that change and of vanished rings.
        for (i, p) in passes.iter().enumerate() {
            if let Some((a, b)) = p.run {
                if pairs[i] == i && a == b {
                    continue;
                }
                let mut v = a;
                loop {
                    self.retire(v, node);
                    if v == b {
                        break;
                    }
                    v = self.verts[v].next;
                }
            }
        }
        for &v in &vanished {
            self.retire(v, node);
        }
        // Reconnect.
        let mut touched = Vec::new();
        for (i, &j) in pairs.iter().enumerate() {
            if i == j && passes[i].run.is_none_or(|(a, b)| a == b) {
                continue;
            }
            let (pi, pj) = (passes[i], passes[j]);
            if pi.in_edge == pj.out_edge {
                self.verts[pi.entry].next = pj.exit;
                self.verts[pj.exit].prev = pi.entry;
                touched.push(pi.entry);
            } else {
                let (vel, degenerate) = self.velocity(pi.in_edge, pj.out_edge);
                let id = self.verts.len();
                self.verts.push(Vert {
                    l: pi.in_edge,
                    r: pj.out_edge,
                    node,
                    t0: self.nodes[node].t,
                    p0: self.nodes[node].p,
                    vel,
                    degenerate,
                    prev: pi.entry,
                    next: pj.exit,
                    alive: true,
                });
                self.verts[pi.entry].next = id;
                self.verts[pj.exit].prev = id;
                touched.push(id);
            }
        }
        for v in touched {
            if self.verts[v].alive {
                self.check_ring(v)?;
            }
        }
        Ok(true)
    }

    /// A node at `x` at the current time, reusing a member's start node when it is there.
    pub(super) fn node_at(&mut self, x: DVec2, members: &[usize]) -> usize {
        let rad = self.radius();
        for &m in members {
            let n = self.nodes[self.verts[m].node];
            if (n.t - self.t).abs() <= self.eps && n.p.distance(x) <= rad {
                return self.verts[m].node;
            }
        }
        self.nodes.push(Node { p: x, t: self.t });
        self.nodes.len() - 1
    }

    /// Ends vertex `v` at `node`, recording its trace for the faces of its two edges.
    pub(super) fn retire(&mut self, v: usize, node: usize) {
        let vv = &mut self.verts[v];
        vv.alive = false;
        if vv.node != node {
            self.segs[vv.l].push((vv.node, node));
            self.segs[vv.r].push((node, vv.node));
        }
    }

    /// Pairs each pass's incoming edge with the outgoing edge nearest clockwise from it.
    /// Returns, for each pass `i`, the pass whose outgoing edge continues it.
    pub(super) fn match_passes(&self, passes: &[Pass]) -> Result<Vec<usize>, SkeletonError> {
        // (angle, is_in, pass)
        let mut rays: Vec<(f64, bool, usize)> = Vec::with_capacity(2 * passes.len());
        for (i, p) in passes.iter().enumerate() {
            let din = -self.edges[p.in_edge].d;
            let dout = self.edges[p.out_edge].d;
            rays.push((din.y.atan2(din.x), true, i));
            rays.push((dout.y.atan2(dout.x), false, i));
        }
        rays.sort_by(|a, b| a.0.total_cmp(&b.0));
        // Start after the largest angular gap so that groups of equal angles are not cut.
        let k = rays.len();
        let mut cut = 0;
        let mut gap = -1.0;
        for i in 0..k {
            let g = if i + 1 < k {
                rays[i + 1].0 - rays[i].0
            } else {
                rays[0].0 + std::f64::consts::TAU - rays[i].0
            };
            if g > gap {
                gap = g;
                cut = (i + 1) % k;
            }
        }
        rays.rotate_left(cut);
        // Group equal directions; within a group outgoing rays come first (counter-clockwise),
        // so an incoming edge pairs with an antiparallel outgoing one (two wavefronts meeting).
        let mut group = vec![0usize; k];
        for i in 1..k {
            let mut d = rays[i].0 - rays[i - 1].0;
            if d < 0.0 {
                d += std::f64::consts::TAU;
            }
            group[i] = group[i - 1] + usize::from(d > ANGLE_TOL);
        }
        let mut order: Vec<usize> = (0..k).collect();
        order.sort_by_key(|&i| (group[i], rays[i].1));
        let seq: Vec<(bool, usize)> = order.iter().map(|&i| (rays[i].1, rays[i].2)).collect();
        // Parenthesis matching (out opens, in closes), from a rotation with no deficit.
        let mut bal = 0i64;
        let mut min_bal = 0i64;
        let mut start = 0;
        for (i, &(is_in, _)) in seq.iter().enumerate() {
            bal += if is_in { -1 } else { 1 };
            if bal < min_bal {
                min_bal = bal;
                start = i + 1;
            }
        }
        if bal != 0 {
            return Err(SkeletonError::Inconsistent("unbalanced event point"));
        }
        let mut pairs = vec![usize::MAX; passes.len()];
        let mut stack = Vec::new();
        for s in 0..k {
            let (is_in, p) = seq[(start + s) % k];
            if is_in {
                let o = stack
                    .pop()
                    .ok_or(SkeletonError::Inconsistent("unmatched edge"))?;
                pairs[p] = o;
            } else {
                stack.push(p);
            }
        }
        if pairs.contains(&usize::MAX) {
            return Err(SkeletonError::Inconsistent("unmatched edge"));
        }
        Ok(pairs)
    }

    /// Retires the ring through `v` if it has collapsed (fewer than 3 vertices or no area):
    /// its edges become skeleton edges.
    pub(super) fn check_ring(&mut self, v: usize) -> Result<(), SkeletonError> {
        let t = self.t;
        let mut ring = vec![v];
        let mut u = self.verts[v].next;
        while u != v {
            ring.push(u);
            if ring.len() > self.verts.len() {
                return Err(SkeletonError::Inconsistent("wavefront ring is not a cycle"));
            }
            u = self.verts[u].next;
        }
        let pts: Vec<DVec2> = ring.iter().map(|&u| self.pos(u, t)).collect();
        let area = ring_signed_area(&pts);
        let perim: f64 = (0..pts.len())
            .map(|i| pts[i].distance(pts[(i + 1) % pts.len()]))
            .sum();
        // Rings of holes that have not met the outer ring yet run clockwise: only the size of
        // the area tells a collapsed ring.
        if ring.len() >= 3 && area.abs() > self.radius() * perim {
            return Ok(());
        }
        // End nodes, shared between vertices at the same place.
        let rad = self.radius();
        let mut ends = Vec::with_capacity(ring.len());
        let mut fresh: Vec<usize> = Vec::new();
        for (k, &u) in ring.iter().enumerate() {
            let p = pts[k];
            let n0 = self.nodes[self.verts[u].node];
            let id = if (n0.t - t).abs() <= self.eps && n0.p.distance(p) <= rad {
                self.verts[u].node
            } else if let Some(&f) = fresh.iter().find(|&&f| self.nodes[f].p.distance(p) <= rad) {
                f
            } else {
                self.nodes.push(Node { p, t });
                fresh.push(self.nodes.len() - 1);
                self.nodes.len() - 1
            };
            ends.push(id);
        }
        for (k, &u) in ring.iter().enumerate() {
            self.retire(u, ends[k]);
        }
        for k in 0..ring.len() {
            let k1 = (k + 1) % ring.len();
            let e = self.verts[ring[k]].r;
            if self.verts[ring[k1]].l != e {
                return Err(SkeletonError::Inconsistent(
                    "wavefront edge labels disagree",
                ));
            }
            if ends[k] != ends[k1] {
                self.segs[e].push((ends[k1], ends[k]));
            }
        }
        Ok(())
    }

    /// Vertices between antiparallel edges must disappear at the time they were made (the two
    /// wavefronts annihilate along their overlap). First every point where a vertex lies on a
    /// non-incident wavefront edge or another vertex is handled; a degenerate vertex still left
    /// then slides along the common line of its two edges to the nearer of its neighbours (the
    /// end of the overlap, which a nearly antiparallel vertex reaches almost at once, moving at
    /// a speed of about 2 / angle) and that point is handled as an edge event.
    pub(super) fn resolve_degenerate(&mut self) -> Result<bool, SkeletonError> {
        let mut any = false;
        let limit = 4 * self.verts.len() + 16;
        for _ in 0..limit {
            // Nothing to do (the usual case) is found without gathering the alive vertices.
            if !self.verts.iter().any(|v| v.alive && v.degenerate) {
                return Ok(any);
            }
            let alive = self.alive();
            let Some(&v) = alive.iter().find(|&&v| self.verts[v].degenerate) else {
                return Ok(any);
            };
            let t = self.t;
            let rad = self.radius();
            let mut pts: Vec<DVec2> = Vec::new();
            for &v in &alive {
                let p = self.pos(v, t);
                for &u in &alive {
                    let w = self.verts[u].next;
                    if u == v || w == v {
                        continue;
                    }
                    if point_seg_dist(p, self.pos(u, t), self.pos(w, t)) <= rad
                        && !pts.iter().any(|q| q.distance(p) <= rad)
                    {
                        pts.push(p);
                    }
                }
            }
            let mut changed = false;
            for p in pts {
                changed |= self.handle_point(p)?;
            }
            if !changed {
                self.slide(v)?;
            }
            any = true;
        }
        Err(SkeletonError::Inconsistent(
            "unresolved antiparallel wavefront vertex",
        ))
    }

    /// Moves degenerate vertex `v` to the neighbour it meets first along the line of its edges
    /// and handles that point (see [`Sim::resolve_degenerate`]). When the edges are not exactly
    /// antiparallel the meeting time is computed from the vertex's true (large) velocity and
    /// the node placed on the neighbour's trajectory at that time, so that the node lies on
    /// all the planes involved however far the vertex slides.
    pub(super) fn slide(&mut self, v: usize) -> Result<(), SkeletonError> {
        let t = self.t;
        let vv = self.verts[v].clone();
        let p = self.pos(v, t);
        let (nl, nr) = (self.edges[vv.l].n, self.edges[vv.r].n);
        let den = 1.0 + nl.dot(nr);
        let vel = if den > 0.0 {
            (nl + nr) / den
        } else {
            DVec2::ZERO
        };
        // Time to meet the next vertex (edge r collapses) and the previous one (edge l).
        let meet = |w: usize, d: DVec2, sign: f64| -> f64 {
            let len = sign * (self.pos(w, t) - p).dot(d);
            let rate = sign * (self.verts[w].vel - vel).dot(d);
            if rate < 0.0 {
                (len / -rate).max(0.0)
            } else {
                f64::INFINITY
            }
        };
        let tw = meet(vv.next, self.edges[vv.r].d, 1.0);
        let tu = meet(vv.prev, self.edges[vv.l].d, -1.0);
        // Both neighbours lie ahead along the right edge's direction (the ring folds back).
        let d = self.edges[vv.r].d;
        let (pu, pw) = (self.pos(vv.prev, t), self.pos(vv.next, t));
        let (w, dt) = if tw.is_finite() || tu.is_finite() {
            if tw <= tu {
                (vv.next, tw)
            } else {
                (vv.prev, tu)
            }
        } else if (pw - p).dot(d) <= (pu - p).dot(d) {
            (vv.next, 0.0)
        } else {
            (vv.prev, 0.0)
        };
        // A slide is instantaneous up to the angle: a long wait means it is no slide.
        let dt = if dt * self.verts[w].vel.length() > 1e-3 * self.size {
            0.0
        } else {
            dt
        };
        let x = self.pos(w, t);
        let target = self.pos(w, t + dt);
        let node = self.nodes.len();
        self.nodes.push(Node {
            p: target,
            t: t + dt,
        });
        self.retire(v, node);
        let id = self.verts.len();
        // The slid vertex rides on its neighbour's trajectory, so it is at the event point now.
        self.verts.push(Vert {
            node,
            t0: t + dt,
            p0: target,
            vel: self.verts[w].vel,
            alive: true,
            ..vv
        });
        self.verts[vv.prev].next = id;
        self.verts[vv.next].prev = id;
        self.handle_point_at(x, Some(node))?;
        if self.verts[id].alive {
            return Err(SkeletonError::Inconsistent(
                "unresolved antiparallel wavefront vertex",
            ));
        }
        Ok(())
    }

    /// Makes nodes closer than [`NODE_MERGE_REL`]` × size` (at most [`NODE_MERGE_MAX`]) in
    /// place and time one node: the first made of them, so that the footprint's corners
    /// (made first) are never moved. Events at one point handled apart (a slid antiparallel
    /// vertex, events a rounding error apart in time) leave such pairs, which would otherwise
    /// give faces a zero-length edge (a hip end with two apexes a micrometre apart is no
    /// triangle, so it could not become a gable) and the solid an edge shared by four faces.
    /// Corners (time 0) are neither merged nor absorb interior nodes: an edge of a millimetre
    /// keeps its face.
    pub(super) fn merge_nodes(&mut self) {
        let r = (NODE_MERGE_REL * self.size).min(NODE_MERGE_MAX);
        let n = self.nodes.len();
        let mut rep: Vec<usize> = (0..n).collect();
        let key = |nd: &Node| DVec3::new(nd.p.x, nd.p.y, nd.t);
        // Sweep in x order (ties by index, so the result does not depend on the sort).
        let mut order: Vec<usize> = (0..n).filter(|&i| self.nodes[i].t > 0.0).collect();
        order.sort_by(|&a, &b| {
            self.nodes[a]
                .p
                .x
                .total_cmp(&self.nodes[b].p.x)
                .then(a.cmp(&b))
        });
        // Union-find: every node within `r` of another joins its group; the group's smallest
        // index is its node.
        fn find(rep: &mut [usize], mut i: usize) -> usize {
            while rep[i] != i {
                rep[i] = rep[rep[i]];
                i = rep[i];
            }
            i
        }
        for (k, &i) in order.iter().enumerate() {
            for &j in &order[k + 1..] {
                if self.nodes[j].p.x - self.nodes[i].p.x > r {
                    break;
                }
                if key(&self.nodes[i]).distance(key(&self.nodes[j])) <= r {
                    let (a, b) = (find(&mut rep, i), find(&mut rep, j));
                    if a != b {
                        rep[a.max(b)] = a.min(b);
                    }
                }
            }
        }
        let rep: Vec<usize> = (0..n).map(|i| find(&mut rep, i)).collect();
        for segs in &mut self.segs {
            for s in segs.iter_mut() {
                *s = (rep[s.0], rep[s.1]);
            }
        }
    }

    /// Chains each edge's boundary segments into its face and (with `split`) splits faces of
    /// merged edges back into one face per input edge.
    /// With `split` false, a merged edge keeps one face.
    pub(super) fn faces(&self, split: bool) -> Result<Vec<SkeletonFace>, SkeletonError> {
        let mut out = Vec::new();
        for (e, edge) in self.edges.iter().enumerate() {
            let ring = self.chain(e)?;
            let poly: Vec<DVec3> = ring
                .iter()
                .map(|&n| {
                    let nd = self.nodes[n];
                    DVec3::new(nd.p.x, nd.p.y, nd.t)
                })
                .collect();
            if edge.inputs.len() == 1 || !split {
                out.push(SkeletonFace {
                    edge: (edge.ring, edge.inputs[0].0),
                    polygon: poly,
                });
                continue;
            }
            // Cut the (edge-monotone) face into slabs across the edge, one per input edge.
            for (k, &(input, s0)) in edge.inputs.iter().enumerate() {
                let lo = if k == 0 { f64::NEG_INFINITY } else { s0 };
                let hi = edge.inputs.get(k + 1).map_or(f64::INFINITY, |x| x.1);
                if hi - lo <= DUPLICATE_REL * self.size {
                    continue;
                }
                let mut piece = clip(&poly, edge.a, edge.d, lo, false);
                piece = clip(&piece, edge.a, edge.d, hi, true);
                ring::dedup_within(&mut piece, self.radius());
                // Start at the base edge: the first vertex at time 0 followed by another.
                let m = piece.len();
                if m < 3 {
                    return Err(SkeletonError::Inconsistent("empty face piece"));
                }
                let tol = self.radius();
                let st = (0..m).find(|&i| piece[i].z <= tol && piece[(i + 1) % m].z <= tol);
                let st = st.ok_or(SkeletonError::Inconsistent("face piece lost its base"))?;
                piece.rotate_left(st);
                out.push(SkeletonFace {
                    edge: (edge.ring, input),
                    polygon: piece,
                });
            }
        }
        out.sort_by_key(|f| f.edge);
        Ok(out)
    }

    /// The cycle of nodes bounding edge `e`'s face, starting with the base edge.
    pub(super) fn chain(&self, e: usize) -> Result<Vec<usize>, SkeletonError> {
        let mut segs: Vec<(usize, usize)> = self.segs[e]
            .iter()
            .copied()
            .filter(|s| s.0 != s.1)
            .collect();
        segs.sort_unstable();
        segs.dedup();
        // Cancel segments traversed both ways (slits of zero width).
        let mut keep = vec![true; segs.len()];
        for i in 0..segs.len() {
            if let Ok(j) = segs.binary_search(&(segs[i].1, segs[i].0)) {
                keep[i] = false;
                keep[j] = false;
            }
        }
        let segs: Vec<(usize, usize)> = segs
            .iter()
            .zip(&keep)
            .filter(|(_, k)| **k)
            .map(|(s, _)| *s)
            .collect();
        let mut used = vec![false; segs.len()];
        let (start, second) = self.base[e];
        let mut ring = vec![start];
        let mut cur = start;
        let mut prev_dir = self.nodes[second].p - self.nodes[start].p;
        let mut first = true;
        loop {
            // Outgoing candidates from `cur`.
            let cands: Vec<usize> = (0..segs.len())
                .filter(|&i| !used[i] && segs[i].0 == cur)
                .collect();
            let pick = if first {
                cands.iter().copied().find(|&i| segs[i].1 == second)
            } else if cands.len() <= 1 {
                cands.first().copied()
            } else {
                // Face touching itself: take the rightmost turn.
                cands.iter().copied().max_by(|&i, &j| {
                    let ti = turn(prev_dir, self.nodes[segs[i].1].p - self.nodes[cur].p);
                    let tj = turn(prev_dir, self.nodes[segs[j].1].p - self.nodes[cur].p);
                    tj.total_cmp(&ti)
                })
            };
            let i = pick.ok_or(SkeletonError::Inconsistent("face boundary does not close"))?;
            first = false;
            used[i] = true;
            prev_dir = self.nodes[segs[i].1].p - self.nodes[cur].p;
            cur = segs[i].1;
            if cur == start {
                break;
            }
            ring.push(cur);
            if ring.len() > segs.len() + 1 {
                return Err(SkeletonError::Inconsistent("face boundary does not close"));
            }
        }
        if used.iter().any(|u| !u) {
            return Err(SkeletonError::Inconsistent(
                "face boundary has extra pieces",
            ));
        }
        if ring.len() < 3 {
            return Err(SkeletonError::Inconsistent(
                "face with fewer than 3 vertices",
            ));
        }
        Ok(ring)
    }
}

/// Signed turn angle from direction `a` to direction `b` (counter-clockwise positive).
pub(super) fn turn(a: DVec2, b: DVec2) -> f64 {
    a.perp_dot(b).atan2(a.dot(b))
}

/// Sutherland–Hodgman clip of a ring against `s >= c` (or `s <= c` when `upper`), where `s` is
/// the ground position along `d` measured from `a`. `z` is interpolated linearly.
pub(super) fn clip(poly: &[DVec3], a: DVec2, d: DVec2, c: f64, upper: bool) -> Vec<DVec3> {
    if !c.is_finite() {
        return poly.to_vec();
    }
    let f = |p: DVec3| {
        let s = (p.truncate() - a).dot(d) - c;
        if upper {
            -s
        } else {
            s
        }
    };
    let n = poly.len();
    let mut out = Vec::with_capacity(n + 2);
    for i in 0..n {
        let (p, q) = (poly[i], poly[(i + 1) % n]);
        let (fp, fq) = (f(p), f(q));
        if fp >= 0.0 {
            out.push(p);
        }
        if (fp >= 0.0) != (fq >= 0.0) {
            let t = fp / (fp - fq);
            out.push(p + (q - p) * t);
        }
    }
    out
}
