//! Record and replay of the node's topics as MCAP files (the ROS 2 log format).
//!
//! A bag stores opaque message payloads (CDR bytes) together with the channel they were
//! published on; it knows nothing about the message codecs. [`BagWriter`] writes a chunked,
//! zstd-compressed MCAP with the `ros2` profile, `ros2msg` schemas and one channel per distinct
//! [`ChannelInfo`], so `ros2 bag` (rosbag2's MCAP plugin) and Foxglove open it. [`BagReader`]
//! reads it back in log-time order, bit for bit, checking the chunk and summary CRCs so that a
//! damaged file gives a [`BagError`] instead of wrong data; [`BagReader::recover`] reads the
//! complete chunks of a recording that was cut off (a recorder killed with -9), saying how
//! much it kept ([`Recovery`]). Neither lets a damaged file make the `mcap` crate allocate
//! what its lengths claim: every string length and chunk size is checked against the bytes
//! present before the crate parses the record. The writer closes a chunk at least every
//! second while recording ([`BagWriter::flush`]), so such a kill loses about the last second.
//! [`Pacer`] turns recorded log times into sleeps so a replay keeps the recorded timing, a
//! multiple of it, or none.
//!
//! Chunks are compressed with zstd only: the `mcap` crate's lz4 feature would add a C build of
//! liblz4 for a compression that ROS 2 tools rarely write; an lz4 bag gives a
//! [`BagError::Format`] naming the unsupported compression.

mod error;
mod pacing;
mod qos;
mod reader;
mod records;
mod recover;
mod summary;
mod writer;

pub use error::BagError;
pub use pacing::{Pacer, Rate};
pub use qos::offered_qos_profiles;
pub use reader::{BagReader, Messages};
pub use recover::Recovery;
pub use summary::ChannelSummary;
pub use writer::BagWriter;

use std::sync::Arc;

/// The MCAP header profile of a ROS 2 bag.
pub const PROFILE: &str = "ros2";
/// The schema encoding of ROS 2 `.msg` definitions.
pub const SCHEMA_ENCODING: &str = "ros2msg";
/// The message encoding of ROS 2 serialized messages.
pub const CDR: &str = "cdr";

/// Where messages of one kind were published: a topic, its ROS 2 type and how payloads are
/// encoded. Two channels are the same channel when every field is equal.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct ChannelInfo {
    /// The topic name, e.g. `/stereo/left/image_raw`.
    pub topic: String,
    /// The ROS 2 type name, e.g. `sensor_msgs/msg/Image`.
    pub schema_name: String,
    /// The type's `.msg` definition (with its dependencies, as rosbag2 stores it), stored with
    /// schema encoding [`SCHEMA_ENCODING`].
    pub schema_text: String,
    /// How the payloads are encoded, normally [`CDR`].
    pub message_encoding: String,
    /// The publishers' QoS profiles as rosbag2's YAML ([`offered_qos_profiles`]), stored as
    /// the channel's `offered_qos_profiles` metadata; empty when unknown.
    pub offered_qos: String,
}

/// One recorded message: its channel, the two timestamps and sequence number of the MCAP
/// message record, and the payload exactly as it was written.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Message {
    /// The channel it was published on (shared by all messages of the channel).
    pub channel: Arc<ChannelInfo>,
    /// When the recorder received it, nanoseconds; replay paces by this time.
    pub log_time_ns: u64,
    /// When the publisher sent it, nanoseconds.
    pub publish_time_ns: u64,
    /// The publisher's sequence number (0 when unknown).
    pub sequence: u32,
    /// The serialized message, untouched.
    pub payload: Vec<u8>,
}
