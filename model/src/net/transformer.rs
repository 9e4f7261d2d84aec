//! The multi-view transformer: in each layer, every view's 1/4-resolution features attend to
//! themselves within a window (self-attention) and then to the same window of every other
//! input view (cross-attention, where stereo correspondences sit for a rectified pair), then
//! an MLP. Any number of views goes through the same weights.
//!
//! Windows do not shift between layers (Swin's shift is left out: with 1 to 2 layers in the
//! small presets it buys little). Maps whose size is not a multiple of the window are padded
//! with zeros and cropped back; padded tokens take part in attention as zero features.

use candle_core::{Module, Result, Tensor, D};
use candle_nn::{linear, Linear, VarBuilder};

use super::Config;

/// Whether any of `tensors` takes part in a gradient. Where none does (inference), candle's
/// fused kernels run instead of the compositions of differentiable ops, which compute the
/// same function.
pub(super) fn tracked(tensors: &[&Tensor]) -> bool {
    tensors.iter().any(|t| t.track_op())
}

/// Softmax over the last dimension: candle's differentiable composition when training, its
/// fused kernel (which drops gradients) otherwise.
pub(super) fn softmax_last(x: &Tensor) -> Result<Tensor> {
    if tracked(&[x]) {
        candle_nn::ops::softmax(x, D::Minus1)
    } else {
        candle_nn::ops::softmax_last_dim(&x.contiguous()?)
    }
}

/// Layer norm over the last dimension: composed of differentiable tensor ops when training.
/// Shared with the enhancer's joint attention.
#[derive(Clone, Debug)]
pub(crate) struct Norm {
    weight: Tensor,
    bias: Tensor,
}

impl Norm {
    /// A norm over `c` features (`weight` 1, `bias` 0).
    pub(crate) fn new(vb: VarBuilder, c: usize) -> Result<Self> {
        Ok(Self {
            weight: vb.get_with_hints(c, "weight", candle_nn::Init::Const(1.0))?,
            bias: vb.get_with_hints(c, "bias", candle_nn::Init::Const(0.0))?,
        })
    }

    /// Normalises `x` over its last dimension.
    pub(crate) fn forward(&self, x: &Tensor) -> Result<Tensor> {
        if tracked(&[x, &self.weight]) {
            candle_nn::ops::layer_norm_slow(x, &self.weight, &self.bias, 1e-5)
        } else {
            candle_nn::ops::layer_norm(&x.contiguous()?, &self.weight, &self.bias, 1e-5)
        }
    }
}

/// Multi-head attention of queries `q` `(B, Tq, C)` over keys and values `(B, Tk, C)`.
/// Shared with the enhancer's joint attention.
#[derive(Clone, Debug)]
pub(crate) struct Attention {
    q: Linear,
    k: Linear,
    v: Linear,
    out: Linear,
    heads: usize,
}

impl Attention {
    /// Attention on `c` features with `heads` heads (`c` divisible by `heads`).
    pub(crate) fn new(vb: VarBuilder, c: usize, heads: usize) -> Result<Self> {
        Ok(Self {
            q: linear(c, c, vb.pp("q"))?,
            k: linear(c, c, vb.pp("k"))?,
            v: linear(c, c, vb.pp("v"))?,
            out: linear(c, c, vb.pp("out"))?,
            heads,
        })
    }

    /// Queries `x` `(B, Tq, C)` attending over `context` `(B, Tk, C)`.
    pub(crate) fn forward(&self, x: &Tensor, context: &Tensor) -> Result<Tensor> {
        let (b, tq, c) = x.dims3()?;
        let tk = context.dim(1)?;
        let dh = c / self.heads;
        let split = |t: Tensor, n: usize| {
            t.reshape((b, n, self.heads, dh))?
                .transpose(1, 2)?
                .contiguous()
        };
        let q = split(self.q.forward(x)?, tq)?;
        let k = split(self.k.forward(context)?, tk)?;
        let v = split(self.v.forward(context)?, tk)?;
        let logits = (q.matmul(&k.transpose(2, 3)?.contiguous()?)? / (dh as f64).sqrt())?;
        let weights = softmax_last(&logits)?;
        let y = weights.matmul(&v)?.transpose(1, 2)?.reshape((b, tq, c))?;
        self.out.forward(&y)
    }
}

/// One layer: self-attention, cross-attention, MLP, each pre-normed with a residual.
#[derive(Clone, Debug)]
struct Layer {
    norm_self: Norm,
    self_attn: Attention,
    norm_cross: Norm,
    cross_attn: Attention,
    norm_mlp: Norm,
    mlp_in: Linear,
    mlp_out: Linear,
}

impl Layer {
    fn new(vb: VarBuilder, c: usize, heads: usize) -> Result<Self> {
        Ok(Self {
            norm_self: Norm::new(vb.pp("norm_self"), c)?,
            self_attn: Attention::new(vb.pp("self_attn"), c, heads)?,
            norm_cross: Norm::new(vb.pp("norm_cross"), c)?,
            cross_attn: Attention::new(vb.pp("cross_attn"), c, heads)?,
            norm_mlp: Norm::new(vb.pp("norm_mlp"), c)?,
            mlp_in: linear(c, 2 * c, vb.pp("mlp_in"))?,
            mlp_out: linear(2 * c, c, vb.pp("mlp_out"))?,
        })
    }

    /// Tokens `(V, nW, T, C)`.
    fn forward(&self, t: &Tensor) -> Result<Tensor> {
        let (v, nw, tt, c) = t.dims4()?;
        let flat = |x: &Tensor| x.reshape((v * nw, tt, c));
        let x = flat(&self.norm_self.forward(t)?)?;
        let t = (t + self.self_attn.forward(&x, &x)?.reshape((v, nw, tt, c))?)?;
        let t = if v > 1 {
            let x = self.norm_cross.forward(&t)?;
            let mut out = Vec::with_capacity(v);
            for i in 0..v {
                let others: Vec<u32> = (0..v as u32).filter(|&j| j as usize != i).collect();
                let idx = Tensor::new(others.as_slice(), t.device())?;
                // (V-1, nW, T, C) -> (nW, (V-1) T, C): the window's tokens in every other view.
                let context =
                    x.index_select(&idx, 0)?
                        .transpose(0, 1)?
                        .reshape((nw, (v - 1) * tt, c))?;
                out.push(self.cross_attn.forward(&x.get(i)?, &context)?);
            }
            (&t + Tensor::stack(&out, 0)?)?
        } else {
            t
        };
        let y = self
            .mlp_out
            .forward(&self.mlp_in.forward(&self.norm_mlp.forward(&t)?)?.gelu()?)?;
        t + y
    }
}

/// The transformer: a learned position embedding inside the window, then the layers.
#[derive(Clone, Debug)]
pub struct MultiViewTransformer {
    layers: Vec<Layer>,
    position: Tensor,
    window: (usize, usize),
}

impl MultiViewTransformer {
    /// Built from the preset's layer count, heads and window, on `backbone_channels`.
    pub fn new(vb: VarBuilder, cfg: &Config) -> Result<Self> {
        let c = cfg.backbone_channels;
        let (wh, ww) = cfg.window;
        let layers = (0..cfg.transformer_layers)
            .map(|i| Layer::new(vb.pp(format!("layer{i}")), c, cfg.heads))
            .collect::<Result<_>>()?;
        let position = vb.get_with_hints(
            (wh * ww, c),
            "position",
            candle_nn::Init::Randn {
                mean: 0.0,
                stdev: 0.02,
            },
        )?;
        Ok(Self {
            layers,
            position,
            window: (wh, ww),
        })
    }

    /// Features `(V, C, h, w)` of all input views to features of the same shape.
    pub fn forward(&self, x: &Tensor) -> Result<Tensor> {
        if self.layers.is_empty() {
            return Ok(x.clone());
        }
        let (v, c, h, w) = x.dims4()?;
        let (wh, ww) = self.window;
        let (nh, nw) = (h.div_ceil(wh), w.div_ceil(ww));
        let padded = x
            .pad_with_zeros(2, 0, nh * wh - h)?
            .pad_with_zeros(3, 0, nw * ww - w)?;
        // (V, C, nh, wh, nw, ww) -> (V, nh, nw, wh, ww, C) -> (V, nW, T, C)
        let tokens = padded
            .reshape(vec![v, c, nh, wh, nw, ww])?
            .permute(vec![0, 2, 4, 3, 5, 1])?
            .reshape((v, nh * nw, wh * ww, c))?
            .broadcast_add(&self.position)?;
        let tokens = self
            .layers
            .iter()
            .try_fold(tokens, |t, layer| layer.forward(&t))?;
        tokens
            .reshape(vec![v, nh, nw, wh, ww, c])?
            .permute(vec![0, 5, 1, 3, 2, 4])?
            .reshape((v, c, nh * wh, nw * ww))?
            .narrow(2, 0, h)?
            .narrow(3, 0, w)?
            .contiguous()
    }
}
