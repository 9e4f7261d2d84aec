//! Per-pixel error of a render against its ground truth, for the evaluation pictures.

use super::{check_pair, MetricError};
use crate::frame::RgbImage;

/// The mean absolute RGB error at every pixel, `(|ar-br| + |ag-bg| + |ab-bb|) / 3`, row
/// major (`width * height` values, in [0, 1] for images in [0, 1]); colour it with a
/// colour map to show where a render goes wrong.
/// Errors: different sizes, a malformed buffer, a non-finite value, or an empty image.
pub fn error_map(a: &RgbImage, b: &RgbImage) -> Result<Vec<f32>, MetricError> {
    check_pair(a, b)?;
    Ok(a.data
        .chunks_exact(3)
        .zip(b.data.chunks_exact(3))
        .map(|(p, q)| {
            let sum: f32 = p.iter().zip(q).map(|(x, y)| (x - y).abs()).sum();
            sum / 3.0
        })
        .collect())
}
