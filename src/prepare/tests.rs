//! Tests of the preparation: cleaning, fronts, interior points, tiles.

use super::clean::{is_valid, merge_ring};
use super::fronts::{front_of, StreetSegment};
use super::*;
use crate::input::Streets;
use rstar::RTree;

fn sq(x0: f64, y0: f64, s: f64) -> Vec<DVec2> {
    vec![
        DVec2::new(x0, y0),
        DVec2::new(x0 + s, y0),
        DVec2::new(x0 + s, y0 + s),
        DVec2::new(x0, y0 + s),
    ]
}

#[test]
fn bow_tie_is_repaired_into_two_triangles() {
    let bow = vec![
        DVec2::new(0.0, 0.0),
        DVec2::new(10.0, 10.0),
        DVec2::new(10.0, 0.0),
        DVec2::new(0.0, 10.0),
    ];
    let p = Polygon {
        outer: bow,
        holes: vec![],
    };
    assert!(!is_valid(&p));
    let mut report = Report::default();
    let out = clean_polygons(SourceId::Way(1), vec![p], &mut report).unwrap();
    assert_eq!(out.len(), 2);
    let area: f64 = out.iter().map(Polygon::area).sum();
    assert!((area - 50.0).abs() < 1e-6, "{area}");
    assert_eq!(report.entries[0].outcome, Outcome::Repaired);
}

#[test]
fn duplicates_and_spikes_are_removed() {
    let mut r = sq(0.0, 0.0, 10.0);
    r.insert(1, DVec2::new(0.0, 0.0));
    r.insert(3, DVec2::new(15.0, 0.0)); // spike out of (10,0) and back
    r.insert(4, DVec2::new(10.0, 0.0));
    let (c, spikes) = merge_ring(&r).unwrap();
    assert_eq!(spikes, 1);
    assert_eq!(c.len(), 4, "{c:?}");
}

#[test]
fn sliver_is_skipped_with_a_reason() {
    let sliver = vec![
        DVec2::new(0.0, 0.0),
        DVec2::new(10.0, 0.0),
        DVec2::new(10.0, 0.01),
    ];
    let mut report = Report::default();
    let out = clean_polygons(
        SourceId::Way(2),
        vec![Polygon::new(sliver, vec![])],
        &mut report,
    );
    assert!(out.is_none());
    assert_eq!(report.entries[0].outcome, Outcome::Skipped);
    assert!(report.entries[0].reason.contains("smaller than"));
}

#[test]
fn courtyard_stays_a_hole() {
    let p = Polygon::new(sq(0.0, 0.0, 20.0), vec![sq(5.0, 5.0, 10.0)]);
    let mut report = Report::default();
    let out = clean_polygons(SourceId::Relation(3), vec![p], &mut report).unwrap();
    assert_eq!(out[0].holes.len(), 1);
    assert!((out[0].area() - 300.0).abs() < 1e-9);
    assert!(report.entries.is_empty());
}

/// The front of a 20 m × 10 m block at the origin with one street from `a` to `b`.
fn front_with_street(a: DVec2, b: DVec2) -> Option<DVec2> {
    let tree = RTree::bulk_load(vec![StreetSegment::road(a.to_array(), b.to_array())]);
    let block = Polygon::new(
        vec![
            DVec2::new(0.0, 0.0),
            DVec2::new(20.0, 0.0),
            DVec2::new(20.0, 10.0),
            DVec2::new(0.0, 10.0),
        ],
        vec![],
    );
    front_of(&[block], &tree, None, &|_| false)
}

#[test]
fn the_front_is_the_normal_of_the_edge_that_faces_the_nearest_street() {
    let v = DVec2::new;
    // Along the north side.
    assert_eq!(
        front_with_street(v(-50.0, 15.0), v(70.0, 15.0)),
        Some(DVec2::Y)
    );
    // A north-south street past the east end: the end wall faces it, not the long south
    // side, although both touch the corner nearest to the street.
    assert_eq!(
        front_with_street(v(25.0, -40.0), v(25.0, 50.0)),
        Some(DVec2::X)
    );
    // A street along the wall itself (a mapped sidewalk) counts.
    assert_eq!(
        front_with_street(v(-5.0, 0.0), v(25.0, 0.0)),
        Some(-DVec2::Y)
    );
    // Too far.
    assert_eq!(front_with_street(v(-50.0, 70.0), v(70.0, 70.0)), None);
}

/// A wall against another building does not face the street beyond it: the block's north
/// side touches a neighbour 0.2 m away, so its front is the east end, which faces the street
/// 30 m off, not the north side 20 m from the street behind the neighbour.
#[test]
fn a_wall_against_a_neighbour_is_no_front() {
    let v = DVec2::new;
    let tree = RTree::bulk_load(vec![StreetSegment::road([-10.0, 30.0], [50.0, 30.0])]);
    let block = Polygon::new(
        vec![v(0.0, 0.0), v(20.0, 0.0), v(20.0, 10.0), v(0.0, 10.0)],
        vec![],
    );
    let neighbour = Polygon::new(
        vec![v(-5.0, 10.2), v(25.0, 10.2), v(25.0, 20.0), v(-5.0, 20.0)],
        vec![],
    );
    let free = front_of(std::slice::from_ref(&block), &tree, None, &|_| false);
    assert_eq!(free, Some(DVec2::Y));
    let against = |p: DVec2| neighbour.contains(p);
    assert_eq!(
        front_of(std::slice::from_ref(&block), &tree, None, &against),
        None
    );
    let both: Vec<StreetSegment> = vec![
        StreetSegment::road([-10.0, 30.0], [50.0, 30.0]),
        StreetSegment::road([50.0, -20.0], [50.0, 40.0]),
    ];
    let both = RTree::bulk_load(both);
    assert_eq!(front_of(&[block], &both, None, &against), Some(DVec2::X));
}

#[test]
fn fronts_need_streets_and_do_not_move_the_lots() {
    let mut report = Report::default();
    let block = Polygon::new(sq(0.0, 0.0, 10.0), vec![]);
    let mut site = single_lot(block, (7.42, 43.73), None, &mut report).unwrap();
    let before = site.lots[0].polygons.clone();
    let crs = site.crs;
    assign_fronts(&mut site, &Streets::default(), Some(crs));
    assert_eq!(site.lots[0].front, None);
    // A west street in lon/lat (source CRS None = WGS84), projected like the footprints.
    let (x, y) = (site.origin.x - 12.0, site.origin.y);
    let a = crs.to_lonlat(x, y - 50.0);
    let b = crs.to_lonlat(x, y + 50.0);
    let mut streets = Streets::default();
    streets.push(&[a, b]);
    assign_fronts(&mut site, &streets, None);
    let f = site.lots[0].front.unwrap();
    assert!(f.dot(-DVec2::X) > 0.999, "{f}");
    assert_eq!(site.lots[0].polygons, before);
}

#[test]
fn interior_point_of_a_u_shape_is_inside() {
    let u = vec![
        DVec2::new(0.0, 0.0),
        DVec2::new(30.0, 0.0),
        DVec2::new(30.0, 20.0),
        DVec2::new(20.0, 20.0),
        DVec2::new(20.0, 5.0),
        DVec2::new(10.0, 5.0),
        DVec2::new(10.0, 20.0),
        DVec2::new(0.0, 20.0),
    ];
    let p = Polygon::new(u, vec![]);
    assert!(p.contains(interior_point(&p)));
}

#[test]
fn tiles_hold_every_lot_once_in_input_order_and_name_their_corner() {
    let crs = Crs::utm_for(7.42, 43.73);
    let lot = |i: i64, x: f64, y: f64| {
        let (lon, lat) = crs.to_lonlat(x, y);
        Lot {
            id: SourceId::Way(i),
            tags: Default::default(),
            polygons: vec![Polygon::new(sq(0.0, 0.0, 10.0), vec![])],
            parts: Vec::new(),
            drawn: None,
            rest_tags: None,
            lonlat: (lon, lat),
            front: None,
            ground: 0.0,
            terrain: None,
        }
    };
    // Input order mixes the tiles; 5 and 2 share a tile with 1, in that input order.
    let mut site = Site {
        crs,
        origin: DVec2::new(370_000.0, 4_842_000.0),
        origin_lonlat: crs.to_lonlat(370_000.0, 4_842_000.0),
        lots: vec![
            lot(1, 370_010.0, 4_842_010.0),
            lot(3, 370_260.0, 4_842_010.0),
            lot(4, 370_010.0, 4_842_260.0),
            lot(2, 370_240.0, 4_842_240.0),
            lot(5, 370_100.0, 4_842_100.0),
        ],
        boundaries: Vec::new(),
        elevation: None,
        vertical_datum: None,
        attributes: Default::default(),
    };
    let tiles = group_into_tiles(&mut site, 250);
    let ids: Vec<SourceId> = site.lots.iter().map(|l| l.id).collect();
    let way = SourceId::Way;
    assert_eq!(ids, vec![way(1), way(2), way(5), way(4), way(3)]);
    let names: Vec<(String, std::ops::Range<usize>)> = tiles
        .iter()
        .map(|t| (t.suffix(), t.range.clone()))
        .collect();
    assert_eq!(
        names,
        vec![
            ("370000_4842000".to_string(), 0..3),
            ("370000_4842250".to_string(), 3..4),
            ("370250_4842000".to_string(), 4..5),
        ]
    );
}
