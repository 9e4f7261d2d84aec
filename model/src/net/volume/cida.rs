//! Cross-image deformable attention (CIDA, TPVFormer's image cross-attention): each plane
//! query's pillar anchors, projected into every input view ([`ViewAnchors`]), sample the
//! view's features (with the view's pose code already added) at learned offsets around the
//! anchors with learned softmax weights per head. Offsets and weights come from the query,
//! so all views share them and only the anchors' pixels differ; the result is averaged over
//! the views that see the query (a query no view sees gets nothing), projected and added to
//! the query. Any number of views, at any pose, goes through the same weights.

use candle_core::{Module, Result, Tensor};
use candle_nn::{linear, Linear, VarBuilder};

use super::anchors::{pillar_points, ViewAnchors};
use super::deformable::{offset_spread, project_channels, weighted_sum, zero_linear};
use super::{Plane, VolumeConfig};
use crate::net::transformer::softmax_last;
use crate::ops::grid_sample;

/// The offset and weight projections of the queries of one plane.
#[derive(Clone, Debug)]
struct PlaneHeads {
    offsets: Linear,
    spread: Tensor,
    weights: Linear,
    anchors: usize,
}

/// Cross-image deformable attention over the three planes.
#[derive(Clone, Debug)]
pub struct CrossImageAttention {
    planes: [PlaneHeads; 3],
    value: Linear,
    out: Linear,
    heads: usize,
    offsets_per_anchor: usize,
}

impl CrossImageAttention {
    /// The block of `cfg` (channels, heads, pillar points, offsets per anchor) under `vb`:
    /// offset and weight projections per plane (`xz`, `xy`, `zy`) starting at zero
    /// (Deformable-DETR), shared value and output projections.
    pub fn new(vb: VarBuilder, cfg: &VolumeConfig) -> Result<Self> {
        let (c, heads, k) = (cfg.channels, cfg.heads, cfg.offsets_per_anchor.max(1));
        let names = ["xz", "xy", "zy"];
        let one = |i: usize| -> Result<PlaneHeads> {
            let vb = vb.pp(names[i]);
            let anchors = pillar_points(cfg, Plane::ALL[i]);
            Ok(PlaneHeads {
                offsets: zero_linear(vb.pp("offsets"), c, heads * anchors * k * 2)?,
                spread: offset_spread(heads, anchors, k, vb.dtype(), vb.device())?,
                weights: zero_linear(vb.pp("weights"), c, heads * anchors * k)?,
                anchors,
            })
        };
        Ok(Self {
            planes: [one(0)?, one(1)?, one(2)?],
            value: linear(c, c, vb.pp("value"))?,
            out: linear(c, c, vb.pp("out"))?,
            heads,
            offsets_per_anchor: k,
        })
    }

    /// Queries `(N_p, C)` per plane attend to `features` `(V, C, h, w)` (the views' features
    /// with their pose codes, feature pixels as in `anchors`); returns the updated queries
    /// (residual included).
    pub fn forward(
        &self,
        queries: &[Tensor; 3],
        features: &Tensor,
        anchors: &[ViewAnchors; 3],
    ) -> Result<[Tensor; 3]> {
        let (v, c, h, w) = features.dims4()?;
        let dh = c / self.heads;
        let value = project_channels(&self.value, features)?.reshape((v * self.heads, dh, h, w))?;
        let one = |i: usize| -> Result<Tensor> {
            let (q, heads, anchors) = (&queries[i], &self.planes[i], &anchors[i]);
            let n = q.dim(0)?;
            let (a, k) = (heads.anchors, self.offsets_per_anchor);
            // (N, heads, A, K, 2) -> (heads, N, A, K, 2): feature pixels around each anchor.
            let offsets = heads
                .offsets
                .forward(q)?
                .broadcast_add(&heads.spread)?
                .reshape((n, self.heads, a, k, 2))?
                .transpose(0, 1)?
                .contiguous()?;
            // The anchors (constant) laid out as the grid, then the offsets added per view.
            let grid = anchors
                .pixels
                .reshape((v, 1, n, a, 1, 2))?
                .broadcast_as((v, self.heads, n, a, k, 2))?
                .contiguous()?
                .broadcast_add(&offsets.unsqueeze(0)?)?
                .reshape((v * self.heads, n, a * k, 2))?;
            // The weights are the same for every view: sum the views' samples first (as
            // adds of contiguous slices: candle's reduction over a leading axis is slow).
            let samples = grid_sample(&value, &grid)?.reshape((v, self.heads, dh, n, a * k))?;
            let samples = (1..v).try_fold(samples.narrow(0, 0, 1)?, |sum, i| {
                sum + samples.narrow(0, i, 1)?
            })?;
            let weights =
                softmax_last(&heads.weights.forward(q)?.reshape((n, self.heads, a * k))?)?
                    .transpose(0, 1)?;
            // Unseen anchors sampled zero: divided by the views that see the query, a mean.
            let attended = weighted_sum(&samples, &weights)?
                .reshape((c, n))?
                .t()?
                .broadcast_mul(&anchors.inverse_count)?;
            let update = self.out.forward(&attended)?.broadcast_mul(&anchors.seen)?;
            q + update
        };
        Ok([one(0)?, one(1)?, one(2)?])
    }
}
