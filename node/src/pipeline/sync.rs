//! Approximate-time synchronisation of the three input streams (left image, right image,
//! camera pose): a frame is complete when one message of each stream lies within `slop` of
//! the left image's stamp. Nothing can wedge it and nothing grows without bound; the rules:
//!
//! - **Bounded buffers.** Each stream holds at most `capacity` messages and
//!   `max_bytes_per_stream` bytes; beyond either, the message received longest ago is dropped
//!   (counted `unmatched`, or `over_budget` for the bytes; a message larger than the whole
//!   budget is refused). Oldest *received*, not oldest stamped, so messages stamped far away
//!   cannot make the node drop the live stream's newest frames.
//! - **Late.** A message stamped at or up to `jump_ns` before the last emitted frame is late:
//!   refused and counted (`late`).
//! - **Time jumps.** A complete frame stamped more than `jump_ns` from the last emitted frame
//!   (either way: a stamp far in the future or the past, a drive replayed again, a clock
//!   reset) is held as the start of a possible new timeline. Once `confirm` such frames follow
//!   each other (each after the previous one by at most `jump_ns`), the jump is confirmed: the
//!   synchroniser resets (counted `reset`), drops what it buffered for the old timeline, and
//!   emits the held frames, the first marked [`Synced::reset`] so the binner starts over. A
//!   frame on the current timeline emitted in between discards the held ones (counted
//!   `outlier`): one stray frame stamped far away costs nothing but itself, and of two sources
//!   interleaving on different clocks the first keeps the node.
//! - **Two sources at once.** A camera sends one image per instant, so two images of one
//!   stream less than `slop` apart (both waiting, or one just after the last emitted frame)
//!   mean that two sources publish on the same keys: every message within `slop` of that
//!   instant, in all three streams, is dropped, and later ones are refused for a while
//!   (`conflict`; poses may come faster than images and are not checked so). A frame is
//!   then never made of parts from two sources when each source sends a frame's messages in
//!   one order (left image first) and its streams arrive in order (one zenoh session): a
//!   second source's part can only complete a frame after its left image, which conflicts.
//!   The slop must be below half the image period.

use std::collections::VecDeque;

/// Settings of the synchroniser.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SyncConfig {
    /// Largest stamp difference, in nanoseconds, between the left image and the right image
    /// or pose it is paired with. KITTI-360's cameras are triggered together and its poses
    /// share the image stamps, so 10 ms (a tenth of the frame period) is generous. Must be
    /// below half the frame period (closer messages of one stream are a source conflict).
    pub slop_ns: i64,
    /// Messages kept per stream while waiting for partners; beyond it the message received
    /// longest ago is dropped.
    pub capacity: usize,
    /// Bytes kept per stream (as the caller weighs its messages); beyond it the message
    /// received longest ago is dropped. 64 MiB holds 10 decoded 1408 x 376 images (f32 RGB).
    pub max_bytes_per_stream: usize,
    /// A frame stamped farther than this from the last emitted frame starts a new timeline
    /// (once confirmed); messages up to this far before it are late. 2 s: twenty frames at
    /// 10 Hz, far beyond any transport delay, far below a drive's length.
    pub jump_ns: i64,
    /// Consecutive frames on a new timeline that confirm a jump.
    pub confirm: usize,
}

impl Default for SyncConfig {
    fn default() -> Self {
        Self {
            slop_ns: 10_000_000,
            capacity: 16,
            max_bytes_per_stream: 64 << 20,
            jump_ns: 2_000_000_000,
            confirm: 3,
        }
    }
}

/// What the synchroniser did with the messages, by outcome. Each count is of messages,
/// except `matched`, `outlier` (frames) and `reset` (events).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SyncCounters {
    /// Frames emitted.
    pub matched: u64,
    /// Messages stamped at or shortly (`jump_ns`) before the last emitted frame.
    pub late: u64,
    /// Messages that aged out without a partner (passed over by a newer match, pushed out of
    /// a full buffer, or left behind by a reset).
    pub unmatched: u64,
    /// Messages dropped or refused for the per-stream byte budget.
    pub over_budget: u64,
    /// Messages dropped or refused because two sources sent one stream at the same instant.
    pub conflict: u64,
    /// Complete frames stamped off the timeline that no later frame confirmed.
    pub outlier: u64,
    /// Confirmed time jumps: the synchroniser (and the binner after it) started over.
    pub reset: u64,
}

/// One synchronised frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Synced<L, R, P> {
    /// The left image's stamp, the frame's stamp.
    pub stamp_ns: i64,
    /// Left image.
    pub left: L,
    /// Right image.
    pub right: R,
    /// Pose.
    pub pose: P,
    /// The first frame of a new timeline: what came before belongs to another one.
    pub reset: bool,
}

/// Pairs left, right and pose messages by stamp.
#[derive(Debug)]
pub struct Synchronizer<L, R, P> {
    config: SyncConfig,
    left: Stream<L>,
    right: Stream<R>,
    pose: Stream<P>,
    state: State,
    /// Complete frames off the timeline, waiting for confirmation (at most `confirm`).
    held: Vec<Synced<L, R, P>>,
}

/// The timeline and the counters, apart from the buffers so both can be borrowed at once.
#[derive(Debug, Default)]
struct State {
    last_emitted: Option<i64>,
    /// Instants where two sources met, with the arrival number when they did.
    poisoned: VecDeque<(i64, u64)>,
    /// Messages received so far (the arrival order).
    arrivals: u64,
    counters: SyncCounters,
}

impl<L, R, P> Synchronizer<L, R, P> {
    /// An empty synchroniser.
    pub fn new(config: SyncConfig) -> Self {
        Self {
            config,
            left: Stream::default(),
            right: Stream::default(),
            pose: Stream::default(),
            state: State::default(),
            held: Vec::new(),
        }
    }

    /// What has been matched and dropped so far.
    pub fn counters(&self) -> SyncCounters {
        self.state.counters
    }

    /// Messages waiting for partners, over all streams.
    pub fn pending(&self) -> usize {
        self.left.q.len() + self.right.q.len() + self.pose.q.len()
    }

    /// Bytes waiting for partners, over all streams.
    pub fn pending_bytes(&self) -> usize {
        self.left.bytes + self.right.bytes + self.pose.bytes
    }

    /// Adds a left image weighing `bytes`; returns the frames it completes (oldest first).
    pub fn push_left(&mut self, stamp_ns: i64, bytes: usize, msg: L) -> Vec<Synced<L, R, P>> {
        let arrival = (stamp_ns, bytes, msg);
        let conflict = self.state.add(&self.config, &mut self.left, arrival, true);
        if let Some(t) = conflict {
            self.poison(t);
        }
        self.drain()
    }

    /// Adds a right image weighing `bytes`; returns the frames it completes.
    pub fn push_right(&mut self, stamp_ns: i64, bytes: usize, msg: R) -> Vec<Synced<L, R, P>> {
        let arrival = (stamp_ns, bytes, msg);
        let conflict = self.state.add(&self.config, &mut self.right, arrival, true);
        if let Some(t) = conflict {
            self.poison(t);
        }
        self.drain()
    }

    /// Adds a pose weighing `bytes`; returns the frames it completes.
    pub fn push_pose(&mut self, stamp_ns: i64, bytes: usize, msg: P) -> Vec<Synced<L, R, P>> {
        let arrival = (stamp_ns, bytes, msg);
        let conflict = self.state.add(&self.config, &mut self.pose, arrival, false);
        if let Some(t) = conflict {
            self.poison(t);
        }
        self.drain()
    }

    /// Two sources met at `t`: drops every waiting message near it and refuses later ones.
    fn poison(&mut self, t: i64) {
        let s = self.config.slop_ns;
        let range = (t.saturating_sub(s - 1), t.saturating_add(s - 1));
        let dropped = self.left.remove_range(range)
            + self.right.remove_range(range)
            + self.pose.remove_range(range);
        self.state.counters.conflict += dropped;
        self.state.poisoned.push_back((t, self.state.arrivals));
        while self.state.poisoned.len() > self.config.capacity.max(1) {
            self.state.poisoned.pop_front();
        }
    }

    /// Takes every complete frame out of the buffers, oldest first, and emits, holds or
    /// confirms it by its place on the timeline. A left image is given up (counted unmatched)
    /// once a newer left image of its timeline has been matched.
    fn drain(&mut self) -> Vec<Synced<L, R, P>> {
        let mut out = Vec::new();
        let (slop, jump) = (self.config.slop_ns, self.config.jump_ns);
        loop {
            let found = self.left.q.iter().enumerate().find_map(|(i, e)| {
                let r = self.right.nearest(e.stamp, slop)?;
                let p = self.pose.nearest(e.stamp, slop)?;
                Some((i, r, p))
            });
            let Some((i, r, p)) = found else { break };
            let (stamp_ns, left) = self.left.take(i);
            let right = self.right.take(r).1;
            let pose = self.pose.take(p).1;
            // What is stamped up to this frame on its timeline can no longer match in order.
            let passed = (stamp_ns.saturating_sub(jump), stamp_ns);
            self.state.counters.unmatched += self.left.remove_range(passed)
                + self.right.remove_range(passed)
                + self.pose.remove_range(passed);
            let frame = Synced {
                stamp_ns,
                left,
                right,
                pose,
                reset: false,
            };
            self.place(frame, &mut out);
        }
        out
    }

    /// Emits `frame` if it is on the timeline, else holds it and confirms a jump when enough
    /// frames agree.
    fn place(&mut self, frame: Synced<L, R, P>, out: &mut Vec<Synced<L, R, P>>) {
        let jump = self.config.jump_ns.max(0);
        let t = frame.stamp_ns;
        let on_timeline = self
            .state
            .last_emitted
            .is_none_or(|last| t > last && t.abs_diff(last) <= jump as u64);
        if on_timeline {
            self.state.counters.outlier += self.held.len() as u64;
            self.held.clear();
            self.emit(frame, out);
            return;
        }
        let follows = self
            .held
            .last()
            .is_some_and(|h| t > h.stamp_ns && t.abs_diff(h.stamp_ns) <= jump as u64);
        if !follows {
            self.state.counters.outlier += self.held.len() as u64;
            self.held.clear();
        }
        self.held.push(frame);
        if self.held.len() < self.config.confirm.max(1) {
            return;
        }
        // Confirmed: start over on the new timeline.
        self.state.counters.reset += 1;
        self.state.last_emitted = None;
        self.state.poisoned.clear();
        let newest = self.held.last().map_or(t, |h| h.stamp_ns);
        let kept = (newest.saturating_sub(jump), newest.saturating_add(jump));
        self.state.counters.unmatched += self.left.retain_range(kept)
            + self.right.retain_range(kept)
            + self.pose.retain_range(kept);
        let mut held = std::mem::take(&mut self.held);
        held[0].reset = true;
        for f in held {
            self.emit(f, out);
        }
    }

    fn emit(&mut self, frame: Synced<L, R, P>, out: &mut Vec<Synced<L, R, P>>) {
        self.state.last_emitted = Some(frame.stamp_ns);
        self.state.counters.matched += 1;
        out.push(frame);
    }
}

/// What [`State::admit`] decided about a message.
enum Admit {
    /// Buffer it.
    In,
    /// Refused and counted.
    Refused,
    /// It meets another source at this instant: refused, and the instant is poisoned.
    Conflict(i64),
}

impl State {
    /// Admits and buffers one message `(stamp, bytes, msg)`; the instant where it meets
    /// another source, if it does.
    fn add<T>(
        &mut self,
        config: &SyncConfig,
        stream: &mut Stream<T>,
        (t, bytes, msg): (i64, usize, T),
        one_per_instant: bool,
    ) -> Option<i64> {
        match self.admit(config, stream, t, one_per_instant) {
            Admit::In => stream.insert(config, self, t, bytes, msg),
            Admit::Refused => {}
            Admit::Conflict(at) => return Some(at),
        }
        None
    }

    /// Counts and refuses a late message or one at a poisoned instant; finds where an image
    /// (`one_per_instant`) meets another source's.
    fn admit<T>(
        &mut self,
        config: &SyncConfig,
        stream: &Stream<T>,
        t: i64,
        one_per_instant: bool,
    ) -> Admit {
        self.arrivals += 1;
        let s = config.slop_ns.max(0) as u64;
        // A poisoned instant stays so while the sources that met there may still send it.
        let memory = 3 * config.capacity.max(1) as u64;
        let now = self.arrivals;
        self.poisoned.retain(|&(_, at)| now - at <= memory);
        if self.poisoned.iter().any(|&(p, _)| p.abs_diff(t) < s) {
            self.counters.conflict += 1;
            return Admit::Refused;
        }
        if let Some(last) = self.last_emitted {
            if t <= last && last.abs_diff(t) <= config.jump_ns.max(0) as u64 {
                self.counters.late += 1;
                return Admit::Refused;
            }
        }
        if !one_per_instant {
            return Admit::In;
        }
        let just_emitted = self
            .last_emitted
            .is_some_and(|last| t > last && t.abs_diff(last) < s);
        if just_emitted || stream.q.iter().any(|e| e.stamp.abs_diff(t) < s) {
            self.counters.conflict += 1;
            return Admit::Conflict(t);
        }
        Admit::In
    }
}

/// One stream's waiting messages, sorted by stamp, with their arrival numbers and weights.
#[derive(Debug)]
struct Stream<T> {
    q: VecDeque<Entry<T>>,
    bytes: usize,
}

impl<T> Default for Stream<T> {
    fn default() -> Self {
        Self {
            q: VecDeque::new(),
            bytes: 0,
        }
    }
}

#[derive(Debug)]
struct Entry<T> {
    stamp: i64,
    arrival: u64,
    bytes: usize,
    msg: T,
}

impl<T> Stream<T> {
    /// Inserts in stamp order, then drops the messages received longest ago while the stream
    /// is over its count or byte budget (counted); a message over the whole budget is refused.
    fn insert(&mut self, config: &SyncConfig, state: &mut State, t: i64, bytes: usize, msg: T) {
        let c = &mut state.counters;
        if bytes > config.max_bytes_per_stream {
            c.over_budget += 1;
            return;
        }
        let at = self.q.partition_point(|e| e.stamp <= t);
        self.q.insert(
            at,
            Entry {
                stamp: t,
                arrival: state.arrivals,
                bytes,
                msg,
            },
        );
        self.bytes += bytes;
        loop {
            let over_count = self.q.len() > config.capacity.max(1);
            let over_bytes = self.bytes > config.max_bytes_per_stream;
            if !(over_count || over_bytes) {
                break;
            }
            let oldest = (0..self.q.len())
                .min_by_key(|&i| self.q[i].arrival)
                .expect("over budget means not empty");
            self.take(oldest);
            match over_count {
                true => c.unmatched += 1,
                false => c.over_budget += 1,
            }
        }
    }

    /// The index of the message nearest to `t` within `slop`, if any.
    fn nearest(&self, t: i64, slop: i64) -> Option<usize> {
        self.q
            .iter()
            .enumerate()
            .map(|(i, e)| (i, e.stamp.abs_diff(t)))
            .filter(|(_, d)| *d <= slop.max(0) as u64)
            .min_by_key(|(_, d)| *d)
            .map(|(i, _)| i)
    }

    /// Removes and returns the message at `i` with its stamp.
    fn take(&mut self, i: usize) -> (i64, T) {
        let e = self.q.remove(i).expect("index within the buffer");
        self.bytes -= e.bytes;
        (e.stamp, e.msg)
    }

    /// Removes the messages stamped within `lo..=hi`; how many.
    fn remove_range(&mut self, (lo, hi): (i64, i64)) -> u64 {
        self.remove_where(|s| (lo..=hi).contains(&s))
    }

    /// Removes the messages stamped outside `lo..=hi`; how many.
    fn retain_range(&mut self, (lo, hi): (i64, i64)) -> u64 {
        self.remove_where(|s| !(lo..=hi).contains(&s))
    }

    fn remove_where(&mut self, gone: impl Fn(i64) -> bool) -> u64 {
        let before = self.q.len();
        let mut freed = 0;
        self.q.retain(|e| {
            let g = gone(e.stamp);
            freed += if g { e.bytes } else { 0 };
            !g
        });
        self.bytes -= freed;
        (before - self.q.len()) as u64
    }
}

#[cfg(test)]
#[path = "sync_tests.rs"]
mod tests;
