//! A peer's oversize frame against a good camera: the node's per-bin cost is bounded by its
//! working size, so one pair of the largest images the input limits admit (2000x2000 `rgb8`,
//! 24 MB, with camera infos of that size) sent before a good drive costs the worker about
//! one of the good camera's bins, and the drive, replayed behind it at half its recorded
//! rate (headroom for a loaded CI machine), loses none of its bins to the worker queue.
//!
//! The node runs with the command line's queue of 2 and a working size of the good camera's
//! own pixels (`--working-pixels`, as a node sized for its camera is run); the oversize pair
//! is area-averaged to that size before any per-bin stage (range fit and stereo matching
//! included). Before that bound, the range fit ran SGM at the full 2000x2000 and the pair
//! held the worker 10-14 s, which made the queue drop most of a drive's bins.

use crate::drive_support;

use std::time::Duration;

use drive_support::{Collector, Drive, Player, RunningNode};
use glam::{DAffine3, DVec3};
use model::frame::{RgbImage, StereoFrame, StereoRig};
use node::pipeline::worker::RenderWith;
use node::service::{InputLimits, NodeConfig};
use node::transport::Keys;
use renderer::Intrinsics;

/// The peer's image side: the largest square inside the default input limits' pixel count
/// (3840 x 2160) and width.
const OVERSIZE: u32 = 2000;

/// Seeded noise bytes: a textured image, so the reconstructor has something to match.
fn noise(width: u32, height: u32, seed: u64) -> RgbImage {
    let mut state = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
    let bytes: Vec<u8> = (0..3 * width as usize * height as usize)
        .map(|_| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 24) as u8
        })
        .collect();
    RgbImage::from_rgb8(width, height, &bytes)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_oversize_pair_before_a_drive_costs_the_drive_no_bin() {
    let drive = Drive::small_of_seed("oversize", 31);
    let opened = drive.bins_opened(8.0);
    let keys = Keys::new("oversize");
    let working_pixels = drive.rig.intrinsics.width as u64 * drive.rig.intrinsics.height as u64;
    let node = RunningNode::start(NodeConfig {
        keys: keys.clone(),
        queue_capacity: 2,
        renders: RenderWith::Off,
        limits: InputLimits {
            max_working_pixels: working_pixels,
            ..InputLimits::default()
        },
        ..NodeConfig::default()
    })
    .await;
    let outputs = Collector::connect_truncated(&node, &[keys.bin_map()], 1 << 12).await;

    // The peer: camera infos of its own size, one oversize pair a second before the drive,
    // 500 m from where the drive starts (so the drive's first frame opens a bin of its own).
    let peer = Player::connect(&node).await;
    let rig = StereoRig {
        intrinsics: Intrinsics::from_hfov(OVERSIZE, OVERSIZE, 90.0),
        baseline: 0.5,
    };
    let (first_stamp, first) = &drive.frames[0];
    let far = DAffine3::from_translation(DVec3::new(500.0, 0.0, 0.0)) * first.left_to_world;
    let pair = StereoFrame {
        index: 0,
        left: noise(OVERSIZE, OVERSIZE, 1),
        right: noise(OVERSIZE, OVERSIZE, 2),
        left_to_world: far,
    };
    let peer_stamp = first_stamp - 1_000_000_000;
    peer.camera_infos(&rig, peer_stamp).await;
    peer.frame(&rig, peer_stamp, &pair, &far).await;

    // The good camera, at half its recorded rate: headroom for the suite's other tests on
    // two cores, while a pair holding the worker for seconds (the old 10-14 s) would still
    // make the queue drop most of the drive's bins.
    let player = Player::connect(&node).await;
    player.camera_infos(&drive.rig, *first_stamp).await;
    let start = tokio::time::Instant::now();
    for (stamp, frame) in &drive.frames {
        let due = Duration::from_nanos(2 * (stamp - first_stamp).max(0) as u64);
        tokio::time::sleep_until(start + due).await;
        player
            .frame(&drive.rig, *stamp, frame, &frame.left_to_world)
            .await;
    }
    assert!(
        outputs.wait_count(&keys.bin_map(), opened + 1).await,
        "the peer's bin and every bin of the drive are published"
    );
    let summary = node.stop().await;

    let c = &summary.counters;
    println!(
        "{opened} bins of the drive and the peer's: {} published, {} dropped by the queue, {} images downscaled",
        summary.bins_published,
        c.get("dropped/worker_queue"),
        c.get("input/downscaled")
    );
    assert_eq!(c.get("dropped/worker_queue"), 0, "{c:?}");
    assert_eq!(summary.bins_published, opened as u64 + 1, "{c:?}");
    assert_eq!(
        c.get("input/downscaled"),
        2,
        "the peer's two images, and none of the drive's"
    );
}
