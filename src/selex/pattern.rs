//! The `pattern(regex, pat)` selection function (seed 000 §4.3) as a real grammar.
//!
//! ```text
//! seq  := item*
//! item := (LETTER | '(' seq ')') ('{' INT '}' | '*')?
//! ```
//!
//! - A LETTER is any alphabetic character (Unicode included). Only the cells whose letter equals
//!   `pat` are selected; every other letter means "not selected" (`X`, `x`, `B` alike).
//! - `(...)` groups; groups nest up to [`MAX_DEPTH`] deep and may not be empty.
//! - `{n}` repeats the preceding letter or group n times, n >= 1 (`{0}` is an error, and so is a
//!   count above [`MAX_CELLS`]).
//! - `*` repeats the preceding letter or group as many whole times (zero included) as needed for
//!   the whole expansion to be exactly rows × cols cells. At most one `*` in the whole pattern, at
//!   any depth; inside a repeated group it is filled once and the fill is repeated with the group.
//!   `B*AA` repeats the letter `B` (the seed's code ignored a `*` after a bare letter).
//! - A repeat may not follow a repeat: `X{8}{7}` and `X{2}*` are errors (write `(X{8}){7}`); the
//!   seed's appendix has `X{8}{7}`, a transcription slip.
//! - Whitespace between tokens is ignored, so a long pattern may be written row by row.
//! - **Strict tiling**: the expansion must be exactly rows × cols cells. Too short without a `*`,
//!   too long, or a `*` whose repeated length does not divide what is left are errors that say
//!   where the expansion stops (the seed left a short tail unselected and indexed past the grid
//!   on a long one).
//! - The expansion reads **as the facade is seen**: cell i (0-based) is the top row's leftmost
//!   cell for i = 0, row-major, the ground floor last: grid row `rows - i / cols` (row 1 is the
//!   ground floor), column `i % cols + 1`.
//!
//! Every [`PatternError`] carries a byte offset into the regex string so the caller can put a
//! caret under it. Lengths are computed arithmetically with checked math before anything is
//! allocated; a pattern longer than [`MAX_CELLS`] is refused.

use std::fmt;

use super::grid::{CellSet, MAX_CELLS};

/// The deepest nesting of groups accepted.
pub const MAX_DEPTH: usize = 32;

/// What is wrong with a pattern (see [`PatternError`] for where).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum PatternErrorKind {
    /// The pattern has no letter at all.
    Empty,
    /// A character that is neither a letter nor `(`, `)`, `{n}`, `*` or whitespace.
    UnexpectedChar(char),
    /// A `{n}` or `*` with no letter or group before it.
    RepeatWithoutItem(char),
    /// A `(` never closed (the offset is the `(`).
    UnclosedGroup,
    /// A `)` with no `(` open.
    UnmatchedClose,
    /// `()`.
    EmptyGroup,
    /// `{` not followed by digits and `}`.
    BadCount,
    /// `{0}`.
    ZeroCount,
    /// A count above [`MAX_CELLS`].
    CountTooLarge,
    /// A repeat right after a repeat (`X{8}{7}`, `X{2}*`).
    ChainedRepeat,
    /// A second `*` (the offset is the second; `first` is the first's offset).
    MultipleStars {
        /// Byte offset of the first `*`.
        first: usize,
    },
    /// Groups nested deeper than [`MAX_DEPTH`].
    TooDeep,
    /// The expansion (without the `*`'s fill) is longer than [`MAX_CELLS`].
    TooLong,
    /// A grid with zero rows or columns, or more than [`MAX_CELLS`] cells.
    BadGrid {
        /// Rows asked.
        rows: usize,
        /// Columns asked.
        cols: usize,
    },
    /// The letter to select is not exactly one alphabetic character (offset 0: it is the second
    /// argument, not the regex).
    BadLetter(String),
    /// No `*`, and the expansion ends before the grid is full (offset: the end of the regex).
    Short {
        /// Grid rows.
        rows: usize,
        /// Grid columns.
        cols: usize,
        /// Cells the pattern gives.
        got: usize,
    },
    /// The expansion runs past the grid's last cell (offset: the letter that would make the
    /// first cell too many, with the `*` repeated zero times).
    Overflow {
        /// Grid rows.
        rows: usize,
        /// Grid columns.
        cols: usize,
        /// Cells the pattern gives (with zero repeats of a `*`).
        got: usize,
    },
    /// The `*` repeats `unit` cells but `left` cells remain to fill and `unit` does not divide
    /// `left` (offset: the `*`).
    StarNotDividing {
        /// Grid rows.
        rows: usize,
        /// Grid columns.
        cols: usize,
        /// Cells left for the `*` to fill.
        left: usize,
        /// Cells one repeat of the `*` adds.
        unit: usize,
    },
}

/// A pattern error: what, and the byte offset in the regex string where it is.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PatternError {
    /// Byte offset into the regex string (for a caret).
    pub offset: usize,
    /// What is wrong.
    pub kind: PatternErrorKind,
    /// The regex string, for the message.
    pub pattern: String,
}

impl std::error::Error for PatternError {}

/// "9 rows" or "9 rows and 3 cells" of a `cols`-wide grid.
fn in_rows(n: usize, cols: usize) -> String {
    let cols = cols.max(1);
    let (r, c) = (n / cols, n % cols);
    let rows = if r == 1 { "row" } else { "rows" };
    match c {
        0 => format!("{r} {rows}"),
        1 => format!("{r} {rows} and 1 cell"),
        _ => format!("{r} {rows} and {c} cells"),
    }
}

impl fmt::Display for PatternError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use PatternErrorKind as K;
        let p = &self.pattern;
        let o = self.offset;
        match &self.kind {
            K::Empty => write!(f, "pattern \"{p}\" is empty: it needs at least one letter"),
            K::UnexpectedChar(c) => write!(
                f,
                "pattern \"{p}\": unexpected `{c}` at offset {o}; a pattern has letters, (groups), {{n}} and one *"
            ),
            K::RepeatWithoutItem(c) => write!(
                f,
                "pattern \"{p}\": `{c}` at offset {o} repeats nothing; put a letter or a (group) before it"
            ),
            K::UnclosedGroup => {
                write!(f, "pattern \"{p}\": the `(` at offset {o} is never closed")
            }
            K::UnmatchedClose => {
                write!(f, "pattern \"{p}\": the `)` at offset {o} closes no group")
            }
            K::EmptyGroup => write!(f, "pattern \"{p}\": empty group `()` at offset {o}"),
            K::BadCount => write!(
                f,
                "pattern \"{p}\": the `{{` at offset {o} needs a count and a `}}`, as in {{3}}"
            ),
            K::ZeroCount => write!(
                f,
                "pattern \"{p}\": `{{0}}` at offset {o}; a count is at least 1 (leave the item out)"
            ),
            K::CountTooLarge => write!(
                f,
                "pattern \"{p}\": the count at offset {o} is larger than the limit of {MAX_CELLS} cells"
            ),
            K::ChainedRepeat => write!(
                f,
                "pattern \"{p}\": a repeat at offset {o} follows a repeat; group first, as in (X{{8}}){{7}}"
            ),
            K::MultipleStars { first } => write!(
                f,
                "pattern \"{p}\": a second `*` at offset {o} (the first is at {first}); a pattern has at most one"
            ),
            K::TooDeep => write!(
                f,
                "pattern \"{p}\": groups nested more than {MAX_DEPTH} deep at offset {o}"
            ),
            K::TooLong => write!(
                f,
                "pattern \"{p}\": the expansion passes the limit of {MAX_CELLS} cells at offset {o}"
            ),
            K::BadGrid { rows, cols } => write!(
                f,
                "pattern \"{p}\" cannot tile a {rows} × {cols} grid: it needs 1 to {MAX_CELLS} cells"
            ),
            K::BadLetter(l) => write!(
                f,
                "pattern \"{p}\": the letter to select must be one alphabetic character, not \"{l}\""
            ),
            // The fields are public: the arithmetic saturates so that any values display.
            K::Short { rows, cols, got } => {
                let need = rows.saturating_mul(*cols);
                let width = (*cols).max(1);
                write!(
                    f,
                    "pattern \"{p}\" gives {got} cells ({}) for a {rows} × {cols} grid ({need}): {} short; it stops at row {}, column {} (row 1 is the ground floor); add a `*` or more cells",
                    in_rows(*got, *cols),
                    need.saturating_sub(*got),
                    rows.saturating_sub(got / width),
                    got % width + 1
                )
            }
            K::Overflow { rows, cols, got } => {
                let need = rows.saturating_mul(*cols);
                write!(
                    f,
                    "pattern \"{p}\" gives {got} cells ({}) for a {rows} × {cols} grid ({need}): {} too many; the grid is full (row 1, column {cols}) at offset {o}",
                    in_rows(*got, *cols),
                    got.saturating_sub(need)
                )
            }
            K::StarNotDividing {
                rows,
                cols,
                left,
                unit,
            } => {
                let unit = (*unit).max(1);
                let k = left / unit;
                write!(
                    f,
                    "pattern \"{p}\": the `*` at offset {o} repeats {unit} cells to fill the {left} cells left of a {rows} × {cols} grid, which is not a whole number of repeats: {k} leave {} cells empty, {} overflow by {}",
                    left - k * unit,
                    k.saturating_add(1),
                    (k.saturating_add(1)).saturating_mul(unit).saturating_sub(*left)
                )
            }
        }
    }
}

/// How many times an item is written.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Rep {
    Once,
    Times(usize),
    Star,
}

#[derive(Clone, Debug, PartialEq, Eq)]
enum Node {
    Letter(char),
    Group(Vec<Item>),
}

/// One item with its lengths: the node alone gives `a + b·k` cells for a `*` fill count k.
#[derive(Clone, Debug, PartialEq, Eq)]
struct Item {
    node: Node,
    offset: usize,
    rep: Rep,
    node_a: usize,
    node_b: usize,
}

impl Item {
    /// The item's length as `a + b·k`.
    fn len(&self) -> (usize, usize) {
        match self.rep {
            Rep::Once => (self.node_a, self.node_b),
            // Capped at parse time: both products are at most MAX_CELLS.
            Rep::Times(n) => (self.node_a * n, self.node_b * n),
            Rep::Star => (0, self.node_a),
        }
    }

    /// The node's length for a fill count k, and how many times it is written.
    fn node_len_times(&self, k: usize) -> (usize, usize) {
        let node = self.node_a + self.node_b * k;
        let times = match self.rep {
            Rep::Once => 1,
            Rep::Times(n) => n,
            Rep::Star => k,
        };
        (node, times)
    }
}

/// A parsed pattern.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Pattern {
    source: String,
    items: Vec<Item>,
    star: Option<usize>,
    fixed: usize,
    unit: usize,
}

/// Parses a pattern string.
pub fn parse(regex: &str) -> Result<Pattern, PatternError> {
    let mut p = Parser {
        src: regex,
        pos: 0,
        star: None,
    };
    let items = p.seq(0)?;
    p.skip_ws();
    if let Some(c) = p.peek() {
        // seq stops only at ')' or the end.
        let kind = if c == ')' {
            PatternErrorKind::UnmatchedClose
        } else {
            PatternErrorKind::UnexpectedChar(c)
        };
        return Err(p.err(p.pos, kind));
    }
    if items.is_empty() {
        return Err(p.err(0, PatternErrorKind::Empty));
    }
    let (fixed, unit) = p.seq_len(&items)?;
    let mut items = items;
    annotate(&mut items);
    Ok(Pattern {
        source: regex.to_string(),
        items,
        star: p.star,
        fixed,
        unit,
    })
}

/// Parses `regex` and selects the cells of a rows × cols grid whose letter is `pat`.
#[cfg(test)]
pub(crate) fn select(
    regex: &str,
    pat: &str,
    rows: usize,
    cols: usize,
) -> Result<CellSet, PatternError> {
    parse(regex)?.select(pat, rows, cols)
}

struct Parser<'a> {
    src: &'a str,
    pos: usize,
    star: Option<usize>,
}

impl Parser<'_> {
    fn err(&self, offset: usize, kind: PatternErrorKind) -> PatternError {
        PatternError {
            offset,
            kind,
            pattern: self.src.to_string(),
        }
    }

    fn peek(&self) -> Option<char> {
        self.src[self.pos..].chars().next()
    }

    fn bump(&mut self) {
        if let Some(c) = self.peek() {
            self.pos += c.len_utf8();
        }
    }

    fn skip_ws(&mut self) {
        while self.peek().is_some_and(char::is_whitespace) {
            self.bump();
        }
    }

    fn seq(&mut self, depth: usize) -> Result<Vec<Item>, PatternError> {
        let mut items = Vec::new();
        loop {
            self.skip_ws();
            let start = self.pos;
            let node = match self.peek() {
                None | Some(')') => return Ok(items),
                Some('(') => {
                    if depth + 1 > MAX_DEPTH {
                        return Err(self.err(start, PatternErrorKind::TooDeep));
                    }
                    self.bump();
                    let inner = self.seq(depth + 1)?;
                    self.skip_ws();
                    if self.peek() != Some(')') {
                        return Err(self.err(start, PatternErrorKind::UnclosedGroup));
                    }
                    if inner.is_empty() {
                        return Err(self.err(start, PatternErrorKind::EmptyGroup));
                    }
                    self.bump();
                    Node::Group(inner)
                }
                Some(c) if c.is_alphabetic() => {
                    self.bump();
                    Node::Letter(c)
                }
                Some(c @ ('{' | '*')) => {
                    return Err(self.err(start, PatternErrorKind::RepeatWithoutItem(c)))
                }
                Some(c) => return Err(self.err(start, PatternErrorKind::UnexpectedChar(c))),
            };
            self.skip_ws();
            let rep = self.rep()?;
            if rep != Rep::Once {
                self.skip_ws();
                if matches!(self.peek(), Some('{' | '*')) {
                    return Err(self.err(self.pos, PatternErrorKind::ChainedRepeat));
                }
            }
            items.push(Item {
                node,
                offset: start,
                rep,
                node_a: 0,
                node_b: 0,
            });
        }
    }

    fn rep(&mut self) -> Result<Rep, PatternError> {
        let at = self.pos;
        match self.peek() {
            Some('*') => {
                if let Some(first) = self.star {
                    return Err(self.err(at, PatternErrorKind::MultipleStars { first }));
                }
                self.star = Some(at);
                self.bump();
                Ok(Rep::Star)
            }
            Some('{') => {
                self.bump();
                self.skip_ws();
                let digits = self.pos;
                let mut n: usize = 0;
                let mut big = false;
                while let Some(d) = self.peek().and_then(|c| c.to_digit(10)) {
                    n = n.saturating_mul(10).saturating_add(d as usize);
                    big |= n > MAX_CELLS;
                    self.bump();
                }
                let empty = self.pos == digits;
                self.skip_ws();
                if empty || self.peek() != Some('}') {
                    return Err(self.err(at, PatternErrorKind::BadCount));
                }
                self.bump();
                if big {
                    return Err(self.err(digits, PatternErrorKind::CountTooLarge));
                }
                if n == 0 {
                    return Err(self.err(at, PatternErrorKind::ZeroCount));
                }
                Ok(Rep::Times(n))
            }
            _ => Ok(Rep::Once),
        }
    }

    /// The sequence's length as `a + b·k` (k the `*`'s fill count), or an error if either part
    /// passes [`MAX_CELLS`].
    fn seq_len(&self, items: &[Item]) -> Result<(usize, usize), PatternError> {
        let mut a = 0usize;
        let mut b = 0usize;
        for item in items {
            let (ia, ib) = self.item_len(item)?;
            a = a.saturating_add(ia);
            b = b.saturating_add(ib);
            if a > MAX_CELLS || b > MAX_CELLS {
                return Err(self.err(item.offset, PatternErrorKind::TooLong));
            }
        }
        Ok((a, b))
    }

    fn item_len(&self, item: &Item) -> Result<(usize, usize), PatternError> {
        let (na, nb) = match &item.node {
            Node::Letter(_) => (1, 0),
            Node::Group(inner) => self.seq_len(inner)?,
        };
        let too_long = || self.err(item.offset, PatternErrorKind::TooLong);
        match item.rep {
            Rep::Once => Ok((na, nb)),
            Rep::Star => Ok((0, na)),
            Rep::Times(n) => {
                let a = na.checked_mul(n).filter(|&x| x <= MAX_CELLS);
                let b = nb.checked_mul(n).filter(|&x| x <= MAX_CELLS);
                match (a, b) {
                    (Some(a), Some(b)) => Ok((a, b)),
                    _ => Err(too_long()),
                }
            }
        }
    }
}

/// Stores each item's node lengths (once `seq_len` has checked they are in bounds).
fn annotate(items: &mut [Item]) -> (usize, usize) {
    let mut a = 0;
    let mut b = 0;
    for item in items {
        let (na, nb) = match &mut item.node {
            Node::Letter(_) => (1, 0),
            Node::Group(inner) => annotate(inner),
        };
        item.node_a = na;
        item.node_b = nb;
        let (ia, ib) = item.len();
        a += ia;
        b += ib;
    }
    (a, b)
}

/// Walks the expansion for a fill count k, calling `emit` on each letter in order.
fn walk(items: &[Item], k: usize, emit: &mut impl FnMut(char)) {
    for item in items {
        let (_, times) = item.node_len_times(k);
        for _ in 0..times {
            match &item.node {
                Node::Letter(c) => emit(*c),
                Node::Group(inner) => walk(inner, k, emit),
            }
        }
    }
}

/// The byte offset of the letter that writes cell `t` (0-based) for a fill count k, if the
/// expansion is that long.
fn locate(items: &[Item], mut t: usize, k: usize) -> Option<usize> {
    for item in items {
        let (node, times) = item.node_len_times(k);
        let len = node.saturating_mul(times);
        if t < len {
            return match &item.node {
                Node::Letter(_) => Some(item.offset),
                Node::Group(inner) => locate(inner, t % node, k),
            };
        }
        t -= len;
    }
    None
}

#[cfg(test)]
fn collect_letters(items: &[Item], out: &mut Vec<char>) {
    for item in items {
        match &item.node {
            Node::Letter(c) => {
                if !out.contains(c) {
                    out.push(*c);
                }
            }
            Node::Group(inner) => collect_letters(inner, out),
        }
    }
}

impl Pattern {
    /// The pattern string as written.
    pub fn source(&self) -> &str {
        &self.source
    }

    /// The byte offset of the `*`, if there is one.
    pub fn star(&self) -> Option<usize> {
        self.star
    }

    /// The distinct letters of the pattern, in order of first appearance (for a warning when the
    /// letter to select is not among them).
    #[cfg(test)]
    pub(crate) fn letters(&self) -> Vec<char> {
        let mut out = Vec::new();
        collect_letters(&self.items, &mut out);
        out
    }

    fn err(&self, offset: usize, kind: PatternErrorKind) -> PatternError {
        PatternError {
            offset,
            kind,
            pattern: self.source.clone(),
        }
    }

    /// How many times the `*` repeats on a rows × cols grid (0 without a `*`), or the error
    /// saying where the pattern stops tiling it.
    pub(crate) fn fill_count(&self, rows: usize, cols: usize) -> Result<usize, PatternError> {
        let need = rows
            .checked_mul(cols)
            .filter(|&n| rows > 0 && cols > 0 && n <= MAX_CELLS)
            .ok_or_else(|| self.err(0, PatternErrorKind::BadGrid { rows, cols }))?;
        if self.fixed > need {
            let at = locate(&self.items, need, 0).unwrap_or(self.source.len());
            return Err(self.err(
                at,
                PatternErrorKind::Overflow {
                    rows,
                    cols,
                    got: self.fixed,
                },
            ));
        }
        let left = need - self.fixed;
        match self.star {
            None if left > 0 => Err(self.err(
                self.source.len(),
                PatternErrorKind::Short {
                    rows,
                    cols,
                    got: self.fixed,
                },
            )),
            None => Ok(0),
            Some(at) => {
                // unit >= 1: a starred item is a letter or a non-empty group.
                let unit = self.unit.max(1);
                if left % unit != 0 {
                    return Err(self.err(
                        at,
                        PatternErrorKind::StarNotDividing {
                            rows,
                            cols,
                            left,
                            unit,
                        },
                    ));
                }
                Ok(left / unit)
            }
        }
    }

    /// The letters of a rows × cols grid, exactly rows × cols of them, as the facade is seen:
    /// the top row's leftmost cell first, row-major, the ground floor last.
    pub fn expand(&self, rows: usize, cols: usize) -> Result<Vec<char>, PatternError> {
        let k = self.fill_count(rows, cols)?;
        let mut out = Vec::with_capacity(rows * cols);
        walk(&self.items, k, &mut |c| out.push(c));
        Ok(out)
    }

    /// The cells of a rows × cols grid whose letter is `pat` (one alphabetic character), in the
    /// grid's convention (row 1 is the ground floor). The set may be empty: the caller warns when
    /// `pat` is not among [`Pattern::letters`].
    #[cfg(test)]
    pub(crate) fn select(
        &self,
        pat: &str,
        rows: usize,
        cols: usize,
    ) -> Result<CellSet, PatternError> {
        self.select_with(pat, rows, cols, false).map(|(set, _)| set)
    }

    /// [`Pattern::select`], but a pattern without `*` that ends before the grid is full is not
    /// an error: the cells after its end are not selected, as the seed says (L927). Also
    /// returns how many cells the pattern left out (0 when it tiles), for the caller's warning.
    /// Every other error stays an error.
    pub(crate) fn select_allowing_short(
        &self,
        pat: &str,
        rows: usize,
        cols: usize,
    ) -> Result<(CellSet, usize), PatternError> {
        self.select_with(pat, rows, cols, true)
    }

    fn select_with(
        &self,
        pat: &str,
        rows: usize,
        cols: usize,
        allow_short: bool,
    ) -> Result<(CellSet, usize), PatternError> {
        let mut chars = pat.chars();
        let letter = match (chars.next(), chars.next()) {
            (Some(c), None) if c.is_alphabetic() => c,
            _ => return Err(self.err(0, PatternErrorKind::BadLetter(pat.to_string()))),
        };
        let (k, left_out) = match self.fill_count(rows, cols) {
            Ok(k) => (k, 0),
            Err(PatternError {
                kind: PatternErrorKind::Short { got, .. },
                ..
            }) if allow_short => (0, rows * cols - got),
            Err(e) => return Err(e),
        };
        let mut set = CellSet::empty(rows, cols)
            .map_err(|_| self.err(0, PatternErrorKind::BadGrid { rows, cols }))?;
        let mut i = 0usize;
        walk(&self.items, k, &mut |c| {
            if c == letter {
                // In range: the expansion has at most rows × cols cells.
                let _ = set.insert(rows - i / cols, i % cols + 1);
            }
            i += 1;
        });
        Ok((set, left_out))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use PatternErrorKind as K;

    fn expand(p: &str, rows: usize, cols: usize) -> String {
        parse(p)
            .unwrap()
            .expand(rows, cols)
            .unwrap()
            .into_iter()
            .collect()
    }

    fn err(p: &str, rows: usize, cols: usize) -> PatternError {
        match parse(p) {
            Err(e) => e,
            Ok(x) => x.expand(rows, cols).unwrap_err(),
        }
    }

    #[test]
    fn a_short_pattern_leaves_the_rest_unselected_when_allowed() {
        let p = parse("X{10}(XA{8}X){8}").unwrap();
        assert!(matches!(
            p.select("A", 40, 10).unwrap_err().kind,
            K::Short { got: 90, .. }
        ));
        let (set, left) = p.select_allowing_short("A", 40, 10).unwrap();
        assert_eq!((set.len(), left), (64, 310));
        // Rows 39 down to 32 (the top row is 40), columns 2 to 9.
        assert!(set.contains(39, 2) && set.contains(32, 9) && !set.contains(31, 5));
        // Other errors stay errors.
        assert!(parse("X{500}")
            .unwrap()
            .select_allowing_short("X", 4, 4)
            .is_err());
    }

    #[test]
    fn seed_examples_under_strict_tiling() {
        assert_eq!(expand("(AB)*", 1, 10), "ABABABABAB");
        assert_eq!(expand("(B)*AA", 1, 10), "BBBBBBBBAA");
        // A `*` after a bare letter repeats the letter (the seed's code ignored it: BAA).
        assert_eq!(expand("B*AA", 1, 10), "BBBBBBBBAA");
        assert_eq!(expand("B*AA", 2, 5), "BBBBBBBBAA");
        // Fig. 29: 11 + k·22 = 121 -> k = 5: a blank row, then 5 × (window row, blank row).
        let s = expand("X{11}((XA){5}XX{11})*", 11, 11);
        let rows: Vec<&str> = (0..11).map(|r| &s[r * 11..r * 11 + 11]).collect();
        assert_eq!(rows[0], "XXXXXXXXXXX");
        assert_eq!(rows[1], "XAXAXAXAXAX");
        assert_eq!(rows[2], "XXXXXXXXXXX");
        assert_eq!(rows[9], "XAXAXAXAXAX");
        assert_eq!(rows[10], "XXXXXXXXXXX");
        // Fig. 30b: 11 + 4·22 + 2·11 = 121, tiles.
        let p = "X{11}((XA{4}){2}XX{11}){4}(XXXX{5}XXX){2}";
        let set = select(p, "A", 11, 11).unwrap();
        assert_eq!(set.len(), 32);
        // Row 2 from the top is row 10 from the ground: cells 2-5 and 7-10 are windows.
        assert!(set.contains(10, 2) && set.contains(10, 5) && !set.contains(10, 6));
        // Fig. 31: 33 + 55 + 33 = 121.
        assert_eq!(
            select("(X{11}){3}((XA){5}X){5}(X{11}){3}", "A", 11, 11)
                .unwrap()
                .len(),
            25
        );
        // The door in the last two rows of a 21 × 10 grid: the ground floor and the one above.
        let door = select("(X)*(X{4}A{2}X{4}){2}", "A", 21, 10).unwrap();
        let cells: Vec<_> = door.iter().collect();
        assert_eq!(cells, vec![(1, 5), (1, 6), (2, 5), (2, 6)]);
        // The clock: 90 of 400 cells.
        let e = err("X{10}(XA{8}X){8}", 40, 10);
        assert_eq!(e.offset, 16);
        assert_eq!(
            e.kind,
            K::Short {
                rows: 40,
                cols: 10,
                got: 90
            }
        );
        assert_eq!(
            e.to_string(),
            "pattern \"X{10}(XA{8}X){8}\" gives 90 cells (9 rows) for a 40 × 10 grid (400): 310 short; it stops at row 31, column 1 (row 1 is the ground floor); add a `*` or more cells"
        );
        // ... and with a `*` it tiles: the clock in the top 9 rows.
        let clock = select("X{10}(XA{8}X){8}(X)*", "A", 40, 10).unwrap();
        assert_eq!(clock.len(), 64);
        assert!(clock.contains(39, 2) && clock.contains(32, 9) && !clock.contains(31, 2));
    }

    #[test]
    fn row_convention() {
        // First character = top row, leftmost; last = ground floor, rightmost.
        let set = select("AX{5}", "A", 2, 3).unwrap();
        assert_eq!(set.iter().collect::<Vec<_>>(), vec![(2, 1)]);
        let set = select("X{5}A", "A", 2, 3).unwrap();
        assert_eq!(set.iter().collect::<Vec<_>>(), vec![(1, 3)]);
    }

    #[test]
    fn grammar_and_errors() {
        assert_eq!(expand("((XA))", 1, 2), "XA");
        assert_eq!(expand("((XA){2}B){2}", 1, 10), "XAXABXAXAB");
        assert_eq!(expand("X{2} (A B)*", 2, 3), "XXABAB");
        assert_eq!(expand("éa{2}", 1, 3), "éaa");
        // A star inside a repeated group: filled once, repeated with the group.
        assert_eq!(expand("(X(A)*X){2}", 2, 4), "XAAXXAAX");
        // Zero repeats of the `*` are allowed.
        assert_eq!(expand("XA(B)*", 1, 2), "XA");
        let cases: &[(&str, usize, K)] = &[
            ("", 0, K::Empty),
            ("  ", 0, K::Empty),
            ("X{8}{7}", 4, K::ChainedRepeat),
            ("(X{8}{7}(XXXAAXX){4}", 5, K::ChainedRepeat),
            ("X{2}*", 4, K::ChainedRepeat),
            ("X*{2}", 2, K::ChainedRepeat),
            ("(X{3}(XAX){2}", 0, K::UnclosedGroup),
            ("XA)", 2, K::UnmatchedClose),
            ("X()", 1, K::EmptyGroup),
            ("X{}", 1, K::BadCount),
            ("X{a}", 1, K::BadCount),
            ("X{3", 1, K::BadCount),
            ("X{0}", 1, K::ZeroCount),
            ("X{99999999999999999999999}", 2, K::CountTooLarge),
            ("{3}", 0, K::RepeatWithoutItem('{')),
            ("(*X)", 1, K::RepeatWithoutItem('*')),
            ("X1", 1, K::UnexpectedChar('1')),
            ("X}", 1, K::UnexpectedChar('}')),
            ("X?", 1, K::UnexpectedChar('?')),
            ("(X)*A(B)*", 8, K::MultipleStars { first: 3 }),
            ("((X)*)*", 6, K::MultipleStars { first: 4 }),
            ("(X{1000}){1000}X", 15, K::TooLong),
            ("((X{1000}){1000}){1000}", 0, K::TooLong),
        ];
        for (p, offset, kind) in cases {
            let e = parse(p).unwrap_err();
            assert_eq!((e.offset, &e.kind), (*offset, kind), "{p}: {e}");
            assert!(!e.to_string().is_empty());
        }
        let deep = format!(
            "{}X{}",
            "(".repeat(MAX_DEPTH + 1),
            ")".repeat(MAX_DEPTH + 1)
        );
        assert_eq!(parse(&deep).unwrap_err().kind, K::TooDeep);
        let ok = format!("{}X{}", "(".repeat(MAX_DEPTH), ")".repeat(MAX_DEPTH));
        assert_eq!(expand(&ok, 1, 1), "X");
        // Overflow names the letter that makes the first cell too many.
        let e = err("XXA{5}", 2, 2);
        assert_eq!(
            (e.offset, e.kind.clone()),
            (
                2,
                K::Overflow {
                    rows: 2,
                    cols: 2,
                    got: 7
                }
            )
        );
        let e = err("X{3}(AB){4}", 2, 3);
        assert_eq!(e.offset, 6); // the B of the second repeat writes cell 7
        assert_eq!(
            e.to_string(),
            "pattern \"X{3}(AB){4}\" gives 11 cells (3 rows and 2 cells) for a 2 × 3 grid (6): 5 too many; the grid is full (row 1, column 3) at offset 6"
        );
        // A `*` that cannot divide what is left.
        let e = err("X{10}(XXAXAAXXXX{10})*X{20}", 21, 10);
        assert_eq!(e.offset, 21);
        assert_eq!(
            e.kind,
            K::StarNotDividing {
                rows: 21,
                cols: 10,
                left: 180,
                unit: 19
            }
        );
        assert_eq!(
            e.to_string(),
            "pattern \"X{10}(XXAXAAXXXX{10})*X{20}\": the `*` at offset 21 repeats 19 cells to fill the 180 cells left of a 21 × 10 grid, which is not a whole number of repeats: 9 leave 9 cells empty, 10 overflow by 10"
        );
        // Overflow even with zero repeats of the `*`.
        let e = err("X{5}(A)*", 1, 4);
        assert_eq!(
            e.kind,
            K::Overflow {
                rows: 1,
                cols: 4,
                got: 5
            }
        );
        assert_eq!(e.offset, 0);
        // Bad grids and bad letters.
        let p = parse("(X)*").unwrap();
        assert_eq!(
            p.expand(0, 3).unwrap_err().kind,
            K::BadGrid { rows: 0, cols: 3 }
        );
        assert!(p.expand(usize::MAX, 3).is_err());
        assert!(p.expand(2000, 2000).is_err());
        assert_eq!(
            p.select("AB", 1, 1).unwrap_err().kind,
            K::BadLetter("AB".into())
        );
        assert_eq!(
            p.select("", 1, 1).unwrap_err().kind,
            K::BadLetter(String::new())
        );
        assert_eq!(
            p.select("1", 1, 1).unwrap_err().kind,
            K::BadLetter("1".into())
        );
        // A letter absent from the pattern selects nothing; the caller warns from `letters`.
        assert!(p.select("A", 3, 3).unwrap().is_empty());
        assert_eq!(parse("X{3}(AxA)*").unwrap().letters(), vec!['X', 'A', 'x']);
        // Hand-made errors with odd fields still display.
        for kind in [
            K::Short {
                rows: 0,
                cols: 0,
                got: 9,
            },
            K::Overflow {
                rows: 0,
                cols: 0,
                got: 0,
            },
            K::StarNotDividing {
                rows: usize::MAX,
                cols: 2,
                left: usize::MAX,
                unit: 0,
            },
        ] {
            let e = PatternError {
                offset: 99,
                kind,
                pattern: String::new(),
            };
            assert!(!e.to_string().is_empty());
        }
    }

    /// The seed's appendix patterns (Código-fonte 12-15, L1687-L2088), each with the grid of the
    /// nearest `updateGrid` before it, lines joined. `Ok(n)`: it tiles and selects n cells of
    /// `A`; `Err((offset, kind))`: where and why it does not.
    #[allow(clippy::type_complexity)]
    const APPENDIX: &[(&str, usize, usize, Result<usize, (usize, &str)>)] = &[
        // Código-fonte 12
        ("X{10}(XXAXAAXXXX{10})*X{20}", 21, 10, Err((21, "star"))),
        ("(X)*(X{4}A{2}X{4}){2}", 21, 10, Ok(4)),
        ("(X{20}(XAXAXA{10}XAXAX){2}){2}(X{20}(XAX{14}AAX){2}){2}", 45, 20, Err((55, "short"))),
        ("(X{17}(XA){8}X){4}X{22}(AX){4}", 17, 17, Err((30, "short"))),
        // Código-fonte 13
        ("X{41}((XAXXA){8}X){2}X{82}(XAXXX){8}X((XAXXA){8}X){2}(XAXXX){8}X", 9, 41, Ok(80)),
        ("X{41}((XAXXX){8}X){2}X{82}((XAXXX){8}X){4}", 9, 41, Ok(48)),
        ("X{40}(X(AAXX){9}AAX){3}X{80}(X(AAXX){9}AAX){3}", 10, 40, Err((46, "short"))),
        ("(X{29}(X(AX){14}){2}){2}X{29}X(AX){14}XAXAX{20}XAXAXX{29}(XAXAX{20}XAXAX){2}", 14, 29, Err((76, "short"))),
        ("(X{3}(XAX){2}", 7, 3, Err((0, "unclosed"))),
        ("(X{3}(XAX){3}X{6}(XAX){2}", 13, 3, Err((0, "unclosed"))),
        ("(X{8}{7}(XXXAAXX){4}", 11, 8, Err((5, "chained"))),
        ("(X{20}((XA){4}XAX(XA){4}X){2}){3}X{20}((XA){3}X{12}AX){2}X{20}XAX{18}XA", 20, 20, Err((71, "short"))),
        ("(X{20}(X{10}AX{9}){2}){3}", 20, 20, Err((25, "short"))),
        // Código-fonte 14
        ("(X{33}(X(XAX){3}X){2}x{22}(X(XAX){3}X){4}X{22}(X(XAX){3}X){2}", 18, 11, Err((0, "unclosed"))),
        ("X{8}(XXAXXAXX){3}", 4, 8, Ok(6)),
        ("X{7}X(AX){3}X{7}(X(AX){3}){3}X{7}(X(AX){3}){2}", 10, 7, Err((46, "short"))),
        ("X{3}XAXX{3}(XAX){2}X{3}XA", 8, 3, Err((25, "short"))),
        ("X{25}((XA){12}X){2}X{25}((XA){3}X{10}(XA){4}X){2}X{25}(XA){3}X{10}(XA){4}", 20, 25, Err((73, "short"))),
        ("(X{16}(X{3}AXAX{4}AXAX{3}){2}){3}", 10, 16, Err((33, "short"))),
        ("(X)*(XX(AX){5}X){3}X{26}", 21, 13, Ok(15)),
        // Código-fonte 15
        ("X{6}(XXAAX){3}", 4, 6, Err((14, "short"))),
        ("X{16}((XXAAX){3}XX){3}X{32}{8}", 40, 16, Err((27, "chained"))),
        ("X{6}((XXAAX){3}X{12}){3}(X)*(XXAAX){4}X{6}", 30, 6, Ok(26)),
        ("XXXXAXXX", 3, 3, Err((8, "short"))),
        ("(X{20}(XAA){10}){5}(X{20}(XAA){12}XAA){2}){2}", 42, 20, Err((41, "unmatched"))),
        ("x{26}(X{4}(XAA){2}XX(XAA){2}X{4}){2}(x{26}((XAAAX){3}XX(XAAAX){3}){2}){3}(XAAAX){3}XX(XAAAX){3}", 42, 26, Err((95, "short"))),
        ("X{16}(X(AAAX){5}){2}XAAAX{4}AAAX{4}AAAX{16}(X(AAX){5}){2}X{4}AAAX{4}AAAX{4}X{16}(X(AAX){5}){2}XAAAX{4}AAAX{4}AAAX{16}(X(AAX){5}){2}", 16, 16, Ok(114)),
        ("X{16}(X(AAAX){5}){2}X{16}XAAAX{4}AAAX{4}AAAX(X(AAX){5}){3}(XAAAX{4}AAAX{4}AAAX){2}", 10, 16, Err((59, "overflow"))),
        ("X{10}(XXXAAAXXX){2}", 12, 10, Err((19, "short"))),
    ];

    fn kind_name(k: &K) -> &'static str {
        match k {
            K::Short { .. } => "short",
            K::Overflow { .. } => "overflow",
            K::StarNotDividing { .. } => "star",
            K::UnclosedGroup => "unclosed",
            K::UnmatchedClose => "unmatched",
            K::ChainedRepeat => "chained",
            _ => "other",
        }
    }

    #[test]
    fn appendix_patterns() {
        let mut report = Vec::new();
        for (p, rows, cols, want) in APPENDIX {
            let got = select(p, "A", *rows, *cols)
                .map(|s| s.len())
                .map_err(|e| (e.offset, kind_name(&e.kind)));
            if got != *want {
                report.push(format!("{p} on {rows}×{cols}: got {got:?}, want {want:?}"));
            }
        }
        assert!(report.is_empty(), "{}", report.join("\n"));
        // 29 distinct (pattern, grid) pairs of the 37 calls: 7 tile, 22 do not (14 short,
        // 1 overflow, 1 `*` that cannot divide, 3 unclosed groups, 1 stray `)`, 2 chained repeats).
        assert_eq!(APPENDIX.len(), 29);
        assert_eq!(APPENDIX.iter().filter(|x| x.3.is_ok()).count(), 7);
    }

    /// A pattern naming `sel` (top row first) as run-length encoded rows.
    fn rle(sel: &[Vec<bool>]) -> String {
        let mut s = String::new();
        for row in sel {
            let mut c = 0;
            while c < row.len() {
                let v = row[c];
                let mut n = 1;
                while c + n < row.len() && row[c + n] == v {
                    n += 1;
                }
                s.push(if v { 'A' } else { 'X' });
                if n > 1 {
                    s.push_str(&format!("{{{n}}}"));
                }
                c += n;
            }
        }
        s
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(200))]

        #[test]
        fn generated_patterns_select_what_they_name(
            rows in 1usize..=40,
            cols in 1usize..=40,
            seed in any::<u64>(),
            density in 0u32..=100,
            blank in 0usize..=3,
            style in 0u8..4,
        ) {
            // A random selection from a small LCG, top row first.
            let mut x = seed | 1;
            let mut sel: Vec<Vec<bool>> = (0..rows)
                .map(|_| (0..cols).map(|_| {
                    x = x.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                    ((x >> 33) % 100) < u64::from(density)
                }).collect())
                .collect();
            // `blank` rows left empty at the top (style 1, 2) or the bottom (style 3) for a `*`.
            let blank = blank.min(rows);
            let pattern = match style {
                0 => rle(&sel),
                1 | 2 => {
                    for r in sel.iter_mut().take(blank) { r.fill(false); }
                    let star = if style == 1 { "X*".to_string() } else { format!("(X{{{cols}}})*") };
                    format!("{star}{}", rle(&sel[blank..]))
                }
                _ => {
                    for r in sel.iter_mut().skip(rows - blank) { r.fill(false); }
                    format!("{}(X)*", rle(&sel[..rows - blank]))
                }
            };
            let got = match parse(&pattern) {
                Ok(p) => p.select("A", rows, cols),
                Err(e) => Err(e),
            };
            let got = got.unwrap();
            let mut want = CellSet::empty(rows, cols).unwrap();
            for (i, row) in sel.iter().enumerate() {
                for (j, &v) in row.iter().enumerate() {
                    if v { want.insert(rows - i, j + 1).unwrap(); }
                }
            }
            prop_assert_eq!(got, want, "{}", pattern);
        }

        #[test]
        fn random_strings_never_panic(
            s in "[XAa()*{}0-9 é?]{0,40}",
            rows in 0usize..50,
            cols in 0usize..50,
        ) {
            if let Ok(p) = parse(&s) {
                let _ = p.expand(rows, cols);
                let _ = p.select("A", rows, cols);
                let _ = p.letters();
            } else if let Err(e) = parse(&s) {
                prop_assert!(e.offset <= s.len());
                prop_assert!(s.is_char_boundary(e.offset));
                let _ = e.to_string();
            }
        }
    }
}
