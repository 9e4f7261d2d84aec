//! A robot's `ros2 bag record` replayed as it is. A generated drive is written as a rosbag2
//! recording (MCAP storage) by rosbags' own writer (`scripts/write_rosbag2.py`), with a
//! robot's topic names and types: JPEG `CompressedImage`s on
//! `/camera/{left,right}/image_raw/compressed`, `CameraInfo`s on
//! `/camera/{left,right}/camera_info`, the body on `/tf` and the map and the camera's mount
//! on `/tf_static`, and a `/rosout`-like topic the node does not take. Replayed through a
//! topic map into a node whose poses come from `/tf`, it publishes every bin, each stamped
//! with its frame's recorded stamp. A copy cut off mid-file (a killed recorder) replays the
//! complete part; a channel mapped onto a topic of another type is skipped and counted.

use crate::drive_support;
use crate::node_pose_sources::CLOCK_NS;
use crate::python_support;

use std::path::Path;

use drive_support::{sgm_config, Collector, Drive, RunningNode};
use glam::{DAffine3, DMat3, DQuat, DVec3};
use model::bins::{make_bins, BinConfig, BinLayout};
use model::frame::{Rgb8Image, RgbImage};
use model::synth::SynthConfig;
use node::bag::{BagReader, Rate};
use node::clients::replay_bag;
use node::clients::BagReplayOptions;
use node::clients::BagReplaySummary;
use node::msg::compressed::{compressed_image, Compression};
use node::msg::image::camera_info;
use node::msg::std_msgs::Header;
use node::msg::tf2_msgs::{world_to, TfMessage};
use node::msg::{Message, MessageKind};
use node::service::{NodeConfig, NodeSummary};
use node::tf::{PoseSourceConfig, PoseSourceKind};
use node::transport::keys::{self, Topic};
use node::transport::open;
use node::transport::Keys;

/// `map -> odom`.
fn map_to_odom() -> DAffine3 {
    DAffine3::from_rotation_translation(DQuat::from_rotation_z(-0.2), DVec3::new(2.0, 1.0, 0.0))
}

/// `base_link -> camera_left_optical_frame`: optical axes, 1 m ahead, 1.6 m up.
fn mount() -> DAffine3 {
    let optical = DMat3::from_cols(DVec3::NEG_Y, DVec3::NEG_Z, DVec3::X);
    DAffine3::from_mat3_translation(optical, DVec3::new(1.0, 0.0, 1.6))
}

fn edge(parent: &str, child: &str, child_to_parent: &DAffine3, stamp_ns: i64) -> Vec<u8> {
    let mut t = world_to(child, child_to_parent, stamp_ns);
    t.header.frame_id = parent.into();
    TfMessage {
        transforms: vec![t],
    }
    .encode()
}

fn jpeg(img: &RgbImage, header: Header) -> Vec<u8> {
    let rgb8 = Rgb8Image {
        width: img.width,
        height: img.height,
        data: img.to_rgb8(),
    };
    compressed_image(&rgb8, Compression::Jpeg { quality: 95 }, header)
        .expect("encodes")
        .encode()
}

/// The drive as a robot records it: (topic, type, stamp, CDR payload), in time order.
fn recording(drive: &Drive) -> Vec<(&'static str, MessageKind, i64, Vec<u8>)> {
    let rig = &drive.rig;
    let first = drive.frames[0].0 + CLOCK_NS;
    let mut messages = vec![
        (
            "/tf_static",
            MessageKind::TfMessage,
            first,
            edge("map", "odom", &map_to_odom(), first),
        ),
        (
            "/tf_static",
            MessageKind::TfMessage,
            first,
            edge("base_link", "camera_left_optical_frame", &mount(), first),
        ),
    ];
    for (stamp, frame) in &drive.frames {
        let stamp = &(stamp + CLOCK_NS);
        let header = |id: &str| Header::new(*stamp, id);
        let body = map_to_odom().inverse() * frame.left_to_world * mount().inverse();
        let left_info = camera_info(&rig.intrinsics, 0.0, header("camera_left_optical_frame"));
        let right_info = camera_info(
            &rig.intrinsics,
            rig.baseline,
            header("camera_right_optical_frame"),
        );
        messages.extend([
            (
                "/tf",
                MessageKind::TfMessage,
                *stamp,
                edge("odom", "base_link", &body, *stamp),
            ),
            (
                "/camera/left/camera_info",
                MessageKind::CameraInfo,
                *stamp,
                left_info.encode(),
            ),
            (
                "/camera/right/camera_info",
                MessageKind::CameraInfo,
                *stamp,
                right_info.encode(),
            ),
            (
                "/camera/left/image_raw/compressed",
                MessageKind::CompressedImage,
                *stamp,
                jpeg(&frame.left, header("camera_left_optical_frame")),
            ),
            (
                "/camera/right/image_raw/compressed",
                MessageKind::CompressedImage,
                *stamp,
                jpeg(&frame.right, header("camera_right_optical_frame")),
            ),
            (
                "/diagnostics_agg",
                MessageKind::CameraInfo,
                *stamp,
                left_info.encode(),
            ),
        ]);
    }
    messages
}

/// Writes `messages` with rosbags' rosbag2 writer under `dir`: the MCAP file.
fn write_rosbag2(dir: &Path, messages: &[(&str, MessageKind, i64, Vec<u8>)]) -> std::path::PathBuf {
    python_support::require("rosbags");
    let request = serde_json::json!({
        "path": dir,
        "messages": messages
            .iter()
            .map(|(topic, kind, stamp, payload)| serde_json::json!({
                "topic": topic,
                "type": kind.ros_name(),
                "stamp_ns": stamp,
                "hex": payload.iter().map(|b| format!("{b:02x}")).collect::<String>(),
            }))
            .collect::<Vec<_>>(),
    });
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/../scripts/write_rosbag2.py");
    let reply = python_support::run_json(&["python3", script], &request);
    reply["mcap"].as_str().expect("the bag's MCAP file").into()
}

/// The robot's topics as the node's.
fn topic_map() -> Vec<(String, Topic)> {
    [
        ("/camera/left/image_raw/compressed", keys::LEFT_COMPRESSED),
        ("/camera/right/image_raw/compressed", keys::RIGHT_COMPRESSED),
        ("/camera/left/camera_info", keys::LEFT_INFO),
        ("/camera/right/camera_info", keys::RIGHT_INFO),
        ("/tf", keys::TF),
        ("/tf_static", keys::TF_STATIC),
        // Mapped onto a topic of another type: skipped and counted.
        ("/diagnostics_agg", keys::POSE),
    ]
    .into_iter()
    .map(|(recorded, topic)| (recorded.to_string(), topic))
    .collect()
}

/// Replays `bag` into a fresh node taking its poses from `/tf` and waits for `bins` bin maps:
/// the replay's and the node's summaries and the bin maps' stamps.
async fn replay_into_node(
    tag: &str,
    bag: &BagReader,
    bins: usize,
) -> (BagReplaySummary, NodeSummary, Vec<i64>) {
    let keys = Keys::new(tag);
    // A bag replayed as fast as possible on a loaded machine: `/tf` (a subscription of its
    // own) may lag the images by more than a live camera's 500 ms, so stamps wait 10 s.
    let mut pose_source = PoseSourceConfig::new(PoseSourceKind::Tf, Some("map".into()));
    pose_source.wait_ns = 10_000_000_000;
    let node = RunningNode::start(NodeConfig {
        pose_source: Some(pose_source),
        ..sgm_config(&keys)
    })
    .await;
    let outputs = Collector::connect_truncated(&node, &[keys.bin_map()], 1 << 12).await;
    let session = open(&node.client()).await.expect("player session");
    let options = BagReplayOptions {
        rate: Rate::AsFastAsPossible,
        inputs_only: true,
        recorded_namespace: None,
        topic_map: topic_map(),
    };
    let replayed = replay_bag(&session, &keys, bag, &options, &mut |_, _| {})
        .await
        .expect("replays");
    let all = outputs.wait_count(&keys.bin_map(), bins).await;
    let summary = node.stop().await;
    assert!(all, "{bins} bin maps: {:?}", summary.counters);
    let stamps = outputs
        .headers(&keys.bin_map())
        .iter()
        .map(|h| h.stamp.to_nanos())
        .collect();
    (replayed, summary, stamps)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_robots_rosbag2_recording_replays_through_a_topic_map() {
    // At 544x112 the recording spans a few of rosbags' 1 MiB chunks, so a cut keeps some.
    let drive = Drive::generate(
        "rosbag",
        &SynthConfig {
            seed: 41,
            frames: 40,
            width: 544,
            height: 112,
            supersample: 1,
            lidar_azimuth_steps: 64,
            ..SynthConfig::default()
        },
    );
    let opened = drive.bins_opened(8.0);
    let messages = recording(&drive);
    let mcap = write_rosbag2(&drive.dir("robot_bag"), &messages);

    let bag = BagReader::open(&mcap).expect("rosbags' MCAP opens");
    let (replayed, summary, stamps) = replay_into_node("rosbag_whole", &bag, opened).await;
    let frames = drive.frames.len() as u64;
    assert_eq!(replayed.wrong_types.get("/diagnostics_agg"), Some(&frames));
    assert_eq!(replayed.published, messages.len() as u64 - frames);
    assert_eq!(
        summary.bins_published, opened as u64,
        "{:?}",
        summary.counters
    );
    assert_eq!(
        summary.counters.sum("bad_message/"),
        0,
        "{:?}",
        summary.counters
    );
    assert_eq!(summary.counters.get("pose_source/ready"), frames);
    // Each bin map carries the recorded stamp of the frame that opened it.
    let recorded: Vec<i64> = drive.frames.iter().map(|(t, _)| t + CLOCK_NS).collect();
    assert!(stamps.iter().all(|s| recorded.contains(s)), "{stamps:?}");

    // A recorder killed mid-drive: the file cut at 60%, its complete chunks replayed.
    let bytes = std::fs::read(&mcap).unwrap();
    let cut = drive.dir("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() * 6 / 10]).unwrap();
    let (bag, recovery) = BagReader::open_or_recover(&cut).expect("the complete part reads");
    assert!(recovery.is_some(), "not a finished recording");
    // The frames whose two images survived (their /tf comes first at the same stamp).
    let mut images: std::collections::BTreeMap<i64, u32> = Default::default();
    for m in bag.messages() {
        let m = m.expect("a recovered message");
        if m.channel.topic.ends_with("image_raw/compressed") {
            *images.entry(m.log_time_ns as i64).or_default() += 1;
        }
    }
    let complete = images.values().filter(|&&n| n == 2).count();
    assert!(complete > 1, "the cut keeps complete frames");
    let poses: Vec<DAffine3> = drive.poses()[..complete].to_vec();
    let bins_kept = make_bins(
        &poses,
        &BinConfig {
            length_m: 8.0,
            layout: BinLayout::Consecutive,
        },
    )
    .len()
        + 1;
    // The synchroniser may hold the last complete frame for a later sample that never
    // comes: its bin, if it opens one, is then not made.
    let (replayed, summary, _) = replay_into_node("rosbag_cut", &bag, bins_kept - 1).await;
    println!(
        "rosbag2 replay: {} messages, {opened} bins; cut at 60%: {} messages, {} bins",
        messages.len() as u64 - frames,
        replayed.published,
        summary.bins_published
    );
    assert!(replayed.published > 0 && replayed.published < messages.len() as u64);
    let kept = summary.bins_published;
    assert!(
        (bins_kept as u64 - 1..=bins_kept as u64).contains(&kept),
        "{kept} of {bins_kept}: {:?}",
        summary.counters
    );
    assert!(bins_kept < opened, "the cut loses the last bins");
    assert_eq!(
        summary.counters.sum("bad_message/"),
        0,
        "{:?}",
        summary.counters
    );
}
