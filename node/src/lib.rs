//! The StereoSplat node: transport, pipeline and the `stereosplat` command line. It sits at
//! the top of the dependency chain (`renderer` <- `model` <- `node`) and is the one crate
//! that knows about zenoh, ROS 2 messages and the command line; the crates below it know
//! nothing of it. Its modules stand in layers, each using only the layers below it
//! (`docs/architecture.md` has the table, and a test holds the code to it):
//!
//! - the node's commands: [`cli`] (what a user operates), [`research`] (generated data,
//!   training, evaluation), [`mod@bench`] (benchmarks printing JSON); [`untrusted_input`]:
//!   every decoder of outside input as one entry point on raw bytes (what the fuzz targets
//!   and the decoders' mutation test call).
//! - around a running node: [`clients`] (replay, record, monitor, a loopback drive),
//!   [`view`] (the live page on loopback), [`pair`] (one stereo pair from files,
//!   `stereosplat reconstruct`).
//! - [`service`]: the running node, its loop from inputs to published bins.
//! - [`pareto`]: operating points measured side by side (latency against quality), for
//!   `bench pareto` and the latency budget's measured table; [`progress`]: progress bars.
//! - [`store`]: the global map on disk (journal, tiles, checkpoint, resume, export);
//!   [`foxglove`]: the node live in Foxglove through the Foxglove SDK's WebSocket server.
//! - [`fusion`]: the fused global map in the f64 world frame; [`remote`]: bins on worker
//!   processes over zenoh.
//! - [`pipeline`]: time sync, binning, the worker thread that owns the reconstructor and
//!   the operating points; [`transport`]: zenoh sessions (loopback peers by default) and
//!   the node's topic table ([`transport::keys`]); [`tf`]: a tf buffer of `/tf` and
//!   `/tf_static` and the camera's pose from `nav_msgs/Odometry`; [`rectify`]: raw camera
//!   images rectified from their `CameraInfo`, as ROS's `stereo_image_proc` does; [`bag`]:
//!   MCAP logs of the node's topics; [`launch`]: graphs of processes from TOML.
//! - [`msg`]: the ROS 2 CDR wire messages and their rmw_zenoh type hashes; [`counters`]:
//!   the node's named counters; [`memory`]: the process's allocator and resident memory;
//!   [`error_text`]: an error and its causes as one line.

#[cfg(test)]
mod alloc_probe;
pub mod bag;
#[cfg(feature = "runtime")]
pub mod bench;
#[cfg(feature = "runtime")]
pub mod cli;
#[cfg(feature = "runtime")]
pub mod clients;
pub mod counters;
pub mod error_text;
#[cfg(feature = "runtime")]
pub mod foxglove;
pub mod fusion;
pub mod launch;
pub mod memory;
pub mod msg;
#[cfg(feature = "runtime")]
pub mod pair;
#[cfg(feature = "runtime")]
pub mod pareto;
#[cfg(feature = "runtime")]
pub mod pipeline;
#[cfg(feature = "runtime")]
pub mod progress;
pub mod rectify;
#[cfg(feature = "runtime")]
pub mod remote;
#[cfg(feature = "runtime")]
pub mod research;
#[cfg(feature = "runtime")]
pub mod service;
#[cfg(feature = "runtime")]
pub mod store;
pub mod tf;
pub mod transport;
pub mod untrusted_input;
#[cfg(feature = "runtime")]
pub mod view;
