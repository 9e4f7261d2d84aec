//! Tests of the view's tiled copy of the map.

use super::*;

fn g(x: f64, y: f64) -> WorldGaussian {
    crate::view::test_gaussian::at(DVec3::new(x, y, 1.0))
}

fn inc(bin_id: u64, added: &[(u64, f64, f64)], removed: &[u64]) -> Increment {
    Increment {
        bin_id,
        added: added
            .iter()
            .map(|&(i, x, y)| (GaussianId(i), g(x, y)))
            .collect(),
        removed: removed.iter().map(|&i| GaussianId(i)).collect(),
        ..Increment::default()
    }
}

fn rules() -> TileRules {
    TileRules {
        side_m: 10.0,
        keep_m: 25.0,
        cache_gaussians: 3,
    }
}

#[test]
fn increments_land_in_their_tiles_and_a_bad_one_changes_nothing() {
    let mut t = ViewTiles::new(rules());
    t.apply(
        &inc(0, &[(0, 1.0, 1.0), (1, 15.0, 1.0), (2, -0.5, 1.0)], &[]),
        1,
    )
    .unwrap();
    assert_eq!(t.len(), 3);
    assert_eq!(t.tile_counts(), (3, 0), "tiles (0,0), (1,0) and (-1,0)");
    t.apply(&inc(1, &[(3, 2.0, 2.0)], &[0]), 2).unwrap();
    assert_eq!(t.info((0, 0)).unwrap().version, 2);
    assert_eq!(t.info((1, 0)).unwrap().version, 1, "untouched");
    assert_eq!(
        t.apply(&inc(2, &[(9, 0.0, 0.0)], &[42]), 3),
        Err(TilesError::UnknownId { bin_id: 2, id: 42 })
    );
    assert_eq!(
        t.apply(&inc(2, &[(3, 0.0, 0.0)], &[]), 3),
        Err(TilesError::DuplicateId { bin_id: 2, id: 3 })
    );
    assert_eq!(t.len(), 3, "a refused increment changes nothing");
    assert_eq!(t.info((0, 0)).unwrap().version, 2);
    // Removing a tile's last Gaussian removes the tile.
    t.apply(&inc(3, &[], &[2]), 4).unwrap();
    assert!(t.info((-1, 0)).is_none());
}

#[test]
fn tiles_the_vehicle_leaves_are_let_go_then_fetched_into_a_bounded_cache() {
    let mut t = ViewTiles::new(rules());
    let far: Vec<(u64, f64, f64)> = (0..3).map(|i| (i, 1.0 + i as f64, 1.0)).collect();
    t.apply(&inc(0, &far, &[]), 1).unwrap();
    t.apply(&inc(1, &[(10, 101.0, 1.0), (11, 111.0, 1.0)], &[]), 2)
        .unwrap();
    t.let_go_far_from(DVec3::new(105.0, 5.0, 0.0));
    assert_eq!(t.len(), 2, "tile (0,0) let go");
    assert_eq!(t.tile_counts(), (2, 1));
    let info = t.info((0, 0)).unwrap();
    assert_eq!((info.held, info.gaussians, info.version), (false, 3, 1));
    // Once a tile is let go, removals of what the view no longer holds are skipped, and
    // an addition to a let-go tile bumps its version without being held.
    t.apply(&inc(2, &[(20, 5.0, 5.0)], &[1]), 3).unwrap();
    assert_eq!(t.skipped_removals(), 1);
    assert_eq!(t.info((0, 0)).unwrap().version, 3);
    assert_eq!(t.len(), 2);
    // Asking for it marks it wanted; the node's answer (with a Gaussian of another
    // tile, ignored) is cached for the tile's version.
    assert!(t.tile((0, 0)).is_none());
    assert_eq!(t.wanted(), vec![(0, 0)]);
    let answer = [
        (GaussianId(0), g(1.0, 1.0)),
        (GaussianId(2), g(3.0, 1.0)),
        (GaussianId(20), g(5.0, 5.0)),
        (GaussianId(99), g(55.0, 5.0)),
    ];
    t.fetched(&[(0, 0)], &answer);
    assert!(t.wanted().is_empty());
    let (version, got) = t.tile((0, 0)).unwrap();
    assert_eq!((version, got.len()), (3, 3));
    // A newer version is fetched again; the cache (3 Gaussians) keeps the newest tile.
    t.apply(&inc(3, &[(21, 6.0, 6.0)], &[]), 4).unwrap();
    assert!(t.tile((0, 0)).is_none(), "the cached copy is of version 3");
    t.fetched(&[(0, 0)], &answer);
    t.fetched(&[(0, 0)], &answer[..1]);
    assert_eq!(t.tile((0, 0)).unwrap().1.len(), 1);
    assert!(t.cached_gaussians <= 3);
}

#[test]
fn the_page_gets_the_nearest_tiles_until_its_budget_with_the_last_one_cut() {
    let mut t = ViewTiles::new(rules());
    let mut added = Vec::new();
    for tile in 0..5u64 {
        for k in 0..=tile {
            added.push((tile * 10 + k, tile as f64 * 10.0 + 1.0, 1.0));
        }
    }
    t.apply(&inc(0, &added, &[]), 1).unwrap();
    let listed = |at: f64, radius: f64, budget: usize| -> Vec<(TileKey, usize, usize)> {
        t.near(DVec3::new(at, 0.0, 0.0), radius, budget)
            .into_iter()
            .map(|n| (n.key, n.info.gaussians, n.take))
            .collect()
    };
    // 1 + 2 + 3 Gaussians fit 6 exactly; with 8 the fourth tile gives 2 of its 4.
    assert_eq!(
        listed(0.0, 1000.0, 6),
        vec![((0, 0), 1, 1), ((1, 0), 2, 2), ((2, 0), 3, 3)]
    );
    assert_eq!(listed(0.0, 1000.0, 8).last(), Some(&((3, 0), 4, 2)));
    assert_eq!(listed(0.0, 15.0, 1000).len(), 2, "within 15 m");
    // A budget smaller than the nearest tile takes part of it, never more than asked.
    assert_eq!(listed(45.0, 1000.0, 3), vec![((4, 0), 5, 3)]);
    assert_eq!(listed(45.0, 1000.0, 0), vec![]);
    let total: usize = listed(0.0, 1000.0, usize::MAX).iter().map(|l| l.2).sum();
    assert_eq!(total, 15, "an unbounded budget takes every Gaussian");
}

#[test]
fn a_cut_tile_keeps_its_most_opaque_gaussians_in_their_order() {
    let opacities = [0.5, 0.9, f32::NAN, 0.9, 0.1, 1.0, 0.0];
    let gaussians: Vec<WorldGaussian> = opacities
        .iter()
        .map(|&o| WorldGaussian {
            opacity: o,
            ..g(0.0, 0.0)
        })
        .collect();
    assert_eq!(most_opaque(&gaussians, 3), vec![1, 3, 5]);
    // Ties keep the earlier: of the two 0.9s only index 1 fits beside 1.0.
    assert_eq!(most_opaque(&gaussians, 2), vec![1, 5]);
    assert_eq!(most_opaque(&gaussians, 0), Vec::<usize>::new());
    // NaN is the least opaque: the last to be kept.
    assert_eq!(most_opaque(&gaussians, 6), vec![0, 1, 3, 4, 5, 6]);
    assert_eq!(most_opaque(&gaussians, 7), (0..7).collect::<Vec<_>>());
    assert_eq!(most_opaque(&gaussians, usize::MAX).len(), 7);
    assert!(most_opaque(&[], 5).is_empty());
}

#[test]
fn extreme_positions_and_settings_stay_defined() {
    let bad = TileRules {
        side_m: f64::NAN,
        keep_m: -1.0,
        cache_gaussians: 0,
    };
    let mut t = ViewTiles::new(bad);
    assert_eq!(t.rules().side_m, TileRules::default().side_m);
    assert_eq!(t.rules().keep_m, TileRules::default().keep_m);
    assert_eq!(t.tile_of(DVec3::new(f64::NAN, f64::INFINITY, 0.0)), (0, 0));
    assert_eq!(
        t.tile_of(DVec3::new(1e300, -1e300, 0.0)),
        (i64::MAX, i64::MIN)
    );
    t.apply(&inc(0, &[(0, 1e300, -1e300), (1, 0.0, 0.0)], &[]), 1)
        .unwrap();
    t.let_go_far_from(DVec3::ZERO);
    assert_eq!(t.tile_counts(), (1, 1));
    assert!(t.tile((i64::MAX, i64::MIN)).is_none());
    t.fetched(
        &[(i64::MAX, i64::MIN)],
        &[(GaussianId(0), g(1e300, -1e300))],
    );
    assert!(
        t.tile((i64::MAX, i64::MIN)).is_none(),
        "a cache of 0 keeps nothing"
    );
    let (lo, hi) = t.bounds((i64::MAX, i64::MIN));
    assert!(lo.x.is_finite() && hi.y.is_finite());
}
