//! Subcommands of the `stereosplat` binary, one module each, plus what they share.

pub mod bench;
pub mod render;
pub mod scene_source;
