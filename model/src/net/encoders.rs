//! The two per-view encoders: the shared CNN backbone (image features at 1/4 resolution,
//! plus its 1/2-resolution features for the Gaussian heads) and the monocular geometry
//! encoder, which plays the role of the paper's Depth-Anything-V2 features (same interface:
//! one image in, geometry features at 1/4 resolution out) but is trained here.
//!
//! Every stride-2 convolution has a 3x3 kernel and padding 1, so feature pixel `i` at stride
//! `s` sits on image pixel `s * i`; the cost volume and the heads use that mapping.

use candle_core::{Module, Result, Tensor};
use candle_nn::VarBuilder;

use super::blocks::{chain, ConvRelu, ResBlock};
use super::Config;
use crate::ops::upsample_bilinear;

/// Features of a batch of views from the backbone.
pub struct BackboneFeatures {
    /// `(V, C/2, ceil(H/2), ceil(W/2))`.
    pub half: Tensor,
    /// `(V, C, h, w)` at 1/4 resolution.
    pub quarter: Tensor,
}

/// The shared image backbone.
#[derive(Clone, Debug)]
pub struct Backbone {
    stem: ConvRelu,
    down: ConvRelu,
    blocks: Vec<ResBlock>,
}

impl Backbone {
    /// Built from the preset's backbone sizes.
    pub fn new(vb: VarBuilder, cfg: &Config) -> Result<Self> {
        let c = cfg.backbone_channels;
        Ok(Self {
            stem: ConvRelu::new(vb.pp("stem"), 3, c / 2, 2)?,
            down: ConvRelu::new(vb.pp("down"), c / 2, c, 2)?,
            blocks: super::blocks::res_blocks(vb.pp("blocks"), c, cfg.backbone_blocks)?,
        })
    }

    /// Images `(V, 3, H, W)` in `[-1, 1]` to features.
    pub fn forward(&self, images: &Tensor) -> Result<BackboneFeatures> {
        let half = self.stem.forward(images)?;
        let quarter = chain(&self.blocks, &self.down.forward(&half)?)?;
        Ok(BackboneFeatures { half, quarter })
    }
}

/// The monocular geometry encoder: down to 1/8 resolution for a wider view of the scene,
/// residual blocks there, back up to 1/4.
#[derive(Clone, Debug)]
pub struct GeometryEncoder {
    down: Vec<ConvRelu>,
    blocks: Vec<ResBlock>,
    out: ConvRelu,
}

impl GeometryEncoder {
    /// Built from the preset's geometry-encoder sizes.
    pub fn new(vb: VarBuilder, cfg: &Config) -> Result<Self> {
        let c = cfg.mono_channels;
        let down = vec![
            ConvRelu::new(vb.pp("down0"), 3, c / 2, 2)?,
            ConvRelu::new(vb.pp("down1"), c / 2, c, 2)?,
            ConvRelu::new(vb.pp("down2"), c, c, 2)?,
        ];
        Ok(Self {
            down,
            blocks: super::blocks::res_blocks(vb.pp("blocks"), c, cfg.mono_blocks)?,
            out: ConvRelu::new(vb.pp("out"), c, c, 1)?,
        })
    }

    /// Images `(V, 3, H, W)` in `[-1, 1]` to `(V, mono_channels, h, w)`, `(h, w)` the
    /// backbone's 1/4 size.
    pub fn forward(&self, images: &Tensor, h: usize, w: usize) -> Result<Tensor> {
        let eighth = chain(&self.blocks, &chain(&self.down, images)?)?;
        self.out.forward(&upsample_bilinear(&eighth, h, w)?)
    }
}
