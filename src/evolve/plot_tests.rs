//! The SVGs parse as XML, escape their labels, carry tick labels and are deterministic.

use std::collections::BTreeMap;

use quick_xml::events::Event;
use quick_xml::XmlVersion;

use super::nsga2::{run, Config, History};
use super::plot::{convergence_svg, escape, front_svg};

/// A parsed SVG: the content of every `<text>` element (entities resolved) and how many
/// elements of each name it has. Fails on any well-formedness error or unknown entity.
struct Parsed {
    texts: Vec<String>,
    counts: BTreeMap<String, usize>,
}

/// Counts an element and checks its attributes; returns its name.
fn element(e: &quick_xml::events::BytesStart<'_>, parsed: &mut Parsed) -> String {
    let name = e.name().as_ref().to_string();
    for a in e.attributes() {
        a.expect("attribute")
            .normalized_value(XmlVersion::Implicit1_0)
            .expect("attribute value");
    }
    *parsed.counts.entry(name.clone()).or_insert(0) += 1;
    name
}

fn parse(svg: &str) -> Parsed {
    let mut reader = quick_xml::Reader::from_str(svg);
    let mut parsed = Parsed {
        texts: Vec::new(),
        counts: BTreeMap::new(),
    };
    let mut open: Vec<String> = Vec::new();
    loop {
        match reader.read_event().expect("well-formed XML") {
            Event::Start(e) => {
                let name = element(&e, &mut parsed);
                if name == "text" {
                    parsed.texts.push(String::new());
                }
                open.push(name);
            }
            Event::Empty(e) => {
                element(&e, &mut parsed);
            }
            Event::End(_) => {
                open.pop();
            }
            Event::Text(t) if open.last().is_some_and(|n| n == "text") => {
                let s = t.xml10_content().into_owned();
                parsed.texts.last_mut().unwrap().push_str(&s);
            }
            Event::GeneralRef(r) if open.last().is_some_and(|n| n == "text") => {
                let c = match &*r {
                    "amp" => '&',
                    "lt" => '<',
                    "gt" => '>',
                    "quot" => '"',
                    "apos" => '\'',
                    other => panic!("unknown entity {other}"),
                };
                parsed.texts.last_mut().unwrap().push(c);
            }
            Event::Eof => break,
            _ => {}
        }
    }
    assert!(open.is_empty(), "unclosed {open:?}");
    parsed
}

fn toy(g: &[u32]) -> Vec<f64> {
    let rest: u32 = g[1..].iter().sum();
    vec![f64::from(g[0] + rest), f64::from(9 - g[0] + rest)]
}

fn toy_run(objectives: usize) -> History {
    let config = Config {
        generations: 10,
        seed: 1,
        reference: vec![80.0; objectives],
        ..Config::default()
    };
    run(&config, &[10; 8], |g| {
        let mut v = toy(g);
        v.resize(objectives, f64::from(g[2]));
        v
    })
}

#[test]
fn escape_covers_the_five_entities() {
    assert_eq!(
        escape(r#"a<b & "c" > 'd'"#),
        "a&lt;b &amp; &quot;c&quot; &gt; &apos;d&apos;"
    );
    assert_eq!(escape("x\u{1}y"), "x y");
}

#[test]
fn front_svg_draws_every_genome_and_the_front_with_tick_labels() {
    let h = toy_run(2);
    let svg = front_svg(&h, &["a<b", "c&d"]);
    assert_eq!(svg, front_svg(&h, &["a<b", "c&d"]), "deterministic");
    let p = parse(&svg);
    let distinct: std::collections::BTreeSet<&Vec<u32>> = h
        .generations
        .iter()
        .flat_map(|g| g.individuals.iter().map(|i| &i.genome))
        .collect();
    assert_eq!(p.counts["circle"], distinct.len() + h.front.len());
    assert!(p.texts.iter().any(|t| t == "a<b"), "{:?}", p.texts);
    assert!(p.texts.iter().any(|t| t == "c&d"));
    assert!(p.texts.iter().any(|t| t.contains("Pareto front")));
    // Tick labels: numbers, at least 3 per axis, and 0 among them (the front reaches 0).
    let numbers = p.texts.iter().filter(|t| t.parse::<f64>().is_ok()).count();
    assert!(numbers >= 6, "{:?}", p.texts);
    assert!(p.texts.iter().any(|t| t == "0"));
}

#[test]
fn front_svg_for_one_and_three_objectives_says_what_it_shows() {
    let one = parse(&front_svg(&toy_run(1), &["hsym"]));
    assert!(one.texts.iter().any(|t| t == "best hsym per generation"));
    assert_eq!(one.counts["circle"], 11, "one point per generation");
    let three = parse(&front_svg(&toy_run(3), &[]));
    assert!(three
        .texts
        .iter()
        .any(|t| t.contains("objectives 1 and 2 of 3 shown")));
    assert!(three.texts.iter().any(|t| t == "objective 2"));
    let empty = History {
        generations: Vec::new(),
        front: Vec::new(),
        ..toy_run(1)
    };
    let e = parse(&front_svg(&empty, &[]));
    assert!(e.texts.iter().any(|t| t.contains("no objective values")));
    let e = parse(&convergence_svg(&empty, &[]));
    assert!(e.texts.iter().any(|t| t.contains("no generation")));
}

#[test]
fn convergence_svg_has_min_mean_and_hypervolume() {
    let h = toy_run(2);
    let svg = convergence_svg(&h, &["vsym", "hsym"]);
    assert_eq!(svg, convergence_svg(&h, &["vsym", "hsym"]));
    let p = parse(&svg);
    // min and mean per objective, and the hypervolume.
    assert_eq!(p.counts["polyline"], 2 * 2 + 1);
    assert!(svg.contains("stroke-dasharray"));
    for label in ["vsym", "hsym", "hypervolume per generation", "generation"] {
        assert!(p.texts.iter().any(|t| t == label), "{label}: {:?}", p.texts);
    }
    // The generation axis is labelled 0 … 10.
    assert!(p.texts.iter().any(|t| t == "10"));
}
