//! The node's event loop.

use std::collections::HashMap;
use std::future::Future;
use std::path::PathBuf;
use std::time::Instant;

use model::methods::MethodSpec;
use renderer::formats::MapFormat;
use tokio::sync::mpsc;
use zenoh::handlers::FifoChannelHandler;
use zenoh::pubsub::Subscriber;
use zenoh::query::{Query, Queryable};
use zenoh::sample::{Locality, Sample};

use super::error::ServiceError;
use super::input_thread::InputThread;
use super::inputs::{Inputs, Step};
use super::limits::InputLimits;
use super::outputs::{NodeSummary, Outputs};
use super::pace::Pace;
use super::pose_topics::PoseTopics;
use super::snapshot_gate::SnapshotGate;
use super::snapshot_reply::answer_snapshot;
use super::start_report::announce_start;
use super::workers::{publish_released, workers_event, WorkerBinCounters, STALL_CHECK};
use crate::foxglove::{Foxglove, FoxgloveConfig};
use crate::fusion::FusionConfig;
use crate::memory::{limit_arenas_to_cores, Releaser};
use crate::msg::Message;
use crate::pipeline::binner::BinnerConfig;
use crate::pipeline::operating::{OperatingConfig, PointRunner};
use crate::pipeline::self_check::OnCheckFail;
use crate::pipeline::sync::SyncConfig;
use crate::pipeline::worker::{RenderWith, Worker, WorkerEvent};
use crate::remote::{Dispatch, Fingerprint, Pool, PoolConfig, Slot};
use crate::store::map_files::{export, start_map, Start, StartMap};
use crate::store::map_store::{Compaction, MapStore, Paging};
use crate::tf::{PoseSource, PoseSourceConfig};
use crate::transport::keys::{Direction, Keys, Topic, DIAGNOSTICS, TOPICS};
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
    /// The reconstructor: method, preset, weights and settings (`model::methods`); a
    /// learned method's `tiny-plus` preset runs StereoSplat+'s progressive pass per bin.
    pub method: MethodSpec,
    /// What to do with a bin whose map fails its self-check (see
    /// [`crate::pipeline::self_check`]).
    pub on_check_fail: OnCheckFail,
    /// The global map's settings.
    pub fusion: FusionConfig,
    /// Where the fused map (PLY, bird's-eye PNG, saved map) goes when the node stops, and
    /// where its checkpoint is kept and resumed from (see [`crate::store::map_files`]).
    pub out_dir: Option<PathBuf>,
    /// The format of the global map file written to `out_dir` when the node stops.
    pub map_format: MapFormat,
    /// Resume the checkpoint in `out_dir` or start fresh.
    pub start_map: StartMap,
    /// The map's journal in `out_dir` is synced after every this many fused bins, before
    /// they are published (0: nothing is written until the node stops). 1 is what makes "a
    /// crash loses nothing that was published" hold; larger values trade that for fewer
    /// syncs.
    pub checkpoint_every: u64,
    /// When the journal is folded into the checkpoint's base ([`crate::store::map_store`]).
    pub compaction: Compaction,
    /// Which tiles of the map stay in memory while a journal is kept (`None`: all of it;
    /// [`crate::store::map_store`]).
    pub paging: Option<Paging>,
    /// A global map snapshot is published after every this many bins (0: only on request).
    pub snapshot_every: u64,
    /// Per-bin renders: the bin map seen from its input view (drawn on the worker with this
    /// rasterizer), and a bird's-eye view of the global map; `Off` publishes neither.
    pub renders: RenderWith,
    /// The node's name (ROS 2 liveliness tokens, logs).
    pub name: String,
    /// The counters go out on `diagnostics` this often as well as with every bin's latency,
    /// so a node that publishes no bins still says why (zero: only with the bins).
    pub diagnostics_every: std::time::Duration,
    /// Sizes, poses and calibrations accepted, and the snapshot query rate.
    pub limits: InputLimits,
    /// A Foxglove WebSocket server streaming the outputs (`None`: none).
    pub foxglove: Option<FoxgloveConfig>,
    /// Operating points chosen per bin to meet a latency budget (`None`: every bin runs
    /// the method, preset, weights and settings above).
    pub operating: Option<OperatingConfig>,
    /// Who makes the bins' maps: the node's own worker thread, worker processes, or both.
    pub workers: WorkersConfig,
    /// Where the left camera's poses come from: the `pose` topic (`None`), or `/tf` or the
    /// odometry topic through a tf buffer.
    pub pose_source: Option<PoseSourceConfig>,
    /// The frame the poses are in, and so the node's outputs (the map, bin poses, the
    /// transforms it publishes): `world` by default, the pose source's world frame (`map`,
    /// `odom`) when poses come from the robot's tree.
    pub world_frame: String,
    /// The memory the allocator keeps after it is freed goes back to the system this often,
    /// and its arenas are capped at one per core ([`crate::memory`]), so resident memory
    /// follows the map in memory on a long drive (zero: neither, the allocator's defaults).
    pub release_memory_every: std::time::Duration,
}

/// Who makes the bins' maps ([`crate::remote`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct WorkersConfig {
    /// The node's own worker thread takes bins too (off: only worker processes do; bins
    /// wait for one to join).
    pub local: bool,
    /// A worker process that has not sent a bin's map this long after it was handed the
    /// bin is taken as stalled: the bin goes to another worker, and the stalled one's late
    /// answer is discarded and counted.
    pub timeout: std::time::Duration,
}

impl Default for WorkersConfig {
    /// The node's own thread on; 60 s before a worker process is taken as stalled (a full
    /// 1408x376 bin whose learned map fails the self-check takes about 12 s on this
    /// machine's two cores, and about twice that on one).
    fn default() -> Self {
        Self {
            local: true,
            timeout: std::time::Duration::from_secs(60),
        }
    }
}

impl NodeConfig {
    /// The reconstructor [`NodeConfig::method`] names.
    pub fn reconstructor(
        &self,
    ) -> Result<Box<dyn model::reconstruct::Reconstructor + Send>, model::methods::MethodError>
    {
        self.method.build()
    }

    /// What worker processes must run to take this node's bins.
    pub fn fingerprint(&self) -> Result<Fingerprint, crate::remote::FingerprintError> {
        Fingerprint::of(&self.method)
    }

    /// What the node asks of its worker processes: its reconstructor, self-check policy and
    /// renders; with a latency budget it takes none (it chooses a point per bin and runs
    /// every point itself).
    pub fn pool_config(&self) -> Result<PoolConfig, ServiceError> {
        Ok(PoolConfig {
            fingerprint: self.fingerprint()?,
            on_check_fail: self.on_check_fail,
            render: self.renders != RenderWith::Off,
            refuse_all: self.operating.as_ref().map(|_| {
                "the node chooses an operating point per bin (--latency-budget) and runs them itself"
                    .to_string()
            }),
            hello_timeout: std::time::Duration::from_secs(10),
            // Long enough that a stalled worker's late answer is still heard, and counted.
            late_limit: self
                .workers
                .timeout
                .saturating_mul(4)
                .max(std::time::Duration::from_secs(30)),
        })
    }

    /// The worker's operating points: the table's rows, most accurate first, with a
    /// latency budget; else the one reconstructor [`Self::reconstructor`] makes.
    pub fn points(&self) -> Result<Vec<PointRunner>, model::methods::MethodError> {
        match &self.operating {
            Some(o) => o
                .table
                .rows
                .iter()
                .map(|r| PointRunner::build(&r.point))
                .collect(),
            None => Ok(vec![PointRunner::whole(self.reconstructor()?)]),
        }
    }
}

impl Default for NodeConfig {
    /// Loopback peer, namespace `stereosplat`, the default method (the learned network, with
    /// bins failing the self-check replaced by SGM's), a
    /// snapshot every 10 bins, renders on, nothing exported (with an out folder: resume its
    /// checkpoint, checkpoint after every bin, export PLY), diagnostics every second, no
    /// Foxglove server.
    fn default() -> Self {
        Self {
            transport: TransportConfig::default(),
            keys: Keys::default(),
            sync: SyncConfig::default(),
            binner: BinnerConfig::default(),
            queue_capacity: DEFAULT_QUEUE,
            method: MethodSpec::default(),
            on_check_fail: OnCheckFail::default(),
            fusion: FusionConfig::default(),
            out_dir: None,
            map_format: MapFormat::Ply,
            start_map: StartMap::Resume,
            checkpoint_every: 1,
            compaction: Compaction::default(),
            paging: Some(Paging::default()),
            snapshot_every: 10,
            renders: RenderWith::Auto,
            name: "stereosplat_node".into(),
            diagnostics_every: std::time::Duration::from_secs(1),
            limits: InputLimits::default(),
            foxglove: None,
            operating: None,
            workers: WorkersConfig::default(),
            pose_source: None,
            world_frame: crate::msg::tf2_msgs::WORLD.into(),
            release_memory_every: std::time::Duration::from_secs(5),
        }
    }
}

fn zenoh_err(e: zenoh::Error) -> TransportError {
    TransportError::Zenoh(e.to_string())
}

/// Bins waiting for the worker at most, by default (beyond it the oldest waiting is
/// dropped): the node's and `run --queue`'s.
pub const DEFAULT_QUEUE: usize = 2;

/// Runs the node until `stop` completes; then finishes the queued bins, exports the global
/// map and returns what happened.
pub async fn run(
    config: NodeConfig,
    stop: impl Future<Output = ()>,
) -> Result<NodeSummary, ServiceError> {
    run_announced(config, stop, |_| {}).await
}

/// [`run`], calling `ready` with the node's session once it is open (its endpoints bound) and
/// the inputs are subscribed: a node that cannot bind fails before it says it is ready. A
/// subscriber declared on that session (the live view's) hears the node's outputs and
/// every peer connected to the node, its inputs too.
pub async fn run_announced(
    config: NodeConfig,
    stop: impl Future<Output = ()>,
    ready: impl FnOnce(&zenoh::Session),
) -> Result<NodeSummary, ServiceError> {
    let points = config.points()?;
    run_with(config, points, stop, ready).await
}

/// [`run_announced`] with the operating points the caller has already made from `config`
/// ([`NodeConfig::points`]; the loopback run makes them before it opens its client
/// sessions, so a missing weights file fails there, and each network is loaded once).
pub async fn run_with(
    config: NodeConfig,
    points: Vec<PointRunner>,
    stop: impl Future<Output = ()>,
    ready: impl FnOnce(&zenoh::Session),
) -> Result<NodeSummary, ServiceError> {
    let empty = crate::fusion::GlobalMap::new(config.fusion)?;
    let start = start_map(config.out_dir.as_deref(), empty, config.start_map)?;
    announce_start(&start);
    let mut binner = config.binner;
    if let Some(last) = start.map.last_bin_id() {
        binner.first_bin_id = binner.first_bin_id.max(last + 1);
    }
    // Bound before the zenoh session opens, so an address in use fails first.
    let foxglove = start_foxglove(&config).await?;
    let session = open(&config.transport).await?;
    let keys = &config.keys;
    let (inputs, outputs): (Vec<Topic>, Vec<Topic>) =
        TOPICS.iter().partition(|t| t.direction == Direction::Input);
    let outlet = Outlet::declare(&session, keys, &config.name, &outputs, &inputs).await?;
    let (input, snapshot_requests) = declare_inputs(&session, keys).await?;
    // Input keys looked up per sample, built once.
    let input_keys: HashMap<String, Topic> = inputs.iter().map(|&t| (keys.key(t), t)).collect();

    let (pool, mut pool_rx) = Pool::start(&session, keys, config.pool_config()?).await?;
    let mut dispatch = Dispatch::new(config.queue_capacity, config.workers.local);
    let (out_tx, mut out_rx) = mpsc::unbounded_channel::<WorkerEvent>();
    let point_names: Vec<String> = points.iter().map(|p| p.name.clone()).collect();
    let mut pace = config.operating.as_ref().map(Pace::new);
    // The dispatcher holds the waiting bins; the thread is handed one when it is idle.
    let worker = Worker::spawn_points(
        points,
        pace.as_ref().map(Pace::governor),
        config.renders,
        1,
        config.on_check_fail,
        move |o| {
            let _ = out_tx.send(o);
        },
    );
    let pose_source = match config.pose_source.clone() {
        Some(c) => Some(PoseSource::new(c)?),
        None => None,
    };
    let pose_topics = match pose_source {
        Some(_) => Some(PoseTopics::declare(&session, keys).await?),
        None => None,
    };
    let (mut input_thread, mut batches) =
        InputThread::spawn(Inputs::new(config.sync, binner, config.limits, pose_source));
    let mut snapshot_gate =
        SnapshotGate::new(keys.snapshot_request(), config.limits.snapshot_interval);
    let mut outputs = open_outputs(&config, &outlet, start, foxglove.as_ref(), &point_names)?;
    ready(&session);
    tokio::pin!(stop);
    let diagnostics_on = !config.diagnostics_every.is_zero();
    let mut diagnostics = delayed_interval(config.diagnostics_every);
    let mut stall_check = delayed_interval(STALL_CHECK);
    // After `stop`: no more inputs; the bins in hand are finished (for a worker
    // process's timeout at most) and published.
    let mut stopping: Option<Instant> = None;
    let mut worker_bins = WorkerBinCounters::default();
    // Until the input thread has ended (after `stop`) and its last steps are taken.
    let mut inputs_open = true;

    loop {
        let mut todo = Vec::new();
        tokio::select! {
            _ = &mut stop, if stopping.is_none() => {
                stopping = Some(Instant::now() + config.workers.timeout);
                input_thread.close();
            },
            Ok(s) = input.recv_async(), if stopping.is_none() => {
                match input_keys.get(s.key_expr().as_str()) {
                    Some(&t) => input_thread.send(t, s.payload().clone()).await,
                    None => outputs.counters.add("ignored/unknown_key", 1),
                }
            },
            (t, s) = PoseTopics::next(pose_topics.as_ref()), if stopping.is_none() => {
                input_thread.send(t, s.payload().clone()).await;
            },
            batch = batches.recv(), if inputs_open => match batch {
                Some(batch) => {
                    if let Some(counters) = &batch.counters {
                        outputs.counters.set_all(counters);
                    }
                    todo = batch.steps;
                }
                // Closed at stop, after the samples it held.
                None => inputs_open = false,
            },
            Ok(q) = snapshot_requests.recv_async() => {
                answer_snapshot(q, &mut outputs, &mut snapshot_gate).await?;
            },
            Some(event) = out_rx.recv() => {
                dispatch.event(&Slot::Local, None, event);
            },
            Some(event) = pool_rx.recv() => {
                workers_event(&mut dispatch, event, &mut outputs.counters);
            },
            _ = stall_check.tick() => {
                input_thread.tick();
                outputs.retry_held(dispatch.drops()).await?;
                for id in dispatch.stalled(Instant::now(), config.workers.timeout) {
                    eprintln!(
                        "worker {id} sent no map within {:?}: its bin goes to another",
                        config.workers.timeout
                    );
                    outputs.counters.add("workers/stalled", 1);
                }
            },
            _ = diagnostics.tick(), if diagnostics_on => {
                let msg = outputs.diagnostics();
                outlet.put(DIAGNOSTICS, msg.encode()).await?;
                outputs.put_static_tf().await?;
                if let Some(f) = &foxglove {
                    f.bin_frames_again();
                }
            },
        }
        let on_tf = config.pose_source.is_none();
        take_steps(
            todo,
            on_tf,
            pace.as_ref(),
            foxglove.as_ref(),
            &mut dispatch,
            &mut outputs,
        )
        .await?;
        for a in dispatch.assign(Instant::now()) {
            match a.slot.clone() {
                Slot::Local => _ = worker.submit(a.job),
                Slot::Remote(id) => {
                    worker_bins.count(&id, &mut outputs.counters);
                    pool.send(&id, a);
                }
            }
        }
        publish_released(&mut dispatch, &mut outputs, pace.as_mut(), &point_names).await?;
        let at_rest =
            !inputs_open && (dispatch.idle() || (!config.workers.local && dispatch.workers() == 0));
        if stopping.is_some_and(|deadline| at_rest || Instant::now() > deadline) {
            break;
        }
    }

    // The node's own thread finishes its bin, if it holds one.
    worker.shutdown();
    while let Ok(event) = out_rx.try_recv() {
        dispatch.event(&Slot::Local, None, event);
    }
    publish_released(&mut dispatch, &mut outputs, pace.as_mut(), &point_names).await?;
    drop(pool);
    let mut summary = finish(&config, dispatch, outputs).await?;
    if let Some(mut f) = foxglove {
        // What was still queued is logged first, so the counts are final.
        f.stop().await;
        f.count_into(&mut summary.counters);
    }
    drop(outlet);
    // Closing (rather than dropping) the session flushes what is still queued for peers.
    session.close().await.map_err(zenoh_err)?;
    Ok(summary)
}

/// The Foxglove server `config` asks for, started (its address bound).
async fn start_foxglove(config: &NodeConfig) -> Result<Option<Foxglove>, ServiceError> {
    let Some(c) = &config.foxglove else {
        return Ok(None);
    };
    let f = Foxglove::start(c, &config.keys.namespace, &config.world_frame).await?;
    eprintln!("foxglove ready: {}", f.url());
    Ok(Some(f))
}

/// The node's input subscriber and its snapshot queryable on `session`. One subscriber for
/// every input key keeps the samples in arrival order across keys, so left, right and pose
/// of a frame reach the synchroniser together; samples this session publishes itself are
/// not delivered to it.
async fn declare_inputs(
    session: &zenoh::Session,
    keys: &Keys,
) -> Result<
    (
        Subscriber<FifoChannelHandler<Sample>>,
        Queryable<FifoChannelHandler<Query>>,
    ),
    ServiceError,
> {
    let input = session
        .declare_subscriber(keys.input_wildcard())
        .allowed_origin(Locality::Remote)
        .await
        .map_err(zenoh_err)?;
    let snapshot_requests = session
        .declare_queryable(keys.snapshot_request())
        .await
        .map_err(zenoh_err)?;
    Ok((input, snapshot_requests))
}

/// The node's outputs on `outlet`, fusing into the started map: its store in the out folder,
/// the memory releaser, Foxglove, and the warnings about endpoints others can reach counted.
fn open_outputs<'a>(
    config: &NodeConfig,
    outlet: &'a Outlet,
    start: Start,
    foxglove: Option<&'a Foxglove>,
    point_names: &[String],
) -> Result<Outputs<'a>, ServiceError> {
    let bev = config.renders != RenderWith::Off;
    let store = match config.out_dir.clone() {
        Some(dir) => Some(MapStore::new(
            dir,
            &start.map,
            config.checkpoint_every,
            config.compaction,
            config.paging,
        )?),
        None => None,
    };
    if !config.release_memory_every.is_zero() {
        limit_arenas_to_cores();
    }
    let releaser =
        Releaser::start(config.release_memory_every).map_err(ServiceError::MemoryRelease)?;
    let resumed = start.resumed_from.is_some();
    let mut outputs = Outputs::new(outlet, start.map, bev, config.snapshot_every, store)
        .with_releaser(releaser)
        .with_foxglove(foxglove)
        .with_world_frame(&config.world_frame)
        .with_points(point_names.to_vec());
    if resumed {
        outputs.announce_resume();
    }
    // Listen endpoints other machines can reach (each also warned about on stderr).
    let exposed = config.transport.exposure_warnings()?.len() as u64;
    if exposed > 0 {
        outputs.counters.set("warning/exposed_listen", exposed);
    }
    if foxglove.is_some_and(|f| !f.addr().ip().is_loopback()) {
        outputs.counters.set("warning/exposed_foxglove", 1);
    }
    Ok(outputs)
}

/// A timer ticking every `period` (at least 1 ms), its missed ticks delayed, not bunched.
fn delayed_interval(period: std::time::Duration) -> tokio::time::Interval {
    let mut interval = tokio::time::interval(period.max(std::time::Duration::from_millis(1)));
    interval.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    interval
}

/// Takes the input thread's steps: bins opened go to the dispatcher, bins closed and camera
/// poses to the outputs (`on_tf`: the camera's pose goes out on `/tf`, when no pose source
/// reads it from there).
async fn take_steps(
    steps: Vec<Step>,
    on_tf: bool,
    pace: Option<&Pace>,
    foxglove: Option<&Foxglove>,
    dispatch: &mut Dispatch,
    outputs: &mut Outputs<'_>,
) -> Result<(), ServiceError> {
    for step in steps {
        match step {
            Step::Submit(job) => {
                if let Some(p) = pace {
                    p.bin_opened(job.stamps.opened_ns);
                }
                if let Some(f) = foxglove {
                    f.input_image(job.bin_id, job.stamps.source_ns, &job.frame.left);
                }
                dispatch.submit(*job);
            }
            Step::Closed(bin_id) => outputs.bin_closed(bin_id, dispatch.drops()).await?,
            Step::Camera(camera) => outputs.camera_moved(camera, on_tf).await?,
        }
    }
    Ok(())
}

/// After the last bin is published: counts the bins left waiting, finishes the outputs and
/// the store and exports the map into the out folder; returns the summary.
async fn finish(
    config: &NodeConfig,
    dispatch: Dispatch,
    mut outputs: Outputs<'_>,
) -> Result<NodeSummary, ServiceError> {
    let drops = dispatch.drops();
    let unfinished = dispatch.unfinished();
    if unfinished > 0 {
        eprintln!("{unfinished} bins were still waiting for a worker when the node stopped");
        outputs.counters.set("dropped/at_stop", unfinished as u64);
    }
    outputs.finish(drops).await?;
    outputs.fused.close_store(&mut outputs.counters);
    // A map that never held a bin (nothing arrived, nothing was resumed) leaves no files:
    // an empty checkpoint would only shadow a later run's start.
    if let (Some(dir), Some(_)) = (&config.out_dir, outputs.fused.map.last_bin_id()) {
        export(&outputs.fused.map, dir, config.map_format)?;
    }
    let mut summary = std::mem::take(&mut outputs.summary);
    summary.global_gaussians = outputs.fused.map.total_len() as usize;
    summary.counters = std::mem::take(&mut outputs.counters);
    Ok(summary)
}
