//! The StereoSplat model side: the data it learns from and is judged on (KITTI-360 layout reader,
//! the synthetic street, desk and room generator, bins, metrics), the reconstructors that turn
//! stereo frames into Gaussian sets (the classical SGM baseline, [`baseline`], and the candle
//! network, [`net`], with its training, [`train`]), the differentiable candle ops the network
//! trains through ([`ops`]), the LPIPS loss and metric ([`lpips`]), the evaluation protocol of the
//! paper's section 4, loss-curve charts ([`curve`]), and the one-step enhancer of StereoSplat+ with
//! its training pairs, training and scores ([`enhance`]). The shipped weights are embedded
//! and found wherever the binary is installed ([`assets`]).
//!
//! It depends on `renderer` for the Gaussian, camera and rasterizer types and must not know
//! about transport (`node`).

#[cfg(feature = "net")]
pub mod assets;
pub mod baseline;
pub mod bins;
#[cfg(feature = "net")]
pub mod compute;
pub mod consistency;
#[cfg(feature = "charts")]
pub mod curve;
#[cfg(feature = "net")]
pub mod enhance;
#[cfg(feature = "net")]
pub mod eval;
pub mod frame;
pub mod generate;
pub mod kitti360;
#[cfg(feature = "net")]
pub mod lpips;
#[cfg(feature = "net")]
pub mod methods;
pub mod metrics;
#[cfg(feature = "net")]
pub mod net;
#[cfg(feature = "net")]
pub mod ops;
#[cfg(feature = "net")]
pub mod progressive;
pub mod reconstruct;
pub mod synth;
#[cfg(feature = "net")]
pub mod train;
