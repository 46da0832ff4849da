//! `citygen evolve`: its arguments, the search, the baseline table and `--into-kb`.

use std::path::PathBuf;

use clap::Args;

use super::{AppError, Outcome};

/// `citygen evolve`.
#[derive(Args, Debug)]
pub(crate) struct EvolveArgs {
    /// The objectives, comma-separated: vsym, hsym, uniform, rectilinear, monolithic,
    /// fragmented.
    #[arg(long, value_name = "LIST")]
    objectives: String,
    /// The test facade, WIDTHxHEIGHT metres (default 12x9).
    #[arg(long, value_name = "WxH", conflicts_with = "lot")]
    facade: Option<String>,
    /// A box building on a WIDTHxDEPTH lot instead (its front facade is scored), --height m
    /// to the eaves.
    #[arg(long, value_name = "WxD")]
    lot: Option<String>,
    /// The box building's wall height with --lot, metres.
    #[arg(long, default_value_t = 9.0, requires = "lot")]
    height: f64,
    /// Individuals per generation.
    #[arg(long, default_value_t = 50, value_parser = clap::value_parser!(u32).range(2..=10_000))]
    population: u32,
    /// The generation cap (the search also stops earlier when it has converged: --window).
    #[arg(long, default_value_t = 30, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    generations: u32,
    /// The convergence window: the search stops when the population's min and mean of every
    /// objective have not changed over this many generations.
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    window: u32,
    /// The seed of the search and of the test facades' random choices.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// The output folder.
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Also compare with random search on N seeds (from --seed; the same number of evaluations
    /// each): baseline.json and a table.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..=1000))]
    baseline: Option<u64>,
    /// Add the best front member of each objective as appearances of --zone in this knowledge
    /// base (rulesets written to evolved/ beside it; the KB edited atomically, checked first).
    #[arg(long, value_name = "KB", requires = "zone")]
    into_kb: Option<PathBuf>,
    /// The zone for --into-kb (a path as `kb explain` prints it, or its tail).
    #[arg(long, value_name = "PATH", requires = "into_kb")]
    zone: Option<String>,
    /// The share of the group's buildings the new appearances take together (0 < S < 1; a
    /// group without appearances of its own gets only the new ones).
    #[arg(long, default_value_t = 0.5, requires = "into_kb")]
    share: f64,
    /// The building kinds the evolved facades are for (OSM building=* values, comma-separated):
    /// they join the zone's appearances whose `building` list holds them all, take that group's
    /// values and its list (`yes`: the appearances without a list). Default: the appearances
    /// without a list, else the group of `apartments`.
    #[arg(long, value_name = "LIST", value_delimiter = ',', requires = "into_kb")]
    kinds: Option<Vec<String>>,
    /// Worker threads (default: all cores). The files do not depend on it.
    #[arg(long)]
    threads: Option<usize>,
}

/// `citygen evolve`.
pub(crate) fn run(args: EvolveArgs) -> Result<Outcome, AppError> {
    use crate::evolve::{nsga2, objectives::Objective, run};
    let fail = |msg: String| Err(AppError::Usage(msg));
    if let Some(n) = args.threads {
        let _ = rayon::ThreadPoolBuilder::new()
            .num_threads(n.max(1))
            .build_global();
    }
    let objectives = match Objective::parse_list(&args.objectives) {
        Ok(o) => o,
        Err(e) => return fail(format!("--objectives: {e}")),
    };
    let test = match (&args.lot, &args.facade) {
        (Some(l), _) => run::TestObject::parse(l, true, args.height),
        (None, Some(f)) => run::TestObject::parse(f, false, 0.0),
        (None, None) => Ok(run::TestObject::default()),
    };
    let test = match test {
        Ok(t) => t,
        Err(e) => return fail(e.to_string()),
    };
    if args.lot.is_some() && !(args.height.is_finite() && (2.0..=200.0).contains(&args.height)) {
        return fail(format!("--height {}: give 2-200 m", args.height));
    }
    let settings = run::Settings {
        objectives,
        test,
        config: nsga2::Config {
            population: args.population as usize,
            generations: args.generations as usize,
            seed: args.seed,
            window: args.window as usize,
            ..nsga2::Config::default()
        },
    };
    let (history, secs) = run::search(&settings);
    let w = match run::write_outputs(&args.out, &settings, &history) {
        Ok(w) => w,
        Err(e) => return Err(AppError::Output(e.to_string())),
    };
    let gens = history.generations.len();
    eprintln!(
        "citygen evolve: {} generations ({:?}), {} evaluations, {:.2} s ({:.3} s a generation); \
         front of {}, hypervolume {:.1}",
        gens,
        history.stopped,
        history.evaluations,
        secs,
        secs / gens.max(1) as f64,
        w.members.len(),
        history.hypervolume
    );
    for p in &w.files {
        eprintln!("  wrote {}", p.display());
    }
    if let Some(n) = args.baseline {
        let rows = run::baseline(&settings, n);
        eprintln!(
            "  seed  NSGA-II hypervolume (reached after)  random search (reached after)  \
             evaluations  s/generation"
        );
        let after = |e: Option<usize>| e.map_or_else(|| "-".to_string(), |e| e.to_string());
        for r in &rows {
            eprintln!(
                "  {:>4}  {:>19.1} {:>16}  {:>13.1} {:>15}  {:>11}  {:>12.3}",
                r.seed,
                r.nsga2,
                format!("({})", after(r.nsga2_evaluations_to_final)),
                r.random,
                format!("({})", after(r.random_evaluations_to_final)),
                r.evaluations,
                r.seconds_per_generation
            );
        }
        let mean = |f: &dyn Fn(&run::BaselineRow) -> f64| {
            rows.iter().map(f).sum::<f64>() / rows.len().max(1) as f64
        };
        let wins = rows.iter().filter(|r| r.nsga2 > r.random).count();
        let ties: Vec<&run::BaselineRow> = rows.iter().filter(|r| r.nsga2 == r.random).collect();
        let sooner = ties
            .iter()
            .filter(|r| r.nsga2_evaluations_to_final < r.random_evaluations_to_final)
            .count();
        eprintln!(
            "  mean hypervolume: NSGA-II {:.1}, random search {:.1}; NSGA-II higher on {wins} of \
             {} seeds, equal on {} (of which it got there first on {sooner})",
            mean(&|r| r.nsga2),
            mean(&|r| r.random),
            rows.len(),
            ties.len()
        );
        let json = serde_json::to_string_pretty(&rows).unwrap_or_default() + "\n";
        let p = args.out.join("baseline.json");
        if let Err(e) = run::write_atomic(&p, json.as_bytes()) {
            return Err(AppError::Output(e.to_string()));
        }
        eprintln!("  wrote {}", p.display());
    }
    if let (Some(kb), Some(zone)) = (args.into_kb, args.zone) {
        // The best member of each objective, once each.
        let mut chosen: Vec<(String, String)> = Vec::new();
        let mut seen = std::collections::BTreeSet::new();
        for &(name, i) in &w.best {
            if !seen.insert(i) {
                continue;
            }
            let Some(m) = w.members.get(i) else { continue };
            match std::fs::read_to_string(args.out.join(&m.rules)) {
                Ok(t) => chosen.push((format!("{name}-{}", args.seed), t)),
                Err(e) => return fail(format!("{}: {e}", m.rules)),
            }
        }
        let target = run::IntoKb {
            kb: kb.clone(),
            zone,
            share: args.share,
            kinds: args.kinds.map(|k| {
                k.into_iter()
                    .map(|s| s.trim().to_string())
                    .filter(|s| !s.is_empty())
                    .collect()
            }),
        };
        match run::into_kb(&target, &chosen) {
            Ok(a) => {
                let kinds = if a.kinds.is_empty() {
                    "without a building list (building=yes and kinds no group names)".to_string()
                } else {
                    format!("for building={}", a.kinds.join(","))
                };
                eprintln!(
                    "  added {} appearance(s) to {} in {}, among its appearances {kinds}: \
                     {:.0} % of those buildings; the group's own weights scaled to the rest",
                    a.rulesets.len(),
                    a.zone,
                    kb.display(),
                    a.share * 100.0
                );
                for (p, w) in a.rulesets.iter().zip(&a.probas) {
                    eprintln!("    proba {w:.4}: {}", p.display());
                }
            }
            Err(e) => return fail(e.to_string()),
        }
    }
    Ok(Outcome::Done)
}
