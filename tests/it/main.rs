//! The integration tests, in one binary (one link of the library instead of one per file): a
//! module per area, its tests named `module::test` (`cargo test --test it -- e2e::`). The
//! `#[ignore]`d whole-sample tests run in release by name: `cargo test --release --test it --
//! --ignored iso19107::` (and `facades::`), as .ci/run does.

mod common;

mod architecture;
mod atomic;
mod bad_inputs;
mod budgets;
mod clear_errors;
mod crs;
mod day2;
mod dem;
mod deploy;
mod e2e;
mod evolve;
mod facades;
mod fronts;
mod geojson;
mod gis_attributes;
mod ifc_schemas;
mod ifc_split;
mod incremental;
mod infer;
mod iso19107;
mod kb_edit;
mod learn;
mod lod4;
mod lod4_export;
mod materials;
mod merge_guard;
mod osm_xml;
mod preview;
mod provenance;
mod roofs;
mod rule_bombs;
mod s3db;
mod selex;
mod shards;
mod slope;
mod split;
mod terrain;
mod world_kb;
mod zones;
