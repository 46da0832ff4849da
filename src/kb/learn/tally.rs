//! What the writer counts per group: tagged samples, the group each attribute is learned from,
//! distributions, matching samples, colours and floor heights.

use std::collections::BTreeMap;

use super::fit::{fit_joint, normalise, roof_key, Bin};
use super::format::{median, mode};
use super::{
    kind_class, Attr, Group, Joint, Sample, Writer, ATTRS, KIND_CLASSES, MIN_PER_APPEARANCE,
};

impl<'a> Writer<'a> {
    /// Counts, and what each zone's values describe. A zone's values serve only the buildings
    /// that use them: those in it but in no sub-zone with that attribute of its own. So they are
    /// learned from those (the rest) when it holds at least `min` tagged values, else from the
    /// whole zone; drawn over the extract, every building then follows the distribution of the
    /// buildings around it that use the same values, and the extract's overall distribution is
    /// kept.
    pub(super) fn new(
        samples: &'a [&'a Sample],
        groups: &'a [Group],
        min: usize,
        max_apps: usize,
    ) -> Self {
        let counts: Vec<[usize; 6]> = groups
            .iter()
            .map(|g| ATTRS.map(|a| g.members.iter().filter(|&&k| a.has(samples[k])).count()))
            .collect();
        let mut children: Vec<Vec<usize>> = vec![Vec::new(); groups.len()];
        for (i, g) in groups.iter().enumerate() {
            if let Some(p) = g.parent.filter(|&p| p < i) {
                children[p].push(i);
            }
        }
        let mut data = Vec::with_capacity(groups.len());
        let mut rest = Vec::with_capacity(groups.len());
        for (g, grp) in groups.iter().enumerate() {
            let mut d: [Vec<usize>; 6] = Default::default();
            let mut r = [false; 6];
            for (ai, &a) in ATTRS.iter().enumerate() {
                let tagged: Vec<usize> = grp
                    .members
                    .iter()
                    .copied()
                    .filter(|&k| a.has(samples[k]))
                    .collect();
                // The members of the outermost sub-zones with the attribute of their own.
                let mut excluded = std::collections::BTreeSet::new();
                let mut stack: Vec<usize> = children[g].clone();
                while let Some(c) = stack.pop() {
                    if counts[c][ai] >= min {
                        excluded.extend(groups[c].members.iter().copied());
                    } else {
                        stack.extend(children[c].iter().copied());
                    }
                }
                let left: Vec<usize> = tagged
                    .iter()
                    .copied()
                    .filter(|k| !excluded.contains(k))
                    .collect();
                if !excluded.is_empty() && left.len() >= min {
                    d[ai] = left;
                    r[ai] = true;
                } else {
                    d[ai] = tagged;
                }
            }
            data.push(d);
            rest.push(r);
        }
        // Per-kind groups: a class with `min` tagged values of an attribute in the zone; its
        // values from the class's part of what the zone's describe (the rest, when that holds
        // `min`), else of the whole zone.
        let mut counts = counts;
        let mut classes: Vec<Vec<(usize, usize)>> = vec![Vec::new(); groups.len()];
        for (g, grp) in groups.iter().enumerate() {
            for ci in 0..KIND_CLASSES.len() {
                let in_class = |k: &usize| kind_class(samples[*k].kind.as_deref()) == Some(ci);
                let mut d: [Vec<usize>; 6] = Default::default();
                let mut n = [0usize; 6];
                let mut r = [false; 6];
                let mut own = false;
                for (ai, &a) in ATTRS.iter().enumerate() {
                    let whole: Vec<usize> = grp
                        .members
                        .iter()
                        .copied()
                        .filter(|k| a.has(samples[*k]) && in_class(k))
                        .collect();
                    n[ai] = whole.len();
                    if whole.len() < min {
                        continue;
                    }
                    own |= ai < 5;
                    let left: Vec<usize> = data[g][ai].iter().copied().filter(in_class).collect();
                    if rest[g][ai] && left.len() >= min {
                        d[ai] = left;
                        r[ai] = true;
                    } else {
                        d[ai] = whole;
                    }
                }
                if own {
                    classes[g].push((ci, data.len()));
                    data.push(d);
                    rest.push(r);
                    counts.push(n);
                }
            }
        }
        // The unfiltered appearances serve `building=yes` and the classes without a group of
        // their own: for an attribute that some class draws from its own group, they are
        // learned from the buildings outside those classes (when `min` of them are tagged), so
        // that the class's values are not counted twice in the zone's mix.
        for (g, cls) in classes.iter().enumerate() {
            for ai in 0..ATTRS.len() {
                let grouped: Vec<usize> = cls
                    .iter()
                    .filter(|(_, di)| counts[*di][ai] >= min)
                    .map(|(ci, _)| *ci)
                    .collect();
                if grouped.is_empty() {
                    continue;
                }
                let left: Vec<usize> = data[g][ai]
                    .iter()
                    .copied()
                    .filter(|&k| {
                        kind_class(samples[k].kind.as_deref()).is_none_or(|c| !grouped.contains(&c))
                    })
                    .collect();
                if left.len() >= min {
                    data[g][ai] = left;
                }
            }
        }
        Writer {
            samples,
            groups,
            min,
            max_apps,
            out: String::new(),
            zones: 0,
            appearances: 0,
            kind_groups: 0,
            own: 0,
            counts,
            data,
            rest,
            children,
            classes,
            cache: Default::default(),
        }
    }

    pub(super) fn index(a: Attr) -> usize {
        ATTRS.iter().position(|&x| x == a).unwrap_or(0)
    }

    pub(super) fn count(&self, g: usize, a: Attr) -> usize {
        self.counts[g][Self::index(a)]
    }

    /// The group whose data give `g` attribute `a`: `g` with at least `min` tagged values, else
    /// its parent's, up to none (the built-in defaults).
    pub(super) fn source(&self, g: usize, a: Attr) -> Option<usize> {
        let mut cur = Some(g);
        while let Some(c) = cur {
            if self.count(c, a) >= self.min {
                return Some(c);
            }
            cur = self.groups[c].parent;
        }
        None
    }

    /// The tagged samples group `g`'s values of `a` describe (see [`Writer::new`]).
    fn tagged<'s>(&'s self, g: usize, a: Attr) -> impl Iterator<Item = &'s Sample> + 's {
        self.data[g][Self::index(a)]
            .iter()
            .map(|&k| self.samples[k])
    }

    /// [`Writer::storeys_dist_of`], computed once per group (a big parent serves many cells).
    pub(super) fn storeys_dist(&self, g: usize) -> BTreeMap<u32, f64> {
        if let Some(d) = self.cache.borrow().storeys.get(&g) {
            return d.clone();
        }
        let d = self.storeys_dist_of(g);
        self.cache.borrow_mut().storeys.insert(g, d.clone());
        d
    }

    /// [`Writer::roof_dist_of`], computed once per group.
    pub(super) fn roof_dist(&self, g: usize) -> BTreeMap<&'static str, f64> {
        if let Some(d) = self.cache.borrow().roofs.get(&g) {
            return d.clone();
        }
        let d = self.roof_dist_of(g);
        self.cache.borrow_mut().roofs.insert(g, d.clone());
        d
    }

    /// [`Writer::joint_of`], computed once per pair of sources.
    pub(super) fn joint(&self, ss: Option<usize>, sr: Option<usize>) -> (Joint, String) {
        if let Some(j) = self.cache.borrow().joints.get(&(ss, sr)) {
            return j.clone();
        }
        let j = self.joint_of(ss, sr);
        self.cache.borrow_mut().joints.insert((ss, sr), j.clone());
        j
    }

    fn storeys_dist_of(&self, g: usize) -> BTreeMap<u32, f64> {
        let mut m: BTreeMap<u32, f64> = BTreeMap::new();
        for s in self.tagged(g, Attr::Storeys) {
            *m.entry(s.storeys.unwrap_or(1)).or_default() += 1.0;
        }
        normalise(m)
    }

    fn roof_dist_of(&self, g: usize) -> BTreeMap<&'static str, f64> {
        let mut m: BTreeMap<&'static str, f64> = BTreeMap::new();
        for s in self.tagged(g, Attr::Roof) {
            *m.entry(roof_key(s.roof)).or_default() += 1.0;
        }
        normalise(m)
    }

    /// The joint (roof, storeys) distribution a zone's appearances draw, and how it was made.
    fn joint_of(&self, ss: Option<usize>, sr: Option<usize>) -> (Joint, String) {
        match (ss, sr) {
            (None, None) => (Joint::new(), String::new()),
            (Some(a), None) => (
                self.storeys_dist(a)
                    .into_iter()
                    .map(|(s, p)| (("", s), p))
                    .collect(),
                "storeys only (no roof shape learned)".into(),
            ),
            (None, Some(b)) => (
                self.roof_dist(b)
                    .into_iter()
                    .map(|(r, p)| ((r, 0), p))
                    .collect(),
                "roof shape only (no storeys learned)".into(),
            ),
            (Some(a), Some(b)) => {
                let rows = self.storeys_dist(a);
                let cols = self.roof_dist(b);
                let roofed: std::collections::BTreeSet<usize> = self.data[b]
                    [Self::index(Attr::Roof)]
                .iter()
                .copied()
                .collect();
                let both: Vec<&Sample> = self.data[a][Self::index(Attr::Storeys)]
                    .iter()
                    .filter(|k| roofed.contains(k))
                    .map(|&k| self.samples[k])
                    .collect();
                if a == b && both.len() >= self.min {
                    let mut seed: BTreeMap<(u32, &'static str), f64> = BTreeMap::new();
                    for s in &both {
                        *seed
                            .entry((s.storeys.unwrap_or(1), roof_key(s.roof)))
                            .or_default() += 1.0;
                    }
                    (
                        fit_joint(&seed, &rows, &cols),
                        format!(
                            "storeys and roof shape jointly: the {} buildings tagged with both, \
                             fitted to the two distributions",
                            both.len()
                        ),
                    )
                } else {
                    let mut j = Joint::new();
                    for (s, ps) in &rows {
                        for (r, pr) in &cols {
                            j.insert((r, *s), ps * pr);
                        }
                    }
                    (
                        j,
                        format!(
                            "storeys and roof shape independently ({} buildings tagged with both, \
                             fewer than {} or from different zones)",
                            both.len(),
                            self.min
                        ),
                    )
                }
            }
        }
    }

    /// The samples of group `src` tagged with `a` that match a bin (its roof and storeys range).
    fn matching<'s>(
        &'s self,
        src: usize,
        a: Attr,
        bin: &'s Bin,
    ) -> impl Iterator<Item = &'s Sample> + 's {
        self.tagged(src, a).filter(move |s| {
            let roof_ok = bin.roof.is_empty() || roof_key(s.roof) == bin.roof;
            let storeys_ok =
                bin.hi == 0 || s.storeys.is_some_and(|n| (bin.lo..=bin.hi).contains(&n));
            roof_ok && storeys_ok
        })
    }

    /// The colour (or material) `a` of group `g`'s appearance `bin` (`None`: of its info): the
    /// most frequent among the bin's buildings when the attribute is `g`'s own and
    /// [`MIN_PER_APPEARANCE`] of them are tagged, else the most frequent of the source's.
    pub(super) fn colour_for(
        &self,
        g: usize,
        src: Option<usize>,
        a: Attr,
        bin: Option<&Bin>,
    ) -> Option<String> {
        let src = src?;
        let get = |s: &Sample| match a {
            Attr::WallColour => s.wall_colour.clone(),
            Attr::RoofColour => s.roof_colour.clone(),
            _ => s.material.clone(),
        };
        if let Some(b) = bin.filter(|_| src == g) {
            let own: Vec<String> = self.matching(src, a, b).filter_map(get).collect();
            if own.len() >= MIN_PER_APPEARANCE {
                return mode(own.iter().map(String::as_str));
            }
        }
        let key = (src, Self::index(a));
        if let Some(c) = self.cache.borrow().modes.get(&key) {
            return c.clone();
        }
        let all: Vec<String> = self.tagged(src, a).filter_map(get).collect();
        let c = mode(all.iter().map(String::as_str));
        self.cache.borrow_mut().modes.insert(key, c.clone());
        c
    }

    /// The floor height of group `g`'s appearance `bin` (`None`: of its info), as
    /// [`Writer::colour_for`] with the median.
    pub(super) fn floor_for(&self, g: usize, src: Option<usize>, bin: Option<&Bin>) -> Option<f64> {
        let src = src?;
        if let Some(b) = bin.filter(|_| src == g) {
            let own: Vec<f64> = self
                .matching(src, Attr::FloorHeight, b)
                .filter_map(|s| s.floor_height)
                .collect();
            if own.len() >= MIN_PER_APPEARANCE {
                return median(own);
            }
        }
        if let Some(f) = self.cache.borrow().floors.get(&src) {
            return *f;
        }
        let f = median(
            self.tagged(src, Attr::FloorHeight)
                .filter_map(|s| s.floor_height)
                .collect(),
        );
        self.cache.borrow_mut().floors.insert(src, f);
        f
    }
}
