//! What ROS tools need to pair and place the node's outputs, on a real node over loopback
//! zenoh (SGM reconstructor, CPU renders): every bin's map, pose, render, map update and
//! bird's-eye view carry the `header.stamp` of the input frame the bin came from (the bin's
//! first frame), while the latency message keeps the node's own clock; `/tf` carries world ->
//! the left camera (the left images' `frame_id`) at every frame's stamp and pose, and
//! `/tf_static` world -> `bin_<id>` for every bin, equal to the bin poses.

use crate::drive_support;

use std::collections::BTreeMap;

use drive_support::{bin_of_frame_id, Collector, Drive, Player, RunningNode};
use glam::{DAffine3, DQuat, DVec3};
use model::synth::SynthConfig;
use node::msg::geometry_msgs::{PoseStamped, TransformStamped};
use node::msg::latency::BinLatency;
use node::msg::map_update::MapUpdate;
use node::msg::pose::affine_from_pose;
use node::msg::sensor_msgs::{Image, PointCloud2};
use node::msg::tf2_msgs::TfMessage;
use node::pipeline::worker::RenderWith;
use node::service::NodeConfig;
use node::transport::keys::{TF, TF_STATIC};
use node::transport::Keys;

/// Drive stamps are moved this far back (about 23 years), so a stamp taken from the node's
/// wall clock can never be mistaken for a source stamp.
const OFFSET_NS: i64 = -730_000_000_000_000_000;

/// The rotation and translation of a transform message as a rigid transform.
fn affine_of(t: &TransformStamped) -> DAffine3 {
    let (p, q) = (t.transform.translation, t.transform.rotation);
    DAffine3::from_rotation_translation(
        DQuat::from_xyzw(q.x, q.y, q.z, q.w),
        DVec3::new(p.x, p.y, p.z),
    )
}

/// Whether two rigid transforms agree to 1e-9 (translations are passed through exactly, the
/// rotation goes matrix -> quaternion).
fn same_pose(a: &DAffine3, b: &DAffine3) -> bool {
    a.translation == b.translation && a.matrix3.abs_diff_eq(b.matrix3, 1e-9)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn outputs_carry_their_source_stamp_and_tf_places_every_bin() {
    let drive = Drive::generate(
        "stamps",
        &SynthConfig {
            seed: 5,
            frames: 40,
            width: 136,
            height: 40,
            ..SynthConfig::default()
        },
    );
    let keys = Keys::new("stamps_ns");
    let node = RunningNode::start(NodeConfig {
        keys: keys.clone(),
        method: "sgm".into(),
        renders: RenderWith::Cpu,
        snapshot_every: 1,
        queue_capacity: 64,
        ..NodeConfig::default()
    })
    .await;
    let watched = [
        keys.bin_map(),
        keys.bin_pose(),
        keys.bin_render(),
        keys.map_update(),
        keys.map_bev(),
        keys.latency(),
        keys.key(TF),
        keys.key(TF_STATIC),
    ];
    let collector = Collector::connect(&node, &watched).await;
    Player::connect(&node)
        .await
        .drive(&drive, DAffine3::IDENTITY, OFFSET_NS)
        .await;
    let bins = drive.bins_opened(8.0);
    assert!(bins >= 3, "{bins} bins");
    assert!(collector.wait_count(&keys.bin_pose(), bins).await);
    // The open bin's render (and every latency) is out once the node stops.
    node.stop().await;

    // Source frames by stamp: (pose, left frame name as the player sends it).
    let frames: BTreeMap<i64, DAffine3> = drive
        .frames
        .iter()
        .map(|(t, f)| (t + OFFSET_NS, f.left_to_world))
        .collect();

    // Bin maps and poses: the stamp of a frame of the drive whose pose is the bin's pose.
    let maps: Vec<PointCloud2> = collector.decoded(&keys.bin_map());
    let poses: Vec<PoseStamped> = collector.decoded(&keys.bin_pose());
    assert_eq!((maps.len(), poses.len()), (bins, bins));
    let mut stamp_of_bin = BTreeMap::new();
    for (map, pose) in maps.iter().zip(&poses) {
        let stamp = map.header.stamp.to_nanos();
        let source = frames
            .get(&stamp)
            .unwrap_or_else(|| panic!("map stamp {stamp} is no input frame's"));
        assert_eq!(pose.header.stamp, map.header.stamp, "map and pose pair");
        assert!(same_pose(&affine_from_pose(pose).unwrap(), source));
        stamp_of_bin.insert(bin_of_frame_id(&map.header.frame_id), stamp);
    }
    let bin_stamps: Vec<i64> = stamp_of_bin.values().copied().collect();
    assert!(bin_stamps.windows(2).all(|w| w[0] < w[1]), "{bin_stamps:?}");

    // Renders: each bin's, at its map's stamp.
    let renders: Vec<Image> = collector.decoded(&keys.bin_render());
    assert_eq!(renders.len(), bins);
    for r in &renders {
        let bin = bin_of_frame_id(&r.header.frame_id);
        assert_eq!(
            r.header.stamp.to_nanos(),
            stamp_of_bin[&bin],
            "render of bin {bin}"
        );
    }

    // Map updates (an increment and a snapshot per bin) and bird's-eye views: the stamp of
    // the bin each was made for, in bin order.
    let updates: Vec<MapUpdate> = collector.decoded(&keys.map_update());
    assert_eq!(updates.len(), 2 * bins);
    for u in &updates {
        assert_eq!(
            u.header.stamp.to_nanos(),
            stamp_of_bin[&u.bin_id],
            "{}",
            u.sequence
        );
    }
    let bev: Vec<i64> = collector
        .headers(&keys.map_bev())
        .iter()
        .map(|h| h.stamp.to_nanos())
        .collect();
    assert_eq!(bev, bin_stamps);

    // The node's own times stay in the latency message (one per bin: the last, which never
    // closes, when the node stops), on its wall clock.
    assert!(collector.wait_count(&keys.latency(), bins).await);
    let latency: Vec<BinLatency> = collector.decoded(&keys.latency());
    assert_eq!(latency.len(), bins);
    for l in &latency {
        let source = stamp_of_bin[&l.bin_id];
        assert!(l.first_frame_arrival_ns - source > -OFFSET_NS / 2, "{l:?}");
        assert!(l.publish_ns >= l.first_frame_arrival_ns);
    }

    // /tf: world -> left at every frame, at its stamp and pose.
    let tf: Vec<TfMessage> = collector.decoded(&keys.key(TF));
    assert_eq!(tf.len(), frames.len());
    for (msg, (stamp, pose)) in tf.iter().zip(&frames) {
        let [t] = msg.transforms.as_slice() else {
            panic!("one transform per /tf message: {msg:?}");
        };
        assert_eq!(
            (t.header.frame_id.as_str(), t.child_frame_id.as_str()),
            ("world", "left")
        );
        assert_eq!(t.header.stamp.to_nanos(), *stamp);
        assert!(same_pose(&affine_of(t), pose), "frame at {stamp}");
    }

    // /tf_static: the whole set each time; the last holds every bin, equal to its pose.
    let statics: Vec<TfMessage> = collector.decoded(&keys.key(TF_STATIC));
    let last = statics.last().expect("a /tf_static message");
    assert_eq!(last.transforms.len(), bins);
    for (t, pose) in last.transforms.iter().zip(&poses) {
        assert_eq!(t.header.frame_id, "world");
        let bin = bin_of_frame_id(&t.child_frame_id);
        assert_eq!(t.header.stamp.to_nanos(), stamp_of_bin[&bin]);
        let want = affine_from_pose(pose).unwrap();
        assert_eq!(affine_of(t).translation, want.translation, "bin {bin}");
        assert!(
            affine_of(t).matrix3.abs_diff_eq(want.matrix3, 1e-12),
            "bin {bin}"
        );
    }
    println!(
        "{bins} bins, {} frames on /tf, {} /tf_static messages",
        tf.len(),
        statics.len()
    );
}
