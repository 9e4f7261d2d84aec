//! The node's input side: decoding each input sample, pairing left, right and pose, waiting
//! for the camera infos, and binning; what comes out are steps for the worker and the
//! outputs. Bad input is counted per key (`bad_message/<key>`) and changes nothing else;
//! input outside the [`InputLimits`] is refused before it is decoded further and counted
//! under its reason as well (`refused/<reason>`). Images are kept as the messages that came
//! in ([`InputImage`]: raw in any encoding read, or JPEG/PNG on the `compressed` topics)
//! until a frame opens a bin: only those frames are converted to floats and, when larger
//! than the working size, area-averaged down to it (every such image is counted as
//! `input/downscaled` when it arrives); the rig's intrinsics are scaled alike. A frame
//! whose image turns out undecodable then (a cut-off JPEG) is counted against its image's
//! key and skipped before it opens a bin, so the next frame opens it instead.
//!
//! Raw camera images are rectified here, as `stereo_image_proc` does: the camera infos' K,
//! D, R and P ([`crate::rectify`]) give one remap table per camera, built when a calibration
//! first arrives or changes, and the node works in the rectified frame P gives. Images of
//! cameras already rectified (D zero, R identity, P's 3x3 equal to K) pass through.
//!
//! Poses come from the `pose` topic (a PoseStamped of the left camera), or from a pose
//! source ([`crate::tf::PoseSource`], `run --pose-source tf|odometry`): each left image's
//! stamp then waits for the `/tf` tree (or the odometry and the camera's mount on
//! `/tf_static`) to reach it, and the pose looked up there is paired like a PoseStamped one
//! (`pose` samples are then ignored and counted, `ignored/pose_topic`).
//!
//! Each camera's images come raw (`left/image`) or compressed (`left/image/compressed`,
//! image_transport's convention): the first valid image of a camera chooses its transport,
//! and images of the other one are then ignored and counted (`ignored/second_transport`),
//! so a driver publishing both does not give every frame twice.

use std::borrow::Cow;
use std::collections::VecDeque;

use glam::DAffine3;
use model::frame::{RgbImage, StereoFrame, StereoRig};
use model::kitti360::resample::resample_area;
use zenoh::bytes::ZBytes;

use super::input_image::InputImage;
use super::limits::{InputLimits, Refusal};
use super::unusable::Unusable;
use crate::counters::Counters;
use crate::error_text::error_chain as chain;
use crate::msg::geometry_msgs::PoseStamped;
use crate::msg::image::intrinsics_from_camera_info;
use crate::msg::nav_msgs::Odometry;
use crate::msg::pose::affine_from_pose;
use crate::msg::sensor_msgs::CameraInfo;
use crate::msg::tf2_msgs::TfMessage;
use crate::msg::Message;
use crate::pipeline::binner::{BinEvent, Binner, BinnerConfig};
use crate::pipeline::sync::{SyncConfig, Synced, Synchronizer};
use crate::pipeline::worker::{now_ns, Job, Stamps};
use crate::rectify::{self, CameraModel, Rectifier, StereoRectifier};
use crate::tf::PoseSource;
use crate::transport::keys::{self, Topic};

/// Frames kept while no valid pair of camera infos has arrived yet (the oldest is dropped
/// beyond this and counted as `dropped/no_camera_info`).
const MAX_WAITING_FOR_RIG: usize = 16;

/// What an input sample led to.
#[derive(Debug)]
pub(super) enum Step {
    /// A bin opened: its first frame goes to the worker.
    Submit(Box<Job>),
    /// A bin closed (its last frame arrived).
    Closed(u64),
    /// A frame entered the binner: where its left camera was when it was taken.
    Camera(CameraPose),
}

/// The left camera's pose at one frame, for `/tf`.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct CameraPose {
    /// The frame's stamp (its left image's `header.stamp`), ns.
    pub stamp_ns: i64,
    /// The left image's `header.frame_id`, the camera's frame name.
    pub frame_id: String,
    /// Left camera to world.
    pub left_to_world: DAffine3,
}

/// A left image as the synchroniser holds it: the image, when it arrived (ns, the node's
/// clock) and its `header.frame_id`.
type Left = (InputImage, i64, String);

/// A synchronised frame as the binner holds it: its images as they came in.
#[derive(Clone, Debug)]
struct RawFrame {
    index: u32,
    left: InputImage,
    right: InputImage,
    left_to_world: DAffine3,
}

type Frame = (RawFrame, Stamps);

/// What the synchroniser emits: the left image with its arrival time and frame name, the
/// right image, the pose.
type SyncedFrame = Synced<Left, InputImage, DAffine3>;

/// How a camera's images arrive.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Transport {
    /// `sensor_msgs/Image`.
    Raw,
    /// `sensor_msgs/CompressedImage`.
    Compressed,
}

/// Decoders, synchroniser, camera model and binner.
pub(super) struct Inputs {
    sync: Synchronizer<Left, InputImage, DAffine3>,
    /// Where poses come from when not the `pose` topic.
    pose_source: Option<PoseSource>,
    /// Each camera's transport (left, right), chosen by its first valid image.
    transports: [Option<Transport>; 2],
    binner: Binner<Frame>,
    left_info: Option<CameraInfo>,
    right_info: Option<CameraInfo>,
    rig: Option<StereoRig>,
    /// The rig's rectification tables (none built for cameras already rectified).
    rectifier: Option<StereoRectifier>,
    /// Synchronised frames (with their reset marks and left camera frame names) waiting for
    /// the camera infos.
    waiting_for_rig: VecDeque<(Frame, bool, String)>,
    next_index: u32,
    limits: InputLimits,
}

impl Inputs {
    /// Nothing received yet; inputs are checked against `limits`; poses come from the
    /// `pose` topic, or from `pose_source` (`/tf` or odometry) when given.
    pub fn new(
        sync: SyncConfig,
        binner: BinnerConfig,
        limits: InputLimits,
        pose_source: Option<PoseSource>,
    ) -> Self {
        Self {
            pose_source,
            sync: Synchronizer::new(sync),
            transports: [None; 2],
            binner: Binner::new(binner),
            left_info: None,
            right_info: None,
            rig: None,
            rectifier: None,
            waiting_for_rig: VecDeque::new(),
            next_index: 0,
            limits,
        }
    }

    /// Takes one sample of input `topic` that arrived at `arrival_ns` (the node's clock); a
    /// payload that does not decode, is unusable or is refused by the limits is counted as
    /// `bad_message/<topic>` (and a refusal under its reason too) and ignored. The payload's
    /// size is checked before it is made contiguous (a copy when zenoh received it in
    /// fragments).
    pub fn on_sample_at(
        &mut self,
        topic: Topic,
        payload: &ZBytes,
        arrival_ns: i64,
        counters: &mut Counters,
    ) -> Vec<Step> {
        let synced = match self.limits.check_message(payload.len()) {
            Err(e) => Err(e.into()),
            Ok(()) => self.take(topic, &payload.to_bytes(), arrival_ns, counters),
        };
        match synced {
            Ok(synced) => self.advance(synced, counters),
            Err(e) => {
                count_unusable(topic, &e, counters);
                Vec::new()
            }
        }
    }

    /// The node's clock moved on with no sample: stamps waiting for the pose source past
    /// their wait are given up (counted) and any pose it has now is paired, so a drive that
    /// stops does not leave its last images waiting uncounted.
    pub fn on_tick(&mut self, counters: &mut Counters) -> Vec<Step> {
        if self.pose_source.is_none() {
            return Vec::new();
        }
        let synced = self.ready_poses(counters);
        self.advance(synced, counters)
    }

    /// Takes the frames the synchroniser completed: into the wait for the rig, then, with a
    /// rig, through the binner. The steps they lead to.
    fn advance(&mut self, synced: Vec<SyncedFrame>, counters: &mut Counters) -> Vec<Step> {
        let c = self.sync.counters();
        counters.set("sync/late", c.late);
        counters.set("sync/unmatched", c.unmatched);
        counters.set("sync/over_budget", c.over_budget);
        counters.set("sync/conflict", c.conflict);
        counters.set("sync/outlier", c.outlier);
        counters.set("sync/reset", c.reset);
        for f in synced {
            let reset = f.reset;
            let (frame, frame_id) = self.frame(f);
            self.waiting_for_rig.push_back((frame, reset, frame_id));
            if self.waiting_for_rig.len() > MAX_WAITING_FOR_RIG {
                // A reset still applies to the frames after the dropped one.
                let (_, dropped_reset, _) = self.waiting_for_rig.pop_front().expect("not empty");
                if let Some(next) = self.waiting_for_rig.front_mut() {
                    next.1 |= dropped_reset;
                }
                counters.add("dropped/no_camera_info", 1);
            }
        }
        let Some(rig) = self.rig else {
            return Vec::new();
        };
        let mut steps = Vec::new();
        while let Some((frame, reset, frame_id)) = self.waiting_for_rig.pop_front() {
            // A new timeline: the open bin ends with the old one (its latency still goes out).
            if let Some(bin_id) = reset.then(|| self.binner.reset()).flatten() {
                steps.push(Step::Closed(bin_id));
            }
            if let Err(r) = fits_rig(&frame.0, &rig, &self.limits) {
                counters.add(r.counter(), 1);
                continue;
            }
            let pose = frame.0.left_to_world;
            // Only a frame that opens a bin is converted, before it does.
            let mut working = None;
            if self.binner.opens(&pose) {
                let rectifier = self.rectifier.as_ref().expect("with the rig");
                match working_frame(&frame.0, rectifier, &self.limits) {
                    Ok(f) => working = Some(f),
                    Err((topic, e)) => {
                        count_unusable(topic, &e, counters);
                        continue;
                    }
                }
            }
            steps.push(Step::Camera(CameraPose {
                stamp_ns: frame.1.source_ns,
                frame_id,
                left_to_world: pose,
            }));
            let mut job = |bin_id: u64, (_, stamps): Frame| {
                Box::new(Job {
                    bin_id,
                    frame: working.take().expect("converted: the frame opens a bin"),
                    rig,
                    stamps,
                    point: 0,
                })
            };
            match self.binner.push(frame, pose) {
                BinEvent::Opened { bin_id, first } => steps.push(Step::Submit(job(bin_id, first))),
                BinEvent::Closed {
                    bin_id, next_first, ..
                } => {
                    steps.push(Step::Closed(bin_id));
                    steps.push(Step::Submit(job(bin_id + 1, next_first)));
                }
                BinEvent::Inside => {}
                BinEvent::Rejected => counters.add("dropped/non_finite_pose", 1),
            }
        }
        steps
    }

    /// Decodes and checks one sample and hands it to the synchroniser (or, for a camera
    /// info, to the rig): the frames it completes.
    fn take(
        &mut self,
        topic: Topic,
        payload: &[u8],
        arrival_ns: i64,
        counters: &mut Counters,
    ) -> Result<Vec<SyncedFrame>, Unusable> {
        let limits = self.limits;
        let camera = match topic {
            keys::LEFT_IMAGE | keys::LEFT_COMPRESSED => Some(0),
            keys::RIGHT_IMAGE | keys::RIGHT_COMPRESSED => Some(1),
            _ => None,
        };
        if let Some(camera) = camera {
            let transport = match topic {
                keys::LEFT_COMPRESSED | keys::RIGHT_COMPRESSED => Transport::Compressed,
                _ => Transport::Raw,
            };
            if self.transports[camera].is_some_and(|t| t != transport) {
                counters.add("ignored/second_transport", 1);
                return Ok(Vec::new());
            }
            let (t, img, frame_id) = image(payload, transport, &limits, counters)?;
            self.transports[camera] = Some(transport);
            let weight = img.bytes();
            if camera == 1 {
                return Ok(self.sync.push_right(t, weight, img));
            }
            if let Some(source) = &mut self.pose_source {
                source.on_image(t, &frame_id, arrival_ns);
            }
            let mut frames = self.sync.push_left(t, weight, (img, arrival_ns, frame_id));
            frames.extend(self.ready_poses(counters));
            return Ok(frames);
        }
        match topic {
            keys::POSE if self.pose_source.is_some() => {
                counters.add("ignored/pose_topic", 1);
                Ok(Vec::new())
            }
            keys::POSE => pose(payload, &limits)
                .map(|(t, p)| self.sync.push_pose(t, std::mem::size_of::<DAffine3>(), p)),
            keys::TF | keys::TF_STATIC | keys::ODOMETRY => {
                let Some(source) = &mut self.pose_source else {
                    return Ok(Vec::new());
                };
                match topic {
                    keys::ODOMETRY => source.on_odometry(&Odometry::decode(payload)?),
                    _ => source.on_tf(&TfMessage::decode(payload)?, topic == keys::TF_STATIC),
                }
                Ok(self.ready_poses(counters))
            }
            keys::LEFT_INFO | keys::RIGHT_INFO => {
                self.camera_info(topic, payload).map(|()| Vec::new())
            }
            _ => Ok(Vec::new()),
        }
    }

    /// Keeps a usable, sane camera info and, once both cameras' are in, updates the rig and
    /// its rectification (tables rebuilt only when a calibration changed). Two infos of the
    /// same stamp that no rectified rig can come from are refused as a pair
    /// (`refused/stereo_rig`) and the rig in force stays; infos of different stamps that
    /// disagree are a change half through (a new size or calibration reaches one camera's
    /// topic first) and wait, uncounted, for the other camera's. Each info is kept, so a
    /// change of both takes effect once both new infos are in.
    fn camera_info(&mut self, topic: Topic, payload: &[u8]) -> Result<(), Unusable> {
        let msg = CameraInfo::decode(payload)?;
        let (k, baseline) = intrinsics_from_camera_info(&msg)?;
        // The right camera's P[3] = -fx * baseline: a rig needs a positive baseline.
        let right = topic == keys::RIGHT_INFO;
        self.limits.check_camera(&k, right.then_some(baseline))?;
        CameraModel::from_camera_info(&msg).map_err(|e| Refusal::CameraInfo(chain(&e)))?;
        match right {
            true => self.right_info = Some(msg),
            false => self.left_info = Some(msg),
        }
        let (Some(left), Some(right)) = (&self.left_info, &self.right_info) else {
            return Ok(());
        };
        let stereo = match rectify::StereoRig::from_camera_infos(left, right) {
            Ok(stereo) => stereo,
            // Infos of one moment that disagree: refused.
            Err(e) if left.header.stamp == right.header.stamp => {
                return Err(Refusal::StereoRig(chain(&e)).into())
            }
            // One camera's info is newer than the other's: a calibration or size change
            // half through; the rig in force stays until the other camera's arrives.
            Err(_) => return Ok(()),
        };
        let (intrinsics, baseline) = stereo.intrinsics();
        let (w, h) = self
            .limits
            .working_size(intrinsics.width, intrinsics.height);
        let intrinsics = match (w, h) == (intrinsics.width, intrinsics.height) {
            true => intrinsics,
            false => intrinsics.scaled(w, h),
        };
        self.rig = Some(StereoRig {
            intrinsics,
            baseline,
        });
        match &mut self.rectifier {
            Some(r) => _ = r.update(stereo),
            None => self.rectifier = Some(StereoRectifier::new(stereo)),
        }
        Ok(())
    }

    /// The poses the pose source has for waiting image stamps, checked against the limits
    /// and paired like PoseStamped poses: the frames they complete. Sets the pose source's
    /// counters.
    fn ready_poses(&mut self, counters: &mut Counters) -> Vec<SyncedFrame> {
        let Some(source) = &mut self.pose_source else {
            return Vec::new();
        };
        let ready = source.take_ready(now_ns());
        for (name, value) in source.counts() {
            counters.set(name, value);
        }
        let mut frames = Vec::new();
        for (t, pose) in ready {
            match self.limits.check_pose(&pose) {
                Ok(()) => {
                    let weight = std::mem::size_of::<DAffine3>();
                    frames.extend(self.sync.push_pose(t, weight, pose));
                }
                Err(r) => counters.add(r.counter(), 1),
            }
        }
        frames
    }

    /// A synchronised frame with its stamps, and its left camera's frame name.
    fn frame(&mut self, f: SyncedFrame) -> (Frame, String) {
        let ((left, arrival_ns, frame_id), right, left_to_world) = (f.left, f.right, f.pose);
        let frame = RawFrame {
            index: self.next_index,
            left,
            right,
            left_to_world,
        };
        self.next_index += 1;
        let stamps = Stamps {
            source_ns: f.stamp_ns,
            arrival_ns,
            opened_ns: now_ns(),
            ..Stamps::default()
        };
        ((frame, stamps), frame_id)
    }
}

/// A stamped image as it came in, checked, with its frame name. Its declared size is
/// checked against the limits before anything is copied (for a compressed image, the size
/// its file's header declares); one larger than the working size is counted as
/// `input/downscaled` (it is brought to that size if its frame opens a bin,
/// [`working_frame`]).
fn image(
    payload: &[u8],
    transport: Transport,
    limits: &InputLimits,
    counters: &mut Counters,
) -> Result<(i64, InputImage, String), Unusable> {
    let taken = match transport {
        Transport::Raw => InputImage::raw(payload, limits)?,
        Transport::Compressed => InputImage::compressed(payload, limits)?,
    };
    let (w, h) = taken.1.size();
    if limits.working_size(w, h) != (w, h) {
        counters.add("input/downscaled", 1);
    }
    Ok(taken)
}

/// A frame's images as [0, 1] floats at the working size (converted from their encoding or
/// decoded, rectified unless their cameras are rectified already, then area-averaged down
/// when larger): what the worker is given. An image that cannot be converted is an error
/// with the key it came on.
fn working_frame(
    frame: &RawFrame,
    rectifier: &StereoRectifier,
    limits: &InputLimits,
) -> Result<StereoFrame, (Topic, Unusable)> {
    let working = |img: &InputImage,
                   camera: &Rectifier,
                   topic: Topic|
     -> Result<RgbImage, (Topic, Unusable)> {
        let fail = |e: Unusable| (topic, e);
        let raw = img.to_rgb8(limits).map_err(fail)?;
        let rectified = match camera.rectify(&raw).map_err(|e| fail(e.into()))? {
            Cow::Owned(rectified) => Some(rectified),
            Cow::Borrowed(_) => None,
        };
        let rgb = rectified.unwrap_or(raw).to_rgb();
        Ok(match limits.working_size(rgb.width, rgb.height) {
            (w, h) if (w, h) == (rgb.width, rgb.height) => rgb,
            (w, h) => resample_area(&rgb, w, h),
        })
    };
    let key = |img: &InputImage, raw: Topic, compressed: Topic| match img {
        InputImage::Raw(_) => raw,
        InputImage::Compressed { .. } => compressed,
    };
    Ok(StereoFrame {
        index: frame.index,
        left: working(
            &frame.left,
            rectifier.left(),
            key(&frame.left, keys::LEFT_IMAGE, keys::LEFT_COMPRESSED),
        )?,
        right: working(
            &frame.right,
            rectifier.right(),
            key(&frame.right, keys::RIGHT_IMAGE, keys::RIGHT_COMPRESSED),
        )?,
        left_to_world: frame.left_to_world,
    })
}

/// Counts an unusable sample of `topic`: `bad_message/<topic>`, and a refusal under its
/// reason too.
fn count_unusable(topic: Topic, e: &Unusable, counters: &mut Counters) {
    let name = topic.name.trim_start_matches('/').replace('/', "_");
    counters.add(&format!("bad_message/{name}"), 1);
    if let Unusable::Refused(r) = e {
        counters.add(r.counter(), 1);
    }
}

/// A stamped camera-to-world pose: it must decode, be rigid and lie within the limits.
fn pose(payload: &[u8], limits: &InputLimits) -> Result<(i64, DAffine3), Unusable> {
    let msg = PoseStamped::decode(payload)?;
    let pose = affine_from_pose(&msg)?;
    limits.check_pose(&pose)?;
    Ok((msg.header.stamp.to_nanos(), pose))
}

/// Whether a frame's images, at their working size, have the size of the rig's cameras; a
/// frame that does not would fail in the reconstructor, so it is refused before reaching
/// the worker.
fn fits_rig(frame: &RawFrame, rig: &StereoRig, limits: &InputLimits) -> Result<(), Refusal> {
    let camera = (rig.intrinsics.width, rig.intrinsics.height);
    for image in [&frame.left, &frame.right] {
        let (w, h) = image.size();
        let working = limits.working_size(w, h);
        if working != camera {
            return Err(Refusal::SizeMismatch {
                image: working,
                camera,
            });
        }
    }
    Ok(())
}

/// The input topics, in the order [`feed`]'s callers number them.
pub(crate) const INPUT_TOPICS: [Topic; 7] = [
    keys::LEFT_IMAGE,
    keys::RIGHT_IMAGE,
    keys::LEFT_INFO,
    keys::RIGHT_INFO,
    keys::POSE,
    keys::LEFT_COMPRESSED,
    keys::RIGHT_COMPRESSED,
];

/// [`INPUT_TOPICS`] then the pose source's (`/tf`, `/tf_static`, odometry): what a node with
/// `--pose-source` reads.
pub(crate) const POSE_SOURCE_TOPICS: [Topic; 10] = {
    let mut topics = [keys::TF; 10];
    let mut i = 0;
    while i < INPUT_TOPICS.len() {
        topics[i] = INPUT_TOPICS[i];
        i += 1;
    }
    topics[8] = keys::TF_STATIC;
    topics[9] = keys::ODOMETRY;
    topics
};

/// Runs `samples` (topic and payload) through a fresh input side with the default
/// synchroniser, binner and limits and `pose_source` (`None`: the `pose` topic), then one
/// tick, as the node takes its inputs: what the fuzzing of the input path calls
/// (`crate::untrusted_input::live::node_inputs`). Returns the jobs it submitted (each frame
/// already brought to the working size, as the worker gets it) and the counters.
pub(crate) fn feed<'a>(
    samples: impl IntoIterator<Item = (Topic, &'a [u8])>,
    pose_source: Option<crate::tf::PoseSourceConfig>,
) -> (usize, Counters) {
    let pose_source = pose_source.and_then(|c| PoseSource::new(c).ok());
    let mut inputs = Inputs::new(
        SyncConfig::default(),
        BinnerConfig::default(),
        InputLimits::default(),
        pose_source,
    );
    let mut counters = Counters::default();
    let mut jobs = 0;
    for (topic, payload) in samples {
        let payload = ZBytes::from(payload.to_vec());
        let steps = inputs.on_sample_at(topic, &payload, now_ns(), &mut counters);
        jobs += submitted(&steps);
    }
    jobs += submitted(&inputs.on_tick(&mut counters));
    (jobs, counters)
}

/// Jobs among `steps`.
fn submitted(steps: &[Step]) -> usize {
    steps
        .iter()
        .filter(|s| matches!(s, Step::Submit(_)))
        .count()
}
