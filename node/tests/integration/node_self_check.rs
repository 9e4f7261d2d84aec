//! The per-bin self-check in a real node on loopback, which keeps the node from publishing
//! confident garbage: a generated drive passes it on every bin with the default method (the
//! learned network, shipped `tiny` weights); a drive whose right images are of another scene,
//! or whose left and right images are swapped, fails it on every bin, and the node does what
//! `--on-check-fail` says: replaces the map by SGM's (the default; SGM's map is checked too
//! and, on such a pair, flagged) or publishes it with opacity and confidence lowered. Checked
//! on the latency messages' check fields, the counters, and the published maps.

use crate::drive_support;

use drive_support::{Collector, Drive, Player, RunningNode};
use glam::DVec3;
use model::frame::StereoFrame;
use node::msg::gaussians::gaussians_from_cloud;
use node::msg::latency::BinLatency;
use node::msg::sensor_msgs::PointCloud2;
use node::pipeline::self_check::{OnCheckFail, LOWERED_FACTOR};
use node::pipeline::worker::RenderWith;
use node::service::{NodeConfig, NodeSummary};
use node::transport::Keys;

/// What a node made of a drive: its summary, every closed bin's latency message, every
/// published bin map.
struct Run {
    summary: NodeSummary,
    latencies: Vec<BinLatency>,
    maps: Vec<PointCloud2>,
    opened: usize,
}

/// Runs `frames` (the frames of `drive`, possibly altered) through a node with `on_fail`.
async fn run(tag: &str, drive: &Drive, frames: &[(i64, StereoFrame)], on_fail: OnCheckFail) -> Run {
    let opened = drive.bins_opened(8.0);
    let keys = Keys::new(tag);
    let node = RunningNode::start(NodeConfig {
        keys: keys.clone(),
        queue_capacity: 64,
        renders: RenderWith::Off,
        on_check_fail: on_fail,
        ..NodeConfig::default()
    })
    .await;
    let outputs = Collector::connect(&node, &[keys.latency(), keys.bin_map()]).await;
    let player = Player::connect(&node).await;
    player.frames(&drive.rig, frames).await;
    outputs.wait_count(&keys.bin_map(), opened).await;
    let summary = node.stop().await;
    // The last bin's latency goes out as the node stops.
    outputs.wait_count(&keys.latency(), opened).await;
    Run {
        summary,
        latencies: outputs.decoded(&keys.latency()),
        maps: outputs.decoded(&keys.bin_map()),
        opened,
    }
}

/// The small drive with every right image taken from the same frame of another drive.
fn other_scene(drive: &Drive, other: &Drive) -> Vec<(i64, StereoFrame)> {
    drive
        .frames
        .iter()
        .zip(&other.frames)
        .map(|((stamp, f), (_, o))| {
            let mut f = f.clone();
            f.right = o.right.clone();
            (*stamp, f)
        })
        .collect()
}

/// The small drive with left and right images swapped.
fn swapped(drive: &Drive) -> Vec<(i64, StereoFrame)> {
    drive
        .frames
        .iter()
        .map(|(stamp, f)| {
            let mut f = f.clone();
            std::mem::swap(&mut f.left, &mut f.right);
            (*stamp, f)
        })
        .collect()
}

/// The small drive with the frames `range` replaced by independent uniform noise in both
/// cameras (a peer sending garbage at the drive's size, which decodes fine).
fn noise_in(drive: &Drive, range: std::ops::Range<usize>) -> Vec<(i64, StereoFrame)> {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let mut frames = drive.frames.clone();
    for (_, f) in &mut frames[range] {
        for img in [&mut f.left, &mut f.right] {
            img.data.iter_mut().for_each(|v| *v = rng.random::<f32>());
        }
    }
    frames
}

/// Every bin was published and every bin's latency came out (the last, never closed, when
/// the node stopped).
fn assert_complete(r: &Run) {
    assert_eq!(r.summary.bins_published, r.opened as u64, "{:?}", r.summary);
    assert_eq!(r.maps.len(), r.opened);
    assert_eq!(r.latencies.len(), r.opened, "every bin");
    assert!(r.opened >= 3, "the drive opens several bins: {}", r.opened);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_generated_drive_passes_the_check_on_every_bin() {
    let drive = Drive::small("selfcheck-good");
    let r = run("selfcheck_good", &drive, &drive.frames, OnCheckFail::Sgm).await;
    assert_complete(&r);
    for l in &r.latencies {
        assert_eq!(
            (l.check_verdict, l.check_action, l.fallback_verdict),
            (1, 0, 0),
            "{l:?}"
        );
        assert!(l.check_score >= 0.6 && l.check_score <= 1.0, "{l:?}");
        assert!(l.check_samples >= 32, "{l:?}");
    }
    let c = &r.summary.counters;
    assert_eq!(c.get("check/pass"), r.opened as u64, "{c:?}");
    assert_eq!(c.sum("check/") - c.get("check/pass"), 0, "{c:?}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn another_scenes_right_images_fail_and_sgm_replaces_the_map() {
    let drive = Drive::small("selfcheck-other");
    let other = Drive::small_of_seed("selfcheck-other-scene", 1_000_003);
    let frames = other_scene(&drive, &other);
    let r = run("selfcheck_other", &drive, &frames, OnCheckFail::Sgm).await;
    assert_complete(&r);
    for l in &r.latencies {
        // Failed, replaced by SGM's map, which was checked: on a pair of two scenes it
        // fails too (published flagged).
        assert_eq!(
            (l.check_verdict, l.check_action, l.fallback_verdict),
            (2, 3, 2),
            "{l:?}"
        );
        // The network's dense map scores low; SGM's sparse one may score well on the few
        // pixels it matched by chance, and fails on how few those are (coverage).
        assert!(l.check_score < 0.6, "{l:?}");
    }
    let c = &r.summary.counters;
    let bins = r.opened as u64;
    assert_eq!(c.get("check/fail"), bins, "{c:?}");
    assert_eq!(c.get("check/fallback_sgm"), bins, "{c:?}");
    assert_eq!(c.get("check/fallback_sgm_failed"), bins, "{c:?}");
    assert_eq!(c.get("check/pass"), 0, "{c:?}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn swapped_images_fail_and_the_map_is_published_dimmed() {
    let drive = Drive::small("selfcheck-swapped");
    let frames = swapped(&drive);
    let r = run(
        "selfcheck_swapped",
        &drive,
        &frames,
        OnCheckFail::LowerOpacity,
    )
    .await;
    assert_complete(&r);
    for l in &r.latencies {
        assert_eq!(
            (l.check_verdict, l.check_action, l.fallback_verdict),
            (2, 2, 0),
            "{l:?}"
        );
    }
    let c = &r.summary.counters;
    assert_eq!(c.get("check/fail"), r.opened as u64, "{c:?}");
    assert_eq!(c.get("check/lowered_opacity"), r.opened as u64, "{c:?}");
    // Every published Gaussian carries the lowered opacity and confidence.
    for cloud in &r.maps {
        let set = gaussians_from_cloud(cloud, DVec3::ZERO).expect("a bin map decodes");
        assert!(!set.is_empty());
        let eps = 1e-4;
        assert!(set.opacities.iter().all(|&o| o <= LOWERED_FACTOR + eps));
        assert!(set.confidences.iter().all(|&o| o <= LOWERED_FACTOR + eps));
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_noise_bin_is_published_flagged_but_not_fused() {
    let drive = Drive::small("selfcheck-noise");
    let clean = run(
        "selfcheck_noise_ref",
        &drive,
        &drive.frames,
        OnCheckFail::Sgm,
    )
    .await;
    let n = drive.frames.len();
    let frames = noise_in(&drive, n / 3..2 * n / 3);
    let r = run("selfcheck_noise", &drive, &frames, OnCheckFail::Sgm).await;
    assert_complete(&r);
    // A bin is unfused exactly when the network's map and SGM's both failed.
    let both_failed = r
        .latencies
        .iter()
        .filter(|l| (l.check_verdict, l.check_action, l.fallback_verdict) == (2, 3, 2))
        .count() as u64;
    let c = &r.summary.counters;
    assert!(
        both_failed >= 1,
        "the noise bins fail both: {:?}",
        r.latencies
    );
    assert_eq!(c.get("check/unfused"), both_failed, "{c:?}");
    // Every bin is still published; the noise adds nothing to the global map (it holds
    // fewer Gaussians than the clean drive's, which has those bins' true geometry).
    assert_eq!(r.maps.len(), clean.maps.len());
    assert!(
        r.summary.global_gaussians <= clean.summary.global_gaussians,
        "noisy {} vs clean {}",
        r.summary.global_gaussians,
        clean.summary.global_gaussians
    );
    assert_eq!(clean.summary.counters.get("check/unfused"), 0);
}
