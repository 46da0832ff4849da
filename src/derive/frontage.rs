//! What a LOD3 facade may have where it stands, decided for a whole building on the openings the
//! grammar found ([`Facades`], in wall coordinates) before [`facade::apply`] cuts them:
//!
//! 1. **Curved and many-edged walls.** A run of consecutive footprint edges each shorter than a
//!    bay, turning little at each corner (a round tower, a curved street front), is laid out as
//!    one facade: windows at bay spacing along the run, each cut into the real walls it spans
//!    (one pane per facet, a mullion at each corner). The grammar gives such edges none: each
//!    is narrower than a bay. Facades a SELEX program laid out keep what it put.
//! 2. **Party walls.** Where a wall touches or faces another part of the building or another
//!    building closer than [`PARTY_REACH`], up to that one's top, no window, door or balcony
//!    is kept ([`party_spans`]); above the neighbour's roof the wall is a facade again.
//! 3. **One main entrance.** Doors the rules made are kept only on balconies. The building gets
//!    one entrance on the ground storey of a part standing on the ground that is no structure
//!    (or, when it has none, at the base of a tower: [`towers_take_entrance`]), on the wall facing
//!    its street ([`crate::prepare::Lot::front`]): among the walls free of neighbours for the
//!    door's height, those within 5° of the street side first (the street-facing edge and
//!    those parallel to it), then 25°, then 60°, then any facing it; the one the rules put a
//!    door on; the longest free stretch; centred on the window of the bay nearest the stretch's middle,
//!    which it replaces. Its size is the style's ([`Style::door_width`], `door_height`: 0.8 to
//!    2.5 m by 2.0 to 2.6 m), narrowed to its stretch, never below 0.8 m, always under the
//!    storey's lintel. Other doors become windows of their storey where one fits
//!    ([`FacadeCounts`] says how many of each). Facades a SELEX program laid out
//!    (`derive::facade::Facades::programmed`) keep the doors it put on the ground storey, each an entrance
//!    (sized like any door); only a building whose program put none gets one placed.
//! 4. **On a slope** (`--dem` at LOD3, [`slope`]): no opening or balcony below the terrain,
//!    and the entrance where its sill stands at the terrain, on whichever storey that is.

use glam::DVec2;

use crate::derive::facade::{self, Facades, FoundBalcony, FoundOpening, JAMB_SNAP};
use crate::derive::surroundings::{
    party_spans, share, strip_spans, Neighbour, Span, Surroundings, PARTY_REACH,
};
use crate::kb::{compile, defaults, Style, WindowHeight};
use crate::model::{
    FacadeCounts, OpeningKind, Part, SourceId, Structure, LINTEL, OPENING_MARGIN, RAILING_HEIGHT,
};

pub(crate) mod slope;

pub(crate) use slope::Slope;

/// A part whose base is this close to the ground (metres) stands on it.
pub(crate) const GROUND: f64 = 0.1;
/// The narrowest door drawn (metres, after the jambs' snap to the grid).
pub(crate) const DOOR_MIN_WIDTH: f64 = defaults::DOOR_WIDTH_RANGE.0;
/// The lowest door drawn (metres).
pub(crate) const DOOR_MIN_HEIGHT: f64 = defaults::DOOR_HEIGHT_RANGE.0;
/// The widest door drawn (metres).
pub(crate) const DOOR_MAX_WIDTH: f64 = defaults::DOOR_WIDTH_RANGE.1;
/// The tallest door drawn (metres).
pub(crate) const DOOR_MAX_HEIGHT: f64 = defaults::DOOR_HEIGHT_RANGE.1;
/// The most a footprint edge of a run may turn at its corner (degrees).
const RUN_MAX_TURN_DEG: f64 = 35.0;
/// The narrowest window pane cut on a facet of a run (metres).
const RUN_MIN_PANE: f64 = 0.15;

/// One part of the building with the openings found on it, before [`facade::apply`].
pub(crate) struct Draft<'a> {
    /// The part with one wall per footprint edge (as `massing::build_part` makes it).
    pub part: &'a Part,
    /// The openings, balconies and levels its rules made.
    pub facades: &'a mut Facades,
    /// Its style: window and door sizes.
    pub style: &'a Style,
    /// The structure the part is (issue 45): no openings, a tower's on its top storey only,
    /// never the entrance ([`structure_gate`]).
    pub structure: Option<Structure>,
}

impl Draft<'_> {
    /// Whether the building's entrance may be on this part: a part on the ground that is no
    /// structure, or with `towers` a tower on the ground (its base door: see
    /// [`towers_take_entrance`]).
    pub(crate) fn takes_entrance(&self, towers: bool) -> bool {
        self.part.base_z <= GROUND
            && match self.structure {
                None => true,
                Some(Structure::Tower) => towers,
                Some(_) => false,
            }
    }
}

/// Whether a tower of `drafts` may take the building's entrance: when no part on the ground
/// is a house (a lighthouse, an observation tower, a church's tower mapped on its own: the
/// door at its base). A church whose nave stands on the ground keeps its entrance there.
pub(crate) fn towers_take_entrance(drafts: &[Draft<'_>]) -> bool {
    !drafts.iter().any(|d| d.takes_entrance(false))
}

/// What [`arrange`] decided, besides the changes to the drafts' openings.
#[derive(Debug, Default)]
pub struct Arrangement {
    /// Per draft, per footprint edge: the stretches in front of a neighbour.
    pub spans: Vec<Vec<Vec<Span>>>,
    /// The draft holding the main entrance and the outward normal of its wall.
    pub entrance: Option<(usize, DVec2)>,
    /// What was left out, made or placed.
    pub counts: FacadeCounts,
    /// Why a building standing on the ground got no entrance.
    pub note: Option<String>,
    /// What the terrain changed ([`slope`]): openings left out below it, an entrance above it.
    pub slope_notes: Vec<String>,
}

/// Applies the rules of the module docs to the drafts of one building (`owner`, standing on
/// `ground`: the drafts are on z = 0, `around` at its neighbours' own grounds), whose street
/// side is `front`, among `around`, on the terrain `slope` when it has one (`--dem`).
/// `windows_from_style`: a part whose rules made no window at all still gets windows on its
/// runs, from the style (the knowledge base's rules; a ruleset file that draws no windows is
/// obeyed).
pub(crate) fn arrange(
    drafts: &mut [Draft<'_>],
    (owner, ground): (SourceId, f64),
    front: Option<DVec2>,
    around: &Surroundings,
    windows_from_style: bool,
    slope: Option<Slope<'_>>,
) -> Arrangement {
    let mut out = Arrangement::default();
    // Every part of the building as a neighbour of the others, indexed by their bounds (a
    // part whose bounds do not meet the strip along a wall makes no span on it): a building
    // of 10,000 parts asks each about its neighbours, not about every part.
    let own = Surroundings::new(
        drafts
            .iter()
            .map(|d| Neighbour::of_part(owner, d.part))
            .collect(),
    );
    for (p, d) in drafts.iter().enumerate() {
        let (lo, hi) = d.part.footprint.bounds();
        let m = DVec2::splat(PARTY_REACH + 0.1);
        let others = around.near(owner, lo - m, hi + m);
        let mine = own.indices_near(lo - m, hi + m);
        let spans = d
            .part
            .walls
            .iter()
            .map(|w| {
                let mut s = Vec::new();
                for &q in &mine {
                    if q != p {
                        party_spans(w.start, w.end, own.part(q), &mut s);
                    }
                }
                let first = s.len();
                for n in &others {
                    party_spans(w.start, w.end, n, &mut s);
                }
                // The neighbours' heights seen from this building's ground.
                if ground != 0.0 {
                    for span in &mut s[first..] {
                        span.z0 -= ground;
                        span.z1 -= ground;
                    }
                }
                s
            })
            .collect();
        out.spans.push(spans);
    }
    for d in drafts.iter_mut() {
        out.counts.run_windows += windows_on_runs(d, windows_from_style);
    }
    structure_gate(drafts);
    for (p, d) in drafts.iter_mut().enumerate() {
        for (k, spans) in out.spans[p].iter().enumerate() {
            let ops = &mut d.facades.openings[k];
            let before = ops.len();
            ops.retain(|o| !spans.iter().any(|s| s.meets(o.u0, o.u1, o.z0, o.z1)));
            out.counts.openings_on_party_walls += before - ops.len();
            let bal = &mut d.facades.balconies[k];
            let before = bal.len();
            bal.retain(|b| {
                !spans
                    .iter()
                    .any(|s| s.meets(b.u0, b.u1, b.z0, b.z0 + RAILING_HEIGHT))
            });
            out.counts.balconies_on_party_walls += before - bal.len();
        }
    }
    out.counts.balconies_clipped += clip_balconies(drafts, (owner, ground), &own, around);
    let wanted = doors_to_windows(drafts, &out.spans, &mut out.counts);
    if let Some(s) = slope {
        let buried = slope::drop_buried(drafts, s);
        if buried > 0 {
            out.slope_notes.push(format!(
                "{buried} opening(s) or balcony(ies) below the terrain left out"
            ));
        }
    }
    if !programmed_entrances(drafts, &mut out) {
        match slope {
            Some(s) => slope::entrance(drafts, front, &wanted, &mut out, s),
            None => entrance(drafts, front, &wanted, &mut out),
        }
    }
    out
}

/// What a structure keeps of the openings its rules found (issue 45, `model::Structure`):
/// nothing, or for a tower the windows of its top storey, and only when that storey is in the
/// upper half of the building (a belfry, a lantern, a viewing platform; a tower's shaft
/// under its platform keeps none lower down). No balcony, no door (a tower's base door is the
/// entrance, placed afterwards: [`towers_take_entrance`]).
fn structure_gate(drafts: &mut [Draft<'_>]) {
    let top = drafts
        .iter()
        .map(|d| d.part.top_z)
        .fold(f64::NEG_INFINITY, f64::max);
    for d in drafts.iter_mut() {
        let Some(class) = d.structure else {
            continue;
        };
        let storeys = facade::storeys(d.part, d.facades);
        let keep = storeys
            .last()
            .copied()
            .filter(|&(lo, _)| class.keeps_top_openings() && lo >= 0.5 * top);
        for ops in &mut d.facades.openings {
            ops.retain(|o| {
                o.kind == OpeningKind::Window
                    && keep.is_some_and(|(lo, hi)| {
                        let mid = 0.5 * (o.z0 + o.z1);
                        mid >= lo && mid < hi
                    })
            });
        }
        for b in &mut d.facades.balconies {
            b.clear();
        }
    }
}

/// How far out (metres) a balcony's slab must be free of every footprint: its depth and a
/// little more.
const BALCONY_REACH: f64 = facade::BALCONY_DEPTH + 0.05;
/// The narrowest balcony kept after clipping (metres): room for a balcony door and its margins.
const BALCONY_MIN_WIDTH: f64 = DOOR_MIN_WIDTH + 2.0 * OPENING_MARGIN;

/// Narrows each balcony of `drafts` (building `owner` on `ground`) to the longest stretch of
/// it whose slab, [`BALCONY_REACH`] out, meets no footprint over the balcony's height: not a
/// neighbour's (`around`), not another part's, not its own part's (a re-entrant corner, a
/// narrow court; `own` holds the building's parts in draft order); one narrower than
/// [`BALCONY_MIN_WIDTH`] is left out (issue 45). Its door, no longer over a balcony, then
/// becomes a window ([`doors_to_windows`]). How many were narrowed or left out.
fn clip_balconies(
    drafts: &mut [Draft<'_>],
    (owner, ground): (SourceId, f64),
    own: &Surroundings,
    around: &Surroundings,
) -> usize {
    let mut clipped = 0;
    for d in drafts.iter_mut() {
        let (lo, hi) = d.part.footprint.bounds();
        let m = DVec2::splat(BALCONY_REACH + 0.1);
        let others = around.near(owner, lo - m, hi + m);
        let mine = own.indices_near(lo - m, hi + m);
        for (k, w) in d.part.walls.iter().enumerate() {
            let Some(bal) = d.facades.balconies.get_mut(k).filter(|b| !b.is_empty()) else {
                continue;
            };
            let mut s = Vec::new();
            for &q in &mine {
                // The part itself too: its own wings in front of the wall.
                strip_spans(w.start, w.end, own.part(q), BALCONY_REACH, &mut s);
            }
            let first = s.len();
            for n in &others {
                strip_spans(w.start, w.end, n, BALCONY_REACH, &mut s);
            }
            for span in &mut s[first..] {
                span.z0 -= ground;
                span.z1 -= ground;
            }
            bal.retain_mut(|b| {
                let blocked: Vec<(f64, f64)> = s
                    .iter()
                    .filter(|sp| sp.meets(b.u0, b.u1, b.z0, b.z0 + RAILING_HEIGHT))
                    .map(|sp| (sp.u0 - OPENING_MARGIN, sp.u1 + OPENING_MARGIN))
                    .collect();
                if blocked.is_empty() {
                    return true;
                }
                clipped += 1;
                match longest_free(b.u0, b.u1, blocked) {
                    Some((u0, u1)) if u1 - u0 >= BALCONY_MIN_WIDTH => {
                        (b.u0, b.u1) = (u0, u1);
                        true
                    }
                    _ => false,
                }
            });
        }
    }
    clipped
}

/// How squarely a wall of outward normal `normal` faces the street side `front`: 0 within 5°
/// (or without a street), 1 within 25°, 2 within 60°, 3 facing it at all, 4 facing away.
fn tier(normal: DVec2, front: Option<DVec2>) -> u8 {
    match front {
        None => 0,
        Some(f) => {
            let c = normal.dot(f);
            if c >= 5f64.to_radians().cos() {
                0
            } else if c >= 25f64.to_radians().cos() {
                1
            } else if c >= 0.5 {
                2
            } else if c > 0.0 {
                3
            } else {
                4
            }
        }
    }
}

/// Puts the main entrance `door` among the openings `ops` of its wall: whatever it covers,
/// with the margin [`facade::apply`] keeps between openings, gives way; counted.
fn put_entrance(
    ops: &mut Vec<FoundOpening>,
    door: FoundOpening,
    wanted: &[Option<(usize, f64, Option<crate::color::Color>)>],
    out: &mut Arrangement,
) {
    let m = 2.0 * OPENING_MARGIN;
    ops.retain(|o| {
        o.u1 + m <= door.u0 || door.u1 + m <= o.u0 || o.z0 >= door.z1 + m || o.z1 + m <= door.z0
    });
    ops.push(door);
    ops.sort_by(|a, b| a.z0.total_cmp(&b.z0).then(a.u0.total_cmp(&b.u0)));
    out.counts.entrances += 1;
    // The door replaces the rules' own entrance, which was counted as extra.
    if wanted.iter().any(Option::is_some) {
        out.counts.extra_doors -= 1;
    }
}

/// The storey (floor, next floor) of `storeys` holding the middle of `o`.
fn in_storey(storeys: &[(f64, f64)], o: &FoundOpening) -> Option<(f64, f64)> {
    let mid = 0.5 * (o.z0 + o.z1);
    storeys.iter().copied().find(|&(a, b)| mid >= a && mid < b)
}

/// The doors a SELEX program put on the ground storey of a part standing on the ground (kept
/// by [`doors_to_windows`], sized like any door): the building's entrances, counted in
/// [`FacadeCounts::entrances`]; the first is the one [`Arrangement::entrance`] names. `false`
/// when there is none, and [`entrance`] places one.
fn programmed_entrances(drafts: &[Draft<'_>], out: &mut Arrangement) -> bool {
    let mut first = None;
    for (p, d) in drafts.iter().enumerate() {
        if !d.facades.programmed || !d.takes_entrance(false) {
            continue;
        }
        let storeys = facade::storeys(d.part, d.facades);
        let ground = storeys.first().copied();
        for (k, ops) in d.facades.openings.iter().enumerate() {
            for o in ops {
                if o.kind != OpeningKind::Door
                    || on_balcony(o, &d.facades.balconies[k])
                    || in_storey(&storeys, o) != ground
                {
                    continue;
                }
                out.counts.entrances += 1;
                if first.is_none() {
                    if let Some(w) = d.part.walls.get(k).filter(|w| w.length() > 0.0) {
                        let dir = (w.end - w.start) / w.length();
                        first = Some((p, DVec2::new(dir.y, -dir.x)));
                    }
                }
            }
        }
    }
    out.entrance = out.entrance.or(first);
    first.is_some()
}

/// The wall area and the party-wall area of a part after [`facade::apply`] (its walls cut per
/// storey), with `spans` per footprint edge; sets each wall's [`crate::model::Wall::party`].
pub(crate) fn mark_party_walls(part: &mut Part, spans: &[Vec<Span>], counts: &mut FacadeCounts) {
    let edges = spans.len();
    if edges == 0 || part.walls.len() % edges != 0 {
        return;
    }
    for (i, w) in part.walls.iter_mut().enumerate() {
        let len = w.length();
        let s = share(&spans[i % edges], len, w.base_z, w.top_z);
        w.party = s;
        let area = len * (w.top_z - w.base_z).max(0.0);
        counts.wall_area += area;
        counts.party_wall_area += s * area;
    }
}

/// A window's place in its storey: sill and head above the floor, width (metres), and looks.
#[derive(Clone, Debug)]
struct Template {
    sill: f64,
    height: f64,
    width: f64,
    like: FoundOpening,
}

/// The window of storey `(lo, hi)` of a draft: one the rules made on that storey, else one of
/// another storey scaled to this one's height, else (when `from_style`) the style's.
fn template(d: &Draft<'_>, lo: f64, hi: f64, from_style: bool) -> Option<Template> {
    let storeys = facade::storeys(d.part, d.facades);
    let windows = || {
        d.facades
            .openings
            .iter()
            .flatten()
            .filter(|o| o.kind == OpeningKind::Window)
    };
    let level_of = |o: &FoundOpening| {
        let mid = 0.5 * (o.z0 + o.z1);
        storeys.iter().copied().find(|&(a, b)| mid >= a && mid < b)
    };
    let found = windows()
        .find(|o| level_of(o) == Some((lo, hi)))
        .or_else(|| windows().find(|o| level_of(o).is_some()));
    if let Some(o) = found {
        let (a, b) = level_of(o)?;
        let scale = (hi - lo) / (b - a);
        return Some(Template {
            sill: (o.z0 - a) * scale,
            height: (o.z1 - o.z0) * scale,
            width: o.u1 - o.u0,
            like: o.clone(),
        });
    }
    if !from_style {
        return None;
    }
    let s = d.style;
    let height_class = match s.window_height {
        WindowHeight::Irregular => WindowHeight::Tall,
        h => h,
    };
    let rows = compile::window_rows(height_class).first()?.0;
    let h = hi - lo;
    Some(Template {
        sill: rows[0] * h,
        height: rows[1] * h,
        width: s.window_width,
        like: FoundOpening {
            kind: OpeningKind::Window,
            u0: 0.0,
            u1: 0.0,
            z0: 0.0,
            z1: 0.0,
            color: None,
            frame_color: None,
            glazed: s.window_material == "glass",
            framed: s.window_style == "framed",
            frame_size: None,
            rounding: None,
        },
    })
}

/// Lays windows along the runs of short edges of a draft (module docs, 1); returns the panes.
fn windows_on_runs(d: &mut Draft<'_>, from_style: bool) -> usize {
    let bay = compile::bay_width(d.style);
    let walls = &d.part.walls;
    // A program's facades (a bay's rounded front among them) have what it put, no more.
    if walls.len() != d.facades.openings.len() || d.facades.programmed {
        return 0;
    }
    let lens: Vec<f64> = walls.iter().map(|w| w.length()).collect();
    let dir = |k: usize| (walls[k].end - walls[k].start) / lens[k].max(1e-12);
    let max_turn = RUN_MAX_TURN_DEG.to_radians().cos();
    let mut runs: Vec<Vec<usize>> = Vec::new();
    let mut first = 0;
    for ring in d.part.footprint.rings() {
        let n = ring.len();
        let ks: Vec<usize> = (first..first + n).collect();
        first += n;
        if n < 3 {
            continue;
        }
        let short = |i: usize| lens[ks[i % n]] < bay && lens[ks[i % n]] > 1e-6;
        // Whether edge i and edge i + 1 continue one run.
        let joined = |i: usize| {
            short(i) && short(i + 1) && dir(ks[i % n]).dot(dir(ks[(i + 1) % n])) >= max_turn
        };
        match (0..n).find(|&i| !joined(i)) {
            None => runs.push(ks.clone()),
            Some(b) => {
                // Walk the ring from just after a break.
                let mut cur: Vec<usize> = Vec::new();
                for j in 1..=n {
                    let i = (b + j) % n;
                    if short(i) {
                        cur.push(ks[i]);
                    }
                    if !joined(i) && !cur.is_empty() {
                        runs.push(std::mem::take(&mut cur));
                    }
                }
            }
        }
    }
    let storeys = facade::storeys(d.part, d.facades);
    let mut panes = 0;
    for run in runs {
        let total: f64 = run.iter().map(|&k| lens[k]).sum();
        // Edges with windows of their own are laid out already (a door there is placed later).
        let has_windows = |k: usize| {
            d.facades.openings[k]
                .iter()
                .any(|o| o.kind == OpeningKind::Window)
        };
        if run.len() < 2 || total < bay || run.iter().any(|&k| has_windows(k)) {
            continue;
        }
        let n = (total / bay).floor().max(1.0);
        let spacing = total / n;
        for &(lo, hi) in &storeys {
            let Some(t) = template(d, lo, hi, from_style) else {
                continue;
            };
            let (z0, z1) = (lo + t.sill, lo + t.sill + t.height);
            for i in 0..n as usize {
                let c = (i as f64 + 0.5) * spacing;
                let (w0, w1) = (c - 0.5 * t.width, c + 0.5 * t.width);
                let mut at = 0.0;
                for &k in &run {
                    let len = lens[k];
                    let mullion = OPENING_MARGIN.max((0.1 * len).min(0.05)) + JAMB_SNAP;
                    let (u0, u1) = ((w0 - at).max(mullion), (w1 - at).min(len - mullion));
                    at += len;
                    if u1 - u0 < RUN_MIN_PANE {
                        continue;
                    }
                    d.facades.openings[k].push(FoundOpening {
                        u0,
                        u1,
                        z0,
                        z1,
                        ..t.like.clone()
                    });
                    panes += 1;
                }
            }
        }
    }
    panes
}

/// Whether door `o` on edge `k` opens onto one of the edge's balconies.
fn on_balcony(o: &FoundOpening, balconies: &[FoundBalcony]) -> bool {
    // Within the balcony's span (5 cm play), not merely touching it: a balcony cut back by
    // `clip_balconies` left doors that overlapped its old span standing over nothing.
    balconies
        .iter()
        .any(|b| b.u0 - 0.05 <= o.u0 && o.u1 <= b.u1 + 0.05 && (o.z0 - b.z0).abs() < 0.5)
}

/// Takes every door not on a balcony out of the drafts (module docs, 3), putting a window of
/// its storey in its place where one fits. Returns, per draft, where the rules wanted an
/// entrance: the first such door on a ground storey of a part on the ground, as (edge, centre
/// along it, colour).
fn doors_to_windows(
    drafts: &mut [Draft<'_>],
    spans: &[Vec<Vec<Span>>],
    counts: &mut FacadeCounts,
) -> Vec<Option<(usize, f64, Option<crate::color::Color>)>> {
    let mut wanted = Vec::with_capacity(drafts.len());
    for (p, d) in drafts.iter_mut().enumerate() {
        let storeys = facade::storeys(d.part, d.facades);
        let ground_storey = storeys.first().copied();
        let on_ground = d.part.base_z <= GROUND;
        let mut want = None;
        #[allow(clippy::needless_range_loop)] // k indexes openings, balconies, walls and spans
        for k in 0..d.facades.openings.len() {
            // A program's doors on the ground storey are entrances where it put them.
            let programmed = d.facades.programmed && on_ground;
            let (doors, kept): (Vec<FoundOpening>, Vec<FoundOpening>) =
                std::mem::take(&mut d.facades.openings[k])
                    .into_iter()
                    .partition(|o| {
                        o.kind == OpeningKind::Door
                            && !on_balcony(o, &d.facades.balconies[k])
                            && !(programmed && in_storey(&storeys, o) == ground_storey)
                    });
            d.facades.openings[k] = kept;
            // Balcony doors at a door's size: at most 2.5 by 2.6 m, dropped below 0.8 by 2.0 m.
            let before = d.facades.openings[k].len();
            d.facades.openings[k].retain_mut(|o| {
                if o.kind != OpeningKind::Door {
                    return true;
                }
                let Some(&(lo, hi)) = storeys.iter().find(|&&(a, b)| {
                    let mid = 0.5 * (o.z0 + o.z1);
                    mid >= a && mid < b
                }) else {
                    return false;
                };
                let z0 = o.z0.max(lo + OPENING_MARGIN);
                o.z1 = o.z1.min(hi - LINTEL).min(z0 + DOOR_MAX_HEIGHT);
                let c = 0.5 * (o.u0 + o.u1);
                let w = (o.u1 - o.u0).min(DOOR_MAX_WIDTH);
                (o.u0, o.u1) = (c - 0.5 * w, c + 0.5 * w);
                w >= DOOR_MIN_WIDTH + 2.0 * JAMB_SNAP && o.z1 - z0 >= DOOR_MIN_HEIGHT
            });
            counts.doors_too_small += before - d.facades.openings[k].len();
            for o in doors {
                let mid = 0.5 * (o.z0 + o.z1);
                let storey = storeys.iter().copied().find(|&(a, b)| mid >= a && mid < b);
                let at_ground = on_ground && storey.is_some() && storey == ground_storey;
                if at_ground {
                    counts.extra_doors += 1;
                    if want.is_none() {
                        want = Some((k, 0.5 * (o.u0 + o.u1), o.color));
                    }
                } else {
                    counts.doors_off_ground += 1;
                }
                let Some((lo, hi)) = storey else {
                    continue;
                };
                let Some(t) = template(d, lo, hi, false) else {
                    continue;
                };
                let c = 0.5 * (o.u0 + o.u1);
                let w = FoundOpening {
                    u0: c - 0.5 * t.width,
                    u1: c + 0.5 * t.width,
                    z0: lo + t.sill,
                    z1: lo + t.sill + t.height,
                    ..t.like.clone()
                };
                let clear = d.facades.openings[k].iter().all(|q| {
                    w.u1 + OPENING_MARGIN <= q.u0
                        || q.u1 + OPENING_MARGIN <= w.u0
                        || w.z1 + OPENING_MARGIN <= q.z0
                        || q.z1 + OPENING_MARGIN <= w.z0
                });
                let party = spans[p][k].iter().any(|s| s.meets(w.u0, w.u1, w.z0, w.z1));
                let inside =
                    w.u0 >= OPENING_MARGIN && w.u1 <= d.part.walls[k].length() - OPENING_MARGIN;
                if clear && inside && !party {
                    d.facades.openings[k].push(w);
                }
            }
        }
        wanted.push(want);
    }
    wanted
}

/// Places the main entrance (module docs, 3).
fn entrance(
    drafts: &mut [Draft<'_>],
    front: Option<DVec2>,
    wanted: &[Option<(usize, f64, Option<crate::color::Color>)>],
    out: &mut Arrangement,
) {
    struct Choice {
        key: (u8, bool, i64),
        p: usize,
        k: usize,
        free: (f64, f64),
        height: f64,
        normal: DVec2,
    }
    let mut best: Option<Choice> = None;
    let mut grounded = false;
    let mut lowest_storey = f64::INFINITY;
    let towers = towers_take_entrance(drafts);
    for (p, d) in drafts.iter().enumerate() {
        if !d.takes_entrance(towers) {
            continue;
        }
        grounded = true;
        let Some(&(lo, hi)) = facade::storeys(d.part, d.facades).first() else {
            continue;
        };
        lowest_storey = lowest_storey.min(hi - lo);
        // Drawn from lo + OPENING_MARGIN (facade::apply) up to under the lintel.
        let height = d.style.door_height.min(hi - LINTEL - lo - OPENING_MARGIN);
        if height < DOOR_MIN_HEIGHT {
            continue;
        }
        let outer = d.part.footprint.outer.len().min(d.part.walls.len());
        for k in 0..outer {
            let w = &d.part.walls[k];
            let len = w.length();
            if len <= 0.0 {
                continue;
            }
            let dir = (w.end - w.start) / len;
            let normal = DVec2::new(dir.y, -dir.x);
            let blocked: Vec<(f64, f64)> = out.spans[p][k]
                .iter()
                .filter(|s| s.z0 < lo + OPENING_MARGIN + height && lo < s.z1)
                .map(|s| (s.u0, s.u1))
                .collect();
            let Some(free) = longest_free(OPENING_MARGIN, len - OPENING_MARGIN, blocked) else {
                continue;
            };
            if free.1 - free.0 < DOOR_MIN_WIDTH + 2.0 * JAMB_SNAP {
                continue;
            }
            let tier = tier(normal, front);
            let rules_chose = wanted[p].is_some_and(|(wk, _, _)| wk == k);
            // Longer free stretches first, in centimetres up to 6 m (a wall that long has room).
            let room = -((free.1 - free.0).min(6.0) * 100.0).round() as i64;
            let key = (tier, !rules_chose, room);
            if best.as_ref().is_none_or(|b| key < b.key) {
                best = Some(Choice {
                    key,
                    p,
                    k,
                    free,
                    height,
                    normal,
                });
            }
        }
    }
    let Some(c) = best else {
        if grounded {
            out.counts.without_entrance += 1;
            out.note = Some(
                if lowest_storey < DOOR_MIN_HEIGHT + LINTEL + OPENING_MARGIN {
                    format!(
                    "no entrance: a ground storey of {lowest_storey:.2} m has no room for a door of {DOOR_MIN_HEIGHT} m under its lintel"
                )
                } else {
                    format!(
                    "no entrance: no ground-storey wall has {DOOR_MIN_WIDTH} m free of neighbours"
                )
                },
            );
        }
        return;
    };
    let d = &mut drafts[c.p];
    let (lo, _) = facade::storeys(d.part, d.facades)[0];
    let width = d
        .style
        .door_width
        .max(DOOR_MIN_WIDTH + 2.0 * JAMB_SNAP)
        .min(c.free.1 - c.free.0);
    let (f0, f1) = (c.free.0 + 0.5 * width, c.free.1 - 0.5 * width);
    let mid = match wanted[c.p] {
        Some((wk, u, _)) if wk == c.k => u,
        _ => 0.5 * (c.free.0 + c.free.1),
    };
    // Centred on the bay whose window is nearest the middle, when there is one.
    let ops = &mut d.facades.openings[c.k];
    let centre = ops
        .iter()
        .filter(|o| o.z0 < lo + c.height && o.kind == OpeningKind::Window)
        .map(|o| 0.5 * (o.u0 + o.u1))
        .filter(|u| (f0..=f1).contains(u))
        .min_by(|a, b| (a - mid).abs().total_cmp(&(b - mid).abs()))
        .unwrap_or(mid)
        .clamp(f0, f1.max(f0));
    let door = FoundOpening {
        kind: OpeningKind::Door,
        u0: centre - 0.5 * width,
        u1: centre + 0.5 * width,
        z0: lo,
        z1: lo + OPENING_MARGIN + c.height,
        color: wanted[c.p].and_then(|w| w.2).or(Some(d.style.door_color)),
        frame_color: None,
        glazed: false,
        framed: false,
        frame_size: None,
        rounding: None,
    };
    put_entrance(ops, door, wanted, out);
    out.entrance = Some((c.p, c.normal));
}

/// The longest stretch of `lo..hi` outside every interval of `blocked`.
fn longest_free(lo: f64, hi: f64, mut blocked: Vec<(f64, f64)>) -> Option<(f64, f64)> {
    blocked.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut best: Option<(f64, f64)> = None;
    let mut at = lo;
    let mut consider = |a: f64, b: f64| {
        if b > a && best.is_none_or(|(x, y)| b - a > y - x) {
            best = Some((a, b));
        }
    };
    for (s, e) in blocked {
        consider(at, s.min(hi));
        at = at.max(e);
    }
    consider(at, hi);
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_longest_free_stretch_skips_the_blocked_ones() {
        assert_eq!(longest_free(0.0, 10.0, vec![]), Some((0.0, 10.0)));
        assert_eq!(
            longest_free(0.0, 10.0, vec![(6.0, 7.0), (1.0, 3.0)]),
            Some((3.0, 6.0))
        );
        assert_eq!(longest_free(0.0, 10.0, vec![(-1.0, 11.0)]), None);
        assert_eq!(
            longest_free(0.0, 10.0, vec![(2.0, 5.0), (4.0, 8.0)]),
            Some((0.0, 2.0))
        );
    }

    /// Issue 45, item 5, over many footprints and seeds in Monaco's zone (balconies on a third
    /// of the upper bays): an L-shaped block (an acute re-entrant corner) between a terraced
    /// neighbour and one across a narrow passage, at LOD3. No window or door is narrower than the
    /// knowledge base's minimum (0.4 m), and no balcony leaves its wall or has its slab (1.2 m
    /// out) in a footprint: a neighbour's, another part's or its own part's, over its height.
    #[test]
    fn no_slit_and_no_balcony_into_a_footprint() {
        use crate::derive::{Generator, Rules};
        use crate::geometry::Polygon;
        use crate::grammar::Caps;
        use crate::kb::KnowledgeBase;
        use crate::model::Lod;

        let path = std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/knowledge_base/kb.xml"
        ));
        let v = DVec2::new;
        let (mut balconies, mut openings) = (0, 0);
        for case in 0..24u64 {
            let kb = KnowledgeBase::load(path).unwrap().0;
            let mut gen = Generator::new(kb, Rules::Kb, Lod::Lod3, case, Caps::default());
            let f = case as f64;
            let (w, d) = (12.0 + (f * 1.7) % 9.0, 9.0 + (f * 2.3) % 7.0);
            let (nw, nd) = (
                0.35 + 0.03 * (case % 7) as f64,
                0.4 + 0.04 * (case % 5) as f64,
            );
            // The wing's inner wall leans over the lower wing's roof edge (an acute re-entrant
            // corner); the right neighbour stands across a 0.9 m passage, deeper.
            let ell = vec![
                v(0.0, 0.0),
                v(w, 0.0),
                v(w, d * nd),
                v(w * nw, d * nd),
                v(w * nw + 2.0, d),
                v(0.0, d),
            ];
            let left = vec![v(-7.0, 0.0), v(0.0, 0.0), v(0.0, d), v(-7.0, d)];
            let (x0, x1) = (w + 0.9, w + 7.0);
            let right = vec![v(x0, -2.0), v(x1, -2.0), v(x1, d + 3.0), v(x0, d + 3.0)];
            let mut report = crate::report::Report::default();
            let mut site = None;
            let mut lots = Vec::new();
            for (i, ring) in [ell, left, right].into_iter().enumerate() {
                let mut s = crate::prepare::single_lot(
                    Polygon::new(ring, vec![]),
                    (7.4206, 43.7308),
                    None,
                    &mut report,
                )
                .unwrap();
                let mut lot = s.lots.pop().unwrap();
                lot.id = SourceId::Lot(i as u64);
                lots.push(lot);
                site = Some(s);
            }
            let mut site = site.unwrap();
            site.lots = lots;
            gen.surroundings = gen.neighbours_of(&site.lots, |_| true);
            for lot in &site.lots {
                let (b, _) = gen.generate(lot).unwrap();
                let around =
                    gen.surroundings
                        .near(b.id, DVec2::splat(f64::MIN), DVec2::splat(f64::MAX));
                for part in &b.parts {
                    for wall in &part.walls {
                        let len = wall.length();
                        for o in &wall.openings {
                            openings += 1;
                            assert!(o.width() >= 0.4 - 1e-9, "{}: {o:?}", b.id);
                        }
                        let dir = (wall.end - wall.start) / len;
                        let out = DVec2::new(dir.y, -dir.x);
                        for bal in &wall.balconies {
                            balconies += 1;
                            assert!(bal.u0 >= -1e-9 && bal.u1 <= len + 1e-9, "{bal:?}");
                            let z = bal.z + 0.5;
                            let inside = |p: DVec2| {
                                b.parts
                                    .iter()
                                    .filter(|q| q.base_z <= z && z < q.top_z)
                                    .any(|q| q.footprint.contains(p))
                                    || around.iter().any(|n| {
                                        n.z0 <= z + lot.ground
                                            && z + lot.ground < n.z1
                                            && crate::geometry::ring_contains(&n.rings[0], p)
                                    })
                            };
                            let steps = ((bal.u1 - bal.u0) / 0.1).ceil() as usize;
                            for i in 0..=steps {
                                let u = (bal.u0 + 0.02)
                                    + (bal.u1 - bal.u0 - 0.04) * i as f64 / steps as f64;
                                for t in [0.05, 0.3, 0.6, 0.9, 1.15] {
                                    let p = wall.start + dir * u + out * t;
                                    assert!(!inside(p), "{}: {bal:?} reaches {p}", b.id);
                                }
                            }
                        }
                    }
                }
            }
        }
        assert!(openings > 500, "{openings} openings");
        assert!(balconies > 20, "{balconies} balconies");
    }
}
