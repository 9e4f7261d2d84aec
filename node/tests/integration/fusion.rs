//! The global map: fusion rule, f64 precision far from the origin, increments against
//! snapshots, budget eviction, pruning, bad input, save/restore and the bird's-eye view.

use std::f64::consts::FRAC_PI_2;
use std::path::PathBuf;

use glam::{DAffine3, DMat3, DQuat, DVec2, DVec3, Quat, Vec3};
use node::fusion::{
    bev_image, decode_update, encode_map_snapshot, local_set, save_bev_png, snapshot_message,
    BevView, FusionConfig, FusionError, GaussianId, GlobalMap, Keep, MapReplica, StoreError,
    Update,
};
use node::msg::Message;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use renderer::{Gaussian, GaussianSet};

/// A small Gaussian (1 cm) at `mean` with confidence `confidence` and colour `color`.
fn gauss(mean: [f32; 3], confidence: f32, color: [f32; 3]) -> Gaussian {
    Gaussian {
        mean: Vec3::from_array(mean),
        log_scale: Vec3::splat(0.01f32.ln()),
        rotation: Quat::IDENTITY,
        opacity: 0.9,
        color: Vec3::from_array(color),
        confidence,
    }
}

fn set_of(gs: &[Gaussian]) -> GaussianSet {
    let mut set = GaussianSet::default();
    gs.iter().for_each(|&g| set.push(g));
    set
}

/// A map that fuses every distance and confidence (the keep rule has its own tests in
/// `fusion_keep.rs`).
pub(crate) fn map_with(cell_size: f64, opacity_floor: f32, max_gaussians: usize) -> GlobalMap {
    GlobalMap::new(FusionConfig {
        cell_size,
        opacity_floor,
        max_gaussians,
        keep: Keep::ALL,
        ..FusionConfig::default()
    })
    .unwrap()
}

fn at(x: f64) -> DAffine3 {
    DAffine3::from_translation(DVec3::new(x, 0.0, 0.0))
}

fn tmp_path(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("stereosplat_fusion_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

#[test]
fn higher_confidence_wins_in_overlap_cells_and_the_rest_is_kept() {
    let mut map = map_with(1.0, 0.01, 1000);
    // Bin 1 at the origin: cell 0 holds two (max confidence 0.5), cells 1 and 2 one each.
    let a = map
        .insert_bin(
            1,
            &set_of(&[
                gauss([0.2, 0.5, 0.5], 0.2, [1.0, 0.0, 0.0]),
                gauss([0.7, 0.5, 0.5], 0.5, [1.0, 0.0, 0.0]),
                gauss([1.5, 0.5, 0.5], 0.9, [1.0, 0.0, 0.0]),
                gauss([2.5, 0.5, 0.5], 0.3, [1.0, 0.0, 0.0]),
            ]),
            at(0.0),
        )
        .unwrap();
    assert_eq!(a.added.len(), 4);
    assert_eq!(map.cell_count(), 3);
    let ids_a: Vec<_> = a.added.iter().map(|(id, _)| *id).collect();

    // Bin 2 one metre further: 0.7 beats 0.5 in cell 0, 0.6 loses to 0.9 in cell 1, 0.3 ties
    // 0.3 in cell 2 (the incumbent stays), cell 4 is new.
    let b = map
        .insert_bin(
            2,
            &set_of(&[
                gauss([-0.5, 0.5, 0.5], 0.7, [0.0, 1.0, 0.0]),
                gauss([0.5, 0.5, 0.5], 0.6, [0.0, 1.0, 0.0]),
                gauss([1.5, 0.5, 0.5], 0.3, [0.0, 1.0, 0.0]),
                gauss([3.5, 0.5, 0.5], 0.1, [0.0, 1.0, 0.0]),
            ]),
            at(1.0),
        )
        .unwrap();
    assert_eq!(b.removed, ids_a[..2].to_vec());
    assert_eq!(b.stats.replaced, 2);
    assert_eq!(b.stats.dropped_lower_confidence, 2);
    let added: Vec<_> = b
        .added
        .iter()
        .map(|(_, g)| (g.position, g.confidence))
        .collect();
    assert_eq!(
        added,
        vec![
            (DVec3::new(0.5, 0.5, 0.5), 0.7),
            (DVec3::new(4.5, 0.5, 0.5), 0.1)
        ]
    );
    assert!(b.added.iter().all(|(id, g)| id.0 >= 4 && g.bin_id == 2));

    let snap = map.snapshot();
    let by_cell: Vec<_> = snap
        .gaussians
        .iter()
        .map(|(_, g)| (g.position.x, g.confidence, g.bin_id))
        .collect();
    assert_eq!(
        by_cell,
        vec![(1.5, 0.9, 1), (2.5, 0.3, 1), (0.5, 0.7, 2), (4.5, 0.1, 2)]
    );
    assert_eq!(snap.last_bin_id, Some(2));
}

#[test]
fn positions_far_from_the_origin_stay_exact() {
    let mut map = map_with(0.2, 0.01, 1000);
    let t = DVec3::new(100_000.123_456_789, -99_999.987_654_321, 12.5);
    // A quarter turn about z (exact entries): world = (t.x - y, t.y + x, t.z + z).
    let r = DMat3::from_cols(DVec3::Y, -DVec3::X, DVec3::Z);
    let pose = DAffine3::from_mat3_translation(r, t);
    let locals = [
        [1.25f32, -0.375, 7.5],
        [-3.1, 0.7, 20.3],
        [0.001, 0.002, 0.003],
    ];
    let local_rot = Quat::from_rotation_x(0.4);
    let mut gs: Vec<_> = locals.iter().map(|&m| gauss(m, 0.5, [0.5; 3])).collect();
    gs.iter_mut().for_each(|g| g.rotation = local_rot);
    let inc = map.insert_bin(7, &set_of(&gs), pose).unwrap();
    assert_eq!(inc.added.len(), 3);
    let expected: Vec<DVec3> = locals
        .iter()
        .map(|m| {
            let m = Vec3::from_array(*m).as_dvec3();
            DVec3::new(t.x - m.y, t.y + m.x, t.z + m.z)
        })
        .collect();
    for ((_, g), e) in inc.added.iter().zip(&expected) {
        assert!(
            (g.position - *e).abs().max_element() < 1e-6,
            "{} vs {e}",
            g.position
        );
        // Rotation: the pose's quarter turn composed with the local rotation.
        let want = (DQuat::from_rotation_z(FRAC_PI_2) * local_rot.as_dquat()).as_quat();
        assert!(g.rotation.dot(want).abs() > 1.0 - 1e-6);
        assert_eq!(g.log_scale, Vec3::splat(0.01f32.ln()));
    }

    // Save and restore: bit-identical f64 positions.
    let path = tmp_path("far.map");
    map.save(&path).unwrap();
    let back = GlobalMap::load(&path).unwrap();
    assert_eq!(back.snapshot(), map.snapshot());

    // Export around an f64 origin next to the map: small f32 offsets, still exact to 1e-6.
    let set = local_set(
        back.gaussians().map(|(_, g)| g),
        DAffine3::from_translation(t),
    )
    .unwrap();
    for (m, e) in set.means.iter().zip(&expected) {
        assert!((m.as_dvec3() - (*e - t)).abs().max_element() < 1e-6, "{m}");
    }
    assert!(set.rotations[0].dot(inc.added[0].1.rotation).abs() > 1.0 - 1e-6);
    // The exported set goes through the renderer's PLY unchanged.
    let mut ply = Vec::new();
    renderer::ply::write_ply(&set, &mut ply).unwrap();
    assert_eq!(
        renderer::ply::read_ply(ply.as_slice()).unwrap().means,
        set.means
    );
}

/// A random bin: origin 4 m further along x than the last (so consecutive bins overlap
/// by half), a random yaw, Gaussians in an 8 x 2 x 10 m box around the origin, some below
/// the opacity floor, some with NaN fields, every 17th bin empty.
pub(crate) fn random_bin(rng: &mut ChaCha8Rng, k: u64) -> (GaussianSet, DAffine3) {
    let yaw = rng.random_range(-0.3..0.3);
    let pose = DAffine3::from_rotation_translation(
        DQuat::from_rotation_z(yaw),
        DVec3::new(4.0 * k as f64, rng.random_range(-1.0..1.0), 0.0),
    );
    let n = if k % 17 == 16 {
        0
    } else {
        rng.random_range(20..80)
    };
    let mut set = GaussianSet::default();
    for _ in 0..n {
        let mut g = gauss(
            [
                rng.random_range(-4.0..4.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(0.0..10.0),
            ],
            rng.random_range(0.0..1.0),
            [rng.random(), rng.random(), rng.random()],
        );
        g.opacity = rng.random_range(0.0..1.0);
        g.rotation = Quat::from_rotation_y(rng.random_range(-3.0..3.0));
        if rng.random_range(0..40) == 0 {
            g.color.y = f32::NAN;
        }
        set.push(g);
    }
    (set, pose)
}

#[test]
fn replayed_increments_equal_the_snapshot_over_50_random_bins() {
    let budget = 300;
    let mut map = map_with(1.0, 0.1, budget);
    let mut replica = MapReplica::new();
    let mut late: Option<MapReplica> = None;
    let mut rng = ChaCha8Rng::seed_from_u64(42);
    let (mut replaced, mut evicted, mut skipped, mut pruned) = (0, 0, 0, 0);
    let mut last_id = None;
    for k in 0..50u64 {
        let (set, pose) = random_bin(&mut rng, k);
        let inc = map.insert_bin(k, &set, pose).unwrap();
        assert!(map.len() <= budget, "bin {k}: {} > {budget}", map.len());
        // Ids are new: above every id published before.
        if let (Some(first), Some(last)) = (inc.added.first(), last_id) {
            assert!(first.0 > last);
        }
        last_id = inc.added.last().map(|(id, _)| *id).or(last_id);
        if set.is_empty() {
            assert!(inc.is_empty());
        }
        replaced += inc.stats.replaced;
        evicted += inc.stats.evicted;
        skipped += inc.stats.skipped_invalid;
        pruned += inc.stats.pruned_opacity;
        replica.apply(&inc).unwrap();
        if let Some(late) = late.as_mut() {
            late.apply(&inc).unwrap();
        }
        if k == 25 {
            late = Some(MapReplica::from_snapshot(&map.snapshot()));
        }
        assert_eq!(replica.snapshot(), map.snapshot(), "bin {k}");
    }
    assert_eq!(late.unwrap().snapshot(), map.snapshot());
    assert!(replaced > 0 && evicted > 0 && skipped > 0 && pruned > 0);
    // The snapshot encoded straight from the map is the message of its snapshot, byte for
    // byte, written into the buffer reserved up front (never regrown).
    let header = node::msg::std_msgs::Header::default();
    let direct = encode_map_snapshot(&map, header.clone()).unwrap();
    let copied = snapshot_message(&map.snapshot(), map.increments(), header).unwrap();
    assert_eq!(direct, copied.encode());
    assert!(
        direct.capacity() < direct.len() + 2048,
        "{} bytes in a buffer of {}",
        direct.len(),
        direct.capacity()
    );
    let message = node::msg::map_update::MapUpdate::decode(&direct).unwrap();
    let Update::Snapshot(decoded) = decode_update(&message).unwrap() else {
        panic!("a snapshot decodes as a snapshot");
    };
    assert_eq!(decoded.gaussians.len(), map.len());
    assert!(map.len() > budget / 2);
    // A repeated increment does not fit and leaves the replica unchanged.
    let (set, pose) = random_bin(&mut rng, 51);
    let inc = map.insert_bin(51, &set, pose).unwrap();
    assert!(!inc.added.is_empty());
    replica.apply(&inc).unwrap();
    let before = replica.snapshot();
    assert!(replica.apply(&inc).is_err());
    assert_eq!(replica.snapshot(), before);
}

#[test]
fn over_budget_the_cells_farthest_from_the_latest_bin_go_first() {
    let mut map = map_with(1.0, 0.01, 5);
    let c = [0.5; 3];
    let a = map
        .insert_bin(
            1,
            &set_of(&[
                gauss([0.5, 0.5, 0.5], 0.5, c),
                gauss([10.5, 0.5, 0.5], 0.5, c),
                gauss([20.5, 0.5, 0.5], 0.5, c),
            ]),
            at(0.0),
        )
        .unwrap();
    let ids_a: Vec<_> = a.added.iter().map(|(id, _)| *id).collect();
    // Bin 2 at x = 30: six Gaussians, budget five -> the cell at x = 0.5 (29.5 m away) goes.
    let b = map
        .insert_bin(
            2,
            &set_of(&[
                gauss([0.5, 0.5, 0.5], 0.5, c),
                gauss([1.5, 0.5, 0.5], 0.5, c),
                gauss([2.5, 0.5, 0.5], 0.5, c),
            ]),
            at(30.0),
        )
        .unwrap();
    assert_eq!(b.removed, vec![ids_a[0]]);
    assert_eq!((b.added.len(), b.stats.evicted, map.len()), (3, 1, 5));
    // Bin 3 at x = -5 with two Gaussians: the two farthest (x = 32.5, 31.5) go.
    let c3 = map
        .insert_bin(
            3,
            &set_of(&[
                gauss([0.5, 0.5, 0.5], 0.5, c),
                gauss([1.5, 0.5, 0.5], 0.5, c),
            ]),
            at(-5.0),
        )
        .unwrap();
    let gone = [b.added[2].0, b.added[1].0];
    let mut want = gone.to_vec();
    want.sort();
    assert_eq!(c3.removed, want);
    let xs: Vec<f64> = map.gaussians().map(|(_, g)| g.position.x).collect();
    assert_eq!(xs, vec![10.5, 20.5, 30.5, -4.5, -3.5]);

    // A bin bigger than the budget on its own: its farthest Gaussians are never published.
    let mut fresh = map_with(1.0, 0.01, 5);
    let row: Vec<_> = (0..8)
        .map(|i| gauss([i as f32 + 0.5, 0.5, 0.5], 0.5, c))
        .collect();
    let inc = fresh.insert_bin(9, &set_of(&row), at(0.0)).unwrap();
    let xs: Vec<f64> = inc.added.iter().map(|(_, g)| g.position.x).collect();
    assert_eq!(xs, vec![0.5, 1.5, 2.5, 3.5, 4.5]);
    assert!(inc.removed.is_empty());
    assert_eq!(inc.stats.evicted, 3);
}

#[test]
fn low_opacity_and_nan_gaussians_are_skipped_and_bad_bins_refused() {
    let mut map = map_with(0.2, 0.1, 100);
    let mut gs: Vec<_> = [0.05f32, 0.1, 0.5]
        .iter()
        .enumerate()
        .map(|(i, &o)| {
            let mut g = gauss([i as f32, 0.0, 5.0], 0.5, [1.0; 3]);
            g.opacity = o;
            g
        })
        .collect();
    let mut nan = gauss([5.0, 0.0, 5.0], 0.5, [1.0; 3]);
    nan.log_scale.x = f32::NAN;
    gs.push(nan);
    let mut inf = gauss([6.0, 0.0, 5.0], 0.5, [1.0; 3]);
    inf.mean.z = f32::INFINITY;
    gs.push(inf);
    let inc = map.insert_bin(1, &set_of(&gs), at(0.0)).unwrap();
    let opacities: Vec<f32> = inc.added.iter().map(|(_, g)| g.opacity).collect();
    assert_eq!(opacities, vec![0.1, 0.5]);
    assert_eq!(
        (inc.stats.pruned_opacity, inc.stats.skipped_invalid),
        (1, 2)
    );
    assert_eq!(inc.stats.input, 5);

    let before = map.snapshot();
    let one = set_of(&[gauss([0.0, 0.0, 1.0], 0.9, [1.0; 3])]);
    let mut nan_pose = at(0.0);
    nan_pose.translation.y = f64::NAN;
    let mut inf_pose = at(0.0);
    inf_pose.matrix3.x_axis.x = f64::INFINITY;
    let scaled = DAffine3::from_scale(DVec3::splat(2.0));
    let mirrored = DAffine3::from_scale(DVec3::new(1.0, 1.0, -1.0));
    for pose in [nan_pose, inf_pose, scaled, mirrored] {
        let err = map.insert_bin(2, &one, pose).unwrap_err();
        assert!(
            matches!(err, FusionError::BadPose { bin_id: 2, .. }),
            "{err}"
        );
    }
    let mut short = one.clone();
    short.confidences.clear();
    let err = map.insert_bin(3, &short, at(0.0)).unwrap_err();
    assert!(err.to_string().contains("confidences"), "{err}");
    assert_eq!(map.snapshot(), before);

    let empty = map
        .insert_bin(4, &GaussianSet::default(), at(50.0))
        .unwrap();
    assert!(empty.is_empty());
    assert_eq!(map.snapshot().gaussians, before.gaussians);
    assert_eq!(map.latest_origin(), Some(DVec3::ZERO));
    assert!(GlobalMap::new(FusionConfig {
        cell_size: 0.0,
        ..FusionConfig::default()
    })
    .is_err());
}

#[test]
fn save_and_restore_round_trip_and_corrupt_files_are_typed_errors() {
    let mut map = map_with(0.5, 0.1, 150);
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    for k in 0..6 {
        let (set, pose) = random_bin(&mut rng, k);
        map.insert_bin(k, &set, pose).unwrap();
    }
    let path = tmp_path("round.map");
    map.save(&path).unwrap();
    let mut back = GlobalMap::load(&path).unwrap();
    assert_eq!(back.snapshot(), map.snapshot());
    assert_eq!(back.config(), map.config());
    assert_eq!(back.cell_count(), map.cell_count());
    assert_eq!(back.latest_origin(), map.latest_origin());
    assert_eq!((back.increments(), back.epoch()), (6, 0));
    // The restored map goes on exactly as the original (same ids, same decisions).
    let (set, pose) = random_bin(&mut rng, 6);
    let next = map.insert_bin(6, &set, pose).unwrap();
    assert_eq!(back.insert_bin(6, &set, pose).unwrap(), next);
    assert!(!next.is_empty());

    let good = std::fs::read(&path).unwrap();
    let bad = tmp_path("corrupt.map");
    let load_with = |bytes: &[u8]| {
        std::fs::write(&bad, bytes).unwrap();
        GlobalMap::load(&bad).unwrap_err()
    };
    let mut flipped = good.clone();
    flipped[good.len() / 2] ^= 0x10;
    let err = load_with(&flipped);
    assert!(matches!(err, StoreError::Checksum { .. }), "{err}");
    assert!(err.to_string().contains("corrupt.map"), "{err}");
    let err = load_with(&good[..good.len() - 100]);
    assert!(matches!(err, StoreError::Checksum { .. }), "{err}");
    let err = load_with(&good[..10]);
    assert!(matches!(err, StoreError::Truncated { .. }), "{err}");
    let mut magic = good.clone();
    magic[0] = b'X';
    assert!(matches!(load_with(&magic), StoreError::BadMagic { .. }));
    let mut version = good.clone();
    version[8] = 9;
    assert!(matches!(
        load_with(&version),
        StoreError::UnsupportedVersion { version: 9, .. }
    ));
    assert!(matches!(load_with(&[]), StoreError::Truncated { .. }));
    let missing = GlobalMap::load(tmp_path("missing.map")).unwrap_err();
    assert!(matches!(missing, StoreError::Io { .. }), "{missing}");
}

#[test]
fn a_map_of_several_write_chunks_saves_and_loads_whole() {
    // 15,000 Gaussians, one per cell: the file is written a chunk of 4,096 records at a time
    // with its checksum carried across chunks.
    let mut map = map_with(0.05, 0.0, 100_000);
    let gs: Vec<Gaussian> = (0..15_000)
        .map(|i| {
            let (x, y) = ((i % 150) as f32 * 0.1, (i / 150) as f32 * 0.1 - 5.0);
            gauss([x, y, 8.0], 0.5, [x / 15.0, 0.5, 0.25])
        })
        .collect();
    map.insert_bin(0, &set_of(&gs), at(3.0)).unwrap();
    assert_eq!(map.len(), 15_000);
    let path = tmp_path("chunks.map");
    map.save(&path).unwrap();
    let file = std::fs::read(&path).unwrap();
    assert_eq!(file.len() as u64, map.stored_bytes());
    assert_eq!(file, map.to_bytes());
    let back = GlobalMap::load(&path).unwrap();
    assert_eq!(back.snapshot(), map.snapshot());
    assert_eq!(back.to_bytes(), file);
}

#[test]
fn bird_s_eye_view_puts_colours_at_the_expected_pixels() {
    let mut map = map_with(0.1, 0.01, 100);
    let mut yellow = gauss([-1.05, 1.05, 0.0], 0.5, [1.0, 1.0, 0.0]);
    yellow.log_scale = Vec3::splat(0.31f32.ln());
    let set = set_of(&[
        gauss([1.05, 1.05, 0.0], 0.5, [1.0, 0.0, 0.0]),
        gauss([1.05, 1.05, 2.0], 0.5, [0.0, 0.0, 1.0]),
        gauss([-0.95, -0.95, 0.0], 0.5, [0.0, 1.0, 0.0]),
        yellow,
    ]);
    map.insert_bin(1, &set, DAffine3::IDENTITY).unwrap();
    let view = BevView {
        centre: DVec2::ZERO,
        width: 40,
        height: 40,
        metres_per_pixel: 0.1,
        background: [0, 0, 0],
    };
    let img = bev_image(map.gaussians().map(|(_, g)| g), &view).unwrap();
    let path = tmp_path("bev.png");
    save_bev_png(&img, &path).unwrap();
    let img = image::open(&path).unwrap().to_rgb8();
    let px = |c, r| img.get_pixel(c, r).0;
    // (x, y) = (1.05, 1.05) -> column 30, row 9: blue (z = 2) hides red (z = 0).
    assert_eq!(px(30, 9), [0, 0, 255]);
    assert_eq!(px(10, 29), [0, 255, 0]);
    // Yellow's 0.31 m sigma covers pixel centres up to 3 pixels away.
    assert_eq!(px(9, 9), [255, 255, 0]);
    assert_eq!(px(12, 9), [255, 255, 0]);
    assert_eq!(px(9, 6), [255, 255, 0]);
    assert_eq!(px(13, 9), [0, 0, 0]);
    assert_eq!(px(20, 20), [0, 0, 0]);
    let lit = img.pixels().filter(|p| p.0 != [0, 0, 0]).count();
    assert_eq!(lit, 2 + 29); // two points and a disc of radius 3 pixels (29 centres)
    let bad = BevView {
        metres_per_pixel: 0.0,
        ..view
    };
    assert!(bev_image(map.gaussians().map(|(_, g)| g), &bad).is_err());
    assert_eq!(
        map.get(GaussianId(1)).map(|g| g.color),
        Some(Vec3::Z),
        "ids follow input order"
    );
}

#[test]
fn a_ground_box_query_finds_exactly_the_gaussians_in_it_and_the_bird_s_eye_view_needs_no_more() {
    // 120 random bins on a loop of 60 m radius around the origin (negative coordinates too).
    let mut map = map_with(0.2, 0.1, 1_000_000);
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    for k in 0..120u64 {
        let (set, _) = random_bin(&mut rng, k);
        let a = k as f64 / 120.0 * std::f64::consts::TAU;
        let pose = DAffine3::from_rotation_translation(
            DQuat::from_rotation_z(a),
            DVec3::new(60.0 * a.cos(), 60.0 * a.sin(), 0.0),
        );
        map.insert_bin(k, &set, pose).unwrap();
    }
    assert!(map.len() > 3000, "{}", map.len());
    let brute = |min: DVec2, max: DVec2| -> Vec<GaussianId> {
        map.gaussians()
            .filter(|(_, g)| {
                let p = g.position.truncate();
                p.cmpge(min).all() && p.cmple(max).all()
            })
            .map(|(id, _)| id)
            .collect()
    };
    let ids = |found: Vec<(GaussianId, &node::fusion::WorldGaussian)>| -> Vec<GaussianId> {
        found.into_iter().map(|(id, _)| id).collect()
    };
    for _ in 0..40 {
        let c = DVec2::new(rng.random_range(-80.0..80.0), rng.random_range(-80.0..80.0));
        let half = DVec2::new(rng.random_range(0.1..40.0), rng.random_range(0.1..40.0));
        let (min, max) = (c - half, c + half);
        let found = ids(map.gaussians_in(min, max));
        assert_eq!(found, brute(min, max), "box {min} - {max}");
    }
    // Everything, nothing far away, an inverted box, a NaN box.
    let all = ids(map.gaussians_in(DVec2::splat(-1e300), DVec2::splat(1e300)));
    assert_eq!(all.len(), map.len());
    assert!(map
        .gaussians_in(DVec2::splat(1e12), DVec2::splat(1e12 + 50.0))
        .is_empty());
    assert!(map
        .gaussians_in(DVec2::splat(10.0), DVec2::splat(-10.0))
        .is_empty());
    assert!(map.gaussians_in(DVec2::NAN, DVec2::splat(1.0)).is_empty());
    // The published bird's-eye view drawn from its ground box equals the one drawn from the
    // whole map.
    for centre in [DVec2::new(60.0, 0.0), DVec2::new(-42.0, -42.0), DVec2::ZERO] {
        let view = BevView::square(centre, 256, 0.25);
        let (min, max) = view.ground_box();
        let near = map.gaussians_in(min, max);
        assert!(
            near.len() < map.len() / 2,
            "{} of {}",
            near.len(),
            map.len()
        );
        let whole = bev_image(map.gaussians().map(|(_, g)| g), &view).unwrap();
        let local = bev_image(near.into_iter().map(|(_, g)| g), &view).unwrap();
        assert_eq!(whole, local, "view at {centre}");
    }
}

#[test]
fn over_budget_along_a_long_road_the_farthest_columns_go_and_the_near_road_stays() {
    // 300 bins 4 m apart along x (1.2 km), budget 2,000: what is left is the road behind the
    // latest bin, nearest first, and never a Gaussian farther than one evicted.
    let budget = 2_000;
    let mut map = map_with(0.2, 0.1, budget);
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let mut evicted = 0;
    for k in 0..300u64 {
        let (set, pose) = random_bin(&mut rng, k);
        evicted += map.insert_bin(k, &set, pose).unwrap().stats.evicted;
        assert!(map.len() <= budget);
    }
    assert!(evicted > 5_000, "{evicted}");
    let anchor = map.latest_origin().unwrap();
    let far = map
        .gaussians()
        .map(|(_, g)| (g.position - anchor).truncate().length())
        .fold(0.0, f64::max);
    // Kept: at most about two columns' diagonal (2 x 16 m x sqrt 2) beyond the road the
    // budget holds (2,000 Gaussians of about 40 per 4 m bin: about 200 m).
    eprintln!("{evicted} evicted; kept {} within {far:.0} m", map.len());
    assert!(
        far < 260.0,
        "a Gaussian {far} m from the latest bin is kept"
    );
    assert!(map.len() > budget * 9 / 10, "{}", map.len());
}
