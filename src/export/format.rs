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

/// Appends the decimal digits of `v`.
pub(crate) fn push_uint(out: &mut impl Ascii, mut v: u64) {
    let mut digits = [0u8; 20];
    let mut i = digits.len();
    loop {
        i -= 1;
        digits[i] = b'0' + (v % 10) as u8;
        v /= 10;
        if v == 0 {
            break;
        }
    }
    out.push_ascii(&digits[i..]);
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
pub fn push_real(out: &mut impl Ascii, v: f64) {
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
    let k = (v * 1e6).round();
    if k == 0.0 {
        out.push_ascii(b"0.");
        return;
    }
    if k < 0.0 {
        out.push_ascii(b"-");
    }
    let m = k.abs() as u64;
    push_uint(out, m / 1_000_000);
    out.push_ascii(b".");
    let mut frac = m % 1_000_000;
    if frac != 0 {
        let mut width = 6;
        while frac % 10 == 0 {
            frac /= 10;
            width -= 1;
        }
        let mut digits = [b'0'; 6];
        for d in digits[..width].iter_mut().rev() {
            *d = b'0' + (frac % 10) as u8;
            frac /= 10;
        }
        out.push_ascii(&digits[..width]);
    }
}

/// Appends a finite number with exactly 3 decimals, never `-0.000`.
pub(crate) fn push_fixed3(out: &mut impl Ascii, v: f64) {
    let scaled = (v * 1000.0).round();
    if scaled.abs() >= 1e18 {
        // Beyond u64 millimetres (never a real coordinate): let the formatter do it.
        let mut s = String::with_capacity(32);
        let _ = write!(s, "{v:.3}");
        out.push_ascii(s.as_bytes());
        return;
    }
    let n = scaled as i64;
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
    let v = u64::from(v);
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
