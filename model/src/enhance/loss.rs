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
    /// Difix's 1 / 1 for L2 and LPIPS. The Gram term on LPIPS's unit-normalised AlexNet
    /// features is about 5e-6 on raw renders against LPIPS's 0.2 (the first steps of
    /// `train-enhancer` on the synthetic drives), so its weight is 1e4: about a fifth of
    /// LPIPS, a say without ruling.
    fn default() -> Self {
        Self {
            l2: 1.0,
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
