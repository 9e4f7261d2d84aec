//! What the streaming-node tests share: a generated drive loaded into memory, a node running
//! inside the test process on a free loopback port, a player that publishes frames onto the
//! node's input keys (poses optionally moved, stamps optionally offset), a collector of what
//! the node publishes, and the process's resident memory.
//!
//! Everything goes through the node's public API (`node::service`, `node::transport`,
//! `node::msg`) and real zenoh sessions over loopback.

#![allow(dead_code)] // each test binary uses part of it

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use glam::DAffine3;
use model::bins::{make_bins, BinConfig, BinLayout};
use model::frame::{StereoFrame, StereoRig};
use model::generate::write_synthetic;
use model::kitti360::Sequence;
use model::synth::SynthConfig;
use node::msg::image::{camera_info, image_from_rgb};
use node::msg::latency::Diagnostics;
use node::msg::pose::pose_from_affine;
use node::msg::std_msgs::Header;
use node::msg::Message;
use node::pipeline::worker::RenderWith;
use node::service::{run_announced, NodeConfig, NodeSummary, ServiceError};
use node::transport::Keys;
use node::transport::{open, TransportConfig};
use zenoh::qos::CongestionControl;
use zenoh::Session;

#[path = "../net_support/mod.rs"]
pub mod net_support;

/// A TCP port on 127.0.0.1 that was free a moment ago, for a node started as a process.
pub fn free_port() -> u16 {
    net_support::free_port()
}

/// A generated drive in the KITTI-360 layout under a temporary folder (removed on drop), with
/// every frame loaded.
pub struct Drive {
    /// The temporary folder (`data/` holds the drive; tests may add `out*/`).
    pub root: PathBuf,
    /// The drive as the replay reads it.
    pub sequence: Sequence,
    /// The rig it was taken with.
    pub rig: StereoRig,
    /// Every frame with its stamp (ns), in order.
    pub frames: Vec<(i64, StereoFrame)>,
}

impl Drive {
    /// The small, quick drive the load tests replay many times (40 frames at 272x72, no
    /// supersampling, seed 23).
    pub fn small(tag: &str) -> Self {
        Self::small_of_seed(tag, 23)
    }

    /// A drive like [`Drive::small`] of another seed (another street).
    pub fn small_of_seed(tag: &str, seed: u64) -> Self {
        Self::generate(
            tag,
            &SynthConfig {
                seed,
                frames: 40,
                width: 272,
                height: 72,
                supersample: 1,
                lidar_azimuth_steps: 64,
                ..SynthConfig::default()
            },
        )
    }

    /// Generates the drive `config` describes under a folder named after `tag` and the process.
    pub fn generate(tag: &str, config: &SynthConfig) -> Self {
        let root = std::env::temp_dir().join(format!("stereosplat-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        let data = root.join("data");
        let name = write_synthetic(&data, config, &mut |_, _| {}).expect("drive generated");
        let sequence = Sequence::open(&data, &name).expect("drive opens");
        let rig = sequence.rig();
        let frames = sequence
            .frames()
            .iter()
            .enumerate()
            .map(|(i, f)| {
                let stamp = f.timestamp_ns.unwrap_or(i as i64 * 100_000_000);
                (stamp, sequence.load_frame(f.index).expect("frame loads"))
            })
            .collect();
        Self {
            root,
            sequence,
            rig,
            frames,
        }
    }

    /// The left camera poses, one per frame.
    pub fn poses(&self) -> Vec<DAffine3> {
        self.frames.iter().map(|(_, f)| f.left_to_world).collect()
    }

    /// Bins the node opens on this drive with bins `length_m` long: the evaluation's closed
    /// bins plus the one still open when the drive ends.
    pub fn bins_opened(&self, length_m: f64) -> usize {
        let closed = make_bins(
            &self.poses(),
            &BinConfig {
                length_m,
                layout: BinLayout::Consecutive,
            },
        )
        .len();
        closed + 1
    }

    /// A folder under the drive's root.
    pub fn dir(&self, name: &str) -> PathBuf {
        self.root.join(name)
    }
}

impl Drop for Drive {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.root);
    }
}

/// A node under `keys` that makes its bins with SGM (deterministic, fast), draws no
/// renders and queues up to 64 bins (a drive sent as fast as possible loses none): what the
/// input tests compare runs with.
pub fn sgm_config(keys: &Keys) -> NodeConfig {
    NodeConfig {
        keys: keys.clone(),
        queue_capacity: 64,
        renders: RenderWith::Off,
        method: "sgm".into(),
        ..NodeConfig::default()
    }
}

/// A node running on a tokio task of the test, listening on a free loopback port.
pub struct RunningNode {
    /// Where it listens.
    pub endpoint: String,
    /// Its keys.
    pub keys: Keys,
    /// The node's own session (what the node publishes on): tests wait on it for their
    /// subscribers to reach the node.
    pub session: Session,
    stop: Option<tokio::sync::oneshot::Sender<()>>,
    task: tokio::task::JoinHandle<Result<NodeSummary, ServiceError>>,
}

impl RunningNode {
    /// Starts the node with `config` (its listen endpoints replaced by a free port, the
    /// endpoints it connects to kept) and waits until it says it is ready (bound and
    /// subscribed), two minutes at most.
    pub async fn start(mut config: NodeConfig) -> Self {
        let endpoint = format!("tcp/127.0.0.1:{}", net_support::free_port());
        config.transport = TransportConfig {
            listen: vec![endpoint.clone()],
            connect: std::mem::take(&mut config.transport.connect),
            ..TransportConfig::default()
        };
        let keys = config.keys.clone();
        let (stop_tx, stop_rx) = tokio::sync::oneshot::channel::<()>();
        let (ready_tx, ready_rx) = tokio::sync::oneshot::channel::<Session>();
        let task = tokio::spawn(run_announced(
            config,
            async {
                let _ = stop_rx.await;
            },
            move |session| {
                let _ = ready_tx.send(session.clone());
            },
        ));
        let ready = tokio::time::timeout(Duration::from_secs(120), ready_rx).await;
        let Ok(Ok(session)) = ready else {
            panic!("the node stopped at start or was not ready in two minutes")
        };
        assert!(!task.is_finished(), "the node stopped at start");
        Self {
            endpoint,
            keys,
            session,
            stop: Some(stop_tx),
            task,
        }
    }

    /// A peer that connects to the node.
    pub fn client(&self) -> TransportConfig {
        client_of(&self.endpoint)
    }

    /// Whether the node's task is still running.
    pub fn is_running(&self) -> bool {
        !self.task.is_finished()
    }

    /// Stops the node (it finishes the queued bins and exports) and returns its summary.
    pub async fn stop(mut self) -> NodeSummary {
        if let Some(tx) = self.stop.take() {
            let _ = tx.send(());
        }
        (&mut self.task)
            .await
            .expect("the node task does not panic")
            .expect("the node stops without error")
    }
}

/// A peer that connects to `endpoint` (a node in this process or another).
pub fn client_of(endpoint: &str) -> TransportConfig {
    TransportConfig {
        connect: vec![endpoint.to_string()],
        ..TransportConfig::default()
    }
}

/// A session that publishes onto the node's input keys, blocking (not dropping) when zenoh's
/// queues are full, so every frame reaches the node.
pub struct Player {
    /// The session.
    pub session: Session,
    keys: Keys,
}

impl Player {
    /// Connects to `node`.
    pub async fn connect(node: &RunningNode) -> Self {
        Self::at(&node.endpoint, node.keys.clone()).await
    }

    /// Connects to a node (in this process or another) listening on `endpoint` with `keys`,
    /// and waits until the node's input subscription is known here (two minutes at most): a
    /// put before it would reach no one.
    pub async fn at(endpoint: &str, keys: Keys) -> Self {
        let player = Self::with(&client_of(endpoint), keys).await;
        let inputs = player.keys.left_info();
        assert!(
            net_support::sees_a_subscriber(&player.session, &inputs).await,
            "the node at {endpoint} never subscribed to {inputs}"
        );
        player
    }

    /// A player on a session opened as `transport` says (a secure one, say).
    pub async fn with(transport: &TransportConfig, keys: Keys) -> Self {
        Self {
            session: open(transport).await.expect("player session"),
            keys,
        }
    }

    /// Puts `payload` on `key`.
    pub async fn put(&self, key: String, payload: Vec<u8>) {
        self.session
            .put(key, payload)
            .congestion_control(CongestionControl::Block)
            .await
            .expect("put");
    }

    /// Publishes both camera infos stamped `stamp_ns`. The node reads every input key on one
    /// subscriber, in arrival order, and the player's messages reach it in the order they
    /// were put, so frames put after this are taken after the infos.
    pub async fn camera_infos(&self, rig: &StereoRig, stamp_ns: i64) {
        let k = &self.keys;
        let left = camera_info(&rig.intrinsics, 0.0, Header::new(stamp_ns, "left"));
        let right = camera_info(
            &rig.intrinsics,
            rig.baseline,
            Header::new(stamp_ns, "right"),
        );
        self.put(k.left_info(), left.encode()).await;
        self.put(k.right_info(), right.encode()).await;
    }

    /// Publishes the camera infos, then every frame of `frames` at its stamp with its own
    /// pose.
    pub async fn frames(&self, rig: &StereoRig, frames: &[(i64, StereoFrame)]) {
        if let Some((first, _)) = frames.first() {
            self.camera_infos(rig, *first).await;
        }
        for (stamp, frame) in frames {
            self.frame(rig, *stamp, frame, &frame.left_to_world).await;
        }
    }

    /// Publishes one frame as the replay does: both camera infos, the left and right images
    /// and the pose, all stamped `stamp_ns`, with `left_to_world` as the pose.
    pub async fn frame(
        &self,
        rig: &StereoRig,
        stamp_ns: i64,
        frame: &StereoFrame,
        left_to_world: &DAffine3,
    ) {
        let k = &self.keys;
        let header = |id: &str| Header::new(stamp_ns, id);
        let infos = [
            (
                k.left_info(),
                camera_info(&rig.intrinsics, 0.0, header("left")),
            ),
            (
                k.right_info(),
                camera_info(&rig.intrinsics, rig.baseline, header("right")),
            ),
        ];
        for (key, info) in infos {
            self.put(key, info.encode()).await;
        }
        self.put(
            k.left_image(),
            image_from_rgb(&frame.left, header("left")).encode(),
        )
        .await;
        self.put(
            k.right_image(),
            image_from_rgb(&frame.right, header("right")).encode(),
        )
        .await;
        self.put(
            k.pose(),
            pose_from_affine(left_to_world, header("world")).encode(),
        )
        .await;
    }

    /// Publishes every frame of `drive`, poses premultiplied by `shift` (world to world),
    /// stamps moved by `stamp_offset_ns`, as fast as the node takes them (camera infos
    /// first, see [`Player::camera_infos`]).
    pub async fn drive(&self, drive: &Drive, shift: DAffine3, stamp_offset_ns: i64) {
        self.camera_infos(&drive.rig, drive.frames[0].0 + stamp_offset_ns)
            .await;
        for (stamp, frame) in &drive.frames {
            let pose = shift * frame.left_to_world;
            self.frame(&drive.rig, stamp + stamp_offset_ns, frame, &pose)
                .await;
        }
        // Let the last samples leave before anyone closes the session.
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}

/// One sample as received: its key and payload.
pub type Received = (String, Vec<u8>);

/// A session subscribed to some of the node's keys, keeping every sample in arrival order
/// (unbounded, so a slow test never makes zenoh drop or block).
pub struct Collector {
    samples: Arc<Mutex<Vec<Received>>>,
    _subscribers: Vec<zenoh::pubsub::Subscriber<()>>,
    _session: Session,
}

impl Collector {
    /// Subscribes to each key in `keys` on a new session connected to `node`, then waits
    /// until the node's session sees a subscriber on each (two minutes at most).
    pub async fn connect(node: &RunningNode, keys: &[String]) -> Self {
        Self::connect_truncated(node, keys, usize::MAX).await
    }

    /// As [`Collector::connect`], keeping only the first `max_bytes` of each payload (enough
    /// for a message's header: see [`Collector::headers`]), so that collecting many large
    /// maps does not grow the test process.
    pub async fn connect_truncated(node: &RunningNode, keys: &[String], max_bytes: usize) -> Self {
        let collector = Self::subscribed(&node.endpoint, keys, max_bytes).await;
        for key in keys {
            assert!(
                net_support::sees_a_subscriber(&node.session, key).await,
                "the node never saw the subscriber on {key}"
            );
        }
        collector
    }

    /// As [`Collector::connect_truncated`], for a node in another process listening on
    /// `endpoint`: with no session of the node's at hand to ask, it waits half a second for
    /// the subscriptions to reach the node.
    pub async fn at(endpoint: &str, keys: &[String], max_bytes: usize) -> Self {
        let collector = Self::subscribed(endpoint, keys, max_bytes).await;
        tokio::time::sleep(Duration::from_millis(500)).await;
        collector
    }

    /// A session connected to `endpoint` with a subscriber on each of `keys`.
    async fn subscribed(endpoint: &str, keys: &[String], max_bytes: usize) -> Self {
        let session = open(&client_of(endpoint)).await.expect("listener session");
        let samples: Arc<Mutex<Vec<Received>>> = Arc::default();
        let mut subscribers = Vec::new();
        for key in keys {
            let sink = samples.clone();
            let sub = session
                .declare_subscriber(key.clone())
                .callback(move |s| {
                    let payload = s.payload().to_bytes();
                    let bytes = payload[..payload.len().min(max_bytes)].to_vec();
                    sink.lock()
                        .unwrap()
                        .push((s.key_expr().as_str().to_string(), bytes));
                })
                .await
                .expect("subscriber");
            subscribers.push(sub);
        }
        Self {
            samples,
            _subscribers: subscribers,
            _session: session,
        }
    }

    /// Every sample so far.
    pub fn all(&self) -> Vec<Received> {
        self.samples.lock().unwrap().clone()
    }

    /// How many samples arrived on `key`.
    pub fn count(&self, key: &str) -> usize {
        self.samples
            .lock()
            .unwrap()
            .iter()
            .filter(|(k, _)| k == key)
            .count()
    }

    /// Waits (up to two minutes, a guard against hanging) until `n` samples arrived on
    /// `key`, then half a second more for whatever the node sends with them; whether they
    /// did. Tests wait for the last bin this way before stopping the node, so that nothing
    /// they count is published while the node shuts down (see `python_subscriber.rs`).
    pub async fn wait_count(&self, key: &str, n: usize) -> bool {
        let done = wait_for(Duration::from_secs(120), || self.count(key) >= n).await;
        tokio::time::sleep(Duration::from_millis(500)).await;
        done
    }

    /// Every sample on `key` decoded as `T` (a payload that does not decode fails the test).
    pub fn decoded<T: Message>(&self, key: &str) -> Vec<T> {
        self.samples
            .lock()
            .unwrap()
            .iter()
            .filter(|(k, _)| k == key)
            .map(|(_, p)| {
                T::decode(p).unwrap_or_else(|e| panic!("{key}: the node's message decodes: {e}"))
            })
            .collect()
    }
}

impl Collector {
    /// The headers of the samples on `key` (for messages whose first field is a
    /// std_msgs/Header: images, point clouds, poses).
    pub fn headers(&self, key: &str) -> Vec<Header> {
        self.decoded::<Header>(key)
    }
}

/// Waits, two minutes at most, for a `diagnostics` message on `subscriber` whose counter
/// sum over the names starting with `prefix` reaches `at_least`; the last sum seen. A
/// loaded machine may take seconds to count what a test sent: tests wait for the count, not
/// a fixed time.
pub async fn wait_counted(
    subscriber: &zenoh::pubsub::Subscriber<
        zenoh::handlers::FifoChannelHandler<zenoh::sample::Sample>,
    >,
    prefix: &str,
    at_least: u64,
) -> u64 {
    let deadline = tokio::time::Instant::now() + Duration::from_secs(120);
    let mut seen = 0;
    while seen < at_least {
        let sample = tokio::time::timeout_at(deadline, subscriber.recv_async()).await;
        let Ok(Ok(sample)) = sample else { break };
        if let Ok(d) = Diagnostics::decode(&sample.payload().to_bytes()) {
            seen = d
                .counters
                .iter()
                .filter(|c| c.kind.starts_with(prefix))
                .map(|c| c.count)
                .sum();
        }
    }
    seen
}

/// Polls `done` every 50 ms until it holds or `limit` passes; whether it held. A guard
/// against hanging forever, not a timing check: limits are minutes.
pub async fn wait_for(limit: Duration, mut done: impl FnMut() -> bool) -> bool {
    let start = Instant::now();
    while start.elapsed() < limit {
        if done() {
            return true;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    done()
}

/// The bin id in a bin map's `frame_id` (`bin_<id>`).
pub fn bin_of_frame_id(frame_id: &str) -> u64 {
    frame_id
        .strip_prefix("bin_")
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("frame_id `{frame_id}` is not bin_<id>"))
}

/// This process's resident set size in bytes (`VmRSS` of /proc/self/status; Linux only).
pub fn rss_bytes() -> u64 {
    let bytes = node::memory::rss_bytes();
    assert!(bytes > 0, "VmRSS in /proc/self/status");
    bytes
}

/// A file under the node's out folder.
pub fn out_file(dir: &Path, name: &str) -> PathBuf {
    let path = dir.join(name);
    assert!(path.exists(), "{} was exported", path.display());
    path
}
