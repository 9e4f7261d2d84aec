//! The enhancer's objective, as Difix's: image L2 + LPIPS + a Gram (style) term on the
//! LPIPS network's features (`Lpips::forward_with_style`), each averaged over the batch.

use candle_core::{Result, Tensor};

use crate::lpips::Lpips;

/// Weights of the three terms.
#[derive(Clone, Debug)]
pub struct LossWeights {
    /// Mean squared error over pixels and channels.
    pub l2: f64,
    /// LPIPS.
    pub lpips: f64,
    /// The Gram-matrix distance.
    pub style: f64,
}

impl Default for LossWeights {
    /// L2 20, LPIPS 1, Gram 1e4. Difix weighs L2 and LPIPS 1 / 1, but here L2 is about 1/20
    /// of LPIPS on raw renders, and at 1 / 1 the network trades PSNR for LPIPS; at 20 / 1
    /// the two pull about equally. The Gram term on LPIPS's unit-normalised AlexNet features
    /// is about 5e-6 against LPIPS's 0.2, so its weight 1e4 makes it about a fifth of LPIPS.
    fn default() -> Self {
        Self {
            l2: 20.0,
            lpips: 1.0,
            style: 1e4,
        }
    }
}

/// The loss and its parts.
pub struct Losses {
    /// The weighted total, differentiable.
    pub total: Tensor,
    /// Mean L2.
    pub l2: f32,
    /// Mean LPIPS.
    pub lpips: f32,
    /// Mean Gram distance.
    pub style: f32,
}

/// The objective of `output` against `target`, both `(N, 3, H, W)` in `[0, 1]`.
pub fn losses(output: &Tensor, target: &Tensor, lpips: &Lpips, w: &LossWeights) -> Result<Losses> {
    let l2 = (output - target)?.sqr()?.mean_all()?;
    let (perceptual, style) = lpips.forward_with_style(output, target)?;
    let (perceptual, style) = (perceptual.mean_all()?, style.mean_all()?);
    let total = (((&l2 * w.l2)? + (&perceptual * w.lpips)?)? + (&style * w.style)?)?;
    Ok(Losses {
        total,
        l2: l2.to_scalar()?,
        lpips: perceptual.to_scalar()?,
        style: style.to_scalar()?,
    })
}
