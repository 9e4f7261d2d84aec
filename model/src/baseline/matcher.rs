//! The matcher: census costs, semi-global aggregation, per-row selection, speckle filter and
//! optional median, from a rectified pair to a [`DisparityMap`].
//!
//! Memory is bounded for any input: the census strings and grey images (`20 x W x H`
//! bytes), the disparity map (`8 x W x H` bytes), `O(W x D)` per path direction, and with
//! eight paths the `2 x W x H x D`-byte sum volume, which is never allowed past
//! [`SgmConfig::max_volume_bytes`] (five paths in one sweep are used beyond it). `D` is at
//! most half the width by default ([`SgmConfig::levels_for`]).

use super::aggregate::{self, Inputs, Paths, Penalties};
use super::census::{census, Grey};
use super::config::SgmConfig;
use super::{disparity, speckle};
use crate::frame::RgbImage;
use crate::reconstruct::ReconstructError;

/// A dense disparity map of the left image with a confidence per pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct DisparityMap {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Left-image disparity in pixels (x_left - x_right), row major; NaN where rejected.
    pub disparity: Vec<f32>,
    /// Confidence in (0, 1] where valid, 0 where rejected.
    pub confidence: Vec<f32>,
}

impl DisparityMap {
    /// How many pixels hold a disparity.
    pub fn valid_count(&self) -> usize {
        self.disparity.iter().filter(|d| !d.is_nan()).count()
    }
}

/// The paths to aggregate: the configured ones, unless eight would need a volume beyond the
/// memory budget.
fn paths_within_budget(config: &SgmConfig, cells: usize) -> Paths {
    match config.paths {
        Paths::Eight if cells.saturating_mul(2) > config.max_volume_bytes => Paths::Five,
        paths => paths,
    }
}

/// SGM disparity of a rectified pair over `levels` disparities `0..levels` (at least 1,
/// at most the width). Fails on images of different or zero size, or a bad config.
pub fn match_pair(
    left: &RgbImage,
    right: &RgbImage,
    config: &SgmConfig,
    levels: usize,
) -> Result<DisparityMap, ReconstructError> {
    config.validate()?;
    check_image(left, "left")?;
    check_image(right, "right")?;
    if (left.width, left.height) != (right.width, right.height) {
        return Err(ReconstructError::InvalidInput(format!(
            "left image is {}x{} but right is {}x{}",
            left.width, left.height, right.width, right.height
        )));
    }
    let (w, h) = (left.width as usize, left.height as usize);
    let levels = levels.clamp(1, w);
    let grey = Grey::from_rgb(left);
    let (codes_left, codes_right) = (census(&grey), census(&Grey::from_rgb(right)));
    let inputs = Inputs {
        left: &codes_left,
        right: &codes_right,
        grey: &grey,
        levels,
    };
    let penalties = Penalties {
        p1: config.p1,
        p2: config.p2,
        p2_gradient: config.p2_gradient,
    };
    let checks = disparity::Checks {
        uniqueness_ratio: config.uniqueness_ratio,
        lr_tolerance: config.lr_tolerance,
        margin_for_full_confidence: config.margin_for_full_confidence,
    };
    let mut map = vec![f32::NAN; w * h];
    let mut confidence = vec![0.0f32; w * h];
    let paths = paths_within_budget(config, w * h * levels);
    aggregate::aggregate(&inputs, penalties, paths, |y, sums| {
        let row = y * w..(y + 1) * w;
        disparity::select_row(
            sums,
            levels,
            checks,
            &mut map[row.clone()],
            &mut confidence[row],
        );
    });
    speckle::filter(
        &mut map,
        w,
        config.speckle_window as usize,
        config.speckle_range,
    );
    let map = match config.median {
        true => disparity::median3(&map, w, h),
        false => map,
    };
    for (c, d) in confidence.iter_mut().zip(&map) {
        if d.is_nan() {
            *c = 0.0;
        }
    }
    Ok(DisparityMap {
        width: left.width,
        height: left.height,
        disparity: map,
        confidence,
    })
}

/// An image must be non-empty and hold `3 * width * height` values.
fn check_image(image: &RgbImage, which: &str) -> Result<(), ReconstructError> {
    let expected = 3 * image.width as usize * image.height as usize;
    if expected == 0 || image.data.len() != expected {
        return Err(ReconstructError::InvalidInput(format!(
            "{which} image is {}x{} with {} values (expected {expected}, non-empty)",
            image.width,
            image.height,
            image.data.len()
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eight_paths_fall_back_to_five_beyond_the_volume_budget() {
        let config = SgmConfig {
            max_volume_bytes: 1000,
            ..SgmConfig::default()
        };
        assert_eq!(paths_within_budget(&config, 500), Paths::Eight);
        assert_eq!(paths_within_budget(&config, 501), Paths::Five);
        assert_eq!(paths_within_budget(&config, usize::MAX), Paths::Five);
        let five = SgmConfig {
            paths: Paths::Five,
            ..SgmConfig::default()
        };
        assert_eq!(paths_within_budget(&five, 1), Paths::Five);
    }
}
