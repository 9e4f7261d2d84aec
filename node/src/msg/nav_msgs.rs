//! `nav_msgs`: Odometry (a body frame's pose and velocity, what wheel, visual and lidar
//! odometry publish) and Path (a trajectory of stamped poses, what SLAM back ends publish as
//! their corrected history), and the checked reading of an Odometry's pose as a rigid
//! transform.

use glam::DAffine3;

use super::cdr::{CdrReader, CdrWriter, DecodeError};
use super::geometry_msgs::{
    PoseStamped, PoseWithCovariance, TwistWithCovariance, POSE_STAMPED_MIN_BYTES,
};
use super::pose::affine_from_msg_pose;
use super::std_msgs::Header;
use super::{ConvertError, Message, MessageKind};

/// `nav_msgs/msg/Odometry`: the pose of `child_frame_id` in `header.frame_id` and its
/// velocity in `child_frame_id`, at `header.stamp`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Odometry {
    /// Time and the parent frame (the frame the pose is expressed in, e.g. `odom`).
    pub header: Header,
    /// The body frame whose pose this is (e.g. `base_link`); the twist is expressed in it.
    pub child_frame_id: String,
    /// Body to parent, with its covariance.
    pub pose: PoseWithCovariance,
    /// The body's velocity, with its covariance.
    pub twist: TwistWithCovariance,
}

impl Message for Odometry {
    const KIND: MessageKind = MessageKind::Odometry;

    fn write(&self, w: &mut CdrWriter) {
        self.header.write(w);
        w.string(&self.child_frame_id);
        self.pose.write(w);
        self.twist.write(w);
    }

    fn read(r: &mut CdrReader<'_>) -> Result<Self, DecodeError> {
        Ok(Self {
            header: Header::read(r)?,
            child_frame_id: r.string("child_frame_id")?,
            pose: PoseWithCovariance::read(r)?,
            twist: TwistWithCovariance::read(r)?,
        })
    }
}

/// `nav_msgs/msg/Path`: poses in `header.frame_id` (each `PoseStamped` carries its own stamp
/// and, by convention, the same or an empty frame).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Path {
    /// Time of the path and the frame of its poses.
    pub header: Header,
    /// The poses, oldest first by convention (not enforced).
    pub poses: Vec<PoseStamped>,
}

impl Message for Path {
    const KIND: MessageKind = MessageKind::Path;

    fn write(&self, w: &mut CdrWriter) {
        self.header.write(w);
        w.seq_len(self.poses.len());
        for p in &self.poses {
            p.write(w);
        }
    }

    fn read(r: &mut CdrReader<'_>) -> Result<Self, DecodeError> {
        let header = Header::read(r)?;
        // The count is checked against the bytes left before anything is allocated.
        let n = r.seq_len("poses", POSE_STAMPED_MIN_BYTES)?;
        let poses = (0..n)
            .map(|_| PoseStamped::read(r))
            .collect::<Result<_, _>>()?;
        Ok(Self { header, poses })
    }

    fn size_hint(&self) -> usize {
        64 + self.poses.len() * (POSE_STAMPED_MIN_BYTES + 16)
    }
}

/// An Odometry's pose read as a rigid transform: `child_frame_id` to `frame_id` at `stamp_ns`.
#[derive(Clone, Debug, PartialEq)]
pub struct OdometryPose {
    /// `header.stamp`, nanoseconds since the epoch.
    pub stamp_ns: i64,
    /// The parent frame (`header.frame_id`).
    pub frame_id: String,
    /// The body frame (`child_frame_id`).
    pub child_frame_id: String,
    /// Body to parent (points in the body frame to the parent frame).
    pub child_to_parent: DAffine3,
}

/// The pose of an Odometry message as a rigid transform, checked as
/// [`super::pose::affine_from_pose`] checks a pose (finite, unit quaternion). The covariances
/// and the twist are not read.
pub fn odometry_pose(msg: &Odometry) -> Result<OdometryPose, ConvertError> {
    Ok(OdometryPose {
        stamp_ns: msg.header.stamp.to_nanos(),
        frame_id: msg.header.frame_id.clone(),
        child_frame_id: msg.child_frame_id.clone(),
        child_to_parent: affine_from_msg_pose(&msg.pose.pose)?,
    })
}

#[cfg(test)]
#[path = "nav_msgs_tests.rs"]
mod tests;
