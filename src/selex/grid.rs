//! Virtual grids on a wall: rows × columns of cells that guide where elements go and are never
//! used to split the wall (seed 000 §3.2), their cell selection and their grouping into elements.
//!
//! # Conventions
//!
//! - A grid lies on one wall, in metres, **seen from outside**: the origin is the wall's
//!   bottom-left corner, x runs to the right, y up.
//! - **Row 1 is the ground floor** (the bottom row, y = 0), counted upwards; **column 1 is the
//!   leftmost** (x = 0). Indices are 1-based; a negative index counts from the end (-1 is the top
//!   row or the rightmost column); 0 is never an index.
//! - Default labels: rows `gnd` (row 1), `top` (the last row) and `mid` (the others); columns
//!   `left` (column 1), `right` (the last column) and `mid` (the others), as Jiang et al. (2018,
//!   Fig. 13) use them. A one-row grid's only row carries both `gnd` and `top`, a one-column
//!   grid's only column both `left` and `right`; a two-row (two-column) grid has no `mid`. An index
//!   may carry any number of labels: `rowLabel == "x"` keeps the cells whose row carries `x`
//!   among its labels, `rowLabel != "x"` those whose row does not. `Grid::with_col_labels` and
//!   `Grid::with_row_labels` replace the defaults (Jiang's figure labels several columns
//!   `left`).
//! - A selection is a [`CellSet`]; selectors on one step are intersected, so `[rowIdx in R]`
//!   `[colIdx in C]` gives the Cartesian product R × C as the seed does.
//! - Grouping ([`Grouping`]) turns a selection into [`Element`]s, each a rectangle of cells,
//!   listed **bottom row first, then left to right** (by first row, then first column).
//!
//! Everything here is a pure function and returns an error rather than panicking: zero rows or
//! columns, non-finite, zero or negative sizes, more than [`MAX_CELLS`] cells, an index out of
//! range, a reversed range.

use std::fmt;

/// The largest number of cells a grid (or a pattern's expansion) may have.
pub const MAX_CELLS: usize = 1_000_000;

/// Which axis of a grid an index, a range or a label refers to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Axis {
    /// Rows (storeys), `rowIdx` and `rowLabel`.
    Row,
    /// Columns (bays), `colIdx` and `colLabel`.
    Col,
}

impl fmt::Display for Axis {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Axis::Row => "row",
            Axis::Col => "column",
        })
    }
}

/// A comparison operator of an attribute selector (`rowIdx > 1`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) enum CmpOp {
    /// `==`
    Eq,
    /// `!=`
    Ne,
    /// `<`
    Lt,
    /// `<=`
    Le,
    /// `>`
    Gt,
    /// `>=`
    Ge,
}

impl CmpOp {
    fn holds(self, a: usize, b: usize) -> bool {
        match self {
            CmpOp::Eq => a == b,
            CmpOp::Ne => a != b,
            CmpOp::Lt => a < b,
            CmpOp::Le => a <= b,
            CmpOp::Gt => a > b,
            CmpOp::Ge => a >= b,
        }
    }
}

/// One member of an `in (...)` list: a single index or an inclusive range.
///
/// `indexRange(a, b)` (Brito, Anchiêta) and `rowRange(a, b)` (Jiang) are the same thing here:
/// both inclusive, both resolve a negative bound from the end of the axis they index
/// (`rowRange(2, -2)` on 5 rows is rows 2, 3, 4; on columns it counts columns).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) enum IndexItem {
    /// One index, 1-based, negative from the end.
    One(i64),
    /// An inclusive range `from..=to`, each bound 1-based or negative from the end.
    Range(i64, i64),
}

/// What went wrong building a grid or selecting cells. The caller adds file:line:col.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum GridError {
    /// A size (width, height, storey height, bay width) is NaN, infinite, zero or negative.
    #[error("{what} must be a finite positive number of metres, not {value}")]
    BadSize {
        /// Which size.
        what: &'static str,
        /// The value given.
        value: f64,
    },
    /// Zero rows or zero columns.
    #[error("a grid needs at least one {0}")]
    ZeroCount(Axis),
    /// More than [`MAX_CELLS`] cells.
    #[error("a grid of {rows} × {cols} cells is larger than the limit of {max} cells", max = MAX_CELLS)]
    TooManyCells {
        /// Rows asked.
        rows: usize,
        /// Columns asked.
        cols: usize,
    },
    /// Index 0 (indices are 1-based, negative from the end).
    #[error("{0} index 0 does not exist: indices start at 1 (or -1 for the last)")]
    IndexZero(Axis),
    /// An index beyond the grid.
    #[error("{axis} index {index} is out of range: the grid has {count} {axis}s (valid: 1..={count} or -{count}..=-1)")]
    IndexOutOfRange {
        /// The axis.
        axis: Axis,
        /// The index as written.
        index: i64,
        /// How many rows or columns the grid has.
        count: usize,
    },
    /// A range whose start comes after its end once negative bounds are resolved.
    #[error("{axis} range ({from}, {to}) is empty: it runs from {axis} {from_resolved} down to {to_resolved}; ranges are inclusive and ascending")]
    ReversedRange {
        /// The axis.
        axis: Axis,
        /// The first bound as written.
        from: i64,
        /// The second bound as written.
        to: i64,
        /// The first bound resolved (1-based).
        from_resolved: usize,
        /// The second bound resolved (1-based).
        to_resolved: usize,
    },
    /// A cell (row, col) outside the grid.
    #[error("cell (row {row}, column {col}) is outside a {rows} × {cols} grid")]
    CellOutOfRange {
        /// Row asked.
        row: usize,
        /// Column asked.
        col: usize,
        /// Rows of the grid.
        rows: usize,
        /// Columns of the grid.
        cols: usize,
    },
    /// Two cell sets (or a set and a grid) of different sizes.
    #[error("a selection of {a_rows} × {a_cols} cells cannot be combined with one of {b_rows} × {b_cols}")]
    DimsMismatch {
        /// Rows of the first.
        a_rows: usize,
        /// Columns of the first.
        a_cols: usize,
        /// Rows of the second.
        b_rows: usize,
        /// Columns of the second.
        b_cols: usize,
    },
    /// A label list whose length is not the number of rows or columns.
    #[error("{axis} labels given for {got} {axis}s, but the grid has {count}")]
    LabelCount {
        /// The axis.
        axis: Axis,
        /// How many label lists were given.
        got: usize,
        /// How many the grid needs.
        count: usize,
    },
    /// A label comparison other than `==` or `!=`.
    #[error("labels compare only with == and != (not an ordering)")]
    LabelOrdering,
}

impl GridError {
    /// Whether the error comes from the grid's size (an index or range past its rows or
    /// columns), so that the same selector fits a larger grid.
    pub(crate) fn depends_on_size(&self) -> bool {
        matches!(
            self,
            GridError::IndexOutOfRange { .. } | GridError::ReversedRange { .. }
        )
    }
}

fn check_dims(rows: usize, cols: usize) -> Result<(), GridError> {
    if rows == 0 {
        return Err(GridError::ZeroCount(Axis::Row));
    }
    if cols == 0 {
        return Err(GridError::ZeroCount(Axis::Col));
    }
    match rows.checked_mul(cols) {
        Some(n) if n <= MAX_CELLS => Ok(()),
        _ => Err(GridError::TooManyCells { rows, cols }),
    }
}

fn check_size(what: &'static str, value: f64) -> Result<f64, GridError> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(GridError::BadSize { what, value })
    }
}

/// Resolves a 1-based index (negative from the end) on an axis of `count` entries.
pub(crate) fn resolve_index(axis: Axis, index: i64, count: usize) -> Result<usize, GridError> {
    let out = GridError::IndexOutOfRange { axis, index, count };
    if index == 0 {
        return Err(GridError::IndexZero(axis));
    }
    let mag = usize::try_from(index.unsigned_abs()).map_err(|_| out.clone())?;
    if mag > count {
        return Err(out);
    }
    Ok(if index > 0 { mag } else { count + 1 - mag })
}

/// Resolves an `in (...)` list to sorted, de-duplicated 1-based indices.
pub(crate) fn resolve_items(
    axis: Axis,
    items: &[IndexItem],
    count: usize,
) -> Result<Vec<usize>, GridError> {
    let mut out = Vec::new();
    for item in items {
        match *item {
            IndexItem::One(i) => out.push(resolve_index(axis, i, count)?),
            IndexItem::Range(a, b) => {
                let from = resolve_index(axis, a, count)?;
                let to = resolve_index(axis, b, count)?;
                if from > to {
                    return Err(GridError::ReversedRange {
                        axis,
                        from: a,
                        to: b,
                        from_resolved: from,
                        to_resolved: to,
                    });
                }
                out.extend(from..=to);
            }
        }
    }
    out.sort_unstable();
    out.dedup();
    Ok(out)
}

/// A set of cells of a rows × cols grid, stored as one bit per cell.
///
/// Iteration ([`CellSet::iter`]) goes **bottom row first** (row 1), each row left to right.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct CellSet {
    rows: usize,
    cols: usize,
    bits: Vec<u64>,
}

impl CellSet {
    /// An empty set over a rows × cols grid.
    pub fn empty(rows: usize, cols: usize) -> Result<CellSet, GridError> {
        check_dims(rows, cols)?;
        Ok(CellSet {
            rows,
            cols,
            bits: vec![0; (rows * cols).div_ceil(64)],
        })
    }

    /// Every cell of a rows × cols grid.
    pub fn full(rows: usize, cols: usize) -> Result<CellSet, GridError> {
        let mut s = CellSet::empty(rows, cols)?;
        let n = rows * cols;
        for (w, word) in s.bits.iter_mut().enumerate() {
            let left = n - w * 64;
            *word = if left >= 64 {
                u64::MAX
            } else {
                (1u64 << left) - 1
            };
        }
        Ok(s)
    }

    /// Rows of the grid the set is over.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Columns of the grid the set is over.
    pub fn cols(&self) -> usize {
        self.cols
    }

    fn slot(&self, row: usize, col: usize) -> Option<usize> {
        (row >= 1 && row <= self.rows && col >= 1 && col <= self.cols)
            .then(|| (row - 1) * self.cols + (col - 1))
    }

    fn out_of_range(&self, row: usize, col: usize) -> GridError {
        GridError::CellOutOfRange {
            row,
            col,
            rows: self.rows,
            cols: self.cols,
        }
    }

    /// Whether cell (row, col) (1-based, row 1 at the bottom) is in the set; false outside it.
    pub fn contains(&self, row: usize, col: usize) -> bool {
        self.slot(row, col)
            .is_some_and(|i| self.bits[i / 64] >> (i % 64) & 1 == 1)
    }

    /// Adds cell (row, col); an error outside the grid.
    pub fn insert(&mut self, row: usize, col: usize) -> Result<(), GridError> {
        let i = self
            .slot(row, col)
            .ok_or_else(|| self.out_of_range(row, col))?;
        self.bits[i / 64] |= 1 << (i % 64);
        Ok(())
    }

    /// Removes cell (row, col); an error outside the grid.
    pub fn remove(&mut self, row: usize, col: usize) -> Result<(), GridError> {
        let i = self
            .slot(row, col)
            .ok_or_else(|| self.out_of_range(row, col))?;
        self.bits[i / 64] &= !(1 << (i % 64));
        Ok(())
    }

    /// Number of cells in the set.
    pub fn len(&self) -> usize {
        self.bits.iter().map(|w| w.count_ones() as usize).sum()
    }

    /// Whether the set has no cell.
    pub fn is_empty(&self) -> bool {
        self.bits.iter().all(|&w| w == 0)
    }

    /// The cells as (row, col), bottom row first, each row left to right.
    pub fn iter(&self) -> impl Iterator<Item = (usize, usize)> + '_ {
        let cols = self.cols;
        self.bits.iter().enumerate().flat_map(move |(w, &word)| {
            let mut word = word;
            std::iter::from_fn(move || {
                if word == 0 {
                    return None;
                }
                let b = word.trailing_zeros() as usize;
                word &= word - 1;
                let i = w * 64 + b;
                Some((i / cols + 1, i % cols + 1))
            })
        })
    }

    fn same_dims(&self, other: &CellSet) -> Result<(), GridError> {
        if self.rows == other.rows && self.cols == other.cols {
            Ok(())
        } else {
            Err(GridError::DimsMismatch {
                a_rows: self.rows,
                a_cols: self.cols,
                b_rows: other.rows,
                b_cols: other.cols,
            })
        }
    }

    fn zip(&self, other: &CellSet, f: impl Fn(u64, u64) -> u64) -> Result<CellSet, GridError> {
        self.same_dims(other)?;
        Ok(CellSet {
            rows: self.rows,
            cols: self.cols,
            bits: self
                .bits
                .iter()
                .zip(&other.bits)
                .map(|(&a, &b)| f(a, b))
                .collect(),
        })
    }

    /// Cells in both sets (two selectors on one step); an error if the sizes differ.
    pub fn intersect(&self, other: &CellSet) -> Result<CellSet, GridError> {
        self.zip(other, |a, b| a & b)
    }

    /// Cells in either set; an error if the sizes differ.
    pub fn union(&self, other: &CellSet) -> Result<CellSet, GridError> {
        self.zip(other, |a, b| a | b)
    }

    /// Cells of `self` not in `other`; an error if the sizes differ.
    pub fn difference(&self, other: &CellSet) -> Result<CellSet, GridError> {
        self.zip(other, |a, b| a & !b)
    }
}

/// A rectangle of cells, 1-based and inclusive: rows `row_from..=row_to` (row 1 at the bottom),
/// columns `col_from..=col_to` (column 1 at the left).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct CellRect {
    /// Lowest row.
    pub row_from: usize,
    /// Highest row.
    pub row_to: usize,
    /// Leftmost column.
    pub col_from: usize,
    /// Rightmost column.
    pub col_to: usize,
}

impl CellRect {
    /// Rows spanned.
    pub fn height(&self) -> usize {
        self.row_to + 1 - self.row_from
    }

    /// Columns spanned.
    pub fn width(&self) -> usize {
        self.col_to + 1 - self.col_from
    }

    /// Cells covered.
    pub fn cells(&self) -> usize {
        self.height() * self.width()
    }
}

/// A rectangle on the wall in metres: bottom-left corner (x, y) seen from outside, width, height.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rect {
    /// Left edge, metres from the wall's left end.
    pub x: f64,
    /// Bottom edge, metres above the wall's foot.
    pub y: f64,
    /// Width in metres.
    pub w: f64,
    /// Height in metres.
    pub h: f64,
}

/// How a selection is turned into elements (the grouping selectors `[::groupX()]`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Grouping {
    /// `groupEach` (and no grouping selector at all): one element per cell.
    Each,
    /// `groupRows`: in each row, one element per maximal run of horizontally adjacent cells.
    Rows,
    /// `groupCols` / `groupColumns`: in each column, one element per maximal vertical run.
    Cols,
    /// `groupPairs`: in each row, each horizontal run cut into consecutive pairs from the left;
    /// an odd run's last cell stays an element alone.
    Pairs,
    /// `groupRegions`: each 4-connected component of selected cells. A component that is not a
    /// rectangle is cut into rectangles: the maximal horizontal runs of each row, from the
    /// bottom row up, each merged with the rectangle directly below it when that rectangle ends
    /// on the row below and spans exactly the same columns. The rectangles of one component
    /// share [`Element::region`].
    Regions,
}

/// One grouped element: a rectangle of cells and its place on the wall.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Element {
    /// The cells it covers.
    pub cells: CellRect,
    /// Its rectangle on the wall, metres.
    pub rect: Rect,
    /// For [`Grouping::Regions`], the number (0-based) of the connected component it belongs to,
    /// components numbered in the order of their first cell (bottom row first, left to right);
    /// for the other groupings, the element's own position in the list.
    pub region: usize,
}

/// A virtual grid on a wall: row heights and column widths in metres, and labels.
#[derive(Clone, Debug, PartialEq)]
pub struct Grid {
    row_heights: Vec<f64>,
    col_widths: Vec<f64>,
    row_labels: Vec<Vec<String>>,
    col_labels: Vec<Vec<String>>,
}

fn default_labels(n: usize, first: &str, middle: &str, last: &str) -> Vec<Vec<String>> {
    (1..=n)
        .map(|i| {
            let mut l = Vec::new();
            if i == 1 {
                l.push(first.to_string());
            }
            if i == n {
                l.push(last.to_string());
            }
            if l.is_empty() {
                l.push(middle.to_string());
            }
            l
        })
        .collect()
}

impl Grid {
    fn from_sizes(row_heights: Vec<f64>, col_widths: Vec<f64>) -> Grid {
        let (rows, cols) = (row_heights.len(), col_widths.len());
        Grid {
            row_heights,
            col_widths,
            row_labels: default_labels(rows, "gnd", "mid", "top"),
            col_labels: default_labels(cols, "left", "mid", "right"),
        }
    }

    /// A uniform grid: `rows` equal rows over height `height`, `cols` equal columns over width
    /// `width` (the seed's `createGrid(label, rows, cols)`).
    pub fn uniform(width: f64, height: f64, rows: usize, cols: usize) -> Result<Grid, GridError> {
        let width = check_size("wall width", width)?;
        let height = check_size("wall height", height)?;
        check_dims(rows, cols)?;
        Ok(Grid::from_sizes(
            vec![height / rows as f64; rows],
            vec![width / cols as f64; cols],
        ))
    }

    /// A metric grid that fits a real wall: one row per storey, from the storey heights given
    /// bottom up, and `n = max(1, round(width / bay))` equal columns of `width / n`.
    pub(crate) fn metric(width: f64, storey_heights: &[f64], bay: f64) -> Result<Grid, GridError> {
        let width = check_size("wall width", width)?;
        let bay = check_size("bay width", bay)?;
        for &h in storey_heights {
            check_size("storey height", h)?;
        }
        let n = (width / bay).round().max(1.0);
        if n > MAX_CELLS as f64 {
            return Err(GridError::TooManyCells {
                rows: storey_heights.len(),
                cols: MAX_CELLS + 1,
            });
        }
        let cols = n as usize;
        check_dims(storey_heights.len(), cols)?;
        Ok(Grid::from_sizes(
            storey_heights.to_vec(),
            vec![width / n; cols],
        ))
    }

    /// The same wall re-divided uniformly into `rows` × `cols` (the seed's `updateGrid`);
    /// labels return to the defaults.
    #[cfg(test)]
    pub(crate) fn update(&self, rows: usize, cols: usize) -> Result<Grid, GridError> {
        Grid::uniform(self.width(), self.height(), rows, cols)
    }

    /// Replaces the row labels: one list per row, bottom row first.
    pub(crate) fn with_row_labels(mut self, labels: Vec<Vec<String>>) -> Result<Grid, GridError> {
        if labels.len() != self.rows() {
            return Err(GridError::LabelCount {
                axis: Axis::Row,
                got: labels.len(),
                count: self.rows(),
            });
        }
        self.row_labels = labels;
        Ok(self)
    }

    /// Replaces the column labels: one list per column, leftmost first.
    pub(crate) fn with_col_labels(mut self, labels: Vec<Vec<String>>) -> Result<Grid, GridError> {
        if labels.len() != self.cols() {
            return Err(GridError::LabelCount {
                axis: Axis::Col,
                got: labels.len(),
                count: self.cols(),
            });
        }
        self.col_labels = labels;
        Ok(self)
    }

    /// Number of rows (storeys).
    pub fn rows(&self) -> usize {
        self.row_heights.len()
    }

    /// Number of columns (bays).
    pub fn cols(&self) -> usize {
        self.col_widths.len()
    }

    /// Row heights in metres, row 1 (ground) first.
    pub(crate) fn row_heights(&self) -> &[f64] {
        &self.row_heights
    }

    /// Column widths in metres, column 1 (left) first.
    #[cfg(test)]
    pub(crate) fn col_widths(&self) -> &[f64] {
        &self.col_widths
    }

    /// The labels of each row, row 1 first.
    #[cfg(test)]
    pub(crate) fn row_labels(&self) -> &[Vec<String>] {
        &self.row_labels
    }

    /// The labels of each column, column 1 first.
    #[cfg(test)]
    pub(crate) fn col_labels(&self) -> &[Vec<String>] {
        &self.col_labels
    }

    /// Wall width (sum of the column widths).
    pub fn width(&self) -> f64 {
        self.col_widths.iter().sum()
    }

    /// Wall height (sum of the row heights).
    pub fn height(&self) -> f64 {
        self.row_heights.iter().sum()
    }

    fn count(&self, axis: Axis) -> usize {
        match axis {
            Axis::Row => self.rows(),
            Axis::Col => self.cols(),
        }
    }

    fn labels(&self, axis: Axis) -> &[Vec<String>] {
        match axis {
            Axis::Row => &self.row_labels,
            Axis::Col => &self.col_labels,
        }
    }

    /// An empty selection over this grid.
    pub fn none(&self) -> CellSet {
        CellSet {
            rows: self.rows(),
            cols: self.cols(),
            bits: vec![0; (self.rows() * self.cols()).div_ceil(64)],
        }
    }

    /// Every cell (`cell()` / `[type == "cell"]`).
    pub fn all(&self) -> CellSet {
        let mut s = self.none();
        for r in 1..=self.rows() {
            for c in 1..=self.cols() {
                let i = (r - 1) * s.cols + (c - 1);
                s.bits[i / 64] |= 1 << (i % 64);
            }
        }
        s
    }

    /// The cells whose index on `axis` is in `keep` (a predicate on the 1-based index).
    fn select_by(&self, axis: Axis, keep: impl Fn(usize) -> bool) -> CellSet {
        let mut s = self.none();
        for r in 1..=self.rows() {
            for c in 1..=self.cols() {
                let i = match axis {
                    Axis::Row => r,
                    Axis::Col => c,
                };
                if keep(i) {
                    let k = (r - 1) * s.cols + (c - 1);
                    s.bits[k / 64] |= 1 << (k % 64);
                }
            }
        }
        s
    }

    /// `[rowIdx op v]` / `[colIdx op v]`: `v` must be a valid index (1-based or negative from the
    /// end, resolved first) for every operator, so `rowIdx > 7` on a 4-row grid is an error, not
    /// an empty selection.
    pub(crate) fn select_cmp(
        &self,
        axis: Axis,
        op: CmpOp,
        value: i64,
    ) -> Result<CellSet, GridError> {
        let v = resolve_index(axis, value, self.count(axis))?;
        Ok(self.select_by(axis, |i| op.holds(i, v)))
    }

    /// `[rowIdx in (...)]` / `[colIdx in (...)]` with single indices and inclusive ranges.
    pub(crate) fn select_in(&self, axis: Axis, items: &[IndexItem]) -> Result<CellSet, GridError> {
        let keep = resolve_items(axis, items, self.count(axis))?;
        Ok(self.select_by(axis, |i| keep.binary_search(&i).is_ok()))
    }

    /// `[rowLabel == "x"]` (the row carries `x`) or `[rowLabel != "x"]` (it does not); the
    /// ordering operators are an error.
    pub(crate) fn select_label(
        &self,
        axis: Axis,
        op: CmpOp,
        label: &str,
    ) -> Result<CellSet, GridError> {
        let want = match op {
            CmpOp::Eq => true,
            CmpOp::Ne => false,
            _ => return Err(GridError::LabelOrdering),
        };
        let labels = self.labels(axis);
        Ok(self.select_by(axis, |i| labels[i - 1].iter().any(|l| l == label) == want))
    }

    /// `[rowLabel in ("a", "b")]`: the row carries any of the labels.
    pub(crate) fn select_label_in(&self, axis: Axis, labels: &[&str]) -> CellSet {
        let have = self.labels(axis);
        self.select_by(axis, |i| {
            have[i - 1].iter().any(|l| labels.contains(&l.as_str()))
        })
    }

    /// The Cartesian product of row and column index lists (1-based, negative from the end), as
    /// the seed's `selectCells` does.
    #[cfg(test)]
    pub(crate) fn product(
        &self,
        rows: &[IndexItem],
        cols: &[IndexItem],
    ) -> Result<CellSet, GridError> {
        self.select_in(Axis::Row, rows)?
            .intersect(&self.select_in(Axis::Col, cols)?)
    }

    fn check_cell(&self, row: usize, col: usize) -> Result<(), GridError> {
        if row >= 1 && row <= self.rows() && col >= 1 && col <= self.cols() {
            Ok(())
        } else {
            Err(GridError::CellOutOfRange {
                row,
                col,
                rows: self.rows(),
                cols: self.cols(),
            })
        }
    }

    /// Cell (row, col)'s rectangle on the wall: row 1 has y = 0, column 1 has x = 0.
    pub(crate) fn cell_rect(&self, row: usize, col: usize) -> Result<Rect, GridError> {
        self.group_rect(CellRect {
            row_from: row,
            row_to: row,
            col_from: col,
            col_to: col,
        })
    }

    /// A rectangle of cells' rectangle on the wall; an error if it is reversed or leaves the grid.
    pub(crate) fn group_rect(&self, cells: CellRect) -> Result<Rect, GridError> {
        self.check_cell(cells.row_from, cells.col_from)?;
        self.check_cell(cells.row_to, cells.col_to)?;
        if cells.row_from > cells.row_to {
            return Err(GridError::ReversedRange {
                axis: Axis::Row,
                from: cells.row_from as i64,
                to: cells.row_to as i64,
                from_resolved: cells.row_from,
                to_resolved: cells.row_to,
            });
        }
        if cells.col_from > cells.col_to {
            return Err(GridError::ReversedRange {
                axis: Axis::Col,
                from: cells.col_from as i64,
                to: cells.col_to as i64,
                from_resolved: cells.col_from,
                to_resolved: cells.col_to,
            });
        }
        let rh = &self.row_heights;
        let cw = &self.col_widths;
        Ok(Rect {
            x: cw[..cells.col_from - 1].iter().sum(),
            y: rh[..cells.row_from - 1].iter().sum(),
            w: cw[cells.col_from - 1..cells.col_to].iter().sum(),
            h: rh[cells.row_from - 1..cells.row_to].iter().sum(),
        })
    }

    /// The sub-grid of a rectangle of cells, on its own wall (origin at the rectangle's
    /// bottom-left): what `addVolume` gives its bay's front. Its sizes are the parent's; its
    /// labels are the defaults of its own size (its bottom row is `gnd`, and so on).
    pub(crate) fn crop(&self, cells: CellRect) -> Result<Grid, GridError> {
        self.group_rect(cells)?;
        Ok(Grid::from_sizes(
            self.row_heights[cells.row_from - 1..cells.row_to].to_vec(),
            self.col_widths[cells.col_from - 1..cells.col_to].to_vec(),
        ))
    }

    /// Groups a selection of this grid into elements (see [`Grouping`]), bottom row first, then
    /// left to right; an error if the selection is over a grid of another size.
    pub fn group(&self, set: &CellSet, grouping: Grouping) -> Result<Vec<Element>, GridError> {
        if set.rows != self.rows() || set.cols != self.cols() {
            return Err(GridError::DimsMismatch {
                a_rows: set.rows,
                a_cols: set.cols,
                b_rows: self.rows(),
                b_cols: self.cols(),
            });
        }
        let (rects, regions) = group_cells(set, grouping);
        rects
            .into_iter()
            .zip(regions)
            .map(|(cells, region)| {
                Ok(Element {
                    cells,
                    rect: self.group_rect(cells)?,
                    region,
                })
            })
            .collect()
    }
}

/// Maximal horizontal runs of each row, bottom row first: (row, col_from, col_to).
fn row_runs(set: &CellSet) -> Vec<(usize, usize, usize)> {
    let mut runs = Vec::new();
    for r in 1..=set.rows {
        let mut c = 1;
        while c <= set.cols {
            if set.contains(r, c) {
                let start = c;
                while c < set.cols && set.contains(r, c + 1) {
                    c += 1;
                }
                runs.push((r, start, c));
            }
            c += 1;
        }
    }
    runs
}

fn one(row: usize, col_from: usize, col_to: usize) -> CellRect {
    CellRect {
        row_from: row,
        row_to: row,
        col_from,
        col_to,
    }
}

/// The rectangles of a grouping, sorted bottom row first then left to right, and each one's
/// region number.
fn group_cells(set: &CellSet, grouping: Grouping) -> (Vec<CellRect>, Vec<usize>) {
    let mut rects: Vec<CellRect> = match grouping {
        Grouping::Each => set.iter().map(|(r, c)| one(r, c, c)).collect(),
        Grouping::Rows => row_runs(set)
            .into_iter()
            .map(|(r, a, b)| one(r, a, b))
            .collect(),
        Grouping::Pairs => row_runs(set)
            .into_iter()
            .flat_map(|(r, a, b)| (a..=b).step_by(2).map(move |c| one(r, c, (c + 1).min(b))))
            .collect(),
        Grouping::Cols => {
            let mut v = Vec::new();
            for c in 1..=set.cols {
                let mut r = 1;
                while r <= set.rows {
                    if set.contains(r, c) {
                        let start = r;
                        while r < set.rows && set.contains(r + 1, c) {
                            r += 1;
                        }
                        v.push(CellRect {
                            row_from: start,
                            row_to: r,
                            col_from: c,
                            col_to: c,
                        });
                    }
                    r += 1;
                }
            }
            v
        }
        Grouping::Regions => {
            // Runs from the bottom up; a run extends the open rectangle that ends on the row
            // below with exactly its columns, else starts one.
            let mut v: Vec<CellRect> = Vec::new();
            for (r, a, b) in row_runs(set) {
                match v
                    .iter_mut()
                    .find(|x| x.row_to + 1 == r && x.col_from == a && x.col_to == b)
                {
                    Some(x) => x.row_to = r,
                    None => v.push(one(r, a, b)),
                }
            }
            v
        }
    };
    rects.sort_by_key(|x| (x.row_from, x.col_from));
    let regions = if grouping == Grouping::Regions {
        component_numbers(set, &rects)
    } else {
        (0..rects.len()).collect()
    };
    (rects, regions)
}

/// The 4-connected component number of each rectangle, components numbered by their first
/// cell (bottom row first, left to right).
fn component_numbers(set: &CellSet, rects: &[CellRect]) -> Vec<usize> {
    let (rows, cols) = (set.rows, set.cols);
    let mut comp = vec![usize::MAX; rows * cols];
    let mut next = 0;
    let mut stack = Vec::new();
    for (r, c) in set.iter() {
        let i = (r - 1) * cols + (c - 1);
        if comp[i] != usize::MAX {
            continue;
        }
        comp[i] = next;
        stack.push((r, c));
        while let Some((r, c)) = stack.pop() {
            let mut visit = |rr: usize, cc: usize| {
                if set.contains(rr, cc) {
                    let j = (rr - 1) * cols + (cc - 1);
                    if comp[j] == usize::MAX {
                        comp[j] = next;
                        stack.push((rr, cc));
                    }
                }
            };
            visit(r + 1, c);
            visit(r - 1, c);
            visit(r, c + 1);
            visit(r, c - 1);
        }
        next += 1;
    }
    rects
        .iter()
        .map(|x| comp[(x.row_from - 1) * cols + (x.col_from - 1)])
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn s(x: &str) -> String {
        x.to_string()
    }

    fn cells(e: &[Element]) -> Vec<(usize, usize, usize, usize)> {
        e.iter()
            .map(|e| {
                (
                    e.cells.row_from,
                    e.cells.row_to,
                    e.cells.col_from,
                    e.cells.col_to,
                )
            })
            .collect()
    }

    #[test]
    fn row_one_is_the_ground_and_column_one_the_left() {
        let g = Grid::uniform(10.0, 9.0, 3, 5).unwrap();
        assert_eq!(
            g.cell_rect(1, 1).unwrap(),
            Rect {
                x: 0.0,
                y: 0.0,
                w: 2.0,
                h: 3.0
            }
        );
        let top_right = g.cell_rect(3, 5).unwrap();
        assert_eq!((top_right.x, top_right.y), (8.0, 6.0));
        assert_eq!(g.row_labels()[0], vec![s("gnd")]);
        assert_eq!(g.row_labels()[1], vec![s("mid")]);
        assert_eq!(g.row_labels()[2], vec![s("top")]);
        assert_eq!(g.col_labels()[0], vec![s("left")]);
        assert_eq!(g.col_labels()[4], vec![s("right")]);
        // -1 is the top row / the rightmost column.
        assert_eq!(resolve_index(Axis::Row, -1, 3), Ok(3));
        assert_eq!(resolve_index(Axis::Col, -5, 5), Ok(1));
        let set = g.select_cmp(Axis::Row, CmpOp::Eq, 1).unwrap();
        assert_eq!(set.iter().next(), Some((1, 1)));
        assert_eq!(set.len(), 5);
        assert_eq!(
            g.cell_rect(4, 1),
            Err(GridError::CellOutOfRange {
                row: 4,
                col: 1,
                rows: 3,
                cols: 5
            })
        );
        assert!(g.cell_rect(0, 1).is_err());
    }

    #[test]
    fn one_row_grid_has_both_labels() {
        let g = Grid::uniform(3.0, 3.0, 1, 1).unwrap();
        assert_eq!(g.row_labels()[0], vec![s("gnd"), s("top")]);
        assert_eq!(g.col_labels()[0], vec![s("left"), s("right")]);
        assert_eq!(
            g.select_label(Axis::Row, CmpOp::Eq, "gnd").unwrap().len(),
            1
        );
        assert_eq!(
            g.select_label(Axis::Row, CmpOp::Eq, "top").unwrap().len(),
            1
        );
        assert_eq!(
            g.select_label(Axis::Row, CmpOp::Ne, "top").unwrap().len(),
            0
        );
        assert_eq!(
            g.select_label(Axis::Row, CmpOp::Eq, "mid").unwrap().len(),
            0
        );
        assert_eq!(
            g.select_label(Axis::Row, CmpOp::Gt, "mid"),
            Err(GridError::LabelOrdering)
        );
        let g2 = Grid::uniform(3.0, 3.0, 2, 2).unwrap();
        assert_eq!(
            g2.select_label(Axis::Col, CmpOp::Eq, "mid").unwrap().len(),
            0
        );
    }

    #[test]
    fn constructors_refuse_bad_sizes() {
        assert_eq!(
            Grid::uniform(10.0, 3.0, 0, 2),
            Err(GridError::ZeroCount(Axis::Row))
        );
        assert_eq!(
            Grid::uniform(10.0, 3.0, 2, 0),
            Err(GridError::ZeroCount(Axis::Col))
        );
        assert!(matches!(
            Grid::uniform(f64::NAN, 3.0, 1, 1),
            Err(GridError::BadSize { .. })
        ));
        assert!(matches!(
            Grid::uniform(10.0, -3.0, 1, 1),
            Err(GridError::BadSize { .. })
        ));
        assert!(matches!(
            Grid::uniform(10.0, f64::INFINITY, 1, 1),
            Err(GridError::BadSize { .. })
        ));
        assert!(matches!(
            Grid::uniform(10.0, 3.0, 2000, 2000),
            Err(GridError::TooManyCells { .. })
        ));
        assert!(matches!(
            Grid::uniform(10.0, 3.0, usize::MAX, 2),
            Err(GridError::TooManyCells { .. })
        ));
        assert!(matches!(
            Grid::metric(10.0, &[3.0], 0.0),
            Err(GridError::BadSize { .. })
        ));
        assert!(matches!(
            Grid::metric(10.0, &[3.0, f64::NAN], 2.0),
            Err(GridError::BadSize { .. })
        ));
        assert_eq!(
            Grid::metric(10.0, &[], 2.0),
            Err(GridError::ZeroCount(Axis::Row))
        );
        assert!(matches!(
            Grid::metric(1e300, &[3.0], 1e-300),
            Err(GridError::TooManyCells { .. })
        ));
        assert!(CellSet::empty(0, 3).is_err());
        let e = Grid::uniform(10.0, -3.0, 1, 1).unwrap_err().to_string();
        assert_eq!(
            e,
            "wall height must be a finite positive number of metres, not -3"
        );
    }

    #[test]
    fn metric_grid_fits_the_wall() {
        // 13 m wall, 2.5 m bays -> round(5.2) = 5 bays of 2.6 m; storeys 4 + 3 + 3.
        let g = Grid::metric(13.0, &[4.0, 3.0, 3.0], 2.5).unwrap();
        assert_eq!((g.rows(), g.cols()), (3, 5));
        assert!((g.col_widths()[0] - 2.6).abs() < 1e-12);
        assert!((g.width() - 13.0).abs() < 1e-12);
        assert_eq!(g.height(), 10.0);
        let r = g.cell_rect(2, 1).unwrap();
        assert_eq!((r.y, r.h), (4.0, 3.0));
        // A wall narrower than one bay still gets one column.
        let g = Grid::metric(1.0, &[3.0], 2.5).unwrap();
        assert_eq!((g.cols(), g.col_widths()[0]), (1, 1.0));
        // updateGrid re-divides the same wall uniformly.
        let g = Grid::metric(13.0, &[4.0, 3.0, 3.0], 2.5)
            .unwrap()
            .update(5, 2)
            .unwrap();
        assert_eq!((g.rows(), g.cols()), (5, 2));
        assert_eq!(g.row_heights(), &[2.0; 5]);
        assert_eq!(g.col_widths(), &[6.5; 2]);
    }

    #[test]
    fn ranges_and_index_errors() {
        assert_eq!(
            resolve_items(Axis::Row, &[IndexItem::Range(2, -2)], 5),
            Ok(vec![2, 3, 4])
        );
        assert_eq!(
            resolve_items(Axis::Row, &[IndexItem::Range(3, 3)], 5),
            Ok(vec![3])
        );
        assert_eq!(
            resolve_items(Axis::Row, &[IndexItem::One(3), IndexItem::Range(1, 3)], 5),
            Ok(vec![1, 2, 3])
        );
        let e = resolve_items(Axis::Row, &[IndexItem::Range(2, -2)], 2).unwrap_err();
        assert!(matches!(
            e,
            GridError::ReversedRange {
                from_resolved: 2,
                to_resolved: 1,
                ..
            }
        ));
        assert_eq!(
            e.to_string(),
            "row range (2, -2) is empty: it runs from row 2 down to 1; ranges are inclusive and ascending"
        );
        assert_eq!(
            resolve_index(Axis::Col, 0, 3),
            Err(GridError::IndexZero(Axis::Col))
        );
        let e = resolve_index(Axis::Col, 4, 3).unwrap_err();
        assert_eq!(
            e.to_string(),
            "column index 4 is out of range: the grid has 3 columns (valid: 1..=3 or -3..=-1)"
        );
        assert!(resolve_index(Axis::Col, -4, 3).is_err());
        assert!(resolve_index(Axis::Col, i64::MIN, 3).is_err());
        assert!(resolve_index(Axis::Col, i64::MAX, 3).is_err());
        let g = Grid::uniform(4.0, 4.0, 4, 4).unwrap();
        assert!(g.select_cmp(Axis::Row, CmpOp::Gt, 7).is_err());
        assert_eq!(g.select_cmp(Axis::Row, CmpOp::Gt, 1).unwrap().len(), 12);
        assert_eq!(g.select_cmp(Axis::Col, CmpOp::Le, 3).unwrap().len(), 12);
        assert_eq!(g.select_cmp(Axis::Col, CmpOp::Ne, -1).unwrap().len(), 12);
        assert_eq!(g.select_cmp(Axis::Col, CmpOp::Lt, 2).unwrap().len(), 4);
        assert_eq!(g.select_cmp(Axis::Col, CmpOp::Ge, -2).unwrap().len(), 8);
    }

    /// Jiang et al. 2018, Fig. 13, on a 4-storey facade whose columns are labelled like his:
    /// two `left` bays, one `mid` bay with the door, two `right` bays.
    fn jiang() -> Grid {
        let cols = ["left", "left", "mid", "right", "right"];
        Grid::uniform(17.6, 12.8, 4, 5)
            .unwrap()
            .with_col_labels(cols.iter().map(|l| vec![s(l)]).collect())
            .unwrap()
    }

    #[test]
    fn jiang_fig13() {
        let g = jiang();
        let label = |a, l| g.select_label(a, CmpOp::Eq, l).unwrap();
        // C4: door at mid/gnd.
        let door = label(Axis::Col, "mid")
            .intersect(&label(Axis::Row, "gnd"))
            .unwrap();
        assert_eq!(
            cells(&g.group(&door, Grouping::Each).unwrap()),
            vec![(1, 1, 3, 3)]
        );
        // C5: glass above the door, grouped by columns: one element 3 cells high.
        let glass = label(Axis::Col, "mid")
            .intersect(&g.select_cmp(Axis::Row, CmpOp::Gt, 1).unwrap())
            .unwrap();
        let e = g.group(&glass, Grouping::Cols).unwrap();
        assert_eq!(cells(&e), vec![(2, 4, 3, 3)]);
        assert!((e[0].rect.y - 3.2).abs() < 1e-12 && (e[0].rect.h - 9.6).abs() < 1e-12);
        // C6: ledges on the left of the top floor, in pairs: one pair.
        let top = label(Axis::Row, "top");
        let ledges = label(Axis::Col, "left").intersect(&top).unwrap();
        assert_eq!(
            cells(&g.group(&ledges, Grouping::Pairs).unwrap()),
            vec![(4, 4, 1, 2)]
        );
        // C7: the two-cell window on the right of the top floor, grouped by rows.
        let win4 = label(Axis::Col, "right").intersect(&top).unwrap();
        assert_eq!(
            cells(&g.group(&win4, Grouping::Rows).unwrap()),
            vec![(4, 4, 4, 5)]
        );
        // C8: left and right windows on the ground floor.
        let win1 = g
            .select_label_in(Axis::Col, &["left", "right"])
            .intersect(&g.select_cmp(Axis::Row, CmpOp::Eq, 1).unwrap())
            .unwrap();
        assert_eq!(
            cells(&g.group(&win1, Grouping::Each).unwrap()),
            vec![(1, 1, 1, 1), (1, 1, 2, 2), (1, 1, 4, 4), (1, 1, 5, 5)]
        );
        // C9: rowRange(2, -2) is rows 2 and 3 of 4.
        let win2 = g
            .select_label_in(Axis::Col, &["left", "right"])
            .intersect(&g.select_in(Axis::Row, &[IndexItem::Range(2, -2)]).unwrap())
            .unwrap();
        let got: Vec<_> = win2.iter().collect();
        assert_eq!(
            got,
            vec![
                (2, 1),
                (2, 2),
                (2, 4),
                (2, 5),
                (3, 1),
                (3, 2),
                (3, 4),
                (3, 5)
            ]
        );
        // Default labels on the plain 4 × 3 grid: left / mid / right are single columns.
        let g3 = Grid::uniform(17.6, 12.8, 4, 3).unwrap();
        let glass = g3
            .select_label(Axis::Col, CmpOp::Eq, "mid")
            .unwrap()
            .intersect(&g3.select_cmp(Axis::Row, CmpOp::Gt, 1).unwrap())
            .unwrap();
        assert_eq!(
            cells(&g3.group(&glass, Grouping::Cols).unwrap()),
            vec![(2, 4, 2, 2)]
        );
        // groupPairs on the whole top row of 3: one pair and one single cell.
        let top = g3.select_label(Axis::Row, CmpOp::Eq, "top").unwrap();
        assert_eq!(
            cells(&g3.group(&top, Grouping::Pairs).unwrap()),
            vec![(4, 4, 1, 2), (4, 4, 3, 3)]
        );
    }

    #[test]
    fn brito_entrance_region() {
        let g = Grid::uniform(9.0, 5.0, 3, 7).unwrap();
        let sel = g
            .product(
                &[IndexItem::One(2), IndexItem::One(3)],
                &[IndexItem::One(3), IndexItem::One(4), IndexItem::One(5)],
            )
            .unwrap();
        assert_eq!(sel.len(), 6);
        let e = g.group(&sel, Grouping::Regions).unwrap();
        assert_eq!(cells(&e), vec![(2, 3, 3, 5)]);
        let r = e[0].rect;
        assert!((r.x - 9.0 * 2.0 / 7.0).abs() < 1e-12);
        assert!((r.y - 5.0 / 3.0).abs() < 1e-12);
        assert!((r.w - 9.0 * 3.0 / 7.0).abs() < 1e-12);
        assert!((r.h - 10.0 / 3.0).abs() < 1e-12);
        // The bay's front grid: the crop, on its own wall.
        let bay = g.crop(e[0].cells).unwrap();
        assert_eq!((bay.rows(), bay.cols()), (2, 3));
        assert_eq!(bay.cell_rect(1, 1).unwrap().x, 0.0);
        assert!((bay.width() - r.w).abs() < 1e-12);
        assert_eq!(bay.row_labels()[0], vec![s("gnd")]);
        assert!(g
            .crop(CellRect {
                row_from: 2,
                row_to: 4,
                col_from: 1,
                col_to: 1
            })
            .is_err());
    }

    #[test]
    fn groupings_on_an_irregular_selection() {
        // Row 3: . X X X .
        // Row 2: . X . X X
        // Row 1: X X . . X
        let g = Grid::uniform(5.0, 3.0, 3, 5).unwrap();
        let mut set = g.none();
        for (r, c) in [
            (1, 1),
            (1, 2),
            (1, 5),
            (2, 2),
            (2, 4),
            (2, 5),
            (3, 2),
            (3, 3),
            (3, 4),
        ] {
            set.insert(r, c).unwrap();
        }
        assert_eq!(g.group(&set, Grouping::Each).unwrap().len(), 9);
        assert_eq!(
            cells(&g.group(&set, Grouping::Rows).unwrap()),
            vec![
                (1, 1, 1, 2),
                (1, 1, 5, 5),
                (2, 2, 2, 2),
                (2, 2, 4, 5),
                (3, 3, 2, 4)
            ]
        );
        assert_eq!(
            cells(&g.group(&set, Grouping::Cols).unwrap()),
            vec![
                (1, 1, 1, 1),
                (1, 3, 2, 2),
                (1, 2, 5, 5),
                (2, 3, 4, 4),
                (3, 3, 3, 3)
            ]
        );
        assert_eq!(
            cells(&g.group(&set, Grouping::Pairs).unwrap()),
            vec![
                (1, 1, 1, 2),
                (1, 1, 5, 5),
                (2, 2, 2, 2),
                (2, 2, 4, 5),
                (3, 3, 2, 3),
                (3, 3, 4, 4)
            ]
        );
        // One 4-connected component (via (2,2)-(3,2)-(3,4)-(2,4)-(2,5)-(1,5)), cut into
        // rectangles by runs merged upwards over identical columns.
        let e = g.group(&set, Grouping::Regions).unwrap();
        assert_eq!(
            cells(&e),
            vec![
                (1, 1, 1, 2),
                (1, 1, 5, 5),
                (2, 2, 2, 2),
                (2, 2, 4, 5),
                (3, 3, 2, 4)
            ]
        );
        assert!(e.iter().all(|e| e.region == 0));
        // Two separate columns of the same height: two regions, each merged into one rectangle.
        let sel = g
            .product(
                &[IndexItem::Range(1, 3)],
                &[IndexItem::One(1), IndexItem::One(3)],
            )
            .unwrap();
        let e = g.group(&sel, Grouping::Regions).unwrap();
        assert_eq!(cells(&e), vec![(1, 3, 1, 1), (1, 3, 3, 3)]);
        assert_eq!(e.iter().map(|e| e.region).collect::<Vec<_>>(), vec![0, 1]);
        // An empty selection gives no element; a set of another size is an error.
        assert!(g.group(&g.none(), Grouping::Regions).unwrap().is_empty());
        let other = CellSet::full(2, 2).unwrap();
        assert!(matches!(
            g.group(&other, Grouping::Each),
            Err(GridError::DimsMismatch { .. })
        ));
        assert!(g.all().intersect(&other).is_err());
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(200))]

        /// Every grouping covers the selection exactly once, with rectangles in the documented
        /// order, and regions never join cells of different components.
        #[test]
        fn groupings_partition_the_selection(
            rows in 1usize..=12,
            cols in 1usize..=12,
            bits in proptest::collection::vec(proptest::prelude::any::<bool>(), 144),
        ) {
            let g = Grid::uniform(cols as f64, rows as f64 * 3.0, rows, cols).unwrap();
            let mut set = g.none();
            for r in 1..=rows {
                for c in 1..=cols {
                    if bits[(r - 1) * 12 + (c - 1)] {
                        set.insert(r, c).unwrap();
                    }
                }
            }
            for grouping in [Grouping::Each, Grouping::Rows, Grouping::Cols, Grouping::Pairs, Grouping::Regions] {
                let elements = g.group(&set, grouping).unwrap();
                let mut seen = g.none();
                let mut total = 0;
                for e in &elements {
                    for r in e.cells.row_from..=e.cells.row_to {
                        for c in e.cells.col_from..=e.cells.col_to {
                            proptest::prop_assert!(set.contains(r, c));
                            proptest::prop_assert!(!seen.contains(r, c));
                            seen.insert(r, c).unwrap();
                        }
                    }
                    total += e.cells.cells();
                    let rect = g.group_rect(e.cells).unwrap();
                    proptest::prop_assert!((rect.w - e.cells.width() as f64).abs() < 1e-9);
                    proptest::prop_assert!((rect.h - 3.0 * e.cells.height() as f64).abs() < 1e-9);
                }
                proptest::prop_assert_eq!(total, set.len());
                proptest::prop_assert_eq!(&seen, &set);
                let keys: Vec<_> = elements.iter().map(|e| (e.cells.row_from, e.cells.col_from)).collect();
                let mut sorted = keys.clone();
                sorted.sort();
                proptest::prop_assert_eq!(keys, sorted);
                if grouping == Grouping::Regions {
                    // Rectangles of different regions never touch edge to edge.
                    for a in &elements {
                        for b in &elements {
                            if a.region == b.region {
                                continue;
                            }
                            let (x, y) = (a.cells, b.cells);
                            let rows_overlap = x.row_from <= y.row_to && y.row_from <= x.row_to;
                            let cols_overlap = x.col_from <= y.col_to && y.col_from <= x.col_to;
                            let side = rows_overlap && (x.col_to + 1 == y.col_from || y.col_to + 1 == x.col_from);
                            let above = cols_overlap && (x.row_to + 1 == y.row_from || y.row_to + 1 == x.row_from);
                            proptest::prop_assert!(!side && !above);
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn cell_set_basics() {
        let mut s = CellSet::empty(3, 50).unwrap();
        assert!(s.is_empty());
        s.insert(3, 50).unwrap();
        s.insert(1, 1).unwrap();
        assert!(s.insert(4, 1).is_err());
        assert!(s.insert(1, 0).is_err());
        assert_eq!(s.iter().collect::<Vec<_>>(), vec![(1, 1), (3, 50)]);
        assert!(s.contains(3, 50) && !s.contains(2, 50) && !s.contains(9, 9));
        let full = CellSet::full(3, 50).unwrap();
        assert_eq!(full.len(), 150);
        assert_eq!(full.difference(&s).unwrap().len(), 148);
        assert_eq!(full.intersect(&s).unwrap(), s);
        s.remove(1, 1).unwrap();
        assert_eq!(s.len(), 1);
        assert_eq!(s.union(&full).unwrap(), full);
        let g = Grid::uniform(5.0, 3.0, 3, 50).unwrap();
        assert_eq!(g.all(), full);
    }
}
