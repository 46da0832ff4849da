//! GLB assembly and spooling of the glTF writer: the binary data and the growing JSON arrays
//! spooled as buildings arrive, and the final GLB (header, JSON chunk, BIN chunk).

use std::fs::File;
use std::io::{self, BufWriter, Read, Seek, SeekFrom, Write};

use serde::Serialize;

use crate::export::glb::{CHUNK_BIN, CHUNK_JSON, GLB_MAGIC, GLB_VERSION};
use crate::export::ExportError;
use crate::model::Building;

use super::json::{
    AccessorRec, Attributes, BuildingExtras, ImageRec, MeshRec, NodeRec, PartExtras, Piece,
    PrimitiveRec, TextureRec, ViewRec,
};
use super::json::{ACCESSORS, MESHES, NODES, VIEWS};
use super::mesh::{Encoded, PrimLayout};
use super::{GltfWriter, State, ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER, FLOAT, VEC3_STRIDE};

/// Byte stride of the texture coordinates' view: f32 VEC2.
const VEC2_STRIDE: u32 = 8;

/// The serialised records of one JSON array, comma-separated, without the brackets.
pub(super) enum Spool {
    Mem {
        buf: Vec<u8>,
        count: u32,
    },
    File {
        w: BufWriter<File>,
        len: u64,
        count: u32,
    },
    /// A dry run's: the records are serialised and counted, not kept.
    Count {
        len: u64,
        count: u32,
    },
}

impl Default for Spool {
    fn default() -> Spool {
        Spool::Mem {
            buf: Vec::new(),
            count: 0,
        }
    }
}

impl Spool {
    /// Records so far (the index the next one gets).
    pub(super) fn count(&self) -> u32 {
        match self {
            Spool::Mem { count, .. } | Spool::File { count, .. } | Spool::Count { count, .. } => {
                *count
            }
        }
    }

    /// Bytes so far.
    pub(super) fn len(&self) -> u64 {
        match self {
            Spool::Mem { buf, .. } => buf.len() as u64,
            Spool::File { len, .. } | Spool::Count { len, .. } => *len,
        }
    }

    /// Appends one record; returns its index.
    pub(super) fn push(&mut self, rec: &impl Serialize, scratch: &mut Vec<u8>) -> io::Result<u32> {
        scratch.clear();
        if self.count() > 0 {
            scratch.push(b',');
        }
        serde_json::to_writer(&mut *scratch, rec).map_err(io::Error::from)?;
        match self {
            Spool::Mem { buf, count } => {
                buf.extend_from_slice(scratch);
                *count += 1;
                Ok(*count - 1)
            }
            Spool::File { w, len, count } => {
                w.write_all(scratch)?;
                *len += scratch.len() as u64;
                *count += 1;
                Ok(*count - 1)
            }
            Spool::Count { len, count } => {
                *len += scratch.len() as u64;
                *count += 1;
                Ok(*count - 1)
            }
        }
    }

    /// Copies the records to `out`.
    fn copy_to(&mut self, out: &mut impl Write) -> io::Result<()> {
        match self {
            Spool::Mem { buf, .. } => out.write_all(buf),
            Spool::File { w, len, .. } => {
                w.flush()?;
                let f = w.get_mut();
                f.seek(SeekFrom::Start(0))?;
                let copied = io::copy(&mut (&mut *f).take(*len), out)?;
                if copied != *len {
                    return Err(io::Error::other(format!(
                        "glTF JSON scratch file is {copied} bytes, expected {len}: was it modified?"
                    )));
                }
                Ok(())
            }
            Spool::Count { len, .. } => write_blank(out, *len, b' '),
        }
    }
}

/// Writes `len` copies of `byte` (a dry run's stand-in for data it did not keep), in pieces
/// large enough to pass through buffered writers without a copy.
fn write_blank(out: &mut impl Write, len: u64, byte: u8) -> io::Result<()> {
    let block = vec![byte; len.min(1 << 20) as usize];
    let mut left = len;
    while left > 0 {
        let n = left.min(block.len() as u64) as usize;
        out.write_all(&block[..n])?;
        left -= n as u64;
    }
    Ok(())
}

impl<W: Write + Send> GltfWriter<W> {
    /// Spools an encoded building's bytes and serialises its records.
    pub(super) fn add_encoded(&mut self, b: &Building, e: &Encoded) -> Result<(), ExportError> {
        let Encoded {
            layouts,
            vertex_bytes,
            index_bytes,
            uv_bytes,
        } = e;
        // Spool the bytes first: records are added only once their data is in the scratch file.
        let vertex_view_offset = self.bin_len;
        let index_view_offset = self.bin_len + vertex_bytes.len() as u64;
        if !layouts.is_empty() {
            if !self.discard {
                let scratch = self.scratch.as_mut().ok_or_else(|| {
                    ExportError::Invalid("glTF writer: scratch file missing".into())
                })?;
                let written = scratch
                    .write_all(vertex_bytes)
                    .and_then(|()| scratch.write_all(index_bytes))
                    .and_then(|()| scratch.write_all(uv_bytes));
                if let Err(e) = written {
                    self.state = State::Failed;
                    return Err(e.into());
                }
            }
            self.bin_len = index_view_offset + (index_bytes.len() + uv_bytes.len()) as u64;
            // Fail as soon as the file cannot be a GLB any more, not hours later at the end.
            if self.bin_len > self.max_bin {
                self.state = State::Failed;
                return Err(ExportError::Invalid(format!(
                    "the glTF binary is over the GLB limit of 4 GiB ({} bytes of vertex data at \
                     building {}); write fewer buildings per file (--tile METRES or --bbox)",
                    self.bin_len, b.id
                )));
            }
        }

        let written = self.records(
            b,
            layouts,
            vertex_view_offset,
            vertex_bytes.len() as u64,
            index_bytes.len() as u64,
            uv_bytes.len() as u64,
        );
        written.map_err(|e| {
            self.state = State::Failed;
            e.into()
        })
    }

    /// Serialises the JSON records of one building (its data already spooled at
    /// `vertex_view_offset`..): the building node, then per class its accessors, mesh and child
    /// node; the building's children are the nodes that follow it.
    fn records(
        &mut self,
        b: &Building,
        layouts: &[Vec<PrimLayout>],
        vertex_view_offset: u64,
        vertex_len: u64,
        index_len: u64,
        uv_len: u64,
    ) -> io::Result<()> {
        let mut tmp = std::mem::take(&mut self.json_scratch);
        let index_view_offset = vertex_view_offset + vertex_len;
        let key = b.key();
        let classes = layouts.iter().filter(|p| !p.is_empty()).count() as u32;
        let building_node = self.spools[NODES].count();
        self.doc.roots.push(building_node);
        self.spools[NODES].push(
            &NodeRec {
                name: &key,
                children: (building_node + 1..=building_node + classes).collect(),
                mesh: None,
                extras: Some(BuildingExtras {
                    id: b.id.to_string(),
                    name: b.name.as_deref(),
                    zone: &b.zone,
                    appearance: &b.appearance,
                    height: b.measured_height,
                    base: b.base_z,
                    storeys: b.storeys_above_ground,
                    roof_shape: b.roof_shape.osm_name(),
                    lod: b.lod.number(),
                    attributes: b.attributes.as_ref().map(super::json::AttrsExtras),
                    provenance: (&b.provenance).into(),
                    parts: if b
                        .parts
                        .iter()
                        .any(|p| p.traced_source(b.id).is_some() || p.structure.is_some())
                    {
                        b.parts
                            .iter()
                            .map(|p| PartExtras {
                                key: &p.key,
                                id: p.source.map(|s| s.to_string()),
                                base: p.base_z,
                                top: p.top_z,
                                roof_shape: p.roof_shape.osm_name(),
                                role: p.role.name(),
                                structure: p.structure.map(|s| s.name()),
                            })
                            .collect()
                    } else {
                        Vec::new()
                    },
                }),
            },
            &mut tmp,
        )?;
        if classes == 0 {
            self.json_scratch = tmp;
            return Ok(());
        }
        let vertex_view = self.spools[VIEWS].push(
            &ViewRec {
                buffer: 0,
                byte_offset: vertex_view_offset,
                byte_length: vertex_len,
                byte_stride: Some(VEC3_STRIDE),
                target: Some(ARRAY_BUFFER),
            },
            &mut tmp,
        )?;
        let index_view = self.spools[VIEWS].push(
            &ViewRec {
                buffer: 0,
                byte_offset: index_view_offset,
                byte_length: index_len,
                byte_stride: None,
                target: Some(ELEMENT_ARRAY_BUFFER),
            },
            &mut tmp,
        )?;
        // The texture coordinates' view, after the indices (`--textures`).
        let uv_view = if uv_len > 0 {
            Some(self.spools[VIEWS].push(
                &ViewRec {
                    buffer: 0,
                    byte_offset: index_view_offset + index_len,
                    byte_length: uv_len,
                    byte_stride: Some(VEC2_STRIDE),
                    target: Some(ARRAY_BUFFER),
                },
                &mut tmp,
            )?)
        } else {
            None
        };

        for prims in layouts {
            let Some(class) = prims.first().map(|p| p.class) else {
                continue;
            };
            let mut primitives = Vec::with_capacity(prims.len());
            for p in prims {
                let texture = p.uv_offset.and(p.texture);
                let material = self.material_for(p.class, p.color, p.material, texture);
                let acc = &mut self.spools[ACCESSORS];
                let position = acc.push(
                    &AccessorRec {
                        buffer_view: vertex_view,
                        byte_offset: p.pos_offset,
                        component_type: FLOAT,
                        count: p.count,
                        kind: "VEC3",
                        min: Some(p.min),
                        max: Some(p.max),
                    },
                    &mut tmp,
                )?;
                let normal = acc.push(
                    &AccessorRec {
                        buffer_view: vertex_view,
                        byte_offset: p.nrm_offset,
                        component_type: FLOAT,
                        count: p.count,
                        kind: "VEC3",
                        min: None,
                        max: None,
                    },
                    &mut tmp,
                )?;
                let indices = acc.push(
                    &AccessorRec {
                        buffer_view: index_view,
                        byte_offset: p.idx_offset,
                        component_type: p.idx_type,
                        count: p.idx_count,
                        kind: "SCALAR",
                        min: None,
                        max: None,
                    },
                    &mut tmp,
                )?;
                let texcoord = match (uv_view, p.uv_offset) {
                    (Some(view), Some(at)) => Some(self.spools[ACCESSORS].push(
                        &AccessorRec {
                            buffer_view: view,
                            byte_offset: at,
                            component_type: FLOAT,
                            count: p.count,
                            kind: "VEC2",
                            min: None,
                            max: None,
                        },
                        &mut tmp,
                    )?),
                    _ => None,
                };
                primitives.push(PrimitiveRec {
                    attributes: Attributes {
                        position,
                        normal,
                        texcoord,
                    },
                    indices,
                    material,
                });
            }
            let mesh = self.spools[MESHES].push(
                &MeshRec {
                    name: format!("{key} {}", class.name()),
                    primitives,
                },
                &mut tmp,
            )?;
            self.spools[NODES].push(
                &NodeRec {
                    name: class.name(),
                    children: Vec::new(),
                    mesh: Some(mesh),
                    extras: None,
                },
                &mut tmp,
            )?;
        }
        self.json_scratch = tmp;
        Ok(())
    }

    /// Appends the pictures the materials use (`--textures`), in first-use order, to the
    /// binary data as PNG images, each in its own buffer view, with a texture each.
    pub(super) fn add_pictures(&mut self) -> Result<(), ExportError> {
        let mut tmp = std::mem::take(&mut self.json_scratch);
        for (i, t) in self.pictures.clone().into_iter().enumerate() {
            let png = t.png();
            let offset = self.bin_len;
            let padded = pad4(png.len() as u64);
            if !self.discard {
                let scratch = self.scratch.as_mut().ok_or_else(|| {
                    ExportError::Invalid("glTF writer: scratch file missing".into())
                })?;
                scratch.write_all(&png)?;
                scratch.write_all(&[0; 3][..(padded - png.len() as u64) as usize])?;
            }
            self.bin_len += padded;
            let view = self.spools[VIEWS].push(
                &ViewRec {
                    buffer: 0,
                    byte_offset: offset,
                    byte_length: png.len() as u64,
                    byte_stride: None,
                    target: None,
                },
                &mut tmp,
            )?;
            self.doc.images.push(ImageRec {
                buffer_view: view,
                mime_type: "image/png",
                name: t.name(),
            });
            self.doc.textures.push(TextureRec {
                sampler: 0,
                source: i as u32,
                name: t.name(),
            });
        }
        self.json_scratch = tmp;
        if self.bin_len > self.max_bin {
            return Err(ExportError::Invalid(
                "the glTF binary is over the GLB limit of 4 GiB with its textures".into(),
            ));
        }
        Ok(())
    }

    /// Writes the GLB: header, JSON chunk, BIN chunk copied from the scratch file.
    pub(super) fn write_glb(&mut self) -> Result<(), ExportError> {
        let mut scratch = match self.scratch.take() {
            Some(s) => Some(s.into_inner().map_err(|e| e.into_error())?),
            None if self.discard => None,
            None => {
                return Err(ExportError::Invalid(
                    "glTF writer: scratch file missing".into(),
                ))
            }
        };
        let bin_len = self.bin_len;
        self.doc.buffer_length = bin_len;

        let pieces = self.doc.pieces(self.spools.each_ref().map(Spool::count))?;
        let json_len: u64 = pieces
            .iter()
            .map(|p| match p {
                Piece::Text(t) => t.len() as u64,
                Piece::Spool(i) => self.spools[*i].len(),
            })
            .sum();
        let json_padded = pad4(json_len);
        let bin_padded = pad4(bin_len);
        let total = 12 + 8 + json_padded + if bin_len > 0 { 8 + bin_padded } else { 0 };
        let too_big = || {
            ExportError::Invalid(format!(
                "the glTF binary would be {total} bytes, over the GLB limit of 4 GiB; write fewer buildings per file (--tile METRES or --bbox)"
            ))
        };
        let total32 = u32::try_from(total).map_err(|_| too_big())?;

        let mut w = BufWriter::with_capacity(1 << 20, &mut self.out);
        w.write_all(&GLB_MAGIC.to_le_bytes())?;
        w.write_all(&GLB_VERSION.to_le_bytes())?;
        w.write_all(&total32.to_le_bytes())?;
        w.write_all(&(json_padded as u32).to_le_bytes())?;
        w.write_all(&CHUNK_JSON.to_le_bytes())?;
        for p in &pieces {
            match p {
                Piece::Text(t) => w.write_all(t)?,
                Piece::Spool(i) => self.spools[*i].copy_to(&mut w)?,
            }
        }
        for _ in json_len..json_padded {
            w.write_all(b" ")?;
        }
        if bin_len > 0 {
            w.write_all(&(bin_padded as u32).to_le_bytes())?;
            w.write_all(&CHUNK_BIN.to_le_bytes())?;
            match &mut scratch {
                Some(scratch) => {
                    scratch.seek(SeekFrom::Start(0))?;
                    let copied = io::copy(&mut scratch.take(bin_len), &mut w)?;
                    if copied != bin_len {
                        return Err(ExportError::Invalid(format!(
                            "glTF scratch file is {copied} bytes, expected {bin_len}: was it modified?"
                        )));
                    }
                }
                None => write_blank(&mut w, bin_len, 0)?,
            }
            for _ in bin_len..bin_padded {
                w.write_all(&[0])?;
            }
        }
        w.flush()?;
        drop(w);
        self.out.flush()?;
        Ok(())
    }
}

pub(super) fn pad4(n: u64) -> u64 {
    n.div_ceil(4) * 4
}
