//! Names and numbers in messages: quoted and cut names, lists, plurals, did-you-mean.

use super::MAX_NAME_CHARS;

/// `` `name` ``, cut to [`MAX_NAME_CHARS`] characters with `…` (a generated file may have
/// megabyte names).
pub(super) fn quote(name: &str) -> String {
    format!("`{}`", cut(name))
}

/// `name`, cut to [`MAX_NAME_CHARS`] characters with `…`.
pub(super) fn cut(name: &str) -> String {
    match name.char_indices().nth(MAX_NAME_CHARS) {
        Some((i, _)) => format!("{}…", &name[..i]),
        None => name.to_string(),
    }
}

/// `a, b, c`, or `a, b, c and 5 more` when `total` is more than the names shown.
pub(super) fn list_names(shown: &[String], total: usize) -> String {
    let mut s = shown.join(", ");
    if total > shown.len() {
        s.push_str(&format!(" and {} more", total - shown.len()));
    }
    s
}

/// The candidate closest to `name`, if within 2 edits (and fewer edits than `name` has
/// characters, so `a` does not suggest `b`); ties go to the earlier candidate. Candidates
/// whose length differs by more than 2 are skipped unmeasured; each distance measured costs
/// its table's cells from `budget`, and a spent budget gives no suggestion (so that a file of
/// thousands of similar names stays fast). Names longer than [`MAX_NAME_CHARS`] get none.
pub(crate) fn suggest<'c>(
    name: &str,
    candidates: &[(&'c str, usize)],
    budget: &mut usize,
) -> Option<&'c str> {
    let len = name.chars().count();
    if len > MAX_NAME_CHARS {
        return None;
    }
    let mut best: Option<(usize, &str)> = None;
    for &(c, clen) in candidates {
        if c == name || clen.abs_diff(len) > 2 {
            continue;
        }
        let cost = (len + 1) * (clen + 1);
        if cost > *budget {
            return None;
        }
        *budget -= cost;
        let d = edit_distance(name, c);
        if d <= 2 && d < len && best.is_none_or(|(b, _)| d < b) {
            best = Some((d, c));
        }
    }
    best.map(|(_, c)| c)
}

pub(super) fn plural(n: usize) -> &'static str {
    if n == 1 {
        ""
    } else {
        "s"
    }
}

/// A probability for messages: at most 6 decimals, trailing zeros trimmed (`1.2`, not
/// `1.2000000000000002`).
pub(super) fn fmt_num(v: f64) -> String {
    let s = format!("{v:.6}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s.is_empty() || s == "-" {
        "0".to_string()
    } else {
        s.to_string()
    }
}

/// Levenshtein distance in characters (insert, delete, substitute each cost 1).
pub(crate) fn edit_distance(a: &str, b: &str) -> usize {
    let a: Vec<char> = a.chars().collect();
    let b: Vec<char> = b.chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    let mut cur = vec![0; b.len() + 1];
    for (i, ca) in a.iter().enumerate() {
        cur[0] = i + 1;
        for (j, cb) in b.iter().enumerate() {
            let sub = prev[j] + usize::from(ca != cb);
            cur[j + 1] = sub.min(prev[j + 1] + 1).min(cur[j] + 1);
        }
        std::mem::swap(&mut prev, &mut cur);
    }
    prev[b.len()]
}
