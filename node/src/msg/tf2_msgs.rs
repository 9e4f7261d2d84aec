//! `tf2_msgs/msg/TFMessage`, what `/tf` and `/tf_static` carry, and the transforms the node
//! broadcasts on them: world -> `bin_<id>` per bin (static) and world -> the left camera per
//! frame, so RViz and Foxglove place each bin map (`frame_id` `bin_<id>`) in the world.

use glam::{DAffine3, DQuat};

use super::cdr::{CdrReader, CdrWriter, DecodeError};
use super::geometry_msgs::{
    Quaternion, Transform, TransformStamped, Vector3, TRANSFORM_STAMPED_MIN_BYTES,
};
use super::std_msgs::Header;
use super::{Message, MessageKind};

/// The frame the node's outputs are in unless configured otherwise (`run --world-frame`):
/// the poses' frame.
pub const WORLD: &str = "world";

/// `tf2_msgs/msg/TFMessage`: a list of transforms.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TfMessage {
    /// The transforms.
    pub transforms: Vec<TransformStamped>,
}

impl Message for TfMessage {
    const KIND: MessageKind = MessageKind::TfMessage;

    fn write(&self, w: &mut CdrWriter) {
        w.seq_len(self.transforms.len());
        for t in &self.transforms {
            t.write(w);
        }
    }

    fn read(r: &mut CdrReader<'_>) -> Result<Self, DecodeError> {
        let n = r.seq_len("transforms", TRANSFORM_STAMPED_MIN_BYTES)?;
        let transforms = (0..n)
            .map(|_| TransformStamped::read(r))
            .collect::<Result<_, _>>()?;
        Ok(Self { transforms })
    }
}

/// The transform from [`WORLD`] to `child` (the pose of `child` in the world) at
/// `stamp_ns`: [`frame_to`] with `WORLD` as the parent.
pub fn world_to(
    child: impl Into<String>,
    child_to_world: &DAffine3,
    stamp_ns: i64,
) -> TransformStamped {
    frame_to(WORLD, child, child_to_world, stamp_ns)
}

/// The transform from `parent` to `child` (the pose of `child` in `parent`) at `stamp_ns`:
/// a rigid `child_to_parent` (its rotation part is taken as a rotation and normalised).
pub fn frame_to(
    parent: &str,
    child: impl Into<String>,
    child_to_parent: &DAffine3,
    stamp_ns: i64,
) -> TransformStamped {
    let q = DQuat::from_mat3(&child_to_parent.matrix3).normalize();
    let p = child_to_parent.translation;
    TransformStamped {
        header: Header::new(stamp_ns, parent),
        child_frame_id: child.into(),
        transform: Transform {
            translation: Vector3 {
                x: p.x,
                y: p.y,
                z: p.z,
            },
            rotation: Quaternion {
                x: q.x,
                y: q.y,
                z: q.z,
                w: q.w,
            },
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    #[test]
    fn a_transform_round_trips_and_every_cut_is_an_error() {
        let pose = DAffine3::from_rotation_translation(
            DQuat::from_rotation_y(0.3),
            DVec3::new(1e5, -2.0, 3.5),
        );
        let msg = TfMessage {
            transforms: vec![world_to("bin_3", &pose, 1_700_000_000_123_456_789)],
        };
        let bytes = msg.encode();
        assert_eq!(TfMessage::decode(&bytes).unwrap(), msg);
        let t = &msg.transforms[0].transform;
        assert_eq!((t.translation.x, t.translation.z), (1e5, 3.5));
        assert!((t.rotation.y - (0.15f64).sin()).abs() < 1e-15);
        for cut in 0..bytes.len() {
            assert!(TfMessage::decode(&bytes[..cut]).is_err(), "cut at {cut}");
        }
    }

    #[test]
    fn a_huge_count_is_refused_before_allocating() {
        let mut bytes = TfMessage::default().encode();
        bytes[4..8].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(TfMessage::decode(&bytes).is_err());
    }
}
