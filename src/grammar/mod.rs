//! The stochastic, attributed shape grammar of seed 003 §3.3: parser, interpreter, shape tree.
//!
//! ```text
//! lot -> extrude(20){building:roof=hip,roofcolor=sandybrown}
//! building -> split(Y,sy/2,sy/2){b1|b2:color=grey}
//! floor -> comp(){side:face}
//! gback -> wall
//! ```
//!
//! [`parse`] turns a rule file into a [`RuleSet`] (errors point at `file:line:col`); [`derive()`]
//! applies it to one footprint and returns the [`ShapeTree`] the exporters consume. The
//! semantic decisions (remainders, truncation, repeat fitting, comp selectors, labels) are
//! documented on the [`interp`] module; the language reference is docs/grammar.md, whose
//! examples are tests (`doc_tests.rs`).

pub(crate) mod ast;
pub(crate) mod expr;
pub mod interp;
pub mod lint;
pub(crate) mod parser;
pub(crate) mod shape;

#[cfg(test)]
mod doc_tests;
#[cfg(test)]
mod tests;

pub use ast::{
    AttrValue, Attrs, Axis, Op, Rule, RuleSet, Selector, SplitKind, Successor, SymbolId,
};
pub use interp::{derive, derive_facing, recycle, Caps, DeriveError};
pub(crate) use parser::read_capped;
pub use parser::{
    parse, read_source, GrammarError, ParseErrorKind, MAX_EXPR_DEPTH, MAX_SOURCE_BYTES,
};
pub use shape::{FaceKind, Geometry, Label, Scope, ShapeNode, ShapeTree, Terminal};
