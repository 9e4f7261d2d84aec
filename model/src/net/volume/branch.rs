//! The volume branch as one block inside `StereoSplat`: projection-guided fusion of the
//! cost-volume Gaussians into plane priors, the triplane encoder over the views' features,
//! and the occupancy head and voxel decoder (paper section 3.2.2).
//!
//! The fusion reads the Gaussians' features detached: their centres already only pick cells
//! (no gradient), and the cost-volume heads keep their own supervision (joint render, depth
//! losses), so a fresh volume branch cannot pull a warm-started context through a mean over
//! thousands of Gaussians in its first noisy steps. The views' features the cross-image
//! attention samples are not detached: that is where the branch learns what to read from the
//! shared backbone, as the paper's joint training does.

use candle_core::{Result, Tensor};
use candle_nn::VarBuilder;
use renderer::Camera;

use super::fusion::{gaussian_rows, ProjectionFusion};
use super::{Planes, TriplaneEncoder, VolumeHead, VolumeOutput};
use crate::net::Config;

/// Fusion, encoder and head of the volume branch.
#[derive(Clone, Debug)]
pub struct VolumeBranch {
    fusion: ProjectionFusion,
    encoder: TriplaneEncoder,
    head: VolumeHead,
}

/// What the volume branch reads from the cost-volume branch.
pub struct BranchInputs<'a> {
    /// The cost-volume Gaussians' centres, `(N, 3)` in the bin frame.
    pub means: &'a Tensor,
    /// Their features, `(V, k, Hg, Wg)` (`Prediction::features`), in the same order.
    pub features: &'a Tensor,
    /// The views' features before normalisation, `(V, cost_channels, h, w)`.
    pub view_features: &'a Tensor,
    /// The views' cameras in the bin frame.
    pub cameras: &'a [Camera],
    /// Image pixels per pixel of `view_features`.
    pub stride: usize,
}

impl VolumeBranch {
    /// The branch of `cfg.volume` under `vb` (`fusion.*`, `encoder.*`, `head.*`), fusing
    /// Gaussians with `features` channels each.
    pub fn new(vb: VarBuilder, cfg: &Config, features: usize) -> Result<Self> {
        Ok(Self {
            fusion: ProjectionFusion::new(vb.pp("fusion"), &cfg.volume, features)?,
            encoder: TriplaneEncoder::new(vb.pp("encoder"), cfg)?,
            head: VolumeHead::new(vb.pp("head"), &cfg.volume)?,
        })
    }

    /// The volume branch's Gaussians and what training supervises.
    pub fn forward(&self, inputs: &BranchInputs<'_>) -> Result<VolumeOutput> {
        let rows = gaussian_rows(&inputs.features.detach())?;
        let prior = Planes(self.fusion.forward(inputs.means, &rows)?);
        let planes = self.encoder.forward(
            Some(&prior),
            inputs.view_features,
            inputs.cameras,
            inputs.stride,
        )?;
        self.head.forward(&planes.0, inputs.cameras)
    }
}
