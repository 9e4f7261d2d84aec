//! The node live in Foxglove: a WebSocket server made with Foxglove's own Rust SDK (the
//! `foxglove` crate) that streams, as Foxglove schemas, each bin's map and the fused map's
//! new points (`foxglove.PointCloud`), each bin's input image and render
//! (`foxglove.RawImage`), the camera and bin frames (`foxglove.FrameTransforms`), and the
//! per-bin latency, the fused map's increments and the counters as JSON ([`messages`]).
//!
//! Bounded, so that no client can hold the node: the node hands its outputs to
//! [`Foxglove`] without blocking (a bounded queue, keep newest: when it is full the oldest
//! waiting item is dropped and counted as `foxglove/dropped`), and only for channels a
//! client subscribed to; a thread of its own turns them into messages and logs them to the
//! SDK, whose log never blocks either (each client has its own queue of
//! [`FoxgloveConfig::backlog`] messages, dropping the oldest when a slow client falls
//! behind). The channels are made when the server starts, so a client sees them all
//! advertised before the first bin.

pub mod messages;

use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;

use ::foxglove::messages::{FrameTransform, FrameTransforms, PointCloud, RawImage};
use ::foxglove::{Channel, Context, RawChannel, Schema, WebSocketServerHandle};
use crossbeam_channel::{Receiver, Sender, TrySendError};
use glam::{DAffine3, DVec3};
use model::frame::RgbImage;
use renderer::GaussianSet;
use serde_json::Value;

use crate::counters::Counters;
use crate::fusion::{GaussianId, WorldGaussian};

/// How long [`Foxglove::stop`] waits for the clients' connections to close.
pub const STOP_GRACE: std::time::Duration = std::time::Duration::from_secs(2);

/// The default address: loopback, Foxglove's usual port.
pub const DEFAULT_ADDR: &str = "127.0.0.1:8765";

/// Where the server listens and how much it holds.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FoxgloveConfig {
    /// Address (loopback by default; another prints a warning and is counted as
    /// `warning/exposed_foxglove`). Port 0 takes any free one, printed.
    pub bind: SocketAddr,
    /// Outputs waiting for the server's thread at most (then the oldest is dropped).
    pub queue: usize,
    /// Messages the SDK queues per client at most (then it drops that client's oldest).
    pub backlog: usize,
}

impl Default for FoxgloveConfig {
    /// [`DEFAULT_ADDR`], 64 outputs waiting, the SDK's default backlog of 1024 messages.
    fn default() -> Self {
        Self {
            bind: SocketAddr::from(([127, 0, 0, 1], 8765)),
            queue: 64,
            backlog: 1024,
        }
    }
}

/// Why the server did not start.
#[derive(Debug, thiserror::Error)]
pub enum FoxgloveError {
    /// The address could not be bound (in use, not this machine's, no permission).
    #[error("binding the Foxglove WebSocket server to {addr}")]
    Bind {
        /// The address.
        addr: SocketAddr,
        /// The SDK's error (its cause is the system's).
        #[source]
        source: ::foxglove::FoxgloveError,
    },
    /// A channel could not be made (a bad namespace in a topic name).
    #[error("making the Foxglove channel {topic}")]
    Channel {
        /// The topic.
        topic: String,
        /// The SDK's error.
        #[source]
        source: ::foxglove::FoxgloveError,
    },
}

/// The server's channels, one per topic.
struct Channels {
    bin_map: Channel<PointCloud>,
    new_points: Channel<PointCloud>,
    input: Channel<RawImage>,
    render: Channel<RawImage>,
    tf: Channel<FrameTransforms>,
    latency: Arc<RawChannel>,
    increment: Arc<RawChannel>,
    counters: Arc<RawChannel>,
    /// The frame world clouds and transforms are in (the node's world frame).
    world: String,
}

/// The topics under `/<namespace>/` (and `/tf`), as the docs and the layout name them.
pub mod topics {
    /// Each bin's map in its bin frame (`foxglove.PointCloud`).
    pub const BIN_MAP: &str = "bin/map";
    /// The Gaussians the fused map took in with each bin, world frame (`foxglove.PointCloud`).
    pub const NEW_POINTS: &str = "map/new_points";
    /// Each bin's input (left) image (`foxglove.RawImage`).
    pub const INPUT: &str = "bin/input";
    /// Each bin's map rendered from its input view (`foxglove.RawImage`).
    pub const RENDER: &str = "bin/render";
    /// Each bin's latency (JSON).
    pub const LATENCY: &str = "latency";
    /// What each bin changed in the fused map (JSON).
    pub const INCREMENT: &str = "map/increment";
    /// The counters (JSON).
    pub const COUNTERS: &str = "diagnostics";
    /// World -> camera per frame and world -> `bin_<id>` per bin (`foxglove.FrameTransforms`).
    pub const TF: &str = "/tf";
}

impl Channels {
    fn image(&self, kind: ImageKind) -> &Channel<RawImage> {
        match kind {
            ImageKind::Input => &self.input,
            ImageKind::Render => &self.render,
        }
    }

    fn json(&self, kind: JsonKind) -> &Arc<RawChannel> {
        match kind {
            JsonKind::Latency => &self.latency,
            JsonKind::Increment => &self.increment,
            JsonKind::Counters => &self.counters,
        }
    }

    fn new(ctx: &Arc<Context>, namespace: &str, world: &str) -> Result<Self, FoxgloveError> {
        let topic = |t: &str| format!("/{namespace}/{t}");
        let json = |t: &str, title: &str, schema: &'static str| {
            ctx.channel_builder(topic(t))
                .message_encoding("json")
                .schema(Schema::new(title, "jsonschema", schema.as_bytes()))
                .build_raw()
                .map_err(|source| FoxgloveError::Channel {
                    topic: topic(t),
                    source,
                })
        };
        Ok(Self {
            bin_map: ctx.channel_builder(topic(topics::BIN_MAP)).build(),
            new_points: ctx.channel_builder(topic(topics::NEW_POINTS)).build(),
            input: ctx.channel_builder(topic(topics::INPUT)).build(),
            render: ctx.channel_builder(topic(topics::RENDER)).build(),
            tf: ctx.channel_builder(topics::TF).build(),
            latency: json(
                topics::LATENCY,
                "stereosplat.BinLatency",
                messages::LATENCY_SCHEMA,
            )?,
            increment: json(
                topics::INCREMENT,
                "stereosplat.MapIncrement",
                messages::INCREMENT_SCHEMA,
            )?,
            counters: json(
                topics::COUNTERS,
                "stereosplat.Counters",
                messages::COUNTERS_SCHEMA,
            )?,
            world: world.into(),
        })
    }
}

/// What the node hands the server's thread: the data of one message, with its frame name
/// and source stamp (ns) where it has them.
enum Item {
    /// A bin map in its frame.
    BinMap(String, i64, GaussianSet),
    /// The fused map's new Gaussians, relative to an origin in the world frame.
    NewPoints(Vec<WorldGaussian>, DVec3, i64),
    /// An input image or a render, in its bin's frame.
    Image(ImageKind, String, i64, RgbImage),
    /// World -> a camera frame.
    Camera(String, DAffine3, i64),
    /// World -> a bin frame (also kept for [`Item::BinFramesAgain`]).
    BinFrame(String, DAffine3, i64),
    /// Every bin frame so far.
    BinFramesAgain,
    /// A JSON message.
    Json(JsonKind, Value),
}

/// The image channels.
#[derive(Clone, Copy)]
enum ImageKind {
    Input,
    Render,
}

/// The JSON channels.
#[derive(Clone, Copy)]
enum JsonKind {
    Latency,
    Increment,
    Counters,
}

/// Items sent and dropped.
#[derive(Default)]
struct Stats {
    sent: AtomicU64,
    dropped: AtomicU64,
}

/// The running server and the queue to its thread.
pub struct Foxglove {
    addr: SocketAddr,
    channels: Arc<Channels>,
    tx: Option<Sender<Item>>,
    steal: Receiver<Item>,
    stats: Arc<Stats>,
    server: Option<WebSocketServerHandle>,
    thread: Option<JoinHandle<()>>,
    _context: Arc<Context>,
}

impl Foxglove {
    /// Binds `config.bind`, advertises the channels (topics under `/<namespace>/`, world
    /// clouds and transforms in `world_frame`) and starts the server's thread. Must be
    /// called inside a tokio runtime (the SDK serves clients on it). Prints a warning when
    /// the address is not loopback.
    pub async fn start(
        config: &FoxgloveConfig,
        namespace: &str,
        world_frame: &str,
    ) -> Result<Self, FoxgloveError> {
        if !config.bind.ip().is_loopback() {
            eprintln!(
                "warning: the Foxglove server listens on {}, which other machines may reach",
                config.bind
            );
        }
        // A context of its own: two nodes in one process keep their channels apart.
        let context = Context::new();
        let channels = Arc::new(Channels::new(&context, namespace, world_frame)?);
        let server = context
            .websocket_server()
            .name(format!("stereosplat ({namespace})"))
            .bind(config.bind.ip().to_string(), config.bind.port())
            .message_backlog_size(config.backlog.max(1))
            .start()
            .await
            .map_err(|source| FoxgloveError::Bind {
                addr: config.bind,
                source,
            })?;
        let addr = SocketAddr::new(config.bind.ip(), server.port());
        let (tx, rx) = crossbeam_channel::bounded::<Item>(config.queue.max(1));
        let steal = rx.clone();
        let stats = Arc::new(Stats::default());
        let thread = {
            let (channels, stats) = (channels.clone(), stats.clone());
            std::thread::Builder::new()
                .name("stereosplat-foxglove".into())
                .spawn(move || {
                    let mut bin_frames = Vec::new();
                    for item in rx.iter() {
                        log(&channels, &mut bin_frames, item);
                        stats.sent.fetch_add(1, Ordering::Relaxed);
                    }
                })
                .expect("spawning the Foxglove thread")
        };
        Ok(Self {
            addr,
            channels,
            tx: Some(tx),
            steal,
            stats,
            server: Some(server),
            thread: Some(thread),
            _context: context,
        })
    }

    /// The address the server listens on (the port picked when it was 0).
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// The URL a Foxglove client opens.
    pub fn url(&self) -> String {
        format!("ws://{}", self.addr)
    }

    /// Clients connected now.
    pub fn clients(&self) -> usize {
        self.server.as_ref().map_or(0, |s| s.client_count())
    }

    /// Queues `item` without blocking; on a full queue the oldest waiting item is dropped
    /// (and counted) to make room.
    fn send(&self, mut item: Item) {
        let Some(tx) = &self.tx else { return };
        loop {
            match tx.try_send(item) {
                Ok(()) => return,
                Err(TrySendError::Full(back)) => {
                    item = back;
                    if self.steal.try_recv().is_ok() {
                        self.stats.dropped.fetch_add(1, Ordering::Relaxed);
                    }
                }
                Err(TrySendError::Disconnected(_)) => {
                    self.stats.dropped.fetch_add(1, Ordering::Relaxed);
                    return;
                }
            }
        }
    }

    /// A bin's map, in its frame `bin_<id>`, stamped with the bin's source stamp (copied
    /// only when a client subscribed).
    pub fn bin_map(&self, bin_id: u64, stamp_ns: i64, set: &GaussianSet) {
        if self.channels.bin_map.has_sinks() {
            self.send(Item::BinMap(bin_frame(bin_id), stamp_ns, set.clone()));
        }
    }

    /// The Gaussians the fused map took in with a bin, and the increment's summary.
    /// Points are sent relative to `origin` (the bin's origin in the world frame).
    pub fn map_increment(
        &self,
        summary: Value,
        added: &[(GaussianId, WorldGaussian)],
        origin: DVec3,
        stamp_ns: i64,
    ) {
        if self.channels.new_points.has_sinks() {
            let added = added.iter().map(|(_, g)| *g).collect();
            self.send(Item::NewPoints(added, origin, stamp_ns));
        }
        self.json(JsonKind::Increment, summary);
    }

    /// A bin's input (left) image, in its frame `bin_<id>`.
    pub fn input_image(&self, bin_id: u64, stamp_ns: i64, image: &RgbImage) {
        self.image(ImageKind::Input, bin_id, stamp_ns, image);
    }

    /// A bin's render from its input view, in its frame `bin_<id>`.
    pub fn render(&self, bin_id: u64, stamp_ns: i64, image: &RgbImage) {
        self.image(ImageKind::Render, bin_id, stamp_ns, image);
    }

    fn image(&self, kind: ImageKind, bin_id: u64, stamp_ns: i64, image: &RgbImage) {
        if self.channels.image(kind).has_sinks() {
            let frame = bin_frame(bin_id);
            self.send(Item::Image(kind, frame, stamp_ns, image.clone()));
        }
    }

    /// Where a frame's left camera (`frame_id`) was in the world when it was taken.
    pub fn camera(&self, frame_id: &str, left_to_world: &DAffine3, stamp_ns: i64) {
        if self.channels.tf.has_sinks() {
            self.send(Item::Camera(frame_id.into(), *left_to_world, stamp_ns));
        }
    }

    /// Where a bin's frame `bin_<id>` is in the world (kept, and sent again by
    /// [`Foxglove::bin_frames_again`]).
    pub fn bin_frame(&self, bin_id: u64, bin_to_world: &DAffine3, stamp_ns: i64) {
        self.send(Item::BinFrame(bin_frame(bin_id), *bin_to_world, stamp_ns));
    }

    /// Every bin frame so far in one message, for clients that joined after them (what
    /// `/tf_static` is to ROS tools); the node calls it with every diagnostics period.
    pub fn bin_frames_again(&self) {
        if self.channels.tf.has_sinks() {
            self.send(Item::BinFramesAgain);
        }
    }

    /// A bin's latency (JSON, [`messages::latency_json`]).
    pub fn latency(&self, latency: Value) {
        self.json(JsonKind::Latency, latency);
    }

    /// The counters (JSON, [`messages::counters_json`]).
    pub fn counters(&self, counters: &Counters, stamp_ns: i64) {
        if self.channels.json(JsonKind::Counters).has_sinks() {
            let json = messages::counters_json(counters, stamp_ns);
            self.send(Item::Json(JsonKind::Counters, json));
        }
    }

    fn json(&self, kind: JsonKind, value: Value) {
        if self.channels.json(kind).has_sinks() {
            self.send(Item::Json(kind, value));
        }
    }

    /// Writes the server's own counters into `counters`: `foxglove/sent` (items logged to
    /// the SDK), `foxglove/dropped` (items dropped from the full queue) and
    /// `foxglove/clients` (connected now).
    pub fn count_into(&self, counters: &mut Counters) {
        counters.set("foxglove/sent", self.stats.sent.load(Ordering::Relaxed));
        counters.set(
            "foxglove/dropped",
            self.stats.dropped.load(Ordering::Relaxed),
        );
        counters.set("foxglove/clients", self.clients() as u64);
    }

    /// Logs what is queued, then closes the clients' connections and waits for them
    /// ([`STOP_GRACE`] at most); the counts stay readable ([`Foxglove::count_into`]).
    pub async fn stop(&mut self) {
        self.tx.take();
        if let Some(t) = self.thread.take() {
            // The thread ends when the queue is drained; joining it off the runtime's
            // threads keeps the runtime serving meanwhile.
            let _ = tokio::task::spawn_blocking(move || t.join()).await;
        }
        if let Some(server) = self.server.take() {
            // A client that stopped reading never takes the closing frame: past the grace
            // its task is aborted (dropping the handle does).
            let _ = tokio::time::timeout(STOP_GRACE, server.stop().wait()).await;
        }
    }
}

impl Drop for Foxglove {
    fn drop(&mut self) {
        self.tx.take();
        if let Some(server) = self.server.take() {
            // Without waiting: the clients' tasks are aborted with the handle.
            drop(server.stop());
        }
    }
}

/// A bin's frame name, as on `/tf_static`.
fn bin_frame(bin_id: u64) -> String {
    format!("bin_{bin_id}")
}

/// Turns one item into its message and logs it on its channel; `bin_frames` holds the
/// transform of every bin so far.
fn log(channels: &Channels, bin_frames: &mut Vec<FrameTransform>, item: Item) {
    match item {
        Item::BinMap(frame, stamp, set) => channels
            .bin_map
            .log(&messages::bin_cloud(&set, frame, stamp)),
        Item::NewPoints(added, origin, stamp) => channels.new_points.log(&messages::world_cloud(
            &added,
            channels.world.clone(),
            origin,
            stamp,
        )),
        Item::Image(kind, frame, stamp, img) => channels
            .image(kind)
            .log(&messages::raw_image(&img, frame, stamp)),
        Item::Camera(child, pose, stamp) => channels.tf.log(&FrameTransforms {
            transforms: vec![messages::frame_transform(
                &channels.world,
                child,
                &pose,
                stamp,
            )],
        }),
        Item::BinFrame(child, pose, stamp) => {
            let t = messages::frame_transform(&channels.world, child, &pose, stamp);
            bin_frames.push(t.clone());
            channels.tf.log(&FrameTransforms {
                transforms: vec![t],
            });
        }
        Item::BinFramesAgain => {
            if !bin_frames.is_empty() {
                channels.tf.log(&FrameTransforms {
                    transforms: bin_frames.clone(),
                });
            }
        }
        Item::Json(kind, value) => channels.json(kind).log(value.to_string().as_bytes()),
    }
}

#[cfg(test)]
mod tests {
    use super::topics;

    /// Every topic the shipped layout names is one the server advertises (namespace
    /// `stereosplat`), so the layout's panels find their data.
    #[test]
    fn the_layout_names_only_topics_the_server_advertises() {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../launch/foxglove_layout.json"
        );
        let layout: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
        let advertised: Vec<String> = [
            topics::BIN_MAP,
            topics::NEW_POINTS,
            topics::INPUT,
            topics::RENDER,
            topics::LATENCY,
            topics::INCREMENT,
            topics::COUNTERS,
        ]
        .iter()
        .map(|t| format!("/stereosplat/{t}"))
        .chain([topics::TF.to_string()])
        .collect();
        let mut named = Vec::new();
        collect_topics(&layout, &mut named);
        assert!(named.len() >= 5, "{named:?}");
        for topic in &named {
            assert!(advertised.contains(topic), "the layout names {topic}");
        }
        for want in ["/stereosplat/bin/input", "/stereosplat/bin/render"] {
            assert!(named.iter().any(|t| t == want), "no panel shows {want}");
        }
        let panels = layout["configById"].as_object().unwrap();
        for kind in ["3D!", "Image!", "Plot!"] {
            assert!(
                panels.keys().any(|k| k.starts_with(kind)),
                "no {kind} panel"
            );
        }
    }

    /// Topic names in keys and strings (`/topic` or `/topic.field` message paths).
    fn collect_topics(v: &serde_json::Value, out: &mut Vec<String>) {
        fn take(s: &str, out: &mut Vec<String>) {
            if s.starts_with("/stereosplat/") || s == "/tf" {
                out.push(s.split('.').next().unwrap_or(s).to_string());
            }
        }
        match v {
            serde_json::Value::String(s) => take(s, out),
            serde_json::Value::Object(m) => {
                for (k, v) in m {
                    take(k, out);
                    collect_topics(v, out);
                }
            }
            serde_json::Value::Array(a) => a.iter().for_each(|v| collect_topics(v, out)),
            _ => {}
        }
    }
}
