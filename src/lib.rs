//! citygen: GIS footprints to BIM (IFC, CityGML 2.0, glTF).
//!
//! The pipeline runs one way: read footprints -> project to the local frame -> match the
//! knowledge-base zone -> pick an appearance -> grammar rules -> derive the shape tree ->
//! semantic building model cut at the LOD -> writers. See ARCHITECTURE.md.
//!
//! # The front door
//!
//! A run as the command line does it: fill [`Options`] and call [`run`], which returns a
//! [`Summary`] or a [`RunError`] (bad input, exit 1; an output that could not be written,
//! exit 3). The semantic model every writer consumes is [`model`] ([`model::Building`]); a
//! writer of one more format implements [`BuildingWriter`].
//!
//! The stages are public modules for the tests, the examples and the tools (`kb explain`,
//! `rules derive`), in the order data flows: [`input`] → [`prepare`] → [`mod@derive`] →
//! [`export`], run by [`pipeline`]; the two languages [`kb`] and [`grammar`]; the ground floor
//! [`model`], [`geometry`], [`crs`], [`color`], [`rng`], [`report`], [`fsio`] (files written
//! atomically). Their layering (what may import what) is in ARCHITECTURE.md and is enforced by
//! `tests/it/architecture.rs`.

#![forbid(unsafe_code)]

pub use export::BuildingWriter;
pub use pipeline::{run, Options, RunError, Summary};

pub mod app;
pub mod color;
pub mod crs;
pub mod derive;
pub mod editor;
pub mod evolve;
pub mod export;
pub mod fsio;
pub mod geometry;
pub mod grammar;
pub(crate) mod guard;
pub mod input;
pub mod kb;
pub mod model;
pub mod pipeline;
pub mod prepare;
pub mod report;
pub mod rng;
pub mod selex;
#[doc(hidden)]
pub mod testkit;
