//! Opacity and confidence stay in [0, 1] on every path into the map: fusion and the reader
//! of stored Gaussians (the base, the journal and the tiles).

use std::path::Path;

use glam::{DAffine3, DVec3, Quat, Vec3};
use renderer::gaussians::Gaussian;
use renderer::GaussianSet;

use super::snapshot::{fnv1a, put_gaussian, Reader};
use super::{FusionConfig, GaussianId, GlobalMap, WorldGaussian};

/// A bin map of one Gaussian per (opacity, confidence), 1 m apart along x, 5 m ahead.
fn bin(values: &[(f32, f32)]) -> GaussianSet {
    let mut set = GaussianSet::default();
    for (i, &(opacity, confidence)) in values.iter().enumerate() {
        set.push(Gaussian {
            mean: Vec3::new(i as f32, 0.0, 5.0),
            log_scale: Vec3::splat(-3.0),
            rotation: Quat::IDENTITY,
            opacity,
            color: Vec3::splat(0.5),
            confidence,
        });
    }
    set
}

/// The stored (opacity, confidence) of the map's Gaussians, in id order.
fn values(map: &GlobalMap) -> Vec<(f32, f32)> {
    map.gaussians()
        .map(|(_, g)| (g.opacity, g.confidence))
        .collect()
}

#[test]
fn fusion_clamps_opacity_and_confidence_and_skips_nan() {
    let mut map = GlobalMap::new(FusionConfig::default()).unwrap();
    let inc = map
        .insert_bin(
            0,
            &bin(&[
                (1e30, 1e30),
                (0.5, -1.0),
                (0.5, f32::NAN),
                (f32::NAN, 0.5),
                (-1.0, 0.5),
                (0.5, f32::INFINITY),
                (2.0, 0.25),
            ]),
            DAffine3::IDENTITY,
        )
        .unwrap();
    // 1e30 is 1, -1 is 0 (an opacity of 0 is under the floor: pruned); NaN and infinity
    // never enter the map.
    assert_eq!(values(&map), [(1.0, 1.0), (0.5, 0.0), (1.0, 0.25)]);
    assert_eq!(inc.stats.skipped_invalid, 3);
    assert_eq!(inc.stats.pruned_opacity, 1);
    assert!(inc
        .added
        .iter()
        .all(|(_, g)| g.confidence <= 1.0 && g.opacity <= 1.0));

    // A later bin in the same cells: 1e30 is no more than the 1 already there, so it does
    // not take the cell over; 0.75 takes over the cell whose -1 became 0.
    let inc = map
        .insert_bin(1, &bin(&[(0.5, 1e30), (0.5, 0.75)]), DAffine3::IDENTITY)
        .unwrap();
    assert_eq!(inc.stats.dropped_lower_confidence, 1);
    assert_eq!(inc.stats.replaced, 1);
    let by_bin: Vec<(u64, f32)> = map
        .gaussians()
        .map(|(_, g)| (g.bin_id, g.confidence))
        .collect();
    assert_eq!(by_bin, [(0, 1.0), (0, 0.25), (1, 0.75)]);
}

fn world(opacity: f32, confidence: f32) -> WorldGaussian {
    WorldGaussian {
        position: DVec3::new(1.0e5, 2.0, 3.0),
        log_scale: Vec3::splat(-2.0),
        rotation: Quat::IDENTITY,
        opacity,
        color: Vec3::splat(0.25),
        confidence,
        bin_id: 4,
    }
}

/// What the shared reader makes of one stored Gaussian.
fn read_back(g: &WorldGaussian) -> Result<WorldGaussian, super::StoreError> {
    let mut bytes = Vec::new();
    put_gaussian(&mut bytes, GaussianId(9), g);
    let mut r = Reader {
        bytes: &bytes,
        pos: 0,
        path: Path::new("test.ssgmap"),
    };
    r.gaussian().map(|(_, g)| g)
}

#[test]
fn the_reader_of_stored_gaussians_clamps_and_refuses_nan() {
    for ((opacity, confidence), want) in [
        ((1e30, 1e30), (1.0, 1.0)),
        ((-1.0, -1.0), (0.0, 0.0)),
        ((0.5, 0.25), (0.5, 0.25)),
        ((f32::MAX, -0.0), (1.0, -0.0)),
    ] {
        let g = read_back(&world(opacity, confidence)).unwrap();
        assert_eq!((g.opacity, g.confidence), want);
        assert_eq!(g.position, world(0.0, 0.0).position);
    }
    for bad in [f32::NAN, f32::INFINITY] {
        assert!(read_back(&world(bad, 0.5)).is_err());
        assert!(read_back(&world(0.5, bad)).is_err());
    }
}

#[test]
fn a_map_file_holding_a_confidence_of_1e30_restores_it_as_1() {
    let mut map = GlobalMap::new(FusionConfig::default()).unwrap();
    map.insert_bin(0, &bin(&[(0.5, 0.123_456_7)]), DAffine3::IDENTITY)
        .unwrap();
    let mut bytes = map.to_bytes();
    // Another writer's file: the confidence is 1e30, its checksum right.
    let old = 0.123_456_7f32.to_le_bytes();
    let at = bytes.windows(4).position(|w| w == old).unwrap();
    bytes[at..at + 4].copy_from_slice(&1e30f32.to_le_bytes());
    let body = bytes.len() - 8;
    let sum = fnv1a(&bytes[..body]);
    bytes[body..].copy_from_slice(&sum.to_le_bytes());
    let restored = GlobalMap::from_bytes(&bytes, Path::new("map.ssgmap")).unwrap();
    assert_eq!(values(&restored), [(0.5, 1.0)]);
    // Its cell competes at 1: a bin of confidence 1 does not take it over.
    let mut restored = restored;
    let inc = restored
        .insert_bin(1, &bin(&[(0.5, 1.0)]), DAffine3::IDENTITY)
        .unwrap();
    assert_eq!(inc.stats.dropped_lower_confidence, 1);
}
