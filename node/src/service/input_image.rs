//! A camera image as the input side holds it between arrival and binning: the message as
//! it came in, checked but not converted. A `sensor_msgs/Image` in any encoding the node
//! reads has its encoding, step and length checked on arrival; a `sensor_msgs/CompressedImage`
//! (image_transport's `compressed` transport, JPEG or PNG) has its size read from the file's
//! own header and checked against the input limits, before a pixel is decoded. Only the
//! frames that open bins are converted to packed RGB ([`InputImage::to_rgb8`]), so a
//! camera at 10 Hz costs one decode per bin, not one per frame, and an image claiming more
//! pixels than the limits allow is refused without allocating for it.

use model::frame::Rgb8Image;

use super::limits::InputLimits;
use super::unusable::Unusable;
use crate::msg::compressed::{peek_compressed, rgb8_from_compressed, PixelLimits};
use crate::msg::encodings::Encoding;
use crate::msg::image::rgb8_from_image;
use crate::msg::sensor_msgs::{CompressedImage, Image, ImageLayout};
use crate::msg::Message;

/// An input image as it came in, checked.
#[derive(Clone, Debug)]
pub enum InputImage {
    /// A `sensor_msgs/Image` whose encoding, step and length are valid.
    Raw(Image),
    /// A `sensor_msgs/CompressedImage` with the size its header declares.
    Compressed {
        /// The message.
        msg: CompressedImage,
        /// Columns and rows, from the file's header.
        size: (u32, u32),
    },
}

impl InputImage {
    /// A `sensor_msgs/Image` payload: its declared size checked against `limits` before
    /// its pixels are copied, then its encoding and layout. Returns the stamp (ns), the
    /// image and its `header.frame_id`.
    pub fn raw(payload: &[u8], limits: &InputLimits) -> Result<(i64, Self, String), Unusable> {
        limits.check_image(&ImageLayout::peek(payload)?)?;
        let mut msg = Image::decode(payload)?;
        Encoding::of(&msg)?;
        let frame_id = std::mem::take(&mut msg.header.frame_id);
        Ok((msg.header.stamp.to_nanos(), Self::Raw(msg), frame_id))
    }

    /// A `sensor_msgs/CompressedImage` payload: its file's header read and the size it
    /// declares checked against `limits`. Same returns as [`InputImage::raw`].
    pub fn compressed(
        payload: &[u8],
        limits: &InputLimits,
    ) -> Result<(i64, Self, String), Unusable> {
        let mut msg = CompressedImage::decode(payload)?;
        let header = peek_compressed(&msg.data)?;
        // The decoded image's size, refused as a raw image of it would be.
        limits.check_image(&ImageLayout {
            width: header.width,
            height: header.height,
            step: header.width.saturating_mul(3),
            data_len: 0,
        })?;
        let frame_id = std::mem::take(&mut msg.header.frame_id);
        let size = (header.width, header.height);
        let stamp = msg.header.stamp.to_nanos();
        Ok((stamp, Self::Compressed { msg, size }, frame_id))
    }

    /// Columns and rows.
    pub fn size(&self) -> (u32, u32) {
        match self {
            Self::Raw(msg) => (msg.width, msg.height),
            Self::Compressed { size, .. } => *size,
        }
    }

    /// The bytes it holds (what the synchroniser's byte budget counts).
    pub fn bytes(&self) -> usize {
        match self {
            Self::Raw(msg) => msg.data.len(),
            Self::Compressed { msg, .. } => msg.data.len(),
        }
    }

    /// The image as packed RGB: converted from its encoding, or decoded (within `limits`);
    /// a compressed file that turns out cut off or corrupt is an error.
    pub fn to_rgb8(&self, limits: &InputLimits) -> Result<Rgb8Image, Unusable> {
        match self {
            Self::Raw(msg) => Ok(rgb8_from_image(msg.clone())?),
            Self::Compressed { msg, .. } => Ok(rgb8_from_compressed(msg, &pixel_limits(limits))?),
        }
    }
}

/// The image limits of `limits` as the compressed decoder takes them.
fn pixel_limits(limits: &InputLimits) -> PixelLimits {
    PixelLimits {
        max_width: limits.max_width,
        max_height: limits.max_height,
        max_pixels: limits.max_pixels,
    }
}
