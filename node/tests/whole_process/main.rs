//! The node's tests that measure the whole test process: its resident memory under a burst
//! (`node_burst`), under oversized and hostile input (`node_limits`), and a node process of
//! its own loaded at twenty times the frame rate while both cores are busy (`node_overload`).
//!
//! One binary, so the node's generic code is compiled once for the three (as three binaries
//! they took 133 s of the test build's CPU); its tests run one at a time under [`SERIAL`],
//! so each one's memory and load are its own. Every allocation is measured by `msg_fuzz`,
//! which stays a binary of its own (its allocator records the whole process).
//!
//! Run one file's tests with `cargo test --release -p node --test whole_process MODULE::`.

#[path = "../drive_support/mod.rs"]
mod drive_support;

mod node_burst;
mod node_limits;
mod node_overload;

/// Held for the whole of every test of this binary: tests in one binary otherwise run in
/// parallel, and each here measures the process.
static SERIAL: tokio::sync::Mutex<()> = tokio::sync::Mutex::const_new(());
