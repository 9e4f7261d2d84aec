//! The CPU reference rasterizer: the standard EWA splatting of 3DGS (as the original 3DGS and
//! gsplat define it), forward and backward, in plain Rust over slices, parallel over tiles.
//!
//! It is the oracle: the wgpu rasterizer is tested against it stage by stage, and the model
//! trains through its backward pass. It is generic over [`crate::Real`] so the same code runs
//! in `f32` (speed) and `f64` (finite-difference gradient checks).
//!
//! Stages, each a module: [`mod@project`] (3D Gaussian to screen-space conic, depth and tile
//! rectangle), [`tiles`] (which Gaussians touch which 16x16 tile, depth sorted),
//! [`composite`] (front-to-back blending per pixel), and [`mod@backward`] (gradients);
//! [`visibility`] sums each Gaussian's blend weight over a view.

pub mod backward;
pub mod composite;
pub mod math;
pub mod project;
pub mod tiles;
pub mod visibility;

pub use backward::{backward, OutputGrads, SplatGrads};
pub use composite::{render, ForwardPass};
pub use project::{project, Projected};
pub use tiles::TileBins;
pub use visibility::blend_weights;

/// Tile edge in pixels: the screen is cut into square tiles of this size, each composited
/// from its own depth-sorted list of Gaussians.
pub const TILE_SIZE: u32 = 16;
/// Alpha is clamped to this from above so transmittance never reaches zero in one step.
pub const MAX_ALPHA: f64 = 0.99;
/// Contributions with alpha below this are skipped (1/255, invisible in 8-bit output).
pub const MIN_ALPHA: f64 = 1.0 / 255.0;
/// A pixel stops compositing once its transmittance would fall below this.
pub const MIN_TRANSMITTANCE: f64 = 1e-4;
/// Screen-space dilation added to the projected covariance, px^2 (low-pass filter).
pub const COV2D_DILATION: f64 = 0.3;
