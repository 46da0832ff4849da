//! How names, comments, numbers and coordinates are written, and the mode and median of
//! values.

use std::collections::BTreeMap;

use super::round7;

/// A name the strict reader takes as a designation: no `/`, no tab or line break, trimmed,
/// not empty.
pub(super) fn designation(name: &str) -> String {
    let s: String = name
        .chars()
        .map(|c| if c == '/' || c.is_control() { ' ' } else { c })
        .collect();
    let s = s.split_whitespace().collect::<Vec<_>>().join(" ");
    if s.is_empty() {
        "extract".into()
    } else {
        s
    }
}

/// `s` with `& < > "` escaped, for an attribute value.
pub(super) fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// `s` made safe inside an XML comment (no `--`, no trailing `-`, no control character).
pub(super) fn comment_text(s: &str) -> String {
    let mut t: String = s
        .chars()
        .map(|c| if c.is_control() { ' ' } else { c })
        .collect();
    while t.contains("--") {
        t = t.replace("--", "- ");
    }
    if t.ends_with('-') {
        t.push(' ');
    }
    t
}

/// Compact number: at most `decimals` decimals, no trailing zeros.
pub(super) fn num(x: f64, decimals: usize) -> String {
    let s = format!("{x:.decimals$}");
    let s = if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.')
    } else {
        &s
    };
    if s == "-0" {
        "0".into()
    } else {
        s.to_string()
    }
}

/// A coordinate with its 7 decimals.
pub(super) fn coord(x: f64) -> String {
    num(round7(x), 7)
}

/// The most frequent value, ties to the smallest.
pub(super) fn mode<'a>(values: impl Iterator<Item = &'a str>) -> Option<String> {
    let mut counts: BTreeMap<&str, usize> = BTreeMap::new();
    for v in values {
        *counts.entry(v).or_default() += 1;
    }
    let mut best: Option<(&str, usize)> = None;
    for (v, n) in counts {
        if best.is_none_or(|(_, b)| n > b) {
            best = Some((v, n));
        }
    }
    best.map(|(v, _)| v.to_string())
}

/// The median (the lower middle of an even count).
pub(super) fn median(mut v: Vec<f64>) -> Option<f64> {
    v.sort_by(f64::total_cmp);
    v.get(v.len().saturating_sub(1) / 2).copied()
}
