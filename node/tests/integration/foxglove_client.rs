//! The node live in Foxglove, checked by a client no one here wrote: `tests/foxglove/client.mjs`
//! runs `@foxglove/ws-protocol`'s client (Node.js, on the `ws` WebSocket), subscribes to
//! every channel the node's Foxglove server advertises and decodes every message with
//! protobufjs from `@foxglove/schemas`' own definitions (and, agreeing, from the schema the
//! server advertised). A real node (SGM, CPU renders) runs in this process on loopback while
//! a generated drive is fed to it; a zenoh subscriber listens beside.
//!
//! Checked against what the node published on zenoh: one `foxglove.PointCloud` per bin map
//! with as many points, the same positions, and colours within 1/255 of the map's SH DC
//! colour (`0.5 + SH_C0 * f_dc`, clamped); the bin frames' `foxglove.FrameTransforms` equal
//! the bin poses, the camera's equal the drive's poses; the renders are the same bytes, the
//! input images the drive's; the fused map's new points add up to the map's size. A client
//! that stops reading and one that leaves mid-stream cost the node no bin, and one that stops
//! reading under a stream larger than the kernel's socket buffers gets only what its
//! bounded queue and those buffers held. Without a drive:
//! empty and one-Gaussian maps, colours outside [0, 1], NaN, and points 1e5 m from the
//! origin, through the same client; an address in use is a clear error.
//!
//! `npm ci` in `tests/foxglove` (`.ci/setup`) installs the client's packages; without them
//! (or without Node.js) the test fails and says so.

use crate::drive_support;

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader};
use std::net::SocketAddr;
use std::path::Path;
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc;
use std::time::Duration;

use drive_support::{bin_of_frame_id, free_port, Collector, Drive, Player, RunningNode};
use glam::{DAffine3, DQuat, DVec3, Quat, Vec3};
use node::foxglove::{Foxglove, FoxgloveConfig, FoxgloveError};
use node::fusion::{GaussianId, WorldGaussian};
use node::msg::gaussians::gaussians_from_cloud;
use node::msg::geometry_msgs::PoseStamped;
use node::msg::pose::affine_from_pose;
use node::msg::sensor_msgs::{Image, PointCloud2};
use node::pipeline::worker::RenderWith;
use node::service::{NodeConfig, ServiceError};
use node::transport::Keys;
use renderer::GaussianSet;
use serde_json::Value;
use sha2::{Digest, Sha256};

fn client_dir() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../tests/foxglove"))
}

/// Panics with what to install when Node.js or the client's packages are missing.
fn require_client() {
    let node = Command::new("node")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    let modules = [
        "@foxglove/ws-protocol",
        "@foxglove/schemas",
        "protobufjs",
        "ws",
    ]
    .iter()
    .all(|m| client_dir().join("node_modules").join(m).is_dir());
    assert!(
        node && modules,
        "the Foxglove test needs Node.js and tests/foxglove/node_modules: run `bash .ci/setup`"
    );
}

/// One client process and its JSON lines.
struct Client {
    child: Child,
    stdin: Option<ChildStdin>,
    lines: mpsc::Receiver<Value>,
    seen: Vec<Value>,
}

impl Client {
    /// Starts `client.mjs` in `mode` on `url` and waits until it subscribed to the
    /// advertised channels; returns it with the channels as `(topic, schema)`.
    fn start(url: &str, mode: &str) -> (Self, Vec<(String, String)>) {
        let mut child = Command::new("node")
            .arg(client_dir().join("client.mjs"))
            .args(["--url", url, "--mode", mode])
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("node client.mjs starts");
        let stdout = BufReader::new(child.stdout.take().unwrap());
        let (tx, lines) = mpsc::channel();
        std::thread::spawn(move || {
            for line in stdout.lines().map_while(Result::ok) {
                let v: Value = serde_json::from_str(&line).expect("the client prints JSON");
                let _ = tx.send(v);
            }
        });
        let stdin = child.stdin.take();
        let mut client = Self {
            child,
            stdin,
            lines,
            seen: Vec::new(),
        };
        let subscribed = client.wait(|v| v["event"] == "subscribed");
        let channels = subscribed["channels"]
            .as_array()
            .unwrap()
            .iter()
            .map(|c| (c[0].as_str().unwrap().into(), c[1].as_str().unwrap().into()))
            .collect();
        // The subscriptions reach the server after the client sent them.
        std::thread::sleep(Duration::from_millis(500));
        (client, channels)
    }

    /// Waits (two minutes at most, a guard against hanging) for a line that `done` accepts.
    fn wait(&mut self, done: impl Fn(&Value) -> bool) -> Value {
        loop {
            match self.lines.recv_timeout(Duration::from_secs(120)) {
                Ok(v) if done(&v) => return v,
                Ok(v) => self.seen.push(v),
                Err(e) => panic!(
                    "the client went quiet ({e}) after {} lines",
                    self.seen.len()
                ),
            }
        }
    }

    /// Messages so far on `topic` (the lines read by [`Client::wait`] and any waiting).
    fn messages(&mut self, topic: &str) -> Vec<Value> {
        while let Ok(v) = self.lines.try_recv() {
            self.seen.push(v);
        }
        self.seen
            .iter()
            .filter(|v| v["event"] == "message" && v["topic"] == topic)
            .cloned()
            .collect()
    }

    /// Waits until `n` messages arrived on `topic`.
    fn wait_messages(&mut self, topic: &str, n: usize) {
        while self.messages(topic).len() < n {
            let v = self.wait(|_| true);
            self.seen.push(v);
        }
    }

    /// Closes its stdin and returns its summary line.
    fn finish(mut self) -> (Value, Vec<Value>) {
        drop(self.stdin.take());
        let summary = self.wait(|v| v["event"] == "summary");
        let _ = self.child.wait();
        let errors = summary["errors"].as_array().unwrap();
        assert!(errors.is_empty(), "the client's errors: {errors:?}");
        (summary, std::mem::take(&mut self.seen))
    }
}

impl Drop for Client {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn stamp_ns(v: &Value) -> i64 {
    v[0].as_i64().unwrap() * 1_000_000_000 + v[1].as_i64().unwrap()
}

fn f64s(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap_or(f64::NAN))
        .collect()
}

/// A transform line's child pose in the world.
fn pose_of(t: &Value) -> DAffine3 {
    let (p, q) = (f64s(&t["t"]), f64s(&t["q"]));
    DAffine3::from_rotation_translation(
        DQuat::from_xyzw(q[0], q[1], q[2], q[3]),
        DVec3::new(p[0], p[1], p[2]),
    )
}

/// The largest difference between two poses' matrices and translations.
fn pose_error(a: &DAffine3, b: &DAffine3) -> f64 {
    let m = (a.matrix3 - b.matrix3).to_cols_array();
    let r = m.iter().fold(0.0f64, |e, x| e.max(x.abs()));
    r.max((a.translation - b.translation).abs().max_element())
}

fn sha256(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// Checks a cloud line against the map it came from: same count, positions, and colours
/// within 1/255 of the clamped SH DC colour.
fn assert_cloud_is(cloud: &Value, set: &GaussianSet) {
    assert_eq!(cloud["count"].as_u64().unwrap() as usize, set.len());
    let (xyz, rgba) = (f64s(&cloud["xyz"]), f64s(&cloud["rgba"]));
    for (i, mean) in set.means.iter().enumerate() {
        for (k, want) in [mean.x, mean.y, mean.z].into_iter().enumerate() {
            assert!(
                xyz[3 * i + k] as f32 == want || (want.is_nan() && xyz[3 * i + k].is_nan()),
                "point {i}: {} against {want}",
                xyz[3 * i + k]
            );
        }
        let c = set.colors[i];
        for (k, dc) in [c.x, c.y, c.z, set.opacities[i]].into_iter().enumerate() {
            let want = if dc.is_nan() { 0.0 } else { dc.clamp(0.0, 1.0) };
            let got = rgba[4 * i + k] / 255.0;
            assert!(
                (got - want as f64).abs() <= 1.0 / 255.0,
                "point {i} channel {k}: {got} against {want}"
            );
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_foxglove_client_decodes_the_live_node_and_a_stalled_one_costs_no_bin() {
    require_client();
    let drive = Drive::small("foxglove");
    let bins = drive.bins_opened(8.0);
    assert!(bins >= 3, "{bins} bins");
    let port = free_port();
    let keys = Keys::new("fox");
    let node = RunningNode::start(NodeConfig {
        keys: keys.clone(),
        method: "sgm".into(),
        queue_capacity: 64,
        renders: RenderWith::Cpu,
        diagnostics_every: Duration::from_millis(250),
        foxglove: Some(FoxgloveConfig {
            bind: SocketAddr::from(([127, 0, 0, 1], port)),
            ..FoxgloveConfig::default()
        }),
        ..NodeConfig::default()
    })
    .await;
    let zenoh_keys = [keys.bin_map(), keys.bin_pose(), keys.bin_render()];
    let collector = Collector::connect(&node, &zenoh_keys).await;
    let url = format!("ws://127.0.0.1:{port}");
    let (mut reader, channels) = tokio::task::block_in_place(|| Client::start(&url, "read"));
    let (stalled, _) = tokio::task::block_in_place(|| Client::start(&url, "stall"));
    let (leaver, _) = tokio::task::block_in_place(|| Client::start(&url, "leave"));
    let want: BTreeMap<&str, &str> = [
        ("/fox/bin/map", "foxglove.PointCloud"),
        ("/fox/map/new_points", "foxglove.PointCloud"),
        ("/fox/bin/input", "foxglove.RawImage"),
        ("/fox/bin/render", "foxglove.RawImage"),
        ("/tf", "foxglove.FrameTransforms"),
        ("/fox/latency", "json"),
        ("/fox/map/increment", "json"),
        ("/fox/diagnostics", "json"),
    ]
    .into();
    let got: BTreeMap<&str, &str> = channels
        .iter()
        .map(|(t, k)| (t.as_str(), k.as_str()))
        .collect();
    assert_eq!(got, want);

    Player::connect(&node)
        .await
        .drive(&drive, DAffine3::IDENTITY, 0)
        .await;
    assert!(collector.wait_count(&keys.bin_map(), bins).await);
    tokio::task::block_in_place(|| {
        reader.wait_messages("/fox/bin/map", bins);
        reader.wait_messages("/fox/bin/render", bins);
    });
    let summary = node.stop().await;
    let (_, lines) = tokio::task::block_in_place(|| reader.finish());
    let (stalled, _) = tokio::task::block_in_place(|| stalled.finish());
    let (leaver, _) = tokio::task::block_in_place(|| leaver.finish());

    // No bin lost to the clients: every bin the drive opened was published.
    assert_eq!(summary.bins_published, bins as u64, "{summary:?}");
    assert_eq!(summary.counters.get("dropped/worker_queue"), 0);
    let sent = summary.counters.get("foxglove/sent");
    let dropped = summary.counters.get("foxglove/dropped");
    assert!(sent > 0);
    eprintln!(
        "foxglove: {sent} items sent, {dropped} dropped; stalled client received {}, \
         the leaving one {}",
        stalled["received"], leaver["received"]
    );
    let total = |s: &Value| -> u64 {
        s["received"]
            .as_object()
            .unwrap()
            .values()
            .map(|v| v.as_u64().unwrap())
            .sum()
    };
    assert_eq!(total(&leaver), 1, "{leaver}");
    let on = |topic: &str| -> Vec<&Value> {
        lines
            .iter()
            .filter(|v| v["event"] == "message" && v["topic"] == topic)
            .collect()
    };

    // Bin maps: as many points as the node's maps, same positions, SH DC colours.
    let maps: BTreeMap<u64, GaussianSet> = collector
        .decoded::<PointCloud2>(&keys.bin_map())
        .iter()
        .map(|c| {
            let set = gaussians_from_cloud(c, DVec3::ZERO).unwrap();
            (bin_of_frame_id(&c.header.frame_id), set)
        })
        .collect();
    let clouds = on("/fox/bin/map");
    assert_eq!(clouds.len(), bins);
    for cloud in &clouds {
        let bin = bin_of_frame_id(cloud["frame_id"].as_str().unwrap());
        assert!(
            maps[&bin].len() > 100,
            "bin {bin}: {} points",
            maps[&bin].len()
        );
        assert_cloud_is(cloud, &maps[&bin]);
    }

    // Frames: each bin frame where its pose says, each camera where the drive was.
    let poses: BTreeMap<u64, DAffine3> = collector
        .decoded::<PoseStamped>(&keys.bin_pose())
        .iter()
        .zip(collector.decoded::<PointCloud2>(&keys.bin_map()))
        .map(|(p, c)| {
            (
                bin_of_frame_id(&c.header.frame_id),
                affine_from_pose(p).unwrap(),
            )
        })
        .collect();
    let by_stamp: BTreeMap<i64, DAffine3> = drive
        .frames
        .iter()
        .map(|(s, f)| (*s, f.left_to_world))
        .collect();
    let (mut bin_frames, mut cameras) = (BTreeMap::new(), 0);
    for tf in on("/tf") {
        for t in tf["transforms"].as_array().unwrap() {
            assert_eq!(t["parent"], "world");
            let child = t["child"].as_str().unwrap();
            let pose = pose_of(t);
            let want = match child.starts_with("bin_") {
                true => {
                    bin_frames.insert(child.to_string(), pose);
                    poses[&bin_of_frame_id(child)]
                }
                false => {
                    cameras += 1;
                    by_stamp[&stamp_ns(&t["stamp_ns"])]
                }
            };
            assert!(
                pose_error(&pose, &want) < 1e-9,
                "{child}: {pose:?} against {want:?}"
            );
        }
    }
    assert_eq!(bin_frames.len(), bins);
    assert_eq!(
        cameras,
        drive.frames.len(),
        "one camera transform per frame"
    );

    // Renders: the bytes the node published on zenoh; inputs: the drive's left images.
    let renders: BTreeMap<u64, String> = collector
        .decoded::<Image>(&keys.bin_render())
        .iter()
        .map(|i| (bin_of_frame_id(&i.header.frame_id), sha256(&i.data)))
        .collect();
    for r in on("/fox/bin/render") {
        assert_eq!(r["encoding"], "rgb8");
        assert_eq!(
            r["sha256"],
            renders[&bin_of_frame_id(r["frame_id"].as_str().unwrap())]
        );
    }
    let lefts: BTreeMap<i64, String> = drive
        .frames
        .iter()
        .map(|(s, f)| (*s, sha256(&f.left.to_rgb8())))
        .collect();
    let inputs = on("/fox/bin/input");
    assert_eq!(inputs.len(), bins);
    for i in inputs {
        assert_eq!(
            i["width"].as_u64(),
            Some(drive.frames[0].1.left.width as u64)
        );
        assert_eq!(i["sha256"], lefts[&stamp_ns(&i["stamp_ns"])]);
    }

    // The fused map: each increment's new points, adding up to the map's size.
    let increments = on("/fox/map/increment");
    let new_points = on("/fox/map/new_points");
    assert_eq!(increments.len(), bins);
    assert_eq!(new_points.len(), bins);
    let mut size = 0i64;
    for (inc, cloud) in increments.iter().zip(&new_points) {
        let v = &inc["value"];
        assert_eq!(cloud["count"], v["added"]);
        assert_eq!(cloud["frame_id"], "world");
        let origin = f64s(&cloud["origin"]);
        let bin_origin = poses[&v["bin_id"].as_u64().unwrap()].translation;
        assert_eq!(DVec3::new(origin[0], origin[1], origin[2]), bin_origin);
        size += v["added"].as_i64().unwrap() - v["removed"].as_i64().unwrap();
        assert_eq!(v["total"].as_i64(), Some(size));
    }
    assert_eq!(size as usize, summary.global_gaussians);

    // Latency and counters as JSON.
    let latency = on("/fox/latency");
    assert!(
        latency.len() >= bins - 1,
        "{} latency messages",
        latency.len()
    );
    for l in latency {
        assert!(l["value"]["arrival_to_publish_ms"].as_f64().unwrap() > 0.0);
    }
    let counters = on("/fox/diagnostics");
    assert!(counters
        .iter()
        .any(|c| c["value"]["counters"]["foxglove/clients"].as_u64() >= Some(1)));
}

/// A map of `n` Gaussians along x with the given colours and opacities.
fn set_of(means: &[Vec3], colors: &[Vec3], opacities: &[f32]) -> GaussianSet {
    let n = means.len();
    GaussianSet {
        means: means.to_vec(),
        log_scales: vec![Vec3::ZERO; n],
        rotations: vec![Quat::IDENTITY; n],
        opacities: opacities.to_vec(),
        colors: colors.to_vec(),
        confidences: vec![1.0; n],
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn empty_and_extreme_maps_reach_the_client_and_an_address_in_use_is_a_clear_error() {
    require_client();
    let mut server = Foxglove::start(
        &FoxgloveConfig {
            bind: SocketAddr::from(([127, 0, 0, 1], 0)),
            ..FoxgloveConfig::default()
        },
        "edge",
        "world",
    )
    .await
    .unwrap();
    let port = server.addr().port();
    assert_ne!(port, 0);

    // Nothing is copied or queued while no client listens (bin frames are kept).
    server.bin_map(0, 1, &set_of(&[Vec3::ONE], &[Vec3::ONE], &[1.0]));
    let mut counters = node::counters::Counters::default();
    server.count_into(&mut counters);
    assert_eq!(counters.get("foxglove/clients"), 0);
    assert_eq!(counters.get("foxglove/dropped"), 0);

    // The same address again: refused, naming the address, with the system's reason.
    let taken = Foxglove::start(
        &FoxgloveConfig {
            bind: server.addr(),
            ..FoxgloveConfig::default()
        },
        "again",
        "world",
    )
    .await;
    let err = match taken {
        Err(e @ FoxgloveError::Bind { .. }) => e,
        other => panic!("expected a bind error, got {:?}", other.map(|f| f.addr())),
    };
    let chain = format!("{err}: {}", std::error::Error::source(&err).unwrap());
    assert!(chain.contains(&format!("127.0.0.1:{port}")), "{chain}");
    assert!(chain.to_lowercase().contains("in use"), "{chain}");
    let as_node: ServiceError = err.into();
    assert!(as_node.to_string().contains("Foxglove"), "{as_node}");

    let url = format!("ws://{}", server.addr());
    let (client, _) = tokio::task::block_in_place(|| Client::start(&url, "read"));
    let extreme = set_of(
        &[Vec3::new(1.0, 2.0, 3.0), Vec3::new(f32::NAN, 0.0, 1e30)],
        &[Vec3::new(-2.0, 0.5, 9.0), Vec3::new(f32::NAN, 1.0, 0.0)],
        &[0.5, f32::INFINITY],
    );
    server.bin_map(1, 10, &GaussianSet::default());
    server.bin_map(2, 20, &set_of(&[Vec3::ZERO], &[Vec3::splat(0.25)], &[0.75]));
    server.bin_map(3, 30, &extreme);
    let far = DVec3::new(1.0e5, -1.0e5, 12.5);
    let g = WorldGaussian {
        position: far + DVec3::new(0.0012, -0.0034, 2.0),
        log_scale: Vec3::ZERO,
        rotation: Quat::IDENTITY,
        opacity: 1.0,
        color: Vec3::new(0.2, 0.4, 0.6),
        confidence: 1.0,
        bin_id: 3,
    };
    let summary = serde_json::json!({"bin_id": 3, "added": 1});
    server.map_increment(summary, &[(GaussianId(7), g)], far, 30);
    server.map_increment(serde_json::json!({}), &[], far, 31);
    tokio::time::sleep(Duration::from_millis(500)).await;
    server.stop().await;
    let (_, lines) = tokio::task::block_in_place(|| client.finish());
    let on = |topic: &str| -> Vec<&Value> {
        lines
            .iter()
            .filter(|v| v["event"] == "message" && v["topic"] == topic)
            .collect()
    };
    let clouds = on("/edge/bin/map");
    assert_eq!(
        clouds.len(),
        3,
        "the map logged before any client is not sent"
    );
    assert_eq!(clouds[0]["count"], 0);
    assert_eq!(clouds[0]["fields"].as_array().unwrap().len(), 7);
    assert_cloud_is(
        clouds[1],
        &set_of(&[Vec3::ZERO], &[Vec3::splat(0.25)], &[0.75]),
    );
    assert_cloud_is(clouds[2], &extreme);
    let new = on("/edge/map/new_points");
    assert_eq!(
        (new[0]["count"].as_u64(), new[1]["count"].as_u64()),
        (Some(1), Some(0))
    );
    let (o, p) = (f64s(&new[0]["origin"]), f64s(&new[0]["xyz"]));
    let back = DVec3::new(o[0] + p[0], o[1] + p[1], o[2] + p[2]);
    // f32 offsets from the f64 origin: well below a millimetre 1e5 m out.
    assert!((back - g.position).abs().max_element() < 1e-6, "{back}");
    eprintln!("far point error {:e} m", (back - g.position).length());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_client_that_stops_reading_gets_only_what_its_bounded_queue_held() {
    require_client();
    // A queue of 8 messages per client in the SDK; 300 images of 640x360 (691 KB each,
    // 207 MB in all) against this machine's loopback buffers (at most 32 MiB received plus
    // 4 MiB sent by default on Linux).
    const BACKLOG: usize = 8;
    const IMAGES: u64 = 300;
    let mut server = Foxglove::start(
        &FoxgloveConfig {
            bind: SocketAddr::from(([127, 0, 0, 1], 0)),
            backlog: BACKLOG,
            ..FoxgloveConfig::default()
        },
        "slow",
        "world",
    )
    .await
    .unwrap();
    let url = server.url();
    let (stalled, _) = tokio::task::block_in_place(|| Client::start(&url, "stall"));
    let image = model::frame::RgbImage::from_rgb8(
        640,
        360,
        &(0..640 * 360 * 3)
            .map(|i| (i % 251) as u8)
            .collect::<Vec<_>>(),
    );
    for bin in 0..IMAGES {
        server.render(bin, bin as i64, &image);
        // Paced so the node's own queue (64 items) never fills: every loss is the SDK's.
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    // Let the server's thread hand the last items to the SDK before the count is read.
    tokio::time::sleep(Duration::from_millis(500)).await;
    let mut counters = node::counters::Counters::default();
    server.count_into(&mut counters);
    // The stalled client reads what was held for it, until 2 s pass with nothing new.
    let (summary, _) = tokio::task::block_in_place(|| stalled.finish());
    server.stop().await;
    let received = summary["received"]["/slow/bin/render"]
        .as_u64()
        .unwrap_or(0);
    let sent = counters.get("foxglove/sent");
    eprintln!(
        "stalled client: {received} of {sent} images (node queue dropped {})",
        counters.get("foxglove/dropped")
    );
    assert_eq!(counters.get("foxglove/dropped"), 0, "{counters:?}");
    assert_eq!(sent, IMAGES);
    // What the socket buffers hold (36 MiB, 55 images) plus the queue, not the stream.
    assert!(received >= 1, "{summary}");
    assert!(received <= 55 + BACKLOG as u64 + 10, "{summary}");
}
