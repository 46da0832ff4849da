//! A minimal OSM PBF writer: `citygen split` writes each shard's part of an input with it
//! ([`crate::pipeline::split`]), and tests and benchmarks build inputs (synthetic, corrupt,
//! tiled from real data) with it without a committed binary fixture.
//!
//! Output layout: one `OSMHeader` blob (required features `OsmSchema-V0.6` and `DenseNodes`),
//! then `OSMData` blobs of one `PrimitiveBlock` each, holding up to `BLOCK_ENTITIES` entities
//! of one kind: nodes as `DenseNodes` (ids and coordinates delta-coded), ways (delta-coded node
//! refs) or relations (delta-coded member ids). Each block has its own string table, granularity
//! 100 (coordinates in 1e-7 degrees), and is zlib-compressed with its `raw_size`. The protobuf is
//! encoded by hand (varints, zigzag, length-delimited fields).
//!
//! Entities are written in call order; a change of kind (node, way, relation) starts a new block,
//! so callers that want a conventional file write nodes, then ways, then relations.

use std::io::{self, Write};

use flate2::write::ZlibEncoder;
use flate2::Compression;

/// Entities of one kind per `PrimitiveBlock` (osmium writes 8,000 too).
pub(crate) const BLOCK_ENTITIES: usize = 8_000;

/// The type of a relation member.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MemberKind {
    /// A node member (PBF member type 0).
    Node,
    /// A way member (type 1).
    Way,
    /// A relation member (type 2).
    Relation,
}

/// A buffered entity of the block being filled.
enum Pending {
    Nodes(Vec<(i64, i64, i64, TagIdx)>),
    Ways(Vec<(i64, Vec<i64>, TagIdx)>),
    Relations(Vec<RelEntry>),
}

/// Tags as (key, value) string-table indices.
type TagIdx = Vec<(u32, u32)>;

/// (id, members as (kind, id, role string index), tags).
type RelEntry = (i64, Vec<(MemberKind, i64, u32)>, TagIdx);

/// Writes an OSM PBF file entity by entity. See the module documentation for the layout.
pub struct PbfWriter<W: Write> {
    out: W,
    pending: Option<Pending>,
    /// The string table of the block being filled; index 0 is the empty string by convention.
    strings: Vec<String>,
    index: std::collections::HashMap<String, u32>,
    /// Groups held back to share one block ([`PbfWriter::join_groups`]).
    held: Option<Vec<Vec<u8>>>,
}

impl<W: Write> PbfWriter<W> {
    /// Starts a file on `w` and writes its OSMHeader blob.
    pub fn new(w: W) -> io::Result<Self> {
        let mut header = Vec::new();
        field_bytes(&mut header, 4, b"OsmSchema-V0.6");
        field_bytes(&mut header, 4, b"DenseNodes");
        field_bytes(&mut header, 16, b"citygen pbf_write");
        let mut pw = PbfWriter {
            out: w,
            pending: None,
            strings: Vec::new(),
            index: Default::default(),
            held: None,
        };
        pw.reset_strings();
        pw.write_blob("OSMHeader", &header)?;
        Ok(pw)
    }

    /// Adds a node at (`lon`, `lat`) degrees, rounded to 1e-7 degrees.
    pub fn node(&mut self, id: i64, lon: f64, lat: f64, tags: &[(&str, &str)]) -> io::Result<()> {
        self.make_room(0)?;
        let tags = self.tag_indices(tags);
        let (lat, lon) = ((lat * 1e7).round() as i64, (lon * 1e7).round() as i64);
        if let Some(Pending::Nodes(v)) = &mut self.pending {
            v.push((id, lat, lon, tags));
        }
        Ok(())
    }

    /// Adds a node at (`lon_e7`, `lat_e7`) in 1e-7 degrees, as a PBF of granularity 100 holds
    /// it: a node copied from such a file keeps its coordinates bit for bit.
    pub fn node_e7(
        &mut self,
        id: i64,
        lon_e7: i64,
        lat_e7: i64,
        tags: &[(&str, &str)],
    ) -> io::Result<()> {
        self.make_room(0)?;
        let tags = self.tag_indices(tags);
        if let Some(Pending::Nodes(v)) = &mut self.pending {
            v.push((id, lat_e7, lon_e7, tags));
        }
        Ok(())
    }

    /// Adds a way with its node refs in order (a closed ring repeats its first node).
    pub fn way(&mut self, id: i64, refs: &[i64], tags: &[(&str, &str)]) -> io::Result<()> {
        self.make_room(1)?;
        let tags = self.tag_indices(tags);
        if let Some(Pending::Ways(v)) = &mut self.pending {
            v.push((id, refs.to_vec(), tags));
        }
        Ok(())
    }

    /// Adds a relation with its members as (kind, id, role).
    pub fn relation(
        &mut self,
        id: i64,
        members: &[(MemberKind, i64, &str)],
        tags: &[(&str, &str)],
    ) -> io::Result<()> {
        self.make_room(2)?;
        let tags = self.tag_indices(tags);
        let members = members
            .iter()
            .map(|&(k, m, role)| (k, m, self.string(role)))
            .collect();
        if let Some(Pending::Relations(v)) = &mut self.pending {
            v.push((id, members, tags));
        }
        Ok(())
    }

    /// From here until [`PbfWriter::end_join`], the blocks that a change of kind would start
    /// are groups of one block instead (its first group's kind the first entity's): a block
    /// holding more than one kind of element, which some writers make and readers must take.
    #[cfg(test)]
    pub(crate) fn join_groups(&mut self) -> io::Result<()> {
        self.flush_block()?;
        self.held = Some(Vec::new());
        Ok(())
    }

    /// Writes the joined groups ([`PbfWriter::join_groups`]) as one block.
    pub(crate) fn end_join(&mut self) -> io::Result<()> {
        self.flush_block()?;
        let Some(groups) = self.held.take() else {
            return Ok(());
        };
        self.write_block(&groups)
    }

    /// Writes the last block and returns the underlying writer (flushed).
    pub fn finish(mut self) -> io::Result<W> {
        self.end_join()?;
        self.flush_block()?;
        self.out.flush()?;
        Ok(self.out)
    }

    /// Flushes the pending block when it is full or of another kind than `kind`
    /// (0 nodes, 1 ways, 2 relations), then makes sure a block of `kind` is pending.
    fn make_room(&mut self, kind: u8) -> io::Result<()> {
        let (same, len) = match &self.pending {
            None => (false, 0),
            Some(Pending::Nodes(v)) => (kind == 0, v.len()),
            Some(Pending::Ways(v)) => (kind == 1, v.len()),
            Some(Pending::Relations(v)) => (kind == 2, v.len()),
        };
        if !same || len >= BLOCK_ENTITIES {
            self.flush_block()?;
            self.pending = Some(match kind {
                0 => Pending::Nodes(Vec::new()),
                1 => Pending::Ways(Vec::new()),
                _ => Pending::Relations(Vec::new()),
            });
        }
        Ok(())
    }

    fn reset_strings(&mut self) {
        self.strings.clear();
        self.index.clear();
        self.string("");
    }

    fn string(&mut self, s: &str) -> u32 {
        if let Some(&i) = self.index.get(s) {
            return i;
        }
        let i = self.strings.len() as u32;
        self.strings.push(s.to_string());
        self.index.insert(s.to_string(), i);
        i
    }

    fn tag_indices(&mut self, tags: &[(&str, &str)]) -> TagIdx {
        tags.iter()
            .map(|(k, v)| (self.string(k), self.string(v)))
            .collect()
    }

    /// Encodes the pending entities as one PrimitiveBlock and writes it as an OSMData blob.
    fn flush_block(&mut self) -> io::Result<()> {
        let Some(pending) = self.pending.take() else {
            return Ok(());
        };
        let mut group = Vec::new();
        match pending {
            Pending::Nodes(nodes) => {
                let mut dense = Vec::new();
                packed_sint_delta(&mut dense, 1, nodes.iter().map(|n| n.0));
                packed_sint_delta(&mut dense, 8, nodes.iter().map(|n| n.1));
                packed_sint_delta(&mut dense, 9, nodes.iter().map(|n| n.2));
                if nodes.iter().any(|n| !n.3.is_empty()) {
                    let kv = nodes.iter().flat_map(|n| {
                        n.3.iter()
                            .flat_map(|&(k, v)| [k as u64, v as u64])
                            .chain(std::iter::once(0))
                    });
                    packed_varint(&mut dense, 10, kv);
                }
                field_bytes(&mut group, 2, &dense);
            }
            Pending::Ways(ways) => {
                for (id, refs, tags) in &ways {
                    let mut w = Vec::new();
                    field_varint(&mut w, 1, *id as u64);
                    packed_varint(&mut w, 2, tags.iter().map(|t| t.0 as u64));
                    packed_varint(&mut w, 3, tags.iter().map(|t| t.1 as u64));
                    packed_sint_delta(&mut w, 8, refs.iter().copied());
                    field_bytes(&mut group, 3, &w);
                }
            }
            Pending::Relations(rels) => {
                for (id, members, tags) in &rels {
                    let mut r = Vec::new();
                    field_varint(&mut r, 1, *id as u64);
                    packed_varint(&mut r, 2, tags.iter().map(|t| t.0 as u64));
                    packed_varint(&mut r, 3, tags.iter().map(|t| t.1 as u64));
                    packed_varint(&mut r, 8, members.iter().map(|m| m.2 as u64));
                    packed_sint_delta(&mut r, 9, members.iter().map(|m| m.1));
                    packed_varint(
                        &mut r,
                        10,
                        members.iter().map(|m| match m.0 {
                            MemberKind::Node => 0,
                            MemberKind::Way => 1,
                            MemberKind::Relation => 2,
                        }),
                    );
                    field_bytes(&mut group, 4, &r);
                }
            }
        }
        if let Some(held) = &mut self.held {
            // The string table goes on: the block's groups share it.
            held.push(group);
            return Ok(());
        }
        self.write_block(&[group])
    }

    /// Writes one `PrimitiveBlock` of `groups` with the string table so far, then starts a new
    /// table.
    fn write_block(&mut self, groups: &[Vec<u8>]) -> io::Result<()> {
        let mut table = Vec::new();
        for s in &self.strings {
            field_bytes(&mut table, 1, s.as_bytes());
        }
        let mut block = Vec::new();
        field_bytes(&mut block, 1, &table);
        for group in groups {
            field_bytes(&mut block, 2, group);
        }
        field_varint(&mut block, 17, 100);
        self.reset_strings();
        self.write_blob("OSMData", &block)
    }

    /// Writes one fileblock: BlobHeader length (4 bytes, big-endian), BlobHeader, Blob with
    /// `raw_size` and `zlib_data`.
    fn write_blob(&mut self, kind: &str, raw: &[u8]) -> io::Result<()> {
        let mut z = ZlibEncoder::new(Vec::new(), Compression::default());
        z.write_all(raw)?;
        let zlib = z.finish()?;
        let mut blob = Vec::new();
        field_varint(&mut blob, 2, raw.len() as u64);
        field_bytes(&mut blob, 3, &zlib);
        let mut header = Vec::new();
        field_bytes(&mut header, 1, kind.as_bytes());
        field_varint(&mut header, 3, blob.len() as u64);
        self.out.write_all(&(header.len() as u32).to_be_bytes())?;
        self.out.write_all(&header)?;
        self.out.write_all(&blob)
    }
}

// ---- protobuf encoding ----------------------------------------------------------------------

fn varint(out: &mut Vec<u8>, mut v: u64) {
    while v >= 0x80 {
        out.push((v as u8) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

fn zigzag(v: i64) -> u64 {
    ((v << 1) ^ (v >> 63)) as u64
}

/// A varint field (wire type 0); negative int64 values take ten bytes, as protobuf says.
fn field_varint(out: &mut Vec<u8>, field: u32, v: u64) {
    varint(out, u64::from(field) << 3);
    varint(out, v);
}

/// A length-delimited field (wire type 2).
fn field_bytes(out: &mut Vec<u8>, field: u32, bytes: &[u8]) {
    varint(out, (u64::from(field) << 3) | 2);
    varint(out, bytes.len() as u64);
    out.extend_from_slice(bytes);
}

/// A packed repeated varint field; nothing when empty.
fn packed_varint(out: &mut Vec<u8>, field: u32, values: impl Iterator<Item = u64>) {
    let mut body = Vec::new();
    for v in values {
        varint(&mut body, v);
    }
    if !body.is_empty() {
        field_bytes(out, field, &body);
    }
}

/// A packed repeated sint64 field of deltas (each value minus the previous one, from 0).
fn packed_sint_delta(out: &mut Vec<u8>, field: u32, values: impl Iterator<Item = i64>) {
    let mut prev = 0i64;
    packed_varint(
        out,
        field,
        values.map(|v| {
            let d = v.wrapping_sub(prev);
            prev = v;
            zigzag(d)
        }),
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input::FootprintKind;
    use crate::model::SourceId;
    use crate::report::Report;
    use osmpbf::{Element, ElementReader, RelMemberType};

    fn tags_of<'a>(t: impl Iterator<Item = (&'a str, &'a str)>) -> Vec<(String, String)> {
        t.map(|(k, v)| (k.to_string(), v.to_string())).collect()
    }

    #[test]
    fn round_trip_through_osmpbf() {
        let mut w = PbfWriter::new(Vec::new()).unwrap();
        // More nodes than one block holds, with negative ids and coordinates.
        let n = BLOCK_ENTITIES as i64 + 123;
        for i in 0..n {
            let tags: &[(&str, &str)] = if i % 1000 == 0 {
                &[("name", "n"), ("amenity", "bench")]
            } else {
                &[]
            };
            w.node(
                i - 50,
                -179.5 + i as f64 * 1.234_567_1e-3,
                -60.0 + i as f64 * 1e-3,
                tags,
            )
            .unwrap();
        }
        w.way(7, &[1, 2, 3, 1], &[("building", "yes"), ("height", "12")])
            .unwrap();
        w.way(-8, &[3, 2], &[]).unwrap();
        w.relation(
            9,
            &[
                (MemberKind::Way, 7, "outer"),
                (MemberKind::Node, -3, ""),
                (MemberKind::Relation, 10, "sub"),
            ],
            &[("type", "multipolygon"), ("building", "yes")],
        )
        .unwrap();
        let bytes = w.finish().unwrap();

        let mut nodes = Vec::new();
        let mut ways = Vec::new();
        let mut rels = Vec::new();
        ElementReader::new(bytes.as_slice())
            .for_each(|e| match e {
                Element::DenseNode(d) => nodes.push((d.id(), d.lon(), d.lat(), tags_of(d.tags()))),
                Element::Node(d) => nodes.push((d.id(), d.lon(), d.lat(), tags_of(d.tags()))),
                Element::Way(w) => {
                    ways.push((w.id(), w.refs().collect::<Vec<_>>(), tags_of(w.tags())))
                }
                Element::Relation(r) => rels.push((
                    r.id(),
                    r.members()
                        .map(|m| {
                            let role = m.role().unwrap().to_string();
                            (m.member_type, m.member_id, role)
                        })
                        .collect::<Vec<_>>(),
                    tags_of(r.tags()),
                )),
            })
            .unwrap();
        assert_eq!(nodes.len(), n as usize);
        for (i, (id, lon, lat, tags)) in nodes.iter().enumerate() {
            let i = i as i64;
            assert_eq!(*id, i - 50);
            assert!(
                (lon - (-179.5 + i as f64 * 1.234_567_1e-3)).abs() < 1e-7,
                "{lon}"
            );
            assert!((lat - (-60.0 + i as f64 * 1e-3)).abs() < 1e-7, "{lat}");
            if i % 1000 == 0 {
                assert_eq!(tags.len(), 2);
                assert_eq!(tags[1], ("amenity".into(), "bench".into()));
            } else {
                assert!(tags.is_empty());
            }
        }
        assert_eq!(ways.len(), 2);
        assert_eq!(ways[0].0, 7);
        assert_eq!(ways[0].1, vec![1, 2, 3, 1]);
        assert_eq!(ways[0].2[1], ("height".into(), "12".into()));
        assert_eq!((ways[1].0, ways[1].1.clone()), (-8, vec![3, 2]));
        assert_eq!(rels.len(), 1);
        assert_eq!(
            rels[0].1,
            vec![
                (RelMemberType::Way, 7, "outer".to_string()),
                (RelMemberType::Node, -3, String::new()),
                (RelMemberType::Relation, 10, "sub".to_string()),
            ]
        );
        assert_eq!(rels[0].2[0], ("type".into(), "multipolygon".into()));
    }

    #[test]
    fn blocks_hold_one_kind_and_at_most_8000_entities() {
        let mut w = PbfWriter::new(Vec::new()).unwrap();
        for i in 0..(2 * BLOCK_ENTITIES + 1) as i64 {
            w.node(i + 1, 7.0, 43.0, &[]).unwrap();
        }
        w.way(1, &[1, 2], &[]).unwrap();
        let bytes = w.finish().unwrap();
        let reader = osmpbf::BlobReader::new(bytes.as_slice());
        let types: Vec<String> = reader
            .map(|b| format!("{:?}", b.unwrap().get_type()))
            .collect();
        // Header, 3 node blocks (8000, 8000, 1), 1 way block.
        assert_eq!(types.len(), 5, "{types:?}");
        assert!(types[0].contains("Header"));
    }

    #[test]
    fn citygen_reads_a_building_way_and_a_multipolygon() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.osm.pbf");
        let mut w = PbfWriter::new(std::fs::File::create(&path).unwrap()).unwrap();
        // A 20 m square building near Monaco, and a 40 m courtyard building as a relation.
        let (lon0, lat0, d) = (7.42, 43.73, 0.0002);
        let pts = [
            (1, 0.0, 0.0),
            (2, 1.0, 0.0),
            (3, 1.0, 1.0),
            (4, 0.0, 1.0),
            (11, 2.0, 0.0),
            (12, 4.0, 0.0),
            (13, 4.0, 2.0),
            (14, 2.0, 2.0),
            (21, 2.5, 0.5),
            (22, 3.5, 0.5),
            (23, 3.5, 1.5),
            (24, 2.5, 1.5),
        ];
        for (id, x, y) in pts {
            w.node(id, lon0 + x * d, lat0 + y * d, &[]).unwrap();
        }
        w.way(
            100,
            &[1, 2, 3, 4, 1],
            &[("building", "yes"), ("height", "9")],
        )
        .unwrap();
        w.way(101, &[11, 12, 13, 14, 11], &[]).unwrap();
        w.way(102, &[21, 22, 23, 24, 21], &[]).unwrap();
        w.relation(
            200,
            &[
                (MemberKind::Way, 101, "outer"),
                (MemberKind::Way, 102, "inner"),
            ],
            &[("type", "multipolygon"), ("building", "apartments")],
        )
        .unwrap();
        w.finish().unwrap();

        let mut report = Report::default();
        let r = crate::input::read_osm(&path, &mut report).unwrap();
        assert_eq!(r.footprints.len(), 2, "{:?}", report.entries);
        assert_eq!(r.footprints[0].id, SourceId::Way(100));
        assert_eq!(r.footprints[0].kind, FootprintKind::Building);
        assert_eq!(r.footprints[0].tags.height, Some(9.0));
        assert_eq!(r.footprints[0].polygons[0].outer.len(), 4);
        let (x, y) = r.footprints[0].polygons[0].outer[2];
        assert!((x - (lon0 + d)).abs() < 1e-7 && (y - (lat0 + d)).abs() < 1e-7);
        assert_eq!(r.footprints[1].id, SourceId::Relation(200));
        assert_eq!(r.footprints[1].polygons.len(), 1);
        assert_eq!(r.footprints[1].polygons[0].holes.len(), 1);
        assert_eq!(report.read, 2);
        assert_eq!(report.skipped, 0);
    }
}
