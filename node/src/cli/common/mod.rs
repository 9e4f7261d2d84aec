//! What the commands share: flag groups (method, operating point, pose source, zenoh),
//! flag values in the node's units, generated drives, the scene source, the shader cache,
//! the shutdown signal and progress bars.

pub mod drives;
pub mod method_args;
pub mod operating_args;
pub mod pose_args;
#[cfg(unix)]
pub mod scene_source;
pub mod shader_cache;
pub mod shutdown;
pub mod units;
pub mod zenoh_args;
