//! Clients of a running node over zenoh: [`replay()`] of a KITTI-360-layout sequence onto its
//! input topics, [`record()`] of its topics to MCAP and [`replay_bag()`] of such a recording,
//! [`monitor()`] of its latency, and [`loopback`], a drive through a node in this process.

pub mod loopback;
pub mod monitor;
pub mod record;
pub mod replay;
pub mod replay_bag;

pub use monitor::{monitor, MonitorEvent, MonitorReport};
pub use record::{channel_of, record, LogError, RecordLimits, RecordSummary};
pub use replay::{replay, ReplaySummary, UnreadFrame};
pub use replay_bag::{replay_bag, BagReplayOptions, BagReplaySummary};
