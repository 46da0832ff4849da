//! From masses to the semantic model: walls, ground and roof of each building part.
//!
//! A [`Mass`] is one vertical extrusion of one footprint with its roof and colours: what the
//! derived shape tree says a building part is (see [`crate::derive`]). [`build_part`] turns it
//! into a [`Part`] cut at the run's LOD: at LOD1 a block with a flat top at the overall height,
//! from LOD2 the real roof on walls that stop at the eave.

use glam::{DVec2, DVec3};

use crate::color::Color;
use crate::derive::roof::{self, RoofGeometry};
use crate::geometry::{ring, CellHash, Polygon};
use crate::model::{on_grid, Face, Lod, Part, PartRole, RoofShape, Wall};

pub mod grid;

/// Default exterior wall thickness in metres.
pub(crate) const WALL_THICKNESS: f64 = 0.3;

/// Pitch used when a mass carries none usable (a KB angle of 0 or 90 on a pitched roof).
pub(crate) const DEFAULT_PITCH_DEG: f64 = 30.0;

/// Roofs lower than this are drawn flat (a pitched roof of a few centimetres is noise).
const MIN_ROOF_HEIGHT: f64 = 0.05;

/// One building part before it becomes geometry.
#[derive(Clone, Debug, PartialEq)]
pub struct Mass {
    /// Footprint of the mass in the local frame (metres): the derived volume's footprint.
    pub footprint: Polygon,
    /// Bottom of the walls, metres: the derived volume's base (the style's `min_height`, from OSM
    /// `min_height` or `building:min_level`, for a mass extruded from the lot).
    pub base_z: f64,
    /// Top of the walls.
    pub eave_z: f64,
    /// Storeys above the base: the finest partition of the rules' horizontal storey cuts, else the
    /// style's `storeys`.
    pub storeys: u32,
    /// Roof shape asked for: the mass's `roof` attribute in the rules, else the style's.
    pub roof: RoofShape,
    /// Pitch in degrees, used when `roof_height` is not given.
    pub roof_angle_deg: f64,
    /// Compass bearing (degrees from north) a skillion slopes down towards (OSM
    /// `roof:direction`); `None`: across the footprint's short side.
    pub roof_direction: Option<f64>,
    /// OSM `roof:orientation=across`: the ridge of a gabled, saltbox, `gabled_height_moved`,
    /// butterfly or sawtooth roof parallel to the short side (see `roof::build_oriented`).
    pub roof_across: bool,
    /// Height of the roof above the eave, when known (OSM `roof:height`).
    pub roof_height: Option<f64>,
    /// Wall colour: the mass's `color` attribute in the rules, else the style's.
    pub wall_color: Color,
    /// Roof colour: the mass's `roofcolor` attribute in the rules, else the style's.
    pub roof_color: Color,
}

/// A roof that could not be built as asked and fell back to flat.
#[derive(Clone, Debug, PartialEq)]
pub struct RoofFallback {
    /// The roof shape that was asked for.
    pub asked: RoofShape,
    /// Why it could not be built, for the report (a roof-builder error, or `roof would be 0.030 m
    /// high` for a roof under 5 cm).
    pub reason: String,
}

/// Computes the roof surfaces of a mass at z = 0 (the eave), or the reason it must be flat.
///
/// Every shape of [`RoofShape`] is built on every valid simple footprint, holes included (see
/// [`roof::build`]); the height is `roof_height` when given, else follows from the pitch. The
/// only fallbacks are an invalid footprint or parameter, and a roof lower than 5 cm.
pub fn roof_geometry(mass: &Mass) -> Result<RoofGeometry, RoofFallback> {
    let fallback = |reason: String| RoofFallback {
        asked: mass.roof,
        reason,
    };
    let footprint = &mass.footprint;
    if mass.roof == RoofShape::Flat {
        return Ok(roof::flat(footprint));
    }
    let pitch = if mass.roof_angle_deg.is_finite()
        && mass.roof_angle_deg > 0.0
        && mass.roof_angle_deg < 90.0
    {
        mass.roof_angle_deg
    } else {
        DEFAULT_PITCH_DEG
    };
    let down = mass.roof_direction.map(|b| {
        let r = b.to_radians();
        DVec2::new(r.sin(), r.cos())
    });
    let pitched = pitched_roof(footprint, mass.roof, pitch, down, mass.roof_across)
        .map_err(|e| fallback(e.to_string()))?;
    let pitched = match mass.roof_height {
        Some(h) if h > MIN_ROOF_HEIGHT => pitched.scaled_to_height(h),
        _ => pitched,
    };
    if pitched.height.is_nan() || pitched.height <= MIN_ROOF_HEIGHT {
        return Err(fallback(format!(
            "roof would be {:.3} m high",
            pitched.height
        )));
    }
    Ok(pitched)
}

/// The mass a roof drawn by cutting the footprint with lines falls back to when its part fails
/// [`check_part`] (a safety net: the cuts keep clear of the footprint's corners, but a
/// footprint may still leave a sliver the grid cannot keep planar): sawtooth and butterfly
/// become a skillion, saltbox, `gabled_height_moved`, crosspitched and a gabled roof turned by
/// `roof:direction`/`roof:orientation` the plain (straight-skeleton) gabled roof, a skillion
/// flat; a skeleton roof turned by those tags (`shapes::turned_profile_roof`: hipped,
/// half-hipped, mansard, gambrel, ...) the same shape unturned. `None` for the roofs that are
/// not cut or turned (they are the fallbacks).
pub(crate) fn simpler_roof(mass: &Mass) -> Option<Mass> {
    let turned = mass.roof_direction.is_some() || mass.roof_across;
    let roof = match mass.roof {
        RoofShape::Sawtooth | RoofShape::Butterfly => RoofShape::Skillion,
        RoofShape::Saltbox | RoofShape::GabledHeightMoved | RoofShape::Crosspitched => {
            RoofShape::Gabled
        }
        RoofShape::Gabled if turned => RoofShape::Gabled,
        RoofShape::Skillion => RoofShape::Flat,
        RoofShape::Hipped
        | RoofShape::HalfHipped
        | RoofShape::SideHipped
        | RoofShape::SideHalfHipped
        | RoofShape::HippedAndGabled
        | RoofShape::BellcastGable
        | RoofShape::Mansard
        | RoofShape::Gambrel
        | RoofShape::Round
            if turned =>
        {
            mass.roof
        }
        _ => return None,
    };
    let plain = roof == RoofShape::Gabled || roof == mass.roof;
    Some(Mass {
        roof,
        roof_direction: if plain { None } else { mass.roof_direction },
        roof_across: !plain && mass.roof_across,
        ..mass.clone()
    })
}

/// Builds the part of `mass` (see [`build_part`]) with the roof `roof_of` gives it; a roof that
/// cannot be built is flat, and from LOD2 a cut roof whose part fails [`check_part`] is drawn
/// as the next simpler shape ([`simpler_roof`]) until one passes. Returns the part and, for
/// the report, a line for each fallback naming `id` (the building or part the mass is of).
pub(crate) fn part_with_roof(
    key: String,
    mass: &Mass,
    lod: Lod,
    id: &str,
    roof_of: impl Fn(&Mass) -> Result<RoofGeometry, RoofFallback>,
) -> (Part, Vec<String>) {
    let mut notes = Vec::new();
    let mut m = std::borrow::Cow::Borrowed(mass);
    loop {
        let roof = match roof_of(&m) {
            Ok(r) => r,
            Err(f) => {
                notes.push(format!(
                    "{} roof of {id} drawn flat: {}",
                    f.asked.osm_name(),
                    f.reason
                ));
                return (build_part(key, &m, &roof::flat(&m.footprint), lod), notes);
            }
        };
        let part = build_part(key.clone(), &m, &roof, lod);
        let next = if lod == Lod::Lod1 {
            None
        } else {
            simpler_roof(&m)
        };
        let Some(next) = next else {
            return (part, notes);
        };
        let defects = check_part(&part);
        let Some(first) = defects.first() else {
            return (part, notes);
        };
        notes.push(format!(
            "{} roof of {id} drawn {}: as {}, it failed the roof checks ({first})",
            m.roof.osm_name(),
            if next.roof == RoofShape::Flat {
                "flat".to_string()
            } else if next.roof == m.roof {
                "unturned".to_string()
            } else {
                format!("as {}", next.roof.osm_name())
            },
            if next.roof == m.roof { "turned" } else { "cut" },
        ));
        m = std::borrow::Cow::Owned(next);
    }
}

/// The roof of [`roof_geometry`] before it is fitted to a height.
fn pitched_roof(
    footprint: &Polygon,
    shape: RoofShape,
    pitch: f64,
    down: Option<DVec2>,
    across: bool,
) -> Result<RoofGeometry, roof::RoofError> {
    roof::build_oriented(footprint, shape, pitch, down, across)
}

/// Builds the walls, ground and roof of one part at the given LOD.
///
/// `roof` is the result of [`roof_geometry`] for this mass (computed by the caller, which may
/// need the roof height first). At LOD1 the part is a block up to its overall top.
pub fn build_part(key: String, mass: &Mass, roof: &RoofGeometry, lod: Lod) -> Part {
    let footprint = built_footprint(mass).into_owned();
    let (base_z, eave_z) = (on_grid(mass.base_z), on_grid(mass.eave_z));
    let flat = roof.faces.is_empty() || roof.height <= MIN_ROOF_HEIGHT;
    let top_z = if flat { eave_z } else { eave_z + roof.height };
    let wall_top = if lod == Lod::Lod1 {
        on_grid(top_z)
    } else {
        eave_z
    };
    let (mut walls, mut roof_faces) = if lod == Lod::Lod1 || flat {
        (
            walls(&footprint, base_z, wall_top),
            vec![horizontal_face(&footprint, wall_top, true)],
        )
    } else {
        (
            walls_under_roof(&footprint, base_z, eave_z, roof),
            roof.faces
                .iter()
                .map(|f| translate_face(f, eave_z))
                .collect(),
        )
    };
    let mut ground = horizontal_face(&footprint, base_z, false);
    weld(&footprint, &mut ground, &mut walls, &mut roof_faces);
    roof_faces.retain(|f| f.outer.len() >= 3);
    grid::finish(&mut ground, &mut walls, &mut roof_faces);
    // The top as built (the highest roof vertex, on the grid).
    let top_z = if lod == Lod::Lod1 || flat {
        wall_top
    } else {
        roof_faces
            .iter()
            .flat_map(|f| f.outer.iter())
            .map(|p| p.z)
            .fold(eave_z, f64::max)
    };
    Part {
        key,
        footprint,
        base_z,
        eave_z: if lod == Lod::Lod1 { top_z } else { eave_z },
        top_z,
        storeys: mass.storeys.max(1),
        levels: even_levels(base_z, eave_z, mass.storeys.max(1))
            .into_iter()
            .map(on_grid)
            .collect(),
        wall_color: mass.wall_color,
        roof_color: mass.roof_color,
        wall_material: Default::default(),
        roof_material: Default::default(),
        roof_shape: if flat { RoofShape::Flat } else { mass.roof },
        walls,
        roof: roof_faces,
        ground,
        interior: Vec::new(),
        source: None,
        role: PartRole::Own,
        structure: None,
        rhythm: None,
        cornice: None,
        eaves: None,
    }
}

/// The footprint a mass is built on: its own on the output grid ([`grid::polygon_on_grid`]),
/// or as it is when rounding would make it touch itself.
pub(crate) fn built_footprint(mass: &Mass) -> std::borrow::Cow<'_, Polygon> {
    match grid::polygon_on_grid(&mass.footprint) {
        Some(p) if p != mass.footprint => std::borrow::Cow::Owned(p),
        _ => std::borrow::Cow::Borrowed(&mass.footprint),
    }
}

/// One wall per ring edge, outer ring first, rectangles from `base` to `top`.
///
/// The outer ring is counter-clockwise and holes clockwise, so the outside of the building is
/// always on the right of start->end and the outline (start, end, end-up, start-up) faces out.
pub fn walls(footprint: &Polygon, base: f64, top: f64) -> Vec<Wall> {
    let mut out = Vec::with_capacity(footprint.outer.len());
    for ring in footprint.rings() {
        let n = ring.len();
        for i in 0..n {
            let (s, e) = (ring[i], ring[(i + 1) % n]);
            out.push(Wall {
                start: s,
                end: e,
                base_z: base,
                top_z: top,
                thickness: WALL_THICKNESS,
                outline: Face::new(vec![at(s, base), at(e, base), at(e, top), at(s, top)]),
                storey: 0,
                openings: Vec::new(),
                balconies: Vec::new(),
                party: 0.0,
            });
        }
    }
    out
}

/// Floor elevations of `n` equal storeys between `base` and `eave`.
pub(crate) fn even_levels(base: f64, eave: f64, n: u32) -> Vec<f64> {
    let n = n.max(1);
    let h = (eave - base) / f64::from(n);
    (0..n).map(|i| base + h * f64::from(i)).collect()
}

/// One wall per ring edge whose top follows the roof: the outline is start-base, end-base, then
/// the roof line over the edge from the end back to the start ([`crate::derive::roof::shapes::RoofLine::over`]): a rectangle
/// under eaves, a pentagon (or more, under a profile roof) under a gable, a trapezoid under a
/// skillion. `roof` is at z = 0 at the eave; the eave is at `eave`.
pub(crate) fn walls_under_roof(
    footprint: &Polygon,
    base: f64,
    eave: f64,
    roof: &RoofGeometry,
) -> Vec<Wall> {
    let mut out = Vec::with_capacity(footprint.outer.len());
    let line = crate::derive::roof::shapes::RoofLine::new(&roof.faces, footprint);
    for (ri, ring) in footprint.rings().enumerate() {
        let n = ring.len();
        for i in 0..n {
            let (s, e) = (ring[i], ring[(i + 1) % n]);
            let mut outline = vec![at(s, base), at(e, base)];
            outline.extend(
                line.over(ri, i)
                    .into_iter()
                    .map(|p| DVec3::new(p.x, p.y, p.z + eave)),
            );
            out.push(Wall {
                start: s,
                end: e,
                base_z: base,
                top_z: eave,
                thickness: WALL_THICKNESS,
                outline: Face::new(outline),
                storey: 0,
                openings: Vec::new(),
                balconies: Vec::new(),
                party: 0.0,
            });
        }
    }
    out
}

/// Makes the part's surfaces meet exactly: vertices closer than a tolerance (1e-5 of the
/// footprint size, within 1 µm..0.5 mm) become one, and a vertex lying on another face's edge is
/// inserted into that edge (the skeleton cuts faces of collinear footprint edges, and profile
/// bands put points on edges, so neighbouring faces may otherwise meet in T-junctions). A wall
/// outline's first edge (its base) is left as it is: nothing else stands on it but the ground's
/// own vertices.
fn weld(footprint: &Polygon, ground: &mut Face, walls: &mut [Wall], roof: &mut [Face]) {
    let (lo, hi) = footprint.bounds();
    let size = (hi - lo).max_element();
    if !size.is_finite() {
        return;
    }
    let tol = (1e-5 * size).clamp(1e-6, 5e-4);
    // Canonical vertices, bucketed on a grid of cell `tol`: ground and walls first, so the
    // footprint's exact corners win. (A hash map with a fixed hasher: only looked up, never
    // iterated, so its order cannot reach the output.)
    // Up to WELD_LINEAR canonical vertices they are scanned one by one (cheaper than 27
    // probes), taking the one the cells would give first: the nearest cell in (dx, dy, dz)
    // order, then the first made.
    const WELD_LINEAR: usize = 64;
    let mut canon: Vec<DVec3> = Vec::new();
    let mut canon_cells: Vec<(i64, i64, i64)> = Vec::new();
    let mut grid: std::collections::HashMap<(i64, i64, i64), Vec<usize>, CellHash> =
        Default::default();
    let cell = |p: DVec3| {
        (
            (p.x / tol).floor() as i64,
            (p.y / tol).floor() as i64,
            (p.z / tol).floor() as i64,
        )
    };
    // The canonical vertices bit for bit: a vertex that is one of them stays as it is (no
    // other canonical vertex is within `tol` of it in the cells around it, or one of the two
    // would have joined the other when it came).
    let n_points = ground.outer.len()
        + ground.holes.iter().map(Vec::len).sum::<usize>()
        + walls.iter().map(|w| w.outline.outer.len()).sum::<usize>()
        + roof
            .iter()
            .map(|f| f.outer.len() + f.holes.iter().map(Vec::len).sum::<usize>())
            .sum::<usize>();
    let mut canon_bits: std::collections::HashSet<(u64, u64, u64), CellHash> =
        std::collections::HashSet::with_capacity_and_hasher(n_points, CellHash);
    let bits = |p: &DVec3| (p.x.to_bits(), p.y.to_bits(), p.z.to_bits());
    let mut snap = |p: &mut DVec3| {
        if canon_bits.contains(&bits(p)) {
            return;
        }
        let c = cell(*p);
        if canon.len() <= WELD_LINEAR {
            let mut best: Option<(i64, usize)> = None;
            for (i, (q, qc)) in canon.iter().zip(&canon_cells).enumerate() {
                let d = (qc.0 - c.0, qc.1 - c.1, qc.2 - c.2);
                if d.0.abs() > 1 || d.1.abs() > 1 || d.2.abs() > 1 {
                    continue;
                }
                let rank = (d.0 + 1) * 9 + (d.1 + 1) * 3 + (d.2 + 1);
                if best.is_some_and(|(r, _)| r <= rank) {
                    continue;
                }
                if q.distance(*p) <= tol {
                    best = Some((rank, i));
                }
            }
            if let Some((_, i)) = best {
                *p = canon[i];
                return;
            }
        } else {
            for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        if let Some(v) = grid.get(&(c.0 + dx, c.1 + dy, c.2 + dz)) {
                            if let Some(&i) = v.iter().find(|&&i| canon[i].distance(*p) <= tol) {
                                *p = canon[i];
                                return;
                            }
                        }
                    }
                }
            }
        }
        canon.push(*p);
        canon_bits.insert(bits(p));
        canon_cells.push(c);
        if canon.len() == WELD_LINEAR + 1 {
            for (i, qc) in canon_cells.iter().enumerate() {
                grid.entry(*qc).or_default().push(i);
            }
        } else if canon.len() > WELD_LINEAR + 1 {
            grid.entry(c).or_default().push(canon.len() - 1);
        }
    };
    {
        let mut all: Vec<&mut Vec<DVec3>> = Vec::new();
        all.push(&mut ground.outer);
        all.extend(ground.holes.iter_mut());
        for w in walls.iter_mut() {
            all.push(&mut w.outline.outer);
        }
        for f in roof.iter_mut() {
            all.push(&mut f.outer);
            all.extend(f.holes.iter_mut());
        }
        for r in all {
            for p in r.iter_mut() {
                snap(p);
            }
            drop_collapsed(r);
        }
    }
    // T-junctions: a dense plan grid over the canonical vertices (compressed rows: `start[c]..
    // start[c + 1]` of `members`), about one vertex per cell and at most 64 cells a side.
    let (clo, chi) = canon.iter().fold(
        (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(p.truncate()), hi.max(p.truncate())),
    );
    let n_side = ((canon.len() as f64).sqrt().ceil() as usize).clamp(1, 64);
    let g = (((chi - clo).max_element()) / n_side as f64).max(tol);
    if !g.is_finite() {
        return;
    }
    let cell_of =
        |v: f64, lo: f64| -> usize { (((v - lo) / g).floor().max(0.0) as usize).min(n_side - 1) };
    let index_of = |p: DVec3| cell_of(p.y, clo.y) * n_side + cell_of(p.x, clo.x);
    let mut start = vec![0usize; n_side * n_side + 1];
    for p in &canon {
        start[index_of(*p) + 1] += 1;
    }
    for i in 1..start.len() {
        start[i] += start[i - 1];
    }
    let mut fill = start.clone();
    let mut members = vec![0usize; canon.len()];
    for (k, p) in canon.iter().enumerate() {
        let c = index_of(*p);
        members[fill[c]] = k;
        fill[c] += 1;
    }
    let mut on: Vec<(f64, usize)> = Vec::new();
    let mut split = |r: &mut Vec<DVec3>, skip_first: bool| {
        let n = r.len();
        let mut out = Vec::with_capacity(n);
        for i in 0..n {
            let (u, v) = (r[i], r[(i + 1) % n]);
            out.push(u);
            if skip_first && i == 0 {
                continue;
            }
            let d = v - u;
            let l2 = d.length_squared();
            if l2 <= tol * tol {
                continue;
            }
            let (a, b) = (u.min(v), u.max(v));
            on.clear();
            let (x0, x1) = (cell_of(a.x - tol, clo.x), cell_of(b.x + tol, clo.x));
            let (y0, y1) = (cell_of(a.y - tol, clo.y), cell_of(b.y + tol, clo.y));
            for cy in y0..=y1 {
                let row = cy * n_side;
                for &k in &members[start[row + x0]..start[row + x1 + 1]] {
                    let q = canon[k];
                    let along = (q - u).dot(d);
                    // Off the segment's span (then `s` below is too): spares the division.
                    if along <= 0.0 || along >= l2 {
                        continue;
                    }
                    let s = along / l2;
                    if s <= 0.0 || s >= 1.0 || q == u || q == v {
                        continue;
                    }
                    if (u + d * s).distance(q) <= tol {
                        on.push((s, k));
                    }
                }
            }
            // Along the edge; ties by canonical index, so the order does not depend on the grid.
            on.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
            on.dedup_by(|x, y| canon[x.1] == canon[y.1]);
            out.extend(on.iter().map(|x| canon[x.1]));
        }
        *r = out;
    };
    split(&mut ground.outer, false);
    for h in ground.holes.iter_mut() {
        split(h, false);
    }
    for w in walls.iter_mut() {
        split(&mut w.outline.outer, true);
    }
    for f in roof.iter_mut() {
        split(&mut f.outer, false);
        for h in f.holes.iter_mut() {
            split(h, false);
        }
    }
}

/// Removes consecutive duplicates and spikes (`x, y, x`: a sliver face collapsed by welding
/// runs along an edge and back) from a ring, exactly, so no collapsed piece leaves a doubled
/// edge; a ring left with fewer than 3 vertices is emptied.
fn drop_collapsed(r: &mut Vec<DVec3>) {
    ring::dedup_by(r, |a, b| a == b);
    ring::remove_spikes_by(r, |a, b| a == b);
    if r.len() < 3 {
        r.clear();
    }
}

/// Checks that a part's surfaces (ground, wall outlines, roof faces) bound a closed solid:
/// every edge is used exactly twice, once in each direction (consistently oriented faces).
/// Returns a description of each defect, empty when the solid is closed. Edges are compared
/// on exact coordinates (after [`build_part`]'s welding).
pub fn closure_defects(part: &Part) -> Vec<String> {
    use std::collections::BTreeMap;
    type K = (u64, u64, u64);
    let key = |p: DVec3| (p.x.to_bits(), p.y.to_bits(), p.z.to_bits());
    let mut count: BTreeMap<(K, K), i64> = BTreeMap::new();
    let mut rings: Vec<&Vec<DVec3>> = vec![&part.ground.outer];
    rings.extend(part.ground.holes.iter());
    rings.extend(part.walls.iter().map(|w| &w.outline.outer));
    for f in &part.roof {
        rings.push(&f.outer);
        rings.extend(f.holes.iter());
    }
    for r in rings {
        for i in 0..r.len() {
            let (a, b) = (key(r[i]), key(r[(i + 1) % r.len()]));
            if a == b {
                continue;
            }
            *count.entry((a, b)).or_default() += 1;
        }
    }
    let mut out = Vec::new();
    let f = |k: K| {
        DVec3::new(
            f64::from_bits(k.0),
            f64::from_bits(k.1),
            f64::from_bits(k.2),
        )
    };
    for (&(a, b), &n) in &count {
        let back = count.get(&(b, a)).copied().unwrap_or(0);
        if n != 1 || back != 1 {
            out.push(format!(
                "edge {} -> {} used {n} times, reverse {back} times",
                f(a),
                f(b)
            ));
        }
    }
    out
}

/// Checks the geometric invariants of a part built by [`build_part`] and returns one line per
/// violation (empty when all hold):
///
/// * every coordinate is finite;
/// * every face (ground, wall outlines, roof faces) is planar within `PLANAR_TOL` and has an
///   area above 1e-6 m² (no zero-area face or sliver triangle face);
/// * wall outlines stand on their footprint edge's vertical plane (within `PLANAR_TOL`), face
///   out of the building (their normal points to the right of start → end) and start with their
///   base edge;
/// * roof faces face up, lie within `PLANAR_TOL` of the footprint in plan, and their plan areas add up
///   to the footprint's area within 0.1 %;
/// * the surfaces bound a closed solid ([`closure_defects`]).
pub fn check_part(part: &Part) -> Vec<String> {
    let mut out = Vec::new();
    let planar = |f: &Face, what: &str, out: &mut Vec<String>| {
        let pts = f.outer.iter().chain(f.holes.iter().flatten());
        if pts.clone().any(|p| !p.is_finite()) {
            out.push(format!("{what}: non-finite vertex"));
            return;
        }
        let n = crate::geometry::newell_normal(&f.outer);
        let area = 0.5 * n.length();
        if area.is_nan() || area < 1e-6 {
            out.push(format!("{what}: area {area}"));
            return;
        }
        // Against the least-squares plane, as val3dity measures it (a sliver's Newell normal
        // tilts off the plane its points lie on).
        let dev = crate::geometry::least_squares_plane_deviation(pts);
        if dev > PLANAR_TOL {
            out.push(format!("{what}: not planar ({dev} m)"));
        }
    };
    planar(&part.ground, "ground", &mut out);
    for (i, w) in part.walls.iter().enumerate() {
        let what = format!("wall {i}");
        planar(&w.outline, &what, &mut out);
        let n = w.outline.normal();
        let outward = -(w.end - w.start).perp().normalize_or_zero();
        // On its footprint edge's vertical plane (within the grid's tolerance), facing out.
        let off = w
            .outline
            .outer
            .iter()
            .map(|p| (p.truncate() - w.start).dot(outward).abs())
            .fold(0.0, f64::max);
        if off > PLANAR_TOL || n.truncate().dot(outward) < 0.999 {
            out.push(format!(
                "{what}: normal {n} not outward {outward}, or {off} m off its plane"
            ));
        }
        let o = &w.outline.outer;
        if o.len() < 3
            || o[0] != DVec3::new(w.start.x, w.start.y, w.base_z)
            || o[1] != DVec3::new(w.end.x, w.end.y, w.base_z)
        {
            out.push(format!("{what}: outline does not start with its base"));
        }
    }
    let fp = &part.footprint;
    let mut area = 0.0;
    for (i, f) in part.roof.iter().enumerate() {
        let what = format!("roof face {i}");
        planar(f, &what, &mut out);
        if f.normal().z <= 1e-9 {
            out.push(format!("{what}: does not face up"));
        }
        let plan = |r: &Vec<DVec3>| {
            crate::geometry::ring_signed_area(&r.iter().map(|p| p.truncate()).collect::<Vec<_>>())
        };
        area += plan(&f.outer) + f.holes.iter().map(plan).sum::<f64>();
        for p in f.outer.iter().chain(f.holes.iter().flatten()) {
            let g = p.truncate();
            if !fp.contains(g) && dist_to_boundary(fp, g) > PLANAR_TOL {
                out.push(format!("{what}: vertex {g} outside the footprint"));
            }
        }
    }
    // The roof's boundary vertices sit on the millimetre grid, each up to MIN_VERTEX_GAP
    // from where the footprint's edge runs (an apex on a gable wall rounded off its line): a
    // strip that wide along the outline, beside the relative tolerance for large footprints.
    let want = fp.area();
    let perimeter: f64 = fp.rings().map(|r| crate::geometry::ring_perimeter(r)).sum();
    if (area - want).abs() > 1e-3 * want + perimeter * crate::model::MIN_VERTEX_GAP {
        out.push(format!("roof covers {area} m², footprint {want} m²"));
    }
    out.extend(closure_defects(part));
    out
}

/// Checks a part as the writers put it on disk: every coordinate `origin + p` rounded to the
/// millimetre (CityGML's 3 decimals; `origin` is the local frame's origin, whole metres), and
/// returns one line per violation of the solid rules a validator such as val3dity applies at
/// its default tolerances (empty when all hold):
///
/// * no ring repeats a vertex consecutively (closing vertex included);
/// * no ring has a spike (a vertex where the ring turns straight back: `x, y, x`, or two
///   edges running exactly opposite) or touches itself (`geometry::is_simple` in the face's
///   plane);
/// * the rounded surfaces bound a closed solid: every edge used exactly once in each
///   direction;
/// * every face is planar within `WRITTEN_PLANARITY` (1 cm) and has no sliver: each triangle
///   of the face (`geometry::triangulate`, an ear clipper) has its normal within
///   `WRITTEN_NORMAL_DEG` (20°) of the face's normal. These lines start with `sliver:`; the
///   ear clipper also cuts ears of three boundary vertices of one straight run (a footprint's
///   collinear vertex on an eave, moved off the line by the rounding), which a constrained
///   Delaunay triangulation (val3dity's) would not, so this check is stricter than the
///   validator's.
pub fn written_defects(part: &Part, origin: DVec3) -> Vec<String> {
    use std::collections::BTreeMap;
    type K = (i64, i64, i64);
    let q = |v: f64| (v * 1000.0).round() as i64;
    let key = |p: DVec3| {
        let g = origin + p;
        (q(g.x), q(g.y), q(g.z))
    };
    let back = |k: K| DVec3::new(k.0 as f64, k.1 as f64, k.2 as f64) / 1000.0 - origin;
    let mut out = Vec::new();
    let mut count: BTreeMap<(K, K), i64> = BTreeMap::new();
    let mut faces: Vec<(String, &Face)> = vec![("ground".to_string(), &part.ground)];
    faces.extend(
        part.walls
            .iter()
            .enumerate()
            .map(|(i, w)| (format!("wall {i}"), &w.outline)),
    );
    faces.extend(
        part.roof
            .iter()
            .enumerate()
            .map(|(i, f)| (format!("roof face {i}"), f)),
    );
    let min_cos = WRITTEN_NORMAL_DEG.to_radians().cos();
    for (what, f) in &faces {
        let rings: Vec<Vec<K>> = std::iter::once(&f.outer)
            .chain(f.holes.iter())
            .map(|r| r.iter().map(|p| key(*p)).collect())
            .collect();
        for (ri, r) in rings.iter().enumerate() {
            let n = r.len();
            for i in 0..n {
                let (a, b, c) = (r[(i + n - 1) % n], r[i], r[(i + 1) % n]);
                if a == b {
                    out.push(format!("{what} ring {ri}: repeated vertex {}", back(b)));
                } else if a == c {
                    out.push(format!("{what} ring {ri}: spike at {}", back(b)));
                } else if b != c {
                    let (u, v) = (
                        (b.0 - a.0, b.1 - a.1, b.2 - a.2),
                        (c.0 - b.0, c.1 - b.1, c.2 - b.2),
                    );
                    let cross = (
                        u.1 * v.2 - u.2 * v.1,
                        u.2 * v.0 - u.0 * v.2,
                        u.0 * v.1 - u.1 * v.0,
                    );
                    let dot = u.0 * v.0 + u.1 * v.1 + u.2 * v.2;
                    if cross == (0, 0, 0) && dot < 0 {
                        out.push(format!("{what} ring {ri}: spike at {}", back(b)));
                    }
                }
                if a != b {
                    *count.entry((a, b)).or_default() += 1;
                }
            }
        }
        let pts: Vec<Vec<DVec3>> = rings
            .iter()
            .map(|r| r.iter().map(|k| back(*k)).collect())
            .collect();
        let newell = crate::geometry::newell_normal(&pts[0]);
        if newell.length().is_nan() || newell.length() <= 1e-12 {
            out.push(format!("{what}: no area once rounded"));
            continue;
        }
        let normal = newell.normalize();
        let c = pts[0].iter().copied().sum::<DVec3>() / pts[0].len() as f64;
        // Against the least-squares plane, as val3dity measures it (203).
        let dev = crate::geometry::least_squares_plane_deviation(pts.iter().flatten());
        if dev > WRITTEN_PLANARITY {
            out.push(format!("{what}: not planar ({dev:.4} m)"));
        }
        // The rings in the face's plane: simple, and every triangle facing the same way.
        let (ex, ey) = crate::geometry::plane_axes(normal);
        for (ri, r) in pts.iter().enumerate() {
            let plan: Vec<DVec2> = r
                .iter()
                .map(|p| DVec2::new((*p - c).dot(ex), (*p - c).dot(ey)))
                .collect();
            if !crate::geometry::is_simple(&plan) {
                out.push(format!("{what} ring {ri}: touches itself once rounded"));
            }
        }
        if let Some(t) = crate::geometry::triangulate::triangulate_face(&pts[0], &pts[1..]) {
            for tri in &t.triangles {
                let [a, b, c] = tri.map(|i| t.vertices[i as usize]);
                let n = (b - a).cross(c - a);
                if n.length() > 0.0 && n.normalize().dot(normal) < min_cos {
                    out.push(format!(
                        "sliver: {what}: triangle {a} {b} {c} off the face's plane"
                    ));
                    break;
                }
            }
        }
    }
    for (&(a, b), &n) in &count {
        let rev = count.get(&(b, a)).copied().unwrap_or(0);
        if n != 1 || rev != 1 {
            out.push(format!(
                "rounded edge {} -> {} used {n} times, reverse {rev} times",
                back(a),
                back(b)
            ));
        }
    }
    out
}

/// Most distance (metres) of a part's vertex from its face's plane ([`check_part`]): a vertex
/// on the grid ([`grid`]) is half a millimetre step from where it was computed, and one merged
/// into a neighbour less than [`grid::MIN_GAP`] away.
pub(crate) const PLANAR_TOL: f64 = 0.01;

/// Most distance (metres) of a written face's vertex from the face's plane
/// ([`written_defects`]): val3dity's default planarity tolerance.
pub(crate) const WRITTEN_PLANARITY: f64 = 0.01;

/// Most angle (degrees) between a written face's normal and the normal of any of its triangles
/// ([`written_defects`]): val3dity's default normal deviation.
pub(crate) const WRITTEN_NORMAL_DEG: f64 = 20.0;

fn dist_to_boundary(p: &Polygon, q: DVec2) -> f64 {
    p.rings()
        .flat_map(|r| {
            (0..r.len()).map(move |i| {
                let (a, b) = (r[i], r[(i + 1) % r.len()]);
                let ab = b - a;
                let t = ((q - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
                q.distance(a + ab * t)
            })
        })
        .fold(f64::INFINITY, f64::min)
}

/// The footprint as a horizontal face at `z`, facing up (a roof) or down (a ground).
pub(crate) fn horizontal_face(footprint: &Polygon, z: f64, up: bool) -> Face {
    let ring = |r: &Vec<DVec2>, reverse: bool| {
        let mut v: Vec<DVec3> = r.iter().map(|p| at(*p, z)).collect();
        if reverse {
            v.reverse();
        }
        v
    };
    Face {
        outer: ring(&footprint.outer, !up),
        holes: footprint.holes.iter().map(|h| ring(h, !up)).collect(),
    }
}

fn translate_face(f: &Face, dz: f64) -> Face {
    let t = |r: &Vec<DVec3>| r.iter().map(|p| DVec3::new(p.x, p.y, p.z + dz)).collect();
    Face {
        outer: t(&f.outer),
        holes: f.holes.iter().map(t).collect(),
    }
}

fn at(p: DVec2, z: f64) -> DVec3 {
    DVec3::new(p.x, p.y, z)
}

#[cfg(test)]
mod tests;
