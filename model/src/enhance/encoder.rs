//! The enhancer's encoder: a stride-2 stem to 1/2 resolution, then three levels at 1/4, 1/8
//! and 1/16, each a stride-2 convolution and residual blocks. The render and the reference
//! view go through it as one batch (the same weights, as Difix's U-Net sees both views).

use candle_core::{Module, Result, Tensor};
use candle_nn::VarBuilder;

use super::Config;
use crate::net::blocks::{chain, res_blocks, ConvRelu, ResBlock};

/// Channels of the encoder's input: RGB, alpha, confidence.
pub const INPUT_CHANNELS: usize = 5;

/// The feature maps the decoder reads.
pub struct Features {
    /// Stem output at 1/2 resolution.
    pub half: Tensor,
    /// Level outputs at 1/4, 1/8 and 1/16 resolution.
    pub levels: Vec<Tensor>,
}

impl Features {
    /// Samples `start..start + len` of every map (one view's part of a joint batch).
    pub fn narrow(&self, start: usize, len: usize) -> Result<Self> {
        Ok(Self {
            half: self.half.narrow(0, start, len)?,
            levels: self
                .levels
                .iter()
                .map(|l| l.narrow(0, start, len))
                .collect::<Result<_>>()?,
        })
    }
}

/// One level: a stride-2 convolution and residual blocks.
#[derive(Clone, Debug)]
struct Level {
    down: ConvRelu,
    blocks: Vec<ResBlock>,
}

/// The encoder.
#[derive(Clone, Debug)]
pub struct Encoder {
    stem: ConvRelu,
    levels: Vec<Level>,
}

impl Encoder {
    /// The encoder of `cfg`.
    pub fn new(vb: VarBuilder, cfg: &Config) -> Result<Self> {
        let stem = ConvRelu::new(vb.pp("stem"), INPUT_CHANNELS, cfg.stem_channels, 2)?;
        let mut cin = cfg.stem_channels;
        let mut levels = Vec::with_capacity(cfg.channels.len());
        for (i, &c) in cfg.channels.iter().enumerate() {
            let vb = vb.pp(format!("level{i}"));
            levels.push(Level {
                down: ConvRelu::new(vb.pp("down"), cin, c, 2)?,
                blocks: res_blocks(vb.pp("blocks"), c, cfg.blocks)?,
            });
            cin = c;
        }
        Ok(Self { stem, levels })
    }

    /// Features of `x` `(B, 5, H, W)` (values in `[0, 1]`, mapped to `[-1, 1]` here).
    pub fn forward(&self, x: &Tensor) -> Result<Features> {
        let half = self.stem.forward(&x.affine(2.0, -1.0)?)?;
        let mut levels = Vec::with_capacity(self.levels.len());
        let mut y = half.clone();
        for level in &self.levels {
            y = chain(&level.blocks, &level.down.forward(&y)?)?;
            levels.push(y.clone());
        }
        Ok(Features { half, levels })
    }
}
