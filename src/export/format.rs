//! Number formatting shared by the writers, appending ASCII without allocating: decimal
//! integers (STEP ids and INTEGERs, CityGML ids and counts), STEP REALs ([`push_real`]) and
//! fixed-point decimals (CityGML coordinates with 3 decimals, colour components with 4).
//!
//! Text escaping is not here: each format has its own rules (STEP strings in
//! [`crate::export::step`], XML in the CityGML writer; glTF's JSON goes through serde).

use std::fmt::Write as _;

/// An output the formatters append ASCII to: a `String` (STEP lines) or a byte buffer (XML).
pub trait Ascii {
    /// Appends `s`, which is ASCII.
    fn push_ascii(&mut self, s: &[u8]);
}

impl Ascii for String {
    #[inline]
    fn push_ascii(&mut self, s: &[u8]) {
        // The formatters only push ASCII.
        self.push_str(std::str::from_utf8(s).unwrap_or_default());
    }
}

impl Ascii for Vec<u8> {
    #[inline]
    fn push_ascii(&mut self, s: &[u8]) {
        self.extend_from_slice(s);
    }
}

/// The two-digit decimals `00` to `99`, back to back.
const PAIRS: &[u8; 200] = b"\
0001020304050607080910111213141516171819\
2021222324252627282930313233343536373839\
4041424344454647484950515253545556575859\
6061626364656667686970717273747576777879\
8081828384858687888990919293949596979899";

/// Writes the decimal digits of `v` at the end of `buf`; returns where they start.
#[inline]
fn digits_at_end(buf: &mut [u8], mut v: u64) -> usize {
    let mut i = buf.len();
    while v >= 100 {
        let r = (v % 100) as usize * 2;
        v /= 100;
        i -= 2;
        buf[i..i + 2].copy_from_slice(&PAIRS[r..r + 2]);
    }
    if v >= 10 {
        let r = v as usize * 2;
        i -= 2;
        buf[i..i + 2].copy_from_slice(&PAIRS[r..r + 2]);
    } else {
        i -= 1;
        buf[i] = b'0' + v as u8;
    }
    i
}

/// Appends the decimal digits of `v`.
#[inline]
pub(crate) fn push_uint(out: &mut impl Ascii, v: u64) {
    let mut digits = [0u8; 20];
    let i = digits_at_end(&mut digits, v);
    out.push_ascii(&digits[i..]);
}

/// `x.round() as i64` (halves away from zero) for `|x| < 2^63`, without the libm call: below
/// 2^52 the truncation and the remainder are exact, above every f64 is an integer.
#[inline]
fn round_i64(x: f64) -> i64 {
    let t = x as i64;
    let rest = x - t as f64;
    if rest >= 0.5 {
        t + 1
    } else if rest <= -0.5 {
        t - 1
    } else {
        t
    }
}

/// Appends a REAL the way STEP Part 21 wants it: always a decimal point, never an exponent,
/// rounded to 6 decimals (micrometres for lengths), with the shortest digits that read back to
/// the rounded value (see [`crate::export::step::format_real`]).
///
/// Below 1e9 the rounded value is `k / 1e6` for an integer `k` of at most 15 digits; every
/// decimal of at most 15 significant digits reads back to a distinct f64, so the shortest
/// round-trip form of the rounded value is exactly `k / 1e6` written out with its trailing
/// zeros dropped, which is what is written here with integer arithmetic (the property test
/// `fast_real_matches_display` in `step` checks it against `Display`).
pub(crate) fn push_real(out: &mut impl Ascii, v: f64) {
    if !v.is_finite() {
        out.push_ascii(b"0.");
        return;
    }
    if v.abs() >= 1e9 {
        // Rust's Display for f64 is the shortest round-trip form and never uses an exponent.
        let mut s = String::with_capacity(32);
        let _ = write!(s, "{v}");
        if !s.contains('.') {
            s.push('.');
        }
        out.push_ascii(s.as_bytes());
        return;
    }
    let k = round_i64(v * 1e6);
    if k == 0 {
        out.push_ascii(b"0.");
        return;
    }
    let m = k.unsigned_abs();
    // [sign][integer digits].[6 decimals], the decimals' trailing zeros dropped.
    let mut buf = [0u8; 32];
    let frac = (m % 1_000_000) as usize;
    let mut end = 26;
    if frac != 0 {
        let (hi, mid, lo) = (frac / 10_000 * 2, frac / 100 % 100 * 2, frac % 100 * 2);
        buf[20..22].copy_from_slice(&PAIRS[hi..hi + 2]);
        buf[22..24].copy_from_slice(&PAIRS[mid..mid + 2]);
        buf[24..26].copy_from_slice(&PAIRS[lo..lo + 2]);
        while buf[end - 1] == b'0' {
            end -= 1;
        }
    } else {
        end = 20;
    }
    buf[19] = b'.';
    let mut i = digits_at_end(&mut buf[..19], m / 1_000_000);
    if k < 0 {
        i -= 1;
        buf[i] = b'-';
    }
    out.push_ascii(&buf[i..end]);
}

/// Appends a finite number with exactly 3 decimals, never `-0.000`.
pub(crate) fn push_fixed3(out: &mut impl Ascii, v: f64) {
    let scaled = v * 1000.0;
    if scaled.abs() >= 1e18 {
        // Beyond u64 millimetres (never a real coordinate): let the formatter do it.
        let mut s = String::with_capacity(32);
        let _ = write!(s, "{v:.3}");
        out.push_ascii(s.as_bytes());
        return;
    }
    let n = round_i64(scaled);
    if n < 0 {
        out.push_ascii(b"-");
    }
    let m = n.unsigned_abs();
    push_uint(out, m / 1000);
    let frac = m % 1000;
    out.push_ascii(&[
        b'.',
        b'0' + (frac / 100) as u8,
        b'0' + (frac / 10 % 10) as u8,
        b'0' + (frac % 10) as u8,
    ]);
}

/// Appends a value in 1/10000 as a decimal with 4 places (`5020` -> `0.5020`).
pub(crate) fn push_fixed4(out: &mut impl Ascii, v: u16) {
    push_fixed4_i64(out, i64::from(v));
}

/// Appends a signed value in 1/10000 as a decimal with 4 places (`-12345` -> `-1.2345`): the
/// texture coordinates of `--textures` (`crate::export::texture::UvMap::st`).
pub(crate) fn push_fixed4_i64(out: &mut impl Ascii, q: i64) {
    if q < 0 {
        out.push_ascii(b"-");
    }
    let v = q.unsigned_abs();
    push_uint(out, v / 10_000);
    let f = v % 10_000;
    out.push_ascii(&[
        b'.',
        b'0' + (f / 1000) as u8,
        b'0' + (f / 100 % 10) as u8,
        b'0' + (f / 10 % 10) as u8,
        b'0' + (f % 10) as u8,
    ]);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn s(f: impl Fn(&mut String)) -> String {
        let mut out = String::new();
        f(&mut out);
        out
    }

    #[test]
    fn integers_and_fixed_point() {
        assert_eq!(s(|o| push_uint(o, 0)), "0");
        assert_eq!(s(|o| push_uint(o, u64::MAX)), u64::MAX.to_string());
        assert_eq!(s(|o| push_fixed3(o, -0.0004)), "0.000");
        assert_eq!(s(|o| push_fixed3(o, -1.2346)), "-1.235");
        assert_eq!(s(|o| push_fixed3(o, 574_321.5)), "574321.500");
        assert_eq!(s(|o| push_fixed3(o, 1e30)), format!("{:.3}", 1e30));
        assert_eq!(s(|o| push_fixed4(o, 5020)), "0.5020");
        assert_eq!(s(|o| push_fixed4(o, 10_000)), "1.0000");
        let mut bytes = Vec::new();
        push_real(&mut bytes, -3.25);
        push_uint(&mut bytes, 7);
        assert_eq!(bytes, b"-3.257");
    }
}
