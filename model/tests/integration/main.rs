//! The model's integration tests, one module per former test file, built as one test binary:
//! each test binary compiled its own instances of candle's generic code, and 27 of them
//! took a third of the model's test build. `cuda_ops` stays a binary of its own, built only
//! with the `cuda` feature (`scripts/build_cuda.sh`).
//!
//! Run one file's tests with `cargo test --release -p model --test integration MODULE::`.

#[path = "../drive_support/mod.rs"]
mod drive_support;
#[path = "../finite_support/mod.rs"]
mod finite_support;
#[path = "../shipped_support/mod.rs"]
mod shipped_support;
#[path = "../train_support/mod.rs"]
mod train_support;
#[path = "../var_support/mod.rs"]
mod var_support;
#[path = "../volume_support/mod.rs"]
mod volume_support;

mod baseline;
mod baseline_range;
mod enhance;
mod enhance_train;
mod eval;
mod generate;
mod guidance;
mod kitti360;
mod lpips;
mod metrics;
mod net;
mod ops_bilinear;
mod ops_conv;
mod ops_render;
mod ops_transpose;
mod pair_fusion;
mod progressive;
mod pseudo_mix;
mod rig_range;
mod synth;
mod synth_randomised;
mod synth_scenes;
mod tiny_3d_weights;
mod tiny_weights_unchanged;
mod train;
mod volume_decoder;
mod volume_encoder;
mod volume_fusion;
mod volume_occupancy;
mod volume_training;
