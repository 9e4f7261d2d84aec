//! The triplane encoder (TPVFormer's, with the paper's pose code): the learned plane queries
//! (plus the cost-volume prior when given) go through the preset's layers, post-norm:
//! hybrid = cross-plane attention -> LN -> cross-image attention -> LN -> FFN -> LN,
//! self = cross-plane attention -> LN -> FFN -> LN. The views' features are projected to the
//! plane channels once and carry their pose code PE(T_i).

use std::collections::HashMap;

use candle_core::{DType, Module, Result, Tensor};
use candle_nn::{linear, Linear, VarBuilder, VarMap};
use renderer::Camera;

use super::anchors::ViewAnchors;
use super::cida::CrossImageAttention;
use super::cpda::CrossPlaneAttention;
use super::deformable::project_channels;
use super::pose_encoding::PoseEncoding;
use super::queries::{PlaneQueries, Planes};
use super::{VolumeConfig, VolumeLayer};
use crate::net::transformer::Norm;
use crate::net::Config;

/// One post-norm layer; `image` is `None` for a self-only layer.
#[derive(Clone, Debug)]
struct Layer {
    planes: CrossPlaneAttention,
    norm_planes: Norm,
    image: Option<(CrossImageAttention, Norm)>,
    ffn_in: Linear,
    ffn_out: Linear,
    norm_ffn: Norm,
}

impl Layer {
    fn new(vb: VarBuilder, cfg: &VolumeConfig, kind: VolumeLayer) -> Result<Self> {
        let c = cfg.channels;
        let image = match kind {
            VolumeLayer::Hybrid => Some((
                CrossImageAttention::new(vb.pp("image"), cfg)?,
                Norm::new(vb.pp("norm_image"), c)?,
            )),
            VolumeLayer::SelfOnly => None,
        };
        Ok(Self {
            planes: CrossPlaneAttention::new(vb.pp("planes"), cfg)?,
            norm_planes: Norm::new(vb.pp("norm_planes"), c)?,
            image,
            ffn_in: linear(c, cfg.ffn_channels, vb.pp("ffn_in"))?,
            ffn_out: linear(cfg.ffn_channels, c, vb.pp("ffn_out"))?,
            norm_ffn: Norm::new(vb.pp("norm_ffn"), c)?,
        })
    }

    fn forward(
        &self,
        tokens: &[Tensor; 3],
        positions: &[Tensor; 3],
        views: Option<(&Tensor, &[ViewAnchors; 3])>,
    ) -> Result<[Tensor; 3]> {
        // Norms and the FFN act on each token alone: all planes' tokens go through at once.
        let sizes = tokens.each_ref().map(|t| t.dim(0).unwrap_or(0));
        let join = |t: &[Tensor; 3]| Tensor::cat(t, 0);
        let split = |t: &Tensor| -> Result<[Tensor; 3]> {
            Ok([
                t.narrow(0, 0, sizes[0])?,
                t.narrow(0, sizes[0], sizes[1])?,
                t.narrow(0, sizes[0] + sizes[1], sizes[2])?,
            ])
        };
        let mut t = self
            .norm_planes
            .forward(&join(&self.planes.forward(tokens, positions)?)?)?;
        if let (Some((attention, norm)), Some((features, anchors))) = (&self.image, views) {
            t = norm.forward(&join(&attention.forward(
                &split(&t)?,
                features,
                anchors,
            )?)?)?;
        }
        let y = self.ffn_out.forward(&self.ffn_in.forward(&t)?.relu()?)?;
        split(&self.norm_ffn.forward(&(t + y)?)?)
    }
}

/// The triplane encoder of a preset.
#[derive(Clone, Debug)]
pub struct TriplaneEncoder {
    queries: PlaneQueries,
    input: Linear,
    pose: PoseEncoding,
    layers: Vec<Layer>,
    cfg: VolumeConfig,
}

impl TriplaneEncoder {
    /// The encoder of `cfg.volume` under `vb` (`queries`, `input`, `layer{i}`), reading
    /// view features of `cfg.cost_channels` channels (the cost-volume branch's per-view
    /// features before their normalisation).
    pub fn new(vb: VarBuilder, cfg: &Config) -> Result<Self> {
        let v = &cfg.volume;
        if v.heads == 0 || !v.channels.is_multiple_of(v.heads) {
            candle_core::bail!(
                "volume channels {} must be a multiple of its heads {}",
                v.channels,
                v.heads
            );
        }
        let layers = v
            .layers
            .iter()
            .enumerate()
            .map(|(i, &kind)| Layer::new(vb.pp(format!("layer{i}")), v, kind))
            .collect::<Result<_>>()?;
        Ok(Self {
            queries: PlaneQueries::new(vb.pp("queries"), v)?,
            input: linear(cfg.cost_channels, v.channels, vb.pp("input"))?,
            pose: PoseEncoding::new(v, v.channels),
            layers,
            cfg: v.clone(),
        })
    }

    /// The encoder of `cfg` with fresh random weights held as plain tensors (no gradient
    /// tracked, so the inference kernels run), and its parameter count: what a benchmark
    /// times before trained weights exist.
    pub fn untrained(cfg: &Config) -> Result<(Self, usize)> {
        let varmap = VarMap::new();
        let device = cfg.device.open()?;
        Self::new(VarBuilder::from_varmap(&varmap, DType::F32, &device), cfg)?;
        let weights: HashMap<String, Tensor> = varmap
            .data()
            .lock()
            .map_err(|_| candle_core::Error::Msg("variable map poisoned".into()))?
            .iter()
            .map(|(k, v)| (k.clone(), v.as_tensor().detach()))
            .collect();
        let parameters = weights.values().map(|t| t.elem_count()).sum();
        let vb = VarBuilder::from_tensors(weights, DType::F32, &device);
        Ok((Self::new(vb, cfg)?, parameters))
    }

    /// The planes for the views' `features` `(V, cost_channels, h, w)` (feature pixel `j` at
    /// image pixel `stride j`) seen by `cameras` (bin frame, one per view), starting from the
    /// learned queries plus `prior` (the cost-volume Gaussians fused into plane shapes) when
    /// given.
    pub fn forward(
        &self,
        prior: Option<&Planes>,
        features: &Tensor,
        cameras: &[Camera],
        stride: usize,
    ) -> Result<Planes> {
        let v = features.dim(0)?;
        if v != cameras.len() || v == 0 {
            candle_core::bail!("{v} feature maps but {} cameras", cameras.len());
        }
        let (dtype, device) = (features.dtype(), features.device());
        let mut tokens = self.queries.forward();
        if let Some(prior) = prior {
            let p = prior.to_tokens()?;
            tokens = [
                (&tokens[0] + &p[0])?,
                (&tokens[1] + &p[1])?,
                (&tokens[2] + &p[2])?,
            ];
        }
        let positions = self.queries.positions()?;
        let hybrid = self.layers.iter().any(|l| l.image.is_some());
        let views = if hybrid {
            let pose = self.pose.forward(cameras, dtype, device)?;
            let values = project_channels(&self.input, features)?
                .broadcast_add(&pose.reshape((v, self.cfg.channels, 1, 1))?)?;
            let anchors = ViewAnchors::all(&self.cfg, cameras, stride, dtype, device)?;
            Some((values, anchors))
        } else {
            None
        };
        for layer in &self.layers {
            tokens = layer.forward(&tokens, &positions, views.as_ref().map(|(f, a)| (f, a)))?;
        }
        Planes::from_tokens(&self.cfg, &tokens)
    }
}
