//! File access: the blob framing of the PBF file, the sweep's peek at each data blob's first
//! group, and the decoding of the blobs of one kind in parallel.

use super::*;

// ---------------------------------------------------------------------------------------------
// File access

/// Largest BlobHeader the PBF format allows (64 KiB).
pub(super) const MAX_HEADER: usize = 64 * 1024;
/// Largest Blob the PBF format allows (32 MiB).
pub(super) const MAX_BLOB: u64 = 32 * 1024 * 1024;

/// Which elements a data blob holds, as far as the sweep can tell from its first group.
///
/// Writers (osmium, osmosis, ours) put one kind of element in a block, so the first group tells
/// the pass that needs the block. `Any` (the blob could not be peeked, or holds no group) is
/// decoded by every pass. A block that turns out to hold other kinds too makes the read start
/// again with every blob `Any`: exact, and as slow as three full decodes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum BlobKind {
    Nodes,
    Ways,
    Relations,
    Any,
}

/// Where a data blob lies in the file: its frame (length prefix, header, blob) and kind.
#[derive(Clone, Copy, Debug)]
pub(super) struct BlobLoc {
    /// 0-based index among all blobs of the file, for messages.
    pub(super) index: usize,
    pub(super) start: u64,
    pub(super) len: usize,
    pub(super) kind: BlobKind,
}

/// One framed blob of the file.
pub(super) struct Frame<'a> {
    pub(super) index: usize,
    pub(super) start: u64,
    /// The whole frame: 4-byte length, BlobHeader, Blob.
    pub(super) bytes: &'a [u8],
    /// Where the Blob message starts in `bytes`.
    pub(super) data: usize,
    /// The header's type: `OSMHeader`, `OSMData` or something else.
    pub(super) data_blob: bool,
}

/// An opened PBF file: the path for messages and the length to detect trailing garbage.
pub(super) struct Pbf {
    pub(super) path: PathBuf,
    pub(super) len: u64,
}

impl Pbf {
    pub(super) fn open(path: &Path) -> Result<Pbf, InputError> {
        let io = |source| InputError::Io {
            path: path.to_path_buf(),
            source,
        };
        let meta = std::fs::metadata(path).map_err(io)?;
        if meta.is_dir() {
            return Err(InputError::NotPbf {
                path: path.to_path_buf(),
                reason: "it is a directory".into(),
            });
        }
        if meta.len() == 0 {
            return Err(InputError::NotPbf {
                path: path.to_path_buf(),
                reason: "the file is empty".into(),
            });
        }
        if let Some(reason) = sniff(path) {
            return Err(InputError::NotPbf {
                path: path.to_path_buf(),
                reason,
            });
        }
        Ok(Pbf {
            path: path.to_path_buf(),
            len: meta.len(),
        })
    }

    pub(super) fn corrupt(
        &self,
        block: usize,
        offset: Option<u64>,
        reason: impl Into<String>,
    ) -> InputError {
        InputError::CorruptPbf {
            path: self.path.clone(),
            block,
            offset,
            reason: reason.into(),
        }
    }

    /// The whole file, read once: the passes take their blobs from it.
    pub(super) fn load(&self) -> Result<Vec<u8>, InputError> {
        std::fs::read(&self.path).map_err(|source| InputError::Io {
            path: self.path.clone(),
            source,
        })
    }

    /// An error while framing blob `index`: the first blob failing means this is not a PBF.
    pub(super) fn framing_error(&self, index: usize, offset: u64, reason: &str) -> InputError {
        if index == 0 {
            InputError::NotPbf {
                path: self.path.clone(),
                reason: format!("cannot read the first block: {reason}"),
            }
        } else {
            self.corrupt(index, Some(offset), reason)
        }
    }

    /// The frame of blob `index` starting at `start` in `file`, or `None` at the end of the
    /// file. Checks the sizes the format allows.
    pub(super) fn read_frame<'a>(
        &self,
        file: &'a [u8],
        index: usize,
        start: usize,
    ) -> Result<Option<Frame<'a>>, InputError> {
        let err = |reason: &str| self.framing_error(index, start as u64, reason);
        let rest = file.get(start..).unwrap_or_default();
        if rest.is_empty() {
            return Ok(None);
        }
        let Some(len4) = rest.get(..4) else {
            return Err(self.corrupt(
                index,
                Some(start as u64),
                format!(
                    "{} bytes after the last complete block: the file is truncated or has trailing garbage",
                    rest.len()
                ),
            ));
        };
        let hlen = u32::from_be_bytes([len4[0], len4[1], len4[2], len4[3]]) as usize;
        if hlen > MAX_HEADER {
            return Err(err(&format!(
                "blob header of {hlen} bytes (at most {MAX_HEADER})"
            )));
        }
        let Some(header) = rest.get(4..4 + hlen) else {
            return Err(err("the file ends inside a blob header"));
        };
        let (data_blob, size) = parse_blob_header(header)
            .map(|(kind, size)| (kind == b"OSMData", size))
            .ok_or_else(|| err("unreadable blob header"))?;
        if size > MAX_BLOB {
            return Err(err(&format!("blob of {size} bytes (at most {MAX_BLOB})")));
        }
        let data = 4 + hlen;
        let Some(bytes) = rest.get(..data + size as usize) else {
            return Err(err("the file ends inside a blob"));
        };
        Ok(Some(Frame {
            index,
            start: start as u64,
            bytes,
            data,
            data_blob,
        }))
    }

    /// Frames every blob of `file` (the whole file) once, checks the header block, and peeks
    /// at each data blob's first group to tell its kind, in parallel. Checks the framing: the
    /// first blob must be an OSMHeader, and the blobs must end exactly at the end of the file.
    pub(super) fn sweep(&self, file: &[u8]) -> Result<Vec<BlobLoc>, InputError> {
        let mut frames = Vec::new();
        let mut pos = 0usize;
        while let Some(frame) = self.read_frame(file, frames.len(), pos)? {
            pos += frame.bytes.len();
            frames.push(frame);
        }
        if frames.is_empty() {
            return Err(InputError::NotPbf {
                path: self.path.clone(),
                reason: "no PBF blocks found".into(),
            });
        }
        if pos as u64 != self.len {
            return Err(self.corrupt(
                frames.len(),
                Some(pos as u64),
                format!(
                    "{} bytes after the last complete block: the file is truncated or has trailing garbage",
                    self.len.saturating_sub(pos as u64)
                ),
            ));
        }
        let kinds: Vec<Result<Option<BlobKind>, InputError>> = frames
            .par_iter()
            .map(|f| {
                if f.data_blob && f.index > 0 {
                    let kind = catch_unwind(AssertUnwindSafe(|| peek_kind(&f.bytes[f.data..])));
                    return Ok(Some(kind.unwrap_or(BlobKind::Any)));
                }
                // The header block, a data block in its place, or an unknown type: fully
                // decoded, as osmpbf sees them.
                self.decode(f, |_| ()).map(|_| None)
            })
            .collect();
        let mut locs = Vec::new();
        for (f, k) in frames.iter().zip(kinds) {
            if let Some(kind) = k? {
                locs.push(BlobLoc {
                    index: f.index,
                    start: f.start,
                    len: f.bytes.len(),
                    kind,
                });
            }
        }
        Ok(locs)
    }

    /// Decodes one frame with osmpbf and runs `f` on its block: `Ok(None)` for a header or
    /// unknown blob (checked like a header when it is the first). Fenced against panics: a
    /// corrupt file must never bring the process down.
    pub(super) fn decode<T, F>(&self, frame: &Frame, f: F) -> Result<Option<T>, InputError>
    where
        F: Fn(&PrimitiveBlock) -> T,
    {
        let i = frame.index;
        let decoded = catch_unwind(AssertUnwindSafe(|| {
            let blob = match BlobReader::new(frame.bytes).next() {
                Some(Ok(b)) => b,
                Some(Err(e)) => return Err(e.to_string()),
                None => return Err("empty blob".to_string()),
            };
            match blob.decode() {
                Ok(BlobDecode::OsmHeader(h)) => {
                    let unsupported: Vec<&String> = h
                        .required_features()
                        .iter()
                        .filter(|f| !matches!(f.as_str(), "OsmSchema-V0.6" | "DenseNodes"))
                        .collect();
                    if unsupported.is_empty() {
                        Ok(None)
                    } else {
                        Err(format!("unsupported required features {unsupported:?}"))
                    }
                }
                Ok(BlobDecode::OsmData(_)) if i == 0 => {
                    Err("the first block is not an OSMHeader".to_string())
                }
                Ok(BlobDecode::OsmData(block)) => Ok(Some(f(&block))),
                Ok(BlobDecode::Unknown(t)) if i == 0 => {
                    Err(format!("the first block has unknown type {t:?}"))
                }
                Ok(BlobDecode::Unknown(_)) => Ok(None),
                Err(e) => Err(e.to_string()),
            }
        }));
        match decoded {
            Ok(Ok(v)) => Ok(v),
            Ok(Err(reason)) if i == 0 => Err(InputError::NotPbf {
                path: self.path.clone(),
                reason,
            }),
            Ok(Err(reason)) => Err(self.corrupt(i, Some(frame.start), reason)),
            Err(_) => Err(self.corrupt(i, Some(frame.start), "the block cannot be decoded")),
        }
    }

    /// Runs `f` on every data block of kind `want` (and every `Any` block) of `file`, in
    /// parallel, and returns the results in file order, with whether a block held elements of
    /// another kind than the sweep saw (then the caller starts again with every blob `Any`).
    /// `fast` is tried first on each block of kind `want`: the same result from the raw frame
    /// ([`wire`]), or `None` to leave the block to osmpbf and `f`.
    pub(super) fn pass<T, F, G>(
        &self,
        file: &[u8],
        locs: &[BlobLoc],
        want: BlobKind,
        fast: G,
        f: F,
    ) -> Result<(Vec<T>, bool), InputError>
    where
        T: Send,
        F: Fn(&PrimitiveBlock) -> T + Sync,
        G: Fn(&Frame, &mut Scratch) -> Option<T> + Sync,
    {
        let wanted: Vec<&BlobLoc> = locs
            .iter()
            .filter(|l| l.kind == want || l.kind == BlobKind::Any)
            .collect();
        let results: Vec<Result<Option<(T, bool)>, InputError>> = wanted
            .par_iter()
            .map_init(Scratch::default, |scratch, l| {
                let bytes = usize::try_from(l.start)
                    .ok()
                    .and_then(|s| file.get(s..s.checked_add(l.len)?))
                    .ok_or_else(|| self.corrupt(l.index, Some(l.start), "blob out of the file"))?;
                let frame = Frame {
                    index: l.index,
                    start: l.start,
                    data: 0,
                    bytes,
                    data_blob: true,
                };
                if l.kind == want {
                    let v = catch_unwind(AssertUnwindSafe(|| fast(&frame, scratch)));
                    if let Ok(Some(v)) = v {
                        return Ok(Some((v, false)));
                    }
                    // A panic (never expected) leaves the inflater in an unknown state.
                    if v.is_err() {
                        *scratch = Scratch::default();
                    }
                }
                self.decode(&frame, |block| {
                    let foreign = l.kind != BlobKind::Any && holds_other_than(block, want);
                    (f(block), foreign)
                })
            })
            .collect();
        let mut out = Vec::with_capacity(results.len());
        let mut mixed = false;
        for r in results {
            if let Some((v, foreign)) = r? {
                mixed |= foreign;
                out.push(v);
            }
        }
        Ok((out, mixed))
    }
}

/// Whether a block holds elements of another kind than `want`.
pub(super) fn holds_other_than(block: &PrimitiveBlock, want: BlobKind) -> bool {
    block.groups().any(|g| {
        let nodes = g.nodes().next().is_some() || g.dense_nodes().next().is_some();
        let ways = g.ways().next().is_some();
        let rels = g.relations().next().is_some();
        match want {
            BlobKind::Nodes => ways || rels,
            BlobKind::Ways => nodes || rels,
            BlobKind::Relations => nodes || ways,
            BlobKind::Any => false,
        }
    })
}

/// A protobuf varint at `*pos`, advancing it; `None` when the bytes end or it is too long.
pub(super) fn varint(b: &[u8], pos: &mut usize) -> Option<u64> {
    let mut v = 0u64;
    for shift in (0..64).step_by(7) {
        let byte = *b.get(*pos)?;
        *pos += 1;
        v |= u64::from(byte & 0x7f) << shift;
        if byte & 0x80 == 0 {
            return Some(v);
        }
    }
    None
}

/// Skips a field of wire type `wire` at `*pos`; `None` when the bytes end or the type is
/// unknown.
pub(super) fn skip_field(b: &[u8], pos: &mut usize, wire: u64) -> Option<()> {
    let end = match wire {
        0 => return varint(b, pos).map(|_| ()),
        1 => pos.checked_add(8)?,
        2 => {
            let len = usize::try_from(varint(b, pos)?).ok()?;
            pos.checked_add(len)?
        }
        5 => pos.checked_add(4)?,
        _ => return None,
    };
    (end <= b.len()).then(|| *pos = end)
}

/// A BlobHeader's type (field 1) and data size (field 3).
pub(super) fn parse_blob_header(b: &[u8]) -> Option<(&[u8], u64)> {
    let (mut pos, mut kind, mut size) = (0, None, None);
    while pos < b.len() {
        let key = varint(b, &mut pos)?;
        match key {
            0x0a => {
                let len = usize::try_from(varint(b, &mut pos)?).ok()?;
                let end = pos.checked_add(len).filter(|&e| e <= b.len())?;
                kind = Some(&b[pos..end]);
                pos = end;
            }
            0x18 => size = Some(varint(b, &mut pos)?),
            _ => skip_field(b, &mut pos, key & 7)?,
        }
    }
    Some((kind?, size?))
}

/// The kind of a data blob's first group, inflating only as much of the block as it takes
/// (the string table and the first group's first field). `Any` when it cannot tell.
pub(super) fn peek_kind(blob: &[u8]) -> BlobKind {
    // Blob: field 1 raw bytes, field 3 zlib_data; other compressions are left to osmpbf.
    let (mut pos, mut raw, mut zlib) = (0, None, None);
    while pos < blob.len() {
        let Some(key) = varint(blob, &mut pos) else {
            return BlobKind::Any;
        };
        if key == 0x0a || key == 0x1a {
            let Some(len) = varint(blob, &mut pos).and_then(|l| usize::try_from(l).ok()) else {
                return BlobKind::Any;
            };
            let Some(end) = pos.checked_add(len).filter(|&e| e <= blob.len()) else {
                return BlobKind::Any;
            };
            if key == 0x0a {
                raw = Some(&blob[pos..end]);
            } else {
                zlib = Some(&blob[pos..end]);
            }
            pos = end;
        } else if skip_field(blob, &mut pos, key & 7).is_none() {
            return BlobKind::Any;
        }
    }
    if let Some(r) = raw {
        return first_group_kind(r, true).unwrap_or(BlobKind::Any);
    }
    let Some(z) = zlib else {
        return BlobKind::Any;
    };
    // Inflated in small steps into a buffer that grows (miniz_oxide's core decoder stops when
    // the buffer is full, where a stream inflater decodes 32 KiB at a time): a block of nodes
    // tells its kind within its first hundred bytes.
    use miniz_oxide::inflate::core::{decompress, inflate_flags, DecompressorOxide};
    use miniz_oxide::inflate::TINFLStatus;
    let flags = inflate_flags::TINFL_FLAG_PARSE_ZLIB_HEADER
        | inflate_flags::TINFL_FLAG_USING_NON_WRAPPING_OUTPUT_BUF
        | inflate_flags::TINFL_FLAG_IGNORE_ADLER32;
    let mut inflater = Box::<DecompressorOxide>::default();
    let mut buf = vec![0u8; 1024];
    let (mut read, mut written) = (0usize, 0usize);
    loop {
        let Some(input) = z.get(read..) else {
            return BlobKind::Any;
        };
        let (status, r, w) = decompress(&mut inflater, input, &mut buf, written, flags);
        read += r;
        written += w;
        let done = status == TINFLStatus::Done;
        if let Some(kind) = first_group_kind(&buf[..written], done) {
            return kind;
        }
        if status != TINFLStatus::HasMoreOutput || buf.len() as u64 >= MAX_BLOB {
            return BlobKind::Any;
        }
        let more = buf.len() * 2;
        buf.resize(more, 0);
    }
}

/// The kind of a PrimitiveBlock's first non-empty group (field 2), from its first field;
/// `None` when `b` is a prefix too short to tell (and `complete` is false).
pub(super) fn first_group_kind(b: &[u8], complete: bool) -> Option<BlobKind> {
    let more = if complete { Some(BlobKind::Any) } else { None };
    let mut pos = 0;
    loop {
        if pos >= b.len() {
            return more;
        }
        let Some(key) = varint(b, &mut pos) else {
            return more;
        };
        if key == 0x12 {
            let Some(len) = varint(b, &mut pos) else {
                return more;
            };
            if len == 0 {
                continue;
            }
            let Some(inner) = varint(b, &mut pos) else {
                return more;
            };
            return Some(match inner >> 3 {
                1 | 2 => BlobKind::Nodes,
                3 => BlobKind::Ways,
                4 => BlobKind::Relations,
                _ => BlobKind::Any,
            });
        }
        if skip_field(b, &mut pos, key & 7).is_none() {
            return more;
        }
    }
}

/// What a file that cannot be an OSM PBF is, and what to do, from its first bytes (`None`: it
/// may be a PBF; the block reader decides). A PBF starts with the 4-byte length of its first
/// blob header (at most 64 KiB), so its first two bytes are 0.
fn sniff(path: &Path) -> Option<String> {
    use std::io::Read;
    let mut head = [0u8; 64];
    let n = std::fs::File::open(path)
        .and_then(|mut f| f.read(&mut head))
        .ok()?;
    describe_head(&head[..n])
}

/// [`sniff`] on the bytes.
fn describe_head(head: &[u8]) -> Option<String> {
    const CONVERT: &str =
        "convert it with `osmium cat FILE -o FILE.osm.pbf` (or `osmconvert FILE -o=FILE.osm.pbf`)";
    if head.len() >= 2 && head[0] == 0 && head[1] == 0 {
        return None;
    }
    let text = head.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(head);
    let start = text
        .iter()
        .position(|b| !b.is_ascii_whitespace())
        .map_or(&[][..], |i| &text[i..]);
    let what = if start.starts_with(b"<?xml") || start.starts_with(b"<osm") {
        format!("it is OSM XML; citygen reads OSM PBF: {CONVERT}")
    } else if head.starts_with(&[0x1f, 0x8b]) {
        format!("it is gzip-compressed (an .osm.gz, or a gzipped PBF): decompress it with `gunzip`; if it then is OSM XML, {CONVERT}")
    } else if head.starts_with(b"BZh") {
        format!("it is bzip2-compressed (an .osm.bz2): decompress it with `bunzip2`; if it then is OSM XML, {CONVERT}")
    } else if head.starts_with(&[0x28, 0xb5, 0x2f, 0xfd])
        || head.starts_with(&[0xfd, b'7', b'z', b'X', b'Z', 0])
    {
        "it is zstd- or xz-compressed: decompress it first".to_string()
    } else if head.starts_with(&[0xff, 0xe0])
        && head.get(3..7).is_some_and(|m| m.starts_with(b"o5"))
    {
        format!("it is o5m/o5c; {CONVERT}")
    } else if head.starts_with(b"PK\x03\x04") {
        "it is a zip archive: unpack the .osm.pbf inside it".to_string()
    } else if start.starts_with(b"{") {
        "it is JSON (GeoJSON?); citygen reads OSM PBF and ESRI shapefiles (--shp)".to_string()
    } else {
        return None;
    };
    Some(what)
}

#[cfg(test)]
mod sniff_tests {
    use super::describe_head;

    #[test]
    fn the_formats_people_give_instead_of_a_pbf_are_named() {
        let named = |head: &[u8], word: &str| {
            let r = describe_head(head).unwrap_or_default();
            assert!(r.contains(word), "{head:?}: {r}");
        };
        named(b"<?xml version='1.0'?><osm>", "OSM XML");
        named(b"\xEF\xBB\xBF  <osm version=\"0.6\">", "OSM XML");
        named(&[0x1f, 0x8b, 8, 0], "gzip");
        named(b"BZh91AY", "bzip2");
        named(&[0xff, 0xe0, 0x04, b'o', b'5', b'm', b'2'], "o5m");
        named(b"PK\x03\x04rest", "zip");
        // A PBF's first blob header length: not judged here.
        assert_eq!(describe_head(&[0, 0, 0, 14, 10, 9]), None);
    }
}
