//! `citygen evolve`: the search run end to end: genomes decoded ([`super::decode`](mod@super::decode)), derived on
//! the test facade ([`super::facade`]), scored ([`super::objectives`]) and evolved
//! ([`super::nsga2`]); the front written as ruleset files with pictures and a JSON report; the
//! comparison with random search (`--baseline`); and the chosen rulesets added to a knowledge
//! base's zone (`--into-kb`).
//!
//! Every file is written to a temporary beside it and renamed into place, so a failed run
//! leaves no half-written file. The same settings and seed give the same files, whatever the
//! thread count (the search draws its random numbers in sequence; each genome's test facade
//! is derived with the run's seed).

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Serialize;

use super::nsga2::{self, Config, History, Individual};
use super::objectives::{self, Objective};
use super::{decode, facade, genome, EvolveError, Facade};

/// The test object every genome is derived on.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum TestObject {
    /// A flat facade `width` × `height` metres (the thesis's "single simple facade object").
    Facade {
        /// Metres.
        width: f64,
        /// Metres.
        height: f64,
    },
    /// A box building on a `width` × `depth` lot, `height` metres to the eaves: the whole
    /// ruleset derived, its front facade read.
    Lot {
        /// Metres.
        width: f64,
        /// Metres.
        depth: f64,
        /// Metres.
        height: f64,
    },
}

impl Default for TestObject {
    fn default() -> Self {
        TestObject::Facade {
            width: decode::REFERENCE_WIDTH,
            height: decode::REFERENCE_HEIGHT,
        }
    }
}

impl TestObject {
    /// The facade's width and height, metres.
    pub fn size(&self) -> (f64, f64) {
        match *self {
            TestObject::Facade { width, height } => (width, height),
            TestObject::Lot { width, height, .. } => (width, height),
        }
    }

    /// `WxH` (a facade) or `WxD` (a lot, with `height`) in metres.
    pub fn parse(text: &str, lot: bool, height: f64) -> Result<TestObject, EvolveError> {
        let (a, b) = text
            .split_once(['x', 'X'])
            .ok_or_else(|| EvolveError::SizeFormat {
                text: text.to_string(),
            })?;
        let num = |s: &str| -> Result<f64, EvolveError> {
            let v: f64 = s.trim().parse().map_err(|_| EvolveError::SizeNumber {
                text: text.to_string(),
                side: s.to_string(),
            })?;
            if v.is_finite() && (1.0..=200.0).contains(&v) {
                Ok(v)
            } else {
                Err(EvolveError::SizeRange {
                    text: text.to_string(),
                    value: v,
                })
            }
        };
        let (a, b) = (num(a)?, num(b)?);
        Ok(if lot {
            TestObject::Lot {
                width: a,
                depth: b,
                height,
            }
        } else {
            TestObject::Facade {
                width: a,
                height: b,
            }
        })
    }
}

/// What `citygen evolve` is asked.
#[derive(Clone, Debug)]
pub struct Settings {
    /// The objectives, all minimised.
    pub objectives: Vec<Objective>,
    /// The test object.
    pub test: TestObject,
    /// The search's settings (its reference point is set from the objectives).
    pub config: Config,
}

/// One genome's evaluation: its decoded ruleset and its facade as derived.
pub(crate) fn evaluate(
    genes: &[u32],
    test: &TestObject,
    seed: u64,
) -> (Option<decode::Decoded>, Facade) {
    let (w, h) = test.size();
    let decoded = match decode::decode_for(genes, w, h) {
        Ok(d) => d,
        Err(_) => {
            return (
                None,
                Facade {
                    width: w,
                    height: h,
                    violations: 1,
                    ..Facade::default()
                },
            )
        }
    };
    let f = match *test {
        TestObject::Facade { width, height } => {
            facade::derive_facade(decoded.facade_rules(), width, height, seed)
        }
        TestObject::Lot {
            width,
            depth,
            height,
        } => facade::derive_lot_facade(&decoded.text, width, depth, height, seed),
    };
    (Some(decoded), f)
}

/// Test facades a genome is scored on, seeded `seed`, `seed + 1`, ...: the objectives are
/// their means. The decoded rules choose their terminals when written ([`decode::choose_terminal`]),
/// so a derivation is the same whatever its seed and one is enough; more would average the
/// draws of rules with stochastic choices.
pub(crate) const SAMPLES: u64 = 1;

/// The objective values of one genome (each with the global constraints' penalty): means
/// over [`SAMPLES`] derivations.
pub(crate) fn score(genes: &[u32], settings: &Settings) -> Vec<f64> {
    let mut sum = vec![0.0; settings.objectives.len()];
    for k in 0..SAMPLES {
        let (decoded, f) = evaluate(genes, &settings.test, settings.config.seed.wrapping_add(k));
        let v = objectives::score(&f, &settings.objectives);
        for (s, x) in sum.iter_mut().zip(v) {
            *s += x;
        }
        if decoded.is_none() {
            // Not decoded: every draw is the same failure.
            return sum;
        }
    }
    sum.iter().map(|s| s / SAMPLES as f64).collect()
}

/// The search's settings with the reference point of the objectives and the genome's cut
/// order (crossover between steps, [`genome::cut_order`]) unless the settings give one.
fn config_of(settings: &Settings) -> Config {
    let cut_order = if settings.config.cut_order.is_empty() {
        genome::cut_order()
    } else {
        settings.config.cut_order.clone()
    };
    Config {
        reference: objectives::reference_point(&settings.objectives),
        cut_order,
        ..settings.config.clone()
    }
}

/// Runs NSGA-II. Returns the history and the wall time in seconds.
pub fn search(settings: &Settings) -> (History, f64) {
    let t = Instant::now();
    let alphabet = genome::alphabet();
    let h = nsga2::run(&config_of(settings), &alphabet, |g| score(g, settings));
    (h, t.elapsed().as_secs_f64())
}

/// Random search with `evaluations` distinct genomes (the same budget as a search).
pub fn random(settings: &Settings, evaluations: usize) -> History {
    let alphabet = genome::alphabet();
    nsga2::random_search(
        &config_of(settings),
        &alphabet,
        |g| score(g, settings),
        evaluations,
    )
}

/// One seed of the comparison with random search.
#[derive(Clone, Debug, Serialize)]
pub(crate) struct BaselineRow {
    /// The seed.
    pub seed: u64,
    /// NSGA-II's final hypervolume.
    pub nsga2: f64,
    /// Random search's final hypervolume with the same number of evaluations.
    pub random: f64,
    /// That number.
    pub evaluations: usize,
    /// The evaluations NSGA-II had made when it first reached its final hypervolume.
    pub nsga2_evaluations_to_final: Option<usize>,
    /// The evaluations random search had made when it first reached its own final hypervolume.
    pub random_evaluations_to_final: Option<usize>,
    /// NSGA-II's generations and wall time per generation, seconds.
    pub generations: usize,
    /// Seconds per generation of NSGA-II.
    pub seconds_per_generation: f64,
}

/// NSGA-II against random search on `seeds` consecutive seeds from the settings' seed.
pub(crate) fn baseline(settings: &Settings, seeds: u64) -> Vec<BaselineRow> {
    (0..seeds)
        .map(|i| {
            let mut s = settings.clone();
            s.config.seed = settings.config.seed.wrapping_add(i);
            let (h, secs) = search(&s);
            let r = random(&s, h.evaluations);
            BaselineRow {
                seed: s.config.seed,
                nsga2: h.hypervolume,
                random: r.hypervolume,
                evaluations: h.evaluations,
                nsga2_evaluations_to_final: h.evaluations_to_reach(h.hypervolume),
                random_evaluations_to_final: r.evaluations_to_reach(r.hypervolume),
                generations: h.generations.len(),
                seconds_per_generation: secs / h.generations.len().max(1) as f64,
            }
        })
        .collect()
}

/// A front member as the report lists it.
#[derive(Clone, Debug, Serialize)]
pub struct Member {
    /// Its ruleset file, relative to the output folder.
    pub rules: String,
    /// Its facade picture.
    pub picture: String,
    /// The genome.
    pub genome: Vec<u32>,
    /// The objective values (penalty included), in the order of the objectives.
    pub objectives: Vec<f64>,
    /// The terminal matrix of its test facade, bottom row first.
    pub matrix: super::Matrix,
    /// Its test facade's terminals.
    pub terminals: usize,
    /// Global-constraint violations (each costs `objectives::PENALTY` on every objective).
    pub violations: usize,
}

/// The JSON report of a run (`evolve.json`).
#[derive(Clone, Debug, Serialize)]
pub struct Report<'a> {
    /// citygen's version.
    pub citygen: &'static str,
    /// The objectives' names.
    pub objectives: Vec<&'static str>,
    /// The test object.
    pub test: TestObject,
    /// The genome's layout.
    pub genome: String,
    /// The front, as written.
    pub front: Vec<Member>,
    /// The best member for each objective (index into `front`), by objective name.
    pub best: Vec<(&'static str, usize)>,
    /// The search: settings, every generation's individuals, min, mean and hypervolume, why it
    /// stopped.
    pub history: &'a History,
}

/// Writes `bytes` to `path` through a temporary beside it ([`crate::fsio::write_atomic`]); the
/// error names the folder, temporary or target that failed.
pub(crate) fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), EvolveError> {
    Ok(crate::fsio::write_atomic(path, bytes)?)
}

/// The header comment of a front member's ruleset file.
fn header(names: &[&str], ind: &Individual, test: &TestObject) -> String {
    let values: Vec<String> = names
        .iter()
        .zip(&ind.objectives)
        .map(|(n, v)| format!("{n} {v}"))
        .collect();
    let object = match *test {
        TestObject::Facade { width, height } => format!("a {width} x {height} m facade"),
        TestObject::Lot {
            width,
            depth,
            height,
        } => format!("the front of a {width} x {depth} m box building, {height} m high"),
    };
    let derivations = if SAMPLES == 1 {
        "one derivation".to_string()
    } else {
        format!("means over {SAMPLES} derivations")
    };
    format!(
        "# Objectives ({derivations} of the test object, {object}): {}\n",
        values.join(", ")
    )
}

/// The rules a city gets for the decoded `text`: the same, but each window and door cell of
/// the test facade becomes a pane or a door framed by wall (a cell is a whole bay of the
/// facade; as a city's opening it would touch its neighbours and fill its storey).
pub(crate) fn city_rules(text: &str) -> String {
    let mut out = String::with_capacity(text.len() + 512);
    for line in text.lines() {
        let framed = line.split_once(" -> ").and_then(|(lhs, rhs)| {
            let rhs = rhs.trim();
            let (term, rest) = rhs.split_once(' ').unwrap_or((rhs, ""));
            let to = match term {
                "window" => "evolve_window",
                "door" => "evolve_door",
                _ => return None,
            };
            Some(format!(
                "{lhs} -> {to}{}{rest}",
                if rest.is_empty() { "" } else { " " }
            ))
        });
        out.push_str(framed.as_deref().unwrap_or(line));
        out.push('\n');
    }
    if out.contains("evolve_window") {
        out.push_str(
            "# A window cell framed for a city: a pane with wall around it.\n\
             evolve_window -> rsplit(X, 0.15, 0.7, 0.15){wall | evolve_window_column | wall}\n\
             evolve_window_column -> rsplit(Z, 0.25, 0.6, 0.15){wall | window | wall}\n",
        );
    }
    if out.contains("evolve_door") {
        out.push_str(
            "# A door cell framed for a city: a door 0.4 of its width and 0.9 of its height.\n\
             evolve_door -> rsplit(X, 0.3, 0.4, 0.3){wall | evolve_door_column | wall}\n\
             evolve_door_column -> rsplit(Z, 0.9, 0.1){door | wall}\n",
        );
    }
    out
}

/// What [`write_outputs`] wrote.
#[derive(Clone, Debug)]
pub(crate) struct Written {
    /// The front as written.
    pub members: Vec<Member>,
    /// The best member of each objective (index into `members`), by objective name.
    pub best: Vec<(&'static str, usize)>,
    /// Every file written.
    pub files: Vec<PathBuf>,
}

/// Writes the run's files into `out`: `front/NN.cga` and `front/NN.svg` per member,
/// `best-OBJECTIVE.cga|svg`, `front.svg`, `convergence.svg`, `evolve.json`.
pub(crate) fn write_outputs(
    out: &Path,
    settings: &Settings,
    history: &History,
) -> Result<Written, EvolveError> {
    let names: Vec<&'static str> = settings.objectives.iter().map(|o| o.name()).collect();
    let mut written = Vec::new();
    let mut put = |rel: &str, bytes: &[u8]| -> Result<(), EvolveError> {
        let p = out.join(rel);
        write_atomic(&p, bytes)?;
        written.push(p);
        Ok(())
    };
    let mut members = Vec::new();
    let mut texts = Vec::new();
    // Members with the same objective values and the same terminal matrix look alike: the
    // first (in the front's order) stands for them.
    let mut looks = std::collections::BTreeSet::new();
    for ind in &history.front {
        let (decoded, f) = evaluate(&ind.genome, &settings.test, settings.config.seed);
        let Some(decoded) = decoded else { continue };
        let bits: Vec<u64> = ind.objectives.iter().map(|v| v.to_bits()).collect();
        if !looks.insert((bits, f.matrix.clone())) {
            continue;
        }
        let i = members.len();
        let rules = format!("front/{i:02}.cga");
        let picture = format!("front/{i:02}.svg");
        let text = format!(
            "{}{}",
            header(&names, ind, &settings.test),
            city_rules(&decoded.text)
        );
        put(&rules, text.as_bytes())?;
        put(&picture, super::svg::facade_svg(&f).as_bytes())?;
        texts.push((text, super::svg::facade_svg(&f)));
        members.push(Member {
            rules,
            picture,
            genome: ind.genome.clone(),
            objectives: ind.objectives.clone(),
            matrix: f.matrix.clone(),
            terminals: f.terminals.len(),
            violations: objectives::global_violations(&f) + f.violations,
        });
    }
    let mut best = Vec::new();
    for (k, name) in names.iter().enumerate() {
        let Some((i, _)) = members.iter().enumerate().min_by(|a, b| {
            let va = a.1.objectives.get(k).copied().unwrap_or(f64::INFINITY);
            let vb = b.1.objectives.get(k).copied().unwrap_or(f64::INFINITY);
            va.total_cmp(&vb).then(a.0.cmp(&b.0))
        }) else {
            continue;
        };
        best.push((*name, i));
        if let Some((text, svg)) = texts.get(i) {
            put(&format!("best-{name}.cga"), text.as_bytes())?;
            put(&format!("best-{name}.svg"), svg.as_bytes())?;
        }
    }
    put(
        "front.svg",
        super::plot::front_svg(history, &names).as_bytes(),
    )?;
    put(
        "convergence.svg",
        super::plot::convergence_svg(history, &names).as_bytes(),
    )?;
    let report = Report {
        citygen: env!("CARGO_PKG_VERSION"),
        objectives: names.clone(),
        test: settings.test,
        genome: format!(
            "{} genes: {} (action, arrangement) pairs in 0..3, then {} parameters in 0..7 (src/evolve/genome.rs)",
            genome::LENGTH,
            genome::STEPS,
            genome::STEPS
        ),
        front: members.clone(),
        best: best.clone(),
        history,
    };
    let json = serde_json::to_string_pretty(&report)?;
    put("evolve.json", (json + "\n").as_bytes())?;
    Ok(Written {
        members,
        best,
        files: written,
    })
}

/// `--into-kb`: what to add and where.
#[derive(Clone, Debug)]
pub(crate) struct IntoKb {
    /// The knowledge base file, edited in place (atomically).
    pub kb: PathBuf,
    /// The zone's path (`kb explain` spelling; a tail such as `Monaco/Fontvieille` works).
    pub zone: String,
    /// The share of the group's buildings the new appearances take together, 0 < share < 1
    /// (ignored for a group without appearances of its own: there they take all).
    pub share: f64,
    /// The building kinds the new appearances are for (`--kinds`): the zone's group whose
    /// `building` list holds them all; `yes` alone means the appearances without a list.
    /// `None`: the appearances without a list, else the group of `apartments`.
    pub kinds: Option<Vec<String>>,
}

/// The zone's appearances that one `building` list serves (the run draws among them and their
/// weights sum to 1).
#[derive(Clone, Debug, PartialEq)]
struct Group {
    /// The list as the text has it (`None`: the appearances without a list).
    building: Option<String>,
    /// Indices of the zone's appearances in the group.
    members: Vec<usize>,
}

/// The group the evolved appearances join (see [`IntoKb::kinds`]); a list no group holds
/// makes a new group of those kinds; `None` when no kinds are given and the zone has neither
/// appearances without a list nor a group of `apartments`.
fn target_group(buildings: &[Option<String>], kinds: Option<&[String]>) -> Option<Group> {
    let list = |b: &Option<String>| -> Vec<String> {
        b.iter()
            .flat_map(|s| s.split(','))
            .map(|k| k.trim().to_string())
            .filter(|k| !k.is_empty())
            .collect()
    };
    let group_of = |pick: &dyn Fn(&[String]) -> bool| -> Option<Group> {
        let first = buildings.iter().position(|b| pick(&list(b)))?;
        let key = list(&buildings[first]);
        Some(Group {
            building: buildings[first].clone().filter(|_| !key.is_empty()),
            members: (0..buildings.len())
                .filter(|&i| list(&buildings[i]) == key)
                .collect(),
        })
    };
    let unlisted = || group_of(&|l| l.is_empty());
    match kinds {
        Some(k) if k.iter().all(|k| k == "yes") => unlisted().or(Some(Group {
            building: None,
            members: Vec::new(),
        })),
        Some(k) => group_of(&|l| k.iter().all(|x| l.contains(x))).or_else(|| {
            Some(Group {
                building: Some(k.join(",")),
                members: Vec::new(),
            })
        }),
        None => unlisted().or_else(|| group_of(&|l| l.iter().any(|x| x == "apartments"))),
    }
}

/// What `into_kb` did.
#[derive(Clone, Debug)]
pub struct Added {
    /// The zone's full path.
    pub zone: String,
    /// The ruleset files written beside the KB.
    pub rulesets: Vec<PathBuf>,
    /// Each new appearance's weight (its share of the group's buildings).
    pub probas: Vec<f64>,
    /// The share of the group's buildings they take together.
    pub share: f64,
    /// The group's kinds (empty: the appearances without a `building` list).
    pub kinds: Vec<String>,
}

/// Adds `members` (ruleset texts with a name) as appearances of a zone: the rulesets are
/// written to `evolved/` beside the KB, and the appearances after the zone's own, with the
/// `<values>` of its heaviest own appearance (so heights, roof and colours stay the place's)
/// and weights that give them `share` of its buildings together. The new KB text is read back
/// (lenient, and strict when the KB was strict-clean) before it replaces the file; on any
/// error nothing is changed.
pub(crate) fn into_kb(target: &IntoKb, members: &[(String, String)]) -> Result<Added, EvolveError> {
    use crate::kb::{edit, tools, KnowledgeBase, ReadMode};
    if members.is_empty() {
        return Err(EvolveError::NoMembers);
    }
    let kb_file = target.kb.display().to_string();
    let io = |file: &str| {
        let file = file.to_string();
        move |source| EvolveError::Io { file, source }
    };
    let edit_err = |source| EvolveError::Edit {
        file: kb_file.clone(),
        source,
    };
    let (kb, _) = KnowledgeBase::load(&target.kb)?;
    let z = tools::find_zone(&kb, &target.zone).ok_or_else(|| EvolveError::NoZone {
        file: kb_file.clone(),
        zone: target.zone.clone(),
    })?;
    let zone = &kb.zones()[z];
    let text = std::fs::read_to_string(&target.kb).map_err(io(&kb_file))?;
    let own = edit::zone_appearances(&text, zone.line).map_err(edit_err)?;
    let group = target_group(&own.buildings, target.kinds.as_deref()).ok_or_else(|| {
        EvolveError::NoKinds {
            file: kb_file.clone(),
            zone: zone.path.clone(),
        }
    })?;
    // The group's own weights as the run normalises them: given ones as they are, absent ones
    // sharing what the given leave of 1.
    let given: Vec<Option<f64>> = group
        .members
        .iter()
        .map(|&i| {
            own.values[i]
                .iter()
                .find(|(k, _)| k == "proba")
                .and_then(|(_, p)| p.trim().parse::<f64>().ok())
                .filter(|p| p.is_finite() && *p >= 0.0)
        })
        .collect();
    let weights = crate::kb::proba_weights(given.iter().copied());
    let share = if group.members.is_empty() || weights.iter().sum::<f64>() <= 0.0 {
        1.0
    } else if target.share > 0.0 && target.share < 1.0 {
        target.share
    } else {
        return Err(EvolveError::Share(target.share));
    };
    // The values of the group's heaviest appearance (the first of equals), without its weight.
    let heaviest = weights
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1).then(b.0.cmp(&a.0)))
        .map(|(k, _)| group.members[k]);
    let values: Vec<(String, String)> = heaviest
        .and_then(|i| own.values.get(i))
        .map(|v| v.iter().filter(|(k, _)| k != "proba").cloned().collect())
        .unwrap_or_default();
    // The group's weights normalised: its own appearances keep 1 - share between them.
    let rescaled: Vec<(usize, f64)> = group
        .members
        .iter()
        .zip(&weights)
        .map(|(&i, w)| (i, w * (1.0 - share)))
        .collect();
    let dir = target
        .kb
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
        .to_path_buf();
    let slug: String = zone
        .path
        .rsplit('/')
        .next()
        .unwrap_or("zone")
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() {
                c.to_ascii_lowercase()
            } else {
                '-'
            }
        })
        .collect();
    let each = share / members.len() as f64;
    let mut new = Vec::new();
    let mut files = Vec::new();
    for (name, rules) in members {
        let mut rel = format!("evolved/{slug}-{name}.cga");
        let mut k = 2;
        while dir.join(&rel).exists()
            && std::fs::read_to_string(dir.join(&rel)).ok().as_deref() != Some(rules)
        {
            rel = format!("evolved/{slug}-{name}-{k}.cga");
            k += 1;
        }
        files.push((dir.join(&rel), rules.clone()));
        new.push(edit::NewAppearance {
            proba: each,
            values: values.clone(),
            ruleset: rel,
            comment: Some(format!("citygen evolve: {name}")),
            building: group.building.clone(),
        });
    }
    let edited = edit::set_probas(&text, zone.line, &rescaled)
        .and_then(|t| edit::add_appearances(&t, zone.line, &new))
        .map_err(edit_err)?;
    // Rulesets first (new files), then the KB checked from a temporary beside it.
    let mut made = Vec::new();
    let undo = |made: &[PathBuf]| {
        for p in made {
            let _ = std::fs::remove_file(p);
        }
    };
    for (p, rules) in &files {
        if !p.exists() {
            if let Err(e) = write_atomic(p, rules.as_bytes()) {
                undo(&made);
                return Err(e);
            }
            made.push(p.clone());
        }
    }
    // The edited KB in a temporary beside it, checked there, then renamed over it (dropped on
    // an error, the temporary is removed).
    let checked = crate::fsio::write_pending(&target.kb, Some("evolve"), edited.as_bytes())
        .map_err(EvolveError::Write)
        .and_then(|pending| {
            let tmp = pending.temporary();
            let lenient = tools::check_report(tmp, ReadMode::Lenient)?;
            if lenient.has_errors() {
                return Err(EvolveError::EditedErrors(Box::new(lenient)));
            }
            let was_strict = tools::check_report(&target.kb, ReadMode::Strict)
                .map(|r| !r.has_errors())
                .unwrap_or(false);
            if was_strict {
                let strict = tools::check_report(tmp, ReadMode::Strict)?;
                if strict.has_errors() {
                    return Err(EvolveError::EditedNotStrict(Box::new(strict)));
                }
            }
            pending.commit().map_err(io(&kb_file))
        });
    if let Err(e) = checked {
        undo(&made);
        return Err(e);
    }
    Ok(Added {
        zone: zone.path.clone(),
        rulesets: files.into_iter().map(|(p, _)| p).collect(),
        probas: new.iter().map(|n| n.proba).collect(),
        share,
        kinds: group
            .building
            .iter()
            .flat_map(|b| b.split(','))
            .map(|k| k.trim().to_string())
            .filter(|k| !k.is_empty())
            .collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grammar::{lint::lint, parse};
    use crate::rng::Rng;

    fn settings(objectives: &str, population: usize, generations: usize) -> Settings {
        Settings {
            objectives: Objective::parse_list(objectives).unwrap(),
            test: TestObject::default(),
            config: Config {
                population,
                generations,
                seed: 3,
                ..Config::default()
            },
        }
    }

    #[test]
    fn city_rules_of_random_genomes_parse_lint_clean_and_frame_every_opening() {
        let mut rng = Rng::new(7, 26);
        let alphabet = genome::alphabet();
        let mut framed = 0;
        for _ in 0..300 {
            let genes: Vec<u32> = alphabet
                .iter()
                .map(|&n| (rng.next_f64() * f64::from(n)) as u32 % n)
                .collect();
            let d = decode::decode(&genes).unwrap();
            let text = city_rules(&d.text);
            let rules = parse(&text, "city").unwrap_or_else(|e| panic!("{e}\n{text}"));
            let found = lint(&rules, &text);
            assert!(found.is_empty(), "{found:?}\n{text}");
            // No window or door is a leaf of the evolved markers any more.
            for line in text
                .lines()
                .filter(|l| l.starts_with("shape") || l.starts_with("facade"))
            {
                let rhs = line.split_once(" -> ").map_or("", |(_, r)| r);
                assert!(
                    !rhs.starts_with("window") && !rhs.starts_with("door"),
                    "{line}"
                );
            }
            framed += usize::from(text.contains("evolve_window ->"));
        }
        assert!(framed > 100, "{framed} of 300 rulesets have windows");
    }

    #[test]
    fn the_same_seed_writes_the_same_files_with_one_and_two_threads() {
        let s = settings("rectilinear,monolithic", 12, 4);
        let files = |threads: usize| {
            let dir = tempfile::tempdir().unwrap();
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let (h, _) = pool.install(|| search(&s));
            let w = write_outputs(dir.path(), &s, &h).unwrap();
            assert!(!w.members.is_empty() && w.best.len() == 2);
            let mut out = Vec::new();
            for p in &w.files {
                out.push((
                    p.strip_prefix(dir.path()).unwrap().to_path_buf(),
                    std::fs::read(p).unwrap(),
                ));
            }
            out
        };
        let one = files(1);
        assert!(one.iter().any(|(p, _)| p.ends_with("evolve.json")));
        assert!(one.iter().any(|(p, _)| p.ends_with("front.svg")));
        assert!(one == files(2));
    }

    const KB: &str = r##"<earth>
  <info nbfloor="2" rooftype="flat"/>
  <town designation="T">
    <info lat="43.73" lon="7.42" dist="1"/>
    <!-- the town's own -->
    <appearance><values proba="1" color="#d8a05a" floorsize="3"/></appearance>
  </town>
</earth>
"##;

    fn member(name: &str) -> (String, String) {
        let d = decode::decode(genome::THESIS_CHROMOSOMES[0]).unwrap();
        (name.to_string(), city_rules(&d.text))
    }

    #[test]
    fn into_kb_adds_appearances_with_the_zones_values_and_checks_before_writing() {
        let dir = tempfile::tempdir().unwrap();
        let kb = dir.path().join("kb.xml");
        std::fs::write(&kb, KB).unwrap();
        let target = IntoKb {
            kb: kb.clone(),
            zone: "T".into(),
            share: 0.5,
            kinds: None,
        };
        let a = into_kb(&target, &[member("a"), member("b")]).unwrap();
        assert_eq!(a.zone, "earth/T");
        // Half of the town's buildings: its own appearance keeps 0.5, the new ones 0.25 each,
        // and the group still sums to 1.
        assert_eq!(a.probas, vec![0.25, 0.25]);
        assert!(a.kinds.is_empty());
        let text = std::fs::read_to_string(&kb).unwrap();
        assert!(
            text.starts_with(
                &KB[..KB.find("  </town>").unwrap()].replace("proba=\"1\"", "proba=\"0.5\"")
            ),
            "{text}"
        );
        assert!(text.contains(
            "<appearance><values proba=\"0.25\" color=\"#d8a05a\" floorsize=\"3\"/><ruleset file=\"evolved/t-a.cga\"/></appearance>"
        ));
        assert!(dir.path().join("evolved/t-b.cga").exists());
        let r = crate::kb::tools::check_report(&kb, crate::kb::ReadMode::Strict).unwrap();
        assert!(!r.has_errors(), "{r}");
        // The appearance's buildings are derived with the file.
        let (k, _) = crate::kb::KnowledgeBase::load(&kb).unwrap();
        let t = crate::kb::tools::find_zone(&k, "T").unwrap();
        assert_eq!(k.zones()[t].appearances.len(), 3);
        assert_eq!(
            k.ruleset_path(t, 1, false).unwrap(),
            Some(dir.path().join("evolved/t-a.cga"))
        );

        // Refusals change nothing: an unknown zone, a share out of range.
        let before = std::fs::read(&kb).unwrap();
        let files = std::fs::read_dir(dir.path().join("evolved"))
            .unwrap()
            .count();
        let bad_zone = IntoKb {
            zone: "Nowhere".into(),
            ..target.clone()
        };
        assert!(into_kb(&bad_zone, &[member("c")])
            .unwrap_err()
            .to_string()
            .contains("no zone"));
        let bad_share = IntoKb {
            share: 1.0,
            ..target.clone()
        };
        assert!(into_kb(&bad_share, &[member("c")])
            .unwrap_err()
            .to_string()
            .contains("--share"));
        assert_eq!(std::fs::read(&kb).unwrap(), before);
        assert_eq!(
            std::fs::read_dir(dir.path().join("evolved"))
                .unwrap()
                .count(),
            files
        );
        // A ruleset name taken by another file gets a new name, never overwrites it.
        std::fs::write(
            dir.path().join("evolved/t-z.cga"),
            "lot -> extrude(3){building}\n",
        )
        .unwrap();
        let a = into_kb(&target, &[member("z")]).unwrap();
        assert_eq!(a.rulesets, vec![dir.path().join("evolved/t-z-2.cga")]);
        assert_eq!(
            std::fs::read_to_string(dir.path().join("evolved/t-z.cga")).unwrap(),
            "lot -> extrude(3){building}\n"
        );
    }

    const GROUPS: &str = r##"<earth>
  <info nbfloor="2" rooftype="flat"/>
  <town designation="U">
    <info lat="40.7" lon="-74" dist="1"/>
    <appearance building="house,terrace"><values proba="1" color="#aa0000" bdRooftype="gabled"/></appearance>
    <appearance building="apartments,residential"><values proba="0.6" color="#884422" bdRooftype="flat" material="brick" floorsize="3.2"/></appearance>
    <appearance building="apartments,residential"><values proba="0.4" color="#cccccc" bdRooftype="flat" material="plaster"/></appearance>
    <appearance building="industrial,shed"><values proba="0.9" color="#777777" bdRooftype="gabled" material="metal" floorsize="5"/></appearance>
    <appearance building="industrial,shed"><values proba="0.1" color="#666666"/></appearance>
  </town>
</earth>
"##;

    type Apps = Vec<(Vec<String>, Option<f64>)>;

    /// Zone U's appearances in `kb`: (building list, proba).
    fn group_of(kb: &Path) -> Apps {
        let (k, _) = crate::kb::KnowledgeBase::load(kb).unwrap();
        let u = crate::kb::tools::find_zone(&k, "U").unwrap();
        k.zones()[u]
            .appearances
            .iter()
            .map(|a| (a.buildings.clone(), a.proba))
            .collect()
    }

    #[test]
    fn into_kb_joins_the_group_of_the_kinds_it_is_for_and_keeps_its_weights_summing_to_one() {
        let dir = tempfile::tempdir().unwrap();
        let kb = dir.path().join("kb.xml");
        std::fs::write(&kb, GROUPS).unwrap();
        let target = IntoKb {
            kb: kb.clone(),
            zone: "U".into(),
            share: 0.5,
            kinds: None,
        };
        // No list-less appearances: the default is the group of apartments (not the heaviest
        // appearance of the zone, the metal sheds), its list and its heaviest values copied.
        let a = into_kb(&target, &[member("a")]).unwrap();
        assert_eq!(a.kinds, vec!["apartments", "residential"]);
        assert_eq!(a.probas, vec![0.5]);
        let text = std::fs::read_to_string(&kb).unwrap();
        assert!(text.contains(
            "<appearance building=\"apartments,residential\"><values proba=\"0.5\" color=\"#884422\" bdRooftype=\"flat\" material=\"brick\" floorsize=\"3.2\"/><ruleset file=\"evolved/u-a.cga\"/></appearance>"
        ), "{text}");
        let apps = group_of(&kb);
        let sum = |list: &[&str]| -> f64 {
            apps.iter()
                .filter(|(b, _)| b.iter().map(String::as_str).eq(list.iter().copied()))
                .filter_map(|(_, p)| *p)
                .sum()
        };
        assert!((sum(&["apartments", "residential"]) - 1.0).abs() < 1e-9);
        assert!((sum(&["house", "terrace"]) - 1.0).abs() < 1e-9);
        assert!((sum(&["industrial", "shed"]) - 1.0).abs() < 1e-9);
        // No appearance without a list was added: building=yes is not dressed by the search.
        assert!(apps.iter().all(|(b, _)| !b.is_empty()));
        let r = crate::kb::tools::check_report(&kb, crate::kb::ReadMode::Strict).unwrap();
        assert!(!r.has_errors() && r.warnings.is_empty(), "{r}");

        // --kinds house: the house group; --kinds yes: a new list-less group taking all of it.
        let houses = IntoKb {
            kinds: Some(vec!["house".into()]),
            share: 0.25,
            ..target.clone()
        };
        let a = into_kb(&houses, &[member("h")]).unwrap();
        assert_eq!(a.kinds, vec!["house", "terrace"]);
        assert_eq!(a.probas, vec![0.25]);
        let yes = IntoKb {
            kinds: Some(vec!["yes".into()]),
            ..target.clone()
        };
        let a = into_kb(&yes, &[member("y")]).unwrap();
        assert!(a.kinds.is_empty());
        assert_eq!((a.share, a.probas.clone()), (1.0, vec![1.0]));
        let r = crate::kb::tools::check_report(&kb, crate::kb::ReadMode::Strict).unwrap();
        assert!(!r.has_errors() && r.warnings.is_empty(), "{r}");

        // A zone with neither list-less appearances nor apartments: the user must say.
        let only = GROUPS.replace("apartments,residential", "office");
        std::fs::write(&kb, &only).unwrap();
        let e = into_kb(&target, &[member("c")]).unwrap_err().to_string();
        assert!(e.contains("--kinds") && e.contains("kb.xml"), "{e}");
        assert_eq!(std::fs::read_to_string(&kb).unwrap(), only);
    }
}
