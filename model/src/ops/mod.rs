//! Differentiable operations that candle lacks, as candle custom ops with CPU kernels.
//!
//! - [`grid_sample`] / [`upsample_bilinear`]: bilinear sampling of feature maps at arbitrary
//!   points, forward and backward (candle has no grid_sample and its upsampling has no
//!   backward); the plane-sweep warp and deformable attention are built on it.
//! - [`render`]: the renderer's CPU rasterizer as an op, so losses on rendered images, depth
//!   and confidence train the network that predicts the Gaussians.
//!
//! - [`Conv`]: a convolution whose gradients are matrix products (fast on the CPU).
//! - [`transpose_last2`]: a tiled transpose (candle's strided copy of a permuted tensor is
//!   slow on the CPU).
//!
//! The kernels run on CPU tensors of `f32` (training) or `f64` (gradient checks), and the
//! sampler's also on CUDA; on other devices each op follows the rule in `crate::compute`
//! ([`grid_sample_by_gathers`] is `grid_sample` where no kernel runs). Second
//! derivatives are not supported: the gradients these ops return are not themselves
//! differentiable.

mod bilinear;
#[cfg(feature = "cuda")]
mod bilinear_cuda;
mod conv;
mod cpu;
mod gather_sample;
mod im2col;
mod render;
mod transpose;

pub use bilinear::{grid_sample, upsample_bilinear};
pub use conv::Conv;
pub use cpu::OpError;
pub use gather_sample::grid_sample_by_gathers;
pub use im2col::{im2col, Patches};
pub use render::{
    render, SplatTensors, CH_ALPHA, CH_B, CH_CONFIDENCE, CH_DEPTH, CH_G, CH_R, COL_COLOR,
    COL_CONFIDENCE, COL_LOG_SCALE, COL_MEAN, COL_OPACITY_LOGIT, COL_ROTATION, OUT_CHANNELS, PARAMS,
};
pub use transpose::transpose_last2;
