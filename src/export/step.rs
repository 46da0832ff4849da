//! A small streaming writer of ISO 10303-21 ("STEP Part 21") exchange files, the container of IFC.
//!
//! The writer numbers entity instances (`#1`, `#2`, ...) in creation order and writes each one as
//! soon as it is made, so memory stays bounded by what the caller keeps. It only knows the
//! encoding rules (reals, strings, enumerations, lists, the header); what the entities mean is
//! the business of [`crate::export::ifc`].
//!
//! ```
//! use citygen::export::step::{Header, StepWriter};
//! let mut w = StepWriter::new(Vec::new());
//! w.write_header(&Header::new("a.ifc", "IFC4")).unwrap();
//! let p = w.entity("IFCCARTESIANPOINT", |a| { a.reals(&[0.0, 1.5, -3.25]); }).unwrap();
//! assert_eq!(p.to_string(), "#1");
//! let text = String::from_utf8(w.finish().unwrap()).unwrap();
//! assert!(text.contains("#1=IFCCARTESIANPOINT((0.,1.5,-3.25));"));
//! ```

use std::fmt;
use std::io::{self, Write};

use crate::export::format::push_uint;

/// A reference to an entity instance of the file (`#n`), or, with `Id::LOCAL` set, to the
/// entity numbered `n & !LOCAL` (from 0) of a [`StepBuf`], whose final number is known only
/// when the buffer is appended (`StepWriter::append`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Id(pub u64);

impl Id {
    /// The bit that marks an id local to a [`StepBuf`]: local ids sort after every file id,
    /// in creation order, as their final numbers will.
    pub(crate) const LOCAL: u64 = 1 << 63;

    /// Whether this is an id local to a [`StepBuf`].
    pub(crate) fn is_local(self) -> bool {
        self.0 & Id::LOCAL != 0
    }

    /// The file id of this id once the buffer it is local to starts at entity number `start`
    /// (a file id is returned unchanged).
    pub(crate) fn relocate(self, start: u64) -> Id {
        if self.is_local() {
            Id(start + (self.0 & !Id::LOCAL))
        } else {
            self
        }
    }
}

impl fmt::Display for Id {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "#{}", self.0)
    }
}

/// Formats a REAL the way Part 21 wants it: always a decimal point, never an exponent, rounded
/// to 6 decimals (micrometres for lengths) so that files stay small and free of float noise, and
/// printed with the shortest digits that read back to the rounded value.
///
/// Values of magnitude 1e9 or more are not rounded (a multiply by 1e6 would lose their low
/// digits). `-0` prints as `0.`. Non-finite values cannot be encoded; they print as `0.` and
/// callers are expected to reject them before (the IFC writer does).
#[cfg(test)]
pub(crate) fn format_real(v: f64) -> String {
    let mut s = String::with_capacity(24);
    push_real(&mut s, v);
    s
}

/// Appends [`format_real`]`(v)` to `out` without allocating.
pub(crate) use crate::export::format::push_real;

/// Encodes a STRING literal with its quotes: `'` doubled, `\` doubled, printable ASCII as is,
/// anything else (non-ASCII, control characters) as `\X2\HHHH..\X0\` runs of UTF-16 code units
/// for the Basic Multilingual Plane and `\X4\HHHHHHHH..\X0\` runs for the other planes.
pub(crate) fn encode_string(s: &str) -> String {
    let mut out = Vec::with_capacity(s.len() + 2);
    push_string(&mut out, s);
    // Only ASCII is pushed.
    String::from_utf8(out).unwrap_or_default()
}

/// Appends [`encode_string`]`(s)` to `out` (ASCII bytes).
pub(crate) fn push_string(out: &mut Vec<u8>, s: &str) {
    #[derive(PartialEq, Clone, Copy)]
    enum Run {
        None,
        X2,
        X4,
    }
    if s.bytes()
        .all(|b| (b' '..=b'~').contains(&b) && b != b'\'' && b != b'\\')
    {
        out.reserve(s.len() + 2);
        out.push(b'\'');
        out.extend_from_slice(s.as_bytes());
        out.push(b'\'');
        return;
    }
    out.push(b'\'');
    let mut run = Run::None;
    for c in s.chars() {
        let wanted = match c {
            ' '..='~' => Run::None,
            c if (c as u32) <= 0xFFFF => Run::X2,
            _ => Run::X4,
        };
        if wanted != run {
            if run != Run::None {
                out.extend_from_slice(b"\\X0\\");
            }
            match wanted {
                Run::X2 => out.extend_from_slice(b"\\X2\\"),
                Run::X4 => out.extend_from_slice(b"\\X4\\"),
                Run::None => {}
            }
            run = wanted;
        }
        match (run, c) {
            (Run::None, '\'') => out.extend_from_slice(b"''"),
            (Run::None, '\\') => out.extend_from_slice(b"\\\\"),
            // Printable ASCII.
            (Run::None, c) => out.push(c as u8),
            (Run::X2, c) => {
                let _ = write!(out, "{:04X}", c as u32);
            }
            (Run::X4, c) => {
                let _ = write!(out, "{:08X}", c as u32);
            }
        }
    }
    if run != Run::None {
        out.extend_from_slice(b"\\X0\\");
    }
    out.push(b'\'');
}

/// The 64 characters of IFC's base-64 encoding of GUIDs, in digit order.
pub(crate) const IFC_BASE64: &[u8; 64] =
    b"0123456789ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz_$";

/// FNV-1a over `bytes`, continuing from each of the two states (two independent streams in
/// one pass).
fn fnv1a2(mut h: [u64; 2], bytes: &[u8]) -> [u64; 2] {
    for b in bytes {
        for h in &mut h {
            *h ^= u64::from(*b);
            *h = h.wrapping_mul(0x0000_0100_0000_01B3);
        }
    }
    h
}

/// SplitMix64's finaliser: spreads every input bit over the whole word.
fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A deterministic 128-bit hash of (namespace, path): two independent FNV-1a streams, each
/// finished with SplitMix64 and cross-mixed. A 0xFF byte (never in UTF-8) separates the two
/// strings so that ("ab", "c") and ("a", "bc") differ.
pub(crate) fn hash128(namespace: &str, path: &str) -> u128 {
    let h = [0xCBF2_9CE4_8422_2325, 0x6C62_272E_07BB_0142];
    let [a, b] = fnv1a2(
        fnv1a2(fnv1a2(h, namespace.as_bytes()), &[0xFF]),
        path.as_bytes(),
    );
    let hi = mix64(a ^ b.rotate_left(32));
    let lo = mix64(b ^ hi);
    (u128::from(hi) << 64) | u128::from(lo)
}

/// The 22-character IFC GlobalId encoding of a 128-bit value: the first character carries the
/// top 2 bits, each of the 21 others 6 bits, most significant first.
pub(crate) fn encode_guid(v: u128) -> String {
    String::from_utf8(guid_bytes(v).to_vec()).unwrap_or_default()
}

/// [`encode_guid`] as bytes.
fn guid_bytes(v: u128) -> [u8; 22] {
    let mut out = [0u8; 22];
    out[0] = IFC_BASE64[(v >> 126) as usize];
    for (i, c) in out[1..].iter_mut().enumerate() {
        *c = IFC_BASE64[((v >> (6 * (20 - i))) & 0x3F) as usize];
    }
    out
}

/// A deterministic IFC GlobalId for the object at `path` (e.g. `p0/wall/3`) of the object family
/// `namespace` (e.g. a building key): equal inputs give equal ids in every run, distinct inputs
/// give distinct ids (up to a 128-bit hash collision).
pub(crate) fn global_id(namespace: &str, path: &str) -> String {
    encode_guid(hash128(namespace, path))
}

/// The Part 21 HEADER section.
#[derive(Clone, Debug, PartialEq)]
pub struct Header {
    /// FILE_DESCRIPTION.description, e.g. `ViewDefinition [DesignTransferView_V1.0]`.
    pub description: Vec<String>,
    /// FILE_NAME.name.
    pub name: String,
    /// FILE_NAME.time_stamp (ISO 8601). Fixed, never the clock: see `timestamp_from_env`.
    pub time_stamp: String,
    /// FILE_NAME.author.
    pub author: String,
    /// FILE_NAME.organization.
    pub organization: String,
    /// FILE_NAME.preprocessor_version: the software that wrote the STEP encoding.
    pub preprocessor_version: String,
    /// FILE_NAME.originating_system: the software the model comes from.
    pub originating_system: String,
    /// FILE_NAME.authorization.
    pub authorization: String,
    /// FILE_SCHEMA, e.g. `IFC4`.
    pub schema: String,
}

impl Header {
    /// A header for `name` in `schema`, stamped by `timestamp_from_env`, with citygen as the
    /// originating system.
    pub fn new(name: &str, schema: &str) -> Header {
        Header {
            description: vec!["ViewDefinition [DesignTransferView_V1.0]".to_string()],
            name: name.to_string(),
            time_stamp: timestamp_from_env(),
            author: String::new(),
            organization: String::new(),
            preprocessor_version: format!("citygen {}", env!("CARGO_PKG_VERSION")),
            originating_system: "citygen".to_string(),
            authorization: String::new(),
            schema: schema.to_string(),
        }
    }
}

/// The time stamp to write: `SOURCE_DATE_EPOCH` (seconds since 1970, the reproducible-builds
/// convention) when it is set and valid, else `1970-01-01T00:00:00`. Never the clock, so equal
/// runs give byte-identical files.
pub(crate) fn timestamp_from_env() -> String {
    let secs = std::env::var("SOURCE_DATE_EPOCH")
        .ok()
        .and_then(|s| s.trim().parse::<i64>().ok())
        .unwrap_or(0);
    iso8601_utc(secs)
}

/// `YYYY-MM-DDTHH:MM:SS` (UTC) of a Unix time, proleptic Gregorian calendar. Years outside
/// 0..=9999 are clamped to that range's ends.
pub(crate) fn iso8601_utc(secs: i64) -> String {
    // Clamp to 0000-01-01 .. 9999-12-31T23:59:59 so the format stays fixed-width.
    let secs = secs.clamp(-62_167_219_200, 253_402_300_799);
    let days = secs.div_euclid(86_400);
    let sod = secs.rem_euclid(86_400);
    // Howard Hinnant's civil_from_days.
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}",
        sod / 3600,
        sod % 3600 / 60,
        sod % 60
    )
}
/// Builder of one entity's parameter list, handed to [`StepWriter::entity`]. Each call appends one
/// parameter (commas are managed here).
pub struct Args<'a> {
    buf: &'a mut Vec<u8>,
    /// Where the references to local ids ([`Id::LOCAL`]) are, for [`StepBuf::append_to`].
    holes: &'a mut Vec<Hole>,
    count: usize,
    /// The first argument that broke its type's rule ([`Args::positive`]), for [`StepWriter::entity`]
    /// to refuse the entity with.
    bad: Option<String>,
}

/// A reference to a local id in a [`StepBuf`]: the byte offset where its number goes and the
/// local number.
type Hole = (usize, u64);

/// An entity that would break a rule of the schema (a positive length written as 0): the
/// writer refuses it rather than write an invalid file. Carried inside the `io::Error` that
/// [`StepWriter::entity`] returns; [`broken_rule`] finds it.
#[derive(Debug)]
pub(crate) struct BrokenRule(pub String);

impl std::fmt::Display for BrokenRule {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for BrokenRule {}

/// The [`BrokenRule`] inside an error of [`StepWriter::entity`], if that is what it is.
pub(crate) fn broken_rule(e: &io::Error) -> Option<&BrokenRule> {
    e.get_ref()
        .and_then(|inner| inner.downcast_ref::<BrokenRule>())
}

impl Args<'_> {
    #[inline]
    fn sep(&mut self) -> &mut Vec<u8> {
        if self.count > 0 {
            self.buf.push(b',');
        }
        self.count += 1;
        self.buf
    }

    /// An entity reference `#n`.
    pub fn id(&mut self, id: Id) -> &mut Self {
        let b = self.sep();
        b.push(b'#');
        if id.is_local() {
            self.holes.push((self.buf.len(), id.0 & !Id::LOCAL));
        } else {
            push_uint(self.buf, id.0);
        }
        self
    }

    /// An entity reference `#n`, or `$` for `None`.
    pub(crate) fn opt_id(&mut self, id: Option<Id>) -> &mut Self {
        match id {
            Some(id) => self.id(id),
            None => self.null(),
        }
    }

    /// A list of references `(#a,#b)`.
    pub fn ids(&mut self, ids: &[Id]) -> &mut Self {
        self.list(|a| {
            for id in ids {
                a.id(*id);
            }
        })
    }

    /// A REAL (see `format_real`).
    pub fn real(&mut self, v: f64) -> &mut Self {
        push_real(self.sep(), v);
        self
    }

    /// A REAL that the schema requires to be above zero (`IfcPositiveLengthMeasure`: profile
    /// sizes, extrusion depths). One that is not, or that would be written as `0.` (below half
    /// a micrometre), makes [`StepWriter::entity`] refuse the entity.
    pub(crate) fn positive(&mut self, v: f64) -> &mut Self {
        let written_positive = v.is_finite() && (v >= 1e9 || (v * 1e6).round() > 0.0);
        if !written_positive && self.bad.is_none() {
            self.bad = Some(format!(
                "argument {} must be a positive length, is {v}",
                self.count + 1
            ));
        }
        self.real(v)
    }

    /// A list of REALs.
    pub fn reals(&mut self, vs: &[f64]) -> &mut Self {
        self.list(|a| {
            for v in vs {
                a.real(*v);
            }
        })
    }

    /// An INTEGER.
    pub fn int(&mut self, v: i64) -> &mut Self {
        let b = self.sep();
        if v < 0 {
            b.push(b'-');
        }
        push_uint(b, v.unsigned_abs());
        self
    }

    /// A list of INTEGERs.
    pub(crate) fn ints(&mut self, vs: &[i64]) -> &mut Self {
        self.list(|a| {
            for v in vs {
                a.int(*v);
            }
        })
    }

    /// A STRING (see `encode_string`).
    pub fn string(&mut self, s: &str) -> &mut Self {
        push_string(self.sep(), s);
        self
    }

    /// The STRING of [`global_id`]`(namespace, path)`.
    pub(crate) fn guid(&mut self, namespace: &str, path: &str) -> &mut Self {
        let b = self.sep();
        b.push(b'\'');
        b.extend_from_slice(&guid_bytes(hash128(namespace, path)));
        b.push(b'\'');
        self
    }

    /// A STRING, or `$` when absent.
    pub(crate) fn opt_string(&mut self, s: Option<&str>) -> &mut Self {
        match s {
            Some(s) => self.string(s),
            None => self.null(),
        }
    }

    /// `$`: an unset optional attribute.
    pub fn null(&mut self) -> &mut Self {
        self.sep().push(b'$');
        self
    }

    /// `*`: an attribute derived in a subtype (e.g. `IfcSIUnit.Dimensions`).
    pub fn derived(&mut self) -> &mut Self {
        self.sep().push(b'*');
        self
    }

    /// An enumeration value `.NAME.`; `name` must be the bare upper-case identifier.
    pub(crate) fn enumeration(&mut self, name: &str) -> &mut Self {
        let b = self.sep();
        b.push(b'.');
        b.extend_from_slice(name.as_bytes());
        b.push(b'.');
        self
    }

    /// A BOOLEAN `.T.` / `.F.`.
    pub fn boolean(&mut self, v: bool) -> &mut Self {
        self.enumeration(if v { "T" } else { "F" })
    }

    /// A typed value of a SELECT, e.g. `IFCLABEL('x')`; `f` writes the inner parameter.
    pub fn typed(&mut self, type_name: &str, f: impl FnOnce(&mut Args<'_>)) -> &mut Self {
        let b = self.sep();
        b.extend_from_slice(type_name.as_bytes());
        b.push(b'(');
        self.inner(f);
        self
    }

    /// A list `( ... )`; `f` writes its members.
    pub fn list(&mut self, f: impl FnOnce(&mut Args<'_>)) -> &mut Self {
        self.sep().push(b'(');
        self.inner(f);
        self
    }

    /// The parameters `f` writes, then `)`.
    fn inner(&mut self, f: impl FnOnce(&mut Args<'_>)) {
        let mut inner = Args {
            buf: &mut *self.buf,
            holes: &mut *self.holes,
            count: 0,
            bad: None,
        };
        f(&mut inner);
        if self.bad.is_none() {
            self.bad = inner.bad;
        }
        self.buf.push(b')');
    }
}

/// Entity instances rendered apart from the file, numbered locally from 0 (`Id::LOCAL` ids),
/// so that several can be rendered in parallel and appended in order
/// (`StepWriter::append`): appending only writes the final numbers of the local ids into the
/// rendered text. References to file ids are written as they are.
#[derive(Default)]
pub struct StepBuf {
    /// The entities' text, `#=KEYWORD(args);\n` each, without the numbers of local ids.
    bytes: Vec<u8>,
    /// Where the numbers of local ids go, in byte order.
    holes: Vec<Hole>,
    count: u64,
}

impl StepBuf {
    /// An empty buffer.
    pub fn new() -> StepBuf {
        StepBuf::default()
    }

    /// Renders one entity instance `#n=KEYWORD(args);` and returns its local id (see
    /// [`StepWriter::entity`]). An entity refused for a broken rule leaves nothing behind.
    pub fn entity(&mut self, keyword: &str, f: impl FnOnce(&mut Args<'_>)) -> io::Result<Id> {
        let (mark, holes) = (self.bytes.len(), self.holes.len());
        let id = Id(Id::LOCAL | self.count);
        self.bytes.push(b'#');
        self.holes.push((self.bytes.len(), self.count));
        self.bytes.push(b'=');
        self.bytes.extend_from_slice(keyword.as_bytes());
        self.bytes.push(b'(');
        let mut args = Args {
            buf: &mut self.bytes,
            holes: &mut self.holes,
            count: 0,
            bad: None,
        };
        f(&mut args);
        if let Some(why) = args.bad {
            self.bytes.truncate(mark);
            self.holes.truncate(holes);
            return Err(io::Error::other(BrokenRule(format!("{keyword}: {why}"))));
        }
        self.bytes.extend_from_slice(b");\n");
        self.count += 1;
        Ok(id)
    }

    /// Number of entities rendered.
    pub fn len(&self) -> u64 {
        self.count
    }

    /// Whether no entity was rendered.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// Bytes the buffer holds without reallocating.
    pub(crate) fn capacity(&self) -> usize {
        self.bytes.capacity()
    }

    /// Forgets the rendered entities (keeping the storage).
    pub fn clear(&mut self) {
        self.bytes.clear();
        self.holes.clear();
        self.count = 0;
    }

    /// At least the bytes [`StepBuf::append_to`] writes with local id 0 numbered `start`:
    /// the text and, for each local reference, the digits of the largest number it can get.
    pub(crate) fn appended_len_bound(&self, start: u64) -> u64 {
        self.bytes.len() as u64 + self.holes.len() as u64 * decimal_digits(start + self.count)
    }

    /// Appends the text of the entities to `out`, local id `k` numbered `start + k`.
    pub(crate) fn append_to(&self, out: &mut Vec<u8>, start: u64) {
        out.reserve(self.bytes.len() + 8 * self.holes.len());
        let mut pos = 0;
        for &(at, k) in &self.holes {
            out.extend_from_slice(&self.bytes[pos..at]);
            push_uint(out, start + k);
            pos = at;
        }
        out.extend_from_slice(&self.bytes[pos..]);
    }
}

/// Bytes [`StepWriter::finish`] writes: `ENDSEC;` and `END-ISO-10303-21;`, each on its line.
pub(crate) const TRAILER_LEN: u64 = 26;

/// Decimal digits of `v`.
pub(crate) fn decimal_digits(v: u64) -> u64 {
    u64::from(v.checked_ilog10().unwrap_or(0)) + 1
}

/// Streaming writer of one Part 21 file: `write_header`, then `entity` (or `append`) as many
/// times as needed, then `finish`. Entities are numbered from 1 in call order.
pub struct StepWriter<W: Write> {
    out: W,
    next: u64,
    /// Bytes handed to `out` so far.
    written: u64,
    one: StepBuf,
    line: Vec<u8>,
}

impl<W: Write> StepWriter<W> {
    /// A writer onto `out`; nothing is written yet.
    pub fn new(out: W) -> StepWriter<W> {
        StepWriter {
            out,
            next: 1,
            written: 0,
            one: StepBuf::new(),
            line: Vec::with_capacity(256),
        }
    }

    /// Writes `ISO-10303-21;`, the HEADER section and opens the DATA section.
    pub fn write_header(&mut self, h: &Header) -> io::Result<()> {
        let list = |items: &[String]| {
            items
                .iter()
                .map(|s| encode_string(s))
                .collect::<Vec<_>>()
                .join(",")
        };
        let mut text = Vec::with_capacity(512);
        writeln!(text, "ISO-10303-21;")?;
        writeln!(text, "HEADER;")?;
        writeln!(text, "FILE_DESCRIPTION(({}),'2;1');", list(&h.description))?;
        writeln!(
            text,
            "FILE_NAME({},{},({}),({}),{},{},{});",
            encode_string(&h.name),
            encode_string(&h.time_stamp),
            encode_string(&h.author),
            encode_string(&h.organization),
            encode_string(&h.preprocessor_version),
            encode_string(&h.originating_system),
            encode_string(&h.authorization)
        )?;
        writeln!(text, "FILE_SCHEMA(({}));", encode_string(&h.schema))?;
        writeln!(text, "ENDSEC;")?;
        writeln!(text, "DATA;")?;
        self.out.write_all(&text)?;
        self.written += text.len() as u64;
        Ok(())
    }

    /// Writes one entity instance `#n=KEYWORD(args);` and returns its id. `keyword` is the
    /// upper-case entity name; `f` writes the attributes in schema order.
    pub fn entity(&mut self, keyword: &str, f: impl FnOnce(&mut Args<'_>)) -> io::Result<Id> {
        let mut one = std::mem::take(&mut self.one);
        one.clear();
        let done = one.entity(keyword, f);
        let appended = match done {
            Ok(_) => self.append(&one).map(Id),
            Err(e) => Err(e),
        };
        self.one = one;
        appended
    }

    /// Writes the entities of `buf` and returns the number its local id 0 gets (the number
    /// of the next entity when `buf` is empty).
    pub(crate) fn append(&mut self, buf: &StepBuf) -> io::Result<u64> {
        let start = self.next;
        self.line.clear();
        buf.append_to(&mut self.line, start);
        self.out.write_all(&self.line)?;
        self.written += self.line.len() as u64;
        self.next += buf.len();
        Ok(start)
    }

    /// The number the next entity gets.
    pub(crate) fn next_number(&self) -> u64 {
        self.next
    }

    /// Bytes written so far (the header and the entities; `finish` adds [`TRAILER_LEN`]).
    pub(crate) fn bytes_written(&self) -> u64 {
        self.written
    }

    /// Number of entities written so far.
    #[cfg(test)]
    pub(crate) fn entity_count(&self) -> u64 {
        self.next - 1
    }

    /// Closes the DATA section and the file (`TRAILER_LEN` bytes), flushes, and hands the
    /// output back.
    pub fn finish(mut self) -> io::Result<W> {
        writeln!(self.out, "ENDSEC;")?;
        writeln!(self.out, "END-ISO-10303-21;")?;
        self.out.flush()?;
        Ok(self.out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn a_positive_length_written_as_zero_refuses_the_entity() {
        let mut w = StepWriter::new(Vec::new());
        for v in [0.0, -1.0, 4e-7, f64::NAN, f64::INFINITY] {
            let e = w
                .entity("IFCRECTANGLEPROFILEDEF", |a| {
                    a.enumeration("AREA")
                        .null()
                        .null()
                        .positive(1.0)
                        .positive(v);
                })
                .unwrap_err();
            let rule = broken_rule(&e).unwrap_or_else(|| panic!("{v}: {e}"));
            assert!(
                rule.0.starts_with("IFCRECTANGLEPROFILEDEF: argument 5"),
                "{rule}"
            );
        }
        // Inside a list too.
        let e = w
            .entity("X", |a| {
                a.list(|l| {
                    l.positive(0.0);
                });
            })
            .unwrap_err();
        assert!(broken_rule(&e).is_some());
        assert!(w
            .entity("X", |a| {
                a.positive(1e-6).positive(2e9);
            })
            .is_ok());
    }

    #[test]
    fn reals_have_a_point_and_no_exponent() {
        assert_eq!(format_real(0.0), "0.");
        assert_eq!(format_real(-0.0), "0.");
        assert_eq!(format_real(1.0), "1.");
        assert_eq!(format_real(1.5), "1.5");
        assert_eq!(format_real(-3.25), "-3.25");
        assert_eq!(format_real(0.1 + 0.2), "0.3");
        assert_eq!(format_real(1e-5), "0.00001");
        assert_eq!(format_real(1e-7), "0.");
        assert_eq!(format_real(-1e-7), "0.");
        assert_eq!(format_real(574_123.123_456_7), "574123.123457");
        assert_eq!(format_real(6_300_000.5), "6300000.5");
        assert_eq!(format_real(1e20), "100000000000000000000.");
        assert_eq!(format_real(f64::NAN), "0.");
        assert_eq!(format_real(f64::INFINITY), "0.");
    }

    /// The formatting before `push_real` (Display of the value rounded to micrometres).
    fn format_real_by_display(v: f64) -> String {
        if !v.is_finite() {
            return "0.".to_string();
        }
        let mut r = if v.abs() < 1e9 {
            (v * 1e6).round() / 1e6
        } else {
            v
        };
        if r == 0.0 {
            r = 0.0;
        }
        let mut s = format!("{r}");
        if !s.contains('.') {
            s.push('.');
        }
        s
    }

    #[test]
    fn fast_real_matches_display_at_the_edges() {
        for v in [
            0.0,
            -0.0,
            1e-6,
            -1e-6,
            4.9e-7,
            5e-7,
            0.1,
            0.3,
            999_999_999.999_999,
            -999_999_999.999_999,
            1e9,
            -1e9,
            1.5e9,
            123_456.000_001,
            0.000_010,
            7.25,
            f64::MIN_POSITIVE,
            1e300,
            -1e300,
        ] {
            assert_eq!(format_real(v), format_real_by_display(v), "{v:e}");
        }
    }

    proptest! {
        #[test]
        fn fast_real_matches_display(v in -1e9f64..1e9, e in -12i32..10) {
            prop_assert_eq!(format_real(v), format_real_by_display(v));
            let w = v / 1e9 * 10f64.powi(e);
            prop_assert_eq!(format_real(w), format_real_by_display(w));
        }

        #[test]
        fn reals_round_trip_to_micrometres(v in -1e8f64..1e8) {
            let s = format_real(v);
            prop_assert!(s.contains('.'));
            prop_assert!(!s.contains('e') && !s.contains('E'));
            let back: f64 = s.parse().unwrap();
            prop_assert!((back - v).abs() <= 5e-7 + 1e-9 * v.abs());
        }
    }

    #[test]
    fn strings_are_escaped() {
        assert_eq!(encode_string(""), "''");
        assert_eq!(
            encode_string("Rue de l'Église"),
            "'Rue de l''\\X2\\00C9\\X0\\glise'"
        );
        assert_eq!(encode_string("a\\b"), "'a\\\\b'");
        assert_eq!(encode_string("日本"), "'\\X2\\65E5672C\\X0\\'");
        assert_eq!(encode_string("a\nb"), "'a\\X2\\000A\\X0\\b'");
        assert_eq!(encode_string("😀x"), "'\\X4\\0001F600\\X0\\x'");
        assert_eq!(
            encode_string("é😀"),
            "'\\X2\\00E9\\X0\\\\X4\\0001F600\\X0\\'"
        );
    }

    #[test]
    fn guids_use_the_ifc_alphabet_and_are_stable() {
        let g = global_id("way_1", "p0/wall/0");
        assert_eq!(g.len(), 22);
        assert!(g.bytes().all(|c| IFC_BASE64.contains(&c)));
        assert!(matches!(g.as_bytes()[0], b'0'..=b'3'));
        assert_eq!(g, global_id("way_1", "p0/wall/0"));
        assert_ne!(g, global_id("way_1", "p0/wall/1"));
        assert_ne!(global_id("ab", "c"), global_id("a", "bc"));
        assert_eq!(encode_guid(0), "0000000000000000000000");
        assert_eq!(encode_guid(u128::MAX), "3$$$$$$$$$$$$$$$$$$$$$");
    }

    #[test]
    fn guids_are_unique_over_many_paths() {
        let mut seen = std::collections::BTreeSet::new();
        for b in 0..200 {
            for e in 0..50 {
                assert!(seen.insert(global_id(&format!("way_{b}"), &format!("p0/wall/{e}"))));
            }
        }
    }

    #[test]
    fn timestamps() {
        assert_eq!(iso8601_utc(0), "1970-01-01T00:00:00");
        assert_eq!(iso8601_utc(951_782_400), "2000-02-29T00:00:00");
        assert_eq!(iso8601_utc(1_700_000_000), "2023-11-14T22:13:20");
        assert_eq!(iso8601_utc(-1), "1969-12-31T23:59:59");
        assert_eq!(iso8601_utc(i64::MAX), "9999-12-31T23:59:59");
    }

    #[test]
    fn writer_numbers_entities_and_frames_the_file() {
        let mut w = StepWriter::new(Vec::new());
        let mut h = Header::new("x.ifc", "IFC4");
        h.time_stamp = "1970-01-01T00:00:00".into();
        w.write_header(&h).unwrap();
        let a = w
            .entity("IFCDIRECTION", |a| {
                a.reals(&[1.0, 0.0, 0.0]);
            })
            .unwrap();
        let b = w
            .entity("IFCTEST", |a| {
                a.id(Id(1))
                    .null()
                    .derived()
                    .enumeration("T")
                    .ints(&[43, -1])
                    .typed("IFCLABEL", |t| {
                        t.string("x");
                    })
                    .ids(&[]);
            })
            .unwrap();
        assert_eq!((a, b), (Id(1), Id(2)));
        assert_eq!(w.entity_count(), 2);
        let s = String::from_utf8(w.finish().unwrap()).unwrap();
        assert!(s.starts_with("ISO-10303-21;\nHEADER;\nFILE_DESCRIPTION(('ViewDefinition"));
        assert!(s.contains("FILE_NAME('x.ifc','1970-01-01T00:00:00',"));
        assert!(
            s.contains("FILE_SCHEMA(('IFC4'));\nENDSEC;\nDATA;\n#1=IFCDIRECTION((1.,0.,0.));\n")
        );
        assert!(s.contains("#2=IFCTEST(#1,$,*,.T.,(43,-1),IFCLABEL('x'),());\n"));
        assert!(s.ends_with("ENDSEC;\nEND-ISO-10303-21;\n"));
    }
}
