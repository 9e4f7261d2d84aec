//! Malformed input on every input key: a malformed message on each input key must be counted
//! and must not stop the node; `node_replay.rs` sends one only on the left image. Here one bad
//! message goes to each of the five input keys (left and right image, left and right camera
//! info, pose) of an in-process node, then a generated drive follows. Checked: each key's
//! `bad_message/<key>` counter is exactly 1 in the node's summary and in the last Diagnostics
//! message, every latency message's `bad_messages` ends at 5, and every bin the drive opens is
//! still published.
//!
//! Two kinds of bad message: payloads that are not CDR of the type at all (truncated,
//! garbage), and well-formed CDR whose content the node cannot use (an image whose data does
//! not match its size or has an unknown encoding, a pose with a non-unit quaternion or a NaN,
//! a camera info with a zero or NaN focal length).

use crate::drive_support;

use drive_support::{bin_of_frame_id, Collector, Drive, Player, RunningNode};
use glam::DAffine3;
use model::synth::SynthConfig;
use node::msg::geometry_msgs::PoseStamped;
use node::msg::image::{camera_info, image_from_rgb};
use node::msg::latency::{BinLatency, Diagnostics};
use node::msg::pose::pose_from_affine;
use node::msg::std_msgs::Header;
use node::msg::Message;
use node::pipeline::worker::RenderWith;
use node::service::NodeConfig;
use node::transport::Keys;

/// The counter of each input key, in the order the tests send to them.
const COUNTERS: [&str; 5] = [
    "bad_message/left_image",
    "bad_message/right_image",
    "bad_message/left_camera_info",
    "bad_message/right_camera_info",
    "bad_message/pose",
];

fn drive(tag: &str) -> Drive {
    Drive::generate(
        tag,
        &SynthConfig {
            seed: 11,
            frames: 40,
            width: 136,
            height: 40,
            lidar_azimuth_steps: 64,
            ..SynthConfig::default()
        },
    )
}

/// The input keys in [`COUNTERS`] order.
fn input_keys(k: &Keys) -> [String; 5] {
    [
        k.left_image(),
        k.right_image(),
        k.left_info(),
        k.right_info(),
        k.pose(),
    ]
}

/// Sends `bad[i]` on input key `i`, then the drive; checks every counter is 1 and the drive
/// still comes out.
async fn bad_then_drive(tag: &str, bad: impl Fn(&Drive) -> [Vec<u8>; 5]) {
    let drive = drive(tag);
    let opened = drive.bins_opened(8.0);
    let keys = Keys::new(tag);
    let node = RunningNode::start(NodeConfig {
        keys: keys.clone(),
        queue_capacity: 64,
        renders: RenderWith::Off,
        ..NodeConfig::default()
    })
    .await;
    let outputs = Collector::connect_truncated(
        &node,
        &[keys.latency(), keys.diagnostics(), keys.bin_map()],
        1 << 16,
    )
    .await;
    let player = Player::connect(&node).await;
    for (key, payload) in input_keys(&keys).into_iter().zip(bad(&drive)) {
        player.put(key, payload).await;
    }
    player.drive(&drive, DAffine3::IDENTITY, 0).await;
    assert!(node.is_running());
    outputs.wait_count(&keys.bin_map(), opened).await;
    let summary = node.stop().await;

    for c in COUNTERS {
        assert_eq!(summary.counters.get(c), 1, "{c}: {:?}", summary.counters);
    }
    assert_eq!(summary.counters.sum("bad_message/"), 5);
    assert_eq!(summary.bins_published, opened as u64, "{summary:?}");
    let bins: Vec<u64> = outputs
        .headers(&keys.bin_map())
        .iter()
        .map(|h| bin_of_frame_id(&h.frame_id))
        .collect();
    assert_eq!(bins, (0..opened as u64).collect::<Vec<_>>());
    let latencies: Vec<BinLatency> = outputs.decoded(&keys.latency());
    assert_eq!(
        latencies.len(),
        opened,
        "one per bin, the last when the node stopped"
    );
    assert!(latencies.iter().all(|l| l.bad_messages <= 5));
    assert_eq!(latencies.last().unwrap().bad_messages, 5);
    let diagnostics: Vec<Diagnostics> = outputs.decoded(&keys.diagnostics());
    let last = diagnostics.last().expect("diagnostics arrive");
    for c in COUNTERS {
        let n = last.counters.iter().find(|x| x.kind == c).map(|x| x.count);
        assert_eq!(n, Some(1), "{c} in the last Diagnostics");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_payload_that_is_not_the_type_is_counted_once_per_input_key() {
    bad_then_drive("badcdr", |_| {
        [
            vec![0, 1, 0, 0, 9],          // encapsulation header, then a truncated stamp
            vec![0xde, 0xad, 0xbe, 0xef], // no CDR encapsulation at all
            vec![0, 1, 0, 0],             // header only
            Vec::new(),                   // empty
            // A PoseStamped cut in the middle of the position.
            pose_from_affine(&DAffine3::IDENTITY, Header::new(1, "world")).encode()[..30].to_vec(),
        ]
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn well_formed_but_unusable_content_is_counted_once_per_input_key() {
    bad_then_drive("badvalue", |d| {
        let (_, f) = &d.frames[0];
        let header = |id: &str| Header::new(1, id);
        // Left image: one byte short of its declared size.
        let mut short = image_from_rgb(&f.left, header("left"));
        short.data.pop();
        // Right image: an encoding the node does not read.
        let mut float = image_from_rgb(&f.right, header("right"));
        float.encoding = "32FC1".into();
        // Camera infos: zero focal length (left), NaN focal length (right).
        let mut zero = camera_info(&d.rig.intrinsics, 0.0, header("left"));
        zero.p[0] = 0.0;
        zero.k[0] = 0.0;
        let mut nan = camera_info(&d.rig.intrinsics, d.rig.baseline, header("right"));
        nan.p[5] = f64::NAN;
        // Pose: a quaternion of norm 2.
        let mut pose: PoseStamped = pose_from_affine(&f.left_to_world, header("world"));
        pose.pose.orientation.w *= 2.0;
        pose.pose.orientation.x *= 2.0;
        pose.pose.orientation.y *= 2.0;
        pose.pose.orientation.z *= 2.0;
        [
            short.encode(),
            float.encode(),
            zero.encode(),
            nan.encode(),
            pose.encode(),
        ]
    })
    .await;
}

/// The parts of the above that the node does count (images and pose), so they stay checked
/// while the camera-info case is open.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn well_formed_but_unusable_images_and_poses_are_counted() {
    let drive = drive("badimg");
    let keys = Keys::new("badimg");
    let opened = drive.bins_opened(8.0);
    let node = RunningNode::start(NodeConfig {
        keys: keys.clone(),
        queue_capacity: 64,
        renders: RenderWith::Off,
        ..NodeConfig::default()
    })
    .await;
    let player = Player::connect(&node).await;
    let (_, f) = &drive.frames[0];
    let mut short = image_from_rgb(&f.left, Header::new(1, "left"));
    short.data.pop();
    let mut float = image_from_rgb(&f.right, Header::new(1, "right"));
    float.encoding = "32FC1".into();
    let mut pose = pose_from_affine(&f.left_to_world, Header::new(1, "world"));
    pose.pose.position.x = f64::NAN;
    player.put(keys.left_image(), short.encode()).await;
    player.put(keys.right_image(), float.encode()).await;
    player.put(keys.pose(), pose.encode()).await;
    player.drive(&drive, DAffine3::IDENTITY, 0).await;
    let summary = node.stop().await;
    for c in [COUNTERS[0], COUNTERS[1], COUNTERS[4]] {
        assert_eq!(summary.counters.get(c), 1, "{c}: {:?}", summary.counters);
    }
    assert_eq!(summary.counters.sum("bad_message/"), 3);
    assert_eq!(summary.bins_published, opened as u64);
}
