//! A fast transpose of the last two dimensions, `(B, R, C) -> (B, C, R)`, made contiguous:
//! candle copies a permuted tensor element by element with its strided iterator (about
//! 7 ms for the cost-volume branch's `(2, 52, 15232)` per-Gaussian features on this
//! machine); this kernel copies in cache-sized tiles. Its backward is the same transpose of
//! the gradient.

use candle_core::{CpuStorage, CustomOp1, Layout, Result, Shape, Tensor};

use super::cpu::{float_dtype, float_kernel, slice, Float};

/// Tile side of the blocked copy (a tile of `f32` is 16 KiB; 64 measured faster than 32).
const TILE: usize = 64;

/// `x` `(B, R, C)` as the contiguous `(B, C, R)` with `out[b, c, r] = x[b, r, c]`;
/// differentiable; `f32` or `f64`. Off the CPU, candle's own strided copy (fast there).
pub fn transpose_last2(x: &Tensor) -> Result<Tensor> {
    x.dims3()?;
    if !x.device().is_cpu() {
        return x.transpose(1, 2)?.contiguous();
    }
    x.contiguous()?.apply_op1(TransposeLast2)
}

struct TransposeLast2;

impl TransposeLast2 {
    const NAME: &'static str = "transpose-last2";

    fn run<T: Float>(x: &[T], (r, c): (usize, usize)) -> Vec<T> {
        let mut out = vec![T::zero(); x.len()];
        if x.is_empty() {
            return out;
        }
        for (src, dst) in x.chunks_exact(r * c).zip(out.chunks_exact_mut(r * c)) {
            // Tiles of TILE x TILE: each output row segment is written contiguously while
            // the TILE input rows it reads stay in cache.
            for c0 in (0..c).step_by(TILE) {
                for r0 in (0..r).step_by(TILE) {
                    let r1 = (r0 + TILE).min(r);
                    for j in c0..(c0 + TILE).min(c) {
                        let row = &mut dst[j * r + r0..j * r + r1];
                        for (o, i) in row.iter_mut().zip(r0..r1) {
                            *o = src[i * c + j];
                        }
                    }
                }
            }
        }
        out
    }
}

impl CustomOp1 for TransposeLast2 {
    fn name(&self) -> &'static str {
        Self::NAME
    }

    fn cpu_fwd(&self, s: &CpuStorage, l: &Layout) -> Result<(CpuStorage, Shape)> {
        let dtype = float_dtype(Self::NAME, &[s])?;
        let (b, r, c) = l.shape().dims3()?;
        let out = float_kernel!(dtype, T => Self::run(slice::<T>(Self::NAME, s, l)?, (r, c)));
        Ok((out, Shape::from((b, c, r))))
    }

    fn bwd(&self, _arg: &Tensor, _res: &Tensor, grad: &Tensor) -> Result<Option<Tensor>> {
        Ok(Some(transpose_last2(grad)?))
    }
}
