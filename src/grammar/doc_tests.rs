//! Every example of docs/grammar.md is a test: each ```cga block is parsed and derived, and the
//! ```expect block right after it lists assertions on the result. The document therefore
//! cannot drift from the code.
//!
//! Expect directives (one per line; blank lines and `#` comments are skipped):
//!
//! ```text
//! lot 20x12                     the lot: a W x D rectangle at the origin (default 20x12)
//! lot monaco                    the real Monaco footprint of tests.rs (way 49209616)
//! seed 7                        the derivation seed (default 1)
//! input h = 4                   a numeric (or text) attribute of the axiom
//! max-depth 8 | max-shapes 50   caps (defaults: Caps::default())
//! count window = 6              nodes whose symbol is `window`
//! count label Storey = 3        nodes with that label (Label's variant name)
//! widths f = 5, 2, 13           face widths of the nodes named `f`, in tree order
//! heights s = 4, 4, 6.5         heights (volumes and faces) of the nodes named `s`
//! z0 s = 0, 4                   base heights (volumes, lots; lower edge of faces)
//! area s = 120                  footprint areas of the volumes/lots named `s`
//! children f = a, b, wall       symbols of the children of the (first) node named `f`
//! attr window color = yellow    every node named `window` has that attribute value
//! weights gfront = 0.4, 0.6     resolved selection weights of a predecessor's rules
//! error line 2 col 14 BadAxis   parsing fails there with that ParseErrorKind
//! derive-error Unsupported      derivation fails with that DeriveError variant
//! render                        the rest of the block is the exact Display of the error
//! ```

use glam::DVec2;

use super::*;
use crate::geometry::Polygon;
use crate::rng::Rng;

const DOC: &str = include_str!("../../docs/grammar.md");

/// One example: the rule text, the assertions and where they are in the document.
struct Example {
    cga: String,
    cga_line: usize,
    expect: Vec<(usize, String)>,
}

/// Collects the ```cga blocks and the ```expect block that must follow each one.
fn examples(doc: &str) -> Vec<Example> {
    let lines: Vec<&str> = doc.lines().collect();
    let mut out: Vec<Example> = Vec::new();
    let mut i = 0;
    while i < lines.len() {
        let tag = lines[i].trim();
        if tag == "```cga" || tag == "```expect" {
            let start = i + 1;
            let mut j = start;
            while j < lines.len() && lines[j].trim() != "```" {
                j += 1;
            }
            assert!(j < lines.len(), "docs/grammar.md:{i}: unclosed fence");
            if tag == "```cga" {
                out.push(Example {
                    cga: lines[start..j].join("\n"),
                    cga_line: start + 1,
                    expect: Vec::new(),
                });
            } else {
                let ex = out.last_mut().unwrap_or_else(|| {
                    panic!(
                        "docs/grammar.md:{}: expect block before any cga block",
                        i + 1
                    )
                });
                assert!(
                    ex.expect.is_empty(),
                    "docs/grammar.md:{}: second expect block for one example",
                    i + 1
                );
                ex.expect = (start..j).map(|k| (k + 1, lines[k].to_string())).collect();
            }
            i = j + 1;
        } else {
            i += 1;
        }
    }
    out
}

fn rect(w: f64, d: f64) -> Polygon {
    Polygon::new(
        vec![
            DVec2::new(0.0, 0.0),
            DVec2::new(w, 0.0),
            DVec2::new(w, d),
            DVec2::new(0.0, d),
        ],
        vec![],
    )
}

fn numbers(s: &str, at: usize) -> Vec<f64> {
    s.split(',')
        .map(|v| {
            v.trim()
                .parse::<f64>()
                .unwrap_or_else(|_| panic!("docs/grammar.md:{at}: `{v}` is not a number"))
        })
        .collect()
}

/// Splits `NAME rest = VALUE` into (`NAME rest`, `VALUE`).
fn lhs_rhs(s: &str, at: usize) -> (String, String) {
    let (l, r) = s
        .split_once('=')
        .unwrap_or_else(|| panic!("docs/grammar.md:{at}: expected `... = ...` in `{s}`"));
    (l.trim().to_string(), r.trim().to_string())
}

fn close(a: &[f64], b: &[f64]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-6)
}

fn size_of(n: &ShapeNode, width: bool) -> f64 {
    match &n.geometry {
        Geometry::Face {
            width: w, height, ..
        } => {
            if width {
                *w
            } else {
                *height
            }
        }
        Geometry::Volume { height, .. } => *height,
        Geometry::Lot { .. } => 0.0,
    }
}

fn check(ex: &Example) {
    let at = ex.cga_line;
    let mut lot = rect(20.0, 12.0);
    let mut seed = 1u64;
    let mut attrs = Attrs::new();
    let mut caps = Caps::default();
    let mut checks: Vec<(usize, String)> = Vec::new();
    let mut render: Option<String> = None;
    let mut lines = ex.expect.iter();
    while let Some((ln, raw)) = lines.next() {
        let line = raw.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let (word, rest) = line.split_once(' ').unwrap_or((line, ""));
        let rest = rest.trim();
        match word {
            "lot" if rest == "monaco" => lot = super::tests::monaco_footprint(),
            "lot" => {
                let (w, d) = rest
                    .split_once('x')
                    .unwrap_or_else(|| panic!("docs/grammar.md:{ln}: lot WxD"));
                lot = rect(numbers(w, *ln)[0], numbers(d, *ln)[0]);
            }
            "seed" => seed = numbers(rest, *ln)[0] as u64,
            "input" => {
                let (k, v) = lhs_rhs(rest, *ln);
                let v = v
                    .parse::<f64>()
                    .map_or_else(|_| AttrValue::Str(v.as_str().into()), AttrValue::Num);
                attrs.insert(k.as_str().into(), v);
            }
            "max-depth" => caps.max_depth = numbers(rest, *ln)[0] as usize,
            "max-shapes" => caps.max_shapes = numbers(rest, *ln)[0] as usize,
            "render" => {
                let text: Vec<&str> = lines.by_ref().map(|(_, l)| l.as_str()).collect();
                render = Some(text.join("\n"));
            }
            _ => checks.push((*ln, line.to_string())),
        }
    }
    let parsed = parse(&ex.cga, "example.cga");
    let rules = match parsed {
        Err(e) => {
            let want = checks
                .iter()
                .find(|(_, c)| c.starts_with("error "))
                .unwrap_or_else(|| panic!("docs/grammar.md:{at}: example does not parse:\n{e}"));
            let got = format!("error line {} col {} {:?}", e.line, e.col, e.kind);
            assert_eq!(got, want.1, "docs/grammar.md:{}: {e}", want.0);
            if let Some(r) = render {
                assert_eq!(e.to_string(), r, "docs/grammar.md:{at}: rendered error");
            }
            return;
        }
        Ok(r) => r,
    };
    let result = derive(&rules, &lot, attrs, &mut Rng::new(seed, 1), &caps);
    let tree = match result {
        Err(e) => {
            let want = checks
                .iter()
                .find(|(_, c)| c.starts_with("derive-error "))
                .unwrap_or_else(|| panic!("docs/grammar.md:{at}: example fails: {e}"));
            let variant = format!("{e:?}");
            let name = want.1["derive-error ".len()..].trim();
            assert!(
                variant.starts_with(name),
                "docs/grammar.md:{}: expected {name}, got {e}",
                want.0
            );
            if let Some(r) = render {
                assert_eq!(e.to_string(), r, "docs/grammar.md:{at}: rendered error");
            }
            return;
        }
        Ok(t) => t,
    };
    assert!(!checks.is_empty(), "docs/grammar.md:{at}: no assertion");
    for (ln, c) in &checks {
        let (word, rest) = c.split_once(' ').unwrap_or((c, ""));
        let named = |s: &str| -> Vec<&ShapeNode> {
            tree.nodes.iter().filter(|n| &*n.symbol == s).collect()
        };
        match word {
            "count" => {
                let (what, n) = lhs_rhs(rest, *ln);
                let n = numbers(&n, *ln)[0] as usize;
                let got = match what.strip_prefix("label ") {
                    Some(label) => tree
                        .nodes
                        .iter()
                        .filter(|x| format!("{:?}", x.label) == label.trim())
                        .count(),
                    None => named(&what).len(),
                };
                assert_eq!(got, n, "docs/grammar.md:{ln}: {c}");
            }
            "widths" | "heights" => {
                let (sym, v) = lhs_rhs(rest, *ln);
                let got: Vec<f64> = named(&sym)
                    .iter()
                    .map(|n| size_of(n, word == "widths"))
                    .collect();
                assert!(
                    close(&got, &numbers(&v, *ln)),
                    "docs/grammar.md:{ln}: {c}, got {got:?}"
                );
            }
            "z0" | "area" => {
                let (sym, v) = lhs_rhs(rest, *ln);
                let got: Vec<f64> = named(&sym)
                    .iter()
                    .map(|n| match (&n.geometry, word) {
                        (Geometry::Volume { z0, .. }, "z0") => *z0,
                        (Geometry::Lot { z, .. }, "z0") => *z,
                        (Geometry::Face { origin, .. }, "z0") => origin.z,
                        (Geometry::Volume { footprint, .. }, _) => footprint.area(),
                        (Geometry::Lot { polygon, .. }, _) => polygon.area(),
                        (Geometry::Face { .. }, _) => f64::NAN,
                    })
                    .collect();
                assert!(
                    close(&got, &numbers(&v, *ln)),
                    "docs/grammar.md:{ln}: {c}, got {got:?}"
                );
            }
            "children" => {
                let (sym, v) = lhs_rhs(rest, *ln);
                let first = tree
                    .nodes
                    .iter()
                    .position(|n| *n.symbol == *sym)
                    .unwrap_or_else(|| panic!("docs/grammar.md:{ln}: no node `{sym}`"));
                let got: Vec<&str> = tree.children(first).iter().map(|n| &*n.symbol).collect();
                let want: Vec<&str> = v.split(',').map(str::trim).collect();
                assert_eq!(got, want, "docs/grammar.md:{ln}: {c}");
            }
            "attr" => {
                let (l, v) = lhs_rhs(rest, *ln);
                let (sym, key) = l
                    .split_once(' ')
                    .unwrap_or_else(|| panic!("docs/grammar.md:{ln}: attr SYMBOL KEY = VALUE"));
                let nodes = named(sym);
                assert!(!nodes.is_empty(), "docs/grammar.md:{ln}: no node `{sym}`");
                for n in nodes {
                    let got = n.attrs.get(key.trim()).map(|a| a.to_string());
                    assert_eq!(
                        got.as_deref(),
                        Some(v.as_str()),
                        "docs/grammar.md:{ln}: {c}"
                    );
                }
            }
            "weights" => {
                let (sym, v) = lhs_rhs(rest, *ln);
                let got: Vec<f64> = rules.rules_for(&sym).iter().map(|r| r.1).collect();
                assert!(
                    close(&got, &numbers(&v, *ln)),
                    "docs/grammar.md:{ln}: {c}, got {got:?}"
                );
            }
            "error" | "derive-error" => {
                panic!("docs/grammar.md:{ln}: `{c}` expected, but the example derives")
            }
            _ => panic!("docs/grammar.md:{ln}: unknown expect directive `{c}`"),
        }
    }
}

#[test]
fn every_example_of_the_grammar_doc_holds() {
    let exs = examples(DOC);
    assert!(exs.len() >= 20, "only {} examples found", exs.len());
    for ex in &exs {
        assert!(
            !ex.expect.is_empty(),
            "docs/grammar.md:{}: cga block without an expect block",
            ex.cga_line
        );
        check(ex);
    }
}
