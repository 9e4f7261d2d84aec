//! The classical stereo baseline: semi-global matching (Hirschmüller 2008) on each rectified
//! pair, depth from disparity, one pixel-aligned Gaussian per kept pixel. It learns nothing,
//! so every learned reconstructor must beat it.
//!
//! Stages, each a module: [`census`] (census transform and Hamming matching costs, one row
//! at a time), [`aggregate`] (semi-global path costs along 8 or 5 directions, streamed over
//! the rows), [`mod@disparity`] (winner-take-all, sub-pixel parabola, uniqueness, left-right
//! check, confidence, 3x3 median), [`speckle`] (small inconsistent regions removed),
//! [`matcher`] (the stages in order, with the memory bound), [`unproject`] (disparity to
//! Gaussians in the bin frame). [`config`] holds the settings and the disparity range,
//! which follows the image width and the rig rather than fixed metres.
//!
//! Far surfaces and the sky get no Gaussians: their disparity is too small to measure, so
//! pixels deeper than [`SgmConfig::max_depth`] are dropped instead of becoming huge splats.

pub mod aggregate;
pub mod census;
pub mod config;
pub mod disparity;
pub mod matcher;
pub mod speckle;
pub mod unproject;

use renderer::GaussianSet;

pub use aggregate::Paths;
pub use config::SgmConfig;
pub use matcher::DisparityMap;

use crate::frame::RgbImage;
use crate::reconstruct::{ReconstructError, Reconstructor, StereoView};

/// SGM disparity of a rectified pair without a rig: the search spans `0..=max_disparity`
/// when set, otherwise the width's minimum share (a third by default). Fails on images of
/// different or zero size, or a bad config.
pub fn disparity(
    left: &RgbImage,
    right: &RgbImage,
    config: &SgmConfig,
) -> Result<DisparityMap, ReconstructError> {
    matcher::match_pair(left, right, config, config.levels_for(left.width, None))
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
        let rig = (view.left_camera.intrinsics.fx, b);
        let levels = self.config.levels_for(view.left.width, Some(rig));
        let map = matcher::match_pair(view.left, view.right, &self.config, levels)?;
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
