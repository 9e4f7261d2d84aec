//! The streaming node: zenoh subscribers feed the synchroniser and the binner, each bin's
//! first stereo pair goes to the worker, and every finished bin is published (its map in the
//! bin frame, the bin's world pose, its latency) and fused into the global map, which is
//! exported when the node stops.

pub mod counters;
mod inputs;
pub mod keys;
pub mod latency_stats;
pub mod loopback;
pub mod node;
mod outputs;
pub mod replay;

pub use counters::Counters;
pub use keys::Keys;
pub use node::{run, NodeConfig, NodeSummary, ServiceError};
pub use replay::{replay, ReplaySummary};
