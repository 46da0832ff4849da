//! GeoJSON footprints (RFC 7946, and the older GeoJSON 2008 `crs` member GDAL writes for
//! projected data): a `FeatureCollection` read feature by feature, or a single `Feature`.
//!
//! The collection is streamed: serde visits the `features` array one element at a time, so
//! memory holds one feature's JSON and the footprints made so far, never the whole document.
//!
//! - **Geometry**: `Polygon`, `MultiPolygon` (one footprint, several polygons), and a
//!   `GeometryCollection` of those; z is dropped. Rings are grouped by nesting as the
//!   shapefile reader does (`input::rings`); any other geometry, or none, is a skipped report
//!   entry naming the feature.
//! - **Properties**: keys that are OSM building keys (`building`, `height`, `building:levels`,
//!   `roof:shape`, ... as Overpass and osmtogeojson export them) are read as tags; a feature
//!   with `building:part` and no `building` is a part. Overture's names (`num_floors`,
//!   `roof_shape`, `roof_height`, `facade_color`, `roof_color`, `facade_material`,
//!   `roof_material`, `min_height`) map to their OSM keys; a height or levels property under a
//!   municipal name is found as in a shapefile (`--shp-height-field`, `--shp-levels-field`, else
//!   the first of `features::HEIGHT_FIELDS`/`LEVELS_FIELDS` present).
//! - **Ids**: a feature `id` (or `@id` property) of the form `way/123`, `relation/45` keeps its
//!   OSM id (and, without `building` or `building:part`, is skipped: an Overpass export holds
//!   land use and streets too); a non-negative integer id `n` (the feature's, else the first of
//!   the columns `id`, `objectid`, `fid`, `osm_id`, `gml_id` holding one) gives `feature/n`; else the feature's 0-based position
//!   gives `feature/<position>`. When the file's ids are not unique, every feature is numbered by
//!   position instead (a note says so).
//! - **CRS**: `--src-crs`, else the `crs` member's EPSG code, else WGS84 longitude/latitude (RFC
//!   7946).
//!
//! Errors name the file and, for malformed JSON, the line and column.

use std::fmt;
use std::fs::File;
use std::io::{BufReader, Read};
use std::path::Path;

use serde::de::{self, DeserializeSeed, IgnoredAny, MapAccess, SeqAccess, Visitor};
use serde::Deserialize;
use serde_json::{Map, Value};

use super::features::ShpOptions;
use super::features::Sink;
use super::{InputError, ReadResult, Ring, SourceId};
use crate::report::Report;

/// At most this many bytes are looked at to tell a GeoJSON file from a shapefile.
const SNIFF: usize = 64;

/// Whether the file starts like a JSON object (after an optional UTF-8 byte order mark and
/// white space): what `--shp` reads as GeoJSON rather than as a shapefile.
pub(crate) fn looks_like_geojson(path: &Path) -> bool {
    let Ok(f) = File::open(path) else {
        return false;
    };
    let mut head = Vec::with_capacity(SNIFF);
    if f.take(SNIFF as u64).read_to_end(&mut head).is_err() {
        return false;
    }
    let head = head.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(&head);
    head.iter()
        .find(|b| !b.is_ascii_whitespace())
        .is_some_and(|&b| b == b'{')
}

/// One feature as read: its id, its geometry, its properties (all left as JSON).
#[derive(Deserialize, Default)]
struct RawFeature {
    #[serde(default)]
    id: Option<Value>,
    #[serde(default)]
    geometry: Option<Value>,
    #[serde(default)]
    properties: Option<Map<String, Value>>,
}

/// Reads the footprints of a GeoJSON file. See the module documentation.
pub fn read_geojson(
    path: &Path,
    opts: &ShpOptions,
    report: &mut Report,
) -> Result<ReadResult, InputError> {
    let file = File::open(path).map_err(|source| InputError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let mut sink = Sink::new(path, opts, report);
    let mut de = serde_json::Deserializer::from_reader(BufReader::new(file));
    let top = Top { sink: &mut sink }
        .deserialize(&mut de)
        .and_then(|t| de.end().map(|()| t))
        .map_err(|e| json_error(path, &e))?;
    if top.kind.as_deref() == Some("Feature") {
        feature(&mut sink, top.single);
    } else if top.kind.as_deref() != Some("FeatureCollection") {
        return Err(InputError::Shapefile {
            path: path.to_path_buf(),
            reason: format!(
                "a GeoJSON file must be a FeatureCollection or a Feature, this one is {}",
                top.kind.map_or("of no type".into(), |k| format!("a {k:?}"))
            ),
        });
    }
    let source_crs = match (opts.src_crs, top.crs) {
        (Some(c), _) => Some(c),
        (None, Some(name)) => {
            Some(
                crate::crs::Crs::from_epsg_str(&name).map_err(|e| InputError::Crs {
                    path: path.to_path_buf(),
                    reason: format!(
                        "the GeoJSON crs {name:?}: {e}; give the CRS with --src-crs EPSG:n"
                    ),
                })?,
            )
            .filter(|c| *c != crate::crs::Crs::Wgs84)
        }
        (None, None) => None,
    };
    sink.finish(source_crs)
}

/// Hands one feature to the sink.
fn feature(sink: &mut Sink, f: RawFeature) {
    let props = f.properties.unwrap_or_default();
    let mut rings = Vec::new();
    let rings = collect_rings(f.geometry.as_ref(), &mut rings, 0).map(|()| rings);
    sink.add(feature_id(f.id.as_ref(), &props), rings, &props);
}

/// The id a feature keeps: an OSM `way/n` or `relation/n` (the feature's `id`, else its `@id`
/// property), `feature/n` for a non-negative integer id, or a text id for any other
/// (`Sink::add` prefers a whole number in an id column to it).
fn feature_id(id: Option<&Value>, props: &Map<String, Value>) -> Option<SourceId> {
    let osm = |v: &Value| {
        v.as_str()
            .and_then(SourceId::parse)
            .filter(|s| matches!(s, SourceId::Way(_) | SourceId::Relation(_)))
    };
    if let Some(s) = id.and_then(osm).or_else(|| props.get("@id").and_then(osm)) {
        return Some(s);
    }
    match id? {
        Value::Number(n) => Some(match n.as_u64() {
            Some(n) => SourceId::Feature(n),
            None => SourceId::text(&n.to_string()),
        }),
        Value::String(t) if !t.trim().is_empty() => Some(match super::features::whole_number(t) {
            Some(n) => SourceId::Feature(n),
            None => SourceId::text(t.trim()),
        }),
        _ => None,
    }
}

/// The rings of a geometry with their declared roles (the first ring of a polygon is its
/// outer), or why it has none a footprint can use.
fn collect_rings(
    g: Option<&Value>,
    out: &mut Vec<(Ring, bool)>,
    depth: usize,
) -> Result<(), String> {
    let Some(g) = g.filter(|g| !g.is_null()) else {
        return Err("no geometry".into());
    };
    let kind = g.get("type").and_then(Value::as_str).unwrap_or("");
    let coords = g.get("coordinates");
    match kind {
        "Polygon" => polygon(coords, out),
        "MultiPolygon" => {
            let polys = coords
                .and_then(Value::as_array)
                .ok_or("a MultiPolygon without an array of polygons")?;
            polys.iter().try_for_each(|p| polygon(Some(p), out))
        }
        // Nested collections are legal but rare; two levels are plenty.
        "GeometryCollection" if depth < 2 => {
            let parts = g
                .get("geometries")
                .and_then(Value::as_array)
                .ok_or("a GeometryCollection without geometries")?;
            let mut any = false;
            for p in parts {
                let kind = p.get("type").and_then(Value::as_str).unwrap_or("");
                if matches!(kind, "Polygon" | "MultiPolygon" | "GeometryCollection") {
                    collect_rings(Some(p), out, depth + 1)?;
                    any = true;
                }
            }
            if any {
                Ok(())
            } else {
                Err("a GeometryCollection without polygons".into())
            }
        }
        "" => Err("a geometry without a type".into()),
        other => Err(format!("geometry type {other} is not a polygon")),
    }
}

/// The rings of one polygon's coordinates.
fn polygon(coords: Option<&Value>, out: &mut Vec<(Ring, bool)>) -> Result<(), String> {
    let rings = coords
        .and_then(Value::as_array)
        .ok_or("a polygon without an array of rings")?;
    for (i, r) in rings.iter().enumerate() {
        let pts = r
            .as_array()
            .ok_or_else(|| format!("ring {i} is not an array of positions"))?;
        let mut ring = Vec::with_capacity(pts.len());
        for p in pts {
            let xy = p
                .as_array()
                .filter(|a| a.len() >= 2)
                .and_then(|a| Some((a[0].as_f64()?, a[1].as_f64()?)));
            ring.push(xy.ok_or_else(|| format!("ring {i} has a position that is not [x, y]"))?);
        }
        out.push((ring, i == 0));
    }
    Ok(())
}

fn json_error(path: &Path, e: &serde_json::Error) -> InputError {
    InputError::Shapefile {
        path: path.to_path_buf(),
        reason: format!(
            "not valid GeoJSON at line {}, column {}: {e}",
            e.line(),
            e.column()
        ),
    }
}

/// The top-level object: its `type`, its `crs` name, and (for a single `Feature`) the feature.
struct Top<'s, 'a> {
    sink: &'s mut Sink<'a>,
}

#[derive(Default)]
struct TopOut {
    kind: Option<String>,
    crs: Option<String>,
    single: RawFeature,
}

impl<'de> DeserializeSeed<'de> for Top<'_, '_> {
    type Value = TopOut;
    fn deserialize<D: de::Deserializer<'de>>(self, d: D) -> Result<TopOut, D::Error> {
        d.deserialize_map(self)
    }
}

impl<'de> Visitor<'de> for Top<'_, '_> {
    type Value = TopOut;
    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a GeoJSON object")
    }
    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<TopOut, A::Error> {
        let mut out = TopOut::default();
        while let Some(key) = map.next_key::<String>()? {
            match key.as_str() {
                "type" => out.kind = Some(map.next_value()?),
                "crs" => out.crs = crs_name(&map.next_value::<Value>()?),
                "features" => map.next_value_seed(Features {
                    sink: &mut *self.sink,
                })?,
                "id" => out.single.id = Some(map.next_value()?),
                "geometry" => out.single.geometry = Some(map.next_value()?),
                "properties" => out.single.properties = map.next_value()?,
                _ => {
                    map.next_value::<IgnoredAny>()?;
                }
            }
        }
        Ok(out)
    }
}

/// The `name` of a GeoJSON 2008 named CRS (`{"type": "name", "properties": {"name":
/// "urn:ogc:def:crs:EPSG::2056"}}`); OGC's CRS84 is WGS84 longitude/latitude.
fn crs_name(v: &Value) -> Option<String> {
    let name = v.get("properties")?.get("name")?.as_str()?;
    let lower = name.to_ascii_lowercase();
    if lower.ends_with("crs84") || lower.ends_with("crs:84") {
        return Some("EPSG:4326".into());
    }
    Some(name.to_string())
}

/// The `features` array, handed to the sink one element at a time.
struct Features<'s, 'a> {
    sink: &'s mut Sink<'a>,
}

impl<'de> DeserializeSeed<'de> for Features<'_, '_> {
    type Value = ();
    fn deserialize<D: de::Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_seq(self)
    }
}

impl<'de> Visitor<'de> for Features<'_, '_> {
    type Value = ();
    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("an array of GeoJSON features")
    }
    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<(), A::Error> {
        while let Some(f) = seq.next_element::<RawFeature>()? {
            feature(self.sink, f);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input::FootprintKind;

    fn read(text: &str, opts: &ShpOptions) -> (Result<ReadResult, InputError>, Report) {
        let dir = tempfile_dir();
        let p = dir.join("f.geojson");
        std::fs::write(&p, text).unwrap();
        let mut report = Report::default();
        let r = read_geojson(&p, opts, &mut report);
        std::fs::remove_dir_all(&dir).ok();
        (r, report)
    }

    fn tempfile_dir() -> std::path::PathBuf {
        use std::sync::atomic::{AtomicUsize, Ordering};
        static N: AtomicUsize = AtomicUsize::new(0);
        let d = std::env::temp_dir().join(format!(
            "citygen-geojson-{}-{}",
            std::process::id(),
            N.fetch_add(1, Ordering::Relaxed)
        ));
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    const SQUARE: &str =
        "[[[7.42,43.73],[7.4201,43.73],[7.4201,43.7301],[7.42,43.7301],[7.42,43.73]]]";

    /// The ids of the footprints read from features with these `id` members and properties.
    fn ids_of(features: &[(&str, &str)], opts: &ShpOptions) -> (Vec<String>, Report) {
        let f: Vec<String> = features
            .iter()
            .map(|(id, props)| {
                let id = if id.is_empty() { String::new() } else { format!(r#""id":{id},"#) };
                format!(
                    r#"{{"type":"Feature",{id}"properties":{props},"geometry":{{"type":"Polygon","coordinates":{SQUARE}}}}}"#
                )
            })
            .collect();
        let text = format!(
            r#"{{"type":"FeatureCollection","features":[{}]}}"#,
            f.join(",")
        );
        let (r, report) = read(&text, opts);
        let ids = r
            .unwrap()
            .footprints
            .iter()
            .map(|f| f.id.to_string())
            .collect();
        (ids, report)
    }

    #[test]
    fn text_ids_are_kept_after_whole_numbers_and_unique_as_xml_ids() {
        let o = ShpOptions::default();
        // A whole number in an id column first; then the feature's own text id; then a text
        // id column; a zero-padded number is text; positions last.
        let (ids, _) = ids_of(
            &[
                (r#""a-b""#, r#"{"objectid": 50}"#),
                (r#""osgb1000012345678""#, r#"{"gml_id": "x"}"#),
                ("", r#"{"TOID": "osgb1000000347"}"#),
                ("", r#"{"id": "0599100000012345"}"#),
                ("", r#"{"id": " 42 "}"#),
                (r#"{"k":1}"#, r#"{}"#),
            ],
            &o,
        );
        assert_eq!(
            ids,
            [
                "feature/50",
                "osgb1000012345678",
                "osgb1000000347",
                "0599100000012345",
                "feature/42",
                "feature/5"
            ]
        );
        // A whole number of its own gives way to an identity column (the BAG's), not to
        // another; `--field id=` names the column.
        let (ids, _) = ids_of(
            &[
                (
                    "7",
                    r#"{"identificatie": "NL.IMBAG.Pand.0599100000012345"}"#,
                ),
                ("8", r#"{"gml_id": "g8"}"#),
            ],
            &o,
        );
        assert_eq!(ids, ["NL.IMBAG.Pand.0599100000012345", "feature/8"]);
        let named = ShpOptions {
            fields: vec![("id".into(), "GML_ID".into())],
            ..ShpOptions::default()
        };
        let (ids, _) = ids_of(&[("8", r#"{"gml_id": "g8"}"#)], &named);
        assert_eq!(ids, ["g8"]);
        // The report names a text id by its text.
        let text = r#"{"type":"FeatureCollection","features":[{"type":"Feature","id":"{B-7}","properties":{},"geometry":null}]}"#;
        let (_, report) = read(text, &o);
        assert_eq!(report.entries[0].id, "{B-7}");
        assert_eq!(report.entries[0].outcome, crate::report::Outcome::Skipped);
        // Texts that are one XML id once sanitised (`a b`, `a_b` with the hash of `a b`), or
        // a text that reads as a numbered id beside it: renumbered by position, with a note.
        let a_b = SourceId::text("a b").key();
        assert!(
            a_b.starts_with("a_b_h") && a_b.len() == "a_b_h".len() + 8,
            "{a_b}"
        );
        for (first, second) in [
            (r#""a b""#, format!("{a_b:?}")),
            (r#""feature/3""#, "3".to_string()),
            (r#""dup""#, r#""dup""#.to_string()),
        ] {
            let (ids, report) = ids_of(&[(first, "{}"), (&second, "{}")], &o);
            assert_eq!(ids, ["feature/0", "feature/1"], "{first} {second}");
            assert!(
                report
                    .entries
                    .iter()
                    .any(|e| e.reason.contains("not unique")),
                "{first} {second}"
            );
        }
    }

    #[test]
    fn osm_keys_overture_names_and_municipal_fields_become_tags_and_ids_are_kept() {
        let text = format!(
            r#"{{"type":"FeatureCollection","features":[
            {{"type":"Feature","id":"way/42","properties":{{"building":"house","height":7.5,"roof:shape":"gabled"}},"geometry":{{"type":"Polygon","coordinates":{SQUARE}}}}},
            {{"type":"Feature","id":17,"properties":{{"num_floors":4,"roof_shape":"flat","class":"x"}},"geometry":{{"type":"MultiPolygon","coordinates":[{SQUARE}]}}}},
            {{"type":"Feature","properties":{{"HAUTEUR":"12.5","building:part":"yes"}},"geometry":{{"type":"Polygon","coordinates":{SQUARE}}}}},
            {{"type":"Feature","properties":{{}},"geometry":{{"type":"Point","coordinates":[7.42,43.73]}}}},
            {{"type":"Feature","properties":{{}},"geometry":null}},
            {{"type":"Feature","id":"way/7","properties":{{"landuse":"residential"}},"geometry":{{"type":"Polygon","coordinates":{SQUARE}}}}}
            ]}}"#
        );
        let (r, report) = read(&text, &ShpOptions::default());
        let r = r.unwrap();
        assert_eq!(r.source_crs, None);
        let ids: Vec<String> = r.footprints.iter().map(|f| f.id.to_string()).collect();
        assert_eq!(ids, ["way/42", "feature/17", "feature/2"]);
        assert_eq!(r.footprints[0].tags.height, Some(7.5));
        assert_eq!(r.footprints[1].tags.levels, Some(4.0));
        assert_eq!(r.footprints[2].tags.height, Some(12.5));
        assert_eq!(r.footprints[2].kind, FootprintKind::Part);
        assert_eq!((report.read, report.parts_read, report.skipped), (5, 1, 3));
        assert!(reasons_have(&report, "without building or building:part"));
        let reasons: Vec<&str> = report.entries.iter().map(|e| e.reason.as_str()).collect();
        assert!(
            reasons.iter().any(|r| r.contains("Point is not a polygon")),
            "{reasons:?}"
        );
        assert!(
            reasons.iter().any(|r| r.contains("no geometry")),
            "{reasons:?}"
        );
    }

    fn reasons_have(report: &Report, what: &str) -> bool {
        report.entries.iter().any(|e| e.reason.contains(what))
    }

    #[test]
    fn duplicate_ids_number_every_feature_by_position_and_the_crs_member_is_read() {
        let sq = "[[[2600000,1200000],[2600010,1200000],[2600010,1200010],[2600000,1200010],[2600000,1200000]]]";
        let text = format!(
            r#"{{"type":"FeatureCollection","crs":{{"type":"name","properties":{{"name":"urn:ogc:def:crs:EPSG::32632"}}}},"features":[
            {{"type":"Feature","id":5,"properties":{{}},"geometry":{{"type":"Polygon","coordinates":{sq}}}}},
            {{"type":"Feature","id":5,"properties":{{}},"geometry":{{"type":"Polygon","coordinates":{sq}}}}}]}}"#
        );
        let (r, report) = read(&text, &ShpOptions::default());
        let r = r.unwrap();
        assert_eq!(
            r.source_crs,
            Some(crate::crs::Crs::Utm {
                zone: 32,
                north: true
            })
        );
        let ids: Vec<String> = r.footprints.iter().map(|f| f.id.to_string()).collect();
        assert_eq!(ids, ["feature/0", "feature/1"]);
        assert!(report
            .entries
            .iter()
            .any(|e| e.reason.contains("not unique")));
    }

    #[test]
    fn broken_json_names_the_line_and_a_wrong_type_is_refused() {
        let (r, _) = read(
            "{\"type\":\"FeatureCollection\",\n\"features\":[{\"type\":",
            &ShpOptions::default(),
        );
        let e = r.unwrap_err().to_string();
        assert!(e.contains("f.geojson") && e.contains("line 2"), "{e}");
        let (r, _) = read(
            "{\"type\":\"Point\",\"coordinates\":[1,2]}",
            &ShpOptions::default(),
        );
        let e = r.unwrap_err().to_string();
        assert!(e.contains("FeatureCollection or a Feature"), "{e}");
        let (r, _) = read(
            "{\"type\":\"FeatureCollection\",\"features\":[]} trailing",
            &ShpOptions::default(),
        );
        assert!(r.is_err());
        let (r, _) = read(
            "{\"type\":\"FeatureCollection\",\"crs\":{\"type\":\"name\",\"properties\":{\"name\":\"EPSG:9999\"}},\"features\":[]}",
            &ShpOptions::default(),
        );
        assert!(r.unwrap_err().to_string().contains("--src-crs"));
    }

    #[test]
    fn a_single_feature_is_a_file_of_one() {
        let text = format!(
            r#"{{"type":"Feature","properties":{{"building:levels":"3"}},"geometry":{{"type":"Polygon","coordinates":{SQUARE}}}}}"#
        );
        let (r, _) = read(&text, &ShpOptions::default());
        let r = r.unwrap();
        assert_eq!(r.footprints.len(), 1);
        assert_eq!(r.footprints[0].tags.levels, Some(3.0));
    }
}
