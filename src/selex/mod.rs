//! SELEX (seed 000: Jiang et al. 2018, Brito et al. 2021, Anchiêta 2023): selection expressions
//! over the shape tree, and virtual facade grids whose cells are selected, grouped and filled with
//! elements, never split. The language reference is docs/selex.md.
//!
//! A program is a sequence of assignments (`width = 9;`) and rules
//! (`{< selection path > -> action; action}`), executed one at a time in file order: a rule's
//! selection path picks a list of shapes, and its actions run on each of them.
//!
//! # Conventions (fixed here, stated in docs/selex.md, enforced by tests)
//!
//! - **Rows** of a virtual grid are storeys: **row 1 is the ground floor**, counted upwards
//!   (Jiang's convention; the thesis's Blender code counts from the top, which citygen does not
//!   follow). **Columns** are bays, **column 1 is the leftmost seen from outside**, facing the
//!   facade. Indices are 1-based; a negative index counts from the end (-1 is the top row or the
//!   rightmost column).
//! - A `pattern` string is read **as the facade is seen**: its first character is the top row's
//!   leftmost cell, then left to right, then the rows below, the ground floor last (the picture
//!   the seed's appendix patterns draw).
//!
//! # Modules
//!
//! - [`ast`] — programs, rules, selection paths, selectors, actions, values, spans.
//! - [`parser`] — the lexer and parser: file:line:col errors with a caret and did-you-mean.
//! - [`pattern`] — the `pattern(regex, pat)` language: parsed, expanded to exactly rows × cols
//!   cells, or an error naming where it stops tiling.
//! - [`grid`] — virtual grids (uniform or metric), cell selection by index, label and pattern,
//!   and the grouping functions.
//! - [`eval`] — the interpreter: the shape tree, selection, actions and constraints, on box lots
//!   ([`eval::run`]) and on a real building's facades ([`eval::run_on_facades`]).

pub mod ast;
pub mod eval;
pub mod grid;
pub mod parser;
pub mod pattern;

#[cfg(test)]
mod doc_tests;
#[cfg(test)]
mod eval_tests;
#[cfg(test)]
mod tests;
