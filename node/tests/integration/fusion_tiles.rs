//! The map's tiles on disk: a tile paged out and back in is bit for bit the tile it was; a
//! loop driven twice with far tiles paged out fuses its second pass into the first pass's
//! tiles (read back from disk) instead of layering a copy; the map in memory stays bounded
//! while the whole map grows; base, journal and tile files restore the live map bit for bit
//! after every bin and after compaction; the export holds every tile, as one file or one
//! file per tile with an index; damaged or missing tile files are typed errors.

use std::collections::BTreeMap;
use std::path::PathBuf;

use glam::{DAffine3, DQuat, DVec2, DVec3, Quat, Vec3};
use node::fusion::{
    read_tile, tile_path, write_tile, AtTornTail, FusionConfig, GlobalMap, Keep, PagedTile,
    StoreError, TileKey,
};
use node::store::map_files::{
    export_with_limit, gaussians_in_whole, restore, whole_map, RegionReadError, CHECKPOINT, TILES,
};
use node::store::map_store::{MapStore, Recorded};
use node::store::Compaction;
use node::store::Paging;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use renderer::formats::{load_map, MapFormat};
use renderer::{Gaussian, GaussianSet};

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("stereosplat_tiles_{name}_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// 0.5 m cells, 16 m tiles (one ground column), a keep range of 12 m.
fn config(max_gaussians: usize) -> FusionConfig {
    FusionConfig {
        cell_size: 0.5,
        opacity_floor: 0.0,
        max_gaussians,
        keep: Keep {
            max_range_m: 12.0,
            min_confidence: 0.0,
        },
        tile_m: 16.0,
    }
}

/// The camera `s` metres along a loop of radius 60 m (starting at the origin heading +x).
fn on_loop(s: f64) -> DAffine3 {
    let a = s / 60.0;
    let p = DVec3::new(60.0 * a.sin(), 60.0 * (1.0 - a.cos()), 0.0);
    DAffine3::from_rotation_translation(DQuat::from_rotation_z(a), p)
}

/// A bin of random Gaussians on the road ahead of the camera (seeded), for tests that need
/// no revisit.
fn road_bin(rng: &mut ChaCha8Rng) -> GaussianSet {
    let mut set = GaussianSet::default();
    for _ in 0..300 {
        set.push(Gaussian {
            mean: Vec3::new(
                rng.random_range(0.0..8.0),
                rng.random_range(-6.0..6.0),
                rng.random_range(-1.5..0.5),
            ),
            log_scale: Vec3::splat(-2.0),
            rotation: Quat::from_rotation_z(rng.random_range(-3.0..3.0)),
            opacity: rng.random_range(0.2..1.0),
            color: Vec3::new(rng.random(), rng.random(), rng.random()),
            confidence: rng.random_range(0.0..1.0),
        });
    }
    set
}

/// A bin that sees the world's road: a Gaussian at the centre of every 0.5 m cell of the
/// ground 1.25 m below the camera, 0-8 m ahead and up to 6 m to each side, in the bin's
/// frame, with random confidences (seeded). A pass over the same road sees the same cells.
fn world_road_bin(rng: &mut ChaCha8Rng, pose: DAffine3) -> GaussianSet {
    let to_bin = pose.inverse();
    let mut set = GaussianSet::default();
    let c = pose.translation;
    let (x0, y0) = (
        (c.x / 0.5).floor() as i64 - 20,
        (c.y / 0.5).floor() as i64 - 20,
    );
    for i in x0..x0 + 41 {
        for j in y0..y0 + 41 {
            let world = DVec3::new((i as f64 + 0.5) * 0.5, (j as f64 + 0.5) * 0.5, c.z - 1.25);
            let local = to_bin.transform_point3(world);
            if !(0.0..8.0).contains(&local.x) || local.y.abs() >= 6.0 {
                continue;
            }
            set.push(Gaussian {
                mean: local.as_vec3(),
                log_scale: Vec3::splat(-2.0),
                rotation: Quat::IDENTITY,
                opacity: rng.random_range(0.2..1.0),
                color: Vec3::new(rng.random(), rng.random(), rng.random()),
                confidence: rng.random_range(0.0..1.0),
            });
        }
    }
    set
}

/// Gaussians per tile of the whole map (in memory and on disk).
fn per_tile(map: &GlobalMap, dir: &std::path::Path) -> BTreeMap<TileKey, u64> {
    let config = map.config();
    let mut out = BTreeMap::new();
    for g in whole_map(map, &dir.join(CHECKPOINT)).unwrap() {
        *out.entry(config.tile_of(g.position)).or_insert(0) += 1;
    }
    out
}

#[test]
fn a_tile_paged_out_and_back_in_is_bit_identical() {
    let dir = scratch("identity");
    let mut map = GlobalMap::new(config(1_000_000)).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    for k in 0..20u64 {
        let pose = on_loop(8.0 * k as f64);
        map.insert_bin(k, &road_bin(&mut rng), pose).unwrap();
    }
    let before = map.to_bytes();
    let tiles = map.resident_tiles();
    assert!(tiles.len() >= 6, "{tiles:?}");
    let config = *map.config();
    for (&tile, &count) in &tiles {
        let version = map.increments();
        let taken = map.take_tile(tile, version).unwrap();
        assert_eq!(taken.len() as u64, count);
        assert!(taken
            .iter()
            .all(|(_, g)| config.tile_of(g.position) == tile));
        let paged = map.paged_tiles()[&tile];
        assert_eq!(paged, PagedTile { version, count });
        assert!(map.take_tile(tile, version).is_err(), "taken twice");
        write_tile(&dir, tile, version, &taken).unwrap();
        let back = read_tile(&dir, tile, paged, &config).unwrap();
        assert_eq!(back, taken);
        map.put_tile(tile, back).unwrap();
    }
    assert!(map.paged_tiles().is_empty());
    assert_eq!(
        map.to_bytes(),
        before,
        "every tile out and in: the same map, bit for bit"
    );
    // A tile that is not paged out cannot be put in; nor can ids the map holds.
    let first = *tiles.keys().next().unwrap();
    assert!(map.put_tile(first, Vec::new()).is_err());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_loop_driven_twice_fuses_into_its_paged_tiles_and_memory_stays_bounded() {
    let dir = scratch("loop");
    let mut map = GlobalMap::new(config(1_000_000)).unwrap();
    map.save(dir.join(CHECKPOINT)).unwrap();
    let paging = Some(Paging { radius_m: 30.0 });
    let compaction = Compaction { min_bytes: 1 << 40 };
    let mut store = MapStore::new(dir.clone(), &map, 1, compaction, paging).unwrap();
    let lap = std::f64::consts::TAU * 60.0;
    let bins_per_lap = (lap / 4.0) as u64;
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let (mut most_resident, mut after_first) = (0, BTreeMap::new());
    for k in 0..2 * bins_per_lap {
        let pose = on_loop(4.0 * k as f64);
        store.prepare(&mut map, pose.translation).unwrap();
        let inc = map
            .insert_bin(k, &world_road_bin(&mut rng, pose), pose)
            .unwrap();
        assert_eq!(inc.stats.evicted, 0);
        assert_eq!(store.record(&mut map, &inc).unwrap(), Recorded::Durable);
        most_resident = most_resident.max(map.len());
        // A crash after any bin restores the live map, tiles on disk included.
        if k % 7 == 0 {
            let restored = restore(&dir, AtTornTail::Cut).unwrap().unwrap().map;
            assert_eq!(restored.to_bytes(), map.to_bytes(), "bin {k}");
        }
        if k + 1 == bins_per_lap {
            after_first = per_tile(&map, &dir);
        }
    }
    let counts: BTreeMap<_, _> = store.counts().into_iter().collect();
    store.finish().unwrap();
    let after_second = per_tile(&map, &dir);
    let (first_total, second_total): (u64, u64) =
        (after_first.values().sum(), after_second.values().sum());
    eprintln!(
        "{counts:?}; resident at most {most_resident} of {}; {first_total} Gaussians after one lap, {second_total} after two",
        map.total_len()
    );
    assert!(counts["map/tiles_paged_out"] >= 20, "{counts:?}");
    assert!(counts["map/tiles_paged_in"] >= 10, "{counts:?}");
    assert!(map.paged_tiles().len() >= 10);
    assert_eq!(map.total_len(), second_total);
    // In memory: the tiles within about 30 m plus a tile of the vehicle, a fraction of the map.
    assert!(
        (most_resident as u64) * 3 < map.total_len(),
        "{most_resident} of {}",
        map.total_len()
    );
    // The second lap replaced cells of the first instead of adding a layer over them: every
    // tile of the first lap (with 200 Gaussians or more) holds at most 1.1 times what it held after it (a layer on top,
    // as a tile left on disk would get, doubles it), and the map grew by at most 10% (the
    // second lap ends a little past the first's start).
    assert!(
        second_total * 10 <= first_total * 11,
        "{second_total} vs {first_total}"
    );
    for (tile, &n) in after_first.iter().filter(|(_, &n)| n >= 200) {
        let now = after_second[tile];
        assert!(now * 10 <= n * 11, "tile {tile:?}: {now} vs {n}");
    }
    // Stopping saves the base; the tiles folder keeps exactly the files the base names.
    node::store::map_files::checkpoint(&map, &dir).unwrap();
    let mut files: Vec<_> = std::fs::read_dir(dir.join(TILES))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    files.sort();
    let mut named: Vec<_> = map
        .paged_tiles()
        .iter()
        .map(|(t, p)| tile_path(&dir.join(TILES), *t, p.version))
        .collect();
    named.sort();
    assert_eq!(files, named);
    let restored = restore(&dir, AtTornTail::Cut).unwrap().unwrap().map;
    assert_eq!(restored.to_bytes(), map.to_bytes());
    assert_eq!(per_tile(&restored, &dir), after_second);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn compaction_with_paged_tiles_restores_the_live_map_and_bad_tile_files_are_typed_errors() {
    let dir = scratch("compact");
    let mut map = GlobalMap::new(config(1_000_000)).unwrap();
    let paging = Some(Paging { radius_m: 20.0 });
    let mut store =
        MapStore::new(dir.clone(), &map, 1, Compaction { min_bytes: 0 }, paging).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    // Out along a straight road and back: tiles go out, then come back in.
    for k in 0..80u64 {
        let x = if k < 40 {
            4.0 * k as f64
        } else {
            4.0 * (80 - k) as f64
        };
        let heading = if k < 40 { 0.0 } else { std::f64::consts::PI };
        let pose = DAffine3::from_rotation_translation(
            DQuat::from_rotation_z(heading),
            DVec3::new(x, 0.0, 0.0),
        );
        store.prepare(&mut map, pose.translation).unwrap();
        let inc = map.insert_bin(k, &road_bin(&mut rng), pose).unwrap();
        store.record(&mut map, &inc).unwrap();
    }
    store.finish().unwrap();
    let counts: BTreeMap<_, _> = store.counts().into_iter().collect();
    drop(store);
    assert!(counts["map/compactions"] >= 2, "{counts:?}");
    assert_eq!(counts["error/compaction"], 0);
    assert!(counts["map/tiles_paged_in"] > 0 && counts["map/tiles_paged_out"] > 0);
    let restored = restore(&dir, AtTornTail::Stop).unwrap().unwrap().map;
    assert_eq!(restored.to_bytes(), map.to_bytes());
    assert!(!map.paged_tiles().is_empty());

    // The export holds every tile: as one file, and one file per tile with an index.
    export_with_limit(&map, &dir, MapFormat::Ply, u64::MAX).unwrap();
    let (_, one) = load_map(dir.join("global_map.ply")).unwrap();
    assert_eq!(one.len() as u64, map.total_len());
    export_with_limit(&map, &dir, MapFormat::Ply, 100).unwrap();
    let tiles = dir.join("global_map_tiles");
    let index: serde_json::Value =
        serde_json::from_slice(&std::fs::read(tiles.join("index.json")).unwrap()).unwrap();
    let origin = DVec3::from_array(serde_json::from_value(index["origin"].clone()).unwrap());
    let config = map.config();
    let mut total = 0;
    for t in index["tiles"].as_array().unwrap() {
        let (_, set) = load_map(tiles.join(t["file"].as_str().unwrap())).unwrap();
        assert_eq!(set.len() as u64, t["count"].as_u64().unwrap());
        let key = (
            t["tile"][0].as_i64().unwrap(),
            t["tile"][1].as_i64().unwrap(),
        );
        for m in &set.means {
            assert_eq!(config.tile_of(origin + m.as_dvec3()), key, "{m}");
        }
        total += set.len() as u64;
    }
    assert_eq!(total, map.total_len());
    assert_eq!(index["gaussians"].as_u64(), Some(map.total_len()));

    // A region over the whole road reads the tiles on disk it meets; one that may hold more
    // than an answer holds is refused before anything is read.
    let (min, max) = (DVec2::splat(-1e4), DVec2::splat(1e4));
    let region = gaussians_in_whole(&map, &dir.join(TILES), min, max, u64::MAX).unwrap();
    assert_eq!(region.len() as u64, map.total_len());
    assert!(region.windows(2).all(|w| w[0].0 < w[1].0), "in id order");
    let near = DVec2::new(8.0, 0.0);
    let part =
        gaussians_in_whole(&map, &dir.join(TILES), near - 4.0, near + 4.0, u64::MAX).unwrap();
    assert!(!part.is_empty() && part.len() < region.len());
    assert!(part
        .iter()
        .all(|(_, g)| (g.position.truncate() - near).abs().max_element() <= 4.0));
    let e = gaussians_in_whole(&map, &dir.join(TILES), min, max, 100).unwrap_err();
    assert!(
        matches!(e, RegionReadError::TooLarge { at_most: 100, .. }),
        "{e}"
    );

    // A flipped byte in a tile file the map names: its checksum says so, naming the file.
    let (&tile, &paged) = map.paged_tiles().iter().next().unwrap();
    let file = tile_path(&dir.join(TILES), tile, paged.version);
    let mut bytes = std::fs::read(&file).unwrap();
    let at = bytes.len() / 2;
    bytes[at] ^= 0x10;
    std::fs::write(&file, &bytes).unwrap();
    let e = whole_map(&map, &dir.join(CHECKPOINT)).unwrap_err();
    assert!(
        matches!(&e, StoreError::Checksum { path } if *path == file),
        "{e}"
    );
    // The file of another tile under its name: refused.
    bytes[at] ^= 0x10;
    let other = PagedTile {
        version: paged.version,
        count: paged.count + 1,
    };
    assert!(read_tile(&dir.join(TILES), tile, other, map.config()).is_err());
    // A missing tile file: an I/O error naming it.
    std::fs::remove_file(&file).unwrap();
    let e = whole_map(&map, &dir.join(CHECKPOINT)).unwrap_err();
    assert!(
        matches!(&e, StoreError::Io { path, .. } if *path == file),
        "{e}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
