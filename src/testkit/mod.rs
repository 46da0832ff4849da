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

/// Runs what a run infers from the neighbours (colours, then the height and roof estimator)
/// over `lots`, every inference on, as a run does between `fronts` and `select`: for
/// `tests/memory_estimate.rs`, which measures its working set. Returns how many lots have
/// storeys after it (tagged or estimated).
pub fn infer_all(kb: &crate::kb::KnowledgeBase, lots: &mut [crate::prepare::Lot]) -> usize {
    let all = crate::model::Inference {
        levels: true,
        roof: true,
        colour: true,
    };
    let boundaries = crate::kb::BoundaryZones::default();
    let inferred = crate::pipeline::infer_from_neighbours(kb, &boundaries, lots, Some(all));
    drop(inferred);
    lots.iter().filter(|l| l.tags.levels.is_some()).count()
}
