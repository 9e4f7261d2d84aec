//! Difix's reference mixing: the render's and the reference view's low-resolution tokens go
//! through the same self-attention together, so every render token can attend to every
//! reference token (and the reverse). No weights exist for the mixing itself: the layer is
//! plain self-attention, with or without a reference. A fixed 2D sine code tells both views'
//! tokens where in the image they sit (the same code in both views: a token can find the
//! reference content at its own image position). Layer norm and attention are the
//! multi-view transformer's (`net::transformer`).

use candle_core::{DType, Module, Result, Tensor};
use candle_nn::{linear, Linear, VarBuilder};

use crate::net::transformer::{Attention, Norm};

/// One pre-normed layer: joint self-attention then an MLP, each with a residual.
#[derive(Clone, Debug)]
pub struct JointAttention {
    norm_attn: Norm,
    attn: Attention,
    norm_mlp: Norm,
    mlp_in: Linear,
    mlp_out: Linear,
}

impl JointAttention {
    /// A layer on `c` channels with `heads` heads.
    pub fn new(vb: VarBuilder, c: usize, heads: usize) -> Result<Self> {
        Ok(Self {
            norm_attn: Norm::new(vb.pp("norm_attn"), c)?,
            attn: Attention::new(vb.pp("attn"), c, heads)?,
            norm_mlp: Norm::new(vb.pp("norm_mlp"), c)?,
            mlp_in: linear(c, 2 * c, vb.pp("mlp_in"))?,
            mlp_out: linear(2 * c, c, vb.pp("mlp_out"))?,
        })
    }

    /// Tokens `(N, T, C)` of both views (render's first) to tokens of the same shape.
    pub fn forward(&self, t: &Tensor) -> Result<Tensor> {
        let x = self.norm_attn.forward(t)?;
        let t = (t + self.attn.forward(&x, &x)?)?;
        let y = self
            .mlp_out
            .forward(&self.mlp_in.forward(&self.norm_mlp.forward(&t)?)?.gelu()?)?;
        t + y
    }
}

/// Runs `layers` over the render's and the reference's feature maps, both `(N, C, h, w)`,
/// as one token sequence per sample; returns the render's maps, `(N, C, h, w)`.
pub fn mix(layers: &[JointAttention], render: &Tensor, reference: &Tensor) -> Result<Tensor> {
    if layers.is_empty() {
        return Ok(render.clone());
    }
    let (n, c, h, w) = render.dims4()?;
    let code = position_code(h, w, c, render.dtype(), render.device())?;
    let tokens = |x: &Tensor| x.flatten_from(2)?.transpose(1, 2)?.broadcast_add(&code);
    let joint = Tensor::cat(&[tokens(render)?, tokens(reference)?], 1)?;
    let joint = layers.iter().try_fold(joint, |t, l| l.forward(&t))?;
    joint
        .narrow(1, 0, h * w)?
        .transpose(1, 2)?
        .reshape((n, c, h, w))?
        .contiguous()
}

/// A fixed 2D sine code `(h w, c)`: a quarter of the channels each for `sin`/`cos` of the
/// column and of the row at geometric frequencies (channels beyond a multiple of 4 are 0).
fn position_code(
    h: usize,
    w: usize,
    c: usize,
    dtype: DType,
    device: &candle_core::Device,
) -> Result<Tensor> {
    let quarter = c / 4;
    let mut data = vec![0f32; h * w * c];
    for y in 0..h {
        for x in 0..w {
            let row = &mut data[(y * w + x) * c..][..c];
            for k in 0..quarter {
                let f = 1.0 / 100f32.powf(k as f32 / quarter.max(1) as f32);
                row[k] = (x as f32 * f).sin();
                row[quarter + k] = (x as f32 * f).cos();
                row[2 * quarter + k] = (y as f32 * f).sin();
                row[3 * quarter + k] = (y as f32 * f).cos();
            }
        }
    }
    Tensor::from_vec(data, (h * w, c), device)?.to_dtype(dtype)
}
