//! The streaming node: zenoh subscribers feed the synchroniser and the binner, each bin's
//! first stereo pair goes to the worker, and every finished bin is published (its map in the
//! bin frame, the bin's world pose, its latency) and fused into the global map, which is
//! checkpointed as it grows, resumed after a restart and exported when the node stops
//! ([`map_files`]). Inputs beyond the [`InputLimits`] are refused and counted; the snapshot
//! queryable answers through a [`snapshot_gate::SnapshotGate`].
//!
//! Around the node: [`replay()`] of a KITTI-360-layout sequence, [`record()`] of its topics to
//! MCAP and [`replay_bag()`] of such a recording, [`monitor()`] of its latency with
//! [`LatencyStats`].

pub mod counters;
pub mod error;
mod held;
mod input_image;
mod input_thread;
pub(crate) mod inputs;
pub mod keys;
pub mod latency_stats;
pub mod limits;
pub mod loopback;
pub mod map_files;
pub mod map_store;
pub mod memory;
pub mod monitor;
pub mod node;
mod outputs;
mod pace;
mod pose_topics;
pub mod record;
pub mod region;
pub mod replay;
pub mod replay_bag;
pub mod snapshot_gate;
mod snapshot_reply;
pub mod static_frames;
mod unusable;
mod workers;

pub use counters::Counters;
pub use error::ServiceError;
pub use held::MAX_HELD_BINS;
pub use keys::Keys;
pub use latency_stats::{LatencyStats, LatencySummary, StageSummary};
pub use limits::{InputLimits, Refusal};
pub use map_files::{ExportError, RestoreError, StartMap};
pub use map_store::{Compaction, Paging};
pub use monitor::{monitor, MonitorEvent, MonitorReport};
pub use node::{run, run_announced, run_with, NodeConfig, WorkersConfig, DEFAULT_QUEUE};
pub use outputs::NodeSummary;
pub use record::{channel_of, record, LogError, RecordLimits, RecordSummary};
pub use replay::{replay, ReplaySummary, UnreadFrame};
pub use replay_bag::{replay_bag, BagReplayOptions, BagReplaySummary};
