//! Disparity scores against a ground-truth disparity map, the Middlebury way: bad-1 and
//! bad-3 (percent of ground-truth pixels whose predicted disparity is off by more than 1 or
//! 3 px), end-point error (mean |d - d*| in px) and density (percent of ground-truth pixels
//! with a prediction).
//!
//! The prediction is the reconstruction's rendered depth z, as disparity d = fx * B / z,
//! scored at the ground truth's resolution (depth sampled at the nearest input pixel, fx
//! scaled to the truth's width). A ground-truth pixel without a predicted depth counts as
//! wrong for bad-1 and bad-3 (a method cannot score well by predicting little) and is left
//! out of the end-point error, which is over predicted pixels only; density says how many
//! those are, and bad-3 over predicted pixels only is reported beside.

use std::path::Path;

use image::DynamicImage;
use model::frame::DepthMap;
use serde::Serialize;

use super::images::decode;
use super::{Calibration, PairError};

/// A ground-truth disparity map: pixels of its own width, 0 = unknown.
#[derive(Clone, Debug, PartialEq)]
pub struct TruthDisparity {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Disparity per pixel, row major; 0 where unknown.
    pub data: Vec<f32>,
}

impl TruthDisparity {
    /// Reads an 8- or 16-bit grey PNG whose values times `scale` are disparities in pixels
    /// (Middlebury's 8-bit maps: scale 1; KITTI's 16-bit maps: 1/256). Non-finite or
    /// negative products count as unknown.
    pub fn load(path: &Path, scale: f32) -> Result<Self, PairError> {
        let img = decode(path)?;
        let (width, height) = (img.width(), img.height());
        let values: Vec<f32> = match img {
            DynamicImage::ImageLuma8(g) => g.as_raw().iter().map(|v| *v as f32).collect(),
            other => other
                .to_luma16()
                .as_raw()
                .iter()
                .map(|v| *v as f32)
                .collect(),
        };
        let data = values
            .into_iter()
            .map(|v| v * scale)
            .map(|d| if d.is_finite() && d > 0.0 { d } else { 0.0 })
            .collect();
        Ok(Self {
            width,
            height,
            data,
        })
    }
}

/// The scores of one prediction (see the module documentation).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DisparityScores {
    /// Percent of ground-truth pixels off by more than 1 px or without a prediction.
    pub bad1: f64,
    /// Percent of ground-truth pixels off by more than 3 px or without a prediction.
    pub bad3: f64,
    /// Percent of predicted ground-truth pixels off by more than 3 px.
    pub bad3_predicted: f64,
    /// Mean |d - d*| over predicted ground-truth pixels, px; `None` when none is predicted.
    pub epe: Option<f64>,
    /// Percent of ground-truth pixels with a prediction.
    pub density: f64,
    /// Ground-truth pixels (known disparity).
    pub truth_pixels: usize,
}

/// Scores `depth` (input size, from a rig `calib`) against `truth`; also returns the
/// per-pixel |d - d*| at the truth's size (NaN where the truth is unknown, infinite where
/// there is no prediction).
pub fn score(
    depth: &DepthMap,
    calib: &Calibration,
    truth: &TruthDisparity,
) -> (DisparityScores, Vec<f32>) {
    let sx = depth.width as f64 / truth.width.max(1) as f64;
    let sy = depth.height as f64 / truth.height.max(1) as f64;
    let fb = calib.disparity_per_inverse_depth() / sx;
    let mut errors = vec![f32::NAN; truth.data.len()];
    let (mut known, mut predicted, mut over1, mut over3, mut sum) = (0usize, 0usize, 0, 0, 0.0);
    for (i, (&t, e)) in truth.data.iter().zip(errors.iter_mut()).enumerate() {
        if t <= 0.0 {
            continue;
        }
        known += 1;
        let (gx, gy) = (i % truth.width as usize, i / truth.width as usize);
        let x = (((gx as f64 + 0.5) * sx) as usize).min(depth.width as usize - 1);
        let y = (((gy as f64 + 0.5) * sy) as usize).min(depth.height as usize - 1);
        let z = depth.data[y * depth.width as usize + x];
        if !(z > 0.0 && z.is_finite()) {
            *e = f32::INFINITY;
            continue;
        }
        let err = (fb / z as f64 - t as f64).abs();
        predicted += 1;
        sum += err;
        over1 += usize::from(err > 1.0);
        over3 += usize::from(err > 3.0);
        *e = err as f32;
    }
    let pct = |n: usize, of: usize| 100.0 * n as f64 / of.max(1) as f64;
    let missing = known - predicted;
    let scores = DisparityScores {
        bad1: pct(over1 + missing, known),
        bad3: pct(over3 + missing, known),
        bad3_predicted: pct(over3, predicted),
        epe: (predicted > 0).then(|| sum / predicted as f64),
        density: pct(predicted, known),
        truth_pixels: known,
    };
    (scores, errors)
}

#[cfg(test)]
mod tests {
    use super::*;
    use renderer::Intrinsics;

    fn calib(width: u32, height: u32) -> Calibration {
        Calibration {
            intrinsics: Intrinsics {
                fx: 100.0,
                fy: 100.0,
                cx: 0.0,
                cy: 0.0,
                width,
                height,
            },
            baseline: 0.5,
        }
    }

    #[test]
    fn a_missing_prediction_is_wrong_for_bad_n_and_absent_from_epe() {
        // fx * B = 50: depths 5, 2.5, 10 m are disparities 10, 20, 5 px; the 4th has none.
        let depth = DepthMap {
            width: 4,
            height: 1,
            data: vec![5.0, 2.5, 10.0, 0.0],
        };
        let truth = TruthDisparity {
            width: 4,
            height: 1,
            data: vec![10.5, 22.0, 0.0, 7.0],
        };
        let (s, errors) = score(&depth, &calib(4, 1), &truth);
        assert_eq!(s.truth_pixels, 3);
        assert!((s.bad1 - 100.0 * 2.0 / 3.0).abs() < 1e-9, "{s:?}");
        assert!((s.bad3 - 100.0 / 3.0).abs() < 1e-9, "{s:?}");
        assert!((s.epe.unwrap() - 1.25).abs() < 1e-6, "{s:?}");
        assert!((s.density - 100.0 * 2.0 / 3.0).abs() < 1e-9);
        assert_eq!(s.bad3_predicted, 0.0);
        assert!(errors[2].is_nan() && errors[3].is_infinite());
    }

    #[test]
    fn a_half_size_truth_halves_the_predicted_disparity() {
        let depth = DepthMap {
            width: 4,
            height: 2,
            data: vec![5.0; 8],
        };
        let truth = TruthDisparity {
            width: 2,
            height: 1,
            data: vec![5.0, 5.0],
        };
        let (s, _) = score(&depth, &calib(4, 2), &truth);
        assert_eq!((s.bad1, s.epe), (0.0, Some(0.0)));
    }

    #[test]
    fn nothing_predicted_and_no_truth_give_no_nan() {
        let depth = DepthMap::empty(3, 3);
        let truth = TruthDisparity {
            width: 3,
            height: 3,
            data: vec![0.0; 9],
        };
        let (s, _) = score(&depth, &calib(3, 3), &truth);
        assert_eq!((s.bad1, s.bad3, s.density, s.epe), (0.0, 0.0, 0.0, None));
    }
}
