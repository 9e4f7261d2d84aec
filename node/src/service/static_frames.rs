//! What `/tf_static` carries: world -> `bin_<id>` for the most recent bins. tf2's static
//! broadcaster resends its whole set with each message, so a set of every bin would grow
//! with the drive (an hour at 10 m/s is about 4,500 bins, half a megabyte per message, sent
//! with every bin). The node's bin topics are volatile, so a subscriber that joins late gets
//! only new bins and needs only their frames; one that listened all along keeps every frame
//! it received (tf2 never forgets a static transform). So the set is bounded to the last
//! [`STATIC_FRAMES`] bins.

use std::collections::VecDeque;

use crate::msg::geometry_msgs::TransformStamped;

/// Bin frames `/tf_static` carries at most (the most recent).
pub const STATIC_FRAMES: usize = 256;

/// The bounded set of bin frames, oldest first.
#[derive(Debug, Default)]
pub struct StaticFrames {
    frames: VecDeque<TransformStamped>,
}

impl StaticFrames {
    /// Adds a bin's frame, dropping the oldest beyond [`STATIC_FRAMES`].
    pub fn push(&mut self, frame: TransformStamped) {
        if self.frames.len() == STATIC_FRAMES {
            self.frames.pop_front();
        }
        self.frames.push_back(frame);
    }

    /// True before the first bin.
    pub fn is_empty(&self) -> bool {
        self.frames.is_empty()
    }

    /// The frames, oldest first.
    pub fn to_vec(&self) -> Vec<TransformStamped> {
        self.frames.iter().cloned().collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_set_keeps_the_most_recent_bins_only() {
        let mut set = StaticFrames::default();
        assert!(set.is_empty());
        for i in 0..(STATIC_FRAMES + 10) {
            set.push(TransformStamped {
                child_frame_id: format!("bin_{i}"),
                ..TransformStamped::default()
            });
        }
        let frames = set.to_vec();
        assert_eq!(frames.len(), STATIC_FRAMES);
        assert_eq!(frames[0].child_frame_id, "bin_10");
        assert_eq!(
            frames.last().unwrap().child_frame_id,
            format!("bin_{}", STATIC_FRAMES + 9)
        );
    }
}
