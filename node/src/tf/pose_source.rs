//! A pose source: the left camera's pose in the world at each left image's stamp, from what
//! robots publish instead of a `geometry_msgs/PoseStamped` per image: a `/tf` + `/tf_static`
//! tree, or a body frame's `nav_msgs/Odometry` and the camera's mount on the body. Its poses
//! go into the synchroniser as the PoseStamped poses do (`push_pose(stamp, weight, pose)`).
//!
//! Each left image's stamp waits ([`PoseSource::on_image`]) until the transform at that stamp
//! can be looked up, then comes out of [`PoseSource::take_ready`], in stamp order:
//! - [`PoseSourceKind::Tf`]: `world_frame <- camera frame` through the whole tree, each
//!   dynamic edge interpolated at the stamp by the [`TfBuffer`].
//! - [`PoseSourceKind::Odometry`]: each Odometry is inserted into the buffer as the dynamic
//!   edge `header.frame_id -> child_frame_id` ([`odometry_transform`]), so the body's pose
//!   at the stamp is interpolated between the two Odometry messages around it (translation
//!   linearly, rotation by slerp), then the mount (camera -> body) is applied: from
//!   `/tf_static` ([`Mount::TfStatic`], `lookup_static(body, camera)`) or as configured
//!   ([`Mount::Fixed`]). The world frame is the latest Odometry's `header.frame_id` unless
//!   configured (a static `world -> odom` on `/tf_static` then links them). Only
//!   `/tf_static` is read from the tf streams; dynamic `/tf` is ignored and counted, so an
//!   odometry node broadcasting the same edge does not give it twice.
//!
//! A stamp is tried once the dynamic edges on its path all reach it (their
//! [`TfBuffer::latest_common`]): then its lookup either succeeds (ready) or fails for good,
//! the data at that stamp being older than what the buffer holds ([`GiveUp::Failed`]). A
//! stamp not reached waits `wait_ns` of the node's clock from its arrival, and is then
//! given up: [`GiveUp::TimedOut`] when the transform has not come (a lookup into the future),
//! [`GiveUp::Failed`] when the frames are unknown or not connected (a missing link, a tree
//! whose loop-closing edge the buffer refused). A stamp of 0 is tf2's `TimePointZero`: the
//! latest pose. Repeated stamps are not merged (each gets its pose).
//!
//! Cost: [`PoseSource::take_ready`] walks every pending stamp, computing each camera frame's
//! path once (`latest_common`, the tree's depth) and looking up only the stamps that are
//! ready or due: O(pending + frames x depth + (ready + due) x depth) per call, so retrying
//! on every message is linear in the pending stamps (at most `max_pending`, a few hundred).
//! Memory: at most `max_pending` stamps, each with its frame name of at most
//! `buffer.max_name_bytes`, beyond which the oldest arrival is given up
//! ([`GiveUp::Overflow`]); the buffer is bounded by its own [`TfConfig`].

use std::collections::{HashMap, VecDeque};

use glam::{DAffine3, DMat3, DQuat};

use super::{odometry_transform, TfBuffer, TfConfig, TfCounts, TfError, LATEST};
use crate::msg::nav_msgs::Odometry;
use crate::msg::pose::UNIT_TOLERANCE;
use crate::msg::tf2_msgs::TfMessage;

/// How long a stamp waits for its transform by default: 500 ms, five frames at 10 Hz, well
/// beyond a tf publisher's period and transport delay.
pub const DEFAULT_WAIT_NS: i64 = 500_000_000;

/// Stamps waiting at most by default: 5 s of a 50 Hz camera.
pub const DEFAULT_MAX_PENDING: usize = 256;

/// Where the camera's mount on the odometry's body frame comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum Mount {
    /// `/tf_static`: `body <- camera frame` through static edges (the robot's URDF as
    /// `robot_state_publisher` publishes it).
    TfStatic,
    /// A calibrated extrinsic: points in the camera frame to the body frame (finite, rigid).
    Fixed(DAffine3),
}

/// Which streams give the camera's pose.
#[derive(Clone, Debug, PartialEq)]
pub enum PoseSourceKind {
    /// The tf tree: `world_frame <- camera frame` at the stamp.
    Tf,
    /// `nav_msgs/Odometry` of a body frame, and the camera's mount on it.
    Odometry {
        /// Camera to body.
        mount: Mount,
    },
}

/// The pose source's settings.
#[derive(Clone, Debug, PartialEq)]
pub struct PoseSourceConfig {
    /// Tf or Odometry.
    pub kind: PoseSourceKind,
    /// The frame the poses are in. Required for [`PoseSourceKind::Tf`] (e.g. `map`); for
    /// Odometry, `None` is the latest Odometry's `header.frame_id`.
    pub world_frame: Option<String>,
    /// The left camera's frame; `None`: each image's `header.frame_id`.
    pub camera_frame: Option<String>,
    /// How long a stamp waits for its transform, node clock nanoseconds (below 0: 0).
    pub wait_ns: i64,
    /// Stamps waiting at most (at least 1); beyond it the oldest arrival is given up.
    pub max_pending: usize,
    /// The tf buffer's settings.
    pub buffer: TfConfig,
}

impl PoseSourceConfig {
    /// `kind` into `world_frame`, camera frames from the images, the default wait, bound and
    /// buffer.
    pub fn new(kind: PoseSourceKind, world_frame: Option<String>) -> Self {
        Self {
            kind,
            world_frame,
            camera_frame: None,
            wait_ns: DEFAULT_WAIT_NS,
            max_pending: DEFAULT_MAX_PENDING,
            buffer: TfConfig::default(),
        }
    }
}

/// Why a configuration cannot make a pose source.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum PoseSourceError {
    /// A tf pose source without a world frame.
    #[error("a pose source from /tf needs a world frame (e.g. `map`)")]
    NoWorldFrame,
    /// A fixed mount with non-finite values or a matrix that is not a rotation.
    #[error("the camera mount is not a finite rigid transform")]
    MountNotRigid,
}

/// Why an image's stamp got no pose.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum GiveUp {
    /// Its transform did not arrive within the wait.
    #[error("no transform to `{frame}` at {stamp_ns} ns within {wait_ns} ns")]
    TimedOut {
        /// The image's stamp.
        stamp_ns: i64,
        /// The camera frame.
        frame: String,
        /// The wait.
        wait_ns: i64,
        /// The lookup's error when it was given up.
        #[source]
        source: TfError,
    },
    /// No Odometry arrived within the wait (Odometry mode).
    #[error("no Odometry arrived for the image at {stamp_ns} ns within {wait_ns} ns")]
    NoOdometry {
        /// The image's stamp.
        stamp_ns: i64,
        /// The wait.
        wait_ns: i64,
    },
    /// The lookup failed for good: data older than the buffer's, unknown or unconnected
    /// frames, a static mount through a dynamic edge, a bad frame name.
    #[error("no pose of `{frame}` at {stamp_ns} ns")]
    Failed {
        /// The image's stamp.
        stamp_ns: i64,
        /// The camera frame.
        frame: String,
        /// Why.
        #[source]
        source: TfError,
    },
    /// The composed transform overflowed (finite edges far beyond any world's size).
    #[error("the pose of `{frame}` at {stamp_ns} ns is not finite")]
    NotFinite {
        /// The image's stamp.
        stamp_ns: i64,
        /// The camera frame.
        frame: String,
    },
    /// Pushed out by newer stamps while `max` waited.
    #[error("the image at {stamp_ns} ns was dropped: {max} stamps were waiting")]
    Overflow {
        /// The image's stamp.
        stamp_ns: i64,
        /// The bound.
        max: usize,
    },
}

/// A stamp waiting for its pose.
#[derive(Clone, Debug)]
struct Pending {
    stamp_ns: i64,
    frame: String,
    /// Node clock time it is given up at.
    deadline_ns: i64,
}

/// How one camera frame's stamps are looked up now.
#[derive(Clone, Debug)]
struct Path {
    target: String,
    source: String,
    /// Camera to `source` (the identity for tf).
    mount: DAffine3,
    /// The newest stamp every dynamic edge on the path reaches (`None`: static, any).
    reach: Option<i64>,
}

/// What became of a stamp in one pass.
enum Outcome {
    Ready(DAffine3),
    Wait,
    GivenUp(GiveUp),
}

/// Outcome counts, for [`PoseSource::counts`].
#[derive(Clone, Copy, Debug, Default)]
struct Counts {
    ready: u64,
    timed_out: u64,
    failed: u64,
    overflow: u64,
    ignored_tf: u64,
}

/// Turns tf or Odometry streams into left-camera poses at image stamps (see the module
/// documentation).
#[derive(Clone, Debug)]
pub struct PoseSource {
    config: PoseSourceConfig,
    tf: TfBuffer,
    pending: VecDeque<Pending>,
    /// The latest inserted Odometry's `header.frame_id` and `child_frame_id`.
    odometry_frames: Option<(String, String)>,
    counts: Counts,
    last_given_up: Option<GiveUp>,
    last_refused: Option<TfError>,
}

impl PoseSource {
    /// A pose source with `config`; a fixed mount is re-orthonormalised.
    pub fn new(mut config: PoseSourceConfig) -> Result<Self, PoseSourceError> {
        match &mut config.kind {
            PoseSourceKind::Tf if config.world_frame.is_none() => {
                return Err(PoseSourceError::NoWorldFrame)
            }
            PoseSourceKind::Odometry {
                mount: Mount::Fixed(m),
            } => *m = rigid(m).ok_or(PoseSourceError::MountNotRigid)?,
            _ => {}
        }
        config.wait_ns = config.wait_ns.max(0);
        config.max_pending = config.max_pending.max(1);
        Ok(Self {
            tf: TfBuffer::new(config.buffer.clone()),
            config,
            pending: VecDeque::new(),
            odometry_frames: None,
            counts: Counts::default(),
            last_given_up: None,
            last_refused: None,
        })
    }

    /// The settings (the wait and the bound as used).
    pub fn config(&self) -> &PoseSourceConfig {
        &self.config
    }

    /// The tf buffer the poses come from (for diagnostics and other lookups).
    pub fn buffer(&self) -> &TfBuffer {
        &self.tf
    }

    /// Stamps waiting.
    pub fn pending(&self) -> usize {
        self.pending.len()
    }

    /// Why the last stamp given up got no pose.
    pub fn last_given_up(&self) -> Option<&GiveUp> {
        self.last_given_up.as_ref()
    }

    /// Why the buffer last refused a transform or an Odometry.
    pub fn last_refused(&self) -> Option<&TfError> {
        self.last_refused.as_ref()
    }

    /// A left image stamped `stamp_ns` in `frame_id` arrived at `now_ns` (node clock): its
    /// stamp waits for a pose. A bad frame name is given up at once; beyond `max_pending`
    /// the oldest arrival is.
    pub fn on_image(&mut self, stamp_ns: i64, frame_id: &str, now_ns: i64) {
        let frame = self.config.camera_frame.as_deref().unwrap_or(frame_id);
        let max = self.config.buffer.max_name_bytes;
        let bad = match frame.strip_prefix('/').unwrap_or(frame).len() {
            0 => Some(TfError::EmptyFrameName("header.frame_id")),
            len if len > max => Some(TfError::NameTooLong { len, max }),
            _ => None,
        };
        if let Some(source) = bad {
            let frame = String::new();
            return self.give_up(GiveUp::Failed {
                stamp_ns,
                frame,
                source,
            });
        }
        self.pending.push_back(Pending {
            stamp_ns,
            frame: frame.to_owned(),
            deadline_ns: now_ns.saturating_add(self.config.wait_ns),
        });
        while self.pending.len() > self.config.max_pending {
            if let Some(oldest) = self.pending.pop_front() {
                self.give_up(GiveUp::Overflow {
                    stamp_ns: oldest.stamp_ns,
                    max: self.config.max_pending,
                });
            }
        }
    }

    /// A `/tf` (or, when `is_static`, `/tf_static`) message: its transforms into the buffer
    /// (refusals counted there and the last kept); in Odometry mode dynamic ones are
    /// ignored and counted.
    pub fn on_tf(&mut self, msg: &TfMessage, is_static: bool) {
        if !is_static && matches!(self.config.kind, PoseSourceKind::Odometry { .. }) {
            self.counts.ignored_tf += msg.transforms.len() as u64;
            return;
        }
        for t in &msg.transforms {
            if let Err(e) = self.tf.insert(t, is_static) {
                self.last_refused = Some(e);
            }
        }
    }

    /// An Odometry: in Odometry mode its pose becomes a dynamic edge of the buffer and its
    /// frames the body's (a refused one counted by the buffer, the last kept); ignored in tf
    /// mode, where the tree has the same edge.
    pub fn on_odometry(&mut self, msg: &Odometry) {
        if self.config.kind == PoseSourceKind::Tf {
            return;
        }
        match self.tf.insert(&odometry_transform(msg), false) {
            Ok(()) => {
                let frames = (msg.header.frame_id.clone(), msg.child_frame_id.clone());
                self.odometry_frames = Some(frames);
            }
            Err(e) => self.last_refused = Some(e),
        }
    }

    /// The stamps whose pose can be looked up now, in stamp order, with the left camera's
    /// pose (camera to world, finite and rigid); stamps due at `now_ns` without one are
    /// given up and counted.
    pub fn take_ready(&mut self, now_ns: i64) -> Vec<(i64, DAffine3)> {
        let mut paths: HashMap<String, Result<Path, Option<TfError>>> = HashMap::new();
        let mut ready = Vec::new();
        let pending = std::mem::take(&mut self.pending);
        for p in pending {
            if !paths.contains_key(&p.frame) {
                paths.insert(p.frame.clone(), self.path(&p.frame));
            }
            let path = &paths[&p.frame];
            match self.outcome(&p, path, now_ns) {
                Outcome::Ready(pose) => ready.push((p.stamp_ns, pose)),
                Outcome::Wait => self.pending.push_back(p),
                Outcome::GivenUp(why) => self.give_up(why),
            }
        }
        self.counts.ready += ready.len() as u64;
        ready.sort_by_key(|(stamp_ns, _)| *stamp_ns);
        ready
    }

    /// How `frame`'s stamps are looked up, or what blocks them all (`None`: no Odometry).
    fn path(&self, frame: &str) -> Result<Path, Option<TfError>> {
        let (target, source, mount) = match &self.config.kind {
            PoseSourceKind::Tf => {
                let world = self.config.world_frame.clone().unwrap_or_default();
                (world, frame.to_owned(), DAffine3::IDENTITY)
            }
            PoseSourceKind::Odometry { mount } => {
                let (parent, body) = self.odometry_frames.clone().ok_or(None)?;
                let world = self.config.world_frame.clone().unwrap_or(parent);
                let mount = match mount {
                    Mount::Fixed(m) => *m,
                    Mount::TfStatic => self.tf.lookup_static(&body, frame)?,
                };
                (world, body, mount)
            }
        };
        let reach = self.tf.latest_common(&target, &source)?;
        Ok(Path {
            target,
            source,
            mount,
            reach,
        })
    }

    /// A stamp's pose if its path reaches it, its give-up if due, else wait.
    fn outcome(&self, p: &Pending, path: &Result<Path, Option<TfError>>, now_ns: i64) -> Outcome {
        let due = now_ns >= p.deadline_ns;
        let (stamp_ns, frame, wait_ns) = (p.stamp_ns, p.frame.clone(), self.config.wait_ns);
        let path = match path {
            Ok(path) => path,
            Err(_) if !due => return Outcome::Wait,
            Err(None) => return Outcome::GivenUp(GiveUp::NoOdometry { stamp_ns, wait_ns }),
            Err(Some(e)) => {
                let source = e.clone();
                return Outcome::GivenUp(GiveUp::Failed {
                    stamp_ns,
                    frame,
                    source,
                });
            }
        };
        let reached = stamp_ns == LATEST || path.reach.is_none_or(|r| stamp_ns <= r);
        if !reached && !due {
            return Outcome::Wait;
        }
        match self.tf.lookup(&path.target, &path.source, stamp_ns) {
            Ok(pose) => match pose * path.mount {
                pose if pose.is_finite() => Outcome::Ready(pose),
                _ => Outcome::GivenUp(GiveUp::NotFinite { stamp_ns, frame }),
            },
            Err(source @ TfError::ExtrapolationFuture { .. }) if !reached => {
                Outcome::GivenUp(GiveUp::TimedOut {
                    stamp_ns,
                    frame,
                    wait_ns,
                    source,
                })
            }
            Err(source) => Outcome::GivenUp(GiveUp::Failed {
                stamp_ns,
                frame,
                source,
            }),
        }
    }

    fn give_up(&mut self, why: GiveUp) {
        let c = &mut self.counts;
        match why {
            GiveUp::TimedOut { .. } | GiveUp::NoOdometry { .. } => c.timed_out += 1,
            GiveUp::Failed { .. } | GiveUp::NotFinite { .. } => c.failed += 1,
            GiveUp::Overflow { .. } => c.overflow += 1,
        }
        self.last_given_up = Some(why);
    }

    /// The counters for the node to publish: stamps given a pose, given up by reason,
    /// dynamic transforms ignored (Odometry mode), then the buffer's [`TfCounts`].
    pub fn counts(&self) -> [(&'static str, u64); 14] {
        let c = &self.counts;
        let TfCounts {
            inserted,
            invalid,
            frames_full,
            too_old,
            repeated,
            loops,
            stale_parent,
            replaced_edges,
            capped,
        } = self.tf.counts();
        [
            ("pose_source/ready", c.ready),
            ("pose_source/timed_out", c.timed_out),
            ("pose_source/failed", c.failed),
            ("pose_source/overflow", c.overflow),
            ("pose_source/ignored_tf", c.ignored_tf),
            ("tf/inserted", inserted),
            ("tf/invalid", invalid),
            ("tf/frames_full", frames_full),
            ("tf/too_old", too_old),
            ("tf/repeated", repeated),
            ("tf/loops", loops),
            ("tf/stale_parent", stale_parent),
            ("tf/replaced_edges", replaced_edges),
            ("tf/capped", capped),
        ]
    }
}

/// `m` as an exact rigid transform, if it is finite and its matrix a rotation (orthonormal
/// within [`UNIT_TOLERANCE`], determinant +1).
fn rigid(m: &DAffine3) -> Option<DAffine3> {
    let r = m.matrix3;
    let off = (r.transpose() * r - DMat3::IDENTITY).abs().to_cols_array();
    let orthonormal = off.iter().all(|d| *d <= UNIT_TOLERANCE);
    (m.is_finite() && orthonormal && r.determinant() > 0.0).then(|| {
        DAffine3::from_rotation_translation(DQuat::from_mat3(&r).normalize(), m.translation)
    })
}

#[cfg(test)]
#[path = "pose_source_tests.rs"]
mod tests;
