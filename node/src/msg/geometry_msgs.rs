//! `geometry_msgs`: PoseStamped and the Pose, Point and Quaternion it holds; TransformStamped
//! and its Transform and Vector3; and the covariance-carrying PoseWithCovariance, Twist and
//! TwistWithCovariance that `nav_msgs/Odometry` is made of.

use super::cdr::{CdrReader, CdrWriter, DecodeError};
use super::std_msgs::Header;
use super::{Message, MessageKind};

/// `geometry_msgs/msg/Point`: a position, metres.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Point {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}

impl Message for Point {
    const KIND: MessageKind = MessageKind::Point;

    fn write(&self, w: &mut CdrWriter) {
        w.f64_array(&[self.x, self.y, self.z]);
    }

    fn read(r: &mut CdrReader<'_>) -> Result<Self, DecodeError> {
        let [x, y, z] = r.f64_array("position")?;
        Ok(Self { x, y, z })
    }
}

/// `geometry_msgs/msg/Quaternion`: an orientation, fields in the order x, y, z, w.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Quaternion {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
    /// w.
    pub w: f64,
}

impl Default for Quaternion {
    /// The identity rotation (the `.msg` default `w = 1`).
    fn default() -> Self {
        Self {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 1.0,
        }
    }
}

impl Message for Quaternion {
    const KIND: MessageKind = MessageKind::Quaternion;

    fn write(&self, w: &mut CdrWriter) {
        w.f64_array(&[self.x, self.y, self.z, self.w]);
    }

    fn read(r: &mut CdrReader<'_>) -> Result<Self, DecodeError> {
        let [x, y, z, w] = r.f64_array("orientation")?;
        Ok(Self { x, y, z, w })
    }
}

/// `geometry_msgs/msg/Pose`: position then orientation.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Pose {
    /// Position, metres.
    pub position: Point,
    /// Orientation.
    pub orientation: Quaternion,
}

impl Message for Pose {
    const KIND: MessageKind = MessageKind::Pose;

    fn write(&self, w: &mut CdrWriter) {
        self.position.write(w);
        self.orientation.write(w);
    }

    fn read(r: &mut CdrReader<'_>) -> Result<Self, DecodeError> {
        Ok(Self {
            position: Point::read(r)?,
            orientation: Quaternion::read(r)?,
        })
    }
}

/// Fewest bytes one `Pose` takes on the wire: seven `f64`.
pub const POSE_BYTES: usize = 7 * 8;

/// `geometry_msgs/msg/PoseStamped`: a pose in `header.frame_id` at `header.stamp`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PoseStamped {
    /// Time and the frame the pose is expressed in.
    pub header: Header,
    /// The pose.
    pub pose: Pose,
}

impl Message for PoseStamped {
    const KIND: MessageKind = MessageKind::PoseStamped;

    fn write(&self, w: &mut CdrWriter) {
        self.header.write(w);
        self.pose.write(w);
    }

    fn read(r: &mut CdrReader<'_>) -> Result<Self, DecodeError> {
        Ok(Self {
            header: Header::read(r)?,
            pose: Pose::read(r)?,
        })
    }
}

/// Fewest bytes one `PoseStamped` takes on the wire (no padding): stamp, a `frame_id` of
/// length 0 (read as the empty string), the pose.
pub const POSE_STAMPED_MIN_BYTES: usize = 8 + 4 + POSE_BYTES;

/// `geometry_msgs/msg/Vector3`: a vector (a translation, metres).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Vector3 {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}

impl Message for Vector3 {
    const KIND: MessageKind = MessageKind::Vector3;

    fn write(&self, w: &mut CdrWriter) {
        w.f64_array(&[self.x, self.y, self.z]);
    }

    fn read(r: &mut CdrReader<'_>) -> Result<Self, DecodeError> {
        let [x, y, z] = r.f64_array("translation")?;
        Ok(Self { x, y, z })
    }
}

/// `geometry_msgs/msg/Transform`: translation then rotation, the child frame's pose in the
/// parent frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Transform {
    /// The child frame's origin in the parent frame, metres.
    pub translation: Vector3,
    /// The child frame's orientation in the parent frame.
    pub rotation: Quaternion,
}

impl Message for Transform {
    const KIND: MessageKind = MessageKind::Transform;

    fn write(&self, w: &mut CdrWriter) {
        self.translation.write(w);
        self.rotation.write(w);
    }

    fn read(r: &mut CdrReader<'_>) -> Result<Self, DecodeError> {
        Ok(Self {
            translation: Vector3::read(r)?,
            rotation: Quaternion::read(r)?,
        })
    }
}

/// `geometry_msgs/msg/TransformStamped`: the pose of `child_frame_id` in `header.frame_id`
/// at `header.stamp` (what tf2 broadcasts).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TransformStamped {
    /// Time and the parent frame.
    pub header: Header,
    /// The child frame.
    pub child_frame_id: String,
    /// Child to parent.
    pub transform: Transform,
}

/// Fewest bytes one `TransformStamped` takes on the wire (no padding): stamp, frame_id
/// length and NUL, child_frame_id length and NUL, seven `f64`.
pub const TRANSFORM_STAMPED_MIN_BYTES: usize = 8 + 5 + 5 + 7 * 8;

impl Message for TransformStamped {
    const KIND: MessageKind = MessageKind::TransformStamped;

    fn write(&self, w: &mut CdrWriter) {
        self.header.write(w);
        w.string(&self.child_frame_id);
        self.transform.write(w);
    }

    fn read(r: &mut CdrReader<'_>) -> Result<Self, DecodeError> {
        Ok(Self {
            header: Header::read(r)?,
            child_frame_id: r.string("child_frame_id")?,
            transform: Transform::read(r)?,
        })
    }
}

/// A row-major 6x6 covariance over (x, y, z, rotation about x, about y, about z), as
/// `PoseWithCovariance` and `TwistWithCovariance` carry it (`float64[36]`).
pub type Covariance6 = [f64; 36];

/// `geometry_msgs/msg/PoseWithCovariance`: a pose and its uncertainty.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseWithCovariance {
    /// The pose.
    pub pose: Pose,
    /// Its covariance (see [`Covariance6`]); rotations are fixed-axis angles.
    pub covariance: Covariance6,
}

impl Default for PoseWithCovariance {
    fn default() -> Self {
        Self {
            pose: Pose::default(),
            covariance: [0.0; 36],
        }
    }
}

impl Message for PoseWithCovariance {
    const KIND: MessageKind = MessageKind::PoseWithCovariance;

    fn write(&self, w: &mut CdrWriter) {
        self.pose.write(w);
        w.f64_array(&self.covariance);
    }

    fn read(r: &mut CdrReader<'_>) -> Result<Self, DecodeError> {
        Ok(Self {
            pose: Pose::read(r)?,
            covariance: r.f64_array("pose.covariance")?,
        })
    }
}

/// `geometry_msgs/msg/Twist`: a velocity, linear (m/s) then angular (rad/s).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Twist {
    /// Linear velocity.
    pub linear: Vector3,
    /// Angular velocity.
    pub angular: Vector3,
}

impl Message for Twist {
    const KIND: MessageKind = MessageKind::Twist;

    fn write(&self, w: &mut CdrWriter) {
        self.linear.write(w);
        self.angular.write(w);
    }

    fn read(r: &mut CdrReader<'_>) -> Result<Self, DecodeError> {
        let [x, y, z] = r.f64_array("twist.linear")?;
        let linear = Vector3 { x, y, z };
        let [x, y, z] = r.f64_array("twist.angular")?;
        Ok(Self {
            linear,
            angular: Vector3 { x, y, z },
        })
    }
}

/// `geometry_msgs/msg/TwistWithCovariance`: a velocity and its uncertainty.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TwistWithCovariance {
    /// The velocity.
    pub twist: Twist,
    /// Its covariance (see [`Covariance6`]).
    pub covariance: Covariance6,
}

impl Default for TwistWithCovariance {
    fn default() -> Self {
        Self {
            twist: Twist::default(),
            covariance: [0.0; 36],
        }
    }
}

impl Message for TwistWithCovariance {
    const KIND: MessageKind = MessageKind::TwistWithCovariance;

    fn write(&self, w: &mut CdrWriter) {
        self.twist.write(w);
        w.f64_array(&self.covariance);
    }

    fn read(r: &mut CdrReader<'_>) -> Result<Self, DecodeError> {
        Ok(Self {
            twist: Twist::read(r)?,
            covariance: r.f64_array("twist.covariance")?,
        })
    }
}
