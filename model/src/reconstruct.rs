//! The reconstructor interface: stereo views with their cameras in, a Gaussian set out.
//! The classical baseline and the learned StereoSplat network both implement it, so
//! evaluation and the streaming node do not change with the method.

use renderer::{Camera, GaussianSet};

use crate::frame::RgbImage;

/// One rectified stereo pair with its cameras, in a bin's local frame.
#[derive(Clone, Copy, Debug)]
pub struct StereoView<'a> {
    /// Left image.
    pub left: &'a RgbImage,
    /// Right image.
    pub right: &'a RgbImage,
    /// Left camera (bin-local).
    pub left_camera: Camera,
    /// Right camera (bin-local).
    pub right_camera: Camera,
}

/// Why a reconstruction failed.
#[derive(Debug, thiserror::Error)]
pub enum ReconstructError {
    /// No stereo view was given.
    #[error("no stereo view given")]
    NoViews,
    /// The views do not fit the reconstructor (sizes, camera resolution).
    #[error("invalid input: {0}")]
    InvalidInput(String),
    /// The reconstructor's own machinery failed (a tensor op, a device).
    #[error("reconstructor failed: {0}")]
    Backend(String),
}

/// Where the last reconstruction's time went, stage by stage, in milliseconds (the
/// progressive pass reports it; the node turns it into `BinLatency` stamps).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct ModelSplit {
    /// G_base: the network on the real pairs, their fusion, floor and budget.
    pub base_ms: f64,
    /// Rendering the pseudo views from G_base.
    pub pseudo_render_ms: f64,
    /// The enhancer on the pseudo views (0 with it off).
    pub enhance_ms: f64,
    /// The pseudo pairs through the network (G_plus's new part).
    pub plus_ms: f64,
    /// Confidence-guided fusion of G_base and G_plus.
    pub fuse_ms: f64,
}

/// Turns one or more stereo views of a stretch of road into Gaussians in the views' frame.
pub trait Reconstructor {
    /// A short name for tables and logs (`sgm`, `stereosplat-tiny`).
    fn name(&self) -> &str;

    /// Reconstruct the scene seen by `views`; the first view is the reference.
    fn reconstruct(&mut self, views: &[StereoView<'_>]) -> Result<GaussianSet, ReconstructError>;

    /// [`Reconstructor::reconstruct`] told the bin-local left cameras of the bin's frames
    /// after the inputs (their poses known, their images not given, as in `eval`). Only the
    /// progressive pass uses them, to place its pseudo views; the rest ignore them.
    fn reconstruct_ahead(
        &mut self,
        views: &[StereoView<'_>],
        ahead: &[Camera],
    ) -> Result<GaussianSet, ReconstructError> {
        let _ = ahead;
        self.reconstruct(views)
    }

    /// The stage times of the last reconstruction when the reconstructor splits them (the
    /// progressive pass); `None` otherwise, or when the last reconstruction failed.
    fn last_split(&self) -> Option<ModelSplit> {
        None
    }

    /// The depth range (near, far, metres) the last reconstruction's candidates spanned when
    /// the reconstructor fitted it to the scene (`auto_depth_range`); `None` otherwise.
    fn last_depth_range(&self) -> Option<(f32, f32)> {
        None
    }
}
