//! The GLB container of a content: the binary buffer built view by view, and the framing
//! (header, JSON chunk, BIN chunk).

use std::io::Write;

use serde_json::{json, Value};

use crate::export::glb::{CHUNK_BIN, CHUNK_JSON, GLB_MAGIC, GLB_VERSION};
use crate::export::ExportError;

/// Every buffer view starts at a multiple of this: 4 as glTF asks of vertex data, 8 as
/// `EXT_structural_metadata` asks of property columns (FLOAT64).
const ALIGN: usize = 8;

/// The binary chunk and its buffer views.
#[derive(Default)]
pub(crate) struct Bin {
    pub(crate) bytes: Vec<u8>,
    pub(crate) views: Vec<Value>,
}

impl Bin {
    /// Appends `data` as a new buffer view (with `target`, an `ARRAY_BUFFER` or
    /// `ELEMENT_ARRAY_BUFFER`, for vertex and index data); returns its index.
    pub(crate) fn view(&mut self, data: &[u8], target: Option<u32>) -> usize {
        self.view_with(target, |out| out.extend_from_slice(data))
    }

    /// Appends what `fill` appends to the buffer as a new buffer view (see [`Bin::view`]);
    /// returns its index.
    pub(crate) fn view_with(
        &mut self,
        target: Option<u32>,
        fill: impl FnOnce(&mut Vec<u8>),
    ) -> usize {
        while self.bytes.len() % ALIGN != 0 {
            self.bytes.push(0);
        }
        let start = self.bytes.len();
        fill(&mut self.bytes);
        let mut v = json!({
            "buffer": 0,
            "byteOffset": start,
            "byteLength": self.bytes.len() - start,
        });
        if let Some(t) = target {
            v["target"] = json!(t);
        }
        self.views.push(v);
        self.views.len() - 1
    }
}

/// Writes the GLB of `doc` and `bin` to `out`; returns its length. Refuses a GLB over the
/// format's 4 GiB (its length field is a u32).
pub(crate) fn write_glb(out: &mut impl Write, doc: &Value, bin: &[u8]) -> Result<u64, ExportError> {
    let mut json = serde_json::to_vec(doc).map_err(|e| ExportError::Invalid(e.to_string()))?;
    while json.len() % 4 != 0 {
        json.push(b' ');
    }
    let bin_padded = bin.len().next_multiple_of(4);
    let bin_chunk = if bin.is_empty() { 0 } else { 8 + bin_padded };
    let total = 12 + 8 + json.len() as u64 + bin_chunk as u64;
    let too_big = || {
        ExportError::Invalid(format!(
            "3D Tiles writer: the tile's GLB would be {total} bytes, over glTF's 4 GiB: use smaller tiles (--tile)"
        ))
    };
    let total32 = u32::try_from(total).map_err(|_| too_big())?;
    let json_len = u32::try_from(json.len()).map_err(|_| too_big())?;
    let mut head = Vec::with_capacity(20);
    for v in [GLB_MAGIC, GLB_VERSION, total32, json_len, CHUNK_JSON] {
        head.extend_from_slice(&v.to_le_bytes());
    }
    out.write_all(&head)?;
    out.write_all(&json)?;
    if !bin.is_empty() {
        let len = u32::try_from(bin_padded).map_err(|_| too_big())?;
        out.write_all(&len.to_le_bytes())?;
        out.write_all(&CHUNK_BIN.to_le_bytes())?;
        out.write_all(bin)?;
        out.write_all(&[0u8; 3][..bin_padded - bin.len()])?;
    }
    out.flush()?;
    Ok(total)
}
