//! Every SELEX example of docs/selex.md is a test: each fenced block whose info string is
//! `selex` must parse, and each block fenced `selex-error` must fail to parse; a `selex-error`
//! block may name the expected [`ParseErrorKind`] after the tag (```` ```selex-error Unclosed ````).
//! The file must hold at least one `selex` block. The document is read when the test runs (from
//! `CARGO_MANIFEST_DIR`), so a missing file fails this test, not the build.

use super::parser::{parse, ParseErrorKind, SelexError as ParseError};

/// One fenced block: its info string's words, its text and the document line of its first line.
struct Block {
    tag: String,
    arg: Option<String>,
    text: String,
    line: usize,
}

/// The fenced blocks of a Markdown document (``` fences; the info string's first word is the
/// tag, the second its argument).
fn blocks(doc: &str) -> Result<Vec<Block>, String> {
    let lines: Vec<&str> = doc.lines().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < lines.len() {
        let l = lines[i].trim_start();
        if let Some(info) = l.strip_prefix("```") {
            let mut words = info.split_whitespace();
            let tag = words.next().unwrap_or("").to_string();
            let arg = words.next().map(str::to_string);
            let start = i + 1;
            let mut j = start;
            while j < lines.len() && !lines[j].trim_start().starts_with("```") {
                j += 1;
            }
            if j == lines.len() {
                return Err(format!("docs/selex.md:{}: unclosed fence", i + 1));
            }
            out.push(Block {
                tag,
                arg,
                text: lines[start..j].join("\n"),
                line: start + 1,
            });
            i = j + 1;
        } else {
            i += 1;
        }
    }
    Ok(out)
}

fn kind_name(k: ParseErrorKind) -> String {
    format!("{k:?}")
}

/// The failures of the document's examples, one message each.
fn failures(doc: &str) -> Vec<String> {
    let blocks = match blocks(doc) {
        Ok(b) => b,
        Err(e) => return vec![e],
    };
    let mut out = Vec::new();
    if !blocks.iter().any(|b| b.tag == "selex") {
        out.push("docs/selex.md has no ```selex block".to_string());
    }
    for b in &blocks {
        let name = format!("docs/selex.md:{}", b.line);
        // An error's place in the document: its line in the block, shifted to the block.
        let place = |e: &ParseError| {
            format!(
                "docs/selex.md:{}:{}: {}\n{}",
                b.line + e.line as usize - 1,
                e.col,
                e.message,
                e.line_text
            )
        };
        match b.tag.as_str() {
            "selex" => {
                if let Err(e) = parse(&b.text, "docs/selex.md") {
                    out.push(format!("a ```selex block does not parse:\n{}", place(&e)));
                }
            }
            "selex-error" => match parse(&b.text, "docs/selex.md") {
                Ok(_) => out.push(format!("{name}: a ```selex-error block parses")),
                Err(e) => {
                    if let Some(want) = &b.arg {
                        if &kind_name(e.kind) != want {
                            out.push(format!(
                                "{name}: a ```selex-error {want} block fails with {:?}:\n{}",
                                e.kind,
                                place(&e)
                            ));
                        }
                    }
                }
            },
            _ => {}
        }
    }
    out
}

#[test]
fn every_example_of_docs_selex_md_parses() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/docs/selex.md");
    let doc = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let f = failures(&doc);
    assert!(f.is_empty(), "{}", f.join("\n\n"));
}

#[test]
fn the_harness_catches_each_kind_of_failure() {
    assert_eq!(failures("text only\n").len(), 1, "no selex block");
    let good = "```selex\n{<> -> coverShape()}\n```\n";
    assert!(failures(good).is_empty());
    let bad = format!("{good}```selex\n{{<> -> cover()}}\n```\n");
    let f = failures(&bad);
    assert_eq!(f.len(), 1);
    assert!(f[0].contains("docs/selex.md:5:8"), "{}", f[0]);
    let parses = format!("{good}```selex-error\n{{<> -> coverShape()}}\n```\n");
    assert_eq!(failures(&parses).len(), 1);
    let wrong_kind = format!("{good}```selex-error Unclosed\n{{<> -> cover()}}\n```\n");
    assert_eq!(failures(&wrong_kind).len(), 1);
    let right_kind = format!("{good}```selex-error UnknownAction\n{{<> -> cover()}}\n```\n");
    assert!(failures(&right_kind).is_empty());
    assert_eq!(
        failures("```selex\n{<> -> coverShape()}\n").len(),
        1,
        "unclosed fence"
    );
}
