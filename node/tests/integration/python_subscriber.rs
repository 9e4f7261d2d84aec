//! Live interop with software independent of this code base, so that a CDR reader the node's
//! authors did not write decodes what it publishes: while a generated drive is replayed into an
//! in-process node, `scripts/zenoh_listen.py` subscribes to the node's namespace through the
//! Python `eclipse-zenoh` package (its own zenoh implementation of the wire protocol, as a peer
//! connected to the node's endpoint) and decodes every sample with `rosbags`' CDR deserializer
//! (ROS 2 Jazzy types plus the node's messages from node/src/msg/*.msg). A Rust subscriber
//! listens to the same run.
//!
//! Checked: both saw the same output keys with the same message counts and Python decoded every
//! sample; the bin maps have the same widths, frames and fields (the 3DGS PLY names plus
//! `confidence` and the packed `rgb`, 64-byte points) and the same first point; the bin poses
//! are the same f64 bits; latency arrived for every closed bin with the same values; the
//! diagnostics counters and any map updates and images agree.
//!
//! Needs `python3` with the packages of `scripts/requirements.txt`; without them the test fails
//! and says how to install them.

use crate::drive_support;
use crate::python_support;

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader, Read};
use std::process::{Child, ChildStdout, Command, Stdio};

use drive_support::{Collector, Drive, Player, RunningNode};
use model::synth::SynthConfig;
use node::bag::Rate;
use node::clients::replay;
use node::msg::gaussians::{records_from_cloud, FIELD_NAMES, RGB_FIELD};
use node::msg::geometry_msgs::PoseStamped;
use node::msg::latency::{BinLatency, Diagnostics};
use node::msg::map_update::MapUpdate;
use node::msg::sensor_msgs::{Image, PointCloud2};
use node::msg::MessageKind;
use node::service::NodeConfig;
use node::transport::keys::Direction;
use node::transport::Keys;
use serde_json::Value;

const SCRIPT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../scripts/zenoh_listen.py");

/// The Python listener, started and subscribed.
struct PyListener {
    child: Child,
    stdout: BufReader<ChildStdout>,
}

impl PyListener {
    /// Starts the script connected to `endpoint`, subscribed to `<namespace>/**`, and waits
    /// for its `ready` line. Blocking.
    fn start(endpoint: &str, namespace: &str) -> Self {
        python_support::require("zenoh, rosbags, numpy");
        let mut child = Command::new("python3")
            .arg(SCRIPT)
            .args(["--connect", endpoint, "--namespace", namespace])
            .args(["--until-eof", "--timeout", "300"])
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("python3 starts");
        let mut stdout = BufReader::new(child.stdout.take().expect("stdout"));
        let mut line = String::new();
        stdout
            .read_line(&mut line)
            .expect("the script's first line");
        if line.trim().is_empty() {
            let mut err = String::new();
            let _ = child
                .stderr
                .take()
                .expect("stderr")
                .read_to_string(&mut err);
            panic!("zenoh_listen.py did not start:\n{err}");
        }
        let ready: Value = serde_json::from_str(&line).expect("a JSON ready line");
        assert_eq!(ready["ready"], true, "{line}");
        Self { child, stdout }
    }

    /// Closes the script's stdin (it stops listening) and returns its summary. Blocking.
    fn finish(mut self) -> Value {
        drop(self.child.stdin.take());
        let mut rest = String::new();
        self.stdout.read_to_string(&mut rest).expect("summary read");
        let mut err = String::new();
        let _ = self
            .child
            .stderr
            .take()
            .expect("stderr")
            .read_to_string(&mut err);
        let status = self.child.wait().expect("script exits");
        assert!(status.success(), "zenoh_listen.py failed:\n{err}");
        serde_json::from_str(rest.trim()).unwrap_or_else(|e| panic!("summary JSON ({e}): {rest}"))
    }
}

fn u64s(v: &Value) -> Vec<u64> {
    v.as_array()
        .expect("a JSON array")
        .iter()
        .map(|x| x.as_u64().expect("an integer"))
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_python_zenoh_subscriber_decodes_with_rosbags_what_a_rust_subscriber_decodes() {
    let drive = Drive::generate(
        "pysub",
        &SynthConfig {
            seed: 11,
            frames: 40,
            width: 136,
            height: 40,
            lidar_azimuth_steps: 64,
            ..SynthConfig::default()
        },
    );
    let opened = drive.bins_opened(8.0);
    assert!(opened >= 3, "{opened} bins");
    let ns = "pysub_ns";
    let keys = Keys::new(ns);
    let node = RunningNode::start(NodeConfig {
        keys: keys.clone(),
        queue_capacity: 64,
        out_dir: Some(drive.dir("out")),
        // Diagnostics only with the bins: a timer's tick can fall before one subscriber has
        // matched and after the other has, and this test compares exact counts per key.
        diagnostics_every: std::time::Duration::ZERO,
        ..NodeConfig::default()
    })
    .await;
    let outputs: Vec<String> = keys
        .all()
        .into_iter()
        .filter(|(_, t)| t.direction == Direction::Output)
        .map(|(k, _)| k)
        .collect();
    let rust = Collector::connect(&node, &outputs).await;
    let endpoint = node.endpoint.clone();
    let python = tokio::task::spawn_blocking(move || PyListener::start(&endpoint, ns))
        .await
        .unwrap();
    // Let the Python subscription reach the node.
    tokio::time::sleep(std::time::Duration::from_millis(1000)).await;

    let player = Player::connect(&node).await;
    player.camera_infos(&drive.rig, drive.frames[0].0).await;
    let replayed = replay(
        &player.session,
        &keys,
        &drive.sequence,
        Rate::Factor(10.0),
        &mut |_, _| {},
    )
    .await
    .unwrap();
    assert_eq!(replayed.frames as usize, drive.frames.len());
    // Stop only once the last bin is out: what the node publishes while it shuts down does
    // not always reach every subscriber (seen: the last bin pose reached the Rust subscriber
    // but not the Python one), which is not what this test is about.
    assert!(rust.wait_count(&keys.bin_pose(), opened).await);
    let summary = node.stop().await;
    tokio::time::sleep(std::time::Duration::from_millis(500)).await;
    let py = tokio::task::spawn_blocking(move || python.finish())
        .await
        .unwrap();
    assert_eq!(summary.bins_published, opened as u64, "{summary:?}");

    // The same keys, the same counts, everything decoded by rosbags.
    let mut rust_counts = BTreeMap::new();
    for (key, _) in rust.all() {
        *rust_counts.entry(key).or_insert(0u64) += 1;
    }
    let py_keys = py["keys"].as_object().expect("keys");
    let py_counts: BTreeMap<String, u64> = py_keys
        .iter()
        .filter(|(k, _)| outputs.contains(k))
        .map(|(k, v)| (k.clone(), v["count"].as_u64().unwrap()))
        .collect();
    // What the node publishes while it stops (the drive's last bin's latency and the counters
    // after it) may reach one subscriber and not the other: those two keys are compared on
    // what both got before the stop, every other key exactly.
    let stopping = [keys.latency(), keys.diagnostics()];
    let before_stop = |counts: &BTreeMap<String, u64>| -> BTreeMap<String, u64> {
        counts
            .iter()
            .filter(|(k, _)| !stopping.contains(k))
            .map(|(k, v)| (k.clone(), *v))
            .collect()
    };
    assert_eq!(
        before_stop(&py_counts),
        before_stop(&rust_counts),
        "samples per output key"
    );
    for (key, entry) in py_keys {
        assert_eq!(
            entry["errors"],
            Value::Array(vec![]),
            "{key}: rosbags errors"
        );
        assert_eq!(
            entry["messages"].as_array().unwrap().len() as u64,
            entry["count"].as_u64().unwrap(),
            "{key}: every sample decoded"
        );
    }
    let py_key = |k: &str| &py_keys.get(k).unwrap_or_else(|| panic!("python saw {k}"))["messages"];

    // Bin maps: frames, widths, the 3DGS fields plus confidence, and the first point.
    let maps: Vec<PointCloud2> = rust.decoded(&keys.bin_map());
    assert_eq!(maps.len(), opened);
    let py_maps = py_key(&keys.bin_map()).as_array().unwrap();
    assert_eq!(py_maps.len(), maps.len());
    for (m, p) in maps.iter().zip(py_maps) {
        assert_eq!(p["frame_id"], m.header.frame_id.as_str());
        assert_eq!(p["width"].as_u64(), Some(m.width as u64));
        assert!(m.width > 500, "{} Gaussians", m.width);
        assert_eq!(p["height"], 1);
        assert_eq!(p["point_step"], 64);
        let fields: Vec<&str> = p["fields"]
            .as_array()
            .unwrap()
            .iter()
            .map(|f| f.as_str().unwrap())
            .collect();
        assert_eq!(fields[..FIELD_NAMES.len()], FIELD_NAMES);
        assert_eq!(fields[FIELD_NAMES.len()..], [RGB_FIELD]);
        let first = records_from_cloud(m).unwrap()[0];
        for (name, value) in FIELD_NAMES.iter().zip(first) {
            assert_eq!(p["first_point"][name].as_f64(), Some(value), "{name}");
        }
    }

    // Bin poses: the same f64 bits.
    let poses: Vec<PoseStamped> = rust.decoded(&keys.bin_pose());
    let py_poses = py_key(&keys.bin_pose()).as_array().unwrap();
    assert_eq!(poses.len(), opened);
    assert_eq!(py_poses.len(), poses.len());
    for (r, p) in poses.iter().zip(py_poses) {
        let q = r.pose.position;
        assert_eq!(
            u64s(&p["position_bits"]),
            [q.x.to_bits(), q.y.to_bits(), q.z.to_bits()]
        );
        assert_eq!(p["frame_id"], r.header.frame_id.as_str());
    }

    // Latency: every closed bin, every field (the last bin's comes while the node stops).
    let lat: Vec<BinLatency> = rust.decoded(&keys.latency());
    let lat: Vec<BinLatency> = lat
        .into_iter()
        .filter(|l| l.bin_id < opened as u64 - 1)
        .collect();
    let closed: Vec<u64> = (0..opened as u64 - 1).collect();
    assert_eq!(lat.iter().map(|l| l.bin_id).collect::<Vec<_>>(), closed);
    let py_lat = py_key(&keys.latency()).as_array().unwrap();
    assert!(
        py_lat.len() >= lat.len(),
        "{} < {}",
        py_lat.len(),
        lat.len()
    );
    for (r, p) in lat.iter().zip(py_lat) {
        let fields = [
            ("bin_id", r.bin_id as i128),
            ("first_frame_arrival_ns", r.first_frame_arrival_ns as i128),
            ("bin_close_ns", r.bin_close_ns as i128),
            ("model_start_ns", r.model_start_ns as i128),
            ("model_end_ns", r.model_end_ns as i128),
            ("render_end_ns", r.render_end_ns as i128),
            ("publish_ns", r.publish_ns as i128),
            ("queue_depth", r.queue_depth as i128),
            ("drops", r.drops as i128),
            ("bad_messages", r.bad_messages as i128),
            ("check_verdict", r.check_verdict as i128),
            ("check_action", r.check_action as i128),
            ("fallback_verdict", r.fallback_verdict as i128),
            ("check_samples", r.check_samples as i128),
            ("base_end_ns", r.base_end_ns as i128),
            ("pseudo_render_end_ns", r.pseudo_render_end_ns as i128),
            ("enhance_end_ns", r.enhance_end_ns as i128),
            ("plus_end_ns", r.plus_end_ns as i128),
            ("fuse_end_ns", r.fuse_end_ns as i128),
            ("map_fused_ns", r.map_fused_ns as i128),
        ];
        for (name, value) in fields {
            assert_eq!(p[name].as_i64().map(i128::from), Some(value), "{name}");
        }
        assert_eq!(p["check_score"].as_f64(), Some(r.check_score));
        assert_eq!(p["fallback_score"].as_f64(), Some(r.fallback_score));
        assert_eq!(
            p["operating_point"].as_str(),
            Some(r.operating_point.as_str())
        );
    }

    // Diagnostics: the same counters.
    let diag: Vec<Diagnostics> = rust.decoded(&keys.diagnostics());
    let py_diag = py_key(&keys.diagnostics()).as_array().unwrap();
    assert_eq!(py_diag.len(), diag.len());
    for (r, p) in diag.iter().zip(py_diag) {
        let counters: BTreeMap<String, u64> = r
            .counters
            .iter()
            .map(|c| (c.kind.clone(), c.count))
            .collect();
        let py_counters: BTreeMap<String, u64> = p["counters"]
            .as_object()
            .unwrap()
            .iter()
            .map(|(k, v)| (k.clone(), v.as_u64().unwrap()))
            .collect();
        assert_eq!(py_counters, counters);
    }

    // Outputs the node may or may not publish yet (map updates, renders): when there are
    // some, both sides agree on them too.
    for (key, topic) in keys.all() {
        let Some(entry) = py_keys.get(&key) else {
            continue;
        };
        let messages = entry["messages"].as_array().unwrap();
        match topic.kind {
            MessageKind::MapUpdate => {
                let r: Vec<MapUpdate> = rust.decoded(&key);
                let seq: Vec<u64> = r.iter().map(|m| m.sequence).collect();
                assert_eq!(u64s(&entry["sequences"]), seq, "{key}");
                let ids: Vec<u64> = r.iter().map(|m| m.ids.len() as u64).collect();
                assert_eq!(u64s(&entry["id_counts"]), ids, "{key}");
            }
            MessageKind::Image => {
                let r: Vec<Image> = rust.decoded(&key);
                for (m, p) in r.iter().zip(messages) {
                    assert_eq!(p["width"].as_u64(), Some(m.width as u64), "{key}");
                    assert_eq!(p["height"].as_u64(), Some(m.height as u64), "{key}");
                    assert_eq!(p["encoding"], m.encoding.as_str(), "{key}");
                }
            }
            _ => {}
        }
    }
    println!(
        "python decoded {} samples on {} keys: {:?}",
        py["samples"],
        py_counts.len(),
        py_counts
    );
}
