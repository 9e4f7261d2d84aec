//! Peak signal-to-noise ratio of two RGB images in [0, 1].

use super::{check_pair, MetricError};
use crate::frame::RgbImage;

/// PSNR in dB, `10 log10(1 / MSE)` with the MSE taken over all pixels and all three
/// channels in f64: scikit-image's `peak_signal_noise_ratio(a, b, data_range=1.0)`.
///
/// Identical images have MSE 0 and give `f64::INFINITY` (as NumPy's `10 * log10(1 / 0)`
/// does); callers averaging PSNR over frames should decide how to treat that case.
/// Errors: different sizes, a malformed buffer, a non-finite value, or an empty image.
pub fn psnr(a: &RgbImage, b: &RgbImage) -> Result<f64, MetricError> {
    check_pair(a, b)?;
    let sum: f64 = a
        .data
        .iter()
        .zip(&b.data)
        .map(|(&x, &y)| {
            let d = x as f64 - y as f64;
            d * d
        })
        .sum();
    let mse = sum / a.data.len() as f64;
    Ok(10.0 * (1.0 / mse).log10())
}

/// PSNR in dB over the pixels where `mask` (row major, one entry per pixel) is true, MSE over
/// their three channels in f64. Errors as [`psnr`], plus a mask of the wrong length or
/// selecting no pixel ([`MetricError::Empty`]).
pub fn psnr_masked(a: &RgbImage, b: &RgbImage, mask: &[bool]) -> Result<f64, MetricError> {
    check_pair(a, b)?;
    if mask.len() * 3 != a.data.len() {
        return Err(MetricError::BadLength {
            input: "mask",
            expected: a.data.len() / 3,
            actual: mask.len(),
        });
    }
    let (sum, n) = a
        .data
        .chunks_exact(3)
        .zip(b.data.chunks_exact(3))
        .zip(mask)
        .filter(|(_, &m)| m)
        .fold((0.0f64, 0usize), |(sum, n), ((x, y), _)| {
            let d: f64 = x
                .iter()
                .zip(y)
                .map(|(&x, &y)| (x as f64 - y as f64).powi(2))
                .sum();
            (sum + d, n + 3)
        });
    if n == 0 {
        return Err(MetricError::Empty);
    }
    Ok(10.0 * (1.0 / (sum / n as f64)).log10())
}
