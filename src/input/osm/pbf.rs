//! File access: the blob framing of the PBF file, the sweep's peek at each data blob's first
//! group, and the decoding of the blobs of one kind in parallel.

use super::*;
use std::fs::File;
use std::io::{Read, Seek, SeekFrom};

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

/// Where a blob's frame lies in the file, as the sweep reads it: its length prefix and
/// BlobHeader, not the Blob.
struct FrameHead {
    index: usize,
    start: u64,
    /// The whole frame's length.
    len: usize,
    /// Where the Blob message starts in the frame.
    data: usize,
    /// The header's type is `OSMData`.
    data_blob: bool,
}

/// One decoding thread's handle on the file and the bytes of the blob it read last: the read
/// holds a blob a thread, never the whole file (issue 46).
#[derive(Default)]
pub(super) struct BlobBytes {
    file: Option<File>,
    buf: Vec<u8>,
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

/// An opened PBF file: the path for messages and the length to detect trailing garbage. The
/// file is read as a stream, blob by blob ([`Pbf::sweep`], [`Pbf::pass`]), never held whole.
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

    /// The I/O error `source` on this file; a file that ends early (it changed since it was
    /// opened) is a corrupt block `index` at `offset`, saying `early`.
    fn read_error(
        &self,
        source: std::io::Error,
        index: usize,
        offset: u64,
        early: &str,
    ) -> InputError {
        if source.kind() == std::io::ErrorKind::UnexpectedEof {
            self.framing_error(index, offset, early)
        } else {
            InputError::Io {
                path: self.path.clone(),
                source,
            }
        }
    }

    /// The head of the frame of blob `index` starting at byte `start`, read from `file`
    /// (positioned at `start`; left at the frame's end), or `None` at the end of the file.
    /// Checks the sizes the format allows; reads the length and the BlobHeader, not the Blob.
    fn frame_head(
        &self,
        file: &mut std::io::BufReader<File>,
        index: usize,
        start: u64,
        header: &mut Vec<u8>,
    ) -> Result<Option<FrameHead>, InputError> {
        let err = |reason: &str| self.framing_error(index, start, reason);
        let rest = self.len.saturating_sub(start);
        if rest == 0 {
            return Ok(None);
        }
        if rest < 4 {
            return Err(self.corrupt(
                index,
                Some(start),
                format!(
                    "{rest} bytes after the last complete block: the file is truncated or has trailing garbage"
                ),
            ));
        }
        let mut len4 = [0u8; 4];
        file.read_exact(&mut len4)
            .map_err(|e| self.read_error(e, index, start, "the file ends inside a blob header"))?;
        let hlen = u32::from_be_bytes(len4) as usize;
        if hlen > MAX_HEADER {
            return Err(err(&format!(
                "blob header of {hlen} bytes (at most {MAX_HEADER})"
            )));
        }
        if 4 + hlen as u64 > rest {
            return Err(err("the file ends inside a blob header"));
        }
        header.clear();
        header.resize(hlen, 0);
        file.read_exact(header)
            .map_err(|e| self.read_error(e, index, start, "the file ends inside a blob header"))?;
        let (data_blob, size) = parse_blob_header(header)
            .map(|(kind, size)| (kind == b"OSMData", size))
            .ok_or_else(|| err("unreadable blob header"))?;
        if size > MAX_BLOB {
            return Err(err(&format!("blob of {size} bytes (at most {MAX_BLOB})")));
        }
        let data = 4 + hlen;
        if data as u64 + size > rest {
            return Err(err("the file ends inside a blob"));
        }
        // At most MAX_BLOB: fits an i64.
        file.seek_relative(size as i64)
            .map_err(|source| InputError::Io {
                path: self.path.clone(),
                source,
            })?;
        Ok(Some(FrameHead {
            index,
            start,
            len: data + size as usize,
            data,
            data_blob,
        }))
    }

    /// The `len` bytes of blob `index` at byte `start` (its whole frame), read into `reader`'s
    /// buffer from its own handle on the file (opened on first use).
    pub(super) fn read_blob<'r>(
        &self,
        reader: &'r mut BlobBytes,
        index: usize,
        start: u64,
        len: usize,
    ) -> Result<&'r [u8], InputError> {
        let io = |source| InputError::Io {
            path: self.path.clone(),
            source,
        };
        let file = match &mut reader.file {
            Some(f) => f,
            None => reader.file.insert(File::open(&self.path).map_err(io)?),
        };
        file.seek(SeekFrom::Start(start)).map_err(io)?;
        reader.buf.clear();
        reader.buf.resize(len, 0);
        file.read_exact(&mut reader.buf).map_err(|e| {
            self.read_error(
                e,
                index,
                start,
                "the file ends inside a blob (it changed while being read)",
            )
        })?;
        Ok(&reader.buf)
    }

    /// Frames every blob of the file once, reading it as a stream (only the blob headers;
    /// never the whole file), checks the header block, and peeks at each data blob's first
    /// group to tell its kind, in parallel (each thread reads the blobs it peeks at). Checks
    /// the framing: the first blob must be an OSMHeader, and the blobs must end exactly at the
    /// end of the file.
    pub(super) fn sweep(&self) -> Result<Vec<BlobLoc>, InputError> {
        let io = |source| InputError::Io {
            path: self.path.clone(),
            source,
        };
        let mut file =
            std::io::BufReader::with_capacity(1 << 16, File::open(&self.path).map_err(io)?);
        let mut heads = Vec::new();
        let mut header = Vec::new();
        let mut pos = 0u64;
        while let Some(h) = self.frame_head(&mut file, heads.len(), pos, &mut header)? {
            pos += h.len as u64;
            heads.push(h);
        }
        drop(file);
        if heads.is_empty() {
            return Err(InputError::NotPbf {
                path: self.path.clone(),
                reason: "no PBF blocks found".into(),
            });
        }
        if pos != self.len {
            return Err(self.corrupt(
                heads.len(),
                Some(pos),
                format!(
                    "{} bytes after the last complete block: the file is truncated or has trailing garbage",
                    self.len.saturating_sub(pos)
                ),
            ));
        }
        let kinds: Vec<Result<Option<BlobKind>, InputError>> = heads
            .par_iter()
            .map_init(BlobBytes::default, |reader, h| {
                let bytes = self.read_blob(reader, h.index, h.start, h.len)?;
                let f = Frame {
                    index: h.index,
                    start: h.start,
                    bytes,
                    data: h.data,
                    data_blob: h.data_blob,
                };
                if f.data_blob && f.index > 0 {
                    let kind = catch_unwind(AssertUnwindSafe(|| peek_kind(&f.bytes[f.data..])));
                    return Ok(Some(kind.unwrap_or(BlobKind::Any)));
                }
                // The header block, a data block in its place, or an unknown type: fully
                // decoded, as osmpbf sees them.
                self.decode(&f, |_| ()).map(|_| None)
            })
            .collect();
        let mut locs = Vec::new();
        for (h, k) in heads.iter().zip(kinds) {
            if let Some(kind) = k? {
                locs.push(BlobLoc {
                    index: h.index,
                    start: h.start,
                    len: h.len,
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

    /// Runs `f` on every data block of kind `want` (and every `Any` block) of the file, in
    /// parallel (each thread reads the blobs it decodes: one blob a thread in memory), and returns the results in file order, with whether a block held elements of
    /// another kind than the sweep saw (then the caller starts again with every blob `Any`).
    /// `fast` is tried first on each block of kind `want`: the same result from the raw frame
    /// ([`wire`]), or `None` to leave the block to osmpbf and `f`.
    pub(super) fn pass<T, F, G>(
        &self,
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
            .map_init(
                || (Scratch::default(), BlobBytes::default()),
                |(scratch, reader), l| {
                    let bytes = self.read_blob(reader, l.index, l.start, l.len)?;
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
                },
            )
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
