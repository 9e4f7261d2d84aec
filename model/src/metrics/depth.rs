//! Depth errors of a predicted (rendered) depth map against sparse ground truth: AbsRel,
//! SqRel and RMSE on the pixels where the ground truth holds a usable measurement.

use super::{check_length, check_same_size, MetricError};
use crate::frame::DepthMap;

/// Which ground-truth depths count and the range predictions are clamped to.
///
/// The default, 1e-3 m to 80 m, is the KITTI convention (Eigen split, Monodepth
/// evaluation): LiDAR beyond 80 m is too sparse and noisy to judge a prediction by.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DepthFilter {
    /// Smallest ground-truth depth that counts, in metres; also the floor predictions are
    /// clamped to.
    pub min_depth: f32,
    /// Largest ground-truth depth that counts, in metres; also the ceiling predictions are
    /// clamped to.
    pub max_depth: f32,
}

impl Default for DepthFilter {
    /// KITTI's 1e-3 m to 80 m.
    fn default() -> Self {
        Self {
            min_depth: 1e-3,
            max_depth: 80.0,
        }
    }
}

/// Depth errors averaged over the valid pixels (see [`depth_errors`] for the rule).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DepthErrors {
    /// Mean of `|p - g| / g`.
    pub abs_rel: f64,
    /// Mean of `(p - g)^2 / g`, in metres.
    pub sq_rel: f64,
    /// `sqrt(mean((p - g)^2))`, in metres.
    pub rmse: f64,
    /// Pixels whose ground truth passed the filter: the number the means are over.
    pub valid: usize,
    /// Valid pixels where the prediction held no depth (NaN, infinite, zero or negative);
    /// they are included in the means with a penalty, see [`depth_errors`].
    pub missing: usize,
}

/// AbsRel, SqRel and RMSE of `pred` against `gt`, computed in f64.
///
/// A pixel is valid when its ground truth `g` is finite and
/// `filter.min_depth <= g <= filter.max_depth` (so 0, the "no measurement" mark, negative
/// values, NaN and points beyond the range are all excluded). On every valid pixel the
/// prediction is clamped into `[min_depth, max_depth]`, as the Monodepth / Eigen-split
/// evaluation does, after mapping NaN to 0. So a prediction that holds no depth (NaN,
/// infinite, zero or negative) is not dropped, which would let a method score well by
/// leaving hard pixels empty: a hole (NaN, 0, negative, -inf) is scored as `min_depth`,
/// i.e. close to 100 % relative error, and +inf as `max_depth`. Such pixels are counted
/// in [`DepthErrors::missing`] so a reader sees the coverage.
///
/// Errors: different sizes, a malformed buffer, an invalid filter range, or no valid pixel
/// ([`MetricError::NoValidPixels`]: there is nothing to average, so no number is made up).
pub fn depth_errors(
    pred: &DepthMap,
    gt: &DepthMap,
    filter: &DepthFilter,
) -> Result<DepthErrors, MetricError> {
    check_same_size((pred.width, pred.height), (gt.width, gt.height))?;
    check_length("pred", pred.width, pred.height, 1, pred.data.len())?;
    check_length("gt", gt.width, gt.height, 1, gt.data.len())?;
    let (min_depth, max_depth) = (filter.min_depth, filter.max_depth);
    let range_ok = min_depth.is_finite() && max_depth.is_finite() && min_depth > 0.0;
    if !range_ok || min_depth >= max_depth {
        return Err(MetricError::InvalidFilter {
            min_depth,
            max_depth,
        });
    }
    let (lo, hi) = (min_depth as f64, max_depth as f64);
    let (mut abs_rel, mut sq_rel, mut sq) = (0.0, 0.0, 0.0);
    let (mut valid, mut missing) = (0usize, 0usize);
    for (&p, &g) in pred.data.iter().zip(&gt.data) {
        // `contains` is false for NaN, so NaN ground truth is excluded too.
        if !(min_depth..=max_depth).contains(&g) {
            continue;
        }
        valid += 1;
        if !(p.is_finite() && p > 0.0) {
            missing += 1;
        }
        let p = if p.is_nan() { 0.0 } else { p as f64 };
        let p = p.clamp(lo, hi);
        let g = g as f64;
        let d = p - g;
        abs_rel += d.abs() / g;
        sq_rel += d * d / g;
        sq += d * d;
    }
    if valid == 0 {
        return Err(MetricError::NoValidPixels);
    }
    let n = valid as f64;
    Ok(DepthErrors {
        abs_rel: abs_rel / n,
        sq_rel: sq_rel / n,
        rmse: (sq / n).sqrt(),
        valid,
        missing,
    })
}
