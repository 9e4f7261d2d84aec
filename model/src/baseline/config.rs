//! The SGM baseline's settings and the disparity range a rig and image size call for.

use super::aggregate::{Paths, MAX_P2};
use crate::reconstruct::ReconstructError;

/// Settings of the SGM baseline. The defaults are the textbook ones (Hirschmüller 2008,
/// OpenCV `StereoSGBM`): eight paths, a 10% uniqueness ratio, a 1-px left-right check,
/// speckle regions under 100 px with steps over 2 px removed, a 3x3 median. The disparity range follows
/// the image and the rig, not fixed metres ([`SgmConfig::levels_for`]).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SgmConfig {
    /// Largest disparity searched, pixels, overriding the derived range when set.
    pub max_disparity: Option<u32>,
    /// The search always reaches this fraction of the image width (default a third), so
    /// any rig sees surfaces whose disparity is up to W/3 with no setting.
    pub min_search_fraction: f32,
    /// The search never goes beyond this fraction of the width (default a half): nearer
    /// surfaces leave too little overlap to match, and time grows with the range.
    pub max_search_fraction: f32,
    /// Penalty for a one-level disparity change between path neighbours (census units).
    pub p1: u16,
    /// Penalty for a larger disparity jump before intensity adaptation; at most
    /// [`MAX_P2`].
    pub p2: u16,
    /// Grey step (0..255) that halves P2, so disparity may jump where the image has an edge.
    pub p2_gradient: f32,
    /// Path directions aggregated: eight (two sweeps) or five (one sweep); `eight` or
    /// `five` as a setting.
    pub paths: Paths,
    /// Most bytes the eight-path volume (`2 x W x H x D`) may take; a larger pair is
    /// aggregated along five paths in one sweep instead, whose memory is `O(W x D)`.
    pub max_volume_bytes: usize,
    /// The best aggregated cost must beat the next best (away from d±1) by this fraction.
    pub uniqueness_ratio: f32,
    /// Largest left-right disagreement in pixels a match may have.
    pub lr_tolerance: f32,
    /// Relative uniqueness margin that earns full confidence (smaller margins scale down).
    pub margin_for_full_confidence: f32,
    /// Regions of consistent disparity smaller than this many pixels are removed (0 or 1:
    /// no speckle filter).
    pub speckle_window: u32,
    /// Largest disparity step, pixels, between neighbours of one speckle region.
    pub speckle_range: f32,
    /// Apply the 3x3 median filter to the valid disparities (on by default: chosen on
    /// generated validation streets, `results/sgm/sizes.md`).
    pub median: bool,
    /// Nearest depth kept, metres: a safety clamp, and with the baseline the rig's share of
    /// the disparity range (`fx * baseline / min_depth`, within the width fractions).
    pub min_depth: f32,
    /// Farthest depth kept, metres; beyond it disparity is too small to trust and
    /// Gaussians would be huge.
    pub max_depth: f32,
    /// Pixels whose confidence is below this get no Gaussian.
    pub min_confidence: f32,
    /// Keep every `stride`-th pixel in x and y (the Gaussian budget; 2 gives a quarter).
    pub stride: u32,
    /// Most Gaussians returned over all views; the least confident are dropped first.
    pub max_gaussians: usize,
    /// Disc radius (standard deviation) as a fraction of the sampled pixel footprint.
    pub footprint_scale: f32,
    /// Disc thickness along the camera axis as a fraction of its radius.
    pub thickness: f32,
    /// Opacity of a zero-confidence Gaussian; opacity = floor + (1 - floor) * confidence.
    pub opacity_floor: f32,
}

impl Default for SgmConfig {
    fn default() -> Self {
        Self {
            max_disparity: None,
            min_search_fraction: 1.0 / 3.0,
            max_search_fraction: 0.5,
            p1: 8,
            p2: 96,
            p2_gradient: 16.0,
            paths: Paths::Eight,
            max_volume_bytes: 1 << 30,
            uniqueness_ratio: 0.1,
            lr_tolerance: 1.0,
            margin_for_full_confidence: 0.3,
            speckle_window: 100,
            speckle_range: 2.0,
            median: true,
            min_depth: 0.1,
            max_depth: 100.0,
            min_confidence: 0.05,
            stride: 1,
            max_gaussians: 200_000,
            footprint_scale: 0.7,
            thickness: 0.1,
            opacity_floor: 0.3,
        }
    }
}

impl SgmConfig {
    /// Rejects settings the algorithm cannot honour (u16 overflow, empty ranges).
    pub(super) fn validate(&self) -> Result<(), ReconstructError> {
        let bad = |m: &str| Err(ReconstructError::InvalidInput(format!("SgmConfig: {m}")));
        if self.p2 > MAX_P2 || self.p1 >= self.p2 {
            return bad(&format!("need p1 < p2 <= {MAX_P2}"));
        }
        let (lo, hi) = (self.min_search_fraction, self.max_search_fraction);
        if !(lo > 0.0 && lo <= hi && hi <= 1.0) {
            return bad("need 0 < min_search_fraction <= max_search_fraction <= 1");
        }
        if self.stride == 0 {
            return bad("stride must be at least 1");
        }
        if !(self.min_depth > 0.0 && self.max_depth > self.min_depth) {
            return bad("need 0 < min_depth < max_depth");
        }
        if !(self.footprint_scale > 0.0 && self.thickness > 0.0) {
            return bad("footprint_scale and thickness must be positive");
        }
        if !(0.0..=1.0).contains(&self.opacity_floor) {
            return bad("opacity_floor must lie in [0, 1]");
        }
        if !(self.speckle_range >= 0.0 && self.lr_tolerance >= 0.0) {
            return bad("speckle_range and lr_tolerance must be non-negative");
        }
        Ok(())
    }

    /// Disparity levels `0..=d_max` searched on an image `width` pixels wide from a rig
    /// with focal `fx` (pixels) and `baseline` (metres); `None` for the rig searches
    /// the width's minimum share. `d_max` is `max_disparity` when set, otherwise
    /// `fx * baseline / min_depth` kept between `min_search_fraction` and
    /// `max_search_fraction` of the width; never beyond `width - 1`. A desk at 0.2 m seen by
    /// a 5 cm rig at fx 550 px needs 138 px, a street at 3 m by a 60 cm rig 110 px: both
    /// inside a 640-px image's default 213..320 px.
    pub fn levels_for(&self, width: u32, rig: Option<(f32, f32)>) -> usize {
        let w = width.max(1) as f32;
        let lo = (w * self.min_search_fraction).ceil();
        let hi = (w * self.max_search_fraction).floor().max(lo);
        let derived = match rig {
            Some((fx, baseline)) => {
                let wanted = (fx * baseline / self.min_depth).ceil();
                // A NaN rig falls back to the width's minimum share.
                if wanted.is_nan() {
                    lo
                } else {
                    wanted.clamp(lo, hi)
                }
            }
            None => lo,
        };
        let d_max = self.max_disparity.map_or(derived, |d| d as f32);
        d_max.min(w - 1.0).max(0.0) as usize + 1
    }
}
