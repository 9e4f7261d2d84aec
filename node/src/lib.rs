//! The StereoSplat node: transport, pipeline and the `stereosplat` command line.
//!
//! For now it holds the command line's rendering and benchmark subcommands ([`cli`]); the
//! streaming node (zenoh in and out, binning, worker, global map) arrives with its issue.
//! It sits at the top of the dependency chain (`renderer` <- `model` <- `node`).

pub mod cli;
pub mod msg;
