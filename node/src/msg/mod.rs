//! ROS 2 wire messages in CDR, so a ROS 2 stack on rmw_zenoh, or any CDR reader, consumes
//! what the node publishes and the node reads what ROS 2 tools publish.
//!
//! * [`cdr`]: the plain-CDR (XCDR1) reader and writer and [`DecodeError`];
//! * the messages, field for field as ROS 2 Jazzy defines them: [`std_msgs`] (Time, Header),
//!   [`sensor_msgs`] (Image, CompressedImage, CameraInfo, PointCloud2), [`geometry_msgs`]
//!   (PoseStamped, TransformStamped, PoseWithCovariance, TwistWithCovariance), [`tf2_msgs`]
//!   (TFMessage, the `/tf` transforms), [`nav_msgs`] (Odometry, Path), and the node's own
//!   [`latency`] messages (BinLatency, Diagnostics);
//! * conversions to and from the project's types: [`image`] (RgbImage, Intrinsics; the
//!   pixel encodings in [`encodings`], Bayer demosaicing in [`demosaic`]), [`compressed`]
//!   (JPEG and PNG CompressedImage, their size read before they are decoded), [`pose`]
//!   (DAffine3), [`gaussians`] (GaussianSet as a PointCloud2 in the 3DGS PLY convention),
//!   failing with [`ConvertError`] (or [`compressed::CompressedError`]);
//! * names and REP 2011 type hashes for rmw_zenoh: [`MessageKind`], [`mod@type_hash`]; complete
//!   definitions as MCAP schemas: [`schema`].
//!
//! Decoders never panic and never allocate much more than their input: every malformed
//! payload is a [`DecodeError`] naming the field and byte offset.

pub mod cdr;
pub mod compressed;
pub mod demosaic;
pub mod encodings;
pub mod gaussians;
pub mod geometry_msgs;
pub mod image;
pub mod kind;
pub mod latency;
pub mod map_update;
pub mod nav_msgs;
pub mod pose;
pub mod schema;
pub mod sensor_msgs;
pub mod std_msgs;
#[cfg(test)]
mod test_frames;
pub mod tf2_msgs;
pub mod type_hash;

pub use cdr::{CdrReader, CdrWriter, DecodeError};
pub use kind::{type_hash, MessageKind};

/// A message with a CDR wire form. `write`/`read` handle the fields (and nest inside other
/// messages); `encode`/`decode` add and check the encapsulation header of a whole payload.
pub trait Message: Sized {
    /// Which type this is (names and type hash).
    const KIND: MessageKind;

    /// Appends the fields.
    fn write(&self, w: &mut CdrWriter);

    /// Reads the fields.
    fn read(r: &mut CdrReader<'_>) -> Result<Self, DecodeError>;

    /// About how many bytes the fields take, reserved before they are written so that a
    /// large payload is not copied each time it outgrows its buffer (0: grow as written).
    fn size_hint(&self) -> usize {
        0
    }

    /// The whole payload, encapsulation header first.
    fn encode(&self) -> Vec<u8> {
        let mut w = CdrWriter::with_capacity(self.size_hint());
        self.write(&mut w);
        w.into_bytes()
    }

    /// Decodes a whole payload (trailing bytes after the last field are ignored).
    fn decode(bytes: &[u8]) -> Result<Self, DecodeError> {
        Self::read(&mut CdrReader::new(bytes)?)
    }
}

/// Why a decoded message could not become one of the project's types (or the reverse).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ConvertError {
    /// An image encoding not in [`encodings::Encoding::ALL`].
    #[error("unsupported image encoding `{0}` (read: rgb8, bgr8, rgba8, bgra8, mono8, mono16, rgb16, bayer_rggb8, bayer_bggr8, bayer_gbrg8, bayer_grbg8)")]
    UnsupportedEncoding(String),
    /// A Bayer image 1 pixel wide or tall: some channel has no sample to interpolate from.
    #[error("bayer image {width}x{height} is too small to demosaic (needs at least 2x2 pixels)")]
    BayerTooSmall {
        /// Columns.
        width: u32,
        /// Rows.
        height: u32,
    },
    /// The image's step or data length disagree with its size.
    #[error("image {width}x{height} {encoding}: step {step} and {len} data bytes (need step >= {min_step} and data = step * height)")]
    ImageSize {
        /// Columns.
        width: u32,
        /// Rows.
        height: u32,
        /// The encoding.
        encoding: String,
        /// Bytes per row declared.
        step: u32,
        /// Smallest valid step.
        min_step: u64,
        /// Data bytes present.
        len: usize,
    },
    /// A value that must be finite is not (names the value).
    #[error("`{0}` is not finite")]
    NonFinite(&'static str),
    /// A camera's focal length is zero or negative.
    #[error("camera info has focal lengths fx = {fx}, fy = {fy}")]
    BadFocal {
        /// P\[0\].
        fx: f64,
        /// P\[5\].
        fy: f64,
    },
    /// A quaternion too far from unit length to be a rotation.
    #[error("quaternion norm {norm} is not 1 (tolerance {tolerance})")]
    NonUnitQuaternion {
        /// Its norm.
        norm: f64,
        /// The accepted deviation from 1.
        tolerance: f64,
    },
    /// A point cloud lacks a field the Gaussians need.
    #[error("point cloud has no `{0}` field")]
    MissingField(&'static str),
    /// A point cloud field that cannot be read as a float scalar inside the record.
    #[error("point cloud field `{name}`: {reason}")]
    BadField {
        /// The field.
        name: String,
        /// What is wrong with it.
        reason: String,
    },
    /// The cloud's sizes disagree with each other or with its data.
    #[error("point cloud {width}x{height}: point_step {point_step}, row_step {row_step}, {len} data bytes (need row_step >= width * point_step and data = row_step * height)")]
    CloudSize {
        /// Points per row.
        width: u32,
        /// Rows.
        height: u32,
        /// Bytes per point.
        point_step: u32,
        /// Bytes per row.
        row_step: u32,
        /// Data bytes present.
        len: usize,
    },
    /// A Gaussian set whose arrays differ in length.
    #[error(transparent)]
    LengthMismatch(#[from] renderer::gaussians::LengthMismatch),
    /// More points or bytes than one CDR message can hold (4 GiB).
    #[error("{0} does not fit a CDR message")]
    TooLarge(&'static str),
}
