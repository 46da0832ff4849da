//! The layering of ARCHITECTURE.md, enforced (in the spirit of rust-analyzer's tidy tests).
//!
//! Reads every `src/**/*.rs` (test code left out: `tests.rs` files and `#[cfg(test)]` items),
//! resolves every `crate::`, `super::` and `self::` path, and fails, naming file and line:
//! - when a top-level module imports one that its row of [`LAYERS`] does not list;
//! - when the modules of any folder (the top level included) import each other in a cycle;
//! - when a child of a folder named in [`SIBLINGS`] imports a sibling its row there does not
//!   list (the writers of `export/` do not import each other);
//! - when `src/main.rs` (another crate) names anything of the library but [`MAIN_MAY_IMPORT`].
//!
//! The checker is a small tokenizer, not a Rust parser: it skips comments, strings and
//! character literals, follows brace nesting for inline modules and `#[cfg(test)]` items, and
//! expands `use` trees (`crate::a::{b, c::{d, e}}`). Its own tests feed it sources that break
//! each rule, so this test cannot pass by finding nothing.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// What each top-level module of `src/` may import (besides itself). Keep this table and
/// ARCHITECTURE.md's "Layers" in step. From the ground floor up:
const LAYERS: &[(&str, &[&str])] = &[
    // The ground floor: plain values and algorithms, nothing of ours.
    ("color", &[]),
    ("guard", &[]),
    ("rng", &[]),
    ("crs", &[]),
    ("geometry", &[]),
    ("fsio", &[]),
    // The semantic building model every writer consumes, and the run's report.
    ("model", &["geometry", "color"]),
    ("report", &["model"]),
    // Readers: footprints in the source CRS. Never the KB, the grammar, derive or writers.
    ("input", &["model", "report", "crs", "geometry", "color"]),
    // Projection to the local frame, clean-up, parts, tiles.
    (
        "prepare",
        &["input", "model", "report", "crs", "geometry", "color"],
    ),
    // The two languages.
    ("grammar", &["geometry", "rng", "color"]),
    ("selex", &["grammar", "geometry", "rng", "color"]),
    (
        "kb",
        &[
            "grammar", "selex", "input", "model", "rng", "geometry", "color", "fsio",
        ],
    ),
    // Rules written by a genetic search (`citygen evolve`).
    (
        "evolve",
        &["grammar", "kb", "rng", "geometry", "color", "fsio"],
    ),
    // One lot to one building.
    (
        "derive",
        &[
            "kb", "grammar", "selex", "prepare", "input", "model", "report", "rng", "geometry",
            "color", "guard",
        ],
    ),
    // Writers see only the model (and the ground floor).
    (
        "export",
        &["model", "geometry", "color", "crs", "guard", "fsio"],
    ),
    // The run, and the test kit that builds inputs for tests and benches.
    (
        "pipeline",
        &[
            "derive", "export", "kb", "grammar", "selex", "prepare", "input", "model", "report",
            "rng", "geometry", "crs", "color", "guard", "fsio",
        ],
    ),
    (
        "testkit",
        &["input", "model", "report", "geometry", "color", "fsio"],
    ),
    // The knowledge base edited in a browser (`citygen kb edit`): a server over the run.
    (
        "editor",
        &[
            "pipeline", "derive", "export", "kb", "grammar", "selex", "prepare", "input", "model",
            "report", "rng", "geometry", "crs", "color", "guard", "fsio",
        ],
    ),
    // The command line (`citygen`'s arguments, commands and exit codes): the top floor.
    (
        "app",
        &[
            "editor", "pipeline", "evolve", "derive", "export", "kb", "grammar", "selex",
            "prepare", "input", "model", "report", "rng", "geometry", "crs", "color", "guard",
        ],
    ),
];

/// A folder's children and the siblings each may import (see [`SIBLINGS`]).
type Siblings = &'static [(
    &'static str,
    &'static [(&'static str, &'static [&'static str])],
)];

/// Direction inside a folder: for the folder (module path), each listed child and the listed
/// siblings it may import. Children of the folder that are not listed (shared files such as
/// `export::step`) may be imported by any child; a listed child may import an unlisted one.
/// Keep in step with ARCHITECTURE.md's "Layers".
const SIBLINGS: Siblings = &[
    // The writers: one format each, none imports another, but for glTF, which is the content
    // of 3D Tiles and what the preview draws.
    (
        "export",
        &[
            ("ifc", &[]),
            ("citygml", &[]),
            ("cityjson", &[]),
            ("gltf", &[]),
            ("tiles3d", &["gltf"]),
            ("preview", &["gltf"]),
        ],
    ),
    // The readers: one format each.
    (
        "input",
        &[
            ("osm", &[]),
            ("shp", &[]),
            ("geojson", &[]),
            ("gpkg", &[]),
            ("fgb", &[]),
            ("dem", &[]),
        ],
    ),
];

/// What `src/main.rs` may name of the library (`citygen::...`): the commands, nothing deeper.
const MAIN_MAY_IMPORT: &[&str] = &["app"];

/// One `crate::` path found in the code, resolved to module components.
#[derive(Debug, Clone)]
struct Use {
    /// The file's module path (`["export", "ifc", "walls"]`).
    from: Vec<String>,
    /// The resolved path (`["model", "Building"]`).
    to: Vec<String>,
    file: String,
    line: usize,
}

#[derive(Debug, Clone, PartialEq)]
enum Tok {
    Ident(String),
    ColonColon,
    Open,
    Close,
    Comma,
    Semi,
    Star,
    Hash,
    Dollar,
    BracketOpen,
    BracketClose,
    ParenOpen,
    ParenClose,
    Other,
}

/// Tokens with their line numbers, comments and literals left out.
fn tokenize(src: &str) -> Vec<(Tok, usize)> {
    let b = src.as_bytes();
    let mut out = Vec::new();
    let (mut i, mut line) = (0, 1);
    let ident = |c: u8| c.is_ascii_alphanumeric() || c == b'_';
    while i < b.len() {
        let c = b[i];
        match c {
            b'\n' => {
                line += 1;
                i += 1;
            }
            b'/' if b.get(i + 1) == Some(&b'/') => {
                while i < b.len() && b[i] != b'\n' {
                    i += 1;
                }
            }
            b'/' if b.get(i + 1) == Some(&b'*') => {
                let mut depth = 0;
                while i < b.len() {
                    if b[i] == b'/' && b.get(i + 1) == Some(&b'*') {
                        depth += 1;
                        i += 2;
                    } else if b[i] == b'*' && b.get(i + 1) == Some(&b'/') {
                        depth -= 1;
                        i += 2;
                        if depth == 0 {
                            break;
                        }
                    } else {
                        if b[i] == b'\n' {
                            line += 1;
                        }
                        i += 1;
                    }
                }
            }
            b'"' => {
                i += 1;
                while i < b.len() && b[i] != b'"' {
                    if b[i] == b'\\' {
                        i += 1;
                    }
                    if i < b.len() && b[i] == b'\n' {
                        line += 1;
                    }
                    i += 1;
                }
                i += 1;
            }
            b'r' if matches!(b.get(i + 1), Some(b'"') | Some(b'#'))
                && (i == 0 || !ident(b[i - 1])) =>
            {
                // A raw string r"..." or r#"..."#.
                let mut j = i + 1;
                let mut hashes = 0;
                while j < b.len() && b[j] == b'#' {
                    hashes += 1;
                    j += 1;
                }
                if b.get(j) != Some(&b'"') {
                    out.push((Tok::Ident("r".into()), line));
                    i += 1;
                    continue;
                }
                j += 1;
                loop {
                    if j >= b.len() {
                        break;
                    }
                    if b[j] == b'"'
                        && b[j + 1..]
                            .iter()
                            .take(hashes)
                            .filter(|&&h| h == b'#')
                            .count()
                            == hashes
                    {
                        j += 1 + hashes;
                        break;
                    }
                    if b[j] == b'\n' {
                        line += 1;
                    }
                    j += 1;
                }
                i = j;
            }
            b'\'' => {
                // A char literal ('a', '\n', '\u{..}') or a lifetime ('a).
                if b.get(i + 1) == Some(&b'\\') {
                    let mut j = i + 2;
                    while j < b.len() && b[j] != b'\'' {
                        j += 1;
                    }
                    i = j + 1;
                } else if b.get(i + 2) == Some(&b'\'') {
                    i += 3;
                } else {
                    // A lifetime, or a multi-byte char literal.
                    let rest = &src[i + 1..];
                    match rest.chars().next() {
                        Some(ch) if rest[ch.len_utf8()..].starts_with('\'') => {
                            i += 1 + ch.len_utf8() + 1;
                        }
                        _ => i += 1,
                    }
                }
            }
            b':' if b.get(i + 1) == Some(&b':') => {
                out.push((Tok::ColonColon, line));
                i += 2;
            }
            b'{' => {
                out.push((Tok::Open, line));
                i += 1;
            }
            b'}' => {
                out.push((Tok::Close, line));
                i += 1;
            }
            b',' => {
                out.push((Tok::Comma, line));
                i += 1;
            }
            b';' => {
                out.push((Tok::Semi, line));
                i += 1;
            }
            b'*' => {
                out.push((Tok::Star, line));
                i += 1;
            }
            b'#' => {
                out.push((Tok::Hash, line));
                i += 1;
            }
            b'$' => {
                out.push((Tok::Dollar, line));
                i += 1;
            }
            b'[' => {
                out.push((Tok::BracketOpen, line));
                i += 1;
            }
            b']' => {
                out.push((Tok::BracketClose, line));
                i += 1;
            }
            b'(' => {
                out.push((Tok::ParenOpen, line));
                i += 1;
            }
            b')' => {
                out.push((Tok::ParenClose, line));
                i += 1;
            }
            c if ident(c) => {
                let s = i;
                while i < b.len() && ident(b[i]) {
                    i += 1;
                }
                out.push((Tok::Ident(src[s..i].to_string()), line));
            }
            c if c.is_ascii_whitespace() => i += 1,
            _ => {
                out.push((Tok::Other, line));
                i += 1;
            }
        }
    }
    out
}

/// Expands the use tree starting at `toks[i]` (just after `prefix`'s last `::`) into paths.
fn use_tree(
    toks: &[(Tok, usize)],
    mut i: usize,
    prefix: Vec<String>,
    out: &mut Vec<Vec<String>>,
) -> usize {
    let mut path = prefix;
    loop {
        match toks.get(i).map(|t| &t.0) {
            Some(Tok::Ident(s)) => {
                if s != "self" {
                    path.push(s.clone());
                }
                i += 1;
                if toks.get(i).map(|t| &t.0) == Some(&Tok::ColonColon) {
                    i += 1;
                    continue;
                }
                out.push(path);
                return i;
            }
            Some(Tok::Open) => {
                i += 1;
                loop {
                    match toks.get(i).map(|t| &t.0) {
                        Some(Tok::Close) => return i + 1,
                        Some(Tok::Comma) => i += 1,
                        None => return i,
                        _ => i = use_tree(toks, i, path.clone(), out),
                    }
                }
            }
            _ => {
                // `*` or the end of the path.
                out.push(path);
                return i;
            }
        }
    }
}

/// Skips the item starting at `toks[i]`: to its `;` at depth 0 or the end of its first
/// top-level `{ ... }` block. Returns the index after it.
fn skip_item(toks: &[(Tok, usize)], mut i: usize) -> usize {
    // Attributes of the same item first.
    while toks.get(i).map(|t| &t.0) == Some(&Tok::Hash) {
        i = skip_attribute(toks, i);
    }
    let mut depth = 0usize;
    while i < toks.len() {
        match toks[i].0 {
            Tok::Open => depth += 1,
            Tok::Close => {
                depth = depth.saturating_sub(1);
                if depth == 0 {
                    return i + 1;
                }
            }
            Tok::Semi if depth == 0 => return i + 1,
            _ => {}
        }
        i += 1;
    }
    i
}

/// Skips `#[...]` or `#![...]` at `toks[i]`.
fn skip_attribute(toks: &[(Tok, usize)], mut i: usize) -> usize {
    i += 1;
    if toks.get(i).map(|t| &t.0) == Some(&Tok::Other) {
        i += 1; // the `!` of an inner attribute
    }
    if toks.get(i).map(|t| &t.0) != Some(&Tok::BracketOpen) {
        return i;
    }
    let mut depth = 0;
    while i < toks.len() {
        match toks[i].0 {
            Tok::BracketOpen => depth += 1,
            Tok::BracketClose => {
                depth -= 1;
                if depth == 0 {
                    return i + 1;
                }
            }
            _ => {}
        }
        i += 1;
    }
    i
}

/// Whether the attribute at `toks[i]` is `#[cfg(test)]` (also `#[cfg(all(test, ...))]`).
fn is_cfg_test(toks: &[(Tok, usize)], i: usize) -> bool {
    let end = skip_attribute(toks, i);
    let words: Vec<&str> = toks[i..end]
        .iter()
        .filter_map(|t| match &t.0 {
            Tok::Ident(s) => Some(s.as_str()),
            _ => None,
        })
        .collect();
    // `cfg(any(test, feature = "testkit"))` is code that also ships (the test kit): checked.
    words.first() == Some(&"cfg")
        && words.contains(&"test")
        && !words.contains(&"not")
        && !words.contains(&"any")
}

/// The paths a file's non-test code names, with the module each is named in.
struct Scan {
    uses: Vec<Use>,
    /// `mod x;` declared under `#[cfg(test)]`: module paths whose files are test code.
    test_modules: Vec<Vec<String>>,
}

fn scan(file: &str, module: &[String], src: &str) -> Scan {
    let toks = tokenize(src);
    let mut uses = Vec::new();
    let mut test_modules = Vec::new();
    // Inline modules: (name, brace depth at which they close).
    let mut inline: Vec<(String, usize)> = Vec::new();
    let mut depth = 0usize;
    let mut i = 0;
    while i < toks.len() {
        match &toks[i].0 {
            Tok::Hash if is_cfg_test(&toks, i) => {
                let item = skip_attribute(&toks, i);
                // `#[cfg(test)] mod name;` (with any visibility) names a test file.
                let mut m_at = item;
                if toks.get(m_at).map(|t| &t.0) == Some(&Tok::Ident("pub".into())) {
                    m_at += 1;
                    if toks.get(m_at).map(|t| &t.0) == Some(&Tok::ParenOpen) {
                        while toks.get(m_at).is_some_and(|t| t.0 != Tok::ParenClose) {
                            m_at += 1;
                        }
                        m_at += 1;
                    }
                }
                if let (Some(Tok::Ident(m)), Some(Tok::Ident(name)), Some(Tok::Semi)) = (
                    toks.get(m_at).map(|t| &t.0),
                    toks.get(m_at + 1).map(|t| &t.0),
                    toks.get(m_at + 2).map(|t| &t.0),
                ) {
                    if m == "mod" {
                        let mut p = module.to_vec();
                        p.push(name.clone());
                        test_modules.push(p);
                    }
                }
                i = skip_item(&toks, item);
                continue;
            }
            Tok::Ident(m) if m == "mod" => {
                if let (Some(Tok::Ident(name)), Some(Tok::Open)) =
                    (toks.get(i + 1).map(|t| &t.0), toks.get(i + 2).map(|t| &t.0))
                {
                    depth += 1;
                    inline.push((name.clone(), depth));
                    i += 3;
                    continue;
                }
            }
            Tok::Open => depth += 1,
            Tok::Close => {
                if inline.last().map(|l| l.1) == Some(depth) {
                    inline.pop();
                }
                depth = depth.saturating_sub(1);
            }
            Tok::Ident(kw)
                if (kw == "crate" || kw == "super" || kw == "self")
                && toks.get(i + 1).map(|t| &t.0) == Some(&Tok::ColonColon)
                // `$crate::` and `a::self::` are not paths from here.
                && !(i > 0 && matches!(toks[i - 1].0, Tok::ColonColon | Tok::Dollar)) =>
            {
                let line = toks[i].1;
                let here: Vec<String> = module
                    .iter()
                    .cloned()
                    .chain(inline.iter().map(|m| m.0.clone()))
                    .collect();
                let mut base = match kw.as_str() {
                    "crate" => Vec::new(),
                    "self" => here.clone(),
                    _ => {
                        let mut b = here.clone();
                        b.pop();
                        b
                    }
                };
                let mut j = i + 2;
                // super::super::...
                while let (Some(Tok::Ident(s)), Some(Tok::ColonColon)) =
                    (toks.get(j).map(|t| &t.0), toks.get(j + 1).map(|t| &t.0))
                {
                    if s != "super" {
                        break;
                    }
                    base.pop();
                    j += 2;
                }
                let mut paths = Vec::new();
                let end = use_tree(&toks, j, base, &mut paths);
                for to in paths {
                    uses.push(Use {
                        from: module.to_vec(),
                        to,
                        file: file.to_string(),
                        line,
                    });
                }
                i = end.max(i + 1);
                continue;
            }
            _ => {}
        }
        i += 1;
    }
    Scan { uses, test_modules }
}

/// Every `.rs` file under `dir` with its module path (`src/a/mod.rs` is `a`, `src/a/b.rs` is
/// `a::b`); `lib.rs` is the crate root and `main.rs` is left out (another crate).
fn source_files(dir: &Path) -> Vec<(PathBuf, Vec<String>)> {
    fn walk(dir: &Path, module: &[String], out: &mut Vec<(PathBuf, Vec<String>)>) {
        let mut entries: Vec<_> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .collect();
        entries.sort();
        for p in entries {
            let name = p.file_name().unwrap().to_string_lossy().to_string();
            if p.is_dir() {
                let mut m = module.to_vec();
                m.push(name);
                walk(&p, &m, out);
            } else if let Some(stem) = name.strip_suffix(".rs") {
                let mut m = module.to_vec();
                match stem {
                    "mod" | "lib" => {}
                    "main" if module.is_empty() => continue,
                    _ => m.push(stem.to_string()),
                }
                out.push((p, m));
            }
        }
    }
    let mut out = Vec::new();
    walk(dir, &[], &mut out);
    out
}

/// A violation: where, and what.
#[derive(Debug)]
struct Violation(String);

/// Checks the files (path relative to the crate, module path, source) against [`LAYERS`] and
/// for cycles; returns every violation, each naming file and line.
fn check(files: &[(String, Vec<String>, String)], layers: &[(&str, &[&str])]) -> Vec<Violation> {
    check_with(files, layers, &[])
}

/// [`check`], and the direction inside the folders of `siblings` (as [`SIBLINGS`]).
fn check_with(
    files: &[(String, Vec<String>, String)],
    layers: &[(&str, &[&str])],
    siblings: Siblings,
) -> Vec<Violation> {
    let modules: BTreeSet<Vec<String>> = files
        .iter()
        .flat_map(|(_, m, _)| (1..=m.len()).map(move |k| m[..k].to_vec()))
        .collect();
    let mut test_files = BTreeSet::new();
    let mut uses = Vec::new();
    for (file, module, src) in files {
        let s = scan(file, module, src);
        test_files.extend(s.test_modules);
        uses.extend(s.uses);
    }
    let is_test = |m: &[String]| (1..=m.len()).any(|k| test_files.contains(&m[..k]));
    let allowed: BTreeMap<&str, &[&str]> = layers.iter().copied().collect();
    let mut out = Vec::new();
    // Edges per folder: folder -> (child -> (child -> first use)).
    let mut edges: BTreeMap<Vec<String>, BTreeMap<String, BTreeMap<String, Use>>> = BTreeMap::new();
    for u in uses.iter().filter(|u| !is_test(&u.from)) {
        // The longest prefix of the path that is a module.
        let k = (0..=u.to.len())
            .rev()
            .find(|&k| k == 0 || modules.contains(&u.to[..k]))
            .unwrap();
        let to = &u.to[..k];
        if let (Some(a), Some(b)) = (u.from.first(), to.first()) {
            if a != b {
                match allowed.get(a.as_str()) {
                    None => out.push(Violation(format!(
                        "{}:{}: module `{a}` has no row in the layer table (tests/it/architecture.rs LAYERS)",
                        u.file, u.line
                    ))),
                    Some(ok) if !ok.contains(&b.as_str()) => out.push(Violation(format!(
                        "{}:{}: `{a}` imports `crate::{}`, but `{a}` may import only [{}] (layers in ARCHITECTURE.md)",
                        u.file,
                        u.line,
                        u.to.join("::"),
                        ok.join(", ")
                    ))),
                    _ => {}
                }
            }
        }
        // The folder both sit in, and the two children of it that the edge joins.
        let common = u.from.iter().zip(to).take_while(|(x, y)| x == y).count();
        if common < u.from.len() && common < to.len() {
            let folder = u.from[..common].join("::");
            let (a, b) = (u.from[common].as_str(), to[common].as_str());
            let rows = siblings.iter().find(|s| s.0 == folder).map(|s| s.1);
            if let Some(rows) = rows {
                let row = |c: &str| rows.iter().find(|r| r.0 == c).map(|r| r.1);
                if let (Some(ok), Some(_)) = (row(a), row(b)) {
                    if !ok.contains(&b) {
                        out.push(Violation(format!(
                            "{}:{}: `{folder}::{a}` imports `crate::{}`, but inside `{folder}` `{a}` may import only [{}] of its siblings (layers in ARCHITECTURE.md)",
                            u.file,
                            u.line,
                            u.to.join("::"),
                            ok.join(", ")
                        )));
                    }
                }
            }
            edges
                .entry(u.from[..common].to_vec())
                .or_default()
                .entry(u.from[common].clone())
                .or_default()
                .entry(to[common].clone())
                .or_insert_with(|| u.clone());
        }
    }
    for (folder, graph) in &edges {
        for cycle in cycles(graph) {
            let mut steps = Vec::new();
            for w in 0..cycle.len() {
                let (a, b) = (&cycle[w], &cycle[(w + 1) % cycle.len()]);
                let u = &graph[a][b];
                steps.push(format!("{a} -> {b} ({}:{})", u.file, u.line));
            }
            let place = if folder.is_empty() {
                "crate".to_string()
            } else {
                folder.join("::")
            };
            out.push(Violation(format!(
                "import cycle in `{place}`: {}",
                steps.join(", ")
            )));
        }
    }
    out
}

/// `src/main.rs` is another crate: every `citygen::X` path it names must have `X` in `allowed`.
fn check_main(file: &str, src: &str, allowed: &[&str]) -> Vec<Violation> {
    let toks = tokenize(src);
    let mut out = Vec::new();
    for (i, t) in toks.iter().enumerate() {
        if t.0 != Tok::Ident("citygen".into())
            || toks.get(i + 1).map(|t| &t.0) != Some(&Tok::ColonColon)
            || (i > 0 && toks[i - 1].0 == Tok::ColonColon)
        {
            continue;
        }
        let mut paths = Vec::new();
        use_tree(&toks, i + 2, Vec::new(), &mut paths);
        for p in paths {
            let top = p.first().map(String::as_str).unwrap_or("");
            if !allowed.contains(&top) {
                out.push(Violation(format!(
                    "{file}:{}: the binary names `citygen::{}`, but main.rs may use only [{}] (ARCHITECTURE.md)",
                    t.1,
                    p.join("::"),
                    allowed.join(", ")
                )));
            }
        }
    }
    out
}

/// One cycle per strongly connected component of more than one node (Tarjan), as a path.
fn cycles(graph: &BTreeMap<String, BTreeMap<String, Use>>) -> Vec<Vec<String>> {
    let nodes: BTreeSet<&String> = graph
        .keys()
        .chain(graph.values().flat_map(|m| m.keys()))
        .collect();
    let succ = |n: &String| -> Vec<&String> {
        graph.get(n).map(|m| m.keys().collect()).unwrap_or_default()
    };
    let mut found = Vec::new();
    let mut done: BTreeSet<&String> = BTreeSet::new();
    for &start in &nodes {
        if done.contains(start) {
            continue;
        }
        // A cycle through `start`: breadth-first search back to it.
        let mut prev: BTreeMap<&String, &String> = BTreeMap::new();
        let mut queue = std::collections::VecDeque::from([start]);
        let mut hit = None;
        while let Some(n) = queue.pop_front() {
            for s in succ(n) {
                if s == start {
                    hit = Some(n);
                    break;
                }
                if !prev.contains_key(s) && !done.contains(s) {
                    prev.insert(s, n);
                    queue.push_back(s);
                }
            }
            if hit.is_some() {
                break;
            }
        }
        if let Some(mut n) = hit {
            let mut path = vec![n.clone()];
            while n != start {
                n = prev[n];
                path.push(n.clone());
            }
            path.reverse();
            for p in &path {
                done.insert(nodes.iter().find(|x| **x == p).unwrap());
            }
            found.push(path);
        }
        done.insert(start);
    }
    found
}

#[test]
fn the_layers_of_architecture_md_hold_and_no_module_cycle() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let files: Vec<(String, Vec<String>, String)> = source_files(&root.join("src"))
        .into_iter()
        .map(|(p, m)| {
            let rel = p.strip_prefix(root).unwrap().to_string_lossy().to_string();
            (rel, m, std::fs::read_to_string(&p).unwrap())
        })
        .collect();
    assert!(
        files.len() > 50,
        "found only {} files under src/",
        files.len()
    );
    // Every top-level module has a row, and every row a module.
    let tops: BTreeSet<&str> = files
        .iter()
        .filter_map(|(_, m, _)| m.first().map(|s| s.as_str()))
        .collect();
    let rows: BTreeSet<&str> = LAYERS.iter().map(|l| l.0).collect();
    let mut problems: Vec<String> = rows
        .difference(&tops)
        .map(|r| format!("LAYERS has a row for `{r}`, which is not a module of src/"))
        .collect();
    problems.extend(
        check_with(&files, LAYERS, SIBLINGS)
            .into_iter()
            .map(|v| v.0),
    );
    // Every folder of SIBLINGS and every child it lists exist.
    for (folder, rows) in SIBLINGS {
        for (child, ok) in rows.iter() {
            for name in std::iter::once(child).chain(ok.iter()) {
                let m: Vec<String> = folder
                    .split("::")
                    .chain([*name])
                    .map(String::from)
                    .collect();
                if !files.iter().any(|(_, fm, _)| fm.starts_with(&m)) {
                    problems.push(format!(
                        "SIBLINGS names `{}`, which is not a module of src/",
                        m.join("::")
                    ));
                }
            }
        }
    }
    let main = root.join("src/main.rs");
    let main_src = std::fs::read_to_string(&main).unwrap();
    problems.extend(
        check_main("src/main.rs", &main_src, MAIN_MAY_IMPORT)
            .into_iter()
            .map(|v| v.0),
    );
    assert!(
        problems.is_empty(),
        "{} layering violation(s):\n{}",
        problems.len(),
        problems.join("\n")
    );
}

fn file(path: &str, module: &str, src: &str) -> (String, Vec<String>, String) {
    let m = module
        .split("::")
        .filter(|s| !s.is_empty())
        .map(String::from)
        .collect();
    (path.to_string(), m, src.to_string())
}

const TEST_LAYERS: &[(&str, &[&str])] = &[
    ("geometry", &[]),
    ("model", &["geometry"]),
    ("export", &["model"]),
];

#[test]
fn a_downward_import_passes_and_an_upward_one_fails_naming_file_and_line() {
    let ok = [
        file("src/geometry/mod.rs", "geometry", "pub struct Polygon;"),
        file("src/model.rs", "model", "use crate::geometry::Polygon;\n"),
        file(
            "src/export/mod.rs",
            "export",
            "use crate::{model, geometry::Polygon};",
        ),
    ];
    // export -> geometry is not in export's row.
    let v = check(&ok, TEST_LAYERS);
    assert_eq!(v.len(), 1, "{v:?}");
    assert!(
        v[0].0
            .starts_with("src/export/mod.rs:1: `export` imports `crate::geometry::Polygon`"),
        "{}",
        v[0].0
    );

    let up = [
        file("src/geometry/mod.rs", "geometry", "// crate::model in a comment\nfn f() {\n  let s = \"crate::model\";\n  crate::model::Face::new(s);\n}"),
        file("src/model.rs", "model", ""),
    ];
    let v = check(&up, TEST_LAYERS);
    assert_eq!(v.len(), 1, "{v:?}");
    assert!(
        v[0].0
            .starts_with("src/geometry/mod.rs:4: `geometry` imports `crate::model::Face::new`"),
        "{}",
        v[0].0
    );
}

#[test]
fn cycles_between_siblings_are_found_at_any_depth_but_parent_and_child_may_use_each_other() {
    let files = [
        file(
            "src/geometry/mod.rs",
            "geometry",
            "mod roof; pub use roof::build; pub struct Polygon;",
        ),
        file(
            "src/geometry/roof/mod.rs",
            "geometry::roof",
            "use super::Polygon; use self::shapes::x; use super::roof::real;",
        ),
        file(
            "src/geometry/roof/shapes.rs",
            "geometry::roof::shapes",
            "fn f() { super::real::g() }",
        ),
        file(
            "src/geometry/roof/real.rs",
            "geometry::roof::real",
            "\n\nuse crate::geometry::roof::shapes::{a, b::{c}};",
        ),
    ];
    let v = check(&files, TEST_LAYERS);
    assert_eq!(v.len(), 1, "{v:?}");
    assert!(
        v[0].0.contains("import cycle in `geometry::roof`")
            && v[0].0.contains("src/geometry/roof/real.rs:3")
            && v[0].0.contains("src/geometry/roof/shapes.rs:1"),
        "{}",
        v[0].0
    );
}

#[test]
fn test_code_may_import_anything() {
    let files = [
        file("src/geometry/mod.rs", "geometry", "#[cfg(test)]\nmod tests;\n#[cfg(test)]\nmod more { use crate::model::X; }\n#[cfg(test)] use crate::model::Y;\nfn f<'a>(c: char) -> bool { c == '{' }"),
        file("src/model.rs", "model", "pub struct A { b: Option<crate::geometry::Polygon> }"),
        file("src/geometry/tests.rs", "geometry::tests", "use crate::export::Z;"),
        file("src/model.rs", "model", "#[cfg(test)]\npub(crate) mod fixtures;"),
        file("src/model/fixtures.rs", "model::fixtures", "use crate::export::W;"),
    ];
    assert!(check(&files, TEST_LAYERS).is_empty());
}

#[test]
fn a_module_without_a_row_fails() {
    let files = [
        file("src/extra.rs", "extra", "use crate::model::X;"),
        file("src/model.rs", "model", ""),
    ];
    let v = check(&files, TEST_LAYERS);
    assert!(
        v.len() == 1 && v[0].0.contains("module `extra` has no row"),
        "{v:?}"
    );
}

#[test]
fn paths_inside_types_and_expressions_count() {
    let files = [
        file(
            "src/geometry/mod.rs",
            "geometry",
            "fn f(a: &crate::model::A, b: Vec<crate::model::B>) {}",
        ),
        file("src/model.rs", "model", ""),
    ];
    assert_eq!(check(&files, TEST_LAYERS).len(), 2);
}

#[test]
fn a_writer_importing_another_writer_fails_but_shared_files_and_listed_siblings_pass() {
    const SIB: Siblings = &[(
        "export",
        &[
            ("ifc", &[]),
            ("citygml", &[]),
            ("tiles3d", &["gltf"]),
            ("gltf", &[]),
        ],
    )];
    let files = [
        file("src/export/mod.rs", "export", "pub mod step;"),
        file("src/export/step.rs", "export::step", ""),
        file(
            "src/export/ifc/mod.rs",
            "export::ifc",
            "use crate::export::step::StepBuf;\nuse super::citygml::building::id;",
        ),
        file("src/export/citygml/mod.rs", "export::citygml", ""),
        file(
            "src/export/citygml/building.rs",
            "export::citygml::building",
            "",
        ),
        file("src/export/gltf/mod.rs", "export::gltf", ""),
        file(
            "src/export/tiles3d/mod.rs",
            "export::tiles3d",
            "use crate::export::gltf::Group;",
        ),
        file("src/model.rs", "model", ""),
    ];
    let v = check_with(&files, TEST_LAYERS, SIB);
    assert_eq!(v.len(), 1, "{v:?}");
    assert!(
        v[0].0.starts_with(
            "src/export/ifc/mod.rs:2: `export::ifc` imports `crate::export::citygml::building::id`"
        ),
        "{}",
        v[0].0
    );
    // Without the table, the same files pass: the rule is the table's.
    assert!(check(&files, TEST_LAYERS).is_empty());
}

#[test]
fn main_may_name_only_the_commands() {
    let ok = "use citygen::app::{self, Cli};\nfn main() { citygen::app::run(Cli::parse()); }";
    assert!(check_main("src/main.rs", ok, &["app"]).is_empty());
    let bad = "use citygen::app;\n// citygen::kb in a comment\nfn main() {\n  let o = citygen::pipeline::Options::default();\n  use citygen::{app::x, kb::KnowledgeBase};\n}";
    let v = check_main("src/main.rs", bad, &["app"]);
    assert_eq!(v.len(), 2, "{v:?}");
    assert!(
        v[0].0
            .starts_with("src/main.rs:4: the binary names `citygen::pipeline::Options::default`"),
        "{}",
        v[0].0
    );
    assert!(
        v[1].0.contains("`citygen::kb::KnowledgeBase`"),
        "{}",
        v[1].0
    );
}

#[test]
fn a_test_kit_under_cfg_any_test_is_checked_but_cfg_test_is_not() {
    let files = [
        file(
            "src/lib.rs",
            "",
            "#[cfg(any(test, feature = \"testkit\"))]\npub mod testkit;\n#[cfg(test)]\nmod fixtures;",
        ),
        file("src/testkit/mod.rs", "testkit", "use crate::export::Writer;"),
        file("src/fixtures.rs", "fixtures", "use crate::export::Writer;"),
        file("src/export/mod.rs", "export", ""),
    ];
    let layers: &[(&str, &[&str])] = &[("testkit", &[]), ("fixtures", &[]), ("export", &[])];
    let v = check(&files, layers);
    assert_eq!(v.len(), 1, "{v:?}");
    assert!(
        v[0].0
            .starts_with("src/testkit/mod.rs:1: `testkit` imports `crate::export::Writer`"),
        "{}",
        v[0].0
    );
}

/// The backticked paths of ARCHITECTURE.md's code map (`input/osm/pbf.rs`, `kb/`, ...).
fn code_map_paths(doc: &str) -> Vec<String> {
    let start = doc
        .find("## Code map")
        .expect("ARCHITECTURE.md has a `## Code map` section");
    let end = doc[start..].find("\n## ").map_or(doc.len(), |e| start + e);
    doc[start..end]
        .split('`')
        .skip(1)
        .step_by(2)
        .filter(|t| {
            !t.is_empty()
                && (t.ends_with(".rs") || t.ends_with('/'))
                && t.chars()
                    .all(|c| c.is_ascii_alphanumeric() || "_/.-".contains(c))
        })
        .map(String::from)
        .collect()
}

/// What the code map must name for a file of `src/` (one paragraph per module or folder, as
/// rust-analyzer's is): a top-level module file `a.rs`, or a folder, `a/b/` for `a/b/mod.rs`
/// and for `a/b.rs` when `has_children` (its children are in `a/b/`). Files inside a folder
/// are the folder's paragraph's business (named there if it helps, but not required); `None`
/// for those and for test code (`tests.rs`, files under a `tests/` folder).
fn code_map_name(rel: &str, has_children: bool) -> Option<String> {
    let parts: Vec<&str> = rel.split('/').collect();
    if parts.last() == Some(&"tests.rs") || parts[..parts.len() - 1].contains(&"tests") {
        return None;
    }
    if let Some(folder) = rel.strip_suffix("mod.rs") {
        return Some(folder.to_string());
    }
    if parts.len() == 1 {
        return Some(rel.to_string());
    }
    has_children.then(|| format!("{}/", rel.trim_end_matches(".rs")))
}

#[test]
fn the_code_map_of_architecture_md_names_every_module_and_folder_and_nothing_else() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let doc = std::fs::read_to_string(root.join("ARCHITECTURE.md")).unwrap();
    let named: BTreeSet<String> = code_map_paths(&doc).into_iter().collect();
    let src = root.join("src");
    let mut problems = Vec::new();
    for (path, _) in source_files(&src)
        .into_iter()
        .chain([(src.join("main.rs"), Vec::new())])
    {
        let rel = path
            .strip_prefix(&src)
            .unwrap()
            .to_string_lossy()
            .replace('\\', "/");
        let has_children = path.with_extension("").is_dir();
        if let Some(name) = code_map_name(&rel, has_children) {
            if !named.contains(&name) {
                problems.push(format!("src/{rel} is not in the code map (as `{name}`)"));
            }
        }
    }
    for name in &named {
        if !src.join(name).exists() && !root.join(name).exists() {
            problems.push(format!(
                "the code map names `{name}`, which is neither in src/ nor in the repository"
            ));
        }
    }
    assert!(
        problems.is_empty(),
        "ARCHITECTURE.md's code map:\n{}",
        problems.join("\n")
    );
}

#[test]
fn code_map_names_follow_the_tree() {
    assert_eq!(
        code_map_name("input/osm/mod.rs", false).as_deref(),
        Some("input/osm/")
    );
    assert_eq!(code_map_name("input/osm/pbf.rs", false), None);
    assert_eq!(
        code_map_name("geometry/clip.rs", true).as_deref(),
        Some("geometry/clip/")
    );
    assert_eq!(
        code_map_name("prepare.rs", true).as_deref(),
        Some("prepare.rs")
    );
    assert_eq!(
        code_map_name("model.rs", false).as_deref(),
        Some("model.rs")
    );
    assert_eq!(code_map_name("input/osm/tests.rs", false), None);
    assert_eq!(
        code_map_name("derive/roof/tests/real_footprints.rs", false),
        None
    );
    let doc = "x\n## Code map\n- `a/b.rs` — and `c/` and `Polygon` and `x::y`\n## Layers\n`z.rs`";
    assert_eq!(code_map_paths(doc), vec!["a/b.rs", "c/"]);
}

/// No path of one machine in the sources, tests, scripts or examples: tests find tools relative
/// to the checkout or through the validators' variables (`CITYGEN_VALIDATE_HOME`).
#[test]
fn no_absolute_path_of_a_machine_in_the_repository() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    // Built at run time, so that this file does not match itself.
    let roots: Vec<String> = ["root", "home", "work", "tmp"]
        .iter()
        .map(|r| format!("/{r}/"))
        .collect();
    let mut found = Vec::new();
    let mut stack: Vec<PathBuf> = ["src", "tests", "scripts", "examples"]
        .iter()
        .map(|d| root.join(d))
        .collect();
    while let Some(p) = stack.pop() {
        if p.is_dir() {
            // Installed packages (scripts/screenshot's three.js, gitignored) are not ours.
            if p.file_name().is_some_and(|n| n == "node_modules") {
                continue;
            }
            for e in std::fs::read_dir(&p).unwrap() {
                stack.push(e.unwrap().path());
            }
            continue;
        }
        let Ok(text) = std::fs::read_to_string(&p) else {
            continue; // binary fixtures
        };
        for (i, line) in text.lines().enumerate() {
            if roots.iter().any(|r| line.contains(r.as_str())) {
                found.push(format!(
                    "{}:{}: {}",
                    p.strip_prefix(root).unwrap().display(),
                    i + 1,
                    line.trim()
                ));
            }
        }
    }
    assert!(
        found.is_empty(),
        "absolute paths of a machine:\n{}",
        found.join("\n")
    );
}
