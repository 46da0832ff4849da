//! Edits of a knowledge-base file's text that keep everything else of it byte for byte
//! (comments, order, spacing): appearances added to a zone (`citygen evolve --into-kb`).
//!
//! The file is read with quick-xml only to find places: the zone's element (by the line its
//! start tag is on, [`super::Zone::line`]), its direct `<appearance>` children and their
//! `<values>` attributes, and where new appearances go (after the zone's last appearance, or
//! after its `info`, `location` and `polygon` children when it has none: the order the format
//! asks for). The caller checks the result with the strict reader before writing it.

use quick_xml::events::Event;
use quick_xml::Reader;

/// An appearance to add.
#[derive(Clone, Debug, PartialEq)]
pub struct NewAppearance {
    /// Its `proba`.
    pub proba: f64,
    /// Its `<values>` attributes besides `proba`, in order (raw attribute values, escaped as
    /// in XML).
    pub values: Vec<(String, String)>,
    /// Its `<ruleset file>`, relative to the KB's folder.
    pub ruleset: String,
    /// A comment written above it (without `--`).
    pub comment: Option<String>,
}

/// A zone's direct `<appearance>` children as the text has them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ZoneAppearances {
    /// Each appearance's `<values>` attributes (raw), in order, with `proba` among them.
    pub values: Vec<Vec<(String, String)>>,
    /// Each appearance's `building` attribute (raw), if any.
    pub buildings: Vec<Option<String>>,
}

/// Where things are in the zone's element.
struct Places {
    /// Byte offset of the zone's start tag.
    start: usize,
    /// For an empty element (`<town .../>`): the offset of its `/>`.
    empty_close: Option<usize>,
    /// Byte offset right after the last child that new appearances follow (or after the
    /// zone's start tag).
    insert_at: usize,
    /// The zone's own indentation (spaces and tabs before its start tag on its line).
    indent: String,
    /// The zone's element name.
    name: String,
    found: ZoneAppearances,
}

/// Whether an element is a zone: every element but the format's others (any element with a
/// `designation` is a zone, [`super::ZoneKind::Other`]).
fn is_zone(name: &str) -> bool {
    !matches!(
        name.to_ascii_lowercase().as_str(),
        "info"
            | "location"
            | "polygon"
            | "appearance"
            | "values"
            | "opening"
            | "split"
            | "elements"
            | "ruleset"
            | "selex"
    )
}

fn line_of(text: &str, offset: usize) -> usize {
    1 + text
        .as_bytes()
        .iter()
        .take(offset)
        .filter(|&&b| b == b'\n')
        .count()
}

fn attrs(e: &quick_xml::events::BytesStart<'_>) -> Result<Vec<(String, String)>, String> {
    e.attributes()
        .map(|a| {
            let a = a.map_err(|e| e.to_string())?;
            let key = AsRef::<str>::as_ref(&a.key).to_string();
            let value = a.value.to_string();
            Ok((key, value))
        })
        .collect()
}

fn places(text: &str, zone_line: usize) -> Result<Places, String> {
    let mut reader = Reader::from_str(text);
    let mut depth = 0usize;
    // (depth of the zone's children, zone start, name, indent)
    let mut zone: Option<(usize, usize, String, String)> = None;
    let mut insert_at = 0usize;
    let mut after_shapes = true;
    let mut found = ZoneAppearances::default();
    let mut in_appearance = false;
    loop {
        let before = usize::try_from(reader.buffer_position()).unwrap_or(usize::MAX);
        let ev = reader.read_event().map_err(|e| {
            format!(
                "line {}: {e}",
                line_of(text, usize::try_from(reader.error_position()).unwrap_or(0))
            )
        })?;
        let after = usize::try_from(reader.buffer_position()).unwrap_or(usize::MAX);
        // Leading whitespace is part of the text event before a tag: the tag starts at the '<'.
        let tag_at = text
            .get(before..after)
            .and_then(|s| s.find('<'))
            .map_or(before, |i| before + i);
        match &ev {
            Event::Start(e) | Event::Empty(e) => {
                let name = AsRef::<str>::as_ref(&e.name()).to_string();
                let empty = matches!(ev, Event::Empty(_));
                match &zone {
                    None if line_of(text, tag_at) == zone_line && is_zone(&name) => {
                        let line_start = text[..tag_at].rfind('\n').map_or(0, |i| i + 1);
                        let indent: String = text[line_start..tag_at]
                            .chars()
                            .take_while(|c| *c == ' ' || *c == '\t')
                            .collect();
                        if empty {
                            let close = text[..after].rfind("/>").unwrap_or(after);
                            return Ok(Places {
                                start: tag_at,
                                empty_close: Some(close),
                                insert_at: after,
                                indent,
                                name,
                                found,
                            });
                        }
                        zone = Some((depth + 1, tag_at, name, indent));
                        insert_at = after;
                    }
                    Some((d, ..)) if depth == *d => {
                        if name == "appearance" {
                            found.values.push(Vec::new());
                            found.buildings.push(
                                attrs(e)?
                                    .into_iter()
                                    .find(|(k, _)| k == "building")
                                    .map(|(_, v)| v),
                            );
                            in_appearance = !empty;
                            if empty {
                                insert_at = after;
                            }
                            after_shapes = false;
                        } else if after_shapes
                            && matches!(name.as_str(), "info" | "location" | "polygon")
                            && empty
                        {
                            insert_at = after;
                        } else if is_zone(&name) {
                            // Child zones come after the appearances.
                            after_shapes = false;
                        }
                    }
                    Some((d, ..)) if depth == *d + 1 && in_appearance && name == "values" => {
                        if let Some(v) = found.values.last_mut() {
                            *v = attrs(e)?;
                        }
                    }
                    _ => {}
                }
                if !empty {
                    depth += 1;
                }
            }
            Event::End(e) => {
                depth = depth.saturating_sub(1);
                let name = AsRef::<str>::as_ref(&e.name()).to_string();
                if let Some((d, start, zname, indent)) = &zone {
                    if depth == *d && in_appearance && name == "appearance" {
                        in_appearance = false;
                        insert_at = after;
                    } else if depth == *d
                        && after_shapes
                        && matches!(name.as_str(), "info" | "location" | "polygon")
                    {
                        insert_at = after;
                    } else if depth + 1 == *d {
                        // The zone's own end tag.
                        return Ok(Places {
                            start: *start,
                            empty_close: None,
                            insert_at,
                            indent: indent.clone(),
                            name: zname.clone(),
                            found,
                        });
                    }
                }
            }
            Event::Eof => break,
            _ => {}
        }
    }
    Err(format!("no zone element starts on line {zone_line}"))
}

/// The direct appearances of the zone whose start tag is on `zone_line`.
pub fn zone_appearances(text: &str, zone_line: usize) -> Result<ZoneAppearances, String> {
    places(text, zone_line).map(|p| p.found)
}

fn escape_attr(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('"', "&quot;")
}

/// `text` with `new` appearances added to the zone whose start tag is on `zone_line`, after
/// its last appearance (or its shapes), indented one step (two spaces) deeper than the zone.
pub fn add_appearances(
    text: &str,
    zone_line: usize,
    new: &[NewAppearance],
) -> Result<String, String> {
    let p = places(text, zone_line)?;
    let inner = format!("{}  ", p.indent);
    let mut add = String::new();
    for a in new {
        if let Some(c) = &a.comment {
            add.push_str(&format!(
                "\n{inner}<!-- {} -->",
                c.replace("--", "- -").trim()
            ));
        }
        let mut values = format!("<values proba=\"{}\"", fmt_proba(a.proba));
        for (k, v) in &a.values {
            if k != "proba" {
                values.push_str(&format!(" {k}=\"{}\"", escape_attr(v)));
            }
        }
        values.push_str("/>");
        add.push_str(&format!(
            "\n{inner}<appearance>{values}<ruleset file=\"{}\"/></appearance>",
            escape_attr(&a.ruleset)
        ));
    }
    let mut out = String::with_capacity(text.len() + add.len() + 64);
    match p.empty_close {
        Some(close) => {
            // <town .../> becomes <town ...> + appearances + </town>.
            out.push_str(text[..close].trim_end());
            out.push('>');
            out.push_str(&add);
            out.push_str(&format!("\n{}</{}>", p.indent, p.name));
            out.push_str(&text[p.insert_at..]);
        }
        None => {
            out.push_str(&text[..p.insert_at]);
            out.push_str(&add);
            out.push_str(&text[p.insert_at..]);
        }
    }
    let _ = p.start;
    Ok(out)
}

/// A probability as the KB writes it: at most 6 decimals, no trailing zeros.
fn fmt_proba(p: f64) -> String {
    let s = format!("{:.6}", p.clamp(0.0, 1.0));
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s.is_empty() {
        "0".into()
    } else {
        s.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const KB: &str = r##"<earth>
  <!-- a comment kept -->
  <info nbfloor="2"/>
  <country designation="X">
    <info lat="1" lon="2" dist="3"/>
    <appearance building="house"><values proba="0.7" color="red"/></appearance>
    <appearance>
      <values proba="0.3" color="#fff" bdRooftype="flat"/>
    </appearance>
    <town designation="T"/>
    <town designation="U">
      <info lat="1" lon="2" dist="1"/>
    </town>
  </country>
</earth>
"##;

    fn new(p: f64) -> NewAppearance {
        NewAppearance {
            proba: p,
            values: vec![
                ("color".into(), "#fff".into()),
                ("proba".into(), "9".into()),
            ],
            ruleset: "evolved/a.cga".into(),
            comment: Some("evolved -- hsym".into()),
        }
    }

    #[test]
    fn a_zones_appearances_are_read_with_their_values() {
        let z = zone_appearances(KB, 4).unwrap();
        assert_eq!(z.values.len(), 2);
        assert_eq!(z.values[1][1], ("color".into(), "#fff".into()));
        assert_eq!(z.buildings, vec![Some("house".into()), None]);
        assert_eq!(zone_appearances(KB, 10).unwrap().values.len(), 0);
        assert!(zone_appearances(KB, 3).is_err(), "line 3 starts no zone");
    }

    #[test]
    fn appearances_go_after_the_last_one_and_the_rest_is_kept() {
        let out = add_appearances(KB, 4, &[new(0.25)]).unwrap();
        let at = out
            .find("</appearance>\n    <!-- evolved - - hsym -->")
            .unwrap();
        assert!(at > out.find("bdRooftype=\"flat\"").unwrap());
        assert!(out.contains(
            "\n    <appearance><values proba=\"0.25\" color=\"#fff\"/><ruleset file=\"evolved/a.cga\"/></appearance>\n    <town designation=\"T\"/>"
        ));
        // Everything else byte for byte.
        let removed = out.replace(
            "\n    <!-- evolved - - hsym -->\n    <appearance><values proba=\"0.25\" color=\"#fff\"/><ruleset file=\"evolved/a.cga\"/></appearance>",
            "",
        );
        assert_eq!(removed, KB);
        let (kb, _) = crate::kb::KnowledgeBase::parse_str(&out, "kb.xml").unwrap();
        let x = crate::kb::tools::find_zone(&kb, "earth/X").unwrap();
        assert_eq!(kb.zones()[x].appearances.len(), 3);
    }

    #[test]
    fn a_zone_without_appearances_or_an_empty_element_takes_them_too() {
        let out = add_appearances(KB, 11, &[new(1.0)]).unwrap();
        assert!(out.contains("dist=\"1\"/>\n      <!--"), "{out}");
        let out = add_appearances(KB, 10, &[new(0.5), new(0.5)]).unwrap();
        assert!(
            out.contains("<town designation=\"T\">\n      <!--"),
            "{out}"
        );
        assert!(out.contains("</appearance>\n    </town>\n    <town designation=\"U\">"));
        let (kb, _) = crate::kb::KnowledgeBase::parse_str(&out, "kb.xml").unwrap();
        let t = crate::kb::tools::find_zone(&kb, "earth/X/T").unwrap();
        assert_eq!(kb.zones()[t].appearances.len(), 2);
        assert_eq!(
            kb.zones()[t].appearances[0].ruleset.as_deref(),
            Some("evolved/a.cga")
        );
    }

    #[test]
    fn probabilities_are_written_short() {
        assert_eq!(fmt_proba(0.25), "0.25");
        assert_eq!(fmt_proba(1.0), "1");
        assert_eq!(fmt_proba(1.0 / 3.0), "0.333333");
        assert_eq!(fmt_proba(0.0), "0");
    }
}
