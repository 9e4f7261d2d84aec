//! `sensor_msgs/CompressedImage` (JPEG and PNG, image_transport's `compressed` transport)
//! <-> packed RGB, with the decoded size read from the file's own header first, so that a
//! file claiming more pixels than the limits allow is refused before anything is allocated
//! for it.
//!
//! * [`peek_compressed`] reads the size: for JPEG it walks the marker segments from SOI to
//!   the first frame header (SOF0..SOF15 but DHT, JPG and DAC), for PNG it reads the IHDR
//!   chunk, which must come first. It allocates nothing.
//! * [`rgb8_from_compressed`] checks that size against [`PixelLimits`], refuses a JPEG
//!   whose marker structure ends before its end-of-image marker (cut off: the decoder would
//!   fill the missing rows in and succeed), decodes with the `image` crate under
//!   `image::Limits` of the same size (a decoder that found a larger frame elsewhere in the
//!   file stops), checks that the decoded size is the peeked one and converts grey,
//!   grey-alpha, RGBA and 16-bit images to packed RGB8 (alpha dropped, 16-bit values
//!   rounded to `round(v * 255 / 65535)`, the `image` crate's rule, which gives back the
//!   byte `b` of a value `b * 257` as `v >> 8` would).
//! * [`compressed_image`] encodes an RGB8 image as compressed_image_transport does, for
//!   tests and the project's players.
//!
//! The codec is the one the data's magic bytes name (`FF D8 FF` JPEG, the 8-byte PNG
//! signature). The `format` field is not trusted for it: publishers write `jpeg`, `png`,
//! `rgb8; jpeg compressed bgr8`, or nothing, and a disagreeing one changes nothing. Only a
//! `compressedDepth` format (compressed_depth_image_transport's depth images, which are no
//! camera picture) is refused by its name. The `COMPRESSED_PIXFMT` (`bgr8`) describes
//! OpenCV's buffer before encoding, not the file: JPEG and PNG files store RGB either way.

use std::fmt;
use std::io::Cursor;

use image::codecs::jpeg::JpegEncoder;
use image::codecs::png::PngEncoder;
use image::{ExtendedColorType, ImageEncoder, ImageError, ImageFormat, ImageReader};
use model::frame::Rgb8Image;

use super::sensor_msgs::CompressedImage;
use super::std_msgs::Header;

/// An image file format the node decodes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Codec {
    /// JPEG (baseline, extended and progressive Huffman; what the `image` crate reads).
    Jpeg,
    /// PNG.
    Png,
}

impl Codec {
    /// Its name in a `format` field (`jpeg`, `png`).
    pub fn name(self) -> &'static str {
        match self {
            Self::Jpeg => "jpeg",
            Self::Png => "png",
        }
    }

    fn image_format(self) -> ImageFormat {
        match self {
            Self::Jpeg => ImageFormat::Jpeg,
            Self::Png => ImageFormat::Png,
        }
    }
}

impl fmt::Display for Codec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// What a compressed image's header says, read before any pixel is decoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CompressedHeader {
    /// The codec of the magic bytes.
    pub codec: Codec,
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Samples per pixel as the header declares them: JPEG's component count (1 grey, 3
    /// YCbCr or RGB, 4 CMYK), PNG's from its colour type (1 grey or palette index, 2 grey
    /// and alpha, 3 RGB, 4 RGBA).
    pub channels: u8,
    /// Bits per sample (JPEG's precision, PNG's bit depth).
    pub bit_depth: u8,
}

/// The largest image decoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PixelLimits {
    /// Widest, pixels.
    pub max_width: u32,
    /// Tallest, pixels.
    pub max_height: u32,
    /// Most pixels.
    pub max_pixels: u64,
}

impl Default for PixelLimits {
    /// The node's input limits (`service::limits::InputLimits`): 4096 wide or tall, and
    /// no more pixels than 3840x2160.
    fn default() -> Self {
        Self {
            max_width: 4096,
            max_height: 4096,
            max_pixels: 3840 * 2160,
        }
    }
}

impl PixelLimits {
    /// `header`'s size is within the limits.
    pub fn check(&self, header: &CompressedHeader) -> Result<(), CompressedError> {
        let (width, height) = (header.width, header.height);
        if width > self.max_width
            || height > self.max_height
            || width as u64 * height as u64 > self.max_pixels
        {
            return Err(CompressedError::TooLarge {
                codec: header.codec,
                width,
                height,
                limits: *self,
            });
        }
        Ok(())
    }
}

/// Why a compressed image could not be read (or written).
#[derive(Debug, thiserror::Error)]
pub enum CompressedError {
    /// No data at all.
    #[error("compressed image has no data")]
    Empty,
    /// Data that starts neither as JPEG nor as PNG (its first bytes, up to 8).
    #[error("compressed image data starts with {0:02x?}: neither JPEG (ff d8 ff) nor PNG")]
    UnknownCodec(Vec<u8>),
    /// A compressed_depth_image_transport depth image (its `format`).
    #[error("compressed image format `{0}` is a depth image, not a camera picture")]
    Depth(String),
    /// The data ends before the frame header is whole.
    #[error("{codec} data ends at byte {len}, before its frame header")]
    Truncated {
        /// The codec.
        codec: Codec,
        /// Bytes present.
        len: usize,
    },
    /// The data reaches its pixels (JPEG's start of scan), or its end, without a frame
    /// header; or, for PNG, its first chunk is not IHDR.
    #[error("{codec} data has no frame header before {found}")]
    NoFrameHeader {
        /// The codec.
        codec: Codec,
        /// What came instead (`start of scan`, `end of image`, the chunk's type).
        found: String,
    },
    /// A frame header, or the marker structure before it, that no valid file has.
    #[error("{codec} header at byte {at}: {reason}")]
    BadHeader {
        /// The codec.
        codec: Codec,
        /// Where.
        at: usize,
        /// What is wrong.
        reason: &'static str,
    },
    /// A JPEG file whose marker structure does not reach its end-of-image marker: cut off,
    /// where the decoder would fill the missing rows in.
    #[error("{codec} data of {len} bytes ends before its end-of-image marker (cut off?)")]
    Unterminated {
        /// The codec.
        codec: Codec,
        /// Bytes present.
        len: usize,
    },
    /// The header declares a size beyond the limits.
    #[error("{codec} image {width}x{height} exceeds the limits ({}x{}, {} pixels)", limits.max_width, limits.max_height, limits.max_pixels)]
    TooLarge {
        /// The codec.
        codec: Codec,
        /// Columns declared.
        width: u32,
        /// Rows declared.
        height: u32,
        /// The limits.
        limits: PixelLimits,
    },
    /// The decoder refused the data (corrupt or cut-off pixels, an unsupported variant, a
    /// frame beyond the decoder's limits).
    #[error("{codec} data could not be decoded")]
    Decode {
        /// The codec.
        codec: Codec,
        /// The decoder's error.
        #[source]
        source: ImageError,
    },
    /// The decoder produced another size than the header declared.
    #[error("{codec} decoded to {decoded:?} pixels, its header declares {declared:?}")]
    SizeMismatch {
        /// The codec.
        codec: Codec,
        /// Width and height of the header.
        declared: (u32, u32),
        /// Width and height decoded.
        decoded: (u32, u32),
    },
    /// The encoder refused the image.
    #[error("{codec} encoding failed")]
    Encode {
        /// The codec.
        codec: Codec,
        /// The encoder's error.
        #[source]
        source: ImageError,
    },
}

/// The 8 bytes every PNG file starts with.
const PNG_SIGNATURE: [u8; 8] = [0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1a, b'\n'];

/// The codec and size `data` declares, read from its header alone (see the module
/// documentation); nothing is allocated.
pub fn peek_compressed(data: &[u8]) -> Result<CompressedHeader, CompressedError> {
    if data.is_empty() {
        return Err(CompressedError::Empty);
    }
    if data.starts_with(&[0xff, 0xd8, 0xff]) {
        peek_jpeg(data)
    } else if data.starts_with(&PNG_SIGNATURE) {
        peek_png(data)
    } else {
        Err(CompressedError::UnknownCodec(
            data[..data.len().min(8)].to_vec(),
        ))
    }
}

fn be16(data: &[u8], at: usize) -> Option<u16> {
    Some(u16::from_be_bytes(data.get(at..at + 2)?.try_into().ok()?))
}

fn be32(data: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_be_bytes(data.get(at..at + 4)?.try_into().ok()?))
}

/// The first frame header of a JPEG file (starting with SOI).
fn peek_jpeg(data: &[u8]) -> Result<CompressedHeader, CompressedError> {
    let codec = Codec::Jpeg;
    let truncated = || truncated(codec, data);
    let bad = |at, reason| CompressedError::BadHeader { codec, at, reason };
    let no_frame = |found: &str| CompressedError::NoFrameHeader {
        codec,
        found: found.to_owned(),
    };
    let mut at = 2;
    loop {
        match data.get(at) {
            None => return Err(truncated()),
            Some(0xff) => {}
            Some(_) => return Err(bad(at, "expected a marker")),
        }
        // Any number of 0xff fill bytes may precede the marker code.
        while data.get(at) == Some(&0xff) {
            at += 1;
        }
        let code = *data.get(at).ok_or_else(truncated)?;
        at += 1;
        match code {
            0x00 => return Err(bad(at - 1, "a stuffed zero where a marker belongs")),
            // Markers without a segment: TEM, RST0..7, SOI.
            0x01 | 0xd0..=0xd8 => continue,
            0xd9 => return Err(no_frame("end of image")),
            0xda => return Err(no_frame("start of scan")),
            _ => {}
        }
        let len = be16(data, at).ok_or_else(truncated)? as usize;
        if len < 2 {
            return Err(bad(at, "segment length below 2"));
        }
        // SOF0..SOF15, but DHT (c4), JPG (c8) and DAC (cc) share the range.
        if matches!(code, 0xc0..=0xcf) && !matches!(code, 0xc4 | 0xc8 | 0xcc) {
            if len < 8 {
                return Err(bad(at, "frame header shorter than its fields"));
            }
            // Length, precision, height, width, component count.
            let (Some(&bits), Some(height), Some(width), Some(&channels)) = (
                data.get(at + 2),
                be16(data, at + 3),
                be16(data, at + 5),
                data.get(at + 7),
            ) else {
                return Err(truncated());
            };
            if width == 0 || height == 0 {
                // Height 0 defers it to a DNL marker, which the decoder does not read.
                return Err(bad(at + 3, "zero width or height"));
            }
            return Ok(CompressedHeader {
                codec,
                width: width as u32,
                height: height as u32,
                channels,
                bit_depth: bits,
            });
        }
        at += len;
    }
}

/// The data of `codec` ends before its frame header.
fn truncated(codec: Codec, data: &[u8]) -> CompressedError {
    CompressedError::Truncated {
        codec,
        len: data.len(),
    }
}

/// The IHDR chunk of a PNG file (starting with its signature), which must be its first.
fn peek_png(data: &[u8]) -> Result<CompressedHeader, CompressedError> {
    let codec = Codec::Png;
    let (Some(len), Some(kind)) = (be32(data, 8), data.get(12..16)) else {
        return Err(truncated(codec, data));
    };
    if kind != b"IHDR" {
        return Err(CompressedError::NoFrameHeader {
            codec,
            found: format!("chunk {}", String::from_utf8_lossy(kind)),
        });
    }
    let (Some(width), Some(height), Some(&bits), Some(&colour)) =
        (be32(data, 16), be32(data, 20), data.get(24), data.get(25))
    else {
        return Err(truncated(codec, data));
    };
    let bad = |at, reason| CompressedError::BadHeader { codec, at, reason };
    if len != 13 {
        return Err(bad(8, "IHDR length is not 13"));
    }
    if width == 0 || height == 0 {
        return Err(bad(16, "zero width or height"));
    }
    let channels = match colour {
        0 | 3 => 1,
        4 => 2,
        2 => 3,
        6 => 4,
        _ => return Err(bad(25, "unknown colour type")),
    };
    Ok(CompressedHeader {
        codec,
        width,
        height,
        channels,
        bit_depth: bits,
    })
}

/// The pixels of a JPEG or PNG compressed image as packed RGB8 (see the module
/// documentation): its header's size checked against `limits` before decoding, then the
/// decoder bounded by the same size. Empty, unknown, cut-off (for JPEG: ending before its
/// end-of-image marker, which the decoder alone would accept, filling the rows in) or
/// corrupt data, and a size beyond the limits, are errors; none panics.
pub fn rgb8_from_compressed(
    msg: &CompressedImage,
    limits: &PixelLimits,
) -> Result<Rgb8Image, CompressedError> {
    if msg.format.contains("compressedDepth") {
        return Err(CompressedError::Depth(msg.format.clone()));
    }
    let header = peek_compressed(&msg.data)?;
    limits.check(&header)?;
    let codec = header.codec;
    if codec == Codec::Jpeg && !reaches_eoi(&msg.data) {
        return Err(CompressedError::Unterminated {
            codec,
            len: msg.data.len(),
        });
    }
    let decode = |source| CompressedError::Decode { codec, source };
    let mut reader = ImageReader::with_format(Cursor::new(&msg.data[..]), codec.image_format());
    let mut bounds = image::Limits::default();
    bounds.max_image_width = Some(header.width);
    bounds.max_image_height = Some(header.height);
    // The largest output (16-bit RGBA) of the declared size, and room for the decoder's
    // own buffers: proportional to the size checked, not to anything else in the file.
    bounds.max_alloc = Some(16 * header.width as u64 * header.height as u64 + (4 << 20));
    reader.limits(bounds);
    let decoded = reader.decode().map_err(decode)?;
    let size = (decoded.width(), decoded.height());
    if size != (header.width, header.height) {
        return Err(CompressedError::SizeMismatch {
            codec,
            declared: (header.width, header.height),
            decoded: size,
        });
    }
    let rgb = decoded.into_rgb8();
    Ok(Rgb8Image {
        width: size.0,
        height: size.1,
        data: rgb.into_raw(),
    })
}

/// Whether the marker structure of JPEG `data` reaches its end-of-image marker (EOI):
/// segments skipped by their lengths, the entropy-coded data after each start of scan read
/// up to the next marker (in it a byte `FF` is followed by `00`, or by `D0..D7` for a
/// restart). A file cut off anywhere before EOI does not; what follows EOI (the zero
/// padding some cameras add) does not matter. Allocates nothing.
fn reaches_eoi(data: &[u8]) -> bool {
    let mut at = 2;
    while let Some(&[marker, code]) = data.get(at..at + 2) {
        if marker != 0xff {
            return false;
        }
        match code {
            0xd9 => return true,
            // Fill bytes before a marker, and markers without a segment.
            0xff => {
                at += 1;
                continue;
            }
            0x01 | 0xd0..=0xd8 => {
                at += 2;
                continue;
            }
            _ => {}
        }
        let Some(len) = be16(data, at + 2) else {
            return false;
        };
        at += 2 + len as usize;
        if code == 0xda {
            while let Some(&[byte, next]) = data.get(at..at + 2) {
                if byte == 0xff && next != 0 && !(0xd0..=0xd7).contains(&next) {
                    break;
                }
                at += 1;
            }
        }
    }
    false
}

/// How [`compressed_image`] encodes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Compression {
    /// JPEG of this quality (1..=100; compressed_image_transport's default is 95).
    Jpeg {
        /// Quality, 1 (smallest) to 100.
        quality: u8,
    },
    /// PNG (lossless).
    Png,
}

/// A compressed image message of `img` (`3 * width * height` bytes) as compressed_image_transport
/// publishes a colour `rgb8` image: format `rgb8; jpeg compressed bgr8` or
/// `rgb8; png compressed bgr8`, the file holding the RGB picture.
pub fn compressed_image(
    img: &Rgb8Image,
    compression: Compression,
    header: Header,
) -> Result<CompressedImage, CompressedError> {
    let mut data = Vec::new();
    let (codec, result) = match compression {
        Compression::Jpeg { quality } => (
            Codec::Jpeg,
            JpegEncoder::new_with_quality(&mut data, quality.clamp(1, 100)).write_image(
                &img.data,
                img.width,
                img.height,
                ExtendedColorType::Rgb8,
            ),
        ),
        Compression::Png => (
            Codec::Png,
            PngEncoder::new(&mut data).write_image(
                &img.data,
                img.width,
                img.height,
                ExtendedColorType::Rgb8,
            ),
        ),
    };
    result.map_err(|source| CompressedError::Encode { codec, source })?;
    Ok(CompressedImage {
        header,
        format: format!("rgb8; {codec} compressed bgr8"),
        data,
    })
}

#[cfg(test)]
#[path = "compressed_tests.rs"]
mod tests;
