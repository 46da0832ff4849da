//! OSM XML written from an OSM PBF, for tests: the same data as the PBF in the `.osm` format
//! osmium writes (elements in file order, coordinates to the PBF's nanodegree exactly, tag
//! values escaped), optionally gzip- or bzip2-compressed by the caller.

use std::io::{self, Write};
use std::path::Path;

use osmpbf::{Element, ElementReader, RelMemberType};

/// `v` escaped for a double-quoted XML attribute (markup characters and the whitespace XML
/// would normalise to spaces).
pub fn escape(v: &str) -> String {
    let mut out = String::with_capacity(v.len());
    for c in v.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            '\n' => out.push_str("&#10;"),
            '\r' => out.push_str("&#13;"),
            '\t' => out.push_str("&#9;"),
            c => out.push(c),
        }
    }
    out
}

/// Nanodegrees as an exact decimal (`-43.731234500`).
fn decimal(nano: i64) -> String {
    let sign = if nano < 0 { "-" } else { "" };
    let a = nano.unsigned_abs();
    format!("{sign}{}.{:09}", a / 1_000_000_000, a % 1_000_000_000)
}

fn tags<'a>(
    out: &mut impl Write,
    tags: impl Iterator<Item = (&'a str, &'a str)>,
) -> io::Result<()> {
    for (k, v) in tags {
        writeln!(out, "    <tag k=\"{}\" v=\"{}\"/>", escape(k), escape(v))?;
    }
    Ok(())
}

/// Writes the elements of the PBF at `pbf` to `out` as OSM XML, in the PBF's order.
pub fn pbf_to_xml(pbf: &Path, out: &mut impl Write) -> io::Result<()> {
    writeln!(out, "<?xml version='1.0' encoding='UTF-8'?>")?;
    writeln!(out, "<osm version=\"0.6\" generator=\"citygen testkit\">")?;
    let reader = ElementReader::from_path(pbf).map_err(io::Error::other)?;
    let mut result = Ok(());
    let node = |out: &mut dyn Write, id: i64, lon: i64, lat: i64, t: Vec<(&str, &str)>| {
        let (lat, lon) = (decimal(lat), decimal(lon));
        if t.is_empty() {
            return writeln!(out, "  <node id=\"{id}\" lat=\"{lat}\" lon=\"{lon}\"/>");
        }
        writeln!(out, "  <node id=\"{id}\" lat=\"{lat}\" lon=\"{lon}\">")?;
        let mut out = out;
        tags(&mut out, t.into_iter())?;
        writeln!(out, "  </node>")
    };
    reader
        .for_each(|e| {
            if result.is_err() {
                return;
            }
            result = match e {
                Element::DenseNode(n) => {
                    node(out, n.id(), n.nano_lon(), n.nano_lat(), n.tags().collect())
                }
                Element::Node(n) => {
                    node(out, n.id(), n.nano_lon(), n.nano_lat(), n.tags().collect())
                }
                Element::Way(w) => (|| {
                    writeln!(out, "  <way id=\"{}\">", w.id())?;
                    for r in w.refs() {
                        writeln!(out, "    <nd ref=\"{r}\"/>")?;
                    }
                    tags(out, w.tags())?;
                    writeln!(out, "  </way>")
                })(),
                Element::Relation(r) => (|| {
                    writeln!(out, "  <relation id=\"{}\">", r.id())?;
                    for m in r.members() {
                        let t = match m.member_type {
                            RelMemberType::Node => "node",
                            RelMemberType::Way => "way",
                            RelMemberType::Relation => "relation",
                        };
                        let role = m.role().unwrap_or_default();
                        writeln!(
                            out,
                            "    <member type=\"{t}\" ref=\"{}\" role=\"{}\"/>",
                            m.member_id,
                            escape(role)
                        )?;
                    }
                    tags(out, r.tags())?;
                    writeln!(out, "  </relation>")
                })(),
            };
        })
        .map_err(io::Error::other)?;
    result?;
    writeln!(out, "</osm>")
}
