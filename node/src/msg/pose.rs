//! Poses: `geometry_msgs/PoseStamped` <-> camera-to-world [`DAffine3`] (f64 throughout, so
//! world positions kilometres from the origin keep millimetres).

use glam::{DAffine3, DQuat, DVec3};

use super::geometry_msgs::{Point, Pose, PoseStamped, Quaternion};
use super::std_msgs::Header;
use super::ConvertError;

/// How far from 1 a quaternion's norm may be and still be read as a rotation (it is then
/// normalised). Quaternions computed in `f32` are within about `1e-7`.
pub const UNIT_TOLERANCE: f64 = 1e-5;

/// The pose message of a rigid transform (its rotation part must be a rotation: the
/// quaternion is taken from the matrix and normalised).
pub fn pose_from_affine(t: &DAffine3, header: Header) -> PoseStamped {
    let q = DQuat::from_mat3(&t.matrix3).normalize();
    let p = t.translation;
    PoseStamped {
        header,
        pose: Pose {
            position: Point {
                x: p.x,
                y: p.y,
                z: p.z,
            },
            orientation: Quaternion {
                x: q.x,
                y: q.y,
                z: q.z,
                w: q.w,
            },
        },
    }
}

/// The rigid transform of a pose message. Non-finite values and a quaternion whose norm is
/// more than [`UNIT_TOLERANCE`] from 1 are errors.
pub fn affine_from_pose(msg: &PoseStamped) -> Result<DAffine3, ConvertError> {
    let Point { x, y, z } = msg.pose.position;
    let o = msg.pose.orientation;
    let named = [
        (x, "position.x"),
        (y, "position.y"),
        (z, "position.z"),
        (o.x, "orientation.x"),
        (o.y, "orientation.y"),
        (o.z, "orientation.z"),
        (o.w, "orientation.w"),
    ];
    if let Some((_, name)) = named.iter().find(|(v, _)| !v.is_finite()) {
        return Err(ConvertError::NonFinite(name));
    }
    let q = DQuat::from_xyzw(o.x, o.y, o.z, o.w);
    let norm = q.length();
    if (norm - 1.0).abs() > UNIT_TOLERANCE {
        return Err(ConvertError::NonUnitQuaternion {
            norm,
            tolerance: UNIT_TOLERANCE,
        });
    }
    Ok(DAffine3::from_rotation_translation(
        q / norm,
        DVec3::new(x, y, z),
    ))
}
