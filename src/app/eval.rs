//! `citygen eval`: the truth benchmark of the height and roof estimator, and the offline fit
//! of its shipped models (`crate::pipeline::eval`).

use std::path::PathBuf;

use clap::Args;

use super::{AppError, Outcome};
use crate::pipeline::eval::{Case, CaseScore, EvalOptions, Score};
use crate::pipeline::Source;

/// `citygen eval`.
#[derive(Args, Debug)]
pub(crate) struct EvalArgs {
    /// The inputs: `FILE.osm.pbf` or `FILE.shp` to hide the input's own tags fold by fold, or
    /// `FILE=TRUTH.csv` to compare with measured heights and roofs (`id,height_m,roof`; every
    /// tag of height, storeys and roof removed first).
    #[arg(required = true, value_name = "INPUT[=TRUTH.csv]")]
    cases: Vec<String>,
    /// The knowledge base (regional roof priors and storey heights).
    #[arg(long, value_name = "FILE.xml", default_value = "knowledge_base/kb.xml")]
    kb: PathBuf,
    /// Folds for hidden tags: a 1/FOLDS share hidden at a time.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u64).range(2..=20))]
    folds: u64,
    /// Chooses the folds; several (`--seed 1,2,3`) score every input once a seed and print
    /// the mean of each case's ratios over them (a hidden third moves a city's storeys ratio
    /// by up to 0.15 from one seed to the next). `--json` and `--dump` hold the first seed's.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "1",
        value_name = "SEED[,SEED...]"
    )]
    seed: Vec<u64>,
    /// Use the models in this folder (`height.gbt`, `roof.gbt`) instead of the shipped ones.
    #[arg(long, value_name = "DIR")]
    model: Option<PathBuf>,
    /// Fit the shipped models on every input's truth or tags and write them into this folder.
    #[arg(long, value_name = "DIR")]
    save_model: Option<PathBuf>,
    /// Measure each input with models fitted on the other inputs only (leave one city out).
    #[arg(long)]
    loco: bool,
    /// Also fit a model on each input's visible tags (cross-validated; runs do not, so that an
    /// estimate depends on its surroundings only and a nightly increment stays local).
    #[arg(long)]
    fit: bool,
    /// Write the scores as JSON here.
    #[arg(long, value_name = "OUT.json")]
    json: Option<PathBuf>,
    /// Write every compared building as a CSV line here: its features, its zone's prior, the
    /// estimate and the truth (for analysis outside citygen).
    #[arg(long, value_name = "OUT.csv")]
    dump: Option<PathBuf>,
}

fn case(arg: &str) -> Case {
    let (input, truth) = match arg.split_once('=') {
        Some((a, b)) => (a, Some(PathBuf::from(b))),
        None => (arg, None),
    };
    let path = PathBuf::from(input);
    let shp = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("shp"));
    let source = if shp {
        Source::Shp {
            path,
            height_field: None,
            levels_field: None,
            fields: Vec::new(),
            layer: None,
        }
    } else {
        Source::Osm(path)
    };
    Case { source, truth }
}

fn cell(s: &Option<Score>, unit: &str) -> String {
    match s {
        Some(s) => format!(
            "{:>5} {:>6.2}{unit} {:>6.2}{unit} {:>5.2}{}",
            s.n,
            s.error,
            s.baseline,
            s.ratio(),
            s.rank.map_or(String::new(), |r| format!(" ρ {r:.2}"))
                + &s.medians
                    .map_or(String::new(), |(e, t)| format!(" med {e:.1}/{t:.1}"))
        ),
        None => "-".to_string(),
    }
}

fn print(scores: &[CaseScore]) {
    println!("case | mode | height: n, MAE, constant median, ratio, rank | storeys: n, MAE, constant, ratio (exact) | roof flat/pitched: n, wrong, majority wrong, ratio");
    for s in scores {
        let exact = s
            .storeys
            .as_ref()
            .and_then(|x| x.exact)
            .map_or(String::new(), |e| format!(" ({:.0} % exact)", 100.0 * e));
        println!(
            "{} | {} | {} | {}{exact} | {}",
            s.name,
            s.mode,
            cell(&s.height, " m"),
            cell(&s.storeys, ""),
            cell(&s.roof, "")
        );
    }
    for s in scores {
        if let Some(f) = &s.form {
            println!(
                "{} as a run draws it: {} estimated, {:.1} % at 5+ storeys, {:.1} % of those under 60 m² above 2 storeys, storeys-area rank {:.2}, {:.1} % of {} touching pairs differ in roof family ({:.1} % of {} like-sized row pairs)",
                s.name,
                f.estimated,
                100.0 * f.five_plus,
                100.0 * f.small_above_two,
                f.storey_area_rank,
                100.0 * f.pairs_differing,
                f.touching_pairs,
                100.0 * f.row_pairs_differing,
                f.row_pairs
            );
        }
    }
    for s in scores {
        if let Some(a) = &s.attached_roofs {
            println!(
                "{} attached footprints of {} m² and more (a tenth of the walls shared): {:.1} % of {} flat roofs drawn pitched, {:.1} % of {} pitched drawn flat",
                s.name,
                crate::pipeline::eval::ATTACHED_MIN_M2,
                100.0 * a.flat_drawn_pitched,
                a.flat,
                100.0 * a.pitched_drawn_flat,
                a.pitched
            );
        }
    }
    let total = |get: fn(&CaseScore) -> &Option<Score>| {
        let v: Vec<&Score> = scores.iter().filter_map(|s| get(s).as_ref()).collect();
        let n: usize = v.iter().map(|s| s.n).sum();
        let e: f64 = v.iter().map(|s| s.error * s.n as f64).sum::<f64>();
        let b: f64 = v.iter().map(|s| s.baseline * s.n as f64).sum::<f64>();
        (n, e / n.max(1) as f64, b / n.max(1) as f64)
    };
    let (n, e, b) = total(|s| &s.height);
    println!(
        "all heights: n {n}, MAE {e:.2} m, constant {b:.2} m, ratio {:.2}",
        e / b.max(1e-9)
    );
    let (n, e, b) = total(|s| &s.roof);
    println!(
        "all roofs: n {n}, right {:.1} %, majority right {:.1} %",
        100.0 * (1.0 - e),
        100.0 * (1.0 - b)
    );
}

/// The mean over seeds of each case's ratios (height, storeys, roof), in the order of the
/// first seed's cases; a ratio missing for a seed leaves that seed out of its mean.
fn print_means(runs: &[Vec<CaseScore>]) {
    println!(
        "mean over {} seeds | case | mode | height ratio | storeys ratio | roof ratio",
        runs.len()
    );
    let Some(first) = runs.first() else { return };
    for (i, s) in first.iter().enumerate() {
        let mean = |get: fn(&CaseScore) -> &Option<Score>| {
            let v: Vec<f64> = runs
                .iter()
                .filter_map(|r| r.get(i).and_then(|c| get(c).as_ref()))
                .map(|x| x.ratio())
                .collect();
            if v.is_empty() {
                "-".to_string()
            } else {
                format!("{:.2}", v.iter().sum::<f64>() / v.len() as f64)
            }
        };
        println!(
            "mean | {} | {} | {} | {} | {}",
            s.name,
            s.mode,
            mean(|c| &c.height),
            mean(|c| &c.storeys),
            mean(|c| &c.roof)
        );
    }
}

/// `citygen eval`.
pub(crate) fn run(args: EvalArgs) -> Result<Outcome, AppError> {
    let mut runs = Vec::with_capacity(args.seed.len());
    for (k, &seed) in args.seed.iter().enumerate() {
        let opts = EvalOptions {
            cases: args.cases.iter().map(|c| case(c)).collect(),
            kb: Some(args.kb.clone()),
            folds: args.folds as usize,
            seed,
            model: args.model.clone(),
            // Fitted on every input's truth or tags: once is enough.
            save_model: args.save_model.clone().filter(|_| k == 0),
            loco: args.loco,
            fit: args.fit,
        };
        let scores = crate::pipeline::eval::run(&opts)?;
        if args.seed.len() > 1 {
            println!("seed {seed}");
        }
        print(&scores);
        runs.push(scores);
    }
    if runs.len() > 1 {
        print_means(&runs);
    }
    let scores = &runs[0];
    if let Some(p) = &args.json {
        crate::pipeline::eval::write_scores(p, scores)?;
    }
    if let Some(p) = &args.dump {
        crate::pipeline::eval::write_dump(p, scores)?;
    }
    Ok(Outcome::Done)
}
