//! `--dem`: digital elevation models read from GeoTIFF files and SRTM `.hgt` tiles (issue 44).
//!
//! An `.hgt` file (`hgt`: NASA SRTM, 1201² or 3601² big-endian `i16`, named after its tile) is
//! read in strips of rows straight from the file; everything else must be a GeoTIFF.
//!
//! The `tiff` crate decodes the file's strips or tiles (any sample format of 8 to 64 bits,
//! integer or float; uncompressed, deflate or LZW, with their predictors); the georeferencing
//! is read here from the GeoTIFF tags themselves (`geokeys`). Only the header is read when a
//! file is opened: its strips or tiles are decoded when a sample needs them and kept in a cache
//! shared by all the files of a run, the least recently used dropped past a few chunks a thread
//! (never past [`CACHE_BYTES`]), so that a run holds the DEM around its buildings, never a
//! whole big file. The buffers of dropped chunks that no sampler holds any more are decoded
//! into again: sampled in chunk order ([`Framed::chunk_key`]), a run touches fresh memory for
//! a few chunks only, not for every chunk it decodes (the kernel's clearing of fresh pages
//! cost as much as inflating them).
//!
//! Heights are sampled bilinearly between pixel centres. A point within half a pixel outside
//! the outermost centres (still on the raster's area) takes the edge's values. A pixel equal to
//! `GDAL_NODATA` (or NaN) has no height: the bilinear weights of the known pixels around a
//! point are renormalised, and a point whose weighted pixels are all unknown has no height.
//! Several files are tried in the order given: the first that has a height at a point between
//! its pixel centres gives it, else the first that has one in its half-pixel margin (so tiles
//! that share their edge samples, as SRTM's do, or overlap, are bilinear across the seam: the
//! first tile's margin does not hide the next tile's pixels there).

mod geokeys;
mod hgt;
mod segment;

use std::collections::HashMap;
use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, PoisonError};

use glam::DVec2;
use thiserror::Error;
use tiff::decoder::{Decoder, DecodingResult, DecodingSampleType, Limits};
use tiff::tags::Tag;
use tiff::ColorType;
use zlib_rs::{InflateConfig, ReturnCode};

use crate::crs::{webmerc, Crs};

pub(crate) use geokeys::vertical_name;
use geokeys::{GeoError, GeoTags, Georef};

/// The most decoded DEM data (bytes of `f32` samples) a run keeps at once; past it the cache is
/// emptied and what is needed again is decoded again.
pub const CACHE_BYTES: usize = 256 << 20;

/// The largest strip or tile decoded (bytes): a file stored as one huge strip is refused with
/// the command that tiles it.
const MAX_CHUNK_BYTES: usize = 64 << 20;

/// The decoded chunks kept per thread of the run before the least recently used is dropped
/// (the cache's budget; at least [`MIN_BUDGET_BYTES`], at most [`CACHE_BYTES`]).
const CHUNKS_PER_THREAD: usize = 4;

/// The least budget of the cache, bytes.
const MIN_BUDGET_BYTES: usize = 16 << 20;

/// The most buffers of dropped chunks kept for the next decodes.
const SPARE_BUFFERS: usize = 8;

/// Why a DEM cannot be used. Every message names the file as given on the command line.
#[derive(Debug, Error)]
pub enum DemError {
    /// The file cannot be opened or read.
    #[error("{}: cannot read the DEM: {source}", .path.display())]
    Io {
        /// The `--dem` file.
        path: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// Not a TIFF the decoder reads, or a strip or tile that does not decode.
    #[error("{}: not a readable GeoTIFF: {reason}", .path.display())]
    Tiff {
        /// The `--dem` file.
        path: PathBuf,
        /// The decoder's error, with the strip or tile when one failed.
        reason: String,
    },
    /// A TIFF whose georeferencing is missing or unusable.
    #[error("{}: {reason}; citygen reads GeoTIFF DEMs (e.g. from `gdal_translate -of GTiff`)", .path.display())]
    Georef {
        /// The `--dem` file.
        path: PathBuf,
        /// What is wrong with its tags.
        reason: String,
    },
    /// An `.hgt` file whose name or size is not an SRTM tile's.
    #[error("{}: not an SRTM .hgt tile: {reason}", .path.display())]
    Hgt {
        /// The `--dem` file.
        path: PathBuf,
        /// What is wrong with its name or size.
        reason: String,
    },
    /// A CRS citygen does not implement.
    #[error("{}: the DEM's CRS ({what}) is not one citygen knows (EPSG:4326, WGS 84 / UTM EPSG:326xx and 327xx, ETRS89 / UTM EPSG:258xx, Lambert-93 EPSG:2154, British National Grid EPSG:27700, Pseudo-Mercator EPSG:3857); reproject it first, e.g. `gdalwarp -t_srs EPSG:4326 {} dem-4326.tif` (or the run's UTM zone, EPSG:326zz)", .path.display(), .path.display())]
    UnknownCrs {
        /// The `--dem` file.
        path: PathBuf,
        /// The CRS as the file names it.
        what: String,
    },
    /// A raster citygen does not read as heights (colour, complex samples, feet).
    #[error("{}: {what}", .path.display())]
    Unsupported {
        /// The `--dem` file.
        path: PathBuf,
        /// What, and how to convert it.
        what: String,
    },
    /// Two files state different vertical datums.
    #[error("{} and {}: the DEMs state different vertical datums ({a} and {b}); convert them to one first", .first.display(), .second.display())]
    MixedDatums {
        /// A file of the first datum.
        first: PathBuf,
        /// A file of the second.
        second: PathBuf,
        /// The first datum.
        a: String,
        /// The second.
        b: String,
    },
}

/// One decoded strip or tile: `w` by `h` heights row by row, NaN where the file has none.
struct Chunk {
    w: usize,
    z: Vec<f32>,
}

/// Where a DEM's pixels come from.
enum Source {
    /// A GeoTIFF's decoder (and, for deflated `f32` strips, where they are in the file).
    Tiff(Box<Mutex<Decoder<BufReader<File>>>>, Option<Deflated>),
    /// An SRTM `.hgt` tile (strips of `hgt::ROWS` rows).
    Hgt(Mutex<File>),
}

/// Where the deflated strips of a GeoTIFF of one band of `f32` heights (no predictor) are in
/// its file: such strips are inflated here by `zlib-rs` in one call straight into the chunk's
/// buffer (the `tiff` crate streams them through `flate2`'s `miniz_oxide` window, about twice
/// as slow), outside the decoder's lock. A strip that does not inflate to its exact size goes
/// to the `tiff` crate's decoder instead, which reads it or says what is wrong.
struct Deflated {
    offsets: Vec<u64>,
    counts: Vec<u64>,
    /// The file's samples are little-endian.
    little: bool,
    /// Buffers of compressed strips, read into again.
    packed: Mutex<Vec<Vec<u8>>>,
}

impl Deflated {
    /// The strips' places when `dec`'s image is one band of `f32` heights in deflated strips
    /// without predictor (GDAL's `COMPRESS=DEFLATE` default), else `None` (also when a tag
    /// does not read as one number: the `tiff` crate's path then says what it makes of it).
    fn of(dec: &mut Decoder<BufReader<File>>) -> Option<Deflated> {
        let mut tag = |t: Tag| dec.find_tag_unsigned::<u16>(t).ok();
        let one = tag(Tag::SamplesPerPixel)?.unwrap_or(1) == 1;
        if !one {
            return None;
        }
        let deflate = matches!(tag(Tag::Compression)?, Some(8 | 32946));
        let plain = tag(Tag::Predictor)?.unwrap_or(1) == 1;
        let float = tag(Tag::SampleFormat)? == Some(3);
        let bits = tag(Tag::BitsPerSample)? == Some(32);
        let black_is_zero = tag(Tag::PhotometricInterpretation)? == Some(1);
        let strips = dec.get_chunk_type() == tiff::decoder::ChunkType::Strip;
        if !(strips && deflate && plain && float && bits && black_is_zero) {
            return None;
        }
        let offsets = dec.find_tag_unsigned_vec::<u64>(Tag::StripOffsets).ok()??;
        let counts = dec
            .find_tag_unsigned_vec::<u64>(Tag::StripByteCounts)
            .ok()??;
        Some(Deflated {
            offsets,
            counts,
            little: dec.byte_order() == tiff::tags::ByteOrder::LittleEndian,
            packed: Mutex::new(Vec::new()),
        })
    }

    /// Strip `index` (`w` by `h` samples) inflated into `z`'s memory, or `z` back when it does
    /// not inflate to exactly that size (or cannot be read).
    fn inflate(
        &self,
        dec: &Mutex<Decoder<BufReader<File>>>,
        index: u32,
        (w, h): (u32, u32),
        mut z: Vec<f32>,
    ) -> Result<Vec<f32>, Vec<f32>> {
        let i = index as usize;
        let (Some(&at), Some(&len)) = (self.offsets.get(i), self.counts.get(i)) else {
            return Err(z);
        };
        let Some(len) = usize::try_from(len).ok().filter(|n| *n <= MAX_CHUNK_BYTES) else {
            return Err(z);
        };
        let n = w as usize * h as usize;
        if n == 0 || 4 * n > MAX_CHUNK_BYTES {
            return Err(z);
        }
        let mut packed = self
            .packed
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .pop()
            .unwrap_or_default();
        packed.clear();
        packed.resize(len, 0);
        let read = {
            let mut dec = dec.lock().unwrap_or_else(PoisonError::into_inner);
            let r = dec.inner();
            r.seek(SeekFrom::Start(at))
                .and_then(|_| r.read_exact(&mut packed))
        };
        let mut whole = read.is_ok();
        if whole {
            z.clear();
            z.resize(n, 0.0);
            let mut out = DecodingResult::F32(z);
            let mut view = out.as_buffer(0);
            let (done, rc) =
                zlib_rs::decompress_slice(view.as_bytes_mut(), &packed, InflateConfig::default());
            whole = rc == ReturnCode::Ok && done.len() == 4 * n;
            z = match out {
                DecodingResult::F32(z) => z,
                _ => Vec::new(),
            };
        }
        let mut pool = self.packed.lock().unwrap_or_else(PoisonError::into_inner);
        if pool.len() < SPARE_BUFFERS {
            pool.push(packed);
        }
        drop(pool);
        if !whole {
            return Err(z);
        }
        if self.little != cfg!(target_endian = "little") {
            z.iter_mut()
                .for_each(|v| *v = f32::from_bits(v.to_bits().swap_bytes()));
        }
        Ok(z)
    }
}

/// The horizontal CRS of a DEM: one citygen writes in, or web mercator (read only: it is not
/// an output CRS, its metres are not metres on the ground).
#[derive(Clone, Copy, Debug, PartialEq)]
enum DemCrs {
    Known(Crs),
    /// EPSG:3857, WGS 84 / Pseudo-Mercator.
    PseudoMercator,
}

impl DemCrs {
    fn from_epsg(code: u16) -> Option<DemCrs> {
        match code {
            3857 => Some(DemCrs::PseudoMercator),
            // A DEM in feet (its pixels' spacing and heights would need converting) is not
            // read: reproject it to a metre CRS first.
            c => Crs::from_epsg(u32::from(c))
                .ok()
                .filter(|c| c.unit().is_metre())
                .map(DemCrs::Known),
        }
    }

    /// WGS 84 degrees to the DEM's coordinates.
    fn project(self, lon: f64, lat: f64) -> (f64, f64) {
        match self {
            DemCrs::Known(c) => c.from_lonlat(lon, lat),
            DemCrs::PseudoMercator => webmerc::from_lonlat(lon, lat),
        }
    }

    /// The DEM's coordinates to WGS 84 degrees.
    fn unproject(self, x: f64, y: f64) -> (f64, f64) {
        match self {
            DemCrs::Known(c) => c.to_lonlat(x, y),
            DemCrs::PseudoMercator => webmerc::to_lonlat(x, y),
        }
    }
}

/// One opened DEM: its header, its georeferencing and a reader for its strips or tiles.
struct Dem {
    path: PathBuf,
    source: Source,
    width: u32,
    height: u32,
    /// Width and height of a strip or tile.
    chunk: (u32, u32),
    /// Strips or tiles across (1 for strips).
    across: u32,
    /// Samples per pixel in a decoded chunk (the first is the height).
    stride: usize,
    nodata: Option<f64>,
    georef: Georef,
    crs: DemCrs,
}

/// The value of a sample at one point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Sample {
    /// The height there, metres.
    Value(f64),
    /// On a DEM, where it has no data.
    NoData,
    /// On none of the DEMs.
    Outside,
}

/// The decoded chunks of every file of a set, by (file, chunk index), each with when it was
/// last asked for; and the buffers of dropped chunks, decoded into again.
#[derive(Default)]
struct Cache {
    chunks: HashMap<(usize, u32), (Arc<Chunk>, u64)>,
    bytes: usize,
    clock: u64,
    spare: Vec<Vec<f32>>,
}

impl Cache {
    /// Drops the least recently used chunks until `size` more bytes fit in `budget` (or none
    /// is left); keeps the buffers no sampler holds any more.
    fn make_room(&mut self, size: usize, budget: usize) {
        while self.bytes + size > budget {
            let Some(key) = self
                .chunks
                .iter()
                .min_by_key(|(k, (_, used))| (*used, **k))
                .map(|(k, _)| *k)
            else {
                return;
            };
            let Some((c, _)) = self.chunks.remove(&key) else {
                return;
            };
            self.bytes = self.bytes.saturating_sub(4 * c.z.len());
            if let Ok(c) = Arc::try_unwrap(c) {
                if self.spare.len() < SPARE_BUFFERS {
                    self.spare.push(c.z);
                }
            }
        }
    }
}

/// The `--dem` files of a run, in the order given.
pub struct DemSet {
    dems: Vec<Dem>,
    cache: Mutex<Cache>,
    /// The most bytes the cache holds before dropping its least recently used chunk.
    budget: usize,
}

impl std::fmt::Debug for DemSet {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list().entries(self.paths()).finish()
    }
}

fn tiff_err(path: &Path) -> impl Fn(tiff::TiffError) -> DemError + '_ {
    move |e| DemError::Tiff {
        path: path.to_path_buf(),
        reason: e.to_string(),
    }
}

impl Dem {
    /// Opens `path` and reads its header and georeferencing (no pixel): an SRTM tile when
    /// its extension is `.hgt`, else a GeoTIFF.
    fn open(path: &Path) -> Result<Dem, DemError> {
        let io = |source| DemError::Io {
            path: path.to_path_buf(),
            source,
        };
        let file = File::open(path).map_err(io)?;
        let meta = file.metadata().map_err(io)?;
        if meta.is_dir() {
            return Err(io(std::io::Error::other("it is a directory")));
        }
        if hgt::is_hgt(path) {
            return Dem::open_hgt(path, file, meta.len());
        }
        let mut limits = Limits::default();
        limits.decoding_buffer_size = MAX_CHUNK_BYTES;
        let mut dec = Decoder::new(BufReader::new(file))
            .map_err(tiff_err(path))?
            .with_limits(limits);
        let (width, height) = dec.dimensions().map_err(tiff_err(path))?;
        let unsupported = |what: String| DemError::Unsupported {
            path: path.to_path_buf(),
            what,
        };
        let planar = dec
            .find_tag_unsigned::<u16>(Tag::PlanarConfiguration)
            .map_err(tiff_err(path))?
            .unwrap_or(1);
        let stride = match dec.colortype().map_err(tiff_err(path))? {
            _ if planar == 2 => 1,
            ColorType::Gray(_) => 1,
            ColorType::GrayA(_) => 2,
            ColorType::Multiband { num_samples, .. } => usize::from(num_samples.max(1)),
            other => {
                return Err(unsupported(format!(
                    "a {other:?} image, not heights: a DEM has one band of heights \
                     (`gdal_translate -b 1` keeps the first)"
                )))
            }
        };
        let tags = geo_tags(&mut dec).map_err(tiff_err(path))?;
        let georef = geokeys::georef(&tags).map_err(|e: GeoError| DemError::Georef {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })?;
        if let Some(what) = &georef.non_metre {
            return Err(unsupported(format!(
                "{what}: citygen reads heights and projected coordinates in metres; convert \
                 them first (e.g. `gdalwarp -t_srs EPSG:4326` and `gdal_calc.py`)"
            )));
        }
        let crs = match georef.epsg {
            Some(code) => DemCrs::from_epsg(code).ok_or_else(|| DemError::UnknownCrs {
                path: path.to_path_buf(),
                what: format!("EPSG:{code}"),
            })?,
            None => {
                return Err(DemError::UnknownCrs {
                    path: path.to_path_buf(),
                    what: georef
                        .citation
                        .clone()
                        .map_or("no EPSG code".into(), |c| format!("user-defined: {c}")),
                })
            }
        };
        let nodata = match dec.find_tag(Tag::GdalNodata).map_err(tiff_err(path))? {
            None => None,
            Some(v) => {
                let s = v.into_string().map_err(tiff_err(path))?;
                let s = s.trim_matches(|c: char| c.is_whitespace() || c == '\0');
                Some(
                    s.parse::<f64>()
                        .map_err(|_| unsupported(format!("GDAL_NODATA {s:?} is not a number")))?,
                )
            }
        };
        let chunk = dec.chunk_dimensions();
        let across = match dec.get_chunk_type() {
            tiff::decoder::ChunkType::Strip => 1,
            tiff::decoder::ChunkType::Tile => width.div_ceil(chunk.0.max(1)),
        };
        if chunk.0 == 0 || chunk.1 == 0 || width == 0 || height == 0 {
            return Err(unsupported("an empty raster".into()));
        }
        let deflated = Deflated::of(&mut dec);
        Ok(Dem {
            path: path.to_path_buf(),
            source: Source::Tiff(Box::new(Mutex::new(dec)), deflated),
            width,
            height,
            chunk,
            across,
            stride,
            nodata,
            georef,
            crs,
        })
    }

    /// Opens an SRTM `.hgt` tile of `bytes` bytes: its name and size checked, nothing read.
    fn open_hgt(path: &Path, file: File, bytes: u64) -> Result<Dem, DemError> {
        let tile = hgt::tile(path, bytes).map_err(|e| DemError::Hgt {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })?;
        Ok(Dem {
            path: path.to_path_buf(),
            source: Source::Hgt(Mutex::new(file)),
            width: tile.side,
            height: tile.side,
            chunk: (tile.side, hgt::ROWS),
            across: 1,
            stride: 1,
            nodata: Some(hgt::VOID),
            georef: tile.georef,
            crs: DemCrs::Known(Crs::Wgs84),
        })
    }

    /// The chunk holding pixel (i, j), and the pixel's column and row in it.
    fn locate(&self, i: u32, j: u32) -> (u32, usize, usize) {
        let (cw, ch) = self.chunk;
        if self.across == 1 {
            // Strips span the width (one division fewer: this is on every sample's path).
            return (j / ch, i as usize, (j % ch) as usize);
        }
        let index = (j / ch) * self.across + i / cw;
        (index, (i % cw) as usize, (j % ch) as usize)
    }

    /// Decodes chunk `index` into heights (into `spare`'s memory when its samples are `f32`).
    fn decode(&self, index: u32, spare: Vec<f32>) -> Result<Chunk, DemError> {
        let (decoder, deflated) = match &self.source {
            Source::Tiff(d, deflated) => (d, deflated),
            Source::Hgt(file) => {
                let mut file = file.lock().unwrap_or_else(PoisonError::into_inner);
                let z = hgt::read_strip(&mut file, self.width, index).map_err(|source| {
                    DemError::Io {
                        path: self.path.clone(),
                        source,
                    }
                })?;
                return Ok(Chunk {
                    w: self.width as usize,
                    z,
                });
            }
        };
        let bad = |e: tiff::TiffError| DemError::Tiff {
            path: self.path.clone(),
            reason: format!("strip or tile {index}: {e}"),
        };
        let dims = decoder
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .chunk_data_dimensions(index);
        let w = dims.0;
        let (raw, spare) = match deflated {
            Some(d) => match d.inflate(decoder, index, dims, spare) {
                Ok(z) => (Some(DecodingResult::F32(z)), Vec::new()),
                Err(spare) => (None, spare),
            },
            None => (None, spare),
        };
        let raw = match raw {
            Some(raw) => raw,
            None => {
                let mut dec = decoder.lock().unwrap_or_else(PoisonError::into_inner);
                read_chunk(&mut dec, index, spare).map_err(bad)?
            }
        };
        let nd = self.nodata;
        let keep = |v: f64| -> f32 {
            match nd {
                Some(n) if v == n || (v as f32) == (n as f32) => f32::NAN,
                _ => v as f32,
            }
        };
        let s = self.stride;
        let z: Vec<f32> = match raw {
            // The common case (one band of f32) in place: no second buffer of the chunk's size.
            DecodingResult::F32(mut v) if s == 1 => {
                if nd.is_some() {
                    v.iter_mut().for_each(|x| *x = keep(f64::from(*x)));
                }
                v
            }
            DecodingResult::U8(v) => v.iter().step_by(s).map(|x| keep(f64::from(*x))).collect(),
            DecodingResult::I8(v) => v.iter().step_by(s).map(|x| keep(f64::from(*x))).collect(),
            DecodingResult::U16(v) => v.iter().step_by(s).map(|x| keep(f64::from(*x))).collect(),
            DecodingResult::I16(v) => v.iter().step_by(s).map(|x| keep(f64::from(*x))).collect(),
            DecodingResult::U32(v) => v.iter().step_by(s).map(|x| keep(f64::from(*x))).collect(),
            DecodingResult::I32(v) => v.iter().step_by(s).map(|x| keep(f64::from(*x))).collect(),
            DecodingResult::U64(v) => v.iter().step_by(s).map(|x| keep(*x as f64)).collect(),
            DecodingResult::I64(v) => v.iter().step_by(s).map(|x| keep(*x as f64)).collect(),
            DecodingResult::F16(v) => v
                .iter()
                .step_by(s)
                .map(|x| keep(f64::from(x.to_f32())))
                .collect(),
            DecodingResult::F32(v) => v.iter().step_by(s).map(|x| keep(f64::from(*x))).collect(),
            DecodingResult::F64(v) => v.iter().step_by(s).map(|x| keep(*x)).collect(),
        };
        Ok(Chunk { w: w as usize, z })
    }
}

/// Chunk `index` of the decoder's image; `f32` samples into `spare`'s memory, zeroed first as
/// a fresh buffer would be (a buffer already in memory: no fresh pages for the kernel to
/// clear), other samples into a new buffer.
fn read_chunk(
    dec: &mut Decoder<BufReader<File>>,
    index: u32,
    mut spare: Vec<f32>,
) -> tiff::TiffResult<DecodingResult> {
    let layout = dec.image_chunk_buffer_layout(index)?;
    if spare.capacity() == 0 || layout.sample_type != Some(DecodingSampleType::F32) {
        return dec.read_chunk(index);
    }
    spare.clear();
    spare.resize(layout.len.div_ceil(4), 0.0);
    let mut raw = DecodingResult::F32(spare);
    dec.read_chunk_bytes(index, raw.as_buffer(0).as_bytes_mut())?;
    Ok(raw)
}

/// The GeoTIFF tags of the decoder's image.
fn geo_tags(dec: &mut Decoder<BufReader<File>>) -> tiff::TiffResult<GeoTags> {
    let f64s = |dec: &mut Decoder<BufReader<File>>, t: Tag| -> tiff::TiffResult<_> {
        dec.find_tag(t)?.map(|v| v.into_f64_vec()).transpose()
    };
    Ok(GeoTags {
        scale: f64s(dec, Tag::ModelPixelScaleTag)?,
        tiepoints: f64s(dec, Tag::ModelTiepointTag)?,
        transformation: f64s(dec, Tag::ModelTransformationTag)?,
        doubles: f64s(dec, Tag::GeoDoubleParamsTag)?,
        keys: dec
            .find_tag(Tag::GeoKeyDirectoryTag)?
            .map(|v| v.into_u16_vec())
            .transpose()?,
        ascii: dec
            .find_tag(Tag::GeoAsciiParamsTag)?
            .map(|v| v.into_string())
            .transpose()?,
    })
}

impl DemSet {
    /// Opens every file (headers and georeferencing only), in the order given.
    pub fn open(paths: &[PathBuf]) -> Result<DemSet, DemError> {
        let dems: Vec<Dem> = paths
            .iter()
            .map(|p| Dem::open(p))
            .collect::<Result<_, _>>()?;
        let largest = dems
            .iter()
            .map(|d: &Dem| 4 * d.chunk.0 as usize * d.chunk.1 as usize)
            .max()
            .unwrap_or(0);
        let budget = (CHUNKS_PER_THREAD * rayon::current_num_threads() * largest)
            .clamp(MIN_BUDGET_BYTES, CACHE_BYTES);
        let set = DemSet {
            dems,
            cache: Mutex::new(Cache::default()),
            budget,
        };
        set.vertical_epsg()?;
        Ok(set)
    }

    /// The files, as given.
    pub fn paths(&self) -> Vec<&Path> {
        self.dems.iter().map(|d| d.path.as_path()).collect()
    }

    /// The vertical CRS the files state (the one code those that state one agree on), or
    /// `None` when none states one.
    pub fn vertical_epsg(&self) -> Result<Option<u16>, DemError> {
        let mut found: Option<(&Dem, u16)> = None;
        for d in &self.dems {
            let Some(code) = d.georef.vertical_epsg else {
                continue;
            };
            match found {
                Some((f, c)) if c != code => {
                    return Err(DemError::MixedDatums {
                        first: f.path.clone(),
                        second: d.path.clone(),
                        a: vertical_name(c),
                        b: vertical_name(code),
                    })
                }
                Some(_) => {}
                None => found = Some((d, code)),
            }
        }
        Ok(found.map(|(_, c)| c))
    }

    /// The set seen from a run's local frame: output CRS `crs`, origin `origin` in it.
    pub fn framed(&self, crs: Crs, origin: DVec2) -> Framed<'_> {
        let mut f = Framed {
            set: self,
            crs,
            origin,
            cells: Vec::new(),
        };
        f.cells = (0..self.dems.len()).map(|d| f.cell_size_of(d)).collect();
        f
    }

    /// Forgets every decoded strip and tile (the samplers' own stay until they are dropped):
    /// once the buildings are seated and the grid made, the run needs them no more.
    pub fn release(&self) {
        let mut cache = self.cache.lock().unwrap_or_else(PoisonError::into_inner);
        *cache = Cache::default();
    }

    fn chunk(&self, d: usize, index: u32) -> Result<Arc<Chunk>, DemError> {
        let key = (d, index);
        let spare = {
            let mut cache = self.cache.lock().unwrap_or_else(PoisonError::into_inner);
            cache.clock += 1;
            let now = cache.clock;
            if let Some((c, used)) = cache.chunks.get_mut(&key) {
                *used = now;
                return Ok(c.clone());
            }
            cache.spare.pop()
        };
        let c = Arc::new(self.dems[d].decode(index, spare.unwrap_or_default())?);
        let mut cache = self.cache.lock().unwrap_or_else(PoisonError::into_inner);
        let size = 4 * c.z.len();
        cache.make_room(size, self.budget);
        let now = cache.clock;
        if let Some((old, _)) = cache.chunks.insert(key, (c.clone(), now)) {
            cache.bytes = cache.bytes.saturating_sub(4 * old.z.len());
        }
        cache.bytes += size;
        Ok(c)
    }
}

impl DemSet {
    /// Keeps the buffer of a chunk a sampler lets go of for the next decode when nothing else
    /// holds the chunk (the cache dropped it already): freed, its pages would be handed back
    /// and cleared afresh by the kernel for a later chunk.
    fn recycle(&self, c: Arc<Chunk>) {
        if let Ok(c) = Arc::try_unwrap(c) {
            let mut cache = self.cache.lock().unwrap_or_else(PoisonError::into_inner);
            if cache.spare.len() < SPARE_BUFFERS {
                cache.spare.push(c.z);
            }
        }
    }
}

impl Drop for Sampler<'_> {
    fn drop(&mut self) {
        for (_, c) in self.memo.drain(..) {
            self.framed.set.recycle(c);
        }
    }
}

/// A pixel centre ([`Framed::centres_in`]).
#[derive(Clone, Copy, Debug)]
pub struct Centre {
    /// Its local position.
    pub p: DVec2,
    /// The file (in the set's order).
    pub file: usize,
    /// Its column.
    pub i: u32,
    /// Its row.
    pub j: u32,
}

/// A [`DemSet`] in a run's local frame.
pub struct Framed<'a> {
    set: &'a DemSet,
    crs: Crs,
    origin: DVec2,
    /// Each file's pixel size in the local frame, metres (the smaller side).
    cells: Vec<f64>,
}

impl Framed<'_> {
    /// The smallest pixel of the files in the local frame, metres.
    pub fn cell_size(&self) -> f64 {
        self.cells.iter().copied().fold(f64::INFINITY, f64::min)
    }

    /// File `d`'s model coordinates of local point `p`.
    fn to_model(&self, d: usize, p: DVec2) -> DVec2 {
        let q = self.origin + p;
        let crs = self.set.dems[d].crs;
        if crs == DemCrs::Known(self.crs) {
            return q;
        }
        let (lon, lat) = self.crs.to_lonlat(q.x, q.y);
        let (x, y) = crs.project(lon, lat);
        DVec2::new(x, y)
    }

    /// The local point of file `d`'s model coordinates `m`.
    fn to_local(&self, d: usize, m: DVec2) -> DVec2 {
        let crs = self.set.dems[d].crs;
        if crs == DemCrs::Known(self.crs) {
            return m - self.origin;
        }
        let (lon, lat) = crs.unproject(m.x, m.y);
        let (x, y) = self.crs.from_lonlat(lon, lat);
        DVec2::new(x, y) - self.origin
    }

    fn cell_size_of(&self, d: usize) -> f64 {
        let dem = &self.set.dems[d];
        let c = DVec2::new(f64::from(dem.width) / 2.0, f64::from(dem.height) / 2.0);
        let at = |c: DVec2| self.to_local(d, dem.georef.to_model(c));
        let o = at(c);
        let s = at(c + DVec2::X)
            .distance(o)
            .min(at(c + DVec2::Y).distance(o));
        if s.is_finite() && s > 0.0 {
            s
        } else {
            1.0
        }
    }

    /// Every pixel centre of every file inside the local rectangle `lo..hi` (a footprint's
    /// bounds), file by file: its local position and its pixel.
    pub fn centres_in(&self, lo: DVec2, hi: DVec2) -> Vec<Centre> {
        let mut out = Vec::new();
        for (d, dem) in self.set.dems.iter().enumerate() {
            let corners = [lo, DVec2::new(hi.x, lo.y), hi, DVec2::new(lo.x, hi.y)];
            let px: Vec<DVec2> = corners
                .iter()
                .map(|c| dem.georef.to_pixel(self.to_model(d, *c)))
                .collect();
            let (mut a, mut b) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
            for p in &px {
                a = a.min(*p);
                b = b.max(*p);
            }
            if !(a.is_finite() && b.is_finite()) {
                continue;
            }
            let i0 = a.x.ceil().max(0.0);
            let j0 = a.y.ceil().max(0.0);
            let i1 = b.x.floor().min(f64::from(dem.width) - 1.0);
            let j1 = b.y.floor().min(f64::from(dem.height) - 1.0);
            if i0 > i1 || j0 > j1 || (i1 - i0 + 1.0) * (j1 - j0 + 1.0) > 4.0e6 {
                continue;
            }
            for j in (j0 as u32)..=(j1 as u32) {
                for i in (i0 as u32)..=(i1 as u32) {
                    let m = dem.georef.to_model(DVec2::new(f64::from(i), f64::from(j)));
                    out.push(Centre {
                        p: self.to_local(d, m),
                        file: d,
                        i,
                        j,
                    });
                }
            }
        }
        out
    }

    /// Whether the set is one file in the run's CRS (at least 2 x 2 pixels): its pixel grid is
    /// then an affine image of the local frame, where a straight local segment stays straight
    /// ([`Sampler::cell_floor`]), and the file's bilinear heights are the set's.
    pub fn single_local(&self) -> bool {
        matches!(self.set.dems.as_slice(), [dem] if dem.crs == DemCrs::Known(self.crs)
            && dem.width >= 2 && dem.height >= 2)
    }

    /// Which decoded chunk local point `p` reads (file, then strip or tile in the file's
    /// order), `u64::MAX` off every file: lots sampled in this order keep few chunks alive at
    /// once, so the cache recycles their buffers instead of growing.
    pub fn chunk_key(&self, p: DVec2) -> u64 {
        for (d, dem) in self.set.dems.iter().enumerate() {
            let c = dem.georef.to_pixel(self.to_model(d, p));
            let (w, h) = (f64::from(dem.width), f64::from(dem.height));
            if c.x >= 0.0 && c.y >= 0.0 && c.x < w && c.y < h {
                let (index, _, _) = dem.locate(c.x as u32, c.y as u32);
                return ((d as u64) << 32) | u64::from(index);
            }
        }
        u64::MAX
    }

    /// A sampler (each thread its own: it remembers the last chunks it read).
    pub fn sampler(&self) -> Sampler<'_> {
        Sampler {
            framed: self,
            memo: Vec::with_capacity(MEMO),
        }
    }
}

/// How many chunks a [`Sampler`] remembers.
const MEMO: usize = 4;

/// Samples a [`Framed`] set at local points.
pub struct Sampler<'a> {
    framed: &'a Framed<'a>,
    memo: Vec<((usize, u32), Arc<Chunk>)>,
}

impl Sampler<'_> {
    /// The height at local point `p`: from the first file that has one there between its
    /// pixel centres, else from the first that has one in its half-pixel margin.
    pub fn sample(&mut self, p: DVec2) -> Result<Sample, DemError> {
        let mut covered = false;
        let mut margin = None;
        for d in 0..self.framed.set.dems.len() {
            let m = self.framed.to_model(d, p);
            match self.bilinear(d, m)? {
                (Sample::Value(z), true) => return Ok(Sample::Value(z)),
                (Sample::Value(z), false) => {
                    margin.get_or_insert(z);
                }
                (Sample::NoData, _) => covered = true,
                (Sample::Outside, _) => {}
            }
        }
        Ok(match margin {
            Some(z) => Sample::Value(z),
            None if covered => Sample::NoData,
            None => Sample::Outside,
        })
    }

    /// Chunk `index` of file `d`, remembered.
    fn chunk(&mut self, d: usize, index: u32) -> Result<&Chunk, DemError> {
        let k = self.remembered(d, index)?;
        Ok(&self.memo[k].1)
    }

    /// Where chunk `index` of file `d` is in the memo, read first when it is not.
    fn remembered(&mut self, d: usize, index: u32) -> Result<usize, DemError> {
        let key = (d, index);
        let k = match self.memo.iter().position(|(k, _)| *k == key) {
            Some(k) => k,
            None => {
                let c = self.framed.set.chunk(d, index)?;
                if self.memo.len() == MEMO {
                    let (_, old) = self.memo.remove(0);
                    self.framed.set.recycle(old);
                }
                self.memo.push((key, c));
                self.memo.len() - 1
            }
        };
        Ok(k)
    }

    fn pixel(&mut self, d: usize, i: u32, j: u32) -> Result<f32, DemError> {
        let (index, col, row) = self.framed.set.dems[d].locate(i, j);
        let chunk = self.chunk(d, index)?;
        Ok(chunk
            .z
            .get(row * chunk.w + col)
            .copied()
            .unwrap_or(f32::NAN))
    }

    /// The height of pixel (`i`, `j`) of file `d` (NaN where it has no data).
    pub fn pixel_height(&mut self, d: usize, i: u32, j: u32) -> Result<f32, DemError> {
        self.pixel(d, i, j)
    }

    /// A lower bound of the heights ([`Sampler::sample`]) along the local segment `p0`..`p1`
    /// of a [`Framed::single_local`] set, when the segment's ends are in one cell between four
    /// pixel centres, all four with data: the least of the four (a bilinear height there is a
    /// weighted mean of them). `None` otherwise. The segment is straight in pixel space, so
    /// every point of it is in that cell (to rounding: a point a few ulps past the cell's side
    /// puts a weight of that order on a pixel beyond it).
    pub fn cell_floor(&mut self, p0: DVec2, p1: DVec2) -> Result<Option<f64>, DemError> {
        let dem = &self.framed.set.dems[0];
        let c0 = dem.georef.to_pixel(self.framed.to_model(0, p0));
        let c1 = dem.georef.to_pixel(self.framed.to_model(0, p1));
        let (lo, hi) = (c0.min(c1), c0.max(c1));
        if !(lo.x >= 0.0 && lo.y >= 0.0 && hi.x.is_finite() && hi.y.is_finite()) {
            return Ok(None);
        }
        let (w, h) = (f64::from(dem.width), f64::from(dem.height));
        if hi.x > w - 1.0 || hi.y > h - 1.0 {
            return Ok(None);
        }
        let i0 = (lo.x as u32).min(dem.width.saturating_sub(2));
        let j0 = (lo.y as u32).min(dem.height.saturating_sub(2));
        if hi.x > f64::from(i0) + 1.0 || hi.y > f64::from(j0) + 1.0 {
            return Ok(None);
        }
        let q = match self.quad(0, i0, j0)? {
            Some(q) => q,
            None => [
                self.pixel(0, i0, j0)?,
                self.pixel(0, i0 + 1, j0)?,
                self.pixel(0, i0, j0 + 1)?,
                self.pixel(0, i0 + 1, j0 + 1)?,
            ],
        };
        Ok(q.iter()
            .all(|v| v.is_finite())
            .then(|| q.iter().copied().fold(f32::INFINITY, f32::min).into()))
    }

    /// Pixels (i, j), (i + 1, j), (i, j + 1), (i + 1, j + 1) of file `d` when all four are in
    /// one chunk (most of the time: one look-up instead of four).
    fn quad(&mut self, d: usize, i: u32, j: u32) -> Result<Option<[f32; 4]>, DemError> {
        let (index, col, row) = self.framed.set.dems[d].locate(i, j);
        let chunk = self.chunk(d, index)?;
        let (w, at) = (chunk.w, row * chunk.w + col);
        Ok(match (col + 1 < w).then(|| chunk.z.get(at..at + w + 2)) {
            Some(Some(z)) => Some([z[0], z[1], z[w], z[w + 1]]),
            _ => None,
        })
    }

    /// File `d`'s bilinear height at its model point `m`, and whether `m` is between the file's
    /// pixel centres (not in the half-pixel margin outside them, where the edge's values hold).
    fn bilinear(&mut self, d: usize, m: DVec2) -> Result<(Sample, bool), DemError> {
        let dem = &self.framed.set.dems[d];
        let c = dem.georef.to_pixel(m);
        let (w, h) = (f64::from(dem.width), f64::from(dem.height));
        if !(c.x >= -0.5 && c.y >= -0.5 && c.x <= w - 0.5 && c.y <= h - 0.5) {
            return Ok((Sample::Outside, false));
        }
        let inner = c.x >= 0.0 && c.y >= 0.0 && c.x <= w - 1.0 && c.y <= h - 1.0;
        let cx = c.x.clamp(0.0, w - 1.0);
        let cy = c.y.clamp(0.0, h - 1.0);
        // `cx`, `cy` are clamped to >= 0: the cast truncates as `floor` would, without the
        // libm call `floor` is on baseline x86-64 (a few % of a `--dem` run's samples).
        let i0 = (cx as u32).min(dem.width.saturating_sub(2));
        let j0 = (cy as u32).min(dem.height.saturating_sub(2));
        let (fx, fy) = (cx - f64::from(i0), cy - f64::from(j0));
        let quad = self.quad(d, i0, j0)?;
        let z = weighted(fx, fy, |k| match quad {
            Some(q) => Ok(q[k]),
            None => self.pixel(d, i0 + CORNERS[k].0, j0 + CORNERS[k].1),
        })?;
        Ok((z, inner))
    }

    /// The heights ([`Sampler::sample`]) at the `n` points `at(0)`, `at(1)`, ..., as `f32`,
    /// NaN where there is none: the same values as `sample` gives, by the same arithmetic,
    /// with less work a point for a [`Framed::single_local`] set (the elevation grid's rows:
    /// one strip or tile held across the points that read it, no file loop).
    pub fn heights(&mut self, n: usize, at: impl Fn(usize) -> DVec2) -> Result<Vec<f32>, DemError> {
        let of = |s: Sample| match s {
            Sample::Value(z) => z as f32,
            _ => f32::NAN,
        };
        if !self.framed.single_local() {
            return (0..n).map(|i| Ok(of(self.sample(at(i))?))).collect();
        }
        let framed = self.framed;
        let dem = &framed.set.dems[0];
        let (w, h) = (f64::from(dem.width), f64::from(dem.height));
        let mut held: Option<(u32, Arc<Chunk>)> = None;
        let mut out = Vec::with_capacity(n);
        for i in 0..n {
            // `to_model` of a file in the run's CRS, then `bilinear`'s steps.
            let c = dem.georef.to_pixel(framed.origin + at(i));
            if !(c.x >= -0.5 && c.y >= -0.5 && c.x <= w - 0.5 && c.y <= h - 0.5) {
                out.push(f32::NAN);
                continue;
            }
            let cx = c.x.clamp(0.0, w - 1.0);
            let cy = c.y.clamp(0.0, h - 1.0);
            let i0 = (cx as u32).min(dem.width.saturating_sub(2));
            let j0 = (cy as u32).min(dem.height.saturating_sub(2));
            let (fx, fy) = (cx - f64::from(i0), cy - f64::from(j0));
            let (index, col, row) = dem.locate(i0, j0);
            if held.as_ref().is_none_or(|(k, _)| *k != index) {
                // Let go of the last chunk first, so that the memo can recycle it.
                drop(held.take());
                let k = self.remembered(0, index)?;
                held = Some((index, self.memo[k].1.clone()));
            }
            let quad = held.as_ref().and_then(|(_, chunk)| {
                let (cw, at) = (chunk.w, row * chunk.w + col);
                (col + 1 < cw)
                    .then(|| chunk.z.get(at..at + cw + 2))
                    .flatten()
                    .map(|z| [z[0], z[1], z[cw], z[cw + 1]])
            });
            let z = weighted(fx, fy, |k| match quad {
                Some(q) => Ok(q[k]),
                None => self.pixel(0, i0 + CORNERS[k].0, j0 + CORNERS[k].1),
            })?;
            out.push(of(z));
        }
        drop(held);
        Ok(out)
    }
}

/// A cell's four pixels from its first: (i, j), (i + 1, j), (i, j + 1), (i + 1, j + 1).
const CORNERS: [(u32, u32); 4] = [(0, 0), (1, 0), (0, 1), (1, 1)];

/// The bilinear height at (`fx`, `fy`) in a cell whose four pixels ([`CORNERS`]) `v` gives:
/// the weighted mean of those with data (a pixel of weight 0 is not read), no data when none.
#[inline(always)]
fn weighted(
    fx: f64,
    fy: f64,
    mut v: impl FnMut(usize) -> Result<f32, DemError>,
) -> Result<Sample, DemError> {
    let (mut sum, mut weight) = (0.0, 0.0);
    for (k, wt) in [
        (1.0 - fx) * (1.0 - fy),
        fx * (1.0 - fy),
        (1.0 - fx) * fy,
        fx * fy,
    ]
    .into_iter()
    .enumerate()
    {
        if wt <= 0.0 {
            continue;
        }
        let v = v(k)?;
        if v.is_finite() {
            sum += wt * f64::from(v);
            weight += wt;
        }
    }
    Ok(if weight > 0.0 {
        Sample::Value(sum / weight)
    } else {
        Sample::NoData
    })
}

#[cfg(test)]
mod tests;
