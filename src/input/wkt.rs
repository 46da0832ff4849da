//! A footprint given as WKT text (`POLYGON ((x y, ...), (hole ...))`), for `rules derive`.

use crate::geometry::Polygon;
use glam::DVec2;

/// Why WKT text is not a polygon: what was expected, and at which byte of the text between
/// the outer parentheses.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub(crate) enum WktError {
    /// The text does not start with `POLYGON`.
    #[error("expected `POLYGON ((x y, ...))`")]
    NotAPolygon,
    /// The rings are not in parentheses.
    #[error("expected the rings in parentheses: POLYGON ((...))")]
    NoParentheses,
    /// A `(` inside a ring.
    #[error("nested parenthesis at byte {at}")]
    Nested {
        /// The byte.
        at: usize,
    },
    /// A `)` closing nothing.
    #[error("unbalanced `)` at byte {at}")]
    Unbalanced {
        /// The byte.
        at: usize,
    },
    /// Something other than a ring, a comma or a space between rings.
    #[error("unexpected `{found}` at byte {at}")]
    Unexpected {
        /// The character.
        found: char,
        /// The byte.
        at: usize,
    },
    /// A `(` not closed.
    #[error("unclosed `(`")]
    Unclosed,
    /// No ring.
    #[error("a polygon needs an outer ring")]
    NoRing,
    /// A coordinate that is not a number.
    #[error("`{0}` is not a number")]
    NotANumber(String),
    /// A point that is not two finite numbers.
    #[error("`{0}` is not a coordinate pair")]
    NotAPair(String),
    /// A ring of fewer than 3 points.
    #[error("a ring needs at least 3 points")]
    FewPoints,
}

/// Parses a WKT `POLYGON` (2D; a Z value is ignored) into a polygon in local metres.
///
/// Errors say what was expected and at which byte.
pub(crate) fn parse_polygon(text: &str) -> Result<Polygon, WktError> {
    let t = text.trim();
    let upper = t.to_ascii_uppercase();
    let Some(rest) = upper.strip_prefix("POLYGON") else {
        return Err(WktError::NotAPolygon);
    };
    let body = t[t.len() - rest.len()..].trim();
    let inner = body
        .strip_prefix('(')
        .and_then(|b| b.strip_suffix(')'))
        .ok_or(WktError::NoParentheses)?;
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
                    return Err(WktError::Nested { at: i });
                }
            }
            ')' => {
                depth -= 1;
                let s = start.take().ok_or(WktError::Unbalanced { at: i })?;
                rings.push(parse_ring(&inner[s..i])?);
            }
            ',' | ' ' | '\t' | '\n' | '\r' if depth == 0 => {}
            _ if depth == 0 => return Err(WktError::Unexpected { found: c, at: i }),
            _ => {}
        }
    }
    if depth != 0 {
        return Err(WktError::Unclosed);
    }
    let mut rings = rings.into_iter();
    let outer = rings.next().ok_or(WktError::NoRing)?;
    Ok(Polygon::new(outer, rings.collect()))
}

fn parse_ring(s: &str) -> Result<Vec<DVec2>, WktError> {
    let mut out = Vec::new();
    for pair in s.split(',') {
        let v: Vec<f64> = pair
            .split_whitespace()
            .map(|n| {
                n.parse::<f64>()
                    .map_err(|_| WktError::NotANumber(n.to_string()))
            })
            .collect::<Result<_, _>>()?;
        if v.len() < 2 || v.iter().any(|x| !x.is_finite()) {
            return Err(WktError::NotAPair(pair.trim().to_string()));
        }
        out.push(DVec2::new(v[0], v[1]));
    }
    if out.len() < 3 {
        return Err(WktError::FewPoints);
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
            .to_string()
            .contains("POLYGON"));
        assert!(parse_polygon("POLYGON ((0 0, 1 x, 1 1))")
            .unwrap_err()
            .to_string()
            .contains("`x`"));
        assert!(parse_polygon("POLYGON ((0 0, 1 0))")
            .unwrap_err()
            .to_string()
            .contains("3 points"));
        assert!(parse_polygon("POLYGON ((0 0, 1 0, 1 1)").is_err());
    }
}
