//! The GLB container (glTF 2.0 binary): a 12-byte header (magic, version, total length) and
//! chunks of length, type and data, all little-endian. One set of constants for the glTF and
//! 3D Tiles writers and the preview's reader.

/// GLB magic `glTF`, little-endian.
pub(crate) const GLB_MAGIC: u32 = 0x4654_6C67;

/// The GLB container's version (glTF 2.0).
pub(crate) const GLB_VERSION: u32 = 2;

/// Chunk type `JSON`.
pub(crate) const CHUNK_JSON: u32 = 0x4E4F_534A;

/// Chunk type `BIN\0`.
pub(crate) const CHUNK_BIN: u32 = 0x004E_4942;
