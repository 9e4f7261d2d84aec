//! The renderer: shared 3D Gaussian geometry and the two rasterizers that draw it.
//!
//! It owns the types every other crate speaks (a [`GaussianSet`], a pinhole [`Camera`],
//! [`RenderOutput`]), the CPU reference rasterizer ([`cpu`], forward and backward, the oracle
//! that training differentiates through), the wgpu rasterizer ([`gpu`], forward, what the node
//! draws with), the one entry point that picks between them ([`raster`]), and file formats
//! ([`ply`] for 3DGS PLY, [`formats`] for the choice between PLY, SPZ and glTF binary with
//! `KHR_gaussian_splatting`, [`picture`] for PNG), written crash-safely through [`atomic`]. The wgpu half (`gpu`, `raster`) is the default feature `gpu`; without
//! it the crate builds without wgpu (the fuzz targets' build).
//!
//! It must not know about networks, data sets or transport: those live in `model` and `node`,
//! which depend on this crate and never the other way round.

pub mod atomic;
pub mod camera;
pub mod cpu;
pub mod formats;
pub mod gaussians;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod output;
pub mod picture;
pub mod ply;
#[cfg(feature = "gpu")]
pub mod raster;
pub mod real;
pub mod scene;

pub use camera::{Camera, CameraParams, Intrinsics};
pub use gaussians::{Gaussian, GaussianSet, SplatsView};
pub use output::{RenderOutput, RenderSettings};
#[cfg(feature = "gpu")]
pub use raster::{Raster, RenderWith};
pub use real::Real;
