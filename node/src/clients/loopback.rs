//! A whole drive through the node in one process: the node, a replay and a listener, each
//! with its own zenoh session, connected over loopback TCP exactly as separate processes
//! would be. `demo` and `bench node` are built on it, so what they report is what a user's
//! setup does, transport included.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use glam::DAffine3;
use model::bins::{make_bins, BinConfig, BinLayout};
use model::frame::RgbImage;
use renderer::GaussianSet;

use super::replay::{replay_drive, Drive};
use crate::bag::Rate;
use crate::memory::{peak_rss_bytes, rss_bytes};
use crate::msg::gaussians::gaussians_from_cloud;
use crate::msg::geometry_msgs::PoseStamped;
use crate::msg::image::rgb_from_image;
use crate::msg::latency::BinLatency;
use crate::msg::pose::affine_from_pose;
use crate::msg::sensor_msgs::{Image, PointCloud2};
use crate::msg::Message;
use crate::service::error::ServiceError;
use crate::service::node::{run_with, NodeConfig};
use crate::service::NodeSummary;
use crate::transport::keys::Keys;
use crate::transport::{open, TransportConfig, TransportError};

/// One bin as a subscriber received it.
#[derive(Clone, Debug)]
pub struct ReceivedBin {
    /// The bin's number.
    pub bin_id: u64,
    /// Its Gaussians in the bin frame.
    pub gaussians: GaussianSet,
    /// Bin frame to world, f64.
    pub bin_to_world: DAffine3,
}

/// What the listener hands on, as it arrives.
#[derive(Clone, Debug)]
pub enum Received {
    /// A bin's map and pose.
    Bin(Box<ReceivedBin>),
    /// A bin's map rendered from its input view (after the bin, when renders are on).
    Render {
        /// The bin.
        bin_id: u64,
        /// The render.
        image: RgbImage,
    },
}

/// How a loopback run went.
#[derive(Clone, Debug, Default)]
pub struct LoopbackReport {
    /// The node's own account (counters, bins published, global map size).
    pub node: NodeSummary,
    /// Frames replayed.
    pub frames: u64,
    /// Bins the binner will have opened for the replayed poses (closed ones plus the last).
    pub bins_expected: u64,
    /// Bin maps the listener received.
    pub bins_received: u64,
    /// Latency messages received, in arrival order.
    pub latencies: Vec<BinLatency>,
    /// Resident memory of the process (bytes) after every 50 frames replayed, with the
    /// frame count: the node, replay and listener together.
    pub rss_samples: Vec<(u64, u64)>,
    /// Highest resident memory of the process, bytes (VmHWM).
    pub peak_rss_bytes: u64,
    /// Seconds from the first frame sent to the node's exit.
    pub wall_s: f64,
}

/// Why a loopback run failed.
#[derive(Debug, thiserror::Error)]
pub enum LoopbackError {
    /// The node failed (not bad input, which it counts).
    #[error(transparent)]
    Node(#[from] ServiceError),
    /// No free loopback port, or a session would not open.
    #[error("loopback transport: {0}")]
    Transport(String),
}

/// Replays `drive` at `rate` into a node configured by `config` (its transport is replaced by a
/// fresh loopback endpoint, keeping its `connect` endpoints), hands every bin and render the
/// listener receives to `on_bin`, waits until every expected bin is published or nothing has
/// come for `idle`, then stops the node and reports. `on_ready` gets the node's session once it
/// is up (the live view subscribes on it).
pub async fn run_loopback(
    mut config: NodeConfig,
    drive: Drive<'_>,
    rate: Rate,
    idle: Duration,
    progress: &mut dyn FnMut(usize, usize),
    on_bin: &mut dyn FnMut(Received),
    on_ready: impl FnOnce(&zenoh::Session) + Send + 'static,
) -> Result<LoopbackReport, LoopbackError> {
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map_err(|e| LoopbackError::Transport(e.to_string()))?
        .port();
    let endpoint = format!("tcp/127.0.0.1:{port}");
    // Its own listen endpoint; the peers it is told to connect to (worker processes) kept.
    config.transport = TransportConfig {
        listen: vec![endpoint.clone()],
        connect: std::mem::take(&mut config.transport.connect),
        ..TransportConfig::default()
    };
    let keys = config.keys.clone();
    let poses: Vec<_> = drive.frames.iter().map(|f| f.left_to_world).collect();
    let bins = BinConfig {
        length_m: config.binner.length_m,
        layout: BinLayout::Consecutive,
    };
    let bins_expected = make_bins(&poses, &bins).len() as u64 + u64::from(!poses.is_empty());

    // A reconstructor that cannot be made (missing weights, a bad setting) fails here, not
    // after the client sessions below wait for a node that never listens.
    let points = config.points().map_err(ServiceError::from)?;
    let (stop_tx, stop_rx) = tokio::sync::oneshot::channel::<()>();
    let node = tokio::spawn(run_with(
        config,
        points,
        async {
            let _ = stop_rx.await;
        },
        on_ready,
    ));
    let client = TransportConfig {
        connect: vec![endpoint],
        ..TransportConfig::default()
    };
    let terr = |e: TransportError| LoopbackError::Transport(e.to_string());
    let listener = Listener::new(&client, &keys).await.map_err(terr)?;
    let player = open(&client).await.map_err(terr)?;
    // Let the sessions find each other before the first frame.
    tokio::time::sleep(Duration::from_millis(800)).await;

    let start = Instant::now();
    let mut report = LoopbackReport {
        bins_expected,
        ..LoopbackReport::default()
    };
    let mut listener = listener;
    {
        let mut hook = |done: usize, total: usize| {
            if done.is_multiple_of(50) || done == total {
                report.rss_samples.push((done as u64, rss_bytes()));
            }
            progress(done, total);
        };
        let replaying = replay_drive(&player, &keys, drive, rate, &mut hook);
        tokio::pin!(replaying);
        // Drain the listener while the replay runs, so nothing piles up in zenoh's queues.
        let summary = loop {
            tokio::select! {
                r = &mut replaying => break r?,
                _ = tokio::time::sleep(Duration::from_millis(20)) => {
                    listener.drain(on_bin);
                }
            }
        };
        report.frames = summary.frames;
    }
    let mut last_progress = Instant::now();
    while listener.bins < bins_expected && last_progress.elapsed() < idle {
        tokio::time::sleep(Duration::from_millis(50)).await;
        if listener.drain(on_bin) {
            last_progress = Instant::now();
        }
    }
    let _ = stop_tx.send(());
    report.node = node
        .await
        .map_err(|e| LoopbackError::Transport(format!("node task: {e}")))??;
    tokio::time::sleep(Duration::from_millis(200)).await;
    listener.drain(on_bin);
    report.wall_s = start.elapsed().as_secs_f64();
    report.bins_received = listener.bins;
    report.latencies = std::mem::take(&mut listener.latencies);
    report.peak_rss_bytes = peak_rss_bytes();
    Ok(report)
}

/// The listener's subscriptions and what it has paired so far.
struct Listener {
    maps: zenoh::pubsub::Subscriber<zenoh::handlers::FifoChannelHandler<zenoh::sample::Sample>>,
    poses: zenoh::pubsub::Subscriber<zenoh::handlers::FifoChannelHandler<zenoh::sample::Sample>>,
    renders: zenoh::pubsub::Subscriber<zenoh::handlers::FifoChannelHandler<zenoh::sample::Sample>>,
    latency: zenoh::pubsub::Subscriber<zenoh::handlers::FifoChannelHandler<zenoh::sample::Sample>>,
    /// Maps by header stamp (the bin's first arrival), waiting for their pose.
    waiting: BTreeMap<i64, (u64, GaussianSet)>,
    latencies: Vec<BinLatency>,
    bins: u64,
    _session: zenoh::Session,
}

impl Listener {
    async fn new(client: &TransportConfig, keys: &Keys) -> Result<Self, TransportError> {
        let session = open(client).await?;
        let sub = |key: String| {
            let s = &session;
            async move {
                s.declare_subscriber(key)
                    .await
                    .map_err(|e| TransportError::Zenoh(e.to_string()))
            }
        };
        Ok(Self {
            maps: sub(keys.bin_map()).await?,
            poses: sub(keys.bin_pose()).await?,
            renders: sub(keys.bin_render()).await?,
            latency: sub(keys.latency()).await?,
            waiting: BTreeMap::new(),
            latencies: Vec::new(),
            bins: 0,
            _session: session,
        })
    }

    /// Takes what has arrived; hands complete bins to `on_bin`. True if a bin completed.
    fn drain(&mut self, on_bin: &mut dyn FnMut(Received)) -> bool {
        while let Ok(Some(s)) = self.renders.try_recv() {
            let Ok(msg) = Image::decode(&s.payload().to_bytes()) else {
                continue;
            };
            if let (Some(bin_id), Ok(image)) = (bin_id(&msg.header.frame_id), rgb_from_image(&msg))
            {
                on_bin(Received::Render { bin_id, image });
            }
        }
        while let Ok(Some(s)) = self.maps.try_recv() {
            let Ok(cloud) = PointCloud2::decode(&s.payload().to_bytes()) else {
                continue;
            };
            let (Some(id), Ok(set)) = (
                bin_id(&cloud.header.frame_id),
                gaussians_from_cloud(&cloud, glam::DVec3::ZERO),
            ) else {
                continue;
            };
            self.waiting
                .insert(cloud.header.stamp.to_nanos(), (id, set));
        }
        while let Ok(Some(s)) = self.latency.try_recv() {
            if let Ok(l) = BinLatency::decode(&s.payload().to_bytes()) {
                self.latencies.push(l);
            }
        }
        let mut completed = false;
        while let Ok(Some(s)) = self.poses.try_recv() {
            let Ok(msg) = PoseStamped::decode(&s.payload().to_bytes()) else {
                continue;
            };
            let (Some((bin_id, gaussians)), Ok(pose)) = (
                self.waiting.remove(&msg.header.stamp.to_nanos()),
                affine_from_pose(&msg),
            ) else {
                continue;
            };
            self.bins += 1;
            completed = true;
            on_bin(Received::Bin(Box::new(ReceivedBin {
                bin_id,
                gaussians,
                bin_to_world: pose,
            })));
        }
        completed
    }
}

/// The bin id in a `bin_<id>` frame name.
fn bin_id(frame_id: &str) -> Option<u64> {
    frame_id.strip_prefix("bin_")?.parse().ok()
}
