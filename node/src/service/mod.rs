//! The streaming node: zenoh subscribers feed the synchroniser and the binner, each bin's
//! first stereo pair goes to the worker, and every finished bin is published (its map in the
//! bin frame, the bin's world pose, its latency) and fused into the global map, which is
//! checkpointed as it grows, resumed after a restart and exported when the node stops
//! ([`crate::store`]). Inputs beyond the [`InputLimits`] are refused and counted; the
//! snapshot queryable answers through a [`snapshot_gate::SnapshotGate`]; [`LatencyStats`]
//! summarises the per-bin latency the node publishes.

pub mod error;
mod fused_map;
mod held;
mod input_image;
mod input_thread;
pub(crate) mod inputs;
pub mod latency_stats;
pub mod limits;
pub mod node;
mod outputs;
mod pace;
mod pose_topics;
pub mod region;
pub mod snapshot_gate;
mod snapshot_reply;
mod start_report;
pub mod static_frames;
mod unusable;
mod workers;

pub use error::ServiceError;
pub use held::MAX_HELD_BINS;
pub use latency_stats::{LatencyStats, LatencySummary, StageSummary};
pub use limits::{InputLimits, Refusal};
pub use node::{run, run_announced, run_with, NodeConfig, WorkersConfig, DEFAULT_QUEUE};
pub use outputs::NodeSummary;
