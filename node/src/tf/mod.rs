//! A tf buffer: the transforms robots publish on `/tf` and `/tf_static` (`tf2_msgs/TFMessage`
//! of `geometry_msgs/TransformStamped`), kept as a tree of frames, and looked up between any
//! two frames at a stamp, as tf2's `BufferCore` does.
//!
//! Each frame has at most one parent. A dynamic edge keeps its samples sorted by stamp for
//! [`TfConfig::cache_ns`] (tf2's default, 10 s) behind its newest sample and at most
//! [`TfConfig::max_samples_per_edge`]; a static edge keeps its one latest transform forever.
//! [`TfBuffer::lookup`] walks from both frames up to their common ancestor and composes the
//! edges on the way, each dynamic edge interpolated between its two samples around the stamp
//! (translation linearly, rotation by slerp), static edges at any time.
//!
//! The rules, where tf2's are matched and where they are stated here:
//! - Stamps may come in any order: a sample is inserted in order. One older than the edge's
//!   newest minus the cache length is refused ([`TfError::TooOld`], tf2's `TF_OLD_DATA`),
//!   as is a second sample at a held stamp ([`TfError::Repeated`], tf2's
//!   `TF_REPEATED_DATA`: the first is kept).
//! - No extrapolation, as tf2: a stamp outside an edge's cached range is
//!   [`TfError::ExtrapolationPast`] or [`TfError::ExtrapolationFuture`]; an edge with one
//!   sample is read at that stamp only. Expiry counts from each edge's own newest sample, not
//!   from the clock.
//! - A frame that gets a second parent: the latest wins for that child, the old edge and its
//!   samples are dropped. For a dynamic transform "latest" is by stamp: one older than the
//!   newest sample from the current parent is refused ([`TfError::StaleParent`]); a static
//!   one replaces whatever edge the child had, and a dynamic one replaces a static edge
//!   (tf2 keeps the parent per sample, so its tree changes with the stamp; here it changes
//!   at the insert). An insert that would close a loop is refused ([`TfError::Loop`]), so
//!   the tree never holds one and every walk ends; tf2 accepts it and fails the lookups
//!   through it. The walks are still bounded by the frame count.
//! - A stamp of [`LATEST`] (0, tf2's `TimePointZero`) means the latest time every dynamic
//!   edge on the path has: the smallest of their newest stamps ([`TfBuffer::latest_common`]).
//!   A transform really stamped 0 ns is stored as any other, but a lookup at exactly 0 ns
//!   always means the latest common time.
//! - Looking a frame up against itself is the identity, known or not (as tf2).
//! - One leading `/` of a frame name is dropped (tf2 strips it on insert, as ROS 1's tf
//!   names had it; tf2 refuses it on lookup, here it is dropped there too), so `/odom` and
//!   `odom` are one frame; names must then be non-empty, distinct and at most
//!   [`TfConfig::max_name_bytes`]. Non-finite values and quaternions
//!   more than [`UNIT_TOLERANCE`](crate::msg::pose::UNIT_TOLERANCE) from unit norm are
//!   refused; the rest are normalised.
//!
//! Memory is bounded for any input: at most [`TfConfig::max_frames`] frames (a new name
//! beyond it is refused and counted, [`TfError::TooManyFrames`]; frames are never forgotten,
//! as in tf2), each with its name (twice, at most `max_name_bytes`) and one edge of at most
//! `max_samples_per_edge` samples of 64 bytes: about 66 MB with the defaults whatever is
//! sent, a few kilobytes for a robot's tree.

mod cache;
mod error;
mod odometry;
mod pose_source;

use std::collections::HashMap;

use glam::{DAffine3, DQuat, DVec3};

use crate::msg::geometry_msgs::TransformStamped;
use crate::msg::pose::checked_transform;
use cache::{At, Refused, Sample, TimeCache};

pub use error::TfError;
pub use odometry::{camera_pose_from_odometry, odometry_transform, CameraPose};
pub use pose_source::{
    GiveUp, Mount, PoseSource, PoseSourceConfig, PoseSourceError, PoseSourceKind,
    DEFAULT_MAX_PENDING, DEFAULT_WAIT_NS,
};

/// The stamp that asks [`TfBuffer::lookup`] for the latest common time (tf2's
/// `TimePointZero`).
pub const LATEST: i64 = 0;

/// tf2's default cache length: 10 s.
pub const DEFAULT_CACHE_NS: i64 = 10_000_000_000;

/// The buffer's settings.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TfConfig {
    /// How long a dynamic edge keeps samples behind its newest, nanoseconds (below 0: 0).
    pub cache_ns: i64,
    /// Samples one dynamic edge holds at most (the oldest go first beyond it): 10 s of a
    /// 100 Hz publisher by default.
    pub max_samples_per_edge: usize,
    /// Frames the buffer knows at most.
    pub max_frames: usize,
    /// Bytes a frame name may have at most.
    pub max_name_bytes: usize,
}

impl Default for TfConfig {
    fn default() -> Self {
        Self {
            cache_ns: DEFAULT_CACHE_NS,
            max_samples_per_edge: 1000,
            max_frames: 1024,
            max_name_bytes: 256,
        }
    }
}

/// What the buffer did with the transforms it was given, by outcome.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TfCounts {
    /// Transforms kept.
    pub inserted: u64,
    /// Refused as malformed: empty, equal or too long names, non-finite values, non-unit
    /// quaternions.
    pub invalid: u64,
    /// Refused because the buffer held its `max_frames` frames.
    pub frames_full: u64,
    /// Refused as older than the cache.
    pub too_old: u64,
    /// Refused as repeating a held stamp.
    pub repeated: u64,
    /// Refused because they would close a loop.
    pub loops: u64,
    /// Refused as older than the current parent's newest sample.
    pub stale_parent: u64,
    /// Kept, and replaced the child's edge from another parent or of the other kind.
    pub replaced_edges: u64,
    /// Samples dropped because an edge held `max_samples_per_edge`.
    pub capped: u64,
}

/// A child's link to its parent.
#[derive(Clone, Debug)]
enum Link {
    /// `/tf_static`: one transform, valid at any time.
    Static(Sample),
    /// `/tf`: samples over time.
    Dynamic(TimeCache),
}

/// A frame and its edge to its parent (none for a root).
#[derive(Clone, Debug)]
struct Frame {
    name: String,
    edge: Option<(usize, Link)>,
}

/// A rigid transform as rotation and translation (`p -> q * p + t`).
#[derive(Clone, Copy, Debug)]
struct Rigid {
    q: DQuat,
    t: DVec3,
}

impl Rigid {
    const IDENTITY: Self = Self {
        q: DQuat::IDENTITY,
        t: DVec3::ZERO,
    };

    /// `self` after `inner` (points go through `inner` first).
    fn then_after(self, inner: Rigid) -> Rigid {
        Rigid {
            q: self.q * inner.q,
            t: self.q * inner.t + self.t,
        }
    }

    fn inverse(self) -> Rigid {
        let q = self.q.conjugate();
        Rigid {
            q,
            t: -(q * self.t),
        }
    }
}

/// When a walk reads its edges.
#[derive(Clone, Copy)]
enum When {
    /// Dynamic edges at this stamp.
    At(i64),
    /// Static edges only.
    StaticOnly,
}

/// The tf buffer (see the module documentation).
#[derive(Clone, Debug, Default)]
pub struct TfBuffer {
    config: TfConfig,
    ids: HashMap<String, usize>,
    frames: Vec<Frame>,
    counts: TfCounts,
}

impl TfBuffer {
    /// An empty buffer with `config`.
    pub fn new(config: TfConfig) -> Self {
        Self {
            config,
            ..Self::default()
        }
    }

    /// The settings.
    pub fn config(&self) -> &TfConfig {
        &self.config
    }

    /// What was kept and refused so far.
    pub fn counts(&self) -> TfCounts {
        self.counts
    }

    /// The names of the frames known, in the order they were first seen.
    pub fn frames(&self) -> impl Iterator<Item = &str> {
        self.frames.iter().map(|f| f.name.as_str())
    }

    /// The parent of `frame`, if it is known and has one.
    pub fn parent(&self, frame: &str) -> Option<&str> {
        let (parent, _) = self.frames[*self.ids.get(strip_slash(frame))?]
            .edge
            .as_ref()?;
        Some(&self.frames[*parent].name)
    }

    /// Dynamic samples held over all edges (static edges not counted).
    pub fn dynamic_samples(&self) -> usize {
        self.frames
            .iter()
            .filter_map(|f| match &f.edge {
                Some((_, Link::Dynamic(cache))) => Some(cache.len()),
                _ => None,
            })
            .sum()
    }

    /// Keeps `transform` (the pose of `child_frame_id` in `header.frame_id` at
    /// `header.stamp`), from `/tf_static` when `is_static`, else from `/tf`; refused
    /// transforms change nothing and are counted ([`TfBuffer::counts`]).
    pub fn insert(&mut self, transform: &TransformStamped, is_static: bool) -> Result<(), TfError> {
        let result = self.try_insert(transform, is_static);
        let c = &mut self.counts;
        match &result {
            Ok(()) => c.inserted += 1,
            Err(TfError::TooManyFrames { .. }) => c.frames_full += 1,
            Err(TfError::TooOld { .. }) => c.too_old += 1,
            Err(TfError::Repeated { .. }) => c.repeated += 1,
            Err(TfError::Loop { .. }) => c.loops += 1,
            Err(TfError::StaleParent { .. }) => c.stale_parent += 1,
            Err(_) => c.invalid += 1,
        }
        result
    }

    fn try_insert(&mut self, transform: &TransformStamped, is_static: bool) -> Result<(), TfError> {
        let parent = strip_slash(&transform.header.frame_id);
        let child = strip_slash(&transform.child_frame_id);
        self.check_names(parent, child)?;
        let (rotation, translation) =
            checked_transform(&transform.transform).map_err(|source| TfError::Invalid {
                parent: parent.to_owned(),
                child: child.to_owned(),
                source,
            })?;
        let sample = Sample {
            stamp_ns: transform.header.stamp.to_nanos(),
            translation,
            rotation,
        };
        let (p, c) = (self.intern(parent), self.intern(child));
        let (cache_ns, max_samples) = (self.config.cache_ns, self.config.max_samples_per_edge);
        match &mut self.frames[c].edge {
            Some((held_parent, Link::Static(held))) if *held_parent == p && is_static => {
                *held = sample;
                return Ok(());
            }
            Some((held_parent, Link::Dynamic(cache))) if *held_parent == p && !is_static => {
                let capped = cache
                    .insert(sample, cache_ns, max_samples)
                    .map_err(|refused| {
                        let (parent, child) = (parent.to_owned(), child.to_owned());
                        let stamp_ns = sample.stamp_ns;
                        match refused {
                            Refused::TooOld { newest_ns } => TfError::TooOld {
                                parent,
                                child,
                                stamp_ns,
                                newest_ns,
                                cache_ns,
                            },
                            Refused::Repeated => TfError::Repeated {
                                parent,
                                child,
                                stamp_ns,
                            },
                        }
                    })?;
                self.counts.capped += capped as u64;
                return Ok(());
            }
            _ => {}
        }
        // A new edge, or the latest replacing the child's edge (another parent or kind).
        if let Some((held_parent, Link::Dynamic(cache))) = &self.frames[c].edge {
            if !is_static && sample.stamp_ns < cache.newest_ns() {
                return Err(TfError::StaleParent {
                    parent: parent.to_owned(),
                    child: child.to_owned(),
                    current_parent: self.frames[*held_parent].name.clone(),
                    stamp_ns: sample.stamp_ns,
                    newest_ns: cache.newest_ns(),
                });
            }
        }
        if self.is_ancestor(c, p) {
            return Err(TfError::Loop {
                parent: parent.to_owned(),
                child: child.to_owned(),
            });
        }
        let link = if is_static {
            Link::Static(sample)
        } else {
            Link::Dynamic(TimeCache::new(sample))
        };
        let replaced = self.frames[c].edge.replace((p, link)).is_some();
        self.counts.replaced_edges += replaced as u64;
        Ok(())
    }

    /// Names non-empty, distinct, not too long, and room for the new ones.
    fn check_names(&self, parent: &str, child: &str) -> Result<(), TfError> {
        for (name, field) in [(parent, "header.frame_id"), (child, "child_frame_id")] {
            if name.is_empty() {
                return Err(TfError::EmptyFrameName(field));
            }
            if name.len() > self.config.max_name_bytes {
                return Err(TfError::NameTooLong {
                    len: name.len(),
                    max: self.config.max_name_bytes,
                });
            }
        }
        if parent == child {
            return Err(TfError::SameFrame(parent.to_owned()));
        }
        let mut new = [parent, child]
            .into_iter()
            .filter(|n| !self.ids.contains_key(*n));
        match new.next() {
            Some(first) if self.frames.len() + 1 + new.count() > self.config.max_frames => {
                Err(TfError::TooManyFrames {
                    frame: first.to_owned(),
                    max: self.config.max_frames,
                })
            }
            _ => Ok(()),
        }
    }

    /// The id of `name`, added if new (room was checked by [`Self::check_names`]).
    fn intern(&mut self, name: &str) -> usize {
        if let Some(&id) = self.ids.get(name) {
            return id;
        }
        let id = self.frames.len();
        self.frames.push(Frame {
            name: name.to_owned(),
            edge: None,
        });
        self.ids.insert(name.to_owned(), id);
        id
    }

    /// Whether `ancestor` is `frame` or above it.
    fn is_ancestor(&self, ancestor: usize, frame: usize) -> bool {
        let mut at = frame;
        for _ in 0..=self.frames.len() {
            if at == ancestor {
                return true;
            }
            match &self.frames[at].edge {
                Some((parent, _)) => at = *parent,
                None => return false,
            }
        }
        // Not reached: the tree holds no loop. A walk that did not end is treated as one.
        true
    }

    /// The id of a known frame (a leading `/` dropped).
    fn id(&self, name: &str) -> Result<usize, TfError> {
        self.ids
            .get(strip_slash(name))
            .copied()
            .ok_or_else(|| TfError::UnknownFrame(name.to_owned()))
    }

    /// Steps from `frame` to its root.
    fn depth(&self, frame: usize) -> Result<usize, TfError> {
        let mut at = frame;
        for depth in 0..=self.frames.len() {
            match &self.frames[at].edge {
                Some((parent, _)) => at = *parent,
                None => return Ok(depth),
            }
        }
        Err(self.loop_at(frame))
    }

    fn loop_at(&self, frame: usize) -> TfError {
        let parent = self.frames[frame].edge.as_ref().map_or(frame, |(p, _)| *p);
        TfError::Loop {
            parent: self.frames[parent].name.clone(),
            child: self.frames[frame].name.clone(),
        }
    }

    /// The parent of a frame that has one (the walks below only step up from such frames).
    fn up(&self, frame: usize) -> usize {
        self.frames[frame].edge.as_ref().map_or(frame, |(p, _)| *p)
    }

    /// The common ancestor of `a` and `b`, or why there is none.
    fn common_ancestor(&self, target: usize, source: usize) -> Result<usize, TfError> {
        let (mut a, mut b) = (target, source);
        let (mut da, mut db) = (self.depth(a)?, self.depth(b)?);
        while da > db {
            (a, da) = (self.up(a), da - 1);
        }
        while db > da {
            (b, db) = (self.up(b), db - 1);
        }
        while a != b {
            if da == 0 {
                return Err(TfError::NotConnected {
                    target_frame: self.frames[target].name.clone(),
                    source_frame: self.frames[source].name.clone(),
                });
            }
            (a, b, da) = (self.up(a), self.up(b), da - 1);
        }
        Ok(a)
    }

    /// `frame` -> `ancestor` composed edge by edge, read `when`.
    fn chain(&self, frame: usize, ancestor: usize, when: When) -> Result<Rigid, TfError> {
        let mut acc = Rigid::IDENTITY;
        let mut at = frame;
        while at != ancestor {
            let Some((parent, link)) = &self.frames[at].edge else {
                return Err(self.loop_at(at));
            };
            let names = || {
                (
                    self.frames[*parent].name.clone(),
                    self.frames[at].name.clone(),
                )
            };
            let sample = match (link, when) {
                (Link::Static(sample), _) => *sample,
                (Link::Dynamic(_), When::StaticOnly) => {
                    let (parent, child) = names();
                    return Err(TfError::NotStatic { parent, child });
                }
                (Link::Dynamic(cache), When::At(stamp_ns)) => match cache.at(stamp_ns) {
                    At::Inside(sample) => sample,
                    At::Past { oldest_ns } => {
                        let (parent, child) = names();
                        return Err(TfError::ExtrapolationPast {
                            parent,
                            child,
                            stamp_ns,
                            oldest_ns,
                        });
                    }
                    At::Future { newest_ns } => {
                        let (parent, child) = names();
                        return Err(TfError::ExtrapolationFuture {
                            parent,
                            child,
                            stamp_ns,
                            newest_ns,
                        });
                    }
                },
            };
            let step = Rigid {
                q: sample.rotation,
                t: sample.translation,
            };
            acc = step.then_after(acc);
            at = *parent;
        }
        Ok(acc)
    }

    /// The smallest newest stamp of the dynamic edges from `frame` up to `ancestor`.
    fn newest_common(&self, frame: usize, ancestor: usize) -> Option<i64> {
        let mut newest: Option<i64> = None;
        let mut at = frame;
        while at != ancestor {
            let Some((parent, link)) = &self.frames[at].edge else {
                break;
            };
            if let Link::Dynamic(cache) = link {
                newest = Some(newest.map_or(cache.newest_ns(), |n| n.min(cache.newest_ns())));
            }
            at = *parent;
        }
        newest
    }

    /// The latest stamp every dynamic edge between the two frames has (tf2's
    /// `getLatestCommonTime`), `None` when the path is static only (any stamp then).
    pub fn latest_common(&self, target: &str, source: &str) -> Result<Option<i64>, TfError> {
        if strip_slash(target) == strip_slash(source) {
            return Ok(None);
        }
        let (t, s) = (self.id(target)?, self.id(source)?);
        Ok(self.newest_on_path(t, s, self.common_ancestor(t, s)?))
    }

    /// The smallest newest stamp of the dynamic edges between `t` and `s` through `ancestor`.
    fn newest_on_path(&self, t: usize, s: usize, ancestor: usize) -> Option<i64> {
        match (
            self.newest_common(t, ancestor),
            self.newest_common(s, ancestor),
        ) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    /// The transform that takes points in `source` to `target` at `stamp_ns` (or, at
    /// [`LATEST`], at [`TfBuffer::latest_common`]): `target <- common ancestor <- source`.
    pub fn lookup(&self, target: &str, source: &str, stamp_ns: i64) -> Result<DAffine3, TfError> {
        if strip_slash(target) == strip_slash(source) {
            return Ok(DAffine3::IDENTITY);
        }
        let (t, s) = (self.id(target)?, self.id(source)?);
        let ancestor = self.common_ancestor(t, s)?;
        let stamp_ns = match stamp_ns {
            LATEST => self.newest_on_path(t, s, ancestor).unwrap_or(LATEST),
            stamp_ns => stamp_ns,
        };
        self.compose(t, s, ancestor, When::At(stamp_ns))
    }

    /// The transform `source` -> `target` through static edges only (a sensor's mount, e.g.
    /// `base_link` <- `camera_optical_frame`); a dynamic edge on the path is
    /// [`TfError::NotStatic`].
    pub fn lookup_static(&self, target: &str, source: &str) -> Result<DAffine3, TfError> {
        if strip_slash(target) == strip_slash(source) {
            return Ok(DAffine3::IDENTITY);
        }
        let (t, s) = (self.id(target)?, self.id(source)?);
        let ancestor = self.common_ancestor(t, s)?;
        self.compose(t, s, ancestor, When::StaticOnly)
    }

    fn compose(
        &self,
        t: usize,
        s: usize,
        ancestor: usize,
        when: When,
    ) -> Result<DAffine3, TfError> {
        let source_up = self.chain(s, ancestor, when)?;
        let target_up = self.chain(t, ancestor, when)?;
        let r = target_up.inverse().then_after(source_up);
        Ok(DAffine3::from_rotation_translation(r.q.normalize(), r.t))
    }
}

/// `name` without one leading `/` (tf2's `stripSlash`).
fn strip_slash(name: &str) -> &str {
    name.strip_prefix('/').unwrap_or(name)
}

#[cfg(test)]
#[path = "buffer_tests.rs"]
mod tests;
