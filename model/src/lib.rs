//! The StereoSplat model: candle networks that turn stereo frames into Gaussian sets, their
//! training, and the data they learn from (KITTI-360 layout readers, the synthetic street
//! generator, binning, metrics).
//!
//! Nothing is here yet: the data issue and the model issue fill it. It depends on `renderer`
//! for the Gaussian and camera types and must not know about transport (`node`).
