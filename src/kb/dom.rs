//! What the two knowledge-base readers share: the element tree of a KB file (quick-xml events
//! with the place of every element and attribute), the errors, the modes and the size caps.
//! The lenient reader ([`super::xml`]) repairs the text before building the tree; the strict
//! one ([`super::strict`]) checks the tree against the clean format.

use std::fmt;

use quick_xml::events::{BytesStart, Event};
use quick_xml::{Reader, XmlVersion};

/// Why a knowledge base could not be read. Every variant names the file and, where there is
/// one, the place.
#[derive(Debug, thiserror::Error)]
pub enum KbError {
    /// The file could not be read.
    #[error("{file}: cannot read the knowledge base: {source}")]
    Io {
        /// The knowledge base as messages name it: the path given to `KnowledgeBase::load`, or the
        /// name given to `KnowledgeBase::parse_str`.
        file: String,
        /// The underlying I/O error; invalid UTF-8 is reported here too, as `InvalidData` with
        /// the byte offset where the text stops being UTF-8.
        #[source]
        source: std::io::Error,
    },
    /// Not well-formed XML (after the lenient pre-pass).
    #[error("{file}:{line}:{col}: malformed knowledge-base XML: {message}")]
    Xml {
        /// The knowledge base as messages name it (see [`KbError::Io`]).
        file: String,
        /// 1-based line of the fault.
        line: usize,
        /// 1-based column of the fault, in characters.
        col: usize,
        /// The XML parser's description, or ours (e.g. `element <town> is never closed`).
        message: String,
    },
    /// A `<!DOCTYPE>`: refused, so that no entity is ever expanded.
    #[error(
        "{file}:{line}:{col}: DOCTYPE declarations are not allowed in a knowledge base \
         (entities are never expanded); remove the <!DOCTYPE ...> block"
    )]
    Doctype {
        /// The knowledge base as messages name it (see [`KbError::Io`]).
        file: String,
        /// 1-based line of the `<!DOCTYPE`.
        line: usize,
        /// 1-based column of the `<!DOCTYPE`, in characters.
        col: usize,
    },
    /// Something the lenient reader would repair, refused by the strict reader
    /// ([`ReadMode::Strict`]): a decimal comma, an unknown or wrongly-cased attribute or
    /// element, missing quotes, an empty value, a value of the wrong type.
    #[error("{file}:{line}:{col}: not a valid knowledge base (strict mode): {message}")]
    Strict {
        /// The knowledge base as messages name it (see [`KbError::Io`]).
        file: String,
        /// 1-based line of what was refused.
        line: usize,
        /// 1-based column of what was refused, in characters.
        col: usize,
        /// What was refused and why, e.g. `CDATA sections are not allowed`.
        message: String,
    },
    /// A safety limit was exceeded: a file over 64 MiB (`MAX_FILE_BYTES`), elements nested more
    /// than 64 deep (`MAX_DEPTH`) or more than 256 attributes on one element (`MAX_ATTRIBUTES`).
    /// A `<polygon>` of more than 4096 points (`MAX_POLYGON_POINTS`) is not a `Limit`: the
    /// lenient reader ignores it with a repair, the strict one refuses it as [`KbError::Strict`].
    #[error("{file}:{line}:{col}: knowledge base refused: {message}")]
    Limit {
        /// The knowledge base as messages name it (see [`KbError::Io`]).
        file: String,
        /// 1-based line of the element over the limit (1 for a file over the 64 MiB cap).
        line: usize,
        /// 1-based column of that element, in characters (1 for a file over the 64 MiB cap).
        col: usize,
        /// Which limit and the value that broke it, e.g. `elements nested more than 64 levels deep`.
        message: String,
    },
    /// A zone path (`kb compile --zone`) that names no zone of the KB.
    #[error("{file}: no zone '{path}' (paths are designations from earth down, e.g. {examples})")]
    UnknownZone {
        /// The knowledge base as messages name it (see [`KbError::Io`]).
        file: String,
        /// The zone path as given on the command line.
        path: String,
        /// Up to six zone paths of the KB (without the leading `earth/`), comma-separated, to show
        /// the expected form.
        examples: String,
    },
    /// Well-formed XML that is not a knowledge base (wrong root, ...).
    #[error("{file}:{line}: {message}")]
    Structure {
        /// The knowledge base as messages name it (see [`KbError::Io`]).
        file: String,
        /// 1-based line of the element at fault (1 when the file holds no element).
        line: usize,
        /// What is wrong, e.g. `the root element must be <earth>, found <country>`.
        message: String,
    },
}

/// Largest knowledge-base file read, bytes (64 MiB). A real KB is a few hundred kilobytes; the
/// cap bounds memory and time on hostile or mistaken input (a PBF passed as `--kb`).
pub(crate) const MAX_FILE_BYTES: u64 = 64 * 1024 * 1024;
/// Deepest element nesting accepted (earth is level 1). The zone tree plus appearance, opening
/// and split levels needs about 12; 64 leaves room while bounding the recursive reader.
pub const MAX_DEPTH: usize = 64;
/// Most attributes on one element. `<values>` has about 20 legitimate ones.
pub(crate) const MAX_ATTRIBUTES: usize = 256;
/// Most vertices in one `<polygon points>`: bounds the simple-ring check (quadratic) and the
/// point-in-polygon test.
pub(crate) const MAX_POLYGON_POINTS: usize = 4096;

/// How forgiving the reader is.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ReadMode {
    /// Repairs legacy files such as the thesis annex and reports every repair
    /// ([`KbRepair`]); only what cannot be repaired is an error.
    #[default]
    Lenient,
    /// Our clean format only (schemas/kb.xsd): anything the lenient reader would repair is a
    /// [`KbError::Strict`] at its file:line:col. A file read in this mode has no repairs.
    Strict,
}

/// One thing the lenient reader repaired or ignored, at a 1-based line of the file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct KbRepair {
    /// 1-based line of the file where the repair was made (for `kb check`'s errors and
    /// warnings, the line of the element concerned).
    pub line: usize,
    /// What was repaired or ignored and how, e.g. `roof 'hip' read as hipped`.
    pub what: String,
}

impl fmt::Display for KbRepair {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "line {}: {}", self.line, self.what)
    }
}

/// Byte offset → (line, column), both 1-based; the column counts characters.
pub(crate) struct LineIndex<'a> {
    text: &'a str,
    starts: Vec<usize>,
}

impl<'a> LineIndex<'a> {
    pub(crate) fn new(text: &'a str) -> Self {
        let mut starts = vec![0];
        starts.extend(
            text.bytes()
                .enumerate()
                .filter(|(_, b)| *b == b'\n')
                .map(|(i, _)| i + 1),
        );
        LineIndex { text, starts }
    }

    pub(crate) fn line_col(&self, offset: usize) -> (usize, usize) {
        let offset = offset.min(self.text.len());
        let line = self.starts.partition_point(|&s| s <= offset).max(1);
        let start = self.starts.get(line - 1).copied().unwrap_or(0);
        let col = self
            .text
            .get(start..offset)
            .map_or(offset - start, |s| s.chars().count())
            + 1;
        (line, col)
    }

    pub(crate) fn line(&self, offset: usize) -> usize {
        self.line_col(offset).0
    }
}

/// A parsed element: name, attributes (name, value, line) and children.
#[derive(Debug)]
pub(crate) struct Elem {
    pub(crate) name: String,
    pub(crate) line: usize,
    pub(crate) col: usize,
    pub(crate) attrs: Vec<(String, String, usize)>,
    /// Column of each attribute's name, parallel to `attrs`.
    pub(crate) attr_cols: Vec<usize>,
    pub(crate) children: Vec<Elem>,
}

impl Elem {
    pub(crate) fn attr(&self, key: &str) -> Option<&(String, String, usize)> {
        self.attrs
            .iter()
            .rev()
            .find(|(k, _, _)| k.eq_ignore_ascii_case(key))
    }
}

/// Step 2: the element tree of the (repaired) text. Enforces [`MAX_DEPTH`] and
/// [`MAX_ATTRIBUTES`]; in strict mode text content (other than whitespace) is an error, since no
/// element of the format has any (it is what a lost `<` leaves behind).
pub(crate) fn parse_tree(text: &str, file: &str, mode: ReadMode) -> Result<Elem, KbError> {
    let idx = LineIndex::new(text);
    let mut reader = Reader::from_str(text);
    reader.config_mut().check_end_names = true;
    let mut stack: Vec<Elem> = Vec::new();
    let mut root: Option<Elem> = None;
    let xml_err = |pos: u64, message: String| {
        let (line, col) = idx.line_col(usize::try_from(pos).unwrap_or(usize::MAX));
        KbError::Xml {
            file: file.to_string(),
            line,
            col,
            message,
        }
    };
    loop {
        let before = usize::try_from(reader.buffer_position()).unwrap_or(usize::MAX);
        let ev = reader
            .read_event()
            .map_err(|e| xml_err(reader.error_position(), e.to_string()))?;
        let after = usize::try_from(reader.buffer_position()).unwrap_or(usize::MAX);
        match ev {
            Event::Start(e) | Event::Empty(e) if root.is_some() => {
                let _ = e;
                return Err(xml_err(
                    before as u64,
                    "content after the root element".into(),
                ));
            }
            Event::Start(ref e) | Event::Empty(ref e) => {
                if stack.len() >= MAX_DEPTH {
                    let (line, col) = idx.line_col(before);
                    return Err(KbError::Limit {
                        file: file.to_string(),
                        line,
                        col,
                        message: format!("elements nested more than {MAX_DEPTH} levels deep"),
                    });
                }
                let el = element(e, text, before, after, &idx, file)?;
                if matches!(ev, Event::Start(_)) {
                    stack.push(el);
                } else if let Some(parent) = stack.last_mut() {
                    parent.children.push(el);
                } else {
                    root = Some(el);
                }
            }
            Event::End(_) => {
                let Some(el) = stack.pop() else {
                    return Err(xml_err(
                        before as u64,
                        "closing tag without an opening tag".into(),
                    ));
                };
                match stack.last_mut() {
                    Some(parent) => parent.children.push(el),
                    None => root = Some(el),
                }
            }
            Event::DocType(_) => {
                let (line, col) = idx.line_col(before);
                return Err(KbError::Doctype {
                    file: file.to_string(),
                    line,
                    col,
                });
            }
            Event::Text(t) if root.is_some() && !AsRef::<str>::as_ref(&t).trim().is_empty() => {
                return Err(xml_err(before as u64, "text after the root element".into()));
            }
            Event::Text(ref t)
                if mode == ReadMode::Strict && !AsRef::<str>::as_ref(t).trim().is_empty() =>
            {
                let raw: &str = t.as_ref();
                let lead = raw.len() - raw.trim_start().len();
                let (line, col) = idx.line_col(before + lead);
                return Err(KbError::Strict {
                    file: file.to_string(),
                    line,
                    col,
                    message: format!(
                        "text \"{}\" is not allowed here (a lost '<'?)",
                        raw.trim().chars().take(40).collect::<String>()
                    ),
                });
            }
            Event::CData(_) if mode == ReadMode::Strict => {
                let (line, col) = idx.line_col(before);
                return Err(KbError::Strict {
                    file: file.to_string(),
                    line,
                    col,
                    message: "CDATA sections are not allowed".into(),
                });
            }
            Event::Eof => break,
            _ => {}
        }
    }
    if let Some(open) = stack.last() {
        let line = open.line;
        return Err(KbError::Xml {
            file: file.to_string(),
            line,
            col: open.col,
            message: format!("element <{}> is never closed", open.name),
        });
    }
    root.ok_or_else(|| KbError::Structure {
        file: file.to_string(),
        line: 1,
        message: "empty knowledge base: no <earth> element".into(),
    })
}

fn element(
    e: &BytesStart,
    text: &str,
    start: usize,
    end: usize,
    idx: &LineIndex,
    file: &str,
) -> Result<Elem, KbError> {
    let name = e.name().into_inner().to_string();
    let (line, col) = idx.line_col(start);
    let tag = text.get(start..end).unwrap_or("");
    let mut attrs = Vec::new();
    let mut attr_cols = Vec::new();
    let mut search_from = 0;
    for a in e.attributes() {
        if attrs.len() >= MAX_ATTRIBUTES {
            return Err(KbError::Limit {
                file: file.to_string(),
                line,
                col,
                message: format!("<{name}> has more than {MAX_ATTRIBUTES} attributes"),
            });
        }
        let a = a.map_err(|err| KbError::Xml {
            file: file.to_string(),
            line,
            col,
            message: format!("in <{name}>: {err}"),
        })?;
        let key = a.key.into_inner().to_string();
        // The attribute's own place: find its name in the tag text after the previous one.
        let at = tag
            .get(search_from..)
            .and_then(|t| t.find(key.as_str()))
            .map(|p| p + search_from);
        let (aline, acol) = at.map_or((line, col), |p| idx.line_col(start + p));
        if let Some(p) = at {
            search_from = p + key.len();
        }
        let value = a.normalized_value(XmlVersion::Implicit1_0).map_err(|err| {
            KbError::Xml {
                file: file.to_string(),
                line: aline,
                col: acol,
                message: format!("in <{name}> attribute '{key}': {err} (only the predefined entities are allowed)"),
            }
        })?;
        attrs.push((key, value.into_owned(), aline));
        attr_cols.push(acol);
    }
    Ok(Elem {
        name,
        line,
        col,
        attrs,
        attr_cols,
        children: Vec::new(),
    })
}
