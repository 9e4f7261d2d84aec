//! The voxel decoder (paper section 3.2.2, "Gaussian parameter prediction for the 3D volume
//! branch"): for the selected voxels only, the voxel feature is the sum of its three plane
//! cells (gathered with `index_select`), an MLP `C -> 2C -> C -> V x 15` predicts V Gaussians
//! per voxel, and the heads bound them to the voxel:
//! - centre = voxel centre + `tanh` x 2 voxel sizes (per axis), so a Gaussian never leaves
//!   the 5 x 5 x 5 voxels around its own;
//! - scale = `sigmoid` x 2 voxel sizes (per axis), given as its log (`ln sigmoid` computed
//!   stably, finite for any finite input);
//! - rotation: a normalised quaternion (`w x y z`, starting near the identity; a zero
//!   quaternion stays zero, which the renderer reads as the identity);
//! - colour `sigmoid` (linear RGB in `[0, 1]`), confidence `sigmoid`;
//! - opacity = `sigmoid(a) sigmoid(o)`, `o` the voxel's occupancy logit, so the render's
//!   gradients train the occupancy head too; given as its logit (what the renderer and the
//!   cost-volume heads use), `-logsumexp(-a, -o, -a - o)`, exact and finite.
//!
//! The output is the project's `SplatTensors`, one row per Gaussian, voxel-major (the V
//! Gaussians of the first selected voxel, then the next voxel's), in the representation the
//! cost-volume heads produce, so the two branches' Gaussians concatenate.

use candle_core::{Module, Result, Tensor};
use candle_nn::{linear, Linear, VarBuilder};

use super::voxels::{check_planes, index_tensor, plane_cell, voxel_at};
use super::{Plane, VolumeConfig};
use crate::ops::{transpose_last2, SplatTensors};

/// Predicted values per Gaussian: offset 3, scale 3, rotation 4, colour 3, opacity 1,
/// confidence 1.
pub const GAUSSIAN_PARAMS: usize = 15;
/// Largest offset of a centre from its voxel's centre, in voxel sizes (per axis).
pub const MAX_OFFSET: f64 = 2.0;
/// Largest scale (standard deviation), in voxel sizes (per axis).
pub const MAX_SCALE: f64 = 2.0;

/// The voxel decoder's MLP.
#[derive(Clone, Debug)]
pub struct VoxelDecoder {
    hidden: Linear,
    narrow: Linear,
    out: Linear,
    cfg: VolumeConfig,
}

impl VoxelDecoder {
    /// The decoder for `cfg` (channels, `gaussians_per_voxel`), its weights under `vb`.
    pub fn new(vb: VarBuilder, cfg: &VolumeConfig) -> Result<Self> {
        let c = cfg.channels;
        Ok(Self {
            hidden: linear(c, 2 * c, vb.pp("hidden"))?,
            narrow: linear(2 * c, c, vb.pp("narrow"))?,
            out: linear(c, cfg.gaussians_per_voxel * GAUSSIAN_PARAMS, vb.pp("out"))?,
            cfg: cfg.clone(),
        })
    }

    /// The Gaussians of `voxels` (flat voxel indices, see `voxels`), `V` per voxel,
    /// `voxels.len() V` rows, from the planes `(C, rows, columns)` in [`Plane::ALL`] order
    /// and the occupancy logits of the whole grid (`(X, Y, Z)`, any shape of that size).
    /// No voxel gives valid empty `(0, k)` tensors.
    pub fn forward(
        &self,
        planes: &[Tensor; 3],
        occupancy_logits: &Tensor,
        voxels: &[usize],
    ) -> Result<SplatTensors> {
        let dtype = check_planes(&self.cfg, planes)?;
        let device = planes[0].device();
        let cfg = &self.cfg;
        let v = cfg.gaussians_per_voxel;
        let rows = voxels.len() * v;
        if voxels.is_empty() || v == 0 {
            let empty = |k: usize| Tensor::zeros((0, k), dtype, device);
            return Ok(SplatTensors {
                means: empty(3)?,
                log_scales: empty(3)?,
                rotations: empty(4)?,
                opacity_logits: empty(1)?,
                colors: empty(3)?,
                confidences: empty(1)?,
            });
        }
        let cells: Vec<[usize; 3]> = voxels.iter().map(|&f| voxel_at(cfg, f)).collect();
        let mut feature: Option<Tensor> = None;
        for (plane, t) in Plane::ALL.into_iter().zip(planes) {
            let ids: Vec<usize> = cells.iter().map(|&i| plane_cell(cfg, plane, i)).collect();
            let (c, r, k) = t.dims3()?;
            let table = transpose_last2(&t.reshape((1, c, r * k))?)?.squeeze(0)?;
            let f = table.index_select(&index_tensor(&ids, device)?, 0)?;
            feature = Some(match feature {
                None => f,
                Some(sum) => (sum + f)?,
            });
        }
        let x = self
            .hidden
            .forward(&feature.expect("three planes"))?
            .relu()?;
        let x = self.narrow.forward(&x)?.relu()?;
        let x = self.out.forward(&x)?.reshape((rows, GAUSSIAN_PARAMS))?;
        let part = |from: usize, n: usize| x.narrow(1, from, n);

        let size = cfg.cell_size();
        let per_axis = |f: &dyn Fn(f64) -> f64| -> Result<Tensor> {
            let values = size.map(|s| f(s as f64) as f32).to_vec();
            Tensor::from_vec(values, (1, 3), device)?.to_dtype(dtype)
        };
        let centres: Vec<f32> = cells
            .iter()
            .flat_map(|&i| std::iter::repeat_n(cfg.cell_centre(i), v))
            .flatten()
            .collect();
        let centres = Tensor::from_vec(centres, (rows, 3), device)?.to_dtype(dtype)?;
        let offsets = part(0, 3)?
            .tanh()?
            .broadcast_mul(&per_axis(&|s| MAX_OFFSET * s)?)?;
        let means = (centres + offsets)?;
        let log_scales =
            log_sigmoid(&part(3, 3)?)?.broadcast_add(&per_axis(&|s| (MAX_SCALE * s).ln())?)?;

        let identity = Tensor::new(&[1f32, 0., 0., 0.], device)?
            .to_dtype(dtype)?
            .reshape((1, 4))?;
        let raw = part(6, 4)?.broadcast_add(&identity)?;
        // Divided by its largest component first (a constant: the direction, and so the
        // gradient, is the same), so squaring never overflows.
        let largest = (raw.abs()?.max_keepdim(1)?.detach() + 1e-30)?;
        let raw = raw.broadcast_div(&largest)?;
        let norm = (raw.sqr()?.sum_keepdim(1)? + 1e-12)?.sqrt()?;
        let rotations = raw.broadcast_div(&norm)?;

        let colors = candle_nn::ops::sigmoid(&part(10, 3)?)?;
        let occupancy = occupancy_logits
            .flatten_all()?
            .index_select(&index_tensor(voxels, device)?, 0)?
            .reshape((voxels.len(), 1))?
            .broadcast_as((voxels.len(), v))?
            .reshape((rows, 1))?;
        let opacity_logits = product_logit(&part(13, 1)?, &occupancy)?;
        let confidences = candle_nn::ops::sigmoid(&part(14, 1)?)?;
        Ok(SplatTensors {
            means,
            log_scales,
            rotations,
            opacity_logits,
            colors,
            confidences,
        })
    }
}

/// `ln sigmoid(x) = -(max(-x, 0) + ln(1 + exp(-|x|)))`, finite for every finite `x`.
pub fn log_sigmoid(x: &Tensor) -> Result<Tensor> {
    let softplus = ((x.abs()?.neg()?.exp()? + 1.0)?.log()? + x.neg()?.relu()?)?;
    softplus.neg()
}

/// The logit of `sigmoid(a) sigmoid(b)`: `-logsumexp(-a, -b, -a - b)`, computed with the
/// largest term factored out (held as a constant: the gradient is the same), so it is exact
/// and finite for every finite `a`, `b`.
pub fn product_logit(a: &Tensor, b: &Tensor) -> Result<Tensor> {
    let terms = Tensor::cat(&[a.neg()?, b.neg()?, (a + b)?.neg()?], 1)?;
    let top = terms.max_keepdim(1)?.detach();
    let sum = terms.broadcast_sub(&top)?.exp()?.sum_keepdim(1)?;
    (sum.log()? + top)?.neg()
}
