//! The node's integration tests, one module per former test file, built as one test binary.
//!
//! Each test binary links its own copy of everything it uses from zenoh, tokio, candle and
//! wgpu, and compiles its own instances of their generic code: 29 binaries took 6 min 45 s
//! (12 min 50 s of CPU) to build on the 2-core CI machine, each streaming test about 40 s of it.
//! Two binaries stay apart, since they measure the whole process: the resident memory
//! (`whole_process`, its tests one at a time) and every allocation (`msg_fuzz`).
//!
//! Run one file's tests with `cargo test --release -p node --test integration MODULE::`.

#[path = "../cli_support/mod.rs"]
mod cli_support;
#[path = "../drive_support/mod.rs"]
mod drive_support;
#[path = "../../examples/fuzz_seeds/seeds.rs"]
mod fuzz_seeds;
#[path = "../msg_support/mod.rs"]
mod msg_support;
#[path = "../python_support/mod.rs"]
mod python_support;

use drive_support::net_support;

mod bag;
mod cli_eval;
mod cli_model;
mod cli_pareto;
mod cli_reconstruct;
mod cli_render;
mod cli_replay;
mod decoders_mutated;
#[cfg(unix)]
mod doc_blocks;
mod formats_interop;
mod foxglove_client;
mod fusion;
mod fusion_journal;
mod fusion_journal_faults;
mod fusion_keep;
mod fusion_tiles;
mod installed_binary;
#[cfg(unix)]
mod launch;
mod layers;
mod msg_codec;
mod msg_interop;
mod msg_rclpy;
mod msg_rgb;
mod node_bad_input;
mod node_budget;
mod node_crash;
mod node_disk_full;
mod node_far;
mod node_image_transports;
mod node_oversize;
mod node_pose_sources;
mod node_region;
mod node_replay;
mod node_ros2;
mod node_rosbag;
mod node_self_check;
mod node_stamps_tf;
mod node_wedge;
mod node_workers;
mod node_workers_rogue;
mod python_subscriber;
mod record;
mod rectify_opencv;
mod ros2_bridge;
mod ros2_robot;
mod ros2_transport;
mod transport;
mod transport_secure;
mod view_page;
mod worker;
