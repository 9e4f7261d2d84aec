//! The volume branch's Gaussian side in one block: occupancy of the whole grid, the voxels
//! some input camera sees, the top-k of those decoded into Gaussians, and how many
//! Gaussians each branch contributes, so reports can give the Gaussians per bin from each
//! branch.

use candle_core::{Result, Tensor};
use candle_nn::VarBuilder;
use renderer::Camera;

use super::decoder::VoxelDecoder;
use super::occupancy::{frustum_mask, top_k, OccupancyHead};
use super::VolumeConfig;
use crate::ops::SplatTensors;

/// Occupancy head plus voxel decoder.
#[derive(Clone, Debug)]
pub struct VolumeHead {
    occupancy: OccupancyHead,
    decoder: VoxelDecoder,
    cfg: VolumeConfig,
}

/// What [`VolumeHead::forward`] gives.
#[derive(Clone, Debug)]
pub struct VolumeOutput {
    /// The volume branch's Gaussians, `voxels.len() V` rows, voxel-major, in the
    /// representation of the cost-volume branch's (`SplatTensors::cat` joins them).
    pub splats: SplatTensors,
    /// Occupancy logit of every voxel, `(X, Y, Z)`: what `occupancy_loss` supervises.
    pub occupancy_logits: Tensor,
    /// The decoded voxels, flat indices in ascending order.
    pub voxels: Vec<usize>,
    /// Per voxel (flat order): whether some input camera sees its centre (the candidates;
    /// also the natural region of `occupancy_loss`).
    pub visible: Vec<bool>,
}

impl VolumeOutput {
    /// Gaussians the volume branch produced.
    pub fn gaussians(&self) -> usize {
        self.splats.means.dims()[0]
    }
}

impl VolumeHead {
    /// The block for `cfg`, its weights under `vb` (`occupancy.*`, `decoder.*`).
    pub fn new(vb: VarBuilder, cfg: &VolumeConfig) -> Result<Self> {
        Ok(Self {
            occupancy: OccupancyHead::new(vb.pp("occupancy"), cfg)?,
            decoder: VoxelDecoder::new(vb.pp("decoder"), cfg)?,
            cfg: cfg.clone(),
        })
    }

    /// The volume branch's Gaussians from the encoder's planes `(C, rows, columns)` in
    /// `Plane::ALL` order and the input `cameras` (bin frame; each camera's intrinsics give
    /// its image size): at most `cfg.top_k` voxels, only voxels whose centre some camera
    /// sees, the most occupied first; `V` Gaussians each.
    pub fn forward(&self, planes: &[Tensor; 3], cameras: &[Camera]) -> Result<VolumeOutput> {
        let occupancy_logits = self.occupancy.forward(planes)?;
        let visible = frustum_mask(&self.cfg, cameras);
        let voxels = top_k(&occupancy_logits, &visible, self.cfg.top_k)?;
        let splats = self.decoder.forward(planes, &occupancy_logits, &voxels)?;
        Ok(VolumeOutput {
            splats,
            occupancy_logits,
            voxels,
            visible,
        })
    }
}

/// Gaussians per bin from each branch, for logs and `bench model`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct GaussiansPerBranch {
    /// Rows of the cost-volume branch's Gaussians (0 when the branch is off).
    pub cost_volume: usize,
    /// Rows of the volume branch's Gaussians (0 when the branch is off).
    pub volume: usize,
}

impl GaussiansPerBranch {
    /// The counts of the branches that ran (`None`: switched off).
    pub fn of(cost_volume: Option<&SplatTensors>, volume: Option<&VolumeOutput>) -> Self {
        Self {
            cost_volume: cost_volume.map_or(0, |s| s.means.dims()[0]),
            volume: volume.map_or(0, VolumeOutput::gaussians),
        }
    }

    /// Both branches together.
    pub fn total(&self) -> usize {
        self.cost_volume + self.volume
    }
}
