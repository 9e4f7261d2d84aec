//! The node loop's side of its workers ([`crate::remote`]): what it makes of the worker
//! processes' events, and the publishing, in bin order, of the maps the dispatcher
//! releases.
//!
//! A worker whose reply the node drops ([`crate::remote::admit`]) is counted under the
//! reason (`discarded/worker_*`) and expelled: it gets no more bins (`workers/expelled`),
//! and the bin it held goes to another worker without using one of its attempts. Replies
//! from another session than the worker's are counted (`discarded/worker_replier`) without
//! blaming the worker.

use crate::pipeline::worker::WorkerEvent;
use crate::remote::{Answer, Dispatch, PoolEvent, Slot};

use super::error::ServiceError;
use super::outputs::Outputs;
use super::pace::Pace;
use crate::counters::Counters;

/// The `workers/bins/<id>` counters: one per worker id for the first
/// [`crate::remote::MAX_WORKERS`] ids only, the rest under `workers/bins_past_limit`, so a
/// peer cycling through ids cannot grow the counters without bound.
#[derive(Debug, Default)]
pub(super) struct WorkerBinCounters {
    /// Worker ids with a counter of their own so far.
    named: usize,
}

impl WorkerBinCounters {
    /// Counts a bin handed to the worker `id`.
    pub(super) fn count(&mut self, id: &str, counters: &mut Counters) {
        let name = format!("workers/bins/{id}");
        if counters.get(&name) > 0 {
            counters.add(&name, 1);
        } else if self.named < crate::remote::MAX_WORKERS {
            self.named += 1;
            counters.add(&name, 1);
        } else {
            counters.add("workers/bins_past_limit", 1);
        }
    }
}

/// How often the node looks for stalled worker processes.
pub(super) const STALL_CHECK: std::time::Duration = std::time::Duration::from_millis(250);

/// Feeds a worker process's event to the dispatcher, counting and saying what matters.
pub(super) fn workers_event(dispatch: &mut Dispatch, event: PoolEvent, counters: &mut Counters) {
    match event {
        PoolEvent::Joined { id, threads } => {
            eprintln!("worker {id} joined ({threads} threads)");
            counters.add("workers/joined", 1);
            dispatch.joined(&id);
        }
        PoolEvent::Refused { id, why } => {
            eprintln!("worker {id} refused: {why}");
            counters.add("refused/worker", 1);
        }
        PoolEvent::Left(id) => {
            if dispatch.left(&id) {
                eprintln!("worker {id} left");
                counters.add("workers/left", 1);
            }
        }
        PoolEvent::Reply { id, attempt, event } => {
            if dispatch.event(&Slot::Remote(id), Some(attempt), event) == Answer::Late {
                counters.set("discarded/late_bin", dispatch.late());
            }
        }
        PoolEvent::Rejected { id, bin, why } => {
            eprintln!("worker {id} on bin {bin}: {why}; its reply is dropped");
            counters.add(why.counter(), 1);
            if dispatch.expel(&id) {
                eprintln!("worker {id} gets no more bins");
                counters.add("workers/expelled", 1);
            }
        }
        PoolEvent::Ended {
            id,
            bin,
            attempt,
            error,
            silent,
            foreign,
        } => {
            if foreign > 0 {
                eprintln!(
                    "bin {bin}: replies from another session on worker {id}'s key: {foreign}"
                );
                counters.add("discarded/worker_replier", foreign);
            }
            if let Some(why) = error {
                eprintln!("worker {id} on bin {bin}: {why}");
                counters.add("error/worker_reply", 1);
            }
            dispatch.answered(&Slot::Remote(id.clone()), bin, attempt);
            // A worker that answers nothing gets no more bins (greeted again if its token
            // comes back).
            if silent && dispatch.left(&id) {
                eprintln!("worker {id} is unreachable: it gets no more bins");
                counters.add("workers/left", 1);
            }
        }
    }
    counters.set("workers/ready", dispatch.workers() as u64);
    counters.set("workers/reassigned", dispatch.reassigned());
}

/// Publishes what the dispatcher released, in bin order.
pub(super) async fn publish_released(
    dispatch: &mut Dispatch,
    outputs: &mut Outputs<'_>,
    mut pace: Option<&mut Pace>,
    point_names: &[String],
) -> Result<(), ServiceError> {
    let depth = dispatch.waiting();
    for mut event in dispatch.released() {
        if let WorkerEvent::Map(o) = &mut event {
            o.queue_depth = depth;
        }
        if let Some(p) = pace.as_deref_mut() {
            p.count(&event, point_names, &mut outputs.counters);
        }
        outputs.worker_event(event, dispatch.drops()).await?;
    }
    outputs
        .counters
        .set("dropped/worker_queue", dispatch.drops());
    Ok(())
}
