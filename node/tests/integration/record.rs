//! `record`, `replay --mcap` and `monitor` on real zenoh sessions over loopback: a drive of
//! known messages on the node's topics (inputs and outputs) is recorded, the recording is
//! replayed as fast as possible while a second recording runs, and both hold the same payloads
//! on the same topics in the same order; the Python `mcap` package and rosbags (types from
//! the file's schemas only) read the recording, and a YAML reader reads each channel's
//! `offered_qos_profiles` as the topic's QoS profile (tf2's for `/tf` and `/tf_static`); the
//! monitor's statistics of known latencies.

use crate::msg_support;
use crate::net_support::{self, sees_a_subscriber};

use std::future::Future;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use model::frame::Rgb8Image;
use node::bag::{BagReader, BagWriter, Rate};
use node::clients::channel_of;
use node::clients::monitor;
use node::clients::record;
use node::clients::replay_bag;
use node::clients::BagReplayOptions;
use node::clients::MonitorEvent;
use node::clients::RecordLimits;
use node::clients::RecordSummary;
use node::msg::compressed::{compressed_image, Compression};
use node::msg::latency::{BinLatency, Counter, Diagnostics};
use node::msg::schema::ros2msg;
use node::msg::sensor_msgs::Image;
use node::msg::std_msgs::Header;
use node::msg::{Message, MessageKind};
use node::transport::keys::{Topic, LATENCY, POSE, TOPICS};
use node::transport::ros2::{Durability, History};
use node::transport::Keys;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use zenoh::qos::CongestionControl;
use zenoh::Session;

/// A file in a fresh scratch folder of this test process.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("stereosplat-record-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// A valid message of `kind` (the test payloads must decode in the Python check), varied by
/// `rng`: images of random size and pixels, latencies and counters with random values.
fn payload(kind: MessageKind, i: usize, rng: &mut ChaCha8Rng) -> Vec<u8> {
    let samples = msg_support::samples();
    let stamp = 1_700_000_000_000_000_000 + i as i64 * 50_000_000;
    match kind {
        MessageKind::Image => {
            let (width, height) = (rng.random_range(1..200u32), rng.random_range(1..60u32));
            Image {
                header: Header::new(stamp, format!("frame_{i}")),
                height,
                width,
                encoding: "rgb8".into(),
                is_bigendian: 0,
                step: 3 * width,
                data: (0..3 * width * height).map(|_| rng.random()).collect(),
            }
            .encode()
        }
        MessageKind::BinLatency => BinLatency {
            bin_id: i as u64,
            publish_ns: stamp + rng.random_range(0..1_000_000_000),
            ..samples.latency
        }
        .encode(),
        MessageKind::Diagnostics => Diagnostics {
            stamp_ns: stamp,
            counters: vec![Counter {
                kind: "bad_message/pose".into(),
                count: rng.random(),
            }],
        }
        .encode(),
        MessageKind::CompressedImage => {
            let (width, height) = (rng.random_range(1..64u32), rng.random_range(1..32u32));
            let img = Rgb8Image {
                width,
                height,
                data: (0..3 * width * height).map(|_| rng.random()).collect(),
            };
            let header = Header::new(stamp, format!("frame_{i}"));
            compressed_image(&img, Compression::Jpeg { quality: 90 }, header)
                .expect("encodes")
                .encode()
        }
        MessageKind::CameraInfo => samples.camera_info.encode(),
        MessageKind::Odometry => samples.odometry.encode(),
        MessageKind::PoseStamped => samples.pose.encode(),
        MessageKind::PointCloud2 => samples.cloud.encode(),
        MessageKind::MapUpdate => samples.map_update.encode(),
        MessageKind::TfMessage => samples.tf.encode(),
        other => panic!("no topic carries {other:?}"),
    }
}

/// `count` messages on the node's topics, every topic at least once, in publishing order.
fn drive(seed: u64, count: usize) -> Vec<(Topic, Vec<u8>)> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..count)
        .map(|i| {
            let topic = match i < TOPICS.len() {
                true => TOPICS[i],
                false => TOPICS[rng.random_range(0..TOPICS.len())],
            };
            (topic, payload(topic.kind, i, &mut rng))
        })
        .collect()
}

/// Every message of a bag as (channel topic, payload), in log-time order.
fn contents(path: &Path) -> Vec<(String, Vec<u8>)> {
    let bag = BagReader::open(path).unwrap();
    bag.messages()
        .map(|m| {
            let m = m.unwrap();
            (m.channel.topic.clone(), m.payload)
        })
        .collect()
}

/// Records `count` messages of `keys` from `recorder` into `path` while `publish` runs (it
/// starts once `publisher` sees the recorder's subscriber on every topic). A 60 s stop
/// guards against a hang.
async fn record_while(
    recorder: &Session,
    publisher: &Session,
    keys: &Keys,
    path: &Path,
    count: usize,
    publish: impl Future<Output = ()>,
) -> RecordSummary {
    let limits = RecordLimits {
        duration: None,
        count: Some(count as u64),
    };
    let guard = tokio::time::sleep(Duration::from_secs(60));
    let publish = async {
        for (key, _) in keys.all() {
            assert!(
                sees_a_subscriber(publisher, &key).await,
                "the recorder on {key}"
            );
        }
        publish.await;
    };
    let (summary, ()) = tokio::join!(record(recorder, keys, path, limits, guard), publish);
    summary.unwrap()
}

/// Publishes `drive` under `keys`, and a message on a key outside the node's topics.
async fn publish_drive(player: &Session, keys: &Keys, drive: &[(Topic, Vec<u8>)]) {
    for (i, (topic, payload)) in drive.iter().enumerate() {
        if i == drive.len() / 2 {
            let stray = format!("{}/not_a_topic", keys.namespace);
            player.put(stray, vec![1, 2, 3]).await.unwrap();
        }
        player
            .put(keys.key(*topic), payload.clone())
            .congestion_control(CongestionControl::Block)
            .await
            .unwrap();
    }
}

/// Records a 60-message drive under namespace `ns` into `name`; returns the file and what
/// was published as (channel topic, payload).
async fn recorded_drive(
    recorder: &Session,
    player: &Session,
    ns: &str,
    name: &str,
) -> (PathBuf, Vec<(String, Vec<u8>)>) {
    let keys = Keys::new(ns);
    let drive = drive(7, 60);
    let path = scratch(name);
    let summary = record_while(
        recorder,
        player,
        &keys,
        &path,
        drive.len(),
        publish_drive(player, &keys, &drive),
    )
    .await;
    assert_eq!(summary.messages, drive.len() as u64, "{summary:?}");
    let published: Vec<(String, Vec<u8>)> = drive
        .into_iter()
        .map(|(t, p)| (channel_of(&keys, t).topic, p))
        .collect();
    for topic in TOPICS {
        let name = channel_of(&keys, topic).topic;
        let expected = published.iter().filter(|(t, _)| *t == name).count() as u64;
        assert_eq!(summary.per_topic.get(&name), Some(&expected), "{name}");
    }
    (path, published)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_recording_replayed_as_fast_as_possible_records_again_bit_for_bit() {
    let (recorder, player) = net_support::connected_pair().await;
    let keys = Keys::new("rec_bits");
    let (first, published) = recorded_drive(&recorder, &player, "rec_bits", "first.mcap").await;
    assert_eq!(contents(&first), published);

    // Channels as `channel_of` describes them; sequences count per channel from 1.
    let bag = BagReader::open(&first).unwrap();
    assert_eq!(bag.channels().len(), TOPICS.len());
    for channel in bag.channels() {
        let topic = TOPICS
            .into_iter()
            .find(|&t| channel.info.topic == channel_of(&keys, t).topic)
            .unwrap();
        assert_eq!(*channel.info, channel_of(&keys, topic));
    }
    let mut sequences = std::collections::BTreeMap::<String, Vec<u32>>::new();
    for m in bag.messages() {
        let m = m.unwrap();
        assert!(m.publish_time_ns > 0 && m.log_time_ns > 0);
        sequences
            .entry(m.channel.topic.clone())
            .or_default()
            .push(m.sequence);
    }
    for (topic, seq) in sequences {
        assert_eq!(seq, (1..=seq.len() as u32).collect::<Vec<_>>(), "{topic}");
    }

    let second = scratch("second.mcap");
    let options = BagReplayOptions {
        rate: Rate::AsFastAsPossible,
        inputs_only: false,
        recorded_namespace: None,
        topic_map: Vec::new(),
    };
    let replay = async {
        let summary = replay_bag(&player, &keys, &bag, &options, &mut |_, _| {})
            .await
            .unwrap();
        assert_eq!(summary.published, published.len() as u64);
        assert_eq!(summary.skipped_outputs, 0);
        assert!(summary.unknown_topics.is_empty());
    };
    let again = record_while(&recorder, &player, &keys, &second, published.len(), replay).await;
    assert_eq!(again.messages, published.len() as u64);
    assert_eq!(contents(&second), published);
}

/// Runs `scripts/mcap_check.py --decode` on `path` and parses its JSON.
fn python_check(path: &Path) -> serde_json::Value {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scripts/mcap_check.py");
    let output = Command::new("python3")
        .arg(script)
        .arg("--decode")
        .arg(path)
        .output()
        .expect("python3 must be installed to run scripts/mcap_check.py");
    assert!(
        output.status.success(),
        "scripts/mcap_check.py failed (if the Python `mcap` or `rosbags` package is missing: \
         pip install -r scripts/requirements.txt): {}",
        String::from_utf8_lossy(&output.stderr)
    );
    serde_json::from_slice(&output.stdout).expect("mcap_check.py prints JSON")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn python_mcap_and_rosbags_read_a_recording_with_its_schemas() {
    let (recorder, player) = net_support::connected_pair().await;
    let (path, published) = recorded_drive(&recorder, &player, "rec_py", "python.mcap").await;
    let seen = python_check(&path);
    assert_eq!(seen["profile"], "ros2");
    assert_eq!(seen["statistics_message_count"], published.len());
    let channels = seen["channels"].as_array().unwrap();
    let keys = Keys::new("rec_py");
    let mut expected: Vec<Topic> = TOPICS.to_vec();
    expected.sort_by_key(|&t| channel_of(&keys, t).topic);
    assert_eq!(channels.len(), expected.len());
    for (channel, topic) in channels.iter().zip(expected) {
        let name = channel_of(&keys, topic).topic;
        let count = published.iter().filter(|(t, _)| *t == name).count();
        assert_eq!(channel["topic"], name);
        assert_eq!(channel["message_encoding"], "cdr");
        assert_eq!(channel["schema_encoding"], "ros2msg");
        assert_eq!(channel["schema_name"], topic.kind.ros_name());
        assert_eq!(channel["schema_text"], ros2msg(topic.kind));
        assert_eq!(channel["message_count"], count, "{name}");
        // rosbag2's QoS YAML, as a YAML reader parses it: the topic's profile.
        let (history, depth) = match topic.qos.history {
            History::KeepLast(n) => ("keep_last", n),
            History::KeepAll => ("keep_all", 0),
        };
        let infinite = serde_json::json!({"sec": 9_223_372_036u64, "nsec": 854_775_807u64});
        let want = serde_json::json!([{
            "history": history, "depth": depth,
            "reliability": "reliable",
            "durability": match topic.qos.durability {
                Durability::Volatile => "volatile",
                Durability::TransientLocal => "transient_local",
            },
            "deadline": infinite, "lifespan": infinite, "liveliness": "automatic",
            "liveliness_lease_duration": infinite,
            "avoid_ros_namespace_conventions": false,
        }]);
        assert_eq!(channel["offered_qos"], want, "{name}");
        // rosbags, given nothing but this schema text, decodes every message.
        assert_eq!(channel["decode_error"], serde_json::Value::Null, "{name}");
        assert_eq!(channel["decoded"], count, "{name}");
    }
    let sha: Vec<&str> = seen["messages"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m["sha256"].as_str().unwrap())
        .collect();
    let expected_sha: Vec<String> = published
        .iter()
        .map(|(_, p)| {
            use sha2::Digest;
            format!("{:x}", sha2::Sha256::digest(p))
        })
        .collect();
    assert_eq!(sha, expected_sha);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn replay_maps_the_recorded_namespace_skips_outputs_and_unknown_topics() {
    let (receiver, player) = net_support::connected_pair().await;
    let old = Keys::new("old_ns");
    let new = Keys::new("new_ns");
    let path = scratch("mapped.mcap");
    let mut writer = BagWriter::create(&path).unwrap();
    let mut stray = channel_of(&old, TOPICS[0]);
    stray.topic = "/elsewhere/left/image".into();
    let t0 = 1_000_000_000;
    // Input, output, unknown, input: 1 ms apart.
    let rows = [
        (channel_of(&old, TOPICS[0]), vec![1u8, 1]),
        (channel_of(&old, LATENCY), vec![2, 2]),
        (stray, vec![3, 3]),
        (channel_of(&old, POSE), vec![4, 4]),
    ];
    for (i, (channel, payload)) in rows.iter().enumerate() {
        let t = t0 + i as u64 * 1_000_000;
        writer.write(channel, t, t, 1, payload).unwrap();
    }
    writer.finish().unwrap();

    let subscriber = receiver.declare_subscriber("**").await.unwrap();
    assert!(sees_a_subscriber(&player, &new.left_image()).await);
    let bag = BagReader::open(&path).unwrap();
    let options = BagReplayOptions {
        rate: Rate::Recorded,
        inputs_only: true,
        recorded_namespace: Some("old_ns".into()),
        topic_map: Vec::new(),
    };
    let mut progress = Vec::new();
    let summary = replay_bag(&player, &new, &bag, &options, &mut |done, total| {
        progress.push((done, total))
    })
    .await
    .unwrap();
    assert_eq!(summary.published, 2);
    assert_eq!(summary.skipped_outputs, 1);
    assert_eq!(
        summary.unknown_topics,
        [("/elsewhere/left/image".to_string(), 1)].into()
    );
    assert_eq!(progress, [(1, 4), (2, 4), (3, 4), (4, 4)]);
    let mut received = Vec::new();
    while received.len() < 2 {
        let sample = tokio::time::timeout(Duration::from_secs(10), subscriber.recv_async())
            .await
            .expect("both inputs arrive")
            .unwrap();
        received.push((
            sample.key_expr().to_string(),
            sample.payload().to_bytes().into_owned(),
        ));
    }
    assert_eq!(
        received,
        [(new.left_image(), vec![1, 1]), (new.pose(), vec![4, 4])]
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn monitor_summarises_known_latencies() {
    let (watcher, node) = net_support::connected_pair().await;
    let keys = Keys::new("mon");
    const MS: i64 = 1_000_000;
    let t0 = 1_700_000_000_000 * MS;
    // Bin i: wait 2 ms, model 100 + 10 i ms, no renders, published 1 ms after the model,
    // closed 500 ms after its first frame; queue depth i, 3 drops and i bad messages so far.
    let bins: Vec<BinLatency> = (0..5)
        .map(|i| {
            let arrival = t0 + i * 1000 * MS;
            let model_end = arrival + (2 + 100 + 10 * i) * MS;
            BinLatency {
                bin_id: i as u64,
                first_frame_arrival_ns: arrival,
                bin_close_ns: arrival + 500 * MS,
                model_start_ns: arrival + 2 * MS,
                model_end_ns: model_end,
                render_end_ns: model_end,
                publish_ns: model_end + MS,
                queue_depth: i as u32,
                drops: 3,
                bad_messages: i as u64,
                ..BinLatency::default()
            }
        })
        .collect();
    let diagnostics = Diagnostics {
        stamp_ns: t0,
        counters: vec![Counter {
            kind: "sync/late".into(),
            count: 4,
        }],
    };
    let publish = async {
        for key in [keys.latency(), keys.diagnostics()] {
            assert!(sees_a_subscriber(&node, &key).await, "the monitor on {key}");
        }
        node.put(keys.latency(), vec![0, 1, 0, 0, 7]).await.unwrap();
        node.put(keys.diagnostics(), diagnostics.encode())
            .await
            .unwrap();
        for b in &bins {
            node.put(keys.latency(), b.encode()).await.unwrap();
        }
    };
    let mut events = Vec::new();
    let watch = monitor(
        &watcher,
        &keys,
        Some(5),
        tokio::time::sleep(Duration::from_secs(60)),
        |event, stats| events.push((event.clone(), stats.bins())),
    );
    let (report, ()) = tokio::join!(watch, publish);
    let report = report.unwrap();
    assert_eq!(report.undecodable, 1);
    assert_eq!(report.diagnostics.as_ref(), Some(&diagnostics));
    assert_eq!(events.len(), 7);
    assert_eq!(
        events[0].0,
        MonitorEvent::Undecodable {
            key: keys.latency()
        }
    );
    assert_eq!(events[6], (MonitorEvent::Bin(bins[4].clone()), 5));

    let s = report.stats.summary();
    assert_eq!(s.bins, 5);
    let model = s.model.unwrap();
    // Model times 100, 110, 120, 130, 140 ms: nearest ranks 3, 5, 5.
    assert_eq!(
        (model.count, model.p50_ms, model.p90_ms, model.p99_ms),
        (5, 120.0, 140.0, 140.0)
    );
    assert_eq!((model.max_ms, model.mean_ms), (140.0, 120.0));
    let total = s.arrival_to_publish.unwrap();
    assert_eq!(
        (total.p50_ms, total.max_ms, total.mean_ms),
        (123.0, 143.0, 123.0)
    );
    assert_eq!(s.wait.unwrap().p99_ms, 2.0);
    assert_eq!(s.render.unwrap().max_ms, 0.0);
    // Published 397, 387, ..., 357 ms before the bin closed.
    let margin = s.before_close_margin.unwrap();
    assert_eq!((margin.p50_ms, margin.min_ms), (377.0, 357.0));
    assert_eq!((s.max_queue_depth, s.drops, s.bad_messages), (4, 3, 4));
    let json = serde_json::to_value(s).unwrap();
    assert_eq!(json["model"]["p90_ms"], 140.0);
}
