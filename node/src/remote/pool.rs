//! The node's side of its worker processes, on its zenoh session: it watches their
//! liveliness tokens under `<ns>/workers/*`, greets each newcomer (a worker whose
//! fingerprint differs from the node's is refused), sends each assigned bin as a query to
//! its worker's key and turns the replies into [`PoolEvent`]s for the node's loop, which
//! feeds them to its [`super::dispatch::Dispatch`].
//!
//! Every reply is bound to its worker, and a map to the bin the node sent
//! ([`super::admit`]):
//!
//! - **Which session is the worker.** zenoh's liveliness samples do not name the session
//!   that declared a token, so the worker is the session its greeting reply came from
//!   (`Reply::replier_id`), recorded when it joins. A greeting answered by more than one
//!   session is refused. Queries go to every queryable on the worker's key
//!   ([`QueryTarget::All`]), so another session's queryable there cannot take a bin away
//!   from the worker; that session's replies are dropped unread and counted
//!   (`discarded/worker_replier`), and the worker keeps its bin.
//! - **Bounded.** Replies are taken in zenoh's callback, which never waits: one larger
//!   than the bin's limit ([`super::admit::Rules::reply_limit`]) goes on as its size only,
//!   and at most [`REPLIES_PER_BIN`] go on per bin, into a channel of that size; any more
//!   are dropped there and the worker's reply is rejected as too many. Decoding and the
//!   node's own checks (its self-check) run on a blocking thread, off the node's loop.
//! - **Workers and greetings.** At most [`MAX_WORKERS`] workers are joined and
//!   [`MAX_GREETINGS`] greetings under way; a token announced beyond either is refused at
//!   once, without a task, and a worker's binding goes when its token does.
//! - **Events** reach the node's loop through a channel of [`EVENTS`]; while it is full,
//!   the tasks sending into it wait (nothing is lost, and no zenoh thread waits).
//!
//! The node keeps each job it sends for as long as its query runs (one per worker
//! process at a time), to check the answer against.

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use tokio::sync::mpsc::{channel, Receiver, Sender};
use tokio::sync::Semaphore;
use zenoh::bytes::ZBytes;
use zenoh::query::{ConsolidationMode, QueryTarget};
use zenoh::sample::SampleKind;
use zenoh::session::ZenohId;
use zenoh::Session;

use super::admit::{admit_map, admit_render, Rejection, Rules, HELLO_LIMIT};
use super::dispatch::Assignment;
use super::fingerprint::Fingerprint;
use super::wire::{BinJob, Reply, Request};
use crate::pipeline::self_check::OnCheckFail;
use crate::pipeline::worker::{Job, WorkerEvent};
use crate::transport::Keys;
use crate::transport::TransportError;

/// Events waiting for the node's loop at most.
pub const EVENTS: usize = 256;

/// Replies a worker sends for one bin at most: its map and the map's render (or one error).
pub const REPLIES_PER_BIN: usize = 2;

/// Workers joined at most; a token announced beyond them is refused at once.
pub const MAX_WORKERS: usize = 64;

/// Greetings under way at most; a token announced while they are is refused at once (it
/// may announce again), so a flood of tokens costs no task per token.
pub const MAX_GREETINGS: usize = 8;

/// What the node asks of its worker processes.
#[derive(Clone, Debug)]
pub struct PoolConfig {
    /// The reconstructor every worker must run.
    pub fingerprint: Fingerprint,
    /// What a worker does with a map failing its self-check.
    pub on_check_fail: OnCheckFail,
    /// Whether workers render each map from its input view.
    pub render: bool,
    /// Why worker processes are not taken, when they are not (a node choosing operating
    /// points per bin runs them all itself).
    pub refuse_all: Option<String>,
    /// How long a greeting may take.
    pub hello_timeout: Duration,
    /// How long a worker's late answer is still heard (and discarded) after its bin was
    /// given to another.
    pub late_limit: Duration,
}

/// What happened among the worker processes.
#[derive(Debug)]
pub enum PoolEvent {
    /// A worker answered the greeting with the node's fingerprint: it takes bins.
    Joined {
        /// The worker.
        id: String,
        /// Threads its reconstructor uses.
        threads: u32,
    },
    /// A worker was refused (another fingerprint, no answer, refuse-all).
    Refused {
        /// The worker.
        id: String,
        /// Why, in words.
        why: String,
    },
    /// A worker's liveliness token went away (it stopped, died, or lost the network).
    Left(String),
    /// A map or render for `attempt` of a bin, as the node takes it ([`super::admit`]).
    Reply {
        /// The worker.
        id: String,
        /// The attempt it answers.
        attempt: u32,
        /// The map or render.
        event: WorkerEvent,
    },
    /// A worker's reply was dropped: the worker gets no more bins.
    Rejected {
        /// The worker.
        id: String,
        /// The bin.
        bin: u64,
        /// Why.
        why: Rejection,
    },
    /// A worker's query for a bin ended: it will send nothing more for that attempt.
    Ended {
        /// The worker.
        id: String,
        /// The bin.
        bin: u64,
        /// The attempt.
        attempt: u32,
        /// Why it ended without a map, when the worker said (an error reply, a reply that
        /// did not decode).
        error: Option<String>,
        /// Nothing at all came back from the worker: it is unreachable (it died and its
        /// token has not gone yet, or it never answered before the late limit).
        silent: bool,
        /// Replies from other sessions than the worker's, dropped unread.
        foreign: u64,
    },
}

/// The node's worker processes (a clone shares the session and the event channel).
#[derive(Clone)]
pub struct Pool {
    session: Session,
    keys: Keys,
    config: PoolConfig,
    rules: Rules,
    tx: Sender<PoolEvent>,
    /// The session each joined worker's greeting came from.
    repliers: Arc<Mutex<HashMap<String, ZenohId>>>,
}

/// What a query's callback passes on of one reply.
enum Heard {
    /// A sample's payload.
    Payload(ZBytes),
    /// An error reply's words.
    Error(String),
    /// A reply over the limit: only its size.
    TooLarge(usize),
}

/// Whose replies a query takes.
#[derive(Clone, Copy)]
enum Whose {
    /// Any session's (a greeting: the node learns who answers).
    Any,
    /// The worker's session only; none when the worker was never greeted.
    Worker(Option<ZenohId>),
}

/// The replies of one query as its callback passes them on, with who sent each.
struct Asked {
    heard: Receiver<(Option<ZenohId>, Heard)>,
    /// Replies from other sessions, dropped.
    foreign: Arc<AtomicU64>,
    /// Replies beyond [`REPLIES_PER_BIN`], dropped.
    extra: Arc<AtomicU64>,
    /// The query ran out of time before every queryable had finished.
    timed_out: Arc<AtomicBool>,
}

/// What became of one reply to a bin.
enum Taken {
    /// A map or render the node takes.
    Event(WorkerEvent),
    /// A reply that does not decode or answers something else.
    Unusable(String),
    /// A reply the node drops, and its worker with it.
    Rejected(Rejection),
}

impl Pool {
    /// Starts watching for workers under `keys` on `session`; their events come out of
    /// the receiver.
    pub async fn start(
        session: &Session,
        keys: &Keys,
        config: PoolConfig,
    ) -> Result<(Self, Receiver<PoolEvent>), TransportError> {
        let (tx, rx) = channel(EVENTS);
        let watch = session
            .liveliness()
            .declare_subscriber(format!("{}/*", keys.workers()))
            .history(true)
            .await?;
        let pool = Self {
            session: session.clone(),
            keys: keys.clone(),
            rules: Rules::of(&config.fingerprint, config.on_check_fail),
            config,
            tx,
            repliers: Arc::default(),
        };
        let greeter = pool.clone();
        let greetings = Arc::new(Semaphore::new(MAX_GREETINGS));
        let prefix = format!("{}/", keys.workers());
        tokio::spawn(async move {
            while let Ok(sample) = watch.recv_async().await {
                let Some(id) = sample.key_expr().as_str().strip_prefix(&prefix) else {
                    continue;
                };
                let id = id.to_string();
                match sample.kind() {
                    SampleKind::Put => {
                        let known = lock(&greeter.repliers).len();
                        let permit = greetings.clone().try_acquire_owned();
                        let why = match permit {
                            _ if known >= MAX_WORKERS => {
                                format!("the node takes at most {MAX_WORKERS} workers")
                            }
                            Err(_) => format!(
                                "{MAX_GREETINGS} greetings are under way: announce again later"
                            ),
                            Ok(permit) => {
                                let greeter = greeter.clone();
                                tokio::spawn(async move {
                                    greeter.greet(id).await;
                                    drop(permit);
                                });
                                continue;
                            }
                        };
                        _ = greeter.tx.send(PoolEvent::Refused { id, why }).await;
                    }
                    SampleKind::Delete => {
                        lock(&greeter.repliers).remove(&id);
                        _ = greeter.tx.send(PoolEvent::Left(id)).await;
                    }
                }
            }
        });
        Ok((pool, rx))
    }

    /// Asks worker `id` who it is; it joins when it runs the node's fingerprint.
    async fn greet(self, id: String) {
        let verdict = match &self.config.refuse_all {
            Some(why) => Err(why.clone()),
            None => self.hello(&id).await,
        };
        let event = match verdict {
            Ok((threads, zid)) => {
                lock(&self.repliers).insert(id.clone(), zid);
                PoolEvent::Joined { id, threads }
            }
            Err(why) => PoolEvent::Refused { id, why },
        };
        let _ = self.tx.send(event).await;
    }

    /// Greets worker `id`: its thread count and its session when it runs the node's
    /// fingerprint and one session answers, else why not.
    async fn hello(&self, id: &str) -> Result<(u32, ZenohId), String> {
        let want = &self.config.fingerprint;
        let payload = Request::Hello(want.clone()).encode();
        let timeout = self.config.hello_timeout;
        let mut asked = self
            .ask(id, payload, timeout, HELLO_LIMIT, Whose::Any)
            .await?;
        let mut first = None;
        let mut sessions = Vec::new();
        while let Some((replier, heard)) = asked.heard.recv().await {
            if !sessions.contains(&replier) {
                sessions.push(replier);
            }
            first.get_or_insert((replier, heard));
        }
        if sessions.len() > 1 || asked.extra.load(Ordering::Relaxed) > 0 {
            return Err("more than one session answers the greeting for it".into());
        }
        let Some((replier, heard)) = first else {
            return Err("it did not answer the greeting".into());
        };
        let zid = replier.ok_or("its greeting names no session")?;
        let bytes = match heard {
            Heard::Payload(p) => p,
            Heard::Error(why) => return Err(why),
            Heard::TooLarge(n) => return Err(format!("its greeting of {n} bytes is too large")),
        };
        match Reply::decode(&bytes.to_bytes()) {
            Ok(Reply::Hello(h)) if &h.fingerprint == want => Ok((h.threads, zid)),
            Ok(Reply::Hello(h)) => Err(format!(
                "it runs {}; the node runs {}",
                h.fingerprint.describe(),
                want.describe()
            )),
            Ok(_) => Err("it answered the greeting with a bin".into()),
            Err(e) => Err(format!("its reply does not decode: {e}")),
        }
    }

    /// Queries worker `id`'s key (every queryable on it) with `payload`; the replies
    /// `from` takes, at most [`REPLIES_PER_BIN`] of them and of `limit` bytes each (larger
    /// ones as their size), come out of the receiver until the query ends.
    async fn ask(
        &self,
        id: &str,
        payload: Vec<u8>,
        timeout: Duration,
        limit: usize,
        from: Whose,
    ) -> Result<Asked, String> {
        let (tx, heard) = channel(REPLIES_PER_BIN);
        let (foreign, extra) = (Arc::new(AtomicU64::new(0)), Arc::new(AtomicU64::new(0)));
        let (other, more) = (Arc::clone(&foreign), Arc::clone(&extra));
        let timed_out = Arc::new(AtomicBool::new(false));
        let late = Arc::clone(&timed_out);
        let taken = AtomicUsize::new(0);
        let callback = move |reply: zenoh::query::Reply| {
            let replier = reply.replier_id().map(|r| r.zid());
            // zenoh's own error reply when the query times out names no replier.
            if replier.is_none() && reply.result().is_err() {
                late.store(true, Ordering::Relaxed);
                return;
            }
            let ours = match from {
                Whose::Any => true,
                Whose::Worker(want) => want.is_some_and(|w| replier == Some(w)),
            };
            if !ours {
                other.fetch_add(1, Ordering::Relaxed);
                return;
            }
            if taken.fetch_add(1, Ordering::Relaxed) >= REPLIES_PER_BIN {
                more.fetch_add(1, Ordering::Relaxed);
                return;
            }
            let body = match reply.result() {
                Ok(s) => s.payload(),
                Err(e) => e.payload(),
            };
            let heard = match reply.result() {
                _ if body.len() > limit => Heard::TooLarge(body.len()),
                Ok(_) => Heard::Payload(body.clone()),
                Err(_) => Heard::Error(body.try_to_string().unwrap_or_default().into()),
            };
            if tx.try_send((replier, heard)).is_err() {
                more.fetch_add(1, Ordering::Relaxed);
            }
        };
        // A map and its render share the key: consolidation would hold back the map.
        self.session
            .get(self.keys.worker(id))
            .payload(payload)
            .target(QueryTarget::All)
            .consolidation(ConsolidationMode::None)
            .timeout(timeout)
            .callback(callback)
            .await
            .map_err(|e| e.to_string())?;
        Ok(Asked {
            heard,
            foreign,
            extra,
            timed_out,
        })
    }

    /// Sends assignment `a` to its worker (a worker process's slot).
    pub fn send(&self, id: &str, a: Assignment) {
        let bin = BinJob {
            bin_id: a.job.bin_id,
            attempt: a.attempt,
            fingerprint: self.config.fingerprint.clone(),
            on_check_fail: self.config.on_check_fail,
            render: self.config.render,
            frame: a.job.frame,
            rig: a.job.rig,
            stamps: a.job.stamps,
        };
        let payload = bin.request();
        let job = Job {
            bin_id: bin.bin_id,
            frame: bin.frame,
            rig: bin.rig,
            stamps: bin.stamps,
            point: a.job.point,
        };
        let replier = lock(&self.repliers).get(id).copied();
        let this = self.clone();
        let id = id.to_string();
        tokio::spawn(async move { this.run_bin(id, job, a.attempt, payload, replier).await });
    }

    /// Runs `attempt` of `job` on worker `id` (the session `replier`) to its end.
    async fn run_bin(
        self,
        id: String,
        job: Job,
        attempt: u32,
        payload: Vec<u8>,
        replier: Option<ZenohId>,
    ) {
        let bin = job.bin_id;
        let limit = self.rules.reply_limit(&job);
        let job = Arc::new(job);
        let (mut error, mut silent, mut rejected) = (None, true, false);
        let mut foreign = 0;
        let from = Whose::Worker(replier);
        match self
            .ask(&id, payload, self.config.late_limit, limit, from)
            .await
        {
            Ok(mut asked) => {
                while let Some((_, heard)) = asked.heard.recv().await {
                    silent = false;
                    if rejected {
                        continue;
                    }
                    let taken = match heard {
                        Heard::TooLarge(bytes) => {
                            Taken::Rejected(Rejection::TooLarge { bytes, limit })
                        }
                        Heard::Error(why) => Taken::Unusable(why),
                        Heard::Payload(bytes) => {
                            let (job, rules) = (Arc::clone(&job), self.rules);
                            let admitted = tokio::task::spawn_blocking(move || {
                                take(&job, &rules, attempt, &bytes.to_bytes())
                            });
                            admitted
                                .await
                                .unwrap_or_else(|e| Taken::Unusable(e.to_string()))
                        }
                    };
                    match taken {
                        Taken::Event(event) => {
                            let id = id.clone();
                            let _ = self.tx.send(PoolEvent::Reply { id, attempt, event }).await;
                        }
                        Taken::Unusable(why) => error = Some(why),
                        Taken::Rejected(why) => {
                            rejected = true;
                            self.reject(&id, bin, why).await;
                        }
                    }
                }
                foreign = asked.foreign.load(Ordering::Relaxed);
                // A worker that sent nothing at all stays silent (unreachable).
                if asked.timed_out.load(Ordering::Relaxed) && !silent {
                    error
                        .get_or_insert_with(|| "it sent nothing more within the late limit".into());
                }
                let extra = asked.extra.load(Ordering::Relaxed);
                if extra > 0 && !rejected {
                    let why = Rejection::TooMany(REPLIES_PER_BIN);
                    self.reject(&id, bin, why).await;
                }
            }
            Err(e) => {
                silent = false;
                error = Some(e);
            }
        }
        let _ = self
            .tx
            .send(PoolEvent::Ended {
                id,
                bin,
                attempt,
                error,
                silent,
                foreign,
            })
            .await;
    }

    async fn reject(&self, id: &str, bin: u64, why: Rejection) {
        let id = id.to_string();
        let _ = self.tx.send(PoolEvent::Rejected { id, bin, why }).await;
    }
}

/// A bin reply's payload as the node takes it for `attempt` of `job`.
fn take(job: &Job, rules: &Rules, attempt: u32, bytes: &[u8]) -> Taken {
    let taken = match Reply::decode(bytes) {
        Ok(Reply::Map(a, out)) if a == attempt => {
            admit_map(job, rules, *out).map(|o| WorkerEvent::Map(Box::new(o)))
        }
        Ok(Reply::Render(r)) => admit_render(job, r).map(WorkerEvent::Render),
        Ok(_) => return Taken::Unusable("it answered a bin with something else".into()),
        Err(e) => return Taken::Unusable(format!("its reply does not decode: {e}")),
    };
    match taken {
        Ok(event) => Taken::Event(event),
        Err(why) => Taken::Rejected(why),
    }
}

/// The map of workers' sessions, also after a panic elsewhere left its lock poisoned (each
/// entry is written whole).
fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}
