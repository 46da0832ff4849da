//! A corpus of hard footprints built in code: near-rectangles skewed by hundredths of a degree,
//! rectangles with collinear vertices, thin strips, combs, stars, regular polygons, holes near
//! the outline, millimetre edges and mirror-symmetric shapes whose events are simultaneous.
//! Every hipped, gabled and mansard roof must build (no flat fallback) and pass the part checks
//! (as built and as written to the millimetre); every gabled end that the shape defines (both
//! ends of a rectangle, every wing of an L, T, U, H or cross) must be a gable.

use glam::{DVec2, DVec3};

use super::check_shape;
use crate::derive::massing::{build_part, roof_geometry, written_defects, Mass};
use crate::derive::roof::RoofGeometry;
use crate::geometry::Polygon;
use crate::model::{Lod, RoofShape};

fn rot(pts: &[DVec2], angle: f64, at: DVec2) -> Vec<DVec2> {
    let (s, c) = angle.sin_cos();
    pts.iter()
        .map(|p| DVec2::new(c * p.x - s * p.y, s * p.x + c * p.y) + at)
        .collect()
}

/// A rectangle `l × w` whose corners are turned off 90° by `skew_deg` (a quadrilateral with
/// one side turned about its start by `skew_deg` and the opposite side by `-skew_deg / 2`).
fn near_rectangle(l: f64, w: f64, skew_deg: f64) -> Vec<DVec2> {
    let k = skew_deg.to_radians().tan();
    vec![
        DVec2::new(0.0, 0.0),
        DVec2::new(l, 0.0),
        DVec2::new(l + w * k, w),
        DVec2::new(-0.5 * w * k, w + 0.5 * l * k),
    ]
}

/// Footprints whose gabled roof must have exactly `ends` gable walls and `planes` roof planes
/// (`None`: not checked), with a name.
fn gable_cases() -> Vec<(String, Polygon, usize, Option<usize>)> {
    let mut out = Vec::new();
    let sizes = [
        (12.0, 6.0),
        (10.0, 9.9),
        (30.0, 4.0),
        (8.0, 7.0),
        (100.0, 0.6),
    ];
    let angles = [0.0, 0.3, 1.0, 2.0];
    for &(l, w) in &sizes {
        for skew in [0.0, 0.01, 0.05, 0.1, 0.3, 1.0, -0.05, -0.5] {
            for &a in &angles {
                let r = rot(&near_rectangle(l, w, skew), a, DVec2::new(3.0, -7.0));
                out.push((
                    format!("near-rectangle {l}x{w} skew {skew} angle {a}"),
                    Polygon::new(r, vec![]),
                    2,
                    Some(2),
                ));
            }
        }
        // A collinear vertex on a long side (or on a short side), anywhere along it.
        for f in [0.001, 0.05, 0.2, 0.5, 0.83, 0.999] {
            for side in 0..4 {
                // Footprints are cleaned to the millimetre (`prepare`): no shorter edge.
                let len = if side % 2 == 0 { l } else { w };
                if f * len < 2e-3 || (1.0 - f) * len < 2e-3 {
                    continue;
                }
                let mut r = vec![
                    DVec2::new(0.0, 0.0),
                    DVec2::new(l, 0.0),
                    DVec2::new(l, w),
                    DVec2::new(0.0, w),
                ];
                let (a, b) = (r[side], r[(side + 1) % 4]);
                r.insert(side + 1, a + (b - a) * f);
                out.push((
                    format!("rectangle {l}x{w} vertex at {f} of side {side}"),
                    Polygon::new(rot(&r, 0.4, DVec2::ZERO), vec![]),
                    2,
                    Some(2),
                ));
            }
        }
    }
    // A collinear vertex 0.5 mm off the line, and two on one side.
    out.push((
        "rectangle with a vertex 0.5 mm off a long side".into(),
        Polygon::new(
            vec![
                DVec2::new(0., 0.),
                DVec2::new(7.3, -0.0005),
                DVec2::new(14., 0.),
                DVec2::new(14., 6.),
                DVec2::new(0., 6.),
            ],
            vec![],
        ),
        2,
        None,
    ));
    out.push((
        "rectangle with two collinear vertices on each long side".into(),
        Polygon::new(
            vec![
                DVec2::new(0., 0.),
                DVec2::new(3., 0.),
                DVec2::new(9., 0.),
                DVec2::new(14., 0.),
                DVec2::new(14., 6.),
                DVec2::new(10., 6.),
                DVec2::new(2., 6.),
                DVec2::new(0., 6.),
            ],
            vec![],
        ),
        2,
        Some(2),
    ));
    // Wings: L, T, U, H and a cross, wings at least twice as long as wide, each end a gable.
    let p = |v: &[(f64, f64)]| v.iter().map(|&(x, y)| DVec2::new(x, y)).collect::<Vec<_>>();
    let letters: Vec<(&str, Vec<DVec2>, usize)> = vec![
        (
            "L",
            p(&[
                (0., 0.),
                (20., 0.),
                (20., 6.),
                (6., 6.),
                (6., 18.),
                (0., 18.),
            ]),
            2,
        ),
        (
            "T",
            p(&[
                (7., 0.),
                (13., 0.),
                (13., 14.),
                (20., 14.),
                (20., 20.),
                (0., 20.),
                (0., 14.),
                (7., 14.),
            ]),
            3,
        ),
        (
            "U",
            p(&[
                (0., 0.),
                (24., 0.),
                (24., 18.),
                (18., 18.),
                (18., 6.),
                (6., 6.),
                (6., 18.),
                (0., 18.),
            ]),
            2,
        ),
        (
            "H",
            p(&[
                (0., 0.),
                (6., 0.),
                (6., 9.),
                (14., 9.),
                (14., 0.),
                (20., 0.),
                (20., 24.),
                (14., 24.),
                (14., 15.),
                (6., 15.),
                (6., 24.),
                (0., 24.),
            ]),
            4,
        ),
        (
            "cross",
            p(&[
                (7., 0.),
                (13., 0.),
                (13., 7.),
                (20., 7.),
                (20., 13.),
                (13., 13.),
                (13., 20.),
                (7., 20.),
                (7., 13.),
                (0., 13.),
                (0., 7.),
                (7., 7.),
            ]),
            4,
        ),
    ];
    for (name, r, ends) in letters {
        for &a in &[0.0, 0.7, 2.1] {
            out.push((
                format!("{name} angle {a}"),
                Polygon::new(rot(&r, a, DVec2::new(-4.0, 9.0)), vec![]),
                ends,
                None,
            ));
        }
    }
    out
}

/// Footprints that must get every roof, but whose gable ends are not counted.
fn hard_cases() -> Vec<(String, Polygon)> {
    let mut out: Vec<(String, Polygon)> = gable_cases()
        .into_iter()
        .map(|(n, p, _, _)| (n, p))
        .collect();
    let p = |v: &[(f64, f64)]| v.iter().map(|&(x, y)| DVec2::new(x, y)).collect::<Vec<_>>();
    for n in [3, 4, 5, 6, 7, 8, 12, 16, 17, 32, 64, 200] {
        for r in [0.8, 5.0, 40.0] {
            let ring: Vec<DVec2> = (0..n)
                .map(|i| {
                    let a = (i as f64 + 0.25) / n as f64 * std::f64::consts::TAU;
                    DVec2::new(a.cos(), a.sin()) * r
                })
                .collect();
            out.push((format!("regular {n}-gon r {r}"), Polygon::new(ring, vec![])));
        }
    }
    for n in [5, 8, 13] {
        let ring: Vec<DVec2> = (0..2 * n)
            .map(|i| {
                let a = i as f64 / (2 * n) as f64 * std::f64::consts::TAU;
                DVec2::new(a.cos(), a.sin()) * if i % 2 == 0 { 10.0 } else { 4.0 }
            })
            .collect();
        out.push((format!("{n}-pointed star"), Polygon::new(ring, vec![])));
    }
    for (l, w) in [(100.0, 0.5), (60.0, 0.2), (40.0, 0.05), (300.0, 3.0)] {
        out.push((
            format!("strip {l}x{w}"),
            Polygon::new(p(&[(0., 0.), (l, 0.), (l, w), (0., w)]), vec![]),
        ));
        out.push((
            format!("skewed strip {l}x{w}"),
            Polygon::new(near_rectangle(l, w, 0.02), vec![]),
        ));
    }
    // Combs with equal teeth (simultaneous events) and with teeth of one step more each.
    for (teeth, grow) in [(6, 0.0), (12, 0.0), (8, 0.5)] {
        let mut r = vec![
            DVec2::new(0.0, 0.0),
            DVec2::new(4.0 * teeth as f64 - 1.0, 0.0),
        ];
        for i in (0..teeth).rev() {
            let x = i as f64 * 4.0;
            let h = 10.0 + grow * i as f64;
            r.push(DVec2::new(x + 3.0, 3.0));
            r.push(DVec2::new(x + 3.0, h));
            r.push(DVec2::new(x, h));
            if i > 0 {
                r.push(DVec2::new(x, 3.0));
            }
        }
        out.push((format!("comb {teeth} grow {grow}"), Polygon::new(r, vec![])));
    }
    // Holes near the outline (5 cm and 1 cm of wall), and several holes in a row.
    let outer = p(&[(0., 0.), (20., 0.), (20., 12.), (0., 12.)]);
    for gap in [0.05, 0.01, 1.0] {
        out.push((
            format!("hole {gap} m from the outline"),
            Polygon::new(
                outer.clone(),
                vec![p(&[(gap, gap), (8., gap), (8., 6.), (gap, 6.)])],
            ),
        ));
    }
    out.push((
        "three courtyards".into(),
        Polygon::new(
            outer.clone(),
            (0..3)
                .map(|i| {
                    let x = 1.0 + 6.5 * i as f64;
                    p(&[(x, 4.), (x + 5., 4.), (x + 5., 8.), (x, 8.)])
                })
                .collect(),
        ),
    ));
    // Millimetre edges: a chamfered corner, a notch and a step of 1 mm.
    out.push((
        "1 mm chamfer".into(),
        Polygon::new(
            p(&[(0., 0.), (12., 0.), (12., 5.999), (11.999, 6.), (0., 6.)]),
            vec![],
        ),
    ));
    out.push((
        "1 mm step".into(),
        Polygon::new(
            p(&[
                (0., 0.),
                (6., 0.),
                (6., 0.001),
                (12., 0.001),
                (12., 6.),
                (0., 6.),
            ]),
            vec![],
        ),
    ));
    out.push((
        "1 mm notch".into(),
        Polygon::new(
            p(&[
                (0., 0.),
                (6., 0.),
                (6., 0.001),
                (6.001, 0.001),
                (6.001, 0.),
                (12., 0.),
                (12., 6.),
                (0., 6.),
            ]),
            vec![],
        ),
    ));
    // Mirror-symmetric shapes: a stepped pyramid plan and an octagon with a square hole.
    out.push((
        "stepped symmetric".into(),
        Polygon::new(
            p(&[
                (0., 0.),
                (30., 0.),
                (30., 10.),
                (25., 10.),
                (25., 15.),
                (20., 15.),
                (20., 20.),
                (10., 20.),
                (10., 15.),
                (5., 15.),
                (5., 10.),
                (0., 10.),
            ]),
            vec![],
        ),
    ));
    let oct: Vec<DVec2> = (0..8)
        .map(|i| {
            let a = (i as f64 + 0.5) / 8.0 * std::f64::consts::TAU;
            DVec2::new(a.cos(), a.sin()) * 15.0
        })
        .collect();
    out.push((
        "octagon with a centred square hole".into(),
        Polygon::new(oct, vec![p(&[(-4., -4.), (4., -4.), (4., 4.), (-4., 4.)])]),
    ));
    out
}

fn gabled(p: &Polygon, roof: RoofShape) -> Result<(RoofGeometry, Vec<String>), String> {
    let m = Mass {
        footprint: p.clone(),
        base_z: 0.0,
        eave_z: 5.0,
        storeys: 2,
        roof,
        roof_angle_deg: 40.0,
        roof_direction: None,
        roof_across: false,
        roof_height: None,
        wall_color: crate::color::Color::WHITE,
        roof_color: crate::color::Color::GREY,
    };
    let r = roof_geometry(&m).map_err(|f| f.reason)?;
    let part = build_part("p0".into(), &m, &r, Lod::Lod2);
    let w = written_defects(&part, DVec3::new(500_000.0, 4_000_000.0, 0.0))
        .into_iter()
        .filter(|l| !l.starts_with("sliver:"))
        .collect();
    Ok((r, w))
}

#[test]
fn every_end_of_a_rectangle_or_wing_is_a_gable() {
    let mut bad = Vec::new();
    let shapes = [
        (RoofShape::Gabled, 1),
        (RoofShape::HalfHipped, 2),
        (RoofShape::Gambrel, 2),
    ];
    for ((name, p, ends, planes), (shape, per_side)) in gable_cases()
        .into_iter()
        .flat_map(|c| shapes.iter().map(move |s| (c.clone(), *s)))
    {
        let name = format!("{name} {shape:?}");
        let planes = planes.map(|n| n * per_side);
        match gabled(&p, shape) {
            Err(e) => bad.push(format!("{name}: {e}")),
            Ok((r, w)) => {
                let got = super::planes(&r.faces);
                // Gable ends: vertical planes (a side with a collinear vertex has two walls).
                let gables = super::gable_ends(&r.gable_walls);
                if gables != ends || planes.is_some_and(|n| n != got) {
                    bad.push(format!(
                        "{name}: {gables} gable ends (want {ends}), {got} roof planes (want \
                         {planes:?})"
                    ));
                }
                if let Some(first) = w.first() {
                    bad.push(format!(
                        "{name}: {} written defects, first: {first}",
                        w.len()
                    ));
                }
            }
        }
    }
    assert!(
        bad.is_empty(),
        "{} failures:\n{}",
        bad.len(),
        bad.join("\n")
    );
}

#[test]
fn every_roof_builds_on_every_hard_footprint() {
    let mut bad = Vec::new();
    for (name, p) in hard_cases() {
        for shape in [RoofShape::Hipped, RoofShape::Gabled, RoofShape::Mansard] {
            for pitch in [30.0, 45.0] {
                if let Err(e) = check_shape(&p, shape, pitch) {
                    bad.push(format!("{name} pitch {pitch}: {e}"));
                }
            }
        }
    }
    assert!(
        bad.is_empty(),
        "{} failures:\n{}",
        bad.len(),
        bad.join("\n")
    );
}
