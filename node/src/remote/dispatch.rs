//! Which bin runs where: the node's waiting bins, the workers that take them (the node's
//! own worker thread and any number of worker processes), the bins each has in hand, and
//! the release of finished bins in bin order. No transport here: [`super::pool`] does the
//! talking and this decides, so every rule is tested on its own.
//!
//! - A new bin waits in a queue of `capacity`; when it is full the oldest waiting bin is
//!   dropped and counted (keep newest, as the node's worker queue always did).
//! - An idle worker takes the oldest waiting bin; worker processes are served before the
//!   node's own thread, which shares its cores with fusion and publishing.
//! - A bin whose worker left (its liveliness token is gone) or has not answered within the
//!   timeout is given out again, ahead of every waiting bin and never dropped: it was
//!   already accepted. Each hand-out is an attempt; an answer for an older attempt is late,
//!   discarded and counted, so no bin is published twice.
//! - A worker whose reply the node dropped is expelled ([`Dispatch::expel`]): its bin is
//!   given out again too, but that hand-out does not count towards [`MAX_ATTEMPTS`]: the
//!   worker failed, not the bin (and each such hand-out costs the pool a worker).
//! - Maps are released in bin order: a finished bin waits until every earlier bin still in
//!   the node's hands is finished or dropped. A render follows its map.

use std::collections::{BTreeMap, BTreeSet, VecDeque};
use std::time::{Duration, Instant};

use crate::pipeline::self_check::CheckOutcome;
use crate::pipeline::worker::{now_ns, Job, Output, Rendered, Submitted, WorkerEvent};

/// How many times a bin is handed out at most; after that it is published as failed (its
/// latency message and the counters say so) rather than lost or retried for ever.
pub const MAX_ATTEMPTS: u32 = 3;

/// A worker: the node's own thread or a worker process by its id.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Slot {
    /// The node's worker thread.
    Local,
    /// A worker process.
    Remote(String),
}

/// A bin handed to a worker.
#[derive(Debug)]
pub struct Assignment {
    /// Who runs it.
    pub slot: Slot,
    /// The bin.
    pub job: Job,
    /// 0 the first time the bin is handed out, then 1, 2, …
    pub attempt: u32,
}

/// A bin in a worker's hands.
#[derive(Debug)]
struct Flight {
    job: Job,
    slot: Slot,
    attempt: u32,
    since: Instant,
    /// Its map arrived (the worker may still be rendering it).
    mapped: bool,
    /// Hand-outs so far that do not count towards [`MAX_ATTEMPTS`] (their worker was
    /// expelled).
    forgiven: u32,
}

/// What became of an answer.
#[derive(Debug, PartialEq, Eq)]
pub enum Answer {
    /// Accepted: the bin's events are released in order by [`Dispatch::released`].
    Accepted,
    /// For an attempt the node has given to another worker (or a bin it has already
    /// accepted): discarded.
    Late,
}

/// The dispatcher's state.
#[derive(Debug)]
pub struct Dispatch {
    capacity: usize,
    local: bool,
    waiting: VecDeque<Job>,
    /// Bins to give out again: the job, its next attempt and its forgiven hand-outs.
    again: VecDeque<(Job, u32, u32)>,
    flights: BTreeMap<u64, Flight>,
    /// Worker processes ready for bins, and the bin each holds; a stalled one (its bin
    /// given out again) holds its bin id until it answers or leaves.
    remotes: BTreeMap<String, Option<u64>>,
    /// The bin the node's own thread holds.
    local_bin: Option<u64>,
    /// Bins accepted and not yet released, and what of them arrived.
    open: BTreeSet<u64>,
    done: BTreeMap<u64, Vec<WorkerEvent>>,
    ready: Vec<WorkerEvent>,
    /// Bins whose map was released and whose render may still come.
    renders_due: BTreeSet<u64>,
    drops: u64,
    reassigned: u64,
    late: u64,
}

impl Dispatch {
    /// A dispatcher with `capacity` waiting bins at most, and the node's own worker thread
    /// among its workers when `local`.
    pub fn new(capacity: usize, local: bool) -> Self {
        Self {
            capacity: capacity.max(1),
            local,
            waiting: VecDeque::new(),
            again: VecDeque::new(),
            flights: BTreeMap::new(),
            remotes: BTreeMap::new(),
            local_bin: None,
            open: BTreeSet::new(),
            done: BTreeMap::new(),
            ready: Vec::new(),
            renders_due: BTreeSet::new(),
            drops: 0,
            reassigned: 0,
            late: 0,
        }
    }

    /// Queues a new bin; on a full queue the oldest waiting bin is dropped.
    pub fn submit(&mut self, job: Job) -> Submitted {
        self.open.insert(job.bin_id);
        self.waiting.push_back(job);
        if self.waiting.len() <= self.capacity {
            return Submitted::Queued;
        }
        if let Some(oldest) = self.waiting.pop_front() {
            self.open.remove(&oldest.bin_id);
            self.drops += 1;
            self.release();
        }
        Submitted::DroppedOldest
    }

    /// A worker process is ready for bins.
    pub fn joined(&mut self, id: &str) {
        self.remotes.entry(id.to_string()).or_insert(None);
    }

    /// A worker process left: the bin it held, if any, is given out again (or, when its
    /// map had come, finished without its render). False for a worker that had not joined.
    pub fn left(&mut self, id: &str) -> bool {
        self.remove(id, true)
    }

    /// A worker process whose reply the node dropped: it gets no more bins, and the bin it
    /// held, if any, is given out again without using one of the bin's attempts. False for
    /// a worker that had not joined (or already left).
    pub fn expel(&mut self, id: &str) -> bool {
        self.remove(id, false)
    }

    /// Takes worker `id` out; its bin's hand-out counts towards [`MAX_ATTEMPTS`] when
    /// `counts`.
    fn remove(&mut self, id: &str, counts: bool) -> bool {
        let Some(held) = self.remotes.remove(id) else {
            return false;
        };
        let slot = Slot::Remote(id.to_string());
        if let Some(bin) = held.filter(|&b| self.holds(b, &slot, None)) {
            self.lost(bin, counts);
        }
        true
    }

    /// Whether `slot` holds `bin` (at `attempt`, when given).
    fn holds(&self, bin: u64, slot: &Slot, attempt: Option<u32>) -> bool {
        self.flights
            .get(&bin)
            .is_some_and(|f| &f.slot == slot && attempt.is_none_or(|a| a == f.attempt))
    }

    /// `bin`'s worker will send nothing more: a bin without its map is given out again (the
    /// hand-out counting towards [`MAX_ATTEMPTS`] when `counts`), one whose render is
    /// missing is finished with an error in its place.
    fn lost(&mut self, bin: u64, counts: bool) {
        match self.flights.get(&bin).map(|f| f.mapped) {
            Some(true) => {
                let render = WorkerEvent::Render(Rendered {
                    bin_id: bin,
                    image: Err("the worker sent no render".into()),
                    render_end_ns: now_ns(),
                });
                self.render(bin, render);
            }
            Some(false) => self.again(bin, counts),
            None => {}
        }
    }

    /// Gives out again every bin held longer than `timeout` by a worker process that has
    /// not sent its map; the worker gets no new bin until it answers or leaves. Returns the
    /// workers that stalled.
    pub fn stalled(&mut self, now: Instant, timeout: Duration) -> Vec<String> {
        let late: Vec<(u64, String)> = self
            .flights
            .iter()
            .filter_map(|(&bin, f)| match &f.slot {
                Slot::Remote(id) if !f.mapped && now.duration_since(f.since) > timeout => {
                    Some((bin, id.clone()))
                }
                _ => None,
            })
            .collect();
        // The worker keeps holding the bin, as far as anyone knows, until it answers or
        // leaves: `again` takes the bin back without freeing its worker.
        late.into_iter()
            .map(|(bin, id)| {
                self.again(bin, true);
                id
            })
            .collect()
    }

    /// Gives `bin` out again, or after [`MAX_ATTEMPTS`] counted hand-outs (this one counts
    /// when `counts`) publishes it as failed. Its worker is not freed here: one that left is
    /// gone, one whose query ended is freed by [`Self::answered`], and a stalled one stays
    /// busy until then.
    fn again(&mut self, bin: u64, counts: bool) {
        let Some(f) = self.flights.remove(&bin) else {
            return;
        };
        self.reassigned += 1;
        let forgiven = f.forgiven + u32::from(!counts);
        if f.attempt + 1 - forgiven < MAX_ATTEMPTS {
            self.again.push_back((f.job, f.attempt + 1, forgiven));
            return;
        }
        let job = f.job;
        let failed = Output {
            bin_id: bin,
            bin_to_world: job.frame.left_to_world,
            result: Err(format!("no worker answered in {MAX_ATTEMPTS} attempts")),
            check: CheckOutcome::default(),
            render_follows: false,
            stamps: job.stamps,
            queue_depth: self.waiting(),
            point: job.point,
        };
        self.open.remove(&bin);
        self.done
            .insert(bin, vec![WorkerEvent::Map(Box::new(failed))]);
        self.release();
    }

    /// Hands waiting bins to idle workers, given-out-again bins first.
    pub fn assign(&mut self, now: Instant) -> Vec<Assignment> {
        let mut idle: Vec<Slot> = self
            .remotes
            .iter()
            .filter(|(_, held)| held.is_none())
            .map(|(id, _)| Slot::Remote(id.clone()))
            .collect();
        if self.local && self.local_bin.is_none() {
            idle.push(Slot::Local);
        }
        let mut out = Vec::new();
        for slot in idle {
            let Some((job, attempt, forgiven)) = self
                .again
                .pop_front()
                .or_else(|| self.waiting.pop_front().map(|j| (j, 0, 0)))
            else {
                break;
            };
            let bin = job.bin_id;
            match &slot {
                Slot::Local => self.local_bin = Some(bin),
                Slot::Remote(id) => _ = self.remotes.insert(id.clone(), Some(bin)),
            }
            self.flights.insert(
                bin,
                Flight {
                    job: job.clone(),
                    slot: slot.clone(),
                    attempt,
                    since: now,
                    mapped: false,
                    forgiven,
                },
            );
            out.push(Assignment { slot, job, attempt });
        }
        out
    }

    /// An event from `slot` for `attempt` of its bin (`None`: the node's own thread, whose
    /// bins are never given out again): a map is accepted if that attempt is still the
    /// bin's, else late; a render follows its map's fate.
    pub fn event(&mut self, slot: &Slot, attempt: Option<u32>, event: WorkerEvent) -> Answer {
        let (bin, is_map) = match &event {
            WorkerEvent::Map(o) => (o.bin_id, true),
            WorkerEvent::Render(r) => (r.bin_id, false),
        };
        let mapped = self.flights.get(&bin).is_some_and(|f| f.mapped);
        if !self.holds(bin, slot, attempt) || mapped == is_map {
            if is_map {
                self.late += 1;
            }
            return Answer::Late;
        }
        if !is_map {
            self.render(bin, event);
            return Answer::Accepted;
        }
        let render_follows = matches!(&event, WorkerEvent::Map(o) if o.render_follows);
        if let Some(f) = self.flights.get_mut(&bin) {
            f.mapped = true;
        }
        self.open.remove(&bin);
        self.done.entry(bin).or_default().push(event);
        if !render_follows {
            self.finished(bin);
        }
        self.release();
        Answer::Accepted
    }

    /// `bin`'s render (or what stands for it): its worker is done.
    fn render(&mut self, bin: u64, event: WorkerEvent) {
        self.finished(bin);
        if self.renders_due.remove(&bin) {
            self.ready.push(event);
        } else {
            self.done.entry(bin).or_default().push(event);
        }
    }

    /// `slot` will send nothing more for `attempt` of `bin` (its query ended, answered or
    /// not): it is idle again. A bin whose map never came is given out again.
    pub fn answered(&mut self, slot: &Slot, bin: u64, attempt: u32) {
        if self.holds(bin, slot, Some(attempt)) {
            self.lost(bin, true);
        }
        self.free(slot, bin);
    }

    /// The bin's worker is done with it.
    fn finished(&mut self, bin: u64) {
        if let Some(f) = self.flights.remove(&bin) {
            self.free(&f.slot, bin);
        }
    }

    fn free(&mut self, slot: &Slot, bin: u64) {
        match slot {
            Slot::Local if self.local_bin == Some(bin) => self.local_bin = None,
            Slot::Remote(id) => {
                if let Some(held) = self.remotes.get_mut(id) {
                    if *held == Some(bin) {
                        *held = None;
                    }
                }
            }
            _ => {}
        }
    }

    /// Moves every finished bin below the first open one to the ready list.
    fn release(&mut self) {
        let first_open = self.open.first().copied().unwrap_or(u64::MAX);
        while let Some(entry) = self.done.first_entry() {
            if *entry.key() >= first_open {
                break;
            }
            let (bin, events) = entry.remove_entry();
            let rendered = events.len() > 1;
            let due = matches!(events.first(), Some(WorkerEvent::Map(o)) if o.render_follows);
            if due && !rendered {
                self.renders_due.insert(bin);
            }
            self.ready.extend(events);
        }
    }

    /// The events released for publishing since the last call, in bin order.
    pub fn released(&mut self) -> Vec<WorkerEvent> {
        std::mem::take(&mut self.ready)
    }

    /// Bins waiting for a worker (given-out-again ones included).
    pub fn waiting(&self) -> usize {
        self.waiting.len() + self.again.len()
    }

    /// Whether no bin is waiting, in a worker's hands or unreleased.
    pub fn idle(&self) -> bool {
        self.waiting() == 0 && self.flights.is_empty() && self.done.is_empty()
    }

    /// Bins accepted and not published: waiting, in a worker's hands, or finished behind
    /// an earlier one.
    pub fn unfinished(&self) -> usize {
        self.open.len() + self.done.len()
    }

    /// Worker processes ready for bins.
    pub fn workers(&self) -> usize {
        self.remotes.len()
    }

    /// Bins dropped because every worker was behind.
    pub fn drops(&self) -> u64 {
        self.drops
    }

    /// Bins given out again (their worker left or stalled).
    pub fn reassigned(&self) -> u64 {
        self.reassigned
    }

    /// Late maps discarded.
    pub fn late(&self) -> u64 {
        self.late
    }
}

#[cfg(test)]
#[path = "dispatch_tests.rs"]
mod tests;
