//! Photometric consistency, a score for pairs without ground truth: the right image warped
//! into the left camera by the predicted depth, against the left image. A left pixel (x, y)
//! with depth z sees the point the right camera sees at x - fx * B / z on the same row
//! (rectified); its error is the mean over the three channels of |left - right| there
//! (bilinear in x), in [0, 1].
//!
//! A pixel is scored when it has depth, its match lies inside the right image, and it is
//! not occluded in the right view: no left pixel to its right on the same row lands at or
//! left of its match (a nearer surface would cover it there). Scores: the mean error over
//! scored pixels and the fraction of left pixels scored; methods are compared on the pixels
//! every one of them scores (`scripts/real_pairs.sh`).

use model::frame::{DepthMap, RgbImage};
use serde::Serialize;

use super::Calibration;

/// Photometric consistency of one prediction.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Photometric {
    /// Mean absolute error over scored pixels, [0, 1]; `None` when no pixel is scored.
    pub mae: Option<f64>,
    /// Fraction of left pixels scored, [0, 1].
    pub scored_fraction: f64,
    /// Per-pixel error at the input size, row major; NaN where not scored.
    #[serde(skip)]
    pub errors: Vec<f32>,
}

/// Where each pixel of one row matches in the right image (NaN without depth).
fn row_matches(depth: &[f32], fb: f32) -> Vec<f32> {
    depth
        .iter()
        .enumerate()
        .map(|(x, &z)| match z > 0.0 && z.is_finite() {
            true => x as f32 - fb / z,
            false => f32::NAN,
        })
        .collect()
}

/// Scores `depth` (left camera, input size) on the pair (see the module documentation).
pub fn photometric(
    left: &RgbImage,
    right: &RgbImage,
    depth: &DepthMap,
    calib: &Calibration,
) -> Photometric {
    let (w, h) = (left.width as usize, left.height as usize);
    let fb = calib.disparity_per_inverse_depth() as f32;
    let mut errors = vec![f32::NAN; w * h];
    let (mut scored, mut sum) = (0usize, 0.0f64);
    for y in 0..h {
        let matches = row_matches(&depth.data[y * w..][..w], fb);
        let mut nearest_right = f32::INFINITY;
        for x in (0..w).rev() {
            let xr = matches[x];
            if xr.is_nan() {
                continue;
            }
            let occluded = nearest_right <= xr;
            nearest_right = nearest_right.min(xr);
            if occluded || !(0.0..=(w - 1) as f32).contains(&xr) {
                continue;
            }
            let (x0, f) = (xr.floor() as usize, xr - xr.floor());
            let x1 = (x0 + 1).min(w - 1);
            let mut err = 0.0f32;
            for c in 0..3 {
                let at = |xx: usize| right.data[3 * (y * w + xx) + c];
                let warped = at(x0) * (1.0 - f) + at(x1) * f;
                err += (left.data[3 * (y * w + x) + c] - warped).abs();
            }
            let err = err / 3.0;
            if err.is_finite() {
                errors[y * w + x] = err;
                scored += 1;
                sum += err as f64;
            }
        }
    }
    Photometric {
        mae: (scored > 0).then(|| sum / scored as f64),
        scored_fraction: scored as f64 / (w * h).max(1) as f64,
        errors,
    }
}
