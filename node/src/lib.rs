//! The StereoSplat node: transport, pipeline and the `stereosplat` command line.
//!
//! [`cli`] holds the subcommands; [`pipeline`] the transport-free stages of the streaming
//! node (time sync, binning). Zenoh in and out, the worker and the global map arrive with the
//! streaming node's issue. It sits at the top of the dependency chain (`renderer` <- `model`
//! <- `node`).

pub mod bag;
pub mod cli;
pub mod fusion;
pub mod launch;
pub mod msg;
pub mod pipeline;
pub mod transport;
