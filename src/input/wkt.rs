//! A footprint given as WKT text (`POLYGON ((x y, ...), (hole ...))`), for `rules derive`.

use crate::geometry::Polygon;
use glam::DVec2;

/// Parses a WKT `POLYGON` (2D; a Z value is ignored) into a polygon in local metres.
///
/// Errors say what was expected and at which byte.
pub fn parse_polygon(text: &str) -> Result<Polygon, String> {
    let t = text.trim();
    let upper = t.to_ascii_uppercase();
    let Some(rest) = upper.strip_prefix("POLYGON") else {
        return Err("expected `POLYGON ((x y, ...))`".into());
    };
    let body = t[t.len() - rest.len()..].trim();
    let inner = body
        .strip_prefix('(')
        .and_then(|b| b.strip_suffix(')'))
        .ok_or("expected the rings in parentheses: POLYGON ((...))")?;
    let mut rings = Vec::new();
    let mut depth = 0;
    let mut start = None;
    for (i, c) in inner.char_indices() {
        match c {
            '(' => {
                depth += 1;
                if depth == 1 {
                    start = Some(i + 1);
                } else {
                    return Err(format!("nested parenthesis at byte {i}"));
                }
            }
            ')' => {
                depth -= 1;
                let s = start.take().ok_or(format!("unbalanced `)` at byte {i}"))?;
                rings.push(parse_ring(&inner[s..i])?);
            }
            ',' | ' ' | '\t' | '\n' | '\r' if depth == 0 => {}
            _ if depth == 0 => return Err(format!("unexpected `{c}` at byte {i}")),
            _ => {}
        }
    }
    if depth != 0 {
        return Err("unclosed `(`".into());
    }
    let mut rings = rings.into_iter();
    let outer = rings.next().ok_or("a polygon needs an outer ring")?;
    Ok(Polygon::new(outer, rings.collect()))
}

fn parse_ring(s: &str) -> Result<Vec<DVec2>, String> {
    let mut out = Vec::new();
    for pair in s.split(',') {
        let v: Vec<f64> = pair
            .split_whitespace()
            .map(|n| {
                n.parse::<f64>()
                    .map_err(|_| format!("`{n}` is not a number"))
            })
            .collect::<Result<_, _>>()?;
        if v.len() < 2 || v.iter().any(|x| !x.is_finite()) {
            return Err(format!("`{}` is not a coordinate pair", pair.trim()));
        }
        out.push(DVec2::new(v[0], v[1]));
    }
    if out.len() < 3 {
        return Err("a ring needs at least 3 points".into());
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn polygon_with_hole() {
        let p =
            parse_polygon("POLYGON ((0 0, 20 0, 20 20, 0 20, 0 0), (5 5, 5 15, 15 15, 15 5, 5 5))")
                .unwrap();
        assert_eq!(p.outer.len(), 4);
        assert_eq!(p.holes.len(), 1);
        assert!((p.area() - 300.0).abs() < 1e-9);
    }

    #[test]
    fn errors_say_what_is_wrong() {
        assert!(parse_polygon("LINESTRING (0 0, 1 1)")
            .unwrap_err()
            .contains("POLYGON"));
        assert!(parse_polygon("POLYGON ((0 0, 1 x, 1 1))")
            .unwrap_err()
            .contains("`x`"));
        assert!(parse_polygon("POLYGON ((0 0, 1 0))")
            .unwrap_err()
            .contains("3 points"));
        assert!(parse_polygon("POLYGON ((0 0, 1 0, 1 1)").is_err());
    }
}
