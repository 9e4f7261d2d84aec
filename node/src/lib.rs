//! The StereoSplat node: transport, pipeline and the `stereosplat` command line. It sits at
//! the top of the dependency chain (`renderer` <- `model` <- `node`) and is the one crate
//! that knows about zenoh, ROS 2 messages and the command line; the crates below it know
//! nothing of it.
//!
//! - [`cli`]: the subcommands.
//! - [`transport`]: zenoh sessions (loopback peers by default); [`msg`]: the ROS 2 CDR wire
//!   messages and their rmw_zenoh type hashes.
//! - [`pipeline`]: time sync, binning and the worker thread that owns the reconstructor;
//!   [`remote`]: bins on worker processes over zenoh.
//! - [`service`]: the running node around the pipeline, and the replay, recording and
//!   monitoring of its topics.
//! - [`fusion`]: the fused global map in the f64 world frame; [`map_eval`]: its own quality
//!   on a drive (`stereosplat eval-map`).
//! - [`rectify`]: raw camera images rectified from their `CameraInfo` (K, D, R, P), as
//!   ROS's `stereo_image_proc` does.
//! - [`pair`]: one stereo pair from files reconstructed, checked and scored
//!   (`stereosplat reconstruct`).
//! - [`view`]: the live page on loopback (splats, renders, latency charts); [`foxglove`]:
//!   the node live in Foxglove through the Foxglove SDK's WebSocket server.
//! - [`pareto`]: operating points measured side by side (`stereosplat bench pareto`).
//! - [`bag`]: MCAP logs of the node's topics; [`launch`]: graphs of processes from TOML.
//! - [`tf`]: a tf buffer of `/tf` and `/tf_static`, looked up between frames at a stamp, and
//!   the camera's pose from a body's `nav_msgs/Odometry` and the camera mount.
//! - [`error_text`]: an error and its causes as one line.
//! - [`untrusted_input`]: every decoder of outside input as one entry point on raw bytes
//!   (what the fuzz targets and the decoders' mutation test call).

#[cfg(test)]
mod alloc_probe;
pub mod bag;
#[cfg(feature = "runtime")]
pub mod cli;
pub mod error_text;
#[cfg(feature = "runtime")]
pub mod foxglove;
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
pub mod rectify;
#[cfg(feature = "runtime")]
pub mod remote;
#[cfg(feature = "runtime")]
pub mod service;
pub mod tf;
pub mod transport;
pub mod untrusted_input;
#[cfg(feature = "runtime")]
pub mod view;
