//! A hand-built LOD4 building shared by the writers' tests: the LOD3 exterior of
//! [`crate::export::lod3geom::samples`] plus an interior on each storey laid out as the model's
//! LOD4 contract says (rooms partition the usable area, interior walls centred on shared edges,
//! each once, doors inside their walls).

use glam::DVec2;

use crate::export::lod3geom::samples;
use crate::geometry::Polygon;
use crate::model::SourceId;
use crate::model::{Building, InteriorDoor, InteriorWall, Lod, Room, Stair, StoreyInterior};

fn rect(x0: f64, y0: f64, x1: f64, y1: f64) -> Vec<DVec2> {
    vec![
        DVec2::new(x0, y0),
        DVec2::new(x1, y0),
        DVec2::new(x1, y1),
        DVec2::new(x0, y1),
    ]
}

fn room(ring: Vec<DVec2>, usage: &str, name: &str) -> Room {
    Room {
        polygon: Polygon::new(ring, Vec::new()),
        usage: usage.into(),
        name: name.into(),
    }
}

/// A 12 x 8 m house with 2 storeys of 3 m (0.3 m exterior walls, usable area 0.3..11.7 x
/// 0.3..7.7). Each storey: a hall (x < 4.3, its east edge split at y = 4 by a collinear vertex)
/// and two rooms east of it (south and north of y = 4); three interior walls (hall/south,
/// hall/north, south/north), two doors (hall to each room, both on the hall's east side). The
/// ground storey's hall holds a stair (x 0.5..1.5, y 3..7.5, rising north, 17 risers of 3 m);
/// the upper storey has none. The front wall has a door into the hall and windows.
pub(crate) fn lod4_house() -> Building {
    let openings = [
        (0, 0, samples::door(1.8, 2.8, 0.02, 2.2)),
        (0, 0, samples::window(6.0, 7.2, 0.9, 2.2)),
        (2, 1, samples::window(3.0, 4.2, 3.9, 5.2)),
    ];
    let mut part = samples::part(
        "p0",
        Polygon::new(rect(0.0, 0.0, 12.0, 8.0), vec![]),
        vec![0.0, 3.0],
        6.0,
        &openings,
        &[],
    );
    let v = DVec2::new;
    let storey = |i: usize, floor_z: f64, ceiling_z: f64, stair: bool| StoreyInterior {
        storey: i,
        floor_z,
        ceiling_z,
        rooms: vec![
            room(
                vec![
                    v(0.3, 0.3),
                    v(4.3, 0.3),
                    v(4.3, 4.0),
                    v(4.3, 7.7),
                    v(0.3, 7.7),
                ],
                "hall",
                "Hall",
            ),
            room(rect(4.3, 0.3, 11.7, 4.0), "living room", "Living room"),
            room(rect(4.3, 4.0, 11.7, 7.7), "bedroom", "Bedroom 1"),
        ],
        walls: vec![
            InteriorWall {
                a: v(4.3, 0.3),
                b: v(4.3, 4.0),
                thickness: 0.1,
                rooms: [0, 1],
            },
            InteriorWall {
                a: v(4.3, 4.0),
                b: v(4.3, 7.7),
                thickness: 0.1,
                rooms: [0, 2],
            },
            InteriorWall {
                a: v(11.7, 4.0),
                b: v(4.3, 4.0),
                thickness: 0.1,
                rooms: [1, 2],
            },
        ],
        doors: vec![
            InteriorDoor {
                wall: 0,
                u0: 1.5,
                u1: 2.4,
                height: 2.1,
            },
            InteriorDoor {
                wall: 1,
                u0: 1.3,
                u1: 2.2,
                height: 2.1,
            },
        ],
        stair: stair.then(|| Stair {
            footprint: Polygon::new(rect(0.5, 3.0, 1.5, 7.5), vec![]),
            run: v(0.0, 1.0),
            rise: 3.0,
            risers: 17,
        }),
    };
    part.interior = vec![storey(0, 0.0, 2.8, true), storey(1, 3.0, 5.8, false)];
    let mut b = samples::building(SourceId::Way(401), vec![part]);
    b.name = Some("Maison \"LOD4\" & co".into());
    b.lod = Lod::Lod4;
    b
}

/// The LOD4 house and the LOD3 samples (exteriors only) as a LOD4 run would write them.
pub(crate) fn lod4_all() -> Vec<Building> {
    let mut all = vec![lod4_house()];
    for mut b in samples::all() {
        b.lod = Lod::Lod4;
        all.push(b);
    }
    all
}

/// A provenance as the estimator sets it: storeys and height from the shipped model, the roof
/// from the knowledge base, every uncertainty known (0.75 storeys, 2.25 m, 0.8).
pub(crate) fn model_provenance() -> crate::model::Provenance {
    use crate::model::ValueSource;
    crate::model::Provenance {
        storeys: ValueSource::Model,
        storeys_error: Some(0.75),
        height: ValueSource::Model,
        height_error: Some(2.25),
        roof: ValueSource::Kb,
        roof_probability: Some(0.8),
    }
}

/// The reference validator for the test `what` ([`crate::testkit::validators::validate_outputs`]:
/// skipped with a note where it is not installed, a failure under CI).
pub fn validator(what: &str) -> Option<std::path::PathBuf> {
    crate::testkit::validators::validate_outputs(what)
}
