//! What the two deformable attentions share: Deformable-DETR's initialisation (offset and
//! weight projections that start at zero, around a fixed spread of sampling directions per
//! head), a projection applied to channel-first maps, and the weighted sum of sampled points.

use candle_core::{DType, Device, Result, Tensor};
use candle_nn::{Init, Linear, VarBuilder};

/// A linear layer `inputs -> outputs` whose weight and bias start at zero (Deformable-DETR's
/// sampling-offset and attention-weight projections).
pub(super) fn zero_linear(vb: VarBuilder, inputs: usize, outputs: usize) -> Result<Linear> {
    let weight = vb.get_with_hints((outputs, inputs), "weight", Init::Const(0.0))?;
    let bias = vb.get_with_hints(outputs, "bias", Init::Const(0.0))?;
    Ok(Linear::new(weight, Some(bias)))
}

/// Deformable-DETR's initial sampling offsets as a constant `(heads * groups * points * 2)`
/// added to the (zero-initialised) offset projection: head `h` looks along direction
/// `theta_h = 2 pi h / heads` (scaled so its larger component is 1), point `k` of each group
/// `k + 1` units out. A constant rather than the bias's initial value, so that it holds for
/// weights loaded from a file too; the gradient is the same.
pub(super) fn offset_spread(
    heads: usize,
    groups: usize,
    points: usize,
    dtype: DType,
    device: &Device,
) -> Result<Tensor> {
    let mut data = Vec::with_capacity(heads * groups * points * 2);
    for h in 0..heads {
        let theta = 2.0 * std::f64::consts::PI * h as f64 / heads as f64;
        let (x, y) = (theta.cos(), theta.sin());
        let m = x.abs().max(y.abs());
        for _ in 0..groups {
            for k in 0..points {
                let s = (k + 1) as f64 / m;
                data.extend([x * s, y * s]);
            }
        }
    }
    Tensor::from_vec(data, heads * groups * points * 2, device)?.to_dtype(dtype)
}

/// `linear` applied to the channels of channel-first maps `(B, C_in, ...)`, giving `(B,
/// C_out, ...)` (the weight multiplies from the left, so no transpose of the maps).
pub(super) fn project_channels(linear: &Linear, x: &Tensor) -> Result<Tensor> {
    let dims = x.dims().to_vec();
    let (b, c) = (dims[0], dims[1]);
    let rest: usize = dims[2..].iter().product();
    let y = linear
        .weight()
        .broadcast_matmul(&x.reshape((b, c, rest))?)?;
    let y = match linear.bias() {
        Some(bias) => y.broadcast_add(&bias.unsqueeze(1)?)?,
        None => y,
    };
    let mut out = dims;
    out[1] = linear.weight().dim(0)?;
    y.reshape(out)
}

/// The weighted sum over the last axis of `samples` `(B, heads, dh, N, P)` with `weights`
/// `(heads, N, P)`: `(B, heads, dh, N)`. The sum over the short last axis is a product with
/// a column of ones: candle's matmul does it about twice as fast as its `sum`.
pub(super) fn weighted_sum(samples: &Tensor, weights: &Tensor) -> Result<Tensor> {
    let (heads, n, p) = weights.dims3()?;
    let (b, _, dh, _, _) = samples.dims5()?;
    let ones = Tensor::ones((p, 1), samples.dtype(), samples.device())?;
    samples
        .broadcast_mul(&weights.reshape((1, heads, 1, n, p))?)?
        .reshape((b * heads * dh * n, p))?
        .matmul(&ones)?
        .reshape((b, heads, dh, n))
}
