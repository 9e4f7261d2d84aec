//! Bilinear sampling of `(N, C, H, W)` feature maps at arbitrary points, with gradients with
//! respect to both the maps and the points.
//!
//! **Convention.** A grid point `(x, y)` is in pixel coordinates of the input: pixel `(i, j)`
//! (column `i`, row `j`) sits at `x = i`, `y = j`, so the image spans `x` in `[0, W-1]` and
//! `y` in `[0, H-1]`. The value at `(x, y)` blends the four pixels around it with weights
//! `(1 - fx)(1 - fy)`, `fx (1 - fy)`, `(1 - fx) fy`, `fx fy` (`fx = x - floor(x)`, likewise
//! `fy`); a pixel outside the image contributes zero (zeros padding). This is PyTorch's
//! `grid_sample(mode="bilinear", padding_mode="zeros", align_corners=True)` after mapping
//! its normalised `[-1, 1]` coordinates to pixels by `x = (u + 1) (W - 1) / 2`. A point with
//! a NaN coordinate, or at or beyond one pixel outside the image (including infinities),
//! samples zero and gets a zero gradient.
//!
//! The gradient with respect to a point is the derivative of the bilinear blend; at integer
//! coordinates, where the blend has a kink, it is the one-sided derivative from the right
//! (`floor` picks the cell to the right / below).

use candle_core::{CpuStorage, CustomOp2, CustomOp3, Layout, Result, Shape, Tensor};
use rayon::prelude::*;

use super::cpu::{float_dtype, float_kernel, slice, Float, OpError};
#[cfg(feature = "cuda")]
use {super::bilinear_cuda as cuda, candle_core::CudaStorage};

/// Samples `input` `(N, C, H, W)` bilinearly at the pixel coordinates in `grid`
/// `(N, Ho, Wo, 2)` (last axis `x, y`; see the module doc for the convention), giving
/// `(N, C, Ho, Wo)`. Differentiable with respect to both `input` and `grid`; `f32` or `f64`
/// tensors of one dtype. On the CPU and on CUDA (`cuda` feature) it runs as kernels; on any
/// other device it is [`super::grid_sample_by_gathers`].
pub fn grid_sample(input: &Tensor, grid: &Tensor) -> Result<Tensor> {
    if !(input.device().is_cpu() || input.device().is_cuda()) {
        return super::grid_sample_by_gathers(input, grid);
    }
    let (n, _, h, w) = input.dims4()?;
    let (gn, _, _, two) = grid.dims4()?;
    if gn != n || two != 2 {
        return Err(OpError::shape(
            GridSample::NAME,
            format!(
                "grid {:?} must be (N, Ho, Wo, 2) with N of input {:?}",
                grid.dims(),
                input.dims()
            ),
        ));
    }
    if h == 0 || w == 0 {
        return Err(OpError::shape(
            GridSample::NAME,
            format!("input {:?} has an empty plane", input.dims()),
        ));
    }
    input
        .contiguous()?
        .apply_op2(&grid.contiguous()?, GridSample)
}

/// Resizes `x` `(N, C, H, W)` to `(N, C, out_h, out_w)` by bilinear interpolation with the
/// half-pixel convention (output pixel `i` samples input `x = (i + 0.5) W / out_w - 0.5`,
/// clamped to `[0, W - 1]`): PyTorch's `interpolate(mode="bilinear", align_corners=False)`
/// and the convention of `renderer::Intrinsics::scaled`. Built on [`grid_sample`], so it has
/// a backward pass.
pub fn upsample_bilinear(x: &Tensor, out_h: usize, out_w: usize) -> Result<Tensor> {
    let (n, _, h, w) = x.dims4()?;
    let src = |i: usize, from: usize, to: usize| {
        ((i as f64 + 0.5) * from as f64 / to as f64 - 0.5).clamp(0.0, from as f64 - 1.0)
    };
    let mut pts = Vec::with_capacity(n * out_h * out_w * 2);
    for _ in 0..n {
        for i in 0..out_h {
            for j in 0..out_w {
                pts.push(src(j, w, out_w));
                pts.push(src(i, h, out_h));
            }
        }
    }
    let grid = Tensor::from_vec(pts, (n, out_h, out_w, 2), x.device())?.to_dtype(x.dtype())?;
    grid_sample(x, &grid)
}

/// The four pixels a point blends: flat indices into an `H x W` plane, weights, and the
/// weights' derivatives with respect to `x` and `y`. Taps outside the image have zero weight
/// and derivatives (and index 0, which every non-empty plane has).
struct Taps<T> {
    idx: [usize; 4],
    w: [T; 4],
    dx: [T; 4],
    dy: [T; 4],
}

impl<T: Float> Taps<T> {
    fn new(x: T, y: T, w: usize, h: usize) -> Self {
        let zero = T::zero();
        let mut t = Self {
            idx: [0; 4],
            w: [zero; 4],
            dx: [zero; 4],
            dy: [zero; 4],
        };
        let (xf, yf) = (x.f64(), y.f64());
        // Written so that NaN fails it; bounds the floors below to small integers.
        let inside = xf > -1.0 && xf < w as f64 && yf > -1.0 && yf < h as f64;
        if !inside {
            return t;
        }
        let (x0, y0) = (x.floor(), y.floor());
        let (ax, ay) = (x - x0, y - y0);
        let (x0, y0) = (x0.f64() as i64, y0.f64() as i64);
        let one = T::one();
        for (k, (cx, cy)) in [(0, 0), (1, 0), (0, 1), (1, 1)].into_iter().enumerate() {
            let (xi, yi) = (x0 + cx, y0 + cy);
            if xi < 0 || yi < 0 || xi >= w as i64 || yi >= h as i64 {
                continue;
            }
            let (wx, sx) = if cx == 1 { (ax, one) } else { (one - ax, -one) };
            let (wy, sy) = if cy == 1 { (ay, one) } else { (one - ay, -one) };
            t.idx[k] = yi as usize * w + xi as usize;
            t.w[k] = wx * wy;
            t.dx[k] = sx * wy;
            t.dy[k] = sy * wx;
        }
        t
    }

    /// The taps of point `p` of a grid slice `(x, y, x, y, ...)`.
    fn at(grid: &[T], p: usize, w: usize, h: usize) -> Self {
        Self::new(grid[2 * p], grid[2 * p + 1], w, h)
    }

    /// The taps of every point of the grid, computed once and shared by all channels.
    fn all(grid: &[T], d: Dims) -> Vec<Self> {
        (0..grid.len() / 2)
            .into_par_iter()
            .map(|p| Self::at(grid, p, d.w, d.h))
            .collect()
    }
}

/// Sizes the three kernels share: channels, input plane, output pixels per plane.
#[derive(Clone, Copy, Debug)]
struct Dims {
    c: usize,
    h: usize,
    w: usize,
    /// Output pixels per plane, `Ho * Wo`.
    p: usize,
}

impl Dims {
    /// The sizes of an `(N, C, H, W)` input and an `(N, Ho, Wo, 2)` grid, with `N`.
    fn of(input: &Layout, grid: &Layout) -> Result<(usize, Self)> {
        let (n, c, h, w) = input.shape().dims4()?;
        let (_, ho, wo, _) = grid.shape().dims4()?;
        Ok((
            n,
            Self {
                c,
                h,
                w,
                p: ho * wo,
            },
        ))
    }

    fn hw(&self) -> usize {
        self.h * self.w
    }

    /// Runs CUDA kernel `name` of `bilinear.cu` for `op` with these sizes: `threads`
    /// threads into a new buffer of `out_len` values (`zeroed` first for a kernel that
    /// accumulates).
    #[cfg(feature = "cuda")]
    fn launch(
        &self,
        op: &'static str,
        name: &'static str,
        (threads, out_len): (usize, usize),
        zeroed: bool,
        inputs: &[(&CudaStorage, &Layout)],
    ) -> Result<CudaStorage> {
        cuda::Kernel {
            op,
            name,
            sizes: [self.c, self.h, self.w, self.p],
            threads,
            out_len,
            zeroed,
        }
        .launch(inputs)
    }
}

/// The forward op: `(input, grid) -> output`.
struct GridSample;

impl GridSample {
    const NAME: &'static str = "grid-sample";

    fn run<T: Float>(input: &[T], grid: &[T], d: Dims) -> Vec<T> {
        let taps = Taps::all(grid, d);
        let mut out = vec![T::zero(); input.len() / d.hw() * d.p];
        out.par_chunks_mut(d.p)
            .enumerate()
            .for_each(|(plane, out)| {
                let src = &input[plane * d.hw()..(plane + 1) * d.hw()];
                let taps = &taps[plane / d.c * d.p..];
                for (o, t) in out.iter_mut().zip(taps) {
                    *o = (0..4).fold(T::zero(), |s, k| s + t.w[k] * src[t.idx[k]]);
                }
            });
        out
    }
}

impl CustomOp2 for GridSample {
    fn name(&self) -> &'static str {
        Self::NAME
    }

    fn cpu_fwd(
        &self,
        s1: &CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
    ) -> Result<(CpuStorage, Shape)> {
        let (n, d) = Dims::of(l1, l2)?;
        let dtype = float_dtype(Self::NAME, &[s1, s2])?;
        let out = float_kernel!(dtype, T => Self::run(
                slice::<T>(Self::NAME, s1, l1)?,
                slice::<T>(Self::NAME, s2, l2)?,
                d,
        ));
        let (_, ho, wo, _) = l2.shape().dims4()?;
        Ok((out, Shape::from((n, d.c, ho, wo))))
    }

    #[cfg(feature = "cuda")]
    fn cuda_fwd(
        &self,
        s1: &CudaStorage,
        l1: &Layout,
        s2: &CudaStorage,
        l2: &Layout,
    ) -> Result<(CudaStorage, Shape)> {
        let (n, d) = Dims::of(l1, l2)?;
        let len = n * d.c * d.p;
        let out = d.launch(
            Self::NAME,
            "grid_sample",
            (len, len),
            false,
            &[(s1, l1), (s2, l2)],
        )?;
        let (_, ho, wo, _) = l2.shape().dims4()?;
        Ok((out, Shape::from((n, d.c, ho, wo))))
    }

    fn bwd(
        &self,
        input: &Tensor,
        grid: &Tensor,
        _res: &Tensor,
        grad: &Tensor,
    ) -> Result<(Option<Tensor>, Option<Tensor>)> {
        let grad = grad.contiguous()?;
        let (_, _, h, w) = input.dims4()?;
        let d_input = input
            .track_op()
            .then(|| grid.apply_op2_no_bwd(&grad, &InputGrad { h, w }))
            .transpose()?;
        let d_grid = grid
            .track_op()
            .then(|| input.apply_op3_no_bwd(grid, &grad, &GridGrad))
            .transpose()?;
        Ok((d_input, d_grid))
    }
}

/// Gradient with respect to the input: `(grid, d output) -> d input`, scattering each output
/// gradient onto its four taps (one thread per input plane, so no two threads write one
/// element and the sums are deterministic; the CUDA kernel adds atomically, so there the
/// order of the sums, and their last bits, may vary).
struct InputGrad {
    h: usize,
    w: usize,
}

impl InputGrad {
    const NAME: &'static str = "grid-sample-input-grad";

    /// `N` and the sizes, from the output gradient's `(N, C, Ho, Wo)` layout.
    fn dims(&self, grad: &Layout) -> Result<(usize, Dims)> {
        let (n, c, ho, wo) = grad.shape().dims4()?;
        let d = Dims {
            c,
            h: self.h,
            w: self.w,
            p: ho * wo,
        };
        Ok((n, d))
    }

    fn run<T: Float>(grid: &[T], grad: &[T], d: Dims) -> Vec<T> {
        let taps = Taps::all(grid, d);
        let mut out = vec![T::zero(); grad.len() / d.p * d.hw()];
        out.par_chunks_mut(d.hw())
            .enumerate()
            .for_each(|(plane, dst)| {
                let g = &grad[plane * d.p..(plane + 1) * d.p];
                let taps = &taps[plane / d.c * d.p..];
                for (&gp, t) in g.iter().zip(taps) {
                    for k in 0..4 {
                        dst[t.idx[k]] += t.w[k] * gp;
                    }
                }
            });
        out
    }
}

impl CustomOp2 for InputGrad {
    fn name(&self) -> &'static str {
        Self::NAME
    }

    fn cpu_fwd(
        &self,
        s1: &CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
    ) -> Result<(CpuStorage, Shape)> {
        let (n, d) = self.dims(l2)?;
        let dtype = float_dtype(Self::NAME, &[s1, s2])?;
        let out = float_kernel!(dtype, T => Self::run(
                slice::<T>(Self::NAME, s1, l1)?,
                slice::<T>(Self::NAME, s2, l2)?,
                d,
        ));
        Ok((out, Shape::from((n, d.c, self.h, self.w))))
    }

    #[cfg(feature = "cuda")]
    fn cuda_fwd(
        &self,
        s1: &CudaStorage,
        l1: &Layout,
        s2: &CudaStorage,
        l2: &Layout,
    ) -> Result<(CudaStorage, Shape)> {
        let (n, d) = self.dims(l2)?;
        let out = d.launch(
            Self::NAME,
            "grid_sample_input_grad",
            (n * d.c * d.p, n * d.c * d.hw()),
            true,
            &[(s1, l1), (s2, l2)],
        )?;
        Ok((out, Shape::from((n, d.c, self.h, self.w))))
    }
}

/// Gradient with respect to the grid: `(input, grid, d output) -> d grid`, the derivative of
/// each point's blend summed over channels.
struct GridGrad;

impl GridGrad {
    const NAME: &'static str = "grid-sample-grid-grad";

    fn run<T: Float>(input: &[T], grid: &[T], grad: &[T], d: Dims) -> Vec<T> {
        let mut out = vec![T::zero(); grid.len()];
        out.par_chunks_mut(2).enumerate().for_each(|(q, dst)| {
            let (n, p) = (q / d.p, q % d.p);
            let t = Taps::at(grid, q, d.w, d.h);
            let (mut gx, mut gy) = (T::zero(), T::zero());
            for c in 0..d.c {
                let plane = n * d.c + c;
                let src = &input[plane * d.hw()..];
                let g = grad[plane * d.p + p];
                for k in 0..4 {
                    let v = g * src[t.idx[k]];
                    gx += t.dx[k] * v;
                    gy += t.dy[k] * v;
                }
            }
            dst[0] = gx;
            dst[1] = gy;
        });
        out
    }
}

impl CustomOp3 for GridGrad {
    fn name(&self) -> &'static str {
        Self::NAME
    }

    fn cpu_fwd(
        &self,
        s1: &CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
        s3: &CpuStorage,
        l3: &Layout,
    ) -> Result<(CpuStorage, Shape)> {
        let (_, d) = Dims::of(l1, l2)?;
        let dtype = float_dtype(Self::NAME, &[s1, s2, s3])?;
        let out = float_kernel!(dtype, T => Self::run(
                slice::<T>(Self::NAME, s1, l1)?,
                slice::<T>(Self::NAME, s2, l2)?,
                slice::<T>(Self::NAME, s3, l3)?,
                d,
        ));
        Ok((out, l2.shape().clone()))
    }

    #[cfg(feature = "cuda")]
    fn cuda_fwd(
        &self,
        s1: &CudaStorage,
        l1: &Layout,
        s2: &CudaStorage,
        l2: &Layout,
        s3: &CudaStorage,
        l3: &Layout,
    ) -> Result<(CudaStorage, Shape)> {
        let (n, d) = Dims::of(l1, l2)?;
        let out = d.launch(
            Self::NAME,
            "grid_sample_grid_grad",
            (n * d.p, n * d.p * 2),
            false,
            &[(s1, l1), (s2, l2), (s3, l3)],
        )?;
        Ok((out, l2.shape().clone()))
    }
}
