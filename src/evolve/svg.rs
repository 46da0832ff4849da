//! A derived facade drawn to scale as SVG: the picture of a front member or of the best facade
//! per objective (issue 26, output).
//!
//! `facade_svg` draws the facade outline and every terminal as a rectangle, 40 px per metre
//! with a 10 px margin, the ground at the bottom: walls grey, windows blue, doors brown. The
//! text depends only on the [`Facade`] (coordinates written with 2 decimals), so the same
//! facade gives the same bytes; it is well-formed XML with no text from the rules in it.

use super::{Facade, Kind};

/// Pixels per metre.
pub(crate) const SCALE: f64 = 40.0;

/// Margin around the facade, pixels.
pub(crate) const MARGIN: f64 = 10.0;

/// Fill colour of each kind: wall, window, door.
pub fn fill(kind: Kind) -> &'static str {
    match kind {
        Kind::Wall => "#a0a0a0",
        Kind::Window => "#4a86c8",
        Kind::Door => "#8b5a2b",
    }
}

/// A length for the SVG: 2 decimals, non-finite values as 0.
fn px(v: f64) -> String {
    let v = if v.is_finite() { v } else { 0.0 };
    let s = format!("{v:.2}");
    if s == "-0.00" {
        "0.00".to_string()
    } else {
        s
    }
}

/// The SVG document of a facade (module docs). A facade of no or non-finite size is drawn as
/// 1 m × 1 m; terminals with non-finite coordinates are left out.
pub(crate) fn facade_svg(f: &Facade) -> String {
    let size = |v: f64| if v.is_finite() && v > 0.0 { v } else { 1.0 };
    let (w, h) = (size(f.width), size(f.height));
    let (pw, ph) = (w * SCALE + 2.0 * MARGIN, h * SCALE + 2.0 * MARGIN);
    let count = |k: Kind| f.terminals.iter().filter(|t| t.kind == k).count();
    let mut out = String::new();
    out.push_str(&format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{}\" height=\"{}\" viewBox=\"0 0 {} {}\">\n",
        px(pw),
        px(ph),
        px(pw),
        px(ph)
    ));
    out.push_str(&format!(
        "<title>facade {} x {} m: {} terminals ({} walls, {} windows, {} doors), {} violations</title>\n",
        px(f.width),
        px(f.height),
        f.terminals.len(),
        count(Kind::Wall),
        count(Kind::Window),
        count(Kind::Door),
        f.violations
    ));
    out.push_str(&format!(
        "<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"white\" stroke=\"black\" stroke-width=\"1\"/>\n",
        px(MARGIN),
        px(MARGIN),
        px(w * SCALE),
        px(h * SCALE)
    ));
    for t in &f.terminals {
        if ![t.x, t.y, t.w, t.h].iter().all(|v| v.is_finite()) {
            continue;
        }
        // SVG's y runs down: the terminal's top edge is h - (y + height) below the facade top.
        out.push_str(&format!(
            "<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"{}\" stroke=\"#303030\" stroke-width=\"0.5\"/>\n",
            px(MARGIN + t.x * SCALE),
            px(MARGIN + (h - t.y - t.h) * SCALE),
            px(t.w.max(0.0) * SCALE),
            px(t.h.max(0.0) * SCALE),
            fill(t.kind)
        ));
    }
    out.push_str("</svg>\n");
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::evolve::Terminal;

    fn facade() -> Facade {
        Facade {
            width: 4.0,
            height: 3.0,
            terminals: vec![
                Terminal {
                    kind: Kind::Door,
                    x: 0.0,
                    y: 0.0,
                    w: 1.0,
                    h: 2.0,
                },
                Terminal {
                    kind: Kind::Window,
                    x: 2.0,
                    y: 1.0,
                    w: 1.0,
                    h: 1.0,
                },
                Terminal {
                    kind: Kind::Wall,
                    x: f64::NAN,
                    y: 0.0,
                    w: 1.0,
                    h: 1.0,
                },
            ],
            ..Facade::default()
        }
    }

    #[test]
    fn terminals_are_drawn_to_scale_with_the_ground_at_the_bottom() {
        let s = facade_svg(&facade());
        // 4 x 3 m at 40 px/m plus margins.
        assert!(s.starts_with(
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"180.00\" height=\"140.00\""
        ));
        // The door stands on the ground: its top is 1 m below the facade's top edge.
        assert!(s.contains(
            "<rect x=\"10.00\" y=\"50.00\" width=\"40.00\" height=\"80.00\" fill=\"#8b5a2b\""
        ));
        assert!(s.contains(
            "<rect x=\"90.00\" y=\"50.00\" width=\"40.00\" height=\"40.00\" fill=\"#4a86c8\""
        ));
        // The terminal with a NaN coordinate is left out; the title still counts it.
        assert_eq!(s.matches("<rect").count(), 3);
        assert!(s.contains("3 terminals (1 walls, 1 windows, 1 doors)"));
        assert_eq!(s, facade_svg(&facade()));
    }

    #[test]
    fn the_svg_is_well_formed_xml() {
        for f in [facade(), Facade::default()] {
            let s = facade_svg(&f);
            let mut reader = quick_xml::Reader::from_str(&s);
            let mut depth = 0i32;
            loop {
                match reader.read_event() {
                    Ok(quick_xml::events::Event::Start(_)) => depth += 1,
                    Ok(quick_xml::events::Event::End(_)) => depth -= 1,
                    Ok(quick_xml::events::Event::Eof) => break,
                    Ok(_) => {}
                    Err(e) => panic!("{e}: {s}"),
                }
            }
            assert_eq!(depth, 0);
        }
    }
}
