//! The columns of a convolution for inference: every input patch unrolled into a column, in
//! one parallel pass over CPU memory, with an optional row of ones so the bias rides in the
//! matrix product. The differentiable im2col in [`super::Conv`] is a gather whose backward
//! is one scatter-add; where no gradient is wanted that gather and the separate bias add
//! took half of a reconstruction's profile, so inference uses this kernel instead.

use candle_core::{CpuStorage, CustomOp1, Layout, Result, Shape, Tensor};
use rayon::prelude::*;

use super::cpu::{float_dtype, float_kernel, slice, Float, OpError};

/// Geometry of a square-kernel convolution with zero padding.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Patches {
    /// Kernel size.
    pub kernel: usize,
    /// Stride.
    pub stride: usize,
    /// Zero padding on every side.
    pub padding: usize,
    /// Whether a last row of ones is appended (for a bias column in the weights).
    pub ones_row: bool,
}

impl Patches {
    /// Output rows and columns of an `h` x `w` input.
    pub fn output_size(&self, h: usize, w: usize) -> (usize, usize) {
        let (k, s, p) = (self.kernel, self.stride, self.padding);
        (
            (h + 2 * p).saturating_sub(k) / s + 1,
            (w + 2 * p).saturating_sub(k) / s + 1,
        )
    }
}

/// The columns of `x` `(N, C, H, W)`: `(N, C k^2 [+ 1], Ho Wo)`, row `c k^2 + dy k + dx`
/// holding input `(c, s i + dy - p, s j + dx - p)` at column `i Wo + j` (zero outside), the
/// order of a `(out, C, k, k)` weight; with `ones_row`, a last row of ones. No gradient.
pub fn im2col(x: &Tensor, patches: Patches) -> Result<Tensor> {
    let (_, _, h, w) = x.dims4()?;
    let reach = |n: usize| n + 2 * patches.padding >= patches.kernel;
    if patches.kernel == 0 || patches.stride == 0 || !reach(h) || !reach(w) {
        return Err(OpError::shape(
            "im2col",
            format!("input {:?} too small for {patches:?}", x.dims()),
        ));
    }
    x.contiguous()?.apply_op1_no_bwd(&patches)
}

impl Patches {
    fn run<T: Float>(&self, x: &[T], (n, c, h, w): (usize, usize, usize, usize)) -> Vec<T> {
        let (k, s, p) = (self.kernel, self.stride, self.padding);
        let (ho, wo) = self.output_size(h, w);
        let plane = ho * wo;
        let rows = c * k * k + usize::from(self.ones_row);
        let mut out = vec![T::zero(); n * rows * plane];
        out.par_chunks_mut(plane).enumerate().for_each(|(r, dst)| {
            let (b, row) = (r / rows, r % rows);
            if row == c * k * k {
                dst.fill(T::one());
                return;
            }
            let (ch, tap) = (row / (k * k), row % (k * k));
            let (dy, dx) = (tap / k, tap % k);
            let src = &x[(b * c + ch) * h * w..][..h * w];
            for i in 0..ho {
                let y = (s * i + dy) as isize - p as isize;
                if y < 0 || y >= h as isize {
                    continue;
                }
                let line = &src[y as usize * w..][..w];
                let dst = &mut dst[i * wo..][..wo];
                for (j, d) in dst.iter_mut().enumerate() {
                    let xx = (s * j + dx) as isize - p as isize;
                    if xx >= 0 && xx < w as isize {
                        *d = line[xx as usize];
                    }
                }
            }
        });
        out
    }
}

impl CustomOp1 for Patches {
    fn name(&self) -> &'static str {
        "im2col"
    }

    fn cpu_fwd(&self, storage: &CpuStorage, layout: &Layout) -> Result<(CpuStorage, Shape)> {
        let dims = layout.shape().dims4()?;
        let (n, c, h, w) = dims;
        let (ho, wo) = self.output_size(h, w);
        let rows = c * self.kernel * self.kernel + usize::from(self.ones_row);
        let out = float_kernel!(float_dtype("im2col", &[storage])?, T => {
            self.run::<T>(slice("im2col", storage, layout)?, dims)
        });
        Ok((out, Shape::from((n, rows, ho * wo))))
    }
}
