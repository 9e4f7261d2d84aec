//! The worker thread: it owns the reconstructor and the rasterizer, takes one bin's first
//! stereo pair at a time from a bounded queue and hands back the bin's Gaussian map with its
//! timings as soon as the model is done, then the map's render from the input view (so
//! renders never delay the map). Every map is checked against the bin's own stereo pair
//! first, and a failing one is flagged, dimmed or replaced by SGM's ([`super::self_check`]).
//! The async side
//! never blocks on it: when the queue is full the oldest waiting bin is dropped and counted
//! (keep newest), because a map of the road just driven is worth more than a late one. A panic
//! inside the reconstructor is caught, reported on that bin, and the worker goes on.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

use crossbeam_channel::{Receiver, Sender, TrySendError};
use glam::DAffine3;
use model::frame::{RgbImage, Side, StereoFrame, StereoRig};
use model::reconstruct::{ModelSplit, Reconstructor, StereoView};
use renderer::{GaussianSet, Raster, RenderSettings};

use super::operating::{Governor, PointRunner};
use super::self_check::{CheckOutcome, OnCheckFail, SelfCheck};

/// Whether and how each bin's map is drawn from its input (left) view: off, or one of the
/// renderer's choices ([`renderer::RenderWith`], which owns the pick of rasterizer).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum RenderWith {
    /// No renders.
    Off,
    /// The CPU reference rasterizer.
    Cpu,
    /// wgpu; when no adapter is found the worker says so once and uses the CPU instead.
    Gpu,
    /// wgpu on a hardware GPU, else the CPU reference.
    #[default]
    Auto,
}

impl RenderWith {
    /// The rasterizer, made on the thread that will use it.
    pub fn raster(self) -> Option<Raster> {
        let with = match self {
            RenderWith::Off => return None,
            RenderWith::Cpu => renderer::RenderWith::Cpu,
            RenderWith::Gpu => renderer::RenderWith::Gpu,
            RenderWith::Auto => renderer::RenderWith::Auto,
        };
        Some(with.raster())
    }
}

/// Wall-clock time in nanoseconds since the Unix epoch: the clock of every latency stamp, so
/// stamps from different processes compare.
pub fn now_ns() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as i64)
}

/// Latency stamps of one bin (ns, [`now_ns`]'s clock; 0 = not reached), and the source
/// stamp every output derived from the bin carries.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Stamps {
    /// The `header.stamp` of the bin's first frame (its left image's), in the inputs' clock:
    /// the stamp of the bin's map, pose, render and map update, so a subscriber pairs them
    /// with the frame they came from.
    pub source_ns: i64,
    /// The bin's first frame's last part arrived (the frame was complete).
    pub arrival_ns: i64,
    /// The binner opened the bin (the frame entered the worker queue).
    pub opened_ns: i64,
    /// The reconstructor started.
    pub model_start_ns: i64,
    /// The reconstructor returned and the map was checked (and replaced, if it failed and
    /// the policy says so).
    pub model_end_ns: i64,
    /// Renders of the bin (if any) were done.
    pub render_end_ns: i64,
    /// The map was fused into the global map and its change journaled (set by the node's
    /// outputs, never sent to or from a worker process).
    pub map_fused_ns: i64,
    /// The map was published.
    pub publish_ns: i64,
    /// The progressive pass's stage ends within the model, in `BinLatency`'s order (G_base,
    /// pseudo render, enhance, G_plus, fuse); all 0 without the pass.
    pub stage_end_ns: [i64; 5],
}

impl Stamps {
    /// Places the stages of `split` after `model_start_ns`, one after another.
    pub fn set_split(&mut self, split: &ModelSplit) {
        let mut t = self.model_start_ns;
        let durations = [
            split.base_ms,
            split.pseudo_render_ms,
            split.enhance_ms,
            split.plus_ms,
            split.fuse_ms,
        ];
        for (end, ms) in self.stage_end_ns.iter_mut().zip(durations) {
            t += (ms * 1e6) as i64;
            *end = t;
        }
    }
}

/// One bin for the worker: its first stereo frame and the rig.
#[derive(Clone, Debug)]
pub struct Job {
    /// The bin.
    pub bin_id: u64,
    /// The bin's first frame; its left camera is the bin frame.
    pub frame: StereoFrame,
    /// The rig the frame was taken with.
    pub rig: StereoRig,
    /// Stamps so far.
    pub stamps: Stamps,
    /// The operating point to run it with, an index into the worker's points, when the
    /// worker has no governor to choose (0 when the node runs one point).
    pub point: usize,
}

/// What the worker made of a job.
#[derive(Debug)]
pub struct Output {
    /// The bin.
    pub bin_id: u64,
    /// Bin frame to world (the first left camera's pose), f64.
    pub bin_to_world: DAffine3,
    /// The bin's map in the bin frame, or why there is none.
    pub result: Result<GaussianSet, String>,
    /// The map's self-check and what was done about it.
    pub check: CheckOutcome,
    /// A [`Rendered`] follows for this bin.
    pub render_follows: bool,
    /// Stamps up to the model's end.
    pub stamps: Stamps,
    /// Jobs still waiting when this one finished.
    pub queue_depth: usize,
    /// The operating point it ran with (the job's, within the worker's points).
    pub point: usize,
}

/// A bin's map rendered from its input (left) view, sent after its [`Output`].
#[derive(Debug)]
pub struct Rendered {
    /// The bin.
    pub bin_id: u64,
    /// The render, or why the rasterizer failed.
    pub image: Result<RgbImage, String>,
    /// When the render was done ([`now_ns`]).
    pub render_end_ns: i64,
}

/// What the worker hands back, in order: a bin's map, then (renders on, map made) its render.
#[derive(Debug)]
pub enum WorkerEvent {
    /// The map and its timings.
    Map(Box<Output>),
    /// The render of the map just sent.
    Render(Rendered),
}

/// Whether [`Worker::submit`] had to drop a waiting bin.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Submitted {
    /// Queued behind what was waiting.
    Queued,
    /// The queue was full: the oldest waiting bin was dropped to make room.
    DroppedOldest,
}

/// The worker thread and its queue.
pub struct Worker {
    tx: Option<Sender<Job>>,
    steal: Receiver<Job>,
    drops: Arc<AtomicU64>,
    thread: Option<JoinHandle<()>>,
}

impl Worker {
    /// Starts the worker with `reconstructor`, renders drawn `with` a rasterizer, a queue of
    /// `capacity` bins, maps failing their self-check handled as `on_check_fail` says, and
    /// `on_event` called on the worker thread for every map and render.
    pub fn spawn(
        reconstructor: Box<dyn Reconstructor + Send>,
        with: RenderWith,
        capacity: usize,
        on_check_fail: OnCheckFail,
        on_event: impl FnMut(WorkerEvent) + Send + 'static,
    ) -> Self {
        let points = vec![PointRunner::whole(reconstructor)];
        Self::spawn_points(points, None, with, capacity, on_check_fail, on_event)
    }

    /// [`Self::spawn`] with several operating points: each job runs with the one
    /// `governor` chooses when the worker takes the job (and is told how long the job took
    /// on the worker), or with the one the job's `point` names when there is no governor
    /// (the last, when it names none of them).
    pub fn spawn_points(
        mut points: Vec<PointRunner>,
        governor: Option<Arc<Mutex<Governor>>>,
        with: RenderWith,
        capacity: usize,
        on_check_fail: OnCheckFail,
        mut on_event: impl FnMut(WorkerEvent) + Send + 'static,
    ) -> Self {
        assert!(!points.is_empty(), "a worker needs an operating point");
        let (tx, rx) = crossbeam_channel::bounded::<Job>(capacity.max(1));
        let steal = rx.clone();
        let thread = std::thread::Builder::new()
            .name("stereosplat-worker".into())
            .spawn(move || {
                let mut raster = with.raster();
                let mut self_check = SelfCheck::new(on_check_fail);
                for job in rx.iter() {
                    let point = match &governor {
                        Some(g) => lock(g).choose().point,
                        None => job.point,
                    }
                    .min(points.len() - 1);
                    let (model_ns, render_ns) = run_job(
                        &mut points[point],
                        point,
                        &mut self_check,
                        raster.as_mut(),
                        job,
                        rx.len(),
                        &mut on_event,
                    );
                    if let Some(g) = &governor {
                        lock(g).record(point, model_ns, render_ns);
                    }
                }
            })
            .expect("spawning the worker thread");
        Self {
            tx: Some(tx),
            steal,
            drops: Arc::new(AtomicU64::new(0)),
            thread: Some(thread),
        }
    }

    /// Queues `job` without blocking; on a full queue the oldest waiting job is dropped.
    pub fn submit(&self, mut job: Job) -> Submitted {
        let tx = self.tx.as_ref().expect("worker running until shutdown");
        let mut dropped = false;
        loop {
            match tx.try_send(job) {
                Ok(()) => break,
                Err(TrySendError::Full(back)) => {
                    job = back;
                    if self.steal.try_recv().is_ok() {
                        self.drops.fetch_add(1, Ordering::Relaxed);
                        dropped = true;
                    }
                }
                Err(TrySendError::Disconnected(_)) => {
                    // The worker thread is gone (it only exits on shutdown): count the loss.
                    self.drops.fetch_add(1, Ordering::Relaxed);
                    return Submitted::DroppedOldest;
                }
            }
        }
        if dropped {
            Submitted::DroppedOldest
        } else {
            Submitted::Queued
        }
    }

    /// Bins dropped so far because the worker fell behind.
    pub fn drops(&self) -> u64 {
        self.drops.load(Ordering::Relaxed)
    }

    /// Finishes the queued bins, then stops the thread.
    pub fn shutdown(mut self) {
        self.tx.take();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for Worker {
    fn drop(&mut self) {
        self.tx.take();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Runs one job, handing its map and render to `on_event`; returns the nanoseconds the
/// model path and the render took. The worker thread and a worker process
/// ([`mod@crate::remote::serve`]) both make bins' maps with it.
pub fn run_job(
    runner: &mut PointRunner,
    point: usize,
    self_check: &mut SelfCheck,
    raster: Option<&mut Raster>,
    job: Job,
    queue_depth: usize,
    on_event: &mut dyn FnMut(WorkerEvent),
) -> (i64, i64) {
    let mut stamps = job.stamps;
    let origin = job.frame.left_to_world;
    let left_camera = job.rig.local_camera(origin, origin, Side::Left);
    let view = StereoView {
        left: &job.frame.left,
        right: &job.frame.right,
        left_camera,
        right_camera: job.rig.local_camera(origin, origin, Side::Right),
    };
    stamps.model_start_ns = now_ns();
    let (result, check) = runner.bin_map(self_check, &[view]);
    stamps.model_end_ns = now_ns();
    let model_end_ns = stamps.model_end_ns;
    let mut render_ns = 0;
    if let Some(split) = runner.reconstructor.last_split().filter(|_| result.is_ok()) {
        stamps.set_split(&split);
    }
    // The set goes out with the map; the render needs only a copy of what it draws.
    let to_render = match (&raster, &result) {
        (Some(_), Ok(set)) => Some(set.clone()),
        _ => None,
    };
    on_event(WorkerEvent::Map(Box::new(Output {
        bin_id: job.bin_id,
        bin_to_world: origin,
        result,
        check,
        render_follows: to_render.is_some(),
        stamps,
        queue_depth,
        point,
    })));
    if let (Some(raster), Some(set)) = (raster, to_render) {
        let image = raster
            .render(&set, &left_camera, &RenderSettings::default())
            .map(|o| RgbImage {
                width: o.width,
                height: o.height,
                data: o.rgb,
            })
            .map_err(|e| e.to_string());
        let render_end_ns = now_ns();
        on_event(WorkerEvent::Render(Rendered {
            bin_id: job.bin_id,
            image,
            render_end_ns,
        }));
        render_ns = render_end_ns - model_end_ns;
    }
    (model_end_ns - stamps.model_start_ns, render_ns)
}

/// The governor, also after a panic elsewhere left its lock poisoned (its state is a set of
/// windows of numbers, valid after any partial update).
fn lock(g: &Mutex<Governor>) -> std::sync::MutexGuard<'_, Governor> {
    g.lock().unwrap_or_else(|p| p.into_inner())
}
