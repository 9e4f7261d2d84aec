//! `builtin_interfaces/msg/Time` and `std_msgs/msg/Header`, the stamp and frame every
//! stamped message starts with.

use super::cdr::{CdrReader, CdrWriter, DecodeError};
use super::{Message, MessageKind};

/// `builtin_interfaces/msg/Time`: `int32 sec`, `uint32 nanosec` (nanosec < 1e9 by
/// convention; not enforced on decode, as ROS does not).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Time {
    /// Whole seconds since the Unix epoch.
    pub sec: i32,
    /// Nanoseconds within the second.
    pub nanosec: u32,
}

impl Time {
    /// From nanoseconds since the epoch, floored to whole seconds as ROS does (so -1 ns is
    /// `sec = -1, nanosec = 999_999_999`); seconds beyond `i32` saturate.
    pub fn from_nanos(ns: i64) -> Self {
        let sec = ns.div_euclid(1_000_000_000);
        Self {
            sec: sec.clamp(i32::MIN as i64, i32::MAX as i64) as i32,
            nanosec: ns.rem_euclid(1_000_000_000) as u32,
        }
    }

    /// Nanoseconds since the epoch.
    pub fn to_nanos(self) -> i64 {
        self.sec as i64 * 1_000_000_000 + self.nanosec as i64
    }
}

impl Message for Time {
    const KIND: MessageKind = MessageKind::Time;

    fn write(&self, w: &mut CdrWriter) {
        w.i32(self.sec);
        w.u32(self.nanosec);
    }

    fn read(r: &mut CdrReader<'_>) -> Result<Self, DecodeError> {
        Ok(Self {
            sec: r.i32("stamp.sec")?,
            nanosec: r.u32("stamp.nanosec")?,
        })
    }
}

/// `std_msgs/msg/Header`: `builtin_interfaces/Time stamp`, `string frame_id`.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Header {
    /// When the data was captured (or, for derived data, of the data it came from).
    pub stamp: Time,
    /// The coordinate frame the data is expressed in (for bin maps, the bin frame's name).
    pub frame_id: String,
}

impl Header {
    /// A header at `ns` nanoseconds since the epoch in frame `frame_id`.
    pub fn new(ns: i64, frame_id: impl Into<String>) -> Self {
        Self {
            stamp: Time::from_nanos(ns),
            frame_id: frame_id.into(),
        }
    }
}

impl Message for Header {
    const KIND: MessageKind = MessageKind::Header;

    fn write(&self, w: &mut CdrWriter) {
        self.stamp.write(w);
        w.string(&self.frame_id);
    }

    fn read(r: &mut CdrReader<'_>) -> Result<Self, DecodeError> {
        Ok(Self {
            stamp: Time::read(r)?,
            frame_id: r.string("header.frame_id")?,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn negative_nanos_floor_to_the_previous_second() {
        let t = Time::from_nanos(-1);
        assert_eq!((t.sec, t.nanosec), (-1, 999_999_999));
        assert_eq!(t.to_nanos(), -1);
        let t = Time::from_nanos(1_700_000_000_123_456_789);
        assert_eq!((t.sec, t.nanosec), (1_700_000_000, 123_456_789));
    }

    #[test]
    fn a_header_is_stamp_then_frame() {
        let b = Header::new(3_000_000_004, "map").encode();
        let want = [
            0, 1, 0, 0, 3, 0, 0, 0, 4, 0, 0, 0, 4, 0, 0, 0, b'm', b'a', b'p', 0,
        ];
        assert_eq!(b, want);
        assert_eq!(Header::decode(&b).unwrap().frame_id, "map");
    }
}
