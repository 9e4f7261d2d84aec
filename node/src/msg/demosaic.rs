//! Bayer colour filter arrays: the four 2x2 patterns of `image_encodings.hpp`, bilinear
//! demosaicing of one-sample-per-pixel images into RGB, and the reverse (mosaicking an RGB
//! image, for tests and the project's players).
//!
//! Demosaicing is bilinear: at each pixel the channel its filter passes is kept, and each
//! missing channel is the mean of the nearest samples of it (two or four, rounded). Edges
//! reflect about the border pixel (`x = -1` reads `x = 1`), which keeps the pattern's
//! parity, so odd widths and heights need no special case. An image needs at least 2x2
//! pixels for every channel to have a sample to reflect; a Bayer image 1 pixel wide or
//! tall is [`ConvertError::BayerTooSmall`] (one with no pixel is an empty image).

use model::frame::Rgb8Image;

use super::ConvertError;

/// Which filter covers the top-left 2x2 block, read row by row (`Rggb`: red, green on the
/// first row; green, blue on the second).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BayerPattern {
    /// `bayer_rggb8`.
    Rggb,
    /// `bayer_bggr8`.
    Bggr,
    /// `bayer_gbrg8`.
    Gbrg,
    /// `bayer_grbg8`.
    Grbg,
}

impl BayerPattern {
    /// The channel (0 red, 1 green, 2 blue) the filter at column `x`, row `y` passes.
    pub fn channel(self, x: usize, y: usize) -> usize {
        let block = match self {
            Self::Rggb => [0, 1, 1, 2],
            Self::Bggr => [2, 1, 1, 0],
            Self::Gbrg => [1, 2, 0, 1],
            Self::Grbg => [1, 0, 2, 1],
        };
        block[(y & 1) * 2 + (x & 1)]
    }
}

/// A Bayer image of `width` x `height` can be demosaiced: both at least 2, or no pixel.
pub fn check_size(width: u32, height: u32) -> Result<(), ConvertError> {
    match width == 0 || height == 0 || (width >= 2 && height >= 2) {
        true => Ok(()),
        false => Err(ConvertError::BayerTooSmall { width, height }),
    }
}

/// The RGB bytes (`3 * width * height`) of the Bayer samples in `data`, rows `step` bytes
/// apart; `data` holds `step * height` bytes with `step >= width`, and the size passed
/// [`check_size`].
pub fn bilinear(
    data: &[u8],
    width: usize,
    height: usize,
    step: usize,
    pattern: BayerPattern,
) -> Vec<u8> {
    let mut rgb = vec![0u8; 3 * width * height];
    if width < 2 || height < 2 {
        return rgb;
    }
    let row = |y: usize| &data[y * step..y * step + width];
    let reflect = |i: usize, n: usize, delta: isize| match i.checked_add_signed(delta) {
        Some(j) if j < n => j,
        // Past either end: the pixel as far inside (-1 -> 1, n -> n - 2).
        _ => i.wrapping_add_signed(-delta),
    };
    for (y, out) in rgb.chunks_exact_mut(3 * width).enumerate() {
        let (up, mid, down) = (
            row(reflect(y, height, -1)),
            row(y),
            row(reflect(y, height, 1)),
        );
        for (x, px) in out.chunks_exact_mut(3).enumerate() {
            let (l, r) = (reflect(x, width, -1), reflect(x, width, 1));
            let own = pattern.channel(x, y);
            px[own] = mid[x];
            if own == 1 {
                // Green: the row's other colour left and right, the other one above and below.
                let across = pattern.channel(x ^ 1, y);
                px[across] = mean2(mid[l], mid[r]);
                px[2 - across] = mean2(up[x], down[x]);
            } else {
                px[1] = mean4(up[x], down[x], mid[l], mid[r]);
                px[2 - own] = mean4(up[l], up[r], down[l], down[r]);
            }
        }
    }
    rgb
}

/// The Bayer samples of `img` behind `pattern` (each pixel's filtered channel), rows packed.
pub fn mosaic(img: &Rgb8Image, pattern: BayerPattern) -> Vec<u8> {
    let width = img.width as usize;
    img.data
        .chunks_exact(3)
        .enumerate()
        .map(|(i, p)| p[pattern.channel(i % width, i / width)])
        .collect()
}

/// The mean of two samples, halves rounded up.
fn mean2(a: u8, b: u8) -> u8 {
    (a as u16 + b as u16).div_ceil(2) as u8
}

/// The mean of four samples, rounded half up.
fn mean4(a: u8, b: u8, c: u8, d: u8) -> u8 {
    ((a as u16 + b as u16 + c as u16 + d as u16 + 2) / 4) as u8
}
