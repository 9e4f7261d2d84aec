//! The enhancer's decoder: from 1/16 back to full resolution, each step a bilinear upsampling
//! (`ops::upsample_bilinear`, which has a backward pass), the encoder's map of that size
//! concatenated (the U-Net skip), a convolution and residual blocks; at full resolution the
//! render itself is the skip, and a 3x3 head predicts the RGB residual. The head starts at
//! zero (`Conv::zeros`), so the untrained decoder adds nothing.

use candle_core::{Module, Result, Tensor};
use candle_nn::VarBuilder;

use super::encoder::{Features, INPUT_CHANNELS};
use super::Config;
use crate::net::blocks::{chain, res_blocks, ConvRelu, ResBlock};
use crate::ops::{upsample_bilinear, Conv};

/// One step up: fuse the upsampled map with the skip, then residual blocks.
#[derive(Clone, Debug)]
struct Up {
    fuse: ConvRelu,
    blocks: Vec<ResBlock>,
}

impl Up {
    fn new(vb: VarBuilder, cin: usize, cskip: usize, cout: usize, blocks: usize) -> Result<Self> {
        Ok(Self {
            fuse: ConvRelu::new(vb.pp("fuse"), cin + cskip, cout, 1)?,
            blocks: res_blocks(vb.pp("blocks"), cout, blocks)?,
        })
    }

    /// `x` upsampled to `skip`'s size, joined with it, fused.
    fn forward(&self, x: &Tensor, skip: &Tensor) -> Result<Tensor> {
        let (_, _, h, w) = skip.dims4()?;
        let x = Tensor::cat(&[&upsample_bilinear(x, h, w)?, skip], 1)?;
        chain(&self.blocks, &self.fuse.forward(&x)?)
    }
}

/// The decoder.
#[derive(Clone, Debug)]
pub struct Decoder {
    ups: Vec<Up>,
    head: Conv,
}

impl Decoder {
    /// The decoder of `cfg`.
    pub fn new(vb: VarBuilder, cfg: &Config) -> Result<Self> {
        let [c0, c1, c2] = cfg.channels;
        let s = cfg.stem_channels;
        let ups = vec![
            Up::new(vb.pp("up8"), c2, c1, c1, cfg.blocks)?,
            Up::new(vb.pp("up4"), c1, c0, c0, cfg.blocks)?,
            Up::new(vb.pp("up2"), c0, s, s, 0)?,
            Up::new(vb.pp("up1"), s, INPUT_CHANNELS, s, 0)?,
        ];
        Ok(Self {
            ups,
            head: Conv::zeros(vb.pp("zero_head"), (s, 3), 3, 1, 1)?,
        })
    }

    /// The RGB residual `(N, 3, H, W)` from the render's features (the deepest already
    /// mixed with the reference) and the render itself `(N, 5, H, W)`.
    pub fn forward(&self, f: &Features, deepest: &Tensor, render: &Tensor) -> Result<Tensor> {
        let skips = [&f.levels[1], &f.levels[0], &f.half, render];
        let x = self
            .ups
            .iter()
            .zip(skips)
            .try_fold(deepest.clone(), |x, (up, skip)| up.forward(&x, skip))?;
        self.head.forward(&x)
    }
}
