//! Which voxels the volume branch decodes (paper section 3.2.2, "model only what the scene
//! requires"): an occupancy logit per voxel, cheap for the whole grid, the voxels whose
//! centre some input camera sees, and the top-k of those by occupancy. The number of
//! Gaussians then follows the scene (at most `top_k` voxels, none outside every frustum),
//! not the grid.
//!
//! The score is a linear function of the voxel feature (the sum of its three plane cells,
//! as the decoder reads it): `w . (f_xz + f_xy + f_zy) + b = w . f_xz + w . f_xy + w . f_zy
//! + b`, so each plane is scored once and the three score maps broadcast-add over the grid.

use candle_core::{DType, Result, Tensor};
use candle_nn::{linear, Linear, VarBuilder};
use glam::DVec3;
use renderer::Camera;

use super::voxels::{check_planes, voxel_at, voxel_count};
use super::{Plane, VolumeConfig};

/// Nearest camera-frame depth at which a voxel centre counts as in front of a camera, metres
/// (the cross-image attention's visibility test uses the same).
pub const MIN_DEPTH: f64 = 1e-5;

/// The occupancy head: one linear layer `C -> 1` on the voxel feature.
#[derive(Clone, Debug)]
pub struct OccupancyHead {
    score: Linear,
    cfg: VolumeConfig,
}

impl OccupancyHead {
    /// The head for `cfg`'s channels, its weights under `vb`.
    pub fn new(vb: VarBuilder, cfg: &VolumeConfig) -> Result<Self> {
        Ok(Self {
            score: linear(cfg.channels, 1, vb.pp("score"))?,
            cfg: cfg.clone(),
        })
    }

    /// The occupancy logit of every voxel, `(X, Y, Z)` (flat order of `voxels`), from the
    /// three planes `(C, rows, columns)` in [`Plane::ALL`] order.
    pub fn forward(&self, planes: &[Tensor; 3]) -> Result<Tensor> {
        check_planes(&self.cfg, planes)?;
        let c = self.cfg.channels;
        let weight = self.score.weight(); // (1, C)
        let mut grid: Option<Tensor> = None;
        for (plane, t) in Plane::ALL.into_iter().zip(planes) {
            let (r, k) = plane.axes();
            let (rows, columns) = (self.cfg.cells[r], self.cfg.cells[k]);
            let scores = weight
                .matmul(&t.reshape((c, rows * columns))?)?
                .reshape((rows, columns))?;
            let scores = if r > k { scores.t()? } else { scores };
            let mut shape = [1; 3];
            shape[r] = rows;
            shape[k] = columns;
            let scores = scores.reshape((shape[0], shape[1], shape[2]))?;
            grid = Some(match grid {
                None => scores,
                Some(g) => g.broadcast_add(&scores)?,
            });
        }
        let [x, y, z] = self.cfg.cells;
        let grid = grid.expect("three planes").broadcast_as((x, y, z))?;
        match self.score.bias() {
            Some(b) => grid.broadcast_add(&b.reshape((1, 1, 1))?),
            None => grid.contiguous(),
        }
    }
}

/// Per voxel (flat order): whether its centre is in front of at least one of `cameras`
/// (camera-frame depth above [`MIN_DEPTH`]) and projects inside its image (pixel centres at
/// integers, so inside is `[-0.5, width - 0.5)` x `[-0.5, height - 0.5)`). Cameras are in
/// the bin frame; computed in `f64`.
pub fn frustum_mask(cfg: &VolumeConfig, cameras: &[Camera]) -> Vec<bool> {
    let mut mask = vec![false; voxel_count(cfg)];
    for camera in cameras {
        let rotation = camera.rotation.as_dmat3();
        let position = camera.position.as_dvec3();
        let k = camera.intrinsics;
        let (fx, fy, cx, cy) = (k.fx as f64, k.fy as f64, k.cx as f64, k.cy as f64);
        let (w, h) = (k.width as f64 - 0.5, k.height as f64 - 0.5);
        for (flat, seen) in mask.iter_mut().enumerate() {
            if *seen {
                continue;
            }
            let centre = DVec3::from_array(cfg.cell_centre(voxel_at(cfg, flat)).map(f64::from));
            let p = rotation * (centre - position);
            if p.z <= MIN_DEPTH {
                continue; // behind (a NaN falls through and fails the image test)
            }
            let u = fx * p.x / p.z + cx;
            let v = fy * p.y / p.z + cy;
            *seen = u >= -0.5 && u < w && v >= -0.5 && v < h;
        }
    }
    mask
}

/// The voxels to decode: among those `mask` allows, the `k` with the highest finite-or-
/// infinite logit in `logits` (any shape, flat voxel order; NaN never selected), ties broken
/// by the lower index; returned in ascending voxel order. Fewer when fewer are allowed.
pub fn top_k(logits: &Tensor, mask: &[bool], k: usize) -> Result<Vec<usize>> {
    let scores = logits
        .detach()
        .to_dtype(DType::F32)?
        .flatten_all()?
        .to_vec1::<f32>()?;
    if scores.len() != mask.len() {
        candle_core::bail!("{} logits but a mask of {}", scores.len(), mask.len());
    }
    let mut candidates: Vec<usize> = (0..scores.len())
        .filter(|&i| mask[i] && !scores[i].is_nan())
        .collect();
    // Higher score first, then lower index: a total order, so the choice is deterministic.
    let order = |a: &usize, b: &usize| scores[*b].total_cmp(&scores[*a]).then(a.cmp(b));
    if candidates.len() > k {
        if k > 0 {
            candidates.select_nth_unstable_by(k - 1, order);
        }
        candidates.truncate(k);
    }
    candidates.sort_unstable();
    Ok(candidates)
}
