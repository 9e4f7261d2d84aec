//! A worker process (`stereosplat worker`): it answers bin requests on `<ns>/workers/<id>`
//! with the worker thread's own path ([`crate::pipeline::worker::run_job`]: the
//! reconstructor at its point, the self-check with the node's policy, the render) and
//! announces itself with a liveliness token on the same key, so a node sees it come and go.
//!
//! A request for another reconstructor than this worker's, or of another protocol
//! version, is refused with an error reply saying both, and counted. Bins run one at a time
//! on one thread; a second bin arriving while one runs waits, a third is refused as busy
//! (a node sends one at a time), so memory stays bounded whatever arrives. Busy is told
//! from the request's first bytes ([`Request::kind`]), before its images are decoded.
//!
//! The queryable is declared complete: it answers its whole key, as the node's greeting
//! and bins ask (the node sends them to every queryable on the key and takes replies from
//! the session whose greeting it took, [`super::pool`]).

use std::future::Future;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use crossbeam_channel::Sender;
use tokio::sync::mpsc::{unbounded_channel, UnboundedSender};
use zenoh::query::Query;

use super::fingerprint::Fingerprint;
use super::wire::{BinJob, Hello, Reply, Request, RequestKind, REQUEST_PREFIX};
use crate::pipeline::operating::PointRunner;
use crate::pipeline::self_check::{OnCheckFail, SelfCheck};
use crate::pipeline::worker::{run_job, Job, RenderWith, WorkerEvent};
use crate::transport::Keys;
use crate::transport::{open, TransportConfig, TransportError};

/// How a worker process runs.
#[derive(Clone, Debug)]
pub struct ServeConfig {
    /// How to reach the node (or a router).
    pub transport: TransportConfig,
    /// The node's keys (its namespace).
    pub keys: Keys,
    /// This worker's id, one key chunk (no `/`, `*`, `$`, `?` or `#`).
    pub id: String,
    /// The rasterizer of the renders a node asks for.
    pub renders: RenderWith,
    /// Threads the reconstructor uses (reported to the node).
    pub threads: u32,
}

/// What a worker process did.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct ServeSummary {
    /// Bins whose map was sent.
    pub bins: u64,
    /// Requests refused: another fingerprint or protocol, or busy.
    pub refused: u64,
    /// Requests that did not decode.
    pub bad_requests: u64,
}

/// Why a worker process stopped before its time.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    /// The id is not one key chunk.
    #[error("worker id `{0}` must be non-empty, without `/`, `*`, `$`, `?` or `#`")]
    BadId(String),
    /// The transport failed.
    #[error(transparent)]
    Transport(#[from] TransportError),
}

#[derive(Default)]
struct Counts {
    bins: AtomicU64,
    refused: AtomicU64,
    bad: AtomicU64,
}

/// A bin for the compute thread, and where its replies go.
type Work = (BinJob, UnboundedSender<Reply>);

/// Answers bin requests with `runner` (whose reconstructor `fingerprint` describes) until
/// `stop` completes; `ready` is called with the worker's key once it is announced.
pub async fn serve(
    config: ServeConfig,
    runner: PointRunner,
    fingerprint: Fingerprint,
    stop: impl Future<Output = ()>,
    ready: impl FnOnce(&str),
) -> Result<ServeSummary, ServeError> {
    let id = &config.id;
    if id.is_empty() || id.contains(['/', '*', '$', '?', '#']) {
        return Err(ServeError::BadId(id.clone()));
    }
    let session = open(&config.transport).await?;
    let key = config.keys.worker(id);
    let queries = session
        .declare_queryable(key.clone())
        .complete(true)
        .await
        .map_err(TransportError::from)?;
    let token = session
        .liveliness()
        .declare_token(key.clone())
        .await
        .map_err(TransportError::from)?;
    let (work_tx, work_rx) = crossbeam_channel::bounded::<Work>(1);
    let compute = compute_thread(runner, config.renders, work_rx);
    let counts = Arc::new(Counts::default());
    let me = Hello {
        fingerprint,
        threads: config.threads,
    };
    ready(&key);
    tokio::pin!(stop);
    loop {
        tokio::select! {
            _ = &mut stop => break,
            Ok(query) = queries.recv_async() => {
                let (me, work_tx, counts) = (me.clone(), work_tx.clone(), Arc::clone(&counts));
                tokio::spawn(answer(query, me, work_tx, counts));
            }
        }
    }
    drop(token);
    drop(queries);
    drop(work_tx);
    session.close().await.map_err(TransportError::from)?;
    let _ = tokio::task::spawn_blocking(move || compute.join()).await;
    Ok(ServeSummary {
        bins: counts.bins.load(Ordering::Relaxed),
        refused: counts.refused.load(Ordering::Relaxed),
        bad_requests: counts.bad.load(Ordering::Relaxed),
    })
}

/// Answers one query.
async fn answer(query: Query, me: Hello, work: Sender<Work>, counts: Arc<Counts>) {
    if work.is_full() && kind(&query) == Some(RequestKind::Bin) {
        counts.refused.fetch_add(1, Ordering::Relaxed);
        let _ = query.reply_err("refused: busy with another bin").await;
        return;
    }
    let payload = query.payload().map(|p| p.to_bytes());
    let request = match Request::decode(payload.as_deref().unwrap_or_default()) {
        Ok(r) => r,
        Err(e) => {
            counts.bad.fetch_add(1, Ordering::Relaxed);
            let _ = query.reply_err(format!("not a bin request: {e}")).await;
            return;
        }
    };
    let asked = match &request {
        Request::Hello(f) => f,
        Request::Bin(job) => &job.fingerprint,
    };
    if asked != &me.fingerprint {
        counts.refused.fetch_add(1, Ordering::Relaxed);
        let why = format!(
            "refused: this worker runs {}; the node asks for {}",
            me.fingerprint.describe(),
            asked.describe()
        );
        eprintln!("{why}");
        let _ = query.reply_err(why).await;
        return;
    }
    let job = match request {
        Request::Hello(_) => {
            let _ = query
                .reply(query.key_expr().clone(), Reply::Hello(me).encode())
                .await;
            return;
        }
        Request::Bin(job) => *job,
    };
    let (tx, mut rx) = unbounded_channel();
    if work.try_send((job, tx)).is_err() {
        counts.refused.fetch_add(1, Ordering::Relaxed);
        let _ = query.reply_err("refused: busy with another bin").await;
        return;
    }
    while let Some(reply) = rx.recv().await {
        if matches!(reply, Reply::Map(..)) {
            counts.bins.fetch_add(1, Ordering::Relaxed);
        }
        let _ = query.reply(query.key_expr().clone(), reply.encode()).await;
    }
}

/// What `query` asks, from its payload's first bytes (`None`: not a request).
fn kind(query: &Query) -> Option<RequestKind> {
    let mut prefix = [0u8; REQUEST_PREFIX];
    let mut reader = query.payload()?.reader();
    std::io::Read::read_exact(&mut reader, &mut prefix).ok()?;
    Request::kind(&prefix).ok()
}

/// The thread that owns the reconstructor and the rasterizer and runs bins one at a time.
fn compute_thread(
    mut runner: PointRunner,
    renders: RenderWith,
    work: crossbeam_channel::Receiver<Work>,
) -> std::thread::JoinHandle<()> {
    std::thread::Builder::new()
        .name("stereosplat-worker".into())
        .spawn(move || {
            let mut raster = renders.raster();
            let mut checks: Vec<(OnCheckFail, SelfCheck)> = Vec::new();
            for (job, replies) in work.iter() {
                let policy = job.on_check_fail;
                let at = match checks.iter().position(|(p, _)| *p == policy) {
                    Some(i) => i,
                    None => {
                        checks.push((policy, SelfCheck::new(policy)));
                        checks.len() - 1
                    }
                };
                let attempt = job.attempt;
                let raster = raster.as_mut().filter(|_| job.render);
                let job = Job {
                    bin_id: job.bin_id,
                    frame: job.frame,
                    rig: job.rig,
                    stamps: job.stamps,
                    point: 0,
                };
                let mut send = |event| {
                    let reply = match event {
                        WorkerEvent::Map(out) => Reply::Map(attempt, out),
                        WorkerEvent::Render(r) => Reply::Render(r),
                    };
                    let _ = replies.send(reply);
                };
                run_job(&mut runner, 0, &mut checks[at].1, raster, job, 0, &mut send);
            }
        })
        .expect("spawning the worker process's compute thread")
}
