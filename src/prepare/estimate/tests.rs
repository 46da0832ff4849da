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
    // A like-sized untagged neighbour of the hotels does take their height, with its source.
    assert!(e(10).storeys >= 5.0, "{:?}", e(10));
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
