//! Poses: `geometry_msgs/PoseStamped` <-> camera-to-world [`DAffine3`] (f64 throughout, so
//! world positions kilometres from the origin keep millimetres), and the same checked reading
//! of a bare `Pose` and of a `Transform` (what Odometry, Path and tf carry).

use glam::{DAffine3, DQuat, DVec3};

use super::geometry_msgs::{Point, Pose, PoseStamped, Quaternion, Transform};
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
    affine_from_msg_pose(&msg.pose)
}

/// The rigid transform of a `geometry_msgs/Pose` (the checks of [`affine_from_pose`]).
pub fn affine_from_msg_pose(pose: &Pose) -> Result<DAffine3, ConvertError> {
    let Point { x, y, z } = pose.position;
    let o = pose.orientation;
    let (q, t) = checked(
        [x, y, z, o.x, o.y, o.z, o.w],
        [
            "position.x",
            "position.y",
            "position.z",
            "orientation.x",
            "orientation.y",
            "orientation.z",
            "orientation.w",
        ],
    )?;
    Ok(DAffine3::from_rotation_translation(q, t))
}

/// The rotation and translation of a `geometry_msgs/Transform` (child to parent), with the
/// checks of [`affine_from_pose`] (the quaternion then normalised); errors name the
/// transform's own fields.
pub fn checked_transform(t: &Transform) -> Result<(DQuat, DVec3), ConvertError> {
    let (p, q) = (t.translation, t.rotation);
    checked(
        [p.x, p.y, p.z, q.x, q.y, q.z, q.w],
        [
            "translation.x",
            "translation.y",
            "translation.z",
            "rotation.x",
            "rotation.y",
            "rotation.z",
            "rotation.w",
        ],
    )
}

/// A translation (x, y, z) and a quaternion (x, y, z, w) checked finite and unit (within
/// [`UNIT_TOLERANCE`], then normalised); `names` name the seven values in errors.
fn checked(values: [f64; 7], names: [&'static str; 7]) -> Result<(DQuat, DVec3), ConvertError> {
    if let Some(i) = values.iter().position(|v| !v.is_finite()) {
        return Err(ConvertError::NonFinite(names[i]));
    }
    let [x, y, z, qx, qy, qz, qw] = values;
    let q = DQuat::from_xyzw(qx, qy, qz, qw);
    let norm = q.length();
    if (norm - 1.0).abs() > UNIT_TOLERANCE {
        return Err(ConvertError::NonUnitQuaternion {
            norm,
            tolerance: UNIT_TOLERANCE,
        });
    }
    Ok((q / norm, DVec3::new(x, y, z)))
}
