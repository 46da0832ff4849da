//! A small GeoTIFF writer for tests (issue 44's `--dem`): one band of heights in strips, with
//! the GeoTIFF tags GDAL writes (ModelPixelScale and ModelTiepoint, the GeoKey directory with
//! the model type, raster type, horizontal and vertical CRS, and GDAL_NODATA).

use std::path::Path;

use tiff::encoder::colortype::{Gray16, Gray32Float, Gray64Float, GrayI16, GrayI32};
use tiff::encoder::compression::DeflateLevel;
use tiff::encoder::{Compression, TiffEncoder};
use tiff::tags::Tag;

/// The sample type the heights are stored as.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SampleType {
    /// Signed 16-bit integers (as SRTM).
    I16,
    /// Unsigned 16-bit integers.
    U16,
    /// Signed 32-bit integers.
    I32,
    /// 32-bit floats.
    F32,
    /// 64-bit floats.
    F64,
}

/// How the strips are compressed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Packing {
    /// Uncompressed.
    None,
    /// Deflate.
    Deflate,
    /// LZW.
    Lzw,
}

/// A DEM to write: `values` row by row from the top (north) row, `width` by `height`.
#[derive(Clone, Debug)]
pub struct GeoTiff {
    /// Pixels across.
    pub width: u32,
    /// Pixels down.
    pub height: u32,
    /// Heights, row by row from the top; `nodata`'s value (or NaN for floats) where unknown.
    pub values: Vec<f64>,
    /// Model (x, y) of the raster's origin: the top-left pixel's corner (PixelIsArea) or its
    /// centre (PixelIsPoint).
    pub tiepoint: (f64, f64),
    /// Pixel size along x and y (model units: metres or degrees), both positive.
    pub scale: (f64, f64),
    /// EPSG code of the horizontal CRS.
    pub epsg: u16,
    /// Whether `epsg` is geographic (lon/lat degrees) rather than projected.
    pub geographic: bool,
    /// PixelIsPoint (else PixelIsArea).
    pub pixel_is_point: bool,
    /// `GDAL_NODATA`.
    pub nodata: Option<f64>,
    /// `VerticalCSTypeGeoKey`.
    pub vertical: Option<u16>,
    /// Sample type.
    pub sample: SampleType,
    /// Compression.
    pub packing: Packing,
    /// Rows per strip.
    pub rows_per_strip: u32,
}

impl GeoTiff {
    /// A projected PixelIsArea f32 DEM of `width` by `height` pixels of `cell` metres whose
    /// top-left corner is at (`x0`, `y0`) of EPSG `epsg`, heights `f(x, y)` of each pixel
    /// centre.
    pub fn projected(
        epsg: u16,
        (x0, y0): (f64, f64),
        cell: f64,
        (width, height): (u32, u32),
        f: impl Fn(f64, f64) -> f64,
    ) -> GeoTiff {
        let mut values = Vec::with_capacity((width * height) as usize);
        for j in 0..height {
            for i in 0..width {
                let x = x0 + (f64::from(i) + 0.5) * cell;
                let y = y0 - (f64::from(j) + 0.5) * cell;
                values.push(f(x, y));
            }
        }
        GeoTiff {
            width,
            height,
            values,
            tiepoint: (x0, y0),
            scale: (cell, cell),
            epsg,
            geographic: false,
            pixel_is_point: false,
            nodata: None,
            vertical: None,
            sample: SampleType::F32,
            packing: Packing::None,
            rows_per_strip: 7,
        }
    }

    /// Writes the file.
    pub fn write(&self, path: &Path) -> Result<(), tiff::TiffError> {
        let file = std::fs::File::create(path)?;
        let compression = match self.packing {
            Packing::None => Compression::Uncompressed,
            Packing::Deflate => Compression::Deflate(DeflateLevel::Balanced),
            Packing::Lzw => Compression::Lzw,
        };
        let mut enc =
            TiffEncoder::new(std::io::BufWriter::new(file))?.with_compression(compression);
        let (w, h) = (self.width, self.height);
        let v = &self.values;
        match self.sample {
            SampleType::I16 => {
                let data: Vec<i16> = v.iter().map(|x| *x as i16).collect();
                let mut img = enc.new_image::<GrayI16>(w, h)?;
                self.tags(img.encoder())?;
                img.rows_per_strip(self.rows_per_strip)?;
                img.write_data(&data)
            }
            SampleType::U16 => {
                let data: Vec<u16> = v.iter().map(|x| *x as u16).collect();
                let mut img = enc.new_image::<Gray16>(w, h)?;
                self.tags(img.encoder())?;
                img.rows_per_strip(self.rows_per_strip)?;
                img.write_data(&data)
            }
            SampleType::I32 => {
                let data: Vec<i32> = v.iter().map(|x| *x as i32).collect();
                let mut img = enc.new_image::<GrayI32>(w, h)?;
                self.tags(img.encoder())?;
                img.rows_per_strip(self.rows_per_strip)?;
                img.write_data(&data)
            }
            SampleType::F32 => {
                let data: Vec<f32> = v.iter().map(|x| *x as f32).collect();
                let mut img = enc.new_image::<Gray32Float>(w, h)?;
                self.tags(img.encoder())?;
                img.rows_per_strip(self.rows_per_strip)?;
                img.write_data(&data)
            }
            SampleType::F64 => {
                let mut img = enc.new_image::<Gray64Float>(w, h)?;
                self.tags(img.encoder())?;
                img.rows_per_strip(self.rows_per_strip)?;
                img.write_data(v)
            }
        }
    }

    /// The GeoTIFF tags.
    fn tags<W: std::io::Write + std::io::Seek, K: tiff::encoder::TiffKind>(
        &self,
        d: &mut tiff::encoder::DirectoryEncoder<'_, W, K>,
    ) -> Result<(), tiff::TiffError> {
        d.write_tag(
            Tag::ModelPixelScaleTag,
            &[self.scale.0, self.scale.1, 0.0][..],
        )?;
        d.write_tag(
            Tag::ModelTiepointTag,
            &[0.0, 0.0, 0.0, self.tiepoint.0, self.tiepoint.1, 0.0][..],
        )?;
        let mut keys: Vec<[u16; 4]> = vec![
            [1024, 0, 1, if self.geographic { 2 } else { 1 }],
            [1025, 0, 1, if self.pixel_is_point { 2 } else { 1 }],
        ];
        if self.geographic {
            keys.push([2048, 0, 1, self.epsg]);
        } else {
            keys.push([3072, 0, 1, self.epsg]);
        }
        if let Some(v) = self.vertical {
            keys.push([4096, 0, 1, v]);
        }
        let mut dir: Vec<u16> = vec![1, 1, 0, keys.len() as u16];
        dir.extend(keys.iter().flatten());
        d.write_tag(Tag::GeoKeyDirectoryTag, &dir[..])?;
        if let Some(n) = self.nodata {
            d.write_tag(Tag::GdalNodata, format!("{n}").as_str())?;
        }
        Ok(())
    }
}
