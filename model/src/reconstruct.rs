//! The reconstructor interface: stereo views with their cameras in, a Gaussian set out.
//! The classical baseline implements it now and the learned StereoSplat model later, so
//! evaluation and the streaming node never change when the model does.

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
}
