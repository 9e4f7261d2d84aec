//! Image and depth quality metrics for the evaluation protocol (paper section 4): PSNR and
//! SSIM on RGB exactly as scikit-image computes them in the feed-forward 3DGS papers, AbsRel,
//! SqRel and RMSE of depth against sparse LiDAR-like ground truth, and a per-pixel error map
//! for the evaluation pictures.
//!
//! Every function checks its inputs (matching sizes, buffer lengths, finite values) and
//! returns a [`MetricError`] instead of panicking, so a broken render is reported, not fatal.

mod depth;
mod error_map;
mod psnr;
mod ssim;

pub use depth::{depth_errors, DepthErrors, DepthFilter};
pub use error_map::error_map;
pub use psnr::{psnr, psnr_masked};
pub use ssim::{ssim, ssim_map, SsimMap, SSIM_WINDOW};

use crate::frame::RgbImage;

/// Why a metric could not be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MetricError {
    /// The two inputs do not have the same width and height.
    #[error("size mismatch: {a_width}x{a_height} vs {b_width}x{b_height}")]
    SizeMismatch {
        /// Width of the first input.
        a_width: u32,
        /// Height of the first input.
        a_height: u32,
        /// Width of the second input.
        b_width: u32,
        /// Height of the second input.
        b_height: u32,
    },
    /// An input's buffer does not hold `channels * width * height` values.
    #[error("{input}: buffer holds {actual} values, its size needs {expected}")]
    BadLength {
        /// Which input (`"a"`, `"b"`, `"pred"`, `"gt"`, `"map"`).
        input: &'static str,
        /// Values the width and height call for.
        expected: usize,
        /// Values the buffer holds.
        actual: usize,
    },
    /// An image holds a NaN or an infinity.
    #[error("{input}: non-finite value at pixel ({x}, {y})")]
    NonFinite {
        /// Which input (`"a"` or `"b"`).
        input: &'static str,
        /// Column of the offending pixel.
        x: u32,
        /// Row of the offending pixel.
        y: u32,
    },
    /// The images have no pixels.
    #[error("empty image (0 pixels)")]
    Empty,
    /// The images are smaller than the SSIM window in some direction.
    #[error("image {width}x{height} is smaller than the {window}x{window} SSIM window")]
    TooSmall {
        /// Image width.
        width: u32,
        /// Image height.
        height: u32,
        /// Side of the SSIM window.
        window: u32,
    },
    /// No ground-truth depth passed the validity filter.
    #[error("no valid ground-truth depth pixel")]
    NoValidPixels,
    /// The depth filter's range is not `0 < min_depth < max_depth`, both finite.
    #[error("invalid depth range [{min_depth}, {max_depth}]: need 0 < min < max, finite")]
    InvalidFilter {
        /// The filter's minimum depth.
        min_depth: f32,
        /// The filter's maximum depth.
        max_depth: f32,
    },
}

/// Checks that a buffer of `actual` values holds `channels * width * height` of them.
fn check_length(
    input: &'static str,
    width: u32,
    height: u32,
    channels: usize,
    actual: usize,
) -> Result<(), MetricError> {
    let expected = channels * width as usize * height as usize;
    if actual == expected {
        Ok(())
    } else {
        Err(MetricError::BadLength {
            input,
            expected,
            actual,
        })
    }
}

/// Checks that two sizes agree.
fn check_same_size(a: (u32, u32), b: (u32, u32)) -> Result<(), MetricError> {
    if a == b {
        Ok(())
    } else {
        Err(MetricError::SizeMismatch {
            a_width: a.0,
            a_height: a.1,
            b_width: b.0,
            b_height: b.1,
        })
    }
}

/// Checks that one image's buffer fits its size and holds only finite values.
fn check_image(input: &'static str, image: &RgbImage) -> Result<(), MetricError> {
    check_length(input, image.width, image.height, 3, image.data.len())?;
    // A branch-free scan first (it vectorizes); the position only when something is wrong.
    if image.data.iter().fold(true, |ok, v| ok & v.is_finite()) {
        return Ok(());
    }
    match image.data.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(i) => {
            let pixel = i / 3;
            let width = image.width as usize;
            Err(MetricError::NonFinite {
                input,
                x: (pixel % width) as u32,
                y: (pixel / width) as u32,
            })
        }
    }
}

/// The checks every image-pair metric starts with: equal sizes, well-formed buffers, finite
/// values and at least one pixel.
fn check_pair(a: &RgbImage, b: &RgbImage) -> Result<(), MetricError> {
    check_same_size((a.width, a.height), (b.width, b.height))?;
    check_image("a", a)?;
    check_image("b", b)?;
    if a.data.is_empty() {
        return Err(MetricError::Empty);
    }
    Ok(())
}
