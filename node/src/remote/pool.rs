//! The node's side of its worker processes, on its zenoh session: it watches their
//! liveliness tokens under `<ns>/workers/*`, greets each newcomer (a worker whose
//! fingerprint differs from the node's is refused), sends each assigned bin as a query to
//! its worker's key and turns the replies into [`PoolEvent`]s for the node's loop, which
//! feeds them to its [`super::dispatch::Dispatch`].

use std::time::Duration;

use tokio::sync::mpsc::{unbounded_channel, UnboundedReceiver, UnboundedSender};
use zenoh::query::ConsolidationMode;
use zenoh::sample::SampleKind;
use zenoh::Session;

use super::dispatch::Assignment;
use super::fingerprint::Fingerprint;
use super::wire::{BinJob, Reply, Request};
use crate::pipeline::self_check::OnCheckFail;
use crate::pipeline::worker::WorkerEvent;
use crate::service::Keys;
use crate::transport::TransportError;

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
    /// A map or render for `attempt` of a bin.
    Reply {
        /// The worker.
        id: String,
        /// The attempt it answers.
        attempt: u32,
        /// The map or render.
        event: WorkerEvent,
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
        /// Nothing at all came back: the worker is unreachable (it died and its token has
        /// not gone yet, or it never answered before the late limit).
        silent: bool,
    },
}

/// The node's worker processes (a clone shares the session and the event channel).
#[derive(Clone)]
pub struct Pool {
    session: Session,
    keys: Keys,
    config: PoolConfig,
    tx: UnboundedSender<PoolEvent>,
}

impl Pool {
    /// Starts watching for workers under `keys` on `session`; their events come out of
    /// the receiver.
    pub async fn start(
        session: &Session,
        keys: &Keys,
        config: PoolConfig,
    ) -> Result<(Self, UnboundedReceiver<PoolEvent>), TransportError> {
        let (tx, rx) = unbounded_channel();
        let watch = session
            .liveliness()
            .declare_subscriber(format!("{}/*", keys.workers()))
            .history(true)
            .await?;
        let pool = Self {
            session: session.clone(),
            keys: keys.clone(),
            config,
            tx,
        };
        let greeter = pool.clone();
        let prefix = format!("{}/", keys.workers());
        tokio::spawn(async move {
            while let Ok(sample) = watch.recv_async().await {
                let Some(id) = sample.key_expr().as_str().strip_prefix(&prefix) else {
                    continue;
                };
                match sample.kind() {
                    SampleKind::Put => {
                        let greeter = greeter.clone();
                        let id = id.to_string();
                        tokio::spawn(async move { greeter.greet(id).await });
                    }
                    SampleKind::Delete => _ = greeter.tx.send(PoolEvent::Left(id.to_string())),
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
            Ok(threads) => PoolEvent::Joined { id, threads },
            Err(why) => PoolEvent::Refused { id, why },
        };
        let _ = self.tx.send(event);
    }

    /// Greets worker `id`: its thread count when it runs the node's fingerprint, else why
    /// not.
    async fn hello(&self, id: &str) -> Result<u32, String> {
        let want = &self.config.fingerprint;
        let replies = self
            .session
            .get(self.keys.worker(id))
            .payload(Request::Hello(want.clone()).encode())
            .timeout(self.config.hello_timeout)
            .await
            .map_err(|e| e.to_string())?;
        let reply = replies
            .recv_async()
            .await
            .map_err(|_| "it did not answer the greeting".to_string())?;
        match decode(&reply)? {
            Reply::Hello(h) if &h.fingerprint == want => Ok(h.threads),
            Reply::Hello(h) => Err(format!(
                "it runs {}; the node runs {}",
                h.fingerprint.describe(),
                want.describe()
            )),
            _ => Err("it answered the greeting with a bin".into()),
        }
    }

    /// Sends assignment `a` to its worker (a worker process's slot).
    pub fn send(&self, id: &str, a: Assignment) {
        let job = BinJob {
            bin_id: a.job.bin_id,
            attempt: a.attempt,
            fingerprint: self.config.fingerprint.clone(),
            on_check_fail: self.config.on_check_fail,
            render: self.config.render,
            frame: a.job.frame,
            rig: a.job.rig,
            stamps: a.job.stamps,
        };
        let this = self.clone();
        let id = id.to_string();
        tokio::spawn(async move { this.run_bin(id, job).await });
    }

    async fn run_bin(self, id: String, job: BinJob) {
        let (bin, attempt) = (job.bin_id, job.attempt);
        let payload = Request::Bin(Box::new(job)).encode();
        let mut error = None;
        let mut silent = true;
        // A map and its render share the key: consolidation would hold back the map.
        let asked = self
            .session
            .get(self.keys.worker(&id))
            .payload(payload)
            .consolidation(ConsolidationMode::None)
            .timeout(self.config.late_limit)
            .await;
        match asked {
            Ok(replies) => {
                while let Ok(reply) = replies.recv_async().await {
                    silent = false;
                    let event = match decode(&reply) {
                        Ok(Reply::Map(a, out)) if a == attempt => WorkerEvent::Map(out),
                        Ok(Reply::Render(r)) => WorkerEvent::Render(r),
                        Ok(_) => {
                            error = Some("it answered a bin with something else".into());
                            continue;
                        }
                        Err(why) => {
                            error = Some(why);
                            continue;
                        }
                    };
                    let id = id.clone();
                    let _ = self.tx.send(PoolEvent::Reply { id, attempt, event });
                }
            }
            Err(e) => {
                silent = false;
                error = Some(e.to_string());
            }
        }
        let _ = self.tx.send(PoolEvent::Ended {
            id,
            bin,
            attempt,
            error,
            silent,
        });
    }
}

/// A worker's reply decoded, or why not: its error reply's words, or the decoder's.
fn decode(reply: &zenoh::query::Reply) -> Result<Reply, String> {
    match reply.result() {
        Ok(sample) => Reply::decode(&sample.payload().to_bytes())
            .map_err(|e| format!("its reply does not decode: {e}")),
        Err(e) => Err(e.payload().try_to_string().unwrap_or_default().into()),
    }
}
