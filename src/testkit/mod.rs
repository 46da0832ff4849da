//! Helpers for tests and benchmarks, not part of citygen's API: compiled only for the crate's
//! own tests and with the `testkit` feature (which the integration tests and examples turn on
//! through the self dev-dependency in Cargo.toml). Synthetic, corrupt and tiled inputs are
//! built in code with them instead of being committed as fixtures.

pub mod day2;
pub mod geotiff;
pub mod osm_xml;
/// The OSM PBF writer (in the library since `citygen split` writes PBF parts).
pub use crate::input::osm::pbf_write;
pub mod tiled;
pub mod validators;
