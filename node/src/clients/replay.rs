//! Replaying a sequence in the KITTI-360 layout (real or synthetic) onto the node's input
//! topics: camera infos, then per frame the left and right images and the pose, paced by the
//! recorded timestamps (or a multiple of them, or as fast as possible). Puts block rather
//! than drop when zenoh's queues are full (the Outlet's publishers), so "as fast as
//! possible" means as fast as the node takes them. A frame whose images cannot be read is
//! skipped and listed with its error (which names the file and the reason), so the caller
//! can report it and fail.

use std::time::{Duration, Instant};

use model::kitti360::{FramePose, Kitti360Error, Sequence};
use zenoh::Session;

use crate::bag::Rate;
use crate::msg::image::{camera_info, image_from_rgb8};
use crate::msg::pose::pose_from_affine;
use crate::msg::std_msgs::Header;
use crate::msg::Message;
use crate::service::error::ServiceError;
use crate::transport::keys::{self, Direction, Keys, Topic, TOPICS};
use crate::transport::Outlet;

/// A frame the replay could not publish.
#[derive(Debug)]
pub struct UnreadFrame {
    /// The frame's index in the sequence.
    pub index: u32,
    /// Why it could not be loaded (names the file).
    pub error: Kitti360Error,
}

/// What a replay published.
#[derive(Debug, Default)]
pub struct ReplaySummary {
    /// Frames published.
    pub frames: u64,
    /// Frames that failed to load, in order.
    pub skipped: Vec<UnreadFrame>,
}

/// What a replay plays: frames of a sequence, each published with its own pose and
/// timestamp and the images of its frame index. The sequence's own frames, or frames made
/// from them, such as [`model::kitti360::laps::chain_laps`]'s laps.
#[derive(Clone, Copy, Debug)]
pub struct Drive<'a> {
    /// Where the images and the rig come from.
    pub sequence: &'a Sequence,
    /// The frames to play, in order.
    pub frames: &'a [FramePose],
}

impl<'a> Drive<'a> {
    /// Every frame of `sequence`, as recorded.
    pub fn whole(sequence: &'a Sequence) -> Self {
        Self {
            sequence,
            frames: sequence.frames(),
        }
    }
}

/// Publishes every frame of `sequence` on `session`; `progress(done, total)` after each.
pub async fn replay(
    session: &Session,
    keys: &Keys,
    sequence: &Sequence,
    rate: Rate,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<ReplaySummary, ServiceError> {
    replay_drive(session, keys, Drive::whole(sequence), rate, progress).await
}

/// Publishes the frames of `drive` on `session`; `progress(done, total)` after each.
pub async fn replay_drive(
    session: &Session,
    keys: &Keys,
    drive: Drive<'_>,
    rate: Rate,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<ReplaySummary, ServiceError> {
    let Drive { sequence, frames } = drive;
    let inputs: Vec<_> = TOPICS
        .into_iter()
        .filter(|t| t.direction == Direction::Input)
        .collect();
    let outlet = Outlet::declare(session, keys, "stereosplat_replay", &inputs, &[]).await?;
    let put = |topic: Topic, payload: Vec<u8>| {
        let outlet = &outlet;
        async move { outlet.put(topic, payload).await }
    };
    let rig = sequence.rig();
    let stamp = |i: usize| frames[i].timestamp_ns.unwrap_or(i as i64 * 100_000_000);
    let start = Instant::now();
    let first_ns = frames.first().map_or(0, |_| stamp(0));
    let mut summary = ReplaySummary::default();
    for (i, f) in frames.iter().enumerate() {
        let t = stamp(i);
        let due = rate.due_after(t.saturating_sub(first_ns).max(0) as u64);
        if let Some(wait) = due.checked_sub(start.elapsed()) {
            tokio::time::sleep(wait).await;
        }
        let header = |frame_id: &str| Header::new(t, frame_id);
        put(
            keys::LEFT_INFO,
            camera_info(&rig.intrinsics, 0.0, header("left")).encode(),
        )
        .await?;
        put(
            keys::RIGHT_INFO,
            camera_info(&rig.intrinsics, rig.baseline, header("right")).encode(),
        )
        .await?;
        // The PNGs' bytes go out as they are (no round trip through floats).
        match sequence.load_frame_rgb8(f.index) {
            Ok(frame) => {
                put(
                    keys::LEFT_IMAGE,
                    image_from_rgb8(frame.left, header("left")).encode(),
                )
                .await?;
                put(
                    keys::RIGHT_IMAGE,
                    image_from_rgb8(frame.right, header("right")).encode(),
                )
                .await?;
                put(
                    keys::POSE,
                    pose_from_affine(&f.left_to_world, header("world")).encode(),
                )
                .await?;
                summary.frames += 1;
            }
            Err(error) => summary.skipped.push(UnreadFrame {
                index: f.index,
                error,
            }),
        }
        progress(i + 1, frames.len());
    }
    // Let the last samples leave before the caller closes the session.
    tokio::time::sleep(Duration::from_millis(50)).await;
    Ok(summary)
}
