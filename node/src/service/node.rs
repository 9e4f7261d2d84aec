//! The node's event loop.

use std::collections::HashMap;
use std::future::Future;
use std::path::PathBuf;

use glam::DVec2;
use tokio::sync::mpsc;
use zenoh::sample::Locality;

use super::counters::Counters;
use super::inputs::{Inputs, Step};
use super::keys::{Direction, Keys, Topic, TOPICS};
use super::outputs::Outputs;
use crate::fusion::{bev_image, local_set, save_bev_png, BevView, FusionConfig, GlobalMap};
use crate::msg::std_msgs::Header;
use crate::msg::Message;
use crate::pipeline::binner::BinnerConfig;
use crate::pipeline::sync::SyncConfig;
use crate::pipeline::worker::{now_ns, RenderWith, Worker, WorkerEvent};
use crate::transport::{open, Outlet, TransportConfig, TransportError};

/// Everything the node is configured by.
#[derive(Clone, Debug)]
pub struct NodeConfig {
    /// How to reach the other processes.
    pub transport: TransportConfig,
    /// Topic keys.
    pub keys: Keys,
    /// Pairing of left, right and pose.
    pub sync: SyncConfig,
    /// Bin length.
    pub binner: BinnerConfig,
    /// Bins waiting for the worker at most (then the oldest waiting is dropped).
    pub queue_capacity: usize,
    /// The reconstructor (see `model::methods`).
    pub method: String,
    /// The global map's settings.
    pub fusion: FusionConfig,
    /// Where the fused map (PLY, bird's-eye PNG, saved map) goes when the node stops.
    pub out_dir: Option<PathBuf>,
    /// A global map snapshot is published after every this many bins (0: only on request).
    pub snapshot_every: u64,
    /// Per-bin renders: the bin map seen from its input view (drawn on the worker with this
    /// rasterizer), and a bird's-eye view of the global map; `Off` publishes neither.
    pub renders: RenderWith,
    /// The node's name (ROS 2 liveliness tokens, logs).
    pub name: String,
}

impl Default for NodeConfig {
    /// Loopback peer, namespace `stereosplat`, the default method (the learned network), a
    /// snapshot every 10 bins, renders on, nothing exported.
    fn default() -> Self {
        Self {
            transport: TransportConfig::default(),
            keys: Keys::default(),
            sync: SyncConfig::default(),
            binner: BinnerConfig::default(),
            queue_capacity: 4,
            method: model::methods::DEFAULT.into(),
            fusion: FusionConfig::default(),
            out_dir: None,
            snapshot_every: 10,
            renders: RenderWith::Auto,
            name: "stereosplat_node".into(),
        }
    }
}

/// What a run of the node did.
#[derive(Clone, Debug, Default)]
pub struct NodeSummary {
    /// Bins whose maps were published.
    pub bins_published: u64,
    /// Gaussians in the global map at the end.
    pub global_gaussians: usize,
    /// The counters at the end.
    pub counters: Counters,
}

/// Why the node stopped with an error (bad input never stops it).
#[derive(Debug, thiserror::Error)]
pub enum ServiceError {
    /// The zenoh session.
    #[error(transparent)]
    Transport(#[from] TransportError),
    /// The method name.
    #[error(transparent)]
    Method(#[from] model::methods::MethodError),
    /// The fusion settings.
    #[error(transparent)]
    Fusion(#[from] crate::fusion::FusionError),
    /// Declaring the publishers (a bad node name) or publishing.
    #[error(transparent)]
    Outlet(#[from] crate::transport::OutletError),
    /// Writing the exports.
    #[error("exporting the global map: {0}")]
    Export(String),
}

fn zenoh_err(e: zenoh::Error) -> TransportError {
    TransportError::Zenoh(e.to_string())
}

/// Runs the node until `stop` completes; then finishes the queued bins, exports the global
/// map and returns what happened.
pub async fn run(
    config: NodeConfig,
    stop: impl Future<Output = ()>,
) -> Result<NodeSummary, ServiceError> {
    run_announced(config, stop, || {}).await
}

/// [`run`], calling `ready` once the session is open (its endpoints bound) and the inputs are
/// subscribed: a node that cannot bind fails before it says it is ready.
pub async fn run_announced(
    config: NodeConfig,
    stop: impl Future<Output = ()>,
    ready: impl FnOnce(),
) -> Result<NodeSummary, ServiceError> {
    let session = open(&config.transport).await?;
    let keys = &config.keys;
    let (inputs, outputs): (Vec<Topic>, Vec<Topic>) =
        TOPICS.iter().partition(|t| t.direction == Direction::Input);
    let outlet = Outlet::declare(&session, keys, &config.name, &outputs, &inputs).await?;
    // Input keys looked up per sample, built once.
    let input_keys: HashMap<String, Topic> = inputs.iter().map(|&t| (keys.key(t), t)).collect();
    // One subscriber for every input key keeps the samples in arrival order across keys,
    // so left, right and pose of a frame reach the synchroniser together. Samples this
    // session publishes itself are not delivered to it.
    let input = session
        .declare_subscriber(keys.input_wildcard())
        .allowed_origin(Locality::Remote)
        .await
        .map_err(zenoh_err)?;
    let snapshot_requests = session
        .declare_queryable(keys.snapshot_request())
        .await
        .map_err(zenoh_err)?;

    let (out_tx, mut out_rx) = mpsc::unbounded_channel::<WorkerEvent>();
    let worker = Worker::spawn(
        model::methods::by_name(&config.method)?,
        config.renders,
        config.queue_capacity,
        move |o| {
            let _ = out_tx.send(o);
        },
    );
    let mut steps = Inputs::new(config.sync, config.binner);
    let bev = config.renders != RenderWith::Off;
    let mut outputs = Outputs::new(&outlet, config.fusion, bev, config.snapshot_every)?;
    // Listen endpoints other machines can reach (each also warned about on stderr).
    let exposed = config.transport.exposure_warnings()?.len() as u64;
    if exposed > 0 {
        outputs.counters.set("warning/exposed_listen", exposed);
    }
    ready();
    tokio::pin!(stop);

    loop {
        let mut todo = Vec::new();
        tokio::select! {
            _ = &mut stop => break,
            Ok(s) = input.recv_async() => {
                match input_keys.get(s.key_expr().as_str()) {
                    Some(&t) => {
                        todo = steps.on_sample(t, &s.payload().to_bytes(), &mut outputs.counters);
                    }
                    None => outputs.counters.add("ignored/unknown_key", 1),
                }
            },
            Ok(q) = snapshot_requests.recv_async() => {
                let header = Header::new(now_ns(), "world");
                match outputs.snapshot(header) {
                    Ok(m) => q.reply(q.key_expr().clone(), m.encode()).await.map_err(zenoh_err)?,
                    Err(_) => outputs.counters.add("error/encode_map_update", 1),
                }
            },
            Some(event) = out_rx.recv() => outputs.worker_event(event, worker.drops()).await?,
        }
        for step in todo {
            match step {
                Step::Submit(job) => {
                    worker.submit(*job);
                }
                Step::Closed(bin_id) => outputs.bin_closed(bin_id, worker.drops()).await?,
            }
        }
        outputs.counters.set("dropped/worker_queue", worker.drops());
    }

    // Finish what is queued, then publish it.
    let drops = worker.drops();
    worker.shutdown();
    while let Ok(event) = out_rx.try_recv() {
        outputs.worker_event(event, drops).await?;
    }
    outputs.counters.set("dropped/worker_queue", drops);
    if let Some(dir) = &config.out_dir {
        export(&outputs.map, dir)?;
    }
    let mut summary = std::mem::take(&mut outputs.summary);
    summary.global_gaussians = outputs.map.len();
    summary.counters = std::mem::take(&mut outputs.counters);
    drop(outputs);
    drop(outlet);
    // Closing (rather than dropping) the session flushes what is still queued for peers.
    session.close().await.map_err(zenoh_err)?;
    Ok(summary)
}

/// Writes the global map as 3DGS PLY (positions relative to the latest bin's origin, which is
/// recorded in the file name's sidecar), a bird's-eye PNG and the restorable map file.
fn export(map: &GlobalMap, dir: &std::path::Path) -> Result<(), ServiceError> {
    let err = |e: &dyn std::fmt::Display| ServiceError::Export(e.to_string());
    std::fs::create_dir_all(dir).map_err(|e| err(&e))?;
    map.save(dir.join("global_map.ssgmap"))
        .map_err(|e| err(&e))?;
    let Some(origin) = map.latest_origin() else {
        return Ok(());
    };
    let frame = glam::DAffine3::from_translation(origin);
    let set = local_set(map.gaussians().map(|(_, g)| g), frame).map_err(|e| err(&e))?;
    renderer::ply::save_ply(&set, dir.join("global_map.ply")).map_err(|e| err(&e))?;
    std::fs::write(
        dir.join("global_map_origin.json"),
        format!(
            "{{\"x\": {}, \"y\": {}, \"z\": {}}}\n",
            origin.x, origin.y, origin.z
        ),
    )
    .map_err(|e| err(&e))?;
    let view = BevView {
        centre: DVec2::new(origin.x, origin.y),
        width: 512,
        height: 512,
        metres_per_pixel: 0.25,
        background: [0, 0, 0],
    };
    let image = bev_image(map.gaussians().map(|(_, g)| g), &view).map_err(|e| err(&e))?;
    save_bev_png(&image, dir.join("global_map_bev.png")).map_err(|e| err(&e))
}
