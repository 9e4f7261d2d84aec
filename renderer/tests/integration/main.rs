//! The renderer's integration tests, one module per former test file, built as one test
//! binary: each binary linked its own copy of wgpu and compiled its own instances of the
//! generic code, a cost node's and model's tests dropped the same way (docs/ci.md,
//! "Keeping it short").
//! One module alone: `cargo test --release -p renderer --test integration MODULE::`.

mod cpu_extremes;
mod cpu_gradients;
mod gpu_parity;
mod picture;
mod ply;
mod surface_depth;
