//! No input wedges the node, on an in-process node (SGM) over loopback zenoh:
//!
//! - the same drive replayed twice: every bin of both replays comes out (the synchroniser
//!   confirms the jump back in time and resets, `sync/reset` = 1);
//! - one frame stamped far in the future, 16 tiny left images stamped in the future and one
//!   frame stamped far in the past, mid-drive: every bin of the drive still comes out, the
//!   two stray frames are counted (`sync/outlier` = 2);
//! - three drives replayed at once, with the same stamps and with stamps 30 ms apart: every
//!   published bin is made of one drive's left image, right image and pose (its map equals
//!   SGM run here on that drive's frame, found by the bin's pose);
//! - diagnostics arrive on their timer while no bin finishes, with the counters that say why.

use crate::drive_support;

use std::time::Duration;

use drive_support::{wait_for, Collector, Drive, Player, RunningNode};
use glam::{DAffine3, DVec3};
use model::bins::{make_bins, BinConfig, BinLayout};
use model::frame::{RgbImage, Side, StereoFrame};
use model::reconstruct::StereoView;
use model::synth::SynthConfig;
use node::msg::gaussians::gaussians_from_cloud;
use node::msg::geometry_msgs::PoseStamped;
use node::msg::image::{image_from_rgb, rgb_from_image};
use node::msg::latency::Diagnostics;
use node::msg::pose::{affine_from_pose, pose_from_affine};
use node::msg::sensor_msgs::PointCloud2;
use node::msg::std_msgs::Header;
use node::msg::Message;
use node::pipeline::worker::RenderWith;
use node::service::{NodeConfig, NodeSummary};
use node::transport::Keys;
use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

const S: i64 = 1_000_000_000;

fn drive(tag: &str, seed: u64, frames: u32) -> Drive {
    Drive::generate(
        tag,
        &SynthConfig {
            seed,
            frames,
            width: 136,
            height: 40,
            lidar_azimuth_steps: 64,
            ..SynthConfig::default()
        },
    )
}

fn config(keys: &Keys) -> NodeConfig {
    NodeConfig {
        keys: keys.clone(),
        method: "sgm".into(),
        queue_capacity: 256,
        renders: RenderWith::Off,
        ..NodeConfig::default()
    }
}

/// The left camera poses of the first frames of the bins the node opens on `drive` (8 m).
fn bin_firsts(drive: &Drive) -> Vec<DAffine3> {
    let poses = drive.poses();
    let bins = make_bins(
        &poses,
        &BinConfig {
            length_m: 8.0,
            layout: BinLayout::Consecutive,
        },
    );
    let mut firsts: Vec<DAffine3> = bins.iter().map(|b| poses[b.first]).collect();
    firsts.push(poses[bins.last().map_or(0, |b| b.last)]);
    firsts
}

/// The bin poses published, in order.
fn bin_poses(c: &Collector, keys: &Keys) -> Vec<DAffine3> {
    c.decoded::<PoseStamped>(&keys.bin_pose())
        .iter()
        .map(|p| affine_from_pose(p).unwrap())
        .collect()
}

fn same_pose(a: &DAffine3, b: &DAffine3) -> bool {
    a.translation.distance(b.translation) < 1e-6 && a.matrix3.abs_diff_eq(b.matrix3, 1e-9)
}

fn assert_poses(got: &[DAffine3], want: &[DAffine3]) {
    assert_eq!(got.len(), want.len(), "bins published");
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        assert!(same_pose(g, w), "bin {i}: {g:?} != {w:?}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_same_drive_replayed_twice_comes_out_twice() {
    let drive = drive("wedge-twice", 11, 40);
    let keys = Keys::new("wedge_twice");
    let node = RunningNode::start(config(&keys)).await;
    let out = Collector::connect(&node, &[keys.bin_pose(), keys.latency()]).await;
    let player = Player::connect(&node).await;
    let firsts = bin_firsts(&drive);
    player.drive(&drive, DAffine3::IDENTITY, 0).await;
    player.drive(&drive, DAffine3::IDENTITY, 0).await;
    let want: Vec<DAffine3> = firsts.iter().chain(&firsts).copied().collect();
    assert!(out.wait_count(&keys.bin_pose(), want.len()).await);
    let s = node.stop().await;
    assert_poses(&bin_poses(&out, &keys), &want);
    let c = &s.counters;
    assert_eq!(
        (c.get("sync/reset"), c.get("sync/outlier")),
        (1, 0),
        "{c:?}"
    );
    assert_eq!(c.get("sync/conflict"), 0);
    // Latency for every bin: the reset closed the first replay's open bin, and the second
    // replay's open bin gets its message when the node stops.
    assert!(out.wait_count(&keys.latency(), want.len()).await);
    assert_eq!(out.count(&keys.latency()), want.len());
    assert_eq!(s.bins_published, want.len() as u64);
}

/// A tiny 4 x 4 image (stray frames of a timestamp flood are a few hundred bytes each).
fn tiny(stamp_ns: i64, frame_id: &str) -> Vec<u8> {
    image_from_rgb(&RgbImage::new(4, 4), Header::new(stamp_ns, frame_id)).encode()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn frames_stamped_far_in_the_future_or_past_mid_drive_cost_no_bin() {
    let drive = drive("wedge-stray", 11, 40);
    let keys = Keys::new("wedge_stray");
    let node = RunningNode::start(config(&keys)).await;
    let out = Collector::connect(&node, &[keys.bin_pose(), keys.diagnostics()]).await;
    let player = Player::connect(&node).await;
    player.camera_infos(&drive.rig, drive.frames[0].0).await;
    let pose_of = |i: usize| {
        pose_from_affine(&drive.frames[i].1.left_to_world, Header::new(0, "world")).encode()
    };
    for (i, (stamp, f)) in drive.frames.iter().enumerate() {
        if i == 20 {
            // A whole frame of tiny images stamped 1000 s ahead.
            let t = stamp + 1000 * S;
            player.put(keys.left_image(), tiny(t, "left")).await;
            player.put(keys.right_image(), tiny(t, "right")).await;
            let mut pose = PoseStamped::decode(&pose_of(i)).unwrap();
            pose.header.stamp = Header::new(t, "world").stamp;
            player.put(keys.pose(), pose.encode()).await;
            // 16 tiny left images further ahead, a full buffer of them.
            for k in 0..16 {
                player
                    .put(keys.left_image(), tiny(t + (k + 1) * S / 10, "left"))
                    .await;
            }
        }
        if i == 30 {
            // A real frame of the drive, stamped 1000 s back.
            player
                .frame(&drive.rig, stamp - 1000 * S, f, &f.left_to_world)
                .await;
        }
        player.frame(&drive.rig, *stamp, f, &f.left_to_world).await;
    }
    let want = bin_firsts(&drive);
    assert!(out.wait_count(&keys.bin_pose(), want.len()).await);
    let s = node.stop().await;
    assert_poses(&bin_poses(&out, &keys), &want);
    let c = &s.counters;
    assert_eq!(
        (c.get("sync/outlier"), c.get("sync/reset")),
        (2, 0),
        "{c:?}"
    );
    assert_eq!(
        (c.get("sync/late"), c.get("sync/conflict")),
        (0, 0),
        "{c:?}"
    );
}

/// A drive and the offset added to its stamps.
struct Source {
    drive: Drive,
    offset_ns: i64,
}

/// SGM on `frame` of the drive as the node's worker runs it.
fn reconstruct(drive: &Drive, frame: &StereoFrame) -> renderer::GaussianSet {
    let wire = |img: &RgbImage| rgb_from_image(&image_from_rgb(img, Header::new(0, ""))).unwrap();
    let (left, right) = (wire(&frame.left), wire(&frame.right));
    let origin = frame.left_to_world;
    let view = StereoView {
        left: &left,
        right: &right,
        left_camera: drive.rig.local_camera(origin, origin, Side::Left),
        right_camera: drive.rig.local_camera(origin, origin, Side::Right),
    };
    let mut sgm = model::methods::by_name("sgm").unwrap();
    sgm.reconstruct(&[view]).unwrap()
}

/// Replays the drives at once, each from its own session, their messages interleaved at random
/// (each source in the order left, right, pose, as the replay sends them); checks every bin
/// published is one drive's frame whole. Returns the node's summary and how many bins came out.
async fn at_once(tag: &str, offsets_ns: [i64; 3]) -> (NodeSummary, usize) {
    let sources: Vec<Source> = offsets_ns
        .iter()
        .enumerate()
        .map(|(i, &offset_ns)| Source {
            drive: drive(&format!("{tag}-{i}"), 11 + i as u64, 30),
            offset_ns,
        })
        .collect();
    let keys = Keys::new(tag);
    let node = RunningNode::start(config(&keys)).await;
    let out = Collector::connect(&node, &[keys.bin_map(), keys.bin_pose()]).await;
    let mut players = Vec::new();
    for s in &sources {
        let p = Player::connect(&node).await;
        p.camera_infos(&s.drive.rig, s.offset_ns).await;
        players.push(p);
    }
    // Each source sends a frame's left image, right image and pose in that order from its
    // own session; the three sources' messages are interleaved at random, frame by frame.
    let mut rng = ChaCha8Rng::seed_from_u64(13);
    let frames = sources[0].drive.frames.len();
    for k in 0..frames {
        let mut turns: Vec<usize> = (0..3).flat_map(|src| [src; 3]).collect();
        turns.shuffle(&mut rng);
        let mut next = [0usize; 3];
        for src in turns {
            let s = &sources[src];
            let (stamp, f) = &s.drive.frames[k];
            let header = |id: &str| Header::new(stamp + s.offset_ns, id);
            let (key, payload) = match next[src] {
                0 => (
                    keys.left_image(),
                    image_from_rgb(&f.left, header("left")).encode(),
                ),
                1 => (
                    keys.right_image(),
                    image_from_rgb(&f.right, header("right")).encode(),
                ),
                _ => (
                    keys.pose(),
                    pose_from_affine(&f.left_to_world, header("world")).encode(),
                ),
            };
            players[src].put(key, payload).await;
            next[src] += 1;
        }
        tokio::time::sleep(Duration::from_millis(25)).await;
    }
    // Let the worker finish: no new bin for two seconds.
    let mut last = usize::MAX;
    while out.count(&keys.bin_pose()) != last {
        last = out.count(&keys.bin_pose());
        tokio::time::sleep(Duration::from_secs(2)).await;
    }
    let summary = node.stop().await;

    let maps = out.decoded::<PointCloud2>(&keys.bin_map());
    let poses = bin_poses(&out, &keys);
    assert_eq!(maps.len(), poses.len());
    for (map, pose) in maps.iter().zip(&poses) {
        // The pose names the drive and frame; the map must be that frame's own stereo pair.
        let (src, frame) = sources
            .iter()
            .find_map(|s| {
                let f = s
                    .drive
                    .frames
                    .iter()
                    .find(|(_, f)| same_pose(&f.left_to_world, pose));
                f.map(|(_, f)| (s, f))
            })
            .unwrap_or_else(|| panic!("bin pose {pose:?} is no drive's frame"));
        let got = gaussians_from_cloud(map, DVec3::ZERO).unwrap();
        let want = reconstruct(&src.drive, frame);
        assert_eq!(got.len(), want.len(), "{}: Gaussians", map.header.frame_id);
        let worst = got
            .means
            .iter()
            .zip(&want.means)
            .map(|(a, b)| a.distance(*b))
            .fold(0.0f32, f32::max);
        assert!(
            worst < 1e-4,
            "{}: means differ by {worst}",
            map.header.frame_id
        );
    }
    (summary, poses.len())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn three_drives_with_the_same_stamps_at_once_are_never_paired_across() {
    let (s, bins) = at_once("wedge_same", [0, 0, 0]).await;
    println!("same stamps: {bins} bins, counters {:?}", s.counters);
    // Most frames met another source's: refused and counted, as a conflict, or as late
    // when the node lags behind the three players (a loaded machine: 9 conflicts and 174
    // late once beside two training runs, 0 and 180 beside two busy loops, so which of the
    // two is not asserted; the synchroniser's unit tests hold the conflict itself);
    // `at_once` checked that none was paired across.
    let refused = s.counters.get("sync/conflict") + s.counters.get("sync/late");
    assert!(refused > 30, "{:?}", s.counters);
    assert_eq!(s.counters.get("sync/reset"), 0);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn three_drives_30_ms_apart_at_once_are_never_paired_across() {
    let ms = 1_000_000;
    let (s, bins) = at_once("wedge_apart", [0, 30 * ms, 60 * ms]).await;
    println!("30 ms apart: {bins} bins, counters {:?}", s.counters);
    // Frames 30 ms apart are told apart by their stamps: many come out, each whole.
    assert!(bins >= 10, "{bins} bins");
    assert_eq!(s.counters.get("sync/conflict"), 0);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn diagnostics_arrive_on_their_timer_while_no_bin_finishes() {
    let drive = drive("wedge-diag", 11, 20);
    let keys = Keys::new("wedge_diag");
    let node = RunningNode::start(NodeConfig {
        diagnostics_every: Duration::from_millis(300),
        ..config(&keys)
    })
    .await;
    let out = Collector::connect(&node, &[keys.diagnostics(), keys.bin_map()]).await;
    let player = Player::connect(&node).await;
    player.camera_infos(&drive.rig, 0).await;
    // Left images and poses, never a right image: no frame, no bin; the buffers fill.
    for (stamp, f) in &drive.frames {
        let header = |id: &str| Header::new(*stamp, id);
        let left = image_from_rgb(&f.left, header("left"));
        player.put(keys.left_image(), left.encode()).await;
        let pose = pose_from_affine(&f.left_to_world, header("world"));
        player.put(keys.pose(), pose.encode()).await;
    }
    let why = |d: &Diagnostics| {
        d.counters
            .iter()
            .find(|c| c.kind == "sync/unmatched")
            .map(|c| c.count)
    };
    let said = wait_for(Duration::from_secs(30), || {
        let d = out.decoded::<Diagnostics>(&keys.diagnostics());
        d.len() >= 3 && d.last().and_then(why) == Some(8)
    })
    .await;
    let s = node.stop().await;
    let d = out.decoded::<Diagnostics>(&keys.diagnostics());
    assert!(said, "{} diagnostics, last {:?}", d.len(), d.last());
    assert_eq!(out.count(&keys.bin_map()), 0);
    assert_eq!(s.bins_published, 0);
    // 20 left images and 20 poses, 16 of each kept: 8 pushed out.
    assert_eq!(s.counters.get("sync/unmatched"), 8);
}
