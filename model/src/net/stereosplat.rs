//! The whole cost-volume branch: views in, per-view depth and per-pixel Gaussians out.

use candle_core::{Module, Result, Tensor};
use candle_nn::VarBuilder;

use crate::ops::Conv;
use renderer::Camera;

use super::blocks::conv;
use super::cost_volume::{candidate_depths, cost_volume};
use super::depth_head::{peak, DepthHead};
use super::encoders::{Backbone, GeometryEncoder};
use super::gaussian_head::{GaussianHead, HeadInputs};
use super::transformer::MultiViewTransformer;
use super::Config;
use crate::ops::{upsample_bilinear, SplatTensors};

/// Image pixels per feature pixel of the cost volume (the paper's downscale factor).
pub const COST_STRIDE: usize = 4;

/// What one forward pass predicts. The triplane branch will consume the same Gaussians and
/// `features` (its fusion is guided by the cost-volume Gaussians' positions).
pub struct Prediction {
    /// Every Gaussian, `V * Hg * Wg` rows, view-major; nothing pruned (training needs all).
    pub splats: SplatTensors,
    /// Estimated metric depth per view at the Gaussians' resolution, `(V, 1, Hg, Wg)`.
    pub depth: Tensor,
    /// Per-Gaussian features (the heads' context), `(V, k, Hg, Wg)`.
    pub features: Tensor,
}

impl Prediction {
    /// Predictions of disjoint view sets joined in order, as one prediction of all their views.
    pub fn cat(parts: &[Prediction]) -> Result<Self> {
        let cat = |f: &dyn Fn(&Prediction) -> &Tensor| {
            Tensor::cat(&parts.iter().map(f).collect::<Vec<_>>(), 0)
        };
        Ok(Self {
            splats: SplatTensors::cat(&parts.iter().map(|p| &p.splats).collect::<Vec<_>>())?,
            depth: cat(&|p| &p.depth)?,
            features: cat(&|p| &p.features)?,
        })
    }
}

/// The StereoSplat cost-volume network.
#[derive(Clone, Debug)]
pub struct StereoSplat {
    backbone: Backbone,
    geometry: GeometryEncoder,
    transformer: MultiViewTransformer,
    project: Conv,
    depth_head: DepthHead,
    gaussians: GaussianHead,
    depths: Vec<f64>,
    cfg: Config,
}

impl StereoSplat {
    /// The network of preset `cfg`, its variables under `vb`.
    pub fn new(vb: VarBuilder, cfg: &Config) -> Result<Self> {
        let context = 3 + cfg.cost_channels + cfg.backbone_channels / 2 + 1;
        Ok(Self {
            backbone: Backbone::new(vb.pp("backbone"), cfg)?,
            geometry: GeometryEncoder::new(vb.pp("geometry"), cfg)?,
            transformer: MultiViewTransformer::new(vb.pp("transformer"), cfg)?,
            project: conv(
                vb.pp("project"),
                cfg.view_channels(),
                cfg.cost_channels,
                1,
                1,
            )?,
            depth_head: DepthHead::new(vb.pp("depth_head"), cfg)?,
            gaussians: GaussianHead::new(vb.pp("gaussians"), cfg, context)?,
            depths: candidate_depths(cfg),
            cfg: cfg.clone(),
        })
    }

    /// The preset.
    pub fn config(&self) -> &Config {
        &self.cfg
    }

    /// `images` `(V, 3, H, W)` in `[0, 1]` (left and right of each pair, any order) with their
    /// `cameras` in the bin's frame, `V >= 1`.
    pub fn forward(&self, images: &Tensor, cameras: &[Camera]) -> Result<Prediction> {
        let (v, _, height, width) = images.dims4()?;
        if v != cameras.len() || v == 0 {
            candle_core::bail!("{v} images but {} cameras", cameras.len());
        }
        let x = ((images * 2.0)? - 1.0)?;
        let bb = self.backbone.forward(&x)?;
        let (_, _, h, w) = bb.quarter.dims4()?;
        let mono = self.geometry.forward(&x, h, w)?;
        let attended = self.transformer.forward(&bb.quarter)?;
        let features = self
            .project
            .forward(&Tensor::cat(&[&mono, &attended], 1)?)?;
        // Unit features: the volume holds cosine similarities, whose scale the depth head's
        // learned temperature sets (raw dot products of fresh features give a flat softmax).
        let norm = (features.sqr()?.sum_keepdim(1)? + 1e-6)?.sqrt()?;
        let unit = features.broadcast_div(&norm)?;
        let cost = cost_volume(&unit, cameras, &self.depths, &self.cfg, COST_STRIDE)?;
        let coarse = self.depth_head.forward(&cost, &features)?;

        let g = self.cfg.gaussian_stride;
        let (hg, wg) = (height.div_ceil(g), width.div_ceil(g));
        let up = |t: &Tensor| -> Result<Tensor> {
            let (_, _, th, tw) = t.dims4()?;
            if (th, tw) == (hg, wg) {
                Ok(t.clone())
            } else {
                upsample_bilinear(t, hg, wg)
            }
        };
        let image = every_nth_pixel(images, g)?;
        let confidence = up(&peak(&coarse.probabilities)?)?;
        let context = Tensor::cat(&[&image, &up(&features)?, &up(&bb.half)?, &confidence], 1)?;
        let heads = self.gaussians.forward(&HeadInputs {
            context: &context,
            image: &image,
            coarse: &up(&coarse.inverse)?,
            probabilities: &coarse.probabilities,
            cameras,
        })?;
        Ok(Prediction {
            splats: heads.splats,
            depth: heads.depth,
            features: context,
        })
    }
}

/// Pixels `(g i, g j)` of `(V, C, H, W)`: `(V, C, ceil(H/g), ceil(W/g))`, the pixels the
/// Gaussians sit on.
pub fn every_nth_pixel(x: &Tensor, g: usize) -> Result<Tensor> {
    if g == 1 {
        return Ok(x.clone());
    }
    let (_, _, h, w) = x.dims4()?;
    let pick = |n: usize| Tensor::arange_step(0u32, n as u32, g as u32, x.device());
    x.index_select(&pick(h)?, 2)?.index_select(&pick(w)?, 3)
}
