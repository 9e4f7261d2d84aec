//! Approximate-time synchronisation of the three input streams (left image, right image,
//! camera pose): a frame is emitted when one message of each stream lies within `slop` of the
//! left image's stamp. Unmatched and late messages are counted and dropped, never queued
//! forever: each stream holds at most `capacity` messages.

use std::collections::VecDeque;

/// Settings of the synchroniser.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SyncConfig {
    /// Largest stamp difference, in nanoseconds, between the left image and the right image
    /// or pose it is paired with. KITTI-360's cameras are triggered together and its poses
    /// share the image stamps, so 10 ms (a tenth of the frame period) is generous.
    pub slop_ns: i64,
    /// Messages kept per stream while waiting for partners; beyond it the oldest is dropped.
    pub capacity: usize,
}

impl Default for SyncConfig {
    fn default() -> Self {
        Self {
            slop_ns: 10_000_000,
            capacity: 16,
        }
    }
}

/// What the synchroniser dropped, by reason.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SyncCounters {
    /// Frames emitted.
    pub matched: u64,
    /// Messages stamped at or before the last emitted frame.
    pub late: u64,
    /// Messages that aged out without a partner (passed over by a newer match, or pushed out
    /// of a full buffer).
    pub unmatched: u64,
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
}

/// Pairs left, right and pose messages by stamp.
#[derive(Debug)]
pub struct Synchronizer<L, R, P> {
    config: SyncConfig,
    left: VecDeque<(i64, L)>,
    right: VecDeque<(i64, R)>,
    pose: VecDeque<(i64, P)>,
    last_emitted: Option<i64>,
    counters: SyncCounters,
}

impl<L, R, P> Synchronizer<L, R, P> {
    /// An empty synchroniser.
    pub fn new(config: SyncConfig) -> Self {
        Self {
            config,
            left: VecDeque::new(),
            right: VecDeque::new(),
            pose: VecDeque::new(),
            last_emitted: None,
            counters: SyncCounters::default(),
        }
    }

    /// What has been matched and dropped so far.
    pub fn counters(&self) -> SyncCounters {
        self.counters
    }

    /// Messages waiting for partners, over all streams.
    pub fn pending(&self) -> usize {
        self.left.len() + self.right.len() + self.pose.len()
    }

    /// Adds a left image; returns the frames it completes (oldest first).
    pub fn push_left(&mut self, stamp_ns: i64, msg: L) -> Vec<Synced<L, R, P>> {
        if self.accept(stamp_ns) {
            insert(
                &mut self.left,
                stamp_ns,
                msg,
                self.config.capacity,
                &mut self.counters,
            );
        }
        self.drain()
    }

    /// Adds a right image; returns the frames it completes.
    pub fn push_right(&mut self, stamp_ns: i64, msg: R) -> Vec<Synced<L, R, P>> {
        if self.accept(stamp_ns) {
            insert(
                &mut self.right,
                stamp_ns,
                msg,
                self.config.capacity,
                &mut self.counters,
            );
        }
        self.drain()
    }

    /// Adds a pose; returns the frames it completes.
    pub fn push_pose(&mut self, stamp_ns: i64, msg: P) -> Vec<Synced<L, R, P>> {
        if self.accept(stamp_ns) {
            insert(
                &mut self.pose,
                stamp_ns,
                msg,
                self.config.capacity,
                &mut self.counters,
            );
        }
        self.drain()
    }

    /// Counts and refuses a message stamped at or before the last emitted frame.
    fn accept(&mut self, stamp_ns: i64) -> bool {
        let late = self.last_emitted.is_some_and(|t| stamp_ns <= t);
        self.counters.late += late as u64;
        !late
    }

    /// Emits every left image that has both partners within the slop, oldest first. A left
    /// image is given up (counted unmatched) once a newer left image has been matched.
    fn drain(&mut self) -> Vec<Synced<L, R, P>> {
        let mut out = Vec::new();
        let slop = self.config.slop_ns;
        loop {
            let found = self.left.iter().enumerate().find_map(|(i, (t, _))| {
                let r = nearest(&self.right, *t, slop)?;
                let p = nearest(&self.pose, *t, slop)?;
                Some((i, r, p))
            });
            let Some((i, r, p)) = found else { break };
            // Older left images were passed over: they can no longer match in order.
            for _ in 0..i {
                self.left.pop_front();
                self.counters.unmatched += 1;
            }
            let (stamp_ns, left) = self.left.pop_front().expect("index found above");
            let right = take_at(&mut self.right, r, &mut self.counters);
            let pose = take_at(&mut self.pose, p, &mut self.counters);
            self.last_emitted = Some(stamp_ns);
            self.counters.matched += 1;
            // Partners at or before this frame cannot serve a later one.
            for q in [&mut self.right as &mut dyn Expire, &mut self.pose] {
                self.counters.unmatched += q.expire(stamp_ns);
            }
            out.push(Synced {
                stamp_ns,
                left,
                right,
                pose,
            });
        }
        out
    }
}

/// Inserts keeping the buffer sorted by stamp and bounded (oldest dropped and counted).
fn insert<T>(q: &mut VecDeque<(i64, T)>, t: i64, msg: T, cap: usize, c: &mut SyncCounters) {
    let at = q.partition_point(|(s, _)| *s <= t);
    q.insert(at, (t, msg));
    while q.len() > cap.max(1) {
        q.pop_front();
        c.unmatched += 1;
    }
}

/// The index of the message nearest to `t` within `slop`, if any.
fn nearest<T>(q: &VecDeque<(i64, T)>, t: i64, slop: i64) -> Option<usize> {
    q.iter()
        .enumerate()
        .map(|(i, (s, _))| (i, (s - t).saturating_abs()))
        .filter(|(_, d)| *d <= slop)
        .min_by_key(|(_, d)| *d)
        .map(|(i, _)| i)
}

/// Removes the message at `i`; those before it were passed over and are counted unmatched.
fn take_at<T>(q: &mut VecDeque<(i64, T)>, i: usize, c: &mut SyncCounters) -> T {
    for _ in 0..i {
        q.pop_front();
        c.unmatched += 1;
    }
    q.pop_front().expect("index from nearest()").1
}

/// Dropping what is stamped at or before a time, over buffers of any payload.
trait Expire {
    fn expire(&mut self, t: i64) -> u64;
}

impl<T> Expire for VecDeque<(i64, T)> {
    fn expire(&mut self, t: i64) -> u64 {
        let n = self.partition_point(|(s, _)| *s <= t);
        self.drain(..n);
        n as u64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: i64 = 1_000_000;

    fn sync() -> Synchronizer<u32, u32, u32> {
        Synchronizer::new(SyncConfig::default())
    }

    #[test]
    fn a_frame_is_emitted_when_its_last_part_arrives_in_any_order() {
        let mut s = sync();
        assert!(s.push_pose(100 * MS, 3).is_empty());
        assert!(s.push_right(101 * MS, 2).is_empty());
        let out = s.push_left(100 * MS, 1);
        assert_eq!(out.len(), 1);
        assert_eq!(
            (out[0].stamp_ns, out[0].left, out[0].right, out[0].pose),
            (100 * MS, 1, 2, 3)
        );
        assert_eq!(s.pending(), 0);
        assert_eq!(s.counters().matched, 1);
    }

    #[test]
    fn partners_beyond_the_slop_do_not_pair() {
        let mut s = sync();
        s.push_left(100 * MS, 1);
        s.push_pose(100 * MS, 1);
        assert!(
            s.push_right(111 * MS, 1).is_empty(),
            "11 ms apart, slop 10 ms"
        );
        assert_eq!(s.push_right(109 * MS, 2).len(), 1);
    }

    #[test]
    fn a_missing_right_image_drops_only_its_frame() {
        let mut s = sync();
        let mut frames = Vec::new();
        for k in 0..5i64 {
            let t = k * 100 * MS;
            frames.extend(s.push_left(t, k as u32));
            frames.extend(s.push_pose(t, k as u32));
            if k != 2 {
                frames.extend(s.push_right(t, k as u32));
            }
        }
        let lefts: Vec<u32> = frames.iter().map(|f| f.left).collect();
        assert_eq!(lefts, vec![0, 1, 3, 4]);
        let c = s.counters();
        assert_eq!(
            (c.matched, c.unmatched, c.late),
            (4, 2, 0),
            "left and pose of frame 2"
        );
        assert_eq!(s.pending(), 0);
    }

    #[test]
    fn late_messages_are_counted_and_refused() {
        let mut s = sync();
        for t in [0, 100 * MS] {
            s.push_left(t, 0);
            s.push_right(t, 0);
            s.push_pose(t, 0);
        }
        assert!(s.push_right(50 * MS, 9).is_empty());
        assert!(
            s.push_left(100 * MS, 9).is_empty(),
            "same stamp as the last frame"
        );
        assert_eq!(s.counters().late, 2);
        assert_eq!(s.pending(), 0);
    }

    #[test]
    fn buffers_stay_bounded_when_one_stream_is_silent() {
        let mut s = sync();
        for k in 0..1000i64 {
            s.push_left(k * 100 * MS, 0);
            s.push_pose(k * 100 * MS, 0);
        }
        assert_eq!(s.pending(), 2 * SyncConfig::default().capacity);
        assert_eq!(s.counters().unmatched, 2 * (1000 - 16));
    }
}
