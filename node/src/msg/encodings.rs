//! The pixel encodings of `sensor_msgs/Image` the node reads and writes, by their names in
//! ROS 2's `sensor_msgs/image_encodings.hpp`: checking a message's step and data against
//! its encoding, and converting its rows to and from packed RGB bytes.
//!
//! * `rgb8`, `bgr8`, `rgba8`, `bgra8`: 8-bit colour, alpha dropped on reading (written 255).
//! * `mono8`: 8-bit grey, copied to the three channels; written as the BT.601 luma of the
//!   RGB (`(299 R + 587 G + 114 B) / 1000`, rounded, as OpenCV's `RGB2GRAY` weighs them).
//! * `mono16`, `rgb16`: 16-bit grey and colour, in the byte order `is_bigendian` names. Each
//!   value `v` becomes the byte `v >> 8` (its high byte: the usual reduction, as
//!   `cv_bridge`'s 16-to-8-bit conversion truncates), and each byte `b` is written as
//!   `b * 257`, so 8-bit content round-trips exactly.
//! * `bayer_rggb8`, `bayer_bggr8`, `bayer_gbrg8`, `bayer_grbg8`: one 8-bit sample per pixel
//!   behind a colour filter array, demosaiced bilinearly ([`super::demosaic`]).
//!
//! Any other encoding is [`ConvertError::UnsupportedEncoding`].

use model::frame::Rgb8Image;

use super::demosaic::{self, BayerPattern};
use super::sensor_msgs::Image;
use super::ConvertError;

/// One encoding of `sensor_msgs/Image` this module reads and writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Encoding {
    /// `rgb8`: red, green, blue bytes.
    Rgb8,
    /// `bgr8`: blue, green, red bytes (OpenCV's order).
    Bgr8,
    /// `rgba8`: red, green, blue, alpha bytes.
    Rgba8,
    /// `bgra8`: blue, green, red, alpha bytes.
    Bgra8,
    /// `mono8`: one grey byte.
    Mono8,
    /// `mono16`: one 16-bit grey value.
    Mono16,
    /// `rgb16`: red, green, blue 16-bit values.
    Rgb16,
    /// `bayer_*8`: one byte per pixel behind the colour filter `pattern`.
    Bayer(BayerPattern),
}

impl Encoding {
    /// Every encoding read, in the order [`ConvertError::UnsupportedEncoding`] lists them.
    pub const ALL: [Encoding; 11] = [
        Self::Rgb8,
        Self::Bgr8,
        Self::Rgba8,
        Self::Bgra8,
        Self::Mono8,
        Self::Mono16,
        Self::Rgb16,
        Self::Bayer(BayerPattern::Rggb),
        Self::Bayer(BayerPattern::Bggr),
        Self::Bayer(BayerPattern::Gbrg),
        Self::Bayer(BayerPattern::Grbg),
    ];

    /// The encoding named `name` (exactly as `image_encodings.hpp` spells it), if read.
    pub fn parse(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|e| e.name() == name)
    }

    /// Its name in the message's `encoding` field.
    pub fn name(self) -> &'static str {
        match self {
            Self::Rgb8 => "rgb8",
            Self::Bgr8 => "bgr8",
            Self::Rgba8 => "rgba8",
            Self::Bgra8 => "bgra8",
            Self::Mono8 => "mono8",
            Self::Mono16 => "mono16",
            Self::Rgb16 => "rgb16",
            Self::Bayer(BayerPattern::Rggb) => "bayer_rggb8",
            Self::Bayer(BayerPattern::Bggr) => "bayer_bggr8",
            Self::Bayer(BayerPattern::Gbrg) => "bayer_gbrg8",
            Self::Bayer(BayerPattern::Grbg) => "bayer_grbg8",
        }
    }

    /// Bytes one pixel takes in a row.
    pub fn bytes_per_pixel(self) -> u32 {
        match self {
            Self::Mono8 | Self::Bayer(_) => 1,
            Self::Mono16 => 2,
            Self::Rgb8 | Self::Bgr8 => 3,
            Self::Rgba8 | Self::Bgra8 => 4,
            Self::Rgb16 => 6,
        }
    }

    /// The encoding of a message after checking that its step holds a row and its data is
    /// `step * height` bytes (and, for Bayer, that it has at least 2x2 pixels or none).
    pub fn of(msg: &Image) -> Result<Self, ConvertError> {
        let encoding = Self::parse(&msg.encoding)
            .ok_or_else(|| ConvertError::UnsupportedEncoding(msg.encoding.clone()))?;
        let min_step = msg.width as u64 * encoding.bytes_per_pixel() as u64;
        if (msg.step as u64) < min_step
            || msg.data.len() as u64 != msg.step as u64 * msg.height as u64
        {
            return Err(ConvertError::ImageSize {
                width: msg.width,
                height: msg.height,
                encoding: msg.encoding.clone(),
                step: msg.step,
                min_step,
                len: msg.data.len(),
            });
        }
        if let Self::Bayer(_) = encoding {
            demosaic::check_size(msg.width, msg.height)?;
        }
        Ok(encoding)
    }
}

/// The pixels of a message checked by [`Encoding::of`] as packed RGB bytes. The output is
/// `3 * width * height` bytes, at most three times the data checked.
pub fn packed_rgb(msg: &Image, encoding: Encoding) -> Vec<u8> {
    // The high byte of a 16-bit value: the second of a little-endian pair.
    let hi = usize::from(msg.is_bigendian == 0);
    match encoding {
        Encoding::Bayer(pattern) => demosaic::bilinear(
            &msg.data,
            msg.width as usize,
            msg.height as usize,
            msg.step as usize,
            pattern,
        ),
        Encoding::Rgb8 => rows(msg, encoding, |px, rgb| rgb.copy_from_slice(px)),
        Encoding::Bgr8 | Encoding::Bgra8 => rows(msg, encoding, |px, rgb| {
            rgb.copy_from_slice(&[px[2], px[1], px[0]])
        }),
        Encoding::Rgba8 => rows(msg, encoding, |px, rgb| rgb.copy_from_slice(&px[..3])),
        Encoding::Mono8 => rows(msg, encoding, |px, rgb| rgb.fill(px[0])),
        Encoding::Mono16 => rows(msg, encoding, |px, rgb| rgb.fill(px[hi])),
        Encoding::Rgb16 => rows(msg, encoding, |px, rgb| {
            rgb.copy_from_slice(&[px[hi], px[2 + hi], px[4 + hi]])
        }),
    }
}

/// Packed RGB made pixel by pixel: `f` writes the RGB of one pixel's bytes, for a message
/// checked by [`Encoding::of`] (row padding skipped).
fn rows(msg: &Image, encoding: Encoding, f: impl Fn(&[u8], &mut [u8])) -> Vec<u8> {
    let (width, height) = (msg.width as usize, msg.height as usize);
    let bpp = encoding.bytes_per_pixel() as usize;
    let mut rgb = vec![0; 3 * width * height];
    if width == 0 {
        return rgb;
    }
    // `step >= width * bpp` and `data = step * height` are checked, so every row is whole.
    let src = msg.data.chunks_exact(msg.step.max(1) as usize);
    for (row, out) in src.zip(rgb.chunks_exact_mut(3 * width)) {
        for (px, dst) in row[..width * bpp]
            .chunks_exact(bpp)
            .zip(out.chunks_exact_mut(3))
        {
            f(px, dst);
        }
    }
    rgb
}

/// The rows of `img` in `encoding`, packed (`step = width * bytes_per_pixel`), 16-bit
/// values little endian; `img.data` must be `3 * width * height` bytes.
pub fn encode_rows(img: &Rgb8Image, encoding: Encoding) -> Vec<u8> {
    let n = img.width as usize * img.height as usize * encoding.bytes_per_pixel() as usize;
    let each = |f: &dyn Fn(&[u8], &mut Vec<u8>)| {
        let mut out = Vec::with_capacity(n);
        img.data.chunks_exact(3).for_each(|p| f(p, &mut out));
        out
    };
    match encoding {
        Encoding::Rgb8 => img.data.clone(),
        Encoding::Bgr8 => each(&|p, out| out.extend([p[2], p[1], p[0]])),
        Encoding::Rgba8 => each(&|p, out| out.extend([p[0], p[1], p[2], 255])),
        Encoding::Bgra8 => each(&|p, out| out.extend([p[2], p[1], p[0], 255])),
        Encoding::Mono8 => each(&|p, out| out.push(luma(p))),
        Encoding::Mono16 => each(&|p, out| out.extend(widen(luma(p)))),
        Encoding::Rgb16 => each(&|p, out| p.iter().for_each(|&v| out.extend(widen(v)))),
        Encoding::Bayer(pattern) => demosaic::mosaic(img, pattern),
    }
}

/// The BT.601 luma of an RGB pixel, rounded.
fn luma(p: &[u8]) -> u8 {
    ((299 * p[0] as u32 + 587 * p[1] as u32 + 114 * p[2] as u32 + 500) / 1000) as u8
}

/// A byte as the 16-bit value of the same brightness (`b * 257`), little endian.
fn widen(b: u8) -> [u8; 2] {
    (b as u16 * 257).to_le_bytes()
}
