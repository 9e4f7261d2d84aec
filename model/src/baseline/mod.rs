//! The classical stereo baseline: semi-global matching (Hirschmüller 2008) on each rectified
//! pair, depth from disparity, one pixel-aligned Gaussian per kept pixel. It learns nothing,
//! so every learned reconstructor must beat it.
//!
//! Stages, each a module: [`census`] (census transform and Hamming cost volume, `u8`
//! W x H x D), [`aggregate`] (semi-global path costs along 4 or 8 directions, summed in
//! `u16`), [`mod@disparity`] (winner-take-all, sub-pixel parabola, uniqueness, left-right check,
//! confidence, 3x3 median), [`unproject`] (disparity to Gaussians in the bin frame).
//!
//! Far surfaces and the sky get no Gaussians: their disparity is too small to measure, so
//! pixels deeper than [`SgmConfig::max_depth`] are dropped instead of becoming huge splats.

pub mod aggregate;
pub mod census;
pub mod disparity;
pub mod unproject;

use renderer::GaussianSet;

use crate::frame::RgbImage;
use crate::reconstruct::{ReconstructError, Reconstructor, StereoView};

/// Settings of the SGM baseline; `Default` suits 544x112 KITTI-360-like input.
#[derive(Clone, Debug, PartialEq)]
pub struct SgmConfig {
    /// Largest disparity searched, pixels. `None` derives it from the rig as
    /// `fx * baseline / min_depth` (capped by `disparity_cap`); the rig-free [`disparity()`]
    /// function then searches up to `disparity_cap`.
    pub max_disparity: Option<u32>,
    /// Upper bound on the searched disparity, which bounds the cost volume (W x H x D bytes).
    pub disparity_cap: u32,
    /// Penalty for a one-level disparity change between path neighbours (census units).
    pub p1: u16,
    /// Penalty for a larger disparity jump before intensity adaptation; at most 4000.
    pub p2: u16,
    /// Grey step (0..255) that halves P2, so disparity may jump where the image has an edge.
    pub p2_gradient: f32,
    /// Aggregate along 8 directions (true) or only the 4 straight ones (faster).
    pub diagonals: bool,
    /// The best aggregated cost must beat the next best (away from d±1) by this fraction.
    pub uniqueness_ratio: f32,
    /// Largest left-right disagreement in pixels a match may have.
    pub lr_tolerance: f32,
    /// Relative uniqueness margin that earns full confidence (smaller margins scale down).
    pub margin_for_full_confidence: f32,
    /// Apply the 3x3 median filter to the valid disparities.
    pub median: bool,
    /// Nearest depth kept, metres; also sets the default disparity range.
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
            disparity_cap: 128,
            p1: 8,
            p2: 96,
            p2_gradient: 16.0,
            diagonals: true,
            uniqueness_ratio: 0.03,
            lr_tolerance: 1.0,
            margin_for_full_confidence: 0.3,
            median: true,
            min_depth: 1.5,
            max_depth: 80.0,
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
    fn validate(&self) -> Result<(), ReconstructError> {
        let bad = |m: &str| Err(ReconstructError::InvalidInput(format!("SgmConfig: {m}")));
        if self.p2 > 4000 || self.p1 >= self.p2 {
            return bad("need p1 < p2 <= 4000");
        }
        if self.stride == 0 || self.disparity_cap < 1 {
            return bad("stride and disparity_cap must be at least 1");
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
        Ok(())
    }

    /// Disparity levels (0..=d_max) searched for a rig with focal `fx` and `baseline`.
    pub fn levels_for_rig(&self, fx: f32, baseline: f32) -> usize {
        let derived = (fx * baseline / self.min_depth).ceil().max(1.0) as u32;
        self.max_disparity
            .unwrap_or(derived)
            .min(self.disparity_cap) as usize
            + 1
    }
}

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

/// SGM disparity of a rectified pair, searching `0..=max_disparity` (or `disparity_cap`
/// when unset). Fails on images of different or zero size, or a bad config.
pub fn disparity(
    left: &RgbImage,
    right: &RgbImage,
    config: &SgmConfig,
) -> Result<DisparityMap, ReconstructError> {
    let d_max = config.max_disparity.unwrap_or(config.disparity_cap);
    disparity_with_levels(
        left,
        right,
        config,
        d_max.min(config.disparity_cap) as usize + 1,
    )
}

fn disparity_with_levels(
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
    let grey_left = census::Grey::from_rgb(left);
    let grey_right = census::Grey::from_rgb(right);
    let cost = census::cost_volume(
        &census::census(&grey_left),
        &census::census(&grey_right),
        w,
        levels,
    );
    let penalties = aggregate::Penalties {
        p1: config.p1,
        p2: config.p2,
        p2_gradient: config.p2_gradient,
    };
    let sum = aggregate::aggregate(&cost, &grey_left, levels, penalties, config.diagonals);
    drop(cost);
    let checks = disparity::Checks {
        uniqueness_ratio: config.uniqueness_ratio,
        lr_tolerance: config.lr_tolerance,
        margin_for_full_confidence: config.margin_for_full_confidence,
    };
    let selected = disparity::select(&sum, w, levels, checks);
    let disparity = if config.median {
        disparity::median3(&selected.disparity, w, h)
    } else {
        selected.disparity
    };
    Ok(DisparityMap {
        width: left.width,
        height: left.height,
        disparity,
        confidence: selected.confidence,
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

/// The baseline in metres of a rectified view: both cameras share rotation and intrinsics
/// and the right centre sits on the left camera's +x axis; anything else is rejected.
pub fn rectified_baseline(view: &StereoView<'_>) -> Result<f32, ReconstructError> {
    let (l, r) = (&view.left_camera, &view.right_camera);
    let bad = |m: String| {
        Err(ReconstructError::InvalidInput(format!(
            "not rectified: {m}"
        )))
    };
    if l.intrinsics != r.intrinsics {
        return bad("left and right intrinsics differ".into());
    }
    if !l.rotation.abs_diff_eq(r.rotation, 1e-4) {
        return bad("left and right rotations differ".into());
    }
    let offset = l.rotation * (r.position - l.position);
    let b = offset.x;
    let tolerance = 1e-3 * b.abs().max(1e-3);
    if !(b > 0.0 && offset.y.abs() <= tolerance && offset.z.abs() <= tolerance) {
        return bad(format!(
            "right camera offset {offset} (left camera frame) is not along +x"
        ));
    }
    let k = l.intrinsics;
    if (view.left.width, view.left.height) != (k.width, k.height) {
        return Err(ReconstructError::InvalidInput(format!(
            "left image is {}x{} but the camera is {}x{}",
            view.left.width, view.left.height, k.width, k.height
        )));
    }
    Ok(b)
}

/// The SGM baseline as a [`Reconstructor`]: each view's pair is matched and unprojected
/// through its own left camera, and the views' Gaussians are concatenated.
#[derive(Clone, Debug, Default)]
pub struct SgmReconstructor {
    /// The settings used for every view.
    pub config: SgmConfig,
}

impl SgmReconstructor {
    /// A reconstructor with the given settings.
    pub fn new(config: SgmConfig) -> Self {
        Self { config }
    }

    /// The disparity map of one view with the disparity range derived from its rig.
    pub fn view_disparity(&self, view: &StereoView<'_>) -> Result<DisparityMap, ReconstructError> {
        Ok(self.match_view(view)?.0)
    }

    /// The view's disparity map and baseline (metres), after checking it is rectified.
    fn match_view(&self, view: &StereoView<'_>) -> Result<(DisparityMap, f32), ReconstructError> {
        let b = rectified_baseline(view)?;
        let levels = self
            .config
            .levels_for_rig(view.left_camera.intrinsics.fx, b);
        let map = disparity_with_levels(view.left, view.right, &self.config, levels)?;
        Ok((map, b))
    }
}

impl Reconstructor for SgmReconstructor {
    fn name(&self) -> &str {
        "sgm"
    }

    fn reconstruct(&mut self, views: &[StereoView<'_>]) -> Result<GaussianSet, ReconstructError> {
        if views.is_empty() {
            return Err(ReconstructError::NoViews);
        }
        let mut all = Vec::new();
        for view in views {
            let (map, b) = self.match_view(view)?;
            all.extend(unproject::unproject(
                &map,
                view.left,
                &view.left_camera,
                b,
                &self.config,
            ));
        }
        if all.len() > self.config.max_gaussians {
            all.sort_by(|a, b| b.confidence.total_cmp(&a.confidence));
            all.truncate(self.config.max_gaussians);
        }
        let mut set = GaussianSet::with_capacity(all.len());
        all.into_iter().for_each(|g| set.push(g));
        Ok(set)
    }
}
