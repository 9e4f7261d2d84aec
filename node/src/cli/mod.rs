//! Subcommands of the `stereosplat` binary, one module each, plus what they share.

pub mod bench;
pub mod bench_check;
pub mod bench_drive;
pub mod bench_export;
pub mod bench_fusion;
pub mod bench_keep_up;
pub mod bench_model;
pub mod bench_node;
pub mod bench_pareto;
pub mod bench_view;
pub mod bench_workers;
pub mod demo;
pub mod enhancer_data;
pub mod eval;
pub mod eval_enhancer;
pub mod eval_map;
pub mod export;
pub mod interpolate_weights;
pub mod launch;
pub mod logs;
pub mod method_args;
pub mod operating_args;
pub mod progress;
pub mod reconstruct;
pub mod render;
#[cfg(unix)]
pub mod scene_source;
pub mod shader_cache;
pub mod shutdown;
pub mod stream;
pub mod synth;
pub mod train;
pub mod train_enhancer;
pub mod view;
pub mod worker;
pub mod zenoh_args;
