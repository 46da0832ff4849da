//! LOD3 facades: what a derived mass says about its storeys and about the windows, doors and
//! balconies of each wall, in wall coordinates.
//!
//! The grammar's `comp` makes one side face per footprint edge of each storey; subdivisions of
//! those faces end in `window`, `door`, `balcony` and `wall` terminals. [`facades_of`] finds, for
//! every such terminal, the footprint edge it stands on and its place along that edge. Pieces
//! that are not on a footprint edge (a face turned by `R`, the inner faces where a `split` cut
//! the mass) are not on the envelope and are counted in [`Facades::off_envelope`].

use glam::{DVec2, DVec3};

use crate::color::Color;
use crate::geometry::Polygon;
use crate::grammar::{AttrValue, FaceKind, Geometry, Label, ShapeNode, ShapeTree, Terminal};
pub use crate::model::OpeningKind;

/// How far (metres) a face may be from a footprint edge and still stand on it.
const ON_EDGE: f64 = 0.01;

/// A storey of a mass: its floor and ceiling heights.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Level {
    pub z0: f64,
    pub z1: f64,
}

/// A window or door found on a wall: `u0..u1` along the footprint edge from its start (metres),
/// `z0..z1` absolute heights, and the terminal's attributes.
#[derive(Clone, Debug, PartialEq)]
pub struct FoundOpening {
    pub kind: OpeningKind,
    pub u0: f64,
    pub u1: f64,
    pub z0: f64,
    pub z1: f64,
    /// `color` attribute (glass or panel colour).
    pub color: Option<Color>,
    /// `framecolor` attribute.
    pub frame_color: Option<Color>,
    /// `material=glass`.
    pub glazed: bool,
    /// `style=framed`.
    pub framed: bool,
}

/// A balcony found on a wall: the facade piece it belongs to.
#[derive(Clone, Debug, PartialEq)]
pub struct FoundBalcony {
    pub u0: f64,
    pub u1: f64,
    pub z0: f64,
    pub z1: f64,
    pub color: Option<Color>,
}

/// The facade details of one mass.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Facades {
    /// Storeys from bottom to top (one level spanning the mass when the rules make none).
    pub levels: Vec<Level>,
    /// Openings per footprint edge, edges numbered in ring order (outer ring first).
    pub openings: Vec<Vec<FoundOpening>>,
    /// Balconies per footprint edge.
    pub balconies: Vec<Vec<FoundBalcony>>,
    /// Opening and balcony terminals that stand on no footprint edge.
    pub off_envelope: usize,
}

/// One footprint edge in the local frame.
struct Edge {
    start: DVec2,
    dir: DVec2,
    len: f64,
}

/// Reads the levels and the openings of the mass at node `mass` of `tree`, whose footprint is
/// `footprint` and whose walls span `z0..z1`.
pub fn facades_of(tree: &ShapeTree, mass: usize, footprint: &Polygon, z0: f64, z1: f64) -> Facades {
    let edges: Vec<Edge> = footprint
        .rings()
        .flat_map(|r| {
            (0..r.len()).map(move |i| {
                let (a, b) = (r[i], r[(i + 1) % r.len()]);
                let len = a.distance(b);
                Edge {
                    start: a,
                    dir: if len > 0.0 { (b - a) / len } else { DVec2::X },
                    len,
                }
            })
        })
        .collect();
    let mut out = Facades {
        levels: Vec::new(),
        openings: vec![Vec::new(); edges.len()],
        balconies: vec![Vec::new(); edges.len()],
        off_envelope: 0,
    };
    let mut stack = vec![mass];
    while let Some(i) = stack.pop() {
        let node = &tree.nodes[i];
        if i != mass && matches!(node.label, Label::Building | Label::BuildingPart) {
            continue; // another mass: its facades are its own
        }
        if node.label == Label::Storey {
            if let Geometry::Volume { z0, height, .. } = node.geometry {
                // A storey inside another storey's range (a room cut) adds nothing.
                out.levels.push(Level {
                    z0,
                    z1: z0 + height,
                });
            }
        }
        if let Some(t) = node.terminal {
            match t {
                Terminal::Window | Terminal::Door | Terminal::Balcony => {
                    place(node, t, &edges, &mut out)
                }
                Terminal::Wall | Terminal::Other => {}
            }
        }
        stack.extend(node.children.clone().rev());
    }
    out.levels = levels(out.levels, z0, z1);
    for v in &mut out.openings {
        v.sort_by(|a, b| a.z0.total_cmp(&b.z0).then(a.u0.total_cmp(&b.u0)));
    }
    out
}

/// Storey ranges sorted and de-duplicated (nested room cuts dropped); one level over the whole
/// wall when there are none.
fn levels(mut found: Vec<Level>, z0: f64, z1: f64) -> Vec<Level> {
    found.sort_by(|a, b| a.z0.total_cmp(&b.z0).then(b.z1.total_cmp(&a.z1)));
    let mut out: Vec<Level> = Vec::with_capacity(found.len());
    for l in found {
        if l.z1 - l.z0 <= ON_EDGE {
            continue;
        }
        match out.last() {
            Some(last) if l.z0 < last.z1 - ON_EDGE => {} // nested or overlapping: keep the first
            _ => out.push(l),
        }
    }
    if out.is_empty() {
        out.push(Level { z0, z1 });
    }
    out
}

/// Finds the footprint edge a terminal face stands on and records it there.
fn place(node: &ShapeNode, t: Terminal, edges: &[Edge], out: &mut Facades) {
    let Geometry::Face {
        kind: FaceKind::Side,
        origin,
        x_axis,
        z_axis,
        width,
        height,
        ..
    } = node.geometry
    else {
        out.off_envelope += 1;
        return;
    };
    if (z_axis - DVec3::Z).length() > 1e-6 || width <= 0.0 || height <= 0.0 {
        out.off_envelope += 1;
        return;
    }
    let o = DVec2::new(origin.x, origin.y);
    let x = DVec2::new(x_axis.x, x_axis.y);
    let found = edges.iter().enumerate().find_map(|(k, e)| {
        let along = (o - e.start).dot(e.dir);
        let off = (o - e.start).perp_dot(e.dir).abs();
        let parallel = x.dot(e.dir) > 1.0 - 1e-6;
        (parallel && off <= ON_EDGE && along >= -ON_EDGE && along + width <= e.len + ON_EDGE)
            .then_some((k, along))
    });
    let Some((k, u0)) = found else {
        out.off_envelope += 1;
        return;
    };
    let text = |key: &str| match node.attrs.get(key) {
        Some(AttrValue::Str(s)) => Some(s.to_string()),
        Some(AttrValue::Num(n)) => Some(n.to_string()),
        None => None,
    };
    let color = text("color").and_then(|c| Color::parse(&c));
    let u0 = u0.max(0.0);
    let u1 = (u0 + width).min(edges[k].len);
    let (z0, z1) = (origin.z, origin.z + height);
    match t {
        Terminal::Balcony => out.balconies[k].push(FoundBalcony {
            u0,
            u1,
            z0,
            z1,
            color,
        }),
        _ => out.openings[k].push(FoundOpening {
            kind: if t == Terminal::Door {
                OpeningKind::Door
            } else {
                OpeningKind::Window
            },
            u0,
            u1,
            z0,
            z1,
            color,
            frame_color: text("framecolor").and_then(|c| Color::parse(&c)),
            glazed: text("material").is_some_and(|m| m.eq_ignore_ascii_case("glass")),
            framed: text("style").is_some_and(|s| s.eq_ignore_ascii_case("framed")),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::derive::mass_nodes;
    use crate::grammar::{derive, parse, Attrs, Caps};
    use crate::rng::Rng;

    fn rect(w: f64, d: f64) -> Polygon {
        let v = DVec2::new;
        Polygon::new(vec![v(0.0, 0.0), v(w, 0.0), v(w, d), v(0.0, d)], vec![])
    }

    #[test]
    fn a_simple_facade_gives_storeys_and_one_window_per_bay() {
        let rules = parse(
            "lot -> extrude(9){building}\n\
             building -> repeat(Z, 3){floor}\n\
             floor -> comp(){front: groundfront | others: facade}\n\
             facade -> repeat(X, 2){bay}\n\
             bay -> rsplit(X, 0.25, 0.5, 0.25){wall | col | wall}\n\
             col -> rsplit(Z, 0.3, 0.5, 0.2){wall | window: material=glass, color=lightblue | wall}\n\
             groundfront -> split(X, 4, 1.2, 4.8){facade | door: color=brown | facade}\n",
            "t.cga",
        )
        .unwrap();
        let lot = rect(10.0, 6.0);
        let tree = derive(
            &rules,
            &lot,
            Attrs::new(),
            &mut Rng::new(1, 1),
            &Caps::default(),
        )
        .unwrap();
        let masses = mass_nodes(&tree);
        assert_eq!(masses.len(), 1);
        let f = facades_of(&tree, masses[0], &lot, 0.0, 9.0);
        assert_eq!(f.levels.len(), 3);
        assert!((f.levels[1].z0 - 3.0).abs() < 1e-9 && (f.levels[2].z1 - 9.0).abs() < 1e-9);
        assert_eq!(f.off_envelope, 0);
        let doors: Vec<&FoundOpening> = f
            .openings
            .iter()
            .flatten()
            .filter(|o| o.kind == OpeningKind::Door)
            .collect();
        assert_eq!(doors.len(), 3, "one door on the front of each storey");
        // The front is the south edge (edge 0, from (0,0) to (10,0)): the door sits 4 m along it.
        assert!(f.openings[0].iter().any(|o| o.kind == OpeningKind::Door
            && (o.u0 - 4.0).abs() < 1e-9
            && (o.u1 - 5.2).abs() < 1e-9));
        let d = doors[0];
        assert_eq!(d.color, Color::parse("brown"));
        // Windows: the 6 m sides get 3 bays, the 10 m back gets 5, per storey; the front's
        // two facade pieces (4 m and 4.8 m) get 2 each.
        let windows = f
            .openings
            .iter()
            .flatten()
            .filter(|o| o.kind == OpeningKind::Window)
            .count();
        assert_eq!(windows, 3 * (3 + 3 + 5 + 2 + 2));
        for (k, ops) in f.openings.iter().enumerate() {
            let len = [10.0, 6.0, 10.0, 6.0][k];
            for o in ops {
                assert!(o.u0 >= 0.0 && o.u1 <= len + 1e-9 && o.u0 < o.u1, "{o:?}");
                assert!(o.z0 >= 0.0 && o.z1 <= 9.0 + 1e-9 && o.z0 < o.z1, "{o:?}");
            }
        }
        assert!(f.openings[1].iter().all(|o| o.glazed));
    }

    #[test]
    fn without_storeys_one_level_spans_the_wall() {
        let rules = parse("lot -> extrude(5){building}\n", "t.cga").unwrap();
        let lot = rect(8.0, 8.0);
        let tree = derive(
            &rules,
            &lot,
            Attrs::new(),
            &mut Rng::new(1, 1),
            &Caps::default(),
        )
        .unwrap();
        let f = facades_of(&tree, 1, &lot, 0.0, 5.0);
        assert_eq!(f.levels, vec![Level { z0: 0.0, z1: 5.0 }]);
        assert!(f.openings.iter().all(Vec::is_empty));
    }
}
