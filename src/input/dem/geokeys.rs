//! GeoTIFF georeferencing read from the tags themselves (OGC GeoTIFF 1.1): the raster-to-model
//! transformation (`ModelPixelScale` 33550 with `ModelTiepoint` 33922, or
//! `ModelTransformation` 34264) and the GeoKey directory (34735, its doubles 34736 and text
//! 34737): the model type, the raster type (PixelIsArea or PixelIsPoint), the horizontal CRS
//! (`ProjectedCSTypeGeoKey` 3072 or `GeographicTypeGeoKey` 2048), its linear unit and the
//! vertical CRS (`VerticalCSTypeGeoKey` 4096).
//!
//! Everything here works in *centre-index* space: (c, r) = (column, row) of a pixel's centre,
//! so pixel (0, 0)'s centre is (0, 0) and its area runs from -0.5 to 0.5. A PixelIsArea file's
//! raster space puts (0, 0) at the top-left pixel's corner (centre = raster + 0.5); a
//! PixelIsPoint file's puts it at that pixel's centre, as GDAL reads both.

use glam::DVec2;

/// `GTModelTypeGeoKey`.
const MODEL_TYPE: u16 = 1024;
/// `GTRasterTypeGeoKey`.
const RASTER_TYPE: u16 = 1025;
/// `GeographicTypeGeoKey`.
const GEOGRAPHIC_TYPE: u16 = 2048;
/// `ProjectedCSTypeGeoKey`.
const PROJECTED_TYPE: u16 = 3072;
/// `ProjLinearUnitsGeoKey`.
const LINEAR_UNITS: u16 = 3076;
/// `VerticalCSTypeGeoKey`.
const VERTICAL_TYPE: u16 = 4096;
/// `VerticalUnitsGeoKey`.
const VERTICAL_UNITS: u16 = 4099;
/// EPSG's metre (linear units).
const METRE: u16 = 9001;
/// GeoTIFF's "user-defined" code: a CRS spelt out by parameters rather than by a code.
pub(super) const USER_DEFINED: u16 = 32767;

/// The raw tag values a GeoTIFF's georeferencing is made from.
#[derive(Clone, Debug, Default)]
pub(super) struct GeoTags {
    /// `ModelPixelScale` (Sx, Sy, Sz).
    pub scale: Option<Vec<f64>>,
    /// `ModelTiepoint`: (I, J, K, X, Y, Z) sextuples.
    pub tiepoints: Option<Vec<f64>>,
    /// `ModelTransformation`: a 4 x 4 matrix, row by row.
    pub transformation: Option<Vec<f64>>,
    /// `GeoKeyDirectory`.
    pub keys: Option<Vec<u16>>,
    /// `GeoDoubleParams`.
    pub doubles: Option<Vec<f64>>,
    /// `GeoAsciiParams`.
    pub ascii: Option<String>,
}

/// What the tags say: where each pixel centre is, in which CRS, and the heights' datum.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Georef {
    /// Model (x, y) of centre-index (c, r): `x = a[0] + a[1] c + a[2] r`, `y = a[3] + a[4] c +
    /// a[5] r`.
    pub affine: [f64; 6],
    /// Whether the file said PixelIsPoint (else PixelIsArea, the default).
    pub pixel_is_point: bool,
    /// The horizontal CRS's EPSG code (projected or geographic).
    pub epsg: Option<u16>,
    /// A user-defined CRS's citation (`GTCitationGeoKey` and the like), for the message.
    pub citation: Option<String>,
    /// The vertical CRS's EPSG code, when the file names one.
    pub vertical_epsg: Option<u16>,
    /// Whether the projected CRS's linear unit, or the vertical unit, is something else than
    /// the metre: named in the error.
    pub non_metre: Option<String>,
}

/// Why a file's georeferencing cannot be used.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub(crate) enum GeoError {
    /// No transformation tags at all: a plain TIFF.
    #[error("no GeoTIFF georeferencing (neither ModelPixelScale with ModelTiepoint nor ModelTransformation)")]
    NoTransform,
    /// Tags present but unusable (wrong lengths, zero scale, a rotation that cannot be
    /// inverted, a malformed key directory).
    #[error("bad GeoTIFF tags: {0}")]
    Bad(String),
}

impl Georef {
    /// The centre-index (c, r) of model point `p` (the inverse of [`Georef::affine`]).
    pub(crate) fn to_pixel(&self, p: DVec2) -> DVec2 {
        let a = &self.affine;
        let det = a[1] * a[5] - a[2] * a[4];
        let (dx, dy) = (p.x - a[0], p.y - a[3]);
        DVec2::new(
            (a[5] * dx - a[2] * dy) / det,
            (-a[4] * dx + a[1] * dy) / det,
        )
    }

    /// The model point of centre-index (c, r).
    pub(crate) fn to_model(&self, c: DVec2) -> DVec2 {
        let a = &self.affine;
        DVec2::new(
            a[0] + a[1] * c.x + a[2] * c.y,
            a[3] + a[4] * c.x + a[5] * c.y,
        )
    }
}

/// One GeoKey's value: a short, doubles or text.
#[derive(Clone, Debug, PartialEq)]
enum KeyValue {
    Short(u16),
    Doubles(Vec<f64>),
    Text(String),
}

/// The GeoKey directory as (key, value) pairs.
fn read_keys(t: &GeoTags) -> Result<Vec<(u16, KeyValue)>, GeoError> {
    let Some(dir) = &t.keys else {
        return Ok(Vec::new());
    };
    if dir.len() < 4 {
        return Err(GeoError::Bad(
            "GeoKeyDirectory shorter than its header".into(),
        ));
    }
    let n = usize::from(dir[3]);
    if dir.len() < 4 + 4 * n {
        return Err(GeoError::Bad(format!(
            "GeoKeyDirectory announces {n} keys but holds {}",
            (dir.len() - 4) / 4
        )));
    }
    let mut out = Vec::with_capacity(n);
    for e in dir[4..4 + 4 * n].chunks_exact(4) {
        let (key, loc, count, off) = (e[0], e[1], usize::from(e[2]), usize::from(e[3]));
        let v = match loc {
            0 => KeyValue::Short(e[3]),
            34736 => {
                let d = t.doubles.as_deref().unwrap_or_default();
                let v = d.get(off..off + count).ok_or_else(|| {
                    GeoError::Bad(format!("GeoKey {key} points past GeoDoubleParams"))
                })?;
                KeyValue::Doubles(v.to_vec())
            }
            34737 => {
                let s = t.ascii.as_deref().unwrap_or_default();
                let v = s.get(off..off + count).unwrap_or_default();
                KeyValue::Text(v.trim_end_matches(['|', '\0']).trim().to_string())
            }
            34735 => {
                let v = dir.get(off).copied().ok_or_else(|| {
                    GeoError::Bad(format!("GeoKey {key} points past GeoKeyDirectory"))
                })?;
                KeyValue::Short(v)
            }
            other => {
                return Err(GeoError::Bad(format!(
                    "GeoKey {key} stored in unknown tag {other}"
                )))
            }
        };
        out.push((key, v));
    }
    Ok(out)
}

/// Parses the georeferencing of `t`.
pub(super) fn georef(t: &GeoTags) -> Result<Georef, GeoError> {
    let keys = read_keys(t)?;
    let short = |k: u16| {
        keys.iter().find_map(|(key, v)| match v {
            KeyValue::Short(s) if *key == k => Some(*s),
            _ => None,
        })
    };
    let pixel_is_point = short(RASTER_TYPE) == Some(2);
    let raster = raster_affine(t)?;
    // Centre-index to raster space: + 0.5 for PixelIsArea.
    let h = if pixel_is_point { 0.0 } else { 0.5 };
    let [x0, xc, xr, y0, yc, yr] = raster;
    let affine = [x0 + (xc + xr) * h, xc, xr, y0 + (yc + yr) * h, yc, yr];
    let det = xc * yr - xr * yc;
    if !(det.is_finite() && det.abs() > 0.0 && affine.iter().all(|v| v.is_finite())) {
        return Err(GeoError::Bad(
            "the pixel-to-model transformation is not invertible (a zero or infinite pixel size)"
                .into(),
        ));
    }
    let model = short(MODEL_TYPE);
    let epsg = match model {
        Some(2) => short(GEOGRAPHIC_TYPE),
        _ => short(PROJECTED_TYPE).or_else(|| {
            // A geographic file that does not state its model type.
            short(GEOGRAPHIC_TYPE).filter(|_| model.is_none())
        }),
    };
    let citation = keys.iter().find_map(|(_, v)| match v {
        KeyValue::Text(s) if !s.is_empty() => Some(s.clone()),
        _ => None,
    });
    let mut non_metre = None;
    if model != Some(2) {
        if let Some(u) = short(LINEAR_UNITS).filter(|u| *u != METRE) {
            non_metre = Some(format!("horizontal unit EPSG:{u}"));
        }
    }
    if let Some(u) = short(VERTICAL_UNITS).filter(|u| *u != METRE) {
        non_metre = Some(format!("height unit EPSG:{u}"));
    }
    Ok(Georef {
        affine,
        pixel_is_point,
        epsg: epsg.filter(|c| *c != USER_DEFINED && *c != 0),
        citation,
        vertical_epsg: short(VERTICAL_TYPE).filter(|c| *c != USER_DEFINED && *c != 0),
        non_metre,
    })
}

/// Raster (i, j) to model (x, y), as `[x0, dx/di, dx/dj, y0, dy/di, dy/dj]`.
fn raster_affine(t: &GeoTags) -> Result<[f64; 6], GeoError> {
    if let Some(m) = &t.transformation {
        if m.len() < 16 {
            return Err(GeoError::Bad(format!(
                "ModelTransformation has {} values, not 16",
                m.len()
            )));
        }
        return Ok([m[3], m[0], m[1], m[7], m[4], m[5]]);
    }
    let (Some(s), Some(tp)) = (&t.scale, &t.tiepoints) else {
        return Err(GeoError::NoTransform);
    };
    if s.len() < 2 || tp.len() < 6 {
        return Err(GeoError::Bad(format!(
            "ModelPixelScale has {} values and ModelTiepoint {}: need 3 and 6",
            s.len(),
            tp.len()
        )));
    }
    if tp.len() > 6 {
        return Err(GeoError::Bad(format!(
            "{} tiepoints (a warped raster): only one tiepoint with a pixel scale is read; \
             rewrite it with `gdalwarp`",
            tp.len() / 6
        )));
    }
    let (i, j, x, y) = (tp[0], tp[1], tp[3], tp[4]);
    let (sx, sy) = (s[0], s[1]);
    // x = X + (i' - I) Sx, y = Y - (j' - J) Sy.
    Ok([x - i * sx, sx, 0.0, y + j * sy, 0.0, -sy])
}

/// The EPSG name of a vertical CRS citygen knows, else `EPSG:n`.
pub(crate) fn vertical_name(code: u16) -> String {
    match code {
        5773 => "EGM96 height".into(),
        3855 => "EGM2008 height".into(),
        5703 => "NAVD88 height".into(),
        5720 => "NGF-IGN69 height".into(),
        5701 => "ODN height".into(),
        5783 => "DHHN92 height".into(),
        7837 => "DHHN2016 height".into(),
        5728 => "LN02 height".into(),
        5215 => "European Vertical Reference Frame 2007 height".into(),
        5730 => "EVRF2000 height".into(),
        c => format!("EPSG:{c}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn keys(entries: &[[u16; 4]]) -> Vec<u16> {
        let mut v = vec![1, 1, 0, entries.len() as u16];
        for e in entries {
            v.extend_from_slice(e);
        }
        v
    }

    #[test]
    fn area_and_point_differ_by_half_a_pixel() {
        let mut t = GeoTags {
            scale: Some(vec![2.0, 3.0, 0.0]),
            tiepoints: Some(vec![0.0, 0.0, 0.0, 1000.0, 5000.0, 0.0]),
            keys: Some(keys(&[
                [1024, 0, 1, 1],
                [1025, 0, 1, 1],
                [3072, 0, 1, 32632],
            ])),
            ..Default::default()
        };
        let g = georef(&t).unwrap();
        assert!(!g.pixel_is_point);
        assert_eq!(g.epsg, Some(32632));
        // The first pixel's centre is half a pixel in from the corner.
        assert_eq!(g.to_model(DVec2::ZERO), DVec2::new(1001.0, 4998.5));
        assert_eq!(g.to_pixel(DVec2::new(1005.0, 4992.5)), DVec2::new(2.0, 2.0));
        t.keys = Some(keys(&[
            [1024, 0, 1, 1],
            [1025, 0, 1, 2],
            [3072, 0, 1, 32632],
        ]));
        let g = georef(&t).unwrap();
        assert!(g.pixel_is_point);
        assert_eq!(g.to_model(DVec2::ZERO), DVec2::new(1000.0, 5000.0));
    }

    #[test]
    fn transformation_matrix_and_vertical_key() {
        let t = GeoTags {
            transformation: Some(vec![
                1.0, 0.0, 0.0, 10.0, //
                0.0, -1.0, 0.0, 20.0, //
                0.0, 0.0, 0.0, 0.0, //
                0.0, 0.0, 0.0, 1.0,
            ]),
            keys: Some(keys(&[
                [1024, 0, 1, 2],
                [2048, 0, 1, 4326],
                [4096, 0, 1, 5773],
            ])),
            ..Default::default()
        };
        let g = georef(&t).unwrap();
        assert_eq!(g.epsg, Some(4326));
        assert_eq!(g.vertical_epsg, Some(5773));
        assert_eq!(g.to_model(DVec2::ZERO), DVec2::new(10.5, 19.5));
    }

    #[test]
    fn refusals() {
        assert_eq!(georef(&GeoTags::default()), Err(GeoError::NoTransform));
        let t = GeoTags {
            scale: Some(vec![0.0, 1.0, 0.0]),
            tiepoints: Some(vec![0.0; 6]),
            ..Default::default()
        };
        assert!(matches!(georef(&t), Err(GeoError::Bad(_))));
        let t = GeoTags {
            scale: Some(vec![1.0, 1.0, 0.0]),
            tiepoints: Some(vec![0.0; 6]),
            keys: Some(vec![1, 1, 0, 3, 1024, 0, 1, 1]),
            ..Default::default()
        };
        assert!(matches!(georef(&t), Err(GeoError::Bad(_))));
        // A user-defined CRS has no code, its citation is kept for the message.
        let t = GeoTags {
            scale: Some(vec![1.0, 1.0, 0.0]),
            tiepoints: Some(vec![0.0; 6]),
            keys: Some(keys(&[
                [1024, 0, 1, 1],
                [3072, 0, 1, 32767],
                [1026, 34737, 6, 0],
            ])),
            ascii: Some("LAEA |".into()),
            ..Default::default()
        };
        let g = georef(&t).unwrap();
        assert_eq!(g.epsg, None);
        assert_eq!(g.citation.as_deref(), Some("LAEA"));
    }
}
