//! A 2D convolution composed of tensor ops (im2col by one gather, then a matrix product), so that training is fast on the CPU: candle's own convolution backward runs a
//! direct transposed convolution for the input and a whole-image-kernel convolution for the
//! weights, both slow on the CPU, while here both gradients are matrix products. Weights are
//! named and shaped as candle-nn's `Conv2d` (`weight` `(out, in, k, k)`, `bias` `(out,)`),
//! so files are interchangeable. Where no gradient is tracked (inference) the columns come
//! from one parallel unrolling pass ([`super::im2col`]) with the bias folded into the product.
//! Off the CPU the convolution is candle's own (see `Conv::forward`).

use candle_core::{Module, Result, Tensor};
use candle_nn::{Init, VarBuilder};

use super::im2col::{im2col, Patches};

/// A square-kernel convolution with zero padding.
#[derive(Clone, Debug)]
pub struct Conv {
    weight: Tensor,
    bias: Option<Tensor>,
    /// Fixed weights (not variables) as the inference product's left side, made once:
    /// `(1, out, in k^2 [+ 1])`, the bias as the last column.
    folded: Option<Tensor>,
    kernel: usize,
    stride: usize,
    padding: usize,
}

impl Conv {
    /// A `kernel` x `kernel` convolution `cin -> cout`, initialised as candle-nn's (Kaiming
    /// normal weights, uniform bias within `1/sqrt(fan_in)`).
    pub fn new(
        vb: VarBuilder,
        (cin, cout): (usize, usize),
        kernel: usize,
        stride: usize,
        padding: usize,
        bias: bool,
    ) -> Result<Self> {
        let bound = 1.0 / ((cin * kernel * kernel) as f64).sqrt();
        let inits = (
            candle_nn::init::DEFAULT_KAIMING_NORMAL,
            Init::Uniform {
                lo: -bound,
                up: bound,
            },
        );
        Self::with_init(
            vb,
            (cin, cout),
            kernel,
            stride,
            padding,
            bias.then_some(inits),
        )
    }

    /// A convolution like [`Self::new`] whose weights and bias start at zero: the last layer
    /// of a residual branch that must begin as "add nothing" (ControlNet's zero convolution).
    /// The trainer's seeded initialisation keeps variables under a `zero_` name at zero.
    pub fn zeros(
        vb: VarBuilder,
        (cin, cout): (usize, usize),
        kernel: usize,
        stride: usize,
        padding: usize,
    ) -> Result<Self> {
        let zero = Init::Const(0.0);
        Self::with_init(vb, (cin, cout), kernel, stride, padding, Some((zero, zero)))
    }

    /// The convolution with `inits` (weight, bias) initialisers; `None`: no bias and Kaiming
    /// weights.
    fn with_init(
        vb: VarBuilder,
        (cin, cout): (usize, usize),
        kernel: usize,
        stride: usize,
        padding: usize,
        inits: Option<(Init, Init)>,
    ) -> Result<Self> {
        let weight_init = inits.map_or(candle_nn::init::DEFAULT_KAIMING_NORMAL, |i| i.0);
        let weight = vb.get_with_hints((cout, cin, kernel, kernel), "weight", weight_init)?;
        let bias = match inits {
            Some((_, init)) => Some(vb.get_with_hints(cout, "bias", init)?),
            None => None,
        };
        let folded = if weight.track_op() {
            None
        } else {
            let flat = weight.reshape((cout, cin * kernel * kernel))?;
            let flat = match &bias {
                Some(b) => Tensor::cat(&[&flat, &b.reshape((cout, 1))?], 1)?,
                None => flat,
            };
            Some(flat.unsqueeze(0)?)
        };
        Ok(Self {
            weight,
            bias,
            folded,
            kernel,
            stride,
            padding,
        })
    }

    /// The convolution's patch geometry.
    fn patches(&self, ones_row: bool) -> Patches {
        Patches {
            kernel: self.kernel,
            stride: self.stride,
            padding: self.padding,
            ones_row,
        }
    }

    /// `(N, k^2 C, Ho Wo)` columns of `x` `(N, C, H, W)` and the output size.
    fn columns(&self, x: &Tensor) -> Result<(Tensor, usize, usize)> {
        let (n, c, h, w) = x.dims4()?;
        let (k, s, p) = (self.kernel, self.stride, self.padding);
        if k == 1 && s == 1 && p == 0 {
            return Ok((x.reshape((n, c, h * w))?, h, w));
        }
        let (ho, wo) = self.patches(false).output_size(h, w);
        let padded = x.pad_with_zeros(2, p, p)?.pad_with_zeros(3, p, p)?;
        let wp = w + 2 * p;
        // One gather for all taps: its backward is a single scatter-add, where slicing per
        // tap would add k^2 full-size gradients.
        let mut idx = Vec::with_capacity(k * k * ho * wo);
        for dy in 0..k {
            for dx in 0..k {
                for i in 0..ho {
                    let row = (dy + s * i) * wp + dx;
                    idx.extend((0..wo).map(|j| (row + s * j) as u32));
                }
            }
        }
        let idx = Tensor::from_vec(idx, k * k * ho * wo, x.device())?;
        let flat = padded.reshape((n, c, (h + 2 * p) * wp))?;
        // (N, C, k^2 Ho Wo): channel-major then tap, the order of the weight's (C, k, k).
        let cols = flat
            .index_select(&idx, 2)?
            .reshape((n, c * k * k, ho * wo))?;
        Ok((cols, ho, wo))
    }
}

impl Module for Conv {
    fn forward(&self, x: &Tensor) -> Result<Tensor> {
        let (cout, cin, k, _) = self.weight.dims4()?;
        let n = x.dim(0)?;
        let y = if !x.device().is_cpu() {
            // Off the CPU: candle's own convolution (its im2col kernel and one matrix
            // product, its own backward), a few launches; the gather below would build and
            // upload a k^2 Ho Wo index on the host and launch about ten kernels per call.
            x.conv2d(&self.weight, self.padding, self.stride, 1, 1)?
        } else if let (Some(folded), false) = (&self.folded, x.track_op()) {
            // No gradient wanted (inference, fixed inputs to LPIPS): one parallel im2col
            // pass with a row of ones for the bias column, so no bias is added after.
            let patches = self.patches(self.bias.is_some());
            let (ho, wo) = patches.output_size(x.dim(2)?, x.dim(3)?);
            return folded
                .broadcast_matmul(&im2col(x, patches)?)?
                .reshape((n, cout, ho, wo));
        } else {
            let (cols, ho, wo) = self.columns(x)?;
            let w = self.weight.reshape((1, cout, cin * k * k))?;
            w.broadcast_matmul(&cols)?.reshape((n, cout, ho, wo))?
        };
        match &self.bias {
            Some(b) => y.broadcast_add(&b.reshape((1, cout, 1, 1))?),
            None => Ok(y),
        }
    }
}
