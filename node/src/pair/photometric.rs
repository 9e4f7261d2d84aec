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

#[cfg(test)]
mod tests {
    use super::*;
    use renderer::Intrinsics;

    /// A 64x4 pair whose right image is the left moved 4 px to the left, fx * B = 40.
    fn pair() -> (RgbImage, RgbImage, Calibration) {
        let (w, h) = (64u32, 4u32);
        let value = |x: i32| ((x * 37 % 11) as f32) / 10.0;
        let image = |shift: i32| RgbImage {
            width: w,
            height: h,
            data: (0..w * h)
                .flat_map(|i| [value((i % w) as i32 + shift); 3])
                .collect(),
        };
        let calib = Calibration {
            intrinsics: Intrinsics {
                fx: 40.0,
                fy: 40.0,
                cx: 32.0,
                cy: 2.0,
                width: w,
                height: h,
            },
            baseline: 1.0,
        };
        (image(0), image(4), calib)
    }

    #[test]
    fn the_right_depth_is_consistent_and_a_wrong_one_is_not() {
        let (left, right, calib) = pair();
        let depth = |z: f32| DepthMap {
            width: 64,
            height: 4,
            data: vec![z; 256],
        };
        let good = photometric(&left, &right, &depth(10.0), &calib);
        assert_eq!(good.mae, Some(0.0));
        // Columns 0..3 match outside the right image.
        assert!((good.scored_fraction - 60.0 / 64.0).abs() < 1e-9);
        let bad = photometric(&left, &right, &depth(20.0), &calib);
        assert!(bad.mae.unwrap() > 0.1, "{:?}", bad.mae);
    }

    #[test]
    fn pixels_hidden_behind_a_nearer_surface_are_not_scored() {
        let (left, right, calib) = pair();
        // Background at 4 px disparity; columns 20..24 a near strip at 10 px, which covers
        // the background pixels whose match falls at or right of its own matches.
        let mut data = vec![10.0f32; 256];
        for row in data.chunks_exact_mut(64) {
            row[20..24].fill(4.0);
        }
        let depth = DepthMap {
            width: 64,
            height: 4,
            data,
        };
        let p = photometric(&left, &right, &depth, &calib);
        // Background columns 14..19 match at 10..15, behind the strip's 10..13: hidden.
        for x in 14..20 {
            assert!(p.errors[x].is_nan(), "column {x}");
        }
        assert!(p.errors[13].is_finite() && p.errors[20].is_finite());
    }

    #[test]
    fn no_depth_scores_nothing() {
        let (left, right, calib) = pair();
        let p = photometric(&left, &right, &DepthMap::empty(64, 4), &calib);
        assert_eq!((p.mae, p.scored_fraction), (None, 0.0));
    }
}
