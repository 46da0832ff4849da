//! The knowledge base of regional appearance (seed 003 §3.4): a zone tree
//! earth > country > region > town > district, each zone with `<info>` defaults and a circle,
//! and `<appearance>` alternatives chosen by `proba`.

pub mod compile;
pub mod xml;
