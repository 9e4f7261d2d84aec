//! The node's event loop.

use std::future::Future;
use std::path::PathBuf;

use glam::DVec2;
use model::frame::{RgbImage, StereoFrame, StereoRig};
use tokio::sync::mpsc;

use super::counters::Counters;
use super::keys::Keys;
use super::outputs::Outputs;
use crate::fusion::{bev_image, local_set, save_bev_png, BevView, FusionConfig, GlobalMap};
use crate::msg::geometry_msgs::PoseStamped;
use crate::msg::image::{intrinsics_from_camera_info, rgb_from_image};
use crate::msg::pose::affine_from_pose;
use crate::msg::sensor_msgs::{CameraInfo, Image};
use crate::msg::std_msgs::Header;
use crate::msg::Message;
use crate::pipeline::binner::{BinEvent, Binner, BinnerConfig};
use crate::pipeline::sync::{SyncConfig, Synced, Synchronizer};
use crate::pipeline::worker::{now_ns, Job, RenderWith, Stamps, Worker, WorkerEvent};
use crate::transport::{open, TransportConfig, TransportError};

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
    /// Loopback peer, namespace `stereosplat`, the SGM baseline, a snapshot every 10 bins,
    /// renders on, nothing exported.
    fn default() -> Self {
        Self {
            transport: TransportConfig::default(),
            keys: Keys::default(),
            sync: SyncConfig::default(),
            binner: BinnerConfig::default(),
            queue_capacity: 4,
            method: "sgm".into(),
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
    Method(#[from] model::methods::UnknownMethod),
    /// The fusion settings.
    #[error(transparent)]
    Fusion(#[from] crate::fusion::FusionError),
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
    let session = open(&config.transport).await?;
    let keys = &config.keys;
    let sub = |key: String| {
        let s = &session;
        async move { s.declare_subscriber(key).await.map_err(zenoh_err) }
    };
    let left = sub(keys.left_image()).await?;
    let right = sub(keys.right_image()).await?;
    let left_info = sub(keys.left_info()).await?;
    let right_info = sub(keys.right_info()).await?;
    let pose = sub(keys.pose()).await?;
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
    let mut sync: Synchronizer<(RgbImage, i64), RgbImage, glam::DAffine3> =
        Synchronizer::new(config.sync);
    let mut binner: Binner<(StereoFrame, Stamps)> = Binner::new(config.binner);
    let bev = config.renders != RenderWith::Off;
    let mut outputs = Outputs::new(&session, keys, config.fusion, bev, config.snapshot_every)?;
    let (mut left_k, mut right_k): (Option<CameraInfo>, Option<CameraInfo>) = (None, None);
    let mut rig: Option<StereoRig> = None;
    let mut frame_index = 0u32;
    tokio::pin!(stop);

    loop {
        let mut frames = Vec::new();
        let counters = &mut outputs.counters;
        tokio::select! {
            _ = &mut stop => break,
            Ok(s) = left.recv_async() => match decode_image(&s) {
                Some((t, img)) => frames = sync.push_left(t, (img, now_ns())),
                None => counters.add("bad_message/left_image", 1),
            },
            Ok(s) = right.recv_async() => match decode_image(&s) {
                Some((t, img)) => frames = sync.push_right(t, img),
                None => counters.add("bad_message/right_image", 1),
            },
            Ok(s) = pose.recv_async() => match decode_pose(&s) {
                Some((t, p)) => frames = sync.push_pose(t, p),
                None => counters.add("bad_message/pose", 1),
            },
            Ok(s) = left_info.recv_async() => match CameraInfo::decode(&s.payload().to_bytes()) {
                Ok(m) => {
                    left_k = Some(m);
                    rig = rig_of(left_k.as_ref(), right_k.as_ref());
                }
                Err(_) => counters.add("bad_message/left_camera_info", 1),
            },
            Ok(s) = right_info.recv_async() => match CameraInfo::decode(&s.payload().to_bytes()) {
                Ok(m) => {
                    right_k = Some(m);
                    rig = rig_of(left_k.as_ref(), right_k.as_ref());
                }
                Err(_) => counters.add("bad_message/right_camera_info", 1),
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
        for f in frames {
            let Some(rig) = rig else {
                outputs.counters.add("dropped/no_camera_info", 1);
                continue;
            };
            let job = frame_job(f, &mut frame_index);
            match binner.push(job.clone(), job.0.left_to_world) {
                BinEvent::Opened { bin_id, first } => submit(&worker, bin_id, first, rig),
                BinEvent::Closed {
                    bin_id, next_first, ..
                } => {
                    submit(&worker, bin_id + 1, next_first, rig);
                    outputs.bin_closed(bin_id, worker.drops()).await?;
                }
                BinEvent::Inside => {}
                BinEvent::Rejected => outputs.counters.add("dropped/non_finite_pose", 1),
            }
        }
        let c = sync.counters();
        outputs.counters.set("sync/late", c.late);
        outputs.counters.set("sync/unmatched", c.unmatched);
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
    Ok(summary)
}

/// A stamped image from a sample, `None` if it does not decode or convert.
fn decode_image(sample: &zenoh::sample::Sample) -> Option<(i64, RgbImage)> {
    let msg = Image::decode(&sample.payload().to_bytes()).ok()?;
    Some((msg.header.stamp.to_nanos(), rgb_from_image(&msg).ok()?))
}

/// A stamped camera-to-world pose from a sample, `None` if it does not decode or is invalid.
fn decode_pose(sample: &zenoh::sample::Sample) -> Option<(i64, glam::DAffine3)> {
    let msg = PoseStamped::decode(&sample.payload().to_bytes()).ok()?;
    Some((msg.header.stamp.to_nanos(), affine_from_pose(&msg).ok()?))
}

/// The rig once both camera infos are known and consistent.
fn rig_of(left: Option<&CameraInfo>, right: Option<&CameraInfo>) -> Option<StereoRig> {
    let (k, _) = intrinsics_from_camera_info(left?).ok()?;
    let (_, baseline) = intrinsics_from_camera_info(right?).ok()?;
    (baseline > 0.0).then_some(StereoRig {
        intrinsics: k,
        baseline,
    })
}

type FrameJob = (StereoFrame, Stamps);

fn frame_job(f: Synced<(RgbImage, i64), RgbImage, glam::DAffine3>, index: &mut u32) -> FrameJob {
    let ((left, arrival_ns), right, left_to_world) = (f.left, f.right, f.pose);
    *index += 1;
    let frame = StereoFrame {
        index: *index - 1,
        left,
        right,
        left_to_world,
    };
    let stamps = Stamps {
        arrival_ns,
        opened_ns: now_ns(),
        ..Stamps::default()
    };
    (frame, stamps)
}

fn submit(worker: &Worker, bin_id: u64, (frame, stamps): FrameJob, rig: StereoRig) {
    worker.submit(Job {
        bin_id,
        frame,
        rig,
        stamps,
    });
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
