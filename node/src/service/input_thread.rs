//! The input side ([`Inputs`]) on a thread of its own: decoding each sample, converting the
//! images of frames that open bins (to floats, downscaled to the working size), pairing and
//! binning all run off the node's async loop, which only forwards samples (with the time
//! each arrived) and takes back what they led to, in arrival order.
//!
//! The loop also ticks the thread now and then ([`InputThread::tick`]), so what waits on
//! time alone (stamps waiting for the pose source) moves on when no sample comes.
//!
//! The loop waits for room when [`SAMPLE_BACKLOG`] samples are in hand (the subscriber's
//! own queue then holds the rest, as it did when the loop decoded them itself), so a slow
//! decode costs no memory beyond that; what comes back is made from those samples only.

use tokio::sync::mpsc;
use zenoh::bytes::ZBytes;

use super::inputs::{Inputs, Step};
use crate::counters::Counters;
use crate::pipeline::worker::now_ns;
use crate::transport::keys::Topic;

/// Samples handed to the input thread and not yet taken by it, at most.
pub(super) const SAMPLE_BACKLOG: usize = 8;

/// What reaches the input thread.
enum Item {
    /// A sample of a topic, with the time it arrived (node clock, ns).
    Sample(Topic, ZBytes, i64),
    /// Time passed ([`Inputs::on_tick`]).
    Tick,
}

/// What one sample led to: its steps, and the input side's counters after it when they
/// changed (every counter the input side keeps, by value: the node's counters take them as
/// they are).
pub(super) struct Batch {
    /// The steps, in order.
    pub steps: Vec<Step>,
    /// The input side's counters (`bad_message/`, `refused/`, `sync/`, ...), when any
    /// changed with this sample.
    pub counters: Option<Counters>,
}

/// The input thread and the way samples reach it.
pub(super) struct InputThread {
    samples: Option<mpsc::Sender<Item>>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl InputThread {
    /// Starts the thread with `inputs`; the receiver yields a [`Batch`] per sample or tick
    /// that led to steps or changed the counters.
    pub fn spawn(mut inputs: Inputs) -> (Self, mpsc::UnboundedReceiver<Batch>) {
        let (tx, mut rx) = mpsc::channel::<Item>(SAMPLE_BACKLOG);
        let (batches, batches_rx) = mpsc::unbounded_channel();
        let thread = std::thread::Builder::new()
            .name("inputs".into())
            .spawn(move || {
                let mut counters = Counters::default();
                let mut sent = Counters::default();
                while let Some(item) = rx.blocking_recv() {
                    let steps = match item {
                        Item::Sample(topic, payload, arrival_ns) => {
                            inputs.on_sample_at(topic, &payload, arrival_ns, &mut counters)
                        }
                        Item::Tick => inputs.on_tick(&mut counters),
                    };
                    let changed = counters != sent;
                    if steps.is_empty() && !changed {
                        continue;
                    }
                    if changed {
                        sent.set_all(&counters);
                    }
                    let batch = Batch {
                        steps,
                        counters: changed.then(|| counters.clone()),
                    };
                    if batches.send(batch).is_err() {
                        break;
                    }
                }
            })
            .expect("the input thread starts");
        let thread = Self {
            samples: Some(tx),
            thread: Some(thread),
        };
        (thread, batches_rx)
    }

    /// Hands a sample that arrived now to the thread, waiting while it holds
    /// [`SAMPLE_BACKLOG`] samples.
    pub async fn send(&self, topic: Topic, payload: ZBytes) {
        if let Some(tx) = &self.samples {
            // The thread ends only when this sender is dropped: the send cannot fail.
            let _ = tx.send(Item::Sample(topic, payload, now_ns())).await;
        }
    }

    /// Tells the thread that time passed, unless samples fill its backlog (they move the
    /// inputs on themselves).
    pub fn tick(&self) {
        if let Some(tx) = &self.samples {
            let _ = tx.try_send(Item::Tick);
        }
    }

    /// No more samples: the thread finishes the ones it holds, sends their batches and
    /// ends (the receiver then yields `None` once they are taken).
    pub fn close(&mut self) {
        self.samples = None;
    }
}

impl Drop for InputThread {
    fn drop(&mut self) {
        self.samples = None;
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
