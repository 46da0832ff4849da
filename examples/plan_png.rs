//! Draws one storey plan of a real Monaco building as SVG (rooms coloured by kind, interior
//! walls, doors, the entrance and the stair core), for the README.
//!
//!     cargo run --example plan_png -- [OUT.svg] [STOREY] [LOT_ID]
//!
//! Default: docs/images/lod4-plan.svg, the ground floor (0) of the first concave Monaco
//! building of 250-700 m² with 3+ storeys. Convert to PNG with
//! `convert -density 150 OUT.svg OUT.png` (ImageMagick) or headless Chromium.

use std::fmt::Write as _;
use std::path::Path;

use citygen::derive::interior::{plan_building, PlanInput, RoomKind};
use citygen::input::osm::read_osm;
use citygen::prepare::prepare;
use citygen::report::Report;
use citygen::rng::Rng;
use glam::DVec2;

fn colour(k: RoomKind) -> &'static str {
    match k {
        RoomKind::Hall => "#f4e3b5",
        RoomKind::Corridor => "#efe6cf",
        RoomKind::Stair => "#b9b9b9",
        RoomKind::Living => "#f6b26b",
        RoomKind::Kitchen => "#e06666",
        RoomKind::Bedroom => "#6fa8dc",
        RoomKind::Bathroom | RoomKind::Wc => "#76d7c4",
        RoomKind::Office => "#93c47d",
        RoomKind::OpenPlan => "#d5a6bd",
        RoomKind::Shop => "#c27ba0",
        RoomKind::Storage => "#cccccc",
    }
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let out = args
        .first()
        .cloned()
        .unwrap_or_else(|| "docs/images/lod4-plan.svg".into());
    let storey: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(0);
    let want = args.get(2).cloned();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut report = Report::default();
    let read = read_osm(&root.join("data/monaco/monaco.osm.pbf"), &mut report)?;
    let site = prepare(read.footprints, read.source_crs, None, &mut report);
    let lot = site
        .lots
        .iter()
        .find(|l| match &want {
            Some(id) => l.id.to_string() == *id,
            None => {
                let p = &l.polygons[0];
                l.polygons.len() == 1
                    && (250.0..700.0).contains(&p.area())
                    && p.outer.len() >= 8
                    && l.tags.levels.unwrap_or(0.0) >= 3.0
            }
        })
        .ok_or_else(|| anyhow::anyhow!("no matching building"))?;
    let fp = &lot.polygons[0];
    let storeys = lot.tags.levels.unwrap_or(3.0).clamp(1.0, 30.0) as u32;
    let input = PlanInput {
        footprint: fp,
        storeys,
        storey_height: 3.0,
        building: lot.tags.building.as_deref(),
        programme: None,
        front: None,
        wall_thickness: 0.3,
    };
    let plan = plan_building(&input, &mut Rng::new(0, lot.id.seed_value()));
    let s = plan
        .storeys
        .get(storey)
        .ok_or_else(|| anyhow::anyhow!("no storey {storey}"))?;

    let (lo, hi) = fp.bounds();
    let scale = 900.0 / (hi - lo).max_element();
    let pad = 30.0;
    let (w, h) = (
        (hi.x - lo.x) * scale + 2.0 * pad,
        (hi.y - lo.y) * scale + 2.0 * pad + 40.0,
    );
    // SVG y points down: flip.
    let tx = |p: DVec2| DVec2::new((p.x - lo.x) * scale + pad, (hi.y - p.y) * scale + pad);
    let path = |r: &[DVec2]| {
        let mut d = String::new();
        for (i, p) in r.iter().enumerate() {
            let q = tx(*p);
            let _ = write!(
                d,
                "{}{:.2},{:.2} ",
                if i == 0 { "M" } else { "L" },
                q.x,
                q.y
            );
        }
        d + "Z"
    };
    let mut svg = String::new();
    let _ = writeln!(
        svg,
        r##"<svg xmlns="http://www.w3.org/2000/svg" width="{w:.0}" height="{h:.0}" font-family="sans-serif">"##
    );
    let _ = writeln!(svg, r##"<rect width="100%" height="100%" fill="white"/>"##);
    // Footprint (exterior wall band) in dark grey, usable area on top.
    let mut d = path(&fp.outer);
    for hole in &fp.holes {
        d += &path(hole);
    }
    let _ = writeln!(svg, r##"<path d="{d}" fill="#444" fill-rule="evenodd"/>"##);
    for r in &s.rooms {
        let _ = writeln!(
            svg,
            r##"<path d="{}" fill="{}" stroke="none"/>"##,
            path(&r.polygon.outer),
            colour(r.kind)
        );
    }
    for wall in &s.walls {
        let (a, b) = (tx(wall.segment.0), tx(wall.segment.1));
        let _ = writeln!(
            svg,
            r##"<line x1="{:.2}" y1="{:.2}" x2="{:.2}" y2="{:.2}" stroke="#333" stroke-width="{:.1}"/>"##,
            a.x,
            a.y,
            b.x,
            b.y,
            0.12 * scale
        );
    }
    for (door, col) in s
        .doors
        .iter()
        .map(|d| (d, "white"))
        .chain(s.entrance.iter().map(|d| (d, "#2e7d32")))
    {
        let (a, b) = (tx(door.segment.0), tx(door.segment.1));
        let width = if door.b.is_none() { 0.5 } else { 0.18 };
        let _ = writeln!(
            svg,
            r##"<line x1="{:.2}" y1="{:.2}" x2="{:.2}" y2="{:.2}" stroke="{col}" stroke-width="{:.1}"/>"##,
            a.x,
            a.y,
            b.x,
            b.y,
            width * scale
        );
    }
    if let Some(st) = &plan.stair {
        // Treads across the stair rectangle.
        let r = &st.polygon.outer;
        let e0 = r[1] - r[0];
        let e1 = r[3] - r[0];
        let (run, across, o) = if e0.length() >= e1.length() {
            (e0, e1, r[0])
        } else {
            (e1, e0, r[0])
        };
        let n = (run.length() / st.going).floor() as usize;
        for i in 1..n {
            let a = tx(o + run * (i as f64 / n as f64));
            let b = tx(o + run * (i as f64 / n as f64) + across);
            let _ = writeln!(
                svg,
                r##"<line x1="{:.2}" y1="{:.2}" x2="{:.2}" y2="{:.2}" stroke="#777" stroke-width="1"/>"##,
                a.x, a.y, b.x, b.y
            );
        }
    }
    let font = (0.35 * scale).clamp(8.0, 14.0);
    for r in &s.rooms {
        let c = r.polygon.outer.iter().copied().sum::<DVec2>() / r.polygon.outer.len() as f64;
        if !r.polygon.contains(c) || r.area() < 4.0 {
            continue;
        }
        let q = tx(c);
        let _ = writeln!(
            svg,
            r##"<text x="{:.1}" y="{:.1}" font-size="{font:.1}" text-anchor="middle">{}</text>"##,
            q.x,
            q.y,
            r.kind.label()
        );
    }
    let _ = writeln!(
        svg,
        r##"<text x="{pad}" y="{:.0}" font-size="16">{} ({}, {} storeys, {:?}): storey {storey}, {} rooms, {} doors; entrance green</text>"##,
        h - 14.0,
        lot.id,
        lot.tags.building.as_deref().unwrap_or("?"),
        storeys,
        plan.programme,
        s.rooms.len(),
        s.doors.len()
    );
    svg += "</svg>\n";
    std::fs::write(&out, svg)?;
    println!("wrote {out}");
    Ok(())
}
