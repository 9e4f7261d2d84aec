//! The global map's keep rule (`node::fusion::Keep`): far Gaussians (sky at the network's
//! farthest depth) and unconfident ones stay out of the fused map; near ones are fused; the
//! extremes (distance 0, huge, NaN) and the setting's round trip through the map file.

use glam::{DAffine3, DQuat, DVec3, Quat, Vec3};
use node::fusion::{FusionConfig, GlobalMap, Keep, DEFAULT_MAX_RANGE_M};
use node::research::map_quality::{Backdrops, BinMap};
use renderer::{Gaussian, GaussianSet};

fn gauss(mean: [f32; 3], confidence: f32) -> Gaussian {
    Gaussian {
        mean: Vec3::from_array(mean),
        log_scale: Vec3::splat(0.05f32.ln()),
        rotation: Quat::IDENTITY,
        opacity: 0.9,
        color: Vec3::new(0.5, 0.7, 1.0),
        confidence,
    }
}

fn set_of(gs: &[Gaussian]) -> GaussianSet {
    let mut set = GaussianSet::default();
    gs.iter().for_each(|&g| set.push(g));
    set
}

#[test]
fn sky_at_the_far_plane_is_not_fused_and_the_road_is() {
    let mut map = GlobalMap::new(FusionConfig::default()).unwrap();
    // A bin camera 1 km from the world origin, turned: the range is measured in the bin
    // frame (from its camera), not in the world.
    let pose = DAffine3::from_rotation_translation(
        DQuat::from_rotation_z(0.7),
        DVec3::new(1000.0, -250.0, 3.0),
    );
    let road = gauss([0.0, 1.6, 12.0], 0.8);
    let kerb = gauss([3.0, 1.5, 19.0], 0.8);
    let sky = gauss([-20.0, -30.0, 100.0], 0.9);
    let far_wall = gauss([0.0, 0.0, 30.0], 0.9);
    let inc = map
        .insert_bin(0, &set_of(&[road, sky, kerb, far_wall]), pose)
        .unwrap();
    assert_eq!(inc.added.len(), 2);
    assert_eq!(inc.stats.not_kept, 2);
    let kept: Vec<DVec3> = map.gaussians().map(|(_, g)| g.position).collect();
    for (want, got) in [road, kerb].iter().zip(&kept) {
        let p = pose.transform_point3(want.mean.as_dvec3());
        assert!((p - *got).length() < 1e-9, "{p} vs {got}");
    }
    assert_eq!(DEFAULT_MAX_RANGE_M, Keep::default().max_range_m);
}

#[test]
fn what_is_not_fused_for_range_is_the_sky_layer_drawn_from_its_own_bins_frames() {
    let keep = Keep::default();
    let road = gauss([0.0, 1.6, 12.0], 0.8);
    let sky = gauss([-20.0, -30.0, 100.0], 0.9);
    let far_wall = gauss([0.0, 0.0, 60.0], 0.1);
    let lost = gauss([f32::NAN, 0.0, 1e3], 0.9);
    let bin = set_of(&[road, sky, far_wall, lost]);
    let layer = keep.backdrop(&bin);
    assert_eq!(layer.means, vec![sky.mean, far_wall.mean]);
    assert!(Keep::ALL.backdrop(&bin).is_empty());
    // Two bins 10 m apart along a turned road, far from the world origin.
    let turn = DQuat::from_rotation_y(0.3);
    let p0 = DAffine3::from_rotation_translation(turn, DVec3::new(1e5, 3.0, -2e5));
    let p1 = p0 * DAffine3::from_translation(DVec3::new(0.0, 0.0, 10.0));
    let maps = [
        BinMap {
            bin_id: 0,
            first_frame: 0,
            bin_to_world: p0,
            set: set_of(&[road, sky]),
        },
        BinMap {
            bin_id: 1,
            first_frame: 10,
            bin_to_world: p1,
            set: set_of(&[far_wall]),
        },
    ];
    let b = Backdrops::new(&maps, keep);
    // Frame 5 belongs to bin 0; seen from bin 0's camera the sky sits where the bin put it.
    let at5 = b.at(5, p0);
    assert_eq!(at5.len(), 1);
    assert!((at5.means[0] - sky.mean).length() < 1e-3, "{:?}", at5.means);
    // Frame 12 belongs to bin 1; from 2 m behind bin 1's camera its wall is 62 m ahead.
    let at12 = b.at(
        12,
        p1 * DAffine3::from_translation(DVec3::new(0.0, 0.0, -2.0)),
    );
    assert_eq!(at12.len(), 1);
    assert!(
        (at12.means[0] - Vec3::new(0.0, 0.0, 62.0)).length() < 1e-3,
        "{:?}",
        at12.means
    );
    assert!((at12.rotations[0].length() - 1.0).abs() < 1e-5);
    let none = Backdrops::new(&[], keep);
    assert!(none.at(3, p0).is_empty());
}

#[test]
fn the_rule_at_its_extremes() {
    let keep = Keep {
        max_range_m: 40.0,
        min_confidence: 0.2,
    };
    // Distance 0 and just inside the range are kept; just beyond, huge and NaN are not.
    assert!(keep.keeps(Vec3::ZERO, 0.5));
    assert!(keep.keeps(Vec3::new(0.0, 0.0, 1e-6), 0.5));
    assert!(keep.keeps(Vec3::new(0.0, 0.0, 39.99), 0.5));
    assert!(!keep.keeps(Vec3::new(0.0, 0.0, 40.01), 0.5));
    assert!(!keep.keeps(Vec3::new(0.0, 0.0, 1e30), 0.5));
    assert!(!keep.keeps(Vec3::new(0.0, 0.0, f32::INFINITY), 0.5));
    assert!(!keep.keeps(Vec3::new(f32::NAN, 0.0, 5.0), 0.5));
    // The confidence floor: below is out, at it is in, NaN is out.
    assert!(!keep.keeps(Vec3::new(0.0, 0.0, 5.0), 0.19));
    assert!(keep.keeps(Vec3::new(0.0, 0.0, 5.0), 0.2));
    assert!(!keep.keeps(Vec3::new(0.0, 0.0, 5.0), f32::NAN));
    // Keep::ALL fuses any finite distance.
    assert!(Keep::ALL.keeps(Vec3::new(0.0, 0.0, 1e30), 0.0));
    // Settings out of range are refused.
    for bad in [
        Keep {
            max_range_m: 0.0,
            ..keep
        },
        Keep {
            max_range_m: f32::NAN,
            ..keep
        },
        Keep {
            min_confidence: 1.5,
            ..keep
        },
    ] {
        let config = FusionConfig {
            keep: bad,
            ..FusionConfig::default()
        };
        assert!(GlobalMap::new(config).is_err(), "{bad:?}");
    }
}

#[test]
fn an_unconfident_bin_is_kept_out_and_a_nan_position_is_counted_invalid() {
    let mut map = GlobalMap::new(FusionConfig {
        keep: Keep {
            max_range_m: 40.0,
            min_confidence: 0.3,
        },
        ..FusionConfig::default()
    })
    .unwrap();
    let set = set_of(&[
        gauss([0.0, 0.0, 5.0], 0.1),
        gauss([0.0, 0.0, 6.0], 0.6),
        gauss([f32::NAN, 0.0, 6.0], 0.6),
    ]);
    let inc = map.insert_bin(0, &set, DAffine3::IDENTITY).unwrap();
    assert_eq!(
        (
            inc.added.len(),
            inc.stats.not_kept,
            inc.stats.skipped_invalid
        ),
        (1, 1, 1)
    );
}

#[test]
fn the_keep_rule_is_saved_with_the_map() {
    let config = FusionConfig {
        keep: Keep {
            max_range_m: 25.0,
            min_confidence: 0.05,
        },
        ..FusionConfig::default()
    };
    let mut map = GlobalMap::new(config).unwrap();
    map.insert_bin(
        0,
        &set_of(&[gauss([0.0, 0.0, 5.0], 0.5)]),
        DAffine3::IDENTITY,
    )
    .unwrap();
    let path = std::env::temp_dir().join(format!("keep_{}.map", std::process::id()));
    map.save(&path).unwrap();
    let back = GlobalMap::load(&path).unwrap();
    assert_eq!(*back.config(), config);
    assert_eq!(back.len(), 1);
    let _ = std::fs::remove_file(&path);
}
