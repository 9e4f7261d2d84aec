//! The StereoSplat node: transport, pipeline and the `stereosplat` command line. It sits at
//! the top of the dependency chain (`renderer` <- `model` <- `node`).
//!
//! - [`cli`]: the subcommands.
//! - [`transport`]: zenoh sessions (loopback peers by default); [`msg`]: the ROS 2 CDR wire
//!   messages and their rmw_zenoh type hashes.
//! - [`pipeline`]: time sync, binning and the worker thread that owns the reconstructor.
//! - [`fusion`]: the fused global map in the f64 world frame; [`map_eval`]: its own quality
//!   on a drive (`stereosplat eval-map`).
//! - [`pair`]: one stereo pair from files reconstructed, checked and scored
//!   (`stereosplat reconstruct`).
//! - [`view`]: the live page on loopback (splats, renders, latency charts).
//! - [`pareto`]: operating points measured side by side (`stereosplat bench pareto`).
//! - [`bag`]: MCAP logs of the node's topics; [`launch`]: graphs of processes from TOML.

pub mod bag;
#[cfg(feature = "runtime")]
pub mod cli;
pub mod fusion;
pub mod launch;
#[cfg(feature = "runtime")]
pub mod map_eval;
pub mod msg;
#[cfg(feature = "runtime")]
pub mod pair;
#[cfg(feature = "runtime")]
pub mod pareto;
#[cfg(feature = "runtime")]
pub mod pipeline;
#[cfg(feature = "runtime")]
pub mod service;
pub mod transport;
#[cfg(feature = "runtime")]
pub mod view;
