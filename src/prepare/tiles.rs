//! Which lots a run keeps and writes where: the `--bbox` selection and its margins, and the
//! square tiles of `--tile`.

use glam::DVec2;
use rstar::{RTree, AABB};

use super::{Lot, Site};
use crate::crs::Crs;
use crate::report::{Outcome, Report};

/// A `--bbox` that holds none of the buildings ([`retain_in_bbox`]): the data's extent, and
/// whether the box with its longitudes and latitudes swapped would hold some.
#[derive(Debug, Clone)]
pub struct EmptyBox {
    /// The box asked for: west, south, east, north.
    pub bbox: [f64; 4],
    /// How many buildings there were.
    pub buildings: usize,
    /// The data's south-west corner (longitude, latitude).
    pub lo: (f64, f64),
    /// The data's north-east corner.
    pub hi: (f64, f64),
    /// Whether the box with its corners swapped holds some.
    pub swapped_holds_some: bool,
}

impl std::fmt::Display for EmptyBox {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let [w, s, e, n] = self.bbox;
        write!(
            f,
            "--bbox {w},{s},{e},{n} holds none of the {} buildings, which lie in longitude {:.5} to {:.5}, latitude {:.5} to {:.5}",
            self.buildings, self.lo.0, self.hi.0, self.lo.1, self.hi.1
        )?;
        if self.swapped_holds_some {
            write!(
                f,
                "; its corners look swapped: --bbox {s},{w},{n},{e} (longitude first) holds some"
            )?;
        }
        Ok(())
    }
}

impl std::error::Error for EmptyBox {}

/// Keeps the lots whose representative point lies in `bbox` = [min lon, min lat, max lon,
/// max lat] (degrees), so a region can be split across runs or machines: every footprint lies in
/// exactly one of several boxes that tile the region (min inclusive, max exclusive). The lots
/// left out are counted in one report note. A box that holds none of the lots (when there are
/// some) leaves none and is an `Err` naming the data's extent, and saying so when the box with
/// its longitudes and latitudes swapped would hold some: the caller decides whether an empty
/// run is an error (`--allow-empty`).
pub fn retain_in_bbox(
    site: &mut Site,
    bbox: [f64; 4],
    report: &mut Report,
) -> Result<(), EmptyBox> {
    let inside = in_bbox;
    let before = site.lots.len();
    if before > 0 && !site.lots.iter().any(|l| inside(l.lonlat, bbox)) {
        let (mut lo, mut hi) = (
            (f64::INFINITY, f64::INFINITY),
            (f64::NEG_INFINITY, f64::NEG_INFINITY),
        );
        for l in &site.lots {
            lo = (lo.0.min(l.lonlat.0), lo.1.min(l.lonlat.1));
            hi = (hi.0.max(l.lonlat.0), hi.1.max(l.lonlat.1));
        }
        let swapped = [bbox[1], bbox[0], bbox[3], bbox[2]];
        let why = EmptyBox {
            bbox,
            buildings: before,
            lo,
            hi,
            swapped_holds_some: site.lots.iter().any(|l| inside(l.lonlat, swapped)),
        };
        site.lots.clear();
        report.add(None, Outcome::Note, why.to_string());
        return Err(why);
    }
    site.lots.retain(|l| inside(l.lonlat, bbox));
    let out = before - site.lots.len();
    if out > 0 {
        report.add(
            None,
            Outcome::Note,
            format!(
                "{out} of {before} building(s) outside --bbox {},{},{},{} were not generated",
                bbox[0], bbox[1], bbox[2], bbox[3]
            ),
        );
    }
    Ok(())
}

/// One square tile of a tiled run: the lots whose representative point lies in it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Tile {
    /// Output-CRS coordinates of the tile's lower-left corner, in whole metres.
    pub corner: (i64, i64),
    /// The tile's lots: `site.lots[range]` after [`group_into_tiles`].
    pub range: std::ops::Range<usize>,
}

impl Tile {
    /// The file-name suffix of the tile, `{easting}_{northing}` of its lower-left corner, so
    /// that the same grid gives the same names night after night.
    pub(crate) fn suffix(&self) -> String {
        format!("{}_{}", self.corner.0, self.corner.1)
    }
}

/// The grid cell (easting, northing divided by `size`, rounded down) of the `size`-metre tile
/// holding the lot's representative point in `crs`: its tile's corner is the cell times `size`.
pub fn tile_cell(crs: Crs, lot: &Lot, size: u32) -> (i64, i64) {
    let size = f64::from(size.max(1));
    let (x, y) = crs.from_lonlat(lot.lonlat.0, lot.lonlat.1);
    // A non-finite point (cannot happen for a prepared lot) goes to the origin's tile rather
    // than being lost.
    let cell = |v: f64| {
        if v.is_finite() {
            (v / size).floor() as i64
        } else {
            0
        }
    };
    (cell(x), cell(y))
}

/// Groups the lots by the `size`-metre square of the output CRS grid holding their
/// representative point, and reorders `site.lots` so that each tile's lots are contiguous.
/// Tiles come in (easting, northing) order of their corners; inside a tile the lots keep their
/// input order, so the outputs stay deterministic. Every lot is in exactly one tile.
pub fn group_into_tiles(site: &mut Site, size: u32) -> Vec<Tile> {
    let key = |lot: &Lot| tile_cell(site.crs, lot, size);
    let size = i64::from(size.max(1));
    let mut keyed: Vec<((i64, i64), Lot)> = std::mem::take(&mut site.lots)
        .into_iter()
        .map(|l| (key(&l), l))
        .collect();
    // Stable: lots of one tile keep their input order.
    keyed.sort_by_key(|(k, _)| *k);
    let mut tiles: Vec<Tile> = Vec::new();
    for (i, (k, lot)) in keyed.into_iter().enumerate() {
        let corner = (k.0 * size, k.1 * size);
        match tiles.last_mut() {
            Some(t) if t.corner == corner => t.range.end = i + 1,
            _ => tiles.push(Tile {
                corner,
                range: i..i + 1,
            }),
        }
        site.lots.push(lot);
    }
    tiles
}

/// Whether a representative point (lon, lat) is in `--bbox` b (west, south, east, north), as
/// [`retain_in_bbox`] decides.
pub fn in_bbox((lon, lat): (f64, f64), b: [f64; 4]) -> bool {
    lon >= b[0] && lon < b[2] && lat >= b[1] && lat < b[3]
}

/// Which lots `--bbox` keeps or whose outline comes within `margin` metres of one it keeps: the
/// lots a run in the box needs as neighbours.
pub fn near_bbox(lots: &[Lot], bbox: [f64; 4], margin: f64) -> Vec<bool> {
    let kept: Vec<bool> = lots.iter().map(|l| in_bbox(l.lonlat, bbox)).collect();
    near_selected(lots, &kept, margin)
}

/// A lot's bounds with its parts' (local metres), `None` when it has no finite point.
pub(crate) fn full_bounds(l: &Lot) -> Option<(DVec2, DVec2)> {
    let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
    for p in l
        .polygons
        .iter()
        .chain(l.parts.iter().flat_map(|p| &p.polygons))
    {
        let (a, b) = p.bounds();
        lo = lo.min(a);
        hi = hi.max(b);
    }
    (lo.is_finite() && hi.is_finite()).then_some((lo, hi))
}

/// Which lots are `selected` or have an outline within `margin` metres of a selected one's (the
/// lots a run writing the selected ones needs as neighbours: a `--bbox`, a shard's tiles).
/// `selected` has one flag per lot.
pub fn near_selected(lots: &[Lot], selected: &[bool], margin: f64) -> Vec<bool> {
    let bounds = |l: &Lot| {
        full_bounds(l)
            .map(|(lo, hi)| AABB::from_corners((lo - margin).to_array(), (hi + margin).to_array()))
    };
    let is_selected = |i: usize| selected.get(i).copied().unwrap_or(false);
    let kept: Vec<rstar::primitives::Rectangle<[f64; 2]>> = lots
        .iter()
        .enumerate()
        .filter(|(i, _)| is_selected(*i))
        .filter_map(|(_, l)| bounds(l))
        .map(|b| rstar::primitives::Rectangle::from_corners(b.lower(), b.upper()))
        .collect();
    let tree = RTree::bulk_load(kept);
    lots.iter()
        .enumerate()
        .map(|(i, l)| {
            is_selected(i)
                || bounds(l)
                    .is_some_and(|b| tree.locate_in_envelope_intersecting(b).next().is_some())
        })
        .collect()
}
