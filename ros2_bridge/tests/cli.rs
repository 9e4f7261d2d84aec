//! The bridge's command line, run as a user runs it: without a configuration, or with one that
//! cannot be read, it exits non-zero and says why, before it starts any zenoh or DDS runtime.
//! (Running it against ROS 2 nodes is node's `ros2_bridge` test, which needs this binary:
//! being an integration test here makes `cargo test --workspace` build it.)

use std::process::{Command, Output};

fn bridge(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_stereosplat-ros2-bridge"))
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn without_a_configuration_it_prints_its_usage_and_fails() {
    let out = bridge(&[]);
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("usage: stereosplat-ros2-bridge CONFIG.json5"),
        "{stderr}"
    );
}

#[test]
fn an_unreadable_configuration_is_named_and_fails() {
    let missing = std::env::temp_dir().join("stereosplat-ros2-bridge-no-such-config.json5");
    let out = bridge(&[missing.to_str().unwrap()]);
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("reading the bridge configuration"),
        "{stderr}"
    );
    assert!(stderr.contains("no-such-config.json5"), "{stderr}");
}
