//! Odometry as a pose source: a body frame's `nav_msgs/Odometry` and the camera's mount on
//! the body give the camera's pose in the odometry's parent frame; or the Odometry becomes a
//! dynamic edge of the tf buffer (`header.frame_id` -> `child_frame_id`), as
//! `robot_localization` and most odometry nodes also broadcast it.

use glam::DAffine3;

use crate::msg::geometry_msgs::{Transform, TransformStamped, Vector3};
use crate::msg::nav_msgs::{odometry_pose, Odometry};
use crate::msg::ConvertError;

/// A camera's pose from an Odometry: camera -> `frame_id` at `stamp_ns`.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraPose {
    /// The Odometry's stamp, nanoseconds since the epoch.
    pub stamp_ns: i64,
    /// The frame the pose is in (the Odometry's `header.frame_id`, e.g. `odom`).
    pub frame_id: String,
    /// Camera to `frame_id` (points in the camera frame to the parent frame).
    pub camera_to_parent: DAffine3,
}

/// The camera's pose in the Odometry's parent frame: the body's pose (`child_frame_id` ->
/// `header.frame_id`) after `camera_to_body`, the camera's mount (points in the camera frame
/// to the body frame: what [`super::TfBuffer::lookup_static`]`(body, camera)` returns, or a
/// calibrated extrinsic). The Odometry's pose is checked as
/// [`crate::msg::pose::affine_from_pose`] checks one.
pub fn camera_pose_from_odometry(
    odometry: &Odometry,
    camera_to_body: &DAffine3,
) -> Result<CameraPose, ConvertError> {
    let body = odometry_pose(odometry)?;
    Ok(CameraPose {
        stamp_ns: body.stamp_ns,
        frame_id: body.frame_id,
        camera_to_parent: body.child_to_parent * *camera_to_body,
    })
}

/// The Odometry's pose as the transform `header.frame_id` -> `child_frame_id` at its stamp,
/// for [`super::TfBuffer::insert`] (as dynamic); the buffer checks its values.
pub fn odometry_transform(odometry: &Odometry) -> TransformStamped {
    let p = odometry.pose.pose.position;
    let o = odometry.pose.pose.orientation;
    TransformStamped {
        header: odometry.header.clone(),
        child_frame_id: odometry.child_frame_id.clone(),
        transform: Transform {
            translation: Vector3 {
                x: p.x,
                y: p.y,
                z: p.z,
            },
            rotation: o,
        },
    }
}

#[cfg(test)]
#[path = "odometry_tests.rs"]
mod tests;
