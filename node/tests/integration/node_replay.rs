//! The streaming node end to end on real zenoh sessions over loopback: a generated drive is
//! replayed into a running node (SGM reconstructor) while a third session listens to the
//! outputs. Every bin's map and renders arrive and decode, latency arrives for every bin (the
//! drive's last, which never closes, when the node stops), the global map's increments add up
//! to its snapshots (periodic and requested), a malformed message is counted without stopping
//! the node, and the global map is exported.

use crate::net_support;

use std::time::Duration;

use model::bins::{make_bins, BinConfig, BinLayout};
use model::generate::write_synthetic;
use model::kitti360::Sequence;
use model::synth::SynthConfig;
use node::bag::Rate;
use node::clients::replay;
use node::fusion::FusionConfig;
use node::fusion::{decode_update, MapReplica, Snapshot, Update};
use node::msg::gaussians::gaussians_from_cloud;
use node::msg::latency::BinLatency;
use node::msg::map_update::MapUpdate;
use node::msg::sensor_msgs::{Image, PointCloud2};
use node::msg::Message;
use node::pipeline::binner::BinnerConfig;
use node::pipeline::sync::SyncConfig;
use node::pipeline::worker::RenderWith;
use node::service::{run_announced, NodeConfig};
use node::transport::Keys;
use node::transport::{open, TransportConfig};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_replayed_drive_comes_out_as_bin_maps_latency_and_a_global_map() {
    let root = std::env::temp_dir().join(format!("stereosplat-node-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&root);
    let config = SynthConfig {
        seed: 11,
        frames: 60,
        width: 136,
        height: 40,
        ..SynthConfig::default()
    };
    let name = write_synthetic(&root.join("data"), &config, &mut |_, _| {}).unwrap();
    let sequence = Sequence::open(&root.join("data"), &name).unwrap();
    let poses: Vec<_> = sequence.frames().iter().map(|f| f.left_to_world).collect();
    let closed = make_bins(
        &poses,
        &BinConfig {
            length_m: 8.0,
            layout: BinLayout::Consecutive,
        },
    )
    .len();
    assert!(closed >= 3, "{closed} bins");

    let endpoint = format!("tcp/127.0.0.1:{}", net_support::free_port());
    let keys = Keys::new("test_ns");
    let node_config = NodeConfig {
        transport: TransportConfig {
            listen: vec![endpoint.clone()],
            ..TransportConfig::default()
        },
        keys: keys.clone(),
        sync: SyncConfig::default(),
        binner: BinnerConfig::default(),
        queue_capacity: 64,
        method: "sgm".into(),
        fusion: FusionConfig::default(),
        out_dir: Some(root.join("out")),
        snapshot_every: 2,
        renders: RenderWith::Cpu,
        ..NodeConfig::default()
    };
    let (stop_tx, stop_rx) = tokio::sync::oneshot::channel::<()>();
    let (ready_tx, ready_rx) = tokio::sync::oneshot::channel::<zenoh::Session>();
    let node = tokio::spawn(run_announced(
        node_config,
        async {
            let _ = stop_rx.await;
        },
        move |session| {
            let _ = ready_tx.send(session.clone());
        },
    ));
    let node_session = ready_rx.await.expect("the node is ready");

    let client = TransportConfig {
        connect: vec![endpoint],
        ..TransportConfig::default()
    };
    let listener = open(&client).await.unwrap();
    let maps = listener.declare_subscriber(keys.bin_map()).await.unwrap();
    let latency = listener.declare_subscriber(keys.latency()).await.unwrap();
    let updates = listener
        .declare_subscriber(keys.map_update())
        .await
        .unwrap();
    let renders = listener
        .declare_subscriber(keys.bin_render())
        .await
        .unwrap();
    let bevs = listener.declare_subscriber(keys.map_bev()).await.unwrap();
    let player = open(&client).await.unwrap();
    for key in [
        keys.bin_map(),
        keys.latency(),
        keys.map_update(),
        keys.bin_render(),
        keys.map_bev(),
    ] {
        assert!(
            net_support::sees_a_subscriber(&node_session, &key).await,
            "{key}"
        );
    }
    assert!(net_support::sees_a_subscriber(&player, &keys.left_image()).await);

    // A malformed message on an input key first: counted, the node keeps going.
    player
        .put(keys.left_image(), vec![0u8, 1, 0, 0, 9])
        .await
        .unwrap();
    let replayed = replay(&player, &keys, &sequence, Rate::Factor(4.0), &mut |_, _| {})
        .await
        .unwrap();
    assert_eq!(replayed.frames, 60);
    tokio::time::sleep(Duration::from_secs(2)).await;
    let requested = requested_snapshot(&listener, &keys).await;
    stop_tx.send(()).unwrap();
    let summary = node.await.unwrap().unwrap();

    // Every closed bin plus the one still open when the drive ended.
    assert_eq!(summary.bins_published, closed as u64 + 1, "{summary:?}");
    assert_eq!(summary.counters.get("bad_message/left_image"), 1);
    assert_eq!(summary.counters.get("dropped/worker_queue"), 0);
    let mut received = 0;
    while let Ok(Some(s)) = maps.try_recv() {
        let cloud = PointCloud2::decode(&s.payload().to_bytes()).unwrap();
        let set = gaussians_from_cloud(&cloud, glam::DVec3::ZERO).unwrap();
        assert!(set.len() > 500, "{} Gaussians", set.len());
        received += 1;
    }
    assert_eq!(received, summary.bins_published);
    // One latency message per published bin: the last bin of the drive never closes, so
    // its message comes when the node stops, without a close stamp.
    let mut latencies = Vec::new();
    let deadline = std::time::Instant::now() + Duration::from_secs(10);
    while latencies.len() < closed + 1 && std::time::Instant::now() < deadline {
        match latency.try_recv() {
            Ok(Some(s)) => latencies.push(BinLatency::decode(&s.payload().to_bytes()).unwrap()),
            _ => tokio::time::sleep(Duration::from_millis(20)).await,
        }
    }
    assert_eq!(latencies.len(), closed + 1, "one per published bin");
    for l in &latencies {
        assert!(l.first_frame_arrival_ns <= l.model_start_ns);
        assert!(l.model_start_ns <= l.model_end_ns && l.model_end_ns <= l.publish_ns);
    }
    let (last, closed_bins) = latencies.split_last().unwrap();
    assert!(closed_bins
        .iter()
        .all(|l| l.bin_close_ns >= l.first_frame_arrival_ns));
    assert_eq!(
        last.bin_close_ns, 0,
        "the drive's last bin never closed: {last:?}"
    );
    assert!(summary.global_gaussians > 1000);

    // Increments applied in order give every periodic snapshot and the requested one.
    let mut replica = MapReplica::new();
    let (mut last_seq, mut snapshots) = (0, 0);
    while let Ok(Some(s)) = updates.try_recv() {
        let msg = MapUpdate::decode(&s.payload().to_bytes()).unwrap();
        match decode_update(&msg).unwrap() {
            Update::Increment(inc) => {
                assert_eq!(msg.sequence, last_seq + 1, "increments in order");
                last_seq = msg.sequence;
                replica.apply(&inc).unwrap();
            }
            Update::Snapshot(snap) => {
                assert_eq!(msg.sequence, last_seq);
                assert_eq!(snap.gaussians, replica.snapshot().gaussians);
                snapshots += 1;
            }
        }
    }
    assert_eq!(last_seq, summary.bins_published);
    assert_eq!(snapshots, summary.bins_published / 2);
    assert_eq!(replica.len(), summary.global_gaussians);
    assert_eq!(requested.gaussians, replica.snapshot().gaussians);

    // One render of the input view and one bird's-eye view per bin.
    let mut n_renders = 0;
    while let Ok(Some(s)) = renders.try_recv() {
        let img = Image::decode(&s.payload().to_bytes()).unwrap();
        assert_eq!((img.width, img.height), (136, 40));
        n_renders += 1;
    }
    assert_eq!(n_renders, summary.bins_published);
    let mut n_bev = 0;
    while let Ok(Some(s)) = bevs.try_recv() {
        let img = Image::decode(&s.payload().to_bytes()).unwrap();
        assert_eq!(
            (img.width, img.height, img.encoding.as_str()),
            (256, 256, "rgb8")
        );
        assert!(img.data.iter().any(|&b| b > 0), "the map shows from above");
        n_bev += 1;
    }
    assert_eq!(n_bev, summary.bins_published);
    for f in ["global_map.ply", "global_map_bev.png", "global_map.ssgmap"] {
        assert!(root.join("out").join(f).exists(), "{f}");
    }
    let _ = std::fs::remove_dir_all(&root);
}

/// The snapshot the node answers a query with.
async fn requested_snapshot(session: &zenoh::Session, keys: &Keys) -> Snapshot {
    let replies = session.get(keys.snapshot_request()).await.unwrap();
    let reply = replies.recv_async().await.expect("the node answers");
    let sample = reply.result().expect("a snapshot, not an error");
    let msg = MapUpdate::decode(&sample.payload().to_bytes()).unwrap();
    assert!(msg.snapshot);
    match decode_update(&msg).unwrap() {
        Update::Snapshot(s) => s,
        Update::Increment(_) => unreachable!("asserted a snapshot above"),
    }
}
