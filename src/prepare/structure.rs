//! The structure class of every lot and piece (issue 45): what a footprint is when it is not a
//! house, decided once here from its tags and its size, and set on its parsed tags
//! ([`BuildingTags::structure`]) for `derive` to honour (no openings, no interior; a tower's
//! openings on its top storey only) and the writers to record. The table of tags is in
//! docs/structures.md; the rules, in order:
//!
//! 1. `building=roof|carport|canopy` (a part's `building:part=roof|canopy`): [`Structure::Roof`].
//! 2. The building (a part's `building:part`) value: `column|pillar` a column, `bridge` a
//!    bridge, `monument|memorial|obelisk|statue` a monument, `tower|bell_tower|campanile|
//!    minaret|steeple|lighthouse` a tower (`tower` only when it is no storeyed house: with a
//!    `tower:type`, in a place of worship, or without `building:levels`).
//! 3. `man_made=column` a column, `obelisk` a monument, `tower|lighthouse|water_tower` a tower,
//!    `bridge` a bridge; any `tower:type` a tower.
//! 4. `historic=monument|memorial` a monument when the building is no house: its value is
//!    `yes` (or none, or one of the monument values above) and it has at most one tagged
//!    storey (`building:levels` ≤ 1 or none). A historic house (`building=house|church|...`, or
//!    a storeyed `building=yes`) stays a house.
//! 5. A `building:part` with none of these takes its outline's class (the drums of a
//!    monumental column are the column's); an outline's uncovered rest takes the outline's.
//! 6. Anything else under [`SMALL_AREA`] square metres or narrower than [`SMALL_WIDTH`] holds
//!    no room: [`Structure::Small`].

use rayon::prelude::*;

use crate::geometry::Polygon;
use crate::input::{BuildingTags, SharedTags};
use crate::model::{Structure, SMALL_AREA, SMALL_WIDTH};
use crate::prepare::Lot;

/// Values of a place of worship's `building=*`: a `building:part=tower` in one is its tower.
const WORSHIP: [&str; 10] = [
    "church",
    "cathedral",
    "chapel",
    "basilica",
    "mosque",
    "temple",
    "synagogue",
    "shrine",
    "monastery",
    "religious",
];

/// Sets the structure class of every lot's tags, its pieces' and its rest's (rules in the
/// module docs). Lots of no structure keep their shared tags as they are.
pub(crate) fn classify(lots: &mut [Lot]) {
    lots.par_iter_mut().for_each(classify_lot);
}

/// [`classify`] of one lot.
pub(crate) fn classify_lot(lot: &mut Lot) {
    let outline = own_class(&lot.tags, None).or_else(|| small(&lot.polygons));
    let inherited = outline.filter(|c| *c != Structure::Small);
    let worship = lot
        .tags
        .building
        .as_deref()
        .is_some_and(|b| WORSHIP.contains(&b));
    for piece in &mut lot.parts {
        let class = own_class(&piece.tags, Some(worship))
            .or(inherited)
            .or_else(|| small(&piece.polygons));
        piece.tags = with_class(&piece.tags, class);
    }
    if let Some(rest) = &lot.rest_tags {
        let class = inherited.or_else(|| small(lot.drawn_outline()));
        lot.rest_tags = Some(with_class(rest, class));
    }
    lot.tags = with_class(&lot.tags, outline);
}

/// `tags` with `class` set: the same shared tags when nothing changes.
fn with_class(tags: &SharedTags, class: Option<Structure>) -> SharedTags {
    if tags.structure == class {
        return tags.clone();
    }
    let mut t = BuildingTags::clone(tags);
    t.structure = class;
    SharedTags::new(t)
}

/// [`Structure::Small`] when the polygons hold no room: under [`SMALL_AREA`] in all, or
/// narrower than [`SMALL_WIDTH`] across their principal axis.
fn small(polygons: &[Polygon]) -> Option<Structure> {
    let area: f64 = polygons.iter().map(|p| p.area().abs()).sum();
    let points: Vec<glam::DVec2> = polygons.iter().flat_map(|p| p.outer.clone()).collect();
    let (width, _) = crate::prepare::morph::extents(&points);
    (area < SMALL_AREA || width < SMALL_WIDTH).then_some(Structure::Small)
}

/// The class the tags alone give (rules 1-4 of the module docs); `worship`: for a part, whether
/// its outline is a place of worship (`None` for an outline).
fn own_class(t: &BuildingTags, worship: Option<bool>) -> Option<Structure> {
    if t.is_roof() {
        return Some(Structure::Roof);
    }
    // A part's own value says what the part is; `building` when it has none.
    let value = t.building_part.as_deref().or(t.building.as_deref());
    let storeyed = t.levels.is_some_and(|l| l > 1.0);
    let by_value = match value {
        Some("column" | "pillar") => Some(Structure::Column),
        Some("bridge") => Some(Structure::Bridge),
        Some("monument" | "memorial" | "obelisk" | "statue") => Some(Structure::Monument),
        Some("bell_tower" | "campanile" | "minaret" | "steeple" | "lighthouse") => {
            Some(Structure::Tower)
        }
        Some("tower") if t.tower_type.is_some() || worship == Some(true) || t.levels.is_none() => {
            Some(Structure::Tower)
        }
        _ => None,
    };
    let by_man_made = match t.man_made.as_deref() {
        Some("column") => Some(Structure::Column),
        Some("obelisk") => Some(Structure::Monument),
        Some("tower" | "lighthouse" | "water_tower") => Some(Structure::Tower),
        Some("bridge") => Some(Structure::Bridge),
        _ => None,
    };
    let by_tower = t.tower_type.as_ref().map(|_| Structure::Tower);
    let monument_like = matches!(
        value,
        None | Some("yes" | "no" | "monument" | "memorial" | "obelisk" | "statue" | "column")
    );
    let by_historic = matches!(t.historic.as_deref(), Some("monument" | "memorial"))
        .then_some(Structure::Monument)
        .filter(|_| monument_like && !storeyed);
    by_value.or(by_man_made).or(by_tower).or(by_historic)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tags(pairs: &[(&str, &str)]) -> BuildingTags {
        BuildingTags::from_pairs(pairs.iter().copied())
    }

    #[test]
    fn the_tags_decide_the_class() {
        type Case<'a> = (&'a [(&'a str, &'a str)], Option<Structure>);
        let cases: &[Case<'_>] = &[
            (&[("building", "yes")], None),
            (&[("building", "roof")], Some(Structure::Roof)),
            (&[("building", "carport")], Some(Structure::Roof)),
            (&[("building:part", "canopy")], Some(Structure::Roof)),
            (
                &[("building", "yes"), ("man_made", "column")],
                Some(Structure::Column),
            ),
            (&[("building:part", "pillar")], Some(Structure::Column)),
            (
                &[("building", "yes"), ("man_made", "obelisk")],
                Some(Structure::Monument),
            ),
            (&[("building", "bridge")], Some(Structure::Bridge)),
            (
                &[("building", "yes"), ("man_made", "tower")],
                Some(Structure::Tower),
            ),
            (
                &[("building", "yes"), ("man_made", "lighthouse")],
                Some(Structure::Tower),
            ),
            (&[("building", "bell_tower")], Some(Structure::Tower)),
            (
                &[("building", "yes"), ("historic", "monument")],
                Some(Structure::Monument),
            ),
            (
                &[("building", "yes"), ("historic", "memorial")],
                Some(Structure::Monument),
            ),
            // A historic house stays a house.
            (&[("building", "house"), ("historic", "monument")], None),
            (&[("building", "church"), ("historic", "monument")], None),
            (
                &[
                    ("building", "yes"),
                    ("historic", "monument"),
                    ("building:levels", "3"),
                ],
                None,
            ),
            // An office tower with storeys is a building.
            (&[("building", "tower"), ("building:levels", "30")], None),
            (
                &[("building:part", "tower"), ("tower:type", "bell_tower")],
                Some(Structure::Tower),
            ),
        ];
        for (pairs, want) in cases {
            assert_eq!(own_class(&tags(pairs), None), *want, "{pairs:?}");
        }
        let storeyed_tower = tags(&[("building:part", "tower"), ("building:levels", "5")]);
        assert_eq!(own_class(&storeyed_tower, Some(false)), None);
        assert_eq!(
            own_class(&storeyed_tower, Some(true)),
            Some(Structure::Tower),
            "a church's tower"
        );
    }

    #[test]
    fn small_footprints_hold_no_room() {
        let rect = |w: f64, d: f64| {
            Polygon::new(
                vec![
                    glam::DVec2::new(0.0, 0.0),
                    glam::DVec2::new(w, 0.0),
                    glam::DVec2::new(w, d),
                    glam::DVec2::new(0.0, d),
                ],
                vec![],
            )
        };
        assert_eq!(small(&[rect(1.5, 2.0)]), Some(Structure::Small));
        assert_eq!(small(&[rect(1.2, 10.0)]), Some(Structure::Small));
        assert_eq!(small(&[rect(2.0, 2.5)]), None);
        assert_eq!(small(&[rect(10.0, 8.0)]), None);
    }
}
