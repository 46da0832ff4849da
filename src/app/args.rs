//! The value parsers the commands share (clap `value_parser = ...`), and their error: clap
//! prints it after "invalid value '...' for '--flag': ".

use thiserror::Error;

use crate::crs::{Crs, CrsError};
use crate::geometry::Polygon;
use crate::model::Lod;

/// Why a flag's value was refused.
#[derive(Debug, Error)]
pub(crate) enum ArgError {
    #[error("LOD must be 1, 2, 3 or 4, not {0:?}")]
    Lod(String),
    #[error("{0}")]
    Crs(#[from] CrsError),
    #[error(
        "{0} is geographic (degrees), and the output CRS must be projected (metres): a UTM \
         zone (EPSG:326xx north, 327xx south, 258xx ETRS89), a national grid (EPSG:2154, \
         27700, 28992, 2056...); without --crs, citygen uses the input's projected CRS or the \
         UTM zone of the data"
    )]
    GeographicCrs(String),
    #[error("{0}")]
    FeetCrs(String),
    #[error("expected kb, none, all, or a list of levels, roof, colour")]
    Infer,
    #[error("expected WxD, e.g. 20x12")]
    LotShape,
    #[error("bad width {0:?}")]
    Width(String),
    #[error("bad depth {0:?}")]
    Depth(String),
    #[error("width and depth must be positive")]
    LotSize,
    #[error("{0}")]
    Wkt(String),
    #[error("bad number {0:?}")]
    Number(String),
    #[error("expected megabytes (10^6 bytes) from 0.001 to 1000000, not {0:?}")]
    Megabytes(String),
    #[error("expected LON0,LAT0,LON1,LAT1 with LON0 < LON1 and LAT0 < LAT1")]
    Bbox,
    #[error("expected LON,LAT")]
    LonLatShape,
    #[error("bad longitude {0:?}")]
    Longitude(String),
    #[error("bad latitude {0:?}")]
    Latitude(String),
    #[error("longitude must be in -180..180 and latitude in -84..84")]
    LonLatRange,
    #[error("expected WIDTHxDEPTHxHEIGHT in metres, e.g. 12x10x9, not {0:?}")]
    BoxShape(String),
    #[error("{0:?} is not a size in metres (0 to 10 km)")]
    BoxSize(String),
    #[error("{0:?} is not a height in metres between -500 and 9000")]
    GroundHeight(String),
}

/// `--ground-height METRES`: a finite height between the Dead Sea's shore and Everest's top,
/// rounded.
pub(crate) fn parse_ground_height(s: &str) -> Result<f64, ArgError> {
    match s.trim().parse::<f64>() {
        Ok(h) if (-500.0..=9000.0).contains(&h) => Ok(h),
        _ => Err(ArgError::GroundHeight(s.to_string())),
    }
}

pub(crate) fn parse_lod(s: &str) -> Result<Lod, ArgError> {
    match s.trim() {
        "1" => Ok(Lod::Lod1),
        "2" => Ok(Lod::Lod2),
        "3" => Ok(Lod::Lod3),
        "4" => Ok(Lod::Lod4),
        _ => Err(ArgError::Lod(s.to_string())),
    }
}

/// `--ifc-max-mb`: megabytes (10^6 bytes, decimals allowed: `0.5`), as bytes; from 0.001
/// (1000 bytes) to 10^6 (a terabyte).
pub(crate) fn parse_megabytes(s: &str) -> Result<u64, ArgError> {
    match s.trim().parse::<f64>() {
        Ok(mb) if mb.is_finite() && (0.001..=1e6).contains(&mb) => Ok((mb * 1e6).round() as u64),
        _ => Err(ArgError::Megabytes(s.to_string())),
    }
}

pub(crate) fn parse_crs(s: &str) -> Result<Crs, ArgError> {
    Ok(Crs::from_epsg_str(s)?)
}

/// `--crs`: a projected CRS. The model is built in metres in a local frame of the output CRS,
/// so a geographic one (degrees) would make every footprint degenerate.
pub(crate) fn parse_output_crs(s: &str) -> Result<Crs, ArgError> {
    let crs = parse_crs(s)?;
    if crs.is_geographic() {
        return Err(ArgError::GeographicCrs(s.to_string()));
    }
    if !crs.unit().is_metre() {
        let twin = crs.in_metres().map_or_else(String::new, |t| {
            format!(": give its metre edition, --crs {t}")
        });
        return Err(ArgError::FeetCrs(format!(
            "{crs} is in feet (its unit is the {}); citygen writes its outputs in metres{twin}",
            crs.unit().name
        )));
    }
    Ok(crs)
}

/// `--infer`: `kb` (the zones decide: `None`) or an [`Inference`](crate::model::Inference).
#[derive(Clone, Copy, Debug)]
pub(crate) struct InferArg(pub(crate) Option<crate::model::Inference>);

pub(crate) fn parse_infer(s: &str) -> Result<InferArg, ArgError> {
    if s.trim().eq_ignore_ascii_case("kb") {
        return Ok(InferArg(None));
    }
    crate::model::Inference::parse(s)
        .map(|i| InferArg(Some(i)))
        .ok_or(ArgError::Infer)
}

pub(crate) fn parse_lot(s: &str) -> Result<Polygon, ArgError> {
    let (w, d) = s.split_once(['x', 'X']).ok_or(ArgError::LotShape)?;
    let w: f64 = w
        .trim()
        .parse()
        .map_err(|_| ArgError::Width(w.to_string()))?;
    let d: f64 = d
        .trim()
        .parse()
        .map_err(|_| ArgError::Depth(d.to_string()))?;
    if !(w.is_finite() && d.is_finite() && w > 0.0 && d > 0.0) {
        return Err(ArgError::LotSize);
    }
    let v = |x, y| glam::DVec2::new(x, y);
    Ok(Polygon::new(
        vec![
            v(-w / 2.0, -d / 2.0),
            v(w / 2.0, -d / 2.0),
            v(w / 2.0, d / 2.0),
            v(-w / 2.0, d / 2.0),
        ],
        vec![],
    ))
}

pub(crate) fn parse_wkt(s: &str) -> Result<Polygon, ArgError> {
    crate::input::wkt::parse_polygon(s).map_err(|e| ArgError::Wkt(e.to_string()))
}

pub(crate) fn parse_bbox(s: &str) -> Result<[f64; 4], ArgError> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| {
            x.trim()
                .parse::<f64>()
                .map_err(|_| ArgError::Number(x.to_string()))
        })
        .collect::<Result<_, _>>()?;
    match v[..] {
        [a, b, c, d] if a < c && b < d && v.iter().all(|x| x.is_finite()) => Ok([a, b, c, d]),
        _ => Err(ArgError::Bbox),
    }
}

pub(crate) fn parse_lonlat(s: &str) -> Result<(f64, f64), ArgError> {
    let (a, b) = s.split_once(',').ok_or(ArgError::LonLatShape)?;
    let lon: f64 = a
        .trim()
        .parse()
        .map_err(|_| ArgError::Longitude(a.to_string()))?;
    let lat: f64 = b
        .trim()
        .parse()
        .map_err(|_| ArgError::Latitude(b.to_string()))?;
    if !((-180.0..=180.0).contains(&lon) && (-84.0..=84.0).contains(&lat)) {
        return Err(ArgError::LonLatRange);
    }
    Ok((lon, lat))
}

/// `WxDxH` in metres, each positive.
pub(crate) fn parse_box(s: &str) -> Result<(f64, f64, f64), ArgError> {
    let parts: Vec<&str> = s.split(['x', 'X']).collect();
    let [w, d, h] = parts.as_slice() else {
        return Err(ArgError::BoxShape(s.to_string()));
    };
    let num = |t: &str| -> Result<f64, ArgError> {
        match t.trim().parse::<f64>() {
            Ok(v) if v.is_finite() && v > 0.0 && v <= 10_000.0 => Ok(v),
            _ => Err(ArgError::BoxSize(t.to_string())),
        }
    };
    Ok((num(w)?, num(d)?, num(h)?))
}
