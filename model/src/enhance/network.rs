//! The whole enhancer: render (RGB, alpha, confidence) and reference image in, the enhanced
//! render out, `clamp(render + residual, 0, 1)`.
//!
//! The residual's last layer starts at zero, so the untrained network is exactly the
//! identity (Difix starts from a pretrained model and near-zero skip convolutions for the
//! same reason: training begins at "change nothing"), and that layer gets gradients from the
//! first step (a gate at zero in front of a random layer would starve both). The clamp keeps
//! the output a valid image; its gradient is zero only where the output is pushed past 0 or 1.

use candle_core::{Result, Tensor};
use candle_nn::VarBuilder;

use super::decoder::Decoder;
use super::encoder::{Encoder, INPUT_CHANNELS};
use super::joint_attention::{mix, JointAttention};
use super::Config;

/// The one-step enhancer.
#[derive(Clone, Debug)]
pub struct Enhancer {
    encoder: Encoder,
    attention: Vec<JointAttention>,
    decoder: Decoder,
    cfg: Config,
}

impl Enhancer {
    /// The network of `cfg`, its variables under `vb`.
    pub fn new(vb: VarBuilder, cfg: &Config) -> Result<Self> {
        let c = cfg.channels[2];
        Ok(Self {
            encoder: Encoder::new(vb.pp("encoder"), cfg)?,
            attention: (0..cfg.attention_layers)
                .map(|i| JointAttention::new(vb.pp(format!("attention{i}")), c, cfg.heads))
                .collect::<Result<_>>()?,
            decoder: Decoder::new(vb.pp("decoder"), cfg)?,
            cfg: cfg.clone(),
        })
    }

    /// The preset it was built from.
    pub fn config(&self) -> &Config {
        &self.cfg
    }

    /// Enhances `render` `(N, 5, H, W)` (RGB, alpha, confidence, all in `[0, 1]`) with the
    /// reference view `reference` `(N, 3, H, W)` (RGB in `[0, 1]`, same size): `(N, 3, H,
    /// W)` in `[0, 1]`. One fixed step, no noise.
    pub fn forward(&self, render: &Tensor, reference: &Tensor) -> Result<Tensor> {
        let (n, c, h, w) = render.dims4()?;
        if c != INPUT_CHANNELS || reference.dims4()? != (n, 3, h, w) {
            candle_core::bail!(
                "enhancer: render {:?} must be (N, {INPUT_CHANNELS}, H, W) and reference {:?} (N, 3, H, W)",
                render.dims(),
                reference.dims()
            );
        }
        let ones = Tensor::ones((n, 2, h, w), reference.dtype(), reference.device())?;
        let reference = Tensor::cat(&[reference, &ones], 1)?;
        let both = self
            .encoder
            .forward(&Tensor::cat(&[render, &reference], 0)?)?;
        let deepest = both.levels.last().expect("three levels");
        let mixed = mix(
            &self.attention,
            &deepest.narrow(0, 0, n)?,
            &deepest.narrow(0, n, n)?,
        )?;
        let residual = self.decoder.forward(&both.narrow(0, n)?, &mixed, render)?;
        (render.narrow(1, 0, 3)? + residual)?.clamp(0.0, 1.0)
    }
}
