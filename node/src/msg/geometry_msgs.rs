//! `geometry_msgs`: PoseStamped and the Pose, Point and Quaternion it holds.

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
