//! Appearance choice: the appearances a zone offers a building's kind, their weights, the
//! draw, and the rule and SELEX files an appearance names.

use std::path::{Component, Path, PathBuf};

use super::{Appearance, KbError, KnowledgeBase, ZoneKind};
use crate::fsio::InsideError;
use crate::model::{RoofMix, RoofShape};
use crate::rng::Rng;

impl KnowledgeBase {
    /// The appearances that apply to a zone: its own, or if it has none those of the nearest
    /// ancestor that has some. Returns the owning zone index and the slice (empty, owner 0, when
    /// no zone up to earth has any).
    pub(crate) fn appearances_for(&self, zone: usize) -> (usize, &[Appearance]) {
        for i in self.lineage(zone).into_iter().rev() {
            if let Some(z) = self.zones.get(i) {
                if !z.appearances.is_empty() {
                    return (i, &z.appearances);
                }
            }
        }
        (0, &[])
    }

    /// Which of the appearances that apply to `zone` ([`KnowledgeBase::appearances_for`]) a
    /// building of this OSM `building=*` kind may be drawn from: those whose `building` list
    /// names the kind (`None` and `yes` both stand for `yes`); if none does, those with no
    /// list; if every appearance has a list, all of them. Returns the owning zone and the
    /// indices, in appearance order (empty when no zone up to earth has an appearance).
    #[cfg(test)]
    pub(crate) fn eligible_appearances(
        &self,
        zone: usize,
        kind: Option<&str>,
    ) -> (usize, Vec<usize>) {
        let (owner, apps) = self.appearances_for(zone);
        (owner, eligible(apps, kind))
    }

    /// Chooses one of the appearances that apply to `zone` for a building of this `building=*`
    /// kind ([`KnowledgeBase::eligible_appearances`]).
    ///
    /// Weights among the eligible appearances ([`appearance_weights`]): a given `proba` is
    /// used as is; appearances without one share what the given ones leave of 1 equally
    /// (nothing when they already sum to 1 or more); the weights are then normalised. If every
    /// weight is zero the choice is uniform. Draws exactly one number from `rng` when there is
    /// at least one eligible appearance. Returns (owner zone, index).
    ///
    /// With the building's `storeys` known (tagged, or estimated where the map is silent), the
    /// draw is among the eligible appearances whose storey range holds them ([`fitting`]): a
    /// nine-storey block is not drawn as a one-storey cottage.
    #[cfg(test)]
    pub(crate) fn pick_appearance(
        &self,
        zone: usize,
        kind: Option<&str>,
        storeys: Option<f64>,
        rng: &mut Rng,
    ) -> Option<(usize, usize)> {
        self.pick_appearance_for(zone, kind, storeys, (None, None), rng)
    }

    /// [`KnowledgeBase::pick_appearance`] for a footprint of this area (m²) and form: among
    /// the eligible appearances, those whose conditions hold ([`conditioned`]) before the
    /// storeys choose.
    pub(crate) fn pick_appearance_for(
        &self,
        zone: usize,
        kind: Option<&str>,
        storeys: Option<f64>,
        (area, form): (Option<f64>, Option<crate::model::Form>),
        rng: &mut Rng,
    ) -> Option<(usize, usize)> {
        let (owner, apps) = self.appearances_for(zone);
        let floor = self
            .resolved(zone)
            .floor_height
            .filter(|f| (2.0..8.0).contains(f))
            .unwrap_or(3.0);
        let ids = conditioned(apps, eligible(apps, kind), area, form);
        let ids = fitting(apps, ids, storeys, floor);
        let weights = proba_weights(ids.iter().map(|&i| apps[i].proba));
        rng.pick_weighted(&weights)
            .and_then(|k| ids.get(k).copied())
            .map(|i| (owner, i))
    }
}

impl KnowledgeBase {
    /// Whether any appearance has conditions on the footprint's form
    /// ([`super::values::Conditions`]): the run then measures every footprint's form.
    pub(crate) fn has_conditions(&self) -> bool {
        self.zones
            .iter()
            .any(|z| z.appearances.iter().any(|a| !a.when.is_empty()))
    }

    /// The roof and storey prior of `zone` for a building of this `building=*` kind: the
    /// eligible appearances weighted as [`KnowledgeBase::pick_appearance`] draws them.
    pub(crate) fn roof_mix(&self, zone: usize, kind: Option<&str>) -> RoofMix {
        let info = self.resolved(zone);
        let (_, apps) = self.appearances_for(zone);
        let ids = eligible(apps, kind);
        let weights = proba_weights(ids.iter().map(|&i| apps[i].proba));
        let zone_roof = info.roof.unwrap_or(RoofShape::Gabled);
        let zone_angle = info
            .roof_angle
            .filter(|a| (5.0..80.0).contains(a))
            .unwrap_or(30.0);
        let zone_floor = info
            .floor_height
            .filter(|f| (2.0..8.0).contains(f))
            .unwrap_or(3.0);
        let urban = self.lineage(zone).iter().any(|&i| {
            self.zones.get(i).is_some_and(|z| {
                !matches!(
                    z.kind,
                    ZoneKind::Earth | ZoneKind::Country | ZoneKind::Region
                )
            })
        });
        let storeys = info
            .storeys
            .filter(|&n| n > 0)
            .map_or(2.0, |n| f64::from(n.min(12)))
            .min(if urban { 12.0 } else { 3.0 });
        if ids.is_empty() {
            let pitched = f64::from(u8::from(zone_roof != RoofShape::Flat));
            let shape = if pitched > 0.0 {
                zone_roof
            } else {
                RoofShape::Gabled
            };
            return RoofMix {
                pitched,
                shape,
                angle_deg: zone_angle,
                floor_height: zone_floor,
                storeys,
                urban,
            };
        }
        let mut shapes: Vec<(RoofShape, f64, f64)> = Vec::new();
        let mut floors: Vec<(f64, f64)> = Vec::new();
        let mut pitched = 0.0;
        for (&i, &w) in ids.iter().zip(&weights) {
            let v = &apps[i].values;
            let roof = v.roof.unwrap_or(zone_roof);
            let floor = v
                .floor_height
                .filter(|f| (2.0..8.0).contains(f))
                .unwrap_or(zone_floor);
            match floors.iter_mut().find(|f| f.0 == floor) {
                Some(f) => f.1 += w,
                None => floors.push((floor, w)),
            }
            if roof == RoofShape::Flat {
                continue;
            }
            pitched += w;
            let angle = v
                .roof_angle
                .filter(|a| (5.0..80.0).contains(a))
                .unwrap_or(zone_angle);
            match shapes.iter_mut().find(|s| s.0 == roof) {
                Some(s) => s.1 += w,
                None => shapes.push((roof, w, angle)),
            }
        }
        let best = |v: &[(RoofShape, f64, f64)]| {
            v.iter()
                .copied()
                .reduce(|a, b| if b.1 > a.1 { b } else { a })
        };
        let (shape, _, angle_deg) = best(&shapes).unwrap_or((RoofShape::Gabled, 0.0, zone_angle));
        let floor_height = floors
            .iter()
            .copied()
            .reduce(|a, b| if b.1 > a.1 { b } else { a })
            .map_or(zone_floor, |f| f.0);
        RoofMix {
            pitched: pitched.clamp(0.0, 1.0),
            shape,
            angle_deg,
            floor_height,
            storeys,
            urban,
        }
    }
}

impl KnowledgeBase {
    /// Where an appearance's `ruleset file=` points, resolved against the KB's folder.
    /// Refuses absolute paths and paths that climb out of that folder (`..`) unless
    /// `allow_outside` is set. `Ok(None)` when the appearance names no ruleset.
    pub(crate) fn ruleset_path(
        &self,
        zone: usize,
        appearance: usize,
        allow_outside: bool,
    ) -> Result<Option<PathBuf>, KbError> {
        self.appearance_file(zone, appearance, "ruleset", allow_outside, |a| {
            a.ruleset.as_deref()
        })
    }

    /// Where an appearance's `selex file=` points, resolved against the KB's folder, with the
    /// same refusals as [`KnowledgeBase::ruleset_path`] (a SELEX program is always inside the
    /// KB's folder: no `allow_outside`). `Ok(None)` when the appearance names none.
    pub(crate) fn selex_path(
        &self,
        zone: usize,
        appearance: usize,
    ) -> Result<Option<PathBuf>, KbError> {
        self.appearance_file(zone, appearance, "selex", false, |a| a.selex.as_deref())
    }

    fn appearance_file(
        &self,
        zone: usize,
        appearance: usize,
        what: &str,
        allow_outside: bool,
        file: impl Fn(&Appearance) -> Option<&str>,
    ) -> Result<Option<PathBuf>, KbError> {
        let Some(app) = self
            .zones
            .get(zone)
            .and_then(|z| z.appearances.get(appearance))
        else {
            return Ok(None);
        };
        let Some(file) = file(app) else {
            return Ok(None);
        };
        let rel = Path::new(file);
        let mut depth: i64 = 0;
        let mut escapes = rel.is_absolute();
        for c in rel.components() {
            match c {
                Component::ParentDir => depth -= 1,
                Component::Normal(_) => depth += 1,
                Component::CurDir => {}
                Component::RootDir | Component::Prefix(_) => escapes = true,
            }
            if depth < 0 {
                escapes = true;
            }
        }
        if escapes && !allow_outside {
            return Err(KbError::Structure {
                file: self.source.clone(),
                line: app.line,
                message: format!(
                    "{what} file \"{file}\" lies outside the knowledge base's folder; \
                     move it next to the KB{}",
                    if what == "ruleset" {
                        " or allow outside rulesets explicitly"
                    } else {
                        ""
                    }
                ),
            });
        }
        Ok(Some(match &self.base_dir {
            Some(d) => d.join(rel),
            None => rel.to_path_buf(),
        }))
    }

    /// [`KnowledgeBase::ruleset_path`], and the file as it is now: a symlink leaving the KB's
    /// folder or something other than a regular file is refused, with the appearance's line
    /// (`allow_outside` skips this check as it does the path's). What reads the file reads it
    /// with [`KnowledgeBase::read_appearance_file`], which checks again as it opens.
    pub(crate) fn ruleset_file(
        &self,
        zone: usize,
        appearance: usize,
        allow_outside: bool,
    ) -> Result<Option<PathBuf>, KbError> {
        let path = self.ruleset_path(zone, appearance, allow_outside)?;
        if !allow_outside {
            self.check_inside(zone, appearance, "ruleset", path.as_deref())?;
        }
        Ok(path)
    }

    /// [`KnowledgeBase::selex_path`] with the checks of [`KnowledgeBase::ruleset_file`].
    pub(crate) fn selex_file(
        &self,
        zone: usize,
        appearance: usize,
    ) -> Result<Option<PathBuf>, KbError> {
        let path = self.selex_path(zone, appearance)?;
        self.check_inside(zone, appearance, "selex", path.as_deref())?;
        Ok(path)
    }

    /// `path` (of appearance `appearance` of `zone`) refused when it leads outside the KB's
    /// folder or is not a regular file. A file that is not there is the reader's to report.
    fn check_inside(
        &self,
        zone: usize,
        appearance: usize,
        what: &str,
        path: Option<&Path>,
    ) -> Result<(), KbError> {
        let (Some(path), Some(app)) = (
            path,
            self.zones
                .get(zone)
                .and_then(|z| z.appearances.get(appearance)),
        ) else {
            return Ok(());
        };
        match self.open_inside(path) {
            Ok(_) | Err(InsideError::Io(_)) => Ok(()),
            Err(e) => Err(KbError::Structure {
                file: self.source.clone(),
                line: app.line,
                message: format!("{what} file {} is refused: {e}", path.display()),
            }),
        }
    }

    /// `path` opened only inside the KB's folder (`fsio::open_inside`; the working folder for
    /// a KB read from text).
    fn open_inside(&self, path: &Path) -> Result<std::fs::File, InsideError> {
        let dir = match &self.base_dir {
            Some(d) if !d.as_os_str().is_empty() => d.as_path(),
            _ => Path::new("."),
        };
        crate::fsio::open_inside(dir, path)
    }

    /// The text of a file an appearance names ([`KnowledgeBase::ruleset_path`],
    /// [`KnowledgeBase::selex_path`]), read only if at the moment it is opened it still lies
    /// inside the KB's folder and is a regular file (`fsio::open_inside`), at most
    /// `grammar::MAX_SOURCE_BYTES`. A refusal is an error that says why (the file's content
    /// is never in it).
    pub(crate) fn read_appearance_file(&self, path: &Path) -> std::io::Result<String> {
        let file = self.open_inside(path).map_err(|e| match e {
            InsideError::Io(e) => e,
            refused => std::io::Error::new(
                std::io::ErrorKind::PermissionDenied,
                format!("refused: {refused}"),
            ),
        })?;
        crate::grammar::read_capped(file)
    }
}

/// Indices of the appearances a building of this kind is drawn from; see
/// [`KnowledgeBase::eligible_appearances`].
pub(crate) fn eligible(apps: &[Appearance], kind: Option<&str>) -> Vec<usize> {
    let kind = kind
        .map(str::trim)
        .filter(|k| !k.is_empty())
        .unwrap_or("yes");
    let named: Vec<usize> = (0..apps.len())
        .filter(|&i| {
            apps[i]
                .buildings
                .iter()
                .any(|b| b.eq_ignore_ascii_case(kind))
        })
        .collect();
    if !named.is_empty() {
        return named;
    }
    let open: Vec<usize> = (0..apps.len())
        .filter(|&i| apps[i].buildings.is_empty())
        .collect();
    if open.is_empty() {
        (0..apps.len()).collect()
    } else {
        open
    }
}

/// The storey range an appearance draws from: `minFloors..maxFloors`, else its eave height
/// range over its storey height (`floor`: the zone's), else `None` (any).
fn storey_range(a: &Appearance, floor: f64) -> Option<(f64, f64)> {
    let v = &a.values;
    match (v.min_floors, v.max_floors) {
        (Some(lo), Some(hi)) => return Some((f64::from(lo.min(hi)), f64::from(lo.max(hi)))),
        (Some(n), None) | (None, Some(n)) => return Some((f64::from(n), f64::from(n))),
        (None, None) => {}
    }
    let floor = v
        .floor_height
        .filter(|f| (2.0..8.0).contains(f))
        .unwrap_or(floor);
    let (lo, hi) = match (v.min_height, v.max_height) {
        (Some(lo), Some(hi)) => (lo.min(hi), lo.max(hi)),
        (Some(h), None) | (None, Some(h)) => (h, h),
        (None, None) => return None,
    };
    Some(((lo / floor).round().max(1.0), (hi / floor).round().max(1.0)))
}

/// Of the eligible appearances `ids`, those whose conditions hold for a footprint of `area` m²
/// and `form` ([`super::values::Conditions::hold`]; an appearance without conditions holds
/// everywhere); all of `ids` when none holds (conditions narrow a draw, they never leave a
/// building without an appearance).
fn conditioned(
    apps: &[Appearance],
    ids: Vec<usize>,
    area: Option<f64>,
    form: Option<crate::model::Form>,
) -> Vec<usize> {
    let holding: Vec<usize> = ids
        .iter()
        .copied()
        .filter(|&i| apps[i].when.hold(area, form))
        .collect();
    if holding.is_empty() {
        ids
    } else {
        holding
    }
}

/// Of the eligible appearances `ids`, those whose storey range ([`storey_range`]) holds
/// `storeys` (an appearance without a range holds any); when none does, those whose range is
/// nearest. `storeys` unknown: `ids` unchanged.
fn fitting(apps: &[Appearance], ids: Vec<usize>, storeys: Option<f64>, floor: f64) -> Vec<usize> {
    let Some(s) = storeys.filter(|s| s.is_finite() && *s >= 1.0) else {
        return ids;
    };
    let gap = |i: usize| match storey_range(&apps[i], floor) {
        None => 0.0,
        Some((lo, hi)) => (lo - s).max(s - hi).max(0.0),
    };
    let best = ids.iter().map(|&i| gap(i)).fold(f64::INFINITY, f64::min);
    if !best.is_finite() {
        return ids;
    }
    ids.into_iter().filter(|&i| gap(i) <= best).collect()
}

/// The weights [`KnowledgeBase::pick_appearance`] uses over a set of appearances, in order.
#[cfg(test)]
pub(crate) fn appearance_weights(apps: &[Appearance]) -> Vec<f64> {
    proba_weights(apps.iter().map(|a| a.proba))
}

/// The weights of appearances with these `proba`s, in order: given ones as they are, absent
/// ones sharing what the given leave of 1, normalised (see [`KnowledgeBase::pick_appearance`]).
pub(crate) fn proba_weights(probas: impl Iterator<Item = Option<f64>> + Clone) -> Vec<f64> {
    let given: f64 = probas.clone().flatten().sum();
    let missing = probas.clone().filter(Option::is_none).count();
    let share = if missing > 0 {
        ((1.0 - given) / missing as f64).max(0.0)
    } else {
        0.0
    };
    let raw: Vec<f64> = probas.map(|p| p.unwrap_or(share)).collect();
    let total: f64 = raw.iter().sum();
    if total > 0.0 {
        raw.iter().map(|w| w / total).collect()
    } else {
        raw
    }
}
