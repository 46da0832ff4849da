//! Tests of `rules check`.

use super::names::edit_distance;
use super::*;
use crate::grammar::parse;

const FIG_3_19: &str = include_str!("../../../knowledge_base/rules/fig3_19.cga");
const TOULOUSE: &str = include_str!("../../../knowledge_base/rules/toulouse_downtown.cga");

fn run(src: &str) -> Vec<Diagnostic> {
    let rules = parse(src, "t.cga").unwrap_or_else(|e| panic!("{e}"));
    lint(&rules, src)
}

/// (code, line, col) of each diagnostic, in output order.
fn codes(d: &[Diagnostic]) -> Vec<(&'static str, u32, u32)> {
    d.iter().map(|d| (d.code, d.line, d.col)).collect()
}

#[test]
fn undefined_successor_warns_with_terminals_and_suggestion() {
    let d = run("a -> split(X,1,1,1){windowarae|windowarea|zzz}\n\
                 windowarea -> {wall|window|door|balcony}\n");
    assert_eq!(
        codes(&d),
        [("undefined-symbol", 1, 21), ("undefined-symbol", 1, 43)]
    );
    assert!(d.iter().all(|d| d.severity == Severity::Warning));
    assert!(d[0].message.contains("(wall, window, door, balcony)"));
    assert!(
        d[0].message.ends_with("did you mean `windowarea`?"),
        "{}",
        d[0].message
    );
    // Nothing within 2 edits of `zzz`: no suggestion.
    assert!(!d[1].message.contains("did you mean"), "{}", d[1].message);
    assert!(!has_errors(&d));
}

#[test]
fn undefined_successor_suggests_a_terminal_but_not_for_one_letter_names() {
    let d = run("a -> split(X,1,1){windw|b}\n");
    assert_eq!(
        codes(&d),
        [("undefined-symbol", 1, 19), ("undefined-symbol", 1, 25)]
    );
    assert!(d[0].message.ends_with("did you mean `window`?"));
    // `b` is one edit from the defined `a`, but that is the whole name: no suggestion.
    assert!(!d[1].message.contains("did you mean"), "{}", d[1].message);
}

#[test]
fn unreachable_rules_are_reported_once_per_predecessor_with_their_user() {
    let d = run("a -> b\nb -> wall\nc -> d = 0.5\nc -> wall = 0.5\nd -> window\n");
    assert_eq!(
        codes(&d),
        [("unreachable-rule", 3, 1), ("unreachable-rule", 5, 1)]
    );
    assert!(
        d[0].message.starts_with("rules for `c` are never used"),
        "{}",
        d[0].message
    );
    assert!(d[0].message.contains("axiom `a`"));
    assert!(
        d[1].message.ends_with("(only used by the unreachable `c`)"),
        "{}",
        d[1].message
    );
}

#[test]
fn probabilities_above_one_are_an_error() {
    let d = run("a -> b = 0.7\na -> c = 0.5\nb -> wall\nc -> wall\n");
    assert_eq!(codes(&d), [("probability-sum", 1, 1)]);
    assert_eq!(d[0].severity, Severity::Error);
    assert!(
        d[0].message.contains("sum to 1.2 > 1 (lines 1, 2)"),
        "{}",
        d[0].message
    );
    assert!(has_errors(&d));
}

#[test]
fn explicit_probabilities_above_one_starve_the_implicit_rules() {
    let d = run("a -> b = 0.7\na -> wall\na -> c = 0.5\nb -> wall\nc -> wall\n");
    assert_eq!(codes(&d), [("probability-sum", 1, 1)]);
    assert_eq!(d[0].severity, Severity::Error);
    assert!(
        d[0].message
            .contains("without probability (line 2) get weight 0"),
        "{}",
        d[0].message
    );
}

#[test]
fn explicit_probabilities_below_one_are_normalised_with_a_warning() {
    let d = run("a -> b = 0.3\na -> c = 0.3\nb -> wall\nc -> wall\n");
    assert_eq!(codes(&d), [("probability-sum", 1, 1)]);
    assert_eq!(d[0].severity, Severity::Warning);
    assert!(d[0].message.contains("sum to 0.6 < 1"), "{}", d[0].message);
    assert!(d[0].message.contains("normalised"), "{}", d[0].message);
    // All zero: selection falls back to uniform, and says so.
    let d = run("a -> wall = 0\na -> window = 0\n");
    assert_eq!(codes(&d), [("probability-sum", 1, 1)]);
    assert!(d[0].message.contains("uniformly"), "{}", d[0].message);
}

#[test]
fn implicit_rule_after_explicit_ones_reaching_one_is_never_chosen() {
    let d = run("a -> wall = 0.5\na -> window = 0.5\na -> door\n");
    assert_eq!(codes(&d), [("probability-sum", 3, 1)]);
    assert_eq!(d[0].severity, Severity::Warning);
    assert!(d[0].message.contains("never chosen"), "{}", d[0].message);
    // An implicit rule that takes the remainder is the normal way to write a default.
    assert!(run("a -> wall = 0.3\na -> window\n").is_empty());
}

#[test]
fn negative_probability_is_an_error() {
    // The parser refuses `= -0.1`; a rule set built otherwise is still checked.
    let src = "a -> wall = 0.5\na -> window = 0.5\n";
    let mut rules = parse(src, "t.cga").unwrap_or_else(|e| panic!("{e}"));
    rules.rules[1].prob = Some(-0.1);
    let d = lint(&rules, src);
    assert!(
        d.iter()
            .any(|d| d.code == "probability-sum" && d.line == 2 && d.severity == Severity::Error),
        "{d:?}"
    );
}

#[test]
fn duplicate_deterministic_rules_are_an_error_that_says_they_are_drawn() {
    let d = run("a -> b\nb -> wall\nb -> window\nb -> wall\n");
    assert_eq!(
        codes(&d),
        [("duplicate-rule", 3, 1), ("duplicate-rule", 4, 1)]
    );
    assert!(d.iter().all(|d| d.severity == Severity::Error));
    // The parser shares the weight equally: 1/3 each, no shadowing.
    assert!(
        d[0].message
            .contains("each is chosen at random with probability 0.333333"),
        "{}",
        d[0].message
    );
    assert!(d[0].message.contains("the first is at line 2"));
    assert!(!d[0].message.contains("identical"));
    assert!(d[1].message.contains("identical"), "{}", d[1].message);
    // Cross-check against the parser's resolution.
    let rules = parse("a -> wall\na -> window\n", "t.cga").unwrap_or_else(|e| panic!("{e}"));
    let w: Vec<f64> = rules.rules_for("a").iter().map(|x| x.1).collect();
    assert_eq!(w, [0.5, 0.5]);
}

#[test]
fn duplicate_rules_starved_by_explicit_ones_say_never_chosen() {
    let d = run("a -> wall = 1\na -> window\na -> door\n");
    let dup: Vec<_> = d.iter().filter(|d| d.code == "duplicate-rule").collect();
    assert_eq!(dup.len(), 1);
    assert_eq!(dup[0].line, 3);
    assert!(
        dup[0].message.contains("never chosen"),
        "{}",
        dup[0].message
    );
}

#[test]
fn operation_on_the_wrong_shape_kind() {
    // comp on the lot itself: always fails.
    let d = run("lot -> comp(){side:wall}\n");
    assert_eq!(codes(&d), [("op-shape-mismatch", 1, 1)]);
    assert_eq!(d[0].severity, Severity::Error);
    assert!(d[0].message.contains("extrude first"), "{}", d[0].message);
    // split(Y) and R on facades, split(Z) on a lot.
    let d = run("lot -> extrude(9){v}\nv -> comp(){side:f|top:r}\n\
                 f -> split(Y,1){wall}\nr -> R(Z,10){wall}\n");
    assert_eq!(
        codes(&d),
        [("op-shape-mismatch", 3, 1), ("op-shape-mismatch", 4, 1)]
    );
    assert!(d[0].message.contains("`split(Y, ...)`"), "{}", d[0].message);
    let d = run("lot -> split(Z,3){wall}\n");
    assert_eq!(codes(&d), [("op-shape-mismatch", 1, 1)]);
    // A symbol met both as a lot and as a volume: warning only.
    let d = run("lot -> m = 0.5\nlot -> extrude(3){m} = 0.5\nm -> comp(){side:wall}\n");
    assert_eq!(codes(&d), [("op-shape-mismatch", 3, 1)]);
    assert_eq!(d[0].severity, Severity::Warning);
    assert!(d[0].message.contains("can be a lot"), "{}", d[0].message);
    // extrude of a facade is supported (a balcony-like volume): no finding.
    assert!(run("lot -> extrude(9){v}\nv -> comp(){side:f}\nf -> extrude(1){wall}\n").is_empty());
}

#[test]
fn recursion_without_shrinking_may_not_terminate() {
    let d = run("a -> S(sx,sy,sz){a}\n");
    assert_eq!(codes(&d), [("non-terminating", 1, 1)]);
    assert_eq!(d[0].severity, Severity::Warning);
    assert_eq!(
        d[0].message,
        "the rules for `a` recurse through operations that never drop the shape (S): may not \
         terminate; the derivation stops at the depth cap (max_depth, 64 by default)"
    );
    // A two-symbol cycle: one finding, at its first rule, naming both.
    let d = run("a -> T(0,0,1){b}\nb -> {a:color=red}\n");
    assert_eq!(codes(&d), [("non-terminating", 1, 1)]);
    assert!(d[0].message.contains("`a`, `b`"), "{}", d[0].message);
    assert!(d[0].message.contains("(T, relabel)"), "{}", d[0].message);
    // An alternative way out.
    let d = run("a -> S(sx,sy,sz){a} = 0.5\na -> wall = 0.5\n");
    assert_eq!(codes(&d), [("non-terminating", 1, 1)]);
    assert!(d[0]
        .message
        .contains("unless another alternative is chosen"));
    // A split that drops the recursive piece once it no longer fits is fine.
    assert!(run("a -> split(X,1,sx-1){wall|a}\n").is_empty());
}

/// The message of the only finding of `src`, which must be a warning `code` at line:col.
fn only(src: &str, code: &'static str, line: u32, col: u32) -> String {
    let d = run(src);
    assert_eq!(codes(&d), [(code, line, col)], "{src}: {d:?}");
    assert_eq!(d[0].severity, Severity::Warning);
    d[0].message.clone()
}

#[test]
fn a_repeat_that_reproduces_itself_never_terminates() {
    // The bomb: each copy of a 1 m pattern on a piece 1-2 m long is one copy of the
    // same length, for ever (on a lot and a volume; a face too, the pattern being one size).
    let m = only("a -> repeat(X, 1){a}\n", "non-terminating", 1, 1);
    assert_eq!(
        m,
        "the rules for `a` recurse through operations that never drop the shape (repeat; a \
         one-size repeat makes one copy of the same length again): may not terminate; the \
         derivation stops at the depth cap (max_depth, 64 by default)"
    );
    only(
        "lot -> extrude(9){v}\nv -> comp(){side:f}\nf -> repeat(X, 1){f}\n",
        "non-terminating",
        3,
        1,
    );
    // On a face, a two-size pattern drops its pieces once the face is narrower than it.
    assert!(
        run("lot -> extrude(9){v}\nv -> comp(){side:f}\nf -> repeat(X, 2, 1){f|wall}\n").is_empty()
    );
    // ... and on a volume, a two-size pattern makes a share of the parent (2/3 here),
    // which shrinks until it is thinner than 1e-9 m: not judged.
    assert!(run("lot -> extrude(9){v}\nv -> repeat(X, 2, 1){v|wall}\n").is_empty());
    // The first piece of a constant size: 1 m, then 1 m again, for ever (the second piece
    // comes after it, so it shrinks).
    let m = only(
        "lot -> extrude(9){a}\na -> split(Z, 1, 1){a|a}\n",
        "non-terminating",
        2,
        1,
    );
    assert!(m.contains("(split)"), "{m}");
    only(
        "lot -> extrude(9){a}\na -> split(X, 0, 1, sx - 1){wall|a|wall}\n",
        "non-terminating",
        2,
        1,
    );
    // A recursion the axiom never reaches is only an unreachable rule.
    let d = run("lot -> extrude(9){wall}\nz -> {z|z}\n");
    assert_eq!(codes(&d), [("unreachable-rule", 2, 1)]);
    // A one-entry split of a volume gives the piece the whole length again.
    only(
        "lot -> extrude(9){v}\nv -> split(X, sx - 1){v}\n",
        "non-terminating",
        2,
        1,
    );
    // A box's front is always there: comp and extrude make a recursion of one face.
    let m = only(
        "lot -> extrude(9){v}\nv -> comp(){front:f}\nf -> extrude(1){v}\n",
        "non-terminating",
        2,
        1,
    );
    assert!(
        m.ends_with("(max_depth, 64 by default), at LOD3 and LOD4 (where comp is applied)"),
        "{m}"
    );
}

#[test]
fn recursion_that_multiplies_the_shapes_is_exponential_growth() {
    let m = only(
        "a -> split(X, sx/2, sx/2){a|a}\n",
        "exponential-growth",
        1,
        1,
    );
    assert_eq!(
        m,
        "the rules for `a` recurse through `split(X, ...)`, which makes 2 shapes of the \
         recursion from one: the shape count grows 2× per level and may reach 2^depth \
         shapes; the derivation stops at the shape cap (max_shapes, 100000 by default) about \
         17 levels down"
    );
    // A relabel to two copies of itself: growth, reported once (not also non-terminating).
    let m = only("a -> {a|a}\n", "exponential-growth", 1, 1);
    assert!(m.contains("through `relabel`, which makes 2 shapes"), "{m}");
    // A three-way repeat pattern, at the rule that branches.
    let m = only(
        "lot -> extrude(9){v}\nv -> repeat(X, 1, 1, 1){v|w|v}\nw -> {v}\n",
        "exponential-growth",
        2,
        1,
    );
    assert!(
        m.contains("`v`, `w`") && m.contains("makes 3 shapes"),
        "{m}"
    );
    // comp's four side faces of a box, each extruded back into a volume: 4 every 2 levels.
    let m = only(
        "lot -> extrude(3){v}\nv -> comp(){side:f}\nf -> extrude(1){v}\n",
        "exponential-growth",
        2,
        1,
    );
    assert!(
        m.contains("makes 4 shapes") && m.contains("grows 2× per level"),
        "{m}"
    );
    assert!(
        m.ends_with(", at LOD3 and LOD4 (where comp is applied)"),
        "{m}"
    );
    // A repeat whose length an extrude restores: its count is renewed at every trip.
    let m = only(
        "lot -> extrude(10){b}\nb -> repeat(Z, 1){c}\nc -> extrude(10){b}\n",
        "exponential-growth",
        2,
        1,
    );
    assert!(
        m.contains("whose count of copies is renewed at every trip"),
        "{m}"
    );
    assert!(m.contains("may multiply by a repeat's count"), "{m}");
    // Probabilities: 3 pieces with p = 0.5 is 1.5 per level on average.
    let m = only(
        "a -> rsplit(X, 1, 1, 1){a|a|a} = 0.5\na -> wall = 0.5\n",
        "exponential-growth",
        1,
        1,
    );
    assert!(
        m.contains("grows 1.50× per level on average (with the other alternatives' probabilities)"),
        "{m}"
    );
    assert!(m.contains("about 29 levels down"), "{m}");
}

#[test]
fn critical_and_subcritical_branching() {
    // Two copies half the time: on average one, but a fat tail (with an extrude in front,
    // 7 of 300 seeds reached max_depth through `rules derive`).
    let m = only(
        "a -> {a|a} = 0.5\na -> wall = 0.5\n",
        "exponential-growth",
        1,
        1,
    );
    assert!(m.contains("a critical branching process"), "{m}");
    // 0.6 per level on average: ends quickly, not reported.
    assert!(run("a -> rsplit(X, 0.5, 0.5){a|a} = 0.3\na -> wall = 0.7\n").is_empty());
}

#[test]
fn bounded_recursion_is_not_reported() {
    // Each trip takes a fixed metre off an axis that nothing in the recursion enlarges.
    for src in [
        "a -> split(X, 1, sx - 1){wall|a}\n",
        "a -> split(X, 1, sx/2 - 1, sx/2){wall|a|a}\n",
        // On faces: `E - c` shrinks (the rest is a wall, never given to the last piece).
        "lot -> extrude(9){v}\nv -> comp(){side:f}\nf -> split(X, sx - 1){f}\n",
        "lot -> extrude(9){v}\nv -> comp(){side:f}\nf -> split(X, sx/2 - 0.5, sx/2 - 0.5){f|f}\n",
        // rand of constants is a positive constant.
        "a -> split(Y, rand(0.5, 1), sy - 1){wall|a}\n",
    ] {
        let d = run(src);
        assert!(d.is_empty(), "{src}: {d:?}");
    }
    // A split piece that only shrinks by a factor, or on a volume whose last piece takes
    // the rest, is not bounded by this rule: growth through two of them is reported.
    only(
        "a -> split(X, sx/2, sx/2){a|a}\n",
        "exponential-growth",
        1,
        1,
    );
    only(
        "lot -> extrude(9){v}\nv -> split(X, sx/2 - 0.5, sx/2 - 0.5){v|v}\n",
        "exponential-growth",
        2,
        1,
    );
    // A fixed piece does not bound the recursion when the recursion can grow that axis
    // back: S scales X up again.
    only(
        "a -> split(X, 1, sx - 1){wall|b}\nb -> S(sx*2, sy, sz){a|a}\n",
        "exponential-growth",
        2,
        1,
    );
    // ... nor does an S that keeps or shrinks the axis when it makes two copies: the copies
    // do not share the length, so the count doubles at every trip within the bounded depth.
    only(
        "a -> split(X, 1, sx - 1){wall|b}\nb -> S(sx*rand(0.5,1), sy, sz){a|a}\n",
        "exponential-growth",
        2,
        1,
    );
    // One copy is fine.
    assert!(
        run("a -> split(X, 1, sx - 1){wall|b}\nb -> S(sx*rand(0.5,1), sy, sz){a}\n").is_empty()
    );
}

#[test]
fn shipped_and_compiled_rulesets_have_no_recursion_findings() {
    for (name, src) in [
        ("fig3_19.cga", FIG_3_19),
        ("toulouse_downtown.cga", TOULOUSE),
    ] {
        let rules = parse(src, name).unwrap_or_else(|e| panic!("{e}"));
        let d = lint(&rules, src);
        assert!(
            !d.iter()
                .any(|d| d.code == "exponential-growth" || d.code == "non-terminating"),
            "{name}: {d:?}"
        );
    }
    // Every appearance of every zone of the shipped KB, as `kb compile` prints it, and the
    // compiler's variants (balconies, irregular and short windows).
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("knowledge_base/kb.xml");
    let (kb, _) = crate::kb::KnowledgeBase::load(&path).unwrap_or_else(|e| panic!("{e}"));
    let mut texts: Vec<(String, String)> = Vec::new();
    for z in kb.zones() {
        texts
            .extend(crate::kb::tools::compile_zone(&kb, &z.path).unwrap_or_else(|e| panic!("{e}")));
    }
    let tags = crate::input::tags::BuildingTags::default();
    let (style, _) = kb.style_for(0, &tags, &mut crate::rng::Rng::new(1, 1));
    for balconies in [0.0, 0.5, 1.0] {
        for wh in [
            crate::kb::WindowHeight::Tall,
            crate::kb::WindowHeight::Short,
            crate::kb::WindowHeight::Irregular,
        ] {
            let s = crate::kb::Style {
                balconies,
                window_height: wh,
                ..style.clone()
            };
            texts.push((
                format!("{balconies} {wh:?}"),
                crate::kb::compile::ruleset_text(&s),
            ));
        }
    }
    assert!(texts.len() > 20, "{}", texts.len());
    for (label, text) in &texts {
        let rules = parse(text, label).unwrap_or_else(|e| panic!("{label}: {e}"));
        let d = lint(&rules, text);
        assert!(d.is_empty(), "{label}: {d:?}\n{text}");
    }
}

#[test]
fn toulouse_downtown_reports_exactly_the_floor2_branch() {
    let rules = parse(TOULOUSE, "toulouse_downtown.cga").unwrap_or_else(|e| panic!("{e}"));
    let d = lint(&rules, TOULOUSE);
    assert!(!has_errors(&d), "{d:?}");
    let got: Vec<(&str, u32, &str)> = d
        .iter()
        .map(|d| {
            let sym = d.line_text.split(" ->").next().unwrap_or("");
            (d.code, d.line, sym)
        })
        .collect();
    assert_eq!(
        got,
        [
            ("unreachable-rule", 14, "floor2"),
            ("unreachable-rule", 16, "face2"),
            ("unreachable-rule", 18, "upper_face2"),
            ("unreachable-rule", 21, "windowarea2"),
            ("unreachable-rule", 23, "vwindow2"),
            ("unreachable-rule", 26, "bwindow2"),
        ]
    );
    assert!(d.iter().all(|d| d.severity == Severity::Warning));
    assert!(d[0]
        .message
        .contains("`floor2` is not reachable from the axiom `lot`"));
    assert!(d[1]
        .message
        .ends_with("(only used by the unreachable `floor2`)"));
}

#[test]
fn figure_3_19_is_clean() {
    let rules = parse(FIG_3_19, "fig3_19.cga").unwrap_or_else(|e| panic!("{e}"));
    let d = lint(&rules, FIG_3_19);
    assert!(!has_errors(&d));
    assert!(d.is_empty(), "{d:?}");
}

#[test]
fn errors_and_warnings_together_sorted_by_place() {
    let src = "a -> b\na -> c\nb -> windw\nc -> wall\n";
    let d = run(src);
    assert_eq!(
        codes(&d),
        [("duplicate-rule", 2, 1), ("undefined-symbol", 3, 6)]
    );
    assert_eq!(d[0].severity, Severity::Error);
    assert_eq!(d[1].severity, Severity::Warning);
    assert!(has_errors(&d));
    assert!(!has_errors(&d[1..]));
    assert_eq!(d, run(src), "deterministic");
}

#[test]
fn display_has_location_code_source_line_and_caret() {
    let src = "a -> b = 0.5\r\n\ta -> c = 0.6\r\nb -> wall\nc -> winow\n";
    let d = run(src);
    assert_eq!(
        codes(&d),
        [("probability-sum", 1, 1), ("undefined-symbol", 4, 6)]
    );
    assert_eq!(
        d[1].to_string(),
        "t.cga:4:6: warning[undefined-symbol]: `winow` has no rule and is not a known \
         terminal (wall, window, door, balcony): it becomes a leaf of the shape tree with no \
         element kind; did you mean `window`?\nc -> winow\n     ^"
    );
    assert!(d[0]
        .to_string()
        .starts_with("t.cga:1:1: error[probability-sum]: "));
    assert!(d[0].to_string().ends_with("\na -> b = 0.5\n^"));
    // Tabs are kept in the caret line so that it lines up; CR is not shown.
    let d = run("b -> wall\n\tb -> window\n");
    assert_eq!(codes(&d), [("duplicate-rule", 2, 2)]);
    assert!(
        d[0].to_string().ends_with("\n\tb -> window\n\t^"),
        "{:?}",
        d[0].to_string()
    );
}

#[test]
fn mismatched_source_gives_empty_lines_not_a_panic() {
    let rules = parse("a -> b\na -> c\n", "t.cga").unwrap_or_else(|e| panic!("{e}"));
    let d = lint(&rules, "");
    assert!(!d.is_empty());
    assert!(d.iter().all(|d| d.line_text.is_empty()));
    assert!(d[0].to_string().ends_with("\n\n^"));
}

#[test]
fn findings_past_the_cap_are_counted_and_long_lines_are_windowed() {
    // One line of 300 undefined successors (about 2,000 characters).
    let succ: Vec<String> = (0..300).map(|i| format!("u{i}")).collect();
    let sizes = vec!["1"; 300].join(",");
    let src = format!("lot -> split(X,{sizes}){{{}}}\n", succ.join("|"));
    let d = run(&src);
    assert_eq!(d.len(), MAX_PER_CODE + 1, "{:?}", codes(&d));
    assert!(d.iter().all(|d| d.code == "undefined-symbol"));
    // The first 100 in file order are listed, then one diagnostic at the 101st.
    let line = src.lines().next().unwrap_or_default();
    let col_of = |name: &str| {
        line.find(&format!("{{{name}|"))
            .or_else(|| line.find(&format!("|{name}|")))
            .map(|i| i as u32 + 2)
    };
    assert_eq!(Some(d[0].col), col_of("u0"));
    assert_eq!(Some(d[99].col), col_of("u99"));
    assert_eq!(Some(d[100].col), col_of("u100"));
    assert_eq!(
        d[100].message,
        "200 more `undefined-symbol` findings from here on are not shown: rules check lists \
         at most 100 of each kind"
    );
    for x in &d {
        // 80 characters each side, two ellipses: never the whole 2,000-character line.
        assert!(
            x.line_text.chars().count() <= 2 * CONTEXT_CHARS + 2,
            "{}",
            x.line_text
        );
        // The caret is under the successor's first character.
        let under: String = x
            .line_text
            .chars()
            .skip(x.text_col as usize - 1)
            .take(2)
            .collect();
        assert!(under.starts_with('u'), "{under:?} in {:?}", x.line_text);
        let shown = x.to_string();
        let caret = shown.lines().last().unwrap_or_default();
        assert_eq!(caret.chars().count() as u32, x.text_col, "{shown}");
    }
    assert!(d[50].line_text.starts_with('…') && d[50].line_text.ends_with('…'));
    // A short line is kept whole, with the caret at its column.
    let d = run("lot -> {zz}\n");
    assert_eq!((d[0].line_text.as_str(), d[0].text_col), ("lot -> {zz}", 9));
}

#[test]
fn line_window_cuts_at_characters_not_bytes() {
    let line = format!("{}X{}", "é".repeat(200), "ü".repeat(200));
    let pos = line.find('X').unwrap_or_default();
    let (shown, col) = line_window(&line, pos);
    assert_eq!(shown.chars().count(), 1 + 2 * CONTEXT_CHARS + 1);
    assert_eq!(shown.chars().nth(col as usize - 1), Some('X'));
    assert!(shown.starts_with("…é") && shown.ends_with("ü…"));
    // At the start of a long line: no leading ellipsis.
    let (shown, col) = line_window(&line, 0);
    assert_eq!(col, 1);
    assert!(shown.starts_with('é') && shown.ends_with('…'));
    assert_eq!(line_window("", 0), (String::new(), 1));
}

#[test]
fn generated_files_with_thousands_of_symbols_lint_in_linear_work() {
    // A cycle of 20,000 symbols through T: one finding, with a bounded list of names.
    let n = 20_000;
    let mut src = String::from("lot -> s0\n");
    for i in 0..n {
        src.push_str(&format!("s{i} -> T(0,0,1){{s{}}}\n", (i + 1) % n));
    }
    let d = run(&src);
    assert_eq!(codes(&d), [("non-terminating", 2, 1)]);
    assert!(
        d[0].message
            .contains("`s0`, `s1`, `s2`, `s3`, `s4`, `s5`, `s6`, `s7` and 19992 more"),
        "{}",
        d[0].message
    );
    // A chain of 20,000 unreachable rules: each names its one user; 100 listed.
    let mut src = String::from("lot -> wall\n");
    for i in 0..n {
        src.push_str(&format!("c{i} -> c{}\n", i + 1));
    }
    let d: Vec<Diagnostic> = run(&src)
        .into_iter()
        .filter(|d| d.code == "unreachable-rule")
        .collect();
    assert_eq!(d.len(), MAX_PER_CODE + 1);
    assert!(
        d[1].message
            .ends_with("(only used by the unreachable `c0`)"),
        "{}",
        d[1].message
    );
    assert!(d[MAX_PER_CODE]
        .message
        .starts_with("19900 more `unreachable-rule` findings"));
    // 50,000 probabilities of one predecessor: one error listing 8 lines.
    let src = "lot -> wall = 0.00004\n".repeat(50_000);
    let d = run(&src);
    assert_eq!(codes(&d), [("probability-sum", 1, 1)]);
    assert!(
        d[0].message
            .contains("(lines 1, 2, 3, 4, 5, 6, 7, 8 and 49992 more)"),
        "{}",
        d[0].message
    );
}

#[test]
fn long_names_are_cut_in_messages_and_get_no_suggestion() {
    let long = "x".repeat(10_000);
    let src = format!("lot -> {{{long}|{long}y}}\n{long}z -> wall\n");
    let d = run(&src);
    assert_eq!(
        codes(&d),
        [
            ("undefined-symbol", 1, 9),
            ("undefined-symbol", 1, 10_010),
            ("unreachable-rule", 2, 1)
        ]
    );
    for x in &d {
        assert!(x.message.len() < 400, "{}", x.message);
        assert!(!x.message.contains("did you mean"), "{}", x.message);
    }
    assert!(d[0]
        .message
        .starts_with(&format!("`{}…` has no rule", "x".repeat(MAX_NAME_CHARS))));
}

#[test]
fn suggestions_stop_when_their_budget_is_spent() {
    let candidates = [("window", 6), ("wall", 4)];
    let mut budget = 1_000;
    assert_eq!(suggest("windw", &candidates, &mut budget), Some("window"));
    assert_eq!(
        budget,
        1_000 - 6 * 7 - 6 * 5,
        "one table per measured candidate"
    );
    // Not enough left for the first table: no suggestion, nothing spent.
    let mut budget = 10;
    assert_eq!(suggest("windw", &candidates, &mut budget), None);
    assert_eq!(budget, 10);
    // A file of thousands of similar names still lints, and the first ones get suggestions.
    let succ: Vec<String> = (0..5_000).map(|i| format!("d{i:04}x")).collect();
    let mut src = format!("lot -> {{{}}}\n", succ.join("|"));
    for i in 0..5_000 {
        src.push_str(&format!("d{i:04} -> wall\n"));
    }
    let d = run(&src);
    assert!(
        d[0].message.ends_with("did you mean `d0000`?"),
        "{}",
        d[0].message
    );
}

#[test]
fn edit_distance_counts_characters() {
    assert_eq!(edit_distance("windowarae", "windowarea"), 2);
    assert_eq!(edit_distance("windw", "window"), 1);
    assert_eq!(edit_distance("", "abc"), 3);
    assert_eq!(edit_distance("façade", "facade"), 1);
    assert_eq!(edit_distance("same", "same"), 0);
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]
    /// Any rule file assembled from valid pieces lints without panicking, sorted and
    /// deterministically, with every diagnostic on a line of the file.
    #[test]
    fn lint_is_total_sorted_and_deterministic(
        lines in proptest::collection::vec(
            (0usize..5, 0usize..7, 0usize..5, 0usize..5, proptest::option::of(0u8..=10)),
            1..10,
        )
    ) {
        let syms = ["a", "b", "c", "wall", "windw"];
        let mut src = String::new();
        for (p, op, s1, s2, prob) in &lines {
            let (p, s1, s2) = (syms[*p], syms[*s1], syms[*s2]);
            let body = match op {
                0 => s1.to_string(),
                1 => format!("extrude(3){{{s1}}}"),
                2 => format!("comp(){{side:{s1}|top:{s2}}}"),
                3 => format!("split(Z,1,1){{{s1}|{s2}}}"),
                4 => format!("split(Y,1){{{s1}}}"),
                5 => format!("S(sx,sy,sz){{{s1}}}"),
                _ => format!("R(Z,5){{{s1}|{s2}}}"),
            };
            let prob = prob.map_or(String::new(), |q| format!(" = {}", f64::from(q) / 10.0));
            src.push_str(&format!("{p} -> {body}{prob}\n"));
        }
        let rules = parse(&src, "p.cga").unwrap_or_else(|e| panic!("{e}\n{src}"));
        let d = lint(&rules, &src);
        let n = src.lines().count() as u32;
        for w in d.windows(2) {
            proptest::prop_assert!((w[0].line, w[0].col, w[0].code) <= (w[1].line, w[1].col, w[1].code));
        }
        for x in &d {
            proptest::prop_assert!(x.line >= 1 && x.line <= n && !x.line_text.is_empty());
        }
        proptest::prop_assert_eq!(d, lint(&rules, &src));
    }
}
