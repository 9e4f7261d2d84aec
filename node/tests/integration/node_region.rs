//! Snapshot queries for a region of the map: a running node (SGM, a small generated drive,
//! loopback) answers `box=` and `around=;radius=` queries with exactly the Gaussians whose
//! centres lie in the region, in pages of at most `page_size`, each page saying which it is;
//! a region with nothing in it gets one empty page; bad parameters get an error reply naming
//! them, counted as `refused/snapshot_region`, and do not use up the rate limit. On a drive
//! whose first tiles were paged to disk, a region over the whole drive is answered with
//! those tiles too (the whole snapshot holds only the tiles in memory, and names the others
//! in its attachment, through which a live view started late lists them and fetches one).

use crate::drive_support;

use std::collections::BTreeSet;
use std::time::Duration;

use drive_support::{Collector, Drive, Player, RunningNode};
use glam::{DAffine3, DVec2};
use model::synth::SynthConfig;
use node::fusion::{decode_update, GaussianId, Snapshot, Update};
use node::fusion::{AtTornTail, FusionConfig, Keep};
use node::msg::map_update::MapUpdate;
use node::msg::Message;
use node::pipeline::worker::RenderWith;
use node::service::{InputLimits, NodeConfig};
use node::store::map_files::{restore, TILES};
use node::store::Paging;
use node::transport::Keys;
use zenoh::query::ConsolidationMode;

/// One reply: the page's snapshot and its attachment, or the error text.
type Reply = Result<(Snapshot, serde_json::Value), String>;

/// The input limits with no wait between snapshot queries: these tests query the map
/// several times in a row and are not about the rate limit.
fn any_rate() -> InputLimits {
    InputLimits {
        snapshot_interval: Duration::ZERO,
        ..InputLimits::default()
    }
}

async fn query(player: &Player, selector: &str) -> Vec<Reply> {
    // Pages share the key: without consolidation off, zenoh would keep only the last.
    let replies = player
        .session
        .get(selector)
        .consolidation(ConsolidationMode::None)
        .await
        .unwrap();
    let mut out = Vec::new();
    while let Ok(reply) = replies.recv_async().await {
        out.push(match reply.result() {
            Ok(sample) => {
                let msg = MapUpdate::decode(&sample.payload().to_bytes()).unwrap();
                let Update::Snapshot(snap) = decode_update(&msg).unwrap() else {
                    panic!("a region is answered with snapshots")
                };
                let attachment = sample
                    .attachment()
                    .map(|a| serde_json::from_slice(&a.to_bytes()).unwrap())
                    .unwrap_or(serde_json::Value::Null);
                Ok((snap, attachment))
            }
            Err(e) => Err(String::from_utf8_lossy(&e.payload().to_bytes()).into_owned()),
        });
    }
    out
}

/// The ids of a region's pages, checking page sizes and numbering.
fn pages_ids(replies: &[Reply], page_size: usize) -> Vec<GaussianId> {
    let mut ids = Vec::new();
    for (i, reply) in replies.iter().enumerate() {
        let (snap, att) = reply.as_ref().expect("a page, not an error");
        assert!(snap.gaussians.len() <= page_size);
        assert_eq!(att["page"], i);
        assert_eq!(att["pages"], replies.len());
        ids.extend(snap.gaussians.iter().map(|(id, _)| *id));
    }
    let total = replies[0].as_ref().unwrap().1["gaussians"]
        .as_u64()
        .unwrap();
    assert_eq!(ids.len() as u64, total);
    ids
}

/// Plays `drive` into `node` and waits until every bin's pose was published; the player.
async fn drive_through(node: &RunningNode, keys: &Keys, drive: &Drive) -> Player {
    let poses = Collector::connect(node, &[keys.bin_pose()]).await;
    let player = Player::connect(node).await;
    player.drive(drive, DAffine3::IDENTITY, 0).await;
    assert!(
        poses
            .wait_count(&keys.bin_pose(), drive.bins_opened(8.0))
            .await
    );
    player
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn region_queries_answer_exactly_the_region_in_pages_and_bad_ones_are_refused() {
    let drive = Drive::small("region");
    let keys = Keys::new("region");
    let node = RunningNode::start(NodeConfig {
        keys: keys.clone(),
        method: "sgm".into(),
        queue_capacity: 64,
        renders: RenderWith::Off,
        limits: any_rate(),
        ..NodeConfig::default()
    })
    .await;
    let player = drive_through(&node, &keys, &drive).await;

    let key = keys.snapshot_request();
    let whole = query(&player, &key).await;
    assert_eq!(whole.len(), 1);
    let map = &whole[0].as_ref().unwrap().0.gaussians;
    assert!(map.len() > 1000, "{} Gaussians", map.len());
    let inside = |min: DVec2, max: DVec2| -> Vec<GaussianId> {
        map.iter()
            .filter(|(_, g)| {
                let p = g.position.truncate();
                p.cmpge(min).all() && p.cmple(max).all()
            })
            .map(|(id, _)| *id)
            .collect()
    };
    // Around the middle of the map.
    let mid = map[map.len() / 2].1.position.truncate();
    let (min, max) = (mid - DVec2::new(6.0, 4.0), mid + DVec2::new(5.0, 3.0));

    // Bad parameters first: answered at once, whatever the rate limit.
    for (params, says) in [
        ("box=1,2,3", "needs 4 numbers"),
        ("box=0,0,nan,1", "finite"),
        ("around=1,2;radius=-1", "above 0"),
        ("tiles=0", "unknown snapshot parameter"),
    ] {
        let replies = query(&player, &format!("{key}?{params}")).await;
        match replies.as_slice() {
            [Err(text)] => assert!(text.contains(says), "{params}: {text}"),
            other => panic!("{params}: {} replies, not one error", other.len()),
        }
    }

    let selector = format!("{key}?box={},{},{},{}", min.x, min.y, max.x, max.y);
    let replies = query(&player, &selector).await;
    let want = inside(min, max);
    assert!(
        want.len() > 20 && want.len() < map.len() / 2,
        "{}",
        want.len()
    );
    assert_eq!(pages_ids(&replies, usize::MAX), want);
    assert_eq!(replies.len(), 1);

    let page = 37;
    let selector = format!("{key}?around={},{};radius=5;page_size={page}", mid.x, mid.y);
    let replies = query(&player, &selector).await;
    let want = inside(mid - 5.0, mid + 5.0);
    assert!(replies.len() >= 2, "{} pages", replies.len());
    let got = pages_ids(&replies, page);
    assert_eq!(got, want, "in id order across pages");
    assert_eq!(got.iter().collect::<BTreeSet<_>>().len(), got.len());

    let replies = query(&player, &format!("{key}?box=1e6,1e6,1.0001e6,1.0001e6")).await;
    assert_eq!(replies.len(), 1);
    assert!(replies[0].as_ref().unwrap().0.gaussians.is_empty());

    let summary = node.stop().await;
    assert_eq!(summary.counters.get("refused/snapshot_region"), 4);
}

/// A node whose first tiles go to disk as `name`'s drive goes on: 150 frames (about 120 m)
/// with 16 m tiles, a 5 m keep range and tiles kept in memory only within 1 m (plus one
/// tile) of the vehicle. The drive, the node's keys, the node and its output folder.
async fn paged_node(name: &str) -> (Drive, Keys, RunningNode, std::path::PathBuf) {
    let drive = Drive::generate(
        name,
        &SynthConfig {
            seed: 29,
            frames: 150,
            width: 272,
            height: 72,
            supersample: 1,
            lidar_azimuth_steps: 64,
            ..SynthConfig::default()
        },
    );
    let out = drive.dir("out");
    let keys = Keys::new(name);
    let node = RunningNode::start(NodeConfig {
        keys: keys.clone(),
        method: "sgm".into(),
        queue_capacity: 64,
        renders: RenderWith::Off,
        out_dir: Some(out.clone()),
        fusion: FusionConfig {
            keep: Keep {
                max_range_m: 5.0,
                min_confidence: 0.0,
            },
            tile_m: 16.0,
            ..FusionConfig::default()
        },
        paging: Some(Paging { radius_m: 1.0 }),
        limits: any_rate(),
        ..NodeConfig::default()
    })
    .await;
    (drive, keys, node, out)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_region_over_tiles_paged_to_disk_is_answered_from_their_files() {
    let (drive, keys, node, out) = paged_node("region_paged").await;
    let player = drive_through(&node, &keys, &drive).await;
    let key = keys.snapshot_request();
    let in_memory = query(&player, &key).await;
    let in_memory = in_memory[0].as_ref().unwrap().0.gaussians.len();
    let replies = query(&player, &format!("{key}?box=-1e4,-1e4,1e4,1e4")).await;
    let got = pages_ids(&replies, usize::MAX);
    let summary = node.stop().await;
    let paged_out = summary.counters.get("map/tiles_paged_out");
    assert!(paged_out >= 2, "{paged_out} tiles paged out");

    // The region holds the whole map: what the node saved when it stopped, tiles included.
    let map = restore(&out, AtTornTail::Fail).unwrap().unwrap().map;
    let mut want: Vec<GaussianId> = map.gaussians().map(|(id, _)| id).collect();
    for tile in map.paged_tiles().keys() {
        let read = map.read_paged_tile(&out.join(TILES), *tile).unwrap();
        want.extend(read.into_iter().map(|(id, _)| id));
    }
    want.sort_unstable();
    eprintln!(
        "{} Gaussians in the region, {in_memory} in memory, {paged_out} tiles paged out",
        got.len()
    );
    assert_eq!(got, want);
    assert!(in_memory < got.len(), "{in_memory} vs {}", got.len());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_late_view_lists_the_tiles_on_disk_and_serves_them_from_the_node() {
    use drive_support::net_support::{http_get, http_json};
    use node::view::{default_node_modules, Bound, ViewConfig};

    let (drive, keys, node, out) = paged_node("view_paged").await;
    let player = drive_through(&node, &keys, &drive).await;
    // A view started after the drive: its whole-snapshot query names the tiles on disk.
    let view = Bound::bind(&ViewConfig {
        bind: ([127, 0, 0, 1], 0).into(),
        node_modules: default_node_modules(),
    })
    .await
    .expect("the view's libraries are installed (bash .ci/setup)")
    .serve(&player.session, keys.clone());
    let port = view.addr().port();
    let listing = || http_json(port, "/api/tiles?x=0&y=0&radius=1e4&budget=5e7");
    let mut tiles = Vec::new();
    for _ in 0..100 {
        tokio::time::sleep(Duration::from_millis(200)).await;
        let Some(l) = listing() else { continue };
        tiles = l["tiles"].as_array().cloned().unwrap_or_default();
        if tiles.iter().any(|t| t["held"] == false) {
            assert_eq!(l["tile_m"], 16.0, "the node's tile side");
            break;
        }
    }
    let on_disk: Vec<(i64, i64)> = tiles
        .iter()
        .filter(|t| t["held"] == false)
        .map(|t| (t["x"].as_i64().unwrap(), t["y"].as_i64().unwrap()))
        .collect();
    assert!(on_disk.len() >= 2, "tiles listed: {tiles:?}");

    // A tile on disk is fetched from the node when the page asks (503 until it came).
    let (x, y) = on_disk[0];
    let mut served = None;
    for _ in 0..100 {
        match http_get(port, &format!("/map/tile.ply?x={x}&y={y}")) {
            Some((200, body)) => {
                served = Some(body);
                break;
            }
            Some((503, _)) => tokio::time::sleep(Duration::from_millis(200)).await,
            other => panic!("tile ({x}, {y}): {other:?}"),
        }
    }
    let served = served.expect("the tile came from the node within 20 s");
    let set = renderer::ply::read_ply(served.as_slice()).unwrap();
    view.stop().await;
    node.stop().await;

    // It holds exactly what the node's tile file holds.
    let map = restore(&out, AtTornTail::Fail).unwrap().unwrap().map;
    let file = map.read_paged_tile(&out.join(TILES), (x, y)).unwrap();
    eprintln!(
        "tile ({x}, {y}): {} Gaussians served, {} in its file",
        set.len(),
        file.len()
    );
    assert!(!file.is_empty());
    assert_eq!(set.len(), file.len());
}
