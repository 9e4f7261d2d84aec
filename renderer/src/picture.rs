//! Renders as PNG pictures, for looking at results and for tests to compare: colour as it is,
//! depth through a colour map, alpha and confidence as grey.
//!
//! Colour is written without gamma: the linear values are clamped to [0, 1] and rounded to
//! 8 bits, so the picture shows the numbers the rasterizer produced (it looks darker than a
//! gamma-encoded photograph of the same scene). NaN is drawn black; +inf saturates to 255.
//!
//! Depth is drawn with a viridis-like map (dark purple, teal, yellow; luminance rises
//! monotonically), near bright and far dark, over a range chosen by [`DepthScale`]. Pixels
//! without a valid depth (alpha at most [`DEPTH_MIN_ALPHA`], depth not finite or not
//! positive) are black, which the map never produces.
//!
//! Files are replaced atomically ([`crate::atomic`]): a crash mid-write keeps the old picture.

use std::path::Path;

use image::{ExtendedColorType, ImageFormat};

use crate::output::RenderOutput;

/// Pixels whose accumulated alpha is at most this have no depth worth drawing (the depth is
/// then a ratio of two tiny sums, or the 0 the rasterizer writes); they are drawn black.
pub const DEPTH_MIN_ALPHA: f32 = 1e-3;

/// The percentiles of valid depths that [`DepthScale::Auto`] maps to the ends of the colour
/// map, so a few stray pixels (a sliver of sky, a floater at the lens) do not flatten the
/// rest of the picture.
pub const AUTO_PERCENTILES: (f64, f64) = (0.02, 0.98);

/// How depth values are mapped onto the colour map.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum DepthScale {
    /// Near and far from the valid pixels' 2nd and 98th percentiles ([`AUTO_PERCENTILES`]).
    #[default]
    Auto,
    /// Fixed near (`min`) and far (`max`) depths, e.g. to compare frames on one scale;
    /// depths outside are clamped to the ends.
    Range {
        /// Depth drawn brightest (and everything nearer).
        min: f32,
        /// Depth drawn darkest (and everything farther).
        max: f32,
    },
}

/// Everything that can go wrong turning a render into a picture.
#[derive(Debug, thiserror::Error)]
pub enum PictureError {
    /// A channel's length does not match the output's `width * height`.
    #[error("render output `{channel}` has {got} values, {expected} expected")]
    SizeMismatch {
        /// The channel: `rgb`, `depth`, `alpha` or `confidence`.
        channel: &'static str,
        /// `width * height` times the channel's components.
        expected: usize,
        /// Its actual length.
        got: usize,
    },
    /// A [`DepthScale::Range`] that is not finite or has `min >= max`.
    #[error("depth range [{min}, {max}] is empty or not finite")]
    BadRange {
        /// Its near end.
        min: f32,
        /// Its far end.
        max: f32,
    },
    /// The PNG encoder or the file failed (an empty image is refused by the encoder too).
    #[error("writing the PNG failed: {0}")]
    Encode(#[from] image::ImageError),
}

fn check(
    out: &RenderOutput,
    channel: &'static str,
    got: usize,
    per_pixel: usize,
) -> Result<(), PictureError> {
    let expected = out.pixels() * per_pixel;
    match got == expected {
        true => Ok(()),
        false => Err(PictureError::SizeMismatch {
            channel,
            expected,
            got,
        }),
    }
}

/// A value in [0, 1] as 8 bits: clamped, then rounded (`0.5 / 255` and up round up). NaN
/// gives 0, so invalid values show black.
pub fn unit_to_u8(v: f32) -> u8 {
    if v.is_nan() {
        0
    } else {
        (v.clamp(0.0, 1.0) * 255.0).round() as u8
    }
}

/// The colour image as interleaved 8-bit RGB, row major: linear values clamped to [0, 1],
/// no gamma, rounded (see [`unit_to_u8`]).
pub fn to_rgb8(out: &RenderOutput) -> Result<Vec<u8>, PictureError> {
    check(out, "rgb", out.rgb.len(), 3)?;
    Ok(out.rgb.iter().map(|&v| unit_to_u8(v)).collect())
}

/// Alpha as 8-bit grey, one byte per pixel (clamped to [0, 1], NaN black).
pub fn alpha_to_gray8(out: &RenderOutput) -> Result<Vec<u8>, PictureError> {
    check(out, "alpha", out.alpha.len(), 1)?;
    Ok(out.alpha.iter().map(|&v| unit_to_u8(v)).collect())
}

/// Confidence as 8-bit grey, one byte per pixel (clamped to [0, 1], NaN black).
pub fn confidence_to_gray8(out: &RenderOutput) -> Result<Vec<u8>, PictureError> {
    check(out, "confidence", out.confidence.len(), 1)?;
    Ok(out.confidence.iter().map(|&v| unit_to_u8(v)).collect())
}

/// The valid depth at pixel `i`, if any: alpha above [`DEPTH_MIN_ALPHA`] (NaN is not), depth
/// finite and positive.
fn valid_depth(out: &RenderOutput, i: usize) -> Option<f32> {
    let d = out.depth[i];
    (out.alpha[i] > DEPTH_MIN_ALPHA && d.is_finite() && d > 0.0).then_some(d)
}

/// The near and far depths [`DepthScale::Auto`] uses: the [`AUTO_PERCENTILES`] of the valid
/// pixels' depths (nearest rank), or `None` when no pixel is valid. Exposed so callers can
/// fix one frame's scale for a sequence.
pub fn auto_depth_range(out: &RenderOutput) -> Result<Option<(f32, f32)>, PictureError> {
    check(out, "depth", out.depth.len(), 1)?;
    check(out, "alpha", out.alpha.len(), 1)?;
    let mut depths: Vec<f32> = (0..out.pixels())
        .filter_map(|i| valid_depth(out, i))
        .collect();
    if depths.is_empty() {
        return Ok(None);
    }
    let last = (depths.len() - 1) as f64;
    let mut at = |p: f64| {
        *depths
            .select_nth_unstable_by((last * p).round() as usize, f32::total_cmp)
            .1
    };
    let near = at(AUTO_PERCENTILES.0);
    let far = at(AUTO_PERCENTILES.1);
    Ok(Some((near, far)))
}

/// Depth through the colour map as interleaved 8-bit RGB, row major: near bright, far dark,
/// invalid pixels black (see the module documentation). When the auto range is a single
/// depth, every valid pixel takes the map's middle colour.
pub fn depth_to_rgb8(out: &RenderOutput, scale: DepthScale) -> Result<Vec<u8>, PictureError> {
    let range = match scale {
        DepthScale::Auto => auto_depth_range(out)?,
        DepthScale::Range { min, max } => {
            if !(min.is_finite() && max.is_finite() && min < max) {
                return Err(PictureError::BadRange { min, max });
            }
            check(out, "depth", out.depth.len(), 1)?;
            check(out, "alpha", out.alpha.len(), 1)?;
            Some((min, max))
        }
    };
    let mut rgb = vec![0u8; 3 * out.pixels()];
    let Some((near, far)) = range else {
        return Ok(rgb);
    };
    for (i, px) in rgb.chunks_exact_mut(3).enumerate() {
        if let Some(d) = valid_depth(out, i) {
            let t = match far > near {
                true => (far - d) / (far - near),
                false => 0.5,
            };
            px.copy_from_slice(&viridis(t));
        }
    }
    Ok(rgb)
}

/// Colour-map anchors at t = 0, 1/8, ..., 1: an approximation of matplotlib's viridis,
/// display (sRGB-encoded) values. Rec. 709 luminance rises at every step (0.08 to 0.87), so
/// the piecewise-linear map between them is monotonic in luminance too.
const MAP: [[f32; 3]; 9] = [
    [0.267, 0.005, 0.329],
    [0.283, 0.141, 0.458],
    [0.230, 0.322, 0.546],
    [0.173, 0.449, 0.558],
    [0.128, 0.567, 0.551],
    [0.135, 0.659, 0.518],
    [0.369, 0.789, 0.383],
    [0.678, 0.864, 0.190],
    [0.993, 0.906, 0.144],
];

/// The viridis-like colour at `t` (clamped to [0, 1]; 0 dark purple, 1 yellow) as 8-bit
/// RGB, interpolated linearly between the map's anchors. NaN gives black.
pub fn viridis(t: f32) -> [u8; 3] {
    if t.is_nan() {
        return [0; 3];
    }
    let x = t.clamp(0.0, 1.0) * (MAP.len() - 1) as f32;
    let k = (x as usize).min(MAP.len() - 2);
    let f = x - k as f32;
    let (a, b) = (MAP[k], MAP[k + 1]);
    [0, 1, 2].map(|c| unit_to_u8(a[c] + (b[c] - a[c]) * f))
}

fn save(
    path: &Path,
    buf: &[u8],
    out: &RenderOutput,
    color: ExtendedColorType,
) -> Result<(), PictureError> {
    crate::atomic::write_atomic(path, |w| {
        image::write_buffer_with_format(w, buf, out.width, out.height, color, ImageFormat::Png)
    })?;
    Ok(())
}

/// Writes the colour image to `path` as an 8-bit RGB PNG ([`to_rgb8`]: clamped, no gamma).
pub fn save_rgb_png(out: &RenderOutput, path: impl AsRef<Path>) -> Result<(), PictureError> {
    save(path.as_ref(), &to_rgb8(out)?, out, ExtendedColorType::Rgb8)
}

/// Writes depth to `path` as an 8-bit RGB PNG through the colour map ([`depth_to_rgb8`]).
pub fn save_depth_png(
    out: &RenderOutput,
    path: impl AsRef<Path>,
    scale: DepthScale,
) -> Result<(), PictureError> {
    save(
        path.as_ref(),
        &depth_to_rgb8(out, scale)?,
        out,
        ExtendedColorType::Rgb8,
    )
}

/// Writes alpha to `path` as an 8-bit greyscale PNG ([`alpha_to_gray8`]).
pub fn save_alpha_png(out: &RenderOutput, path: impl AsRef<Path>) -> Result<(), PictureError> {
    save(
        path.as_ref(),
        &alpha_to_gray8(out)?,
        out,
        ExtendedColorType::L8,
    )
}

/// Writes confidence to `path` as an 8-bit greyscale PNG ([`confidence_to_gray8`]).
pub fn save_confidence_png(out: &RenderOutput, path: impl AsRef<Path>) -> Result<(), PictureError> {
    save(
        path.as_ref(),
        &confidence_to_gray8(out)?,
        out,
        ExtendedColorType::L8,
    )
}
