//! SVG pictures of a run: the Pareto front (`front_svg`) and the convergence
//! (`convergence_svg`). Hand-written SVG 1.1, deterministic text (coordinates to 0.01 px),
//! labels XML-escaped, axes with tick labels. Non-finite values are not drawn (a note says how
//! many were left out).

use std::collections::BTreeMap;
use std::fmt::Write;

use super::nsga2::History;

/// Picture width, px.
const WIDTH: f64 = 640.0;
/// Left margin (tick labels and the y label), px.
const LEFT: f64 = 72.0;
/// Right margin, px.
const RIGHT: f64 = 24.0;
/// Panel height, px.
const PANEL: f64 = 340.0;
/// Space above a panel (title), px.
const TOP: f64 = 44.0;
/// Space below a panel (tick labels and the x label), px.
const BOTTOM: f64 = 52.0;

/// Line colours, one per objective (cycled).
const COLOURS: [&str; 6] = [
    "#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf",
];

/// Escapes text for XML content and attribute values.
pub fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c if (c as u32) < 0x20 && c != '\t' && c != '\n' && c != '\r' => out.push(' '),
            c => out.push(c),
        }
    }
    out
}

/// A linear axis: its range and its "nice" ticks (1, 2 or 5 × 10^k apart).
struct Axis {
    lo: f64,
    hi: f64,
    step: f64,
    ticks: Vec<f64>,
}

impl Axis {
    /// An axis covering `[lo, hi]` (finite; widened when empty or a single value) with about
    /// five ticks.
    fn new(lo: f64, hi: f64) -> Axis {
        let (mut lo, mut hi) = if lo.is_finite() && hi.is_finite() && lo <= hi {
            (lo, hi)
        } else {
            (0.0, 1.0)
        };
        if hi - lo <= f64::EPSILON * lo.abs().max(hi.abs()).max(1.0) {
            let pad = (lo.abs() * 0.1).max(1.0);
            lo -= pad;
            hi += pad;
        }
        let raw = (hi - lo) / 5.0;
        let magnitude = 10f64.powf(raw.log10().floor());
        let step = [1.0, 2.0, 5.0, 10.0]
            .iter()
            .map(|f| f * magnitude)
            .find(|s| *s >= raw)
            .unwrap_or(10.0 * magnitude);
        let lo = (lo / step).floor() * step;
        let hi = (hi / step).ceil() * step;
        let count = ((hi - lo) / step).round() as usize;
        let ticks = (0..=count.min(50)).map(|k| lo + k as f64 * step).collect();
        Axis {
            lo,
            hi,
            step,
            ticks,
        }
    }

    /// Where `v` falls in `[0, 1]` along the axis.
    fn fraction(&self, v: f64) -> f64 {
        (v - self.lo) / (self.hi - self.lo)
    }

    /// A tick's label, with as many decimals as the step needs.
    fn label(&self, v: f64) -> String {
        let decimals = (-self.step.log10().floor()).clamp(0.0, 6.0) as usize;
        let text = format!("{v:.decimals$}");
        if text
            .trim_start_matches('-')
            .chars()
            .all(|c| c == '0' || c == '.')
        {
            "0".to_string()
        } else {
            text
        }
    }
}

/// One plotting area: its pixel box and its two axes.
struct Panel {
    x0: f64,
    y0: f64,
    w: f64,
    h: f64,
    x: Axis,
    y: Axis,
}

impl Panel {
    fn px(&self, v: f64) -> f64 {
        self.x0 + self.x.fraction(v) * self.w
    }

    fn py(&self, v: f64) -> f64 {
        self.y0 + self.h - self.y.fraction(v) * self.h
    }

    /// The frame, grid, tick labels, axis labels and title.
    fn axes(&self, out: &mut String, title: &str, x_label: &str, y_label: &str) {
        let (x0, y0, w, h) = (self.x0, self.y0, self.w, self.h);
        let _ = writeln!(
            out,
            r##"<text x="{:.2}" y="{:.2}" text-anchor="middle" font-size="14">{}</text>"##,
            x0 + w / 2.0,
            y0 - 16.0,
            escape(title)
        );
        for &t in &self.x.ticks {
            let x = self.px(t);
            let _ = writeln!(
                out,
                r##"<line x1="{x:.2}" y1="{y0:.2}" x2="{x:.2}" y2="{:.2}" stroke="#e0e0e0"/>"##,
                y0 + h
            );
            let _ = writeln!(
                out,
                r##"<text x="{x:.2}" y="{:.2}" text-anchor="middle">{}</text>"##,
                y0 + h + 16.0,
                escape(&self.x.label(t))
            );
        }
        for &t in &self.y.ticks {
            let y = self.py(t);
            let _ = writeln!(
                out,
                r##"<line x1="{x0:.2}" y1="{y:.2}" x2="{:.2}" y2="{y:.2}" stroke="#e0e0e0"/>"##,
                x0 + w
            );
            let _ = writeln!(
                out,
                r##"<text x="{:.2}" y="{:.2}" text-anchor="end">{}</text>"##,
                x0 - 6.0,
                y + 4.0,
                escape(&self.y.label(t))
            );
        }
        let _ = writeln!(
            out,
            r##"<rect x="{x0:.2}" y="{y0:.2}" width="{w:.2}" height="{h:.2}" fill="none" stroke="#000000"/>"##
        );
        let _ = writeln!(
            out,
            r##"<text x="{:.2}" y="{:.2}" text-anchor="middle">{}</text>"##,
            x0 + w / 2.0,
            y0 + h + 38.0,
            escape(x_label)
        );
        let (lx, ly) = (16.0, y0 + h / 2.0);
        let _ = writeln!(
            out,
            r##"<text x="{lx:.2}" y="{ly:.2}" text-anchor="middle" transform="rotate(-90 {lx:.2} {ly:.2})">{}</text>"##,
            escape(y_label)
        );
    }

    /// A polyline through the finite points, in order (a gap where a value is not finite).
    fn line(&self, out: &mut String, points: &[(f64, f64)], colour: &str, dashed: bool) {
        let dash = if dashed {
            r#" stroke-dasharray="6 4""#
        } else {
            ""
        };
        for run in points.split(|(x, y)| !(x.is_finite() && y.is_finite())) {
            if run.is_empty() {
                continue;
            }
            let coords: Vec<String> = run
                .iter()
                .map(|&(x, y)| format!("{:.2},{:.2}", self.px(x), self.py(y)))
                .collect();
            let _ = writeln!(
                out,
                r#"<polyline points="{}" fill="none" stroke="{colour}" stroke-width="2"{dash}/>"#,
                coords.join(" ")
            );
        }
    }
}

/// The axis bounds of some values, finite ones only.
fn bounds(values: impl Iterator<Item = f64>) -> (f64, f64) {
    values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        })
}

/// The SVG header for a picture `height` px tall.
fn header(height: f64) -> String {
    format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<svg xmlns=\"http://www.w3.org/2000/svg\" version=\"1.1\" width=\"{WIDTH:.0}\" height=\"{height:.0}\" viewBox=\"0 0 {WIDTH:.0} {height:.0}\" font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"100%\" height=\"100%\" fill=\"#ffffff\"/>\n"
    )
}

/// The name of objective `k` (`"objective k+1"` when `names` has none).
fn name(names: &[&str], k: usize) -> String {
    names
        .get(k)
        .map_or_else(|| format!("objective {}", k + 1), |s| s.to_string())
}

/// A note line under the title (left-aligned).
fn note(out: &mut String, y: f64, text: &str) {
    let _ = writeln!(
        out,
        r##"<text x="{LEFT:.2}" y="{y:.2}" fill="#555555" font-size="11">{}</text>"##,
        escape(text)
    );
}

/// The final front of a run, with `names` the objectives' names in the run's order.
///
/// - Two objectives or more: a scatter of the first two objectives (a note says so when there
///   are more): every genome evaluated in any recorded generation, faded grey, and the final
///   front ([`History::front`]) in colour, joined as a staircase.
/// - One objective: the best value per generation.
/// - No objective or no generation: a picture saying there is nothing to draw.
pub(crate) fn front_svg(history: &History, names: &[&str]) -> String {
    let height = TOP + PANEL + BOTTOM + 20.0;
    let mut out = header(height);
    let panel_box = (LEFT, TOP + 20.0, WIDTH - LEFT - RIGHT, PANEL);
    if history.objectives == 0 || history.generations.is_empty() {
        note(&mut out, TOP, "no objective values to draw");
        out.push_str("</svg>\n");
        return out;
    }
    if history.objectives == 1 {
        let points: Vec<(f64, f64)> = history
            .generations
            .iter()
            .map(|g| (g.index as f64, g.min.first().copied().unwrap_or(f64::NAN)))
            .collect();
        let (xlo, xhi) = bounds(points.iter().map(|p| p.0));
        let (ylo, yhi) = bounds(points.iter().map(|p| p.1));
        let panel = Panel {
            x0: panel_box.0,
            y0: panel_box.1,
            w: panel_box.2,
            h: panel_box.3,
            x: Axis::new(xlo, xhi),
            y: Axis::new(ylo, yhi),
        };
        let objective = name(names, 0);
        panel.axes(
            &mut out,
            &format!("best {objective} per generation"),
            "generation",
            &objective,
        );
        panel.line(&mut out, &points, COLOURS[0], false);
        for &(x, y) in points.iter().filter(|p| p.1.is_finite()) {
            let _ = writeln!(
                out,
                r#"<circle cx="{:.2}" cy="{:.2}" r="3" fill="{}"/>"#,
                panel.px(x),
                panel.py(y),
                COLOURS[0]
            );
        }
        out.push_str("</svg>\n");
        return out;
    }

    // Every evaluated genome once (BTreeMap: a stable order).
    let mut evaluated: BTreeMap<&[u32], (f64, f64)> = BTreeMap::new();
    for g in &history.generations {
        for ind in &g.individuals {
            let x = ind.objectives.first().copied().unwrap_or(f64::NAN);
            let y = ind.objectives.get(1).copied().unwrap_or(f64::NAN);
            evaluated.insert(&ind.genome, (x, y));
        }
    }
    let front: Vec<(f64, f64)> = history
        .front
        .iter()
        .map(|i| {
            (
                i.objectives.first().copied().unwrap_or(f64::NAN),
                i.objectives.get(1).copied().unwrap_or(f64::NAN),
            )
        })
        .collect();
    // Genomes past the reference point (penalised: a violated constraint costs 100 on every
    // objective) would squeeze the front into a corner: they are counted, not drawn.
    let reference = &history.config.reference;
    let within = |p: &(f64, f64)| {
        reference.first().is_none_or(|r| p.0 <= *r) && reference.get(1).is_none_or(|r| p.1 <= *r)
    };
    let beyond = evaluated.values().filter(|p| !within(p)).count();
    let all = || evaluated.values().filter(|p| within(p)).chain(front.iter());
    let (xlo, xhi) = bounds(all().map(|p| p.0));
    let (ylo, yhi) = bounds(all().map(|p| p.1));
    let panel = Panel {
        x0: panel_box.0,
        y0: panel_box.1,
        w: panel_box.2,
        h: panel_box.3,
        x: Axis::new(xlo, xhi),
        y: Axis::new(ylo, yhi),
    };
    let (xn, yn) = (name(names, 0), name(names, 1));
    panel.axes(
        &mut out,
        &format!("Pareto front: {xn} and {yn} (minimised)"),
        &xn,
        &yn,
    );
    let finite = |p: &&(f64, f64)| p.0.is_finite() && p.1.is_finite();
    let left_out = all().filter(|p| !finite(p)).count();
    let mut notes = vec![format!(
        "{} evaluated (grey), {} on the front (colour)",
        evaluated.len(),
        front.len()
    )];
    if history.objectives > 2 {
        notes.push(format!(
            "objectives 1 and 2 of {} shown",
            history.objectives
        ));
    }
    if beyond > 0 {
        notes.push(format!("{beyond} penalised past the reference, not drawn"));
    }
    if left_out > 0 {
        notes.push(format!("{left_out} points not finite, not drawn"));
    }
    note(&mut out, TOP - 22.0, &notes.join("; "));
    for p in evaluated.values().filter(finite).filter(|p| within(p)) {
        let _ = writeln!(
            out,
            r##"<circle cx="{:.2}" cy="{:.2}" r="2.5" fill="#808080" fill-opacity="0.3"/>"##,
            panel.px(p.0),
            panel.py(p.1)
        );
    }
    let mut staircase: Vec<(f64, f64)> = front.iter().filter(finite).copied().collect();
    staircase.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    let mut steps = Vec::new();
    for (k, &(x, y)) in staircase.iter().enumerate() {
        if k > 0 {
            steps.push((x, staircase[k - 1].1));
        }
        steps.push((x, y));
    }
    panel.line(&mut out, &steps, COLOURS[1], false);
    for p in &staircase {
        let _ = writeln!(
            out,
            r#"<circle cx="{:.2}" cy="{:.2}" r="4" fill="{}"/>"#,
            panel.px(p.0),
            panel.py(p.1),
            COLOURS[1]
        );
    }
    out.push_str("</svg>\n");
    out
}

/// The convergence of a run, `names` the objectives' names in the run's order: on top, per
/// generation, each objective's population minimum (solid) and mean (dashed), one colour per
/// objective; below, the hypervolume per generation ([`super::nsga2::Generation::hypervolume`]).
pub(crate) fn convergence_svg(history: &History, names: &[&str]) -> String {
    let height = 2.0 * (TOP + PANEL + BOTTOM) + 20.0;
    let mut out = header(height);
    if history.generations.is_empty() {
        note(&mut out, TOP, "no generation to draw");
        out.push_str("</svg>\n");
        return out;
    }
    let gens = &history.generations;
    let (xlo, xhi) = bounds(gens.iter().map(|g| g.index as f64));
    let values = gens
        .iter()
        .flat_map(|g| g.min.iter().chain(&g.mean).copied());
    let (ylo, yhi) = bounds(values);
    // Penalised values (a violated constraint costs 100 on every objective) would flatten the
    // curves: the axis stops at the reference point and what is above is drawn at the top.
    let cap = history
        .config
        .reference
        .iter()
        .copied()
        .filter(|r| r.is_finite())
        .reduce(f64::max)
        .filter(|r| *r > ylo && *r < yhi);
    let yhi = cap.unwrap_or(yhi);
    let top = Panel {
        x0: LEFT,
        y0: TOP + 20.0,
        w: WIDTH - LEFT - RIGHT,
        h: PANEL,
        x: Axis::new(xlo, xhi),
        y: Axis::new(ylo, yhi),
    };
    top.axes(
        &mut out,
        if cap.is_some() {
            "minimum (solid) and mean (dashed) per generation, capped at the reference"
        } else {
            "objectives per generation: minimum (solid), mean (dashed)"
        },
        "generation",
        "objective value (minimised)",
    );
    let mut legend = Vec::new();
    for k in 0..history.objectives {
        let colour = COLOURS[k % COLOURS.len()];
        let series = |pick: fn(&super::nsga2::Generation) -> &Vec<f64>| -> Vec<(f64, f64)> {
            gens.iter()
                .map(|g| {
                    let v = pick(g).get(k).copied().unwrap_or(f64::NAN);
                    (g.index as f64, v.min(yhi))
                })
                .collect()
        };
        top.line(&mut out, &series(|g| &g.min), colour, false);
        top.line(&mut out, &series(|g| &g.mean), colour, true);
        legend.push((name(names, k), colour));
    }
    let mut lx = LEFT;
    for (label, colour) in &legend {
        let _ = writeln!(
            out,
            r#"<rect x="{lx:.2}" y="{:.2}" width="10" height="10" fill="{colour}"/>"#,
            TOP - 30.0
        );
        let _ = writeln!(
            out,
            r#"<text x="{:.2}" y="{:.2}">{}</text>"#,
            lx + 14.0,
            TOP - 20.0,
            escape(label)
        );
        lx += 22.0 + 7.0 * label.chars().count() as f64;
    }

    let hv: Vec<(f64, f64)> = gens
        .iter()
        .map(|g| (g.index as f64, g.hypervolume))
        .collect();
    let (hlo, hhi) = bounds(hv.iter().map(|p| p.1));
    let bottom = Panel {
        x0: LEFT,
        y0: TOP + PANEL + BOTTOM + TOP + 20.0,
        w: WIDTH - LEFT - RIGHT,
        h: PANEL,
        x: Axis::new(xlo, xhi),
        y: Axis::new(hlo.min(0.0), hhi),
    };
    bottom.axes(
        &mut out,
        "hypervolume per generation",
        "generation",
        "hypervolume",
    );
    bottom.line(&mut out, &hv, "#000000", false);
    out.push_str("</svg>\n");
    out
}
