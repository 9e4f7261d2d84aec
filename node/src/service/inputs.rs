//! The node's input side: decoding each input sample, pairing left, right and pose, waiting
//! for the camera infos, and binning; what comes out are steps for the worker and the
//! outputs. Bad input is counted per key and changes nothing else.

use std::collections::VecDeque;

use glam::DAffine3;
use model::frame::{RgbImage, StereoFrame, StereoRig};

use super::counters::Counters;
use super::keys::{self, Topic};
use crate::msg::geometry_msgs::PoseStamped;
use crate::msg::image::{intrinsics_from_camera_info, rgb_from_image};
use crate::msg::pose::affine_from_pose;
use crate::msg::sensor_msgs::{CameraInfo, Image};
use crate::msg::Message;
use crate::pipeline::binner::{BinEvent, Binner, BinnerConfig};
use crate::pipeline::sync::{SyncConfig, Synced, Synchronizer};
use crate::pipeline::worker::{now_ns, Job, Stamps};

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
}

type Frame = (StereoFrame, Stamps);

/// Decoders, synchroniser, camera model and binner.
pub(super) struct Inputs {
    sync: Synchronizer<(RgbImage, i64), RgbImage, DAffine3>,
    binner: Binner<Frame>,
    left_info: Option<CameraInfo>,
    right_info: Option<CameraInfo>,
    rig: Option<StereoRig>,
    /// Synchronised frames (with their reset marks) waiting for the camera infos.
    waiting_for_rig: VecDeque<(Frame, bool)>,
    next_index: u32,
}

impl Inputs {
    /// Nothing received yet.
    pub fn new(sync: SyncConfig, binner: BinnerConfig) -> Self {
        Self {
            sync: Synchronizer::new(sync),
            binner: Binner::new(binner),
            left_info: None,
            right_info: None,
            rig: None,
            waiting_for_rig: VecDeque::new(),
            next_index: 0,
        }
    }

    /// Takes one sample of input `topic`; a payload that does not decode or is unusable is
    /// counted as `bad_message/<topic>` and ignored.
    pub fn on_sample(
        &mut self,
        topic: Topic,
        payload: &[u8],
        counters: &mut Counters,
    ) -> Vec<Step> {
        let arrival_ns = now_ns();
        let synced = match topic {
            keys::LEFT_IMAGE => image(payload)
                .map(|(t, img)| self.sync.push_left(t, weight(&img), (img, arrival_ns))),
            keys::RIGHT_IMAGE => {
                image(payload).map(|(t, img)| self.sync.push_right(t, weight(&img), img))
            }
            keys::POSE => pose(payload)
                .map(|(t, p)| self.sync.push_pose(t, std::mem::size_of::<DAffine3>(), p)),
            keys::LEFT_INFO | keys::RIGHT_INFO => {
                self.camera_info(topic, payload).map(|()| Vec::new())
            }
            _ => Some(Vec::new()),
        };
        let Some(synced) = synced else {
            counters.add(&format!("bad_message/{}", topic.name.replace('/', "_")), 1);
            return Vec::new();
        };
        let c = self.sync.counters();
        counters.set("sync/late", c.late);
        counters.set("sync/unmatched", c.unmatched);
        counters.set("sync/over_budget", c.over_budget);
        counters.set("sync/conflict", c.conflict);
        counters.set("sync/outlier", c.outlier);
        counters.set("sync/reset", c.reset);
        for f in synced {
            let reset = f.reset;
            let frame = self.frame(f);
            self.waiting_for_rig.push_back((frame, reset));
            if self.waiting_for_rig.len() > MAX_WAITING_FOR_RIG {
                // A reset still applies to the frames after the dropped one.
                let (_, dropped_reset) = self.waiting_for_rig.pop_front().expect("not empty");
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
        while let Some((frame, reset)) = self.waiting_for_rig.pop_front() {
            // A new timeline: the open bin ends with the old one (its latency still goes out).
            if let Some(bin_id) = reset.then(|| self.binner.reset()).flatten() {
                steps.push(Step::Closed(bin_id));
            }
            let pose = frame.0.left_to_world;
            let job = |bin_id: u64, (frame, stamps): Frame| {
                Box::new(Job {
                    bin_id,
                    frame,
                    rig,
                    stamps,
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

    /// Keeps a usable camera info (`None` if it is not one) and updates the rig.
    fn camera_info(&mut self, topic: Topic, payload: &[u8]) -> Option<()> {
        let msg = CameraInfo::decode(payload).ok()?;
        let (_, baseline) = intrinsics_from_camera_info(&msg).ok()?;
        if topic == keys::RIGHT_INFO {
            // The right camera's P[3] = -fx * baseline: a rig needs a positive baseline.
            (baseline > 0.0 && baseline.is_finite()).then_some(())?;
            self.right_info = Some(msg);
        } else {
            self.left_info = Some(msg);
        }
        self.rig = rig_of(self.left_info.as_ref(), self.right_info.as_ref());
        Some(())
    }

    /// A synchronised frame with its stamps.
    fn frame(&mut self, f: Synced<(RgbImage, i64), RgbImage, DAffine3>) -> Frame {
        let ((left, arrival_ns), right, left_to_world) = (f.left, f.right, f.pose);
        let frame = StereoFrame {
            index: self.next_index,
            left,
            right,
            left_to_world,
        };
        self.next_index += 1;
        let stamps = Stamps {
            arrival_ns,
            opened_ns: now_ns(),
            ..Stamps::default()
        };
        (frame, stamps)
    }
}

/// A stamped image, `None` if it does not decode or convert.
fn image(payload: &[u8]) -> Option<(i64, RgbImage)> {
    let msg = Image::decode(payload).ok()?;
    Some((msg.header.stamp.to_nanos(), rgb_from_image(&msg).ok()?))
}

/// The bytes a decoded image holds (what the synchroniser's byte budget counts).
fn weight(img: &RgbImage) -> usize {
    std::mem::size_of_val(img.data.as_slice())
}

/// A stamped camera-to-world pose, `None` if it does not decode or is not a rigid pose.
fn pose(payload: &[u8]) -> Option<(i64, DAffine3)> {
    let msg = PoseStamped::decode(payload).ok()?;
    Some((msg.header.stamp.to_nanos(), affine_from_pose(&msg).ok()?))
}

/// The rig once both camera infos are known.
fn rig_of(left: Option<&CameraInfo>, right: Option<&CameraInfo>) -> Option<StereoRig> {
    let (intrinsics, _) = intrinsics_from_camera_info(left?).ok()?;
    let (_, baseline) = intrinsics_from_camera_info(right?).ok()?;
    Some(StereoRig {
        intrinsics,
        baseline,
    })
}
