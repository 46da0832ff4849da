//! A PNG encoder for 8-bit RGB pictures (PNG 1.2 / ISO 15948): the preview's picture and the textures (`export::texture`): signature, `IHDR`, one `IDAT`
//! (zlib through `flate2`, every row given the filter of least absolute sum, the heuristic the
//! PNG specification suggests), `IEND`; chunk CRCs by `crc32fast`. No clock, no metadata: the
//! bytes are a function of the pixels.

use std::io::Write;

use flate2::write::ZlibEncoder;
use flate2::Compression;

/// The 8 bytes every PNG starts with.
pub(crate) const SIGNATURE: [u8; 8] = [0x89, b'P', b'N', b'G', 0x0D, 0x0A, 0x1A, 0x0A];

/// `rgb` (`width * height` pixels, 3 bytes each, rows top to bottom) as a PNG file. `None` when
/// the sizes do not match or a side is 0 or over PNG's limit (2^31 - 1).
pub(crate) fn encode_rgb(width: u32, height: u32, rgb: &[u8]) -> Option<Vec<u8>> {
    let limit = (1u32 << 31) - 1;
    if width == 0 || height == 0 || width > limit || height > limit {
        return None;
    }
    let row = (width as usize).checked_mul(3)?;
    if rgb.len() != row.checked_mul(height as usize)? {
        return None;
    }

    let mut ihdr = Vec::with_capacity(13);
    ihdr.extend_from_slice(&width.to_be_bytes());
    ihdr.extend_from_slice(&height.to_be_bytes());
    // Bit depth 8, colour type 2 (RGB), deflate, adaptive filtering, no interlace.
    ihdr.extend_from_slice(&[8, 2, 0, 0, 0]);

    let mut z = ZlibEncoder::new(Vec::new(), Compression::new(6));
    let mut filtered = vec![0u8; 1 + row];
    let mut best = vec![0u8; 1 + row];
    let zero = vec![0u8; row];
    for y in 0..height as usize {
        let cur = &rgb[y * row..(y + 1) * row];
        let prev = if y == 0 {
            &zero[..]
        } else {
            &rgb[(y - 1) * row..y * row]
        };
        let mut best_sum = u64::MAX;
        for kind in 0..5u8 {
            filter_row(kind, cur, prev, &mut filtered);
            // Bytes read as signed, summed by magnitude; ties keep the lower filter type.
            let sum: u64 = filtered[1..]
                .iter()
                .map(|&b| u64::from((b as i8).unsigned_abs()))
                .sum();
            if sum < best_sum {
                best_sum = sum;
                best.copy_from_slice(&filtered);
            }
        }
        // Writing to a Vec cannot fail.
        z.write_all(&best).ok()?;
    }
    let idat = z.finish().ok()?;

    let mut png = Vec::with_capacity(idat.len() + 64);
    png.extend_from_slice(&SIGNATURE);
    push_chunk(&mut png, b"IHDR", &ihdr);
    push_chunk(&mut png, b"IDAT", &idat);
    push_chunk(&mut png, b"IEND", &[]);
    Some(png)
}

/// One row filtered by filter `kind` (0 None, 1 Sub, 2 Up, 3 Average, 4 Paeth) into `out`,
/// whose first byte is the filter type. 3 bytes a pixel.
fn filter_row(kind: u8, cur: &[u8], prev: &[u8], out: &mut [u8]) {
    out[0] = kind;
    for i in 0..cur.len() {
        let a = if i >= 3 { cur[i - 3] } else { 0 };
        let b = prev[i];
        let c = if i >= 3 { prev[i - 3] } else { 0 };
        let predicted = match kind {
            0 => 0,
            1 => a,
            2 => b,
            3 => ((u16::from(a) + u16::from(b)) / 2) as u8,
            _ => paeth(a, b, c),
        };
        out[1 + i] = cur[i].wrapping_sub(predicted);
    }
}

/// The Paeth predictor of PNG's filter type 4.
fn paeth(a: u8, b: u8, c: u8) -> u8 {
    let (ia, ib, ic) = (i16::from(a), i16::from(b), i16::from(c));
    let p = ia + ib - ic;
    let (pa, pb, pc) = ((p - ia).abs(), (p - ib).abs(), (p - ic).abs());
    if pa <= pb && pa <= pc {
        a
    } else if pb <= pc {
        b
    } else {
        c
    }
}

/// Appends a chunk: length, type, data, CRC-32 of type and data.
fn push_chunk(png: &mut Vec<u8>, kind: &[u8; 4], data: &[u8]) {
    // Chunks here are far below 2^31 bytes: the IDAT of the largest picture allowed is too.
    png.extend_from_slice(&(data.len() as u32).to_be_bytes());
    png.extend_from_slice(kind);
    png.extend_from_slice(data);
    let mut crc = crc32fast::Hasher::new();
    crc.update(kind);
    crc.update(data);
    png.extend_from_slice(&crc.finalize().to_be_bytes());
}
