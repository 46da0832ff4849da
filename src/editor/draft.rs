//! The knowledge base being edited: its text (the draft), the edits applied to it through
//! [`crate::kb::edit`], each checked as `kb check --strict` checks a file before it is taken,
//! what the page is shown of it, and the writes: the KB itself and rulesets in its folder.

use std::io::Read;
use std::path::{Component, Path, PathBuf};

use serde::Deserialize;
use serde_json::{json, Value};

use crate::grammar::GrammarError;
use crate::kb::edit::{self, AppearanceText, CircleText, EditError, NewShape, OpeningText};
use crate::kb::tools::{self, CheckReport};
use crate::kb::{write, KbError, KbRepair, KnowledgeBase, ReadMode};

/// Why the draft cannot be opened, an edit is refused, or a save or a ruleset is not written:
/// the message the page shows.
#[derive(Debug, thiserror::Error)]
pub enum DraftError {
    /// A file cannot be found or read.
    #[error("{}: {source}", .path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The system's error.
        source: std::io::Error,
    },
    /// The KB file has no folder.
    #[error("{}: no folder", .path.display())]
    NoFolder {
        /// The file.
        path: PathBuf,
    },
    /// The text does not read (in the draft's mode).
    #[error(transparent)]
    Kb(#[from] KbError),
    /// The text reads but has `kb check` errors: one `file:line: what` line each.
    #[error("{}", check_errors(.path, .errors))]
    Check {
        /// The KB file.
        path: PathBuf,
        /// The errors.
        errors: Vec<KbRepair>,
    },
    /// A lenient draft's strict form does not pass the check.
    #[error("the strict form of the draft does not pass the check: {0}")]
    StrictForm(Box<DraftError>),
    /// At save, the KB file is no longer the regular file in its folder that was opened (a
    /// symlink now, or its folder leads elsewhere): nothing is written.
    #[error("{}: not saved: {why}", .path.display())]
    NotInPlace {
        /// The KB file as given.
        path: PathBuf,
        /// What changed.
        why: String,
    },
    /// The file changed on disk since it was opened or saved.
    #[error("{} changed on disk since it was opened: not overwritten", .path.display())]
    Changed {
        /// The file.
        path: PathBuf,
    },
    /// A file could not be written: the message of `write_atomic`, which names it.
    #[error("{}: {source}", .path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// The system's error.
        source: std::io::Error,
    },
    /// An attribute name the editor may not write.
    #[error("{name:?} is not an attribute name")]
    AttributeName {
        /// The name.
        name: String,
    },
    /// A polygon point that is not finite.
    #[error("a polygon point is not a finite number")]
    PointNotFinite,
    /// No zone has this path.
    #[error("no zone {zone:?} in the draft")]
    NoZone {
        /// The path.
        zone: String,
    },
    /// Two zones start on one line: an edit could not tell them apart.
    #[error(
        "zones {zone:?} and {other:?} start on line {line}: put them on lines of their own to \
         edit them"
    )]
    SharedLine {
        /// The zone edited.
        zone: String,
        /// The other zone.
        other: String,
        /// The line.
        line: usize,
    },
    /// A new zone's name is empty, has a `/` or surrounding spaces.
    #[error("{designation:?} is not a zone name (not empty, no '/', no surrounding spaces)")]
    ZoneName {
        /// The name given.
        designation: String,
    },
    /// A new zone's path is taken.
    #[error("there is already a zone {zone:?}")]
    ZoneExists {
        /// The path.
        zone: String,
    },
    /// A new zone given neither or both of a circle and a polygon.
    #[error("a new zone needs a circle or a polygon (one)")]
    Shape,
    /// The text edit is refused.
    #[error(transparent)]
    Edit(#[from] EditError),
    /// A ruleset's text does not parse.
    #[error(transparent)]
    Ruleset(#[from] GrammarError),
    /// A ruleset path that is empty or absolute.
    #[error("ruleset {file:?}: give a path relative to the KB's folder")]
    RulesetNotRelative {
        /// The path given.
        file: String,
    },
    /// A ruleset path with `..`, `.` or a root.
    #[error("ruleset {file:?} climbs out of the KB's folder (no '..', '.' or root)")]
    RulesetClimbs {
        /// The path given.
        file: String,
    },
    /// A ruleset name not ending in `.cga`.
    #[error("ruleset {file:?}: the name must end in .cga")]
    RulesetExtension {
        /// The path given.
        file: String,
    },
    /// A ruleset path without a folder.
    #[error("ruleset {file:?}: no folder")]
    RulesetNoFolder {
        /// The path given.
        file: String,
    },
    /// A ruleset's folder cannot be resolved.
    #[error("ruleset {file:?}: its folder: {source}")]
    RulesetFolder {
        /// The path given.
        file: String,
        /// The system's error.
        source: std::io::Error,
    },
    /// A ruleset's folder outside the KB's (through a symlink).
    #[error("ruleset {file:?}: its folder lies outside the KB's folder (through a symlink)")]
    RulesetOutside {
        /// The path given.
        file: String,
    },
    /// A ruleset target that is a symlink.
    #[error("ruleset {file:?} is a symlink: not written")]
    RulesetSymlink {
        /// The path given.
        file: String,
    },
    /// A ruleset target that is not a file.
    #[error("ruleset {file:?} is not a file")]
    RulesetNotFile {
        /// The path given.
        file: String,
    },
}

/// The message of [`DraftError::Check`]: `file:line: what`, one line each.
fn check_errors(path: &Path, errors: &[KbRepair]) -> String {
    let list: Vec<String> = errors
        .iter()
        .map(|r| format!("{}:{}: {}", path.display(), r.line, r.what))
        .collect();
    list.join("\n")
}

/// The draft and where it came from.
pub(crate) struct Draft {
    /// The KB file, resolved (symlinks followed): the one file [`Draft::save`] writes.
    path: PathBuf,
    /// The KB file as given (for messages).
    given: PathBuf,
    /// Its folder, resolved: rulesets are written only inside it.
    dir: PathBuf,
    /// The draft's text.
    text: String,
    /// The file's bytes as last read or saved (a save refuses when the file changed since).
    on_disk: String,
    /// How edits are checked: strict when the file read strictly at the start.
    mode: ReadMode,
    /// Why the file did not read strictly (then `mode` is lenient and saving writes the strict
    /// form of the draft).
    strict_error: Option<String>,
    /// What the lenient reader repaired in the draft (empty once it reads strictly).
    repairs: Vec<KbRepair>,
    /// The draft parsed.
    kb: KnowledgeBase,
    /// `kb check` of the draft.
    report: CheckReport,
}

fn repairs_json(list: &[KbRepair]) -> Value {
    Value::Array(
        list.iter()
            .map(|r| json!({"line": r.line, "what": r.what}))
            .collect(),
    )
}

fn pairs_json(pairs: &[(String, String)]) -> Value {
    Value::Array(pairs.iter().map(|(k, v)| json!([k, v])).collect())
}

/// A circle as the page sends it.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CircleJson {
    lat: f64,
    lon: f64,
    /// Radius, km.
    dist: f64,
}

impl From<CircleJson> for CircleText {
    fn from(c: CircleJson) -> CircleText {
        CircleText {
            lat: c.lat,
            lon: c.lon,
            dist: c.dist,
        }
    }
}

/// One `<split>` as the page sends it.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct SplitJson {
    axis: String,
    parent: String,
    children: Vec<String>,
    values: Vec<f64>,
}

/// An `<opening>` as the page sends it.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct OpeningJson {
    root: String,
    splits: Vec<SplitJson>,
    terms: Vec<String>,
}

/// An appearance as the page sends it.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AppearanceJson {
    #[serde(default)]
    building: Option<String>,
    /// `[name, value]` pairs, `proba` among them.
    values: Vec<(String, String)>,
    #[serde(default)]
    opening: Option<OpeningJson>,
    #[serde(default)]
    ruleset: Option<String>,
}

/// One edit of the draft (`POST /api/edit`, docs/kb-editor.md). Zones are named by their
/// path (`earth/Monaco/Fontvieille`), appearances by their 0-based index in the zone.
#[derive(Clone, Debug, Deserialize)]
#[serde(tag = "op", rename_all = "snake_case", deny_unknown_fields)]
pub(crate) enum Edit {
    /// A new zone, last child of `parent`, with a circle or a polygon.
    AddZone {
        /// The parent zone's path.
        parent: String,
        /// `country`, `region`, `town`, `district`, `zone` or `continent`.
        element: String,
        /// Its name.
        designation: String,
        /// Its circle.
        #[serde(default)]
        circle: Option<CircleJson>,
        /// Or its polygon, `[lon, lat]` points.
        #[serde(default)]
        polygon: Option<Vec<[f64; 2]>>,
    },
    /// The zone and its sub-zones removed.
    DeleteZone {
        /// The zone's path.
        zone: String,
    },
    /// The zone's circle moved, resized or removed (`null`).
    SetCircle {
        /// The zone's path.
        zone: String,
        /// The new circle.
        circle: Option<CircleJson>,
    },
    /// A polygon replaced (`index`), removed (`points: null`) or added (`index: null`).
    SetPolygon {
        /// The zone's path.
        zone: String,
        /// 0-based polygon index; `null` adds one.
        #[serde(default)]
        index: Option<usize>,
        /// `[lon, lat]` points; `null` removes polygon `index`.
        points: Option<Vec<[f64; 2]>>,
    },
    /// `<info>` attributes set (`[name, value]`) or removed (`[name, null]`).
    SetInfo {
        /// The zone's path.
        zone: String,
        /// The changes.
        values: Vec<(String, Option<String>)>,
    },
    /// A new appearance after the zone's last one.
    AddAppearance {
        /// The zone's path.
        zone: String,
        /// The appearance.
        appearance: AppearanceJson,
    },
    /// Appearance `index` replaced by this one (its comments and `<selex>` kept).
    SetAppearance {
        /// The zone's path.
        zone: String,
        /// 0-based index among the zone's own appearances.
        index: usize,
        /// The appearance.
        appearance: AppearanceJson,
    },
    /// Appearance `index` removed.
    DeleteAppearance {
        /// The zone's path.
        zone: String,
        /// 0-based index among the zone's own appearances.
        index: usize,
    },
}

/// An attribute name the editor may write: an XML name of ASCII letters, digits, `_` and `-`.
fn check_name(name: &str) -> Result<(), DraftError> {
    let ok = name.chars().next().is_some_and(|c| c.is_ascii_alphabetic())
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-');
    if ok {
        Ok(())
    } else {
        Err(DraftError::AttributeName {
            name: name.to_string(),
        })
    }
}

fn points(p: &[[f64; 2]]) -> Result<Vec<(f64, f64)>, DraftError> {
    if p.iter().flatten().any(|x| !x.is_finite()) {
        return Err(DraftError::PointNotFinite);
    }
    Ok(p.iter().map(|[lon, lat]| (*lon, *lat)).collect())
}

impl From<AppearanceJson> for AppearanceText {
    fn from(a: AppearanceJson) -> AppearanceText {
        AppearanceText {
            building: a.building.filter(|b| !b.trim().is_empty()),
            values: a.values,
            opening: a.opening.map(|o| OpeningText {
                root: o.root,
                splits: o
                    .splits
                    .into_iter()
                    .map(|s| (s.axis, s.parent, s.children, s.values))
                    .collect(),
                terms: o.terms,
            }),
            ruleset: a.ruleset.filter(|r| !r.trim().is_empty()),
        }
    }
}

fn check_appearance(a: &AppearanceJson) -> Result<(), DraftError> {
    for (k, _) in &a.values {
        check_name(k)?;
    }
    Ok(())
}

impl Draft {
    /// Reads the KB at `path`. A file that does not read leniently is an error; one that reads
    /// only leniently is opened with its repairs listed and edits checked leniently; saving
    /// writes it in the strict format ([`Draft::save`]).
    pub(crate) fn open(path: &Path) -> Result<Draft, DraftError> {
        let io = |source| DraftError::Io {
            path: path.to_path_buf(),
            source,
        };
        let resolved = std::fs::canonicalize(path).map_err(io)?;
        let dir = resolved
            .parent()
            .map(Path::to_path_buf)
            .ok_or_else(|| DraftError::NoFolder {
                path: path.to_path_buf(),
            })?;
        let text = std::fs::read_to_string(&resolved).map_err(io)?;
        let (mode, strict_error, repairs) =
            match KnowledgeBase::parse_str_at(&text, &resolved, ReadMode::Strict) {
                Ok(_) => (ReadMode::Strict, None, Vec::new()),
                Err(e) => {
                    let (_, repairs) =
                        KnowledgeBase::parse_str_at(&text, &resolved, ReadMode::Lenient)?;
                    (ReadMode::Lenient, Some(e.to_string()), repairs)
                }
            };
        let (kb, report) = check(&text, &resolved, mode)?;
        Ok(Draft {
            path: resolved,
            given: path.to_path_buf(),
            dir,
            on_disk: text.clone(),
            text,
            mode,
            strict_error,
            repairs,
            kb,
            report,
        })
    }

    /// The draft's text.
    #[cfg(test)]
    pub(crate) fn text(&self) -> &str {
        &self.text
    }

    /// The KB file written by [`Draft::save`].
    #[cfg(test)]
    pub(crate) fn path(&self) -> &Path {
        &self.path
    }

    /// The draft parsed.
    #[cfg(test)]
    pub(crate) fn kb(&self) -> &KnowledgeBase {
        &self.kb
    }

    /// The draft parsed afresh (for a derivation that takes the KB).
    pub(crate) fn parsed(&self) -> Result<KnowledgeBase, DraftError> {
        check(&self.text, &self.path, self.mode).map(|(kb, _)| kb)
    }

    /// The line of zone `path`'s start tag (text edits find zones by it). Refused when another
    /// zone starts on the same line: an edit could not tell them apart.
    fn zone_line(&self, path: &str) -> Result<usize, DraftError> {
        let line = self
            .kb
            .find(path)
            .and_then(|i| self.kb.zone(i))
            .map(|z| z.line)
            .ok_or_else(|| DraftError::NoZone {
                zone: path.to_string(),
            })?;
        if let Some(other) = self
            .kb
            .zones()
            .iter()
            .find(|z| z.line == line && z.path != path)
        {
            return Err(DraftError::SharedLine {
                zone: path.to_string(),
                other: other.path.clone(),
                line,
            });
        }
        Ok(line)
    }

    /// Applies `e` to the draft. The edited text is checked ([`check`]: the strict reader and
    /// `kb check`'s errors); when it fails the draft is unchanged and the message says why.
    pub(crate) fn apply(&mut self, e: Edit) -> Result<(), DraftError> {
        let t = &self.text;
        let new = match e {
            Edit::AddZone {
                parent,
                element,
                designation,
                circle,
                polygon,
            } => {
                let name = designation.trim();
                if name.is_empty() || name.contains('/') || name != designation {
                    return Err(DraftError::ZoneName { designation });
                }
                let full = format!("{parent}/{name}");
                if self.kb.find(&full).is_some() {
                    return Err(DraftError::ZoneExists { zone: full });
                }
                let shape = match (circle, polygon) {
                    (Some(c), None) => NewShape::Circle(c.into()),
                    (None, Some(p)) => NewShape::Polygon(points(&p)?),
                    _ => return Err(DraftError::Shape),
                };
                edit::add_zone(t, self.zone_line(&parent)?, &element, name, &shape)?
            }
            Edit::DeleteZone { zone } => edit::delete_zone(t, self.zone_line(&zone)?)?,
            Edit::SetCircle { zone, circle } => {
                edit::set_circle(t, self.zone_line(&zone)?, circle.map(Into::into))?
            }
            Edit::SetPolygon {
                zone,
                index,
                points: p,
            } => {
                let p = p.as_deref().map(points).transpose()?;
                edit::set_polygon(t, self.zone_line(&zone)?, index, p.as_deref())?
            }
            Edit::SetInfo { zone, values } => {
                for (k, _) in &values {
                    check_name(k)?;
                }
                edit::set_info(t, self.zone_line(&zone)?, &values)?
            }
            Edit::AddAppearance { zone, appearance } => {
                check_appearance(&appearance)?;
                edit::add_appearance(t, self.zone_line(&zone)?, &appearance.into())?
            }
            Edit::SetAppearance {
                zone,
                index,
                appearance,
            } => {
                check_appearance(&appearance)?;
                edit::set_appearance(t, self.zone_line(&zone)?, index, &appearance.into())?
            }
            Edit::DeleteAppearance { zone, index } => {
                edit::delete_appearance(t, self.zone_line(&zone)?, index)?
            }
        };
        let (kb, report) = check(&new, &self.path, self.mode)?;
        if self.mode == ReadMode::Lenient {
            self.repairs.clone_from(&report.repairs);
        }
        self.text = new;
        self.kb = kb;
        self.report = report;
        Ok(())
    }

    /// Writes the draft over the KB file atomically (a temporary beside it, renamed). Refused
    /// when the draft does not pass the strict check, and when the file changed on disk since
    /// it was read or last saved.
    ///
    /// A draft read leniently is written in the strict format ([`write::to_strict`] of the
    /// draft's model: the lenient reader's repairs applied, comments lost); after the save the
    /// draft is that text, read strictly, and later edits keep its bytes as for any strict KB.
    pub(crate) fn save(&mut self) -> Result<(), DraftError> {
        let (text, (kb, report)) = match self.mode {
            ReadMode::Strict => {
                let read = check(&self.text, &self.path, ReadMode::Strict)?;
                (self.text.clone(), read)
            }
            ReadMode::Lenient => {
                let text = write::to_strict(&self.kb).text;
                let read = check(&text, &self.path, ReadMode::Strict)
                    .map_err(|e| DraftError::StrictForm(Box::new(e)))?;
                (text, read)
            }
        };
        let now = self.read_in_place()?;
        if now != self.on_disk.as_bytes() {
            return Err(DraftError::Changed {
                path: self.path.clone(),
            });
        }
        write_atomic(&self.path, text.as_bytes())?;
        self.on_disk.clone_from(&text);
        self.text = text;
        self.kb = kb;
        self.report = report;
        self.mode = ReadMode::Strict;
        self.strict_error = None;
        self.repairs.clear();
        Ok(())
    }

    /// The KB file's bytes now, read only if it is still the regular file in the KB's folder
    /// that was opened: not a symlink (to a file outside or anywhere), its folder still the
    /// same folder. The save then renames a new file over that name, never writing through it.
    fn read_in_place(&self) -> Result<Vec<u8>, DraftError> {
        let refused = |why: String| DraftError::NotInPlace {
            path: self.given.clone(),
            why,
        };
        let io = |source| DraftError::Io {
            path: self.given.clone(),
            source,
        };
        let folder = self.path.parent().unwrap_or(&self.dir);
        match std::fs::canonicalize(folder) {
            Ok(real) if real == self.dir => {}
            Ok(real) => {
                return Err(refused(format!(
                    "its folder {} now leads to {}",
                    self.dir.display(),
                    real.display()
                )))
            }
            Err(source) => return Err(io(source)),
        }
        let meta = std::fs::symlink_metadata(&self.path).map_err(io)?;
        if meta.file_type().is_symlink() {
            let to = std::fs::read_link(&self.path)
                .map(|t| format!(" (to {})", t.display()))
                .unwrap_or_default();
            return Err(refused(format!(
                "it was replaced by a symlink{to} while it was edited"
            )));
        }
        if !meta.is_file() {
            return Err(refused("it is no longer a regular file".into()));
        }
        let file = crate::fsio::open_inside(&self.dir, &self.path)
            .map_err(|e| refused(format!("it cannot be opened in its folder: {e}")))?;
        // One byte over what was read at the start is enough to see that it changed.
        let cap = self.on_disk.len() as u64 + 1;
        let mut bytes = Vec::new();
        file.take(cap).read_to_end(&mut bytes).map_err(io)?;
        Ok(bytes)
    }

    /// Writes a ruleset `file` (relative to the KB's folder, `.cga`) with `text`, which must
    /// parse. Refused: absolute paths, `..`, a folder that is not inside the KB's (symlinks
    /// resolved), a target that is a symlink or not a file.
    pub(crate) fn write_ruleset(&self, file: &str, text: &str) -> Result<PathBuf, DraftError> {
        let target = ruleset_target(&self.dir, file)?;
        crate::grammar::parse(text, file)?;
        write_atomic(&target, text.as_bytes())?;
        Ok(target)
    }

    /// What the page shows: the zone tree with shapes, own and inherited values (with the zone
    /// each comes from), appearances; the check's warnings and errors; the lenient repairs.
    pub(crate) fn state(&self) -> Value {
        let texts = edit::zone_texts(&self.text).unwrap_or_default();
        let kb = &self.kb;
        let zones: Vec<Value> = kb
            .zones()
            .iter()
            .enumerate()
            .map(|(i, z)| {
                let own = texts.get(&z.line).cloned().unwrap_or_default();
                let (owner, _) = kb.appearances_for(i);
                let appearances: Vec<Value> = own
                    .appearances
                    .iter()
                    .zip(&z.appearances)
                    .map(|(t, a)| {
                        json!({
                            "building": t.building,
                            "values": pairs_json(&t.values),
                            "proba": a.proba,
                            "opening": a.opening.as_ref().map(|o| json!({
                                "root": o.root,
                                "terms": o.terms,
                                "splits": o.splits.iter().map(|s| json!({
                                    "axis": s.axis.as_str(),
                                    "parent": s.parent,
                                    "children": s.children,
                                    "values": s.fractions,
                                })).collect::<Vec<_>>(),
                            })),
                            "ruleset": t.ruleset,
                            "selex": t.selex,
                            "line": a.line,
                        })
                    })
                    .collect();
                json!({
                    "path": z.path,
                    "name": z.name,
                    "element": z.kind.as_str(),
                    "depth": z.depth,
                    "parent": z.parent.map(|p| kb.zone_path(p)),
                    "line": z.line,
                    "circle": z.circle.map(|c| json!({"lat": c.lat, "lon": c.lon, "dist": c.radius_km})),
                    "polygons": z.polygons.iter().map(|p| p.ring.clone()).collect::<Vec<_>>(),
                    "info": pairs_json(&own.info),
                    "location": own.location.as_deref().map(pairs_json),
                    "resolved": tools::zone_values(kb, i).iter().map(|v| json!({
                        "attribute": v.attribute, "value": v.value, "from": v.from,
                    })).collect::<Vec<_>>(),
                    "appearances": appearances,
                    "appearances_from": kb.zone_path(owner),
                })
            })
            .collect();
        json!({
            "file": self.path.file_name().map(|n| n.to_string_lossy().into_owned()),
            "mode": match self.mode { ReadMode::Strict => "strict", ReadMode::Lenient => "lenient" },
            "strict_error": self.strict_error,
            "dirty": self.text != self.on_disk,
            "repairs": repairs_json(&self.repairs),
            "conversion": match self.mode {
                ReadMode::Strict => Value::Array(Vec::new()),
                ReadMode::Lenient => repairs_json(&write::to_strict(kb).notes),
            },
            "errors": repairs_json(&self.report.errors),
            "warnings": repairs_json(&self.report.warnings),
            "zones": zones,
        })
    }
}

/// The draft text read as `kb check` reads the file at `path` in `mode`: the reader, then
/// the check's errors (a ruleset or SELEX program outside the folder, a SELEX program that
/// does not parse). `Err` is the message to show.
pub fn check(
    text: &str,
    path: &Path,
    mode: ReadMode,
) -> Result<(KnowledgeBase, CheckReport), DraftError> {
    let (kb, repairs) = KnowledgeBase::parse_str_at(text, path, mode)?;
    let report = tools::report_for(&kb, mode, repairs, false);
    if report.has_errors() {
        return Err(DraftError::Check {
            path: path.to_path_buf(),
            errors: report.errors,
        });
    }
    Ok((kb, report))
}

/// Where ruleset `file` goes in `dir` (resolved), or why it may not.
fn ruleset_target(dir: &Path, file: &str) -> Result<PathBuf, DraftError> {
    let rel = Path::new(file);
    let file = file.to_string();
    if file.is_empty() || rel.is_absolute() {
        return Err(DraftError::RulesetNotRelative { file });
    }
    if !rel.components().all(|c| matches!(c, Component::Normal(_))) {
        return Err(DraftError::RulesetClimbs { file });
    }
    if rel.extension().and_then(|e| e.to_str()) != Some("cga") {
        return Err(DraftError::RulesetExtension { file });
    }
    let target = dir.join(rel);
    let Some(parent) = target.parent() else {
        return Err(DraftError::RulesetNoFolder { file });
    };
    let real_parent = match std::fs::canonicalize(parent) {
        Ok(p) => p,
        Err(source) => return Err(DraftError::RulesetFolder { file, source }),
    };
    if !real_parent.starts_with(dir) {
        return Err(DraftError::RulesetOutside { file });
    }
    match std::fs::symlink_metadata(&target) {
        Ok(m) if m.file_type().is_symlink() => Err(DraftError::RulesetSymlink { file }),
        Ok(m) if !m.is_file() => Err(DraftError::RulesetNotFile { file }),
        _ => Ok(real_parent.join(rel.file_name().unwrap_or_default())),
    }
}

/// [`crate::fsio::write_atomic`], its error naming `path` whatever failed.
fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), DraftError> {
    crate::fsio::write_atomic(path, bytes).map_err(|e| DraftError::Write {
        path: path.to_path_buf(),
        source: e.error,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn draft_of(text: &str) -> (tempfile::TempDir, Draft) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("kb.xml");
        std::fs::write(&path, text).unwrap();
        let d = Draft::open(&path).unwrap();
        (dir, d)
    }

    fn set_info(zone: &str, k: &str, v: &str) -> Edit {
        Edit::SetInfo {
            zone: zone.into(),
            values: vec![(k.into(), Some(v.into()))],
        }
    }

    #[test]
    fn zones_sharing_a_line_are_not_edited() {
        let text = "<earth>\n  <town designation=\"A\"/><town designation=\"B\"/>\n  <town designation=\"C\"/>\n</earth>\n";
        let (_dir, mut d) = draft_of(text);
        let e = d
            .apply(set_info("earth/B", "nbfloor", "3"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 2"), "{e}");
        assert!(d.apply(set_info("earth/A", "nbfloor", "3")).is_err());
        assert_eq!(d.text(), text);
        d.apply(set_info("earth/C", "nbfloor", "3")).unwrap();
        assert!(
            d.text()
                .contains("<town designation=\"C\">\n    <info nbfloor=\"3\"/>\n  </town>"),
            "{}",
            d.text()
        );
    }

    #[test]
    fn a_lenient_file_is_saved_in_the_strict_format_then_edited_as_text() {
        let text = "<earth>\n  <!-- lost -->\n  <info nbfloor=\"2\" floorsize=\"3,5\"/>\n  <town designation=\"C\"/>\n</earth>\n";
        let (_dir, mut d) = draft_of(text);
        let st = d.state();
        assert_eq!(st["mode"], "lenient");
        assert!(st["strict_error"].as_str().is_some());
        let repairs = st["repairs"].as_array().map_or(0, Vec::len);
        assert!(repairs > 0, "{st}");
        assert_eq!(st["conversion"].as_array().map(Vec::len), Some(0), "{st}");
        d.apply(set_info("earth/C", "nbfloor", "3")).unwrap();
        let lenient = d.kb().zones().to_vec();
        d.save().unwrap();
        let saved = std::fs::read_to_string(d.path()).unwrap();
        assert_eq!(saved, d.text());
        assert!(
            !saved.contains("lost") && saved.contains("floorsize=\"3.5\""),
            "{saved}"
        );
        let (kb, _) = KnowledgeBase::parse_str_with(&saved, "s.xml", ReadMode::Strict).unwrap();
        let strip = |zs: &[crate::kb::Zone]| {
            zs.iter()
                .map(|z| {
                    (
                        z.path.clone(),
                        z.info.clone(),
                        z.circle,
                        z.appearances.len(),
                    )
                })
                .collect::<Vec<_>>()
        };
        assert_eq!(strip(kb.zones()), strip(&lenient));
        let st = d.state();
        assert_eq!(st["mode"], "strict");
        assert!(st["strict_error"].is_null() && st["dirty"] == false, "{st}");
        assert_eq!(st["repairs"].as_array().map(Vec::len), Some(0));
        // Now a strict draft: an edit changes only its own line.
        d.apply(set_info("earth/C", "nbfloor", "4")).unwrap();
        let changed: Vec<_> = saved
            .lines()
            .zip(d.text().lines())
            .filter(|(a, b)| a != b)
            .collect();
        assert_eq!(changed.len(), 1, "{changed:?}");
        assert_eq!(saved.lines().count(), d.text().lines().count());
    }

    #[test]
    fn a_lenient_save_is_refused_when_the_file_changed_on_disk() {
        let text = "<earth>\n  <info floorsize=\"3,5\"/>\n</earth>\n";
        let (_dir, mut d) = draft_of(text);
        std::fs::write(d.path(), "<earth/>\n").unwrap();
        let e = d.save().unwrap_err().to_string();
        assert!(e.contains("changed on disk"), "{e}");
        assert_eq!(std::fs::read_to_string(d.path()).unwrap(), "<earth/>\n");
        assert_eq!(d.state()["mode"], "lenient");
    }
}
