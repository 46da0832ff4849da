//! Admin boundaries (`boundary=administrative`, `admin_level` 2..=10) assembled from the
//! relations and closed ways the passes kept, with the multipolygon assembly of the
//! footprints.
//!
//! An extract cut by a box holds many boundaries in part only (a country's ring runs out of
//! the box): a relation is kept with the rings that close when no `inner` member is lost
//! (`partial` in the report), and dropped when none closes or a hole is lost (`incomplete`).
//! A lost hole would put an enclave's buildings in the country around it.

use super::*;
use crate::input::AdminBoundary;
use crate::report::Boundaries;

/// The boundaries of `rels` ([`RelKind::Boundary`]) and of the closed boundary ways, sorted
/// by id (ways, then relations). Counts them into `report.boundaries` (left `None` when the
/// input holds no boundary at all).
pub(super) fn admin_boundaries(
    ways: &Ways,
    rels: &[RelRec],
    nodes: &Nodes,
    report: &mut Report,
) -> Vec<AdminBoundary> {
    let mut out = Vec::new();
    let mut counts = Boundaries::default();
    for (id, tags) in &ways.boundaries {
        let Some(w) = ways.find(*id) else { continue };
        let ring = resolve(ways.refs(w), nodes).ok().and_then(|mut r| {
            ring::dedup_by(&mut r, |a, b| a == b);
            (ring_problem(&r).is_none() && lonlat_problem(&r).is_none()).then_some(r)
        });
        match ring {
            Some(r) => out.extend(boundary(
                SourceId::Way(*id),
                tags,
                vec![oriented_polygon(r, Vec::new())],
            )),
            None => counts.incomplete.push(SourceId::Way(*id).to_string()),
        }
    }
    // Each relation on its own: the large ones (a country's thousands of member ways) are the
    // costly part, and they are few.
    let built: Vec<(i64, Assembled)> = rels
        .par_iter()
        .filter(|r| r.kind == RelKind::Boundary)
        .map(|r| (r.id, assemble_relation(r, ways, nodes)))
        .collect();
    let by_id = |id: i64| {
        rels.binary_search_by_key(&id, |r| r.id)
            .ok()
            .map(|i| &rels[i])
    };
    for (id, a) in built {
        let sid = SourceId::Relation(id);
        if a.polygons.is_empty() || a.inner_lost {
            counts.incomplete.push(sid.to_string());
            continue;
        }
        if !a.whole {
            counts.partial.push(sid.to_string());
        }
        let polygons = a
            .polygons
            .into_iter()
            .map(|(o, h, _)| oriented_polygon(o, h))
            .collect();
        if let Some(rel) = by_id(id) {
            out.extend(boundary(sid, &rel.tags, polygons));
        }
    }
    counts.read = out.len();
    if counts.read > 0 || !counts.incomplete.is_empty() {
        report.boundaries = Some(counts);
    }
    out
}

/// The boundary of these tags ([`BOUNDARY_KEYS`]) and polygons; `None` without a usable
/// `admin_level` (the passes keep only boundaries with one).
fn boundary(id: SourceId, tags: &Tags, polygons: Vec<SourcePolygon>) -> Option<AdminBoundary> {
    let get = |key: &str| {
        tags.iter()
            .find(|(k, v)| k == key && !v.is_empty())
            .map(|(_, v)| v.clone())
    };
    let admin_level = get("admin_level")?.parse().ok()?;
    let mut names: Vec<String> = Vec::new();
    for key in ["name", "name:en", "int_name"] {
        if let Some(n) = get(key).filter(|n| !names.contains(n)) {
            names.push(n);
        }
    }
    Some(AdminBoundary {
        id,
        admin_level,
        names,
        iso3166_1: get("ISO3166-1").or_else(|| get("ISO3166-1:alpha2")),
        iso3166_2: get("ISO3166-2"),
        polygons,
    })
}
