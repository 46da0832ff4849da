use super::*;

#[test]
fn the_shipped_models_read() {
    assert!(Model::from_text(SHIPPED_HEIGHT).is_ok());
    assert!(Model::from_text(SHIPPED_ROOF).is_ok());
}

/// A `w` by `d` rectangle at (x, y) with these tags (the footprint of `morph`'s tests).
fn lot(i: i64, x: f64, y: f64, w: f64, d: f64, tags: BuildingTags) -> Lot {
    let mut l = crate::prepare::morph::tests::rect(i, x, y, w, d, "yes");
    l.tags = std::sync::Arc::new(tags);
    l
}

fn kind(k: &str) -> BuildingTags {
    BuildingTags {
        building: Some(k.to_string()),
        ..Default::default()
    }
}

fn tower(levels: f64) -> BuildingTags {
    BuildingTags {
        levels: Some(levels),
        roof_shape: Some(RoofShape::Flat),
        ..kind("hotel")
    }
}

fn run(lots: &[Lot]) -> Outcome {
    let want = vec![Inference::ALL; lots.len()];
    let mixes = vec![RoofMix::DEFAULT; lots.len()];
    estimate(lots, &mixes, &want, &Models::shipped(), false)
}

#[test]
fn sheds_kiosks_and_small_footprints_do_not_borrow_a_towers_storeys() {
    // Six 13-storey hotels around a shed, a kiosk, a stable and an untagged 20 m² hut.
    let mut lots: Vec<Lot> = (0..6)
        .map(|k| lot(k, 40.0 * k as f64, 0.0, 25.0, 25.0, tower(13.0)))
        .collect();
    lots.push(lot(10, 60.0, 40.0, 8.0, 5.5, kind("shed")));
    lots.push(lot(11, 80.0, 40.0, 3.0, 4.0, kind("kiosk")));
    lots.push(lot(12, 100.0, 40.0, 12.0, 20.0, kind("stable")));
    lots.push(lot(13, 120.0, 40.0, 4.0, 5.0, kind("yes")));
    lots.push(lot(14, 140.0, 40.0, 25.0, 25.0, kind("yes")));
    let out = run(&lots);
    let e = |i: usize| out.estimates[i].unwrap_or_else(|| panic!("lot {i} estimated"));
    for i in [6, 7] {
        assert!(e(i).storeys <= 1.0, "lot {i}: {:?}", e(i));
        assert!(
            e(i).height <= 3.0 + 0.5 + roof_allowance(8.0, 30.0),
            "{:?}",
            e(i)
        );
    }
    assert!(e(8).storeys <= 2.0, "a stable: {:?}", e(8));
    assert!(e(9).storeys <= 2.0, "20 m²: {:?}", e(9));
    // A like-sized untagged neighbour of the hotels is lifted towards them (by at most the
    // lending factor over its own prior), with its source.
    let prior = prior_log_height(&out.features[10], &RoofMix::DEFAULT).exp();
    assert!(e(10).height >= 1.4 * prior, "{:?} over {prior}", e(10));
    assert!(
        e(10).height <= MAX_LEND * prior + 1e-9,
        "{:?} over {prior}",
        e(10)
    );
    assert!(e(10).storeys >= 4.0, "{:?}", e(10));
    assert_eq!(e(10).height_source, ValueSource::Neighbours);
    for i in 0..6 {
        assert!(out.estimates[i].is_none(), "tagged lot {i} is left alone");
    }
}

#[test]
fn two_neighbours_are_not_enough_to_lend() {
    let lots = vec![
        lot(1, 0.0, 0.0, 20.0, 20.0, tower(13.0)),
        lot(2, 30.0, 0.0, 20.0, 20.0, tower(13.0)),
        lot(3, 60.0, 0.0, 20.0, 20.0, kind("yes")),
    ];
    let e = run(&lots).estimates[2].unwrap_or_else(|| panic!("estimated"));
    assert_ne!(e.height_source, ValueSource::Neighbours);
    assert!(e.storeys < 6.0, "{e:?}");
}

/// Issue 42's case: tagged 13-storey hotels among untagged rowhouse-sized footprints. Without
/// like-size voters the hotels may lift a house by [`LIKE_LESS_LEND`] at most, never make it a
/// tower; a footprint of the hotels' own size beside them still rises towards them.
#[test]
fn tagged_towers_do_not_make_rowhouses_towers() {
    // Two terraces of eight 6 by 12 m houses (72 m²), 25 m and 60 m from four 40 by 40 m
    // hotels, and a 40 by 40 m untagged block beside the hotels.
    let houses: Vec<Lot> = (0..16)
        .map(|k| {
            let y = if k < 8 { 65.0 } else { 100.0 };
            lot(100 + k, 6.0 * (k % 8) as f64, y, 6.0, 12.0, kind("yes"))
        })
        .collect();
    let alone = run(&houses);
    let mut lots = houses.clone();
    for k in 0..4 {
        lots.push(lot(k, 50.0 * k as f64, 0.0, 40.0, 40.0, tower(13.0)));
    }
    lots.push(lot(200, 200.0, 0.0, 40.0, 40.0, kind("yes")));
    let with = run(&lots);
    for i in 0..houses.len() {
        let (a, w) = (
            alone.estimates[i].unwrap_or_else(|| panic!("house {i} estimated alone")),
            with.estimates[i].unwrap_or_else(|| panic!("house {i} estimated")),
        );
        assert!(
            w.storeys <= (LIKE_LESS_LEND * a.storeys).ceil(),
            "house {i}: {} storeys beside the hotels, {} alone",
            w.storeys,
            a.storeys
        );
        assert!(w.storeys < 5.0, "house {i}: {w:?}");
    }
    let block = with.estimates[houses.len() + 4].unwrap_or_else(|| panic!("block estimated"));
    let block_alone = run(&[lot(200, 200.0, 0.0, 40.0, 40.0, kind("yes"))]).estimates[0]
        .unwrap_or_else(|| panic!("block estimated alone"));
    assert!(
        block.storeys >= 2.0 * block_alone.storeys,
        "the like-size block: {block:?} beside the hotels, {block_alone:?} alone"
    );
    assert_eq!(block.height_source, ValueSource::Neighbours);
}

#[test]
fn an_attached_row_shares_one_height_and_one_roof() {
    let lots: Vec<Lot> = (0..6)
        .map(|k| {
            let w = if k % 2 == 0 { 5.5 } else { 6.5 };
            let x: f64 = (0..k).map(|j| if j % 2 == 0 { 5.5 } else { 6.5 }).sum();
            lot(k, x, 0.0, w, 11.0 + k as f64, kind("yes"))
        })
        .collect();
    let out = run(&lots);
    let all: Vec<Estimate> = out
        .estimates
        .iter()
        .map(|e| e.unwrap_or_else(|| panic!("estimated")))
        .collect();
    for e in &all {
        assert_eq!(e.height, all[0].height, "{all:?}");
        assert_eq!(e.shape, all[0].shape);
        assert_eq!(e.storeys, all[0].storeys);
    }
}

#[test]
fn touching_footprints_of_like_size_share_a_roof_family_whatever_their_heights() {
    // A 50 m² house (mostly pitched by its size) against a 100 m² block of flats (mostly
    // flat, and too tall to share the house's height): one roof family. A 15 m² shed against
    // a 120 m² house (8 times its size), in no row of its own, takes the house's family.
    let lots = vec![
        lot(1, 0.0, 0.0, 5.0, 10.0, kind("yes")),
        lot(2, 5.0, 0.0, 10.0, 10.0, kind("apartments")),
        lot(3, 1000.0, 0.0, 10.0, 12.0, kind("yes")),
        lot(4, 1010.0, 0.0, 3.0, 5.0, kind("yes")),
    ];
    let out = run(&lots);
    let e = |i: usize| out.estimates[i].unwrap_or_else(|| panic!("lot {i} estimated"));
    let alone = |i: usize| {
        gbt::sigmoid(
            prior_roof(&RoofMix::DEFAULT, &out.features[i])
                + Models::shipped().roof.predict(&out.features[i]),
        )
    };
    assert!(
        alone(0) >= 0.5 && alone(1) < 0.5,
        "{} {}",
        alone(0),
        alone(1)
    );
    assert!(e(1).height > 1.35 * e(0).height, "{:?} {:?}", e(0), e(1));
    assert_eq!(e(0).shape == RoofShape::Flat, e(1).shape == RoofShape::Flat);
    assert_eq!(e(0).pitched, e(1).pitched);
    assert!(
        e(2).pitched >= 0.5 && e(2).shape != RoofShape::Flat,
        "{:?}",
        e(2)
    );
    assert!(alone(3) < 0.5, "alone the shed is flat: {}", alone(3));
    assert_eq!(e(3).pitched, e(2).pitched, "{:?}", e(3));
    assert_ne!(e(3).shape, RoofShape::Flat, "{:?}", e(3));
}

#[test]
fn an_annex_takes_its_hosts_roof_family_and_a_row_keeps_its_own() {
    // A 12 m² shed against a flat-tagged 200 m² block: flat, from the block's tag. A 9 m²
    // garage against a pitched-tagged 100 m² house: pitched, the house's shape. A row of
    // four 48 m² cottages against the end of a 600 m² flat block (12 times larger) keeps
    // the row's own family: members of a row are not annexes.
    let tagged = |shape: RoofShape| BuildingTags {
        roof_shape: Some(shape),
        ..kind("yes")
    };
    let mut lots = vec![
        lot(1, 0.0, 0.0, 20.0, 10.0, tagged(RoofShape::Flat)),
        lot(2, 20.0, 0.0, 3.0, 4.0, kind("yes")),
        lot(3, 500.0, 0.0, 10.0, 10.0, tagged(RoofShape::Hipped)),
        lot(4, 510.0, 0.0, 3.0, 3.0, kind("yes")),
        lot(5, 1000.0, 0.0, 30.0, 20.0, kind("yes")),
    ];
    lots.extend(terrace(6, 1030.0, 4, |_| 6.0, |_| 8.0, |_| kind("yes")));
    let out = run_in(&lots, roofs_in(0.6));
    let e = |i: usize| out.estimates[i].unwrap_or_else(|| panic!("lot {i} estimated"));
    assert_eq!(e(1).shape, RoofShape::Flat, "{:?}", e(1));
    assert_eq!(e(1).roof_source, ValueSource::Neighbours);
    assert_eq!(e(3).shape, RoofShape::Hipped, "{:?}", e(3));
    assert_eq!(e(3).roof_source, ValueSource::Neighbours);
    assert_eq!(e(4).shape, RoofShape::Flat, "{:?}", e(4));
    for i in 5..9 {
        assert_ne!(e(i).shape, RoofShape::Flat, "cottage {i}: {:?}", e(i));
    }
}

#[test]
fn estimates_are_set_with_their_provenance_and_the_same_at_any_thread_count() {
    let mut lots: Vec<Lot> = (0..40)
        .map(|k| {
            let t = if k % 3 == 0 {
                tower(2.0 + (k % 5) as f64)
            } else {
                kind("yes")
            };
            lot(
                k,
                14.0 * (k % 8) as f64,
                14.0 * (k / 8) as f64,
                10.0,
                9.0 + (k % 4) as f64,
                t,
            )
        })
        .collect();
    let pool = |n| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .unwrap_or_else(|e| panic!("{e}"))
    };
    let one = pool(1).install(|| run(&lots));
    let two = pool(2).install(|| run(&lots));
    assert_eq!(one.estimates, two.estimates);
    let before: Vec<_> = lots.iter().map(|l| l.tags.clone()).collect();
    let changed = apply(&mut lots, &one.estimates);
    assert_eq!(changed, one.estimates.iter().flatten().count());
    for (l, b) in lots.iter().zip(&before) {
        if b.levels.is_some() {
            assert!(std::sync::Arc::ptr_eq(&l.tags, b), "tagged lots untouched");
            continue;
        }
        let p = l.tags.provenance.unwrap_or_else(|| panic!("provenance"));
        assert!(l.tags.height.is_some() && l.tags.roof_shape.is_some());
        assert_ne!(p.height, ValueSource::Tag);
        assert!(p.height_error.is_some() && p.roof_probability.is_some());
    }
}

/// A regional prior: `storeys` storeys of 3 m, half the roofs pitched.
fn zone(storeys: f64, urban: bool) -> RoofMix {
    RoofMix {
        storeys,
        urban,
        ..RoofMix::DEFAULT
    }
}

fn run_in(lots: &[Lot], mix: RoofMix) -> Outcome {
    let want = vec![Inference::ALL; lots.len()];
    estimate(
        lots,
        &vec![mix; lots.len()],
        &want,
        &Models::shipped(),
        false,
    )
}

/// A village of detached houses with a shed behind each and a barn at every fifth farm, on
/// 35 m plots (a tenth of the ground built), all untagged.
fn village() -> Vec<Lot> {
    let mut lots = Vec::new();
    for k in 0..100_i64 {
        let (x, y) = (35.0 * (k % 10) as f64, 35.0 * (k / 10) as f64);
        lots.push(lot(3 * k, x, y, 10.0, 11.0, kind("yes")));
        lots.push(lot(3 * k + 1, x + 14.0, y + 14.0, 4.0, 5.0, kind("yes")));
        if k % 5 == 0 {
            lots.push(lot(3 * k + 2, x + 2.0, y + 16.0, 16.0, 22.0, kind("yes")));
        }
    }
    lots
}

/// An old town: rows of 6 m wide, 9 m deep houses (54 m²) along streets 12 m apart.
fn old_town(rows: i64, houses: i64) -> Vec<Lot> {
    (0..rows * houses)
        .map(|k| {
            let (i, j) = (k % houses, k / houses);
            lot(k, 6.0 * i as f64, 21.0 * j as f64, 6.0, 9.0, kind("yes"))
        })
        .collect()
}

#[test]
fn a_village_stays_low_whatever_its_countrys_level() {
    // Issue 42's villages: at most 5 % at 5+ storeys, no footprint under 60 m² above 2.
    for level in [2.0, 3.0] {
        let lots = village();
        let out = run_in(&lots, zone(level, false));
        let all: Vec<Estimate> = out.estimates.iter().flatten().copied().collect();
        assert_eq!(all.len(), lots.len());
        let tall = all.iter().filter(|e| e.storeys >= 5.0).count();
        assert!(tall * 20 <= all.len(), "{tall} of {} at 5+", all.len());
        for (e, f) in all.iter().zip(&out.features) {
            if f64::from(f[0]).exp() < 60.0 {
                assert!(e.storeys <= 2.0, "{e:?}");
            }
        }
        let mut houses: Vec<f64> = all
            .iter()
            .zip(&out.features)
            .filter(|(_, f)| (100.0..200.0).contains(&f64::from(f[0]).exp()))
            .map(|(e, _)| e.storeys)
            .collect();
        houses.sort_by(f64::total_cmp);
        assert!(houses[houses.len() / 2] <= 2.0, "{houses:?}");
    }
}

#[test]
fn small_town_houses_stay_at_two_storeys_outside_the_kbs_towns_and_rise_in_them() {
    let lots = old_town(6, 20);
    let small = run_in(&lots, zone(3.0, false));
    for e in small.estimates.iter().flatten() {
        assert!(e.storeys <= 2.0, "{e:?}");
    }
    // In a town of 4-storey fabric, narrow row houses are 3 (their footprint's cap).
    let town = run_in(&lots, zone(4.0, true));
    for e in town.estimates.iter().flatten() {
        assert_eq!(e.storeys, 3.0, "{e:?}");
    }
}

#[test]
fn a_city_of_blocks_rises_to_its_zones_level() {
    // Perimeter blocks of 16 m deep, 40 m long buildings (640 m²), closely set.
    let lots: Vec<Lot> = (0..60)
        .map(|k| {
            let (i, j) = (k % 6, k / 6);
            lot(k, 42.0 * i as f64, 18.0 * j as f64, 40.0, 16.0, kind("yes"))
        })
        .collect();
    for level in [4.0, 6.0] {
        let out = run_in(&lots, zone(level, true));
        let mut s: Vec<f64> = out.estimates.iter().flatten().map(|e| e.storeys).collect();
        s.sort_by(f64::total_cmp);
        let median = s[s.len() / 2];
        assert!(
            (level..=level * 1.5).contains(&median),
            "level {level}: {s:?}"
        );
    }
}

/// Issue 42 step 4: every lot's form is set for the KB's appearance conditions, from the
/// estimator's features or measured anew: a row's members are attached, a lone house is not,
/// and a dense block's density class is above a hamlet's.
#[test]
fn forms_tell_rows_from_lone_houses_and_dense_blocks_from_hamlets() {
    use crate::model::Density;
    // A row of ten 6 x 10 m houses wall to wall, and 2 km away one house alone.
    let mut lots: Vec<Lot> = (0..10)
        .map(|k| lot(k, 6.0 * k as f64, 0.0, 6.0, 10.0, kind("yes")))
        .collect();
    // A dense block: 9 x 9 buildings of 20 x 20 m on a 25 m grid.
    for k in 0..81 {
        let (x, y) = (1000.0 + 25.0 * (k % 9) as f64, 25.0 * (k / 9) as f64);
        lots.push(lot(100 + k, x, y, 20.0, 20.0, kind("yes")));
    }
    lots.push(lot(500, 2000.0, 2000.0, 10.0, 10.0, kind("house")));
    for features in [Vec::new(), run(&lots).features] {
        let mut lots = lots.clone();
        apply_forms(&mut lots, &features);
        let form = |i: usize| {
            lots[i]
                .tags
                .form
                .unwrap_or_else(|| panic!("lot {i} has a form"))
        };
        assert!((1..9).all(|i| form(i).attached), "the row");
        assert!(!form(91).attached, "the lone house");
        assert_eq!(form(91).density, Density::Low);
        assert_eq!(
            form(10 + 40).density,
            Density::High,
            "the middle of the block"
        );
        // The interned tags are shared: the row's inner houses have one tag set.
        assert!(std::sync::Arc::ptr_eq(&lots[3].tags, &lots[4].tags));
    }
}

/// A zone where a share `pitched` of the roofs is pitched.
fn roofs_in(pitched: f64) -> RoofMix {
    RoofMix {
        pitched,
        ..RoofMix::DEFAULT
    }
}

/// A terrace of `n` houses wall to wall along x from (x0, 0): house `k` is `width(k)` wide
/// and `depth(k)` deep, with `tags(k)`.
fn terrace(
    id0: i64,
    x0: f64,
    n: i64,
    width: impl Fn(i64) -> f64,
    depth: impl Fn(i64) -> f64,
    tags: impl Fn(i64) -> BuildingTags,
) -> Vec<Lot> {
    let mut x = x0;
    (0..n)
        .map(|k| {
            let l = lot(id0 + k, x, 0.0, width(k), depth(k), tags(k));
            x += width(k);
            l
        })
        .collect()
}

/// The touching pairs of like size (members of one row) whose drawn roof families differ, and
/// every estimate's roof the likelier family of its probability (not a draw).
fn row_pairs_differing(out: &Outcome) -> (usize, usize) {
    for e in out.estimates.iter().flatten() {
        assert_eq!(e.shape != RoofShape::Flat, e.pitched >= 0.5, "{e:?}");
    }
    let flat = |i: u32| out.estimates[i as usize].map(|e| e.shape == RoofShape::Flat);
    let area = |i: u32| f64::from(out.features[i as usize][0]).exp();
    let mut n = 0;
    let mut differ = 0;
    for &(a, b, shared) in &out.touching {
        let (x, y) = (area(a), area(b));
        if shared < ROW_SHARED_M || x.max(y) / x.min(y) > ROW_AREA_RATIO {
            continue;
        }
        if let (Some(fa), Some(fb)) = (flat(a), flat(b)) {
            n += 1;
            differ += usize::from(fa != fb);
        }
    }
    (n, differ)
}

#[test]
fn a_flat_roofed_terrace_is_drawn_flat_and_a_pitched_row_pitched() {
    // Rowhouses of 5.5 x 14 m (flat-roofed brick rows) where a sixth of the roofs is pitched:
    // every one flat.
    let rows = terrace(0, 0.0, 12, |_| 5.5, |_| 14.0, |_| kind("yes"));
    let out = run_in(&rows, roofs_in(0.15));
    assert_eq!(row_pairs_differing(&out), (11, 0));
    for (i, e) in out.estimates.iter().enumerate() {
        let e = e.unwrap_or_else(|| panic!("house {i} estimated"));
        assert_eq!(e.shape, RoofShape::Flat, "house {i}: {e:?}");
        assert_ne!(e.roof_source, ValueSource::Tag);
    }
    // Cottages of 6 x 8 m where most roofs are pitched: every one pitched, one shape.
    let row = terrace(0, 0.0, 12, |_| 6.0, |_| 8.0, |_| kind("yes"));
    let out = run_in(&row, roofs_in(0.6));
    assert_eq!(row_pairs_differing(&out), (11, 0));
    for (i, e) in out.estimates.iter().enumerate() {
        let e = e.unwrap_or_else(|| panic!("house {i} estimated"));
        assert_eq!(e.shape, RoofShape::Gabled, "house {i}: {e:?}");
    }
}

#[test]
fn a_row_of_mixed_sizes_shares_one_roof_family() {
    // Alone, the 45 m² houses would be pitched and the 77 m² ones flat (the prior's size
    // steps); wall to wall they are one row and one family.
    let rows = terrace(
        0,
        0.0,
        10,
        |k| if k % 2 == 0 { 5.5 } else { 5.0 },
        |k| if k % 2 == 0 { 14.0 } else { 9.0 },
        |_| kind("yes"),
    );
    let mix = roofs_in(0.35);
    let out = run_in(&rows, mix);
    let alone = |i: usize| prior_roof(&mix, &out.features[i]) >= 0.0;
    assert!(!alone(0) && alone(1), "the prior tells them apart");
    assert_eq!(row_pairs_differing(&out), (9, 0));
}

#[test]
fn tagged_members_set_their_rows_roof_family() {
    let flat = BuildingTags {
        roof_shape: Some(RoofShape::Flat),
        ..kind("yes")
    };
    let hipped = BuildingTags {
        roof_shape: Some(RoofShape::Hipped),
        ..kind("yes")
    };
    // Where most roofs are pitched, a row whose tagged members are flat is flat; where most
    // are flat, a row whose tagged members are hipped is hipped (two rows 1 km apart).
    let mut lots = terrace(
        0,
        0.0,
        12,
        |_| 6.0,
        |_| 8.0,
        |k| {
            if k % 3 == 0 {
                flat.clone()
            } else {
                kind("yes")
            }
        },
    );
    lots.extend(terrace(
        100,
        1000.0,
        12,
        |_| 5.5,
        |_| 14.0,
        |k| {
            if k % 3 == 0 {
                hipped.clone()
            } else {
                kind("yes")
            }
        },
    ));
    let out = run_in(&lots, roofs_in(0.5));
    assert_eq!(row_pairs_differing(&out).1, 0);
    for (i, e) in out.estimates.iter().enumerate() {
        let Some(e) = e else { continue };
        if i % 12 % 3 == 0 {
            // A tagged member: its roof is its own (its height is estimated).
            assert_eq!(e.roof_source, ValueSource::Tag, "lot {i}: {e:?}");
            continue;
        }
        let want = if i < 12 {
            RoofShape::Flat
        } else {
            RoofShape::Hipped
        };
        assert_eq!(e.shape, want, "lot {i}: {e:?}");
        assert_eq!(e.roof_source, ValueSource::Neighbours, "lot {i}: {e:?}");
    }
    assert_eq!(out.estimates.iter().flatten().count(), 24);
}

#[test]
fn like_houses_along_a_street_get_like_heights() {
    // Ten like houses 20 m apart; one's model says 12 m, the others 7 m; a 40 m² shed among
    // them whose model says 3 m; a house 1 km away with no neighbours.
    let mut lots: Vec<Lot> = (0..10)
        .map(|k| lot(k, 20.0 * k as f64, 0.0, 10.0, 10.0, kind("yes")))
        .collect();
    lots.push(lot(10, 40.0, 30.0, 5.0, 8.0, kind("yes")));
    lots.push(lot(11, 1000.0, 1000.0, 10.0, 10.0, kind("yes")));
    let m = morph::measure(&lots);
    let points: Vec<Option<DVec2>> = lots
        .iter()
        .map(|l| l.bounds().map(|(lo, hi)| 0.5 * (lo + hi)))
        .collect();
    let mut base = vec![7f64.ln(); lots.len()];
    base[5] = 12f64.ln();
    base[10] = 3f64.ln();
    let out = local_form(&lots, &m, &points, base.clone());
    let h = |i: usize| out[i].exp();
    assert!(h(5) < 8.5, "the odd house comes most of the way: {}", h(5));
    assert!(
        h(4) > 7.0 && h(4) < 7.6,
        "its neighbours move a little: {}",
        h(4)
    );
    assert!(
        h(10) <= 3.0 + 1e-9,
        "a small footprint is never lifted: {}",
        h(10)
    );
    assert_eq!(out[11], base[11], "no neighbours, no change");
    // The same at one thread and at several (the neighbours are summed in index order).
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .map(|p| p.install(|| local_form(&lots, &m, &points, base.clone())));
    assert_eq!(one.ok(), Some(out));
}

/// Narrow old-town houses (50 m²) among tagged narrow houses of 5 storeys take their storeys
/// (up to [`SMALL_LENT_CAP`]); without small tagged lenders the footprint's cap of 3 holds,
/// and a 20 m² footprint stays at 2 whatever they say.
#[test]
fn small_tagged_lenders_lend_narrow_houses_their_storeys() {
    let five = BuildingTags {
        levels: Some(5.0),
        ..kind("yes")
    };
    // Two rows 30 m apart: the first of tagged 5 x 10 m houses, the second untagged, with a
    // 4 x 5 m footprint at its end.
    let mut lots: Vec<Lot> = (0..8)
        .map(|k| lot(k, 5.0 * k as f64, 0.0, 5.0, 10.0, five.clone()))
        .collect();
    lots.extend((0..8).map(|k| lot(100 + k, 5.0 * k as f64, 40.0, 5.0, 10.0, kind("yes"))));
    lots.push(lot(200, 60.0, 40.0, 4.0, 5.0, kind("yes")));
    let out = run_in(&lots, zone(3.0, true));
    for i in 8..16 {
        let e = out.estimates[i].unwrap_or_else(|| panic!("house {i} estimated"));
        assert_eq!(e.storeys, 5.0, "house {i}: {e:?}");
        assert!(e.voted && e.storey_cap >= 5.0, "{e:?}");
    }
    let tiny = out.estimates[16].unwrap_or_else(|| panic!("the 20 m² footprint estimated"));
    assert!(tiny.storeys <= 2.0, "{tiny:?}");
    // The same houses among tagged 5-storey blocks of 400 m²: not small lenders, capped.
    let mut lots: Vec<Lot> = (0..4)
        .map(|k| lot(k, 25.0 * k as f64, 0.0, 20.0, 20.0, five.clone()))
        .collect();
    lots.extend((0..8).map(|k| lot(100 + k, 5.0 * k as f64, 40.0, 5.0, 10.0, kind("yes"))));
    let out = run_in(&lots, zone(3.0, true));
    for i in 4..12 {
        let e = out.estimates[i].unwrap_or_else(|| panic!("house {i} estimated"));
        assert!(e.storeys <= 3.0, "house {i}: {e:?}");
    }
}

/// A row whose members' storeys the tagged neighbours voted keeps the voted storeys when it
/// takes the row's height, also where the vote agreed with the model (source `Model`): the
/// storeys are counted under the roof the estimate expected, not under the row's whole roof.
#[test]
fn voted_row_members_keep_their_voted_storeys() {
    let pitched_zone = RoofMix {
        pitched: 0.5,
        ..zone(4.0, true)
    };
    // Untagged 8 x 12 m houses in a row; tagged detached houses of the same size 30-60 m away.
    let untagged: Vec<Lot> = (0..6)
        .map(|k| lot(100 + k, 8.0 * k as f64, 0.0, 8.0, 12.0, kind("yes")))
        .collect();
    let alone = run_in(&untagged, pitched_zone);
    let model: Vec<f64> = alone
        .estimates
        .iter()
        .flatten()
        .map(|e| e.storeys)
        .collect();
    let levels = model[2];
    let tagged = BuildingTags {
        levels: Some(levels),
        ..kind("yes")
    };
    let mut lots = untagged.clone();
    lots.extend((0..6).map(|k| lot(k, 14.0 * k as f64, 40.0, 8.0, 12.0, tagged.clone())));
    let out = run_in(&lots, pitched_zone);
    for i in 0..untagged.len() {
        let e = out.estimates[i].unwrap_or_else(|| panic!("house {i} estimated"));
        assert!(e.voted, "{e:?}");
        assert_eq!(e.storeys, levels, "house {i}: {e:?} (alone {model:?})");
    }
}
