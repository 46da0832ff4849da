//! Tests of the SELEX front end: the seed's printed programs (golden parses), one test per
//! error kind (message, line, column), `check`'s warnings, caps, and property tests that no
//! input panics.
//!
//! The listings are copied from the seed (seed file 000_64a5ceb3d4de14d8.txt of the shared seeds) with the
//! listing's line numbers removed. The only fixes are transcription breaks: a line wrapped
//! inside a string (`createGrid("\n   main_front_grid", ...)`) is joined, since a string does not
//! cross a line, and a comment wrapped onto a second line (Jiang's C3 and C7) is joined. Rules
//! wrapped across lines are kept as printed (whitespace is free).

use proptest::prelude::*;

use super::ast::*;
use super::parser::*;

/// Jiang et al. (2018) Fig. 13 (seed L508-L546). The seed elides the arguments of `addShape`
/// and `createGrid` with `...`; here they are plausible values: the facade is `facW` × `facH`,
/// the grid has 4 rows (gnd, mid, mid, top) and 5 columns (left, left, mid, right, right), so
/// C6's ledges pair the two left cells, C7's window groups the two right cells and C9's
/// `rowRange(2, -2)` is the second and third floor.
const JIANG_FIG13: &str = r#"##C1:
facW = 17.6; facH = 12.8;
##C2:
{<> -> addShape("facade", facW, facH);}
##C3: split facade into cells and set it as the working node
{<[label == "facade"]> -> createGrid("main", ["gnd", "mid", "mid", "top"], ["left", "left", "mid", "right", "right"]);}
{<[label == "facade"]/[label == main]> -> setHeadNode();}
##C4: add a door touching the ground;
{<cell()[colLabel == "mid"][rowLabel == "gnd"]> ->
addShape("door", 1.4, 2.6);}
##C5: add the glass windows above the door
{<cell()[colLabel == "mid"][rowIdx > 1][::groupCols()]> ->
addShape("glass");}
##C6: add ledges at the left side of the top floor.
{<cell()[colLabel == "left"][rowLabel == "top"]
[::groupPairs()]> ->
addShape("ledge", facW / 5 * 2, 0.2, 0.4);}
##C7: add the two-cell window at the right side the top floor.
{<cell()[colLabel == "right"][rowLabel == "top"]
[::groupRows()]> ->
addShape("win4", 5.2, 1.8);}
##C8: add windows on the ground floor.
{<cell()[colLabel in ("left", "right")][rowIdx == 1]> ->
addShape("win1", 1.6, 2.2);}
##C9: add windows on the second and third floor.
{<cell()[colLabel in ("left", "right")][rowIdx in
rowRange(2, -2)]> ->
addShape("win2", 1.2, 1.8);}
##C10: add windows in the left side of the top floor
{<cell()[colLabel == "left"][rowLabel == "top"]> ->
addShape("win3", 1.2, 1.6);}
##C11: generate walls to fill the space.
{<root()/[label == "facade"]> -> coverShape();}
"#;

/// Brito et al. (2021), Código-fonte 1 (seed L598-L620), with its `>` for `->`.
const BRITO_MASS_MODEL: &str = r#"#C1: Initial settings
label = "building"; width = 9; depth = 11; height = 5;

#C2: Generating mass model
{<> > createShape(label, width, depth, height)};

#C3: Adding virtual shape
{<descendant() [label=="building"] / [label=="building_front"]> > createGrid("main_front_grid", 3, 7)};

#C4: Selecting regions and performing extrusion
{<descendant() [label=="building"] / [label=="building_front"] / [label=="main_front_grid"] / [type=="cell"] [rowIdx in (2, 3)] [colIdx in (3, 4, 5)] [::
   groupRegions()]> > addVolume("entrance", "building_front", 3, ["entrance_front"
   , "entrance_left", "entrance_right"])};

#C5: Applying roundShape deformation
{<descendant() [label=="building"] / [label=="building_front"] / [label=="entrance"] /
   [label=="entrance_front"]> > roundShape("front", "outside", 0.42, 30, "main_front", "vertical")};
"#;

/// Anchiêta (2023), Código-fonte 4 (seed L1004-L1036): a rounded door on a rounded bay.
const CF4_ROUNDED_DOOR: &str = r#"#C1 Variables
label = "building"; width = 9; depth = 5; height = 5;

#C2 Create construction shape
{<> -> createShape(label, width, depth, height)};

#C3 Add virtual shape
{< descendant() [label=="building"] / [label=="building_front"] > -> createGrid("main_front_grid", 4, 7)};

#C4 Add volume to selected cells
{< descendant() [label=="building"] / [label=="building_front"] / [label=="main_front_grid"] / [type=="cell"] [rowIdx in (2, 3, 4)] [colIdx in (3, 4, 5)] [::
   groupRegions()] > -> addVolume("entrance", "building_front", 3, ["entrance_front",
   "entrance_left", "entrance_right"])};

#C5 Add deformation in construction shape
{< descendant() [label=="building"] / [label=="building_front"] / [label=="entrance"]
    / [label=="entrance_front"] > -> roundShape("front", "outside", 0.42, 30, "main_front", "vertical")};

#C6 Add round facade in construction shape
{< descendant() [label=="building"] / [label=="building_front"] / [label=="entrance"] /
    [label=="entrance_front"] / [label=="entrance_front_grid"] / [type=="cell"] [
    rowIdx in (2,3)] [colIdx in (2)] [::groupRegions] > -> addRoundFacade("door", ["top_left", "top_right"], 0.9, 5, 0.5)}
"#;

/// Código-fonte 8 (seed L1232-L1275) as printed: C5 and C6 miss the `]` of
/// `[label=="entrance"` (a typo of the listing, which the thesis's regex parser never noticed).
const CF8_AS_PRINTED: &str = r#"#C1 Variables
label = "building"; width = 10; depth = 5; height = 5;

#C2 Create construction shape
{<> -> createShape(label, width, depth, height)};

#C3 Add virtual shape
{< descendant() [label=="building"] / [label=="building_front"] > -> createGrid("main_front_grid", 1, 3)};

#C4 Add volume to selected cells
{< descendant() [label=="building"] / [label=="building_front"] / [label=="main_front_grid"] / [type=="cell"] [rowIdx in (1)] [colIdx in (1)] [::groupRegions
   ()] > -> addVolume("entrance", "building_front", 3, ["entrance_front", "entrance_left", "entrance_right"])};

#C5 Add deformation in construction shape
{< descendant() [label=="building"] / [label=="building_front"] / [label=="entrance"
   / [label=="entrance_front"] > -> roundShape("front", "outside", 0.42, 10, "main_front", "vertical")};

#C6 Update grid entrance_front_grid
{< descendant() [label=="building"] / [label=="building_front"] / [label=="entrance"
   / [label=="entrance_front"] / [label=="entrance_front_grid"] > -> updateGrid(5, 4)
   };

#C7 Add round facade in construction shape
{< descendant() [label=="building"] / [label=="building_front"] / [label=="entrance"] /
   [label=="entrance_front"] / [label=="entrance_front_grid"] / [type=="cell"] [
   rowIdx in (3,4,5)] [colIdx in (2,3)] [::groupRegions] > -> addRoundFacade("door",
   ["top_left", "top_right"], 0.9, 5, 0.5)}

#C8 Update grid main_front_grid
{< descendant() [label=="building"] / [label=="building_front"] / [label=="main_front_grid"] > -> updateGrid(7, 7)};

#C9 Add windows in entrance lateral
{< descendant() [label=="building"] / [label=="building_front"] / [label=="main_front_grid"] / [type=="cell"] [rowIdx in (3,4,5)] [colIdx in (4,6)] [::
   groupRegions] > -> addRoundFacade("window", ["top_left", "top_right"], 0.9, 5,
   0.5)}
"#;

/// Código-fonte 8 with the two missing `]` written.
const CF8_FIXED: &str = r#"#C1 Variables
label = "building"; width = 10; depth = 5; height = 5;

#C2 Create construction shape
{<> -> createShape(label, width, depth, height)};

#C3 Add virtual shape
{< descendant() [label=="building"] / [label=="building_front"] > -> createGrid("main_front_grid", 1, 3)};

#C4 Add volume to selected cells
{< descendant() [label=="building"] / [label=="building_front"] / [label=="main_front_grid"] / [type=="cell"] [rowIdx in (1)] [colIdx in (1)] [::groupRegions
   ()] > -> addVolume("entrance", "building_front", 3, ["entrance_front", "entrance_left", "entrance_right"])};

#C5 Add deformation in construction shape
{< descendant() [label=="building"] / [label=="building_front"] / [label=="entrance"]
   / [label=="entrance_front"] > -> roundShape("front", "outside", 0.42, 10, "main_front", "vertical")};

#C6 Update grid entrance_front_grid
{< descendant() [label=="building"] / [label=="building_front"] / [label=="entrance"]
   / [label=="entrance_front"] / [label=="entrance_front_grid"] > -> updateGrid(5, 4)
   };

#C7 Add round facade in construction shape
{< descendant() [label=="building"] / [label=="building_front"] / [label=="entrance"] /
   [label=="entrance_front"] / [label=="entrance_front_grid"] / [type=="cell"] [
   rowIdx in (3,4,5)] [colIdx in (2,3)] [::groupRegions] > -> addRoundFacade("door",
   ["top_left", "top_right"], 0.9, 5, 0.5)}

#C8 Update grid main_front_grid
{< descendant() [label=="building"] / [label=="building_front"] / [label=="main_front_grid"] > -> updateGrid(7, 7)};

#C9 Add windows in entrance lateral
{< descendant() [label=="building"] / [label=="building_front"] / [label=="main_front_grid"] / [type=="cell"] [rowIdx in (3,4,5)] [colIdx in (4,6)] [::
   groupRegions] > -> addRoundFacade("window", ["top_left", "top_right"], 0.9, 5,
   0.5)}
"#;

/// Código-fonte 9 (seed L1322-L1353): framed windows on a round tower bay.
const CF9_FRAMED_WINDOWS: &str = r#"#C1 Variables
label = "tower"; width = 5; depth = 3; height = 10;

#C2 Create construction shape
{<> -> createShape(label, width, depth, height)};

#C3 Add virtual shape
{< descendant() [label=="tower"] / [label=="tower_front"] > -> createGrid("main_front_grid", 1, 1)};

#C4 Add volume to selected cells
{< descendant() [label=="tower"] / [label=="tower_front"] / [label=="main_front_grid"]
   / [type=="cell"] [rowIdx in (1)] [colIdx in (1)] [::groupRegions()] > ->
   addVolume("entrance", "tower_front", 1.6, ["entrance_front", "entrance_left", "entrance_right"])};

#C5 Add deformation in construction shape
{< descendant() [label=="tower"] / [label=="tower_front"] / [label=="entrance"] / [
   label=="entrance_front"] > -> roundShape("front", "outside", 1, 10, "main_front",
   "vertical")};

#C6 Update cell's grid
{< descendant() [label=="tower"] / [label=="tower_front"] / [label=="entrance"] / [
   label=="entrance_front"] / [label=="entrance_front_grid"] > -> updateGrid(7, 6)};

#C7 Add round facade with frame around construction shape
{< descendant() [label=="tower"] / [label=="tower_front"] / [label=="entrance"] / [
   label=="entrance_front"] / [label=="entrance_front_grid"] / [type=="cell"] [rowIdx
   in (2,3,5,6)] [colIdx in (3,4)] [::groupRegions] > -> addFacadeWithFrame("windows", "frame", 0.2, 0.2)}
"#;

/// Código-fonte 11 (seed L1455-L1488): the clock tower. The listing is printed in two blocks
/// (the second renumbered from 13); they are joined here.
const CF11_CLOCK_TOWER: &str = concat!(
    r#"label = "clock_tower"; width = 3; depth = 3; height = 12;

{<> -> createShape(label, width, depth, height)};

{< descendant() [label=="clock_tower"] / [label=="clock_tower_front"] > -> createGrid(
    "main_front_grid", 1, 1)};

{< descendant() [label=="clock_tower"] / [label=="clock_tower_front"] / [label=="main_front_grid"] > -> updateGrid(40, 10)};

{< descendant() [label=="clock_tower"] / [label=="clock_tower_front"] / [label=="main_front_grid"] / [type=="cell"] [pattern("X{10}(XA{8}X){8}", "A")] [::
    groupRegions] > -> addRoundFacadeWithFrame("clock", ["top_left", "top_right", "bottom_left", "bottom_right"], 1, 5, 0.5, "frame", 0.1, 0.2)}
"#,
    "\n",
    r#"{<descendant() [label=="clock_tower"] / [label=="clock_tower_front"] / [label=="main_front_grid"] / [type=="cell"] [rowIdx in (9,10)] [colIdx in (3,4)] [::
    groupRegions] > -> addRoundFacadeWithFrame("door", ["top_left", "top_right"], 1,
    5, 0.5, "frame", 0.1, 0.2)}

{< descendant() [label=="clock_tower"] / [label=="clock_tower_front"] / [label=="main_front_grid"] > -> updateGrid(20, 7)};

{<descendant() [label=="clock_tower"] / [label=="clock_tower_front"] / [label=="main_front_grid"] / [type=="cell"] [rowIdx in (7,8,10,11,13,14)] [colIdx in
    (2,3,5,6)] [::groupRegions] > -> addRoundFacade("windows", ["top_left", "top_right"], 1, 5, 0.7)}
"#
);

fn ok(src: &str) -> Program {
    parse(src, "t.slx").unwrap_or_else(|e| panic!("{e}"))
}

fn err(src: &str) -> SelexError {
    match parse(src, "t.slx") {
        Ok(p) => panic!("parsed, expected an error: {p:?}"),
        Err(e) => e,
    }
}

fn rules(p: &Program) -> Vec<&Rule> {
    p.rules().collect()
}

fn assigns(p: &Program) -> usize {
    p.commands
        .iter()
        .filter(|c| matches!(c, Command::Assign { .. }))
        .count()
}

fn steps_per_rule(p: &Program) -> Vec<usize> {
    p.rules().map(|r| r.selection.steps.len()).collect()
}

fn actions(p: &Program) -> Vec<ActionKind> {
    p.rules()
        .flat_map(|r| r.actions.iter().map(|a| a.name))
        .collect()
}

fn warnings(src: &str) -> Vec<(WarningKind, u32, u32)> {
    let p = ok(src);
    check(&p, src, "t.slx")
        .into_iter()
        .map(|w| (w.kind, w.line, w.col))
        .collect()
}

fn str_expr(e: &Expr) -> &str {
    e.as_str().unwrap_or_else(|| panic!("not a string: {e:?}"))
}

#[test]
fn jiang_fig13_parses() {
    let p = ok(JIANG_FIG13);
    assert_eq!(assigns(&p), 2);
    assert_eq!(steps_per_rule(&p), [0, 1, 2, 1, 1, 1, 1, 1, 1, 1, 2]);
    use ActionKind::*;
    assert_eq!(
        actions(&p),
        [
            AddShape,
            CreateGrid,
            SetHeadNode,
            AddShape,
            AddShape,
            AddShape,
            AddShape,
            AddShape,
            AddShape,
            AddShape,
            CoverShape
        ]
    );
    let r = rules(&p);
    // C5: cell()[colLabel == "mid"][rowIdx > 1][::groupCols()]
    let s = &r[4].selection.steps[0];
    assert_eq!(s.topo, Some(Topo::Cell));
    assert_eq!(s.filters.len(), 3);
    match &s.filters[0] {
        Filter::Compare {
            attr: Attr::ColLabel,
            op: Cmp::Eq,
            value,
            ..
        } => assert_eq!(str_expr(value), "mid"),
        f => panic!("{f:?}"),
    }
    match &s.filters[1] {
        Filter::Compare {
            attr: Attr::RowIdx,
            op: Cmp::Gt,
            value,
            ..
        } => assert_eq!(value.constant(), Some(1.0)),
        f => panic!("{f:?}"),
    }
    assert!(matches!(
        s.filters[2],
        Filter::Group {
            grouping: Grouping::Cols,
            ..
        }
    ));
    // C9: [colLabel in ("left", "right")][rowIdx in rowRange(2, -2)]
    let s = &r[8].selection.steps[0];
    match &s.filters[0] {
        Filter::In {
            attr: Attr::ColLabel,
            set: IndexSet::List(items),
            ..
        } => assert_eq!(
            items.iter().map(str_expr).collect::<Vec<_>>(),
            ["left", "right"]
        ),
        f => panic!("{f:?}"),
    }
    match &s.filters[1] {
        Filter::In {
            attr: Attr::RowIdx,
            set: IndexSet::RowRange(a, b),
            ..
        } => assert_eq!((a.constant(), b.constant()), (Some(2.0), Some(-2.0))),
        f => panic!("{f:?}"),
    }
    // C3's `[label == main]` is a bare word, the only warning.
    match &r[2].selection.steps[1].filters[0] {
        Filter::Compare { value, .. } => {
            assert_eq!(value.kind, ExprKind::BareWord("main".into()))
        }
        f => panic!("{f:?}"),
    }
    assert_eq!(warnings(JIANG_FIG13), [(WarningKind::BareWord, 7, 33)]);
    // C6's width `facW / 5 * 2` refers to the variable.
    let ledge = &r[5].actions[0];
    assert_eq!(ledge.args.len(), 4);
    match &ledge.args[1].kind {
        ExprKind::Binary(BinOp::Mul, a, _) => match &a.kind {
            ExprKind::Binary(BinOp::Div, v, _) => {
                assert_eq!(v.kind, ExprKind::Var("facW".into()))
            }
            k => panic!("{k:?}"),
        },
        k => panic!("{k:?}"),
    }
}

#[test]
fn jiang_fig13_as_printed_is_refused_at_its_ellipsis() {
    let e = err("##C2:\n{<> -> addShape(\"facade\", ...);}\n");
    assert_eq!((e.kind, e.line, e.col), (ParseErrorKind::Elided, 2, 27));
    assert!(
        e.message.contains("write the arguments of `addShape`"),
        "{e}"
    );
}

#[test]
fn brito_mass_model_parses_with_its_arrow() {
    let p = ok(BRITO_MASS_MODEL);
    assert_eq!(assigns(&p), 4);
    assert_eq!(steps_per_rule(&p), [0, 2, 4, 4]);
    use ActionKind::*;
    assert_eq!(
        actions(&p),
        [CreateShape, CreateGrid, AddVolume, RoundShape]
    );
    assert!(p.rules().all(|r| r.arrow == Arrow::Gt));
    let r = rules(&p);
    let last = &r[2].selection.steps[3];
    assert_eq!(last.topo, None);
    assert_eq!(last.filters.len(), 4);
    match &last.filters[2] {
        Filter::In {
            attr: Attr::ColIdx,
            set: IndexSet::List(items),
            ..
        } => assert_eq!(
            items.iter().map(|e| e.constant()).collect::<Vec<_>>(),
            [Some(3.0), Some(4.0), Some(5.0)]
        ),
        f => panic!("{f:?}"),
    }
    let vol = &r[2].actions[0];
    match &vol.args[3].kind {
        ExprKind::List(items) => assert_eq!(
            items.iter().map(str_expr).collect::<Vec<_>>(),
            ["entrance_front", "entrance_left", "entrance_right"]
        ),
        k => panic!("{k:?}"),
    }
    // createShape(label, ...) refers to the variables.
    assert_eq!(r[0].actions[0].args[0].kind, ExprKind::Var("label".into()));
    let w = warnings(BRITO_MASS_MODEL);
    assert_eq!(w.len(), 4, "{w:?}");
    assert!(w.iter().all(|(k, _, _)| *k == WarningKind::LegacyArrow));
    assert_eq!((w[0].1, w[0].2), (5, 5));
}

#[test]
fn rounded_door_parses() {
    let p = ok(CF4_ROUNDED_DOOR);
    assert_eq!(assigns(&p), 4);
    assert_eq!(steps_per_rule(&p), [0, 2, 4, 4, 6]);
    use ActionKind::*;
    assert_eq!(
        actions(&p),
        [
            CreateShape,
            CreateGrid,
            AddVolume,
            RoundShape,
            AddRoundFacade
        ]
    );
    let r = rules(&p);
    let door = &r[4].actions[0];
    assert_eq!(door.args.len(), 5);
    assert_eq!(str_expr(&door.args[0]), "door");
    match &door.args[1].kind {
        ExprKind::List(c) => assert_eq!(
            c.iter().map(str_expr).collect::<Vec<_>>(),
            ["top_left", "top_right"]
        ),
        k => panic!("{k:?}"),
    }
    let last = r[4].selection.steps.last().unwrap();
    assert_eq!(last.filters.len(), 4);
    assert!(matches!(
        last.filters[3],
        Filter::Group {
            grouping: Grouping::Regions,
            ..
        }
    ));
    assert_eq!(warnings(CF4_ROUNDED_DOOR), []);
}

#[test]
fn update_grid_listing_as_printed_misses_two_brackets() {
    let e = err(CF8_AS_PRINTED);
    assert_eq!((e.kind, e.line, e.col), (ParseErrorKind::Unclosed, 15, 67));
    assert!(
        e.message
            .starts_with("unclosed `[`: expected `]` before `/`"),
        "{e}"
    );
    let p = ok(CF8_FIXED);
    assert_eq!(steps_per_rule(&p), [0, 2, 4, 4, 5, 6, 3, 4]);
    use ActionKind::*;
    assert_eq!(
        actions(&p),
        [
            CreateShape,
            CreateGrid,
            AddVolume,
            RoundShape,
            UpdateGrid,
            AddRoundFacade,
            UpdateGrid,
            AddRoundFacade
        ]
    );
    assert_eq!(warnings(CF8_FIXED), []);
}

#[test]
fn framed_windows_parse() {
    let p = ok(CF9_FRAMED_WINDOWS);
    assert_eq!(assigns(&p), 4);
    assert_eq!(steps_per_rule(&p), [0, 2, 4, 4, 5, 6]);
    let r = rules(&p);
    let w = &r[5].actions[0];
    assert_eq!(w.name, ActionKind::AddFacadeWithFrame);
    assert_eq!(str_expr(&w.args[1]), "frame");
    assert_eq!(w.args[2].constant(), Some(0.2));
    match &r[5].selection.steps[5].filters[1] {
        Filter::In {
            attr: Attr::RowIdx,
            set: IndexSet::List(items),
            ..
        } => assert_eq!(items.len(), 4),
        f => panic!("{f:?}"),
    }
    assert_eq!(warnings(CF9_FRAMED_WINDOWS), []);
}

#[test]
fn clock_tower_parses_and_keeps_its_pattern_raw() {
    let src = CF11_CLOCK_TOWER;
    let p = ok(src);
    assert_eq!(assigns(&p), 4);
    assert_eq!(steps_per_rule(&p), [0, 2, 3, 4, 4, 3, 4]);
    use ActionKind::*;
    assert_eq!(
        actions(&p),
        [
            CreateShape,
            CreateGrid,
            UpdateGrid,
            AddRoundFacadeWithFrame,
            AddRoundFacadeWithFrame,
            UpdateGrid,
            AddRoundFacade
        ]
    );
    let r = rules(&p);
    let step = &r[3].selection.steps[3];
    match &step.filters[1] {
        Filter::Pattern {
            regex,
            pat,
            regex_span,
            pat_span,
            ..
        } => {
            assert_eq!(regex, "X{10}(XA{8}X){8}");
            assert_eq!(pat, "A");
            assert_eq!(&src[regex_span.offset..regex_span.end()], regex);
            assert_eq!(&src[pat_span.offset..pat_span.end()], "A");
            // Character n of the regex is at column regex_span.col + n.
            let line = src.lines().nth(regex_span.line as usize - 1).unwrap();
            let col = regex_span.col as usize - 1;
            assert_eq!(&line[col..col + 5], "X{10}");
        }
        f => panic!("{f:?}"),
    }
    let clock = &r[3].actions[0];
    assert_eq!(clock.args.len(), 8);
    match &clock.args[1].kind {
        ExprKind::List(c) => assert_eq!(c.len(), 4),
        k => panic!("{k:?}"),
    }
    assert_eq!(warnings(src), []);
}

#[test]
fn comments_arrows_and_optional_parts() {
    // `#` and `##` comments, `->` and `;` optional after a rule, trailing `;` in actions,
    // `[::g]` and `[::g()]`, `groupColumns`, spans and `constrain`.
    let src = "## head\n# c\nw = 2 * (3 + 1) - -1; # nine\n\
               {<cell()[type == \"cell\"][::groupColumns]> -> addFacade(\"a\"); addFacade(\"b\");}\n\
               {<> -> constrain(align(\"w1\", \"w2\", \"vertical\"), symmetric(\"w3\", \"horizontal\"), \
               boundaryDistance(\"door\", w / 18), noIntersection(), noIntersection(\"a\", \"b\"))};\n";
    let p = ok(src);
    match &p.commands[0] {
        Command::Assign { name, value, span } => {
            assert_eq!(name, "w");
            assert_eq!(value.constant(), Some(9.0));
            assert_eq!((span.line, span.col), (3, 1));
            assert_eq!(&src[span.offset..span.end()], "w = 2 * (3 + 1) - -1;");
        }
        c => panic!("{c:?}"),
    }
    let r = rules(&p);
    assert_eq!(r[0].actions.len(), 2);
    assert!(matches!(
        r[0].selection.steps[0].filters[1],
        Filter::Group {
            grouping: Grouping::Cols,
            ..
        }
    ));
    let c = &r[1].actions[0];
    assert_eq!(c.name, ActionKind::Constrain);
    assert!(c.args.is_empty());
    assert_eq!(c.constraints.len(), 5);
    assert!(matches!(
        c.constraints[0].kind,
        ConstraintKind::Align {
            axis: ConstraintAxis::Vertical,
            ..
        }
    ));
    assert!(matches!(
        c.constraints[1].kind,
        ConstraintKind::Symmetric {
            axis: ConstraintAxis::Horizontal,
            ..
        }
    ));
    match &c.constraints[2].kind {
        ConstraintKind::BoundaryDistance { label, min } => {
            assert_eq!(str_expr(label), "door");
            assert!(matches!(min.kind, ExprKind::Binary(BinOp::Div, ..)));
        }
        k => panic!("{k:?}"),
    }
    assert!(
        matches!(&c.constraints[3].kind, ConstraintKind::NoIntersection { labels } if labels.is_empty())
    );
    assert!(
        matches!(&c.constraints[4].kind, ConstraintKind::NoIntersection { labels } if labels.len() == 2)
    );
    assert_eq!(warnings(src), []);
    // Rule and action spans.
    assert_eq!(
        &src[r[0].span.offset..r[0].span.end()],
        "{<cell()[type == \"cell\"][::groupColumns]> -> addFacade(\"a\"); addFacade(\"b\");}"
    );
    let a = &r[0].actions[1];
    assert_eq!(&src[a.span.offset..a.span.end()], "addFacade(\"b\")");
    // An empty program parses (check warns).
    assert_eq!(ok("# nothing\n").commands.len(), 0);
    assert_eq!(warnings("x = 1;"), [(WarningKind::NoRules, 1, 1)]);
}

#[test]
fn every_action_signature_is_accepted_at_its_arities() {
    let src = r#"{<> -> createShape("b", 9, 11, 5);
    createGrid("g", 3, 7); createGrid("g", ["gnd", "top"], 4);
    updateGrid(5, 4); setHeadNode(); addShape("x"); addShape("x", 1); addShape("x", 1, 2, 3);
    addFacade("w"); addRoundFacade("w", ["top_left"], 0.2, 10, 0.5);
    addFacadeWithFrame("w", "none", 0.1, 0.2);
    addRoundFacadeWithFrame("w", ["bottom_left", "bottom_right"], 1, 5, 0.5, "all", 0.1, 0.2);
    addVolume("e", "b_front", 3, ["f", "l", "r"]);
    roundShape("front", "inside", 0.4, 30, "main_back");
    roundShape("top", "outside", 0.4, 30, "main_left", "horizontal", 0.1);
    coverShape(); constrain(noIntersection())}"#;
    let p = ok(src);
    assert_eq!(p.rules().next().unwrap().actions.len(), 17);
    for a in ActionKind::ALL {
        assert_eq!(ActionKind::from_name(a.name()), Some(a));
        assert!(a.signature().starts_with(a.name()));
    }
    assert_eq!(
        ActionKind::RoundShape.signature(),
        "roundShape(type, direction, roundingDegree, segments, sideReference, axis?, insideDegree?)"
    );
}

/// One source per error kind: (source, kind, line, col, a piece of the message).
const ERRORS: &[(&str, ParseErrorKind, u32, u32, &str)] = {
    use ParseErrorKind::*;
    &[
        ("{<> -> coverShape() @}", BadCharacter, 1, 21, "unexpected character `@`"),
        ("{<[label == 2D]> -> coverShape()}", BadCharacter, 1, 13, "malformed number `2D`"),
        ("{<> => coverShape()}", UnexpectedToken, 1, 5, "expected `->` after the selection, found `=`"),
        ("{<[label = \"a\"]> -> coverShape()}", UnexpectedToken, 1, 10, "write `==`"),
        ("{<> -> coverShape();\n", Unclosed, 1, 1, "unclosed `{`"),
        ("{<> -> coverShape()\n{<> -> coverShape()}", Unclosed, 1, 1, "unclosed `{`"),
        ("{<[label == \"a\"] -> coverShape()}", Unclosed, 1, 2, "unclosed `<`: expected `>` before `->`"),
        ("{<[label == \"a\" > -> coverShape()}", Unclosed, 1, 3, "unclosed `[`: expected `]` before `>`"),
        ("{<> -> addFacade(\"a\"}", Unclosed, 1, 17, "unclosed `(`"),
        ("{<[label == \"a]> -> coverShape()}", Unclosed, 1, 13, "unclosed string"),
        ("{<chld()> -> coverShape()}", UnknownTopology, 1, 3, "did you mean `child`?"),
        ("{<label()> -> coverShape()}", UnknownTopology, 1, 3, "`label` is an attribute"),
        ("{<[lable == \"a\"]> -> coverShape()}", UnknownAttribute, 1, 4, "did you mean `label`?"),
        ("{<[patern(\"X\", \"X\")]> -> coverShape()}", UnknownSelector, 1, 4, "did you mean `pattern`?"),
        ("{<[rowIdx in range(1, 2)]> -> coverShape()}", UnknownSelector, 1, 14, "rowRange(a, b)"),
        ("{<[type == \"cell\"][::groupRegion()]> -> coverShape()}", UnknownGrouping, 1, 22, "did you mean `groupRegions`?"),
        ("{<> -> addFacde(\"a\")}", UnknownAction, 1, 8, "did you mean `addFacade`?"),
        ("{<> -> constrain(symetric(\"a\", \"vertical\"))}", UnknownConstraint, 1, 18, "did you mean `symmetric`?"),
        ("width = 9;\nw = widht / 2;", UnknownVariable, 2, 5, "did you mean `width`?"),
        ("{<[label == \"a\"] child()> -> coverShape()}", TopologyNotFirst, 1, 18, "topology selector `child()` after a filter"),
        ("{<root() child()> -> coverShape()}", TopologyNotFirst, 1, 10, "at most one"),
        ("{<cell()[groupRegions()]> -> coverShape()}", GroupingWithoutColons, 1, 10, "`[::groupRegions()]`"),
        ("{<cell()[groupRows]> -> coverShape()}", GroupingWithoutColons, 1, 10, "`[::groupRows()]`"),
        ("{<cell()[::groupRows][::groupRows()]> -> coverShape()}", DuplicateGrouping, 1, 22, "twice"),
        ("{<cell()[rowIdx in ()]> -> coverShape()}", EmptyList, 1, 20, "the list is empty"),
        ("{<cell()[rowIdx in (1.5)]> -> coverShape()}", NonIntegerIndex, 1, 21, "not a whole number"),
        ("{<cell()[colIdx == 0]> -> coverShape()}", ZeroIndex, 1, 20, "1-based"),
        ("{<cell()[label < \"a\"]> -> coverShape()}", BadComparison, 1, 16, "compare it with `==` or `!=`"),
        ("{<cell()[label in rowRange(1, 2)]> -> coverShape()}", BadComparison, 1, 19, "applies to rowIdx and colIdx"),
        ("{<cell()[rowIdx == \"a\"]> -> coverShape()}", WrongValueKind, 1, 20, "compare it with a number, found the string \"a\""),
        ("label = \"a\"; w = label * 2;", NotANumber, 1, 18, "arithmetic needs numbers, found the variable `label` (a string)"),
        (
            "{<> -> addRoundFacade(\"windows_1\", [\"top_right\",\"top_left\"], \"none\", 0.2, 10, 0.5)}",
            WrongArgCount, 1, 79,
            "addRoundFacade takes 5 arguments (label, corners, offset, segments, profile), found 6",
        ),
        ("{<> -> setHeadNode(1)}", WrongArgCount, 1, 20, "setHeadNode takes 0 arguments"),
        ("{<> -> roundShape(\"front\")}", WrongArgCount, 1, 26, "roundShape takes 5 to 7 arguments"),
        ("{<> -> constrain()}", WrongArgCount, 1, 18, "one or more constraints"),
        ("{<child(1)> -> coverShape()}", WrongArgCount, 1, 9, "`child()` takes no argument"),
        (
            "{<> -> addRoundFacade(\"door\", 0.9, 5, 0.5, 0.5)}",
            WrongArgKind, 1, 31,
            "addRoundFacade: argument 2 `corners` must be a list of corner names (top_left, top_right, bottom_right, bottom_left), found the number 0.9",
        ),
        ("{<> -> addRoundFacade(\"d\", [\"top_lef\"], 1, 5, 0.5)}", WrongArgKind, 1, 29, "did you mean \"top_left\"?"),
        ("{<> -> addRoundFacade(\"d\", [\"top_left\", \"top_left\"], 1, 5, 0.5)}", WrongArgKind, 1, 41, "twice"),
        ("{<> -> addRoundFacade(\"d\", [\"top_left\"], 1, 5, 1.5)}", WrongArgKind, 1, 48, "`profile` must be a number between 0 and 1"),
        ("{<> -> addRoundFacade(\"d\", [\"top_left\"], 1, 2.5, 0.5)}", WrongArgKind, 1, 45, "`segments` must be a whole number"),
        ("{<> -> addFacadeWithFrame(\"w\", \"frames\", 1, 1)}", WrongArgKind, 1, 32, "did you mean \"frame\"?"),
        ("{<> -> addVolume(\"e\", \"s\", 3, [\"f\", \"l\"])}", WrongArgKind, 1, 31, "a list of 3 labels, found a list of 2 items"),
        ("{<> -> createShape(1, 2, 3, 4)}", WrongArgKind, 1, 20, "argument 1 `label` must be a string"),
        ("{<> -> createGrid(\"g\", 0, 2)}", WrongArgKind, 1, 24, "`rows` must be a whole number of at least 1"),
        ("{<> -> constrain(align(\"a\", \"b\", \"diagonal\"))}", WrongArgKind, 1, 34, "one of \"vertical\", \"horizontal\""),
        ("{<> -> constrain(\"a\")}", WrongArgKind, 1, 18, "must be a constraint"),
        ("{<[pattern(\"X\", 1)]> -> coverShape()}", WrongArgKind, 1, 17, "argument 2 `pat` must be a string"),
        ("{<> -> addShape(\"facade\", ...);}", Elided, 1, 27, "elided"),
    ]
};

#[test]
fn each_error_kind_has_its_message_and_place() {
    let mut wrong = Vec::new();
    for &(src, kind, line, col, piece) in ERRORS {
        let e = err(src);
        if (e.kind, e.line, e.col) != (kind, line, col) || !e.message.contains(piece) {
            wrong.push(format!(
                "{src}\n{e}\nwanted {kind:?} at {line}:{col} with: {piece}"
            ));
            continue;
        }
        // Every message renders with the place and a caret under it.
        let shown = e.to_string();
        assert!(
            shown.starts_with(&format!("t.slx:{line}:{col}: ")),
            "{shown}"
        );
        assert!(shown.ends_with('^'), "{shown}");
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n\n"));
}

#[test]
fn an_error_renders_file_line_col_the_line_and_a_caret() {
    let e = err("x = 1;\n{<cell()[rowIdx in (1.5)]> -> coverShape()}\n");
    assert_eq!(
        e.to_string(),
        "t.slx:2:21: `rowIdx` 1.5 is not a whole number: rows and columns are counted 1, 2, ... \
         (negative from the end)\n\
         {<cell()[rowIdx in (1.5)]> -> coverShape()}\n                    ^"
    );
}

#[test]
fn size_and_nesting_are_capped() {
    let mut big = "# ".to_string();
    big.push_str(&"x".repeat(MAX_SOURCE_BYTES - 2));
    assert_eq!(big.len(), MAX_SOURCE_BYTES);
    assert!(parse(&big, "big.slx").is_ok());
    big.push('x');
    let e = err(&big);
    assert_eq!((e.kind, e.line, e.col), (ParseErrorKind::TooLarge, 1, 1));
    assert!(
        e.to_string().len() < 1_000,
        "the message shows a window of the line"
    );

    let deep = format!("w = {}1{};", "(".repeat(500), ")".repeat(500));
    assert_eq!(err(&deep).kind, ParseErrorKind::TooDeep);
    let neg = format!("w = {}1;", "-".repeat(500));
    assert_eq!(err(&neg).kind, ParseErrorKind::TooDeep);
    let list = format!("w = {}1{};", "[".repeat(500), "]".repeat(500));
    assert_eq!(err(&list).kind, ParseErrorKind::TooDeep);
    let chain = format!("w = 1{};", " + 1".repeat(10_000));
    assert_eq!(err(&chain).kind, ParseErrorKind::TooDeep);
    // Just under the cap is fine.
    let ok_deep = format!("w = {}1{};", "(".repeat(100), ")".repeat(100));
    assert!(parse(&ok_deep, "t.slx").is_ok());
}

#[test]
fn check_warns_on_suspicious_programs() {
    use WarningKind::*;
    assert_eq!(
        warnings("{<[label == \"a\"][::groupRegions]> -> coverShape()}"),
        [(GroupingOutsideCells, 1, 17)]
    );
    assert_eq!(
        warnings("{<cell()[::groupRows][::groupPairs]> -> coverShape()}"),
        [(SeveralGroupings, 1, 22)]
    );
    assert_eq!(
        warnings("{<> -> roundShape(\"front\", \"outside\", 0.4, 10, \"main_front\")}"),
        [(RoundShapeWithoutVolume, 1, 8)]
    );
    assert_eq!(
        warnings("{<descendant()[type == \"cells\"]/[side == \"rear\"]> -> coverShape()}"),
        [(UnknownValue, 1, 24), (UnknownValue, 1, 42)]
    );
    assert_eq!(warnings("{<> -> addFacade(window)}"), [(BareWord, 1, 18)]);
    let p = ok("{<> > coverShape()}");
    let w = check(&p, "{<> > coverShape()}", "t.slx");
    assert_eq!(
        w[0].to_string(),
        "t.slx:1:5: warning: `>` separates the selection from the actions as Brito's listing \
         prints it; write `->`\n{<> > coverShape()}\n    ^"
    );
}

/// Whether the error's place is inside `src`: a line that exists and a column at most one past
/// its end.
fn place_is_inside(src: &str, e: &SelexError) -> bool {
    let lines: Vec<&str> = src.split('\n').collect();
    e.line >= 1
        && (e.line as usize) <= lines.len()
        && e.col >= 1
        && (e.col as usize) <= lines[e.line as usize - 1].chars().count() + 1
}

const SOUP: &[&str] = &[
    "{",
    "}",
    "<",
    ">",
    "->",
    "/",
    "[",
    "]",
    "(",
    ")",
    "::",
    ",",
    ";",
    "=",
    "==",
    "!=",
    "<=",
    ">=",
    "-",
    "+",
    "*",
    "...",
    "\n",
    " ",
    "#c\n",
    "\"",
    "\"a\"",
    "\"X{2}\"",
    "1",
    "-2",
    "0.5",
    "0",
    "x",
    "in",
    "cell",
    "child",
    "root",
    "label",
    "rowIdx",
    "colLabel",
    "type",
    "pattern",
    "groupRegions",
    "rowRange",
    "indexRange",
    "addFacade",
    "addRoundFacade",
    "constrain",
    "align",
    "noIntersection",
    "createGrid",
    "coverShape",
    "[\"top_left\"]",
    "é",
];

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2_000))]

    #[test]
    fn random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..200)) {
        let src = String::from_utf8_lossy(&bytes).into_owned();
        match parse(&src, "p.slx") {
            Ok(p) => { let _ = check(&p, &src, "p.slx"); }
            Err(e) => {
                prop_assert!(place_is_inside(&src, &e), "{:?} at {}:{} in {:?}", e.kind, e.line, e.col, src);
                let _ = e.to_string();
            }
        }
    }

    #[test]
    fn token_soups_never_panic(idx in proptest::collection::vec(0..SOUP.len(), 0..60)) {
        let src: String = idx.iter().map(|&i| SOUP[i]).collect::<Vec<_>>().join(" ");
        match parse(&src, "p.slx") {
            Ok(p) => { let _ = check(&p, &src, "p.slx"); }
            Err(e) => {
                prop_assert!(place_is_inside(&src, &e), "{:?} at {}:{} in {:?}", e.kind, e.line, e.col, src);
                let _ = e.to_string();
            }
        }
    }

    #[test]
    fn mutated_listings_never_panic(cut in 0usize..2_000, len in 0usize..40, junk in 0..SOUP.len()) {
        // The clock tower with a piece cut out and a token put in its place.
        let src = CF11_CLOCK_TOWER;
        let mut at = cut.min(src.len());
        while !src.is_char_boundary(at) { at -= 1; }
        let mut end = (at + len).min(src.len());
        while !src.is_char_boundary(end) { end -= 1; }
        let s = format!("{}{}{}", &src[..at], SOUP[junk], &src[end..]);
        match parse(&s, "p.slx") {
            Ok(p) => { let _ = check(&p, &s, "p.slx"); }
            Err(e) => prop_assert!(place_is_inside(&s, &e), "{:?} at {}:{} in {:?}", e.kind, e.line, e.col, s),
        }
    }
}
