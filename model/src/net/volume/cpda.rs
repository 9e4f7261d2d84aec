//! Cross-plane deformable attention (CPDA, TPVFormer's cross-view hybrid attention): the
//! three planes act as three levels; a query samples its own plane around its own cell and
//! each other plane around the orthogonal projections of its pillar anchors, at learned
//! offsets (in cells) with learned weights per head: a softmax within each level times a
//! softmax across the levels, whose own-plane term starts high so the block begins as plane
//! self-attention. Offsets and weights come from the query plus its positional code; the
//! result is projected and added to the query. This is how context reaches cells whose
//! pillars no view sees.

use candle_core::{Module, Result, Tensor};
use candle_nn::{linear, Linear, VarBuilder};

use super::anchors::plane_references;
use super::deformable::{offset_spread, project_channels, weighted_sum, zero_linear};
use super::{Plane, VolumeConfig};
use crate::net::transformer::softmax_last;
use crate::ops::grid_sample;

/// The initial level logit of a query's own plane (the others start at 0): about 96 % of
/// the weight stays on the own plane at first.
const OWN_PLANE_LOGIT: f64 = 4.0;

/// The projections and constant references of the queries of one plane.
#[derive(Clone, Debug)]
struct PlaneHeads {
    offsets: Linear,
    within: Linear,
    levels: Linear,
    level_bias: Tensor,
    /// `(N, heads, 3, P, 2)`: where the points sit before the learned offsets, the
    /// references (pixels of each level's tensor, levels in [`Plane::ALL`] order) plus
    /// Deformable-DETR's spread.
    start: Tensor,
}

/// Cross-plane deformable attention.
#[derive(Clone, Debug)]
pub struct CrossPlaneAttention {
    planes: [PlaneHeads; 3],
    value: Linear,
    out: Linear,
    heads: usize,
    points: usize,
    shapes: [(usize, usize); 3],
}

impl CrossPlaneAttention {
    /// The block of `cfg` (channels, heads, plane points, pillars) under `vb`: per query
    /// plane (`xz`, `xy`, `zy`) offset and weight projections starting at zero, shared value
    /// and output projections.
    pub fn new(vb: VarBuilder, cfg: &VolumeConfig) -> Result<Self> {
        let (c, heads, p) = (cfg.channels, cfg.heads, cfg.plane_points.max(1));
        let (dtype, device) = (vb.dtype(), vb.device().clone());
        let names = ["xz", "xy", "zy"];
        let one = |i: usize| -> Result<PlaneHeads> {
            let vb = vb.pp(names[i]);
            let query = Plane::ALL[i];
            let references = (0..3)
                .map(|l| plane_references(cfg, query, Plane::ALL[l], p, dtype, &device))
                .collect::<Result<Vec<_>>>()?;
            let references = Tensor::stack(&references, 1)?; // (N, 3, P, 2)
            let spread =
                offset_spread(heads, 3, p, dtype, &device)?.reshape((1, heads, 3, p, 2))?;
            let start = references
                .unsqueeze(1)?
                .broadcast_add(&spread)?
                .contiguous()?;
            let mut bias = vec![0.0; heads * 3];
            for h in 0..heads {
                bias[h * 3 + i] = OWN_PLANE_LOGIT;
            }
            Ok(PlaneHeads {
                offsets: zero_linear(vb.pp("offsets"), c, heads * 3 * p * 2)?,
                within: zero_linear(vb.pp("within"), c, heads * 3 * p)?,
                levels: zero_linear(vb.pp("levels"), c, heads * 3)?,
                level_bias: Tensor::from_vec(bias, heads * 3, &device)?.to_dtype(dtype)?,
                start,
            })
        };
        Ok(Self {
            planes: [one(0)?, one(1)?, one(2)?],
            value: linear(c, c, vb.pp("value"))?,
            out: linear(c, c, vb.pp("out"))?,
            heads,
            points: p,
            shapes: cfg.plane_shapes(),
        })
    }

    /// Queries `(N_p, C)` per plane with their positional codes (same shapes) attend to the
    /// three planes; returns the updated queries (residual included).
    pub fn forward(&self, queries: &[Tensor; 3], positions: &[Tensor; 3]) -> Result<[Tensor; 3]> {
        let c = queries[0].dim(1)?;
        let (heads, p) = (self.heads, self.points);
        let dh = c / heads;
        // Each plane's values as a (heads, dh, rows, cols) map to sample.
        let values = (0..3)
            .map(|l| {
                let (rows, cols) = self.shapes[l];
                project_channels(&self.value, &queries[l].t()?.unsqueeze(0)?)?
                    .reshape((heads, dh, rows, cols))
            })
            .collect::<Result<Vec<_>>>()?;
        let one = |i: usize| -> Result<Tensor> {
            let planes = &self.planes[i];
            let q = &queries[i];
            let n = q.dim(0)?;
            let key = (q + &positions[i])?;
            // (N, heads, 3, P, 2) -> (3, heads, N, P, 2): cells around each reference.
            let grids = (planes.offsets.forward(&key)?.reshape((n, heads, 3, p, 2))?
                + &planes.start)?
                .permute((2, 1, 0, 3, 4))?
                .contiguous()?;
            let within = softmax_last(&planes.within.forward(&key)?.reshape((n, heads, 3, p))?)?;
            let across = softmax_last(
                &planes
                    .levels
                    .forward(&key)?
                    .broadcast_add(&planes.level_bias)?
                    .reshape((n, heads, 3))?,
            )?;
            // (3, heads, N, P)
            let weights = within
                .broadcast_mul(&across.unsqueeze(3)?)?
                .permute((2, 1, 0, 3))?
                .contiguous()?;
            let parts: Vec<Tensor> = values
                .iter()
                .enumerate()
                .map(|(l, value)| {
                    let samples = grid_sample(value, &grids.get(l)?)?.unsqueeze(0)?;
                    weighted_sum(&samples, &weights.get(l)?)
                })
                .collect::<Result<_>>()?;
            let attended = ((&parts[0] + &parts[1])? + &parts[2])?
                .reshape((c, n))?
                .t()?;
            q + self.out.forward(&attended)?
        };
        Ok([one(0)?, one(1)?, one(2)?])
    }
}
